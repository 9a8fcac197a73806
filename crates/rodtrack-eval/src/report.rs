//! The Markdown report (`report.md`: headline against the paper, tables per scenario, plots)
//! and `summary.json`.

use crate::figures::write_figures;
use crate::run::{find, median, ScenarioResult, MODES};
use crate::score::Stats;
use crate::{EvalError, Result};
use std::f64::consts::TAU;
use std::fmt::Write as _;
use std::path::Path;

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

/// The headline table (Markdown): the paper's figures, the paper's algorithm on the simulator
/// and rodtrack's, quantity by quantity.
pub fn headline(results: &[ScenarioResult]) -> String {
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

/// Writes `report.md`, `summary.json` and the plots into `out`.
pub fn write_report(out: &Path, results: &[ScenarioResult], info: &ReportInfo) -> Result<Written> {
    let plots = write_figures(out, results)?;
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
    write(&out.join("report.md"), md.as_bytes())?;
    let summary = serde_json::json!({
        "modes": MODES,
        "seed": info.seed,
        "frame_scale": info.scale,
        "run_s": info.run_s,
        "machine": machine(),
        "scenarios": results,
    });
    write(
        &out.join("summary.json"),
        serde_json::to_string_pretty(&summary)?.as_bytes(),
    )?;
    Ok(Written {
        headline: head,
        plots: plots.into_iter().map(|(s, _)| s).collect(),
    })
}

/// Writes `bytes` to `path`.
fn write(path: &Path, bytes: &[u8]) -> Result<()> {
    std::fs::write(path, bytes).map_err(|source| EvalError::Write {
        path: path.to_path_buf(),
        source,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plan::Plan;
    use crate::run::run_plans;

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
