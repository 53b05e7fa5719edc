//! ISO-TP (ISO 15765-2): messages longer than one frame, segmented into a
//! first frame and consecutive frames paced by the receiver's flow control.
//! Classic CAN (8-byte frames) and CAN-FD (up to 64), normal addressing, as
//! the Linux kernel's `CAN_ISOTP` sockets speak it.
//!
//! The core is sans-IO: [`Sender`] and [`Receiver`] take frames and the time
//! and give frames back. [`send`] and [`recv`] drive them on any [`CanBus`].
//!
//! ```
//! use std::time::Duration;
//! use motorwire_can::{CanId, Clock, SimBus, SimConfig, isotp::{self, IsoTpConfig}};
//!
//! let bus = SimBus::new(SimConfig { clock: Clock::Real, ..SimConfig::default() })?;
//! let (mut a, mut b) = (bus.port(), bus.port());
//! let a_cfg = IsoTpConfig::fd(CanId::standard(0x123)?, CanId::standard(0x321)?);
//! let b_cfg = IsoTpConfig::fd(CanId::standard(0x321)?, CanId::standard(0x123)?);
//! let message: Vec<u8> = (0..200).map(|i| i as u8).collect();
//! let receiver = std::thread::spawn(move || isotp::recv(&mut b, &b_cfg, Duration::from_secs(1)));
//! isotp::send(&mut a, &a_cfg, &message)?;
//! assert_eq!(receiver.join().unwrap()?, message);
//! # Ok::<(), motorwire_can::Error>(())
//! ```

use std::collections::VecDeque;
use std::fmt;
use std::time::{Duration, Instant};

use crate::{CanBus, CanId, Error, FD_LENGTHS, Frame, fd_len};

/// What went wrong in a transfer.
#[derive(Debug, Clone, PartialEq, Eq)]
#[non_exhaustive]
pub enum IsoTpError {
    /// The peer did not answer in time.
    Timeout {
        /// What was awaited: "flow control" or "consecutive frame".
        waiting_for: &'static str,
    },
    /// The receiver refused the message's length (flow status overflow).
    Overflow,
    /// A message longer than this side accepts.
    TooLong {
        /// Its length.
        len: usize,
        /// The most accepted.
        max: usize,
    },
    /// An empty message (ISO-TP cannot carry one).
    Empty,
    /// A consecutive frame out of sequence.
    WrongSequence {
        /// The sequence number expected.
        expected: u8,
        /// The one received.
        got: u8,
    },
    /// A frame that cannot be ISO-TP here (reserved PCI, impossible length).
    InvalidFrame {
        /// Why.
        reason: &'static str,
    },
    /// The receiver asked to wait more often than allowed.
    TooManyWaits,
    /// A send was started while another was in progress.
    Busy,
    /// The transfer's configuration is invalid.
    InvalidConfig {
        /// Why.
        reason: &'static str,
    },
}

impl fmt::Display for IsoTpError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Timeout { waiting_for } => write!(f, "timed out waiting for a {waiting_for}"),
            Self::Overflow => write!(f, "the receiver refused the message as too long"),
            Self::TooLong { len, max } => {
                write!(f, "a {len}-byte message is longer than the {max} accepted")
            }
            Self::Empty => write!(f, "an empty message cannot be sent"),
            Self::WrongSequence { expected, got } => write!(
                f,
                "consecutive frame {got} out of sequence (expected {expected})"
            ),
            Self::InvalidFrame { reason } => write!(f, "invalid frame: {reason}"),
            Self::TooManyWaits => write!(f, "the receiver asked to wait too often"),
            Self::Busy => write!(f, "a transfer is already in progress"),
            Self::InvalidConfig { reason } => write!(f, "invalid configuration: {reason}"),
        }
    }
}

impl std::error::Error for IsoTpError {}

/// One side of an ISO-TP link.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct IsoTpConfig {
    /// The identifier this side sends with.
    pub tx_id: CanId,
    /// The identifier of the peer's frames.
    pub rx_id: CanId,
    /// Send CAN-FD frames.
    pub fd: bool,
    /// The largest frame this side sends: 8 for classic CAN, an FD length
    /// from 8 to 64 for CAN-FD.
    pub tx_dl: usize,
    /// Pad every frame to `tx_dl` (classic) with this byte. CAN-FD frames are
    /// always padded to a valid FD length, with this byte or 0xCC as Linux does.
    pub padding: Option<u8>,
    /// Block size this side asks for as a receiver (0: no more flow control).
    pub block_size: u8,
    /// Separation time this side asks for as a receiver, encoded as ISO-TP's
    /// STmin byte (0x00-0x7F ms, 0xF1-0xF9 100-900 us).
    pub st_min: u8,
    /// How long to wait for the peer's next frame (N_Bs, N_Cr).
    pub timeout: Duration,
    /// The longest message accepted as a receiver.
    pub max_len: usize,
    /// How many flow-control WAITs a sender tolerates in a row.
    pub max_waits: u8,
}

