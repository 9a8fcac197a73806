//! `rodtrack track`: every camera through the runtime [`Pipeline`].
//!
//! ```text
//!  recordings (batch):
//!  --input 0 -> [capture 0] -> queue -> [CameraPipeline 0 + filter 0] --\
//!                                                                         >-> [group by frame id, fusion] -> sinks
//!  --input 1 -> [capture 1] -> queue -> [CameraPipeline 1 + filter 1] --/                                  (CSV/JSONL, UDP)
//!
//!  live sources: one thread per camera reads, tracks, filters and writes its rows; the thread
//!  that completes a frame set fuses it and writes the fused rows.
//!  --input 0 -> [capture 0 + CameraPipeline 0 + filter 0] -> sinks (camera 0's rows)
//!  --input 1 -> [capture 1 + CameraPipeline 1 + filter 1] -> sinks (camera 1's rows)
//!                                  \-> [group by frame id, fusion] -> sinks (fused rows)
//! ```
//!
//! - One processing closure per camera: the camera's [`CameraPipeline::process`]; a frame that
//!   the source could not deliver, or the tracker could not use, gives `bad_frame` rows for
//!   every rod of that camera and the run goes on.
//! - The temporal filter and the fusion ([`FrameSetFilter`]'s, split by [`CameraFilter`] and
//!   [`SetFusion`]): each camera's rows go through that camera's per-rod filters in its own
//!   thread (the pipeline's camera filter stage), and the fusion of the measured rows, filtered
//!   again, is the pipeline's fusion stage. The results are the same as
//!   [`FrameSetFilter::process`] over each frame set.
//! - Recordings run in [`RunMode::Batch`] (never drop, as fast as possible) with one `write`
//!   per frame set, so that files are identical whatever the timing. Live sources (cameras,
//!   the real-time simulator) run in [`RunMode::Live`] with [`Handoff::Inline`] (each camera's
//!   thread processes the frame it read: no hand-off; frames the source skips meanwhile are
//!   counted from gaps in its frame ids) and [`WriteMode::PerCamera`] (each camera's rows are
//!   written as soon as they are measured; the fused rows when the set is complete), the
//!   lowest latency; see [`pipeline_config`].
//! - A progress bar for recordings, live statistics (frames/s, time per camera frame, drops)
//!   about once a second for live sources, on stderr.
//! - On the end of the inputs, an error or Ctrl-C: every pending set is written, the sinks
//!   flushed and the [`rodtrack_io::runtime::PipelineReport`] printed.

use crate::calibration_io::read_calibration;
pub use crate::track_out::{check_out_is_not_an_input, is_broken_pipe, open_sinks};
use anyhow::{anyhow, bail, Context, Result};
use rodtrack_console::{Console, ConsoleHandle};
use rodtrack_core::filter::{FilterBank, FilterConfig};
use rodtrack_core::fusion::{Fuser, FusionConfig};
#[cfg(doc)]
use rodtrack_core::FrameSetFilter;
use rodtrack_core::{CameraId, CameraPipeline, Measurement, Mode, PixelFormat};
use rodtrack_io::runtime::{
    Handoff, LatencyHistogram, LatencySummary, Pipeline, PipelineConfig, PipelineCounters,
    PipelineReport, RunMode, WriteMode,
};
use rodtrack_io::source::{OpenOptions, SourceInfo};
use rodtrack_io::{FrameBuffer, FrameSource, MeasurementSink, SourceError, SourceFactory};
use std::io::Write;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// Arguments of `rodtrack track`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Calibration file (TOML) from `rodtrack calibrate`.
    #[arg(long)]
    pub calib: PathBuf,
    /// Frame source per camera, in the calibration's camera order: a folder of images,
    /// `raw:FILE?width=W&height=H&format=F`, `video:FILE`, `genicam://ID`,
    /// `sim://SCENARIO?camera=N&frames=M&seed=S&realtime=1` (repeat for several cameras).
    #[arg(long = "input", required = true)]
    pub inputs: Vec<String>,
    /// Output file for measurements.
    #[arg(long)]
    pub out: PathBuf,
    /// Output format; by default from the file extension (`.jsonl` is JSON Lines, else CSV).
    #[arg(long, value_parser = ["csv", "jsonl"])]
    pub format: Option<String>,
    /// Also stream every frame set over UDP to this address (e.g. 127.0.0.1:9870).
    #[arg(long)]
    pub udp: Option<String>,
    /// Algorithm: `enhanced` (default) or `paper` (the published method, as a baseline).
    #[arg(long, default_value = "enhanced", value_parser = ["paper", "enhanced"])]
    pub mode: String,
    /// Write each camera's raw measurements, without the temporal filter and fusion.
    #[arg(long)]
    pub raw: bool,
    /// Also serve the web console at this address (e.g. 127.0.0.1:8620): live view and plots.
    #[arg(long)]
    pub console: Option<std::net::SocketAddr>,
    /// Stop after this many frames per camera.
    #[arg(long)]
    pub max_frames: Option<u64>,
}

