//! Binary codecs against their baselines, measured in the same run:
//! iRPC against real postcard on an equivalent plain serde struct, and the
//! compact command against copying 24 bytes.
//!
//! `cargo bench -p motorwire-benches --bench codecs`
#![allow(
    missing_docs,
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing
)]

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use motorwire_compact::{CompactCommand, ControlMode, Flags, MotorHash, VelocityLimit};
use motorwire_irpc::{Header, Message, Payload, SetTargetPayloadV2, WireVersion};
use serde::{Deserialize, Serialize};

/// The same message as plain serde types in v2.0's variant order: what a
/// direct postcard user would write.
#[derive(Serialize, Deserialize, PartialEq, Debug)]
struct PlainMessage {
    header: PlainHeader,
    payload: PlainPayload,
}

#[derive(Serialize, Deserialize, PartialEq, Debug)]
struct PlainHeader {
    source_id: u16,
    target_id: u16,
    msg_id: u32,
}

#[derive(Serialize, Deserialize, PartialEq, Debug)]
enum PlainPayload {
    SetTarget(f32, f32),
    Configure,
    Activate,
    Deactivate,
    Reset,
    SetTargetV2(PlainSetTargetV2),
}

#[derive(Serialize, Deserialize, PartialEq, Debug)]
struct PlainSetTargetV2 {
    target_angle: f32,
    max_velocity: f32,
    target_velocity: f32,
    max_acceleration: f32,
    max_deceleration: f32,
    max_jerk: f32,
    profile: PlainProfile,
    max_current: f32,
    max_temperature: f32,
}

#[derive(Serialize, Deserialize, PartialEq, Debug)]
enum PlainProfile {
    Trapezoidal,
    SCurve,
    Adaptive,
}

fn irpc(c: &mut Criterion) {
    let msg = Message {
        header: Header {
            source_id: 0x0000,
            target_id: 0x0010,
            msg_id: 42,
        },
        payload: Payload::SetTargetV2(SetTargetPayloadV2::scurve(90.0, 100.0, 500.0, 2000.0)),
    };
    let plain = PlainMessage {
        header: PlainHeader {
            source_id: 0x0000,
            target_id: 0x0010,
            msg_id: 42,
        },
        payload: PlainPayload::SetTargetV2(PlainSetTargetV2 {
            target_angle: 90.0,
            max_velocity: 100.0,
            target_velocity: 0.0,
            max_acceleration: 500.0,
            max_deceleration: 500.0,
            max_jerk: 2000.0,
            profile: PlainProfile::SCurve,
            max_current: 0.0,
            max_temperature: 0.0,
        }),
    };
    // Sanity: both produce the document's 37 bytes.
    let mut a = [0u8; 64];
    let n = msg.encode(WireVersion::V2_0, &mut a).unwrap();
    let mut b = [0u8; 64];
    let m = postcard::to_slice(&plain, &mut b).unwrap().len();
    assert_eq!((n, &a[..n]), (m, &b[..m]));
    assert_eq!(n, 37);
    let bytes = a[..n].to_vec();

    let mut g = c.benchmark_group("irpc_set_target_v2");
    g.bench_function("encode_motorwire", |bch| {
        let mut buf = [0u8; 64];
        bch.iter(|| {
            black_box(&msg)
                .encode(WireVersion::V2_0, black_box(&mut buf))
                .unwrap()
        })
    });
    g.bench_function("encode_postcard_plain_struct", |bch| {
        let mut buf = [0u8; 64];
        bch.iter(|| {
            postcard::to_slice(black_box(&plain), black_box(&mut buf))
                .unwrap()
                .len()
        })
    });
    g.bench_function("decode_motorwire", |bch| {
        bch.iter(|| Message::decode(WireVersion::V2_0, black_box(&bytes)).unwrap())
    });
    g.bench_function("decode_postcard_plain_struct", |bch| {
        bch.iter(|| postcard::from_bytes::<PlainMessage>(black_box(&bytes)).unwrap())
    });
    g.finish();
}

fn compact(c: &mut Criterion) {
    let cmd = CompactCommand {
        motor: MotorHash::of("shoulder_pitch"),
        timestamp_ms: 1_704_067_200_000,
        control_mode: ControlMode::Position,
        flags: Flags::REQUIRE_ACK,
        setpoint: 45.0,
        velocity_limit: Some(VelocityLimit(600)),
        torque_limit: None,
    };
    let bytes = cmd.encode().unwrap();
    let mut g = c.benchmark_group("compact_command");
    g.bench_function("copy_24_bytes_baseline", |b| {
        let mut dst = [0u8; 24];
        b.iter(|| {
            dst.copy_from_slice(black_box(&bytes[..]));
            black_box(&mut dst);
        })
    });
    g.bench_function("encode", |b| b.iter(|| black_box(&cmd).encode().unwrap()));
    g.bench_function("decode", |b| {
        b.iter(|| CompactCommand::decode(black_box(&bytes[..])).unwrap())
    });
    g.finish();
}

criterion_group!(benches, irpc, compact);
criterion_main!(benches);
