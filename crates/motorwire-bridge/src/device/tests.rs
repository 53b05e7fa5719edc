//! Unit tests.

use super::*;
use motorwire_compact::VelocityLimit;
use motorwire_irpc::SetTargetPayloadV2;

/// The engine's sources, every file of `engine/` but its tests.
const ENGINE: [&str; 15] = [
    include_str!("../engine/mod.rs"),
    include_str!("../engine/input.rs"),
    include_str!("../engine/admit.rs"),
    include_str!("../engine/complete.rs"),
    include_str!("../engine/feedback.rs"),
    include_str!("../engine/jobs.rs"),
    include_str!("../engine/limits.rs"),
    include_str!("../engine/links.rs"),
    include_str!("../engine/motion.rs"),
    include_str!("../engine/motor_line.rs"),
    include_str!("../engine/phase.rs"),
    include_str!("../engine/queries.rs"),
    include_str!("../engine/stop.rs"),
    include_str!("../engine/timers.rs"),
    include_str!("../engine/watch.rs"),
];

/// `Bridge::poll_timeout` keeps its deadline until an input comes,
/// held against the engine's own source: every input goes through
/// `Bridge::handle`, which clears it first (once, for all of them);
/// every other `&mut self` method the engine's users can call is a
/// way into `handle`, but those that only hand out what is queued
/// (and clear it when they hand something out).
#[test]
fn every_entry_point_that_changes_the_bridge_forgets_its_next_deadline() {
    let engine = ENGINE.concat();
    let engine = engine.as_str();
    let mut entry_points = 0;
    let mut rest = engine;
    while let Some(at) = rest.find("\n    pub") {
        rest = rest.get(at + 1..).unwrap_or("");
        let head = rest.split('{').next().unwrap_or("");
        // `pub(super)`: the engine's own parts, not an entry point.
        if !head.contains("fn ")
            || !head.contains("&mut self")
            || head.trim_start().starts_with("pub(super)")
        {
            continue;
        }
        let name = head
            .split("fn ")
            .nth(1)
            .and_then(|n| n.split(['(', '<']).next())
            .unwrap_or("");
        let body = rest.get(head.len() + 1..).unwrap_or("");
        let own = body.split("\n    }").next().unwrap_or("");
        entry_points += 1;
        match name {
            "poll_output" => assert!(!own.contains("changed()"), "{name}"),
            "poll_transmit" | "poll_link_line" | "poll_serial" => assert!(
                own.contains("self.changed();"),
                "{name} clears the deadline when it hands something out"
            ),
            "handle" => assert!(
                own.trim_start().starts_with("self.changed();"),
                "Bridge::handle takes an input without clearing its next deadline"
            ),
            // A crate-private setting, before the start.
            "anchor_epoch" => assert!(own.trim_start().starts_with("self.changed();")),
            _ => assert!(
                own.trim_start().starts_with("self.handle("),
                "Bridge::{name} changes the bridge other than through Bridge::handle"
            ),
        }
    }
    // Nothing else forgets the deadline: it is done where inputs come.
    assert_eq!(engine.matches("self.changed();").count(), 5);
    assert!(entry_points >= 20, "{entry_points} entry points found");
}

/// The layering this module promises, held against the engine's own
/// source: it names no dialect (no variant of [`Device`], [`Order`]
/// or the bus map's `Target`, no driver of [`Drivers`] by name), and
/// it is one `impl Bridge` in one file.
#[test]
fn the_engine_asks_no_dialect_question() {
    let code: String = ENGINE
        .concat()
        .lines()
        .map(|l| l.split("//").next().unwrap_or(""))
        .collect::<Vec<_>>()
        .join("\n");
    for dialect in ["Irpc", "Compact", "Orion"] {
        for name in [
            format!("Device::{dialect}"),
            format!("Order::{dialect}"),
            format!("Target::{dialect}"),
        ] {
            assert!(!code.contains(&name), "the engine names {name}");
        }
    }
    // The lifecycle it drives is its own ([`Lifecycle`]), said in each
    // dialect's terms by the device layer.
    for payload in [
        "Reset",
        "Configure",
        "Activate",
        "Deactivate",
        "ConfigureTelemetry",
    ] {
        let named = format!("Payload::{payload}");
        assert!(!code.contains(&named), "the engine names {named}");
    }
    for driver in [".irpc", ".compact", ".orion"] {
        let named = format!("drivers{driver}");
        assert!(!code.contains(&named), "the engine reaches {named}");
    }
    // No dialect's crate or type outside its tests: the states devices
    // say, the moves it plans, what a line asks of a device and the
    // arm-wide actions are the device layer's ([`DeviceState`],
    // [`plan::Move`], [`Ask`], `classify::ArmAction`).
    let outside_tests: String = ENGINE
        .iter()
        .map(|f| f.split("#[cfg(test)]").next().unwrap_or(""))
        .collect::<Vec<_>>()
        .concat();
    for name in [
        "motorwire_irpc",
        "motorwire_orion",
        "motorwire_moteus",
        "motorwire_compact",
        "Payload",
        "LifecycleState",
        "WireVersion",
        "CalibrationRequest",
        "ArmCommand",
        "to_irpc",
    ] {
        assert!(!outside_tests.contains(name), "the engine names {name}");
    }
    // One `impl Bridge` a file of the engine, each its concern.
    for file in ENGINE {
        assert_eq!(file.matches(concat!("impl ", "Bridge {")).count(), 1);
    }
    for other in [
        include_str!("../job.rs"),
        include_str!("../joints.rs"),
        include_str!("../arrival.rs"),
        include_str!("mod.rs"),
        include_str!("irpc.rs"),
        include_str!("compact.rs"),
        include_str!("orion.rs"),
    ] {
        assert!(!other.contains(concat!("impl ", "Bridge {")));
    }
}

