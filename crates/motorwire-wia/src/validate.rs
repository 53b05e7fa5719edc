//! The validation pipeline: limits, typed parse, schema-level and semantic
//! checks, and the JSON Schema as the fallback that explains type errors.

use serde::Serialize;

use crate::error::{Error, Report};
use crate::kind::{Message, MessageKind, WiaMessage};
use crate::{
    ControlModeConfig, MotorCommand, MotorFeedback, MultiAxisCommand, PidConfig, Rule,
    SafetyLimits, Trajectory, Violation, schema,
};

/// Validates WIA JSON documents and typed messages.
///
/// A `Validator` holds the limits on hostile input and the clock used by the
/// staleness rule; it is cheap to create and to clone, and the schemas it
/// uses are compiled once per process.
///
/// ```
/// use motorwire_wia::{MessageKind, Rule, Validator};
///
/// let v = Validator::new().now_ms(1_704_067_200_000.0);
/// let report = v.validate(MessageKind::MotorCommand, r#"{
///     "motor_id": "elbow", "timestamp": 1704067200000, "control_mode": "position",
///     "setpoint": 95.0, "pid_gains": {"kp": 0, "ki": 0.1, "kd": 1},
///     "safety_limits": {"min_position": 0, "max_position": 90}
/// }"#);
/// let found: Vec<(&str, Rule)> = report.violations.iter().map(|v| (v.pointer.as_str(), v.rule)).collect();
/// assert_eq!(found, [("/pid_gains/kp", Rule::KpPositive), ("/setpoint", Rule::SetpointWithinLimits)]);
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct Validator {
    max_document_size: usize,
    max_depth: usize,
    now_ms: Option<f64>,
    window: TimestampWindow,
    deny_unknown: bool,
}

/// How far from the validator's clock a timestamp may be before it is
/// stale ([`Rule::TimestampStale`]), each way in milliseconds (`None`: no
/// bound that way).
///
/// WIA §10.1 bounds only the past, at five minutes ([`Self::WIA`]); the
/// bridge applies its clock skew (`--max-age`) both ways
/// ([`Self::skew`]), and `motorwire validate --now --max-age` judges as
/// the bridge does.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TimestampWindow {
    /// How far behind the clock a timestamp may be.
    pub behind_ms: Option<f64>,
    /// How far ahead of the clock a timestamp may be.
    pub ahead_ms: Option<f64>,
}

impl TimestampWindow {
    /// WIA §10.1: at most five minutes behind, any time ahead.
    pub const WIA: Self = Self {
        behind_ms: Some(300_000.0),
        ahead_ms: None,
    };

    /// At most `ms` either way (the bridge's clock skew).
    pub const fn skew(ms: f64) -> Self {
        Self {
            behind_ms: Some(ms),
            ahead_ms: Some(ms),
        }
    }

    /// No bound either way: only the form of a timestamp is checked.
    pub const ANY: Self = Self {
        behind_ms: None,
        ahead_ms: None,
    };
}

impl Default for Validator {
    fn default() -> Self {
        Self::new()
    }
}

impl Validator {
    /// The default maximum document size: 1 MiB.
    pub const DEFAULT_MAX_DOCUMENT_SIZE: usize = 1 << 20;
    /// The default maximum nesting depth (the top-level object is depth 1).
    pub const DEFAULT_MAX_DEPTH: usize = 32;
    /// The deepest nesting any setting allows: `serde_json`'s own recursion
    /// limit, which keeps parsing off the end of the stack.
    pub const MAX_DEPTH_CEILING: usize = 128;

    /// Default limits (1 MiB, depth 32), no clock (no staleness check), and
    /// unknown members refused ([`Validator::deny_unknown_members`]): the
    /// reading of a line the bridge, `motorwire validate` and `motorwire
    /// translate` apply. [`Validator::lenient`] takes them.
    pub const fn new() -> Self {
        Self {
            max_document_size: Self::DEFAULT_MAX_DOCUMENT_SIZE,
            max_depth: Self::DEFAULT_MAX_DEPTH,
            now_ms: None,
            window: TimestampWindow::WIA,
            deny_unknown: true,
        }
    }

