//! The calibration file: everything tracking needs per rod, human-readable (TOML), validated on
//! load with errors that name the rod and the field.

use super::ball::BallCalibration;
use super::opencv::OpencvModel;
use super::table::TableCalibration;
use crate::line::Knots;
use crate::marker::{Marker, MarkerSpec};
use crate::{CoreError, PixelFormat};
use serde::{Deserialize, Serialize};

/// Current file version.
pub const CALIBRATION_VERSION: u32 = 1;

/// The paper's per-rod parameters (section 2).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PaperParams {
    /// Trajectory `x(t) = a t^2 + b t + c`: `[a, b, c]`.
    pub trajectory_abc: [f64; 3],
    /// Camera view angle of eq. (1), degrees.
    pub view_angle_deg: f64,
    /// Barcode cell length on the line, samples.
    pub cell_px: f64,
    /// +1 when the marker's `u` runs towards larger line indices, else -1.
    pub direction: i32,
    /// `O_m`: offset from the kernel position to the Gray-code samples, samples (signed).
    pub offset_px: f64,
    /// `S_m`: spacing of bit spaces, samples (signed).
    pub spacing_px: f64,
    /// `T_hat`: stripe period across the rod over bit space 0, px.
    pub period_px: f64,
    /// `phi_offset`, rad.
    pub phase_offset_rad: f64,
    /// Sign applied to eq. (6) so that the phase grows with the angle.
    pub phase_sign: i32,
    /// `N_p`: pixels each side of the centre line for eq. (6).
    pub half_width_px: u32,
    /// mm per line sample, from the barcode's known length.
    pub mm_per_px: f64,
    /// Kernel position `p_m` in the reference frame.
    pub zero_px: f64,
    /// Angle removed so the reference frame reads its known angle, rad.
    pub angle_offset_rad: f64,
}

/// rodtrack's enhanced per-rod parameters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EnhancedParams {
    /// +1 when the print angle grows along the line's normal `(-ty, tx)`, else -1.
    pub phase_sign: i32,
    /// Correction added to the phase-derived fraction, Gray steps.
    pub phase_offset_steps: f64,
    /// Angle removed so the reference frame reads its known angle, rad.
    pub angle_offset_rad: f64,
    /// The angle's bias along the travel, measured at the known poses whose angle is given:
    /// `[position_mm, bias_rad]` sorted by position (the reference pose's bias is 0 by
    /// construction), removed by linear interpolation between them (constant beyond). Empty
    /// when no known pose gives an angle.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub angle_bias_rad: Vec<[f64; 2]>,
    /// Whether the tracker may move the centre line along the travel from the silhouettes it
    /// measures while tracking (the angle's lateral reference). Off when calibration measured
    /// the line at known poses over the travel: the tracker's quick silhouettes then only add
    /// their own drift.
    #[serde(default = "default_true", skip_serializing_if = "is_true")]
    pub learn_centre_slope: bool,
    /// With a camera model: the rod's own perspective `r / D` (its radius over the distance
    /// from the camera centre to its axis at the reference pose). The knots' radius is then
    /// the lens' projection of the cylinder, and the phase samples the print across the rod
    /// through this perspective instead of learning the radius from the silhouettes. Absent
    /// without a camera model (the radius is then measured and refined while tracking).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lens_perspective: Option<f64>,
}

fn default_true() -> bool {
    true
}

fn is_true(v: &bool) -> bool {
    *v
}

impl EnhancedParams {
    /// The angle's bias at `position_mm` ([`EnhancedParams::angle_bias_rad`] interpolated),
    /// rad; 0 without known-pose angles.
    pub fn angle_bias_at(&self, position_mm: f64) -> f64 {
        angle_bias_at(&self.angle_bias_rad, position_mm)
    }
}

/// `[position_mm, bias_rad]` points (sorted by position) interpolated linearly at
/// `position_mm`, constant beyond the first and last; 0 when there are none.
pub fn angle_bias_at(points: &[[f64; 2]], position_mm: f64) -> f64 {
    let (Some(first), Some(last)) = (points.first(), points.last()) else {
        return 0.0;
    };
    if position_mm <= first[0] {
        return first[1];
    }
    if position_mm >= last[0] {
        return last[1];
    }
    for w in points.windows(2) {
        let ([p0, b0], [p1, b1]) = (w[0], w[1]);
        if position_mm <= p1 {
            let f = if p1 > p0 {
                (position_mm - p0) / (p1 - p0)
            } else {
                1.0
            };
            return b0 + f * (b1 - b0);
        }
    }
    last[1]
}

