//! The calibration-inputs file (SPEC section 5): what an operator, the web console or the
//! simulator produces, one JSON file per camera.
//!
//! The OpenCV camera model may be given inline (`opencv_model_optional`, see [`OpencvModel`])
//! or as the file OpenCV's `cv::FileStorage` wrote after `calibrateCamera`: the key
//! [`OPENCV_MODEL_FILE_KEY`] (`"opencv_model_file": "cam0_intrinsics.yml"`, relative to the
//! inputs file, YAML or JSON; see [`super::opencv`]). The loader that reads inputs from disk
//! resolves that key and puts the model it reads into `opencv_model_optional`; giving both is
//! an error.

pub use super::ball::BallInputs;
pub use super::image_size::ImageSize;
pub use super::opencv::OpencvModel;
pub use super::table::{TableInputs, TablePoint};
use crate::marker::MarkerSpec;
use serde::{Deserialize, Serialize};

/// Key of the calibration inputs that names an OpenCV FileStorage file (YAML or JSON) holding
/// the camera model, relative to the inputs file. Read by the file loader, never stored in
/// [`CalibrationInputs`]: the model read from it becomes `opencv_model_optional`.
pub const OPENCV_MODEL_FILE_KEY: &str = "opencv_model_file";

/// Where the reference frames are.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ReferenceFrames {
    /// Folder of images, relative to the JSON file.
    pub dir: String,
    /// Default reference frame: index in name order.
    pub reference_frame: usize,
}

/// A rod's known pose in a reference frame.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
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
    /// Frames of the reference folder in which the rod stands at a known pose (for example
    /// against its end stops): they fix the along-travel model, and `calibrate` prints the
    /// residual at each.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub known_poses: Vec<KnownPose>,
    /// The frames of the reference folder where the rod stands at its travel's start, middle
    /// (0) and end: the same as three [`KnownPose`]s without an angle.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub travel_frames: Option<TravelFrames>,
}

/// A frame of the reference folder in which a rod stands at a known pose.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct KnownPose {
    /// Frame index in the reference folder (name order).
    pub frame: usize,
    /// Known position, mm (same zero as `position_mm`).
    pub position_mm: f64,
    /// Known angle, rad, when known.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub angle_rad: Option<f64>,
}

/// The frames of the reference folder where a rod stands at its travel's start, middle and end.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TravelFrames {
    /// Frame with the rod at `travel_mm[0]`.
    pub min: usize,
    /// Frame with the rod at position 0.
    pub zero: usize,
    /// Frame with the rod at `travel_mm[1]`.
    pub max: usize,
    /// The rod's angle in these frames, rad, when known (then they also measure the angle's
    /// bias along the travel).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub angle_rad: Option<f64>,
}

impl RodInputs {
    /// Every known pose of the rod: `known_poses`, then those `travel_frames` gives (with its
    /// angle when it gives one), in that order, without duplicates of the same frame.
    pub fn all_known_poses(&self) -> Vec<KnownPose> {
        let mut out = self.known_poses.clone();
        if let Some(t) = self.travel_frames {
            for (frame, position_mm) in [
                (t.min, self.travel_mm[0]),
                (t.zero, 0.0),
                (t.max, self.travel_mm[1]),
            ] {
                if !out.iter().any(|k| k.frame == frame) {
                    out.push(KnownPose {
                        frame,
                        position_mm,
                        angle_rad: t.angle_rad,
                    });
                }
            }
        }
        out
    }
}

/// One camera's calibration inputs.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
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
    /// Field points clicked in the reference frame: they give the camera's pose in the table
    /// frame (SPEC section 9; needs the camera model).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub table: Option<TableInputs>,
    /// The ball clicked once in a frame of the reference folder: its colour.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ball: Option<BallInputs>,
}
