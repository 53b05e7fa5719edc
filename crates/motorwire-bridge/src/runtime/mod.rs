//! Running a [`Bridge`] in real time on a blocking bus.

use std::io::{self, BufRead};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, Receiver, Sender};
use std::thread;
use std::time::Instant;

use motorwire_can::{CanBus, Frame};

use std::collections::BTreeMap;
use std::sync::{Condvar, Mutex, OnceLock, PoisonError};

use crate::classify::asks_for_stop;
use crate::clocks::clocks_together;
use crate::engine::Bridge;
use crate::error::BridgeError;
use crate::output::{Origin, Output};
use crate::tap::{Direction, Mark, Tap};

mod bus_errors;
mod orion;
mod read;
mod run;
mod serial;

pub use serial::MAX_SERIAL_QUEUED;

pub use read::*;

/// The longest input line accepted by default (bytes, without the
/// newline): 1 MiB, the size `motorwire validate` takes by default too
/// (both `--max-size`). [`Runner::max_line`] sets another.
pub const DEFAULT_MAX_LINE: usize = 1 << 20;

/// Bytes of one origin's lines handed to a [`Runner`] and not yet taken,
/// at most (beyond its first line waiting): with lines up to
/// [`DEFAULT_MAX_LINE`] and more, a client's queue is bounded by its bytes
/// as well as by [`MAX_QUEUED_PER_ORIGIN`] lines.
pub const MAX_QUEUED_BYTES_PER_ORIGIN: usize = 8 << 20;

/// How much of a line too long to take is skipped looking for its end:
/// beyond this the input is given up ([`read_line`] fails), so an endless
/// input (`/dev/zero`) ends instead of being read forever.
pub const MAX_SKIP: u64 = 16 * 1024 * 1024;

/// Lines of one origin handed to a [`Runner`] and not yet taken by it (and
/// as many stops): [`InputSender::line`] waits beyond this, so a client
/// that floods is slowed to the bridge's pace (its socket fills, and its
/// sender waits) instead of growing the bridge's memory.
pub const MAX_QUEUED_PER_ORIGIN: usize = 256;

/// Lines from the Orion controller waiting for the bridge, at most; more
/// are dropped (and counted) until it catches up. The controller answers
/// one line per line it is sent, every 100 ms when idle.
pub const MAX_ORION_QUEUED: usize = 64;

/// Lines from the Orion controller taken in one second beyond its answers,
/// at most: every line the bridge writes earns one line back that this
/// budget does not count (the controller answers each line it is sent), so
/// a fast exchange (a stop and a release every few milliseconds) is never
/// cut, while unsolicited lines beyond the budget are dropped and counted,
/// and a bad-line event says how many. A controller that floods costs its
/// own motors (their answers may be among those dropped), never the
/// bridge's memory or another device's latency.
pub const MAX_ORION_LINES_PER_S: u32 = 500;

/// Per origin, lines handed over and not yet taken (normal, urgent): how
/// many, and their bytes.
#[derive(Debug, Default)]
struct Budget {
    queued: Mutex<BTreeMap<(Origin, bool), (usize, usize)>>,
    freed: Condvar,
}

impl Budget {
    /// Waits until `origin` may hand over one more line of `bytes`: fewer
    /// than [`MAX_QUEUED_PER_ORIGIN`] waiting, and their bytes with it
    /// within [`MAX_QUEUED_BYTES_PER_ORIGIN`] (a line alone always fits).
    fn take(&self, origin: Origin, urgent: bool, bytes: usize) {
        let mut q = self.queued.lock().unwrap_or_else(PoisonError::into_inner);
        while q.get(&(origin, urgent)).is_some_and(|&(n, b)| {
            n >= MAX_QUEUED_PER_ORIGIN || b.saturating_add(bytes) > MAX_QUEUED_BYTES_PER_ORIGIN
        }) {
            q = self.freed.wait(q).unwrap_or_else(PoisonError::into_inner);
        }
        let e = q.entry((origin, urgent)).or_insert((0, 0));
        e.0 += 1;
        e.1 = e.1.saturating_add(bytes);
    }

    /// The runner took one of `origin`'s lines, of `bytes`.
    fn give(&self, origin: Origin, urgent: bool, bytes: usize) {
        let mut q = self.queued.lock().unwrap_or_else(PoisonError::into_inner);
        if let Some(e) = q.get_mut(&(origin, urgent)) {
            e.0 = e.0.saturating_sub(1);
            e.1 = e.1.saturating_sub(bytes);
            if e.0 == 0 {
                q.remove(&(origin, urgent));
            }
        }
        drop(q);
        self.freed.notify_all();
    }
}

