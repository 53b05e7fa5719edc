//! An in-memory CAN bus: any number of ports, deterministic, with seeded
//! fault injection and a simulated (or real) clock.

use std::collections::BTreeMap;
use std::sync::{Arc, Condvar, Mutex, MutexGuard, PoisonError};
use std::time::{Duration, Instant};

use crate::bus::FrameWaker;
use crate::{CanBus, Error, Frame, Received};

/// Fault rates, each the probability (0 to 1) that it happens to one frame
/// on its way to one receiver.
///
/// ```
/// use motorwire_can::Faults;
/// let f = Faults { drop: 0.1, duplicate: 0.1, corrupt: 0.05, ..Faults::default() };
/// assert!(f.validate().is_ok());
/// assert!(Faults { drop: 1.5, ..Faults::default() }.validate().is_err());
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Faults {
    /// The frame does not arrive.
    pub drop: f64,
    /// The frame arrives twice.
    pub duplicate: f64,
    /// One bit of the frame's data is flipped (as if a CRC had missed it).
    pub corrupt: f64,
    /// The frame arrives up to `max_delay` late.
    pub delay: f64,
    /// The frame is held back until after the next frame to the same
    /// receiver (or `max_delay`, whichever comes first).
    pub reorder: f64,
    /// The longest extra delay `delay` and `reorder` add.
    pub max_delay: Duration,
}

impl Default for Faults {
    /// No faults; `max_delay` 5 ms.
    fn default() -> Self {
        Self {
            drop: 0.0,
            duplicate: 0.0,
            corrupt: 0.0,
            delay: 0.0,
            reorder: 0.0,
            max_delay: Duration::from_millis(5),
        }
    }
}

impl Faults {
    /// Checks every rate is within 0..=1 (NaN is not).
    ///
    /// # Errors
    /// [`Error::InvalidFaultRate`] naming the first rate that is not.
    pub fn validate(&self) -> Result<(), Error> {
        for (name, value) in [
            ("drop", self.drop),
            ("duplicate", self.duplicate),
            ("corrupt", self.corrupt),
            ("delay", self.delay),
            ("reorder", self.reorder),
        ] {
            if !(0.0..=1.0).contains(&value) {
                return Err(Error::InvalidFaultRate {
                    name,
                    value: value.to_string(),
                });
            }
        }
        Ok(())
    }
}

/// What the in-memory bus did to the frames sent on it.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct FaultStats {
    /// Frames sent by ports.
    pub sent: u64,
    /// Copies put in a receiver's queue.
    pub delivered: u64,
    /// Copies dropped.
    pub dropped: u64,
    /// Extra copies made.
    pub duplicated: u64,
    /// Copies with a flipped bit.
    pub corrupted: u64,
    /// Copies delayed.
    pub delayed: u64,
    /// Copies held back behind a later frame.
    pub reordered: u64,
}

/// Which clock the bus keeps.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Clock {
    /// Time moves only when the bus is told to ([`SimBus::advance_to`]) or
    /// when a port waits in [`CanBus::recv`]: a wait moves the clock to the
    /// next frame due for that port, or by the whole timeout. Runs are exact
    /// and as fast as the machine.
    #[default]
    Simulated,
    /// Wall-clock time since the bus was made: waits really wait.
    Real,
}

/// How to build a [`SimBus`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimConfig {
    /// Seed of the fault generator: the same seed and traffic give the same faults.
    pub seed: u64,
    /// Fault rates.
    pub faults: Faults,
    /// Time from send to arrival for every frame.
    pub latency: Duration,
    /// The clock.
    pub clock: Clock,
}

impl Default for SimConfig {
    /// Seed 0, no faults, no latency, simulated time.
    fn default() -> Self {
        Self {
            seed: 0,
            faults: Faults::default(),
            latency: Duration::ZERO,
            clock: Clock::Simulated,
        }
    }
}

/// SplitMix64: small, fast, and the same everywhere.
#[derive(Debug)]
struct Rng(u64);

