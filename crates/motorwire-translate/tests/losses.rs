//! The loss report names where each value really came from: a
//! deceleration taken from an acceleration limit says whose. Self-contained
//! (an inline map), so it ships with the package.
#![allow(clippy::unwrap_used, clippy::panic, clippy::indexing_slicing)]

use motorwire_irpc::Payload;
use motorwire_translate::{BusMap, to_irpc};
use motorwire_wia::MotorCommand;

const MAP: &str = r#"
[motors.pitch]
dialect = "irpc"
node = 0x10
limits = { min_position = -90, max_position = 90, max_velocity = 120, max_acceleration = 500, max_jerk = 2000 }

[motors.elbow]
dialect = "irpc"
node = 0x12
limits = { min_position = 0, max_position = 150, max_velocity = 120, max_acceleration = 500, max_deceleration = 400, max_jerk = 2000 }
"#;

/// The SetTargetV2's max_deceleration and the report's deceleration line.
fn deceleration(motor: &str, acceleration_limit: Option<f64>) -> (f32, String) {
    let map = BusMap::from_toml(MAP).unwrap();
    let accel =
        acceleration_limit.map_or(String::new(), |a| format!(r#","acceleration_limit":{a}"#));
    let cmd: MotorCommand = serde_json::from_str(&format!(
        r#"{{"motor_id":"{motor}","timestamp":0,"control_mode":"position","setpoint":10,"velocity_limit":60{accel}}}"#
    ))
    .unwrap();
    let t = to_irpc(&map, &cmd).unwrap();
    let Payload::SetTargetV2(p) = t.value.payloads[0] else {
        panic!("{:?}", t.value.payloads);
    };
    let line = t
        .report
        .losses
        .iter()
        .map(ToString::to_string)
        .find(|l| l.starts_with("max_deceleration"))
        .unwrap_or_default();
    (p.max_deceleration, line)
}

#[test]
fn no_map_deceleration_takes_the_maps_acceleration_and_says_so() {
    assert_eq!(
        deceleration("pitch", None),
        (
            500.0,
            "max_deceleration: defaulted: 500, the max_acceleration from the bus map (the bus map gives no max_deceleration)".to_owned()
        )
    );
}

#[test]
fn no_map_deceleration_takes_the_commands_acceleration_and_says_so() {
    assert_eq!(
        deceleration("pitch", Some(300.0)),
        (
            300.0,
            "max_deceleration: defaulted: 300, the command's acceleration_limit (the bus map gives no max_deceleration)".to_owned()
        )
    );
}

#[test]
fn a_commands_acceleration_below_the_maps_deceleration_bounds_it_and_says_so() {
    assert_eq!(
        deceleration("elbow", Some(300.0)),
        (
            300.0,
            "max_deceleration: defaulted: 300, the command's acceleration_limit (below max_deceleration 400 from the bus map)".to_owned()
        )
    );
}

#[test]
fn the_maps_deceleration_when_it_is_the_tighter() {
    assert_eq!(
        deceleration("elbow", Some(450.0)),
        (
            400.0,
            "max_deceleration: defaulted: 400 from the bus map".to_owned()
        )
    );
    assert_eq!(
        deceleration("elbow", None),
        (
            400.0,
            "max_deceleration: defaulted: 400 from the bus map".to_owned()
        )
    );
}
