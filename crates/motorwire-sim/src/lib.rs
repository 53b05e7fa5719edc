#![doc = include_str!("../README.md")]

pub mod compact;
mod device;
pub mod joint;
pub mod moteus;
pub mod orion;
pub mod rig;
pub mod servo;

pub use compact::{
    CompactDeviceConfig, CompactDeviceLimits, CompactDeviceStats, CompactExecution, CompactOutcome,
    CompactRefusal, DEFAULT_FEEDBACK_PERIOD, FEEDBACK_NODE_BIT, SimCompactDevice,
};
pub use joint::{
    DEDUP_WINDOW, Execution, JointConfig, JointFault, JointLimits, JointStats, MAX_SENDERS,
    RESTART_SPAN, SimJoint, WATCHDOG_STOP,
};

use thiserror::Error;

/// What can go wrong building or running a simulated device.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[non_exhaustive]
pub enum SimError {
    /// A configuration value that cannot work.
    #[error("invalid simulated device configuration: {field}: {reason}")]
    InvalidConfig {
        /// The field.
        field: &'static str,
        /// Why.
        reason: String,
    },
    /// The bus failed.
    #[error(transparent)]
    Bus(#[from] motorwire_can::Error),
    /// The thread the simulated devices run on could not be started (what
    /// the operating system said).
    #[error("starting the simulated devices' thread: {0}")]
    Thread(String),
}
