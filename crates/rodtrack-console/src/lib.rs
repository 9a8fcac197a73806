//! rodtrack's web console: a live view of every camera with the rods' overlays, scrolling plots
//! of every rod's position and angle with the pipeline's counters, and calibration in the
//! browser (freeze a frame, click the rods' paths, mark the reference pose, calibrate with
//! [`rodtrack_core::calib::calibrate_rod`], see the residuals, save the TOML file).
//!
//! # Never blocking the tracking
//! The tracking side only ever *publishes*, and gives a live frame only when the console asks
//! for one: while a browser is connected, the console sets a camera's "want" bit a few times
//! per second, and every other frame costs the tracking side one atomic load
//! ([`ConsoleHandle::wants_frame`]; no clock, no lock). Every camera's want and freeze bits
//! share one word on a cache line of its own, so that the check is one line, which the other
//! cameras' checks of the same frame set find in the cache (the tracking streams megabytes of
//! pixels per frame set and evicts the console's lines: a chain of pointers to per-camera flags
//! cost several cache misses, 0.25-0.3 us, per frame). A wanted frame is either copied,
//! decimated to at most [`LIVE_COPY_MAX_WIDTH`] pixels across
//! ([`ConsoleHandle::publish_frame`], [`LIVE_COPY_FPS`] per camera), or swapped in without a copy
//! ([`ConsoleHandle::publish_frame_buffer`], [`LIVE_FPS`] per camera), into a latest-value slot
//! (`try_lock`: when the console is reading the slot the frame is skipped).
//! [`ConsoleHandle::publish_rows`] packs compact rows into a preallocated ring of atomic words
//! (oldest rows are overwritten) and makes them visible with one store: no lock, nothing the
//! console can hold; the console copies the rows out and drops any a publisher overwrote
//! meanwhile, as a sequence lock's reader would. [`ConsoleHandle::publish_stats`] replaces the
//! latest counters (`try_lock`). What the tracking side writes (frame counts, the publish
//! calls' accounting, the rows ring's positions) sits on lines the console only reads. The
//! console's own thread (a one-worker tokio runtime serving axum) downscales, encodes and sends
//! at its own pace. The time spent inside the publish calls is measured
//! ([`ConsoleHandle::overhead`]); their share of the tracking time is the `overhead` bench
//! (`cargo bench -p rodtrack-console --bench overhead -- --runs 9`): about 0.6 % with swapped
//! live frames (a live frame's call about 3 us) and 1.7-1.9 % with copied ones, almost all of
//! it the copy itself (70-100 us, bound by memory bandwidth: it reads half the rows of a
//! 1440x1080 Bayer frame, the fewest a 360x270 colour preview needs, into a buffer last
//! written half a second earlier).
//!
//! A live frame's overlays cost the tracking side a copy of the rods' results: the constant
//! part of each rod's overlay (its sampling line, the marker's dimensions, a compact copy of
//! the knots) is computed once per camera ([`CameraOverlays`]) and shared by reference; the
//! marker's pixels (barcode, Gray bit points, phase window) are computed when the console
//! serialises the frame, on its own thread (see [`overlay`]). Computing everything on the
//! tracking thread took about 14 us per live frame (mostly cache misses on the knots), copying
//! it into the console's slot with its vectors a few more.
//!
//! # API
//! - [`Console::start`]`(addr, Option<CalibrationContext>) -> Result<ConsoleHandle>`
//!   (port 0 picks a free port: [`ConsoleHandle::addr`]).
//! - [`ConsoleHandle::wants_frame`]`(camera)`, [`ConsoleHandle::publish_frame`]`(camera,
//!   &FrameView, frame_id, timestamp_s, &[RodOverlay])`; the overlays from
//!   [`CameraOverlays::new`]`(pipeline.rods())` (once) and
//!   [`CameraOverlays::fill`]`(pipeline.last_results(), &mut Vec<RodOverlay>)` (per live
//!   frame, no allocation once the vector holds the camera's rods); [`overlays_for`]`(&RodTracker,
//!   &RodResult)` for a one-off overlay.
//! - [`ConsoleHandle::publish_frame_buffer`]: the same for an owned buffer, swapped instead of
//!   copied (zero copy, full resolution; `rodtrack demo` and `rodtrack console --demo` use it,
//!   and `rodtrack track`, whose frames are the runtime's, through the runtime's frame hook).
//! - [`ConsoleHandle::publish_rows`]`(&[Measurement])`, [`ConsoleHandle::publish_stats`].
//! - [`ConsoleHandle::publish_events`]`(&[BallEvent])`: the ball's running score and last
//!   events (from the session's event sink).
//! - [`ConsoleHandle::publish_ball`]`(&[BallRow])` (one frame set's rows per call, from the
//!   session's ball sink) and [`ConsoleHandle::set_ball_field`]: the ball's position, speed
//!   and trail on a top view of the field.
//! - Remote nodes (a console fed from a camera network): [`ConsoleHandle::publish_preview`]
//!   (a camera's preview image, shown as its live frame), [`ConsoleHandle::publish_node_status`]
//!   (a node's status JSON, shown as silent after [`remote::SILENT_AFTER`] without one),
//!   [`ConsoleHandle::note_malformed`] (a message that could not be used); see [`remote`].
//! - [`ConsoleHandle::attach_session`]`(Arc<dyn SessionCommands>)`: the running session, for
//!   the page's re-anchoring of a rod's turn count (see [`control`]).
//! - HTTP: `/` (the page), `/ws` (live data), `/api/status`, `/api/calib` and its actions,
//!   `/api/reanchor` (see [`server`]).