impl IsoTpConfig {
    /// Classic CAN, 8-byte frames, no padding, no pacing, 1 s timeouts,
    /// messages up to 8192 bytes.
    pub fn classic(tx_id: CanId, rx_id: CanId) -> Self {
        Self {
            tx_id,
            rx_id,
            fd: false,
            tx_dl: 8,
            padding: None,
            block_size: 0,
            st_min: 0,
            timeout: Duration::from_secs(1),
            max_len: 8192,
            max_waits: 10,
        }
    }

    /// CAN-FD, 64-byte frames; otherwise as [`IsoTpConfig::classic`].
    pub fn fd(tx_id: CanId, rx_id: CanId) -> Self {
        Self {
            fd: true,
            tx_dl: 64,
            ..Self::classic(tx_id, rx_id)
        }
    }

    fn check(&self) -> Result<(), IsoTpError> {
        let ok = if self.fd {
            self.tx_dl >= 8 && FD_LENGTHS.contains(&self.tx_dl)
        } else {
            self.tx_dl == 8
        };
        if ok {
            Ok(())
        } else {
            Err(IsoTpError::InvalidConfig {
                reason: "tx_dl must be 8 for classic CAN and an FD length from 8 to 64 for CAN-FD",
            })
        }
    }

    /// Builds a frame of `payload`, padded as configured.
    fn frame(&self, payload: &[u8]) -> Result<Frame, Error> {
        let pad = self.padding.unwrap_or(0xCC);
        let mut buf = payload.to_vec();
        if self.fd {
            let len = fd_len(buf.len()).unwrap_or(64);
            buf.resize(len, pad);
            Frame::fd_exact(self.tx_id, &buf, true, false)
        } else {
            if let Some(p) = self.padding {
                buf.resize(8, p);
            }
            Frame::classic(self.tx_id, &buf)
        }
    }
}

/// The time an STmin byte asks for between consecutive frames.
///
/// ```
/// use std::time::Duration;
/// use motorwire_can::isotp::st_min_duration;
/// assert_eq!(st_min_duration(10), Duration::from_millis(10));
/// assert_eq!(st_min_duration(0xF3), Duration::from_micros(300));
/// assert_eq!(st_min_duration(0x80), Duration::from_millis(127)); // reserved: the longest
/// ```
pub fn st_min_duration(st_min: u8) -> Duration {
    match st_min {
        0x00..=0x7F => Duration::from_millis(u64::from(st_min)),
        0xF1..=0xF9 => Duration::from_micros(100 * u64::from(st_min - 0xF0)),
        _ => Duration::from_millis(127),
    }
}

#[derive(Debug)]
enum SendState {
    Idle,
    WaitFlowControl {
        deadline: Duration,
        waits: u8,
    },
    Sending {
        /// Frames left before the next flow control (None: unlimited).
        block_left: Option<u8>,
        st_min: Duration,
        next_at: Duration,
    },
}

/// The sending side of a transfer (sans-IO).
#[derive(Debug)]
pub struct Sender {
    config: IsoTpConfig,
    data: Vec<u8>,
    offset: usize,
    sn: u8,
    state: SendState,
    out: VecDeque<Frame>,
    done: Option<Result<(), IsoTpError>>,
}

impl Sender {
    /// A sender with `config`.
    ///
    /// # Errors
    /// [`IsoTpError::InvalidConfig`].
    pub fn new(config: IsoTpConfig) -> Result<Self, IsoTpError> {
        config.check()?;
        Ok(Self {
            config,
            data: Vec::new(),
            offset: 0,
            sn: 0,
            state: SendState::Idle,
            out: VecDeque::new(),
            done: None,
        })
    }

