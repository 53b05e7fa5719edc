//! `motorwire irpc` and `motorwire compact`, run as a user runs them.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing
)]

mod common;

use std::process::Output;

fn run(args: &[&str], stdin: &str) -> Output {
    common::run(args, stdin.as_bytes())
}

fn stdout(o: &Output) -> String {
    String::from_utf8(o.stdout.clone()).unwrap()
}

const DOC_JSON: &str = r#"{"header":{"source_id":0,"target_id":16,"msg_id":42},"payload":{"SetTargetV2":{"target_angle":90.0,"max_velocity":100.0,"target_velocity":0.0,"max_acceleration":500.0,"max_deceleration":500.0,"max_jerk":2000.0,"profile":"SCurve","max_current":0.0,"max_temperature":0.0}}}"#;
const DOC_HEX: &str = "00102a050000b4420000c842000000000000fa430000fa430000fa44010000000000000000";

#[test]
fn irpc_encode_prints_the_documents_37_bytes_and_decode_returns_the_json() {
    let o = run(
        &["irpc", "encode", "--wire", "v2.0"],
        &format!("{DOC_JSON}\n"),
    );
    assert_eq!(o.status.code(), Some(0));
    assert_eq!(stdout(&o), format!("{DOC_HEX}\n"));
    assert_eq!(DOC_HEX.len(), 74);
    let o = run(
        &["irpc", "decode", "--wire", "v2.0"],
        &format!("{DOC_HEX}\n"),
    );
    assert_eq!(o.status.code(), Some(0));
    assert_eq!(stdout(&o), format!("{DOC_JSON}\n"));
}