/// The bytes a queued message holds against its origin's budget.
fn queued_bytes(msg: &Msg) -> usize {
    match msg {
        Msg::Line { text, .. } => text.len(),
        _ => 0,
    }
}

#[derive(Debug)]
enum Msg {
    Line {
        origin: Origin,
        number: u64,
        text: String,
        at: Instant,
        /// What the line is, read on its reader's thread (the bridge's
        /// own validator): the engine's thread does not parse it again, so
        /// a heavy line costs its own client's thread, never another
        /// client's stop. `None` before the runner knows its bridge.
        input: Option<Box<crate::classify::Line>>,
    },
    Refused {
        origin: Origin,
        number: u64,
        reason: String,
        /// It names `emergency_stop`: taken as a stop.
        stop: bool,
        /// Its first bytes (at most [`UNREADABLE_HEAD`]) and its length,
        /// for the recording.
        bytes: Option<(Vec<u8>, u64)>,
    },
    /// A stop is waiting on the urgent channel.
    Wake,
    /// An origin is gone: its pending lines are cancelled.
    Dropped {
        origin: Origin,
        reason: String,
    },
    /// A client connected: greet it.
    Greet {
        origin: Origin,
    },
    Finish,
    Interrupt,
    Frame {
        frame: Frame,
        at: Instant,
    },
    BusError(String),
    /// A line from the Orion controller.
    OrionLine {
        text: String,
        at: Instant,
    },
    /// A line from the Orion controller that could not be read.
    OrionUnreadable(String),
    /// The Orion controller's stream ended or failed.
    OrionLost(String),
    /// Bytes from a serial servo port.
    Serial {
        port: u8,
        bytes: Vec<u8>,
        at: Instant,
    },
}

/// The byte stream to the Orion arm controller (WIRE-FACTS §4.1): one
/// JSON object per line each way. The controller's lines are read from
/// `reader` on a thread of their own; the bridge's are written to `writer`
/// on another, so a controller that stops reading never holds up the
/// engine.
pub struct OrionPort {
    /// Where the controller's lines come from.
    pub reader: Box<dyn io::Read + Send>,
    /// Where the bridge's lines go.
    pub writer: Box<dyn io::Write + Send>,
}

/// The byte stream of one serial servo port (the bus map's
/// [`motorwire_translate::BusMap::servo_ports`], in their order): the
/// servos' status packets are read from `reader` on a thread of their own;
/// the bridge's instruction packets are written to `writer` on another.
/// A serial port opened at the map's baud rate, or
/// `crate::sim::servo_links`'s simulated servos.
pub struct ServoLink {
    /// Where the servos' bytes come from.
    pub reader: Box<dyn io::Read + Send>,
    /// Where the bridge's packets go.
    pub writer: Box<dyn io::Write + Send>,
    /// How to open the port again when it fails (a USB adapter unplugged
    /// and plugged back): tried every half second until it opens; `None`:
    /// a failed port stays failed (its servos go offline).
    pub reopen: Option<Reopen>,
}

/// Opens a serial servo port again: its reader and its writer.
pub type Reopen =
    Box<dyn FnMut() -> io::Result<(Box<dyn io::Read + Send>, Box<dyn io::Write + Send>)> + Send>;

impl std::fmt::Debug for ServoLink {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("ServoLink")
    }
}

impl std::fmt::Debug for OrionPort {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("OrionPort")
    }
}

/// The channel of stops, and a flag the runner reads between the items of
/// its longer loops (outputs to hand out, frames heard): a stop waiting
/// ends them early, so it waits behind one item, not hundreds.
#[derive(Debug, Clone)]
struct Urgent {
    tx: Sender<Msg>,
    waiting: Arc<AtomicBool>,
}

impl Urgent {
    fn send(&self, msg: Msg) -> Result<(), mpsc::SendError<Msg>> {
        let sent = self.tx.send(msg);
        self.waiting.store(true, Ordering::Release);
        sent
    }
}

/// Hands input to a running [`Runner`]; clone it for each input.
///
/// Lines are numbered per origin as they arrive (blank lines not
/// counted); a line that asks for an emergency stop ([`asks_for_stop`])
/// overtakes every line queued before it.
#[derive(Debug, Clone)]
pub struct InputSender {
    tx: Sender<Msg>,
    /// The bridge's validator, once the runner has its bridge: lines are
    /// read with it where they are read.
    validator: Arc<OnceLock<motorwire_wia::Validator>>,
    urgent: Urgent,
    numbers: Arc<Mutex<BTreeMap<Origin, u64>>>,
    budget: Arc<Budget>,
    max_line: usize,
}

