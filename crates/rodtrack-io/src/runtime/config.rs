//! The pipeline's settings ([`PipelineConfig`], the release [`RunMode`], [`Handoff`],
//! [`WriteMode`], [`Grouping`]) and the stages a caller plugs in ([`ProcessFn`],
//! [`CameraFilterFn`], [`FrameHookFn`], [`FusionFn`] with its [`FrameSetInfo`]).

use crate::frame::{FrameBuffer, FrameMeta, Timestamp};
use crate::IoError;
use rodtrack_core::{FrameView, Measurement};
use std::time::Duration;

#[cfg(doc)]
use super::{CameraStats, Pipeline};

/// A camera's processing stage (the tracker): given a frame's metadata and its view (or the
/// error that made it bad), appends measurement rows to the vector (which arrives empty).
pub type ProcessFn =
    Box<dyn FnMut(&FrameMeta, Result<FrameView<'_>, &IoError>, &mut Vec<Measurement>) + Send>;

/// A camera's filter stage, run in the camera's thread right after its processing stage: given
/// the frame's metadata and the rows measured, appends the rows to write (the vector arrives
/// empty; e.g. a temporal filter). The fusion stage still receives the measured rows.
pub type CameraFilterFn = Box<dyn FnMut(&FrameMeta, &[Measurement], &mut Vec<Measurement>) + Send>;

/// A camera's frame hook, run in the camera's thread right after its processing stage, on
/// the frames that were read without error: it may take the frame's pixels by swapping the
/// buffer's `data` with a vector of its own (e.g. a live view that keeps the frame instead of
/// copying it), which then goes back to the buffer pool in the frame's place. The frame's
/// rows are already measured; the hook must leave `meta` as it is.
pub type FrameHookFn = Box<dyn FnMut(&mut FrameBuffer) + Send>;

/// Fusion of a frame set: given the set and the measured rows of all its cameras, appends extra
/// rows (e.g. `camera = fused`).
pub type FusionFn = Box<dyn FnMut(&FrameSetInfo, &[Measurement], &mut Vec<Measurement>) + Send>;

/// Run right after the fusion stage on the set's camera rows about to be written, which it may
/// change (e.g. mark the rows the fusion overruled). Only with [`WriteMode::Set`]: with
/// [`WriteMode::PerCamera`] the camera rows are written before the set is complete.
pub type CameraRowsFn = Box<dyn FnMut(&mut [Measurement]) + Send>;

/// How frames are released.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum RunMode {
    /// As the source delivers them (cameras); drop when the queue is full.
    Live,
    /// At the source's timestamps, scaled by `speed` (1.0 = real time), replaying files as a
    /// live camera; drop when the queue is full.
    Paced {
        /// Playback speed factor (> 0).
        speed: f64,
    },
    /// As fast as possible; block when the queue is full, never drop (offline files).
    Batch,
}

impl RunMode {
    /// [`RunMode::Live`] for live sources (cameras), [`RunMode::Batch`] for recordings.
    pub fn for_source(live: bool) -> RunMode {
        if live {
            RunMode::Live
        } else {
            RunMode::Batch
        }
    }
}

/// Which thread processes a camera's frames.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Handoff {
    /// A capture thread reads the source into a bounded queue, a processing thread takes the
    /// frames from it: capture never waits for the tracker (live sources drop and count when
    /// the queue is full), at the cost of one thread wake-up per frame.
    Queue,
    /// The capture thread processes each frame right after the source returned it: no
    /// hand-off and no wake-up. While it processes, frames wait in the source's own buffers
    /// (a camera driver's); a source that skips frames then shows gaps in its frame ids
    /// ([`CameraStats::frames_skipped`]), one that never skips delivers late.
    Inline,
}

/// When rows reach the sink.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WriteMode {
    /// One `write` per frame set: every camera's rows in camera order, then the fusion's rows.
    Set,
    /// Each camera's rows in their own `write` as soon as they are measured (a camera's rows
    /// stay in frame order; cameras interleave), then the fusion's rows in one more `write`
    /// once the set is complete.
    PerCamera,
}

/// How frames of different cameras are matched into a set.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Grouping {
    /// Same frame id (hardware-triggered cameras with a shared counter, files).
    FrameId,
    /// Timestamps within `window_ns` of the set's first frame.
    Timestamp {
        /// Half-width of the matching window, ns.
        window_ns: u64,
    },
}

/// Pipeline settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PipelineConfig {
    /// Release mode.
    pub mode: RunMode,
    /// Frames queued per camera between capture and processing (at least 1;
    /// [`Handoff::Queue`]).
    pub queue_depth: usize,
    /// Frame matching.
    pub grouping: Grouping,
    /// Longest wait for the missing frames of a set.
    pub group_timeout: Duration,
    /// After stop, how long to wait for threads (a camera stuck in a read) before giving up on
    /// them.
    pub stop_grace: Duration,
    /// Which thread processes a camera's frames.
    pub handoff: Handoff,
    /// When rows reach the sink.
    pub write: WriteMode,
    /// A thread about to block on a queue (the processing thread with [`Handoff::Queue`], the
    /// calling thread of [`Pipeline::run`]) or on the output lock ([`Pipeline::run_direct`],
    /// held by another camera's thread while it writes) first polls it for this long: it then
    /// goes on without being put to sleep and woken up if the item or the lock comes within
    /// that time. Zero (default) blocks at once; spinning costs a core while it lasts, so
    /// leave it off on machines with few cores unless a benchmark shows it helps.
    pub spin: Duration,
}

impl Default for PipelineConfig {
    fn default() -> Self {
        PipelineConfig {
            mode: RunMode::Batch,
            queue_depth: 4,
            grouping: Grouping::FrameId,
            group_timeout: Duration::from_millis(200),
            stop_grace: Duration::from_secs(2),
            handoff: Handoff::Queue,
            write: WriteMode::Set,
            spin: Duration::ZERO,
        }
    }
}

/// A frame set as passed to the fusion stage.
#[derive(Debug, Clone)]
pub struct FrameSetInfo {
    /// Frame id (of the first camera present).
    pub frame_id: u64,
    /// Timestamp (of the first camera present).
    pub timestamp_ns: Timestamp,
    /// Per camera: its frame's metadata, or `None` when it missed this set.
    pub frames: Vec<Option<FrameMeta>>,
    /// True when every camera is present.
    pub complete: bool,
}
