//! Calibration (paper 2.7): inputs, the calibration file, and the measurements that make it.

pub mod auto;
pub mod ball;
pub mod camera;
pub mod compute;
pub mod file;
pub mod find;
mod image_size;
pub mod inputs;
mod kernel_search;
mod known;
mod limbs;
pub mod opencv;
pub mod rods;
mod silhouette;
pub mod table;
pub mod travel;
pub mod validate;

pub use ball::{BallCalibration, BallInputs};
pub use camera::{calibrate_camera, calibrate_camera_from_view};
pub use compute::{calibrate_rod, calibrate_rod_with, RodExtras, DEFAULT_VIEW_ANGLE_DEG};
pub use file::{
    angle_bias_at, CalibrationFile, CameraCalibration, EnhancedParams, PaperParams, Residuals,
    RodCalibration, CALIBRATION_VERSION,
};
pub use inputs::{
    CalibrationInputs, ImageSize, KnownPose, OpencvModel, ReferenceFrames, ReferencePose,
    RodInputs, TravelFrames,
};
pub use rods::calibrate_rods;
pub use table::{TableCalibration, TableInputs, TablePoint};
