//! WIA commands to iRPC, the compact command and Orion.

use std::cell::RefCell;
use std::sync::Arc;

use motorwire_compact::{CompactCommand, Flags, MotorHash, TorqueLimit, VelocityLimit};
use motorwire_core::ControlMode;
use motorwire_irpc::{MotionProfile, Payload, SetTargetPayload, SetTargetPayloadV2, WireVersion};
use motorwire_orion::{MotorValues, Quantity};
use motorwire_wia::{AxisCommand, MotorCommand, MultiAxisCommand};

use crate::gate::{Effective, gate};
use crate::report::{LossKind, LossText, Report, Translated};
use crate::{BusMap, MappedMotor, Refusal, Target};

/// WIA `priority` from which the compact command's `PRIORITY_HIGH` is set.
pub const HIGH_PRIORITY: i64 = 75;

/// What to send to one iRPC joint for one WIA command, in order.
#[derive(Debug, Clone, PartialEq)]
pub struct IrpcCommand {
    /// The joint's node id.
    pub node: u16,
    /// Its wire version.
    pub wire: WireVersion,
    /// The payloads, in the order to send them.
    pub payloads: Vec<Payload>,
}

pub(crate) fn emergency(cmd: &MotorCommand) -> bool {
    cmd.safety_limits.as_ref().and_then(|l| l.emergency_stop) == Some(true)
}

/// Reports every member of `cmd` that is present and not in `used`.
pub(crate) fn report_unused(cmd: &MotorCommand, used: &[&str], dialect: &str, report: &mut Report) {
    let present = [
        ("velocity_limit", cmd.velocity_limit.is_some()),
        ("acceleration_limit", cmd.acceleration_limit.is_some()),
        ("torque_limit", cmd.torque_limit.is_some()),
        ("pid_gains", cmd.pid_gains.is_some()),
        ("impedance_params", cmd.impedance_params.is_some()),
        ("filter_config", cmd.filter_config.is_some()),
        ("priority", cmd.priority.is_some()),
        ("metadata", cmd.metadata.is_some()),
    ];
    for (name, is) in present {
        if is && !used.contains(&name) {
            report.push(
                name,
                LossKind::Dropped,
                format!("{dialect} has no place for it"),
            );
        }
    }
    // motorwire's `stream` is the bridge's to read, not a member lost.
    for key in cmd
        .extra
        .keys()
        .filter(|k| k.as_str() != motorwire_wia::STREAM)
    {
        report.push(
            key.clone(),
            LossKind::Dropped,
            format!("an unknown member; {dialect} has no place for it"),
        );
    }
}

/// Whether the joint's planner takes `p`'s limits (each finite and above
/// zero once an f32, the target velocity within the velocity limit): the
/// checks that do not depend on where the joint is, so that this
/// translation refuses what a bridge, planning the move from the joint's
/// state, refuses as [`Refusal::Unplannable`] (a `velocity_limit` of
/// `1e-300` is 0 as an f32, which no joint can plan with).
fn plannable(motor: &str, p: &SetTargetPayloadV2) -> Result<(), Refusal> {
    p.planner_request(f64::from(p.target_angle), 0.0)
        .check()
        .map_err(|e| Refusal::Unplannable {
            motor: motor.to_owned(),
            segment: None,
            problem: e.to_string(),
        })
}

fn f32_of(motor: &str, field: &'static str, v: f64, report: &mut Report) -> Result<f32, Refusal> {
    #[allow(clippy::cast_possible_truncation)]
    let x = v as f32;
    if !x.is_finite() {
        return Err(Refusal::NotRepresentable {
            motor: motor.to_owned(),
            field,
            problem: format!("{field} {v} does not fit an f32"),
        });
    }
    if f64::from(x) != v {
        report.push(
            field,
            LossKind::Converted,
            format!("{v} rounded to the f32 {x}"),
        );
    }
    Ok(x)
}

