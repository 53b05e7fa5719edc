//! The crate's one error type.

/// What can go wrong starting or running a [`crate::Participant`].
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ZenohError {
    /// The robot name cannot be one chunk of a key expression.
    #[error("robot name {name:?}: {why}")]
    RobotName {
        /// The name given.
        name: String,
        /// Why it cannot be used.
        why: &'static str,
    },
    /// The Zenoh configuration could not be read or is not valid.
    #[error("zenoh configuration: {0}")]
    Config(String),
    /// Zenoh refused to open the session or to declare something on it.
    #[error("zenoh: {0}")]
    Zenoh(String),
    /// The participant's own threads could not be started.
    #[error("starting the zenoh participant's runtime: {0}")]
    Runtime(#[from] std::io::Error),
}

impl ZenohError {
    pub(crate) fn zenoh(e: impl std::fmt::Display) -> Self {
        Self::Zenoh(e.to_string())
    }
}
