//! The typed path and the JSON Schema must agree on schema-level validity.
//!
//! The typed path is serde's parse into motorwire's types (which enforces
//! `type`, `required` and `enum`) followed by the typed checks of the other
//! keywords (`minimum`, `pattern`, `minItems`, ...). The JSON Schema verdict is
//! `jsonschema`'s on the same text. They are compared over every fixture and
//! over generated documents: random valid variants of the fixtures, and
//! mutations of them (members deleted, values replaced by values of other
//! types and at the edges of their ranges, unknown members added).
//!
//! The one allowed difference: an integer beyond 64 bits is valid JSON Schema
//! `integer` but motorwire refuses it as `unrepresentable`; the test checks
//! that this is the reason whenever it happens.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing
)]

use std::path::Path;

use motorwire_wia::{
    ControlModeConfig, Level, MessageKind, MotorCommand, MotorFeedback, MultiAxisCommand,
    PidConfig, Rule, SafetyLimits, Trajectory, Validator, WiaMessage, schema_validator,
};
use serde_json::{Map, Value, json};

/// SplitMix64: small, seedable, good enough to pick mutations.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
    fn chance(&mut self, percent: u64) -> bool {
        self.next() % 100 < percent
    }
    fn pick<'a, T>(&mut self, items: &'a [T]) -> &'a T {
        &items[self.below(items.len())]
    }
}

fn pool(rng: &mut Rng) -> Value {
    let choices: [fn(&mut Rng) -> Value; 24] = [
        |_| Value::Null,
        |_| json!(true),
        |_| json!(false),
        |_| json!("position"),
        |_| json!("velocity"),
        |_| json!("impedance"),
        |_| json!("spline"),
        |_| json!("lowpass"),
        |_| json!(""),
        |_| json!("motor 1"),
        |_| json!("m_1-A"),
        |_| json!(-1),
        |_| json!(-2),
        |_| json!(0),
        |_| json!(0.0),
        |_| json!(0.5),
        |_| json!(1),
        |_| json!(1.0),
        |_| json!(100),
        |_| json!(101),
        |_| json!([]),
        |_| json!({}),
        |r| json!(((r.next() % 2_000_000) as f64 - 1_000_000.0) / 7.0),
        |r| match r.below(4) {
            0 => json!(1e300),
            1 => json!(u64::MAX),
            2 => json!(9_223_372_036_854_775_807i64),
            _ => json!([1, {"a": null}]),
        },
    ];
    rng.pick(&choices)(rng)
}

/// Every pointer into `v` (the root excluded).
fn pointers(v: &Value, at: String, out: &mut Vec<String>) {
    match v {
        Value::Object(m) => {
            for (k, x) in m {
                let p = format!("{at}/{}", k.replace('~', "~0").replace('/', "~1"));
                out.push(p.clone());
                pointers(x, p, out);
            }
        }
        Value::Array(a) => {
            for (i, x) in a.iter().enumerate() {
                let p = format!("{at}/{i}");
                out.push(p.clone());
                pointers(x, p, out);
            }
        }
        _ => {}
    }
}

fn parent_and_key(ptr: &str) -> (&str, String) {
    let cut = ptr.rfind('/').unwrap();
    (
        &ptr[..cut],
        ptr[cut + 1..].replace("~1", "/").replace("~0", "~"),
    )
}

fn mutate(doc: &mut Value, rng: &mut Rng) {
    let mut ptrs = Vec::new();
    pointers(doc, String::new(), &mut ptrs);
    if ptrs.is_empty() {
        *doc = pool(rng);
        return;
    }
    let target = rng.pick(&ptrs).clone();
    match rng.below(4) {
        0 => {
            let (parent, key) = parent_and_key(&target);
            match doc.pointer_mut(parent) {
                Some(Value::Object(m)) => {
                    m.remove(&key);
                }
                Some(Value::Array(a)) => {
                    let i: usize = key.parse().unwrap();
                    if i < a.len() {
                        a.remove(i);
                    }
                }
                _ => {}
            }
        }
        1 => {
            let (parent, _) = parent_and_key(&target);
            if let Some(Value::Object(m)) = doc.pointer_mut(parent) {
                m.insert(format!("x_unknown_{}", rng.below(3)), pool(rng));
            }
        }
        _ => {
            if let Some(slot) = doc.pointer_mut(&target) {
                *slot = pool(rng);
            }
        }
    }
}

