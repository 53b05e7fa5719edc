//! One `Controller.make_*` call of mjbots' Python library, as a JSON object
//! with the library's own names, and its frame built by `moteus-protocol`.
//!
//! ```
//! use motorwire_moteus::Call;
//! let call = Call::from_json(
//!     r#"{"command":"position","id":1,"position":0.5,"velocity":null,"maximum_torque":1.0,"query":true}"#,
//! )?;
//! let frame = call.encode()?;
//! assert_eq!(frame.can_id, 0x8001);
//! assert_eq!(
//!     motorwire_moteus::hex(&frame.data),
//!     // mode = position; position and velocity as f32 (0.5, NaN);
//!     // maximum torque as f32 (1.0); the default query.
//!     "01000a".to_owned() + "0e20" + "0000003f" + "0000c07f" + "0d25" + "0000803f" + "11001f01130d",
//! );
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use moteus_protocol::command::{
    BrakeCommand, CurrentFormat, OutputExactCommand, OutputNearestCommand, PositionFormat,
    StopCommand, ZeroVelocityFormat,
};
use moteus_protocol::query::QueryFormat;
use moteus_protocol::{
    CanFdFrame, Mode, Register, Resolution, WRITE_INT8, WriteCanData, WriteCombiner,
    calculate_arbitration_id,
};
use serde_json::{Map, Value};

use crate::Frame;

/// The calls `Call` knows, by the library's name without `make_`.
pub const COMMANDS: &[&str] = &[
    "position",
    "stop",
    "brake",
    "query",
    "current",
    "stay_within",
    "zero_velocity",
    "set_output_nearest",
    "set_output_exact",
];

const POSITION_FIELDS: &[&str] = &[
    "position",
    "velocity",
    "feedforward_torque",
    "kp_scale",
    "kd_scale",
    "maximum_torque",
    "stop_position",
    "watchdog_timeout",
    "velocity_limit",
    "accel_limit",
    "fixed_voltage_override",
    "ilimit_scale",
    "fixed_current_override",
    "ignore_position_bounds",
];

const STAY_WITHIN_FIELDS: &[&str] = &[
    "lower_bound",
    "upper_bound",
    "feedforward_torque",
    "kp_scale",
    "kd_scale",
    "maximum_torque",
    "stop_position",
    "watchdog_timeout",
    "ilimit_scale",
    "ignore_position_bounds",
];

/// `QueryResolution`'s attributes, in the order the query writes them
/// (`rezero_state` is the older name of `home_state`'s register: the
/// library merges the two, the finer resolution winning).
pub const QUERY_FIELDS: &[&str] = &[
    "mode",
    "position",
    "velocity",
    "torque",
    "q_current",
    "d_current",
    "abs_position",
    "power",
    "motor_temperature",
    "trajectory_complete",
    "rezero_state",
    "home_state",
    "voltage",
    "temperature",
    "fault",
    "aux1_gpio",
    "aux2_gpio",
    "aux1_pwm_input_period_us",
    "aux1_pwm_input_duty_cycle",
    "aux2_pwm_input_period_us",
    "aux2_pwm_input_duty_cycle",
];

const CURRENT_FIELDS: &[&str] = &["d_A", "q_A"];
const ZERO_VELOCITY_FIELDS: &[&str] = &["kd_scale"];
const RESOLUTION_OBJECTS: &[&str] = &[
    "query_resolution",
    "position_resolution",
    "current_resolution",
    "zero_velocity_resolution",
];

/// A position-mode command's arguments (`make_position`'s), in
/// revolutions, revolutions a second, Nm, seconds and scales. `None` is not
/// sent; `Some(NaN)` is sent as the protocol's "no value".
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct PositionArgs {
    /// Target position, revolutions.
    pub position: Option<f64>,
    /// Velocity, revolutions a second (with position NaN: a velocity command).
    pub velocity: Option<f64>,
    /// Feedforward torque, Nm.
    pub feedforward_torque: Option<f64>,
    /// Scale of the position gain (0..1).
    pub kp_scale: Option<f64>,
    /// Scale of the velocity gain (0..1).
    pub kd_scale: Option<f64>,
    /// Torque limit, Nm.
    pub maximum_torque: Option<f64>,
    /// Position at which the motion stops, revolutions.
    pub stop_position: Option<f64>,
    /// The controller's watchdog: with no new command for this long (s) it enters mode TIMEOUT.
    pub watchdog_timeout: Option<f64>,
    /// Velocity limit of the controller's own trajectory, revolutions a second.
    pub velocity_limit: Option<f64>,
    /// Acceleration limit of its trajectory, revolutions a second squared.
    pub accel_limit: Option<f64>,
    /// Fixed voltage override, V.
    pub fixed_voltage_override: Option<f64>,
    /// Scale of the integrator limit.
    pub ilimit_scale: Option<f64>,
    /// Fixed current override, A.
    pub fixed_current_override: Option<f64>,
    /// Sent as `int(value)`, as the library sends it (a JSON `true` is 1,
    /// `false` 0, as Python's `int(True)`).
    pub ignore_position_bounds: Option<f64>,
}

