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

pub(crate) mod json;
mod numbers;
mod refusal;

pub(crate) use numbers::shortest;
pub use refusal::{Refusal, Wider};

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
        /// The result (boxed: a result is the largest line, and every
        /// output is moved through the bridge's queues).
        result: Box<LineResult>,
    },
    /// Whether a motion line's moves arrived, for its origin: one per
    /// motion line that moved something, after its result.
    Arrival {
        /// Whose line it answers.
        origin: Origin,
        /// The completion.
        arrival: ArrivalLine,
    },
    /// One joint's feedback, for every reader (boxed, as a result is).
    Feedback(Box<FeedbackLine>),
    /// Something that happened, for every reader.
    Event(Event),
    /// An event for one reader only: the `ready` a client that connects
    /// once the bridge is ready is greeted with ([`crate::Bridge::greet`]).
    ToOne {
        /// Who it is for.
        origin: Origin,
        /// The event.
        event: Event,
    },
}

impl Output {
    /// The line as JSON text (no newline).
    pub fn to_json(&self) -> String {
        let text = match self {
            // Written for every command: directly ([`json`]).
            Self::Result { result, .. } => {
                let mut j = json::Json::with_capacity(result.json_capacity());
                result.write_json(&mut j).map(|()| j.into_string())
            }
            Self::Arrival { arrival, .. } => {
                let mut j = json::Json::with_capacity(arrival.json_capacity());
                arrival.write_json(&mut j).map(|()| j.into_string())
            }
            Self::Feedback(f) => serde_json::to_string(f),
            Self::Event(e) | Self::ToOne { event: e, .. } => serde_json::to_string(e),
        };
        // Serializing these types cannot fail: no maps with non-string keys,
        // no non-finite floats (they are refused at the input).
        text.unwrap_or_else(|e| format!("{{\"event\":\"internal_error\",\"error\":\"{e}\"}}"))
    }

    /// Whose line it is: one client's (a result, a completion, a
    /// greeting), or `None` for every reader's (feedback, events).
    pub const fn reader(&self) -> Option<Origin> {
        match self {
            Self::Result { origin, .. }
            | Self::Arrival { origin, .. }
            | Self::ToOne { origin, .. } => Some(*origin),
            Self::Feedback(_) | Self::Event(_) => None,
        }
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
    /// Its target, in its unit (an f32, as the devices' setpoints are:
    /// written as its shortest decimal, `0.1` and not
    /// `0.10000000149011612`).
    pub target: f32,
    /// How far from the target it was when it arrived, or at the verdict
    /// (in its unit, an f32 as `target`; absent when no position was ever
    /// reported).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<f32>,
    /// When it arrived, from the result (ms).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub after_ms: Option<u64>,
}

fn is_zero(n: &u64) -> bool {
    *n == 0
}

/// Losses written as their texts.
fn loss_texts<S: serde::Serializer>(
    losses: &[motorwire_translate::Loss],
    s: S,
) -> Result<S::Ok, S::Error> {
    s.collect_seq(losses.iter().map(motorwire_translate::Loss::text))
}

/// The most losses or problems a result lists (the first; the rest are
/// counted): a result is one bounded line whatever its line held.
pub const MAX_LISTED: usize = 100;

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
    /// `Some(true)`: a completion line (`{"arrived":...}`) for this line
    /// will follow (it moved something). `Some(false)`: a stream's
    /// setpoint, which has none. Absent otherwise.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub arrival_follows: Option<bool>,
    /// A stream's setpoint replaced by a newer one of the motor before it
    /// was sent (never sent; what a stream does, so `ok` stays true).
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub superseded: bool,
    /// What became of each motor's part that was not acked.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub outcomes: Vec<StepReport>,
    /// Problems of a line that stopped anyway (an emergency stop carried by
    /// an otherwise invalid line).
    /// At most [`MAX_LISTED`]; the rest are counted in `more_problems`.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub problems: Vec<String>,
    /// Problems beyond those listed.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub more_problems: Option<usize>,
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
    /// What the translation could not carry exactly, each written as its
    /// text (`field: kind: detail`, [`motorwire_translate::Loss::text`]).
    /// Kept as the losses themselves: a result is written once, and the
    /// text is made only there.
    /// At most [`MAX_LISTED`]; the rest are counted in `more_losses`.
    #[serde(skip_serializing_if = "Vec::is_empty", serialize_with = "loss_texts")]
    pub losses: Vec<motorwire_translate::Loss>,
    /// Losses beyond those listed.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub more_losses: Option<usize>,
    /// For a request or calibration line: what the joint answered,
    /// `{"telemetry"|"power_metrics"|"fault_history"|"calibration_result": {...}}`
    /// (iRPC's field names, WIRE-FACTS §1.3).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub data: Option<Value>,
    /// For a SafetyLimits line or a limits query: the motor's limits in
    /// force now (`effective`) and the bus map's (`bus_map`), in its unit.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub limits: Option<Value>,
    /// For a state query (`{"query":"state"}`): the bridge's state now.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub state: Option<BridgeState>,
    /// For a feedback rate line (`{"feedback_hz":N}`): the rate the client
    /// now gets each motor's feedback at (Hz; 0: none), the bridge's own
    /// divided by [`LineResult::feedback_every`].
    #[serde(skip_serializing_if = "Option::is_none")]
    pub feedback_hz: Option<f64>,
    /// For a feedback rate line: each motor's every k-th feedback line is
    /// the client's (0: none). For whoever delivers the lines; not written.
    #[serde(skip)]
    pub feedback_every: Option<u32>,
}

