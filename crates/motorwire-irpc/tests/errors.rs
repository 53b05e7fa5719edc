//! Every way a frame or a message can be refused, with the exact error.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing
)]

mod common;

use WireVersion::*;
use common::hex;
use motorwire_irpc::*;

const EXAMPLE: &str = "00 10 2a 05 00 00 b4 42 00 00 c8 42 00 00 00 00 00 00 fa 43 00 00 fa 43 00 00 fa 44 01 00 00 00 00 00 00 00 00";

fn dec(v: WireVersion, h: &str) -> Result<Message, Error> {
    Message::decode(v, &hex(h))
}

#[test]
fn truncation_names_the_field_being_read() {
    let full = hex(EXAMPLE);
    assert_eq!(
        Message::decode(V2_0, &[]),
        Err(Error::Truncated {
            field: "header.source_id",
            offset: 0
        })
    );
    assert_eq!(
        Message::decode(V2_0, &full[..3]),
        Err(Error::Truncated {
            field: "payload",
            offset: 3
        })
    );
    assert_eq!(
        Message::decode(V2_0, &full[..7]),
        Err(Error::Truncated {
            field: "SetTargetV2.target_angle",
            offset: 7
        })
    );
    assert_eq!(
        Message::decode(V2_0, &full[..28]),
        Err(Error::Truncated {
            field: "SetTargetV2.profile",
            offset: 28
        })
    );
    assert_eq!(
        Message::decode(V2_0, &full[..36]),
        Err(Error::Truncated {
            field: "SetTargetV2.max_temperature",
            offset: 36
        })
    );
    // A varint cut inside its continuation bytes.
    assert_eq!(
        dec(V2_0, "80"),
        Err(Error::Truncated {
            field: "header.source_id",
            offset: 1
        })
    );
}

#[test]
fn unknown_tags_depend_on_the_version() {
    // SetTargetV2's tag 5 is Encoder in v1; tag 10 is ArmReady in v2.0 only.
    assert!(matches!(
        dec(V1, "00 10 01 05 00 00 00 00 00 00 00 00")
            .unwrap()
            .payload,
        Payload::Encoder(_)
    ));
    assert_eq!(
        dec(V1, "00 10 01 0a"),
        Err(Error::UnknownTag {
            tag: 10,
            version: V1,
            offset: 3
        })
    );
    assert_eq!(
        dec(V2_0, "00 10 01 0b"),
        Err(Error::UnknownTag {
            tag: 11,
            version: V2_0,
            offset: 3
        })
    );
    assert_eq!(
        dec(V2_1, "00 10 01 15"),
        Err(Error::UnknownTag {
            tag: 21,
            version: V2_1,
            offset: 3
        })
    );
    assert_eq!(
        dec(V2_2, "00 10 01 1c"),
        Err(Error::UnknownTag {
            tag: 28,
            version: V2_2,
            offset: 3
        })
    );
    assert_eq!(
        dec(V2_2, "00 10 01 ff ff ff ff 0f"),
        Err(Error::UnknownTag {
            tag: u32::MAX,
            version: V2_2,
            offset: 3
        })
    );
}

#[test]
fn enum_indices_out_of_range() {
    let mut b = hex(EXAMPLE);
    b[28] = 3;
    assert_eq!(
        Message::decode(V2_0, &b),
        Err(Error::InvalidEnum {
            field: "SetTargetV2.profile",
            index: 3,
            offset: 28
        })
    );
    // LifecycleState: 4 is Error in v2.1, nothing in v2.0.
    assert_eq!(
        dec(V2_0, "10 00 01 07 04 00"),
        Err(Error::InvalidEnum {
            field: "JointStatus.state",
            index: 4,
            offset: 4
        })
    );
    assert_eq!(
        dec(V2_1, "10 00 01 07 04 00").unwrap().payload,
        Payload::JointStatus {
            state: LifecycleState::Error,
            error_code: 0
        }
    );
    assert_eq!(
        dec(V2_0, "10 00 01 07 03 00").unwrap().payload,
        Payload::JointStatus {
            state: LifecycleState::Error,
            error_code: 0
        }
    );
}

