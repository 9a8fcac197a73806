//! [`GenicamSource`]: a live camera through Aravis, with reconnection.

use crate::clock::{group_clock, TriggerClock};
use crate::ffi::{self, CameraInfo, ARAVIS_GLOBAL};
use crate::ids::{IdExtender, IdStep};
use crate::options::{
    format_from_genicam, genicam_format_name, GenicamOptions, TimestampSource, Trigger,
};
use aravis::prelude::*;
use aravis::{AcquisitionMode, Auto, Buffer, BufferStatus, Camera, Stream};
use rodtrack_core::PixelFormat;
use rodtrack_io::{
    FrameBuffer, FrameSource, InputSpec, IoError, OpenOptions, SourceError, SourceFactory,
    SourceInfo, Timestamp,
};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

/// First wait between reconnection attempts; doubles up to [`MAX_BACKOFF`].
const FIRST_BACKOFF: Duration = Duration::from_millis(100);
/// Longest wait between reconnection attempts.
const MAX_BACKOFF: Duration = Duration::from_secs(2);
/// Bad buffers in a row before `next_frame` returns an error instead of waiting on.
const MAX_BAD_IN_A_ROW: u32 = 64;

/// Counters of a [`GenicamSource`], shared (readable from any thread while the source runs).
#[derive(Debug, Default)]
pub struct GenicamCounters {
    frames: AtomicU64,
    incomplete: AtomicU64,
    dropped: AtomicU64,
    stale: AtomicU64,
    timeouts: AtomicU64,
    disconnects: AtomicU64,
    reconnects: AtomicU64,
    last_recovery_us: AtomicU64,
    max_recovery_us: AtomicU64,
}

/// A snapshot of [`GenicamCounters`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct GenicamStats {
    /// Frames delivered.
    pub frames: u64,
    /// Buffers dropped because incomplete or corrupt (missing packets, timeout, wrong size).
    pub incomplete: u64,
    /// Frames missing from the id sequence (camera ids skipped, or trigger ticks missed).
    pub dropped: u64,
    /// Duplicate or out-of-order buffers dropped.
    pub stale: u64,
    /// Waits for a frame that timed out.
    pub timeouts: u64,
    /// Times the camera was lost.
    pub disconnects: u64,
    /// Successful reconnections.
    pub reconnects: u64,
    /// Last recovery: from the last frame before the loss to the first frame after it.
    pub last_recovery: Duration,
    /// Longest recovery.
    pub max_recovery: Duration,
}

impl GenicamCounters {
    /// A snapshot.
    pub fn snapshot(&self) -> GenicamStats {
        let g = |a: &AtomicU64| a.load(Ordering::Relaxed);
        GenicamStats {
            frames: g(&self.frames),
            incomplete: g(&self.incomplete),
            dropped: g(&self.dropped),
            stale: g(&self.stale),
            timeouts: g(&self.timeouts),
            disconnects: g(&self.disconnects),
            reconnects: g(&self.reconnects),
            last_recovery: Duration::from_micros(g(&self.last_recovery_us)),
            max_recovery: Duration::from_micros(g(&self.max_recovery_us)),
        }
    }
    fn add(a: &AtomicU64, n: u64) {
        a.fetch_add(n, Ordering::Relaxed);
    }
}

/// Where a source stands.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum CameraStatus {
    /// Connected and acquiring.
    Streaming,
    /// Lost; reconnecting.
    Reconnecting {
        /// Failed attempts so far.
        attempts: u32,
        /// Why it was lost.
        reason: String,
    },
    /// Gave up (fatal error returned); the stream has ended.
    Failed,
}

/// An open, configured, acquiring camera.
struct Connection {
    camera: Camera,
    stream: Stream,
    device_id: String,
    width: usize,
    height: usize,
    format: PixelFormat,
    arv_format: aravis::PixelFormat,
    control_lost: Arc<AtomicBool>,
    /// When acquisition started.
    started: Instant,
    /// False once the camera is known to be gone (no goodbye commands then).
    alive: bool,
}

impl Drop for Connection {
    fn drop(&mut self) {
        if self.alive {
            let _ = self.camera.stop_acquisition();
        }
        self.stream.set_emit_signals(false);
    }
}

