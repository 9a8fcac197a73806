//! The runtime pipeline: one capture thread per camera, per-camera processing, frame-set
//! grouping, fusion and the sink.
//!
//! ```text
//!  Handoff::Queue (default):
//!  source 0 -> [capture 0] -> queue (depth d) -> [process 0 + filter 0] --\
//!                                                                          >-> [group by frame id] -> fusion -> sink
//!  source 1 -> [capture 1] -> queue (depth d) -> [process 1 + filter 1] --/
//!
//!  Handoff::Inline (one thread per camera, no hand-off):
//!  source 0 -> [capture 0 + process 0 + filter 0] --\
//!                                                    >-> [group by frame id] -> fusion -> sink
//!  source 1 -> [capture 1 + process 1 + filter 1] --/
//! ```
//!
//! - Capture never waits for a slow consumer in [`Mode::Live`] and [`Mode::Paced`] with
//!   [`Handoff::Queue`]: when the queue is full the frame is dropped and counted.
//!   [`Mode::Batch`] (files read as fast as possible) blocks instead and never drops. With
//!   [`Handoff::Inline`] the capture thread processes each frame itself: the source's own
//!   buffers are the queue, and frames it skips meanwhile show as gaps in its frame ids
//!   ([`CameraStats::frames_skipped`], counted in every mode).
//! - Output: with [`Pipeline::run`] the calling thread groups and writes (one more hand-off);
//!   with [`Pipeline::run_direct`] the thread that completes a frame set (or, with
//!   [`WriteMode::PerCamera`], that measured a frame) groups and writes it itself, under a
//!   lock, and the calling thread only handles time-outs and the end.
//! - [`WriteMode::Set`]: one sink `write` per frame set, every camera's rows then the
//!   fusion's. [`WriteMode::PerCamera`]: each camera's rows are written as soon as they are
//!   measured, the fusion's rows when the set is complete.
//! - Frame buffers and row vectors are recycled through pools: steady state allocates no
//!   frame or row memory.
//! - A frame set is emitted when every camera has delivered its frame for it, or has moved past
//!   it (a newer id arrived: the camera missed this frame), or has ended, or after
//!   [`PipelineConfig::group_timeout`]. Sets are emitted in order; missing frames are counted
//!   per camera.
//! - Latency of a frame: from the moment it is *available* (the source's `next_frame`
//!   returned it, and in paced mode its release time came) to the return of the sink's `write`
//!   call that wrote its camera's rows (the set's `write` with [`WriteMode::Set`]). Split into
//!   stages in [`PipelineReport::stages`]; [`PipelineReport::set_latency`] runs to the write of
//!   the set's last rows (the fusion's).
//! - The stop flag ends capture; frames already read are processed, every pending set is
//!   emitted and the sink is flushed.
//!
//! ```no_run
//! use rodtrack_core::{CameraId, Measurement, Status};
//! use rodtrack_io::runtime::{Mode, Pipeline, PipelineConfig};
//! use rodtrack_io::{CsvSink, OpenOptions, SourceFactory};
//!
//! # fn main() -> Result<(), rodtrack_io::IoError> {
//! let factory = SourceFactory::new();
//! let mut pipeline = Pipeline::new(PipelineConfig { mode: Mode::Paced { speed: 1.0 }, ..Default::default() });
//! for input in ["rec/cam0", "raw:rec/cam1.raw?width=1440&height=1080&format=bayer_rggb8"] {
//!     let source = factory.open(input, &OpenOptions::default())?;
//!     pipeline.add_camera(source, Box::new(|meta, frame, rows| {
//!         // The tracker goes here; a bad frame arrives as Err and can be reported as such.
//!         let status = if frame.is_ok() { Status::NotFound } else { Status::BadFrame };
//!         let t = meta.timestamp_ns.as_secs_f64();
//!         rows.push(Measurement::empty(meta.frame_id, t, CameraId::Camera(meta.camera), 0, status));
//!     }));
//! }
//! let stop = pipeline.stop_flag(); // set it from a Ctrl-C handler
//! # let _ = stop;
//! let mut sink = CsvSink::create("out.csv".as_ref())?;
//! let report = pipeline.run(&mut sink)?;
//! eprintln!("{report}");
//! # Ok(())
//! # }
//! ```

mod budget;
mod latency;
#[cfg(test)]
mod tests;

pub use budget::{track_memory_budget, BASE_BYTES};
pub use latency::{LatencyHistogram, LatencyStages, LatencySummary};

use crate::frame::{BufferPool, FrameBuffer, FrameMeta, Timestamp};
use crate::sink::MeasurementSink;
use crate::source::FrameSource;
use crate::IoError;
use crossbeam_channel::{
    bounded, Receiver, RecvTimeoutError, SendTimeoutError, Sender, TryRecvError, TrySendError,
};
use latency::StageHistograms;
use rodtrack_core::{FrameView, Measurement};
use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, TryLockError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

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

/// How frames are released.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Mode {
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

