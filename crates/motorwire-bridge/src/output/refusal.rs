//! Every refusal and failure the engine gives a line, one variant each,
//! turned into the wire's `error` in one place ([`From<Refusal>` for
//! `ErrorBody`](ErrorBody)): its kind, its rule, its message and the values
//! it names. The engine builds refusals from what it knows (a motor, a
//! value, a limit) and never writes a message itself.

use std::borrow::Cow;
use std::time::Duration;

use serde_json::Value;

use super::{BridgeRule, Broke, ErrorBody, ErrorKind, StepOutcome, StepReport, short_number};

/// Why the bridge refused a line, or why a line it took failed.
///
/// ```
/// use motorwire_bridge::{ErrorBody, Refusal};
/// let e = ErrorBody::from(Refusal::QueueFull { motor: "elbow".into(), max: 16 });
/// assert_eq!(
///     serde_json::to_string(&e)?,
///     r#"{"kind":"busy","rule":"busy","message":"elbow has 16 steps waiting, the most it takes; nothing was sent, send it again later","motor":"elbow"}"#
/// );
/// # Ok::<(), serde_json::Error>(())
/// ```
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum Refusal {
    /// The line could not be read (too long, not UTF-8, cut off): the
    /// reader's reason.
    Unreadable {
        /// What the reader found.
        reason: String,
    },
    /// Not JSON, or not valid WIA: the validator's message and violations
    /// (the first [`motorwire_wia::MAX_VIOLATIONS`], `more` beyond).
    Invalid {
        /// The validator's summary.
        message: String,
        /// The violations listed.
        violations: Option<Value>,
        /// How many more were found.
        more: usize,
    },
    /// A sequential multi-axis line that also gives
    /// `coordination.total_duration_ms`.
    SequentialWithTotalDuration,
    /// A `feedback_hz` the bridge cannot give.
    FeedbackRate {
        /// The rate asked.
        asked: f64,
        /// The bridge's own rate (`None`: it sends no feedback).
        bridge_hz: Option<f64>,
    },
    /// Valid WIA of a kind the bridge does not take.
    UnsupportedKind {
        /// Its kind (`Trajectory`, ...).
        kind: motorwire_wia::MessageKind,
    },
    /// A PIDConfig: no dialect carries gains.
    PidGains,
    /// A ControlModeConfig: no dialect carries one.
    ControlModeConfig,
    /// A request of a message the joint's wire version has not.
    NoSuchMessage {
        /// The motor.
        motor: String,
        /// Its wire version (`v2.1`).
        wire: &'static str,
        /// The message (`PowerMetrics (v2.2)`).
        what: String,
    },
    /// The bridge is shutting down.
    ShuttingDown,
    /// A stop after the bridge has stopped every joint and ended.
    AlreadyStopped,
    /// The bridge was interrupted before the line was served.
    Interrupted,
    /// The emergency stop is latched.
    Latched,
    /// A reset while the emergency stop is latched.
    LatchedReset,
    /// A release with no stop latched.
    NotLatched,
    /// A release a stop sent after it overtook.
    StopOvertookRelease,
    /// A line that tries to release the stop but is not exactly
    /// `{"emergency_stop": false}`: the classifier's reason.
    BadRelease {
        /// What is wrong with it.
        reason: String,
    },
    /// The line reached the bridge before the last emergency stop.
    ArrivedBeforeStop {
        /// By how much.
        early: Duration,
    },
    /// The line's timestamp is before the last emergency stop.
    StampedBeforeStop {
        /// Its timestamp (Unix ms).
        timestamp: f64,
        /// The stop's (Unix ms).
        stop_ms: f64,
    },
    /// The line's timestamp is outside the allowed clock skew.
    Stale {
        /// Its timestamp (Unix ms).
        timestamp: f64,
        /// How old it is (ms; negative: in the future).
        age_ms: f64,
        /// The skew allowed.
        max_age: Duration,
        /// Whether read in microseconds it would have been within it.
        microseconds: bool,
    },
    /// A trajectory whose `timing.start_time` is further ahead than the
    /// clock skew allowed.
    StartTooFarAhead {
        /// Its start time (Unix ms).
        start_ms: f64,
        /// How far ahead (ms).
        ahead_ms: f64,
        /// The skew allowed.
        max_age: Duration,
    },
    /// A motor that faulted or rebooted takes nothing but a reset.
    NeedsReset {
        /// The motor.
        motor: String,
        /// What happened to it (`faulted: ...`).
        why: String,
    },
    /// A motor of the line is offline.
    Offline {
        /// The motor.
        motor: String,
        /// Why, where its driver knows.
        why: Option<String>,
    },
    /// As many lines are in progress as the bridge takes.
    LinesInProgress {
        /// The most.
        max: usize,
    },
    /// As many steps wait for a motor as it takes.
    QueueFull {
        /// The motor.
        motor: String,
        /// The most.
        max: usize,
    },
    /// As many lines wait for the joints to start as the bridge keeps.
    WaitingForStart,
    /// The gate's (or the planner's, or translation's) refusal.
    Gate {
        /// The refusal (boxed: it is the largest, and refusals are
        /// passed back through admission on every line).
        refusal: Box<motorwire_translate::Refusal>,
        /// The motor of the line's axis it concerns (said in place of the
        /// one the refusal names, where given).
        motor: Option<String>,
    },
    /// A motor the bus map does not have.
    UnknownMotor {
        /// The name given.
        motor: String,
    },
    /// A request, trajectory or command for a motor that is not an iRPC
    /// joint.
    NotAnIrpcJoint {
        /// The motor.
        motor: String,
    },
    /// A reset of a motor that takes none.
    NoReset {
        /// The motor.
        motor: String,
    },
    /// One motor with two trajectories in a line.
    MotorTwice {
        /// The motor.
        motor: String,
    },
    /// A trajectory whose first waypoint is not where the joint is.
    NotAtStart {
        /// The motor.
        motor: String,
        /// The first waypoint (the motor's unit).
        first: f64,
        /// Where it is (`None`: not known).
        at: Option<f64>,
    },
    /// A `timing.start_time` no clock of the bridge reaches.
    StartUnreachable {
        /// The start time (Unix ms).
        start_ms: f64,
    },
    /// A waypoint time no clock of the bridge reaches.
    WaypointUnreachable {
        /// The motor.
        motor: String,
    },
    /// A SafetyLimits line wider than the bus map's limits.
    WiderThanBusMap {
        /// The motor.
        motor: String,
        /// Each limit that is wider.
        wider: Vec<Wider>,
    },
    /// A SafetyLimits line motion already accepted would break.
    MotionOutsideNewLimits {
        /// The motor.
        motor: String,
        /// What of its motion (`its move under way goes to 140`).
        motion: String,
    },
    /// A sequential multi-axis line with an axis that never arrives.
    SequentialWithoutArrival {
        /// The motor of that axis.
        motor: String,
        /// Its control mode (`velocity`, `torque`).
        mode: &'static str,
    },
    /// No Orion controller is attached, for an Orion line.
    OrionNotAttached,
    /// An Orion motor named, and no Orion controller attached.
    OrionMotorNotAttached {
        /// The motor.
        motor: String,
    },
    /// A velocity or torque toward a position limit the motor could not
    /// stop before.
    OutwardAtLimit {
        /// The motor.
        motor: String,
        /// Where it is.
        at: f64,
        /// `velocity` or `torque`.
        mode: &'static str,
        /// The setpoint.
        setpoint: f64,
        /// `max_position` or `min_position`.
        limit_name: &'static str,
        /// Where that limit came from.
        source: &'static str,
        /// The limit.
        limit: f64,
    },
    /// A motor line its device has no means for.
    ActionNotExpressible {
        /// The motor.
        motor: String,
        /// Why (the device's, or the planner's, reason).
        why: String,
        /// The motor is not up (never started, or its start failed): a
        /// reset starts it.
        not_active: bool,
    },
    /// A stop (or the end, a reset, a lost joint) cut the line.
    Cut {
        /// What cut it.
        why: String,
        /// A part was in flight and not answered when it came.
        unknown: bool,
        /// The one motor of the line, where one.
        motor: Option<String>,
    },
    /// Parts of the line failed: the gravest outcome (an unknown outcome,
    /// then a refusal, then what was never sent), as [`Refusal::failed`]
    /// finds it.
    Failed {
        /// That outcome.
        outcome: StepOutcome,
        /// Its step's own message, for one superseded.
        message: Option<Cow<'static, str>>,
        /// The one motor of the line, where one.
        motor: Option<String>,
    },
    /// A request was acked, and what it asked for never came (or failed).
    NoAnswer {
        /// What the driver says of it.
        why: String,
    },
}