    /// [`Validator::new`] taking members a kind's schema does not name, as
    /// WIA's open schemas do (kept in each type's `extra`): for documents
    /// that carry members of their own. A misspelled member then passes
    /// unseen.
    ///
    /// ```
    /// use motorwire_wia::{MessageKind, Validator};
    /// let doc = r#"{"motor_id":"elbow","timestamp":1,"control_mode":"position","setpoint":20,"site":"lab 2"}"#;
    /// assert!(Validator::lenient().validate(MessageKind::MotorCommand, doc).is_valid());
    /// assert!(!Validator::new().validate(MessageKind::MotorCommand, doc).is_valid());
    /// ```
    pub const fn lenient() -> Self {
        Self::new().deny_unknown_members(false)
    }

    /// Refuses every member a kind's schema does not name where it stands
    /// ([`Rule::UnknownMember`], naming the nearest known member): WIA's
    /// schemas leave objects open, so a misspelled `velocity_limt` would be
    /// valid and ignored. Free-form objects (`metadata`) take any member,
    /// and a MotorCommand takes motorwire's `stream` (a boolean). On by
    /// default; `false` is [`Validator::lenient`].
    ///
    /// ```
    /// use motorwire_wia::{MessageKind, Rule, Validator};
    /// let doc = r#"{"motor_id":"elbow","timestamp":1,"control_mode":"position","setpoint":20,"velocity_limt":5}"#;
    /// let r = Validator::new().validate(MessageKind::MotorCommand, doc);
    /// assert_eq!(r.violations[0].rule, Rule::UnknownMember);
    /// assert_eq!(r.violations[0].pointer, "/velocity_limt");
    /// assert!(r.violations[0].message.contains("did you mean velocity_limit?"));
    /// assert!(Validator::new().deny_unknown_members(false).validate(MessageKind::MotorCommand, doc).is_valid());
    /// // motorwire's `stream` member is known.
    /// let stream = r#"{"motor_id":"elbow","timestamp":1,"control_mode":"velocity","setpoint":20,"stream":true}"#;
    /// assert!(Validator::new().validate(MessageKind::MotorCommand, stream).is_valid());
    /// ```
    #[must_use]
    pub const fn deny_unknown_members(mut self, deny: bool) -> Self {
        self.deny_unknown = deny;
        self
    }

    /// Whether unknown members are refused.
    pub const fn denies_unknown_members(&self) -> bool {
        self.deny_unknown
    }

    /// Sets the largest document accepted, in bytes.
    #[must_use]
    pub const fn max_document_size(mut self, bytes: usize) -> Self {
        self.max_document_size = bytes;
        self
    }

    /// Sets the deepest nesting accepted. Values above
    /// [`MAX_DEPTH_CEILING`](Self::MAX_DEPTH_CEILING) (128) act as 128.
    #[must_use]
    pub const fn max_depth(mut self, depth: usize) -> Self {
        self.max_depth = if depth > Self::MAX_DEPTH_CEILING {
            Self::MAX_DEPTH_CEILING
        } else {
            depth
        };
        self
    }

    /// Sets the current time (Unix milliseconds) for the staleness rule: a
    /// timestamp more than 5 minutes older than `now_ms` is stale (unless a
    /// [`Validator::timestamp_window`] says otherwise). Future
    /// timestamps are allowed (WIA §10.1).
    #[must_use]
    pub const fn now_ms(mut self, now_ms: f64) -> Self {
        self.now_ms = Some(now_ms);
        self
    }

