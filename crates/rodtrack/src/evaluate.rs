//! `rodtrack evaluate`: every simulator scenario through calibration and tracking, in the
//! paper's mode and in rodtrack's, scored against ground truth, written up as a Markdown report
//! with the paper's reference numbers (SPEC section 7) and plots in the style of its figures
//! 13-16 (all of it in [`rodtrack_eval`]).

use anyhow::{bail, Context, Result};
use rodtrack_eval::plan::{full_frames, plan_for, Plan};
use rodtrack_eval::report::{write_report, ReportInfo};
use rodtrack_eval::run::run_plans;
use rodtrack_sim::SCENARIO_NAMES;
use std::path::PathBuf;
use std::time::Instant;

/// Arguments of `rodtrack evaluate`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Output folder (report.md, summary.json, plots).
    #[arg(long)]
    pub out: PathBuf,
    /// Scales the frames processed per scenario (2 = twice as many; 0.5 = half).
    #[arg(long, default_value_t = 1.0)]
    pub frames_scale: f64,
    /// About a tenth of the frames (CI): under a minute in all.
    #[arg(long)]
    pub quick: bool,
    /// Run only these scenarios (repeatable; default: all).
    #[arg(long = "scenario", value_parser = SCENARIO_NAMES)]
    pub scenarios: Vec<String>,
    /// Seed (scene noise, calibration clicks, random motions).
    #[arg(long, default_value_t = 7)]
    pub seed: u64,
    /// Scenarios run at once (default: the number of CPUs, at most 4).
    #[arg(long)]
    pub jobs: Option<usize>,
}

/// Runs the command.
pub fn run(args: Args) -> Result<()> {
    let t0 = Instant::now();
    let scale = args.frames_scale * if args.quick { 0.1 } else { 1.0 };
    if !(scale.is_finite() && scale > 0.0) {
        bail!("--frames-scale must be positive, got {}", args.frames_scale);
    }
    let names: Vec<String> = if args.scenarios.is_empty() {
        SCENARIO_NAMES.iter().map(|s| s.to_string()).collect()
    } else {
        args.scenarios.clone()
    };
    let plans: Vec<Plan> = names
        .iter()
        .map(|n| plan_for(n, scale, full_frames(n, args.seed)))
        .collect();
    let jobs = args.jobs.unwrap_or_else(|| {
        std::thread::available_parallelism()
            .map(|n| n.get())
            .unwrap_or(1)
            .min(4)
    });
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("cannot create {}", args.out.display()))?;
    eprintln!(
        "rodtrack evaluate: {} scenarios, frame scale {scale}, {jobs} at once, into {}",
        plans.len(),
        args.out.display()
    );
    let results = run_plans(&plans, args.seed, jobs, true)?;
    let run_s = t0.elapsed().as_secs_f64();
    let cmd: Vec<String> = std::env::args().collect();
    let report = write_report(
        &args.out,
        &results,
        &ReportInfo {
            command: cmd.join(" "),
            seed: args.seed,
            scale,
            jobs,
            run_s,
        },
    )?;
    print!("{}", report.headline);
    println!(
        "wrote {} and {} plots in {:.1} s",
        args.out.join("report.md").display(),
        report.plots.len(),
        t0.elapsed().as_secs_f64()
    );
    Ok(())
}