impl Mode {
    /// [`Mode::Live`] for live sources (cameras), [`Mode::Batch`] for recordings.
    pub fn for_source(live: bool) -> Mode {
        if live {
            Mode::Live
        } else {
            Mode::Batch
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
    pub mode: Mode,
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
            mode: Mode::Batch,
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

struct Camera {
    source: Box<dyn FrameSource>,
    process: ProcessFn,
    filter: Option<CameraFilterFn>,
    hook: Option<FrameHookFn>,
}

/// A multi-camera pipeline; see the module documentation.
pub struct Pipeline {
    config: PipelineConfig,
    cameras: Vec<Camera>,
    fusion: Option<FusionFn>,
    stop: Arc<AtomicBool>,
    counters: Arc<PipelineCounters>,
}

impl std::fmt::Debug for Pipeline {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Pipeline")
            .field("config", &self.config)
            .field(
                "cameras",
                &self
                    .cameras
                    .iter()
                    .map(|c| c.source.info().name)
                    .collect::<Vec<_>>(),
            )
            .finish()
    }
}

/// A frame handed from capture to processing.
struct Captured {
    buf: FrameBuffer,
    result: Result<(), IoError>,
    available: Instant,
}

/// When a frame passed each point of the pipeline.
#[derive(Debug, Clone, Copy)]
struct Stamps {
    /// The source returned it (and, paced, its release time came).
    available: Instant,
    /// Its processing started.
    started: Instant,
    /// Its processing (and the camera's filter) ended.
    processed: Instant,
    /// The output stage took its rows.
    entered: Instant,
}

/// One camera's processed frame.
struct Part {
    meta: FrameMeta,
    /// Rows of the processing stage (the fusion's input).
    rows: Vec<Measurement>,
    /// Rows of the camera's filter, written instead of `rows` (`None`: no filter).
    filtered: Option<Vec<Measurement>>,
    stamps: Stamps,
}

impl Part {
    /// The rows to write.
    fn output(&self) -> &[Measurement] {
        self.filtered.as_deref().unwrap_or(&self.rows)
    }
}

/// A message to the calling thread.
enum ToMain {
    /// A processed frame ([`Pipeline::run`] only).
    Frame(usize, Part),
    /// A camera's processing thread ended.
    Ended(usize),
}

const MAX_ERRORS: usize = 16;

/// Placeholder frame id while a source reads (see the capture loop).
const UNKNOWN_ID: u64 = u64::MAX;

fn push_error(errors: &Mutex<Vec<String>>, msg: String) {
    if let Ok(mut e) = errors.lock() {
        if e.len() < MAX_ERRORS {
            e.push(msg);
        }
    }
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    // A stage that panicked while holding the lock left consistent-enough state: the set it
    // was emitting is lost (its camera reports the panic), the others go on.
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// [`lock`], polling the lock for up to `spin` before blocking on it (see
/// [`PipelineConfig::spin`]).
fn lock_spin<T>(m: &Mutex<T>, spin: Duration) -> MutexGuard<'_, T> {
    if !spin.is_zero() {
        let start = Instant::now();
        loop {
            match m.try_lock() {
                Ok(g) => return g,
                Err(TryLockError::Poisoned(e)) => return e.into_inner(),
                Err(TryLockError::WouldBlock) if start.elapsed() < spin => std::hint::spin_loop(),
                Err(TryLockError::WouldBlock) => break,
            }
        }
    }
    lock(m)
}

/// Sends `Ended` when the processing thread ends, panics included.
struct EndGuard {
    camera: usize,
    tx: Sender<ToMain>,
}

impl Drop for EndGuard {
    fn drop(&mut self) {
        let _ = self.tx.send(ToMain::Ended(self.camera));
    }
}

/// Sleeps until `until` unless `stop` is set first; returns false on stop.
fn sleep_until(until: Instant, stop: &AtomicBool) -> bool {
    loop {
        if stop.load(Ordering::Relaxed) {
            return false;
        }
        let now = Instant::now();
        if now >= until {
            return true;
        }
        std::thread::sleep((until - now).min(Duration::from_millis(20)));
    }
}

/// Polls `rx` for up to `spin`; `Err(Empty)` when nothing came in that time.
fn spin_recv<T>(rx: &Receiver<T>, spin: Duration) -> Result<T, TryRecvError> {
    let start = Instant::now();
    loop {
        match rx.try_recv() {
            Err(TryRecvError::Empty) if start.elapsed() < spin => std::hint::spin_loop(),
            r => return r,
        }
    }
}

/// Receives with a short spin first (see [`PipelineConfig::spin`]).
fn recv_spin<T>(rx: &Receiver<T>, spin: Duration) -> Option<T> {
    if !spin.is_zero() {
        match spin_recv(rx, spin) {
            Ok(v) => return Some(v),
            Err(TryRecvError::Disconnected) => return None,
            Err(TryRecvError::Empty) => {}
        }
    }
    rx.recv().ok()
}

/// Receives with a short spin first, then waits up to `timeout`.
fn recv_spin_timeout<T>(
    rx: &Receiver<T>,
    spin: Duration,
    timeout: Duration,
) -> Result<T, RecvTimeoutError> {
    if !spin.is_zero() {
        match spin_recv(rx, spin) {
            Ok(v) => return Ok(v),
            Err(TryRecvError::Disconnected) => return Err(RecvTimeoutError::Disconnected),
            Err(TryRecvError::Empty) => {}
        }
    }
    rx.recv_timeout(timeout)
}

/// Where a processed frame goes: to the calling thread, or straight into the output stage.
trait Deliver: Send + 'static {
    /// False when the output is gone (the run ended).
    fn deliver(&self, camera: usize, part: Part) -> bool;
}

/// [`Pipeline::run`]: a hand-off to the calling thread.
struct ToCaller(Sender<ToMain>);

impl Deliver for ToCaller {
    fn deliver(&self, camera: usize, part: Part) -> bool {
        self.0.send(ToMain::Frame(camera, part)).is_ok()
    }
}

/// The output stage with its sink, shared by the camera threads ([`Pipeline::run_direct`]).
struct Shared<S> {
    grouper: Grouper,
    /// `None` once the run has ended.
    sink: Option<S>,
}

/// [`Pipeline::run_direct`]: the camera's thread runs the output stage.
struct Direct<S> {
    shared: Arc<Mutex<Shared<S>>>,
    spin: Duration,
}

impl<S: MeasurementSink + 'static> Deliver for Direct<S> {
    fn deliver(&self, camera: usize, mut part: Part) -> bool {
        let mut guard = lock_spin(&self.shared, self.spin);
        part.stamps.entered = Instant::now();
        let Shared { grouper, sink } = &mut *guard;
        let Some(sink) = sink.as_mut() else {
            grouper.recycle(part);
            return false;
        };
        grouper.add(camera, part, sink);
        grouper.emit_ready(Instant::now(), false, sink);
        true
    }
}

