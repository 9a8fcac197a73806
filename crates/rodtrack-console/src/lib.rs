//! rodtrack's web console: a live view of every camera with the rods' overlays, scrolling plots
//! of every rod's position and angle with the pipeline's counters, and calibration in the
//! browser (freeze a frame, click the rods' paths, mark the reference pose, calibrate with
//! [`rodtrack_core::calib::calibrate_rod`], see the residuals, save the TOML file).
//!
//! # Never blocking the tracking
//! The tracking side only ever *publishes*: [`ConsoleHandle::publish_frame`] copies a raw frame
//! into a latest-value slot a few times per second, and only while a browser is connected
//! (`try_lock`: when the console is reading the slot the frame is skipped);
//! [`ConsoleHandle::publish_rows`] appends to a bounded ring buffer (oldest rows are dropped);
//! [`ConsoleHandle::publish_stats`] replaces the latest counters. The console's own thread
//! (a one-worker tokio runtime serving axum) downscales, encodes and sends at its own pace.
//! The time spent inside the publish calls is measured ([`ConsoleHandle::overhead`]).
//!
//! # API
//! - [`Console::start`]`(addr, Option<CalibrationContext>) -> Result<ConsoleHandle>`
//!   (port 0 picks a free port: [`ConsoleHandle::addr`]).
//! - [`ConsoleHandle::wants_frame`]`(camera)`, [`ConsoleHandle::publish_frame`]`(camera,
//!   &FrameView, frame_id, timestamp_s, &[RodOverlay])`, [`overlays_for`]`(&RodTracker,
//!   &RodResult)`.
//! - [`ConsoleHandle::publish_frame_buffer`]: the same for an owned buffer, swapped instead of
//!   copied (zero copy; the demo uses it).
//! - [`ConsoleHandle::publish_rows`]`(&[Measurement])`, [`ConsoleHandle::publish_stats`].
//! - HTTP: `/` (the page), `/ws` (live data), `/api/status`, `/api/calib` and its actions
//!   (see [`server`]).

pub mod calib;
pub mod error;
pub mod image;
pub mod overlay;
pub mod server;

pub use calib::{CalibrationContext, CameraSetup, RodOutcome, Saved};
pub use error::ConsoleError;
pub use image::{preview, OwnedFrame, Preview};
pub use overlay::{overlays_for, BitOverlay, MarkerOverlay, RodOverlay};

use calib::CalibState;
use rodtrack_core::{FrameView, Measurement};
use serde::{Deserialize, Serialize};
use std::collections::VecDeque;
use std::net::SocketAddr;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// The default address: loopback only.
pub const DEFAULT_ADDR: &str = "127.0.0.1:8620";
/// Cameras the console can show (indices `0..MAX_CAMERAS`).
pub const MAX_CAMERAS: usize = 16;
/// Rows kept for the plots (about 20 s of 2 cameras x 8 rods + fused at 200 fps).
pub const ROW_CAPACITY: usize = 1 << 16;
/// Live frames per second per camera sent to the browser. With
/// [`ConsoleHandle::publish_frame_buffer`] a live frame costs the tracking thread a buffer swap;
/// with [`ConsoleHandle::publish_frame`] one frame copy (0.1 to 0.25 ms for 1440x1080, about
/// 2 % of the tracking time at 200 fps); measured in `tests/overhead.rs`.
pub const LIVE_FPS: f64 = 3.0;

/// The pipeline's counters, as the tracking side sees them.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct PipelineStats {
    /// Frame sets processed.
    pub frames: u64,
    /// Frame sets per second (recent).
    pub fps: f64,
    /// Processing time per frame set, microseconds (recent median or mean).
    pub frame_time_us: f64,
    /// Frames dropped (not processed: late, lost by the camera, ...).
    pub dropped_frames: u64,
    /// Frames that could not be used (corrupt, wrong size).
    pub bad_frames: u64,
}

