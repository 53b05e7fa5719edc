//! Properties over arbitrary input: nothing panics, and every report is
//! well-formed.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing
)]

use motorwire_wia::{Level, MessageKind, Validator};
use proptest::prelude::*;

fn json_like() -> impl Strategy<Value = String> {
    // Strings made of JSON's own punctuation, keywords and member names reach
    // far deeper into the parser than uniformly random text.
    let token = prop_oneof![
        Just("{".to_owned()),
        Just("}".to_owned()),
        Just("[".to_owned()),
        Just("]".to_owned()),
        Just(",".to_owned()),
        Just(":".to_owned()),
        Just("null".to_owned()),
        Just("true".to_owned()),
        Just("\"motor_id\"".to_owned()),
        Just("\"setpoint\"".to_owned()),
        Just("\"control_mode\"".to_owned()),
        Just("\"position\"".to_owned()),
        Just("\"timestamp\"".to_owned()),
        Just("\"waypoints\"".to_owned()),
        Just("\"motors\"".to_owned()),
        Just("\"pid_gains\"".to_owned()),
        Just("\"kp\"".to_owned()),
        Just("-1e999".to_owned()),
        Just("1e-400".to_owned()),
        Just("\"\\ud800\"".to_owned()),
        any::<i64>().prop_map(|n| n.to_string()),
        any::<f64>().prop_map(|n| n.to_string()),
        "[a-z_]{0,8}".prop_map(|s| format!("\"{s}\"")),
    ];
    prop::collection::vec(token, 0..60).prop_map(|t| t.concat())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    #[test]
    fn arbitrary_text_never_panics(text in any::<String>()) {
        let v = Validator::new();
        let r = v.validate_auto(&text);
        prop_assert!(!r.is_valid() || r.kind.is_some());
        for kind in MessageKind::ALL {
            let _ = v.validate(kind, &text);
            let _ = v.validate_schema_only(kind, &text);
        }
    }

    #[test]
    fn json_like_text_never_panics_and_reports_are_well_formed(text in json_like()) {
        let v = Validator::new().max_depth(8).now_ms(1_704_067_200_000.0);
        for kind in MessageKind::ALL {
            let r = v.validate(kind, &text);
            prop_assert_eq!(r.kind, Some(kind));
            for x in &r.violations {
                prop_assert!(x.pointer.is_empty() || x.pointer.starts_with('/'));
                prop_assert!(!x.message.is_empty());
            }
            // A document-level problem is the only thing reported.
            if r.violations.iter().any(|x| x.rule.level() == Level::Document) {
                prop_assert_eq!(r.violations.len(), 1);
            }
            // The full verdict is never more lenient than the schema's.
            if r.is_valid() {
                prop_assert!(v.validate_schema_only(kind, &text).is_valid());
            }
        }
    }
}
