#![doc = include_str!("../README.md")]

pub mod joint;
pub mod rig;

pub use joint::{
    DEDUP_WINDOW, Execution, JointConfig, JointLimits, JointStats, MAX_SENDERS, RESTART_SPAN,
    SimJoint, WATCHDOG_STOP,
};

use thiserror::Error;

/// What can go wrong building or running a simulated device.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[non_exhaustive]
pub enum SimError {
    /// A configuration value that cannot work.
    #[error("invalid joint configuration: {field}: {reason}")]
    InvalidConfig {
        /// The field.
        field: &'static str,
        /// Why.
        reason: String,
    },
    /// The bus failed.
    #[error(transparent)]
    Bus(#[from] motorwire_can::Error),
}
