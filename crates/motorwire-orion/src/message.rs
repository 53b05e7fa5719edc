//! Input and output messages: parsing with typed errors, and emission.

use serde_json::{Number, Value};

use crate::error::controller_group;
use crate::node::Node;
use crate::{Error, Motor};

/// The arm controller's ID, present in every message both ways.
pub const CONTROLLER_ID: u64 = 32;

const MESSAGE: &str = "the message";
const DATA: &str = "DATA";

/// Something for any subset of the seven motors: a value each
/// ([`MotorValues`], direct-control `DATA`) or a feedback each
/// ([`Feedback`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PerMotor<T>([Option<T>; 7]);

/// A value for any subset of the seven motors (direct-control `DATA`).
pub type MotorValues = PerMotor<f64>;

/// Direct-control feedback for any subset of the motors.
pub type Feedback = PerMotor<MotorFeedback>;

impl<T> Default for PerMotor<T> {
    fn default() -> Self {
        Self::new()
    }
}

impl<T> PerMotor<T> {
    /// No motor set.
    pub const fn new() -> Self {
        Self([const { None }; 7])
    }

    /// Sets `motor`.
    pub fn set(&mut self, motor: Motor, value: T) {
        if let Some(slot) = self.0.get_mut(motor.index()) {
            *slot = Some(value);
        }
    }

    /// Sets `motor` (builder style).
    #[must_use]
    pub fn with(mut self, motor: Motor, value: T) -> Self {
        self.set(motor, value);
        self
    }

    /// How many motors are set.
    pub fn len(&self) -> usize {
        self.0.iter().flatten().count()
    }

    /// Whether no motor is set.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

impl<T: Copy> PerMotor<T> {
    /// `motor`'s entry, if set.
    pub fn get(&self, motor: Motor) -> Option<T> {
        self.0.get(motor.index()).copied().flatten()
    }

    /// The motors set, in the document's order.
    pub fn iter(&self) -> impl Iterator<Item = (Motor, T)> + '_ {
        Motor::ALL
            .into_iter()
            .filter_map(|m| self.get(m).map(|v| (m, v)))
    }
}

impl MotorValues {
    /// The values clamped to each motor's range, as the document demands
    /// ("values out of bounds will be treated like marginal values"), and
    /// one [`Clamp`] for every value that changed.
    ///
    /// ```
    /// use motorwire_orion::{Clamp, Motor, MotorValues};
    /// let v = MotorValues::new().with(Motor::Turntable, -1000.0).with(Motor::LowerArmActuator, 0.5);
    /// let (clamped, clamps) = v.clamped();
    /// assert_eq!(clamped.get(Motor::Turntable), Some(-400.0));
    /// assert_eq!(clamps, vec![Clamp { motor: Motor::Turntable, requested: -1000.0, applied: -400.0 }]);
    /// ```
    pub fn clamped(&self) -> (MotorValues, Vec<Clamp>) {
        let mut out = *self;
        let mut clamps = Vec::new();
        for (motor, requested) in self.iter() {
            let (lo, hi) = motor.range();
            let applied = requested.clamp(lo, hi);
            if applied != requested {
                clamps.push(Clamp {
                    motor,
                    requested,
                    applied,
                });
                out.set(motor, applied);
            }
        }
        (out, clamps)
    }
}

/// A value moved into its motor's range.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Clamp {
    /// The motor.
    pub motor: Motor,
    /// The value sent.
    pub requested: f64,
    /// The value the motor runs at.
    pub applied: f64,
}

impl std::fmt::Display for Clamp {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let (lo, hi) = self.motor.range();
        write!(
            f,
            "{} {} is outside [{lo}, {hi}]; clamped to {}",
            self.motor, self.requested, self.applied
        )
    }
}

/// The commands of command mode.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ArmCommand {
    /// 1: stop the arm movement.
    Stop,
    /// 2: completely fold the arm (for transport).
    Fold,
    /// 3: unfold the arm to its default position.
    Unfold,
}

