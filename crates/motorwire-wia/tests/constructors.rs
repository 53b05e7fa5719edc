//! The constructors build exactly the message the minimal JSON of its
//! required members reads as, valid; they check and clamp nothing, so a
//! bad value is the validator's to refuse, with the rule its JSON breaks.
#![allow(clippy::unwrap_used, clippy::indexing_slicing)]

use motorwire_wia::core::ControlMode;
use motorwire_wia::{
    AxisCommand, ControlModeConfig, MotorCommand, MotorFeedback, MotorStatus, MultiAxisCommand,
    PidConfig, PidConfigGains, PositionLimits, Rule, SafetyLimits, Timing, TorqueLimits,
    Trajectory, Validator, VelocityLimits, Waypoint, WiaMessage,
};

/// `built` is what `json` reads as, valid, and serializes back to `json`.
fn same_as_json<T: WiaMessage + PartialEq + std::fmt::Debug>(built: &T, json: &str) {
    let v = Validator::new();
    let parsed: T = v.parse(json).unwrap();
    assert_eq!(*built, parsed, "{json}");
    assert_eq!(v.check(built), [], "{json}");
    assert_eq!(serde_json::to_string(built).unwrap(), json);
}

/// The (pointer, rule) of each violation of `msg`.
fn refused<T: WiaMessage>(msg: &T) -> Vec<(String, Rule)> {
    Validator::new()
        .check(msg)
        .into_iter()
        .map(|v| (v.pointer, v.rule))
        .collect()
}

fn at(pointer: &str, rule: Rule) -> Vec<(String, Rule)> {
    vec![(pointer.to_owned(), rule)]
}

#[test]
fn each_constructor_builds_its_minimal_message() {
    same_as_json(
        &MotorCommand::new("elbow", 1_704_067_200_000.0, ControlMode::Position, 45.0),
        r#"{"motor_id":"elbow","timestamp":1704067200000,"control_mode":"position","setpoint":45.0}"#,
    );
    same_as_json(
        &MultiAxisCommand::new(
            "cmd_1",
            1_704_067_200_000.0,
            vec![AxisCommand::new("elbow", ControlMode::Velocity, 10.0)],
        ),
        r#"{"command_id":"cmd_1","timestamp":1704067200000,"motors":[{"motor_id":"elbow","control_mode":"velocity","setpoint":10.0}]}"#,
    );
    same_as_json(
        &Trajectory::new(
            "t1",
            "elbow",
            vec![Waypoint::new(0.0, 0.0), Waypoint::new(10.0, 1.0)],
            Timing::default(),
        ),
        r#"{"trajectory_id":"t1","motor_id":"elbow","waypoints":[{"position":0.0,"time":0.0},{"position":10.0,"time":1.0}],"timing":{}}"#,
    );
    same_as_json(
        &SafetyLimits::new(
            "elbow",
            PositionLimits::new(0.0, 150.0),
            VelocityLimits::default(),
            TorqueLimits::default(),
        ),
        r#"{"motor_id":"elbow","position_limits":{"min":0.0,"max":150.0},"velocity_limits":{},"torque_limits":{}}"#,
    );
    same_as_json(
        &PidConfig::new(
            "elbow",
            ControlMode::Torque,
            PidConfigGains::new(40.0, 0.0, 1.5),
        ),
        r#"{"motor_id":"elbow","control_mode":"torque","gains":{"kp":40.0,"ki":0.0,"kd":1.5}}"#,
    );
    same_as_json(
        &ControlModeConfig::new(ControlMode::Position),
        r#"{"mode":"position"}"#,
    );
    same_as_json(
        &MotorFeedback::new(
            "elbow",
            1_704_067_200_150.0,
            44.5,
            -2.0,
            0.25,
            MotorStatus::default(),
        ),
        r#"{"motor_id":"elbow","timestamp":1704067200150,"position":44.5,"velocity":-2.0,"torque":0.25,"status":{}}"#,
    );
}

