//! `rodtrack track`: every camera through an SDK [`Session`] into the output files, with a
//! progress bar (recordings) or live statistics (live sources) on stderr, and optionally the
//! web console.

use crate::choices::{FormatArg, ModeArg, WriteArg};
use crate::console_hooks::ConsoleHooks;
use anyhow::{bail, Context, Result};
use rodtrack_console::{Console, ConsoleHandle};
use rodtrack_core::Measurement;
use rodtrack_io::{FrameSource, MeasurementSink};
use rodtrack_sdk::{
    check_out_is_not_an_input, is_broken_pipe, open_sinks, read_calibration, Hooks, Progress,
    RowFormat, Session, SessionOptions,
};
use std::io::Write;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};

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
    /// Output file for measurements (optional with --publish).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Output format; by default from the file extension (`.jsonl` is JSON Lines, else CSV).
    #[arg(long, value_enum)]
    pub format: Option<FormatArg>,
    /// Also stream every frame set over UDP to this address (e.g. 127.0.0.1:9870); with
    /// --ball-out or --events-out, the ball's rows and its events too, in datagrams of their
    /// own (docs/formats.md).
    #[arg(long)]
    pub udp: Option<String>,
    /// Algorithm: `enhanced` (default) or `paper` (the published method, as a baseline).
    #[arg(long, value_enum, default_value_t = ModeArg::Enhanced)]
    pub mode: ModeArg,
    /// Write each camera's raw measurements, without the temporal filter and fusion.
    #[arg(long)]
    pub raw: bool,
    /// Also serve the web console at this address (e.g. 127.0.0.1:8620): live view and plots;
    /// with --events-out, the ball's running score and last events.
    #[arg(long)]
    pub console: Option<std::net::SocketAddr>,
    /// Stop after this many frames per camera.
    #[arg(long)]
    pub max_frames: Option<u64>,
    /// When rows are written: `set` (default) one write per frame set after the fusion, the
    /// camera rows the fusion overruled marked `conflict`; `camera` each camera's rows as soon
    /// as they are measured, the lowest latency for live sources of several cameras (camera
    /// rows not flagged `conflict`: only the fused row shows it).
    #[arg(long, value_enum, default_value_t = WriteArg::Set)]
    pub write: WriteArg,
    /// Re-anchor a rod's turn count by hand: `FRAME:ROD:TURNS` says that at frame FRAME rod
    /// ROD is at whole turn TURNS (`angle_unwrapped_rad = 2 pi TURNS + angle_rad`), and its
    /// count is known from there (repeat for several). For a count that became unknown
    /// (`turns_known` false) when the rod's true turn is known, e.g. at a mark.
    #[arg(long = "reanchor", value_parser = parse_anchor)]
    pub reanchor: Vec<rodtrack_core::TurnAnchor>,
    /// Track the ball too (cameras whose calibration has `[cameras.ball]`) and write its rows
    /// to this CSV file: `frame,timestamp_s,camera,x_mm,y_mm,vx_mm_s,vy_mm_s,quality,status`
    /// (table frame, docs/ball.md); JSON Lines with the same fields for `.jsonl` or `.json`.
    #[arg(long)]
    pub ball_out: Option<PathBuf>,
    /// The ball's events.
    #[command(flatten)]
    pub events: crate::event_args::EventArgs,
    /// Run as a camera node of a camera network: publish this camera's rows (docs/network.md).
    #[arg(long, value_enum)]
    pub publish: Option<crate::network::NetworkArg>,
    /// With --publish and a calibration of several cameras: this node's camera (its name or
    /// index in the calibration).
    #[arg(long)]
    pub camera: Option<String>,
    /// With --publish: preview frames per second (a downscaled image of the camera's latest
    /// frame on `rodtrack/<table>/cam/<camera>/preview`, for remote consoles); 0: none.
    #[arg(long, default_value_t = 2.0)]
    pub preview_fps: f64,
    /// With --publish: track the ball too and publish its rows, with their uncertainty, on
    /// `rodtrack/<table>/cam/<camera>/ball` (the fusion node fuses them per frame).
    #[arg(long, requires = "publish")]
    pub zenoh_ball: bool,
    /// With --publish: detect the ball's events from this camera alone and publish them on
    /// `rodtrack/<table>/cam/<camera>/events` (one JSON object per event, as a line of
    /// --events-out), with or without --events-out: a table one camera sees whole, with no
    /// fusion node.
    #[arg(long, requires = "publish")]
    pub zenoh_events: bool,
    /// With --publish zenoh: also publish this camera's rows for ROS 2 over rmw_zenoh in this
    /// domain (ROS_DOMAIN_ID), as sensor_msgs/msg/JointState on
    /// `/rodtrack/<table>/cam/<camera>/joint_states`: a table of one camera in ROS 2; with
    /// --zenoh-ball its ball too, as geometry_msgs/msg/PointStamped on `.../<camera>/ball` and
    /// geometry_msgs/msg/Vector3Stamped on `.../<camera>/ball/velocity` (docs/network.md).
    #[arg(long, requires = "publish")]
    pub ros2_domain: Option<u32>,
    /// The network's endpoints and table.
    #[command(flatten)]
    pub net: crate::network::NetArgs,
    /// The MCAP recording.
    #[command(flatten)]
    pub mcap: crate::recording::McapArgs,
}

