//! A WIA Trajectory for an iRPC joint, as the `SetTargetV2` segments that
//! pass each waypoint at its time.

use motorwire_irpc::{MotionProfile, SetTargetPayloadV2};
use motorwire_planner::{minimum_duration, plan, plan_with_duration};
use motorwire_wia::Trajectory;

use crate::gate::Effective;
use crate::path::check_segment;
use crate::report::{LossKind, Report, Translated};
use crate::{BusMap, Refusal, Target};

/// How long before a waypoint's time the next segment is sent (s): the
/// joint replans from where it then is, still on its way to the waypoint
/// at its velocity, so it flies through instead of stopping there.
pub const TRAJECTORY_LEAD_S: f64 = 0.002;

/// How close to its time each waypoint is passed, as the joint's own f32
/// plan has it (s).
pub const WAYPOINT_TOLERANCE_S: f64 = 0.001;

/// The most segments one trajectory line may plan to (waypoints times
/// passes): planning takes the bridge's engine some microseconds per
/// segment, and a stop waits behind it.
pub const MAX_TRAJECTORY_SEGMENTS: usize = 1000;

/// One segment: sent `at` seconds after the trajectory starts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrajectorySegment {
    /// When to send it (s from the start).
    pub at: f64,
    /// What to send.
    pub payload: SetTargetPayloadV2,
    /// When the joint's own plan of it reaches its waypoint (s from the
    /// start).
    pub arrives: f64,
}

/// A trajectory's segments, in order.
#[derive(Debug, Clone, PartialEq)]
pub struct TrajectoryPlan {
    /// The segments (one per waypoint after the first, times the loops).
    pub segments: Vec<TrajectorySegment>,
    /// How long the whole trajectory takes (s); for one that loops
    /// forever, one cycle.
    pub duration: f64,
    /// `loop.count` -1: `segments` are one cycle (one pass, or a pass and
    /// its reverse), repeated every `duration` until stopped. Each cycle
    /// ends at rest where it starts, so it repeats exactly.
    pub forever: bool,
}