struct Lost {
    reason: String,
    /// The last frame before the loss (or the moment of the loss).
    since: Instant,
    next_attempt: Instant,
    backoff: Duration,
    attempts: u32,
}

/// A GenICam camera (GigE Vision, USB3 Vision, Aravis' fake) as a [`FrameSource`].
///
/// - Opens the camera by device id, serial number or address (`first`: the first one listed),
///   configures everything in [`GenicamOptions`] at every connection, and streams with a pool of
///   [`GenicamOptions::buffers`] Aravis buffers: a popped buffer's bytes are read in place
///   (zero-copy view of `arv_buffer_get_data`) and copied once into the caller's pooled
///   [`FrameBuffer`] (packed rows, honouring the camera's row padding), then the buffer goes
///   straight back to the stream.
/// - Frame ids: the camera's ids extended to a monotonic `u64` (16-bit GigE ids wrap), from 0
///   at the first frame; with software triggers, the trigger clock's tick number. Gaps are
///   counted as dropped frames; incomplete buffers are dropped and counted ([`Self::stats`]).
/// - Timestamps: the camera's (ns), made monotonic across reconnections, or the host's
///   arrival time ([`TimestampSource::Host`]).
/// - A camera that disappears (no frame within [`GenicamOptions::frame_timeout`], or Aravis'
///   `control-lost`) is reported once per reconnection attempt as a non-fatal
///   `IoError::File { action: "camera lost, reconnecting", .. }` naming `genicam://ID`, and
///   reopened with backoff (100 ms doubling to 2 s); ids and timestamps go on from where they
///   were. After [`GenicamOptions::give_up_after`] without success: a fatal `SourceFailed`.
pub struct GenicamSource {
    opts: GenicamOptions,
    name: String,
    conn: Option<Connection>,
    width: usize,
    height: usize,
    format: PixelFormat,
    ids: IdExtender,
    counters: Arc<GenicamCounters>,
    clock: Option<Arc<TriggerClock>>,
    last_tick: Option<u64>,
    /// Host time (ns since the epoch) when the last software trigger was fired.
    fired_at_ns: u64,
    /// Drain stale buffers before the next software trigger.
    resync: bool,
    lost: Option<Lost>,
    failed: bool,
    /// The loss being recovered from: the time of the last frame before it.
    recovering_since: Option<Instant>,
    last_frame_at: Option<Instant>,
    /// Camera timestamp continuity: offset added to camera timestamps, last value delivered.
    ts_offset: i128,
    last_ts: Option<u64>,
    /// After a reconnection: re-base the camera timestamps at the next frame.
    rebase_ts: bool,
}

impl std::fmt::Debug for GenicamSource {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GenicamSource")
            .field("name", &self.name)
            .field("width", &self.width)
            .field("height", &self.height)
            .field("format", &self.format)
            .field("status", &self.status())
            .field("stats", &self.stats())
            .finish_non_exhaustive()
    }
}

fn lost_error(name: &str, reason: &str) -> IoError {
    IoError::File {
        path: name.into(),
        action: "camera lost, reconnecting",
        source: std::io::Error::new(std::io::ErrorKind::NotConnected, reason.to_string()),
    }
}

fn gerr(what: &str, e: aravis::glib::Error) -> String {
    format!("{what}: {}", e.message())
}

/// Finds the device id Aravis opens for `id` (device id, serial, address, physical id or
/// `first`), from the device list.
fn resolve(id: &str) -> Result<String, String> {
    let list = ffi::device_list();
    let found = if id == "first" {
        list.first()
    } else {
        list.iter()
            .find(|c| c.id == id || c.serial == id || c.address == id || c.physical_id == id)
    };
    match found {
        Some(c) => Ok(c.id.clone()),
        None => Err(format!(
            "no camera `{id}` (found: {})",
            if list.is_empty() {
                "none".to_string()
            } else {
                list.iter()
                    .map(|c| format!("{} [serial {}, {}]", c.id, c.serial, c.address))
                    .collect::<Vec<_>>()
                    .join(", ")
            }
        )),
    }
}

