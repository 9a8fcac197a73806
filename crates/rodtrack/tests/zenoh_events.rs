//! The ball's events on the camera network (feature `zenoh`): scenario `goals` (a shot, then a
//! goal) through two camera nodes with `--zenoh-ball` and a fusion node with `--events-out` and
//! `--zenoh-events`, each its own `rodtrack` process on loopback. The events file must be that
//! of one in-process session on the same frames (`track --events-out`), and each event must go
//! out on `rodtrack/<table>/fused/events` as its line of the file, and again when the fusion
//! node's recording (`--mcap`) is replayed. A camera node alone (`track --publish zenoh
//! --zenoh-events`) publishes the events of its camera on `.../cam/<camera>/events`.
#![cfg(feature = "zenoh")]
#![allow(missing_docs, clippy::unwrap_used, clippy::expect_used)]

use rodtrack_zenoh::zenoh::Wait;
use std::path::Path;
use std::time::Duration;

mod zenoh_common;
use zenoh_common::{
    calibration_of, camera_nodes, collect_text, dir, end_run, free_port, run_ok, test_session,
    unix_ms, Proc,
};

/// The scenario's frames (its goal is at frame 93 of seed 3).
const FRAMES: u32 = 200;
/// From the nodes' start to the shared trigger's frame 0 (each node renders its frames first).
const START_MS: u64 = 8000;

fn sim(cam: u32, t0: Option<u64>) -> String {
    let base = format!("sim://goals?camera={cam}&seed=3&frames={FRAMES}");
    match t0 {
        Some(t) => format!("{base}&prerender={FRAMES}&realtime=1&trigger_unix_ms={t}"),
        None => base,
    }
}

/// A fresh test folder `name` and the calibration of the `goals` table (seed 3) in it, from
/// frame 0's images only.
fn goals_table(name: &str) -> (std::path::PathBuf, String) {
    let t = dir(name);
    let calib = calibration_of(&t, "goals", &["--seed", "3", "--every", "100000"]);
    let c = calib.display().to_string();
    (t, c)
}

fn read_lines(path: &Path) -> Vec<String> {
    std::fs::read_to_string(path)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .lines()
        .map(String::from)
        .collect()
}

#[test]
fn the_fusion_node_scores_the_goal_as_an_in_process_session_does() {
    let (t, c) = goals_table("zenoh_events");
    let port = free_port();
    let events = t.join("events.jsonl");
    let mcap = t.join("fuse.mcap");
    let mut fusion = Proc::start(
        &[
            "fuse",
            "--calib",
            &c,
            "--subscribe",
            "zenoh",
            "--publish",
            "zenoh",
            "--out",
            &t.join("fused.csv").display().to_string(),
            "--events-out",
            &events.display().to_string(),
            "--zenoh-events",
            "--mcap",
            &mcap.display().to_string(),
            "--zenoh-listen",
            &format!("tcp/127.0.0.1:{port}"),
            // No fault here: a camera late by a few frames on a loaded machine is waited for.
            "--loss-frames",
            "40",
        ]
        .map(String::from),
        t.join("fuse.err"),
    );
    // A control program's subscriber on the events' key.
    let session = test_session("connect", port);
    let seen = collect_text(&session, "rodtrack/default/fused/events");
    let t0 = unix_ms() + START_MS;
    let mut nodes = camera_nodes(&t, &c, port, |cam| sim(cam, Some(t0)), &["--zenoh-ball"]);
    let log = end_run(
        &mut nodes,
        &mut fusion,
        Duration::from_millis(START_MS + 20_000),
    );
    assert!(log.contains("events: 1 goal(s), score 1:0"), "{log}");

    // The same frames in one process.
    let reference = t.join("reference_events.jsonl");
    run_ok(&[
        "track",
        "--calib",
        &c,
        "--input",
        &sim(0, None),
        "--input",
        &sim(1, None),
        "--out",
        &t.join("reference.csv").display().to_string(),
        "--events-out",
        &reference.display().to_string(),
    ]);
    let (got, want) = (read_lines(&events), read_lines(&reference));
    assert!(
        want.iter().any(|l| l.contains("\"event\":\"goal\"")),
        "the scenario's goal: {want:?}"
    );
    assert!(
        want.iter().any(|l| l.contains("\"event\":\"shot\"")),
        "the scenario's shot: {want:?}"
    );
    assert_eq!(
        got, want,
        "the fusion node's events differ from the in-process session's\n{log}"
    );
    // Each event on the network as its line of the file, in order.
    std::thread::sleep(Duration::from_millis(200));
    assert_eq!(*seen.lock().unwrap(), want, "events on fused/events");
    session.close().wait().unwrap();

    // The fusion node's recording, replayed: the events go out again on fused/events.
    let port = free_port();
    let session = test_session("listen", port);
    let replayed = collect_text(&session, "rodtrack/default/fused/events");
    let out = std::process::Command::new(zenoh_common::BIN)
        .arg("replay")
        .arg(&mcap)
        .args([
            "--publish",
            "zenoh",
            "--speed",
            "4",
            "--start-delay-s",
            "1.5",
        ])
        .args(["--zenoh-connect", &format!("tcp/127.0.0.1:{port}")])
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        stdout.contains(&format!(", {} events)", want.len())),
        "{stdout}"
    );
    std::thread::sleep(Duration::from_millis(200));
    assert_eq!(*replayed.lock().unwrap(), want, "replayed events");
    session.close().wait().unwrap();
}

