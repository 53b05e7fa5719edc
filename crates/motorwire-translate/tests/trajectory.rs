//! WIA trajectories for an iRPC joint: gated, checked, planned segment by
//! segment so each waypoint is passed at its time.
#![allow(clippy::unwrap_used, clippy::panic, clippy::indexing_slicing)]

use motorwire_translate::{BusMap, Refusal, WAYPOINT_TOLERANCE_S, trajectory_to_irpc};
use motorwire_wia::Trajectory;

const DOC: &str = include_str!("../../../fixtures/wia/valid/doc-5.2-trajectory.json");

fn map() -> BusMap {
    BusMap::from_toml(
        r#"
        [motors.gripper_axis]
        dialect = "irpc"
        node = 0x20
        limits = { min_position = -10, max_position = 100, max_velocity = 200, max_acceleration = 500, max_jerk = 5000 }
        "#,
    )
    .unwrap()
}

fn feasible() -> Trajectory {
    let mut t: Trajectory = serde_json::from_str(DOC).unwrap();
    let c = t.constraints.as_mut().unwrap();
    c.max_velocity = Some(90.0);
    c.max_acceleration = Some(200.0);
    c.max_jerk = Some(1000.0);
    t
}

#[test]
fn the_documents_example_is_refused_naming_waypoint_4() {
    let t: Trajectory = serde_json::from_str(DOC).unwrap();
    let e = trajectory_to_irpc(&map(), &t).unwrap_err();
    assert!(
        matches!(e, Refusal::Infeasible { waypoint: 4, .. }),
        "{e:?}"
    );
    assert_eq!(
        e.to_string(),
        "gripper_axis: waypoint 4: its segment needs 2.24 s of the 2.00 s it is given under max_velocity 60, max_acceleration 120, max_jerk 500"
    );
}

#[test]
fn its_feasible_variant_passes_each_waypoint_at_its_time() {
    let plan = trajectory_to_irpc(&map(), &feasible()).unwrap().value;
    let times = [1.5, 3.0, 4.0, 6.0];
    assert_eq!(plan.segments.len(), 4);
    for (s, t) in plan.segments.iter().zip(times) {
        if s.payload.target_velocity == 0.0 {
            // At rest on it by its time (it holds there until then).
            assert!(
                s.arrives <= t + WAYPOINT_TOLERANCE_S,
                "{} for {t}",
                s.arrives
            );
        } else {
            assert!(
                (s.arrives - t).abs() <= WAYPOINT_TOLERANCE_S,
                "{} for {t}",
                s.arrives
            );
        }
    }
    // The segment leaving 90 at 15 deg/s to be back at rest one second
    // later arrives early and holds; the next starts at its waypoint's time.
    assert!(
        plan.segments[2].arrives < 3.9,
        "{}",
        plan.segments[2].arrives
    );
    assert_eq!(plan.segments[3].at, 4.0);
    assert_eq!(plan.duration, 6.0);
    assert_eq!(plan.segments[0].at, 0.0);
    assert_eq!(plan.segments[1].payload.target_velocity, 15.0);
    // Each segment after the first is sent just before the waypoint before it.
    assert!(
        (plan.segments[1].at - (1.5 - 0.002)).abs() < 1e-6,
        "{}",
        plan.segments[1].at
    );
}