fn open_camera(device_id: &str) -> Result<Camera, String> {
    let _guard = ARAVIS_GLOBAL.lock().unwrap_or_else(|e| e.into_inner());
    Camera::new(Some(device_id)).map_err(|e| gerr(&format!("cannot open `{device_id}`"), e))
}

/// Opens, configures and starts camera `device_id`.
fn connect(opts: &GenicamOptions, device_id: &str) -> Result<Connection, String> {
    let camera = open_camera(device_id)?;
    let c = &camera;
    let _ = c.stop_acquisition();
    c.set_acquisition_mode(AcquisitionMode::Continuous)
        .map_err(|e| gerr("AcquisitionMode", e))?;
    if let Some(f) = opts.format {
        c.set_pixel_format_from_string(genicam_format_name(f))
            .map_err(|e| gerr(&format!("PixelFormat {}", genicam_format_name(f)), e))?;
    }
    // Region: offsets to 0 first, so that any width fits, then size, then offsets.
    let (ox, oy) = (opts.offset_x as i32, opts.offset_y as i32);
    let (_, wmax) = c.width_bounds().map_err(|e| gerr("Width", e))?;
    let (_, hmax) = c.height_bounds().map_err(|e| gerr("Height", e))?;
    let (sw, sh) = c.sensor_size().unwrap_or((wmax, hmax));
    let w = opts.width.map_or((sw - ox).min(wmax), |w| w as i32);
    let h = opts.height.map_or((sh - oy).min(hmax), |h| h as i32);
    c.set_region(0, 0, w, h)
        .and_then(|()| c.set_region(ox, oy, w, h))
        .map_err(|e| gerr(&format!("region {w}x{h}+{ox}+{oy}"), e))?;
    if let Some(us) = opts.exposure_us {
        let _ = c.set_exposure_time_auto(Auto::Off);
        c.set_exposure_time(us)
            .map_err(|e| gerr(&format!("exposure {us} us"), e))?;
    }
    if let Some(g) = opts.gain {
        if !c.is_gain_available().unwrap_or(false) {
            return Err("this camera has no Gain feature".into());
        }
        let _ = c.set_gain_auto(Auto::Off);
        c.set_gain(g).map_err(|e| gerr(&format!("gain {g}"), e))?;
    }
    // Triggers off first: setting the frame rate may touch them.
    c.clear_triggers().map_err(|e| gerr("clear triggers", e))?;
    match opts.trigger {
        Trigger::Free => {
            if let Some(fps) = opts.fps {
                c.set_frame_rate(fps)
                    .map_err(|e| gerr(&format!("frame rate {fps}"), e))?;
            }
        }
        Trigger::Software | Trigger::Line0 => {
            // The camera's own rate must not hold triggers back.
            if let Ok((_, max)) = c.frame_rate_bounds() {
                let _ = c.set_frame_rate(max);
            }
            let source = if opts.trigger == Trigger::Software {
                "Software"
            } else {
                "Line0"
            };
            c.set_trigger(source)
                .map_err(|e| gerr(&format!("trigger {source}"), e))?;
        }
    }
    if c.is_gv_device() {
        match opts.packet_size {
            Some(p) => c
                .gv_set_packet_size(p as i32)
                .map_err(|e| gerr(&format!("packet size {p}"), e))?,
            None => {
                let _ = c.gv_auto_packet_size();
            }
        }
    }
    // Read back what the camera does.
    let (_, _, w, h) = c.region().map_err(|e| gerr("region", e))?;
    let name = c
        .pixel_format_as_string()
        .map_err(|e| gerr("PixelFormat", e))?;
    let format = format_from_genicam(&name)
        .ok_or_else(|| format!("pixel format {name} is not one rodtrack reads"))?;
    let arv_format = c.pixel_format().map_err(|e| gerr("PixelFormat", e))?;
    let payload = c.payload().map_err(|e| gerr("PayloadSize", e))? as usize;
    let stream = c.create_stream().map_err(|e| gerr("create stream", e))?;
    for _ in 0..opts.buffers {
        stream.push_buffer(Buffer::new_allocate(payload));
    }
    let control_lost = Arc::new(AtomicBool::new(false));
    if let Some(device) = c.device() {
        let flag = Arc::clone(&control_lost);
        device.connect_control_lost(move |_| flag.store(true, Ordering::Relaxed));
    }
    c.start_acquisition()
        .map_err(|e| gerr("start acquisition", e))?;
    Ok(Connection {
        camera,
        stream,
        device_id: device_id.to_string(),
        width: usize::try_from(w).unwrap_or(0),
        height: usize::try_from(h).unwrap_or(0),
        format,
        arv_format,
        control_lost,
        started: Instant::now(),
        alive: true,
    })
}

