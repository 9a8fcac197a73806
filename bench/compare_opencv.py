#!/usr/bin/env python3
"""Per-frame processing time: rodtrack vs the full-frame OpenCV work it avoids, on the same frames.

On the Bayer frames of one camera (as `rodtrack simulate` writes them), this times:

  * OpenCV Bayer-to-BGR demosaicing (cv2.cvtColor) plus full-frame undistortion
    (cv2.initUndistortRectifyMap once, cv2.remap per frame): the approach the paper avoids;
  * OpenCV's ArUco detector in ArUco3 mode (useAruco3Detection=True) on the frame's grey image,
    a typical fiducial-marker alternative;
  * rodtrack's whole per-frame processing of every rod the camera sees (enhanced and paper
    mode), through `rodtrack bench-frames`, which prints its median per-frame time as JSON;

and prints the ratios. OpenCV is timed with one thread (rodtrack processes a frame on one
thread) and with its default thread count.

Needs: numpy and opencv-python-headless (`pip install opencv-python-headless`), a release build
of rodtrack.

    cargo build --release -p rodtrack
    python3 bench/compare_opencv.py --rodtrack target/release/rodtrack

renders 20 gameplay frames and calibrates into --workdir if they are not there yet; or give
--frames DIR --calib FILE --inputs JSON for an existing recording.
"""

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import time
from pathlib import Path

try:
    import cv2
    import numpy as np
except ImportError as e:  # pragma: no cover
    sys.exit(f"{e}: install numpy and opencv-python-headless (pip install opencv-python-headless)")


def machine():
    model = "unknown CPU"
    try:
        out = subprocess.run(["lscpu"], capture_output=True, text=True, check=True).stdout
        for line in out.splitlines():
            if line.startswith("Model name:"):
                model = line.split(":", 1)[1].strip()
    except (OSError, subprocess.CalledProcessError):
        pass
    return {"cpu": model, "nproc": os.cpu_count(), "load_average": os.getloadavg(), "os": platform.platform(),
            "python": platform.python_version(), "opencv": cv2.__version__}


def run(cmd):
    print("+", " ".join(str(c) for c in cmd), file=sys.stderr)
    return subprocess.run([str(c) for c in cmd], check=True, capture_output=True, text=True).stdout


def prepare(args):
    """Renders and calibrates a short recording unless --frames/--calib are given."""
    if args.frames and args.calib:
        inputs = Path(args.inputs) if args.inputs else Path(args.frames).parent / (Path(args.frames).name + ".json")
        return Path(args.frames), Path(args.calib), inputs
    work = Path(args.workdir)
    frames, calib, inputs = work / "cam0", work / "calibration.toml", work / "cam0.json"
    if not frames.is_dir() or len(list(frames.glob("*.png"))) < args.max_frames:
        run([args.rodtrack, "simulate", "--scenario", args.scenario, "--out", work,
             "--frames", args.max_frames, "--seed", "7"])
    if not calib.is_file():
        run([args.rodtrack, "calibrate", "--inputs", inputs, "--out", calib])
    return frames, calib, inputs


