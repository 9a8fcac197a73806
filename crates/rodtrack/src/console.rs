//! `rodtrack console`: the web console, on the built-in simulator (`--demo`) or for
//! calibrating real cameras from their calibration inputs (`--inputs cam0.json ...`).

use crate::calibration_io::read_inputs;
use crate::simulate::build;
use anyhow::{anyhow, bail, Context, Result};
use rodtrack_console::{
    CalibrationContext, CameraOverlays, CameraSetup, Console, ConsoleHandle, ConsoleOptions,
    OwnedFrame, PipelineStats, RodOverlay,
};

use rodtrack_core::{
    CameraId, CameraPipeline, FrameSetFilter, FrameView, Measurement, Mode, PixelFormat,
};
use rodtrack_io::source::{decode_image_file, list_image_files};
use rodtrack_io::FrameBuffer;
use rodtrack_sim::{RenderInfo, Simulation};
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::sync::mpsc;
use std::time::{Duration, Instant};

/// Arguments of `rodtrack console`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Address to serve the console on (loopback by default; `0.0.0.0:8620` serves the network).
    #[arg(long, default_value = rodtrack_console::DEFAULT_ADDR)]
    pub addr: SocketAddr,
    /// Also answer to this host name (repeat for several): requests whose `Host` is not an IP
    /// address, `localhost` or an allowed name are refused (DNS rebinding).
    #[arg(long = "allow-host")]
    pub allow_host: Vec<String>,
    /// Run on the built-in simulator: the scenario in a loop at real time, tracked in enhanced
    /// mode and shown live.
    #[arg(long, conflicts_with = "inputs")]
    pub demo: bool,
    /// Calibration-inputs JSON, one per camera (repeat): serve the calibration page for them,
    /// their reference frames frozen.
    #[arg(long = "inputs")]
    pub inputs: Vec<PathBuf>,
    /// Where the page's "Save" writes the calibration file (TOML); the edited inputs and the
    /// reference frames go to `<out without extension>.inputs/`.
    #[arg(long, default_value = "calibration.toml")]
    pub out: PathBuf,
    /// Scenario of `--demo`.
    #[arg(long, default_value = "gameplay")]
    pub scenario: String,
    /// Seed of `--demo`.
    #[arg(long, default_value_t = 7)]
    pub seed: u64,
    /// Stop after this many seconds (default: run until interrupted).
    #[arg(long)]
    pub seconds: Option<f64>,
}

/// Runs the command.
pub fn run(args: Args) -> Result<()> {
    if args.demo {
        return run_demo(&args);
    }
    if args.inputs.is_empty() {
        bail!("give --demo (the built-in simulator) or --inputs CAM.json (calibration inputs)");
    }
    let mut cameras = Vec::new();
    for (index, path) in args.inputs.iter().enumerate() {
        let inputs = read_inputs(path)?;
        rodtrack_core::calib::validate::validate_inputs(&inputs, index as u32)
            .with_context(|| format!("calibration inputs {} are invalid", path.display()))?;
        let reference = load_reference(&inputs, path)?;
        cameras.push(CameraSetup {
            index: index as u32,
            inputs,
            reference: Some(reference),
        });
    }
    let console = Console::start_with(
        args.addr,
        Some(CalibrationContext {
            out_path: Some(args.out.clone()),
            cameras,
        }),
        &ConsoleOptions {
            allowed_hosts: args.allow_host.clone(),
        },
    )
    .context("cannot start the console")?;
    println!(
        "rodtrack console: {} (calibration; \"Save\" writes {})",
        console.url(),
        args.out.display()
    );
    match args.seconds {
        Some(s) => std::thread::sleep(Duration::from_secs_f64(s.max(0.0))),
        None => console.wait(),
    }
    Ok(())
}

/// Reads a camera's reference frame (`reference_frames.reference_frame` of its folder), as
/// `rodtrack calibrate` does.
fn load_reference(
    inputs: &rodtrack_core::calib::CalibrationInputs,
    path: &Path,
) -> Result<OwnedFrame> {
    let name = path.display();
    let format = PixelFormat::from_name(&inputs.pixel_format).ok_or_else(|| {
        anyhow!(
            "{name}: field `pixel_format`: unknown format {:?}",
            inputs.pixel_format
        )
    })?;
    let dir = path
        .parent()
        .unwrap_or(Path::new("."))
        .join(&inputs.reference_frames.dir);
    let files =
        list_image_files(&dir).with_context(|| format!("{name}: field `reference_frames.dir`"))?;
    let idx = inputs.reference_frames.reference_frame;
    if let Some(r) = inputs.rods.iter().find(|r| r.reference.frame != idx) {
        eprintln!(
            "warning: {name}: rod {} refers to frame {}, the console freezes frame {idx} for every rod",
            r.rod, r.reference.frame
        );
    }
    let file = files.get(idx).ok_or_else(|| {
        anyhow!(
            "{name}: field `reference_frames.reference_frame`: frame {idx} does not exist ({} images in {})",
            files.len(),
            dir.display()
        )
    })?;
    let mut buf = FrameBuffer::new();
    decode_image_file(file, Some(format), &mut buf)
        .with_context(|| format!("reference frame {}", file.display()))?;
    let view: FrameView = buf.view()?;
    Ok(OwnedFrame::from_view(&view, idx as u64, 0.0))
}

