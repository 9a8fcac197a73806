//! The ball's events in recordings: [`McapRecorder::event_sink`] records each event (goal,
//! shot, ball out, ball stopped) as one `rodtrack.Event` JSON message ([`EVENT_SCHEMA`]) on
//! `/rodtrack/<table>/fused/events`, the key the camera network's fusion node publishes them
//! on; the message is the event's line of `--events-out` (docs/formats.md), its log time the
//! event's frame's capture time. [`parse_event_message`] reads one back.
//!
//! The messages are in the order the events were decided: a goal is decided after its grace
//! time, so its log time is earlier than the rows recorded before it. A ROS 2 bag holds no
//! events (no standard ROS message fits them).

use super::record::{McapRecorder, Profile, Topic};
use crate::{EventSink, IoError};
use rodtrack_core::ball::events::BallEvent;
use std::path::Path;

/// The event messages' schema name.
pub const EVENT_SCHEMA_NAME: &str = "rodtrack.Event";

/// The JSON schema of an event message (`rodtrack.Event`).
pub const EVENT_SCHEMA: &str = r#"{
  "title": "rodtrack.Event",
  "description": "One of the ball's events, as a line of `rodtrack track --events-out` (docs/formats.md); positions in the table frame, mm.",
  "type": "object",
  "properties": {
    "frame": {"type": "integer", "minimum": 0, "description": "The frame of the event (a goal's: the frame the ball crossed the goal line)"},
    "timestamp_s": {"type": "number", "description": "Its capture time, s (the message's log time in ns)"},
    "event": {"type": "string", "enum": ["goal", "shot", "ball_out", "ball_stopped"]},
    "side": {"type": "string", "enum": ["a", "b"], "description": "goal: the side that scored"},
    "goal": {"type": "string", "enum": ["a", "b"], "description": "goal: the goal the ball went into"},
    "score": {"type": "array", "items": {"type": "integer", "minimum": 0}, "minItems": 2, "maxItems": 2, "description": "goal: the running score, [side a, side b]"},
    "speed_mm_s": {"type": "number", "description": "shot: the ball's speed after the kick, mm/s"},
    "rod": {"type": ["integer", "null"], "description": "shot: the rod that kicked (null: not known)"},
    "x_mm": {"type": "number", "description": "shot, ball_out, ball_stopped: where, mm"},
    "y_mm": {"type": "number", "description": "shot, ball_out, ball_stopped: where, mm"}
  },
  "required": ["frame", "timestamp_s", "event"]
}"#;

impl McapRecorder {
    /// An event sink whose events are recorded (none in a ROS 2 bag).
    pub fn event_sink(&self) -> McapEventSink {
        McapEventSink {
            recorder: self.clone(),
            line: String::with_capacity(256),
        }
    }
}

/// Records the events written to it (see [`McapRecorder::event_sink`]).
pub struct McapEventSink {
    recorder: McapRecorder,
    /// One event's JSON, kept for its capacity.
    line: String,
}

impl EventSink for McapEventSink {
    fn write(&mut self, events: &[BallEvent]) -> Result<(), IoError> {
        let mut inner = self.recorder.lock();
        if inner.options.profile == Profile::Ros2 {
            return Ok(());
        }
        for e in events {
            self.line.clear();
            e.push_json(&mut self.line);
            inner.message(
                Topic::Events,
                e.timestamp_ns.as_nanos(),
                self.line.as_bytes(),
            )?;
        }
        Ok(())
    }
    fn flush(&mut self) -> Result<(), IoError> {
        Ok(())
    }
}

/// Parses a `rodtrack.Event` message.
pub fn parse_event_message(data: &[u8]) -> Result<BallEvent, String> {
    let text = std::str::from_utf8(data).map_err(|_| "an event that is not UTF-8".to_string())?;
    crate::parse_event_json(text, Path::new("event message"), 1).map_err(|e| e.to_string())
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use rodtrack_core::ball::events::{EventKind, Side};
    use rodtrack_core::Timestamp;

    #[test]
    fn an_event_message_reads_back_and_a_bad_one_is_refused() {
        let e = BallEvent {
            frame: 93,
            timestamp_ns: Timestamp(465_000_000),
            kind: EventKind::Goal {
                side: Side::A,
                goal: Side::B,
                score: [1, 0],
            },
        };
        let back = parse_event_message(e.json_line().as_bytes()).unwrap();
        assert_eq!(back.json_line(), e.json_line());
        assert!(parse_event_message(b"{\"frame\":1}").is_err());
        assert!(parse_event_message(&[0xff]).unwrap_err().contains("UTF-8"));
        let schema: serde_json::Value = serde_json::from_str(EVENT_SCHEMA).unwrap();
        assert_eq!(schema["title"], EVENT_SCHEMA_NAME);
    }
}
