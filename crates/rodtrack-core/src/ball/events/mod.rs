//! The ball's events (SPEC section 9, issue 20): `goal`, `shot`, `ball_out`, `ball_stopped`,
//! from one ball row per frame set (the `fused` row, or a single camera's), with no I/O.
//!
//! [`EventDetector::push`] takes the rows in frame order and appends the events it can
//! decide to a caller-owned vector; it allocates nothing per frame. [`EventDetector::finish`]
//! decides what is still open at the end (a goal whose grace time has not run out). The
//! rules, and the constants of [`EventConfig`], are documented in `docs/ball.md`.
//!
//! - **goal**: the ball's centre crosses a goal line (from an `ok` or `predicted` row on the
//!   field to one beyond the line) within the goal mouth (`|y - y_centre|` at the crossing at
//!   most half [`EventConfig::goal_width_mm`]), and no `ok` row puts it back on the field
//!   near that goal ([`EventConfig::return_zone_mm`]) within [`EventConfig::goal_grace_s`].
//!   A crossing only the prediction makes counts when the ball was seen at most
//!   [`EventConfig::goal_unseen_max_s`] before it (a ball held or hidden before the mouth
//!   does not score).
//!   The event's frame is the crossing's; it is written once the grace time has passed. A
//!   goal is counted again only after the ball has been seen on the field.
//! - **shot**: an `ok` row at least [`EventConfig::shot_min_speed_mm_s`] whose speed exceeds
//!   by [`EventConfig::shot_min_jump_mm_s`] the fastest `ok` row of the window before it
//!   (ages [`EventConfig::shot_before_min_s`] to [`EventConfig::shot_before_max_s`]): a
//!   bounce, which only slows the ball, is no shot. At least [`EventConfig::shot_min_rows`]
//!   `ok` rows within [`EventConfig::shot_settle_s`] of the jump are that fast; the speed is
//!   the mean of the rows after the jump's within that time (the filter's velocity restarts
//!   at the jump from the positions before and after the kick); the rod is the one that swung
//!   at the kick within [`EventConfig::rod_swing_reach_mm`] of the ball's last slow position
//!   (the fastest, from the angles given to [`EventDetector::push_rod_angle`]), else the one
//!   whose axis is nearest that position, when within [`EventConfig::rod_reach_mm`] (module
//!   `kicker`).
//! - **ball_out**: an `ok` row more than [`EventConfig::out_margin_mm`] beyond the field's
//!   edge (not within a goal mouth), or the last `ok` row within [`EventConfig::out_edge_mm`]
//!   of the field's edge followed by no `ok` row for [`EventConfig::out_lost_s`] (no goal
//!   pending). Frame: the last row that saw it.
//! - **ball_stopped**: the ball's speed, fitted over the `ok` rows of a short window
//!   ([`EventConfig::stopped_window_s`]), within [`EventConfig::stopped_sigmas`] standard
//!   errors of zero (the positions' noise measured from the same rows) for
//!   [`EventConfig::stopped_min_s`] (module `stop`). Frame: the first still window's mean
//!   time's row.

mod config;
mod geometry;
mod kicker;
mod score;
mod stop;
#[cfg(test)]
mod tests;

pub use config::EventConfig;
pub use geometry::TableGeometry;
pub use score::{final_score, match_events, same_kind, shot_agreement, EventMatch};

use super::{BallRow, BallStatus};
use crate::Timestamp;
use serde::{Deserialize, Serialize};

/// An end of the table: goal A at the table frame's smallest `x`, goal B at its largest. Side
/// A defends goal A and scores in goal B.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Side {
    /// Goal A's end (`x < 0`).
    A,
    /// Goal B's end (`x > 0`).
    B,
}

impl Side {
    /// `a` or `b`.
    pub fn name(self) -> &'static str {
        match self {
            Side::A => "a",
            Side::B => "b",
        }
    }

    /// The other side.
    pub fn other(self) -> Side {
        match self {
            Side::A => Side::B,
            Side::B => Side::A,
        }
    }

    /// 0 for A, 1 for B (the score's order).
    pub fn index(self) -> usize {
        match self {
            Side::A => 0,
            Side::B => 1,
        }
    }
}

