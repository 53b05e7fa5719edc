//! mjbots' fdcanusb: a USB CAN-FD adapter that speaks a text protocol over
//! its serial port (`can send ID HEX FLAGS` out; `OK`, `rcv ID HEX FLAGS`
//! and `ERR ...` in), and that moteus controllers speak directly over a
//! UART. The lines are built and read by mjbots' `moteus-protocol`
//! (`moteus_protocol::fdcanusb`); this is the [`CanBus`] around them, over
//! any byte stream: a serial port (`serialport`), a pty, a pipe.
//!
//! A [`FdcanusbBus`] used only to send writes its lines and reads nothing;
//! one used to receive skips the adapter's `OK`s, gives back each `rcv` as
//! a frame, and each `ERR` line as [`Error::Adapter`] (the adapter refused
//! a line: a frame was not sent). A stream whose reads time out (a serial
//! port's timeout) makes [`CanBus::recv`] return [`Error::Timeout`].
//!
//! ```
//! use std::time::Duration;
//! use motorwire_can::fdcanusb::FdcanusbBus;
//! use motorwire_can::{CanBus, CanId, Frame};
//!
//! // What an adapter answers: the OK of a `can send`, then a reply frame
//! // (`E`: an extended id; `B`: bit-rate switching; `F`: CAN-FD).
//! let adapter: &[u8] = b"OK\r\nrcv 100 21000A E B F\r\n";
//! let mut bus = FdcanusbBus::new(std::io::Cursor::new(adapter.to_vec()), Vec::new());
//! let r = bus.recv(Duration::from_millis(10))?;
//! assert_eq!(r.frame.id(), CanId::extended(0x100)?);
//! assert_eq!(r.frame.data(), &[0x21, 0x00, 0x0A]);
//!
//! let mut out = FdcanusbBus::new(std::io::empty(), Vec::new());
//! out.send(&Frame::fd(CanId::extended(0x8001)?, &[0x01, 0x00, 0x00])?)?;
//! assert_eq!(out.into_writer(), b"can send 8001 010000 BF\n");
//! # Ok::<(), motorwire_can::Error>(())
//! ```

use std::io::{BufReader, Read, Write};
use std::time::{Duration, Instant};

use moteus_protocol::CanFdFrame;
use moteus_protocol::fdcanusb::{
    EncodeOptions, Line, MAX_LINE_LENGTH, encode_can_send, parse_line, strip_checksum,
};

use crate::{CanBus, CanId, Error, Frame, Received};

/// The longest line read from an adapter: a `rcv` of 64 bytes with its
/// flags and a checksum fits in [`MAX_LINE_LENGTH`]; a longer one is not the
/// protocol's.
const MAX_READ_LINE: usize = 4 * MAX_LINE_LENGTH;

/// A CAN-FD bus through an fdcanusb adapter (or a moteus UART), over a
/// byte stream read from `R` and written to `W`.
#[derive(Debug)]
pub struct FdcanusbBus<R, W> {
    reader: BufReader<R>,
    writer: W,
    line: Vec<u8>,
    start: Instant,
    options: EncodeOptions,
}

impl<R: Read, W: Write> FdcanusbBus<R, W> {
    /// A bus reading the adapter's lines from `reader` and writing its
    /// commands to `writer` (for a serial port, the port and its clone).
    pub fn new(reader: R, writer: W) -> Self {
        Self {
            reader: BufReader::new(reader),
            writer,
            line: Vec::new(),
            start: Instant::now(),
            options: EncodeOptions::default(),
        }
    }

    /// Appends a CRC-8 checksum to each line sent (what a moteus UART
    /// wants; an fdcanusb takes lines with or without).
    #[must_use]
    pub fn with_checksum(mut self) -> Self {
        self.options.checksum = true;
        self
    }

    /// The writer (what was sent to it).
    pub fn into_writer(self) -> W {
        self.writer
    }

    /// One line from the adapter, without its end; `None` at a timeout.
    fn read_line(&mut self, timeout: Duration) -> Result<Option<Vec<u8>>, Error> {
        let deadline = Instant::now() + timeout;
        loop {
            let mut byte = [0u8; 1];
            match self.reader.read(&mut byte) {
                Ok(0) => return Err(Error::Closed),
                Ok(_) => match byte[0] {
                    b'\n' => return Ok(Some(std::mem::take(&mut self.line))),
                    b'\r' => {}
                    b => {
                        if self.line.len() >= MAX_READ_LINE {
                            self.line.clear();
                            return Err(Error::Adapter(format!(
                                "a line of over {MAX_READ_LINE} bytes (not the fdcanusb protocol)"
                            )));
                        }
                        self.line.push(b);
                    }
                },
                Err(e)
                    if matches!(
                        e.kind(),
                        std::io::ErrorKind::TimedOut | std::io::ErrorKind::WouldBlock
                    ) =>
                {
                    if Instant::now() >= deadline {
                        return Ok(None);
                    }
                }
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) => {
                    return Err(Error::Io {
                        op: "reading the fdcanusb",
                        kind: e.kind(),
                        message: e.to_string(),
                    });
                }
            }
        }
    }
}

