//! What an input line asks for, decided before anything else: a pure
//! function of the text, so every rule about stops can be tested alone.
//!
//! The emergency stop wins over everything: a line that parses as JSON and
//! asks for a stop in any of these forms stops, whatever else it carries,
//! and its other problems are reported alongside:
//!
//! - a top-level `emergency_stop` member whose value is anything but
//!   `false` (`true`, `"true"`, `1`, `null`, ...), with any other members;
//! - a top-level `safety_limits` object whose `emergency_stop` is anything
//!   but `false` (a MotorCommand's), valid or not;
//! - any `motors[i].safety_limits.emergency_stop` that is anything but
//!   `false` (a multi-axis command's), valid or not.
//!
//! A member named twice counts every time: `{"emergency_stop": false,
//! "emergency_stop": true}` stops, and so does a nested one named twice
//! (`"safety_limits":{"emergency_stop":true,"emergency_stop":false}`).
//! When the text names `emergency_stop` more often than those places show
//! (under `metadata`, under a misspelled member), or spells a name with an
//! escape, any `emergency_stop` in it that is not `false` stops: when in
//! doubt, stop. The release is exact: the line
//! `{"emergency_stop": false}` with no other member and no repeat; any
//! other line whose every `emergency_stop` is `false` is an
//! [`Line::BadRelease`] and the latch holds.
//!
//! A line that is not a JSON object this bridge can read (truncated,
//! garbage before or after it, nested deeper than the parser goes, `NaN`,
//! an array, a byte-order mark) stops when it names `emergency_stop`
//! anywhere (escapes decoded) with a value that is not `false`: when in
//! doubt, stop. It is never taken as a command or a release.
//!
//! JSON that is valid but that no parser holds exactly (a number such as
//! `1e400` beyond the f64 range, a lone UTF-16 surrogate such as
//! `"\ud800"`) still stops when it asks for a stop: such numbers are read
//! as 0 and such escapes as U+FFFD only to find the stop, and the line's
//! problem is reported alongside. It is never taken as a command.

use std::fmt;

use motorwire_wia::{Message, Validator};

use crate::output::Label;

/// What a calibration line starts (an iRPC joint's `StartCalibration`),
/// carried to the device layer as it was read.
pub(crate) type Calibration = motorwire_irpc::CalibrationRequest;

/// What an arm-wide line asks (the Orion controller's fold, unfold or
/// stop), carried to the device layer as it was read.
pub(crate) type ArmAction = motorwire_orion::ArmCommand;

/// An arm-wide action in one word, as its line and its result say it.
pub(crate) const fn arm_action_name(action: ArmAction) -> &'static str {
    match action {
        ArmAction::Fold => "fold",
        ArmAction::Unfold => "unfold",
        ArmAction::Stop => "stop",
    }
}
use serde::de::{Deserializer, MapAccess, Visitor};
use serde_json::Value;

/// What a line asks for.
#[derive(Debug, Clone, PartialEq)]
pub enum Line {
    /// An emergency stop.
    Stop {
        /// Its `motor_id` or `command_id`, when the line names one.
        label: Option<Label>,
        /// What else is wrong with the line (reported; it stops anyway).
        problems: Vec<String>,
    },
    /// `{"emergency_stop": false}`, exactly.
    Release,
    /// A release that is not exact; the latch holds.
    BadRelease {
        /// Why.
        reason: String,
    },
    /// A multi-axis trajectory: `{"trajectory_id":..,"trajectories":[..]}`,
    /// each a WIA Trajectory for its own joint, on one time base.
    Trajectories {
        /// Its `trajectory_id`.
        id: String,
        /// Each joint's.
        trajectories: Vec<motorwire_wia::Trajectory>,
    },
    /// `{"reset":M}`: bring joint M back after a fault or a reboot.
    Reset {
        /// The joint.
        motor_id: String,
    },
    /// `{"request":K,"motor_id":M}`: ask joint M for its telemetry
    /// (`telemetry`, v2.1 on), its power metrics (`power_metrics`) or its
    /// fault history (`fault_history`, both v2.2); answered as JSON.
    Request {
        /// What is asked for.
        kind: RequestKind,
        /// The joint.
        motor_id: String,
    },
    /// `{"calibration":"start","motor_id":M,...}` (with any of
    /// `phases`, `max_current`, `max_velocity`, `max_position_range`,
    /// `phase_timeout`, `return_home`) or `{"calibration":"stop","motor_id":M}`.
    Calibration {
        /// The joint.
        motor_id: String,
        /// The request to start with; `None` to stop.
        start: Option<motorwire_irpc::CalibrationRequest>,
    },
    /// `{"orion":"fold"}` or `{"orion":"unfold"}`: the Orion arm
    /// controller's command mode.
    OrionCommand {
        /// Fold or unfold.
        command: motorwire_orion::ArmCommand,
    },
    /// `{"query":"limits","motor_id":M}`: the motor's limits in force.
    QueryLimits {
        /// The motor asked about.
        motor_id: String,
    },
    /// `{"query":"state"}`, optionally with `"motor_id":M`: every motor's
    /// state now (or that one's).
    QueryState {
        /// The motor asked about, if one.
        motor_id: Option<String>,
    },
    /// `{"feedback_hz":N}`: the rate at which this client is sent each
    /// motor's feedback (0: none), at most the bridge's own.
    FeedbackRate {
        /// The rate asked for (Hz).
        hz: f64,
    },
    /// A valid WIA message.
    Message(Box<Message>),
    /// A MotorCommand with `"stream": true`: a setpoint of a policy's
    /// stream (it replaces the motor's target; no completion line follows
    /// it).
    Stream(Box<motorwire_wia::MotorCommand>),
    /// A multi-axis command with `"stream": true`: one setpoint of a
    /// policy's stream for each of its motors, in one line and one result
    /// (each replaces its motor's setpoint waiting to be sent).
    StreamAxes(Box<motorwire_wia::MultiAxisCommand>),
    /// `{"motor":"hold"|"free"|"stop","motor_id":M}`: one motor held,
    /// freed or stopped alone, by its dialect's own means.
    Motor {
        /// What is asked.
        action: MotorAction,
        /// The motor.
        motor_id: String,
    },
    /// Not JSON, or not valid WIA.
    Invalid {
        /// Said for a person.
        message: String,
        /// The WIA violations, when it was JSON (at most
        /// [`motorwire_wia::MAX_VIOLATIONS`]).
        violations: Option<Value>,
        /// Violations found beyond those listed.
        more: usize,
        /// Its `motor_id` or `command_id`, when the line names one.
        label: Option<Label>,
    },
}

