//! The core's error type.

use thiserror::Error;

/// Everything that can go wrong in the core.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum CoreError {
    /// A frame's size, stride or buffer does not fit.
    #[error("frame: {what}: expected {expected}, got {got}")]
    FrameSize {
        /// What was checked.
        what: &'static str,
        /// Expected value.
        expected: usize,
        /// Value found.
        got: usize,
    },
    /// A frame does not match what a rod's calibration was made for.
    #[error("frame does not match the calibration: {field}: expected {expected}, got {got}")]
    FrameMismatch {
        /// Which property.
        field: &'static str,
        /// Expected value.
        expected: String,
        /// Value found.
        got: String,
    },
    /// A marker description field is invalid.
    #[error("marker description: field `{field}` {reason}")]
    Marker {
        /// The field.
        field: &'static str,
        /// What is wrong.
        reason: String,
    },
    /// A camera model field is invalid.
    #[error("camera model: field `{field}` {reason}")]
    Camera {
        /// The field.
        field: &'static str,
        /// What is wrong.
        reason: String,
    },
    /// A file-level field of a calibration file is invalid.
    #[error("calibration field `{field}` {reason}")]
    FileField {
        /// The field.
        field: String,
        /// What is wrong.
        reason: String,
    },
    /// A camera-level field of calibration inputs or of a calibration file is invalid.
    #[error("camera {camera}: calibration field `{field}` {reason}")]
    CameraField {
        /// The camera: its index, and its name when known (`0 (cam0)`).
        camera: String,
        /// The field.
        field: String,
        /// What is wrong.
        reason: String,
    },
    /// A rod's calibration is invalid.
    #[error("rod {rod}: calibration field `{field}` {reason}")]
    Calibration {
        /// Rod id.
        rod: u32,
        /// The field.
        field: String,
        /// What is wrong.
        reason: String,
    },
    /// Calibration could not measure what it needs.
    #[error("rod {rod}: calibration failed: {reason}")]
    CalibrationFailed {
        /// Rod id.
        rod: u32,
        /// Why.
        reason: String,
    },
    /// Automatic calibration could not find or follow the markers.
    #[error("{camera}: {reason}")]
    AutoCalibration {
        /// The camera (`camera 0 (INPUT)`).
        camera: String,
        /// Why.
        reason: String,
    },
    /// The ball's events' table geometry or rules are invalid.
    #[error("events: `{field}` {reason}")]
    Events {
        /// The field.
        field: &'static str,
        /// What is wrong.
        reason: String,
    },
}
