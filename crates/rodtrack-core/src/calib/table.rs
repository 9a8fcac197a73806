//! The table frame (SPEC section 9): the camera's pose in table millimetres from field points
//! clicked in the reference frame (the field's corners, the centre line's ends, ...), at z = 0.
//!
//! Table frame: origin at the centre of the field, `x` along the table (towards goal B), `y`
//! across it along the rods, `z` up; the field at `z = 0`. The points are undistorted with the
//! camera model, a homography from the field plane to the normalised image plane gives a first
//! pose (`H ~ [r1 r2 t]`), and a Levenberg-Marquardt refinement minimises the reprojection
//! error in pixels.

use crate::camera::{Camera, CameraIntrinsics, Pose};
use crate::linalg_small::{cross, mat_inv3, norm3, solve_dense};
use crate::CoreError;
use serde::{Deserialize, Serialize};

/// One clicked field point: where it is in the image and in the table frame.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TablePoint {
    /// Image position (with the lens's distortion), px.
    pub px: [f64; 2],
    /// Table position on the field (z = 0), mm.
    pub mm: [f64; 2],
}

/// The calibration inputs' `table`: field points clicked in the reference frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
pub struct TableInputs {
    /// At least 4 points, not all on one line.
    pub points: Vec<TablePoint>,
}

/// The calibration file's `[cameras.table]`: the camera's pose in the table frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TableCalibration {
    /// Table to camera rotation (`X_c = R X_t + t`), row major.
    pub rotation: [[f64; 3]; 3],
    /// Table to camera translation, mm.
    pub translation_mm: [f64; 3],
    /// The camera's centre in the table frame, mm (informative: `-R^T t`).
    pub camera_centre_mm: [f64; 3],
    /// The field's extent in the table frame spanned by the points: `[[x_min, y_min], [x_max,
    /// y_max]]`, mm.
    pub field_mm: [[f64; 2]; 2],
    /// Points used.
    pub points: usize,
    /// RMS reprojection error of the points, px.
    pub residual_rms_px: f64,
    /// Largest reprojection error of a point, px.
    pub residual_max_px: f64,
}

impl TableCalibration {
    /// The pose as a [`Pose`] (table to camera).
    pub fn pose(&self) -> Pose {
        Pose {
            rotation: self.rotation,
            translation_mm: self.translation_mm,
        }
    }

    /// The camera in the table frame.
    pub fn camera(&self, intrinsics: CameraIntrinsics, width: usize, height: usize) -> Camera {
        Camera {
            intrinsics,
            pose: self.pose(),
            width,
            height,
        }
    }

    /// Checks the fields (finite, a rotation, the camera above the field); `camera` names the
    /// camera in the error.
    pub fn validate(&self, camera: &str) -> Result<(), CoreError> {
        let err = |field: &str, reason: String| CoreError::CameraField {
            camera: camera.to_string(),
            field: format!("table.{field}"),
            reason,
        };
        let r = &self.rotation;
        if !r.iter().flatten().all(|v| v.is_finite()) {
            return Err(err("rotation", "holds a non-finite number".into()));
        }
        for i in 0..3 {
            for j in 0..3 {
                let d: f64 = (0..3).map(|k| r[i][k] * r[j][k]).sum();
                let want = if i == j { 1.0 } else { 0.0 };
                if (d - want).abs() > 1e-6 {
                    return Err(err(
                        "rotation",
                        format!("is not a rotation (row {i} . row {j} = {d:.9})"),
                    ));
                }
            }
        }
        if cross(r[0], r[1])
            .iter()
            .zip(r[2])
            .any(|(a, b)| (a - b).abs() > 1e-6)
        {
            return Err(err("rotation", "is a reflection, not a rotation".into()));
        }
        for (name, v) in [
            ("translation_mm", &self.translation_mm[..]),
            ("camera_centre_mm", &self.camera_centre_mm[..]),
            ("field_mm", &self.field_mm.concat()[..]),
        ] {
            if !v.iter().all(|x| x.is_finite()) {
                return Err(err(name, "holds a non-finite number".into()));
            }
        }
        let c = self.pose().centre_world();
        if c.iter()
            .zip(self.camera_centre_mm)
            .any(|(a, b)| (a - b).abs() > 1e-3)
        {
            return Err(err(
                "camera_centre_mm",
                format!(
                    "{:?} does not match rotation and translation_mm ({c:?})",
                    self.camera_centre_mm
                ),
            ));
        }
        if c[2] <= 0.0 {
            return Err(err(
                "translation_mm",
                format!("puts the camera below the field (z = {:.1} mm)", c[2]),
            ));
        }
        let f = &self.field_mm;
        if !(f[0][0] < f[1][0] && f[0][1] < f[1][1]) {
            return Err(err(
                "field_mm",
                format!("must be [[x_min, y_min], [x_max, y_max]], got {f:?}"),
            ));
        }
        if !(self.residual_rms_px.is_finite() && self.residual_max_px.is_finite()) {
            return Err(err("residual_rms_px", "must be finite".into()));
        }
        Ok(())
    }
}