/// What one wait for a buffer gave.
enum Grab {
    /// A good frame in `buf`, with the camera's raw frame id.
    Frame(u64),
    /// A buffer was dropped (incomplete, stale, wrong size): try again.
    Bad(String),
    /// No buffer in time, or control lost.
    Lost(String),
}

impl GenicamSource {
    /// Opens and starts camera `opts.id` (see [`GenicamOptions`]).
    pub fn open(opts: GenicamOptions) -> Result<Self, IoError> {
        let name = format!("genicam://{}", opts.id);
        let failed = |reason: String| IoError::SourceFailed {
            name: name.clone(),
            reason,
        };
        let clock = match (opts.trigger, opts.fps) {
            (Trigger::Software, Some(fps)) => Some(match &opts.sync {
                Some(group) => group_clock(group, fps).map_err(|other| {
                    failed(format!(
                        "sync group `{group}` runs at {other} fps, not {fps}"
                    ))
                })?,
                None => TriggerClock::new(fps),
            }),
            (Trigger::Software, None) => {
                return Err(failed("software triggers need `fps`".into()));
            }
            _ => None,
        };
        // Always through the device list: a GigE camera opened without a fresh discovery may
        // stream to nowhere (seen with the fake camera after a restart).
        let device_id = resolve(&opts.id).map_err(&failed)?;
        let conn = connect(&opts, &device_id).map_err(failed)?;
        Ok(GenicamSource {
            name,
            width: conn.width,
            height: conn.height,
            format: conn.format,
            conn: Some(conn),
            opts,
            ids: IdExtender::new(0),
            counters: Arc::new(GenicamCounters::default()),
            clock,
            last_tick: None,
            fired_at_ns: 0,
            resync: false,
            lost: None,
            failed: false,
            recovering_since: None,
            last_frame_at: None,
            ts_offset: 0,
            last_ts: None,
            rebase_ts: false,
        })
    }

    /// The Aravis device id of the open camera.
    pub fn device_id(&self) -> Option<&str> {
        self.conn.as_ref().map(|c| c.device_id.as_str())
    }

    /// The options it was opened with.
    pub fn options(&self) -> &GenicamOptions {
        &self.opts
    }

    /// Counters so far.
    pub fn stats(&self) -> GenicamStats {
        self.counters.snapshot()
    }

    /// The counters, shared: readable from another thread while the source runs in a pipeline.
    pub fn counters(&self) -> Arc<GenicamCounters> {
        Arc::clone(&self.counters)
    }

    /// Streaming, reconnecting or failed.
    pub fn status(&self) -> CameraStatus {
        match (&self.lost, self.failed) {
            (_, true) => CameraStatus::Failed,
            (Some(l), _) => CameraStatus::Reconnecting {
                attempts: l.attempts,
                reason: l.reason.clone(),
            },
            (None, _) => CameraStatus::Streaming,
        }
    }

    /// The trigger clock (software triggers), to share with sources opened by other means.
    pub fn trigger_clock(&self) -> Option<Arc<TriggerClock>> {
        self.clock.clone()
    }

    /// Marks the camera lost, drops the connection; the error to return.
    fn mark_lost(&mut self, reason: String) -> IoError {
        if let Some(mut c) = self.conn.take() {
            c.alive = false;
            // Releasing a GigE camera that is gone waits for its control timeouts (seconds):
            // not in the capture thread.
            let _ = std::thread::Builder::new()
                .name("genicam-release".into())
                .spawn(move || drop(c));
        }
        GenicamCounters::add(&self.counters.disconnects, 1);
        let now = Instant::now();
        self.lost = Some(Lost {
            reason: reason.clone(),
            since: self.last_frame_at.unwrap_or(now),
            next_attempt: now + FIRST_BACKOFF,
            backoff: FIRST_BACKOFF,
            attempts: 0,
        });
        lost_error(&self.name, &reason)
    }

