//! `rodtrack track`: every camera through the runtime [`Pipeline`].
//!
//! ```text
//!  --input 0 -> [capture 0] -> queue -> [CameraPipeline 0] --\
//!                                                              >-> [group by frame id] -> FilterSink -> sinks
//!  --input 1 -> [capture 1] -> queue -> [CameraPipeline 1] --/      (filter + fusion)    (CSV/JSONL, UDP)
//! ```
//!
//! - One processing closure per camera: the camera's [`CameraPipeline::process`]; a frame that
//!   the source could not deliver, or the tracker could not use, gives `bad_frame` rows for
//!   every rod of that camera and the run goes on.
//! - The temporal filter and the fusion ([`FrameSetFilter`]) run in a sink wrapper,
//!   [`FilterSink`], not in the pipeline's fusion hook: the hook can only *append* rows to a
//!   set, while the filter *replaces* each camera's raw rows by filtered ones (and appends the
//!   fused rows). The wrapper sees exactly one frame set per `write`, in frame order, so the
//!   result is the same as a sequential loop; its time counts in the latency (which the
//!   pipeline measures up to the return of the sink's `write`).
//! - Recordings run in [`Mode::Batch`] (never drop, as fast as possible), live sources (cameras,
//!   the real-time simulator) in [`Mode::Live`] (capture never blocked; drops counted).
//! - A progress bar for recordings, live statistics (frames/s, time per camera frame, drops)
//!   about once a second for live sources, on stderr.
//! - On the end of the inputs, an error or Ctrl-C: every pending set is written, the sinks
//!   flushed and the [`rodtrack_io::runtime::PipelineReport`] printed.

use crate::calibration_io::read_calibration;
use anyhow::{anyhow, bail, Context, Result};
use rodtrack_console::{Console, ConsoleHandle};
use rodtrack_core::{CameraPipeline, FrameSetFilter, Measurement, Mode, PixelFormat};
use rodtrack_io::runtime::{
    LatencyHistogram, LatencySummary, Mode as RunMode, Pipeline, PipelineConfig, PipelineCounters,
    PipelineReport,
};
use rodtrack_io::source::{OpenOptions, SourceInfo};
use rodtrack_io::{
    CsvSink, FrameBuffer, FrameSource, IoError, JsonlSink, MeasurementSink, MultiSink, SourceError,
    SourceFactory, UdpSink,
};
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
    let filter = (!args.raw).then(|| FrameSetFilter::new(mode, cal.cameras.len() > 1));
    let mut sink = ConsoleRows {
        inner: FilterSink::new(filter, sink),
        console: console.clone(),
    };
    let stop = Arc::new(AtomicBool::new(false));
    install_ctrlc(stop.clone());
    let outcome = run_cameras(cameras, &mut sink, &stop, args.max_frames, true)?;
    eprintln!("{}", outcome.summary());
    sink.inner.print_summary();
    if outcome.report.sink_errors > 0 {
        bail!(
            "{} write(s) to the output failed (first: {}); rows written before are in {}",
            outcome.report.sink_errors,
            outcome.report.first_sink_error.as_deref().unwrap_or("?"),
            args.out.display()
        );
    }
    println!("wrote {}", args.out.display());
    Ok(())
}

/// Passes rows on to `inner` and shows them in the web console's plots.
struct ConsoleRows<S> {
    inner: S,
    console: Option<Arc<ConsoleHandle>>,
}