/// What a `{"motor":...,"motor_id":M}` line asks of one motor. Each is
/// undone by the motor's next command (an iRPC joint left inactive is
/// activated before it).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MotorAction {
    /// Stop within the limits in force and hold where it stops, torque on
    /// (a freed motor: torque back on where it stands).
    Hold,
    /// Torque off: the motor turns freely.
    Free,
    /// The motor's own stop, as the emergency stop stops it, for this
    /// motor alone (nothing latches).
    Stop,
}

impl MotorAction {
    /// Every action, as lines name them.
    pub const ALL: [Self; 3] = [Self::Hold, Self::Free, Self::Stop];

    /// Its name in lines and results.
    pub const fn name(self) -> &'static str {
        match self {
            Self::Hold => "hold",
            Self::Free => "free",
            Self::Stop => "stop",
        }
    }

    /// The action named `name`.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|a| a.name() == name)
    }
}

/// What a request line asks a joint for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RequestKind {
    /// One TelemetryStream (v2.1 on).
    Telemetry,
    /// PowerMetrics (v2.2).
    PowerMetrics,
    /// FaultHistory (v2.2).
    FaultHistory,
}

impl RequestKind {
    /// Its name in lines and results.
    pub const fn name(self) -> &'static str {
        match self {
            Self::Telemetry => "telemetry",
            Self::PowerMetrics => "power_metrics",
            Self::FaultHistory => "fault_history",
        }
    }
}

/// The calibration a start line asks for when it gives no parameter: all
/// five phases, 2 A, 30 deg/s, within 20 degrees, 10 s per phase, back
/// home afterwards.
pub const DEFAULT_CALIBRATION: motorwire_irpc::CalibrationRequest =
    motorwire_irpc::CalibrationRequest {
        phases: 0x1F,
        max_current: 2.0,
        max_velocity: 30.0,
        max_position_range: 20.0,
        phase_timeout: 10.0,
        return_home: true,
    };

fn calibration_line(members: &[(String, Value)], label: Option<Label>) -> Line {
    let usage = r#"a calibration line is {"calibration":"start","motor_id":"..."} (optionally with phases, max_current, max_velocity, max_position_range, phase_timeout, return_home) or {"calibration":"stop","motor_id":"..."}"#;
    let invalid = |message: String| Line::Invalid {
        message,
        violations: None,
        more: 0,
        label: label.clone(),
    };
    let Some(Label::Motor(motor_id)) = label.clone() else {
        return invalid(usage.to_owned());
    };
    let action = members
        .iter()
        .find(|(k, _)| k == "calibration")
        .and_then(|(_, v)| v.as_str());
    match action {
        Some("stop") if members.len() == 2 => Line::Calibration {
            motor_id,
            start: None,
        },
        Some("start") => {
            let mut r = DEFAULT_CALIBRATION;
            for (k, v) in members {
                let number = || {
                    v.as_f64()
                        .filter(|x| x.is_finite() && *x > 0.0 && *x <= f64::from(f32::MAX))
                        .map(|x| x as f32)
                        .ok_or_else(|| format!("calibration {k}: {v} is not a positive number"))
                };
                let set = match k.as_str() {
                    "calibration" | "motor_id" => Ok(()),
                    "phases" => v
                        .as_u64()
                        .and_then(|p| u8::try_from(p).ok())
                        .filter(|p| *p != 0 && *p <= 0x1F)
                        .map(|p| r.phases = p)
                        .ok_or_else(|| {
                            format!(
                                "calibration phases: {v} is not a mask of the five phases (1 to 31)"
                            )
                        }),
                    "max_current" => number().map(|x| r.max_current = x),
                    "max_velocity" => number().map(|x| r.max_velocity = x),
                    "max_position_range" => number().map(|x| r.max_position_range = x),
                    "phase_timeout" => number().map(|x| r.phase_timeout = x),
                    "return_home" => v.as_bool().map(|b| r.return_home = b).ok_or_else(|| {
                        format!("calibration return_home: {v} is not true or false")
                    }),
                    other => Err(format!("calibration: unknown member {other:?}; {usage}")),
                };
                if let Err(e) = set {
                    return invalid(e);
                }
            }
            Line::Calibration {
                motor_id,
                start: Some(r),
            }
        }
        _ => invalid(usage.to_owned()),
    }
}

