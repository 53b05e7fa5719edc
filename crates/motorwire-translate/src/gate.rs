//! The safety gate: nothing outside a motor's limits gets past it.

use motorwire_core::ControlMode;
use motorwire_wia::MotorCommand;

use crate::{BusMap, MappedMotor, Target};

/// Why a command was refused before any bytes existed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum Refusal {
    /// The motor is not in the bus map.
    #[error("motor {motor:?} is not in the bus map")]
    UnknownMotor {
        /// The `motor_id`.
        motor: String,
    },
    /// A value is NaN or infinite.
    #[error("{motor}: {field} is not a finite number")]
    NonFinite {
        /// The motor.
        motor: String,
        /// The field.
        field: &'static str,
    },
    /// A value outside a limit.
    #[error("{motor}: {field} {value} is outside {limit} ({limit_source}) {bound}")]
    OutsideLimit {
        /// The motor.
        motor: String,
        /// The command's field.
        field: &'static str,
        /// The value.
        value: f64,
        /// The limit broken (`max_position`, `max_velocity` ...).
        limit: &'static str,
        /// Where the limit came from ([`Bound::source`]: `bus map`, a
        /// SafetyLimits line, `command`, `Orion range`).
        limit_source: &'static str,
        /// The limit's value.
        bound: f64,
    },
    /// The target dialect cannot express the control mode.
    #[error("{motor}: {dialect} cannot express control mode {mode}")]
    ModeNotExpressible {
        /// The motor.
        motor: String,
        /// The mode.
        mode: &'static str,
        /// The target dialect.
        dialect: &'static str,
    },
    /// The target needs a limit neither the command nor the bus map gives.
    #[error("{motor}: {dialect} needs {field}, and neither the command nor the bus map gives it")]
    MissingLimit {
        /// The motor.
        motor: String,
        /// The target dialect.
        dialect: &'static str,
        /// The limit (`max_velocity` ...).
        field: &'static str,
    },
    /// A value the target format cannot hold.
    #[error("{motor}: {problem}")]
    NotRepresentable {
        /// The motor.
        motor: String,
        /// The field.
        field: &'static str,
        /// Why, naming the field.
        problem: String,
    },
    /// A synchronized move needs a joint's current position, and it is
    /// not known (no feedback yet).
    #[error("{motor}: its current position is not known, so its move cannot be synchronized")]
    UnknownPosition {
        /// The motor.
        motor: String,
    },
    /// A trajectory waypoint that cannot be reached at its time within the
    /// limits, or is outside them.
    #[error("{motor}: waypoint {waypoint}: {problem}")]
    Infeasible {
        /// The motor.
        motor: String,
        /// The waypoint (counted from 0).
        waypoint: usize,
        /// Why, naming the limit.
        problem: String,
    },
    /// A multi-axis move whose axes cannot arrive together.
    #[error("{problem}")]
    Unsynchronizable {
        /// Why.
        problem: String,
    },
    /// A move whose target is within the limits but whose planned path,
    /// from the joint's current position and velocity, passes a position
    /// limit on the way ([`check_path`](crate::check_path)). Positions are
    /// in the motor's unit. The message rounds the extreme and the
    /// overshoot to the same decimals, enough for three significant digits
    /// of the overshoot (at least three), and the time to the millisecond;
    /// the fields keep them in full.
    #[error(
        "{motor}: {}the planned path reaches {} past {limit} ({limit_source}) {bound} by {} ({} s into the move)",
        in_segment(*.segment),
        shown(*.extreme, *.overshoot),
        shown(*.overshoot, *.overshoot),
        shown(*.at, 1.0)
    )]
    PathOutsideLimit {
        /// The motor.
        motor: String,
        /// For a trajectory, the segment whose path passes the limit,
        /// counted from 0 (the index in the slice of segments); `None` for
        /// a single move.
        segment: Option<usize>,
        /// The limit passed (`min_position` or `max_position`).
        limit: &'static str,
        /// Where the limit came from ([`Bound::source`]).
        limit_source: &'static str,
        /// The limit's value.
        bound: f64,
        /// The lowest (for `min_position`) or highest (for `max_position`)
        /// position the path reaches.
        extreme: f64,
        /// How far past the limit it reaches: `|extreme - bound|`.
        overshoot: f64,
        /// When it reaches `extreme` (s after the move starts).
        at: f64,
    },
    /// A move the joint's planner refuses (a limit that is zero or
    /// negative, a target velocity faster than `max_velocity`, a value
    /// that is not finite ...): the joint would refuse it too.
    #[error("{motor}: {}the joint cannot plan the move: {problem}", in_segment(*.segment))]
    Unplannable {
        /// The motor.
        motor: String,
        /// For a trajectory, the segment, counted from 0; `None` for a
        /// single move.
        segment: Option<usize>,
        /// The planner's reason.
        problem: String,
    },
}

