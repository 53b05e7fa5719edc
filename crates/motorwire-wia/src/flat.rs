//! The commonest line a controller writes, read without serde: one flat
//! `MotorCommand` object.
//!
//! A bridge reads a command per line, at the rate the controller writes
//! them. Most of those lines are one flat object:
//! `{"motor_id":"elbow","timestamp":1704067200000,"control_mode":"position","setpoint":30,"velocity_limit":100}`.
//! [`flat_command`] reads exactly that shape, in one pass over its bytes,
//! and declines everything else, which serde then reads (and judges) as
//! before:
//!
//! - members other than `motor_id`, `timestamp`, `control_mode`,
//!   `setpoint`, `velocity_limit`, `acceleration_limit`, `torque_limit`
//!   and `priority`, a member given twice, or one of the first four
//!   missing;
//! - a string with an escape or a control character, a `control_mode`
//!   that is not a mode's name, a `null`, a nested value;
//! - a number with an exponent, more than 22 digits after its point, or
//!   a significand of 2^53 or more; a `priority` that is not an integer.
//!
//! What it accepts it reads to the bit as `serde_json` (with
//! `float_roundtrip`) does: an integer below 2^53 is exact, and a
//! significand below 2^53 divided by a power of ten up to 10^22 (both
//! exact in an `f64`) is one correctly rounded division, which is the
//! correctly rounded value of the decimal. `-0` and `-0.0` are `-0.0`,
//! as serde_json reads them. A test compares the two readings on
//! generated and mutated lines.

use crate::MotorCommand;
use motorwire_core::ControlMode;
use serde_json::Map;

/// 2^53: below it every integer is exact in an `f64`.
const EXACT: u64 = 1 << 53;

/// The powers of ten exact in an `f64`.
const POW10: [f64; 23] = [
    1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15, 1e16,
    1e17, 1e18, 1e19, 1e20, 1e21, 1e22,
];

/// The bytes a string read here ends at: its closing quote, or what it
/// may not hold (an escape, a control character).
#[allow(clippy::indexing_slicing)] // evaluated at compile time
const STOPS: [bool; 256] = {
    let mut t = [false; 256];
    let mut b = 0;
    while b < 0x20 {
        t[b] = true;
        b += 1;
    }
    t[b'"' as usize] = true;
    t[b'\\' as usize] = true;
    t
};

/// The members read here, each a bit of the set seen so far.
const MOTOR_ID: u8 = 1;
const TIMESTAMP: u8 = 1 << 1;
const CONTROL_MODE: u8 = 1 << 2;
const SETPOINT: u8 = 1 << 3;
const VELOCITY_LIMIT: u8 = 1 << 4;
const ACCELERATION_LIMIT: u8 = 1 << 5;
const TORQUE_LIMIT: u8 = 1 << 6;
const PRIORITY: u8 = 1 << 7;
const REQUIRED: u8 = MOTOR_ID | TIMESTAMP | CONTROL_MODE | SETPOINT;

/// `json` as a flat `MotorCommand` (see the module's docs), or `None`
/// where serde must read it. Not validated: the caller checks the value
/// as it checks serde's.
pub(crate) fn flat_command(json: &str) -> Option<MotorCommand> {
    let mut c = Cursor { text: json, at: 0 };
    let mut seen = 0u8;
    let mut motor_id = None;
    let mut control_mode = None;
    let (mut timestamp, mut setpoint) = (0.0, 0.0);
    let (mut velocity, mut acceleration, mut torque, mut priority) = (None, None, None, None);
    c.space();
    c.eat(b'{')?;
    loop {
        c.space();
        let bit = c.name()?;
        c.space();
        c.eat(b':')?;
        c.space();
        match bit {
            MOTOR_ID => motor_id = Some(c.string()?),
            TIMESTAMP => timestamp = c.number()?.value(),
            CONTROL_MODE => control_mode = Some(ControlMode::from_name(c.string()?).ok()?),
            SETPOINT => setpoint = c.number()?.value(),
            VELOCITY_LIMIT => velocity = Some(c.number()?.value()),
            ACCELERATION_LIMIT => acceleration = Some(c.number()?.value()),
            TORQUE_LIMIT => torque = Some(c.number()?.value()),
            _ => priority = Some(c.number()?.integer()?),
        }
        if seen & bit != 0 {
            return None;
        }
        seen |= bit;
        c.space();
        match c.next()? {
            b',' => {}
            b'}' => break,
            _ => return None,
        }
    }
    c.space();
    if c.at != json.len() || seen & REQUIRED != REQUIRED {
        return None;
    }
    Some(MotorCommand {
        motor_id: motor_id?.to_owned(),
        timestamp,
        control_mode: control_mode?,
        setpoint,
        velocity_limit: velocity,
        acceleration_limit: acceleration,
        torque_limit: torque,
        pid_gains: None,
        impedance_params: None,
        filter_config: None,
        safety_limits: None,
        priority,
        metadata: None,
        extra: Map::new(),
    })
}

