//! The OpenCV camera model: pinhole intrinsics with Brown-Conrady distortion
//! `(k1, k2, p1, p2, k3)`, and an optional pose.
//!
//! Conventions are OpenCV's: camera `x` right, `y` down, `z` forward; normalised coordinates
//! `(x/z, y/z)`; pixel `(u, v) = (fx x_d + cx, fy y_d + cy)` with pixel centres at integers.

use crate::CoreError;
use serde::{Deserialize, Serialize};

/// Intrinsics and distortion as OpenCV's `calibrateCamera` gives them.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CameraIntrinsics {
    /// Focal length in x, px.
    pub fx: f64,
    /// Focal length in y, px.
    pub fy: f64,
    /// Principal point x, px.
    pub cx: f64,
    /// Principal point y, px.
    pub cy: f64,
    /// Radial distortion k1.
    pub k1: f64,
    /// Radial distortion k2.
    pub k2: f64,
    /// Tangential distortion p1.
    pub p1: f64,
    /// Tangential distortion p2.
    pub p2: f64,
    /// Radial distortion k3.
    pub k3: f64,
}

impl CameraIntrinsics {
    /// From OpenCV's camera matrix and distortion vector (4, 5, 8, 12 or 14 coefficients; only
    /// the first five are used, and the rest must be zero).
    pub fn from_opencv(camera_matrix: [[f64; 3]; 3], dist: &[f64]) -> Result<Self, CoreError> {
        let bad = |field: &'static str, reason: String| CoreError::Camera { field, reason };
        let k = camera_matrix;
        if !k.iter().flatten().all(|v| v.is_finite()) {
            return Err(bad("camera_matrix", "holds a non-finite number".into()));
        }
        if k[0][0] <= 0.0 || k[1][1] <= 0.0 {
            return Err(bad(
                "camera_matrix",
                format!(
                    "focal lengths must be positive, got fx={} fy={}",
                    k[0][0], k[1][1]
                ),
            ));
        }
        if k[1][0] != 0.0 || k[2][0] != 0.0 || k[2][1] != 0.0 || k[2][2] != 1.0 {
            return Err(bad(
                "camera_matrix",
                "must be [[fx, s, cx], [0, fy, cy], [0, 0, 1]]".into(),
            ));
        }
        if !matches!(dist.len(), 0 | 4 | 5 | 8 | 12 | 14) {
            return Err(bad(
                "dist_coeffs",
                format!("must have 4, 5, 8, 12 or 14 entries, has {}", dist.len()),
            ));
        }
        if !dist.iter().all(|v| v.is_finite()) {
            return Err(bad("dist_coeffs", "holds a non-finite number".into()));
        }
        if dist.iter().skip(5).any(|v| *v != 0.0) {
            return Err(bad(
                "dist_coeffs",
                "only k1, k2, p1, p2, k3 are supported; the rational and thin-prism terms must be 0"
                    .into(),
            ));
        }
        let d = |i: usize| dist.get(i).copied().unwrap_or(0.0);
        Ok(CameraIntrinsics {
            fx: k[0][0],
            fy: k[1][1],
            cx: k[0][2],
            cy: k[1][2],
            k1: d(0),
            k2: d(1),
            p1: d(2),
            p2: d(3),
            k3: d(4),
        })
    }

    /// OpenCV's camera matrix.
    pub fn camera_matrix(&self) -> [[f64; 3]; 3] {
        [
            [self.fx, 0.0, self.cx],
            [0.0, self.fy, self.cy],
            [0.0, 0.0, 1.0],
        ]
    }

    /// OpenCV's distortion vector `(k1, k2, p1, p2, k3)`.
    pub fn dist_coeffs(&self) -> [f64; 5] {
        [self.k1, self.k2, self.p1, self.p2, self.k3]
    }