/// A JSON object's members in order, repeats kept.
struct Members(Vec<(String, Value)>);

impl<'de> serde::Deserialize<'de> for Members {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = Members;
            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str("a JSON object")
            }
            fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<Members, A::Error> {
                let mut v = Vec::new();
                while let Some((k, x)) = map.next_entry::<String, Value>()? {
                    v.push((k, x));
                }
                Ok(Members(v))
            }
        }
        d.deserialize_map(V)
    }
}

/// The top-level members of a line that is a JSON object, in order, with
/// repeats kept: the one reading [`classify`] makes of a line's members
/// (a member named twice is there twice). An envelope around a line (a
/// Zenoh query's `request_id`) is read with it, so that it and the line
/// agree on what the line holds.
///
/// # Errors
/// The parser's error when `line` is not one JSON object serde_json can
/// hold (truncated, garbage around it, too deep, a number beyond f64).
///
/// ```
/// use serde_json::json;
/// let m = motorwire_bridge::members(r#"{"setpoint":20,"setpoint":140}"#).unwrap();
/// assert_eq!(m, [("setpoint".to_owned(), json!(20)), ("setpoint".to_owned(), json!(140))]);
/// assert!(motorwire_bridge::members("[1]").is_err());
/// ```
pub fn members(line: &str) -> Result<Vec<(String, Value)>, serde_json::Error> {
    serde_json::from_str::<Members>(line).map(|m| m.0)
}

fn stops(v: &Value) -> bool {
    *v != Value::Bool(false)
}

/// The `emergency_stop` of a `safety_limits` value, when it stops; counts
/// in `seen` each one read (a parsed object keeps only the last of a
/// repeated member: [`hidden_stop`] looks at the text for the others).
fn nested_stops(safety_limits: &Value, out: &mut Vec<String>, at: &str, seen: &mut usize) {
    if let Value::Object(m) = safety_limits
        && let Some(v) = m.get("emergency_stop")
    {
        *seen += 1;
        if stops(v) {
            out.push(format!("{at}.emergency_stop is {v}"));
        }
    }
}

/// A stop the parsed members cannot show: the text names `emergency_stop`
/// more often than the members read (a nested member named twice, whose
/// parsed object keeps the last; one under `metadata` or an unknown
/// member), or spells a name with an escape; then any `emergency_stop` in
/// it whose value is not `false` stops. When in doubt, stop.
fn hidden_stop(line: &str, seen: usize) -> bool {
    let named = line.matches("\"emergency_stop\"").count();
    (named > seen || line.contains('\\')) && names_a_stop(line)
}

/// Whether `line` asks for an emergency stop (in any of the forms above):
/// a quick test a runner uses to let a stop overtake the lines queued
/// before it. It agrees with [`classify`] on every line.
///
/// ```
/// use motorwire_bridge::asks_for_stop;
/// assert!(asks_for_stop(r#"{"emergency_stop": "true", "x": 1}"#));
/// assert!(!asks_for_stop(r#"{"emergency_stop": false}"#));
/// assert!(!asks_for_stop(r#"{"motor_id":"elbow","setpoint":1}"#));
/// ```
pub fn asks_for_stop(line: &str) -> bool {
    // Without the word, only an escape (`\u0065`, or one JSON does not
    // allow, `\g`, which the fallback reads as the letter) can spell it.
    if !line.contains("emergency") && !line.contains('\\') {
        return false;
    }
    let Ok((members, _)) = members_of(line) else {
        return names_a_stop(line);
    };
    let (top, reasons, seen) = stop_members(&members);
    top.iter().any(|v| stops(v)) || !reasons.is_empty() || hidden_stop(line, seen)
}

/// For a line that is not a JSON object this bridge can read (truncated,
/// garbage around it, nested past the parser's depth, `NaN`, an array, a
/// byte-order mark): whether it anywhere names `emergency_stop` (escapes
/// decoded) with a value that is not `false`. When in doubt, stop.
pub(crate) fn names_a_stop(line: &str) -> bool {
    let mut chars = line.chars().peekable();
    let mut last_string: Option<String> = None;
    while let Some(c) = chars.next() {
        match c {
            '"' => {
                let mut text = String::new();
                while let Some(c) = chars.next() {
                    match c {
                        '"' => break,
                        '\\' => match chars.next() {
                            Some('u') => {
                                let hex: String = chars.by_ref().take(4).collect();
                                let ch = u32::from_str_radix(&hex, 16)
                                    .ok()
                                    .and_then(char::from_u32)
                                    .unwrap_or('\u{FFFD}');
                                text.push(ch);
                            }
                            Some(other) => text.push(other),
                            None => break,
                        },
                        other => text.push(other),
                    }
                }
                last_string = Some(text);
            }
            ':' if last_string.as_deref() == Some("emergency_stop") => {
                while chars.next_if(|c| c.is_whitespace()).is_some() {}
                let value: String = chars
                    .clone()
                    .take_while(|c| !matches!(c, ',' | '}' | ']') && !c.is_whitespace())
                    .collect();
                if value != "false" {
                    return true;
                }
                last_string = None;
            }
            c if c.is_whitespace() => {}
            _ => last_string = None,
        }
    }
    false
}

