//! Frames byte for byte as mjbots' Python library (moteus 1.1.1) builds
//! them for the same calls (`Controller(...).make_*(...).data`), and
//! replies valued as its `parse_message` values them. The random
//! differential test against the library itself is
//! `tools/moteus_reference.py`, run in CI.
#![allow(clippy::unwrap_used, clippy::indexing_slicing, clippy::panic)]

use motorwire_moteus::{Call, CallError, ReplyError, Scaled, decode, hex};

fn encode(json: &str) -> (u32, String) {
    let f = Call::from_json(json)
        .unwrap_or_else(|e| panic!("{json}: {e}"))
        .encode()
        .unwrap();
    (f.can_id, hex(&f.data))
}

#[test]
fn calls_encode_as_the_library_builds_them() {
    let cases: &[(&str, u32, &str)] = &[
        // int16 position 0.29: the library divides in f64 (2899.99..., sent
        // 2899); moteus-protocol's f32 division would send 2900. Velocity
        // -1.5 at int16 is -6000 exactly (f32: -5999).
        (
            r#"{"command":"position","id":2,"position":0.29,"velocity":-1.5,"maximum_torque":2.0,"position_resolution":{"position":"int16","velocity":"int16","maximum_torque":"int8"}}"#,
            2,
            "01000a0620530b90e8012504",
        ),
        (
            r#"{"command":"query","id":5,"source":1,"query_override":{"q_current":"f32","trajectory_complete":"int8","voltage":"int16"}}"#,
            0x8105,
            "11001c0401110b150d120e",
        ),
        (
            r#"{"command":"current","id":3,"d_A":0.0,"q_A":1.25,"query":true}"#,
            0x8003,
            "0100090e1c0000a03f0000000011001f01130d",
        ),
        (
            r#"{"command":"stay_within","id":4,"lower_bound":-0.25,"upper_bound":0.25,"kp_scale":0.5}"#,
            4,
            "01000d0e40000080be0000803e0d430000003f",
        ),
        (
            r#"{"command":"zero_velocity","id":1,"kd_scale":0.8}"#,
            1,
            "01000c0d24cdcc4c3f",
        ),
        (
            r#"{"command":"set_output_exact","id":1,"position":1.5}"#,
            1,
            "0db1020000c03f",
        ),
        (
            r#"{"command":"brake","id":9,"can_prefix":4660}"#,
            0x1234_0009,
            "01000f",
        ),
        (
            r#"{"command":"position","id":1,"position":null,"velocity":0.5,"watchdog_timeout":0.1,"ignore_position_bounds":1}"#,
            1,
            "01000a0e200000c07f0000003f0d27cdcccc3d0d2d0000803f",
        ),
    ];
    for (json, can_id, data) in cases {
        assert_eq!(encode(json), (*can_id, (*data).to_owned()), "{json}");
    }
}