#[test]
fn each_setter_sets_the_member_it_names() {
    same_as_json(
        &MotorCommand::new("elbow", 1.0, ControlMode::Velocity, 20.0)
            .with_velocity_limit(30.0)
            .with_acceleration_limit(100.0)
            .with_torque_limit(5.0)
            .with_priority(80),
        r#"{"motor_id":"elbow","timestamp":1,"control_mode":"velocity","setpoint":20.0,"velocity_limit":30.0,"acceleration_limit":100.0,"torque_limit":5.0,"priority":80}"#,
    );
    same_as_json(
        &Trajectory::new(
            "t1",
            "elbow",
            vec![
                Waypoint::new(0.0, 0.0).with_velocity(0.0),
                Waypoint::new(10.0, 1.0)
                    .with_acceleration(-5.0)
                    .with_torque(1.0),
            ],
            Timing::default(),
        ),
        r#"{"trajectory_id":"t1","motor_id":"elbow","waypoints":[{"position":0.0,"velocity":0.0,"time":0.0},{"position":10.0,"acceleration":-5.0,"time":1.0,"torque":1.0}],"timing":{}}"#,
    );
    same_as_json(
        &SafetyLimits::new(
            "elbow",
            PositionLimits::new(0.0, 150.0)
                .with_soft_min(5.0)
                .with_soft_max(145.0)
                .with_home_position(90.0),
            VelocityLimits::default(),
            TorqueLimits::default(),
        ),
        r#"{"motor_id":"elbow","position_limits":{"min":0.0,"max":150.0,"soft_min":5.0,"soft_max":145.0,"home_position":90.0},"velocity_limits":{},"torque_limits":{}}"#,
    );
}

#[test]
fn constructors_check_nothing_and_the_validator_refuses_with_the_rule() {
    // A NaN setpoint: the command is made; the validator names the rule.
    let cmd = MotorCommand::new("elbow", 1.0, ControlMode::Position, f64::NAN);
    assert!(cmd.setpoint.is_nan());
    assert_eq!(refused(&cmd), at("/setpoint", Rule::NonFinite));
    // An empty motor id breaks the schema's pattern.
    let cmd = MotorCommand::new("", 1.0, ControlMode::Position, 1.0);
    assert_eq!(refused(&cmd), at("/motor_id", Rule::Pattern));
    // Seconds where milliseconds belong.
    let cmd = MotorCommand::new("elbow", 1_704_067_200.0, ControlMode::Position, 1.0);
    assert_eq!(refused(&cmd), at("/timestamp", Rule::TimestampUnit));
    // A limit a setter gives is not clamped either.
    let cmd = MotorCommand::new("elbow", 1.0, ControlMode::Position, 1.0).with_velocity_limit(-1.0);
    assert_eq!(cmd.velocity_limit, Some(-1.0));
    assert_eq!(refused(&cmd), at("/velocity_limit", Rule::Minimum));
    // Impedance control without its parameters.
    let cmd = MotorCommand::new("elbow", 1.0, ControlMode::Impedance, 1.0);
    assert_eq!(refused(&cmd), at("/impedance_params", Rule::ModeParameters));

    let multi = MultiAxisCommand::new("cmd_1", 1.0, Vec::new());
    assert_eq!(refused(&multi), at("/motors", Rule::MinItems));
    let multi = MultiAxisCommand::new(
        "cmd_1",
        1.0,
        vec![AxisCommand::new(
            "elbow",
            ControlMode::Position,
            f64::INFINITY,
        )],
    );
    assert_eq!(refused(&multi), at("/motors/0/setpoint", Rule::NonFinite));

    let t = Trajectory::new(
        "t1",
        "elbow",
        vec![Waypoint::new(0.0, 0.0)],
        Timing::default(),
    );
    assert_eq!(refused(&t), at("/waypoints", Rule::MinItems));
    let t = Trajectory::new(
        "t1",
        "elbow",
        vec![Waypoint::new(0.0, 1.0), Waypoint::new(10.0, 1.0)],
        Timing::default(),
    );
    assert_eq!(
        refused(&t),
        at("/waypoints/1/time", Rule::WaypointTimeOrder)
    );

    let l = SafetyLimits::new(
        "elbow",
        PositionLimits::new(150.0, 0.0),
        VelocityLimits::default(),
        TorqueLimits::default(),
    );
    assert_eq!(
        refused(&l),
        at("/position_limits/min", Rule::PositionLimitsOrder)
    );

    let c = PidConfig::new(
        "elbow",
        ControlMode::Position,
        PidConfigGains::new(0.0, 0.1, 1.0),
    );
    assert_eq!(refused(&c), at("/gains/kp", Rule::KpPositive));
    let c = PidConfig::new(
        "elbow",
        ControlMode::Impedance,
        PidConfigGains::new(1.0, 0.1, 1.0),
    );
    assert_eq!(refused(&c), at("/control_mode", Rule::Enum));

    let c = ControlModeConfig::new(ControlMode::Position).with_motor_id("el bow");
    assert_eq!(refused(&c), at("/motor_id", Rule::Pattern));

    let fb = MotorFeedback::new("elbow", 1.5, 0.0, f64::NAN, 0.0, MotorStatus::default());
    assert_eq!(
        refused(&fb),
        [
            ("/timestamp".to_owned(), Rule::TimestampInteger),
            ("/velocity".to_owned(), Rule::NonFinite),
        ]
    );
}
