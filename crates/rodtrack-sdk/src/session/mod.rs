//! A tracking session: cameras (a source and a tracker each) run through the runtime
//! pipeline into a sink, with the temporal filter and the fusion, and hooks for the user.
//!
//! ```text
//!  recordings (batch):
//!  source 0 -> [capture 0] -> queue -> [tracker 0 + filter 0] --\
//!                                                                 >-> [group by frame id, fusion] -> sink
//!  source 1 -> [capture 1] -> queue -> [tracker 1 + filter 1] --/
//!
//!  live sources: one thread per camera reads, tracks and filters its frame; the thread that
//!  completes a frame set fuses it and writes the whole set (every camera's rows, then the
//!  fused ones).
//! ```
//!
//! - One processing stage per camera: its [`CameraPipeline::process`]; a frame that the source
//!   could not deliver, or the tracker could not use, gives `bad_frame` rows for every rod of
//!   that camera ([`Hooks::bad_frame`]) and the run goes on.
//! - The temporal filter and the fusion: each camera's rows go through its
//!   [`rodtrack_core::CameraFilter`] in its own thread, and the fusion of the measured rows
//!   ([`rodtrack_core::SetFusion`]) is the pipeline's fusion stage. The rows are those of
//!   [`rodtrack_core::FrameSetFilter`] over each set.
//! - Recordings run in [`RunMode::Batch`] (never drop, as fast as possible), live sources in
//!   [`RunMode::Live`], each camera's thread processing the frame it read (no hand-off)
//!   ([`pipeline_config`]). Both write one frame set at a time, after the fusion, so that a
//!   camera row the fusion overruled is marked `conflict` and files of recordings are identical
//!   whatever the timing; a set of one camera is complete, and written, as soon as its frame is
//!   measured. [`SessionOptions::write`] = [`WriteMode::PerCamera`] writes each camera's rows
//!   as soon as they are measured instead, the fused rows when the set is complete: a camera's
//!   rows then do not wait for the other cameras' frames of the set (with 2 cameras about
//!   40 us less at p50, see `rodtrack bench-latency --write camera` and docs/performance.md),
//!   but camera rows are not flagged `conflict` (only the fused row shows it).
//! - On the end of the inputs, an error or [`Session::stop_flag`]: every pending set is
//!   written and the sink flushed.
//!
//! ```no_run
//! use rodtrack_sdk::{open_sinks, RowFormat, Session, SessionOptions};
//! let cal = rodtrack_sdk::read_calibration("table.toml".as_ref())?;
//! let session = Session::open(&cal, &["rec/cam0", "rec/cam1"], SessionOptions::default())?;
//! let (report, _) = session.run(open_sinks("rows.csv".as_ref(), RowFormat::Csv, None)?)?;
//! eprintln!("{}", report.summary());
//! # Ok::<(), rodtrack_sdk::SdkError>(())
//! ```

mod run;

use crate::ball::{BallCounts, BallStage, EventCounts};
use crate::control::SessionControl;
use crate::health::{health_lines, RodHealth};
use crate::hooks::{Hooks, NoHooks};
use crate::SdkError;
use rodtrack_core::calib::CalibrationFile;
use rodtrack_core::{CameraPipeline, Mode, TurnAnchor};
use rodtrack_io::runtime::{
    Handoff, LatencySummary, PipelineConfig, PipelineReport, RunMode, WriteMode,
};
use rodtrack_io::source::OpenOptions;
use rodtrack_io::{FrameSource, MeasurementSink, SourceFactory};
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Duration;

/// One camera of a session: its source and its tracker.
///
/// ```no_run
/// use rodtrack_sdk::{source_factory, Session, SessionCamera, SessionOptions};
/// // A camera opened by hand: any source, any tracker.
/// let cal = rodtrack_sdk::read_calibration("table.toml".as_ref())?;
/// let source = source_factory()
///     .open("raw:cam0.raw?width=1440&height=1080&format=bayer_rggb8", &Default::default())
///     .map_err(|e| rodtrack_sdk::SdkError::Invalid(e.to_string()))?;
/// let pipe = rodtrack_core::CameraPipeline::new(&cal.cameras[0], rodtrack_core::Mode::Enhanced)
///     .map_err(|e| rodtrack_sdk::SdkError::Invalid(e.to_string()))?;
/// let camera = SessionCamera { label: "camera 0 (cam0.raw)".into(), source, pipe };
/// let session = Session::from_cameras(vec![camera], SessionOptions::default());
/// # Ok::<(), rodtrack_sdk::SdkError>(())
/// ```
pub struct SessionCamera {
    /// `camera 0 (cam0)`, for messages.
    pub label: String,
    /// The opened source.
    pub source: Box<dyn FrameSource>,
    /// The camera's tracker.
    pub pipe: CameraPipeline,
}