/// Members of `line`, or, when it is valid JSON that serde_json cannot
/// hold (an out-of-range number, a lone surrogate) and it may name a stop,
/// the members of its repaired copy with the original error.
#[allow(clippy::type_complexity)]
fn members_of(line: &str) -> Result<(Vec<(String, Value)>, Option<String>), serde_json::Error> {
    match serde_json::from_str::<Members>(line) {
        Ok(m) => Ok((m.0, None)),
        Err(e) => {
            if !line.contains("emergency_stop") {
                return Err(e);
            }
            match repair(line).map(|r| serde_json::from_str::<Members>(&r)) {
                Some(Ok(m)) => Ok((m.0, Some(e.to_string()))),
                _ => Err(e),
            }
        }
    }
}

/// `line` with every number beyond the f64 range written `0` and every
/// surrogate escape (`\uD800`..`\uDFFF`) written `\uFFFD`; `None` when
/// there was nothing to repair.
fn repair(line: &str) -> Option<String> {
    let mut out = String::with_capacity(line.len());
    let mut changed = false;
    let mut rest = line;
    let mut in_string = false;
    while let Some(c) = rest.chars().next() {
        if in_string {
            if let Some(esc) = rest.strip_prefix("\\u")
                && let Some(hex) = esc.get(..4)
                && let Ok(u) = u16::from_str_radix(hex, 16)
                && (0xD800..=0xDFFF).contains(&u)
            {
                out.push_str("\\uFFFD");
                changed = true;
                rest = esc.get(4..).unwrap_or_default();
                continue;
            }
            if c == '\\' {
                // An escape: it and the character after it.
                out.push(c);
                rest = rest.get(1..).unwrap_or_default();
                if let Some(n) = rest.chars().next() {
                    out.push(n);
                    rest = rest.get(n.len_utf8()..).unwrap_or_default();
                }
                continue;
            }
            in_string = c != '"';
        } else if c == '"' {
            in_string = true;
        } else if c == '-' || c.is_ascii_digit() {
            let len = rest
                .find(|c: char| !matches!(c, '0'..='9' | '-' | '+' | '.' | 'e' | 'E'))
                .unwrap_or(rest.len());
            let token = rest.get(..len).unwrap_or_default();
            if token.parse::<f64>().is_ok_and(f64::is_infinite) {
                out.push('0');
                changed = true;
            } else {
                out.push_str(token);
            }
            rest = rest.get(len..).unwrap_or_default();
            continue;
        }
        out.push(c);
        rest = rest.get(c.len_utf8()..).unwrap_or_default();
    }
    changed.then_some(out)
}

/// The top-level `emergency_stop` values, the nested ones that stop, and
/// how many `emergency_stop` members were read in all.
fn stop_members(members: &[(String, Value)]) -> (Vec<&Value>, Vec<String>, usize) {
    let mut reasons = Vec::new();
    let mut top = Vec::new();
    let mut seen = 0;
    for (k, v) in members {
        match k.as_str() {
            "emergency_stop" => {
                top.push(v);
                seen += 1;
            }
            "safety_limits" => nested_stops(v, &mut reasons, "safety_limits", &mut seen),
            "motors" => {
                if let Value::Array(axes) = v {
                    for (i, a) in axes.iter().enumerate() {
                        if let Some(l) = a.get("safety_limits") {
                            nested_stops(
                                l,
                                &mut reasons,
                                &format!("motors[{i}].safety_limits"),
                                &mut seen,
                            );
                        }
                    }
                }
            }
            _ => {}
        }
    }
    (top, reasons, seen)
}

/// Decides what `line` asks for. `validator` parses the WIA messages.
///
/// ```
/// use motorwire_bridge::{Line, classify};
/// use motorwire_wia::Validator;
/// let v = Validator::new();
/// assert_eq!(classify(&v, r#"{"emergency_stop": false}"#), Line::Release);
/// // Stops, whatever else the line carries; the rest is reported.
/// let Line::Stop { problems, .. } = classify(&v, r#"{"emergency_stop": "true", "x": 1}"#) else { panic!() };
/// assert_eq!(problems, [
///     "emergency_stop is \"true\", not true: taken as a stop",
///     "the line also carries x",
/// ]);
/// // An invalid command that carries a stop stops.
/// let line = r#"{"motor_id":"elbow","control_mode":"warp","safety_limits":{"emergency_stop":true}}"#;
/// assert!(matches!(classify(&v, line), Line::Stop { .. }));
/// // A release with anything else is not one.
/// assert!(matches!(classify(&v, r#"{"emergency_stop": false, "emergency_stop": false}"#), Line::BadRelease { .. }));
/// ```
pub fn classify(validator: &Validator, line: &str) -> Line {
    if let Some(c) = plain_command(validator, line) {
        return Line::Message(Box::new(Message::MotorCommand(c)));
    }
    if let Some(c) = plain_multi_axis(validator, line) {
        return Line::Message(Box::new(Message::MultiAxisCommand(c)));
    }
    classify_scanned(validator, line)
}

