//! The runtime pipeline: one capture thread per camera, bounded queues, one processing thread
//! per camera, frame-set grouping and the sink in the calling thread.
//!
//! ```text
//!  source 0 -> [capture 0] -> queue (depth d) -> [process 0] --\
//!                                                                >-> [group by frame id] -> fusion -> sink
//!  source 1 -> [capture 1] -> queue (depth d) -> [process 1] --/
//! ```
//!
//! - Capture never waits for a slow consumer in [`Mode::Live`] and [`Mode::Paced`]: when the
//!   queue is full the frame is dropped and counted. [`Mode::Batch`] (files read as fast as
//!   possible) blocks instead and never drops.
//! - Frame buffers and row vectors are recycled through pools: steady state allocates no
//!   frame memory.
//! - A frame set is emitted when every camera has delivered its frame for it, or has moved past
//!   it (a newer id arrived: the camera missed this frame), or has ended, or after
//!   [`PipelineConfig::group_timeout`]. Sets are emitted in order; missing frames are counted
//!   per camera.
//! - Latency: from the moment a frame is available (decoded, and released in paced mode) to the
//!   return of the sink's `write` for its set.
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

mod latency;

pub use latency::{LatencyHistogram, LatencySummary};

use crate::frame::{BufferPool, FrameBuffer, FrameMeta, Timestamp};
use crate::sink::MeasurementSink;
use crate::source::FrameSource;
use crate::IoError;
use crossbeam_channel::{bounded, RecvTimeoutError, SendTimeoutError, Sender, TrySendError};
use rodtrack_core::{FrameView, Measurement};
use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// A camera's processing stage (the tracker): given a frame's metadata and its view (or the
/// error that made it bad), appends measurement rows to the vector (which arrives empty).
pub type ProcessFn =
    Box<dyn FnMut(&FrameMeta, Result<FrameView<'_>, &IoError>, &mut Vec<Measurement>) + Send>;

/// Fusion of a frame set: given the set and the rows of all its cameras, appends extra rows
/// (e.g. `camera = fused`).
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
    /// Frames queued per camera between capture and processing (at least 1).
    pub queue_depth: usize,
    /// Frame matching.
    pub grouping: Grouping,
    /// Longest wait for the missing frames of a set.
    pub group_timeout: Duration,
    /// After stop, how long to wait for threads (a camera stuck in a read) before giving up on
    /// them.
    pub stop_grace: Duration,
}

impl Default for PipelineConfig {
    fn default() -> Self {
        PipelineConfig {
            mode: Mode::Batch,
            queue_depth: 4,
            grouping: Grouping::FrameId,
            group_timeout: Duration::from_millis(200),
            stop_grace: Duration::from_secs(2),
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
    /// Frame latency, availability to sink write.
    pub latency: LatencySummary,
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
            writeln!(
                f,
                "  camera {i} ({}): {} read, {} processed, {} dropped, {} bad, {} missing from sets",
                c.name, c.frames_read, c.frames_processed, c.frames_dropped, c.bad_frames, c.missing_in_sets
            )?;
            for e in &c.errors {
                writeln!(f, "    {e}")?;
            }
        }
        write!(f, "  latency: {}", self.latency)
    }
}