/// What calibration measured about its own quality (informative; not used for tracking).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct Residuals {
    /// RMS distance of the path points from the fitted path, px.
    pub path_rms_px: f64,
    /// Largest distance of a path point from the fitted path, px.
    pub path_max_px: f64,
    /// Barcode length measured in the reference frame divided by its nominal length.
    pub scale_ratio: f64,
    /// RMS of the barcode edges around the fitted scale, mm.
    pub edge_rms_mm: f64,
    /// Barcode correlation peak in the reference frame (1 = perfect).
    pub reference_ncc: f64,
    /// Distance of the Gray code from the phase in the reference frame, Gray steps.
    pub reference_code_phase_steps: f64,
    /// Apparent rod radius measured from the silhouette over the predicted one.
    pub radius_ratio: f64,
    /// How the line's scale is carried along the travel: `known_poses` (fitted to the
    /// barcode's edges at the known poses), `vanishing_direction` (from the camera's parallel
    /// rods) or `affine` (the reference pose's scale).
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub travel_model: String,
    /// Relative change of depth along the rod, per metre (`h` of the travel model times 1000).
    #[serde(default)]
    pub depth_change_per_m: f64,
    /// What the camera's parallel rods predict for `depth_change_per_m` (a cross-check of the
    /// known poses' fit), when there is a camera model and enough rods.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub depth_change_per_m_from_rods: Option<f64>,
    /// Where the direction the camera's rods share (their vanishing point) came from: the bare
    /// rods' outlines (`outlines: S sides of N rods`) or the markers' lines (`marker lines
    /// ...`, with why the outlines were not used); empty without a camera model. The same for
    /// every rod of a camera.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub common_direction: String,
    /// At each known pose: `[frame, position error mm]` of the barcode read with the final
    /// calibration against the pose given.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub known_pose_errors_mm: Vec<[f64; 2]>,
    /// Warnings for the operator.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<String>,
}

/// One rod's calibration.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RodCalibration {
    /// Rod id.
    pub rod: u32,
    /// The marker on this rod.
    pub marker: MarkerSpec,
    /// Travel range, mm.
    pub travel_mm: [f64; 2],
    /// Known pose in the reference frame.
    pub reference_position_mm: f64,
    /// Known angle in the reference frame.
    pub reference_angle_rad: f64,
    /// How the enhanced line was made (`camera` or `poly`).
    pub line_model: String,
    /// The clicked or found path points.
    pub path_points_px: Vec<[f64; 2]>,
    /// Enhanced mode's line.
    pub knots: Knots,
    /// Enhanced mode's parameters.
    pub enhanced: EnhancedParams,
    /// Paper mode's parameters (absent when the rod does not run along image rows).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub paper: Option<PaperParams>,
    /// Calibration's own measurements of its quality.
    #[serde(default)]
    pub residuals: Residuals,
}

/// One camera's calibration.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraCalibration {
    /// Camera name.
    pub name: String,
    /// Camera index in the output rows.
    pub index: u32,
    /// Image width, px.
    pub image_width: usize,
    /// Image height, px.
    pub image_height: usize,
    /// Pixel format name.
    pub pixel_format: String,
    /// Frames per second (timestamps of image sequences).
    pub fps: f64,
    /// The OpenCV model, when one was given.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub opencv_model: Option<OpencvModel>,
    /// The camera's pose in the table frame, when the inputs gave field points.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub table: Option<TableCalibration>,
    /// The ball's and the field's colours, when the inputs gave a ball click.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ball: Option<BallCalibration>,
    /// The rods this camera sees.
    pub rods: Vec<RodCalibration>,
}

/// The calibration file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CalibrationFile {
    /// File version.
    pub version: u32,
    /// Cameras.
    pub cameras: Vec<CameraCalibration>,
}

impl CameraCalibration {
    /// The pixel format, validated.
    pub fn format(&self) -> Result<PixelFormat, CoreError> {
        PixelFormat::from_name(&self.pixel_format).ok_or_else(|| CoreError::CameraField {
            camera: self.index.to_string(),
            field: format!("cameras[{}].pixel_format", self.index),
            reason: format!("unknown pixel format {:?}", self.pixel_format),
        })
    }
}