impl LineResult {
    /// Keeps the first [`MAX_LISTED`] losses and problems, counting the
    /// rest (`more_losses`, `more_problems`).
    pub(crate) fn bound(&mut self) {
        fn cut<T>(list: &mut Vec<T>, more: &mut Option<usize>) {
            let over = list.len().saturating_sub(MAX_LISTED);
            if over > 0 {
                list.truncate(MAX_LISTED);
                *more = Some(more.unwrap_or(0).saturating_add(over));
            }
        }
        cut(&mut self.losses, &mut self.more_losses);
        cut(&mut self.problems, &mut self.more_problems);
    }
}

/// `v` as a person reads a rate: a whole number without a fraction, else
/// at most three decimals (`12.5`, `33.333`).
pub(crate) fn short_number(v: f64) -> String {
    let s = format!("{v:.3}");
    s.trim_end_matches('0').trim_end_matches('.').to_owned()
}

/// What the bridge knows of its motors now: in `ready`, in the answer to
/// `{"query":"state"}`, and in the `ready` a client connecting later is
/// greeted with.
#[derive(Debug, Clone, PartialEq, Default, Serialize)]
pub struct BridgeState {
    /// Whether the emergency stop is latched (nothing moves until
    /// `{"emergency_stop":false}`).
    pub latched: bool,
    /// Each motor of the bus map the bridge drives, in the map's order.
    pub motors: Vec<MotorState>,
}

/// One motor's state: `{"motor_id":"elbow","online":true,"active":true,
/// "position":45.0,"velocity":0.0,"moving":false}` (`target`, `fault`
/// when there are).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MotorState {
    /// Its name in the bus map.
    pub motor_id: String,
    /// Whether it was heard within the offline timeout.
    pub online: bool,
    /// Whether it takes motion now (an iRPC joint: Active; the other
    /// dialects have no lifecycle and always do).
    pub active: bool,
    /// Where it is, in its unit, as it last reported (absent: nothing
    /// reported yet).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub position: Option<f64>,
    /// How fast it moves, in its unit a second, as it last reported.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub velocity: Option<f64>,
    /// The target of its last move taken, in its unit.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub target: Option<f64>,
    /// Whether a move or a setpoint it took is still under way, as the
    /// bridge planned it.
    pub moving: bool,
    /// Why it takes nothing but a reset line (it faulted, rebooted or
    /// stopped itself).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fault: Option<String>,
}