    /// With a clock ([`Validator::now_ms`]), a timestamp more than
    /// `ahead_ms` ahead of it is stale too ([`Rule::TimestampStale`]):
    /// WIA allows future timestamps, the bridge a clock skew (its
    /// `--max-age`, 5 minutes by default) either way, and `motorwire
    /// validate --now` judges as the bridge does.
    ///
    /// ```
    /// use motorwire_wia::{MessageKind, Validator};
    /// let doc = r#"{"motor_id":"m","timestamp":1704070800000,"control_mode":"position","setpoint":1}"#;
    /// let v = Validator::new().now_ms(1_704_067_200_000.0);
    /// assert!(v.validate(MessageKind::MotorCommand, doc).is_valid()); // an hour ahead: WIA allows it
    /// assert!(!v.max_ahead_ms(300_000.0).validate(MessageKind::MotorCommand, doc).is_valid());
    /// ```
    #[must_use]
    pub const fn max_ahead_ms(mut self, ahead_ms: f64) -> Self {
        self.window.ahead_ms = Some(ahead_ms);
        self
    }

    /// With a clock ([`Validator::now_ms`]), the window a timestamp must
    /// fall in, replacing WIA's five minutes behind and any time ahead.
    ///
    /// ```
    /// use motorwire_wia::{MessageKind, TimestampWindow, Validator};
    /// let doc = r#"{"motor_id":"m","timestamp":1704066600000,"control_mode":"position","setpoint":1}"#;
    /// let v = Validator::new().now_ms(1_704_067_200_000.0); // doc is 10 minutes old
    /// assert!(!v.clone().validate(MessageKind::MotorCommand, doc).is_valid());
    /// let wide = v.timestamp_window(TimestampWindow::skew(900_000.0));
    /// assert!(wide.validate(MessageKind::MotorCommand, doc).is_valid());
    /// ```
    #[must_use]
    pub const fn timestamp_window(mut self, window: TimestampWindow) -> Self {
        self.window = window;
        self
    }

    /// The configured clock, if any.
    pub const fn clock(&self) -> Option<f64> {
        self.now_ms
    }

    /// Parses and fully validates a document as `T`.
    ///
    /// ```
    /// use motorwire_wia::{MotorCommand, Rule, Validator};
    ///
    /// let err = Validator::new()
    ///     .parse::<MotorCommand>(r#"{"motor_id": "m", "timestamp": 0, "control_mode": "warp", "setpoint": 1}"#)
    ///     .unwrap_err();
    /// assert_eq!(err.violations()[0].pointer, "/control_mode");
    /// assert_eq!(err.violations()[0].rule, Rule::Enum);
    /// ```
    ///
    /// # Errors
    /// [`Error::Invalid`] with every violation found.
    pub fn parse<T: WiaMessage>(&self, json: &str) -> Result<T, Error> {
        let (msg, violations, more) = match self.precheck(json) {
            Ok(()) => self.run::<T>(json),
            Err(v) => (None, vec![v], 0),
        };
        match msg {
            Some(msg) if violations.is_empty() && more == 0 => Ok(msg),
            _ => Err(Error::Invalid(Report::bounded(
                Some(T::KIND),
                violations,
                more,
            ))),
        }
    }

    /// Parses and validates a document of any kind, inferring the kind as
    /// [`MessageKind::infer`] does.
    ///
    /// # Errors
    /// [`Error::Invalid`]; `kind` in its report is `None` when the kind could
    /// not be inferred.
    pub fn parse_any(&self, json: &str) -> Result<Message, Error> {
        // The document is parsed once when it is valid: the kind comes from
        // a scan of its top-level member names. On any failure, the kind is
        // inferred by a parse and the document judged again, so that every
        // error is exactly the one `infer` and the typed parse give.
        if let Some(kind) = crate::kind::scan_kind(json)
            && self.precheck(json).is_ok()
            && let Ok(m) = self.typed(kind, json)
        {
            return Ok(m);
        }
        let kind = self
            .precheck(json)
            .and_then(|()| infer(json))
            .map_err(|v| Error::Invalid(Report::bounded(None, vec![v], 0)))?;
        self.typed(kind, json)
    }

