//! The ball's events in a session or a fusion node's [`super::BallSets`]: the detector fed
//! with each frame set's ball row, in frame order, with the rods' angles of the same frames.

use super::MAX_PENDING_ROWS;
use crate::SdkError;
use rodtrack_core::ball::events::{
    BallEvent, EventConfig, EventDetector, EventKind, TableGeometry,
};
use rodtrack_core::ball::BallRow;
use rodtrack_core::calib::CalibrationFile;
use rodtrack_core::{Measurement, Status};
use rodtrack_io::EventSink;

/// The most rod angles held for the events until their frame's ball row (as many frames as
/// [`MAX_PENDING_ROWS`], 8 rods each); more are dropped (the shot's rod then falls back to
/// the nearest axis).
const MAX_PENDING_RODS: usize = MAX_PENDING_ROWS * 8;

/// Counts of the events a session wrote ([`crate::Session::with_events`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct EventCounts {
    /// Goals.
    pub goals: u64,
    /// Shots.
    pub shots: u64,
    /// Balls out of play.
    pub ball_out: u64,
    /// Balls stopped.
    pub ball_stopped: u64,
    /// The final score, `[side A, side B]`.
    pub score: [u32; 2],
}

impl std::fmt::Display for EventCounts {
    /// `1 goal(s), score 1:0 (a:b), 2 shot(s), 0 ball out, 1 ball stopped`.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} goal(s), score {}:{} (a:b), {} shot(s), {} ball out, {} ball stopped",
            self.goals, self.score[0], self.score[1], self.shots, self.ball_out, self.ball_stopped
        )
    }
}

/// The events of the frame sets' ball rows: the detector and its sink.
pub(super) struct EventStage {
    det: EventDetector,
    sink: Box<dyn EventSink>,
    /// The events of one write, kept for its capacity.
    buf: Vec<BallEvent>,
    /// The last frame given to the detector (a row that comes later, out of order, is not).
    last_frame: Option<u64>,
    /// Trusted rod angles `(frame, rod, time, angle_rad)` waiting for their frame's ball row:
    /// given to the detector in frame order with the ball rows (a camera ahead of the others
    /// would otherwise push the kick's swing out of the detector's window before the shot
    /// is decided).
    pending_rods: Vec<PendingRod>,
    counts: EventCounts,
    error: Option<String>,
}

/// A rod's trusted angle waiting for its frame's ball row.
#[derive(Debug, Clone, Copy)]
struct PendingRod {
    frame: u64,
    camera: u32,
    rod: u32,
    t: rodtrack_core::Timestamp,
    angle_rad: f64,
}

impl EventStage {
    /// The detector of the table of `cal` with the rules `cfg`, into `sink`.
    pub(super) fn new(
        cal: &CalibrationFile,
        cfg: EventConfig,
        sink: Box<dyn EventSink>,
    ) -> Result<EventStage, SdkError> {
        let geom = TableGeometry::from_calibration(cal, &cfg)
            .map_err(|e| SdkError::core("the events", e))?;
        let det = EventDetector::new(geom, cfg).map_err(|e| SdkError::core("the events", e))?;
        Ok(EventStage {
            det,
            sink,
            buf: Vec::with_capacity(64),
            last_frame: None,
            pending_rods: Vec::with_capacity(MAX_PENDING_RODS),
            counts: EventCounts::default(),
            error: None,
        })
    }

    pub(super) fn push(&mut self, row: &BallRow) {
        if self.last_frame.is_some_and(|f| row.frame <= f) {
            return;
        }
        self.last_frame = Some(row.frame);
        // In frame order, cameras in index order: the detector keeps the first angle of a
        // rod at a time, whichever camera's thread came first.
        self.pending_rods
            .sort_unstable_by_key(|r| (r.frame, r.camera, r.rod));
        for r in self
            .pending_rods
            .iter()
            .take_while(|r| r.frame <= row.frame)
        {
            self.det.push_rod_angle(r.rod, r.t, r.angle_rad);
        }
        self.pending_rods.retain(|r| r.frame > row.frame);
        self.det.push(row, &mut self.buf);
    }

    /// The rods' angles of one camera's frame (trusted rows only), for the shot's rod.
    pub(super) fn push_rods(&mut self, rows: &[Measurement]) {
        for m in rows.iter().filter(|m| m.status == Status::Ok) {
            if self.last_frame.is_some_and(|f| m.frame <= f) {
                // Its frame's ball row is gone: now.
                self.det.push_rod_angle(m.rod, m.timestamp_ns, m.angle_rad);
            } else if self.pending_rods.len() < MAX_PENDING_RODS {
                self.pending_rods.push(PendingRod {
                    frame: m.frame,
                    camera: camera_index(m.camera),
                    rod: m.rod,
                    t: m.timestamp_ns,
                    angle_rad: m.angle_rad,
                });
            }
        }
    }

    /// Writes the events decided so far (counted), keeping the first error.
    pub(super) fn write(&mut self) {
        if self.buf.is_empty() {
            return;
        }
        for e in &self.buf {
            match e.kind {
                EventKind::Goal { .. } => self.counts.goals += 1,
                EventKind::Shot { .. } => self.counts.shots += 1,
                EventKind::BallOut { .. } => self.counts.ball_out += 1,
                EventKind::BallStopped { .. } => self.counts.ball_stopped += 1,
            }
        }
        self.counts.score = self.det.score();
        if self.error.is_none() {
            if let Err(e) = self.sink.write(&self.buf) {
                self.error = Some(e.to_string());
            }
        }
        self.buf.clear();
    }

    pub(super) fn finish(&mut self) -> Result<EventCounts, SdkError> {
        self.det.finish(&mut self.buf);
        self.write();
        self.counts.score = self.det.score();
        if self.error.is_none() {
            if let Err(e) = self.sink.flush() {
                self.error = Some(e.to_string());
            }
        }
        match &self.error {
            Some(e) => Err(SdkError::Runtime(format!("writing the events: {e}"))),
            None => Ok(self.counts),
        }
    }
}

/// A camera's index, the fused rows after every camera.
pub(super) fn camera_index(c: rodtrack_core::CameraId) -> u32 {
    match c {
        rodtrack_core::CameraId::Camera(i) => i,
        rodtrack_core::CameraId::Fused => u32::MAX,
    }
}