/// Runs the command.
pub fn run(args: Args) -> Result<()> {
    check_out_is_not_an_input(&args.out, &[&args.calib])?;
    let cal = read_calibration(&args.calib)?;
    let mode = Mode::from_name(&args.mode).ok_or_else(|| anyhow!("unknown mode {}", args.mode))?;
    if args.inputs.len() != cal.cameras.len() {
        bail!(
            "{} has {} camera(s) but {} --input given: give one input per camera, in order",
            args.calib.display(),
            cal.cameras.len(),
            args.inputs.len()
        );
    }
    let factory = source_factory();
    let console = match args.console {
        Some(addr) => {
            let c = Console::start(addr, None).context("starting the web console")?;
            eprintln!("web console: {}", c.url());
            Some(Arc::new(c))
        }
        None => None,
    };
    let mut cameras = Vec::new();
    for (cam, input) in cal.cameras.iter().zip(&args.inputs) {
        let format: PixelFormat = cam.format()?;
        let opts = OpenOptions {
            format: Some(format),
            fps: Some(cam.fps),
            size: Some((cam.image_width, cam.image_height)),
        };
        let source = factory
            .open(input, &opts)
            .with_context(|| format!("camera {} ({}): input {input}", cam.index, cam.name))?;
        print_source_warnings(&format!("camera {} ({})", cam.index, cam.name), &*source);
        let pipe = CameraPipeline::new(cam, mode)
            .with_context(|| format!("camera {} ({})", cam.index, cam.name))?;
        cameras.push(TrackCamera {
            label: format!("camera {} ({})", cam.index, cam.name),
            source,
            pipe,
            console: console.clone(),
        });
    }
    let sink = open_sinks(&args.out, args.format.as_deref(), args.udp.as_deref())?;
    let stop = Arc::new(AtomicBool::new(false));
    let sink = ConsoleRows {
        inner: sink,
        console: console.clone(),
        stop_on_broken_pipe: Some(stop.clone()),
    };
    install_ctrlc(stop.clone());
    let options = RunOptions {
        max_frames: args.max_frames,
        progress: true,
        filter: (!args.raw).then_some(mode),
        config: None,
    };
    let (outcome, sink) = run_cameras(cameras, sink, &stop, &options)?;
    drop(sink);
    eprintln!("{}", outcome.summary());
    let report = &outcome.report;
    if report.cameras.iter().any(|c| c.frames_read > 0)
        && report.cameras.iter().all(|c| c.bad_frames >= c.frames_read)
    {
        bail!(
            "every frame read was bad ({} frame(s)): nothing was measured; the rows written \
             (all `bad_frame`) are in {}",
            report.cameras.iter().map(|c| c.frames_read).sum::<u64>(),
            args.out.display()
        );
    }
    if outcome.report.sink_errors > 0 {
        bail!(
            "{} write(s) to the output failed (first: {}); rows written before are in {}",
            outcome.report.sink_errors,
            outcome.report.first_sink_error.as_deref().unwrap_or("?"),
            args.out.display()
        );
    }
    if args.out.as_os_str() == "-" {
        eprintln!("wrote standard output");
    } else {
        println!("wrote {}", args.out.display());
    }
    Ok(())
}