/// A valid motor command and nothing else, the commonest line, that names
/// no stop: read once ([`Validator::parse_plain_command`]). That parse
/// stops at the first name a command does not have (a top-level
/// `emergency_stop`, the bridge's own forms, another kind) and says no
/// member is unknown anywhere in it; then the only places a stop can be
/// named are the command's own `safety_limits` and its `metadata`.
fn plain_command(validator: &Validator, line: &str) -> Option<motorwire_wia::MotorCommand> {
    let c = validator.parse_plain_command(line);
    let plain = c.as_ref().is_some_and(|c| {
        c.metadata.is_none()
            && c.safety_limits
                .as_ref()
                .is_none_or(|s| s.emergency_stop.is_none())
    });
    if plain { c } else { None }
}

/// A valid multi-axis command and nothing else that names no stop, read
/// once ([`Validator::parse_plain_multi_axis`]), as [`plain_command`]: the
/// only places a stop can then be named are each axis's own
/// `safety_limits` and the `metadata` (the command's or an axis's).
fn plain_multi_axis(validator: &Validator, line: &str) -> Option<motorwire_wia::MultiAxisCommand> {
    validator.parse_plain_multi_axis(line).filter(|c| {
        c.metadata.is_none()
            && c.motors.iter().all(|a| {
                a.metadata.is_none()
                    && a.safety_limits
                        .as_ref()
                        .is_none_or(|s| s.emergency_stop.is_none())
            })
    })
}

/// [`classify`] without its one-parse paths for a plain motor command or
/// multi-axis command: any other ordinary valid message is read twice, a scan of its top-level
/// names (no value kept) saying it is none of the bridge's own forms and
/// it cannot name a stop, then the typed parse. Anything else (a stop, a
/// release, the bridge's own forms, an invalid line) is decided from all
/// its members ([`classify_members`]).
fn classify_scanned(validator: &Validator, line: &str) -> Line {
    match plain_message(line) {
        Some(Some(kind)) => {
            if let Ok(m) = validator.parse_as(kind, line) {
                return Line::Message(Box::new(m));
            }
        }
        Some(None) => {
            if let Ok(m) = validator.parse_any(line) {
                return Line::Message(Box::new(m));
            }
        }
        None => {}
    }
    classify_members(validator, line)
}

/// The top-level names of the bridge's own forms.
const OWN_FORMS: [&[u8]; 9] = [
    b"trajectories",
    b"motor",
    b"reset",
    b"calibration",
    b"request",
    b"orion",
    b"query",
    b"stream",
    b"feedback_hz",
];

/// `Some` when `line` cannot name a stop (no `emergency` and no escape in
/// it) and is a JSON object none of whose top-level names is one of the
/// bridge's own forms: then [`classify_members`] would take it as a WIA
/// message if the validator does; with the kind its names say, if any.
/// One scan of the bytes ([`motorwire_wia::scan_kind_noting`]), nothing
/// parsed and nothing allocated; `None` whenever the scan cannot be sure.
fn plain_message(line: &str) -> Option<Option<motorwire_wia::MessageKind>> {
    if line.contains("emergency") || line.contains('\\') {
        return None;
    }
    let mut own = false;
    let kind =
        motorwire_wia::scan_kind_noting(line, |name| own |= OWN_FORMS.contains(&name)).ok()?;
    (!own).then_some(kind)
}

/// [`classify`] from every member of the line: a stop or a release first,
/// then the bridge's own forms, then a WIA message.
fn classify_members(validator: &Validator, line: &str) -> Line {
    let (members, unholdable) = match members_of(line) {
        Ok(m) => m,
        Err(e) => return not_an_object(validator, line, &e),
    };
    let label = label_of(&members);
    let (top, mut reasons, seen) = stop_members(&members);
    if reasons.is_empty() && hidden_stop(line, seen) {
        reasons.push(
            "emergency_stop is named where the members read do not show it (a repeated nested member, metadata, an unknown member) with a value that is not false".to_owned(),
        );
    }
    let top_stop = top.iter().any(|v| stops(v));
    if let Some(e) = unholdable {
        return unholdable_line(&e, top_stop || !reasons.is_empty(), label);
    }
    if top_stop || !reasons.is_empty() {
        let problems = stop_problems(validator, line, &members, &top, top_stop);
        return Line::Stop { label, problems };
    }
    if !top.is_empty() {
        return release_line(&members, &top);
    }
    own_form(validator, line, &members, label)
}

/// A line that is not a JSON object this bridge can read (`e` says why):
/// a stop when it names one, else neither a stop nor a release.
fn not_an_object(validator: &Validator, line: &str, e: &serde_json::Error) -> Line {
    if names_a_stop(line) {
        return Line::Stop {
            label: None,
            problems: vec![format!(
                "the line is not a JSON object this bridge can read ({e}); it names emergency_stop with a value other than false, so it stops"
            )],
        };
    }
    // Not an object (or not JSON): it can be neither a stop nor a release.
    match validator.parse_any(line) {
        Ok(m) => Line::Message(Box::new(m)),
        Err(err) => Line::Invalid {
            message: if serde_json::from_str::<Value>(line).is_ok() {
                invalid_message(&err)
            } else {
                format!("not JSON: {}", motorwire_wia::json_error_text(line, e))
            },
            violations: serde_json::to_value(err.violations()).ok(),
            more: err.more(),
            label: None,
        },
    }
}

