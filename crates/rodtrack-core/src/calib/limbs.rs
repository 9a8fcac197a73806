//! The bare rod's outline beside its marker, for the direction the camera's rods share.
//!
//! A cylinder's outline in a perspective image is the image of two lines on its surface
//! parallel to its axis (where the rays graze it): each outline's plane through the camera
//! centre holds the rod's 3-D direction, as the axis' own plane does. The first pass's line of
//! a rod comes from its marker's ring silhouettes (100 mm of them in the reference frame, a few
//! more at known poses) and its clicks; the bare steel rod lies beside the marker in the
//! reference frame over the rest of the span the marker sweeps over its travel (the line's
//! knots: up to about 450 mm). Along the first pass's line over that span, in the reference
//! frame and away from the marker, each side's outline is found where the profile across the rod crosses halfway from the rod's limb to
//! the background beyond it; the rows where the background beyond is not uniform (a figure, a
//! field line, the marker) or the limb does not stand out from it are left out. One line is
//! fitted to each side's points through the lens (undistorted), robustly; its plane weighs in
//! the rods' common direction by the inverse variance of its direction (its points' scatter
//! over their count and span).
//!
//! A constant bias of the outline (the limb's shading, the blur) moves a line sideways, not
//! its direction: it stays out of the common direction. On a table rendered by an independent
//! renderer one side of each steel rod stood out from the field (its dark limb, 25 levels
//! below the field) and the other did not (docs/accuracy.md).

use super::file::RodCalibration;
use super::travel::line_plane;
use crate::camera::CameraIntrinsics;
use crate::frame::FrameView;
use crate::line::fit_line_tls;

/// Outline points a side needs for its line.
const MIN_POINTS: usize = 20;
/// The limb's contrast to the background beyond, in standard deviations of that background
/// (the noise and texture the edge's place suffers from).
const MIN_CONTRAST_SIGMAS: f64 = 5.0;
/// Profile samples per pixel across the rod.
const SAMPLES_PER_PX: f64 = 10.0;
/// Iterations of the robust line fit (points beyond 3 standard deviations dropped each time).
const ROBUST_ITERATIONS: usize = 4;

/// Each side's outline plane of a calibrated rod in its reference frame (`frame`) that stands
/// out from the background, with its weight (inverse variance of its direction); empty when
/// none does.
pub(super) fn limb_planes(
    cal: &RodCalibration,
    frame: &FrameView,
    k: &CameraIntrinsics,
) -> Vec<([f64; 3], f64)> {
    let Ok(marker) = cal.marker.validate() else {
        return Vec::new();
    };
    let kn = &cal.knots;
    if kn.len() < 2 {
        return Vec::new();
    }
    let full_scale = if frame.format().is_16bit() {
        65535.0
    } else {
        255.0
    };
    // The marker at the reference pose, a rod's radius either side.
    let radius_mm = 0.5 * cal.marker.rod_diameter_mm;
    let (m0, m1) = (
        cal.reference_position_mm - radius_mm,
        cal.reference_position_mm + marker.length_mm() + radius_mm,
    );
    let mut planes = Vec::new();
    let mut profile = Vec::new();
    for side in [-1.0f64, 1.0] {
        let mut pts: Vec<[f64; 2]> = Vec::new();
        for i in 0..kn.len() {
            let s = kn.s0_mm + i as f64 * kn.step_mm;
            if s >= m0 && s <= m1 {
                continue;
            }
            let lp = kn.at(s);
            let r = lp.radius_px;
            if r.is_nan() || r < 2.0 {
                continue;
            }
            // The profile from 0.7 radii to 2.2 radii out.
            let (t0, t1) = (0.7 * r, 2.2 * r);
            let n = ((t1 - t0) * SAMPLES_PER_PX) as usize + 1;
            profile.clear();
            let mut inside = true;
            for j in 0..n {
                let t = t0 + j as f64 / SAMPLES_PER_PX;
                let (x, y) = lp.offset(0.0, side * t);
                if !frame.contains(x as f32, y as f32, 3.0) {
                    inside = false;
                    break;
                }
                profile.push(frame.luma_bilinear(x as f32, y as f32) as f64);
            }
            if !inside {
                continue;
            }
            let j_of = |t: f64| (((t - t0) * SAMPLES_PER_PX).round() as usize).min(n - 1);
            let limb = j_of(0.8 * r)..j_of(1.0 * r) + 1;
            let Some(edge) = outline_at(&profile, limb, j_of(1.4 * r), full_scale) else {
                continue;
            };
            let t = t0 + edge / SAMPLES_PER_PX;
            let (x, y) = lp.offset(0.0, side * t);
            let (u, v) = k.pixel_to_normalized(x, y);
            pts.push([u, v]);
        }
        if let Some(p) = robust_line_plane(&mut pts) {
            planes.push(p);
        }
    }
    planes
}