/// How a session runs.
///
/// ```
/// use rodtrack_sdk::SessionOptions;
/// // Each camera's raw rows (no temporal filter, no fusion), the first 100 frames.
/// let raw = SessionOptions { filter: false, max_frames: Some(100), ..SessionOptions::default() };
/// assert_eq!(raw.mode, rodtrack_core::Mode::Enhanced);
/// ```
#[derive(Debug, Clone)]
pub struct SessionOptions {
    /// The algorithm (`Enhanced`, or `Paper` as the published baseline); it also tunes the
    /// temporal filter.
    pub mode: Mode,
    /// The temporal filter and, with several cameras, the fusion; `false`: each camera's raw
    /// rows.
    pub filter: bool,
    /// Stop after this many frames per camera.
    pub max_frames: Option<u64>,
    /// Pipeline settings instead of [`pipeline_config`]'s.
    pub config: Option<PipelineConfig>,
    /// When rows reach the sink, over the pipeline settings' choice (`None`: keep it,
    /// [`WriteMode::Set`] by default, live or not). [`WriteMode::Set`]: whole frame sets
    /// after the fusion, camera rows the fusion overruled marked `conflict`.
    /// [`WriteMode::PerCamera`]: each camera's rows as soon as they are measured, the lowest
    /// latency for live runs of several cameras; camera rows not flagged `conflict` (only the
    /// fused row shows a conflict).
    ///
    /// ```
    /// use rodtrack_io::runtime::WriteMode;
    /// use rodtrack_sdk::SessionOptions;
    /// // Lowest latency: each camera's rows at once, camera rows not flagged.
    /// let fast = SessionOptions { write: Some(WriteMode::PerCamera), ..SessionOptions::default() };
    /// # let _ = fast;
    /// ```
    pub write: Option<WriteMode>,
    /// How often [`Hooks::progress`] is called (default: 250 ms for recordings, 1 s live).
    pub progress_period: Option<Duration>,
    /// Turn counts set by hand at given frames (re-anchoring a count that became unknown, see
    /// [`rodtrack_core::filter::RodFilter::reanchor_turns`]), in every camera's filter and the
    /// fusion's.
    pub turn_anchors: Vec<TurnAnchor>,
}

impl Default for SessionOptions {
    fn default() -> Self {
        SessionOptions {
            mode: Mode::Enhanced,
            filter: true,
            max_frames: None,
            config: None,
            write: None,
            progress_period: None,
            turn_anchors: Vec::new(),
        }
    }
}

/// A tracking session; see the module documentation.
///
/// ```no_run
/// use rodtrack_sdk::{read_calibration, Session, SessionOptions};
/// let cal = read_calibration("calib.toml".as_ref())?;
/// let session = Session::open(&cal, &["rec/cam0", "rec/cam1"], SessionOptions::default())?;
/// let (report, rows) = session.run(rodtrack_io::VecSink::default())?;
/// println!("{} rows, {}", rows.rows.len(), report.summary());
/// # Ok::<(), rodtrack_sdk::SdkError>(())
/// ```
pub struct Session {
    cameras: Vec<SessionCamera>,
    options: SessionOptions,
    hooks: Arc<dyn Hooks>,
    stop: Arc<AtomicBool>,
    control: SessionControl,
    ball: Option<BallStage>,
}

