use std::fmt;

use serde::Serialize;

use crate::{MessageKind, Violation};

/// The most violations a report lists: the first found, in document
/// order; the rest are counted ([`Report::more`]). A document of a million
/// faults costs its reader a hundred lines, not a million.
pub const MAX_VIOLATIONS: usize = 100;

/// Why a document was refused: the violations found (the first
/// [`MAX_VIOLATIONS`], and how many more), with the kind it was judged as
/// (absent when `auto` could not tell).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Report {
    /// The kind the document was judged as.
    pub kind: Option<MessageKind>,
    /// The violations, at most [`MAX_VIOLATIONS`]; empty when the document
    /// is valid.
    pub violations: Vec<Violation>,
    /// Violations found beyond those listed (serialized as
    /// `more_violations`, left out when 0).
    #[serde(rename = "more_violations", skip_serializing_if = "is_zero")]
    pub more: usize,
}

// A reference is what serde's `skip_serializing_if` passes.
#[allow(clippy::trivially_copy_pass_by_ref)]
const fn is_zero(n: &usize) -> bool {
    *n == 0
}

impl Report {
    /// A report of `kind` with `violations`, the first [`MAX_VIOLATIONS`]
    /// kept and the rest counted in [`Report::more`] (with `more` found
    /// and not listed before).
    pub fn bounded(kind: Option<MessageKind>, mut violations: Vec<Violation>, more: usize) -> Self {
        let over = violations.len().saturating_sub(MAX_VIOLATIONS);
        violations.truncate(MAX_VIOLATIONS);
        Self {
            kind,
            violations,
            more: more.saturating_add(over),
        }
    }

    /// Whether the document broke no rule.
    pub fn is_valid(&self) -> bool {
        self.violations.is_empty() && self.more == 0
    }

    /// How many violations were found: those listed and the rest.
    pub fn count(&self) -> usize {
        self.violations.len().saturating_add(self.more)
    }
}

impl fmt::Display for Report {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let kind = self.kind.map_or("document", MessageKind::name);
        if self.violations.is_empty() {
            return write!(f, "valid {kind}");
        }
        write!(f, "invalid {kind}: {} violation(s)", self.count())?;
        for v in &self.violations {
            write!(f, "\n  {v}")?;
        }
        if self.more > 0 {
            write!(f, "\n  and {} more, not listed", self.more)?;
        }
        Ok(())
    }
}

/// The one error type of `motorwire-wia`.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// The document (or value) broke at least one rule; the report lists all.
    #[error("{0}")]
    Invalid(Report),
}

impl Error {
    /// The violations, for matching on (at most [`MAX_VIOLATIONS`]).
    pub fn violations(&self) -> &[Violation] {
        match self {
            Self::Invalid(r) => &r.violations,
        }
    }

    /// Violations found beyond those [`Error::violations`] lists.
    pub fn more(&self) -> usize {
        match self {
            Self::Invalid(r) => r.more,
        }
    }
}
