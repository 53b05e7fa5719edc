//! Message kinds, the typed message trait, and kind inference.

use std::borrow::Cow;
use std::fmt;
use std::str::FromStr;

use serde::de::{DeserializeOwned, IgnoredAny, MapAccess, Visitor};
use serde::{Deserialize, Deserializer, Serialize};

use crate::check::Sink;
use crate::{
    ControlModeConfig, MotorCommand, MotorFeedback, MultiAxisCommand, PidConfig, SafetyLimits,
    Trajectory, Violation,
};

/// The seven kinds of WIA message motorwire validates.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum MessageKind {
    /// [`MotorCommand`].
    MotorCommand,
    /// [`MultiAxisCommand`].
    MultiAxisCommand,
    /// [`MotorFeedback`].
    MotorFeedback,
    /// [`Trajectory`].
    Trajectory,
    /// [`PidConfig`].
    PidConfig,
    /// [`SafetyLimits`].
    SafetyLimits,
    /// [`ControlModeConfig`].
    ControlModeConfig,
}

impl MessageKind {
    /// Every kind.
    pub const ALL: [MessageKind; 7] = [
        Self::MotorCommand,
        Self::MultiAxisCommand,
        Self::MotorFeedback,
        Self::Trajectory,
        Self::PidConfig,
        Self::SafetyLimits,
        Self::ControlModeConfig,
    ];

    /// The kebab-case name used on the command line and in reports.
    pub const fn name(self) -> &'static str {
        match self {
            Self::MotorCommand => "motor-command",
            Self::MultiAxisCommand => "multi-axis-command",
            Self::MotorFeedback => "motor-feedback",
            Self::Trajectory => "trajectory",
            Self::PidConfig => "pid-config",
            Self::SafetyLimits => "safety-limits",
            Self::ControlModeConfig => "control-mode-config",
        }
    }

    /// The kind with the given name.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|k| k.name() == name)
    }

    /// The JSON Schema (draft-07) of this kind, as shipped in `schemas/`.
    ///
    /// ```
    /// use motorwire_wia::MessageKind;
    /// assert!(MessageKind::MotorCommand.schema().contains("\"title\": \"MotorCommand\""));
    /// ```
    pub const fn schema(self) -> &'static str {
        match self {
            Self::MotorCommand => include_str!("../schemas/motor-command.json"),
            Self::MultiAxisCommand => include_str!("../schemas/multi-axis-command.json"),
            Self::MotorFeedback => include_str!("../schemas/motor-feedback.json"),
            Self::Trajectory => include_str!("../schemas/trajectory.json"),
            Self::PidConfig => include_str!("../schemas/pid-config.json"),
            Self::SafetyLimits => include_str!("../schemas/safety-limits.json"),
            Self::ControlModeConfig => include_str!("../schemas/control-mode-config.json"),
        }
    }

    /// Infers the kind of a JSON object from the names of its top-level
    /// members, by the first rule that applies:
    ///
    /// | any of these members present | kind |
    /// |---|---|
    /// | `motors`, `command_id` | multi-axis-command |
    /// | `waypoints`, `trajectory_id` | trajectory |
    /// | `position_limits`, `velocity_limits`, `torque_limits` | safety-limits |
    /// | `gains` | pid-config |
    /// | `setpoint`, `control_mode` | motor-command |
    /// | `status`, `position`, `velocity`, `torque` | motor-feedback |
    /// | `mode`, `parameters` | control-mode-config |
    ///
    /// Missing required members are then reported against the kind chosen,
    /// so a command without its setpoint is still judged as a command.
    ///
    /// Returns `None` for an object that matches none of them; the caller
    /// learns about syntax errors and non-objects from the `Err`.
    ///
    /// ```
    /// use motorwire_wia::MessageKind;
    /// assert_eq!(MessageKind::infer(r#"{"setpoint": 1}"#).unwrap(), Some(MessageKind::MotorCommand));
    /// assert_eq!(MessageKind::infer(r#"{"hello": 1}"#).unwrap(), None);
    /// assert!(MessageKind::infer("[1]").is_err());
    /// ```
    ///
    /// # Errors
    /// The JSON error when the text is not a JSON object.
    pub fn infer(json: &str) -> Result<Option<Self>, serde_json::Error> {
        let keys: TopLevelKeys = serde_json::from_str(json)?;
        Ok(keys.kind())
    }
}

impl fmt::Display for MessageKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for MessageKind {
    type Err = UnknownKindName;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Self::from_name(s).ok_or(UnknownKindName)
    }
}

impl Serialize for MessageKind {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.name())
    }
}