impl Session {
    /// Opens one input per camera of `cal`, in its camera order, with
    /// [`crate::source_factory`]: a folder of images, `raw:FILE?...`, `video:FILE`,
    /// `genicam://ID`, `sim://SCENARIO?camera=N...`.
    ///
    /// ```no_run
    /// use rodtrack_sdk::{Session, SessionOptions};
    /// let cal = rodtrack_sdk::read_calibration("table.toml".as_ref())?;
    /// let session = Session::open(&cal, &["rec/cam0", "rec/cam1"], SessionOptions::default())?;
    /// let (report, sink) = session.run(rodtrack_io::VecSink::default())?;
    /// println!("{} rows{}", sink.rows.len(), report.summary());
    /// # Ok::<(), rodtrack_sdk::SdkError>(())
    /// ```
    pub fn open<S: AsRef<str>>(
        cal: &CalibrationFile,
        inputs: &[S],
        options: SessionOptions,
    ) -> Result<Session, SdkError> {
        Self::open_with(&crate::source_factory(), cal, inputs, options)
    }

    /// [`Session::open`] with the sources of `factory`.
    ///
    /// ```no_run
    /// use rodtrack_sdk::{source_factory, Session, SessionOptions};
    /// // The sources of this build plus one's own (registered on the factory before opening).
    /// let factory = source_factory();
    /// let cal = rodtrack_sdk::read_calibration("table.toml".as_ref())?;
    /// let session = Session::open_with(&factory, &cal, &["sim://exp3?camera=0"], SessionOptions::default())?;
    /// # Ok::<(), rodtrack_sdk::SdkError>(())
    /// ```
    pub fn open_with<S: AsRef<str>>(
        factory: &SourceFactory,
        cal: &CalibrationFile,
        inputs: &[S],
        options: SessionOptions,
    ) -> Result<Session, SdkError> {
        if inputs.len() != cal.cameras.len() {
            return Err(SdkError::Invalid(format!(
                "the calibration has {} camera(s) but {} input(s) were given: give one input \
                 per camera, in order",
                cal.cameras.len(),
                inputs.len()
            )));
        }
        let mut cameras = Vec::new();
        for (cam, input) in cal.cameras.iter().zip(inputs) {
            let input = input.as_ref();
            let label = format!("camera {} ({})", cam.index, cam.name);
            let format = cam.format().map_err(|e| SdkError::core(&label, e))?;
            let opts = OpenOptions {
                format: Some(format),
                fps: Some(cam.fps),
                size: Some((cam.image_width, cam.image_height)),
            };
            let source = factory.open(input, &opts).map_err(|e| SdkError::Source {
                context: format!("{label}: input {input}"),
                source: e,
            })?;
            let pipe =
                CameraPipeline::new(cam, options.mode).map_err(|e| SdkError::core(&label, e))?;
            cameras.push(SessionCamera {
                label,
                source,
                pipe,
            });
        }
        Ok(Self::from_cameras(cameras, options))
    }

    /// A session over cameras opened by the caller.
    ///
    /// ```no_run
    /// use rodtrack_sdk::{Session, SessionOptions};
    /// let cal = rodtrack_sdk::read_calibration("table.toml".as_ref())?;
    /// let session = Session::open(&cal, &["rec/cam0", "rec/cam1"], SessionOptions::default())?;
    /// // The same cameras again, with other options: take them over from a session opened by URI.
    /// let cameras = Vec::from_iter(std::iter::empty()); // or cameras opened by hand
    /// let other = Session::from_cameras(cameras, SessionOptions { filter: false, ..Default::default() });
    /// assert!(other.cameras().is_empty());
    /// # let _ = session;
    /// # Ok::<(), rodtrack_sdk::SdkError>(())
    /// ```
    pub fn from_cameras(cameras: Vec<SessionCamera>, options: SessionOptions) -> Session {
        let control = SessionControl::new(
            cameras
                .iter()
                .map(|c| {
                    (
                        c.pipe.index(),
                        c.pipe.rods().iter().map(|r| r.rod()).collect(),
                    )
                })
                .collect(),
        );
        Session {
            cameras,
            options,
            hooks: Arc::new(NoHooks),
            stop: Arc::new(AtomicBool::new(false)),
            control,
            ball: None,
        }
    }