/// Access to the output stage from the calling thread.
trait Output {
    fn with<R>(&mut self, f: impl FnOnce(&mut Grouper, &mut dyn MeasurementSink) -> R)
        -> Option<R>;
}

/// [`Pipeline::run`]: the calling thread owns the output stage.
struct Local<'a> {
    grouper: Grouper,
    sink: &'a mut dyn MeasurementSink,
}

impl Output for Local<'_> {
    fn with<R>(
        &mut self,
        f: impl FnOnce(&mut Grouper, &mut dyn MeasurementSink) -> R,
    ) -> Option<R> {
        Some(f(&mut self.grouper, &mut *self.sink))
    }
}

impl<S: MeasurementSink> Output for Arc<Mutex<Shared<S>>> {
    fn with<R>(
        &mut self,
        f: impl FnOnce(&mut Grouper, &mut dyn MeasurementSink) -> R,
    ) -> Option<R> {
        let mut guard = lock(self);
        let Shared { grouper, sink } = &mut *guard;
        let sink = sink.as_mut()?;
        Some(f(grouper, sink))
    }
}

/// A camera's processing stage as run by its thread.
struct Worker<D> {
    camera: usize,
    process: ProcessFn,
    filter: Option<CameraFilterFn>,
    hook: Option<FrameHookFn>,
    counters: Arc<PipelineCounters>,
    errors: Arc<Mutex<Vec<String>>>,
    pool: BufferPool,
    vec_rx: Receiver<Vec<Measurement>>,
    deliver: D,
}

impl<D: Deliver> Worker<D> {
    fn rows_vec(&self) -> Vec<Measurement> {
        let mut v = self.vec_rx.try_recv().unwrap_or_default();
        v.clear();
        v
    }

    /// Processes a frame and delivers its rows; false when the output is gone.
    fn handle(&mut self, mut cap: Captured) -> bool {
        let started = Instant::now();
        let c = &self.counters.cameras[self.camera];
        let mut rows = self.rows_vec();
        let meta = cap.buf.meta;
        match cap.result {
            Ok(()) => match cap.buf.try_view() {
                Ok(view) => {
                    (self.process)(&meta, Ok(view), &mut rows);
                    if let Some(hook) = self.hook.as_mut() {
                        hook(&mut cap.buf);
                    }
                }
                Err(e) => {
                    c.bad_frames.fetch_add(1, Ordering::Relaxed);
                    push_error(&self.errors, e.to_string());
                    (self.process)(&meta, Err(&e), &mut rows);
                }
            },
            Err(e) => (self.process)(&meta, Err(&e), &mut rows),
        }
        self.pool.put(cap.buf);
        let filtered = if self.filter.is_some() {
            let mut out = self.rows_vec();
            if let Some(f) = self.filter.as_mut() {
                f(&meta, &rows, &mut out);
            }
            Some(out)
        } else {
            None
        };
        c.frames_processed.fetch_add(1, Ordering::Relaxed);
        let processed = Instant::now();
        self.deliver.deliver(
            self.camera,
            Part {
                meta,
                rows,
                filtered,
                stamps: Stamps {
                    available: cap.available,
                    started,
                    processed,
                    entered: processed,
                },
            },
        )
    }
}

/// Reads a source until it ends, fails or `stop` is set, and passes every frame to `emit`
/// (which returns false to end the loop).
struct Capture {
    camera: usize,
    source: Box<dyn FrameSource>,
    mode: Mode,
    stop: Arc<AtomicBool>,
    counters: Arc<PipelineCounters>,
    errors: Arc<Mutex<Vec<String>>>,
    pool: BufferPool,
}

