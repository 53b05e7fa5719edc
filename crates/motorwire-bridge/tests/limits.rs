//! Velocity and torque setpoints are bounded by the position limits in
//! force, on every dialect that takes them (issue 58 part 1): a
//! SafetyLimits line narrows a motor's range, and setpoints within its
//! velocity limit are then streamed toward the new limit. Before, every
//! one was taken and the motor went on to the device's own bounds (the
//! moteus knee to 140 past a limit of 60, the compact gripper to 90 past
//! 30). Now the bridge brakes it to a stop short of the limit (a
//! `limit_brake` event), and refuses a setpoint pointing outward from a
//! motor at its limit (`outward_at_limit`), while one pointing back in
//! is taken.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing
)]

mod common;

use motorwire_bridge::Origin;
use motorwire_bridge::sim::SimulatedArm;
use motorwire_can::Faults;
use serde_json::Value;

const MAP: &str = r#"
[motors.knee]
dialect = "moteus"
id = 2
query_rate_hz = 50
limits = { min_position = 0, max_position = 140, max_velocity = 240, max_acceleration = 960, max_torque = 3 }

[motors.gripper_axis]
dialect = "compact"
node = 0x20
limits = { min_position = 0, max_position = 90, max_velocity = 60, max_acceleration = 240, max_torque = 5 }
"#;

/// Where `motor` stands on its device (degrees).
fn position(arm: &SimulatedArm, motor: &str) -> f64 {
    match motor {
        "knee" => arm.moteus(2).unwrap().position() * 360.0,
        _ => arm.compact_device(0x20).unwrap().position(),
    }
}

/// An arm whose `motor` a SafetyLimits line has narrowed to 0..`limit`
/// (at most `speed` a second), the line taken.
fn narrowed(motor: &str, limit: f64, speed: f64) -> SimulatedArm {
    let mut arm = common::arm(MAP, Faults::default(), 0);
    arm.line(
        Origin(1),
        &format!(
            r#"{{"motor_id":"{motor}","position_limits":{{"min":0,"max":{limit}}},"velocity_limits":{{"max_velocity":{speed}}},"torque_limits":{{"continuous_torque":1,"peak_torque":2}}}}"#
        ),
    );
    arm.run_until(arm.now() + common::ms(100)).unwrap();
    let out = common::outputs(&mut arm);
    assert_eq!(out[0]["ok"], true, "{motor}: {out:?}");
    arm
}

/// `line` for `motor` sent every 50 ms for 3 s (its deadman never fires),
/// the motor's position sampled every 2 ms: the furthest it went, and
/// every output but feedback.
fn streamed(arm: &mut SimulatedArm, motor: &str, line: &str) -> (f64, Vec<Value>) {
    let mut furthest: f64 = 0.0;
    let mut all = Vec::new();
    for _ in 0..60 {
        arm.line(Origin(1), line);
        for _ in 0..25 {
            arm.step(common::ms(2)).unwrap();
            furthest = furthest.max(position(arm, motor));
        }
        all.extend(common::outputs(arm));
    }
    (furthest, all)
}

#[test]
fn a_velocity_stream_is_braked_short_of_the_limit_in_force_on_every_dialect() {
    for (motor, limit, speed) in [("knee", 60.0, 200.0), ("gripper_axis", 30.0, 50.0)] {
        let mut arm = narrowed(motor, limit, speed);
        // Streamed toward the limit at the speed the limits allow.
        let (furthest, all) = streamed(&mut arm, motor, &common::velocity(motor, speed));
        let braked: Vec<&Value> = all
            .iter()
            .filter(|v| v["event"] == "limit_brake" && v["motor_id"] == motor)
            .collect();
        assert!(!braked.is_empty(), "{motor}: no limit_brake in {all:?}");
        assert_eq!(braked[0]["limit_name"], "max_position");
        assert_eq!(braked[0]["limit"], limit);
        assert!(
            furthest <= limit + 1e-6,
            "{motor} went to {furthest}, past its limit {limit}"
        );
        assert!(
            furthest > limit - 15.0,
            "{motor} stopped at {furthest}, far short of {limit}"
        );
        // At its limit: outward refused, inward taken.
        let refused: Vec<&Value> = all.iter().filter(|v| v["ok"] == false).collect();
        assert!(!refused.is_empty(), "{motor}: every setpoint was taken");
        for r in &refused {
            assert_eq!(r["error"]["rule"], "outward_at_limit", "{r}");
        }
        arm.line(Origin(1), &common::velocity(motor, -speed / 2.0));
        arm.run_until(arm.now() + common::ms(100)).unwrap();
        let out = common::outputs(&mut arm);
        let r = out.iter().find(|v| v.get("ok").is_some()).unwrap();
        assert_eq!(r["ok"], true, "{motor}: {r}");
        eprintln!(
            "{motor}: limit {limit}, stopped at {furthest:.3}, {} setpoints refused outward",
            refused.len()
        );
    }
}

fn torque(motor: &str, t: f64) -> String {
    format!(r#"{{"motor_id":"{motor}","timestamp":0,"control_mode":"torque","setpoint":{t}}}"#)
}

/// A torque setpoint (the moteus knee: kp and kd scale 0, the simulated
/// rotor accelerating at torque over inertia, 0.2 Nm being 1,440 deg/s²,
/// past the limits' 960) streamed toward a narrowed limit is braked short
/// of it too. (The simulated compact device applies a torque without
/// moving: it has no load model, so a torque stream cannot carry it
/// anywhere, and the property test drives it by velocity.)
#[test]
fn a_torque_stream_never_carries_a_motor_past_the_limit_in_force() {
    let (motor, limit) = ("knee", 60.0);
    let mut arm = narrowed(motor, limit, 240.0);
    let (furthest, all) = streamed(&mut arm, motor, &torque(motor, 0.2));
    let braked = all.iter().filter(|v| v["event"] == "limit_brake").count();
    assert!(braked > 0, "no limit_brake in {all:?}");
    assert!(
        furthest <= limit + 1e-6,
        "the knee went to {furthest}, past its limit {limit}"
    );
    assert!(
        furthest > limit - 15.0,
        "the knee stopped at {furthest}, far short of {limit}"
    );
    // No fault: the controller's own bound (set to the limit) was never hit.
    assert!(!all.iter().any(|v| v["event"] == "joint_fault"), "{all:?}");
    eprintln!(
        "knee: limit {limit}, stopped at {furthest:.3}, {braked} limit brakes, {} torques refused",
        all.iter().filter(|v| v["ok"] == false).count()
    );
}
