//! The checking sink: collects violations, renders pointers only on failure.

use motorwire_core::{CoreError, MotorId};

use crate::path::Path;
use crate::{Rule, Violation};

pub(crate) struct Sink {
    pub(crate) now_ms: Option<f64>,
    /// How far from `now_ms` a timestamp may be.
    pub(crate) window: crate::TimestampWindow,
    pub(crate) list: Vec<Violation>,
    /// Violations found beyond those kept (the list holds at most twice
    /// [`crate::MAX_VIOLATIONS`]: some are dropped at `finish`).
    pub(crate) more: usize,
}

impl Sink {
    pub(crate) fn new(now_ms: Option<f64>) -> Self {
        Self {
            now_ms,
            window: crate::TimestampWindow::WIA,
            list: Vec::new(),
            more: 0,
        }
    }

    pub(crate) fn push(&mut self, path: &Path<'_>, rule: Rule, message: String) {
        if self.list.len() >= 2 * crate::MAX_VIOLATIONS {
            self.more += 1;
            return;
        }
        self.list.push(Violation {
            pointer: path.render(),
            rule,
            message,
        });
    }

    /// Records a `motorwire-core` check's failure under `rule`.
    pub(crate) fn core<T>(&mut self, path: &Path<'_>, rule: Rule, result: Result<T, CoreError>) {
        if let Err(e) = result {
            let rule = match e {
                CoreError::NonFinite { .. } => Rule::NonFinite,
                _ => rule,
            };
            self.push(path, rule, e.to_string());
        }
    }

    /// Every number is checked for finiteness once; returns whether it is finite.
    pub(crate) fn num(&mut self, path: &Path<'_>, v: f64) -> bool {
        if v.is_finite() {
            true
        } else {
            self.push(path, Rule::NonFinite, format!("{v} is not a finite number"));
            false
        }
    }

    pub(crate) fn opt_num(&mut self, path: &Path<'_>, v: Option<f64>) -> Option<f64> {
        match v {
            Some(v) if self.num(path, v) => Some(v),
            _ => None,
        }
    }

    // --- JSON Schema keywords, as the typed path enforces them ----------

    pub(crate) fn minimum(&mut self, path: &Path<'_>, v: f64, limit: f64) {
        if self.num(path, v) && v < limit {
            self.push(
                path,
                Rule::Minimum,
                format!("{v} is less than the minimum of {limit}"),
            );
        }
    }

    pub(crate) fn opt_minimum(&mut self, path: &Path<'_>, v: Option<f64>, limit: f64) {
        if let Some(v) = v {
            self.minimum(path, v, limit);
        }
    }

    pub(crate) fn range(&mut self, path: &Path<'_>, v: f64, min: f64, max: f64) {
        if !self.num(path, v) {
            return;
        }
        if v < min {
            self.push(
                path,
                Rule::Minimum,
                format!("{v} is less than the minimum of {min}"),
            );
        } else if v > max {
            self.push(
                path,
                Rule::Maximum,
                format!("{v} is greater than the maximum of {max}"),
            );
        }
    }

    pub(crate) fn int_range(&mut self, path: &Path<'_>, v: i64, min: i64, max: Option<i64>) {
        if v < min {
            self.push(
                path,
                Rule::Minimum,
                format!("{v} is less than the minimum of {min}"),
            );
        } else if let Some(max) = max.filter(|m| v > *m) {
            self.push(
                path,
                Rule::Maximum,
                format!("{v} is greater than the maximum of {max}"),
            );
        }
    }

    pub(crate) fn exclusive_minimum(&mut self, path: &Path<'_>, v: f64, limit: f64) {
        if self.num(path, v) && v <= limit {
            self.push(
                path,
                Rule::ExclusiveMinimum,
                format!("{v} is less than or equal to the minimum of {limit}"),
            );
        }
    }

    /// The schema pattern `^[a-zA-Z0-9_-]+$`.
    pub(crate) fn id_pattern(&mut self, path: &Path<'_>, id: &str) {
        // Byte by byte: every allowed character is ASCII, and a character
        // beyond it has no byte below 0x80.
        if id.is_empty() || !id.bytes().all(|b| MotorId::is_id_char(char::from(b))) {
            self.push(
                path,
                Rule::Pattern,
                format!("{id:?} does not match \"^[a-zA-Z0-9_-]+$\""),
            );
        }
    }

    pub(crate) fn min_items(&mut self, path: &Path<'_>, len: usize, limit: usize) {
        if len < limit {
            self.push(
                path,
                Rule::MinItems,
                format!("has {len} item(s); at least {limit} are required"),
            );
        }
    }

    pub(crate) fn one_of_names(&mut self, path: &Path<'_>, name: &str, allowed: &[&str]) {
        if !allowed.contains(&name) {
            self.push(
                path,
                Rule::Enum,
                format!("{name:?} is not one of {allowed:?}"),
            );
        }
    }

    // --- semantic rules shared by several messages ------------------------

