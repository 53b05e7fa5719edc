//! The moves the bridge plans, in the engine's terms. motorwire-translate's gate holds a command to the limits in force and plans its move (a jerk-limited or trapezoidal profile to a target), in the terms of the devices the bridge plans for (an iRPC joint's `SetTargetV2`); here each is a [`Move`], and what a device takes for it an [`Order`], so the engine plans, keeps and checks moves without naming a dialect.

use std::time::Duration;

use motorwire_irpc::{Payload, SetTargetPayloadV2};
use motorwire_planner::{Profile, Request};
use motorwire_translate::{
    BusMap, Effective, JointState, MappedMotor, Refusal, Report, Translated,
};
use motorwire_wia::{MotorCommand, MultiAxisCommand, Trajectory};

use super::{Kinematics, Order, in_unit};

/// One planned move to a position (degrees), with the limits it is
/// planned within: what the gate planned, and what the device plans again
/// from where it is when it takes it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Move(SetTargetPayloadV2);

impl Move {
    /// The planner's request for it from `position` (degrees) at
    /// `velocity` (degrees a second), as the device plans it.
    pub(crate) fn planner_request(&self, position: f64, velocity: f64) -> Request<f64> {
        self.0.planner_request(position, velocity)
    }

    /// Its terms on the wire (for the device layer's translations).
    pub(super) const fn terms(self) -> SetTargetPayloadV2 {
        self.0
    }
}

impl From<SetTargetPayloadV2> for Move {
    fn from(p: SetTargetPayloadV2) -> Self {
        Self(p)
    }
}

/// A joint's move as the bridge planned it: where it started, the move,
/// how long it takes, and its profile (boxed where it is made: a profile
/// is some 300 bytes, and a plan is moved several times on its way to the
/// joint).
pub(crate) type Plan = ((Kinematics, Move, Duration), Box<Profile<f64>>);

/// A motor command gated against the limits in force and planned, for a
/// device whose moves the bridge plans: the orders it sends, what the
/// translation lost, and the motor and limits its path is held to.
#[derive(Debug)]
pub(crate) struct Gated<'m> {
    /// The device's orders, in order (kept in the gate's terms until they
    /// are taken: no list is made twice).
    payloads: Vec<Payload>,
    /// What the translation could not carry, or defaulted.
    pub(crate) report: Report,
    motor: &'m MappedMotor,
    limits: Effective,
}

/// `cmd` gated against `map`'s limits in force and planned.
///
/// # Errors
/// The gate's refusal.
#[inline]
pub(crate) fn gate<'m>(map: &'m BusMap, cmd: &MotorCommand) -> Result<Gated<'m>, Refusal> {
    let (t, motor, limits) = motorwire_translate::to_irpc_gated(map, cmd)?;
    Ok(Gated {
        payloads: t.value.payloads,
        report: t.report,
        motor,
        limits,
    })
}

impl Gated<'_> {
    /// Its orders and its report, the motor let go.
    #[inline]
    pub(crate) fn into_parts(self) -> (impl Iterator<Item = Order> + use<>, Report) {
        (self.payloads.into_iter().map(Order::Irpc), self.report)
    }

    /// Its first order's move, if that is one.
    #[inline]
    pub(crate) fn first_move(&self) -> Option<Move> {
        match self.payloads.first() {
            Some(Payload::SetTargetV2(p)) => Some(Move(*p)),
            _ => None,
        }
    }

    /// Its move's whole path from `from` (the joint's kinematics now,
    /// degrees), as the joint will plan it, held to the limits the command
    /// was gated against (a joint moving fast toward a limit overshoots a
    /// target inside it): the plan, which the bridge keeps. Nothing to
    /// plan from (no report yet): `None`, and the joint's own check
    /// stands.
    ///
    /// # Errors
    /// The path's refusal.
    pub(crate) fn plan_from(&self, from: Option<Kinematics>) -> Result<Option<Plan>, Refusal> {
        let Some(from) = from else {
            return Ok(None);
        };
        let mut planned = None;
        let moves = self.payloads.iter().filter_map(|p| match p {
            Payload::SetTargetV2(p) => Some(Move(*p)),
            _ => None,
        });
        for m in moves {
            let start = in_unit(self.motor.unit, from);
            let path = motorwire_translate::check_path_from(self.motor, &self.limits, &m.0, start)?;
            planned = Duration::try_from_secs_f64(path.duration)
                .ok()
                .map(|d| ((from, m, d), Box::new(path.profile)));
        }
        Ok(planned)
    }
}

