//! The ball's colour from calibration: the operator clicks the ball once in a frame of the
//! reference folder (`ball: { "frame": N, "px": [u, v], "diameter_mm": 35 }`); calibration
//! reads the ball's mean colour from the mosaic's quads inside its image and the empty
//! field's colour in a ring around it, with their spreads, into `[cameras.ball]`.

use super::table::TableCalibration;
use crate::ball::colour::{chroma, ColourModel, QuadLayout};
use crate::{Camera, CameraIntrinsics, CoreError, FrameView};
use serde::{Deserialize, Serialize};

/// The calibration inputs' `ball`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct BallInputs {
    /// Frame of the reference folder (name order) that shows the ball.
    pub frame: usize,
    /// The ball's centre in that frame, px.
    pub px: [f64; 2],
    /// The ball's diameter, mm.
    #[serde(default = "default_diameter")]
    pub diameter_mm: f64,
}

fn default_diameter() -> f64 {
    35.0
}

/// The calibration file's `[cameras.ball]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BallCalibration {
    /// The ball's diameter, mm.
    pub diameter_mm: f64,
    /// The ball's mean colour `[R, G, B]` (8-bit scale, quads of the mosaic).
    pub ball_rgb: [f64; 3],
    /// RMS distance of the ball's quads from its mean chromaticity.
    pub ball_chroma_spread: f64,
    /// The empty field's colour around the ball (median per channel).
    pub field_rgb: [f64; 3],
    /// Robust spread (1.4826 x median distance) of the field's quads' chromaticity.
    pub field_chroma_spread: f64,
    /// Quads read inside the ball.
    pub ball_quads: usize,
    /// Quads read in the field's ring.
    pub field_quads: usize,
}

impl BallCalibration {
    /// The colour model for detection; `camera` names the camera in the error.
    pub fn colour_model(&self, camera: &str) -> Result<ColourModel, CoreError> {
        ColourModel::new(
            self.ball_rgb,
            self.ball_chroma_spread,
            self.field_rgb,
            self.field_chroma_spread,
        )
        .ok_or_else(|| CoreError::CameraField {
            camera: camera.to_string(),
            field: "ball.ball_rgb".into(),
            reason: "ball or field colour is black, or both are the same".into(),
        })
    }

    /// Checks the fields.
    pub fn validate(&self, camera: &str) -> Result<(), CoreError> {
        let err = |field: &str, reason: String| CoreError::CameraField {
            camera: camera.to_string(),
            field: format!("ball.{field}"),
            reason,
        };
        if !(self.diameter_mm.is_finite() && self.diameter_mm > 0.0 && self.diameter_mm < 500.0) {
            return Err(err(
                "diameter_mm",
                format!("must be a diameter in mm, got {}", self.diameter_mm),
            ));
        }
        for (name, c) in [("ball_rgb", self.ball_rgb), ("field_rgb", self.field_rgb)] {
            if !c.iter().all(|v| v.is_finite() && *v >= 0.0) {
                return Err(err(
                    name,
                    format!("must be 3 non-negative numbers, got {c:?}"),
                ));
            }
        }
        for (name, s) in [
            ("ball_chroma_spread", self.ball_chroma_spread),
            ("field_chroma_spread", self.field_chroma_spread),
        ] {
            if !(s.is_finite() && s > 0.0 && s < 1.0) {
                return Err(err(name, format!("must be in (0, 1), got {s}")));
            }
        }
        self.colour_model(camera).map(|_| ())
    }
}

/// The ball's expected image radius at pixel `(u, v)` (the ball's centre on the plane `z =
/// radius`), px; `None` when the ray misses the plane.
pub fn expected_radius_px(cam: &Camera, u: f64, v: f64, radius_mm: f64) -> Option<f64> {
    let (o, d) = cam.ray(u, v);
    if d[2].abs() < 1e-9 {
        return None;
    }
    let s = (radius_mm - o[2]) / d[2];
    if s <= 0.0 {
        return None;
    }
    let dist = s;
    if dist <= radius_mm {
        return None;
    }
    let k = &cam.intrinsics;
    Some(0.5 * (k.fx + k.fy) * radius_mm / (dist * dist - radius_mm * radius_mm).sqrt())
}

