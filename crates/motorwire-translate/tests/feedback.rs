//! Device feedback to WIA MotorFeedback.
#![allow(clippy::unwrap_used, clippy::panic, clippy::indexing_slicing)]

use motorwire_irpc::{EncoderTelemetry, LifecycleState, Payload, TelemetryStream};
use motorwire_orion::{Feedback, Motor, MotorFeedback as OrionFeedback};
use motorwire_translate::*;

fn demo() -> BusMap {
    BusMap::from_toml(include_str!("../../../fixtures/maps/demo-arm.toml")).unwrap()
}

#[test]
fn irpc_encoder_and_status_accumulate_into_one_feedback() {
    let map = demo();
    let enc = Payload::Encoder(EncoderTelemetry {
        position: 44.95,
        velocity: 12.25,
    });
    let first = feedback_from_irpc(&map, 0x12, &enc, 1000.0, None).unwrap();
    let fb = &first.value;
    assert_eq!(fb.motor_id, "elbow");
    assert_eq!(
        (fb.timestamp, fb.position, fb.velocity, fb.torque),
        (1000.0, f64::from(44.95f32), 12.25, 0.0)
    );
    let text: Vec<String> = first
        .report
        .losses
        .iter()
        .map(ToString::to_string)
        .collect();
    assert_eq!(
        text,
        [
            "position: filled: not reported yet; 0",
            "velocity: filled: not reported yet; 0",
            "torque: filled: not reported yet; 0"
        ]
    );
    let status = Payload::JointStatus {
        state: LifecycleState::Active,
        error_code: 0,
    };
    let second = feedback_from_irpc(&map, 0x12, &status, 1010.0, Some(fb)).unwrap();
    assert_eq!(second.value.position, f64::from(44.95f32));
    assert_eq!(second.value.status.enabled, Some(true));
    assert_eq!(second.value.status.fault, Some(false));
    assert!(second.report.is_exact());
    let fault = Payload::JointStatus {
        state: LifecycleState::Inactive,
        error_code: 7,
    };
    let third = feedback_from_irpc(&map, 0x12, &fault, 1020.0, Some(&second.value)).unwrap();
    assert_eq!(
        (third.value.status.enabled, third.value.status.fault),
        (Some(false), Some(true))
    );
    assert_eq!(
        third.report.losses[0].to_string(),
        "error_code: converted: 7 becomes the fault flag"
    );
}

#[test]
fn telemetry_fills_what_wia_has_and_reports_the_rest() {
    let map = BusMap::from_toml(
        "[motors.j]\ndialect = \"irpc\"\nnode = 9\nwire = \"v2.1\"\nunit = \"rad\"",
    )
    .unwrap();
    let t = TelemetryStream {
        timestamp_us: 5,
        position: 180.0,
        velocity: 90.0,
        acceleration: -45.0,
        current_d: 0.5,
        current_q: 2.0,
        voltage_d: 3.0,
        voltage_q: 4.0,
        torque_estimate: 1.25,
        power: 10.0,
        load_percent: 40.0,
        foc_loop_time_us: 50,
        temperature_c: 41.5,
        warnings: 0,
        trajectory_active: true,
    };
    let out = feedback_from_irpc(&map, 9, &Payload::TelemetryStream(t), 7.0, None).unwrap();
    let fb = out.value;
    assert_eq!(fb.position, std::f64::consts::PI);
    assert_eq!(fb.velocity, std::f64::consts::FRAC_PI_2);
    assert_eq!(fb.acceleration, Some(-std::f64::consts::FRAC_PI_4));
    assert_eq!(
        (fb.torque, fb.current, fb.voltage, fb.power),
        (1.25, Some(2.0), Some(5.0), Some(10.0))
    );
    assert_eq!(
        (fb.temperature, fb.control_effort),
        (Some(41.5), Some(40.0))
    );
    assert_eq!(
        (fb.status.in_motion, fb.status.warning),
        (Some(true), Some(false))
    );
    assert!(
        out.report
            .losses
            .iter()
            .any(|l| l.to_string() == "position: converted: degrees (iRPC's unit) to radians")
    );
    // A voltage that is no round number is the joint's f32 all the same,
    // which prints as its shortest decimal (not as an f64's noise).
    let t = TelemetryStream {
        voltage_d: 0.1,
        voltage_q: 0.05,
        ..t
    };
    let fb = feedback_from_irpc(&map, 9, &Payload::TelemetryStream(t), 7.0, None)
        .unwrap()
        .value;
    let v = fb.voltage.unwrap();
    #[allow(clippy::cast_possible_truncation)]
    let as_f32 = v as f32;
    assert_eq!(f64::from(as_f32), v, "{v} is no f32");
    assert_eq!(as_f32, 0.1f32.hypot(0.05));
    assert_eq!(as_f32.to_string(), "0.1118034");
    assert!(out.report.losses.iter().any(
        |l| l.to_string() == "foc_loop_time_us: dropped: WIA MotorFeedback has no place for it"
    ));
}

