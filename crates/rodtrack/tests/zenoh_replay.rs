//! `rodtrack replay FILE.mcap --publish zenoh` (feature `zenoh`): a `track --mcap`
//! recording played back in real time, received in this process by a zenoh subscriber on an
//! explicit `tcp/127.0.0.1` endpoint with multicast scouting off, and compared row by row with
//! the recording; and the same replay's fused rows published for ROS 2 over rmw_zenoh
//! (`--ros2-domain`), read as rmw_zenoh's subscribers and graph read them.
#![cfg(feature = "zenoh")]
#![allow(missing_docs, clippy::unwrap_used, clippy::expect_used)]

mod common;

use rodtrack_core::Status;
use rodtrack_core::{CameraId, Measurement};
use rodtrack_io::mcap::{parse_rows_message, read_mcap, JointState};
use rodtrack_zenoh::layout::{decode, Kind};
use rodtrack_zenoh::net::NetworkOptions;
use rodtrack_zenoh::ros2::{gid_of, Ros2Names, ATTACHMENT_LEN};
use rodtrack_zenoh::zenoh::Wait;
use std::collections::BTreeMap;
use std::process::{Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

/// A `track --mcap` recording of 60 frames of two cameras (table `bench`), and its rows per
/// key with the span of their log times (s).
fn record(name: &str) -> (std::path::PathBuf, BTreeMap<String, Vec<Measurement>>, f64) {
    let (dir, calib) = common::two_cameras(name, 60);
    let mcap = dir.join("run.mcap");
    let o = common::track_two_cameras(
        &dir,
        &calib,
        &["--mcap", mcap.to_str().unwrap(), "--table", "bench"],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let file = read_mcap(&mcap).unwrap();
    let mut recorded: BTreeMap<String, Vec<Measurement>> = BTreeMap::new();
    let (mut t0, mut t1) = (u64::MAX, 0);
    for m in &file.messages {
        let topic = &file.channels[&m.channel].topic;
        if topic.ends_with("/rows") {
            let rows = parse_rows_message(&m.data).unwrap().rows;
            recorded
                .entry(topic.trim_start_matches('/').to_string())
                .or_default()
                .extend(rows);
            t0 = t0.min(m.log_time_ns);
            t1 = t1.max(m.log_time_ns);
        }
    }
    (mcap, recorded, (t1 - t0) as f64 * 1e-9)
}

/// Runs `rodtrack replay MCAP --publish zenoh` connecting to `port`, with `extra` options,
/// to its end (60 s at most); its standard output.
fn replay_to(mcap: &std::path::Path, port: u16, extra: &[&str]) -> String {
    let mut child = Command::new(common::BIN)
        .args([
            "replay",
            mcap.to_str().unwrap(),
            "--publish",
            "zenoh",
            "--zenoh-connect",
            &format!("tcp/127.0.0.1:{port}"),
            "--start-delay-s",
            "1.5",
        ])
        .args(extra)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let until = Instant::now() + Duration::from_secs(60);
    while child.try_wait().unwrap().is_none() {
        if Instant::now() > until {
            let _ = child.kill();
            panic!("the replay did not end within 60 s");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let out = child.wait_with_output().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// A session listening on a free loopback port.
fn listening() -> (rodtrack_zenoh::zenoh::Session, u16) {
    let port = free_port();
    let net = NetworkOptions {
        listen: vec![format!("tcp/127.0.0.1:{port}")],
        ..NetworkOptions::default()
    };
    (net.open().unwrap(), port)
}

#[test]
fn a_recording_is_replayed_in_real_time_on_the_nodes_keys() {
    let (mcap, recorded, span_s) = record("zenoh_replay");
    let keys: Vec<&str> = recorded.keys().map(String::as_str).collect();
    assert_eq!(
        keys,
        [
            "rodtrack/bench/cam/cam0/rows",
            "rodtrack/bench/cam/cam1/rows",
            "rodtrack/bench/fused/rows"
        ]
    );
    assert!(span_s > 0.25, "60 frames at 200 fps: {span_s} s");

    // The subscriber listens; the replay connects to it.
    let (session, port) = listening();
    type Received = Vec<(String, Vec<u8>, Instant)>;
    let got: Arc<Mutex<Received>> = Arc::default();
    let sink = got.clone();
    let _sub = session
        .declare_subscriber("rodtrack/bench/**")
        .callback(move |s| {
            let bytes = s.payload().to_bytes().to_vec();
            let key = s.key_expr().as_str().to_string();
            sink.lock().unwrap().push((key, bytes, Instant::now()));
        })
        .wait()
        .unwrap();
    let stdout = replay_to(&mcap, port, &[]);
    assert!(stdout.contains("replayed 180 messages"), "{stdout}");
    std::thread::sleep(Duration::from_millis(300));

    // Every row, in order, on its key, with the right kind; paced by the log times.
    let got = got.lock().unwrap();
    let mut received: BTreeMap<String, Vec<Measurement>> = BTreeMap::new();
    for (key, bytes, _) in got.iter() {
        let m = decode(bytes).unwrap();
        let want = if key.ends_with("/fused/rows") {
            Kind::Fused
        } else {
            Kind::CameraRows
        };
        assert_eq!(m.header.kind, want, "{key}");
        if want == Kind::Fused {
            assert!(m.rows.iter().all(|r| r.camera == CameraId::Fused));
        }
        received.entry(key.clone()).or_default().extend(m.rows);
    }
    assert_eq!(received, recorded);
    let first = got.first().unwrap().2;
    let last = got.last().unwrap().2;
    let played_s = (last - first).as_secs_f64();
    assert!(
        played_s > 0.8 * span_s && played_s < span_s + 1.0,
        "played over {played_s} s, recorded over {span_s} s"
    );
}

#[test]
fn a_replay_publishes_the_fused_rods_for_ros2_as_rmw_zenoh_does() {
    let (mcap, recorded, _) = record("zenoh_replay_ros2");
    let fused = &recorded["rodtrack/bench/fused/rows"];
    let names = Ros2Names::fused(7, "bench").unwrap();

    // As an rmw_zenoh subscription: the topic's key, every sample with its attachment.
    let (session, port) = listening();
    type Received = Vec<(Vec<u8>, Option<Vec<u8>>)>;
    let got: Arc<Mutex<Received>> = Arc::default();
    let sink = got.clone();
    let _sub = session
        .declare_subscriber(names.topic_keyexpr())
        .callback(move |s| {
            let att = s.attachment().map(|a| a.to_bytes().to_vec());
            sink.lock()
                .unwrap()
                .push((s.payload().to_bytes().to_vec(), att));
        })
        .wait()
        .unwrap();
    // The ROS graph's view while the replay runs: its liveliness tokens.
    let tokens: Arc<Mutex<Vec<String>>> = Arc::default();
    let seen = tokens.clone();
    let _graph = session
        .liveliness()
        .declare_subscriber("@ros2_lv/7/**")
        .callback(move |s| seen.lock().unwrap().push(s.key_expr().as_str().to_string()))
        .wait()
        .unwrap();
    replay_to(&mcap, port, &["--ros2-domain", "7"]);
    std::thread::sleep(Duration::from_millis(300));

    let tokens = tokens.lock().unwrap().clone();
    let publisher = tokens
        .iter()
        .find(|t| t.split('/').nth(5) == Some("MP"))
        .unwrap_or_else(|| panic!("no publisher token in {tokens:?}"));
    let zid = publisher.split('/').nth(2).unwrap();
    assert_eq!(publisher, &names.publisher_token(zid, 0, 1));
    assert!(tokens.contains(&names.node_token(zid, 0)), "{tokens:?}");
    let gid = gid_of(publisher);

    // One joint state per recorded frame set, in order, with the fused rows' values.
    let got = got.lock().unwrap();
    let frames: Vec<&[Measurement]> = fused.chunk_by(|a, b| a.frame == b.frame).collect();
    assert_eq!(got.len(), frames.len());
    for (k, ((cdr, att), rows)) in got.iter().zip(&frames).enumerate() {
        let att = att
            .as_ref()
            .expect("rmw_zenoh's subscribers drop a sample without attachment");
        assert_eq!(att.len(), ATTACHMENT_LEN);
        assert_eq!(
            i64::from_le_bytes(att[..8].try_into().unwrap()),
            k as i64 + 1
        );
        assert_eq!(att[16], 16);
        assert_eq!(&att[17..], &gid);
        let m = JointState::from_cdr(cdr).unwrap();
        assert_eq!(m.frame_id, "rodtrack/bench");
        assert_eq!(m.stamp_ns(), rows[0].timestamp_ns.as_nanos());
        let valued: Vec<&Measurement> = rows
            .iter()
            .filter(|r| matches!(r.status, Status::Ok | Status::Predicted | Status::Conflict))
            .collect();
        assert_eq!(m.name.len(), 2 * valued.len());
        for (j, r) in valued.iter().enumerate() {
            assert_eq!(m.name[2 * j], format!("rod{}_slide", r.rod));
            assert_eq!(m.name[2 * j + 1], format!("rod{}_turn", r.rod));
            assert!((m.position[2 * j] - r.position_mm * 1e-3).abs() < 1e-12);
            assert!((m.position[2 * j + 1] - r.angle_unwrapped_rad).abs() < 1e-12);
        }
    }
}

#[test]
fn a_recordings_ball_is_replayed_as_the_nodes_publish_it() {
    use rodtrack_io::mcap::StampedXyz;
    use rodtrack_zenoh::ball_layout::decode_ball;
    use rodtrack_zenoh::ros2::POINT_STAMPED;
    let (dir, calib) = common::two_cameras_of("zenoh_replay_ball", "ball", 40);
    let (mcap, ball_csv) = (dir.join("run.mcap"), dir.join("b.csv"));
    let o = common::track_two_cameras(
        &dir,
        &calib,
        &[
            "--ball-out",
            ball_csv.to_str().unwrap(),
            "--mcap",
            mcap.to_str().unwrap(),
            "--table",
            "bench",
        ],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // The CSV's lines per camera (`0`, `1`, `fused`), in frame order.
    let mut want: BTreeMap<String, Vec<String>> = BTreeMap::new();
    for l in std::fs::read_to_string(&ball_csv).unwrap().lines().skip(1) {
        let camera = l.split(',').nth(2).unwrap().to_string();
        want.entry(camera).or_default().push(l.to_string());
    }

    let (session, port) = listening();
    type Got = Arc<Mutex<Vec<(String, Vec<String>)>>>;
    let got: Got = Arc::default();
    let sink = got.clone();
    let _sub = session
        .declare_subscriber("rodtrack/bench/**/ball")
        .callback(move |s| {
            let m = decode_ball(&s.payload().to_bytes()).unwrap();
            let lines = m.rows.iter().map(|r| r.0.csv_line()).collect();
            sink.lock()
                .unwrap()
                .push((s.key_expr().as_str().to_string(), lines));
        })
        .wait()
        .unwrap();
    let names = Ros2Names::fused(6, "bench").unwrap();
    let ros: Arc<Mutex<Vec<StampedXyz>>> = Arc::default();
    let ros_sink = ros.clone();
    let _ros_sub = session
        .declare_subscriber(names.keyexpr_of(&names.ball_topic(), POINT_STAMPED))
        .callback(move |s| {
            let m = StampedXyz::from_cdr(&s.payload().to_bytes()).unwrap();
            ros_sink.lock().unwrap().push(m);
        })
        .wait()
        .unwrap();
    let out = replay_to(&mcap, port, &["--ros2-domain", "6"]);
    // 40 rows of each camera, and 40 fused messages of 3 rows.
    assert!(out.contains("200 ball rows"), "{out}");
    std::thread::sleep(Duration::from_millis(300));

    let got = got.lock().unwrap();
    for k in ["0", "1"] {
        // A camera node's messages: its row of each frame.
        let key = format!("rodtrack/bench/cam/cam{k}/ball");
        let msgs: Vec<&Vec<String>> = got.iter().filter(|g| g.0 == key).map(|g| &g.1).collect();
        assert!(msgs.iter().all(|m| m.len() == 1), "{key}");
        let lines: Vec<String> = msgs.iter().map(|m| m[0].clone()).collect();
        assert_eq!(lines, want[k], "{key}");
    }
    // The fusion node's: each frame's camera rows, then the fused one.
    let fused: Vec<&Vec<String>> = got
        .iter()
        .filter(|g| g.0 == "rodtrack/bench/fused/ball")
        .map(|g| &g.1)
        .collect();
    assert_eq!(fused.len(), 40);
    for (i, m) in fused.iter().enumerate() {
        assert_eq!(
            **m,
            vec![
                want["0"][i].clone(),
                want["1"][i].clone(),
                want["fused"][i].clone()
            ],
            "frame {i}"
        );
    }
    // For ROS 2: the fused rows with a place.
    let placed: Vec<&String> = want["fused"]
        .iter()
        .filter(|l| l.ends_with(",ok") || l.ends_with(",predicted"))
        .collect();
    let ros = ros.lock().unwrap();
    assert_eq!(ros.len(), placed.len());
    for (m, l) in ros.iter().zip(placed) {
        let x_mm: f64 = l.split(',').nth(3).unwrap().parse().unwrap();
        assert!(
            (m.xyz[0] * 1e3 - x_mm).abs() <= 0.0005 + 1e-9,
            "{l}: {:?}",
            m.xyz
        );
        assert_eq!(m.frame_id, "rodtrack/bench");
    }
}
