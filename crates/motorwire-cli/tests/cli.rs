//! The `motorwire` binary, run as a user runs it.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing
)]

mod common;

use std::process::Output;

use common::root;

use serde_json::Value;

fn motorwire(args: &[&str], stdin: Option<&[u8]>) -> Output {
    common::run(args, stdin.unwrap_or_default())
}

fn fixture_files(dir: &str) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(root().join(dir))
        .unwrap()
        .map(|e| format!("{dir}/{}", e.unwrap().file_name().to_str().unwrap()))
        .filter(|p| p.ends_with(".json"))
        .collect();
    v.sort();
    v
}

fn json_lines(out: &Output) -> Vec<Value> {
    String::from_utf8(out.stdout.clone())
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

#[test]
fn every_valid_fixture_passes_auto() {
    let files = fixture_files("fixtures/wia/valid");
    let mut args = vec!["validate", "--kind", "auto"];
    args.extend(files.iter().map(String::as_str));
    let out = motorwire(&args, None);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stdout)
    );
    let text = String::from_utf8(out.stdout).unwrap();
    assert_eq!(text.lines().count(), files.len());
    assert!(text.lines().all(|l| l.ends_with("(auto): valid")), "{text}");
}

#[test]
fn every_invalid_fixture_exits_1_naming_its_pointer_and_rule() {
    let manifest: Value = serde_json::from_str(
        &std::fs::read_to_string(root().join("fixtures/wia/invalid.expected.json")).unwrap(),
    )
    .unwrap();
    for file in fixture_files("fixtures/wia/invalid") {
        let name = file.rsplit('/').next().unwrap();
        let expect = &manifest[name];
        let kind = expect["kind"].as_str().unwrap_or("auto");
        let mut args = vec!["validate", "--kind", kind, "--format", "json"];
        if let Some(extra) = expect.get("args") {
            args.extend(
                extra
                    .as_array()
                    .unwrap()
                    .iter()
                    .map(|a| a.as_str().unwrap()),
            );
        }
        args.push(&file);
        let out = motorwire(&args, None);
        assert_eq!(out.status.code(), Some(1), "{file}");
        let lines = json_lines(&out);
        assert_eq!(lines.len(), 1);
        assert_eq!(lines[0]["file"], file.as_str());
        assert_eq!(lines[0]["valid"], false);
        let mut got: Vec<(String, String)> = lines[0]["errors"]
            .as_array()
            .unwrap()
            .iter()
            .map(|e| {
                (
                    e["rule"].as_str().unwrap().into(),
                    e["pointer"].as_str().unwrap().into(),
                )
            })
            .collect();
        let mut want: Vec<(String, String)> = expect["violations"]
            .as_array()
            .unwrap()
            .iter()
            .map(|e| {
                (
                    e["rule"].as_str().unwrap().into(),
                    e["pointer"].as_str().unwrap().into(),
                )
            })
            .collect();
        got.sort();
        want.sort();
        assert_eq!(got, want, "{file}");

        // The text format names the same pointers and rules.
        let mut text_args: Vec<&str> = args
            .iter()
            .filter(|a| **a != "json" && **a != "--format")
            .copied()
            .collect();
        text_args.retain(|a| *a != "--format");
        let out = motorwire(&text_args, None);
        assert_eq!(out.status.code(), Some(1), "{file}");
        let text = String::from_utf8(out.stdout).unwrap();
        for (rule, pointer) in &want {
            let pointer = if pointer.is_empty() {
                "(document)"
            } else {
                pointer
            };
            assert!(
                text.contains(&format!("  {pointer}  [{rule}]  ")),
                "{file}: {text}"
            );
        }
    }
}

