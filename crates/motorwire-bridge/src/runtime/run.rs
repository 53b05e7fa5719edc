//! The runner's loop: one thread that sends the bridge's frames, hands
//! its outputs out and takes, in this order, the stops, what the devices
//! said and the clients' lines.
//!
//! What wakes it is one channel (the lines'); the stops' and the devices'
//! channels wake it through a [`Msg::Wake`] there. A bus that can say
//! when a frame is queued for it ([`CanBus::set_waker`], the simulated
//! bus) is polled by this thread itself: no thread of its own is woken for
//! each frame and then wakes this one (two context switches a frame
//! instead of one). Any other bus is read by a thread blocked in `recv`.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError, Sender};
use std::thread::{self, JoinHandle};
use std::time::{Duration, Instant};

use motorwire_can::{CanBus, Error as CanError, Frame};

use super::bus_errors::{BusErrors, fatal_to_receive, fatal_to_send};
use super::orion::spawn_orion;
use super::{Ahead, Budget, Msg, OrionPort, queued_bytes};
use crate::engine::{Bridge, Classified, Input};
use crate::error::BridgeError;
use crate::output::{Event, Origin, Output};
use crate::tap::{Direction, Mark, Tap, Taps};

/// Frames from the bus taken ahead of the input lines at a time.
const FRAMES_AHEAD: usize = 256;

/// How long the bus's reading thread waits in `recv` before it looks
/// whether the run is over.
const READER_POLL: Duration = Duration::from_millis(20);

/// What a look at a polled bus found.
enum Polled {
    /// A frame.
    Frame(Msg),
    /// An error to say (and the bus looked at again in the next turn when
    /// it can go on).
    Said(Msg),
    /// An error not said: looked at again at once.
    Again,
    /// Nothing due, or a pause after errors in a row.
    Nothing,
}

/// How frames from the bus reach the loop.
enum BusIn<R> {
    /// A thread blocked in `recv` hands them over on the devices' channel.
    Thread {
        stop: Arc<AtomicBool>,
        handle: JoinHandle<()>,
    },
    /// The bus wakes the loop when a frame is queued; the loop polls it.
    /// `None` once it failed for good.
    Polled(Option<R>),
}

impl<R: CanBus + Send + 'static> BusIn<R> {
    /// Reads `rx` as the bus allows: polled when it can wake `ahead`'s
    /// loop, else on a thread of its own.
    fn start(mut rx: R, ahead: &Ahead) -> Result<Self, BridgeError> {
        let waker = ahead.clone();
        if rx.set_waker(Arc::new(move || waker.wake())) {
            return Ok(Self::Polled(Some(rx)));
        }
        let stop = Arc::new(AtomicBool::new(false));
        let handle = {
            let stop = Arc::clone(&stop);
            let ahead = ahead.clone();
            thread::Builder::new()
                .name("mw-bus-reader".to_owned())
                .spawn(move || read_bus(&mut rx, &ahead, &stop))
                .map_err(|e| BridgeError::Thread("bus reader", e))?
        };
        Ok(Self::Thread { stop, handle })
    }

    /// The next frame of a polled bus, if one is due; `Err` with what it
    /// said when it failed (the bus is then given up when `fatal`).
    fn poll(&mut self) -> Result<Option<Frame>, CanError> {
        let Self::Polled(slot) = self else {
            return Ok(None);
        };
        let Some(rx) = slot else { return Ok(None) };
        match rx.recv(Duration::ZERO) {
            Ok(r) => Ok(Some(r.frame)),
            Err(CanError::Timeout(_)) => Ok(None),
            Err(e) => {
                if fatal_to_receive(&e) {
                    *slot = None;
                }
                Err(e)
            }
        }
    }

    /// Whether receiving failed for good (the reading thread ended on its
    /// own, or the polled bus was given up): a send failing then ends the
    /// run, the bus being gone both ways.
    fn gone(&self) -> bool {
        match self {
            Self::Thread { handle, .. } => handle.is_finished(),
            Self::Polled(rx) => rx.is_none(),
        }
    }

    fn end(self) {
        if let Self::Thread { stop, handle } = self {
            stop.store(true, Ordering::Relaxed);
            let _ = handle.join();
        }
    }
}