    /// One reconnection attempt (waiting for its time first). `Ok` when connected again.
    fn reconnect(&mut self) -> Result<(), IoError> {
        let Some(lost) = self.lost.as_mut() else {
            return Ok(());
        };
        let now = Instant::now();
        if lost.next_attempt > now {
            std::thread::sleep(lost.next_attempt - now);
        }
        let result = resolve(&self.opts.id).and_then(|id| connect(&self.opts, &id));
        let lost = self
            .lost
            .as_mut()
            .ok_or_else(|| lost_error(&self.name, "?"))?;
        match result {
            Ok(conn) => {
                if (conn.width, conn.height, conn.format) != (self.width, self.height, self.format)
                {
                    // Cannot happen with explicit settings; do not deliver a changed stream.
                    self.failed = true;
                    return Err(IoError::SourceFailed {
                        name: self.name.clone(),
                        reason: format!(
                            "reconnected camera delivers {}x{} {}, not {}x{} {}",
                            conn.width,
                            conn.height,
                            conn.format,
                            self.width,
                            self.height,
                            self.format
                        ),
                    });
                }
                let gap = lost.since.elapsed().as_secs_f64();
                let skipped = match (self.opts.trigger, self.opts.fps) {
                    (Trigger::Free, Some(fps)) => ((gap * fps).round() as u64).saturating_sub(1),
                    _ => 0,
                };
                self.ids.restart(skipped);
                self.recovering_since = Some(lost.since);
                self.lost = None;
                self.conn = Some(conn);
                self.rebase_ts = true;
                self.resync = false;
                GenicamCounters::add(&self.counters.reconnects, 1);
                Ok(())
            }
            Err(reason) => {
                lost.attempts += 1;
                lost.backoff = (lost.backoff * 2).min(MAX_BACKOFF);
                lost.next_attempt = Instant::now() + lost.backoff;
                if let Some(limit) = self.opts.give_up_after {
                    if lost.since.elapsed() > limit {
                        self.failed = true;
                        return Err(IoError::SourceFailed {
                            name: self.name.clone(),
                            reason: format!(
                                "camera lost ({}); no reconnection in {:.1} s: {reason}",
                                lost.reason,
                                limit.as_secs_f64()
                            ),
                        });
                    }
                }
                Err(lost_error(
                    &self.name,
                    &format!(
                        "{}; reconnection attempt {} failed: {reason}",
                        lost.reason, lost.attempts
                    ),
                ))
            }
        }
    }

    /// Software trigger: wait for the next tick and fire it. Returns the tick.
    fn fire_trigger(&mut self) -> Result<u64, String> {
        let (clock, conn) = match (&self.clock, &self.conn) {
            (Some(c), Some(n)) => (c, n),
            _ => return Err("no trigger clock".into()),
        };
        if self.resync {
            // A frame that came too late must not be taken for the next trigger's.
            while let Some(b) = conn.stream.try_pop_buffer() {
                GenicamCounters::add(&self.counters.stale, 1);
                conn.stream.push_buffer(b);
            }
            self.resync = false;
        }
        let (k, at) = clock.next_tick(self.last_tick);
        clock.wait_for(at);
        self.fired_at_ns = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .map_or(0, |d| u64::try_from(d.as_nanos()).unwrap_or(u64::MAX));
        conn.camera
            .software_trigger()
            .map_err(|e| gerr("software trigger", e))?;
        if let Some(prev) = self.last_tick {
            GenicamCounters::add(&self.counters.dropped, k.saturating_sub(prev + 1));
        }
        self.last_tick = Some(k);
        Ok(k)
    }

