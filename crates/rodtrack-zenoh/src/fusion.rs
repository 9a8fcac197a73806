//! The fusion node: the camera nodes' measured rows through the runtime pipeline, with the
//! same stages as an in-process session (each camera's `CameraFilter`, the frame-set grouper,
//! `SetFusion`, the overruled camera rows flagged), into the caller's sink and onto
//! `rodtrack/<table>/fused/rows`.
//!
//! Each camera of the calibration is a pipeline camera whose source is its messages
//! (`rodtrack/<table>/cam/<name>/raw`): a message is a "frame" whose rows the processing stage
//! passes on as measured. The grouper then forms the frame sets exactly as for local cameras
//! (by frame id, or by timestamp within half a frame period).
//!
//! A camera whose messages stop while another camera's go on is **lost** after
//! [`FusionOptions::loss_periods`] frame periods: it is reported (stderr through the `log`
//! callback, and `.../fused/status`), and the frame sets go on without waiting for it, marked
//! incomplete (the fused messages' `complete` flag and camera mask). When its messages come
//! back it is taken back; its frames whose sets went out without it are written on their own,
//! not fused again. A camera node that ends its run says so (`end`), and is not waited for
//! either.

use crate::layout::{camera_bit, decode, Header, Kind, Message};
use crate::net::{camera_key, fused_key, NetworkOptions, RowPublisher, WireFormat};
use crate::ros2::{Ros2BallPublisher, Ros2Names, Ros2Node, Ros2Publisher};
use crate::ZenohError;
use rodtrack_core::calib::CalibrationFile;
use rodtrack_core::{CameraFilter, CameraId, Measurement, Mode, PixelFormat, SetFusion};
use rodtrack_io::runtime::{
    Grouping, Handoff, Pipeline, PipelineConfig, PipelineReport, RunMode, WriteMode,
};
use rodtrack_io::source::SourceInfo;
use rodtrack_io::{FrameBuffer, FrameSource, IoError, MeasurementSink, SourceError};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{sync_channel, Receiver, RecvTimeoutError, SyncSender};
use std::sync::{Arc, Mutex, OnceLock};
use std::time::{Duration, Instant};
use zenoh::Wait;

mod ball;
mod status;
mod watch;
pub use ball::{BallReport, FusionEvents};
use status::status_json;
pub use watch::CameraState;
use watch::{CameraWatch, Watch};

/// How frames of the cameras are matched.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SetGrouping {
    /// By frame id (hardware-triggered cameras, a shared trigger counter).
    #[default]
    FrameId,
    /// By capture timestamp, within half a frame period (cameras not triggered together).
    Timestamp,
}

/// How the fusion node runs.
#[derive(Debug, Clone)]
pub struct FusionOptions {
    /// The algorithm the cameras run (it tunes the filters).
    pub mode: Mode,
    /// Frame matching.
    pub grouping: SetGrouping,
    /// A camera silent for this many frame periods while another one sends is lost.
    pub loss_periods: f64,
    /// Publish the fused rows on `rodtrack/<table>/fused/rows`.
    pub publish: bool,
    /// Also publish them for ROS 2 over rmw_zenoh in this domain, as
    /// `sensor_msgs/msg/JointState` on `/rodtrack/<table>/joint_states` ([`crate::ros2`]).
    pub ros2_domain: Option<u32>,
}

impl Default for FusionOptions {
    fn default() -> Self {
        FusionOptions {
            mode: Mode::Enhanced,
            grouping: SetGrouping::FrameId,
            loss_periods: 3.0,
            publish: true,
            ros2_domain: None,
        }
    }
}

/// One camera's messages as a frame source of the pipeline: each message a 1x1 "frame" with
/// its frame id and timestamp, its rows left in `slot` for the processing stage (run right
/// after in the same thread, [`Handoff::Inline`]).
struct RowSource {
    pos: usize,
    rx: Receiver<Message>,
    slot: Arc<Mutex<Vec<Measurement>>>,
    watch: Arc<Watch>,
    stop: Arc<AtomicBool>,
    grouping: SetGrouping,
    name: String,
    fps: f64,
}

