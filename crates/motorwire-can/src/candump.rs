//! The `candump -L` log format: `(1700000000.123456) vcan0 010#0102` for
//! classic frames and `010##1...` (FD flags digit, then data) for CAN-FD.

use std::fmt;
use std::time::Duration;

use crate::{CanId, Error, Frame};

/// One line of a candump log.
///
/// ```
/// use std::time::Duration;
/// use motorwire_can::candump::LogEntry;
///
/// let e = LogEntry::parse("(1700000000.123456) vcan0 000##100102A05")?;
/// assert_eq!(e.timestamp, Duration::new(1_700_000_000, 123_456_000));
/// assert_eq!(e.interface, "vcan0");
/// assert!(e.frame.is_fd() && e.frame.brs());
/// assert_eq!(e.frame.data(), &[0x00, 0x10, 0x2A, 0x05]);
/// assert_eq!(e.to_string(), "(1700000000.123456) vcan0 000##100102A05");
/// assert!(LogEntry::parse("(1.0) vcan0 010#0").is_err());
/// # Ok::<(), String>(())
/// ```
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LogEntry {
    /// Receive time since the UNIX epoch, microsecond resolution.
    pub timestamp: Duration,
    /// The interface name.
    pub interface: String,
    /// The frame.
    pub frame: Frame,
}

impl LogEntry {
    /// Parses one line (without its newline).
    ///
    /// # Errors
    /// A sentence saying what is wrong.
    pub fn parse(line: &str) -> Result<Self, String> {
        let mut parts = line.split_ascii_whitespace();
        let stamp = parts.next().ok_or("empty line")?;
        let iface = parts.next().ok_or("no interface after the timestamp")?;
        let frame = parts.next().ok_or("no frame after the interface")?;
        // Newer candump versions may append a direction flag (R or T).
        match parts.next() {
            None | Some("R" | "T") => {}
            Some(other) => return Err(format!("unexpected {other:?} after the frame")),
        }
        if parts.next().is_some() {
            return Err("unexpected text after the frame".into());
        }
        Ok(Self {
            timestamp: parse_timestamp(stamp)?,
            interface: iface.to_owned(),
            frame: parse_frame(frame)?,
        })
    }
}

impl fmt::Display for LogEntry {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "({}.{:06}) {} {}",
            self.timestamp.as_secs(),
            self.timestamp.subsec_micros(),
            self.interface,
            self.frame
        )
    }
}

fn parse_timestamp(s: &str) -> Result<Duration, String> {
    let inner = s
        .strip_prefix('(')
        .and_then(|s| s.strip_suffix(')'))
        .ok_or_else(|| format!("timestamp {s:?} is not in parentheses"))?;
    let (secs, frac) = inner
        .split_once('.')
        .ok_or_else(|| format!("timestamp {inner:?} has no fractional part"))?;
    let digits = |t: &str| !t.is_empty() && t.bytes().all(|b| b.is_ascii_digit());
    if !digits(secs) || !digits(frac) || frac.len() > 9 {
        return Err(format!("timestamp {inner:?} is not seconds.fraction"));
    }
    let secs: u64 = secs
        .parse()
        .map_err(|_| format!("timestamp seconds {secs:?} out of range"))?;
    let mut nanos: u32 = frac
        .parse()
        .map_err(|_| format!("timestamp fraction {frac:?} out of range"))?;
    for _ in frac.len()..9 {
        nanos *= 10;
    }
    Ok(Duration::new(secs, nanos))
}

