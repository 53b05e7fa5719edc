//! Position limits along the whole planned path (issue 17, part 3): the
//! gate plans a move as the joint will, from its current state, and refuses
//! a path that passes a position limit, naming the limit and by how much.
#![allow(clippy::unwrap_used, clippy::panic, clippy::indexing_slicing)]

use motorwire_irpc::{Payload, SetTargetPayloadV2};
use motorwire_planner::{Profile, plan};
use motorwire_translate::*;
use motorwire_wia::{MotorCommand, MultiAxisCommand};

const MAP: &str = r#"
[motors.elbow]
dialect = "irpc"
node = 0x12
profile = "scurve"
limits = { min_position = 0, max_position = 150, max_velocity = 120, max_acceleration = 500, max_deceleration = 400, max_jerk = 2000 }

[motors.wrist]
dialect = "irpc"
node = 0x13
profile = "trapezoidal"
limits = { min_position = 0, max_position = 150, max_velocity = 120, max_acceleration = 500, max_deceleration = 400 }

[motors.forearm]
dialect = "irpc"
node = 0x14
unit = "rad"
profile = "scurve"
limits = { min_position = -2.5, max_position = 2.5, max_velocity = 2, max_acceleration = 8, max_jerk = 40 }
"#;

fn map() -> BusMap {
    BusMap::from_toml(MAP).unwrap()
}

fn command(json: &str) -> MotorCommand {
    serde_json::from_str(json).unwrap()
}

/// The gate's motor and limits, and the SetTargetV2 `to_irpc` makes, for a
/// position command to `setpoint` (with `extra` members).
fn move_to(
    map: &BusMap,
    motor: &str,
    setpoint: f64,
    extra: &str,
) -> (MappedMotor, Effective, SetTargetPayloadV2) {
    let cmd = command(&format!(
        r#"{{"motor_id": "{motor}", "timestamp": 0, "control_mode": "position", "setpoint": {setpoint}{extra}}}"#
    ));
    let (m, limits) = gate(map, &cmd).unwrap();
    let Payload::SetTargetV2(p) = to_irpc(map, &cmd).unwrap().value.payloads[0] else {
        panic!("not a SetTargetV2")
    };
    (m.clone(), limits, p)
}

/// The joint's plan, as the joint makes it (degrees).
fn joint_plan(p: &SetTargetPayloadV2, start: f64, velocity: f64) -> Profile<f64> {
    plan(&p.planner_request(start, velocity)).unwrap()
}

/// The lowest and highest positions among `n + 1` evenly spaced samples of
/// the whole profile: no use of the planner's own extrema.
fn sampled(profile: &Profile<f64>, n: u32) -> (f64, f64) {
    let ((lo, _), (hi, _)) = sampled_at(profile, n);
    (lo, hi)
}

/// [`sampled`], with the times of the lowest and highest samples.
fn sampled_at(profile: &Profile<f64>, n: u32) -> ((f64, f64), (f64, f64)) {
    let t = profile.duration();
    (0..=n)
        .map(|k| {
            let at = t * f64::from(k) / f64::from(n);
            (profile.sample(at).position, at)
        })
        .fold(
            ((f64::INFINITY, 0.0), (f64::NEG_INFINITY, 0.0)),
            |(lo, hi), (p, at)| {
                (
                    if p < lo.0 { (p, at) } else { lo },
                    if p > hi.0 { (p, at) } else { hi },
                )
            },
        )
}

fn outside(r: &Refusal) -> (Option<usize>, String, f64, f64, f64, f64) {
    let Refusal::PathOutsideLimit {
        segment,
        limit,
        limit_source,
        bound,
        extreme,
        overshoot,
        at,
        ..
    } = r
    else {
        panic!("not PathOutsideLimit: {r:?}")
    };
    (
        *segment,
        format!("{limit} ({limit_source})"),
        *bound,
        *extreme,
        *overshoot,
        *at,
    )
}

