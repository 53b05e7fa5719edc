use std::fmt;

use serde::{Serialize, Serializer};

/// Which layer of validation a [`Rule`] belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Level {
    /// The text could not be judged as a message at all (not JSON, too
    /// large, too deep, of no known kind, or not representable).
    Document,
    /// A JSON Schema keyword (`type`, `required`, `minimum`, ...).
    Schema,
    /// A rule of WIA Phase 1 §10, or one the schemas cannot express.
    Semantic,
}

macro_rules! rules {
    ($( $(#[$doc:meta])* $variant:ident = $name:literal, $level:ident; )*) => {
        /// A validation rule; [`Rule::name`] is the stable, kebab-case name
        /// used in reports and on the command line.
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
        #[non_exhaustive]
        pub enum Rule {
            $( $(#[$doc])* $variant, )*
        }

        impl Rule {
            /// Every rule, in declaration order.
            pub const ALL: &'static [Rule] = &[$(Rule::$variant,)*];

            /// The rule's stable name, e.g. `"kp-positive"`.
            pub const fn name(self) -> &'static str {
                match self { $( Rule::$variant => $name, )* }
            }

            /// The layer the rule belongs to.
            pub const fn level(self) -> Level {
                match self { $( Rule::$variant => Level::$level, )* }
            }

            /// The rule with the given name.
            pub fn from_name(name: &str) -> Option<Rule> {
                match name { $( $name => Some(Rule::$variant), )* _ => None }
            }
        }
    };
}

rules! {
    /// The text is not well-formed JSON.
    JsonSyntax = "json-syntax", Document;
    /// The text is longer than the configured maximum document size.
    DocumentTooLarge = "document-too-large", Document;
    /// The JSON nests deeper than the configured maximum depth.
    DocumentTooDeep = "document-too-deep", Document;
    /// `auto` could not tell which kind of message the document is.
    UnknownKind = "unknown-kind", Document;
    /// The document satisfies the JSON Schema but cannot be represented
    /// faithfully: an integer beyond 64 bits, or a key given twice.
    Unrepresentable = "unrepresentable", Document;

    /// JSON Schema `type`: a value has the wrong JSON type.
    Type = "type", Schema;
    /// JSON Schema `required`: a required member is missing.
    Required = "required", Schema;
    /// JSON Schema `enum`: a value is not one of the allowed ones.
    Enum = "enum", Schema;
    /// JSON Schema `minimum`.
    Minimum = "minimum", Schema;
    /// JSON Schema `maximum`.
    Maximum = "maximum", Schema;
    /// JSON Schema `exclusiveMinimum`.
    ExclusiveMinimum = "exclusive-minimum", Schema;
    /// JSON Schema `pattern`.
    Pattern = "pattern", Schema;
    /// JSON Schema `minItems`.
    MinItems = "min-items", Schema;
    /// JSON Schema `minLength`.
    MinLength = "min-length", Schema;
    /// Any other JSON Schema keyword.
    SchemaOther = "schema", Schema;

    /// A number is NaN or infinite (only possible for values built in code).
    NonFinite = "non-finite", Semantic;
    /// A timestamp is not a whole number of Unix milliseconds.
    TimestampInteger = "timestamp-integer", Semantic;
    /// A timestamp is a count of seconds, not milliseconds (from 10^9 to
    /// 10^11: as milliseconds, a time in 1970 to 1973 no clock sends; as
    /// seconds, 2001 to 5138).
    TimestampUnit = "timestamp-unit", Semantic;
    /// A MotorCommand's `stream` member is not a boolean.
    Stream = "stream", Semantic;
    /// A timestamp is outside the window around the caller's `now`: by default more
    /// than 5 minutes older ([`TimestampWindow`](crate::TimestampWindow)).
    TimestampStale = "timestamp-stale", Semantic;
    /// A motor id breaks motorwire's motor-id rules (length, alphabet).
    MotorId = "motor-id", Semantic;
    /// `kp` must be greater than zero for stable control.
    KpPositive = "kp-positive", Semantic;
    /// `ki_limit` must be greater than zero when given.
    KiLimitPositive = "ki-limit-positive", Semantic;
    /// A gain, limit or physical quantity that cannot be negative is.
    NonNegative = "non-negative", Semantic;
    /// A limit, constraint or duration that must be greater than zero is not.
    Positive = "positive", Semantic;
    /// The setpoint lies outside the command's own safety limits for its mode.
    SetpointWithinLimits = "setpoint-within-limits", Semantic;
    /// A command's velocity or torque limit exceeds its own safety limits.
    LimitWithinSafety = "limit-within-safety", Semantic;
    /// The control mode needs parameters the command does not give.
    ModeParameters = "mode-parameters", Semantic;
    /// Position limits are out of order (min <= soft_min <= soft_max <= max).
    PositionLimitsOrder = "position-limits-order", Semantic;
    /// The home position lies outside the position limits.
    HomePosition = "home-position", Semantic;
    /// The warning temperature is above the maximum temperature.
    TemperatureOrder = "temperature-order", Semantic;
    /// The continuous torque is above the peak torque.
    TorqueOrder = "torque-order", Semantic;
    /// The continuous current is above the peak current.
    CurrentOrder = "current-order", Semantic;
    /// The output limits are out of order (min <= max).
    OutputLimitsOrder = "output-limits-order", Semantic;
    /// Waypoint times are not strictly increasing from zero.
    WaypointTimeOrder = "waypoint-time-order", Semantic;
    /// A waypoint's velocity exceeds the trajectory's max_velocity.
    WaypointVelocity = "waypoint-velocity", Semantic;
    /// A waypoint's acceleration exceeds the trajectory's max_acceleration.
    WaypointAcceleration = "waypoint-acceleration", Semantic;
    /// A waypoint's torque exceeds the trajectory's max_torque.
    WaypointTorque = "waypoint-torque", Semantic;
    /// The average speed between two waypoints exceeds max_velocity.
    SegmentVelocity = "segment-velocity", Semantic;
    /// timing.total_duration disagrees with the last waypoint's time.
    TrajectoryDuration = "trajectory-duration", Semantic;
    /// An enabled loop has a count of 0 or below -1.
    LoopCount = "loop-count", Semantic;
    /// A motor appears twice in one multi-axis command.
    DuplicateMotor = "duplicate-motor", Semantic;
    /// A member the kind's schema does not name where it stands (a typo,
    /// most often), refused by default
    /// ([`Validator::deny_unknown_members`](crate::Validator::deny_unknown_members);
    /// [`Validator::lenient`](crate::Validator::lenient) takes it).
    UnknownMember = "unknown-member", Schema;
}

impl fmt::Display for Rule {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl Serialize for Rule {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.name())
    }
}

/// One thing wrong with a document: where (a JSON pointer, RFC 6901), which
/// rule, and a message for a person.
///
/// For a missing member the pointer names the member that is missing
/// (`/setpoint`), not the object that lacks it.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct Violation {
    /// JSON pointer to the offending value; `""` is the whole document.
    pub pointer: String,
    /// The rule that was broken.
    pub rule: Rule,
    /// What is wrong, with the offending value and the limit it broke.
    pub message: String,
}

impl Violation {
    /// A violation at `pointer`.
    pub fn new(pointer: impl Into<String>, rule: Rule, message: impl Into<String>) -> Self {
        Self {
            pointer: pointer.into(),
            rule,
            message: message.into(),
        }
    }
}

impl fmt::Display for Violation {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let pointer = if self.pointer.is_empty() {
            "(document)"
        } else {
            &self.pointer
        };
        write!(f, "{pointer}: {} ({})", self.message, self.rule)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_unique_and_round_trip() {
        let mut seen = std::collections::HashSet::new();
        for rule in Rule::ALL {
            assert!(seen.insert(rule.name()), "duplicate name {}", rule.name());
            assert_eq!(Rule::from_name(rule.name()), Some(*rule));
        }
        assert_eq!(Rule::from_name("no-such-rule"), None);
    }

    #[test]
    fn violation_displays_pointer_message_and_rule() {
        let v = Violation::new("/pid_gains/kp", Rule::KpPositive, "kp must be > 0 (got 0)");
        assert_eq!(
            v.to_string(),
            "/pid_gains/kp: kp must be > 0 (got 0) (kp-positive)"
        );
        let json = serde_json::to_string(&v).unwrap();
        assert_eq!(
            json,
            r#"{"pointer":"/pid_gains/kp","rule":"kp-positive","message":"kp must be > 0 (got 0)"}"#
        );
    }
}