    /// Tracks the ball too: every camera of `cal` with `[cameras.ball]` (matched by index)
    /// runs a [`rodtrack_core::ball::BallTracker`] on its frames, and the rows go to `sink` in
    /// frame order (cameras in index order within a frame). Fails when no camera has a ball
    /// calibration or one is invalid.
    ///
    /// ```no_run
    /// use rodtrack_sdk::{Session, SessionOptions};
    /// let cal = rodtrack_sdk::read_calibration("table.toml".as_ref())?;
    /// let ball = rodtrack_io::BallCsvSink::create("ball.csv".as_ref())
    ///     .map_err(|e| rodtrack_sdk::SdkError::Invalid(e.to_string()))?;
    /// let session = Session::open(&cal, &["rec/cam0", "rec/cam1"], SessionOptions::default())?
    ///     .with_ball(&cal, Box::new(ball))?;
    /// let (report, _) = session.run(rodtrack_io::VecSink::default())?;
    /// println!("{:?}", report.ball);
    /// # Ok::<(), rodtrack_sdk::SdkError>(())
    /// ```
    pub fn with_ball(
        mut self,
        cal: &CalibrationFile,
        sink: Box<dyn rodtrack_io::BallSink>,
    ) -> Result<Session, SdkError> {
        self.ball = Some(BallStage::new(cal, sink)?);
        Ok(self)
    }

    /// Detects the ball's events too (goals with the score, shots, ball out, ball stopped:
    /// [`rodtrack_core::ball::events`]) from each frame set's ball row (the `fused` row with
    /// several cameras), with the table of `cal` (its field, goal mouths and rods'
    /// axes: [`rodtrack_core::ball::events::TableGeometry::from_calibration`]) and the rules
    /// `cfg`; they go to `sink` as they are decided. Needs [`Session::with_ball`] first; fails
    /// when the calibration has no table frame or `cfg` is invalid.
    ///
    /// ```no_run
    /// use rodtrack_sdk::{Session, SessionOptions};
    /// let cal = rodtrack_sdk::read_calibration("table.toml".as_ref())?;
    /// let events = rodtrack_io::EventVecSink::default();
    /// let session = Session::open(&cal, &["rec/cam0", "rec/cam1"], SessionOptions::default())?
    ///     .with_ball(&cal, Box::new(rodtrack_io::BallVecSink::default()))?
    ///     .with_events(&cal, Default::default(), Box::new(events.clone()))?;
    /// let (report, _) = session.run(rodtrack_io::VecSink::default())?;
    /// println!("score {:?}: {:?}", report.events.map(|e| e.score), events.events());
    /// # Ok::<(), rodtrack_sdk::SdkError>(())
    /// ```
    pub fn with_events(
        mut self,
        cal: &CalibrationFile,
        cfg: rodtrack_core::ball::events::EventConfig,
        sink: Box<dyn rodtrack_io::EventSink>,
    ) -> Result<Session, SdkError> {
        let Some(ball) = self.ball.as_mut() else {
            return Err(SdkError::Invalid(
                "the events need the ball: call `with_ball` before `with_events`".into(),
            ));
        };
        ball.set_events(cal, cfg, sink)?;
        Ok(self)
    }

    /// A handle to send commands to the session while it runs (re-anchoring a rod's turn
    /// count, see [`SessionControl`]); the commands reach the temporal filter, so they do
    /// nothing with [`SessionOptions::filter`] false.
    pub fn control(&self) -> SessionControl {
        self.control.clone()
    }

    /// The hooks to call while running.
    ///
    /// ```no_run
    /// use rodtrack_sdk::{Hooks, Progress, Session, SessionOptions};
    /// use std::sync::Arc;
    /// struct Print;
    /// impl Hooks for Print {
    ///     fn progress(&self, p: &Progress) {
    ///         eprintln!("{} frame sets", p.sets);
    ///     }
    /// }
    /// let cal = rodtrack_sdk::read_calibration("table.toml".as_ref())?;
    /// let session = Session::open(&cal, &["rec/cam0", "rec/cam1"], SessionOptions::default())?;
    /// let session = session.with_hooks(Arc::new(Print));
    /// # Ok::<(), rodtrack_sdk::SdkError>(())
    /// ```
    pub fn with_hooks(mut self, hooks: Arc<dyn Hooks>) -> Session {
        self.hooks = hooks;
        self
    }

    /// Uses `stop` as the stop flag (e.g. one set on Ctrl-C).
    ///
    /// ```no_run
    /// use rodtrack_sdk::{Session, SessionOptions};
    /// use std::sync::{atomic::AtomicBool, Arc};
    /// let stop = Arc::new(AtomicBool::new(false)); // shared with a Ctrl-C handler
    /// let cal = rodtrack_sdk::read_calibration("table.toml".as_ref())?;
    /// let session = Session::open(&cal, &["rec/cam0", "rec/cam1"], SessionOptions::default())?;
    /// let session = session.with_stop_flag(stop.clone());
    /// # Ok::<(), rodtrack_sdk::SdkError>(())
    /// ```
    pub fn with_stop_flag(mut self, stop: Arc<AtomicBool>) -> Session {
        self.stop = stop;
        self
    }

