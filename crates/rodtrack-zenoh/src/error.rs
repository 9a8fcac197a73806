//! The crate's error type.

/// What can go wrong on the network.
#[derive(Debug, thiserror::Error)]
pub enum ZenohError {
    /// A message that does not follow the layout.
    #[error("bad message: {0}")]
    Message(String),
    /// An option or name that cannot be used (a key expression, an endpoint, a camera).
    #[error("{0}")]
    Invalid(String),
    /// zenoh refused (the session, a config file, a publisher, a put).
    #[error("zenoh: {context}: {reason}")]
    Zenoh {
        /// What was being done.
        context: String,
        /// zenoh's message.
        reason: String,
    },
    /// The runtime pipeline of the fusion node.
    #[error("fusion pipeline: {0}")]
    Io(#[from] rodtrack_io::IoError),
}

impl ZenohError {
    /// A zenoh error while doing `context`.
    pub(crate) fn zenoh(context: impl Into<String>, e: impl std::fmt::Display) -> ZenohError {
        ZenohError::Zenoh {
            context: context.into(),
            reason: e.to_string(),
        }
    }
}
