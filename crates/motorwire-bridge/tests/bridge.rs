//! The bridge end to end on simulated joints, in simulated time: results,
//! faults on the bus, the emergency stop, liveness, shutdown.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing
)]

mod common;

use std::collections::BTreeMap;
use std::time::Duration;

use motorwire_bridge::sim::SimulatedArm;
use motorwire_bridge::{Bridge, BridgeConfig, Origin, Output};
use motorwire_can::{Faults, SimConfig};
use motorwire_irpc::{LifecycleState, Payload};
use motorwire_translate::BusMap;
use serde_json::Value;

const MAP: &str = include_str!("../../../fixtures/maps/demo-arm.toml");
const MULTI: &str = include_str!("../../../fixtures/wia/valid/doc-3.2-multi-axis-command.json");
const PITCH: u16 = 0x10;
const ROLL: u16 = 0x11;
const ELBOW: u16 = 0x12;

/// A bridge on `map` with `config`, on simulated joints, ready.
fn started(map: BusMap, config: BridgeConfig) -> SimulatedArm {
    let mut arm =
        SimulatedArm::new(Bridge::new(map, config).unwrap(), SimConfig::default()).unwrap();
    assert!(
        arm.run_while(Duration::from_secs(2), |a| a.bridge().is_ready())
            .unwrap()
    );
    arm
}

#[test]
fn startup_configures_and_activates_every_joint() {
    let arm = common::arm(MAP, Faults::default(), 0);
    for node in [PITCH, ROLL, ELBOW] {
        assert_eq!(arm.joint(node).unwrap().state(), LifecycleState::Active);
    }
}

#[test]
fn a_move_is_acked_and_the_joint_gets_there() {
    let mut arm = common::arm(MAP, Faults::default(), 0);
    arm.line(Origin(3), &common::command("elbow", 60.0));
    let r = common::results(&mut arm, 1, Duration::from_secs(1));
    assert_eq!(r.len(), 1);
    assert_eq!(r[0]["ok"], true, "{}", r[0]);
    assert_eq!(r[0]["motor_id"], "elbow");
    assert_eq!(r[0]["acked"], serde_json::json!(["elbow"]));
    assert_eq!(
        r[0]["latency_us"], 0,
        "no latency on this bus, in simulated time"
    );
    arm.run_until(arm.now() + Duration::from_secs(3)).unwrap();
    assert!((arm.joint(ELBOW).unwrap().position() - 60.0).abs() < 1e-3);
}

#[test]
fn the_documents_multi_axis_command_arrives_together() {
    let mut arm = common::arm(MAP, Faults::default(), 0);
    // Feedback first: a synchronized move is planned from the positions.
    arm.run_until(arm.now() + Duration::from_millis(50))
        .unwrap();
    let line: String = MULTI.lines().map(str::trim).collect();
    arm.line(Origin(1), &line);
    let r = common::results(&mut arm, 1, Duration::from_secs(1));
    assert_eq!(r[0]["ok"], true, "{}", r[0]);
    assert_eq!(r[0]["command_id"], "cmd_1234567890");
    let start = arm.now();
    // total_duration_ms 2000: every joint arrives at 2 s, none before 1.9 s.
    arm.run_until(start + Duration::from_millis(1900)).unwrap();
    for node in [PITCH, ROLL, ELBOW] {
        assert!(arm.joint(node).unwrap().is_moving(), "node {node:#x}");
    }
    arm.run_until(start + Duration::from_millis(2100)).unwrap();
    for (node, target) in [(PITCH, 45.0), (ROLL, 15.0), (ELBOW, 90.0)] {
        let j = arm.joint(node).unwrap();
        assert!(!j.is_moving(), "node {node:#x}");
        assert!(
            (j.position() - target).abs() < 1e-3,
            "node {node:#x}: {}",
            j.position()
        );
    }
}

