//! The ball on the camera network (feature `zenoh`): two camera nodes with `--zenoh-ball` on
//! `sim://ball` sources and a fusion node with `--ball-out`, each its own `rodtrack` process on
//! loopback; the fused ball rows must be those of one in-process session on the same frames.
#![cfg(feature = "zenoh")]
#![allow(missing_docs, clippy::unwrap_used, clippy::expect_used)]

use rodtrack_zenoh::ball_layout::decode_ball;
use rodtrack_zenoh::zenoh::{self, Wait};
use std::collections::BTreeSet;
use std::path::Path;
use std::sync::{Arc, Mutex};
use std::time::Duration;

mod zenoh_common;
use zenoh_common::{calibration, dir, free_port, run_ok, unix_ms, Proc};

/// Frames prerendered by each node.
const PRERENDER: u32 = 40;
/// From the nodes' start to the shared trigger's frame 0.
const START_MS: u64 = 8000;

fn sim(cam: u32, t0: Option<u64>) -> String {
    let base = format!("sim://ball?camera={cam}&frames={PRERENDER}&loop=1&prerender={PRERENDER}");
    match t0 {
        Some(t) => format!("{base}&realtime=1&trigger_unix_ms={t}"),
        None => base,
    }
}

fn lines(path: &Path) -> BTreeSet<String> {
    std::fs::read_to_string(path)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .lines()
        .skip(1)
        .map(String::from)
        .collect()
}

#[test]
fn ball_rows_cross_the_network_and_fuse_as_in_process() {
    const FRAMES: u64 = 300;
    let t = dir("zenoh_ball");
    let calib = calibration(&t);
    let c = calib.display().to_string();
    let port = free_port();
    let (fused, ball) = (t.join("fused.csv"), t.join("ball.csv"));
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
            &fused.display().to_string(),
            "--ball-out",
            &ball.display().to_string(),
            "--zenoh-listen",
            &format!("tcp/127.0.0.1:{port}"),
            // No fault here: a camera late by a few frames on a loaded machine is waited for.
            "--loss-frames",
            "40",
        ]
        .map(String::from),
        t.join("fuse.err"),
    );
    // A subscriber of the test's own on the fused ball key: one message per frame.
    let mut config = zenoh::Config::default();
    config
        .insert_json5("connect/endpoints", &format!("[\"tcp/127.0.0.1:{port}\"]"))
        .unwrap();
    config
        .insert_json5("scouting/multicast/enabled", "false")
        .unwrap();
    let session = zenoh::open(config).wait().unwrap();
    let seen: Arc<Mutex<Vec<(u64, usize)>>> = Arc::default();
    let s = seen.clone();
    session
        .declare_subscriber("rodtrack/default/fused/ball")
        .callback(move |sample| {
            let m = decode_ball(&sample.payload().to_bytes()).unwrap();
            let frame = m.rows[0].0.frame;
            assert!(m.rows.iter().all(|r| r.0.frame == frame));
            s.lock().unwrap().push((frame, m.rows.len()));
        })
        .background()
        .wait()
        .unwrap();
    let t0 = unix_ms() + START_MS;
    let mut nodes: Vec<Proc> = (0..2u32)
        .map(|cam| {
            Proc::start(
                &[
                    "track",
                    "--calib",
                    &c,
                    "--camera",
                    &format!("cam{cam}"),
                    "--input",
                    &sim(cam, Some(t0)),
                    "--publish",
                    "zenoh",
                    "--zenoh-ball",
                    "--zenoh-connect",
                    &format!("tcp/127.0.0.1:{port}"),
                    "--max-frames",
                    &FRAMES.to_string(),
                ]
                .map(String::from),
                t.join(format!("cam{cam}.err")),
            )
        })
        .collect();
    for n in &mut nodes {
        n.wait(Duration::from_millis(START_MS + 20_000));
    }
    std::thread::sleep(Duration::from_millis(500));
    let log = fusion.interrupt(Duration::from_secs(10));
    assert!(log.contains("ball rows:"), "{log}");

    // The same frames in one process.
    let reference = t.join("reference_ball.csv");
    run_ok(&[
        "track",
        "--calib",
        &c,
        "--input",
        &sim(0, None),
        "--input",
        &sim(1, None),
        "--max-frames",
        &FRAMES.to_string(),
        "--out",
        &t.join("reference.csv").display().to_string(),
        "--ball-out",
        &reference.display().to_string(),
    ]);
    let (got, want) = (lines(&ball), lines(&reference));
    assert_eq!(
        want.len() as u64,
        3 * FRAMES,
        "2 cameras and fused per frame"
    );
    let ok = want.iter().filter(|l| l.ends_with(",ok")).count();
    assert!(ok as u64 > FRAMES, "the ball is seen: {ok} rows ok");
    let missing: Vec<_> = want.difference(&got).take(5).collect();
    let extra: Vec<_> = got.difference(&want).take(5).collect();
    assert!(
        got == want,
        "the network's ball rows differ from the in-process session's: missing {missing:?}, extra {extra:?}\n{log}"
    );
    let seen = seen.lock().unwrap();
    let frames: BTreeSet<u64> = seen.iter().map(|s| s.0).collect();
    assert_eq!(
        frames.len() as u64,
        FRAMES,
        "a fused ball message per frame"
    );
    assert!(
        seen.iter().all(|s| s.1 == 3),
        "both cameras and the fused row in each"
    );
}
