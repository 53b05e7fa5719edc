//! The compact device's feedback record (WIRE-FACTS §2.1): golden bytes
//! written by hand from the layout, every refusal, and a round trip.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing
)]

use motorwire_compact::{
    Error, FEEDBACK_FRAME_LEN, FEEDBACK_LEN, FeedbackRecord, MotorHash, StatusFlag, StatusFlags,
};
use proptest::prelude::*;

fn hex(s: &str) -> Vec<u8> {
    s.split_whitespace()
        .map(|b| u8::from_str_radix(b, 16).unwrap())
        .collect()
}

fn test_one(record: FeedbackRecord, expected: &str) {
    let bytes = record.encode().unwrap();
    assert_eq!(bytes.to_vec(), hex(expected), "{record:?}");
    assert_eq!(FeedbackRecord::decode(&bytes).unwrap(), record);
    assert_eq!(
        FeedbackRecord::decode(&bytes[..FEEDBACK_LEN]).unwrap(),
        record,
        "the 44-byte record alone"
    );
}

fn elbow() -> FeedbackRecord {
    FeedbackRecord {
        motor: MotorHash(0x8157_CB22),
        timestamp_us: 1_500_000,
        position: 45.0,
        velocity: -2.5,
        acceleration: 0.0,
        torque: 1.5,
        current: 2.0,
        voltage: 24.0,
        temperature: 25.0,
        status: StatusFlags::EMPTY
            .with(StatusFlag::Enabled)
            .with(StatusFlag::Calibrated)
            .with(StatusFlag::Homed)
            .with(StatusFlag::AtTarget),
        health: 100,
    }
}

#[test]
fn golden_vectors() {
    assert_eq!(MotorHash::of("elbow"), elbow().motor);
    test_one(
        elbow(),
        "22 cb 57 81 \
         60 e3 16 00 00 00 00 00 \
         00 00 34 42 \
         00 00 20 c0 \
         00 00 00 00 \
         00 00 c0 3f \
         00 00 00 40 \
         00 00 c0 41 \
         00 00 c8 41 \
         59 00 64 00 \
         00 00 00 00",
    );
    // Every status bit, a health of zero, the largest timestamp, the
    // extremes of f32.
    test_one(
        FeedbackRecord {
            motor: MotorHash::of("shoulder_pitch"),
            timestamp_us: u64::MAX,
            position: -0.0,
            velocity: f32::MAX,
            acceleration: f32::MIN,
            torque: f32::MIN_POSITIVE,
            current: -1.0,
            voltage: 0.5,
            temperature: -40.0,
            status: StatusFlags::from_bits(0x07FF).unwrap(),
            health: 0,
        },
        "cf 43 3b f3 \
         ff ff ff ff ff ff ff ff \
         00 00 00 80 \
         ff ff 7f 7f \
         ff ff 7f ff \
         00 00 80 00 \
         00 00 80 bf \
         00 00 00 3f \
         00 00 20 c2 \
         ff 07 00 00 \
         00 00 00 00",
    );
}

#[test]
fn every_float_must_be_finite_and_is_named() {
    let fields = [
        "position",
        "velocity",
        "acceleration",
        "torque",
        "current",
        "voltage",
        "temperature",
    ];
    for (i, field) in fields.into_iter().enumerate() {
        for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
            let mut r = elbow();
            let slot = match i {
                0 => &mut r.position,
                1 => &mut r.velocity,
                2 => &mut r.acceleration,
                3 => &mut r.torque,
                4 => &mut r.current,
                5 => &mut r.voltage,
                _ => &mut r.temperature,
            };
            *slot = bad;
            assert_eq!(r.encode(), Err(Error::NonFinite { field }));
            let mut bytes = elbow().encode().unwrap();
            bytes[12 + 4 * i..16 + 4 * i].copy_from_slice(&bad.to_le_bytes());
            assert_eq!(
                FeedbackRecord::decode(&bytes),
                Err(Error::NonFinite { field })
            );
        }
    }
}

