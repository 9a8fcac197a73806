//! The turn counts in the live view, and re-anchoring one through the page, on a real
//! tracking session of the simulator: its frames lost for 200 ms make every rod's count
//! unknown (and at 100 fps the filter cannot re-anchor them by itself); the page shows each
//! rod's "turns ?" badge, the user enters a rod and a turn and clicks "Re-anchor", the session
//! applies it on its next frame, and that rod's badge goes while the others stay.
#![allow(clippy::unwrap_used, missing_docs)]

mod common;

use common::{chromium, post_json, Browser};
use rodtrack_console::{Console, ConsoleHandle, SessionCommands};
use rodtrack_core::{CameraPipeline, Measurement, Mode};
use rodtrack_io::source::SourceInfo;
use rodtrack_io::{FrameBuffer, FrameSource, IoError, MeasurementSink, SourceError};
use rodtrack_sdk::{Session, SessionCamera, SessionControl, SessionOptions};
use rodtrack_sim::{
    calibrate_sim_camera, default_cameras, Playback, RenderMode, Scenario, SceneConfig, SimSource,
    Simulation,
};
use serde_json::json;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;

/// Timeline frames the source loses: 200 ms at 200 fps.
const GAP: std::ops::Range<u64> = 40..80;

struct Gap(SimSource);

impl FrameSource for Gap {
    fn info(&self) -> SourceInfo {
        self.0.info()
    }
    fn next_frame(&mut self, buf: &mut FrameBuffer) -> Result<Option<()>, SourceError> {
        loop {
            let r = self.0.next_frame(buf)?;
            if r.is_none() || !GAP.contains(&buf.meta.frame_id) {
                return Ok(r);
            }
        }
    }
}

/// The session's rows to the console's plots, as `rodtrack track --console` sends them, and
/// the last frame written.
struct ToConsole(Arc<ConsoleHandle>, Arc<AtomicU64>);

impl MeasurementSink for ToConsole {
    fn write(&mut self, rows: &[Measurement]) -> Result<(), IoError> {
        self.0.publish_rows(rows);
        if let Some(m) = rows.last() {
            self.1.fetch_max(m.frame, Ordering::SeqCst);
        }
        Ok(())
    }
    fn flush(&mut self) -> Result<(), IoError> {
        Ok(())
    }
}

#[derive(Debug)]
struct Commands(SessionControl);

impl SessionCommands for Commands {
    fn reanchor(&self, camera: Option<u32>, rod: u32, turns: i64) -> Result<(), String> {
        self.0
            .reanchor(camera, rod, turns)
            .map_err(|e| e.to_string())
    }
}