/// A name that is not one of the seven [`MessageKind`] names.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error(
    "unknown message kind; expected one of motor-command, multi-axis-command, motor-feedback, \
     trajectory, pid-config, safety-limits, control-mode-config"
)]
pub struct UnknownKindName;

#[derive(Default)]
struct TopLevelKeys {
    motors: bool,
    waypoints: bool,
    position_limits: bool,
    gains: bool,
    setpoint: bool,
    status_or_position: bool,
    mode: bool,
}

impl TopLevelKeys {
    /// Notes one top-level member name.
    fn note(&mut self, key: &[u8]) {
        match key {
            b"motors" | b"command_id" => self.motors = true,
            b"waypoints" | b"trajectory_id" => self.waypoints = true,
            b"position_limits" | b"velocity_limits" | b"torque_limits" => {
                self.position_limits = true;
            }
            b"gains" => self.gains = true,
            b"setpoint" | b"control_mode" => self.setpoint = true,
            b"status" | b"position" | b"velocity" | b"torque" => {
                self.status_or_position = true;
            }
            b"mode" | b"parameters" => self.mode = true,
            _ => {}
        }
    }

    fn kind(&self) -> Option<MessageKind> {
        [
            (self.motors, MessageKind::MultiAxisCommand),
            (self.waypoints, MessageKind::Trajectory),
            (self.position_limits, MessageKind::SafetyLimits),
            (self.gains, MessageKind::PidConfig),
            (self.setpoint, MessageKind::MotorCommand),
            (self.status_or_position, MessageKind::MotorFeedback),
            (self.mode, MessageKind::ControlModeConfig),
        ]
        .into_iter()
        .find_map(|(present, kind)| present.then_some(kind))
    }
}

impl<'de> Deserialize<'de> for TopLevelKeys {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct KeysVisitor;
        impl<'de> Visitor<'de> for KeysVisitor {
            type Value = TopLevelKeys;

            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str("a JSON object")
            }

            fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<TopLevelKeys, A::Error> {
                let mut keys = TopLevelKeys::default();
                while let Some(key) = map.next_key::<Cow<'de, str>>()? {
                    keys.note(key.as_bytes());
                    map.next_value::<IgnoredAny>()?;
                }
                Ok(keys)
            }
        }
        d.deserialize_map(KeysVisitor)
    }
}

/// The kind [`MessageKind::infer`] would give `json`, told from a scan of
/// its bytes for the top-level member names, without parsing it (no
/// numbers read, nothing allocated), so that inferring the kind does not
/// cost a parse of its own. `None` when the scan cannot be sure: the text
/// does not start with an object, no member names a kind, a top-level
/// name has an escape in it, or the object never closes; the caller then
/// asks [`MessageKind::infer`], which also says what is wrong. The scan
/// does not check the syntax: the typed parse that follows does.
pub(crate) fn scan_kind(json: &str) -> Option<MessageKind> {
    scan_kind_noting(json, |_| {}).ok()?
}

/// The kind of WIA message the top-level member names of the JSON object
/// `json` holds say it is (as [`MessageKind::infer`] says it of a valid
/// message), from one scan of its bytes ([`top_level_names`]) that also
/// gives each name to `note`: `Ok(None)` when the names fit no kind,
/// `Err(())` when the scan cannot be sure of them. What a caller that
/// looks at the names itself reads the line once for; then
/// [`crate::Validator::parse_as`].
///
/// ```
/// use motorwire_wia::{MessageKind, scan_kind_noting};
/// let mut names = 0;
/// let line = r#"{"motor_id":"m","timestamp":1,"control_mode":"position","setpoint":1}"#;
/// assert_eq!(scan_kind_noting(line, |_| names += 1), Ok(Some(MessageKind::MotorCommand)));
/// assert_eq!(names, 4);
/// assert_eq!(scan_kind_noting(r#"{"a":1}"#, |_| {}), Ok(None));
/// assert_eq!(scan_kind_noting("[1]", |_| {}), Err(()));
/// ```
///
/// # Errors
/// `()` when the scan cannot be sure of the names (not an object, an
/// escaped name, an object that never closes).
#[allow(clippy::result_unit_err)]
pub fn scan_kind_noting(
    json: &str,
    mut note: impl FnMut(&[u8]),
) -> Result<Option<MessageKind>, ()> {
    let mut keys = TopLevelKeys::default();
    if top_level_names(json, |name| {
        note(name);
        keys.note(name);
    }) {
        Ok(keys.kind())
    } else {
        Err(())
    }
}

