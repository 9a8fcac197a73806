//! Event sinks: where the ball's [`BallEvent`]s go (JSON Lines file, memory), and the JSON
//! Lines reader (for truth files and scoring).

use super::csv::TextOut;
use crate::IoError;
use rodtrack_core::ball::events::{BallEvent, EventKind, Side};
use rodtrack_core::Timestamp;
use std::fs::File;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

/// Where events go.
pub trait EventSink: Send {
    /// Writes events (in the order they were decided).
    fn write(&mut self, events: &[BallEvent]) -> Result<(), IoError>;
    /// Pushes buffered events to their destination.
    fn flush(&mut self) -> Result<(), IoError>;
}

/// Events as JSON Lines: one [`BallEvent::json_line`] per line. Each `write` is flushed to the
/// writer: a crash loses nothing already written.
///
/// ```
/// use rodtrack_core::ball::events::{BallEvent, EventKind};
/// use rodtrack_io::{EventJsonlSink, EventSink};
/// let mut sink = EventJsonlSink::new(Vec::new(), "events.jsonl");
/// let e = BallEvent {
///     frame: 3,
///     timestamp_ns: rodtrack_core::Timestamp(15_000_000),
///     kind: EventKind::BallStopped { x_mm: 10.0, y_mm: -5.0 },
/// };
/// sink.write(&[e])?;
/// let text = String::from_utf8(sink.into_inner()?).unwrap();
/// assert_eq!(
///     text,
///     "{\"frame\":3,\"timestamp_s\":0.015000,\"event\":\"ball_stopped\",\"x_mm\":10.0,\"y_mm\":-5.0}\n"
/// );
/// # Ok::<(), rodtrack_io::IoError>(())
/// ```
pub struct EventJsonlSink<W: Write + Send> {
    out: TextOut<W>,
    line: String,
}

impl EventJsonlSink<File> {
    /// Creates (truncates) a JSON Lines file.
    pub fn create(path: &Path) -> Result<Self, IoError> {
        let f = File::create(path).map_err(|e| IoError::file(path, "cannot create", e))?;
        Ok(EventJsonlSink::new(f, path))
    }
}

impl<W: Write + Send> EventJsonlSink<W> {
    /// JSON Lines into `writer`; `name` names it in errors.
    pub fn new(writer: W, name: impl Into<PathBuf>) -> Self {
        EventJsonlSink {
            out: TextOut::new(writer, name.into()),
            line: String::with_capacity(1024),
        }
    }

    /// Flushes and returns the writer.
    pub fn into_inner(self) -> Result<W, IoError> {
        self.out.into_inner()
    }
}

impl<W: Write + Send> EventSink for EventJsonlSink<W> {
    fn write(&mut self, events: &[BallEvent]) -> Result<(), IoError> {
        if events.is_empty() {
            return Ok(());
        }
        self.line.clear();
        for e in events {
            e.push_json(&mut self.line);
            self.line.push('\n');
        }
        self.out.write_all(self.line.as_bytes())?;
        self.out.flush()
    }
    fn flush(&mut self) -> Result<(), IoError> {
        self.out.flush()
    }
}

/// Events kept in memory, shared with its clones (give one to a session, read the other).
#[derive(Debug, Clone, Default)]
pub struct EventVecSink {
    events: Arc<Mutex<Vec<BallEvent>>>,
}

impl EventVecSink {
    /// A copy of the events written so far.
    pub fn events(&self) -> Vec<BallEvent> {
        self.events.lock().map(|e| e.clone()).unwrap_or_default()
    }
}

impl EventSink for EventVecSink {
    fn write(&mut self, events: &[BallEvent]) -> Result<(), IoError> {
        if let Ok(mut v) = self.events.lock() {
            v.extend_from_slice(events);
        }
        Ok(())
    }
    fn flush(&mut self) -> Result<(), IoError> {
        Ok(())
    }
}

impl<S: EventSink + ?Sized> EventSink for Box<S> {
    fn write(&mut self, events: &[BallEvent]) -> Result<(), IoError> {
        (**self).write(events)
    }
    fn flush(&mut self) -> Result<(), IoError> {
        (**self).flush()
    }
}