impl ArmCommand {
    /// The command's number.
    pub const fn number(self) -> i64 {
        match self {
            ArmCommand::Stop => 1,
            ArmCommand::Fold => 2,
            ArmCommand::Unfold => 3,
        }
    }
}

/// A command-mode `DATA`: any integer. Only 1, 2 and 3 are commands; the
/// controller answers the others (0 is the document's "invalid command")
/// with `CMDF: 0`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CommandNumber(pub i64);

impl CommandNumber {
    /// The command, if the number is one.
    pub const fn command(self) -> Option<ArmCommand> {
        match self.0 {
            1 => Some(ArmCommand::Stop),
            2 => Some(ArmCommand::Fold),
            3 => Some(ArmCommand::Unfold),
            _ => None,
        }
    }
}

impl From<ArmCommand> for CommandNumber {
    fn from(c: ArmCommand) -> Self {
        CommandNumber(c.number())
    }
}

/// A message to the arm controller.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Input {
    /// `MODE` 1: values for any subset of the motors, as sent (not yet
    /// clamped; [`MotorValues::clamped`] does that and reports it).
    DirectControl(MotorValues),
    /// `MODE` 2: a command number.
    Command(CommandNumber),
}

/// Which keys direct-control feedback uses (WIRE-FACTS §4: the document's
/// table and its example disagree). Both are accepted on input.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum FeedbackKeys {
    /// `TRMF` ... as the document's table (LV1-MM-201 to 207) names them.
    /// The default: the table is the normative part, and a feedback line
    /// can then never be mistaken for a command.
    #[default]
    Table,
    /// `TRM` ... as the document's example output spells them.
    Example,
}

/// One motor's feedback: `[value, current, error flag]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MotorFeedback {
    /// Actual speed, direction or position.
    pub value: f64,
    /// Actual current draw (the document gives no unit).
    pub current: f64,
    /// Error flag; 0 is no error.
    pub error: u64,
}

/// A message from the arm controller.
// 232 bytes at most, and Copy: boxing the feedback would allocate per
// message for no gain.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Output {
    /// `{"ID": 32}`, sent after boot until the first command.
    Beacon,
    /// After direct control: each motor's feedback.
    DirectControl(Feedback),
    /// After command mode: `CMDF`, whether the command succeeded.
    Command {
        /// `CMDF: 1`.
        succeeded: bool,
    },
}

/// Parses a JSON text into the member list of its top-level object.
fn parse_object(text: &str) -> Result<Vec<(String, Node)>, Error> {
    let node: Node = serde_json::from_str(text).map_err(|e| Error::Json {
        message: e.to_string(),
    })?;
    match node {
        Node::Object(members) => {
            check_duplicates(&members, MESSAGE)?;
            Ok(members)
        }
        other => Err(Error::NotAnObject {
            got: other.type_name(),
        }),
    }
}

fn check_duplicates(members: &[(String, Node)], within: &'static str) -> Result<(), Error> {
    for (i, (key, _)) in members.iter().enumerate() {
        if members.iter().skip(i + 1).any(|(k, _)| k == key) {
            return Err(Error::DuplicateKey {
                key: key.clone(),
                within,
            });
        }
    }
    Ok(())
}

fn find<'a>(members: &'a [(String, Node)], key: &str) -> Option<&'a Node> {
    members.iter().find(|(k, _)| k == key).map(|(_, v)| v)
}

fn wrong_type(key: &str, expected: &'static str, got: &Node) -> Error {
    Error::WrongType {
        key: key.to_owned(),
        expected,
        got: got.text(),
    }
}

/// A non-negative integer, or a typed error.
fn unsigned(key: &str, node: &Node) -> Result<u64, Error> {
    match node {
        Node::Number(n) => n
            .as_u64()
            .ok_or_else(|| wrong_type(key, "a non-negative integer", node)),
        _ => Err(wrong_type(key, "a non-negative integer", node)),
    }
}

