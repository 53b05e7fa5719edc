//! Telemetry, power metrics, fault history and calibration through the
//! bridge (v2.1 and v2.2 joints, in simulated time): the subscription at
//! startup, WIA feedback carrying what TelemetryStream reports, request
//! lines answered as JSON (messages over one frame travel segmented), and
//! calibration with progress events.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing
)]

mod common;

use std::time::Duration;

use motorwire_bridge::sim::SimulatedArm;
use motorwire_bridge::{Bridge, BridgeConfig, DeviceState, Origin};
use motorwire_can::{Faults, SimConfig};
use motorwire_irpc::Payload;
use motorwire_sim::JointFault;
use motorwire_translate::BusMap;
use serde_json::{Value, json};

const MAP: &str = r#"
[motors.elbow]
dialect = "irpc"
node = 0x12
wire = "v2.2"
limits = { min_position = 0, max_position = 150, max_velocity = 120, max_acceleration = 500, max_jerk = 2000 }

[motors.wrist]
dialect = "irpc"
node = 0x13
wire = "v2.1"
limits = { min_position = -90, max_position = 90, max_velocity = 120, max_acceleration = 500 }

[motors.base]
dialect = "irpc"
node = 0x14
wire = "v2.0"
"#;

const ELBOW: u16 = 0x12;

fn telemetry_arm(telemetry_hz: Option<u16>, faults: Faults) -> SimulatedArm {
    let config = BridgeConfig {
        telemetry_hz,
        feedback_period: Some(Duration::from_millis(50)),
        ..BridgeConfig::default()
    };
    let sim = SimConfig {
        seed: 7,
        faults,
        ..SimConfig::default()
    };
    common::ready(MAP, config, sim)
}

/// Every output line until `n` results are in (at most `limit`).
fn until_results(arm: &mut SimulatedArm, n: usize, limit: Duration) -> Vec<Value> {
    let mut got = Vec::new();
    let end = arm.now() + limit;
    while got.iter().filter(|v: &&Value| is_result(v)).count() < n && arm.now() < end {
        arm.step(Duration::from_millis(5)).unwrap();
        got.extend(arm.take_outputs().iter().map(|o| o.to_value()));
    }
    got
}

fn is_result(v: &Value) -> bool {
    v.get("ok").is_some() && v.get("event").is_none()
}

fn result(out: &[Value], line: u64) -> &Value {
    out.iter()
        .find(|v| v["line"] == line && is_result(v))
        .unwrap_or_else(|| panic!("no result for line {line}: {out:?}"))
}

#[test]
fn v2_1_and_v2_2_joints_are_subscribed_and_their_feedback_carries_the_telemetry() {
    let mut arm = telemetry_arm(Some(50), Faults::default());
    // Subscribed at startup: before any request, the joints' feedback
    // carries what only TelemetryStream reports.
    arm.run_until(arm.now() + Duration::from_millis(200))
        .unwrap();
    for name in ["elbow", "wrist"] {
        let f = arm
            .bridge()
            .joints()
            .find(|j| j.name == name)
            .unwrap()
            .feedback
            .unwrap();
        assert_eq!(f.temperature.map(|t| t.round()), Some(25.0), "{name}");
        assert_eq!(f.control_effort, Some(0.0), "{name}");
    }
    arm.line(
        Origin(1),
        r#"{"motor_id":"elbow","timestamp":0,"control_mode":"position","setpoint":60}"#,
    );
    // Mid-move: accelerating, drawing current, warming.
    let mut moving = None;
    let end = arm.now() + Duration::from_secs(2);
    while arm.now() < end && moving.is_none() {
        arm.step(Duration::from_millis(5)).unwrap();
        for o in arm.take_outputs() {
            let v = o.to_value();
            if v["motor_id"] == "elbow"
                && v["feedback"]["current"]
                    .as_f64()
                    .is_some_and(|c| c.abs() > 0.1)
            {
                moving = Some(v);
            }
        }
    }
    let v = moving.expect("feedback with current while the elbow accelerates");
    let f = &v["feedback"];
    for field in [
        "acceleration",
        "torque",
        "current",
        "voltage",
        "temperature",
        "power",
        "control_effort",
    ] {
        assert!(f[field].is_number(), "{field}: {v}");
    }
    // The motion model: torque = inertia · α and i_q = torque / k_t.
    let torque = f["torque"].as_f64().unwrap();
    let current = f["current"].as_f64().unwrap();
    assert!(
        (current - torque / motorwire_sim::joint::TORQUE_CONSTANT).abs()
            < 1e-3 * current.abs().max(1.0),
        "{v}"
    );
    // A v2.0 joint has no telemetry: its feedback carries none of it.
    let base = arm
        .bridge()
        .joints()
        .find(|j| j.name == "base")
        .unwrap()
        .feedback
        .unwrap();
    assert_eq!((base.current, base.power), (None, None));
}