/// A JSON number as read here: its sign, its significand (below 2^53)
/// and how many of its digits follow the point (at most 22).
#[derive(Debug, Clone, Copy)]
struct Number {
    negative: bool,
    significand: u64,
    decimals: usize,
}

impl Number {
    /// As serde_json reads it into an `f64`.
    #[allow(clippy::cast_precision_loss)] // below 2^53: exact
    fn value(self) -> f64 {
        let magnitude = self.significand as f64 / POW10.get(self.decimals).copied().unwrap_or(1.0);
        if self.negative { -magnitude } else { magnitude }
    }

    /// As an integer member reads it (`3`, not `3.0`, which serde reads).
    fn integer(self) -> Option<i64> {
        if self.decimals != 0 {
            return None;
        }
        let n = i64::try_from(self.significand).ok()?;
        Some(if self.negative { -n } else { n })
    }
}

struct Cursor<'a> {
    text: &'a str,
    at: usize,
}

impl<'a> Cursor<'a> {
    fn peek(&self) -> Option<u8> {
        self.text.as_bytes().get(self.at).copied()
    }

    fn next(&mut self) -> Option<u8> {
        let b = self.peek()?;
        self.at += 1;
        Some(b)
    }

    fn eat(&mut self, b: u8) -> Option<()> {
        (self.next()? == b).then_some(())
    }

    /// JSON's white space.
    fn space(&mut self) {
        while matches!(self.peek(), Some(b' ' | b'\t' | b'\n' | b'\r')) {
            self.at += 1;
        }
    }

    /// A member's name, quoted, as its bit: one of the names read here.
    fn name(&mut self) -> Option<u8> {
        let rest = self.text.as_bytes().get(self.at..)?;
        // Each name with its quotes: where the text starts with one, the
        // name has no escape in it.
        let (name, bit): (&[u8], u8) = match rest.get(1)? {
            b'm' => (b"\"motor_id\"", MOTOR_ID),
            b't' if rest.get(2) == Some(&b'i') => (b"\"timestamp\"", TIMESTAMP),
            b't' => (b"\"torque_limit\"", TORQUE_LIMIT),
            b'c' => (b"\"control_mode\"", CONTROL_MODE),
            b's' => (b"\"setpoint\"", SETPOINT),
            b'v' => (b"\"velocity_limit\"", VELOCITY_LIMIT),
            b'a' => (b"\"acceleration_limit\"", ACCELERATION_LIMIT),
            b'p' => (b"\"priority\"", PRIORITY),
            _ => return None,
        };
        rest.starts_with(name).then(|| {
            self.at += name.len();
            bit
        })
    }

