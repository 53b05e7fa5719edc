//! One parse for the commonest documents a bridge reads: a `MotorCommand`
//! or a multi-axis command, and nothing else
//! ([`crate::Validator::parse_plain_command`],
//! [`crate::Validator::parse_plain_multi_axis`]).
//!
//! The typed parse is told the kind's top-level names (its schema's, as
//! the unknown-member check reads them): it stops at the first other name
//! (another kind's, a bridge's own form, a misspelling), before reading
//! that member's value. Nothing is scanned before the parse to tell the
//! kind, and nothing after it to find unknown members or the nesting
//! depth: the typed value says both.

use std::borrow::Cow;
use std::fmt;
use std::marker::PhantomData;

use serde::de::value::{BorrowedStrDeserializer, StringDeserializer};
use serde::de::{self, Deserialize, DeserializeSeed, Deserializer, Error as _, MapAccess, Visitor};
use serde::forward_to_deserialize_any;

/// A kind a bridge reads with one parse: its typed value says all a scan
/// of its text would (the `extra` maps hold any unknown member, at every
/// level), except how deep a free-form member nests.
pub(crate) trait Plain: crate::kind::WiaMessage + crate::members::Unknowns {
    /// Whether the value may nest deeper than `max_depth` (a free-form
    /// member, or its own parts deeper than that): then the text is read
    /// for its depth.
    fn may_nest_beyond(&self, max_depth: usize) -> bool;

    /// The value read from `json` without serde where the text has the
    /// kind's commonest shape, to the bit as serde reads it; `None` where
    /// serde must read it (the default: every other kind).
    fn read_flat(json: &str) -> Option<Self>
    where
        Self: Sized,
    {
        let _ = json;
        None
    }
}

impl Plain for crate::MotorCommand {
    /// Without `metadata`, two objects deep at most: the command, a part.
    fn may_nest_beyond(&self, max_depth: usize) -> bool {
        let parts = self.pid_gains.is_some()
            || self.impedance_params.is_some()
            || self.filter_config.is_some()
            || self.safety_limits.is_some();
        self.metadata.is_some() || 1 + usize::from(parts) > max_depth
    }

    /// One flat object, the commonest line a controller writes
    /// ([`crate::flat`]).
    fn read_flat(json: &str) -> Option<Self> {
        crate::flat::flat_command(json)
    }
}

impl Plain for crate::MultiAxisCommand {
    /// Without a `metadata`, four levels at most: the command, its
    /// `motors`, an axis, an axis's gains or limits.
    fn may_nest_beyond(&self, max_depth: usize) -> bool {
        self.metadata.is_some() || self.motors.iter().any(|a| a.metadata.is_some()) || max_depth < 4
    }
}

/// `T` from the JSON object `json` whose top-level names are all in
/// `names` (a kind's: [`crate::members::top_level_members`]): `None` at
/// the first other name (its value not read), on any parse error, or when
/// text other than white space follows the object.
pub(crate) fn parse_named<'de, T: Deserialize<'de>>(
    json: &'de str,
    names: &'static [&'static str],
) -> Option<T> {
    let mut de = serde_json::Deserializer::from_str(json);
    let value = T::deserialize(Only {
        inner: &mut de,
        names,
    })
    .ok()?;
    de.end().ok()?;
    Some(value)
}

/// A deserializer of one JSON object that refuses a member whose name is
/// not in `names` (nested objects are read as they are).
struct Only<D> {
    inner: D,
    names: &'static [&'static str],
}

impl<'de, D: Deserializer<'de>> Deserializer<'de> for Only<D> {
    type Error = D::Error;

    fn deserialize_any<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, D::Error> {
        self.inner.deserialize_map(OnlyVisitor {
            inner: visitor,
            names: self.names,
        })
    }

    forward_to_deserialize_any! {
        bool i8 i16 i32 i64 i128 u8 u16 u32 u64 u128 f32 f64 char str string
        bytes byte_buf option unit unit_struct newtype_struct seq tuple
        tuple_struct map struct enum identifier ignored_any
    }
}

struct OnlyVisitor<V> {
    inner: V,
    names: &'static [&'static str],
}

