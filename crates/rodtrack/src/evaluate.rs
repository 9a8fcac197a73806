//! `rodtrack evaluate`: every simulator scenario through calibration and tracking, in the
//! paper's mode and in rodtrack's, scored against ground truth, written up as a Markdown report
//! with the paper's reference numbers (SPEC section 7) and plots in the style of its figures
//! 13-16.

use crate::plots::{write_figure, Figure, Line, Panel, Series, PALETTE};
use crate::score::{score, wrap_angle, Stats};
use anyhow::{anyhow, bail, Context, Result};
use plotters::style::RGBColor;
use rodtrack_core::calib::CameraCalibration;
use rodtrack_core::{CameraId, FrameView, Measurement, Status};
use rodtrack_sim::SCENARIO_NAMES;
use std::collections::BTreeMap;
use std::f64::consts::TAU;
use std::fmt::Write as _;
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;
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

/// Which part of a scenario's timeline is processed.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Span {
    /// The whole timeline, every `n`-th frame (slow motions: the camera at 200/n fps).
    Whole(usize),
    /// The first `n` frames at the full 200 fps.
    First(usize),
}

/// Default spans: about 9,300 frame sets in all (a few minutes on 2 cores).
const DEFAULT_SPANS: [(&str, Span); 9] = [
    ("exp1", Span::Whole(3)),
    ("exp2", Span::Whole(8)),
    ("exp3", Span::Whole(6)),
    ("spin600", Span::First(1000)),
    ("spin3000", Span::First(1000)),
    ("lighting", Span::Whole(5)),
    ("gameplay", Span::First(1200)),
    ("sweep", Span::Whole(5)),
    ("static", Span::First(600)),
];

/// What one scenario runs: `frames` of the timeline (200 fps), every `stride`-th processed.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Plan {
    /// Scenario name.
    pub name: String,
    /// Frames of the timeline simulated (None: the whole scenario).
    pub frames: Option<usize>,
    /// Every `stride`-th frame is rendered and processed.
    pub stride: usize,
}

/// The plan of scenario `name` at frame scale `scale`: above 1, more frames (a smaller
/// stride); below 1, a shorter part of the timeline (the stride stays, so that the temporal
/// filter sees the same frame rate).
pub fn plan_for(name: &str, scale: f64, full_frames: usize) -> Plan {
    let span = DEFAULT_SPANS
        .iter()
        .find(|(n, _)| *n == name)
        .map_or(Span::First(600), |(_, s)| *s);
    let scale = if scale.is_finite() && scale > 0.0 {
        scale
    } else {
        1.0
    };
    let (frames, stride) = match span {
        Span::Whole(s) if scale >= 1.0 => (None, ((s as f64 / scale).round() as usize).max(1)),
        Span::Whole(s) => (Some((full_frames as f64 * scale).round() as usize), s),
        Span::First(n) => (Some((n as f64 * scale).round() as usize), 1),
    };
    Plan {
        name: name.to_string(),
        frames: frames.map(|n| n.clamp(4 * stride, full_frames.max(4 * stride))),
        stride,
    }
}

/// Rows of one way of measuring, with the `Option<bool>` that `score` takes.
type Rows = Vec<(Measurement, Option<bool>)>;

/// The ways of measuring that are scored, in table order.
pub const MODES: [&str; 4] = [
    "paper mode, each camera (raw)",
    "rodtrack, each camera (raw)",
    "rodtrack, each camera, filtered",
    "rodtrack, cameras fused + filtered",
];

/// Everything measured on one scenario.
#[derive(Debug, Clone, serde::Serialize)]
pub struct ScenarioResult {
    /// What was run.
    pub plan: Plan,
    /// Frame sets processed.
    pub frames_processed: usize,
    /// Cameras.
    pub cameras: usize,
    /// Overall stats per mode, in [`MODES`] order.
    pub overall: Vec<Stats>,
    /// Per-rod stats per mode.
    pub per_rod: Vec<BTreeMap<u32, Stats>>,
    /// Stats per mode on the rows where the rod turns at 90 % of the scenario's top angular
    /// speed or more (the spin scenarios' constant-rate part).
    pub at_top_speed: Option<(f64, Vec<Stats>)>,
    /// Median processing time per camera frame (all its rods), us: rodtrack, paper mode.
    pub median_us: (f64, f64),
    /// Seconds spent: simulator setup + calibration, then the frame loop.
    pub setup_s: f64,
    /// Seconds in the frame loop.
    pub loop_s: f64,
    /// Calibration warnings.
    pub warnings: Vec<String>,
    /// All rows, kept for the scenarios that are plotted.
    #[serde(skip)]
    pub rows: Option<Box<ScenarioRows>>,
}

/// The rows of one scenario.
#[derive(Debug, Clone, Default)]
pub struct ScenarioRows {
    /// Ground truth (every camera).
    pub truth: Rows,
    /// Per mode, in [`MODES`] order.
    pub modes: [Rows; 4],
}

/// Progress shared by the jobs.
struct Progress {
    done: AtomicUsize,
    total: usize,
    start: Instant,
    current: Mutex<BTreeMap<String, (usize, usize)>>,
    last: Mutex<Instant>,
    enabled: bool,
}

