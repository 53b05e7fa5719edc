//! Synchronized multi-axis moves on iRPC joints.

use motorwire_core::ControlMode;
use motorwire_irpc::{Payload, SetTargetPayloadV2};
use motorwire_planner::{Request, minimum_duration, plan, plan_with_duration};
use motorwire_wia::{MultiAxisCommand, SyncMode};

use crate::command::to_irpc;
use crate::gate::gate;
use crate::path::check_path;
use crate::report::{LossKind, Report, Translated};
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
    let total = cmd.coordination.as_ref().and_then(|c| c.total_duration_ms);
    let synchronized = cmd.sync_mode == Some(SyncMode::Simultaneous) || total.is_some();
    let mut report = Report::default();
    if !synchronized {
        let mut commands = Vec::new();
        for axis in &cmd.motors {
            let t = to_irpc(map, &axis.to_motor_command(cmd.timestamp))?;
            for mut loss in t.report.losses {
                loss.field = format!("{}.{}", axis.motor_id, loss.field);
                report.losses.push(loss);
            }
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
        let start = position(&motor.name).ok_or_else(|| Refusal::UnknownPosition {
            motor: motor.name.clone(),
        })?;
        if !start.is_finite() {
            return Err(Refusal::UnknownPosition {
                motor: motor.name.clone(),
            });
        }
        for mut loss in t.report.losses {
            loss.field = format!("{}.{}", motor.name, loss.field);
            report.losses.push(loss);
        }
        let start_deg = motor.unit.to_degrees(start);
        axes.push((
            t.value,
            p,
            joint_request(f64::from(start_deg as f32), &p),
            (motor, limits, start),
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
        if req.start == req.target {
            report.push(
                format!("{name}.max_velocity"),
                LossKind::Converted,
                "already at its target: no move to synchronize",
            );
        } else {
            let profile =
                plan_with_duration(&req, duration).map_err(|e| Refusal::Unsynchronizable {
                    problem: format!("{name}: {e}"),
                })?;
            #[allow(clippy::cast_possible_truncation)]
            let cruise = profile.peak_velocity().0 as f32;
            if cruise < p.max_velocity {
                report.push(
                    format!("{name}.max_velocity"),
                    LossKind::Converted,
                    format!(
                        "{} lowered to {cruise} so every joint arrives after {duration:.4} s",
                        p.max_velocity
                    ),
                );
                p.max_velocity = cruise;
            }
            // The check: the joint's own plan, in f32, from the same start.
            #[allow(clippy::cast_possible_truncation)]
            let joint = plan(&joint_request_f32(req.start as f32, &p)).map_err(|e| {
                Refusal::Unsynchronizable {
                    problem: format!("{name}: the joint's own plan fails: {e}"),
                }
            })?;
            let arrival = f64::from(joint.duration());
            if (arrival - duration).abs() > SYNC_TOLERANCE_S {
                return Err(Refusal::Unsynchronizable {
                    problem: format!("{name} would arrive after {arrival} s, not {duration} s"),
                });
            }
        }
        check_path(motor, &limits, &p, start, 0.0)?;
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

/// The planner's request for the move a joint makes on `p` from rest at
/// `start` (degrees), in f64: the joint's own reading of a `SetTargetV2`.
fn joint_request(start: f64, p: &SetTargetPayloadV2) -> Request<f64> {
    p.planner_request(start, 0.0)
}

/// The same request as the joint sees it, in f32.
fn joint_request_f32(start: f32, p: &SetTargetPayloadV2) -> Request<f32> {
    p.planner_request(start, 0.0)
}