impl RowSource {
    fn key(&self, h: &Header) -> u64 {
        match self.grouping {
            SetGrouping::FrameId => h.frame,
            SetGrouping::Timestamp => h.timestamp_ns.as_nanos(),
        }
    }

    /// Takes back a camera that was lost or ended, at its first message. Its frames are
    /// taken from there on: one whose frame set was written while it was away goes out on its
    /// own (its rows written, not fused: the set's fused rows are out already), so no row of
    /// a camera that was slow rather than gone is lost.
    fn take_back(&self, m: &Message) {
        let me = &self.watch.cameras[self.pos];
        let was = me.state();
        let missed = m
            .header
            .frame
            .saturating_sub(me.last_frame.load(Ordering::Relaxed))
            .saturating_sub(1);
        if was == CameraState::Lost {
            me.frames_missed.fetch_add(missed, Ordering::Relaxed);
        }
        me.returns.fetch_add(1, Ordering::Relaxed);
        me.set_state(CameraState::Ok);
        self.watch.set_absent(self.pos, false);
        (self.watch.log)(&format!(
            "fusion: camera {} ({}) back at frame {} after being {} ({} frame(s) missed); frame sets are complete again",
            me.index,
            me.name,
            m.header.frame,
            was.name(),
            missed
        ));
    }
}

impl FrameSource for RowSource {
    fn info(&self) -> SourceInfo {
        SourceInfo {
            name: self.name.clone(),
            width: 2,
            height: 2,
            format: PixelFormat::Mono8,
            fps: Some(self.fps),
            frame_count: None,
            live: true,
        }
    }

    fn next_frame(&mut self, buf: &mut FrameBuffer) -> Result<Option<()>, SourceError> {
        let tick = Duration::from_nanos((self.watch.period_ns / 4).max(100_000));
        loop {
            if self.stop.load(Ordering::Relaxed) {
                return Ok(None);
            }
            let m = match self.rx.recv_timeout(tick) {
                Ok(m) => m,
                Err(RecvTimeoutError::Timeout) => {
                    self.watch.check_loss(self.pos);
                    continue;
                }
                Err(RecvTimeoutError::Disconnected) => return Ok(None),
            };
            let w = &self.watch;
            let me = &w.cameras[self.pos];
            w.heard(self.pos, w.now_ns());
            if m.header.kind == Kind::End {
                if me.state() != CameraState::Ended {
                    me.set_state(CameraState::Ended);
                    w.set_absent(self.pos, true);
                    (w.log)(&format!(
                        "fusion: camera {} ({}) ended its run after frame {}; frame sets go on without it",
                        me.index, me.name, m.header.frame
                    ));
                }
                continue;
            }
            match me.state() {
                CameraState::Lost | CameraState::Ended => self.take_back(&m),
                CameraState::Waiting => me.set_state(CameraState::Ok),
                CameraState::Ok => {}
            }
            me.last_key.store(self.key(&m.header), Ordering::Relaxed);
            me.last_frame.store(m.header.frame, Ordering::Relaxed);
            buf.reshape_packed(2, 2, PixelFormat::Mono8);
            buf.meta.frame_id = m.header.frame;
            buf.meta.timestamp_ns = m.header.timestamp_ns;
            let mut slot = self.slot.lock().unwrap_or_else(|e| e.into_inner());
            slot.clear();
            slot.extend_from_slice(&m.rows);
            return Ok(Some(()));
        }
    }
}

/// The last frame set's completeness, from the fusion stage to the sink (same thread).
#[derive(Debug, Default, Clone, Copy)]
struct SetState {
    complete: bool,
    cameras: u64,
}

/// Writes to the caller's sink and publishes the fused rows.
struct FusedSink<S> {
    inner: S,
    publisher: Option<RowPublisher>,
    ros2: Option<Ros2Publisher>,
    set: Arc<Mutex<SetState>>,
    fused: Vec<Measurement>,
    rows_published: u64,
    sets_published: u64,
    publish_errors: u64,
    first_publish_error: Option<String>,
}