impl Progress {
    fn update(&self, name: &str, done: usize, total: usize, step: usize) {
        self.done.fetch_add(step, Ordering::Relaxed);
        if let Ok(mut c) = self.current.lock() {
            if done >= total {
                c.remove(name);
            } else {
                c.insert(name.to_string(), (done, total));
            }
        }
        self.draw(false);
    }
    fn draw(&self, force: bool) {
        if !self.enabled {
            return;
        }
        let Ok(mut last) = self.last.lock() else {
            return;
        };
        if !force && last.elapsed().as_millis() < 200 {
            return;
        }
        *last = Instant::now();
        let done = self.done.load(Ordering::Relaxed).min(self.total);
        let frac = done as f64 / self.total.max(1) as f64;
        let width = 30;
        let filled = (frac * width as f64).round() as usize;
        let running = self
            .current
            .lock()
            .map(|c| {
                c.iter()
                    .map(|(n, (d, t))| format!("{n} {d}/{t}"))
                    .collect::<Vec<_>>()
                    .join(", ")
            })
            .unwrap_or_default();
        let mut err = std::io::stderr().lock();
        let _ = write!(
            err,
            "\r[{}{}] {:>3.0}%  {:>5.1} s  {:<48.48}",
            "#".repeat(filled),
            ".".repeat(width - filled),
            100.0 * frac,
            self.start.elapsed().as_secs_f64(),
            running
        );
        let _ = err.flush();
    }
}

/// Units of progress for the setup of one scenario (simulator tables, calibration), in frame
/// sets.
const SETUP_UNITS: usize = 400;

/// A calibration and its warnings.
type Calibrated = (Vec<CameraCalibration>, Vec<String>);

/// Calibrations made so far, one per lighting of the table: the table and its cameras are
/// calibrated once (as an operator would), not before every experiment.
type CalibCache =
    Mutex<BTreeMap<String, std::sync::Arc<std::sync::OnceLock<Result<Calibrated, String>>>>>;

/// Calibrates every camera from the simulated clicks and reference frame, the cameras in
/// parallel.
fn calibrate_all(sim: &mut rodtrack_sim::Simulation, seed: u64) -> Result<Calibrated> {
    let ncam = sim.cameras().len();
    let mut refs = Vec::new();
    for c in 0..ncam {
        let inputs = sim.calibration_inputs(c, seed)?;
        let mut buf = vec![0u8; sim.frame_bytes(c)?];
        let meta = sim.render_reference(c, &mut buf)?;
        refs.push((inputs, buf, meta));
    }
    let per_camera: Vec<Result<(CameraCalibration, Vec<String>)>> = std::thread::scope(|s| {
        let handles: Vec<_> = refs
            .iter()
            .enumerate()
            .map(|(c, (inputs, buf, meta))| {
                s.spawn(move || -> Result<(CameraCalibration, Vec<String>)> {
                    let view =
                        FrameView::new(buf, meta.width, meta.height, meta.stride, meta.format)?;
                    let cal = rodtrack_core::calib::calibrate_camera_from_view(
                        inputs, &view, c as u32, 200.0,
                    )?;
                    let warnings = cal
                        .rods
                        .iter()
                        .flat_map(|r| {
                            r.residuals
                                .warnings
                                .iter()
                                .map(move |w| format!("camera {c} rod {}: {w}", r.rod))
                        })
                        .collect();
                    Ok((cal, warnings))
                })
            })
            .collect();
        handles
            .into_iter()
            .map(|h| {
                h.join()
                    .unwrap_or_else(|_| Err(anyhow!("a calibration thread panicked")))
            })
            .collect()
    });
    let mut cals = Vec::new();
    let mut warnings = Vec::new();
    for r in per_camera {
        let (c, w) = r?;
        cals.push(c);
        warnings.extend(w);
    }
    Ok((cals, warnings))
}

fn median(v: &mut [f64]) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(|a, b| a.total_cmp(b));
    v[v.len() / 2]
}

fn overall(t: &BTreeMap<Option<u32>, Stats>) -> Stats {
    t.get(&None).cloned().unwrap_or_default()
}

fn split_rods(t: &BTreeMap<Option<u32>, Stats>) -> BTreeMap<u32, Stats> {
    t.iter()
        .filter_map(|(k, s)| k.map(|r| (r, s.clone())))
        .collect()
}