impl Refusal {
    /// Every name [`Refusal::rule`] gives, in the order of the variants.
    pub const RULES: &'static [&'static str] = &[
        "unknown_motor",
        "non_finite",
        "outside_limit",
        "mode_not_expressible",
        "missing_limit",
        "not_representable",
        "unknown_position",
        "infeasible",
        "unsynchronizable",
        "path_outside_limit",
        "unplannable",
    ];

    /// The refusal's kind as a stable snake_case name, for machine-readable
    /// output (`motorwire translate`'s `error.rule`): `unknown_motor`,
    /// `non_finite`, `outside_limit`, `mode_not_expressible`,
    /// `missing_limit`, `not_representable`, `unknown_position`,
    /// `unsynchronizable`, `path_outside_limit`, `unplannable`.
    ///
    /// ```
    /// use motorwire_translate::Refusal;
    /// assert_eq!(Refusal::UnknownMotor { motor: "knee".into() }.rule(), "unknown_motor");
    /// ```
    pub const fn rule(&self) -> &'static str {
        match self {
            Self::UnknownMotor { .. } => "unknown_motor",
            Self::NonFinite { .. } => "non_finite",
            Self::OutsideLimit { .. } => "outside_limit",
            Self::ModeNotExpressible { .. } => "mode_not_expressible",
            Self::MissingLimit { .. } => "missing_limit",
            Self::NotRepresentable { .. } => "not_representable",
            Self::UnknownPosition { .. } => "unknown_position",
            Self::Unsynchronizable { .. } => "unsynchronizable",
            Self::Infeasible { .. } => "infeasible",
            Self::PathOutsideLimit { .. } => "path_outside_limit",
            Self::Unplannable { .. } => "unplannable",
        }
    }
}

/// What a [`Refusal`] names, as values, for a program to read beside its
/// message ([`Refusal::detail`]): each member is there where the refusal
/// has it.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[non_exhaustive]
pub struct RefusalDetail<'a> {
    /// The motor.
    pub motor: Option<&'a str>,
    /// The command's field (`setpoint`, `velocity_limit` ...).
    pub field: Option<&'static str>,
    /// The field's value, or the position the path reaches.
    pub value: Option<f64>,
    /// The limit's name (`max_position` ...).
    pub limit: Option<&'static str>,
    /// The limit's value.
    pub bound: Option<f64>,
    /// Where the limit came from ([`Bound::source`]).
    pub source: Option<&'static str>,
}

impl Refusal {
    /// What the refusal names, as values.
    ///
    /// ```
    /// use motorwire_translate::Refusal;
    /// let r = Refusal::OutsideLimit {
    ///     motor: "elbow".into(), field: "setpoint", value: 170.0,
    ///     limit: "max_position", limit_source: "bus map", bound: 150.0,
    /// };
    /// let d = r.detail();
    /// assert_eq!((d.field, d.value, d.limit, d.bound, d.source),
    ///            (Some("setpoint"), Some(170.0), Some("max_position"), Some(150.0), Some("bus map")));
    /// assert_eq!(r.to_string(), "elbow: setpoint 170 is outside max_position (bus map) 150");
    /// ```
    pub fn detail(&self) -> RefusalDetail<'_> {
        fn of(motor: &str) -> RefusalDetail<'_> {
            RefusalDetail {
                motor: Some(motor),
                ..RefusalDetail::default()
            }
        }
        match self {
            Self::UnknownMotor { motor }
            | Self::ModeNotExpressible { motor, .. }
            | Self::UnknownPosition { motor }
            | Self::Infeasible { motor, .. }
            | Self::Unplannable { motor, .. } => of(motor),
            Self::NonFinite { motor, field } | Self::NotRepresentable { motor, field, .. } => {
                RefusalDetail {
                    field: Some(field),
                    ..of(motor)
                }
            }
            Self::MissingLimit { motor, field, .. } => RefusalDetail {
                limit: Some(field),
                ..of(motor)
            },
            Self::OutsideLimit {
                motor,
                field,
                value,
                limit,
                limit_source,
                bound,
            } => RefusalDetail {
                field: Some(field),
                value: Some(*value),
                limit: Some(limit),
                bound: Some(*bound),
                source: Some(limit_source),
                ..of(motor)
            },
            Self::PathOutsideLimit {
                motor,
                limit,
                limit_source,
                bound,
                extreme,
                ..
            } => RefusalDetail {
                field: Some("path"),
                value: Some(*extreme),
                limit: Some(limit),
                bound: Some(*bound),
                source: Some(limit_source),
                ..of(motor)
            },
            Self::Unsynchronizable { .. } => RefusalDetail::default(),
        }
    }
}

