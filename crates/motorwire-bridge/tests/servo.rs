//! Serial bus servos behind the bridge, in simulated time: Feetech STS3215
//! and Dynamixel X servos on simulated half-duplex buses (motorwire-sim's
//! `ServoBus`, which answers every instruction from its model's control
//! table), beside an iRPC joint, under one gate and one emergency stop.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing
)]

mod common;

use std::time::Duration;

use motorwire_bridge::sim::SimulatedArm;
use motorwire_bridge::{Bridge, BridgeConfig, Origin};
use motorwire_can::SimConfig;
use motorwire_sim::servo::ServoFaults;
use motorwire_translate::BusMap;
use serde_json::Value;

const MAP: &str = r#"
[motors.elbow]
dialect = "irpc"
node = 0x12
limits = { min_position = 0, max_position = 150, max_velocity = 120, max_acceleration = 500 }

[motors.pan]
dialect = "feetech"
port = "/dev/ttyACM0"
id = 1
model = "sts3215"
calibration = { homing_offset = 0, range_min = 1048, range_max = 3048, drive_mode = 0 }
limits = { max_velocity = 180, max_acceleration = 900 }

[motors.gripper]
dialect = "feetech"
port = "/dev/ttyACM0"
id = 6
model = "sts3215"
stop = "hold"
calibration = { homing_offset = 0, range_min = 1500, range_max = 3000, drive_mode = 0 }

[motors.wrist]
dialect = "dynamixel"
port = "/dev/ttyUSB0"
id = 4
model = "xl330-m288"
unit = "rad"
calibration = { homing_offset = 0, range_min = 1024, range_max = 3072, drive_mode = 0 }
limits = { max_velocity = 3, max_acceleration = 15 }

[motors.shoulder]
dialect = "dynamixel"
port = "/dev/ttyUSB0"
id = 2
model = "xl430-w250"
calibration = { homing_offset = 0, range_min = 1024, range_max = 3072, drive_mode = 0 }
"#;

fn servo_arm(config: BridgeConfig) -> SimulatedArm {
    let map = BusMap::from_toml(MAP).unwrap();
    let bridge = Bridge::new(map, config).unwrap();
    let mut arm = SimulatedArm::new(bridge, SimConfig::default()).unwrap();
    arm.run_until(Duration::from_millis(300)).unwrap();
    arm
}

fn register(arm: &SimulatedArm, port: u8, id: u8, name: &str) -> i64 {
    arm.servo(port, id).unwrap().get(name).unwrap()
}

fn feedback_of<'a>(out: &'a [Value], motor: &str) -> Vec<&'a Value> {
    out.iter()
        .filter(|v| v["feedback"]["motor_id"] == motor)
        .map(|v| &v["feedback"])
        .collect()
}

