//! What a translation could not carry over exactly.

use std::borrow::Cow;
use std::fmt;
use std::sync::Arc;

/// The kind of a lossy step.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LossKind {
    /// A field with no place in the target dialect, left out.
    Dropped,
    /// A value converted (a unit, or a number format with less precision).
    Converted,
    /// A value the target needs, taken from the bus map or a default.
    Defaulted,
    /// A value the target does not report, filled in.
    Filled,
}

impl LossKind {
    /// The kind as a loss's text names it: `dropped`, `converted`,
    /// `defaulted` or `filled`.
    pub const fn name(self) -> &'static str {
        match self {
            Self::Dropped => "dropped",
            Self::Converted => "converted",
            Self::Defaulted => "defaulted",
            Self::Filled => "filled",
        }
    }
}

/// A loss's words ([`Loss::detail`]): fixed text, a string made for this
/// loss, or text made once and shared by every loss that says the same
/// (a defaulted limit's `500 from the bus map`, the same for every
/// command that leaves the limit out). It reads as the `str` it holds;
/// `&'static str`, `String`, `Cow<'static, str>` and `Arc<str>` convert.
///
/// ```
/// use motorwire_translate::LossText;
/// let fixed = LossText::from("500 from the bus map");
/// let made = LossText::from(format!("{} from the bus map", 500));
/// assert_eq!(fixed, made);
/// assert_eq!(made, "500 from the bus map");
/// assert!(made.ends_with("bus map"));
/// assert_eq!(format!("{made} / {made:?}"), r#"500 from the bus map / "500 from the bus map""#);
/// ```
#[derive(Clone)]
pub struct LossText(TextRepr);

#[derive(Clone)]
enum TextRepr {
    Fixed(&'static str),
    Made(String),
    Shared(Arc<str>),
}

impl LossText {
    /// The text.
    pub fn as_str(&self) -> &str {
        match &self.0 {
            TextRepr::Fixed(s) => s,
            TextRepr::Made(s) => s,
            TextRepr::Shared(s) => s,
        }
    }
}

impl std::ops::Deref for LossText {
    type Target = str;
    fn deref(&self) -> &str {
        self.as_str()
    }
}

impl AsRef<str> for LossText {
    fn as_ref(&self) -> &str {
        self.as_str()
    }
}

impl fmt::Display for LossText {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

impl fmt::Debug for LossText {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Debug::fmt(self.as_str(), f)
    }
}

impl PartialEq for LossText {
    fn eq(&self, other: &Self) -> bool {
        self.as_str() == other.as_str()
    }
}

impl Eq for LossText {}

impl PartialEq<str> for LossText {
    fn eq(&self, other: &str) -> bool {
        self.as_str() == other
    }
}

impl PartialEq<&str> for LossText {
    fn eq(&self, other: &&str) -> bool {
        self.as_str() == *other
    }
}

impl From<&'static str> for LossText {
    fn from(s: &'static str) -> Self {
        Self(TextRepr::Fixed(s))
    }
}

impl From<String> for LossText {
    fn from(s: String) -> Self {
        Self(TextRepr::Made(s))
    }
}

impl From<Cow<'static, str>> for LossText {
    fn from(s: Cow<'static, str>) -> Self {
        match s {
            Cow::Borrowed(s) => s.into(),
            Cow::Owned(s) => s.into(),
        }
    }
}

impl From<Arc<str>> for LossText {
    fn from(s: Arc<str>) -> Self {
        Self(TextRepr::Shared(s))
    }
}

/// One lossy step.
///
/// The field is a [`Cow`] and the detail a [`LossText`]: a field's name
/// and most details are fixed text, which a bridge translating every
/// command should not copy into a new string each time (`"x".into()` and
/// `String`s both convert).
#[derive(Debug, Clone, PartialEq)]
pub struct Loss {
    /// The field, as the source (or, for `Defaulted`/`Filled`, the target)
    /// names it.
    pub field: Cow<'static, str>,
    /// What happened.
    pub kind: LossKind,
    /// How, in words.
    pub detail: LossText,
}

impl Loss {
    /// The loss as a report line says it, `field: kind: detail` (what its
    /// `Display` writes), built without the formatting machinery: a bridge
    /// writes one for every lossy step of every command.
    ///
    /// ```
    /// use motorwire_translate::{Loss, LossKind};
    /// let l = Loss { field: "max_acceleration".into(), kind: LossKind::Defaulted, detail: "500 from the bus map".into() };
    /// assert_eq!(l.text(), "max_acceleration: defaulted: 500 from the bus map");
    /// assert_eq!(l.text(), l.to_string());
    /// ```
    pub fn text(&self) -> String {
        let kind = self.kind_name();
        let mut s = String::with_capacity(self.field.len() + kind.len() + self.detail.len() + 4);
        s.push_str(&self.field);
        s.push_str(": ");
        s.push_str(kind);
        s.push_str(": ");
        s.push_str(&self.detail);
        s
    }

    /// The loss of one motor of a line that names several: its field as
    /// `owner.field`.
    ///
    /// ```
    /// use motorwire_translate::{Loss, LossKind};
    /// let l = Loss { field: "max_jerk".into(), kind: LossKind::Defaulted, detail: "2000 from the bus map".into() };
    /// assert_eq!(l.under("elbow").text(), "elbow.max_jerk: defaulted: 2000 from the bus map");
    /// ```
    #[must_use]
    pub fn under(mut self, owner: &str) -> Self {
        let mut field = String::with_capacity(owner.len() + 1 + self.field.len());
        field.push_str(owner);
        field.push('.');
        field.push_str(&self.field);
        self.field = field.into();
        self
    }

    const fn kind_name(&self) -> &'static str {
        self.kind.name()
    }
}

impl fmt::Display for Loss {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}: {}", self.field, self.kind_name(), self.detail)
    }
}

/// Every lossy step of one translation, in the order they happened.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Report {
    /// The steps.
    pub losses: Vec<Loss>,
}

impl Report {
    pub(crate) fn push(
        &mut self,
        field: impl Into<Cow<'static, str>>,
        kind: LossKind,
        detail: impl Into<LossText>,
    ) {
        self.losses.push(Loss {
            field: field.into(),
            kind,
            detail: detail.into(),
        });
    }

    /// Whether the translation was exact.
    pub fn is_exact(&self) -> bool {
        self.losses.is_empty()
    }
}

/// A translation's result and its report.
#[derive(Debug, Clone, PartialEq)]
pub struct Translated<T> {
    /// The translated message.
    pub value: T,
    /// What was lost or changed on the way.
    pub report: Report,
}