    /// Starts sending `data` at time `now`. A message that fits one frame is
    /// a single frame and is done once transmitted.
    ///
    /// # Errors
    /// [`IsoTpError::Busy`], [`IsoTpError::Empty`], [`IsoTpError::TooLong`]
    /// (over 4 GiB - 1).
    pub fn start(&mut self, now: Duration, data: &[u8]) -> Result<(), Error> {
        if !matches!(self.state, SendState::Idle) {
            return Err(IsoTpError::Busy.into());
        }
        if data.is_empty() {
            return Err(IsoTpError::Empty.into());
        }
        let len32 = u32::try_from(data.len()).map_err(|_| IsoTpError::TooLong {
            len: data.len(),
            max: u32::MAX as usize,
        })?;
        let dl = self.config.tx_dl;
        self.done = None;
        // Single frame: classic PCI up to 7 bytes, the FD escape above.
        if data.len() <= 7 {
            let mut p = vec![u8::try_from(data.len()).unwrap_or(0)];
            p.extend_from_slice(data);
            self.out.push_back(self.config.frame(&p)?);
            self.done = Some(Ok(()));
            return Ok(());
        }
        if dl > 8 && data.len() <= dl - 2 {
            let mut p = vec![0x00, u8::try_from(data.len()).unwrap_or(0)];
            p.extend_from_slice(data);
            self.out.push_back(self.config.frame(&p)?);
            self.done = Some(Ok(()));
            return Ok(());
        }
        // First frame.
        let mut p = if data.len() <= 0xFFF {
            let [_, _, hi, lo] = len32.to_be_bytes();
            vec![0x10 | (hi & 0x0F), lo]
        } else {
            let mut p = vec![0x10, 0x00];
            p.extend_from_slice(&len32.to_be_bytes());
            p
        };
        let take = dl - p.len();
        p.extend_from_slice(data.get(..take).unwrap_or(data));
        self.out.push_back(self.config.frame(&p)?);
        self.data = data.to_vec();
        self.offset = take;
        self.sn = 1;
        self.state = SendState::WaitFlowControl {
            deadline: now.saturating_add(self.config.timeout),
            waits: 0,
        };
        Ok(())
    }

    /// Takes a frame from the bus; only flow control from `rx_id` matters.
    pub fn handle_frame(&mut self, now: Duration, frame: &Frame) {
        if frame.id() != self.config.rx_id {
            return;
        }
        let SendState::WaitFlowControl { waits, .. } = self.state else {
            return;
        };
        let d = frame.data();
        let (Some(&pci), Some(&bs), Some(&st)) = (d.first(), d.get(1), d.get(2)) else {
            return;
        };
        if pci >> 4 != 3 {
            return;
        }
        match pci & 0x0F {
            0 => {
                self.state = SendState::Sending {
                    block_left: if bs == 0 { None } else { Some(bs) },
                    st_min: st_min_duration(st),
                    next_at: now,
                };
            }
            1 if waits < self.config.max_waits => {
                self.state = SendState::WaitFlowControl {
                    deadline: now.saturating_add(self.config.timeout),
                    waits: waits + 1,
                };
            }
            1 => self.fail(IsoTpError::TooManyWaits),
            2 => self.fail(IsoTpError::Overflow),
            _ => self.fail(IsoTpError::InvalidFrame {
                reason: "reserved flow status",
            }),
        }
    }

    fn fail(&mut self, e: IsoTpError) {
        self.state = SendState::Idle;
        self.data.clear();
        self.done = Some(Err(e));
    }

    /// The next frame to send at `now`, if one is due.
    pub fn poll_transmit(&mut self, now: Duration) -> Option<Frame> {
        if let Some(f) = self.out.pop_front() {
            return Some(f);
        }
        let SendState::Sending {
            block_left,
            st_min,
            next_at,
        } = self.state
        else {
            return None;
        };
        if now < next_at {
            return None;
        }
        let room = self.config.tx_dl - 1;
        let end = (self.offset + room).min(self.data.len());
        let mut p = vec![0x20 | self.sn];
        p.extend_from_slice(self.data.get(self.offset..end).unwrap_or(&[]));
        let frame = match self.config.frame(&p) {
            Ok(f) => f,
            Err(_) => {
                self.fail(IsoTpError::InvalidConfig {
                    reason: "frame length",
                });
                return None;
            }
        };
        self.offset = end;
        self.sn = (self.sn + 1) & 0x0F;
        if self.offset >= self.data.len() {
            self.state = SendState::Idle;
            self.data.clear();
            self.done = Some(Ok(()));
        } else {
            self.state = match block_left {
                Some(1) => SendState::WaitFlowControl {
                    deadline: now.saturating_add(self.config.timeout),
                    waits: 0,
                },
                left => SendState::Sending {
                    block_left: left.map(|n| n - 1),
                    st_min,
                    next_at: now.saturating_add(st_min),
                },
            };
        }
        Some(frame)
    }