#[test]
fn refusals_in_wire_order() {
    let good = elbow().encode().unwrap();

    let mut health = elbow();
    health.health = 101;
    assert_eq!(
        health.encode(),
        Err(Error::HealthOutOfRange { health: 101 })
    );
    let mut b = good;
    b[42] = 0xFF;
    assert_eq!(
        FeedbackRecord::decode(&b),
        Err(Error::HealthOutOfRange { health: 0xFF })
    );

    let mut b = good;
    b[41] = 0x08; // status bit 0x0800: no flag
    assert_eq!(
        FeedbackRecord::decode(&b),
        Err(Error::ReservedStatusBits { bits: 0x0800 })
    );

    let mut b = good;
    b[43] = 0x01;
    assert_eq!(
        FeedbackRecord::decode(&b),
        Err(Error::FeedbackReserved { value: 0x01 })
    );

    for offset in FEEDBACK_LEN..FEEDBACK_FRAME_LEN {
        let mut b = good;
        b[offset] = 0xAA;
        assert_eq!(
            FeedbackRecord::decode(&b),
            Err(Error::FeedbackPadding {
                offset,
                value: 0xAA
            })
        );
    }

    // Several problems: the first in wire order wins.
    let mut b = good;
    b[12..16].copy_from_slice(&f32::NAN.to_le_bytes());
    b[42] = 200;
    b[47] = 1;
    assert_eq!(
        FeedbackRecord::decode(&b),
        Err(Error::NonFinite { field: "position" })
    );
}

#[test]
fn wrong_lengths() {
    let good = elbow().encode().unwrap();
    for len in [0, 24, 43, 45, 47, 64] {
        let mut v = good.to_vec();
        v.resize(len, 0);
        assert_eq!(
            FeedbackRecord::decode(&v),
            Err(Error::WrongFeedbackLength { len })
        );
    }
    let mut short = [0u8; 43];
    assert_eq!(
        elbow().encode_into(&mut short),
        Err(Error::WrongFeedbackLength { len: 43 })
    );
    let mut exact = [0xEEu8; 44];
    elbow().encode_into(&mut exact).unwrap();
    assert_eq!(exact[..], good[..FEEDBACK_LEN]);
}

#[test]
fn errors_say_what_is_wrong() {
    assert_eq!(
        Error::WrongFeedbackLength { len: 40 }.to_string(),
        "a feedback record is 44 bytes (or its 48-byte CAN-FD frame), not 40"
    );
    assert_eq!(
        Error::FeedbackPadding {
            offset: 45,
            value: 2
        }
        .to_string(),
        "the feedback frame's padding must be zero, but byte 45 is 0x02"
    );
    assert_eq!(
        Error::HealthOutOfRange { health: 101 }.to_string(),
        "health score 101 is over 100"
    );
}

fn finite() -> impl Strategy<Value = f32> {
    any::<f32>().prop_filter("finite", |v| v.is_finite())
}

proptest! {
    #[test]
    fn round_trip(
        motor in any::<u32>(),
        timestamp_us in any::<u64>(),
        floats in proptest::array::uniform7(finite()),
        status in 0u16..=0x07FF,
        health in 0u8..=100,
    ) {
        let [position, velocity, acceleration, torque, current, voltage, temperature] = floats;
        let r = FeedbackRecord {
            motor: MotorHash(motor),
            timestamp_us,
            position, velocity, acceleration, torque, current, voltage, temperature,
            status: StatusFlags::from_bits(status).unwrap(),
            health,
        };
        let bytes = r.encode().unwrap();
        let back = FeedbackRecord::decode(&bytes).unwrap();
        // Bit-exact (so -0.0 stays -0.0).
        prop_assert_eq!(back.encode().unwrap(), bytes);
    }

    #[test]
    fn decode_never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..64)) {
        let _ = FeedbackRecord::decode(&bytes);
    }
}
