//! Line sampling: where a rod's 1-D line lies in the image.
//!
//! - [`PaperLine`]: the paper's trajectory `x(t) = a t^2 + b t + c` with the projection
//!   compensation of eqs. (1)-(2), nearest pixel. Eq. (2) is written as a forward map from image
//!   row `t` to line index `y'`; where `tan` stretches, consecutive rows skip line indices and
//!   would leave them empty. We build the inverse (the paper's own `g_m(y')`): for every `y'` in
//!   `0..h0` the row `t = h0/2 + (h0/alpha) atan((2 y'/h0 - 1) tan(alpha/2))`, rounded. Every
//!   line sample is then filled, and where the forward map is one-to-one both agree.
//! - [`Knots`]: rodtrack's line at uniform physical spacing: a table of image points every
//!   `step_mm` along the rod's axis, interpolated linearly between knots (the path's curvature
//!   makes that exact to far below 0.01 px at a few mm spacing), with the rod's apparent radius.
//! - [`CurveModel`]: the path fitted at calibration, from a camera model (a straight line in
//!   undistorted normalised coordinates) or as an image-space polynomial.

use crate::camera::CameraIntrinsics;
use serde::{Deserialize, Serialize};

/// The paper's line: for each line index `y'`, the pixel it reads.
#[derive(Debug, Clone)]
pub struct PaperLine {
    /// Pixel (x, y) per line index, nearest pixel.
    pub pixels: Vec<(i32, i32)>,
    /// Image row `t` per line index (not rounded).
    pub rows: Vec<f64>,
}

impl PaperLine {
    /// Builds the line for trajectory `x(t) = abc[0] t^2 + abc[1] t + abc[2]`, view angle
    /// `alpha_rad` and image height `h0`.
    pub fn new(abc: [f64; 3], alpha_rad: f64, h0: usize) -> PaperLine {
        let h = h0 as f64;
        let ta = (alpha_rad * 0.5).tan();
        let mut pixels = Vec::with_capacity(h0);
        let mut rows = Vec::with_capacity(h0);
        for yp in 0..h0 {
            let q = (2.0 * yp as f64 / h - 1.0) * ta;
            let t = h * 0.5 + h / alpha_rad * q.atan();
            let t = t.clamp(0.0, h - 1.0);
            let tr = t.round();
            let x = abc[0] * tr * tr + abc[1] * tr + abc[2];
            pixels.push((x.round() as i32, tr as i32));
            rows.push(t);
        }
        PaperLine { pixels, rows }
    }

    /// The paper's forward map, eq. (2): line index of image row `t`.
    pub fn forward_index(t: f64, alpha_rad: f64, h0: usize) -> f64 {
        let h = h0 as f64;
        let f = (t - h * 0.5) / h * alpha_rad;
        (h * 0.5 * (1.0 + f.tan() / (alpha_rad * 0.5).tan())).floor()
    }
}

/// A rod's line at uniform physical spacing (rodtrack's enhanced mode).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Knots {
    /// Axis coordinate of the first knot, mm (same frame as `position_mm`: a point `u` mm into
    /// the marker lies at `position_mm + u`).
    pub s0_mm: f64,
    /// Spacing of knots, mm.
    pub step_mm: f64,
    /// Image x of each knot, px.
    pub x_px: Vec<f64>,
    /// Image y of each knot, px.
    pub y_px: Vec<f64>,
    /// Apparent rod radius at each knot, px.
    pub radius_px: Vec<f64>,
}

/// A point of the line with its local frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinePoint {
    /// Image x, px.
    pub x: f64,
    /// Image y, px.
    pub y: f64,
    /// Unit tangent (direction of increasing s) in the image.
    pub tx: f64,
    /// Unit tangent, y.
    pub ty: f64,
    /// Apparent radius, px.
    pub radius_px: f64,
    /// Image length of one mm along the axis here, px.
    pub px_per_mm: f64,
}

impl LinePoint {
    /// The point `across` px to the side (along the normal `(-ty, tx)`) and `along` px along.
    #[inline]
    pub fn offset(&self, along: f64, across: f64) -> (f64, f64) {
        (
            self.x + self.tx * along - self.ty * across,
            self.y + self.ty * along + self.tx * across,
        )
    }
}

