//! A camera node's preview frames (`.../preview`, layout in [`crate::preview`]).
//!
//! The tracking thread's cost: one relaxed atomic load per frame. A few times per second (the
//! preview rate) the preview thread raises a "want" flag; the tracking thread's next frame is
//! then copied into the preview's own buffer (`try_lock`: skipped if the preview thread holds
//! it; a plain copy into a buffer reused from one preview to the next, so no allocation after
//! the first), and the preview thread downscales it, encodes it and publishes it, on its own
//! time. The publisher drops a preview rather than wait when the network is congested.

use crate::preview::{encode_preview, header_of, PREVIEW_MAX_WIDTH_PX};
use crate::ZenohError;
use rodtrack_core::preview::{preview_into, Preview};
use rodtrack_io::FrameBuffer;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};
use zenoh::bytes::Encoding;
use zenoh::qos::{CongestionControl, Priority};
use zenoh::Wait;

/// How long the preview thread waits for a frame it asked for before asking again.
const FRAME_WAIT: Duration = Duration::from_secs(1);

#[derive(Default)]
struct Slot {
    frame: FrameBuffer,
    fresh: bool,
    stop: bool,
}

struct Shared {
    want: AtomicBool,
    slot: Mutex<Slot>,
    wake: Condvar,
    published: AtomicU64,
    errors: AtomicU64,
}

fn lock(m: &Mutex<Slot>) -> MutexGuard<'_, Slot> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// The preview thread and what the tracking thread shares with it. Dropped, it stops the
/// thread (and undeclares the publisher) before returning.
pub(crate) struct PreviewFeed {
    shared: Arc<Shared>,
    thread: Option<JoinHandle<()>>,
}

impl PreviewFeed {
    /// Declares the publisher on `key` and starts the preview thread at `fps` previews per
    /// second of camera `camera`.
    pub(crate) fn start(
        session: &zenoh::Session,
        key: String,
        camera: u32,
        fps: f64,
    ) -> Result<PreviewFeed, ZenohError> {
        if !(fps.is_finite() && fps > 0.0 && fps <= 1000.0) {
            return Err(ZenohError::Invalid(format!(
                "preview rate {fps} per second: expected more than 0 and at most 1000"
            )));
        }
        let publisher = session
            .declare_publisher(key.clone())
            .encoding(Encoding::APPLICATION_OCTET_STREAM)
            .congestion_control(CongestionControl::Drop)
            .priority(Priority::DataLow)
            .wait()
            .map_err(|e| ZenohError::zenoh(format!("declaring a publisher on {key}"), e))?;
        let shared = Arc::new(Shared {
            want: AtomicBool::new(false),
            slot: Mutex::new(Slot::default()),
            wake: Condvar::new(),
            published: AtomicU64::new(0),
            errors: AtomicU64::new(0),
        });
        let sh = shared.clone();
        let interval = Duration::from_secs_f64(1.0 / fps);
        let thread = std::thread::Builder::new()
            .name(format!("rodtrack-preview-{camera}"))
            .spawn(move || run(&sh, &publisher, camera, interval))
            .map_err(|e| ZenohError::Invalid(format!("starting the preview thread: {e}")))?;
        Ok(PreviewFeed {
            shared,
            thread: Some(thread),
        })
    }

    /// The tracking thread's side, once per frame: one atomic load unless a preview is due.
    #[inline]
    pub(crate) fn offer(&self, buf: &FrameBuffer) {
        let sh = &self.shared;
        if !sh.want.load(Ordering::Relaxed) {
            return;
        }
        if let Ok(mut s) = sh.slot.try_lock() {
            s.frame.meta = buf.meta;
            s.frame.data.clear();
            s.frame.data.extend_from_slice(&buf.data);
            s.fresh = true;
            sh.want.store(false, Ordering::Relaxed);
            drop(s);
            sh.wake.notify_one();
        }
    }

    /// Previews published so far.
    pub(crate) fn published(&self) -> u64 {
        self.shared.published.load(Ordering::Relaxed)
    }

    /// Previews that could not be made or published.
    pub(crate) fn errors(&self) -> u64 {
        self.shared.errors.load(Ordering::Relaxed)
    }
}

impl Drop for PreviewFeed {
    fn drop(&mut self) {
        lock(&self.shared.slot).stop = true;
        self.shared.wake.notify_all();
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// Waits on the slot while `waiting` holds, at most until `until`.
fn wait_while<'a>(
    sh: &Shared,
    mut s: MutexGuard<'a, Slot>,
    until: Instant,
    waiting: impl Fn(&Slot) -> bool,
) -> MutexGuard<'a, Slot> {
    loop {
        let now = Instant::now();
        if !waiting(&s) || now >= until {
            return s;
        }
        s = sh
            .wake
            .wait_timeout(s, until - now)
            .map_or_else(|e| e.into_inner().0, |r| r.0);
    }
}

