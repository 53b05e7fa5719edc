//! Deserialization helpers that make serde as strict as the JSON Schemas:
//! an optional member may be absent but never `null`, integers accept any
//! JSON number with no fractional part, and enums accept only their strings.

use std::fmt;

use motorwire_core::{ControlMode, FilterKind};
use serde::de::{self, Deserializer, Visitor};
use serde::{Deserialize, Serializer};

/// A present optional member must hold a value of its type: `null` is a type
/// error, as in the schemas (which never allow `null`).
pub(crate) fn some<'de, D, T>(d: D) -> Result<Option<T>, D::Error>
where
    D: Deserializer<'de>,
    T: Deserialize<'de>,
{
    T::deserialize(d).map(Some)
}

/// Largest integer an `f64` holds exactly; timestamps up to here are written
/// back as JSON integers.
const EXACT_F64_INT: f64 = 9_007_199_254_740_992.0;

/// Writes an integral number (a timestamp, a duration in ms) as a JSON
/// integer rather than `1704067200000.0`.
pub(crate) fn number<S: Serializer>(v: &f64, s: S) -> Result<S::Ok, S::Error> {
    if v.fract() == 0.0 && v.abs() <= EXACT_F64_INT {
        // Exact: |v| <= 2^53 and integral.
        #[allow(clippy::cast_possible_truncation)]
        s.serialize_i64(*v as i64)
    } else {
        s.serialize_f64(*v)
    }
}

pub(crate) fn opt_number<S: Serializer>(v: &Option<f64>, s: S) -> Result<S::Ok, S::Error> {
    match v {
        Some(v) => number(v, s),
        None => s.serialize_none(),
    }
}

struct IntegerVisitor;

impl Visitor<'_> for IntegerVisitor {
    type Value = i64;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("an integer")
    }

    fn visit_i64<E: de::Error>(self, v: i64) -> Result<i64, E> {
        Ok(v)
    }

    fn visit_u64<E: de::Error>(self, v: u64) -> Result<i64, E> {
        i64::try_from(v).map_err(|_| E::custom(format_args!("integer {v} does not fit in 64 bits")))
    }

    fn visit_f64<E: de::Error>(self, v: f64) -> Result<i64, E> {
        if v.fract() != 0.0 || !v.is_finite() {
            return Err(E::invalid_type(de::Unexpected::Float(v), &self));
        }
        // i64::MIN is -2^63 exactly; i64::MAX rounds up to 2^63 as f64.
        if (-9_223_372_036_854_775_808.0..9_223_372_036_854_775_808.0).contains(&v) {
            #[allow(clippy::cast_possible_truncation)]
            Ok(v as i64)
        } else {
            Err(E::custom(format_args!(
                "integer {v:e} does not fit in 64 bits"
            )))
        }
    }
}

/// An integer member: JSON Schema's `integer` accepts `3` and `3.0` alike.
pub(crate) fn opt_integer<'de, D: Deserializer<'de>>(d: D) -> Result<Option<i64>, D::Error> {
    d.deserialize_any(IntegerVisitor).map(Some)
}

/// Declares a string-only enum (unit variants written as their names).
macro_rules! string_enum {
    ($(#[$meta:meta])* $vis:vis enum $name:ident { $( $(#[$vdoc:meta])* $variant:ident = $text:literal, )* }) => {
        $(#[$meta])*
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
        $vis enum $name {
            $( $(#[$vdoc])* $variant, )*
        }

        impl $name {
            /// Every value, in schema order.
            pub const ALL: &'static [$name] = &[$($name::$variant,)*];

            /// The value's name in WIA JSON.
            pub const fn name(self) -> &'static str {
                match self { $( $name::$variant => $text, )* }
            }

            /// The value with the given WIA name.
            pub fn from_name(name: &str) -> Option<Self> {
                match name { $( $text => Some($name::$variant), )* _ => None }
            }
        }

        impl ::std::fmt::Display for $name {
            fn fmt(&self, f: &mut ::std::fmt::Formatter<'_>) -> ::std::fmt::Result {
                f.write_str(self.name())
            }
        }

        impl ::serde::Serialize for $name {
            fn serialize<S: ::serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
                s.serialize_str(self.name())
            }
        }

        impl<'de> ::serde::Deserialize<'de> for $name {
            fn deserialize<D: ::serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
                $crate::serde_util::deserialize_name(d, stringify!($name), &[$($text,)*], $name::from_name)
            }
        }
    };
}
pub(crate) use string_enum;

struct NameVisitor<T, F> {
    what: &'static str,
    names: &'static [&'static str],
    parse: F,
    _t: std::marker::PhantomData<T>,
}

