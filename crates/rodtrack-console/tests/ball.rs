//! The ball on the console: the status carries its last row and trail (checked over HTTP,
//! always), and the page draws it on a top view of the field with its speed (in a real
//! browser: headless chromium, skipped with a message when it is absent, unless
//! `RODTRACK_REQUIRE_BROWSER=1`).
#![allow(clippy::unwrap_used)]

mod common;

use common::{chromium, get_json, Browser};
use rodtrack_console::Console;
use rodtrack_core::ball::{BallRow, BallStatus};
use rodtrack_core::{CameraId, Timestamp};
use std::time::Duration;

/// Frame set `f` of a ball rolling along `x` at 1.5 m/s from -300 mm: camera 0's row and the
/// fused one (10 mm further, to tell them apart).
fn frame_set(f: u64) -> [BallRow; 2] {
    let x_mm = -300.0 + 7.5 * f as f64;
    let row = |camera, x_mm| BallRow {
        frame: f,
        timestamp_ns: Timestamp(f * 5_000_000),
        camera,
        x_mm,
        y_mm: 40.0,
        vx_mm_s: 1500.0,
        vy_mm_s: 0.0,
        quality: 0.9,
        status: BallStatus::Ok,
    };
    [
        row(CameraId::Camera(0), x_mm),
        row(CameraId::Fused, x_mm + 10.0),
    ]
}

#[test]
fn the_status_carries_the_balls_last_row_and_trail() {
    let console = Console::start("127.0.0.1:0".parse().unwrap(), None).unwrap();
    assert!(get_json(console.addr(), "/api/status")["ball"].is_null());
    console.set_ball_field(1100.0, 600.0);
    for f in 0..80 {
        console.publish_ball(&frame_set(f));
    }
    let b = &get_json(console.addr(), "/api/status")["ball"];
    assert_eq!(b["camera"], "fused");
    assert_eq!(b["frame"], 79);
    assert_eq!(b["status"], "ok");
    assert_eq!(b["field_mm"], serde_json::json!([1100.0, 600.0]));
    assert!((b["x_mm"].as_f64().unwrap() - (-300.0 + 7.5 * 79.0 + 10.0)).abs() < 1e-9);
    assert!((b["speed_mm_s"].as_f64().unwrap() - 1500.0).abs() < 1e-9);
    // 80 frame sets thinned to at most 50 points, the newest last.
    let trail = b["trail"].as_array().unwrap();
    assert_eq!(trail.len(), 40);
    assert_eq!(trail.last().unwrap(), &serde_json::json!([b["x_mm"], 40.0]));
    console.shutdown();
}

#[test]
fn the_page_draws_the_ball_its_trail_and_speed() {
    let Some(exe) = chromium() else { return };
    let console = Console::start("127.0.0.1:0".parse().unwrap(), None).unwrap();
    let mut b = Browser::start(&exe);
    b.open(&console.url());
    b.wait_for("window.rodtrack !== undefined", Duration::from_secs(30));
    assert_eq!(
        b.eval("document.getElementById('ball').textContent")
            .as_str(),
        Some("not tracked")
    );
    for f in 0..120 {
        console.publish_ball(&frame_set(f));
    }
    // The live view sends the ball each tick (25 per second) when a frame set came.
    b.wait_for(
        "window.rodtrack.ball !== undefined && window.rodtrack.ball.frame === 119",
        Duration::from_secs(30),
    );
    let text = b
        .eval("document.getElementById('ball').textContent")
        .as_str()
        .unwrap_or("")
        .to_string();
    assert_eq!(text, "1.50 m/s at (603, 40) mm ok", "{text}");
    let drawn = b.eval("document.getElementById('field').dataset.trail");
    assert_eq!(drawn.as_str(), Some("40"), "trail points drawn");
    // The ball is drawn where the table frame puts it: x = 602.5 mm on a 1200 mm field is
    // near the right end (goal B), y = 40 mm just above the middle.
    let lit = b.eval(
        "(() => { const cv = document.getElementById('field'); const g = cv.getContext('2d');\
          const k = Math.min((cv.width - 16) / 1200, (cv.height - 16) / 680);\
          const x = Math.round(cv.width / 2 + 602.5 * k), y = Math.round(cv.height / 2 - 40 * k);\
          const p = g.getImageData(x, y, 1, 1).data; return p[0] > 200 && p[1] > 120; })()",
    );
    assert_eq!(lit.as_bool(), Some(true), "the ball's colour at its place");
    drop(b);
    console.shutdown();
}