impl Capture {
    fn run(mut self, mut emit: impl FnMut(Captured) -> bool) {
        let i = self.camera;
        let c = &self.counters.cameras[i];
        let mut pace: Option<(Instant, u64)> = None;
        let mut last: Option<(u64, Timestamp)> = None;
        while !self.stop.load(Ordering::Relaxed) {
            let mut buf = self.pool.get();
            buf.meta.camera = i as u32;
            // A bad frame whose source could not tell its id gets the next one.
            buf.meta.frame_id = UNKNOWN_ID;
            let result = match self.source.next_frame(&mut buf) {
                Ok(None) => break,
                Ok(Some(())) => Ok(()),
                Err(e) => Err(e),
            };
            buf.meta.camera = i as u32;
            if buf.meta.frame_id == UNKNOWN_ID {
                buf.meta.frame_id = last.map_or(0, |(id, _)| id + 1);
                buf.meta.timestamp_ns = last.map_or(Timestamp(0), |(_, t)| t);
            } else if let Some((prev, _)) = last {
                let gap = buf.meta.frame_id.saturating_sub(prev).saturating_sub(1);
                if gap > 0 {
                    c.frames_skipped.fetch_add(gap, Ordering::Relaxed);
                }
            }
            last = Some((buf.meta.frame_id, buf.meta.timestamp_ns));
            c.frames_read.fetch_add(1, Ordering::Relaxed);
            if let Err(e) = &result {
                c.bad_frames.fetch_add(1, Ordering::Relaxed);
                push_error(&self.errors, e.to_string());
                if e.is_fatal() {
                    break;
                }
            }
            if let Mode::Paced { speed } = self.mode {
                let ts = buf.meta.timestamp_ns.as_nanos();
                let (t0, ts0) = *pace.get_or_insert((Instant::now(), ts));
                let dt = ts.saturating_sub(ts0) as f64 / speed;
                if !sleep_until(t0 + Duration::from_nanos(dt as u64), &self.stop) {
                    c.frames_dropped.fetch_add(1, Ordering::Relaxed);
                    break;
                }
            }
            let msg = Captured {
                buf,
                result,
                available: Instant::now(),
            };
            if !emit(msg) {
                break;
            }
        }
    }
}

/// The queue sender of [`Handoff::Queue`]: drops and counts when full (live, paced), or
/// blocks (batch); false when the processing thread is gone.
fn enqueue(
    tx: &Sender<Captured>,
    msg: Captured,
    mode: Mode,
    stop: &AtomicBool,
    counters: &CameraCounters,
    pool: &BufferPool,
) -> bool {
    match mode {
        Mode::Live | Mode::Paced { .. } => match tx.try_send(msg) {
            Ok(()) => true,
            Err(TrySendError::Full(m)) => {
                counters.frames_dropped.fetch_add(1, Ordering::Relaxed);
                pool.put(m.buf);
                true
            }
            Err(TrySendError::Disconnected(_)) => false,
        },
        Mode::Batch => {
            let mut m = msg;
            loop {
                match tx.send_timeout(m, Duration::from_millis(20)) {
                    Ok(()) => return true,
                    Err(SendTimeoutError::Timeout(back)) => {
                        if stop.load(Ordering::Relaxed) {
                            counters.frames_dropped.fetch_add(1, Ordering::Relaxed);
                            pool.put(back.buf);
                            return true;
                        }
                        m = back;
                    }
                    Err(SendTimeoutError::Disconnected(_)) => return false,
                }
            }
        }
    }
}

impl Pipeline {
    /// An empty pipeline.
    pub fn new(config: PipelineConfig) -> Self {
        Pipeline {
            config,
            cameras: Vec::new(),
            fusion: None,
            stop: Arc::new(AtomicBool::new(false)),
            counters: Arc::new(PipelineCounters::default()),
        }
    }

    /// Adds a camera; returns its index (written to `FrameMeta::camera`).
    pub fn add_camera(&mut self, source: Box<dyn FrameSource>, process: ProcessFn) -> u32 {
        self.cameras.push(Camera {
            source,
            process,
            filter: None,
            hook: None,
        });
        (self.cameras.len() - 1) as u32
    }

    /// Sets camera `camera`'s filter stage (see [`CameraFilterFn`]).
    pub fn set_camera_filter(
        &mut self,
        camera: u32,
        filter: CameraFilterFn,
    ) -> Result<(), IoError> {
        self.camera_mut(camera, "camera filter")?.filter = Some(filter);
        Ok(())
    }

    /// Sets camera `camera`'s frame hook (see [`FrameHookFn`]).
    pub fn set_frame_hook(&mut self, camera: u32, hook: FrameHookFn) -> Result<(), IoError> {
        self.camera_mut(camera, "frame hook")?.hook = Some(hook);
        Ok(())
    }

    /// Camera `camera`, for setting its `what`; an error naming both when it was not added.
    fn camera_mut(&mut self, camera: u32, what: &str) -> Result<&mut Camera, IoError> {
        let n = self.cameras.len();
        self.cameras.get_mut(camera as usize).ok_or_else(|| {
            IoError::Config(format!(
                "{what} for camera {camera}, but {n} camera(s) added"
            ))
        })
    }

    /// Sets the fusion stage.
    pub fn set_fusion(&mut self, fusion: FusionFn) {
        self.fusion = Some(fusion);
    }

    /// The stop flag: set it (e.g. from a Ctrl-C handler) to end the run cleanly.
    pub fn stop_flag(&self) -> Arc<AtomicBool> {
        self.stop.clone()
    }

