//! Line-by-line filters: one input line in, one output line out, a failed
//! line replaced by `{"error": "...", "line": N}` and processing going on.

use std::io::{self, Write};

use crate::console::note;
use crate::input::{self, Live, Refused};

/// The longest input line accepted.
pub(crate) const MAX_LINE: usize = 1 << 20;

/// Runs `f` on every non-blank stdin line, printing each result as soon as
/// its line is in; returns the exit status (0 when every line succeeded, 1
/// when any failed, 2 on an I/O error or a closed stdout).
pub(crate) fn filter(mut f: impl FnMut(&str) -> Result<String, String>) -> u8 {
    let out = io::BufWriter::new(io::stdout().lock());
    let mut reader = Live::new(Box::new(io::stdin().lock()), out);
    let mut line_no = 0;
    let mut failed = false;
    loop {
        let doc = match input::next_line(&mut reader, MAX_LINE, &mut line_no) {
            Ok(Some(doc)) => doc,
            Ok(None) => break,
            Err(e) => {
                if !reader.out_failed() {
                    let _ = reader.out().flush();
                    note!("motorwire: reading standard input: {e}");
                }
                return 2;
            }
        };
        let result = match doc.text {
            Ok(text) => f(text.trim()),
            Err(Refused::TooLarge { limit }) => Err(format!("the line is over {limit} bytes")),
            Err(Refused::NotUtf8) => Err("the line is not UTF-8".to_owned()),
        };
        let line = match result {
            Ok(line) => line,
            Err(error) => {
                failed = true;
                let n = doc.line.unwrap_or(line_no);
                serde_json::json!({ "error": error, "line": n }).to_string()
            }
        };
        if writeln!(reader.out(), "{line}").is_err() {
            return 2;
        }
    }
    if reader.out().flush().is_err() {
        return 2;
    }
    u8::from(failed)
}

/// Lowercase hex, no separators.
pub(crate) fn to_hex(bytes: &[u8]) -> String {
    use std::fmt::Write as _;
    let mut s = String::with_capacity(bytes.len() * 2);
    for b in bytes {
        let _ = write!(s, "{b:02x}");
    }
    s
}

/// Hex digits, with any whitespace between them.
pub(crate) fn from_hex(text: &str) -> Result<Vec<u8>, String> {
    let digits: Vec<u8> = text.bytes().filter(|b| !b.is_ascii_whitespace()).collect();
    if !digits.len().is_multiple_of(2) {
        return Err(format!("odd number of hex digits ({})", digits.len()));
    }
    let value = |d: u8| -> Result<u8, String> {
        match d {
            b'0'..=b'9' => Ok(d - b'0'),
            b'a'..=b'f' => Ok(d - b'a' + 10),
            b'A'..=b'F' => Ok(d - b'A' + 10),
            _ => Err(format!("{:?} is not a hex digit", char::from(d))),
        }
    };
    digits
        .chunks_exact(2)
        .map(|pair| match pair {
            [hi, lo] => Ok(value(*hi)? << 4 | value(*lo)?),
            _ => Err("odd number of hex digits".to_owned()),
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hex_round_trips_and_refuses_junk() {
        assert_eq!(
            from_hex("00 10 2A\t05").unwrap(),
            vec![0x00, 0x10, 0x2a, 0x05]
        );
        assert_eq!(to_hex(&[0x00, 0xff, 0x10]), "00ff10");
        assert_eq!(from_hex("abc").unwrap_err(), "odd number of hex digits (3)");
        assert_eq!(from_hex("zz").unwrap_err(), "'z' is not a hex digit");
        assert_eq!(from_hex("").unwrap(), Vec::<u8>::new());
    }
}
