//! Why an OpenCV file could not be read.

use thiserror::Error;

/// Why an OpenCV file (or an inline model) could not be read. The caller adds the file name.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum OpencvFileError {
    /// The text is not the YAML/JSON that OpenCV writes.
    #[error("line {line}: {reason}")]
    Syntax {
        /// 1-based line number.
        line: usize,
        /// What is wrong.
        reason: String,
    },
    /// A field is there but unusable.
    #[error("field `{field}`: {reason}")]
    Field {
        /// The field (key path, e.g. `camera_matrix.data`).
        field: String,
        /// What is wrong.
        reason: String,
    },
    /// A required field is missing.
    #[error("no {what} (looked for {looked_for}); fields found: {found}")]
    Missing {
        /// What is missing.
        what: &'static str,
        /// The key names accepted.
        looked_for: String,
        /// The keys the file has.
        found: String,
    },
}
