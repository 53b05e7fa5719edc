//! What an order is and does: each dialect's orders read by the engine's questions (a position move? a setpoint? a stop?), joined into one message, and told as their effect on the device.

use super::*;

impl Order {
    /// Whether it is a position move (which a newer one may replace while
    /// it waits, and whose arrival is watched).
    pub(crate) fn is_position_move(&self) -> bool {
        match self {
            Self::Irpc(p) => matches!(p, Payload::SetTargetV2(_) | Payload::SetTarget(_)),
            Self::Compact(c) => c.control_mode == CompactMode::Position,
            Self::Orion(OrionOrder::Set(m, _)) => m.quantity() == Quantity::PositionDegrees,
            Self::Orion(OrionOrder::Command(_)) => false,
            Self::Moteus(MoteusCommand::Position(a)) => a.position.is_some_and(f64::is_finite),
            Self::Moteus(_) => false,
            Self::Servo(c) => matches!(c, ServoCommand::Goal { .. }),
        }
    }

    /// Whether it is a motor command's setpoint (a position move, a
    /// velocity or a torque), which a stream's newer setpoint replaces
    /// while it waits; a stop, a lifecycle step or an arm-wide command is
    /// not.
    pub(crate) fn is_setpoint(&self) -> bool {
        match self {
            Self::Irpc(p) => matches!(p, Payload::SetTargetV2(_) | Payload::SetTarget(_)),
            Self::Compact(c) => {
                matches!(
                    c.control_mode,
                    CompactMode::Position | CompactMode::Velocity | CompactMode::Torque
                ) && !c.flags.contains(Flags::EMERGENCY_STOP)
            }
            Self::Orion(OrionOrder::Set(..)) => true,
            Self::Orion(OrionOrder::Command(_)) => false,
            Self::Moteus(c) => matches!(c, MoteusCommand::Position(_)),
            Self::Servo(c) => matches!(c, ServoCommand::Goal { .. }),
        }
    }

    /// Whether it leaves its device holding a setpoint that does not end
    /// by itself (a compact velocity or torque, an Orion speed or actuator
    /// value, other than 0): what the deadman watches.
    pub(crate) fn holds_setpoint(&self) -> bool {
        match self {
            Self::Irpc(_) | Self::Servo(_) => false,
            Self::Compact(c) => {
                matches!(c.control_mode, CompactMode::Velocity | CompactMode::Torque)
                    && c.setpoint != 0.0
                    && !c.flags.contains(Flags::EMERGENCY_STOP)
            }
            Self::Orion(OrionOrder::Set(m, v)) => {
                m.quantity() != Quantity::PositionDegrees && *v != 0.0
            }
            Self::Orion(OrionOrder::Command(_)) => false,
            // A velocity (position NaN) or a torque other than 0.
            Self::Moteus(MoteusCommand::Position(a)) => {
                !a.position.is_some_and(f64::is_finite)
                    && (a.velocity.is_some_and(|v| v != 0.0)
                        || a.feedforward_torque.is_some_and(|t| t != 0.0))
            }
            Self::Moteus(_) => false,
        }
    }

    /// Whether it stops a device whose acknowledgement cannot be tied to
    /// it (a compact command: the device's next feedback record, whatever
    /// caused it, acknowledges it), and how its feedback shows it taken:
    /// `Some(true)`, the `enabled` status cleared (disabled, or the
    /// emergency-stop flag); `Some(false)`, slowing to rest (velocity 0).
    pub(crate) fn unconfirmed_stop(&self) -> Option<bool> {
        match self {
            Self::Compact(c)
                if c.flags.contains(Flags::EMERGENCY_STOP)
                    || c.control_mode == CompactMode::Disabled =>
            {
                Some(true)
            }
            Self::Compact(c) if c.control_mode == CompactMode::Velocity && c.setpoint == 0.0 => {
                Some(false)
            }
            _ => None,
        }
    }