#[test]
fn waypoints_outside_the_limits_and_loops_are_checked() {
    let mut t = feasible();
    t.waypoints[2].position = 120.0;
    assert_eq!(
        trajectory_to_irpc(&map(), &t).unwrap_err().to_string(),
        "gripper_axis: waypoint 2: position 120 is above max_position (bus map) 100"
    );
    // Forever: one cycle, repeated (it ends at rest where it starts).
    let mut t = feasible();
    t.loop_config = Some(serde_json::from_str(r#"{"enabled": true, "count": -1}"#).unwrap());
    let plan = trajectory_to_irpc(&map(), &t).unwrap().value;
    assert!(plan.forever);
    assert_eq!((plan.segments.len(), plan.duration), (4, 6.0));
    // A forever loop that would not end where it starts: refused.
    t.waypoints[4].position = 10.0;
    assert_eq!(
        trajectory_to_irpc(&map(), &t).unwrap_err().to_string(),
        "gripper_axis: waypoint 4: a loop forever must end at rest, where it starts (or reverse_on_loop)"
    );
    let mut t = feasible();
    t.loop_config = Some(serde_json::from_str(r#"{"enabled": true, "count": 3}"#).unwrap());
    let plan = trajectory_to_irpc(&map(), &t).unwrap().value;
    assert_eq!(plan.segments.len(), 12);
    assert_eq!(plan.duration, 18.0);
}

#[test]
fn a_trajectory_too_long_to_plan_at_once_is_refused_and_the_longest_is_quick() {
    let mut t = feasible();
    t.loop_config = Some(serde_json::from_str(r#"{"enabled": true, "count": 251}"#).unwrap());
    assert_eq!(
        trajectory_to_irpc(&map(), &t).unwrap_err().to_string(),
        "gripper_axis: waypoint 4: 5 waypoints over 251 passes are more than the 1000 segments one line may plan"
    );
    t.loop_config = Some(serde_json::from_str(r#"{"enabled": true, "count": 250}"#).unwrap());
    let started = std::time::Instant::now();
    let plan = trajectory_to_irpc(&map(), &t).unwrap().value;
    assert_eq!(plan.segments.len(), 1000);
    eprintln!("1000 segments planned in {:?}", started.elapsed());
}

/// A waypoint to pass at speed long after the joint could (45 at 30 deg/s
/// at 3 s, from rest at 0): no single SetTargetV2 takes that long (a
/// time-optimal profile does not dawdle), so the segment is split, and
/// said so: a stop short of the waypoint, then the take-off from rest
/// that reaches 30 deg/s exactly at 45, sent so it does at 3 s. Planned
/// as the joint plans each (f32), the waypoint is passed at 3 s.
#[test]
fn a_waypoint_the_joint_would_pass_early_at_speed_is_split_and_passed_on_time() {
    let t: Trajectory = serde_json::from_str(
        r#"{"trajectory_id":"late","motor_id":"gripper_axis","waypoints":[
            {"position":0,"velocity":0,"time":0},{"position":45,"velocity":30,"time":3.0},
            {"position":90,"velocity":0,"time":5.0}],
            "timing":{},"constraints":{"max_velocity":90,"max_acceleration":200,"max_jerk":1000}}"#,
    )
    .unwrap();
    let translated = trajectory_to_irpc(&map(), &t).unwrap();
    let plan = translated.value;
    assert_eq!(plan.segments.len(), 3, "{:?}", plan.segments);
    let (stop, takeoff) = (&plan.segments[0], &plan.segments[1]);
    assert_eq!(
        (
            stop.payload.target_velocity,
            takeoff.payload.target_velocity
        ),
        (0.0, 30.0)
    );
    assert_eq!(takeoff.payload.target_angle, 45.0);
    assert_eq!(takeoff.payload.max_velocity, 30.0);
    assert!(stop.arrives <= takeoff.at, "at rest before it takes off");
    // The take-off as the joint plans it, from rest where the stop ends.
    let own = motorwire_planner::plan(
        &takeoff
            .payload
            .planner_request(stop.payload.target_angle, 0.0),
    )
    .unwrap();
    let passes = takeoff.at + f64::from(own.duration());
    assert!(
        (passes - 3.0).abs() <= WAYPOINT_TOLERANCE_S,
        "passes at {passes}"
    );
    let end = own.end_state();
    assert!(
        (end.position - 45.0).abs() < 1e-4 && (end.velocity - 30.0).abs() < 1e-3,
        "{end:?}"
    );
    assert!(
        translated
            .report
            .losses
            .iter()
            .any(|l| l.field == "waypoints[1]"
                && l.detail.starts_with("the joint would pass it early at ")
                && l.detail.ends_with("to pass it at 3.0000 s at its velocity")),
        "{:?}",
        translated.report
    );
}

/// Found by a new user: a `loop` with a count but without `"enabled":
/// true` ran once without a word.
#[test]
fn a_loop_that_is_not_enabled_runs_once_and_says_so() {
    let loss = |json: &str| {
        let mut t = feasible();
        t.loop_config = Some(serde_json::from_str(json).unwrap());
        let translated = trajectory_to_irpc(&map(), &t).unwrap();
        assert_eq!(translated.value.segments.len(), 4, "{json}");
        translated
            .report
            .losses
            .iter()
            .find(|l| l.field == "loop")
            .map(ToString::to_string)
    };
    assert_eq!(
        loss(r#"{"count": 3}"#).as_deref(),
        Some(
            r#"loop: dropped: the loop is not enabled (it takes "enabled": true): the trajectory runs once"#
        )
    );
    assert_eq!(
        loss(r#"{"enabled": false, "count": -1}"#).as_deref(),
        Some(r#"loop: dropped: the loop is disabled ("enabled": false): the trajectory runs once"#)
    );
    assert_eq!(
        loss(r#"{"reverse_on_loop": true}"#).as_deref(),
        Some(
            r#"loop: dropped: the loop is not enabled (it takes "enabled": true): the trajectory runs once"#
        )
    );
    // Once is what it asks for: nothing to say.
    assert_eq!(loss(r#"{"count": 1}"#), None);
    assert_eq!(loss(r#"{"enabled": false}"#), None);
}

/// Every segment brakes within the map's deceleration where it is tighter
/// than the acceleration (the segments carried the acceleration as their
/// deceleration: 500 on a joint limited to 400), and within the
/// trajectory's own acceleration where that is tighter still.
#[test]
fn each_segment_brakes_within_the_deceleration_in_force() {
    let braking = BusMap::from_toml(
        r#"
        [motors.gripper_axis]
        dialect = "irpc"
        node = 0x20
        limits = { min_position = -10, max_position = 100, max_velocity = 200, max_acceleration = 500, max_deceleration = 400, max_jerk = 5000 }
        "#,
    )
    .unwrap();
    let mut t = feasible();
    for (own, decel) in [(450.0, 400.0), (200.0, 200.0)] {
        t.constraints.as_mut().unwrap().max_acceleration = Some(own);
        let plan = trajectory_to_irpc(&braking, &t).unwrap().value;
        for s in &plan.segments {
            assert_eq!(
                (s.payload.max_acceleration, s.payload.max_deceleration),
                (own as f32, decel as f32)
            );
        }
    }
    // Without a deceleration in the map, the acceleration brakes.
    let plan = trajectory_to_irpc(&map(), &feasible()).unwrap().value;
    assert!(
        plan.segments
            .iter()
            .all(|s| s.payload.max_deceleration == 200.0)
    );
}
