//! Every fixture under `fixtures/wia/`: the valid ones pass, each invalid one
//! yields exactly the violations `fixtures/wia/invalid.expected.json` lists.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing
)]

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use motorwire_wia::{Level, MessageKind, Rule, Validator};
use serde_json::Value;

/// The workspace's `fixtures/wia/`, or `None` (saying so) in a packaged
/// crate, which has no workspace around it.
fn workspace_fixtures() -> Option<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/wia");
    if dir.is_dir() {
        Some(dir)
    } else {
        eprintln!(
            "skipped: {} does not exist (a packaged crate, outside the workspace)",
            dir.display()
        );
        None
    }
}

fn files(dir: &Path) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "json"))
        .collect();
    v.sort();
    v
}

#[test]
fn valid_fixtures_have_no_violations_by_kind_and_by_auto() {
    let Some(fixtures) = workspace_fixtures() else {
        return;
    };
    let v = Validator::new();
    let files = files(&fixtures.join("valid"));
    assert!(files.len() >= 9, "{files:?}");
    for f in files {
        let text = std::fs::read_to_string(&f).unwrap();
        let auto = v.validate_auto(&text);
        assert!(auto.is_valid(), "{}: {auto}", f.display());
        let kind = auto.kind.unwrap();
        assert!(v.validate(kind, &text).is_valid());
        assert!(v.validate_schema_only(kind, &text).is_valid());
        // Every member of the document's examples is one its schema names.
        let strict = v.clone().deny_unknown_members(true);
        assert!(
            strict.validate(kind, &text).is_valid(),
            "{}: {}",
            f.display(),
            strict.validate(kind, &text)
        );
    }
}

#[test]
fn document_examples_are_inferred_as_their_kinds() {
    let Some(fixtures) = workspace_fixtures() else {
        return;
    };
    let v = Validator::new();
    for (file, kind) in [
        (
            "doc-2.2-control-mode-config.json",
            MessageKind::ControlModeConfig,
        ),
        (
            "doc-3.2-multi-axis-command.json",
            MessageKind::MultiAxisCommand,
        ),
        ("doc-4.2-motor-feedback.json", MessageKind::MotorFeedback),
        ("doc-5.2-trajectory.json", MessageKind::Trajectory),
        ("motor-command.json", MessageKind::MotorCommand),
        ("pid-config.json", MessageKind::PidConfig),
        ("safety-limits.json", MessageKind::SafetyLimits),
    ] {
        let text = std::fs::read_to_string(fixtures.join("valid").join(file)).unwrap();
        assert_eq!(v.validate_auto(&text).kind, Some(kind), "{file}");
    }
}

/// The validator `motorwire validate` would judge with, given `args`: it
/// refuses unknown members unless told otherwise.
fn validator_for(args: Option<&Value>) -> Validator {
    let mut v = Validator::new().deny_unknown_members(true);
    let Some(args) = args else { return v };
    let args: Vec<&str> = args
        .as_array()
        .unwrap()
        .iter()
        .map(|a| a.as_str().unwrap())
        .collect();
    for pair in args.chunks(2) {
        match pair[0] {
            "--now" => v = v.now_ms(pair[1].parse().unwrap()),
            "--max-size" => v = v.max_document_size(pair[1].parse().unwrap()),
            "--max-depth" => v = v.max_depth(pair[1].parse().unwrap()),
            "--allow-unknown" => v = v.deny_unknown_members(false),
            other => panic!("unknown fixture argument {other}"),
        }
    }
    v
}

#[test]
fn invalid_fixtures_yield_exactly_their_expected_violations() {
    let Some(fixtures) = workspace_fixtures() else {
        return;
    };
    let manifest: Value = serde_json::from_str(
        &std::fs::read_to_string(fixtures.join("invalid.expected.json")).unwrap(),
    )
    .unwrap();
    let manifest = manifest.as_object().unwrap();
    let files = files(&fixtures.join("invalid"));
    assert!(files.len() >= 40);
    assert_eq!(
        files.len(),
        manifest.len(),
        "every invalid fixture has an expectation"
    );
    let mut covered = BTreeSet::new();
    for f in files {
        let name = f.file_name().unwrap().to_str().unwrap();
        let expect = &manifest[name];
        let text = std::fs::read_to_string(&f).unwrap();
        let v = validator_for(expect.get("args"));
        let report = match expect["kind"].as_str() {
            Some(kind) => {
                let kind = MessageKind::from_name(kind).unwrap();
                let by_kind = v.validate(kind, &text);
                let auto = v.validate_auto(&text);
                assert_eq!(
                    auto.violations, by_kind.violations,
                    "{name}: auto and {kind} disagree"
                );
                // Size and depth are judged before the kind can be told.
                if auto.kind.is_some() {
                    assert_eq!(auto.kind, Some(kind), "{name}: auto must choose {kind}");
                }
                by_kind
            }
            None => v.validate_auto(&text),
        };
        let mut got: Vec<(String, String)> = report
            .violations
            .iter()
            .map(|x| (x.rule.name().to_owned(), x.pointer.clone()))
            .collect();
        let mut want: Vec<(String, String)> = expect["violations"]
            .as_array()
            .unwrap()
            .iter()
            .map(|x| {
                (
                    x["rule"].as_str().unwrap().to_owned(),
                    x["pointer"].as_str().unwrap().to_owned(),
                )
            })
            .collect();
        got.sort();
        want.sort();
        assert_eq!(got, want, "{name}: {report}");
        for x in &report.violations {
            assert!(!x.message.is_empty());
            covered.insert(x.rule);
        }
    }
    // Every rule a JSON document can break has a fixture. `non-finite` cannot
    // be written in JSON (it is tested on values built in code) and `schema`
    // would need a keyword motorwire's schemas do not use.
    for rule in Rule::ALL {
        if matches!(rule, Rule::NonFinite | Rule::SchemaOther) {
            continue;
        }
        assert!(covered.contains(rule), "no invalid fixture breaks {rule}");
    }
    assert!(covered.iter().any(|r| r.level() == Level::Document));
}