/// A render request: frame index of the scenario, into this buffer.
type Request = (usize, Vec<u8>);
/// A rendered frame.
type Rendered = Result<(Vec<u8>, RenderInfo), String>;

/// One render thread per camera, each with its own copy of the simulation.
struct Renderer {
    tx: mpsc::SyncSender<Request>,
    rx: mpsc::Receiver<Rendered>,
}

fn spawn_renderer(mut sim: Simulation, camera: usize) -> Result<Renderer> {
    let (tx, req_rx) = mpsc::sync_channel::<Request>(2);
    let (out_tx, rx) = mpsc::sync_channel::<Rendered>(2);
    std::thread::Builder::new()
        .name(format!("render-{camera}"))
        .spawn(move || {
            while let Ok((index, mut buf)) = req_rx.recv() {
                let r = sim
                    .render(index, camera, &mut buf)
                    .map(|meta| (buf, meta))
                    .map_err(|e| e.to_string());
                if out_tx.send(r).is_err() {
                    break;
                }
            }
        })?;
    Ok(Renderer { tx, rx })
}

fn run_demo(args: &Args) -> Result<()> {
    println!(
        "rodtrack console --demo: two simulated 1440x1080 Bayer cameras, scenario `{}`",
        args.scenario
    );
    let mut sim = build(&args.scenario, None, args.seed, false)?;
    let ncam = sim.cameras().len();
    let fps = 1.0 / sim.timestamp_s(1).max(1e-6);
    // Calibrate as `rodtrack demo` does; the inputs and reference frames go to the console.
    let mut cals = Vec::new();
    let mut setups = Vec::new();
    for c in 0..ncam {
        let (inputs, buf, meta, cal) =
            crate::simulate::calibrate_sim_camera(&mut sim, c, args.seed)?;
        let view = FrameView::new(&buf, meta.width, meta.height, meta.stride, meta.format)?;
        cals.push(cal);
        setups.push(CameraSetup {
            index: c as u32,
            inputs,
            reference: Some(OwnedFrame::from_view(&view, meta.frame_id, 0.0)),
        });
    }
    let console = Console::start_with(
        args.addr,
        Some(CalibrationContext {
            out_path: Some(args.out.clone()),
            cameras: setups,
        }),
        &ConsoleOptions {
            allowed_hosts: args.allow_host.clone(),
        },
    )
    .context("cannot start the console")?;
    println!(
        "rodtrack console: {} (live demo at {fps:.0} fps)",
        console.url()
    );
    let mut pipes: Vec<CameraPipeline> = cals
        .iter()
        .map(|c| CameraPipeline::new(c, Mode::Enhanced))
        .collect::<Result<_, _>>()?;
    let renderers: Vec<Renderer> = (0..ncam)
        .map(|c| spawn_renderer(sim.clone(), c))
        .collect::<Result<_>>()?;
    let mut spare: Vec<Vec<u8>> = (0..ncam)
        .map(|c| sim.frame_bytes(c).map(|b| vec![0u8; b]))
        .collect::<Result<_, _>>()?;
    drop(sim);
    let n = sim_frames(args)?;
    let mut loop_state = DemoLoop {
        console: &console,
        filter: FrameSetFilter::new(Mode::Enhanced, ncam > 1),
        rows: Vec::new(),
        filtered: Vec::new(),
        overlays: Vec::new(),
        geometry: pipes
            .iter()
            .map(|p| CameraOverlays::new(p.rods()))
            .collect(),
        frame_us: Vec::new(),
        processed: 0,
        dropped: 0,
        last_stats: Instant::now(),
        window_start: (Instant::now(), 0),
        fps_recent: 0.0,
    };
    let t0 = Instant::now();
    let deadline = args.seconds.map(Duration::from_secs_f64);
    // Frame k of the endless run is scenario frame k % n; one frame set in flight ahead.
    let mut k: u64 = 0;
    for (c, r) in renderers.iter().enumerate() {
        r.tx.send(((k % n) as usize, std::mem::take(&mut spare[c])))
            .map_err(|_| anyhow!("render thread {c} stopped"))?;
    }
    loop {
        let mut frames = Vec::with_capacity(ncam);
        for (c, r) in renderers.iter().enumerate() {
            let got =
                r.rx.recv()
                    .map_err(|_| anyhow!("render thread {c} stopped"))?;
            frames.push(got.map_err(|e| anyhow!("camera {c}: {e}"))?);
        }
        // Real time: the next frame set is the one due now (frames we are late for are dropped).
        let due = (t0.elapsed().as_secs_f64() * fps) as u64;
        let next = (k + 1).max(due);
        loop_state.dropped += next - k - 1;
        for (c, r) in renderers.iter().enumerate() {
            let buf = vec![0u8; frames[c].0.len()];
            let buf = if spare[c].len() == buf.len() {
                std::mem::take(&mut spare[c])
            } else {
                buf
            };
            r.tx.send(((next % n) as usize, buf))
                .map_err(|_| anyhow!("render thread {c} stopped"))?;
        }
        // Wait for frame k's time, then track and publish it.
        let at = Duration::from_secs_f64(k as f64 / fps);
        if let Some(wait) = at.checked_sub(t0.elapsed()) {
            std::thread::sleep(wait);
        }
        if k % n == 0 {
            loop_state.filter = FrameSetFilter::new(Mode::Enhanced, ncam > 1);
        }
        loop_state.frame_set(&mut pipes, &mut frames, k, k as f64 / fps)?;
        for (c, (buf, _)) in frames.into_iter().enumerate() {
            spare[c] = buf;
        }
        k = next;
        if deadline.is_some_and(|d| t0.elapsed() >= d) {
            break;
        }
    }
    let o = console.overhead();
    println!(
        "processed {} frame sets, dropped {}; console publish calls: {}, {:.1} ms in total",
        loop_state.processed,
        loop_state.dropped,
        o.calls,
        o.total_ns as f64 / 1e6
    );
    Ok(())
}

