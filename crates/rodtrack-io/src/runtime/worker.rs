//! A camera's processing stage as run by its thread ([`Worker`]), and where its processed
//! frames go: to the calling thread ([`ToCaller`]) or straight into the output stage under a
//! lock ([`Direct`]).

use super::capture::Captured;
use super::config::{CameraFilterFn, FrameHookFn, ProcessFn};
use super::grouper::{Grouper, Part, Stamps};
use super::report::{push_error, PipelineCounters};
use super::sync::lock_spin;
use crate::frame::BufferPool;
use crate::sink::MeasurementSink;
use crossbeam_channel::{Receiver, Sender};
use rodtrack_core::Measurement;
use std::sync::atomic::Ordering;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

#[cfg(doc)]
use super::Pipeline;

/// A message to the calling thread.
pub(super) enum ToMain {
    /// A processed frame ([`Pipeline::run`] only).
    Frame(usize, Part),
    /// A camera's processing thread ended.
    Ended(usize),
}

/// Sends `Ended` when the processing thread ends, panics included.
pub(super) struct EndGuard {
    pub(super) camera: usize,
    pub(super) tx: Sender<ToMain>,
}

impl Drop for EndGuard {
    fn drop(&mut self) {
        let _ = self.tx.send(ToMain::Ended(self.camera));
    }
}

/// Where a processed frame goes: to the calling thread, or straight into the output stage.
pub(super) trait Deliver: Send + 'static {
    /// False when the output is gone (the run ended).
    fn deliver(&self, camera: usize, part: Part) -> bool;
}

/// [`Pipeline::run`]: a hand-off to the calling thread.
pub(super) struct ToCaller(pub(super) Sender<ToMain>);

impl Deliver for ToCaller {
    fn deliver(&self, camera: usize, part: Part) -> bool {
        self.0.send(ToMain::Frame(camera, part)).is_ok()
    }
}

/// The output stage with its sink, shared by the camera threads ([`Pipeline::run_direct`]).
pub(super) struct Shared<S> {
    pub(super) grouper: Grouper,
    /// `None` once the run has ended.
    pub(super) sink: Option<S>,
}

/// [`Pipeline::run_direct`]: the camera's thread runs the output stage.
pub(super) struct Direct<S> {
    pub(super) shared: Arc<Mutex<Shared<S>>>,
    pub(super) spin: Duration,
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

/// A camera's processing stage as run by its thread.
pub(super) struct Worker<D> {
    pub(super) camera: usize,
    pub(super) process: ProcessFn,
    pub(super) filter: Option<CameraFilterFn>,
    pub(super) hook: Option<FrameHookFn>,
    pub(super) counters: Arc<PipelineCounters>,
    pub(super) errors: Arc<Mutex<Vec<String>>>,
    pub(super) pool: BufferPool,
    pub(super) vec_rx: Receiver<Vec<Measurement>>,
    pub(super) deliver: D,
}

impl<D: Deliver> Worker<D> {
    fn rows_vec(&self) -> Vec<Measurement> {
        let mut v = self.vec_rx.try_recv().unwrap_or_default();
        v.clear();
        v
    }

    /// Processes a frame and delivers its rows; false when the output is gone.
    pub(super) fn handle(&mut self, mut cap: Captured) -> bool {
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