impl<S: MeasurementSink> MeasurementSink for FusedSink<S> {
    fn write(&mut self, rows: &[Measurement]) -> Result<(), IoError> {
        let r = self.inner.write(rows);
        if self.publisher.is_some() || self.ros2.is_some() {
            self.fused.clear();
            self.fused
                .extend(rows.iter().filter(|m| m.camera == CameraId::Fused));
        }
        if let Some(p) = &self.publisher {
            if !self.fused.is_empty() {
                let s = *self.set.lock().unwrap_or_else(|e| e.into_inner());
                match p.publish_runs(Kind::Fused, s.complete, s.cameras, &self.fused) {
                    Ok(()) => {
                        self.rows_published += self.fused.len() as u64;
                        self.sets_published += 1;
                    }
                    Err(e) => {
                        self.publish_errors += 1;
                        self.first_publish_error.get_or_insert(e.to_string());
                    }
                }
            }
        }
        // After the fused rows: ROS 2 subscribers do not hold up the fusion's own.
        if let Some(p) = &self.ros2 {
            if let Err(e) = p.publish_frames(&self.fused) {
                self.publish_errors += 1;
                self.first_publish_error.get_or_insert(e.to_string());
            }
        }
        r
    }
    fn flush(&mut self) -> Result<(), IoError> {
        self.inner.flush()
    }
}

/// What a fusion run did.
#[derive(Debug, Clone)]
pub struct FusionReport {
    /// The pipeline's report (sets complete and incomplete, rows written, latency).
    pub pipeline: PipelineReport,
    /// Per camera: name, state at the end, times lost, times taken back, frames missed while
    /// lost, messages refused.
    pub cameras: Vec<CameraSummary>,
    /// Fused rows published, and the frame sets they belong to.
    pub rows_published: u64,
    /// Frame sets whose fused rows were published.
    pub sets_published: u64,
    /// Fused messages that could not be published, and the first error.
    pub publish_errors: u64,
    /// The first publishing error.
    pub first_publish_error: Option<String>,
    /// The ball's rows, when a camera of the calibration has a ball.
    pub ball: Option<BallReport>,
}

/// One camera's numbers in a [`FusionReport`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CameraSummary {
    /// Index in the calibration.
    pub index: u32,
    /// Name in the calibration (and the key expression).
    pub name: String,
    /// State at the end.
    pub state: CameraState,
    /// Times lost.
    pub losses: u64,
    /// Times taken back.
    pub returns: u64,
    /// Frames missed while lost.
    pub frames_missed: u64,
    /// Messages refused or dropped.
    pub refused: u64,
}

impl std::fmt::Display for FusionReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let p = &self.pipeline;
        writeln!(
            f,
            "fusion: {} frame sets complete, {} incomplete, {} rows written",
            p.sets_complete, p.sets_incomplete, p.rows_written
        )?;
        for c in &self.cameras {
            writeln!(
                f,
                "  camera {} ({}): {}, lost {}x, taken back {}x, {} frame(s) missed, {} message(s) refused",
                c.index,
                c.name,
                c.state.name(),
                c.losses,
                c.returns,
                c.frames_missed,
                c.refused
            )?;
        }
        if self.sets_published > 0 || self.publish_errors > 0 {
            writeln!(
                f,
                "  published: {} fused rows of {} frame sets",
                self.rows_published, self.sets_published
            )?;
        }
        if self.publish_errors > 0 {
            writeln!(
                f,
                "  {} fused message(s) not published (first: {})",
                self.publish_errors,
                self.first_publish_error.as_deref().unwrap_or("?")
            )?;
        }
        if let Some(b) = &self.ball {
            let c = &b.counts;
            writeln!(
                f,
                "  ball rows: {} ok, {} predicted, {} lost, {} conflict; {} ball message(s) refused",
                c.ok, c.predicted, c.lost, c.conflict, b.refused
            )?;
            if let Some(e) = &b.events {
                writeln!(f, "  events: {e}")?;
            }
        }
        Ok(())
    }
}

/// Where the fusion node's ball goes besides the network.
#[derive(Default)]
pub struct BallOutputs {
    /// Every camera's ball rows and the fused ones.
    pub rows: Option<Box<dyn rodtrack_io::BallSink>>,
    /// Detect the ball's events (goals with the score, shots, ball out, ball stopped) from the
    /// fused rows, as an in-process session does: published on `.../fused/events` when
    /// publishing, and into the sink given.
    pub events: Option<FusionEvents>,
}

