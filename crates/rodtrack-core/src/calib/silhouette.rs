//! The rod's silhouette and centre line at calibration: the marker's rings measured across the
//! rod in each frame where the rod stands at a known pose, and the line through them and the
//! clicked points.

use super::travel::{AlongTravel, RodAxis};
use crate::camera::CameraIntrinsics;
use crate::frame::FrameView;
use crate::line::{CurveModel, Knots, LinePoint};
use crate::marker::Marker;

/// Knot spacing, mm.
pub(super) const KNOT_STEP_MM: f64 = 2.0;
/// Assumed error of a clicked path point, px (the silhouettes are weighted against it).
const CLICK_SIGMA_PX: f64 = 1.0;

/// The axis range the knots cover, mm.
pub(super) struct KnotRange {
    /// First knot.
    pub s0: f64,
    /// Last knot (at most).
    pub s1: f64,
}

/// How the knots' apparent radius is made.
pub(super) enum RadiusModel {
    /// `radius_mm * px per mm along the line * ratio`, carried along the travel as the depth
    /// changes (`1 / (1 + h d)`).
    Measured(f64),
    /// The projection of the cylinder about the rod's 3-D axis through the lens.
    Geometric(CameraIntrinsics, RodAxis),
}

/// The knots of the line every [`KNOT_STEP_MM`] over `range`: centre from `curve` at
/// `along`'s parameter, radius by `radius`.
pub(super) fn make_knots(
    curve: &CurveModel,
    along: &AlongTravel,
    range: &KnotRange,
    marker: &Marker,
    radius: &RadiusModel,
) -> Knots {
    let nk = ((range.s1 - range.s0) / KNOT_STEP_MM).ceil() as usize + 1;
    let mut kx = Vec::with_capacity(nk);
    let mut ky = Vec::with_capacity(nk);
    let mut kr = Vec::with_capacity(nk);
    for i in 0..nk {
        let s = range.s0 + i as f64 * KNOT_STEP_MM;
        let (x, y) = curve.point(along.lambda(s));
        let (x2, y2) = curve.point(along.lambda(s + 0.5));
        let ppm = ((x2 - x).powi(2) + (y2 - y).powi(2)).sqrt() / 0.5;
        let r = match radius {
            RadiusModel::Measured(ratio) => {
                marker.radius_mm() * ppm * ratio * along.depth_ratio(s + 0.25)
            }
            RadiusModel::Geometric(intr, axis) => {
                let t = [(x2 - x) / (0.5 * ppm), (y2 - y) / (0.5 * ppm)];
                axis.half_width_px(intr, s, marker.radius_mm(), [-t[1], t[0]])
                    .unwrap_or(marker.radius_mm() * ppm)
            }
        };
        kx.push(x);
        ky.push(y);
        kr.push(r);
    }
    Knots {
        s0_mm: range.s0,
        step_mm: KNOT_STEP_MM,
        x_px: kx,
        y_px: ky,
        radius_px: kr,
    }
}

/// The barcode's edges near where `lambda_of_u` puts each (marker coordinate `u`): the
/// crossing of the halfway level within half a cell (`half_px`) of it, on the line sampled
/// every `lam_per_px / 40 * 2 half_px`. Returns `(u, lambda)` of each edge found.
pub(super) fn refine_edges(
    frame: &FrameView,
    curve: &CurveModel,
    marker: &Marker,
    dir: i32,
    lambda_of_u: &dyn Fn(f64) -> f64,
    half_px: f64,
    lam_per_px: f64,
) -> Vec<(f64, f64)> {
    let mut edge_pts = Vec::new();
    for (u_e, rising) in marker.barcode_edges_mm() {
        let steps = 40usize;
        let lc = lambda_of_u(u_e);
        let vals: Vec<(f64, f32)> = (0..=steps)
            .map(|i| {
                let off = -half_px + 2.0 * half_px * i as f64 / steps as f64; // px along
                let l = lc + off * lam_per_px;
                let (x, y) = curve.point(l);
                (l, frame.luma_bilinear(x as f32, y as f32))
            })
            .collect();
        let level = 0.5 * (vals[0].1 + vals[steps].1);
        // In +lambda the edge is falling (white to black) when rising==true and dir>0.
        let falling = rising == (dir > 0);
        let sign = if falling { 1.0f32 } else { -1.0 };
        for w in vals.windows(2) {
            let a = (level - w[0].1) * sign;
            let b = (level - w[1].1) * sign;
            if a <= 0.0 && b > 0.0 {
                let f = (a / (a - b)) as f64;
                edge_pts.push((u_e, w[0].0 + f * (w[1].0 - w[0].0)));
                break;
            }
        }
    }
    edge_pts
}

