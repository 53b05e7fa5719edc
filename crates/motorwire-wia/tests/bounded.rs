//! A report lists the first [`MAX_VIOLATIONS`] violations and counts the
//! rest, whichever path found them (the schema's, the semantic checks',
//! each entry point's): a document of a million faults is answered in a
//! hundred lines (issue 58 part 3).
#![allow(clippy::unwrap_used)]

use motorwire_wia::{MAX_VIOLATIONS, MessageKind, Trajectory, Validator};

fn waypoints(n: usize, each: &str) -> String {
    format!(
        r#"{{"trajectory_id":"t","motor_id":"elbow","waypoints":[{}],"timing":{{}}}}"#,
        vec![each; n].join(",")
    )
}

#[test]
fn schema_violations_beyond_the_first_hundred_are_counted() {
    // Each `{}` waypoint lacks `position` and `time`.
    let doc = waypoints(10_000, "{}");
    let v = Validator::new();
    let err = v.parse::<Trajectory>(&doc).unwrap_err();
    assert_eq!(err.violations().len(), MAX_VIOLATIONS);
    assert_eq!(err.more(), 20_000 - MAX_VIOLATIONS);
    assert_eq!(err.violations()[0].pointer, "/waypoints/0/position");
    assert_eq!(err.violations()[99].pointer, "/waypoints/49/time");
    let text = err.to_string();
    assert!(
        text.starts_with("invalid trajectory: 20000 violation(s)"),
        "{text}"
    );
    assert!(text.ends_with("\n  and 19900 more, not listed"), "{text}");
    for report in [
        v.validate(MessageKind::Trajectory, &doc),
        v.validate_auto(&doc),
        v.validate_schema_only(MessageKind::Trajectory, &doc),
    ] {
        assert_eq!((report.violations.len(), report.more), (100, 19_900));
        assert_eq!(report.count(), 20_000);
        assert!(!report.is_valid());
        let json = serde_json::to_value(&report).unwrap();
        assert_eq!(json["more_violations"], 19_900);
    }
    let err = v.parse_any(&doc).unwrap_err();
    assert_eq!((err.violations().len(), err.more()), (100, 19_900));
}

#[test]
fn semantic_violations_beyond_the_first_hundred_are_counted() {
    // Typed and valid by the schema, every waypoint at time 0 after the
    // first breaks the time order: the count grows by one a waypoint.
    let wp = r#"{"position":1,"time":0}"#;
    let count = |n: usize| {
        let r = Validator::new().validate(MessageKind::Trajectory, &waypoints(n, wp));
        (r.violations.len(), r.more, r.count())
    };
    let (l10, m10, c10) = count(10);
    let (l20, _, c20) = count(20);
    assert_eq!((l10, m10, l20), (c10, 0, c20), "a short list is whole");
    let per = c20 - c10;
    assert!(per >= 10, "{c10} {c20}");
    let (listed, more, total) = count(5_000);
    assert_eq!(listed, MAX_VIOLATIONS);
    assert_eq!(total, c10 + per * (5_000 - 10) / 10);
    assert_eq!(more, total - MAX_VIOLATIONS);
    // A short report serializes without the count.
    let r = Validator::new().validate(MessageKind::Trajectory, &waypoints(3, wp));
    assert!(
        serde_json::to_value(&r)
            .unwrap()
            .get("more_violations")
            .is_none()
    );
}

/// Found by a new user: a line with `NaN` (what Python's `json.dumps`
/// writes for a float NaN) was answered `not valid JSON: expected value at
/// line 1 column 91`, naming nothing.
#[test]
fn a_number_json_has_no_word_for_is_named() {
    for (word, line) in [
        (
            "NaN",
            r#"{"motor_id":"elbow","timestamp":1,"control_mode":"velocity","setpoint":NaN}"#,
        ),
        (
            "Infinity",
            r#"{"motor_id":"elbow","timestamp":1,"control_mode":"velocity","setpoint":Infinity}"#,
        ),
        (
            "-Infinity",
            r#"{"motor_id":"elbow","timestamp":1,"control_mode":"velocity","setpoint":-Infinity}"#,
        ),
        (
            "NaN",
            "{\"motor_id\":\"elbow\",\n\"timestamp\":1,\n\"setpoint\": NaN}",
        ),
    ] {
        let e = motorwire_wia::Validator::new().parse_any(line).unwrap_err();
        let v = &e.violations()[0];
        assert_eq!(v.rule, motorwire_wia::Rule::JsonSyntax, "{line}");
        assert!(
            v.message
                .starts_with(&format!("not valid JSON: {word} is not a JSON number")),
            "{line}: {}",
            v.message
        );
    }
    // Anything else keeps serde_json's words alone.
    let e = motorwire_wia::Validator::new()
        .parse_any(r#"{"a":nope}"#)
        .unwrap_err();
    assert_eq!(
        e.violations()[0].message,
        "not valid JSON: expected ident at line 1 column 7"
    );
}
