//! Running a [`Bridge`] in real time on a blocking bus.

use std::io::{self, BufRead, Write};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError, Sender};
use std::thread;
use std::time::{Duration, Instant};

use motorwire_can::{CanBus, Error as CanError, Frame};

use std::collections::BTreeMap;
use std::sync::{Condvar, Mutex, OnceLock, PoisonError};

use crate::classify::asks_for_stop;
use crate::clocks::clocks_together;
use crate::engine::{Bridge, Classified, Input};
use crate::error::BridgeError;
use crate::output::{Event, Origin, Output};
use crate::tap::{Direction, Mark, Tap, Taps};

mod read;

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
    /// with [`crate::BridgeConfig::orion`]).
    #[must_use]
    pub fn with_orion(mut self, port: OrionPort) -> Self {
        self.orion = Some(port);
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
    /// [`BridgeError::Bus`] when sending on the bus fails for good (bus off,
    /// interface down).
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
    /// let (tx, rx) = (arm.sender(), arm.port());
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
        mut self,
        mut bridge: Bridge,
        mut tx: T,
        mut rx: R,
        render: bool,
        mut sink: impl FnMut(&Output, Option<&Arc<str>>),
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
        let since = |at: Instant| at.saturating_duration_since(start);
        // From now on, lines are read where they are read.
        let _ = self.validator.set(bridge.validator().clone());
        let stop_waiting = Arc::clone(&self.urgent_tx.waiting);
        let stop = Arc::new(AtomicBool::new(false));
        // Frames from the bus have a channel of their own, read ahead of
        // the input lines (after the stops): an Ack is never queued behind
        // a flood of lines (its request would time out, and a stop come
        // back outcome_unknown). One Wake on the lines' channel rouses the
        // loop when it waits there.
        let (frames_tx, frames_rx) = mpsc::channel::<Msg>();
        let frames_waiting = Arc::new(AtomicBool::new(false));
        // What the devices say, CAN frames and the Orion controller's lines
        // alike, goes ahead of the clients' lines.
        let ahead = Ahead {
            tx: frames_tx,
            wake: self.tx.clone(),
            waiting: Arc::clone(&frames_waiting),
        };
        let reader = {
            let stop = Arc::clone(&stop);
            let wake = self.tx.clone();
            let ahead = ahead.clone();
            thread::spawn(move || {
                while !stop.load(Ordering::Relaxed) {
                    match rx.recv(Duration::from_millis(20)) {
                        Ok(r) => {
                            let _ = ahead.send(Msg::Frame {
                                frame: r.frame,
                                at: Instant::now(),
                            });
                        }
                        Err(CanError::Timeout(_)) => {}
                        Err(e) => {
                            let _ = wake.send(Msg::BusError(e.to_string()));
                            if fatal(&e) {
                                break;
                            }
                        }
                    }
                }
            })
        };
        let orion_queued = Arc::new(AtomicUsize::new(0));
        let orion = self
            .orion
            .take()
            .map(|port| spawn_orion(port, ahead.clone(), Arc::clone(&orion_queued)));
        let taps = Taps(std::mem::take(&mut self.taps));
        let rec: Option<&dyn Tap> = (!taps.0.is_empty()).then_some(&taps);
        // Each output to the caller's sink, then to the taps, which take
        // it as it is (or its line, when rendered for the sink): the
        // bridge's thread copies nothing for them.
        let mut sink = |o: Output| {
            let at = Instant::now();
            if render {
                let line: Arc<str> = Arc::from(o.to_json());
                sink(&o, Some(&line));
                if let Some(r) = rec {
                    r.output_line_owned(at, o, &line);
                }
            } else {
                sink(&o, None);
                if let Some(r) = rec {
                    r.output_owned(at, o);
                }
            }
        };
        if let Some(r) = rec {
            r.mark(start, Mark::Start);
        }
        bridge.start(since(Instant::now()));
        // The taps are hushed while a stop is handled.
        let mut hushed = false;
        // What the taps are told once the frames are out: the frames sent
        // (each with when it went) and the lines handled since the last
        // time. A stop's frames never wait for its recording.
        let mut sent: Vec<(Instant, Frame)> = Vec::new();
        let mut handled: Vec<(Instant, Instant, Origin, u64, String)> = Vec::new();
        let result = loop {
            let mut failed = None;
            while let Some(f) = bridge.poll_transmit() {
                if let Err(e) = tx.send(&f) {
                    failed = Some(e);
                    break;
                }
                if rec.is_some() {
                    sent.push((Instant::now(), f));
                }
            }
            while let Some(line) = bridge.poll_link_line() {
                if let Some(r) = rec {
                    r.orion(Instant::now(), Direction::Tx, &line);
                }
                if let Some((to_orion, _)) = &orion {
                    let _ = to_orion.send(line);
                }
            }
            bridge.flushed(since(Instant::now()));
            if let Some(r) = rec {
                for (at, f) in sent.drain(..) {
                    r.frame(at, Direction::Tx, &f);
                }
                for (at, taken, origin, number, text) in handled.drain(..) {
                    r.input_owned(at, taken, origin, number, text);
                }
            }
            if hushed {
                // The stop's frames are out: the taps may work again.
                if let Some(r) = rec {
                    r.hush(false);
                }
                hushed = false;
            }
            // Outputs to hand out, until a stop waits (the rest go
            // after its frames).
            while !stop_waiting.load(Ordering::Acquire)
                && let Some(o) = bridge.poll_output()
            {
                sink(o);
            }
            if let Some(e) = failed {
                break Err(BridgeError::Bus(e));
            }
            if bridge.is_finished() {
                break Ok(());
            }
            let now = since(Instant::now());
            let wait = bridge
                .poll_timeout()
                .map_or(Duration::from_millis(100), |t| t.saturating_sub(now));
            // Stops first, ahead of every line queued before them.
            let mut stopped = false;
            stop_waiting.store(false, Ordering::Release);
            while let Ok(msg) = self.urgent.try_recv() {
                if !hushed && let Some(r) = rec {
                    r.hush(true);
                    hushed = true;
                }
                if let Msg::Line { origin, .. } | Msg::Refused { origin, .. } = &msg {
                    self.budget.give(*origin, true, queued_bytes(&msg));
                }
                if let Some(r) = rec
                    && !matches!(msg, Msg::Line { .. })
                {
                    record_input(r, &msg);
                }
                match msg {
                    Msg::Line {
                        origin,
                        number,
                        text,
                        at,
                        input,
                    } => {
                        let taken = Instant::now();
                        bridge.handle(
                            since(at),
                            Input::NumberedLine {
                                origin,
                                number,
                                text: &text,
                                read: input.map(Classified),
                            },
                        );
                        if rec.is_some() {
                            handled.push((at, taken, origin, number, text));
                        }
                    }
                    Msg::Refused {
                        origin,
                        number,
                        reason,
                        ..
                    } => bridge.handle_numbered_unreadable_stop(
                        since(Instant::now()),
                        origin,
                        number,
                        &reason,
                    ),
                    Msg::Interrupt => bridge.interrupt(since(Instant::now())),
                    _ => {}
                }
                stopped = true;
            }
            if stopped {
                continue; // its frames go out before anything else is read
            }
            // Then what came from the bus, ahead of the lines (at most
            // FRAMES_AHEAD at a time: a bus flooded with frames still lets
            // a line through between them).
            frames_waiting.store(false, Ordering::SeqCst);
            let mut heard = 0;
            while heard < FRAMES_AHEAD
                && !stop_waiting.load(Ordering::Acquire)
                && let Ok(msg) = frames_rx.try_recv()
            {
                if let Some(r) = rec {
                    record_input(r, &msg);
                }
                match msg {
                    Msg::Frame { frame, at } => bridge.handle_frame(since(at), &frame),
                    Msg::OrionLine { text, at } => {
                        orion_queued.fetch_sub(1, Ordering::SeqCst);
                        bridge.handle_link_line(since(at), &text);
                    }
                    Msg::OrionUnreadable(error) => {
                        orion_queued.fetch_sub(1, Ordering::SeqCst);
                        bridge.handle_link_unreadable(since(Instant::now()), &error);
                    }
                    Msg::OrionLost(e) => bridge.handle_link_lost(since(Instant::now()), &e),
                    _ => {}
                }
                heard += 1;
            }
            if heard == FRAMES_AHEAD {
                // More may wait: looked at again after one line.
                frames_waiting.store(true, Ordering::SeqCst);
            }
            if stop_waiting.load(Ordering::Acquire) {
                // A stop came while frames were taken: it goes first, the
                // frames left after it.
                frames_waiting.store(true, Ordering::SeqCst);
                continue;
            }
            // Frames taken: one line (if one waits) in the same turn, so
            // a busy bus never holds the lines back; none taken: wait.
            let wait = if heard > 0 { Duration::ZERO } else { wait };
            let msg = self.rx.recv_timeout(wait);
            if let Ok(m @ (Msg::Line { origin, .. } | Msg::Refused { origin, .. })) = &msg {
                self.budget.give(*origin, false, queued_bytes(m));
            }
            if let (Some(r), Ok(m)) = (rec, &msg)
                && !matches!(m, Msg::Line { .. })
            {
                record_input(r, m);
            }
            match msg {
                Ok(Msg::Wake) => {}
                Ok(Msg::Dropped { origin, reason }) => {
                    bridge.drop_origin(since(Instant::now()), origin, &reason);
                }
                Ok(Msg::Line {
                    origin,
                    number,
                    text,
                    at,
                    input,
                }) => {
                    // Told to the taps once its frames are out, the line
                    // moved to them.
                    let taken = Instant::now();
                    bridge.handle(
                        since(at),
                        Input::NumberedLine {
                            origin,
                            number,
                            text: &text,
                            read: input.map(Classified),
                        },
                    );
                    if rec.is_some() {
                        handled.push((at, taken, origin, number, text));
                    }
                }
                Ok(Msg::Refused {
                    origin,
                    number,
                    reason,
                    stop: true,
                    ..
                }) => {
                    bridge.handle_numbered_unreadable_stop(
                        since(Instant::now()),
                        origin,
                        number,
                        &reason,
                    );
                }
                Ok(Msg::Refused {
                    origin,
                    number,
                    reason,
                    stop: false,
                    ..
                }) => {
                    bridge.handle_numbered_unreadable(
                        since(Instant::now()),
                        origin,
                        number,
                        &reason,
                    );
                }
                Ok(Msg::Frame { frame, at }) => bridge.handle_frame(since(at), &frame),
                Ok(Msg::Greet { origin }) => bridge.greet(since(Instant::now()), origin),
                Ok(Msg::Finish) => bridge.finish(since(Instant::now())),
                Ok(Msg::Interrupt) => bridge.interrupt(since(Instant::now())),
                Ok(Msg::BusError(e)) => sink(Output::Event(Event::BusError { error: e })),
                Ok(Msg::OrionLine { text, at }) => {
                    orion_queued.fetch_sub(1, Ordering::SeqCst);
                    bridge.handle_link_line(since(at), &text);
                }
                Ok(Msg::OrionUnreadable(error)) => {
                    orion_queued.fetch_sub(1, Ordering::SeqCst);
                    bridge.handle_link_unreadable(since(Instant::now()), &error);
                }
                Ok(Msg::OrionLost(e)) => bridge.handle_link_lost(since(Instant::now()), &e),
                Err(RecvTimeoutError::Timeout) => bridge.handle_timeout(since(Instant::now())),
                Err(RecvTimeoutError::Disconnected) => {
                    if let Some(r) = rec {
                        r.mark(Instant::now(), Mark::Finish);
                    }
                    bridge.finish(since(Instant::now()));
                }
            }
            // Timers that fell due while a message was handled.
            let now = since(Instant::now());
            if bridge.poll_timeout().is_some_and(|t| t <= now) {
                bridge.handle_timeout(now);
            }
        };
        if hushed && let Some(r) = rec {
            r.hush(false);
        }
        stop.store(true, Ordering::Relaxed);
        let _ = reader.join();
        if let Some((to_orion, written)) = orion {
            // The last lines (the stop) reach the controller before the
            // end, unless its stream is stuck.
            drop(to_orion);
            let _ = written.recv_timeout(Duration::from_secs(1));
        }
        result.map(|()| bridge)
    }
}

