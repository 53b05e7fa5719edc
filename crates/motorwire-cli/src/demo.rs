//! `motorwire demo`: the WIA document's example messages, validated one by
//! one, then a broken command and every rule it breaks.

use motorwire_wia::{MessageKind, Rule, Validator};

/// Walk through the WIA document's example messages.
///
/// Exits 0 only if every expectation held: each example is valid and the
/// broken command is refused for exactly the expected reasons.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {}

struct Example {
    title: &'static str,
    json: &'static str,
}

const EXAMPLES: [Example; 7] = [
    Example {
        title: "§2.2 control-mode configuration",
        json: include_str!("../../../fixtures/wia/valid/doc-2.2-control-mode-config.json"),
    },
    Example {
        title: "§3.2 multi-axis command (3-joint arm)",
        json: include_str!("../../../fixtures/wia/valid/doc-3.2-multi-axis-command.json"),
    },
    Example {
        title: "§4.2 motor feedback",
        json: include_str!("../../../fixtures/wia/valid/doc-4.2-motor-feedback.json"),
    },
    Example {
        title: "§5.2 trajectory (pick and place)",
        json: include_str!("../../../fixtures/wia/valid/doc-5.2-trajectory.json"),
    },
    Example {
        title: "§3.1 motor command (from §3.2's shoulder_pitch)",
        json: include_str!("../../../fixtures/wia/valid/motor-command.json"),
    },
    Example {
        title: "§6 PID configuration (from §3.2's elbow gains)",
        json: include_str!("../../../fixtures/wia/valid/pid-config.json"),
    },
    Example {
        title: "§7 safety limits (motorwire's, shoulder_pitch)",
        json: include_str!("../../../fixtures/wia/valid/safety-limits.json"),
    },
];

/// A command an AI controller might get wrong in three ways at once.
const BROKEN: &str = r#"{
  "motor_id": "shoulder_pitch",
  "timestamp": 1704067200000,
  "control_mode": "position",
  "setpoint": 120.0,
  "velocity_limit": 150.0,
  "pid_gains": {"kp": 0, "ki": 0.1, "kd": 2.5},
  "safety_limits": {"min_position": -90, "max_position": 90, "max_velocity": 120}
}"#;

const BROKEN_EXPECTED: [(Rule, &str); 3] = [
    (Rule::KpPositive, "/pid_gains/kp"),
    (Rule::SetpointWithinLimits, "/setpoint"),
    (Rule::LimitWithinSafety, "/velocity_limit"),
];

pub(crate) fn run(_args: &Args) -> u8 {
    let validator = Validator::new();
    let mut held = true;
    println!(
        "motorwire demo: the WIA Phase 1 example messages (and motorwire's for the kinds the document shows only as schemas)\n"
    );
    for (i, ex) in EXAMPLES.iter().enumerate() {
        let report = validator.validate_auto(ex.json);
        let kind = report.kind.map_or("unknown kind", MessageKind::name);
        let mark = if report.is_valid() { "ok  " } else { "FAIL" };
        println!(
            "[{}/{}] {mark} {:<45} as {kind}",
            i + 1,
            EXAMPLES.len(),
            ex.title
        );
        for v in &report.violations {
            println!("          {v}");
        }
        held &= report.is_valid();
    }

    println!("\nA broken command:\n{BROKEN}\n");
    let report = validator.validate(MessageKind::MotorCommand, BROKEN);
    println!("refused with {} violation(s):", report.violations.len());
    for v in &report.violations {
        println!("  {:<16} [{}] {}", v.pointer, v.rule, v.message);
    }
    let mut found: Vec<(Rule, &str)> = report
        .violations
        .iter()
        .map(|v| (v.rule, v.pointer.as_str()))
        .collect();
    found.sort();
    let mut expected = BROKEN_EXPECTED.to_vec();
    expected.sort();
    let broken_ok = found == expected;
    held &= broken_ok;

    println!();
    if held {
        println!(
            "summary: {} examples valid, the broken command refused for the {} expected reasons: all expectations held",
            EXAMPLES.len(),
            BROKEN_EXPECTED.len()
        );
        0
    } else {
        println!("summary: an expectation did not hold (see FAIL above)");
        1
    }
}