#[test]
fn a_move_reaches_its_goal_through_the_calibration_on_both_vendors() {
    let mut arm = servo_arm(BridgeConfig::default());
    let t0 = arm.now();
    // Before any command, feedback reads each servo where it stands: the
    // simulated servos start at step 2048, which the pan's calibration
    // (middle 2048) reads as 0°.
    let out = common::run_for(&mut arm, Duration::ZERO);
    let pan = feedback_of(&out, "pan");
    assert!(!pan.is_empty(), "{out:?}");
    assert_eq!(pan[0]["position"], 0.0);
    arm.line(Origin(1), &common::command("pan", 45.0));
    arm.line(Origin(1), &common::command("wrist", -0.5));
    arm.run_until(t0 + Duration::from_secs(3)).unwrap();
    let out = common::run_for(&mut arm, Duration::ZERO);
    let results: Vec<&Value> = out
        .iter()
        .filter(|v| v.get("ok").is_some() && v.get("event").is_none())
        .collect();
    assert_eq!(results.len(), 2, "{out:?}");
    assert!(results.iter().all(|r| r["ok"] == true), "{results:?}");
    assert_eq!(
        results[0]["losses"],
        serde_json::json!([
            "velocity_limit: defaulted: 180 from the bus map",
            "acceleration_limit: defaulted: 900 from the bus map"
        ])
    );
    for motor in ["pan", "wrist"] {
        assert!(
            out.iter()
                .any(|v| v["arrived"] == true && v["motor_id"] == motor),
            "{motor}: {:?}",
            feedback_of(&out, motor).last()
        );
    }
    // 45° from the middle (2048) of a 4096-step turn read over 4095: step
    // 2560 (2048 + 45 * 4095 / 360 = 2559.9); at 180°/s (2048 steps/s)
    // and 900°/s² (102 of 100 steps/s²).
    assert_eq!(register(&arm, 0, 1, "Goal_Position"), 2560);
    assert_eq!(register(&arm, 0, 1, "Goal_Velocity"), 2048);
    assert_eq!(register(&arm, 0, 1, "Acceleration"), 102);
    assert_eq!(register(&arm, 0, 1, "Torque_Enable"), 1);
    assert_eq!(register(&arm, 0, 1, "Present_Position"), 2560);
    // -0.5 rad is -28.648°: step 2048 - 325.9 = 1722 on the Dynamixel,
    // within 3 rad/s (125 of 0.229 rpm) and 15 rad/s² (40 of 214.577
    // rev/min²), the torque on after the goal.
    assert_eq!(register(&arm, 1, 4, "Goal_Position"), 1722);
    assert_eq!(register(&arm, 1, 4, "Profile_Velocity"), 125);
    assert_eq!(register(&arm, 1, 4, "Profile_Acceleration"), 40);
    assert_eq!(register(&arm, 1, 4, "Torque_Enable"), 1);
    assert_eq!(register(&arm, 1, 4, "Present_Position"), 1722);
    // Feedback in each motor's unit, with the servo's own readings.
    let out = common::run_for(&mut arm, Duration::from_millis(300));
    let pan = feedback_of(&out, "pan");
    let last = pan.last().unwrap();
    assert!(
        (last["position"].as_f64().unwrap() - 45.0).abs() < 0.1,
        "{last}"
    );
    assert_eq!(last["status"]["enabled"], true);
    assert!(last["voltage"].as_f64().unwrap() > 0.0, "{last}");
    let wrist = feedback_of(&out, "wrist");
    let last = wrist.last().unwrap();
    assert!(
        (last["position"].as_f64().unwrap() + 0.5).abs() < 0.002,
        "{last}"
    );
}

#[test]
fn beyond_the_calibrated_range_nothing_is_written() {
    let mut arm = servo_arm(BridgeConfig::default());
    let goal = register(&arm, 0, 1, "Goal_Position");
    // The pan's range 1048..=3048 is ±87.9°: 90° is beyond it.
    arm.line(Origin(1), &common::command("pan", 90.0));
    let out = common::run_for(&mut arm, Duration::from_millis(500));
    let r = out
        .iter()
        .find(|v| v.get("ok").is_some() && v.get("event").is_none())
        .unwrap();
    assert_eq!(r["ok"], false, "{r}");
    assert_eq!(r["error"]["rule"], "outside_limit", "{r}");
    assert_eq!(register(&arm, 0, 1, "Goal_Position"), goal);
    assert_eq!(register(&arm, 0, 1, "Torque_Enable"), 0);
    // Velocity commands are refused: a servo's wheel mode would turn past
    // its range with nothing to stop it.
    arm.line(
        Origin(1),
        r#"{"motor_id":"pan","timestamp":0,"control_mode":"velocity","setpoint":10}"#,
    );
    let out = common::run_for(&mut arm, Duration::from_millis(200));
    let r = out
        .iter()
        .find(|v| v.get("ok").is_some() && v.get("event").is_none())
        .unwrap();
    assert_eq!(r["ok"], false, "{r}");
    assert_eq!(register(&arm, 0, 1, "Torque_Enable"), 0);
}