/// What happened.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum EventKind {
    /// A goal: `side` scored, the ball went into goal `goal` (the other side's).
    Goal {
        /// The side that scored.
        side: Side,
        /// The goal the ball went into.
        goal: Side,
        /// The score after it, `[side A, side B]`.
        score: [u32; 2],
    },
    /// A kick: the ball's speed jumped.
    Shot {
        /// The speed at the start, mm/s.
        speed_mm_s: f64,
        /// The rod whose axis was nearest the ball when it was kicked (calibration index),
        /// when one was within reach.
        rod: Option<u32>,
        /// The ball's last position before the kick, table frame, mm.
        x_mm: f64,
        /// See `x_mm`.
        y_mm: f64,
    },
    /// The ball left the field, or was lost near its edge for long.
    BallOut {
        /// The last position seen, table frame, mm.
        x_mm: f64,
        /// See `x_mm`.
        y_mm: f64,
    },
    /// The ball came to rest.
    BallStopped {
        /// Where, table frame, mm.
        x_mm: f64,
        /// See `x_mm`.
        y_mm: f64,
    },
}

impl EventKind {
    /// The event's name in files: `goal`, `shot`, `ball_out`, `ball_stopped`.
    pub fn name(&self) -> &'static str {
        match self {
            EventKind::Goal { .. } => "goal",
            EventKind::Shot { .. } => "shot",
            EventKind::BallOut { .. } => "ball_out",
            EventKind::BallStopped { .. } => "ball_stopped",
        }
    }
}

/// One event, at the frame and time it happened.
///
/// ```
/// use rodtrack_core::ball::events::{BallEvent, EventKind, Side};
/// use rodtrack_core::Timestamp;
/// let e = BallEvent {
///     frame: 412,
///     timestamp_ns: Timestamp(2_060_000_000),
///     kind: EventKind::Goal { side: Side::A, goal: Side::B, score: [1, 0] },
/// };
/// assert_eq!(
///     e.json_line(),
///     r#"{"frame":412,"timestamp_s":2.060000,"event":"goal","side":"a","goal":"b","score":[1,0]}"#
/// );
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BallEvent {
    /// Frame id of the frame set it happened in.
    pub frame: u64,
    /// Capture time of that frame set.
    pub timestamp_ns: Timestamp,
    /// What happened.
    pub kind: EventKind,
}

impl BallEvent {
    /// Capture time, s (for printing).
    pub fn timestamp_s(&self) -> f64 {
        self.timestamp_ns.as_secs_f64()
    }

    /// One JSON object (no newline); see [`BallEvent::push_json`].
    pub fn json_line(&self) -> String {
        let mut s = String::with_capacity(128);
        self.push_json(&mut s);
        s
    }

    /// Appends the event as one JSON object to `out` (no allocation once `out` has room):
    /// `frame`, `timestamp_s`, `event`, then per event `side`, `goal`, `score` (goal);
    /// `speed_mm_s`, `rod` (a number or `null`), `x_mm`, `y_mm` (shot); `x_mm`, `y_mm`
    /// (`ball_out`, `ball_stopped`). Non-finite numbers are written as 0.
    pub fn push_json(&self, out: &mut String) {
        use std::fmt::Write;
        let f = |v: f64| if v.is_finite() { v } else { 0.0 };
        let _ = write!(
            out,
            "{{\"frame\":{},\"timestamp_s\":{:.6},\"event\":\"{}\"",
            self.frame,
            self.timestamp_s(),
            self.kind.name()
        );
        let _ = match self.kind {
            EventKind::Goal { side, goal, score } => write!(
                out,
                ",\"side\":\"{}\",\"goal\":\"{}\",\"score\":[{},{}]",
                side.name(),
                goal.name(),
                score[0],
                score[1]
            ),
            EventKind::Shot {
                speed_mm_s,
                rod,
                x_mm,
                y_mm,
            } => {
                let _ = write!(out, ",\"speed_mm_s\":{:.1},\"rod\":", f(speed_mm_s));
                let _ = match rod {
                    Some(r) => write!(out, "{r}"),
                    None => write!(out, "null"),
                };
                write!(out, ",\"x_mm\":{:.1},\"y_mm\":{:.1}", f(x_mm), f(y_mm))
            }
            EventKind::BallOut { x_mm, y_mm } | EventKind::BallStopped { x_mm, y_mm } => {
                write!(out, ",\"x_mm\":{:.1},\"y_mm\":{:.1}", f(x_mm), f(y_mm))
            }
        };
        out.push('}');
    }
}