#[test]
fn an_s_curve_too_fast_to_brake_passes_max_position_and_is_refused() {
    let map = map();
    // The target, 145, is within [0, 150]: the gate lets the command through.
    let (elbow, limits, p) = move_to(&map, "elbow", 145.0, "");
    assert_eq!(p.profile, motorwire_irpc::MotionProfile::SCurve);
    // At 100°/s from 130°, jerk-limited braking at 400°/s² needs more room.
    let err = check_path(&elbow, &limits, &p, 130.0, 100.0).unwrap_err();
    let (segment, limit, bound, extreme, overshoot, at) = outside(&err);
    // Independently: 400,000 samples of the joint's plan (a sample lands
    // within 1e-6 s of the peak, where the velocity is 0: error < 1e-9).
    let (_, (highest, highest_at)) = sampled_at(&joint_plan(&p, 130.0, 100.0), 400_000);
    assert!((extreme - highest).abs() < 1e-9, "{extreme} vs {highest}");
    assert!((overshoot - (highest - 150.0)).abs() < 1e-9, "{overshoot}");
    assert_eq!(
        (segment, limit.as_str(), bound),
        (None, "max_position (bus map)", 150.0)
    );
    assert!((at - highest_at).abs() < 1e-5, "{at} vs {highest_at}");
    assert_eq!(
        err.to_string(),
        "elbow: the planned path reaches 151.841 past max_position (bus map) 150 by 1.841 (0.352 s into the move)"
    );
}

#[test]
fn the_same_s_curve_from_rest_stays_within_the_limits() {
    let map = map();
    let (elbow, limits, p) = move_to(&map, "elbow", 145.0, "");
    let path = check_path(&elbow, &limits, &p, 130.0, 0.0).unwrap();
    assert_eq!((path.lowest, path.lowest_at), (130.0, 0.0));
    assert_eq!(
        (path.highest, path.end_position, path.end_velocity),
        (145.0, 145.0, 0.0)
    );
    assert_eq!(path.highest_at, path.duration);
    assert_eq!(path.duration, joint_plan(&p, 130.0, 0.0).duration());
}

#[test]
fn a_trapezoid_passes_max_position_by_exactly_its_braking_distance() {
    let map = map();
    let (wrist, limits, p) = move_to(&map, "wrist", 145.0, "");
    assert_eq!(p.profile, motorwire_irpc::MotionProfile::Trapezoidal);
    assert_eq!(p.max_deceleration, 400.0);
    // From 140° at 100°/s, braking at 400°/s² takes v²/2d = 12.5° and
    // v/d = 0.25 s: the path turns at 152.5°.
    let err = check_path(&wrist, &limits, &p, 140.0, 100.0).unwrap_err();
    let (_, limit, bound, extreme, overshoot, at) = outside(&err);
    assert_eq!((limit.as_str(), bound), ("max_position (bus map)", 150.0));
    assert!((extreme - 152.5).abs() < 1e-12, "{extreme}");
    assert!((overshoot - 2.5).abs() < 1e-12, "{overshoot}");
    assert!((at - 0.25).abs() < 1e-12, "{at}");
    assert_eq!(
        err.to_string(),
        "wrist: the planned path reaches 152.5 past max_position (bus map) 150 by 2.5 (0.25 s into the move)"
    );
    // Braking from 135°, the same move turns at 147.5° and passes.
    let path = check_path(&wrist, &limits, &p, 135.0, 100.0).unwrap();
    assert!((path.highest - 147.5).abs() < 1e-12, "{}", path.highest);
}

#[test]
fn a_path_below_min_position_names_the_commands_own_limit() {
    let map = map();
    // The command tightens min_position to 10; its target 15 is above it.
    let (elbow, limits, p) = move_to(
        &map,
        "elbow",
        15.0,
        r#", "safety_limits": {"min_position": 10}"#,
    );
    let err = check_path(&elbow, &limits, &p, 25.0, -100.0).unwrap_err();
    let (_, limit, bound, extreme, overshoot, _) = outside(&err);
    let (lowest, _) = sampled(&joint_plan(&p, 25.0, -100.0), 400_000);
    assert!((extreme - lowest).abs() < 1e-9, "{extreme} vs {lowest}");
    assert!((overshoot - (10.0 - lowest)).abs() < 1e-9, "{overshoot}");
    assert_eq!((limit.as_str(), bound), ("min_position (command)", 10.0));
    assert_eq!(
        err.to_string(),
        "elbow: the planned path reaches 3.167 past min_position (command) 10 by 6.833 (0.35 s into the move)"
    );
    // Against the bus map's own limit, 0, the same path passes.
    let path = check_path(&elbow, &Effective::from_bus_map(&elbow), &p, 25.0, -100.0).unwrap();
    assert_eq!(path.lowest, extreme);
}

