//! The capture loop: a camera's source read frame by frame (paced in [`RunMode::Paced`]), and the
//! bounded queue to its processing thread ([`super::Handoff::Queue`]).

use super::config::RunMode;
use super::report::{push_error, CameraCounters, PipelineCounters};
use crate::frame::{BufferPool, FrameBuffer, Timestamp};
use crate::source::FrameSource;
use crate::IoError;
use crossbeam_channel::{SendTimeoutError, Sender, TrySendError};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

#[cfg(doc)]
use super::Handoff;

/// Placeholder frame id while a source reads (see the capture loop).
const UNKNOWN_ID: u64 = u64::MAX;

/// A frame handed from capture to processing.
pub(super) struct Captured {
    pub(super) buf: FrameBuffer,
    pub(super) result: Result<(), IoError>,
    pub(super) available: Instant,
}

/// Reads a source until it ends, fails or `stop` is set, and passes every frame to `emit`
/// (which returns false to end the loop).
pub(super) struct Capture {
    pub(super) camera: usize,
    pub(super) source: Box<dyn FrameSource>,
    pub(super) mode: RunMode,
    pub(super) stop: Arc<AtomicBool>,
    pub(super) counters: Arc<PipelineCounters>,
    pub(super) errors: Arc<Mutex<Vec<String>>>,
    pub(super) pool: BufferPool,
}

impl Capture {
    pub(super) fn run(mut self, mut emit: impl FnMut(Captured) -> bool) {
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
            if let RunMode::Paced { speed } = self.mode {
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
pub(super) fn enqueue(
    tx: &Sender<Captured>,
    msg: Captured,
    mode: RunMode,
    stop: &AtomicBool,
    counters: &CameraCounters,
    pool: &BufferPool,
) -> bool {
    match mode {
        RunMode::Live | RunMode::Paced { .. } => match tx.try_send(msg) {
            Ok(()) => true,
            Err(TrySendError::Full(m)) => {
                counters.frames_dropped.fetch_add(1, Ordering::Relaxed);
                pool.put(m.buf);
                true
            }
            Err(TrySendError::Disconnected(_)) => false,
        },
        RunMode::Batch => {
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
