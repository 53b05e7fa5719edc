//! Synchronized multi-axis moves on iRPC joints.

use motorwire_core::ControlMode;
use motorwire_irpc::{Payload, SetTargetPayloadV2};
use motorwire_planner::{minimum_duration, plan, plan_with_duration};
use motorwire_wia::{MultiAxisCommand, SyncMode};

use crate::command::to_irpc;
use crate::gate::gate;
use crate::path::{JointState, check_path_from};
use crate::report::{LossKind, Report, Translated};
use crate::trajectory::limit_for_duration;
use crate::{BusMap, IrpcCommand, Refusal, Target};

/// The most two synchronized joints' planned arrivals may differ by (s).
pub const SYNC_TOLERANCE_S: f64 = 0.001;

/// A multi-axis command for iRPC joints.
#[derive(Debug, Clone, PartialEq)]
pub struct MultiAxisMove {
    /// One command per axis, in the command's order.
    pub commands: Vec<IrpcCommand>,
    /// For a synchronized move, when every joint arrives (s after the
    /// start), as the joints will plan it; `None` for independent axes.
    pub duration: Option<f64>,
}

/// Translates a WIA multi-axis command for iRPC joints.
///
/// Independent (no `sync_mode: simultaneous` and no
/// `coordination.total_duration_ms`): each axis as [`to_irpc`] translates
/// it. Synchronized: every axis must be a `position` move; each joint's move
/// from `position(motor_id)` (its current position, in the motor's unit) is
/// planned with the joint's limits, and the common duration is the longest
/// minimum (or `total_duration_ms`). Each joint then gets a `SetTargetV2`
/// whose `max_velocity` is the cruise velocity that makes its time-optimal
/// profile take exactly that long (the move the exact-duration planner
/// finds, with the same acceleration and jerk limits). The result is
/// checked by planning each joint's `SetTargetV2` in f32, as the joint
/// does: every arrival agrees within [`SYNC_TOLERANCE_S`]. Each joint's
/// final `SetTargetV2` is also planned from its current position at rest
/// (as the synchronization plans it) and its whole path held to the
/// joint's position limits ([`check_path`](crate::check_path)).
///
/// # Errors
/// Any axis's refusal (naming it); [`Refusal::UnknownPosition`] for a joint
/// whose position is unknown; [`Refusal::Unsynchronizable`] when the
/// requested duration is shorter than a joint's fastest move, or the check
/// fails; [`Refusal::PathOutsideLimit`] for a path that leaves a joint's
/// position limits.
pub fn multi_axis_to_irpc(
    map: &BusMap,
    cmd: &MultiAxisCommand,
    position: &dyn Fn(&str) -> Option<f64>,
) -> Result<Translated<MultiAxisMove>, Refusal> {
    multi_axis_to_irpc_from(map, cmd, &|m| position(m).map(|p| (p, 0.0, 0.0)))
}

