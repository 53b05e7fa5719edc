//! A multi-axis command as large as the default document size allows:
//! every repeated motor found exactly as for a small one, in one pass
//! (the check was a search per axis, 0.1 s for 8,192 axes; issue 15); the
//! first 100 listed and the rest counted (issue 58 part 3).
#![allow(clippy::unwrap_used, clippy::indexing_slicing)]

use std::time::Instant;

use motorwire_wia::{MessageKind, Rule, Validator};

/// 8,192 axes; axis `i` moves motor `m{7i mod 3000}`, so every motor
/// appears two or three times and first at axis `i mod 3000` (7 is
/// invertible mod 3000).
fn command() -> String {
    let axes: Vec<String> = (0..8192)
        .map(|i| {
            format!(
                r#"{{"motor_id":"m{}","control_mode":"position","setpoint":1}}"#,
                (7 * i) % 3000
            )
        })
        .collect();
    format!(
        r#"{{"command_id":"big","timestamp":1704067200000,"motors":[{}]}}"#,
        axes.join(",")
    )
}

#[test]
fn eight_thousand_axes_report_each_repeat_with_its_first_place() {
    let json = command();
    assert!(json.len() < Validator::DEFAULT_MAX_DOCUMENT_SIZE);
    let started = Instant::now();
    let report = Validator::new().validate(MessageKind::MultiAxisCommand, &json);
    let took = started.elapsed();
    let got: Vec<(Rule, &str, &str)> = report
        .violations
        .iter()
        .map(|v| (v.rule, v.pointer.as_str(), v.message.as_str()))
        .collect();
    let expected: Vec<(String, String)> = (3000..8192)
        .map(|i| {
            (
                format!("/motors/{i}/motor_id"),
                format!(
                    "motor \"m{}\" already appears at /motors/{}",
                    (7 * i) % 3000,
                    i % 3000
                ),
            )
        })
        .collect();
    assert_eq!(got.len(), 100, "{:?}", got.first());
    assert_eq!(report.more, expected.len() - 100);
    for ((rule, pointer, message), (want_pointer, want_message)) in got.iter().zip(&expected) {
        assert_eq!(*rule, Rule::DuplicateMotor);
        assert_eq!(pointer, want_pointer);
        assert_eq!(message, want_message);
    }
    eprintln!("8,192 axes validated in {took:?}");
}
