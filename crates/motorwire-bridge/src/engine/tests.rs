//! The engine's own unit tests.

#![allow(clippy::unwrap_used)]
use super::*;
use motorwire_irpc::Payload;

/// A bridge on `map` (a bus map's TOML), started at time zero without
/// activating its joints: running at once.
fn running(map: &str) -> Bridge {
    let config = BridgeConfig {
        activate_on_start: false,
        ..BridgeConfig::default()
    };
    let mut b = Bridge::new(BusMap::from_toml(map).unwrap(), config).unwrap();
    b.start(Duration::ZERO);
    b
}

/// After handle_timeout at the time poll_timeout gave, no timer is
/// due at that time again: a runner waiting for poll_timeout never
/// spins. Here at the end of input, with a request waiting for its
/// Ack and nothing moving.
#[test]
fn no_timer_is_due_again_once_handled() {
    let mut b = running(
        "[motors.elbow]\ndialect = \"irpc\"\nnode = 0x12\n\
         limits = { max_velocity = 120, max_acceleration = 500 }",
    );
    let ms = Duration::from_millis;
    b.handle_line(
        ms(1),
        Origin(0),
        r#"{"motor_id":"elbow","timestamp":0,"control_mode":"position","setpoint":10}"#,
    );
    while b.poll_transmit().is_some() {}
    b.flushed(ms(1));
    b.finish(ms(2));
    let mut now = ms(2);
    for _ in 0..500 {
        let Some(t) = b.poll_timeout() else { break };
        now = now.max(t);
        b.handle_timeout(now);
        while b.poll_transmit().is_some() {}
        b.flushed(now);
        let due: Vec<Timer> = Timer::ALL
            .into_iter()
            .filter(|t| b.deadline(*t).is_some_and(|d| d <= now))
            .collect();
        assert_eq!(due, [], "at {now:?}");
    }
    // The request timed out (4 sendings, 100 ms each), its line was
    // answered, and the drain ended then, not at its 30 s deadline.
    assert!(b.is_finished(), "{now:?}");
    assert!(now < ms(1000), "{now:?}");
    let r = std::iter::from_fn(|| b.poll_output())
        .find_map(|o| o.result().cloned())
        .unwrap();
    assert_eq!(r.error.unwrap().kind, ErrorKind::OutcomeUnknown);
}

/// A joint's frame to the bridge, in v2.2.
fn from_joint(node: u16, msg_id: u32, payload: Payload) -> Frame {
    crate::device::irpc::joint_frame(node, msg_id, payload, motorwire_irpc::WireVersion::V2_2)
}