    /// When [`Sender::poll_transmit`] or [`Sender::handle_timeout`] next has
    /// something to do.
    pub fn poll_timeout(&self) -> Option<Duration> {
        match self.state {
            SendState::Idle => None,
            SendState::WaitFlowControl { deadline, .. } => Some(deadline),
            SendState::Sending { next_at, .. } => Some(next_at),
        }
    }

    /// Fails the transfer if the flow control is overdue.
    pub fn handle_timeout(&mut self, now: Duration) {
        if let SendState::WaitFlowControl { deadline, .. } = self.state
            && now >= deadline
        {
            self.fail(IsoTpError::Timeout {
                waiting_for: "flow control",
            });
        }
    }

    /// The transfer's end, once: `Ok` when its last frame was handed out.
    pub fn poll_done(&mut self) -> Option<Result<(), IsoTpError>> {
        if self.out.is_empty() {
            self.done.take()
        } else {
            None
        }
    }
}

#[derive(Debug)]
struct Receiving {
    buf: Vec<u8>,
    len: usize,
    sn: u8,
    block_count: u8,
    deadline: Duration,
}

/// The receiving side of a transfer (sans-IO).
#[derive(Debug)]
pub struct Receiver {
    config: IsoTpConfig,
    rx: Option<Receiving>,
    out: VecDeque<Frame>,
}

impl Receiver {
    /// A receiver with `config`.
    ///
    /// # Errors
    /// [`IsoTpError::InvalidConfig`].
    pub fn new(config: IsoTpConfig) -> Result<Self, IsoTpError> {
        config.check()?;
        Ok(Self {
            config,
            rx: None,
            out: VecDeque::new(),
        })
    }

    fn flow_control(&mut self, status: u8) {
        let fc = [0x30 | status, self.config.block_size, self.config.st_min];
        if let Ok(f) = self.config.frame(&fc) {
            self.out.push_back(f);
        }
    }

    /// Takes a frame from the bus (frames from other ids are ignored) and
    /// returns a completed message or the error that ended one.
    pub fn handle_frame(
        &mut self,
        now: Duration,
        frame: &Frame,
    ) -> Option<Result<Vec<u8>, IsoTpError>> {
        if frame.id() != self.config.rx_id {
            return None;
        }
        let d = frame.data();
        let pci = *d.first()?;
        match pci >> 4 {
            0 => {
                // A single frame ends any transfer in progress (ISO 15765-2).
                self.rx = None;
                let (len, start) = if d.len() <= 8 {
                    (usize::from(pci & 0x0F), 1)
                } else if pci & 0x0F == 0 {
                    (usize::from(*d.get(1)?), 2)
                } else {
                    return Some(Err(IsoTpError::InvalidFrame {
                        reason: "single frame over 8 bytes without the escape length",
                    }));
                };
                if len == 0 {
                    return Some(Err(IsoTpError::InvalidFrame {
                        reason: "single frame of length 0",
                    }));
                }
                match d.get(start..start + len) {
                    Some(p) => Some(Ok(p.to_vec())),
                    None => Some(Err(IsoTpError::InvalidFrame {
                        reason: "single frame shorter than its length",
                    })),
                }
            }
            1 => {
                self.rx = None;
                let (len, start) = match (pci & 0x0F, d.get(1)) {
                    (0, Some(0)) => {
                        let b: [u8; 4] = d.get(2..6)?.try_into().ok()?;
                        (u32::from_be_bytes(b) as usize, 6)
                    }
                    (hi, Some(&lo)) => ((usize::from(hi) << 8) | usize::from(lo), 2),
                    (_, None) => {
                        return Some(Err(IsoTpError::InvalidFrame {
                            reason: "first frame without its length",
                        }));
                    }
                };
                if len > self.config.max_len {
                    self.flow_control(2);
                    return Some(Err(IsoTpError::TooLong {
                        len,
                        max: self.config.max_len,
                    }));
                }
                let first = d.get(start..).unwrap_or(&[]);
                if first.len() >= len || d.len() < 8 {
                    return Some(Err(IsoTpError::InvalidFrame {
                        reason: "first frame of a message that fits one frame",
                    }));
                }
                self.rx = Some(Receiving {
                    buf: first.to_vec(),
                    len,
                    sn: 1,
                    block_count: 0,
                    deadline: now.saturating_add(self.config.timeout),
                });
                self.flow_control(0);
                None
            }
            2 => {
                let rx = self.rx.as_mut()?;
                let sn = pci & 0x0F;
                if sn != rx.sn {
                    let expected = rx.sn;
                    self.rx = None;
                    return Some(Err(IsoTpError::WrongSequence { expected, got: sn }));
                }
                let want = rx.len - rx.buf.len();
                let chunk = d.get(1..).unwrap_or(&[]);
                rx.buf
                    .extend_from_slice(chunk.get(..want.min(chunk.len())).unwrap_or(chunk));
                rx.sn = (rx.sn + 1) & 0x0F;
                rx.deadline = now.saturating_add(self.config.timeout);
                if rx.buf.len() >= rx.len {
                    return self.rx.take().map(|r| Ok(r.buf));
                }
                rx.block_count = rx.block_count.wrapping_add(1);
                if self.config.block_size != 0 && rx.block_count == self.config.block_size {
                    rx.block_count = 0;
                    self.flow_control(0);
                }
                None
            }
            // Flow control for a sender on the same id pair: not ours.
            3 => None,
            _ => Some(Err(IsoTpError::InvalidFrame {
                reason: "reserved protocol control information",
            })),
        }
    }

