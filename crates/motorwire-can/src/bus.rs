//! The bus traits: write user code once, run it on every bus.

use std::future::Future;
use std::time::Duration;

use crate::{Error, Frame};

/// A frame as it arrived, with its receive time.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Received {
    /// The frame.
    pub frame: Frame,
    /// When it arrived: time since the UNIX epoch on SocketCAN (the kernel's
    /// receive timestamp), time since the bus started on the in-memory bus.
    pub timestamp: Duration,
}

/// A CAN bus, blocking.
///
/// ```
/// use std::time::Duration;
/// use motorwire_can::{CanBus, CanId, Frame, SimBus};
///
/// fn ping(bus: &mut impl CanBus) -> Result<Frame, motorwire_can::Error> {
///     bus.send(&Frame::fd(CanId::standard(0x10)?, &[1, 2, 3])?)?;
///     Ok(bus.recv(Duration::from_millis(100))?.frame)
/// }
///
/// let bus = SimBus::default();
/// let (mut a, mut b) = (bus.port(), bus.port());
/// b.send(&Frame::classic(CanId::standard(0x20)?, &[9])?)?;
/// assert_eq!(ping(&mut a)?.data(), &[9]);
/// assert_eq!(b.recv(Duration::ZERO)?.frame.data(), &[1, 2, 3]);
/// # Ok::<(), motorwire_can::Error>(())
/// ```
pub trait CanBus {
    /// Sends one frame.
    ///
    /// # Errors
    /// The bus's own: [`Error::InterfaceDown`], [`Error::BusOff`], [`Error::Closed`]...
    fn send(&mut self, frame: &Frame) -> Result<(), Error>;

    /// Receives the next frame, waiting up to `timeout` (`Duration::ZERO`
    /// polls). Error frames come back as typed errors.
    ///
    /// # Errors
    /// [`Error::Timeout`] when nothing arrived; the bus's own errors.
    fn recv(&mut self, timeout: Duration) -> Result<Received, Error>;
}

/// A CAN bus, async (tokio). Wrap `recv` in `tokio::time::timeout` for a
/// deadline.
pub trait AsyncCanBus {
    /// Sends one frame.
    ///
    /// # Errors
    /// As [`CanBus::send`].
    fn send(&mut self, frame: &Frame) -> impl Future<Output = Result<(), Error>> + Send;

    /// Receives the next frame.
    ///
    /// # Errors
    /// As [`CanBus::recv`], without the timeout.
    fn recv(&mut self) -> impl Future<Output = Result<Received, Error>> + Send;
}

impl<B: CanBus + ?Sized> CanBus for &mut B {
    fn send(&mut self, frame: &Frame) -> Result<(), Error> {
        (**self).send(frame)
    }
    fn recv(&mut self, timeout: Duration) -> Result<Received, Error> {
        (**self).recv(timeout)
    }
}
