//! The report's figures, in the style of the paper's figures 13-16.

use crate::plots::{write_figure, Figure, Line, Panel, Series, PALETTE};
use crate::run::{find, Rows, ScenarioResult, ScenarioRows};
use crate::score::wrap_angle;
use crate::Result;
use plotters::style::RGBColor;
use rodtrack_core::{CameraId, Measurement, Status};
use std::path::Path;

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
    let k = rodtrack_core::angle::whole_turns(b0 - a0);
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
            (m.timestamp_s(), y)
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
        .map(|(m, _)| (m.timestamp_s(), value(m)))
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
            (m.timestamp_s(), y)
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

/// Draws the figures of the scenarios whose rows were kept (`exp1`, `exp2`, `exp3`,
/// `gameplay`) into `out`, each as PNG and SVG; returns their stems and captions.
pub fn write_figures(out: &Path, results: &[ScenarioResult]) -> Result<Vec<(String, String)>> {
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
        .map(|(m, _)| m.timestamp_s())
        .fold(f64::INFINITY, f64::min);
    let t1 = truth
        .iter()
        .map(|(m, _)| m.timestamp_s())
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