/// The line's label: its last `motor_id` or `command_id` that is a string.
fn label_of(members: &[(String, Value)]) -> Option<Label> {
    members
        .iter()
        .rev()
        .find_map(|(k, v)| match (k.as_str(), v) {
            ("motor_id", Value::String(s)) => Some(Label::Motor(s.clone())),
            ("command_id", Value::String(s)) => Some(Label::Command(s.clone())),
            _ => None,
        })
}

/// Valid JSON that no parser holds exactly (`e` says why): a stop if it
/// asks for one (`stop`), else invalid.
fn unholdable_line(e: &str, stop: bool, label: Option<Label>) -> Line {
    if stop {
        return Line::Stop {
            label,
            problems: vec![format!(
                "the line cannot be read exactly ({e}); it asks for a stop, so it stops"
            )],
        };
    }
    Line::Invalid {
        message: format!("not JSON this bridge can read: {e}"),
        violations: None,
        more: 0,
        label,
    }
}

/// What else is wrong with a line that stops: its top-level stop's
/// problems (`top_stop`), or a command's violations (its stop is obeyed
/// even if the rest of it is not valid).
fn stop_problems(
    validator: &Validator,
    line: &str,
    members: &[(String, Value)],
    top: &[&Value],
    top_stop: bool,
) -> Vec<String> {
    let mut problems = Vec::new();
    if top_stop {
        for v in top.iter().filter(|v| **v != &Value::Bool(true) && stops(v)) {
            problems.push(format!("emergency_stop is {v}, not true: taken as a stop"));
        }
        if top.len() > 1 {
            problems.push(format!("emergency_stop appears {} times", top.len()));
        }
        let others: Vec<&str> = members
            .iter()
            .map(|(k, _)| k.as_str())
            .filter(|k| *k != "emergency_stop")
            .collect();
        if !others.is_empty() {
            problems.push(format!("the line also carries {}", names(&others)));
        }
    } else if let Err(e) = validator.parse_any(line) {
        // A command carrying a stop: its stop is obeyed even if the
        // rest of it is not valid.
        for v in e.violations() {
            problems.push(v.to_string());
        }
        if e.more() > 0 {
            problems.push(format!("and {} more violations, not listed", e.more()));
        }
    }
    problems
}

/// A line whose every `emergency_stop` (`top`, at least one) is `false`:
/// the release when it is exactly `{"emergency_stop": false}`.
fn release_line(members: &[(String, Value)], top: &[&Value]) -> Line {
    if members.len() == 1 {
        return Line::Release;
    }
    let reason = if top.len() > 1 {
        format!("emergency_stop appears {} times", top.len())
    } else {
        let others: Vec<&str> = members
            .iter()
            .map(|(k, _)| k.as_str())
            .filter(|k| *k != "emergency_stop")
            .collect();
        format!("the line also carries {}", names(&others))
    };
    Line::BadRelease {
        reason: format!(
            "{reason}: a release is exactly {{\"emergency_stop\": false}}; the emergency stop stays latched"
        ),
    }
}

/// A line that names no stop: one of the bridge's own forms, by the first
/// of their names it carries, or else a WIA message.
fn own_form(
    validator: &Validator,
    line: &str,
    members: &[(String, Value)],
    label: Option<Label>,
) -> Line {
    if let Some((_, Value::Array(items))) = members.iter().find(|(k, _)| k == "trajectories") {
        return trajectories_line(validator, members, items, label);
    }
    if let Some((_, m)) = members.iter().find(|(k, _)| k == "reset") {
        return reset_line(members, m, label);
    }
    if members.iter().any(|(k, _)| k == "calibration") {
        return calibration_line(members, label);
    }
    if let Some((_, q)) = members.iter().find(|(k, _)| k == "request") {
        return request_line(members, q, label);
    }
    if let Some((_, c)) = members.iter().find(|(k, _)| k == "orion") {
        return orion_line(members, c, label);
    }
    if let Some((_, q)) = members.iter().find(|(k, _)| k == "query") {
        return query_line(members, q, label);
    }
    if let Some((_, a)) = members.iter().find(|(k, _)| k == "motor") {
        return motor_line(members, a, label);
    }
    if let Some((_, hz)) = members.iter().find(|(k, _)| k == "feedback_hz") {
        return feedback_rate_line(members, hz, label);
    }
    if let Some(at) = members.iter().position(|(k, _)| k == "stream") {
        return stream_line(validator, members, at, label);
    }
    match validator.parse_any(line) {
        Ok(m) => Line::Message(Box::new(m)),
        Err(err) => Line::Invalid {
            message: invalid_message(&err),
            violations: serde_json::to_value(err.violations()).ok(),
            more: err.more(),
            label,
        },
    }
}

