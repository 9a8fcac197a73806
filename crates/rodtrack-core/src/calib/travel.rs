//! The rod's geometry over its whole travel, measured at calibration (no learning needed).
//!
//! The marker is 106 mm long and a rod travels up to 350 mm; what calibration measures on the
//! marker at the reference pose must be carried to the travel's ends. A straight rod seen
//! through a pinhole maps its axis coordinate `s` to the image line's parameter `lambda` by a
//! 1-D projective map, not an affine one:
//!
//! `lambda(s) = l0 + g d / (1 + h d)`, `d = s - s_ref`,
//!
//! where `h = dZ/ds / Z` is the relative change of depth per mm along the rod (a camera pitched
//! by 2.5 degrees along 750 mm-distant rods has `h` of about 6e-5 per mm: 1 % of scale over
//! 175 mm). `h` is measured, in this order of preference:
//!
//! 1. from **known poses**: frames of the reference folder with the rod at known positions
//!    (its end stops, say); the barcode's edges in each give `(s, lambda)` pairs over the whole
//!    travel, and `(l0, g, h)` are fitted to all of them;
//! 2. from the **vanishing direction** of the camera's parallel rods: with a camera model,
//!    every rod's line is the image of a 3-D line of the same direction `D`, the direction that
//!    is orthogonal to every rod's plane through the camera centre; the rod's own `h` follows
//!    from `D`, its line and its scale `g` ([`h_from_direction`]);
//! 3. otherwise `h = 0` (the affine map of the reference pose).
//!
//! With a camera model, `(line, l0, g, h)` fix the rod's axis in 3-D in the camera frame
//! ([`RodAxis`]), and with the rod's diameter its apparent radius everywhere: the projection of
//! the cylinder's two contour lines through the lens' distortion ([`RodAxis::half_width_px`]).

use crate::camera::CameraIntrinsics;
use crate::linalg_small::{cross, normalise3};

/// The 1-D projective map from the rod's axis coordinate to the line's parameter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AlongTravel {
    /// `lambda` at the reference position.
    pub l0: f64,
    /// `d lambda / d s` at the reference position (signed: carries the marker's direction).
    pub g: f64,
    /// Relative change of depth per mm along the rod (0: affine).
    pub h: f64,
    /// The reference position, mm.
    pub s_ref_mm: f64,
}

impl AlongTravel {
    /// The line's parameter at axis coordinate `s_mm`.
    pub fn lambda(&self, s_mm: f64) -> f64 {
        let d = s_mm - self.s_ref_mm;
        self.l0 + self.g * d / (1.0 + self.h * d)
    }

    /// The axis coordinate at the line's parameter `lambda` (the inverse of [`Self::lambda`]).
    pub fn s_of(&self, lambda: f64) -> f64 {
        let y = lambda - self.l0;
        self.s_ref_mm + y / (self.g - self.h * y)
    }

    /// Depth at `s_mm` over the depth at the reference position.
    pub fn depth_ratio(&self, s_mm: f64) -> f64 {
        1.0 + self.h * (s_mm - self.s_ref_mm)
    }
}

/// Least squares `(l0, g)` of `lambda = l0 + g x` with `x = d / (1 + h d)` over `(s_mm,
/// lambda)` pairs, `d = s - s_ref`, and its RMS.
pub fn fit_at_h(points: &[(f64, f64)], s_ref: f64, h: f64) -> Option<(f64, f64, f64)> {
    let n = points.len() as f64;
    if points.len() < 2 {
        return None;
    }
    let xs: Vec<f64> = points
        .iter()
        .map(|p| {
            let d = p.0 - s_ref;
            d / (1.0 + h * d)
        })
        .collect();
    let mx = xs.iter().sum::<f64>() / n;
    let my = points.iter().map(|p| p.1).sum::<f64>() / n;
    let (mut sxx, mut sxy) = (0.0, 0.0);
    for (x, p) in xs.iter().zip(points) {
        sxx += (x - mx) * (x - mx);
        sxy += (x - mx) * (p.1 - my);
    }
    if sxx <= 0.0 {
        return None;
    }
    let g = sxy / sxx;
    let l0 = my - g * mx;
    let rss: f64 = xs
        .iter()
        .zip(points)
        .map(|(x, p)| (p.1 - l0 - g * x).powi(2))
        .sum();
    Some((l0, g, (rss / n).sqrt()))
}