/// Puts the calling thread in Linux's idle scheduling class (`SCHED_IDLE`): it then runs only
/// on a core no other thread wants, and a woken tracking, network or fusion thread of any
/// process on the machine takes the core from it at once. Elsewhere, or if refused, the
/// lowest nice value. Returns whether the class was set.
#[allow(unsafe_code)]
fn yield_to_everything() -> bool {
    #[cfg(target_os = "linux")]
    {
        let param = libc::sched_param { sched_priority: 0 };
        // SAFETY: `sched_setscheduler` reads `param` (a valid, initialised struct that
        // outlives the call); pid 0 is the calling thread. No memory is shared with it.
        if unsafe { libc::sched_setscheduler(0, libc::SCHED_IDLE, &param) } == 0 {
            return true;
        }
    }
    #[cfg(unix)]
    {
        // SAFETY: plain integer arguments; on Linux `who` 0 is the calling thread.
        let _ = unsafe { libc::setpriority(libc::PRIO_PROCESS, 0, 19) };
    }
    false
}

/// The preview thread.
fn run(
    sh: &Shared,
    publisher: &zenoh::pubsub::Publisher<'static>,
    camera: u32,
    interval: Duration,
) {
    // A preview's downscale and its message take a millisecond or two of a core,
    // a few times a second: never while a frame is being tracked, fused or sent (on a 2-core
    // machine with two camera nodes and the fusion node, previews at the default rate took
    // the network's latency p99 from about 1 ms to 2-4 ms).
    yield_to_everything();
    let mut preview = Preview::default();
    let mut acc = Vec::new();
    let mut message = Vec::new();
    let mut seq = 0u32;
    let mut next = Instant::now();
    loop {
        // Until the next preview is due.
        let s = wait_while(sh, lock(&sh.slot), next, |s| !s.stop);
        if s.stop {
            return;
        }
        next += interval;
        // Ask the tracking thread for its next frame, and wait for it.
        sh.want.store(true, Ordering::Relaxed);
        let mut s = wait_while(sh, s, Instant::now() + FRAME_WAIT, |s| !s.fresh && !s.stop);
        if s.stop {
            return;
        }
        let now = Instant::now();
        if next < now {
            // A stalled camera: previews resume at the rate, not in a burst.
            next = now;
        }
        if !s.fresh {
            continue;
        }
        s.fresh = false;
        let meta = s.frame.meta;
        let made = s
            .frame
            .view()
            .map_err(|e| ZenohError::Message(e.to_string()))
            .and_then(|view| {
                preview_into(&view, PREVIEW_MAX_WIDTH_PX, &mut preview, &mut acc);
                let mut h = header_of(
                    &preview,
                    camera,
                    meta.frame_id,
                    meta.timestamp_ns,
                    (meta.width, meta.height),
                )?;
                h.seq = seq;
                encode_preview(&h, &preview.pixels, &mut message)
            });
        // The tracking thread may fill the slot again while the message goes out.
        drop(s);
        let sent = made.and_then(|()| {
            publisher
                .put(message.as_slice())
                .wait()
                .map_err(|e| ZenohError::zenoh("publishing a preview", e))
        });
        match sent {
            Ok(()) => {
                seq = seq.wrapping_add(1);
                sh.published.fetch_add(1, Ordering::Relaxed);
            }
            Err(_) => {
                sh.errors.fetch_add(1, Ordering::Relaxed);
            }
        }
    }
}

#[cfg(all(test, target_os = "linux"))]
mod tests {
    use super::yield_to_everything;

    /// The preview thread's class is Linux's idle one, and only that thread's: the tracking
    /// thread that started it keeps its own.
    #[test]
    #[allow(unsafe_code)]
    fn the_preview_thread_yields_to_every_other_thread() {
        // SAFETY: no arguments; pid 0 is the calling thread.
        let before = unsafe { libc::sched_getscheduler(0) };
        let (set, class) = std::thread::spawn(|| {
            let set = yield_to_everything();
            // SAFETY: as above.
            (set, unsafe { libc::sched_getscheduler(0) })
        })
        .join()
        .expect("the thread ran");
        assert!(set, "SCHED_IDLE refused");
        assert_eq!(class, libc::SCHED_IDLE);
        // SAFETY: as above.
        assert_eq!(unsafe { libc::sched_getscheduler(0) }, before);
    }
}