/// A stay-within command's arguments (`make_stay_within`'s).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StayWithinArgs {
    /// Lower bound, revolutions.
    pub lower_bound: Option<f64>,
    /// Upper bound, revolutions.
    pub upper_bound: Option<f64>,
    /// Feedforward torque, Nm.
    pub feedforward_torque: Option<f64>,
    /// Scale of the position gain (0..1).
    pub kp_scale: Option<f64>,
    /// Scale of the velocity gain (0..1).
    pub kd_scale: Option<f64>,
    /// Torque limit, Nm.
    pub maximum_torque: Option<f64>,
    /// Taken and never sent: the library (1.1.1) accepts `stop_position`
    /// here and writes no register for it (stay-within mode has none).
    pub stop_position: Option<f64>,
    /// The controller's watchdog: with no new command for this long (s) it enters mode TIMEOUT.
    pub watchdog_timeout: Option<f64>,
    /// Scale of the integrator limit.
    pub ilimit_scale: Option<f64>,
    /// Sent as `int(value)` (`true` is 1, `false` 0).
    pub ignore_position_bounds: Option<f64>,
}

/// The call's command and its arguments.
#[derive(Debug, Clone, PartialEq)]
pub enum Command {
    /// `make_position`.
    Position(PositionArgs),
    /// `make_stop`.
    Stop,
    /// `make_brake`.
    Brake,
    /// `make_query`.
    Query,
    /// `make_current(d_A, q_A)`, amperes.
    Current {
        /// D-axis current.
        d_a: f64,
        /// Q-axis current.
        q_a: f64,
    },
    /// `make_stay_within`.
    StayWithin(StayWithinArgs),
    /// `make_zero_velocity`.
    ZeroVelocity {
        /// Its damping scale.
        kd_scale: Option<f64>,
    },
    /// `make_set_output_nearest(position)`, revolutions.
    SetOutputNearest(f64),
    /// `make_set_output_exact(position)`, revolutions.
    SetOutputExact(f64),
}

/// A controller's resolutions (the library's `*Resolution` objects).
#[derive(Debug, Clone, Default)]
pub struct Resolutions {
    /// `query_resolution`.
    pub query: QueryFormat,
    /// `position_resolution` (also stay-within's, as in the library).
    pub position: PositionFormat,
    /// `current_resolution`.
    pub current: CurrentFormat,
    /// `zero_velocity_resolution`.
    pub zero_velocity: ZeroVelocityFormat,
}

/// One call: the controller it addresses and what it sends.
#[derive(Debug, Clone)]
pub struct Call {
    /// The controller's id (1..=127).
    pub id: u8,
    /// Our own id (`source_can_id`, 0..=127).
    pub source: u8,
    /// The 13-bit CAN prefix.
    pub can_prefix: u16,
    /// What is sent.
    pub command: Command,
    /// Whether the default query is appended (a reply is asked for).
    pub query: bool,
    /// A query of its own, in place of the default one (`null` is the
    /// library's default, None).
    pub query_override: Option<QueryFormat>,
    /// The controller's resolutions.
    pub resolutions: Resolutions,
}

