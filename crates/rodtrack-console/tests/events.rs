//! The ball's events on the console: the status carries the running score and the last events
//! (checked over HTTP, always), and the page shows them (in a real browser: headless chromium,
//! skipped with a message when it is absent, unless `RODTRACK_REQUIRE_BROWSER=1`).
#![allow(clippy::unwrap_used)]

mod common;

use common::{chromium, get_json, Browser};
use rodtrack_console::Console;
use rodtrack_core::ball::events::{BallEvent, EventKind, Side};
use rodtrack_core::Timestamp;
use std::time::Duration;

/// A shot by rod 3, a goal for side A (2:1 after it), a stop.
fn events() -> Vec<BallEvent> {
    let at = |frame: u64, kind| BallEvent {
        frame,
        timestamp_ns: Timestamp(frame * 5_000_000),
        kind,
    };
    vec![
        at(
            400,
            EventKind::Shot {
                speed_mm_s: 4321.0,
                rod: Some(3),
                x_mm: -75.0,
                y_mm: 20.0,
            },
        ),
        at(
            440,
            EventKind::Goal {
                side: Side::A,
                goal: Side::B,
                score: [2, 1],
            },
        ),
        at(
            900,
            EventKind::BallStopped {
                x_mm: 0.0,
                y_mm: 0.0,
            },
        ),
    ]
}

#[test]
fn the_status_carries_the_score_and_the_last_events() {
    let console = Console::start("127.0.0.1:0".parse().unwrap(), None).unwrap();
    let before = get_json(console.addr(), "/api/status");
    assert_eq!(before["events"]["score"], serde_json::json!([0, 0]));
    assert_eq!(before["events"]["count"], 0);
    console.publish_events(&events());
    let s = get_json(console.addr(), "/api/status");
    assert_eq!(s["events"]["score"], serde_json::json!([2, 1]));
    let names: Vec<&str> = s["events"]["last"]
        .as_array()
        .unwrap()
        .iter()
        .map(|e| e["event"].as_str().unwrap())
        .collect();
    assert_eq!(names, ["shot", "goal", "ball_stopped"]);
    assert_eq!(s["events"]["last"][0]["rod"], 3);
    console.shutdown();
}

#[test]
fn the_page_shows_the_score_and_the_last_events() {
    let Some(exe) = chromium() else { return };
    let console = Console::start("127.0.0.1:0".parse().unwrap(), None).unwrap();
    let mut b = Browser::start(&exe);
    b.open(&console.url());
    b.wait_for("window.rodtrack !== undefined", Duration::from_secs(30));
    assert_eq!(
        b.eval("document.getElementById('score').textContent")
            .as_str(),
        Some("0 : 0")
    );
    console.publish_events(&events());
    // The live view's status messages come 4 times a second.
    b.wait_for(
        "document.getElementById('score').textContent === '2 : 1'",
        Duration::from_secs(30),
    );
    let text = b
        .eval("document.getElementById('events').textContent")
        .as_str()
        .unwrap_or("")
        .to_string();
    // Newest first.
    assert_eq!(
        text, "4.50 s ball stopped · 2.20 s goal for A (2 : 1) · 2.00 s shot 4.3 m/s rod 3",
        "{text}"
    );
    drop(b);
    console.shutdown();
}
