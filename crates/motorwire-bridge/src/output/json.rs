//! The result and completion lines written directly as JSON text.
//!
//! A line's result and its completion are written for every command, so
//! they are written here member by member, exactly as `serde_json` writes
//! their `Serialize` derive (the same members in the same order, the same
//! escapes, the same numbers), without its per-call machinery: a member's
//! name is known not to need escaping and goes in whole with its quotes
//! and colon, and a string value with nothing to escape (nearly every one)
//! is copied at once. What is rare on this path (a refusal's broken value,
//! a request's data, the limits, the state) is handed to `serde_json`.
//! `tests::written_as_serde_json_writes_them` holds both to the same bytes.

use serde::Serialize;

use super::{ArrivalLine, ErrorBody, LineResult, MotorArrival, StepReport};

/// A member's name as it is written: `k!("ok")` is `"ok":`.
macro_rules! k {
    ($name:literal) => {
        concat!("\"", $name, "\":")
    };
}

/// One JSON object being written into a line.
pub(crate) struct Json {
    text: String,
    /// No member written yet in the object open now.
    first: bool,
}

impl Json {
    pub(crate) fn with_capacity(n: usize) -> Self {
        Self {
            text: String::with_capacity(n),
            first: true,
        }
    }

    pub(crate) fn into_string(self) -> String {
        self.text
    }

    #[inline(always)]
    fn open(&mut self) {
        self.text.push('{');
        self.first = true;
    }

    #[inline(always)]
    fn close(&mut self) {
        self.text.push('}');
        self.first = false;
    }

    /// A member's name, written whole by [`k!`] (a field's name, which
    /// needs no escape).
    #[inline(always)]
    fn key(&mut self, name: &'static str) {
        if !self.first {
            self.text.push(',');
        }
        self.first = false;
        self.text.push_str(name);
    }

    #[inline(always)]
    fn bool(&mut self, name: &'static str, v: bool) {
        self.key(name);
        self.text.push_str(if v { "true" } else { "false" });
    }

    #[inline(always)]
    fn u64(&mut self, name: &'static str, v: u64) {
        self.key(name);
        push_u64(&mut self.text, v);
    }

    #[inline(always)]
    fn str(&mut self, name: &'static str, v: &str) {
        self.key(name);
        push_str(&mut self.text, v);
    }

    /// The member `name` when there is a value.
    #[inline(always)]
    fn opt_str(&mut self, name: &'static str, v: Option<&str>) {
        if let Some(v) = v {
            self.str(name, v);
        }
    }

    /// The member `name` when there is a value.
    #[inline(always)]
    fn opt_u64(&mut self, name: &'static str, v: Option<u64>) {
        if let Some(v) = v {
            self.u64(name, v);
        }
    }

    /// The member `name`: an array of `items`, each written by `each`.
    fn array<T>(
        &mut self,
        name: &'static str,
        items: &[T],
        mut each: impl FnMut(&T, &mut Self) -> Result<(), serde_json::Error>,
    ) -> Result<(), serde_json::Error> {
        self.key(name);
        self.text.push('[');
        for (i, item) in items.iter().enumerate() {
            if i > 0 {
                self.text.push(',');
            }
            each(item, self)?;
        }
        self.text.push(']');
        Ok(())
    }

    fn strs(&mut self, name: &'static str, v: &[String]) {
        self.key(name);
        self.text.push('[');
        for (i, s) in v.iter().enumerate() {
            if i > 0 {
                self.text.push(',');
            }
            push_str(&mut self.text, s);
        }
        self.text.push(']');
    }

    /// Each loss as its text, `field: kind: detail`, written in place.
    fn losses(&mut self, name: &'static str, v: &[motorwire_translate::Loss]) {
        self.key(name);
        self.text.push('[');
        for (i, l) in v.iter().enumerate() {
            if i > 0 {
                self.text.push(',');
            }
            self.text.push('"');
            push_unquoted(&mut self.text, &l.field);
            self.text.push_str(": ");
            self.text.push_str(l.kind.name());
            self.text.push_str(": ");
            push_unquoted(&mut self.text, &l.detail);
            self.text.push('"');
        }
        self.text.push(']');
    }