#[test]
fn a_trajectory_names_its_first_segment_that_leaves_counting_from_0() {
    let map = map();
    let wrist = map.motor("wrist").unwrap();
    let limits = Effective::from_bus_map(wrist);
    let stop_at = |target: f32| SetTargetPayloadV2::trapezoidal(target, 100.0, 400.0);
    let fly_by = |target: f32| SetTargetPayloadV2 {
        target_velocity: 100.0,
        ..stop_at(target)
    };
    // 0: to 60 from rest; 1: through 140 at 100°/s; 2: back to 130, which
    // brakes 12.5° past 140 first.
    let segments = [stop_at(60.0), fly_by(140.0), stop_at(130.0)];
    let err = check_trajectory(wrist, &limits, &segments, 10.0, 0.0).unwrap_err();
    let (segment, _, _, extreme, overshoot, at) = outside(&err);
    assert_eq!(segment, Some(2));
    assert!((extreme - 152.5).abs() < 1e-9 && (overshoot - 2.5).abs() < 1e-9);
    assert!((at - 0.25).abs() < 1e-9, "{at}");
    assert_eq!(
        err.to_string(),
        "wrist: segment 2 (counted from 0): the planned path reaches 152.5 past max_position (bus map) 150 by 2.5 (0.25 s into the move)"
    );
    // Arriving at 148 at 100°/s as the last segment is within the limits
    // (what follows is not this trajectory's); braking after a fly-by
    // through 140 is segment 1's fault when segment 1 is the one that brakes.
    let segments = [stop_at(60.0), stop_at(145.0), fly_by(148.0)];
    assert!(check_trajectory(wrist, &limits, &segments, 10.0, 0.0).is_ok());
    let segments = [fly_by(140.0), stop_at(145.0), stop_at(20.0)];
    let err = check_trajectory(wrist, &limits, &segments, 10.0, 0.0).unwrap_err();
    assert_eq!(outside(&err).0, Some(1));
    // Within the limits: each segment starts where the previous one ended.
    let segments = [stop_at(60.0), fly_by(120.0), stop_at(120.0)];
    let paths = check_trajectory(wrist, &limits, &segments, 10.0, 0.0).unwrap();
    assert_eq!(paths.len(), 3);
    assert_eq!((paths[0].end_position, paths[0].end_velocity), (60.0, 0.0));
    assert_eq!(
        (paths[1].end_position, paths[1].end_velocity),
        (120.0, 100.0)
    );
    let third = joint_plan(&segments[2], 120.0, 100.0);
    assert_eq!(paths[2].profile, third);
    assert!(
        (paths[2].highest - 132.5).abs() < 1e-12,
        "{}",
        paths[2].highest
    );
    // No segments, nothing to refuse.
    assert_eq!(check_trajectory(wrist, &limits, &[], 10.0, 0.0), Ok(vec![]));
}

#[test]
fn reaching_a_limit_exactly_is_not_passing_it() {
    let map = map();
    // To the limit itself, from rest.
    let (elbow, limits, p) = move_to(&map, "elbow", 150.0, "");
    let path = check_path(&elbow, &limits, &p, 0.0, 0.0).unwrap();
    assert_eq!(path.end_position, 150.0);
    let (elbow_min, _, p_min) = move_to(&map, "elbow", 0.0, "");
    check_path(&elbow_min, &limits, &p_min, 150.0, 0.0).unwrap();
    // Braking to a stop exactly at 150 (from 137.5 at 100°/s: 12.5°).
    let (wrist, limits, p) = move_to(&map, "wrist", 145.0, "");
    let path = check_path(&wrist, &limits, &p, 137.5, 100.0).unwrap();
    assert_eq!(path.highest, 150.0);
    // A thousandth of a degree further is refused.
    let err = check_path(&wrist, &limits, &p, 137.501, 100.0).unwrap_err();
    assert!((outside(&err).4 - 0.001).abs() < 1e-9, "{err}");
    assert_eq!(
        err.to_string(),
        "wrist: the planned path reaches 150.001 past max_position (bus map) 150 by 0.001 (0.25 s into the move)"
    );
    // 2.5 rad is no f32 of degrees: its SetTargetV2 rounds it up
    // (7.4e-6° past 143.239...°), within the margin of one f32 step.
    let (forearm, limits, p) = move_to(&map, "forearm", 2.5, "");
    assert!(f64::from(p.target_angle) > 2.5f64.to_degrees());
    let path = check_path(&forearm, &limits, &p, 0.0, 0.0).unwrap();
    assert!(
        path.highest > 2.5 && path.highest - 2.5 < 1e-6,
        "{}",
        path.highest
    );
}