/// Runs one scenario: simulate, calibrate, track in both modes, filter and fuse, score.
fn run_scenario(
    plan: &Plan,
    seed: u64,
    keep_rows: bool,
    progress: &std::sync::Arc<Progress>,
    cache: &CalibCache,
) -> Result<ScenarioResult> {
    let t0 = Instant::now();
    let mut sim = rodtrack_sim::build_simulation(&plan.name, plan.frames, seed, false, "default")?;
    let sim_s = t0.elapsed().as_secs_f64();
    let ncam = sim.cameras().len();
    // Same lighting, same reference frame, same calibration.
    let key = format!("{:?}", sim.scenario().lighting);
    let cell = cache
        .lock()
        .map_err(|_| anyhow!("calibration cache poisoned"))?
        .entry(key)
        .or_default()
        .clone();
    let (cals, warnings) = cell
        .get_or_init(|| calibrate_all(&mut sim, seed).map_err(|e| format!("{e:#}")))
        .clone()
        .map_err(|e| anyhow!("scenario {}: calibration: {e}", plan.name))?;
    let setup_s = t0.elapsed().as_secs_f64();
    if std::env::var_os("RODTRACK_DEBUG").is_some() {
        eprintln!(
            "\n{}: simulator {sim_s:.1} s, calibration {:.1} s",
            plan.name,
            setup_s - sim_s
        );
    }
    let n = sim.frame_count();
    let indices: Vec<usize> = (0..n).step_by(plan.stride.max(1)).collect();
    progress.update(&plan.name, 0, indices.len(), SETUP_UNITS);

    // The simulated cameras through a session (enhanced mode, filter, fusion), the paper's
    // algorithm on the same frames alongside.
    let t1 = Instant::now();
    let total = indices.len();
    let name = plan.name.clone();
    let stride = plan.stride.max(1);
    let shared = progress.clone();
    let mut reported = 0;
    let on_rows: crate::sim_run::RowsCallback = Box::new(move |written, _| {
        // Frame sets written so far, from the fused (or, with one camera, the camera) rows.
        let Some(last) = written.iter().map(|m| m.frame).max() else {
            return;
        };
        let fused = written.iter().any(|m| m.camera == CameraId::Fused);
        if (ncam > 1) != fused {
            return;
        }
        let k = last as usize / stride + 1;
        if k >= reported + 20 || k == total {
            shared.update(&name, k, total, k.saturating_sub(reported));
            reported = k;
        }
    });
    let (got, report) = crate::sim_run::run_sim(
        &cals,
        crate::sim_run::SimRun {
            sim: &sim,
            every: plan.stride.max(1),
            paper: true,
            console: None,
            on_rows: Some(on_rows),
        },
    )?;
    let mut rows = ScenarioRows::default();
    for &f in &indices {
        for c in 0..ncam {
            for t in sim.truth(f, c)? {
                rows.truth.push((t.m, Some(t.visible)));
            }
        }
    }
    let with_none = |v: &[Measurement]| -> Rows { v.iter().map(|m| (*m, None)).collect() };
    rows.modes = [
        with_none(&got.paper),
        with_none(&got.raw),
        with_none(&got.filtered),
        with_none(&got.fused),
    ];
    // The trackers' medians per camera frame: rodtrack's from the session's report.
    let mut enh_us: Vec<f64> = report
        .tracker
        .iter()
        .map(|t| t.p50.as_secs_f64() * 1e6)
        .collect();
    let mut pap_us = got.paper_us;
    let loop_s = t1.elapsed().as_secs_f64();

    let mut overall_stats = Vec::new();
    let mut per_rod = Vec::new();
    for m in &rows.modes {
        let t = score(&rows.truth, m);
        overall_stats.push(overall(&t));
        per_rod.push(split_rods(&t));
    }
    // Top speed: rows turning at 90 % of the top angular speed or more.
    let top = rows
        .truth
        .iter()
        .map(|(m, _)| m.angular_velocity_rad_s.abs())
        .fold(0.0f64, f64::max);
    let at_top_speed = if plan.name.starts_with("spin") && top > 1.0 {
        let fast: Rows = rows
            .truth
            .iter()
            .filter(|(m, _)| m.angular_velocity_rad_s.abs() >= 0.9 * top)
            .copied()
            .collect();
        Some((
            top,
            rows.modes
                .iter()
                .map(|m| overall(&score(&fast, m)))
                .collect(),
        ))
    } else {
        None
    };
    Ok(ScenarioResult {
        plan: plan.clone(),
        frames_processed: indices.len(),
        cameras: ncam,
        overall: overall_stats,
        per_rod,
        at_top_speed,
        median_us: (median(&mut enh_us), median(&mut pap_us)),
        setup_s,
        loop_s,
        warnings,
        rows: keep_rows.then(|| Box::new(rows)),
    })
}

/// Scenarios whose rows feed a plot.
const PLOTTED: [&str; 4] = ["exp1", "exp2", "exp3", "gameplay"];

/// Runs the plans (`jobs` at once) and returns results in plan order.
pub fn run_plans(
    plans: &[Plan],
    seed: u64,
    jobs: usize,
    show_progress: bool,
) -> Result<Vec<ScenarioResult>> {
    let total: usize = plans
        .iter()
        .map(|p| {
            SETUP_UNITS
                + p.frames
                    .unwrap_or_else(|| full_frames(&p.name, seed))
                    .div_ceil(p.stride.max(1))
        })
        .sum();
    let progress = std::sync::Arc::new(Progress {
        done: AtomicUsize::new(0),
        total,
        start: Instant::now(),
        current: Mutex::new(BTreeMap::new()),
        last: Mutex::new(Instant::now()),
        enabled: show_progress,
    });
    let next = AtomicUsize::new(0);
    let cache: CalibCache = Mutex::new(BTreeMap::new());
    let results: Mutex<Vec<Option<Result<ScenarioResult>>>> =
        Mutex::new((0..plans.len()).map(|_| None).collect());
    std::thread::scope(|s| {
        for _ in 0..jobs.clamp(1, plans.len().max(1)) {
            s.spawn(|| loop {
                let i = next.fetch_add(1, Ordering::Relaxed);
                let Some(plan) = plans.get(i) else { break };
                let keep = PLOTTED.contains(&plan.name.as_str());
                let r = run_scenario(plan, seed, keep, &progress, &cache);
                if let Ok(mut v) = results.lock() {
                    v[i] = Some(r);
                }
            });
        }
    });
    progress.draw(true);
    if show_progress {
        eprintln!();
    }
    let results = results
        .into_inner()
        .map_err(|_| anyhow!("a scenario thread panicked"))?;
    results
        .into_iter()
        .zip(plans)
        .map(|(r, p)| r.unwrap_or_else(|| Err(anyhow!("scenario {} did not run", p.name))))
        .collect()
}

/// Frames of a scenario's whole timeline.
fn full_frames(name: &str, seed: u64) -> usize {
    let scene = rodtrack_sim::SceneConfig::default();
    rodtrack_sim::Scenario::by_name(name, &scene, seed).map_or(0, |s| s.frame_count())
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

/// Facts about the run for the report.
pub struct ReportInfo {
    /// The command line.
    pub command: String,
    /// Seed.
    pub seed: u64,
    /// Frame scale.
    pub scale: f64,
    /// Parallel jobs.
    pub jobs: usize,
    /// Seconds for the runs.
    pub run_s: f64,
}

/// What [`write_report`] wrote.
pub struct Written {
    /// The headline table as text.
    pub headline: String,
    /// Plot stems written (each as `.png` and `.svg`).
    pub plots: Vec<String>,
}

/// The machine: CPU model and count.
pub fn machine() -> String {
    let model = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|t| {
            t.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split(':').nth(1))
                .map(|s| s.trim().to_string())
        })
        .unwrap_or_else(|| "unknown CPU".to_string());
    let n = std::thread::available_parallelism().map_or(1, |n| n.get());
    format!(
        "{model}, {n} CPUs ({} {})",
        std::env::consts::OS,
        std::env::consts::ARCH
    )
}