const HASH: MotorHash = MotorHash(0x1234_5678);

fn compact() -> Device {
    Device::Compact {
        feedback_node: 0x31,
        hash: HASH,
    }
}

/// A stop is each dialect's own: Deactivate for a joint, the
/// emergency-stop flag for a compact device, the stop command for the
/// Orion controller; what the release brings back goes to joints only.
#[test]
fn each_dialect_is_stopped_in_its_own_way() {
    let irpc = Device::Irpc {
        wire: WireVersion::V2_1,
    };
    let stop = [Lifecycle::Deactivate];
    assert_eq!(
        irpc.lifecycle_orders(&stop, 7),
        [Order::Irpc(Payload::Deactivate)]
    );
    // Telemetry where the wire version has it (v2.1 on), nothing on v2.0.
    let telemetry = [Lifecycle::Telemetry { rate_hz: 50 }];
    let [Order::Irpc(Payload::ConfigureTelemetry(t))] = irpc.lifecycle_orders(&telemetry, 7)[..]
    else {
        panic!("one ConfigureTelemetry");
    };
    assert_eq!(
        (t.mode, t.rate_hz),
        (motorwire_irpc::TelemetryMode::Periodic, 50)
    );
    let v20 = Device::Irpc {
        wire: WireVersion::V2_0,
    };
    assert_eq!(v20.lifecycle_orders(&telemetry, 7), []);
    assert_eq!(
        Order::Irpc(Payload::ConfigureTelemetry(t)).lifecycle(),
        Some(telemetry[0])
    );
    let [Order::Compact(c)] = compact().lifecycle_orders(&stop, 7)[..] else {
        panic!("one compact order");
    };
    assert_eq!(c.motor, HASH);
    assert_eq!(c.timestamp_ms, 7);
    assert_eq!(c.control_mode, CompactMode::Disabled);
    assert!(c.flags.contains(Flags::EMERGENCY_STOP));
    assert_eq!(
        Device::Orion(Motor::Turntable)
            .lifecycle_orders(&[Lifecycle::Reset, Lifecycle::Deactivate], 7),
        [Order::Orion(OrionOrder::Command(ArmCommand::Stop))]
    );
    // The release's Activate has nothing to send to either.
    assert_eq!(compact().lifecycle_orders(&[Lifecycle::Activate], 7), []);
    assert_eq!(
        Device::Orion(Motor::GrasperRotation).lifecycle_orders(&[Lifecycle::Activate], 7),
        []
    );
    // The deadman: a held setpoint to 0; a joint holds none.
    assert_eq!(irpc.hold_still(7), None);
    assert_eq!(
        Device::Orion(Motor::Turntable).hold_still(7),
        Some(Order::Orion(OrionOrder::Set(Motor::Turntable, 0.0)))
    );
    let Some(Order::Compact(h)) = compact().hold_still(9) else {
        panic!("a compact hold");
    };
    assert_eq!((h.control_mode, h.setpoint), (CompactMode::Velocity, 0.0));
    assert!(!h.flags.contains(Flags::EMERGENCY_STOP));
    assert!(
        irpc.supports(Capability::Reset) && irpc.speaks(Needs(PayloadKind::ConfigureTelemetry))
    );
    assert!(!compact().supports(Capability::Trajectory));
    assert!(!Device::Orion(Motor::Turntable).supports(Capability::Reset));
    assert_eq!(irpc.who(0x12), "node 0x12");
    assert_eq!(
        Device::Orion(Motor::Turntable).who(orion::ORION_NODE),
        "the Orion arm controller (ID 32)"
    );
}

