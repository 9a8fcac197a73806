//! Automatic calibration from a sweep: every rod's marker found in a reference frame (all
//! rods at their reference pose), then followed through frames in which each rod sweeps its
//! travel; its detections become its path points. Pure functions over frame views; reading
//! the frames is the caller's (the SDK's `calibration::auto`).

use super::find::{find_markers, find_markers_in, path_points_from_sweep, FoundMarker};
use super::inputs::{ReferencePose, RodInputs};
use crate::{CoreError, FrameView, Marker, MarkerSpec};

/// Smallest barcode correlation accepted as a marker.
pub const MIN_NCC: f64 = 0.7;
/// Below this correlation a reference marker is doubtful...
pub const DOUBTFUL_NCC: f64 = 0.8;
/// ... and so it is when its barcode edges lie this far (RMS, mm) from their fit (0.01-0.02 mm
/// on a sharp frame)...
pub const DOUBTFUL_EDGE_MM: f64 = 0.1;
/// ... or its Gray code and phase disagree by this many steps (up to 0.5 when they agree).
pub const DOUBTFUL_CODE_PHASE: f64 = 0.75;
/// Detections closer than this along the rod (px) are one path point (a rod at rest).
pub const MERGE_PX: f64 = 1.5;
/// Margin added to a travel measured from the sweep, mm.
pub const TRAVEL_MARGIN_MM: f64 = 2.0;
/// A rod is looked for this far (px) beyond its width around its last line coordinate...
pub const FOLLOW_MARGIN_PX: f64 = 8.0;
/// ... at barcode cells this factor smaller or larger than its last ones...
pub const FOLLOW_SCALE: f64 = 1.15;
/// ... first within this many px (beyond the barcode's length) of its last place along the rod.
pub const FOLLOW_REACH_PX: f64 = 120.0;

/// Across the rod: image x for rods along image rows.
pub fn line_of(f: &FoundMarker, along_rows: bool) -> f64 {
    if along_rows {
        f.x_px
    } else {
        f.y_px
    }
}

/// Along the rod: image y for rods along image rows.
pub fn along_of(f: &FoundMarker, along_rows: bool) -> f64 {
    if along_rows {
        f.y_px
    } else {
        f.x_px
    }
}

/// One rod followed through the sweep.
pub struct RodSweep {
    /// Its id.
    pub id: u32,
    /// Its detection in the reference frame.
    pub reference: FoundMarker,
    /// The last detection going forward and backward in time.
    pub forward: Last,
    /// The last detection going backward in time.
    pub backward: Last,
    /// Every detection, the reference's first.
    pub found: Vec<FoundMarker>,
}

/// The rods of one camera, found in the reference frame.
pub struct Sweep {
    /// The rods lie along image rows (else columns).
    pub along_rows: bool,
    /// The rods, in image order.
    pub rods: Vec<RodSweep>,
    /// Frames analysed.
    pub analysed: usize,
}

impl Sweep {
    /// Finds the markers of the reference frame and names them.
    pub fn from_reference(
        view: &FrameView,
        marker: &Marker,
        ids: Option<&[u32]>,
        camera: &str,
    ) -> Result<Sweep, CoreError> {
        // Rods along image rows (the usual mounting), else along columns.
        let mut along_rows = true;
        let mut found = find_markers(view, marker, true, MIN_NCC);
        if found.is_empty() {
            along_rows = false;
            found = find_markers(view, marker, false, MIN_NCC);
        }
        if found.is_empty() {
            return Err(CoreError::AutoCalibration {
                camera: camera.to_string(),
                reason: "no marker found in the reference frame: are the markers in view, \
                         lit, and of the --marker description?"
                    .into(),
            });
        }
        found.sort_by(|a, b| line_of(a, along_rows).total_cmp(&line_of(b, along_rows)));
        let ids: Vec<u32> = match ids {
            Some(ids) => {
                if ids.len() != found.len() {
                    let at: Vec<String> = found
                        .iter()
                        .map(|f| format!("({:.0}, {:.0})", f.x_px, f.y_px))
                        .collect();
                    return Err(CoreError::AutoCalibration {
                        camera: camera.to_string(),
                        reason: format!(
                            "--rods names {} rod(s) but the reference frame shows {} \
                             marker(s), at {} px",
                            ids.len(),
                            found.len(),
                            at.join(", ")
                        ),
                    });
                }
                ids.to_vec()
            }
            None => (0..found.len() as u32).collect(),
        };
        let rods = found
            .iter()
            .zip(ids)
            .map(|(f, id)| {
                let start = Last {
                    line: line_of(f, along_rows),
                    along: along_of(f, along_rows),
                    cell: f.cell_px,
                };
                RodSweep {
                    id,
                    reference: *f,
                    forward: start,
                    backward: start,
                    found: vec![*f],
                }
            })
            .collect();
        Ok(Sweep {
            along_rows,
            rods,
            analysed: 1,
        })
    }

