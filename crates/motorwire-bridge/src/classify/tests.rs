//! Unit tests.

#![allow(clippy::unwrap_used, clippy::panic)]
use super::*;

/// Lines the fast path must read exactly as every member would be.
const LINES: [&str; 16] = [
    r#"{"motor_id":"elbow","timestamp":1,"control_mode":"position","setpoint":20}"#,
    r#" {"motor_id":"elbow","timestamp":1,"control_mode":"position","setpoint":20} "#,
    r#"{"motor_id":"elbow","timestamp":1,"control_mode":"position","setpoint":20,"setpoint":140}"#,
    r#"{"motor_id":"elbow","timestamp":1,"control_mode":"position","setpoint":20,"query":"limits"}"#,
    r#"{"query":"limits","motor_id":"elbow"}"#,
    r#"{"reset":"elbow"}"#,
    r#"{"motor_id":"elbow","timestamp":1,"control_mode":"position","setpoint":1e400}"#,
    r#"{"motor_id":"elbow","timestamp":1,"control_mode":"position","setpoint":20}x"#,
    r#"{"motor_id":"elbow","timestamp":1,"control_mode":"position","setpoint":20"#,
    r#"{"motor_id":"elbow","timestamp":1,"control_mode":"position","x":{"query":1},"setpoint":20}"#,
    r#"{"motor_id":"el\u0062ow","timestamp":1,"control_mode":"position","setpoint":20}"#,
    r#"{"command_id":"c","timestamp":1,"motors":[{"motor_id":"elbow","control_mode":"position","setpoint":1}]}"#,
    r#"{"trajectory_id":"t","trajectories":[]}"#,
    r#"{"orion":"fold"}"#,
    r#"[{"motor_id":"elbow"}]"#,
    r#"{"motor_id":"elbow","position_limits":{"min":0,"max":50},"velocity_limits":{"max_velocity":10},"torque_limits":{"continuous_torque":1,"peak_torque":2}}"#,
];

#[test]
fn the_one_parse_path_reads_every_line_as_the_whole_reading_does() {
    let v = Validator::new();
    for line in LINES {
        assert_eq!(classify(&v, line), classify_members(&v, line), "{line}");
    }
    // Which lines took the one-parse path: the plain messages only.
    let plain: Vec<bool> = LINES.iter().map(|l| plain_message(l).is_some()).collect();
    // With the kind their names say, read in the same scan.
    use motorwire_wia::MessageKind;
    assert_eq!(
        plain_message(LINES[0]),
        Some(Some(MessageKind::MotorCommand))
    );
    assert_eq!(
        plain_message(LINES[11]),
        Some(Some(MessageKind::MultiAxisCommand))
    );
    assert_eq!(
        plain_message(LINES[15]),
        Some(Some(MessageKind::SafetyLimits))
    );
    assert_eq!(
        plain,
        [
            true, true, true, false, false, false, true, true, false, true, false, true, false,
            false, false, true
        ]
    );
}