mod ball;
pub mod calib;
pub mod control;
pub mod error;
mod events;
mod guard;
pub mod image;
pub mod overlay;
mod poses;
pub mod remote;
pub(crate) mod rows;
pub mod server;

pub use calib::{CalibrationContext, CameraSetup, RodOutcome, Saved};
pub use control::SessionCommands;
pub use error::ConsoleError;
pub use image::{preview, OwnedFrame, Preview};
pub use overlay::{
    overlays_for, BitOverlay, BitOverlays, CameraOverlays, MarkerOverlay, RodGeometry, RodOverlay,
};

use calib::CalibState;
use rodtrack_core::{FrameView, Measurement};
use rows::RowRing;
use serde::{Deserialize, Serialize};
use std::net::SocketAddr;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// The default address: loopback only.
pub const DEFAULT_ADDR: &str = "127.0.0.1:8620";
/// Cameras the console can show (indices `0..MAX_CAMERAS`).
pub const MAX_CAMERAS: usize = 16;
/// Rows kept for the plots (about 13 s of 2 cameras x 8 rods + fused at 200 fps).
pub const ROW_CAPACITY: usize = 1 << 16;
/// Live frames per second per camera sent to the browser when the tracking side gives them with
/// [`ConsoleHandle::publish_frame_buffer`] (a live frame then costs the tracking thread a buffer
/// swap). Measured by `cargo bench -p rodtrack-console --bench overhead`.
pub const LIVE_FPS: f64 = 3.0;
/// Live frames per second per camera when the tracking side gives them with
/// [`ConsoleHandle::publish_frame`]: each costs the tracking thread a decimated copy (see
/// [`LIVE_COPY_MAX_WIDTH`]), so they come less often.
pub const LIVE_COPY_FPS: f64 = 2.0;
/// Widest live frame [`ConsoleHandle::publish_frame`] copies, px: wider frames are decimated
/// (every `d`-th pixel of every `d`-th row; for Bayer frames every `d`-th 2x2 block, so a
/// 1440x1080 Bayer camera is copied as 720x540 Bayer, a quarter of its bytes, and shown as a
/// 360x270 colour preview; the full copy took 2.5 times as long). Frozen frames (calibration)
/// are always copied whole.
pub const LIVE_COPY_MAX_WIDTH: usize = 720;