    /// Looks for every rod near where it was last seen (forward or backward in time).
    pub fn follow(&mut self, view: &FrameView, marker: &Marker, backward: bool) {
        self.analysed += 1;
        let along_rows = self.along_rows;
        for rod in &mut self.rods {
            let last = if backward { rod.backward } else { rod.forward };
            // Near its last detection first (a sweep moves little between analysed frames),
            // then along the whole image.
            let f = follow_rod(
                view,
                marker,
                along_rows,
                rod.reference.direction,
                last,
                true,
            )
            .or_else(|| {
                follow_rod(
                    view,
                    marker,
                    along_rows,
                    rod.reference.direction,
                    last,
                    false,
                )
            });
            if let Some(f) = f {
                let state = Last {
                    line: line_of(&f, along_rows),
                    along: along_of(&f, along_rows),
                    cell: f.cell_px,
                };
                if backward {
                    rod.backward = state;
                } else {
                    rod.forward = state;
                }
                rod.found.push(f);
            }
        }
    }
}

/// Where a rod was last seen.
#[derive(Debug, Clone, Copy)]
pub struct Last {
    /// Line coordinate (image x for rods along rows), px.
    pub line: f64,
    /// Along the rod (image y for rods along rows), px.
    pub along: f64,
    /// Barcode cell, px.
    pub cell: f64,
}

/// Looks for one rod's marker on the few scan lines around its last line coordinate, at scales
/// near its last one: within `FOLLOW_REACH_PX` of its last place along the rod (`near`), or
/// along the whole image. Scans a crop of the frame (the luminance is the same inside it).
fn follow_rod(
    view: &FrameView,
    marker: &Marker,
    along_rows: bool,
    direction: i32,
    last: Last,
    near: bool,
) -> Option<FoundMarker> {
    // The rod's half width plus a margin for its line bending between analysed frames.
    let r_px = marker.radius_mm() * last.cell / marker.cell_mm();
    let half = r_px + FOLLOW_MARGIN_PX;
    // The crop: the scan lines and the silhouette beside them (2 radii out) across the rod;
    // the barcode's length and the reach along it. Even offsets keep a Bayer mosaic's phase.
    let (n_lines, len) = if along_rows {
        (view.width(), view.height())
    } else {
        (view.height(), view.width())
    };
    let even = |v: f64, max: usize| ((v.max(0.0) as usize) & !1).min(max);
    let l0 = even(last.line - half - 2.0 * r_px, n_lines);
    let l1 = ((last.line + half + 2.0 * r_px).ceil() as usize + 1).min(n_lines);
    let (a0, a1) = if near {
        let reach = 16.0 * last.cell + FOLLOW_REACH_PX;
        (
            even(last.along - reach, len),
            ((last.along + reach).ceil() as usize + 1).min(len),
        )
    } else {
        (0, len)
    };
    if l1 < l0 + 4 || a1 < a0 + 4 {
        return None;
    }
    let (x0, y0, w, h) = if along_rows {
        (l0, a0, l1 - l0, a1 - a0)
    } else {
        (a0, l0, a1 - a0, l1 - l0)
    };
    let bpp = view.format().bytes_per_pixel();
    let data = view.data().get(y0 * view.stride() + x0 * bpp..)?;
    let crop = FrameView::new(data, w, h, view.stride(), view.format()).ok()?;
    let lines_lo = (last.line - half).max(0.0) as usize;
    let lines_hi = (last.line + half).ceil() as usize + 1;
    let hits = find_markers_in(
        &crop,
        marker,
        along_rows,
        MIN_NCC,
        lines_lo.saturating_sub(l0)..lines_hi.saturating_sub(l0),
        (last.cell / FOLLOW_SCALE, last.cell * FOLLOW_SCALE),
    );
    hits.into_iter()
        .filter(|f| f.direction == direction)
        .map(|mut f| {
            f.x_px += x0 as f64;
            f.y_px += y0 as f64;
            f
        })
        .map(|f| ((line_of(&f, along_rows) - last.line).abs(), f))
        .filter(|(d, _)| *d <= half)
        .min_by(|a, b| a.0.total_cmp(&b.0))
        .map(|(_, f)| f)
}