    /// The next flow-control frame to send.
    pub fn poll_transmit(&mut self) -> Option<Frame> {
        self.out.pop_front()
    }

    /// When the transfer in progress times out.
    pub fn poll_timeout(&self) -> Option<Duration> {
        self.rx.as_ref().map(|r| r.deadline)
    }

    /// Ends an overdue transfer with its error.
    pub fn handle_timeout(&mut self, now: Duration) -> Option<IsoTpError> {
        if self.rx.as_ref().is_some_and(|r| now >= r.deadline) {
            self.rx = None;
            return Some(IsoTpError::Timeout {
                waiting_for: "consecutive frame",
            });
        }
        None
    }
}

/// Sends `data` on `bus` as one ISO-TP message, waiting for the receiver's
/// flow control as needed.
///
/// # Errors
/// [`Error::IsoTp`] (timeout, overflow...) or the bus's errors.
pub fn send(bus: &mut impl CanBus, config: &IsoTpConfig, data: &[u8]) -> Result<(), Error> {
    let start = Instant::now();
    let now = || start.elapsed();
    let mut tx = Sender::new(*config)?;
    tx.start(now(), data)?;
    loop {
        while let Some(f) = tx.poll_transmit(now()) {
            bus.send(&f)?;
        }
        if let Some(done) = tx.poll_done() {
            return done.map_err(Error::from);
        }
        match tx.poll_timeout() {
            Some(at) if matches!(tx.state, SendState::Sending { .. }) => {
                std::thread::sleep(at.saturating_sub(now()));
            }
            Some(at) => match bus.recv(at.saturating_sub(now())) {
                Ok(r) => tx.handle_frame(now(), &r.frame),
                Err(Error::Timeout(_)) => tx.handle_timeout(at.max(now())),
                Err(e) => return Err(e),
            },
            None => return Ok(()),
        }
    }
}

/// Receives one ISO-TP message from `bus`, answering with flow control.
/// Waits up to `timeout` for it to begin; frames of other ids are skipped.
///
/// # Errors
/// [`Error::Timeout`] when nothing began, [`Error::IsoTp`] when a transfer
/// failed, or the bus's errors.
pub fn recv(
    bus: &mut impl CanBus,
    config: &IsoTpConfig,
    timeout: Duration,
) -> Result<Vec<u8>, Error> {
    let start = Instant::now();
    let now = || start.elapsed();
    let mut rx = Receiver::new(*config)?;
    loop {
        let deadline = rx.poll_timeout().unwrap_or(timeout);
        let wait = deadline.saturating_sub(now());
        match bus.recv(wait) {
            Ok(r) => {
                let done = rx.handle_frame(now(), &r.frame);
                while let Some(f) = rx.poll_transmit() {
                    bus.send(&f)?;
                }
                match done {
                    Some(Ok(m)) => return Ok(m),
                    Some(Err(e)) => return Err(e.into()),
                    None => {}
                }
            }
            Err(Error::Timeout(_)) => {
                if let Some(e) = rx.handle_timeout(deadline.max(now())) {
                    return Err(e.into());
                }
                if rx.poll_timeout().is_none() {
                    return Err(Error::Timeout(timeout));
                }
            }
            Err(e) => return Err(e),
        }
    }
}