/// `"segment N (counted from 0): "` for a trajectory's segment, or nothing.
fn in_segment(segment: Option<usize>) -> String {
    segment.map_or_else(String::new, |i| format!("segment {i} (counted from 0): "))
}

/// `x` rounded to as many decimals as show three significant digits of
/// `overshoot` (at least three), trailing zeros dropped: an extreme and
/// its overshoot shown side by side add up.
fn shown(x: f64, overshoot: f64) -> String {
    let mut decimals: i32 = 3;
    while decimals < 17 && overshoot < 10f64.powi(2 - decimals) {
        decimals += 1;
    }
    let text = format!("{x:.*}", decimals.unsigned_abs() as usize);
    let text = text.trim_end_matches('0').trim_end_matches('.');
    if text == "-0" {
        "0".to_owned()
    } else {
        text.to_owned()
    }
}

/// A limit and where it came from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bound {
    /// The value.
    pub value: f64,
    /// `"bus map"` (or, once a runtime tightening replaced the map's,
    /// what [`BusMap::set_limits`](crate::BusMap::set_limits) was told),
    /// `"command"` or `"Orion range"`.
    pub source: &'static str,
}

/// The limits a command is held to: the bus map's, tightened by the
/// command's own `safety_limits` and, for Orion motors, by the document's
/// value range.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Effective {
    /// Lowest position.
    pub min_position: Option<Bound>,
    /// Highest position.
    pub max_position: Option<Bound>,
    /// Largest speed.
    pub max_velocity: Option<Bound>,
    /// Largest torque.
    pub max_torque: Option<Bound>,
    /// Largest acceleration (bus map only).
    pub max_acceleration: Option<Bound>,
}

fn tighter(a: Option<Bound>, b: Option<Bound>, lower_wins: bool) -> Option<Bound> {
    match (a, b) {
        (Some(x), Some(y)) => Some(if (y.value < x.value) == lower_wins {
            y
        } else {
            x
        }),
        (x, None) => x,
        (None, y) => y,
    }
}

fn from_map(v: Option<f64>, source: &'static str) -> Option<Bound> {
    v.map(|value| Bound { value, source })
}

impl Effective {
    /// The limits a motor is held to by the bus map alone (and, for an
    /// Orion motor, the document's value range), when there is no command
    /// to tighten them: for checking payloads built elsewhere, such as a
    /// trajectory's segments ([`check_trajectory`](crate::check_trajectory)).
    ///
    /// ```
    /// use motorwire_translate::{BusMap, Effective};
    /// let map = BusMap::from_toml(r#"
    ///     [motors.elbow]
    ///     dialect = "irpc"
    ///     node = 0x12
    ///     limits = { min_position = 0, max_position = 150 }
    /// "#)?;
    /// let e = Effective::from_bus_map(map.motor("elbow").unwrap());
    /// assert_eq!(e.max_position.map(|b| (b.value, b.source)), Some((150.0, "bus map")));
    /// # Ok::<(), motorwire_translate::MapError>(())
    /// ```
    pub fn from_bus_map(motor: &MappedMotor) -> Self {
        Self::with(motor, None)
    }

    fn new(motor: &MappedMotor, cmd: &MotorCommand) -> Self {
        Self::with(motor, cmd.safety_limits.as_ref())
    }

