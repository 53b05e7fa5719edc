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
                    match key.as_ref() {
                        "motors" | "command_id" => keys.motors = true,
                        "waypoints" | "trajectory_id" => keys.waypoints = true,
                        "position_limits" | "velocity_limits" | "torque_limits" => {
                            keys.position_limits = true;
                        }
                        "gains" => keys.gains = true,
                        "setpoint" | "control_mode" => keys.setpoint = true,
                        "status" | "position" | "velocity" | "torque" => {
                            keys.status_or_position = true;
                        }
                        "mode" | "parameters" => keys.mode = true,
                        _ => {}
                    }
                    map.next_value::<IgnoredAny>()?;
                }
                Ok(keys)
            }
        }
        d.deserialize_map(KeysVisitor)
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
}

macro_rules! wia_message {
    ($($ty:ident),*) => {$(
        impl WiaMessage for $ty {
            const KIND: MessageKind = MessageKind::$ty;

            fn violations(&self, now_ms: Option<f64>) -> Vec<Violation> {
                let mut sink = Sink::new(now_ms);
                self.check(&mut sink);
                sink.finish()
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