    fn f32(&mut self, name: &'static str, v: f32) -> Result<(), serde_json::Error> {
        self.key(name);
        // A whole number of up to seven digits (a target such as 30) is
        // written by serde_json as its digits and `.0`.
        if v.fract() == 0.0 && v.abs() < 1.0e7 && !(v == 0.0 && v.is_sign_negative()) {
            #[allow(clippy::cast_possible_truncation)]
            let n = v as i32;
            if n < 0 {
                self.text.push('-');
            }
            push_u64(&mut self.text, u64::from(n.unsigned_abs()));
            self.text.push_str(".0");
            return Ok(());
        }
        push_number(&mut self.text, &v)
    }

    fn f64(&mut self, name: &'static str, v: f64) -> Result<(), serde_json::Error> {
        self.key(name);
        push_number(&mut self.text, &v)
    }

    /// The member `name` as `serde_json` writes `v` (what is rare on this
    /// path: a JSON value, the state).
    fn serde<T: Serialize + ?Sized>(
        &mut self,
        name: &'static str,
        v: &T,
    ) -> Result<(), serde_json::Error> {
        self.key(name);
        self.text.push_str(&serde_json::to_string(v)?);
        Ok(())
    }
}

/// A number as `serde_json` writes it, through a buffer on the stack (an
/// f32 or f64 takes at most 24 bytes).
fn push_number<T: Serialize>(s: &mut String, v: &T) -> Result<(), serde_json::Error> {
    let mut buf = [0u8; 48];
    let mut cursor = std::io::Cursor::new(&mut buf[..]);
    serde_json::to_writer(&mut cursor, v)?;
    let n = usize::try_from(cursor.position()).unwrap_or(0);
    let text = buf.get(..n).unwrap_or_default();
    s.push_str(core::str::from_utf8(text).map_err(serde::ser::Error::custom)?);
    Ok(())
}

/// `superseded by line N of client C`, the reason of a watched line whose
/// motor took a newer line's move: made for every move that replaces one
/// under way, so built without the formatting machinery.
pub(crate) fn superseded_by(by: super::LineRef) -> String {
    let mut s = String::with_capacity(64);
    s.push_str("superseded by line ");
    push_u64(&mut s, by.line);
    s.push_str(" of client ");
    push_u64(&mut s, by.origin.0);
    s
}

/// `v` in decimal, as `serde_json` writes a `u64`.
fn push_u64(s: &mut String, v: u64) {
    s.push_str(itoa::Buffer::new().format(v));
}

/// `v` as a JSON string, escaped as `serde_json` escapes it: `"`, `\\` and
/// the control characters below U+0020 (`\\b \\t \\n \\f \\r` by name, the
/// others as `\\u00XX`); nothing else.
fn push_str(s: &mut String, v: &str) {
    s.push('"');
    push_unquoted(s, v);
    s.push('"');
}

/// `v` escaped as inside a JSON string, without its quotes.
fn push_unquoted(s: &mut String, v: &str) {
    // Nearly every string has nothing to escape: one pass over its bytes
    // that does not stop early (so the compiler can take many at a time),
    // then the whole string at once.
    let needs = v
        .bytes()
        .fold(false, |n, b| n | (b < 0x20) | (b == b'"') | (b == b'\\'));
    if needs {
        push_escaped(s, v);
    } else {
        s.push_str(v);
    }
}

#[cold]
fn push_escaped(s: &mut String, v: &str) {
    let mut from = 0;
    for (i, &b) in v.as_bytes().iter().enumerate() {
        let escape: &str = match b {
            b'"' => "\\\"",
            b'\\' => "\\\\",
            b'\n' => "\\n",
            b'\r' => "\\r",
            b'\t' => "\\t",
            0x08 => "\\b",
            0x0C => "\\f",
            0x00..=0x1F => "",
            _ => continue,
        };
        // Everything before `i` since the last escape, unchanged: `i` is a
        // byte below 0x80, so a character's boundary.
        s.push_str(v.get(from..i).unwrap_or_default());
        if escape.is_empty() {
            const HEX: &[u8; 16] = b"0123456789abcdef";
            s.push_str("\\u00");
            s.push(char::from(
                HEX.get(usize::from(b >> 4)).copied().unwrap_or(b'0'),
            ));
            s.push(char::from(
                HEX.get(usize::from(b & 0xF)).copied().unwrap_or(b'0'),
            ));
        } else {
            s.push_str(escape);
        }
        from = i + 1;
    }
    s.push_str(v.get(from..).unwrap_or_default());
}

