"""Bad input raises exceptions that carry the Rust message, never a crash or a NaN."""

import numpy as np
import pytest

import rodtrack


@pytest.fixture()
def tracker(sim):
    return rodtrack.Tracker(sim.calibration, camera=0)


def test_wrong_dtype_is_a_type_error(sim, tracker):
    f = sim.frames[0, 0]
    with pytest.raises(TypeError, match=r"bayer_rggb8 frames: give a uint8 array, got float32"):
        tracker.process(f.astype(np.float32), frame_id=0)
    with pytest.raises(TypeError, match=r"got uint16"):
        tracker.process(f.astype(np.uint16), frame_id=0)
    with pytest.raises(TypeError, match=r"must be a numpy array, got list"):
        tracker.process([[0, 1], [2, 3]], frame_id=0)


def test_wrong_shape_is_a_value_error(sim, tracker):
    f = sim.frames[0, 0]
    with pytest.raises(ValueError, match=r"camera 0 \(cam0\).*shape \(1080, 1440\): got shape \(1080, 1439\)"):
        tracker.process(f[:, :-1], frame_id=0)
    with pytest.raises(ValueError, match=r"got shape \(1080, 1440, 1\)"):
        tracker.process(f[:, :, None], frame_id=0)
    with pytest.raises(ValueError, match=r"got shape \(1555200,\)"):
        tracker.process(f.ravel(), frame_id=0)


def test_strides_that_cannot_be_a_frame_are_refused(sim, tracker):
    f = sim.frames[0, 0]
    wide = np.zeros((1080, 2880), np.uint8)
    with pytest.raises(ValueError, match=r"pixels of a row are not next to each other.*ascontiguousarray"):
        tracker.process(wide[:, ::2], frame_id=0)
    with pytest.raises(ValueError, match=r"rows do not follow each other top to bottom"):
        tracker.process(f[::-1], frame_id=0)
    # The same pixels made contiguous are fine.
    rows = tracker.process(np.ascontiguousarray(f[::-1]), frame_id=0)
    assert len(rows) == 7


def test_bad_arguments_name_what_is_wrong(sim):
    with pytest.raises(rodtrack.RodtrackError, match=r'unknown mode "fast": expected one of enhanced, paper'):
        rodtrack.Tracker(sim.calibration, mode="fast")
    with pytest.raises(IndexError, match=r"camera 5 does not exist: the calibration has 2 camera"):
        rodtrack.Tracker(sim.calibration, camera=5)
    with pytest.raises(rodtrack.RodtrackError, match=r"2 camera\(s\) but 1 input"):
        rodtrack.open(sim.calibration, inputs=["sim://gameplay?camera=0"])
    with pytest.raises(rodtrack.RodtrackError, match=r"camera 1 \(cam1\): input /nonexistent/cam1"):
        rodtrack.open(sim.calibration, inputs=["sim://gameplay?camera=0&frames=2", "/nonexistent/cam1"])


def test_a_closed_session_raises(sim):
    session = rodtrack.open(sim.calibration, inputs=[f"sim://gameplay?camera={c}&frames=50" for c in range(2)])
    with session:
        first = next(session)
        assert first.frame == 0
    assert not session.is_open
    with pytest.raises(rodtrack.SessionClosed, match="closed"):
        next(session)
    with pytest.raises(rodtrack.SessionClosed):
        with session:
            pass
    session.close()  # twice: nothing
    assert session.summary is not None


def test_a_session_that_ends_stops_iterating(sim):
    with rodtrack.open(sim.calibration, inputs=[f"sim://gameplay?camera={c}&frames=3" for c in range(2)]) as s:
        assert [fs.frame for fs in s] == [0, 1, 2]
        assert list(s) == []


def test_malformed_calibrations_raise_naming_the_file_and_field(tmp_path, sim):
    bad = tmp_path / "bad.toml"
    bad.write_text("this is = = not toml")
    with pytest.raises(rodtrack.CalibrationError, match=r"calibration file .*bad\.toml is malformed"):
        rodtrack.Calibration.load(bad)
    good = tmp_path / "good.toml"
    sim.calibration.save(good)
    text = good.read_text()
    assert "image_width = 1440" in text
    wrong = tmp_path / "wrong.toml"
    wrong.write_text(text.replace("image_width = 1440", 'image_width = "wide"', 1))
    with pytest.raises(rodtrack.CalibrationError, match=r"(?s)wrong\.toml is malformed.*image_width = \"wide\""):
        rodtrack.Calibration.load(wrong)
    with pytest.raises(rodtrack.CalibrationError, match=r"cannot read calibration file .*missing\.toml"):
        rodtrack.Calibration.load(tmp_path / "missing.toml")
    again = rodtrack.Calibration.load(good)
    assert again.rods(1) == sim.calibration.rods(1)


def test_malformed_calibration_inputs_raise(tmp_path):
    inputs = tmp_path / "cam0.json"
    inputs.write_text('{"camera_name": "cam0", "image_size": 7}')
    with pytest.raises(rodtrack.CalibrationError, match=r"cam0\.json are malformed"):
        rodtrack.calibrate(inputs=[inputs])