/// The bus's reading thread: each frame to the loop, with when it came,
/// until `stop` or a failure for good; errors it can go on after said as
/// [`BusErrors`] says.
fn read_bus<R: CanBus>(rx: &mut R, ahead: &Ahead, stop: &AtomicBool) {
    let mut errors = BusErrors::default();
    while !stop.load(Ordering::Relaxed) {
        match rx.recv(READER_POLL) {
            Ok(r) => {
                if let Some(said) = errors.worked() {
                    ahead.bus_error(said);
                }
                let _ = ahead.send(Msg::Frame {
                    frame: r.frame,
                    at: Instant::now(),
                });
            }
            Err(CanError::Timeout(_)) => {}
            Err(e) if fatal_to_receive(&e) => {
                ahead.bus_error(format!("receiving: {e}"));
                break;
            }
            Err(e) => {
                if let Some(said) = errors.failed("receiving", &e, Instant::now()) {
                    ahead.bus_error(said);
                }
                thread::sleep(errors.pause());
            }
        }
    }
}

/// What the runner hands its loop.
pub(super) struct Channels {
    pub(super) lines: Receiver<Msg>,
    pub(super) wake: Sender<Msg>,
    pub(super) urgent: Receiver<Msg>,
    pub(super) stop_waiting: Arc<AtomicBool>,
    pub(super) budget: Arc<Budget>,
    pub(super) orion: Option<OrionPort>,
    pub(super) servo_links: Vec<super::ServoLink>,
    pub(super) taps: Vec<Arc<dyn Tap>>,
}

/// A line taken, told to the taps once its frames are out: when it came,
/// when it was taken, whose, its number and text.
type Handled = (Instant, Instant, Origin, u64, String);

/// The loop's state between its turns.
pub(super) struct Loop<T, R, S> {
    bridge: Bridge,
    tx: T,
    bus: Option<BusIn<R>>,
    ch: Channels,
    frames: Receiver<Msg>,
    frames_waiting: Arc<AtomicBool>,
    orion: Option<(Sender<String>, Receiver<()>)>,
    orion_queued: Arc<AtomicUsize>,
    /// The serial servo ports, in the map's order.
    servo_ports: Vec<super::serial::SerialPort>,
    /// The taps, when there are any.
    taps: Option<Taps>,
    render: bool,
    sink: S,
    start: Instant,
    /// The taps are hushed while a stop is handled.
    hushed: bool,
    /// Frames sent since the taps were last told, each with when it went
    /// (a stop's frames never wait for its recording).
    sent: Vec<(Instant, Frame)>,
    handled: Vec<Handled>,
    /// A polled bus is looked at in the next turn though it did not wake
    /// the loop: frames were left in it. Otherwise it is polled only when
    /// it woke the loop (every look takes the bus's lock, which its
    /// devices' thread takes too).
    look_at_bus: bool,
    /// After errors in a row, when a polled bus is looked at again.
    bus_retry_at: Option<Instant>,
    /// What the bus said when receiving (polled) and sending failed.
    receive_errors: BusErrors,
    send_errors: BusErrors,
}