/// Prints what a source noticed while opening (files left out, ...): the first
/// [`MAX_WARNINGS`], then how many more.
pub fn print_source_warnings(label: &str, source: &dyn FrameSource) {
    let w = source.warnings();
    for msg in w.iter().take(MAX_WARNINGS as usize) {
        eprintln!("{label}: warning: {msg}");
    }
    if w.len() > MAX_WARNINGS as usize {
        eprintln!(
            "{label}: {} more warning(s) not printed",
            w.len() - MAX_WARNINGS as usize
        );
    }
}

/// A live frame's overlays between a camera's processing stage and its frame hook: made for
/// the frame `frame_id` (None when no frame waits for the hook).
#[derive(Default)]
struct LiveOverlays {
    frame_id: Option<u64>,
    overlays: Vec<rodtrack_console::RodOverlay>,
}

/// Passes rows on to `inner` and shows them in the web console's plots; a write that fails on
/// a broken pipe (`--out - | head`) sets `stop_on_broken_pipe`: nobody reads any more.
struct ConsoleRows<S> {
    inner: S,
    console: Option<Arc<ConsoleHandle>>,
    stop_on_broken_pipe: Option<Arc<AtomicBool>>,
}

impl<S: MeasurementSink> MeasurementSink for ConsoleRows<S> {
    fn write(&mut self, rows: &[Measurement]) -> Result<(), rodtrack_io::IoError> {
        let r = self.inner.write(rows);
        if let Some(c) = &self.console {
            c.publish_rows(rows);
        }
        if let (Err(e), Some(stop)) = (&r, &self.stop_on_broken_pipe) {
            if is_broken_pipe(e) && !stop.swap(true, Ordering::SeqCst) {
                eprintln!("\nthe output's reader has gone (broken pipe): stopping");
            }
        }
        r
    }
    fn flush(&mut self) -> Result<(), rodtrack_io::IoError> {
        self.inner.flush()
    }
}

/// The frame sources of this build: image sequences, raw files and the simulator (`sim://`)
/// always; video files and GenICam cameras with the `video` and `genicam` features.
pub fn source_factory() -> SourceFactory {
    let mut factory = SourceFactory::new();
    crate::sim_source::register(&mut factory);
    #[cfg(feature = "video")]
    rodtrack_video::register(&mut factory);
    #[cfg(feature = "genicam")]
    rodtrack_genicam::register(&mut factory);
    factory
}

/// Sets `stop` on Ctrl-C; a second Ctrl-C while stopping ends the process the usual way.
pub fn install_ctrlc(stop: Arc<AtomicBool>) {
    let _ = ctrlc::set_handler(move || {
        if stop.swap(true, Ordering::SeqCst) {
            std::process::exit(130);
        }
    });
}

/// The disagreements and sync warnings printed in full; later ones are only counted.
const MAX_WARNINGS: u64 = 20;
/// The bad frames printed in full per camera; later ones are only counted.
const MAX_BAD_FRAMES_PRINTED: u64 = 20;

/// The temporal filter tuned to the measurement noise of `mode`, as [`FrameSetFilter::new`]
/// tunes it (a test checks that both give the same rows).
pub fn filter_config(mode: Mode) -> FilterConfig {
    let mut config = FilterConfig::default();
    if mode == Mode::Paper {
        // The paper's resolution: about 1 px (0.6-0.9 mm) and 0.013 rad.
        config.position_noise_mm = 0.3;
        config.angle_noise_rad = 0.013;
    }
    config
}

/// One camera's part of [`FrameSetFilter`]: its rows through its per-rod filters (run in the
/// camera's thread, as the pipeline's camera filter stage).
#[derive(Debug, Clone)]
pub struct CameraFilter {
    bank: FilterBank,
}