impl Rng {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    fn unit(&mut self) -> f64 {
        // 53 random bits; the cast is exact.
        #[allow(clippy::cast_precision_loss)]
        let x = (self.next_u64() >> 11) as f64;
        x / (1u64 << 53) as f64
    }

    fn chance(&mut self, p: f64) -> bool {
        p > 0.0 && self.unit() < p
    }

    fn below(&mut self, n: u64) -> u64 {
        if n == 0 { 0 } else { self.next_u64() % n }
    }
}

/// What wakes a port a frame was queued for: its waiting thread's
/// condition variable, and its waker.
type Arrival = (Arc<Condvar>, Option<FrameWaker>);

#[derive(Default)]
struct PortState {
    /// Frames sent on the bus are queued for it (false for a dropped port
    /// and a send-only port).
    open: bool,
    queue: BTreeMap<(Duration, u64), Frame>,
    held: Option<(Duration, Frame)>,
    /// The receiving port a sending half belongs to: its frames are not
    /// queued there (a node does not hear itself), [`SimPort::sending_half`].
    twin: Option<usize>,
    /// Wakes the thread waiting in this port's `recv`, and only it: a frame
    /// for one node does not rouse every node's thread.
    arrived: Arc<Condvar>,
    /// Told when a frame is queued for this port ([`CanBus::set_waker`]).
    waker: Option<FrameWaker>,
    /// Threads waiting in this port's `recv` (none on a bus in simulated
    /// time, which never waits): only a port with one is notified.
    waiting: u32,
}

impl std::fmt::Debug for PortState {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PortState")
            .field("open", &self.open)
            .field("queue", &self.queue)
            .field("held", &self.held)
            .field("twin", &self.twin)
            .field("waker", &self.waker.is_some())
            .field("waiting", &self.waiting)
            .finish_non_exhaustive()
    }
}

#[derive(Debug)]
struct State {
    config: SimConfig,
    start: Instant,
    now: Duration,
    rng: Rng,
    seq: u64,
    ports: Vec<PortState>,
    /// How many ports hold a frame back ([`PortState::held`]): with none,
    /// receiving does not look at every port (a bus of many ports would
    /// otherwise pay for all of them on every frame received).
    held: usize,
    stats: FaultStats,
    /// The ports a frame was queued for since they were last woken.
    touched: Vec<usize>,
    /// The places of ports dropped, for the next ports made: a bus whose
    /// ports come and go does not walk the dead ones on every frame.
    free: Vec<usize>,
}

impl State {
    fn now(&self) -> Duration {
        match self.config.clock {
            Clock::Simulated => self.now,
            Clock::Real => self.start.elapsed(),
        }
    }

    /// Puts `port` in a place of its own: a dropped port's, or a new one.
    fn add(&mut self, port: PortState) -> usize {
        match self.free.pop() {
            Some(i) if i < self.ports.len() => {
                if let Some(slot) = self.ports.get_mut(i) {
                    *slot = port;
                }
                i
            }
            _ => {
                self.ports.push(port);
                self.ports.len() - 1
            }
        }
    }

    fn push(&mut self, port: usize, at: Duration, frame: Frame) {
        self.seq += 1;
        let seq = self.seq;
        if let Some(p) = self.ports.get_mut(port) {
            p.queue.insert((at, seq), frame);
            self.stats.delivered += 1;
            if self.touched.last() != Some(&port) {
                self.touched.push(port);
            }
        }
    }

    /// What wakes the ports a frame was queued for (each port's own
    /// waiting thread, none other, and its waker), to be told once the
    /// lock is let go: a thread woken while the lock is still held would
    /// wake only to wait for it.
    fn take_touched(&mut self, wake: &mut Vec<Arrival>) {
        for port in self.touched.drain(..) {
            if let Some(p) = self.ports.get(port)
                && (p.waiting > 0 || p.waker.is_some())
            {
                wake.push((Arc::clone(&p.arrived), p.waker.clone()));
            }
        }
    }