    /// Applies distortion to a normalised point.
    pub fn distort(&self, x: f64, y: f64) -> (f64, f64) {
        let r2 = x * x + y * y;
        let radial = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3));
        let xd = x * radial + 2.0 * self.p1 * x * y + self.p2 * (r2 + 2.0 * x * x);
        let yd = y * radial + self.p1 * (r2 + 2.0 * y * y) + 2.0 * self.p2 * x * y;
        (xd, yd)
    }

    /// Normalised (undistorted) point to pixel.
    pub fn normalized_to_pixel(&self, x: f64, y: f64) -> (f64, f64) {
        let (xd, yd) = self.distort(x, y);
        (self.fx * xd + self.cx, self.fy * yd + self.cy)
    }

    /// Pixel to normalised (undistorted) point, by Newton iteration on the distortion model
    /// (more accurate than OpenCV's fixed-point `undistortPoints` under strong distortion).
    pub fn pixel_to_normalized(&self, u: f64, v: f64) -> (f64, f64) {
        let xd = (u - self.cx) / self.fx;
        let yd = (v - self.cy) / self.fy;
        // Start from one fixed-point step (the radial factor at the distorted point), then
        // Newton with the model's own Jacobian: three or four steps to 1e-13.
        let r2 = xd * xd + yd * yd;
        let radial = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3));
        let (mut x, mut y) = if radial > 0.2 {
            (xd / radial, yd / radial)
        } else {
            (xd, yd)
        };
        for _ in 0..30 {
            let (fx, fy, j) = self.distort_jacobian(x, y);
            let (ex, ey) = (fx - xd, fy - yd);
            if ex.abs() < 1e-13 && ey.abs() < 1e-13 {
                break;
            }
            let [[j11, j12], [j21, j22]] = j;
            let det = j11 * j22 - j12 * j21;
            if det.abs() < 1e-12 {
                break;
            }
            x -= (j22 * ex - j12 * ey) / det;
            y -= (-j21 * ex + j11 * ey) / det;
        }
        (x, y)
    }

    /// [`CameraIntrinsics::distort`] and its Jacobian `d(xd, yd) / d(x, y)` at `(x, y)`.
    pub fn distort_jacobian(&self, x: f64, y: f64) -> (f64, f64, [[f64; 2]; 2]) {
        let r2 = x * x + y * y;
        let radial = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3));
        // d radial / d r2.
        let dr = self.k1 + r2 * (2.0 * self.k2 + 3.0 * r2 * self.k3);
        let xd = x * radial + 2.0 * self.p1 * x * y + self.p2 * (r2 + 2.0 * x * x);
        let yd = y * radial + self.p1 * (r2 + 2.0 * y * y) + 2.0 * self.p2 * x * y;
        let j11 = radial + 2.0 * x * x * dr + 2.0 * self.p1 * y + 6.0 * self.p2 * x;
        let j12 = 2.0 * x * y * dr + 2.0 * self.p1 * x + 2.0 * self.p2 * y;
        let j21 = 2.0 * x * y * dr + 2.0 * self.p1 * x + 2.0 * self.p2 * y;
        let j22 = radial + 2.0 * y * y * dr + 6.0 * self.p1 * y + 2.0 * self.p2 * x;
        (xd, yd, [[j11, j12], [j21, j22]])
    }
}

/// A rigid transform from world to camera coordinates: `X_c = R X_w + t`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Pose {
    /// Rotation, row major.
    pub rotation: [[f64; 3]; 3],
    /// Translation, mm.
    pub translation_mm: [f64; 3],
}

