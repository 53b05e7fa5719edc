//! A simulated mjbots moteus controller: it answers the register protocol
//! on CAN-FD as a controller does, frames in, frames out (sans-IO, like
//! the other simulated devices).
//!
//! What it models:
//! - the modes stopped (0), fault (1), position (10), timeout (11) and
//!   brake (15); a position-mode command with a position plans a move to
//!   it within its `velocity_limit` and `accel_limit` (the defaults of the
//!   configuration where it sends none), ending at its `velocity` (then going on at it); with
//!   position NaN it runs at its velocity (accelerating within its
//!   `accel_limit`); with kp and kd scale 0 it applies its feedforward
//!   torque to a simple inertia; `maximum_torque` bounds the torque;
//! - the watchdog: in position mode, with no new command within the
//!   command's `watchdog_timeout` (the configuration's default where it
//!   sends none; NaN: none), it enters mode timeout (11) and decelerates to
//!   rest; it leaves timeout and fault only for a stop;
//! - the position bounds: a position-mode command while outside them
//!   faults (mode 1, fault 39, "outside limit"); a target beyond them is
//!   held to them;
//! - queries: a frame with read subframes whose CAN id asks for a reply
//!   (0x8000) is answered with those registers at the resolutions asked
//!   (a register it does not know with a read error); the reply's CAN id
//!   is its own id << 8 to the sender, on the frame's prefix.
//!
//! The watchdog is fed by frames that write the mode register (commands),
//! not by pure queries.

use std::collections::VecDeque;
use std::sync::atomic::AtomicBool;
use std::time::Duration;

use motorwire_can::{CanBus, CanId, Frame, SimPort};
use motorwire_moteus::diagnostic::{CLIENT_DATA, CLIENT_POLL, MAX_WRITE, SERVER_DATA};
use motorwire_moteus::protocol::{
    CanFdFrame, REPLY_INT8, Register, Resolution, Subframe, SubframeType, Value, WriteCanData,
    WriteCombiner,
};
use motorwire_moteus::{Scaled, scale};

use crate::SimError;

/// The modes it takes.
pub mod mode {
    /// No output.
    pub const STOPPED: u8 = 0;
    /// A fault; the fault register says which.
    pub const FAULT: u8 = 1;
    /// Position mode.
    pub const POSITION: u8 = 10;
    /// The watchdog expired.
    pub const TIMEOUT: u8 = 11;
    /// The windings shorted.
    pub const BRAKE: u8 = 15;
}

/// The fault for a position command outside the position bounds.
pub const FAULT_OUTSIDE_LIMIT: u8 = 39;

/// The supply voltage it reports (V).
pub const SUPPLY_VOLTAGE: f64 = 24.0;
/// The board temperature it reports (°C).
pub const TEMPERATURE: f64 = 30.0;
/// Torque per ampere of q current (Nm/A).
pub const TORQUE_CONSTANT: f64 = 0.1;
/// The rotor's inertia for torque commands (Nm per rev/s²).
pub const INERTIA: f64 = 0.05;
/// The step its motion is integrated with.
const STEP: Duration = Duration::from_millis(1);

/// How a [`SimMoteus`] is built.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MoteusConfig {
    /// Its id (1..=127).
    pub id: u8,
    /// The CAN prefix it answers on.
    pub prefix: u16,
    /// Its lower position bound (revolutions; `servopos.position_min`;
    /// NaN, set over the diagnostic stream: no bound, as on a controller).
    pub position_min: f64,
    /// Its upper position bound (`servopos.position_max`; NaN: none).
    pub position_max: f64,
    /// The velocity limit of a move that sends none (rev/s;
    /// `servo.default_velocity_limit`).
    pub default_velocity_limit: f64,
    /// The acceleration limit of a move that sends none, and of a stop by
    /// the watchdog (rev/s²; `servo.default_accel_limit`).
    pub default_accel_limit: f64,
    /// The watchdog of a command that sends none (s; NaN: none;
    /// `servo.default_timeout_s`, 0.1 s by default as on a controller).
    pub default_timeout: f64,
    /// The largest torque it gives (Nm).
    pub max_torque: f64,
    /// Where it starts (revolutions).
    pub initial_position: f64,
}

