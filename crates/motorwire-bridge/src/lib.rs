#![doc = include_str!("../README.md")]

mod arrival;
mod classify;
mod clocks;
mod device;
mod engine;
mod error;
mod job;
mod joints;
mod output;
pub mod route;
mod runtime;
#[cfg(feature = "sim")]
pub mod sim;
pub mod tap;

pub use classify::{
    DEFAULT_CALIBRATION, Line, MotorAction, RequestKind, asks_for_stop, classify, members,
};
pub use clocks::clocks_together;
pub use device::DeviceState;
pub use device::orion::{MAX_BAD_LINE_EVENTS, MAX_ORION_LINE, POLL as ORION_POLL};
pub use engine::{
    Bridge, BridgeConfig, BridgeStats, Classified, DEFAULT_MAX_AGE_MS, Input, JointView,
};
pub use error::BridgeError;

/// The frame the bridge sends moteus controller `target` for `cmd`: its
/// CAN id and its data (padded with 0x50, the protocol's no-op): the
/// command with the bridge's query (the library's default registers with
/// the q current and the trajectory's completion), and a position move's
/// watchdog of five polls at the map's `query_rate_hz` (at least 0.25 s).
///
/// # Errors
/// [`MoteusFrameError`]: a target that is not a moteus controller, or the
/// codec's refusal.
pub fn moteus_frame(
    target: &motorwire_translate::Target,
    cmd: &motorwire_translate::MoteusCommand,
) -> Result<(u32, Vec<u8>), MoteusFrameError> {
    let motorwire_translate::Target::Moteus {
        id,
        bus,
        query_rate_hz,
        ..
    } = *target
    else {
        return Err(MoteusFrameError::NotMoteus(target.dialect()));
    };
    let period = std::time::Duration::from_millis(u64::from(1000 / query_rate_hz.max(1)).max(1));
    let f =
        device::moteus::command_frame(id, bus, cmd, Some(device::moteus::hold_watchdog(period)))
            .map_err(|e| MoteusFrameError::Codec(e.to_string()))?;
    Ok((f.id().raw(), f.data().to_vec()))
}

/// Whose a moteus frame on the bus is: `Some(true)` a reply from
/// controller `id` on prefix `bus` to the bridge, `Some(false)` the
/// bridge's own frame to it (heard back), `None` neither (`raw`: its
/// 29-bit CAN id).
///
/// ```
/// // The bridge (source 0) to controller 1 on prefix 0, and its answer.
/// assert_eq!(motorwire_bridge::moteus_addressed(0x8001, 1, 0), Some(false));
/// assert_eq!(motorwire_bridge::moteus_addressed(0x0100, 1, 0), Some(true));
/// assert_eq!(motorwire_bridge::moteus_addressed(0x0100, 2, 0), None);
/// ```
#[must_use]
pub fn moteus_addressed(raw: u32, id: u8, bus: u16) -> Option<bool> {
    device::moteus::addressed(raw, id, bus)
}

/// Why [`moteus_frame`] made no frame.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum MoteusFrameError {
    /// The target is not a moteus controller (its dialect).
    #[error("a {0} motor is not a moteus controller")]
    NotMoteus(&'static str),
    /// moteus's codec (or the CAN frame) refused the command: why.
    #[error("{0}")]
    Codec(String),
}
/// The WIA crate whose [`motorwire_wia::Validator`] [`classify`] takes.
pub use motorwire_wia;
pub use output::{
    ArrivalLine, BridgeRule, BridgeState, Broke, ErrorBody, ErrorKind, Event, FeedbackLine, Label,
    LineRef, LineResult, MAX_LISTED, MotorArrival, MotorState, Origin, Output, Refusal,
    StepOutcome, StepReport, Wider, rules,
};
pub use runtime::{
    DEFAULT_MAX_LINE, Gate, InputSender, MAX_ORION_LINES_PER_S, MAX_ORION_QUEUED,
    MAX_QUEUED_BYTES_PER_ORIGIN, MAX_QUEUED_PER_ORIGIN, MAX_READ_AHEAD, MAX_SERIAL_QUEUED,
    MAX_SKIP, OrionPort, ReadLine, Reopen, Runner, Secret, ServoLink, Stamped, UNREADABLE_HEAD,
    feed, feed_gated, feed_withholding, read_line,
};
