//! `rodtrack replay FILE.mcap --publish zenoh` (feature `zenoh`): a `track --mcap`
//! recording played back in real time, received in this process by a zenoh subscriber on an
//! explicit `tcp/127.0.0.1` endpoint with multicast scouting off, and compared row by row with
//! the recording.
#![cfg(feature = "zenoh")]
#![allow(missing_docs, clippy::unwrap_used, clippy::expect_used)]

mod common;

use common::rodtrack;
use rodtrack_core::{CameraId, Measurement};
use rodtrack_io::mcap::{parse_rows_message, read_mcap};
use rodtrack_zenoh::layout::{decode, Kind};
use rodtrack_zenoh::net::NetworkOptions;
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

#[test]
fn a_recording_is_replayed_in_real_time_on_the_nodes_keys() {
    let (dir, calib) = common::two_cameras("zenoh_replay", 60);
    let mcap = dir.join("run.mcap");
    let rec = dir.join("rec");
    let o = rodtrack(&[
        "track",
        "--calib",
        calib.to_str().unwrap(),
        "--input",
        rec.join("cam0").to_str().unwrap(),
        "--input",
        rec.join("cam1").to_str().unwrap(),
        "--mcap",
        mcap.to_str().unwrap(),
        "--table",
        "bench",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));

    // What the recording holds, per key.
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
    let keys: Vec<&str> = recorded.keys().map(String::as_str).collect();
    assert_eq!(
        keys,
        [
            "rodtrack/bench/cam/cam0/rows",
            "rodtrack/bench/cam/cam1/rows",
            "rodtrack/bench/fused/rows"
        ]
    );
    let span_s = (t1 - t0) as f64 * 1e-9;
    assert!(span_s > 0.25, "60 frames at 200 fps: {span_s} s");

    // The subscriber listens; the replay connects to it.
    let port = free_port();
    let net = NetworkOptions {
        listen: vec![format!("tcp/127.0.0.1:{port}")],
        ..NetworkOptions::default()
    };
    let session = net.open().unwrap();
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
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
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