#[test]
fn a_rod_with_an_unknown_turn_count_is_badged_until_reanchored_through_the_page() {
    let scene = SceneConfig::default();
    let sc = Scenario::by_name("static", &scene, 9)
        .unwrap()
        .with_frames(400);
    let mut sim = Simulation::new(scene, default_cameras(), sc, RenderMode::Fast)
        .unwrap()
        .with_seed(9);
    let cal = calibrate_sim_camera(&mut sim, 0, 9).unwrap().calibration;
    let playback = Playback {
        realtime: true,
        looping: true,
        every: 2,
        prerender: 16,
        trigger_unix_ms: None,
    };
    let source = SimSource::for_simulation(&sim, playback).unwrap().remove(0);
    let camera = SessionCamera {
        label: "camera 0".into(),
        source: Box::new(Gap(source)),
        pipe: CameraPipeline::new(&cal, Mode::Enhanced).unwrap(),
    };
    let rods: Vec<u32> = cal.rods.iter().map(|r| r.rod).collect();
    let (target, other) = (rods[1], rods[2]);
    let console = Arc::new(Console::start("127.0.0.1:0".parse().unwrap(), None).unwrap());
    let addr = console.addr();
    // No session attached yet: the console says so.
    let (code, body) = post_json(addr, "/api/reanchor", json!({"rod": target, "turns": 3}));
    assert_eq!(code, 409, "{body}");
    assert!(
        body["error"]
            .as_str()
            .unwrap()
            .contains("no tracking session"),
        "{body}"
    );
    let session = Session::from_cameras(vec![camera], SessionOptions::default());
    console.attach_session(Arc::new(Commands(session.control())));
    let stop = session.stop_flag();
    let last_frame = Arc::new(AtomicU64::new(0));
    let runner = {
        let sink = ToConsole(console.clone(), last_frame.clone());
        std::thread::spawn(move || session.run(sink).map(|(report, _)| report))
    };
    let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        // Bad requests are refused with the field named.
        for (body, field) in [
            (json!({"rod": target, "turns": 1.5}), "turns:"),
            (json!({"rod": target}), "turns:"),
            (json!({"rod": "one", "turns": 1}), "rod:"),
            (json!({"rod": 999, "turns": 1}), "rod:"),
        ] {
            let (code, answer) = post_json(addr, "/api/reanchor", body.clone());
            assert_eq!(code, 400, "{body} -> {answer}");
            let msg = answer["error"].as_str().unwrap();
            assert!(msg.starts_with(field), "{body} -> {msg}");
        }
        let Some(exe) = chromium() else {
            // No browser: let the session run past the gap, so that the report's counts below
            // have something to count.
            let t0 = std::time::Instant::now();
            while last_frame.load(Ordering::SeqCst) < GAP.end + 20
                && t0.elapsed() < Duration::from_secs(60)
            {
                std::thread::sleep(Duration::from_millis(20));
            }
            return;
        };
        let mut b = Browser::start(&exe);
        b.open(&console.url());
        let badge = |rod: u32| {
            format!("!!document.querySelector('#turns .turns.unknown[data-rod=\"{rod}\"]')")
        };
        // After the gap every rod's count is unknown: the badges appear, the control too.
        b.wait_for(
            &format!(
                "{} && {} && !document.getElementById('reanchor').hidden",
                badge(target),
                badge(other)
            ),
            Duration::from_secs(60),
        );
        let before = b.eval(&format!("rodtrack.turnsOf(0, {target})"));
        assert_eq!(before["known"], json!(false), "{before}");
        b.eval(&format!(
            "document.getElementById('ra-rod').value = '{target}'; \
             document.getElementById('ra-turns').value = '3'; true"
        ));
        let r = b.eval(
            "(() => { const r = document.getElementById('ra-go').getBoundingClientRect(); \
             return [r.left + r.width / 2, r.top + r.height / 2]; })()",
        );
        b.click(r[0].as_f64().unwrap(), r[1].as_f64().unwrap());
        b.wait_for(&format!("!{}", badge(target)), Duration::from_secs(20));
        let after = b.eval(&format!("rodtrack.turnsOf(0, {target})"));
        assert_eq!(after["known"], json!(true), "{after}");
        assert_eq!(after["turns"], json!(3), "{after}");
        let msg = b.eval("document.getElementById('ra-msg').textContent");
        assert!(msg.as_str().unwrap().contains("set to 3"), "{msg}");
        // The other rods were not re-anchored: still unknown.
        std::thread::sleep(Duration::from_millis(500));
        assert_eq!(b.eval(&badge(other)), json!(true));
        // A bad entry through the page: the console's message is shown.
        b.eval("document.getElementById('ra-turns').value = ''; document.getElementById('ra-go').click(); true");
        b.wait_for(
            "document.getElementById('ra-msg').textContent.startsWith('turns:')",
            Duration::from_secs(10),
        );
    }));
    stop.store(true, Ordering::SeqCst);
    let report = runner.join().unwrap().unwrap();
    if let Err(e) = result {
        std::panic::resume_unwind(e);
    }
    let h = report.rods.iter().find(|h| h.rod == target).unwrap();
    eprintln!("{}", report.summary());
    if chromium().is_some() {
        assert_eq!(h.turns_set_by_user, 1, "{h:?}");
    }
    assert!(h.turns_lost >= 1, "{h:?}");
}
