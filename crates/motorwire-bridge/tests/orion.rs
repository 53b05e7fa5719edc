//! The Orion arm controller behind the bridge (WIRE-FACTS §4.1), in
//! simulated time: the bridge's lines go to motorwire's `ArmController`
//! (or are lost, or answered late, as a test says), its answers come back.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing
)]

mod common;

use std::time::Duration;

use motorwire_bridge::{Bridge, BridgeConfig, Origin, Output};
use motorwire_orion::Motor;
use motorwire_translate::BusMap;
use serde_json::{Value, json};

const MAP: &str = r#"
[motors.elbow]
dialect = "irpc"
node = 0x12
limits = { min_position = 0, max_position = 150, max_velocity = 120, max_acceleration = 500 }

[motors.turntable]
dialect = "orion"
key = "TRM"

[motors.arm_extension]
dialect = "orion"
key = "AEM"

[motors.grasper_horizontal_servo]
dialect = "orion"
key = "GHS"
limits = { min_position = -90, max_position = 90 }
"#;

use common::OrionRig as Rig;

#[test]
fn nothing_goes_before_the_boot_beacon_then_only_changed_keys() {
    let mut rig = Rig::new(MAP);
    // Before the beacon the motors are offline: refused at once, never
    // held to run once it comes.
    rig.line(&common::velocity("turntable", 200.0));
    assert!(rig.sent.is_empty(), "{:?}", rig.sent);
    let r = rig.result(1).unwrap();
    assert_eq!(r["error"]["kind"], "offline", "{r}");
    assert_eq!(
        r["error"]["message"],
        "turntable is offline: the Orion arm controller has not sent its boot beacon"
    );
    rig.boot();
    assert!(rig.commands_since(0).is_empty(), "{:?}", rig.sent);
    assert!(
        rig.out
            .iter()
            .any(|v| v["event"] == "online" && v["motor_id"] == "turntable"),
        "{:?}",
        rig.out
    );
    rig.line(&common::velocity("turntable", 200.0));
    assert_eq!(
        rig.commands_since(0),
        [r#"{"ID":32,"MODE":1,"DATA":{"TRM":200}}"#]
    );
    let r = rig.result(2).unwrap();
    assert_eq!(r["ok"], true, "{r}");
    assert_eq!(r["acked"], json!(["turntable"]));
    assert_eq!(rig.arm.value(Motor::Turntable), 200.0);
    // The same value again is not sent again (the controller remembers
    // it); another motor's key goes alone.
    let from = rig.sent.len();
    rig.line(&common::velocity("turntable", 200.0));
    rig.line(&common::velocity("arm_extension", -50.0));
    assert_eq!(
        rig.commands_since(from),
        [r#"{"ID":32,"MODE":1,"DATA":{"AEM":-50}}"#]
    );
    assert_eq!(rig.result(3).unwrap()["ok"], true);
    assert_eq!(rig.result(4).unwrap()["ok"], true);
    assert_eq!(rig.arm.value(Motor::ArmExtension), -50.0);
}

/// A controller heard again, after its link was lost or it went silent, is
/// stopped before anything else (it may still turn at what it was last
/// told); its motors are online once the stop is answered, and nothing
/// that was under way is resumed.
#[test]
fn a_controller_heard_again_is_stopped_before_its_motors_are_online() {
    let stop = r#"{"ID":32,"MODE":2,"DATA":1}"#;
    let online = |rig: &Rig, from: usize| {
        rig.out[from..]
            .iter()
            .filter(|v| v["event"] == "online" && v["motor_id"] == "turntable")
            .count()
    };
    let mut rig = Rig::new(MAP);
    rig.boot();
    for (case, lose) in [("lost", true), ("silent", false)] {
        rig.line(&common::velocity("turntable", 200.0));
        assert_eq!(rig.arm.value(Motor::Turntable), 200.0, "{case}");
        // Nothing reaches the controller any more, nor comes from it.
        rig.answering = false;
        if lose {
            rig.bridge
                .handle_link_lost(rig.now, "writing to the controller: Broken pipe");
            rig.pump();
        }
        rig.advance(Duration::from_millis(800));
        let out = rig.out.len();
        let n = rig.out.iter().filter(|v| v.get("ok").is_some()).count() as u64;
        rig.line(&common::velocity("turntable", 100.0));
        let r = rig.result(n + 1).unwrap();
        // Silent, the deadman's stop went unanswered, which latches the
        // emergency stop (when in doubt, stop); lost, the link says so.
        let refused = if lose {
            "offline"
        } else {
            "emergency_stop_latched"
        };
        assert_eq!(r["error"]["kind"], refused, "{case}: {r}");
        assert_eq!(
            rig.arm.value(Motor::Turntable),
            200.0,
            "{case}: still turning"
        );
        // Heard again: the stop goes first, then the motors are online.
        let from = rig.sent.len();
        rig.answering = true;
        rig.advance(Duration::from_millis(300));
        assert_eq!(
            rig.commands_since(from).first(),
            Some(&stop),
            "{case}: {:?}",
            rig.sent
        );
        assert_eq!(rig.arm.value(Motor::Turntable), 0.0, "{case}");
        assert_eq!(online(&rig, out), 1, "{case}: {:?}", &rig.out[out..]);
        assert!(
            !rig.commands_since(from).iter().any(|l| l.contains("TRM")),
            "{case}: nothing resumed: {:?}",
            rig.commands_since(from)
        );
        let mut next = n + 2;
        if !lose {
            rig.line(r#"{"emergency_stop": false}"#);
            assert_eq!(rig.result(next).unwrap()["released"], true, "{case}");
            next += 1;
        }
        rig.line(&common::velocity("turntable", 0.0));
        assert_eq!(rig.result(next).unwrap()["ok"], true, "{case}");
    }
}

#[test]
fn a_multi_axis_command_for_orion_motors_is_one_line_and_the_gate_refuses_a_clamp() {
    let mut rig = Rig::new(MAP);
    rig.boot();
    let from = rig.sent.len();
    rig.line(
        r#"{"command_id":"m1","timestamp":0,"motors":[
            {"motor_id":"turntable","control_mode":"velocity","setpoint":-120},
            {"motor_id":"grasper_horizontal_servo","control_mode":"position","setpoint":30}]}"#
            .replace('\n', "")
            .as_str(),
    );
    assert_eq!(
        rig.commands_since(from),
        [r#"{"ID":32,"MODE":1,"DATA":{"TRM":-120,"GHS":30}}"#]
    );
    let r = rig.result(1).unwrap();
    assert_eq!(
        r["acked"],
        json!(["turntable", "grasper_horizontal_servo"]),
        "{r}"
    );
    // The servo's position is watched for arrival.
    let arrival = rig.out.iter().find(|v| v["arrived"].is_boolean()).unwrap();
    assert_eq!(arrival["arrived"], true, "{arrival}");
    assert_eq!(arrival["motors"][0]["motor_id"], "grasper_horizontal_servo");
    // 500 is outside the controller's [-400, 400]: it would clamp it, so
    // the gate refuses it and nothing is written.
    let from = rig.sent.len();
    rig.line(&common::velocity("turntable", 500.0));
    let r = rig.result(2).unwrap();
    assert_eq!(r["ok"], false);
    assert_eq!(
        r["error"],
        json!({
            "kind": "refused",
            "rule": "outside_limit",
            "message": "turntable: setpoint 500 is outside max_velocity (Orion range) 400",
            "motor": "turntable",
            "field": "setpoint",
            "value": 500.0,
            "limit": 400.0,
            "limit_name": "max_velocity",
            "limit_source": "Orion range",
        })
    );
    assert!(rig.commands_since(from).is_empty());
    // A servo position beyond the map's ±90 is refused too.
    rig.line(
        r#"{"motor_id":"grasper_horizontal_servo","timestamp":0,"control_mode":"position","setpoint":120}"#,
    );
    assert_eq!(rig.result(3).unwrap()["error"]["kind"], "refused");
    assert_eq!(rig.arm.value(Motor::GrasperHorizontalServo), 30.0);
}

#[test]
fn the_stop_goes_out_at_once_ahead_of_a_line_in_flight_and_its_answer_is_not_taken_for_the_stop() {
    let mut rig = Rig::new(MAP);
    rig.boot();
    rig.holding = true;
    let from = rig.sent.len();
    rig.line(&common::velocity("turntable", 300.0));
    rig.line(&common::velocity("arm_extension", 100.0));
    // One line in flight: the second waits for its answer.
    assert_eq!(
        rig.commands_since(from),
        [r#"{"ID":32,"MODE":1,"DATA":{"TRM":300}}"#]
    );
    rig.line(r#"{"emergency_stop":true}"#);
    assert_eq!(
        rig.commands_since(from),
        [
            r#"{"ID":32,"MODE":1,"DATA":{"TRM":300}}"#,
            r#"{"ID":32,"MODE":2,"DATA":1}"#
        ]
    );
    // The answer to the direct-control line comes first: the stop waits
    // for its own (CMDF).
    let first = rig.held.remove(0);
    rig.bridge.handle_link_line(rig.now, &first);
    rig.pump();
    assert!(rig.result(3).is_none(), "{:?}", rig.out);
    rig.release();
    // The elbow (an iRPC joint nobody simulates here) times out.
    rig.advance(Duration::from_millis(600));
    let stop = rig.result(3).unwrap();
    assert_eq!(stop["emergency_stop"], true, "{stop}");
    assert_eq!(
        stop["acked"],
        json!([
            "arm_extension",
            "elbow",
            "grasper_horizontal_servo",
            "turntable"
        ])
        .as_array()
        .unwrap()
        .iter()
        .filter(|m| *m != "elbow")
        .cloned()
        .collect::<Value>(),
        "{stop}"
    );
    // The line in flight may have run; the one waiting never went.
    assert_eq!(rig.result(1).unwrap()["error"]["kind"], "cancelled");
    assert_eq!(
        rig.result(1).unwrap()["outcomes"][0]["outcome"],
        "outcome_unknown"
    );
    assert_eq!(
        rig.result(2).unwrap()["outcomes"][0]["outcome"],
        "cancelled"
    );
    assert_eq!(rig.arm.value(Motor::Turntable), 0.0);
    assert_eq!(rig.arm.value(Motor::ArmExtension), 0.0);
    assert!(!rig.sent.iter().any(|l| l.contains("AEM")));
}

#[test]
fn a_silent_controller_stops_a_spinning_turntable_by_the_deadman() {
    let mut rig = Rig::new(MAP);
    rig.boot();
    rig.line(&common::velocity("turntable", 250.0));
    assert_eq!(rig.arm.value(Motor::Turntable), 250.0);
    // Renewed within 200 ms: it keeps turning.
    rig.advance(Duration::from_millis(150));
    rig.line(&common::velocity("turntable", 250.0));
    rig.advance(Duration::from_millis(150));
    assert_eq!(rig.arm.value(Motor::Turntable), 250.0);
    assert!(!rig.out.iter().any(|v| v["event"] == "deadman"));
    // Then the controller's commander falls silent.
    rig.advance(Duration::from_millis(100));
    let deadman = rig.out.iter().find(|v| v["event"] == "deadman").unwrap();
    assert_eq!(
        deadman,
        &json!({"event":"deadman","motor_id":"turntable","timeout_ms":200})
    );
    assert_eq!(rig.arm.value(Motor::Turntable), 0.0);
    assert!(
        rig.sent
            .iter()
            .any(|l| l == r#"{"ID":32,"MODE":1,"DATA":{"TRM":0}}"#)
    );
    // Once per silent command: the stop (speed 0) is not timed out, nor is
    // a speed 0 from the controller.
    rig.advance(Duration::from_secs(2));
    rig.line(&common::velocity("turntable", 0.0));
    rig.advance(Duration::from_secs(2));
    let deadmen = rig.out.iter().filter(|v| v["event"] == "deadman").count();
    assert_eq!(deadmen, 1, "{:?}", rig.out);
}

#[test]
fn an_unanswered_line_is_sent_again_then_its_outcome_is_unknown_and_the_motors_go_offline() {
    let mut rig = Rig::new(MAP);
    rig.boot();
    rig.answering = false;
    let from = rig.sent.len();
    rig.line(&common::velocity("turntable", 100.0));
    rig.advance(Duration::from_millis(1000));
    // Sent once and again three times (100 ms Ack timeout, 3 retries).
    assert_eq!(
        rig.commands_since(from)
            .iter()
            .filter(|l| **l == r#"{"ID":32,"MODE":1,"DATA":{"TRM":100}}"#)
            .count(),
        4
    );
    let r = rig.result(1).unwrap();
    assert_eq!(r["outcomes"][0]["outcome"], "outcome_unknown", "{r}");
    assert_eq!(
        r["outcomes"][0]["message"],
        "sent 4 times, never answered: the Orion arm controller (ID 32) may or may not have executed it"
    );
    let offline: Vec<&Value> = rig.out.iter().filter(|v| v["event"] == "offline").collect();
    assert!(
        offline.iter().any(|v| v["motor_id"] == "turntable"),
        "{:?}",
        rig.out
    );
    // The setpoint may be turning the turntable: the deadman watches it as
    // if acked, its stop is never answered either, and that latches the
    // emergency stop (when in doubt, stop).
    assert!(
        rig.out
            .iter()
            .any(|v| v["event"] == "deadman" && v["motor_id"] == "turntable"),
        "{:?}",
        rig.out
    );
    assert!(rig.bridge.is_latched());
    rig.line(&common::velocity("arm_extension", 10.0));
    let r = rig.result(2).unwrap();
    assert_eq!(r["error"]["kind"], "emergency_stop_latched", "{r}");
    // Released, its motors are still offline: nothing heard.
    rig.line(r#"{"emergency_stop": false}"#);
    rig.line(&common::velocity("arm_extension", 10.0));
    let r = rig.result(4).unwrap();
    assert_eq!(r["error"]["kind"], "offline", "{r}");
    assert_eq!(
        r["error"]["message"],
        "arm_extension is offline: nothing heard from the Orion arm controller (ID 32)"
    );
}

#[test]
fn lines_that_are_not_the_controllers_are_reported_and_never_acted_on() {
    let mut rig = Rig::new(MAP);
    rig.boot();
    rig.holding = true;
    rig.line(&common::velocity("turntable", 100.0));
    for bad in [
        "not json",
        r#"{"ID":33,"MODE":1,"DATA":{"TRMF":[100,20,0]}}"#,
        r#"{"ID":32,"MODE":1,"DATA":{"XYZ":[1,2,0]}}"#,
        r#"[32]"#,
    ] {
        rig.bridge.handle_link_line(rig.now, bad);
    }
    rig.pump();
    let bad: Vec<&Value> = rig
        .out
        .iter()
        .filter(|v| v["event"] == "bad_orion_line")
        .collect();
    assert_eq!(bad.len(), 4, "{:?}", rig.out);
    // Not one of them acknowledged the line in flight.
    assert!(rig.result(1).is_none());
    rig.release();
    assert_eq!(rig.result(1).unwrap()["ok"], true);
}

#[test]
fn fold_and_unfold_are_the_controllers_command_mode_and_cmdf_0_fails_the_line() {
    let mut rig = Rig::new(MAP);
    rig.boot();
    let from = rig.sent.len();
    rig.line(r#"{"orion":"fold"}"#);
    assert_eq!(rig.commands_since(from), [r#"{"ID":32,"MODE":2,"DATA":2}"#]);
    let r = rig.result(1).unwrap();
    assert_eq!(r["ok"], true, "{r}");
    assert_eq!(r["orion"], "fold");
    assert_eq!(rig.arm.posture(), motorwire_orion::Posture::Folded);
    // A controller that answers CMDF 0.
    rig.answering = false;
    rig.line(r#"{"orion":"unfold"}"#);
    rig.bridge
        .handle_link_line(rig.now, r#"{"ID":32,"MODE":2,"DATA":{"CMDF":0}}"#);
    rig.pump();
    let r = rig.result(2).unwrap();
    assert_eq!(r["ok"], false, "{r}");
    assert_eq!(r["outcomes"][0]["outcome"], "nacked");
    // Said as the controller's answer, not as an iRPC Nack code.
    assert_eq!(
        r["outcomes"][0]["message"],
        "the controller answered CMDF 0: the command failed"
    );
    assert_eq!(r["outcomes"][0].get("code"), None, "{r}");
    // Anything else is not an Orion command line.
    rig.line(r#"{"orion":"dance"}"#);
    let r = rig.result(3).unwrap();
    assert_eq!(r["error"]["kind"], "invalid");
    assert_eq!(
        r["error"]["message"],
        r#"an Orion command is exactly {"orion":"fold"} or {"orion":"unfold"} (a stop is {"emergency_stop":true})"#
    );
}

#[test]
fn a_lost_link_reports_it_and_takes_the_orion_motors_offline() {
    let mut rig = Rig::new(MAP);
    rig.boot();
    rig.bridge
        .handle_link_lost(rig.now, "the controller's stream ended");
    rig.pump();
    assert!(
        rig.out
            .iter()
            .any(|v| v
                == &json!({"event":"orion_link_lost","error":"the controller's stream ended"}))
    );
    // Each motor offline, saying why, the link's error with it.
    assert!(
        rig.out.iter().any(|v| v
            == &json!({"event":"offline","motor_id":"turntable","node":65535,
                "reason":"the link to the Orion controller is lost: the controller's stream ended"})),
        "{:?}",
        rig.out
    );
    // Lost already: a second loss says nothing more.
    let before = rig.out.len();
    rig.bridge.handle_link_lost(rig.now, "again");
    rig.pump();
    assert_eq!(rig.out.len(), before, "{:?}", &rig.out[before..]);
    rig.line(&common::velocity("turntable", 10.0));
    assert_eq!(rig.result(1).unwrap()["error"]["kind"], "offline");
    // A stop still answers, and the iRPC joint is still served.
    rig.line(r#"{"emergency_stop":true}"#);
    rig.advance(Duration::from_millis(600));
    let stop = rig.result(2).unwrap();
    assert_eq!(stop["emergency_stop"], true, "{stop}");
}

/// A move acked and still watched when the link is lost: its completion
/// says the link was lost (without the link's own error, which the
/// offline event carries).
#[test]
fn a_move_watched_when_the_link_is_lost_is_said_so() {
    let mut rig = Rig::new(MAP);
    rig.boot();
    // The servo acknowledges the line still standing at 0 (it moves on
    // its own time).
    rig.answering = false;
    rig.line(
        r#"{"motor_id":"grasper_horizontal_servo","timestamp":0,"control_mode":"position","setpoint":30}"#,
    );
    controller_answers(&mut rig, r#"{"GHSF":[0,0,0]}"#);
    assert_eq!(rig.result(1).unwrap()["ok"], true, "{:?}", rig.out);
    assert!(
        !rig.out.iter().any(|v| v.get("arrived").is_some()),
        "{:?}",
        rig.out
    );
    rig.bridge.handle_link_lost(rig.now, "EOF");
    rig.pump();
    let arrival = rig
        .out
        .iter()
        .find(|v| v.get("arrived").is_some())
        .unwrap_or_else(|| panic!("{:?}", rig.out));
    assert_eq!(arrival["arrived"], false);
    assert_eq!(
        arrival["reason"],
        "the link to the Orion controller is lost"
    );
}

#[test]
fn without_an_orion_controller_its_motors_are_refused() {
    let config = BridgeConfig {
        activate_on_start: false,
        ..BridgeConfig::default()
    };
    let mut bridge = Bridge::new(BusMap::from_toml(MAP).unwrap(), config).unwrap();
    bridge.start(Duration::ZERO);
    bridge.handle_line(
        Duration::ZERO,
        Origin(0),
        &common::velocity("turntable", 10.0),
    );
    let r = std::iter::from_fn(|| bridge.poll_output())
        .find_map(|o| match o {
            Output::Result { result, .. } => Some(result),
            _ => None,
        })
        .unwrap();
    assert!(!r.ok);
    assert_eq!(
        r.error.unwrap().message,
        "turntable is an Orion motor, and no Orion controller is attached (motorwire bridge --orion ...)"
    );
    assert!(bridge.poll_link_line().is_none());
}

/// Answers the line in flight by hand: `data` is the answer's DATA.
fn controller_answers(rig: &mut Rig, data: &str) {
    let line = format!(r#"{{"ID":32,"MODE":1,"DATA":{data}}}"#);
    rig.bridge.handle_link_line(rig.now, &line);
    rig.pump();
}

#[test]
fn what_the_controller_reports_never_stands_for_what_was_commanded() {
    // A controller whose feedback is the motor's actual speed, still 0
    // while it spins up: a stop value is sent all the same.
    let mut rig = Rig::new(MAP);
    rig.boot();
    rig.answering = false;
    let from = rig.sent.len();
    rig.line(&common::velocity("turntable", 150.0));
    controller_answers(&mut rig, r#"{"TRMF":[0,0.1,0]}"#);
    assert_eq!(rig.result(1).unwrap()["ok"], true);
    rig.line(&common::velocity("turntable", 0.0));
    assert_eq!(
        rig.commands_since(from),
        [
            r#"{"ID":32,"MODE":1,"DATA":{"TRM":150}}"#,
            r#"{"ID":32,"MODE":1,"DATA":{"TRM":0}}"#
        ]
    );
    controller_answers(&mut rig, r#"{"TRMF":[0,0,0]}"#);
    // And the deadman's 0 for a speed set again goes out too.
    rig.line(&common::velocity("turntable", 150.0));
    controller_answers(&mut rig, r#"{"TRMF":[0,0.1,0]}"#);
    let from = rig.sent.len();
    rig.advance(Duration::from_millis(250));
    assert!(
        rig.commands_since(from)
            .contains(&r#"{"ID":32,"MODE":1,"DATA":{"TRM":0}}"#),
        "{:?}",
        rig.sent
    );
    // An unsolicited report of 150 does not make a later 150 "unchanged".
    controller_answers(&mut rig, r#"{"TRMF":[0,0,0]}"#);
    rig.bridge
        .handle_link_line(rig.now, r#"{"ID":32,"MODE":1,"DATA":{"TRMF":[150,0,0]}}"#);
    rig.pump();
    let from = rig.sent.len();
    rig.line(&common::velocity("turntable", 150.0));
    assert_eq!(
        rig.commands_since(from),
        [r#"{"ID":32,"MODE":1,"DATA":{"TRM":150}}"#]
    );
}

#[test]
fn an_answer_that_does_not_report_the_motors_set_acknowledges_nothing() {
    let mut rig = Rig::new(MAP);
    rig.boot();
    rig.answering = false;
    rig.line(&common::velocity("turntable", 150.0));
    controller_answers(&mut rig, "{}");
    controller_answers(&mut rig, r#"{"LAAF":[0,0,0]}"#);
    assert!(rig.result(1).is_none(), "{:?}", rig.out);
    controller_answers(&mut rig, r#"{"TRM":[150,20,0]}"#);
    assert_eq!(rig.result(1).unwrap()["ok"], true);
}

#[test]
fn a_flooding_controller_cannot_flood_the_output() {
    let mut rig = Rig::new(MAP);
    rig.boot();
    for _ in 0..1000 {
        rig.bridge.handle_link_line(rig.now, "x");
    }
    rig.pump();
    let bad = |rig: &Rig| {
        rig.out
            .iter()
            .filter(|v| v["event"] == "bad_orion_line")
            .cloned()
            .collect::<Vec<_>>()
    };
    assert_eq!(bad(&rig).len(), 10);
    assert_eq!(rig.bridge.stats().bad_frames, 1000);
    // A second later, the next one says how many were not reported.
    rig.advance(Duration::from_millis(1000));
    rig.bridge.handle_link_line(rig.now, "x");
    rig.pump();
    let last = bad(&rig).pop().unwrap();
    assert_eq!(last["suppressed"], 990, "{last}");
}

#[test]
fn a_stop_is_still_written_when_nothing_comes_from_the_controller_any_more() {
    let mut rig = Rig::new(MAP);
    rig.boot();
    rig.bridge
        .handle_link_lost(rig.now, "the controller's stream ended");
    rig.pump();
    let from = rig.sent.len();
    rig.line(r#"{"emergency_stop":true}"#);
    assert_eq!(rig.commands_since(from), [r#"{"ID":32,"MODE":2,"DATA":1}"#]);
}

#[test]
fn a_deadman_stop_that_is_never_answered_stops_everything() {
    let mut rig = Rig::new(MAP);
    rig.boot();
    rig.line(&common::velocity("turntable", 150.0));
    assert_eq!(rig.result(1).unwrap()["ok"], true);
    // The controller stops answering: the deadman's TRM 0 is sent, sent
    // again, never answered; then the emergency stop latches.
    rig.answering = false;
    rig.advance(Duration::from_millis(1000));
    let stop = rig
        .out
        .iter()
        .find(|v| v["event"] == "emergency_stop")
        .unwrap_or_else(|| panic!("{:?}", rig.out));
    assert_eq!(
        stop["cause"],
        "deadman: could not stop turntable (outcome_unknown)"
    );
    assert!(rig.bridge.is_latched());
    assert!(
        rig.sent
            .iter()
            .any(|l| l == r#"{"ID":32,"MODE":2,"DATA":1}"#)
    );
}

/// A reset names one device: an Orion motor has no iRPC node, and its
/// Reset went to the broadcast node, rebooting every joint mid-move.
#[test]
fn a_reset_of_an_orion_motor_is_refused_and_reaches_no_joint() {
    let mut rig = Rig::new(MAP);
    rig.boot();
    let lines = rig.sent.len();
    rig.bridge.handle_line(
        rig.now,
        Origin(0),
        r#"{"reset":"grasper_horizontal_servo"}"#,
    );
    let frames: Vec<_> = std::iter::from_fn(|| rig.bridge.poll_transmit()).collect();
    assert_eq!(frames, [], "no frame for any joint");
    rig.pump();
    let r = rig
        .out
        .iter()
        .find(|v| v.get("ok").is_some())
        .unwrap()
        .clone();
    assert_eq!(r["ok"], false, "{r}");
    assert_eq!(r["motor_id"], "grasper_horizontal_servo", "{r}");
    assert_eq!(r["error"]["kind"], "refused", "{r}");
    assert_eq!(
        r["error"]["message"],
        "grasper_horizontal_servo takes no reset: only iRPC joints and moteus controllers do",
        "{r}"
    );
    assert_eq!(rig.commands_since(lines), Vec::<&str>::new(), "nor a line");
}

/// A stop takes back what was made and not yet handed out: a compact
/// frame still waiting for `poll_transmit` and an Orion line still waiting
/// for `poll_link_line` are never written; the stop goes out alone, and
/// the lines they carried are answered cancelled "before it was sent" (not
/// `outcome_unknown`: nothing of them reached a device).
#[test]
fn a_stop_takes_back_a_frame_and_a_line_not_yet_handed_out() {
    let map = BusMap::from_toml(
        r#"
[motors.gripper_axis]
dialect = "compact"
node = 0x20
limits = { min_position = 0, max_position = 90, max_velocity = 60, max_torque = 5 }

[motors.turntable]
dialect = "orion"
key = "TRM"
"#,
    )
    .unwrap();
    let config = BridgeConfig {
        line_link: true,
        activate_on_start: false,
        ..BridgeConfig::default()
    };
    let mut bridge = Bridge::new(map, config).unwrap();
    let t = Duration::ZERO;
    bridge.start(t);
    bridge.handle_link_line(t, r#"{"ID":32}"#);
    bridge.handle_timeout(t);
    // The first poll, answered.
    assert_eq!(
        bridge.poll_link_line().as_deref(),
        Some(r#"{"ID":32,"MODE":1,"DATA":{}}"#)
    );
    bridge.handle_link_line(t, r#"{"ID":32,"MODE":1,"DATA":{"TRM":[0,0,0]}}"#);
    bridge.handle_line(t, Origin(1), &common::velocity("turntable", 200.0));
    bridge.handle_line(
        t,
        Origin(1),
        r#"{"motor_id":"gripper_axis","timestamp":1,"control_mode":"velocity","setpoint":20}"#,
    );
    bridge.handle_line(t, Origin(2), r#"{"emergency_stop":true}"#);
    let lines: Vec<String> = std::iter::from_fn(|| bridge.poll_link_line()).collect();
    assert_eq!(lines, [r#"{"ID":32,"MODE":2,"DATA":1}"#]);
    let frames: Vec<_> = std::iter::from_fn(|| bridge.poll_transmit()).collect();
    assert_eq!(frames.len(), 1, "{frames:?}");
    let stop = motorwire_compact::CompactCommand::decode(frames[0].data()).unwrap();
    assert_eq!(stop.flags.bits() & 0x01, 0x01, "{stop:?}");
    bridge.flushed(t);
    let out: Vec<Value> = std::iter::from_fn(|| bridge.poll_output())
        .map(|o| o.to_value())
        .collect();
    let of = |line: u64| {
        out.iter()
            .find(|v| {
                v["line"] == line && v.get("ok").is_some() && v.get("emergency_stop").is_none()
            })
            .unwrap()
    };
    for (line, motor) in [(1, "turntable"), (2, "gripper_axis")] {
        let r = of(line);
        assert_eq!(r["ok"], false, "{r}");
        assert_eq!(r["outcomes"][0]["motor"], motor, "{r}");
        assert_eq!(r["outcomes"][0]["outcome"], "cancelled", "{r}");
        assert_eq!(
            r["outcomes"][0]["message"], "cancelled by the emergency stop before it was sent",
            "{r}"
        );
    }
}