    /// Live counters for this pipeline's cameras (one [`CameraCounters`] per camera added so
    /// far; call after the last `add_camera`). Read them from another thread while it runs.
    pub fn counters(&mut self) -> Arc<PipelineCounters> {
        let n = self.cameras.len();
        if self.counters.cameras.len() != n {
            self.counters = Arc::new(PipelineCounters {
                cameras: (0..n).map(|_| CameraCounters::default()).collect(),
                ..Default::default()
            });
        }
        self.counters.clone()
    }

    fn check(&self) -> Result<(), IoError> {
        if self.cameras.is_empty() {
            return Err(IoError::Config("no cameras".into()));
        }
        if let Mode::Paced { speed } = self.config.mode {
            if !(speed > 0.0 && speed.is_finite()) {
                return Err(IoError::Config(format!(
                    "paced speed must be > 0, got {speed}"
                )));
            }
        }
        Ok(())
    }

    /// Runs until every source ends or the stop flag is set; writes every frame set to `sink`
    /// from the calling thread and flushes it. Blocks the calling thread. Errors only on an
    /// invalid configuration; bad frames, failed sources and sink errors are counted in the
    /// report.
    pub fn run(mut self, sink: &mut dyn MeasurementSink) -> Result<PipelineReport, IoError> {
        self.check()?;
        let counters = self.counters();
        let started = Instant::now();
        let n = self.cameras.len();
        let (main_tx, main_rx) = bounded::<ToMain>(256 * n);
        let (vec_tx, vec_rx) = bounded::<Vec<Measurement>>(128 * n);
        let grouper = Grouper::new(self.config, n, self.fusion.take(), &counters, vec_tx);
        let threads = self.spawn(&counters, &main_tx, &vec_rx, |_| ToCaller(main_tx.clone()))?;
        drop(main_tx);
        let mut threads = threads;
        let mut out = Local { grouper, sink };
        let stopped = self.main_loop(&main_rx, &mut out, &mut threads);
        Ok(out.grouper.finish(&counters, &threads, started, stopped))
    }

    /// Like [`Pipeline::run`], but the camera threads write: the thread that measured a frame
    /// (or completed its set) groups, fuses and writes it itself, under a lock, without a
    /// hand-off to another thread; the calling thread only emits the sets whose cameras time
    /// out, and ends the run. Returns the report and the sink (flushed).
    pub fn run_direct<S: MeasurementSink + 'static>(
        mut self,
        sink: S,
    ) -> Result<(PipelineReport, S), IoError> {
        self.check()?;
        let counters = self.counters();
        let started = Instant::now();
        let n = self.cameras.len();
        let (main_tx, main_rx) = bounded::<ToMain>(4 * n);
        let (vec_tx, vec_rx) = bounded::<Vec<Measurement>>(128 * n);
        let grouper = Grouper::new(self.config, n, self.fusion.take(), &counters, vec_tx);
        let shared = Arc::new(Mutex::new(Shared {
            grouper,
            sink: Some(sink),
        }));
        let spin = self.config.spin;
        let threads = self.spawn(&counters, &main_tx, &vec_rx, |_| Direct {
            shared: shared.clone(),
            spin,
        })?;
        drop(main_tx);
        let mut threads = threads;
        let mut out = shared.clone();
        let stopped = self.main_loop(&main_rx, &mut out, &mut threads);
        // Threads abandoned after the stop grace find no sink and end.
        let mut guard = lock(&shared);
        let sink = guard
            .sink
            .take()
            .ok_or_else(|| IoError::Config("pipeline sink already taken".into()))?;
        let report = guard.grouper.finish(&counters, &threads, started, stopped);
        Ok((report, sink))
    }

    /// Starts every camera's threads; `deliver` makes each camera's output end.
    fn spawn<D: Deliver>(
        &mut self,
        counters: &Arc<PipelineCounters>,
        main_tx: &Sender<ToMain>,
        vec_rx: &Receiver<Vec<Measurement>>,
        mut deliver: impl FnMut(usize) -> D,
    ) -> Result<Threads, IoError> {
        let n = self.cameras.len();
        let depth = self.config.queue_depth.max(1);
        let mut t = Threads {
            names: Vec::with_capacity(n),
            pools: Vec::with_capacity(n),
            errors: Vec::with_capacity(n),
            capture: Vec::with_capacity(n),
            processing: Vec::with_capacity(n),
        };
        for (i, cam) in std::mem::take(&mut self.cameras).into_iter().enumerate() {
            let Camera {
                source,
                process,
                filter,
                hook,
            } = cam;
            t.names.push(source.info().name);
            let pool = BufferPool::new(depth + 3);
            t.pools.push(pool.clone());
            let errs = Arc::new(Mutex::new(Vec::new()));
            t.errors.push(errs.clone());
            let capture = Capture {
                camera: i,
                source,
                mode: self.config.mode,
                stop: self.stop.clone(),
                counters: counters.clone(),
                errors: errs.clone(),
                pool: pool.clone(),
            };
            let mut worker = Worker {
                camera: i,
                process,
                filter,
                hook,
                counters: counters.clone(),
                errors: errs,
                pool,
                vec_rx: vec_rx.clone(),
                deliver: deliver(i),
            };
            let guard = EndGuard {
                camera: i,
                tx: main_tx.clone(),
            };
            let spin = self.config.spin;
            let handle = match self.config.handoff {
                Handoff::Inline => std::thread::Builder::new()
                    .name(format!("rodtrack-camera-{i}"))
                    .spawn(move || {
                        let _guard = guard;
                        capture.run(|cap| worker.handle(cap));
                    }),
                Handoff::Queue => {
                    let (cap_tx, cap_rx) = bounded::<Captured>(depth);
                    let mode = self.config.mode;
                    let stop = self.stop.clone();
                    let ctr = counters.clone();
                    let cpool = capture.pool.clone();
                    let h = std::thread::Builder::new()
                        .name(format!("rodtrack-capture-{i}"))
                        .spawn(move || {
                            capture.run(|cap| {
                                enqueue(&cap_tx, cap, mode, &stop, &ctr.cameras[i], &cpool)
                            });
                        })
                        .map_err(|e| {
                            IoError::Config(format!("cannot start capture thread: {e}"))
                        })?;
                    t.capture.push(h);
                    std::thread::Builder::new()
                        .name(format!("rodtrack-process-{i}"))
                        .spawn(move || {
                            let _guard = guard;
                            while let Some(cap) = recv_spin(&cap_rx, spin) {
                                if !worker.handle(cap) {
                                    break;
                                }
                            }
                        })
                }
            }
            .map_err(|e| IoError::Config(format!("cannot start processing thread: {e}")))?;
            t.processing.push(Some(handle));
        }
        Ok(t)
    }

    /// Waits for every camera to end (or the stop grace to pass), emitting the sets that are
    /// ready; then emits the rest and flushes. Returns whether the stop flag ended the run.
    fn main_loop(&self, rx: &Receiver<ToMain>, out: &mut impl Output, t: &mut Threads) -> bool {
        let mut ended = vec![false; t.processing.len()];
        let tick = (self.config.group_timeout / 4)
            .clamp(Duration::from_millis(1), Duration::from_millis(10));
        let mut stop_since: Option<Instant> = None;
        let mut stopped = false;
        while ended.iter().any(|e| !e) {
            if self.stop.load(Ordering::Relaxed) {
                stopped = true;
                let since = *stop_since.get_or_insert_with(Instant::now);
                if since.elapsed() > self.config.stop_grace {
                    break;
                }
            }
            match recv_spin_timeout(rx, self.config.spin, tick) {
                Ok(msg) => t.take(msg, &mut ended, out),
                Err(RecvTimeoutError::Timeout) => {}
                Err(RecvTimeoutError::Disconnected) => break,
            }
            out.with(|g, sink| g.emit_ready(Instant::now(), false, sink));
        }
        // Frames still queued (threads abandoned after the grace period are not waited for).
        while let Ok(msg) = rx.try_recv() {
            t.take(msg, &mut ended, out);
        }
        out.with(|g, sink| {
            g.emit_ready(Instant::now(), true, sink);
            g.flush(sink);
        });
        for h in t.capture.drain(..) {
            if h.is_finished() {
                let _ = h.join();
            }
        }
        stopped
    }
}

