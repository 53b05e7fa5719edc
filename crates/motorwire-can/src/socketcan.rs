//! Linux SocketCAN (feature `socketcan`): a CAN-FD raw socket on an interface.
//!
//! ```no_run
//! use std::time::Duration;
//! use motorwire_can::{CanBus, CanId, Frame, socketcan::{Filter, SocketCanBus}};
//!
//! let mut bus = SocketCanBus::open("vcan0")?;
//! // Only the joints' answers, ids 0x010 to 0x01F.
//! bus.set_filters(&[Filter::standard(0x010, 0x7F0)])?;
//! bus.send(&Frame::fd(CanId::standard(0x000)?, &[0x00, 0x10, 0x01, 0x01])?)?;
//! let answer = bus.recv(Duration::from_millis(100))?;
//! println!("{} at {:?}", answer.frame, answer.timestamp);
//! # Ok::<(), motorwire_can::Error>(())
//! ```

use std::io;
use std::time::{Duration, UNIX_EPOCH};

use socketcan::errors::{ControllerProblems, ErrorCause};
use socketcan::id::FdFlags;
use socketcan::{
    CanAnyFrame, CanDataFrame, CanFdFrame, CanFilter, EmbeddedFrame, ExtendedId,
    Frame as KernelFrame, Id, Socket, SocketOptions, StandardId,
};

use crate::{CanBus, CanId, Error, Frame, Received};

/// A kernel receive filter: a frame passes when `frame_id & mask == id & mask`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Filter {
    /// The identifier to match.
    pub id: u32,
    /// Which bits of it must match.
    pub mask: u32,
    /// Match extended (true) or standard (false) frames only.
    pub extended: bool,
}

impl Filter {
    /// Standard frames whose id matches `id` under `mask`.
    pub fn standard(id: u16, mask: u16) -> Self {
        Self {
            id: u32::from(id),
            mask: u32::from(mask),
            extended: false,
        }
    }

    /// Extended frames whose id matches `id` under `mask`.
    pub fn extended(id: u32, mask: u32) -> Self {
        Self {
            id,
            mask,
            extended: true,
        }
    }

    fn to_kernel(self) -> CanFilter {
        const EFF: u32 = 0x8000_0000;
        const RTR: u32 = 0x4000_0000;
        let id = if self.extended {
            self.id | EFF
        } else {
            self.id
        };
        // Match the frame format too, and never remote frames.
        CanFilter::new(id, self.mask | EFF | RTR)
    }
}

/// A SocketCAN interface opened for CAN-FD (classic frames too).
#[derive(Debug)]
pub struct SocketCanBus {
    iface: String,
    socket: socketcan::CanFdSocket,
}

fn open_error(iface: &str, e: &io::Error) -> Error {
    match e.raw_os_error() {
        Some(19) => Error::NoSuchInterface {
            iface: iface.to_owned(),
        },
        Some(100) => Error::InterfaceDown {
            iface: iface.to_owned(),
        },
        _ => Error::io("opening a CAN socket", e),
    }
}

/// Receive timestamps on, and every error frame delivered.
fn prepare(socket: &impl SocketOptions) -> Result<(), Error> {
    socket
        .set_recv_timestamp(true)
        .map_err(|e| Error::io("enabling receive timestamps", &e))?;
    socket
        .set_error_filter_accept_all()
        .map_err(|e| Error::io("enabling error frames", &e))
}

/// An error of an open interface.
fn io_error(iface: &str, op: &'static str, e: &io::Error) -> Error {
    match e.raw_os_error() {
        Some(100) => Error::InterfaceDown {
            iface: iface.to_owned(),
        },
        Some(19) => Error::NoSuchInterface {
            iface: iface.to_owned(),
        },
        _ => Error::io(op, e),
    }
}

/// An error sending `frame`: an FD frame on a classic interface is EINVAL.
fn send_error(iface: &str, frame: &Frame, e: &io::Error) -> Error {
    if e.raw_os_error() == Some(22) && frame.is_fd() {
        Error::FdNotSupported {
            iface: iface.to_owned(),
        }
    } else {
        io_error(iface, "sending a CAN frame", e)
    }
}

