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

    /// Asks the bus to call `waker` (on the sending thread, without
    /// blocking) whenever a frame is queued for this port, due at once, so
    /// that a program can wait for frames and for its other work on one
    /// thread, polling `recv(Duration::ZERO)` when woken, instead of
    /// keeping a thread blocked in `recv`. Whether the bus does it:
    /// `false` (the default, every bus that only blocks, and a bus that
    /// may hold a frame for later, which no waker would tell when it
    /// falls due) leaves the waker unused.
    ///
    /// ```
    /// use std::sync::Arc;
    /// use std::sync::atomic::{AtomicUsize, Ordering};
    /// use std::time::Duration;
    /// use motorwire_can::{CanBus, CanId, Frame, SimBus};
    ///
    /// let bus = SimBus::default();
    /// let (mut a, mut b) = (bus.port(), bus.port());
    /// let woken = Arc::new(AtomicUsize::new(0));
    /// let count = Arc::clone(&woken);
    /// assert!(b.set_waker(Arc::new(move || {
    ///     count.fetch_add(1, Ordering::SeqCst);
    /// })));
    /// a.send(&Frame::classic(CanId::standard(0x20)?, &[9])?)?;
    /// assert_eq!(woken.load(Ordering::SeqCst), 1);
    /// assert_eq!(b.recv(Duration::ZERO)?.frame.data(), &[9]);
    /// // A port is not woken by its own frames.
    /// b.send(&Frame::classic(CanId::standard(0x21)?, &[1])?)?;
    /// assert_eq!(woken.load(Ordering::SeqCst), 1);
    /// # Ok::<(), motorwire_can::Error>(())
    /// ```
    fn set_waker(&mut self, waker: FrameWaker) -> bool {
        let _ = waker;
        false
    }
}

/// What a bus calls when a frame is queued for a port ([`CanBus::set_waker`]).
pub type FrameWaker = std::sync::Arc<dyn Fn() + Send + Sync>;

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
    fn set_waker(&mut self, waker: FrameWaker) -> bool {
        (**self).set_waker(waker)
    }
}