impl CameraFilter {
    /// Filters for `mode`.
    pub fn new(mode: Mode) -> Self {
        CameraFilter {
            bank: FilterBank::new(filter_config(mode)),
        }
    }

    /// Appends the filtered row of each camera row (fused rows are not a camera's).
    pub fn process(&mut self, rows: &[Measurement], out: &mut Vec<Measurement>) {
        for m in rows {
            if let CameraId::Camera(_) = m.camera {
                out.push(self.bank.update(m).sanitized());
            }
        }
    }
}

/// The fusion part of [`FrameSetFilter`]: the measured rows of a frame set fused per rod and
/// filtered again (the pipeline's fusion stage); disagreements and sync warnings printed.
#[derive(Debug)]
pub struct SetFusion {
    fuser: Fuser,
    bank: FilterBank,
    warnings: Arc<Warnings>,
}

impl SetFusion {
    /// Fusion and filters for `mode`, printing to `warnings`.
    pub fn new(mode: Mode, warnings: Arc<Warnings>) -> Self {
        SetFusion {
            fuser: Fuser::new(FusionConfig::default()),
            bank: FilterBank::new(filter_config(mode)),
            warnings,
        }
    }

    /// Appends the fused rows of the set's measured rows `raw`.
    pub fn process(&mut self, raw: &[Measurement], out: &mut Vec<Measurement>) {
        let start = out.len();
        self.fuser.process(raw, &mut self.bank, out);
        for m in &mut out[start..] {
            *m = m.sanitized();
        }
        rodtrack_core::pipeline::mark_fused_bad_frames(raw, &mut out[start..]);
        for d in self.fuser.disagreements() {
            self.warnings.warn(format_args!(
                "frame {}: rod {}: cameras {} and {} disagree by {:.2} mm / {:.3} rad",
                d.frame, d.rod, d.cameras[0], d.cameras[1], d.position_diff_mm, d.angle_diff_rad
            ));
        }
        for o in self.fuser.out_of_sync() {
            self.warnings.warn(format_args!(
                "frame {}: camera {} out of sync by {:.2} ms",
                o.frame,
                o.camera,
                o.offset_s * 1e3
            ));
        }
    }
}

/// Camera disagreements and sync warnings: the first [`MAX_WARNINGS`] printed, all counted.
#[derive(Debug, Default)]
pub struct Warnings {
    count: AtomicU64,
}

impl Warnings {
    fn warn(&self, msg: std::fmt::Arguments<'_>) {
        if self.count.fetch_add(1, Ordering::Relaxed) < MAX_WARNINGS {
            eprintln!("\n{msg}");
        }
    }

    /// Prints how many warnings were not printed.
    pub fn print_summary(&self) {
        let n = self.count.load(Ordering::Relaxed);
        if n > MAX_WARNINGS {
            eprintln!(
                "{n} camera disagreement / sync warnings ({} not printed)",
                n - MAX_WARNINGS
            );
        }
    }
}

/// One camera to track: its source and its tracker.
pub struct TrackCamera {
    /// `camera 0 (cam0)`, for messages.
    pub label: String,
    /// The opened source.
    pub source: Box<dyn FrameSource>,
    /// The camera's tracker.
    pub pipe: CameraPipeline,
    /// The web console to show this camera's frames in, if any.
    pub console: Option<Arc<ConsoleHandle>>,
}

/// Time spent in one camera's tracker, per frame.
#[derive(Default)]
pub struct ProcessTimes {
    /// Sum, ns (for the live statistics).
    pub total_ns: AtomicU64,
    /// Frames measured (bad frames excluded).
    pub frames: AtomicU64,
    /// Bad frames.
    pub bad: AtomicU64,
    /// Histogram.
    pub histogram: Mutex<LatencyHistogram>,
}

/// What [`run_cameras`] did.
#[derive(Debug, Clone)]
pub struct Outcome {
    /// The pipeline's report.
    pub report: PipelineReport,
    /// Per camera: time in the tracker per frame.
    pub process: Vec<LatencySummary>,
    /// The pipeline's settings.
    pub config: PipelineConfig,
}