impl<'de, V: Visitor<'de>> Visitor<'de> for OnlyVisitor<V> {
    type Value = V::Value;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        self.inner.expecting(f)
    }

    fn visit_map<A: MapAccess<'de>>(self, map: A) -> Result<V::Value, A::Error> {
        self.inner.visit_map(OnlyMap {
            inner: map,
            names: self.names,
        })
    }
}

struct OnlyMap<A> {
    inner: A,
    names: &'static [&'static str],
}

impl<'de, A: MapAccess<'de>> MapAccess<'de> for OnlyMap<A> {
    type Error = A::Error;

    fn next_key_seed<K: DeserializeSeed<'de>>(
        &mut self,
        seed: K,
    ) -> Result<Option<K::Value>, A::Error> {
        let Some(name) = self.inner.next_key_seed(Name(PhantomData))? else {
            return Ok(None);
        };
        if !self.names.contains(&&*name) {
            return Err(A::Error::custom("a member this parse does not take"));
        }
        match name {
            Cow::Borrowed(s) => seed.deserialize(BorrowedStrDeserializer::new(s)),
            Cow::Owned(s) => seed.deserialize(StringDeserializer::new(s)),
        }
        .map(Some)
    }

    fn next_value_seed<S: DeserializeSeed<'de>>(&mut self, seed: S) -> Result<S::Value, A::Error> {
        self.inner.next_value_seed(seed)
    }

    fn size_hint(&self) -> Option<usize> {
        self.inner.size_hint()
    }
}

/// A member name, borrowed from the text when it has no escape.
struct Name<'de>(PhantomData<&'de ()>);

impl<'de> DeserializeSeed<'de> for Name<'de> {
    type Value = Cow<'de, str>;

    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<Cow<'de, str>, D::Error> {
        d.deserialize_str(self)
    }
}