fn find<'a>(results: &'a [ScenarioResult], name: &str) -> Option<&'a ScenarioResult> {
    results.iter().find(|r| r.plan.name == name)
}

fn stat_row(s: &Stats) -> String {
    format!(
        "| {} | {:.3} | {:.3} | {:.3} | {:.4} | {:.4} | {:.4} | {} | {:.1} % | {} | {} |",
        s.n,
        s.pos_mean_mm,
        s.pos_std_mm,
        s.pos_max_mm,
        s.ang_mean_rad,
        s.ang_std_rad,
        s.ang_max_rad,
        s.gross,
        100.0 * s.coverage,
        s.false_ok,
        s.wrong_ok
    )
}

/// The columns of [`stat_row`].
const STAT_COLUMNS: [&str; 11] = [
    "rows ok",
    "pos mean mm",
    "pos std mm",
    "pos max mm",
    "ang mean rad",
    "ang std rad",
    "ang max rad",
    "gross",
    "coverage",
    "false ok",
    "wrong ok",
];

/// The header of a Markdown table of statistics: the columns `keys` (name, alignment) that
/// name the row, then [`STAT_COLUMNS`], right-aligned.
fn stat_header(keys: &[(&str, &str)]) -> String {
    let names: Vec<&str> = keys.iter().map(|k| k.0).chain(STAT_COLUMNS).collect();
    let aligns: Vec<&str> = keys
        .iter()
        .map(|k| k.1)
        .chain(STAT_COLUMNS.map(|_| "---:"))
        .collect();
    format!("| {} |\n|{}|\n", names.join(" | "), aligns.join("|"))
}

/// A table of statistics with one row per mode, in [`MODES`] order.
fn push_mode_table(md: &mut String, stats: &[Stats]) {
    md.push_str(&stat_header(&[("mode", "---")]));
    for (name, s) in MODES.iter().zip(stats) {
        let _ = writeln!(md, "| {name} {}", stat_row(s));
    }
}

/// "tracked" at top speed: coverage >= 95 % and gross <= 1 % of ok rows.
fn speed_cell(r: &ScenarioResult, mode: usize) -> String {
    let Some((top, stats)) = &r.at_top_speed else {
        return format!("{}: not reached", r.plan.name);
    };
    let s = &stats[mode];
    let gross = s.gross as f64 / s.n.max(1) as f64;
    let ok = s.coverage >= 0.95 && gross <= 0.01;
    format!(
        "{:.0} rad/s ({:.0} rpm): {} ({:.1} % ok, {:.2} % gross, ang std {:.3} rad)",
        top,
        top * 60.0 / TAU,
        if ok { "tracked" } else { "not tracked" },
        100.0 * s.coverage,
        100.0 * gross,
        s.ang_std_rad
    )
}

/// The best rodtrack row of a scenario: fused with several cameras, else filtered.
fn best_mode(r: &ScenarioResult) -> usize {
    if r.cameras > 1 {
        3
    } else {
        2
    }
}

/// `f(s)` with its unit, or a note when no row was scored.
fn val(s: &Stats, f: impl Fn(&Stats) -> f64, digits: usize, unit: &str) -> String {
    if s.n == 0 {
        "no row ok".to_string()
    } else {
        format!("{:.*} {unit}", digits, f(s))
    }
}

fn headline(results: &[ScenarioResult]) -> String {
    let mut t = String::new();
    t.push_str("| quantity (SPEC section 7) | paper (published) | paper mode on our simulator | rodtrack |\n|---|---|---|---|\n");
    let na = "not run".to_string();
    // Translation std, static.
    let (p, e) = find(results, "static").map_or((na.clone(), na.clone()), |r| {
        let pos = |s: &Stats| s.pos_std_mm;
        (
            val(&r.overall[0], pos, 3, "mm"),
            format!(
                "{} fused ({} raw per camera)",
                val(&r.overall[best_mode(r)], pos, 3, "mm"),
                val(&r.overall[1], pos, 3, "mm")
            ),
        )
    });
    let _ = writeln!(t, "| translation error std, static rods (`static`) | 0.5 mm (resolution 0.6-0.9 mm) | {p} | {e} |");
    let (p, e, pb, eb) =
        find(results, "exp2").map_or((na.clone(), na.clone(), na.clone(), na.clone()), |r| {
            let b = best_mode(r);
            let std = |s: &Stats| s.ang_std_rad;
            let max = |s: &Stats| s.ang_max_rad;
            (
                val(&r.overall[0], std, 4, "rad"),
                format!(
                    "{} fused ({} raw per camera)",
                    val(&r.overall[b], std, 4, "rad"),
                    val(&r.overall[1], std, 4, "rad")
                ),
                format!("+/-{} (largest error)", val(&r.overall[0], max, 3, "rad")),
                format!(
                    "+/-{} fused, +/-{} raw (largest error)",
                    val(&r.overall[b], max, 3, "rad"),
                    val(&r.overall[1], max, 3, "rad")
                ),
            )
        });
    let _ = writeln!(
        t,
        "| angle error std, turning at 1.2 rad/s (`exp2`) | 0.013 rad | {p} | {e} |"
    );
    let _ = writeln!(t, "| angle error bound (`exp2`) | +/-0.03 rad after removing the 25 ms motion-system delay (the simulator has none) | {pb} | {eb} |");
    let mut ps = Vec::new();
    let mut es = Vec::new();
    for name in ["spin600", "spin3000"] {
        if let Some(r) = find(results, name) {
            ps.push(speed_cell(r, 0));
            es.push(format!("{} (fused)", speed_cell(r, best_mode(r))));
        }
    }
    let join = |v: Vec<String>| {
        if v.is_empty() {
            na.clone()
        } else {
            v.join("; ")
        }
    };
    let _ = writeln!(
        t,
        "| rotation speed tracked (`spin600`, `spin3000`) | 60 rad/s (about 600 rpm) | {} | {} |",
        join(ps),
        join(es)
    );
    let mut pt: Vec<f64> = results
        .iter()
        .map(|r| r.median_us.1)
        .filter(|v| *v > 0.0)
        .collect();
    let mut et: Vec<f64> = results
        .iter()
        .map(|r| r.median_us.0)
        .filter(|v| *v > 0.0)
        .collect();
    let _ = writeln!(
        t,
        "| processing time per camera frame, 7 rods | within 5 ms (200 fps, C++, desktop PC) | {:.0} us (median over scenarios of per-scenario medians) | {:.0} us (same) |",
        median(&mut pt),
        median(&mut et)
    );
    let _ = writeln!(t, "| full-frame OpenCV undistort + warp (avoided) | about 20 ms per frame | not used | not used; see BENCHMARKS.md for OpenCV on this machine |");
    let _ = writeln!(t, "| measurement delay | 1 frame or less | 0 frames: the row for frame n uses frame n only | 0 frames: the filter predicts nothing ahead and adds no delay |");
    t
}