/// Parses one line of an events file ([`BallEvent::push_json`]'s fields); `path` and `line`
/// (from 1) name it in errors.
///
/// ```
/// use rodtrack_core::ball::events::{EventKind, Side};
/// let line = r#"{"frame":412,"timestamp_s":2.06,"event":"goal","side":"a","goal":"b","score":[1,0]}"#;
/// let e = rodtrack_io::parse_event_json(line, "events.jsonl".as_ref(), 1)?;
/// assert_eq!(e.frame, 412);
/// assert_eq!(e.kind, EventKind::Goal { side: Side::A, goal: Side::B, score: [1, 0] });
/// # Ok::<(), rodtrack_io::IoError>(())
/// ```
pub fn parse_event_json(text: &str, path: &Path, line: usize) -> Result<BallEvent, IoError> {
    let err = |column: &str, reason: String| IoError::Parse {
        path: path.to_path_buf(),
        line,
        column: column.to_string(),
        reason,
    };
    let v: serde_json::Value =
        serde_json::from_str(text).map_err(|e| err("(line)", format!("not JSON: {e}")))?;
    let num = |k: &str| -> Result<f64, IoError> {
        v.get(k)
            .and_then(|x| x.as_f64())
            .filter(|x| x.is_finite())
            .ok_or_else(|| err(k, "missing or not a finite number".into()))
    };
    let side = |k: &str| -> Result<Side, IoError> {
        match v.get(k).and_then(|x| x.as_str()) {
            Some("a") => Ok(Side::A),
            Some("b") => Ok(Side::B),
            other => Err(err(k, format!("expected \"a\" or \"b\", got {other:?}"))),
        }
    };
    let frame = v
        .get("frame")
        .and_then(|x| x.as_u64())
        .ok_or_else(|| err("frame", "missing or not a whole number".into()))?;
    let t = num("timestamp_s")?;
    let timestamp_ns = Timestamp::try_from_secs_f64(t)
        .ok_or_else(|| err("timestamp_s", format!("out of range: {t}")))?;
    let kind = match v.get("event").and_then(|x| x.as_str()) {
        Some("goal") => {
            let score = v
                .get("score")
                .and_then(|s| s.as_array())
                .filter(|s| s.len() == 2)
                .and_then(|s| {
                    let a = u32::try_from(s[0].as_u64()?).ok()?;
                    let b = u32::try_from(s[1].as_u64()?).ok()?;
                    Some([a, b])
                })
                .ok_or_else(|| err("score", "expected [a, b], two whole numbers".into()))?;
            EventKind::Goal {
                side: side("side")?,
                goal: side("goal")?,
                score,
            }
        }
        Some("shot") => {
            let rod = match v.get("rod") {
                None | Some(serde_json::Value::Null) => None,
                Some(r) => Some(
                    r.as_u64()
                        .and_then(|r| u32::try_from(r).ok())
                        .ok_or_else(|| err("rod", "expected a rod index or null".into()))?,
                ),
            };
            EventKind::Shot {
                speed_mm_s: num("speed_mm_s")?,
                rod,
                x_mm: num("x_mm")?,
                y_mm: num("y_mm")?,
            }
        }
        Some("ball_out") => EventKind::BallOut {
            x_mm: num("x_mm")?,
            y_mm: num("y_mm")?,
        },
        Some("ball_stopped") => EventKind::BallStopped {
            x_mm: num("x_mm")?,
            y_mm: num("y_mm")?,
        },
        other => {
            return Err(err(
                "event",
                format!("expected goal, shot, ball_out or ball_stopped, got {other:?}"),
            ))
        }
    };
    Ok(BallEvent {
        frame,
        timestamp_ns,
        kind,
    })
}

/// Reads an events file (JSON Lines, blank lines skipped).
pub fn read_events_jsonl(path: &Path) -> Result<Vec<BallEvent>, IoError> {
    let text = std::fs::read_to_string(path).map_err(|e| IoError::file(path, "cannot read", e))?;
    text.lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty())
        .map(|(i, l)| parse_event_json(l, path, i + 1))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every kind written and read back is the same event (the numbers to their printed
    /// precision).
    #[test]
    fn events_round_trip_through_json_lines() {
        let kinds = [
            EventKind::Goal {
                side: Side::B,
                goal: Side::A,
                score: [2, 3],
            },
            EventKind::Shot {
                speed_mm_s: 4500.5,
                rod: Some(6),
                x_mm: 300.5,
                y_mm: -20.0,
            },
            EventKind::Shot {
                speed_mm_s: 1500.0,
                rod: None,
                x_mm: 0.0,
                y_mm: 0.0,
            },
            EventKind::BallOut {
                x_mm: 10.0,
                y_mm: 345.5,
            },
            EventKind::BallStopped {
                x_mm: -1.5,
                y_mm: 2.5,
            },
        ];
        let events: Vec<BallEvent> = kinds
            .iter()
            .enumerate()
            .map(|(i, k)| BallEvent {
                frame: 10 * i as u64,
                timestamp_ns: Timestamp(50_000_000 * i as u64),
                kind: *k,
            })
            .collect();
        let mut sink = EventJsonlSink::new(Vec::new(), "e.jsonl");
        sink.write(&events).unwrap();
        let text = String::from_utf8(sink.into_inner().unwrap()).unwrap();
        let back: Vec<BallEvent> = text
            .lines()
            .enumerate()
            .map(|(i, l)| parse_event_json(l, "e.jsonl".as_ref(), i + 1).unwrap())
            .collect();
        assert_eq!(back, events);
        let bad = parse_event_json(
            r#"{"frame":1,"timestamp_s":0,"event":"goal","side":"c","goal":"a","score":[1,0]}"#,
            "e.jsonl".as_ref(),
            4,
        )
        .unwrap_err();
        assert!(
            bad.to_string().contains("e.jsonl") && bad.to_string().contains("side"),
            "{bad}"
        );
    }
}
