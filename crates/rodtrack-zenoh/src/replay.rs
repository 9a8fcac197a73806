//! Replays an MCAP recording's rows (`track --mcap`, `fuse --mcap`) on the network, in real
//! time by their log times (the frames' capture timestamps), on the key expressions the
//! camera nodes and the fusion node use: a camera's rows on `rodtrack/<table>/cam/<camera>/rows`
//! (kind `rows`), the fused rows on `rodtrack/<table>/fused/rows` (kind `fused`), in the
//! node's wire format. The keys are the recording's topics without their leading `/`. A
//! recording's ball rows (`rodtrack.Ball`) go out as the nodes publish them: a camera's row of
//! a frame on `rodtrack/<table>/cam/<camera>/ball`, and on `rodtrack/<table>/fused/ball` the
//! frame's camera rows with the fused one. Its events (`rodtrack.Event`) go out on
//! `rodtrack/<table>/fused/events`, each the JSON the fusion node publishes, in the order they
//! were recorded (decided). With [`ReplayOptions::ros2_domain`] the fused rows,
//! and the fused ball, also go out for ROS 2 over rmw_zenoh, as the fusion node publishes them
//! ([`crate::ros2`]).

use crate::layout::{camera_bit, Kind};
use crate::net::{NetworkOptions, RowPublisher};
use crate::ros2::{Ros2BallPublisher, Ros2Names, Ros2Node, Ros2Publisher};
use crate::ZenohError;
use rodtrack_core::ball::BallRow;
use rodtrack_core::{CameraId, Measurement};
use rodtrack_io::mcap::{
    parse_ball_message, parse_event_message, parse_rows_message, McapFile, BALL_SCHEMA_NAME,
    EVENT_SCHEMA_NAME, ROWS_SCHEMA_NAME,
};
use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// How a recording is replayed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReplayOptions {
    /// Playback speed: 1 is real time, 2 twice as fast.
    pub speed: f64,
    /// The wait after joining the network and before the first message, so that the
    /// subscribers' interest has reached this node (zenoh drops what nobody is known to want).
    pub start_delay: Duration,
    /// Also publish the fused rows for ROS 2 over rmw_zenoh in this domain, as the fusion node
    /// does ([`crate::ros2`]; the table from the fused rows' topic).
    pub ros2_domain: Option<u32>,
}

impl Default for ReplayOptions {
    fn default() -> Self {
        ReplayOptions {
            speed: 1.0,
            start_delay: Duration::from_secs(1),
            ros2_domain: None,
        }
    }
}

/// What a replay published.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ReplayReport {
    /// Messages published.
    pub messages: u64,
    /// Rows in them.
    pub rows: u64,
    /// Ball rows in them (a fused message's camera rows counted again).
    pub ball_rows: u64,
    /// Events in them.
    pub events: u64,
    /// Messages of the recording's rows channels that could not be read (skipped).
    pub skipped: u64,
    /// From the first message to the last, wall time, s.
    pub duration_s: f64,
    /// The recording's span of log times, s.
    pub recorded_s: f64,
}

impl std::fmt::Display for ReplayReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "replayed {} messages ({} rows, {} ball rows, {} events) in {:.3} s (recorded over {:.3} s), {} skipped",
            self.messages, self.rows, self.ball_rows, self.events, self.duration_s, self.recorded_s, self.skipped
        )
    }
}

/// One message to publish.
struct Planned {
    log_time_ns: u64,
    publisher: usize,
    what: Payload,
}

enum Payload {
    Rows(Vec<Measurement>),
    /// Ball rows with their spreads (a fused message: the frame's camera rows, then the fused
    /// one).
    Ball(Vec<BallRow>, Vec<f64>),
    /// An event, as its JSON (checked).
    Event(String),
}

/// A channel replayed: its key and what it carries.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Carries {
    Rows(Kind),
    /// Ball rows; `true` for the fused ones.
    Ball(bool),
    /// The ball's events.
    Events,
}

