//! Values built in code (not parsed) are judged by the same rules, and what
//! JSON cannot carry (NaN, infinity) is refused rather than written as null.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing
)]

use motorwire_wia::{
    Error, MotorCommand, MotorFeedback, PidGains, Rule, Trajectory, Validator, WiaMessage,
};

const COMMAND: &str = include_str!("../../../fixtures/wia/valid/motor-command-full.json");
const TRAJECTORY: &str = include_str!("../../../fixtures/wia/valid/doc-5.2-trajectory.json");
const FEEDBACK: &str = include_str!("../../../fixtures/wia/valid/doc-4.2-motor-feedback.json");

fn found(v: &[motorwire_wia::Violation]) -> Vec<(Rule, &str)> {
    v.iter().map(|x| (x.rule, x.pointer.as_str())).collect()
}

#[test]
fn non_finite_numbers_are_violations_wherever_they_are() {
    let v = Validator::new();
    let mut cmd: MotorCommand = v.parse(COMMAND).unwrap();
    cmd.setpoint = f64::INFINITY;
    cmd.pid_gains = Some(PidGains {
        kp: Some(f64::NAN),
        ..cmd.pid_gains.clone().unwrap()
    });
    cmd.safety_limits.as_mut().unwrap().max_torque = Some(f64::NEG_INFINITY);
    let all = cmd.violations(None);
    let mut got = found(&all);
    got.sort();
    assert_eq!(
        got,
        [
            (Rule::NonFinite, "/pid_gains/kp"),
            (Rule::NonFinite, "/safety_limits/max_torque"),
            (Rule::NonFinite, "/setpoint"),
        ]
    );

    let mut t: Trajectory = v.parse(TRAJECTORY).unwrap();
    t.waypoints[2].time = f64::NAN;
    assert_eq!(
        found(&t.violations(None)),
        [(Rule::NonFinite, "/waypoints/2/time")]
    );

    let mut f: MotorFeedback = v.parse(FEEDBACK).unwrap();
    f.timestamp = f64::NAN;
    f.health.as_mut().unwrap().estimated_lifetime = Some(f64::INFINITY);
    assert_eq!(
        found(&f.violations(None)),
        [
            (Rule::NonFinite, "/timestamp"),
            (Rule::NonFinite, "/health/estimated_lifetime")
        ]
    );
}

#[test]
fn to_json_refuses_what_json_would_silently_turn_into_null() {
    let v = Validator::new();
    let mut cmd: MotorCommand = v.parse(COMMAND).unwrap();
    cmd.setpoint = f64::NAN;
    let err = v.to_json(&cmd).unwrap_err();
    assert!(matches!(err, Error::Invalid(_)));
    assert_eq!(found(err.violations()), [(Rule::NonFinite, "/setpoint")]);
    assert_eq!(
        err.to_string(),
        "invalid motor-command: 1 violation(s)\n  /setpoint: NaN is not a finite number (non-finite)"
    );
}

#[test]
fn to_json_writes_back_exactly_what_was_given() {
    let v = Validator::new();
    let cmd: MotorCommand = v.parse(COMMAND).unwrap();
    let again: MotorCommand = v.parse(&v.to_json(&cmd).unwrap()).unwrap();
    assert_eq!(cmd, again);
    let given: serde_json::Value = serde_json::from_str(COMMAND).unwrap();
    let written: serde_json::Value = serde_json::from_str(&v.to_json(&cmd).unwrap()).unwrap();
    assert_eq!(written["metadata"], given["metadata"]);
    assert_eq!(written["timestamp"], serde_json::json!(1704067200000u64));
}

#[test]
fn unknown_members_are_kept_not_dropped() {
    // Taken by the lenient validator only (the default refuses them).
    let v = Validator::lenient();
    let json = r#"{"motor_id":"m","timestamp":1,"control_mode":"torque","setpoint":1.5,
                   "vendor":{"x":[1,2]},"pid_gains":{"kp":1,"ki":0,"kd":0,"aw":"clamp"}}"#;
    assert!(Validator::new().parse::<MotorCommand>(json).is_err());
    let cmd: MotorCommand = v.parse(json).unwrap();
    assert_eq!(cmd.extra["vendor"], serde_json::json!({"x": [1, 2]}));
    assert_eq!(cmd.pid_gains.as_ref().unwrap().extra["aw"], "clamp");
    let out = v.to_json(&cmd).unwrap();
    assert!(
        out.contains(r#""vendor":{"x":[1,2]}"#) && out.contains(r#""aw":"clamp""#),
        "{out}"
    );
}

#[test]
fn repeated_keys_are_refused_as_unrepresentable() {
    let v = Validator::new();
    let json =
        r#"{"motor_id":"m","timestamp":1,"control_mode":"torque","setpoint":1,"setpoint":2}"#;
    let err = v.parse::<MotorCommand>(json).unwrap_err();
    assert_eq!(found(err.violations()), [(Rule::Unrepresentable, "")]);
    assert!(
        err.violations()[0]
            .message
            .contains("duplicate field `setpoint`"),
        "{err}"
    );
}

#[test]
fn stale_is_measured_against_the_callers_clock_and_the_future_is_allowed() {
    let json = r#"{"motor_id":"m","timestamp":1000000,"control_mode":"disabled","setpoint":0}"#;
    let at = |now: f64| {
        Validator::new()
            .now_ms(now)
            .validate(motorwire_wia::MessageKind::MotorCommand, json)
    };
    assert!(
        at(1_300_000.0).is_valid(),
        "exactly 5 minutes old is tolerated"
    );
    assert_eq!(
        found(&at(1_300_001.0).violations),
        [(Rule::TimestampStale, "/timestamp")]
    );
    assert!(at(0.0).is_valid(), "a future timestamp is allowed");
    assert!(
        Validator::new()
            .validate(motorwire_wia::MessageKind::MotorCommand, json)
            .is_valid()
    );
}

#[test]
fn parse_any_infers_and_validates() {
    let v = Validator::new();
    let msg = v.parse_any(TRAJECTORY).unwrap();
    assert_eq!(msg.kind(), motorwire_wia::MessageKind::Trajectory);
    let err = v.parse_any(r#"{"hello": 1}"#).unwrap_err();
    assert_eq!(found(err.violations()), [(Rule::UnknownKind, "")]);
}