impl Knots {
    /// Number of knots.
    pub fn len(&self) -> usize {
        self.x_px.len()
    }
    /// True when there are no knots.
    pub fn is_empty(&self) -> bool {
        self.x_px.is_empty()
    }
    /// Axis coordinate of the last knot, mm.
    pub fn s_end_mm(&self) -> f64 {
        self.s0_mm + self.step_mm * (self.len().saturating_sub(1)) as f64
    }

    /// The line at axis coordinate `s_mm` (clamped to the knots' range).
    #[inline]
    pub fn at(&self, s_mm: f64) -> LinePoint {
        let n = self.len();
        let g = ((s_mm - self.s0_mm) / self.step_mm).clamp(0.0, (n - 1) as f64);
        let i = (g.floor() as usize).min(n - 2);
        let f = g - i as f64;
        let x = self.x_px[i] + (self.x_px[i + 1] - self.x_px[i]) * f;
        let y = self.y_px[i] + (self.y_px[i + 1] - self.y_px[i]) * f;
        let r = self.radius_px[i] + (self.radius_px[i + 1] - self.radius_px[i]) * f;
        let dx = self.x_px[i + 1] - self.x_px[i];
        let dy = self.y_px[i + 1] - self.y_px[i];
        let len = (dx * dx + dy * dy).sqrt().max(1e-12);
        LinePoint {
            x,
            y,
            tx: dx / len,
            ty: dy / len,
            radius_px: r,
            px_per_mm: len / self.step_mm,
        }
    }
}

/// [`Knots`] with each segment's direction and scale computed once, for the hot path: `at`
/// is then two multiply-adds per coordinate. Same results as [`Knots::at`].
#[derive(Debug, Clone)]
pub struct PreparedKnots {
    s0_mm: f64,
    inv_step: f64,
    /// Per knot: x, y, radius, and the segment to the next knot: tx, ty, px per mm.
    rows: Vec<[f64; 6]>,
}

impl PreparedKnots {
    /// Prepares knots (at least 2).
    pub fn new(k: &Knots) -> PreparedKnots {
        let n = k.len();
        let rows = (0..n)
            .map(|i| {
                let j = (i + 1).min(n - 1);
                let i0 = if j == i { i.saturating_sub(1) } else { i };
                let dx = k.x_px[j] - k.x_px[i0];
                let dy = k.y_px[j] - k.y_px[i0];
                let len = (dx * dx + dy * dy).sqrt().max(1e-12);
                [
                    k.x_px[i],
                    k.y_px[i],
                    k.radius_px[i],
                    dx / len,
                    dy / len,
                    len / k.step_mm,
                ]
            })
            .collect();
        PreparedKnots {
            s0_mm: k.s0_mm,
            inv_step: 1.0 / k.step_mm,
            rows,
        }
    }

    /// The line at axis coordinate `s_mm` (clamped to the knots' range).
    #[inline]
    pub fn at(&self, s_mm: f64) -> LinePoint {
        let n = self.rows.len();
        let g = ((s_mm - self.s0_mm) * self.inv_step).clamp(0.0, (n - 1) as f64);
        // Through u32: one instruction each way (the knots are far fewer than 2^32).
        let i = (g as u32).min(n as u32 - 2);
        let f = g - i as f64;
        let i = i as usize;
        let a = &self.rows[i];
        let b = &self.rows[i + 1];
        LinePoint {
            x: a[0] + (b[0] - a[0]) * f,
            y: a[1] + (b[1] - a[1]) * f,
            tx: a[3],
            ty: a[4],
            radius_px: a[2] + (b[2] - a[2]) * f,
            px_per_mm: a[5],
        }
    }
}

/// The rod's path as fitted at calibration, with a raw parameter `lambda` along it.
#[derive(Debug, Clone, PartialEq)]
pub enum CurveModel {
    /// A straight line in undistorted normalised coordinates: `n(lambda) = n0 + lambda d`;
    /// `lambda` is in normalised units.
    Camera {
        /// Intrinsics and distortion.
        intrinsics: CameraIntrinsics,
        /// A point of the line, normalised coordinates.
        n0: [f64; 2],
        /// Unit direction, normalised coordinates.
        d: [f64; 2],
    },
    /// An image-space polynomial `x(t)` (or `y(t)` when `along_x`), `lambda = t` in px.
    Poly {
        /// Coefficients, lowest degree first.
        coeffs: Vec<f64>,
        /// True when the parameter is image x (rods along image rows).
        along_x: bool,
    },
}