/// Fits the projective map to `(s_mm, lambda)` pairs spread along the travel (the barcode's
/// edges at several known poses). `h` is searched where the map stays monotonic over the
/// points (`|h d| < 1/2`). Returns the map and the RMS of `lambda`.
pub fn fit_along(points: &[(f64, f64)], s_ref_mm: f64) -> Option<(AlongTravel, f64)> {
    let d_max = points
        .iter()
        .map(|p| (p.0 - s_ref_mm).abs())
        .fold(0.0, f64::max);
    if d_max <= 0.0 {
        return None;
    }
    let rms_at = |h: f64| fit_at_h(points, s_ref_mm, h).map_or(f64::MAX, |f| f.2);
    // A coarse scan, then golden-section search around the best cell.
    let h_max = 0.5 / d_max;
    let n = 40;
    let hs: Vec<f64> = (0..=n)
        .map(|i| -h_max + 2.0 * h_max * i as f64 / n as f64)
        .collect();
    let best = (0..hs.len()).min_by(|&a, &b| rms_at(hs[a]).total_cmp(&rms_at(hs[b])))?;
    let (mut a, mut b) = (hs[best.saturating_sub(1)], hs[(best + 1).min(hs.len() - 1)]);
    let phi = 0.5 * (5f64.sqrt() - 1.0);
    let mut c = b - phi * (b - a);
    let mut d = a + phi * (b - a);
    for _ in 0..80 {
        if rms_at(c) < rms_at(d) {
            b = d;
        } else {
            a = c;
        }
        c = b - phi * (b - a);
        d = a + phi * (b - a);
    }
    let h = 0.5 * (a + b);
    let (l0, g, rms) = fit_at_h(points, s_ref_mm, h)?;
    Some((AlongTravel { l0, g, h, s_ref_mm }, rms))
}

/// The plane through the camera centre that holds a rod's image line (normalised point `n0`,
/// unit direction `d`): its unit normal.
pub fn line_plane(n0: [f64; 2], d: [f64; 2]) -> [f64; 3] {
    let a = [n0[0], n0[1], 1.0];
    let b = [d[0], d[1], 0.0];
    normalise3(cross(a, b))
}

/// The 3-D direction common to parallel rods: the unit vector most nearly orthogonal to every
/// rod's plane (the smallest eigenvector of the planes' scatter, each plane's unit normal
/// weighed by its weight: the inverse variance of its direction), or `None` with fewer than 2
/// planes, a weight that is not finite and positive, or planes that do not fix it (all the
/// same).
pub fn common_direction(planes: &[([f64; 3], f64)]) -> Option<[f64; 3]> {
    if planes.len() < 2 || !planes.iter().all(|p| p.1.is_finite() && p.1 > 0.0) {
        return None;
    }
    let mut m = [[0.0f64; 3]; 3];
    for (p, w) in planes {
        for i in 0..3 {
            for j in 0..3 {
                m[i][j] += w * p[i] * p[j];
            }
        }
    }
    // Eigenvalues of the scatter: the smallest must stand apart from the next one, or the
    // direction is not fixed by the rods.
    let trace = m[0][0] + m[1][1] + m[2][2];
    // Inverse iteration from the planes' mean cross product.
    let mut x = normalise3(cross(planes[0].0, planes[planes.len() - 1].0));
    if !x.iter().all(|v| v.is_finite()) {
        x = [0.0, 1.0, 0.0];
    }
    let shift = 1e-12 * trace.max(1e-300);
    for _ in 0..50 {
        let a: Vec<Vec<f64>> = (0..3)
            .map(|i| {
                let mut row: Vec<f64> = (0..3)
                    .map(|j| m[i][j] + if i == j { shift } else { 0.0 })
                    .collect();
                row.push(x[i]);
                row
            })
            .collect();
        let y = crate::line::solve(a)?;
        let y = normalise3([y[0], y[1], y[2]]);
        if !y.iter().all(|v| v.is_finite()) {
            return None;
        }
        x = y;
    }
    let rayleigh: f64 = (0..3)
        .map(|i| x[i] * (0..3).map(|j| m[i][j] * x[j]).sum::<f64>())
        .sum();
    // The other two eigenvalues sum to trace - smallest; both must be well above it.
    if (trace - rayleigh) < 1e-9 * trace || !rayleigh.is_finite() {
        return None;
    }
    Some(x)
}