/// Publishes the rows of `file`; see the module documentation. Stops early when `stop` is
/// set; `warn` gets the messages skipped (the first ten).
pub fn replay(
    file: &McapFile,
    net: &NetworkOptions,
    options: &ReplayOptions,
    stop: &AtomicBool,
    warn: &mut dyn FnMut(&str),
) -> Result<ReplayReport, ZenohError> {
    if !(options.speed.is_finite() && options.speed > 0.0) {
        return Err(ZenohError::Invalid(format!(
            "speed {}: expected a number above 0",
            options.speed
        )));
    }
    // The rows and ball channels: id -> (key, what), and the ball's diameter.
    let mut channels: BTreeMap<u16, (String, Carries)> = BTreeMap::new();
    let mut ball_diameter_mm = None;
    for c in file.channels.values() {
        let key = c.topic.trim_start_matches('/').to_string();
        let carries = match file.schemas.get(&c.schema_id).map(|s| s.name.as_str()) {
            Some(ROWS_SCHEMA_NAME) if key.ends_with("/fused/rows") => Carries::Rows(Kind::Fused),
            Some(ROWS_SCHEMA_NAME) => Carries::Rows(Kind::CameraRows),
            Some(BALL_SCHEMA_NAME) => {
                let d = c.metadata.get("ball_diameter_mm");
                ball_diameter_mm = ball_diameter_mm.or(d.and_then(|d| d.parse::<f64>().ok()));
                Carries::Ball(key.ends_with("/fused/ball"))
            }
            Some(EVENT_SCHEMA_NAME) => Carries::Events,
            _ => continue,
        };
        channels.insert(c.id, (key, carries));
    }
    if !channels.values().any(|c| matches!(c.1, Carries::Rows(_))) {
        return Err(ZenohError::Invalid(format!(
            "the recording has no {ROWS_SCHEMA_NAME} channel: nothing to replay"
        )));
    }
    let mut report = ReplayReport::default();
    let index: BTreeMap<u16, usize> = channels.keys().enumerate().map(|(i, &c)| (c, i)).collect();
    let mut plan = Vec::new();
    let mut cameras = 0u64;
    // The cameras' ball rows of the frame, for its fused message.
    let mut frame_balls: (Vec<BallRow>, Vec<f64>) = Default::default();
    for m in &file.messages {
        let Some(&publisher) = index.get(&m.channel) else {
            continue;
        };
        let parsed = match channels[&m.channel].1 {
            Carries::Rows(_) => parse_rows_message(&m.data).map(|msg| {
                for r in &msg.rows {
                    if let CameraId::Camera(k) = r.camera {
                        cameras |= camera_bit(k);
                    }
                }
                Payload::Rows(msg.rows)
            }),
            Carries::Ball(fused) => parse_ball_message(&m.data).map(|b| {
                let (rows, sigma) = &mut frame_balls;
                if rows.first().is_some_and(|r| r.frame != b.row.frame) {
                    rows.clear();
                    sigma.clear();
                }
                if fused {
                    rows.push(b.row);
                    sigma.push(b.sigma_mm);
                    let (rows, sigma) = std::mem::take(&mut frame_balls);
                    Payload::Ball(rows, sigma)
                } else {
                    rows.push(b.row);
                    sigma.push(b.sigma_mm);
                    Payload::Ball(vec![b.row], vec![b.sigma_mm])
                }
            }),
            Carries::Events => parse_event_message(&m.data).map(|e| Payload::Event(e.json_line())),
        };
        match parsed {
            Ok(what) => {
                plan.push(Planned {
                    log_time_ns: m.log_time_ns,
                    publisher,
                    what,
                });
            }
            Err(e) => {
                report.skipped += 1;
                if report.skipped <= 10 {
                    warn(&format!(
                        "message {} of {}: {e}",
                        m.sequence, channels[&m.channel].0
                    ));
                }
            }
        }
    }
    let session = net.open()?;
    let publishers = channels
        .values()
        .map(|(key, _)| RowPublisher::declare(&session, key.clone(), net.format))
        .collect::<Result<Vec<_>, _>>()?;
    let carries: Vec<Carries> = channels.values().map(|(_, c)| *c).collect();
    let (ros2, ros2_ball) = match options.ros2_domain {
        Some(domain) => {
            let table = channels
                .values()
                .find_map(|(key, _)| {
                    key.strip_prefix("rodtrack/")
                        .and_then(|k| k.strip_suffix("/fused/rows"))
                })
                .ok_or_else(|| {
                    ZenohError::Invalid(
                        "the recording has no fused rows (rodtrack/<table>/fused/rows) to publish for ROS 2".into(),
                    )
                })?;
            let node = Ros2Node::declare(&session, &Ros2Names::fused(domain, table)?)?;
            let joints = Ros2Publisher::declare(&session, &node)?;
            let fused_ball = carries.contains(&Carries::Ball(true));
            let ball = match ball_diameter_mm {
                Some(d) if fused_ball => Some(Ros2BallPublisher::declare(&session, &node, d)?),
                None if fused_ball => {
                    // A recording of another writer: its ball channels do not say the ball's
                    // size, and the centre's height would be a guess.
                    warn("the recording's ball channels have no ball_diameter_mm: the ball is replayed on rodtrack's keys, not for ROS 2");
                    None
                }
                _ => None,
            };
            (Some(joints), ball)
        }
        None => (None, None),
    };
    if !sleep_until(Instant::now() + options.start_delay, stop) {
        return Ok(report);
    }
    let t0 = plan.iter().map(|p| p.log_time_ns).min().unwrap_or(0);
    let t1 = plan.iter().map(|p| p.log_time_ns).max().unwrap_or(0);
    report.recorded_s = (t1 - t0) as f64 * 1e-9;
    let start = Instant::now();
    for p in &plan {
        let offset = (p.log_time_ns - t0) as f64 * 1e-9 / options.speed;
        if !sleep_until(start + Duration::from_secs_f64(offset), stop) {
            break;
        }
        let publisher = &publishers[p.publisher];
        match &p.what {
            Payload::Rows(rows) => {
                // A rows payload comes from a rows channel.
                let Carries::Rows(kind) = carries[p.publisher] else {
                    continue;
                };
                let mask = match (kind, rows.first().map(|r| r.camera)) {
                    (Kind::Fused, _) => cameras,
                    (_, Some(CameraId::Camera(k))) => camera_bit(k),
                    _ => 0,
                };
                publisher.publish_runs(kind, true, mask, rows)?;
                if let (Kind::Fused, Some(r)) = (kind, &ros2) {
                    r.publish_frames(rows)?;
                }
                report.rows += rows.len() as u64;
            }
            Payload::Ball(rows, sigma) => {
                publisher.publish_ball(rows, sigma)?;
                if let Some(r) = &ros2_ball {
                    for row in rows.iter().filter(|r| r.camera == CameraId::Fused) {
                        r.publish(row)?;
                    }
                }
                report.ball_rows += rows.len() as u64;
            }
            Payload::Event(json) => {
                publisher.publish_text(json)?;
                report.events += 1;
            }
        }
        report.messages += 1;
    }
    report.duration_s = start.elapsed().as_secs_f64();
    // Undeclared before the session closes.
    drop(publishers);
    drop((ros2, ros2_ball));
    Ok(report)
}

/// Sleeps until `t` (at once when past), waking every 100 ms to look at `stop`; false when
/// stopped.
fn sleep_until(t: Instant, stop: &AtomicBool) -> bool {
    loop {
        if stop.load(Ordering::Relaxed) {
            return false;
        }
        let now = Instant::now();
        if now >= t {
            return true;
        }
        std::thread::sleep((t - now).min(Duration::from_millis(100)));
    }
}