impl CurveModel {
    /// Fits the path to clicked points (at least 3). With a camera model the points are
    /// undistorted and a straight line is fitted (total least squares); without one, a
    /// polynomial of degree 2 (3 or 4 points) or 3 (5 or more).
    pub fn fit(points: &[[f64; 2]], intrinsics: Option<&CameraIntrinsics>) -> Option<CurveModel> {
        if points.len() < 2 {
            return None;
        }
        if let Some(k) = intrinsics {
            let n: Vec<[f64; 2]> = points
                .iter()
                .map(|p| {
                    let (x, y) = k.pixel_to_normalized(p[0], p[1]);
                    [x, y]
                })
                .collect();
            let (c, d) = fit_line_tls(&n)?;
            return Some(CurveModel::Camera {
                intrinsics: *k,
                n0: c,
                d,
            });
        }
        let (xs, ys): (Vec<f64>, Vec<f64>) = points.iter().map(|p| (p[0], p[1])).unzip();
        let spread = |v: &[f64]| {
            v.iter().cloned().fold(f64::MIN, f64::max) - v.iter().cloned().fold(f64::MAX, f64::min)
        };
        let along_x = spread(&xs) > spread(&ys);
        let (t, v) = if along_x { (&xs, &ys) } else { (&ys, &xs) };
        let degree = if points.len() >= 5 {
            3
        } else {
            2.min(points.len() - 1)
        };
        let coeffs = polyfit(t, v, degree)?;
        Some(CurveModel::Poly { coeffs, along_x })
    }

    /// Image point at `lambda`.
    pub fn point(&self, lambda: f64) -> (f64, f64) {
        match self {
            CurveModel::Camera { intrinsics, n0, d } => {
                intrinsics.normalized_to_pixel(n0[0] + lambda * d[0], n0[1] + lambda * d[1])
            }
            CurveModel::Poly { coeffs, along_x } => {
                let v = polyval(coeffs, lambda);
                if *along_x {
                    (lambda, v)
                } else {
                    (v, lambda)
                }
            }
        }
    }

    /// The `lambda` of the point of the curve nearest to an image point (for ordering and for
    /// residuals).
    pub fn project(&self, p: [f64; 2]) -> f64 {
        let mut lam = match self {
            CurveModel::Camera { intrinsics, n0, d } => {
                let (x, y) = intrinsics.pixel_to_normalized(p[0], p[1]);
                (x - n0[0]) * d[0] + (y - n0[1]) * d[1]
            }
            CurveModel::Poly { along_x, .. } => {
                if *along_x {
                    p[0]
                } else {
                    p[1]
                }
            }
        };
        // Newton refinement on the squared distance.
        for _ in 0..10 {
            let h = self.lambda_per_px(lam) * 0.5;
            let (x0, y0) = self.point(lam - h);
            let (x1, y1) = self.point(lam + h);
            let (xm, ym) = self.point(lam);
            let (dx, dy) = ((x1 - x0) / (2.0 * h), (y1 - y0) / (2.0 * h));
            let g = (xm - p[0]) * dx + (ym - p[1]) * dy;
            let hh = dx * dx + dy * dy;
            if hh < 1e-18 {
                break;
            }
            lam -= g / hh;
        }
        lam
    }

    /// Distance of an image point from the curve, px.
    pub fn distance(&self, p: [f64; 2]) -> f64 {
        let (x, y) = self.point(self.project(p));
        ((x - p[0]).powi(2) + (y - p[1]).powi(2)).sqrt()
    }

    /// Roughly how much `lambda` changes per image pixel along the curve (for step sizes).
    pub fn lambda_per_px(&self, lambda: f64) -> f64 {
        match self {
            CurveModel::Camera { intrinsics, .. } => {
                let _ = lambda;
                1.0 / intrinsics.fx
            }
            CurveModel::Poly { .. } => 1.0,
        }
    }