    /// Whether it ends a velocity or torque setpoint its device holds (a
    /// stop of the device's own, or a velocity 0): the deadman has nothing
    /// to add to one in flight.
    pub(crate) fn ends_setpoint(&self) -> bool {
        match self {
            Self::Irpc(_) | Self::Orion(OrionOrder::Command(_)) => false,
            Self::Compact(_) => self.unconfirmed_stop().is_some(),
            Self::Orion(OrionOrder::Set(m, v)) => {
                m.quantity() != Quantity::PositionDegrees && *v == 0.0
            }
            Self::Moteus(MoteusCommand::Stop | MoteusCommand::Brake) => true,
            Self::Moteus(MoteusCommand::Position(a)) => {
                !a.position.is_some_and(f64::is_finite)
                    && a.velocity == Some(0.0)
                    && a.feedforward_torque.is_none_or(|t| t == 0.0)
            }
            Self::Servo(c) => !matches!(c, ServoCommand::Goal { .. }),
        }
    }

    /// Whether it is a device's emergency stop (a compact command's flag):
    /// what may still go while the emergency stop is latched.
    pub(crate) fn is_emergency_stop(&self) -> bool {
        matches!(self, Self::Compact(c) if c.flags.contains(Flags::EMERGENCY_STOP))
    }

    /// The same order with `now_ms` as its timestamp where it carries one
    /// (a compact command sent again is new bytes: a device executes it
    /// even if it took the first).
    #[must_use]
    pub(crate) fn restamped(self, now_ms: u64) -> Self {
        match self {
            Self::Compact(c) => Self::Compact(CompactCommand {
                timestamp_ms: now_ms,
                ..c
            }),
            other => other,
        }
    }

    /// The velocity setpoint it leaves its device holding, in the
    /// motor's `unit` a second: a compact velocity command's (in that unit
    /// already), a moteus velocity's (position NaN; revolutions on the
    /// wire); `None` for anything else.
    pub(crate) fn held_velocity(&self, unit: AngleUnit) -> Option<f64> {
        match self {
            Self::Compact(c) if c.control_mode == CompactMode::Velocity => {
                Some(f64::from(c.setpoint))
            }
            Self::Moteus(MoteusCommand::Position(a)) if !a.position.is_some_and(f64::is_finite) => {
                a.velocity
                    .filter(|v| v.is_finite())
                    .map(|v| unit.from_degrees(v * 360.0))
            }
            _ => None,
        }
    }

    /// The target of a move (degrees) where the order alone says it (an
    /// iRPC target is in degrees; the others are in the motor's unit and
    /// are given their target by the engine, which knows it).
    pub(crate) fn own_target(&self) -> Option<f64> {
        match self {
            Self::Irpc(Payload::SetTargetV2(p)) => Some(f64::from(p.target_angle)),
            Self::Irpc(Payload::SetTarget(p)) => Some(f64::from(p.target_angle)),
            // Revolutions on the wire, whatever the motor's unit.
            Self::Moteus(MoteusCommand::Position(a)) => {
                a.position.filter(|p| p.is_finite()).map(|p| p * 360.0)
            }
            // Degrees, through the servo's calibration.
            Self::Servo(ServoCommand::Goal { position, .. }) => Some(*position),
            _ => None,
        }
    }

    /// The motion the device plans for this order from `from` (its
    /// kinematics, degrees), where the bridge plans it as the device does
    /// (an iRPC `SetTargetV2`: the joint plans it from where it is, how
    /// fast it moves and how that changes, with motorwire's planner).
    /// `planned`: the gate's plan of a move from the same state, taken
    /// when it is this order's.
    pub(crate) fn device_plan(
        &self,
        from: Kinematics,
        planned: Option<(plan::Move, Box<motorwire_planner::Profile<f64>>)>,
    ) -> Option<Box<motorwire_planner::Profile<f64>>> {
        match self {
            Self::Irpc(Payload::SetTargetV2(p)) => match planned {
                Some((q, profile)) if q.terms() == *p => Some(profile),
                _ => motorwire_planner::plan(
                    &p.planner_request(from.0, from.1)
                        .with_start_acceleration(from.2),
                )
                .ok()
                .map(Box::new),
            },
            _ => None,
        }
    }

