//! The image size, shared by the calibration inputs and the OpenCV model files.

use serde::{Deserialize, Serialize};

/// Image size in pixels.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct ImageSize {
    /// Width, px.
    pub width: usize,
    /// Height, px.
    pub height: usize,
}