impl InputSender {
    /// The longest line taken (bytes, without its newline): what
    /// [`feed`] and every reader of lines for this runner read with
    /// [`read_line`]; a longer one is refused ([`InputSender::too_long`]).
    pub const fn max_line(&self) -> usize {
        self.max_line
    }

    /// Why a line over [`InputSender::max_line`] was not taken, as its
    /// refusal says it.
    pub fn too_long(&self) -> String {
        format!(
            "the line is over {} bytes (the bridge's --max-size)",
            self.max_line
        )
    }

    fn number(&self, origin: Origin) -> u64 {
        let mut n = self.numbers.lock().unwrap_or_else(PoisonError::into_inner);
        let c = n.entry(origin).or_insert(0);
        *c += 1;
        *c
    }

    /// One line from `origin`, received now. Waits while
    /// [`MAX_QUEUED_PER_ORIGIN`] of `origin`'s lines are still waiting for
    /// the runner (a stop waits only behind other stops).
    pub fn line(&self, origin: Origin, text: impl Into<String>) {
        if let Some(read) = self.stamp(origin, text) {
            self.hand(read);
        }
    }

    /// A line of `origin`'s, read now: numbered and timed (when it reached
    /// the bridge) at once, to be handed over with [`InputSender::hand`],
    /// maybe later, behind lines read before it; `None` for a blank line
    /// (not counted, never answered). Lines stamped and handed so are
    /// answered as [`InputSender::line`] answers them.
    pub fn stamp(&self, origin: Origin, text: impl Into<String>) -> Option<Stamped> {
        let text = text.into();
        if text.trim().is_empty() {
            return None;
        }
        // When the line reached the bridge (read whole), taken before any
        // wait for the runner: a line read before a stop, kept waiting
        // behind its client's earlier lines, was written before it.
        let at = Instant::now();
        let urgent = asks_for_stop(text.trim());
        Some(Stamped {
            origin,
            number: self.number(origin),
            at,
            urgent,
            what: Stamp::Line(text),
        })
    }

    /// A line of `origin`'s that could not be taken, stamped as
    /// [`InputSender::stamp`] does: answered with an error (`reason`), or,
    /// when `stop`, taken as a stop; `bytes`: its first bytes and length,
    /// for the recording.
    fn stamp_refused(
        &self,
        origin: Origin,
        reason: String,
        stop: bool,
        bytes: Option<(Vec<u8>, u64)>,
    ) -> Stamped {
        Stamped {
            origin,
            number: self.number(origin),
            at: Instant::now(),
            urgent: stop,
            what: Stamp::Refused { reason, bytes },
        }
    }

    /// Hands a line stamped by this sender to the runner. Waits while
    /// [`MAX_QUEUED_PER_ORIGIN`] of its origin's lines are still waiting
    /// for the runner (a stop waits only behind other stops); a stop
    /// overtakes every line handed before it.
    pub fn hand(&self, read: Stamped) {
        let Stamped {
            origin,
            number,
            at,
            urgent,
            what,
        } = read;
        let msg = match what {
            Stamp::Line(text) => {
                // Read here, with the bridge's validator (once the runner
                // has its bridge): never on the engine's thread.
                let input = self
                    .validator
                    .get()
                    .map(|v| Box::new(crate::classify::classify(v, text.trim())));
                Msg::Line {
                    origin,
                    number,
                    text,
                    at,
                    input,
                }
            }
            Stamp::Refused { reason, bytes } => Msg::Refused {
                origin,
                number,
                reason,
                stop: urgent,
                bytes,
            },
        };
        self.budget.take(origin, urgent, queued_bytes(&msg));
        if urgent {
            let _ = self.urgent.send(msg);
            let _ = self.tx.send(Msg::Wake);
        } else {
            let _ = self.tx.send(msg);
        }
    }

    /// A line that could not be taken (too long, not UTF-8): answered with
    /// an error, never sent.
    pub fn refused(&self, origin: Origin, reason: impl Into<String>) {
        self.hand(self.stamp_refused(origin, reason.into(), false, None));
    }

