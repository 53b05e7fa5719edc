//! Position limits along a move's whole planned path, not only at its
//! target.

use motorwire_irpc::SetTargetPayloadV2;
use motorwire_planner::{Profile, plan};

use crate::gate::{Bound, Effective};
use crate::{MappedMotor, Refusal};

/// Where a joint is and how it moves: its position, velocity and
/// acceleration, in the motor's unit (the bus map's `unit`), a second, a
/// second squared.
pub type JointState = (f64, f64, f64);

/// A move's planned path, as [`check_path`] found it within the limits.
/// Positions are in the motor's unit (the bus map's `unit`), velocities in
/// that unit per second, times in seconds after the move starts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PathExtent {
    /// The lowest position along the path (the start and the end count).
    pub lowest: f64,
    /// When the path is lowest (s).
    pub lowest_at: f64,
    /// The highest position along the path.
    pub highest: f64,
    /// When the path is highest (s).
    pub highest_at: f64,
    /// How long the move takes (s).
    pub duration: f64,
    /// Where the move ends: the payload's `target_angle`, in the motor's
    /// unit.
    pub end_position: f64,
    /// How fast it ends: the payload's `target_velocity`, in the motor's
    /// unit per second.
    pub end_velocity: f64,
    /// The joint's plan itself, in degrees (iRPC's unit): what
    /// [`motorwire_planner::plan`] makes of
    /// [`SetTargetPayloadV2::planner_request`] from the start state.
    pub profile: Profile<f64>,
}

/// Plans `payload` as the joint will, from its current state, and refuses
/// the move if the planned path passes `limits`' `min_position` or
/// `max_position` anywhere on the way, not only at the target.
///
/// `start_position` (in the motor's unit, as the bus map's limits are) and
/// `start_velocity` (the motor's unit per second) are the joint's current
/// state, from its feedback. They are converted to degrees, and the move is
/// planned in f64 from [`SetTargetPayloadV2::planner_request`], the same
/// reading of the payload (trapezoidal or S-curve, deceleration and jerk
/// defaults, target velocity, overshoot allowed) that the simulated joint
/// and the bridge use, so the path checked is the path the joint takes.
/// The path's exact lowest and highest positions
/// ([`Profile::position_extrema`]) are converted back to the motor's unit
/// and compared with the limits.
///
/// A path that reaches a limit exactly passes. So does one that passes it
/// by no more than one f32 step of the limit: `f32::EPSILON × max(|limit|,
/// 1°)`, computed in degrees (1.8e-5° at 150°). The margin is needed
/// because a `SetTargetV2` carries its target as an f32, so a target at a
/// limit that is not itself an f32 (2.6 rad is 148.969...°) is rounded up
/// to half an f32 step past it, and the planner's phase ends land within
/// f64 rounding of the target; without it a move to exactly the limit
/// would be refused. It is far below any encoder's resolution.
///
/// A joint that starts past a limit (pushed there, or held to a limit the
/// command tightened) may be brought back: its path is refused only if it
/// goes farther past the limit than where it starts.
///
/// Only positions are checked here: velocity, acceleration and jerk are
/// [`gate`](crate::gate())'s and [`to_irpc`](crate::to_irpc)'s business.
///
/// ```
/// use motorwire_irpc::Payload;
/// use motorwire_translate::{BusMap, Refusal, check_path, gate, to_irpc};
///
/// let map = BusMap::from_toml(r#"
///     [motors.elbow]
///     dialect = "irpc"
///     node = 0x12
///     limits = { min_position = 0, max_position = 150, max_velocity = 120, max_acceleration = 500, max_jerk = 2000 }
/// "#)?;
/// let cmd: motorwire_wia::MotorCommand = serde_json::from_str(r#"{
///     "motor_id": "elbow", "timestamp": 0, "control_mode": "position", "setpoint": 145
/// }"#)?;
/// let (motor, limits) = gate(&map, &cmd)?; // the target is within the limits
/// let Payload::SetTargetV2(move_to_145) = to_irpc(&map, &cmd)?.value.payloads[0] else { unreachable!() };
///
/// // From rest at 130°, the S-curve stays within [0, 150].
/// let path = check_path(motor, &limits, &move_to_145, 130.0, 0.0)?;
/// assert_eq!((path.lowest, path.highest), (130.0, 145.0));
///
/// // At 100°/s towards the limit, it cannot brake in time.
/// let err = check_path(motor, &limits, &move_to_145, 130.0, 100.0).unwrap_err();
/// assert_eq!(
///     err.to_string(),
///     "elbow: the planned path reaches 151.343 past max_position (bus map) 150 by 1.343 (0.339 s into the move)"
/// );
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
/// [`Refusal::PathOutsideLimit`] naming the limit, the extreme position
/// and how far past the limit it is; [`Refusal::NonFinite`] for a start
/// state that is not finite (in degrees); [`Refusal::Unplannable`] for a
/// payload the joint's planner refuses.
pub fn check_path(
    motor: &MappedMotor,
    limits: &Effective,
    payload: &SetTargetPayloadV2,
    start_position: f64,
    start_velocity: f64,
) -> Result<PathExtent, Refusal> {
    check_path_from(
        motor,
        limits,
        payload,
        (start_position, start_velocity, 0.0),
    )
}