impl Pose {
    /// A camera at `position_mm` (world) looking straight down (world `-z`), with image `x`
    /// along world `+x` and image `y` along world `-y`, then turned by `yaw_rad` about its
    /// viewing axis and tilted by `pitch_rad` about its own `x` axis.
    pub fn looking_down(position_mm: [f64; 3], yaw_rad: f64, pitch_rad: f64) -> Pose {
        // Base: rotation of 180 deg about x: x_c = x_w, y_c = -y_w, z_c = -z_w.
        let base = [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]];
        let (sy, cy) = yaw_rad.sin_cos();
        let yaw = [[cy, -sy, 0.0], [sy, cy, 0.0], [0.0, 0.0, 1.0]];
        let (sp, cp) = pitch_rad.sin_cos();
        let pitch = [[1.0, 0.0, 0.0], [0.0, cp, -sp], [0.0, sp, cp]];
        let r = mat_mul(&pitch, &mat_mul(&yaw, &base));
        let t = mat_vec(&r, &position_mm);
        Pose {
            rotation: r,
            translation_mm: [-t[0], -t[1], -t[2]],
        }
    }

    /// World point to camera coordinates.
    pub fn to_camera(&self, p: [f64; 3]) -> [f64; 3] {
        let r = mat_vec(&self.rotation, &p);
        [
            r[0] + self.translation_mm[0],
            r[1] + self.translation_mm[1],
            r[2] + self.translation_mm[2],
        ]
    }

    /// Camera centre in world coordinates.
    pub fn centre_world(&self) -> [f64; 3] {
        // C = -R^T t
        let rt = transpose(&self.rotation);
        let c = mat_vec(&rt, &self.translation_mm);
        [-c[0], -c[1], -c[2]]
    }

    /// Camera direction (camera coordinates) to world direction.
    pub fn dir_to_world(&self, d: [f64; 3]) -> [f64; 3] {
        mat_vec(&transpose(&self.rotation), &d)
    }
}

/// Intrinsics plus pose: a full camera.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Camera {
    /// Intrinsics and distortion.
    pub intrinsics: CameraIntrinsics,
    /// World to camera.
    pub pose: Pose,
    /// Image width, px.
    pub width: usize,
    /// Image height, px.
    pub height: usize,
}

impl Camera {
    /// Projects a world point to a pixel; `None` behind the camera.
    pub fn project(&self, p_world: [f64; 3]) -> Option<(f64, f64)> {
        let c = self.pose.to_camera(p_world);
        if c[2] <= 1e-9 {
            return None;
        }
        Some(
            self.intrinsics
                .normalized_to_pixel(c[0] / c[2], c[1] / c[2]),
        )
    }

    /// The world-space ray through a pixel: (origin, unit direction).
    pub fn ray(&self, u: f64, v: f64) -> ([f64; 3], [f64; 3]) {
        let (x, y) = self.intrinsics.pixel_to_normalized(u, v);
        let d = self.pose.dir_to_world([x, y, 1.0]);
        let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        (self.pose.centre_world(), [d[0] / n, d[1] / n, d[2] / n])
    }
}

fn mat_mul(a: &[[f64; 3]; 3], b: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let mut r = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            r[i][j] = (0..3).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    r
}

fn mat_vec(a: &[[f64; 3]; 3], v: &[f64; 3]) -> [f64; 3] {
    [
        a[0][0] * v[0] + a[0][1] * v[1] + a[0][2] * v[2],
        a[1][0] * v[0] + a[1][1] * v[1] + a[1][2] * v[2],
        a[2][0] * v[0] + a[2][1] * v[1] + a[2][2] * v[2],
    ]
}

