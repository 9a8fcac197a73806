//! Calibration from a reference frame and path points (paper 2.7), measured, never typed in:
//! the barcode is found by correlation over scales and both directions; its 12 edges give the mm
//! scale and the marker's start; the rod's silhouette gives the centre line and the apparent
//! radius; the Gray code read at both sides of the centre line gives the direction of the print;
//! the phase and angle offsets come from the reference pose.

use super::file::{EnhancedParams, PaperParams, Residuals, RodCalibration};
use super::inputs::{KnownPose, RodInputs};
use super::kernel_search::{barcode_kernel, paper_kernel_search};
use super::known::{read_back_known_poses, Reference};
use super::silhouette::{
    edges_at_pose, make_knots, refine_centre_line, refine_edges, KnotRange, RadiusModel,
    SilhouetteFit,
};
use super::travel::{fit_along, fit_at_h, h_from_direction, AlongTravel, RodAxis};
use crate::angle::{wrap_2pi, wrap_step_diff, wrap_steps};
use crate::camera::CameraIntrinsics;
use crate::frame::FrameView;
use crate::line::{fit_line_tls, CurveModel, Knots, PaperLine};
use crate::marker::{gray_decode, Marker};
use crate::signal::{
    hysteresis, ncc_direct, ncc_runs_prefix, paper_bandpass, prefix_sums, KernelRuns,
    PAPER_HYSTERESIS,
};
use crate::track::{Mode, RodTracker};
use crate::CoreError;
use std::f64::consts::TAU;

/// Knots extend this far beyond the marker's travel, mm.
const KNOT_MARGIN_MM: f64 = 15.0;
/// Default view angle for the paper's eq. (1) when no camera model is given, degrees.
pub const DEFAULT_VIEW_ANGLE_DEG: f64 = 53.2;

/// Calibrates one rod from its inputs and its reference frame (no known poses, no other
/// rods: the along-travel scale is the reference pose's).
pub fn calibrate_rod(
    inputs: &RodInputs,
    frame: &FrameView,
    intrinsics: Option<&CameraIntrinsics>,
) -> Result<RodCalibration, CoreError> {
    calibrate_rod_with(inputs, frame, intrinsics, &RodExtras::default())
}

/// What calibration may know of a rod beyond its reference frame.
#[derive(Default)]
pub struct RodExtras<'a> {
    /// Frames with the rod at a known pose, each with that pose.
    pub known: &'a [(KnownPose, FrameView<'a>)],
    /// The 3-D direction the camera's rods share, in the camera frame (from
    /// [`super::travel::common_direction`]), when there is a camera model.
    pub direction: Option<[f64; 3]>,
}