/// A stop line that comes while a stop the bridge made itself (a
/// joint's own emergency stop) is under way rides on it and is
/// answered when that stop ends: every line gets exactly one result,
/// whoever started the stop. (Before, such a rider was never answered.)
#[test]
fn a_stop_line_riding_on_a_stop_the_bridge_made_is_answered() {
    use motorwire_irpc::{EmergencyReason, EmergencyStop, Message, WireVersion};
    let mut b = running(
        "[motors.elbow]\ndialect = \"irpc\"\nnode = 0x12\nwire = \"v2.2\"\n\
         limits = { max_velocity = 120, max_acceleration = 500 }",
    );
    let ms = Duration::from_millis;
    let stop = EmergencyStop {
        reason: EmergencyReason::Overtemperature,
        vbus_mv: 24_000,
        current_ma: 0,
        temp_c: 90.0,
        timestamp_ms: 1,
    };
    b.handle_frame(ms(1), &from_joint(0x12, 9, Payload::EmergencyStop(stop)));
    assert!(b.is_latched());
    let deactivate =
        Message::decode_frame(WireVersion::V2_2, b.poll_transmit().unwrap().data()).unwrap();
    assert_eq!(deactivate.payload, Payload::Deactivate);
    b.flushed(ms(1));
    // A client's stop while the joint's is under way: it rides on it.
    b.handle_line(ms(2), Origin(7), r#"{"emergency_stop":true}"#);
    assert_eq!(b.stats().stops_coalesced, 1);
    assert!(b.poll_transmit().is_none(), "no second Deactivate");
    let id = deactivate.header.msg_id;
    b.handle_frame(ms(3), &from_joint(0x12, id, Payload::Ack(id)));
    let results: Vec<LineResult> = std::iter::from_fn(|| b.poll_output())
        .filter_map(|o| o.result().cloned())
        .collect();
    assert_eq!(results.len(), 1, "{results:?}");
    assert_eq!(
        (results[0].line, results[0].ok, results[0].emergency_stop),
        (1, true, true)
    );
    assert_eq!(results[0].acked.as_deref(), Some(&["elbow".to_owned()][..]));
}

/// The phase changes are a closed table: each one the engine makes, and
/// no other.
#[test]
fn the_phase_changes_are_the_tables_and_no_other() {
    let starting = || {
        let mut s = Starting::default();
        s.drain_after = Some(Duration::from_secs(1));
        Phase::Starting(s)
    };
    let draining = Phase::Draining {
        deadline: Duration::from_secs(1),
        recheck: false,
    };
    let all = [
        starting(),
        Phase::Running,
        draining,
        Phase::Stopping,
        Phase::Finished,
    ];
    let allowed: Vec<(&str, &str)> = all
        .iter()
        .flat_map(|f| all.iter().map(move |t| (f, t)))
        .filter(|(f, t)| f.allows(t))
        .map(|(f, t)| (f.name(), t.name()))
        .collect();
    assert_eq!(
        allowed,
        [
            ("starting", "running"),
            ("starting", "stopping"),
            ("running", "draining"),
            ("running", "stopping"),
            ("draining", "stopping"),
            ("stopping", "finished"),
        ]
    );
}

/// A change the table has not is never ignored: the bridge says so and
/// stops every joint (when in doubt, stop).
#[test]
fn an_illegal_phase_change_stops_the_bridge_and_says_why() {
    let mut b = running("[motors.elbow]\ndialect = \"irpc\"\nnode = 0x12\n");
    assert_eq!(b.phase, Phase::Running);
    while b.poll_output().is_some() {}
    b.enter(Phase::Finished);
    let said: Vec<String> = std::iter::from_fn(|| b.poll_output())
        .map(|o| o.to_json())
        .collect();
    assert_eq!(
        said.first().map(String::as_str),
        Some(
            r#"{"event":"stopping","reason":"internal error: the bridge went from running to finished, which it never does; it stops every joint"}"#
        ),
        "{said:?}"
    );
    assert_eq!(b.phase, Phase::Stopping);
    // Its Deactivate is on its way.
    assert!(b.poll_transmit().is_some());
}

/// Stopping before ever running leaves no line unanswered: each line
/// waiting for the start is refused `shutting_down`, and each client
/// waiting for its greeting is told the bridge stops.
#[test]
fn a_stop_while_starting_answers_every_waiting_line() {
    let map = BusMap::from_toml("[motors.elbow]\ndialect = \"irpc\"\nnode = 0x12\n").unwrap();
    let mut b = Bridge::new(map, BridgeConfig::default()).unwrap();
    b.start(Duration::ZERO);
    let command = r#"{"motor_id":"elbow","timestamp":0,"control_mode":"position","setpoint":10}"#;
    b.greet(Duration::ZERO, Origin(2));
    b.handle_line(Duration::ZERO, Origin(1), command);
    b.handle_line(Duration::ZERO, Origin(2), command);
    assert_eq!(b.pending_lines(), 2);
    while b.poll_output().is_some() {}
    // A bug's change (starting to finished) stops the bridge from starting.
    b.enter(Phase::Finished);
    assert_eq!(b.phase, Phase::Stopping);
    assert_eq!(b.pending_lines(), 0);
    let said: Vec<(Option<u64>, String)> = std::iter::from_fn(|| b.poll_output())
        .map(|o| {
            let to = match &o {
                Output::Result { origin, .. } | Output::ToOne { origin, .. } => Some(origin.0),
                _ => None,
            };
            (to, o.to_json())
        })
        .collect();
    let refused = r#"{"ok":false,"line":1,"error":{"kind":"shutting_down","rule":"shutting_down","message":"the bridge is shutting down"}}"#;
    let stopping = r#"{"event":"stopping","reason":"the bridge is stopping the joints"}"#;
    assert_eq!(
        said[1..],
        [
            (Some(2), stopping.to_owned()),
            (Some(1), refused.to_owned()),
            (Some(2), refused.to_owned()),
        ],
        "{said:?}"
    );
}

/// The timeout takes every timer in its turn, each once: [`Timer::FIRING`]
/// and [`Timer::ALL`] name every kind (the match below, without a
/// wildcard, names each), and nothing twice.
#[test]
fn firing_names_every_timer_once() {
    let kind = |t: Timer| match t {
        Timer::Requests => 0,
        Timer::Commands => 1,
        Timer::Link => 2,
        Timer::Feedback => 3,
        Timer::Liveness => 4,
        Timer::Heartbeat => 5,
        Timer::Drain => 6,
        Timer::Arrival => 7,
        Timer::Sequence => 8,
        Timer::Deadman => 9,
        Timer::LimitBrake => 10,
        Timer::Segment => 11,
        Timer::Answer => 12,
        Timer::Settle => 13,
    };
    let every: Vec<usize> = (0..14).collect();
    for table in [Timer::FIRING, Timer::ALL] {
        let mut kinds: Vec<usize> = table.into_iter().map(kind).collect();
        kinds.sort_unstable();
        assert_eq!(kinds, every);
    }
    // The order the steps ran in before the table: kept.
    assert_eq!(
        Timer::FIRING,
        [
            Timer::Requests,
            Timer::Settle,
            Timer::Commands,
            Timer::LimitBrake,
            Timer::Deadman,
            Timer::Link,
            Timer::Answer,
            Timer::Segment,
            Timer::Sequence,
            Timer::Arrival,
            Timer::Liveness,
            Timer::Feedback,
            Timer::Heartbeat,
            Timer::Drain,
        ]
    );
}
