//! What the bridge says: one typed shape for each kind of line.
//!
//! Every line is one JSON object whose first key tells its kind: `ok` (the
//! result of an input line), `arrived` (whether a motion line's moves got
//! there, after its result), `feedback` (a joint's WIA MotorFeedback) or
//! `event` (something that happened). Fields come in the order declared
//! here; optional ones are left out when empty.

use motorwire_wia::MotorFeedback;
use serde::Serialize;
use serde_json::Value;

/// Who sent a line: the runner's name for an input (stdin, a TCP client).
/// Results go back to the origin of their line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
pub struct Origin(pub u64);

/// A line for someone to read.
#[derive(Debug, Clone, PartialEq)]
pub enum Output {
    /// The result of one input line, for its origin.
    Result {
        /// Whose line it answers.
        origin: Origin,
        /// The result.
        result: LineResult,
    },
    /// Whether a motion line's moves arrived, for its origin: one per
    /// motion line that moved something, after its result.
    Arrival {
        /// Whose line it answers.
        origin: Origin,
        /// The completion.
        arrival: ArrivalLine,
    },
    /// One joint's feedback, for every reader.
    Feedback(FeedbackLine),
    /// Something that happened, for every reader.
    Event(Event),
}

impl Output {
    /// The line as JSON text (no newline).
    pub fn to_json(&self) -> String {
        let text = match self {
            Self::Result { result, .. } => serde_json::to_string(result),
            Self::Arrival { arrival, .. } => serde_json::to_string(arrival),
            Self::Feedback(f) => serde_json::to_string(f),
            Self::Event(e) => serde_json::to_string(e),
        };
        // Serializing these types cannot fail: no maps with non-string keys,
        // no non-finite floats (they are refused at the input).
        text.unwrap_or_else(|e| format!("{{\"event\":\"internal_error\",\"error\":\"{e}\"}}"))
    }

    /// The line as a JSON value (for tests and tools that inspect it).
    pub fn to_value(&self) -> Value {
        serde_json::from_str(&self.to_json()).unwrap_or(Value::Null)
    }

    /// The result, if this is one.
    pub fn result(&self) -> Option<&LineResult> {
        match self {
            Self::Result { result, .. } => Some(result),
            _ => None,
        }
    }
}

/// A motion line's completion: `{"arrived":true,"line":N,...}` once every
/// motor it moved is within its `arrival_tolerance` of its target and at
/// rest, or `{"arrived":false,...,"reason":...}` when that will not happen
/// (stopped, superseded, timed out, the joint offline, the bridge ending).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ArrivalLine {
    /// Whether every motor arrived.
    pub arrived: bool,
    /// The line's number.
    pub line: u64,
    /// The line's `motor_id`, for a MotorCommand.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub motor_id: Option<String>,
    /// The line's `command_id`, for a multi-axis command.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub command_id: Option<String>,
    /// Why not, when it did not.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reason: Option<String>,
    /// From the result (the joints' Acks) to the arrival or the verdict (ms).
    pub after_ms: u64,
    /// Each motor.
    pub motors: Vec<MotorArrival>,
}

/// One motor of an [`ArrivalLine`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MotorArrival {
    /// The motor.
    pub motor_id: String,
    /// Whether it arrived.
    pub arrived: bool,
    /// Its target, in its unit.
    pub target: f64,
    /// How far from the target it was when it arrived, or at the verdict
    /// (in its unit; absent when no position was ever reported).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<f64>,
    /// When it arrived, from the result (ms).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub after_ms: Option<u64>,
}

fn is_zero(n: &u64) -> bool {
    *n == 0
}

/// The result of one input line: `{"ok":true,...}` or
/// `{"ok":false,"error":{...},...}`.
#[derive(Debug, Clone, PartialEq, Default, Serialize)]
pub struct LineResult {
    /// Whether every part of the line was done.
    pub ok: bool,
    /// The line's number among its origin's non-blank lines, from 1.
    pub line: u64,
    /// The MotorCommand's `motor_id`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub motor_id: Option<String>,
    /// The multi-axis command's `command_id`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub command_id: Option<String>,
    /// The Orion controller's command of an `{"orion":...}` line (`fold`,
    /// `unfold`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub orion: Option<String>,
    /// The line was an emergency stop (it stopped every joint).
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub emergency_stop: bool,
    /// The line released the emergency stop.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub released: bool,
    /// Why not, when `ok` is false.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<ErrorBody>,
    /// The motors whose every request was acked.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub acked: Option<Vec<String>>,
    /// A completion line (`{"arrived":...}`) for this line will follow:
    /// it moved something.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub arrival_follows: bool,
    /// What became of each motor's part that was not acked.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub outcomes: Vec<StepReport>,
    /// Problems of a line that stopped anyway (an emergency stop carried by
    /// an otherwise invalid line).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub problems: Vec<String>,
    /// From the line's arrival to its last frame on the bus (µs).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub latency_us: Option<u64>,
    /// From the line's arrival to its last answer (µs).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ack_us: Option<u64>,
    /// For an emergency stop: from the line's arrival to the last stop
    /// frame on the bus (µs).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stop_latency_us: Option<u64>,
    /// What the translation could not carry exactly.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub losses: Vec<String>,
    /// For a request or calibration line: what the joint answered,
    /// `{"telemetry"|"power_metrics"|"fault_history"|"calibration_result": {...}}`
    /// (iRPC's field names, WIRE-FACTS §1.3).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub data: Option<Value>,
    /// For a SafetyLimits line or a limits query: the motor's limits in
    /// force now (`effective`) and the bus map's (`bus_map`), in its unit.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub limits: Option<Value>,
}