    /// Moves held-back frames whose time has come into their queues.
    fn release_held(&mut self, now: Duration) {
        if self.held == 0 {
            return;
        }
        let due: Vec<(usize, Duration, Frame)> = self
            .ports
            .iter_mut()
            .enumerate()
            .filter_map(|(i, p)| match p.held {
                Some((at, _)) if at <= now => p.held.take().map(|(at, f)| (i, at, f)),
                _ => None,
            })
            .collect();
        self.held = self.held.saturating_sub(due.len());
        for (i, at, f) in due {
            self.push(i, at, f);
        }
    }

    fn send(&mut self, from: usize, frame: &Frame) {
        let now = self.now();
        self.release_held(now);
        self.stats.sent += 1;
        let faults = self.config.faults;
        let base = now.saturating_add(self.config.latency);
        let twin = self.ports.get(from).and_then(|p| p.twin);
        for to in 0..self.ports.len() {
            if to == from || Some(to) == twin || !self.ports.get(to).is_some_and(|p| p.open) {
                continue;
            }
            if self.rng.chance(faults.drop) {
                self.stats.dropped += 1;
                continue;
            }
            let copies = if self.rng.chance(faults.duplicate) {
                self.stats.duplicated += 1;
                2
            } else {
                1
            };
            for _ in 0..copies {
                let mut f = *frame;
                if self.rng.chance(faults.corrupt) && !f.is_empty() {
                    let bits = (f.len() * 8) as u64;
                    let bit = usize::try_from(self.rng.below(bits)).unwrap_or(0);
                    if let Some(b) = f.data_mut().get_mut(bit / 8) {
                        *b ^= 1 << (bit % 8);
                        self.stats.corrupted += 1;
                    }
                }
                let mut at = base;
                if self.rng.chance(faults.delay) {
                    let max = u64::try_from(faults.max_delay.as_nanos()).unwrap_or(u64::MAX);
                    at = at.saturating_add(Duration::from_nanos(1 + self.rng.below(max)));
                    self.stats.delayed += 1;
                }
                let hold = self.rng.chance(faults.reorder)
                    && self.ports.get(to).is_some_and(|p| p.held.is_none());
                if hold {
                    self.stats.reordered += 1;
                    if let Some(p) = self.ports.get_mut(to) {
                        p.held = Some((at.saturating_add(faults.max_delay), f));
                        self.held += 1;
                    }
                    continue;
                }
                self.push(to, at, f);
                // A held frame goes right after the frame that overtook it.
                if let Some((_, held)) = self.ports.get_mut(to).and_then(|p| p.held.take()) {
                    self.held = self.held.saturating_sub(1);
                    self.push(to, at, held);
                }
            }
        }
    }

    /// The earliest frame queued for `port`, and when it is due.
    fn next_for(&self, port: usize) -> Option<Duration> {
        let p = self.ports.get(port)?;
        let queued = p.queue.keys().next().map(|(at, _)| *at);
        let held = p.held.as_ref().map(|(at, _)| *at);
        match (queued, held) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        }
    }

    fn pop_due(&mut self, port: usize) -> Option<Received> {
        let now = self.now();
        self.release_held(now);
        let p = self.ports.get_mut(port)?;
        let (&(at, seq), _) = p.queue.iter().next()?;
        if at > now {
            return None;
        }
        let frame = p.queue.remove(&(at, seq))?;
        Some(Received {
            frame,
            timestamp: at,
        })
    }
}

#[derive(Debug)]
struct Shared {
    state: Mutex<State>,
    #[cfg(feature = "tokio")]
    notify: tokio::sync::Notify,
}