/// A limit of a SafetyLimits line wider than the bus map's.
#[derive(Debug, Clone, PartialEq)]
pub struct Wider {
    /// The line's member (`position_limits.max`).
    pub field: &'static str,
    /// Its value.
    pub value: f64,
    /// The bus map's limit (`max_position`).
    pub map_field: &'static str,
    /// Its value.
    pub bound: f64,
}

impl Refusal {
    /// The gate's refusal `refusal`, as it names its motor.
    #[must_use]
    pub fn gate(refusal: motorwire_translate::Refusal) -> Self {
        Self::Gate {
            refusal: Box::new(refusal),
            motor: None,
        }
    }

    /// The error of a line whose parts did not all succeed (`failures`):
    /// cut by `cut` (a stop, the end, a reset, a lost joint), or the
    /// gravest outcome among them.
    #[must_use]
    pub fn failed(failures: &[StepReport], cut: Option<&str>) -> Self {
        let motor = match failures {
            [only] => Some(only.motor.clone()),
            _ => None,
        };
        if let Some(why) = cut {
            return Self::Cut {
                why: why.to_owned(),
                unknown: failures
                    .iter()
                    .any(|f| f.outcome == StepOutcome::OutcomeUnknown),
                motor,
            };
        }
        let rank = |o: StepOutcome| match o {
            StepOutcome::OutcomeUnknown => 0,
            StepOutcome::Nacked => 1,
            StepOutcome::Cancelled => 2,
            StepOutcome::Superseded => 3,
            StepOutcome::NotSent => 4,
            StepOutcome::Acked => 5,
        };
        let worst = failures.iter().min_by_key(|f| rank(f.outcome));
        Self::Failed {
            outcome: worst.map_or(StepOutcome::NotSent, |f| f.outcome),
            message: worst
                .filter(|f| f.outcome == StepOutcome::Superseded)
                .map(|f| f.message.clone()),
            motor,
        }
    }