/// `ok` rows kept for the shot's window (80 ms at 200 fps; a faster camera's window is cut
/// to the last this many rows).
const HISTORY: usize = 16;

#[derive(Debug, Clone, Copy, Default)]
struct Sample {
    frame: u64,
    t: Timestamp,
    x_mm: f64,
    y_mm: f64,
    speed_mm_s: f64,
}

#[derive(Debug, Clone, Copy)]
struct PendingGoal {
    goal: Side,
    frame: u64,
    t: Timestamp,
}

#[derive(Debug, Clone, Copy)]
struct PendingShot {
    start: Sample,
    /// The first fast row's time.
    jump: Timestamp,
    /// The speed before the jump, mm/s.
    before_mm_s: f64,
    /// The jump row's speed, mm/s.
    first_mm_s: f64,
    /// The sum of the later rows' speeds within the settle time, mm/s, and their count.
    later_sum_mm_s: f64,
    later: u32,
    /// `ok` rows within the settle time still faster than `before_mm_s` by the least jump.
    fast_rows: u32,
}

/// The event rules over a sequence of ball rows (see the module's documentation).
///
/// ```
/// use rodtrack_core::ball::events::{EventConfig, EventDetector, TableGeometry};
/// let geometry = TableGeometry::reference();
/// let mut det = EventDetector::new(geometry, EventConfig::default())?;
/// let mut events = Vec::with_capacity(4);
/// # let rows: Vec<rodtrack_core::ball::BallRow> = Vec::new();
/// for row in &rows {
///     det.push(row, &mut events);
/// }
/// det.finish(&mut events);
/// assert_eq!(det.score(), [0, 0]);
/// # Ok::<(), rodtrack_core::CoreError>(())
/// ```
#[derive(Debug, Clone)]
pub struct EventDetector {
    cfg: EventConfig,
    geom: TableGeometry,
    score: [u32; 2],
    /// The ball has been seen on the field since the last goal.
    armed: bool,
    /// The last row's position (`ok` or `predicted`), for the crossing.
    prev: Option<(f64, f64)>,
    pending_goal: Option<PendingGoal>,
    /// The last `ok` row.
    last_seen: Option<Sample>,
    out_reported: bool,
    stop: stop::StopRule,
    history: [Sample; HISTORY],
    history_len: usize,
    history_next: usize,
    pending_shot: Option<PendingShot>,
    last_shot: Option<Timestamp>,
    last_time: Option<(u64, Timestamp)>,
    swings: kicker::RodSwings,
}

impl EventDetector {
    /// A detector for the table `geom` with the rules' constants `cfg` (checked).
    pub fn new(geom: TableGeometry, cfg: EventConfig) -> Result<EventDetector, crate::CoreError> {
        cfg.validate()?;
        geom.validate()?;
        Ok(EventDetector {
            cfg,
            score: [0, 0],
            armed: true,
            prev: None,
            pending_goal: None,
            last_seen: None,
            out_reported: false,
            stop: stop::StopRule::new(),
            history: [Sample::default(); HISTORY],
            history_len: 0,
            history_next: 0,
            pending_shot: None,
            last_shot: None,
            last_time: None,
            swings: kicker::RodSwings::new(&geom),
            geom,
        })
    }

    /// The score so far, `[side A, side B]`.
    pub fn score(&self) -> [u32; 2] {
        self.score
    }

    /// The table it works on.
    pub fn geometry(&self) -> &TableGeometry {
        &self.geom
    }

    /// The rules' constants.
    pub fn config(&self) -> &EventConfig {
        &self.cfg
    }