#[test]
fn what_the_library_would_do_wrong_or_cannot_send_is_refused() {
    let err = |json: &str| Call::from_json(json).and_then(|c| c.encode()).unwrap_err();
    assert_eq!(
        err(r#"{"command":"position","id":1,"velocty":1.0}"#).to_string(),
        "position: unknown member \"velocty\" (did you mean \"velocity\"?)"
    );
    assert_eq!(
        err(r#"{"command":"postion","id":1}"#),
        CallError::UnknownCommand {
            name: "postion".into(),
            suggestion: Some("position")
        }
    );
    assert_eq!(
        err(r#"{"command":"current","id":1,"q_A":1.0}"#),
        CallError::Missing {
            command: "current",
            member: "d_A"
        }
    );
    assert!(matches!(
        err(r#"{"command":"stop","id":128}"#),
        CallError::OutOfRange { .. }
    ));
    assert!(matches!(
        err(r#"{"command":"position","id":1,"ignore_position_bounds":null}"#),
        CallError::OutOfRange { .. }
    ));
    assert!(matches!(
        err(r#"{"command":"position","id":1,"position":1e39}"#),
        CallError::OutOfRange { .. }
    ));
    // At int16 the same value saturates, as the library saturates it.
    assert_eq!(
        encode(r#"{"command":"position","id":1,"position":1e39,"position_resolution":{"position":"int16"}}"#).1,
        "01000a0520ff7f"
    );
    // Every position field at f32 with the default query: 62 + 6 bytes,
    // over one CAN-FD frame.
    let all = r#"{"command":"position","id":1,"position":0,"velocity":0,"feedforward_torque":0,"kp_scale":0,"kd_scale":0,"maximum_torque":0,"stop_position":0,"watchdog_timeout":0,"velocity_limit":0,"accel_limit":0,"fixed_voltage_override":0,"ilimit_scale":0,"fixed_current_override":0,"ignore_position_bounds":0,"query":true}"#;
    assert_eq!(err(all), CallError::TooLong { size: 68 });
    assert_eq!(encode(&all.replace(r#","query":true"#, "")).1.len(), 62 * 2);
}

/// Every keyword of the library's `make_*` signatures, with the types Python
/// passes: the bytes are the library's own (moteus 1.1.1,
/// `Controller(...).make_*(...).data` and the transport's arbitration id).
#[test]
fn keywords_take_the_types_python_passes() {
    let cases: &[(&str, u32, &str)] = &[
        // make_position(position=0.5, ignore_position_bounds=True): True is
        // int(True), 1, as an f32.
        (
            r#"{"command":"position","id":1,"position":0.5,"ignore_position_bounds":true}"#,
            1,
            "01000a0d200000003f0d2d0000803f",
        ),
        // ignore_position_bounds=False at int8, position at int16, query=True.
        (
            r#"{"command":"position","id":3,"position":0.5,"ignore_position_bounds":false,"query":true,"position_resolution":{"position":"int16","ignore_position_bounds":"int8"}}"#,
            0x8003,
            "01000a05208813012d0011001f01130d",
        ),
        // make_stay_within(..., stop_position=0.1): taken, and not sent.
        (
            r#"{"command":"stay_within","id":1,"lower_bound":-0.25,"upper_bound":0.25,"stop_position":0.1}"#,
            1,
            "01000d0e40000080be0000803e",
        ),
        // stop_position=1e300 (no f32 holds it: ignored all the same) with
        // ignore_position_bounds=True and query=True.
        (
            r#"{"command":"stay_within","id":1,"lower_bound":-0.25,"upper_bound":0.25,"stop_position":1e300,"ignore_position_bounds":true,"query":true}"#,
            0x8001,
            "01000d0e40000080be0000803e0d480000803f11001f01130d",
        ),
        // query_override=None: the default query (or none).
        (
            r#"{"command":"stop","id":1,"query":true,"query_override":null}"#,
            0x8001,
            "01000011001f01130d",
        ),
        (
            r#"{"command":"query","id":1,"query_override":null}"#,
            0x8001,
            "11001f01130d",
        ),
        // A QueryResolution's rezero_state, merged with home_state as the
        // library merges them (the finer wins; alone, its own).
        (
            r#"{"command":"query","id":1,"query_override":{"rezero_state":"int16","home_state":"int8"}}"#,
            0x8001,
            "11001f01150c130d",
        ),
        (
            r#"{"command":"brake","id":1,"query_override":{"rezero_state":"f32"}}"#,
            0x8001,
            "01000f11001f011d0c130d",
        ),
        (
            r#"{"command":"brake","id":1,"query_override":{"rezero_state":"int8","home_state":"int32"}}"#,
            0x8001,
            "01000f11001f01190c130d",
        ),
    ];
    for (json, can_id, data) in cases {
        assert_eq!(encode(json), (*can_id, (*data).to_owned()), "{json}");
    }
}

#[test]
fn keywords_the_library_does_not_take_are_still_refused() {
    let err = |json: &str| Call::from_json(json).and_then(|c| c.encode()).unwrap_err();
    assert_eq!(
        err(r#"{"command":"stay_within","id":1,"stop_positon":0.5}"#).to_string(),
        "stay_within: unknown member \"stop_positon\" (did you mean \"stop_position\"?)"
    );
    // make_query has no `query` keyword (the library raises TypeError).
    assert!(matches!(
        err(r#"{"command":"query","id":1,"query":true}"#),
        CallError::UnknownMember { member, .. } if member == "query"
    ));
    assert_eq!(
        err(r#"{"command":"position","id":1,"ignore_position_bounds":"yes"}"#).to_string(),
        "ignore_position_bounds: expected true or false, a number, or null for NaN, got the string \"yes\""
    );
    // A bool only where the library takes a flag.
    assert!(matches!(
        err(r#"{"command":"position","id":1,"kp_scale":true}"#),
        CallError::WrongType { .. }
    ));
    assert!(matches!(
        err(r#"{"command":"query","id":1,"query_override":{"rezero":"int8"}}"#),
        CallError::UnknownMember { .. }
    ));
}

#[test]
fn replies_decode_as_the_library_values_them() {
    // Mode 10 (int8); position 1998 and velocity -736 (int16); torque 11791
    // (int32); a read error on register 0x102, code 3; padding. The
    // library's parse_registers: response {0: 10, 1: 0.1998, 2: -0.184,
    // 3: 11.791}, errors [(258, 3)].
    let data = [
        0x21, 0x00, 0x0a, 0x26, 0x01, 0xce, 0x07, 0x20, 0xfd, 0x29, 0x03, 0x0f, 0x2e, 0x00, 0x00,
        0x31, 0x82, 0x02, 0x03, 0x50, 0x50,
    ];
    let r = decode(0x10500, &data).unwrap();
    assert_eq!((r.source, r.destination, r.can_prefix), (5, 0, 1));
    let values: Vec<(u16, Option<&str>, Scaled)> = r
        .values
        .iter()
        .map(|v| (v.register, v.name(), v.value))
        .collect();
    assert_eq!(
        values,
        [
            (0, Some("MODE"), Scaled::Int(10)),
            (1, Some("POSITION"), Scaled::Float(0.1998)),
            (2, Some("VELOCITY"), Scaled::Float(-0.184)),
            (3, Some("TORQUE"), Scaled::Float(11.791)),
        ]
    );
    assert_eq!(r.errors.len(), 1);
    assert_eq!(
        (r.errors[0].register, r.errors[0].code, r.errors[0].write),
        (0x102, 3, false)
    );
    // Cut one byte short of its last value: refused, saying where.
    assert_eq!(
        decode(0x10500, &data[..14]),
        Err(ReplyError::Truncated { at: 9, len: 14 })
    );
}

/// The diagnostic stream's frames as `Controller(id=5).make_diagnostic_write`
/// and `make_diagnostic_read` build them (moteus 1.1.1; the transport sets
/// the CAN id: `0x8005` where a reply is asked for, `0x0005` where not), and
/// answers as `parse_diagnostic_message` reads them.
#[test]
fn the_diagnostic_stream_is_the_librarys() {
    use motorwire_moteus::diagnostic;
    let writes: &[(&[u8], u8, &str)] = &[
        (
            b"conf get servopos.position_min\n",
            1,
            "40011f636f6e662067657420736572766f706f732e706f736974696f6e5f6d696e0a",
        ),
        (
            b"conf set servopos.position_max 0.16666666666666666\n",
            1,
            "400133636f6e662073657420736572766f706f732e706f736974696f6e5f6d617820302e31363636363636363636363636363636360a",
        ),
        (b"x", 3, "40030178"),
        (
            &[b'a'; 61],
            1,
            "40013d61616161616161616161616161616161616161616161616161616161616161616161616161616161616161616161616161616161616161616161616161",
        ),
    ];
    for (data, channel, expected) in writes {
        let f = diagnostic::write(5, 0, *channel, data).unwrap();
        assert_eq!((f.can_id, hex(&f.data)), (0x0005, (*expected).to_owned()));
    }
    for (max, channel, expected) in [(48, 1, "420130"), (61, 2, "42023d"), (1, 1, "420101")] {
        let f = diagnostic::read(5, 0, channel, max).unwrap();
        assert_eq!((f.can_id, hex(&f.data)), (0x8005, expected.to_owned()));
    }
    // On CAN prefix 0x12 the id carries it in bits 16..28.
    assert_eq!(diagnostic::read(5, 0x12, 1, 48).unwrap().can_id, 0x12_8005);
    let a =
        diagnostic::decode(0x0500, &[0x41, 0x01, 0x04, b'O', b'K', b'\r', b'\n', 0x50]).unwrap();
    assert_eq!(
        (a.source, a.destination, a.can_prefix, a.channel),
        (5, 0, 0, 1)
    );
    assert_eq!(a.data, b"OK\r\n");
    // Channel 2 is read as 2 (the library returns None when it is not the
    // channel it asked for: the caller compares).
    let a = diagnostic::decode(0x0500, &[0x41, 0x02, 0x03, b'A', b'B', b'C']).unwrap();
    assert_eq!((a.channel, a.data.as_slice()), (2, &b"ABC"[..]));
    // Nothing waiting: an empty answer.
    assert_eq!(
        diagnostic::decode(0x0500, &[0x41, 0x01, 0x00])
            .unwrap()
            .data,
        b""
    );
}