#[test]
fn bad_lines_are_answered_and_never_reach_the_bus() {
    let mut arm = common::arm(MAP, Faults::default(), 0);
    arm.run_until(arm.now() + Duration::from_millis(20))
        .unwrap();
    let sent = arm.bridge().stats().frames_sent;
    let deep = format!("{}{}", "[".repeat(10_000), "]".repeat(10_000));
    let lines = [
        ("{oops", "invalid"),
        ("[1,2]", "invalid"),
        (deep.as_str(), "invalid"),
        (
            r#"{"motor_id":"elbow","timestamp":0,"control_mode":"position","setpoint":NaN}"#,
            "invalid",
        ),
        (&common::command("elbow", 1e300), "refused"),
        (&common::command("elbow", 170.0), "refused"),
        (&common::command("nobody", 1.0), "refused"),
        (&common::command("turntable", 1.0), "refused"),
        (
            r#"{"motor_id":"elbow","timestamp":0,"control_mode":"torque","setpoint":1}"#,
            "refused",
        ),
        (r#"{"motor_id":"m","kp":1.0,"ki":0.0,"kd":0.0}"#, "invalid"),
        (
            include_str!("../../../fixtures/wia/valid/doc-4.2-motor-feedback.json"),
            "unsupported_kind",
        ),
        (r#"{"emergency_stop": false}"#, "not_latched"),
    ];
    for (i, (line, _)) in lines.iter().enumerate() {
        arm.line(Origin(i as u64), &line.replace('\n', " "));
    }
    arm.run_until(arm.now() + Duration::from_millis(1)).unwrap();
    let outs = arm.take_outputs();
    let mut by_origin = BTreeMap::new();
    for o in outs {
        if let Output::Result { origin, .. } = o {
            let json = o.to_value();
            assert!(
                by_origin.insert(origin.0, json).is_none(),
                "one result per line"
            );
        }
    }
    for (i, (line, kind)) in lines.iter().enumerate() {
        let r = &by_origin[&(i as u64)];
        assert_eq!(r["ok"], false, "{line}");
        assert_eq!(r["error"]["kind"], *kind, "{line}: {r}");
    }
    // Only the bridge's own heartbeat-free idle traffic: nothing sent.
    assert_eq!(arm.bridge().stats().frames_sent, sent);
    assert_eq!(arm.bridge().stats().failed, lines.len() as u64);
}

/// 10 % of frames dropped, 5 % duplicated, 5 % delayed up to 30 ms, 5 %
/// reordered: every command gets exactly one result, acked or failed, and
/// no joint executes one command twice.
#[test]
fn under_faults_every_command_is_acked_or_failed_and_never_executed_twice() {
    let faults = Faults {
        drop: 0.10,
        duplicate: 0.05,
        delay: 0.05,
        reorder: 0.05,
        max_delay: Duration::from_millis(30),
        ..Faults::default()
    };
    let mut arm = common::arm(MAP, faults, 7);
    let motors = [
        ("shoulder_pitch", PITCH),
        ("shoulder_roll", ROLL),
        ("elbow", ELBOW),
    ];
    let n = 300;
    let mut answered = 0;
    let mut acked: BTreeMap<&str, u64> = BTreeMap::new();
    let mut failed = 0;
    for i in 0..n {
        let (motor, _) = motors[i % 3];
        let setpoint = if (i / 3) % 2 == 0 { 20.0 } else { 30.0 } + (i % 7) as f64;
        arm.line(Origin(i as u64), &common::command(motor, setpoint));
        for r in common::results(&mut arm, 1, Duration::from_secs(2)) {
            answered += 1;
            if r["ok"] == true {
                *acked.entry(motor).or_default() += 1;
            } else {
                failed += 1;
                let kind = r["error"]["kind"].as_str().unwrap();
                assert!(
                    matches!(kind, "outcome_unknown" | "nacked" | "offline"),
                    "{r}"
                );
            }
        }
        // Joints that were called offline after a lost answer come back
        // with their next feedback; give them the time.
        arm.run_until(arm.now() + Duration::from_millis(20))
            .unwrap();
    }
    assert_eq!(answered, n, "one result per line");
    assert!(
        acked.values().sum::<u64>() >= (n as u64) * 8 / 10,
        "{acked:?}, {failed} failed"
    );
    for (motor, node) in motors {
        let log = arm.joint(node).unwrap().log();
        let mut seen = BTreeMap::new();
        for e in log {
            assert!(
                seen.insert((e.source, e.msg_id), ()).is_none(),
                "{motor}: msg_id {} executed twice",
                e.msg_id
            );
        }
        let moves = log
            .iter()
            .filter(|e| matches!(e.payload, Payload::SetTargetV2(_)))
            .count() as u64;
        // Every acked move was executed; a move can also be executed with
        // its every Ack lost (then reported failed, never acked).
        assert!(
            moves >= acked[motor],
            "{motor}: {moves} executed, {} acked",
            acked[motor]
        );
    }
    let stats = arm.bus().stats();
    assert!(
        stats.dropped > 0 && stats.duplicated > 0 && stats.reordered > 0,
        "{stats:?}"
    );
}

#[test]
fn the_emergency_stop_stops_latches_and_releases() {
    let mut arm = common::arm(MAP, Faults::default(), 0);
    arm.line(Origin(1), &common::command("elbow", 140.0));
    assert_eq!(
        common::results(&mut arm, 1, Duration::from_secs(1))[0]["ok"],
        true
    );
    arm.run_until(arm.now() + Duration::from_millis(500))
        .unwrap();
    assert!(arm.joint(ELBOW).unwrap().is_moving());
    arm.line(Origin(2), r#"{"emergency_stop": true}"#);
    let r = common::results(&mut arm, 1, Duration::from_secs(1));
    assert_eq!(r[0]["ok"], true, "{}", r[0]);
    assert_eq!(r[0]["emergency_stop"], true);
    assert!(r[0]["stop_latency_us"].is_u64());
    assert_eq!(
        r[0]["acked"].as_array().unwrap().len(),
        4,
        "three joints and the gripper"
    );
    arm.run_until(arm.now() + Duration::from_millis(500))
        .unwrap();
    for node in [PITCH, ROLL, ELBOW] {
        let j = arm.joint(node).unwrap();
        assert_eq!(j.state(), LifecycleState::Inactive);
        assert!(!j.is_moving());
    }
    let stopped_at = arm.joint(ELBOW).unwrap().position();
    assert!(stopped_at < 140.0);
    // Latched: motion refused, on every path.
    arm.line(Origin(3), &common::command("elbow", 10.0));
    arm.line(Origin(4), &MULTI.replace('\n', " "));
    let r = common::results(&mut arm, 2, Duration::from_millis(100));
    for x in &r {
        assert_eq!(x["error"]["kind"], "emergency_stop_latched", "{x}");
    }
    // A command carrying the emergency stop in its safety limits is one too.
    arm.line(
        Origin(5),
        r#"{"motor_id":"elbow","timestamp":0,"control_mode":"position","setpoint":10,"safety_limits":{"emergency_stop":true}}"#,
    );
    let r = common::results(&mut arm, 1, Duration::from_secs(1));
    assert_eq!(r[0]["emergency_stop"], true, "{}", r[0]);
    assert_eq!(
        r[0]["ok"], true,
        "a joint already stopped is stopped: {}",
        r[0]
    );
    // Release: the joints are active again, where they stopped.
    arm.line(Origin(6), r#"{"emergency_stop": false}"#);
    let r = common::results(&mut arm, 1, Duration::from_secs(1));
    assert_eq!(r[0]["released"], true, "{}", r[0]);
    assert_eq!(arm.joint(ELBOW).unwrap().state(), LifecycleState::Active);
    assert_eq!(arm.joint(ELBOW).unwrap().position(), stopped_at);
    arm.line(Origin(7), &common::command("elbow", 10.0));
    assert_eq!(
        common::results(&mut arm, 1, Duration::from_secs(1))[0]["ok"],
        true
    );
}

#[test]
fn a_silent_joint_is_reported_offline_and_the_others_are_served() {
    let mut arm = common::arm(MAP, Faults::default(), 0);
    arm.disconnect(ROLL);
    arm.run_until(arm.now() + Duration::from_millis(600))
        .unwrap();
    let outs = arm.take_outputs();
    let offline: Vec<Value> = outs
        .iter()
        .map(|o| o.to_value())
        .filter(|j| j["event"] == "offline")
        .collect();
    assert_eq!(offline.len(), 1, "{offline:?}");
    assert_eq!(offline[0]["motor_id"], "shoulder_roll");
    let fb = outs
        .iter()
        .map(|o| o.to_value())
        .rfind(|j| j["motor_id"] == "shoulder_roll" && j.get("feedback").is_some())
        .unwrap();
    assert_eq!(fb["online"], false);
    assert_eq!(fb["feedback"]["status"]["fault"], true);
    arm.line(Origin(1), &common::command("shoulder_roll", 10.0));
    arm.line(Origin(2), &common::command("elbow", 10.0));
    let r = common::results(&mut arm, 2, Duration::from_secs(1));
    let roll = r.iter().find(|x| x["motor_id"] == "shoulder_roll").unwrap();
    let elbow = r.iter().find(|x| x["motor_id"] == "elbow").unwrap();
    assert_eq!(roll["error"]["kind"], "offline");
    assert_eq!(elbow["ok"], true);
}

#[test]
fn end_of_input_lets_moves_finish_then_deactivates_every_joint() {
    let mut arm = common::arm(MAP, Faults::default(), 0);
    arm.line(Origin(1), &common::command("elbow", 50.0));
    assert_eq!(
        common::results(&mut arm, 1, Duration::from_secs(1))[0]["ok"],
        true
    );
    let now = arm.now();
    arm.bridge_mut().finish(now);
    arm.line(Origin(2), &common::command("elbow", 10.0));
    assert!(
        arm.run_while(Duration::from_secs(5), |a| a.bridge().is_finished())
            .unwrap()
    );
    let outs = arm.take_outputs();
    let late = outs
        .iter()
        .map(|o| o.to_value())
        .find(|j| j["ok"] == false)
        .unwrap();
    assert_eq!(late["error"]["kind"], "shutting_down");
    let stopped = outs
        .iter()
        .map(|o| o.to_value())
        .find(|j| j["event"] == "stopped")
        .unwrap();
    assert_eq!(stopped["failures"], serde_json::json!([]));
    let elbow = arm.joint(ELBOW).unwrap();
    assert!(
        (elbow.position() - 50.0).abs() < 1e-3,
        "the move finished first"
    );
    for node in [PITCH, ROLL, ELBOW] {
        assert_eq!(arm.joint(node).unwrap().state(), LifecycleState::Inactive);
    }
}

#[test]
fn an_interrupt_stops_the_joints_at_once() {
    let mut arm = common::arm(MAP, Faults::default(), 0);
    arm.line(Origin(1), &common::command("elbow", 140.0));
    assert_eq!(
        common::results(&mut arm, 1, Duration::from_secs(1))[0]["ok"],
        true
    );
    arm.run_until(arm.now() + Duration::from_millis(300))
        .unwrap();
    let now = arm.now();
    arm.bridge_mut().interrupt(now);
    assert!(
        arm.run_while(Duration::from_secs(1), |a| a.bridge().is_finished())
            .unwrap()
    );
    arm.run_until(arm.now() + Duration::from_millis(500))
        .unwrap();
    let elbow = arm.joint(ELBOW).unwrap();
    assert_eq!(elbow.state(), LifecycleState::Inactive);
    assert!(!elbow.is_moving());
    assert!(
        elbow.position() < 100.0,
        "stopped early: {}",
        elbow.position()
    );
}

/// Input that ends before the joints are ready (a short file on stdin):
/// its lines are still served, then the joints are stopped.
#[test]
fn input_ending_during_startup_is_served_then_stopped() {
    let map = BusMap::from_toml(MAP).unwrap();
    let bridge = Bridge::new(map, BridgeConfig::default()).unwrap();
    let mut arm = SimulatedArm::new(bridge, SimConfig::default()).unwrap();
    arm.line(Origin(1), &common::command("elbow", 5.0));
    arm.bridge_mut().finish(Duration::ZERO);
    assert!(
        arm.run_while(Duration::from_secs(5), |a| a.bridge().is_finished())
            .unwrap()
    );
    let outs = arm.take_outputs();
    let result = outs
        .iter()
        .map(|o| o.to_value())
        .find(|j| j.get("ok").is_some())
        .unwrap();
    assert_eq!(result["ok"], true, "{result}");
    assert!((arm.joint(ELBOW).unwrap().position() - 5.0).abs() < 1e-3);
    assert_eq!(arm.joint(ELBOW).unwrap().state(), LifecycleState::Inactive);
}

/// A bus of two joints in different wire versions, both moving (so the
/// bridge sends its heartbeat): each keeps its watchdog fed by ArmReady in
/// its own version, and neither takes a heartbeat for another request (v2.0's
/// ArmReady tag is v2.1's RequestTelemetry).
#[test]
fn the_heartbeat_is_armready_to_every_joint_in_its_own_wire_version() {
    let map = BusMap::from_toml(
        r#"
[motors.shoulder_pitch]
dialect = "irpc"
node = 0x10
wire = "v2.0"
limits = { min_position = -90, max_position = 90, max_velocity = 40, max_acceleration = 200 }

[motors.shoulder_roll]
dialect = "irpc"
node = 0x11
wire = "v2.1"
limits = { min_position = -45, max_position = 45, max_velocity = 20, max_acceleration = 200 }
"#,
    )
    .unwrap();
    let mut arm = started(map, BridgeConfig::default());
    // Two seconds of motion each, ten times their watchdogs' 200 ms.
    arm.line(Origin(1), &common::command("shoulder_pitch", 80.0));
    arm.line(Origin(1), &common::command("shoulder_roll", 40.0));
    arm.run_until(arm.now() + Duration::from_secs(4)).unwrap();
    for (node, at) in [(PITCH, 80.0), (ROLL, 40.0)] {
        let joint = arm.joint(node).unwrap();
        assert!(
            (joint.position() - at).abs() < 1e-3,
            "joint {node:#x} at {}",
            joint.position()
        );
        assert_eq!(joint.stats().watchdog_stops, 0, "joint {node:#x}");
        let taken: Vec<_> = joint
            .log()
            .iter()
            .filter(|e| {
                !matches!(
                    e.payload,
                    Payload::Configure | Payload::Activate | Payload::SetTargetV2(_)
                )
            })
            .map(|e| e.payload)
            .collect();
        assert!(taken.is_empty(), "joint {node:#x} took {taken:?}");
    }
}

/// Lines another client wrote before a stop, still on their way when it
/// came, never run after the release: their timestamps are older than the
/// stop. Every dialect (an iRPC joint, the compact gripper), single and
/// multi-axis.
#[test]
fn commands_written_before_a_stop_are_refused_after_the_release() {
    const EPOCH: f64 = 1_767_225_600_000.0; // 2026-01-01, the bridge's time zero
    let map = BusMap::from_toml(MAP).unwrap();
    let config = BridgeConfig {
        epoch_unix_ms: Some(EPOCH),
        ..BridgeConfig::default()
    };
    let mut arm = started(map, config);
    let at = |ms: f64, motor: &str, setpoint: f64| {
        format!(
            r#"{{"motor_id":"{motor}","timestamp":{},"control_mode":"position","setpoint":{setpoint}}}"#,
            EPOCH + ms
        )
    };
    // A stop from `origin` at `after` from now, then a release; when the
    // stop came (ms on the bridge's clock).
    let stop_then_release = |arm: &mut SimulatedArm, origin: u64, after: Duration| {
        arm.run_until(arm.now() + after).unwrap();
        let stop_ms = arm.now().as_secs_f64() * 1000.0;
        arm.line(Origin(origin), r#"{"emergency_stop": true}"#);
        assert_eq!(
            common::results(arm, 1, Duration::from_secs(1))[0]["ok"],
            true
        );
        arm.line(Origin(1), r#"{"emergency_stop": false}"#);
        assert_eq!(
            common::results(arm, 1, Duration::from_secs(1))[0]["released"],
            true
        );
        stop_ms
    };
    arm.line(Origin(1), r#"{"emergency_stop": true}"#);
    assert_eq!(
        common::results(&mut arm, 1, Duration::from_secs(1))[0]["ok"],
        true
    );
    // A second stop while the first is latched counts too: the last stop
    // is the later one.
    let stop_ms = stop_then_release(&mut arm, 3, Duration::from_millis(100));
    let executed = arm.joint(ELBOW).unwrap().stats().executed;
    let gripper = arm.compact_device(0x20).unwrap().log().len();
    // 37 lines written 1 to 37 ms before the stop, by a second client.
    for i in 1..=37 {
        let written = stop_ms - f64::from(i);
        let line = match i % 3 {
            0 => at(written, "elbow", 100.0),
            1 => at(written, "gripper_axis", 45.0),
            _ => format!(
                r#"{{"command_id":"m{i}","timestamp":{},"motors":[{{"motor_id":"elbow","control_mode":"position","setpoint":90}}]}}"#,
                EPOCH + written
            ),
        };
        arm.line(Origin(2), &line);
    }
    let r = common::results(&mut arm, 37, Duration::from_secs(1));
    assert_eq!(r.len(), 37);
    for x in &r {
        assert_eq!(x["ok"], false, "{x}");
        assert_eq!(x["error"]["kind"], "stale_before_stop", "{x}");
    }
    assert_eq!(
        r[0]["error"]["message"],
        format!(
            "timestamp {} is 0.001 s before the last emergency stop (at {}): written before the stop, it does not run after the release",
            EPOCH + stop_ms - 1.0,
            EPOCH + stop_ms
        )
    );
    arm.run_until(arm.now() + Duration::from_secs(1)).unwrap();
    assert_eq!(arm.joint(ELBOW).unwrap().stats().executed, executed);
    assert_eq!(arm.compact_device(0x20).unwrap().log().len(), gripper);
    // A line written after the stop runs.
    let now_ms = arm.now().as_secs_f64() * 1000.0;
    arm.line(Origin(2), &at(now_ms, "elbow", 20.0));
    assert_eq!(
        common::results(&mut arm, 1, Duration::from_secs(1))[0]["ok"],
        true
    );
    // Timestamps are whole milliseconds: one stamped in the millisecond a
    // stop came in (0.6 ms after its start here) may have been written
    // after it, and runs; one a millisecond earlier does not.
    let stop_ms = stop_then_release(&mut arm, 3, Duration::from_micros(100_600));
    let same_ms = at(stop_ms.floor(), "elbow", 30.0);
    let before = at(stop_ms.floor() - 1.0, "elbow", 40.0);
    arm.line(Origin(2), &before);
    let r = common::results(&mut arm, 1, Duration::from_secs(1));
    assert_eq!(r[0]["error"]["kind"], "stale_before_stop", "{}", r[0]);
    arm.line(Origin(2), &same_ms);
    assert_eq!(
        common::results(&mut arm, 1, Duration::from_secs(1))[0]["ok"],
        true
    );
}

/// At the end of input, motion that would not end by itself stops at once
/// (a trajectory looping forever, one scheduled 15 s ahead, a compact
/// velocity setpoint whose deadman is 10 s), while a finite move on another
/// joint finishes; a start_time a year ahead is refused.
#[test]
fn end_of_input_stops_what_would_not_end_by_itself_at_once() {
    const EPOCH: f64 = 1_767_225_600_000.0;
    let map = BusMap::from_toml(
        r#"
[motors.pendulum]
dialect = "irpc"
node = 0x13
limits = { min_position = -170, max_position = 170, max_velocity = 200, max_acceleration = 800, max_jerk = 8000 }

[motors.later]
dialect = "irpc"
node = 0x14
limits = { min_position = -170, max_position = 170, max_velocity = 200, max_acceleration = 800, max_jerk = 8000 }

[motors.elbow]
dialect = "irpc"
node = 0x12
limits = { min_position = 0, max_position = 150, max_velocity = 60, max_acceleration = 500 }

[motors.gripper_axis]
dialect = "compact"
node = 0x20
command_timeout_ms = 10000
limits = { min_position = 0, max_position = 90, max_velocity = 60, max_torque = 5 }
"#,
    )
    .unwrap();
    let config = BridgeConfig {
        epoch_unix_ms: Some(EPOCH),
        ..BridgeConfig::default()
    };
    let mut arm = started(map, config);
    let trajectory = |motor: &str, start: Option<f64>, forever: bool| {
        format!(
            r#"{{"trajectory_id":"{motor}","motor_id":"{motor}","waypoints":[{{"position":0,"velocity":0,"time":0}},{{"position":30,"velocity":30,"time":1}},{{"position":0,"velocity":0,"time":2}}],"timing":{{{}}}{}}}"#,
            start.map_or(String::new(), |s| format!(r#""start_time":{s}"#)),
            if forever {
                r#","loop":{"enabled":true,"count":-1}"#
            } else {
                ""
            }
        )
    };
    let t0 = EPOCH + arm.now().as_secs_f64() * 1000.0;
    arm.line(Origin(1), &trajectory("pendulum", None, true));
    arm.line(Origin(1), &trajectory("later", Some(t0 + 15_000.0), false));
    arm.line(
        Origin(1),
        &trajectory("later", Some(t0 + 365.0 * 86_400_000.0), false),
    );
    arm.line(
        Origin(1),
        &format!(
            r#"{{"motor_id":"gripper_axis","timestamp":{t0},"control_mode":"velocity","setpoint":20}}"#
        ),
    );
    arm.line(
        Origin(1),
        &format!(
            r#"{{"motor_id":"elbow","timestamp":{t0},"control_mode":"position","setpoint":140}}"#
        ),
    );
    arm.run_until(arm.now() + Duration::from_millis(1500))
        .unwrap();
    let early = arm.take_results();
    let year = early.iter().find(|v| v["line"] == 3).unwrap().clone();
    // The loop is answered once it is under way (its first segment
    // acked), not when it ends: a loop that never ends was never answered.
    let pendulum_result = early.iter().find(|v| v["line"] == 1).unwrap();
    assert_eq!(pendulum_result["ok"], true, "{pendulum_result}");
    assert_eq!(
        pendulum_result["arrival_follows"], true,
        "{pendulum_result}"
    );
    assert_eq!(year["error"]["kind"], "stale", "{year}");
    assert!(
        year["error"]["message"]
            .as_str()
            .unwrap()
            .starts_with("timing.start_time "),
        "{year}"
    );
    assert!((arm.compact_device(0x20).unwrap().velocity() - 20.0).abs() < 1e-3);
    let segments = |arm: &SimulatedArm, node: u16| {
        arm.joint(node)
            .unwrap()
            .log()
            .iter()
            .filter(|e| matches!(e.payload, Payload::SetTargetV2(_)))
            .count()
    };
    let pendulum = segments(&arm, 0x13);
    assert!(pendulum >= 2, "{pendulum}");
    assert!(
        arm.joint(ELBOW).unwrap().is_moving(),
        "the elbow is still on its way"
    );
    let ended = arm.now();
    arm.bridge_mut().finish(ended);
    assert!(
        arm.run_while(Duration::from_secs(5), |a| a.bridge().is_finished())
            .unwrap()
    );
    let took = arm.now() - ended;
    assert!(
        took < Duration::from_secs(2),
        "the drain waited {took:?} for the elbow's finite move only"
    );
    let out: Vec<Value> = arm.take_outputs().iter().map(Output::to_value).collect();
    let result = |line: u64| {
        out.iter()
            .find(|v| v["line"] == line && v.get("ok").is_some())
            .unwrap_or_else(|| panic!("no result for line {line}: {out:?}"))
    };
    // The scheduled one never started: its result says it was cancelled.
    assert_eq!(result(2)["error"]["kind"], "cancelled", "{}", result(2));
    assert!(
        result(2)["error"]["message"]
            .as_str()
            .unwrap()
            .starts_with("cancelled by the end of input: it would not end by itself"),
        "{}",
        result(2)
    );
    // The loop, answered when it got under way: its completion says why
    // it ended.
    let completion = out
        .iter()
        .find(|v| v["line"] == 1 && v.get("arrived").is_some())
        .unwrap_or_else(|| panic!("no completion for line 1: {out:?}"));
    assert_eq!(completion["arrived"], false, "{completion}");
    assert!(
        completion["reason"]
            .as_str()
            .unwrap()
            .starts_with("cancelled by the end of input: it would not end by itself: the rest of the trajectory was not sent"),
        "{completion}"
    );
    assert!(
        segments(&arm, 0x13) <= pendulum + 1,
        "no new cycle after the end"
    );
    assert_eq!(segments(&arm, 0x14), 0, "the scheduled one never started");
    assert_eq!(arm.compact_device(0x20).unwrap().velocity(), 0.0);
    assert!(
        !out.iter().any(|v| v["event"] == "deadman"),
        "stopped by the end, not by its deadman: {out:?}"
    );
    assert!(
        (arm.joint(ELBOW).unwrap().position() - 140.0).abs() < 1e-3,
        "the finite move finished"
    );
}

/// A velocity setpoint still in flight when input ends (sent, not yet
/// answered) is stopped too: the deadman would not watch what was never
/// acked, so the end stops it as if it had been.
#[test]
fn end_of_input_stops_a_setpoint_still_in_flight() {
    let map = BusMap::from_toml(
        r#"
[motors.gripper_axis]
dialect = "compact"
node = 0x20
command_timeout_ms = 10000
limits = { min_position = 0, max_position = 90, max_velocity = 60, max_torque = 5 }
"#,
    )
    .unwrap();
    let mut arm = started(map, BridgeConfig::default());
    arm.line(
        Origin(1),
        r#"{"motor_id":"gripper_axis","timestamp":1,"control_mode":"velocity","setpoint":20}"#,
    );
    let ended = arm.now();
    arm.bridge_mut().finish(ended);
    assert!(
        arm.run_while(Duration::from_secs(5), |a| a.bridge().is_finished())
            .unwrap()
    );
    assert!(
        arm.now() - ended < Duration::from_secs(1),
        "{:?}",
        arm.now() - ended
    );
    let device = arm.compact_device(0x20).unwrap();
    assert_eq!(device.velocity(), 0.0, "{:?}", device.log());
    let out: Vec<Value> = arm.take_outputs().iter().map(Output::to_value).collect();
    let r = out
        .iter()
        .find(|v| v["line"] == 1 && v.get("ok").is_some())
        .unwrap();
    assert_eq!(r["ok"], false, "{r}");
    assert!(!out.iter().any(|v| v["event"] == "deadman"), "{out:?}");
}

/// A timestamp in seconds (or microseconds) is refused `stale` saying so,
/// with the command that makes milliseconds; one merely old is not given
/// the hint.
#[test]
fn a_timestamp_in_seconds_is_refused_with_the_hint() {
    const EPOCH: f64 = 1_767_225_600_000.0; // 2026-01-01, the bridge's time zero
    let config = BridgeConfig {
        epoch_unix_ms: Some(EPOCH),
        ..BridgeConfig::default()
    };
    let mut arm = started(BusMap::from_toml(MAP).unwrap(), config);
    let now_ms = EPOCH + arm.now().as_secs_f64() * 1000.0;
    let line = |ts: f64| {
        format!(
            r#"{{"motor_id":"elbow","timestamp":{ts},"control_mode":"position","setpoint":10}}"#
        )
    };
    let seconds = (now_ms / 1000.0).floor();
    let micros = now_ms * 1000.0;
    let old = now_ms - 3_600_000.0;
    for ts in [seconds, micros, old] {
        arm.line(Origin(1), &line(ts));
    }
    let mut r = common::results(&mut arm, 3, Duration::from_secs(1));
    r.sort_by_key(|v| v["line"].as_u64());
    // Seconds are refused by the library's own rule (the line is read as
    // `motorwire validate` and the library read it); the others are stale.
    assert_eq!(r[0]["error"]["kind"], "invalid", "{}", r[0]);
    assert_eq!(
        r[0]["error"]["violations"][0]["rule"], "timestamp-unit",
        "{}",
        r[0]
    );
    assert_eq!(
        r[0]["error"]["violations"][0]["message"],
        format!(
            "timestamp {seconds} looks like seconds: WIA timestamps are Unix milliseconds ({} for that time)",
            seconds * 1000.0
        ),
        "{}",
        r[0]
    );
    for x in &r[1..] {
        assert_eq!(x["error"]["kind"], "stale", "{x}");
        assert_eq!(x["error"]["rule"], "stale", "{x}");
    }
    let message = |i: usize| r[i]["error"]["message"].as_str().unwrap().to_owned();
    assert!(
        message(1).ends_with(
            "(WIA §10.1); it looks like microseconds: WIA timestamps are Unix milliseconds (`date +%s%3N`)"
        ),
        "{}",
        message(1)
    );
    assert_eq!(
        message(2),
        format!("timestamp {old} is 3600.0 s old; the allowed clock skew is 300 s (WIA §10.1)")
    );
    // No move reached the elbow.
    assert!(
        !arm.joint(ELBOW)
            .unwrap()
            .log()
            .iter()
            .any(|e| matches!(e.payload, Payload::SetTargetV2(_)))
    );
}

/// A compact command whose acknowledgement never comes (its device silent
/// past every retry) has an unknown outcome; once the device reports
/// standing at its target, the bridge says the move was executed, as it
/// does for an iRPC joint: the rule lives once, for every dialect.
#[test]
fn a_compact_move_of_unknown_outcome_is_said_executed_when_the_device_shows_it() {
    use motorwire_can::{CanId, Frame};
    use motorwire_compact::{FeedbackRecord, MotorHash, StatusFlags};
    let map = BusMap::from_toml(
        "[motors.gripper_axis]\ndialect = \"compact\"\nnode = 0x20\n\
         limits = { min_position = 0, max_position = 90, max_velocity = 60 }",
    )
    .unwrap();
    // Ready at once (no startup to wait for, no reading).
    let config = BridgeConfig {
        activate_on_start: false,
        ..BridgeConfig::default()
    };
    let mut bridge = Bridge::new(map, config).unwrap();
    let ms = Duration::from_millis;
    bridge.start(Duration::ZERO);
    bridge.handle_line(ms(1), Origin(3), &common::command("gripper_axis", 40.0));
    let mut sent = 0;
    // The device never answers: the command is sent, then sent again
    // after each of the client's 100 ms timeouts, then given up.
    for t in (1..=500).step_by(10) {
        bridge.handle_timeout(ms(t));
        while bridge.poll_transmit().is_some() {
            sent += 1;
        }
        bridge.flushed(ms(t));
    }
    assert_eq!(sent, 4, "the first sending and three retries");
    let outputs: Vec<Output> = std::iter::from_fn(|| bridge.poll_output()).collect();
    let r = outputs.iter().find_map(Output::result).unwrap();
    assert_eq!(r.error.as_ref().unwrap().kind.name(), "outcome_unknown");
    let record = |position: f32| {
        let r = FeedbackRecord {
            motor: MotorHash::of("gripper_axis"),
            timestamp_us: 0,
            position,
            velocity: 0.0,
            acceleration: 0.0,
            torque: 0.0,
            current: 0.0,
            voltage: 24.0,
            temperature: 30.0,
            status: StatusFlags::EMPTY,
            health: 100,
        };
        Frame::fd(CanId::standard(0x420).unwrap(), &r.encode().unwrap()).unwrap()
    };
    // Not there yet: nothing said.
    bridge.handle_frame(ms(600), &record(20.0));
    let said = |b: &mut Bridge| -> Vec<Value> {
        std::iter::from_fn(|| b.poll_output())
            .filter(|o| matches!(o, Output::Event(motorwire_bridge::Event::Outcome { .. })))
            .map(|o| serde_json::from_str(&o.to_json()).unwrap())
            .collect()
    };
    assert_eq!(said(&mut bridge), Vec::<Value>::new());
    bridge.handle_frame(ms(700), &record(40.0));
    assert_eq!(
        said(&mut bridge),
        [serde_json::json!({
            "event": "outcome",
            "origin": 3,
            "line": 1,
            "motor_id": "gripper_axis",
            "outcome": "executed",
            "position": 40.0
        })]
    );
}

/// `ready` comes once every device that answers was read: it carries each
/// motor's state (online, active, where it stands), and a trajectory sent
/// with the first line starts from the joint's real position (it was
/// refused "the joint is at an unknown position" until its first Encoder).
#[test]
fn ready_carries_every_motors_state_and_the_first_line_knows_where_the_joints_are() {
    let map = BusMap::from_toml(MAP).unwrap();
    let mut arm = SimulatedArm::new(
        Bridge::new(map, BridgeConfig::default()).unwrap(),
        SimConfig::default(),
    )
    .unwrap();
    let mut ready = None;
    while ready.is_none() && arm.now() < Duration::from_secs(2) {
        arm.step(Duration::from_millis(1)).unwrap();
        ready = arm
            .take_outputs()
            .into_iter()
            .map(|o| o.to_value())
            .find(|v| v["event"] == "ready");
    }
    let ready = ready.expect("ready within 2 s");
    assert_eq!(ready["latched"], false);
    let motors = ready["motors"].as_array().unwrap();
    let names: Vec<&str> = motors
        .iter()
        .map(|m| m["motor_id"].as_str().unwrap())
        .collect();
    assert_eq!(
        names,
        ["elbow", "gripper_axis", "shoulder_pitch", "shoulder_roll"]
    );
    for m in motors {
        assert_eq!(m["online"], true, "{m}");
        assert_eq!(m["active"], true, "{m}");
        assert_eq!(m["position"], 0.0, "{m}");
        assert_eq!(m["moving"], false, "{m}");
    }
    // The first line, in the same instant: a trajectory from where the
    // elbow stands.
    arm.line(
        Origin(1),
        r#"{"trajectory_id":"t","motor_id":"elbow","waypoints":[{"position":0,"velocity":0,"time":0},{"position":20,"velocity":0,"time":1}],"timing":{}}"#,
    );
    let r = common::results(&mut arm, 1, Duration::from_secs(3));
    assert_eq!(r[0]["ok"], true, "{}", r[0]);
}

/// `{"query":"state"}` answers every motor's state now, `"motor_id"` one
/// motor's; an unknown motor is refused by rule; a client greeted once
/// the bridge is ready gets `ready` with the state, for it alone.
#[test]
fn the_state_is_asked_for_and_a_client_connecting_later_is_greeted_with_it() {
    let mut arm = common::arm(MAP, Faults::default(), 0);
    arm.line(Origin(1), &common::command("elbow", 30.0));
    arm.run_until(arm.now() + Duration::from_secs(2)).unwrap();
    arm.take_outputs();
    arm.line(Origin(1), r#"{"query":"state","motor_id":"elbow"}"#);
    arm.line(Origin(1), r#"{"query":"state"}"#);
    arm.line(Origin(1), r#"{"query":"state","motor_id":"knee"}"#);
    arm.line(Origin(1), r#"{"query":"state","motor":"elbow"}"#);
    let r = common::results(&mut arm, 4, Duration::from_millis(50));
    assert_eq!(r[0]["ok"], true, "{}", r[0]);
    assert_eq!(r[0]["motor_id"], "elbow");
    let elbow = &r[0]["state"]["motors"][0];
    assert_eq!(r[0]["state"]["motors"].as_array().unwrap().len(), 1);
    assert_eq!(elbow["motor_id"], "elbow");
    assert_eq!(elbow["target"], 30.0, "{elbow}");
    assert!(
        (elbow["position"].as_f64().unwrap() - 30.0).abs() < 0.1,
        "{elbow}"
    );
    assert_eq!(elbow["moving"], false, "{elbow}");
    assert_eq!(r[1]["state"]["motors"].as_array().unwrap().len(), 4);
    assert_eq!(r[1]["state"]["latched"], false);
    assert_eq!(r[2]["error"]["rule"], "unknown_motor", "{}", r[2]);
    assert_eq!(r[3]["error"]["kind"], "invalid", "{}", r[3]);
    // Latched: said in the state.
    arm.line(Origin(1), r#"{"emergency_stop":true}"#);
    arm.run_until(arm.now() + Duration::from_millis(200))
        .unwrap();
    arm.take_outputs();
    let now = arm.now();
    arm.bridge_mut().greet(now, Origin(9));
    let out = arm.take_outputs();
    let greeting: Vec<(Origin, Value)> = out
        .iter()
        .filter_map(|o| match o {
            Output::ToOne { origin, .. } => Some((*origin, o.to_value())),
            _ => None,
        })
        .collect();
    assert_eq!(greeting.len(), 1, "{out:?}");
    assert_eq!(greeting[0].0, Origin(9));
    assert_eq!(greeting[0].1["event"], "ready");
    assert_eq!(greeting[0].1["latched"], true);
    let motors = greeting[0].1["motors"].as_array().unwrap();
    let elbow = motors.iter().find(|m| m["motor_id"] == "elbow").unwrap();
    assert_eq!(elbow["active"], false, "stopped: {elbow}");
}

/// A stream setpoint for `motor` (`"stream":true`), position `setpoint`.
fn stream(motor: &str, setpoint: f64) -> String {
    format!(
        r#"{{"motor_id":"{motor}","timestamp":1704067200000,"control_mode":"position","setpoint":{setpoint},"stream":true}}"#
    )
}

/// A policy streaming position setpoints at 100 Hz: one result per line
/// (`ok`, `arrival_follows: false`), no completion lines, and each motor
/// ends where the stream left it, on an iRPC joint and on the compact
/// gripper. (How closely a joint follows a stream is measured, not
/// asserted: `MOTORWIRE_BENCH_STREAM_ONLY=1 cargo bench -p motorwire-benches
/// --bench bridge`, BENCHMARKS.md.)
#[test]
fn a_stream_of_setpoints_is_answered_line_by_line() {
    let mut arm = common::arm(MAP, Faults::default(), 0);
    // The stream starts where the joints stand.
    arm.line(Origin(1), &common::command("elbow", 60.0));
    arm.line(
        Origin(1),
        r#"{"motor_id":"gripper_axis","timestamp":1704067200000,"control_mode":"position","setpoint":45}"#,
    );
    arm.run_until(arm.now() + Duration::from_secs(3)).unwrap();
    arm.take_outputs();
    let reference = |t: f64| 60.0 + 20.0 * (std::f64::consts::TAU * 0.5 * t).sin();
    let grip = |t: f64| 45.0 + 10.0 * (std::f64::consts::TAU * 0.5 * t).sin();
    let start = arm.now();
    let mut outputs = Vec::new();
    for k in 0..200u32 {
        let t = f64::from(k) * 0.01;
        arm.line(Origin(1), &stream("elbow", reference(t)));
        arm.line(Origin(1), &stream("gripper_axis", grip(t)));
        arm.run_until(start + Duration::from_millis(10 * u64::from(k + 1)))
            .unwrap();
        outputs.extend(arm.take_outputs());
    }
    arm.run_until(arm.now() + Duration::from_secs(3)).unwrap();
    outputs.extend(arm.take_outputs());
    let values: Vec<Value> = outputs.iter().map(|o| o.to_value()).collect();
    let results: Vec<&Value> = values
        .iter()
        .filter(|v| v.get("ok").is_some() && v.get("event").is_none())
        .collect();
    assert_eq!(results.len(), 400, "{results:?}");
    for (k, r) in results.iter().enumerate() {
        assert_eq!(r["line"], k + 3, "{r}");
        assert_eq!(r["ok"], true, "{r}");
        assert_eq!(r["arrival_follows"], false, "{r}");
    }
    assert!(
        !values.iter().any(|v| v.get("arrived").is_some()),
        "no completion line for a stream"
    );
    // The last setpoint holds: each motor stands where the stream ended.
    let elbow = arm.joint(ELBOW).unwrap().position();
    assert!((elbow - reference(1.99)).abs() < 0.01, "{elbow}");
    let gripper = arm.compact_device(0x20).unwrap().position();
    assert!((gripper - grip(1.99)).abs() < 0.5, "{gripper}");
}

/// A 100 Hz stream replans the joint at every setpoint from where it is,
/// how fast it moves and how its speed changes: its acceleration never
/// steps at a switch (each millisecond it changes by no more than the
/// elbow's jerk limit allows, 2,000 deg/s³), it stays within 500 deg/s²,
/// and the joint follows the sine's shape. (Planned from position and
/// velocity alone, every switch set the acceleration back to zero: the
/// joint crept, more than 10 degrees from the sine.)
#[test]
fn a_streamed_joint_is_replanned_without_a_step_in_acceleration() {
    let mut arm = common::arm(MAP, Faults::default(), 0);
    arm.line(Origin(1), &common::command("elbow", 60.0));
    arm.run_until(arm.now() + Duration::from_secs(3)).unwrap();
    arm.take_outputs();
    let reference = |t: f64| 60.0 + 20.0 * (std::f64::consts::TAU * 0.5 * t).sin();
    let start = arm.now();
    let (mut last, mut steepest, mut largest) = (0.0f64, 0.0f64, 0.0f64);
    let mut worst_after_lag = 0.0f64;
    for ms in 0..3000u64 {
        if ms % 10 == 0 {
            arm.line(Origin(1), &stream("elbow", reference(ms as f64 / 1000.0)));
        }
        let at = start + Duration::from_millis(ms + 1);
        arm.run_until(at).unwrap();
        let joint = arm.joint(ELBOW).unwrap();
        let a = joint.acceleration_at(at);
        steepest = steepest.max((a - last).abs());
        largest = largest.max(a.abs());
        last = a;
        // Once under way, it follows the sine a fifth of a second behind.
        if ms >= 1000 {
            let behind = reference((ms as f64 + 1.0) / 1000.0 - 0.2);
            worst_after_lag = worst_after_lag.max((joint.position_at(at) - behind).abs());
        }
        arm.take_outputs();
    }
    assert!(
        steepest <= 2.0 + 1e-6,
        "the acceleration stepped by {steepest} in 1 ms"
    );
    assert!(largest <= 500.0 + 1e-6, "{largest}");
    assert!(
        worst_after_lag < 3.0,
        "{worst_after_lag} degrees from the sine 200 ms before"
    );
}

/// A stream that repeats its target near a limit, while the joint brakes
/// toward it at speed, is answered `ok` at every setpoint: each is planned
/// from where the joint is, how fast it moves and how it brakes (the
/// bridge's model of its move), so the path it checks is the one the joint
/// takes, stopping on the target, not one that ignores the braking and
/// passes the limit.
#[test]
fn a_stream_repeating_its_target_near_a_limit_is_not_refused() {
    // Frames take half a millisecond each way: the joint starts each move
    // that much after the bridge sent it, and its reports are that old.
    let config = SimConfig {
        latency: Duration::from_micros(500),
        ..SimConfig::default()
    };
    let bridge = Bridge::new(BusMap::from_toml(MAP).unwrap(), BridgeConfig::default()).unwrap();
    let mut arm = SimulatedArm::new(bridge, config).unwrap();
    assert!(
        arm.run_while(Duration::from_secs(2), |a| a.bridge().is_ready())
            .unwrap()
    );
    arm.line(Origin(1), &stream("elbow", 150.0));
    let mut results = Vec::new();
    let mut highest = 0.0f64;
    for _ in 0..200 {
        arm.run_until(arm.now() + Duration::from_millis(10))
            .unwrap();
        let p = arm.joint(ELBOW).unwrap().position();
        highest = highest.max(p);
        if p > 100.0 {
            arm.line(Origin(1), &stream("elbow", 150.0));
        }
        results.extend(
            arm.take_outputs()
                .iter()
                .map(|o| o.to_value())
                .filter(|v| v.get("ok").is_some()),
        );
    }
    assert!(results.len() > 50, "{}", results.len());
    for r in &results {
        assert_eq!(r["ok"], true, "{r}");
    }
    assert!((highest - 150.0).abs() < 1e-3, "{highest}");
}

/// A setpoint replaced by a newer one of the stream before it was sent is
/// answered ok and `superseded`; a refused setpoint is refused with its
/// rule; a stream's setpoint ends the watch of an ordinary move on the
/// joint (that line will not arrive), and `"stream"` that is not a
/// boolean is invalid.
#[test]
fn a_stream_supersedes_refuses_and_replaces_ordinary_moves() {
    let mut arm = common::arm(MAP, Faults::default(), 0);
    arm.line(Origin(1), &common::command("elbow", 100.0));
    let r = common::results(&mut arm, 1, Duration::from_secs(1));
    assert_eq!(r[0]["arrival_follows"], true, "{}", r[0]);
    // Three at once: the first goes, the second waits for it and is
    // replaced by the third.
    for s in [40.0, 50.0, 55.0] {
        arm.line(Origin(1), &stream("elbow", s));
    }
    arm.line(Origin(1), &stream("elbow", 170.0));
    arm.line(
        Origin(1),
        r#"{"motor_id":"elbow","timestamp":1704067200000,"control_mode":"position","setpoint":1,"stream":"yes"}"#,
    );
    arm.run_until(arm.now() + Duration::from_millis(200))
        .unwrap();
    let out: Vec<Value> = arm.take_outputs().iter().map(|o| o.to_value()).collect();
    let result = |line: u64| {
        out.iter()
            .find(|v| v.get("ok").is_some() && v.get("event").is_none() && v["line"] == line)
            .unwrap_or_else(|| panic!("no result for line {line}: {out:?}"))
    };
    assert_eq!(result(2)["ok"], true);
    assert_eq!(result(2)["acked"], serde_json::json!(["elbow"]));
    assert_eq!(result(3)["ok"], true, "{}", result(3));
    assert_eq!(result(3)["superseded"], true, "{}", result(3));
    assert_eq!(result(3)["acked"], serde_json::json!([]), "{}", result(3));
    assert_eq!(result(4)["ok"], true);
    assert_eq!(result(5)["ok"], false);
    assert_eq!(result(5)["error"]["rule"], "outside_limit", "{}", result(5));
    assert_eq!(result(6)["ok"], false);
    assert_eq!(
        result(6)["error"]["message"],
        "stream is \"yes\": it is true (the command is a setpoint of a stream) or false"
    );
    // The ordinary move's completion: replaced by the stream's line 2.
    assert_line_1_superseded_by_line_2(&out);
    assert_eq!(out.iter().filter(|v| v.get("arrived").is_some()).count(), 1);
    arm.run_until(arm.now() + Duration::from_secs(2)).unwrap();
    assert!((arm.joint(ELBOW).unwrap().position() - 55.0).abs() < 0.01);
}

/// A stream's velocity setpoints, many at once: each waiting one is
/// replaced by the next (answered ok and superseded, never sent), none is
/// refused for room, and the device ends on the newest; a velocity
/// setpoint of a stream ends the watch of an ordinary move on the motor.
#[test]
fn a_streams_velocity_setpoints_replace_each_other_and_ordinary_moves() {
    let mut arm = common::arm(MAP, Faults::default(), 0);
    let velocity = |v: f64| {
        format!(
            r#"{{"motor_id":"gripper_axis","timestamp":1704067200000,"control_mode":"velocity","setpoint":{v},"stream":true}}"#
        )
    };
    arm.line(
        Origin(1),
        r#"{"motor_id":"gripper_axis","timestamp":1704067200000,"control_mode":"position","setpoint":80}"#,
    );
    arm.run_until(arm.now() + Duration::from_millis(20))
        .unwrap();
    for k in 0..40u32 {
        arm.line(Origin(1), &velocity(1.0 + f64::from(k) * 0.1));
    }
    arm.run_until(arm.now() + Duration::from_millis(100))
        .unwrap();
    let out: Vec<Value> = arm.take_outputs().iter().map(|o| o.to_value()).collect();
    let results: Vec<&Value> = out
        .iter()
        .filter(|v| v.get("ok").is_some() && v.get("event").is_none())
        .collect();
    assert_eq!(results.len(), 41, "{results:?}");
    assert!(results.iter().all(|r| r["ok"] == true), "{results:?}");
    let superseded = results.iter().filter(|r| r["superseded"] == true).count();
    assert!(superseded >= 30, "{superseded} of 40 replaced: {results:?}");
    let last = results.iter().find(|r| r["line"] == 41).unwrap();
    assert_eq!(last["acked"], serde_json::json!(["gripper_axis"]), "{last}");
    // The newest setpoint is what the device runs.
    let device = arm.compact_device(0x20).unwrap();
    assert!(
        (device.velocity() - 4.9).abs() < 1e-3,
        "{}",
        device.velocity()
    );
    // The ordinary move's completion: replaced by the stream's first
    // setpoint.
    assert_line_1_superseded_by_line_2(&out);
}

/// The first completion among `out` is line 1's, not arrived, replaced by
/// client 1's line 2.
fn assert_line_1_superseded_by_line_2(out: &[Value]) {
    let arrival = out
        .iter()
        .find(|v| v.get("arrived").is_some())
        .unwrap_or_else(|| panic!("{out:?}"));
    assert_eq!(arrival["line"], 1);
    assert_eq!(arrival["arrived"], false);
    assert_eq!(arrival["reason"], "superseded by line 2 of client 1");
}
/// A sequential line whose first motor is given a newer line before it
/// arrived: the axes waiting for that arrival are not sent, at once (not
/// when the arrival's time runs out), and the line's completion says it
/// was superseded; by an ordinary line and by a stream's setpoint alike.
#[test]
fn a_sequential_line_ends_when_its_first_motor_is_moved_elsewhere() {
    for extra in ["", r#","stream":true"#] {
        let mut arm = common::arm(MAP, Faults::default(), 0);
        arm.line(
            Origin(1),
            r#"{"command_id":"seq","timestamp":1704067200000,"sync_mode":"sequential","motors":[{"motor_id":"elbow","control_mode":"position","setpoint":140},{"motor_id":"gripper_axis","control_mode":"position","setpoint":80}]}"#,
        );
        arm.run_until(arm.now() + Duration::from_millis(300))
            .unwrap();
        arm.take_outputs();
        arm.line(
            Origin(1),
            &format!(
                r#"{{"motor_id":"elbow","timestamp":1704067200000,"control_mode":"position","setpoint":20{extra}}}"#
            ),
        );
        arm.run_until(arm.now() + Duration::from_millis(50))
            .unwrap();
        let out: Vec<Value> = arm.take_outputs().iter().map(|o| o.to_value()).collect();
        let first = out
            .iter()
            .find(|v| v.get("ok").is_some() && v["line"] == 1)
            .unwrap_or_else(|| panic!("{extra}: {out:?}"));
        assert_eq!(first["ok"], false, "{first}");
        assert_eq!(first["outcomes"][0]["motor"], "gripper_axis", "{first}");
        assert_eq!(first["outcomes"][0]["outcome"], "not_sent", "{first}");
        assert_eq!(
            first["outcomes"][0]["message"],
            "not sent: the axis before it was replaced by line 2 of client 1 before it arrived"
        );
        let arrival = out
            .iter()
            .find(|v| v.get("arrived").is_some() && v["line"] == 1)
            .unwrap_or_else(|| panic!("{extra}: {out:?}"));
        assert_eq!(arrival["arrived"], false);
        assert_eq!(arrival["reason"], "superseded by line 2 of client 1");
        // The gripper never moved.
        assert!(arm.compact_device(0x20).unwrap().position().abs() < 1e-6);
    }
}

/// `{"feedback_hz":N}` is answered with the rate the client gets: the
/// bridge's (10 Hz by default) over the smallest whole k that keeps it at
/// or below N (the result's `feedback_hz`, and `feedback_every` k for the
/// runner that delivers); 0 is none; above the bridge's, negative, or any
/// but 0 on a bridge without feedback, refused naming the limit.
#[test]
fn a_feedback_rate_is_answered_with_the_rate_the_client_gets() {
    let mut arm = common::arm(MAP, Faults::default(), 0);
    let answer = |arm: &mut SimulatedArm, line: &str| {
        arm.take_outputs();
        arm.line(Origin(1), line);
        let o = arm.take_outputs();
        let r = o.iter().find_map(Output::result).unwrap().clone();
        (
            r.feedback_every,
            o.iter().find(|o| o.result().is_some()).unwrap().to_value(),
        )
    };
    for (asked, every, hz) in [
        (10.0, 1, 10.0),
        (3.0, 4, 2.5),
        (5.0, 2, 5.0),
        (0.0, 0, 0.0),
        (0.001, 10_000, 0.001),
    ] {
        let (e, v) = answer(&mut arm, &format!(r#"{{"feedback_hz":{asked}}}"#));
        assert_eq!(e, Some(every), "{v}");
        assert_eq!(v["ok"], true, "{v}");
        assert_eq!(v["feedback_hz"], hz, "{v}");
    }
    for asked in ["10.5", "-1", "1e300", "1e-300", "5e-324"] {
        let (e, v) = answer(&mut arm, &format!(r#"{{"feedback_hz":{asked}}}"#));
        assert_eq!(e, None, "{v}");
        assert_eq!(v["ok"], false, "{v}");
        assert_eq!(v["error"]["kind"], "invalid", "{v}");
        assert_eq!(v["error"]["limit"], 10.0, "{v}");
        assert_eq!(
            v["error"]["limit_source"], "the bridge's --feedback-hz",
            "{v}"
        );
    }
    // Found by a hostile test: extreme numbers are said in short, and a
    // rate slower than every 2^32 - 1-th line is refused, not answered
    // with a faster one.
    let (_, v) = answer(&mut arm, r#"{"feedback_hz":1e300}"#);
    assert_eq!(
        v["error"]["message"], "feedback_hz 1e300 is above the bridge's own rate, 10",
        "{v}"
    );
    let (_, v) = answer(&mut arm, r#"{"feedback_hz":1e-300}"#);
    assert_eq!(
        v["error"]["message"],
        "feedback_hz 1e-300 is below the slowest rate, the bridge's divided by 4294967295 (2.3283064370807974e-9); 0 turns feedback off",
        "{v}"
    );
    let config = BridgeConfig {
        feedback_period: None,
        ..BridgeConfig::default()
    };
    let mut quiet = started(BusMap::from_toml(MAP).unwrap(), config);
    let (_, v) = answer(&mut quiet, r#"{"feedback_hz":1}"#);
    assert_eq!(
        v["error"]["message"],
        "feedback_hz 1: the bridge sends no feedback (--feedback-hz 0); 0 is the only rate",
        "{v}"
    );
    let (e, v) = answer(&mut quiet, r#"{"feedback_hz":0}"#);
    assert_eq!((e, &v["feedback_hz"]), (Some(0), &Value::from(0.0)), "{v}");
}

/// The issue's case of a simultaneous line: sent 0.2 s after a trajectory
/// started on the elbow, it replaces the rest of the trajectory and plans
/// the elbow from where it is and how fast it moves. Both joints come to
/// rest at their targets within 1 ms of each other, at the time the
/// result's losses promise (within 1.5 ms), and each motor's `after_ms` in
/// the completion is its own arrival (within its arrival tolerance, seen
/// by a report: its reports come every 10 ms).
/// Also from rest, and with the elbow moving toward, and away from, its
/// new target.
#[test]
fn a_simultaneous_line_is_simultaneous_from_a_moving_start() {
    let trajectory = |to: f64| {
        format!(
            r#"{{"trajectory_id":"t","motor_id":"elbow","waypoints":[{{"position":0,"velocity":0,"time":0}},{{"position":{to},"velocity":0,"time":1.5}}],"timing":{{}}}}"#
        )
    };
    // (the elbow's trajectory first, if any, a negative one: a stream of
    // setpoints at 100 Hz up to it; the elbow's and the shoulder's
    // targets)
    for (first, elbow, shoulder) in [
        (Some(60.0), 100.0, 30.0),
        (Some(60.0), 10.0, -40.0),
        (None, 100.0, 30.0),
        (Some(90.0), 40.0, 5.0),
        (Some(-50.0), 20.0, 10.0),
    ] {
        let mut arm = common::arm(MAP, Faults::default(), 0);
        match first {
            Some(to) if to > 0.0 => {
                arm.line(Origin(1), &trajectory(to));
                arm.run_until(arm.now() + Duration::from_millis(200))
                    .unwrap();
            }
            Some(to) => {
                for k in 1..=20 {
                    let setpoint = -to * f64::from(k) / 20.0;
                    arm.line(
                        Origin(1),
                        &format!(
                            r#"{{"motor_id":"elbow","timestamp":1704067200000,"control_mode":"position","setpoint":{setpoint},"stream":true}}"#
                        ),
                    );
                    arm.run_until(arm.now() + Duration::from_millis(10))
                        .unwrap();
                }
            }
            None => {}
        }
        if first.is_some() {
            assert!(arm.joint(ELBOW).unwrap().velocity().abs() > 1.0, "moving");
        }
        arm.take_outputs();
        let sent = arm.now();
        arm.line(
            Origin(1),
            &format!(
                r#"{{"command_id":"sync","timestamp":1704067200000,"sync_mode":"simultaneous","motors":[{{"motor_id":"elbow","control_mode":"position","setpoint":{elbow}}},{{"motor_id":"shoulder_pitch","control_mode":"position","setpoint":{shoulder}}}]}}"#
            ),
        );
        // Each joint's arrival: when it first stands at its target.
        let mut arrived: [Option<Duration>; 2] = [None, None];
        let mut out: Vec<Value> = Vec::new();
        while arrived.iter().any(Option::is_none) && arm.now() < sent + Duration::from_secs(6) {
            arm.run_until(arm.now() + Duration::from_micros(250))
                .unwrap();
            out.extend(arm.take_outputs().iter().map(Output::to_value));
            for (k, (node, target)) in [(ELBOW, elbow), (PITCH, shoulder)].into_iter().enumerate() {
                let j = arm.joint(node).unwrap();
                if arrived[k].is_none()
                    && (j.position() - target).abs() < 1e-3
                    && j.velocity().abs() < 1e-3
                {
                    arrived[k] = Some(arm.now());
                }
            }
        }
        let [Some(e), Some(s)] = arrived else {
            panic!("{first:?}: not both arrived: {arrived:?} {out:?}");
        };
        let apart = e.abs_diff(s);
        assert!(
            apart <= Duration::from_millis(1),
            "{first:?}: the elbow at {e:?}, the shoulder at {s:?}: {apart:?} apart"
        );
        let result = out
            .iter()
            .find(|v| v.get("ok").is_some() && v["command_id"] == "sync")
            .unwrap();
        assert_eq!(result["ok"], true, "{result}");
        let promised: f64 = result["losses"]
            .as_array()
            .unwrap()
            .iter()
            .find_map(|l| {
                let l = l.as_str()?;
                let at = l.find("every joint arrives after ")? + "every joint arrives after ".len();
                l.get(at..)?.strip_suffix(" s")?.parse().ok()
            })
            .unwrap_or_else(|| panic!("{first:?}: no promise in {result}"));
        let last = e.max(s).saturating_sub(sent).as_secs_f64();
        assert!(
            (last - promised).abs() <= 0.0015,
            "{first:?}: promised {promised} s, both at rest after {last} s"
        );
        // Run on until the completion comes.
        arm.run_until(arm.now() + Duration::from_millis(300))
            .unwrap();
        out.extend(arm.take_outputs().iter().map(Output::to_value));
        let done = out
            .iter()
            .find(|v| v.get("arrived").is_some() && v["command_id"] == "sync")
            .unwrap_or_else(|| panic!("{first:?}: no completion: {out:?}"));
        assert_eq!(done["arrived"], true, "{done}");
        for m in done["motors"].as_array().unwrap() {
            let at = if m["motor_id"] == "elbow" { e } else { s };
            let own = at.saturating_sub(sent).as_millis() as i64;
            let said = m["after_ms"].as_i64().unwrap();
            // Within its arrival tolerance (0.1°) a little before it is
            // at rest, seen by a report (every 10 ms) after.
            assert!(
                (own - 50..=own + 12).contains(&said),
                "{first:?}: {} said after_ms {said}, it came to rest after {own} ms: {done}",
                m["motor_id"]
            );
        }
    }
}

fn sequential(id: &str, motors: &[(&str, f64)]) -> String {
    let motors: Vec<String> = motors
        .iter()
        .map(|(m, s)| format!(r#"{{"motor_id":"{m}","control_mode":"position","setpoint":{s}}}"#))
        .collect();
    format!(
        r#"{{"command_id":"{id}","timestamp":1704067200000,"sync_mode":"sequential","motors":[{}]}}"#,
        motors.join(",")
    )
}

fn completion<'a>(out: &'a [Value], origin_line: (&str, u64)) -> &'a Value {
    out.iter()
        .find(|v| {
            v.get("arrived").is_some()
                && v["line"] == origin_line.1
                && (v["command_id"] == origin_line.0 || v["motor_id"] == origin_line.0)
        })
        .unwrap_or_else(|| panic!("no completion for {origin_line:?}: {out:?}"))
}

/// Found by a hostile test: a sequential line of three or four axes whose
/// first motor is moved by a newer line ends at once, every waiting axis
/// not sent (not only the next one), its completion superseded by the
/// newer line; the newer line, which the elbow carries out, arrives (it
/// was called superseded by the older line, which timed out).
#[test]
fn a_long_sequential_line_ends_whole_and_never_supersedes_the_newer_line() {
    for axes in [3, 4] {
        let mut arm = common::arm(MAP, Faults::default(), 0);
        let all = [
            ("elbow", 60.0),
            ("shoulder_roll", 20.0),
            ("gripper_axis", 40.0),
            ("shoulder_pitch", 30.0),
        ];
        arm.line(Origin(1), &sequential("seq", &all[..axes]));
        common::run_for(&mut arm, common::ms(300));
        arm.line(Origin(2), &common::command("elbow", 10.0));
        let out = common::run_for(&mut arm, common::ms(30));
        let first = out
            .iter()
            .find(|v| v.get("ok").is_some() && v["command_id"] == "seq")
            .unwrap_or_else(|| panic!("{axes}: {out:?}"));
        assert_eq!(first["ok"], false, "{first}");
        let outcomes = first["outcomes"].as_array().unwrap();
        assert_eq!(outcomes.len(), axes - 1, "{first}");
        assert!(
            outcomes.iter().all(|o| o["outcome"] == "not_sent"),
            "{first}"
        );
        let seq = completion(&out, ("seq", 1));
        assert_eq!(seq["arrived"], false, "{seq}");
        assert_eq!(seq["reason"], "superseded by line 1 of client 2", "{seq}");
        let out = common::run_for(&mut arm, common::ms(3000));
        let newer = completion(&out, ("elbow", 1));
        assert_eq!(newer["arrived"], true, "{axes}: {newer}");
        assert!(arm.compact_device(0x20).unwrap().position().abs() < 1e-6);
        assert!(arm.joint(ROLL).unwrap().position().abs() < 1e-6);
    }
}

/// Found by a hostile test: a line whose move a newer sequential line (or
/// any line) replaces is superseded when the newer move is taken, not when
/// the newer line ends (a sequential line ends with its last axis: the
/// older one had timed out by then).
#[test]
fn a_move_replaced_by_a_sequential_lines_axis_is_superseded_when_it_is_taken() {
    for older in [
        sequential("a", &[("elbow", 20.0), ("gripper_axis", 80.0)]),
        common::command("elbow", 30.0),
    ] {
        let mut arm = common::arm(MAP, Faults::default(), 0);
        arm.line(Origin(1), &older);
        common::run_for(&mut arm, common::ms(200));
        arm.line(
            Origin(2),
            &sequential("b", &[("elbow", 140.0), ("shoulder_pitch", 30.0)]),
        );
        let out = common::run_for(&mut arm, common::ms(30));
        let replaced = out
            .iter()
            .find(|v| v.get("arrived").is_some() && v["line"] == 1 && v["command_id"] != "b")
            .unwrap_or_else(|| panic!("{older}: not superseded at once: {out:?}"));
        assert_eq!(replaced["arrived"], false, "{replaced}");
        assert_eq!(
            replaced["reason"], "superseded by line 1 of client 2",
            "{replaced}"
        );
        let out = common::run_for(&mut arm, common::ms(5000));
        assert_eq!(completion(&out, ("b", 1))["arrived"], true, "{out:?}");
    }
}

/// Found by a hostile test: a sequential line that an emergency stop cuts
/// says so in its completion at once (it said `timed out` a second later,
/// where a single command says `stopped by the emergency stop`).
#[test]
fn a_sequential_line_cut_by_a_stop_says_so_at_once() {
    let mut arm = common::arm(MAP, Faults::default(), 0);
    arm.line(
        Origin(1),
        &sequential("seq", &[("elbow", 60.0), ("gripper_axis", 40.0)]),
    );
    common::run_for(&mut arm, common::ms(300));
    arm.line(Origin(2), r#"{"emergency_stop":true}"#);
    let out = common::run_for(&mut arm, common::ms(30));
    let seq = completion(&out, ("seq", 1));
    assert_eq!(seq["arrived"], false, "{seq}");
    assert_eq!(seq["reason"], "stopped by the emergency stop", "{seq}");
}

/// Found by a hostile test: a newer line's axis that waits (its own
/// sequence's earlier axis not arrived) has replaced nothing yet: the
/// older line's sequence goes on until that axis is sent.
#[test]
fn a_waiting_axis_replaces_nothing_until_it_is_sent() {
    let mut arm = common::arm(MAP, Faults::default(), 0);
    arm.line(
        Origin(1),
        &sequential("a", &[("elbow", 100.0), ("gripper_axis", 80.0)]),
    );
    arm.line(
        Origin(2),
        &sequential("c", &[("shoulder_roll", -30.0), ("elbow", 30.0)]),
    );
    let out = common::run_for(&mut arm, common::ms(50));
    assert!(
        !out.iter()
            .any(|v| v["command_id"] == "a" && v.get("ok").is_some()),
        "line a was answered before c's elbow axis went: {out:?}"
    );
}

/// Found by a hostile test: a move is held to the limits from where the
/// joint is when its turn comes, not only when its line came (a sequential
/// or independent multi-axis line had no path check at all). A sequential
/// line's slow-braking elbow move to 149 waits for the shoulder to arrive
/// while an earlier line drives the elbow to 140 at full speed: when its
/// turn comes its path would run far past 150. It is not sent, and its
/// result says why.
#[test]
fn a_move_is_held_to_the_limits_from_where_the_joint_is_when_it_is_sent() {
    let mut arm = common::arm(MAP, Faults::default(), 0);
    arm.take_outputs();
    arm.line(Origin(1), &common::command("elbow", 140.0));
    arm.line(
        Origin(1),
        r#"{"command_id":"seq","timestamp":1704067200000,"sync_mode":"sequential","motors":[{"motor_id":"shoulder_pitch","control_mode":"position","setpoint":10},{"motor_id":"elbow","control_mode":"position","setpoint":149,"acceleration_limit":20}]}"#,
    );
    let out = common::run_for(&mut arm, common::ms(3000));
    let second = out
        .iter()
        .find(|v| v.get("ok").is_some() && v["line"] == 2)
        .unwrap_or_else(|| panic!("{out:?}"));
    assert_eq!(second["ok"], false, "{second}");
    assert_eq!(second["outcomes"][0]["outcome"], "not_sent", "{second}");
    let why = second["outcomes"][0]["message"].as_str().unwrap();
    assert!(
        why.starts_with("not sent: from where it was when its turn came (")
            && why.contains("past max_position (bus map) 150"),
        "{why}"
    );
    let targets = targets_taken(&arm, ELBOW);
    assert_eq!(targets, [140.0], "only the first move reached the elbow");
    assert_eq!(arm.bridge().stats().refused_at_send, 1);
}

/// Found by a hostile test: a trajectory scheduled to start later holds
/// nothing meanwhile. A command for its joint sent before it starts goes
/// at once (it waited for the trajectory, forever behind one looping
/// forever); the trajectory still starts at its time, replacing that move.
#[test]
fn a_scheduled_trajectory_does_not_hold_its_joint_until_it_starts() {
    let (mut arm, t0) = with_wall_clock();
    arm.line(
        Origin(1),
        &format!(
            r#"{{"trajectory_id":"later","motor_id":"elbow","waypoints":[{{"position":0,"velocity":0,"time":0}},{{"position":60,"velocity":0,"time":1.5}},{{"position":0,"velocity":0,"time":3}}],"timing":{{"start_time":{}}},"loop":{{"enabled":true,"count":-1}}}}"#,
            t0 + 1500.0
        ),
    );
    common::run_for(&mut arm, common::ms(300));
    arm.line(
        Origin(2),
        &format!(
            r#"{{"motor_id":"elbow","timestamp":{},"control_mode":"position","setpoint":30}}"#,
            t0 + 300.0
        ),
    );
    let out = common::run_for(&mut arm, common::ms(30));
    let moved = out
        .iter()
        .find(|v| v.get("ok").is_some() && v["motor_id"] == "elbow")
        .unwrap_or_else(|| panic!("the command was not answered at once: {out:?}"));
    assert_eq!(moved["ok"], true, "{moved}");
    let out = common::run_for(&mut arm, common::ms(2500));
    let to_30 = completion(&out, ("elbow", 1));
    assert_eq!(
        to_30["arrived"], true,
        "it got to 30 before the trajectory's start: {to_30}"
    );
    let targets = targets_taken(&arm, ELBOW);
    // The command's move, then the trajectory's first segment at its time.
    assert_eq!(targets, [30.0, 60.0], "{targets:?}");
}

/// Found by a hostile test: an axis of a sequential line waiting for its
/// turn replaces nothing (a running trajectory on its motor went on until
/// the axis was sent: it was cut when the line came), and it holds its
/// motor for nobody: a newer line for that motor (here a trajectory, and
/// a velocity setpoint for the gripper) replaces it at once.
#[test]
fn a_waiting_sequential_axis_neither_cuts_nor_holds_its_motor() {
    let mut arm = common::arm(MAP, Faults::default(), 0);
    let pitch_loop = r#"{"trajectory_id":"t2","motor_id":"shoulder_pitch","waypoints":[{"position":0,"velocity":0,"time":0},{"position":-40,"velocity":0,"time":1.2},{"position":0,"velocity":0,"time":2.4}],"timing":{},"loop":{"enabled":true,"count":-1}}"#;
    arm.line(Origin(1), pitch_loop);
    common::run_for(&mut arm, common::ms(500));
    arm.line(
        Origin(2),
        &sequential("seq", &[("elbow", 100.0), ("shoulder_pitch", 30.0)]),
    );
    let out = common::run_for(&mut arm, common::ms(500));
    assert!(
        !out.iter().any(|v| v.get("arrived").is_some()
            && v["line"] == 1
            && v["motor_id"] == "shoulder_pitch"),
        "the waiting axis cut the trajectory: {out:?}"
    );
    // Its turn comes once the elbow is at 100: then it replaces the loop.
    let out = common::run_for(&mut arm, common::ms(3000));
    let looped = completion(&out, ("shoulder_pitch", 1));
    assert_eq!(looped["arrived"], false, "{looped}");
    // A newer line for a motor a waiting axis holds takes it at once.
    let mut arm = self::common::arm(MAP, Faults::default(), 0);
    arm.line(
        Origin(1),
        &sequential("seq", &[("elbow", 140.0), ("gripper_axis", 60.0)]),
    );
    common::run_for(&mut arm, common::ms(100));
    arm.line(
        Origin(2),
        r#"{"motor_id":"gripper_axis","timestamp":1704067200000,"control_mode":"velocity","setpoint":5}"#,
    );
    let out = common::run_for(&mut arm, common::ms(30));
    let velocity = out
        .iter()
        .find(|v| v.get("ok").is_some() && v["motor_id"] == "gripper_axis")
        .unwrap_or_else(|| panic!("the velocity line waited: {out:?}"));
    assert_eq!(velocity["ok"], true, "{velocity}");
    let seq = out
        .iter()
        .find(|v| v.get("ok").is_some() && v["command_id"] == "seq")
        .unwrap_or_else(|| panic!("{out:?}"));
    assert_eq!(seq["outcomes"][0]["motor"], "gripper_axis", "{seq}");
    assert_eq!(seq["outcomes"][0]["outcome"], "superseded", "{seq}");
}

/// Found by a hostile test: `sync_mode: sequential` with
/// `coordination.total_duration_ms` ran each axis over the whole duration,
/// one after another, and promised them all after it: refused.
#[test]
fn sequential_with_a_total_duration_is_refused() {
    let mut arm = common::arm(MAP, Faults::default(), 0);
    arm.line(
        Origin(1),
        r#"{"command_id":"c","timestamp":1704067200000,"sync_mode":"sequential","coordination":{"total_duration_ms":2500},"motors":[{"motor_id":"elbow","control_mode":"position","setpoint":10},{"motor_id":"shoulder_pitch","control_mode":"position","setpoint":30}]}"#,
    );
    let out = common::run_for(&mut arm, common::ms(20));
    let r = out
        .iter()
        .find(|v| v.get("ok").is_some() && v["line"] == 1)
        .unwrap();
    assert_eq!(r["ok"], false, "{r}");
    assert_eq!(r["error"]["kind"], "invalid", "{r}");
    assert!(
        r["error"]["message"]
            .as_str()
            .unwrap()
            .starts_with("sync_mode sequential runs the axes one after another")
    );
}

/// Found by a hostile test: a compact device's emergency stop is
/// acknowledged only by a record that shows the device stopped (`enabled`
/// clear). Its stop frame lost on the bus, the device's next periodic
/// record (still driving) acknowledged it, the stop was reported `acked`
/// and the gripper ran on to its target; now the stop is sent again until
/// a record says the device holds still.
#[test]
fn a_compact_stop_is_acknowledged_only_by_a_record_that_shows_it() {
    use motorwire_can::{CanId, Frame};
    use motorwire_compact::{FeedbackRecord, MotorHash, StatusFlag, StatusFlags};
    let map = BusMap::from_toml(
        r#"
[motors.gripper_axis]
dialect = "compact"
node = 0x20
limits = { min_position = 0, max_position = 90, max_velocity = 60, max_torque = 5 }
"#,
    )
    .unwrap();
    let config = BridgeConfig {
        activate_on_start: false,
        ..BridgeConfig::default()
    };
    let mut bridge = Bridge::new(map, config).unwrap();
    let ms = Duration::from_millis;
    bridge.start(Duration::ZERO);
    let record = |enabled: bool| {
        let r = FeedbackRecord {
            motor: MotorHash::of("gripper_axis"),
            timestamp_us: 0,
            position: 30.0,
            velocity: if enabled { 60.0 } else { 0.0 },
            acceleration: 0.0,
            torque: 0.0,
            current: 0.0,
            voltage: 24.0,
            temperature: 30.0,
            status: StatusFlags::EMPTY.set(StatusFlag::Enabled, enabled),
            health: 100,
        };
        Frame::fd(CanId::standard(0x420).unwrap(), &r.encode().unwrap()).unwrap()
    };
    bridge.handle_line(ms(1), Origin(1), r#"{"emergency_stop":true}"#);
    // Runs the bridge at `t`: how many frames it sent.
    let drain = |b: &mut Bridge, t: u64| {
        b.handle_timeout(ms(t));
        let mut sent = 0;
        while b.poll_transmit().is_some() {
            sent += 1;
        }
        b.flushed(ms(t));
        sent
    };
    let mut stops = 0;
    stops += drain(&mut bridge, 1);
    // A record the device sent before the (lost) stop reached it.
    bridge.handle_frame(ms(20), &record(true));
    stops += drain(&mut bridge, 20);
    let results = |b: &mut Bridge| -> Vec<Value> {
        std::iter::from_fn(|| b.poll_output())
            .filter(|o| o.result().is_some())
            .map(|o| o.to_value())
            .collect()
    };
    assert_eq!(
        results(&mut bridge),
        Vec::<Value>::new(),
        "not acked by a driving record"
    );
    // Its time-out: sent again; then a record that shows it stopped.
    stops += drain(&mut bridge, 150);
    assert_eq!(stops, 2, "sent again");
    bridge.handle_frame(ms(160), &record(false));
    drain(&mut bridge, 160);
    let r = results(&mut bridge);
    assert_eq!(r[0]["ok"], true, "{r:?}");
    assert_eq!(r[0]["acked"], serde_json::json!(["gripper_axis"]), "{r:?}");
}

/// Found by a hostile test: a move sent again by the client's retries (its
/// first sending unanswered: lost, or its Ack lost) goes now, and is held
/// to the limits from where the joint is now. Sent with the elbow at 100
/// moving 100 deg/s toward 150 (braking at 400 it stops by 112.5), its
/// answer lost; at its resend the elbow is at 142 still moving 100 deg/s
/// (it would stop past 150): withdrawn, never sent again, its outcome
/// unknown, saying why.
#[test]
fn a_move_sent_again_is_held_to_the_limits_from_where_the_joint_is_then() {
    use motorwire_can::{CanId, Frame};
    use motorwire_irpc::{EncoderTelemetry, Header, Message, WireVersion};
    let config = BridgeConfig {
        activate_on_start: false,
        feedback_period: None,
        ..BridgeConfig::default()
    };
    let mut bridge = Bridge::new(BusMap::from_toml(MAP).unwrap(), config).unwrap();
    bridge.start(Duration::ZERO);
    let ms = Duration::from_millis;
    let mut msg_id = 0;
    let mut encoder = |b: &mut Bridge, t: u64, position: f32, velocity: f32| {
        msg_id += 1;
        let m = Message {
            header: Header {
                source_id: ELBOW,
                target_id: 0,
                msg_id,
            },
            payload: Payload::Encoder(EncoderTelemetry { position, velocity }),
        };
        let mut buf = [0u8; 64];
        let n = m.encode_frame(WireVersion::V2_0, &mut buf).unwrap();
        b.handle_frame(
            ms(t),
            &Frame::fd(CanId::standard(ELBOW).unwrap(), &buf[..n]).unwrap(),
        );
    };
    encoder(&mut bridge, 0, 99.0, 100.0);
    encoder(&mut bridge, 10, 100.0, 100.0);
    bridge.handle_line(ms(10), Origin(1), &common::command("elbow", 105.0));
    let mut moves = 0;
    let mut run = |b: &mut Bridge, t: u64| {
        b.handle_timeout(ms(t));
        while let Some(f) = b.poll_transmit() {
            let m = Message::decode_frame(WireVersion::V2_0, f.data()).unwrap();
            if matches!(m.payload, Payload::SetTargetV2(_)) {
                moves += 1;
            }
        }
        b.flushed(ms(t));
    };
    run(&mut bridge, 10);
    // No answer; the elbow reports it goes on at 100 deg/s.
    for t in (20..=110).step_by(10) {
        #[allow(clippy::cast_precision_loss)]
        encoder(&mut bridge, t, 100.0 + (t - 10) as f32 * 0.42, 100.0);
        run(&mut bridge, t);
    }
    assert_eq!(moves, 1, "sent once, not again");
    let out: Vec<Value> = std::iter::from_fn(|| bridge.poll_output())
        .map(|o| o.to_value())
        .collect();
    let r = out
        .iter()
        .find(|v| v.get("ok").is_some() && v["line"] == 1)
        .unwrap_or_else(|| panic!("{out:?}"));
    assert_eq!(r["ok"], false, "{r}");
    assert_eq!(r["outcomes"][0]["outcome"], "outcome_unknown", "{r}");
    let why = r["outcomes"][0]["message"].as_str().unwrap();
    assert!(
        why.starts_with(
            "sent once and not answered; not sent again: from where it was when its turn came ("
        ) && why.contains("past max_position (bus map) 150")
            && why.ends_with("the joint may or may not have taken its first sending"),
        "{why}"
    );
    assert_eq!(bridge.stats().refused_at_send, 1);
}

/// The targets of the `SetTargetV2`s joint `node` received, in order.
fn targets_taken(arm: &SimulatedArm, node: u16) -> Vec<f32> {
    arm.joint(node)
        .unwrap()
        .log()
        .iter()
        .filter_map(|e| match e.payload {
            Payload::SetTargetV2(p) => Some(p.target_angle),
            _ => None,
        })
        .collect()
}

/// Found by a review of the change: a trajectory line queues behind a
/// trajectory already scheduled on the joint, as it always did (taking the
/// scheduled one off the joint is for a step that goes at once): two
/// scheduled trajectories run in the order of their times.
#[test]
fn scheduled_trajectories_run_in_their_order() {
    let (mut arm, t0) = with_wall_clock();
    let trajectory = |to: f64, start: f64| {
        format!(
            r#"{{"trajectory_id":"t{to}","motor_id":"elbow","waypoints":[{{"position":0,"velocity":0,"time":0}},{{"position":{to},"velocity":0,"time":1.5}}],"timing":{{"start_time":{start}}}}}"#
        )
    };
    arm.line(Origin(1), &trajectory(40.0, t0 + 300.0));
    arm.line(Origin(1), &trajectory(60.0, t0 + 3000.0));
    common::run_for(&mut arm, common::ms(5000));
    assert_eq!(targets_taken(&arm, ELBOW), [40.0, 60.0]);
}

/// The demo arm, ready, its bridge with a wall clock: and the Unix ms it
/// reads now (for `start_time` and timestamps).
fn with_wall_clock() -> (SimulatedArm, f64) {
    const EPOCH: f64 = 1_767_225_600_000.0;
    let config = BridgeConfig {
        epoch_unix_ms: Some(EPOCH),
        ..BridgeConfig::default()
    };
    let arm = started(BusMap::from_toml(MAP).unwrap(), config);
    let t0 = EPOCH + arm.now().as_secs_f64() * 1000.0;
    (arm, t0)
}

/// A Rust program's typed WIA values are read exactly as their lines are
/// (`Input::Command` and the rest): the same validation, the same gate,
/// the same result, on the same simulated arm.
#[test]
fn typed_inputs_are_answered_as_their_lines_are() {
    use motorwire_bridge::Input;
    use motorwire_bridge::motorwire_wia::{
        MotorCommand, MultiAxisCommand, SafetyLimits, Trajectory,
    };
    let trajectory = include_str!("../../../fixtures/wia/valid/doc-5.2-trajectory.json");
    let limits = include_str!("../../../fixtures/wia/valid/safety-limits.json");
    type Typed = Box<dyn Fn(Origin) -> Input<'static>>;
    let cases: Vec<(String, Typed)> = vec![
        (common::command("elbow", 30.0), {
            let c: MotorCommand = serde_json::from_str(&common::command("elbow", 30.0)).unwrap();
            Box::new(move |origin| Input::Command {
                origin,
                command: Box::new(c.clone()),
            })
        }),
        (common::command("elbow", 1e9), {
            let c: MotorCommand = serde_json::from_str(&common::command("elbow", 1e9)).unwrap();
            Box::new(move |origin| Input::Command {
                origin,
                command: Box::new(c.clone()),
            })
        }),
        (MULTI.to_owned(), {
            let c: MultiAxisCommand = serde_json::from_str(MULTI).unwrap();
            Box::new(move |origin| Input::MultiAxis {
                origin,
                command: Box::new(c.clone()),
            })
        }),
        (trajectory.to_owned(), {
            let t: Trajectory = serde_json::from_str(trajectory).unwrap();
            Box::new(move |origin| Input::Trajectory {
                origin,
                trajectory: Box::new(t.clone()),
            })
        }),
        (limits.to_owned(), {
            let l: SafetyLimits = serde_json::from_str(limits).unwrap();
            Box::new(move |origin| Input::SafetyLimits {
                origin,
                limits: Box::new(l.clone()),
            })
        }),
        (
            r#"{"emergency_stop": true}"#.to_owned(),
            Box::new(|origin| Input::EmergencyStop { origin }),
        ),
    ];
    for (line, typed) in &cases {
        let mut by_line = common::arm(MAP, Faults::default(), 7);
        let mut by_value = common::arm(MAP, Faults::default(), 7);
        by_line.line(Origin(1), &line.replace('\n', " "));
        let now = by_value.now();
        by_value.bridge_mut().handle(now, typed(Origin(1)));
        let a = common::results(&mut by_line, 1, Duration::from_secs(5));
        let b = common::results(&mut by_value, 1, Duration::from_secs(5));
        assert_eq!(a.len(), 1, "{line}: {a:?}");
        assert_eq!(a, b, "{line}");
    }
    // The release, after a stop, both ways.
    let mut by_line = common::arm(MAP, Faults::default(), 7);
    let mut by_value = common::arm(MAP, Faults::default(), 7);
    by_line.line(Origin(1), r#"{"emergency_stop": true}"#);
    by_line.line(Origin(1), r#"{"emergency_stop": false}"#);
    let now = by_value.now();
    by_value
        .bridge_mut()
        .handle(now, Input::EmergencyStop { origin: Origin(1) });
    by_value
        .bridge_mut()
        .handle(now, Input::Release { origin: Origin(1) });
    let a = common::results(&mut by_line, 2, Duration::from_secs(5));
    assert_eq!(a.len(), 2);
    assert_eq!(a[1]["released"], true, "{a:?}");
    assert_eq!(a, common::results(&mut by_value, 2, Duration::from_secs(5)));
}

/// A command a Rust program builds with `MotorCommand::new` and its
/// setters is answered as the JSON line of the same members is: taken,
/// refused by the bus map's limits, refused by the validator.
#[test]
fn a_built_command_is_answered_as_its_line_is() {
    use motorwire_bridge::Input;
    use motorwire_bridge::motorwire_wia::MotorCommand;
    use motorwire_bridge::motorwire_wia::core::ControlMode;
    let elbow = |setpoint| MotorCommand::new("elbow", 1.0, ControlMode::Position, setpoint);
    let cases = [
        (
            elbow(30.0)
                .with_velocity_limit(60.0)
                .with_acceleration_limit(200.0),
            r#"{"motor_id":"elbow","timestamp":1,"control_mode":"position","setpoint":30.0,"velocity_limit":60.0,"acceleration_limit":200.0}"#,
            None,
        ),
        // Beyond the map's max_position (150): the gate refuses it.
        (
            elbow(170.0).with_velocity_limit(60.0),
            r#"{"motor_id":"elbow","timestamp":1,"control_mode":"position","setpoint":170.0,"velocity_limit":60.0}"#,
            Some("refused"),
        ),
        // Nothing clamps a negative limit: the validator refuses it.
        (
            elbow(30.0).with_velocity_limit(-1.0),
            r#"{"motor_id":"elbow","timestamp":1,"control_mode":"position","setpoint":30.0,"velocity_limit":-1.0}"#,
            Some("invalid"),
        ),
    ];
    for (command, line, kind) in cases {
        assert_eq!(serde_json::to_string(&command).unwrap(), line);
        let mut by_line = common::arm(MAP, Faults::default(), 7);
        let mut by_value = common::arm(MAP, Faults::default(), 7);
        by_line.line(Origin(1), line);
        let now = by_value.now();
        by_value.bridge_mut().handle(
            now,
            Input::Command {
                origin: Origin(1),
                command: Box::new(command),
            },
        );
        let a = common::results(&mut by_line, 1, Duration::from_secs(5));
        let b = common::results(&mut by_value, 1, Duration::from_secs(5));
        assert_eq!(a.len(), 1, "{line}: {a:?}");
        assert_eq!(a[0]["ok"], kind.is_none(), "{line}: {a:?}");
        assert_eq!(a[0]["error"]["kind"].as_str(), kind, "{line}: {a:?}");
        assert_eq!(a, b, "{line}");
        // And the arrival that follows a command taken, the same.
        for arm in [&mut by_line, &mut by_value] {
            arm.run_until(arm.now() + Duration::from_secs(3)).unwrap();
        }
        let a = common::answers(&mut by_line);
        assert_eq!(a.len(), usize::from(kind.is_none()), "{line}: {a:?}");
        assert_eq!(a, common::answers(&mut by_value), "{line}");
    }
}