/// Aligns a measured unwrapped angle on the truth's turn count at its first row (the turn
/// count is relative to where tracking started).
fn align_turns(meas: &mut [(f64, f64)], truth: &[(f64, f64)]) {
    let Some(&(t0, a0)) = meas.iter().find(|p| p.1.is_finite()) else {
        return;
    };
    let Some(&(_, b0)) = truth
        .iter()
        .min_by(|a, b| (a.0 - t0).abs().total_cmp(&(b.0 - t0).abs()))
    else {
        return;
    };
    let k = ((b0 - a0) / TAU).round() * TAU;
    for p in meas.iter_mut() {
        p.1 += k;
    }
}

/// Time series of one rod: `value(m)` for rows of `camera`, NaN where not ok.
fn series_of(
    rows: &Rows,
    rod: u32,
    camera: CameraId,
    value: impl Fn(&Measurement) -> f64,
) -> Vec<(f64, f64)> {
    let mut v: Vec<(f64, f64)> = rows
        .iter()
        .filter(|(m, _)| m.rod == rod && m.camera == camera)
        .map(|(m, _)| {
            let y = if m.status == Status::Ok {
                value(m)
            } else {
                f64::NAN
            };
            (m.timestamp_s, y)
        })
        .collect();
    v.sort_by(|a, b| a.0.total_cmp(&b.0));
    v
}

/// Truth of one rod (first camera that has it), one point per frame.
fn truth_of(rows: &Rows, rod: u32, value: impl Fn(&Measurement) -> f64) -> Vec<(f64, f64)> {
    let mut seen = std::collections::HashSet::new();
    let mut v: Vec<(f64, f64)> = rows
        .iter()
        .filter(|(m, _)| m.rod == rod && seen.insert(m.frame))
        .map(|(m, _)| (m.timestamp_s, value(m)))
        .collect();
    v.sort_by(|a, b| a.0.total_cmp(&b.0));
    v
}

/// Angle error of one rod over time (wrapped), NaN where not ok.
fn angle_error_of(rows: &Rows, truth: &Rows, rod: u32, camera: CameraId) -> Vec<(f64, f64)> {
    let t: std::collections::HashMap<u64, f64> = truth
        .iter()
        .filter(|(m, _)| m.rod == rod)
        .map(|(m, _)| (m.frame, m.angle_rad))
        .collect();
    let mut v: Vec<(f64, f64)> = rows
        .iter()
        .filter(|(m, _)| m.rod == rod && m.camera == camera)
        .map(|(m, _)| {
            let y = match (m.status, t.get(&m.frame)) {
                (Status::Ok, Some(a)) => wrap_angle(m.angle_rad - a),
                _ => f64::NAN,
            };
            (m.timestamp_s, y)
        })
        .collect();
    v.sort_by(|a, b| a.0.total_cmp(&b.0));
    v
}

/// The rod plotted for the experiments: rod 1 (two figures, 350 mm travel), seen by both
/// cameras.
const PLOT_ROD: u32 = 1;
const TRUTH_COLOUR: RGBColor = RGBColor(0, 0, 0);
const PAPER_COLOUR: RGBColor = RGBColor(213, 94, 0);
const OURS_COLOUR: RGBColor = RGBColor(0, 114, 178);

/// rodtrack's best rows and their camera: fused and filtered with several cameras, else
/// camera 0's filtered rows.
fn ours(rows: &ScenarioRows, fused: bool) -> (&Rows, CameraId) {
    if fused {
        (&rows.modes[3], CameraId::Fused)
    } else {
        (&rows.modes[2], CameraId::Camera(0))
    }
}

/// Truth, paper mode and rodtrack of [`PLOT_ROD`] over time.
fn three(
    rows: &ScenarioRows,
    fused: bool,
    value: impl Fn(&Measurement) -> f64 + Copy,
    unwrap: bool,
) -> Vec<Series> {
    let truth = truth_of(&rows.truth, PLOT_ROD, value);
    let (ours_rows, ours_cam) = ours(rows, fused);
    let mut paper = series_of(&rows.modes[0], PLOT_ROD, CameraId::Camera(0), value);
    let mut ours = series_of(ours_rows, PLOT_ROD, ours_cam, value);
    if unwrap {
        align_turns(&mut paper, &truth);
        align_turns(&mut ours, &truth);
    }
    vec![
        Series {
            label: "commanded (truth)".into(),
            colour: TRUTH_COLOUR,
            line: Line::Solid(3),
            points: truth,
        },
        Series {
            label: "paper mode (camera 0, raw)".into(),
            colour: PAPER_COLOUR,
            line: Line::Solid(1),
            points: paper,
        },
        Series {
            label: if fused {
                "rodtrack (fused + filtered)".into()
            } else {
                "rodtrack (filtered)".into()
            },
            colour: OURS_COLOUR,
            line: Line::Solid(1),
            points: ours,
        },
    ]
}