impl<S: MeasurementSink> MeasurementSink for ConsoleRows<S> {
    fn write(&mut self, rows: &[Measurement]) -> Result<(), rodtrack_io::IoError> {
        let r = self.inner.write(rows);
        if let Some(c) = &self.console {
            c.publish_rows(rows);
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

/// Opens the file sink (and the UDP sink).
pub fn open_sinks(
    out: &std::path::Path,
    format: Option<&str>,
    udp: Option<&str>,
) -> Result<MultiSink> {
    let jsonl = match format {
        Some(f) => f == "jsonl",
        None => out.extension().is_some_and(|e| e == "jsonl" || e == "json"),
    };
    let mut sink = MultiSink::new();
    if jsonl {
        sink.push(Box::new(JsonlSink::create(out)?));
    } else {
        sink.push(Box::new(CsvSink::create(out)?));
    }
    if let Some(addr) = udp {
        sink.push(Box::new(UdpSink::new(addr)?));
    }
    Ok(sink)
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

/// A sink that runs the temporal filter and the fusion over each frame set before passing the
/// rows on (`None`: rows pass unchanged). See the module documentation for why this is a sink
/// wrapper and not the pipeline's fusion hook.
pub struct FilterSink<S: MeasurementSink> {
    filter: Option<FrameSetFilter>,
    inner: S,
    out: Vec<Measurement>,
    warnings: u64,
    /// Time of each `write` (filter, fusion and the inner sinks).
    write_times: LatencyHistogram,
}

impl<S: MeasurementSink> FilterSink<S> {
    /// Wraps `inner`.
    pub fn new(filter: Option<FrameSetFilter>, inner: S) -> Self {
        FilterSink {
            filter,
            inner,
            out: Vec::with_capacity(64),
            warnings: 0,
            write_times: LatencyHistogram::new(),
        }
    }

    /// Time per `write` call (one frame set): filter, fusion and the inner sinks.
    pub fn write_times(&self) -> LatencySummary {
        self.write_times.summary()
    }

    /// Prints how many warnings were not printed.
    pub fn print_summary(&self) {
        if self.warnings > MAX_WARNINGS {
            eprintln!(
                "{} camera disagreement / sync warnings ({} not printed)",
                self.warnings,
                self.warnings - MAX_WARNINGS
            );
        }
    }

    fn warn(&mut self, msg: std::fmt::Arguments<'_>) {
        self.warnings += 1;
        if self.warnings <= MAX_WARNINGS {
            eprintln!("\n{msg}");
        }
    }
}

impl<S: MeasurementSink> MeasurementSink for FilterSink<S> {
    fn write(&mut self, rows: &[Measurement]) -> Result<(), IoError> {
        let start = Instant::now();
        let result = self.write_inner(rows);
        self.write_times.record(start.elapsed());
        result
    }

    fn flush(&mut self) -> Result<(), IoError> {
        self.inner.flush()
    }
}

impl<S: MeasurementSink> FilterSink<S> {
    fn write_inner(&mut self, rows: &[Measurement]) -> Result<(), IoError> {
        let Some(f) = self.filter.as_mut() else {
            return self.inner.write(rows);
        };
        self.out.clear();
        f.process(rows, &mut self.out);
        if !f.disagreements().is_empty() || !f.out_of_sync().is_empty() {
            let dis = f.disagreements().to_vec();
            let sync = f.out_of_sync().to_vec();
            for d in dis {
                self.warn(format_args!(
                    "frame {}: rod {}: cameras {} and {} disagree by {:.2} mm / {:.3} rad",
                    d.frame,
                    d.rod,
                    d.cameras[0],
                    d.cameras[1],
                    d.position_diff_mm,
                    d.angle_diff_rad
                ));
            }
            for o in sync {
                self.warn(format_args!(
                    "frame {}: camera {} out of sync by {:.2} ms",
                    o.frame,
                    o.camera,
                    o.offset_s * 1e3
                ));
            }
        }
        self.inner.write(&self.out)
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
    /// The mode the pipeline ran in.
    pub mode: RunMode,
}

impl Outcome {
    /// The report, the mode and the per-camera tracker times, for printing.
    pub fn summary(&self) -> String {
        let mut s = format!(
            "\n{} mode, {}",
            match self.mode {
                RunMode::Live => "live",
                RunMode::Paced { .. } => "paced",
                RunMode::Batch => "batch",
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

/// Pipeline settings for recordings (`live` false) or live sources.
pub fn pipeline_config(live: bool) -> PipelineConfig {
    if live {
        PipelineConfig {
            mode: RunMode::Live,
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

/// Runs the cameras through the runtime pipeline into `sink` until the sources end or `stop`
/// is set; Live mode when any source is live, else Batch. With `progress`, prints a progress
/// bar (recordings) or live statistics on stderr. Bad frames are marked and printed (the first
/// few per camera); the sink is flushed before returning.
pub fn run_cameras(
    cameras: Vec<TrackCamera>,
    sink: &mut dyn MeasurementSink,
    stop: &Arc<AtomicBool>,
    max_frames: Option<u64>,
    progress: bool,
) -> Result<Outcome> {
    let live = cameras.iter().any(|c| c.source.info().live);
    let config = pipeline_config(live);
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
        let mut overlays = Vec::new();
        pipeline.add_camera(
            source,
            Box::new(move |meta, frame, rows| {
                let ts = meta.timestamp_ns.as_secs_f64();
                let start = Instant::now();
                let result = match frame {
                    Ok(view) => {
                        let r = pipe
                            .process(&view, meta.frame_id, ts, rows)
                            .map_err(|e| e.to_string());
                        // The frame is the runtime's: the console gets a decimated copy, and
                        // only when it asks for one (two atomic loads per frame otherwise).
                        if let (Ok(()), Some(c)) = (&r, console.as_ref()) {
                            if c.wants_frame(cam_index) {
                                overlays.clear();
                                overlays.extend(
                                    pipe.rods()
                                        .iter()
                                        .zip(pipe.last_results())
                                        .map(|(t, r)| rodtrack_console::overlays_for(t, r)),
                                );
                                c.publish_frame(cam_index, &view, meta.frame_id, ts, &overlays);
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
    let result = pipeline.run(sink);
    done.store(true, Ordering::SeqCst);
    let _ = monitor.join();
    let report = result.context("running the pipeline")?;
    let process = times
        .iter()
        .map(|t| t.histogram.lock().map(|h| h.summary()).unwrap_or_default())
        .collect();
    Ok(Outcome {
        report,
        process,
        mode: config.mode,
    })
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