/// An in-memory CAN bus. Clone it freely: clones are the same bus. Every
/// frame a port sends reaches every other open port (never the sender), as
/// on a real bus; receivers filter by content.
///
/// ```
/// use std::time::Duration;
/// use motorwire_can::{CanBus, CanId, Faults, Frame, SimBus, SimConfig};
///
/// let bus = SimBus::new(SimConfig {
///     seed: 7,
///     faults: Faults { duplicate: 1.0, ..Faults::default() },
///     latency: Duration::from_micros(200),
///     ..SimConfig::default()
/// })?;
/// let (mut a, mut b) = (bus.port(), bus.port());
/// a.send(&Frame::classic(CanId::standard(1)?, &[0xAA])?)?;
/// // Waiting moves simulated time to the arrival.
/// let first = b.recv(Duration::from_secs(1))?;
/// assert_eq!(first.timestamp, Duration::from_micros(200));
/// assert_eq!(b.recv(Duration::ZERO)?.frame, first.frame); // the duplicate
/// assert!(b.recv(Duration::ZERO).is_err());
/// assert_eq!(bus.stats().duplicated, 1);
/// # Ok::<(), motorwire_can::Error>(())
/// ```
#[derive(Debug, Clone)]
pub struct SimBus {
    shared: Arc<Shared>,
}

impl Default for SimBus {
    fn default() -> Self {
        Self::from_valid(SimConfig::default())
    }
}

impl SimBus {
    /// A bus with `config`.
    ///
    /// # Errors
    /// [`Error::InvalidFaultRate`].
    pub fn new(config: SimConfig) -> Result<Self, Error> {
        config.faults.validate()?;
        Ok(Self::from_valid(config))
    }

    fn from_valid(config: SimConfig) -> Self {
        Self {
            shared: Arc::new(Shared {
                state: Mutex::new(State {
                    config,
                    start: Instant::now(),
                    now: Duration::ZERO,
                    rng: Rng(config.seed),
                    seq: 0,
                    ports: Vec::new(),
                    held: 0,
                    stats: FaultStats::default(),
                    touched: Vec::new(),
                    free: Vec::new(),
                }),
                #[cfg(feature = "tokio")]
                notify: tokio::sync::Notify::new(),
            }),
        }
    }

    fn lock(&self) -> MutexGuard<'_, State> {
        // No code path panics while holding the lock; a poisoned lock still
        // holds a consistent state.
        self.shared
            .state
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
    }

    /// Wakes every port's waiting thread (simulated time moved).
    fn wake_all(&self) {
        let all: Vec<Arc<Condvar>> = {
            let s = self.lock();
            s.ports
                .iter()
                .filter(|p| p.waiting > 0)
                .map(|p| Arc::clone(&p.arrived))
                .collect()
        };
        for arrived in all {
            arrived.notify_all();
        }
        #[cfg(feature = "tokio")]
        self.shared.notify.notify_waiters();
    }

    /// A new port (a node's connection to the bus). It receives every frame
    /// sent after it was made, until it is dropped.
    pub fn port(&self) -> SimPort {
        let index = self.lock().add(PortState {
            open: true,
            ..PortState::default()
        });
        SimPort {
            bus: self.clone(),
            index,
        }
    }

    /// A new port that sends and never receives: no frame is ever queued
    /// for it, so a node that only transmits (a bridge's sending half) costs
    /// no memory however long the bus runs. Its `recv` times out (the async
    /// `recv` never returns).
    ///
    /// ```
    /// use std::time::Duration;
    /// use motorwire_can::{CanBus, CanId, Frame, SimBus};
    ///
    /// let bus = SimBus::default();
    /// let (mut tx, mut rx, mut joint) = (bus.send_only_port(), bus.port(), bus.port());
    /// tx.send(&Frame::fd(CanId::standard(0x10)?, &[1])?)?;
    /// assert_eq!(joint.recv(Duration::ZERO)?.frame.data(), &[1]);
    /// joint.send(&Frame::fd(CanId::standard(0x20)?, &[2])?)?;
    /// // A receiving port hears both, as on a real bus; the send-only one neither.
    /// assert_eq!(rx.recv(Duration::ZERO)?.frame.data(), &[1]);
    /// assert_eq!(rx.recv(Duration::ZERO)?.frame.data(), &[2]);
    /// assert_eq!(tx.queued(), 0);
    /// assert!(tx.recv(Duration::ZERO).is_err());
    /// # Ok::<(), motorwire_can::Error>(())
    /// ```
    pub fn send_only_port(&self) -> SimPort {
        let index = self.lock().add(PortState::default());
        SimPort {
            bus: self.clone(),
            index,
        }
    }

    /// The bus's time: simulated, or wall-clock since it was made.
    pub fn now(&self) -> Duration {
        self.lock().now()
    }

    /// Moves simulated time forward to `t` (never back). Has no effect on a
    /// [`Clock::Real`] bus.
    pub fn advance_to(&self, t: Duration) {
        {
            let mut s = self.lock();
            if s.config.clock == Clock::Simulated && t > s.now {
                s.now = t;
            }
        }
        self.wake_all();
    }

    /// When the next frame in any port's queue is due.
    pub fn next_delivery(&self) -> Option<Duration> {
        let s = self.lock();
        (0..s.ports.len()).filter_map(|i| s.next_for(i)).min()
    }

    /// What the bus has done to the frames so far.
    pub fn stats(&self) -> FaultStats {
        self.lock().stats
    }

    /// The places the bus keeps for its ports: as many as it had open at
    /// once at most (a port made after one was dropped takes its place).
    pub fn ports(&self) -> usize {
        self.lock().ports.len()
    }
}