/// Why a line was not done.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ErrorBody {
    /// What kind of failure.
    pub kind: ErrorKind,
    /// Said for a person.
    pub message: String,
    /// The motor it concerns, when one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub motor: Option<String>,
    /// Every WIA violation, for `invalid`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub violations: Option<Value>,
}

impl ErrorBody {
    /// An error of `kind` saying `message`.
    pub fn new(kind: ErrorKind, message: impl Into<String>) -> Self {
        Self {
            kind,
            message: message.into(),
            motor: None,
            violations: None,
        }
    }

    /// The same, about `motor`.
    #[must_use]
    pub fn about(mut self, motor: impl Into<String>) -> Self {
        self.motor = Some(motor.into());
        self
    }
}

/// The kinds of failure a result reports (`error.kind`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
#[non_exhaustive]
pub enum ErrorKind {
    /// Not JSON, or not valid WIA. Nothing was sent.
    Invalid,
    /// Valid WIA of a kind the bridge does not take. Nothing was sent.
    UnsupportedKind,
    /// Valid WIA the bridge understands but the joints cannot carry (PID
    /// gains, a control-mode configuration: iRPC has no such messages).
    Unsupported,
    /// Outside a limit, or not expressible for the motor. Nothing was sent.
    Refused,
    /// A motor of the line is offline. Nothing was sent.
    Offline,
    /// The emergency stop is latched. Nothing was sent.
    EmergencyStopLatched,
    /// A release with no stop latched.
    NotLatched,
    /// A joint of the line faulted or rebooted: it takes nothing until a
    /// reset line (`{"reset":"elbow"}`) brings it back. Nothing was sent.
    NeedsReset,
    /// A line that tries to release the stop but is not exactly
    /// `{"emergency_stop": false}`; the latch holds.
    InvalidRelease,
    /// The bridge is shutting down. Nothing was sent.
    ShuttingDown,
    /// The line could not be read (too long, not UTF-8, cut off).
    Unreadable,
    /// Too many lines waiting: refused at once. Nothing was sent.
    Busy,
    /// The command's timestamp is outside the allowed clock skew. Nothing was sent.
    Stale,
    /// The command's timestamp is older than the last emergency stop: it
    /// was written before the stop, and does not run after the release.
    /// Nothing was sent.
    StaleBeforeStop,
    /// An emergency stop (or the end) cancelled the line: what it had not
    /// sent never will be; what was in flight was stopped.
    Cancelled,
    /// A newer position command for the same joint replaced it before it
    /// was sent. Nothing of it was sent.
    Superseded,
    /// A joint refused its part (Nack).
    Nacked,
    /// A part was sent but never answered after every retry: the joint may
    /// or may not have executed it.
    OutcomeUnknown,
    /// A part could not be sent (not encodable for the joint's wire version).
    NotSent,
    /// A request was acked, but what it asked for (telemetry, power
    /// metrics, a fault history, a calibration result) never came, or the
    /// calibration failed.
    NoAnswer,
    /// A command id (a fleet query's `request_id` or `command_id`) that
    /// named another command: refused, nothing was sent. A retry must carry
    /// the same command as the first try.
    IdReused,
}

/// What became of one motor's part of a line.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StepReport {
    /// The motor.
    pub motor: String,
    /// What became of it.
    pub outcome: StepOutcome,
    /// The Nack code, for `nacked`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub code: Option<u16>,
    /// Said for a person.
    pub message: String,
}

/// What became of one motor's part of a line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum StepOutcome {
    /// Every request acked.
    Acked,
    /// A request was refused (Nack).
    Nacked,
    /// A request was sent and never answered.
    OutcomeUnknown,
    /// Cancelled by an emergency stop or the end.
    Cancelled,
    /// Replaced by a newer command before it was sent.
    Superseded,
    /// Could not be encoded for the joint, or what it waited for failed.
    NotSent,
}

impl StepOutcome {
    /// Its name on the wire (`acked`, `nacked`, ...).
    pub fn name(self) -> &'static str {
        match self {
            Self::Acked => "acked",
            Self::Nacked => "nacked",
            Self::OutcomeUnknown => "outcome_unknown",
            Self::Cancelled => "cancelled",
            Self::Superseded => "superseded",
            Self::NotSent => "not_sent",
        }
    }
}

/// One joint's feedback: `{"feedback":{WIA MotorFeedback}|null,"motor_id":...,"online":bool}`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FeedbackLine {
    /// The WIA MotorFeedback (`null` when nothing was heard yet).
    pub feedback: Option<MotorFeedback>,
    /// The motor.
    pub motor_id: String,
    /// Whether it was heard within the offline timeout.
    pub online: bool,
}