/// The decimation [`ConsoleHandle::publish_frame`] applies to a live frame `width` px wide.
pub fn live_decimation(width: usize, format: rodtrack_core::PixelFormat) -> usize {
    if format.luma_kind() == rodtrack_core::LumaKind::Bayer {
        // Whole 2x2 blocks are kept.
        (width / 2).div_ceil(LIVE_COPY_MAX_WIDTH / 2).max(1)
    } else {
        width.div_ceil(LIVE_COPY_MAX_WIDTH).max(1)
    }
}

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
    /// Publish calls that did something (frame copies or swaps, rows, counters); frames offered
    /// when no live frame is due return after an atomic load and are only counted per camera.
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

/// One camera's slots (the console's side: the tracking side reads none of this unless it gives
/// a frame).
#[derive(Debug, Default)]
pub(crate) struct CameraSlot {
    /// When the console last asked for a live frame (ns since `Shared::started`).
    pub last_request_ns: AtomicU64,
    /// The last live frame was copied ([`ConsoleHandle::publish_frame`]), not swapped in: the
    /// console asks at [`LIVE_COPY_FPS`] instead of [`LIVE_FPS`].
    pub copied: AtomicBool,
    pub live: Mutex<LiveFrame>,
}

/// Bit of camera `c`'s "want a live frame" request in [`Requests`]; its freeze request is this
/// bit shifted by [`FREEZE_SHIFT`].
const fn want_bit(camera: usize) -> u64 {
    1 << camera
}
/// Shift from a camera's want bit to its freeze bit.
const FREEZE_SHIFT: usize = 32;
const WANT_MASK: u64 = (1 << MAX_CAMERAS) - 1;
const _: () = assert!(MAX_CAMERAS <= FREEZE_SHIFT);

/// The console's requests to the tracking side, every camera's in one word on a cache line of
/// its own: the tracking side's per-frame check ([`ConsoleHandle::wants_frame`]) is one load of
/// one line, which the other cameras' checks of the same frame set find in the cache. Bit `c`:
/// camera `c` should give its next frame for the live view (set by the console at the live
/// rate, cleared by the tracking side when it gives one); bit `c + FREEZE_SHIFT`: camera `c`
/// should give its next frame whole for calibration.
#[derive(Debug, Default)]
#[repr(align(64))]
pub(crate) struct Requests {
    bits: AtomicU64,
}

impl Requests {
    /// True when camera `camera` (below [`MAX_CAMERAS`]) should give its next frame. One load.
    #[inline]
    fn due(&self, camera: usize) -> bool {
        let bit = want_bit(camera);
        self.bits.load(Ordering::Acquire) & (bit | bit << FREEZE_SHIFT) != 0
    }
    /// (live frame wanted, freeze pending) of `camera`.
    fn get(&self, camera: usize) -> (bool, bool) {
        let (bits, bit) = (self.bits.load(Ordering::Acquire), want_bit(camera));
        (bits & bit != 0, bits & bit << FREEZE_SHIFT != 0)
    }
    pub(crate) fn freeze_pending(&self, camera: usize) -> bool {
        camera < MAX_CAMERAS && self.get(camera).1
    }
    pub(crate) fn request_freeze(&self, camera: usize) {
        if camera < MAX_CAMERAS {
            self.bits
                .fetch_or(want_bit(camera) << FREEZE_SHIFT, Ordering::Release);
        }
    }
    fn request_live(&self, camera: usize) {
        self.bits.fetch_or(want_bit(camera), Ordering::Release);
    }
    fn cancel_live(&self) {
        self.bits.fetch_and(!WANT_MASK, Ordering::Relaxed);
    }
    fn clear(&self, bits: u64) {
        self.bits.fetch_and(!bits, Ordering::Relaxed);
    }
}

/// Frames offered per camera, written only by the tracking side (on a line of their own).
#[derive(Debug, Default)]
#[repr(align(64))]
pub(crate) struct FrameCounts {
    frames: [AtomicU64; MAX_CAMERAS],
}

