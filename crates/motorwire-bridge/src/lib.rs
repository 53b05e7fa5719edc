#![doc = include_str!("../README.md")]

mod arrival;
mod classify;
mod device;
mod engine;
mod error;
mod job;
mod joints;
mod output;
pub mod record;
pub mod replay;
mod runtime;
pub mod sim;

pub use classify::{DEFAULT_CALIBRATION, Input, RequestKind, asks_for_stop, classify, members};
pub use engine::{
    Bridge, BridgeConfig, BridgeStats, DEFAULT_MAX_AGE_MS, JointView, MAX_BAD_LINE_EVENTS,
    MAX_ORION_LINE, ORION_POLL,
};
pub use error::BridgeError;
/// The WIA crate whose [`motorwire_wia::Validator`] [`classify`] takes.
pub use motorwire_wia;
pub use output::{
    ArrivalLine, BridgeRule, BridgeState, Broke, ErrorBody, ErrorKind, Event, FeedbackLine, Label,
    LineRef, LineResult, MotorArrival, MotorState, Origin, Output, StepOutcome, StepReport, rules,
};
pub use runtime::{
    DEFAULT_MAX_LINE, InputSender, MAX_ORION_LINES_PER_S, MAX_ORION_QUEUED,
    MAX_QUEUED_BYTES_PER_ORIGIN, MAX_QUEUED_PER_ORIGIN, MAX_SKIP, OrionPort, ReadLine, Runner,
    UNREADABLE_HEAD, feed, read_line,
};