fn number(key: &str, node: &Node) -> Result<f64, Error> {
    match node {
        // serde_json only makes finite numbers; a literal beyond f64 is a
        // parse error.
        Node::Number(n) => n
            .as_f64()
            .filter(|v| v.is_finite())
            .ok_or_else(|| wrong_type(key, "a finite number", node)),
        _ => Err(wrong_type(key, "a number", node)),
    }
}

/// Checks `ID` and `MODE` and the top-level keys; returns the mode (`None`
/// for a message with `ID` alone) and `DATA`.
fn envelope(members: &[(String, Node)]) -> Result<(Option<u64>, Option<&Node>), Error> {
    for (key, _) in members {
        if !matches!(key.as_str(), "ID" | "MODE" | "DATA") {
            let hint = if Motor::from_key(key).is_some() || Motor::from_feedback_key(key).is_some()
            {
                Some("motor keys go inside DATA")
            } else {
                None
            };
            return Err(Error::UnknownKey {
                key: key.clone(),
                within: MESSAGE,
                hint,
            });
        }
    }
    let id = find(members, "ID").ok_or(Error::MissingKey {
        key: "ID",
        within: MESSAGE,
    })?;
    let id = unsigned("ID", id)?;
    if id != CONTROLLER_ID {
        return Err(Error::WrongControllerId {
            got: id,
            group: controller_group(id),
        });
    }
    let mode = match find(members, "MODE") {
        None => None,
        Some(node) => {
            let mode = match node {
                Node::Number(n) if n.as_i64().is_some_and(|m| m < 0) => {
                    return Err(Error::WrongType {
                        key: "MODE".into(),
                        expected: "1 or 2",
                        got: node.text(),
                    });
                }
                _ => unsigned("MODE", node)?,
            };
            match mode {
                0 => return Err(Error::InvalidMode),
                1 | 2 => Some(mode),
                got => return Err(Error::ModeOutOfRange { got }),
            }
        }
    };
    let data = find(members, "DATA");
    match (mode, data) {
        (Some(_), None) => Err(Error::MissingKey {
            key: "DATA",
            within: MESSAGE,
        }),
        (None, Some(_)) => Err(Error::MissingKey {
            key: "MODE",
            within: MESSAGE,
        }),
        _ => Ok((mode, data)),
    }
}

fn data_object<'a>(data: &'a Node, expected: &'static str) -> Result<&'a [(String, Node)], Error> {
    match data {
        Node::Object(members) => {
            check_duplicates(members, DATA)?;
            Ok(members)
        }
        other => Err(wrong_type(DATA, expected, other)),
    }
}

impl Input {
    /// Parses one message to the controller.
    ///
    /// ```
    /// use motorwire_orion::{Error, Input, Motor};
    /// let input = Input::parse(r#"{"ID":32,"MODE":1,"DATA":{"TRM":200,"LAA":1}}"#)?;
    /// let Input::DirectControl(values) = input else { unreachable!() };
    /// assert_eq!(values.get(Motor::Turntable), Some(200.0));
    /// assert_eq!(values.len(), 2);
    ///
    /// assert_eq!(Input::parse(r#"{"ID":32,"MODE":0,"DATA":1}"#), Err(Error::InvalidMode));
    /// # Ok::<(), Error>(())
    /// ```
    ///
    /// # Errors
    /// An [`Error`] naming what is wrong: not JSON, not an object, a
    /// duplicate, missing or unknown key, a wrong type, another controller's
    /// ID, `MODE` 0 or out of range. Out-of-range motor values are not
    /// errors (the document clamps them; see [`MotorValues::clamped`]).
    pub fn parse(text: &str) -> Result<Input, Error> {
        let members = parse_object(text)?;
        let (mode, data) = envelope(&members)?;
        let (Some(mode), Some(data)) = (mode, data) else {
            return Err(Error::MissingKey {
                key: "MODE",
                within: MESSAGE,
            });
        };
        if mode == 2 {
            return match data {
                Node::Number(n) => match (n.as_i64(), n.as_u64()) {
                    (Some(v), _) => Ok(Input::Command(CommandNumber(v))),
                    (None, Some(_)) => Err(Error::CommandOutOfRange { got: n.to_string() }),
                    (None, None) => Err(wrong_type(DATA, "an integer command number", data)),
                },
                other => Err(wrong_type(DATA, "an integer command number", other)),
            };
        }
        let members = data_object(data, "an object of motor values")?;
        let mut values = MotorValues::new();
        for (key, value) in members {
            let Some(motor) = Motor::from_key(key) else {
                let hint = if Motor::from_feedback_key(key).is_some() {
                    Some("a feedback key; commands use the key without F")
                } else {
                    None
                };
                return Err(Error::UnknownKey {
                    key: key.clone(),
                    within: DATA,
                    hint,
                });
            };
            values.set(motor, number(key, value)?);
        }
        Ok(Input::DirectControl(values))
    }