impl FrameCounts {
    /// Frames of `camera` offered to [`ConsoleHandle::publish_frame`] or
    /// [`ConsoleHandle::publish_frame_buffer`] (0: the camera was never seen).
    pub(crate) fn frames(&self, camera: usize) -> u64 {
        self.frames
            .get(camera)
            .map_or(0, |f| f.load(Ordering::Relaxed))
    }
    pub(crate) fn seen(&self, camera: usize) -> bool {
        self.frames(camera) > 0
    }
    fn count(&self, camera: usize) {
        if let Some(f) = self.frames.get(camera) {
            f.fetch_add(1, Ordering::Relaxed);
        }
    }
}

/// The publish calls' own accounting ([`PublishOverhead`]), written by the tracking side only,
/// on a line of its own.
#[derive(Debug, Default)]
#[repr(align(64))]
pub(crate) struct Spent {
    calls: AtomicU64,
    total_ns: AtomicU64,
    max_ns: AtomicU64,
}

/// Everything the tracking side and the console share.
#[derive(Debug)]
pub(crate) struct Shared {
    pub started: Instant,
    pub clients: AtomicUsize,
    pub frame_interval_ns: u64,
    pub copy_interval_ns: u64,
    /// The console's requests, read by the tracking side for every frame.
    pub requests: Requests,
    /// Frames offered per camera.
    pub counts: FrameCounts,
    pub cameras: Vec<CameraSlot>,
    pub rows: RowRing,
    pub stats: Mutex<Option<PipelineStats>>,
    pub spent: Spent,
    pub calib: Mutex<CalibState>,
    /// The session token given to the page (see [`guard`]).
    pub token: String,
    /// The tracking session's commands ([`ConsoleHandle::attach_session`]).
    pub session: Mutex<control::Attached>,
    /// The ball's score and last events ([`ConsoleHandle::publish_events`]).
    pub events: Mutex<events::EventBoard>,
    /// The ball's last row and trail ([`ConsoleHandle::publish_ball`]).
    pub ball: Mutex<ball::BallBoard>,
    /// Remote nodes' statuses and previews ([`ConsoleHandle::publish_node_status`]).
    pub remote: Mutex<remote::RemoteBoard>,
}

impl Shared {
    pub(crate) fn now_ns(&self) -> u64 {
        self.started.elapsed().as_nanos() as u64
    }

    /// The console's side: asks every camera for a new live frame when the last request is at
    /// least the live interval old (called on every client's tick; one request per interval
    /// however many clients).
    pub(crate) fn request_live_frames(&self) {
        let now = self.now_ns();
        for (camera, slot) in self.cameras.iter().enumerate() {
            let last = slot.last_request_ns.load(Ordering::Relaxed);
            let interval = if slot.copied.load(Ordering::Relaxed) {
                self.copy_interval_ns
            } else {
                self.frame_interval_ns
            };
            if now.saturating_sub(last) >= interval
                && slot
                    .last_request_ns
                    .compare_exchange(last, now, Ordering::Relaxed, Ordering::Relaxed)
                    .is_ok()
            {
                self.requests.request_live(camera);
            }
        }
    }

    /// The console's side: no client is left, no live frames are wanted.
    pub(crate) fn cancel_live_frames(&self) {
        self.requests.cancel_live();
    }

    fn account(&self, t0: Instant) {
        let ns = t0.elapsed().as_nanos() as u64;
        let spent = &self.spent;
        spent.calls.fetch_add(1, Ordering::Relaxed);
        spent.total_ns.fetch_add(ns, Ordering::Relaxed);
        if ns > spent.max_ns.load(Ordering::Relaxed) {
            spent.max_ns.fetch_max(ns, Ordering::Relaxed);
        }
    }

    pub(crate) fn overhead(&self) -> PublishOverhead {
        let (calls, total_ns, max_ns) = self.rows.spent();
        PublishOverhead {
            calls: self.spent.calls.load(Ordering::Relaxed) + calls,
            total_ns: self.spent.total_ns.load(Ordering::Relaxed) + total_ns,
            max_ns: self.spent.max_ns.load(Ordering::Relaxed).max(max_ns),
        }
    }
}