#[test]
fn the_emergency_stop_turns_torque_off_or_holds_as_the_map_says() {
    let mut arm = servo_arm(BridgeConfig::default());
    let t0 = arm.now();
    arm.line(Origin(1), &common::command("pan", 80.0));
    arm.line(Origin(1), &common::command("gripper", 30.0));
    arm.line(Origin(1), &common::command("elbow", 100.0));
    arm.run_until(t0 + Duration::from_millis(150)).unwrap();
    arm.line(Origin(2), r#"{"emergency_stop":true}"#);
    arm.run_until(t0 + Duration::from_millis(400)).unwrap();
    // The pan's torque is off (the default stop); the gripper holds where
    // it stood when the stop came, its torque on.
    assert_eq!(register(&arm, 0, 1, "Torque_Enable"), 0);
    assert_eq!(register(&arm, 0, 6, "Torque_Enable"), 1);
    let held = register(&arm, 0, 6, "Goal_Position");
    let present = register(&arm, 0, 6, "Present_Position");
    assert!((held - present).abs() <= 2, "{held} {present}");
    // 30° from the middle (2250) is step 2591.
    assert!(held < 2591, "the gripper stopped short of 30°: {held}");
    // Latched: a new move is refused, and nothing is written.
    let before = register(&arm, 0, 1, "Goal_Position");
    arm.line(Origin(1), &common::command("pan", 10.0));
    let out = common::run_for(&mut arm, Duration::from_millis(200));
    let refused = out
        .iter()
        .filter(|v| v.get("ok").is_some() && v.get("event").is_none())
        .find(|v| v["error"]["rule"] == "emergency_stop_latched");
    assert!(refused.is_some(), "{out:?}");
    assert_eq!(register(&arm, 0, 1, "Goal_Position"), before);
    assert_eq!(register(&arm, 0, 1, "Torque_Enable"), 0);
}

#[test]
fn lost_and_corrupt_status_packets_are_asked_again_and_no_move_is_lost() {
    let mut arm = servo_arm(BridgeConfig::default());
    arm.servo_faults(
        0,
        ServoFaults {
            drop: 0.2,
            corrupt: 0.2,
            late: 0.1,
            late_by: Duration::from_millis(3),
        },
        61,
    );
    let t0 = arm.now();
    for (k, target) in [20.0, -30.0, 40.0, -10.0, 5.0].into_iter().enumerate() {
        arm.line(Origin(1), &common::command("pan", target));
        arm.run_until(t0 + Duration::from_millis(800 * (k as u64 + 1)))
            .unwrap();
    }
    let out = common::run_for(&mut arm, Duration::ZERO);
    let results: Vec<&Value> = out
        .iter()
        .filter(|v| v.get("ok").is_some() && v.get("event").is_none())
        .collect();
    assert_eq!(results.len(), 5, "{out:?}");
    assert!(results.iter().all(|r| r["ok"] == true), "{results:?}");
    // 5° is step 2048 + 56.9 = 2105.
    assert_eq!(register(&arm, 0, 1, "Goal_Position"), 2105);
    assert!(
        out.iter().any(|v| v["event"] == "bad_servo_packet"),
        "corrupt packets are reported"
    );
    // Never offline: each lost status was asked again within its cycle.
    assert!(
        !out.iter()
            .any(|v| v["event"] == "offline" && v["motor_id"] == "pan"),
        "{out:?}"
    );
}

#[test]
fn a_silent_bus_takes_its_servos_offline_and_back() {
    let mut arm = servo_arm(BridgeConfig::default());
    arm.servo_faults(
        1,
        ServoFaults {
            drop: 1.0,
            ..ServoFaults::default()
        },
        1,
    );
    let out = common::run_for(&mut arm, Duration::from_secs(2));
    for motor in ["wrist", "shoulder"] {
        assert!(
            out.iter()
                .any(|v| v["event"] == "offline" && v["motor_id"] == motor),
            "{motor}: {out:?}"
        );
    }
    // The Feetech bus is another port: its servos stay online.
    assert!(
        !out.iter()
            .any(|v| v["event"] == "offline" && v["motor_id"] == "pan"),
        "{out:?}"
    );
    arm.line(Origin(1), &common::command("wrist", 0.2));
    let out = common::run_for(&mut arm, Duration::from_millis(200));
    let r = out
        .iter()
        .find(|v| v.get("ok").is_some() && v.get("event").is_none())
        .unwrap();
    assert_eq!(r["ok"], false, "{r}");
    assert_eq!(register(&arm, 1, 4, "Torque_Enable"), 0);
    arm.servo_faults(1, ServoFaults::default(), 1);
    let out = common::run_for(&mut arm, Duration::from_secs(1));
    assert!(
        out.iter()
            .any(|v| v["event"] == "online" && v["motor_id"] == "wrist"),
        "{out:?}"
    );
}