/// [`check_path`] from a joint whose speed is changing: `start` is its
/// position, velocity and acceleration (in the motor's unit, a second, a
/// second squared). A jerk-limited joint continues the motion it is in
/// from its acceleration
/// ([`Request::start_acceleration`](motorwire_planner::Request::start_acceleration)),
/// so its path is planned from it too; a trapezoidal one's is not.
///
/// ```
/// use motorwire_irpc::SetTargetPayloadV2;
/// use motorwire_translate::{BusMap, Effective, check_path, check_path_from};
///
/// let map = BusMap::from_toml(r#"
///     [motors.elbow]
///     dialect = "irpc"
///     node = 0x12
///     limits = { min_position = 0, max_position = 150, max_velocity = 120, max_acceleration = 500, max_jerk = 2000 }
/// "#)?;
/// let elbow = map.motor("elbow").unwrap();
/// let limits = Effective::from_bus_map(elbow);
/// let to_148 = SetTargetPayloadV2::scurve(148.0, 120.0, 500.0, 2000.0);
/// // At 128°, 60°/s towards 148: from a steady speed it stops in time...
/// assert!(check_path(elbow, &limits, &to_148, 128.0, 60.0).is_ok());
/// // ...but still speeding up at 400°/s², it passes 150 before it can stop.
/// let err = check_path_from(elbow, &limits, &to_148, (128.0, 60.0, 400.0)).unwrap_err();
/// assert!(err.to_string().contains("past max_position"), "{err}");
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
/// As [`check_path`]'s.
pub fn check_path_from(
    motor: &MappedMotor,
    limits: &Effective,
    payload: &SetTargetPayloadV2,
    start: JointState,
) -> Result<PathExtent, Refusal> {
    let (p, v) = in_degrees(motor, start.0, start.1)?;
    let a = motor.unit.to_degrees(start.2);
    if !a.is_finite() {
        return Err(Refusal::NonFinite {
            motor: motor.name.clone(),
            field: "start_acceleration",
        });
    }
    check_segment(motor, limits, payload, (p, v, a), None)
}

/// [`check_path`] for a trajectory sent as a sequence of `SetTargetV2`
/// segments, each sent as the previous one ends: the first is planned from
/// the joint's current state (`start_position`, `start_velocity`, in the
/// motor's unit), each next one from where the previous one ends (its
/// `target_angle` at its `target_velocity`, acceleration zero, as every
/// planned profile ends). Returns each segment's path, in order.
///
/// It takes payloads, not a WIA `Trajectory`: nothing in motorwire maps a
/// trajectory's waypoints to `SetTargetV2` segments yet (a waypoint's time
/// has no place in a `SetTargetV2`), so whoever builds the segments checks
/// them here.
///
/// ```
/// use motorwire_irpc::SetTargetPayloadV2;
/// use motorwire_translate::{BusMap, Effective, Refusal, check_trajectory};
///
/// let map = BusMap::from_toml(r#"
///     [motors.elbow]
///     dialect = "irpc"
///     node = 0x12
///     profile = "trapezoidal"
///     limits = { min_position = 0, max_position = 150 }
/// "#)?;
/// let elbow = map.motor("elbow").unwrap();
/// let limits = Effective::from_bus_map(elbow);
/// // Through 145° at 100°/s, then back to 140°: braking at 500°/s² takes 10°.
/// let through = SetTargetPayloadV2::trapezoidal(145.0, 100.0, 500.0);
/// let back = SetTargetPayloadV2::trapezoidal(140.0, 100.0, 500.0);
/// let fly_by = [SetTargetPayloadV2 { target_velocity: 100.0, ..through }, back];
/// let err = check_trajectory(elbow, &limits, &fly_by, 0.0, 0.0).unwrap_err();
/// assert!(matches!(err, Refusal::PathOutsideLimit { segment: Some(1), extreme: 155.0, overshoot: 5.0, .. }));
/// assert_eq!(
///     err.to_string(),
///     "elbow: segment 1 (counted from 0): the planned path reaches 155 past max_position (bus map) 150 by 5 (0.2 s into the move)"
/// );
/// // Stopping at 145° first, both segments stay within the limits.
/// let paths = check_trajectory(elbow, &limits, &[through, back], 0.0, 0.0)?;
/// assert_eq!(paths.iter().map(|p| p.highest).collect::<Vec<_>>(), [145.0, 145.0]);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
/// [`check_path`]'s, with `segment` naming the segment (counted from 0:
/// its index in `segments`).
pub fn check_trajectory(
    motor: &MappedMotor,
    limits: &Effective,
    segments: &[SetTargetPayloadV2],
    start_position: f64,
    start_velocity: f64,
) -> Result<Vec<PathExtent>, Refusal> {
    let (p, v) = in_degrees(motor, start_position, start_velocity)?;
    let mut state = (p, v, 0.0);
    let mut paths = Vec::with_capacity(segments.len());
    for (i, payload) in segments.iter().enumerate() {
        let path = check_segment(motor, limits, payload, state, Some(i))?;
        let end = path.profile.end_state();
        state = (end.position, end.velocity, 0.0);
        paths.push(path);
    }
    Ok(paths)
}

