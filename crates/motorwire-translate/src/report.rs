//! What a translation could not carry over exactly.

use std::borrow::Cow;
use std::fmt;

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

/// One lossy step.
///
/// The field and the detail are [`Cow`]s: a field's name and most details
/// are fixed text, which a bridge translating every command should not
/// copy into a new string each time (`"x".into()` and `String`s both
/// convert).
#[derive(Debug, Clone, PartialEq)]
pub struct Loss {
    /// The field, as the source (or, for `Defaulted`/`Filled`, the target)
    /// names it.
    pub field: Cow<'static, str>,
    /// What happened.
    pub kind: LossKind,
    /// How, in words.
    pub detail: Cow<'static, str>,
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
        detail: impl Into<Cow<'static, str>>,
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