    /// A line that could not be taken but names `emergency_stop`: when in
    /// doubt, stop. It overtakes the lines queued before it, as a stop does
    /// ([`Bridge::handle_numbered_unreadable_stop`]).
    pub fn refused_stop(&self, origin: Origin, reason: impl Into<String>) {
        self.hand(self.stamp_refused(origin, reason.into(), true, None));
    }

    /// A line that could not be read (`reason`: too long, not UTF-8),
    /// with its first bytes (`head`, at most [`UNREADABLE_HEAD`] kept) and
    /// its `length`, which a recording keeps: answered with an error and
    /// never sent, or, when `stop` (it names `emergency_stop`), taken as a
    /// stop, as [`InputSender::refused_stop`] does.
    pub fn unreadable(
        &self,
        origin: Origin,
        reason: impl Into<String>,
        stop: bool,
        head: Vec<u8>,
        length: u64,
    ) {
        self.hand(self.stamp_unreadable(origin, reason.into(), stop, head, length));
    }

    /// [`InputSender::unreadable`], stamped to be handed over later.
    fn stamp_unreadable(
        &self,
        origin: Origin,
        reason: String,
        stop: bool,
        mut head: Vec<u8>,
        length: u64,
    ) -> Stamped {
        head.truncate(UNREADABLE_HEAD);
        self.stamp_refused(origin, reason, stop, Some((head, length)))
    }

    /// How many lines of `origin` were handed over (each gets one result),
    /// until [`InputSender::forget`].
    pub fn lines_of(&self, origin: Origin) -> u64 {
        self.numbers
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .get(&origin)
            .copied()
            .unwrap_or(0)
    }

    /// `origin` left: its line count is forgotten (bounded memory over
    /// many clients).
    pub fn forget(&self, origin: Origin) {
        self.numbers
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .remove(&origin);
    }

    /// `origin` was disconnected by the bridge's owner (it stopped reading
    /// its results, or its connection failed): its lines not yet done are
    /// cancelled ([`Bridge::drop_origin`]) and its count forgotten. Lines
    /// it handed over before are still taken first.
    pub fn drop_origin(&self, origin: Origin, reason: impl Into<String>) {
        let _ = self.tx.send(Msg::Dropped {
            origin,
            reason: reason.into(),
        });
        self.forget(origin);
    }

    /// A client that connected (and authenticated): once the bridge is
    /// ready it is greeted with `ready` and the state now, for it alone
    /// ([`Bridge::greet`], [`Output::ToOne`]).
    pub fn greet(&self, origin: Origin) {
        let _ = self.tx.send(Msg::Greet { origin });
    }

    /// End of input: finish and stop the joints.
    pub fn finish(&self) {
        let _ = self.tx.send(Msg::Finish);
    }

    /// Interrupted: stop the joints now, ahead of every line queued (on
    /// the stops' channel).
    pub fn interrupt(&self) {
        let _ = self.urgent.send(Msg::Interrupt);
        let _ = self.tx.send(Msg::Wake);
    }
}

/// Runs a [`Bridge`] in real time: `tx` sends its frames, a thread
/// receives on `rx` (a second handle on the same bus). Lines come from
/// [`Runner::input`] senders.
#[derive(Debug)]
pub struct Runner {
    tx: Sender<Msg>,
    rx: Receiver<Msg>,
    urgent_tx: Urgent,
    urgent: Receiver<Msg>,
    numbers: Arc<Mutex<BTreeMap<Origin, u64>>>,
    budget: Arc<Budget>,
    orion: Option<OrionPort>,
    servo_links: Vec<ServoLink>,
    max_line: usize,
    taps: Vec<Arc<dyn Tap>>,
    validator: Arc<OnceLock<motorwire_wia::Validator>>,
}

impl Default for Runner {
    fn default() -> Self {
        Self::new()
    }
}

impl Runner {
    /// A runner with no input yet.
    pub fn new() -> Self {
        let (tx, rx) = mpsc::channel();
        let (urgent_tx, urgent) = mpsc::channel();
        Self {
            tx,
            rx,
            urgent_tx: Urgent {
                tx: urgent_tx,
                waiting: Arc::new(AtomicBool::new(false)),
            },
            urgent,
            numbers: Arc::default(),
            budget: Arc::default(),
            orion: None,
            servo_links: Vec::new(),
            max_line: DEFAULT_MAX_LINE,
            taps: Vec::new(),
            validator: Arc::default(),
        }
    }

    /// Takes lines of up to `bytes` (without the newline) from every input
    /// (the CLI's `--max-size`; [`DEFAULT_MAX_LINE`] unless set). Set it
    /// before [`Runner::input`]: a sender keeps the limit it was made with.
    #[must_use]
    pub const fn max_line(mut self, bytes: usize) -> Self {
        self.max_line = bytes;
        self
    }