/// A valid variant: optional members dropped and numbers nudged within range.
fn vary(doc: &mut Value, rng: &mut Rng) {
    if let Value::Object(m) = doc {
        let keys: Vec<String> = m.keys().cloned().collect();
        for k in keys {
            if let Some(Value::Number(n)) = m.get(&k)
                && let Some(f) = n.as_f64()
                && n.is_f64()
                && rng.chance(30)
            {
                m.insert(k.clone(), json!(f * 0.5));
            }
            if let Some(x) = m.get_mut(&k) {
                vary(x, rng);
            }
        }
    }
}

/// JSON equality where numbers compare by value (`50` and `50.0` are equal).
fn same_json(a: &Value, b: &Value) -> bool {
    match (a, b) {
        (Value::Number(x), Value::Number(y)) => match (x.as_i64(), y.as_i64()) {
            (Some(x), Some(y)) => x == y,
            _ => x.as_f64() == y.as_f64(),
        },
        (Value::Array(x), Value::Array(y)) => {
            x.len() == y.len() && x.iter().zip(y).all(|(x, y)| same_json(x, y))
        }
        (Value::Object(x), Value::Object(y)) => {
            x.len() == y.len()
                && x.iter()
                    .all(|(k, v)| y.get(k).is_some_and(|w| same_json(v, w)))
        }
        _ => a == b,
    }
}

fn typed_verdict<T: WiaMessage>(text: &str) -> Result<Vec<(Rule, String)>, String> {
    match serde_json::from_str::<T>(text) {
        Ok(msg) => {
            // JSON -> type -> JSON keeps every member that was given.
            let back = serde_json::to_value(&msg).unwrap();
            let given: Value = serde_json::from_str(text).unwrap();
            assert!(
                same_json(&given, &back),
                "round trip changed {text}\ninto {back}"
            );
            Ok(msg
                .violations(None)
                .into_iter()
                .filter(|v| v.rule.level() == Level::Schema)
                .map(|v| (v.rule, v.pointer))
                .collect())
        }
        Err(e) => Err(e.to_string()),
    }
}

fn typed(kind: MessageKind, text: &str) -> Result<Vec<(Rule, String)>, String> {
    match kind {
        MessageKind::MotorCommand => typed_verdict::<MotorCommand>(text),
        MessageKind::MultiAxisCommand => typed_verdict::<MultiAxisCommand>(text),
        MessageKind::MotorFeedback => typed_verdict::<MotorFeedback>(text),
        MessageKind::Trajectory => typed_verdict::<Trajectory>(text),
        MessageKind::PidConfig => typed_verdict::<PidConfig>(text),
        MessageKind::SafetyLimits => typed_verdict::<SafetyLimits>(text),
        MessageKind::ControlModeConfig => typed_verdict::<ControlModeConfig>(text),
    }
}

/// Size and depth limits are not what this test compares.
fn unlimited() -> Validator {
    Validator::new()
        .max_depth(Validator::MAX_DEPTH_CEILING)
        .max_document_size(usize::MAX)
}

#[derive(Default)]
struct Tally {
    documents: usize,
    valid: usize,
    invalid: usize,
    unrepresentable: usize,
}

/// Compares the verdicts on one document; on a typed parse that succeeds,
/// the typed schema-level violations must be exactly jsonschema's.
fn compare(kind: MessageKind, value: &Value, tally: &mut Tally, what: &str) {
    let text = value.to_string();
    let schema = schema_validator(kind).unwrap();
    let schema_valid = schema.is_valid(value);
    tally.documents += 1;
    match typed(kind, &text) {
        Ok(found) => {
            let mut mine: Vec<(Rule, String)> = found;
            let report = unlimited().validate_schema_only(kind, &text);
            let mut theirs: Vec<(Rule, String)> = report
                .violations
                .into_iter()
                .map(|v| (v.rule, v.pointer))
                .collect();
            mine.sort();
            theirs.sort();
            assert_eq!(mine, theirs, "{kind} {what}: {text}");
            if schema_valid {
                tally.valid += 1;
            } else {
                tally.invalid += 1;
            }
        }
        Err(e) => {
            if schema_valid {
                assert!(
                    e.contains("does not fit in 64 bits"),
                    "{kind} {what}: schema-valid but typed parse failed: {e}: {text}"
                );
                tally.unrepresentable += 1;
                let r = unlimited().validate(kind, &text);
                assert_eq!(r.violations.len(), 1);
                assert_eq!(r.violations[0].rule, Rule::Unrepresentable);
            } else {
                tally.invalid += 1;
            }
        }
    }
}

