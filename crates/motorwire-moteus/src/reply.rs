//! A reply frame from a controller, decoded by `moteus-protocol`'s frame
//! parser into registers named and scaled as mjbots' Python library does.

use moteus_protocol::{Subframe, SubframeType, parse_arbitration_id};

use crate::registers::{NotAnInteger, Scaled, register_name, scale};

/// One register a reply holds.
#[derive(Debug, Clone, PartialEq)]
pub struct RegisterValue {
    /// Its number.
    pub register: u16,
    /// Its value, scaled as the library scales it.
    pub value: Scaled,
}

impl RegisterValue {
    /// The library's name of the register (`None` for one it does not name).
    pub fn name(&self) -> Option<&'static str> {
        register_name(self.register)
    }
}

/// An error subframe: the controller could not read or write a register.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RegisterError {
    /// The register.
    pub register: u16,
    /// The controller's error code.
    pub code: u16,
    /// Whether it was a write (else a read).
    pub write: bool,
}

/// A decoded reply.
#[derive(Debug, Clone, PartialEq)]
pub struct Reply {
    /// The controller that sent it (bits 8..14 of the CAN id).
    pub source: u8,
    /// The id it was sent to (bits 0..6).
    pub destination: u8,
    /// The CAN prefix (bits 16..28).
    pub can_prefix: u16,
    /// The registers it holds, in order of first appearance (a register
    /// sent twice keeps its last value, as the library's dict does).
    pub values: Vec<RegisterValue>,
    /// Its error subframes, in order.
    pub errors: Vec<RegisterError>,
}

impl Reply {
    /// The value of `register`, if the reply holds it.
    pub fn get(&self, register: u16) -> Option<Scaled> {
        self.values
            .iter()
            .find(|v| v.register == register)
            .map(|v| v.value)
    }

    /// The value of `register` as a float (an integer converted), if held.
    pub fn float(&self, register: u16) -> Option<f64> {
        self.get(register).map(|v| match v {
            #[allow(clippy::cast_precision_loss)]
            Scaled::Int(i) => i as f64,
            Scaled::Float(f) => f,
        })
    }

    /// The value of `register` as an integer (a float truncated), if held
    /// and finite.
    pub fn int(&self, register: u16) -> Option<i64> {
        self.get(register).and_then(|v| match v {
            Scaled::Int(i) => Some(i),
            #[allow(clippy::cast_possible_truncation)]
            Scaled::Float(f) if f.is_finite() => Some(f.trunc() as i64),
            Scaled::Float(_) => None,
        })
    }
}

/// Why a reply is refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ReplyError {
    /// Longer than a CAN-FD frame.
    #[error("a reply is at most 64 bytes; this one is {0}")]
    TooLong(usize),
    /// A subframe runs past the end of the data.
    #[error("the frame ends inside a subframe at byte {at} (it is {len} bytes)")]
    Truncated {
        /// Where the cut subframe starts.
        at: usize,
        /// The data's length.
        len: usize,
    },
    /// A byte that starts no subframe the protocol knows.
    #[error("unknown subframe {byte:#04x} at byte {at}")]
    UnknownSubframe {
        /// The byte.
        byte: u8,
        /// Where.
        at: usize,
    },
    /// A register number, count or error code over 16 bits.
    #[error(
        "the subframe at byte {at} has a number over 16 bits (a varuint of more than three bytes)"
    )]
    VaruintTooLarge {
        /// Where the subframe starts.
        at: usize,
    },
    /// A block's register count over 127 (`moteus-protocol` and mjbots'
    /// Python library read such a count differently).
    #[error("the subframe at byte {at} counts more than 127 registers")]
    LongCount {
        /// Where the subframe starts.
        at: usize,
    },
    /// An integer register holding a non-finite float.
    #[error(transparent)]
    NotAnInteger(#[from] NotAnInteger),
}

