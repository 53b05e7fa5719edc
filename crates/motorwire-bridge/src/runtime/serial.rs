//! The serial servo ports' byte streams: per port, a thread reads what the
//! servos send (within a budget) and another writes the bridge's packets.

use std::io::{self, Read, Write};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::mpsc::{self, Receiver, Sender};
use std::thread;
use std::time::Instant;

use super::{Ahead, Msg, ServoLink};
use crate::error::BridgeError;

/// Reads of one servo port handed to the runner and not yet taken, at
/// most: more are dropped (and said) until it catches up. A port at 1
/// Mbit/s carries 100 kB a second; the runner takes each read at once.
pub const MAX_SERIAL_QUEUED: usize = 256;

/// The most bytes one read of a servo port takes.
const READ_CHUNK: usize = 512;

/// A servo port's writer, and what the runner knows of its reader.
pub(super) struct SerialPort {
    pub(super) writer: Sender<Vec<u8>>,
    pub(super) done: Receiver<()>,
    pub(super) queued: Arc<AtomicUsize>,
}

/// Starts each of `links`' reader and writer threads (port `k` is the
/// map's servo port `k`).
pub(super) fn spawn_servo_links(
    links: Vec<ServoLink>,
    ahead: &Ahead,
) -> Result<Vec<SerialPort>, BridgeError> {
    links
        .into_iter()
        .enumerate()
        .map(|(k, link)| {
            let port = u8::try_from(k).unwrap_or(u8::MAX);
            let queued = Arc::new(AtomicUsize::new(0));
            let ServoLink {
                reader,
                writer,
                reopen,
            } = link;
            // A port opened again hands its new writer to the writer.
            let (swap_tx, swap_rx) = mpsc::channel::<Box<dyn Write + Send>>();
            let ended = Arc::new(AtomicBool::new(false));
            {
                let ahead = ahead.clone();
                let queued = Arc::clone(&queued);
                let ended = Arc::clone(&ended);
                let mut reader = Some(reader);
                let mut reopen = reopen;
                // Not joined: a blocking read cannot be interrupted, and
                // the thread ends with its stream or the process.
                thread::Builder::new()
                    .name(format!("mw-servo-reader-{port}"))
                    .spawn(move || {
                        while let Some(r) = reader.take() {
                            read_port(port, r, &ahead, &queued);
                            reader = open_again(port, reopen.as_mut(), &swap_tx, &ahead, &ended);
                        }
                    })
                    .map_err(|e| BridgeError::Thread("servo port reader", e))?;
            }
            let (tx, rx) = mpsc::channel::<Vec<u8>>();
            let (done_tx, done) = mpsc::channel();
            let ahead = ahead.clone();
            thread::Builder::new()
                .name(format!("mw-servo-writer-{port}"))
                .spawn(move || {
                    write_port(port, &rx, writer, &swap_rx, &ahead);
                    ended.store(true, Ordering::SeqCst);
                    let _ = done_tx.send(());
                })
                .map_err(|e| BridgeError::Thread("servo port writer", e))?;
            Ok(SerialPort {
                writer: tx,
                done,
                queued,
            })
        })
        .collect()
}

/// Reads port `port` until its stream ends or fails (said once), handing
/// each read to the runner within [`MAX_SERIAL_QUEUED`].
fn read_port(port: u8, mut reader: Box<dyn Read + Send>, ahead: &Ahead, queued: &AtomicUsize) {
    let mut buf = [0u8; READ_CHUNK];
    let mut dropped: u64 = 0;
    loop {
        let n = match reader.read(&mut buf) {
            Ok(0) => {
                ahead.bus_error(format!("servo port {port}: its stream ended"));
                return;
            }
            Ok(n) => n,
            Err(e)
                if matches!(
                    e.kind(),
                    io::ErrorKind::Interrupted | io::ErrorKind::TimedOut
                ) =>
            {
                continue;
            }
            Err(e) => {
                ahead.bus_error(format!("servo port {port}: reading: {e}"));
                return;
            }
        };
        if queued.load(Ordering::SeqCst) >= MAX_SERIAL_QUEUED {
            dropped += n as u64;
            continue;
        }
        if dropped > 0 {
            ahead.bus_error(format!(
                "servo port {port}: {dropped} bytes dropped while the bridge was behind"
            ));
            dropped = 0;
        }
        queued.fetch_add(1, Ordering::SeqCst);
        let bytes = buf.get(..n).unwrap_or(&[]).to_vec();
        if ahead
            .send(Msg::Serial {
                port,
                bytes,
                at: Instant::now(),
            })
            .is_err()
        {
            return;
        }
    }
}

/// How often a failed port is opened again.
const REOPEN_EVERY: std::time::Duration = std::time::Duration::from_millis(500);

/// Port `port`, failed, opened again with `reopen` every
/// [`REOPEN_EVERY`] until it opens (its writer handed over on `swap`, its
/// reader returned) or the runner is done (`ended`); `None` without a way
/// to open it.
fn open_again(
    port: u8,
    reopen: Option<&mut crate::runtime::Reopen>,
    swap: &mpsc::Sender<Box<dyn Write + Send>>,
    ahead: &Ahead,
    ended: &AtomicBool,
) -> Option<Box<dyn Read + Send>> {
    let reopen = reopen?;
    loop {
        thread::sleep(REOPEN_EVERY);
        if ended.load(Ordering::SeqCst) {
            return None;
        }
        if let Ok((reader, writer)) = reopen() {
            swap.send(writer).ok()?;
            ahead.bus_error(format!("servo port {port}: open again"));
            return Some(reader);
        }
    }
}

/// Writes the bridge's packets to port `port`, each whole and flushed, in
/// order, until the runner is done (on the port's new writer once it is
/// opened again, `swap`); a failed write is said (the servos' missing
/// answers say the rest).
fn write_port(
    port: u8,
    packets: &Receiver<Vec<u8>>,
    mut writer: Box<dyn Write + Send>,
    swap: &Receiver<Box<dyn Write + Send>>,
    ahead: &Ahead,
) {
    let mut failing = false;
    while let Ok(bytes) = packets.recv() {
        while let Ok(w) = swap.try_recv() {
            writer = w;
            failing = false;
        }
        match writer.write_all(&bytes).and_then(|()| writer.flush()) {
            Ok(()) => failing = false,
            Err(e) if !failing => {
                failing = true;
                ahead.bus_error(format!("servo port {port}: writing: {e}"));
            }
            Err(_) => {}
        }
    }
    let _ = writer.flush();
}