    /// WIA §10.1: a whole number of Unix milliseconds, not older than
    /// `now - 5 min` (future timestamps are allowed), or within the
    /// window set.
    pub(crate) fn timestamp(&mut self, path: &Path<'_>, t: f64) {
        if !self.num(path, t) {
            return;
        }
        if t.fract() != 0.0 {
            self.push(
                path,
                Rule::TimestampInteger,
                format!("timestamp {t} is not a whole number of Unix milliseconds"),
            );
        }
        if let (Some(now), Some(behind)) = (self.now_ms, self.window.behind_ms)
            && t < now - behind
        {
            self.push(
                path,
                Rule::TimestampStale,
                format!(
                    "timestamp {t} is {} ms older than now ({now}); at most {behind} ms is tolerated",
                    now - t
                ),
            );
        }
        if let (Some(now), Some(ahead)) = (self.now_ms, self.window.ahead_ms)
            && t > now + ahead
        {
            self.push(
                path,
                Rule::TimestampStale,
                format!(
                    "timestamp {t} is {} ms ahead of now ({now}); at most {ahead} ms is tolerated (the bridge's clock skew)",
                    t - now
                ),
            );
        }
    }

    /// A command's timestamp: not negative, [`Sink::timestamp`]'s rules,
    /// and Unix milliseconds, not seconds: from 10^9 to 10^11 it is refused
    /// (as milliseconds, a time in 1970 to 1973 no clock sends). Feedback is
    /// not held to the last: a device may count milliseconds since it
    /// booted.
    pub(crate) fn command_timestamp(&mut self, path: &Path<'_>, t: f64) {
        self.minimum(path, t, 0.0);
        self.timestamp(path, t);
        if (1e9..1e11).contains(&t) {
            self.push(
                path,
                Rule::TimestampUnit,
                format!(
                    "timestamp {t} looks like seconds: WIA timestamps are Unix milliseconds ({} for that time)",
                    t * 1000.0
                ),
            );
        }
    }

    /// motorwire's motor-id rules (the schema pattern plus a maximum length).
    pub(crate) fn motor_id(&mut self, path: &Path<'_>, id: &str) {
        if let Err(e) = MotorId::validate(id) {
            self.push(path, Rule::MotorId, e.to_string());
        }
    }

    /// `lower <= upper`, both present.
    pub(crate) fn ordered(
        &mut self,
        rule: Rule,
        lower: (&Path<'_>, &'static str, Option<f64>),
        upper: (&'static str, Option<f64>),
    ) {
        if let (Some(lo), Some(hi)) = (lower.2, upper.1)
            && lo.is_finite()
            && hi.is_finite()
            && lo > hi
        {
            self.push(
                lower.0,
                rule,
                format!("{} ({lo}) must be <= {} ({hi})", lower.1, upper.0),
            );
        }
    }

    /// Semantic non-negativity (for quantities the schema leaves open).
    pub(crate) fn non_negative(&mut self, path: &Path<'_>, name: &'static str, v: Option<f64>) {
        if let Some(v) = v
            && v.is_finite()
        {
            self.core(
                path,
                Rule::NonNegative,
                motorwire_core::check::non_negative(name, v),
            );
        }
    }

    /// Semantic positivity.
    pub(crate) fn positive(&mut self, path: &Path<'_>, name: &'static str, v: Option<f64>) {
        if let Some(v) = v
            && v.is_finite()
        {
            self.core(
                path,
                Rule::Positive,
                motorwire_core::check::positive(name, v),
            );
        }
    }

    /// Removes semantic violations at a pointer that already has a schema
    /// violation: `kp: -1` is a `minimum` violation, not also `kp-positive`.
    /// At most [`crate::MAX_VIOLATIONS`] are kept, with the count of the
    /// rest.
    pub(crate) fn finish_counted(mut self) -> (Vec<Violation>, usize) {
        use crate::rule::Level;
        let schema_pointers: Vec<String> = self
            .list
            .iter()
            .filter(|v| v.rule.level() == Level::Schema)
            .map(|v| v.pointer.clone())
            .collect();
        if !schema_pointers.is_empty() {
            self.list.retain(|v| {
                v.rule.level() != Level::Semantic || !schema_pointers.contains(&v.pointer)
            });
        }
        let over = self.list.len().saturating_sub(crate::MAX_VIOLATIONS);
        self.list.truncate(crate::MAX_VIOLATIONS);
        (self.list, self.more.saturating_add(over))
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    /// The schema's `^[a-zA-Z0-9_-]+$`, judged byte by byte, refuses
    /// what a walk over the characters refuses, whatever characters
    /// (one byte or four) stand where.
    #[test]
    fn the_id_pattern_is_the_character_pattern() {
        let chars: Vec<char> = "aZ9_-. \u{7f}\u{80}\u{e9}\u{4e2d}\u{1f916}"
            .chars()
            .collect();
        let mut ids: Vec<String> = vec![String::new()];
        for a in &chars {
            ids.push(a.to_string());
            ids.extend(chars.iter().map(|b| format!("{a}{b}")));
        }
        for id in ids {
            let mut s = Sink::new(None);
            s.id_pattern(&Path::ROOT, &id);
            let refused = !s.finish_counted().0.is_empty();
            let by_characters = id.is_empty() || !id.chars().all(MotorId::is_id_char);
            assert_eq!(refused, by_characters, "{id:?}");
        }
    }
}
