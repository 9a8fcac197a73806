//! The simulator's error type.

use thiserror::Error;

/// Everything that can go wrong in the simulator.
#[derive(Debug, Error)]
pub enum SimError {
    /// A scenario name that does not exist.
    #[error("unknown scenario `{name}`; known: {known}")]
    UnknownScenario {
        /// The name asked for.
        name: String,
        /// The names that exist.
        known: String,
    },
    /// A camera index out of range.
    #[error("camera {index} does not exist (have {count})")]
    NoSuchCamera {
        /// Index asked for.
        index: usize,
        /// Number of cameras.
        count: usize,
    },
    /// A rod index out of range.
    #[error("rod {index} does not exist (have {count})")]
    NoSuchRod {
        /// Index asked for.
        index: usize,
        /// Number of rods.
        count: usize,
    },
    /// A frame index out of range.
    #[error("frame {index} is past the scenario's end ({count} frames)")]
    NoSuchFrame {
        /// Index asked for.
        index: usize,
        /// Number of frames.
        count: usize,
    },
    /// The output buffer is too small.
    #[error("output buffer too short: expected {expected} bytes, got {got}")]
    BufferSize {
        /// Bytes needed.
        expected: usize,
        /// Bytes given.
        got: usize,
    },
    /// A pixel format the simulator does not render.
    #[error("camera `{camera}`: pixel format `{format}` is not supported by the simulator (use an 8-bit Bayer format, mono8 or rgb8)")]
    UnsupportedFormat {
        /// Camera name.
        camera: String,
        /// Format name.
        format: String,
    },
    /// The configuration is inconsistent.
    #[error("invalid simulator configuration: {0}")]
    Config(String),
    /// The marker description is invalid.
    #[error(transparent)]
    Core(#[from] rodtrack_core::CoreError),
    /// Writing a recording failed.
    #[error("cannot write `{path}`: {reason}")]
    Io {
        /// The file or folder.
        path: String,
        /// Why.
        reason: String,
    },
}
