//! The SDK's error type: every message names the file, field, camera or input concerned.
//!
//! ```
//! let e = rodtrack_sdk::read_calibration("missing.toml".as_ref()).unwrap_err();
//! assert!(e.to_string().contains("missing.toml"), "{e}");
//! ```

use rodtrack_core::CoreError;
use rodtrack_io::{IoError, SourceError};
use thiserror::Error;

/// What can go wrong while calibrating, opening sources or running a session.
///
/// ```
/// use rodtrack_sdk::SdkError;
/// let e = rodtrack_sdk::read_calibration("no/such/table.toml".as_ref()).unwrap_err();
/// assert!(matches!(e, SdkError::File { .. }));
/// assert!(e.to_string().contains("table.toml"), "{e}");
/// let e = rodtrack_sdk::mode_from_name("fast").unwrap_err();
/// assert!(matches!(e, SdkError::Invalid(_)));
/// ```
#[derive(Debug, Error)]
pub enum SdkError {
    /// A file (calibration, calibration inputs, camera model) cannot be read or is wrong.
    #[error("{reason}")]
    File {
        /// The file.
        path: String,
        /// What is wrong: a message that names the file, and the field when one is at fault.
        reason: String,
    },
    /// The algorithms refused something (a calibration, a frame).
    #[error("{context}: {source}")]
    Core {
        /// What was being done (`camera 0 (cam0)`, ...).
        context: String,
        /// The core's error.
        #[source]
        source: CoreError,
    },
    /// A frame source cannot be opened.
    #[error("{context}: {source}")]
    Source {
        /// The camera and input (`camera 0 (cam0): input sim://exp3`).
        context: String,
        /// The source's error.
        #[source]
        source: SourceError,
    },
    /// An output or input file operation failed.
    #[error("{context}: {source}")]
    Io {
        /// What was being done.
        context: String,
        /// The error.
        #[source]
        source: IoError,
    },
    /// Something failed while doing `context` (a camera's automatic calibration, ...).
    #[error("{context}: {source}")]
    Context {
        /// What was being done.
        context: String,
        /// The error.
        #[source]
        source: Box<dyn std::error::Error + Send + Sync>,
    },
    /// The session's settings do not fit together (inputs for cameras, ...).
    #[error("{0}")]
    Invalid(String),
    /// The runtime failed (a thread could not start, ...).
    #[error("{0}")]
    Runtime(String),
}

impl SdkError {
    pub(crate) fn file(path: &std::path::Path, reason: impl std::fmt::Display) -> SdkError {
        SdkError::File {
            path: path.display().to_string(),
            reason: reason.to_string(),
        }
    }

    pub(crate) fn core(context: impl std::fmt::Display, source: CoreError) -> SdkError {
        SdkError::Core {
            context: context.to_string(),
            source,
        }
    }
}

/// `.context(...)` on results whose error is a standard error: the error wrapped in
/// [`SdkError::Context`].
pub(crate) trait Context<T> {
    /// Wraps the error with `context`.
    fn context(self, context: impl std::fmt::Display) -> Result<T, SdkError>;
    /// Wraps the error with the context `f` makes (only on error).
    fn with_context<C: std::fmt::Display>(self, f: impl FnOnce() -> C) -> Result<T, SdkError>;
}

impl<T, E: std::error::Error + Send + Sync + 'static> Context<T> for Result<T, E> {
    fn context(self, context: impl std::fmt::Display) -> Result<T, SdkError> {
        self.map_err(|e| SdkError::Context {
            context: context.to_string(),
            source: Box::new(e),
        })
    }
    fn with_context<C: std::fmt::Display>(self, f: impl FnOnce() -> C) -> Result<T, SdkError> {
        self.map_err(|e| SdkError::Context {
            context: f().to_string(),
            source: Box::new(e),
        })
    }
}