/// What an order reaches is read in degrees whatever the motor's unit:
/// a compact command in radians at 1 rad, limited to 0.5 rad/s.
#[test]
fn an_orders_reach_is_in_degrees() {
    let c = CompactCommand {
        motor: HASH,
        timestamp_ms: 0,
        control_mode: CompactMode::Position,
        flags: Flags::REQUIRE_ACK,
        setpoint: 1.0,
        velocity_limit: Some(VelocityLimit::from_units_per_s(0.5).unwrap()),
        torque_limit: None,
    };
    let r = Order::Compact(c).reach(AngleUnit::Radians);
    assert!(
        (r.target.unwrap() - 1f64.to_degrees()).abs() < 1e-9,
        "{r:?}"
    );
    assert!(
        (r.speed.unwrap() - 0.5f64.to_degrees()).abs() < 1e-3,
        "{r:?}"
    );
    let set = Order::Orion(OrionOrder::Set(Motor::GrasperHorizontalServo, 30.0));
    assert_eq!(
        set.reach(AngleUnit::Degrees),
        Reach {
            target: Some(30.0),
            speed: None
        }
    );
    assert!(set.is_position_move() && !set.holds_setpoint());
    let spin = Order::Orion(OrionOrder::Set(Motor::Turntable, 200.0));
    assert!(spin.holds_setpoint() && !spin.is_position_move());
    assert_eq!(spin.reach(AngleUnit::Degrees), Reach::default());
}

/// A held setpoint arms the deadman for the motor's command timeout
/// and moves until then; 0 holds the device still, with no deadman; a
/// compact emergency stop cuts the move short.
#[test]
fn a_held_setpoint_arms_the_deadman_and_zero_does_not() {
    let cx = Context {
        at: Duration::from_millis(1000),
        motion: Some((10.0, 0.0, 0.0)),
        unit: AngleUnit::Degrees,
        max_velocity: Some(100.0),
        max_acceleration: Some(1000.0),
        command_timeout: Some(Duration::from_millis(200)),
        planned: None,
    };
    let spin = Order::Orion(OrionOrder::Set(Motor::Turntable, 200.0)).effect(&cx);
    assert_eq!(spin.deadman, Some(Duration::from_millis(1200)));
    assert_eq!(spin.moving, Moving::Until(Duration::from_millis(1200)));
    assert_eq!(spin.target, Some(None));
    let still = Order::Orion(OrionOrder::Set(Motor::Turntable, 0.0)).effect(&cx);
    assert_eq!(still.deadman, None);
    assert_eq!(still.moving, Moving::Until(Duration::from_millis(1000)));
    let Some(Order::Compact(stop)) = compact()
        .lifecycle_orders(&[Lifecycle::Deactivate], 0)
        .first()
        .copied()
    else {
        panic!("a compact stop");
    };
    let e = Order::Compact(stop).effect(&cx);
    assert_eq!(e.moving, Moving::AtMost(Duration::from_millis(1000)));
    assert_eq!(
        (e.deadman, e.target),
        (None, Some(None)),
        "no target any more"
    );
    // A compact move of 90 degrees at the limit's 100 deg/s and 1000
    // deg/s²: 0.9 s + 0.1 s.
    let mv = CompactCommand {
        setpoint: 100.0,
        control_mode: CompactMode::Position,
        flags: Flags::REQUIRE_ACK,
        ..stop
    };
    let e = Order::Compact(mv).effect(&cx);
    assert_eq!(e.target, Some(Some(100.0)));
    assert_eq!(e.moving, Moving::Until(Duration::from_millis(2000)));
}

/// A moteus segment brakes within the segment's deceleration where it
/// is tighter than its acceleration (moteus has one limit for both).
#[test]
fn a_moteus_segment_brakes_within_the_tighter_limit() {
    let moteus = Device::Moteus {
        id: 1,
        bus: 0,
        period_ms: 10,
        brake: false,
    };
    let p = SetTargetPayloadV2::trapezoidal(36.0, 180.0, 720.0);
    let limit = |p: SetTargetPayloadV2| match moteus.segment_order(p.into(), None) {
        Some(Order::Moteus(MoteusCommand::Position(a))) => a.accel_limit,
        other => panic!("{other:?}"),
    };
    assert_eq!(limit(p), Some(2.0));
    assert_eq!(limit(p.with_deceleration(360.0)), Some(1.0));
    assert_eq!(limit(p.with_deceleration(0.0)), Some(2.0));
}