#[test]
fn a_radian_motors_path_is_checked_and_reported_in_radians() {
    let map = map();
    let (forearm, limits, p) = move_to(&map, "forearm", 2.4, "");
    // 2 rad/s towards 2.4 rad from 2.2 rad: it cannot stop in time.
    let err = check_path(&forearm, &limits, &p, 2.2, 2.0).unwrap_err();
    let (_, limit, bound, extreme, overshoot, _) = outside(&err);
    let (_, highest_deg) = sampled(
        &joint_plan(&p, 2.2f64.to_degrees(), 2.0f64.to_degrees()),
        400_000,
    );
    assert!(
        (extreme - highest_deg.to_radians()).abs() < 1e-9,
        "{extreme}"
    );
    assert!((overshoot - (extreme - 2.5)).abs() < 1e-12);
    assert_eq!((limit.as_str(), bound), ("max_position (bus map)", 2.5));
    assert_eq!(
        err.to_string(),
        "forearm: the planned path reaches 2.637 past max_position (bus map) 2.5 by 0.137 (0.35 s into the move)"
    );
    // From rest, the path is the move itself, in radians.
    let path = check_path(&forearm, &limits, &p, 2.2, 0.0).unwrap();
    assert!((path.lowest - 2.2).abs() < 1e-12 && (path.highest - 2.4).abs() < 1e-6);
}

#[test]
fn a_joint_already_past_a_limit_may_come_back_but_not_go_farther() {
    let map = map();
    let (elbow, limits, p) = move_to(&map, "elbow", 140.0, "");
    // At rest at 155°, past max_position: coming back is allowed.
    let path = check_path(&elbow, &limits, &p, 155.0, 0.0).unwrap();
    assert_eq!((path.highest, path.lowest), (155.0, 140.0));
    // Moving away at 30°/s: the path goes farther out before it returns.
    let err = check_path(&elbow, &limits, &p, 155.0, 30.0).unwrap_err();
    let (_, _, _, extreme, overshoot, _) = outside(&err);
    assert!(extreme > 155.0 && (overshoot - (extreme - 150.0)).abs() < 1e-12);
}

#[test]
fn a_bad_start_or_an_unplannable_payload_is_refused() {
    let map = map();
    let (elbow, limits, p) = move_to(&map, "elbow", 90.0, "");
    assert_eq!(
        check_path(&elbow, &limits, &p, f64::NAN, 0.0)
            .unwrap_err()
            .to_string(),
        "elbow: start_position is not a finite number"
    );
    assert_eq!(
        check_trajectory(&elbow, &limits, &[p], 0.0, f64::INFINITY)
            .unwrap_err()
            .to_string(),
        "elbow: start_velocity is not a finite number"
    );
    let stalled = SetTargetPayloadV2 {
        max_velocity: 0.0,
        ..p
    };
    let err = check_path(&elbow, &limits, &stalled, 0.0, 0.0).unwrap_err();
    assert!(
        matches!(err, Refusal::Unplannable { segment: None, .. }),
        "{err:?}"
    );
    let err = check_trajectory(&elbow, &limits, &[p, stalled], 0.0, 0.0).unwrap_err();
    assert!(
        err.to_string()
            .starts_with("elbow: segment 1 (counted from 0): the joint cannot plan the move: "),
        "{err}"
    );
}