/// Plans `traj` for its iRPC joint: every waypoint gated against the bus
/// map's limits (tightened by the trajectory's `constraints`), then, for
/// each segment, the `SetTargetV2` whose time-optimal profile under those
/// limits (its cruise velocity lowered as needed) takes the joint from the
/// previous waypoint (at its velocity) to the next (at its velocity)
/// exactly in the time between them (a waypoint to be reached at rest may
/// be reached early: the joint holds there until the next segment starts
/// at the waypoint's time; one to be passed at speed that the joint would
/// reach early is split in two, said in the report: a stop at rest short
/// of it, then a take-off from there that is the joint's acceleration to
/// the waypoint's velocity, sent so it passes the waypoint at its time).
/// Each is checked by planning it in
/// f32 as the joint does, from the state the joint will be in when it
/// arrives ([`TRAJECTORY_LEAD_S`] before the waypoint's time): the
/// waypoint is passed within [`WAYPOINT_TOLERANCE_S`]. The path of each
/// segment is held to the position limits ([`check_path`](crate::check_path)).
///
/// Waypoint `time` is in seconds from the start (WIRE-FACTS §3); the first
/// waypoint is where the joint must be. `loop` with a `count` repeats it
/// (`reverse_on_loop` runs every other pass backwards); a count of -1
/// (forever) plans one cycle to repeat ([`TrajectoryPlan::forever`]). A
/// first waypoint time other than 0 is refused.
///
/// # Errors
/// [`Refusal::Infeasible`] naming the waypoint and the limit; the gate's
/// refusals; [`Refusal::PathOutsideLimit`].
#[allow(clippy::too_many_lines)]
pub fn trajectory_to_irpc(
    map: &BusMap,
    traj: &Trajectory,
) -> Result<Translated<TrajectoryPlan>, Refusal> {
    let motor = map
        .motor(&traj.motor_id)
        .ok_or_else(|| Refusal::UnknownMotor {
            motor: traj.motor_id.clone(),
        })?;
    let name = motor.name.clone();
    if !matches!(motor.target, Target::Irpc { .. } | Target::Moteus { .. }) {
        return Err(Refusal::ModeNotExpressible {
            motor: name,
            mode: "trajectory",
            dialect: "this motor's dialect (trajectories run on iRPC joints and moteus controllers)",
        });
    }
    // A moteus controller plans each segment itself as a trapezoid within
    // its velocity and acceleration limits: its segments are planned so.
    let moteus = matches!(motor.target, Target::Moteus { .. });
    let infeasible = |waypoint: usize, problem: String| Refusal::Infeasible {
        motor: name.clone(),
        waypoint,
        problem,
    };
    let mut report = Report::default();
    let unit = motor.unit;
    let e = Effective::from_bus_map(motor);
    let tighter = |own: Option<f64>, map: Option<f64>| match (own, map) {
        (Some(a), Some(b)) => Some(a.min(b)),
        (a, b) => a.or(b),
    };
    let c = traj.constraints.as_ref();
    let max_v = tighter(
        c.and_then(|c| c.max_velocity),
        e.max_velocity.map(|b| b.value),
    );
    let max_a = tighter(
        c.and_then(|c| c.max_acceleration),
        e.max_acceleration.map(|b| b.value),
    );
    let max_j = tighter(c.and_then(|c| c.max_jerk), motor.limits.max_jerk);
    let (Some(max_v), Some(max_a)) = (max_v, max_a) else {
        return Err(Refusal::MissingLimit {
            motor: name,
            dialect: "a trajectory",
            field: "max_velocity and max_acceleration",
        });
    };
    // Braking within the deceleration in force too (the acceleration's
    // where the limits give none).
    let max_d = motor
        .limits
        .max_deceleration
        .map_or(max_a, |d| d.min(max_a));
    let w = &traj.waypoints;
    if w.len() < 2 {
        return Err(infeasible(
            0,
            "a trajectory needs at least 2 waypoints".to_owned(),
        ));
    }
    if w.first().is_some_and(|f| f.time != 0.0) {
        return Err(infeasible(
            0,
            "the first waypoint's time must be 0 (seconds from the start)".to_owned(),
        ));
    }
    // Every waypoint within the limits.
    for (i, p) in w.iter().enumerate() {
        if !(p.position.is_finite() && p.time.is_finite() && p.velocity.is_none_or(f64::is_finite))
        {
            return Err(infeasible(i, "a value is not a finite number".to_owned()));
        }
        if let Some(b) = e.min_position.filter(|b| p.position < b.value) {
            return Err(infeasible(
                i,
                format!(
                    "position {} is below min_position ({}) {}",
                    p.position, b.source, b.value
                ),
            ));
        }
        if let Some(b) = e.max_position.filter(|b| p.position > b.value) {
            return Err(infeasible(
                i,
                format!(
                    "position {} is above max_position ({}) {}",
                    p.position, b.source, b.value
                ),
            ));
        }
        if let Some(v) = p.velocity.filter(|v| v.abs() > max_v) {
            return Err(infeasible(
                i,
                format!("velocity {v} is above max_velocity {max_v}"),
            ));
        }
    }
    let passes: usize = match traj
        .loop_config
        .as_ref()
        .filter(|l| l.enabled == Some(true))
    {
        None => 1,
        Some(l) => match l.count {
            None => 1,
            Some(n) if n >= 1 => usize::try_from(n).unwrap_or(usize::MAX).min(1000),
            Some(-1) => {
                let reverse = l.reverse_on_loop == Some(true);
                let (a, b) = (w.first(), w.last());
                if b.is_some_and(|b| b.velocity.unwrap_or(0.0) != 0.0)
                    || (!reverse && a.map(|p| p.position) != b.map(|p| p.position))
                {
                    return Err(infeasible(
                        w.len() - 1,
                        "a loop forever must end at rest, where it starts (or reverse_on_loop)"
                            .to_owned(),
                    ));
                }
                if reverse { 2 } else { 1 }
            }
            Some(n) => {
                return Err(infeasible(
                    0,
                    format!("loop.count {n} is not a number of passes"),
                ));
            }
        },
    };
    if passes.saturating_mul(w.len() - 1) > MAX_TRAJECTORY_SEGMENTS {
        return Err(infeasible(
            w.len() - 1,
            format!(
                "{} waypoints over {passes} passes are more than the {MAX_TRAJECTORY_SEGMENTS} segments one line may plan",
                w.len()
            ),
        ));
    }
    let reverse = traj.loop_config.as_ref().and_then(|l| l.reverse_on_loop) == Some(true);
    if passes > 1 && !reverse && w.first().map(|p| p.position) != w.last().map(|p| p.position) {
        return Err(infeasible(
            w.len() - 1,
            "a loop without reverse_on_loop must end where it starts".to_owned(),
        ));
    }
    // A loop that asks for more than one pass without `"enabled": true`
    // runs once: said, never silent.
    if let Some(l) = traj
        .loop_config
        .as_ref()
        .filter(|l| l.enabled != Some(true))
        && (l.count.is_some_and(|n| n != 1) || l.reverse_on_loop == Some(true))
    {
        report.push(
            "loop",
            LossKind::Dropped,
            if l.enabled == Some(false) {
                "the loop is disabled (\"enabled\": false): the trajectory runs once"
            } else {
                "the loop is not enabled (it takes \"enabled\": true): the trajectory runs once"
            },
        );
    }
    if traj.timing.interpolation.is_some() || traj.kind.is_some() {
        report.push(
            "timing.interpolation",
            LossKind::Converted,
            if moteus {
                "the controller plans a trapezoid between waypoints, through each at its velocity and time"
            } else {
                "the joint plans a jerk-limited S-curve between waypoints, through each at its velocity and time"
            },
        );
    }
    // The waypoints of every pass, in degrees, with absolute times.
    let mut points: Vec<(usize, f64, f64, f64)> = Vec::new(); // (index, time, position, velocity)
    let span = w.last().map_or(0.0, |p| p.time);
    for pass in 0..passes {
        let backwards = reverse && pass % 2 == 1;
        #[allow(clippy::cast_precision_loss)]
        let t0 = span * pass as f64;
        let order: Vec<usize> = if backwards {
            (0..w.len()).rev().collect()
        } else {
            (0..w.len()).collect()
        };
        for (k, &i) in order.iter().enumerate() {
            if pass > 0 && k == 0 {
                continue; // the same point the last pass ended at
            }
            let Some(p) = w.get(i) else { continue };
            let time = if backwards { span - p.time } else { p.time };
            let v = p.velocity.unwrap_or(0.0);
            points.push((
                i,
                t0 + time,
                unit.to_degrees(p.position),
                unit.to_degrees(if backwards { -v } else { v }),
            ));
        }
    }
    let deg = |x: f64| unit.to_degrees(x);
    #[allow(clippy::cast_possible_truncation)]
    let f = |x: f64| x as f32;
    let scurve = !moteus && max_j.is_some() && motor.profile != MotionProfile::Trapezoidal;
    let mut segments = Vec::new();
    // Where the joint is when each segment is sent: the previous
    // segment's own f32 plan, TRAJECTORY_LEAD_S before its waypoint.
    let (mut from_pos, mut from_vel, mut from_t) = match points.first() {
        Some(&(_, t, p, v)) => (p, v, t),
        None => return Err(infeasible(0, "no waypoints".to_owned())),
    };
    // And how its speed changes then: a jerk-limited joint continues from
    // it (zero where the previous segment ends at rest, and after a
    // trapezoidal segment, whose acceleration steps).
    let mut from_acc = 0.0f64;
    // The joint's state `send` s into its own plan of a segment, when the
    // next one is sent.
    let sent_from = |plan: &motorwire_planner::Profile<f32>, send: f64| {
        let s = plan.sample(f(send));
        let a = if scurve {
            f64::from(s.acceleration)
        } else {
            0.0
        };
        (f64::from(s.position), f64::from(s.velocity), a)
    };
    for (k, pair) in points.windows(2).enumerate() {
        let (&(_, _, _, _), &(index, t1, p1, v1)) = match pair {
            [a, b] => (a, b),
            _ => continue,
        };
        let last = k + 2 == points.len();
        let lead = if last { 0.0 } else { TRAJECTORY_LEAD_S };
        let duration = t1 - from_t;
        if duration <= 0.0 {
            return Err(infeasible(index, "waypoint times must increase".to_owned()));
        }
        let base = if scurve {
            SetTargetPayloadV2::scurve(
                f(p1),
                f(deg(max_v)),
                f(deg(max_a)),
                f(deg(max_j.unwrap_or(0.0))),
            )
        } else {
            SetTargetPayloadV2::trapezoidal(f(p1), f(deg(max_v)), f(deg(max_a)))
        }
        .with_deceleration(f(deg(max_d)));
        let mut payload = SetTargetPayloadV2 {
            target_velocity: f(v1),
            ..base
        };
        payload.profile = if scurve {
            MotionProfile::SCurve
        } else {
            MotionProfile::Trapezoidal
        };
        let req = payload
            .planner_request(from_pos, from_vel)
            .with_start_acceleration(from_acc);
        let fastest = minimum_duration(&req).map_err(|e| infeasible(index, e.to_string()))?;
        if fastest > duration + 1e-9 {
            return Err(infeasible(
                index,
                format!(
                    "its segment needs {:.2} s of the {:.2} s it is given under max_velocity {max_v}, max_acceleration {max_a}{}",
                    fastest,
                    duration,
                    max_j.map_or_else(String::new, |j| format!(", max_jerk {j}"))
                ),
            ));
        }
        // The exact-duration plan's cruise (from zero acceleration: the
        // exact-duration planner starts there).
        let at_rest_acc = payload.planner_request(from_pos, from_vel);
        let profile = plan_with_duration(&at_rest_acc, duration)
            .map_err(|e| infeasible(index, e.to_string()))?;
        let cruise = profile.peak_velocity().0.abs();
        if cruise < f64::from(payload.max_velocity) {
            payload.max_velocity = f(cruise).max(f(v1.abs())).max(f(from_vel.abs()));
        }
        // The joint's own plan, in f32, from where it will be.
        let own = |p: &SetTargetPayloadV2| {
            plan(
                &p.planner_request(f(from_pos), f(from_vel))
                    .with_start_acceleration(f(from_acc)),
            )
        };
        if from_acc != 0.0 {
            // From a changing speed that cruise is not exactly what the
            // joint makes of it: where it must pass the waypoint at its
            // time (at speed), or would reach it late, the velocity limit
            // whose plan takes the duration, by bisection (the time falls
            // as the limit rises). A waypoint reached at rest early is
            // held, as from a steady speed.
            let takes = own(&payload).map(|p| f64::from(p.duration()));
            let late = takes.is_ok_and(|t| t > duration + WAYPOINT_TOLERANCE_S / 2.0);
            if v1 != 0.0 || late {
                payload.max_velocity =
                    limit_for_duration(&payload, duration, base.max_velocity, &own);
            }
        }
        let joint = own(&payload)
            .map_err(|e| infeasible(index, format!("the joint's own plan fails: {e}")))?;
        let arrives = from_t + f64::from(joint.duration());
        // A waypoint to reach at rest may be reached early: the joint holds
        // there until its time, when the next segment starts from rest.
        let early_at_rest = v1 == 0.0 && arrives < t1;
        // One to pass at speed that the joint would reach early (no
        // SetTargetV2 takes longer than its time-optimal profile): split
        // in two, a stop where the joint takes off from rest to pass the
        // waypoint at its speed, and that take-off, sent so it passes the
        // waypoint at its time.
        if v1 != 0.0 && arrives < t1 - WAYPOINT_TOLERANCE_S {
            // (The stop at the fastest the limits allow.)
            let fastest = SetTargetPayloadV2 {
                max_velocity: base.max_velocity,
                ..payload
            };
            let split = split_at_speed(
                &fastest,
                (from_pos, from_vel, from_acc, from_t),
                (p1, v1, t1),
                scurve,
            )
            .map_err(|problem| infeasible(index, problem))?;
            for (sub, from) in [
                (&split.stop, (from_pos, from_vel, from_acc)),
                (&split.takeoff, (split.stop_at, 0.0, 0.0)),
            ] {
                check_segment(motor, &e, &sub.payload, from, None)
                    .map_err(|r| infeasible(index, r.to_string()))?;
            }
            report.push(
                format!("waypoints[{index}]"),
                LossKind::Converted,
                format!(
                    "the joint would pass it early at {arrives:.4} s: it stops at {} and takes off at {:.4} s to pass it at {t1:.4} s at its velocity",
                    split.stop_at, split.takeoff.at
                ),
            );
            segments.push(split.stop);
            segments.push(split.takeoff);
            let send = (split.takeoff_duration - lead).max(0.0);
            (from_pos, from_vel, from_acc) = sent_from(&split.takeoff_plan, send);
            from_t = split.takeoff.at + send;
            continue;
        }
        if (arrives - t1).abs() > WAYPOINT_TOLERANCE_S && !early_at_rest {
            return Err(infeasible(
                index,
                format!("the joint would pass it at {arrives:.4} s, not {t1:.4} s"),
            ));
        }
        check_segment(motor, &e, &payload, (from_pos, from_vel, from_acc), None)
            .map_err(|r| infeasible(index, r.to_string()))?;
        segments.push(TrajectorySegment {
            at: from_t,
            payload,
            arrives,
        });
        if early_at_rest || v1 == 0.0 {
            // At rest on the waypoint at its time.
            from_pos = p1;
            from_vel = 0.0;
            from_acc = 0.0;
            from_t = t1;
        } else {
            // The next segment is sent `lead` before this one's end.
            let send = (f64::from(joint.duration()) - lead).max(0.0);
            (from_pos, from_vel, from_acc) = sent_from(&joint, send);
            from_t += send;
        }
    }
    let duration = points.last().map_or(0.0, |p| p.1);
    if segments.len() > MAX_TRAJECTORY_SEGMENTS {
        return Err(infeasible(
            w.len() - 1,
            format!(
                "split where the joint would be early, it plans {} segments, more than the {MAX_TRAJECTORY_SEGMENTS} one line may plan",
                segments.len()
            ),
        ));
    }
    let forever = traj
        .loop_config
        .as_ref()
        .is_some_and(|l| l.enabled == Some(true) && l.count == Some(-1));
    Ok(Translated {
        value: TrajectoryPlan {
            segments,
            duration,
            forever,
        },
        report,
    })
}