/// Time spent inside the publish calls.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct PublishOverhead {
    /// Number of publish calls.
    pub calls: u64,
    /// Total time inside them, ns.
    pub total_ns: u64,
    /// Longest single call, ns.
    pub max_ns: u64,
}

/// The latest raw frame of one camera, as the console last copied it.
#[derive(Debug, Default)]
pub(crate) struct LiveFrame {
    pub raw: OwnedFrame,
    /// Full-resolution pixels per pixel of `raw`.
    pub decimation: usize,
    /// Full-resolution size.
    pub full_size: (usize, usize),
    pub overlays: Vec<RodOverlay>,
    pub seq: u64,
    /// The encoded preview message of `seq`.
    pub encoded: Option<(u64, axum::body::Bytes)>,
}

/// One camera's slots.
#[derive(Debug, Default)]
pub(crate) struct CameraSlot {
    pub seen: AtomicBool,
    pub frames: AtomicU64,
    pub last_copy_ns: AtomicU64,
    pub freeze: AtomicBool,
    pub live: Mutex<LiveFrame>,
}

/// The rows ring buffer: row `i` of `buf` has sequence number `next_seq - buf.len() + i`.
#[derive(Debug, Default)]
pub(crate) struct RowRing {
    pub buf: VecDeque<Measurement>,
    pub next_seq: u64,
}

/// Everything the tracking side and the console share.
#[derive(Debug)]
pub(crate) struct Shared {
    pub started: Instant,
    pub clients: AtomicUsize,
    pub frame_interval_ns: u64,
    pub cameras: Vec<CameraSlot>,
    pub rows: Mutex<RowRing>,
    pub stats: Mutex<Option<PipelineStats>>,
    pub calls: AtomicU64,
    pub total_ns: AtomicU64,
    pub max_ns: AtomicU64,
    pub calib: Mutex<CalibState>,
}

impl Shared {
    fn now_ns(&self) -> u64 {
        self.started.elapsed().as_nanos() as u64
    }

    fn account(&self, t0: Instant) {
        let ns = t0.elapsed().as_nanos() as u64;
        self.calls.fetch_add(1, Ordering::Relaxed);
        self.total_ns.fetch_add(ns, Ordering::Relaxed);
        self.max_ns.fetch_max(ns, Ordering::Relaxed);
    }

    pub(crate) fn overhead(&self) -> PublishOverhead {
        PublishOverhead {
            calls: self.calls.load(Ordering::Relaxed),
            total_ns: self.total_ns.load(Ordering::Relaxed),
            max_ns: self.max_ns.load(Ordering::Relaxed),
        }
    }
}

/// Starts the console.
#[derive(Debug)]
pub struct Console;