/// How far from the predicted place a known pose's barcode is looked for, mm.
const KNOWN_POSE_SEARCH_MM: f64 = 12.0;

/// The barcode's edges in a frame where the rod stands at `position_mm`: found by correlation
/// within [`KNOWN_POSE_SEARCH_MM`] of where `along` puts it, then refined. Returns `(s,
/// lambda)` of each edge (`s = position + u`), or `None` when no barcode correlates there.
pub(super) fn edges_at_pose(
    frame: &FrameView,
    curve: &CurveModel,
    along: &AlongTravel,
    marker: &Marker,
    dir: i32,
    position_mm: f64,
    lam_per_px: f64,
) -> Option<Vec<(f64, f64)>> {
    // The line sampled every quarter mm of the predicted axis over the barcode and the search.
    let step = 0.25;
    let b0 = marker.barcode_start_mm();
    let blen = marker.barcode_len_mm();
    let from = position_mm + b0 - KNOWN_POSE_SEARCH_MM;
    let n = ((blen + 2.0 * KNOWN_POSE_SEARCH_MM) / step) as usize + 1;
    let mut profile = Vec::with_capacity(n);
    for i in 0..n {
        let (x, y) = curve.point(along.lambda(from + i as f64 * step));
        if !frame.contains(x as f32, y as f32, 2.0) {
            return None;
        }
        profile.push(frame.luma_bilinear(x as f32, y as f32));
    }
    let kernel = marker.kernel();
    let klen = (blen / step).round() as usize;
    let kpx: Vec<f32> = (0..klen)
        .map(|i| {
            let c = (((i as f64 + 0.5) * step / marker.cell_mm()) as usize).min(kernel.len() - 1);
            if kernel[c] {
                0.0
            } else {
                1.0
            }
        })
        .collect();
    let mut corr = vec![0.0f32; n - klen + 1];
    crate::signal::ncc_direct(&kpx, &profile, &mut corr);
    let (best, c) = corr
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.total_cmp(b.1))
        .map(|(i, c)| (i, *c))?;
    if c < 0.6 {
        return None;
    }
    let shift = from + best as f64 * step - (position_mm + b0);
    let ppm = {
        let (x, y) = curve.point(along.lambda(position_mm + b0));
        let (x2, y2) = curve.point(along.lambda(position_mm + b0 + 1.0));
        ((x2 - x).powi(2) + (y2 - y).powi(2)).sqrt()
    };
    let edges = refine_edges(
        frame,
        curve,
        marker,
        dir,
        &|u| along.lambda(position_mm + u + shift),
        0.5 * marker.cell_mm() * ppm,
        lam_per_px,
    );
    Some(
        edges
            .into_iter()
            .map(|(u, l)| (position_mm + u, l))
            .collect(),
    )
}

