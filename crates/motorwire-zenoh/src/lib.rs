#![doc = include_str!("../README.md")]

mod error;
mod ids;
mod keys;
mod participant;

pub use error::ZenohError;
pub use ids::{CONTROLLER_IDLE, CONTROLLERS, IDS_PER_CONTROLLER};
pub use keys::{FLEET_ESTOP, RobotKeys};
pub use participant::{
    ALIVE_CHECK, DEFAULT_SESSION_TIMEOUT, FleetConfig, MAX_QUERIES_IN_PROGRESS, PUBLISH_QUEUE,
    Participant, QUERY_ORIGINS, RETRY_OPEN, STOP_LINE, STOP_ORIGINS, config_from_file,
};
/// The Zenoh crate this participant is built on (its configuration type
/// is [`FleetConfig::zenoh`]'s).
pub use zenoh;