    /// Setting this flag stops the session: every pending frame set is written, the sink
    /// flushed and [`Session::run`] returns.
    ///
    /// ```no_run
    /// use rodtrack_sdk::{Session, SessionOptions};
    /// use std::sync::atomic::Ordering;
    /// let cal = rodtrack_sdk::read_calibration("table.toml".as_ref())?;
    /// let session = Session::open(&cal, &["rec/cam0", "rec/cam1"], SessionOptions::default())?;
    /// let stop = session.stop_flag();
    /// std::thread::spawn(move || {
    ///     std::thread::sleep(std::time::Duration::from_secs(10));
    ///     stop.store(true, Ordering::Relaxed); // ends the run after 10 s
    /// });
    /// let (report, _) = session.run(rodtrack_io::VecSink::default())?;
    /// # Ok::<(), rodtrack_sdk::SdkError>(())
    /// ```
    pub fn stop_flag(&self) -> Arc<AtomicBool> {
        self.stop.clone()
    }

    /// The session's options, to change them once the sources are open (e.g. the pipeline
    /// settings chosen from [`Session::is_live`]).
    ///
    /// ```no_run
    /// use rodtrack_sdk::{pipeline_config, Session, SessionOptions};
    /// let cal = rodtrack_sdk::read_calibration("table.toml".as_ref())?;
    /// let mut session = Session::open(&cal, &["rec/cam0", "rec/cam1"], SessionOptions::default())?;
    /// let live = session.is_live();
    /// session.options_mut().config = Some(pipeline_config(live));
    /// # Ok::<(), rodtrack_sdk::SdkError>(())
    /// ```
    pub fn options_mut(&mut self) -> &mut SessionOptions {
        &mut self.options
    }

    /// The session's cameras.
    ///
    /// ```no_run
    /// use rodtrack_sdk::{Session, SessionOptions};
    /// let cal = rodtrack_sdk::read_calibration("table.toml".as_ref())?;
    /// let session = Session::open(&cal, &["rec/cam0", "rec/cam1"], SessionOptions::default())?;
    /// for c in session.cameras() {
    ///     println!("{}: {:?} frames", c.label, c.source.info().frame_count);
    /// }
    /// # Ok::<(), rodtrack_sdk::SdkError>(())
    /// ```
    pub fn cameras(&self) -> &[SessionCamera] {
        &self.cameras
    }

    /// True when a source is live (a camera, the real-time simulator).
    ///
    /// ```no_run
    /// use rodtrack_sdk::{Session, SessionOptions};
    /// let cal = rodtrack_sdk::read_calibration("table.toml".as_ref())?;
    /// let session = Session::open(&cal, &["rec/cam0", "rec/cam1"], SessionOptions::default())?;
    /// assert!(!session.is_live()); // image folders are recordings
    /// # Ok::<(), rodtrack_sdk::SdkError>(())
    /// ```
    pub fn is_live(&self) -> bool {
        self.cameras.iter().any(|c| c.source.info().live)
    }

    /// Runs the cameras into `sink` until the sources end or the stop flag is set; returns
    /// the report and the sink, flushed.
    ///
    /// ```no_run
    /// use rodtrack_sdk::{open_sinks, RowFormat, Session, SessionOptions};
    /// let cal = rodtrack_sdk::read_calibration("table.toml".as_ref())?;
    /// let session = Session::open(&cal, &["rec/cam0", "rec/cam1"], SessionOptions::default())?;
    /// let sink = open_sinks("rows.csv".as_ref(), RowFormat::Csv, None)?;
    /// let (report, _sink) = session.run(sink)?;
    /// if report.all_bad() {
    ///     eprintln!("no frame could be measured");
    /// }
    /// # Ok::<(), rodtrack_sdk::SdkError>(())
    /// ```
    pub fn run<S: MeasurementSink + 'static>(self, sink: S) -> Result<(RunReport, S), SdkError> {
        run::run_cameras(self, sink)
    }
}