impl MoteusConfig {
    /// Controller `id` on prefix 0: bounds ±0.5 rev, 2 rev/s and 10 rev/s²
    /// by default, a 0.1 s watchdog, 5 Nm, at 0.
    pub fn new(id: u8) -> Self {
        Self {
            id,
            prefix: 0,
            position_min: -0.5,
            position_max: 0.5,
            default_velocity_limit: 2.0,
            default_accel_limit: 10.0,
            default_timeout: 0.1,
            max_torque: 5.0,
            initial_position: 0.0,
        }
    }
}

/// What it did with a frame addressed to it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MoteusActed {
    /// When.
    pub at: Duration,
    /// The mode it was commanded to, if the frame wrote one.
    pub commanded: Option<u8>,
    /// Its mode afterwards.
    pub mode: u8,
    /// Whether it answered.
    pub replied: bool,
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Drive {
    /// To `target` (rev), ending at `end_velocity`, within the limits.
    To {
        target: f64,
        end_velocity: f64,
        vlim: f64,
        alim: f64,
    },
    /// At `velocity` (rev/s), accelerating within `alim`.
    At { velocity: f64, alim: f64 },
    /// A feedforward torque (Nm) with no position or velocity gain.
    Torque(f64),
    /// To rest, within `alim`.
    Rest { alim: f64 },
    /// None: free (stopped) or shorted (brake: to rest at once).
    Idle,
}

/// A simulated moteus controller.
///
/// ```
/// use std::time::Duration;
/// use motorwire_can::{CanId, Frame};
/// use motorwire_moteus::{Call, decode};
/// use motorwire_sim::moteus::{MoteusConfig, SimMoteus, mode};
///
/// let mut m = SimMoteus::new(MoteusConfig::new(1))?;
/// // Position 0.25 rev within 1 rev/s and 4 rev/s², with a reply.
/// let f = Call::from_json(r#"{"command":"position","id":1,"position":0.25,"velocity":0,"velocity_limit":1,"accel_limit":4,"watchdog_timeout":null,"query":true}"#)?.encode()?;
/// // Padded with the protocol's no-op (0x50) to its CAN-FD length, as mjbots' transports pad.
/// let frame = Frame::fd(CanId::extended(f.can_id)?, &motorwire_moteus::padded(&f.data))?;
/// m.handle_frame(Duration::ZERO, &frame);
/// let reply = m.poll_transmit().expect("a reply");
/// assert_eq!(reply.id().raw(), 0x100);
/// assert_eq!(decode(reply.id().raw(), reply.data())?.int(0x000), Some(i64::from(mode::POSITION)));
/// m.handle_timeout(Duration::from_secs(1));
/// assert!((m.position() - 0.25).abs() < 1e-9);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Debug)]
pub struct SimMoteus {
    config: MoteusConfig,
    mode: u8,
    fault: u8,
    drive: Drive,
    position: f64,
    velocity: f64,
    torque: f64,
    max_torque: f64,
    /// When the watchdog expires (position mode).
    watchdog: Option<Duration>,
    trajectory_complete: bool,
    now: Duration,
    out: VecDeque<Frame>,
    commands: u64,
    /// The diagnostic console's text written to it, not yet a whole line.
    console_in: Vec<u8>,
    /// What the console wrote back, waiting for a poll.
    console_out: VecDeque<u8>,
    /// The console lines it ran.
    console_lines: Vec<String>,
}

/// The most the console keeps of a line not yet ended, and of answers not
/// yet polled: beyond it, text is dropped (as a controller's buffers do).
const CONSOLE_BUFFER: usize = 4096;