    /// `json` as a valid [`MotorCommand`] that is nothing but one, from a
    /// single parse of its text: what a bridge reads for nearly every line.
    /// The parse stops at the first top-level name a `MotorCommand` does
    /// not have (its value not read); the typed value then says what a scan
    /// of the text would (no member unknown anywhere in it; how deep it
    /// nests, read from the text only under `metadata`, which is free-form).
    ///
    /// `None` whenever the document is anything else or is not valid:
    /// another kind, a member a `MotorCommand` does not name at any depth,
    /// a violation, a document over the limits. [`Validator::parse_any`]
    /// then says what it is or what is wrong; where both give a command,
    /// it is the same one.
    ///
    /// ```
    /// use motorwire_wia::Validator;
    /// let v = Validator::new().deny_unknown_members(true);
    /// let line = r#"{"motor_id":"elbow","timestamp":1704067200000,"control_mode":"position","setpoint":30}"#;
    /// assert_eq!(v.parse_plain_command(line).unwrap().setpoint, 30.0);
    /// // A misspelled member: not a plain command (parse_any says why).
    /// let typo = r#"{"motor_id":"elbow","timestamp":1704067200000,"control_mode":"position","setpoint":30,"velocity_limt":5}"#;
    /// assert!(v.parse_plain_command(typo).is_none());
    /// assert!(v.parse_any(typo).is_err());
    /// ```
    pub fn parse_plain_command(&self, json: &str) -> Option<MotorCommand> {
        self.parse_plain(json)
    }

    /// [`Validator::parse_plain_command`] for a [`MultiAxisCommand`]: `json`
    /// as a valid multi-axis command that is nothing but one, from a single
    /// parse of its text. The parse stops at the first top-level name a
    /// multi-axis command does not have; the typed value says no member is
    /// unknown at any level (its own, its coordination's, each axis's and
    /// their parts'), and how deep it nests (four levels at most: the
    /// command, its `motors`, an axis, an axis's gains or limits), the text
    /// being read again for depth only under a `metadata`, which is
    /// free-form.
    ///
    /// `None` whenever the document is anything else or is not valid;
    /// [`Validator::parse_any`] then says what it is or what is wrong.
    ///
    /// ```
    /// use motorwire_wia::Validator;
    /// let v = Validator::new().deny_unknown_members(true);
    /// let line = r#"{"command_id":"c1","timestamp":1704067200000,"motors":[
    ///     {"motor_id":"shoulder","control_mode":"position","setpoint":30},
    ///     {"motor_id":"elbow","control_mode":"position","setpoint":-10}]}"#;
    /// let c = v.parse_plain_multi_axis(line).unwrap();
    /// assert_eq!(c.motors.iter().map(|a| a.setpoint).collect::<Vec<_>>(), [30.0, -10.0]);
    /// // A misspelled member of an axis: not a plain command (parse_any says why).
    /// let typo = line.replace(r#""setpoint":30"#, r#""setpoint":30,"velocity_limt":5"#);
    /// assert!(v.parse_plain_multi_axis(&typo).is_none());
    /// assert!(v.parse_any(&typo).is_err());
    /// ```
    pub fn parse_plain_multi_axis(&self, json: &str) -> Option<MultiAxisCommand> {
        self.parse_plain(json)
    }