/// Runs the fusion node until `stop` is set: subscribes to every camera of `cal`, fuses, and
/// writes every camera's filtered rows and the fused rows into `sink` (as `track` writes them
/// for local cameras), publishing the fused rows when [`FusionOptions::publish`]. The camera
/// nodes' ball rows (of the cameras with a ball calibration) are fused per frame too, into
/// `ball.rows` and, when publishing, onto `.../fused/ball`; with `ball.events`, they give the
/// events too. `log` gets the cameras' losses and returns and the messages refused.
pub fn run_fusion<S: MeasurementSink + 'static>(
    cal: &CalibrationFile,
    net: &NetworkOptions,
    options: &FusionOptions,
    sink: S,
    ball: BallOutputs,
    stop: Arc<AtomicBool>,
    log: Box<dyn Fn(&str) + Send + Sync>,
) -> Result<(FusionReport, S), ZenohError> {
    let log: ball::Log = Arc::from(log);
    let table = net.table()?.to_string();
    if cal.cameras.len() < 2 {
        return Err(ZenohError::Invalid(format!(
            "the calibration has {} camera(s): the fusion needs at least 2",
            cal.cameras.len()
        )));
    }
    if cal.cameras.iter().any(|c| c.index >= 64) {
        return Err(ZenohError::Invalid(
            "camera indices of 64 and over do not fit the messages' camera mask".into(),
        ));
    }
    for c in &cal.cameras {
        crate::net::check_chunk("camera name", &c.name)?;
    }
    let fps = cal
        .cameras
        .iter()
        .map(|c| c.fps)
        .filter(|f| f.is_finite() && *f > 0.0)
        .fold(0.0f64, f64::max);
    if fps <= 0.0 {
        return Err(ZenohError::Invalid(
            "the calibration gives no camera frame rate (fps)".into(),
        ));
    }
    if !(options.loss_periods.is_finite() && options.loss_periods >= 1.0) {
        return Err(ZenohError::Invalid(format!(
            "the loss time must be at least 1 frame period, got {}",
            options.loss_periods
        )));
    }
    let period_ns = (1e9 / fps).round() as u64;
    // Noticed within the loss time plus the source's tick (a quarter period) and the wake-up's
    // delay: half a period of margin.
    let loss_ns = ((options.loss_periods - 0.5).max(0.5) * period_ns as f64) as u64;
    let watch = Arc::new(Watch {
        started: Instant::now(),
        cameras: cal
            .cameras
            .iter()
            .map(|c| CameraWatch::new(c.name.clone(), c.index))
            .collect(),
        first_any_ns: AtomicU64::new(0),
        loss_ns,
        period_ns,
        key_slack: match options.grouping {
            SetGrouping::FrameId => 0,
            SetGrouping::Timestamp => period_ns / 2,
        },
        log: Box::new({
            let log = log.clone();
            move |s: &str| log(s)
        }),
        counters: OnceLock::new(),
    });
    let session = net.open()?;
    // The ROS 2 node first, its joint states' publisher its entity 1, then the ball's.
    let ros2_node = match options.ros2_domain {
        Some(domain) => Some(Ros2Node::declare(
            &session,
            &Ros2Names::fused(domain, &table)?,
        )?),
        None => None,
    };
    let ros2 = match &ros2_node {
        Some(node) => Some(Ros2Publisher::declare(&session, node)?),
        None => None,
    };
    let ball_diameter_mm = cal
        .cameras
        .iter()
        .find_map(|c| c.ball.as_ref().map(|b| b.diameter_mm));
    let ros2_ball = match (&ros2_node, ball_diameter_mm) {
        (Some(node), Some(d)) => Some(Ros2BallPublisher::declare(&session, node, d)?),
        _ => None,
    };
    let ball_fusion = if ball_diameter_mm.is_none() {
        if ball.events.is_some() {
            return Err(ZenohError::Invalid(
                "the events need the ball: no camera of the calibration has `[cameras.ball]`"
                    .into(),
            ));
        }
        None
    } else {
        Some(ball::BallFusion::start(
            &session,
            &table,
            cal,
            options.loss_periods.ceil() as u64,
            options.publish.then_some(net.format),
            ros2_ball,
            ball.rows,
            ball.events,
            log.clone(),
        )?)
    };
    let rods_for_events = ball_fusion.as_ref().and_then(ball::BallFusion::rods);
    let grouping = match options.grouping {
        SetGrouping::FrameId => Grouping::FrameId,
        SetGrouping::Timestamp => Grouping::Timestamp {
            window_ns: period_ns / 2,
        },
    };
    let mut pipeline = Pipeline::new(PipelineConfig {
        mode: RunMode::Live,
        grouping,
        group_timeout: Duration::from_nanos(loss_ns),
        handoff: Handoff::Inline,
        write: WriteMode::Set,
        ..PipelineConfig::default()
    });
    let stop_flag = pipeline.stop_flag();
    let mut senders: Vec<SyncSender<Message>> = Vec::new();
    for (pos, cam) in cal.cameras.iter().enumerate() {
        let (tx, rx) = sync_channel(1024);
        senders.push(tx);
        let slot = Arc::new(Mutex::new(Vec::with_capacity(64)));
        let source = RowSource {
            pos,
            rx,
            slot: slot.clone(),
            watch: watch.clone(),
            stop: stop_flag.clone(),
            grouping: options.grouping,
            name: camera_key(&table, &cam.name, "raw"),
            fps,
        };
        let index = pipeline.add_camera(
            Box::new(source),
            Box::new(move |_meta, _frame, rows| {
                let mut s = slot.lock().unwrap_or_else(|e| e.into_inner());
                rows.append(&mut s);
            }),
        );
        let mut filter = CameraFilter::new(options.mode);
        pipeline.set_camera_filter(
            index,
            Box::new(move |_m, rows, out| filter.process(rows, out)),
        )?;
    }
    let set = Arc::new(Mutex::new(SetState::default()));
    let overruled = Arc::new(Mutex::new(Vec::with_capacity(64)));
    {
        let flags = overruled.clone();
        pipeline.set_camera_rows_after_fusion(Box::new(move |rows: &mut [Measurement]| {
            let list = flags.lock().unwrap_or_else(|e| e.into_inner());
            rodtrack_core::fusion::flag_overruled_rows(&list, rows);
        }));
        let mut fusion = SetFusion::new(options.mode);
        let (set, indices) = (
            set.clone(),
            cal.cameras.iter().map(|c| c.index).collect::<Vec<_>>(),
        );
        pipeline.set_fusion(Box::new(move |info, raw, out| {
            fusion.process(raw, out);
            let mut list = overruled.lock().unwrap_or_else(|e| e.into_inner());
            list.clear();
            list.extend_from_slice(fusion.overruled());
            let mut s = set.lock().unwrap_or_else(|e| e.into_inner());
            s.complete = info.complete;
            s.cameras = info
                .frames
                .iter()
                .zip(&indices)
                .filter(|(f, _)| f.is_some())
                .fold(0, |m, (_, &i)| m | camera_bit(i));
        }));
    }
    let counters = pipeline.counters();
    let _ = watch.counters.set(counters.clone());
    // Messages from the camera nodes, by the camera name in the key.
    let prefix = format!("rodtrack/{table}/cam/");
    let names: Vec<String> = cal.cameras.iter().map(|c| c.name.clone()).collect();
    let sub_watch = watch.clone();
    let unknown = Mutex::new(Vec::<String>::new());
    let subscriber = session
        .declare_subscriber(format!("{prefix}*/raw"))
        .callback(move |sample| {
            let key = sample.key_expr().as_str();
            let name = key
                .strip_prefix(&prefix)
                .and_then(|k| k.strip_suffix("/raw"))
                .unwrap_or(key);
            let Some(pos) = names.iter().position(|n| n == name) else {
                let mut u = unknown.lock().unwrap_or_else(|e| e.into_inner());
                if !u.iter().any(|n| n == name) {
                    u.push(name.to_string());
                    (sub_watch.log)(&format!(
                        "fusion: warning: rows on {key} from camera {name:?}, which the calibration does not have (it has {}): ignored",
                        names.join(", ")
                    ));
                }
                return;
            };
            let cam = &sub_watch.cameras[pos];
            let refuse = |why: String| {
                let n = cam.refused.fetch_add(1, Ordering::Relaxed) + 1;
                if n <= 10 {
                    (sub_watch.log)(&format!("fusion: camera {} ({}): message on {key} refused: {why}", cam.index, cam.name));
                }
            };
            let bytes = sample.payload().to_bytes();
            let m = match decode(&bytes) {
                Ok(m) => m,
                Err(e) => return refuse(e.to_string()),
            };
            if !matches!(m.header.kind, Kind::CameraRaw | Kind::End) {
                return refuse(format!("a {} message on a raw key", m.header.kind.name()));
            }
            if let Some(r) = m.rows.iter().find(|r| r.camera != CameraId::Camera(cam.index)) {
                return refuse(format!(
                    "a row of camera {} where the calibration has camera {} ({}): is the node's calibration the same?",
                    r.camera, cam.index, cam.name
                ));
            }
            if let (Some(tx), Kind::CameraRaw) = (&rods_for_events, m.header.kind) {
                // Before the camera's ball row of the frame, which comes after on the link.
                let _ = tx.try_send(ball::Feed::Rods(m.rows.clone()));
            }
            if senders[pos].try_send(m).is_err() {
                refuse("the fusion is behind: queue full, message dropped".into());
            }
        })
        .wait()
        .map_err(|e| ZenohError::zenoh("declaring the subscriber", e))?;
    let publisher = if options.publish {
        Some(RowPublisher::declare(
            &session,
            fused_key(&table, "rows"),
            net.format,
        )?)
    } else {
        None
    };
    let status = RowPublisher::declare(&session, fused_key(&table, "status"), WireFormat::Json)?;
    let done = Arc::new(AtomicBool::new(false));
    let monitor = {
        let (done, watch, counters, stop, stop_flag) = (
            done.clone(),
            watch.clone(),
            counters.clone(),
            stop.clone(),
            stop_flag.clone(),
        );
        let table = table.clone();
        std::thread::Builder::new()
            .name("rodtrack-fusion-status".into())
            .spawn(move || {
                let mut last = Instant::now();
                while !done.load(Ordering::SeqCst) {
                    std::thread::sleep(Duration::from_millis(20));
                    if stop.load(Ordering::SeqCst) {
                        stop_flag.store(true, Ordering::SeqCst);
                    }
                    if last.elapsed() >= Duration::from_secs(1) {
                        last = Instant::now();
                        let _ = status.publish_text(&status_json(&table, &watch, &counters));
                    }
                }
            })
            .map_err(|e| ZenohError::Invalid(format!("cannot start the status thread: {e}")))?
    };
    let result = pipeline.run_direct(FusedSink {
        inner: sink,
        publisher,
        ros2,
        set,
        fused: Vec::with_capacity(64),
        rows_published: 0,
        sets_published: 0,
        publish_errors: 0,
        first_publish_error: None,
    });
    done.store(true, Ordering::SeqCst);
    let _ = monitor.join();
    drop(subscriber);
    let ball_report = ball_fusion.map(ball::BallFusion::finish).transpose();
    let (report, sink) = result?;
    let ball = ball_report?;
    let cameras = watch
        .cameras
        .iter()
        .map(|c| CameraSummary {
            index: c.index,
            name: c.name.clone(),
            state: c.state(),
            losses: c.losses.load(Ordering::Relaxed),
            returns: c.returns.load(Ordering::Relaxed),
            frames_missed: c.frames_missed.load(Ordering::Relaxed),
            refused: c.refused.load(Ordering::Relaxed),
        })
        .collect();
    let _ = session.close().wait();
    Ok((
        FusionReport {
            pipeline: report,
            cameras,
            rows_published: sink.rows_published,
            sets_published: sink.sets_published,
            publish_errors: sink.publish_errors,
            first_publish_error: sink.first_publish_error,
            ball,
        },
        sink.inner,
    ))
}
