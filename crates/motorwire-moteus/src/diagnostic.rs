//! The diagnostic stream: the text console (`conf get`, `conf set`, `d
//! stop`, ...) that mjbots' `moteus_tool` and tview speak, carried in CAN-FD
//! frames as the Python library's `make_diagnostic_write` and
//! `make_diagnostic_read` carry it. A client writes text to a channel
//! (subframe `0x40`) and polls for what the controller wrote back (`0x42`);
//! the controller answers a poll with `0x41`, its channel, a length and at
//! most that many bytes.
//!
//! ```
//! use motorwire_moteus::diagnostic;
//! // Controller 5, bus prefix 0: "conf set servopos.position_max 0.25\n" on channel 1.
//! let line = diagnostic::conf_set("servopos.position_max", 0.25);
//! assert_eq!(line, "conf set servopos.position_max 0.25\n");
//! let frame = diagnostic::write(5, 0, 1, line.as_bytes())?;
//! assert_eq!(frame.can_id, 0x0005); // no reply asked for
//! assert_eq!(&frame.data[..3], &[0x40, 0x01, 36]);
//! // The poll asks for a reply; the reply carries the controller's text.
//! assert_eq!(diagnostic::read(5, 0, 1, 48)?.data, [0x42, 0x01, 48]);
//! let answer = diagnostic::decode(0x0500, &[0x41, 0x01, 0x04, b'O', b'K', b'\r', b'\n', 0x50])?;
//! assert_eq!((answer.source, answer.channel), (5, 1));
//! assert_eq!(answer.data, b"OK\r\n");
//! # Ok::<(), diagnostic::DiagnosticError>(())
//! ```

use moteus_protocol::diagnostic::{write_client_poll, write_client_to_server};
use moteus_protocol::{calculate_arbitration_id, parse_arbitration_id};

use crate::Frame;

/// The subframe that writes to a diagnostic channel (`moteus-protocol`'s
/// `CLIENT_TO_SERVER`).
pub const CLIENT_DATA: u8 = moteus_protocol::CLIENT_TO_SERVER;
/// The subframe a controller answers a poll with (`SERVER_TO_CLIENT`).
pub const SERVER_DATA: u8 = moteus_protocol::SERVER_TO_CLIENT;
/// The subframe that polls a diagnostic channel (`CLIENT_POLL_SERVER`).
pub const CLIENT_POLL: u8 = moteus_protocol::CLIENT_POLL_SERVER;
/// The most text one write carries (the library's `max_diagnostic_write`
/// without a UUID prefix: 64 bytes less the subframe's three).
pub const MAX_WRITE: usize = moteus_protocol::diagnostic::MAX_WRITE;

/// Why a diagnostic frame cannot be made or read.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum DiagnosticError {
    /// More text than one frame carries.
    #[error("a diagnostic write carries at most {MAX_WRITE} bytes; this one is {0}")]
    TooLong(usize),
    /// A channel or poll length the library writes as a signed byte and
    /// cannot write here (over 127), or a poll of more than one frame's text.
    #[error("{what} must be 0 to {max}; it is {value}")]
    OutOfRange {
        /// `channel` or `max_length`.
        what: &'static str,
        /// The value.
        value: u32,
        /// Its largest.
        max: u32,
    },
    /// A controller id over 127 (7 bits of the CAN id).
    #[error("a controller id is 0 to 127; it is {0}")]
    Id(u8),
    /// A reply that is not a diagnostic answer, or is cut short.
    #[error("not a diagnostic answer: {0}")]
    NotAnAnswer(&'static str),
}

/// A controller's answer to a poll: who sent it and the text.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Answer {
    /// The controller that sent it (bits 8..14 of the CAN id).
    pub source: u8,
    /// The id it was sent to (bits 0..6).
    pub destination: u8,
    /// The CAN prefix (bits 16..28).
    pub can_prefix: u16,
    /// The diagnostic channel.
    pub channel: u32,
    /// The text (possibly empty: nothing was waiting).
    pub data: Vec<u8>,
}

fn check_id(id: u8) -> Result<(), DiagnosticError> {
    if id > 127 {
        return Err(DiagnosticError::Id(id));
    }
    Ok(())
}

fn check_byte(what: &'static str, value: u8, max: u8) -> Result<(), DiagnosticError> {
    if value > max {
        return Err(DiagnosticError::OutOfRange {
            what,
            value: u32::from(value),
            max: u32::from(max),
        });
    }
    Ok(())
}

/// `data` written to `channel` of controller `id` on CAN prefix `bus`, as
/// `Controller(id).make_diagnostic_write(data, channel)` makes it (no
/// reply asked for).
///
/// # Errors
/// More than [`MAX_WRITE`] bytes, a channel over 127, an id over 127.
#[allow(clippy::cast_possible_wrap)] // an id of at most 127
pub fn write(id: u8, bus: u16, channel: u8, data: &[u8]) -> Result<Frame, DiagnosticError> {
    check_id(id)?;
    check_byte("channel", channel, 127)?;
    if data.len() > MAX_WRITE {
        return Err(DiagnosticError::TooLong(data.len()));
    }
    // mjbots' own writer (it panics past MAX_WRITE: checked above).
    let mut out = [0u8; 64];
    let n = write_client_to_server(channel, data, &mut out);
    Ok(Frame {
        can_id: calculate_arbitration_id(0, id as i8, bus, false),
        data: out.get(..usize::from(n)).unwrap_or(&out).to_vec(),
    })
}