/// What each joint's `JointStatus` says reaches `Bridge::joints` in the
/// engine's own words: every joint `Active` once started; a faulted one
/// `Error` and no longer held active; the others `Inactive`, as the stop
/// the v2.2 elbow's own emergency stop brings left them.
#[test]
fn each_joints_lifecycle_is_shown_in_the_engines_terms() {
    let mut arm = telemetry_arm(Some(50), Faults::default());
    let states = |arm: &SimulatedArm| -> Vec<(String, Option<DeviceState>, bool)> {
        arm.bridge()
            .joints()
            .map(|j| (j.name, j.state, j.active))
            .collect()
    };
    let before = states(&arm);
    for (name, state, active) in &before {
        assert_eq!(
            (*state, *active),
            (Some(DeviceState::Active), true),
            "{name}"
        );
    }
    arm.fault(ELBOW, JointFault::DriverFault);
    let out = common::run_for(&mut arm, Duration::from_millis(100));
    assert!(out.iter().any(|v| v["event"] == "joint_fault"), "{out:?}");
    let after = states(&arm);
    let elbow = after.iter().find(|(n, ..)| n == "elbow").unwrap();
    assert_eq!((elbow.1, elbow.2), (Some(DeviceState::Error), false));
    assert_eq!(elbow.1.map(DeviceState::name), Some("error"));
    for (name, state, active) in after.iter().filter(|(n, ..)| n != "elbow") {
        assert_eq!(
            (*state, *active),
            (Some(DeviceState::Inactive), false),
            "{name}"
        );
    }
}

