//! Calibration from a reference frame and path points (paper 2.7), measured, never typed in:
//! the barcode is found by correlation over scales and both directions; its 12 edges give the mm
//! scale and the marker's start; the rod's silhouette gives the centre line and the apparent
//! radius; the Gray code read at both sides of the centre line gives the direction of the print;
//! the phase and angle offsets come from the reference pose.

use super::file::{EnhancedParams, PaperParams, Residuals, RodCalibration};
use super::inputs::RodInputs;
use crate::camera::CameraIntrinsics;
use crate::frame::FrameView;
use crate::line::{fit_line_tls, CurveModel, Knots, LinePoint, PaperLine};
use crate::marker::{gray_decode, Marker};
use crate::signal::{hysteresis, ncc_direct, paper_bandpass, PAPER_HYSTERESIS};
use crate::track::{Mode, RodTracker};
use crate::CoreError;
use std::f64::consts::TAU;

/// Knot spacing, mm.
const KNOT_STEP_MM: f64 = 2.0;
/// Knots extend this far beyond the marker's travel, mm.
const KNOT_MARGIN_MM: f64 = 15.0;
/// Assumed error of a clicked path point, px (the silhouettes are weighted against it).
const CLICK_SIGMA_PX: f64 = 1.0;
/// Default view angle for the paper's eq. (1) when no camera model is given, degrees.
pub const DEFAULT_VIEW_ANGLE_DEG: f64 = 53.2;

