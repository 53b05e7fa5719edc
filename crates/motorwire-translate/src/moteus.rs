//! WIA motor commands for mjbots moteus controllers.

use motorwire_core::ControlMode;
use motorwire_moteus::PositionArgs;
use motorwire_wia::{MotorCommand, MultiAxisCommand};

use crate::command::{
    each_axis, emergency, gate_unless_emergency, not_for, own_or_default, report_unused,
};
use crate::gate::Refusal;
use crate::map::{AngleUnit, BusMap, Target};
use crate::report::{LossKind, Report, Translated};

/// What a moteus controller is sent for one WIA command.
// Copy, as the bridge's orders are: a stop is as large as a move.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum MoteusCommand {
    /// A position-mode frame: the controller plans the move itself within
    /// its `velocity_limit` and `accel_limit`. A velocity command is one
    /// with position NaN; a torque command one with feedforward torque
    /// and kp, kd scale 0.
    Position(PositionArgs),
    /// Stop mode: no output.
    Stop,
    /// Brake mode: the windings shorted.
    Brake,
}

/// The f32 nearest `v` that lies within `lo..=hi` (where `v` itself
/// does): one step of f32 inward when the nearest is just outside. NaN
/// and values the f32 cannot hold are left as they are (the codec says
/// what it does with them).
pub fn f32_within(v: f64, lo: Option<f64>, hi: Option<f64>) -> f64 {
    #[allow(clippy::cast_possible_truncation)]
    let f = v as f32;
    if !f.is_finite() {
        return v;
    }
    let step_down = |x: f32| {
        if x > 0.0 {
            f32::from_bits(x.to_bits() - 1)
        } else {
            -f32::from_bits((-x).to_bits() + 1)
        }
    };
    let step_up = |x: f32| {
        if x >= 0.0 {
            f32::from_bits(x.to_bits() + 1)
        } else {
            -f32::from_bits((-x).to_bits() - 1)
        }
    };
    let f = match (lo, hi) {
        (_, Some(h)) if v <= h && f64::from(f) > h => step_down(f),
        (Some(l), _) if v >= l && f64::from(f) < l => step_up(f),
        _ => f,
    };
    f64::from(f)
}

/// What a velocity or torque command's `watchdog_timeout` adds to the
/// motor's command timeout (s).
pub const WATCHDOG_MARGIN_S: f64 = 0.1;

/// Revolutions (moteus's unit) of `v` in `unit`.
pub fn revolutions(unit: AngleUnit, v: f64) -> f64 {
    unit.to_degrees(v) / 360.0
}