#[test]
fn a_camera_node_alone_publishes_its_cameras_events() {
    let (t, c) = goals_table("zenoh_events_camera");
    let port = free_port();
    // A control program listens; the camera node connects to it.
    let session = test_session("listen", port);
    let seen = collect_text(&session, "rodtrack/default/cam/cam1/events");
    let events = t.join("events.jsonl");
    // One node renders its frames before the trigger: half the two nodes' time.
    let t0 = unix_ms() + START_MS / 2;
    let mut node = Proc::start(
        &[
            "track",
            "--calib",
            &c,
            "--camera",
            "cam1",
            "--input",
            &sim(1, Some(t0)),
            "--publish",
            "zenoh",
            "--zenoh-connect",
            &format!("tcp/127.0.0.1:{port}"),
            "--zenoh-events",
            "--events-out",
            &events.display().to_string(),
        ]
        .map(String::from),
        t.join("cam1.err"),
    );
    node.wait(Duration::from_millis(START_MS / 2 + 20_000));
    let want = read_lines(&events);
    // The scenario's shot (rod 3, frame 62) and goal (frame 93, for side a), from camera 1 alone.
    assert!(
        want.iter()
            .any(|l| l.contains("\"event\":\"shot\"") && l.contains("\"rod\":3")),
        "{want:?}"
    );
    assert!(
        want.iter()
            .any(|l| l.contains("\"event\":\"goal\"") && l.contains("\"score\":[1,0]")),
        "{want:?}"
    );
    std::thread::sleep(Duration::from_millis(200));
    assert_eq!(*seen.lock().unwrap(), want, "events on cam/cam1/events");
    session.close().wait().unwrap();
}

#[test]
fn the_events_need_a_ball_and_their_rules_need_the_events() {
    let t = dir("zenoh_events_bad");
    let calib = zenoh_common::calibration(&t);
    let c = calib.display().to_string();
    let out = std::process::Command::new(zenoh_common::BIN)
        .args(["fuse", "--calib", &c, "--subscribe", "zenoh", "--out"])
        .arg(t.join("f.csv"))
        .args(["--goal-width-mm", "180"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("--zenoh-events"),
        "{err}"
    );
    // The calibration without its ball (each `[cameras.ball]` table taken out).
    let mut kept = Vec::new();
    let mut in_ball = false;
    let text = std::fs::read_to_string(&calib).unwrap();
    for line in text.lines() {
        if line.starts_with('[') {
            in_ball = line.trim() == "[cameras.ball]";
        }
        if !in_ball {
            kept.push(line);
        }
    }
    let no_ball = t.join("no_ball.toml");
    std::fs::write(&no_ball, kept.join("\n")).unwrap();
    let out = std::process::Command::new(zenoh_common::BIN)
        .args(["fuse", "--calib"])
        .arg(&no_ball)
        .args(["--subscribe", "zenoh", "--out"])
        .arg(t.join("f.csv"))
        .arg("--events-out")
        .arg(t.join("e.jsonl"))
        .args(["--zenoh-listen", &format!("tcp/127.0.0.1:{}", free_port())])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("need the ball") && err.contains("no_ball.toml"),
        "{err}"
    );
}