/// [`multi_axis_to_irpc`] from each joint's current state, moving or not:
/// `state(motor_id)` is its position and velocity now (in the motor's
/// unit, a second) and its acceleration (a second squared). A joint
/// already moving (on a trajectory, a stream, a move the line replaces) is
/// planned as the joint plans a new `SetTargetV2`: from that position,
/// velocity and acceleration (an S-curve continues from it; see
/// [`Request::start_acceleration`](motorwire_planner::Request::start_acceleration)). Its
/// `max_velocity` is the one, at most the command's, whose time-optimal
/// profile from that state takes the common duration; found from the
/// exact-duration plan's cruise, and where the joint's own plan from a
/// moving start does not take that duration (or its speed is changing),
/// by bisection on it.
///
/// ```
/// use motorwire_translate::{BusMap, multi_axis_to_irpc_from, SYNC_TOLERANCE_S};
/// use motorwire_irpc::Payload;
/// use motorwire_wia::MultiAxisCommand;
///
/// let map = BusMap::from_toml(r#"
///     [motors.a]
///     dialect = "irpc"
///     node = 0x10
///     limits = { min_position = -180, max_position = 180, max_velocity = 120, max_acceleration = 500, max_jerk = 2000 }
///     [motors.b]
///     dialect = "irpc"
///     node = 0x11
///     limits = { min_position = -180, max_position = 180, max_velocity = 120, max_acceleration = 500, max_jerk = 2000 }
/// "#)?;
/// let cmd: MultiAxisCommand = serde_json::from_str(r#"{"command_id":"c","timestamp":1,"sync_mode":"simultaneous",
///     "motors":[{"motor_id":"a","control_mode":"position","setpoint":90},{"motor_id":"b","control_mode":"position","setpoint":30}]}"#)?;
/// // `a` stands at 0; `b` passes 10 at 40 units a second, speeding up at 200.
/// let t = multi_axis_to_irpc_from(&map, &cmd, &|m| Some(if m == "a" { (0.0, 0.0, 0.0) } else { (10.0, 40.0, 200.0) }))?;
/// let duration = t.value.duration.unwrap();
/// for (c, start) in t.value.commands.iter().zip([(0.0f32, 0.0f32, 0.0f32), (10.0, 40.0, 200.0)]) {
///     let Payload::SetTargetV2(p) = c.payloads[0] else { unreachable!() };
///     // Each joint's own plan, in f32, from its state: the same arrival.
///     let req = p.planner_request(start.0, start.1).with_start_acceleration(start.2);
///     let plan = motorwire_planner::plan(&req)?;
///     assert!((f64::from(plan.duration()) - duration).abs() <= SYNC_TOLERANCE_S);
/// }
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
/// As [`multi_axis_to_irpc`]'s.
pub fn multi_axis_to_irpc_from(
    map: &BusMap,
    cmd: &MultiAxisCommand,
    state: &dyn Fn(&str) -> Option<JointState>,
) -> Result<Translated<MultiAxisMove>, Refusal> {
    let total = cmd.coordination.as_ref().and_then(|c| c.total_duration_ms);
    let synchronized = cmd.sync_mode == Some(SyncMode::Simultaneous) || total.is_some();
    let mut report = Report::default();
    if !synchronized {
        let mut commands = Vec::new();
        for axis in &cmd.motors {
            let t = to_irpc(map, &axis.to_motor_command(cmd.timestamp))?;
            report
                .losses
                .extend(t.report.losses.into_iter().map(|l| l.under(&axis.motor_id)));
            commands.push(t.value);
        }
        return Ok(Translated {
            value: MultiAxisMove {
                commands,
                duration: None,
            },
            report,
        });
    }
    // Each axis: its translation (gated, limits resolved) and the planner's
    // request for the move the joint will make.
    let mut axes = Vec::new();
    for axis in &cmd.motors {
        let single = axis.to_motor_command(cmd.timestamp);
        if single.control_mode != ControlMode::Position {
            return Err(Refusal::ModeNotExpressible {
                motor: axis.motor_id.clone(),
                mode: single.control_mode.name(),
                dialect: "a synchronized iRPC move (position only)",
            });
        }
        let (motor, limits) = gate(map, &single)?;
        if !matches!(motor.target, Target::Irpc { .. }) {
            return Err(Refusal::ModeNotExpressible {
                motor: motor.name.clone(),
                mode: single.control_mode.name(),
                dialect: "a synchronized iRPC move (the bus map says this motor is not an iRPC joint)",
            });
        }
        let t = to_irpc(map, &single)?;
        let Some(Payload::SetTargetV2(p)) = t.value.payloads.first().copied() else {
            return Err(Refusal::ModeNotExpressible {
                motor: motor.name.clone(),
                mode: single.control_mode.name(),
                dialect: "a synchronized move on iRPC v1 (SetTarget has no acceleration limit to plan with)",
            });
        };
        let (start, start_velocity, start_acceleration) =
            state(&motor.name).ok_or_else(|| Refusal::UnknownPosition {
                motor: motor.name.clone(),
            })?;
        if !start.is_finite() || !start_velocity.is_finite() || !start_acceleration.is_finite() {
            return Err(Refusal::UnknownPosition {
                motor: motor.name.clone(),
            });
        }
        report
            .losses
            .extend(t.report.losses.into_iter().map(|l| l.under(&motor.name)));
        // As the joint reads them: f32 degrees.
        let start_deg = f64::from(motor.unit.to_degrees(start) as f32);
        let velocity_deg = f64::from(motor.unit.to_degrees(start_velocity) as f32);
        let acceleration_deg = f64::from(motor.unit.to_degrees(start_acceleration) as f32);
        axes.push((
            t.value,
            p,
            p.planner_request(start_deg, velocity_deg)
                .with_start_acceleration(acceleration_deg),
            (motor, limits, (start, start_velocity, start_acceleration)),
        ));
    }
    let mut slowest: (f64, &str) = (0.0, "");
    for ((_, _, req, _), axis) in axes.iter().zip(&cmd.motors) {
        let min = minimum_duration(req).map_err(|e| Refusal::Unsynchronizable {
            problem: format!("{}: {e}", axis.motor_id),
        })?;
        if min > slowest.0 {
            slowest = (min, axis.motor_id.as_str());
        }
    }
    let duration = match total {
        Some(ms) => {
            let t = ms / 1000.0;
            if t < slowest.0 {
                return Err(Refusal::Unsynchronizable {
                    problem: format!(
                        "coordination.total_duration_ms {ms} is shorter than {} needs: {:.1} ms",
                        slowest.1,
                        slowest.0 * 1000.0
                    ),
                });
            }
            t
        }
        None => slowest.0,
    };
    let mut commands = Vec::new();
    for ((mut command, mut p, req, (motor, limits, start)), axis) in
        axes.into_iter().zip(&cmd.motors)
    {
        let name = axis.motor_id.as_str();
        if req.start == req.target && req.start_velocity == 0.0 && req.start_acceleration == 0.0 {
            report.push(
                format!("{name}.max_velocity"),
                LossKind::Converted,
                "already at its target: no move to synchronize",
            );
        } else {
            // The exact-duration plan's cruise, where there is one: from
            // a joint whose speed is changing, the bisection below finds
            // the velocity limit.
            #[allow(clippy::cast_possible_truncation)]
            let cruise = if req.start_acceleration == 0.0 {
                let profile =
                    plan_with_duration(&req, duration).map_err(|e| Refusal::Unsynchronizable {
                        problem: format!("{name}: {e}"),
                    })?;
                (profile.peak_velocity().0.abs() as f32).min(p.max_velocity)
            } else {
                p.max_velocity
            };
            // The joint's own plan, in f32, from the same state.
            #[allow(clippy::cast_possible_truncation)]
            let own = |q: &SetTargetPayloadV2| {
                plan(
                    &q.planner_request(req.start as f32, req.start_velocity as f32)
                        .with_start_acceleration(req.start_acceleration as f32),
                )
            };
            // How long it takes with `max_velocity` v.
            let joint_time = |v: f32| {
                own(&SetTargetPayloadV2 {
                    max_velocity: v,
                    ..p
                })
                .map(|j| f64::from(j.duration()))
                .map_err(|e| Refusal::Unsynchronizable {
                    problem: format!("{name}: the joint's own plan fails: {e}"),
                })
            };
            let mut v = cruise;
            if cruise > 0.0 && (joint_time(cruise)? - duration).abs() > SYNC_TOLERANCE_S / 2.0 {
                // From a moving start the exact-duration plan's cruise is
                // not always what the joint makes of it: the velocity
                // limit whose time-optimal profile takes the duration.
                v = limit_for_duration(&p, duration, p.max_velocity, &own);
            }
            if v < p.max_velocity {
                report.push(
                    format!("{name}.max_velocity"),
                    LossKind::Converted,
                    format!(
                        "{} lowered to {v} so every joint arrives after {duration:.4} s",
                        p.max_velocity
                    ),
                );
                p.max_velocity = v;
            }
            // The check: the joint's own plan, in f32, from the same state,
            // and in f64 (a joint, as motorwire's simulated one, may plan
            // in either; with a velocity limit near zero the two can differ
            // by more than the tolerance).
            let arrival = joint_time(p.max_velocity)?;
            let arrival_f64 = plan(
                &p.planner_request(req.start, req.start_velocity)
                    .with_start_acceleration(req.start_acceleration),
            )
            .map(|j| j.duration())
            .map_err(|e| Refusal::Unsynchronizable {
                problem: format!("{name}: the joint's own plan fails: {e}"),
            })?;
            for arrival in [arrival, arrival_f64] {
                if (arrival - duration).abs() > SYNC_TOLERANCE_S {
                    return Err(Refusal::Unsynchronizable {
                        problem: format!("{name} would arrive after {arrival} s, not {duration} s"),
                    });
                }
            }
        }
        check_path_from(motor, &limits, &p, start)?;
        command.payloads = vec![Payload::SetTargetV2(p)];
        commands.push(command);
    }
    let coordination = cmd.coordination.as_ref();
    for (field, present) in [
        (
            "coordination.type",
            coordination.is_some_and(|c| c.kind.is_some()),
        ),
        (
            "coordination.acceleration_profile",
            coordination.is_some_and(|c| c.acceleration_profile.is_some()),
        ),
    ] {
        if present {
            report.push(
                field,
                LossKind::Dropped,
                "each joint plans its own profile; only the arrival time is shared",
            );
        }
    }
    Ok(Translated {
        value: MultiAxisMove {
            commands,
            duration: Some(duration),
        },
        report,
    })
}