#[test]
fn irpc_failed_lines_are_replaced_and_processing_goes_on() {
    let input = "00 10 01 01\nnot hex\n\n00 10 01 0b\n10 00 2a 12 2a\n";
    let o = run(&["irpc", "decode", "--wire", "v2.1"], input);
    assert_eq!(o.status.code(), Some(1));
    let out = stdout(&o);
    let lines: Vec<&str> = out.lines().collect();
    assert_eq!(lines.len(), 4);
    assert_eq!(
        lines[0],
        r#"{"header":{"source_id":0,"target_id":16,"msg_id":1},"payload":"Configure"}"#
    );
    assert_eq!(lines[1], r#"{"error":"'n' is not a hex digit","line":2}"#);
    assert_eq!(
        lines[2],
        r#"{"error":"the input ends at byte 4, inside ConfigureAdaptive.coolstep_enable","line":4}"#
    );
    assert_eq!(
        lines[3],
        r#"{"header":{"source_id":16,"target_id":0,"msg_id":42},"payload":{"Ack":42}}"#
    );
}

#[test]
fn irpc_encode_refuses_what_the_version_lacks_and_bad_json() {
    let input = format!("{DOC_JSON}\n{{\"header\":1}}\n");
    let o = run(&["irpc", "encode", "--wire", "v1"], &input);
    assert_eq!(o.status.code(), Some(1));
    let out = stdout(&o);
    let lines: Vec<&str> = out.lines().collect();
    assert_eq!(
        lines[0],
        r#"{"error":"SetTargetV2 does not exist in iRPC v1","line":1}"#
    );
    assert!(
        lines[1].starts_with(r#"{"error":"not an iRPC message: "#),
        "{}",
        lines[1]
    );
    assert!(lines[1].ends_with(r#","line":2}"#));
}

#[test]
fn irpc_frames_accept_padding_only_with_frame() {
    let padded = "00 10 01 01 00 00 00 00\n";
    let o = run(&["irpc", "decode", "--wire", "v2.0"], padded);
    assert_eq!(o.status.code(), Some(1));
    assert_eq!(
        stdout(&o),
        "{\"error\":\"4 byte(s) follow the message, which ends at byte 4\",\"line\":1}\n"
    );
    let o = run(&["irpc", "decode", "--wire", "v2.0", "--frame"], padded);
    assert_eq!(o.status.code(), Some(0));
}

#[test]
fn usage_errors_exit_2() {
    assert_eq!(
        run(&["irpc", "encode", "--wire", "v3"], "").status.code(),
        Some(2)
    );
    assert_eq!(run(&["irpc", "encode"], "").status.code(), Some(2));
    assert_eq!(
        run(&["compact", "decode", "--names", "no/such/file"], "")
            .status
            .code(),
        Some(2)
    );
}

#[test]
fn compact_encode_and_decode_with_names() {
    let cmd = r#"{"motor_id":"shoulder_pitch","timestamp":1704067200000,"control_mode":"position","setpoint":45.0,"velocity_limit":60.0,"pid_gains":{"kp":50,"ki":0.1,"kd":2.5}}"#;
    let o = run(&["compact", "encode"], &format!("{cmd}\n"));
    assert_eq!(o.status.code(), Some(0));
    assert_eq!(
        stdout(&o),
        "cf433bf300f451c28c01000001000000000034425802ffff\n"
    );
    assert_eq!(
        String::from_utf8(o.stderr).unwrap(),
        "motorwire compact encode: shoulder_pitch: pid_gains: dropped: the compact command has no place for it\n"
    );
    let names = std::env::temp_dir().join(format!("motorwire-names-{}", std::process::id()));
    std::fs::write(&names, "shoulder_pitch\nelbow\n").unwrap();
    let o = run(
        &["compact", "decode", "--names", names.to_str().unwrap()],
        "cf433bf300f451c28c01000001000000000034425802ffff\n0000000000f451c28c01000001000000000034425802ffff\n",
    );
    std::fs::remove_file(&names).unwrap();
    assert_eq!(o.status.code(), Some(0));
    assert_eq!(
        stdout(&o),
        concat!(
            r#"{"motor":4080747471,"timestamp_ms":1704067200000,"control_mode":"position","flags":0,"setpoint":45.0,"velocity_limit":600,"torque_limit":null,"motor_id":"shoulder_pitch","flag_names":[],"velocity_limit_units_per_s":60.0,"torque_limit_nm":null}"#,
            "\n",
            r#"{"motor":0,"timestamp_ms":1704067200000,"control_mode":"position","flags":0,"setpoint":45.0,"velocity_limit":600,"torque_limit":null,"motor_id":null,"flag_names":[],"velocity_limit_units_per_s":60.0,"torque_limit_nm":null}"#,
            "\n"
        )
    );
}

/// Beside the raw steps (`velocity_limit` in 0.1 units/s, `torque_limit`
/// in 0.01 Nm, `flags` as bits): the same in physical units and by name.
#[test]
fn compact_decode_shows_units_and_flag_names_beside_the_raw_steps() {
    let o = run(
        &["compact", "decode"],
        concat!(
            // elbow, 45.5, 60 deg/s, 2.5 Nm, priority 80 (PRIORITY_HIGH)
            "22cb578100f451c28c01000001800000000036425802fa00\n",
            // flags 0x81: PRIORITY_HIGH | EMERGENCY_STOP; no limits
            "22cb578101000000000000000081000000000000ffffffff\n",
        ),
    );
    assert_eq!(o.status.code(), Some(0));
    assert_eq!(
        stdout(&o),
        concat!(
            r#"{"motor":2170014498,"timestamp_ms":1704067200000,"control_mode":"position","flags":128,"setpoint":45.5,"velocity_limit":600,"torque_limit":250,"flag_names":["PRIORITY_HIGH"],"velocity_limit_units_per_s":60.0,"torque_limit_nm":2.5}"#,
            "\n",
            r#"{"motor":2170014498,"timestamp_ms":1,"control_mode":"disabled","flags":129,"setpoint":0.0,"velocity_limit":null,"torque_limit":null,"flag_names":["PRIORITY_HIGH","EMERGENCY_STOP"],"velocity_limit_units_per_s":null,"torque_limit_nm":null}"#,
            "\n",
        )
    );
}

#[test]
fn compact_encode_refuses_invalid_and_unfitting_commands() {
    let input = concat!(
        // outside its own safety limits: never encoded
        r#"{"motor_id":"elbow","timestamp":1,"control_mode":"position","setpoint":200,"safety_limits":{"max_position":150}}"#,
        "\n",
        // a velocity limit the u16 cannot carry
        r#"{"motor_id":"elbow","timestamp":1,"control_mode":"velocity","setpoint":1,"velocity_limit":7000}"#,
        "\n",
        // emergency stop and high priority become flags
        r#"{"motor_id":"elbow","timestamp":1,"control_mode":"disabled","setpoint":0,"priority":90,"safety_limits":{"emergency_stop":true}}"#,
        "\n",
    );
    let o = run(&["compact", "encode"], input);
    assert_eq!(o.status.code(), Some(1));
    let out = stdout(&o);
    let lines: Vec<&str> = out.lines().collect();
    assert!(
        lines[0].contains("setpoint-within-limits") && lines[0].ends_with(r#""line":1}"#),
        "{}",
        lines[0]
    );
    assert_eq!(
        lines[1],
        r#"{"error":"elbow: velocity_limit 7000 does not fit the wire; the maximum is 6553.4","line":2}"#
    );
    // flags 0x81 = PRIORITY_HIGH | EMERGENCY_STOP, mode 0.
    assert_eq!(lines[2], "22cb578101000000000000000081000000000000ffffffff");
}

#[test]
fn compact_decode_refuses_what_the_codec_refuses() {
    let o = run(
        &["compact", "decode"],
        "cf433bf300f451c28c01000001100000000034425802ffff\ncf433b\n",
    );
    assert_eq!(o.status.code(), Some(1));
    assert_eq!(
        stdout(&o),
        concat!(
            r#"{"error":"the ENCRYPTED flag is set, and motorwire has no encryption layer to decrypt it","line":1}"#,
            "\n",
            r#"{"error":"a compact command is exactly 24 bytes, not 3","line":2}"#,
            "\n"
        )
    );
}

/// Servo packets as the vendors' SDKs write them (feetech-servo-sdk 1.0.0
/// and dynamixel-sdk 4.1.0, captured from their port; the stuffed write is
/// the SDK's own `addStuffing` of its packet, which its `txPacket` drops),
/// and status packets read as their `rxPacket` reads them.
#[test]
fn servo_encode_and_decode_lines_as_the_vendors_sdks_write_and_read_them() {
    let cases: [(&str, &str, &str); 8] = [
        (
            "scs0",
            r#"{"instruction":"write","id":1,"address":42,"value":2048,"length":2}"#,
            "ffff0105032a0008c4",
        ),
        (
            "scs0",
            r#"{"instruction":"sync_read","address":56,"length":2,"ids":[1,2,3,4,5,6]}"#,
            "fffffe0a82380201020304050626",
        ),
        (
            "scs1",
            r#"{"instruction":"write","id":1,"address":42,"value":2048,"length":2}"#,
            "ffff0105032a0800c4",
        ),
        (
            "scs1",
            r#"{"instruction":"write","id":1,"address":42,"value":-2,"length":4}"#,
            "ffff0107032afffeffffcf",
        ),
        (
            "dxl2",
            r#"{"instruction":"write","id":1,"address":116,"data":"fffffd01"}"#,
            "fffffd00010a00037400fffffdfd012467",
        ),
        (
            "dxl2",
            r#"{"instruction":"bulk_read","reads":[[1,132,4],[2,146,1]]}"#,
            "fffffd00fe0d009201840004000292000100fa7c",
        ),
        (
            "dxl2",
            r#"{"instruction":"sync_write","address":116,"length":4,"data":{"2":"00080000","1":"ff070000"}}"#,
            "fffffd00fe11008374000400020008000001ff07000038e0",
        ),
        (
            "dxl2",
            r#"{"instruction":"factory_reset","id":1,"option":255}"#,
            "fffffd0001040006ffa664",
        ),
    ];
    for (protocol, line, hex) in cases {
        let o = run(
            &["servo", "encode", "--protocol", protocol],
            &format!("{line}\n"),
        );
        assert_eq!(o.status.code(), Some(0), "{line}");
        assert_eq!(stdout(&o), format!("{{\"bytes\":\"{hex}\"}}\n"), "{line}");
    }
    // What a protocol cannot carry: a typed refusal, and the next line goes on.
    let o = run(
        &["servo", "encode", "--protocol", "scs0"],
        "{\"instruction\":\"reboot\",\"id\":1}\n{\"instruction\":\"read\",\"id\":1,\"address\":300,\"length\":2}\n{\"instruction\":\"ping\",\"id\":1}\n",
    );
    assert_eq!(o.status.code(), Some(1));
    assert_eq!(
        stdout(&o),
        "{\"error\":\"Feetech has no reboot instruction\",\"line\":1}\n\
         {\"error\":\"address 300 does not fit the protocol's 8-bit field\",\"line\":2}\n\
         {\"bytes\":\"ffff010201fb\"}\n"
    );
    // Status packets: noise skipped, a read's answer cut to what it asked,
    // a wrong checksum and a short answer refused by kind.
    let o = run(
        &["servo", "decode", "--protocol", "scs0"],
        "{\"bytes\":\"00ffff0104000008f2\",\"length\":2}\n{\"bytes\":\"ffff0104000008f3\"}\n{\"bytes\":\"ffff0104000008f2\",\"length\":4}\n",
    );
    assert_eq!(o.status.code(), Some(1));
    assert_eq!(
        stdout(&o),
        "{\"error\":0,\"id\":1,\"params\":\"0008\"}\n\
         {\"error\":\"check: the status packet's check is 0x00f3, its bytes' is 0x00f2\",\"line\":2}\n\
         {\"error\":\"short: the status packet carries 2 parameter bytes, the read asked for 4\",\"line\":3}\n"
    );
    let o = run(
        &["servo", "decode", "--protocol", "dxl2"],
        "{\"bytes\":\"fffffd0001070055 00b0042eed54\"}\n",
    );
    assert_eq!(stdout(&o), "{\"error\":0,\"id\":1,\"params\":\"b0042e\"}\n");
}

#[test]
fn moteus_encode_and_decode_lines_as_mjbots_library_builds_and_reads_them() {
    // The bytes mjbots' Python library (moteus 1.1.1) builds for these
    // calls: Controller(1).make_position(position=0.5, velocity=math.nan,
    // maximum_torque=1.0, query=True) and Controller(3,
    // can_prefix=5).make_stop(query=True).
    let input = concat!(
        r#"{"command":"position","id":1,"position":0.5,"velocity":null,"maximum_torque":1.0,"query":true}"#,
        "\n",
        r#"{"command":"position","id":1,"positon":0.5}"#,
        "\n",
        r#"{"command":"stop","id":3,"query":true,"can_prefix":5}"#,
        "\n",
    );
    let o = run(&["moteus", "encode"], input);
    assert_eq!(o.status.code(), Some(1));
    assert_eq!(
        stdout(&o),
        concat!(
            r#"{"can_id":32769,"data":"01000a0e200000003f0000c07f0d250000803f11001f01130d"}"#,
            "\n",
            r#"{"error":"position: unknown member \"positon\" (did you mean \"position\"?)","line":2}"#,
            "\n",
            r#"{"can_id":360451,"data":"01000011001f01130d"}"#,
            "\n",
        )
    );
    // A reply from controller 1 (mode 10, position 0.5 as f32, padding),
    // then one cut inside its position.
    let o = run(
        &["moteus", "decode"],
        "{\"can_id\":256,\"data\":\"21000a2d010000003f505050\"}\n{\"can_id\":256,\"data\":\"21000a2d01000000\"}\n",
    );
    assert_eq!(o.status.code(), Some(1));
    assert_eq!(
        stdout(&o),
        concat!(
            r#"{"errors":[],"id":1,"values":[{"name":"MODE","register":0,"value":10},{"name":"POSITION","register":1,"value":0.5}]}"#,
            "\n",
            r#"{"error":"the frame ends inside a subframe at byte 3 (it is 8 bytes)","line":2}"#,
            "\n",
        )
    );
}

/// `motorwire sim moteus --bus sim` between `motorwire moteus encode` and
/// `decode`: a position command and a query in, the simulated
/// controller's replies out, read back by the library's names.
#[test]
fn a_simulated_moteus_answers_frames_on_its_lines() {
    let frames = run(
        &["moteus", "encode"],
        concat!(
            r#"{"command":"position","id":1,"position":0.25,"velocity":0,"velocity_limit":1,"accel_limit":4,"query":true}"#,
            "\n",
            r#"{"command":"stop","id":2}"#,
            "\n",
            r#"{"command":"brake","id":1,"query":true}"#,
            "\n",
        ),
    );
    assert_eq!(frames.status.code(), Some(0));
    let replies = run(
        &["sim", "moteus", "--id", "1", "--bus", "sim"],
        &stdout(&frames),
    );
    assert_eq!(replies.status.code(), Some(0));
    let replies = stdout(&replies);
    let lines: Vec<&str> = replies.lines().collect();
    assert_eq!(lines.len(), 3, "{replies}");
    // Frame 2 is for controller 2: no answer from controller 1.
    assert_eq!(lines[1], r#"{"can_id":null,"data":null}"#);
    let decoded = run(
        &["moteus", "decode"],
        &format!("{}\n{}\n", lines[0], lines[2]),
    );
    let decoded = stdout(&decoded);
    let modes: Vec<&str> = decoded
        .lines()
        .map(|l| {
            let start = l.find(r#""name":"MODE","register":0,"value":"#).unwrap();
            &l[start + 35..start + 37]
        })
        .collect();
    // Position mode (10), then brake (15).
    assert_eq!(modes, ["10", "15"], "{decoded}");
}
