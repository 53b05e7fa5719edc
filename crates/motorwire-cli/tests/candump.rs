//! `motorwire candump decode` on the log captured on vcan0 by the
//! real-kernel test (fixtures/candump/vcan0-session.log).
#![allow(clippy::unwrap_used, clippy::indexing_slicing)]

mod common;

use serde_json::{Value, json};

fn lines(out: &[u8]) -> Vec<Value> {
    String::from_utf8(out.to_vec())
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

#[test]
fn the_captured_session_decodes_frame_by_frame_with_errors_inline() {
    let out = common::run(
        &[
            "candump",
            "decode",
            "--wire",
            "v2.0",
            "fixtures/candump/vcan0-session.log",
        ],
        b"",
    );
    // One frame in the session is the malformed one cansend injected.
    assert_eq!(out.status.code(), Some(1));
    let decoded = lines(&out.stdout);
    assert_eq!(decoded.len(), 160);
    let errors: Vec<&Value> = decoded
        .iter()
        .filter(|v| v.get("error").is_some())
        .collect();
    assert_eq!(
        errors,
        [&json!({
            "line": 134, "timestamp": "1795336407.319065", "interface": "vcan0",
            "can_id": "000", "fd": true, "len": 4,
            "error": "the input ends at byte 4, inside payload"
        })]
    );
    // The arm's ArmReady broadcast, its SetTargetV2 and the joint's Ack.
    assert_eq!(decoded[5]["message"]["payload"], json!("ArmReady"));
    assert_eq!(
        decoded[5]["message"]["header"],
        json!({"source_id": 0, "target_id": 65535, "msg_id": 1})
    );
    let set = &decoded[13]["message"];
    assert_eq!(
        set["header"],
        json!({"source_id": 0, "target_id": 16, "msg_id": 4})
    );
    assert_eq!(set["payload"]["SetTargetV2"]["target_angle"], json!(45.0));
    assert_eq!(set["payload"]["SetTargetV2"]["profile"], json!("SCurve"));
    assert_eq!(decoded[13]["len"], json!(48));
    let acked = decoded.iter().any(|v| {
        v["message"]["header"] == json!({"source_id": 16, "target_id": 0, "msg_id": 4})
            && v["message"]["payload"] == json!({"Ack": 4})
    });
    assert!(acked);
    // The out-of-limit target (400 deg) and its Nack 16.
    assert_eq!(
        decoded[126]["message"]["payload"],
        json!({"Nack": {"id": 23, "error": 16}})
    );
}

#[test]
fn compact_frames_and_bad_lines() {
    // A compact command (24 bytes: an FD length) encoded by `motorwire compact encode`.
    let cmd =
        br#"{"motor_id":"m1","timestamp":1704067200000,"control_mode":"position","setpoint":1.5}"#;
    let enc = common::run(&["compact", "encode", "--now", "1704067200000"], cmd);
    assert!(
        enc.status.success(),
        "{}",
        String::from_utf8_lossy(&enc.stderr)
    );
    let hex = String::from_utf8(enc.stdout).unwrap().trim().to_uppercase();
    let log = format!("(1.000000) can0 123##1{hex}\n\n(2.000000) can0 123#00\n(3.0) can0\n");
    let out = common::run(&["candump", "decode", "--compact", "-"], log.as_bytes());
    assert_eq!(out.status.code(), Some(1));
    let v = lines(&out.stdout);
    assert_eq!(v.len(), 3);
    assert_eq!(v[0]["command"]["setpoint"], json!(1.5));
    assert_eq!(v[0]["line"], json!(1));
    assert!(v[1]["error"].as_str().unwrap().contains("24"), "{}", v[1]);
    assert_eq!(
        v[2],
        json!({"line": 4, "error": "no frame after the interface"})
    );
}

#[test]
fn the_wire_version_is_required_and_unreadable_files_are_errors() {
    let out = common::run(
        &["candump", "decode", "fixtures/candump/vcan0-session.log"],
        b"",
    );
    assert_eq!(out.status.code(), Some(2));
    let out = common::run(
        &["candump", "decode", "--wire", "v2.0", "no/such/file.log"],
        b"",
    );
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("reading no/such/file.log"));
}

#[test]
fn sim_joint_refuses_bad_arguments_clearly() {
    let out = common::run(
        &[
            "sim",
            "joint",
            "--bus",
            "socketcan:vcan0",
            "--node",
            "0x800",
        ],
        b"",
    );
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("above 0x7FF"));
    let out = common::run(&["sim", "joint", "--bus", "can0", "--node", "16"], b"");
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("expected socketcan:IFACE"));
    let out = common::run(
        &["sim", "joint", "--bus", "socketcan:nosuch0", "--node", "16"],
        b"",
    );
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("no CAN interface named \"nosuch0\""));
}

/// `candump decode` prints a frame's message byte for byte as `irpc decode`
/// prints it: fields in wire order, each f32 in its shortest form (33.3, not
/// 33.29999923706055 as a detour through `serde_json::Value`'s f64 gives).
#[test]
fn candump_decode_and_irpc_decode_print_the_same_message_json() {
    let message = r#"{"header":{"source_id":0,"target_id":16,"msg_id":7},"payload":{"SetTargetV2":{"target_angle":33.3,"max_velocity":0.1,"target_velocity":0.0,"max_acceleration":123.45,"max_deceleration":500.0,"max_jerk":2000.0,"profile":"SCurve","max_current":1.5,"max_temperature":0.0}}}"#;
    let enc = common::run(&["irpc", "encode", "--wire", "v2.0"], message.as_bytes());
    assert_eq!(enc.status.code(), Some(0));
    let hex = String::from_utf8(enc.stdout).unwrap();
    // 37 bytes, zero-padded to the CAN-FD length 48.
    let frame = format!("{}{}", hex.trim(), "00".repeat(11));
    assert_eq!(frame.len(), 96);

    let irpc = common::run(
        &["irpc", "decode", "--wire", "v2.0", "--frame"],
        format!("{frame}\n").as_bytes(),
    );
    assert_eq!(irpc.status.code(), Some(0));
    let irpc_line = String::from_utf8(irpc.stdout).unwrap();
    assert_eq!(irpc_line, format!("{message}\n"));

    let log = format!("(1795336405.000001) vcan0 000##5{frame}\n");
    let candump = common::run(
        &["candump", "decode", "--wire", "v2.0", "-"],
        log.as_bytes(),
    );
    assert_eq!(candump.status.code(), Some(0));
    assert_eq!(
        String::from_utf8(candump.stdout).unwrap(),
        format!(
            r#"{{"line":1,"timestamp":"1795336405.000001","interface":"vcan0","can_id":"000","fd":true,"len":48,"message":{message}}}"#
        ) + "\n"
    );
}