/// The threads of a run.
struct Threads {
    names: Vec<String>,
    pools: Vec<BufferPool>,
    errors: Vec<Arc<Mutex<Vec<String>>>>,
    /// Capture threads of [`Handoff::Queue`].
    capture: Vec<JoinHandle<()>>,
    /// Per camera, the thread that processes (and sends `Ended`).
    processing: Vec<Option<JoinHandle<()>>>,
}

impl Threads {
    /// Passes a message of the calling thread's queue on: a frame to the output stage; the
    /// end of a camera's processing thread to the grouping (after joining the thread).
    fn take(&mut self, msg: ToMain, ended: &mut [bool], out: &mut impl Output) {
        match msg {
            ToMain::Frame(camera, mut part) => {
                part.stamps.entered = Instant::now();
                out.with(|g, sink| g.add(camera, part, sink));
            }
            ToMain::Ended(c) => {
                ended[c] = true;
                if let Some(h) = self.processing[c].take() {
                    if h.join().is_err() {
                        push_error(
                            &self.errors[c],
                            format!("camera {c}: processing stage panicked"),
                        );
                    }
                }
                out.with(|g, _| g.ended[c] = true);
            }
        }
    }
}

struct Pending {
    key: u64,
    created: Instant,
    parts: Vec<Option<Part>>,
}

/// The output stage: grouping, fusion, writes, latency.
struct Grouper {
    config: PipelineConfig,
    n: usize,
    /// Per camera, the newest key it delivered.
    latest: Vec<Option<u64>>,
    /// Per camera, whether it ended.
    ended: Vec<bool>,
    /// Pending sets in key order (a handful at most).
    pending: VecDeque<Pending>,
    last_emitted: Option<u64>,
    fusion: Option<FusionFn>,
    info: FrameSetInfo,
    out: Vec<Measurement>,
    raw: Vec<Measurement>,
    fused: Vec<Measurement>,
    latency: LatencyHistogram,
    set_latency: LatencyHistogram,
    set_last_latency: LatencyHistogram,
    stages: StageHistograms,
    counters: Arc<PipelineCounters>,
    first_sink_error: Option<String>,
    vec_tx: Sender<Vec<Measurement>>,
    /// Recycled per-set part vectors.
    free_parts: Vec<Vec<Option<Part>>>,
}