    /// The message as one line of JSON, motors in the document's order.
    ///
    /// ```
    /// use motorwire_orion::{ArmCommand, Input, Motor, MotorValues};
    /// let v = MotorValues::new().with(Motor::Turntable, 200.0).with(Motor::GrasperHorizontalServo, -12.5);
    /// assert_eq!(Input::DirectControl(v).to_json(), r#"{"ID":32,"MODE":1,"DATA":{"TRM":200,"GHS":-12.5}}"#);
    /// assert_eq!(Input::Command(ArmCommand::Unfold.into()).to_json(), r#"{"ID":32,"MODE":2,"DATA":3}"#);
    /// ```
    pub fn to_json(&self) -> String {
        match self {
            Input::DirectControl(values) => {
                let members: Vec<(&str, Value)> = values
                    .iter()
                    .map(|(m, v)| (m.key(), json_number(v)))
                    .collect();
                envelope_json(1, &object_json(&members))
            }
            Input::Command(n) => envelope_json(2, &n.0.to_string()),
        }
    }
}

impl Output {
    /// Parses one message from the controller, in either feedback key form
    /// ([`FeedbackKeys`]).
    ///
    /// ```
    /// use motorwire_orion::{Input, Motor, MotorFeedback, Output};
    /// let out = Output::parse(r#"{"ID":32,"MODE":1,"DATA":{"TRM":[200,65,0],"LAAF":[1,50,0]}}"#)?;
    /// let Output::DirectControl(fb) = out else { unreachable!() };
    /// assert_eq!(fb.get(Motor::Turntable), Some(MotorFeedback { value: 200.0, current: 65.0, error: 0 }));
    /// assert_eq!(Output::parse(r#"{"ID":32}"#)?, Output::Beacon);
    /// assert_eq!(Output::parse(r#"{"ID":32,"MODE":2,"DATA":{"CMDF":1}}"#)?, Output::Command { succeeded: true });
    /// # Ok::<(), motorwire_orion::Error>(())
    /// ```
    ///
    /// # Errors
    /// As [`Input::parse`], and [`Error::BadFeedback`] or
    /// [`Error::BadCommandFeedback`] for malformed feedback.
    pub fn parse(text: &str) -> Result<Output, Error> {
        let members = parse_object(text)?;
        let (mode, data) = envelope(&members)?;
        let (Some(mode), Some(data)) = (mode, data) else {
            return Ok(Output::Beacon);
        };
        if mode == 2 {
            let members = data_object(data, "an object {\"CMDF\": 0 or 1}")?;
            let mut cmdf = None;
            for (key, value) in members {
                if key != "CMDF" {
                    return Err(Error::UnknownKey {
                        key: key.clone(),
                        within: DATA,
                        hint: None,
                    });
                }
                cmdf = Some(match value {
                    Node::Number(n) if n.as_u64() == Some(0) => false,
                    Node::Number(n) if n.as_u64() == Some(1) => true,
                    other => return Err(Error::BadCommandFeedback { got: other.text() }),
                });
            }
            return cmdf
                .map(|succeeded| Output::Command { succeeded })
                .ok_or(Error::MissingKey {
                    key: "CMDF",
                    within: DATA,
                });
        }
        let members = data_object(data, "an object of motor feedbacks")?;
        let mut feedback = Feedback::new();
        for (key, value) in members {
            let Some(motor) = Motor::from_feedback_key(key).or_else(|| Motor::from_key(key)) else {
                return Err(Error::UnknownKey {
                    key: key.clone(),
                    within: DATA,
                    hint: None,
                });
            };
            if feedback.get(motor).is_some() {
                // TRM and TRMF in one message.
                return Err(Error::DuplicateKey {
                    key: key.clone(),
                    within: DATA,
                });
            }
            feedback.set(motor, motor_feedback(key, value)?);
        }
        Ok(Output::DirectControl(feedback))
    }

