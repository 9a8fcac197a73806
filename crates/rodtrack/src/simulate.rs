//! `rodtrack simulate`.

use anyhow::{Context, Result};
use rodtrack_sim::{
    default_cameras, write_recording, CalibOptions, RecordOptions, RenderMode, Scenario,
    SceneConfig, Simulation, SCENARIO_NAMES,
};
use std::io::Write;
use std::num::NonZeroUsize;
use std::path::PathBuf;

/// Arguments of `rodtrack simulate`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Scenario name.
    #[arg(long, value_parser = SCENARIO_NAMES)]
    pub scenario: String,
    /// Output folder.
    #[arg(long)]
    pub out: PathBuf,
    /// Number of frames (default: the scenario's duration).
    #[arg(long)]
    pub frames: Option<usize>,
    /// Write only every K-th frame (0, K, 2K, ...), as a camera at 1/K of the frame rate
    /// would record the scenario (e.g. a sweep for `calibrate --auto`). Files keep the frame
    /// ids of the full timeline (so their timestamps stay right); `truth.csv` holds the rows of
    /// the frames written only.
    #[arg(long, value_name = "K", default_value = "1")]
    pub every: NonZeroUsize,
    /// Seed (scene variations, noise, clicks).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Quality rendering (supersampled, finer motion blur) instead of fast.
    #[arg(long)]
    pub quality: bool,
    /// Leave the OpenCV camera model out of the calibration inputs.
    #[arg(long)]
    pub no_opencv_model: bool,
    /// Also write known-pose frames to the reference folder (frames 1+3k, 2+3k, 3+3k: rod k
    /// at the start, middle and end of its travel) and list them in the calibration inputs.
    #[arg(long)]
    pub known_poses: bool,
    /// The table as built: `default`, a named variation, or `asbuilt:SEED` (cameras tilted,
    /// shifted and with other lenses, rods off their places, print seams; drawn from SEED).
    #[arg(long, default_value = "default")]
    pub setup: String,
}

/// Builds a simulation of the reference table.
pub fn build(
    scenario: &str,
    frames: Option<usize>,
    seed: u64,
    quality: bool,
) -> Result<Simulation> {
    build_setup(scenario, frames, seed, quality, "default")
}

/// [`build`] on a table set up as `setup` says (see [`rodtrack_sim::apply_variation`]).
pub fn build_setup(
    scenario: &str,
    frames: Option<usize>,
    seed: u64,
    quality: bool,
    setup: &str,
) -> Result<Simulation> {
    let mut scene = SceneConfig::default();
    let mut cameras = default_cameras();
    rodtrack_sim::apply_variation(setup, &mut scene, &mut cameras)?;
    let mut sc = Scenario::by_name(scenario, &scene, seed)?;
    if let Some(n) = frames {
        sc = sc.with_frames(n);
    }
    let mode = if quality {
        RenderMode::Quality
    } else {
        RenderMode::Fast
    };
    Ok(Simulation::new(scene, cameras, sc, mode)?.with_seed(seed))
}

/// Calibrates camera `c` of a simulation as an operator would: its simulated clicks (about
/// 1 px of error) and a rendered reference frame. Returns the inputs, the reference frame and
/// the calibration.
pub fn calibrate_sim_camera(
    sim: &mut Simulation,
    c: usize,
    seed: u64,
) -> Result<(
    rodtrack_core::calib::CalibrationInputs,
    Vec<u8>,
    rodtrack_sim::RenderInfo,
    rodtrack_core::calib::CameraCalibration,
)> {
    let inputs = sim.calibration_inputs(c, seed)?;
    let mut buf = vec![0u8; sim.frame_bytes(c)?];
    let meta = sim.render_reference(c, &mut buf)?;
    let view =
        rodtrack_core::FrameView::new(&buf, meta.width, meta.height, meta.stride, meta.format)?;
    let fps = 1.0 / sim.timestamp_s(1).max(1e-6);
    let cal = crate::calibrate::calibrate_from_view(&inputs, &view, c as u32, fps)?;
    Ok((inputs, buf, meta, cal))
}

/// Runs the command.
pub fn run(args: Args) -> Result<()> {
    let mut sim = build_setup(
        &args.scenario,
        args.frames,
        args.seed,
        args.quality,
        &args.setup,
    )?;
    let opts = RecordOptions {
        every: args.every,
        calib_seed: args.seed,
        calib: CalibOptions {
            include_opencv_model: !args.no_opencv_model,
            known_poses: args.known_poses,
            ..CalibOptions::default()
        },
        ..RecordOptions::default()
    };
    let mut last = std::time::Instant::now();
    let summary = write_recording(&mut sim, &args.out, &opts, &mut |done, total| {
        if last.elapsed().as_millis() > 200 || done == total {
            last = std::time::Instant::now();
            eprint!("\rrendering {done}/{total} frames");
            let _ = std::io::stderr().flush();
        }
    })
    .with_context(|| format!("writing the recording to {}", args.out.display()))?;
    eprintln!();
    let every = match args.every.get() {
        1 => String::new(),
        k => format!(" (one in {k})"),
    };
    println!(
        "wrote {} frames{every} x {} cameras and {} truth rows to {}",
        summary.frames,
        summary.cameras,
        summary.truth_rows,
        args.out.display()
    );
    Ok(())
}