def median_us(fn, frames, repeat):
    for f in frames:  # warm-up
        fn(f)
    times = []
    for _ in range(repeat):
        for f in frames:
            t = time.perf_counter()
            fn(f)
            times.append((time.perf_counter() - t) * 1e6)
    return statistics.median(times)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--rodtrack", default="target/release/rodtrack", help="rodtrack binary")
    ap.add_argument("--frames", help="folder of one camera's Bayer PNG frames")
    ap.add_argument("--calib", help="calibration file for those frames (rodtrack calibrate)")
    ap.add_argument("--inputs", help="calibration-inputs JSON with the OpenCV camera model "
                    "(default: <frames>.json beside the folder)")
    ap.add_argument("--workdir", default="/tmp/rodtrack-bench-opencv",
                    help="where to render frames when --frames/--calib are not given")
    ap.add_argument("--scenario", default="gameplay")
    ap.add_argument("--max-frames", type=int, default=20)
    ap.add_argument("--repeat", type=int, default=20)
    ap.add_argument("--json", help="also write the results here")
    args = ap.parse_args()

    frames_dir, calib, inputs_path = prepare(args)
    files = sorted(frames_dir.glob("*.png"))[: args.max_frames]
    if not files:
        sys.exit(f"no PNG frames in {frames_dir}")
    raw = [cv2.imread(str(p), cv2.IMREAD_UNCHANGED) for p in files]
    if any(r is None or r.ndim != 2 or r.dtype != np.uint8 for r in raw):
        sys.exit("expected 8-bit single-channel Bayer PNG frames")
    h, w = raw[0].shape
    inputs = json.loads(inputs_path.read_text())
    model = inputs.get("opencv_model_optional")
    if model is None:
        sys.exit(f"{inputs_path} has no opencv_model_optional (camera matrix, distortion)")
    K = np.array(model["camera_matrix"], dtype=np.float64)
    dist = np.array(model["dist_coeffs"], dtype=np.float64)
    # The sensor is RGGB. OpenCV names Bayer codes after the second row's pattern, so RGGB is
    # COLOR_BayerBG2BGR (alias COLOR_BayerRGGB2BGR in recent versions); the time is the same
    # for every pattern.
    bayer2bgr = getattr(cv2, "COLOR_BayerRGGB2BGR", cv2.COLOR_BayerBG2BGR)
    bayer2gray = getattr(cv2, "COLOR_BayerRGGB2GRAY", cv2.COLOR_BayerBG2GRAY)
    map1, map2 = cv2.initUndistortRectifyMap(K, dist, None, K, (w, h), cv2.CV_16SC2)
    grey = [cv2.cvtColor(r, bayer2gray) for r in raw]

    def demosaic_remap(r):
        bgr = cv2.cvtColor(r, bayer2bgr)
        return cv2.remap(bgr, map1, map2, cv2.INTER_LINEAR)

    dictionary = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_4X4_50)
    params = cv2.aruco.DetectorParameters()
    params.useAruco3Detection = True
    detector = cv2.aruco.ArucoDetector(dictionary, params)
    # ArUco3's speed comes from searching a downscaled image for markers of a known smallest
    # size; with the default (0) it searches the full image. A marker that fits on a 16 mm rod
    # is about 20 px of the 1080 px image: ratio 0.02.
    params_small = cv2.aruco.DetectorParameters()
    params_small.useAruco3Detection = True
    params_small.minMarkerLengthRatioOriginalImg = 0.02
    detector_small = cv2.aruco.ArucoDetector(dictionary, params_small)

    results = {"machine": machine(), "frames": len(files), "frames_dir": str(frames_dir),
               "width": w, "height": h, "repeat": args.repeat, "opencv": {}}
    default_threads = cv2.getNumThreads()
    for threads in (1, default_threads):
        cv2.setNumThreads(threads)
        results["opencv"][f"{threads}_threads"] = {
            "bayer_to_bgr_us": median_us(lambda r: cv2.cvtColor(r, bayer2bgr), raw, args.repeat),
            "bayer_to_bgr_plus_remap_us": median_us(demosaic_remap, raw, args.repeat),
            "aruco3_detect_us": median_us(lambda g: detector.detectMarkers(g), grey, args.repeat),
            "aruco3_min_ratio_0.02_detect_us": median_us(lambda g: detector_small.detectMarkers(g), grey,
                                                         args.repeat),
        }
    cv2.setNumThreads(default_threads)

    out = run([args.rodtrack, "bench-frames", "--calib", calib, "--input", frames_dir,
               "--repeat", args.repeat, "--max-frames", args.max_frames])
    rt = json.loads(out)
    results["rodtrack"] = rt
    enh = rt["enhanced"]["median_us"]
    pap = rt["paper"]["median_us"] if rt.get("paper") else None

    print(f"machine: {results['machine']['cpu']}, {results['machine']['nproc']} CPUs, "
          f"load average {results['machine']['load_average'][0]:.1f}; "
          f"OpenCV {cv2.__version__}; {len(files)} frames {w}x{h} from {frames_dir}, "
          f"{rt['rods']} rods, median of {args.repeat} passes")
    print(f"{'':44} {'1 thread':>12} {f'{default_threads} threads':>12}")
    one, many = results["opencv"]["1_threads"], results["opencv"][f"{default_threads}_threads"]
    for key, name in [("bayer_to_bgr_us", "OpenCV Bayer->BGR"),
                      ("bayer_to_bgr_plus_remap_us", "OpenCV Bayer->BGR + undistort remap"),
                      ("aruco3_detect_us", "OpenCV ArUco3 detectMarkers (grey frame)"),
                      ("aruco3_min_ratio_0.02_detect_us", "  same, minMarkerLengthRatioOriginalImg 0.02")]:
        print(f"{name:44} {one[key]:>10.0f}us {many[key]:>10.0f}us")
    print(f"{'rodtrack enhanced, all rods (1 thread)':44} {enh:>10.1f}us")
    if pap is not None:
        print(f"{'rodtrack paper mode, all rods (1 thread)':44} {pap:>10.1f}us")
    ratios = {}
    for label, base in [("enhanced", enh), ("paper", pap)]:
        if base is None:
            continue
        for t, d in [("1 thread", one), (f"{default_threads} threads", many)]:
            r1 = d["bayer_to_bgr_plus_remap_us"] / base
            r2 = d["aruco3_detect_us"] / base
            r3 = d["aruco3_min_ratio_0.02_detect_us"] / base
            ratios[f"{label}, OpenCV {t}"] = {"remap_over_rodtrack": r1, "aruco3_over_rodtrack": r2,
                                              "aruco3_min_ratio_0.02_over_rodtrack": r3}
            print(f"ratio vs rodtrack {label:8} (OpenCV {t:>9}): Bayer->BGR+remap / rodtrack = {r1:6.1f}x "
                  f"(target >= 100x: {'met' if r1 >= 100 else 'NOT met'}), "
                  f"ArUco3 / rodtrack = {r2:6.1f}x (target >= 50x: {'met' if r2 >= 50 else 'NOT met'}; "
                  f"with ratio 0.02: {r3:.1f}x, {'met' if r3 >= 50 else 'NOT met'})")
    results["ratios"] = ratios
    if args.json:
        Path(args.json).write_text(json.dumps(results, indent=2))


if __name__ == "__main__":
    main()