    /// Its kind (`error.kind`).
    #[must_use]
    pub fn kind(&self) -> ErrorKind {
        use ErrorKind as K;
        match self {
            Self::Unreadable { .. } => K::Unreadable,
            Self::Invalid { .. }
            | Self::SequentialWithTotalDuration
            | Self::FeedbackRate { .. } => K::Invalid,
            Self::UnsupportedKind { .. } => K::UnsupportedKind,
            Self::PidGains | Self::ControlModeConfig | Self::NoSuchMessage { .. } => K::Unsupported,
            Self::ShuttingDown | Self::AlreadyStopped => K::ShuttingDown,
            Self::Interrupted | Self::StopOvertookRelease | Self::Cut { .. } => K::Cancelled,
            Self::Latched | Self::LatchedReset => K::EmergencyStopLatched,
            Self::NotLatched => K::NotLatched,
            Self::BadRelease { .. } => K::InvalidRelease,
            Self::ArrivedBeforeStop { .. } | Self::StampedBeforeStop { .. } => K::StaleBeforeStop,
            Self::Stale { .. } | Self::StartTooFarAhead { .. } => K::Stale,
            Self::NeedsReset { .. } => K::NeedsReset,
            Self::Offline { .. } => K::Offline,
            Self::LinesInProgress { .. } | Self::QueueFull { .. } | Self::WaitingForStart => {
                K::Busy
            }
            Self::Gate { .. }
            | Self::UnknownMotor { .. }
            | Self::NotAnIrpcJoint { .. }
            | Self::NoReset { .. }
            | Self::MotorTwice { .. }
            | Self::NotAtStart { .. }
            | Self::StartUnreachable { .. }
            | Self::WaypointUnreachable { .. }
            | Self::WiderThanBusMap { .. }
            | Self::MotionOutsideNewLimits { .. }
            | Self::SequentialWithoutArrival { .. }
            | Self::OrionNotAttached
            | Self::OrionMotorNotAttached { .. }
            | Self::OutwardAtLimit { .. }
            | Self::ActionNotExpressible { .. } => K::Refused,
            Self::Failed { outcome, .. } => match outcome {
                StepOutcome::OutcomeUnknown => K::OutcomeUnknown,
                StepOutcome::Nacked => K::Nacked,
                StepOutcome::Cancelled => K::Cancelled,
                StepOutcome::Superseded => K::Superseded,
                StepOutcome::NotSent | StepOutcome::Acked => K::NotSent,
            },
            Self::NoAnswer { .. } => K::NoAnswer,
        }
    }

    /// The bridge's own rule it broke, for a refusal by one.
    #[must_use]
    pub fn bridge_rule(&self) -> Option<BridgeRule> {
        use BridgeRule as R;
        Some(match self {
            Self::UnknownMotor { .. } => R::UnknownMotor,
            Self::NotAnIrpcJoint { .. } | Self::NoReset { .. } => R::NotAnIrpcJoint,
            Self::MotorTwice { .. } => R::MotorTwice,
            Self::NotAtStart { .. } => R::NotAtStart,
            Self::StartUnreachable { .. } | Self::WaypointUnreachable { .. } => R::TimeUnreachable,
            Self::WiderThanBusMap { .. } => R::WiderThanBusMap,
            Self::MotionOutsideNewLimits { .. } => R::MotionOutsideNewLimits,
            Self::SequentialWithoutArrival { .. } => R::SequentialWithoutArrival,
            Self::OrionNotAttached | Self::OrionMotorNotAttached { .. } => R::OrionNotAttached,
            Self::OutwardAtLimit { .. } => R::OutwardAtLimit,
            Self::ActionNotExpressible { .. } => R::ActionNotExpressible,
            _ => return None,
        })
    }

