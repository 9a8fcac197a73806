//! The ball's events on the page: the running score and the last events, published by the
//! tracking side's event sink ([`crate::ConsoleHandle::publish_events`]) and sent with the
//! status (`/api/status`, the live view's `stats` messages: key `events`).
//!
//! Events are rare (a few per second at most), decided on the ball writer's thread, not per
//! camera frame: a plain lock, which the console holds only to copy the last few.

use rodtrack_core::ball::events::{BallEvent, EventKind};

/// The last events kept for the page.
pub(crate) const LAST_EVENTS: usize = 8;

/// The score and the last events.
#[derive(Debug, Clone, Default)]
pub(crate) struct EventBoard {
    score: [u32; 2],
    /// Events published so far.
    count: u64,
    /// The last [`LAST_EVENTS`], oldest first once full (a ring at `count % LAST_EVENTS`).
    last: [Option<BallEvent>; LAST_EVENTS],
}

impl EventBoard {
    /// Takes events in the order they were decided; a goal's score is the running score.
    pub(crate) fn push(&mut self, events: &[BallEvent]) {
        for e in events {
            if let EventKind::Goal { score, .. } = e.kind {
                self.score = score;
            }
            self.last[(self.count % LAST_EVENTS as u64) as usize] = Some(*e);
            self.count += 1;
        }
    }

    /// `{"score": [a, b], "count": n, "last": [event, ...]}`, the last events oldest first,
    /// each as in `--events-out` (docs/formats.md).
    pub(crate) fn json(&self) -> serde_json::Value {
        let n = self.count.min(LAST_EVENTS as u64);
        let last: Vec<serde_json::Value> = (0..n)
            .filter_map(|k| {
                let i = ((self.count - n + k) % LAST_EVENTS as u64) as usize;
                self.last[i].as_ref()
            })
            .filter_map(|e| serde_json::from_str(&e.json_line()).ok())
            .collect();
        serde_json::json!({ "score": self.score, "count": self.count, "last": last })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rodtrack_core::ball::events::Side;
    use rodtrack_core::Timestamp;

    /// The score follows the goals; the last 8 events are kept, oldest first.
    #[test]
    fn the_board_keeps_the_score_and_the_last_events() {
        let mut b = EventBoard::default();
        let stop = |frame| BallEvent {
            frame,
            timestamp_ns: Timestamp(frame * 5_000_000),
            kind: EventKind::BallStopped {
                x_mm: 1.0,
                y_mm: 2.0,
            },
        };
        let goal = BallEvent {
            frame: 3,
            timestamp_ns: Timestamp(15_000_000),
            kind: EventKind::Goal {
                side: Side::B,
                goal: Side::A,
                score: [0, 1],
            },
        };
        b.push(&[stop(1), goal]);
        let j = b.json();
        assert_eq!(j["score"], serde_json::json!([0, 1]));
        assert_eq!(j["last"][1]["event"], "goal");
        let more: Vec<BallEvent> = (10..20).map(stop).collect();
        b.push(&more);
        let j = b.json();
        assert_eq!(j["count"], 12);
        let frames: Vec<u64> = j["last"]
            .as_array()
            .unwrap()
            .iter()
            .map(|e| e["frame"].as_u64().unwrap())
            .collect();
        assert_eq!(frames, (12..20).collect::<Vec<u64>>());
        assert_eq!(j["score"], serde_json::json!([0, 1]));
    }
}