impl<T, F: Fn(&str) -> Option<T>> Visitor<'_> for NameVisitor<T, F> {
    type Value = T;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "a {} name", self.what)
    }

    fn visit_str<E: de::Error>(self, v: &str) -> Result<T, E> {
        (self.parse)(v).ok_or_else(|| E::unknown_variant(v, self.names))
    }
}

/// Deserializes one of `names` from a JSON string, and nothing else.
pub(crate) fn deserialize_name<'de, D, T>(
    d: D,
    what: &'static str,
    names: &'static [&'static str],
    parse: fn(&str) -> Option<T>,
) -> Result<T, D::Error>
where
    D: Deserializer<'de>,
{
    d.deserialize_str(NameVisitor {
        what,
        names,
        parse,
        _t: std::marker::PhantomData,
    })
}

const MODE_NAMES: &[&str] = &[
    "position",
    "velocity",
    "torque",
    "impedance",
    "admittance",
    "trajectory",
    "gravity_comp",
    "force_ctrl",
    "hybrid",
    "disabled",
];

/// `ControlMode` (a `motorwire-core` type) as its WIA name.
pub(crate) mod control_mode {
    use super::*;

    pub(crate) fn serialize<S: Serializer>(m: &ControlMode, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(m.name())
    }

    pub(crate) fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<ControlMode, D::Error> {
        deserialize_name(d, "control mode", MODE_NAMES, |n| {
            ControlMode::from_name(n).ok()
        })
    }
}

/// `FilterKind` (a `motorwire-core` type) as its WIA name, when present.
pub(crate) mod opt_filter_kind {
    use super::*;

    #[allow(clippy::ref_option)]
    pub(crate) fn serialize<S: Serializer>(
        k: &Option<FilterKind>,
        s: S,
    ) -> Result<S::Ok, S::Error> {
        match k {
            Some(k) => s.serialize_str(k.name()),
            None => s.serialize_none(),
        }
    }

    pub(crate) fn deserialize<'de, D: Deserializer<'de>>(
        d: D,
    ) -> Result<Option<FilterKind>, D::Error> {
        deserialize_name(
            d,
            "filter type",
            &["none", "lowpass", "notch", "butterworth"],
            |n| FilterKind::from_name(n).ok(),
        )
        .map(Some)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Deserialize, Debug)]
    struct Probe {
        #[serde(default, deserialize_with = "opt_integer")]
        n: Option<i64>,
        #[serde(default, deserialize_with = "some")]
        x: Option<f64>,
    }

    #[test]
    fn integers_accept_integral_numbers_only() {
        let p: Probe = serde_json::from_str(r#"{"n": 3.0}"#).unwrap();
        assert_eq!(p.n, Some(3));
        let p: Probe = serde_json::from_str(r#"{"n": -7}"#).unwrap();
        assert_eq!(p.n, Some(-7));
        let e = serde_json::from_str::<Probe>(r#"{"n": 3.5}"#).unwrap_err();
        assert!(
            e.to_string()
                .starts_with("invalid type: floating point `3.5`, expected an integer"),
            "{e}"
        );
        let e = serde_json::from_str::<Probe>(r#"{"n": 18446744073709551615}"#).unwrap_err();
        assert!(
            e.to_string()
                .starts_with("integer 18446744073709551615 does not fit in 64 bits"),
            "{e}"
        );
        let e = serde_json::from_str::<Probe>(r#"{"n": 1e300}"#).unwrap_err();
        assert!(
            e.to_string()
                .starts_with("integer 1e300 does not fit in 64 bits"),
            "{e}"
        );
    }

    #[test]
    fn present_optionals_refuse_null() {
        let p: Probe = serde_json::from_str("{}").unwrap();
        assert_eq!((p.n, p.x), (None, None));
        let e = serde_json::from_str::<Probe>(r#"{"x": null}"#).unwrap_err();
        assert!(
            e.to_string()
                .starts_with("invalid type: null, expected f64"),
            "{e}"
        );
    }

    #[test]
    fn integral_numbers_serialize_as_integers() {
        #[derive(serde::Serialize)]
        struct T {
            #[serde(serialize_with = "number")]
            t: f64,
        }
        assert_eq!(
            serde_json::to_string(&T { t: 1704067200000.0 }).unwrap(),
            r#"{"t":1704067200000}"#
        );
        assert_eq!(
            serde_json::to_string(&T { t: 1.5 }).unwrap(),
            r#"{"t":1.5}"#
        );
        assert_eq!(
            serde_json::to_string(&T { t: 1e300 }).unwrap(),
            r#"{"t":1e+300}"#
        );
    }
}
