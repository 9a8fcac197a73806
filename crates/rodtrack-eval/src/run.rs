//! The scenarios run: simulate, calibrate (once per lighting of the table), track in both
//! modes, filter and fuse, score against the truth.

use crate::plan::{full_frames, Plan};
use crate::progress::Progress;
use crate::score::{score, Stats};
use crate::{error_chain, sim_run, EvalError, Result};
use rodtrack_core::calib::CameraCalibration;
use rodtrack_core::{CameraId, FrameView, Measurement};
use std::collections::BTreeMap;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Instant;

/// Rows of one way of measuring, with the `Option<bool>` that `score` takes.
pub type Rows = Vec<(Measurement, Option<bool>)>;

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
                h.join().unwrap_or_else(|_| {
                    Err(EvalError::Failed("a calibration thread panicked".into()))
                })
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

/// The median of `v` (sorted in place; 0 when empty).
pub(crate) fn median(v: &mut [f64]) -> f64 {
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
    progress: &Arc<Progress>,
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
        .map_err(|_| EvalError::Failed("calibration cache poisoned".into()))?
        .entry(key)
        .or_default()
        .clone();
    let (cals, warnings) = cell
        .get_or_init(|| calibrate_all(&mut sim, seed).map_err(|e| error_chain(&e)))
        .clone()
        .map_err(|e| EvalError::Failed(format!("scenario {}: calibration: {e}", plan.name)))?;
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
    let on_rows: sim_run::RowsCallback = Box::new(move |written, _| {
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
    let (got, report) = sim_run::run_sim(
        &cals,
        sim_run::SimRun {
            sim: &sim,
            every: plan.stride.max(1),
            paper: true,
            hooks: None,
            on_rows: Some(on_rows),
            ball: None,
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
    let progress = Arc::new(Progress::new(total, show_progress));
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
        .map_err(|_| EvalError::Failed("a scenario thread panicked".into()))?;
    results
        .into_iter()
        .zip(plans)
        .map(|(r, p)| {
            r.unwrap_or_else(|| {
                Err(EvalError::Failed(format!(
                    "scenario {} did not run",
                    p.name
                )))
            })
        })
        .collect()
}

/// The result of scenario `name`, if it ran.
pub fn find<'a>(results: &'a [ScenarioResult], name: &str) -> Option<&'a ScenarioResult> {
    results.iter().find(|r| r.plan.name == name)
}