/// The outline's place in a profile across the rod from inside the limb outwards (sample
/// index, fractional): the background is the samples from `j_out` on, the limb the sample in
/// `limb` (where the lens puts the outline, and just inside) that differs most from it; the
/// outline is where the profile, from the limb outwards, first comes halfway back to the
/// background, before `j_out`. `None` when the background is not uniform enough for the limb
/// to stand out.
fn outline_at(
    p: &[f64],
    limb: std::ops::Range<usize>,
    j_out: usize,
    full_scale: f64,
) -> Option<f64> {
    let far = p.get(j_out..)?;
    if far.len() < 3 || limb.is_empty() || limb.end > j_out {
        return None;
    }
    let mean = far.iter().sum::<f64>() / far.len() as f64;
    let sd = (far.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / far.len() as f64).sqrt();
    let (j_limb, level) = p[limb.clone()]
        .iter()
        .enumerate()
        .max_by(|a, b| (a.1 - mean).abs().total_cmp(&(b.1 - mean).abs()))?;
    let (j_limb, contrast) = (limb.start + j_limb, level - mean);
    // At least 1/255 of the full scale: a flat, noiseless background still needs a limb.
    if contrast.abs() < MIN_CONTRAST_SIGMAS * sd.max(full_scale / 255.0) {
        return None;
    }
    let half = |v: f64| (v - mean) / contrast - 0.5;
    for j in j_limb..j_out {
        let (a, b) = (half(p[j]), half(p[j + 1]));
        if a > 0.0 && b <= 0.0 {
            return Some(j as f64 + a / (a - b));
        }
    }
    None
}

/// The plane of the line through `pts` (normalised image points), robustly: points beyond 3
/// standard deviations of the fit dropped, a few times; with its weight, `count span^2 /
/// (12 sigma^2)` (the inverse variance of a fitted line's direction). `None` with fewer than
/// [`MIN_POINTS`] points left.
fn robust_line_plane(pts: &mut Vec<[f64; 2]>) -> Option<([f64; 3], f64)> {
    let mut sigma = 0.0;
    let mut line = None;
    for _ in 0..ROBUST_ITERATIONS {
        if pts.len() < MIN_POINTS {
            return None;
        }
        let (c, d) = fit_line_tls(pts)?;
        let dist = |q: &[f64; 2]| (q[0] - c[0]) * -d[1] + (q[1] - c[1]) * d[0];
        let mut abs: Vec<f64> = pts.iter().map(|q| dist(q).abs()).collect();
        abs.sort_by(f64::total_cmp);
        sigma = super::travel::MAD_TO_SIGMA * abs[abs.len() / 2];
        line = Some((c, d));
        if sigma.is_nan() || sigma <= 0.0 {
            break;
        }
        pts.retain(|q| dist(q).abs() <= 3.0 * sigma);
    }
    let (c, d) = line?;
    if pts.len() < MIN_POINTS || sigma <= 0.0 || !sigma.is_finite() {
        return None;
    }
    let along = |q: &[f64; 2]| (q[0] - c[0]) * d[0] + (q[1] - c[1]) * d[1];
    let (lo, hi) = pts.iter().fold((f64::MAX, f64::MIN), |(lo, hi), q| {
        (lo.min(along(q)), hi.max(along(q)))
    });
    let span = hi - lo;
    let weight = pts.len() as f64 * span * span / (12.0 * sigma * sigma);
    weight
        .is_finite()
        .then(|| (line_plane(c, d), weight))
        .filter(|p| p.1 > 0.0)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn the_outline_is_halfway_from_the_limb_to_the_background() {
        // A dark limb (20) at samples 0-9, a ramp over 10 samples, the background (45) after.
        let mut p: Vec<f64> = vec![20.0; 10];
        p.extend((1..=10).map(|i| 20.0 + 2.5 * i as f64));
        p.extend(std::iter::repeat_n(45.0, 20));
        let e = outline_at(&p, 6..12, 22, 255.0).unwrap();
        // Halfway (32.5) is 5 samples into the ramp: between samples 14 (32.5) and 15.
        assert!((e - 14.0).abs() < 1e-9, "{e}");
        // A background as bright as the limb: nothing stands out.
        let flat = vec![45.0; 40];
        assert!(outline_at(&flat, 6..12, 22, 255.0).is_none());
        // A background that is not uniform (a figure beyond): too noisy for the limb.
        let mut busy = p.clone();
        for (i, v) in busy.iter_mut().enumerate().skip(22) {
            *v = if i % 2 == 0 { 20.0 } else { 70.0 };
        }
        assert!(outline_at(&busy, 6..12, 22, 255.0).is_none());
    }

    #[test]
    fn a_line_with_outliers_keeps_its_direction() {
        let mut pts: Vec<[f64; 2]> = (0..100)
            .map(|i| {
                let t = i as f64 * 0.01;
                // A line of slope 0.1 with a tiny alternating scatter.
                let e = if i % 2 == 0 { 1e-5 } else { -1e-5 };
                [t, 0.1 * t + e]
            })
            .collect();
        for i in 0..8 {
            pts[10 * i][1] += 0.01; // figures beside the rod
        }
        let (n, w) = robust_line_plane(&mut pts).unwrap();
        assert_eq!(pts.len(), 92);
        // The plane holds the line's 3-D direction (1, 0.1, 0), to what the scatter allows
        // (about 4e-6 over this span and count).
        let dot = n[0] * 1.0 + n[1] * 0.1;
        assert!(dot.abs() < 1e-5, "{dot}");
        // Without the outliers' removal the figures turn it by about 1e-3.
        let mut all: Vec<[f64; 2]> = (0..100)
            .map(|i| [i as f64 * 0.01, 0.001 * i as f64])
            .collect();
        for i in 0..8 {
            all[10 * i][1] += 0.01;
        }
        let (c, d) = fit_line_tls(&all).unwrap();
        let plain = line_plane(c, d);
        assert!((plain[0] * 1.0 + plain[1] * 0.1).abs() > 1e-5);
        assert!(w > 0.0 && w.is_finite());
    }
}