impl LineResult {
    /// Room for the result's line: its strings, and its members' names
    /// and numbers (most results fit, so the line is not grown as written).
    pub(crate) fn json_capacity(&self) -> usize {
        let strings: usize = self
            .losses
            .iter()
            .map(|l| l.field.len() + l.detail.len() + 16)
            .sum::<usize>()
            + self
                .acked
                .as_ref()
                .map_or(0, |a| a.iter().map(|m| m.len() + 3).sum())
            + self.error.as_ref().map_or(0, |e| e.message.len() + 160);
        strings + 160
    }

    /// Writes the result as `serde_json` writes its `Serialize`.
    pub(crate) fn write_json(&self, j: &mut Json) -> Result<(), serde_json::Error> {
        j.open();
        j.bool(k!("ok"), self.ok);
        j.u64(k!("line"), self.line);
        j.opt_str(k!("motor_id"), self.motor_id.as_deref());
        j.opt_str(k!("command_id"), self.command_id.as_deref());
        j.opt_str(k!("orion"), self.orion.as_deref());
        if self.emergency_stop {
            j.bool(k!("emergency_stop"), true);
        }
        if self.released {
            j.bool(k!("released"), true);
        }
        if let Some(e) = &self.error {
            j.key(k!("error"));
            e.write_json(j)?;
        }
        if let Some(a) = &self.acked {
            j.strs(k!("acked"), a);
        }
        if let Some(f) = self.arrival_follows {
            j.bool(k!("arrival_follows"), f);
        }
        if self.superseded {
            j.bool(k!("superseded"), true);
        }
        if !self.outcomes.is_empty() {
            j.array(k!("outcomes"), &self.outcomes, |o, j| {
                o.write_json(j);
                Ok(())
            })?;
        }
        if !self.problems.is_empty() {
            j.strs(k!("problems"), &self.problems);
        }
        if let Some(n) = self.more_problems {
            j.serde(k!("more_problems"), &n)?;
        }
        j.opt_u64(k!("latency_us"), self.latency_us);
        j.opt_u64(k!("ack_us"), self.ack_us);
        j.opt_u64(k!("stop_latency_us"), self.stop_latency_us);
        if !self.losses.is_empty() {
            j.losses(k!("losses"), &self.losses);
        }
        if let Some(n) = self.more_losses {
            j.serde(k!("more_losses"), &n)?;
        }
        if let Some(d) = &self.data {
            j.serde(k!("data"), d)?;
        }
        if let Some(l) = &self.limits {
            j.serde(k!("limits"), l)?;
        }
        if let Some(s) = &self.state {
            j.serde(k!("state"), s)?;
        }
        if let Some(hz) = self.feedback_hz {
            j.f64(k!("feedback_hz"), hz)?;
        }
        j.close();
        Ok(())
    }
}

impl ErrorBody {
    fn write_json(&self, j: &mut Json) -> Result<(), serde_json::Error> {
        j.open();
        j.str(k!("kind"), self.kind.name());
        j.str(k!("rule"), self.rule);
        j.str(k!("message"), &self.message);
        j.opt_str(k!("motor"), self.motor.as_deref());
        if let Some(b) = &self.broke {
            // Flattened: its members are the error's own.
            j.opt_str(k!("field"), b.field);
            if let Some(v) = b.value {
                j.f64(k!("value"), v)?;
            }
            if let Some(l) = b.limit {
                j.f64(k!("limit"), l)?;
            }
            j.opt_str(k!("limit_name"), b.limit_name);
            j.opt_str(k!("limit_source"), b.limit_source);
        }
        if let Some(v) = &self.violations {
            j.serde(k!("violations"), v)?;
        }
        if let Some(n) = self.more_violations {
            j.serde(k!("more_violations"), &n)?;
        }
        j.close();
        Ok(())
    }
}

impl StepReport {
    fn write_json(&self, j: &mut Json) {
        j.open();
        j.str(k!("motor"), &self.motor);
        j.str(k!("outcome"), self.outcome.name());
        if let Some(c) = self.code {
            j.u64(k!("code"), u64::from(c));
        }
        j.str(k!("message"), &self.message);
        j.close();
    }
}