/// Start and end times of the truth's moves (speed above `v`).
fn moves(truth: &Rows, rod: u32, v: f64) -> Vec<(f64, f64)> {
    let tr = truth_of(truth, rod, |m| m.velocity_mm_s);
    let mut out = Vec::new();
    let mut start = None;
    for (t, s) in tr {
        match (start, s.abs() > v) {
            (None, true) => start = Some(t),
            (Some(t0), false) => {
                out.push((t0, t));
                start = None;
            }
            _ => {}
        }
    }
    out
}

fn plots(out: &Path, results: &[ScenarioResult]) -> Result<Vec<(String, String)>> {
    let mut written = Vec::new();
    let mut emit = |fig: &Figure, stem: &str, caption: String| -> Result<()> {
        write_figure(fig, out, stem)?;
        written.push((stem.to_string(), caption));
        Ok(())
    };
    let rows_of =
        |name: &str| find(results, name).and_then(|r| r.rows.as_deref().map(|rows| (r, rows)));
    if let Some((r, rows)) = rows_of("exp1") {
        let fused = r.cameras > 1;
        let pos = |m: &Measurement| m.position_mm;
        let series = three(rows, fused, pos, false);
        let t_end = series[0].points.last().map_or(1.0, |p| p.0);
        // The zoom: the end of the third step and the hold after it, a few mm high, where the
        // measurement noise and offsets show (the paper's figure 13 zooms the same way).
        let (zoom, what, y_range) = match moves(&rows.truth, PLOT_ROD, 1.0).get(2) {
            Some(&(_, t1)) => {
                let target = series[0]
                    .points
                    .iter()
                    .find(|p| p.0 >= t1)
                    .map_or(0.0, |p| p.1);
                (
                    (t1 - 0.1, t1 + 0.7),
                    "the end of the third step".to_string(),
                    Some((target - 2.0, target + 2.0)),
                )
            }
            None => (
                (0.4 * t_end, 0.6 * t_end),
                "the middle of the run".to_string(),
                None,
            ),
        };
        let fig = Figure {
            size: (1200, 900),
            panels: vec![
                Panel {
                    title: format!(
                        "exp1: 7 linear steps, rod {PLOT_ROD}: commanded and measured position"
                    ),
                    x_label: "time (s)".into(),
                    y_label: "position (mm)".into(),
                    series: series.clone(),
                    ..Panel::default()
                },
                Panel {
                    title: format!("zoom on {what} ({:.2} s to {:.2} s)", zoom.0, zoom.1),
                    x_label: "time (s)".into(),
                    y_label: "position (mm)".into(),
                    x_range: Some(zoom),
                    y_range,
                    series,
                },
            ],
        };
        emit(
            &fig,
            "fig13_exp1_position",
            format!("Experiment 1 (paper figure 13): rod {PLOT_ROD}'s position over time, commanded (black, thick), the paper's algorithm on camera 0 (orange) and rodtrack fused and filtered (blue); below, a zoom on the end of the third step and the hold after it, 4 mm high (on the middle of the run when it is too short). {}", stride_note(r)),
        )?;
    }
    if let Some((r, rows)) = rows_of("exp2") {
        let fused = r.cameras > 1;
        let top = three(rows, fused, |m| m.angle_unwrapped_rad, true);
        let (ours_rows, ours_cam) = ours(rows, fused);
        let fig = Figure {
            size: (1200, 900),
            panels: vec![
                Panel {
                    title: format!(
                        "exp2: 5 turns and back at 1.2 rad/s, rod {PLOT_ROD}: unwrapped angle"
                    ),
                    x_label: "time (s)".into(),
                    y_label: "angle (rad)".into(),
                    series: top,
                    ..Panel::default()
                },
                Panel {
                    title: "angle error (measured - truth)".into(),
                    x_label: "time (s)".into(),
                    y_label: "error (rad)".into(),
                    y_range: Some((-0.08, 0.08)),
                    series: vec![
                        Series {
                            label: "paper mode (camera 0, raw)".into(),
                            colour: PAPER_COLOUR,
                            line: Line::Dots(1),
                            points: angle_error_of(
                                &rows.modes[0],
                                &rows.truth,
                                PLOT_ROD,
                                CameraId::Camera(0),
                            ),
                        },
                        Series {
                            label: "rodtrack".into(),
                            colour: OURS_COLOUR,
                            line: Line::Dots(1),
                            points: angle_error_of(ours_rows, &rows.truth, PLOT_ROD, ours_cam),
                        },
                        Series {
                            label: "paper's bound +/-0.03 rad".into(),
                            colour: PALETTE[7],
                            line: Line::Solid(1),
                            points: bound_lines(&rows.truth, 0.03),
                        },
                    ],
                    ..Panel::default()
                },
            ],
        };
        emit(
            &fig,
            "fig14_exp2_angle",
            format!("Experiment 2 (paper figure 14): rod {PLOT_ROD}'s unwrapped angle over time (commanded black, paper mode orange, rodtrack blue) and the angle error of each (dots; grey lines: the paper's +/-0.03 rad bound; errors beyond +/-0.08 rad are clipped to the frame). {}", stride_note(r)),
        )?;
    }
    if let Some((r, rows)) = rows_of("exp3") {
        let fused = r.cameras > 1;
        let fig = Figure {
            size: (1200, 900),
            panels: vec![
                Panel {
                    title: format!("exp3: 17 steps, each with a turn to 2 pi and back, rod {PLOT_ROD}: position"),
                    x_label: "time (s)".into(),
                    y_label: "position (mm)".into(),
                    series: three(rows, fused, |m| m.position_mm, false),
                    ..Panel::default()
                },
                Panel {
                    title: "unwrapped angle".into(),
                    x_label: "time (s)".into(),
                    y_label: "angle (rad)".into(),
                    series: three(rows, fused, |m| m.angle_unwrapped_rad, true),
                    ..Panel::default()
                },
            ],
        };
        emit(
            &fig,
            "fig15_exp3_position_angle",
            format!("Experiment 3 (paper figure 15): rod {PLOT_ROD}'s position (top) and unwrapped angle (bottom) over time; commanded black, paper mode orange, rodtrack blue. {}", stride_note(r)),
        )?;
    }
    if let Some((r, rows)) = rows_of("gameplay") {
        let fused = r.cameras > 1;
        let (ours_rows, ours_cam) = ours(rows, fused);
        let rods: std::collections::BTreeSet<u32> = rows.truth.iter().map(|(m, _)| m.rod).collect();
        let mut pos = Vec::new();
        let mut ang = Vec::new();
        for &rod in &rods {
            let colour = PALETTE[rod as usize % PALETTE.len()];
            let grey = RGBColor(205, 205, 205);
            let label = |s: &str| {
                if rod == 0 {
                    s.to_string()
                } else {
                    String::new()
                }
            };
            pos.push(Series {
                label: label("truth"),
                colour: grey,
                line: Line::Solid(4),
                points: truth_of(&rows.truth, rod, |m| m.position_mm),
            });
            let ta = truth_of(&rows.truth, rod, |m| m.angle_unwrapped_rad);
            let mut a = series_of(ours_rows, rod, ours_cam, |m| m.angle_unwrapped_rad);
            align_turns(&mut a, &ta);
            ang.push(Series {
                label: label("truth"),
                colour: grey,
                line: Line::Solid(4),
                points: ta,
            });
            pos.push(Series {
                label: format!("rod {rod}"),
                colour,
                line: Line::Solid(1),
                points: series_of(ours_rows, rod, ours_cam, |m| m.position_mm),
            });
            ang.push(Series {
                label: format!("rod {rod}"),
                colour,
                line: Line::Solid(1),
                points: a,
            });
        }
        let fig = Figure {
            size: (1400, 1000),
            panels: vec![
                Panel {
                    title: "gameplay with hands over the table: every rod's position (rodtrack)"
                        .into(),
                    x_label: "time (s)".into(),
                    y_label: "position (mm)".into(),
                    series: pos,
                    ..Panel::default()
                },
                Panel {
                    title: "every rod's unwrapped angle (rodtrack)".into(),
                    x_label: "time (s)".into(),
                    y_label: "angle (rad)".into(),
                    series: ang,
                    ..Panel::default()
                },
            ],
        };
        emit(
            &fig,
            "fig16_gameplay_traces",
            format!("Gameplay (paper figure 16): every rod's position (top) and unwrapped angle (bottom) as rodtrack measures them (fused and filtered; one colour per rod: rod 0 blue, 1 vermilion, 2 green, 3 pink, 4 orange, 5 sky blue, 6 black, 7 grey), over the truth (thick light grey). Gaps: the rod was not reported ok (hands, out of view). {}", stride_note(r)),
        )?;
    }
    Ok(written)
}