impl SocketCanBus {
    /// Opens `iface` (`can0`, `vcan0`) for CAN-FD, with receive timestamps
    /// and every error frame delivered as an error.
    ///
    /// # Errors
    /// [`Error::NoSuchInterface`], [`Error::FdNotSupported`] (the interface's
    /// MTU is 16), or [`Error::Io`].
    pub fn open(iface: &str) -> Result<Self, Error> {
        let socket = socketcan::CanFdSocket::open(iface).map_err(|e| open_error(iface, &e))?;
        prepare(&socket)?;
        Ok(Self {
            iface: iface.to_owned(),
            socket,
        })
    }

    /// The interface's name.
    pub fn interface(&self) -> &str {
        &self.iface
    }

    /// Receives only frames that pass one of `filters` (in the kernel);
    /// an empty list receives nothing but error frames.
    ///
    /// # Errors
    /// [`Error::Io`].
    pub fn set_filters(&mut self, filters: &[Filter]) -> Result<(), Error> {
        let kernel: Vec<CanFilter> = filters.iter().map(|f| f.to_kernel()).collect();
        self.socket
            .set_filters(&kernel)
            .map_err(|e| Error::io("setting receive filters", &e))
    }

    /// Receives every frame again.
    ///
    /// # Errors
    /// [`Error::Io`].
    pub fn clear_filters(&mut self) -> Result<(), Error> {
        self.socket
            .set_filter_accept_all()
            .map_err(|e| Error::io("clearing receive filters", &e))
    }
}

fn to_kernel(frame: &Frame) -> Result<CanAnyFrame, Error> {
    let id: Id = match frame.id() {
        CanId::Standard(id) => StandardId::new(id).map(Id::Standard),
        CanId::Extended(id) => ExtendedId::new(id).map(Id::Extended),
    }
    .ok_or(Error::InvalidId {
        id: frame.id().raw(),
        extended: frame.id().is_extended(),
    })?;
    let invalid = Error::InvalidLength {
        len: frame.len(),
        fd: frame.is_fd(),
    };
    if frame.is_fd() {
        let mut flags = FdFlags::empty();
        flags.set(FdFlags::BRS, frame.brs());
        flags.set(FdFlags::ESI, frame.esi());
        CanFdFrame::with_flags(id, frame.data(), flags)
            .map(CanAnyFrame::Fd)
            .ok_or(invalid)
    } else {
        CanDataFrame::new(id, frame.data())
            .map(CanAnyFrame::Normal)
            .ok_or(invalid)
    }
}

fn from_id(id: Id) -> Result<CanId, Error> {
    match id {
        Id::Standard(s) => CanId::standard(s.as_raw()),
        Id::Extended(e) => CanId::extended(e.as_raw()),
    }
}

/// A frame from the kernel; error frames become their typed error.
fn from_kernel(k: CanAnyFrame) -> Result<Frame, Error> {
    match k {
        CanAnyFrame::Normal(f) => Frame::classic(from_id(f.id())?, f.data()),
        CanAnyFrame::Fd(f) => Frame::fd_exact(from_id(f.id())?, f.data(), f.is_brs(), f.is_esi()),
        CanAnyFrame::Remote(f) => Err(Error::ErrorFrame(format!(
            "remote frame for id {:X}, which motorwire does not use",
            KernelFrame::raw_id(&f)
        ))),
        CanAnyFrame::Error(f) => Err(error_frame(&f.into_error())),
    }
}

/// Maps a kernel error frame to the most telling typed error.
fn error_frame(e: &socketcan::CanError) -> Error {
    let (tx, rx) = e.counters().unwrap_or((0, 0));
    for cause in e.causes() {
        match *cause {
            ErrorCause::BusOff => return Error::BusOff,
            ErrorCause::LostArbitration(bit) => return Error::LostArbitration { bit },
            ErrorCause::NoAck => return Error::NoAck,
            ErrorCause::TransmitTimeout => return Error::TransmitTimeout,
            ErrorCause::Restarted => return Error::Restarted,
            ErrorCause::Controller(p)
                if p.intersects(
                    ControllerProblems::RX_PASSIVE | ControllerProblems::TX_PASSIVE,
                ) =>
            {
                return Error::ErrorPassive { tx, rx };
            }
            ErrorCause::Controller(p)
                if p.intersects(
                    ControllerProblems::RX_WARNING | ControllerProblems::TX_WARNING,
                ) =>
            {
                return Error::ErrorWarning { tx, rx };
            }
            _ => {}
        }
    }
    Error::ErrorFrame(e.to_string())
}