impl Outcome {
    /// The report, the mode and the per-camera tracker times, for printing.
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
            self.report
        );
        for (i, p) in self.process.iter().enumerate() {
            let us = |d: Duration| d.as_secs_f64() * 1e6;
            s.push_str(&format!(
                "\n  tracker, camera {i}: {} frames, p50 {:.0} us, p99 {:.0} us, max {:.0} us per frame",
                p.count,
                us(p.p50),
                us(p.p99),
                us(p.max)
            ));
        }
        s
    }
}

/// A source that ends after `left` frames.
struct Limit {
    inner: Box<dyn FrameSource>,
    left: u64,
}

impl FrameSource for Limit {
    fn info(&self) -> SourceInfo {
        let mut i = self.inner.info();
        i.frame_count = Some(i.frame_count.map_or(self.left, |n| n.min(self.left)));
        i
    }
    fn next_frame(&mut self, buf: &mut FrameBuffer) -> Result<Option<()>, SourceError> {
        if self.left == 0 {
            return Ok(None);
        }
        self.left -= 1;
        self.inner.next_frame(buf)
    }
}

/// How long a live camera thread polls the output lock, held by another camera's thread while
/// it writes (a few us), before it sleeps on it: with 2 cores or more the holder runs
/// meanwhile, and the poll saves a thread wake-up (`rodtrack bench-latency` on a 2-core
/// machine: the lock wait's p99 falls from up to 40-60 us to under 10 us, the max from
/// milliseconds to about 0.25 ms); on 1 core the holder cannot run while the other polls, so
/// there is no polling.
pub const LIVE_SPIN: Duration = Duration::from_micros(30);