impl Grouper {
    fn new(
        config: PipelineConfig,
        n: usize,
        fusion: Option<FusionFn>,
        counters: &Arc<PipelineCounters>,
        vec_tx: Sender<Vec<Measurement>>,
    ) -> Self {
        Grouper {
            config,
            n,
            latest: vec![None; n],
            ended: vec![false; n],
            pending: VecDeque::with_capacity(16),
            last_emitted: None,
            fusion,
            info: FrameSetInfo {
                frame_id: 0,
                timestamp_ns: Timestamp(0),
                frames: Vec::with_capacity(n),
                complete: false,
            },
            out: Vec::with_capacity(64),
            raw: Vec::with_capacity(64),
            fused: Vec::with_capacity(16),
            latency: LatencyHistogram::new(),
            set_latency: LatencyHistogram::new(),
            set_last_latency: LatencyHistogram::new(),
            stages: StageHistograms::default(),
            counters: counters.clone(),
            first_sink_error: None,
            vec_tx,
            free_parts: Vec::new(),
        }
    }

    fn tolerance(&self) -> u64 {
        match self.config.grouping {
            Grouping::FrameId => 0,
            Grouping::Timestamp { window_ns } => window_ns,
        }
    }

    fn key_of(&self, meta: &FrameMeta) -> u64 {
        match self.config.grouping {
            Grouping::FrameId => meta.frame_id,
            Grouping::Timestamp { .. } => meta.timestamp_ns.as_nanos(),
        }
    }

    fn index_of(&self, key: u64) -> Option<usize> {
        self.pending.iter().position(|p| p.key == key)
    }

    /// Returns a part's vectors to the pool.
    fn recycle(&mut self, part: Part) {
        for mut v in std::iter::once(part.rows).chain(part.filtered) {
            v.clear();
            let _ = self.vec_tx.try_send(v);
        }
    }

    /// Writes rows, counting them or the error.
    fn write(&mut self, rows: &[Measurement], sink: &mut dyn MeasurementSink) {
        match sink.write(rows) {
            Ok(()) => {
                self.counters
                    .rows_written
                    .fetch_add(rows.len() as u64, Ordering::Relaxed);
            }
            Err(e) => {
                self.counters.sink_errors.fetch_add(1, Ordering::Relaxed);
                self.first_sink_error.get_or_insert(e.to_string());
            }
        }
    }

    /// Records a frame's latency and its stages, its rows' write having run from
    /// `write_start` to `written`.
    fn record(&mut self, s: &Stamps, write_start: Instant, written: Instant) {
        let d = |a: Instant, b: Instant| b.saturating_duration_since(a);
        self.latency.record(d(s.available, written));
        self.stages.pickup.record(d(s.available, s.started));
        self.stages.process.record(d(s.started, s.processed));
        self.stages.handoff.record(d(s.processed, s.entered));
        self.stages.wait_set.record(d(s.entered, write_start));
        self.stages.write.record(d(write_start, written));
    }

    fn add(&mut self, camera: usize, mut part: Part, sink: &mut dyn MeasurementSink) {
        if self.config.write == WriteMode::PerCamera {
            let start = Instant::now();
            self.write(part.output(), sink);
            self.record(&part.stamps, start, Instant::now());
            // Written: only the measured rows stay, for the fusion.
            if let Some(mut v) = part.filtered.take() {
                v.clear();
                let _ = self.vec_tx.try_send(v);
            }
        }
        let k = self.key_of(&part.meta);
        let tol = self.tolerance();
        // The set this frame joins: same key (frame id), or within the window (timestamps).
        let mut target = match self.config.grouping {
            Grouping::FrameId => self.index_of(k).map(|_| k),
            Grouping::Timestamp { .. } => self
                .pending
                .iter()
                .find(|p| {
                    p.key >= k.saturating_sub(tol)
                        && p.key <= k.saturating_add(tol)
                        && p.parts[camera].is_none()
                })
                .map(|p| p.key),
        };
        // A camera delivering the same id twice: close the older set first.
        if let Some(t) = target {
            if self
                .index_of(t)
                .is_some_and(|i| self.pending[i].parts[camera].is_some())
            {
                self.emit_through(t, sink);
                target = None;
            }
        }
        self.latest[camera] = Some(self.latest[camera].map_or(k, |l| l.max(k)));
        let late = target.is_none() && self.last_emitted.is_some_and(|l| k <= l);
        let key = target.unwrap_or(k);
        let i = match self.index_of(key) {
            Some(i) => i,
            None => {
                let mut parts = self.free_parts.pop().unwrap_or_default();
                parts.clear();
                parts.resize_with(self.n, || None);
                let at = self.pending.partition_point(|p| p.key < key);
                self.pending.insert(
                    at,
                    Pending {
                        key,
                        created: Instant::now(),
                        parts,
                    },
                );
                at
            }
        };
        self.pending[i].parts[camera] = Some(part);
        if late {
            // Its set was already emitted: write this frame on its own.
            self.emit_key(key, sink);
        }
    }

    fn ready(&self, p: &Pending, now: Instant) -> bool {
        if now.duration_since(p.created) >= self.config.group_timeout {
            return true;
        }
        let tol = self.tolerance();
        (0..self.n).all(|c| {
            p.parts[c].is_some()
                || self.ended[c]
                || self.latest[c].is_some_and(|l| l > p.key.saturating_add(tol))
        })
    }