#[test]
fn json_lines_from_stdin_report_line_numbers() {
    let input =
        b"{\"motor_id\":\"m\",\"timestamp\":1,\"control_mode\":\"position\",\"setpoint\":1}\n\n\
{\"motor_id\":\"m\",\"timestamp\":1,\"control_mode\":\"position\",\"setpoint\":\"x\"}\nnot json\n";
    let out = motorwire(
        &["validate", "--lines", "--format", "json", "-"],
        Some(input),
    );
    assert_eq!(out.status.code(), Some(1));
    let lines = json_lines(&out);
    assert_eq!(lines.len(), 3);
    assert_eq!(
        lines[0],
        serde_json::json!({"file": "-", "line": 1, "kind": "motor-command", "auto": true, "valid": true, "errors": []})
    );
    assert_eq!(lines[1]["line"], 3);
    assert_eq!(
        lines[1]["errors"],
        serde_json::json!([{"pointer": "/setpoint", "rule": "type", "message": "\"x\" is not of type \"number\""}])
    );
    assert_eq!(lines[2]["line"], 4);
    assert_eq!(lines[2]["kind"], Value::Null);
    assert_eq!(lines[2]["errors"][0]["rule"], "json-syntax");
}

#[test]
fn explicit_kind_omits_auto_and_schema_only_skips_semantics() {
    let file = "fixtures/wia/invalid/kp-positive-zero.json";
    let out = motorwire(
        &[
            "validate",
            "--kind",
            "motor-command",
            "--format",
            "json",
            file,
        ],
        None,
    );
    assert_eq!(out.status.code(), Some(1));
    let line = &json_lines(&out)[0];
    assert!(line.get("auto").is_none());
    assert!(line.get("line").is_none());
    let out = motorwire(&["validate", "--schema-only", file], None);
    assert_eq!(out.status.code(), Some(0));
    assert_eq!(
        String::from_utf8(out.stdout).unwrap(),
        format!("{file}: motor-command (auto): valid\n")
    );
}

#[test]
fn usage_and_io_errors_exit_2() {
    let out = motorwire(&["validate", "no/such/file.json"], None);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("no/such/file.json"));
    // The other files are still judged.
    let out = motorwire(
        &[
            "validate",
            "no/such/file.json",
            "fixtures/wia/valid/motor-command.json",
        ],
        None,
    );
    assert_eq!(out.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&out.stdout)
            .contains("motor-command.json: motor-command (auto): valid")
    );
    assert_eq!(
        motorwire(&["validate", "--kind", "bogus", "x"], None)
            .status
            .code(),
        Some(2)
    );
    assert_eq!(motorwire(&["validate"], None).status.code(), Some(2));
    assert_eq!(
        motorwire(&["validate", "--max-depth", "500", "-"], None)
            .status
            .code(),
        Some(2)
    );
}

#[test]
fn hostile_input_is_refused_without_a_crash() {
    // A million brackets: refused by depth before any parser sees them.
    let deep = "[".repeat(1_000_000);
    let out = motorwire(
        &["validate", "--max-size", "2000000", "--format", "json", "-"],
        Some(deep.as_bytes()),
    );
    assert_eq!(out.status.code(), Some(1));
    assert_eq!(
        json_lines(&out)[0]["errors"][0]["rule"],
        "document-too-deep"
    );
    // Over the size limit, from stdin, without reading it all into memory.
    let big = vec![b' '; 3 << 20];
    let out = motorwire(&["validate", "--format", "json", "-"], Some(&big));
    assert_eq!(out.status.code(), Some(1));
    assert_eq!(
        json_lines(&out)[0]["errors"][0]["rule"],
        "document-too-large"
    );
    // Not UTF-8.
    let out = motorwire(
        &["validate", "--format", "json", "-"],
        Some(b"{\"motor_id\": \"\xff\"}"),
    );
    assert_eq!(out.status.code(), Some(1));
    assert_eq!(json_lines(&out)[0]["errors"][0]["rule"], "json-syntax");
}