    fn with(mapped: &MappedMotor, own: Option<&motorwire_wia::CommandSafetyLimits>) -> Self {
        let (limits, target, source) = (&mapped.limits, mapped.target, mapped.limits_source);
        let from_cmd = |v: Option<f64>| {
            v.map(|value| Bound {
                value,
                source: "command",
            })
        };
        let mut e = Effective {
            min_position: tighter(
                from_map(limits.min_position, source),
                from_cmd(own.and_then(|l| l.min_position)),
                false,
            ),
            max_position: tighter(
                from_map(limits.max_position, source),
                from_cmd(own.and_then(|l| l.max_position)),
                true,
            ),
            max_velocity: tighter(
                from_map(limits.max_velocity, source),
                from_cmd(own.and_then(|l| l.max_velocity)),
                true,
            ),
            max_torque: tighter(
                from_map(limits.max_torque, source),
                from_cmd(own.and_then(|l| l.max_torque)),
                true,
            ),
            max_acceleration: from_map(limits.max_acceleration, source),
        };
        if let Target::Orion { motor } = target {
            let (lo, hi) = motor.range();
            let range = |value| {
                Some(Bound {
                    value,
                    source: "Orion range",
                })
            };
            match motor.quantity() {
                // The range is in degrees; positions are compared in the
                // map's unit (180 rad is not within ±180°).
                motorwire_orion::Quantity::PositionDegrees => {
                    let unit = mapped.unit;
                    e.min_position = tighter(e.min_position, range(unit.from_degrees(lo)), false);
                    e.max_position = tighter(e.max_position, range(unit.from_degrees(hi)), true);
                }
                _ => e.max_velocity = tighter(e.max_velocity, range(hi), true),
            }
        }
        e
    }
}

fn outside(motor: &str, field: &'static str, value: f64, name: &'static str, b: Bound) -> Refusal {
    Refusal::OutsideLimit {
        motor: motor.to_owned(),
        field,
        value,
        limit: name,
        limit_source: b.source,
        bound: b.value,
    }
}

/// Checks `cmd` against its motor's limits and returns the motor and the
/// effective limits. Positions are compared in the motor's own unit (the
/// bus map's `unit`), before any conversion. Orion motors are held to the
/// document's value ranges too, so the controller never has to clamp.
///
/// ```
/// use motorwire_translate::{BusMap, Refusal, gate};
/// let map = BusMap::from_toml(r#"
///     [motors.elbow]
///     dialect = "irpc"
///     node = 0x12
///     limits = { min_position = 0, max_position = 150, max_velocity = 120, max_acceleration = 500 }
/// "#)?;
/// let cmd: motorwire_wia::MotorCommand = serde_json::from_str(r#"{
///     "motor_id": "elbow", "timestamp": 0, "control_mode": "position", "setpoint": 170
/// }"#)?;
/// let err = gate(&map, &cmd).unwrap_err();
/// assert_eq!(err.to_string(), "elbow: setpoint 170 is outside max_position (bus map) 150");
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
/// A [`Refusal`] naming the motor, the field, the value and the limit.
pub fn gate<'m>(
    map: &'m BusMap,
    cmd: &MotorCommand,
) -> Result<(&'m MappedMotor, Effective), Refusal> {
    let motor = map
        .motor(&cmd.motor_id)
        .ok_or_else(|| Refusal::UnknownMotor {
            motor: cmd.motor_id.clone(),
        })?;
    let name = motor.name.as_str();
    let finite = |field: &'static str, v: Option<f64>| match v {
        Some(x) if !x.is_finite() => Err(Refusal::NonFinite {
            motor: name.to_owned(),
            field,
        }),
        _ => Ok(()),
    };
    finite("setpoint", Some(cmd.setpoint))?;
    finite("velocity_limit", cmd.velocity_limit)?;
    finite("acceleration_limit", cmd.acceleration_limit)?;
    finite("torque_limit", cmd.torque_limit)?;
    if let Some(l) = &cmd.safety_limits {
        finite("safety_limits.min_position", l.min_position)?;
        finite("safety_limits.max_position", l.max_position)?;
        finite("safety_limits.max_velocity", l.max_velocity)?;
        finite("safety_limits.max_torque", l.max_torque)?;
    }
    let e = Effective::new(motor, cmd);
    let sp = cmd.setpoint;
    match cmd.control_mode {
        ControlMode::Disabled => {}
        ControlMode::Position => {
            if let Some(b) = e.min_position.filter(|b| sp < b.value) {
                return Err(outside(name, "setpoint", sp, "min_position", b));
            }
            if let Some(b) = e.max_position.filter(|b| sp > b.value) {
                return Err(outside(name, "setpoint", sp, "max_position", b));
            }
        }
        ControlMode::Velocity => {
            if let Some(b) = e.max_velocity.filter(|b| sp.abs() > b.value) {
                return Err(outside(name, "setpoint", sp, "max_velocity", b));
            }
        }
        ControlMode::Torque => {
            if let Some(b) = e.max_torque.filter(|b| sp.abs() > b.value) {
                return Err(outside(name, "setpoint", sp, "max_torque", b));
            }
        }
        // The other modes carry a setpoint whose unit the limits do not
        // describe; the dialects refuse the ones they cannot express.
        _ => {}
    }
    if let (Some(v), Some(b)) = (cmd.velocity_limit, e.max_velocity)
        && v > b.value
    {
        return Err(outside(name, "velocity_limit", v, "max_velocity", b));
    }
    if let (Some(v), Some(b)) = (cmd.acceleration_limit, e.max_acceleration)
        && v > b.value
    {
        return Err(outside(
            name,
            "acceleration_limit",
            v,
            "max_acceleration",
            b,
        ));
    }
    if let (Some(v), Some(b)) = (cmd.torque_limit, e.max_torque)
        && v > b.value
    {
        return Err(outside(name, "torque_limit", v, "max_torque", b));
    }
    Ok((motor, e))
}