/// The velocity limit, at most `highest`, with which the joint's own plan
/// of `payload` (`own`) takes `duration`: a bisection, the time falling as
/// the limit rises (a limit whose plan fails counts as too slow); never
/// below the payload's target velocity. The caller checks the arrival it
/// gives.
pub(crate) fn limit_for_duration(
    payload: &SetTargetPayloadV2,
    duration: f64,
    highest: f32,
    own: &dyn Fn(
        &SetTargetPayloadV2,
    ) -> Result<motorwire_planner::Profile<f32>, motorwire_planner::PlanError>,
) -> f32 {
    let time = |v: f32| {
        own(&SetTargetPayloadV2 {
            max_velocity: v,
            ..*payload
        })
        .map(|p| f64::from(p.duration()))
    };
    let (mut lo, mut hi) = (payload.target_velocity.abs(), highest);
    for _ in 0..60 {
        let mid = lo + (hi - lo) / 2.0;
        if mid <= lo || mid >= hi {
            break;
        }
        match time(mid) {
            Ok(t) if t > duration => lo = mid,
            Ok(_) => hi = mid,
            Err(_) => lo = mid,
        }
    }
    hi
}

/// A segment to a waypoint at speed split where the joint would be early:
/// a stop (at rest at `stop_at`, reached early, held), then a take-off
/// from there that is the joint's acceleration from rest to the
/// waypoint's velocity, sent so it ends at the waypoint's time.
struct SplitAtSpeed {
    stop: TrajectorySegment,
    stop_at: f64,
    takeoff: TrajectorySegment,
    takeoff_duration: f64,
    takeoff_plan: motorwire_planner::Profile<f32>,
}

