//! `motorwire candump decode`: a `candump -L` log, decoded frame by frame.

use std::io::{self, Write};
use std::path::PathBuf;

use clap::{Args as ClapArgs, Subcommand};
use motorwire_can::candump::LogEntry;
use motorwire_compact::CompactCommand;
use motorwire_irpc::{Message, WireVersion};
use serde::Serialize;

use crate::console::note;
use crate::input::{self, Live, Refused};
use crate::irpc::parse_wire;

/// Read candump logs.
#[derive(Debug, ClapArgs)]
pub(crate) struct Args {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Print each frame of a `candump -L` log as one JSON line: its time,
    /// interface, CAN id and the decoded iRPC message (or compact command
    /// with --compact), or the reason it does not decode (a line over 4096
    /// bytes or not UTF-8 is one such line). Each line is printed as soon as
    /// it is read, so a live `candump -L` piped in is decoded as it comes.
    /// Exits 1 when any line did not decode, 2 when the file cannot be read
    /// (or has a line with no end within 16 MiB) or stdout closes.
    Decode(DecodeArgs),
}

#[derive(Debug, ClapArgs)]
struct DecodeArgs {
    /// The iRPC wire version: v1, v2.0, v2.1 or v2.2.
    #[arg(long, value_parser = parse_wire, required_unless_present = "compact")]
    wire: Option<WireVersion>,
    /// Decode the frames as 24-byte WIA compact commands instead.
    #[arg(long, conflicts_with = "wire")]
    compact: bool,
    /// The log file (`-` for standard input).
    file: PathBuf,
}

pub(crate) fn run(args: &Args) -> u8 {
    match &args.command {
        Command::Decode(d) => decode(d),
    }
}

/// The longest log line read (bytes): a `candump -L` line is at most about
/// 200 (a 64-byte CAN-FD frame is 128 hex digits).
pub(crate) const MAX_LOG_LINE: usize = 4096;

/// Decodes the log line by line, each line printed as soon as it is read.
fn decode(args: &DecodeArgs) -> u8 {
    let input = match input::open_raw(&args.file) {
        Ok(i) => i,
        Err(e) => {
            note!("motorwire: reading {}: {e}", args.file.display());
            return 2;
        }
    };
    let mut reader = Live::new(input, io::BufWriter::new(io::stdout().lock()));
    let mut line_no = 0;
    let mut failed = false;
    loop {
        let doc = match input::next_line(&mut reader, MAX_LOG_LINE, &mut line_no) {
            Ok(Some(doc)) => doc,
            Ok(None) => break,
            Err(e) => {
                if !reader.out_failed() {
                    let _ = reader.out().flush();
                    note!("motorwire: reading {}: {e}", args.file.display());
                }
                return 2;
            }
        };
        let n = doc.line.unwrap_or(line_no);
        let value = match doc.text {
            Ok(text) => decode_line(n, text.trim(), args.wire, args.compact),
            Err(Refused::TooLarge { limit }) => {
                FrameLine::error(n, format!("the line is over {limit} bytes"))
            }
            Err(Refused::NotUtf8) => FrameLine::error(n, "the line is not UTF-8"),
        };
        failed |= value.failed();
        let Ok(json) = serde_json::to_string(&value) else {
            return 2;
        };
        if writeln!(reader.out(), "{json}").is_err() {
            return 2;
        }
    }
    if reader.out().flush().is_err() {
        return 2;
    }
    u8::from(failed)
}

/// One line's JSON, its fields in this order: always `line`, then the
/// frame (`timestamp`, `interface`, `can_id`, `fd`, `len`) and what it
/// decodes to (`message`, or `command` with --compact), or `error`.
///
/// The message is serialized as itself (not through `serde_json::Value`),
/// so it prints exactly as `motorwire irpc decode` prints it: fields in
/// wire order, each f32 in its shortest form (0.1, not 0.10000000149011612).
#[derive(Debug, Serialize)]
pub(crate) struct FrameLine {
    line: usize,
    #[serde(skip_serializing_if = "Option::is_none")]
    timestamp: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    interface: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    can_id: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    fd: Option<bool>,
    #[serde(skip_serializing_if = "Option::is_none")]
    len: Option<usize>,
    #[serde(skip_serializing_if = "Option::is_none")]
    message: Option<Message>,
    #[serde(skip_serializing_if = "Option::is_none")]
    command: Option<CompactCommand>,
    #[serde(skip_serializing_if = "Option::is_none")]
    error: Option<String>,
}

impl FrameLine {
    fn error(line: usize, error: impl Into<String>) -> FrameLine {
        FrameLine {
            line,
            timestamp: None,
            interface: None,
            can_id: None,
            fd: None,
            len: None,
            message: None,
            command: None,
            error: Some(error.into()),
        }
    }

    fn failed(&self) -> bool {
        self.error.is_some()
    }
}

/// Decodes one log line.
pub(crate) fn decode_line(
    line_no: usize,
    line: &str,
    wire: Option<WireVersion>,
    compact: bool,
) -> FrameLine {
    let entry = match LogEntry::parse(line) {
        Ok(e) => e,
        Err(reason) => return FrameLine::error(line_no, reason),
    };
    let mut out = FrameLine {
        line: line_no,
        timestamp: Some(format!(
            "{}.{:06}",
            entry.timestamp.as_secs(),
            entry.timestamp.subsec_micros()
        )),
        interface: Some(entry.interface),
        can_id: Some(entry.frame.id().to_string()),
        fd: Some(entry.frame.is_fd()),
        len: Some(entry.frame.len()),
        message: None,
        command: None,
        error: None,
    };
    let decoded = if compact {
        CompactCommand::decode(entry.frame.data())
            .map(|c| out.command = Some(c))
            .map_err(|e| e.to_string())
    } else {
        let wire = wire.unwrap_or(WireVersion::V2_0);
        decode_irpc(wire, &entry.frame).map(|m| out.message = Some(m))
    };
    if let Err(e) = decoded {
        out.error = Some(e);
    }
    out
}

fn decode_irpc(wire: WireVersion, frame: &motorwire_can::Frame) -> Result<Message, String> {
    let decode = if frame.is_fd() {
        Message::decode_frame(wire, frame.data())
    } else {
        Message::decode(wire, frame.data())
    };
    let m = decode.map_err(|e| e.to_string())?;
    if u32::from(m.header.source_id) != frame.id().raw() {
        return Err(format!(
            "CAN id {} is not the header's source_id {:#06x}",
            frame.id(),
            m.header.source_id
        ));
    }
    Ok(m)
}
