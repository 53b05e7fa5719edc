//! `motorwire candump decode`: a `candump -L` log, decoded frame by frame.

use std::io::{self, Write};
use std::path::PathBuf;

use clap::{Args as ClapArgs, Subcommand};
use motorwire_can::candump::LogEntry;
use motorwire_compact::CompactCommand;
use motorwire_irpc::{Message, WireVersion};
use serde_json::{Value, json};

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
                json!({ "line": n, "error": format!("the line is over {limit} bytes") })
            }
            Err(Refused::NotUtf8) => json!({ "line": n, "error": "the line is not UTF-8" }),
        };
        failed |= value.get("error").is_some();
        if writeln!(reader.out(), "{value}").is_err() {
            return 2;
        }
    }
    if reader.out().flush().is_err() {
        return 2;
    }
    u8::from(failed)
}

/// One line's JSON: always `line`, then either the frame and what it
/// decodes to, or `error`.
pub(crate) fn decode_line(
    line_no: usize,
    line: &str,
    wire: Option<WireVersion>,
    compact: bool,
) -> Value {
    let entry = match LogEntry::parse(line) {
        Ok(e) => e,
        Err(reason) => return json!({ "line": line_no, "error": reason }),
    };
    let mut v = json!({
        "line": line_no,
        "timestamp": format!("{}.{:06}", entry.timestamp.as_secs(), entry.timestamp.subsec_micros()),
        "interface": entry.interface,
        "can_id": entry.frame.id().to_string(),
        "fd": entry.frame.is_fd(),
        "len": entry.frame.len(),
    });
    let decoded = if compact {
        CompactCommand::decode(entry.frame.data())
            .map_err(|e| e.to_string())
            .and_then(|c| serde_json::to_value(c).map_err(|e| e.to_string()))
            .map(|c| ("command", c))
    } else {
        let wire = wire.unwrap_or(WireVersion::V2_0);
        decode_irpc(wire, &entry.frame).map(|m| ("message", m))
    };
    if let Some(obj) = v.as_object_mut() {
        match decoded {
            Ok((key, value)) => obj.insert(key.to_owned(), value),
            Err(e) => obj.insert("error".to_owned(), Value::String(e)),
        };
    }
    v
}

fn decode_irpc(wire: WireVersion, frame: &motorwire_can::Frame) -> Result<Value, String> {
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
    serde_json::to_value(m).map_err(|e| e.to_string())
}