    /// Emits ready sets in key order, stopping at the first that is not ready (`all`: emit
    /// everything).
    fn emit_ready(&mut self, now: Instant, all: bool, sink: &mut dyn MeasurementSink) {
        while let Some(p) = self.pending.front() {
            if !all && !self.ready(p, now) {
                break;
            }
            let key = p.key;
            self.emit_key(key, sink);
        }
    }

    /// Emits every pending set up to and including `key`.
    fn emit_through(&mut self, key: u64, sink: &mut dyn MeasurementSink) {
        while let Some(p) = self.pending.front() {
            if p.key > key {
                break;
            }
            let k = p.key;
            self.emit_key(k, sink);
        }
    }

    fn emit_key(&mut self, key: u64, sink: &mut dyn MeasurementSink) {
        let Some(mut p) = self.index_of(key).and_then(|i| self.pending.remove(i)) else {
            return;
        };
        let start = Instant::now();
        let per_camera = self.config.write == WriteMode::PerCamera;
        self.last_emitted = Some(self.last_emitted.map_or(key, |l| l.max(key)));
        self.out.clear();
        let mut complete = true;
        for (c, part) in p.parts.iter().enumerate() {
            match part {
                Some(part) => {
                    if !per_camera {
                        self.out.extend_from_slice(part.output());
                    }
                }
                None => {
                    complete = false;
                    self.counters.cameras[c]
                        .missing_in_sets
                        .fetch_add(1, Ordering::Relaxed);
                }
            }
        }
        if complete {
            self.counters.sets_complete.fetch_add(1, Ordering::Relaxed);
        } else {
            self.counters
                .sets_incomplete
                .fetch_add(1, Ordering::Relaxed);
        }
        if let Some(fusion) = self.fusion.as_mut() {
            let first = p.parts.iter().flatten().next().map(|part| part.meta);
            self.info.frame_id = first.map_or(key, |m| m.frame_id);
            self.info.timestamp_ns = first.map_or(Timestamp(0), |m| m.timestamp_ns);
            self.info.frames.clear();
            self.info
                .frames
                .extend(p.parts.iter().map(|x| x.as_ref().map(|part| part.meta)));
            self.info.complete = complete;
            // The fusion's input: the measured rows (the same as the written ones without
            // camera filters).
            let measured = if !per_camera && p.parts.iter().flatten().all(|x| x.filtered.is_none())
            {
                &self.out
            } else {
                self.raw.clear();
                for part in p.parts.iter().flatten() {
                    self.raw.extend_from_slice(&part.rows);
                }
                &self.raw
            };
            self.fused.clear();
            fusion(&self.info, measured, &mut self.fused);
            self.out.extend_from_slice(&self.fused);
        }
        if !self.out.is_empty() {
            let out = std::mem::take(&mut self.out);
            self.write(&out, sink);
            self.out = out;
        }
        let now = Instant::now();
        if let Some(last) = p.parts.iter().flatten().map(|x| x.stamps.available).max() {
            self.set_last_latency
                .record(now.saturating_duration_since(last));
        }
        for part in p.parts.drain(..).flatten() {
            self.set_latency
                .record(now.saturating_duration_since(part.stamps.available));
            if !per_camera {
                self.record(&part.stamps, start, now);
            }
            self.recycle(part);
        }
        if self.free_parts.len() < 64 {
            self.free_parts.push(p.parts);
        }
    }

    fn flush(&mut self, sink: &mut dyn MeasurementSink) {
        if let Err(e) = sink.flush() {
            self.counters.sink_errors.fetch_add(1, Ordering::Relaxed);
            self.first_sink_error.get_or_insert(e.to_string());
        }
    }

    fn finish(
        &mut self,
        counters: &PipelineCounters,
        threads: &Threads,
        started: Instant,
        stopped: bool,
    ) -> PipelineReport {
        let cameras = (0..self.n)
            .map(|i| {
                let c = &counters.cameras[i];
                CameraStats {
                    name: threads.names.get(i).cloned().unwrap_or_default(),
                    frames_read: c.frames_read.load(Ordering::Relaxed),
                    frames_processed: c.frames_processed.load(Ordering::Relaxed),
                    frames_dropped: c.frames_dropped.load(Ordering::Relaxed),
                    frames_skipped: c.frames_skipped.load(Ordering::Relaxed),
                    bad_frames: c.bad_frames.load(Ordering::Relaxed),
                    missing_in_sets: c.missing_in_sets.load(Ordering::Relaxed),
                    buffers_allocated: threads.pools.get(i).map_or(0, BufferPool::created),
                    errors: threads
                        .errors
                        .get(i)
                        .map(|e| lock(e).clone())
                        .unwrap_or_default(),
                }
            })
            .collect();
        PipelineReport {
            cameras,
            sets_complete: counters.sets_complete.load(Ordering::Relaxed),
            sets_incomplete: counters.sets_incomplete.load(Ordering::Relaxed),
            rows_written: counters.rows_written.load(Ordering::Relaxed),
            sink_errors: counters.sink_errors.load(Ordering::Relaxed),
            first_sink_error: self.first_sink_error.take(),
            latency: self.latency.summary(),
            set_latency: self.set_latency.summary(),
            set_last_latency: self.set_last_latency.summary(),
            stages: self.stages.summary(),
            elapsed: started.elapsed(),
            stopped,
        }
    }
}