/// The mode names accepted by [`mode_from_name`]: `enhanced`, `paper`.
///
/// ```
/// for name in rodtrack_sdk::MODE_NAMES {
///     assert!(rodtrack_sdk::mode_from_name(name).is_ok());
/// }
/// ```
pub const MODE_NAMES: [&str; 2] = ["enhanced", "paper"];

/// The algorithm named `name` ([`MODE_NAMES`]).
///
/// ```
/// use rodtrack_core::Mode;
/// assert_eq!(rodtrack_sdk::mode_from_name("paper")?, Mode::Paper);
/// let e = rodtrack_sdk::mode_from_name("fast").unwrap_err();
/// assert!(e.to_string().contains("fast"), "{e}");
/// # Ok::<(), rodtrack_sdk::SdkError>(())
/// ```
pub fn mode_from_name(name: &str) -> Result<Mode, SdkError> {
    Mode::from_name(name).ok_or_else(|| {
        SdkError::Invalid(format!(
            "unknown mode {name:?}: expected one of {}",
            MODE_NAMES.join(", ")
        ))
    })
}

/// What a session did.
///
/// ```
/// use rodtrack_sdk::{Session, SessionCamera, SessionOptions};
/// // Camera 0 of the simulator, calibrated as an operator would, 3 frames.
/// let mut sim = rodtrack_sim::build_simulation("exp3", Some(3), 1, false, "default").unwrap();
/// let cal = rodtrack_sim::calibrate_sim_camera(&mut sim, 0, 1).unwrap().calibration;
/// let mut sources = rodtrack_sim::SimSource::for_simulation(&sim, Default::default()).unwrap();
/// let camera = SessionCamera {
///     label: "camera 0".into(),
///     source: Box::new(sources.remove(0)),
///     pipe: rodtrack_core::CameraPipeline::new(&cal, rodtrack_core::Mode::Enhanced).unwrap(),
/// };
/// let session = Session::from_cameras(vec![camera], SessionOptions::default());
/// let (report, sink) = session.run(rodtrack_io::VecSink::default()).unwrap();
/// assert_eq!(report.pipeline.cameras[0].frames_read, 3);
/// assert!(!report.all_bad());
/// assert_eq!(sink.rows.len(), 3 * cal.rods.len());
/// ```
#[derive(Debug, Clone)]
pub struct RunReport {
    /// The pipeline's report: frames read, processed, dropped and bad per camera, frame sets,
    /// sink errors, latency.
    pub pipeline: PipelineReport,
    /// Per camera: time in the tracker per frame.
    pub tracker: Vec<LatencySummary>,
    /// The pipeline's settings.
    pub config: PipelineConfig,
    /// Camera disagreements and sync warnings of the fusion.
    pub warnings: u64,
    /// Per camera and rod, then per fused rod: fresh searches, learnt-state resets, rows
    /// with the turn count unknown, the count lost and re-anchored, conflicts.
    pub rods: Vec<RodHealth>,
    /// The ball rows written, when the session tracked the ball ([`Session::with_ball`]).
    pub ball: Option<BallCounts>,
    /// The events written, when the session detected them ([`Session::with_events`]).
    pub events: Option<EventCounts>,
}

impl RunReport {
    /// The report, the run mode and the per-camera tracker times, for printing.
    ///
    /// ```no_run
    /// use rodtrack_sdk::{Session, SessionOptions};
    /// let cal = rodtrack_sdk::read_calibration("table.toml".as_ref())?;
    /// let session = Session::open(&cal, &["rec/cam0", "rec/cam1"], SessionOptions::default())?;
    /// let (report, _) = session.run(rodtrack_io::VecSink::default())?;
    /// eprintln!("{}", report.summary()); // the mode, then frames read, dropped and bad per camera
    /// # Ok::<(), rodtrack_sdk::SdkError>(())
    /// ```
    pub fn summary(&self) -> String {
        let mut s = format!(
            "\n{} mode ({}, {}), {}",
            match self.config.mode {
                RunMode::Live => "live",
                RunMode::Paced { .. } => "paced",
                RunMode::Batch => "batch",
            },
            match self.config.handoff {
                Handoff::Inline => "each camera's thread tracks its frames",
                Handoff::Queue => "capture queue, processing thread per camera",
            },
            match self.config.write {
                WriteMode::PerCamera => "rows written per camera",
                WriteMode::Set => "rows written per frame set",
            },
            self.pipeline
        );
        for (i, p) in self.tracker.iter().enumerate() {
            let us = |d: Duration| d.as_secs_f64() * 1e6;
            s.push_str(&format!(
                "\n  tracker, camera {i}: {} frames, p50 {:.0} us, p99 {:.0} us, max {:.0} us per frame",
                p.count,
                us(p.p50),
                us(p.p99),
                us(p.max)
            ));
        }
        s.push_str(&health_lines(&self.rods));
        s
    }

