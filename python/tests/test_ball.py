"""The ball and its events in a Python session: each frame set carries its frame's ball rows
and the events decided, equal to the CLI's `--ball-out` and `--events-out` on the same
frames (at the files' decimals)."""

import csv
import json
import math

import pytest

import rodtrack

FRAMES = 200


@pytest.fixture(scope="module")
def goals(tmp_path_factory, cli):
    """The `goals` table (seed 3: a shot, then a goal within 200 frames), calibrated with its
    ball and table frame, saved for the CLI."""
    sim = rodtrack.simulate("goals", frames=2, seed=3)
    d = tmp_path_factory.mktemp("goals")
    calib = d / "calib.toml"
    sim.calibration.save(calib)
    inputs = [f"sim://goals?camera={c}&seed=3&frames={FRAMES}" for c in range(2)]
    # The scripted events of the whole timeline, as `rodtrack simulate` writes them (the
    # 2-frame Simulation above holds only its own frames' events).
    cli("simulate", "--scenario", "goals", "--seed", "3", "--every", "100000", "--out", str(d / "rec"))
    lines = (d / "rec" / "events_truth.jsonl").read_text().splitlines()
    truth = [e for e in map(json.loads, lines) if e["frame"] < FRAMES]
    assert sim.events_truth == [e for e in truth if e["frame"] < 2]
    return {"cal": sim.calibration, "calib": calib, "dir": d, "inputs": inputs, "truth": truth}


def fields(ball, i):
    """Row `i` of `ball` as the ball CSV's fields, before formatting."""
    camera = int(ball.camera[i])
    return {
        "frame": int(ball.frame[i]),
        "timestamp_s": float(ball.timestamp_s[i]),
        "camera": "fused" if camera == rodtrack.FUSED else str(camera),
        "x_mm": float(ball.x_mm[i]),
        "y_mm": float(ball.y_mm[i]),
        "vx_mm_s": float(ball.vx_mm_s[i]),
        "vy_mm_s": float(ball.vy_mm_s[i]),
        "quality": float(ball.quality[i]),
        "status": rodtrack.BALL_STATUS_NAMES[int(ball.status[i])],
    }


def same(py, text):
    """A value against its CSV text, at the text's decimals."""
    if isinstance(py, float):
        decimals = len(text.split(".")[1]) if "." in text else 0
        return f"{py:.{decimals}f}" == text
    return str(py) == text


def test_each_set_carries_its_ball_rows_and_events_as_the_cli_writes_them(goals, cli):
    ball_csv, events_jsonl = goals["dir"] / "ball.csv", goals["dir"] / "events.jsonl"
    cli("track", "--calib", str(goals["calib"]),
        "--input", goals["inputs"][0], "--input", goals["inputs"][1],
        "--out", str(goals["dir"] / "rows.csv"),
        "--ball-out", str(ball_csv), "--events-out", str(events_jsonl))
    with open(ball_csv, newline="") as f:
        want = list(csv.DictReader(f))
    want_events = [json.loads(l) for l in events_jsonl.read_text().splitlines()]
    got, events, sets, seen = [], [], 0, 0
    with rodtrack.open(goals["cal"], inputs=goals["inputs"], events=True) as session:
        for s in session:
            sets += 1
            ball = s.ball
            got.extend(fields(ball, i) for i in range(len(ball)))
            # The table's ball this frame: the fused row of the set's own frame.
            fused = s.ball_fused
            assert len(fused) == 1 and fused.frame[0] == s.frame
            assert fused.camera[0] == rodtrack.FUSED
            seen += fused.status_names()[0] == "ok"
            events.extend(s.events)
        assert session.dropped_ball_rows == 0
    events.extend(session.final_events)
    assert sets == FRAMES
    fused_ok = sum(w["camera"] == "fused" and w["status"] == "ok" for w in want)
    assert seen == fused_ok > 0, f"the ball seen on {seen} frames, the CLI's {fused_ok}"
    assert len(got) == len(want) == 3 * FRAMES
    for i, (g, w) in enumerate(zip(got, want)):
        bad = [k for k in w if not same(g[k], w[k])]
        assert not bad, f"ball row {i}: {[(k, g[k], w[k]) for k in bad]}"
    assert events == want_events
    assert [e["event"] for e in events] == ["shot", "goal"], events
    assert events[1]["score"] == [1, 0]
    # Against the scenario's scripted events of those frames: the same plays, within 2 frames,
    # the shot by the rod that kicked.
    truth = goals["truth"]
    assert [e["event"] for e in truth] == ["shot", "goal"], truth
    for t, e in zip(truth, events):
        assert abs(t["frame"] - e["frame"]) <= 2, (t, e)
    assert events[0]["rod"] == truth[0]["rod"] and events[1]["score"] == truth[1]["score"]


def test_the_ball_is_asked_for(goals):
    with rodtrack.open(goals["cal"], inputs=goals["inputs"], max_frames=3) as session:
        s = next(iter(session))
        assert len(s.ball) == 0 and len(s.ball_fused) == 0 and s.events == []
    with pytest.raises(ValueError, match="events=True"):
        rodtrack.open(goals["cal"], inputs=goals["inputs"], goal_width_mm=180.0)
    with pytest.raises(rodtrack.RodtrackError, match="goal"):
        rodtrack.open(goals["cal"], inputs=goals["inputs"], events=True, goal_width_mm=-1.0)


def test_the_ball_is_where_the_simulators_truth_has_it():
    """The `ball` scenario (rolling at up to 2 m/s), 120 frames: every fused row `ok` within
    3 mm of the truth (the issue's maximum for such a ball), and the ball found on at least 99 %
    of the frames where a camera sees at least half of it."""
    frames = 120
    sim = rodtrack.simulate("ball", frames=frames, seed=3)
    truth = sim.ball_truth
    assert truth is not None and len(truth["x_mm"]) == frames
    assert truth["visible"].shape == (frames, 2)
    inputs = [f"sim://ball?camera={c}&seed=3&frames={frames}" for c in range(2)]
    errors, found, visible = [], 0, 0
    with rodtrack.open(sim.calibration, inputs=inputs, ball=True) as session:
        for s in session:
            f = int(s.frame)
            b = s.ball_fused
            ok = len(b) == 1 and b.status_names()[0] == "ok"
            if truth["visible"][f].max() >= 0.5:
                visible += 1
                found += ok
            if ok:
                errors.append(math.hypot(b.x_mm[0] - truth["x_mm"][f], b.y_mm[0] - truth["y_mm"][f]))
    assert visible > frames // 2
    assert found >= 0.99 * visible, f"found on {found} of {visible} frames"
    worst = max(errors)
    print(f"\nball: {len(errors)} fused rows ok, error median {sorted(errors)[len(errors) // 2]:.2f} mm, max {worst:.2f} mm")
    assert worst <= 3.0, worst
