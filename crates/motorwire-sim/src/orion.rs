//! The simulated Orion arm controller on a byte stream: one JSON object per
//! line each way, as motorwire reaches the controller (a serial port, a
//! TCP connection or an in-process pipe).
//!
//! It sends the boot beacon `{"ID":32}` at once and every
//! [`OrionConfig::beacon_interval`] until its first command, then answers
//! every line with [`ArmController`]'s feedback. A line that is not an
//! Orion command, is longer than [`MAX_ORION_LINE`] or is not UTF-8 changes
//! nothing and is answered by nothing; each one, and every value the
//! controller clamps, is told to `notes`.
//!
//! ```
//! use std::io::{BufRead, BufReader, Write};
//! use std::time::Duration;
//! use motorwire_sim::orion::{OrionConfig, spawn_in_process};
//!
//! let (reader, mut writer) = spawn_in_process(OrionConfig::default())?;
//! let mut reader = BufReader::new(reader);
//! let mut line = String::new();
//! reader.read_line(&mut line)?;
//! assert_eq!(line, "{\"ID\":32}\n");
//! writer.write_all(b"{\"ID\":32,\"MODE\":1,\"DATA\":{\"TRM\":200}}\n")?;
//! loop {
//!     line.clear();
//!     reader.read_line(&mut line)?;
//!     if line != "{\"ID\":32}\n" { break } // a beacon sent meanwhile
//! }
//! assert!(line.starts_with("{\"ID\":32,\"MODE\":1,\"DATA\":{\"TRMF\":[200,35,0],"), "{line}");
//! # Ok::<(), std::io::Error>(())
//! ```

use std::io::{self, BufRead, BufReader, Read, Write};
use std::sync::mpsc::{self, RecvTimeoutError};
use std::thread;
use std::time::Duration;

use motorwire_orion::{ArmController, FeedbackKeys, Output};

/// The longest line the simulated controller reads (bytes); longer lines
/// are skipped to their end and ignored.
pub const MAX_ORION_LINE: usize = 64 * 1024;

/// How the simulated controller behaves.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct OrionConfig {
    /// Which direct-control feedback keys it sends (default: the
    /// document's table, `TRMF` ...).
    pub keys: FeedbackKeys,
    /// Between boot beacons until the first command (default 1 s;
    /// `None`: the beacon is sent once).
    pub beacon_interval: Option<Duration>,
}

impl Default for OrionConfig {
    fn default() -> Self {
        Self {
            keys: FeedbackKeys::Table,
            beacon_interval: Some(Duration::from_secs(1)),
        }
    }
}

/// One line read, or why not.
enum Got {
    Line(usize, String),
    TooLong(usize),
    NotUtf8(usize),
    Failed(io::Error),
}

/// Reads one line of at most [`MAX_ORION_LINE`] bytes; `None` at the end.
fn next_line(reader: &mut impl BufRead, n: usize) -> Option<Got> {
    let mut bytes = Vec::new();
    let limit = u64::try_from(MAX_ORION_LINE).unwrap_or(u64::MAX) + 1;
    match reader.by_ref().take(limit).read_until(b'\n', &mut bytes) {
        Ok(0) => return None,
        Ok(_) => {}
        Err(e) => return Some(Got::Failed(e)),
    }
    if bytes.last() != Some(&b'\n') && bytes.len() > MAX_ORION_LINE {
        // Skip the rest of the long line.
        let mut rest = Vec::new();
        loop {
            rest.clear();
            match reader.by_ref().take(limit).read_until(b'\n', &mut rest) {
                Ok(0) => break,
                Ok(_) if rest.last() == Some(&b'\n') => break,
                Ok(_) => {}
                Err(e) => return Some(Got::Failed(e)),
            }
        }
        return Some(Got::TooLong(n));
    }
    while matches!(bytes.last(), Some(b'\n' | b'\r')) {
        bytes.pop();
    }
    Some(match String::from_utf8(bytes) {
        Ok(s) => Got::Line(n, s),
        Err(_) => Got::NotUtf8(n),
    })
}

/// Runs the simulated controller on `reader` and `writer` until `reader`
/// ends (`Ok`) or either fails (`Err`: nobody hears the arm any more).
/// What it ignored and what it clamped is told to `notes`, one sentence
/// each.
///
/// # Errors
/// The first read or write error.
pub fn serve(
    reader: impl Read + Send + 'static,
    mut writer: impl Write,
    config: OrionConfig,
    mut notes: impl FnMut(String),
) -> io::Result<()> {
    let (tx, rx) = mpsc::channel();
    // The input is read on its own thread so the beacon keeps its rhythm
    // while no line arrives.
    thread::spawn(move || {
        let mut reader = BufReader::new(reader);
        let mut n = 0;
        loop {
            n += 1;
            let Some(got) = next_line(&mut reader, n) else {
                break;
            };
            let failed = matches!(got, Got::Failed(_));
            if tx.send(got).is_err() || failed {
                break;
            }
        }
    });
    let mut arm = ArmController::new();
    let beacon = Output::Beacon.to_json(config.keys);
    let mut say = |line: &str| -> io::Result<()> {
        writer.write_all(line.as_bytes())?;
        writer.write_all(b"\n")?;
        writer.flush()
    };
    say(&beacon)?;
    loop {
        let got = match config.beacon_interval {
            Some(every) if arm.awaiting_first_command() => match rx.recv_timeout(every) {
                Ok(got) => got,
                Err(RecvTimeoutError::Timeout) => {
                    say(&beacon)?;
                    continue;
                }
                Err(RecvTimeoutError::Disconnected) => return Ok(()),
            },
            _ => match rx.recv() {
                Ok(got) => got,
                Err(_) => return Ok(()),
            },
        };
        let (n, text) = match got {
            Got::Line(n, text) => (n, text),
            Got::Failed(e) => return Err(e),
            Got::TooLong(n) => {
                notes(format!("line {n}: over {MAX_ORION_LINE} bytes; ignored"));
                continue;
            }
            Got::NotUtf8(n) => {
                notes(format!("line {n}: not UTF-8; ignored"));
                continue;
            }
        };
        if text.trim().is_empty() {
            continue;
        }
        match arm.handle_line(text.trim()) {
            Ok(response) => {
                for clamp in &response.clamps {
                    notes(format!("line {n}: {clamp}"));
                }
                say(&response.output.to_json(config.keys))?;
            }
            Err(e) => notes(format!("line {n}: {e}; ignored")),
        }
    }
}

/// A simulated controller on a thread of this process, reached through a
/// pair of pipes: read its lines from the first, write yours to the
/// second. It ends when the writer is dropped.
///
/// # Errors
/// Creating the pipes failed.
pub fn spawn_in_process(config: OrionConfig) -> io::Result<(io::PipeReader, io::PipeWriter)> {
    let (from_arm, arm_out) = io::pipe()?;
    let (arm_in, to_arm) = io::pipe()?;
    thread::spawn(move || {
        // Errors end the controller: the other side has gone.
        let _ = serve(arm_in, arm_out, config, |_| {});
    });
    Ok((from_arm, to_arm))
}