/// One node's connection to a [`SimBus`].
#[derive(Debug)]
pub struct SimPort {
    bus: SimBus,
    index: usize,
}

impl SimPort {
    /// The bus this port is on.
    pub fn bus(&self) -> &SimBus {
        &self.bus
    }

    /// A send-only port that is this port's sending half: what it sends
    /// reaches every other port but this one, as one node's connection
    /// split in two (a thread that sends and one that receives) hears
    /// only the others, the way a SocketCAN socket and its clone do.
    ///
    /// ```
    /// use std::time::Duration;
    /// use motorwire_can::{CanBus, CanId, Frame, SimBus};
    ///
    /// let bus = SimBus::default();
    /// let (mut rx, mut joint) = (bus.port(), bus.port());
    /// let mut tx = rx.sending_half();
    /// tx.send(&Frame::fd(CanId::standard(0x10)?, &[1])?)?;
    /// assert_eq!(joint.recv(Duration::ZERO)?.frame.data(), &[1]);
    /// // Its own frame is not heard back; the joint's answer is.
    /// assert!(rx.recv(Duration::ZERO).is_err());
    /// joint.send(&Frame::fd(CanId::standard(0x20)?, &[2])?)?;
    /// assert_eq!(rx.recv(Duration::ZERO)?.frame.data(), &[2]);
    /// # Ok::<(), motorwire_can::Error>(())
    /// ```
    pub fn sending_half(&self) -> SimPort {
        let index = self.bus.lock().add(PortState {
            twin: Some(self.index),
            ..PortState::default()
        });
        SimPort {
            bus: self.bus.clone(),
            index,
        }
    }

    /// The next frame already due, without waiting or moving the clock.
    pub fn try_recv(&mut self) -> Option<Received> {
        self.bus.lock().pop_due(self.index)
    }

    /// When the next frame for this port is due.
    pub fn next_due(&self) -> Option<Duration> {
        self.bus.lock().next_for(self.index)
    }

    /// How many frames are waiting for this port (due or not, held back
    /// ones included): what it costs in memory until it receives them.
    pub fn queued(&self) -> usize {
        let s = self.bus.lock();
        s.ports
            .get(self.index)
            .map_or(0, |p| p.queue.len() + usize::from(p.held.is_some()))
    }
}