    /// A string without escapes or control characters, unquoted.
    fn string(&mut self) -> Option<&'a str> {
        self.eat(b'"')?;
        let start = self.at;
        let rest = self.text.as_bytes().get(start..)?;
        let len = rest
            .iter()
            .position(|&b| STOPS.get(usize::from(b)) != Some(&false))?;
        if rest.get(len) != Some(&b'"') {
            return None;
        }
        self.at = start + len + 1;
        self.text.get(start..start + len)
    }

    /// A number without an exponent whose significand is below 2^53,
    /// with at most 22 digits after its point.
    fn number(&mut self) -> Option<Number> {
        let negative = self.peek() == Some(b'-');
        if negative {
            self.at += 1;
        }
        let mut significand = 0u64;
        let digit = |significand: &mut u64, b: u8| -> Option<()> {
            let s = significand
                .checked_mul(10)?
                .checked_add(u64::from(b - b'0'))?;
            *significand = (s < EXACT).then_some(s)?;
            Some(())
        };
        match self.next()? {
            b'0' => {
                if self.peek().is_some_and(|b| b.is_ascii_digit()) {
                    return None;
                }
            }
            b @ b'1'..=b'9' => {
                digit(&mut significand, b)?;
                while let Some(b @ b'0'..=b'9') = self.peek() {
                    digit(&mut significand, b)?;
                    self.at += 1;
                }
            }
            _ => return None,
        }
        let mut decimals = 0;
        if self.peek() == Some(b'.') {
            self.at += 1;
            while let Some(b @ b'0'..=b'9') = self.peek() {
                digit(&mut significand, b)?;
                decimals += 1;
                self.at += 1;
            }
            if decimals == 0 || decimals >= POW10.len() {
                return None;
            }
        }
        if matches!(self.peek(), Some(b'e' | b'E')) {
            return None;
        }
        Some(Number {
            negative,
            significand,
            decimals,
        })
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// serde's reading of `json` as a plain command (the path this one
    /// stands in front of).
    fn by_serde(json: &str) -> Option<MotorCommand> {
        crate::plain::parse_named(
            json,
            crate::members::top_level_members(crate::MessageKind::MotorCommand),
        )
    }

    /// The two readings agree to the bit wherever the flat one reads.
    fn same(json: &str) -> Option<MotorCommand> {
        let flat = flat_command(json)?;
        let serde = by_serde(json).unwrap_or_else(|| panic!("serde refused {json}"));
        let bits = |v: Option<f64>| v.map(f64::to_bits);
        assert_eq!(flat.motor_id, serde.motor_id, "{json}");
        assert_eq!(
            flat.timestamp.to_bits(),
            serde.timestamp.to_bits(),
            "{json}"
        );
        assert_eq!(flat.control_mode, serde.control_mode, "{json}");
        assert_eq!(flat.setpoint.to_bits(), serde.setpoint.to_bits(), "{json}");
        assert_eq!(
            bits(flat.velocity_limit),
            bits(serde.velocity_limit),
            "{json}"
        );
        assert_eq!(
            bits(flat.acceleration_limit),
            bits(serde.acceleration_limit),
            "{json}"
        );
        assert_eq!(bits(flat.torque_limit), bits(serde.torque_limit), "{json}");
        assert_eq!(flat.priority, serde.priority, "{json}");
        assert!(serde.extra.is_empty() && serde.metadata.is_none(), "{json}");
        assert!(
            serde.pid_gains.is_none() && serde.safety_limits.is_none(),
            "{json}"
        );
        assert!(
            serde.impedance_params.is_none() && serde.filter_config.is_none(),
            "{json}"
        );
        Some(flat)
    }

    #[test]
    fn the_commonest_line_is_read_as_serde_reads_it() {
        let line = r#"{"motor_id":"elbow","timestamp":1704067200000,"control_mode":"position","setpoint":30,"velocity_limit":100}"#;
        let c = same(line).expect("read");
        assert_eq!(c.motor_id, "elbow");
        assert_eq!(c.timestamp, 1_704_067_200_000.0);
        assert_eq!(c.control_mode, ControlMode::Position);
        assert_eq!(c.setpoint, 30.0);
        assert_eq!(c.velocity_limit, Some(100.0));
        assert_eq!(c.acceleration_limit, None);
        let spaced = " \r\n{ \"setpoint\" :\t-12.5 , \"motor_id\":\"a-b_1\",\"control_mode\":\"torque\",\"timestamp\":1.25,\"priority\":-7,\"torque_limit\":0.000001,\"acceleration_limit\":0} \n";
        let c = same(spaced).expect("read");
        assert_eq!(
            (c.setpoint, c.timestamp, c.priority, c.torque_limit),
            (-12.5, 1.25, Some(-7), Some(0.000_001))
        );
        // serde_json reads `-0` and `-0.0` as negative zero, and so does this.
        let zero = r#"{"motor_id":"m","timestamp":-0,"control_mode":"velocity","setpoint":-0.0}"#;
        let c = same(zero).expect("read");
        assert!(c.timestamp.is_sign_negative() && c.setpoint.is_sign_negative());
    }

    #[test]
    fn what_is_not_a_flat_command_is_left_to_serde() {
        let base = r#""motor_id":"elbow","timestamp":1,"control_mode":"position","setpoint":30"#;
        for json in [
            // Other members, nested or unknown; a member twice; one missing.
            format!(r#"{{{base},"metadata":{{}}}}"#),
            format!(r#"{{{base},"velocity_limt":5}}"#),
            format!(r#"{{{base},"setpoint":31}}"#),
            r#"{"motor_id":"elbow","timestamp":1,"control_mode":"position"}"#.to_owned(),
            // Escapes, nulls, other modes' spellings, text after the object.
            format!(r#"{{{base},"velocity_limit":null}}"#),
            r#"{"motor_id":"el\u0062ow","timestamp":1,"control_mode":"position","setpoint":30}"#
                .to_owned(),
            r#"{"motor_id":"elbow","timestamp":1,"control_mode":"Position","setpoint":30}"#
                .to_owned(),
            format!(r#"{{{base}}} x"#),
            format!(r#"{{{base}}}{{}}"#),
            format!("\u{feff}{{{base}}}"),
            // Numbers serde reads another way, or refuses.
            format!(r#"{{{base},"velocity_limit":1e2}}"#),
            format!(r#"{{{base},"velocity_limit":01}}"#),
            format!(r#"{{{base},"velocity_limit":1.}}"#),
            format!(r#"{{{base},"velocity_limit":.5}}"#),
            format!(r#"{{{base},"velocity_limit":+5}}"#),
            format!(r#"{{{base},"velocity_limit":9007199254740992}}"#),
            format!(r#"{{{base},"velocity_limit":0.00000000000000000000001}}"#),
            format!(r#"{{{base},"priority":5.0}}"#),
            format!(r#"{{{base},"velocity_limit":"5"}}"#),
            format!(r#"{{{base},}}"#),
        ] {
            assert!(flat_command(&json).is_none(), "{json}");
        }
        // The largest significand and the most decimals it reads.
        let edge = format!(
            r#"{{{base},"velocity_limit":9007199254740991,"torque_limit":0.0000000000000000000001}}"#
        );
        let c = same(&edge).expect("read");
        assert_eq!(c.velocity_limit, Some(9_007_199_254_740_991.0));
        assert_eq!(c.torque_limit, Some(1e-22));
    }

    /// A number as a controller might write it, of up to `most` digits:
    /// an integer, or digits with a point somewhere among them, signed or
    /// not.
    fn number(most: usize) -> impl Strategy<Value = String> {
        (
            any::<bool>(),
            proptest::string::string_regex(&format!("[0-9]{{1,{most}}}")).unwrap(),
            0usize..23,
        )
            .prop_map(|(neg, digits, point)| {
                let digits = digits.trim_start_matches('0');
                let digits = if digits.is_empty() { "0" } else { digits };
                let sign = if neg { "-" } else { "" };
                if point == 0 || point >= digits.len() + 3 {
                    format!("{sign}{digits}")
                } else if point > digits.len() {
                    format!("{sign}0.{}{digits}", "0".repeat(point - digits.len()))
                } else {
                    let (int, frac) = digits.split_at(digits.len() - point);
                    let int = if int.is_empty() { "0" } else { int };
                    format!("{sign}{int}.{frac}")
                }
            })
    }

    /// A command's text: the four members it needs and `more` (numbers of
    /// up to `most` digits), in an order turned by `turn`, with `pad`
    /// around every token.
    fn line(most: usize, more: std::ops::Range<usize>) -> impl Strategy<Value = String> {
        let member = prop_oneof![
            number(most).prop_map(|n| ("velocity_limit", n)),
            number(most).prop_map(|n| ("acceleration_limit", n)),
            number(most).prop_map(|n| ("torque_limit", n)),
            "-?[1-9][0-9]{0,5}".prop_map(|n| ("priority", n)),
        ];
        (
            number(most),
            number(most),
            prop::sample::select(vec!["position", "velocity", "torque", "trajectory"]),
            prop::collection::vec(member, more),
            prop::sample::select(vec!["", " ", "\n\t", "\r\n  "]),
            any::<prop::sample::Index>(),
        )
            .prop_map(|(t, s, mode, more, pad, turn)| {
                let mut members = vec![
                    r#""motor_id":"elbow-2_b""#.to_owned(),
                    format!(r#""timestamp"{pad}:{pad}{t}"#),
                    format!(r#""control_mode":"{mode}""#),
                    format!(r#""setpoint":{pad}{s}"#),
                ];
                members.extend(
                    more.into_iter()
                        .map(|(k, v)| format!(r#""{k}"{pad}:{pad}{v}"#)),
                );
                let n = members.len();
                members.rotate_left(turn.index(n));
                format!(
                    "{pad}{{{pad}{}{pad}}}{pad}",
                    members.join(&format!("{pad},{pad}"))
                )
            })
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(4096))]

        /// Wherever the flat reading reads a line (numbers of any length,
        /// members perhaps twice), serde reads the same value to the bit.
        #[test]
        fn the_flat_reading_agrees_with_serde(json in line(20, 0..6)) {
            same(&json);
        }

        /// A command of distinct members whose numbers have at most 15
        /// digits is always read here, and as serde reads it.
        #[test]
        fn a_flat_command_of_short_numbers_is_read(json in line(15, 0..2)) {
            prop_assert!(same(&json).is_some(), "{}", json);
        }

        /// A line with one byte changed anywhere is read the same both
        /// ways, or left to serde.
        #[test]
        fn a_mutated_line_is_never_read_differently(json in line(20, 0..4), at in any::<prop::sample::Index>(), b in any::<u8>()) {
            let mut bytes = json.into_bytes();
            let i = at.index(bytes.len());
            bytes[i] = b;
            if let Ok(json) = String::from_utf8(bytes) {
                same(&json);
            }
        }
    }
}