    /// Its rule (`error.rule`): the gate's, the bridge's own, or the
    /// kind's name.
    #[must_use]
    pub fn rule(&self) -> &'static str {
        match self {
            Self::Gate { refusal, .. } => refusal.rule(),
            _ => self
                .bridge_rule()
                .map_or_else(|| self.kind().name(), BridgeRule::name),
        }
    }

    /// The motor it concerns, where one.
    #[must_use]
    pub fn motor(&self) -> Option<&str> {
        match self {
            Self::NoSuchMessage { motor, .. }
            | Self::NeedsReset { motor, .. }
            | Self::Offline { motor, .. }
            | Self::QueueFull { motor, .. }
            | Self::UnknownMotor { motor }
            | Self::NotAnIrpcJoint { motor }
            | Self::NoReset { motor }
            | Self::WiderThanBusMap { motor, .. }
            | Self::MotionOutsideNewLimits { motor, .. }
            | Self::SequentialWithoutArrival { motor, .. }
            | Self::OrionMotorNotAttached { motor }
            | Self::OutwardAtLimit { motor, .. }
            | Self::ActionNotExpressible { motor, .. } => Some(motor),
            Self::Gate { refusal, motor } => motor.as_deref().or(refusal.detail().motor),
            Self::Cut { motor, .. } | Self::Failed { motor, .. } => motor.as_deref(),
            _ => None,
        }
    }

    /// Said for a person (`error.message`): one arm a variant, so none is
    /// left unsaid; words longer than an arm are made by the helpers below
    /// `impl Refusal`, by group.
    #[must_use]
    pub fn message(&self) -> Cow<'static, str> {
        let s = |t: String| Cow::Owned(t);
        match self {
            // The line itself.
            Self::Unreadable { reason } => s(reason.clone()),
            Self::Invalid { message, .. } => s(message.clone()),
            Self::SequentialWithTotalDuration => SEQUENTIAL_WITH_TOTAL_DURATION.into(),
            Self::FeedbackRate { asked, bridge_hz } => s(feedback_rate(*asked, *bridge_hz)),
            Self::UnsupportedKind { kind } => s(unsupported_kind(kind)),
            Self::PidGains => PID_GAINS.into(),
            Self::ControlModeConfig => CONTROL_MODE_CONFIG.into(),
            Self::NoSuchMessage { motor, wire, what } => s(no_such_message(motor, wire, what)),
            // The bridge's end, the stop and the clock.
            Self::ShuttingDown => "the bridge is shutting down".into(),
            Self::AlreadyStopped => "the bridge has already deactivated every joint".into(),
            Self::Interrupted => "the bridge was interrupted before the line was served".into(),
            Self::Latched => LATCHED.into(),
            Self::LatchedReset => LATCHED_RESET.into(),
            Self::NotLatched => "there is no emergency stop to release".into(),
            Self::StopOvertookRelease => STOP_OVERTOOK_RELEASE.into(),
            Self::BadRelease { reason } => s(reason.clone()),
            Self::ArrivedBeforeStop { early } => s(arrived_before_stop(*early)),
            Self::StampedBeforeStop { timestamp, stop_ms } => {
                s(stamped_before_stop(*timestamp, *stop_ms))
            }
            Self::Stale {
                timestamp,
                age_ms,
                max_age,
                microseconds,
            } => s(stale(*timestamp, *age_ms, *max_age, *microseconds)),
            Self::StartTooFarAhead {
                start_ms,
                ahead_ms,
                max_age,
            } => s(start_too_far_ahead(*start_ms, *ahead_ms, *max_age)),
            // The motor, and the bridge busy.
            Self::NeedsReset { motor, why } => s(needs_reset(motor, why)),
            Self::Offline { motor, why } => s(offline(motor, why.as_deref())),
            Self::LinesInProgress { max } => s(lines_in_progress(*max)),
            Self::QueueFull { motor, max } => s(queue_full(motor, *max)),
            Self::WaitingForStart => WAITING_FOR_START.into(),
            // A rule broken: the gate's or the bridge's own.
            Self::Gate { refusal, .. } => s(refusal.to_string()),
            Self::UnknownMotor { motor } => s(format!("motor {motor:?} is not in the bus map")),
            Self::NotAnIrpcJoint { motor } => s(not_an_irpc_joint(motor)),
            Self::NoReset { motor } => s(no_reset(motor)),
            Self::MotorTwice { motor } => s(format!("{motor} has two trajectories in one line")),
            Self::NotAtStart { motor, first, at } => s(not_at_start(motor, *first, *at)),
            Self::StartUnreachable { start_ms } => s(start_unreachable(*start_ms)),
            Self::WaypointUnreachable { motor } => s(waypoint_unreachable(motor)),
            Self::WiderThanBusMap { motor, wider } => s(wider_than_bus_map(motor, wider)),
            Self::MotionOutsideNewLimits { motor, motion } => s(motion_outside(motor, motion)),
            Self::SequentialWithoutArrival { motor, mode } => s(no_arrival(motor, mode)),
            Self::OrionNotAttached => ORION_NOT_ATTACHED.into(),
            Self::OrionMotorNotAttached { motor } => s(orion_motor_not_attached(motor)),
            Self::OutwardAtLimit {
                motor,
                at,
                mode,
                setpoint: to,
                limit_name: name,
                source,
                limit,
            } => s(outward(motor, *at, mode, *to, name, source, *limit)),
            Self::ActionNotExpressible {
                motor,
                why,
                not_active,
            } => s(not_expressible(motor, why, *not_active)),
            // The line's outcome.
            Self::Cut { why, unknown, .. } => s(cut(why, *unknown)),
            Self::Failed {
                outcome, message, ..
            } => failed(*outcome, message.as_ref()),
            Self::NoAnswer { why } => s(why.clone()),
        }
    }

    /// The value and the limit it names, where it names them.
    fn broke(&self) -> Option<Box<Broke>> {
        match self {
            Self::Gate { refusal, .. } => Broke::of(refusal),
            Self::FeedbackRate { asked, bridge_hz } => Some(Box::new(Broke {
                field: Some("feedback_hz"),
                value: Some(*asked),
                limit: Some(bridge_hz.unwrap_or(0.0)),
                limit_name: Some("feedback_hz"),
                limit_source: Some("the bridge's --feedback-hz"),
            })),
            _ => None,
        }
    }
}

