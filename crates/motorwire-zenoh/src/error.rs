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
    /// Another bridge answers for this robot name already: two bridges
    /// would both run every command sent to it.
    #[error(
        "robot name {robot:?} is taken: bridge {} answers for motorwire/{robot} already (its Zenoh id); give this bridge another --robot, or stop that one",
        bridges.join(", bridge ")
    )]
    RobotTaken {
        /// The name.
        robot: String,
        /// The Zenoh ids of the bridges that answer for it.
        bridges: Vec<String>,
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
