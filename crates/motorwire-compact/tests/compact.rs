//! The compact command: golden bytes, every refusal, and properties.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing
)]

use motorwire_compact::{
    CompactCommand, ControlMode, Error, Flags, LEN, MotorHash, NameRegistry, TorqueLimit,
    VelocityLimit,
};
use proptest::prelude::*;

fn hex(s: &str) -> Vec<u8> {
    s.split_whitespace()
        .map(|b| u8::from_str_radix(b, 16).unwrap())
        .collect()
}

fn test_one(cmd: CompactCommand, expected: &str) {
    let bytes = cmd.encode().unwrap();
    assert_eq!(bytes.to_vec(), hex(expected), "{cmd:?}");
    assert_eq!(CompactCommand::decode(&bytes).unwrap(), cmd);
}

#[test]
fn golden_vectors() {
    // The shoulder_pitch command of the WIA multi-axis example.
    test_one(
        CompactCommand {
            motor: MotorHash::of("shoulder_pitch"),
            timestamp_ms: 1_704_067_200_000,
            control_mode: ControlMode::Position,
            flags: Flags::NONE,
            setpoint: 45.0,
            velocity_limit: Some(VelocityLimit::from_units_per_s(60.0).unwrap()),
            torque_limit: None,
        },
        "cf 43 3b f3 00 f4 51 c2 8c 01 00 00 01 00 00 00 00 00 34 42 58 02 ff ff",
    );
    // Elbow, torque mode, every Phase 3 flag but ENCRYPTED, both limits.
    test_one(
        CompactCommand {
            motor: MotorHash::of("elbow"),
            timestamp_ms: 0x0102_0304_0506_0708,
            control_mode: ControlMode::Torque,
            flags: Flags::PRIORITY_HIGH
                .union(Flags::REQUIRE_ACK)
                .union(Flags::BROADCAST)
                .union(Flags::EMERGENCY_STOP),
            setpoint: -2.5,
            velocity_limit: Some(VelocityLimit(0xFFFE)),
            torque_limit: Some(TorqueLimit::from_nm(12.34).unwrap()),
        },
        "22 cb 57 81 08 07 06 05 04 03 02 01 03 e1 00 00 00 00 20 c0 fe ff d2 04",
    );
    // Every mode code, disabled with nothing else.
    for mode in ControlMode::ALL {
        let cmd = CompactCommand {
            motor: MotorHash(0),
            timestamp_ms: 0,
            control_mode: mode,
            flags: Flags::NONE,
            setpoint: 0.0,
            velocity_limit: None,
            torque_limit: None,
        };
        let expected = format!(
            "00 00 00 00 00 00 00 00 00 00 00 00 {:02x} 00 00 00 00 00 00 00 ff ff ff ff",
            mode.code()
        );
        test_one(cmd, &expected);
    }
}

#[test]
fn motor_hashes_match_wire_facts() {
    assert_eq!(MotorHash::of("shoulder_pitch").0, 0xF33B_43CF);
    assert_eq!(MotorHash::of("elbow").0, 0x8157_CB22);
    assert_eq!(MotorHash::of("").0, 0);
    assert_eq!(MotorHash::of("elbow").to_string(), "0x8157cb22");
}

fn valid() -> [u8; LEN] {
    hex("cf 43 3b f3 00 f4 51 c2 8c 01 00 00 01 00 00 00 00 00 34 42 58 02 ff ff")
        .try_into()
        .unwrap()
}

#[test]
fn decoding_refuses_every_malformed_field() {
    assert!(CompactCommand::decode(&valid()).is_ok());
    let with = |i: usize, b: u8| {
        let mut v = valid();
        v[i] = b;
        CompactCommand::decode(&v)
    };
    assert_eq!(with(12, 10), Err(Error::UnknownControlMode { code: 10 }));
    assert_eq!(
        with(12, 0xFF),
        Err(Error::UnknownControlMode { code: 0xFF })
    );
    for bit in [0x02, 0x04, 0x08] {
        assert_eq!(with(13, bit), Err(Error::ReservedFlags { bits: bit }));
    }
    assert_eq!(with(13, 0x10), Err(Error::Encrypted));
    assert_eq!(with(14, 1), Err(Error::ReservedBytes { value: 1 }));
    assert_eq!(with(15, 1), Err(Error::ReservedBytes { value: 0x100 }));
    // NaN and infinity setpoints.
    let mut v = valid();
    v[16..20].copy_from_slice(&f32::NAN.to_le_bytes());
    assert_eq!(
        CompactCommand::decode(&v),
        Err(Error::NonFinite { field: "setpoint" })
    );
    v[16..20].copy_from_slice(&f32::NEG_INFINITY.to_le_bytes());
    assert_eq!(
        CompactCommand::decode(&v),
        Err(Error::NonFinite { field: "setpoint" })
    );
    // Lengths.
    assert_eq!(
        CompactCommand::decode(&[]),
        Err(Error::WrongLength { len: 0 })
    );
    let long = [valid().as_slice(), &[0]].concat();
    assert_eq!(
        CompactCommand::decode(&long),
        Err(Error::WrongLength { len: 25 })
    );
}