/// Measures the ball's and the field's colours around the click; `camera` names the camera.
pub fn calibrate_ball(
    inputs: &BallInputs,
    view: &FrameView,
    table: &TableCalibration,
    intrinsics: &CameraIntrinsics,
    camera: &str,
) -> Result<BallCalibration, CoreError> {
    let err = |field: &str, reason: String| CoreError::CameraField {
        camera: camera.to_string(),
        field: format!("ball.{field}"),
        reason,
    };
    if !(inputs.diameter_mm.is_finite() && inputs.diameter_mm > 0.0 && inputs.diameter_mm < 500.0) {
        return Err(err(
            "diameter_mm",
            format!("must be a diameter in mm, got {}", inputs.diameter_mm),
        ));
    }
    let layout = QuadLayout::of(view.format()).ok_or_else(|| {
        err(
            "frame",
            format!(
                "the ball's colour needs a colour format, the frames are {}",
                view.format().name()
            ),
        )
    })?;
    let [u, v] = inputs.px;
    let (w, h) = (view.width() as f64, view.height() as f64);
    if !(u.is_finite() && v.is_finite() && u >= 0.0 && v >= 0.0 && u < w && v < h) {
        return Err(err(
            "px",
            format!("{:?} is outside the {w}x{h} image", inputs.px),
        ));
    }
    let cam = table.camera(*intrinsics, view.width(), view.height());
    let r_mm = 0.5 * inputs.diameter_mm;
    let r_px = expected_radius_px(&cam, u, v, r_mm)
        .ok_or_else(|| err("px", "does not look at the field".into()))?;
    let (qw, qh) = (view.width() / 2, view.height() / 2);
    // Quads: centre at pixel (2 qx + 0.5, 2 qy + 0.5).
    let rq = r_px / 2.0;
    let (cqx, cqy) = ((u - 0.5) / 2.0, (v - 0.5) / 2.0);
    let outer = 2.6 * rq;
    let mut ball = Vec::new();
    let mut field = Vec::new();
    let y0 = (cqy - outer).floor().max(0.0) as usize;
    let y1 = ((cqy + outer).ceil().max(0.0) as usize).min(qh.saturating_sub(1));
    let x0 = (cqx - outer).floor().max(0.0) as usize;
    let x1 = ((cqx + outer).ceil().max(0.0) as usize).min(qw.saturating_sub(1));
    for qy in y0..=y1 {
        for qx in x0..=x1 {
            let d = ((qx as f64 - cqx).powi(2) + (qy as f64 - cqy).powi(2)).sqrt();
            if d <= 0.6 * rq {
                ball.push(layout.rgb(view, qx, qy));
            } else if d >= 1.6 * rq && d <= outer {
                field.push(layout.rgb(view, qx, qy));
            }
        }
    }
    if ball.len() < 4 {
        return Err(err(
            "px",
            format!("the ball's image ({r_px:.1} px radius) is too small to read its colour"),
        ));
    }
    if field.len() < 8 {
        return Err(err(
            "px",
            "too close to the image's edge to read the field around it".into(),
        ));
    }
    let mean = |s: &[[f32; 3]]| -> [f64; 3] {
        let mut m = [0.0f64; 3];
        for p in s {
            for c in 0..3 {
                m[c] += p[c] as f64;
            }
        }
        m.map(|v| v / s.len() as f64)
    };
    let median = |s: &[[f32; 3]]| -> [f64; 3] {
        let mut out = [0.0; 3];
        for (c, o) in out.iter_mut().enumerate() {
            let mut ch: Vec<f32> = s.iter().map(|p| p[c]).collect();
            ch.sort_by(|a, b| a.total_cmp(b));
            *o = ch[ch.len() / 2] as f64;
        }
        out
    };
    let ball_rgb = mean(&ball);
    let field_rgb = median(&field);
    let spread = |s: &[[f32; 3]], centre: [f64; 3], robust: bool| -> Option<f64> {
        let c0 = chroma(centre.map(|v| v as f32))?;
        let mut d: Vec<f64> = s
            .iter()
            .filter_map(|p| chroma(*p))
            .map(|c| (((c[0] - c0[0]).powi(2) + (c[1] - c0[1]).powi(2)) as f64).sqrt())
            .collect();
        if d.is_empty() {
            return None;
        }
        // Quantisation floor: one DN of the sample's brightness.
        let floor = 1.0 / (centre[0] + centre[1] + centre[2]).max(1.0);
        let s = if robust {
            d.sort_by(|a, b| a.total_cmp(b));
            1.4826 * d[d.len() / 2]
        } else {
            (d.iter().map(|v| v * v).sum::<f64>() / d.len() as f64).sqrt()
        };
        Some(s.max(floor))
    };
    let ball_spread = spread(&ball, ball_rgb, false)
        .ok_or_else(|| err("px", "the ball's quads are black".into()))?;
    let field_spread = spread(&field, field_rgb, true)
        .ok_or_else(|| err("px", "the field's quads are black".into()))?;
    let cal = BallCalibration {
        diameter_mm: inputs.diameter_mm,
        ball_rgb,
        ball_chroma_spread: ball_spread,
        field_rgb,
        field_chroma_spread: field_spread,
        ball_quads: ball.len(),
        field_quads: field.len(),
    };
    let model = cal.colour_model(camera)?;
    let need = crate::ball::colour::SPREAD_SIGMAS as f64 * (ball_spread + field_spread);
    if (model.separation() as f64) < need {
        return Err(err(
            "px",
            format!(
                "the ball's colour {:?} is too close to the field's {:?} (chromaticity distance \
                 {:.3}, spreads {:.3} and {:.3}): is the ball at the point clicked?",
                ball_rgb.map(|v| v.round()),
                field_rgb.map(|v| v.round()),
                model.separation(),
                ball_spread,
                field_spread
            ),
        ));
    }
    cal.validate(camera)?;
    Ok(cal)
}