/// Refines the path's offset and direction by least squares over the marker's ring
/// silhouettes in each `(frame, position)` given and the clicked points (weighted by
/// [`CLICK_SIGMA_PX`]). Returns the refined path and the first frame's silhouette fit (its
/// radius and scatter), `None` when its rings do not stand out.
pub(super) fn refine_centre_line(
    mut curve: CurveModel,
    along: &AlongTravel,
    range: &KnotRange,
    poses: &[(&FrameView, f64)],
    clicks: &[[f64; 2]],
    marker: &Marker,
) -> (CurveModel, Option<SilhouetteFit>) {
    let mut first = None;
    for _ in 0..5 {
        let knots = make_knots(&curve, along, range, marker, &RadiusModel::Measured(1.0));
        let mut fits: Vec<SilhouetteFit> = Vec::new();
        for (k, (frame, s_base)) in poses.iter().enumerate() {
            // Every pose's centre from the rings of the reference's polarity: the two
            // polarities' centres differ by the shading's bias.
            let polarity = fits.first().map(|f| f.white);
            match fit_silhouette(frame, &knots, marker, *s_base, polarity) {
                Some(f) => fits.push(f),
                None if k == 0 => return (curve, first),
                None => {}
            }
        }
        let lam_c = along.lambda(fits[0].s_mean_mm);
        // Observations: lateral offset (px, along the knots' normal) at lambda, and weight.
        let mut obs: Vec<(f64, f64, f64)> = fits
            .iter()
            .flat_map(|fit| {
                fit.rows
                    .iter()
                    .map(move |&(s, c)| (along.lambda(s), c, fit.weight))
            })
            .collect();
        for p in clicks {
            let lam = curve.project(*p);
            let (x, y) = curve.point(lam);
            let lp = knots.at(along.s_of(lam));
            let off = (p[0] - x) * -lp.ty + (p[1] - y) * lp.tx;
            obs.push((lam, off, 1.0 / (CLICK_SIGMA_PX * CLICK_SIGMA_PX)));
        }
        let lam_span = obs
            .iter()
            .map(|o| (o.0 - lam_c).abs())
            .fold(0.0, f64::max)
            .max(1e-9);
        let ha = curve.lambda_per_px(lam_c);
        let hb = ha / lam_span;
        let ca = curve.shifted(ha, 0.0, lam_c);
        let cb = curve.shifted(0.0, hb, lam_c);
        let (mut m00, mut m01, mut m11, mut r0, mut r1) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for &(lam, off, w) in &obs {
            let (x, y) = curve.point(lam);
            let lp = knots.at(along.s_of(lam));
            let (nx, ny) = (-lp.ty, lp.tx);
            let pa = ca.point(lam);
            let pb = cb.point(lam);
            let ga = (pa.0 - x) * nx + (pa.1 - y) * ny;
            let gb = (pb.0 - x) * nx + (pb.1 - y) * ny;
            m00 += w * ga * ga;
            m01 += w * ga * gb;
            m11 += w * gb * gb;
            r0 += w * ga * off;
            r1 += w * gb * off;
        }
        let det = m00 * m11 - m01 * m01;
        if det.is_nan() || det.abs() <= 1e-12 * (m00 * m11).max(1e-300) {
            break;
        }
        let a = (m11 * r0 - m01 * r1) / det;
        let b = (m00 * r1 - m01 * r0) / det;
        curve = curve.shifted(a * ha, b * hb, lam_c);
        first = fits.into_iter().next();
        if a.abs().max(b.abs()) < 0.005 {
            break;
        }
    }
    (curve, first)
}

/// The rod's silhouette along the marker in one frame.
pub(super) struct SilhouetteFit {
    /// `(s, lateral offset)` of every kept row, px along the knots' normal, both polarities
    /// brought to one centre.
    pub rows: Vec<(f64, f64)>,
    /// Least-squares weight of one row (1 / px^2, thinned for rows closer than a pixel).
    pub weight: f64,
    /// Mean `s` of the rows, mm.
    pub s_mean_mm: f64,
    /// RMS of the rows around their line, px.
    pub rms_px: f64,
    /// Apparent radius over the knots' predicted one.
    pub radius_ratio: f64,
    /// True when the centre and radius are the white rings'.
    pub white: bool,
}

