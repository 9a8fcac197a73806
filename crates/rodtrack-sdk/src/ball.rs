//! The ball in a session: each camera's [`BallTracker`] runs on the frames its tracker reads,
//! and the rows go, in frame order, to a [`BallSink`] ([`crate::Session::with_ball`]).

use crate::SdkError;
use rodtrack_core::ball::{BallRow, BallStatus, BallTracker};
use rodtrack_core::calib::CalibrationFile;
use rodtrack_io::BallSink;
use std::sync::{Arc, Mutex};

/// Counts of the ball rows a session wrote.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct BallCounts {
    /// Rows `ok`.
    pub ok: u64,
    /// Rows `predicted`.
    pub predicted: u64,
    /// Rows `lost`.
    pub lost: u64,
}

/// The session's ball: the trackers (taken by the cameras' threads) and the ordered writer.
pub(crate) struct BallStage {
    trackers: Vec<(u32, BallTracker)>,
    writer: Arc<Mutex<BallWriter>>,
}

/// Rows of all cameras put in frame order before they reach the sink: a frame's rows are
/// written once every camera has reported that frame (or at the end).
pub(crate) struct BallWriter {
    sink: Box<dyn BallSink>,
    pending: Vec<BallRow>,
    last: Vec<(u32, Option<u64>)>,
    error: Option<String>,
    counts: BallCounts,
}

impl BallStage {
    pub(crate) fn new(
        cal: &CalibrationFile,
        sink: Box<dyn BallSink>,
    ) -> Result<BallStage, SdkError> {
        let mut trackers = Vec::new();
        for c in &cal.cameras {
            let t = BallTracker::new(c).map_err(|e| SdkError::core("the ball", e))?;
            if let Some(t) = t {
                trackers.push((c.index, t));
            }
        }
        if trackers.is_empty() {
            return Err(SdkError::Invalid(
                "no camera of the calibration has `[cameras.ball]`: give the calibration inputs \
                 a `ball` click (and `table` points) and calibrate again"
                    .into(),
            ));
        }
        let last = trackers.iter().map(|(i, _)| (*i, None)).collect();
        Ok(BallStage {
            trackers,
            writer: Arc::new(Mutex::new(BallWriter {
                sink,
                pending: Vec::with_capacity(64),
                last,
                error: None,
                counts: BallCounts::default(),
            })),
        })
    }

    /// Camera `index`'s tracker and the shared writer.
    pub(crate) fn take(&mut self, index: u32) -> Option<(BallTracker, Arc<Mutex<BallWriter>>)> {
        let at = self.trackers.iter().position(|(i, _)| *i == index)?;
        Some((self.trackers.swap_remove(at).1, self.writer.clone()))
    }

    /// Writes what is pending and flushes: the counts, or the first error.
    pub(crate) fn finish(&self) -> Result<BallCounts, SdkError> {
        let mut w = self
            .writer
            .lock()
            .map_err(|_| SdkError::Runtime("the ball writer's lock is poisoned".into()))?;
        w.emit(u64::MAX);
        if w.error.is_none() {
            if let Err(e) = w.sink.flush() {
                w.error = Some(e.to_string());
            }
        }
        match &w.error {
            Some(e) => Err(SdkError::Runtime(format!("writing the ball rows: {e}"))),
            None => Ok(w.counts),
        }
    }
}

impl BallWriter {
    /// Takes camera `camera`'s row and writes every frame all cameras have reported.
    pub(crate) fn push(&mut self, camera: u32, row: BallRow) {
        let at = self
            .pending
            .iter()
            .position(|r| (r.frame, cam_key(r)) > (row.frame, cam_key(&row)))
            .unwrap_or(self.pending.len());
        self.pending.insert(at, row);
        for (c, l) in &mut self.last {
            if *c == camera {
                *l = Some(row.frame);
            }
        }
        let done = self.last.iter().map(|(_, l)| *l).min().flatten();
        if let Some(f) = done {
            self.emit(f);
        }
    }

    fn emit(&mut self, up_to_frame: u64) {
        let n = self
            .pending
            .iter()
            .take_while(|r| r.frame <= up_to_frame)
            .count();
        if n == 0 {
            return;
        }
        for r in &self.pending[..n] {
            match r.status {
                BallStatus::Ok => self.counts.ok += 1,
                BallStatus::Predicted => self.counts.predicted += 1,
                BallStatus::Lost => self.counts.lost += 1,
            }
        }
        if self.error.is_none() {
            if let Err(e) = self.sink.write(&self.pending[..n]) {
                self.error = Some(e.to_string());
            }
        }
        self.pending.drain(..n);
    }
}

fn cam_key(r: &BallRow) -> u32 {
    match r.camera {
        rodtrack_core::CameraId::Camera(i) => i,
        rodtrack_core::CameraId::Fused => u32::MAX,
    }
}