/// The camera's pose in the table frame from the clicked points and the camera model.
/// `camera` names the camera in errors.
pub fn calibrate_table(
    inputs: &TableInputs,
    intrinsics: &CameraIntrinsics,
    camera: &str,
) -> Result<TableCalibration, CoreError> {
    let err = |field: &str, reason: String| CoreError::CameraField {
        camera: camera.to_string(),
        field: format!("table.{field}"),
        reason,
    };
    let pts = &inputs.points;
    if pts.len() < 4 {
        return Err(err(
            "points",
            format!("needs at least 4 field points, has {}", pts.len()),
        ));
    }
    for (i, p) in pts.iter().enumerate() {
        if !(p.px.iter().chain(&p.mm).all(|v| v.is_finite())) {
            return Err(err(
                &format!("points[{i}]"),
                "holds a non-finite number".into(),
            ));
        }
    }
    let norm: Vec<[f64; 2]> = pts
        .iter()
        .map(|p| {
            let (x, y) = intrinsics.pixel_to_normalized(p.px[0], p.px[1]);
            [x, y]
        })
        .collect();
    let mm: Vec<[f64; 2]> = pts.iter().map(|p| p.mm).collect();
    let h = homography(&mm, &norm).ok_or_else(|| {
        err(
            "points",
            "are degenerate (fewer than 4 points not on one line)".into(),
        )
    })?;
    let pose0 = pose_from_homography(&h).ok_or_else(|| {
        err(
            "points",
            "give no camera pose (degenerate homography)".into(),
        )
    })?;
    let pose = refine(pose0, &mm, pts, intrinsics);
    let cam = Camera {
        intrinsics: *intrinsics,
        pose,
        width: 0,
        height: 0,
    };
    let mut sum = 0.0;
    let mut max: f64 = 0.0;
    for p in pts {
        let e = match cam.project([p.mm[0], p.mm[1], 0.0]) {
            Some((u, v)) => ((u - p.px[0]).powi(2) + (v - p.px[1]).powi(2)).sqrt(),
            None => f64::INFINITY,
        };
        sum += e * e;
        max = max.max(e);
    }
    if !max.is_finite() {
        return Err(err(
            "points",
            "put the field behind the camera; check the px / mm pairs".into(),
        ));
    }
    let lo = [
        mm.iter().map(|p| p[0]).fold(f64::INFINITY, f64::min),
        mm.iter().map(|p| p[1]).fold(f64::INFINITY, f64::min),
    ];
    let hi = [
        mm.iter().map(|p| p[0]).fold(f64::NEG_INFINITY, f64::max),
        mm.iter().map(|p| p[1]).fold(f64::NEG_INFINITY, f64::max),
    ];
    let cal = TableCalibration {
        rotation: pose.rotation,
        translation_mm: pose.translation_mm,
        camera_centre_mm: pose.centre_world(),
        field_mm: [lo, hi],
        points: pts.len(),
        residual_rms_px: (sum / pts.len() as f64).sqrt(),
        residual_max_px: max,
    };
    cal.validate(camera)?;
    Ok(cal)
}