/// Frames from the bus taken ahead of the input lines at a time.
const FRAMES_AHEAD: usize = 256;

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
        Msg::Wake | Msg::BusError(_) => {}
    }
}

/// Starts the Orion port's reader and writer threads: lines to write go
/// into the returned sender; the receiver hears when the writer is done.
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
        if !self.waiting.swap(true, Ordering::SeqCst) {
            let _ = self.wake.send(Msg::Wake);
        }
        Ok(())
    }
}

fn spawn_orion(
    port: OrionPort,
    events: Ahead,
    queued: Arc<AtomicUsize>,
) -> (Sender<String>, Receiver<()>) {
    let OrionPort { reader, mut writer } = port;
    // Lines written and not yet answered: each lets one line back past the
    // per-second budget.
    let owed = Arc::new(AtomicUsize::new(0));
    {
        let events = events.clone();
        let owed = Arc::clone(&owed);
        // Not joined: a blocking read cannot be interrupted, and the thread
        // ends with its stream or the process.
        thread::spawn(move || {
            let mut reader = io::BufReader::new(reader);
            // This second's lines, and those dropped since the last report.
            let mut second = Instant::now();
            let mut taken: u32 = 0;
            let mut dropped: u64 = 0;
            loop {
                let msg = match read_line(&mut reader, crate::device::orion::MAX_ORION_LINE) {
                    Ok(ReadLine::Line(text)) => Msg::OrionLine {
                        text,
                        at: Instant::now(),
                    },
                    Ok(ReadLine::TooLong { .. }) => Msg::OrionUnreadable(format!(
                        "a line over {} bytes",
                        crate::device::orion::MAX_ORION_LINE
                    )),
                    Ok(ReadLine::NotUtf8 { .. }) => {
                        Msg::OrionUnreadable("a line that is not UTF-8".to_owned())
                    }
                    Ok(ReadLine::Partial(_) | ReadLine::End) => {
                        let _ =
                            events.send(Msg::OrionLost("the controller's stream ended".to_owned()));
                        return;
                    }
                    // A line with no end within MAX_SKIP: reported, and
                    // reading goes on (the next line starts after it).
                    Err(e) if e.kind() == io::ErrorKind::InvalidData => {
                        Msg::OrionUnreadable(e.to_string())
                    }
                    Err(e) => {
                        let _ = events
                            .send(Msg::OrionLost(format!("reading from the controller: {e}")));
                        return;
                    }
                };
                let now = Instant::now();
                if now.duration_since(second) >= Duration::from_secs(1) {
                    second = now;
                    taken = 0;
                }
                if queued.load(Ordering::SeqCst) >= MAX_ORION_QUEUED {
                    dropped += 1;
                    continue;
                }
                let answer = owed
                    .fetch_update(Ordering::SeqCst, Ordering::SeqCst, |n| n.checked_sub(1))
                    .is_ok();
                if !answer {
                    if taken >= MAX_ORION_LINES_PER_S {
                        dropped += 1;
                        continue;
                    }
                    taken += 1;
                }
                if dropped > 0 {
                    queued.fetch_add(1, Ordering::SeqCst);
                    let report = Msg::OrionUnreadable(format!(
                        "{dropped} lines from the controller dropped: more than {MAX_ORION_LINES_PER_S} a second beyond its answers, or {MAX_ORION_QUEUED} waiting"
                    ));
                    dropped = 0;
                    if events.send(report).is_err() {
                        return;
                    }
                }
                queued.fetch_add(1, Ordering::SeqCst);
                if events.send(msg).is_err() {
                    return;
                }
            }
        });
    }
    let (lines_tx, lines_rx) = mpsc::channel::<String>();
    let (done_tx, done_rx) = mpsc::channel();
    thread::spawn(move || {
        let mut failing = false;
        for line in lines_rx {
            let written = writer
                .write_all(line.as_bytes())
                .and_then(|()| writer.write_all(b"\n"))
                .and_then(|()| writer.flush());
            // A failed write is the link lost (reported once per run of
            // failures); the writer goes on, as a link that connects again
            // (TCP) takes the next line.
            if written.is_ok() {
                // Bounded: a controller that never answers owes at most
                // one budget's worth.
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
        let _ = done_tx.send(());
    });
    (lines_tx, done_rx)
}

/// A receive error after which the handle will never receive again.
fn fatal(e: &CanError) -> bool {
    matches!(
        e,
        CanError::Closed
            | CanError::NoSuchInterface { .. }
            | CanError::InterfaceDown { .. }
            | CanError::Io { .. }
    )
}

#[cfg(test)]
mod tests;