fn sim_frames(args: &Args) -> Result<u64> {
    // The scenario's own length (the simulation was built without a frame limit).
    let sc = rodtrack_sim::Scenario::by_name(
        &args.scenario,
        &rodtrack_sim::SceneConfig::default(),
        args.seed,
    )?;
    Ok(sc.frame_count().max(1) as u64)
}

/// The tracking side of the demo: everything per frame set.
struct DemoLoop<'a> {
    console: &'a ConsoleHandle,
    filter: FrameSetFilter,
    rows: Vec<Measurement>,
    filtered: Vec<Measurement>,
    overlays: Vec<RodOverlay>,
    /// The overlays' constant parts, per camera.
    geometry: Vec<CameraOverlays>,
    frame_us: Vec<f64>,
    processed: u64,
    dropped: u64,
    last_stats: Instant,
    window_start: (Instant, u64),
    fps_recent: f64,
}

impl DemoLoop<'_> {
    fn frame_set(
        &mut self,
        pipes: &mut [CameraPipeline],
        frames: &mut [(Vec<u8>, RenderInfo)],
        frame_id: u64,
        timestamp_s: f64,
    ) -> Result<()> {
        let t = Instant::now();
        self.rows.clear();
        for (c, (buf, meta)) in frames.iter_mut().enumerate() {
            let view = FrameView::new(buf, meta.width, meta.height, meta.stride, meta.format)?;
            pipes[c].process(&view, frame_id, timestamp_s, &mut self.rows)?;
            // The overlays only when the console wants the frame (kept between frames: the
            // next live frame reuses them).
            let wanted = self.console.wants_frame(c as u32);
            if wanted {
                self.geometry[c].fill(pipes[c].last_results(), &mut self.overlays);
            }
            let overlays: &[RodOverlay] = if wanted { &self.overlays } else { &[] };
            // The rendered buffer is handed over without a copy (a spare one comes back).
            self.console.publish_frame_buffer(
                c as u32,
                buf,
                meta.width,
                meta.height,
                meta.stride,
                meta.format,
                frame_id,
                timestamp_s,
                overlays,
            );
        }
        self.filtered.clear();
        self.filter.process(&self.rows, &mut self.filtered);
        self.filtered.retain(|m| m.camera == CameraId::Fused);
        // Each camera's rows and the fused ones, in one call.
        self.rows.extend_from_slice(&self.filtered);
        self.console.publish_rows(&self.rows);
        self.frame_us.push(t.elapsed().as_secs_f64() * 1e6);
        self.processed += 1;
        if self.last_stats.elapsed() >= Duration::from_millis(250) {
            self.last_stats = Instant::now();
            let (w0, n0) = self.window_start;
            let dt = w0.elapsed().as_secs_f64();
            if dt >= 1.0 {
                self.fps_recent = (self.processed - n0) as f64 / dt;
                self.window_start = (Instant::now(), self.processed);
            }
            let mut recent = self.frame_us.clone();
            recent.sort_by(|a, b| a.total_cmp(b));
            let median = recent.get(recent.len() / 2).copied().unwrap_or(0.0);
            self.frame_us.clear();
            self.console.publish_stats(&PipelineStats {
                frames: self.processed,
                fps: self.fps_recent,
                frame_time_us: median,
                dropped_frames: self.dropped,
                bad_frames: 0,
            });
        }
        Ok(())
    }
}
