//! `rodtrack simulate`.

use anyhow::{Context, Result};
use rodtrack_sim::{write_recording, CalibOptions, RecordOptions, SCENARIO_NAMES};
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
    /// With `--known-poses`, list each known pose's position alone, without its angle (an
    /// operator who pushes each rod to its stops without knowing its angle there).
    #[arg(long, requires = "known_poses")]
    pub known_poses_without_angle: bool,
    /// The table as built: `default`, a named variation, `asbuilt:SEED` (cameras tilted,
    /// shifted and with other lenses, rods off their places, print seams; drawn from SEED),
    /// `exposure:US` (every camera's exposure, its gain lowered to keep the levels), or several
    /// joined by `+` (`asbuilt:3+exposure:2000`).
    #[arg(long, default_value = "default")]
    pub setup: String,
    /// Render the markers with N x N point rays per pixel instead of each pixel's whole area
    /// (as a ray tracer with a few rays per pixel, or a sensor with a small fill factor: the
    /// print's edges then alias with the pixel grid).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u8).range(1..=8))]
    pub point_rays: Option<u8>,
}

/// Runs the command.
pub fn run(args: Args) -> Result<()> {
    let mut sim = rodtrack_sim::build_simulation(
        &args.scenario,
        args.frames,
        args.seed,
        args.quality,
        &args.setup,
    )?;
    if let Some(n) = args.point_rays {
        sim = sim.with_point_rays(n as usize);
    }
    let opts = RecordOptions {
        every: args.every,
        calib_seed: args.seed,
        calib: CalibOptions {
            include_opencv_model: !args.no_opencv_model,
            known_poses: args.known_poses,
            known_pose_angles: !args.known_poses_without_angle,
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