impl RodCalibration {
    /// Checks the rod's fields against the image size.
    pub fn validate(&self, width: usize, height: usize) -> Result<Marker, CoreError> {
        let rod = self.rod;
        let err = |field: &str, reason: String| CoreError::Calibration {
            rod,
            field: field.to_string(),
            reason,
        };
        let marker = self.marker.validate().map_err(|e| match e {
            CoreError::Marker { field, reason } => err(&format!("marker.{field}"), reason),
            other => other,
        })?;
        let finite = |field: &str, v: f64| {
            if v.is_finite() {
                Ok(())
            } else {
                Err(err(field, format!("must be a finite number, got {v}")))
            }
        };
        finite("travel_mm[0]", self.travel_mm[0])?;
        finite("travel_mm[1]", self.travel_mm[1])?;
        if self.travel_mm[0] > self.travel_mm[1] {
            return Err(err(
                "travel_mm",
                format!("must be [min, max], got {:?}", self.travel_mm),
            ));
        }
        finite("reference_position_mm", self.reference_position_mm)?;
        finite("reference_angle_rad", self.reference_angle_rad)?;
        for (i, p) in self.enhanced.angle_bias_rad.iter().enumerate() {
            finite(&format!("enhanced.angle_bias_rad[{i}]"), p[0])?;
            finite(&format!("enhanced.angle_bias_rad[{i}]"), p[1])?;
            if i > 0 && p[0] < self.enhanced.angle_bias_rad[i - 1][0] {
                return Err(err(
                    "enhanced.angle_bias_rad",
                    "must be sorted by position".into(),
                ));
            }
        }
        let k = &self.knots;
        if k.len() < 2 {
            return Err(err("knots", "needs at least 2 knots".into()));
        }
        if !(k.step_mm.is_finite() && k.step_mm > 0.0) {
            return Err(err(
                "knots.step_mm",
                format!("must be positive, got {}", k.step_mm),
            ));
        }
        finite("knots.s0_mm", k.s0_mm)?;
        if k.y_px.len() != k.len() || k.radius_px.len() != k.len() {
            return Err(err(
                "knots",
                format!(
                    "x_px, y_px and radius_px must have the same length ({}, {}, {})",
                    k.len(),
                    k.y_px.len(),
                    k.radius_px.len()
                ),
            ));
        }
        for (name, v) in [("knots.x_px", &k.x_px), ("knots.y_px", &k.y_px)] {
            if let Some(i) = v.iter().position(|x| !x.is_finite()) {
                return Err(err(name, format!("entry {i} is not a finite number")));
            }
        }
        if let Some(i) = k
            .radius_px
            .iter()
            .position(|r| !(r.is_finite() && *r > 0.5 && *r < (width.max(height) as f64)))
        {
            return Err(err(
                "knots.radius_px",
                format!(
                    "entry {i} must be a plausible radius in px, got {}",
                    k.radius_px[i]
                ),
            ));
        }
        if k.s0_mm > self.travel_mm[0] || k.s_end_mm() < self.travel_mm[1] + marker.length_mm() {
            return Err(err(
                "knots",
                format!(
                    "cover {:.1}..{:.1} mm but the marker moves over {:.1}..{:.1} mm",
                    k.s0_mm,
                    k.s_end_mm(),
                    self.travel_mm[0],
                    self.travel_mm[1] + marker.length_mm()
                ),
            ));
        }
        let e = &self.enhanced;
        if e.phase_sign != 1 && e.phase_sign != -1 {
            return Err(err(
                "enhanced.phase_sign",
                format!("must be 1 or -1, got {}", e.phase_sign),
            ));
        }
        finite("enhanced.phase_offset_steps", e.phase_offset_steps)?;
        finite("enhanced.angle_offset_rad", e.angle_offset_rad)?;
        if let Some(rho) = e.lens_perspective {
            // A rod seen from at least twice its radius away.
            if !(rho.is_finite() && (0.0..=0.5).contains(&rho)) {
                return Err(err(
                    "enhanced.lens_perspective",
                    format!("must be in 0..=0.5 (radius over distance), got {rho}"),
                ));
            }
        }
        if let Some(p) = &self.paper {
            for (name, v) in [
                ("paper.view_angle_deg", p.view_angle_deg),
                ("paper.cell_px", p.cell_px),
                ("paper.period_px", p.period_px),
                ("paper.mm_per_px", p.mm_per_px),
            ] {
                if !(v.is_finite() && v > 0.0) {
                    return Err(err(name, format!("must be positive, got {v}")));
                }
            }
            for (name, v) in [
                ("paper.offset_px", p.offset_px),
                ("paper.spacing_px", p.spacing_px),
                ("paper.phase_offset_rad", p.phase_offset_rad),
                ("paper.zero_px", p.zero_px),
                ("paper.angle_offset_rad", p.angle_offset_rad),
                ("paper.trajectory_abc[0]", p.trajectory_abc[0]),
                ("paper.trajectory_abc[1]", p.trajectory_abc[1]),
                ("paper.trajectory_abc[2]", p.trajectory_abc[2]),
            ] {
                finite(name, v)?;
            }
            if p.direction.abs() != 1 || p.phase_sign.abs() != 1 {
                return Err(err("paper.direction/phase_sign", "must be 1 or -1".into()));
            }
            if p.half_width_px == 0 || p.half_width_px > 200 {
                return Err(err(
                    "paper.half_width_px",
                    format!("must be 1..200, got {}", p.half_width_px),
                ));
            }
        }
        Ok(marker)
    }
}

#[cfg(test)]
mod tests {
    use super::angle_bias_at;

    #[test]
    fn angle_bias_interpolates_between_points_and_holds_beyond() {
        assert_eq!(angle_bias_at(&[], 10.0), 0.0);
        let pts = [[-100.0, 0.004], [0.0, 0.0], [100.0, -0.002]];
        assert!((angle_bias_at(&pts, -50.0) - 0.002).abs() < 1e-12);
        assert!((angle_bias_at(&pts, 50.0) + 0.001).abs() < 1e-12);
        assert!((angle_bias_at(&pts, 0.0)).abs() < 1e-12);
        assert_eq!(angle_bias_at(&pts, -300.0), 0.004);
        assert_eq!(angle_bias_at(&pts, 300.0), -0.002);
    }
}