/// Translates a WIA MotorCommand for an iRPC joint, after the safety gate
/// (an emergency stop passes it whatever it carries: stopping is always
/// safe).
///
/// - `position` becomes `SetTargetV2` (wire v2.0 and later) or `SetTarget`
///   (v1), positions converted to degrees. Velocity and acceleration limits
///   come from the command or, failing that, the bus map; deceleration from
///   the bus map's `max_deceleration` (no more than the command's
///   `acceleration_limit`) or, when the map has none, the acceleration
///   limit, the report saying which; jerk and the profile from the bus map
///   (an S-curve without a `max_jerk` in the map is trapezoidal, and
///   reported).
/// - `disabled` becomes `Deactivate`.
/// - `safety_limits.emergency_stop: true` becomes `Deactivate`, whatever the
///   mode: iRPC executes motion only in the Active state, so leaving it is
///   the one stop every joint obeys (a joint brakes to rest within its own
///   deceleration limit). The bridge sends it to every joint.
/// - Any other mode is refused ([`Refusal::ModeNotExpressible`]).
///
/// # Errors
/// [`gate`]'s refusals; [`Refusal::ModeNotExpressible`];
/// [`Refusal::MissingLimit`] when a move has no velocity or acceleration
/// limit; [`Refusal::NotRepresentable`] for a value beyond f32.
pub fn to_irpc(map: &BusMap, cmd: &MotorCommand) -> Result<Translated<IrpcCommand>, Refusal> {
    to_irpc_gated(map, cmd).map(|(t, ..)| t)
}

/// [`to_irpc`], with the motor the command is for and the limits in force
/// it was gated against (the defaults of an emergency stop, which passes
/// the gate whatever it carries): what a bridge checks the joint's whole
/// planned path against, without gating the command a second time.
///
/// ```
/// use motorwire_translate::{BusMap, to_irpc_gated};
/// use motorwire_wia::MotorCommand;
/// let map = BusMap::from_toml(
///     "[motors.elbow]\ndialect = \"irpc\"\nnode = 0x12\nlimits = { max_position = 90, max_velocity = 60, max_acceleration = 200 }",
/// )?;
/// let cmd: MotorCommand = serde_json::from_str(
///     r#"{"motor_id":"elbow","timestamp":1,"control_mode":"position","setpoint":30}"#,
/// )?;
/// let (t, motor, limits) = to_irpc_gated(&map, &cmd)?;
/// assert_eq!(motor.name, "elbow");
/// assert_eq!(limits.max_position.map(|b| b.value), Some(90.0));
/// assert_eq!(t.value.payloads.len(), 1);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
/// As [`to_irpc`].
pub fn to_irpc_gated<'m>(
    map: &'m BusMap,
    cmd: &MotorCommand,
) -> Result<(Translated<IrpcCommand>, &'m MappedMotor, Effective), Refusal> {
    let (motor, effective) = gate_unless_emergency(map, cmd)?;
    let Target::Irpc { node, wire } = motor.target else {
        return Err(not_for(motor, cmd, "iRPC"));
    };
    // Room for what a move reports: its defaulted limits, its profile.
    let mut report = Report {
        losses: Vec::with_capacity(4),
    };
    let name = motor.name.as_str();
    let payload = if emergency(cmd) {
        report.push(
            "setpoint",
            LossKind::Dropped,
            "emergency stop: the joint is deactivated instead of moved",
        );
        report_unused(cmd, &[], "an emergency stop", &mut report);
        Payload::Deactivate
    } else {
        match cmd.control_mode {
            ControlMode::Disabled => {
                report_unused(cmd, &[], "Deactivate", &mut report);
                Payload::Deactivate
            }
            ControlMode::Position => {
                let payload = set_target(motor, cmd, &effective, wire, &mut report)?;
                if let Payload::SetTargetV2(p) = &payload {
                    plannable(name, p)?;
                }
                payload
            }
            mode => {
                return Err(Refusal::ModeNotExpressible {
                    motor: name.to_owned(),
                    mode: mode.name(),
                    dialect: "iRPC",
                });
            }
        }
    };
    Ok((
        Translated {
            value: IrpcCommand {
                node,
                wire,
                payloads: vec![payload],
            },
            report,
        },
        motor,
        effective,
    ))
}

