use core::fmt;
use core::str::FromStr;

use crate::CoreError;

/// A validated motor identifier, stored inline (no allocation).
///
/// A motor id is 1 to [`MotorId::MAX_LEN`] (64) bytes of ASCII letters,
/// digits, `_` and `-`: the WIA MotorCommand schema's pattern
/// `^[a-zA-Z0-9_-]+$`, plus a maximum length the schema leaves open. 64 bytes
/// holds every realistic name (`left_arm_shoulder_pitch_joint_03` is 32) while
/// keeping the type small enough to copy around on a microcontroller.
///
/// ```
/// use motorwire_core::{CoreError, MotorId};
///
/// let id = MotorId::new("shoulder_pitch")?;
/// assert_eq!(id.as_str(), "shoulder_pitch");
/// assert_eq!(MotorId::new("shoulder pitch"), Err(CoreError::MotorIdInvalidChar { index: 8, ch: ' ' }));
/// # Ok::<(), CoreError>(())
/// ```
#[derive(Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct MotorId {
    len: u8,
    bytes: [u8; MotorId::MAX_LEN],
}

impl MotorId {
    /// The longest motor id motorwire accepts, in bytes.
    pub const MAX_LEN: usize = 64;

    /// Validates `id` and stores it.
    ///
    /// # Errors
    /// [`CoreError::MotorIdEmpty`], [`CoreError::MotorIdTooLong`] or
    /// [`CoreError::MotorIdInvalidChar`] (the first offending character).
    pub fn new(id: &str) -> Result<Self, CoreError> {
        Self::validate(id)?;
        let mut bytes = [0u8; Self::MAX_LEN];
        for (slot, byte) in bytes.iter_mut().zip(id.bytes()) {
            *slot = byte;
        }
        Ok(Self {
            // validate() bounds the length by MAX_LEN (64), which fits a u8.
            len: u8::try_from(id.len()).map_err(|_| CoreError::MotorIdTooLong {
                len: id.len(),
                max: Self::MAX_LEN,
            })?,
            bytes,
        })
    }

    /// Checks `id` against the motor-id rules without storing it.
    ///
    /// ```
    /// # use motorwire_core::{CoreError, MotorId};
    /// assert_eq!(MotorId::validate("elbow"), Ok(()));
    /// assert_eq!(MotorId::validate(""), Err(CoreError::MotorIdEmpty));
    /// assert_eq!(
    ///     MotorId::validate(&"a".repeat(65)),
    ///     Err(CoreError::MotorIdTooLong { len: 65, max: 64 })
    /// );
    /// ```
    ///
    /// # Errors
    /// As [`MotorId::new`].
    pub fn validate(id: &str) -> Result<(), CoreError> {
        if id.is_empty() {
            return Err(CoreError::MotorIdEmpty);
        }
        // Byte by byte: every allowed character is ASCII, so the first
        // byte that is not one starts the first character that is not
        // (a character beyond ASCII starts with a byte above 0x7F).
        if let Some(index) = id.bytes().position(|b| !Self::is_id_char(char::from(b))) {
            let ch = id
                .get(index..)
                .and_then(|s| s.chars().next())
                .unwrap_or('\u{FFFD}');
            return Err(CoreError::MotorIdInvalidChar { index, ch });
        }
        if id.len() > Self::MAX_LEN {
            return Err(CoreError::MotorIdTooLong {
                len: id.len(),
                max: Self::MAX_LEN,
            });
        }
        Ok(())
    }

    /// Whether `c` may appear in a motor id.
    pub const fn is_id_char(c: char) -> bool {
        c.is_ascii_alphanumeric() || c == '_' || c == '-'
    }

    /// The id as a string slice.
    pub fn as_str(&self) -> &str {
        let bytes = self.bytes.get(..usize::from(self.len)).unwrap_or(&[]);
        // Only ASCII bytes are ever stored, so this cannot fail; an empty
        // string is returned rather than panicking if it somehow did.
        core::str::from_utf8(bytes).unwrap_or("")
    }
}

impl FromStr for MotorId {
    type Err = CoreError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Self::new(s)
    }
}

impl fmt::Display for MotorId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

impl fmt::Debug for MotorId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "MotorId({:?})", self.as_str())
    }
}

impl AsRef<str> for MotorId {
    fn as_ref(&self) -> &str {
        self.as_str()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn accepts_the_schema_alphabet_up_to_the_maximum() {
        let max = "aZ09_-".repeat(11);
        let max = &max[..64];
        let id = MotorId::new(max).unwrap();
        assert_eq!(id.as_str(), max);
        assert_eq!(MotorId::new("x").unwrap().as_str(), "x");
    }

    #[test]
    fn refuses_what_the_pattern_refuses() {
        assert_eq!(MotorId::new(""), Err(CoreError::MotorIdEmpty));
        assert_eq!(
            MotorId::new("motor.1"),
            Err(CoreError::MotorIdInvalidChar { index: 5, ch: '.' })
        );
        assert_eq!(
            MotorId::new("m\u{e9}"),
            Err(CoreError::MotorIdInvalidChar {
                index: 1,
                ch: '\u{e9}'
            })
        );
        assert_eq!(
            MotorId::new(&"a".repeat(65)),
            Err(CoreError::MotorIdTooLong { len: 65, max: 64 })
        );
    }

    /// The first offending character, found byte by byte, is the one a
    /// walk over the characters finds, wherever it falls and however
    /// long its encoding.
    #[test]
    fn the_offending_character_is_the_first_by_characters() {
        let parts = [
            "a",
            "Z9",
            "_-",
            ".",
            " ",
            "\u{e9}",
            "\u{4e2d}",
            "\u{1f916}",
            "\u{7f}",
            "\u{80}",
        ];
        for a in parts {
            for b in parts {
                for c in parts {
                    let mut buf = [0u8; 16];
                    let mut at = 0;
                    for p in [a, b, c] {
                        buf[at..at + p.len()].copy_from_slice(p.as_bytes());
                        at += p.len();
                    }
                    let id = core::str::from_utf8(&buf[..at]).unwrap();
                    let expected = id
                        .char_indices()
                        .find(|&(_, ch)| !MotorId::is_id_char(ch))
                        .map(|(index, ch)| CoreError::MotorIdInvalidChar { index, ch });
                    assert_eq!(MotorId::validate(id).err(), expected, "{id:?}");
                }
            }
        }
    }

    #[test]
    fn debug_and_display_show_the_id() {
        let id = MotorId::new("elbow").unwrap();
        let mut buf = [0u8; 32];
        let mut w = Writer {
            buf: &mut buf,
            at: 0,
        };
        core::fmt::write(&mut w, format_args!("{id} {id:?}")).unwrap();
        let at = w.at;
        assert_eq!(&buf[..at], b"elbow MotorId(\"elbow\")");
    }

    struct Writer<'a> {
        buf: &'a mut [u8],
        at: usize,
    }

    impl core::fmt::Write for Writer<'_> {
        fn write_str(&mut self, s: &str) -> core::fmt::Result {
            let end = self.at + s.len();
            self.buf
                .get_mut(self.at..end)
                .ok_or(core::fmt::Error)?
                .copy_from_slice(s.as_bytes());
            self.at = end;
            Ok(())
        }
    }
}