/// `cmd` for a motor the bus map gives the moteus dialect, behind the
/// safety gate (the limits in force, in the motor's unit), in the
/// controller's units (revolutions, revolutions a second, Nm):
/// - position: a position-mode frame to the setpoint, ending at rest,
///   with `velocity_limit` and `accel_limit` (the command's, else the
///   limits in force, said so) and `maximum_torque` (the command's
///   `torque_limit`, else the map's `max_torque`);
/// - velocity: position NaN at the setpoint's velocity, with the
///   acceleration and torque limits, and the motor's command timeout plus
///   [`WATCHDOG_MARGIN_S`] as the controller's own watchdog;
/// - torque: feedforward torque with kp and kd scale 0, the torque limit
///   and the watchdog;
/// - disabled: stop mode, the controller's torque off (the setpoint and
///   any limits are unused, and said so);
/// - an emergency stop: stop mode (brake mode where the map says `stop =
///   "brake"`).
///
/// ```
/// use motorwire_translate::{BusMap, MoteusCommand, to_moteus};
/// let map = BusMap::from_toml(r#"
///     [motors.knee]
///     dialect = "moteus"
///     id = 2
///     limits = { min_position = -90, max_position = 90, max_velocity = 180, max_acceleration = 720 }
/// "#)?;
/// let cmd = serde_json::from_str(r#"{"motor_id":"knee","timestamp":0,"control_mode":"position","setpoint":45}"#)?;
/// let t = to_moteus(&map, &cmd)?;
/// let MoteusCommand::Position(p) = t.value else { unreachable!() };
/// assert_eq!((p.position, p.velocity_limit, p.accel_limit), (Some(0.125), Some(0.5), Some(2.0)));
/// assert_eq!(t.report.losses[1].to_string(), "velocity_limit: defaulted: 180 from the bus map");
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
/// The gate's refusals, a motor of another dialect, a mode moteus's
/// position mode cannot express (impedance, admittance, trajectory as one
/// command, ...).
///
/// ```
/// use motorwire_translate::{BusMap, MoteusCommand, to_moteus};
/// let map = BusMap::from_toml("[motors.knee]\ndialect = \"moteus\"\nid = 2")?;
/// let cmd = serde_json::from_str(r#"{"motor_id":"knee","timestamp":0,"control_mode":"disabled","setpoint":0}"#)?;
/// assert_eq!(to_moteus(&map, &cmd)?.value, MoteusCommand::Stop);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn to_moteus(map: &BusMap, cmd: &MotorCommand) -> Result<Translated<MoteusCommand>, Refusal> {
    let (motor, effective) = gate_unless_emergency(map, cmd)?;
    let Target::Moteus { brake, .. } = motor.target else {
        return Err(not_for(motor, cmd, "moteus"));
    };
    let mut report = Report::default();
    if emergency(cmd) {
        return Ok(Translated {
            value: if brake {
                MoteusCommand::Brake
            } else {
                MoteusCommand::Stop
            },
            report,
        });
    }
    let mode = cmd.control_mode;
    // Disabled: the controller's stop mode, its torque off (brake mode is
    // a stop's, where the map asks for it: a disabled motor turns freely).
    if mode == ControlMode::Disabled {
        report_unused(cmd, &[], "moteus stop mode (torque off)", &mut report);
        if cmd.safety_limits.is_some() {
            report.push(
                "safety_limits",
                LossKind::Dropped,
                "stop mode takes no limits",
            );
        }
        return Ok(Translated {
            value: MoteusCommand::Stop,
            report,
        });
    }
    let unit = motor.unit;
    let rev = |v: f64| revolutions(unit, v);
    if !matches!(
        mode,
        ControlMode::Position | ControlMode::Velocity | ControlMode::Torque
    ) {
        return Err(Refusal::ModeNotExpressible {
            motor: motor.name.clone(),
            mode: mode.name(),
            dialect: "moteus (position, velocity and torque only)",
        });
    }
    let used: &[&str] = match mode {
        ControlMode::Torque => &["torque_limit"],
        _ => &["velocity_limit", "acceleration_limit", "torque_limit"],
    };
    report_unused(cmd, used, "a moteus position-mode command", &mut report);
    if cmd.safety_limits.is_some() {
        report.push(
            "safety_limits",
            LossKind::Dropped,
            "only emergency_stop has a place (stop mode)",
        );
    }
    let maximum_torque = own_or_default(
        "torque_limit",
        cmd.torque_limit,
        effective.max_torque,
        &mut report,
    );
    let mut args = PositionArgs {
        maximum_torque,
        ..PositionArgs::default()
    };
    if mode != ControlMode::Torque {
        args.accel_limit = own_or_default(
            "acceleration_limit",
            cmd.acceleration_limit,
            effective.max_acceleration,
            &mut report,
        )
        .map(rev);
    }
    // The controller's own watchdog: the deadman's time and a margin, so
    // that the bridge's deadman (a controlled stop) comes first and the
    // controller stops by itself only when the bridge cannot.
    let watchdog = motor
        .command_timeout
        .map(|t| t.as_secs_f64() + WATCHDOG_MARGIN_S);
    match mode {
        ControlMode::Position => {
            args.position = Some(rev(cmd.setpoint));
            args.velocity = Some(0.0);
            args.velocity_limit = own_or_default(
                "velocity_limit",
                cmd.velocity_limit,
                effective.max_velocity,
                &mut report,
            )
            .map(rev);
        }
        ControlMode::Velocity => {
            args.position = Some(f64::NAN);
            args.velocity = Some(rev(cmd.setpoint));
            args.watchdog_timeout = watchdog;
        }
        _ => {
            args.position = Some(f64::NAN);
            args.velocity = Some(0.0);
            args.feedforward_torque = Some(cmd.setpoint);
            args.kp_scale = Some(0.0);
            args.kd_scale = Some(0.0);
            args.watchdog_timeout = watchdog;
        }
    }
    // The frame carries f32: each value is the f32 nearest it that stays
    // within the limits in force (60° is 0.16666667 revolution, whose
    // nearest f32 is 60.0000018°).
    let bound = |b: Option<crate::gate::Bound>| b.map(|b| rev(b.value));
    let speed = bound(effective.max_velocity);
    args.position = args.position.map(|p| {
        f32_within(
            p,
            bound(effective.min_position),
            bound(effective.max_position),
        )
    });
    args.velocity = args
        .velocity
        .map(|v| f32_within(v, speed.map(|s| -s), speed));
    args.velocity_limit = args.velocity_limit.map(|v| f32_within(v, None, speed));
    args.accel_limit = args
        .accel_limit
        .map(|a| f32_within(a, None, bound(effective.max_acceleration)));
    args.maximum_torque = args
        .maximum_torque
        .map(|t| f32_within(t, None, effective.max_torque.map(|b| b.value)));
    // A limit of 0 (or one the f32 makes 0) is no limit moteus can plan
    // with: the move would never end.
    for (field, v) in [
        ("velocity_limit", args.velocity_limit),
        ("acceleration_limit", args.accel_limit),
    ] {
        if v.is_some_and(|v| v <= 0.0 || f64::from(v as f32) <= 0.0) {
            return Err(Refusal::NotRepresentable {
                motor: motor.name.clone(),
                field,
                problem: "a moteus move within a limit of 0 never ends; give a positive limit"
                    .to_owned(),
            });
        }
    }
    Ok(Translated {
        value: MoteusCommand::Position(args),
        report,
    })
}