struct Camera {
    source: Box<dyn FrameSource>,
    process: ProcessFn,
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

/// A processed frame handed to the grouper.
enum ToGroup {
    Frame {
        camera: usize,
        meta: FrameMeta,
        rows: Vec<Measurement>,
        available: Instant,
    },
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

/// Sends `End` when the processing thread ends, panics included.
struct EndGuard {
    camera: usize,
    tx: Sender<ToGroup>,
}

impl Drop for EndGuard {
    fn drop(&mut self) {
        let _ = self.tx.send(ToGroup::Ended(self.camera));
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

/// One camera's contribution to a set: metadata, rows, time the frame became available.
type Part = Option<(FrameMeta, Vec<Measurement>, Instant)>;

struct Pending {
    created: Instant,
    parts: Vec<Part>,
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
        self.cameras.push(Camera { source, process });
        (self.cameras.len() - 1) as u32
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

    /// Runs until every source ends or the stop flag is set; writes every frame set to `sink`
    /// and flushes it. Blocks the calling thread. Errors only on an invalid configuration;
    /// bad frames, failed sources and sink errors are counted in the report.
    pub fn run(mut self, sink: &mut dyn MeasurementSink) -> Result<PipelineReport, IoError> {
        let n = self.cameras.len();
        if n == 0 {
            return Err(IoError::Config("no cameras".into()));
        }
        if let Mode::Paced { speed } = self.config.mode {
            if !(speed > 0.0 && speed.is_finite()) {
                return Err(IoError::Config(format!(
                    "paced speed must be > 0, got {speed}"
                )));
            }
        }
        let counters = self.counters();
        let started = Instant::now();
        let depth = self.config.queue_depth.max(1);
        let (group_tx, group_rx) = bounded::<ToGroup>(256 * n);
        let (vec_tx, vec_rx) = bounded::<Vec<Measurement>>(64 * n);
        let mut names = Vec::with_capacity(n);
        let mut pools = Vec::with_capacity(n);
        let mut errors = Vec::with_capacity(n);
        let mut handles: Vec<JoinHandle<()>> = Vec::with_capacity(2 * n);
        let mut proc_handles: Vec<Option<JoinHandle<()>>> = Vec::with_capacity(n);
        let mut ended = vec![false; n];
        for (i, cam) in self.cameras.into_iter().enumerate() {
            let Camera {
                mut source,
                mut process,
            } = cam;
            names.push(source.info().name);
            let pool = BufferPool::new(depth + 3);
            pools.push(pool.clone());
            let errs = Arc::new(Mutex::new(Vec::new()));
            errors.push(errs.clone());
            let (cap_tx, cap_rx) = bounded::<Captured>(depth);
            // Capture thread.
            let stop = self.stop.clone();
            let ctr = counters.clone();
            let cpool = pool.clone();
            let cerrs = errs.clone();
            let mode = self.config.mode;
            let h = std::thread::Builder::new()
                .name(format!("rodtrack-capture-{i}"))
                .spawn(move || {
                    let c = &ctr.cameras[i];
                    let mut pace: Option<(Instant, u64)> = None;
                    let mut last: Option<(u64, Timestamp)> = None;
                    while !stop.load(Ordering::Relaxed) {
                        let mut buf = cpool.get();
                        buf.meta.camera = i as u32;
                        // A bad frame whose source could not tell its id gets the next one.
                        buf.meta.frame_id = UNKNOWN_ID;
                        let result = match source.next_frame(&mut buf) {
                            Ok(None) => break,
                            Ok(Some(())) => Ok(()),
                            Err(e) => Err(e),
                        };
                        buf.meta.camera = i as u32;
                        if buf.meta.frame_id == UNKNOWN_ID {
                            buf.meta.frame_id = last.map_or(0, |(id, _)| id + 1);
                            buf.meta.timestamp_ns = last.map_or(Timestamp(0), |(_, t)| t);
                        }
                        last = Some((buf.meta.frame_id, buf.meta.timestamp_ns));
                        c.frames_read.fetch_add(1, Ordering::Relaxed);
                        if let Err(e) = &result {
                            c.bad_frames.fetch_add(1, Ordering::Relaxed);
                            push_error(&cerrs, e.to_string());
                            if e.is_fatal() {
                                break;
                            }
                        }
                        if let Mode::Paced { speed } = mode {
                            let ts = buf.meta.timestamp_ns.as_nanos();
                            let (t0, ts0) = *pace.get_or_insert((Instant::now(), ts));
                            let dt = ts.saturating_sub(ts0) as f64 / speed;
                            if !sleep_until(t0 + Duration::from_nanos(dt as u64), &stop) {
                                c.frames_dropped.fetch_add(1, Ordering::Relaxed);
                                break;
                            }
                        }
                        let msg = Captured {
                            buf,
                            result,
                            available: Instant::now(),
                        };
                        match mode {
                            Mode::Live | Mode::Paced { .. } => match cap_tx.try_send(msg) {
                                Ok(()) => {}
                                Err(TrySendError::Full(m)) => {
                                    c.frames_dropped.fetch_add(1, Ordering::Relaxed);
                                    cpool.put(m.buf);
                                }
                                Err(TrySendError::Disconnected(_)) => break,
                            },
                            Mode::Batch => {
                                let mut m = msg;
                                loop {
                                    match cap_tx.send_timeout(m, Duration::from_millis(20)) {
                                        Ok(()) => break,
                                        Err(SendTimeoutError::Timeout(back)) => {
                                            if stop.load(Ordering::Relaxed) {
                                                c.frames_dropped.fetch_add(1, Ordering::Relaxed);
                                                break;
                                            }
                                            m = back;
                                        }
                                        Err(SendTimeoutError::Disconnected(_)) => return,
                                    }
                                }
                            }
                        }
                    }
                })
                .map_err(|e| IoError::Config(format!("cannot start capture thread: {e}")))?;
            handles.push(h);
            // Processing thread.
            let ctr = counters.clone();
            let ppool = pool;
            let perrs = errs;
            let gtx = group_tx.clone();
            let vtx = vec_tx.clone();
            let vrx = vec_rx.clone();
            let h = std::thread::Builder::new()
                .name(format!("rodtrack-process-{i}"))
                .spawn(move || {
                    let _guard = EndGuard {
                        camera: i,
                        tx: gtx.clone(),
                    };
                    let c = &ctr.cameras[i];
                    for cap in cap_rx.iter() {
                        let mut rows = vrx.try_recv().unwrap_or_default();
                        rows.clear();
                        let meta = cap.buf.meta;
                        match cap.result {
                            Ok(()) => match cap.buf.try_view() {
                                Ok(view) => process(&meta, Ok(view), &mut rows),
                                Err(e) => {
                                    c.bad_frames.fetch_add(1, Ordering::Relaxed);
                                    push_error(&perrs, e.to_string());
                                    process(&meta, Err(&e), &mut rows);
                                }
                            },
                            Err(e) => process(&meta, Err(&e), &mut rows),
                        }
                        c.frames_processed.fetch_add(1, Ordering::Relaxed);
                        ppool.put(cap.buf);
                        let msg = ToGroup::Frame {
                            camera: i,
                            meta,
                            rows,
                            available: cap.available,
                        };
                        if gtx.send(msg).is_err() {
                            break;
                        }
                    }
                    drop(vtx);
                })
                .map_err(|e| IoError::Config(format!("cannot start processing thread: {e}")))?;
            proc_handles.push(Some(h));
        }
        drop(group_tx);

        // Grouping and output, in this thread.
        let mut g = Grouper {
            config: self.config,
            n,
            latest: vec![None; n],
            pending: BTreeMap::new(),
            last_emitted: None,
            fusion: self.fusion,
            out: Vec::new(),
            fused: Vec::new(),
            latency: LatencyHistogram::new(),
            counters: counters.clone(),
            first_sink_error: None,
            vec_tx,
            free_parts: Vec::new(),
        };
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
            match group_rx.recv_timeout(tick) {
                Ok(ToGroup::Frame {
                    camera,
                    meta,
                    rows,
                    available,
                }) => g.add(camera, meta, rows, available, sink),
                Ok(ToGroup::Ended(c)) => {
                    ended[c] = true;
                    if let Some(h) = proc_handles[c].take() {
                        if h.join().is_err() {
                            push_error(
                                &errors[c],
                                format!("camera {c}: processing stage panicked"),
                            );
                        }
                    }
                }
                Err(RecvTimeoutError::Timeout) => {}
                Err(RecvTimeoutError::Disconnected) => break,
            }
            g.emit_ready(Instant::now(), &ended, false, sink);
        }
        // Frames still queued (threads abandoned after the grace period are not waited for).
        while let Ok(msg) = group_rx.try_recv() {
            if let ToGroup::Frame {
                camera,
                meta,
                rows,
                available,
            } = msg
            {
                g.add(camera, meta, rows, available, sink);
            }
        }
        g.emit_ready(Instant::now(), &ended, true, sink);
        if let Err(e) = sink.flush() {
            counters.sink_errors.fetch_add(1, Ordering::Relaxed);
            g.first_sink_error.get_or_insert(e.to_string());
        }
        for h in handles {
            if h.is_finished() {
                let _ = h.join();
            }
        }
        let cameras = (0..n)
            .map(|i| {
                let c = &counters.cameras[i];
                CameraStats {
                    name: names[i].clone(),
                    frames_read: c.frames_read.load(Ordering::Relaxed),
                    frames_processed: c.frames_processed.load(Ordering::Relaxed),
                    frames_dropped: c.frames_dropped.load(Ordering::Relaxed),
                    bad_frames: c.bad_frames.load(Ordering::Relaxed),
                    missing_in_sets: c.missing_in_sets.load(Ordering::Relaxed),
                    buffers_allocated: pools[i].created(),
                    errors: errors[i].lock().map(|e| e.clone()).unwrap_or_default(),
                }
            })
            .collect();
        let report = PipelineReport {
            cameras,
            sets_complete: counters.sets_complete.load(Ordering::Relaxed),
            sets_incomplete: counters.sets_incomplete.load(Ordering::Relaxed),
            rows_written: counters.rows_written.load(Ordering::Relaxed),
            sink_errors: counters.sink_errors.load(Ordering::Relaxed),
            first_sink_error: g.first_sink_error.take(),
            latency: g.latency.summary(),
            elapsed: started.elapsed(),
            stopped,
        };
        Ok(report)
    }
}

struct Grouper {
    config: PipelineConfig,
    n: usize,
    /// Per camera, the newest key it delivered.
    latest: Vec<Option<u64>>,
    pending: BTreeMap<u64, Pending>,
    last_emitted: Option<u64>,
    fusion: Option<FusionFn>,
    out: Vec<Measurement>,
    fused: Vec<Measurement>,
    latency: LatencyHistogram,
    counters: Arc<PipelineCounters>,
    first_sink_error: Option<String>,
    vec_tx: Sender<Vec<Measurement>>,
    /// Recycled per-set part vectors.
    free_parts: Vec<Vec<Part>>,
}

impl Grouper {
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