    /// The same path moved sideways by `a + b (lambda - lambda_c)`: in normalised units along
    /// the line's normal for a camera model (the line turns about `lambda_c`), in px along the
    /// polynomial's value for a polynomial. `lambda` keeps its meaning along the path (to first
    /// order), so positions measured along the old path stay valid.
    pub fn shifted(&self, a: f64, b: f64, lambda_c: f64) -> CurveModel {
        match self {
            CurveModel::Camera { intrinsics, n0, d } => {
                let p = [-d[1], d[0]];
                let c = a - b * lambda_c;
                let nd = [d[0] + b * p[0], d[1] + b * p[1]];
                let len = nd[0].hypot(nd[1]);
                CurveModel::Camera {
                    intrinsics: *intrinsics,
                    n0: [n0[0] + c * p[0], n0[1] + c * p[1]],
                    d: [nd[0] / len, nd[1] / len],
                }
            }
            CurveModel::Poly { coeffs, along_x } => {
                let mut coeffs = coeffs.clone();
                coeffs[0] += a - b * lambda_c;
                if coeffs.len() > 1 {
                    coeffs[1] += b;
                } else {
                    coeffs.push(b);
                }
                CurveModel::Poly {
                    coeffs,
                    along_x: *along_x,
                }
            }
        }
    }

    /// The same path through its point at `lambda_c`, turned to run towards the vanishing
    /// point of the 3-D direction `dir` (camera frame): the image of a line parallel to `dir`
    /// through that point. `lambda` keeps its meaning along the path (to first order). `None`
    /// for a polynomial path, or when `dir` points at the camera through that point.
    pub fn toward_vanishing(&self, dir: [f64; 3], lambda_c: f64) -> Option<CurveModel> {
        let CurveModel::Camera { intrinsics, n0, d } = self else {
            return None;
        };
        let p = [n0[0] + lambda_c * d[0], n0[1] + lambda_c * d[1]];
        // The point p + t (dir_xy - p dir_z) / ... : the image of p's ray moved along dir.
        let mut nd = [dir[0] - p[0] * dir[2], dir[1] - p[1] * dir[2]];
        let len = nd[0].hypot(nd[1]);
        if len.is_nan() || len <= 1e-9 {
            return None;
        }
        if nd[0] * d[0] + nd[1] * d[1] < 0.0 {
            nd = [-nd[0], -nd[1]];
        }
        let nd = [nd[0] / len, nd[1] / len];
        Some(CurveModel::Camera {
            intrinsics: *intrinsics,
            n0: [p[0] - lambda_c * nd[0], p[1] - lambda_c * nd[1]],
            d: nd,
        })
    }

    /// A short name for reports.
    pub fn kind(&self) -> &'static str {
        match self {
            CurveModel::Camera { .. } => "camera",
            CurveModel::Poly { .. } => "poly",
        }
    }
}

/// Total least squares line through points: (centroid, unit direction).
pub fn fit_line_tls(p: &[[f64; 2]]) -> Option<([f64; 2], [f64; 2])> {
    if p.len() < 2 {
        return None;
    }
    let n = p.len() as f64;
    let cx = p.iter().map(|q| q[0]).sum::<f64>() / n;
    let cy = p.iter().map(|q| q[1]).sum::<f64>() / n;
    let (mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0);
    for q in p {
        let (dx, dy) = (q[0] - cx, q[1] - cy);
        sxx += dx * dx;
        sxy += dx * dy;
        syy += dy * dy;
    }
    if sxx + syy < 1e-18 {
        return None;
    }
    let theta = 0.5 * (2.0 * sxy).atan2(sxx - syy);
    Some(([cx, cy], [theta.cos(), theta.sin()]))
}

/// Least-squares polynomial fit, coefficients lowest degree first. The parameter is centred
/// and scaled internally for conditioning.
pub fn polyfit(t: &[f64], v: &[f64], degree: usize) -> Option<Vec<f64>> {
    let m = degree + 1;
    if t.len() < m || t.len() != v.len() {
        return None;
    }
    // Normal equations on the raw parameter in f64 are fine for degree <= 3 at image scale when
    // solved with partial pivoting; scale t by 1/1000 to keep entries near 1.
    let s = 1e-3;
    let mut a = vec![vec![0.0f64; m + 1]; m];
    for (&ti, &vi) in t.iter().zip(v) {
        let x = ti * s;
        let mut pw = vec![1.0f64; 2 * m];
        for k in 1..2 * m {
            pw[k] = pw[k - 1] * x;
        }
        for r in 0..m {
            for c in 0..m {
                a[r][c] += pw[r + c];
            }
            a[r][m] += pw[r] * vi;
        }
    }
    let sol = solve(a)?;
    Some(
        sol.iter()
            .enumerate()
            .map(|(k, c)| c * s.powi(k as i32))
            .collect(),
    )
}