    /// Attaches the Orion arm controller (the bridge must have been made
    /// with [`crate::BridgeConfig::line_link`]).
    #[must_use]
    pub fn with_orion(mut self, port: OrionPort) -> Self {
        self.orion = Some(port);
        self
    }

    /// Attaches the serial servo ports, one link for each of the bus map's
    /// [`motorwire_translate::BusMap::servo_ports`], in their order.
    #[must_use]
    pub fn with_servo_links(mut self, links: Vec<ServoLink>) -> Self {
        self.servo_links = links;
        self
    }

    /// Records the session (`motorwire_record`'s recorder, or any [`Tap`]
    /// that keeps what it is told: it is told last): every input line,
    /// output line, frame and Orion line, as it happens. The recorder never makes
    /// the bridge wait; keep another `Arc` of it to finish it once
    /// [`Runner::run`] has returned.
    #[must_use]
    pub fn with_recorder(mut self, recorder: Arc<dyn Tap>) -> Self {
        self.taps.push(recorder);
        self
    }

    /// Tells `tap` everything the session takes and gives, as it happens
    /// (a live view, a recorder of one's own): see [`Tap`].
    #[must_use]
    pub fn with_tap(mut self, tap: Arc<dyn Tap>) -> Self {
        // Ahead of the recorders: the last tap keeps each output
        // ([`Tap::output_owned`]), and a recorder is the one that does.
        self.taps.insert(0, tap);
        self
    }

    /// A handle to give input with.
    pub fn input(&self) -> InputSender {
        InputSender {
            tx: self.tx.clone(),
            validator: Arc::clone(&self.validator),
            urgent: self.urgent_tx.clone(),
            numbers: Arc::clone(&self.numbers),
            budget: Arc::clone(&self.budget),
            max_line: self.max_line,
        }
    }

    /// Runs `bridge` until it has stopped the joints (after
    /// [`InputSender::finish`] or [`InputSender::interrupt`]), giving each
    /// output line to `sink` as it comes. `clock_start` is the bridge's
    /// time zero.
    ///
    /// # Errors
    /// [`BridgeError::Bus`] when sending on the bus fails for good: the bus
    /// closed or gone (no such interface, interface down, its connection
    /// broken), a frame it can never carry (an FD frame on a classic
    /// interface), or any send failing once receiving has failed for good.
    /// Any other send error (no node acknowledged the frame, bus off, a
    /// full queue) loses that frame only, as a bus that drops it, and is
    /// said as a `bus_error` event; the engine sends again what waits for
    /// an answer.
    pub fn run<T, R>(
        self,
        bridge: Bridge,
        tx: T,
        rx: R,
        mut sink: impl FnMut(&Output),
    ) -> Result<Bridge, BridgeError>
    where
        T: CanBus,
        R: CanBus + Send + 'static,
    {
        self.run_inner(bridge, tx, rx, false, |o, _| sink(o))
    }

    /// [`Runner::run`] for a sink that writes each output as its JSON line
    /// (`Output::to_json`): the runner renders each output once and hands
    /// `sink` the output with its line, and its taps the same line (a
    /// recording keeps that line, shared, rather than the output, and
    /// writes it as it is).
    ///
    /// ```
    /// use std::sync::Arc;
    /// use motorwire_bridge::{Bridge, BridgeConfig, Output, Runner};
    /// use motorwire_bridge::sim::RealTimeArm;
    /// use motorwire_translate::BusMap;
    ///
    /// let map = BusMap::from_toml(
    ///     r#"
    ///     [motors.elbow]
    ///     dialect = "irpc"
    ///     node = 0x12
    ///     limits = { min_position = 0, max_position = 150, max_velocity = 90 }
    ///     "#,
    /// )?;
    /// let bridge = Bridge::new(map, BridgeConfig::default())?;
    /// let arm = RealTimeArm::start(bridge.map())?;
    /// let runner = Runner::new();
    /// let input = runner.input();
    /// input.finish();
    /// let (tx, rx) = arm.ports();
    /// let mut lines = Vec::new();
    /// let bridge = runner.run_rendered(bridge, tx, rx, |o: &Output, line: &Arc<str>| {
    ///     assert_eq!(**line, o.to_json());
    ///     lines.push(Arc::clone(line));
    /// })?;
    /// assert!(bridge.is_finished());
    /// assert!(lines.iter().any(|l| l.starts_with(r#"{"event":"stopped""#)));
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    ///
    /// # Errors
    /// As [`Runner::run`].
    pub fn run_rendered<T, R>(
        self,
        bridge: Bridge,
        tx: T,
        rx: R,
        mut sink: impl FnMut(&Output, &Arc<str>),
    ) -> Result<Bridge, BridgeError>
    where
        T: CanBus,
        R: CanBus + Send + 'static,
    {
        self.run_inner(bridge, tx, rx, true, |o, line| {
            if let Some(line) = line {
                sink(o, line);
            }
        })
    }