    /// Takes the next frame set's ball row (frame order) and appends the events decided at
    /// it to `out` (at most 4 per row; `out` is not cleared). An event's frame may be an
    /// earlier row's (a goal's crossing, a ball's last sighting).
    pub fn push(&mut self, row: &BallRow, out: &mut Vec<BallEvent>) {
        let t = row.timestamp_ns;
        self.last_time = Some((row.frame, t));
        let position = [row.x_mm, row.y_mm];
        let finite = position.iter().all(|v| v.is_finite());
        let seen = row.status == BallStatus::Ok && finite;
        let placed = finite && matches!(row.status, BallStatus::Ok | BallStatus::Predicted);

        // Goal: the grace time first, then a return, then a crossing.
        if let Some(p) = self.pending_goal {
            if seen && self.on_field(row.x_mm) && self.near_line(row.x_mm, p.goal) {
                self.pending_goal = None;
            } else if t.seconds_since(p.t) >= self.cfg.goal_grace_s {
                self.confirm_goal(out);
            }
        }
        if placed {
            if self.pending_goal.is_none() && self.armed {
                if let Some(prev) = self.prev {
                    // Seen at the crossing, or lost just before it (the mouth hides it).
                    let credible = seen
                        || self
                            .last_seen
                            .is_some_and(|s| t.seconds_since(s.t) <= self.cfg.goal_unseen_max_s);
                    if credible {
                        self.crossing(prev, (row.x_mm, row.y_mm), row.frame, t);
                    }
                }
            }
            self.prev = Some((row.x_mm, row.y_mm));
        }
        if seen && self.on_field(row.x_mm) && self.pending_goal.is_none() {
            self.armed = true;
        }

        let sample = Sample {
            frame: row.frame,
            t,
            x_mm: row.x_mm,
            y_mm: row.y_mm,
            speed_mm_s: row.speed_mm_s(),
        };
        self.out_rule(seen.then_some(sample), t, out);
        if seen {
            if let Some(e) = self.stop.push(&self.cfg, sample) {
                out.push(e);
            }
            self.shot_rule(sample, out);
            self.last_seen = Some(sample);
        } else if let Some(s) = self.pending_shot {
            if t.seconds_since(s.jump) >= self.cfg.shot_settle_s {
                self.emit_shot(out);
            }
        }
    }

    /// Rod `rod`'s measured angle (calibration index, `angle_rad` as in its rows) at `t`, for
    /// the shot's rod: give every rod's angle of each frame, from any camera (a second angle
    /// at the same time is ignored), before or after that frame's ball row. Only angles of
    /// trusted rows should be given. No allocation.
    pub fn push_rod_angle(&mut self, rod: u32, t: Timestamp, angle_rad: f64) {
        self.swings.push(rod, t, angle_rad);
    }

    /// Decides what is still open at the end of the rows: a goal whose grace time has not
    /// run out counts (the ball did not come back), a shot still settling is written.
    pub fn finish(&mut self, out: &mut Vec<BallEvent>) {
        if self.pending_shot.is_some() {
            self.emit_shot(out);
        }
        if self.pending_goal.is_some() {
            self.confirm_goal(out);
        }
    }

    fn on_field(&self, x_mm: f64) -> bool {
        let m = self.cfg.line_margin_mm;
        x_mm >= self.geom.x_min_mm + m && x_mm <= self.geom.x_max_mm - m
    }

    fn near_line(&self, x_mm: f64, goal: Side) -> bool {
        let d = match goal {
            Side::A => x_mm - self.geom.x_min_mm,
            Side::B => self.geom.x_max_mm - x_mm,
        };
        d <= self.cfg.return_zone_mm
    }

    fn in_mouth(&self, y_mm: f64) -> bool {
        (y_mm - self.geom.y_centre_mm()).abs() <= 0.5 * self.cfg.goal_width_mm
    }

    /// A goal line crossed from `a` (on or inside the line) to `b` (beyond) within a mouth.
    fn crossing(&mut self, a: (f64, f64), b: (f64, f64), frame: u64, t: Timestamp) {
        let (lo, hi) = (self.geom.x_min_mm, self.geom.x_max_mm);
        let (goal, line) = if a.0 <= hi && b.0 > hi {
            (Side::B, hi)
        } else if a.0 >= lo && b.0 < lo {
            (Side::A, lo)
        } else {
            return;
        };
        let s = (line - a.0) / (b.0 - a.0);
        let y = a.1 + s * (b.1 - a.1);
        if self.in_mouth(y) {
            self.pending_goal = Some(PendingGoal { goal, frame, t });
        }
    }

    fn confirm_goal(&mut self, out: &mut Vec<BallEvent>) {
        let Some(p) = self.pending_goal.take() else {
            return;
        };
        let side = p.goal.other();
        self.score[side.index()] += 1;
        self.armed = false;
        // The ball in a goal is neither out nor resting.
        self.out_reported = true;
        self.stop.clear();
        out.push(BallEvent {
            frame: p.frame,
            timestamp_ns: p.t,
            kind: EventKind::Goal {
                side,
                goal: p.goal,
                score: self.score,
            },
        });
    }

