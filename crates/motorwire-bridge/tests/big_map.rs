//! A bus map as large as the bridge serves ([`Bridge::MAX_DEVICES`]) is
//! ready within a bounded simulated time and a bounded number of frames;
//! one larger is refused at once, naming its size and the limit (a map of
//! 500 joints once neither started nor was refused).
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing
)]

use std::fmt::Write as _;
use std::time::Duration;

use motorwire_bridge::sim::SimulatedArm;
use motorwire_bridge::{Bridge, BridgeConfig, BridgeError, Event, Output};
use motorwire_can::SimConfig;
use motorwire_translate::BusMap;

/// A map of `irpc` iRPC joints (nodes from 0x10 on) and `compact` compact
/// devices (CAN ids from 0x300 on).
fn map(irpc: usize, compact: usize) -> BusMap {
    let mut text = String::new();
    for i in 0..irpc {
        let _ = writeln!(
            text,
            "[motors.j{i}]\ndialect = \"irpc\"\nnode = {}\n\
             limits = {{ min_position = -90, max_position = 90, max_velocity = 120 }}",
            0x10 + i
        );
    }
    for i in 0..compact {
        let _ = writeln!(
            text,
            "[motors.c{i}]\ndialect = \"compact\"\nnode = {}\n\
             limits = {{ min_position = 0, max_position = 90, max_velocity = 60 }}",
            0x300 + i
        );
    }
    BusMap::from_toml(&text).unwrap()
}

fn config() -> BridgeConfig {
    BridgeConfig {
        feedback_period: None,
        ..BridgeConfig::default()
    }
}

#[test]
fn a_map_at_the_limit_is_ready_in_bounded_simulated_time_and_frames() {
    let n = Bridge::MAX_DEVICES;
    let bridge = Bridge::new(map(n, 0), config()).unwrap();
    let mut arm = SimulatedArm::new(bridge, SimConfig::default()).unwrap();
    arm.keep_sent();
    // Each joint is configured and activated (one request each, answered
    // at once) and then read: its first encoder report, 10 ms later.
    let ready = arm
        .run_while(Duration::from_millis(100), |a| a.bridge().is_ready())
        .unwrap();
    assert!(ready, "not ready by {:?}", arm.now());
    assert!(
        arm.now() <= Duration::from_millis(20),
        "ready at {:?}",
        arm.now()
    );
    // Configure and Activate to each joint, nothing sent twice.
    let sent = arm.sent().len();
    assert_eq!(sent, 2 * n, "{sent} frames for {n} joints");
    let outputs = arm.take_outputs();
    let offline = outputs
        .iter()
        .filter(|o| matches!(o, Output::Event(Event::Offline { .. })))
        .count();
    assert_eq!(offline, 0, "a joint went offline during startup");
    let state = outputs
        .iter()
        .find_map(|o| match o {
            Output::Event(Event::Ready { state, .. }) => Some(state),
            _ => None,
        })
        .expect("a ready event");
    assert_eq!(state.motors.len(), n);
    for m in &state.motors {
        assert!(m.online && m.active, "{m:?}");
        assert_eq!(m.position, Some(0.0), "{m:?}");
    }
}

#[test]
fn a_map_beyond_the_limit_is_refused_at_once_naming_its_size_and_the_limit() {
    let limit = Bridge::MAX_DEVICES;
    let over = map(limit + 1, 0);
    assert!(matches!(
        Bridge::check_map(&over),
        Err(BridgeError::TooManyDevices { count, limit: l }) if count == limit + 1 && l == limit
    ));
    let err = Bridge::new(over, config()).unwrap_err();
    let BridgeError::TooManyDevices { count, limit: l } = err else {
        panic!("{err:?}");
    };
    assert_eq!((count, l), (limit + 1, limit));
    let text = err.to_string();
    assert!(
        text.contains(&(limit + 1).to_string()) && text.contains(&limit.to_string()),
        "{text}"
    );
    // Every device counts, whatever its dialect: a compact device takes
    // a joint's place on the bus.
    let mixed = map(limit - 1, 2);
    assert!(matches!(
        Bridge::new(mixed, config()),
        Err(BridgeError::TooManyDevices { count, .. }) if count == limit + 1
    ));
    assert!(Bridge::check_map(&map(limit - 1, 1)).is_ok());
}