    /// The message as one line of JSON, motor feedback keys as `keys` says.
    ///
    /// ```
    /// use motorwire_orion::{Feedback, FeedbackKeys, Motor, MotorFeedback, Output};
    /// let mut fb = Feedback::new();
    /// fb.set(Motor::Turntable, MotorFeedback { value: 200.0, current: 65.0, error: 0 });
    /// let out = Output::DirectControl(fb);
    /// assert_eq!(out.to_json(FeedbackKeys::Table), r#"{"ID":32,"MODE":1,"DATA":{"TRMF":[200,65,0]}}"#);
    /// assert_eq!(out.to_json(FeedbackKeys::Example), r#"{"ID":32,"MODE":1,"DATA":{"TRM":[200,65,0]}}"#);
    /// assert_eq!(Output::Beacon.to_json(FeedbackKeys::Table), r#"{"ID":32}"#);
    /// ```
    pub fn to_json(&self, keys: FeedbackKeys) -> String {
        match self {
            Output::Beacon => format!("{{\"ID\":{CONTROLLER_ID}}}"),
            Output::Command { succeeded } => {
                envelope_json(2, &format!("{{\"CMDF\":{}}}", u8::from(*succeeded)))
            }
            Output::DirectControl(feedback) => {
                let members: Vec<(&str, Value)> = feedback
                    .iter()
                    .map(|(m, f)| {
                        let key = match keys {
                            FeedbackKeys::Table => m.feedback_key(),
                            FeedbackKeys::Example => m.key(),
                        };
                        let array = Value::Array(vec![
                            json_number(f.value),
                            json_number(f.current),
                            Value::from(f.error),
                        ]);
                        (key, array)
                    })
                    .collect();
                envelope_json(1, &object_json(&members))
            }
        }
    }
}

fn motor_feedback(key: &str, node: &Node) -> Result<MotorFeedback, Error> {
    let bad = || Error::BadFeedback {
        key: key.to_owned(),
        got: node.text(),
    };
    let Node::Array(items) = node else {
        return Err(bad());
    };
    let [value, current, flag] = items.as_slice() else {
        return Err(bad());
    };
    let value = number(key, value).map_err(|_| bad())?;
    let current = number(key, current).map_err(|_| bad())?;
    let error = unsigned(key, flag).map_err(|_| bad())?;
    Ok(MotorFeedback {
        value,
        current,
        error,
    })
}

/// An f64 as JSON: integral values as integers (`200`, as the document
/// writes them), others as they are.
pub(crate) fn json_number(v: f64) -> Value {
    const EXACT: f64 = 9_007_199_254_740_992.0; // 2^53
    if v.fract() == 0.0 && v.abs() < EXACT {
        #[allow(clippy::cast_possible_truncation)]
        let i = v as i64;
        Value::from(i)
    } else {
        Number::from_f64(v).map_or(Value::Null, Value::Number)
    }
}

fn object_json(members: &[(&str, Value)]) -> String {
    let inner: Vec<String> = members
        .iter()
        .map(|(k, v)| format!("\"{k}\":{v}"))
        .collect();
    format!("{{{}}}", inner.join(","))
}

fn envelope_json(mode: u8, data: &str) -> String {
    format!("{{\"ID\":{CONTROLLER_ID},\"MODE\":{mode},\"DATA\":{data}}}")
}
