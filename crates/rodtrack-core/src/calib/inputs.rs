//! The calibration-inputs file (SPEC section 5): what an operator, the web console or the
//! simulator produces, one JSON file per camera.

use crate::marker::MarkerSpec;
use serde::{Deserialize, Serialize};

/// Image size in pixels.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ImageSize {
    /// Width, px.
    pub width: usize,
    /// Height, px.
    pub height: usize,
}

/// An OpenCV camera model as in the calibration inputs.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OpencvModel {
    /// 3x3 camera matrix.
    pub camera_matrix: [[f64; 3]; 3],
    /// Distortion coefficients `(k1, k2, p1, p2[, k3])`.
    pub dist_coeffs: Vec<f64>,
}

/// Where the reference frames are.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ReferenceFrames {
    /// Folder of images, relative to the JSON file.
    pub dir: String,
    /// Default reference frame: index in name order.
    pub reference_frame: usize,
}

/// A rod's known pose in a reference frame.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ReferencePose {
    /// Frame index in the reference folder (name order).
    pub frame: usize,
    /// Known position, mm.
    #[serde(default)]
    pub position_mm: f64,
    /// Known angle, rad.
    #[serde(default)]
    pub angle_rad: f64,
}

/// One rod's calibration inputs.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RodInputs {
    /// Rod id.
    pub rod: u32,
    /// At least 3 image points on the rod's visible centre line, any order.
    pub path_points_px: Vec<[f64; 2]>,
    /// Travel range, mm (relative to the reference pose's zero).
    pub travel_mm: [f64; 2],
    /// The rod's pose in a reference frame.
    pub reference: ReferencePose,
    /// The marker on this rod.
    pub marker: MarkerSpec,
}

/// One camera's calibration inputs.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CalibrationInputs {
    /// Camera name.
    pub camera_name: String,
    /// Image size.
    pub image_size: ImageSize,
    /// Pixel format name (`bayer_rggb8`, `mono8`, ...).
    pub pixel_format: String,
    /// Optional OpenCV camera model.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub opencv_model_optional: Option<OpencvModel>,
    /// Where the reference frames are.
    pub reference_frames: ReferenceFrames,
    /// Frames per second of the recording (used for timestamps of image sequences).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fps: Option<f64>,
    /// The rods.
    pub rods: Vec<RodInputs>,
}