    /// [`Runner::run`], each output rendered first when `render`.
    fn run_inner<T, R>(
        self,
        mut bridge: Bridge,
        tx: T,
        rx: R,
        render: bool,
        sink: impl FnMut(&Output, Option<&Arc<str>>),
    ) -> Result<Bridge, BridgeError>
    where
        T: CanBus,
        R: CanBus + Send + 'static,
    {
        // The bridge's time zero is now: its wall clock too, read with it.
        let (start, wall) = clocks_together();
        if let Some(wall) = wall {
            bridge.anchor_epoch(wall.as_secs_f64() * 1000.0);
        }
        // From now on, lines are read where they are read.
        let _ = self.validator.set(bridge.validator().clone());
        let channels = run::Channels {
            lines: self.rx,
            wake: self.tx,
            urgent: self.urgent,
            stop_waiting: Arc::clone(&self.urgent_tx.waiting),
            budget: self.budget,
            orion: self.orion,
            servo_links: self.servo_links,
            taps: self.taps,
        };
        run::Loop::new(bridge, (tx, rx), channels, (render, sink), start)?.run()
    }
}

/// The channel of what the devices say, read ahead of the clients' lines:
/// a message on it, and a wake on the lines' channel when the loop may be
/// waiting there.
#[derive(Debug, Clone)]
struct Ahead {
    tx: Sender<Msg>,
    wake: Sender<Msg>,
    waiting: Arc<AtomicBool>,
}

impl Ahead {
    /// Hands `msg` to the runner. Whether it is still there.
    fn send(&self, msg: Msg) -> Result<(), ()> {
        self.tx.send(msg).map_err(|_| ())?;
        self.wake();
        Ok(())
    }

    /// Wakes the loop unless a wake is already on its way.
    fn wake(&self) {
        if !self.waiting.swap(true, Ordering::SeqCst) {
            let _ = self.wake.send(Msg::Wake);
        }
    }

    /// Tells the loop the bus failed, on the lines' channel (where it is
    /// woken).
    fn bus_error(&self, error: String) {
        let _ = self.wake.send(Msg::BusError(error));
    }
}

/// What `msg` brings that a recording keeps: an input line, a frame
/// received, a line from the Orion controller, and what else the bridge is
/// told (a client greeted or gone, the end of input, a signal, the Orion
/// link lost), so a replay can tell it the same.
fn record_input(r: &dyn Tap, msg: &Msg) {
    match msg {
        Msg::Line {
            origin,
            number,
            text,
            at,
            ..
        } => r.input(*at, *origin, *number, text),
        Msg::Refused {
            origin,
            number,
            reason,
            stop,
            bytes,
        } => r.unreadable(&crate::tap::Unreadable {
            at: Instant::now(),
            origin: *origin,
            number: *number,
            reason,
            stop: *stop,
            bytes: bytes.as_ref().map(|(b, n)| (b.as_slice(), *n)),
        }),
        Msg::Frame { frame, at } => r.frame_taken(*at, Instant::now(), frame),
        Msg::OrionLine { text, at } => r.orion(*at, Direction::Rx, text),
        Msg::Greet { origin } => r.mark(Instant::now(), Mark::Greet(*origin)),
        Msg::Dropped { origin, reason } => {
            r.mark(Instant::now(), Mark::Dropped(*origin, reason.clone()));
        }
        Msg::Finish => r.mark(Instant::now(), Mark::Finish),
        Msg::Interrupt => r.mark(Instant::now(), Mark::Interrupt),
        Msg::OrionUnreadable(e) => r.mark(Instant::now(), Mark::OrionUnreadable(e.clone())),
        Msg::OrionLost(e) => r.mark(Instant::now(), Mark::OrionLost(e.clone())),
        Msg::Wake | Msg::BusError(_) | Msg::Serial { .. } => {}
    }
}

#[cfg(test)]
mod tests;
