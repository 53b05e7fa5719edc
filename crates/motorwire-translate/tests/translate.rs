//! The bus map, the safety gate and the command translations, on the demo
//! arm's map.
#![allow(clippy::unwrap_used, clippy::panic, clippy::indexing_slicing)]

use motorwire_irpc::{MotionProfile, Payload, SetTargetPayload, SetTargetPayloadV2, WireVersion};
use motorwire_translate::*;
use motorwire_wia::{MotorCommand, MultiAxisCommand};

fn demo() -> BusMap {
    BusMap::from_toml(include_str!("../../../fixtures/maps/demo-arm.toml")).unwrap()
}

fn cmd(json: &str) -> MotorCommand {
    serde_json::from_str(json).unwrap()
}

#[test]
fn the_demo_map_has_every_motor_where_the_issue_puts_it() {
    let map = demo();
    let names: Vec<&str> = map.motors().map(|m| m.name.as_str()).collect();
    assert_eq!(
        names,
        [
            "arm_extension",
            "elbow",
            "grasper_horizontal_servo",
            "grasper_rotation",
            "grasper_vertical",
            "gripper_axis",
            "lower_arm_actuator",
            "shoulder_pitch",
            "shoulder_roll",
            "turntable",
            "upper_arm_actuator"
        ]
    );
    let pitch = map.motor("shoulder_pitch").unwrap();
    assert_eq!(
        pitch.target,
        Target::Irpc {
            node: 0x10,
            wire: WireVersion::V2_0
        }
    );
    assert_eq!(pitch.limits.min_position, Some(-90.0));
    assert_eq!(pitch.limits.max_velocity, Some(120.0));
    assert_eq!(map.irpc_node(0x12).unwrap().name, "elbow");
    assert_eq!(
        map.motor("gripper_axis").unwrap().target,
        Target::Compact {
            node: 0x20,
            feedback_node: 0x420
        }
    );
    assert_eq!(
        map.orion_motor(motorwire_orion::Motor::Turntable)
            .unwrap()
            .name,
        "turntable"
    );
    for m in motorwire_orion::Motor::ALL {
        assert_eq!(map.orion_motor(m).unwrap().name, m.name());
    }
}