/// Parses `FRAME:ROD:TURNS`.
fn parse_anchor(s: &str) -> std::result::Result<rodtrack_core::TurnAnchor, String> {
    let parts: Vec<&str> = s.split(':').collect();
    let [frame, rod, turns] = parts[..] else {
        return Err(format!("`{s}`: expected FRAME:ROD:TURNS, e.g. 1200:5:-3"));
    };
    Ok(rodtrack_core::TurnAnchor {
        frame: frame
            .trim()
            .parse()
            .map_err(|_| format!("`{frame}` is not a frame number (in `{s}`)"))?,
        rod: rod
            .trim()
            .parse()
            .map_err(|_| format!("`{rod}` is not a rod id (in `{s}`)"))?,
        turns: turns
            .trim()
            .parse()
            .map_err(|_| format!("`{turns}` is not a whole number of turns (in `{s}`)"))?,
    })
}

/// The camera of a camera node: the one named by `--camera` (or the calibration's only one),
/// as a calibration of that camera alone.
fn node_calibration(
    cal: &rodtrack_core::calib::CalibrationFile,
    camera: Option<&str>,
    calib: &std::path::Path,
) -> Result<rodtrack_core::calib::CalibrationFile> {
    let names: Vec<String> = cal
        .cameras
        .iter()
        .map(|c| format!("{} ({})", c.index, c.name))
        .collect();
    let cam = match camera {
        Some(want) => cal
            .cameras
            .iter()
            .find(|c| c.name == want || c.index.to_string() == want),
        None if cal.cameras.len() == 1 => cal.cameras.first(),
        None => bail!(
            "{} has {} cameras: give this node's camera with --camera NAME (one of {})",
            calib.display(),
            cal.cameras.len(),
            names.join(", ")
        ),
    };
    let Some(cam) = cam else {
        bail!(
            "--camera {}: {} has no such camera (it has {})",
            camera.unwrap_or(""),
            calib.display(),
            names.join(", ")
        );
    };
    Ok(rodtrack_core::calib::CalibrationFile {
        version: cal.version,
        cameras: vec![cam.clone()],
    })
}