/// A joint's state in the motor's unit, in degrees (iRPC's unit), refused
/// unless finite there.
fn in_degrees(motor: &MappedMotor, position: f64, velocity: f64) -> Result<(f64, f64), Refusal> {
    let degrees = (
        motor.unit.to_degrees(position),
        motor.unit.to_degrees(velocity),
    );
    for (field, value) in [("start_position", degrees.0), ("start_velocity", degrees.1)] {
        if !value.is_finite() {
            return Err(Refusal::NonFinite {
                motor: motor.name.clone(),
                field,
            });
        }
    }
    Ok(degrees)
}

/// How far past `bound` (in the motor's unit) a path may go before it
/// passes it: one f32 step of the limit, in degrees (see [`check_path`]).
fn tolerance(motor: &MappedMotor, bound: f64) -> f64 {
    let unit = motor.unit;
    let degrees = f64::from(f32::EPSILON) * unit.to_degrees(bound).abs().max(1.0);
    unit.from_degrees(degrees)
}

/// Plans one move from `(position, velocity, acceleration)` in degrees
/// and checks its path.
pub(crate) fn check_segment(
    motor: &MappedMotor,
    limits: &Effective,
    payload: &SetTargetPayloadV2,
    (position, velocity, acceleration): (f64, f64, f64),
    segment: Option<usize>,
) -> Result<PathExtent, Refusal> {
    let unit = motor.unit;
    let req = payload
        .planner_request(position, velocity)
        .with_start_acceleration(acceleration);
    let profile = plan(&req).map_err(|e| Refusal::Unplannable {
        motor: motor.name.clone(),
        segment,
        problem: e.to_string(),
    })?;
    let e = profile.position_extrema();
    let start = unit.from_degrees(position);
    let (lowest, highest) = (unit.from_degrees(e.min), unit.from_degrees(e.max));
    let past = |name: &'static str, b: Bound, extreme: f64, at: f64| Refusal::PathOutsideLimit {
        motor: motor.name.clone(),
        segment,
        limit: name,
        limit_source: b.source,
        bound: b.value,
        extreme,
        overshoot: (extreme - b.value).abs(),
        at,
    };
    // A start already past a limit is not held against the move; going
    // farther is.
    let below = limits
        .min_position
        .filter(|b| lowest < b.value.min(start) - tolerance(motor, b.value))
        .map(|b| past("min_position", b, lowest, e.t_min));
    let above = limits
        .max_position
        .filter(|b| highest > b.value.max(start) + tolerance(motor, b.value))
        .map(|b| past("max_position", b, highest, e.t_max));
    // A path past both limits is refused for the one it passes first.
    match (below, above) {
        (Some(b), Some(a)) => Err(if e.t_min <= e.t_max { b } else { a }),
        (Some(r), None) | (None, Some(r)) => Err(r),
        (None, None) => {
            let end = profile.end_state();
            Ok(PathExtent {
                lowest,
                lowest_at: e.t_min,
                highest,
                highest_at: e.t_max,
                duration: profile.duration(),
                end_position: unit.from_degrees(end.position),
                end_velocity: unit.from_degrees(end.velocity),
                profile,
            })
        }
    }
}