/// Something that happened: `{"event":"...",...}`.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "event", rename_all = "snake_case")]
#[non_exhaustive]
pub enum Event {
    /// A joint was configured and activated at startup, or failed to be.
    Startup {
        /// The motor.
        motor_id: String,
        /// Whether it is ready.
        ok: bool,
        /// Why not.
        #[serde(skip_serializing_if = "Option::is_none")]
        error: Option<StepReport>,
    },
    /// Startup is over: lines are served.
    Ready {
        /// The joints.
        joints: Vec<String>,
    },
    /// A joint went silent (or a request to it timed out).
    Offline {
        /// The motor.
        motor_id: String,
        /// Its node id.
        node: u16,
        /// Why.
        reason: String,
    },
    /// A joint was heard again.
    Online {
        /// The motor.
        motor_id: String,
        /// Its node id.
        node: u16,
    },
    /// A frame that is not an iRPC message for the bridge.
    BadFrame {
        /// Its CAN id.
        can_id: String,
        /// Why.
        error: String,
    },
    /// A joint's calibration progress (its `CalibrationStatus`).
    Calibration {
        /// The joint.
        motor_id: String,
        /// The phase (`inertia_test`, `friction_test`,
        /// `torque_constant_verification`, `damping_test`, `validation`,
        /// `complete`, `failed`).
        phase: String,
        /// Overall progress, 0 to 1.
        progress: f64,
        /// Seconds left.
        time_remaining: f64,
    },
    /// A line from the Orion arm controller that is not one of its
    /// messages (WIRE-FACTS §4.1): reported and skipped, never acted on.
    BadOrionLine {
        /// Why.
        error: String,
        /// Bad lines before this one that were not reported (at most ten
        /// are a second).
        #[serde(skip_serializing_if = "is_zero")]
        suppressed: u64,
    },
    /// The Orion arm controller sent its boot beacon (`{"ID":32}`):
    /// `first` when it is the first heard, otherwise the controller
    /// started again (every motor of it at rest, its values forgotten).
    OrionBeacon {
        /// Whether it is the first beacon heard.
        first: bool,
    },
    /// The link to the Orion arm controller ended or failed: its motors
    /// are offline from now on.
    OrionLinkLost {
        /// Why.
        error: String,
    },
    /// A velocity or torque setpoint was not renewed within the motor's
    /// command timeout: the device was brought to a stop (velocity 0).
    Deadman {
        /// The motor.
        motor_id: String,
        /// Its command timeout (ms).
        timeout_ms: u64,
    },
    /// The emergency stop was latched.
    EmergencyStop {
        /// What asked for it (`input`, a motor_id or command_id).
        cause: String,
        /// The input lines it cancelled, as `{"origin":..,"line":..}`.
        cancelled: Vec<LineRef>,
    },
    /// A joint reported a fault (it entered `Error`): it takes nothing
    /// until a reset line brings it back.
    JointFault {
        /// The joint.
        motor_id: String,
        /// Its `JointStatus.error_code`.
        code: u16,
    },
    /// A joint started again (heard `Unconfigured` while it was
    /// configured): it stays inactive, and is never moved by a command
    /// sent before, until a reset line brings it back.
    Rebooted {
        /// The joint.
        motor_id: String,
    },
    /// A client was disconnected by the bridge (it stopped reading its
    /// results, or its connection failed): its commands not yet done were
    /// cancelled (never sent, or never sent again).
    ClientDropped {
        /// The client.
        origin: Origin,
        /// Why.
        reason: String,
        /// Its lines cancelled.
        cancelled: Vec<LineRef>,
    },
    /// The emergency stop was released.
    Released {
        /// The joints activated again (those active when the stop came).
        reactivated: Vec<String>,
        /// The joints left inactive (they were not active when the stop
        /// came): a command for one is refused by the joint until it is
        /// activated again.
        #[serde(skip_serializing_if = "Vec::is_empty")]
        left_inactive: Vec<String>,
    },
    /// The bridge is stopping.
    Stopping {
        /// Why (`end of input`, `interrupted`).
        reason: String,
    },
    /// Every joint was deactivated; the bridge is done.
    Stopped {
        /// The joints that acked their Deactivate.
        deactivated: Vec<String>,
        /// The rest, with why.
        failures: Vec<StepReport>,
    },
    /// The bus reported an error.
    BusError {
        /// What it said.
        error: String,
    },
    /// A part whose outcome was unknown turned out executed: the joint's
    /// feedback shows it at that part's target.
    Outcome {
        /// The line's origin.
        origin: Option<Origin>,
        /// The line's number.
        line: u64,
        /// The motor.
        motor_id: String,
        /// What the feedback shows.
        outcome: &'static str,
        /// The position that shows it (the motor's unit).
        position: f64,
    },
}

/// An input line: its origin and number.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct LineRef {
    /// Its origin.
    pub origin: Origin,
    /// Its number.
    pub line: u64,
}
