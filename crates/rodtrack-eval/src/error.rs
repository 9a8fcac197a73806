//! The crate's error type.

use std::path::PathBuf;
use thiserror::Error;

/// What can go wrong while evaluating or scoring.
#[derive(Debug, Error)]
pub enum EvalError {
    /// The simulator refused something (a scenario name, a frame, a camera).
    #[error(transparent)]
    Sim(#[from] rodtrack_sim::SimError),
    /// The algorithms refused something (a calibration, a frame).
    #[error(transparent)]
    Core(#[from] rodtrack_core::CoreError),
    /// A frame source or a measurement file failed.
    #[error(transparent)]
    Io(#[from] rodtrack_io::IoError),
    /// The tracking session failed.
    #[error(transparent)]
    Sdk(#[from] rodtrack_sdk::SdkError),
    /// A measurement file cannot be read.
    #[error("reading {}", .path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: rodtrack_io::IoError,
    },
    /// An output file cannot be written.
    #[error("writing {}", .path.display())]
    Write {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// A plot cannot be drawn or written.
    #[error("{context}")]
    Plot {
        /// What was being done (`drawing fig13.png`).
        context: String,
        /// Why.
        #[source]
        source: Box<EvalError>,
    },
    /// JSON encoding failed.
    #[error(transparent)]
    Json(#[from] serde_json::Error),
    /// Anything else (a thread panicked, a scenario failed): the message says what.
    #[error("{0}")]
    Failed(String),
}

/// The error and its causes joined by `: ` (as `anyhow`'s `{:#}` prints them).
pub fn error_chain(e: &(dyn std::error::Error + 'static)) -> String {
    let mut out = e.to_string();
    let mut cause = e.source();
    while let Some(c) = cause {
        out.push_str(": ");
        out.push_str(&c.to_string());
        cause = c.source();
    }
    out
}