/// What the sweep gave for one rod.
pub struct SweptRod {
    /// The rod's calibration inputs.
    pub inputs: RodInputs,
    /// Span of the path points along the rod, px.
    pub span_px: f64,
    /// Travel measured from the detections, mm.
    pub measured_mm: [f64; 2],
    /// Path points.
    pub points: usize,
    /// Too few detections were centred on the rod's silhouette: all were used.
    pub unrefined_used: bool,
}

/// Path points (detections merged where the rod rested) and the travel measured, of one rod:
/// its calibration inputs (the travel `travel` when given, else the one measured with a margin).
pub fn swept_rod(
    rod: &RodSweep,
    along_rows: bool,
    spec: &MarkerSpec,
    marker: &Marker,
    travel: Option<[f64; 2]>,
) -> SweptRod {
    let line = line_of(&rod.reference, along_rows);
    // Path points: the detections centred on the rod's silhouette (the others are +/- 1 px
    // across it), unless too few are.
    let refined: Vec<FoundMarker> = rod.found.iter().filter(|f| f.refined).copied().collect();
    let unrefined_used = refined.len() < 3;
    let use_found = if unrefined_used { &rod.found } else { &refined };
    let sorted = path_points_from_sweep(use_found, line, along_rows, f64::INFINITY);
    let key = |p: &[f64; 2]| if along_rows { p[1] } else { p[0] };
    let mut points: Vec<[f64; 2]> = Vec::new();
    let mut group: Vec<[f64; 2]> = Vec::new();
    // (Rounded to 0.001 px for the saved inputs' sake.)
    let flush = |group: &mut Vec<[f64; 2]>, points: &mut Vec<[f64; 2]>| {
        if !group.is_empty() {
            let n = group.len() as f64;
            let mean = |k: usize| (group.iter().map(|p| p[k]).sum::<f64>() / n * 1e3).round() / 1e3;
            points.push([mean(0), mean(1)]);
            group.clear();
        }
    };
    for p in sorted {
        if group.first().is_some_and(|g| key(&p) - key(g) > MERGE_PX) {
            flush(&mut group, &mut points);
        }
        group.push(p);
    }
    flush(&mut group, &mut points);
    let span_px = match (points.first(), points.last()) {
        (Some(a), Some(b)) => key(b) - key(a),
        _ => 0.0,
    };
    // Position of each detection: its distance from the reference along the rod, over the
    // mean of the two scales (each barcode's cells give the local mm scale).
    let r = &rod.reference;
    let ppm = |f: &FoundMarker| f.cell_px / marker.cell_mm();
    let (mut lo, mut hi) = (0.0f64, 0.0f64);
    for f in &rod.found {
        let d = along_of(f, along_rows) - along_of(r, along_rows);
        let mm = r.direction as f64 * d / (0.5 * (ppm(f) + ppm(r)));
        lo = lo.min(mm);
        hi = hi.max(mm);
    }
    let measured_mm = [lo, hi];
    let travel_mm = travel.unwrap_or([
        (lo - TRAVEL_MARGIN_MM).floor(),
        (hi + TRAVEL_MARGIN_MM).ceil(),
    ]);
    SweptRod {
        inputs: RodInputs {
            rod: rod.id,
            path_points_px: points.clone(),
            travel_mm,
            reference: ReferencePose {
                frame: 0,
                position_mm: 0.0,
                angle_rad: 0.0,
            },
            known_poses: Vec::new(),
            travel_frames: None,
            marker: spec.clone(),
        },
        span_px,
        measured_mm,
        points: points.len(),
        unrefined_used,
    }
}