impl<T, R, S> Loop<T, R, S>
where
    T: CanBus,
    R: CanBus + Send + 'static,
    S: FnMut(&Output, Option<&Arc<str>>),
{
    /// The loop for `bridge`, its frames sent on `tx` and heard on `rx`;
    /// the bridge's time zero is `start`.
    pub(super) fn new(
        bridge: Bridge,
        (tx, rx): (T, R),
        mut ch: Channels,
        (render, sink): (bool, S),
        start: Instant,
    ) -> Result<Self, BridgeError> {
        // Frames from the bus have a channel of their own, read ahead of
        // the input lines (after the stops): an Ack is never queued behind
        // a flood of lines (its request would time out, and a stop come
        // back outcome_unknown). One Wake on the lines' channel rouses the
        // loop when it waits there.
        let (frames_tx, frames) = mpsc::channel::<Msg>();
        let frames_waiting = Arc::new(AtomicBool::new(false));
        // What the devices say, CAN frames and the Orion controller's lines
        // alike, goes ahead of the clients' lines.
        let ahead = Ahead {
            tx: frames_tx,
            wake: ch.wake.clone(),
            waiting: Arc::clone(&frames_waiting),
        };
        // The Orion link first: its threads end with their streams, where
        // the bus's reader would be left running if it failed to start.
        let orion_queued = Arc::new(AtomicUsize::new(0));
        let orion = match ch.orion.take() {
            Some(port) => Some(spawn_orion(port, ahead.clone(), Arc::clone(&orion_queued))?),
            None => None,
        };
        let servo_ports =
            super::serial::spawn_servo_links(std::mem::take(&mut ch.servo_links), &ahead)?;
        let bus = Some(BusIn::start(rx, &ahead)?);
        let taps = std::mem::take(&mut ch.taps);
        let taps = (!taps.is_empty()).then_some(Taps(taps));
        Ok(Self {
            bridge,
            tx,
            bus,
            ch,
            frames,
            frames_waiting,
            orion,
            orion_queued,
            servo_ports,
            taps,
            render,
            sink,
            start,
            hushed: false,
            sent: Vec::new(),
            handled: Vec::new(),
            // Frames queued before the waker was taken woke nobody: the
            // bus is looked at in the first turn.
            look_at_bus: true,
            bus_retry_at: None,
            receive_errors: BusErrors::default(),
            send_errors: BusErrors::default(),
        })
    }

    fn since(&self, at: Instant) -> Duration {
        at.saturating_duration_since(self.start)
    }

    fn now(&self) -> Duration {
        self.since(Instant::now())
    }

    /// Runs until the bridge is finished or the bus fails for good.
    pub(super) fn run(mut self) -> Result<Bridge, BridgeError> {
        if let Some(r) = &self.taps {
            r.mark(self.start, Mark::Start);
        }
        let now = self.now();
        self.bridge.start(now);
        let result = loop {
            let failed = self.send_out();
            if let Some(e) = failed {
                break Err(BridgeError::Bus(e));
            }
            if self.bridge.is_finished() {
                break Ok(());
            }
            self.turn();
        };
        self.end(result)
    }

    /// One turn: the stops first; then what the devices said; then one
    /// line, or a wait for one until the next timer.
    fn turn(&mut self) {
        let now = self.now();
        let wait = self
            .bridge
            .poll_timeout()
            .map_or(Duration::from_millis(100), |t| t.saturating_sub(now));
        if self.take_stops() {
            return; // its frames go out before anything else is read
        }
        let heard = self.take_frames();
        if self.ch.stop_waiting.load(Ordering::Acquire) {
            // A stop came while frames were taken: it goes first, the
            // frames left after it.
            self.frames_waiting.store(true, Ordering::SeqCst);
            self.look_at_bus = true;
            return;
        }
        // Frames taken: one line (if one waits) in the same turn, so a
        // busy bus never holds the lines back; none taken: wait (until a
        // failing polled bus is looked at again, at the latest).
        let wait = match self.bus_retry_at {
            Some(at) => wait.min(at.saturating_duration_since(Instant::now())),
            None => wait,
        };
        let wait = if heard > 0 { Duration::ZERO } else { wait };
        let msg = self.ch.lines.recv_timeout(wait);
        self.take(msg);
        // Timers that fell due while a message was handled.
        let now = self.now();
        if self.bridge.poll_timeout().is_some_and(|t| t <= now) {
            self.bridge.handle_timeout(now);
        }
    }

    /// Sends the bridge's frames and link lines, tells the taps, hands
    /// out the outputs (until a stop waits: the rest go after its frames).
    /// The bus's failure, if sending failed.
    fn send_out(&mut self) -> Option<CanError> {
        let mut failed = None;
        while let Some(f) = self.bridge.poll_transmit() {
            match self.tx.send(&f) {
                Ok(()) => {
                    if let Some(said) = self.send_errors.worked() {
                        self.give(Output::Event(Event::BusError { error: said }));
                    }
                }
                Err(e) if fatal_to_send(&e) || self.bus.as_ref().is_some_and(BusIn::gone) => {
                    failed = Some(e);
                    break;
                }
                // That frame lost, as on a bus that drops it: the others
                // go (a stop's other frames first of all), and what waits
                // for an answer is sent again.
                Err(e) => {
                    let what = "sending a frame (taken as lost)";
                    if let Some(said) = self.send_errors.failed(what, &e, Instant::now()) {
                        self.give(Output::Event(Event::BusError { error: said }));
                    }
                    continue;
                }
            }
            if self.taps.is_some() {
                self.sent.push((Instant::now(), f));
            }
        }
        while let Some(line) = self.bridge.poll_link_line() {
            if let Some(r) = &self.taps {
                r.orion(Instant::now(), Direction::Tx, &line);
            }
            if let Some((to_orion, _)) = &self.orion {
                let _ = to_orion.send(line);
            }
        }
        while let Some((port, bytes)) = self.bridge.poll_serial() {
            if let Some(p) = self.servo_ports.get(usize::from(port)) {
                let _ = p.writer.send(bytes);
            }
        }
        let now = self.now();
        self.bridge.flushed(now);
        if let Some(r) = &self.taps {
            for (at, f) in self.sent.drain(..) {
                r.frame(at, Direction::Tx, &f);
            }
            for (at, taken, origin, number, text) in self.handled.drain(..) {
                r.input_owned(at, taken, origin, number, text);
            }
            if self.hushed {
                // The stop's frames are out: the taps may work again.
                r.hush(false);
            }
        }
        self.hushed = false;
        while !self.ch.stop_waiting.load(Ordering::Acquire)
            && let Some(o) = self.bridge.poll_output()
        {
            self.give(o);
        }
        failed
    }

    /// `o` to the caller's sink, then to the taps, which take it as it is
    /// (or its line, when rendered for the sink): the bridge's thread
    /// copies nothing for them.
    fn give(&mut self, o: Output) {
        let at = Instant::now();
        if self.render {
            let line: Arc<str> = Arc::from(o.to_json());
            (self.sink)(&o, Some(&line));
            if let Some(r) = &self.taps {
                r.output_line_owned(at, o, &line);
            }
        } else {
            (self.sink)(&o, None);
            if let Some(r) = &self.taps {
                r.output_owned(at, o);
            }
        }
    }

    /// Every stop waiting, ahead of every line queued before it. Whether
    /// there was one.
    fn take_stops(&mut self) -> bool {
        let mut stopped = false;
        self.ch.stop_waiting.store(false, Ordering::Release);
        while let Ok(msg) = self.ch.urgent.try_recv() {
            if !self.hushed
                && let Some(r) = &self.taps
            {
                r.hush(true);
                self.hushed = true;
            }
            if let Msg::Line { origin, .. } | Msg::Refused { origin, .. } = &msg {
                self.ch.budget.give(*origin, true, queued_bytes(&msg));
            }
            if let Some(r) = &self.taps
                && !matches!(msg, Msg::Line { .. })
            {
                super::record_input(r, &msg);
            }
            match msg {
                Msg::Line { .. } => self.take_line(msg),
                Msg::Refused {
                    origin,
                    number,
                    reason,
                    ..
                } => {
                    let now = self.now();
                    self.bridge
                        .handle_numbered_unreadable_stop(now, origin, number, &reason);
                }
                Msg::Interrupt => {
                    let now = self.now();
                    self.bridge.interrupt(now);
                }
                _ => {}
            }
            stopped = true;
        }
        stopped
    }

    /// What the devices said, ahead of the lines: at most
    /// [`FRAMES_AHEAD`] at a time (a bus flooded with frames still lets a
    /// line through between them), first the devices' channel, then the
    /// bus polled. How many were taken.
    fn take_frames(&mut self) -> usize {
        let woken = self.frames_waiting.swap(false, Ordering::SeqCst);
        let retry = self.bus_retry_at.is_some_and(|t| t <= Instant::now());
        if retry {
            self.bus_retry_at = None;
        }
        let mut look = std::mem::take(&mut self.look_at_bus) || woken || retry;
        let mut heard = 0;
        while heard < FRAMES_AHEAD && !self.ch.stop_waiting.load(Ordering::Acquire) {
            let msg = match self.frames.try_recv() {
                Ok(msg) => msg,
                Err(_) if look => match self.poll_bus() {
                    Polled::Frame(msg) => msg,
                    Polled::Said(msg) => msg,
                    Polled::Again => continue,
                    Polled::Nothing => {
                        look = false;
                        continue;
                    }
                },
                Err(_) => break,
            };
            if let Some(r) = &self.taps {
                super::record_input(r, &msg);
            }
            self.take_device(msg);
            heard += 1;
        }
        if heard == FRAMES_AHEAD {
            // More may wait: looked at again after one line.
            self.frames_waiting.store(true, Ordering::SeqCst);
            self.look_at_bus = true;
        }
        heard
    }

    /// The next of a polled bus. After an error it can go on after, the
    /// frames behind it are read at once; from the second in a row, the
    /// bus is looked at again only after a pause (a bus failing at every
    /// look is not polled in a loop), and what is said of its errors is
    /// [`BusErrors`]'s.
    fn poll_bus(&mut self) -> Polled {
        let Some(bus) = self.bus.as_mut() else {
            return Polled::Nothing;
        };
        match bus.poll() {
            Ok(Some(frame)) => {
                if let Some(said) = self.receive_errors.worked() {
                    self.give(Output::Event(Event::BusError { error: said }));
                }
                let at = Instant::now();
                Polled::Frame(Msg::Frame { frame, at })
            }
            Ok(None) => Polled::Nothing,
            Err(e) if fatal_to_receive(&e) => {
                Polled::Said(Msg::BusError(format!("receiving: {e}")))
            }
            Err(e) => {
                let now = Instant::now();
                let said = self.receive_errors.failed("receiving", &e, now);
                let pause = self.receive_errors.pause();
                if !pause.is_zero() {
                    self.bus_retry_at = Some(now + pause);
                }
                match said {
                    Some(said) if pause.is_zero() => {
                        self.look_at_bus = true;
                        Polled::Said(Msg::BusError(said))
                    }
                    Some(said) => {
                        self.give(Output::Event(Event::BusError { error: said }));
                        Polled::Nothing
                    }
                    None if pause.is_zero() => Polled::Again,
                    None => Polled::Nothing,
                }
            }
        }
    }

    /// A message from the devices' side: a frame, the Orion controller's
    /// line, its loss, a bus error.
    fn take_device(&mut self, msg: Msg) {
        match msg {
            Msg::Frame { frame, at } => {
                let at = self.since(at);
                self.bridge.handle_frame(at, &frame);
            }
            Msg::OrionLine { text, at } => {
                self.orion_queued.fetch_sub(1, Ordering::SeqCst);
                let at = self.since(at);
                self.bridge.handle_link_line(at, &text);
            }
            Msg::OrionUnreadable(error) => {
                self.orion_queued.fetch_sub(1, Ordering::SeqCst);
                let now = self.now();
                self.bridge.handle_link_unreadable(now, &error);
            }
            Msg::OrionLost(e) => {
                let now = self.now();
                self.bridge.handle_link_lost(now, &e);
            }
            Msg::Serial { port, bytes, at } => {
                if let Some(p) = self.servo_ports.get(usize::from(port)) {
                    p.queued.fetch_sub(1, Ordering::SeqCst);
                }
                let at = self.since(at);
                self.bridge.handle_serial(at, port, &bytes);
            }
            Msg::BusError(e) => self.give(Output::Event(Event::BusError { error: e })),
            _ => {}
        }
    }

    /// A client's line, handed to the bridge; told to the taps once its
    /// frames are out, the line moved to them.
    fn take_line(&mut self, msg: Msg) {
        let Msg::Line {
            origin,
            number,
            text,
            at,
            input,
        } = msg
        else {
            return;
        };
        let taken = Instant::now();
        let since = self.since(at);
        self.bridge.handle(
            since,
            Input::NumberedLine {
                origin,
                number,
                text: &text,
                read: input.map(Classified),
            },
        );
        if self.taps.is_some() {
            self.handled.push((at, taken, origin, number, text));
        }
    }

    /// What came on the lines' channel (or that nothing came in time).
    fn take(&mut self, msg: Result<Msg, RecvTimeoutError>) {
        if let Ok(m @ (Msg::Line { origin, .. } | Msg::Refused { origin, .. })) = &msg {
            self.ch.budget.give(*origin, false, queued_bytes(m));
        }
        if let (Some(r), Ok(m)) = (&self.taps, &msg)
            && !matches!(m, Msg::Line { .. })
        {
            super::record_input(r, m);
        }
        let now = self.now();
        let msg = match msg {
            Ok(msg) => msg,
            Err(RecvTimeoutError::Timeout) => return self.bridge.handle_timeout(now),
            Err(RecvTimeoutError::Disconnected) => {
                if let Some(r) = &self.taps {
                    r.mark(Instant::now(), Mark::Finish);
                }
                return self.bridge.finish(now);
            }
        };
        match msg {
            Msg::Wake => {}
            Msg::Line { .. } => self.take_line(msg),
            Msg::Dropped { origin, reason } => self.bridge.drop_origin(now, origin, &reason),
            Msg::Refused {
                origin,
                number,
                reason,
                stop,
                ..
            } => {
                if stop {
                    self.bridge
                        .handle_numbered_unreadable_stop(now, origin, number, &reason);
                } else {
                    self.bridge
                        .handle_numbered_unreadable(now, origin, number, &reason);
                }
            }
            Msg::Greet { origin } => self.bridge.greet(now, origin),
            Msg::Finish => self.bridge.finish(now),
            Msg::Interrupt => self.bridge.interrupt(now),
            Msg::Frame { .. }
            | Msg::BusError(_)
            | Msg::OrionLine { .. }
            | Msg::OrionUnreadable(_)
            | Msg::OrionLost(_)
            | Msg::Serial { .. } => self.take_device(msg),
        }
    }

    /// The run's end: the taps unhushed, the bus's thread joined, the
    /// last lines to the Orion controller written (unless its stream is
    /// stuck).
    fn end(mut self, result: Result<(), BridgeError>) -> Result<Bridge, BridgeError> {
        if self.hushed
            && let Some(r) = &self.taps
        {
            r.hush(false);
        }
        if let Some(bus) = self.bus.take() {
            bus.end();
        }
        if let Some((to_orion, written)) = self.orion.take() {
            drop(to_orion);
            let _ = written.recv_timeout(Duration::from_secs(1));
        }
        // The servo ports' last packets (the stop's) written, a second at
        // most each.
        for p in std::mem::take(&mut self.servo_ports) {
            drop(p.writer);
            let _ = p.done.recv_timeout(Duration::from_secs(1));
        }
        result.map(|()| self.bridge)
    }
}