/// `bytes` as hex digits, two a byte, lower case (as a recording's
/// `lines.jsonl` writes a frame's data): what [`hex_bytes`] reads back.
///
/// ```
/// let text = motorwire_can::candump::bytes_hex(&[0x00, 0xff, 0x12]);
/// assert_eq!(text, "00ff12");
/// assert_eq!(motorwire_can::candump::hex_bytes(&text), Ok(vec![0x00, 0xff, 0x12]));
/// ```
#[must_use]
pub fn bytes_hex(bytes: &[u8]) -> String {
    const DIGITS: &[u8; 16] = b"0123456789abcdef";
    let mut s = String::with_capacity(bytes.len() * 2);
    for &b in bytes {
        for d in [b >> 4, b & 0x0f] {
            s.push(char::from(
                DIGITS.get(usize::from(d)).copied().unwrap_or(b'0'),
            ));
        }
    }
    s
}

/// The bytes hex digits spell (`"deadbeef"`), as a log's data is written.
///
/// ```
/// assert_eq!(motorwire_can::candump::hex_bytes("00ff12"), Ok(vec![0x00, 0xff, 0x12]));
/// assert!(motorwire_can::candump::hex_bytes("0").is_err());
/// ```
///
/// # Errors
/// An odd number of digits, or a character that is not a hex digit.
pub fn hex_bytes(s: &str) -> Result<Vec<u8>, String> {
    if !s.len().is_multiple_of(2) {
        return Err(format!("data {s:?} has an odd number of hex digits"));
    }
    (0..s.len())
        .step_by(2)
        .map(|i| {
            s.get(i..i + 2)
                .and_then(|h| u8::from_str_radix(h, 16).ok())
                .ok_or_else(|| format!("data {s:?} is not hex"))
        })
        .collect()
}

/// Parses the frame part, `010#...` or `010##1...`.
///
/// # Errors
/// A sentence saying what is wrong (remote and error frames are refused).
pub fn parse_frame(s: &str) -> Result<Frame, String> {
    let (id, rest) = s
        .split_once('#')
        .ok_or_else(|| format!("frame {s:?} has no '#'"))?;
    if !id.bytes().all(|b| b.is_ascii_hexdigit()) {
        return Err(format!("CAN id {id:?} is not hex"));
    }
    let raw = u32::from_str_radix(id, 16).map_err(|_| format!("CAN id {id:?} is not hex"))?;
    let id = match id.len() {
        3 => CanId::standard(u16::try_from(raw).unwrap_or(u16::MAX)),
        8 if raw & 0x2000_0000 != 0 => return Err(format!("{s:?} is an error frame")),
        8 => CanId::extended(raw),
        n => return Err(format!("CAN id {id:?} has {n} digits (3 or 8 expected)")),
    }
    .map_err(|e| e.to_string())?;
    if rest.starts_with('R') {
        return Err(format!("{s:?} is a remote frame"));
    }
    if let Some(fd) = rest.strip_prefix('#') {
        let mut chars = fd.chars();
        let flags = chars
            .next()
            .and_then(|c| c.to_digit(16))
            .ok_or_else(|| format!("FD frame {s:?} has no flags digit"))?;
        let data = hex_bytes(chars.as_str())?;
        Frame::fd_exact(id, &data, flags & 1 != 0, flags & 2 != 0).map_err(|e| e.to_string())
    } else {
        let data = hex_bytes(rest)?;
        Frame::classic(id, &data).map_err(|e| e.to_string())
    }
}

/// Reads a whole log: one entry per non-blank line, or the error of the line
/// that is not one.
///
/// ```
/// use motorwire_can::candump::read_log;
/// let log = "(0.000001) vcan0 010#01\n\n(0.000002) vcan0 nonsense\n";
/// let entries: Vec<_> = read_log(log).collect();
/// assert_eq!(entries.len(), 2);
/// assert!(entries[0].is_ok());
/// assert_eq!(entries[1].as_ref().unwrap_err().to_string(),
///            "candump log line 3: frame \"nonsense\" has no '#'");
/// ```
pub fn read_log(text: &str) -> impl Iterator<Item = Result<LogEntry, Error>> + '_ {
    text.lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty())
        .map(|(i, l)| {
            LogEntry::parse(l.trim()).map_err(|reason| Error::Log {
                line: i + 1,
                reason,
            })
        })
}