impl<'de> Visitor<'de> for Name<'de> {
    type Value = Cow<'de, str>;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("a member name")
    }

    fn visit_borrowed_str<E: de::Error>(self, v: &'de str) -> Result<Cow<'de, str>, E> {
        Ok(Cow::Borrowed(v))
    }

    fn visit_str<E: de::Error>(self, v: &str) -> Result<Cow<'de, str>, E> {
        Ok(Cow::Owned(v.to_owned()))
    }

    fn visit_string<E: de::Error>(self, v: String) -> Result<Cow<'de, str>, E> {
        Ok(Cow::Owned(v))
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

    use super::*;
    use crate::MessageKind;
    use crate::MotorCommand;
    use crate::members::top_level_members;

    #[test]
    fn a_name_not_taken_stops_the_parse_and_escaped_names_are_read() {
        // A command's names, as its schema gives them.
        let names = top_level_members(MessageKind::MotorCommand);
        assert_eq!(names.len(), 13);
        for n in ["motor_id", "setpoint", "safety_limits", "metadata"] {
            assert!(names.contains(&n), "{n}");
        }
        let ok = r#"{"motor_id":"elbow","timestamp":1,"control_mode":"position","setpoint":2}"#;
        let c: MotorCommand =
            parse_named(ok, top_level_members(MessageKind::MotorCommand)).unwrap();
        assert_eq!((c.motor_id.as_str(), c.setpoint), ("elbow", 2.0));
        // An escaped name is the name it spells.
        let escaped =
            r#"{"motor_id":"elbow","timestamp":1,"control_mode":"position","set\u0070oint":3}"#;
        let c: MotorCommand =
            parse_named(escaped, top_level_members(MessageKind::MotorCommand)).unwrap();
        assert_eq!(c.setpoint, 3.0);
        for refused in [
            // Another member, wherever it stands.
            r#"{"reset":"elbow","motor_id":"elbow","timestamp":1,"control_mode":"position","setpoint":2}"#,
            r#"{"motor_id":"elbow","timestamp":1,"control_mode":"position","setpoint":2,"emergency_stop":true}"#,
            r#"{"motor_id":"elbow","timestamp":1,"control_mode":"position","setpoint":2,"velocity_limt":5}"#,
            // A name taken twice, text after the object, not an object.
            r#"{"motor_id":"elbow","timestamp":1,"control_mode":"position","setpoint":2,"setpoint":3}"#,
            r#"{"motor_id":"elbow","timestamp":1,"control_mode":"position","setpoint":2} x"#,
            r#"[{"motor_id":"elbow"}]"#,
        ] {
            assert!(
                parse_named::<MotorCommand>(refused, top_level_members(MessageKind::MotorCommand))
                    .is_none(),
                "{refused}"
            );
        }
        // Nested members are the nested parts' own: an unknown one is kept
        // in that part's `extra`, for the caller to see.
        let nested = r#"{"motor_id":"elbow","timestamp":1,"control_mode":"position","setpoint":2,"pid_gains":{"kq":1}}"#;
        let c: MotorCommand =
            parse_named(nested, top_level_members(MessageKind::MotorCommand)).unwrap();
        assert_eq!(c.pid_gains.unwrap().extra.len(), 1);
    }

    /// A multi-axis command read once is the command `parse_any` reads,
    /// and every other line (a member unknown at any level, a violation,
    /// too deep, another kind) is `None`, under three validators.
    #[test]
    fn a_plain_multi_axis_command_is_the_one_parse_any_reads() {
        use crate::{Message, Validator};
        let axis = r#"{"motor_id":"elbow","control_mode":"position","setpoint":20}"#;
        let line = |axes: &str, rest: &str| {
            format!(r#"{{"command_id":"c","timestamp":1,"motors":[{axes}]{rest}}}"#)
        };
        let cases = [
            // (the line, whether it is a plain multi-axis command)
            (line(axis, ""), true),
            (
                line(
                    &format!("{axis},{}", axis.replace("elbow", "wrist")),
                    r#","sync_mode":"simultaneous""#,
                ),
                true,
            ),
            (
                line(
                    r#"{"motor_id":"elbow","control_mode":"position","setpoint":20,"pid_gains":{"kp":1},"safety_limits":{"max_position":90}}"#,
                    r#","coordination":{"type":"linear_interpolation","total_duration_ms":500}"#,
                ),
                true,
            ),
            // A member unknown at the top, in the coordination, in an axis,
            // in an axis's part.
            (line(axis, r#","velocity_limit":5"#), false),
            (line(axis, r#","coordination":{"typo":1}"#), false),
            (
                line(
                    r#"{"motor_id":"elbow","control_mode":"position","setpoint":20,"velocity_limt":5}"#,
                    "",
                ),
                false,
            ),
            (
                line(
                    r#"{"motor_id":"elbow","control_mode":"position","setpoint":20,"pid_gains":{"kq":1}}"#,
                    "",
                ),
                false,
            ),
            // The bridge's own forms and a stop at the top.
            (line(axis, r#","stream":true"#), false),
            (line(axis, r#","emergency_stop":true"#), false),
            // Invalid: no axis, a negative limit, a name twice.
            (line("", ""), false),
            (
                line(
                    r#"{"motor_id":"elbow","control_mode":"position","setpoint":20,"velocity_limit":-1}"#,
                    "",
                ),
                false,
            ),
            (line(axis, r#","command_id":"d""#), false),
            // Another kind.
            (
                r#"{"motor_id":"elbow","timestamp":1,"control_mode":"position","setpoint":2}"#
                    .to_owned(),
                false,
            ),
        ];
        let deep_metadata = line(axis, r#","metadata":{"a":{"b":{"c":1}}}"#);
        for v in [
            Validator::lenient(),
            Validator::new().deny_unknown_members(true),
            Validator::new().max_depth(3),
        ] {
            for (line, plain) in &cases {
                let once = v.parse_plain_multi_axis(line);
                // Read once, it is the command `parse_any` reads; whatever
                // `parse_any` does not read as one is not read as one once.
                match (&once, v.parse_any(line)) {
                    (Some(o), Ok(Message::MultiAxisCommand(c))) => assert_eq!(o, &c, "{line}"),
                    (Some(_), other) => panic!("{line}: {other:?}"),
                    (None, _) => {}
                }
                let deep = v == Validator::new().max_depth(3) && line.contains("pid_gains");
                assert_eq!(once.is_some(), *plain && !deep, "{line}");
            }
            // Free-form metadata is read for its depth.
            let once = v.parse_plain_multi_axis(&deep_metadata);
            let any = v.parse_any(&deep_metadata);
            assert_eq!(once.is_some(), any.is_ok(), "{v:?}");
        }
    }
}