#[test]
fn encoding_refuses_what_does_not_fit() {
    let base = CompactCommand::decode(&valid()).unwrap();
    let nan = CompactCommand {
        setpoint: f32::NAN,
        ..base
    };
    assert_eq!(nan.encode(), Err(Error::NonFinite { field: "setpoint" }));
    let enc = CompactCommand {
        flags: Flags::ENCRYPTED,
        ..base
    };
    assert_eq!(enc.encode(), Err(Error::Encrypted));
    let raw = CompactCommand {
        velocity_limit: Some(VelocityLimit(0xFFFF)),
        ..base
    };
    assert_eq!(
        raw.encode(),
        Err(Error::LimitTooLarge {
            field: "velocity_limit",
            value: 65535.0,
            max: 65534.0
        })
    );
    assert_eq!(
        TorqueLimit::from_nm(655.35),
        Err(Error::LimitTooLarge {
            field: "torque_limit",
            value: 655.35,
            max: 655.34
        })
    );
    assert_eq!(TorqueLimit::from_nm(655.34), Ok(TorqueLimit(65534)));
    assert_eq!(
        VelocityLimit::from_units_per_s(-0.1),
        Err(Error::NegativeLimit {
            field: "velocity_limit",
            value: -0.1
        })
    );
    assert_eq!(
        VelocityLimit::from_units_per_s(f64::INFINITY),
        Err(Error::NonFinite {
            field: "velocity_limit"
        })
    );
    assert_eq!(
        CompactCommand::setpoint_from_f64(f64::NAN),
        Err(Error::NonFinite { field: "setpoint" })
    );
    let mut short = [0u8; 23];
    assert_eq!(
        base.encode_into(&mut short),
        Err(Error::WrongLength { len: 23 })
    );
}

#[test]
fn limits_round_down_never_looser() {
    // Decimal inputs whose binary form sits just below the step still land on it.
    assert_eq!(VelocityLimit::from_units_per_s(0.3), Ok(VelocityLimit(3)));
    assert_eq!(TorqueLimit::from_nm(0.29), Ok(TorqueLimit(29)));
    assert_eq!(
        VelocityLimit::from_units_per_s(60.09),
        Ok(VelocityLimit(600))
    );
    assert_eq!(TorqueLimit::from_nm(1.999), Ok(TorqueLimit(199)));
}

#[test]
fn registry_detects_collisions_and_capacity() {
    let mut r = NameRegistry::<2>::new();
    r.insert("a").unwrap();
    r.insert("a").unwrap();
    assert_eq!(r.len(), 1);
    r.insert("b").unwrap();
    assert_eq!(r.insert("c"), Err(Error::RegistryFull { capacity: 2 }));
    // "plumless" and "buckeroo" are a known CRC-32 collision.
    let mut r = NameRegistry::<4>::new();
    r.insert("plumless").unwrap();
    assert_eq!(MotorHash::of("plumless"), MotorHash::of("buckeroo"));
    assert_eq!(
        r.insert("buckeroo"),
        Err(Error::HashCollision {
            hash: MotorHash::of("plumless").0
        })
    );
}

// Needs the feature, which the workspace turns on for tests (a self
// dev-dependency) and a downloaded crate does with `--features serde`.
#[cfg(feature = "serde")]
#[test]
fn json_form_round_trips_exactly() {
    let cmd = CompactCommand::decode(&valid()).unwrap();
    let json = serde_json::to_string(&cmd).unwrap();
    assert_eq!(
        json,
        r#"{"motor":4080747471,"timestamp_ms":1704067200000,"control_mode":"position","flags":0,"setpoint":45.0,"velocity_limit":600,"torque_limit":null}"#
    );
    assert_eq!(serde_json::from_str::<CompactCommand>(&json).unwrap(), cmd);
    assert!(serde_json::from_str::<CompactCommand>(&json.replace("position", "warp")).is_err());
}

fn any_command() -> impl Strategy<Value = CompactCommand> {
    (
        any::<u32>(),
        any::<u64>(),
        0u8..=9,
        prop::sample::select(vec![0u8, 0x80, 0x40, 0x20, 0x01, 0xE1]),
        any::<f32>().prop_filter("finite", |f| f.is_finite()),
        prop::option::of(0u16..0xFFFF),
        prop::option::of(0u16..0xFFFF),
    )
        .prop_map(|(m, t, mode, flags, sp, v, q)| CompactCommand {
            motor: MotorHash(m),
            timestamp_ms: t,
            control_mode: ControlMode::from_code(mode).unwrap(),
            flags: Flags::from_bits(flags).unwrap(),
            setpoint: sp,
            velocity_limit: v.map(VelocityLimit),
            torque_limit: q.map(TorqueLimit),
        })
}

/// Cases per property: all of them in an optimized build (CI runs this file
/// with `--release`), a tenth in a debug build, so that the README's
/// `cargo test` stays quick.
const fn cases(all: u32) -> u32 {
    if cfg!(debug_assertions) {
        all / 10
    } else {
        all
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(cases(4000)))]

    #[test]
    fn round_trip(cmd in any_command()) {
        let bytes = cmd.encode().unwrap();
        prop_assert_eq!(CompactCommand::decode(&bytes).unwrap(), cmd);
    }

    #[test]
    fn arbitrary_bytes_never_panic(bytes in prop::collection::vec(any::<u8>(), 0..40)) {
        if let Ok(cmd) = CompactCommand::decode(&bytes) {
            prop_assert!(cmd.setpoint.is_finite());
            prop_assert_eq!(bytes.len(), LEN);
            // What decodes re-encodes to the same bytes.
            prop_assert_eq!(cmd.encode().unwrap().to_vec(), bytes);
        }
    }

    #[test]
    fn arbitrary_24_bytes_never_panic(bytes in prop::array::uniform24(any::<u8>())) {
        if let Ok(cmd) = CompactCommand::decode(&bytes) {
            prop_assert!(cmd.setpoint.is_finite());
            prop_assert_eq!(cmd.encode().unwrap(), bytes);
        }
    }
}