/// Calibrates one rod from its inputs, its reference frame and what else is known of it:
/// frames at known poses fix the scale over the whole travel (see [`super::travel`]), and so,
/// without them, does the direction the camera's rods share.
pub fn calibrate_rod_with(
    inputs: &RodInputs,
    frame: &FrameView,
    intrinsics: Option<&CameraIntrinsics>,
    extras: &RodExtras,
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
    // The kernel is made of runs: prefix sums make each scale O(samples x runs).
    let (mut prefix, mut prefix2) = (vec![0.0; n + 1], vec![0.0; n + 1]);
    prefix_sums(&profile, &mut prefix, &mut prefix2);
    let mut runs = KernelRuns::default();
    while cell <= 2.0 * 25.0 {
        let len = (kernel.len() as f64 * cell).round() as usize;
        if len + 2 >= n {
            break;
        }
        for dir in [1i32, -1] {
            let kpx = barcode_kernel(kernel, cell, dir, 0.0);
            corr.resize(n - len + 1, 0.0);
            runs.fill_from(&kpx);
            ncc_runs_prefix(&runs, &prefix, &prefix2, &mut corr);
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
    let half_cell_px = 0.5 * marker.cell_mm() * px_per_mm0;
    let edge_pts = refine_edges(
        frame,
        &curve,
        &marker,
        dir,
        &|u| lam_at(u_start_idx(u)),
        half_cell_px,
        dl * 2.0,
    );
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
    let scale_ratio = (g.abs() / curve.lambda_per_px(l0)) / px_per_mm0;
    let s_ref = inputs.reference.position_mm;
    let mut along = AlongTravel {
        l0,
        g,
        h: 0.0,
        s_ref_mm: s_ref,
    };
    let knot_range = KnotRange {
        s0: inputs.travel_mm[0] - KNOT_MARGIN_MM,
        s1: inputs.travel_mm[1] + marker.length_mm() + KNOT_MARGIN_MM,
    };

    // The rod's centre line and apparent radius from the silhouettes of the marker's rings
    // along its whole length in the reference frame (rows every half mm over about 100 mm),
    // combined with the clicked points by least squares: a correction of the path's offset and
    // direction. The phase needs the centre to a few hundredths of a pixel wherever the marker
    // goes (a centre off by `e` px across a rod of apparent radius `R` px turns the angle by
    // about `e / R`), which a few clicks of about 1 px cannot give.
    let reference_pose = [(frame, s_ref)];
    let (c, silhouette) =
        refine_centre_line(curve, &along, &knot_range, &reference_pose, &used, &marker);
    curve = c;
    // The rods are parallel: with the direction they share (the second pass, from every rod's
    // line), this rod's line runs through the point its silhouettes (or clicks) fixed towards
    // the common vanishing point. One rod's own direction comes from about 100 mm of rings and
    // a few clicks of a pixel; an error of 1e-3 in it turns the angle by about 20 mrad at
    // 175 mm from the reference (the line off by 0.2 px across an 11 px radius). Known poses,
    // when given, measure the line's place over the travel below (its direction stays the
    // common one).
    // The silhouettes' middle along the rod (the marker's middle without them): where the line
    // keeps its place when turned.
    let s_mid = |fit: &Option<SilhouetteFit>| {
        fit.as_ref()
            .map_or(s_ref + 0.5 * marker.length_mm(), |f| f.s_mean_mm)
    };
    let common = |curve: CurveModel, along: &AlongTravel, s_c: f64| match extras.direction {
        Some(dir3) => curve
            .toward_vanishing(dir3, along.lambda(s_c))
            .unwrap_or(curve),
        None => curve,
    };
    curve = common(curve, &along, s_mid(&silhouette));
    let mut radius_ratio = silhouette.as_ref().map_or(1.0, |f| f.radius_ratio);
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

    // Along the travel: the known poses' barcodes, else the parallel rods' direction.
    let mut travel_model = "affine";
    // The reference's edges span 64 mm of the barcode: with the depth changing along the rod
    // their affine fit is the secant's scale, not the scale at the reference; `(l0, g)` are
    // refitted with `h` held, and `h` found again from them.
    let ref_pts: Vec<(f64, f64)> = edge_pts.iter().map(|&(u, l)| (s_ref + u, l)).collect();
    let h_from_rods = match (&curve, extras.direction) {
        (CurveModel::Camera { n0, d, .. }, Some(dir3)) => {
            let (mut l, mut gg, mut h) = (l0, g, None);
            for _ in 0..3 {
                let n_ref = [n0[0] + l * d[0], n0[1] + l * d[1]];
                h = h_from_direction(dir3, n_ref, *d, gg);
                match h.and_then(|h| fit_at_h(&ref_pts, s_ref, h)) {
                    Some((l1, g1, _)) => (l, gg) = (l1, g1),
                    None => break,
                }
            }
            h.map(|h| (h, l, gg))
        }
        _ => None,
    };
    if !extras.known.is_empty() {
        let mut pts = ref_pts.clone();
        let mut poses: Vec<(&FrameView, f64)> = vec![(frame, s_ref)];
        for (kp, kframe) in extras.known {
            match edges_at_pose(
                kframe,
                &curve,
                &along,
                &marker,
                dir,
                kp.position_mm,
                dl * 2.0,
            ) {
                Some(e) if e.len() >= 6 => {
                    pts.extend(e);
                    poses.push((kframe, kp.position_mm));
                }
                found => warnings.push(format!(
                    "known pose in frame {}: only {} barcode edges found near {:.1} mm; pose \
                     not used",
                    kp.frame,
                    found.map_or(0, |e| e.len()),
                    kp.position_mm
                )),
            }
        }
        if poses.len() > 1 {
            if let Some((a, _)) = fit_along(&pts, s_ref) {
                along = a;
                travel_model = "known_poses";
            }
            let (c, at_poses) =
                refine_centre_line(curve, &along, &knot_range, &poses, &used, &marker);
            curve = c;
            // The poses' silhouettes move the line's place; its direction is still the one
            // the rods share: each pose's silhouette is pulled by what lies beside the rod
            // there (a few tenths of a pixel), which one rod's line over its travel takes as a
            // tilt, and the rods' common direction averages over all of them.
            curve = common(curve, &along, s_mid(&at_poses));
        }
    } else if let Some((h, l, gg)) = h_from_rods {
        along = AlongTravel {
            l0: l,
            g: gg,
            h,
            s_ref_mm: s_ref,
        };
        travel_model = "vanishing_direction";
    }
    // With a camera model the radius is the cylinder's projection; without one, what the
    // reference frame's silhouette measured.
    let radius_model = match &curve {
        CurveModel::Camera { intrinsics, n0, d } => match RodAxis::new(*n0, *d, &along) {
            Some(axis) => RadiusModel::Geometric(*intrinsics, axis),
            None => RadiusModel::Measured(radius_ratio),
        },
        CurveModel::Poly { .. } => RadiusModel::Measured(radius_ratio),
    };
    let knots = make_knots(&curve, &along, &knot_range, &marker, &radius_model);
    if let RadiusModel::Geometric(..) = radius_model {
        // The silhouette's width against the lens' prediction (shading moves a ring's
        // half-level edges: a check, not a correction).
        radius_ratio = silhouette.as_ref().map_or(1.0, |f| {
            let predicted = make_knots(
                &curve,
                &along,
                &knot_range,
                &marker,
                &RadiusModel::Measured(1.0),
            );
            let s = f.s_mean_mm;
            f.radius_ratio * predicted.at(s).radius_px / knots.at(s).radius_px
        });
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
            angle_bias_rad: Vec::new(),
            learn_centre_slope: true,
            lens_perspective: match &radius_model {
                RadiusModel::Geometric(_, axis) => axis.perspective(s_ref, marker.radius_mm()),
                RadiusModel::Measured(_) => None,
            },
        },
        paper: None,
        residuals: Residuals::default(),
    };
    // When the vote across the rod is undecided, take the sign whose phase agrees better with
    // the Gray code in the reference frame.
    let mut sigma = match vote {
        Some(s) => s,
        None => {
            let mut best = (f64::MAX, 1);
            for s in [1, -1] {
                cal.enhanced.phase_sign = s;
                let mut t = RodTracker::new(&cal, frame.width(), frame.height(), Mode::Enhanced)?;
                let r = t.process(frame)?;
                let d = wrap_steps(
                    r.theta_steps - (r.gray_step as f64 + 0.5),
                    marker.steps() as f64,
                );
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
    let mut r = tr.process(frame)?;
    // The vote reads the code at a few angles across the rod: with the line facing the
    // camera on an edge of a high bit, it can take the print's direction the wrong way. The
    // tracker's check across the rod then refuses the reading at every angle (the print
    // mirrored about the facing line). Where the other direction reads `ok`, take it.
    if r.status != crate::Status::Ok {
        let mut other = cal.clone();
        other.enhanced.phase_sign = -sigma;
        let mut t = RodTracker::new(&other, frame.width(), frame.height(), Mode::Enhanced)?;
        let r2 = t.process(frame)?;
        if r2.status == crate::Status::Ok {
            warnings.push(format!(
                "print direction taken from the print's agreement across the rod (the code \
                 read across it said the other way: {})",
                r.reason
            ));
            sigma = -sigma;
            cal.enhanced.phase_sign = sigma;
            r = r2;
        }
    }
    // The angle's zero is the print coordinate read here: a reading the tracker would refuse
    // (the Gray code's high bits fooled by a glare, a shadow or a smudge on the marker, a hand
    // over it, or a centre line off the rod) would put every angle of the rod off by whole
    // Gray steps, confidently, or leave a rod that is refused in every frame. Fail the rod
    // instead, saying what to fix.
    if r.status != crate::Status::Ok {
        return Err(fail(format!(
            "the reference frame reads as {} in enhanced mode ({}): the angle's zero cannot be \
             read from it; check that the marker is clean, evenly lit and wholly in view there \
             (no glare, shadow, smudge or hand on it) and that the path points follow the rod \
             over its whole travel, then capture the reference frame again",
            r.status, r.reason
        )));
    }
    let dpos = r.position_mm - s_ref;
    if dpos.abs() < 5.0 {
        cal.knots.s0_mm -= dpos;
    }
    cal.enhanced.angle_offset_rad =
        wrap_2pi(r.theta_steps * TAU / marker.steps() as f64 - inputs.reference.angle_rad);
    let code_phase = {
        let d = wrap_steps(
            r.theta_steps - (r.gray_step as f64 + 0.5),
            marker.steps() as f64,
        );
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
        travel_model: travel_model.to_string(),
        depth_change_per_m: along.h * 1000.0,
        depth_change_per_m_from_rods: h_from_rods.map(|h| h.0 * 1000.0),
        common_direction: String::new(),
        known_pose_errors_mm: Vec::new(),
        warnings,
    };
    cal.validate(frame.width(), frame.height())?;
    // The known poses read back with the final calibration (a first frame: nothing learnt),
    // and where their angle is given, the angle's bias there.
    if travel_model == "known_poses" {
        cal.enhanced.learn_centre_slope = false;
    }
    read_back_known_poses(
        &mut cal,
        extras.known,
        &Reference {
            marker: &marker,
            frame,
            angle_rad: inputs.reference.angle_rad,
        },
    )?;
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
        vote += wrap_step_diff(w[1] - w[0], steps);
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
    let expand = |cell: f64, dir: i32, black: f32| barcode_kernel(kernel, cell, dir, black);
    let best = paper_kernel_search(&bin, |cell, dir| expand(cell, dir, 1.0));
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
    let mut corr = vec![0.0; raw.len() - kraw.len() + 1];
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
    let frac0 = wrap_steps(r0.theta_steps, 4.0);
    p.phase_offset_rad = TAU * (frac0 - ((r0.gray_step % 4) as f64 + 0.5)) / 4.0;
    probe.paper = Some(p.clone());
    let mut tr = RodTracker::new(&probe, frame.width(), frame.height(), Mode::Paper)?;
    let r1 = tr.process(frame)?;
    p.angle_offset_rad =
        wrap_2pi(r1.theta_steps * TAU / marker.steps() as f64 - cal.reference_angle_rad);
    let _ = fit_line_tls;
    Ok(p)
}