    /// `json` as a valid `T` that is nothing but one, from a single parse
    /// stopped at the first top-level name `T`'s schema does not give; the
    /// text read again only for the depth of what may nest deeper than the
    /// limit.
    fn parse_plain<T: crate::plain::Plain>(&self, json: &str) -> Option<T> {
        if json.len() > self.max_document_size {
            return None;
        }
        // The kind's commonest shape (a flat command) read without serde,
        // to the bit as serde reads it; anything else by serde. Judged
        // where it lies: a command is some 500 bytes, and each move out
        // of the `Option` and back copies them.
        let mut m: Option<T> = T::read_flat(json);
        if m.is_none() {
            m = crate::plain::parse_named(json, crate::members::top_level_members(T::KIND));
        }
        let valid = m.as_ref().is_some_and(|m| {
            let unreadable = m.any_unknown()
                || (m.may_nest_beyond(self.max_depth) && self.precheck(json).is_err());
            !unreadable && m.violations_with_skew(self.now_ms, self.window).is_empty()
        });
        if valid { m } else { None }
    }

    /// `json` as a valid message of `kind` (the kind its names say:
    /// [`crate::scan_kind_noting`]), within the size and depth limits.
    /// Where this fails, [`Validator::parse_any`] gives the error a caller
    /// shows (the kind it infers may be another).
    ///
    /// # Errors
    /// [`Error::Invalid`].
    pub fn parse_as(&self, kind: MessageKind, json: &str) -> Result<Message, Error> {
        self.precheck(json)
            .map_err(|v| Error::Invalid(Report::bounded(None, vec![v], 0)))?;
        self.typed(kind, json)
    }

    /// `json`, which passed the size and depth limits, as a valid message
    /// of `kind`.
    fn typed(&self, kind: MessageKind, json: &str) -> Result<Message, Error> {
        fn typed<T: WiaMessage>(v: &Validator, json: &str) -> Result<T, Error> {
            match v.run::<T>(json) {
                (Some(msg), violations, 0) if violations.is_empty() => Ok(msg),
                (_, violations, more) => Err(Error::Invalid(Report::bounded(
                    Some(T::KIND),
                    violations,
                    more,
                ))),
            }
        }
        Ok(match kind {
            MessageKind::MotorCommand => Message::MotorCommand(typed(self, json)?),
            MessageKind::MultiAxisCommand => Message::MultiAxisCommand(typed(self, json)?),
            MessageKind::MotorFeedback => Message::MotorFeedback(typed(self, json)?),
            MessageKind::Trajectory => Message::Trajectory(typed(self, json)?),
            MessageKind::PidConfig => Message::PidConfig(typed(self, json)?),
            MessageKind::SafetyLimits => Message::SafetyLimits(typed(self, json)?),
            MessageKind::ControlModeConfig => Message::ControlModeConfig(typed(self, json)?),
        })
    }

    /// Validates a document as `kind`, returning every violation.
    pub fn validate(&self, kind: MessageKind, json: &str) -> Report {
        let (violations, more) = match self.precheck(json) {
            Ok(()) => self.checked(kind, json),
            Err(v) => (vec![v], 0),
        };
        Report::bounded(Some(kind), violations, more)
    }

    /// The violations of a document that passed the size and depth
    /// limits (the first [`MAX_VIOLATIONS`](crate::MAX_VIOLATIONS)), and
    /// how many more.
    fn checked(&self, kind: MessageKind, json: &str) -> (Vec<Violation>, usize) {
        fn of<T>((_, list, more): (Option<T>, Vec<Violation>, usize)) -> (Vec<Violation>, usize) {
            (list, more)
        }
        match kind {
            MessageKind::MotorCommand => of(self.run::<MotorCommand>(json)),
            MessageKind::MultiAxisCommand => of(self.run::<MultiAxisCommand>(json)),
            MessageKind::MotorFeedback => of(self.run::<MotorFeedback>(json)),
            MessageKind::Trajectory => of(self.run::<Trajectory>(json)),
            MessageKind::PidConfig => of(self.run::<PidConfig>(json)),
            MessageKind::SafetyLimits => of(self.run::<SafetyLimits>(json)),
            MessageKind::ControlModeConfig => of(self.run::<ControlModeConfig>(json)),
        }
    }

