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
    /// Random tables as built (`asbuilt:1` to `asbuilt:N`, `poses` scenario, with known poses
    /// and their angle, with their positions alone, and without) scored per camera, worst and
    /// median, into `tables.md` and `tables.json` (default 10, 2 with --quick; 0 skips them).
    #[arg(long)]
    pub tables: Option<u64>,
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
    let n_tables = args.tables.unwrap_or(if args.quick { 2 } else { 10 });
    if n_tables > 0 {
        let seeds: Vec<u64> = (1..=n_tables).collect();
        eprintln!(
            "rodtrack evaluate: {n_tables} tables as built, with known poses (with their angle, \
             their position alone) and without"
        );
        let work = args.out.join("tables-work");
        let mut tables = Vec::new();
        for known in rodtrack_eval::tables::KnownPoses::ALL {
            tables.push(
                rodtrack_eval::tables::run_tables(&seeds, known, &work)
                    .context("the tables as built")?,
            );
        }
        let _ = std::fs::remove_dir_all(&work);
        let md = rodtrack_eval::tables::format_tables(&tables);
        let (md_path, json_path) = (args.out.join("tables.md"), args.out.join("tables.json"));
        std::fs::write(&md_path, &md)
            .with_context(|| format!("cannot write {}", md_path.display()))?;
        std::fs::write(&json_path, serde_json::to_string_pretty(&tables)?)
            .with_context(|| format!("cannot write {}", json_path.display()))?;
        for t in &tables {
            println!(
                "tables as built (known poses: {}), per camera, worst / median: coverage {:.3} / \
                 {:.3}, position std {:.4} / {:.4} mm, max {:.3} / {:.3} mm, angle std {:.4} / \
                 {:.4} rad, max {:.4} / {:.4} rad, {} gross",
                t.known_poses.label(),
                t.worst.coverage,
                t.median.coverage,
                t.worst.pos_std_mm,
                t.median.pos_std_mm,
                t.worst.pos_max_mm,
                t.median.pos_max_mm,
                t.worst.ang_std_rad,
                t.median.ang_std_rad,
                t.worst.ang_max_rad,
                t.median.ang_max_rad,
                t.gross
            );
        }
        println!("wrote {}", md_path.display());
    }
    println!(
        "wrote {} and {} plots in {:.1} s",
        args.out.join("report.md").display(),
        report.plots.len(),
        t0.elapsed().as_secs_f64()
    );
    Ok(())
}