    fn out_rule(&mut self, seen: Option<Sample>, t: Timestamp, out: &mut Vec<BallEvent>) {
        if let Some(s) = seen {
            let beyond = self.geom.distance_beyond_edge_mm(s.x_mm, s.y_mm);
            let into_mouth = self.in_mouth(s.y_mm)
                && (s.x_mm > self.geom.x_max_mm || s.x_mm < self.geom.x_min_mm);
            if beyond > self.cfg.out_margin_mm && !into_mouth {
                if !self.out_reported && self.pending_goal.is_none() {
                    self.out_reported = true;
                    out.push(BallEvent {
                        frame: s.frame,
                        timestamp_ns: s.t,
                        kind: EventKind::BallOut {
                            x_mm: s.x_mm,
                            y_mm: s.y_mm,
                        },
                    });
                }
            } else if self.on_field(s.x_mm) && beyond <= 0.0 {
                self.out_reported = false;
            }
            return;
        }
        let Some(last) = self.last_seen else {
            return;
        };
        if self.out_reported
            || self.pending_goal.is_some()
            || !self.armed
            || t.seconds_since(last.t) < self.cfg.out_lost_s
        {
            return;
        }
        if -self.geom.distance_beyond_edge_mm(last.x_mm, last.y_mm) <= self.cfg.out_edge_mm {
            self.out_reported = true;
            self.stop.clear();
            out.push(BallEvent {
                frame: last.frame,
                timestamp_ns: last.t,
                kind: EventKind::BallOut {
                    x_mm: last.x_mm,
                    y_mm: last.y_mm,
                },
            });
        }
    }

    fn shot_rule(&mut self, s: Sample, out: &mut Vec<BallEvent>) {
        if let Some(p) = self.pending_shot.as_mut() {
            if s.t.seconds_since(p.jump) < self.cfg.shot_settle_s {
                p.later_sum_mm_s += s.speed_mm_s;
                p.later += 1;
                if s.speed_mm_s - p.before_mm_s >= self.cfg.shot_min_jump_mm_s {
                    p.fast_rows += 1;
                }
            } else {
                self.emit_shot(out);
            }
        }
        let free = self.pending_shot.is_none()
            && self
                .last_shot
                .is_none_or(|l| s.t.seconds_since(l) >= self.cfg.shot_refractory_s);
        if free && s.speed_mm_s >= self.cfg.shot_min_speed_mm_s {
            // The fastest row of the window before, and the last row before this one.
            let (mut before, mut any, mut last_before): (f64, bool, Option<Sample>) =
                (0.0, false, None);
            for h in self.history.iter().take(self.history_len) {
                let age = s.t.seconds_since(h.t);
                if age >= self.cfg.shot_before_min_s && age <= self.cfg.shot_before_max_s {
                    before = before.max(h.speed_mm_s);
                    any = true;
                }
                if age > 0.0 && last_before.is_none_or(|l| h.t > l.t) {
                    last_before = Some(*h);
                }
            }
            if any && s.speed_mm_s - before >= self.cfg.shot_min_jump_mm_s {
                let start = last_before.unwrap_or(s);
                self.pending_shot = Some(PendingShot {
                    start,
                    jump: s.t,
                    before_mm_s: before,
                    first_mm_s: s.speed_mm_s,
                    later_sum_mm_s: 0.0,
                    later: 0,
                    fast_rows: 1,
                });
            }
        }
        self.history[self.history_next] = s;
        self.history_next = (self.history_next + 1) % HISTORY;
        self.history_len = (self.history_len + 1).min(HISTORY);
    }

    /// Writes the pending shot when it was fast on enough rows (else it was one bad row).
    fn emit_shot(&mut self, out: &mut Vec<BallEvent>) {
        if let Some(p) = self
            .pending_shot
            .take()
            .filter(|p| p.fast_rows >= self.cfg.shot_min_rows)
        {
            self.last_shot = Some(p.jump);
            let speed_mm_s = if p.later > 0 {
                p.later_sum_mm_s / f64::from(p.later)
            } else {
                p.first_mm_s
            };
            let rod = self.swings.kicker(
                &self.geom,
                &self.cfg,
                p.start.x_mm,
                speed_mm_s,
                (p.start.t, p.jump),
            );
            out.push(BallEvent {
                frame: p.start.frame,
                timestamp_ns: p.start.t,
                kind: EventKind::Shot {
                    speed_mm_s,
                    rod,
                    x_mm: p.start.x_mm,
                    y_mm: p.start.y_mm,
                },
            });
        }
    }
}