/// Every fixture under the workspace's `fixtures/wia/` with its kind, or
/// `None` (saying so) in a packaged crate, which has no workspace around it.
fn load_fixtures() -> Option<Vec<(MessageKind, Value)>> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/wia");
    if !root.is_dir() {
        eprintln!(
            "skipped: {} does not exist (a packaged crate, outside the workspace)",
            root.display()
        );
        return None;
    }
    let mut out = Vec::new();
    for dir in ["valid", "invalid"] {
        for entry in std::fs::read_dir(root.join(dir)).unwrap() {
            let path = entry.unwrap().path();
            let text = std::fs::read_to_string(&path).unwrap();
            let Ok(value) = serde_json::from_str::<Value>(&text) else {
                continue;
            };
            if let Ok(Some(kind)) = MessageKind::infer(&text) {
                out.push((kind, value));
            }
        }
    }
    out.sort_by_key(|(k, v)| (k.name(), v.to_string()));
    Some(out)
}

#[test]
fn typed_path_and_json_schema_agree() {
    let Some(fixtures) = load_fixtures() else {
        return;
    };
    let mut tally = Tally::default();
    for (kind, value) in &fixtures {
        for k in MessageKind::ALL {
            // Each fixture against every kind's schema: mismatched kinds are
            // a rich source of type and required errors.
            compare(
                k,
                value,
                &mut tally,
                if k == *kind {
                    "fixture"
                } else {
                    "fixture as other kind"
                },
            );
        }
    }
    let valid_bases: Vec<&(MessageKind, Value)> = fixtures
        .iter()
        .filter(|(k, v)| schema_validator(*k).unwrap().is_valid(v))
        .collect();
    let mut rng = Rng(0x6D6F_746F_7277_6972);
    for round in 0..12_000 {
        let (kind, base) = rng.pick(&valid_bases);
        let mut doc = base.clone();
        vary(&mut doc, &mut rng);
        let mutations = if round % 4 == 0 { 0 } else { 1 + rng.below(3) };
        for _ in 0..mutations {
            mutate(&mut doc, &mut rng);
        }
        compare(*kind, &doc, &mut tally, &format!("generated #{round}"));
    }
    eprintln!(
        "differential: {} documents, {} schema-valid, {} schema-invalid, {} unrepresentable",
        tally.documents, tally.valid, tally.invalid, tally.unrepresentable
    );
    assert!(tally.documents >= 10_000);
    assert!(
        tally.valid >= 3_000,
        "too few valid documents: {}",
        tally.valid
    );
    assert!(
        tally.invalid >= 3_000,
        "too few invalid documents: {}",
        tally.invalid
    );
}

#[test]
fn metadata_is_unconstrained_but_must_be_an_object() {
    let base: Map<String, Value> = serde_json::from_value(json!({
        "motor_id": "m", "timestamp": 0, "control_mode": "disabled", "setpoint": 0
    }))
    .unwrap();
    for (metadata, valid) in [
        (json!({}), true),
        (json!({"a": [null, 1e300, {"b": "c"}]}), true),
        (json!([]), false),
        (json!("x"), false),
        (Value::Null, false),
    ] {
        let mut doc = base.clone();
        doc.insert("metadata".into(), metadata);
        let doc = Value::Object(doc);
        let mut tally = Tally::default();
        compare(MessageKind::MotorCommand, &doc, &mut tally, "metadata");
        assert_eq!(tally.valid == 1, valid, "{doc}");
    }
}
