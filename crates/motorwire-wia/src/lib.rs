#![doc = include_str!("../README.md")]
#![cfg_attr(docsrs, feature(doc_cfg))]

mod check;
mod command;
mod error;
mod feedback;
mod flat;
mod kind;
mod members;
mod mode_config;
mod path;
mod pid;
mod plain;
mod rule;
mod safety;
mod schema;
mod serde_util;
mod setters;
mod trajectory;
mod validate;

pub use command::{
    AccelerationProfile, AxisCommand, CommandSafetyLimits, Coordination, CoordinationType,
    FilterConfig, ImpedanceParams, MotorCommand, MultiAxisCommand, PidGains, SyncMode,
};
/// [`Report`] (a document's validation verdict) under a name that cannot
/// be mistaken for `motorwire_translate::Report` (what a translation lost,
/// also `motorwire_translate::TranslationReport`): the same type.
pub use error::Report as ValidationReport;
pub use error::{Error, MAX_VIOLATIONS, Report};
pub use feedback::{MotorFeedback, MotorHealth, MotorStatus};
/// [`Message`] (any of the seven WIA messages) under a name that cannot be
/// mistaken for `motorwire_irpc::Message` (an iRPC frame's message, also
/// `motorwire_irpc::IrpcMessage`): the same type.
pub use kind::Message as AnyWiaMessage;
pub use kind::{
    Message, MessageKind, UnknownKindName, WiaMessage, scan_kind_noting, top_level_names,
};
pub use members::{STREAM, STREAM_SEQUENTIAL};
pub use mode_config::{ControlModeConfig, ModeLimits, ModeParameters};
pub use pid::{OutputLimits, PidConfig, PidConfigGains, SetpointFilter};
pub use rule::{Level, Rule, Violation};
pub use safety::{
    CollisionDetection, CurrentLimits, PositionLimits, SafetyLimits, ThermalLimits, TorqueLimits,
    VelocityLimits,
};
pub use schema::schema_validator;
pub use trajectory::{
    DURATION_TOLERANCE_MS, Interpolation, LoopConfig, Timing, Trajectory, TrajectoryConstraints,
    TrajectoryType, Waypoint,
};
pub use validate::{TimestampWindow, Validator, json_error_text};

/// Re-exported so users name the shared vocabulary through one crate.
pub use motorwire_core as core;
