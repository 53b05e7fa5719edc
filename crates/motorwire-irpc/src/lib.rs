#![doc = include_str!("../README.md")]
#![no_std]
#![cfg_attr(docsrs, feature(doc_cfg))]

mod error;
mod message;
mod nack;
mod payload;
#[cfg(feature = "planner")]
mod plan;
mod version;
mod wire;

pub use error::Error;
pub use message::{CAN_FD_LENGTHS, Header, MAX_FRAME_LEN, Message, Payload, can_fd_len};
pub use nack::NackCode;
pub use payload::{
    AdaptiveStatusPayload, CalibrationConfidence, CalibrationPhase, CalibrationRequest,
    CalibrationResult, CalibrationStatus, ConfigureAdaptivePayload, ConfigureTelemetryPayload,
    EmergencyReason, EmergencyStop, EncoderTelemetry, FaultCounters, FaultHistory, FaultRecord,
    LifecycleState, MotionProfile, MotorParameters, PowerConfig, PowerMetrics, SetTargetPayload,
    SetTargetPayloadV2, StallStatus, TelemetryMode, TelemetryStream,
};
pub use version::{PayloadKind, UnknownWireVersion, WireVersion};

/// [`Message`] under a name that cannot be mistaken for
/// `motorwire_wia::Message` (any WIA JSON message) in code that uses both:
/// the same type.
pub use message::Message as IrpcMessage;
/// [`MotionProfile`] (the wire enum of `SetTargetV2.profile`) under a name
/// that cannot be mistaken for `motorwire_planner::MotionProfile` (the
/// planner's, `motorwire_planner::PlannerMotionProfile`): the same type.
pub use payload::MotionProfile as IrpcMotionProfile;
