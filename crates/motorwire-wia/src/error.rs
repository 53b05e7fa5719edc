use std::fmt;

use serde::Serialize;

use crate::{MessageKind, Violation};

/// Why a document was refused: every violation found, with the kind it was
/// judged as (absent when `auto` could not tell).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Report {
    /// The kind the document was judged as.
    pub kind: Option<MessageKind>,
    /// Every violation; empty when the document is valid.
    pub violations: Vec<Violation>,
}

impl Report {
    /// Whether the document broke no rule.
    pub fn is_valid(&self) -> bool {
        self.violations.is_empty()
    }
}

impl fmt::Display for Report {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let kind = self.kind.map_or("document", MessageKind::name);
        if self.violations.is_empty() {
            return write!(f, "valid {kind}");
        }
        write!(f, "invalid {kind}: {} violation(s)", self.violations.len())?;
        for v in &self.violations {
            write!(f, "\n  {v}")?;
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
    /// The violations, for matching on.
    pub fn violations(&self) -> &[Violation] {
        match self {
            Self::Invalid(r) => &r.violations,
        }
    }
}