/// A WIA multi-axis command for moteus controllers: each axis as
/// [`to_moteus`] translates it (behind the gate), in the command's order,
/// each axis's losses named `motor_id.field`. Each controller plans its own
/// move: `sync_mode`, `coordination` and `metadata` are reported dropped.
///
/// # Errors
/// The first axis's refusal, naming it.
pub fn multi_axis_to_moteus(
    map: &BusMap,
    cmd: &MultiAxisCommand,
) -> Result<Translated<Vec<MoteusCommand>>, Refusal> {
    each_axis(map, cmd, to_moteus, "a moteus position-mode command")
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::panic)]
    use super::*;

    fn map() -> BusMap {
        BusMap::from_toml(
            r#"
            [motors.hip]
            dialect = "moteus"
            id = 1
            unit = "rad"
            stop = "brake"
            limits = { min_position = -1.0, max_position = 1.0, max_velocity = 4.0, max_torque = 2.0 }
            "#,
        )
        .unwrap()
    }

    fn cmd(json: &str) -> MotorCommand {
        serde_json::from_str(json).unwrap()
    }

    #[test]
    fn velocity_and_torque_carry_the_watchdog_and_a_stop_is_the_maps() {
        let map = map();
        let t = to_moteus(
            &map,
            &cmd(
                r#"{"motor_id":"hip","timestamp":0,"control_mode":"velocity","setpoint":3.14159}"#,
            ),
        )
        .unwrap();
        let MoteusCommand::Position(p) = t.value else {
            panic!()
        };
        assert!(p.position.unwrap().is_nan());
        assert!((p.velocity.unwrap() - 0.5).abs() < 1e-5);
        // The deadman's 200 ms and the margin.
        assert_eq!(
            (p.watchdog_timeout, p.maximum_torque),
            (Some(0.2 + WATCHDOG_MARGIN_S), Some(2.0))
        );
        let t = to_moteus(&map, &cmd(r#"{"motor_id":"hip","timestamp":0,"control_mode":"torque","setpoint":1.5,"torque_limit":1.8}"#)).unwrap();
        let MoteusCommand::Position(p) = t.value else {
            panic!()
        };
        assert_eq!(
            (
                p.feedforward_torque,
                p.kp_scale,
                p.kd_scale,
                p.maximum_torque,
                p.velocity_limit
            ),
            (
                Some(1.5),
                Some(0.0),
                Some(0.0),
                Some(f64::from(1.8f32)),
                None
            )
        );
        let t = to_moteus(&map, &cmd(r#"{"motor_id":"hip","timestamp":0,"control_mode":"position","setpoint":0,"safety_limits":{"emergency_stop":true}}"#)).unwrap();
        assert_eq!(t.value, MoteusCommand::Brake);
        // Beyond the map's limit (radians): refused by the gate.
        let e = to_moteus(
            &map,
            &cmd(r#"{"motor_id":"hip","timestamp":0,"control_mode":"position","setpoint":1.5}"#),
        )
        .unwrap_err();
        assert_eq!(e.rule(), "outside_limit");
        let e = to_moteus(
            &map,
            &cmd(r#"{"motor_id":"hip","timestamp":0,"control_mode":"impedance","setpoint":0.5}"#),
        )
        .unwrap_err();
        assert_eq!(e.rule(), "mode_not_expressible");
        // Found by a hostile test: a velocity limit of 0 (or one the f32
        // makes 0) went out as a limit of 0.
        for v in ["0", "1e-320"] {
            let line = format!(
                r#"{{"motor_id":"hip","timestamp":0,"control_mode":"position","setpoint":0.5,"velocity_limit":{v}}}"#
            );
            let e = to_moteus(&map, &cmd(&line)).unwrap_err();
            assert_eq!(e.rule(), "not_representable", "{v}");
        }
    }
}

#[cfg(test)]
mod f32_tests {
    use super::*;

    /// Found by a hostile test: 60° went out as 60.0000018° under a 60°
    /// limit (the f32 nearest 60/360 revolution is above it).
    #[test]
    fn what_the_frame_carries_stays_within_the_limits() {
        let max = 60.0 / 360.0;
        #[allow(clippy::cast_possible_truncation)]
        let nearest = f64::from(max as f32);
        assert!(nearest > max);
        let inside = f32_within(max, Some(-max), Some(max));
        assert!(inside <= max && max - inside < 1e-8, "{inside}");
        assert_eq!(f64::from(inside as f32), inside);
        // Negative bounds, from below.
        assert!(f32_within(-max, Some(-max), Some(max)) >= -max);
        // A value already exact stays.
        assert_eq!(f32_within(0.5, Some(0.0), Some(0.5)), 0.5);
        // NaN stays NaN.
        assert!(f32_within(f64::NAN, None, Some(1.0)).is_nan());
    }
}
