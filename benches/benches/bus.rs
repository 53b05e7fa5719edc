//! The iRPC round trip, request to Ack: the client, the in-memory bus and
//! the simulated joint (which plans each move), against the codec work alone
//! of the same exchange, measured in the same run.
//!
//! `cargo bench -p motorwire-benches --bench bus`
#![allow(
    missing_docs,
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing
)]

use std::hint::black_box;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use motorwire_can::client::{ClientConfig, Outcome};
use motorwire_can::{Faults, SimConfig};
use motorwire_irpc::{Header, Message, Payload, SetTargetPayloadV2, WireVersion};
use motorwire_sim::JointConfig;
use motorwire_sim::rig::Rig;

fn command(i: u32) -> SetTargetPayloadV2 {
    SetTargetPayloadV2::scurve((i % 180) as f32 - 90.0, 100.0, 500.0, 2000.0)
}

fn ready_rig(faults: Faults) -> Rig {
    let mut rig = Rig::new(
        SimConfig {
            faults,
            seed: 1,
            ..SimConfig::default()
        },
        ClientConfig::default(),
        [JointConfig::new(0x10)],
    )
    .unwrap();
    for p in [Payload::Configure, Payload::Activate] {
        assert_eq!(rig.request(0x10, p).unwrap().outcome, Outcome::Acked);
    }
    rig
}

fn round_trip(c: &mut Criterion) {
    let mut g = c.benchmark_group("irpc_round_trip");
    g.throughput(Throughput::Elements(1));

    // Baseline: only the codec work of the exchange (encode the request
    // frame, decode it, encode the Ack frame, decode it).
    g.bench_function("codec_only_baseline", |b| {
        let mut i = 0u32;
        let mut buf = [0u8; 64];
        b.iter(|| {
            i = i.wrapping_add(1);
            let req = Message {
                header: Header {
                    source_id: 0,
                    target_id: 0x10,
                    msg_id: i,
                },
                payload: Payload::SetTargetV2(command(i)),
            };
            let n = req.encode_frame(WireVersion::V2_0, &mut buf).unwrap();
            let got = Message::decode_frame(WireVersion::V2_0, black_box(&buf[..n])).unwrap();
            let ack = Message {
                header: Header {
                    source_id: 0x10,
                    target_id: 0,
                    msg_id: got.header.msg_id,
                },
                payload: Payload::Ack(got.header.msg_id),
            };
            let n = ack.encode_frame(WireVersion::V2_0, &mut buf).unwrap();
            Message::decode_frame(WireVersion::V2_0, black_box(&buf[..n])).unwrap()
        })
    });

    g.bench_function("client_bus_sim_joint", |b| {
        let mut rig = ready_rig(Faults::default());
        let mut i = 0u32;
        b.iter(|| {
            i = i.wrapping_add(1);
            let done = rig.request(0x10, Payload::SetTargetV2(command(i))).unwrap();
            rig.take_events();
            assert_eq!(done.outcome, Outcome::Acked);
        })
    });

    g.bench_function("client_bus_sim_joint_with_faults", |b| {
        // 10% drop, 10% duplicate (no corruption: every command stays valid).
        let mut rig = ready_rig(Faults {
            drop: 0.1,
            duplicate: 0.1,
            ..Faults::default()
        });
        let mut i = 0u32;
        b.iter(|| {
            i = i.wrapping_add(1);
            let done = rig.request(0x10, Payload::SetTargetV2(command(i))).unwrap();
            rig.take_events();
            black_box(done)
        })
    });
    g.finish();
}

criterion_group!(benches, round_trip);
criterion_main!(benches);