// The words of each refusal that says more than an arm of
// [`Refusal::message`] holds, by group.

// The line itself.

const SEQUENTIAL_WITH_TOTAL_DURATION: &str = "sync_mode sequential runs the axes one after another; coordination.total_duration_ms has them all arrive together after it: a line has one or the other";

const PID_GAINS: &str =
    "iRPC carries no PID gains (its joints run their own control loops): nothing was sent";

const CONTROL_MODE_CONFIG: &str = "iRPC carries no control-mode configuration (a joint takes position moves and lifecycle requests): nothing was sent";

/// A `feedback_hz` of `asked` the bridge (at `bridge_hz`) cannot give.
fn feedback_rate(asked: f64, bridge_hz: Option<f64>) -> String {
    // The number as a person reads it (1e308, not 309 digits).
    let hz = asked;
    let asked = if hz != 0.0 && !(1e-4..1e6).contains(&hz.abs()) {
        format!("{hz:e}")
    } else {
        format!("{hz}")
    };
    match bridge_hz {
        _ if hz.is_nan() || hz < 0.0 => {
            format!("feedback_hz {asked} is not a rate: 0 (no feedback) or more")
        }
        None => format!(
            "feedback_hz {asked}: the bridge sends no feedback (--feedback-hz 0); 0 is the only rate"
        ),
        Some(b) if hz > b => format!(
            "feedback_hz {asked} is above the bridge's own rate, {}",
            short_number(b)
        ),
        Some(b) => format!(
            "feedback_hz {asked} is below the slowest rate, the bridge's divided by {} ({:e}); 0 turns feedback off",
            u32::MAX,
            b / f64::from(u32::MAX)
        ),
    }
}

fn unsupported_kind(kind: &motorwire_wia::MessageKind) -> String {
    format!(
        "a {kind} is valid WIA, but the bridge takes motor-command and multi-axis-command lines"
    )
}

fn no_such_message(motor: &str, wire: &str, what: &str) -> String {
    format!("{motor} speaks iRPC {wire}, which has no {what}")
}

// The stop and the clock.

const LATCHED: &str =
    "the emergency stop is latched; send {\"emergency_stop\": false} to release it";

const LATCHED_RESET: &str = "the emergency stop is latched; release it first, then reset";

const STOP_OVERTOOK_RELEASE: &str = "an emergency stop sent after this release was acted on before it; the emergency stop stays latched";

fn arrived_before_stop(early: Duration) -> String {
    format!(
        "the line reached the bridge {:.3} s before the last emergency stop: written before the stop, it does not run after the release",
        early.as_secs_f64()
    )
}

fn stamped_before_stop(timestamp: f64, stop_ms: f64) -> String {
    format!(
        "timestamp {timestamp} is {:.3} s before the last emergency stop (at {stop_ms}): written before the stop, it does not run after the release",
        (stop_ms - timestamp) / 1000.0
    )
}

/// A `timestamp` `age_ms` old (negative: in the future), beyond
/// `max_age`; `microseconds` when read so it would have been within it.
fn stale(timestamp: f64, age_ms: f64, max_age: Duration, microseconds: bool) -> String {
    let when = if age_ms > 0.0 { "old" } else { "in the future" };
    // A timestamp in microseconds is a mistake often made.
    let hint = if microseconds {
        "; it looks like microseconds: WIA timestamps are Unix milliseconds (`date +%s%3N`)"
    } else {
        ""
    };
    format!(
        "timestamp {timestamp} is {:.1} s {when}; the allowed clock skew is {} s (WIA §10.1){hint}",
        age_ms.abs() / 1000.0,
        max_age.as_secs_f64()
    )
}

fn start_too_far_ahead(start_ms: f64, ahead_ms: f64, max_age: Duration) -> String {
    format!(
        "timing.start_time {start_ms} is {:.1} s ahead; a trajectory starts within the allowed clock skew, {} s (WIA §10.1)",
        ahead_ms / 1000.0,
        max_age.as_secs_f64()
    )
}

// The motor, and the bridge busy.

fn needs_reset(motor: &str, why: &str) -> String {
    format!("{motor} {why}: send {{\"reset\":\"{motor}\"}} to bring it back")
}

fn offline(motor: &str, why: Option<&str>) -> String {
    match why {
        Some(why) => format!("{motor} is offline: {why}"),
        None => format!("{motor} is offline"),
    }
}

fn lines_in_progress(max: usize) -> String {
    format!(
        "{max} lines are in progress, the most the bridge takes; nothing was sent, send it again later"
    )
}