fn transpose(a: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let mut r = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            r[i][j] = a[j][i];
        }
    }
    r
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn strong() -> CameraIntrinsics {
        CameraIntrinsics::from_opencv(
            [[1078.0, 0.0, 719.5], [0.0, 1078.0, 539.5], [0.0, 0.0, 1.0]],
            &[-0.25, 0.08, 0.001, -0.0005, -0.01],
        )
        .unwrap()
    }

    proptest! {
        #[test]
        fn undistort_inverts_distort(u in 0.0f64..1440.0, v in 0.0f64..1080.0) {
            let k = strong();
            let (x, y) = k.pixel_to_normalized(u, v);
            let (u2, v2) = k.normalized_to_pixel(x, y);
            prop_assert!((u - u2).abs() < 1e-6 && (v - v2).abs() < 1e-6);
        }
    }

    /// The plain inverse: Newton from the distorted point with a numerical Jacobian.
    fn undistort_reference(k: &CameraIntrinsics, u: f64, v: f64) -> (f64, f64) {
        let (xd, yd) = ((u - k.cx) / k.fx, (v - k.cy) / k.fy);
        let (mut x, mut y) = (xd, yd);
        for _ in 0..100 {
            let (fx, fy) = k.distort(x, y);
            let (ex, ey) = (fx - xd, fy - yd);
            let h = 1e-7;
            let (ax, ay) = k.distort(x + h, y);
            let (bx, by) = k.distort(x, y + h);
            let (j11, j21) = ((ax - fx) / h, (ay - fy) / h);
            let (j12, j22) = ((bx - fx) / h, (by - fy) / h);
            let det = j11 * j22 - j12 * j21;
            x -= (j22 * ex - j12 * ey) / det;
            y -= (-j21 * ex + j11 * ey) / det;
        }
        (x, y)
    }

    proptest! {
        #[test]
        fn the_jacobian_is_the_distortions_derivative(x in -0.8f64..0.8, y in -0.6f64..0.6) {
            let k = strong();
            let (xd, yd, j) = k.distort_jacobian(x, y);
            prop_assert_eq!((xd, yd), k.distort(x, y));
            let h = 1e-6;
            let (ax, ay) = k.distort(x + h, y);
            let (bx, by) = k.distort(x, y + h);
            let (cx, cy) = k.distort(x - h, y);
            let (dx, dy) = k.distort(x, y - h);
            let num = [[(ax - cx) / (2.0 * h), (bx - dx) / (2.0 * h)], [(ay - cy) / (2.0 * h), (by - dy) / (2.0 * h)]];
            for i in 0..2 {
                for c in 0..2 {
                    prop_assert!((j[i][c] - num[i][c]).abs() < 1e-7, "{:?} {:?}", j, num);
                }
            }
        }

        #[test]
        fn undistort_matches_the_plain_newton(u in 0.0f64..1440.0, v in 0.0f64..1080.0) {
            let k = strong();
            let (x, y) = k.pixel_to_normalized(u, v);
            let (xr, yr) = undistort_reference(&k, u, v);
            prop_assert!((x - xr).abs() < 1e-12 && (y - yr).abs() < 1e-12);
        }
    }

    #[test]
    fn looking_down_projects_as_documented() {
        let cam = Camera {
            intrinsics: CameraIntrinsics::from_opencv(
                [[1000.0, 0.0, 720.0], [0.0, 1000.0, 540.0], [0.0, 0.0, 1.0]],
                &[],
            )
            .unwrap(),
            pose: Pose::looking_down([500.0, 300.0, 830.0], 0.0, 0.0),
            width: 1440,
            height: 1080,
        };
        let (u, v) = cam.project([500.0, 300.0, 80.0]).unwrap();
        assert!((u - 720.0).abs() < 1e-9 && (v - 540.0).abs() < 1e-9);
        // +x world -> +u; +y world -> -v; 750 mm away, 1000 px focal: 75 mm -> 100 px.
        let (u, v) = cam.project([575.0, 375.0, 80.0]).unwrap();
        assert!(
            (u - 820.0).abs() < 1e-9 && (v - 440.0).abs() < 1e-9,
            "{u} {v}"
        );
        let (o, d) = cam.ray(820.0, 440.0);
        let s = (80.0 - o[2]) / d[2];
        assert!((o[0] + s * d[0] - 575.0).abs() < 1e-6);
        assert!((o[1] + s * d[1] - 375.0).abs() < 1e-6);
    }

    #[test]
    fn rejects_bad_opencv_input() {
        let k = [[1000.0, 0.0, 720.0], [0.0, 1000.0, 540.0], [0.0, 0.0, 1.0]];
        assert!(CameraIntrinsics::from_opencv(k, &[0.1, 0.0, 0.0]).is_err());
        assert!(
            CameraIntrinsics::from_opencv(k, &[0.1, 0.0, 0.0, 0.0, 0.0, 0.3, 0.0, 0.0]).is_err()
        );
        let mut k2 = k;
        k2[0][0] = -1.0;
        assert!(CameraIntrinsics::from_opencv(k2, &[]).is_err());
    }
}
