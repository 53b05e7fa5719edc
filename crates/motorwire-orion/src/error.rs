//! The one error type of `motorwire-orion`.

/// Why a line is not an Orion message. Every variant names the key and,
/// where there is one, the value it got (as JSON text).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// The line is not JSON (serde_json's message, with line and column);
    /// this includes nesting deeper than 128 and numbers beyond f64.
    #[error("not valid JSON: {message}")]
    Json {
        /// What serde_json reported.
        message: String,
    },
    /// The JSON is not an object.
    #[error("an Orion message is a JSON object, not {got}")]
    NotAnObject {
        /// The JSON type it is.
        got: &'static str,
    },
    /// A key appears twice in one object (JSON parsers disagree on which
    /// one wins, so neither is taken).
    #[error("the key {key:?} appears more than once in {within}")]
    DuplicateKey {
        /// The key.
        key: String,
        /// `"the message"` or `"DATA"`.
        within: &'static str,
    },
    /// A required key is absent.
    #[error("{within} has no {key:?} key")]
    MissingKey {
        /// The key.
        key: &'static str,
        /// `"the message"` or `"DATA"`.
        within: &'static str,
    },
    /// A key the dialect does not have.
    #[error("unknown key {key:?} in {within}{}", hint.map(|h| format!(" ({h})")).unwrap_or_default())]
    UnknownKey {
        /// The key.
        key: String,
        /// `"the message"` or `"DATA"`.
        within: &'static str,
        /// What was probably meant.
        hint: Option<&'static str>,
    },
    /// A value of the wrong JSON type (or a number that must be an integer
    /// and is not).
    #[error("{key} must be {expected}, not {got}")]
    WrongType {
        /// The key.
        key: String,
        /// What it must be.
        expected: &'static str,
        /// The value it had, as JSON text.
        got: String,
    },
    /// The message is addressed to another controller.
    #[error("ID {got} is not the arm controller's 32{}", group.map(|g| format!(" ({got} is in the {g} range)")).unwrap_or_default())]
    WrongControllerId {
        /// The ID given.
        got: u64,
        /// The rover's controller group the ID belongs to, if any.
        group: Option<&'static str>,
    },
    /// `MODE` 0, the document's "invalid mode".
    #[error("MODE 0 is the document's invalid mode; use 1 (direct control) or 2 (command)")]
    InvalidMode,
    /// `MODE` outside [0, 2].
    #[error("MODE {got} is outside [0, 2]")]
    ModeOutOfRange {
        /// The mode given.
        got: u64,
    },
    /// A command number that does not fit a 64-bit signed integer.
    #[error("command number {got} is outside the 64-bit integer range")]
    CommandOutOfRange {
        /// The number, as JSON text.
        got: String,
    },
    /// A motor feedback that is not `[value, current, error flag]`.
    #[error(
        "{key} must be a motor feedback [value, current, error flag] (numbers; the flag a non-negative integer), not {got}"
    )]
    BadFeedback {
        /// The key.
        key: String,
        /// The value it had, as JSON text.
        got: String,
    },
    /// `CMDF` other than 0 or 1.
    #[error("CMDF must be 0 or 1, not {got}")]
    BadCommandFeedback {
        /// The value it had, as JSON text.
        got: String,
    },
}

/// The controller group of a rover controller ID (WIRE-FACTS §4): drive
/// 0–31, manipulator 32–63, lab 64–95, control panel 96–100, misc 101–255.
pub(crate) fn controller_group(id: u64) -> Option<&'static str> {
    match id {
        0..=31 => Some("drive controllers' 0-31"),
        32..=63 => Some("manipulator controllers' 32-63"),
        64..=95 => Some("lab controllers' 64-95"),
        96..=100 => Some("control panel's 96-100"),
        101..=255 => Some("miscellaneous controllers' 101-255"),
        _ => None,
    }
}