/// Decodes a reply frame: `can_id` as received, `data` its payload
/// (padding included).
///
/// ```
/// use motorwire_moteus::{decode, Scaled};
/// // Controller 1's reply: mode 10 (position), position 0.5 as f32, then padding.
/// let reply = decode(0x100, &[0x21, 0x00, 0x0a, 0x2d, 0x01, 0, 0, 0, 0x3f, 0x50, 0x50, 0x50])?;
/// assert_eq!(reply.source, 1);
/// assert_eq!(reply.get(0x000), Some(Scaled::Int(10)));
/// assert_eq!(reply.get(0x001), Some(Scaled::Float(0.5)));
/// assert_eq!(reply.values[1].name(), Some("POSITION"));
/// # Ok::<(), motorwire_moteus::ReplyError>(())
/// ```
///
/// # Errors
/// [`ReplyError`]: over 64 bytes, cut inside a subframe, an unknown
/// subframe byte, an integer register holding a float that is no integer
/// of 64 bits (NaN, an infinity, beyond ±2^63: the library refuses the
/// first two and gives a huge integer for the last). `moteus-protocol`'s
/// parser stops quietly at a cut subframe; this checks the frame's
/// structure first so that nothing is dropped without saying so.
pub fn decode(can_id: u32, data: &[u8]) -> Result<Reply, ReplyError> {
    if data.len() > 64 {
        return Err(ReplyError::TooLong(data.len()));
    }
    check_structure(data)?;
    let (source, destination, can_prefix) = parse_arbitration_id(can_id);
    let mut values: Vec<RegisterValue> = Vec::new();
    let mut errors = Vec::new();
    // An integer register holding a float beyond 64 bits, until a later
    // value of the same register replaces it (the library keeps a
    // register's last value; NaN and the infinities it refuses at once).
    let mut beyond: Vec<NotAnInteger> = Vec::new();
    for sub in moteus_protocol::parse_frame(data) {
        match sub {
            Subframe::Register {
                subframe_type: SubframeType::Response,
                register,
                value: Some(value),
                ..
            } => {
                beyond.retain(|e| e.register != register);
                let value = match scale(register, value) {
                    Ok(v) => v,
                    Err(e) if e.value.is_finite() => {
                        // Its place is kept (the library's dict keeps a
                        // key where it first came).
                        if !values.iter().any(|v| v.register == register) {
                            values.push(RegisterValue {
                                register,
                                value: Scaled::Float(f64::NAN),
                            });
                        }
                        beyond.push(e);
                        continue;
                    }
                    Err(e) => return Err(e.into()),
                };
                match values.iter_mut().find(|v| v.register == register) {
                    Some(v) => v.value = value,
                    None => values.push(RegisterValue { register, value }),
                }
            }
            Subframe::Error {
                subframe_type,
                register,
                error_code,
            } => errors.push(RegisterError {
                register,
                code: error_code,
                write: subframe_type == SubframeType::WriteError,
            }),
            _ => {}
        }
    }
    if let Some(e) = beyond.into_iter().next() {
        return Err(e.into());
    }
    #[allow(clippy::cast_sign_loss)]
    Ok(Reply {
        source: source as u8,
        destination: (destination as u8) & 0x7f,
        can_prefix,
        values,
        errors,
    })
}