    /// Validates a document of whatever kind it is ([`MessageKind::infer`]);
    /// the report says which kind was chosen.
    ///
    /// ```
    /// use motorwire_wia::{MessageKind, Validator};
    /// let r = Validator::new().validate_auto(r#"{"mode": "position"}"#);
    /// assert_eq!((r.kind, r.is_valid()), (Some(MessageKind::ControlModeConfig), true));
    /// ```
    pub fn validate_auto(&self, json: &str) -> Report {
        if let Err(v) = self.precheck(json) {
            return Report::bounded(None, vec![v], 0);
        }
        // The document is parsed once: the kind comes from a scan of its
        // top-level member names. Only when the scan cannot tell, or the
        // text turns out not to be JSON, does `infer` parse it to say why,
        // exactly as before.
        if let Some(kind) = crate::kind::scan_kind(json) {
            let (violations, more) = self.checked(kind, json);
            let not_json = matches!(violations.as_slice(), [v] if v.rule == Rule::JsonSyntax);
            if !not_json {
                return Report::bounded(Some(kind), violations, more);
            }
        }
        match infer(json) {
            Ok(kind) => {
                let (violations, more) = self.checked(kind, json);
                Report::bounded(Some(kind), violations, more)
            }
            Err(v) => Report::bounded(None, vec![v], 0),
        }
    }

    /// Judges a document by the JSON Schema alone (no semantic rules), still
    /// within the size and depth limits.
    ///
    /// ```
    /// use motorwire_wia::{MessageKind, Validator};
    /// // kp = 0 satisfies the schema (minimum 0) but not WIA §10.4.
    /// let doc = r#"{"motor_id": "m", "control_mode": "position", "gains": {"kp": 0, "ki": 0, "kd": 0}}"#;
    /// assert!(Validator::new().validate_schema_only(MessageKind::PidConfig, doc).is_valid());
    /// assert!(!Validator::new().validate(MessageKind::PidConfig, doc).is_valid());
    /// ```
    pub fn validate_schema_only(&self, kind: MessageKind, json: &str) -> Report {
        let (violations, more) = match self.precheck(json) {
            Err(v) => (vec![v], 0),
            Ok(()) => match serde_json::from_str::<serde_json::Value>(json) {
                Ok(value) => schema::violations(kind, &value),
                Err(e) => (vec![json_error(json, &e)], 0),
            },
        };
        Report::bounded(Some(kind), violations, more)
    }

    /// Every violation of a typed value (see [`WiaMessage::violations`]),
    /// judged with this validator's clock.
    pub fn check<T: WiaMessage>(&self, msg: &T) -> Vec<Violation> {
        msg.violations_with_skew(self.now_ms, self.window)
    }

    /// Serializes a message to JSON after checking it: a value that breaks a
    /// rule (a NaN would silently become `null`) is refused.
    ///
    /// ```
    /// use motorwire_wia::{MotorCommand, Validator};
    /// let v = Validator::new();
    /// let json = r#"{"motor_id":"m","timestamp":1704067200000,"control_mode":"velocity","setpoint":2.5}"#;
    /// let cmd: MotorCommand = v.parse(json)?;
    /// assert_eq!(v.to_json(&cmd)?, json);
    /// # Ok::<(), motorwire_wia::Error>(())
    /// ```
    ///
    /// # Errors
    /// [`Error::Invalid`] with the value's violations.
    pub fn to_json<T: WiaMessage>(&self, msg: &T) -> Result<String, Error> {
        let (violations, more) = msg.violations_counted(self.now_ms, self.window);
        if !violations.is_empty() || more > 0 {
            return Err(Error::Invalid(Report::bounded(
                Some(T::KIND),
                violations,
                more,
            )));
        }
        to_string(msg)
    }

