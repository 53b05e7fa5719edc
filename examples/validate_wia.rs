//! Validate WIA messages and print every violation.
//!
//! ```sh
//! cargo run --example validate_wia
//! ```
//!
//! `validate_auto` infers the kind (here a MotorCommand, then a
//! SafetyLimits) and judges the document by its JSON Schema and WIA §10's
//! semantic rules; each violation names the rule, the JSON pointer and the
//! offending value with the limit it broke. To judge a document you know
//! the kind of, `Validator::validate(MessageKind::MotorCommand, json)`; to
//! get a typed message, `Validator::parse::<MotorCommand>(json)`.

use std::io::Write;

use motorwire_wia::{MotorCommand, Validator};

const DOCUMENTS: [&str; 3] = [
    // Valid: the WIA document's position command.
    r#"{"motor_id":"joint_1","timestamp":1704067200000,"control_mode":"position","setpoint":90.0,"velocity_limit":180.0}"#,
    // Three problems at once: every one is reported, not only the first.
    r#"{"motor_id":"joint 1","timestamp":1704067200000,"control_mode":"position","setpoint":90.0,"velocity_limit":-5,"priority":120}"#,
    // Valid to the schema, but a soft limit outside its hard limit (§10).
    r#"{"motor_id":"joint_1","position_limits":{"min":-90,"max":90,"soft_min":-100,"soft_max":80},"velocity_limits":{"max_velocity":120},"torque_limits":{"continuous_torque":10,"peak_torque":25}}"#,
];

fn run(out: &mut dyn Write) -> Result<bool, Box<dyn std::error::Error>> {
    let validator = Validator::new();
    let mut all_valid = true;
    for (i, json) in DOCUMENTS.iter().enumerate() {
        let report = validator.validate_auto(json);
        let kind = report
            .kind
            .map_or_else(|| "unknown kind".to_owned(), |k| k.to_string());
        if report.is_valid() {
            writeln!(out, "document {}: {kind}: valid", i + 1)?;
        } else {
            all_valid = false;
            writeln!(out, "document {}: {kind}: invalid", i + 1)?;
            for v in &report.violations {
                writeln!(out, "  {}: {} [{}]", v.pointer, v.message, v.rule)?;
            }
        }
    }
    // The typed message of a valid one.
    let command: MotorCommand = validator.parse(DOCUMENTS[0])?;
    writeln!(
        out,
        "parsed: {} to {} at up to {:?}",
        command.motor_id, command.setpoint, command.velocity_limit
    )?;
    Ok(all_valid)
}

fn main() -> std::process::ExitCode {
    match run(&mut std::io::stdout()) {
        // Invalid documents are what this example shows: it succeeds.
        Ok(_) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("validate_wia: {e}");
            std::process::ExitCode::FAILURE
        }
    }
}

#[cfg(test)]
mod tests {
    /// The output, exactly.
    const EXPECTED: &str = r##"document 1: motor-command: valid
document 2: motor-command: invalid
  /motor_id: "joint 1" does not match "^[a-zA-Z0-9_-]+$" [pattern]
  /velocity_limit: -5 is less than the minimum of 0 [minimum]
  /priority: 120 is greater than the maximum of 100 [maximum]
document 3: safety-limits: invalid
  /position_limits/min: min (-90) must be <= soft_min (-100) [position-limits-order]
parsed: joint_1 to 90 at up to Some(180.0)
"##;

    #[test]
    fn prints_each_violation() {
        let mut out = Vec::new();
        assert_eq!(super::run(&mut out).ok(), Some(false));
        assert_eq!(String::from_utf8_lossy(&out), EXPECTED);
    }
}
