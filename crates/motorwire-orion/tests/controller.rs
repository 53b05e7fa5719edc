//! The arm controller's state model.
#![allow(clippy::unwrap_used, clippy::panic)]

use motorwire_orion::*;

fn line(arm: &mut ArmController, text: &str) -> Response {
    arm.handle_line(text).unwrap()
}

#[test]
fn partial_updates_are_remembered_and_clamped_values_run() {
    let mut arm = ArmController::new();
    assert!(arm.awaiting_first_command());
    let r = line(
        &mut arm,
        r#"{"ID":32,"MODE":1,"DATA":{"TRM":200,"LAA":1,"UAA":1,"AEM":400}}"#,
    );
    assert!(!arm.awaiting_first_command());
    assert!(r.clamps.is_empty());
    assert_eq!(
        r.output.to_json(FeedbackKeys::Example),
        r#"{"ID":32,"MODE":1,"DATA":{"TRM":[200,35,0],"LAA":[1,50,0],"UAA":[1,50,0],"AEM":[400,65,0],"GVM":[0,0,0],"GRM":[0,0,0],"GHS":[0,0,0]}}"#
    );
    // Only GHS changes (clamped from 200 to 180); the rest is remembered.
    let r = line(&mut arm, r#"{"ID":32,"MODE":1,"DATA":{"GHS":200}}"#);
    assert_eq!(
        r.clamps,
        vec![Clamp {
            motor: Motor::GrasperHorizontalServo,
            requested: 200.0,
            applied: 180.0
        }]
    );
    assert_eq!(
        r.output.to_json(FeedbackKeys::Table),
        r#"{"ID":32,"MODE":1,"DATA":{"TRMF":[200,35,0],"LAAF":[1,50,0],"UAAF":[1,50,0],"AEMF":[400,65,0],"GVMF":[0,0,0],"GRMF":[0,0,0],"GHSF":[180,10,0]}}"#
    );
    assert_eq!(arm.value(Motor::Turntable), 200.0);
}

#[test]
fn commands_stop_fold_unfold_and_refuse_other_numbers() {
    let mut arm = ArmController::new();
    line(
        &mut arm,
        r#"{"ID":32,"MODE":1,"DATA":{"TRM":-100,"UAA":-1,"GHS":45}}"#,
    );
    let stop = line(&mut arm, r#"{"ID":32,"MODE":2,"DATA":1}"#);
    assert_eq!(stop.output, Output::Command { succeeded: true });
    assert_eq!(
        stop.output.to_json(FeedbackKeys::Table),
        r#"{"ID":32,"MODE":2,"DATA":{"CMDF":1}}"#
    );
    // Stop: speeds and actuators to 0, the servo holds.
    assert_eq!(arm.value(Motor::Turntable), 0.0);
    assert_eq!(arm.value(Motor::UpperArmActuator), 0.0);
    assert_eq!(arm.value(Motor::GrasperHorizontalServo), 45.0);
    assert_eq!(arm.posture(), Posture::AsBooted);

    line(&mut arm, r#"{"ID":32,"MODE":2,"DATA":2}"#);
    assert_eq!(arm.posture(), Posture::Folded);
    assert_eq!(arm.value(Motor::GrasperHorizontalServo), 0.0);
    line(&mut arm, r#"{"ID":32,"MODE":2,"DATA":3}"#);
    assert_eq!(arm.posture(), Posture::Unfolded);

    line(&mut arm, r#"{"ID":32,"MODE":1,"DATA":{"GVM":10}}"#);
    let before = arm.clone();
    for n in [0, 4, 99, -1] {
        let r = line(&mut arm, &format!(r#"{{"ID":32,"MODE":2,"DATA":{n}}}"#));
        assert_eq!(
            r.output.to_json(FeedbackKeys::Table),
            r#"{"ID":32,"MODE":2,"DATA":{"CMDF":0}}"#
        );
        assert_eq!(arm, before, "command {n} changed the state");
    }
}

#[test]
fn a_line_that_is_not_an_input_changes_nothing() {
    let mut arm = ArmController::new();
    line(&mut arm, r#"{"ID":32,"MODE":1,"DATA":{"TRM":5}}"#);
    let before = arm.clone();
    for bad in [
        "not json",
        r#"{"ID":32,"MODE":1,"DATA":{"TRM":7,"BAD":1}}"#,
        r#"{"ID":32,"MODE":1,"DATA":{"TRM":7,"TRM":8}}"#,
        r#"{"ID":31,"MODE":2,"DATA":1}"#,
    ] {
        assert!(arm.handle_line(bad).is_err(), "{bad}");
        assert_eq!(arm, before, "{bad}");
    }
    // Errors before the first command leave it awaited.
    let mut fresh = ArmController::new();
    assert!(fresh.handle_line("{}").is_err());
    assert!(fresh.awaiting_first_command());
}