/// Least-squares homography (DLT with Hartley normalisation, `h33 = 1`) mapping `from` to
/// `to`; `None` when degenerate.
fn homography(from: &[[f64; 2]], to: &[[f64; 2]]) -> Option<[[f64; 3]; 3]> {
    let (ta, a) = normalise(from)?;
    let (tb, b) = normalise(to)?;
    let mut ata = [[0.0; 8]; 8];
    let mut atb = [0.0; 8];
    for (p, q) in a.iter().zip(&b) {
        let (x, y, u, v) = (p[0], p[1], q[0], q[1]);
        let rows = [
            ([x, y, 1.0, 0.0, 0.0, 0.0, -u * x, -u * y], u),
            ([0.0, 0.0, 0.0, x, y, 1.0, -v * x, -v * y], v),
        ];
        for (r, rhs) in rows {
            for i in 0..8 {
                atb[i] += r[i] * rhs;
                for j in 0..8 {
                    ata[i][j] += r[i] * r[j];
                }
            }
        }
    }
    let hv = solve_dense::<8>(ata, atb)?;
    let hn = [
        [hv[0], hv[1], hv[2]],
        [hv[3], hv[4], hv[5]],
        [hv[6], hv[7], 1.0],
    ];
    // H = Tb^-1 Hn Ta.
    let tbi = mat_inv3(&tb)?;
    Some(mul3(&tbi, &mul3(&hn, &ta)))
}

/// Translates to the centroid and scales to a mean distance of sqrt(2).
/// A normalising transform and the points it gives.
type Normalised = ([[f64; 3]; 3], Vec<[f64; 2]>);

fn normalise(p: &[[f64; 2]]) -> Option<Normalised> {
    let n = p.len() as f64;
    let cx = p.iter().map(|q| q[0]).sum::<f64>() / n;
    let cy = p.iter().map(|q| q[1]).sum::<f64>() / n;
    let d = p
        .iter()
        .map(|q| ((q[0] - cx).powi(2) + (q[1] - cy).powi(2)).sqrt())
        .sum::<f64>()
        / n;
    if d.is_nan() || d <= 1e-12 {
        return None;
    }
    let s = std::f64::consts::SQRT_2 / d;
    let t = [[s, 0.0, -s * cx], [0.0, s, -s * cy], [0.0, 0.0, 1.0]];
    Some((
        t,
        p.iter()
            .map(|q| [s * (q[0] - cx), s * (q[1] - cy)])
            .collect(),
    ))
}

fn mul3(a: &[[f64; 3]; 3], b: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let mut r = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            r[i][j] = (0..3).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    r
}

/// `H ~ [r1 r2 t]` (plane to normalised image): the pose with the plane in front of the camera.
fn pose_from_homography(h: &[[f64; 3]; 3]) -> Option<Pose> {
    let col = |j: usize| [h[0][j], h[1][j], h[2][j]];
    let (h1, h2, h3) = (col(0), col(1), col(2));
    let s = 0.5 * (norm3(h1) + norm3(h2));
    if s.is_nan() || s <= 1e-15 {
        return None;
    }
    let mut l = 1.0 / s;
    if h3[2] * l < 0.0 {
        l = -l;
    }
    let r1 = h1.map(|v| v * l);
    let r2 = h2.map(|v| v * l);
    let r3 = cross(r1, r2);
    // Columns r1 r2 r3 -> nearest rotation by the polar iteration R <- (R + R^-T) / 2.
    let mut r = [
        [r1[0], r2[0], r3[0]],
        [r1[1], r2[1], r3[1]],
        [r1[2], r2[2], r3[2]],
    ];
    for _ in 0..20 {
        let inv = mat_inv3(&r)?;
        let mut next = [[0.0; 3]; 3];
        for i in 0..3 {
            for j in 0..3 {
                next[i][j] = 0.5 * (r[i][j] + inv[j][i]);
            }
        }
        r = next;
    }
    Some(Pose {
        rotation: r,
        translation_mm: h3.map(|v| v * l),
    })
}

