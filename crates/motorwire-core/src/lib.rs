#![doc = include_str!("../README.md")]
#![no_std]
#![cfg_attr(docsrs, feature(doc_cfg))]

pub mod check;
mod error;
mod gains;
mod limits;
mod mode;
mod motor_id;
mod status;
mod units;

pub use error::CoreError;
pub use gains::{FilterConfig, FilterKind, ImpedanceParams, PidGains};
pub use limits::{MotionLimits, PositionLimits};
pub use mode::ControlMode;
pub use motor_id::MotorId;
pub use status::{Health, StatusFlag, StatusFlags};
pub use units::AngleUnit;