impl Console {
    /// Binds `addr` (port 0 picks a free one) and serves the console from its own thread.
    /// `calibration` gives the cameras' calibration inputs, reference frames and the output
    /// file; without it, cameras appear in the calibration page once a frame is frozen, and
    /// saving is disabled.
    pub fn start(
        addr: SocketAddr,
        calibration: Option<CalibrationContext>,
    ) -> Result<ConsoleHandle, ConsoleError> {
        let listener = std::net::TcpListener::bind(addr)
            .map_err(|source| ConsoleError::Bind { addr, source })?;
        listener
            .set_nonblocking(true)
            .map_err(|source| ConsoleError::Bind { addr, source })?;
        let local = listener
            .local_addr()
            .map_err(|source| ConsoleError::Bind { addr, source })?;
        let shared = Arc::new(Shared {
            started: Instant::now(),
            clients: AtomicUsize::new(0),
            frame_interval_ns: (1e9 / LIVE_FPS) as u64,
            cameras: (0..MAX_CAMERAS).map(|_| CameraSlot::default()).collect(),
            rows: Mutex::new(RowRing::default()),
            stats: Mutex::new(None),
            calls: AtomicU64::new(0),
            total_ns: AtomicU64::new(0),
            max_ns: AtomicU64::new(0),
            calib: Mutex::new(CalibState::new(calibration.unwrap_or_default())),
        });
        let runtime = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(1)
            .thread_name("rodtrack-console-worker")
            .enable_all()
            .build()
            .map_err(ConsoleError::Runtime)?;
        let (stop_tx, stop_rx) = tokio::sync::watch::channel(false);
        let app = server::router(shared.clone(), stop_rx.clone());
        let thread = std::thread::Builder::new()
            .name("rodtrack-console".into())
            .spawn(move || {
                runtime.block_on(async move {
                    let listener = match tokio::net::TcpListener::from_std(listener) {
                        Ok(l) => l,
                        Err(e) => {
                            eprintln!("rodtrack console: cannot listen: {e}");
                            return;
                        }
                    };
                    let mut stop = stop_rx;
                    let serve = axum::serve(listener, app).with_graceful_shutdown(async move {
                        let _ = stop.wait_for(|s| *s).await;
                    });
                    if let Err(e) = serve.await {
                        eprintln!("rodtrack console: server stopped: {e}");
                    }
                });
                runtime.shutdown_timeout(Duration::from_millis(200));
            })
            .map_err(ConsoleError::Runtime)?;
        Ok(ConsoleHandle {
            shared,
            addr: local,
            stop: stop_tx,
            thread: Some(thread),
        })
    }
}