#[test]
fn request_lines_are_answered_with_what_the_joint_sent_exactly() {
    let mut arm = telemetry_arm(None, Faults::default());
    arm.fault(ELBOW, JointFault::DriverFault);
    let out = common::run_for(&mut arm, Duration::from_millis(100));
    assert!(out.iter().any(|v| v["event"] == "joint_fault"), "{out:?}");
    // Read-only requests are answered in every state, Error included.
    arm.line(
        Origin(1),
        r#"{"request":"fault_history","motor_id":"elbow"}"#,
    );
    arm.line(
        Origin(1),
        r#"{"request":"power_metrics","motor_id":"elbow"}"#,
    );
    arm.line(Origin(1), r#"{"request":"telemetry","motor_id":"wrist"}"#);
    arm.line(
        Origin(1),
        r#"{"request":"power_metrics","motor_id":"wrist"}"#,
    );
    arm.line(Origin(1), r#"{"request":"telemetry","motor_id":"base"}"#);
    arm.line(Origin(1), r#"{"request":"energy","motor_id":"elbow"}"#);
    let out = until_results(&mut arm, 6, Duration::from_secs(3));
    let history = result(&out, 1);
    assert_eq!(history["ok"], true, "{history}");
    let expected = arm.joint(ELBOW).unwrap().fault_history();
    assert_eq!(
        history["data"]["fault_history"]["total_faults"],
        json!(expected.total_faults)
    );
    assert_eq!(history["data"]["fault_history"]["valid_count"], 1);
    // Driver fault: the EmergencyReason number 5.
    assert_eq!(
        history["data"]["fault_history"]["records"][0]["fault_type"],
        5
    );
    let power = result(&out, 2);
    assert_eq!(power["ok"], true, "{power}");
    assert_eq!(power["data"]["power_metrics"]["vbus_mv"], 24000);
    assert_eq!(power["data"]["power_metrics"]["faults"]["driver_fault"], 1);
    let telemetry = result(&out, 3);
    assert_eq!(telemetry["data"]["telemetry"]["foc_loop_time_us"], 50);
    assert_eq!(telemetry["data"]["telemetry"]["temperature_c"], 25.0);
    assert_eq!(
        result(&out, 4)["error"],
        json!({"kind":"unsupported","rule":"unsupported","message":"wrist speaks iRPC v2.1, which has no PowerMetrics (v2.2)","motor":"wrist"})
    );
    assert_eq!(
        result(&out, 5)["error"]["message"],
        "base speaks iRPC v2.0, which has no TelemetryStream (v2.1 on)"
    );
    assert_eq!(result(&out, 6)["error"]["kind"], "invalid");
}

#[test]
fn calibration_streams_progress_and_its_result_ends_the_line() {
    let mut arm = telemetry_arm(None, Faults::default());
    // Calibration needs the joint Inactive; an Active joint refuses it.
    arm.line(Origin(1), r#"{"calibration":"start","motor_id":"wrist"}"#);
    let out = until_results(&mut arm, 1, Duration::from_secs(1));
    assert_eq!(result(&out, 1)["outcomes"][0]["code"], 20, "{out:?}");
    arm.line(
        Origin(1),
        r#"{"motor_id":"wrist","timestamp":0,"control_mode":"disabled","setpoint":0}"#,
    );
    arm.line(
        Origin(1),
        r#"{"calibration":"start","motor_id":"wrist","phases":3,"phase_timeout":2}"#,
    );
    let out = until_results(&mut arm, 2, Duration::from_secs(5));
    let done = result(&out, 3);
    assert_eq!(done["ok"], true, "{done}");
    let r = &done["data"]["calibration_result"];
    assert_eq!(r["success"], true);
    assert_eq!(r["total_time"], 1.0);
    assert_eq!(r["parameters"]["inertia"], 0.01);
    let phases: Vec<&str> = out
        .iter()
        .filter(|v| v["event"] == "calibration")
        .map(|v| v["phase"].as_str().unwrap())
        .collect();
    assert_eq!(phases.first(), Some(&"inertia_test"), "{phases:?}");
    assert!(phases.contains(&"friction_test"), "{phases:?}");
    assert_eq!(phases.last(), Some(&"complete"), "{phases:?}");
    // Started again and stopped: the start line fails with the abort.
    arm.line(Origin(1), r#"{"calibration":"start","motor_id":"wrist"}"#);
    let _ = common::run_for(&mut arm, Duration::from_millis(300));
    arm.line(Origin(1), r#"{"calibration":"stop","motor_id":"wrist"}"#);
    let out = until_results(&mut arm, 2, Duration::from_secs(3));
    assert_eq!(result(&out, 5)["ok"], true, "{out:?}");
    let aborted = result(&out, 4);
    assert_eq!(aborted["ok"], false, "{aborted}");
    assert_eq!(aborted["error"]["kind"], "no_answer");
    assert_eq!(
        aborted["error"]["message"],
        format!(
            "wrist: the calibration failed (error code 0x{:X})",
            motorwire_sim::joint::CALIBRATION_ABORTED
        )
    );
    assert_eq!(aborted["data"]["calibration_result"]["success"], false);
    // A v2.0 joint has no calibration.
    arm.line(Origin(1), r#"{"calibration":"start","motor_id":"base"}"#);
    let out = until_results(&mut arm, 1, Duration::from_secs(1));
    assert_eq!(result(&out, 6)["error"]["kind"], "unsupported");
}

#[test]
fn requests_through_a_faulty_bus_are_answered_or_say_no_answer_never_hang() {
    let faults = Faults {
        drop: 0.1,
        duplicate: 0.1,
        reorder: 0.1,
        ..Faults::default()
    };
    let mut arm = telemetry_arm(Some(20), faults);
    let n = 40;
    for i in 0..n {
        let line = if i % 2 == 0 {
            r#"{"request":"fault_history","motor_id":"elbow"}"#
        } else {
            r#"{"request":"telemetry","motor_id":"wrist"}"#
        };
        arm.line(Origin(1), line);
    }
    let out = until_results(&mut arm, n, Duration::from_secs(30));
    let results: Vec<&Value> = out.iter().filter(|v| is_result(v)).collect();
    assert_eq!(results.len(), n, "{out:?}");
    for r in &results {
        if r["ok"] == true {
            assert!(r["data"].is_object(), "{r}");
        } else {
            let kind = r["error"]["kind"].as_str().unwrap();
            assert!(
                ["no_answer", "outcome_unknown", "busy"].contains(&kind),
                "{r}"
            );
        }
    }
    let ok = results.iter().filter(|r| r["ok"] == true).count();
    assert!(ok >= n / 2, "only {ok} of {n} answered: {results:?}");
}

#[test]
fn a_request_acked_without_its_answer_says_no_answer() {
    use motorwire_can::{CanId, Frame};
    use motorwire_irpc::{Header, Message, WireVersion};
    let config = BridgeConfig {
        activate_on_start: false,
        feedback_period: None,
        ..BridgeConfig::default()
    };
    let mut bridge = Bridge::new(BusMap::from_toml(MAP).unwrap(), config).unwrap();
    bridge.start(Duration::ZERO);
    bridge.handle_line(
        Duration::ZERO,
        Origin(1),
        r#"{"request":"fault_history","motor_id":"elbow"}"#,
    );
    let frame = bridge.poll_transmit().unwrap();
    bridge.flushed(Duration::ZERO);
    let request = Message::decode_frame(WireVersion::V2_2, frame.data()).unwrap();
    assert_eq!(request.payload, Payload::RequestFaultHistory);
    // The joint acks, and its FaultHistory never comes.
    let ack = Message {
        header: Header {
            source_id: ELBOW,
            target_id: 0,
            msg_id: request.header.msg_id,
        },
        payload: Payload::Ack(request.header.msg_id),
    };
    let mut buf = [0u8; 64];
    let n = ack.encode_frame(WireVersion::V2_2, &mut buf).unwrap();
    let ms = |m| Duration::from_millis(m);
    bridge.handle_frame(
        ms(2),
        &Frame::fd(CanId::standard(ELBOW).unwrap(), &buf[..n]).unwrap(),
    );
    let mut out = Vec::new();
    for t in (5..=1000).step_by(5) {
        bridge.handle_timeout(ms(t));
        out.extend(std::iter::from_fn(|| bridge.poll_output()).map(|o| o.to_value()));
        if out.iter().any(is_result) {
            break;
        }
    }
    let r = result(&out, 1);
    // Every attempt's Ack timeout (4 × 100 ms) and 500 ms.
    assert_eq!(
        r["error"],
        json!({"kind":"no_answer","rule":"no_answer","message":"elbow acked the request, but no FaultHistory came within 900 ms"}),
        "{r}"
    );
    assert_eq!(r["acked"], json!(["elbow"]));
}

/// A calibration's own limits pass the gate a motion passes (issue 58
/// part 8a): a range of 1000° and 1000°/s on the elbow (0..150°,
/// 120°/s) were taken; now each is refused `outside_limit` naming the
/// limit, nothing is sent, and one within the limits in force (a
/// SafetyLimits line's too) is sent.
#[test]
fn a_calibration_beyond_the_limits_in_force_is_refused() {
    let mut arm = telemetry_arm(None, Faults::default());
    arm.keep_sent();
    for (n, (line, field, value, limit, bound)) in [
        (
            r#"{"calibration":"start","motor_id":"elbow","max_position_range":1000}"#,
            "max_position_range",
            1000.0,
            "position range",
            150.0,
        ),
        (
            r#"{"calibration":"start","motor_id":"elbow","max_velocity":1000}"#,
            "max_velocity",
            1000.0,
            "max_velocity",
            120.0,
        ),
    ]
    .into_iter()
    .enumerate()
    {
        arm.line(Origin(1), line);
        let out = until_results(&mut arm, 1, Duration::from_secs(1));
        let r = result(&out, n as u64 + 1);
        assert_eq!(r["ok"], false, "{r}");
        assert_eq!(r["error"]["rule"], "outside_limit", "{r}");
        assert_eq!(r["error"]["field"], field, "{r}");
        assert_eq!(r["error"]["value"], value, "{r}");
        assert_eq!(r["error"]["limit_name"], limit, "{r}");
        assert_eq!(r["error"]["limit"], bound, "{r}");
    }
    // Tightened to 40°/s by a SafetyLimits line: 60°/s is refused too.
    arm.line(
        Origin(1),
        r#"{"motor_id":"elbow","position_limits":{"min":0,"max":150},"velocity_limits":{"max_velocity":40},"torque_limits":{"continuous_torque":1,"peak_torque":2}}"#,
    );
    arm.line(
        Origin(1),
        r#"{"calibration":"start","motor_id":"elbow","max_velocity":60}"#,
    );
    let out = until_results(&mut arm, 2, Duration::from_secs(1));
    assert_eq!(result(&out, 3)["ok"], true, "{out:?}");
    let r = result(&out, 4);
    assert_eq!(
        (r["error"]["field"].clone(), r["error"]["limit"].clone()),
        (json!("max_velocity"), json!(40.0)),
        "{r}"
    );
    // No StartCalibration went to the elbow.
    let calibrations = arm
        .sent()
        .iter()
        .filter_map(|(_, f)| {
            motorwire_irpc::Message::decode_frame(motorwire_irpc::WireVersion::V2_2, f.data()).ok()
        })
        .filter(|m| {
            m.header.target_id == ELBOW && matches!(m.payload, Payload::StartCalibration(_))
        })
        .count();
    assert_eq!(calibrations, 0, "a calibration was sent");
}