#[test]
fn bad_maps_are_refused_naming_motor_and_field() {
    let cases = [
        (
            "[motors.a]\ndialect = \"canopen\"",
            "bus map: motors.a.dialect: \"canopen\" is not irpc, compact, orion, moteus, feetech or dynamixel",
        ),
        (
            "[motors.a]\ndialect = \"irpc\"",
            "bus map: motors.a speaks irpc and needs node",
        ),
        (
            "[motors.a]\ndialect = \"irpc\"\nnode = 0",
            "bus map: motors.a.node: 0 is not a node id in 0x0001..=0xFFFE (0x0000 and 0xFFFF are broadcast)",
        ),
        (
            "[motors.a]\ndialect = \"irpc\"\nnode = 70000",
            "bus map: motors.a.node: 70000 is not a node id in 0x0001..=0xFFFE (0x0000 and 0xFFFF are broadcast)",
        ),
        (
            "[motors.a]\ndialect = \"irpc\"\nnode = 1\nwire = \"v3\"",
            "bus map: motors.a.wire: unknown iRPC wire version; expected v1, v2.0, v2.1 or v2.2",
        ),
        (
            "[motors.a]\ndialect = \"orion\"\nkey = \"XYZ\"",
            "bus map: motors.a.key: \"XYZ\" is not an Orion motor key (TRM, LAA, UAA, AEM, GVM, GRM, GHS)",
        ),
        (
            "[motors.a]\ndialect = \"orion\"\nkey = \"TRM\"\nnode = 3",
            "bus map: motors.a.node means nothing for a orion motor",
        ),
        (
            "[motors.a]\ndialect = \"compact\"\nnode = 0x20\nunit = \"grad\"",
            "bus map: motors.a.unit: \"grad\" is not deg or rad",
        ),
        (
            "[motors.a]\ndialect = \"compact\"\nnode = 0x20\nlimits = { max_velocity = -1 }",
            "bus map: motors.a.limits.max_velocity: -1 is not > 0",
        ),
        (
            "[motors.a]\ndialect = \"compact\"\nnode = 0x20\nlimits = { max_velocity = nan }",
            "bus map: motors.a.limits.max_velocity: NaN is not a finite number",
        ),
        (
            "[motors.a]\ndialect = \"compact\"\nnode = 0x20\nlimits = { min_position = 5, max_position = 1 }",
            "bus map: motors.a.limits: min_position 5 is above max_position 1",
        ),
        (
            "[motors.a]\ndialect = \"irpc\"\nnode = 3\n[motors.b]\ndialect = \"irpc\"\nnode = 3",
            "bus map: motors.a and motors.b are both iRPC node 0x03",
        ),
        (
            "[motors.a]\ndialect = \"compact\"",
            "bus map: motors.a speaks compact and needs node",
        ),
        (
            "[motors.a]\ndialect = \"compact\"\nnode = 0",
            "bus map: motors.a.node: 0 is not a CAN id in 0x001..=0x7FF (11 bits; 0x000 is the arm's)",
        ),
        (
            "[motors.a]\ndialect = \"compact\"\nnode = 0x20\nfeedback_node = 0x800",
            "bus map: motors.a.feedback_node: 2048 is not a CAN id in 0x001..=0x7FF (11 bits; 0x000 is the arm's)",
        ),
        (
            "[motors.a]\ndialect = \"compact\"\nnode = 0x400",
            "bus map: motors.a.feedback_node: 0x400 is the node itself (the device and its commands need different CAN ids; the default node | 0x400 is the node for nodes from 0x400)",
        ),
        (
            "[motors.a]\ndialect = \"irpc\"\nnode = 0x20\nfeedback_node = 0x21",
            "bus map: motors.a.feedback_node means nothing for a irpc motor",
        ),
        (
            "[motors.a]\ndialect = \"irpc\"\nnode = 0x420\n[motors.b]\ndialect = \"compact\"\nnode = 0x20",
            "bus map: motors.a and motors.b are both CAN id 0x420",
        ),
        (
            "[motors.a]\ndialect = \"compact\"\nnode = 0x20\n[motors.b]\ndialect = \"compact\"\nnode = 0x21\nfeedback_node = 0x20",
            "bus map: motors.a and motors.b are both CAN id 0x020",
        ),
        (
            "[motors.a]\ndialect = \"moteus\"",
            "bus map: motors.a speaks moteus and needs id",
        ),
        (
            "[motors.a]\ndialect = \"moteus\"\nid = 128",
            "bus map: motors.a.id: 128 is not a moteus id in 1..=127",
        ),
        (
            "[motors.a]\ndialect = \"moteus\"\nid = 1\nnode = 0x20",
            "bus map: motors.a.node means nothing for a moteus motor",
        ),
        (
            "[motors.a]\ndialect = \"moteus\"\nid = 1\nstop = \"coast\"",
            "bus map: motors.a.stop: \"coast\" is not stop or brake",
        ),
        (
            "[motors.a]\ndialect = \"compact\"\nnode = 0x20\nid = 1",
            "bus map: motors.a.id means nothing for a compact motor",
        ),
        (
            "[motors.a]\ndialect = \"moteus\"\nid = 3\n[motors.b]\ndialect = \"moteus\"\nid = 3",
            "bus map: motors.a and motors.b are both moteus id 3 on bus 0",
        ),
        (
            "[motors.a]\ndialect = \"feetech\"\nport = \"/dev/ttyACM0\"\nmodel = \"sts3215\"",
            "bus map: motors.a speaks feetech and needs id",
        ),
        (
            "[motors.a]\ndialect = \"feetech\"\nport = \"/dev/ttyACM0\"\nmodel = \"sts3215\"\nid = 253",
            "bus map: motors.a.id: 253 is not a servo id in 0..=252",
        ),
        (
            "[motors.a]\ndialect = \"feetech\"\nport = \"/dev/ttyACM0\"\nid = 1\nmodel = \"xl330-m288\"",
            "bus map: motors.a.model: \"xl330-m288\" is not a feetech model the bridge drives (sts3215)",
        ),
        (
            "[motors.a]\ndialect = \"feetech\"\nport = \"/dev/ttyACM0\"\nmodel = \"sts3215\"\nid = 1\ncalibration = { homing_offset = 0, range_min = 3000, range_max = 1000 }",
            "bus map: motors.a.calibration: range_min 3000 is not below range_max 1000",
        ),
        (
            "[motors.a]\ndialect = \"feetech\"\nport = \"/dev/ttyACM0\"\nmodel = \"sts3215\"\nid = 1\ncalibration = { homing_offset = 0, range_min = 0, range_max = 4096 }",
            "bus map: motors.a.calibration.range_max: 4096 is not a step of a sts3215 (0..=4095)",
        ),
        (
            "[motors.a]\ndialect = \"feetech\"\nport = \"/dev/ttyACM0\"\nmodel = \"sts3215\"\nid = 1\ncalibration = { homing_offset = 5000, range_min = 0, range_max = 4095 }",
            "bus map: motors.a.calibration.homing_offset: 5000 does not fit the servo's Homing_Offset register",
        ),
        (
            "[motors.a]\ndialect = \"feetech\"\nport = \"/dev/ttyACM0\"\nmodel = \"sts3215\"\nid = 1\ncalibration = { homing_offset = 0, range_min = 1048, range_max = 3048 }\nlimits = { max_position = 90 }",
            "bus map: motors.a.limits.max_position: 90 is outside the servo's calibrated range -87.91208791208791..=87.91208791208791",
        ),
        (
            "[motors.a]\ndialect = \"feetech\"\nport = \"/dev/ttyACM0\"\nmodel = \"sts3215\"\nid = 1\n[motors.b]\ndialect = \"feetech\"\nport = \"/dev/ttyACM0\"\nmodel = \"sts3215\"\nid = 1",
            "bus map: motors.a and motors.b are both servo id 1 on /dev/ttyACM0",
        ),
        (
            "[motors.a]\ndialect = \"feetech\"\nport = \"/dev/ttyACM0\"\nmodel = \"sts3215\"\nid = 1\n[motors.b]\ndialect = \"dynamixel\"\nport = \"/dev/ttyACM0\"\nmodel = \"xl330-m288\"\nid = 2",
            "bus map: motors.b.model: a xl330-m288 speaks dxl2, where another servo of /dev/ttyACM0 speaks scs0: one bus, one protocol",
        ),
        (
            "[motors.a]\ndialect = \"feetech\"\nport = \"/dev/ttyACM0\"\nmodel = \"sts3215\"\nid = 1\n[motors.b]\ndialect = \"feetech\"\nport = \"/dev/ttyACM0\"\nmodel = \"sts3215\"\nid = 2\nbaud = 115200",
            "bus map: motors.b.baud: 115200, where another servo of /dev/ttyACM0 says 1000000: one bus, one baud rate",
        ),
        (
            "[motors.a]\ndialect = \"feetech\"\nport = \"/dev/ttyACM0\"\nmodel = \"sts3215\"\nid = 1\nnode = 3",
            "bus map: motors.a.node means nothing for a feetech motor",
        ),
        (
            "[motors.a]\ndialect = \"moteus\"\nid = 1\nport = \"/dev/ttyACM0\"",
            "bus map: motors.a.port means nothing for a moteus motor",
        ),
        (
            "[motors.a]\ndialect = \"feetech\"\nport = \"/dev/ttyACM0\"\nmodel = \"sts3215\"\nid = 1\nstop = \"brake\"",
            "bus map: motors.a.stop: \"brake\" is not torque_off or hold",
        ),
        (
            "[motors.\"a b\"]\ndialect = \"compact\"",
            "bus map: motor name \"a b\" is not a WIA motor_id (letters, digits, _ and -, at most 64 bytes)",
        ),
    ];
    for (text, message) in cases {
        let err = BusMap::from_toml(text).unwrap_err();
        assert_eq!(err.to_string(), message, "{text}");
    }
    // Typos and wrong types come from the TOML reader, with the place.
    let typo = BusMap::from_toml("[motors.a]\ndialect = \"compact\"\nnode = 0x20\nlimit = {}")
        .unwrap_err();
    assert!(
        matches!(&typo, MapError::Toml { message } if message.contains("unknown field `limit`")),
        "{typo}"
    );
    let wrong = BusMap::from_toml("[motors.a]\ndialect = 5").unwrap_err();
    assert!(
        matches!(&wrong, MapError::Toml { message } if message.contains("line 2")),
        "{wrong}"
    );
}