impl CanBus for SocketCanBus {
    fn send(&mut self, frame: &Frame) -> Result<(), Error> {
        let k = to_kernel(frame)?;
        self.socket
            .write_frame(&k)
            .map_err(|e| send_error(&self.iface, frame, &e))
    }

    fn recv(&mut self, timeout: Duration) -> Result<Received, Error> {
        // A zero SO_RCVTIMEO would block forever: poll with the shortest wait.
        let wait = timeout.max(Duration::from_micros(1));
        self.socket
            .set_read_timeout(wait)
            .map_err(|e| Error::io("setting the receive timeout", &e))?;
        let (k, at) = match self.socket.read_frame_with_timestamp() {
            Ok(r) => r,
            Err(e)
                if matches!(
                    e.kind(),
                    io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut
                ) =>
            {
                return Err(Error::Timeout(timeout));
            }
            Err(e) => return Err(io_error(&self.iface, "receiving a CAN frame", &e)),
        };
        let timestamp = at.duration_since(UNIX_EPOCH).unwrap_or_default();
        Ok(Received {
            frame: from_kernel(k)?,
            timestamp,
        })
    }
}

/// The async twin of [`SocketCanBus`] (features `socketcan` and `tokio`).
#[cfg(feature = "tokio")]
#[cfg_attr(docsrs, doc(cfg(feature = "tokio")))]
#[derive(Debug)]
pub struct AsyncSocketCanBus {
    iface: String,
    socket: socketcan::tokio::CanFdSocket,
}

#[cfg(feature = "tokio")]
#[cfg_attr(docsrs, doc(cfg(feature = "tokio")))]
impl AsyncSocketCanBus {
    /// Opens `iface` as [`SocketCanBus::open`] does; needs a tokio runtime
    /// with I/O enabled.
    ///
    /// # Errors
    /// As [`SocketCanBus::open`].
    pub fn open(iface: &str) -> Result<Self, Error> {
        let socket =
            socketcan::tokio::CanFdSocket::open(iface).map_err(|e| open_error(iface, &e))?;
        prepare(&socket)?;
        Ok(Self {
            iface: iface.to_owned(),
            socket,
        })
    }
}

#[cfg(feature = "tokio")]
#[cfg_attr(docsrs, doc(cfg(feature = "tokio")))]
impl crate::AsyncCanBus for AsyncSocketCanBus {
    async fn send(&mut self, frame: &Frame) -> Result<(), Error> {
        let k = to_kernel(frame)?;
        self.socket
            .write_frame(&k)
            .await
            .map_err(|e| send_error(&self.iface, frame, &e))
    }

    async fn recv(&mut self) -> Result<Received, Error> {
        let (k, at) = self
            .socket
            .read_frame_with_timestamp()
            .await
            .map_err(|e| io_error(&self.iface, "receiving a CAN frame", &e))?;
        let timestamp = at.duration_since(UNIX_EPOCH).unwrap_or_default();
        Ok(Received {
            frame: from_kernel(k)?,
            timestamp,
        })
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use socketcan::CanErrorFrame;

    fn mapped(class: u32, data: [u8; 8]) -> Error {
        error_frame(&CanErrorFrame::new_error(class, &data).unwrap().into_error())
    }

    #[test]
    fn error_frames_become_typed_errors() {
        // Class bits and data bytes of linux/can/error.h.
        assert_eq!(mapped(0x40, [0; 8]), Error::BusOff);
        assert_eq!(
            mapped(0x02, [7, 0, 0, 0, 0, 0, 0, 0]),
            Error::LostArbitration { bit: 7 }
        );
        assert_eq!(mapped(0x20, [0; 8]), Error::NoAck);
        assert_eq!(
            mapped(0x04 | 0x200, [0, 0x20, 0, 0, 0, 0, 130, 4]),
            Error::ErrorPassive { tx: 130, rx: 4 }
        );
        assert_eq!(
            mapped(0x04 | 0x200, [0, 0x04, 0, 0, 0, 0, 0, 97]),
            Error::ErrorWarning { tx: 0, rx: 97 }
        );
        assert!(matches!(
            mapped(0x08, [0, 0, 0x02, 0x08, 0, 0, 0, 0]),
            Error::ErrorFrame(_)
        ));
    }
}
