//! The console's error type.

use std::net::SocketAddr;
use std::path::PathBuf;
use thiserror::Error;

/// Everything that can go wrong in the console.
#[derive(Debug, Error)]
pub enum ConsoleError {
    /// The listening socket could not be opened.
    #[error("cannot listen on {addr}: {source}")]
    Bind {
        /// The address asked for.
        addr: SocketAddr,
        /// Why.
        source: std::io::Error,
    },
    /// The console's thread or runtime could not be started.
    #[error("cannot start the console's runtime: {0}")]
    Runtime(std::io::Error),
    /// A request named a camera the console does not know or that has no frame.
    #[error("camera {camera}: {reason}")]
    Camera {
        /// Camera index.
        camera: u32,
        /// What is wrong.
        reason: String,
    },
    /// A request named a rod the camera's inputs do not hold.
    #[error("camera {camera}: no rod {rod} in the calibration inputs")]
    NoSuchRod {
        /// Camera index.
        camera: u32,
        /// Rod id.
        rod: u32,
    },
    /// A request's value is not acceptable.
    #[error("{field}: {reason}")]
    BadRequest {
        /// The field.
        field: &'static str,
        /// What is wrong.
        reason: String,
    },
    /// The console was started without a calibration output path.
    #[error("no calibration output file was given when the console was started")]
    NoOutputPath,
    /// An error from the core (frames, calibration).
    #[error(transparent)]
    Core(#[from] rodtrack_core::CoreError),
    /// A file could not be written.
    #[error("cannot write {path}: {source}")]
    Write {
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// A value could not be serialised.
    #[error("cannot serialise {what}: {reason}")]
    Serialize {
        /// What was being written.
        what: &'static str,
        /// Why.
        reason: String,
    },
}
