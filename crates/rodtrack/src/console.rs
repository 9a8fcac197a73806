//! `rodtrack console`: the web console, on the built-in simulator (`--demo`) or for
//! calibrating real cameras from their calibration inputs (`--inputs cam0.json ...`), or for
//! a camera network's nodes (`--subscribe zenoh`, in `console_remote`).

use crate::console_hooks::{ConsoleHooks, LiveHooks};
use crate::track::ConsoleRows;
use anyhow::{bail, Context, Result};
use rodtrack_console::{CalibrationContext, CameraSetup, Console, ConsoleOptions, OwnedFrame};
use rodtrack_core::FrameView;
use rodtrack_sdk::{print_warning, read_inputs, Session, SessionOptions};
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Duration;

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
    /// Show a camera network's nodes: every camera node's rows, status and preview frames,
    /// the fusion node's fused rows and status (docs/network.md; needs the `zenoh` feature).
    #[arg(long, value_enum, conflicts_with_all = ["demo", "inputs"])]
    pub subscribe: Option<crate::network::NetworkArg>,
    /// The network's endpoints and table (with --subscribe).
    #[command(flatten)]
    pub net: crate::network::NetArgs,
}

/// Runs the command.
pub fn run(args: Args) -> Result<()> {
    if args.demo {
        return run_demo(&args);
    }
    if args.subscribe.is_some() {
        return crate::console_remote::run(&args);
    }
    if args.inputs.is_empty() {
        bail!("give --demo (the built-in simulator), --inputs CAM.json (calibration inputs) or --subscribe zenoh (a camera network)");
    }
    let mut cameras = Vec::new();
    for (index, path) in args.inputs.iter().enumerate() {
        let inputs = read_inputs(path, &mut print_warning)?;
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
    let folder = rodtrack_sdk::ReferenceFolder::open(inputs, path)?;
    let idx = inputs.reference_frames.reference_frame;
    if let Some(r) = inputs.rods.iter().find(|r| r.reference.frame != idx) {
        eprintln!(
            "warning: {}: rod {} refers to frame {}, the console freezes frame {idx} for every rod",
            path.display(),
            r.rod,
            r.reference.frame
        );
    }
    let buf = folder.read(idx, "field `reference_frames.reference_frame`")?;
    let view: FrameView = buf.view()?;
    Ok(OwnedFrame::from_view(&view, idx as u64, 0.0))
}

fn run_demo(args: &Args) -> Result<()> {
    println!(
        "rodtrack console --demo: two simulated 1440x1080 Bayer cameras, scenario `{}`",
        args.scenario
    );
    let mut sim =
        rodtrack_sim::build_simulation(&args.scenario, None, args.seed, false, "default")?;
    let ncam = sim.cameras().len();
    let fps = 1.0 / sim.timestamp_s(1).max(1e-6);
    // Calibrate as `rodtrack demo` does; the inputs and reference frames go to the console.
    let mut cals = Vec::new();
    let mut setups = Vec::new();
    for c in 0..ncam {
        let rodtrack_sim::SimCalibration {
            inputs,
            reference: buf,
            meta,
            calibration: cal,
        } = rodtrack_sim::calibrate_sim_camera(&mut sim, c, args.seed)?;
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
    // The scenario in a loop at real time: the simulated cameras through a session, the
    // console fed by its hooks and its sink.
    let playback = rodtrack_sim::Playback {
        realtime: true,
        looping: true,
        ..Default::default()
    };
    let cameras = rodtrack_eval::sim_run::sim_cameras(&sim, &cals, playback)?;
    drop(sim);
    let console = Arc::new(console);
    let hooks = LiveHooks(ConsoleHooks::new(console.clone(), &cameras));
    let session = Session::from_cameras(cameras, SessionOptions::default());
    console.attach_session(Arc::new(crate::console_hooks::SessionCommands(
        session.control(),
    )));
    let stop = session.stop_flag();
    crate::interrupt::install(stop.clone());
    if let Some(secs) = args.seconds {
        let stop = stop.clone();
        std::thread::Builder::new()
            .name("rodtrack-deadline".into())
            .spawn(move || {
                std::thread::sleep(Duration::from_secs_f64(secs.max(0.0)));
                stop.store(true, std::sync::atomic::Ordering::SeqCst);
            })?;
    }
    let sink = ConsoleRows {
        inner: rodtrack_io::MultiSink::new(),
        console: Some(console.clone()),
        stop_on_broken_pipe: None,
    };
    let (report, sink) = session.with_hooks(Arc::new(hooks)).run(sink)?;
    drop(sink);
    let sets = report.pipeline.sets_complete + report.pipeline.sets_incomplete;
    let dropped: u64 = report
        .pipeline
        .cameras
        .iter()
        .map(|c| c.frames_dropped)
        .sum();
    let o = console.overhead();
    println!(
        "processed {sets} frame sets, dropped {dropped}; console publish calls: {}, {:.1} ms in total",
        o.calls,
        o.total_ns as f64 / 1e6
    );
    Ok(())
}