/// Why a call line is refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CallError {
    /// Not a JSON object.
    #[error("not a JSON object: {0}")]
    NotJson(String),
    /// `command` is missing or not a string.
    #[error("\"command\" is missing: one of {}", COMMANDS.join(", "))]
    NoCommand,
    /// An unknown `command`.
    #[error("unknown command {name:?}{}: one of {}", did_you_mean(suggestion), COMMANDS.join(", "))]
    UnknownCommand {
        /// What was given.
        name: String,
        /// The nearest known command.
        suggestion: Option<&'static str>,
    },
    /// A member the call has no argument for.
    #[error("{command}: unknown member {member:?}{}", did_you_mean(suggestion))]
    UnknownMember {
        /// The command (or resolution object).
        command: String,
        /// The member.
        member: String,
        /// The nearest known member.
        suggestion: Option<&'static str>,
    },
    /// A member of the wrong JSON type.
    #[error("{member}: expected {expected}, got {got}")]
    WrongType {
        /// The member.
        member: String,
        /// What it must be.
        expected: &'static str,
        /// What it was.
        got: String,
    },
    /// A value outside its range.
    #[error("{member}: {value} is outside {range}")]
    OutOfRange {
        /// The member.
        member: String,
        /// The value.
        value: String,
        /// Its range.
        range: &'static str,
    },
    /// A required argument is missing.
    #[error("{command}: {member} is required")]
    Missing {
        /// The command.
        command: &'static str,
        /// The argument.
        member: &'static str,
    },
    /// The frame would be longer than a CAN-FD frame.
    #[error(
        "the frame would be {size} bytes, over CAN-FD's 64 (send fewer fields, or at a lower resolution)"
    )]
    TooLong {
        /// Its size in bytes.
        size: usize,
    },
}

fn did_you_mean(s: &Option<&'static str>) -> String {
    s.map(|s| format!(" (did you mean {s:?}?)"))
        .unwrap_or_default()
}

