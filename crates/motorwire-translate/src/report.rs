//! What a translation could not carry over exactly.

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

/// One lossy step.
#[derive(Debug, Clone, PartialEq)]
pub struct Loss {
    /// The field, as the source (or, for `Defaulted`/`Filled`, the target)
    /// names it.
    pub field: String,
    /// What happened.
    pub kind: LossKind,
    /// How, in words.
    pub detail: String,
}

impl fmt::Display for Loss {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let kind = match self.kind {
            LossKind::Dropped => "dropped",
            LossKind::Converted => "converted",
            LossKind::Defaulted => "defaulted",
            LossKind::Filled => "filled",
        };
        write!(f, "{}: {kind}: {}", self.field, self.detail)
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
        field: impl Into<String>,
        kind: LossKind,
        detail: impl Into<String>,
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