#[test]
fn irpc_feedback_errors_are_typed() {
    let map = demo();
    let enc = Payload::Encoder(EncoderTelemetry {
        position: 1.0,
        velocity: 0.0,
    });
    assert_eq!(
        feedback_from_irpc(&map, 0x44, &enc, 0.0, None)
            .unwrap_err()
            .to_string(),
        "no motor of the bus map is iRPC node 0x44"
    );
    assert_eq!(
        feedback_from_irpc(&map, 0x10, &Payload::Activate, 0.0, None)
            .unwrap_err()
            .to_string(),
        "Activate is not feedback (Encoder, JointStatus or TelemetryStream)"
    );
    let nan = Payload::Encoder(EncoderTelemetry {
        position: f32::NAN,
        velocity: 0.0,
    });
    assert_eq!(
        feedback_from_irpc(&map, 0x10, &nan, 0.0, None).unwrap_err(),
        FeedbackError::NonFinite {
            motor: "shoulder_pitch".into(),
            field: "position"
        }
    );
}

#[test]
fn orion_feedback_becomes_one_wia_feedback_per_mapped_motor() {
    let map = demo();
    let mut fb = Feedback::new();
    fb.set(
        Motor::Turntable,
        OrionFeedback {
            value: 200.0,
            current: 35.0,
            error: 0,
        },
    );
    fb.set(
        Motor::GrasperHorizontalServo,
        OrionFeedback {
            value: -30.0,
            current: 10.0,
            error: 1,
        },
    );
    let out = feedback_from_orion(&map, &fb, 99.0).unwrap();
    assert_eq!(out.len(), 2);
    let turntable = &out[0].value;
    assert_eq!(
        (
            turntable.motor_id.as_str(),
            turntable.velocity,
            turntable.position
        ),
        ("turntable", 200.0, 0.0)
    );
    assert_eq!(
        (turntable.current, turntable.status.fault),
        (Some(35.0), Some(false))
    );
    let servo = &out[1].value;
    assert_eq!(
        (servo.motor_id.as_str(), servo.position, servo.status.fault),
        ("grasper_horizontal_servo", -30.0, Some(true))
    );
    let text: Vec<String> = out[0]
        .report
        .losses
        .iter()
        .map(ToString::to_string)
        .collect();
    assert_eq!(
        text,
        [
            "torque: filled: Orion reports no torque; 0",
            "position: filled: Orion reports a speed, not a position; 0",
            "current: converted: passed on as given (the Orion document gives no unit)"
        ]
    );
    // A map without the turntable skips it and says so.
    let partial = BusMap::from_toml("[motors.servo]\ndialect = \"orion\"\nkey = \"GHS\"").unwrap();
    let out = feedback_from_orion(&partial, &fb, 99.0).unwrap();
    assert_eq!(out.len(), 1);
    assert_eq!(
        out[0].report.losses.last().unwrap().to_string(),
        "TRM: dropped: Orion motors the bus map does not have"
    );
}