#[test]
fn a_synchronized_move_brings_a_joint_back_from_past_its_limit() {
    let cmd: MultiAxisCommand = serde_json::from_str(
        r#"{"command_id": "back", "timestamp": 0, "sync_mode": "simultaneous", "motors": [
            {"motor_id": "elbow", "control_mode": "position", "setpoint": 140},
            {"motor_id": "wrist", "control_mode": "position", "setpoint": 20}
        ]}"#,
    )
    .unwrap();
    // The elbow starts at 152°, past its max_position: the move back passes.
    let starts = |m: &str| Some(if m == "elbow" { 152.0 } else { 10.0 });
    let t = multi_axis_to_irpc(&map(), &cmd, &starts).unwrap();
    assert_eq!(t.value.commands.len(), 2);
}

mod path_property {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// For random moves from random states inside [0, 150]: a path
        /// check_path accepts has all of 1,001 samples within the limits
        /// (to its documented margin of one f32 step), and one it refuses
        /// really passes the limit it names: the samples reach its extreme,
        /// to within what sampling can miss near a turn.
        #[test]
        fn accepted_paths_stay_inside_and_refused_ones_really_leave(
            start in 0.0f64..=150.0,
            start_velocity in -300.0f64..300.0,
            target in 0.0f32..=150.0,
            max_velocity in 20.0f32..200.0,
            arrive in -0.99f32..0.99,
            arriving in any::<bool>(),
            max_acceleration in 100.0f32..2000.0,
            max_deceleration in 100.0f32..2000.0,
            jerk in proptest::option::of(500.0f32..50_000.0),
        ) {
            let map = map();
            let elbow = map.motor("elbow").unwrap();
            let limits = Effective::from_bus_map(elbow);
            let base = match jerk {
                Some(j) => SetTargetPayloadV2::scurve(target, max_velocity, max_acceleration, j),
                None => SetTargetPayloadV2::trapezoidal(target, max_velocity, max_acceleration),
            };
            let p = SetTargetPayloadV2 {
                target_velocity: if arriving { arrive * max_velocity } else { 0.0 },
                ..base.with_deceleration(max_deceleration)
            };
            let profile = joint_plan(&p, start, start_velocity);
            let (lo, hi) = sampled(&profile, 1000);
            let margin = |bound: f64| f64::from(f32::EPSILON) * bound.abs().max(1.0);
            match check_path(elbow, &limits, &p, start, start_velocity) {
                Ok(path) => {
                    prop_assert!(lo >= 0.0 - margin(0.0), "sampled {lo} below 0");
                    prop_assert!(hi <= 150.0 + margin(150.0), "sampled {hi} above 150");
                    prop_assert!(path.lowest <= lo + 1e-9 && path.highest >= hi - 1e-9);
                }
                Err(Refusal::PathOutsideLimit { limit, limit_source, bound, extreme, overshoot, at, .. }) => {
                    // Near a turn the velocity is 0 and grows at most with the
                    // peak acceleration: the nearest of samples dt apart lies
                    // within a·dt²/8 of the extreme.
                    let dt = profile.duration() / 1000.0;
                    let miss = profile.peak_acceleration() * dt * dt / 8.0 + 1e-9;
                    prop_assert!((profile.sample(at).position - extreme).abs() < 1e-9);
                    if (limit, limit_source) == ("max_position", "bus map") {
                        prop_assert_eq!(bound, 150.0);
                        prop_assert!(extreme > 150.0 + margin(150.0));
                        prop_assert!(extreme >= hi - 1e-9 && extreme - hi <= miss, "{extreme} vs {hi}");
                        prop_assert!((overshoot - (extreme - 150.0)).abs() < 1e-12);
                    } else {
                        prop_assert_eq!((limit, limit_source, bound), ("min_position", "bus map", 0.0));
                        prop_assert!(extreme < -margin(0.0));
                        prop_assert!(extreme <= lo + 1e-9 && lo - extreme <= miss, "{extreme} vs {lo}");
                        prop_assert!((overshoot + extreme).abs() < 1e-12);
                    }
                }
                Err(other) => prop_assert!(false, "unexpected refusal {other}"),
            }
        }
    }
}