impl ArrivalLine {
    /// Room for the completion's line: its strings, its members' names and
    /// numbers, and each motor's (so the line is not grown as written).
    pub(crate) fn json_capacity(&self) -> usize {
        let strings = [&self.motor_id, &self.command_id, &self.reason]
            .into_iter()
            .flatten()
            .map(|s| s.len() + 16)
            .sum::<usize>();
        let motors: usize = self.motors.iter().map(|m| m.motor_id.len() + 96).sum();
        strings + motors + 64
    }

    /// Writes the completion as `serde_json` writes its `Serialize`.
    pub(crate) fn write_json(&self, j: &mut Json) -> Result<(), serde_json::Error> {
        j.open();
        j.bool(k!("arrived"), self.arrived);
        j.u64(k!("line"), self.line);
        j.opt_str(k!("motor_id"), self.motor_id.as_deref());
        j.opt_str(k!("command_id"), self.command_id.as_deref());
        j.opt_str(k!("reason"), self.reason.as_deref());
        j.u64(k!("after_ms"), self.after_ms);
        j.array(k!("motors"), &self.motors, MotorArrival::write_json)?;
        j.close();
        Ok(())
    }
}

impl MotorArrival {
    fn write_json(&self, j: &mut Json) -> Result<(), serde_json::Error> {
        j.open();
        j.str(k!("motor_id"), &self.motor_id);
        j.bool(k!("arrived"), self.arrived);
        j.f32(k!("target"), self.target)?;
        if let Some(e) = self.error {
            j.f32(k!("error"), e)?;
        }
        if let Some(a) = self.after_ms {
            j.u64(k!("after_ms"), a);
        }
        j.close();
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use proptest::prelude::*;

    use super::*;
    use crate::output::{BridgeState, Broke, ErrorKind, MotorState, StepOutcome};

    fn written(r: &LineResult) -> String {
        let mut j = Json::with_capacity(0);
        r.write_json(&mut j).unwrap();
        j.into_string()
    }

    fn written_arrival(a: &ArrivalLine) -> String {
        let mut j = Json::with_capacity(0);
        a.write_json(&mut j).unwrap();
        j.into_string()
    }

    #[test]
    fn a_result_with_every_member_is_written_as_serde_json_writes_it() {
        let r = LineResult {
            ok: false,
            line: 18_446_744_073_709_551_615,
            motor_id: Some("elbow \"left\"\\\n\u{1}\u{7f}é😀".into()),
            command_id: Some("c-1".into()),
            orion: Some("fold".into()),
            emergency_stop: true,
            released: true,
            error: Some(ErrorBody {
                kind: ErrorKind::Refused,
                rule: "outside_limit",
                message: "setpoint 170 is outside max_position\t(bus map) 150".into(),
                motor: Some("elbow".into()),
                broke: Some(Box::new(Broke {
                    field: Some("setpoint"),
                    value: Some(170.25),
                    limit: Some(1e300),
                    limit_name: Some("max_position"),
                    limit_source: Some("bus map"),
                })),
                violations: Some(serde_json::json!([{"path": "/setpoint", "x": [1, 2.5]}])),
                more_violations: Some(3),
            }),
            acked: Some(vec!["elbow".into(), String::new()]),
            arrival_follows: Some(false),
            superseded: true,
            outcomes: vec![
                StepReport {
                    motor: "gripper".into(),
                    outcome: StepOutcome::Nacked,
                    code: Some(65_535),
                    message: "nacked \u{8}\u{c}\r".into(),
                },
                StepReport {
                    motor: "wrist".into(),
                    outcome: StepOutcome::OutcomeUnknown,
                    code: None,
                    message: "".into(),
                },
            ],
            problems: vec!["a".into(), "b\u{1f}".into()],
            more_problems: Some(7),
            more_losses: Some(2),
            latency_us: Some(0),
            ack_us: Some(17),
            stop_latency_us: Some(99),
            losses: vec![motorwire_translate::Loss {
                field: "max_jerk".into(),
                kind: motorwire_translate::LossKind::Defaulted,
                detail: "2000 from the \"bus\" map\n".into(),
            }],
            data: Some(serde_json::json!({"telemetry": {"voltage": 0.1}})),
            limits: Some(serde_json::json!({"effective": {"max_position": 150.0}})),
            state: Some(BridgeState {
                latched: true,
                motors: vec![MotorState {
                    motor_id: "elbow".into(),
                    online: true,
                    active: false,
                    position: Some(-0.0),
                    velocity: None,
                    target: Some(1.5),
                    moving: true,
                    fault: Some("overheated".into()),
                }],
            }),
            feedback_hz: Some(12.5),
            feedback_every: Some(4),
        };
        assert_eq!(written(&r), serde_json::to_string(&r).unwrap());
        let plain = LineResult {
            ok: true,
            line: 1,
            ..LineResult::default()
        };
        assert_eq!(written(&plain), r#"{"ok":true,"line":1}"#);
    }

    #[test]
    fn a_completion_is_written_as_serde_json_writes_it() {
        let a = ArrivalLine {
            arrived: false,
            line: 2,
            motor_id: Some("elbow".into()),
            command_id: None,
            reason: Some("superseded by line 3 of client 0".into()),
            after_ms: 4,
            motors: vec![
                MotorArrival {
                    motor_id: "elbow".into(),
                    arrived: false,
                    target: 0.1,
                    error: Some(7.6e-6),
                    after_ms: None,
                },
                MotorArrival {
                    motor_id: "wrist".into(),
                    arrived: true,
                    target: -1e30,
                    error: None,
                    after_ms: Some(753),
                },
            ],
        };
        let text = written_arrival(&a);
        assert_eq!(text, serde_json::to_string(&a).unwrap());
        assert!(
            text.contains(r#""target":0.1,"error":0.0000076}"#),
            "{text}"
        );
    }

    #[test]
    fn whole_f32s_are_written_as_serde_json_writes_them() {
        let mut values: Vec<f32> = (-10_000..=10_000).map(|n| n as f32).collect();
        values.extend((0..2_000).map(|k| (k * 4_999) as f32));
        values.extend([
            9_999_999.0,
            -9_999_999.0,
            1.0e7,
            16_777_216.0,
            -0.0,
            0.0,
            0.5,
        ]);
        for v in values {
            let mut j = Json::with_capacity(0);
            j.f32(k!("v"), v).unwrap();
            assert_eq!(
                j.into_string(),
                format!("\"v\":{}", serde_json::to_string(&v).unwrap()),
                "{v}"
            );
        }
    }

    proptest! {
        #[test]
        fn the_superseded_reason_is_what_format_writes(line in any::<u64>(), origin in any::<u64>()) {
            let by = crate::output::LineRef { origin: crate::output::Origin(origin), line };
            prop_assert_eq!(
                superseded_by(by),
                format!("superseded by line {line} of client {origin}")
            );
        }

        #[test]
        fn written_as_serde_json_writes_them(
            texts in proptest::collection::vec(any::<String>(), 6),
            numbers in proptest::collection::vec(any::<u64>(), 3),
            floats in proptest::collection::vec(any::<f32>().prop_filter("finite", |f| f.is_finite()), 2),
            flags in proptest::collection::vec(any::<bool>(), 6),
        ) {
            let r = LineResult {
                ok: flags[0],
                line: numbers[0],
                motor_id: flags[1].then(|| texts[0].clone()),
                error: flags[2].then(|| ErrorBody::new(ErrorKind::Busy, texts[1].clone()).about(texts[2].clone())),
                acked: flags[3].then(|| vec![texts[3].clone(), texts[4].clone()]),
                latency_us: Some(numbers[1]),
                losses: vec![motorwire_translate::Loss {
                    field: texts[5].clone().into(),
                    kind: motorwire_translate::LossKind::Converted,
                    detail: texts[0].clone().into(),
                }],
                outcomes: vec![StepReport {
                    motor: texts[4].clone(),
                    outcome: StepOutcome::Cancelled,
                    code: flags[4].then_some(7),
                    message: texts[1].clone().into(),
                }],
                ..LineResult::default()
            };
            prop_assert_eq!(written(&r), serde_json::to_string(&r).unwrap());
            let a = ArrivalLine {
                arrived: flags[5],
                line: numbers[2],
                motor_id: None,
                command_id: Some(texts[0].clone()),
                reason: Some(texts[2].clone()),
                after_ms: numbers[1],
                motors: vec![MotorArrival {
                    motor_id: texts[3].clone(),
                    arrived: flags[0],
                    target: floats[0],
                    error: Some(floats[1]),
                    after_ms: Some(numbers[0]),
                }],
            };
            prop_assert_eq!(written_arrival(&a), serde_json::to_string(&a).unwrap());
        }
    }
}