/// Rows across the marker's full rings (white: quiet zones, the barcode's white cells, the gap;
/// black: the barcode's black cells), `margin_mm` inside their ends, every `step_mm`: `(u,
/// white)`.
fn ring_rows_all(marker: &Marker, margin_mm: f64, step_mm: f64) -> Vec<(f64, bool)> {
    let mut zones: Vec<(f64, f64, bool)> = Vec::new();
    let bc0 = marker.barcode_start_mm();
    let cell = marker.cell_mm();
    zones.push((0.0, bc0, true));
    let k = marker.kernel();
    let mut i = 0;
    while i < k.len() {
        let j = (i..k.len()).find(|&j| k[j] != k[i]).unwrap_or(k.len());
        zones.push((bc0 + i as f64 * cell, bc0 + j as f64 * cell, !k[i]));
        i = j;
    }
    let gray_end = marker.gray_start_mm() + marker.bits() as f64 * marker.bit_space_mm();
    zones.push((bc0 + marker.barcode_len_mm(), marker.gray_start_mm(), true));
    zones.push((gray_end, marker.length_mm(), true));
    let mut rows = Vec::new();
    for (a, b, white) in zones {
        let (a, b) = (a + margin_mm, b - margin_mm);
        if b < a {
            continue;
        }
        let n = ((b - a) / step_mm).floor() as usize;
        let off = 0.5 * (b - a - n as f64 * step_mm);
        for q in 0..=n {
            rows.push((a + off + q as f64 * step_mm, white));
        }
    }
    rows
}

/// The silhouette of a full ring across the rod at `lp`, bright (white print) or dark (black
/// print): the careful scan of calibration (0.25 px steps over 0.7 R .. 1.4 R).
fn ring_silhouette_any(frame: &FrameView, lp: &LinePoint, bright: bool) -> Option<(f64, f64)> {
    crate::track::ring_silhouette_scan(
        frame,
        lp,
        &crate::track::SilhouetteScan {
            bright,
            step_px: 0.25,
            min_contrast: 12.0,
            from_radii: 0.7,
            span_radii: 0.7,
        },
    )
}