/// `Activate` (`enable: true`) or `Deactivate` for the iRPC joint named
/// `motor`. WIA has no "enable" command (a `disabled` command disables);
/// a bridge activates a joint before its first motion command and after a
/// `disabled` one.
///
/// ```
/// use motorwire_irpc::Payload;
/// use motorwire_translate::{BusMap, lifecycle};
/// let map = BusMap::from_toml("[motors.elbow]\ndialect = \"irpc\"\nnode = 0x12")?;
/// assert_eq!(lifecycle(&map, "elbow", true)?.payloads, [Payload::Activate]);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
/// [`Refusal::UnknownMotor`], or [`Refusal::ModeNotExpressible`] for a
/// motor that is not an iRPC joint.
pub fn lifecycle(map: &BusMap, motor: &str, enable: bool) -> Result<IrpcCommand, Refusal> {
    let m = map.motor(motor).ok_or_else(|| Refusal::UnknownMotor {
        motor: motor.to_owned(),
    })?;
    let Target::Irpc { node, wire } = m.target else {
        return Err(Refusal::ModeNotExpressible {
            motor: m.name.clone(),
            mode: if enable { "enable" } else { "disabled" },
            dialect: "iRPC (the bus map says this motor is not an iRPC joint)",
        });
    };
    Ok(IrpcCommand {
        node,
        wire,
        payloads: vec![if enable {
            Payload::Activate
        } else {
            Payload::Deactivate
        }],
    })
}

/// The gate, except for an emergency stop: a stop is never refused for
/// the sake of the setpoint or limits it carries (only an unknown motor
/// refuses it).
pub(crate) fn gate_unless_emergency<'m>(
    map: &'m BusMap,
    cmd: &MotorCommand,
) -> Result<(&'m MappedMotor, Effective), Refusal> {
    if emergency(cmd) {
        let motor = map
            .motor(&cmd.motor_id)
            .ok_or_else(|| Refusal::UnknownMotor {
                motor: cmd.motor_id.clone(),
            })?;
        return Ok((motor, Effective::default()));
    }
    gate(map, cmd)
}

pub(crate) fn not_for(motor: &MappedMotor, cmd: &MotorCommand, dialect: &'static str) -> Refusal {
    Refusal::ModeNotExpressible {
        motor: motor.name.clone(),
        mode: cmd.control_mode.name(),
        dialect: match dialect {
            "iRPC" => "iRPC (the bus map says this motor is not an iRPC joint)",
            "compact" => "the compact command (the bus map says this motor does not take it)",
            "moteus" => "moteus (the bus map says this motor is not a moteus controller)",
            _ => "Orion (the bus map says this motor is not an Orion motor)",
        },
    }
}

/// A limit from the command, or else from the effective limits (said so),
/// or else a refusal: iRPC needs it.
/// Where a limit came from, as a report says it: `bus map` is "the bus
/// map"; a source that names itself with its article is left as it is
/// ("the SafetyLimits line in force").
fn the(source: &str) -> String {
    if source.starts_with("the ") {
        source.to_owned()
    } else {
        let mut s = String::with_capacity(source.len() + 4);
        s.push_str("the ");
        s.push_str(source);
        s
    }
}

/// `value from the source`, as a defaulted limit's report says it.
///
/// Every command that leaves a limit out says the same words (a bridge,
/// three of them for every move), so each thread keeps the last
/// [`SAID_KEPT`] it made and shares them ([`LossText`]) rather than
/// writing and freeing them again.
fn from_source(value: f64, source: &'static str) -> LossText {
    thread_local! {
        static SAID: RefCell<Said> = const { RefCell::new(Said::new()) };
    }
    SAID.with(|said| said.borrow_mut().text(value, source))
}

/// How many defaulted limits' words [`from_source`] keeps, per thread.
const SAID_KEPT: usize = 16;

