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

/// Cases per property: all of them in an optimized build (CI runs this file
/// with `--release`), a tenth in a debug build, so that the README's
/// `cargo test` stays quick.
const fn cases(all: u32) -> u32 {
    if cfg!(debug_assertions) {
        all / 10
    } else {
        all
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(cases(2000)))]

    #[test]
    fn arbitrary_text_never_panics(text in any::<String>()) {
        let v = Validator::lenient();
        let r = v.validate_auto(&text);
        prop_assert!(!r.is_valid() || r.kind.is_some());
        let strict = v.clone().deny_unknown_members(true);
        for kind in MessageKind::ALL {
            let _ = v.validate(kind, &text);
            let _ = v.validate_schema_only(kind, &text);
            let _ = strict.validate(kind, &text);
        }
    }

    #[test]
    fn json_like_text_never_panics_and_reports_are_well_formed(text in json_like()) {
        let v = Validator::lenient().max_depth(8).now_ms(1_704_067_200_000.0);
        // Strict or not, the same document gets a well-formed report; the
        // strict one says everything the other does, and unknown members.
        let strict = v.clone().deny_unknown_members(true);
        for kind in MessageKind::ALL {
            let lenient = v.validate(kind, &text).violations;
            let all = strict.validate(kind, &text).violations;
            for x in &lenient {
                prop_assert!(all.contains(x), "{x} missing in strict");
            }
            prop_assert!(all[lenient.len()..].iter().all(|x| x.rule == motorwire_wia::Rule::UnknownMember));
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

/// A JSON object whose top-level member names name kinds (some escaped),
/// with values that hide member names in strings and nested objects, then
/// maybe cut short or followed by garbage.
fn object_like() -> impl Strategy<Value = String> {
    let key = prop_oneof![
        Just("\"motors\"".to_owned()),
        Just("\"mot\\u006frs\"".to_owned()),
        Just("\"setpoint\"".to_owned()),
        Just("\"control_mode\"".to_owned()),
        Just("\"motor_id\"".to_owned()),
        Just("\"timestamp\"".to_owned()),
        Just("\"gains\"".to_owned()),
        Just("\"mode\"".to_owned()),
        Just("\"status\"".to_owned()),
        Just("\"position_limits\"".to_owned()),
        Just("\"waypoints\"".to_owned()),
        Just("\"x\\\"motors\"".to_owned()),
        "[a-z_]{0,8}".prop_map(|s| format!("\"{s}\"")),
    ];
    let value = prop_oneof![
        Just("1".to_owned()),
        Just("\"position\"".to_owned()),
        Just("\"}, \\\"motors\\\": [\"".to_owned()),
        Just("{\"motors\": [1, {\"waypoints\": 2}]}".to_owned()),
        Just("[\"setpoint\", {\"gains\": {}}]".to_owned()),
        Just("null".to_owned()),
        Just("\"elbow\"".to_owned()),
        Just("1704067200000".to_owned()),
    ];
    let members = prop::collection::vec((key, value), 0..8);
    (
        members,
        0usize..200,
        prop_oneof![Just(""), Just(" "), Just("x"), Just("}"), Just(",{}")],
    )
        .prop_map(|(members, cut, tail)| {
            let body: Vec<String> = members.iter().map(|(k, v)| format!("{k}: {v}")).collect();
            let mut doc = format!(" {{{}}}{tail}", body.join(", "));
            if cut < doc.len() && cut % 3 == 0 {
                doc.truncate(cut);
            }
            doc
        })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(cases(4000)))]

    /// `validate_auto` parses a document once (its kind from a scan of the
    /// member names), and judges exactly as inferring the kind with a parse
    /// of its own and then validating as that kind does.
    #[test]
    fn auto_validation_equals_infer_then_validate(doc in prop_oneof![object_like(), json_like()]) {
        let v = Validator::new();
        let auto = v.validate_auto(&doc);
        match MessageKind::infer(&doc) {
            Ok(Some(kind)) => prop_assert_eq!(auto, v.validate(kind, &doc)),
            _ => prop_assert_eq!(auto.kind, None),
        }
    }
}