    /// Size and depth, before any parser sees the text.
    fn precheck(&self, json: &str) -> Result<(), Violation> {
        if json.len() > self.max_document_size {
            return Err(Violation::new(
                "",
                Rule::DocumentTooLarge,
                format!(
                    "the document is {} bytes; the maximum is {}",
                    json.len(),
                    self.max_document_size
                ),
            ));
        }
        if let Some(depth) = depth_exceeding(json.as_bytes(), self.max_depth) {
            return Err(Violation::new(
                "",
                Rule::DocumentTooDeep,
                format!(
                    "the document nests at least {depth} levels deep; the maximum is {}",
                    self.max_depth
                ),
            ));
        }
        Ok(())
    }

    /// Parses and checks a document that passed [`Validator::precheck`]:
    /// the value, the first violations and how many more.
    fn run<T: WiaMessage>(&self, json: &str) -> (Option<T>, Vec<Violation>, usize) {
        match serde_json::from_str::<T>(json) {
            Ok(msg) => {
                let (mut violations, more) = msg.violations_counted(self.now_ms, self.window);
                if self.deny_unknown && msg.may_hold_unknown_members() {
                    violations.extend(crate::members::unknown_members(T::KIND, json));
                }
                // motorwire's `stream`, named twice: which one a reader took
                // would depend on the reader.
                if matches!(
                    T::KIND,
                    MessageKind::MotorCommand | MessageKind::MultiAxisCommand
                ) && json.contains("\"stream\"")
                {
                    let mut times = 0usize;
                    crate::kind::top_level_names(json, |name| {
                        times += usize::from(name == crate::members::STREAM.as_bytes());
                    });
                    if times > 1 {
                        violations.push(Violation::new(
                            "/stream",
                            Rule::Stream,
                            format!("stream appears {times} times"),
                        ));
                    }
                }
                (Some(msg), violations, more)
            }
            Err(e) if e.is_data() => {
                let (list, more) = explain_data_error(T::KIND, json, &e);
                (None, list, more)
            }
            Err(e) => (None, vec![json_error(json, &e)], 0),
        }
    }
}

/// The kind of a document that passed the size and depth limits.
fn infer(json: &str) -> Result<MessageKind, Violation> {
    match MessageKind::infer(json) {
        Ok(Some(kind)) => Ok(kind),
        Ok(None) => Err(Violation::new(
            "",
            Rule::UnknownKind,
            "cannot tell the message kind: no member names one (see MessageKind::infer)",
        )),
        Err(e) if e.is_data() => Err(Violation::new(
            "",
            Rule::UnknownKind,
            "cannot tell the message kind: the document is not a JSON object",
        )),
        Err(e) => Err(json_error(json, &e)),
    }
}

/// The typed parse refused a well-formed document: the JSON Schema says
/// where and why, with every violation; what it accepts is something
/// motorwire cannot represent (an integer beyond 64 bits, a repeated key).
fn explain_data_error(
    kind: MessageKind,
    json: &str,
    error: &serde_json::Error,
) -> (Vec<Violation>, usize) {
    let value: serde_json::Value = match serde_json::from_str(json) {
        Ok(v) => v,
        Err(e) => return (vec![json_error(json, &e)], 0),
    };
    let (violations, more) = schema::violations(kind, &value);
    if violations.is_empty() {
        (
            vec![Violation::new(
                "",
                Rule::Unrepresentable,
                format!(
                    "the document satisfies the {kind} schema but motorwire cannot represent it: {error}"
                ),
            )],
            0,
        )
    } else {
        (violations, more)
    }
}

fn json_error(json: &str, e: &serde_json::Error) -> Violation {
    Violation::new(
        "",
        Rule::JsonSyntax,
        format!("not valid JSON: {}", json_error_text(json, e)),
    )
}

