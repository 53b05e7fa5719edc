//! The embedded JSON Schemas, compiled once per process.

use std::sync::OnceLock;

use jsonschema::error::ValidationErrorKind;
use serde_json::Value;

use crate::{MessageKind, Rule, Violation};

type Compiled = Result<jsonschema::Validator, String>;

fn compiled(kind: MessageKind) -> &'static Compiled {
    static MOTOR_COMMAND: OnceLock<Compiled> = OnceLock::new();
    static MULTI_AXIS_COMMAND: OnceLock<Compiled> = OnceLock::new();
    static MOTOR_FEEDBACK: OnceLock<Compiled> = OnceLock::new();
    static TRAJECTORY: OnceLock<Compiled> = OnceLock::new();
    static PID_CONFIG: OnceLock<Compiled> = OnceLock::new();
    static SAFETY_LIMITS: OnceLock<Compiled> = OnceLock::new();
    static CONTROL_MODE_CONFIG: OnceLock<Compiled> = OnceLock::new();
    let cell = match kind {
        MessageKind::MotorCommand => &MOTOR_COMMAND,
        MessageKind::MultiAxisCommand => &MULTI_AXIS_COMMAND,
        MessageKind::MotorFeedback => &MOTOR_FEEDBACK,
        MessageKind::Trajectory => &TRAJECTORY,
        MessageKind::PidConfig => &PID_CONFIG,
        MessageKind::SafetyLimits => &SAFETY_LIMITS,
        MessageKind::ControlModeConfig => &CONTROL_MODE_CONFIG,
    };
    cell.get_or_init(|| {
        let schema: Value = serde_json::from_str(kind.schema())
            .map_err(|e| format!("the embedded {kind} schema is not JSON: {e}"))?;
        jsonschema::draft7::new(&schema)
            .map_err(|e| format!("the embedded {kind} schema does not compile: {e}"))
    })
}

/// The compiled draft-07 validator of a kind's schema (compiled on first use,
/// then shared by every thread).
///
/// ```
/// use motorwire_wia::{schema_validator, MessageKind};
/// let v = schema_validator(MessageKind::PidConfig).unwrap();
/// assert!(!v.is_valid(&serde_json::json!({"motor_id": "m"})));
/// ```
///
/// # Errors
/// Only if an embedded schema failed to compile, which the test suite rules out.
pub fn schema_validator(kind: MessageKind) -> Result<&'static jsonschema::Validator, &'static str> {
    compiled(kind).as_ref().map_err(String::as_str)
}

/// The JSON Schema violations of `value` as [`Violation`]s: the first
/// [`crate::MAX_VIOLATIONS`], and how many more (counted, not described).
pub(crate) fn violations(kind: MessageKind, value: &Value) -> (Vec<Violation>, usize) {
    let validator = match schema_validator(kind) {
        Ok(v) => v,
        Err(e) => return (vec![Violation::new("", Rule::SchemaOther, e)], 0),
    };
    let mut errors = validator.iter_errors(value);
    let listed = errors
        .by_ref()
        .take(crate::MAX_VIOLATIONS)
        .map(|e| {
            let at = e.instance_path().as_str().to_owned();
            let (rule, pointer) = match e.kind() {
                ValidationErrorKind::Required { property } => {
                    let name = property.as_str().unwrap_or_default();
                    let escaped = name.replace('~', "~0").replace('/', "~1");
                    (Rule::Required, format!("{at}/{escaped}"))
                }
                ValidationErrorKind::Type { .. } => (Rule::Type, at),
                ValidationErrorKind::Enum { .. } => (Rule::Enum, at),
                ValidationErrorKind::Minimum { .. } => (Rule::Minimum, at),
                ValidationErrorKind::Maximum { .. } => (Rule::Maximum, at),
                ValidationErrorKind::ExclusiveMinimum { .. } => (Rule::ExclusiveMinimum, at),
                ValidationErrorKind::Pattern { .. } => (Rule::Pattern, at),
                ValidationErrorKind::MinItems { .. } => (Rule::MinItems, at),
                ValidationErrorKind::MinLength { .. } => (Rule::MinLength, at),
                _ => (Rule::SchemaOther, at),
            };
            Violation::new(pointer, rule, e.to_string())
        })
        .collect();
    (listed, errors.count())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_embedded_schema_compiles_and_names_itself() {
        for kind in MessageKind::ALL {
            assert!(schema_validator(kind).is_ok(), "{kind}");
            let schema: Value = serde_json::from_str(kind.schema()).unwrap();
            assert_eq!(schema["$schema"], "http://json-schema.org/draft-07/schema#");
            let id = schema["$id"].as_str().unwrap();
            assert!(id.ends_with(&format!("/{}.json", kind.name())), "{id}");
        }
    }

    #[test]
    fn required_points_at_the_missing_member() {
        let (v, more) = violations(
            MessageKind::MotorCommand,
            &serde_json::json!({"motor_id": "m", "timestamp": 0, "control_mode": "position"}),
        );
        assert_eq!((v.len(), more), (1, 0));
        assert_eq!(v[0].pointer, "/setpoint");
        assert_eq!(v[0].rule, Rule::Required);
    }
}
