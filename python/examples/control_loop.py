"""A control loop on the simulator's fused rows at 200 Hz: prints the goalkeeper rod's slide
and angle, and the ball. Run: python control_loop.py [seconds]"""
import math
import sys
import time

import rodtrack

GOALKEEPER = 0  # rod 0: the goalkeeper of the team on the x = 0 side
seconds = float(sys.argv[1]) if len(sys.argv) > 1 else 3.0

calib = rodtrack.simulate("gameplay", frames=1, seed=1).calibration
# Two cameras released at 200 fps; prerender: 40 frames rendered up front and cycled (the host
# then only copies frames, as with real cameras; drop it to render every frame live).
inputs = [f"sim://gameplay?camera={c}&seed=1&realtime=1&prerender=40" for c in range(2)]
with rodtrack.open(calib, inputs=inputs, ball=True) as session:
    for n, frame_set in enumerate(session):  # one frame set per trigger
        start = time.perf_counter() if n == 0 else start
        rows = frame_set.fused
        k = list(rows.rod).index(GOALKEEPER)
        ball = frame_set.ball_fused  # the table's ball this frame (one row, or none)
        if frame_set.frame % 20 == 0:  # print at 10 Hz, control at 200 Hz
            at = f"ball {ball.x_mm[0]:+7.1f} {ball.y_mm[0]:+7.1f} mm {ball.status_names()[0]}" if len(ball) else ""
            print(f"frame {frame_set.frame:5d}  slide {rows.position_mm[k]:+8.2f} mm  angle "
                  f"{math.degrees(rows.angle_rad[k]):6.1f} deg  {rodtrack.STATUS_NAMES[rows.status[k]]}  {at}")
        if time.perf_counter() - start > seconds:
            break
    print(f"{n / (time.perf_counter() - start):.0f} frame sets/s, {session.dropped_sets} dropped")