/// Runs the command.
pub fn run(args: Args) -> Result<()> {
    crate::interrupt::catch_early();
    let out = args.out.clone().unwrap_or_default();
    match (&args.out, args.publish) {
        (Some(out), _) => check_out_is_not_an_input(out, &[&args.calib])?,
        (None, None) if args.mcap.mcap.is_none() => {
            bail!("give --out FILE for the measurements (or --mcap FILE, or --publish zenoh)")
        }
        (None, _) => {}
    }
    if let Some(m) = &args.mcap.mcap {
        check_out_is_not_an_input(m, &[&args.calib, &out])?;
    }
    if let Some(b) = &args.ball_out {
        check_out_is_not_an_input(b, &[&args.calib, &out])?;
    }
    if let Some(e) = &args.events.events_out {
        let mut taken: Vec<&std::path::Path> = vec![&args.calib, &out];
        taken.extend(args.ball_out.as_deref());
        check_out_is_not_an_input(e, &taken)?;
    }
    let events_wanted = args.events.events_out.is_some() || args.zenoh_events;
    let events_config = args
        .events
        .config(events_wanted, "--events-out FILE or --zenoh-events")?;
    let mut cal = read_calibration(&args.calib)?;
    let mode = args.mode.into();
    if args.publish.is_some() {
        if args.inputs.len() != 1 {
            bail!(
                "a camera node (--publish) tracks one camera: give one --input, got {}",
                args.inputs.len()
            );
        }
        cal = node_calibration(&cal, args.camera.as_deref(), &args.calib)?;
    } else if args.camera.is_some() {
        bail!("--camera selects a camera node's camera: it needs --publish zenoh");
    }
    if args.inputs.len() != cal.cameras.len() {
        bail!(
            "{} has {} camera(s) but {} --input given: give one input per camera, in order",
            args.calib.display(),
            cal.cameras.len(),
            args.inputs.len()
        );
    }
    let node = match args.publish {
        Some(crate::network::NetworkArg::Zenoh) => {
            let cam = &cal.cameras[0];
            Some(crate::network::open_camera_node(
                &args.net,
                &cam.name,
                cam.index,
                args.preview_fps,
                args.ros2_domain,
                // The ball goes to ROS 2 with the node's ball rows (--zenoh-ball).
                cam.ball
                    .as_ref()
                    .filter(|_| args.zenoh_ball)
                    .map(|b| b.diameter_mm),
            )?)
        }
        None => None,
    };
    let console = match args.console {
        Some(addr) => {
            let c = Console::start(addr, None).context("starting the web console")?;
            eprintln!("web console: {}", c.url());
            Some(Arc::new(c))
        }
        None => None,
    };
    let options = SessionOptions {
        mode,
        filter: !args.raw,
        max_frames: args.max_frames,
        turn_anchors: args.reanchor.clone(),
        write: Some(args.write.into()),
        // A camera node's status goes out once a second.
        progress_period: node.is_some().then_some(std::time::Duration::from_secs(1)),
        ..SessionOptions::default()
    };
    let mut session = Session::open(&cal, &args.inputs, options)?;
    // The ball is tracked for --ball-out or --events-out; its rows go to the file, and with
    // --udp to the stream too, as datagrams of their own (`RTBL`).
    let cameras = cal.cameras.iter().map(|c| (c.index, c.name.clone()));
    let recording = crate::recording::open(&args.mcap, &args.net.table, cameras.collect())?;
    let ball_on_network = args.zenoh_ball && node.is_some();
    if args.ball_out.is_some() || events_wanted || ball_on_network {
        let mut sink = rodtrack_io::BallMultiSink::new();
        // A recording holds the ball's rows when the ball is tracked.
        if let Some(s) = recording
            .as_ref()
            .and_then(|r| crate::recording::ball_sink(r, &cal))
        {
            sink.push(s);
        }
        if let (Some(n), true) = (&node, ball_on_network) {
            sink.push(crate::network::node_ball_sink(n));
        }
        if let Some(path) = &args.ball_out {
            // CSV, or JSON Lines for `.jsonl` / `.json`, as the rods' rows.
            let created: Result<Box<dyn rodtrack_io::BallSink>, _> =
                match RowFormat::from_path(path) {
                    RowFormat::Csv => {
                        rodtrack_io::BallCsvSink::create(path).map(|s| Box::new(s) as _)
                    }
                    RowFormat::Jsonl => {
                        rodtrack_io::BallJsonlSink::create(path).map(|s| Box::new(s) as _)
                    }
                };
            sink.push(
                created.with_context(|| format!("creating the ball output {}", path.display()))?,
            );
        }
        if let Some(udp) = args.udp.as_deref() {
            sink.push(Box::new(
                rodtrack_io::UdpBallSink::new(udp).context("opening the UDP stream's ball rows")?,
            ));
        }
        if let Some(c) = &console {
            c.set_ball_field(events_config.field_length_mm, events_config.field_width_mm);
            sink.push(Box::new(crate::console_hooks::ConsoleBall(c.clone())));
        }
        session = session.with_ball(&cal, Box::new(sink))?;
    }
    if events_wanted {
        let mut sink = rodtrack_io::EventMultiSink::new();
        if let Some(path) = &args.events.events_out {
            sink.push(Box::new(
                rodtrack_io::EventJsonlSink::create(path)
                    .with_context(|| format!("creating the events output {}", path.display()))?,
            ));
        }
        // A camera node's events on `.../cam/<camera>/events` (--zenoh-events).
        if let (Some(n), true) = (&node, args.zenoh_events) {
            sink.push(crate::network::node_event_sink(n));
        }
        // A recording holds the events when they are detected.
        if let Some(r) = &recording {
            sink.push(Box::new(r.event_sink()));
        }
        // With --udp the events go to the stream too, as datagrams of their own (`RTEV`).
        if let Some(udp) = args.udp.as_deref() {
            sink.push(Box::new(
                rodtrack_io::UdpEventSink::new(udp).context("opening the UDP stream's events")?,
            ));
        }
        if let Some(c) = &console {
            sink.push(Box::new(crate::console_hooks::ConsoleEvents(c.clone())));
        }
        let what = match &args.events.events_out {
            Some(path) => path.display().to_string(),
            None => "--zenoh-events".to_string(),
        };
        session = session
            .with_events(&cal, events_config, Box::new(sink))
            .with_context(|| format!("detecting the events for {what}"))?;
    }
    for cam in session.cameras() {
        print_source_warnings(&cam.label, &*cam.source);
    }
    let format = args
        .format
        .map_or_else(|| RowFormat::from_path(&out), RowFormat::from);
    let mut sink = match &args.out {
        Some(out) => open_sinks(out, format, args.udp.as_deref())?,
        None => {
            let mut s = rodtrack_io::MultiSink::new();
            if let Some(udp) = args.udp.as_deref() {
                s.push(Box::new(
                    rodtrack_io::UdpSink::new(udp).context("opening the UDP stream")?,
                ));
            }
            s
        }
    };
    if let Some(n) = &node {
        sink.push(crate::network::node_sink(n));
    }
    if let Some(r) = &recording {
        sink.push(Box::new(r.sink()));
    }
    let stop = session.stop_flag();
    let sink = ConsoleRows {
        inner: sink,
        console: console.clone(),
        stop_on_broken_pipe: Some(stop.clone()),
    };
    crate::interrupt::install(stop);
    if let Some(c) = &console {
        c.attach_session(Arc::new(crate::console_hooks::SessionCommands(
            session.control(),
        )));
    }
    let hooks = CliHooks::new(
        true,
        console.map(|c| ConsoleHooks::new(c, session.cameras())),
    );
    let session_hooks: Arc<dyn Hooks> = match &node {
        Some(n) => crate::network::node_hooks(n, hooks.clone()),
        None => hooks.clone(),
    };
    let session_hooks = crate::recording::frame_hooks(recording.as_ref(), session_hooks);
    let (report, sink) = session.with_hooks(session_hooks).run(sink)?;
    drop(sink);
    crate::recording::finish(recording.as_ref())?;
    if let Some(n) = &node {
        crate::network::node_end(n)?;
    }
    hooks.finish(&report);
    if report.all_bad() {
        bail!(
            "every frame read was bad ({} frame(s)): nothing was measured; the rows written \
             (all `bad_frame`) are in {}",
            report
                .pipeline
                .cameras
                .iter()
                .map(|c| c.frames_read)
                .sum::<u64>(),
            out.display()
        );
    }
    if report.pipeline.sink_errors > 0 {
        bail!(
            "{} write(s) to the output failed (first: {}); rows written before are in {}",
            report.pipeline.sink_errors,
            report.pipeline.first_sink_error.as_deref().unwrap_or("?"),
            out.display()
        );
    }
    if let (Some(path), Some(b)) = (&args.ball_out, report.ball) {
        println!(
            "wrote {}: ball {} ok, {} predicted, {} lost",
            path.display(),
            b.ok,
            b.predicted,
            b.lost
        );
    }
    match (&args.events.events_out, report.events) {
        (Some(path), Some(e)) => println!("{}", crate::event_args::written(path, &e)),
        (None, Some(e)) => println!("published the events: {e}"),
        (_, None) => {}
    }
    match &args.out {
        Some(o) if o.as_os_str() == "-" => eprintln!("wrote standard output"),
        Some(o) => println!("wrote {}", o.display()),
        None => {}
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

/// Passes rows on to `inner` and shows them in the web console's plots; a write that fails on
/// a broken pipe (`--out - | head`) sets `stop_on_broken_pipe`: nobody reads any more.
pub struct ConsoleRows<S> {
    /// The sink written to.
    pub inner: S,
    /// The console whose plots get the rows.
    pub console: Option<Arc<ConsoleHandle>>,
    /// Set when the output's reader has gone.
    pub stop_on_broken_pipe: Option<Arc<AtomicBool>>,
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

/// The disagreements, sync warnings and source warnings printed in full; later ones are only
/// counted.
const MAX_WARNINGS: u64 = 20;
/// The bad frames printed in full per camera; later ones are only counted.
const MAX_BAD_FRAMES_PRINTED: u64 = 20;

/// The CLI's hooks: bad frames and fusion warnings on stderr (the first few), a progress bar
/// for recordings or live statistics, and the web console's live view when there is one.
pub struct CliHooks {
    progress: bool,
    console: Option<ConsoleHooks>,
    /// The last progress seen, for rates: (frames, measured, tracker ns).
    last: Mutex<(u64, u64, u64, std::time::Duration)>,
    printed: AtomicBool,
}

impl CliHooks {
    /// Hooks that print progress when `progress`, and feed `console`.
    pub fn new(progress: bool, console: Option<ConsoleHooks>) -> Arc<CliHooks> {
        Arc::new(CliHooks {
            progress,
            console,
            last: Mutex::new((0, 0, 0, std::time::Duration::ZERO)),
            printed: AtomicBool::new(false),
        })
    }

    /// Ends the progress line and prints the warning count and the run's summary.
    pub fn finish(&self, report: &rodtrack_sdk::RunReport) {
        if self.printed.load(Ordering::Relaxed) {
            eprintln!();
        }
        if report.warnings > MAX_WARNINGS {
            eprintln!(
                "{} camera disagreement / sync warnings ({} not printed)",
                report.warnings,
                report.warnings - MAX_WARNINGS
            );
        }
        eprintln!("{}", report.summary());
    }
}

impl Hooks for CliHooks {
    fn measured(
        &self,
        camera: u32,
        meta: &rodtrack_io::FrameMeta,
        rows: &[Measurement],
        pipe: &rodtrack_core::CameraPipeline,
    ) {
        if let Some(c) = &self.console {
            c.measured(camera, meta, rows, pipe);
        }
    }
    fn uses_frames(&self) -> bool {
        self.console.is_some()
    }
    fn frame(&self, camera: u32, buf: &mut rodtrack_io::FrameBuffer) {
        if let Some(c) = &self.console {
            c.frame(camera, buf);
        }
    }
    fn bad_frame(&self, camera: &str, frame_id: u64, error: &str, count: u64) {
        if count <= MAX_BAD_FRAMES_PRINTED {
            eprintln!("\n{camera}: frame {frame_id}: {error}");
        }
        if count == MAX_BAD_FRAMES_PRINTED {
            eprintln!("{camera}: further bad frames are counted, not printed");
        }
    }
    fn warning(&self, text: &str, count: u64) {
        if count <= MAX_WARNINGS {
            eprintln!("\n{text}");
        }
    }
    fn progress(&self, p: &Progress) {
        if !self.progress {
            return;
        }
        let line = match p.total {
            Some(t) if t > 0 => format!(
                "\r{:>6}/{t} frames [{:<30}] {} bad",
                p.sets,
                "#".repeat((30 * p.sets / t).min(30) as usize),
                p.bad
            ),
            _ => {
                let Ok(mut last) = self.last.lock() else {
                    return;
                };
                let (frames, measured, ns, at) = *last;
                let now_ns = p.tracker_time.as_nanos() as u64;
                let per_frame_us = (now_ns.saturating_sub(ns)) as f64 * 1e-3
                    / (p.measured.saturating_sub(measured)).max(1) as f64;
                let dt = (p.elapsed.saturating_sub(at)).as_secs_f64().max(1e-9);
                let fps = p.frames.saturating_sub(frames) as f64 / dt / p.cameras.max(1) as f64;
                *last = (p.frames, p.measured, now_ns, p.elapsed);
                format!(
                    "\r{:>8} sets  {fps:>6.1} frames/s per camera  {per_frame_us:>6.0} us per camera frame  {} dropped  {} bad   ",
                    p.sets, p.dropped, p.bad
                )
            }
        };
        eprint!("{line}");
        let _ = std::io::stderr().flush();
        self.printed.store(true, Ordering::Relaxed);
    }
}

#[cfg(test)]
mod tests {
    use rodtrack_io::runtime::{Handoff, RunMode, WriteMode};
    use rodtrack_sdk::pipeline_config;

    #[test]
    fn live_sources_run_inline_recordings_queued_both_write_per_set() {
        let live = pipeline_config(true);
        assert_eq!(
            (live.mode, live.handoff, live.write),
            (RunMode::Live, Handoff::Inline, WriteMode::Set)
        );
        let files = pipeline_config(false);
        assert_eq!(
            (files.mode, files.handoff, files.write),
            (RunMode::Batch, Handoff::Queue, WriteMode::Set)
        );
    }
}
