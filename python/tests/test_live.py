"""A live `sim://` session (two cameras, real time) runs for 2 s and keeps up at 200 frame
sets/s with a Python loop that does nothing."""

import time

import rodtrack

FPS = 200.0


def test_live_session_keeps_up_with_two_cameras_at_200_fps(sim):
    cal = sim.calibration
    # Frames rendered when opened and cycled (as a camera delivers them: the host only
    # copies), released at 200 fps.
    inputs = [f"sim://gameplay?camera={c}&seed=1&realtime=1&prerender=20&frames=2000" for c in range(2)]
    with rodtrack.open(cal, inputs=inputs) as session:
        assert session.is_live
        it = iter(session)
        first = next(it)
        start, first_frame = time.perf_counter(), first.frame
        sets, last = 0, first
        for frame_set in it:
            sets += 1
            last = frame_set
            if time.perf_counter() - start >= 2.0:
                break
        elapsed = time.perf_counter() - start
        dropped = session.dropped_sets
    rate = sets / elapsed
    frames_advanced = last.frame - first_frame
    print(f"\nlive sim session: {sets} frame sets in {elapsed:.2f} s = {rate:.1f} sets/s, "
          f"frame ids advanced {frames_advanced}, dropped by the Python side {dropped}")
    print(session.summary)
    assert elapsed >= 2.0
    # Keeping up: the loop got (almost) every frame set the cameras delivered at 200 fps.
    assert rate >= 0.95 * FPS, rate
    assert dropped == 0
    assert sets >= 0.95 * frames_advanced