fn bound_lines(truth: &Rows, b: f64) -> Vec<(f64, f64)> {
    let t0 = truth
        .iter()
        .map(|(m, _)| m.timestamp_s)
        .fold(f64::INFINITY, f64::min);
    let t1 = truth
        .iter()
        .map(|(m, _)| m.timestamp_s)
        .fold(f64::NEG_INFINITY, f64::max);
    vec![(t0, b), (t1, b), (f64::NAN, f64::NAN), (t0, -b), (t1, -b)]
}

fn stride_note(r: &ScenarioResult) -> String {
    if r.plan.stride > 1 {
        format!(
            "One frame in {} of the 200 fps timeline was processed (the camera at {:.0} fps).",
            r.plan.stride,
            200.0 / r.plan.stride as f64
        )
    } else {
        format!("{} frames at 200 fps.", r.frames_processed)
    }
}

/// Writes `report.md`, `summary.json` and the plots into `out`.
pub fn write_report(out: &Path, results: &[ScenarioResult], info: &ReportInfo) -> Result<Written> {
    let plots = plots(out, results)?;
    let head = headline(results);
    let mut md = String::new();
    let _ = writeln!(md, "# rodtrack evaluation on the simulator\n");
    let _ = writeln!(
        md,
        "Made by `{}` (seed {}, frame scale {}, {} scenarios at once) in {:.0} s on {}.\n",
        info.command,
        info.seed,
        info.scale,
        info.jobs,
        info.run_s,
        machine()
    );
    let _ = writeln!(md, "Every scenario of the built-in simulator (two 1440x1080 Bayer cameras over the 8-rod table) is rendered, each camera is calibrated from simulated clicks (about 1 px error) and a reference frame, exactly as `rodtrack calibrate` would (once per lighting of the table: the `lighting` scenario gets its own calibration, the others share one), and every frame is measured by the paper's algorithm (`paper` mode) and by rodtrack's (`enhanced` mode) on the same pixels. Errors are against the simulator's ground truth; rows count only where the marker is wholly visible (see the column notes at the end).\n");
    let _ = writeln!(md, "## Headline: the paper (published) vs the paper's algorithm on our simulator vs rodtrack\n");
    md.push_str(&head);
    md.push_str("\nrodtrack's figure is the cameras fused and filtered (one row per rod and frame); the raw per-camera figure is in brackets. Per-frame times here are measured while the simulator renders beside them (and other scenarios run in parallel); the criterion benchmark (`cargo bench -p rodtrack --bench per_frame`) and BENCHMARKS.md give clean numbers.\n");
    let _ = writeln!(md, "\n## Per scenario\n");
    for r in results {
        let _ = writeln!(
            md,
            "### `{}`\n\n{} frame sets x {} cameras processed ({}); setup (simulator tables, calibration unless shared) {:.1} s, frames {:.1} s; median time per camera frame: rodtrack {:.0} us, paper mode {:.0} us.\n",
            r.plan.name,
            r.frames_processed,
            r.cameras,
            match (r.plan.frames, r.plan.stride) {
                (None, 1) => "the whole scenario".to_string(),
                (None, s) => format!("the whole scenario, one frame in {s}"),
                (Some(n), _) => format!("its first {n} frames at 200 fps"),
            },
            r.setup_s,
            r.loop_s,
            r.median_us.0,
            r.median_us.1
        );
        push_mode_table(&mut md, &r.overall);
        if let Some((top, stats)) = &r.at_top_speed {
            let _ = writeln!(md, "\nOnly the rows turning at {:.0} rad/s or faster (90 % of the top speed, {:.0} rad/s):\n", 0.9 * top, top);
            push_mode_table(&mut md, stats);
        }
        // Per rod, the headline modes only.
        let _ = writeln!(
            md,
            "\n<details><summary>per rod: paper mode (raw) and rodtrack (fused)</summary>\n"
        );
        md.push_str(&stat_header(&[("rod", "---:"), ("mode", "---")]));
        let b = best_mode(r);
        let rods: std::collections::BTreeSet<u32> =
            r.per_rod.iter().flat_map(|m| m.keys().copied()).collect();
        for rod in rods {
            for (mi, label) in [(0, "paper"), (b, "rodtrack")] {
                if let Some(s) = r.per_rod[mi].get(&rod) {
                    let _ = writeln!(md, "| {rod} | {label} {}", stat_row(s));
                }
            }
        }
        md.push_str("\n</details>\n\n");
        if !r.warnings.is_empty() {
            let _ = writeln!(md, "Calibration warnings: {}.\n", r.warnings.join("; "));
        }
    }
    if !plots.is_empty() {
        let _ = writeln!(md, "## Plots (in the style of the paper's figures 13-16)\n");
        for (stem, caption) in &plots {
            let _ = writeln!(
                md,
                "![{stem}]({stem}.png)\n\n{caption} ([SVG]({stem}.svg))\n"
            );
        }
    }
    md.push_str("## Columns\n\n- **rows ok**: rows reported `ok` on a visible marker (the rows scored).\n- **pos / ang mean, std, max**: error against ground truth (angle wrapped to +/-pi), mm and rad.\n- **gross**: rows off by a Gray step (2 pi / 32) or more in angle, or 5 mm or more in position.\n- **coverage**: share of visible markers reported `ok` (fused rows: per rod and frame seen by any camera).\n- **false ok**: reported `ok` while the marker is not wholly visible; **wrong ok**: those off by more than 0.2 rad or 5 mm (confident wrong values).\n- **paper mode, each camera (raw)**: the paper's algorithm as published, no temporal filter. **rodtrack, each camera (raw)**: enhanced mode before the filter. **filtered**: each camera through rodtrack's temporal filter. **fused + filtered**: both cameras fused, one row per rod.\n");
    std::fs::write(out.join("report.md"), &md)
        .with_context(|| format!("writing {}", out.join("report.md").display()))?;
    let summary = serde_json::json!({
        "modes": MODES,
        "seed": info.seed,
        "frame_scale": info.scale,
        "run_s": info.run_s,
        "machine": machine(),
        "scenarios": results,
    });
    std::fs::write(
        out.join("summary.json"),
        serde_json::to_string_pretty(&summary)?,
    )
    .with_context(|| format!("writing {}", out.join("summary.json").display()))?;
    Ok(Written {
        headline: head,
        plots: plots.into_iter().map(|(s, _)| s).collect(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plans_scale() {
        assert_eq!(plan_for("exp2", 1.0, 11000).stride, 8);
        assert_eq!(plan_for("exp2", 2.0, 11000).stride, 4);
        assert_eq!(plan_for("exp2", 1.0, 11000).frames, None);
        let q = plan_for("exp2", 0.1, 11000);
        assert_eq!((q.frames, q.stride), (Some(1100), 8));
        assert_eq!(plan_for("gameplay", 0.1, 6000).frames, Some(120));
        assert_eq!(plan_for("gameplay", 10.0, 6000).frames, Some(6000));
        assert_eq!(plan_for("static", 1e-6, 1000).frames, Some(4));
    }

    #[test]
    fn tiny_run_writes_the_report_and_plots() {
        let dir = std::env::temp_dir().join(format!("rodtrack-eval-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let plans = vec![
            Plan {
                name: "exp1".into(),
                frames: Some(8),
                stride: 1,
            },
            Plan {
                name: "static".into(),
                frames: Some(4),
                stride: 1,
            },
        ];
        let results = run_plans(&plans, 7, 2, false).unwrap();
        assert_eq!(results.len(), 2);
        assert_eq!(results[0].frames_processed, 8);
        let info = ReportInfo {
            command: "test".into(),
            seed: 7,
            scale: 1.0,
            jobs: 2,
            run_s: 0.0,
        };
        let w = write_report(&dir, &results, &info).unwrap();
        assert_eq!(w.plots, vec!["fig13_exp1_position".to_string()]);
        let md = std::fs::read_to_string(dir.join("report.md")).unwrap();
        assert!(md.contains("### `exp1`") && md.contains("### `static`"));
        assert!(md.contains("| translation error std"));
        for ext in ["png", "svg"] {
            let p = dir.join(format!("fig13_exp1_position.{ext}"));
            assert!(
                std::fs::metadata(&p).unwrap().len() > 1000,
                "{}",
                p.display()
            );
        }
        let js: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).unwrap())
                .unwrap();
        assert_eq!(js["scenarios"].as_array().unwrap().len(), 2);
        // The static rods are measured: rodtrack reports most of them ok.
        assert!(results[1].overall[1].n > 0);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