/// The one-parse path for a plain motor command gives every line what
/// the scan and the typed parse give, and what every member read gives:
/// above all, each way a line can name a stop still stops.
#[test]
fn a_plain_command_read_once_is_read_as_before() {
    let cmd = r#""motor_id":"elbow","timestamp":1,"control_mode":"position","setpoint":20"#;
    let cases: Vec<(String, bool)> = [
        // (the line after the command's members, whether it is plain)
        ("", true),
        (
            r#","velocity_limit":50,"pid_gains":{"kp":1},"priority":3"#,
            true,
        ),
        (r#","safety_limits":{"max_position":90}"#, true),
        // A stop in the command's own limits, true or false.
        (r#","safety_limits":{"emergency_stop":true}"#, false),
        (r#","safety_limits":{"emergency_stop":false}"#, false),
        (r#","safety_limits":{"emergency\u005fstop":true}"#, false),
        // Named twice in the limits: the parse refuses, the stop stands.
        (
            r#","safety_limits":{"emergency_stop":false,"emergency_stop":true}"#,
            false,
        ),
        // Under an unknown nested member, under metadata, at the top.
        (r#","pid_gains":{"kp":1,"emergency_stop":true}"#, false),
        (r#","metadata":{"emergency_stop":true}"#, false),
        (r#","metadata":{"note":"x"}"#, false),
        (r#","emergency_stop":true"#, false),
        (r#","emergency\u005fstop":true"#, false),
        (r#","emergency_stop":false"#, false),
        // The bridge's own forms, a misspelling, another kind's name.
        (r#","stream":true"#, false),
        (r#","velocity_limt":5"#, false),
        (r#","position_limits":{"min":0,"max":50}"#, false),
        // Invalid: a value out of range, a wrong type.
        (r#","velocity_limit":-1"#, false),
        (r#","priority":"high""#, false),
    ]
    .into_iter()
    .map(|(rest, plain)| (format!("{{{cmd}{rest}}}"), plain))
    .chain([
        // A motor named after the stop is only a name.
        (
            r#"{"motor_id":"emergency_stop","timestamp":1,"control_mode":"position","setpoint":2}"#
                .to_owned(),
            true,
        ),
        (
            r#"{"motor_id":"el\u0062ow","timestamp":1,"control_mode":"position","setpoint":2}"#
                .to_owned(),
            true,
        ),
        (
            r#"{"timestamp":1,"control_mode":"position","setpoint":2}"#.to_owned(),
            false,
        ),
    ])
    .collect();
    for v in [
        Validator::lenient(),
        Validator::new().deny_unknown_members(true),
        Validator::new().max_depth(1),
    ] {
        for (line, plain) in &cases {
            let once = classify(&v, line);
            assert_eq!(once, classify_scanned(&v, line), "{line}");
            assert_eq!(once, classify_members(&v, line), "{line}");
            let deep = v == Validator::new().max_depth(1)
                && line.contains('{')
                && line.matches('{').count() > 1;
            assert_eq!(plain_command(&v, line).is_some(), *plain && !deep, "{line}");
        }
    }
    // The stops stop.
    let v = Validator::new();
    for (line, _) in &cases {
        if line.contains(r#"emergency_stop":true"#) || line.contains(r#"emergency\u005fstop":true"#)
        {
            assert!(matches!(classify(&v, line), Line::Stop { .. }), "{line}");
        }
    }
}

/// An axis of the elbow's, with `rest` after its setpoint.
fn elbow_axis(rest: &str) -> String {
    format!(r#"{{"motor_id":"elbow","control_mode":"position","setpoint":20{rest}}}"#)
}

/// A multi-axis command of `axes`, with `rest` after its motors.
fn multi_axis_line(axes: &[String], rest: &str) -> String {
    format!(
        r#"{{"command_id":"c","timestamp":1,"motors":[{}]{rest}}}"#,
        axes.join(",")
    )
}

/// Each of `cases` (a line, whether it is plain) read once is classified
/// as the scanned and the member-by-member readings classify it, and only
/// the plain ones are read once; the stops stop.
fn assert_multi_axis_read_as_before(cases: &[(String, bool)]) {
    for v in [
        Validator::lenient(),
        Validator::new().deny_unknown_members(true),
        Validator::new().max_depth(3),
    ] {
        for (line, plain) in cases {
            let once = classify(&v, line);
            assert_eq!(once, classify_scanned(&v, line), "{line}");
            assert_eq!(once, classify_members(&v, line), "{line}");
            let deep = v == Validator::new().max_depth(3)
                && (line.contains("pid_gains") || line.contains("safety_limits"));
            assert_eq!(
                plain_multi_axis(&v, line).is_some(),
                *plain && !deep,
                "{line}"
            );
            assert!(plain_command(&v, line).is_none(), "{line}");
        }
    }
    // The stops stop.
    let v = Validator::new();
    for (line, _) in cases {
        if line.contains(r#"emergency_stop":true"#) || line.contains(r#"emergency\u005fstop":true"#)
        {
            assert!(matches!(classify(&v, line), Line::Stop { .. }), "{line}");
        }
    }
}

/// A multi-axis command read once is classified as the scanned and the
/// member-by-member readings classify it; and only the plain ones are
/// read once: not the bridge's own forms, a misspelling, invalid values.
#[test]
fn a_plain_multi_axis_command_read_once_is_read_as_before() {
    let (axis, line) = (elbow_axis, multi_axis_line);
    let wrist = r#"{"motor_id":"wrist","control_mode":"position","setpoint":5}"#.to_owned();
    let cases: Vec<(String, bool)> = vec![
        // (the line, whether it is plain)
        (line(&[axis("")], ""), true),
        (
            line(
                &[
                    axis(r#","velocity_limit":50,"pid_gains":{"kp":1}"#),
                    wrist.clone(),
                ],
                r#","sync_mode":"sequential""#,
            ),
            true,
        ),
        (
            line(&[axis(r#","safety_limits":{"max_position":90}"#)], ""),
            true,
        ),
        // The bridge's own forms, a misspelling, invalid values.
        (line(&[axis("")], r#","stream":true"#), false),
        (line(&[axis("")], r#","trajectories":[]"#), false),
        (line(&[axis(r#","velocity_limt":5"#)], ""), false),
        (line(&[axis(r#","velocity_limit":-1"#)], ""), false),
        (line(&[], ""), false),
        // A motor named after the stop is only a name.
        (
            line(&[axis("").replace("elbow", "emergency_stop")], ""),
            true,
        ),
    ];
    assert_multi_axis_read_as_before(&cases);
}

/// A multi-axis command that hides a stop in any place an axis can carry
/// one is not read once, and is classified as the scanned and the
/// member-by-member readings classify it.
#[test]
fn a_multi_axis_command_that_may_name_a_stop_is_read_as_before() {
    let (axis, line) = (elbow_axis, multi_axis_line);
    let wrist = r#"{"motor_id":"wrist","control_mode":"position","setpoint":5}"#.to_owned();
    let cases: Vec<(String, bool)> = vec![
        // (the line, whether it is plain)
        // A stop in an axis's own limits (the second axis's), true or false.
        (
            line(
                &[wrist, axis(r#","safety_limits":{"emergency_stop":true}"#)],
                "",
            ),
            false,
        ),
        (
            line(&[axis(r#","safety_limits":{"emergency_stop":false}"#)], ""),
            false,
        ),
        (
            line(&[axis(r#","safety_limits":{"emergency_stop":true}"#)], ""),
            false,
        ),
        (
            line(
                &[axis(
                    r#","safety_limits":{"emergency_stop":false,"emergency_stop":true}"#,
                )],
                "",
            ),
            false,
        ),
        // Under an unknown nested member, under metadata (the command's
        // or an axis's), at the top.
        (
            line(
                &[axis(r#","pid_gains":{"kp":1,"emergency_stop":true}"#)],
                "",
            ),
            false,
        ),
        (
            line(&[axis(r#","metadata":{"emergency_stop":true}"#)], ""),
            false,
        ),
        (line(&[axis(r#","metadata":{"note":"x"}"#)], ""), false),
        (
            line(&[axis("")], r#","metadata":{"emergency_stop":true}"#),
            false,
        ),
        (
            line(&[axis("")], r#","coordination":{"emergency_stop":true}"#),
            false,
        ),
        (line(&[axis("")], r#","emergency_stop":true"#), false),
        (line(&[axis("")], r#","emergency\u005fstop":true"#), false),
        (
            line(
                &[axis(r#","safety_limits":{"emergency\u005fstop":true}"#)],
                "",
            ),
            false,
        ),
        (line(&[axis("")], r#","emergency_stop":false"#), false),
        (line(&[axis(r#","emergency_stop":true"#)], ""), false),
    ];
    assert_multi_axis_read_as_before(&cases);
}

/// `"stream"`: `true` makes a MotorCommand a stream's setpoint,
/// `false` leaves it an ordinary command; anything else, a repeated
/// one, or a stream on another message is invalid, and the command
/// itself is judged as any command is.
#[test]
fn stream_is_a_motor_commands_boolean() {
    let v = Validator::new();
    let cmd = r#""motor_id":"elbow","timestamp":1,"control_mode":"position","setpoint":20"#;
    let Line::Stream(c) = classify(&v, &format!("{{{cmd},\"stream\":true}}")) else {
        panic!("not a stream");
    };
    assert_eq!((c.motor_id.as_str(), c.setpoint), ("elbow", 20.0));
    assert!(c.extra.is_empty());
    assert!(matches!(
        classify(&v, &format!("{{\"stream\":false,{cmd}}}")),
        Line::Message(m) if matches!(*m, Message::MotorCommand(_))
    ));
    let message = |line: &str| match classify(&v, line) {
        Line::Invalid { message, .. } => message,
        other => panic!("{line}: {other:?}"),
    };
    assert_eq!(
        message(&format!("{{{cmd},\"stream\":1}}")),
        "stream is 1: it is true (the command is a setpoint of a stream) or false"
    );
    assert_eq!(
        message(&format!("{{{cmd},\"stream\":true,\"stream\":true}}")),
        "stream appears 2 times"
    );
    // A multi-axis command's stream: one line for all its motors.
    let multi = r#""command_id":"c","timestamp":1,"motors":[{"motor_id":"elbow","control_mode":"position","setpoint":1},{"motor_id":"gripper_axis","control_mode":"velocity","setpoint":-2}]"#;
    let Line::StreamAxes(m) = classify(&v, &format!("{{{multi},\"stream\":true}}")) else {
        panic!("not a multi-axis stream");
    };
    assert_eq!(
        m.motors
            .iter()
            .map(|a| (a.motor_id.as_str(), a.setpoint))
            .collect::<Vec<_>>(),
        [("elbow", 1.0), ("gripper_axis", -2.0)]
    );
    assert!(m.extra.is_empty());
    assert!(matches!(
        classify(&v, &format!("{{\"stream\":false,{multi}}}")),
        Line::Message(m) if matches!(*m, Message::MultiAxisCommand(_))
    ));
    assert_eq!(
        message(&format!("{{{multi},\"stream\":\"yes\"}}")),
        "stream is \"yes\": it is true (the command is a setpoint of a stream) or false"
    );
    assert_eq!(
        message(
            r#"{"motor_id":"elbow","position_limits":{"min":0,"max":9},"velocity_limits":{"max_velocity":9},"torque_limits":{"continuous_torque":1,"peak_torque":2},"stream":true}"#
        ),
        "stream is a command's (a motor command or a multi-axis command); a safety-limits has no stream"
    );
    // As the bridge reads lines: a typo in a stream's setpoint is
    // refused as in any command.
    let strict = Validator::new().deny_unknown_members(true);
    let typo = format!("{{{cmd},\"velocity_limt\":5,\"stream\":true}}");
    let Line::Invalid { message, .. } = classify(&strict, &typo) else {
        panic!("{typo}");
    };
    assert!(message.contains("velocity_limt"), "{message}");
}

/// `{"motor":A,"motor_id":M}`: hold, free or stop, exactly; anything
/// else is invalid and names the form; a stop in it still stops.
#[test]
fn a_motor_line_is_exactly_an_action_and_a_motor() {
    let v = Validator::new();
    for action in MotorAction::ALL {
        for line in [
            format!(r#"{{"motor":"{}","motor_id":"knee"}}"#, action.name()),
            format!(r#"{{"motor_id":"knee","motor":"{}"}}"#, action.name()),
        ] {
            assert_eq!(
                classify(&v, &line),
                Line::Motor {
                    action,
                    motor_id: "knee".to_owned()
                },
                "{line}"
            );
        }
    }
    let form = r#"a motor line is exactly {"motor":"hold"|"free"|"stop","motor_id":"..."}"#;
    for (line, why) in [
        (
            r#"{"motor":"halt","motor_id":"knee"}"#,
            r#""halt" is not one (hold: stop and hold, torque on; free: torque off; stop: the motor's own stop)"#,
        ),
        (r#"{"motor":"hold"}"#, "it names no motor_id"),
        (
            r#"{"motor":"hold","motor_id":"knee","timestamp":1,"x":2}"#,
            "it also carries timestamp, x",
        ),
        (
            r#"{"motor":true,"motor_id":"knee"}"#,
            r#"motor is true: it is "hold", "free" or "stop""#,
        ),
        (
            r#"{"motor":"hold","motor_id":7}"#,
            "motor_id is 7: it is a motor's name",
        ),
        (
            r#"{"motor":"hold","motor_id":"knee","motor_id":"hip"}"#,
            "motor or motor_id appears more than once",
        ),
    ] {
        let message = format!("{form}: {why}");
        let Line::Invalid { message: m, .. } = classify(&v, line) else {
            panic!("{line}");
        };
        assert_eq!(m, message, "{line}");
    }
    // A huge value is not said back whole.
    let huge = format!(r#"{{"motor":"{}","motor_id":"knee"}}"#, "h".repeat(100_000));
    let Line::Invalid { message: m, .. } = classify(&v, &huge) else {
        panic!("huge");
    };
    assert_eq!(
        m,
        format!(
            r#"{form}: "{}... is not one (hold: stop and hold, torque on; free: torque off; stop: the motor's own stop)"#,
            "h".repeat(63)
        )
    );
    assert!(matches!(
        classify(
            &v,
            r#"{"motor":"free","motor_id":"knee","emergency_stop":true}"#
        ),
        Line::Stop { .. }
    ));
}

/// `{"feedback_hz":N}` alone is a client's feedback rate; with other
/// members, or not a number, it is invalid (never a command with an
/// unknown member taken).
#[test]
fn feedback_hz_is_a_line_of_its_own() {
    let v = Validator::new();
    assert_eq!(
        classify(&v, r#"{"feedback_hz":12.5}"#),
        Line::FeedbackRate { hz: 12.5 }
    );
    assert_eq!(
        classify(&v, r#" {"feedback_hz": 0} "#),
        Line::FeedbackRate { hz: 0.0 }
    );
    for line in [
        r#"{"feedback_hz":"10"}"#,
        r#"{"feedback_hz":10,"motor_id":"elbow"}"#,
        r#"{"motor_id":"elbow","timestamp":1,"control_mode":"position","setpoint":20,"feedback_hz":10}"#,
    ] {
        let Line::Invalid { message, .. } = classify(&v, line) else {
            panic!("{line}");
        };
        assert_eq!(
            message,
            r#"a feedback rate is exactly {"feedback_hz":N}, N a number of Hz (0: no feedback)"#,
            "{line}"
        );
    }
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig { cases: 256, failure_persistence: None, ..Default::default() })]
    /// Random members (the bridge's own names among them), values and
    /// junk: both readings agree on every line.
    #[test]
    fn both_readings_agree_on_random_lines(
        parts in proptest::collection::vec(proptest::sample::select(vec![
            r#""motor_id":"elbow""#, r#""timestamp":1"#, r#""control_mode":"position""#,
            r#""setpoint":20"#, r#""setpoint":1e400"#, r#""query":"limits""#, r#""reset":"elbow""#,
            r#""orion":"fold""#, r#""x":{"query":1}"#, r#""motors":[]"#, r#""velocity_limit":5"#,
            r#""y":[1,{"a":"}"}]"#, r#""command_id":"c""#, r#""trajectories":[1]"#,
            // Stops, where the one parse of a command must see them.
            r#""emergency_stop":true"#, r#""emergency_stop":false"#,
            r#""emergency\u005fstop":true"#, r#""safety_limits":{"emergency_stop":true}"#,
            r#""safety_limits":{"emergency_stop":false}"#, r#""safety_limits":{"max_position":90}"#,
            r#""pid_gains":{"kp":1,"emergency_stop":true}"#, r#""pid_gains":{"kp":1}"#,
            r#""metadata":{"emergency_stop":true}"#, r#""metadata":{}"#, r#""stream":true"#,
            r#""priority":2"#, r#""velocity_limit":-1"#,
        ]), 0..8),
        // A whole command first, or not: the one-parse path's lines.
        command in proptest::bool::ANY,
        tail in proptest::sample::select(vec!["", " ", "x", "}", "]", ","]),
    ) {
        let mut parts = parts;
        if command {
            parts.splice(0..0, [r#""motor_id":"elbow""#, r#""timestamp":1"#, r#""control_mode":"position""#, r#""setpoint":20"#]);
        }
        let line = format!("{{{}}}{tail}", parts.join(","));
        let v = Validator::new();
        let once = classify(&v, &line);
        proptest::prop_assert_eq!(&once, &classify_scanned(&v, &line), "{}", line);
        proptest::prop_assert_eq!(&once, &classify_members(&v, &line), "{}", line);
    }
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig { cases: 256, failure_persistence: None, ..Default::default() })]
    /// Multi-axis commands made of random axes (stops, metadata,
    /// typos and invalid values among their members) and random
    /// top-level members: the three readings agree on every line.
    #[test]
    fn all_readings_agree_on_random_multi_axis_lines(
        axes in proptest::collection::vec(proptest::collection::vec(proptest::sample::select(vec![
            r#""velocity_limit":5"#, r#""velocity_limit":-1"#, r#""priority":2"#,
            r#""emergency_stop":true"#, r#""safety_limits":{"emergency_stop":true}"#,
            r#""safety_limits":{"emergency_stop":false}"#, r#""safety_limits":{"max_position":90}"#,
            r#""safety_limits":{"emergency_stop":1}"#, r#""pid_gains":{"kp":1}"#,
            r#""pid_gains":{"kp":1,"emergency_stop":true}"#, r#""metadata":{"emergency_stop":true}"#,
            r#""metadata":{}"#, r#""velocity_limt":5"#, r#""setpoint":3"#,
        ]), 0..4), 0..4),
        top in proptest::collection::vec(proptest::sample::select(vec![
            r#""sync_mode":"simultaneous""#, r#""sync_mode":"warp""#, r#""metadata":{"emergency_stop":true}"#,
            r#""coordination":{"type":"independent"}"#, r#""coordination":{"emergency_stop":true}"#,
            r#""emergency_stop":true"#, r#""emergency_stop":false"#, r#""stream":true"#,
            r#""reset":"elbow""#, r#""command_id":"d""#,
        ]), 0..3),
        tail in proptest::sample::select(vec!["", " ", "x", "}"]),
    ) {
        let axes: Vec<String> = axes
            .iter()
            .enumerate()
            .map(|(i, parts)| {
                let mut members = vec![format!(r#""motor_id":"m{i}""#), r#""control_mode":"position""#.to_owned(), r#""setpoint":1"#.to_owned()];
                members.extend(parts.iter().map(|p| (*p).to_owned()));
                format!("{{{}}}", members.join(","))
            })
            .collect();
        let mut members = vec![r#""command_id":"c""#.to_owned(), r#""timestamp":1"#.to_owned(), format!(r#""motors":[{}]"#, axes.join(","))];
        members.extend(top.iter().map(|p| (*p).to_owned()));
        let line = format!("{{{}}}{tail}", members.join(","));
        let v = Validator::new();
        let once = classify(&v, &line);
        proptest::prop_assert_eq!(&once, &classify_scanned(&v, &line), "{}", line);
        proptest::prop_assert_eq!(&once, &classify_members(&v, &line), "{}", line);
        if line.contains(r#"emergency_stop":true"#) {
            proptest::prop_assert!(matches!(once, Line::Stop { .. }), "{}", line);
        }
    }
}

fn stop(line: &str) -> Vec<String> {
    match classify(&Validator::new(), line) {
        Line::Stop { problems, .. } => problems,
        other => panic!("{line}: {other:?}"),
    }
}

#[test]
fn a_stop_the_parsed_members_cannot_show_still_stops() {
    let v = Validator::new();
    for line in [
        // A nested member named twice: the parsed object keeps the last.
        r#"{"motor_id":"elbow","timestamp":1,"control_mode":"position","setpoint":40,"safety_limits":{"emergency_stop":true,"emergency_stop":false}}"#,
        r#"{"command_id":"c","timestamp":1,"motors":[{"motor_id":"a","control_mode":"position","setpoint":1,"safety_limits":{"emergency_stop":1,"emergency_stop":false}}]}"#,
        // Under metadata, under a misspelled member, spelled with an escape.
        r#"{"motor_id":"elbow","timestamp":1,"control_mode":"position","setpoint":40,"metadata":{"emergency_stop":true}}"#,
        r#"{"motor_id":"elbow","timestamp":1,"control_mode":"position","setpoint":40,"safety_limit":{"emergency_stop":true}}"#,
        r#"{"motor_id":"elbow","timestamp":1,"control_mode":"position","setpoint":40,"safety_limits":{"emergency_stop":false,"emergency_stop":true}}"#,
        // A release that also names a stop elsewhere.
        r#"{"emergency_stop":false,"metadata":{"emergency_stop":true}}"#,
    ] {
        assert!(
            matches!(classify(&v, line), Line::Stop { .. }),
            "{line}: {:?}",
            classify(&v, line)
        );
        assert!(asks_for_stop(line), "{line}");
    }
    // What names no stop is not one: false everywhere, or only as a
    // string value.
    for line in [
        r#"{"motor_id":"elbow","timestamp":1,"control_mode":"position","setpoint":40,"safety_limits":{"emergency_stop":false,"emergency_stop":false}}"#,
        r#"{"motor_id":"elbow","timestamp":1,"control_mode":"position","setpoint":40,"metadata":{"emergency_stop":false,"note":"\"emergency_stop\":true"}}"#,
    ] {
        assert!(!asks_for_stop(line), "{line}");
        assert!(!matches!(classify(&v, line), Line::Stop { .. }), "{line}");
    }
    assert_eq!(classify(&v, r#"{"emergency_stop": false}"#), Line::Release);
}

#[test]
fn every_stop_form_stops() {
    assert!(stop(r#"{"emergency_stop": true}"#).is_empty());
    assert_eq!(
        stop(r#"{"emergency_stop": true, "why": "x"}"#),
        ["the line also carries why"]
    );
    assert_eq!(
        stop(r#"{"emergency_stop": 1}"#),
        ["emergency_stop is 1, not true: taken as a stop"]
    );
    assert_eq!(
        stop(r#"{"emergency_stop": null}"#),
        ["emergency_stop is null, not true: taken as a stop"]
    );
    assert_eq!(
        stop(r#"{"emergency_stop": false, "emergency_stop": true}"#),
        ["emergency_stop appears 2 times"]
    );
    // A valid command carrying the stop: no problems.
    assert!(stop(r#"{"motor_id":"elbow","timestamp":1,"control_mode":"position","setpoint":1,"safety_limits":{"emergency_stop":true}}"#).is_empty());
    // An invalid one: stops, and says what is wrong.
    let p = stop(
        r#"{"motor_id":"elbow","timestamp":1,"control_mode":"warp","setpoint":1,"safety_limits":{"emergency_stop":true}}"#,
    );
    assert!(p.iter().any(|v| v.contains("control_mode")), "{p:?}");
    // A multi-axis command with one stopping axis.
    let p = stop(
        r#"{"command_id":"c","timestamp":1,"motors":[{"motor_id":"a","control_mode":"position","setpoint":1},{"motor_id":"b","safety_limits":{"emergency_stop":"yes"}}]}"#,
    );
    assert!(!p.is_empty());
}

#[test]
fn only_the_exact_release_releases() {
    let v = Validator::new();
    assert_eq!(classify(&v, r#" {"emergency_stop":false} "#), Line::Release);
    for bad in [
        r#"{"emergency_stop": false, "motor_id": "elbow"}"#,
        r#"{"emergency_stop": false, "emergency_stop": false}"#,
    ] {
        assert!(
            matches!(classify(&v, bad), Line::BadRelease { .. }),
            "{bad}"
        );
    }
    // Not JSON, or not an object: never a release (and a stop only when
    // it names one with a value other than false).
    assert!(matches!(
        classify(&v, r#"{"emergency_stop": false"#),
        Line::Invalid { .. }
    ));
    assert!(matches!(
        classify(&v, r#"[{"emergency_stop": false}]"#),
        Line::Invalid { .. }
    ));
}

#[test]
fn valid_json_no_parser_holds_still_stops() {
    let v = Validator::new();
    assert_eq!(
        stop(r#"{"emergency_stop": true, "x": 1e400}"#),
        [
            "the line cannot be read exactly (number out of range at line 1 column 35); it asks for a stop, so it stops"
        ]
    );
    assert_eq!(
        stop(
            r#"{"motor_id":"el\ud800bow","timestamp":1,"control_mode":"position","setpoint":-1e999,"safety_limits":{"emergency_stop":true}}"#
        ),
        [
            "the line cannot be read exactly (unexpected end of hex escape at line 1 column 22); it asks for a stop, so it stops"
        ]
    );
    assert!(asks_for_stop(r#"{"emergency_stop": true, "x": 1e400}"#));
    assert!(asks_for_stop(r#"{"emergency_stop": "\udc00"}"#));
    // Repaired only to find a stop: otherwise invalid, never a release
    // or a command.
    for line in [
        r#"{"emergency_stop": false, "x": 1e400}"#,
        r#"{"motor_id":"elbow","timestamp":1,"control_mode":"position","setpoint":1e400,"emergency_stop_note":1}"#,
    ] {
        assert!(!asks_for_stop(line), "{line}");
        assert!(matches!(classify(&v, line), Line::Invalid { .. }), "{line}");
    }
    // The repair leaves what it does not need to touch alone.
    assert_eq!(
        repair(r#"{"a":"1e400 \"\\ud800","b":[-1e400,2.5e3]}"#).unwrap(),
        r#"{"a":"1e400 \"\\ud800","b":[0,2.5e3]}"#
    );
    assert_eq!(
        repair(r#"{"a":"ü\uD834\uDD1E"}"#).unwrap(),
        r#"{"a":"ü\uFFFD\uFFFD"}"#
    );
    assert_eq!(repair(r#"{"a":1}"#), None);
}

#[test]
fn lines_no_parser_reads_that_name_a_stop_stop() {
    let deep = format!(
        r#"{{"emergency_stop": true, "x": {}1{}}}"#,
        "[".repeat(200),
        "]".repeat(200)
    );
    for line in [
        deep.as_str(),
        "{\"emergency_stop\": true}\u{0}",
        "\u{FEFF}{\"emergency_stop\": true}",
        r#"{"emergency_stop": true} x"#,
        r#"{"emergency_stop": true"#,
        r#"{"emergency_stop": NaN}"#,
        r#"[{"emergency_stop": true}]"#,
        r#"{"emergency\u005fstop": true, "x": }"#,
        r#"{"a": {"b": [{"emergency_stop" : 1}]}, }"#,
        // An escape JSON does not allow: not JSON, and the fallback
        // reads `\g` as `g`; the quick test agrees.
        r#"{"emer\gency_stop": true}"#,
    ] {
        assert!(asks_for_stop(line), "{line}");
        let p = stop(line);
        assert_eq!(p.len(), 1, "{line}: {p:?}");
        assert!(
            p[0].ends_with("it names emergency_stop with a value other than false, so it stops"),
            "{p:?}"
        );
    }
    // Not a stop: false, or no such key.
    for line in [
        r#"{"emergency_stop": false"#,
        r#"{"emergency_stop" : false} x"#,
        r#"{"motor_id": "emergency_stop", "x": }"#,
        "garbage",
    ] {
        assert!(!asks_for_stop(line), "{line}");
        assert!(
            matches!(classify(&Validator::new(), line), Line::Invalid { .. }),
            "{line}"
        );
    }
}

#[test]
fn deep_and_huge_lines_are_invalid_not_a_crash() {
    let v = Validator::new();
    let deep = format!("{}{}", "[".repeat(100_000), "]".repeat(100_000));
    assert!(matches!(classify(&v, &deep), Line::Invalid { .. }));
    let deep_obj = format!("{{\"a\":{}1{}}}", "[".repeat(10_000), "]".repeat(10_000));
    assert!(matches!(classify(&v, &deep_obj), Line::Invalid { .. }));
}