impl<R: Read, W: Write> CanBus for FdcanusbBus<R, W> {
    fn send(&mut self, frame: &Frame) -> Result<(), Error> {
        let mut f = CanFdFrame::new();
        f.arbitration_id = frame.id().raw();
        let data = frame.data();
        let Some(dst) = f.data.get_mut(..data.len()) else {
            return Err(Error::InvalidLength {
                len: data.len(),
                fd: true,
            });
        };
        dst.copy_from_slice(data);
        f.size = u8::try_from(data.len()).unwrap_or(64);
        f.set_fdcan(frame.is_fd());
        f.set_brs(frame.brs());
        let mut line = [0u8; MAX_LINE_LENGTH];
        let n = encode_can_send(&f, &self.options, &mut line)
            .map_err(|_| Error::Adapter("a frame too long for one fdcanusb line".to_owned()))?;
        let io = |e: std::io::Error| Error::Io {
            op: "writing to the fdcanusb",
            kind: e.kind(),
            message: e.to_string(),
        };
        self.writer
            .write_all(line.get(..n).unwrap_or(&[]))
            .map_err(io)?;
        self.writer.flush().map_err(io)
    }

    fn recv(&mut self, timeout: Duration) -> Result<Received, Error> {
        let deadline = Instant::now() + timeout;
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            let Some(raw) = self.read_line(left)? else {
                return Err(Error::Timeout(timeout));
            };
            let (content, had_checksum, valid) = strip_checksum(&raw);
            if had_checksum && !valid {
                return Err(Error::Adapter(format!(
                    "a line with a bad checksum: {}",
                    String::from_utf8_lossy(&raw)
                )));
            }
            match parse_line(content) {
                Line::Ok => {}
                Line::Err(e) => {
                    return Err(Error::Adapter(String::from_utf8_lossy(e).into_owned()));
                }
                Line::Rcv(f) => {
                    let id = f.arbitration_id & 0x1FFF_FFFF;
                    let id = if id > 0x7FF || f.arbitration_id & 0x8000_0000 != 0 {
                        CanId::extended(id)?
                    } else {
                        CanId::standard(u16::try_from(id).unwrap_or(0))?
                    };
                    // The line's own flags (`F`: CAN-FD; `B`: bit-rate switch).
                    let flag = |x: &[u8]| content.split(|b| *b == b' ').skip(3).any(|f| f == x);
                    let frame = if flag(b"F") || f.size > 8 {
                        Frame::fd_exact(id, f.payload(), flag(b"B"), false)
                            .or_else(|_| Frame::fd(id, f.payload()))?
                    } else {
                        Frame::classic(id, f.payload())?
                    };
                    return Ok(Received {
                        frame,
                        timestamp: self.start.elapsed(),
                    });
                }
                // Blank lines and the adapter's own chatter.
                Line::Other([]) => {}
                Line::Other(l) => {
                    return Err(Error::Adapter(format!(
                        "an unexpected line: {}",
                        String::from_utf8_lossy(l)
                    )));
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;
    use std::io::Cursor;

    fn bus(input: &[u8]) -> FdcanusbBus<Cursor<Vec<u8>>, Vec<u8>> {
        FdcanusbBus::new(Cursor::new(input.to_vec()), Vec::new())
    }

    #[test]
    fn oks_are_skipped_errs_and_bad_lines_are_typed_and_the_end_is_closed() {
        let mut b = bus(b"OK\nERR unknown command\nrcv 100 2100 F *00\nwhat\nrcv 0ab 0102\n");
        let ms = Duration::from_millis(5);
        assert_eq!(
            b.recv(ms).unwrap_err(),
            Error::Adapter("ERR unknown command".to_owned())
        );
        assert!(
            matches!(b.recv(ms).unwrap_err(), Error::Adapter(m) if m.starts_with("a line with a bad checksum"))
        );
        assert_eq!(
            b.recv(ms).unwrap_err(),
            Error::Adapter("an unexpected line: what".to_owned())
        );
        // A standard id, a classic frame.
        let r = b.recv(ms).unwrap();
        assert_eq!(
            (r.frame.id(), r.frame.data(), r.frame.is_fd()),
            (CanId::standard(0xab).unwrap(), &[1u8, 2][..], false)
        );
        assert_eq!(b.recv(ms).unwrap_err(), Error::Closed);
    }

    #[test]
    fn frames_go_out_padded_as_the_protocol_pads_with_a_checksum_when_asked() {
        let mut b = FdcanusbBus::new(std::io::empty(), Vec::new()).with_checksum();
        // 9 bytes: padded to 12 with 0x50 by the line encoder.
        b.send(
            &Frame::fd_exact(
                CanId::extended(0x8001).unwrap(),
                &[
                    0x11, 0, 0x1c, 4, 1, 0x11, 0x0b, 0x13, 0x0d, 0x50, 0x50, 0x50,
                ],
                true,
                false,
            )
            .unwrap(),
        )
        .unwrap();
        let line = String::from_utf8(b.into_writer()).unwrap();
        assert!(
            line.starts_with("can send 8001 11001C0401110B130D505050 BF *"),
            "{line}"
        );
        let (content, had, valid) = strip_checksum(line.trim_end().as_bytes());
        assert!(had && valid, "{line}");
        assert_eq!(content, b"can send 8001 11001C0401110B130D505050 BF");
    }
}