    /// True when frames were read and every one of them was bad: nothing was measured.
    ///
    /// ```no_run
    /// use rodtrack_sdk::{Session, SessionOptions};
    /// let cal = rodtrack_sdk::read_calibration("table.toml".as_ref())?;
    /// let session = Session::open(&cal, &["rec/cam0", "rec/cam1"], SessionOptions::default())?;
    /// let (report, _) = session.run(rodtrack_io::VecSink::default())?;
    /// if report.all_bad() {
    ///     return Err(rodtrack_sdk::SdkError::Invalid("every frame was bad".into()));
    /// }
    /// # Ok::<(), rodtrack_sdk::SdkError>(())
    /// ```
    pub fn all_bad(&self) -> bool {
        let c = &self.pipeline.cameras;
        c.iter().any(|c| c.frames_read > 0) && c.iter().all(|c| c.bad_frames >= c.frames_read)
    }
}

/// How long a live camera thread polls the output lock, held by another camera's thread while
/// it writes (a few us), before it sleeps on it: with 2 cores or more the holder runs
/// meanwhile, and the poll saves a thread wake-up (`rodtrack bench-latency` on a 2-core
/// machine: the lock wait's p99 falls from up to 40-60 us to under 10 us, the max from
/// milliseconds to about 0.25 ms); on 1 core the holder cannot run while the other polls, so
/// there is no polling.
///
/// ```
/// assert!(rodtrack_sdk::LIVE_SPIN < std::time::Duration::from_millis(1));
/// ```
pub const LIVE_SPIN: Duration = Duration::from_micros(30);

/// Pipeline settings for recordings (`live` false) or live sources. Both write one frame set
/// at a time, after the fusion ([`WriteMode::Set`]): camera rows the fusion overruled are
/// marked `conflict`, and files of recordings are identical whatever the timing. For live
/// sources: no hand-off between threads (each camera's thread tracks the frame it read, the
/// thread that completes a set writes it; a single camera's set is complete, and written, at
/// once) and [`LIVE_SPIN`] on the output lock. Set `write` to [`WriteMode::PerCamera`] (or
/// [`SessionOptions::write`]) for each camera's rows as soon as they are measured: the lowest
/// latency with several cameras, camera rows not flagged.
///
/// ```
/// use rodtrack_io::runtime::{Handoff, RunMode, WriteMode};
/// // Recordings: one write per frame set, as fast as the tracker goes.
/// assert_eq!(rodtrack_sdk::pipeline_config(false).mode, RunMode::Batch);
/// // Live sources: inline tracking, whole frame sets too (camera rows flagged `conflict`).
/// let live = rodtrack_sdk::pipeline_config(true);
/// assert_eq!((live.mode, live.handoff, live.write), (RunMode::Live, Handoff::Inline, WriteMode::Set));
/// // The lowest latency, camera rows not flagged:
/// let fast = rodtrack_io::runtime::PipelineConfig { write: WriteMode::PerCamera, ..live };
/// # let _ = fast;
/// ```
pub fn pipeline_config(live: bool) -> PipelineConfig {
    if live {
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        PipelineConfig {
            mode: RunMode::Live,
            handoff: Handoff::Inline,
            write: WriteMode::Set,
            spin: if cores >= 2 {
                LIVE_SPIN
            } else {
                Duration::ZERO
            },
            ..PipelineConfig::default()
        }
    } else {
        PipelineConfig {
            mode: RunMode::Batch,
            // Files always deliver or end: a set waits for every camera (the timeout only
            // guards against a source stuck in a read).
            group_timeout: Duration::from_secs(60),
            ..PipelineConfig::default()
        }
    }
}