/// Calls `note` with each top-level member name of the JSON object `json`
/// holds, in order, from a scan of its bytes: nothing is parsed and nothing
/// allocated. Returns `false` when the scan cannot be sure of the names:
/// the text does not start with an object (after white space), a top-level
/// name has an escape in it, or the object never closes. It does not check
/// the syntax (a parse after it does): what follows the object's close is
/// not read.
///
/// ```
/// let mut names = Vec::new();
/// assert!(motorwire_wia::top_level_names(r#" {"a": {"b": 1}, "c": [{"d": 2}]} "#, |n| names.push(n.to_vec())));
/// assert_eq!(names, [b"a".to_vec(), b"c".to_vec()]);
/// assert!(!motorwire_wia::top_level_names(r#"{"\u0061": 1}"#, |_| {}));
/// assert!(!motorwire_wia::top_level_names(r#"[{"a": 1}]"#, |_| {}));
/// assert!(!motorwire_wia::top_level_names(r#"{"a": 1"#, |_| {}));
/// ```
pub fn top_level_names(json: &str, mut note: impl FnMut(&[u8])) -> bool {
    let bytes = json.as_bytes();
    let mut depth = 0usize;
    let mut expect_key = false;
    let mut i = 0;
    loop {
        let Some(&b) = bytes.get(i) else {
            return false;
        };
        i += 1;
        match b {
            b'"' if depth == 0 => return false,
            b'"' => {
                let Some((end, escaped)) = string_end(bytes, i) else {
                    return false;
                };
                if depth == 1 && expect_key {
                    if escaped {
                        return false;
                    }
                    let Some(name) = bytes.get(i..end) else {
                        return false;
                    };
                    note(name);
                    expect_key = false;
                }
                i = end + 1;
            }
            b'{' => {
                expect_key = depth == 0;
                depth += 1;
            }
            b'[' if depth == 0 => return false,
            b'[' => depth += 1,
            b'}' | b']' => {
                let Some(d) = depth.checked_sub(1) else {
                    return false;
                };
                depth = d;
                if depth == 0 {
                    return true;
                }
            }
            b',' if depth == 1 => expect_key = true,
            b' ' | b'\t' | b'\n' | b'\r' => {}
            _ if depth == 0 => return false,
            _ => {}
        }
    }
}

/// The index of the quote that closes the string whose contents start at
/// `start`, and whether the string has an escape; `None` if it never closes.
fn string_end(bytes: &[u8], start: usize) -> Option<(usize, bool)> {
    let mut i = start;
    let mut escaped = false;
    loop {
        let at = bytes
            .get(i..)?
            .iter()
            .position(|&c| c == b'"' || c == b'\\')?;
        i += at;
        if bytes.get(i) == Some(&b'"') {
            return Some((i, escaped));
        }
        // A backslash: it and the byte it escapes.
        escaped = true;
        i += 2;
    }
}

/// A typed WIA message: one of the seven message structs.
///
/// [`WiaMessage::violations`] judges a value however it was made (parsed,
/// or built in code), by the schema-level rules and the semantic rules.
pub trait WiaMessage: Serialize + DeserializeOwned + Sized {
    /// The kind of message this type is.
    const KIND: MessageKind;

    /// Every violation of the schema and semantic rules, with `now_ms`
    /// (Unix milliseconds) for the staleness rule when given.
    ///
    /// ```
    /// use motorwire_wia::{MotorCommand, Rule, Validator, WiaMessage};
    ///
    /// let mut cmd: MotorCommand = Validator::new().parse(
    ///     r#"{"motor_id":"elbow","timestamp":1000,"control_mode":"position","setpoint":1}"#)?;
    /// cmd.setpoint = f64::NAN;
    /// let v = cmd.violations(None);
    /// assert_eq!((v[0].pointer.as_str(), v[0].rule), ("/setpoint", Rule::NonFinite));
    /// # Ok::<(), motorwire_wia::Error>(())
    /// ```
    fn violations(&self, now_ms: Option<f64>) -> Vec<Violation>;

    /// Whether the typed value may hold members its schema does not name
    /// (the `extra` maps the parse filled): `false` only when it is known
    /// to hold none, so a strict validator need not look at the text.
    fn may_hold_unknown_members(&self) -> bool {
        true
    }

    /// [`WiaMessage::violations`], with timestamps judged against
    /// `window` around `now_ms` instead of WIA's five minutes behind
    /// ([`Validator::timestamp_window`](crate::Validator::timestamp_window)).
    fn violations_with_skew(
        &self,
        now_ms: Option<f64>,
        window: crate::TimestampWindow,
    ) -> Vec<Violation> {
        let _ = window;
        self.violations(now_ms)
    }