/// The axes of multi-axis command `cmd` whose moves the bridge plans,
/// planned together (synchronized as the command asks), each from where
/// `state` says its joint is: one list of orders per axis, in the
/// command's order.
///
/// # Errors
/// The gate's refusal.
pub(crate) fn together(
    map: &BusMap,
    cmd: &MultiAxisCommand,
    state: &dyn Fn(&str) -> Option<JointState>,
) -> Result<Translated<Vec<Vec<Order>>>, Refusal> {
    let t = motorwire_translate::multi_axis_to_irpc_from(map, cmd, state)?;
    Ok(Translated {
        value: t
            .value
            .commands
            .into_iter()
            .map(|c| c.payloads.into_iter().map(Order::Irpc).collect())
            .collect(),
        report: t.report,
    })
}

/// A trajectory planned whole: each segment's move and when it is sent.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct TrajectoryPlan {
    /// Each segment: when to send it (seconds from the start), and its move.
    pub(crate) segments: Vec<(f64, Move)>,
    /// How long the whole trajectory takes (seconds).
    pub(crate) duration: f64,
    /// Whether it loops forever.
    pub(crate) forever: bool,
}

/// Trajectory `t` planned and checked whole against `map`'s limits.
///
/// # Errors
/// The gate's refusal.
pub(crate) fn trajectory(
    map: &BusMap,
    t: &Trajectory,
) -> Result<Translated<TrajectoryPlan>, Refusal> {
    let plan = motorwire_translate::trajectory_to_irpc(map, t)?;
    Ok(Translated {
        value: TrajectoryPlan {
            segments: plan
                .value
                .segments
                .iter()
                .map(|s| (s.at, Move(s.payload)))
                .collect(),
            duration: plan.value.duration,
            forever: plan.value.forever,
        },
        report: plan.report,
    })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    const MAP: &str = "[motors.elbow]\ndialect = \"irpc\"\nnode = 0x12\n\
                       limits = { min_position = -90, max_position = 150, max_velocity = 120, max_acceleration = 500 }\n";

    fn command(setpoint: f64) -> MotorCommand {
        MotorCommand::new(
            "elbow",
            0.0,
            motorwire_core::ControlMode::Position,
            setpoint,
        )
    }

    /// A command's move is the gate's, as a device order and as the
    /// engine's `Move`: its target, and a plan from a known state that
    /// takes as long as the planner says; none from an unknown one.
    #[test]
    fn a_gated_command_is_one_move_and_its_plan() {
        let map = BusMap::from_toml(MAP).unwrap();
        let g = gate(&map, &command(60.0)).unwrap();
        let m = g.first_move().unwrap();
        assert_eq!(m.terms().target_angle, 60.0);
        assert_eq!(g.plan_from(None).unwrap(), None);
        let ((from, planned, d), profile) = g.plan_from(Some((0.0, 0.0, 0.0))).unwrap().unwrap();
        assert_eq!((from, planned), ((0.0, 0.0, 0.0), m));
        let expected = motorwire_planner::plan(&m.planner_request(0.0, 0.0)).unwrap();
        assert_eq!(profile.duration(), expected.duration());
        assert_eq!(d, Duration::from_secs_f64(expected.duration()));
        let orders: Vec<Order> = g.into_parts().0.collect();
        assert_eq!(orders, [Order::Irpc(Payload::SetTargetV2(m.terms()))]);
    }

    /// Outside the limits in force, the gate refuses; a path from a state
    /// that cannot stop inside them is refused when planned from it.
    #[test]
    fn the_gate_and_the_path_refuse() {
        let map = BusMap::from_toml(MAP).unwrap();
        assert!(matches!(
            gate(&map, &command(200.0)),
            Err(Refusal::OutsideLimit { .. })
        ));
        let g = gate(&map, &command(149.0)).unwrap();
        // At 140° moving out at 120°/s: it passes 150° before it stops.
        assert!(g.plan_from(Some((140.0, 120.0, 0.0))).is_err());
    }
}
