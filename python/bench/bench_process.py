"""The overhead of a Python `Tracker.process` call over the Rust call it makes.

For each call: the call's wall time seen from Python minus the time Rust spent tracking
(`Tracker.last_process_ns`, measured inside the native call around the tracker and the
temporal filter): what borrowing the numpy frame, releasing and taking back the GIL and
returning the `Rows` cost. Also the cost of reading the row columns as numpy arrays.

Run: python bench/bench_process.py [calls]
"""
import statistics
import sys
import time

import rodtrack

calls = int(sys.argv[1]) if len(sys.argv) > 1 else 2000
sim = rodtrack.simulate("exp3", frames=20, seed=1)
tracker = rodtrack.Tracker(sim.calibration, camera=0)
frames = [sim.frames[0, i] for i in range(sim.frames.shape[1])]
ids = [int(i) for i in sim.frame_ids]
overhead, total, rust, read = [], [], [], []
for k in range(calls):
    i = k % len(frames)
    frame_id = ids[i] + (k // len(frames)) * len(frames)
    t0 = time.perf_counter_ns()
    rows = tracker.process(frames[i], frame_id=frame_id)
    t1 = time.perf_counter_ns()
    rows.position_mm, rows.angle_rad, rows.status
    t2 = time.perf_counter_ns()
    if k < 50:
        continue  # warm-up
    total.append(t1 - t0)
    rust.append(tracker.last_process_ns)
    overhead.append(t1 - t0 - tracker.last_process_ns)
    read.append(t2 - t1)


def us(v):
    return f"{v / 1e3:.2f} us"


q = lambda v, p: sorted(v)[int(p * (len(v) - 1))]
print(f"{len(total)} calls, {len(tracker.rods)} rods, {tracker.pixel_format} "
      f"{tracker.shape[1]}x{tracker.shape[0]}")
print(f"process() from Python: median {us(statistics.median(total))}, "
      f"Rust tracking inside it: median {us(statistics.median(rust))}")
print(f"overhead of the Python call: median {us(statistics.median(overhead))}, "
      f"p90 {us(q(overhead, 0.9))}, p99 {us(q(overhead, 0.99))}")
print(f"reading position_mm, angle_rad, status as numpy arrays: median "
      f"{us(statistics.median(read))}")