/// Pipeline settings for recordings (`live` false) or live sources: for live sources the
/// lowest latency (no hand-off between threads, each camera's rows written as soon as they are
/// measured, [`LIVE_SPIN`] on the output lock); for recordings one write per frame set (files
/// identical whatever the timing).
pub fn pipeline_config(live: bool) -> PipelineConfig {
    if live {
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        PipelineConfig {
            mode: RunMode::Live,
            handoff: Handoff::Inline,
            write: WriteMode::PerCamera,
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

/// How [`run_cameras`] runs.
#[derive(Debug, Clone, Default)]
pub struct RunOptions {
    /// Stop after this many frames per camera.
    pub max_frames: Option<u64>,
    /// A progress bar (recordings) or live statistics on stderr.
    pub progress: bool,
    /// The temporal filter and, with several cameras, the fusion, tuned for this mode
    /// (`None`: each camera's raw rows).
    pub filter: Option<Mode>,
    /// Pipeline settings instead of [`pipeline_config`]'s.
    pub config: Option<PipelineConfig>,
}

/// Runs the cameras through the runtime pipeline into `sink` until the sources end or `stop`
/// is set; Live mode when any source is live, else Batch (see [`pipeline_config`]). Bad frames
/// are marked and printed (the first few per camera). Returns the sink, flushed.
pub fn run_cameras<S: MeasurementSink + 'static>(
    cameras: Vec<TrackCamera>,
    sink: S,
    stop: &Arc<AtomicBool>,
    options: &RunOptions,
) -> Result<(Outcome, S)> {
    let RunOptions {
        max_frames,
        progress,
        filter,
        config,
    } = options.clone();
    let live = cameras.iter().any(|c| c.source.info().live);
    let config = config.unwrap_or_else(|| pipeline_config(live));
    let ncam = cameras.len();
    let total = if live {
        None
    } else {
        cameras
            .iter()
            .map(|c| c.source.info().frame_count)
            .min()
            .flatten()
            .map(|n| max_frames.map_or(n, |m| n.min(m)))
    };
    let mut pipeline = Pipeline::new(config);
    let mut times = Vec::new();
    for cam in cameras {
        let TrackCamera {
            label,
            source,
            mut pipe,
            console,
        } = cam;
        let cam_index = pipe.index();
        let source: Box<dyn FrameSource> = match max_frames {
            Some(left) => Box::new(Limit {
                inner: source,
                left,
            }),
            None => source,
        };
        let t = Arc::new(ProcessTimes::default());
        times.push(t.clone());
        // The overlays' constant parts (the rods' lines), once: a live frame then only places
        // the markers.
        let geometry = console
            .as_ref()
            .map(|_| rodtrack_console::CameraOverlays::new(pipe.rods()))
            .unwrap_or_default();
        // A live frame's overlays, made by the processing stage when the console asks for the
        // frame, published with the frame by the frame hook right after.
        let live = Arc::new(Mutex::new(LiveOverlays::default()));
        let live_hook = live.clone();
        let console_hook = console.clone();
        let index = pipeline.add_camera(
            source,
            Box::new(move |meta, frame, rows| {
                let ts = meta.timestamp_ns.as_secs_f64();
                let start = Instant::now();
                let result = match frame {
                    Ok(view) => {
                        let r = pipe
                            .process(&view, meta.frame_id, ts, rows)
                            .map_err(|e| e.to_string());
                        // Only when the console asks for the frame (two atomic loads per frame
                        // otherwise): the overlays now, the frame itself in the frame hook.
                        if let (Ok(()), Some(c)) = (&r, console.as_ref()) {
                            if c.wants_frame(cam_index) {
                                if let Ok(mut l) = live.lock() {
                                    geometry.fill(pipe.last_results(), &mut l.overlays);
                                    l.frame_id = Some(meta.frame_id);
                                }
                            }
                        }
                        r
                    }
                    Err(e) => Err(e.to_string()),
                };
                match result {
                    Ok(()) => {
                        let d = start.elapsed();
                        t.total_ns.fetch_add(d.as_nanos() as u64, Ordering::Relaxed);
                        t.frames.fetch_add(1, Ordering::Relaxed);
                        if let Ok(mut h) = t.histogram.lock() {
                            h.record(d);
                        }
                    }
                    Err(msg) => {
                        // Rows of a half-measured frame go; every rod is marked instead.
                        rows.clear();
                        pipe.bad_frame(meta.frame_id, ts, rows);
                        let n = t.bad.fetch_add(1, Ordering::Relaxed) + 1;
                        if n <= MAX_BAD_FRAMES_PRINTED {
                            eprintln!("\n{label}: frame {}: {msg}", meta.frame_id);
                        }
                        if n == MAX_BAD_FRAMES_PRINTED {
                            eprintln!("{label}: further bad frames are counted, not printed");
                        }
                    }
                }
            }),
        );
        if let Some(c) = console_hook {
            // The console takes the frame's buffer instead of a copy (swapped with the one it
            // held, which goes back to the runtime's pool).
            pipeline.set_frame_hook(
                index,
                Box::new(move |buf| {
                    // Nothing to do on most frames: two atomic loads, no lock.
                    if !c.wants_frame(cam_index) {
                        return;
                    }
                    let Ok(mut l) = live_hook.lock() else {
                        return;
                    };
                    if l.frame_id.take() != Some(buf.meta.frame_id) {
                        return;
                    }
                    let m = buf.meta;
                    c.publish_frame_buffer(
                        cam_index,
                        &mut buf.data,
                        m.width,
                        m.height,
                        m.stride,
                        m.format,
                        m.frame_id,
                        m.timestamp_ns.as_secs_f64(),
                        &l.overlays,
                    );
                }),
            )?;
        }
        if let Some(mode) = filter {
            let mut f = CameraFilter::new(mode);
            pipeline.set_camera_filter(
                index,
                Box::new(move |_meta, rows, out| f.process(rows, out)),
            )?;
        }
    }
    let warnings = Arc::new(Warnings::default());
    if let (Some(mode), true) = (filter, ncam > 1) {
        let mut fusion = SetFusion::new(mode, warnings.clone());
        pipeline.set_fusion(Box::new(move |_set, raw, out| fusion.process(raw, out)));
    }
    // The Ctrl-C flag is the caller's; the pipeline has its own: forward one to the other.
    let pipeline_stop = pipeline.stop_flag();
    let counters = pipeline.counters();
    let done = Arc::new(AtomicBool::new(false));
    let monitor = {
        let (done, stop, times) = (done.clone(), stop.clone(), times.clone());
        std::thread::Builder::new()
            .name("rodtrack-monitor".into())
            .spawn(move || {
                monitor(
                    &done,
                    &stop,
                    &pipeline_stop,
                    &counters,
                    &times,
                    total,
                    progress,
                )
            })
            .context("cannot start the monitor thread")?
    };
    let result = pipeline.run_direct(sink);
    done.store(true, Ordering::SeqCst);
    let _ = monitor.join();
    let (report, sink) = result.context("running the pipeline")?;
    warnings.print_summary();
    let process = times
        .iter()
        .map(|t| t.histogram.lock().map(|h| h.summary()).unwrap_or_default())
        .collect();
    Ok((
        Outcome {
            report,
            process,
            config,
        },
        sink,
    ))
}

/// Forwards `stop` to the pipeline and prints progress until `done`.
fn monitor(
    done: &AtomicBool,
    stop: &AtomicBool,
    pipeline_stop: &AtomicBool,
    counters: &PipelineCounters,
    times: &[Arc<ProcessTimes>],
    total: Option<u64>,
    progress: bool,
) {
    let tick = Duration::from_millis(20);
    let period = if total.is_some() {
        Duration::from_millis(250)
    } else {
        Duration::from_secs(1)
    };
    let mut last = Instant::now();
    let sum = |f: &dyn Fn(&ProcessTimes) -> u64| times.iter().map(|t| f(t)).sum::<u64>();
    let frames_of = |c: &PipelineCounters| -> u64 {
        c.cameras
            .iter()
            .map(|c| c.frames_processed.load(Ordering::Relaxed))
            .sum()
    };
    let mut last_frames = frames_of(counters);
    let mut last_ns = sum(&|t| t.total_ns.load(Ordering::Relaxed));
    let mut last_timed = sum(&|t| t.frames.load(Ordering::Relaxed));
    let mut printed = false;
    while !done.load(Ordering::SeqCst) {
        std::thread::sleep(tick);
        if stop.load(Ordering::SeqCst) {
            pipeline_stop.store(true, Ordering::SeqCst);
        }
        if !progress || last.elapsed() < period {
            continue;
        }
        let dt = last.elapsed().as_secs_f64();
        last = Instant::now();
        let sets = counters.sets_complete.load(Ordering::Relaxed)
            + counters.sets_incomplete.load(Ordering::Relaxed);
        let dropped: u64 = counters
            .cameras
            .iter()
            .map(|c| c.frames_dropped.load(Ordering::Relaxed))
            .sum();
        let bad = sum(&|t| t.bad.load(Ordering::Relaxed));
        let line = match total {
            Some(t) if t > 0 => format!(
                "\r{sets:>6}/{t} frames [{:<30}] {bad} bad",
                "#".repeat((30 * sets / t).min(30) as usize)
            ),
            _ => {
                let frames = frames_of(counters);
                let ns = sum(&|t| t.total_ns.load(Ordering::Relaxed));
                let timed = sum(&|t| t.frames.load(Ordering::Relaxed));
                let per_frame_us =
                    (ns - last_ns) as f64 * 1e-3 / (timed.saturating_sub(last_timed)).max(1) as f64;
                let fps = (frames - last_frames) as f64 / dt / times.len().max(1) as f64;
                (last_frames, last_ns, last_timed) = (frames, ns, timed);
                format!(
                    "\r{sets:>8} sets  {fps:>6.1} frames/s per camera  {per_frame_us:>6.0} us per camera frame  {dropped} dropped  {bad} bad   "
                )
            }
        };
        eprint!("{line}");
        let _ = std::io::stderr().flush();
        printed = true;
    }
    if printed {
        eprintln!();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rodtrack_core::{FrameSetFilter, Status};

    /// A frame set of `ncam` cameras x 8 rods: motion, noise, an occluded rod, a camera that
    /// sometimes disagrees, a row of low quality.
    fn frame_set(frame: u64, ncam: u32, noise: &mut u64) -> Vec<Measurement> {
        let mut rnd = || {
            *noise ^= *noise << 13;
            *noise ^= *noise >> 7;
            *noise ^= *noise << 17;
            (*noise >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let t = frame as f64 / 200.0;
        let mut rows = Vec::new();
        for cam in 0..ncam {
            for rod in 0..8u32 {
                let status = if rod == 3 && frame % 37 < 4 {
                    Status::Occluded
                } else {
                    Status::Ok
                };
                let mut m = Measurement::empty(frame, t, CameraId::Camera(cam), rod, status);
                if status == Status::Ok {
                    let phase = f64::from(rod);
                    m.position_mm = 40.0 * (6.0 * t + phase).sin() + 0.05 * rnd();
                    if cam == 1 && rod == 5 && frame % 50 == 7 {
                        m.position_mm += 5.0;
                    }
                    let angle = 3.0 * t * (1.0 + phase) + 0.004 * rnd();
                    m.angle_unwrapped_rad = angle;
                    m.angle_rad = angle.rem_euclid(std::f64::consts::TAU);
                    m.quality = if frame % 23 == 0 { 0.1 } else { 0.9 };
                }
                rows.push(m);
            }
        }
        rows
    }

    #[test]
    fn camera_filters_and_set_fusion_give_the_frame_set_filters_rows() {
        for mode in [Mode::Enhanced, Mode::Paper] {
            for ncam in [1u32, 2] {
                let mut reference = FrameSetFilter::new(mode, ncam > 1);
                let mut cameras: Vec<CameraFilter> =
                    (0..ncam).map(|_| CameraFilter::new(mode)).collect();
                let mut fusion = SetFusion::new(mode, Arc::new(Warnings::default()));
                let mut noise = 0x9e37_79b9_7f4a_7c15;
                let (mut want, mut got, mut one) = (Vec::new(), Vec::new(), Vec::new());
                let (mut changed, mut fused) = (0, 0);
                for frame in 0..400 {
                    let raw = frame_set(frame, ncam, &mut noise);
                    want.clear();
                    reference.process(&raw, &mut want);
                    got.clear();
                    for (c, f) in cameras.iter_mut().enumerate() {
                        one.clear();
                        one.extend(
                            raw.iter()
                                .filter(|m| m.camera == CameraId::Camera(c as u32))
                                .copied(),
                        );
                        f.process(&one, &mut got);
                    }
                    if ncam > 1 {
                        fusion.process(&raw, &mut got);
                    }
                    assert_eq!(got, want, "{mode:?}, {ncam} camera(s), frame {frame}");
                    changed += raw
                        .iter()
                        .zip(&want)
                        .filter(|(r, w)| r.position_mm != w.position_mm)
                        .count();
                    fused += want
                        .iter()
                        .filter(|m| m.camera == CameraId::Fused && m.status == Status::Ok)
                        .count();
                }
                // Not vacuous: the filters changed the values and, with 2 cameras, fused them.
                assert!(changed > 1000, "{mode:?}: {changed}");
                assert_eq!(fused > 1000, ncam > 1, "{mode:?}: {fused}");
            }
        }
    }

    #[test]
    fn live_sources_run_inline_with_per_camera_writes_recordings_per_set() {
        let live = pipeline_config(true);
        assert_eq!(
            (live.mode, live.handoff, live.write),
            (RunMode::Live, Handoff::Inline, WriteMode::PerCamera)
        );
        let files = pipeline_config(false);
        assert_eq!(
            (files.mode, files.handoff, files.write),
            (RunMode::Batch, Handoff::Queue, WriteMode::Set)
        );
    }
}
