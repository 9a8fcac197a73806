//! The web console fed from a camera network (feature `zenoh`): two camera nodes on `sim://`
//! sources (the `ball` scenario) with preview frames and their ball rows, a fusion node and
//! `rodtrack console --subscribe zenoh`, each
//! its own `rodtrack` process (the fusion node's events come from the test's own session) on explicit `tcp/127.0.0.1` endpoints with multicast scouting
//! off; the test reads the console's live view (its WebSocket) as the page does.
#![cfg(feature = "zenoh")]
#![allow(missing_docs, clippy::unwrap_used, clippy::expect_used)]

use rodtrack_zenoh::zenoh::{self, Wait};
use serde_json::Value;
use std::collections::{BTreeMap, BTreeSet};
use std::time::{Duration, Instant};

mod zenoh_common;
use zenoh_common::{calibration, dir, free_port, unix_ms, Proc};
/// Frames prerendered by each camera node.
const PRERENDER: u32 = 20;
/// From the nodes' start to the shared trigger's frame 0 (a loaded 2-core machine).
const START_MS: u64 = 6000;
/// Frames each camera node tracks (200 fps: 6 s, time for several statuses while running).
const FRAMES: u64 = 1200;
/// The simulated cameras' frames, px, and the preview's (at most 360 px across, Bayer blocks
/// of 4x4).
const SOURCE_PX: (u64, u64) = (1440, 1080);
const PREVIEW_PX: (u64, u64) = (360, 270);

fn strings(a: &[&str]) -> Vec<String> {
    a.iter().map(|s| s.to_string()).collect()
}

/// What the live view showed.
#[derive(Default)]
struct Seen {
    /// Row cameras (-1: fused).
    row_cameras: BTreeSet<i64>,
    /// Per camera, the last binary frame's header and its pixels.
    frames: BTreeMap<u64, (Value, Vec<u8>)>,
    /// The last `remote` of a `stats` message.
    remote: Value,
    /// The last `ball` message, and how many came with the ball seen (`ok`).
    ball: Value,
    balls_ok: u64,
    /// The last `events` of a `stats` message (score and last events).
    events: Value,
}

impl Seen {
    fn take(&mut self, msg: tungstenite::Message) {
        match msg {
            tungstenite::Message::Text(t) => {
                let v: Value = serde_json::from_str(t.as_str()).unwrap();
                match v["t"].as_str() {
                    Some("rows") => {
                        for r in v["rows"].as_array().unwrap() {
                            self.row_cameras.insert(r[1].as_i64().unwrap());
                        }
                    }
                    Some("stats") => {
                        self.remote = v["remote"].clone();
                        self.events = v["events"].clone();
                    }
                    Some("ball") => {
                        self.balls_ok += u64::from(v["status"] == "ok");
                        self.ball = v;
                    }
                    _ => {}
                }
            }
            tungstenite::Message::Binary(b) => {
                let n = u32::from_le_bytes(b[..4].try_into().unwrap()) as usize;
                let header: Value = serde_json::from_slice(&b[4..4 + n]).unwrap();
                let cam = header["camera"].as_u64().unwrap();
                self.frames.insert(cam, (header, b[4 + n..].to_vec()));
            }
            _ => {}
        }
    }

    fn node(&self, name: &str) -> Option<&Value> {
        self.remote["nodes"]
            .as_array()?
            .iter()
            .find(|n| n["node"] == name)
    }

    /// Rows of both cameras and fused rows, both cameras' previews, every node's status with
    /// frames going through.
    fn running(&self) -> bool {
        let cams_running = ["cam/cam0", "cam/cam1"].iter().all(|n| {
            self.node(n).is_some_and(|v| {
                v["status"]["state"] == "running" && v["status"]["frames"].as_u64() > Some(0)
            })
        });
        let fused = self.node("fused").is_some_and(|v| {
            v["status"]["sets_complete"].as_u64() > Some(0)
                && v["status"]["cameras"]
                    .as_array()
                    .is_some_and(|c| c.len() == 2 && c.iter().all(|c| c["state"] == "ok"))
        });
        self.row_cameras.is_superset(&BTreeSet::from([-1, 0, 1]))
            && self.frames.len() == 2
            && self.balls_ok >= 3
            && cams_running
            && fused
    }
}