#[test]
fn demo_holds_every_expectation_and_plots_the_feedback() {
    let svg = std::env::temp_dir().join(format!("motorwire-demo-{}.svg", std::process::id()));
    let out = motorwire(&["demo", "--svg", svg.to_str().unwrap()], None);
    let text = String::from_utf8(out.stdout).unwrap();
    assert_eq!(out.status.code(), Some(0), "{text}");
    assert_eq!(text.matches("] ok   ").count(), 17, "{text}");
    assert!(
        text.contains("refused (refused): wrist_flex: setpoint 120 is outside max_position"),
        "{text}"
    );
    assert!(text.contains("SO-101: elbow_flex to 40°"), "{text}");
    assert!(text.contains("trajectory: the elbow"), "{text}");
    assert!(
        text.contains(
            "turning at 150: true; the deadman stopped it 200 ms after the last command: true"
        ),
        "{text}"
    );
    assert!(
        text.contains("compact command: close the gripper to 45°"),
        "{text}"
    );
    assert!(
        text.contains("refused (refused): elbow: setpoint 170 is outside max_position"),
        "{text}"
    );
    assert!(text.contains("refused (emergency_stop_latched)"), "{text}");
    assert!(
        text.contains("joints stopped and deactivated: true"),
        "{text}"
    );
    assert!(text.contains("all expectations held"), "{text}");
    let plot = std::fs::read_to_string(&svg).unwrap();
    let _ = std::fs::remove_file(&svg);
    // Drawn as `motorwire plot` draws a recording: a panel per device the
    // demo moves, in its units (the turntable as the speed it was told,
    // in the controller's units), the targets and the limit bands in the
    // key, every step and event numbered with its line in the key.
    for panel in [
        "shoulder_pitch: position (°)",
        "shoulder_pitch: velocity (°/s)",
        "shoulder_roll: position (°)",
        "elbow: position (°)",
        "elbow: velocity (°/s)",
        "gripper_axis: position (°)",
        "elbow_flex: position (°)",
        "shoulder_lift: position (°)",
        "turntable: speed (controller units, ±400)",
        "time (s)",
        "measured (feedback)",
        "target",
        "beyond the limits in the bus map",
    ] {
        assert!(plot.contains(panel), "{panel} not in the plot");
    }
    assert!(
        !plot.contains("lower_arm_actuator"),
        "an Orion motor the demo never moves"
    );
    for mark in [
        "s  step 1: WIA §3.2 multi-axis example",
        "s  step 17: compact command: open the gripper to 0°",
        "wrist_flex refused: outside_limit",
        "s  emergency stop (input)",
        "s  released",
        "s  deadman: turntable stopped, no command within its timeout",
        "elbow refused: outside_limit",
        "elbow refused: emergency_stop_latched",
    ] {
        assert!(plot.contains(mark), "{mark} not in the plot's key");
    }
}

/// The default build has no fleet (the `fleet` feature, Zenoh): `--zenoh`
/// is answered at once, before the map or the bus is opened, with exit 2
/// and the command that builds the fleet in; `--help` says the same.
#[cfg(not(feature = "fleet"))]
#[test]
fn without_the_fleet_feature_zenoh_exits_2_naming_the_build_command() {
    const SAID: &str = "motorwire bridge: --zenoh: this motorwire was built without the fleet (the `fleet` feature): build it with `cargo build --release -p motorwire-cli --features fleet` in the repository, or install it with `cargo install --path crates/motorwire-cli --features fleet`\n";
    for map in ["fixtures/maps/demo-arm.toml", "no/such/map.toml"] {
        let out = motorwire(
            &[
                "bridge", "--map", map, "--bus", "sim", "--zenoh", "--robot", "arm1",
            ],
            Some(b"{\"emergency_stop\":true}\n"),
        );
        assert_eq!(out.status.code(), Some(2), "--map {map}");
        assert_eq!(String::from_utf8(out.stderr).unwrap(), SAID, "--map {map}");
        assert_eq!(String::from_utf8(out.stdout).unwrap(), "", "--map {map}");
    }
    let help = motorwire(&["bridge", "--help"], None);
    assert_eq!(help.status.code(), Some(0));
    let help = String::from_utf8(help.stdout).unwrap();
    assert!(
        help.contains("Not in this build: it was built without the fleet (the `fleet` feature). Build it with `cargo build --release -p motorwire-cli --features fleet` in the repository, or install it with `cargo install --path crates/motorwire-cli --features fleet`"),
        "{help}"
    );
}