    /// Whether the path this order sends its motor along, planned as the
    /// device plans it from `from` (its kinematics, degrees), stays
    /// within the limits in force (`in_force`: the motor and its limits,
    /// looked up only when there is a path to check); `checked`: a move
    /// whose path was already checked from that state (the gate's, when
    /// the line came), which is not planned again. Only for the orders
    /// the bridge plans as the device does (an iRPC `SetTargetV2`); the
    /// others are held to the limits by their targets alone.
    pub(crate) fn path_refusal<'m>(
        &self,
        from: Kinematics,
        checked: Option<(Kinematics, plan::Move)>,
        in_force: impl FnOnce() -> Option<(
            &'m motorwire_translate::MappedMotor,
            motorwire_translate::Effective,
        )>,
    ) -> Option<motorwire_translate::Refusal> {
        let Self::Irpc(Payload::SetTargetV2(p)) = self else {
            return None;
        };
        if checked == Some((from, plan::Move::from(*p))) {
            return None;
        }
        let (motor, limits) = in_force()?;
        motorwire_translate::check_path_from(motor, &limits, p, in_unit(motor.unit, from)).err()
    }

    /// Where it takes the device and how fast, in degrees (`unit`: the
    /// motor's, in which compact commands are written).
    pub(crate) fn reach(&self, unit: AngleUnit) -> Reach {
        match self {
            Self::Irpc(Payload::SetTargetV2(p)) => Reach {
                target: Some(f64::from(p.target_angle)),
                speed: Some(f64::from(p.max_velocity)),
            },
            Self::Irpc(Payload::SetTarget(p)) => Reach {
                target: Some(f64::from(p.target_angle)),
                speed: Some(f64::from(p.velocity_limit)),
            },
            Self::Compact(c) if c.control_mode == CompactMode::Position => Reach {
                target: Some(unit.to_degrees(f64::from(c.setpoint))),
                speed: c.velocity_limit.map(|l| unit.to_degrees(l.units_per_s())),
            },
            Self::Compact(c) if c.control_mode == CompactMode::Velocity => Reach {
                target: None,
                speed: Some(unit.to_degrees(f64::from(c.setpoint))),
            },
            Self::Orion(OrionOrder::Set(m, v)) if m.quantity() == Quantity::PositionDegrees => {
                Reach {
                    target: Some(*v),
                    speed: None,
                }
            }
            // Revolutions on the wire, whatever the motor's unit.
            Self::Moteus(MoteusCommand::Position(a)) => {
                match a.position.filter(|p| p.is_finite()) {
                    Some(p) => Reach {
                        target: Some(p * 360.0),
                        speed: a.velocity_limit.map(|v| v.abs() * 360.0),
                    },
                    None => Reach {
                        target: None,
                        speed: a
                            .velocity
                            .filter(|v| v.is_finite())
                            .map(|v| v.abs() * 360.0),
                    },
                }
            }
            Self::Servo(ServoCommand::Goal {
                position, velocity, ..
            }) => Reach {
                target: Some(*position),
                speed: velocity.map(f64::abs),
            },
            _ => Reach::default(),
        }
    }

    /// What it did to its device once acknowledged, in `cx`.
    pub(crate) fn effect(&self, cx: &Context) -> Effect {
        let at = cx.at;
        match *self {
            Self::Irpc(p) => irpc::effect(p, cx),
            Self::Compact(c) => self.compact_effect(&c, cx),
            Self::Orion(OrionOrder::Set(m, v)) => match m.quantity() {
                Quantity::PositionDegrees => Effect {
                    target: Some(Some(v)),
                    moving: Moving::Until(at),
                    ..Effect::NONE
                },
                Quantity::Speed | Quantity::Actuator => self.holding(cx),
            },
            // A stop abandons the move; fold and unfold move the servo
            // where the controller takes it.
            Self::Orion(OrionOrder::Command(_)) => Effect {
                target: Some(None),
                moving: Moving::Until(at),
                ..Effect::NONE
            },
            Self::Moteus(MoteusCommand::Stop | MoteusCommand::Brake) => Effect {
                target: Some(None),
                moving: Moving::AtMost(at),
                ..Effect::NONE
            },
            Self::Moteus(MoteusCommand::Position(a)) => {
                match a.position.filter(|p| p.is_finite()) {
                    Some(p) => {
                        let target = p * 360.0;
                        let v = a
                            .velocity_limit
                            .map(|v| v.abs() * 360.0)
                            .or(cx.max_velocity)
                            .unwrap_or(60.0)
                            .max(1e-3);
                        let acc = a
                            .accel_limit
                            .map(|v| v.abs() * 360.0)
                            .or(cx.max_acceleration)
                            .unwrap_or(500.0)
                            .max(1e-3);
                        // A trapezoid's duration, a bound on the controller's move.
                        trapezoid(cx, target, v, acc)
                    }
                    None => self.holding(cx),
                }
            }
            Self::Servo(ServoCommand::Goal {
                position,
                velocity,
                acceleration,
            }) => {
                // Without a limit the servo moves at its own top speed
                // (an STS3215's is about 300°/s).
                let v = velocity.or(cx.max_velocity).unwrap_or(300.0).max(1e-3);
                let a = acceleration
                    .or(cx.max_acceleration)
                    .unwrap_or(3000.0)
                    .max(1e-3);
                trapezoid(cx, position, v, a)
            }
            // Held where it stands, or its torque off: the move abandoned.
            Self::Servo(ServoCommand::Hold | ServoCommand::TorqueOff) => Effect {
                target: Some(None),
                moving: Moving::AtMost(at),
                ..Effect::NONE
            },
        }
    }

    /// A compact device's command `c` (this order), acknowledged, in `cx`:
    /// an emergency stop abandons the move; a position move ends within a
    /// trapezoid's duration; a velocity or torque holds.
    fn compact_effect(&self, c: &CompactCommand, cx: &Context) -> Effect {
        let at = cx.at;
        if c.flags.contains(Flags::EMERGENCY_STOP) {
            // Its move abandoned.
            return Effect {
                target: Some(None),
                moving: Moving::AtMost(at),
                ..Effect::NONE
            };
        }
        match c.control_mode {
            CompactMode::Position => {
                let target = cx.unit.to_degrees(f64::from(c.setpoint));
                let v = c
                    .velocity_limit
                    .map(|l| cx.unit.to_degrees(l.units_per_s()))
                    .or(cx.max_velocity)
                    .unwrap_or(60.0)
                    .max(1e-3);
                let a = cx.max_acceleration.unwrap_or(500.0).max(1e-3);
                // A trapezoid's duration, a bound on the device's move.
                trapezoid(cx, target, v, a)
            }
            CompactMode::Velocity | CompactMode::Torque => self.holding(cx),
            _ => Effect {
                moving: Moving::Until(at),
                ..Effect::NONE
            },
        }
    }

    /// A velocity or torque setpoint's effect: no target; one other than
    /// 0 is watched by the deadman (and moves until then), 0 holds the
    /// device still.
    fn holding(&self, cx: &Context) -> Effect {
        let deadman = if self.holds_setpoint() {
            cx.command_timeout.map(|t| cx.at.saturating_add(t))
        } else {
            None
        };
        Effect {
            target: Some(None),
            moving: Moving::Until(deadman.unwrap_or(cx.at)),
            deadman,
            ..Effect::NONE
        }
    }
}

/// A move to `target` (degrees) from where `cx` has the device (no
/// distance when that is not known), at most `v` a second and `a` a
/// second squared: it ends within a trapezoid's duration (an hour at
/// most).
fn trapezoid(cx: &Context, target: f64, v: f64, a: f64) -> Effect {
    let from = cx.motion.map_or(target, |(p, ..)| p);
    let secs = (target - from).abs() / v + v / a;
    Effect {
        target: Some(Some(target)),
        moving: Moving::Until(
            cx.at
                .saturating_add(Duration::from_secs_f64(secs.min(3600.0))),
        ),
        ..Effect::NONE
    }
}