fn queue_full(motor: &str, max: usize) -> String {
    format!(
        "{motor} has {max} steps waiting, the most it takes; nothing was sent, send it again later"
    )
}

const WAITING_FOR_START: &str =
    "too many lines are waiting for the joints to start; nothing was sent, send it again later";

// A rule broken: the bridge's own.

fn not_an_irpc_joint(motor: &str) -> String {
    format!("{motor} is not an iRPC joint of the bus map")
}

fn no_reset(motor: &str) -> String {
    format!("{motor} takes no reset: only iRPC joints and moteus controllers do")
}

/// A trajectory whose `first` waypoint is not where the joint is (`at`).
fn not_at_start(motor: &str, first: f64, at: Option<f64>) -> String {
    let at = at.map_or_else(
        || "at an unknown position".to_owned(),
        |p| format!("at {p}"),
    );
    format!("{motor}: the trajectory starts at {first} and the joint is {at}: move it there first")
}

fn start_unreachable(start_ms: f64) -> String {
    format!("timing.start_time {start_ms} is beyond any time the bridge can wait for")
}

fn waypoint_unreachable(motor: &str) -> String {
    format!("{motor}: a waypoint's time is beyond any time the bridge can wait for")
}

fn wider_than_bus_map(motor: &str, wider: &[Wider]) -> String {
    wider
        .iter()
        .map(|w| {
            format!(
                "{motor}: {} {} is wider than the bus map's {} {}",
                w.field, w.value, w.map_field, w.bound
            )
        })
        .collect::<Vec<_>>()
        .join("; ")
}

fn motion_outside(motor: &str, motion: &str) -> String {
    format!(
        "{motor}: {motion}, which these limits would not allow; send them once it has ended, or stop it first"
    )
}

fn no_arrival(motor: &str, mode: &str) -> String {
    format!(
        "{motor}: sync_mode sequential runs position moves one after another, each once the one before arrived; a {mode} command has no arrival to wait for"
    )
}

const ORION_NOT_ATTACHED: &str =
    "no Orion arm controller is attached (motorwire bridge --orion ...)";

fn orion_motor_not_attached(motor: &str) -> String {
    format!(
        "{motor} is an Orion motor, and no Orion controller is attached (motorwire bridge --orion ...)"
    )
}

/// A `mode` of `setpoint` at `at` toward the limit `limit_name` (from
/// `source`) at `limit` that the motor could not stop before.
fn outward(
    motor: &str,
    at: f64,
    mode: &str,
    setpoint: f64,
    limit_name: &str,
    source: &str,
    limit: f64,
) -> String {
    format!(
        "{motor}: at {at}, a {mode} of {setpoint} toward its {limit_name} ({source}) {limit} could not stop before it; command it away from the limit"
    )
}

/// A motor line its device has no means for (`why`); `not_active` when
/// the motor is not up.
fn not_expressible(motor: &str, why: &str, not_active: bool) -> String {
    if not_active {
        format!(
            "{motor} is not active (never started: --no-activate, or its start failed) and {why}; {{\"reset\":\"{motor}\"}} starts it"
        )
    } else {
        why.to_owned()
    }
}

// The line's outcome.

/// A line cut by `why`; `unknown` when a part was in flight unanswered.
fn cut(why: &str, unknown: bool) -> String {
    if unknown {
        format!(
            "{why}: a part was sent before and not answered, so it may have started; nothing of it is sent again"
        )
    } else {
        format!("{why}; nothing of it is sent")
    }
}

/// A line whose gravest `outcome` failed it (`message`: a superseded
/// step's own).
fn failed(outcome: StepOutcome, message: Option<&Cow<'static, str>>) -> Cow<'static, str> {
    let s = |t: &'static str| Cow::Borrowed(t);
    match outcome {
        StepOutcome::OutcomeUnknown => {
            s("a joint never answered: it may or may not have executed the command")
        }
        StepOutcome::Nacked => s("a joint refused the command"),
        StepOutcome::Cancelled => {
            s("cancelled by an emergency stop or the end; nothing of it runs after the stop")
        }
        // What replaced it, as its step says (a newer move, a stream's
        // setpoint, a motor line).
        StepOutcome::Superseded => message.cloned().unwrap_or(s(
            "a newer command for the motor replaced it before it was sent",
        )),
        StepOutcome::NotSent | StepOutcome::Acked => s("not every part could be sent"),
    }
}

impl From<Refusal> for ErrorBody {
    fn from(r: Refusal) -> Self {
        let mut e = ErrorBody::new(r.kind(), r.message());
        e.rule = r.rule();
        e.motor = r.motor().map(str::to_owned);
        e.broke = r.broke();
        if let Refusal::Invalid {
            violations, more, ..
        } = r
        {
            e.violations = violations;
            e.more_violations = (more > 0).then(|| u32::try_from(more).unwrap_or(u32::MAX));
        }
        e
    }
}

impl std::fmt::Display for Refusal {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.message())
    }
}

