//! What a session tells its user while it runs: frames, measured rows, bad frames, fusion
//! warnings and progress.
//!
//! ```
//! use rodtrack_sdk::{Hooks, NoHooks, Progress};
//! struct Bad;
//! impl Hooks for Bad {
//!     fn bad_frame(&self, camera: &str, frame_id: u64, error: &str, count: u64) {
//!         eprintln!("{camera}: frame {frame_id} is bad ({error}), {count} so far");
//!     }
//! }
//! let hooks: [&dyn Hooks; 2] = [&Bad, &NoHooks];
//! hooks[0].bad_frame("camera 0", 7, "truncated", 1);
//! ```

use rodtrack_core::{CameraPipeline, Measurement};
use rodtrack_io::{FrameBuffer, FrameMeta};
use std::time::Duration;

/// Callbacks of a running [`crate::Session`]; every method has a default that does nothing.
///
/// They run in the session's threads: [`Hooks::measured`] and [`Hooks::frame`] in the
/// camera's own thread right after its tracker, [`Hooks::progress`] in the monitor thread.
/// Keep them short; a hook that blocks holds its camera up.
///
/// ```
/// use std::sync::atomic::{AtomicU64, Ordering};
/// /// Counts the frames measured.
/// #[derive(Default)]
/// struct Count(AtomicU64);
/// impl rodtrack_sdk::Hooks for Count {
///     fn measured(&self, _camera: u32, _meta: &rodtrack_io::FrameMeta,
///                 _rows: &[rodtrack_core::Measurement], _pipe: &rodtrack_core::CameraPipeline) {
///         self.0.fetch_add(1, Ordering::Relaxed);
///     }
/// }
/// ```
pub trait Hooks: Send + Sync {
    /// A camera measured a frame: its raw rows (before the temporal filter) and its tracker,
    /// whose [`CameraPipeline::last_results`] describe the frame's rods.
    fn measured(&self, camera: u32, meta: &FrameMeta, rows: &[Measurement], pipe: &CameraPipeline) {
        let _ = (camera, meta, rows, pipe);
    }

    /// Every frame of a camera, measured or bad: the rows the fusion takes (the raw rows of
    /// [`Hooks::measured`], or the `bad_frame` rows of a frame that could not be measured),
    /// in the camera's thread right after its tracker. A network node publishes them so that
    /// a fusion node elsewhere fuses exactly what an in-process session would.
    fn camera_rows(&self, camera: u32, meta: &FrameMeta, rows: &[Measurement]) {
        let _ = (camera, meta, rows);
    }

    /// True when [`Hooks::frame`] is to be called (asked once, when the session starts).
    fn uses_frames(&self) -> bool {
        false
    }

    /// The pixels of a frame a camera read without error, after [`Hooks::measured`]. The hook
    /// may take them by swapping `buf.data` with a vector of its own, which then goes back to
    /// the session's buffer pool (no copy); it must leave `buf.meta` as it is.
    fn frame(&self, camera: u32, buf: &mut FrameBuffer) {
        let _ = (camera, buf);
    }

    /// A frame a camera could not deliver or measure: every rod of that camera gets a
    /// `bad_frame` row and the session goes on. `count` is the camera's bad frames so far.
    fn bad_frame(&self, camera: &str, frame_id: u64, error: &str, count: u64) {
        let _ = (camera, frame_id, error, count);
    }

    /// Cameras that disagree or are out of sync (from the fusion); `count` is the session's
    /// warnings so far.
    fn warning(&self, text: &str, count: u64) {
        let _ = (text, count);
    }

    /// The session's counters, about every [`crate::SessionOptions::progress_period`].
    fn progress(&self, progress: &Progress) {
        let _ = progress;
    }
}

/// No hooks.
///
/// ```
/// use rodtrack_sdk::{Hooks, NoHooks};
/// use std::sync::Arc;
/// // What a session has until `Session::with_hooks` gives it others.
/// let hooks: Arc<dyn Hooks> = Arc::new(NoHooks);
/// assert!(!hooks.uses_frames());
/// ```
#[derive(Debug, Default, Clone, Copy)]
pub struct NoHooks;

impl Hooks for NoHooks {}

/// The counters of a running session, given to [`Hooks::progress`].
///
/// ```
/// /// Prints frame sets per second.
/// struct Rate;
/// impl rodtrack_sdk::Hooks for Rate {
///     fn progress(&self, p: &rodtrack_sdk::Progress) {
///         let secs = p.elapsed.as_secs_f64().max(1e-9);
///         eprintln!("{} sets, {:.0}/s, {} dropped, {} bad", p.sets, p.sets as f64 / secs, p.dropped, p.bad);
///     }
/// }
/// ```
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Progress {
    /// Frame sets written (complete and incomplete).
    pub sets: u64,
    /// Frame sets the run will have, for recordings (the shortest input); `None` live.
    pub total: Option<u64>,
    /// Camera frames processed (all cameras).
    pub frames: u64,
    /// Camera frames measured (bad frames excluded) and the time spent measuring them.
    pub measured: u64,
    /// Time spent in the trackers over `measured` frames.
    pub tracker_time: Duration,
    /// Frames dropped (live sources whose processing fell behind).
    pub dropped: u64,
    /// Bad frames.
    pub bad: u64,
    /// Number of cameras.
    pub cameras: usize,
    /// Time since the session started.
    pub elapsed: Duration,
}