    fn add(
        &mut self,
        camera: usize,
        meta: FrameMeta,
        rows: Vec<Measurement>,
        available: Instant,
        sink: &mut dyn MeasurementSink,
    ) {
        let k = self.key_of(&meta);
        let tol = self.tolerance();
        // The set this frame joins: same key (frame id), or within the window (timestamps).
        let mut target = match self.config.grouping {
            Grouping::FrameId => self.pending.contains_key(&k).then_some(k),
            Grouping::Timestamp { .. } => self
                .pending
                .range(k.saturating_sub(tol)..=k.saturating_add(tol))
                .find(|(_, p)| p.parts[camera].is_none())
                .map(|(key, _)| *key),
        };
        // A camera delivering the same id twice: close the older set first.
        if let Some(t) = target {
            if self
                .pending
                .get(&t)
                .is_some_and(|p| p.parts[camera].is_some())
            {
                self.emit_through(t, sink);
                target = None;
            }
        }
        self.latest[camera] = Some(self.latest[camera].map_or(k, |l| l.max(k)));
        let late = target.is_none() && self.last_emitted.is_some_and(|l| k <= l);
        let key = target.unwrap_or(k);
        let n = self.n;
        let free = &mut self.free_parts;
        let p = self.pending.entry(key).or_insert_with(|| {
            let mut parts = free.pop().unwrap_or_default();
            parts.clear();
            parts.resize_with(n, || None);
            Pending {
                created: Instant::now(),
                parts,
            }
        });
        p.parts[camera] = Some((meta, rows, available));
        if late {
            // Its set was already emitted: write this frame on its own.
            self.emit_key(key, sink);
        }
    }