impl std::error::Error for Refusal {}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;

    /// One of each variant. The match in [`names_every_variant`] has no
    /// wildcard: a variant added without an example here does not compile.
    fn one_of_each() -> Vec<Refusal> {
        let mut all = the_line_and_the_stop();
        all.extend(the_motor_and_the_bridge_busy());
        all.extend(the_rules_and_the_outcome());
        for r in &all {
            names_every_variant(r);
        }
        all
    }

    /// An example of each refusal of the line itself, the bridge's end,
    /// the stop and the clock.
    fn the_line_and_the_stop() -> Vec<Refusal> {
        let m = || "elbow".to_owned();
        vec![
            Refusal::Unreadable {
                reason: "a line over 65536 bytes".into(),
            },
            Refusal::Invalid {
                message: "not JSON".into(),
                violations: None,
                more: 0,
            },
            Refusal::SequentialWithTotalDuration,
            Refusal::FeedbackRate {
                asked: 200.0,
                bridge_hz: Some(100.0),
            },
            Refusal::UnsupportedKind {
                kind: motorwire_wia::MessageKind::PidConfig,
            },
            Refusal::PidGains,
            Refusal::ControlModeConfig,
            Refusal::NoSuchMessage {
                motor: m(),
                wire: "v2.1",
                what: "PowerMetrics (v2.2)".into(),
            },
            Refusal::ShuttingDown,
            Refusal::AlreadyStopped,
            Refusal::Interrupted,
            Refusal::Latched,
            Refusal::LatchedReset,
            Refusal::NotLatched,
            Refusal::StopOvertookRelease,
            Refusal::BadRelease {
                reason: "not exactly a release".into(),
            },
            Refusal::ArrivedBeforeStop {
                early: Duration::from_millis(250),
            },
            Refusal::StampedBeforeStop {
                timestamp: 1_000.0,
                stop_ms: 1_250.0,
            },
            Refusal::Stale {
                timestamp: 1.0,
                age_ms: 400_000.0,
                max_age: Duration::from_secs(300),
                microseconds: false,
            },
            Refusal::StartTooFarAhead {
                start_ms: 1.0,
                ahead_ms: 400_000.0,
                max_age: Duration::from_secs(300),
            },
        ]
    }

    /// An example of each refusal of a motor, and of the bridge busy.
    fn the_motor_and_the_bridge_busy() -> Vec<Refusal> {
        let m = || "elbow".to_owned();
        vec![
            Refusal::NeedsReset {
                motor: m(),
                why: "faulted".into(),
            },
            Refusal::Offline {
                motor: m(),
                why: None,
            },
            Refusal::LinesInProgress { max: 64 },
            Refusal::QueueFull {
                motor: m(),
                max: 16,
            },
            Refusal::WaitingForStart,
        ]
    }

    /// An example of each refusal by a rule broken, and of the line's
    /// outcome.
    fn the_rules_and_the_outcome() -> Vec<Refusal> {
        let m = || "elbow".to_owned();
        vec![
            Refusal::gate(motorwire_translate::Refusal::UnknownMotor {
                motor: "knee".into(),
            }),
            Refusal::UnknownMotor {
                motor: "knee".into(),
            },
            Refusal::NotAnIrpcJoint { motor: m() },
            Refusal::NoReset { motor: m() },
            Refusal::MotorTwice { motor: m() },
            Refusal::NotAtStart {
                motor: m(),
                first: 10.0,
                at: Some(0.0),
            },
            Refusal::StartUnreachable { start_ms: 1e300 },
            Refusal::WaypointUnreachable { motor: m() },
            Refusal::WiderThanBusMap {
                motor: m(),
                wider: vec![Wider {
                    field: "position_limits.min",
                    value: -5.0,
                    map_field: "min_position",
                    bound: 0.0,
                }],
            },
            Refusal::MotionOutsideNewLimits {
                motor: m(),
                motion: "its move under way goes to 140".into(),
            },
            Refusal::SequentialWithoutArrival {
                motor: m(),
                mode: "velocity",
            },
            Refusal::OrionNotAttached,
            Refusal::OrionMotorNotAttached {
                motor: "turntable".into(),
            },
            Refusal::OutwardAtLimit {
                motor: "knee".into(),
                at: 59.8,
                mode: "velocity",
                setpoint: 20.0,
                limit_name: "max_position",
                source: "SafetyLimits",
                limit: 60.0,
            },
            Refusal::ActionNotExpressible {
                motor: m(),
                why: "no torque off".into(),
                not_active: false,
            },
            Refusal::Cut {
                why: "cancelled by an emergency stop".into(),
                unknown: false,
                motor: None,
            },
            Refusal::Failed {
                outcome: StepOutcome::Nacked,
                message: None,
                motor: None,
            },
            Refusal::NoAnswer {
                why: "no FaultHistory came".into(),
            },
        ]
    }

    /// Nothing: a match of every variant, with no wildcard.
    fn names_every_variant(r: &Refusal) {
        match r {
            Refusal::Unreadable { .. }
            | Refusal::Invalid { .. }
            | Refusal::SequentialWithTotalDuration
            | Refusal::FeedbackRate { .. }
            | Refusal::UnsupportedKind { .. }
            | Refusal::PidGains
            | Refusal::ControlModeConfig
            | Refusal::NoSuchMessage { .. }
            | Refusal::ShuttingDown
            | Refusal::AlreadyStopped
            | Refusal::Interrupted
            | Refusal::Latched
            | Refusal::LatchedReset
            | Refusal::NotLatched
            | Refusal::StopOvertookRelease
            | Refusal::BadRelease { .. }
            | Refusal::ArrivedBeforeStop { .. }
            | Refusal::StampedBeforeStop { .. }
            | Refusal::Stale { .. }
            | Refusal::StartTooFarAhead { .. }
            | Refusal::NeedsReset { .. }
            | Refusal::Offline { .. }
            | Refusal::LinesInProgress { .. }
            | Refusal::QueueFull { .. }
            | Refusal::WaitingForStart
            | Refusal::Gate { .. }
            | Refusal::UnknownMotor { .. }
            | Refusal::NotAnIrpcJoint { .. }
            | Refusal::NoReset { .. }
            | Refusal::MotorTwice { .. }
            | Refusal::NotAtStart { .. }
            | Refusal::StartUnreachable { .. }
            | Refusal::WaypointUnreachable { .. }
            | Refusal::WiderThanBusMap { .. }
            | Refusal::MotionOutsideNewLimits { .. }
            | Refusal::SequentialWithoutArrival { .. }
            | Refusal::OrionNotAttached
            | Refusal::OrionMotorNotAttached { .. }
            | Refusal::OutwardAtLimit { .. }
            | Refusal::ActionNotExpressible { .. }
            | Refusal::Cut { .. }
            | Refusal::Failed { .. }
            | Refusal::NoAnswer { .. } => {}
        }
    }

    /// The README's table of rules, checked against the enum: every
    /// refusal's rule is a row of it, with the refusal's kind.
    #[test]
    fn every_refusal_is_a_row_of_the_readmes_table_with_its_kind() {
        let readme = include_str!("../../README.md");
        let table = readme
            .split("## Refusal rules")
            .nth(1)
            .unwrap()
            .split("\n## ")
            .next()
            .unwrap();
        for r in one_of_each() {
            let row = format!("| `{}` | `{}` |", r.rule(), r.kind().name());
            assert!(table.contains(&row), "{r:?}: no row {row}");
        }
    }

    /// Each refusal on the wire, as the bridge has always said it.
    #[test]
    fn a_refusal_is_said_once_with_its_kind_rule_message_and_motor() {
        let wire = |r: Refusal| serde_json::to_string(&ErrorBody::from(r)).unwrap();
        assert_eq!(
            wire(Refusal::OutwardAtLimit {
                motor: "knee".into(),
                at: 59.8,
                mode: "velocity",
                setpoint: 20.0,
                limit_name: "max_position",
                source: "SafetyLimits",
                limit: 60.0,
            }),
            r#"{"kind":"refused","rule":"outward_at_limit","message":"knee: at 59.8, a velocity of 20 toward its max_position (SafetyLimits) 60 could not stop before it; command it away from the limit","motor":"knee"}"#
        );
        assert_eq!(
            wire(Refusal::FeedbackRate {
                asked: 1e308,
                bridge_hz: Some(100.0)
            }),
            r#"{"kind":"invalid","rule":"invalid","message":"feedback_hz 1e308 is above the bridge's own rate, 100","field":"feedback_hz","value":1e+308,"limit":100.0,"limit_name":"feedback_hz","limit_source":"the bridge's --feedback-hz"}"#
        );
        assert_eq!(
            wire(Refusal::Invalid {
                message: "bad".into(),
                violations: Some(serde_json::json!([1])),
                more: 3
            }),
            r#"{"kind":"invalid","rule":"invalid","message":"bad","violations":[1],"more_violations":3}"#
        );
        assert_eq!(
            wire(Refusal::Gate {
                refusal: Box::new(motorwire_translate::Refusal::UnknownMotor {
                    motor: "knee".into()
                }),
                motor: Some("elbow".into()),
            }),
            r#"{"kind":"refused","rule":"unknown_motor","message":"motor \"knee\" is not in the bus map","motor":"elbow"}"#
        );
        let steps = |o: StepOutcome, msg: &'static str| {
            vec![StepReport {
                motor: "elbow".into(),
                outcome: o,
                code: None,
                message: msg.into(),
            }]
        };
        assert_eq!(
            wire(Refusal::failed(
                &steps(StepOutcome::Superseded, "superseded by line 7"),
                None
            )),
            r#"{"kind":"superseded","rule":"superseded","message":"superseded by line 7","motor":"elbow"}"#
        );
        assert_eq!(
            wire(Refusal::failed(
                &steps(StepOutcome::OutcomeUnknown, "x"),
                Some("cancelled by an emergency stop")
            )),
            r#"{"kind":"cancelled","rule":"cancelled","message":"cancelled by an emergency stop: a part was sent before and not answered, so it may have started; nothing of it is sent again","motor":"elbow"}"#
        );
    }
}