/// Checks a calibration request for `motor` against its limits in force,
/// as a motion is checked (a calibration moves the joint): its velocity
/// limit within `max_velocity`, its position range within the motor's
/// range (`max_position − min_position`), every value finite, its limits
/// and timeout not negative. The request is in degrees (iRPC's unit); the
/// limits are converted from the motor's unit.
///
/// ```
/// use motorwire_irpc::CalibrationRequest;
/// use motorwire_translate::{BusMap, gate_calibration};
/// let map = BusMap::from_toml(r#"
///     [motors.elbow]
///     dialect = "irpc"
///     node = 0x12
///     limits = { min_position = 0, max_position = 150, max_velocity = 120 }
/// "#)?;
/// let mut request = CalibrationRequest {
///     phases: 1, max_current: 2.0, max_velocity: 60.0, max_position_range: 90.0,
///     phase_timeout: 5.0, return_home: true,
/// };
/// assert!(gate_calibration(&map, "elbow", &request).is_ok());
/// request.max_position_range = 1000.0;
/// assert_eq!(
///     gate_calibration(&map, "elbow", &request).unwrap_err().to_string(),
///     "elbow: max_position_range 1000 is outside position range (bus map) 150",
/// );
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
/// A [`Refusal`] naming the motor, the field, the value and the limit.
pub fn gate_calibration<'m>(
    map: &'m BusMap,
    motor: &str,
    request: &motorwire_irpc::CalibrationRequest,
) -> Result<&'m MappedMotor, Refusal> {
    let m = map.motor(motor).ok_or_else(|| Refusal::UnknownMotor {
        motor: motor.to_owned(),
    })?;
    let name = m.name.as_str();
    let source = m.limits_source;
    let fields = [
        ("max_current", request.max_current),
        ("max_velocity", request.max_velocity),
        ("max_position_range", request.max_position_range),
        ("phase_timeout", request.phase_timeout),
    ];
    for (field, v) in fields {
        let v = f64::from(v);
        if !v.is_finite() {
            return Err(Refusal::NonFinite {
                motor: name.to_owned(),
                field,
            });
        }
        if v < 0.0 {
            return Err(Refusal::OutsideLimit {
                motor: name.to_owned(),
                field,
                value: v,
                limit: "minimum",
                limit_source: "calibration",
                bound: 0.0,
            });
        }
    }
    let deg = |x: f64| m.unit.to_degrees(x);
    let velocity = f64::from(request.max_velocity);
    if let Some(max) = m.limits.max_velocity.map(deg)
        && velocity > max
    {
        return Err(Refusal::OutsideLimit {
            motor: name.to_owned(),
            field: "max_velocity",
            value: velocity,
            limit: "max_velocity",
            limit_source: source,
            bound: max,
        });
    }
    let range = f64::from(request.max_position_range);
    if let (Some(lo), Some(hi)) = (m.limits.min_position, m.limits.max_position) {
        let span = deg(hi) - deg(lo);
        if range > span {
            return Err(Refusal::OutsideLimit {
                motor: name.to_owned(),
                field: "max_position_range",
                value: range,
                limit: "position range",
                limit_source: source,
                bound: span,
            });
        }
    }
    Ok(m)
}