#[test]
fn the_console_shows_the_networks_rows_statuses_and_previews() {
    let t = dir("zenoh_console");
    let calib = calibration(&t);
    let c = calib.display().to_string();
    let (zc, zf, http) = (free_port(), free_port(), free_port());
    let (zc_ep, zf_ep) = (format!("tcp/127.0.0.1:{zc}"), format!("tcp/127.0.0.1:{zf}"));
    let addr = format!("127.0.0.1:{http}");
    // The console listens; the fusion node and the camera nodes connect to it.
    let mut console = Proc::start(
        &strings(&[
            "console",
            "--subscribe",
            "zenoh",
            "--addr",
            &addr,
            "--zenoh-listen",
            &zc_ep,
            "--seconds",
            "120",
        ]),
        t.join("console.err"),
    );
    let out = t.join("fused.csv").display().to_string();
    let mut fusion = Proc::start(
        &strings(&[
            "fuse",
            "--calib",
            &c,
            "--subscribe",
            "zenoh",
            "--publish",
            "zenoh",
            "--out",
            &out,
            "--zenoh-listen",
            &zf_ep,
            "--zenoh-connect",
            &zc_ep,
            "--loss-frames",
            "40",
        ]),
        t.join("fuse.err"),
    );
    let t0 = unix_ms() + START_MS;
    let mut nodes: Vec<Proc> = (0..2)
        .map(|cam| {
            let input = format!(
                "sim://ball?camera={cam}&frames={PRERENDER}&loop=1&prerender={PRERENDER}&realtime=1&trigger_unix_ms={t0}"
            );
            Proc::start(
                &strings(&[
                    "track", "--calib", &c, "--camera", &format!("cam{cam}"), "--input", &input,
                    "--publish", "zenoh", "--zenoh-ball", "--zenoh-connect", &zf_ep, "--zenoh-connect", &zc_ep,
                    "--preview-fps", "4", "--max-frames", &FRAMES.to_string(),
                ]),
                t.join(format!("cam{cam}.err")),
            )
        })
        .collect();

    // The live view, as the page opens it.
    let until = Instant::now() + Duration::from_secs(20);
    let stream = loop {
        match std::net::TcpStream::connect(&addr) {
            Ok(s) => break s,
            Err(e) if Instant::now() < until && !console.ended() => {
                let _ = e;
                std::thread::sleep(Duration::from_millis(50));
            }
            Err(e) => panic!("no console on {addr}: {e}\n{}", console.log()),
        }
    };
    stream
        .set_read_timeout(Some(Duration::from_millis(200)))
        .unwrap();
    let (mut ws, _) =
        tungstenite::client::client(format!("ws://{addr}/ws").as_str(), stream).unwrap();
    let mut seen = Seen::default();
    let mut read_until = |seen: &mut Seen, limit: Duration, done: &dyn Fn(&Seen) -> bool| {
        let until = Instant::now() + limit;
        while !done(seen) && Instant::now() < until {
            match ws.read() {
                Ok(m) => seen.take(m),
                Err(tungstenite::Error::Io(e))
                    if matches!(
                        e.kind(),
                        std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                    ) => {}
                Err(e) => panic!("live view: {e}"),
            }
        }
        done(seen)
    };
    let ok = read_until(
        &mut seen,
        Duration::from_millis(START_MS + 20_000),
        &Seen::running,
    );
    assert!(
        ok,
        "row cameras {:?}, previews of cameras {:?}, remote {}\nconsole:\n{}\nfuse:\n{}\ncam0:\n{}",
        seen.row_cameras,
        seen.frames.keys().collect::<Vec<_>>(),
        seen.remote,
        console.log(),
        fusion.log(),
        nodes[0].log()
    );
    // Each camera's preview: the camera's image downscaled, in colour, with real content.
    for cam in 0..2u64 {
        let (h, pixels) = &seen.frames[&cam];
        assert_eq!(
            (h["pw"].as_u64(), h["ph"].as_u64()),
            (Some(PREVIEW_PX.0), Some(PREVIEW_PX.1)),
            "{h}"
        );
        assert_eq!(
            (h["width"].as_u64(), h["height"].as_u64()),
            (Some(SOURCE_PX.0), Some(SOURCE_PX.1)),
            "{h}"
        );
        assert_eq!(h["channels"], 3, "{h}");
        assert_eq!(pixels.len() as u64, PREVIEW_PX.0 * PREVIEW_PX.1 * 3);
        let (lo, hi) = (pixels.iter().min().unwrap(), pixels.iter().max().unwrap());
        assert!(hi - lo > 50, "camera {cam}'s preview is flat: {lo}..{hi}");
        let p = seen.remote["previews"]
            .as_array()
            .unwrap()
            .iter()
            .find(|p| p["camera"] == cam)
            .unwrap();
        assert_eq!(
            (
                p["width"].as_u64(),
                p["height"].as_u64(),
                p["source_width"].as_u64()
            ),
            (Some(PREVIEW_PX.0), Some(PREVIEW_PX.1), Some(SOURCE_PX.0)),
            "{p}"
        );
    }
    assert_eq!(seen.remote["malformed"], 0, "{}", seen.remote);
    // The ball: the fusion node's fused row (not a camera node's), on the reference field,
    // with its trail.
    let b = &seen.ball;
    assert_eq!(b["camera"], "fused", "{b}");
    assert_eq!(b["field_mm"], serde_json::json!([1200.0, 680.0]), "{b}");
    let (x, y) = (b["x_mm"].as_f64().unwrap(), b["y_mm"].as_f64().unwrap());
    assert!(x.abs() < 600.0 && y.abs() < 340.0, "{b}");
    assert!(b["trail"].as_array().is_some_and(|t| t.len() > 1), "{b}");

    // The camera nodes end: their last status says so, and they turn silent.
    for n in &mut nodes {
        let until = Instant::now() + Duration::from_secs(30);
        while !n.ended() {
            assert!(
                Instant::now() < until,
                "a camera node did not end:\n{}",
                n.log()
            );
            std::thread::sleep(Duration::from_millis(50));
        }
    }
    let silent = |s: &Seen| {
        ["cam/cam0", "cam/cam1"].iter().all(|n| {
            s.node(n)
                .is_some_and(|v| v["status"]["state"] == "ended" && v["silent"] == true)
        })
    };
    assert!(
        read_until(&mut seen, Duration::from_secs(15), &silent),
        "camera nodes not shown as ended and silent: {}",
        seen.remote
    );
    let fused = seen.node("fused").unwrap();
    assert_eq!(fused["silent"], false, "{fused}");

    // Malformed messages: counted, shown and printed with their key expression; the console
    // goes on.
    let session = connect(&zc_ep);
    let bad_preview = "rodtrack/default/cam/cam0/preview";
    session
        .put(bad_preview, &b"RTZP\x02\x00"[..])
        .wait()
        .unwrap();
    session
        .put("rodtrack/default/fused/status", "not json")
        .wait()
        .unwrap();
    // A camera node's ball message that holds a fused row.
    let mut fused_row = Vec::new();
    let row = rodtrack_core::ball::BallRow::lost(
        1,
        rodtrack_core::Timestamp(5_000_000),
        rodtrack_core::CameraId::Fused,
    );
    rodtrack_zenoh::ball_layout::encode_ball(0, &[row], &[], &mut Vec::new(), &mut fused_row)
        .unwrap();
    session
        .put("rodtrack/default/cam/cam1/ball", fused_row)
        .wait()
        .unwrap();
    // The fusion node's events (this scenario scores no goal: the test's session sends one as
    // `fuse --zenoh-events` does), and one that is not an event.
    let goal =
        r#"{"frame":93,"timestamp_s":0.465000,"event":"goal","side":"b","goal":"a","score":[0,1]}"#;
    session
        .put("rodtrack/default/fused/events", goal)
        .wait()
        .unwrap();
    session
        .put("rodtrack/default/fused/events", r#"{"frame":94}"#)
        .wait()
        .unwrap();
    let four =
        |s: &Seen| s.remote["malformed"] == 4 && s.events["score"] == serde_json::json!([0, 1]);
    assert!(
        read_until(&mut seen, Duration::from_secs(10), &four),
        "malformed messages and the event not shown: {} {}",
        seen.remote,
        seen.events
    );
    assert_eq!(seen.events["last"][0]["event"], "goal", "{}", seen.events);
    let errors = seen.remote["first_errors"].to_string();
    assert!(
        errors.contains(&format!("{bad_preview}: bad message: preview of 6 bytes"))
            && errors.contains("rodtrack/default/fused/status: bad message: status JSON")
            && errors
                .contains("cam/cam1/ball: bad message: ball rows that are not the camera node's")
            && errors.contains("rodtrack/default/fused/events: bad message: event:"),
        "{errors}"
    );
    session.close().wait().unwrap();
    read_until(&mut seen, Duration::from_millis(600), &|_| false);
    assert!(seen.node("fused").is_some_and(|v| v["silent"] == false));

    fusion.interrupt(Duration::from_secs(10));
    let log = console.interrupt(Duration::from_secs(10));
    assert!(
        log.contains(&format!(
            "malformed message on {bad_preview}: bad message: preview of 6 bytes"
        )),
        "{log}"
    );
    assert!(log.contains("4 malformed message(s) received"), "{log}");
}

/// A zenoh session of the test's own, connected to `endpoint` (scouting off), once the peer
/// is there and has told it its subscribers.
fn connect(endpoint: &str) -> zenoh::Session {
    let mut config = zenoh::Config::default();
    config
        .insert_json5("connect/endpoints", &format!("[\"{endpoint}\"]"))
        .unwrap();
    config
        .insert_json5("scouting/multicast/enabled", "false")
        .unwrap();
    let session = zenoh::open(config).wait().unwrap();
    let until = Instant::now() + Duration::from_secs(10);
    while session.info().peers_zid().wait().count() == 0 {
        assert!(Instant::now() < until, "no zenoh peer at {endpoint}");
        std::thread::sleep(Duration::from_millis(20));
    }
    std::thread::sleep(Duration::from_millis(500));
    session
}