/// Rodrigues: rotation matrix of the rotation vector `w`.
fn rotation_of(w: [f64; 3]) -> [[f64; 3]; 3] {
    let th = norm3(w);
    if th < 1e-15 {
        return [[1.0, -w[2], w[1]], [w[2], 1.0, -w[0]], [-w[1], w[0], 1.0]];
    }
    let k = w.map(|v| v / th);
    let (s, c) = th.sin_cos();
    let v = 1.0 - c;
    [
        [
            c + k[0] * k[0] * v,
            k[0] * k[1] * v - k[2] * s,
            k[0] * k[2] * v + k[1] * s,
        ],
        [
            k[1] * k[0] * v + k[2] * s,
            c + k[1] * k[1] * v,
            k[1] * k[2] * v - k[0] * s,
        ],
        [
            k[2] * k[0] * v - k[1] * s,
            k[2] * k[1] * v + k[0] * s,
            c + k[2] * k[2] * v,
        ],
    ]
}

/// Levenberg-Marquardt on the pixel reprojection error over a rotation increment and the
/// translation.
fn refine(pose: Pose, mm: &[[f64; 2]], pts: &[TablePoint], k: &CameraIntrinsics) -> Pose {
    let apply = |p: &Pose, x: &[f64; 6]| Pose {
        rotation: mul3(&rotation_of([x[0], x[1], x[2]]), &p.rotation),
        translation_mm: [
            p.translation_mm[0] + x[3],
            p.translation_mm[1] + x[4],
            p.translation_mm[2] + x[5],
        ],
    };
    let residuals = |p: &Pose, out: &mut Vec<f64>| -> bool {
        out.clear();
        for (m, q) in mm.iter().zip(pts) {
            let c = p.to_camera([m[0], m[1], 0.0]);
            if c[2] <= 1e-9 {
                return false;
            }
            let (u, v) = k.normalized_to_pixel(c[0] / c[2], c[1] / c[2]);
            out.push(u - q.px[0]);
            out.push(v - q.px[1]);
        }
        true
    };
    let cost = |r: &[f64]| r.iter().map(|v| v * v).sum::<f64>();
    let mut best = pose;
    let mut r0 = Vec::with_capacity(2 * mm.len());
    if !residuals(&best, &mut r0) {
        return pose;
    }
    let mut c0 = cost(&r0);
    let mut lambda = 1e-3;
    let mut r1 = Vec::with_capacity(2 * mm.len());
    let steps = [1e-6, 1e-6, 1e-6, 1e-3, 1e-3, 1e-3];
    for _ in 0..50 {
        // Numerical Jacobian, 2n x 6.
        let mut jac = vec![[0.0; 6]; r0.len()];
        for (j, h) in steps.iter().enumerate() {
            let mut x = [0.0; 6];
            x[j] = *h;
            if !residuals(&apply(&best, &x), &mut r1) {
                return best;
            }
            for (row, (a, b)) in jac.iter_mut().zip(r1.iter().zip(&r0)) {
                row[j] = (a - b) / h;
            }
        }
        let mut jtj = [[0.0; 6]; 6];
        let mut jtr = [0.0; 6];
        for (row, r) in jac.iter().zip(&r0) {
            for i in 0..6 {
                jtr[i] -= row[i] * r;
                for j in 0..6 {
                    jtj[i][j] += row[i] * row[j];
                }
            }
        }
        let mut improved = false;
        for _ in 0..10 {
            let mut a = jtj;
            for (i, row) in a.iter_mut().enumerate() {
                row[i] += lambda * (jtj[i][i] + 1e-12);
            }
            let Some(dx) = solve_dense::<6>(a, jtr) else {
                lambda *= 10.0;
                continue;
            };
            let cand = apply(&best, &dx);
            if residuals(&cand, &mut r1) && cost(&r1) < c0 {
                best = cand;
                std::mem::swap(&mut r0, &mut r1);
                let c1 = cost(&r0);
                let done = c0 - c1 < 1e-12 * (1.0 + c0);
                c0 = c1;
                lambda = (lambda * 0.3).max(1e-9);
                improved = !done;
                break;
            }
            lambda *= 10.0;
        }
        if !improved {
            break;
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    fn intrinsics() -> CameraIntrinsics {
        CameraIntrinsics::from_opencv(
            [[1078.0, 0.0, 719.5], [0.0, 1078.0, 539.5], [0.0, 0.0, 1.0]],
            &[-0.25, 0.08, 0.0004, -0.0003, 0.0],
        )
        .unwrap()
    }

    fn points(cam: &Camera, mm: &[[f64; 2]]) -> TableInputs {
        TableInputs {
            points: mm
                .iter()
                .map(|m| {
                    let (u, v) = cam.project([m[0], m[1], 0.0]).unwrap();
                    TablePoint { px: [u, v], mm: *m }
                })
                .collect(),
        }
    }

    #[test]
    fn exact_points_give_the_exact_pose() {
        let k = intrinsics();
        let pose = Pose::looking_down([-75.0, 0.0, 830.0], 0.01, -0.015);
        let cam = Camera {
            intrinsics: k,
            pose,
            width: 1440,
            height: 1080,
        };
        let mm = [
            [-600.0, -340.0],
            [-600.0, 340.0],
            [0.0, -340.0],
            [0.0, 340.0],
        ];
        let cal = calibrate_table(&points(&cam, &mm), &k, "0").unwrap();
        let c = cal.camera_centre_mm;
        assert!(
            (c[0] + 75.0).abs() < 1e-4 && c[1].abs() < 1e-4 && (c[2] - 830.0).abs() < 1e-4,
            "{c:?}"
        );
        assert!(cal.residual_max_px < 1e-6);
        assert_eq!(cal.field_mm, [[-600.0, -340.0], [0.0, 340.0]]);
    }

    #[test]
    fn bad_points_are_named() {
        let k = intrinsics();
        let few = TableInputs {
            points: vec![
                TablePoint {
                    px: [1.0, 2.0],
                    mm: [0.0, 0.0]
                };
                3
            ],
        };
        let e = calibrate_table(&few, &k, "0 (cam0)")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("table.points") && e.contains("at least 4"),
            "{e}"
        );
        let line: Vec<TablePoint> = (0..5)
            .map(|i| TablePoint {
                px: [100.0 + 10.0 * i as f64, 200.0],
                mm: [i as f64 * 10.0, 0.0],
            })
            .collect();
        let e = calibrate_table(&TableInputs { points: line }, &k, "0")
            .unwrap_err()
            .to_string();
        assert!(e.contains("table.points"), "{e}");
        let mut nan = few.clone();
        nan.points.push(TablePoint {
            px: [f64::NAN, 0.0],
            mm: [1.0, 1.0],
        });
        let e = calibrate_table(&nan, &k, "0").unwrap_err().to_string();
        assert!(e.contains("table.points[3]"), "{e}");
    }

    #[test]
    fn validate_rejects_a_tampered_file() {
        let k = intrinsics();
        let cam = Camera {
            intrinsics: k,
            pose: Pose::looking_down([0.0, 0.0, 800.0], 0.0, 0.0),
            width: 1440,
            height: 1080,
        };
        let mm = [
            [-300.0, -300.0],
            [-300.0, 300.0],
            [300.0, -300.0],
            [300.0, 300.0],
        ];
        let mut cal = calibrate_table(&points(&cam, &mm), &k, "0").unwrap();
        cal.rotation[0][0] = 0.5;
        let e = cal.validate("1 (cam1)").unwrap_err().to_string();
        assert!(
            e.contains("camera 1 (cam1)") && e.contains("table.rotation"),
            "{e}"
        );
    }
}
