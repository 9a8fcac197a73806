"""Writes the OpenCV FileStorage fixtures of `crates/rodtrack-core/tests/opencv_files.rs`.

Run with opencv-python (e.g. `pip install opencv-python-headless` in a virtual environment), once
with OpenCV 4.x and once with 5.x, from this folder:

    python make_fixtures.py

Each run calibrates a simulated camera with `cv2.calibrateCamera` (a chessboard seen from 12
poses, 0.2 px of noise) and writes what OpenCV wrote plus `<name>.expected.txt`: the exact
doubles that were written, as the hex of their bits, which the Rust test compares bit for bit.
"""
import struct

import cv2
import numpy as np

MAJOR = cv2.__version__.split(".")[0]
K = np.array([[1078.0, 0, 719.5], [0, 1078.0, 539.5], [0, 0, 1]])
D = np.array([-0.25, 0.08, 0.001, -0.0005, 0.0])


def views(rng, dist):
    obj = np.zeros((9 * 6, 3), np.float32)
    obj[:, :2] = np.mgrid[0:9, 0:6].T.reshape(-1, 2) * 25.0
    objs, imgs = [], []
    for _ in range(12):
        rvec = rng.normal(0, 0.3, 3)
        tvec = np.array([rng.uniform(-150, 50), rng.uniform(-100, 20), rng.uniform(500, 900)])
        p, _ = cv2.projectPoints(obj, rvec, tvec, K, dist)
        imgs.append((p + rng.normal(0, 0.2, p.shape)).astype(np.float32))
        objs.append(obj)
    return objs, imgs


def write(name, entries, expected):
    fs = cv2.FileStorage(name, cv2.FILE_STORAGE_WRITE)
    for key, value in entries:
        fs.write(key, value)
    fs.release()
    if expected is not None:
        with open(name + ".expected.txt", "w") as f:
            for key in ["camera_matrix", "dist_coeffs"]:
                values = np.asarray(expected[key], dtype=np.float64).ravel()
                bits = [struct.unpack("<Q", struct.pack("<d", v))[0] for v in values]
                f.write(key + " " + " ".join(f"{b:016x}" for b in bits) + "\n")


rng = np.random.default_rng(int(MAJOR))
objs, imgs = views(rng, D)
rms, mtx, dist, rvecs, tvecs = cv2.calibrateCamera(objs, imgs, (1440, 1080), None, None)
extr = np.hstack([np.array(rvecs).reshape(-1, 3), np.array(tvecs).reshape(-1, 3)])
expected = {"camera_matrix": mtx.tolist(), "dist_coeffs": dist.ravel().tolist()}
for ext in ["yml", "json"]:
    # As OpenCV's calibration sample writes it: size, flags, the model, per-view extrinsics.
    write(
        f"opencv{MAJOR}_calib.{ext}",
        [
            ("calibration_time", "Thu Jan  1 00:00:00 1970"),
            ("image_width", 1440),
            ("image_height", 1080),
            ("flags", 0),
            ("camera_matrix", mtx),
            ("distortion_coefficients", dist),
            ("avg_reprojection_error", rms),
            ("extrinsic_parameters", extr),
        ],
        expected,
    )

if MAJOR == "4":
    # The rational model: k4..k6 are not zero, rodtrack must refuse the file.
    flags = cv2.CALIB_RATIONAL_MODEL
    _, mtx8, dist8, _, _ = cv2.calibrateCamera(objs, imgs, (1440, 1080), None, None, flags=flags)
    write("opencv4_rational.yml", [("camera_matrix", mtx8), ("distortion_coefficients", dist8)], None)
    # 14 coefficients as a column, the higher ones zero, under the other common names.
    d14 = np.zeros((14, 1))
    d14[:5, 0] = dist.ravel()
    write(
        "opencv4_14_coeffs.json",
        [("cameraMatrix", mtx), ("distCoeffs", d14)],
        {"camera_matrix": mtx.tolist(), "dist_coeffs": d14.ravel().tolist()},
    )
    # Single-precision matrices (dt: f) and 4 coefficients, as K and D.
    write(
        "opencv4_float.yml",
        [("K", mtx.astype(np.float32)), ("D", dist.ravel()[:4].astype(np.float32).reshape(1, 4))],
        {
            "camera_matrix": mtx.astype(np.float32).astype(np.float64).tolist(),
            "dist_coeffs": dist.ravel()[:4].astype(np.float32).astype(np.float64).tolist(),
        },
    )
print("OpenCV", cv2.__version__, "rms", rms)