#[test]
fn varints_that_overflow_or_are_not_canonical() {
    // u16 with a value above 65535, and with a fourth byte.
    assert_eq!(
        dec(V2_0, "ff ff 7f"),
        Err(Error::VarintOverflow {
            field: "header.source_id",
            offset: 0
        })
    );
    assert_eq!(
        dec(V2_0, "80 80 80 01"),
        Err(Error::VarintOverflow {
            field: "header.source_id",
            offset: 0
        })
    );
    // u32 msg_id with a sixth byte, and with 2^32.
    assert_eq!(
        dec(V2_0, "00 10 80 80 80 80 80 01"),
        Err(Error::VarintOverflow {
            field: "header.msg_id",
            offset: 2
        })
    );
    assert_eq!(
        dec(V2_0, "00 10 80 80 80 80 10 01"),
        Err(Error::VarintOverflow {
            field: "header.msg_id",
            offset: 2
        })
    );
    // u64 2^64: the tenth group may only be 0 or 1.
    let mut ts = hex("00 10 01 08 80 80 80 80 80 80 80 80 80 02");
    ts.extend(std::iter::repeat_n(0u8, 60));
    assert_eq!(
        Message::decode(V2_1, &ts),
        Err(Error::VarintOverflow {
            field: "TelemetryStream.timestamp_us",
            offset: 4
        })
    );
    // A redundant zero group: 0 written as two bytes.
    assert_eq!(
        dec(V2_0, "80 00 10 01 01"),
        Err(Error::NonCanonicalVarint {
            field: "header.source_id",
            offset: 0
        })
    );
    assert_eq!(
        dec(V2_0, "00 10 ff 80 00 01"),
        Err(Error::NonCanonicalVarint {
            field: "header.msg_id",
            offset: 2
        })
    );
}

#[test]
fn non_finite_floats_are_refused_both_ways() {
    let mut b = hex(EXAMPLE);
    b[8..12].copy_from_slice(&f32::NAN.to_le_bytes());
    assert_eq!(
        Message::decode(V2_0, &b),
        Err(Error::NonFinite {
            field: "SetTargetV2.max_velocity",
            offset: 8
        })
    );
    b[8..12].copy_from_slice(&f32::INFINITY.to_le_bytes());
    assert_eq!(
        Message::decode(V2_0, &b),
        Err(Error::NonFinite {
            field: "SetTargetV2.max_velocity",
            offset: 8
        })
    );
    let m = Message {
        header: Header {
            source_id: 0,
            target_id: 0x10,
            msg_id: 1,
        },
        payload: Payload::Encoder(EncoderTelemetry {
            position: 0.0,
            velocity: f32::NEG_INFINITY,
        }),
    };
    // 3 header bytes, the tag, then position: velocity starts at byte 8.
    let mut buf = [0u8; 64];
    assert_eq!(
        m.encode(V2_0, &mut buf),
        Err(Error::NonFinite {
            field: "Encoder.velocity",
            offset: 8
        })
    );
    assert_eq!(
        m.encoded_len(V2_0),
        Err(Error::NonFinite {
            field: "Encoder.velocity",
            offset: 8
        })
    );
}