/// Huber's constant, in standard deviations: the residual beyond which a plane's weight falls
/// as one over its residual (95 % efficiency under normal errors).
pub const HUBER_K: f64 = 1.345;
/// The median of absolute normal residuals times this is their standard deviation.
pub const MAD_TO_SIGMA: f64 = 1.4826;

/// [`common_direction`] made robust to a rod whose line is off by more than the others' (its
/// silhouettes pulled by a figure or a shadow beside it): iteratively reweighted, each plane's
/// residual `n . D` scaled by its weight's root (the residual over its expected error) and its
/// weight cut by Huber's rule beyond [`HUBER_K`] standard deviations, the scale from the
/// median absolute scaled residual. A few iterations; `None` as [`common_direction`].
pub fn robust_common_direction(planes: &[([f64; 3], f64)]) -> Option<[f64; 3]> {
    let mut dir = common_direction(planes)?;
    let mut scaled = vec![0.0f64; planes.len()];
    let mut sorted = vec![0.0f64; planes.len()];
    let mut reweighted = planes.to_vec();
    for _ in 0..5 {
        for (z, (n, w)) in scaled.iter_mut().zip(planes) {
            *z = dot(*n, dir).abs() * w.sqrt();
        }
        sorted.copy_from_slice(&scaled);
        sorted.sort_by(f64::total_cmp);
        let sigma = MAD_TO_SIGMA * sorted[sorted.len() / 2];
        if !(sigma.is_finite() && sigma > 0.0) {
            break;
        }
        let k = HUBER_K * sigma;
        for ((rw, (_, w)), &z) in reweighted.iter_mut().zip(planes).zip(&scaled) {
            rw.1 = if z > k { w * k / z } else { *w };
        }
        dir = common_direction(&reweighted)?;
    }
    Some(dir)
}

/// A rod's `h` from the rods' common 3-D direction `dir`, its line (normalised point `n0` at the
/// reference position, unit direction `d`) and its scale `g` (`d lambda / d s` at the
/// reference, normalised units per mm).
pub fn h_from_direction(dir: [f64; 3], n0: [f64; 2], d: [f64; 2], g: f64) -> Option<f64> {
    // dir = alpha (d, 0) + beta (n0, 1) (+ off-plane residue): solve the 2x2 normal equations.
    let a = [d[0], d[1], 0.0];
    let b = [n0[0], n0[1], 1.0];
    let (aa, ab, bb) = (dot(a, a), dot(a, b), dot(b, b));
    let (ra, rb) = (dot(dir, a), dot(dir, b));
    let det = aa * bb - ab * ab;
    if det.abs() < 1e-15 {
        return None;
    }
    let alpha = (ra * bb - rb * ab) / det;
    let beta = (rb * aa - ra * ab) / det;
    if alpha.abs() < 1e-9 {
        return None;
    }
    Some(g * beta / alpha)
}

/// A rod's axis in 3-D, in the camera frame (mm; only ratios matter to the image, so the
/// scale is that of the normalised coordinates times the depth): `P(s) = p0 + (s - s_ref) u`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RodAxis {
    /// The axis at the reference position, camera frame.
    pub p0: [f64; 3],
    /// Unit direction of increasing `s`, camera frame.
    pub u: [f64; 3],
    /// The reference position, mm.
    pub s_ref_mm: f64,
}