fn nearest(word: &str, known: &[&'static str]) -> Option<&'static str> {
    known
        .iter()
        .map(|k| (strsim::jaro_winkler(word, k), *k))
        .filter(|(score, _)| *score > 0.8)
        .max_by(|a, b| a.0.total_cmp(&b.0))
        .map(|(_, k)| k)
}

fn type_name(v: &Value) -> String {
    match v {
        Value::Null => "null".into(),
        Value::Bool(_) => "a boolean".into(),
        Value::Number(n) => format!("the number {n}"),
        Value::String(s) => format!("the string {s:?}"),
        Value::Array(_) => "an array".into(),
        Value::Object(_) => "an object".into(),
    }
}

/// A resolution by the library's name (`mp.INT8` is `"int8"`, `mp.F32`
/// `"f32"`, `mp.IGNORE` `"ignore"`).
pub fn resolution_by_name(name: &str) -> Option<Resolution> {
    Some(match name {
        "int8" => Resolution::Int8,
        "int16" => Resolution::Int16,
        "int32" => Resolution::Int32,
        "f32" => Resolution::Float,
        "ignore" => Resolution::Ignore,
        _ => return None,
    })
}

fn resolution(member: &str, v: &Value) -> Result<Resolution, CallError> {
    v.as_str()
        .and_then(resolution_by_name)
        .ok_or_else(|| CallError::WrongType {
            member: member.to_owned(),
            expected: "a resolution: \"int8\", \"int16\", \"int32\", \"f32\" or \"ignore\"",
            got: type_name(v),
        })
}

fn integer(
    obj: &Map<String, Value>,
    member: &str,
    max: u64,
    range: &'static str,
) -> Result<Option<u64>, CallError> {
    let Some(v) = obj.get(member) else {
        return Ok(None);
    };
    let n = v.as_u64().ok_or_else(|| CallError::WrongType {
        member: member.to_owned(),
        expected: "an integer",
        got: type_name(v),
    })?;
    if n > max {
        return Err(CallError::OutOfRange {
            member: member.to_owned(),
            value: n.to_string(),
            range,
        });
    }
    Ok(Some(n))
}

/// A value argument: a number, or null for NaN; `None` when absent.
fn value(obj: &Map<String, Value>, member: &str) -> Result<Option<f64>, CallError> {
    match obj.get(member) {
        None => Ok(None),
        Some(Value::Null) => Ok(Some(f64::NAN)),
        Some(v) => v.as_f64().map(Some).ok_or_else(|| CallError::WrongType {
            member: member.to_owned(),
            expected: "a number, or null for NaN",
            got: type_name(v),
        }),
    }
}

/// A flag the library sends as `int(value)` (`ignore_position_bounds`):
/// `true` or `false` as Python's `True` and `False` (1 and 0), or a value.
fn flag(obj: &Map<String, Value>, member: &str) -> Result<Option<f64>, CallError> {
    match obj.get(member) {
        Some(Value::Bool(b)) => Ok(Some(if *b { 1.0 } else { 0.0 })),
        Some(v) if !v.is_number() && !v.is_null() => Err(CallError::WrongType {
            member: member.to_owned(),
            expected: "true or false, a number, or null for NaN",
            got: type_name(v),
        }),
        _ => value(obj, member),
    }
}

/// The library's `_merge_resolutions`: one of two resolutions for one
/// register, the finer when both are sent.
fn merge_resolutions(a: Resolution, b: Resolution) -> Resolution {
    let rank = |r: Resolution| match r {
        Resolution::Int8 => 0,
        Resolution::Int16 => 1,
        Resolution::Int32 => 2,
        _ => 3,
    };
    if a == Resolution::Ignore {
        b
    } else if b == Resolution::Ignore || rank(a) >= rank(b) {
        a
    } else {
        b
    }
}

fn query_format(name: &str, v: &Value, base: QueryFormat) -> Result<QueryFormat, CallError> {
    let obj = v.as_object().ok_or_else(|| CallError::WrongType {
        member: name.to_owned(),
        expected: "an object of QueryResolution attributes",
        got: type_name(v),
    })?;
    let mut q = base;
    let mut rezero_state = None;
    for (k, v) in obj {
        let r = resolution(&format!("{name}.{k}"), v)?;
        let slot = match k.as_str() {
            "mode" => &mut q.mode,
            "position" => &mut q.position,
            "velocity" => &mut q.velocity,
            "torque" => &mut q.torque,
            "q_current" => &mut q.q_current,
            "d_current" => &mut q.d_current,
            "abs_position" => &mut q.abs_position,
            "power" => &mut q.power,
            "motor_temperature" => &mut q.motor_temperature,
            "trajectory_complete" => &mut q.trajectory_complete,
            "rezero_state" => {
                rezero_state = Some(r);
                continue;
            }
            "home_state" => &mut q.home_state,
            "voltage" => &mut q.voltage,
            "temperature" => &mut q.temperature,
            "fault" => &mut q.fault,
            "aux1_gpio" => &mut q.aux1_gpio,
            "aux2_gpio" => &mut q.aux2_gpio,
            "aux1_pwm_input_period_us" => &mut q.aux1_pwm_input_period_us,
            "aux1_pwm_input_duty_cycle" => &mut q.aux1_pwm_input_duty_cycle,
            "aux2_pwm_input_period_us" => &mut q.aux2_pwm_input_period_us,
            "aux2_pwm_input_duty_cycle" => &mut q.aux2_pwm_input_duty_cycle,
            _ => return Err(unknown(name, k, QUERY_FIELDS)),
        };
        *slot = r;
    }
    if let Some(r) = rezero_state {
        // The register's resolution is `_merge_resolutions(rezero_state,
        // home_state)`.
        q.home_state = merge_resolutions(r, q.home_state);
    }
    Ok(q)
}

fn unknown(command: &str, member: &str, known: &[&'static str]) -> CallError {
    CallError::UnknownMember {
        command: command.to_owned(),
        member: member.to_owned(),
        suggestion: nearest(member, known),
    }
}

fn resolutions_object<'a>(
    obj: &'a Map<String, Value>,
    name: &str,
    known: &[&'static str],
) -> Result<Vec<(&'a str, Resolution)>, CallError> {
    let Some(v) = obj.get(name) else {
        return Ok(Vec::new());
    };
    let o = v.as_object().ok_or_else(|| CallError::WrongType {
        member: name.to_owned(),
        expected: "an object of attribute names and resolutions",
        got: type_name(v),
    })?;
    o.iter()
        .map(|(k, v)| {
            if !known.contains(&k.as_str()) {
                return Err(unknown(name, k, known));
            }
            Ok((k.as_str(), resolution(&format!("{name}.{k}"), v)?))
        })
        .collect()
}

impl Call {
    /// Reads one call from its JSON form.
    ///
    /// # Errors
    /// [`CallError`]: a member the call does not have (with the nearest
    /// known name), a wrong type, an id or prefix out of range, a value that
    /// fits no f32 where it is sent as an f32.
    pub fn from_json(text: &str) -> Result<Call, CallError> {
        let v: Value = serde_json::from_str(text).map_err(|e| CallError::NotJson(e.to_string()))?;
        let Value::Object(obj) = v else {
            return Err(CallError::NotJson(format!("got {}", type_name(&v))));
        };
        Call::from_object(&obj)
    }

    /// Reads one call from a parsed JSON object (see [`Call::from_json`]).
    ///
    /// # Errors
    /// As [`Call::from_json`].
    pub fn from_object(obj: &Map<String, Value>) -> Result<Call, CallError> {
        let name = obj
            .get("command")
            .and_then(Value::as_str)
            .ok_or(CallError::NoCommand)?;
        let command: &'static str =
            COMMANDS
                .iter()
                .find(|c| **c == name)
                .copied()
                .ok_or_else(|| CallError::UnknownCommand {
                    name: name.to_owned(),
                    suggestion: nearest(name, COMMANDS),
                })?;
        let fields: &[&'static str] = match command {
            "position" => POSITION_FIELDS,
            "stay_within" => STAY_WITHIN_FIELDS,
            "current" => CURRENT_FIELDS,
            "zero_velocity" => ZERO_VELOCITY_FIELDS,
            "set_output_nearest" | "set_output_exact" => &["position"],
            _ => &[],
        };
        let mut known: Vec<&'static str> =
            vec!["command", "id", "source", "can_prefix", "query_override"];
        if command != "query" {
            known.push("query");
        }
        known.extend_from_slice(RESOLUTION_OBJECTS);
        known.extend_from_slice(fields);
        if let Some(k) = obj.keys().find(|k| !known.contains(&k.as_str())) {
            return Err(unknown(command, k, &known));
        }

        let id = integer(obj, "id", 127, "1..=127")?.ok_or(CallError::Missing {
            command,
            member: "id",
        })?;
        if id == 0 {
            return Err(CallError::OutOfRange {
                member: "id".into(),
                value: "0".into(),
                range: "1..=127",
            });
        }
        let source = integer(obj, "source", 127, "0..=127")?.unwrap_or(0);
        let can_prefix = integer(obj, "can_prefix", 0x1fff, "0..=0x1fff (13 bits)")?.unwrap_or(0);
        let query = match obj.get("query") {
            None => command == "query",
            Some(Value::Bool(b)) => *b,
            Some(v) => {
                return Err(CallError::WrongType {
                    member: "query".into(),
                    expected: "true or false",
                    got: type_name(v),
                });
            }
        };

        let mut res = Resolutions::default();
        if let Some(v) = obj.get("query_resolution") {
            res.query = query_format("query_resolution", v, QueryFormat::default())?;
        }
        for (k, r) in resolutions_object(obj, "position_resolution", POSITION_FIELDS)? {
            let p = &mut res.position;
            *match k {
                "position" => &mut p.position,
                "velocity" => &mut p.velocity,
                "feedforward_torque" => &mut p.feedforward_torque,
                "kp_scale" => &mut p.kp_scale,
                "kd_scale" => &mut p.kd_scale,
                "maximum_torque" => &mut p.maximum_torque,
                "stop_position" => &mut p.stop_position,
                "watchdog_timeout" => &mut p.watchdog_timeout,
                "velocity_limit" => &mut p.velocity_limit,
                "accel_limit" => &mut p.accel_limit,
                "fixed_voltage_override" => &mut p.fixed_voltage_override,
                "ilimit_scale" => &mut p.ilimit_scale,
                "fixed_current_override" => &mut p.fixed_current_override,
                _ => &mut p.ignore_position_bounds,
            } = r;
        }
        for (k, r) in resolutions_object(obj, "current_resolution", CURRENT_FIELDS)? {
            *if k == "d_A" {
                &mut res.current.d_a
            } else {
                &mut res.current.q_a
            } = r;
        }
        for (_, r) in resolutions_object(obj, "zero_velocity_resolution", ZERO_VELOCITY_FIELDS)? {
            res.zero_velocity.kd_scale = r;
        }
        let query_override = match obj.get("query_override") {
            None | Some(Value::Null) => None,
            Some(v) => Some(query_format("query_override", v, QueryFormat::default())?),
        };

        let v = |m: &str| value(obj, m);
        let command = match command {
            "position" => Command::Position(PositionArgs {
                position: v("position")?,
                velocity: v("velocity")?,
                feedforward_torque: v("feedforward_torque")?,
                kp_scale: v("kp_scale")?,
                kd_scale: v("kd_scale")?,
                maximum_torque: v("maximum_torque")?,
                stop_position: v("stop_position")?,
                watchdog_timeout: v("watchdog_timeout")?,
                velocity_limit: v("velocity_limit")?,
                accel_limit: v("accel_limit")?,
                fixed_voltage_override: v("fixed_voltage_override")?,
                ilimit_scale: v("ilimit_scale")?,
                fixed_current_override: v("fixed_current_override")?,
                ignore_position_bounds: flag(obj, "ignore_position_bounds")?,
            }),
            "stay_within" => Command::StayWithin(StayWithinArgs {
                lower_bound: v("lower_bound")?,
                upper_bound: v("upper_bound")?,
                feedforward_torque: v("feedforward_torque")?,
                kp_scale: v("kp_scale")?,
                kd_scale: v("kd_scale")?,
                maximum_torque: v("maximum_torque")?,
                stop_position: v("stop_position")?,
                watchdog_timeout: v("watchdog_timeout")?,
                ilimit_scale: v("ilimit_scale")?,
                ignore_position_bounds: flag(obj, "ignore_position_bounds")?,
            }),
            "current" => Command::Current {
                d_a: v("d_A")?.ok_or(CallError::Missing {
                    command,
                    member: "d_A",
                })?,
                q_a: v("q_A")?.ok_or(CallError::Missing {
                    command,
                    member: "q_A",
                })?,
            },
            "zero_velocity" => Command::ZeroVelocity {
                kd_scale: v("kd_scale")?,
            },
            "set_output_nearest" => Command::SetOutputNearest(v("position")?.unwrap_or(0.0)),
            "set_output_exact" => Command::SetOutputExact(v("position")?.unwrap_or(0.0)),
            "stop" => Command::Stop,
            "brake" => Command::Brake,
            _ => Command::Query,
        };
        #[allow(clippy::cast_possible_truncation)]
        Ok(Call {
            id: id as u8,
            source: source as u8,
            can_prefix: can_prefix as u16,
            command,
            query,
            query_override,
            resolutions: res,
        })
    }

    /// The call's frame, built by `moteus-protocol`: the command, then the
    /// query (the override, or the controller's query when `query` is set),
    /// and the CAN id as mjbots' transports make it (destination, source <<
    /// 8, 0x8000 when a reply is wanted, prefix << 16).
    ///
    /// # Errors
    /// [`CallError::TooLong`] when the command and its query do not fit one
    /// CAN-FD frame (the library builds such a frame; no transport sends it).
    pub fn encode(&self) -> Result<Frame, CallError> {
        let mut command = CanFdFrame::new();
        let r = &self.resolutions;
        // The command's size as written in full (a block the frame cannot
        // hold is not written, and makes this larger than 64).
        let mut needed = 0;
        match &self.command {
            Command::Position(a) => {
                let p = &r.position;
                let fields = [
                    (a.position, p.position, POSITION, "position"),
                    (a.velocity, p.velocity, VELOCITY, "velocity"),
                    (
                        a.feedforward_torque,
                        p.feedforward_torque,
                        TORQUE,
                        "feedforward_torque",
                    ),
                    (a.kp_scale, p.kp_scale, PWM, "kp_scale"),
                    (a.kd_scale, p.kd_scale, PWM, "kd_scale"),
                    (a.maximum_torque, p.maximum_torque, TORQUE, "maximum_torque"),
                    (a.stop_position, p.stop_position, POSITION, "stop_position"),
                    (
                        a.watchdog_timeout,
                        p.watchdog_timeout,
                        TIME,
                        "watchdog_timeout",
                    ),
                    (
                        a.velocity_limit,
                        p.velocity_limit,
                        VELOCITY,
                        "velocity_limit",
                    ),
                    (a.accel_limit, p.accel_limit, ACCEL, "accel_limit"),
                    (
                        a.fixed_voltage_override,
                        p.fixed_voltage_override,
                        VOLTAGE,
                        "fixed_voltage_override",
                    ),
                    (a.ilimit_scale, p.ilimit_scale, PWM, "ilimit_scale"),
                    (
                        a.fixed_current_override,
                        p.fixed_current_override,
                        CURRENT,
                        "fixed_current_override",
                    ),
                    (
                        a.ignore_position_bounds,
                        p.ignore_position_bounds,
                        INT,
                        "ignore_position_bounds",
                    ),
                ];
                write_mode(&mut command, Mode::Position);
                needed = 3 + write_block(&mut command, Register::CommandPosition, &fields)?;
            }
            Command::StayWithin(a) => {
                let p = &r.position;
                let fields = [
                    (a.lower_bound, p.position, POSITION, "lower_bound"),
                    (a.upper_bound, p.position, POSITION, "upper_bound"),
                    (
                        a.feedforward_torque,
                        p.feedforward_torque,
                        TORQUE,
                        "feedforward_torque",
                    ),
                    (a.kp_scale, p.kp_scale, PWM, "kp_scale"),
                    (a.kd_scale, p.kd_scale, PWM, "kd_scale"),
                    (a.maximum_torque, p.maximum_torque, TORQUE, "maximum_torque"),
                    (
                        a.watchdog_timeout,
                        p.watchdog_timeout,
                        TIME,
                        "watchdog_timeout",
                    ),
                    (a.ilimit_scale, p.ilimit_scale, PWM, "ilimit_scale"),
                    (
                        a.ignore_position_bounds,
                        p.ignore_position_bounds,
                        INT,
                        "ignore_position_bounds",
                    ),
                ];
                write_mode(&mut command, Mode::StayWithin);
                needed =
                    3 + write_block(&mut command, Register::CommandStayWithinLowerBound, &fields)?;
            }
            Command::Current { d_a, q_a } => {
                let c = &r.current;
                // The registers' order: Q, then D.
                let fields = [
                    (Some(*q_a), c.q_a, CURRENT, "q_A"),
                    (Some(*d_a), c.d_a, CURRENT, "d_A"),
                ];
                write_mode(&mut command, Mode::Current);
                needed = 3 + write_block(&mut command, Register::CommandQCurrent, &fields)?;
            }
            Command::ZeroVelocity { kd_scale } => {
                write_mode(&mut command, Mode::ZeroVelocity);
                if kd_scale.is_some() {
                    let fields = [(*kd_scale, r.zero_velocity.kd_scale, PWM, "kd_scale")];
                    needed = 3 + write_block(&mut command, Register::CommandKdScale, &fields)?;
                }
            }
            Command::SetOutputNearest(p) => {
                OutputNearestCommand::new(as_f32("position", *p)?).serialize(&mut command);
            }
            Command::SetOutputExact(p) => {
                OutputExactCommand::new(as_f32("position", *p)?).serialize(&mut command);
            }
            Command::Stop => StopCommand::serialize(&mut command),
            Command::Brake => BrakeCommand::serialize(&mut command),
            Command::Query => {}
        }
        let mut query = CanFdFrame::new();
        let wants_reply = self.query || self.query_override.is_some();
        if let Some(q) = &self.query_override {
            q.serialize(&mut query);
        } else if self.query {
            r.query.serialize(&mut query);
        }
        // A query has no values: it never reaches 64 bytes alone (20
        // registers at most, a header each at worst).
        let size = needed.max(usize::from(command.size)) + usize::from(query.size);
        if size > 64 {
            return Err(CallError::TooLong { size });
        }
        let mut data = Vec::with_capacity(size);
        data.extend_from_slice(command.payload());
        data.extend_from_slice(query.payload());
        #[allow(clippy::cast_possible_wrap)]
        let can_id = calculate_arbitration_id(
            self.source as i8,
            self.id as i8,
            self.can_prefix,
            wants_reply,
        );
        Ok(Frame { can_id, data })
    }
}

/// A register's scales at int8, int16 and int32, as the library's
/// `Writer.write_*` methods have them; `INT` is `write_int`'s (the value's
/// `int()` first).
type Scales = (f64, f64, f64);
const POSITION: Scales = (0.01, 0.0001, 0.00001);
const VELOCITY: Scales = (0.1, 0.00025, 0.00001);
const ACCEL: Scales = (0.05, 0.001, 0.00001);
const TORQUE: Scales = (0.5, 0.01, 0.001);
const PWM: Scales = (1.0 / 127.0, 1.0 / 32767.0, 1.0 / 2147483647.0);
const VOLTAGE: Scales = (0.5, 0.1, 0.001);
const TIME: Scales = (0.01, 0.001, 0.000001);
const CURRENT: Scales = (1.0, 0.1, 0.001);
const INT: Scales = (f64::NAN, f64::NAN, f64::NAN);

fn write_mode(frame: &mut CanFdFrame, mode: Mode) {
    let mut w = WriteCanData::new(frame);
    w.write_u8(WRITE_INT8 | 0x01);
    w.write_varuint(u32::from(Register::Mode.address()));
    w.write_u8(mode.into());
}

/// One block of registers from `start`, framed by `moteus-protocol`'s
/// `WriteCombiner` (the library's grouping), each value scaled as the
/// library scales it.
fn write_block(
    frame: &mut CanFdFrame,
    start: Register,
    fields: &[(Option<f64>, Resolution, Scales, &str)],
) -> Result<usize, CallError> {
    let resolutions: Vec<Resolution> = fields
        .iter()
        .map(|(v, r, _, _)| if v.is_some() { *r } else { Resolution::Ignore })
        .collect();
    let needed = block_size(start.address(), &resolutions);
    if usize::from(frame.size) + needed > 64 {
        // The codec's writer stops at 64 bytes: nothing is written.
        return Ok(needed);
    }
    let mut combiner = WriteCombiner::new(WRITE_INT8, start.address(), &resolutions);
    let mut w = WriteCanData::new(frame);
    for (v, res, scales, member) in fields {
        if !combiner.maybe_write(&mut w) {
            continue;
        }
        let Some(v) = *v else { continue };
        let v = if scales.0.is_nan() {
            // `write_int`: int(value), which NaN has not.
            if !v.is_finite() {
                return Err(CallError::OutOfRange {
                    member: (*member).to_owned(),
                    value: if v.is_nan() {
                        "null (NaN)".into()
                    } else {
                        v.to_string()
                    },
                    range: "the numbers (it is sent as int(value))",
                });
            }
            // int(-0.5) is 0, written as +0.0.
            v.trunc() + 0.0
        } else {
            v
        };
        let scale = |s: f64| if scales.0.is_nan() { 1.0 } else { s };
        match res {
            Resolution::Int8 => w.write_i8(saturate(v, scale(scales.0), 127) as i8),
            Resolution::Int16 => w.write_i16(saturate(v, scale(scales.1), 32767) as i16),
            Resolution::Int32 => w.write_i32(saturate(v, scale(scales.2), 2_147_483_647) as i32),
            _ => w.write_f32(as_f32(member, v)?),
        }
    }
    Ok(needed)
}

/// How many bytes `WriteCombiner` writes for `resolutions` from register
/// `start`: for each run of one resolution, its header (the opcode, a
/// count byte for runs over 3, the register as a varuint) and its values.
fn block_size(start: u16, resolutions: &[Resolution]) -> usize {
    let mut size = 0;
    let mut i = 0;
    while let Some(&r) = resolutions.get(i) {
        let run = resolutions.iter().skip(i).take_while(|x| **x == r).count();
        if r != Resolution::Ignore {
            let register = u32::from(start) + u32::try_from(i).unwrap_or(u32::MAX);
            let varuint = if register < 0x80 {
                1
            } else if register < 0x4000 {
                2
            } else {
                3
            };
            size += 1 + usize::from(run > 3) + varuint + run * r.size();
        }
        i += run.max(1);
    }
    size
}

/// The library's `saturate` for an integer resolution: the value over its
/// scale in f64, held within ±`max`, then toward zero; NaN (and the
/// infinities) as the type's most negative value.
#[allow(clippy::cast_possible_truncation)]
fn saturate(v: f64, scale: f64, max: i64) -> i64 {
    if !v.is_finite() {
        return -max - 1;
    }
    let scaled = v / scale;
    #[allow(clippy::cast_precision_loss)]
    let m = max as f64;
    if scaled < -m {
        -max
    } else if scaled > m {
        max
    } else {
        scaled.trunc() as i64
    }
}

/// A value sent as an f32: refused when it rounds beyond f32's range (the
/// library's `struct.pack` refuses it too).
fn as_f32(member: &str, v: f64) -> Result<f32, CallError> {
    #[allow(clippy::cast_possible_truncation)]
    let f = v as f32;
    if v.is_finite() && f.is_infinite() {
        return Err(CallError::OutOfRange {
            member: member.to_owned(),
            value: v.to_string(),
            range: "an f32's range (±3.4028235e38)",
        });
    }
    Ok(f)
}