    /// [`WiaMessage::violations_with_skew`], the first
    /// [`MAX_VIOLATIONS`](crate::MAX_VIOLATIONS) of them, with how many
    /// more were found.
    fn violations_counted(
        &self,
        now_ms: Option<f64>,
        window: crate::TimestampWindow,
    ) -> (Vec<Violation>, usize) {
        let list = self.violations_with_skew(now_ms, window);
        let more = list.len().saturating_sub(crate::MAX_VIOLATIONS);
        let mut list = list;
        list.truncate(crate::MAX_VIOLATIONS);
        (list, more)
    }
}

macro_rules! wia_message {
    ($($ty:ident),*) => {$(
        impl WiaMessage for $ty {
            const KIND: MessageKind = MessageKind::$ty;

            fn violations(&self, now_ms: Option<f64>) -> Vec<Violation> {
                self.violations_with_skew(now_ms, crate::TimestampWindow::WIA)
            }

            fn may_hold_unknown_members(&self) -> bool {
                crate::members::Unknowns::any_unknown(self)
            }

            fn violations_with_skew(&self, now_ms: Option<f64>, window: crate::TimestampWindow) -> Vec<Violation> {
                self.violations_counted(now_ms, window).0
            }

            fn violations_counted(&self, now_ms: Option<f64>, window: crate::TimestampWindow) -> (Vec<Violation>, usize) {
                let mut sink = Sink::new(now_ms);
                sink.window = window;
                self.check(&mut sink);
                sink.finish_counted()
            }
        }
    )*};
}

wia_message!(
    MotorCommand,
    MultiAxisCommand,
    MotorFeedback,
    Trajectory,
    PidConfig,
    SafetyLimits,
    ControlModeConfig
);

/// Any WIA message, as [`Validator::parse_any`](crate::Validator::parse_any) returns it.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(untagged)]
#[allow(clippy::large_enum_variant)]
pub enum Message {
    /// A [`MotorCommand`].
    MotorCommand(MotorCommand),
    /// A [`MultiAxisCommand`].
    MultiAxisCommand(MultiAxisCommand),
    /// A [`MotorFeedback`].
    MotorFeedback(MotorFeedback),
    /// A [`Trajectory`].
    Trajectory(Trajectory),
    /// A [`PidConfig`].
    PidConfig(PidConfig),
    /// A [`SafetyLimits`].
    SafetyLimits(SafetyLimits),
    /// A [`ControlModeConfig`].
    ControlModeConfig(ControlModeConfig),
}

impl Message {
    /// The message's kind.
    pub fn kind(&self) -> MessageKind {
        match self {
            Self::MotorCommand(_) => MessageKind::MotorCommand,
            Self::MultiAxisCommand(_) => MessageKind::MultiAxisCommand,
            Self::MotorFeedback(_) => MessageKind::MotorFeedback,
            Self::Trajectory(_) => MessageKind::Trajectory,
            Self::PidConfig(_) => MessageKind::PidConfig,
            Self::SafetyLimits(_) => MessageKind::SafetyLimits,
            Self::ControlModeConfig(_) => MessageKind::ControlModeConfig,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_scan_finds_the_kind_from_top_level_names_only() {
        let cases: [(&str, Option<MessageKind>); 12] = [
            (r#"{"setpoint": 1}"#, Some(MessageKind::MotorCommand)),
            (
                r#" {"setpoint": 1, "motors": []}"#,
                Some(MessageKind::MultiAxisCommand),
            ),
            // Names inside values and nested objects do not count.
            (r#"{"a": {"motors": 1}, "b": "motors"}"#, None),
            (
                r#"{"a": "\"motors\"", "gains": {}}"#,
                Some(MessageKind::PidConfig),
            ),
            (
                r#"{"a": ["waypoints", {"mode": 1}], "status": "ok"}"#,
                Some(MessageKind::MotorFeedback),
            ),
            // An escape in a top-level name: the scan leaves it to infer.
            (r#"{"mot\u006frs": []}"#, None),
            // Not an object, or not closed.
            ("[1]", None),
            (r#""setpoint""#, None),
            (r#"{"setpoint": 1"#, None),
            ("", None),
            // The syntax is not the scan's to check: the parse after it does.
            (r#"{"setpoint" 1}"#, Some(MessageKind::MotorCommand)),
            (
                r#"{"mode": 1} trailing"#,
                Some(MessageKind::ControlModeConfig),
            ),
        ];
        for (doc, kind) in cases {
            assert_eq!(scan_kind(doc), kind, "{doc}");
        }
    }
}