    /// Waits for one buffer and, if it is good, copies it into `buf`.
    fn grab(&mut self, buf: &mut FrameBuffer, tick: Option<u64>) -> Grab {
        let Some(conn) = self.conn.as_ref() else {
            return Grab::Lost("not connected".into());
        };
        // With software triggers, wait a few periods for this trigger's frame; a camera may
        // miss a trigger (the fake one does right after starting) without being lost.
        let wait = match (tick, self.clock.as_ref()) {
            (Some(_), Some(c)) => self
                .opts
                .frame_timeout
                .min(Duration::from_secs_f64(3.0 / c.fps()).max(Duration::from_millis(100))),
            _ => self.opts.frame_timeout,
        };
        let timeout_us = u64::try_from(wait.as_micros()).unwrap_or(u64::MAX);
        let Some(buffer) = conn.stream.timeout_pop_buffer(timeout_us) else {
            GenicamCounters::add(&self.counters.timeouts, 1);
            if conn.control_lost.load(Ordering::Relaxed) {
                return Grab::Lost("control lost".into());
            }
            if self.opts.trigger == Trigger::Line0 {
                return Grab::Bad("no trigger on line 0 yet".into());
            }
            self.resync = true;
            let last = self
                .last_frame_at
                .filter(|t| *t > conn.started)
                .unwrap_or(conn.started);
            if last.elapsed() < self.opts.frame_timeout {
                return Grab::Bad(format!("no frame for trigger {}", tick.unwrap_or(0)));
            }
            return Grab::Lost(format!(
                "no frame for {:.1} s",
                last.elapsed().as_secs_f64()
            ));
        };
        let result = self.take(conn, &buffer, buf, tick);
        conn.stream.push_buffer(buffer);
        result
    }

    fn take(
        &self,
        conn: &Connection,
        buffer: &Buffer,
        buf: &mut FrameBuffer,
        tick: Option<u64>,
    ) -> Grab {
        let status = buffer.status();
        if status != BufferStatus::Success {
            GenicamCounters::add(&self.counters.incomplete, 1);
            return Grab::Bad(format!("buffer {status:?}"));
        }
        let (w, h) = (buffer.image_width(), buffer.image_height());
        let (w, h) = (
            usize::try_from(w).unwrap_or(0),
            usize::try_from(h).unwrap_or(0),
        );
        if (w, h) != (conn.width, conn.height) || buffer.image_pixel_format() != conn.arv_format {
            GenicamCounters::add(&self.counters.incomplete, 1);
            return Grab::Bad(format!(
                "buffer is {w}x{h} {:?}, expected {}x{} {}",
                buffer.image_pixel_format(),
                conn.width,
                conn.height,
                conn.format
            ));
        }
        if tick.is_some() && buffer.system_timestamp() < self.fired_at_ns {
            // Arrived before this trigger was fired: a late answer to an earlier one.
            GenicamCounters::add(&self.counters.stale, 1);
            return Grab::Bad("late frame of an earlier trigger".into());
        }
        let bpp = conn.format.bytes_per_pixel();
        let row = w * bpp;
        let (pad_x, _) = buffer.image_padding();
        let stride = row + usize::try_from(pad_x).unwrap_or(0);
        let data = ffi::buffer_bytes(buffer);
        let need = if h == 0 { 0 } else { stride * (h - 1) + row };
        if data.len() < need {
            GenicamCounters::add(&self.counters.incomplete, 1);
            return Grab::Bad(format!("buffer holds {} bytes, need {need}", data.len()));
        }
        buf.reshape_packed(w, h, conn.format);
        if stride == row {
            buf.data.copy_from_slice(&data[..row * h]);
        } else {
            for (d, s) in buf.data.chunks_exact_mut(row).zip(data.chunks(stride)) {
                d.copy_from_slice(&s[..row]);
            }
        }
        buf.meta.frame_id = tick.unwrap_or(0);
        buf.meta.timestamp_ns = Timestamp::from_nanos(match self.opts.timestamps {
            TimestampSource::Camera => buffer.timestamp(),
            TimestampSource::Host => buffer.system_timestamp(),
        });
        Grab::Frame(buffer.frame_id())
    }

