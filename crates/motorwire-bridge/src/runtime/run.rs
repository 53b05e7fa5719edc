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
                if fatal(&e) {
                    *slot = None;
                }
                Err(e)
            }
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
/// until `stop` or a failure for good.
fn read_bus<R: CanBus>(rx: &mut R, ahead: &Ahead, stop: &AtomicBool) {
    while !stop.load(Ordering::Relaxed) {
        match rx.recv(READER_POLL) {
            Ok(r) => {
                let _ = ahead.send(Msg::Frame {
                    frame: r.frame,
                    at: Instant::now(),
                });
            }
            Err(CanError::Timeout(_)) => {}
            Err(e) => {
                ahead.bus_error(e.to_string());
                if fatal(&e) {
                    break;
                }
            }
        }
    }
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

/// What the runner hands its loop.
pub(super) struct Channels {
    pub(super) lines: Receiver<Msg>,
    pub(super) wake: Sender<Msg>,
    pub(super) urgent: Receiver<Msg>,
    pub(super) stop_waiting: Arc<AtomicBool>,
    pub(super) budget: Arc<Budget>,
    pub(super) orion: Option<OrionPort>,
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
            taps,
            render,
            sink,
            start,
            hushed: false,
            sent: Vec::new(),
            handled: Vec::new(),
            look_at_bus: false,
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
        // busy bus never holds the lines back; none taken: wait.
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
            if let Err(e) = self.tx.send(&f) {
                failed = Some(e);
                break;
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
        let mut look = std::mem::take(&mut self.look_at_bus) || woken;
        let mut heard = 0;
        while heard < FRAMES_AHEAD && !self.ch.stop_waiting.load(Ordering::Acquire) {
            let (msg, failed) = match self.frames.try_recv() {
                Ok(msg) => (msg, false),
                Err(_) if look => match self.bus.as_mut().map(BusIn::poll) {
                    Some(Ok(Some(frame))) => {
                        let at = Instant::now();
                        (Msg::Frame { frame, at }, false)
                    }
                    // Said once a turn: a bus failing again and again
                    // is not polled in a loop.
                    Some(Err(e)) => (Msg::BusError(e.to_string()), true),
                    Some(Ok(None)) | None => {
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
            if failed {
                break;
            }
        }
        if heard == FRAMES_AHEAD {
            // More may wait: looked at again after one line.
            self.frames_waiting.store(true, Ordering::SeqCst);
            self.look_at_bus = true;
        }
        heard
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
            | Msg::OrionLost(_) => self.take_device(msg),
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
        result.map(|()| self.bridge)
    }
}