impl SimMoteus {
    /// A controller, stopped, at rest at its initial position.
    ///
    /// # Errors
    /// [`SimError::InvalidConfig`] for an id outside 1..=127, a prefix over
    /// 13 bits, bounds that are not ordered and finite, limits that are not
    /// finite and positive, or a start outside the bounds.
    pub fn new(config: MoteusConfig) -> Result<Self, SimError> {
        let bad = |field: &'static str, reason: &str| SimError::InvalidConfig {
            field,
            reason: reason.to_owned(),
        };
        if !(1..=127).contains(&config.id) {
            return Err(bad("id", "must be in 1..=127"));
        }
        if config.prefix > 0x1FFF {
            return Err(bad("prefix", "must fit 13 bits"));
        }
        if !(config.position_min.is_finite()
            && config.position_max.is_finite()
            && config.position_min < config.position_max)
        {
            return Err(bad(
                "position_min",
                "the bounds must be finite with min < max",
            ));
        }
        for (field, v) in [
            ("default_velocity_limit", config.default_velocity_limit),
            ("default_accel_limit", config.default_accel_limit),
            ("max_torque", config.max_torque),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(bad(field, "must be finite and positive"));
            }
        }
        if !(config.position_min..=config.position_max).contains(&config.initial_position) {
            return Err(bad("initial_position", "must lie within the bounds"));
        }
        Ok(Self {
            config,
            mode: mode::STOPPED,
            fault: 0,
            drive: Drive::Idle,
            position: config.initial_position,
            velocity: 0.0,
            torque: 0.0,
            max_torque: config.max_torque,
            watchdog: None,
            trajectory_complete: true,
            now: Duration::ZERO,
            out: VecDeque::new(),
            commands: 0,
            console_in: Vec::new(),
            console_out: VecDeque::new(),
            console_lines: Vec::new(),
        })
    }

    /// Its configuration.
    pub fn config(&self) -> &MoteusConfig {
        &self.config
    }
    /// Its mode (the [`mode`] constants).
    pub fn mode(&self) -> u8 {
        self.mode
    }
    /// Its fault code (0: none).
    pub fn fault(&self) -> u8 {
        self.fault
    }
    /// Its position (revolutions).
    pub fn position(&self) -> f64 {
        self.position
    }
    /// Its velocity (rev/s).
    pub fn velocity(&self) -> f64 {
        self.velocity
    }
    /// How many commands (frames writing the mode) it took.
    pub fn commands(&self) -> u64 {
        self.commands
    }
    /// Sets its position bounds (revolutions; NaN: none), as its console's
    /// `conf set servopos.position_min` and `position_max` set them.
    pub fn set_bounds(&mut self, min: f64, max: f64) {
        self.config.position_min = min;
        self.config.position_max = max;
    }
    /// The diagnostic console lines it ran, in order.
    pub fn console_lines(&self) -> &[String] {
        &self.console_lines
    }

    /// Its position bounds with NaN (no bound) as the infinities.
    fn bounds(&self) -> (f64, f64) {
        let lo = self.config.position_min;
        let hi = self.config.position_max;
        (
            if lo.is_nan() { f64::NEG_INFINITY } else { lo },
            if hi.is_nan() { f64::INFINITY } else { hi },
        )
    }

    /// A diagnostic frame (`0x40` text written, `0x42` a poll), taken as a
    /// controller's console takes it: the text's lines run (`conf get` and
    /// `conf set` of `servopos.position_min` and `servopos.position_max`;
    /// anything else is answered `ERR`), a poll answered with `0x41` and
    /// what is waiting. Whether it replied.
    fn diagnostic(&mut self, to: u32, data: &[u8], wants_reply: bool) -> bool {
        match data {
            [CLIENT_DATA, channel, len, rest @ ..] if *channel == 1 => {
                let Some(text) = rest.get(..usize::from(*len)) else {
                    return false;
                };
                for &b in text {
                    if b == b'\n' || b == b'\r' {
                        let line = String::from_utf8_lossy(&std::mem::take(&mut self.console_in))
                            .trim()
                            .to_owned();
                        if !line.is_empty() {
                            self.console(&line);
                        }
                    } else if self.console_in.len() < CONSOLE_BUFFER {
                        self.console_in.push(b);
                    }
                }
                false
            }
            [CLIENT_POLL, channel, max, ..] if *channel == 1 && wants_reply => {
                let n = usize::from(*max).min(MAX_WRITE).min(self.console_out.len());
                let mut reply = vec![SERVER_DATA, 1];
                #[allow(clippy::cast_possible_truncation)]
                reply.push(n as u8);
                reply.extend(self.console_out.drain(..n));
                if let Ok(id) = CanId::extended(self.reply_id(to))
                    && let Ok(f) = Frame::fd(id, &motorwire_moteus::padded(&reply))
                {
                    self.out.push_back(f);
                }
                true
            }
            _ => false,
        }
    }

    /// The CAN id of its reply to `to`: its prefix, itself as the source.
    fn reply_id(&self, to: u32) -> u32 {
        (u32::from(self.config.prefix) << 16) | (u32::from(self.config.id) << 8) | to
    }

    /// Runs one console line and queues its answer.
    fn console(&mut self, line: &str) {
        self.console_lines.push(line.to_owned());
        let words: Vec<&str> = line.split_whitespace().collect();
        let bound = |name: &str| match name {
            "servopos.position_min" => Some(false),
            "servopos.position_max" => Some(true),
            _ => None,
        };
        let answer = match words.as_slice() {
            ["conf", "get", name] => match bound(name) {
                Some(upper) => {
                    let v = if upper {
                        self.config.position_max
                    } else {
                        self.config.position_min
                    };
                    if v.is_nan() {
                        "nan".to_owned()
                    } else {
                        format!("{v}")
                    }
                }
                None => format!("ERR unknown configuration {name}"),
            },
            ["conf", "set", name, value] => match (bound(name), value.parse::<f64>()) {
                (Some(upper), Ok(v)) if !v.is_infinite() => {
                    let (lo, hi) = if upper {
                        (self.config.position_min, v)
                    } else {
                        (v, self.config.position_max)
                    };
                    if lo > hi {
                        format!("ERR {name} {v} would put the minimum above the maximum")
                    } else {
                        self.config.position_min = lo;
                        self.config.position_max = hi;
                        "OK".to_owned()
                    }
                }
                (Some(_), _) => format!("ERR {value} is no value for {name}"),
                (None, _) => format!("ERR unknown configuration {name}"),
            },
            _ => format!("ERR unknown command {line}"),
        };
        for b in answer.bytes().chain(*b"\r\n") {
            if self.console_out.len() < CONSOLE_BUFFER {
                self.console_out.push_back(b);
            }
        }
    }
    /// Whether it is moving.
    pub fn is_moving(&self) -> bool {
        self.velocity != 0.0
            || !matches!(self.drive, Drive::Idle | Drive::Rest { .. } if self.velocity == 0.0)
    }

    /// Faults now with `code` (what a controller does on, say, a motor
    /// driver fault: 33): mode 1, no output, until a stop.
    pub fn inject_fault(&mut self, now: Duration, code: u8) {
        self.advance(now);
        self.mode = mode::FAULT;
        self.fault = code;
        self.drive = Drive::Idle;
        self.velocity = 0.0;
        self.watchdog = None;
    }

    /// Takes a frame from the bus at `now`: a command, a query or both, if
    /// it is addressed to this controller (its id, its prefix).
    pub fn handle_frame(&mut self, now: Duration, frame: &Frame) -> Option<MoteusActed> {
        self.advance(now);
        let raw = frame.id().raw();
        if !frame.id().is_extended()
            || raw & 0x7F != u32::from(self.config.id)
            || (raw >> 16) & 0x1FFF != u32::from(self.config.prefix)
        {
            return None;
        }
        let source = (raw >> 8) & 0x7F;
        let wants_reply = raw & 0x8000 != 0;
        if matches!(frame.data().first(), Some(&(CLIENT_DATA | CLIENT_POLL))) {
            let replied = self.diagnostic(source, frame.data(), wants_reply);
            return Some(MoteusActed {
                at: self.now,
                commanded: None,
                mode: self.mode,
                replied,
            });
        }
        // A frame the register protocol cannot read is ignored, as a
        // controller ignores it (and never parsed: `parse_frame` overflows
        // on a long varuint).
        if motorwire_moteus::check_structure(frame.data()).is_err() {
            return None;
        }
        let mut writes: Vec<(u16, Value)> = Vec::new();
        let mut reads: Vec<(u16, Resolution)> = Vec::new();
        for sub in motorwire_moteus::protocol::parse_frame(frame.data()) {
            match sub {
                Subframe::Register {
                    subframe_type: SubframeType::Write,
                    register,
                    value: Some(v),
                    ..
                } => {
                    writes.push((register, v));
                }
                Subframe::Register {
                    subframe_type: SubframeType::Read,
                    register,
                    resolution,
                    ..
                } => {
                    reads.push((register, resolution));
                }
                _ => {}
            }
        }
        let commanded = self.command(&writes);
        let replied = wants_reply && !reads.is_empty();
        if replied {
            self.reply(source, &reads);
        }
        Some(MoteusActed {
            at: self.now,
            commanded,
            mode: self.mode,
            replied,
        })
    }

    /// The value of a written register, scaled.
    fn written(writes: &[(u16, Value)], register: Register) -> Option<f64> {
        writes
            .iter()
            .rev()
            .find(|(r, _)| *r == register.address())
            .and_then(|(r, v)| match scale(*r, *v) {
                Ok(Scaled::Float(f)) => Some(f),
                #[allow(clippy::cast_precision_loss)]
                Ok(Scaled::Int(i)) => Some(i as f64),
                Err(_) => None,
            })
    }

    fn command(&mut self, writes: &[(u16, Value)]) -> Option<u8> {
        let m = Self::written(writes, Register::Mode)?;
        #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
        let m = m as u8;
        self.commands += 1;
        let latched = matches!(self.mode, mode::FAULT | mode::TIMEOUT);
        match m {
            mode::STOPPED => {
                self.mode = mode::STOPPED;
                self.fault = 0;
                self.drive = Drive::Idle;
                self.watchdog = None;
            }
            mode::BRAKE if !latched => {
                self.mode = mode::BRAKE;
                self.drive = Drive::Idle;
                self.velocity = 0.0;
                self.watchdog = None;
            }
            mode::POSITION if !latched => self.position_command(writes),
            _ => {}
        }
        Some(m)
    }

    fn position_command(&mut self, writes: &[(u16, Value)]) {
        let w = |r| Self::written(writes, r);
        let c = self.config;
        let (lo, hi) = self.bounds();
        if !(lo..=hi).contains(&self.position) {
            self.mode = mode::FAULT;
            self.fault = FAULT_OUTSIDE_LIMIT;
            self.drive = Drive::Rest {
                alim: c.default_accel_limit,
            };
            self.watchdog = None;
            return;
        }
        self.mode = mode::POSITION;
        let finite_or = |v: Option<f64>, d: f64| v.filter(|x| x.is_finite()).unwrap_or(d);
        let vlim = finite_or(w(Register::CommandVelocityLimit), c.default_velocity_limit)
            .abs()
            .max(1e-6);
        let alim = finite_or(w(Register::CommandAccelLimit), c.default_accel_limit)
            .abs()
            .max(1e-6);
        self.max_torque = finite_or(w(Register::CommandPositionMaxTorque), c.max_torque)
            .abs()
            .min(c.max_torque);
        let kp = finite_or(w(Register::CommandKpScale), 1.0);
        let kd = finite_or(w(Register::CommandKdScale), 1.0);
        let velocity = finite_or(w(Register::CommandVelocity), 0.0);
        let position = w(Register::CommandPosition).unwrap_or(f64::NAN);
        let ff = finite_or(w(Register::CommandFeedforwardTorque), 0.0);
        self.drive = if kp == 0.0 && kd == 0.0 {
            Drive::Torque(ff.clamp(-self.max_torque, self.max_torque))
        } else if position.is_finite() {
            Drive::To {
                target: position.clamp(lo, hi),
                end_velocity: velocity,
                vlim,
                alim,
            }
        } else {
            Drive::At { velocity, alim }
        };
        // A command it already meets (the same move sent again at its end)
        // leaves its trajectory complete, as on a controller.
        self.trajectory_complete = matches!(
            self.drive,
            Drive::To { target, end_velocity, .. }
                if (target - self.position).abs() < 1e-9 && (self.velocity - end_velocity).abs() < 1e-9
        );
        let timeout = match w(Register::CommandTimeout) {
            Some(t) if t.is_nan() => f64::NAN,
            Some(t) if t > 0.0 => t,
            _ => c.default_timeout,
        };
        self.watchdog = Duration::try_from_secs_f64(timeout)
            .ok()
            .map(|d| self.now.saturating_add(d));
    }

    fn reply(&mut self, to: u32, reads: &[(u16, Resolution)]) {
        let mut frame = CanFdFrame::new();
        let mut errors: Vec<u16> = Vec::new();
        // Runs of consecutive registers at one resolution, as asked.
        let mut i = 0;
        while let Some(&(start, _)) = reads.get(i) {
            let mut j = i;
            while let (Some(a), Some(b)) = (reads.get(j), reads.get(j + 1)) {
                if b.0 == a.0 + 1 {
                    j += 1;
                } else {
                    break;
                }
            }
            let run = reads.get(i..=j).unwrap_or(&[]);
            let resolutions: Vec<Resolution> = run
                .iter()
                .map(|(r, res)| {
                    if self.value_of(*r).is_some() {
                        *res
                    } else {
                        Resolution::Ignore
                    }
                })
                .collect();
            errors.extend(
                run.iter()
                    .filter(|(r, _)| self.value_of(*r).is_none())
                    .map(|(r, _)| *r),
            );
            let mut combiner = WriteCombiner::new(REPLY_INT8, start, &resolutions);
            let mut w = WriteCanData::new(&mut frame);
            for (r, res) in run {
                if !combiner.maybe_write(&mut w) {
                    continue;
                }
                let Some(v) = self.value_of(*r) else { continue };
                write_register(&mut w, *r, v, *res);
            }
            i = j + 1;
        }
        let mut w = WriteCanData::new(&mut frame);
        for r in errors {
            w.write_u8(motorwire_moteus::protocol::READ_ERROR);
            w.write_varuint(u32::from(r));
            w.write_varuint(1);
        }
        let data = motorwire_moteus::padded(frame.payload());
        if let (Ok(id), true) = (CanId::extended(self.reply_id(to)), !data.is_empty())
            && let Ok(f) = Frame::fd(id, &data)
        {
            self.out.push_back(f);
        }
    }

    /// The value of register `r` now, if it is one it reports.
    fn value_of(&self, r: u16) -> Option<f64> {
        let current = self.torque / TORQUE_CONSTANT;
        Some(match r {
            0x000 => f64::from(self.mode),
            0x001 => self.position,
            0x002 => self.velocity,
            0x003 => self.torque,
            0x004 => current,
            0x005 => 0.0,
            0x006 => self.position,
            0x007 => self.torque * self.velocity * std::f64::consts::TAU,
            0x00a => TEMPERATURE,
            0x00b => f64::from(u8::from(self.trajectory_complete)),
            0x00c => 0.0,
            0x00d => SUPPLY_VOLTAGE,
            0x00e => TEMPERATURE,
            0x00f => f64::from(self.fault),
            _ => return None,
        })
    }

    /// Advances to `now`: motion, the watchdog.
    pub fn handle_timeout(&mut self, now: Duration) {
        self.advance(now);
    }

    fn advance(&mut self, now: Duration) {
        while self.now < now {
            let next = self.now.saturating_add(STEP).min(now);
            if let Some(w) = self.watchdog
                && w <= next
                && self.mode == mode::POSITION
            {
                self.step((w.saturating_sub(self.now)).as_secs_f64());
                self.now = w;
                self.mode = mode::TIMEOUT;
                self.watchdog = None;
                self.drive = Drive::Rest {
                    alim: self.config.default_accel_limit,
                };
                continue;
            }
            self.step(next.saturating_sub(self.now).as_secs_f64());
            self.now = next;
        }
    }

    fn step(&mut self, dt: f64) {
        if dt <= 0.0 {
            return;
        }
        let v0 = self.velocity;
        match self.drive {
            Drive::Idle => {
                self.velocity = 0.0;
                self.torque = 0.0;
            }
            Drive::Rest { alim } => {
                self.velocity = toward(v0, 0.0, alim * dt);
            }
            Drive::At { velocity, alim } => {
                self.velocity = toward(v0, velocity, alim * dt);
            }
            Drive::Torque(t) => {
                self.velocity = v0 + t / INERTIA * dt;
            }
            Drive::To {
                target,
                end_velocity,
                vlim,
                alim,
            } => {
                let err = target - self.position;
                if err.abs() < 1e-9 && (v0 - end_velocity).abs() < 1e-9 {
                    self.velocity = end_velocity;
                    self.trajectory_complete = true;
                } else {
                    // The fastest speed from which it still comes to the
                    // target at its end velocity (at rest, or passing it
                    // the same way at that speed).
                    let through = if end_velocity * err > 0.0 {
                        end_velocity * end_velocity
                    } else {
                        0.0
                    };
                    let reachable = (through + 2.0 * alim * err.abs()).sqrt().min(vlim);
                    let want = err.signum() * reachable;
                    let v = toward(v0, want, alim * dt);
                    let moved = 0.5 * (v0 + v) * dt;
                    if moved.abs() >= err.abs() || (err.abs() < alim * dt * dt) {
                        self.position = target;
                        self.velocity = end_velocity;
                        self.trajectory_complete = true;
                        self.torque = 0.0;
                        if end_velocity != 0.0 {
                            // Past its target at speed, the setpoint goes on
                            // at that velocity, as on a controller.
                            self.drive = Drive::At {
                                velocity: end_velocity,
                                alim,
                            };
                        }
                        return;
                    }
                    self.velocity = v;
                }
            }
        }
        if !matches!(self.drive, Drive::Idle) {
            let accel = (self.velocity - v0) / dt;
            if !matches!(self.drive, Drive::Torque(_)) {
                self.torque = (accel * INERTIA).clamp(-self.max_torque, self.max_torque);
            } else if let Drive::Torque(t) = self.drive {
                self.torque = t;
            }
            self.position += 0.5 * (v0 + self.velocity) * dt;
        }
        let (lo, hi) = self.bounds();
        if matches!(self.mode, mode::POSITION) && !(lo - 1e-9..=hi + 1e-9).contains(&self.position)
        {
            self.position = self.position.clamp(lo, hi);
            self.mode = mode::FAULT;
            self.fault = FAULT_OUTSIDE_LIMIT;
            self.drive = Drive::Idle;
            self.velocity = 0.0;
            self.watchdog = None;
        }
    }

    /// The next frame to put on the bus.
    pub fn poll_transmit(&mut self) -> Option<Frame> {
        self.out.pop_front()
    }

    /// When [`SimMoteus::handle_timeout`] next has work: the watchdog, or
    /// the next step of a motion.
    pub fn poll_timeout(&self) -> Option<Duration> {
        let moving = (self.velocity != 0.0
            || matches!(
                self.drive,
                Drive::To { .. } | Drive::At { .. } | Drive::Torque(_)
            ) && !self.trajectory_complete)
            .then(|| self.now.saturating_add(Duration::from_millis(10)));
        [self.watchdog, moving].into_iter().flatten().min()
    }

    /// One pass on a simulated bus at simulated time `now`.
    ///
    /// # Errors
    /// The bus's errors.
    pub fn serve(&mut self, port: &mut SimPort, now: Duration) -> Result<bool, SimError> {
        crate::device::serve(self, port, now)
    }

    /// Runs the controller on `bus` in real time until `stop` is set.
    ///
    /// # Errors
    /// The bus's errors, other than receive timeouts.
    pub fn run(
        &mut self,
        bus: &mut impl CanBus,
        stop: &AtomicBool,
        on_acted: impl FnMut(&MoteusActed),
    ) -> Result<(), SimError> {
        crate::device::run(self, bus, stop, on_acted)
    }
}