impl RodAxis {
    /// The axis whose image is the line `n(lambda) = n_line + lambda d` (normalised) with
    /// `lambda(s)` given by `along`. Depth is in mm: `g` is normalised units per mm.
    pub fn new(n_line: [f64; 2], d: [f64; 2], along: &AlongTravel) -> Option<RodAxis> {
        let n0 = [n_line[0] + along.l0 * d[0], n_line[1] + along.l0 * d[1]];
        let (g, h) = (along.g, along.h);
        let q = g * g + h * h * (1.0 + n0[0] * n0[0] + n0[1] * n0[1]) + 2.0 * g * h * dot2(d, n0);
        if q <= 0.0 || !q.is_finite() {
            return None;
        }
        let z0 = 1.0 / q.sqrt();
        let (alpha, beta) = (g * z0, h * z0);
        Some(RodAxis {
            p0: [z0 * n0[0], z0 * n0[1], z0],
            u: [
                alpha * d[0] + beta * n0[0],
                alpha * d[1] + beta * n0[1],
                beta,
            ],
            s_ref_mm: along.s_ref_mm,
        })
    }

    /// The axis point at `s_mm`.
    pub fn at(&self, s_mm: f64) -> [f64; 3] {
        let d = s_mm - self.s_ref_mm;
        [
            self.p0[0] + d * self.u[0],
            self.p0[1] + d * self.u[1],
            self.p0[2] + d * self.u[2],
        ]
    }

    /// The cylinder's own perspective `r / D` at `s_mm`: its radius `radius_mm` over the
    /// distance from the camera centre to the axis (the same all along the axis only when the
    /// axis is square to the line of sight; the reference's value serves the marker). A
    /// surface line at angle `t` from the one facing the camera is seen across the rod at
    /// `R0 sin t / (1 - (r / D) cos t)`: the near side of the rod looks wider than the far.
    pub fn perspective(&self, s_mm: f64, radius_mm: f64) -> Option<f64> {
        let q = self.at(s_mm);
        let qu = dot(q, self.u);
        let w = [
            q[0] - qu * self.u[0],
            q[1] - qu * self.u[1],
            q[2] - qu * self.u[2],
        ];
        let dist = dot(w, w).sqrt();
        (dist > radius_mm && q[2] > 0.0).then(|| radius_mm / dist)
    }

