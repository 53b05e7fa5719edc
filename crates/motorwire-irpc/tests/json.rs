//! The JSON form: serde's externally tagged enums with the wire field names.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing
)]

mod common;

use motorwire_irpc::*;
use proptest::prelude::*;

const DOC_EXAMPLE: &str = r#"{"header":{"source_id":0,"target_id":16,"msg_id":42},"payload":{"SetTargetV2":{"target_angle":90.0,"max_velocity":100.0,"target_velocity":0.0,"max_acceleration":500.0,"max_deceleration":500.0,"max_jerk":2000.0,"profile":"SCurve","max_current":0.0,"max_temperature":0.0}}}"#;

fn header(source_id: u16, target_id: u16, msg_id: u32) -> Header {
    Header {
        source_id,
        target_id,
        msg_id,
    }
}

#[test]
fn the_documents_example() {
    let msg: Message = serde_json::from_str(DOC_EXAMPLE).unwrap();
    assert_eq!(serde_json::to_string(&msg).unwrap(), DOC_EXAMPLE);
    let mut buf = [0u8; 64];
    let n = msg.encode(WireVersion::V2_0, &mut buf).unwrap();
    assert_eq!(n, 37);
}

#[test]
fn unit_ack_nack_and_joint_status_forms() {
    let cases = [
        (
            Message {
                header: header(0, 16, 1),
                payload: Payload::Configure,
            },
            r#"{"header":{"source_id":0,"target_id":16,"msg_id":1},"payload":"Configure"}"#,
        ),
        (
            Message {
                header: header(16, 0, 42),
                payload: Payload::Ack(42),
            },
            r#"{"header":{"source_id":16,"target_id":0,"msg_id":42},"payload":{"Ack":42}}"#,
        ),
        (
            Message {
                header: header(16, 0, 42),
                payload: Payload::Nack { id: 42, error: 255 },
            },
            r#"{"header":{"source_id":16,"target_id":0,"msg_id":42},"payload":{"Nack":{"id":42,"error":255}}}"#,
        ),
        (
            Message {
                header: header(16, 0, 7),
                payload: Payload::JointStatus {
                    state: LifecycleState::Active,
                    error_code: 0,
                },
            },
            r#"{"header":{"source_id":16,"target_id":0,"msg_id":7},"payload":{"JointStatus":{"state":"Active","error_code":0}}}"#,
        ),
    ];
    for (msg, json) in cases {
        assert_eq!(serde_json::to_string(&msg).unwrap(), json);
        assert_eq!(serde_json::from_str::<Message>(json).unwrap(), msg);
    }
}

#[test]
fn json_that_does_not_fit_is_refused() {
    for bad in [
        // unknown field (a typo must not be ignored)
        r#"{"header":{"source_id":0,"target_id":16,"msg_id":1,"extra":1},"payload":"Configure"}"#,
        // unknown payload
        r#"{"header":{"source_id":0,"target_id":16,"msg_id":1},"payload":"Explode"}"#,
        // u16 out of range
        r#"{"header":{"source_id":70000,"target_id":16,"msg_id":1},"payload":"Configure"}"#,
        // missing field
        r#"{"header":{"source_id":0,"target_id":16},"payload":"Configure"}"#,
        // wrong enum name
        r#"{"header":{"source_id":0,"target_id":16,"msg_id":1},"payload":{"JointStatus":{"state":"Dancing","error_code":0}}}"#,
    ] {
        assert!(serde_json::from_str::<Message>(bad).is_err(), "{bad}");
    }
}

/// WIRE-FACTS §1.3: the public implementation names five fields of
/// `MotorParameters` and `FaultCounters` differently (`inertia_J`,
/// `overcurrent_events`, ...); its JSON reads the same, and is written back
/// with motorwire's names.
#[test]
fn the_public_implementations_field_names_are_accepted_as_aliases() {
    let theirs = r#"{"inertia_J":0.5,"torque_constant_kt":0.25,"damping_b":0.125,"friction_coulomb":1.0,"friction_stribeck":2.0,"friction_vstribeck":3.0,"friction_viscous":4.0}"#;
    let ours = r#"{"inertia":0.5,"torque_constant":0.25,"damping":0.125,"friction_coulomb":1.0,"friction_stribeck":2.0,"friction_vstribeck":3.0,"friction_viscous":4.0}"#;
    let parameters: MotorParameters = serde_json::from_str(theirs).unwrap();
    assert_eq!(
        parameters,
        MotorParameters {
            inertia: 0.5,
            torque_constant: 0.25,
            damping: 0.125,
            friction_coulomb: 1.0,
            friction_stribeck: 2.0,
            friction_vstribeck: 3.0,
            friction_viscous: 4.0,
        }
    );
    assert_eq!(
        serde_json::from_str::<MotorParameters>(ours).unwrap(),
        parameters
    );
    assert_eq!(serde_json::to_string(&parameters).unwrap(), ours);

    let theirs = r#"{"overcurrent_events":1,"overvoltage_events":2,"undervoltage_events":3,"overtemp_events":4,"driver_fault_events":5,"emergency_stops":6}"#;
    let ours = r#"{"overcurrent":1,"overvoltage":2,"undervoltage":3,"overtemp":4,"driver_fault":5,"emergency_stops":6}"#;
    let faults: FaultCounters = serde_json::from_str(theirs).unwrap();
    assert_eq!(
        faults,
        FaultCounters {
            overcurrent: 1,
            overvoltage: 2,
            undervoltage: 3,
            overtemp: 4,
            driver_fault: 5,
            emergency_stops: 6,
        }
    );
    assert_eq!(serde_json::to_string(&faults).unwrap(), ours);

    // Both names for one field is a duplicate, as serde reports any.
    let both = r#"{"overcurrent":1,"overcurrent_events":1,"overvoltage":2,"undervoltage":3,"overtemp":4,"driver_fault":5,"emergency_stops":6}"#;
    assert_eq!(
        serde_json::from_str::<FaultCounters>(both)
            .unwrap_err()
            .to_string(),
        "duplicate field `overcurrent` at line 1 column 37"
    );
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
    #![proptest_config(ProptestConfig::with_cases(cases(3000)))]

    #[test]
    fn json_round_trips((_v, msg) in common::versioned_message()) {
        let json = serde_json::to_string(&msg).unwrap();
        let back: Message = serde_json::from_str(&json).unwrap();
        prop_assert_eq!(back, msg);
    }
}