/// `from` moved toward `to` by at most `by`.
fn toward(from: f64, to: f64, by: f64) -> f64 {
    if (to - from).abs() <= by {
        to
    } else {
        from + (to - from).signum() * by
    }
}

/// Writes register `r`'s value `v` at `res`, scaled as the register is.
fn write_register(w: &mut WriteCanData, r: u16, v: f64, res: Resolution) {
    #[allow(clippy::cast_possible_truncation)]
    let f = v as f32;
    match r {
        0x000 | 0x00b | 0x00c | 0x00f => {
            #[allow(clippy::cast_possible_truncation)]
            w.write_int(v as i32, res);
        }
        0x001 | 0x006 => w.write_position(f, res),
        0x002 => w.write_velocity(f, res),
        0x003 => w.write_torque(f, res),
        0x004 | 0x005 => w.write_current(f, res),
        0x007 => w.write_mapped(f, &motorwire_moteus::protocol::scaling::POWER, res),
        0x00a | 0x00e => w.write_temperature(f, res),
        _ => w.write_voltage(f, res),
    }
}

impl crate::device::Device for SimMoteus {
    type Acted = MoteusActed;
    fn handle_frame(&mut self, now: Duration, frame: &Frame) -> Option<MoteusActed> {
        SimMoteus::handle_frame(self, now, frame)
    }
    fn handle_timeout(&mut self, now: Duration) {
        SimMoteus::handle_timeout(self, now);
    }
    fn poll_transmit(&mut self) -> Option<Frame> {
        SimMoteus::poll_transmit(self)
    }
    fn poll_timeout(&self) -> Option<Duration> {
        SimMoteus::poll_timeout(self)
    }
}
