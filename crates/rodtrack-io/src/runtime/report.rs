//! The pipeline's counters (live, [`PipelineCounters`]) and its final numbers
//! ([`PipelineReport`]).

use super::latency::{LatencyStages, LatencySummary};
use std::sync::atomic::AtomicU64;
use std::sync::Mutex;
use std::time::Duration;

#[cfg(doc)]
use super::WriteMode;

/// At most this many error messages are kept per camera ([`CameraStats::errors`]).
const MAX_ERRORS: usize = 16;

/// Appends an error message to a camera's list, unless it is full.
pub(super) fn push_error(errors: &Mutex<Vec<String>>, msg: String) {
    if let Ok(mut e) = errors.lock() {
        if e.len() < MAX_ERRORS {
            e.push(msg);
        }
    }
}

/// Live counters of one camera (atomics; read them while the pipeline runs).
#[derive(Debug, Default)]
pub struct CameraCounters {
    /// Frames delivered by the source, good or bad.
    pub frames_read: AtomicU64,
    /// Frames passed to the processing stage.
    pub frames_processed: AtomicU64,
    /// Frames dropped because the queue was full (or at stop).
    pub frames_dropped: AtomicU64,
    /// Frame ids the source skipped (gaps between consecutive ids it delivered).
    pub frames_skipped: AtomicU64,
    /// Frames the source or the view check reported as bad.
    pub bad_frames: AtomicU64,
    /// Frame sets emitted without this camera's frame.
    pub missing_in_sets: AtomicU64,
    /// Frames that came after their frame set was written: their rows written on their own,
    /// not fused (the set's fused rows are out already).
    pub frames_late: AtomicU64,
    /// Set by the caller while the camera is known to be away (e.g. a network node that
    /// stopped sending): frame sets do not wait for its frames, as if it had ended, until it
    /// is cleared.
    pub absent: std::sync::atomic::AtomicBool,
}

/// Live counters of a pipeline.
#[derive(Debug, Default)]
pub struct PipelineCounters {
    /// Per camera, in the order added.
    pub cameras: Vec<CameraCounters>,
    /// Frame sets emitted with every camera.
    pub sets_complete: AtomicU64,
    /// Frame sets emitted with a camera missing.
    pub sets_incomplete: AtomicU64,
    /// Rows passed to the sink.
    pub rows_written: AtomicU64,
    /// Failed sink calls.
    pub sink_errors: AtomicU64,
}

/// Final numbers of one camera.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct CameraStats {
    /// Source name.
    pub name: String,
    /// Frames delivered by the source, good or bad.
    pub frames_read: u64,
    /// Frames processed.
    pub frames_processed: u64,
    /// Frames dropped.
    pub frames_dropped: u64,
    /// Frame ids the source skipped (gaps between consecutive ids it delivered: frames lost
    /// before they reached the pipeline, e.g. in a camera driver).
    pub frames_skipped: u64,
    /// Bad frames.
    pub bad_frames: u64,
    /// Sets emitted without this camera.
    pub missing_in_sets: u64,
    /// Frames that came after their set was written: written on their own, not fused.
    pub frames_late: u64,
    /// Frame buffers the camera's pool allocated (bounded by the queue depth).
    pub buffers_allocated: usize,
    /// The first error messages (bad frames, a failed source, a panicked stage), at most 16.
    pub errors: Vec<String>,
}

/// What a run did.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct PipelineReport {
    /// Per camera.
    pub cameras: Vec<CameraStats>,
    /// Sets with every camera.
    pub sets_complete: u64,
    /// Sets with a camera missing.
    pub sets_incomplete: u64,
    /// Rows passed to the sink.
    pub rows_written: u64,
    /// Failed sink calls.
    pub sink_errors: u64,
    /// The first sink error message.
    pub first_sink_error: Option<String>,
    /// Per frame: available to the return of the `write` of its camera's rows (see the module
    /// documentation).
    pub latency: LatencySummary,
    /// Per frame: available to the return of the last `write` of its set (the fusion's rows;
    /// the same as `latency` with [`WriteMode::Set`]).
    pub set_latency: LatencySummary,
    /// Per frame set: its last frame available to the return of its last `write`: the
    /// pipeline's share of `set_latency`, without the wait for the other cameras' frames.
    pub set_last_latency: LatencySummary,
    /// `latency` split into consecutive stages.
    pub stages: LatencyStages,
    /// Wall time of the run.
    pub elapsed: Duration,
    /// True when the stop flag ended the run.
    pub stopped: bool,
}

impl std::fmt::Display for PipelineReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(
            f,
            "{:.3} s{}: {} frame sets ({} incomplete), {} rows written, {} sink errors",
            self.elapsed.as_secs_f64(),
            if self.stopped { " (stopped)" } else { "" },
            self.sets_complete + self.sets_incomplete,
            self.sets_incomplete,
            self.rows_written,
            self.sink_errors
        )?;
        if let Some(e) = &self.first_sink_error {
            writeln!(f, "  first sink error: {e}")?;
        }
        for (i, c) in self.cameras.iter().enumerate() {
            write!(
                f,
                "  camera {i} ({}): {} read, {} processed, {} dropped, {} bad, {} missing from sets",
                c.name, c.frames_read, c.frames_processed, c.frames_dropped, c.bad_frames, c.missing_in_sets
            )?;
            if c.frames_skipped > 0 {
                write!(f, ", {} skipped by the source", c.frames_skipped)?;
            }
            if c.frames_late > 0 {
                write!(f, ", {} late (written, not fused)", c.frames_late)?;
            }
            writeln!(f)?;
            for e in &c.errors {
                writeln!(f, "    {e}")?;
            }
        }
        write!(f, "  latency: {}", self.latency)?;
        if self.set_latency != self.latency {
            write!(
                f,
                "\n  latency to the set's last write: {}",
                self.set_latency
            )?;
            write!(
                f,
                "\n  set's last frame available to its last write: {}",
                self.set_last_latency
            )?;
        }
        if self.latency.count > 0 {
            write!(f, "\n  {}", self.stages)?;
        }
        Ok(())
    }
}