#[test]
fn bools_are_zero_or_one() {
    // TelemetryStream's last byte is trajectory_active.
    let msg = Message {
        header: Header {
            source_id: 0x10,
            target_id: 0,
            msg_id: 1,
        },
        payload: Payload::TelemetryStream(TelemetryStream {
            timestamp_us: 1,
            position: 0.0,
            velocity: 0.0,
            acceleration: 0.0,
            current_d: 0.0,
            current_q: 0.0,
            voltage_d: 0.0,
            voltage_q: 0.0,
            torque_estimate: 0.0,
            power: 0.0,
            load_percent: 0.0,
            foc_loop_time_us: 0,
            temperature_c: 0.0,
            warnings: 0,
            trajectory_active: true,
        }),
    };
    let mut buf = [0u8; 128];
    let n = msg.encode(V2_1, &mut buf).unwrap();
    buf[n - 1] = 2;
    assert_eq!(
        Message::decode(V2_1, &buf[..n]),
        Err(Error::InvalidBool {
            field: "TelemetryStream.trajectory_active",
            byte: 2,
            offset: n - 1
        })
    );
}

#[test]
fn trailing_bytes_and_frames() {
    assert_eq!(
        dec(V2_0, "00 10 01 01 00"),
        Err(Error::TrailingBytes {
            offset: 4,
            count: 1
        })
    );
    let frame = |h: &str| Message::decode_frame(V2_0, &hex(h));
    assert!(frame("00 10 01 01").is_ok());
    assert!(frame("00 10 01 01 00 00 00 00").is_ok());
    assert!(frame("00 10 01 01 00 00 00 00 00 00 00 00").is_ok());
    assert_eq!(
        frame("00 10 01 01 00 00 00 00 00"),
        Err(Error::InvalidFrameLength { len: 9 })
    );
    assert_eq!(
        frame("00 10 01 01 00 00 01 00"),
        Err(Error::NonZeroPadding { offset: 6 })
    );
    assert_eq!(
        Message::decode_frame(V2_0, &[0u8; 65]),
        Err(Error::InvalidFrameLength { len: 65 })
    );
    // A truncated message inside a valid frame length is still truncation.
    assert_eq!(
        frame("00 10"),
        Err(Error::Truncated {
            field: "header.msg_id",
            offset: 2
        })
    );
}

#[test]
fn encoding_refuses_what_the_version_lacks() {
    let mut buf = [0u8; 64];
    let v2 = Message {
        header: Header {
            source_id: 0,
            target_id: 0x10,
            msg_id: 1,
        },
        payload: Payload::SetTargetV2(SetTargetPayloadV2 {
            target_angle: 1.0,
            max_velocity: 1.0,
            target_velocity: 0.0,
            max_acceleration: 1.0,
            max_deceleration: 1.0,
            max_jerk: 0.0,
            profile: MotionProfile::Trapezoidal,
            max_current: 0.0,
            max_temperature: 0.0,
        }),
    };
    assert_eq!(
        v2.encode(V1, &mut buf),
        Err(Error::PayloadNotInVersion {
            payload: PayloadKind::SetTargetV2,
            version: V1
        })
    );
    let calibrating = Message {
        header: v2.header,
        payload: Payload::JointStatus {
            state: LifecycleState::Calibrating,
            error_code: 0,
        },
    };
    assert_eq!(
        calibrating.encode(V2_0, &mut buf),
        Err(Error::ValueNotInVersion {
            field: "JointStatus.state",
            version: V2_0
        })
    );
    assert!(calibrating.encode(V2_1, &mut buf).is_ok());
    let mut small = [0u8; 10];
    assert_eq!(
        v2.encode(V2_0, &mut small),
        Err(Error::BufferTooSmall {
            needed: 37,
            available: 10
        })
    );
}