    fn ready(&self, key: u64, p: &Pending, now: Instant, ended: &[bool]) -> bool {
        if now.duration_since(p.created) >= self.config.group_timeout {
            return true;
        }
        let tol = self.tolerance();
        (0..self.n).all(|c| {
            p.parts[c].is_some()
                || ended[c]
                || self.latest[c].is_some_and(|l| l > key.saturating_add(tol))
        })
    }

    /// Emits ready sets in key order, stopping at the first that is not ready (`all`: emit
    /// everything).
    fn emit_ready(
        &mut self,
        now: Instant,
        ended: &[bool],
        all: bool,
        sink: &mut dyn MeasurementSink,
    ) {
        while let Some((&key, p)) = self.pending.first_key_value() {
            if !all && !self.ready(key, p, now, ended) {
                break;
            }
            self.emit_key(key, sink);
        }
    }

    /// Emits every pending set up to and including `key`.
    fn emit_through(&mut self, key: u64, sink: &mut dyn MeasurementSink) {
        while let Some((&k, _)) = self.pending.first_key_value() {
            if k > key {
                break;
            }
            self.emit_key(k, sink);
        }
    }

    fn emit_key(&mut self, key: u64, sink: &mut dyn MeasurementSink) {
        let Some(mut p) = self.pending.remove(&key) else {
            return;
        };
        self.last_emitted = Some(self.last_emitted.map_or(key, |l| l.max(key)));
        self.out.clear();
        let mut complete = true;
        for (c, part) in p.parts.iter().enumerate() {
            match part {
                Some((_, rows, _)) => self.out.extend_from_slice(rows),
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
            let first = p.parts.iter().flatten().next().map(|(m, _, _)| *m);
            let info = FrameSetInfo {
                frame_id: first.map_or(key, |m| m.frame_id),
                timestamp_ns: first.map_or(Timestamp(0), |m| m.timestamp_ns),
                frames: p
                    .parts
                    .iter()
                    .map(|x| x.as_ref().map(|(m, _, _)| *m))
                    .collect(),
                complete,
            };
            self.fused.clear();
            fusion(&info, &self.out, &mut self.fused);
            self.out.extend_from_slice(&self.fused);
        }
        if !self.out.is_empty() {
            match sink.write(&self.out) {
                Ok(()) => {
                    self.counters
                        .rows_written
                        .fetch_add(self.out.len() as u64, Ordering::Relaxed);
                }
                Err(e) => {
                    self.counters.sink_errors.fetch_add(1, Ordering::Relaxed);
                    self.first_sink_error.get_or_insert(e.to_string());
                }
            }
        }
        let now = Instant::now();
        for (_, mut rows, available) in p.parts.drain(..).flatten() {
            self.latency.record(now.duration_since(available));
            rows.clear();
            let _ = self.vec_tx.try_send(rows);
        }
        if self.free_parts.len() < 64 {
            self.free_parts.push(p.parts);
        }
    }
}