#[test]
fn position_commands_become_set_target_v2_with_the_maps_limits() {
    let map = demo();
    let t = to_irpc(
        &map,
        &cmd(r#"{"motor_id":"elbow","timestamp":1,"control_mode":"position","setpoint":90,"velocity_limit":60}"#),
    )
    .unwrap();
    assert_eq!(t.value.node, 0x12);
    assert_eq!(
        t.value.payloads,
        [Payload::SetTargetV2(SetTargetPayloadV2 {
            target_angle: 90.0,
            max_velocity: 60.0,
            target_velocity: 0.0,
            max_acceleration: 500.0,
            max_deceleration: 400.0,
            max_jerk: 2000.0,
            profile: MotionProfile::SCurve,
            max_current: 0.0,
            max_temperature: 0.0,
        })]
    );
    let fields: Vec<(&str, LossKind)> = t
        .report
        .losses
        .iter()
        .map(|l| (l.field.as_ref(), l.kind))
        .collect();
    assert_eq!(
        fields,
        [
            ("max_acceleration", LossKind::Defaulted),
            ("max_deceleration", LossKind::Defaulted),
            ("max_jerk", LossKind::Defaulted)
        ]
    );
    // Radians are converted to degrees, and said so; v1 gets SetTarget and
    // drops what it has no place for.
    let rad = BusMap::from_toml(
        "[motors.j]\ndialect = \"irpc\"\nnode = 5\nwire = \"v1\"\nunit = \"rad\"\nlimits = { max_velocity = 2 }",
    )
    .unwrap();
    let t = to_irpc(
        &rad,
        &cmd(r#"{"motor_id":"j","timestamp":1,"control_mode":"position","setpoint":1.5,"acceleration_limit":3,"pid_gains":{"kp":1}}"#),
    )
    .unwrap();
    assert_eq!(
        t.value.payloads,
        [Payload::SetTarget(SetTargetPayload {
            target_angle: 1.5f64.to_degrees() as f32,
            velocity_limit: 2f64.to_degrees() as f32,
        })]
    );
    let text: Vec<String> = t.report.losses.iter().map(ToString::to_string).collect();
    assert_eq!(
        text,
        [
            "setpoint: converted: radians to degrees (iRPC's unit)",
            "max_velocity: defaulted: 2 from the bus map",
            format!(
                "setpoint: converted: {} rounded to the f32 {}",
                1.5f64.to_degrees(),
                1.5f64.to_degrees() as f32
            )
            .as_str(),
            format!(
                "velocity_limit: converted: {} rounded to the f32 {}",
                2f64.to_degrees(),
                2f64.to_degrees() as f32
            )
            .as_str(),
            "acceleration_limit: dropped: SetTarget (iRPC v1) has no place for it",
            "pid_gains: dropped: SetTarget (iRPC v1) has no place for it",
        ]
    );
}

#[test]
fn the_gate_refuses_naming_limit_and_value() {
    let map = demo();
    let refusals = [
        (
            r#"{"motor_id":"shoulder_pitch","timestamp":1,"control_mode":"position","setpoint":95}"#,
            "shoulder_pitch: setpoint 95 is outside max_position (bus map) 90",
        ),
        (
            r#"{"motor_id":"shoulder_roll","timestamp":1,"control_mode":"position","setpoint":-50}"#,
            "shoulder_roll: setpoint -50 is outside min_position (bus map) -45",
        ),
        (
            r#"{"motor_id":"elbow","timestamp":1,"control_mode":"position","setpoint":100,"safety_limits":{"max_position":80}}"#,
            "elbow: setpoint 100 is outside max_position (command) 80",
        ),
        (
            r#"{"motor_id":"elbow","timestamp":1,"control_mode":"position","setpoint":100,"safety_limits":{"max_position":200}}"#,
            "",
        ),
        (
            r#"{"motor_id":"shoulder_pitch","timestamp":1,"control_mode":"position","setpoint":10,"velocity_limit":150}"#,
            "shoulder_pitch: velocity_limit 150 is outside max_velocity (bus map) 120",
        ),
        (
            r#"{"motor_id":"shoulder_pitch","timestamp":1,"control_mode":"position","setpoint":10,"acceleration_limit":501}"#,
            "shoulder_pitch: acceleration_limit 501 is outside max_acceleration (bus map) 500",
        ),
        (
            r#"{"motor_id":"wrist","timestamp":1,"control_mode":"position","setpoint":10}"#,
            "motor \"wrist\" is not in the bus map",
        ),
        (
            r#"{"motor_id":"elbow","timestamp":1,"control_mode":"velocity","setpoint":10}"#,
            "elbow: iRPC cannot express control mode velocity",
        ),
        (
            r#"{"motor_id":"gripper_axis","timestamp":1,"control_mode":"position","setpoint":10}"#,
            "gripper_axis: iRPC (the bus map says this motor is not an iRPC joint) cannot express control mode position",
        ),
    ];
    for (json, message) in refusals {
        match to_irpc(&map, &cmd(json)) {
            Err(e) => assert_eq!(e.to_string(), message, "{json}"),
            Ok(t) => assert_eq!(message, "", "{json} passed: {t:?}"),
        }
    }
    // Non-finite values cannot come from JSON, but can from Rust.
    let mut nan =
        cmd(r#"{"motor_id":"elbow","timestamp":1,"control_mode":"position","setpoint":10}"#);
    nan.setpoint = f64::NAN;
    assert_eq!(
        gate(&map, &nan).unwrap_err(),
        Refusal::NonFinite {
            motor: "elbow".into(),
            field: "setpoint"
        }
    );
    // The limits are in the refusal for a program to read.
    let err = to_irpc(
        &map,
        &cmd(r#"{"motor_id":"elbow","timestamp":1,"control_mode":"position","setpoint":151}"#),
    )
    .unwrap_err();
    assert_eq!(
        err,
        Refusal::OutsideLimit {
            motor: "elbow".into(),
            field: "setpoint",
            value: 151.0,
            limit: "max_position",
            limit_source: "bus map",
            bound: 150.0
        }
    );
}

#[test]
fn disabled_and_emergency_stop_deactivate_the_joint() {
    let map = demo();
    let off = to_irpc(
        &map,
        &cmd(r#"{"motor_id":"elbow","timestamp":1,"control_mode":"disabled","setpoint":0}"#),
    )
    .unwrap();
    assert_eq!(off.value.payloads, [Payload::Deactivate]);
    assert!(off.report.is_exact());
    // An emergency stop is never refused for what it carries: stopping is
    // always safe (here a setpoint far outside the elbow's limits).
    let stop = to_irpc(
        &map,
        &cmd(r#"{"motor_id":"elbow","timestamp":1,"control_mode":"position","setpoint":1000,"safety_limits":{"emergency_stop":true}}"#),
    )
    .unwrap();
    assert_eq!(stop.value.payloads, [Payload::Deactivate]);
    assert_eq!(
        stop.report.losses[0].to_string(),
        "setpoint: dropped: emergency stop: the joint is deactivated instead of moved"
    );
}

#[test]
fn compact_commands_carry_what_24_bytes_can() {
    let map = demo();
    let t = to_compact(
        &map,
        &cmd(r#"{"motor_id":"gripper_axis","timestamp":1704067200000,"control_mode":"position","setpoint":45.5,"velocity_limit":30,"torque_limit":2,"priority":90,"safety_limits":{"emergency_stop":true,"max_torque":4}}"#),
    )
    .unwrap();
    let c = t.value;
    assert_eq!(c.motor, motorwire_compact::MotorHash::of("gripper_axis"));
    assert_eq!(c.timestamp_ms, 1_704_067_200_000);
    assert_eq!(
        c.flags,
        motorwire_compact::Flags::EMERGENCY_STOP.union(motorwire_compact::Flags::PRIORITY_HIGH)
    );
    let text: Vec<String> = t.report.losses.iter().map(ToString::to_string).collect();
    assert_eq!(
        text,
        [
            "priority: converted: to the PRIORITY_HIGH flag (set from 75)",
            "safety_limits: dropped: only emergency_stop has a place (the EMERGENCY_STOP flag)",
        ]
    );
    assert_eq!(
        to_compact(
            &map,
            &cmd(
                r#"{"motor_id":"gripper_axis","timestamp":1,"control_mode":"torque","setpoint":6}"#
            )
        )
        .unwrap_err()
        .to_string(),
        "gripper_axis: setpoint 6 is outside max_torque (bus map) 5"
    );
}

#[test]
fn multi_axis_commands_become_orion_direct_control() {
    let map = demo();
    let multi: MultiAxisCommand = serde_json::from_str(
        r#"{"command_id":"c1","timestamp":1,"sync_mode":"independent","motors":[
            {"motor_id":"turntable","control_mode":"velocity","setpoint":200},
            {"motor_id":"lower_arm_actuator","control_mode":"velocity","setpoint":-1},
            {"motor_id":"grasper_horizontal_servo","control_mode":"position","setpoint":-30},
            {"motor_id":"arm_extension","control_mode":"disabled","setpoint":0}
        ]}"#,
    )
    .unwrap();
    let t = to_orion(&map, &multi).unwrap();
    assert_eq!(
        t.value.to_json(),
        r#"{"ID":32,"MODE":1,"DATA":{"TRM":200,"LAA":-1,"AEM":0,"GHS":-30}}"#
    );
    assert_eq!(
        t.report.losses[0].to_string(),
        "sync_mode: dropped: Orion direct control has no place for it"
    );
    // Beyond the document's range is refused, not left to the controller to clamp.
    let too_fast: MultiAxisCommand = serde_json::from_str(
        r#"{"command_id":"c2","timestamp":1,"motors":[{"motor_id":"turntable","control_mode":"velocity","setpoint":-500}]}"#,
    )
    .unwrap();
    assert_eq!(
        to_orion(&map, &too_fast).unwrap_err().to_string(),
        "turntable: setpoint -500 is outside max_velocity (Orion range) 400"
    );
    let servo: MultiAxisCommand = serde_json::from_str(
        r#"{"command_id":"c3","timestamp":1,"motors":[{"motor_id":"grasper_horizontal_servo","control_mode":"position","setpoint":120}]}"#,
    )
    .unwrap();
    assert_eq!(
        to_orion(&map, &servo).unwrap_err().to_string(),
        "grasper_horizontal_servo: setpoint 120 is outside max_position (bus map) 90"
    );
    let estop: MultiAxisCommand = serde_json::from_str(
        r#"{"command_id":"c4","timestamp":1,"motors":[{"motor_id":"turntable","control_mode":"velocity","setpoint":10,"safety_limits":{"emergency_stop":true}}]}"#,
    )
    .unwrap();
    assert_eq!(
        to_orion(&map, &estop).unwrap().value.to_json(),
        r#"{"ID":32,"MODE":2,"DATA":1}"#
    );
}

mod gate_property {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// Whatever a command asks, what passes the gate is within every
        /// limit of the map, and nothing panics.
        #[test]
        fn nothing_outside_the_limits_passes(
            motor in prop::sample::select(vec!["shoulder_pitch", "shoulder_roll", "elbow", "gripper_axis", "turntable", "nobody"]),
            mode in prop::sample::select(vec!["position", "velocity", "torque", "disabled", "impedance"]),
            setpoint in -1e4f64..1e4,
            velocity in proptest::option::of(0.0f64..500.0),
            own_max in proptest::option::of(-200.0f64..200.0),
        ) {
            let map = demo();
            let mut json = serde_json::json!({
                "motor_id": motor, "timestamp": 1, "control_mode": mode, "setpoint": setpoint,
            });
            if let Some(v) = velocity {
                json["velocity_limit"] = v.into();
            }
            if let Some(m) = own_max {
                json["safety_limits"] = serde_json::json!({ "max_position": m });
            }
            let cmd: MotorCommand = serde_json::from_value(json).unwrap();
            if let Ok((m, _)) = gate(&map, &cmd) {
                let l = m.limits;
                if mode == "position" {
                    prop_assert!(l.min_position.is_none_or(|lo| setpoint >= lo));
                    prop_assert!(l.max_position.is_none_or(|hi| setpoint <= hi));
                    prop_assert!(own_max.is_none_or(|hi| setpoint <= hi));
                }
                if mode == "velocity" {
                    prop_assert!(l.max_velocity.is_none_or(|v| setpoint.abs() <= v));
                }
                if mode == "torque" {
                    prop_assert!(l.max_torque.is_none_or(|t| setpoint.abs() <= t));
                }
                prop_assert!(velocity.is_none_or(|v| l.max_velocity.is_none_or(|max| v <= max)));
            }
            if let Ok(t) = to_irpc(&map, &cmd) {
                for p in &t.value.payloads {
                    if let Payload::SetTargetV2(p) = p {
                        let l = map.irpc_node(t.value.node).unwrap().limits;
                        prop_assert!(f64::from(p.target_angle) >= l.min_position.unwrap() - 1e-4);
                        prop_assert!(f64::from(p.target_angle) <= l.max_position.unwrap() + 1e-4);
                        prop_assert!(f64::from(p.max_velocity) <= l.max_velocity.unwrap() + 1e-4);
                    }
                }
            }
        }
    }
}

#[test]
fn an_orion_servo_in_radians_is_held_to_its_range_in_radians() {
    let map = BusMap::from_toml(
        r#"
        [motors.grasper_horizontal_servo]
        dialect = "orion"
        key = "GHS"
        unit = "rad"
    "#,
    )
    .unwrap();
    let servo = |setpoint: f64| -> MultiAxisCommand {
        serde_json::from_str(&format!(
            r#"{{"command_id":"c","timestamp":1,"motors":[{{"motor_id":"grasper_horizontal_servo","control_mode":"position","setpoint":{setpoint}}}]}}"#
        ))
        .unwrap()
    };
    // 180 rad is 10,313°: outside ±180°, which is ±π rad.
    assert_eq!(
        to_orion(&map, &servo(180.0)).unwrap_err().to_string(),
        "grasper_horizontal_servo: setpoint 180 is outside max_position (Orion range) 3.141592653589793"
    );
    assert_eq!(
        to_orion(&map, &servo(-3.2)).unwrap_err().to_string(),
        "grasper_horizontal_servo: setpoint -3.2 is outside min_position (Orion range) -3.141592653589793"
    );
    assert_eq!(
        to_orion(&map, &servo(std::f64::consts::FRAC_PI_2))
            .unwrap()
            .value
            .to_json(),
        r#"{"ID":32,"MODE":1,"DATA":{"GHS":90}}"#
    );
}

#[test]
fn hostile_maps_are_errors_not_crashes() {
    let deep = format!("x = {}1{}", "[".repeat(100_000), "]".repeat(100_000));
    assert!(matches!(
        BusMap::from_toml(&deep),
        Err(MapError::Toml { .. })
    ));
    let inline = format!("x = {}1{}", "{a = ".repeat(100_000), "}".repeat(100_000));
    assert!(matches!(
        BusMap::from_toml(&inline),
        Err(MapError::Toml { .. })
    ));
    assert!(matches!(
        BusMap::from_toml("\u{0}"),
        Err(MapError::Toml { .. })
    ));
    assert_eq!(BusMap::from_toml("").unwrap().motors().count(), 0);
}

#[test]
fn irpc_frames_number_and_pad_and_refuse_what_cannot_be_framed() {
    // Two payloads: msg_ids 7 and 8, the counter left at 9.
    let command = IrpcCommand {
        node: 0x12,
        wire: WireVersion::V2_0,
        payloads: vec![Payload::Activate, Payload::Deactivate],
    };
    let mut msg_id = 7;
    let frames = irpc_frames("elbow", &command, 0x0000, &mut msg_id).unwrap();
    assert_eq!(
        frames,
        [
            IrpcFrame {
                can_id: 0x000,
                msg_id: 7,
                data: vec![0x00, 0x12, 0x07, 0x02]
            },
            IrpcFrame {
                can_id: 0x000,
                msg_id: 8,
                data: vec![0x00, 0x12, 0x08, 0x03]
            },
        ]
    );
    assert_eq!(msg_id, 9);
    // A source that is not an 11-bit CAN id, and a payload the wire version
    // does not have: refused, the counter untouched.
    let e = irpc_frames("elbow", &command, 0x800, &mut msg_id).unwrap_err();
    assert_eq!(
        e.to_string(),
        "elbow: source node 0x800 is above 0x7FF: it is the frames' 11-bit CAN id"
    );
    assert_eq!(e.rule(), "not_representable");
    let v1 = IrpcCommand {
        node: 0x12,
        wire: WireVersion::V1,
        payloads: vec![
            Payload::Activate,
            Payload::SetTargetV2(SetTargetPayloadV2::scurve(90.0, 100.0, 500.0, 2000.0)),
        ],
    };
    let e = irpc_frames("elbow", &v1, 0x0000, &mut msg_id).unwrap_err();
    assert!(
        matches!(&e, Refusal::NotRepresentable { field: "payload", problem, .. } if problem.starts_with("SetTargetV2 in iRPC v1: ")),
        "{e}"
    );
    assert_eq!(msg_id, 9);
}

#[test]
fn with_wire_makes_every_joint_speak_one_version() {
    let map = demo().with_wire(WireVersion::V1);
    let t = to_irpc(
        &map,
        &cmd(
            r#"{"motor_id":"elbow","timestamp":0,"control_mode":"position","setpoint":90,"velocity_limit":100}"#,
        ),
    )
    .unwrap();
    assert_eq!(t.value.wire, WireVersion::V1);
    assert_eq!(
        t.value.payloads,
        [Payload::SetTarget(SetTargetPayload {
            target_angle: 90.0,
            velocity_limit: 100.0
        })]
    );
    // Nothing but the wire version changes.
    assert_eq!(
        map.motor("gripper_axis").unwrap(),
        demo().motor("gripper_axis").unwrap()
    );
    assert_eq!(
        map.motor("elbow").unwrap().limits,
        demo().motor("elbow").unwrap().limits
    );
}

#[test]
fn every_refusal_names_a_rule_of_the_list_and_says_its_values() {
    let m = || "elbow".to_owned();
    let all = [
        Refusal::UnknownMotor { motor: m() },
        Refusal::NonFinite {
            motor: m(),
            field: "setpoint",
        },
        Refusal::OutsideLimit {
            motor: m(),
            field: "setpoint",
            value: 170.0,
            limit: "max_position",
            limit_source: "bus map",
            bound: 150.0,
        },
        Refusal::ModeNotExpressible {
            motor: m(),
            mode: "torque",
            dialect: "iRPC",
        },
        Refusal::MissingLimit {
            motor: m(),
            dialect: "iRPC",
            field: "max_velocity",
        },
        Refusal::NotRepresentable {
            motor: m(),
            field: "setpoint",
            problem: "too large".into(),
        },
        Refusal::UnknownPosition { motor: m() },
        Refusal::Infeasible {
            motor: m(),
            waypoint: 1,
            problem: "late".into(),
        },
        Refusal::Unsynchronizable {
            problem: "no".into(),
        },
        Refusal::PathOutsideLimit {
            motor: m(),
            segment: Some(0),
            limit: "max_position",
            limit_source: "command",
            bound: 150.0,
            extreme: 155.0,
            overshoot: 5.0,
            at: 0.25,
        },
        Refusal::Unplannable {
            motor: m(),
            segment: None,
            problem: "zero".into(),
        },
    ];
    let rules: Vec<&str> = all.iter().map(Refusal::rule).collect();
    assert_eq!(rules, Refusal::RULES);
    let d = all[9].detail();
    assert_eq!(
        (d.motor, d.field, d.value, d.limit, d.bound, d.source),
        (
            Some("elbow"),
            Some("path"),
            Some(155.0),
            Some("max_position"),
            Some(150.0),
            Some("command")
        )
    );
    assert_eq!(
        all[9].to_string(),
        "elbow: segment 0 (counted from 0): the planned path reaches 155 past max_position (command) 150 by 5 (0.25 s into the move)"
    );
    assert_eq!(
        all[8].detail(),
        motorwire_translate::RefusalDetail::default()
    );
    assert_eq!(all[4].detail().limit, Some("max_velocity"));
    assert_eq!(all[1].detail().field, Some("setpoint"));
}
