//! WIA motor commands for mjbots moteus controllers.

use motorwire_core::ControlMode;
use motorwire_moteus::PositionArgs;
use motorwire_wia::{MotorCommand, MultiAxisCommand};

use crate::command::{
    each_axis, emergency, from_defaulted, gate_unless_emergency, not_for, report_unused,
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
/// assert_eq!(t.report.losses[0].to_string(), "velocity_limit: defaulted: 180 from the bus map");
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
/// The gate's refusals, a motor of another dialect, a mode moteus's
/// position mode cannot express (impedance, admittance, trajectory as one
/// command, ...).
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
    let unit = motor.unit;
    let rev = |v: f64| revolutions(unit, v);
    let mode = cmd.control_mode;
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
    let maximum_torque = match (cmd.torque_limit, effective.max_torque) {
        (Some(t), _) => Some(t),
        (None, Some(b)) => {
            report.push(
                "torque_limit",
                LossKind::Defaulted,
                from_defaulted(b.value, b.source),
            );
            Some(b.value)
        }
        (None, None) => None,
    };
    let mut args = PositionArgs {
        maximum_torque,
        ..PositionArgs::default()
    };
    if mode != ControlMode::Torque {
        args.accel_limit = match (cmd.acceleration_limit, effective.max_acceleration) {
            (Some(a), _) => Some(rev(a)),
            (None, Some(b)) => {
                report.push(
                    "acceleration_limit",
                    LossKind::Defaulted,
                    from_defaulted(b.value, b.source),
                );
                Some(rev(b.value))
            }
            (None, None) => None,
        };
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
            args.velocity_limit = match (cmd.velocity_limit, effective.max_velocity) {
                (Some(v), _) => Some(rev(v)),
                (None, Some(b)) => {
                    report.push(
                        "velocity_limit",
                        LossKind::Defaulted,
                        from_defaulted(b.value, b.source),
                    );
                    Some(rev(b.value))
                }
                (None, None) => None,
            };
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
    // Report order: as the fields are (defaulted limits last).
    report.losses.sort_by_key(|l| l.kind == LossKind::Defaulted);
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
            (Some(1.5), Some(0.0), Some(0.0), Some(1.8), None)
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
    }
}