/// Why a line was not done: its kind, the rule it broke (a stable name a
/// program can match on), a message for a person and, where the rule is
/// about a value, that value and the limit it broke as JSON values.
///
/// ```
/// use motorwire_bridge::{ErrorBody, ErrorKind};
/// let e = ErrorBody::new(ErrorKind::Busy, "64 lines are in progress");
/// assert_eq!(e.rule, "busy");
/// assert_eq!(
///     serde_json::to_string(&e)?,
///     r#"{"kind":"busy","rule":"busy","message":"64 lines are in progress"}"#
/// );
/// # Ok::<(), serde_json::Error>(())
/// ```
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ErrorBody {
    /// What kind of failure.
    pub kind: ErrorKind,
    /// The rule broken, one of [`rules`]: the gate's
    /// ([`motorwire_translate::Refusal::rule`]) or the bridge's own
    /// ([`BridgeRule`]) for `refused`, the kind's own name
    /// ([`ErrorKind::name`]) for every other kind.
    pub rule: &'static str,
    /// Said for a person.
    pub message: String,
    /// The motor it concerns, when one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub motor: Option<String>,
    /// The value and the limit the rule is about, where it names them
    /// (their members are the error's own in the JSON).
    #[serde(flatten, skip_serializing_if = "Option::is_none")]
    pub broke: Option<Box<Broke>>,
    /// The WIA violations, for `invalid`: at most
    /// [`motorwire_wia::MAX_VIOLATIONS`].
    #[serde(skip_serializing_if = "Option::is_none")]
    pub violations: Option<Value>,
    /// Violations found beyond those listed (saturating at `u32::MAX`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub more_violations: Option<u32>,
}

/// The value a refusal names and the limit it broke: `error.field`,
/// `value`, `limit`, `limit_name`, `limit_source`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Broke {
    /// The member of the line the rule is about (`setpoint`,
    /// `velocity_limit`, `path` for a planned path).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub field: Option<&'static str>,
    /// Its value (for `path`, the farthest position the path reaches), in
    /// the motor's unit.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub value: Option<f64>,
    /// The limit's value, in the motor's unit.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub limit: Option<f64>,
    /// The limit's name (`max_position`, `max_velocity`, ...).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub limit_name: Option<&'static str>,
    /// Where the limit came from: `bus map`, `the SafetyLimits line in
    /// force`, `command` (its own `safety_limits`), `Orion range`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub limit_source: Option<&'static str>,
}

impl Broke {
    /// What the gate's refusal `r` names, when it names a field or a limit.
    pub fn of(r: &motorwire_translate::Refusal) -> Option<Box<Self>> {
        let d = r.detail();
        (d.field.is_some() || d.limit.is_some()).then(|| {
            Box::new(Self {
                field: d.field,
                value: d.value,
                limit: d.bound,
                limit_name: d.limit,
                limit_source: d.source,
            })
        })
    }
}

impl ErrorBody {
    /// An error of `kind` saying `message`, its rule the kind's name. A
    /// `refused` error names its rule: [`ErrorBody::gate`] or
    /// [`ErrorBody::refused`].
    pub fn new(kind: ErrorKind, message: impl Into<String>) -> Self {
        Self {
            kind,
            rule: kind.name(),
            message: message.into(),
            motor: None,
            broke: None,
            violations: None,
            more_violations: None,
        }
    }

    /// A line refused by the bridge's own rule `rule`.
    pub fn refused(rule: BridgeRule, message: impl Into<String>) -> Self {
        Self {
            rule: rule.name(),
            ..Self::new(ErrorKind::Refused, message)
        }
    }

    /// A line refused by the gate (or the planner, or translation): its
    /// rule, its message and the values it names.
    ///
    /// ```
    /// use motorwire_bridge::ErrorBody;
    /// use motorwire_translate::Refusal;
    /// let r = Refusal::OutsideLimit {
    ///     motor: "elbow".into(), field: "setpoint", value: 170.0,
    ///     limit: "max_position", limit_source: "bus map", bound: 150.0,
    /// };
    /// assert_eq!(
    ///     serde_json::to_string(&ErrorBody::gate(&r))?,
    ///     r#"{"kind":"refused","rule":"outside_limit","message":"elbow: setpoint 170 is outside max_position (bus map) 150","motor":"elbow","field":"setpoint","value":170.0,"limit":150.0,"limit_name":"max_position","limit_source":"bus map"}"#
    /// );
    /// # Ok::<(), serde_json::Error>(())
    /// ```
    pub fn gate(r: &motorwire_translate::Refusal) -> Self {
        Self {
            rule: r.rule(),
            motor: r.detail().motor.map(str::to_owned),
            broke: Broke::of(r),
            ..Self::new(ErrorKind::Refused, r.to_string())
        }
    }

    /// The same, about `motor`.
    #[must_use]
    pub fn about(mut self, motor: impl Into<String>) -> Self {
        self.motor = Some(motor.into());
        self
    }
}

/// The kinds of failure a result reports (`error.kind`, written as
/// [`ErrorKind::name`] says).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
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

