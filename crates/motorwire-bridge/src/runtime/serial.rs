//! The serial servo ports' byte streams: per port, a thread reads what the
//! servos send (within a budget) and another writes the bridge's packets.

use std::io::{self, Read, Write};
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
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
            let ServoLink { reader, writer } = link;
            {
                let ahead = ahead.clone();
                let queued = Arc::clone(&queued);
                // Not joined: a blocking read cannot be interrupted, and
                // the thread ends with its stream or the process.
                thread::Builder::new()
                    .name(format!("mw-servo-reader-{port}"))
                    .spawn(move || read_port(port, reader, &ahead, &queued))
                    .map_err(|e| BridgeError::Thread("servo port reader", e))?;
            }
            let (tx, rx) = mpsc::channel::<Vec<u8>>();
            let (done_tx, done) = mpsc::channel();
            let ahead = ahead.clone();
            thread::Builder::new()
                .name(format!("mw-servo-writer-{port}"))
                .spawn(move || {
                    write_port(port, &rx, writer, &ahead);
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

/// Writes the bridge's packets to port `port`, each whole and flushed, in
/// order, until the runner is done; a failed write is said (the servos'
/// missing answers say the rest).
fn write_port(
    port: u8,
    packets: &Receiver<Vec<u8>>,
    mut writer: Box<dyn Write + Send>,
    ahead: &Ahead,
) {
    let mut failing = false;
    while let Ok(bytes) = packets.recv() {
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