/// Calibrates one rod from its inputs and its reference frame.
pub fn calibrate_rod(
    inputs: &RodInputs,
    frame: &FrameView,
    intrinsics: Option<&CameraIntrinsics>,
) -> Result<RodCalibration, CoreError> {
    let rod = inputs.rod;
    let fail = |reason: String| CoreError::CalibrationFailed { rod, reason };
    let marker = inputs
        .marker
        .validate()
        .map_err(|e| CoreError::Calibration {
            rod,
            field: "marker".into(),
            reason: e.to_string(),
        })?;
    if inputs.path_points_px.len() < 3 {
        return Err(CoreError::Calibration {
            rod,
            field: "path_points_px".into(),
            reason: format!(
                "needs at least 3 points, has {}",
                inputs.path_points_px.len()
            ),
        });
    }
    for (i, p) in inputs.path_points_px.iter().enumerate() {
        let finite = p[0].is_finite() && p[1].is_finite();
        if !finite || !frame.contains(p[0] as f32, p[1] as f32, 0.0) {
            return Err(CoreError::Calibration {
                rod,
                field: format!("path_points_px[{i}]"),
                reason: format!(
                    "{p:?} is not a point inside the {}x{} image",
                    frame.width(),
                    frame.height()
                ),
            });
        }
    }
    let travel_ok = inputs.travel_mm[0].is_finite()
        && inputs.travel_mm[1].is_finite()
        && inputs.travel_mm[0] <= inputs.travel_mm[1];
    if !travel_ok {
        return Err(CoreError::Calibration {
            rod,
            field: "travel_mm".into(),
            reason: format!("must be [min, max], got {:?}", inputs.travel_mm),
        });
    }
    let mut warnings = Vec::new();
    let mut curve = CurveModel::fit(&inputs.path_points_px, intrinsics)
        .ok_or_else(|| fail("the path points do not define a line (all the same point?)".into()))?;
    // With many points (an automatic sweep), drop those far from the fit and fit again.
    let mut used: Vec<[f64; 2]> = inputs.path_points_px.clone();
    if used.len() >= 6 {
        for _ in 0..3 {
            let mut d: Vec<f64> = used.iter().map(|p| curve.distance(*p)).collect();
            d.sort_by(|a, b| a.total_cmp(b));
            let limit = (3.0 * d[d.len() / 2]).max(0.3);
            let kept: Vec<[f64; 2]> = used
                .iter()
                .copied()
                .filter(|p| curve.distance(*p) <= limit)
                .collect();
            if kept.len() == used.len() || kept.len() < 5 {
                break;
            }
            warnings.push(format!(
                "{} path point(s) more than {limit:.2} px off the path were left out",
                used.len() - kept.len()
            ));
            used = kept;
            if let Some(c) = CurveModel::fit(&used, intrinsics) {
                curve = c;
            }
        }
    }
    let dists: Vec<f64> = used.iter().map(|p| curve.distance(*p)).collect();
    let path_rms = (dists.iter().map(|d| d * d).sum::<f64>() / dists.len() as f64).sqrt();
    let path_max = dists.iter().cloned().fold(0.0, f64::max);
    let lams: Vec<f64> = used.iter().map(|p| curve.project(*p)).collect();
    let spread_px = {
        let a = lams.iter().cloned().fold(f64::MAX, f64::min);
        let b = lams.iter().cloned().fold(f64::MIN, f64::max);
        (b - a) / curve.lambda_per_px(a)
    };
    if path_max > 3.0 {
        warnings.push(format!(
            "a path point lies {path_max:.1} px off the fitted path: check the clicks"
        ));
    }

    // Dense centre-line profile over the part of the path inside the frame.
    let lam_mid = lams.iter().sum::<f64>() / lams.len() as f64;
    let dl = 0.5 * curve.lambda_per_px(lam_mid);
    let inside = |l: f64| {
        let (x, y) = curve.point(l);
        frame.contains(x as f32, y as f32, 2.0)
    };
    let mut lo = lam_mid;
    while inside(lo - dl) && (lam_mid - lo) / dl < 20000.0 {
        lo -= dl;
    }
    let mut hi = lam_mid;
    while inside(hi + dl) && (hi - lam_mid) / dl < 20000.0 {
        hi += dl;
    }
    let n = ((hi - lo) / dl) as usize + 1;
    let lam_at = |i: f64| lo + i * dl;
    let profile: Vec<f32> = (0..n)
        .map(|i| {
            let (x, y) = curve.point(lam_at(i as f64));
            frame.luma_bilinear(x as f32, y as f32)
        })
        .collect();

    // Find the barcode: NCC over scales and both directions (0.5 px samples).
    let kernel = marker.kernel();
    let mut best: Option<(f32, f64, i32, usize)> = None; // (ncc, cell samples, dir, index)
    let mut cell = 2.0 * 2.0; // 2 px cells at 0.5 px per sample
    let mut corr = Vec::new();
    while cell <= 2.0 * 25.0 {
        let len = (kernel.len() as f64 * cell).round() as usize;
        if len + 2 >= n {
            break;
        }
        for dir in [1i32, -1] {
            let kpx: Vec<f32> = (0..len)
                .map(|i| {
                    let c = (((i as f64 + 0.5) / cell) as usize).min(kernel.len() - 1);
                    let c = if dir > 0 { c } else { kernel.len() - 1 - c };
                    if kernel[c] {
                        0.0
                    } else {
                        1.0
                    }
                })
                .collect();
            corr.resize(n - len + 1, 0.0);
            ncc_direct(&kpx, &profile, &mut corr);
            for (i, &c) in corr.iter().enumerate() {
                if best.is_none_or(|b| c > b.0) {
                    best = Some((c, cell, dir, i));
                }
            }
        }
        cell *= 1.02;
    }
    let (ncc, cell_samples, dir, start_idx) =
        best.ok_or_else(|| fail("the path is too short to hold a marker".into()))?;
    if ncc < 0.6 {
        return Err(fail(format!(
            "no marker found along the path in the reference frame (best correlation {ncc:.2}); \
             check the path points and that the marker is in view"
        )));
    }
    // Edge refinement in lambda.
    let px_per_mm0 = cell_samples * 0.5 / marker.cell_mm();
    let u_start_idx = |u: f64| -> f64 {
        // sample index of marker coordinate u (kernel start is at the barcode's first cell for
        // dir > 0, at its last cell's end for dir < 0)
        let u0 = if dir > 0 {
            marker.barcode_start_mm()
        } else {
            marker.barcode_start_mm() + marker.barcode_len_mm()
        };
        start_idx as f64 + dir as f64 * (u - u0) * px_per_mm0 * 2.0
    };
    let mut edge_pts = Vec::new();
    for (u_e, rising) in marker.barcode_edges_mm() {
        let c_idx = u_start_idx(u_e);
        let half = 0.5 * marker.cell_mm() * px_per_mm0; // px
        let steps = 40usize;
        let vals: Vec<(f64, f32)> = (0..=steps)
            .map(|i| {
                let off = -half + 2.0 * half * i as f64 / steps as f64; // px along
                let l = lam_at(c_idx) + off * dl * 2.0;
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
    if edge_pts.len() < 6 {
        return Err(fail(format!(
            "only {} of the barcode's {} edges were found in the reference frame",
            edge_pts.len(),
            marker.barcode_edges_mm().len()
        )));
    }
    // lambda = l0 + g u (g signed: carries the direction).
    let (l0, g, edge_rms_lam) = fit_affine(&edge_pts);
    let edge_rms_mm = edge_rms_lam / g.abs();
    // The path points should cover most of what the rod's travel spans in the image (as much
    // of it as the image shows).
    let travel_px = (inputs.travel_mm[1] - inputs.travel_mm[0]) * g.abs() / curve.lambda_per_px(l0);
    let expected_px = travel_px.min((hi - lo) / curve.lambda_per_px(l0));
    if spread_px < 0.5 * expected_px {
        warnings.push(format!(
            "path points span only {spread_px:.0} px, {:.0} % of the {expected_px:.0} px the \
             rod's travel covers in the image: spread them along the whole path",
            100.0 * spread_px / expected_px
        ));
    }
    let scale_ratio =
        (g.abs() / curve.lambda_per_px(l0)) / (marker.barcode_len_mm() * 0.0 + 1.0) / px_per_mm0;
    let s_ref = inputs.reference.position_mm;
    let lambda_of_s = |s: f64| l0 + g * (s - s_ref);

    // Knots of a path: centre and apparent radius every 2 mm along the axis.
    let s0 = inputs.travel_mm[0] - KNOT_MARGIN_MM;
    let s1 = inputs.travel_mm[1] + marker.length_mm() + KNOT_MARGIN_MM;
    let nk = ((s1 - s0) / KNOT_STEP_MM).ceil() as usize + 1;
    let make_knots = |curve: &CurveModel, radius_ratio: f64| {
        let mut kx = Vec::with_capacity(nk);
        let mut ky = Vec::with_capacity(nk);
        let mut kr = Vec::with_capacity(nk);
        for i in 0..nk {
            let s = s0 + i as f64 * KNOT_STEP_MM;
            let (x, y) = curve.point(lambda_of_s(s));
            let (x2, y2) = curve.point(lambda_of_s(s + 0.5));
            let ppm = ((x2 - x).powi(2) + (y2 - y).powi(2)).sqrt() / 0.5;
            kx.push(x);
            ky.push(y);
            kr.push(marker.radius_mm() * ppm * radius_ratio);
        }
        Knots {
            s0_mm: s0,
            step_mm: KNOT_STEP_MM,
            x_px: kx,
            y_px: ky,
            radius_px: kr,
        }
    };

    // The rod's centre line and apparent radius from the silhouettes of the marker's rings
    // along its whole length in the reference frame (rows every half mm over about 100 mm),
    // combined with the clicked points by least squares: a correction of the path's offset and
    // direction. The phase needs the centre to a few hundredths of a pixel wherever the marker
    // goes (a centre off by `e` px across a rod of apparent radius `R` px turns the angle by
    // about `e / R`), which a few clicks of about 1 px cannot give.
    let mut radius_ratio = 1.0;
    let mut silhouette = None;
    for _ in 0..5 {
        let knots = make_knots(&curve, 1.0);
        let Some(fit) = fit_silhouette(frame, &knots, &marker, s_ref) else {
            break;
        };
        radius_ratio = fit.radius_ratio;
        let lam_c = lambda_of_s(fit.s_mean_mm);
        // Observations: lateral offset (px, along the knots' normal) at lambda, and weight.
        let mut obs: Vec<(f64, f64, f64)> = fit
            .rows
            .iter()
            .map(|&(s, c)| (lambda_of_s(s), c, fit.weight))
            .collect();
        for p in &used {
            let lam = curve.project(*p);
            let (x, y) = curve.point(lam);
            let lp = knots.at(s_ref + (lam - l0) / g);
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
            let lp = knots.at(s_ref + (lam - l0) / g);
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
        silhouette = Some(fit);
        if a.abs().max(b.abs()) < 0.005 {
            break;
        }
    }
    let knots = make_knots(&curve, radius_ratio);
    if let Some(f) = silhouette.as_ref().filter(|f| f.rms_px > 0.3) {
        warnings.push(format!(
            "the rod's silhouette along the marker scatters by {:.2} px around a line: check \
             the reference frame",
            f.rms_px
        ));
    }
    if silhouette.is_none() {
        warnings.push(
            "the marker's rings do not stand out from the background: centre line and radius \
             not refined"
                .to_string(),
        );
    }

    // Direction of the print across the rod: Gray code read on both sides of the centre line.
    let vote = print_direction(frame, &knots, &marker, s_ref);

    let mut cal = RodCalibration {
        rod,
        marker: inputs.marker.clone(),
        travel_mm: inputs.travel_mm,
        reference_position_mm: s_ref,
        reference_angle_rad: inputs.reference.angle_rad,
        line_model: curve.kind().to_string(),
        path_points_px: inputs.path_points_px.clone(),
        knots,
        enhanced: EnhancedParams {
            phase_sign: vote.unwrap_or(1),
            phase_offset_steps: 0.0,
            angle_offset_rad: 0.0,
        },
        paper: None,
        residuals: Residuals::default(),
    };
    // When the vote across the rod is undecided, take the sign whose phase agrees better with
    // the Gray code in the reference frame.
    let sigma = match vote {
        Some(s) => s,
        None => {
            let mut best = (f64::MAX, 1);
            for s in [1, -1] {
                cal.enhanced.phase_sign = s;
                let mut t = RodTracker::new(&cal, frame.width(), frame.height(), Mode::Enhanced)?;
                let r = t.process(frame)?;
                let d =
                    (r.theta_steps - (r.gray_step as f64 + 0.5)).rem_euclid(marker.steps() as f64);
                let d = d.min(marker.steps() as f64 - d);
                if d < best.0 {
                    best = (d, s);
                }
            }
            warnings.push("print direction decided from the code/phase agreement only".into());
            best.1
        }
    };
    cal.enhanced.phase_sign = sigma;
    // Enhanced offsets from the reference pose.
    let mut tr = RodTracker::new(&cal, frame.width(), frame.height(), Mode::Enhanced)?;
    let r = tr.process(frame)?;
    if r.status != crate::Status::Ok {
        warnings.push(format!(
            "the reference frame reads as {} in enhanced mode: check the reference",
            r.status
        ));
    }
    let dpos = r.position_mm - s_ref;
    if dpos.abs() < 5.0 {
        cal.knots.s0_mm -= dpos;
    }
    cal.enhanced.angle_offset_rad =
        (r.theta_steps * TAU / marker.steps() as f64 - inputs.reference.angle_rad).rem_euclid(TAU);
    let code_phase = {
        let d = (r.theta_steps - (r.gray_step as f64 + 0.5)).rem_euclid(marker.steps() as f64);
        d.min(marker.steps() as f64 - d)
    };
    if code_phase > 1.0 {
        warnings.push(format!(
            "Gray code and phase disagree by {code_phase:.2} steps in the reference frame"
        ));
    }

    // The paper's parameters, when the rod runs along image rows.
    let along_rows = {
        let a = cal.knots.at(cal.knots.s0_mm);
        let b = cal.knots.at(cal.knots.s_end_mm());
        (b.y - a.y).abs() > (b.x - a.x).abs()
    };
    if along_rows {
        match paper_params(&cal, frame, &marker, intrinsics, sigma) {
            Ok(p) => cal.paper = Some(p),
            Err(e) => warnings.push(format!("paper mode unavailable: {e}")),
        }
    } else {
        warnings.push("the rod runs along image columns: the paper's mode needs rows".into());
    }
    cal.residuals = Residuals {
        path_rms_px: path_rms,
        path_max_px: path_max,
        scale_ratio,
        edge_rms_mm,
        reference_ncc: ncc as f64,
        reference_code_phase_steps: code_phase,
        radius_ratio,
        warnings,
    };
    cal.validate(frame.width(), frame.height())?;
    Ok(cal)
}

/// Least squares `y = a + b x` over `(x, y)`; returns `(a, b, rms)`.
fn fit_affine(p: &[(f64, f64)]) -> (f64, f64, f64) {
    let n = p.len() as f64;
    let mx = p.iter().map(|q| q.0).sum::<f64>() / n;
    let my = p.iter().map(|q| q.1).sum::<f64>() / n;
    let sxx: f64 = p.iter().map(|q| (q.0 - mx).powi(2)).sum();
    let sxy: f64 = p.iter().map(|q| (q.0 - mx) * (q.1 - my)).sum();
    let b = if sxx > 0.0 { sxy / sxx } else { 0.0 };
    let a = my - b * mx;
    let rms = (p.iter().map(|q| (q.1 - a - b * q.0).powi(2)).sum::<f64>() / n).sqrt();
    (a, b, rms)
}

/// +1 when the print angle grows along the line's normal, -1 otherwise; from Gray codes read
/// at several angles across the rod at the reference pose.
fn print_direction(frame: &FrameView, knots: &Knots, marker: &Marker, s_ref: f64) -> Option<i32> {
    let mut codes = Vec::new();
    for deg in (-50..=50).step_by(5) {
        let d = (deg as f64).to_radians();
        let mut samples = [0.0f32; 8];
        let mut lo = f32::MAX;
        let mut hi = f32::MIN;
        for (k, smp) in samples.iter_mut().enumerate().take(marker.bits() as usize) {
            let lp = knots.at(s_ref + marker.bit_space_centre_mm(k as u32));
            let (x, y) = lp.offset(0.0, lp.radius_px * d.sin());
            *smp = frame.luma_bilinear(x as f32, y as f32);
            lo = lo.min(*smp);
            hi = hi.max(*smp);
        }
        // Threshold from the barcode would be better; the bit spaces alone hold both colours
        // at almost every angle, and a wrong read only weakens the vote.
        let thr = 0.5 * (lo + hi);
        let mut code = 0u32;
        for (k, &v) in samples.iter().enumerate().take(marker.bits() as usize) {
            if v < thr {
                code |= 1 << k;
            }
        }
        codes.push(gray_decode(code) as i64);
    }
    let steps = marker.steps() as i64;
    let mut vote = 0i64;
    for w in codes.windows(2) {
        let mut d = (w[1] - w[0]).rem_euclid(steps);
        if d > steps / 2 {
            d -= steps;
        }
        vote += d;
    }
    match vote.signum() {
        0 => None,
        s => Some(s as i32),
    }
}

fn paper_params(
    cal: &RodCalibration,
    frame: &FrameView,
    marker: &Marker,
    intrinsics: Option<&CameraIntrinsics>,
    sigma: i32,
) -> Result<PaperParams, CoreError> {
    let rod = cal.rod;
    let fail = |reason: String| CoreError::CalibrationFailed { rod, reason };
    let h0 = frame.height();
    // The trajectory: the paper fits x(t) through the clicked points.
    let pts = &cal.path_points_px;
    let t: Vec<f64> = pts.iter().map(|p| p[1]).collect();
    let x: Vec<f64> = pts.iter().map(|p| p[0]).collect();
    let c = crate::line::polyfit(&t, &x, 2).ok_or_else(|| fail("trajectory fit failed".into()))?;
    let abc = [c[2], c[1], c[0]];
    let view_angle_deg = match intrinsics {
        Some(k) => 2.0 * (0.5 * h0 as f64 / k.fy).atan().to_degrees(),
        None => DEFAULT_VIEW_ANGLE_DEG,
    };
    let line = PaperLine::new(abc, view_angle_deg.to_radians(), h0);
    let raw: Vec<f32> = line
        .pixels
        .iter()
        .map(|&(x, y)| frame.luma_nearest(x as f32, y as f32))
        .collect();
    let mut filt = vec![0.0; raw.len()];
    let mut bin = vec![0.0; raw.len()];
    paper_bandpass(&raw, &mut filt);
    hysteresis(&filt, -PAPER_HYSTERESIS, PAPER_HYSTERESIS, &mut bin);
    // Kernel scale and direction that best match, on the paper's own binary line.
    let kernel = marker.kernel();
    let mut best: Option<(f32, f64, i32, usize)> = None;
    let mut cell = 2.0f64;
    let mut corr = Vec::new();
    let expand = |cell: f64, dir: i32, black: f32| -> Vec<f32> {
        let len = (kernel.len() as f64 * cell).round() as usize;
        (0..len)
            .map(|i| {
                let c = (((i as f64 + 0.5) / cell) as usize).min(kernel.len() - 1);
                let c = if dir > 0 { c } else { kernel.len() - 1 - c };
                if kernel[c] {
                    black
                } else {
                    1.0 - black
                }
            })
            .collect()
    };
    while cell < 25.0 {
        for dir in [1, -1] {
            let k = expand(cell, dir, 1.0);
            if k.len() + 1 >= bin.len() {
                continue;
            }
            corr.resize(bin.len() - k.len() + 1, 0.0);
            ncc_direct(&k, &bin, &mut corr);
            for (i, &cv) in corr.iter().enumerate() {
                if best.is_none_or(|b| cv * cv > b.0) {
                    best = Some((cv * cv, cell, dir, i));
                }
            }
        }
        cell *= 1.01;
    }
    let (c2, cell_px, direction, p_ref) =
        best.ok_or_else(|| fail("paper line too short".into()))?;
    if c2 < 0.25 {
        return Err(fail(format!(
            "the paper's correlation finds no marker (C^2 = {c2:.2})"
        )));
    }
    // The IIR filters delay the binary line; measure that delay against the raw line so the
    // Gray-code samples land where the paper intends.
    let kraw = expand(cell_px, direction, 0.0);
    corr.resize(raw.len() - kraw.len() + 1, 0.0);
    ncc_direct(&kraw, &raw, &mut corr);
    let lo = p_ref.saturating_sub(6);
    let hi = (p_ref + 6).min(corr.len() - 1);
    let p_raw = (lo..=hi)
        .max_by(|&a, &b| corr[a].total_cmp(&corr[b]))
        .unwrap_or(p_ref);
    let lag = p_ref as f64 - p_raw as f64;
    let scale = cell_px / marker.cell_mm();
    let spacing = direction as f64 * marker.bit_space_mm() * scale;
    let u_p = if direction > 0 {
        marker.barcode_start_mm()
    } else {
        marker.barcode_start_mm() + marker.barcode_len_mm()
    };
    let offset =
        direction as f64 * (marker.bit_space_centre_mm(0) - u_p) * scale - 1.5 * spacing - lag;
    // T_hat: the period that best explains the pixels across the rod at bit space 0.
    let j0 = (p_ref as f64 + offset + 1.5 * spacing).round();
    if j0 < 0.0 || j0 >= line.pixels.len() as f64 {
        return Err(fail("bit space 0 lies outside the paper's line".into()));
    }
    let (x0, y0) = line.pixels[j0 as usize];
    let np = 10i32;
    let d: Vec<f64> = (-np..=np)
        .map(|i| frame.luma_nearest((x0 + i) as f32, y0 as f32) as f64)
        .collect();
    let mean = d.iter().sum::<f64>() / d.len() as f64;
    let mut best_t = (0.0, 0.0);
    let mut tp = 3.0;
    while tp < 20.0 {
        let (mut s, mut c) = (0.0, 0.0);
        for (i, v) in d.iter().enumerate() {
            let a = TAU * (i as f64 - np as f64) / tp;
            s += (v - mean) * a.sin();
            c += (v - mean) * a.cos();
        }
        let m = s * s + c * c;
        if m > best_t.1 {
            best_t = (tp, m);
        }
        tp += 0.05;
    }
    // Eq. 6 along image +x gives -sigma_x * phase; choose the sign that makes it grow with the
    // angle. The enhanced sigma is along the normal (-ty, tx).
    let lp = cal
        .knots
        .at(cal.reference_position_mm + marker.bit_space_centre_mm(0));
    let sigma_x = sigma as f64 * (-lp.ty);
    let phase_sign = if sigma_x > 0.0 { -1 } else { 1 };
    let mut p = PaperParams {
        trajectory_abc: abc,
        view_angle_deg,
        cell_px,
        direction,
        offset_px: offset,
        spacing_px: spacing,
        period_px: best_t.0,
        phase_offset_rad: 0.0,
        phase_sign,
        half_width_px: np as u32,
        mm_per_px: marker.cell_mm() / cell_px,
        zero_px: p_ref as f64,
        angle_offset_rad: 0.0,
    };
    // Offsets from the reference pose: phi_offset puts the reference in the middle of its
    // Gray step (one frame cannot tell more), then the angle offset.
    let mut probe = cal.clone();
    probe.paper = Some(p.clone());
    let mut tr = RodTracker::new(&probe, frame.width(), frame.height(), Mode::Paper)?;
    let r0 = tr.process(frame)?;
    let frac0 = r0.theta_steps.rem_euclid(4.0);
    p.phase_offset_rad = TAU * (frac0 - ((r0.gray_step % 4) as f64 + 0.5)) / 4.0;
    probe.paper = Some(p.clone());
    let mut tr = RodTracker::new(&probe, frame.width(), frame.height(), Mode::Paper)?;
    let r1 = tr.process(frame)?;
    p.angle_offset_rad =
        (r1.theta_steps * TAU / marker.steps() as f64 - cal.reference_angle_rad).rem_euclid(TAU);
    let _ = fit_line_tls;
    Ok(p)
}

/// The rod's silhouette along the marker in the reference frame.
struct SilhouetteFit {
    /// `(s, lateral offset)` of every kept row, px along the knots' normal, both polarities
    /// brought to one centre.
    rows: Vec<(f64, f64)>,
    /// Least-squares weight of one row (1 / px^2, thinned for rows closer than a pixel).
    weight: f64,
    /// Mean `s` of the rows, mm.
    s_mean_mm: f64,
    /// RMS of the rows around their line, px.
    rms_px: f64,
    /// Apparent radius over the knots' predicted one.
    radius_ratio: f64,
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
/// The centre is the black rings' when there are enough of them, else the white ones'. `None`
/// when too few rows stand out or they span too little of the marker.
fn fit_silhouette(
    frame: &FrameView,
    knots: &Knots,
    marker: &Marker,
    s_ref: f64,
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
    let centre = if n_black >= 6 { ab } else { aw };
    let kept: Vec<(f64, f64, f64, bool)> = rows
        .iter()
        .zip(&keep)
        .filter(|(_, k)| **k)
        .map(|(r, _)| *r)
        .collect();
    // The radius: from the black rings when there are enough (their edges do not fade into the
    // shading), else from the white ones.
    let ratios: Vec<f64> = kept
        .iter()
        .filter(|r| (n_black >= 6) != r.3)
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
    })
    .filter(|_| b.is_finite())
}