#[test]
fn a_misspelled_member_is_invalid_unless_allowed_and_schema_only_takes_it() {
    let file = "fixtures/wia/invalid/unknown-member-typo.json";
    let out = motorwire(&["validate", file], None);
    assert_eq!(out.status.code(), Some(1));
    let why = "(motorwire takes unknown members only when told to: `Validator::lenient`, `--allow-unknown-members`, `validate --allow-unknown`)";
    assert_eq!(
        String::from_utf8(out.stdout).unwrap(),
        format!(
            "{file}: motor-command (auto): invalid, 2 violation(s)\n  /velocity_limt  [unknown-member]  \"velocity_limt\" is not a member motor-command has here; did you mean velocity_limit? {why}\n  /safety_limits/max_positon  [unknown-member]  \"max_positon\" is not a member motor-command has here; did you mean max_position? {why}\n"
        )
    );
    for args in [
        &["validate", "--allow-unknown", file][..],
        &["validate", "--schema-only", file][..],
    ] {
        let out = motorwire(args, None);
        assert_eq!(out.status.code(), Some(0), "{args:?}");
        assert_eq!(
            String::from_utf8(out.stdout).unwrap(),
            format!("{file}: motor-command (auto): valid\n")
        );
    }
}

#[test]
fn with_now_a_timestamp_further_ahead_than_the_bridges_skew_is_stale() {
    let dir = std::env::temp_dir().join(format!("mw-ahead-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("ahead.json");
    // An hour ahead of --now: WIA allows it, the bridge (5 min) does not.
    std::fs::write(
        &file,
        r#"{"motor_id":"m","timestamp":1704070800000,"control_mode":"position","setpoint":1}"#,
    )
    .unwrap();
    let path = file.display().to_string();
    let out = motorwire(&["validate", "--now", "1704067200000", &path], None);
    assert_eq!(out.status.code(), Some(1));
    assert_eq!(
        String::from_utf8(out.stdout).unwrap(),
        format!(
            "{path}: motor-command (auto): invalid, 1 violation(s)\n  /timestamp  [timestamp-stale]  timestamp 1704070800000 is 3600000 ms ahead of now (1704067200000); at most 300000 ms is tolerated (the bridge's clock skew)\n"
        )
    );
    for args in [
        &[
            "validate",
            "--now",
            "1704067200000",
            "--max-age",
            "0",
            &path,
        ][..],
        &[
            "validate",
            "--now",
            "1704067200000",
            "--max-age",
            "3600000",
            &path,
        ][..],
        &["validate", &path][..],
    ] {
        let out = motorwire(args, None);
        assert_eq!(out.status.code(), Some(0), "{args:?}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// `motorwire validate` lists the first 100 violations and counts the rest
/// (issue 58 part 3): before, a 1 MiB line of `{}` waypoints printed
/// 700,000 of them.
#[test]
fn validate_lists_a_hundred_violations_and_counts_the_rest() {
    let doc = format!(
        r#"{{"trajectory_id":"t","motor_id":"elbow","waypoints":[{}],"timing":{{}}}}"#,
        vec!["{}"; 5_000].join(",")
    );
    let out = motorwire(&["validate", "--format", "json", "-"], Some(doc.as_bytes()));
    assert_eq!(out.status.code(), Some(1));
    let lines = json_lines(&out);
    assert_eq!(lines[0]["errors"].as_array().unwrap().len(), 100);
    assert_eq!(lines[0]["more_errors"], 9_900);
    let out = motorwire(&["validate", "-"], Some(doc.as_bytes()));
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(
        text.starts_with("-: trajectory (auto): invalid, 10000 violation(s)\n"),
        "{text}"
    );
    assert!(text.ends_with("\n  and 9900 more, not listed\n"), "{text}");
    assert_eq!(text.lines().count(), 102);
}

/// Found by a new user (issue 59 part 1): the library, `validate`,
/// `translate` and the bridge read the same line three ways (a misspelled
/// member taken by two of them, `stream` refused by one, a timestamp in
/// seconds passed by the library, NaN refused without naming it). Each line
/// here is judged the same by all four, naming the same rule.
#[test]
fn the_library_validate_translate_and_the_bridge_read_a_line_alike() {
    let now = common::now_ms();
    let line = |rest: &str| {
        format!(
            r#"{{"motor_id":"elbow","timestamp":{now},"control_mode":"velocity","setpoint":10{rest}}}"#
        )
    };
    let multi = |rest: &str| {
        format!(
            r#"{{"command_id":"tick","timestamp":{now},"motors":[{{"motor_id":"elbow","control_mode":"position","setpoint":10}}]{rest}}}"#
        )
    };
    // (line, taken, the rule or words of its refusal)
    let cases: Vec<(String, bool, &str)> = vec![
        (line(""), true, ""),
        (line(r#","stream":true"#), true, ""),
        (line(r#","velocity_limt":5"#), false, "unknown-member"),
        (line(r#","stream":"yes""#), false, "stream is \"yes\""),
        (
            format!(
                r#"{{"motor_id":"elbow","timestamp":{},"control_mode":"velocity","setpoint":10}}"#,
                now / 1000
            ),
            false,
            "timestamp-unit",
        ),
        (
            line("").replace("10}", "NaN}"),
            false,
            "NaN is not a JSON number",
        ),
        // A multi-axis command's stream: a policy's tick in one line.
        (multi(r#","stream":true"#), true, ""),
        (multi(r#","stream":2"#), false, "stream is 2"),
        (
            multi(r#","stream":true,"sync_mode":"sequential""#),
            false,
            "sync_mode sequential waits for each axis to arrive",
        ),
        (
            line(r#","stream":true,"stream":false"#),
            false,
            "stream appears 2 times",
        ),
    ];
    let input: String = cases.iter().map(|(l, ..)| format!("{l}\n")).collect();
    // The library.
    let validator = motorwire_wia::Validator::new();
    for (l, taken, why) in &cases {
        match validator.parse_any(l) {
            Ok(_) => assert!(*taken, "the library took {l}"),
            Err(e) => {
                assert!(!taken, "the library refused {l}: {e}");
                let said = serde_json::to_string(e.violations()).unwrap();
                assert!(
                    said.contains(&why.replace('"', "\\\"")) || said.contains(why),
                    "the library on {l}: {said}"
                );
            }
        }
    }
    // motorwire validate --lines --now.
    let file = std::env::temp_dir().join(format!(
        "motorwire-one-reading-{}.jsonl",
        std::process::id()
    ));
    std::fs::write(&file, &input).unwrap();
    let now_arg = now.to_string();
    let out = common::run(
        &[
            "validate",
            "--lines",
            "--format",
            "json",
            "--now",
            &now_arg,
            file.to_str().unwrap(),
        ],
        b"",
    );
    let _ = std::fs::remove_file(&file);
    let reports: Vec<serde_json::Value> = String::from_utf8_lossy(&out.stdout)
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(reports.len(), cases.len(), "{reports:?}");
    for ((l, taken, why), r) in cases.iter().zip(&reports) {
        assert_eq!(r["valid"], *taken, "validate on {l}: {r}");
        assert!(
            r.to_string().contains(&why.replace('"', "\\\"")),
            "validate on {l}: {r}"
        );
    }
    // motorwire translate.
    let out = common::run(
        &[
            "translate",
            "--map",
            "fixtures/maps/demo-arm.toml",
            "--to",
            "irpc-v2.0",
        ],
        input.as_bytes(),
    );
    let results: Vec<serde_json::Value> = String::from_utf8_lossy(&out.stdout)
        .lines()
        .filter_map(|l| serde_json::from_str::<serde_json::Value>(l).ok())
        .filter(|v| v.get("ok").is_some())
        .collect();
    assert_eq!(results.len(), cases.len(), "{results:?}");
    // The bridge, on the simulated bus.
    let out = common::run(
        &common::sim_bridge(&["--feedback-hz", "0"]),
        input.as_bytes(),
    );
    let mut answers: Vec<serde_json::Value> = String::from_utf8_lossy(&out.stdout)
        .lines()
        .filter_map(|l| serde_json::from_str::<serde_json::Value>(l).ok())
        .filter(|v| v.get("ok").is_some() && v.get("line").is_some())
        .collect();
    answers.sort_by_key(|v| v["line"].as_u64());
    assert_eq!(answers.len(), cases.len(), "{answers:?}");
    for (who, said) in [("translate", &results), ("the bridge", &answers)] {
        for ((l, taken, why), r) in cases.iter().zip(said.iter()) {
            // A velocity line is not an iRPC move: translate refuses it for
            // the joint's dialect, not for how it reads.
            let read_ok = r["ok"] == true
                || !["invalid", "json-syntax"].contains(&r["error"]["rule"].as_str().unwrap_or(""))
                    && r["error"]["kind"] != "invalid";
            assert_eq!(read_ok, *taken, "{who} on {l}: {r}");
            assert!(
                r.to_string().contains(&why.replace('"', "\\\"")),
                "{who} on {l}: {r}"
            );
        }
    }
}