/// Evaluates a polynomial, coefficients lowest degree first.
pub fn polyval(c: &[f64], t: f64) -> f64 {
    c.iter().rev().fold(0.0, |acc, &k| acc * t + k)
}

/// Solves an augmented linear system by Gaussian elimination with partial pivoting.
pub fn solve(mut a: Vec<Vec<f64>>) -> Option<Vec<f64>> {
    let m = a.len();
    for col in 0..m {
        let piv = (col..m).max_by(|&i, &j| a[i][col].abs().total_cmp(&a[j][col].abs()))?;
        if a[piv][col].abs() < 1e-300 {
            return None;
        }
        a.swap(col, piv);
        let pivot_row = a[col].clone();
        for (r, row) in a.iter_mut().enumerate() {
            if r != col {
                let f = row[col] / pivot_row[col];
                for (x, p) in row.iter_mut().zip(&pivot_row).skip(col) {
                    *x -= f * p;
                }
            }
        }
    }
    Some((0..m).map(|i| a[i][m] / a[i][i]).collect())
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn paper_line_fills_every_sample_and_agrees_with_forward_map() {
        let alpha = 53.2f64.to_radians();
        let line = PaperLine::new([1e-5, 0.01, 300.0], alpha, 1080);
        assert_eq!(line.pixels.len(), 1080);
        // Monotonic rows, no gaps larger than the stretch allows.
        for w in line.rows.windows(2) {
            assert!(w[1] >= w[0]);
        }
        // Where the inverse picks row t, the forward map of t lands within one index.
        for (yp, &t) in line.rows.iter().enumerate().step_by(37) {
            let f = PaperLine::forward_index(t.round(), alpha, 1080);
            assert!((f - yp as f64).abs() <= 1.5, "y' {yp} t {t} forward {f}");
        }
        // The literal forward map leaves holes near the ends.
        let hit: std::collections::HashSet<i64> = (0..1080)
            .map(|t| PaperLine::forward_index(t as f64, alpha, 1080) as i64)
            .collect();
        assert!(hit.len() < 1080);
    }

    #[test]
    fn prepared_knots_equal_knots() {
        let k = Knots {
            s0_mm: -20.0,
            step_mm: 2.0,
            x_px: (0..50)
                .map(|i| 300.0 + 0.3 * i as f64 + 0.002 * (i * i) as f64)
                .collect(),
            y_px: (0..50).map(|i| 100.0 + 2.8 * i as f64).collect(),
            radius_px: (0..50).map(|i| 11.0 + 0.01 * i as f64).collect(),
        };
        let p = PreparedKnots::new(&k);
        for s in [-25.0, -20.0, -3.3, 0.0, 41.7, 77.0, 78.0, 90.0] {
            let (a, b) = (k.at(s), p.at(s));
            for (u, v) in [
                (a.x, b.x),
                (a.y, b.y),
                (a.tx, b.tx),
                (a.ty, b.ty),
                (a.radius_px, b.radius_px),
                (a.px_per_mm, b.px_per_mm),
            ] {
                assert!((u - v).abs() < 1e-9, "s {s}: {u} vs {v}");
            }
        }
    }

    #[test]
    fn polyfit_recovers_a_quadratic() {
        let t = [10.0, 400.0, 900.0, 1000.0];
        let v: Vec<f64> = t.iter().map(|x| 2e-5 * x * x - 0.03 * x + 250.0).collect();
        let c = polyfit(&t, &v, 2).unwrap();
        assert!((c[0] - 250.0).abs() < 1e-6 && (c[1] + 0.03).abs() < 1e-9);
    }

    #[test]
    fn camera_curve_passes_through_points_of_a_3d_line() {
        let k = CameraIntrinsics::from_opencv(
            [[1078.0, 0.0, 719.5], [0.0, 1078.0, 539.5], [0.0, 0.0, 1.0]],
            &[-0.25, 0.08, 0.0, 0.0, 0.0],
        )
        .unwrap();
        // A straight line in the world projects to points that lie on one camera curve.
        let pts: Vec<[f64; 2]> = [-300.0, -100.0, 50.0, 250.0]
            .iter()
            .map(|y| {
                let (u, v) = k.normalized_to_pixel(-400.0 / 750.0, y / 750.0);
                [u, v]
            })
            .collect();
        let c = CurveModel::fit(&pts[..3], Some(&k)).unwrap();
        assert!(c.distance(pts[3]) < 1e-6);
    }
}