/// Measures the silhouette of the marker's rings along its whole length at the reference pose
/// and fits `offset(s) = a_polarity + b (s - mean s)` robustly (white and black rings get their
/// own offset: the shading across the rod moves a white ring's edges more than a black one's).
/// The centre and the radius are the black rings', unless most of them fall out of line with
/// the fit; then the white rings'. `None`
/// when too few rows stand out or they span too little of the marker.
fn fit_silhouette(
    frame: &FrameView,
    knots: &Knots,
    marker: &Marker,
    s_ref: f64,
    polarity: Option<bool>,
) -> Option<SilhouetteFit> {
    let step_mm = 0.5;
    let mut rows: Vec<(f64, f64, f64, bool)> = Vec::new(); // (s, c, ratio, white)
    for (u, white) in ring_rows_all(marker, 1.0, step_mm) {
        let s = s_ref + u;
        let lp = knots.at(s);
        if let Some((c, hw)) = ring_silhouette_any(frame, &lp, white) {
            rows.push((s, c, hw / lp.radius_px, white));
        }
    }
    let mut keep = vec![true; rows.len()];
    let mut coef = (0.0, 0.0, 0.0, 0.0); // (a_white, a_black, b, s_mean)
    let mut rms = f64::NAN;
    for _ in 0..4 {
        let kept: Vec<&(f64, f64, f64, bool)> = rows
            .iter()
            .zip(&keep)
            .filter(|(_, k)| **k)
            .map(|(r, _)| r)
            .collect();
        let n = kept.len();
        if n < 8 {
            return None;
        }
        let sm = kept.iter().map(|r| r.0).sum::<f64>() / n as f64;
        let spread = kept.iter().map(|r| r.0).fold(f64::MIN, f64::max)
            - kept.iter().map(|r| r.0).fold(f64::MAX, f64::min);
        if spread < 0.4 * marker.length_mm() {
            return None;
        }
        // Normal equations for (a_white, a_black, b).
        let mut m = vec![vec![0.0f64; 4]; 3];
        let (mut nw, mut nb) = (0usize, 0usize);
        for r in &kept {
            let x = [
                if r.3 { 1.0 } else { 0.0 },
                if r.3 { 0.0 } else { 1.0 },
                r.0 - sm,
            ];
            for i in 0..3 {
                for j in 0..3 {
                    m[i][j] += x[i] * x[j];
                }
                m[i][3] += x[i] * r.1;
            }
            if r.3 {
                nw += 1;
            } else {
                nb += 1;
            }
        }
        let sol = if nw == 0 || nb == 0 {
            // One polarity only: a single offset.
            let i = if nw == 0 { 1 } else { 0 };
            let mm = vec![
                vec![m[i][i], m[i][2], m[i][3]],
                vec![m[2][i], m[2][2], m[2][3]],
            ];
            let s2 = crate::line::solve(mm)?;
            vec![s2[0], s2[0], s2[1]]
        } else {
            crate::line::solve(m)?
        };
        coef = (sol[0], sol[1], sol[2], sm);
        let resid: Vec<f64> = rows
            .iter()
            .map(|r| r.1 - (if r.3 { sol[0] } else { sol[1] }) - sol[2] * (r.0 - sm))
            .collect();
        let mut abs: Vec<f64> = resid
            .iter()
            .zip(&keep)
            .filter(|(_, k)| **k)
            .map(|(e, _)| e.abs())
            .collect();
        abs.sort_by(|a, b| a.total_cmp(b));
        let mad = abs[abs.len() / 2] * 1.4826;
        rms = (abs.iter().map(|e| e * e).sum::<f64>() / abs.len() as f64).sqrt();
        let limit = (4.0 * mad).max(0.05);
        let new_keep: Vec<bool> = resid.iter().map(|e| e.abs() <= limit).collect();
        if new_keep == keep {
            break;
        }
        keep = new_keep;
    }
    let (aw, ab, b, sm) = coef;
    let n_black = rows.iter().zip(&keep).filter(|(r, k)| **k && !r.3).count();
    let n_white = rows.iter().zip(&keep).filter(|(r, k)| **k && r.3).count();
    // The black rings are the witnesses (a white ring's edge fades into the shading) unless
    // most of them are out of line with the fit: a black ring beside the rod's own shadow has
    // one edge found too far out, by an amount that changes from ring to ring.
    let n_all_black = rows.iter().filter(|r| !r.3).count();
    let use_black = match polarity {
        Some(white) => !white && n_black >= 6,
        None => n_black >= 6 && (n_white < 6 || 2 * n_black >= n_all_black),
    };
    let centre = if use_black { ab } else { aw };
    let kept: Vec<(f64, f64, f64, bool)> = rows
        .iter()
        .zip(&keep)
        .filter(|(_, k)| **k)
        .map(|(r, _)| *r)
        .collect();
    let ratios: Vec<f64> = kept
        .iter()
        .filter(|r| use_black != r.3)
        .map(|r| r.2)
        .collect();
    let radius_ratio = ratios.iter().sum::<f64>() / ratios.len().max(1) as f64;
    let ppm = knots.at(sm).px_per_mm;
    let thin = (step_mm * ppm).min(1.0);
    let sigma = rms.max(0.02);
    Some(SilhouetteFit {
        rows: kept
            .iter()
            .map(|r| (r.0, r.1 - if r.3 { aw } else { ab } + centre))
            .collect(),
        weight: thin / (sigma * sigma),
        s_mean_mm: sm,
        rms_px: rms,
        radius_ratio: if ratios.is_empty() { 1.0 } else { radius_ratio },
        white: !use_black,
    })
    .filter(|_| b.is_finite())
}
