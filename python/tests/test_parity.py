"""Python's rows equal the CLI's CSV on the same recorded frames, value for value (at the
CSV's decimals)."""

import re

import numpy as np
import pytest

import rodtrack
from conftest import as_csv_fields, read_csv


def frames_of(folder):
    """(frame id, path) of a recording folder, in name order (ids from the file names)."""
    files = sorted(p for p in folder.iterdir() if p.suffix in (".png", ".pgm", ".tif"))
    return [(int(re.search(r"(\d+)", p.stem).group(1)), p) for p in files]


def assert_same(py_fields, csv_fields, header, what):
    assert len(py_fields) == len(csv_fields), f"{what}: {len(py_fields)} rows vs {len(csv_fields)}"
    for i, (a, b) in enumerate(zip(py_fields, csv_fields)):
        if a != b:
            diff = [f"{h}: python {x} cli {y}" for h, x, y in zip(header, a, b) if x != y]
            pytest.fail(f"{what}: row {i} differs: {'; '.join(diff)}")


def track_with_tracker(recording, camera, filter):
    cal = recording["cal"]
    tracker = rodtrack.Tracker(cal, camera=camera, filter=filter)
    fmt = cal.pixel_format(camera)
    out = []
    for frame_id, path in frames_of(recording["rec"] / f"cam{camera}"):
        frame = rodtrack.read_frame(path, fmt)
        rows = tracker.process(frame, frame_id=frame_id)
        for name in ("position_mm", "angle_rad", "quality", "velocity_mm_s"):
            assert np.all(np.isfinite(getattr(rows, name))), name
        out.append(rows)
    return out


@pytest.mark.parametrize("raw", [True, False], ids=["raw", "filtered"])
def test_tracker_rows_equal_the_cli_csv(recording, cli, raw):
    out = recording["dir"] / ("raw.csv" if raw else "filtered.csv")
    args = ["track", "--calib", str(recording["calib"]),
            "--input", str(recording["rec"] / "cam0"),
            "--input", str(recording["rec"] / "cam1"),
            "--out", str(out)]
    cli(*(args + (["--raw"] if raw else [])))
    header, rows = read_csv(out)
    cam = header.index("camera")
    for camera in range(recording["cal"].cameras):
        py = [f for r in track_with_tracker(recording, camera, filter=not raw)
              for f in as_csv_fields(r, header)]
        want = [r for r in rows if r[cam] == str(camera)]
        assert len(want) == 40 * len(recording["cal"].rods(camera))
        assert_same(py, want, header, f"camera {camera}, {'raw' if raw else 'filtered'}")


def test_session_rows_equal_the_cli_csv(recording, cli):
    out = recording["dir"] / "session.csv"
    inputs = [str(recording["rec"] / "cam0"), str(recording["rec"] / "cam1")]
    cli("track", "--calib", str(recording["calib"]),
        "--input", inputs[0], "--input", inputs[1], "--out", str(out))
    header, want = read_csv(out)
    py = []
    sets = 0
    with rodtrack.open(recording["cal"], inputs=inputs) as session:
        assert not session.is_live
        for frame_set in session:
            sets += 1
            fused = frame_set.fused
            assert len(fused) == 8 and set(fused.camera) == {rodtrack.FUSED}
            assert np.all(fused.frame == frame_set.frame)
            py.extend(as_csv_fields(frame_set.rows, header))
        assert session.dropped_sets == 0
    assert sets == 40
    assert session.summary is not None
    assert any(r[header.index("camera")] == "fused" for r in want)
    assert_same(py, want, header, "session")


