//! The Orion controller's byte stream: a thread reads its lines (within
//! a budget), another writes the bridge's.

use std::io::{self, Write};
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::mpsc::{self, Receiver, Sender};
use std::thread;
use std::time::{Duration, Instant};

use super::{Ahead, MAX_ORION_LINES_PER_S, MAX_ORION_QUEUED, Msg, OrionPort, ReadLine, read_line};
use crate::device::orion::MAX_ORION_LINE;
use crate::error::BridgeError;

/// Starts the Orion port's reader and writer threads: lines to write go
/// into the returned sender; the receiver hears when the writer is done.
pub(super) fn spawn_orion(
    port: OrionPort,
    events: Ahead,
    queued: Arc<AtomicUsize>,
) -> Result<(Sender<String>, Receiver<()>), BridgeError> {
    let OrionPort { reader, writer } = port;
    // Lines written and not yet answered: each lets one line back past the
    // per-second budget.
    let owed = Arc::new(AtomicUsize::new(0));
    {
        let events = events.clone();
        let owed = Arc::clone(&owed);
        // Not joined: a blocking read cannot be interrupted, and the thread
        // ends with its stream or the process.
        thread::Builder::new()
            .name("mw-orion-reader".to_owned())
            .spawn(move || {
                let mut reader = io::BufReader::new(reader);
                let mut budget = Budget {
                    queued,
                    owed,
                    second: Instant::now(),
                    taken: 0,
                    dropped: 0,
                };
                while let Some(msg) = read_one(&mut reader, &events) {
                    if budget.pass(msg, &events).is_err() {
                        return;
                    }
                }
            })
            .map_err(|e| BridgeError::Thread("Orion link reader", e))?;
    }
    let (lines_tx, lines_rx) = mpsc::channel::<String>();
    let (done_tx, done_rx) = mpsc::channel();
    thread::Builder::new()
        .name("mw-orion-writer".to_owned())
        .spawn(move || {
            write_lines(&lines_rx, writer, &events, &owed);
            let _ = done_tx.send(());
        })
        .map_err(|e| BridgeError::Thread("Orion link writer", e))?;
    Ok((lines_tx, done_rx))
}

/// The controller's next line as the runner takes it; `None` when its
/// stream ended or failed (said to the runner first).
fn read_one(reader: &mut impl io::BufRead, events: &Ahead) -> Option<Msg> {
    let msg = match read_line(reader, MAX_ORION_LINE) {
        Ok(ReadLine::Line(text)) => Msg::OrionLine {
            text,
            at: Instant::now(),
        },
        Ok(ReadLine::TooLong { .. }) => {
            Msg::OrionUnreadable(format!("a line over {MAX_ORION_LINE} bytes"))
        }
        Ok(ReadLine::NotUtf8 { .. }) => Msg::OrionUnreadable("a line that is not UTF-8".to_owned()),
        Ok(ReadLine::Partial(_) | ReadLine::End) => {
            let _ = events.send(Msg::OrionLost("the controller's stream ended".to_owned()));
            return None;
        }
        // A line with no end within MAX_SKIP: reported, and reading goes
        // on (the next line starts after it).
        Err(e) if e.kind() == io::ErrorKind::InvalidData => Msg::OrionUnreadable(e.to_string()),
        Err(e) => {
            let _ = events.send(Msg::OrionLost(format!("reading from the controller: {e}")));
            return None;
        }
    };
    Some(msg)
}

/// What the controller's lines may cost: [`MAX_ORION_QUEUED`] waiting,
/// and [`MAX_ORION_LINES_PER_S`] a second beyond its answers.
struct Budget {
    /// Lines handed to the runner and not yet taken.
    queued: Arc<AtomicUsize>,
    /// Lines written and not yet answered.
    owed: Arc<AtomicUsize>,
    /// This second's start and the lines taken in it beyond answers.
    second: Instant,
    taken: u32,
    /// Lines dropped since the last report.
    dropped: u64,
}

impl Budget {
    /// Hands `msg` to the runner if the budget lets it through (after a
    /// report of the lines dropped before it), drops it otherwise. `Err`
    /// when the runner is gone.
    fn pass(&mut self, msg: Msg, events: &Ahead) -> Result<(), ()> {
        let now = Instant::now();
        if now.duration_since(self.second) >= Duration::from_secs(1) {
            self.second = now;
            self.taken = 0;
        }
        if self.queued.load(Ordering::SeqCst) >= MAX_ORION_QUEUED {
            self.dropped += 1;
            return Ok(());
        }
        let answer = self
            .owed
            .fetch_update(Ordering::SeqCst, Ordering::SeqCst, |n| n.checked_sub(1))
            .is_ok();
        if !answer {
            if self.taken >= MAX_ORION_LINES_PER_S {
                self.dropped += 1;
                return Ok(());
            }
            self.taken += 1;
        }
        if self.dropped > 0 {
            self.queued.fetch_add(1, Ordering::SeqCst);
            let report = Msg::OrionUnreadable(format!(
                "{} lines from the controller dropped: more than {MAX_ORION_LINES_PER_S} a second beyond its answers, or {MAX_ORION_QUEUED} waiting",
                self.dropped
            ));
            self.dropped = 0;
            events.send(report)?;
        }
        self.queued.fetch_add(1, Ordering::SeqCst);
        events.send(msg)
    }
}

/// Writes each line the bridge sends the controller, until the runner
/// lets go of the channel.
fn write_lines(
    lines: &Receiver<String>,
    mut writer: Box<dyn io::Write + Send>,
    events: &Ahead,
    owed: &AtomicUsize,
) {
    let mut failing = false;
    for line in lines {
        let written = writer
            .write_all(line.as_bytes())
            .and_then(|()| writer.write_all(b"\n"))
            .and_then(|()| writer.flush());
        // A failed write is the link lost (reported once per run of
        // failures); the writer goes on, as a link that connects again
        // (TCP) takes the next line.
        if written.is_ok() {
            // Bounded: a controller that never answers owes at most one
            // budget's worth.
            let _ = owed.fetch_update(Ordering::SeqCst, Ordering::SeqCst, |n| {
                Some((n + 1).min(MAX_ORION_QUEUED * 8))
            });
        }
        match written {
            Err(e) if !failing => {
                failing = true;
                let _ = events.send(Msg::OrionLost(format!("writing to the controller: {e}")));
            }
            Err(_) => {}
            Ok(()) => failing = false,
        }
    }
}