impl ErrorKind {
    /// Every kind, in the order of the variants.
    pub const ALL: [Self; 21] = [
        Self::Invalid,
        Self::UnsupportedKind,
        Self::Unsupported,
        Self::Refused,
        Self::Offline,
        Self::EmergencyStopLatched,
        Self::NotLatched,
        Self::NeedsReset,
        Self::InvalidRelease,
        Self::ShuttingDown,
        Self::Unreadable,
        Self::Busy,
        Self::Stale,
        Self::StaleBeforeStop,
        Self::Cancelled,
        Self::Superseded,
        Self::Nacked,
        Self::OutcomeUnknown,
        Self::NotSent,
        Self::NoAnswer,
        Self::IdReused,
    ];

    /// Its name in `error.kind` (and, for every kind but `refused`, in
    /// `error.rule`).
    pub const fn name(self) -> &'static str {
        match self {
            Self::Invalid => "invalid",
            Self::UnsupportedKind => "unsupported_kind",
            Self::Unsupported => "unsupported",
            Self::Refused => "refused",
            Self::Offline => "offline",
            Self::EmergencyStopLatched => "emergency_stop_latched",
            Self::NotLatched => "not_latched",
            Self::NeedsReset => "needs_reset",
            Self::InvalidRelease => "invalid_release",
            Self::ShuttingDown => "shutting_down",
            Self::Unreadable => "unreadable",
            Self::Busy => "busy",
            Self::Stale => "stale",
            Self::StaleBeforeStop => "stale_before_stop",
            Self::Cancelled => "cancelled",
            Self::Superseded => "superseded",
            Self::Nacked => "nacked",
            Self::OutcomeUnknown => "outcome_unknown",
            Self::NotSent => "not_sent",
            Self::NoAnswer => "no_answer",
            Self::IdReused => "id_reused",
        }
    }
}

impl Serialize for ErrorKind {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.name())
    }
}

/// The bridge's own rules for a `refused` line, beside the gate's
/// ([`motorwire_translate::Refusal::rule`]): `error.rule`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum BridgeRule {
    /// The line names a motor the bus map does not have
    /// (`unknown_motor`, the gate's name for the same).
    UnknownMotor,
    /// A request, reset or trajectory for a motor that is not an iRPC
    /// joint (`not_an_irpc_joint`).
    NotAnIrpcJoint,
    /// One motor named twice where once is the most (`motor_twice`).
    MotorTwice,
    /// A trajectory whose first waypoint is not where the joint is
    /// (`not_at_start`).
    NotAtStart,
    /// A time (`start_time`, a waypoint's) no clock of the bridge reaches
    /// (`time_unreachable`).
    TimeUnreachable,
    /// A SafetyLimits line wider than the bus map's limits
    /// (`wider_than_bus_map`).
    WiderThanBusMap,
    /// A SafetyLimits line that motion already accepted would break
    /// (`motion_outside_new_limits`).
    MotionOutsideNewLimits,
    /// A sequential multi-axis line with an axis that never arrives (a
    /// velocity or torque command) (`sequential_without_arrival`).
    SequentialWithoutArrival,
    /// An Orion motor, and no Orion controller attached
    /// (`orion_not_attached`).
    OrionNotAttached,
    /// A velocity or torque setpoint pointing past a position limit in
    /// force from a motor at that limit (`outward_at_limit`).
    OutwardAtLimit,
    /// A motor line its device has no means for (an Orion servo freed:
    /// the controller has no torque off) (`action_not_expressible`).
    ActionNotExpressible,
}

impl BridgeRule {
    /// Every rule, in the order of the variants.
    pub const ALL: [Self; 11] = [
        Self::UnknownMotor,
        Self::NotAnIrpcJoint,
        Self::MotorTwice,
        Self::NotAtStart,
        Self::TimeUnreachable,
        Self::WiderThanBusMap,
        Self::MotionOutsideNewLimits,
        Self::SequentialWithoutArrival,
        Self::OrionNotAttached,
        Self::OutwardAtLimit,
        Self::ActionNotExpressible,
    ];

    /// Its name in `error.rule`.
    pub const fn name(self) -> &'static str {
        match self {
            Self::UnknownMotor => "unknown_motor",
            Self::NotAnIrpcJoint => "not_an_irpc_joint",
            Self::MotorTwice => "motor_twice",
            Self::NotAtStart => "not_at_start",
            Self::TimeUnreachable => "time_unreachable",
            Self::WiderThanBusMap => "wider_than_bus_map",
            Self::MotionOutsideNewLimits => "motion_outside_new_limits",
            Self::SequentialWithoutArrival => "sequential_without_arrival",
            Self::OrionNotAttached => "orion_not_attached",
            Self::OutwardAtLimit => "outward_at_limit",
            Self::ActionNotExpressible => "action_not_expressible",
        }
    }
}