    /// Frame id and timestamp bookkeeping for a good frame; false if it is stale.
    fn accept(&mut self, buf: &mut FrameBuffer, raw_id: u64, tick: Option<u64>) -> bool {
        match self.ids.step(raw_id) {
            IdStep::Stale => {
                GenicamCounters::add(&self.counters.stale, 1);
                return false;
            }
            IdStep::Next { id, missed } => {
                if tick.is_none() {
                    buf.meta.frame_id = id;
                    GenicamCounters::add(&self.counters.dropped, missed);
                }
            }
        }
        if self.opts.timestamps == TimestampSource::Camera {
            let raw = i128::from(buf.meta.timestamp_ns.as_nanos());
            if std::mem::take(&mut self.rebase_ts) {
                // Continue from the last timestamp plus the host time that passed.
                if let (Some(last), Some(at)) = (self.last_ts, self.last_frame_at) {
                    let gap = i128::try_from(at.elapsed().as_nanos()).unwrap_or(0);
                    self.ts_offset = i128::from(last) + gap.max(1) - raw;
                }
            }
            let ts = (raw + self.ts_offset).max(i128::from(self.last_ts.map_or(0, |t| t + 1)));
            let ts = u64::try_from(ts.max(0)).unwrap_or(u64::MAX);
            buf.meta.timestamp_ns = Timestamp::from_nanos(ts);
            self.last_ts = Some(ts);
        }
        let now = Instant::now();
        self.last_frame_at = Some(now);
        if let Some(since) = self.recovering_since.take() {
            let us = u64::try_from(now.duration_since(since).as_micros()).unwrap_or(u64::MAX);
            self.counters.last_recovery_us.store(us, Ordering::Relaxed);
            self.counters
                .max_recovery_us
                .fetch_max(us, Ordering::Relaxed);
        }
        GenicamCounters::add(&self.counters.frames, 1);
        true
    }
}

impl FrameSource for GenicamSource {
    fn info(&self) -> SourceInfo {
        SourceInfo {
            name: self.name.clone(),
            width: self.width,
            height: self.height,
            format: self.format,
            fps: self.opts.fps.or_else(|| {
                self.conn
                    .as_ref()
                    .and_then(|c| c.camera.frame_rate().ok())
                    .filter(|f| *f > 0.0)
            }),
            frame_count: None,
            live: true,
        }
    }

    fn next_frame(&mut self, buf: &mut FrameBuffer) -> Result<Option<()>, SourceError> {
        if self.failed {
            return Ok(None);
        }
        if self.lost.is_some() {
            self.reconnect()?;
        }
        let mut bad = 0u32;
        loop {
            let tick = if self.clock.is_some() {
                match self.fire_trigger() {
                    Ok(k) => Some(k),
                    Err(reason) => return Err(self.mark_lost(reason)),
                }
            } else {
                None
            };
            match self.grab(buf, tick) {
                Grab::Frame(raw) => {
                    if self.accept(buf, raw, tick) {
                        return Ok(Some(()));
                    }
                }
                Grab::Lost(reason) => return Err(self.mark_lost(reason)),
                Grab::Bad(reason) => {
                    bad += 1;
                    if bad >= MAX_BAD_IN_A_ROW {
                        return Err(IoError::Decode {
                            path: self.name.clone().into(),
                            reason: format!("{bad} bad buffers in a row; last: {reason}"),
                        });
                    }
                }
            }
        }
    }
}

/// Opens a parsed `genicam://ID?...` input (see [`GenicamOptions::from_spec`]).
pub fn open_input(
    spec: &InputSpec,
    options: &OpenOptions,
) -> Result<Box<dyn FrameSource>, IoError> {
    let opts = GenicamOptions::from_spec(spec, options)?;
    Ok(Box::new(GenicamSource::open(opts)?))
}

/// Registers the `genicam` scheme (`genicam://ID?...`, see [`GenicamOptions::from_spec`]).
pub fn register(factory: &mut SourceFactory) {
    factory.register("genicam", Box::new(open_input));
}

/// The cameras Aravis sees now (GigE discovery takes about a second), for `rodtrack cameras`.
pub fn list_cameras() -> Result<Vec<CameraInfo>, IoError> {
    Ok(ffi::device_list())
}