/// How the console serves.
#[derive(Debug, Clone, Default)]
pub struct ConsoleOptions {
    /// Host names (without port) the console answers to besides IP addresses and `localhost`
    /// (`--allow-host`): any other `Host` header is refused, against DNS rebinding.
    pub allowed_hosts: Vec<String>,
}

/// The header a state-changing request must carry the console's session token in.
pub const TOKEN_HEADER: &str = guard::TOKEN_HEADER;

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
        Self::start_with(addr, calibration, &ConsoleOptions::default())
    }

    /// Like [`Console::start`], with `options` (host names to serve besides addresses and
    /// `localhost`).
    pub fn start_with(
        addr: SocketAddr,
        calibration: Option<CalibrationContext>,
        options: &ConsoleOptions,
    ) -> Result<ConsoleHandle, ConsoleError> {
        let listener = std::net::TcpListener::bind(addr)
            .map_err(|source| ConsoleError::Bind { addr, source })?;
        listener
            .set_nonblocking(true)
            .map_err(|source| ConsoleError::Bind { addr, source })?;
        let local = listener
            .local_addr()
            .map_err(|source| ConsoleError::Bind { addr, source })?;
        let started = Instant::now();
        let shared = Arc::new(Shared {
            started,
            clients: AtomicUsize::new(0),
            frame_interval_ns: (1e9 / LIVE_FPS) as u64,
            copy_interval_ns: (1e9 / LIVE_COPY_FPS) as u64,
            requests: Requests::default(),
            counts: FrameCounts::default(),
            cameras: (0..MAX_CAMERAS).map(|_| CameraSlot::default()).collect(),
            rows: RowRing::new(),
            stats: Mutex::new(None),
            spent: Spent::default(),
            calib: Mutex::new(CalibState::new(calibration.unwrap_or_default())),
            token: guard::new_token(),
            session: Mutex::new(None),
            events: Mutex::new(events::EventBoard::default()),
            ball: Mutex::new(ball::BallBoard::default()),
            remote: Mutex::new(remote::RemoteBoard::default()),
        });
        let guard = Arc::new(guard::GuardConfig {
            addr: local,
            allowed_hosts: options
                .allowed_hosts
                .iter()
                .map(|h| h.trim().to_ascii_lowercase())
                .collect(),
            token: shared.token.clone(),
        });
        let runtime = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(1)
            .thread_name("rodtrack-console-worker")
            .enable_all()
            .build()
            .map_err(ConsoleError::Runtime)?;
        let (stop_tx, stop_rx) = tokio::sync::watch::channel(false);
        let app = server::router(shared.clone(), stop_rx.clone(), guard);
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

    /// The session token state-changing requests must carry in [`TOKEN_HEADER`] (the page
    /// gets it in a `<meta name="rodtrack-token">` tag).
    pub fn token(&self) -> &str {
        &self.shared.token
    }

    /// True when the next [`ConsoleHandle::publish_frame`] of `camera` would copy the frame
    /// (a browser is connected and asked for a live frame, a few times per second, or a freeze
    /// is pending): compute the overlays only then. One atomic load, of a word every camera's
    /// requests share.
    #[inline]
    pub fn wants_frame(&self, camera: u32) -> bool {
        let camera = camera as usize;
        camera < MAX_CAMERAS && self.shared.requests.due(camera)
    }

    /// Offers one camera's frame with its overlays. Cheap: it counts the frame and returns,
    /// unless the live view is due (then the raw frame is copied, decimated to at most
    /// [`LIVE_COPY_MAX_WIDTH`] px across, into the camera's latest-frame slot; skipped if the
    /// console is reading it) or a freeze was asked for (then the full frame is copied for
    /// calibration). Cameras `>= MAX_CAMERAS` are ignored.
    pub fn publish_frame(
        &self,
        camera: u32,
        frame: &FrameView,
        frame_id: u64,
        timestamp_s: f64,
        overlays: &[RodOverlay],
    ) {
        let sh = &self.shared;
        let c = camera as usize;
        if c >= MAX_CAMERAS {
            return;
        }
        sh.counts.count(c);
        if !sh.requests.due(c) {
            return;
        }
        let t0 = Instant::now();
        let Some(slot) = sh.cameras.get(c) else {
            return;
        };
        let (want, freeze) = sh.requests.get(c);
        if freeze {
            if let Ok(mut cal) = sh.calib.try_lock() {
                cal.freeze(camera, OwnedFrame::from_view(frame, frame_id, timestamp_s));
                sh.requests.clear(want_bit(c) << FREEZE_SHIFT);
            }
        }
        if want {
            if let Ok(mut live) = slot.live.try_lock() {
                let d = live_decimation(frame.width(), frame.format());
                live.raw.copy_decimated(frame, d, frame_id, timestamp_s);
                live.decimation = d;
                live.full_size = (frame.width(), frame.height());
                overlays.clone_into(&mut live.overlays);
                live.seq += 1;
                sh.requests.clear(want_bit(c));
                slot.copied.store(true, Ordering::Relaxed);
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
        let sh = &self.shared;
        let c = camera as usize;
        if c >= MAX_CAMERAS {
            return false;
        }
        sh.counts.count(c);
        if !sh.requests.due(c) {
            return false;
        }
        let t0 = Instant::now();
        let Some(slot) = sh.cameras.get(c) else {
            return false;
        };
        let (want, freeze) = sh.requests.get(c);
        if freeze {
            if let (Ok(view), Ok(mut cal)) = (
                FrameView::new(buf, width, height, stride, format),
                sh.calib.try_lock(),
            ) {
                cal.freeze(camera, OwnedFrame::from_view(&view, frame_id, timestamp_s));
                sh.requests.clear(want_bit(c) << FREEZE_SHIFT);
            }
        }
        let mut taken = false;
        if want {
            if let Ok(mut live) = slot.live.try_lock() {
                if live
                    .raw
                    .swap_in(buf, width, height, stride, format, frame_id, timestamp_s)
                    .is_ok()
                {
                    live.decimation = 1;
                    live.full_size = (width, height);
                    overlays.clone_into(&mut live.overlays);
                    live.seq += 1;
                    sh.requests.clear(want_bit(c));
                    slot.copied.store(false, Ordering::Relaxed);
                    taken = true;
                }
            }
        }
        sh.account(t0);
        taken
    }

    /// Appends measurement rows (any cameras, fused included) to the plots' ring buffer; the
    /// oldest rows are overwritten when it is full. Never waits for the console and takes no
    /// lock: the rows are packed into the ring's preallocated slots and made visible with one
    /// store (several threads may publish; each waits only for those that claimed rows before
    /// it to finish writing them).
    pub fn publish_rows(&self, rows: &[Measurement]) {
        if rows.is_empty() {
            return;
        }
        let t0 = Instant::now();
        self.shared.rows.publish(rows, t0);
    }

    /// Replaces the pipeline's counters shown on the page.
    pub fn publish_stats(&self, stats: &PipelineStats) {
        let t0 = Instant::now();
        if let Ok(mut s) = self.shared.stats.try_lock() {
            *s = Some(*stats);
        }
        self.shared.account(t0);
    }

    /// Shows the ball's events on the page: the running score (from the goals) and the last
    /// events (the last 8). Events are rare and decided off the cameras'
    /// threads: a plain lock, held by the console only to copy them.
    pub fn publish_events(&self, events: &[rodtrack_core::ball::events::BallEvent]) {
        if events.is_empty() {
            return;
        }
        let t0 = Instant::now();
        server::lock(&self.shared.events).push(events);
        self.shared.account(t0);
    }

    /// Shows the ball on the page: one frame set's rows per call (each camera's and the fused
    /// one; the fused row is shown, else a camera's), its speed, and the trail of the last
    /// second. Called once per frame set off the cameras' threads: a plain lock, held by the
    /// console only to copy the trail; no allocation.
    pub fn publish_ball(&self, rows: &[rodtrack_core::ball::BallRow]) {
        if rows.is_empty() {
            return;
        }
        let t0 = Instant::now();
        server::lock(&self.shared.ball).push(rows);
        self.shared.account(t0);
    }

    /// The field's size for the ball's top view (mm; the reference table's 1200 x 680 until
    /// set).
    pub fn set_ball_field(&self, length_mm: f64, width_mm: f64) {
        server::lock(&self.shared.ball).set_field(length_mm, width_mm);
    }

    /// Shows a remote camera's preview image (a small 8-bit grey or RGB image, 1 or 3
    /// channels, of a frame `source_px` px in size) as the camera's live frame, and lists it
    /// in the status's `remote.previews`. For a console fed from the network, a few times per
    /// second: it copies the preview under the camera slot's lock (never call it from a
    /// tracking thread; those use [`ConsoleHandle::publish_frame`]).
    pub fn publish_preview(
        &self,
        camera: u32,
        preview: &Preview,
        source_px: (usize, usize),
        frame_id: u64,
        timestamp_s: f64,
    ) -> Result<(), ConsoleError> {
        let sh = &self.shared;
        let c = camera as usize;
        let Some(slot) = sh.cameras.get(c) else {
            return Err(ConsoleError::Camera {
                camera,
                reason: format!("the console shows cameras 0 to {}", MAX_CAMERAS - 1),
            });
        };
        let format = match preview.channels {
            1 => rodtrack_core::PixelFormat::Mono8,
            3 => rodtrack_core::PixelFormat::Rgb8,
            n => {
                return Err(ConsoleError::BadRequest {
                    field: "preview",
                    reason: format!("{n} channels (1 or 3)"),
                })
            }
        };
        let view = FrameView::new(
            &preview.pixels,
            preview.width,
            preview.height,
            preview.width * preview.channels,
            format,
        )?;
        {
            let mut live = server::lock(&slot.live);
            live.raw.copy_from(&view, frame_id, timestamp_s);
            live.decimation = (source_px.0 / preview.width.max(1)).max(1);
            live.full_size = source_px;
            live.overlays.clear();
            live.seq += 1;
        }
        sh.counts.count(c);
        server::lock(&sh.remote).preview(
            camera,
            frame_id,
            (preview.width, preview.height),
            preview.channels,
            source_px,
        );
        Ok(())
    }

    /// Shows a remote node's latest status (`node`: its name, e.g. `cam/cam0` or `fused`;
    /// `status`: its status message) in the status's `remote.nodes`; a node with no status
    /// for [`remote::SILENT_AFTER`] is shown as silent.
    pub fn publish_node_status(&self, node: &str, status: serde_json::Value) {
        server::lock(&self.shared.remote).status(node, status);
    }

    /// Counts a message from the network that could not be used (`key`: where it came from);
    /// the first ones are listed in the status's `remote.first_errors`.
    pub fn note_malformed(&self, key: &str, error: &str) {
        server::lock(&self.shared.remote).malformed(key, error);
    }

    /// Attaches the running tracking session: the page then offers to re-anchor a rod's turn
    /// count (`POST /api/reanchor`), which calls `session`. Only the console's thread calls it.
    pub fn attach_session(&self, session: Arc<dyn SessionCommands>) {
        if let Ok(mut s) = self.shared.session.lock() {
            *s = Some(session);
        }
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn live_frames_are_decimated_to_the_live_width() {
        use rodtrack_core::PixelFormat;
        assert_eq!(live_decimation(1440, PixelFormat::BayerRggb8), 2);
        assert_eq!(live_decimation(720, PixelFormat::BayerRggb8), 1);
        assert_eq!(live_decimation(2048, PixelFormat::BayerRggb8), 3);
        assert_eq!(live_decimation(1440, PixelFormat::Mono8), 2);
        assert_eq!(live_decimation(640, PixelFormat::Mono8), 1);
        assert_eq!(live_decimation(0, PixelFormat::Mono8), 1);
    }
}
