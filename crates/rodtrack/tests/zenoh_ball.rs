//! The ball on the camera network (feature `zenoh`): two camera nodes with `--zenoh-ball` on
//! `sim://ball` sources and a fusion node with `--ball-out`, each its own `rodtrack` process on
//! loopback; the fused ball rows must be those of one in-process session on the same frames,
//! and go out for ROS 2 over rmw_zenoh as the fused rows say.
#![cfg(feature = "zenoh")]
#![allow(missing_docs, clippy::unwrap_used, clippy::expect_used)]

use rodtrack_io::mcap::StampedXyz;
use rodtrack_zenoh::ball_layout::decode_ball;
use rodtrack_zenoh::ros2::{Ros2Names, ATTACHMENT_LEN, POINT_STAMPED, VECTOR3_STAMPED};
use rodtrack_zenoh::zenoh::Wait;
use std::collections::BTreeSet;
use std::path::Path;
use std::sync::{Arc, Mutex};
use std::time::Duration;

mod zenoh_common;
use zenoh_common::{
    calibration, camera_nodes, dir, end_run, free_port, run_ok, test_session, unix_ms, Proc,
};

/// Frames prerendered by each node.
const PRERENDER: u32 = 40;
/// From the nodes' start to the shared trigger's frame 0.
const START_MS: u64 = 8000;

/// The ROS 2 messages received on a topic: (sequence number, message).
type Ros2Seen = Arc<Mutex<Vec<(i64, StampedXyz)>>>;

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
            "--ros2-domain",
            "3",
        ]
        .map(String::from),
        t.join("fuse.err"),
    );
    // A subscriber of the test's own on the fused ball key: one message per frame.
    let session = test_session("connect", port);
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
    // As an rmw_zenoh subscription of the ball's two topics: (sequence number, message).
    let names = Ros2Names::fused(3, "default").unwrap();
    let ros2: [Ros2Seen; 2] = Default::default();
    for (topic, ty, sink) in [
        (names.ball_topic(), POINT_STAMPED, ros2[0].clone()),
        (
            names.ball_velocity_topic(),
            VECTOR3_STAMPED,
            ros2[1].clone(),
        ),
    ] {
        session
            .declare_subscriber(names.keyexpr_of(&topic, ty))
            .callback(move |sample| {
                let a = sample.attachment().unwrap().to_bytes();
                assert_eq!(a.len(), ATTACHMENT_LEN);
                let seq = i64::from_le_bytes(a[..8].try_into().unwrap());
                let m = StampedXyz::from_cdr(&sample.payload().to_bytes()).unwrap();
                sink.lock().unwrap().push((seq, m));
            })
            .background()
            .wait()
            .unwrap();
    }
    let t0 = unix_ms() + START_MS;
    let frames = FRAMES.to_string();
    let mut nodes = camera_nodes(
        &t,
        &c,
        port,
        |cam| sim(cam, Some(t0)),
        &["--zenoh-ball", "--max-frames", &frames],
    );
    let log = end_run(
        &mut nodes,
        &mut fusion,
        Duration::from_millis(START_MS + 20_000),
    );
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
    check_ros2(&ros2, &ball, &calib);
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

/// Each fused ball row with a place (`ok`, `predicted`) went out once for ROS 2, in order:
/// its centre in m at the ball's height, its velocity in m/s, stamped with its capture time, in
/// the table frame; the sequence numbers go up by one from 1 on each topic.
fn check_ros2(ros2: &[Ros2Seen; 2], ball_csv: &Path, calib: &Path) {
    let toml = std::fs::read_to_string(calib).unwrap();
    let diameter_mm: f64 = toml
        .lines()
        .find_map(|l| l.strip_prefix("diameter_mm = "))
        .expect("the calibration's ball diameter")
        .parse()
        .unwrap();
    // frame,timestamp_s,camera,x_mm,y_mm,vx_mm_s,vy_mm_s,quality,status
    let placed: Vec<Vec<f64>> = std::fs::read_to_string(ball_csv)
        .unwrap()
        .lines()
        .map(|l| l.split(',').collect::<Vec<_>>())
        .filter(|c| c[2] == "fused" && (c[8] == "ok" || c[8] == "predicted"))
        .map(|c| c[1..7].iter().filter_map(|v| v.parse().ok()).collect())
        .collect();
    assert!(
        placed.len() > 100,
        "{} fused rows with a place",
        placed.len()
    );
    for (k, (what, unit)) in [("place", 1e-3), ("velocity", 1e-3)]
        .into_iter()
        .enumerate()
    {
        let got = ros2[k].lock().unwrap();
        assert_eq!(got.len(), placed.len(), "ROS 2 {what} messages");
        for (i, ((seq, m), row)) in got.iter().zip(&placed).enumerate() {
            assert_eq!(*seq, i as i64 + 1, "{what}: sequence numbers from 1");
            assert_eq!(m.frame_id, "rodtrack/default");
            let stamp_s = f64::from(m.stamp_sec) + f64::from(m.stamp_nanosec) * 1e-9;
            assert!(
                (stamp_s - row[0]).abs() < 1e-6,
                "{what} {i}: stamp {stamp_s} s, row {row:?}"
            );
            // The CSV's digits: 0.001 mm for the place, 0.1 mm/s for the velocity.
            let (xy, tol, z) = if k == 0 {
                ([row[1], row[2]], 0.0005 + 1e-9, diameter_mm / 2.0 * unit)
            } else {
                ([row[3], row[4]], 0.05 + 1e-9, 0.0)
            };
            for (j, v) in xy.iter().enumerate() {
                assert!(
                    (m.xyz[j] / unit - v).abs() <= tol,
                    "{what} {i}: {:?} m, row {row:?}",
                    m.xyz
                );
            }
            assert_eq!(m.xyz[2], z, "{what} {i}");
        }
    }
}
