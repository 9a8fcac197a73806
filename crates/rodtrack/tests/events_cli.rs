//! `track --events-out` from the command line: scenario `goals` simulated (its calibration
//! inputs and truth events), both cameras calibrated, the first second tracked from `sim://`
//! sources; the events file against the truth's, the same events in the UDP stream and in the
//! MCAP recording, `score
//! --events-truth`; bad arguments.
#![allow(missing_docs, clippy::unwrap_used)]

mod common;

use common::rodtrack;
use rodtrack_core::ball::events::EventKind;
use std::path::Path;

#[test]
fn track_writes_the_events_of_the_first_second_as_the_truth_has_them() {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("events_cli");
    let _ = std::fs::remove_dir_all(&dir);
    let rec = dir.join("rec");
    // Only frame 0's images (the calibration's), the truth events of the whole timeline.
    let o = rodtrack(&[
        "simulate",
        "--scenario",
        "goals",
        "--seed",
        "3",
        "--every",
        "100000",
        "--out",
        rec.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let cal = dir.join("cal.toml");
    let o = rodtrack(&[
        "calibrate",
        "--inputs",
        rec.join("cam0.json").to_str().unwrap(),
        "--inputs",
        rec.join("cam1.json").to_str().unwrap(),
        "--out",
        cal.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let events = dir.join("events.jsonl");
    let rows = dir.join("rows.csv");
    let ball = dir.join("ball.jsonl");
    let mcap = dir.join("run.mcap");
    // The UDP stream: rows' datagrams (`RTRK`) and the events' (`RTEV`), read as they come.
    let rx = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    rx.set_read_timeout(Some(std::time::Duration::from_millis(200)))
        .unwrap();
    let udp = rx.local_addr().unwrap().to_string();
    let done = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let receiver = {
        let done = done.clone();
        std::thread::spawn(move || {
            let (mut rows, mut packets, mut balls) = (0usize, Vec::new(), Vec::new());
            let mut buf = vec![0u8; 65_536];
            loop {
                match rx.recv(&mut buf) {
                    Ok(n) if buf[..4] == *b"RTEV" => {
                        packets.push(rodtrack_io::decode_udp_events(&buf[..n]).unwrap())
                    }
                    Ok(n) if buf[..4] == *b"RTBL" => {
                        balls.extend(rodtrack_io::decode_udp_ball(&buf[..n]).unwrap().rows)
                    }
                    Ok(n) => {
                        rodtrack_io::decode_udp_packet(&buf[..n]).unwrap();
                        rows += 1;
                    }
                    Err(_) if done.load(std::sync::atomic::Ordering::Relaxed) => break,
                    Err(_) => {}
                }
            }
            (rows, packets, balls)
        })
    };
    let o = rodtrack(&[
        "track",
        "--calib",
        cal.to_str().unwrap(),
        "--input",
        "sim://goals?camera=0&seed=3&frames=200",
        "--input",
        "sim://goals?camera=1&seed=3&frames=200",
        "--out",
        rows.to_str().unwrap(),
        "--events-out",
        events.to_str().unwrap(),
        "--ball-out",
        ball.to_str().unwrap(),
        "--udp",
        &udp,
        "--mcap",
        mcap.to_str().unwrap(),
    ]);
    done.store(true, std::sync::atomic::Ordering::Relaxed);
    let (udp_rows, udp_events, udp_balls) = receiver.join().unwrap();
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(stdout.contains("1 goal(s), score 1:0"), "{stdout}");
    // The ball's rows as JSON Lines (`.jsonl`): two cameras and the fused row per frame, the
    // CSV's fields.
    let text = std::fs::read_to_string(&ball).unwrap();
    let lines: Vec<serde_json::Value> = text
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(lines.len(), 3 * 200, "ball rows");
    let fields = [
        "frame",
        "timestamp_s",
        "camera",
        "x_mm",
        "y_mm",
        "vx_mm_s",
        "vy_mm_s",
        "quality",
        "status",
    ];
    for v in &lines {
        let o = v.as_object().unwrap();
        assert_eq!(o.len(), fields.len(), "{v}");
        assert!(fields.iter().all(|f| o.contains_key(*f)), "{v}");
    }
    assert!(lines
        .iter()
        .any(|v| v["camera"] == "fused" && v["status"] == "ok"));
    assert!(lines
        .iter()
        .any(|v| v["camera"] == 1 && v["status"] == "ok"));
    // The same ball rows in the UDP stream (datagrams `RTBL`), field by field as the file
    // has them (its 3 decimals).
    assert_eq!(udp_balls.len(), lines.len(), "ball rows in the UDP stream");
    for (u, v) in udp_balls.iter().zip(&lines) {
        let camera = match u.camera {
            rodtrack_core::CameraId::Camera(c) => serde_json::json!(c),
            rodtrack_core::CameraId::Fused => serde_json::json!("fused"),
        };
        assert_eq!(
            (serde_json::json!(u.frame), camera),
            (v["frame"].clone(), v["camera"].clone())
        );
        assert_eq!(serde_json::json!(u.status), v["status"], "{u:?} {v}");
        for (got, field) in [(u.x_mm, "x_mm"), (u.y_mm, "y_mm"), (u.vx_mm_s, "vx_mm_s")] {
            let want = v[field].as_f64().unwrap();
            assert!(
                (got - want).abs() <= 0.051,
                "{field}: {got} against {want} ({v})"
            );
        }
    }
    // The same events in the recording, each message its line of the file, logged at its
    // frame's capture time, on the fusion node's key.
    let file = rodtrack_io::mcap::read_mcap(&mcap).unwrap();
    let channel = file
        .channels
        .values()
        .find(|c| file.schemas[&c.schema_id].name == rodtrack_io::mcap::EVENT_SCHEMA_NAME)
        .expect("an events channel");
    assert_eq!(channel.topic, "/rodtrack/default/fused/events");
    let recorded: Vec<(String, u64)> = file
        .messages
        .iter()
        .filter(|m| m.channel == channel.id)
        .map(|m| (String::from_utf8(m.data.clone()).unwrap(), m.log_time_ns))
        .collect();
    let lines: Vec<String> = std::fs::read_to_string(&events)
        .unwrap()
        .lines()
        .map(String::from)
        .collect();
    assert_eq!(
        recorded.iter().map(|r| r.0.clone()).collect::<Vec<_>>(),
        lines
    );
    for (text, log_time_ns) in &recorded {
        let e = rodtrack_io::mcap::parse_event_message(text.as_bytes()).unwrap();
        assert_eq!(e.timestamp_ns.as_nanos(), *log_time_ns, "{text}");
    }
    let truth = rodtrack_io::read_events_jsonl(&rec.join("events_truth.jsonl")).unwrap();
    let found = rodtrack_io::read_events_jsonl(&events).unwrap();
    // The same events in the UDP stream, beside the rows, with the running score.
    assert!(udp_rows >= 200, "row datagrams: {udp_rows}");
    let streamed: Vec<_> = udp_events.iter().flat_map(|p| p.events.clone()).collect();
    assert_eq!(streamed.len(), found.len(), "{udp_events:?}");
    for (u, f) in streamed.iter().zip(&found) {
        assert_eq!(
            (u.frame, u.timestamp_ns, u.kind.name()),
            (f.frame, f.timestamp_ns, f.kind.name())
        );
    }
    assert_eq!(udp_events.last().map(|p| p.score), Some([1, 0]));
    let early: Vec<_> = truth.iter().filter(|e| e.frame < 200).collect();
    // The first play: a shot by rod 3, a goal for side A at the crossing's frame.
    assert_eq!(early.len(), 2, "{early:?}");
    assert_eq!(found.len(), 2, "{found:?}");
    for (t, f) in early.iter().zip(&found) {
        assert_eq!(t.kind.name(), f.kind.name());
        assert!(t.frame.abs_diff(f.frame) <= 2, "{t:?} vs {f:?}");
        match (t.kind, f.kind) {
            (EventKind::Shot { rod: a, .. }, EventKind::Shot { rod: b, .. }) => assert_eq!(a, b),
            (EventKind::Goal { score: a, .. }, EventKind::Goal { score: b, .. }) => {
                assert_eq!(a, b)
            }
            other => panic!("{other:?}"),
        }
    }
    let o = rodtrack(&[
        "score",
        "--events-truth",
        rec.join("events_truth.jsonl").to_str().unwrap(),
        "--events",
        events.to_str().unwrap(),
    ]);
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(stdout.contains("final score (a:b): 1:0 found"), "{stdout}");
    // The rules checked before any frame is read; the events need --events-out.
    let bad = rodtrack(&[
        "track",
        "--calib",
        cal.to_str().unwrap(),
        "--input",
        "sim://goals?camera=0&seed=3&frames=2",
        "--input",
        "sim://goals?camera=1&seed=3&frames=2",
        "--out",
        rows.to_str().unwrap(),
        "--events-out",
        events.to_str().unwrap(),
        "--goal-width-mm",
        "700",
    ]);
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(
        !bad.status.success() && err.contains("goal_width_mm"),
        "{err}"
    );
    let bad = rodtrack(&[
        "track",
        "--calib",
        cal.to_str().unwrap(),
        "--input",
        "sim://goals?camera=0&seed=3&frames=2",
        "--input",
        "sim://goals?camera=1&seed=3&frames=2",
        "--out",
        rows.to_str().unwrap(),
        "--goal-width-mm",
        "200",
    ]);
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(
        !bad.status.success() && err.contains("--events-out"),
        "{err}"
    );
}

/// `bench-latency --ball` runs the ball tracker in the live path: it reports the ball rows it
/// wrote, most of them `ok` (the `ball` scenario: one ball rolling in view of both cameras),
/// and judges the latency against the ball's target.
#[test]
fn bench_latency_measures_the_live_path_with_the_ball() {
    let o = rodtrack(&[
        "bench-latency",
        "--scenario",
        "ball",
        "--frames",
        "60",
        "--prerender",
        "60",
        "--runs",
        "1",
        "--noise-samples",
        "0",
        "--ball",
    ]);
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success(),
        "{out}{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let line = out
        .lines()
        .find(|l| l.contains("ball rows"))
        .unwrap_or_else(|| panic!("no ball rows reported: {out}"));
    let ok: u64 = line
        .split(": ")
        .nth(1)
        .and_then(|t| t.split(" ok").next())
        .and_then(|n| n.trim().parse().ok())
        .unwrap_or_else(|| panic!("unreadable: {line}"));
    // 60 frame sets: 2 camera rows and a fused row each.
    assert!(ok >= 150, "{line}");
    assert!(out.contains("target p99 <= 300 us"), "{out}");
}