impl Drop for SimPort {
    fn drop(&mut self) {
        let mut s = self.bus.lock();
        if let Some(p) = s.ports.get_mut(self.index) {
            let held = usize::from(p.held.is_some());
            *p = PortState::default();
            s.held = s.held.saturating_sub(held);
            // Its place is taken by the next port made; a sending half
            // whose twin it was now reaches that port as any other.
            for other in &mut s.ports {
                if other.twin == Some(self.index) {
                    other.twin = None;
                }
            }
            s.free.push(self.index);
        }
    }
}

impl CanBus for SimPort {
    fn send(&mut self, frame: &Frame) -> Result<(), Error> {
        let mut wake = Vec::new();
        {
            let mut s = self.bus.lock();
            s.send(self.index, frame);
            s.take_touched(&mut wake);
        }
        for (arrived, waker) in wake {
            arrived.notify_all();
            if let Some(w) = waker {
                w();
            }
        }
        #[cfg(feature = "tokio")]
        self.bus.shared.notify.notify_waiters();
        Ok(())
    }

    fn recv(&mut self, timeout: Duration) -> Result<Received, Error> {
        let mut s = self.bus.lock();
        let deadline = s.now().saturating_add(timeout);
        loop {
            if let Some(r) = s.pop_due(self.index) {
                return Ok(r);
            }
            match s.config.clock {
                Clock::Simulated => {
                    return match s.next_for(self.index) {
                        Some(at) if at <= deadline => {
                            s.now = s.now.max(at);
                            continue;
                        }
                        _ => {
                            s.now = s.now.max(deadline);
                            Err(Error::Timeout(timeout))
                        }
                    };
                }
                Clock::Real => {
                    let now = s.now();
                    if now >= deadline {
                        return Err(Error::Timeout(timeout));
                    }
                    let until = s
                        .next_for(self.index)
                        .map_or(deadline, |at| at.min(deadline));
                    let wait = until.saturating_sub(now).max(Duration::from_micros(1));
                    let Some(p) = s.ports.get_mut(self.index) else {
                        return Err(Error::Closed);
                    };
                    p.waiting += 1;
                    let arrived = Arc::clone(&p.arrived);
                    s = arrived
                        .wait_timeout(s, wait)
                        .unwrap_or_else(PoisonError::into_inner)
                        .0;
                    if let Some(p) = s.ports.get_mut(self.index) {
                        p.waiting = p.waiting.saturating_sub(1);
                    }
                }
            }
        }
    }

    /// Taken on a bus whose every frame is due as it is sent: no
    /// latency, delay or reordering (a frame held for later would wake
    /// its port too early, and nothing would when it falls due).
    fn set_waker(&mut self, waker: FrameWaker) -> bool {
        let mut s = self.bus.lock();
        let c = s.config;
        if !c.latency.is_zero() || c.faults.delay > 0.0 || c.faults.reorder > 0.0 {
            return false;
        }
        let Some(p) = s.ports.get_mut(self.index) else {
            return false;
        };
        p.waker = Some(waker);
        true
    }
}

#[cfg(feature = "tokio")]
#[cfg_attr(docsrs, doc(cfg(feature = "tokio")))]
impl crate::AsyncCanBus for SimPort {
    async fn send(&mut self, frame: &Frame) -> Result<(), Error> {
        CanBus::send(self, frame)
    }

    async fn recv(&mut self) -> Result<Received, Error> {
        loop {
            let notified = self.bus.shared.notify.notified();
            tokio::pin!(notified);
            notified.as_mut().enable();
            let wait = {
                let mut s = self.bus.lock();
                if let Some(r) = s.pop_due(self.index) {
                    return Ok(r);
                }
                match (s.config.clock, s.next_for(self.index)) {
                    (Clock::Real, Some(at)) => Some(at.saturating_sub(s.now())),
                    _ => None,
                }
            };
            match wait {
                Some(d) => {
                    tokio::select! {
                        () = &mut notified => {}
                        () = tokio::time::sleep(d) => {}
                    }
                }
                None => notified.await,
            }
        }
    }
}
