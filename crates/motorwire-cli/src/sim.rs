//! `motorwire sim`: simulated devices.

use std::io::{self, BufReader, Write};
use std::sync::mpsc::{self, RecvTimeoutError};
use std::thread;
use std::time::Duration;

use clap::{Subcommand, ValueEnum};
use motorwire_orion::{ArmController, FeedbackKeys, Output};

use crate::input::{self, Refused};
use crate::lines::MAX_LINE;

#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    #[command(subcommand)]
    device: Device,
}

#[derive(Debug, Subcommand)]
enum Device {
    /// The Orion arm controller on stdin/stdout: the boot beacon {"ID":32}
    /// until the first command, then one feedback line per command line.
    /// A line that is not an Orion command changes nothing, prints nothing
    /// on stdout and one message on stderr; every clamp is reported on
    /// stderr.
    Orion(OrionArgs),
}

#[derive(Debug, clap::Args)]
struct OrionArgs {
    /// Direct-control feedback keys: `table` (TRMF ..., the document's
    /// table) or `example` (TRM ..., its example output).
    #[arg(long, value_enum, default_value_t = Keys::Table)]
    feedback_keys: Keys,
    /// Milliseconds between boot beacons until the first command; 0 sends
    /// the beacon exactly once.
    #[arg(long, value_name = "MS", default_value_t = 1000)]
    beacon_interval: u64,
}

#[derive(Debug, Clone, Copy, ValueEnum)]
enum Keys {
    Table,
    Example,
}

pub(crate) fn run(args: &Args) -> u8 {
    match &args.device {
        Device::Orion(a) => orion(a),
    }
}

/// One stdin line, as the reader thread hands it over.
enum Line {
    Text(usize, Result<String, Refused>),
    Failed(io::Error),
}

fn orion(args: &OrionArgs) -> u8 {
    let keys = match args.feedback_keys {
        Keys::Table => FeedbackKeys::Table,
        Keys::Example => FeedbackKeys::Example,
    };
    let (tx, rx) = mpsc::channel();
    // stdin is read on its own thread so the beacon keeps its rhythm while
    // no line arrives.
    thread::spawn(move || {
        let mut reader = BufReader::new(io::stdin());
        let mut line_no = 0;
        loop {
            let item = match input::next_line(&mut reader, MAX_LINE, &mut line_no) {
                Ok(Some(doc)) => Line::Text(doc.line.unwrap_or(line_no), doc.text),
                Ok(None) => break,
                Err(e) => Line::Failed(e),
            };
            let failed = matches!(item, Line::Failed(_));
            if tx.send(item).is_err() || failed {
                break;
            }
        }
    });
    let stdout = io::stdout();
    let mut out = stdout.lock();
    let mut arm = ArmController::new();
    let beacon = Output::Beacon.to_json(keys);
    if writeln!(out, "{beacon}")
        .and_then(|()| out.flush())
        .is_err()
    {
        return 0; // the reader went away
    }
    let interval = Duration::from_millis(args.beacon_interval);
    loop {
        let received = if arm.awaiting_first_command() && args.beacon_interval > 0 {
            match rx.recv_timeout(interval) {
                Ok(line) => line,
                Err(RecvTimeoutError::Timeout) => {
                    if writeln!(out, "{beacon}")
                        .and_then(|()| out.flush())
                        .is_err()
                    {
                        return 0;
                    }
                    continue;
                }
                Err(RecvTimeoutError::Disconnected) => return 0,
            }
        } else {
            match rx.recv() {
                Ok(line) => line,
                Err(_) => return 0,
            }
        };
        let (n, text) = match received {
            Line::Text(n, text) => (n, text),
            Line::Failed(e) => {
                eprintln!("motorwire sim orion: reading standard input: {e}");
                return 2;
            }
        };
        let text = match text {
            Ok(text) => text,
            Err(Refused::TooLarge { limit }) => {
                eprintln!("motorwire sim orion: line {n}: over {limit} bytes; ignored");
                continue;
            }
            Err(Refused::NotUtf8) => {
                eprintln!("motorwire sim orion: line {n}: not UTF-8; ignored");
                continue;
            }
        };
        match arm.handle_line(text.trim()) {
            Ok(response) => {
                for clamp in &response.clamps {
                    eprintln!("motorwire sim orion: line {n}: {clamp}");
                }
                let line = response.output.to_json(keys);
                if writeln!(out, "{line}").and_then(|()| out.flush()).is_err() {
                    return 0;
                }
            }
            Err(e) => eprintln!("motorwire sim orion: line {n}: {e}; ignored"),
        }
    }
}