/// Splits `payload` (to `to`: position, velocity, time, degrees) from
/// `from` (position, velocity, acceleration, time): the take-off starts from rest the
/// distance before the waypoint that accelerating to its velocity takes
/// (jerk-limited when `scurve`), its `max_velocity` that velocity, so its
/// time-optimal profile is that acceleration alone; the stop must be
/// reached before the take-off is due. Each is planned in f32 as the
/// joint plans it.
fn split_at_speed(
    payload: &SetTargetPayloadV2,
    from: (f64, f64, f64, f64),
    to: (f64, f64, f64),
    scurve: bool,
) -> Result<SplitAtSpeed, String> {
    #[allow(clippy::cast_possible_truncation)]
    let f = |x: f64| x as f32;
    let (p1, v1, t1) = to;
    let speed = v1.abs();
    let a = f64::from(payload.max_acceleration);
    let j = f64::from(payload.max_jerk);
    // The distance from rest to `speed` at the limits.
    let ramp = if scurve && j > 0.0 {
        if speed >= a * a / j {
            speed / 2.0 * (speed / a + a / j)
        } else {
            speed * (speed / j).sqrt()
        }
    } else {
        speed * speed / (2.0 * a)
    };
    let stop_at = f(p1 - v1.signum() * ramp);
    let takeoff_payload = SetTargetPayloadV2 {
        max_velocity: f(speed),
        ..*payload
    };
    let takeoff_plan = plan(&takeoff_payload.planner_request(stop_at, 0.0))
        .map_err(|e| format!("the take-off's own plan fails: {e}"))?;
    let takeoff_duration = f64::from(takeoff_plan.duration());
    let takeoff_at = t1 - takeoff_duration;
    let stop_payload = SetTargetPayloadV2 {
        target_angle: stop_at,
        target_velocity: 0.0,
        ..*payload
    };
    let stop_plan = plan(
        &stop_payload
            .planner_request(f(from.0), f(from.1))
            .with_start_acceleration(f(from.2)),
    )
    .map_err(|e| format!("the stop's own plan fails: {e}"))?;
    let stopped = from.3 + f64::from(stop_plan.duration());
    if stopped > takeoff_at + WAYPOINT_TOLERANCE_S {
        return Err(format!(
            "the joint would pass it early without a stop, and with one (at {stop_at}, to take off at {takeoff_at:.4} s) it would stand there only at {stopped:.4} s"
        ));
    }
    Ok(SplitAtSpeed {
        stop: TrajectorySegment {
            at: from.3,
            payload: stop_payload,
            arrives: stopped,
        },
        stop_at: f64::from(stop_at),
        takeoff: TrajectorySegment {
            at: takeoff_at,
            payload: takeoff_payload,
            arrives: t1,
        },
        takeoff_duration,
        takeoff_plan,
    })
}