/// What is wrong with `json`, which `serde_json` refused with `e`: its
/// message, and where the refused text is a number JSON has no word for
/// (`NaN`, `Infinity`, `-Infinity`: what Python's `json.dumps` writes for
/// such a float), that word named first.
///
/// ```
/// let line = r#"{"motor_id":"elbow","timestamp":1,"control_mode":"velocity","setpoint":NaN}"#;
/// let e = serde_json::from_str::<serde_json::Value>(line).unwrap_err();
/// assert_eq!(
///     motorwire_wia::json_error_text(line, &e),
///     "NaN is not a JSON number (Python's json.dumps writes it for a float NaN: \
///      send a finite number, or dump with allow_nan=False to find it): \
///      expected value at line 1 column 72"
/// );
/// ```
pub fn json_error_text(json: &str, e: &serde_json::Error) -> String {
    // The error's place: its line (1-based) and column (1-based, bytes).
    // The word may start a byte before it (a `-` read as a number's sign).
    let word = json
        .split('\n')
        .nth(e.line().saturating_sub(1))
        .and_then(|l| {
            let col = e.column().saturating_sub(1);
            [col.saturating_sub(1), col]
                .into_iter()
                .filter_map(|from| l.get(from..))
                .find_map(|rest| {
                    ["-Infinity", "Infinity", "-NaN", "NaN"]
                        .into_iter()
                        .find(|w| rest.starts_with(w))
                })
        });
    match word {
        Some(w) => format!(
            "{w} is not a JSON number (Python's json.dumps writes it for a float {}: \
             send a finite number, or dump with allow_nan=False to find it): {e}",
            if w.contains("Infinity") {
                "infinity"
            } else {
                "NaN"
            }
        ),
        None => e.to_string(),
    }
}

/// Scans the text for `[`/`{` nesting outside strings; returns the depth
/// reached once it exceeds `max`, without parsing anything.
fn depth_exceeding(bytes: &[u8], max: usize) -> Option<usize> {
    // Fast path: a document with no more opening brackets than `max` cannot
    // nest deeper than `max`. `[` (0x5B) and `{` (0x7B) differ only in bit
    // 0x20, so one comparison finds both, in a loop the compiler vectorizes.
    let openings: usize = bytes.iter().map(|&b| usize::from(b | 0x20 == b'{')).sum();
    if openings <= max {
        return None;
    }
    let mut depth = 0usize;
    let mut in_string = false;
    let mut escaped = false;
    for &b in bytes {
        if in_string {
            if escaped {
                escaped = false;
            } else if b == b'\\' {
                escaped = true;
            } else if b == b'"' {
                in_string = false;
            }
            continue;
        }
        match b {
            b'"' => in_string = true,
            b'{' | b'[' => {
                depth += 1;
                if depth > max {
                    return Some(depth);
                }
            }
            b'}' | b']' => depth = depth.saturating_sub(1),
            _ => {}
        }
    }
    None
}

/// Serializes any WIA message to compact JSON, without checking it.
fn to_string<T: Serialize>(msg: &T) -> Result<String, Error> {
    serde_json::to_string(msg).map_err(|e| {
        Error::Invalid(Report::bounded(
            None,
            vec![Violation::new("", Rule::Unrepresentable, e.to_string())],
            0,
        ))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_document_that_is_not_an_object_is_a_type_violation() {
        let r = Validator::new().validate(MessageKind::MotorCommand, r#"[{"motor_id": "m"}]"#);
        assert_eq!(r.violations.len(), 1);
        assert_eq!(
            (r.violations[0].pointer.as_str(), r.violations[0].rule),
            ("", Rule::Type)
        );
        let r = Validator::new().validate_auto("[1]");
        assert_eq!((r.kind, r.violations[0].rule), (None, Rule::UnknownKind));
    }

    #[test]
    fn depth_scan_ignores_brackets_in_strings() {
        assert_eq!(depth_exceeding(br#"{"a":"[[[[{{{{"}"#, 1), None);
        assert_eq!(depth_exceeding(br#"{"a":"\"[[["}"#, 1), None);
        assert_eq!(depth_exceeding(br#"{"a":[{"b":1}]}"#, 2), Some(3));
        assert_eq!(depth_exceeding(br#"{"a":[{"b":1}]}"#, 3), None);
    }
}