#[test]
fn messages_over_64_bytes_need_a_segmented_transport() {
    let worst = Message {
        header: Header {
            source_id: u16::MAX,
            target_id: u16::MAX,
            msg_id: u32::MAX,
        },
        payload: Payload::TelemetryStream(TelemetryStream {
            timestamp_us: u64::MAX,
            position: 1.0,
            velocity: 1.0,
            acceleration: 1.0,
            current_d: 1.0,
            current_q: 1.0,
            voltage_d: 1.0,
            voltage_q: 1.0,
            torque_estimate: 1.0,
            power: 1.0,
            load_percent: 1.0,
            foc_loop_time_us: u16::MAX,
            temperature_c: 1.0,
            warnings: u16::MAX,
            trajectory_active: true,
        }),
    };
    // 11 header + 1 tag + 10 + 40 + 3 + 4 + 3 + 1 = 73 bytes with a worst-case header;
    // the payload alone is WIRE-FACTS' 71 with a 1-byte tag and a minimal header.
    assert_eq!(worst.encoded_len(V2_1).unwrap(), 73);
    let mut frame = [0u8; 64];
    assert_eq!(
        worst.encode_frame(V2_1, &mut frame),
        Err(Error::FrameTooLarge { len: 73 })
    );
    let history = Message {
        header: Header {
            source_id: 0x10,
            target_id: 0,
            msg_id: 1,
        },
        payload: Payload::FaultHistory(FaultHistory {
            records: [FaultRecord::default(); 10],
            total_faults: 0,
            valid_count: 0,
        }),
    };
    // Even all-zero, ten 5-byte records exceed 64 bytes with the rest.
    let len = history.encoded_len(V2_2).unwrap();
    assert_eq!(len, 3 + 1 + 10 * 5 + 1 + 1);
    assert!(history.encode_frame(V2_2, &mut frame).is_ok() == (len <= 64));
    let full = Message {
        header: history.header,
        payload: Payload::FaultHistory(FaultHistory {
            records: [FaultRecord {
                fault_type: 1,
                timestamp_sec: u32::MAX,
                vbus_mv: u16::MAX,
                current_ma: u16::MAX,
                temp_c: -1,
            }; 10],
            total_faults: u32::MAX,
            valid_count: 10,
        }),
    };
    let len = full.encoded_len(V2_2).unwrap();
    assert_eq!(len, 3 + 1 + 10 * (1 + 5 + 3 + 3 + 1) + 5 + 1);
    assert_eq!(
        full.encode_frame(V2_2, &mut frame),
        Err(Error::FrameTooLarge { len })
    );
}

#[test]
fn errors_display_the_field_and_offset() {
    let mut b = hex(EXAMPLE);
    b[8..12].copy_from_slice(&f32::NAN.to_le_bytes());
    let e = Message::decode(V2_0, &b).unwrap_err();
    assert_eq!(
        e.to_string(),
        "SetTargetV2.max_velocity at byte 8 is NaN or infinite"
    );
    assert_eq!(
        Error::UnknownTag {
            tag: 11,
            version: V2_0,
            offset: 3
        }
        .to_string(),
        "payload tag 11 at byte 3 is not a payload of iRPC v2.0"
    );
}

#[test]
fn a_non_finite_float_is_refused_wherever_it_is_and_in_frames_too() {
    let mut m = Message {
        header: Header {
            source_id: 0,
            target_id: 0x10,
            msg_id: 1,
        },
        payload: Payload::SetTargetV2(SetTargetPayloadV2 {
            target_angle: 1.0,
            max_velocity: 1.0,
            target_velocity: 0.0,
            max_acceleration: 1.0,
            max_deceleration: 1.0,
            max_jerk: 0.0,
            profile: MotionProfile::SCurve,
            max_current: 0.0,
            max_temperature: f32::NAN,
        }),
    };
    let mut frame = [0u8; 64];
    let expected = Err(Error::NonFinite {
        field: "SetTargetV2.max_temperature",
        // header 3, tag 1, six floats 24, profile 1, max_current 4.
        offset: 33,
    });
    assert_eq!(m.encode_frame(V2_0, &mut frame), expected);
    assert_eq!(m.encode(V2_0, &mut frame), expected);
    // The first non-finite field is the one named.
    if let Payload::SetTargetV2(p) = &mut m.payload {
        p.max_velocity = f32::INFINITY;
    }
    assert_eq!(
        m.encode(V2_0, &mut frame),
        Err(Error::NonFinite {
            field: "SetTargetV2.max_velocity",
            offset: 8
        })
    );
}