/// The running console; the tracking side publishes through it. Dropping it stops the server.
#[derive(Debug)]
pub struct ConsoleHandle {
    shared: Arc<Shared>,
    addr: SocketAddr,
    stop: tokio::sync::watch::Sender<bool>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl ConsoleHandle {
    /// The address the console listens on.
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// The page's URL.
    pub fn url(&self) -> String {
        format!("http://{}/", self.addr)
    }

    /// True when the next [`ConsoleHandle::publish_frame`] of `camera` would copy the frame
    /// (a browser is connected and the live view is due, or a freeze is pending): compute the
    /// overlays only then.
    pub fn wants_frame(&self, camera: u32) -> bool {
        let Some(slot) = self.shared.cameras.get(camera as usize) else {
            return false;
        };
        if slot.freeze.load(Ordering::Relaxed) {
            return true;
        }
        self.shared.clients.load(Ordering::Relaxed) > 0
            && self
                .shared
                .now_ns()
                .saturating_sub(slot.last_copy_ns.load(Ordering::Relaxed))
                >= self.shared.frame_interval_ns
    }

    /// Offers one camera's frame with its overlays. Cheap: it counts the frame and returns,
    /// unless the live view is due (then the raw frame is copied, one `memcpy` of about 0.1 ms
    /// for 1440x1080, into the camera's latest-frame slot, skipped if the console is reading it) or a freeze was asked for (then the full
    /// frame is copied for calibration). Cameras `>= MAX_CAMERAS` are ignored.
    pub fn publish_frame(
        &self,
        camera: u32,
        frame: &FrameView,
        frame_id: u64,
        timestamp_s: f64,
        overlays: &[RodOverlay],
    ) {
        let t0 = Instant::now();
        let sh = &self.shared;
        let Some(slot) = sh.cameras.get(camera as usize) else {
            return;
        };
        slot.seen.store(true, Ordering::Relaxed);
        slot.frames.fetch_add(1, Ordering::Relaxed);
        if slot.freeze.load(Ordering::Relaxed) {
            if let Ok(mut cal) = sh.calib.try_lock() {
                cal.freeze(camera, OwnedFrame::from_view(frame, frame_id, timestamp_s));
                slot.freeze.store(false, Ordering::Relaxed);
            }
        }
        if self.wants_frame(camera) {
            if let Ok(mut live) = slot.live.try_lock() {
                live.raw.copy_from(frame, frame_id, timestamp_s);
                live.decimation = 1;
                live.full_size = (frame.width(), frame.height());
                live.overlays.clear();
                live.overlays.extend_from_slice(overlays);
                live.seq += 1;
                slot.last_copy_ns.store(sh.now_ns(), Ordering::Relaxed);
            }
        }
        sh.account(t0);
    }

    /// Like [`ConsoleHandle::publish_frame`] for a frame in an owned buffer, without copying:
    /// when the live view is due, the buffer is swapped with the console's previous one (the
    /// caller gets a buffer of the same length back and fills it with a later frame). Returns
    /// true when the buffer was taken. A freeze still copies the frame.
    #[allow(clippy::too_many_arguments)]
    pub fn publish_frame_buffer(
        &self,
        camera: u32,
        buf: &mut Vec<u8>,
        width: usize,
        height: usize,
        stride: usize,
        format: rodtrack_core::PixelFormat,
        frame_id: u64,
        timestamp_s: f64,
        overlays: &[RodOverlay],
    ) -> bool {
        let t0 = Instant::now();
        let sh = &self.shared;
        let Some(slot) = sh.cameras.get(camera as usize) else {
            return false;
        };
        slot.seen.store(true, Ordering::Relaxed);
        slot.frames.fetch_add(1, Ordering::Relaxed);
        if slot.freeze.load(Ordering::Relaxed) {
            if let (Ok(view), Ok(mut cal)) = (
                FrameView::new(buf, width, height, stride, format),
                sh.calib.try_lock(),
            ) {
                cal.freeze(camera, OwnedFrame::from_view(&view, frame_id, timestamp_s));
                slot.freeze.store(false, Ordering::Relaxed);
            }
        }
        let mut taken = false;
        if self.wants_frame(camera) {
            if let Ok(mut live) = slot.live.try_lock() {
                if live
                    .raw
                    .swap_in(buf, width, height, stride, format, frame_id, timestamp_s)
                    .is_ok()
                {
                    live.decimation = 1;
                    live.full_size = (width, height);
                    live.overlays.clear();
                    live.overlays.extend_from_slice(overlays);
                    live.seq += 1;
                    slot.last_copy_ns.store(sh.now_ns(), Ordering::Relaxed);
                    taken = true;
                }
            }
        }
        sh.account(t0);
        taken
    }

    /// Appends measurement rows (any cameras, fused included) to the plots' ring buffer; the
    /// oldest rows are dropped when it is full.
    pub fn publish_rows(&self, rows: &[Measurement]) {
        let t0 = Instant::now();
        if let Ok(mut ring) = self.shared.rows.lock() {
            for m in rows {
                if ring.buf.len() == ROW_CAPACITY {
                    ring.buf.pop_front();
                }
                ring.buf.push_back(*m);
                ring.next_seq += 1;
            }
        }
        self.shared.account(t0);
    }

    /// Replaces the pipeline's counters shown on the page.
    pub fn publish_stats(&self, stats: &PipelineStats) {
        let t0 = Instant::now();
        if let Ok(mut s) = self.shared.stats.try_lock() {
            *s = Some(*stats);
        }
        self.shared.account(t0);
    }

    /// Time spent in the publish calls so far.
    pub fn overhead(&self) -> PublishOverhead {
        self.shared.overhead()
    }

    /// Number of browsers connected to the live view.
    pub fn clients(&self) -> usize {
        self.shared.clients.load(Ordering::Relaxed)
    }

    /// Blocks until the console's server stops (it runs until the handle is dropped or the
    /// process ends).
    pub fn wait(mut self) {
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }

    /// Stops the server and waits for its thread.
    pub fn shutdown(mut self) {
        self.stop_now();
    }

    fn stop_now(&mut self) {
        let _ = self.stop.send(true);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

impl Drop for ConsoleHandle {
    fn drop(&mut self) {
        self.stop_now();
    }
}
