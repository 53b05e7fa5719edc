//! `motorwire irpc encode|decode`.

use clap::{Args as ClapArgs, Subcommand};
use motorwire_irpc::{Message, WireVersion};

use crate::lines::{filter, from_hex, to_hex};

/// Encode and decode iRPC messages.
#[derive(Debug, ClapArgs)]
pub(crate) struct Args {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Read JSON messages, one per line, on stdin; print each as lowercase hex.
    Encode(Wire),
    /// Read hex messages, one per line (spaces allowed), on stdin; print each as JSON.
    Decode(DecodeArgs),
}

#[derive(Debug, ClapArgs)]
struct Wire {
    /// The iRPC wire version: v1, v2.0, v2.1 or v2.2.
    #[arg(long, value_parser = parse_wire)]
    wire: WireVersion,
}

#[derive(Debug, ClapArgs)]
struct DecodeArgs {
    #[command(flatten)]
    wire: Wire,
    /// Each line is a CAN-FD frame: accept zero padding up to a CAN-FD length.
    #[arg(long)]
    frame: bool,
}

pub(crate) fn parse_wire(s: &str) -> Result<WireVersion, String> {
    s.parse()
        .map_err(|e: motorwire_irpc::UnknownWireVersion| e.to_string())
}

pub(crate) fn run(args: &Args) -> u8 {
    match &args.command {
        Command::Encode(w) => filter(|line| encode(w.wire, line)),
        Command::Decode(d) => filter(|line| decode(d.wire.wire, d.frame, line)),
    }
}

fn encode(v: WireVersion, line: &str) -> Result<String, String> {
    let msg: Message =
        serde_json::from_str(line).map_err(|e| format!("not an iRPC message: {e}"))?;
    let mut buf = [0u8; 256];
    let n = msg.encode(v, &mut buf).map_err(|e| e.to_string())?;
    Ok(to_hex(buf.get(..n).unwrap_or_default()))
}

fn decode(v: WireVersion, frame: bool, line: &str) -> Result<String, String> {
    let bytes = from_hex(line)?;
    let msg = if frame {
        Message::decode_frame(v, &bytes)
    } else {
        Message::decode(v, &bytes)
    }
    .map_err(|e| e.to_string())?;
    serde_json::to_string(&msg).map_err(|e| e.to_string())
}