/// Walks the multiplex structure of `data` (a reply's or a command's: the
/// same grammar `moteus-protocol`'s `parse_frame` reads) and says where it
/// is cut, unknown, or holds a number over 16 bits. Anything that reads
/// frames from a bus with `parse_frame` checks them with this first (the
/// parser stops quietly at a cut subframe and overflows on a long varuint).
///
/// # Errors
/// [`ReplyError::Truncated`], [`ReplyError::UnknownSubframe`],
/// [`ReplyError::VaruintTooLarge`].
pub fn check_structure(data: &[u8]) -> Result<(), ReplyError> {
    let len = data.len();
    let mut at = 0;
    let cut = |start| ReplyError::Truncated { at: start, len };
    // A register number, count or code is 16 bits: at most three bytes of
    // varuint, the third holding the top two bits (`moteus-protocol`'s
    // parser reads them into 16 bits; a longer one overflows it).
    let varuint = |pos: &mut usize, start: usize| -> Result<u32, ReplyError> {
        let mut v: u32 = 0;
        for i in 0..3 {
            let b = *data.get(*pos).ok_or(cut(start))?;
            *pos += 1;
            v |= u32::from(b & 0x7f) << (7 * i);
            if b & 0x80 == 0 {
                return if v > u32::from(u16::MAX) {
                    Err(ReplyError::VaruintTooLarge { at: start })
                } else {
                    Ok(v)
                };
            }
        }
        Err(ReplyError::VaruintTooLarge { at: start })
    };
    while let Some(&byte) = data.get(at) {
        let start = at;
        at += 1;
        match byte {
            0x50 => {}
            0x00..=0x2f => {
                let mut count = u32::from(byte & 0x03);
                if count == 0 {
                    // `moteus-protocol` reads a long count as one byte,
                    // the Python library as a varuint: they agree up to
                    // 127, and no frame of 64 bytes needs more.
                    if data.get(at).is_some_and(|b| b & 0x80 != 0) {
                        return Err(ReplyError::LongCount { at: start });
                    }
                    count = varuint(&mut at, start)?;
                    if count == 0 {
                        continue;
                    }
                }
                // The registers a block names run from its first upward,
                // one each, within 16 bits (`parse_frame` counts them in a
                // u16 that would overflow past 0xFFFF).
                let first = varuint(&mut at, start)?;
                if first + count > u32::from(u16::MAX) {
                    return Err(ReplyError::VaruintTooLarge { at: start });
                }
                if byte & 0xf0 != 0x10 {
                    let size = match (byte >> 2) & 0x03 {
                        0 => 1,
                        1 => 2,
                        _ => 4,
                    };
                    at = at
                        .checked_add(count as usize * size)
                        .filter(|end| *end <= len)
                        .ok_or(cut(start))?;
                }
            }
            0x30 | 0x31 => {
                varuint(&mut at, start)?;
                varuint(&mut at, start)?;
            }
            _ => return Err(ReplyError::UnknownSubframe { byte, at: start }),
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_cut_reply_is_refused_where_it_is_cut() {
        // A float position reply missing its last byte.
        assert_eq!(
            decode(0x100, &[0x21, 0x00, 0x0a, 0x2d, 0x01, 0, 0, 0]),
            Err(ReplyError::Truncated { at: 3, len: 8 })
        );
        assert_eq!(
            decode(0x100, &[0x21]),
            Err(ReplyError::Truncated { at: 0, len: 1 })
        );
        assert_eq!(
            decode(0x100, &[0x60]),
            Err(ReplyError::UnknownSubframe { byte: 0x60, at: 0 })
        );
        assert_eq!(decode(0x100, &[0x50; 65]), Err(ReplyError::TooLong(65)));
        // A register number of five varuint bytes (found by a hostile test:
        // it overflowed the parser's 16 bits and panicked).
        assert_eq!(
            decode(0x100, &[0x30, 0x80, 0x80, 0x80, 0x80, 0x01, 0x00, 0x50]),
            Err(ReplyError::VaruintTooLarge { at: 0 })
        );
        assert_eq!(
            decode(0x100, &[0x01, 0x80, 0x80, 0x80, 0x80, 0x01, 0x0a]),
            Err(ReplyError::VaruintTooLarge { at: 0 })
        );
        // 0xFFFF in three bytes is the largest.
        assert_eq!(
            decode(0x100, &[0x31, 0xff, 0xff, 0x03, 0x00]).map(|r| r.errors[0].register),
            Ok(0xffff)
        );
        assert_eq!(
            decode(0x100, &[0x31, 0x80, 0x80, 0x04, 0x00]),
            Err(ReplyError::VaruintTooLarge { at: 0 })
        );
    }

    #[test]
    fn sentinels_errors_and_padding() {
        // int16 position and velocity, both the NaN sentinel; a read error
        // on register 0x130 code 3; padding.
        let r = decode(
            0x8205,
            &[
                0x26, 0x01, 0x00, 0x80, 0x00, 0x80, 0x31, 0xb0, 0x02, 0x03, 0x50, 0x50,
            ],
        )
        .unwrap_or_else(|e| panic!("{e}"));
        assert_eq!((r.source, r.destination), (2, 5));
        assert_eq!(r.values.len(), 2);
        assert!(
            r.values
                .iter()
                .all(|v| matches!(v.value, Scaled::Float(f) if f.is_nan()))
        );
        assert_eq!(
            r.errors,
            vec![RegisterError {
                register: 0x130,
                code: 3,
                write: false
            }]
        );
    }

    #[test]
    fn an_integer_register_holding_nan_is_refused() {
        let nan = f32::NAN.to_le_bytes();
        let data = [0x2d, 0x0f, nan[0], nan[1], nan[2], nan[3]];
        assert!(matches!(
            decode(0x100, &data),
            Err(ReplyError::NotAnInteger(NotAnInteger {
                register: 0x00f,
                ..
            }))
        ));
    }
}
