"""A control loop on the simulator's fused rows at 200 Hz: prints the goalkeeper rod's slide
and angle. Run: python control_loop.py [seconds]"""
import math
import sys
import time

import rodtrack

GOALKEEPER = 0  # rod 0: the goalkeeper of the team on the x = 0 side
seconds = float(sys.argv[1]) if len(sys.argv) > 1 else 3.0

calib = rodtrack.simulate("gameplay", frames=1, seed=1).calibration
inputs = [f"sim://gameplay?camera={c}&seed=1&realtime=1" for c in range(calib.cameras)]
with rodtrack.open(calib, inputs=inputs) as session:
    start = time.perf_counter()
    for frame_set in session:  # one frame set per trigger, 200 per second
        rows = frame_set.fused
        k = list(rows.rod).index(GOALKEEPER)
        status = rodtrack.STATUS_NAMES[rows.status[k]]
        if frame_set.frame % 20 == 0:  # print at 10 Hz, control at 200 Hz
            print(f"frame {frame_set.frame:5d}  slide {rows.position_mm[k]:+8.2f} mm  "
                  f"angle {math.degrees(rows.angle_rad[k]):6.1f} deg  {status}")
        if time.perf_counter() - start > seconds:
            break
    print(f"dropped frame sets: {session.dropped_sets}")