/// A poll of `channel` of controller `id` for at most `max_length` bytes,
/// as `Controller(id).make_diagnostic_read(max_length, channel)` makes it
/// (a reply asked for).
///
/// # Errors
/// A channel over 127, a length over [`MAX_WRITE`] (a reply frame holds no
/// more), an id over 127.
#[allow(clippy::cast_possible_wrap)] // an id of at most 127
pub fn read(id: u8, bus: u16, channel: u8, max_length: u8) -> Result<Frame, DiagnosticError> {
    check_id(id)?;
    check_byte("channel", channel, 127)?;
    #[allow(clippy::cast_possible_truncation)]
    check_byte("max_length", max_length, MAX_WRITE as u8)?;
    let mut out = [0u8; 64];
    let n = write_client_poll(channel, max_length, &mut out);
    Ok(Frame {
        can_id: calculate_arbitration_id(0, id as i8, bus, true),
        data: out.get(..usize::from(n)).unwrap_or(&out).to_vec(),
    })
}

/// A varuint (7 bits a byte, least significant first) of at most 5 bytes
/// from `data[*at..]`.
fn varuint(data: &[u8], at: &mut usize) -> Option<u32> {
    let mut v: u32 = 0;
    for i in 0..5 {
        let b = *data.get(*at)?;
        *at += 1;
        v |= u32::from(b & 0x7f).checked_shl(7 * i)?;
        if b & 0x80 == 0 {
            return Some(v);
        }
    }
    None
}

/// A controller's answer to a poll, read as the library's
/// `parse_diagnostic_message` reads it (padding after the text is
/// ignored); the library's `None` is an error here, saying why. (Not
/// `moteus-protocol`'s `parse_server_to_client`: it reads the channel as
/// one byte and keeps one channel, where the library reads a varuint.)
///
/// # Errors
/// [`DiagnosticError::NotAnAnswer`]: under three bytes, another subframe
/// first, a channel or length that does not end, or a length beyond the
/// frame.
pub fn decode(can_id: u32, data: &[u8]) -> Result<Answer, DiagnosticError> {
    if data.len() < 3 {
        return Err(DiagnosticError::NotAnAnswer("under three bytes"));
    }
    if data.first() != Some(&SERVER_DATA) {
        return Err(DiagnosticError::NotAnAnswer("it does not start with 0x41"));
    }
    let mut at = 1;
    let channel = varuint(data, &mut at).ok_or(DiagnosticError::NotAnAnswer(
        "its channel does not end within five bytes",
    ))?;
    let len = varuint(data, &mut at).ok_or(DiagnosticError::NotAnAnswer(
        "its length does not end within five bytes",
    ))?;
    let text = usize::try_from(len)
        .ok()
        .and_then(|n| data.get(at..at.checked_add(n)?))
        .ok_or(DiagnosticError::NotAnAnswer(
            "its length runs past the frame",
        ))?;
    let (source, destination, can_prefix) = parse_arbitration_id(can_id);
    #[allow(clippy::cast_sign_loss)]
    Ok(Answer {
        source: source as u8,
        destination: (destination as u8) & 0x7f,
        can_prefix,
        channel,
        data: text.to_vec(),
    })
}

/// The console line that sets configuration value `name` to `value` for
/// the controller's running configuration (not written to its flash):
/// `conf set NAME VALUE\n`, NaN as `nan` (for the `servopos` bounds, no
/// bound), every finite value in the shortest text that reads back to it.
pub fn conf_set(name: &str, value: f64) -> String {
    if value.is_nan() {
        format!("conf set {name} nan\n")
    } else {
        format!("conf set {name} {value}\n")
    }
}

/// The console line that asks for configuration value `name`: the
/// controller answers with the value alone on a line.
pub fn conf_get(name: &str) -> String {
    format!("conf get {name}\n")
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;

    #[test]
    fn what_the_library_refuses_is_refused_saying_why() {
        // Each the library's parse_diagnostic_message answers None.
        for (hex, why) in [
            ("41010d4f4b0d0a", "its length runs past the frame"),
            ("41010a", "its length runs past the frame"),
            ("4101", "under three bytes"),
            ("42010d4f4b", "it does not start with 0x41"),
            (
                "4181818181810100",
                "its channel does not end within five bytes",
            ),
        ] {
            let data: Vec<u8> = (0..hex.len())
                .step_by(2)
                .map(|i| u8::from_str_radix(&hex[i..i + 2], 16).unwrap())
                .collect();
            assert_eq!(
                decode(0x500, &data),
                Err(DiagnosticError::NotAnAnswer(why)),
                "{hex}"
            );
        }
    }

    #[test]
    fn values_are_written_to_read_back_the_same() {
        assert_eq!(
            conf_set("servopos.position_min", f64::NAN),
            "conf set servopos.position_min nan\n"
        );
        assert_eq!(
            conf_set("servopos.position_min", -0.5),
            "conf set servopos.position_min -0.5\n"
        );
        let v = 60.0 / 360.0;
        let line = conf_set("servopos.position_max", v);
        assert_eq!(line, "conf set servopos.position_max 0.16666666666666666\n");
        let text = line.trim_end().rsplit(' ').next().unwrap();
        assert_eq!(text.parse::<f64>().unwrap().to_bits(), v.to_bits());
        assert_eq!(
            conf_get("servopos.position_max"),
            "conf get servopos.position_max\n"
        );
    }

    #[test]
    fn out_of_range_arguments_are_refused() {
        assert_eq!(
            write(1, 0, 1, &[b'a'; 62]),
            Err(DiagnosticError::TooLong(62))
        );
        assert_eq!(
            write(1, 0, 128, b"x"),
            Err(DiagnosticError::OutOfRange {
                what: "channel",
                value: 128,
                max: 127
            })
        );
        assert_eq!(
            read(1, 0, 1, 62),
            Err(DiagnosticError::OutOfRange {
                what: "max_length",
                value: 62,
                max: 61
            })
        );
        assert_eq!(read(128, 0, 1, 1), Err(DiagnosticError::Id(128)));
    }
}
