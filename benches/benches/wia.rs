//! WIA MotorCommand: motorwire's parse + full validation against serde_json's
//! typed parse alone and against jsonschema, measured in the same run.
//!
//! `cargo bench -p motorwire-benches --bench wia`
#![allow(
    missing_docs,
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing
)]

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use motorwire_wia::{MessageKind, MotorCommand, Validator, WiaMessage, schema_validator};

/// The WIA document's MotorCommand: the shoulder_pitch entry of its §3.2
/// example, with the command's timestamp.
const MOTOR_COMMAND: &str = include_str!("../../fixtures/wia/valid/motor-command.json");

/// A plain serde struct with the MotorCommand schema's members: no unknown
/// members kept, `null` accepted for optionals, no checks. The baseline a
/// hand-written parser would be.
#[derive(serde::Deserialize)]
#[allow(dead_code)]
struct PlainMotorCommand {
    motor_id: String,
    timestamp: f64,
    control_mode: String,
    setpoint: f64,
    velocity_limit: Option<f64>,
    acceleration_limit: Option<f64>,
    torque_limit: Option<f64>,
    pid_gains: Option<PlainGains>,
    impedance_params: Option<serde_json::Value>,
    filter_config: Option<serde_json::Value>,
    safety_limits: Option<serde_json::Value>,
    priority: Option<i64>,
    metadata: Option<serde_json::Map<String, serde_json::Value>>,
}

#[derive(serde::Deserialize)]
#[allow(dead_code)]
struct PlainGains {
    kp: Option<f64>,
    ki: Option<f64>,
    kd: Option<f64>,
    ki_limit: Option<f64>,
    feedforward: Option<f64>,
}

fn motor_command(c: &mut Criterion) {
    let validator = Validator::new();
    let value: serde_json::Value = serde_json::from_str(MOTOR_COMMAND).unwrap();
    let schema = schema_validator(MessageKind::MotorCommand).unwrap();
    // Sanity: all three agree that the example is valid.
    assert!(validator.parse::<MotorCommand>(MOTOR_COMMAND).is_ok());
    assert!(schema.is_valid(&value));

    let mut g = c.benchmark_group("wia_motor_command");
    g.bench_function("a_serde_json_typed_parse", |b| {
        b.iter(|| serde_json::from_str::<MotorCommand>(black_box(MOTOR_COMMAND)).unwrap())
    });
    g.bench_function("a_plain_serde_struct_parse", |b| {
        b.iter(|| serde_json::from_str::<PlainMotorCommand>(black_box(MOTOR_COMMAND)).unwrap())
    });
    g.bench_function("b_motorwire_parse_and_validate", |b| {
        b.iter(|| {
            validator
                .parse::<MotorCommand>(black_box(MOTOR_COMMAND))
                .unwrap()
        })
    });
    let parsed: MotorCommand = serde_json::from_str(MOTOR_COMMAND).unwrap();
    g.bench_function("b_checks_alone_on_typed_value", |b| {
        b.iter(|| black_box(&parsed).violations(None))
    });
    g.bench_function("c_jsonschema_iter_errors_on_value", |b| {
        b.iter(|| schema.iter_errors(black_box(&value)).count())
    });
    g.bench_function("c_jsonschema_is_valid_on_value", |b| {
        b.iter(|| schema.is_valid(black_box(&value)))
    });
    // What a jsonschema user does with a message that arrives as text.
    g.bench_function("d_jsonschema_from_text", |b| {
        b.iter(|| {
            let v: serde_json::Value = serde_json::from_str(black_box(MOTOR_COMMAND)).unwrap();
            schema.iter_errors(&v).count()
        })
    });
    g.finish();
}

/// `validate --kind auto` against an explicit kind: inferring the kind
/// used to parse each document a second time (about 40 % more); it is now
/// told from a scan of the member names. The old way, `infer` then
/// `validate`, is measured beside it as the baseline.
fn auto_kind(c: &mut Criterion) {
    let validator = Validator::new();
    let explicit = validator.validate(MessageKind::MotorCommand, MOTOR_COMMAND);
    assert!(explicit.is_valid());
    assert_eq!(validator.validate_auto(MOTOR_COMMAND), explicit);

    let mut g = c.benchmark_group("wia_validate_kind");
    g.bench_function("explicit_kind", |b| {
        b.iter(|| validator.validate(MessageKind::MotorCommand, black_box(MOTOR_COMMAND)))
    });
    g.bench_function("auto_kind", |b| {
        b.iter(|| validator.validate_auto(black_box(MOTOR_COMMAND)))
    });
    g.bench_function("infer_then_validate", |b| {
        b.iter(|| {
            let doc = black_box(MOTOR_COMMAND);
            let kind = MessageKind::infer(doc).unwrap().unwrap();
            validator.validate(kind, doc)
        })
    });
    g.finish();
}

criterion_group!(benches, motor_command, auto_kind);
criterion_main!(benches);