def test_padded_and_strided_frames_give_the_same_rows(recording):
    """A frame borrowed from a wider array (padded rows) or from every other row of a taller
    one gives the rows of the packed frame, exactly."""
    cal = recording["cal"]
    frames = [rodtrack.read_frame(p, cal.pixel_format(0))
              for _, p in frames_of(recording["rec"] / "cam0")[:5]]
    h, w = frames[0].shape
    trackers = [rodtrack.Tracker(cal, camera=0) for _ in range(3)]
    for i, f in enumerate(frames):
        wide = np.zeros((h, w + 64), np.uint8)
        wide[:, 32:32 + w] = f
        tall = np.zeros((2 * h, w), np.uint8)
        tall[::2] = f
        views = [f, wide[:, 32:32 + w], tall[::2]]
        assert not views[1].flags.c_contiguous and not views[2].flags.c_contiguous
        got = [t.process(v, frame_id=i).to_dict() for t, v in zip(trackers, views)]
        for other in got[1:]:
            for name in rodtrack.COLUMNS:
                np.testing.assert_array_equal(got[0][name], other[name], err_msg=name)


def test_simulate_frames_track_like_the_truth(sim):
    """simulate() gives frames, truth and a calibration that fit each other: the tracker on
    the frames is close to the truth where the marker is visible."""
    ncam, n, h, w = sim.frames.shape
    assert (ncam, n) == (2, 3) and sim.frames.dtype == np.uint8
    assert sim.calibration.image_size(0) == (w, h)
    assert len(sim.frame_ids) == n and np.all(np.diff(sim.timestamps_ns.astype(np.int64)) > 0)
    truth = sim.truth
    assert len(truth) == len(sim.visible) == n * ncam * 8
    tracker = rodtrack.Tracker(sim.calibration, camera=0, filter=False)
    compared = 0
    for i in range(n):
        rows = tracker.process(sim.frames[0, i], frame_id=int(sim.frame_ids[i]),
                               timestamp_ns=int(sim.timestamps_ns[i]))
        sel = (truth.frame == sim.frame_ids[i]) & (truth.camera == 0)
        t_rod, t_pos, t_vis = truth.rod[sel], truth.position_mm[sel], sim.visible[sel]
        for rod, pos, st in zip(rows.rod, rows.position_mm, rows.status):
            k = np.nonzero(t_rod == rod)[0]
            assert len(k) == 1
            if st == 0 and t_vis[k[0]]:
                compared += 1
                assert abs(pos - t_pos[k[0]]) < 2.0, (i, rod, pos, t_pos[k[0]])
    assert compared >= n * 4


def test_uint16_frames_of_a_16_bit_camera_track_like_their_8_bit_pixels(sim, tmp_path):
    """A 16-bit camera's frames (uint16, the 8-bit pixels times 257: the same luminance) give
    the rows of the 8-bit frames, to float rounding; the other byte order is refused."""
    path = tmp_path / "calib16.toml"
    sim.calibration.save(path)
    text = path.read_text()
    assert text.count('pixel_format = "bayer_rggb8"') == 2
    path.write_text(text.replace('pixel_format = "bayer_rggb8"', 'pixel_format = "bayer_rggb16"'))
    cal16 = rodtrack.Calibration.load(path)
    assert cal16.pixel_format(0) == "bayer_rggb16"
    t8 = rodtrack.Tracker(sim.calibration, camera=0)
    t16 = rodtrack.Tracker(cal16, camera=0)
    for i in range(sim.frames.shape[1]):
        f8 = sim.frames[0, i]
        f16 = f8.astype(np.uint16) * 257
        a, b = t8.process(f8, frame_id=i), t16.process(f16, frame_id=i)
        np.testing.assert_array_equal(a.status, b.status)
        np.testing.assert_allclose(a.position_mm, b.position_mm, atol=1e-3)
        np.testing.assert_allclose(a.angle_rad, b.angle_rad, atol=1e-4)
    with pytest.raises(TypeError, match=r"give a uint16 array, got >u2"):
        t16.process(f16.astype(">u2"), frame_id=99)
    with pytest.raises(TypeError, match=r"give a uint16 array, got uint8"):
        t16.process(f8, frame_id=99)