/// Every name an `error.rule` of the bridge can be, each once, sorted:
/// each kind's own name but `refused` (a refused line always names the
/// rule it broke), the gate's rules and the bridge's own.
///
/// ```
/// let rules = motorwire_bridge::rules();
/// assert!(rules.contains(&"outside_limit") && rules.contains(&"stale"));
/// assert!(!rules.contains(&"refused"));
/// ```
pub fn rules() -> Vec<&'static str> {
    let mut all: Vec<&'static str> = ErrorKind::ALL
        .iter()
        .filter(|k| **k != ErrorKind::Refused)
        .map(|k| k.name())
        .chain(motorwire_translate::Refusal::RULES.iter().copied())
        .chain(BridgeRule::ALL.iter().map(|r| r.name()))
        .collect();
    all.sort_unstable();
    all.dedup();
    all
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
    /// Said for a person (most are fixed texts, not copied for each
    /// step).
    pub message: std::borrow::Cow<'static, str>,
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
    /// Startup is over: lines are served. Each device was configured and
    /// activated, and read once (or found silent: `online` false), so its
    /// position is known from the first line on.
    Ready {
        /// The motors, in the bus map's order.
        joints: Vec<String>,
        /// Their state.
        #[serde(flatten)]
        state: BridgeState,
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
    /// Bytes on a serial servo port that were no status packet the bridge
    /// waited for (noise, a wrong check, a servo it did not ask, a late
    /// answer): reported and skipped, never acted on.
    BadServoPacket {
        /// The port (its index among the map's servo ports).
        port: u8,
        /// Why.
        error: String,
        /// Bad packets before this one that were not reported (at most ten
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
    /// A velocity or torque setpoint would have carried the motor past a
    /// position limit in force before it could stop (at the limits'
    /// deceleration, from where its feedback says it is and how fast it
    /// goes): it was brought to a stop (velocity 0) short of the limit.
    LimitBrake {
        /// The motor.
        motor_id: String,
        /// Where it was (the motor's unit).
        position: f64,
        /// How fast it went (the motor's unit a second).
        velocity: f64,
        /// The limit it was kept from: `min_position` or `max_position`.
        limit_name: &'static str,
        /// The limit's value.
        limit: f64,
    },
    /// A moteus controller's own position bounds (`servopos.position_min`
    /// and `servopos.position_max`, its running configuration) were set to
    /// the limits in force (within the bounds it was configured with), at
    /// start or after a SafetyLimits line changed them; or could not be
    /// (`error`): the bridge still holds the motor to the limits itself.
    DeviceBounds {
        /// The motor.
        motor_id: String,
        /// Its lower bound now (the motor's unit; absent: none).
        #[serde(skip_serializing_if = "Option::is_none")]
        min_position: Option<f64>,
        /// Its upper bound now (absent: none).
        #[serde(skip_serializing_if = "Option::is_none")]
        max_position: Option<f64>,
        /// Why they were not set.
        #[serde(skip_serializing_if = "Option::is_none")]
        error: Option<String>,
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
        /// Its `JointStatus.error_code` (a moteus controller's fault code,
        /// or 11 for its watchdog's timeout).
        code: u16,
        /// What the device said of it, where it stopped itself (a moteus
        /// controller's fault by name: `moteus fault 33: motor driver
        /// fault`); absent for an iRPC joint's `Error` state.
        #[serde(skip_serializing_if = "Option::is_none")]
        reason: Option<String>,
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

/// What a line's result (and its arrival line) is labelled with: the
/// member of the line that names what it is about.
///
/// ```
/// use motorwire_bridge::{Label, LineResult};
/// let mut r = LineResult::default();
/// Label::Motor("elbow".to_owned()).apply(&mut r);
/// assert_eq!(r.motor_id.as_deref(), Some("elbow"));
/// assert_eq!(Label::Command("pick".to_owned()).motor(), None);
/// ```
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Label {
    /// `motor_id`: a motor command, a trajectory, a request, a reset.
    Motor(String),
    /// `command_id`: a multi-axis command, several trajectories at once.
    Command(String),
    /// `orion`: the Orion controller's fold or unfold.
    Orion(String),
}

impl Label {
    /// The motor it names, if it names one.
    pub fn motor(&self) -> Option<&str> {
        match self {
            Self::Motor(m) => Some(m),
            Self::Command(_) | Self::Orion(_) => None,
        }
    }

    /// Writes it into the member of `r` it is.
    pub fn apply(self, r: &mut LineResult) {
        match self {
            Self::Motor(v) => r.motor_id = Some(v),
            Self::Command(v) => r.command_id = Some(v),
            Self::Orion(v) => r.orion = Some(v),
        }
    }
}

/// An input line: its origin and number.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct LineRef {
    /// Its origin.
    pub origin: Origin,
    /// Its number.
    pub line: u64,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_kind_is_listed_once_and_named_as_it_is_written() {
        for k in ErrorKind::ALL {
            // A new kind fails to compile here until it is listed.
            let listed = match k {
                ErrorKind::Invalid
                | ErrorKind::UnsupportedKind
                | ErrorKind::Unsupported
                | ErrorKind::Refused
                | ErrorKind::Offline
                | ErrorKind::EmergencyStopLatched
                | ErrorKind::NotLatched
                | ErrorKind::NeedsReset
                | ErrorKind::InvalidRelease
                | ErrorKind::ShuttingDown
                | ErrorKind::Unreadable
                | ErrorKind::Busy
                | ErrorKind::Stale
                | ErrorKind::StaleBeforeStop
                | ErrorKind::Cancelled
                | ErrorKind::Superseded
                | ErrorKind::Nacked
                | ErrorKind::OutcomeUnknown
                | ErrorKind::NotSent
                | ErrorKind::NoAnswer
                | ErrorKind::IdReused => ErrorKind::ALL.iter().filter(|o| **o == k).count(),
            };
            assert_eq!(listed, 1, "{k:?}");
            assert_eq!(
                serde_json::to_value(k).ok(),
                Some(Value::String(k.name().to_owned()))
            );
            // Its name is its variant's, in snake_case, and no other's.
            let snake: String = format!("{k:?}")
                .chars()
                .enumerate()
                .flat_map(|(i, c)| {
                    let lower = c.to_ascii_lowercase();
                    if c.is_ascii_uppercase() && i > 0 {
                        vec!['_', lower]
                    } else {
                        vec![lower]
                    }
                })
                .collect();
            assert_eq!(k.name(), snake);
        }
        for r in BridgeRule::ALL {
            let listed = match r {
                BridgeRule::UnknownMotor
                | BridgeRule::NotAnIrpcJoint
                | BridgeRule::MotorTwice
                | BridgeRule::NotAtStart
                | BridgeRule::TimeUnreachable
                | BridgeRule::WiderThanBusMap
                | BridgeRule::MotionOutsideNewLimits
                | BridgeRule::SequentialWithoutArrival
                | BridgeRule::OrionNotAttached
                | BridgeRule::OutwardAtLimit
                | BridgeRule::ActionNotExpressible => {
                    BridgeRule::ALL.iter().filter(|o| **o == r).count()
                }
            };
            assert_eq!(listed, 1, "{r:?}");
        }
        // Kinds (but refused), the gate's 11 and the bridge's 11, with
        // unknown_motor in both of the last two.
        assert_eq!(rules().len(), 20 + 11 + 11 - 1);
    }

    #[test]
    fn every_rule_is_in_the_readmes_table_and_the_table_has_no_other() {
        let readme = include_str!("../../README.md");
        let table = readme
            .split("## Refusal rules")
            .nth(1)
            .and_then(|t| t.split("\n## ").next())
            .unwrap_or_default();
        let listed: Vec<&str> = table
            .lines()
            .filter_map(|l| l.strip_prefix("| `"))
            .filter_map(|l| l.split('`').next())
            .collect();
        let mut sorted = listed.clone();
        sorted.sort_unstable();
        assert_eq!(sorted, rules(), "README table: {listed:?}");
    }

    #[test]
    fn a_refusal_by_the_bridges_own_rule_names_it() {
        let e = ErrorBody::refused(
            BridgeRule::MotorTwice,
            "elbow has two trajectories in one line",
        );
        assert_eq!(
            serde_json::to_string(&e).ok().as_deref(),
            Some(
                r#"{"kind":"refused","rule":"motor_twice","message":"elbow has two trajectories in one line"}"#
            )
        );
    }
}