    /// The apparent half width, px, of a cylinder of radius `radius_mm` about the axis at
    /// `s_mm`, across the image line (normal `normal_px`, unit, in pixels): the two contour
    /// lines' points projected through the lens.
    pub fn half_width_px(
        &self,
        intr: &CameraIntrinsics,
        s_mm: f64,
        radius_mm: f64,
        normal_px: [f64; 2],
    ) -> Option<f64> {
        let q = self.at(s_mm);
        // From the axis towards the camera centre, across the axis.
        let qu = dot(q, self.u);
        let w = [
            -q[0] + qu * self.u[0],
            -q[1] + qu * self.u[1],
            -q[2] + qu * self.u[2],
        ];
        let rho = dot(w, w).sqrt();
        if rho <= radius_mm || q[2] <= 0.0 {
            return None;
        }
        let wh = [w[0] / rho, w[1] / rho, w[2] / rho];
        let vh = cross(self.u, wh);
        let ca = radius_mm / rho;
        let sa = (1.0 - ca * ca).sqrt();
        let mut px = [[0.0f64; 2]; 2];
        for (k, side) in [1.0f64, -1.0].into_iter().enumerate() {
            let t = [
                q[0] + radius_mm * (ca * wh[0] + side * sa * vh[0]),
                q[1] + radius_mm * (ca * wh[1] + side * sa * vh[1]),
                q[2] + radius_mm * (ca * wh[2] + side * sa * vh[2]),
            ];
            if t[2] <= 0.0 {
                return None;
            }
            let (x, y) = intr.normalized_to_pixel(t[0] / t[2], t[1] / t[2]);
            px[k] = [x, y];
        }
        let dx = px[0][0] - px[1][0];
        let dy = px[0][1] - px[1][1];
        Some(0.5 * (dx * normal_px[0] + dy * normal_px[1]).abs())
    }
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn dot2(a: [f64; 2], b: [f64; 2]) -> f64 {
    a[0] * b[0] + a[1] * b[1]
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn intr() -> CameraIntrinsics {
        CameraIntrinsics::from_opencv(
            [[1150.0, 0.0, 720.0], [0.0, 1150.0, 540.0], [0.0, 0.0, 1.0]],
            &[-0.25, 0.08, 0.0, 0.0, 0.0],
        )
        .unwrap()
    }

    /// A camera pitched along rods 750 mm away: the rods' image lines, scale and depth.
    fn rods(pitch_deg: f64) -> Vec<([f64; 3], [f64; 3])> {
        let p = pitch_deg.to_radians();
        let u = [0.0, p.cos(), p.sin()];
        (-3..=3)
            .map(|k| ([150.0 * k as f64 + 20.0, -30.0, 750.0], u))
            .collect()
    }

    fn project(p: [f64; 3]) -> [f64; 2] {
        [p[0] / p[2], p[1] / p[2]]
    }

    #[test]
    fn the_projective_map_fits_a_pitched_rod_and_inverts() {
        let (p0, u) = rods(2.5)[2];
        // lambda along the image line through the projections of s = 0 and s = 1.
        let n0 = project(p0);
        let n1 = project([p0[0] + u[0], p0[1] + u[1], p0[2] + u[2]]);
        let dl = [n1[0] - n0[0], n1[1] - n0[1]];
        let len = dl[0].hypot(dl[1]);
        let d = [dl[0] / len, dl[1] / len];
        let pts: Vec<(f64, f64)> = (-90..=90)
            .step_by(3)
            .map(|s| {
                let s = s as f64 * 2.0;
                let n = project([p0[0] + s * u[0], p0[1] + s * u[1], p0[2] + s * u[2]]);
                (s, (n[0] - n0[0]) * d[0] + (n[1] - n0[1]) * d[1])
            })
            .collect();
        let (a, rms) = fit_along(&pts, 0.0).unwrap();
        assert!(rms < 1e-12, "rms {rms}");
        // h = u_z / z0.
        let h_true = u[2] / p0[2];
        assert!((a.h - h_true).abs() < 1e-9, "h {} vs {h_true}", a.h);
        for &(s, l) in &pts {
            assert!((a.s_of(l) - s).abs() < 1e-6);
        }
        // The affine map is off by millimetres at the ends; this one is not.
        let affine = fit_at_h(&pts, 0.0, 0.0).unwrap();
        let g0 = affine.1;
        let worst = pts
            .iter()
            .map(|&(s, l)| ((l - affine.0) / g0 - s).abs())
            .fold(0.0, f64::max);
        assert!(worst > 0.5, "affine worst {worst} mm");
        // The 3-D axis rebuilt from the fitted map has the true direction.
        let axis = RodAxis::new(n0, d, &a).unwrap();
        let z = axis.p0[2];
        for i in 0..3 {
            assert!((axis.u[i] - u[i]).abs() < 1e-6, "u {:?} vs {u:?}", axis.u);
            assert!((axis.p0[i] / z - p0[i] / p0[2]).abs() < 1e-9);
        }
    }

    #[test]
    fn the_rods_common_direction_gives_each_rods_h() {
        let rs = rods(-3.0);
        let lines: Vec<([f64; 2], [f64; 2], f64, f64)> = rs
            .iter()
            .map(|&(p0, u)| {
                let n0 = project(p0);
                let n1 = project([p0[0] + u[0], p0[1] + u[1], p0[2] + u[2]]);
                let dl = [n1[0] - n0[0], n1[1] - n0[1]];
                let len = dl[0].hypot(dl[1]);
                // g at s = 0: the derivative of lambda.
                let e = 1e-4;
                let ne = project([p0[0] + e * u[0], p0[1] + e * u[1], p0[2] + e * u[2]]);
                let g = ((ne[0] - n0[0]).powi(2) + (ne[1] - n0[1]).powi(2)).sqrt() / e;
                (n0, [dl[0] / len, dl[1] / len], g, u[2] / p0[2])
            })
            .collect();
        let planes: Vec<([f64; 3], f64)> =
            lines.iter().map(|l| (line_plane(l.0, l.1), 1.0)).collect();
        let dir = common_direction(&planes).unwrap();
        let u = rs[0].1;
        assert!((dot(dir, u).abs() - 1.0).abs() < 1e-9, "{dir:?}");
        // A rod whose line is off (its plane turned by 10 mrad about the line's point) moves
        // the common direction by its weight's share: weighed at 1/100 of the others (a
        // direction measured over a tenth of their span), ten times less than at their weight.
        let (n0, d) = (lines[0].0, lines[0].1);
        let off = line_plane(n0, [d[0] - 0.01 * d[1], d[1] + 0.01 * d[0]]);
        let turned = |w: f64| {
            let mut p = planes.clone();
            p.push((off, w));
            let x = common_direction(&p).unwrap();
            (1.0 - dot(x, u).abs().min(1.0)).max(0.0).sqrt()
        };
        let (equal, light) = (turned(1.0), turned(0.01));
        assert!(equal > 1e-4 && light < 0.1 * equal, "{equal:e} {light:e}");
        assert!(common_direction(&[(planes[0].0, 1.0), (planes[1].0, f64::NAN)]).is_none());
        // Robust: the same off plane at the others' weight moves the plain direction by
        // `equal`; reweighted, it counts for little.
        let mut p = planes.clone();
        p.push((off, 1.0));
        let x = robust_common_direction(&p).unwrap();
        let robust = (1.0 - dot(x, u).abs().min(1.0)).max(0.0).sqrt();
        assert!(robust < 0.3 * equal, "{robust:e} {equal:e}");
        // And with no plane off it is the plain direction.
        let x = robust_common_direction(&planes).unwrap();
        assert!((dot(x, u).abs() - 1.0).abs() < 1e-9, "{x:?}");
        for l in &lines {
            let h = h_from_direction(dir, l.0, l.1, l.2).unwrap();
            assert!(
                (h - l.3).abs() < 1e-7 * l.3.abs().max(1e-6),
                "{h} vs {}",
                l.3
            );
        }
    }

    #[test]
    fn the_half_width_shrinks_with_depth() {
        let k = intr();
        let (p0, u) = rods(3.0)[4];
        let n0 = project(p0);
        let n1 = project([p0[0] + u[0], p0[1] + u[1], p0[2] + u[2]]);
        let dl = [n1[0] - n0[0], n1[1] - n0[1]];
        let len = dl[0].hypot(dl[1]);
        let d = [dl[0] / len, dl[1] / len];
        let along = AlongTravel {
            l0: 0.0,
            g: len,
            h: u[2] / p0[2],
            s_ref_mm: 0.0,
        };
        let axis = RodAxis::new(n0, d, &along).unwrap();
        let n = [-d[1], d[0]];
        let w0 = axis.half_width_px(&k, 0.0, 8.0, n).unwrap();
        let w1 = axis.half_width_px(&k, 150.0, 8.0, n).unwrap();
        // Near the image centre and undistorted: about f r / z.
        assert!((w0 - 1150.0 * 8.0 / 750.0).abs() < 0.6, "{w0}");
        // The rod goes away from the camera (u_z > 0): narrower.
        assert!(w1 < w0 * (1.0 - 0.5 * 150.0 * along.h), "{w0} {w1}");
    }
}
