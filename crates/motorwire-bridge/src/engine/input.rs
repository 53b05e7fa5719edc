//! The engine's one input: everything that happens to the bridge is an
//! [`Input`] taken by [`Bridge::handle`], where the clock is kept and the
//! cached deadline forgotten, once, before the concern that takes it runs.

use super::*;

/// Something that happened to the bridge, for [`Bridge::handle`]: a line
/// from a client, a frame from the bus, a line from a device's own link,
/// a client come or gone, the time, the start and the end.
///
/// A Rust program commands the bridge with typed WIA values too
/// ([`Input::Command`], [`Input::MultiAxis`], [`Input::Trajectory`],
/// [`Input::SafetyLimits`]), built with their constructors
/// (`MotorCommand::new` and its `with_*` setters, ...) or parsed: each is
/// read exactly as its JSON line would be (validated, gated, answered
/// with one result), so a typed command can do nothing a line could not.
///
/// ```
/// use std::time::Duration;
/// use motorwire_bridge::{Bridge, BridgeConfig, ErrorKind, Input, Origin, Output};
/// use motorwire_bridge::motorwire_wia::MotorCommand;
/// use motorwire_bridge::motorwire_wia::core::ControlMode;
/// use motorwire_translate::BusMap;
///
/// let map = BusMap::from_toml("[motors.elbow]\ndialect = \"irpc\"\nnode = 0x12\n")?;
/// let config = BridgeConfig { activate_on_start: false, ..BridgeConfig::default() };
/// let mut bridge = Bridge::new(map, config)?;
/// bridge.handle(Duration::ZERO, Input::Start);
/// // A value no line could carry is refused as its line would be.
/// let command = MotorCommand::new("elbow", 1.0, ControlMode::Position, f64::NAN);
/// bridge.handle(Duration::ZERO, Input::Command { origin: Origin(1), command: Box::new(command) });
/// let result = std::iter::from_fn(|| bridge.poll_output()).find_map(|o| match o {
///     Output::Result { result, .. } => Some(result),
///     _ => None, // the `ready` event
/// });
/// let Some(result) = result else { panic!("one result") };
/// assert_eq!((result.line, result.ok), (1, false));
/// assert_eq!(result.error.map(|e| e.kind), Some(ErrorKind::Invalid));
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Debug)]
#[non_exhaustive]
pub enum Input<'a> {
    /// The bridge starts: its devices are greeted and configured. `now`
    /// is its time zero.
    Start,
    /// A line from `origin`, numbered among its origin's non-blank lines.
    Line {
        /// Who sent it.
        origin: Origin,
        /// The line (a blank one is ignored).
        text: &'a str,
    },
    /// A line its runner numbered (a runner that lets emergency stops
    /// overtake the lines queued before them numbers lines as they
    /// arrive); `read`: what the runtime's reader made of it (`None`:
    /// read here).
    NumberedLine {
        /// Who sent it.
        origin: Origin,
        /// Its number among its origin's lines.
        number: u64,
        /// The line.
        text: &'a str,
        /// The line as the runtime read it already.
        read: Option<Classified>,
    },
    /// A line that could not be read as text (not UTF-8, too long).
    Unreadable {
        /// Who sent it.
        origin: Origin,
        /// Its number, if its runner numbered it (`None`: the bridge
        /// does).
        number: Option<u64>,
        /// What the reader found.
        reason: &'a str,
        /// It names `emergency_stop`: the bridge cannot tell what it asks,
        /// and when in doubt it stops.
        stop: bool,
    },
    /// A WIA MotorCommand from `origin`, as a typed value.
    Command {
        /// Who sent it.
        origin: Origin,
        /// The command.
        command: Box<motorwire_wia::MotorCommand>,
    },
    /// A WIA multi-axis command from `origin`, as a typed value.
    MultiAxis {
        /// Who sent it.
        origin: Origin,
        /// The command.
        command: Box<motorwire_wia::MultiAxisCommand>,
    },
    /// A WIA Trajectory from `origin`, as a typed value.
    Trajectory {
        /// Who sent it.
        origin: Origin,
        /// The trajectory.
        trajectory: Box<motorwire_wia::Trajectory>,
    },
    /// A WIA SafetyLimits from `origin`, as a typed value.
    SafetyLimits {
        /// Who sent it.
        origin: Origin,
        /// The limits.
        limits: Box<motorwire_wia::SafetyLimits>,
    },
    /// An emergency stop from `origin` (`{"emergency_stop": true}`).
    EmergencyStop {
        /// Who sent it.
        origin: Origin,
    },
    /// The release of the emergency stop (`{"emergency_stop": false}`).
    Release {
        /// Who sent it.
        origin: Origin,
    },
    /// A frame from the bus.
    Frame(&'a Frame),
    /// Every frame [`Bridge::poll_transmit`] gave out is on the bus: the
    /// lines that sent them take now as their input-to-bus latency.
    Flushed,
    /// A line from a device's own link (the Orion arm controller's).
    LinkLine(&'a str),
    /// Bytes from a serial servo port (its index among the bus map's
    /// [`motorwire_translate::BusMap::servo_ports`]).
    SerialBytes {
        /// The port.
        port: u8,
        /// What came, as it came (a packet may come in pieces).
        bytes: &'a [u8],
    },
    /// A line from a device's own link that could not be read.
    LinkUnreadable(&'a str),
    /// A device's own link is lost (why).
    LinkLost(&'a str),
    /// A client connected (and authenticated): it is greeted, once.
    Greet(Origin),
    /// A client left (why): what it sent and has not run is cancelled,
    /// what it started is stopped.
    ClientLeft {
        /// The client.
        origin: Origin,
        /// Why it is gone.
        reason: &'a str,
    },
    /// A client's line count is forgotten (it left); its lines in progress
    /// are still answered.
    Forget(Origin),
    /// An interrupt (a signal): every joint is stopped at once.
    Interrupt,
    /// The end of input: what is in progress is drained, then the joints
    /// are stopped.
    EndOfInput,
    /// The time, for what is due ([`Bridge::poll_timeout`]).
    Timeout,
}

/// A line as the runtime's reader read it ([`crate::classify`] with this
/// bridge's validator, on the reader's thread). Only the runtime makes
/// one: a line handed over read is one the validator read, never a value
/// built to pass it by.
#[derive(Debug)]
pub struct Classified(pub(crate) Box<Line>);

impl Bridge {
    /// Takes `input`, which happened at `now`: the one way in. The clock
    /// only goes forward (an earlier `now` is taken as the latest seen),
    /// and the cached deadline is forgotten here, once, for every input.
    /// What it makes is read with [`Bridge::poll_transmit`],
    /// [`Bridge::poll_output`] and [`Bridge::poll_timeout`].
    pub fn handle(&mut self, now: Duration, input: Input<'_>) {
        self.changed();
        if let Input::Start = input {
            // Its time zero, as given.
            self.on_start(now);
            return;
        }
        self.now = self.now.max(now);
        match input {
            Input::Start => {}
            Input::Line { origin, text } => self.on_line(now, origin, text),
            Input::NumberedLine {
                origin,
                number,
                text,
                read,
            } => self.on_read_line(now, origin, number, text, read.map(|c| c.0)),
            Input::Unreadable {
                origin,
                number,
                reason,
                stop,
            } => match (number, stop) {
                (Some(number), true) => self.on_unreadable_stop(now, origin, number, reason),
                (None, true) => {
                    let number = self.number(origin);
                    self.on_unreadable_stop(now, origin, number, reason);
                }
                (Some(number), false) => {
                    self.on_numbered_unreadable(origin, number, reason);
                }
                (None, false) => self.on_unreadable(origin, reason),
            },
            Input::Command { origin, command } => self.on_typed(now, origin, &command),
            Input::MultiAxis { origin, command } => self.on_typed(now, origin, &command),
            Input::Trajectory { origin, trajectory } => self.on_typed(now, origin, &trajectory),
            Input::SafetyLimits { origin, limits } => self.on_typed(now, origin, &limits),
            Input::EmergencyStop { origin } => {
                self.on_line(now, origin, r#"{"emergency_stop":true}"#);
            }
            Input::Release { origin } => {
                self.on_line(now, origin, r#"{"emergency_stop":false}"#);
            }
            Input::Frame(frame) => self.on_frame(frame),
            Input::Flushed => self.on_flushed(now),
            Input::LinkLine(line) => self.on_link_line(line),
            Input::SerialBytes { port, bytes } => self.on_serial_bytes(port, bytes),
            Input::LinkUnreadable(reason) => self.on_link_unreadable(reason),
            Input::LinkLost(error) => self.on_link_lost(now, error),
            Input::Greet(origin) => self.on_greet(origin),
            Input::ClientLeft { origin, reason } => self.on_client_left(origin, reason),
            Input::Forget(origin) => self.on_forget(origin),
            Input::Interrupt => self.on_interrupt(),
            Input::EndOfInput => self.on_finish(),
            Input::Timeout => self.on_timeout(),
        }
    }

    /// A typed WIA message from `origin`, taken as its JSON line: the
    /// same validation, the same gate, one result.
    fn on_typed(&mut self, now: Duration, origin: Origin, message: &impl serde::Serialize) {
        match serde_json::to_string(message) {
            Ok(text) => self.on_line(now, origin, &text),
            // A value serde cannot write (a map with non-string keys; none
            // of WIA's): unreadable, never a panic.
            Err(e) => {
                let reason = format!("the message cannot be written as JSON: {e}");
                self.on_unreadable(origin, &reason);
            }
        }
    }

    /// [`Input::Start`] at `now`.
    pub fn start(&mut self, now: Duration) {
        self.handle(now, Input::Start);
    }

    /// [`Input::Line`]: one line received at `now` from `origin`. Blank
    /// lines are ignored; every other line gets exactly one result.
    ///
    /// Results carry `"line"`: the line's number among its origin's
    /// non-blank lines (from 1), so a reader can pair every result, an
    /// unlabelled refusal included, with what it sent.
    pub fn handle_line(&mut self, now: Duration, origin: Origin, line: &str) {
        self.handle(now, Input::Line { origin, text: line });
    }

    /// [`Input::NumberedLine`] not read yet: [`Bridge::handle_line`] for a
    /// line its runner already numbered. The bridge's own count for
    /// `origin` is not used.
    pub fn handle_numbered_line(&mut self, now: Duration, origin: Origin, number: u64, line: &str) {
        self.handle(
            now,
            Input::NumberedLine {
                origin,
                number,
                text: line,
                read: None,
            },
        );
    }

    /// [`Input::Unreadable`], numbered by the bridge: the line counts as a
    /// line of `origin` and is answered
    /// `{"ok":false,"error":{"kind":"unreadable",...}}`.
    pub fn handle_unreadable(&mut self, now: Duration, origin: Origin, reason: &str) {
        self.handle(
            now,
            Input::Unreadable {
                origin,
                number: None,
                reason,
                stop: false,
            },
        );
    }

    /// [`Input::Unreadable`] its runner numbered.
    pub fn handle_numbered_unreadable(
        &mut self,
        now: Duration,
        origin: Origin,
        number: u64,
        reason: &str,
    ) {
        self.handle(
            now,
            Input::Unreadable {
                origin,
                number: Some(number),
                reason,
                stop: false,
            },
        );
    }

    /// [`Input::Unreadable`] that names `emergency_stop`: answered as a
    /// stop, `reason` among its problems.
    pub fn handle_numbered_unreadable_stop(
        &mut self,
        now: Duration,
        origin: Origin,
        number: u64,
        reason: &str,
    ) {
        self.handle(
            now,
            Input::Unreadable {
                origin,
                number: Some(number),
                reason,
                stop: true,
            },
        );
    }

    /// [`Input::Frame`]: a frame from the bus at `now`.
    pub fn handle_frame(&mut self, now: Duration, frame: &Frame) {
        self.handle(now, Input::Frame(frame));
    }

    /// [`Input::Flushed`] as of `now`.
    pub fn flushed(&mut self, now: Duration) {
        self.handle(now, Input::Flushed);
    }

    /// [`Input::LinkLine`]: one line from a device's own link (the Orion
    /// controller's), received at `now`.
    pub fn handle_link_line(&mut self, now: Duration, line: &str) {
        self.handle(now, Input::LinkLine(line));
    }

    /// [`Input::SerialBytes`]: bytes from serial servo port `port`,
    /// received at `now`.
    pub fn handle_serial(&mut self, now: Duration, port: u8, bytes: &[u8]) {
        self.handle(now, Input::SerialBytes { port, bytes });
    }

    /// [`Input::LinkUnreadable`].
    pub fn handle_link_unreadable(&mut self, now: Duration, reason: &str) {
        self.handle(now, Input::LinkUnreadable(reason));
    }

    /// [`Input::LinkLost`].
    pub fn handle_link_lost(&mut self, now: Duration, error: &str) {
        self.handle(now, Input::LinkLost(error));
    }

    /// [`Input::Greet`].
    pub fn greet(&mut self, now: Duration, origin: Origin) {
        self.handle(now, Input::Greet(origin));
    }

    /// [`Input::ClientLeft`].
    pub fn drop_origin(&mut self, now: Duration, origin: Origin, reason: &str) {
        self.handle(now, Input::ClientLeft { origin, reason });
    }

    /// [`Input::Forget`].
    pub fn forget_origin(&mut self, origin: Origin) {
        self.handle(self.now, Input::Forget(origin));
    }

    /// [`Input::Interrupt`].
    pub fn interrupt(&mut self, now: Duration) {
        self.handle(now, Input::Interrupt);
    }

    /// [`Input::EndOfInput`].
    pub fn finish(&mut self, now: Duration) {
        self.handle(now, Input::EndOfInput);
    }

    /// [`Input::Timeout`].
    pub fn handle_timeout(&mut self, now: Duration) {
        self.handle(now, Input::Timeout);
    }

    /// The next line for a device's own link (the Orion controller's),
    /// without its newline.
    pub fn poll_link_line(&mut self) -> Option<String> {
        let line = self.drivers.poll_line()?;
        self.changed();
        Some(line)
    }

    /// The next bytes to write on a serial servo port, and the port (its
    /// index among the bus map's
    /// [`motorwire_translate::BusMap::servo_ports`]). Each port is one
    /// half-duplex bus: write the bytes in the order given.
    pub fn poll_serial(&mut self) -> Option<(u8, Vec<u8>)> {
        let out = self.drivers.poll_serial()?;
        self.changed();
        Some(out)
    }
}