/// `{"trajectory_id":T,"trajectories":[...]}` (`items` the array), or why
/// not.
fn trajectories_line(
    validator: &Validator,
    members: &[(String, Value)],
    items: &[Value],
    label: Option<Label>,
) -> Line {
    let id = members
        .iter()
        .find_map(|(k, v)| (k == "trajectory_id").then(|| v.as_str()))
        .flatten();
    let problem = |message: String| Line::Invalid {
        message,
        violations: None,
        more: 0,
        label: label.clone(),
    };
    let Some(id) = id else {
        return problem(r#"a multi-axis trajectory is {"trajectory_id":"...","trajectories":[WIA Trajectory, ...]}"#.to_owned());
    };
    if members.len() != 2 || items.is_empty() {
        return problem(r#"a multi-axis trajectory is {"trajectory_id":"...","trajectories":[WIA Trajectory, ...]} and nothing else"#.to_owned());
    }
    let mut trajectories = Vec::new();
    for (i, item) in items.iter().enumerate() {
        match validator.parse_any(&item.to_string()) {
            Ok(Message::Trajectory(t)) => trajectories.push(*Box::new(t)),
            Ok(other) => {
                return problem(format!(
                    "trajectories[{i}] is a {}, not a trajectory",
                    other.kind()
                ));
            }
            Err(e) => {
                return Line::Invalid {
                    message: format!("trajectories[{i}] is not a valid WIA trajectory"),
                    violations: serde_json::to_value(e.violations()).ok(),
                    more: e.more(),
                    label,
                };
            }
        }
    }
    Line::Trajectories {
        id: id.to_owned(),
        trajectories,
    }
}

/// `{"reset":M}` (`m` the value of `reset`), or why not.
fn reset_line(members: &[(String, Value)], m: &Value, label: Option<Label>) -> Line {
    match (m.as_str(), members.len()) {
        (Some(m), 1) => Line::Reset {
            motor_id: m.to_owned(),
        },
        _ => Line::Invalid {
            message: r#"a reset is exactly {"reset":"<motor_id>"}"#.to_owned(),
            violations: None,
            more: 0,
            label,
        },
    }
}

/// `{"request":kind,"motor_id":M}` (`q` the value of `request`), or why
/// not.
fn request_line(members: &[(String, Value)], q: &Value, label: Option<Label>) -> Line {
    let kind = match q.as_str() {
        Some("telemetry") => Some(RequestKind::Telemetry),
        Some("power_metrics") => Some(RequestKind::PowerMetrics),
        Some("fault_history") => Some(RequestKind::FaultHistory),
        _ => None,
    };
    match (kind, members.len(), &label) {
        (Some(kind), 2, Some(Label::Motor(m))) => Line::Request {
            kind,
            motor_id: m.clone(),
        },
        _ => Line::Invalid {
            message: r#"a request is exactly {"request":"telemetry"|"power_metrics"|"fault_history","motor_id":"..."}"#.to_owned(),
            violations: None,
            more: 0,
            label,
        },
    }
}

/// `{"orion":"fold"}` or `{"orion":"unfold"}` (`c` the value of `orion`),
/// or why not.
fn orion_line(members: &[(String, Value)], c: &Value, label: Option<Label>) -> Line {
    match (c.as_str(), members.len()) {
        (Some("fold"), 1) => Line::OrionCommand {
            command: motorwire_orion::ArmCommand::Fold,
        },
        (Some("unfold"), 1) => Line::OrionCommand {
            command: motorwire_orion::ArmCommand::Unfold,
        },
        _ => Line::Invalid {
            message: r#"an Orion command is exactly {"orion":"fold"} or {"orion":"unfold"} (a stop is {"emergency_stop":true})"#.to_owned(),
            violations: None,
            more: 0,
            label,
        },
    }
}

/// `{"query":"state"}` (with or without a `motor_id`) or
/// `{"query":"limits","motor_id":M}` (`q` the value of `query`), or why
/// not.
fn query_line(members: &[(String, Value)], q: &Value, label: Option<Label>) -> Line {
    match (q.as_str(), members.len(), &label) {
        (Some("limits"), 2, Some(Label::Motor(m))) => Line::QueryLimits {
            motor_id: m.clone(),
        },
        (Some("state"), 1, None) => Line::QueryState { motor_id: None },
        (Some("state"), 2, Some(Label::Motor(m))) => Line::QueryState {
            motor_id: Some(m.clone()),
        },
        _ => Line::Invalid {
            message: r#"a query is exactly {"query":"state"} (optionally with "motor_id":"..."), or {"query":"limits","motor_id":"..."}"#.to_owned(),
            violations: None,
            more: 0,
            label,
        },
    }
}

/// `{"feedback_hz":N}` (`hz` the value of `feedback_hz`), or why not.
fn feedback_rate_line(members: &[(String, Value)], hz: &Value, label: Option<Label>) -> Line {
    match (hz.as_f64(), members.len()) {
        (Some(hz), 1) => Line::FeedbackRate { hz },
        _ => Line::Invalid {
            message:
                r#"a feedback rate is exactly {"feedback_hz":N}, N a number of Hz (0: no feedback)"#
                    .to_owned(),
            violations: None,
            more: 0,
            label,
        },
    }
}

/// `{"motor":action,"motor_id":M}` (`action` the value of `motor`), or
/// why not, naming what is wrong.
fn motor_line(members: &[(String, Value)], action: &Value, label: Option<Label>) -> Line {
    const FORM: &str = r#"a motor line is exactly {"motor":"hold"|"free"|"stop","motor_id":"..."}"#;
    // What a refusal quotes of a value, at most (a megabyte of it is not
    // said back).
    let clip = |t: String| match t.char_indices().nth(64) {
        Some((at, _)) => format!("{}...", t.get(..at).unwrap_or_default()),
        None => t,
    };
    let named = |k: &str| members.iter().filter(|(n, _)| n == k).count();
    let others: Vec<&str> = members
        .iter()
        .map(|(k, _)| k.as_str())
        .filter(|k| *k != "motor" && *k != "motor_id")
        .collect();
    let id = members
        .iter()
        .find(|(k, _)| k == "motor_id")
        .map(|(_, v)| v);
    let chosen = action.as_str().and_then(MotorAction::from_name);
    let why = match (action.as_str(), chosen, id) {
        (None, ..) => format!(
            "motor is {}: it is \"hold\", \"free\" or \"stop\"",
            clip(action.to_string())
        ),
        (Some(name), None, _) => format!(
            "{} is not one (hold: stop and hold, torque on; free: torque off; stop: the motor's own stop)",
            clip(format!("{name:?}"))
        ),
        _ if named("motor") > 1 || named("motor_id") > 1 => {
            "motor or motor_id appears more than once".to_owned()
        }
        _ if !others.is_empty() => format!("it also carries {}", names(&others)),
        (.., None) => "it names no motor_id".to_owned(),
        (_, Some(action), Some(Value::String(m))) => {
            return Line::Motor {
                action,
                motor_id: m.clone(),
            };
        }
        (.., Some(v)) => format!("motor_id is {}: it is a motor's name", clip(v.to_string())),
    };
    Line::Invalid {
        message: format!("{FORM}: {why}"),
        violations: None,
        more: 0,
        label,
    }
}

/// A line with the bridge's `stream` member (at `at` among `members`):
/// the rest of it must be a valid MotorCommand or multi-axis command, and
/// `stream` a boolean
/// (`true`: a setpoint of a stream; `false`: an ordinary command).
fn stream_line(
    validator: &Validator,
    members: &[(String, Value)],
    at: usize,
    label: Option<Label>,
) -> Line {
    let invalid = |message: String| Line::Invalid {
        message,
        violations: None,
        more: 0,
        label: label.clone(),
    };
    let times = members.iter().filter(|(k, _)| k == "stream").count();
    if times > 1 {
        return invalid(format!("stream appears {times} times"));
    }
    let stream = match members.get(at) {
        Some((_, Value::Bool(b))) => *b,
        Some((_, v)) => {
            return invalid(format!(
                "stream is {v}: it is true (the command is a setpoint of a stream) or false"
            ));
        }
        None => false,
    };
    // The command without `stream`, each other member as it came.
    let mut text = String::from("{");
    for (k, v) in members
        .iter()
        .enumerate()
        .filter(|(i, _)| *i != at)
        .map(|(_, m)| m)
    {
        if text.len() > 1 {
            text.push(',');
        }
        text.push_str(&Value::String(k.clone()).to_string());
        text.push(':');
        text.push_str(&v.to_string());
    }
    text.push('}');
    match validator.parse_any(&text) {
        Ok(Message::MotorCommand(c)) if stream => Line::Stream(Box::new(c)),
        // (Read without `stream`: the one rule of the validator that
        // needs it is checked here.)
        Ok(Message::MultiAxisCommand(c))
            if stream && c.sync_mode == Some(motorwire_wia::SyncMode::Sequential) =>
        {
            let v = motorwire_wia::Violation::new(
                "/sync_mode",
                motorwire_wia::Rule::Stream,
                motorwire_wia::STREAM_SEQUENTIAL,
            );
            Line::Invalid {
                message: format!("not a valid WIA message: {v}"),
                violations: serde_json::to_value([v]).ok(),
                more: 0,
                label,
            }
        }
        Ok(Message::MultiAxisCommand(c)) if stream => Line::StreamAxes(Box::new(c)),
        Ok(m @ (Message::MotorCommand(_) | Message::MultiAxisCommand(_))) => {
            Line::Message(Box::new(m))
        }
        Ok(other) => invalid(format!(
            "stream is a command's (a motor command or a multi-axis command); a {} has no stream",
            other.kind()
        )),
        Err(err) => Line::Invalid {
            message: invalid_message(&err),
            violations: serde_json::to_value(err.violations()).ok(),
            more: err.more(),
            label,
        },
    }
}

/// `not a valid WIA message: ` and the first violation (its pointer, what
/// is wrong, its rule), with how many more: what a person reads first.
fn invalid_message(err: &motorwire_wia::Error) -> String {
    match err.violations() {
        [] => "not a valid WIA message".to_owned(),
        [one] if err.more() == 0 => format!("not a valid WIA message: {one}"),
        [first, rest @ ..] => format!(
            "not a valid WIA message: {first}; and {} more (violations)",
            rest.len().saturating_add(err.more())
        ),
    }
}

/// Member names as a refusal lists them: the first [`MAX_NAMES`], and how
/// many more (a line of a hundred thousand members is answered in a line).
fn names(names: &[&str]) -> String {
    let shown = names.get(..MAX_NAMES).unwrap_or(names);
    let mut s = shown.join(", ");
    if names.len() > shown.len() {
        s.push_str(&format!(" and {} more", names.len() - shown.len()));
    }
    s
}

/// Member names a refusal or a stop lists, at most.
const MAX_NAMES: usize = 16;

#[cfg(test)]
mod tests;