/// The words [`from_source`] made last: the value's bits, the source,
/// the text; the oldest made way for the newest.
struct Said {
    kept: [Option<(u64, &'static str, Arc<str>)>; SAID_KEPT],
    next: usize,
}

impl Said {
    const fn new() -> Self {
        Self {
            kept: [const { None }; SAID_KEPT],
            next: 0,
        }
    }

    fn text(&mut self, value: f64, source: &'static str) -> LossText {
        let bits = value.to_bits();
        for (b, s, text) in self.kept.iter().flatten() {
            // The sources are a few fixed texts: the same one is nearly
            // always the same pointer.
            if *b == bits && (std::ptr::eq(*s, source) || *s == source) {
                return LossText::from(Arc::clone(text));
            }
        }
        let text: Arc<str> = Arc::from(source_text(value, source));
        if let Some(slot) = self.kept.get_mut(self.next % SAID_KEPT) {
            *slot = Some((bits, source, Arc::clone(&text)));
        }
        self.next = self.next.wrapping_add(1);
        LossText::from(text)
    }
}

/// [`from_source`]'s words, written.
fn source_text(value: f64, source: &str) -> String {
    let mut s = String::with_capacity(source.len() + 24);
    push_value(&mut s, value);
    s.push_str(" from ");
    if !source.starts_with("the ") {
        s.push_str("the ");
    }
    s.push_str(source);
    s
}

/// Writes `v` as `{v}` writes it. A whole number (a limit such as 500,
/// what every defaulted limit of every command says) is written without
/// the formatting machinery, whose float path costs a bridge more than
/// the rest of the report.
fn push_value(s: &mut String, v: f64) {
    // Below 2^53 every whole f64 is an exact i64.
    if v.fract() == 0.0 && v.abs() < 9.0e15 && !(v == 0.0 && v.is_sign_negative()) {
        #[allow(clippy::cast_possible_truncation)]
        let n = v as i64;
        s.push_str(itoa::Buffer::new().format(n));
        return;
    }
    use core::fmt::Write;
    // Writing to a String cannot fail.
    let _ = write!(s, "{v}");
}

/// A limit from the command (`own`), or else the one in force
/// (`fallback`), reported `defaulted` with where it came from; `None` when
/// neither gives one.
pub(crate) fn own_or_default(
    field: &'static str,
    own: Option<f64>,
    fallback: Option<crate::Bound>,
    report: &mut Report,
) -> Option<f64> {
    own.or_else(|| {
        let b = fallback?;
        report.push(field, LossKind::Defaulted, from_source(b.value, b.source));
        Some(b.value)
    })
}

/// [`own_or_default`], or a refusal: iRPC needs the limit.
fn resolve(
    motor: &str,
    field: &'static str,
    own: Option<f64>,
    fallback: Option<crate::Bound>,
    report: &mut Report,
) -> Result<f64, Refusal> {
    own_or_default(field, own, fallback, report).ok_or_else(|| Refusal::MissingLimit {
        motor: motor.to_owned(),
        dialect: "iRPC",
        field,
    })
}

fn set_target(
    motor: &MappedMotor,
    cmd: &MotorCommand,
    e: &Effective,
    wire: WireVersion,
    report: &mut Report,
) -> Result<Payload, Refusal> {
    let name = motor.name.as_str();
    let unit = motor.unit;
    let deg = |v: f64| unit.to_degrees(v);
    if unit != crate::AngleUnit::Degrees {
        report.push(
            "setpoint",
            LossKind::Converted,
            "radians to degrees (iRPC's unit)",
        );
    }
    let velocity = resolve(
        name,
        "max_velocity",
        cmd.velocity_limit,
        e.max_velocity,
        report,
    )?;
    let target = f32_of(name, "setpoint", deg(cmd.setpoint), report)?;
    let velocity = f32_of(name, "velocity_limit", deg(velocity), report)?;
    if wire == WireVersion::V1 {
        report_unused(cmd, &["velocity_limit"], "SetTarget (iRPC v1)", report);
        return Ok(Payload::SetTarget(SetTargetPayload {
            target_angle: target,
            velocity_limit: velocity,
        }));
    }
    let acceleration = resolve(
        name,
        "max_acceleration",
        cmd.acceleration_limit,
        e.max_acceleration,
        report,
    )?;
    // The command's acceleration_limit bounds slowing down too. The report
    // names where the value really came from: the map's deceleration limit,
    // or an acceleration limit (the command's, or the one just defaulted)
    // when that is what bounds it.
    let from_acceleration = |value: f64| match cmd.acceleration_limit {
        Some(_) => format!("{value}, the command's acceleration_limit"),
        None => format!(
            "{value}, the max_acceleration from {}",
            the(e.max_acceleration.map_or("bus map", |b| b.source))
        ),
    };
    let deceleration = match motor.limits.max_deceleration {
        Some(d) if cmd.acceleration_limit.is_some_and(|a| a < d) => {
            let a = cmd.acceleration_limit.unwrap_or(d);
            report.push(
                "max_deceleration",
                LossKind::Defaulted,
                format!(
                    "{} (below max_deceleration {d} from {})",
                    from_acceleration(a),
                    the(motor.limits_source)
                ),
            );
            a
        }
        Some(d) => {
            report.push(
                "max_deceleration",
                LossKind::Defaulted,
                from_source(d, motor.limits_source),
            );
            d
        }
        None => {
            report.push(
                "max_deceleration",
                LossKind::Defaulted,
                format!(
                    "{} ({} gives no max_deceleration)",
                    from_acceleration(acceleration),
                    the(motor.limits_source)
                ),
            );
            acceleration
        }
    };
    let (profile, jerk) = match (motor.profile, motor.limits.max_jerk) {
        (MotionProfile::Trapezoidal, _) => (MotionProfile::Trapezoidal, 0.0),
        (p, Some(j)) => {
            report.push("max_jerk", LossKind::Defaulted, from_source(j, "bus map"));
            (p, j)
        }
        (_, None) => {
            report.push(
                "profile",
                LossKind::Defaulted,
                "trapezoidal: the bus map gives no max_jerk for an S-curve",
            );
            (MotionProfile::Trapezoidal, 0.0)
        }
    };
    report_unused(
        cmd,
        &["velocity_limit", "acceleration_limit"],
        "SetTargetV2",
        report,
    );
    Ok(Payload::SetTargetV2(SetTargetPayloadV2 {
        target_angle: target,
        max_velocity: velocity,
        target_velocity: 0.0,
        max_acceleration: f32_of(name, "acceleration_limit", deg(acceleration), report)?,
        max_deceleration: f32_of(name, "max_deceleration", deg(deceleration), report)?,
        max_jerk: f32_of(name, "max_jerk", deg(jerk), report)?,
        profile,
        max_current: 0.0,
        max_temperature: 0.0,
    }))
}

/// The compact command for a WIA MotorCommand, with no bus map (and so no
/// safety gate): every field the 24 bytes can carry, and a report of the
/// rest. [`to_compact`] is the same behind the gate.
///
/// # Errors
/// [`Refusal::NotRepresentable`] for a timestamp that is not a whole number
/// of milliseconds fitting 64 bits, or a value the compact fields cannot
/// hold.
pub fn compact_command(cmd: &MotorCommand) -> Result<Translated<CompactCommand>, Refusal> {
    let name = cmd.motor_id.as_str();
    let not_rep = |field: &'static str, problem: String| Refusal::NotRepresentable {
        motor: name.to_owned(),
        field,
        problem,
    };
    let t = cmd.timestamp;
    if !(t >= 0.0 && t.fract() == 0.0 && t < 18_446_744_073_709_551_616.0) {
        return Err(not_rep(
            "timestamp",
            format!("{t} is not a whole number of ms that fits 64 bits"),
        ));
    }
    #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)] // checked just above
    let timestamp_ms = t as u64;
    let setpoint = CompactCommand::setpoint_from_f64(cmd.setpoint)
        .map_err(|e| not_rep("setpoint", e.to_string()))?;
    let velocity_limit = cmd
        .velocity_limit
        .map(VelocityLimit::from_units_per_s)
        .transpose()
        .map_err(|e| not_rep("velocity_limit", e.to_string()))?;
    let torque_limit = cmd
        .torque_limit
        .map(TorqueLimit::from_nm)
        .transpose()
        .map_err(|e| not_rep("torque_limit", e.to_string()))?;
    let mut flags = Flags::NONE;
    if emergency(cmd) {
        flags = flags.union(Flags::EMERGENCY_STOP);
    }
    if cmd.priority.is_some_and(|p| p >= HIGH_PRIORITY) {
        flags = flags.union(Flags::PRIORITY_HIGH);
    }
    let mut report = Report::default();
    report_unused(
        cmd,
        &["velocity_limit", "torque_limit"],
        "the compact command",
        &mut report,
    );
    if let Some(loss) = report.losses.iter_mut().find(|l| l.field == "priority") {
        loss.kind = LossKind::Converted;
        loss.detail = format!("to the PRIORITY_HIGH flag (set from {HIGH_PRIORITY})").into();
    }
    if let Some(l) = &cmd.safety_limits {
        let others = l.min_position.is_some()
            || l.max_position.is_some()
            || l.max_velocity.is_some()
            || l.max_torque.is_some()
            || !l.extra.is_empty();
        if others {
            report.push(
                "safety_limits",
                LossKind::Dropped,
                "only emergency_stop has a place (the EMERGENCY_STOP flag)",
            );
        }
    }
    Ok(Translated {
        value: CompactCommand {
            motor: MotorHash::of(&cmd.motor_id),
            timestamp_ms,
            control_mode: cmd.control_mode,
            flags,
            setpoint,
            velocity_limit,
            torque_limit,
        },
        report,
    })
}

/// [`compact_command`] for a motor the bus map gives the compact dialect,
/// behind the safety gate. A position command without a `velocity_limit`
/// carries the `max_velocity` in force (the bus map's, or a SafetyLimits
/// line's), as an iRPC joint's would: a frame without one would leave the
/// speed to the device.
///
/// ```
/// use motorwire_translate::{BusMap, to_compact};
/// let map = BusMap::from_toml(r#"
///     [motors.gripper]
///     dialect = "compact"
///     node = 0x20
///     limits = { min_position = 0, max_position = 90, max_velocity = 60 }
/// "#)?;
/// let cmd: motorwire_wia::MotorCommand = serde_json::from_str(r#"{
///     "motor_id": "gripper", "timestamp": 0, "control_mode": "position", "setpoint": 45
/// }"#)?;
/// let t = to_compact(&map, &cmd)?;
/// assert_eq!(t.value.velocity_limit.map(|l| l.units_per_s()), Some(60.0));
/// assert_eq!(t.report.losses[0].to_string(), "velocity_limit: defaulted: 60 from the bus map");
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
/// [`gate`]'s refusals, a motor of another dialect, and
/// [`compact_command`]'s.
pub fn to_compact(map: &BusMap, cmd: &MotorCommand) -> Result<Translated<CompactCommand>, Refusal> {
    let (motor, effective) = gate_unless_emergency(map, cmd)?;
    if !matches!(motor.target, Target::Compact { .. }) {
        return Err(not_for(motor, cmd, "compact"));
    }
    let mut t = compact_command(cmd)?;
    if cmd.control_mode == ControlMode::Position
        && cmd.velocity_limit.is_none()
        && !t.value.flags.contains(Flags::EMERGENCY_STOP)
        && let Some(b) = effective.max_velocity
    {
        let limit =
            VelocityLimit::from_units_per_s(b.value).map_err(|e| Refusal::NotRepresentable {
                motor: cmd.motor_id.clone(),
                field: "velocity_limit",
                problem: format!("the max_velocity in force, {}: {e}", b.value),
            })?;
        t.value.velocity_limit = Some(limit);
        t.report.push(
            "velocity_limit",
            LossKind::Defaulted,
            format!("{} from {}", b.value, the(b.source)),
        );
    }
    Ok(t)
}

/// A WIA multi-axis command for compact devices: each axis as
/// [`to_compact`] translates it (behind the gate), one compact command per
/// axis in the command's order, each axis's losses named
/// `motor_id.field`. Compact devices run their commands independently:
/// `sync_mode`, `coordination` and `metadata` have no place in the 24
/// bytes and are reported dropped.
///
/// ```
/// use motorwire_translate::{BusMap, multi_axis_to_compact};
/// let map = BusMap::from_toml(r#"
///     [motors.gripper]
///     dialect = "compact"
///     node = 0x20
///     limits = { min_position = 0, max_position = 90 }
/// "#)?;
/// let cmd: motorwire_wia::MultiAxisCommand = serde_json::from_str(r#"{
///     "command_id": "close", "timestamp": 0, "sync_mode": "simultaneous",
///     "motors": [{"motor_id": "gripper", "control_mode": "position", "setpoint": 45}]
/// }"#)?;
/// let t = multi_axis_to_compact(&map, &cmd)?;
/// assert_eq!(t.value[0].setpoint, 45.0);
/// assert_eq!(
///     t.report.losses[0].to_string(),
///     "sync_mode: dropped: the compact command has no place for it; each device runs its own command"
/// );
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
/// The first axis's refusal, naming it.
pub fn multi_axis_to_compact(
    map: &BusMap,
    cmd: &MultiAxisCommand,
) -> Result<Translated<Vec<CompactCommand>>, Refusal> {
    each_axis(map, cmd, to_compact, "the compact command")
}

/// Each axis of `cmd` translated alone by `one` (behind the gate), in the
/// command's order, each axis's losses named `motor_id.field`; what a
/// dialect whose devices each run their own command (`what`) has no place
/// for (`sync_mode`, `coordination`, `metadata`) reported dropped.
pub(crate) fn each_axis<T>(
    map: &BusMap,
    cmd: &MultiAxisCommand,
    one: impl Fn(&BusMap, &MotorCommand) -> Result<Translated<T>, Refusal>,
    what: &str,
) -> Result<Translated<Vec<T>>, Refusal> {
    let mut report = Report::default();
    let mut commands = Vec::with_capacity(cmd.motors.len());
    for axis in &cmd.motors {
        let t = one(map, &axis.to_motor_command(cmd.timestamp))?;
        report
            .losses
            .extend(t.report.losses.into_iter().map(|l| l.under(&axis.motor_id)));
        commands.push(t.value);
    }
    for (field, present) in [
        ("sync_mode", cmd.sync_mode.is_some()),
        ("coordination", cmd.coordination.is_some()),
        ("metadata", cmd.metadata.is_some()),
    ] {
        if present {
            report.push(
                field,
                LossKind::Dropped,
                format!("{what} has no place for it; each device runs its own command"),
            );
        }
    }
    Ok(Translated {
        value: commands,
        report,
    })
}

/// [`to_orion`] for one WIA MotorCommand: the command as a multi-axis
/// command of one axis, so it is gated and mapped exactly as an axis is
/// (its losses are named `motor_id.field`).
///
/// ```
/// use motorwire_translate::{BusMap, to_orion_motor};
/// let map = BusMap::from_toml("[motors.turntable]\ndialect = \"orion\"\nkey = \"TRM\"")?;
/// let cmd: motorwire_wia::MotorCommand = serde_json::from_str(
///     r#"{"motor_id": "turntable", "timestamp": 0, "control_mode": "velocity", "setpoint": 200}"#,
/// )?;
/// assert_eq!(to_orion_motor(&map, &cmd)?.value.to_json(), r#"{"ID":32,"MODE":1,"DATA":{"TRM":200}}"#);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
/// As [`to_orion`].
pub fn to_orion_motor(
    map: &BusMap,
    cmd: &MotorCommand,
) -> Result<Translated<motorwire_orion::Input>, Refusal> {
    let axis = AxisCommand {
        motor_id: cmd.motor_id.clone(),
        control_mode: cmd.control_mode,
        setpoint: cmd.setpoint,
        velocity_limit: cmd.velocity_limit,
        acceleration_limit: cmd.acceleration_limit,
        torque_limit: cmd.torque_limit,
        pid_gains: cmd.pid_gains.clone(),
        impedance_params: cmd.impedance_params.clone(),
        filter_config: cmd.filter_config.clone(),
        safety_limits: cmd.safety_limits.clone(),
        priority: cmd.priority,
        metadata: cmd.metadata.clone(),
        extra: cmd.extra.clone(),
    };
    to_orion(
        map,
        &MultiAxisCommand {
            command_id: cmd.motor_id.clone(),
            timestamp: cmd.timestamp,
            sync_mode: None,
            motors: vec![axis],
            coordination: None,
            metadata: None,
            extra: serde_json::Map::new(),
        },
    )
}

/// A WIA multi-axis command for Orion motors, as direct-control `DATA`,
/// each axis behind the safety gate (which holds Orion motors to the
/// document's ranges, so nothing is left for the controller to clamp).
/// Speed motors and actuators take `velocity` setpoints, the servo a
/// `position` setpoint (converted to degrees); `disabled` sends 0 to a
/// speed motor or actuator. An axis with `emergency_stop` makes the whole
/// command Orion's stop command (`MODE` 2, `DATA` 1).
///
/// # Errors
/// The first axis's refusal, naming it.
pub fn to_orion(
    map: &BusMap,
    cmd: &MultiAxisCommand,
) -> Result<Translated<motorwire_orion::Input>, Refusal> {
    let mut values = MotorValues::new();
    let mut report = Report::default();
    let mut stop = false;
    for axis in &cmd.motors {
        let single = axis.to_motor_command(cmd.timestamp);
        let (motor, _) = gate_unless_emergency(map, &single)?;
        let Target::Orion { motor: orion } = motor.target else {
            return Err(not_for(motor, &single, "orion"));
        };
        if emergency(&single) {
            stop = true;
            continue;
        }
        let value = match (orion.quantity(), single.control_mode) {
            (Quantity::Speed | Quantity::Actuator, ControlMode::Velocity) => single.setpoint,
            (Quantity::Speed | Quantity::Actuator, ControlMode::Disabled) => 0.0,
            (Quantity::PositionDegrees, ControlMode::Position) => {
                if motor.unit != crate::AngleUnit::Degrees {
                    report.push(
                        format!("{}.setpoint", motor.name),
                        LossKind::Converted,
                        "radians to degrees (GHS's unit)",
                    );
                }
                motor.unit.to_degrees(single.setpoint)
            }
            (_, mode) => {
                return Err(Refusal::ModeNotExpressible {
                    motor: motor.name.clone(),
                    mode: mode.name(),
                    dialect: "Orion",
                });
            }
        };
        let mut axis_report = Report::default();
        report_unused(&single, &[], "Orion direct control", &mut axis_report);
        report
            .losses
            .extend(axis_report.losses.into_iter().map(|l| l.under(&motor.name)));
        values.set(orion, value);
    }
    for (field, present) in [
        ("sync_mode", cmd.sync_mode.is_some()),
        ("coordination", cmd.coordination.is_some()),
        ("metadata", cmd.metadata.is_some()),
    ] {
        if present {
            report.push(
                field,
                LossKind::Dropped,
                "Orion direct control has no place for it",
            );
        }
    }
    let input = if stop {
        report.push(
            "motors",
            LossKind::Converted,
            "an emergency stop: Orion's stop command (MODE 2, DATA 1) replaces the values",
        );
        motorwire_orion::Input::Command(motorwire_orion::ArmCommand::Stop.into())
    } else {
        motorwire_orion::Input::DirectControl(values)
    };
    Ok(Translated {
        value: input,
        report,
    })
}

#[cfg(test)]
mod tests {
    /// The words a defaulted limit is reported with are the same whether
    /// made now or kept from before: for more values than are kept (so
    /// each is made again after it made way), values whose bits differ
    /// and whose text may not (0 and -0), and each source.
    #[test]
    fn a_defaulted_limit_says_the_same_words_made_or_kept() {
        let values = (0..super::SAID_KEPT * 3)
            .map(|i| f64::from(u32::try_from(i).unwrap_or(0)) * 12.5)
            .chain([0.0, -0.0, 1e300, f64::MIN_POSITIVE]);
        for round in 0..3 {
            for v in values.clone() {
                for source in [
                    "bus map",
                    "the command's safety_limits",
                    "SafetyLimits line 4",
                ] {
                    let said = super::from_source(v, source);
                    assert_eq!(
                        said.as_str(),
                        super::source_text(v, source),
                        "{v} {source} {round}"
                    );
                }
            }
        }
        assert_eq!(super::from_source(-0.0, "bus map"), "-0 from the bus map");
        assert_eq!(
            super::from_source(500.0, "the bus map"),
            "500 from the bus map"
        );
        assert_eq!(super::from_source(12.5, "bus map"), "12.5 from the bus map");
    }

    /// A value in a report is written as `{v}` writes it, whole numbers
    /// (the fast path) and the rest alike.
    #[test]
    fn a_reported_value_is_written_as_display_writes_it() {
        for v in [
            0.0,
            -0.0,
            1.0,
            -1.0,
            500.0,
            2000.0,
            -123_456_789.0,
            8_999_999_999_999_998.0,
            9.0e15,
            1e300,
            0.5,
            -2.25,
            120.000_000_1,
            f64::MIN_POSITIVE,
            f64::MAX,
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
        ] {
            let mut s = String::new();
            super::push_value(&mut s, v);
            assert_eq!(s, format!("{v}"), "{v:?}");
        }
    }
}
