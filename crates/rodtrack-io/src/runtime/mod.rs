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
//! - Capture never waits for a slow consumer in [`RunMode::Live`] and [`RunMode::Paced`] with
//!   [`Handoff::Queue`]: when the queue is full the frame is dropped and counted.
//!   [`RunMode::Batch`] (files read as fast as possible) blocks instead and never drops. With
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
//! use rodtrack_io::runtime::{RunMode, Pipeline, PipelineConfig};
//! use rodtrack_io::{CsvSink, OpenOptions, SourceFactory};
//!
//! # fn main() -> Result<(), rodtrack_io::IoError> {
//! let factory = SourceFactory::new();
//! let mut pipeline = Pipeline::new(PipelineConfig { mode: RunMode::Paced { speed: 1.0 }, ..Default::default() });
//! for input in ["rec/cam0", "raw:rec/cam1.raw?width=1440&height=1080&format=bayer_rggb8"] {
//!     let source = factory.open(input, &OpenOptions::default())?;
//!     pipeline.add_camera(source, Box::new(|meta, frame, rows| {
//!         // The tracker goes here; a bad frame arrives as Err and can be reported as such.
//!         let status = if frame.is_ok() { Status::NotFound } else { Status::BadFrame };
//!         let t = meta.timestamp_ns;
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
mod capture;
mod config;
mod grouper;
mod latency;
mod report;
mod sync;
#[cfg(test)]
mod tests;
mod worker;

pub use budget::{track_memory_budget, BASE_BYTES};
pub use config::{
    CameraFilterFn, CameraRowsFn, FrameHookFn, FrameSetInfo, FusionFn, Grouping, Handoff,
    PipelineConfig, ProcessFn, RunMode, WriteMode,
};
pub use latency::{LatencyHistogram, LatencyStages, LatencySummary};
pub use report::{CameraCounters, CameraStats, PipelineCounters, PipelineReport};

use crate::frame::BufferPool;
use crate::sink::MeasurementSink;
use crate::source::FrameSource;
use crate::IoError;
use capture::{enqueue, Capture, Captured};
use crossbeam_channel::{bounded, Receiver, RecvTimeoutError, Sender};
use grouper::Grouper;
use report::push_error;
use rodtrack_core::Measurement;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};
use sync::{lock, recv_spin, recv_spin_timeout};
use worker::{Deliver, Direct, EndGuard, Shared, ToCaller, ToMain, Worker};

/// A camera as added: its source and stages.
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
    camera_rows: Option<CameraRowsFn>,
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

impl Pipeline {
    /// An empty pipeline.
    pub fn new(config: PipelineConfig) -> Self {
        Pipeline {
            config,
            cameras: Vec::new(),
            fusion: None,
            camera_rows: None,
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

    /// Sets the stage that sees (and may change) each set's camera rows after the fusion (see
    /// [`CameraRowsFn`]; [`WriteMode::Set`] only).
    pub fn set_camera_rows_after_fusion(&mut self, f: CameraRowsFn) {
        self.camera_rows = Some(f);
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
        if let RunMode::Paced { speed } = self.config.mode {
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
        let grouper = self.grouper(&counters, vec_tx);
        let threads = self.spawn(&counters, &main_tx, &vec_rx, |_| ToCaller(main_tx.clone()))?;
        drop(main_tx);
        let mut threads = threads;
        let mut out = Local { grouper, sink };
        let stopped = self.main_loop(&main_rx, &mut out, &mut threads);
        let cameras = threads.camera_stats(&counters);
        Ok(out.grouper.finish(&counters, cameras, started, stopped))
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
        let grouper = self.grouper(&counters, vec_tx);
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
        let cameras = threads.camera_stats(&counters);
        let report = guard.grouper.finish(&counters, cameras, started, stopped);
        Ok((report, sink))
    }

    /// The frame-set grouper of a run, taking the fusion and camera-rows hooks.
    fn grouper(
        &mut self,
        counters: &Arc<PipelineCounters>,
        vec_tx: Sender<Vec<Measurement>>,
    ) -> Grouper {
        Grouper::new(
            self.config,
            self.cameras.len(),
            self.fusion.take(),
            self.camera_rows.take(),
            counters,
            vec_tx,
        )
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
    /// The final numbers of each camera.
    fn camera_stats(&self, counters: &PipelineCounters) -> Vec<CameraStats> {
        (0..counters.cameras.len())
            .map(|i| {
                let c = &counters.cameras[i];
                CameraStats {
                    name: self.names.get(i).cloned().unwrap_or_default(),
                    frames_read: c.frames_read.load(Ordering::Relaxed),
                    frames_processed: c.frames_processed.load(Ordering::Relaxed),
                    frames_dropped: c.frames_dropped.load(Ordering::Relaxed),
                    frames_skipped: c.frames_skipped.load(Ordering::Relaxed),
                    bad_frames: c.bad_frames.load(Ordering::Relaxed),
                    missing_in_sets: c.missing_in_sets.load(Ordering::Relaxed),
                    frames_late: c.frames_late.load(Ordering::Relaxed),
                    buffers_allocated: self.pools.get(i).map_or(0, BufferPool::created),
                    errors: self
                        .errors
                        .get(i)
                        .map(|e| lock(e).clone())
                        .unwrap_or_default(),
                }
            })
            .collect()
    }

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
