//! The moteus driver: mjbots moteus controllers on CAN-FD, their frames
//! built by `motorwire_moteus` (mjbots' `moteus-protocol` underneath).
//!
//! It owns the dialect's encoding (a command's frame, built by a pure
//! function first and queued second), its requests in flight (one per
//! controller: every command asks for a reply, and the reply acknowledges
//! it; a command not answered in time is sent again, then given up), its
//! queries (each controller polled at its map's `query_rate_hz`), and its
//! replies decoded into WIA `MotorFeedback` and into the controller's own
//! stops (a fault, the watchdog's timeout) by name.
//!
//! The controller's watchdog: a velocity or torque command carries the
//! motor's command timeout (the bridge's deadman) as its
//! `watchdog_timeout`, and is not renewed by the driver: a controller
//! whose stream stops times out by itself. A position move (and a
//! velocity or torque with the deadman disabled) is held: its frame is
//! sent again at each poll in place of the query, with a watchdog of five
//! poll periods (at least 0.25 s), so that a controller whose bridge dies
//! stops by itself within that. A held move is held where it stands
//! (position NaN, velocity 0) once the controller reports it complete,
//! once the limits in force change, and once the bridge gives the command
//! up: its target is never sent again after any of these.

use super::DeviceError;
use std::collections::BTreeMap;
use std::time::Duration;

use motorwire_can::{CanId, Frame};
use motorwire_moteus::protocol::Resolution;
use motorwire_moteus::{Call, Command, PositionArgs, Reply, Resolutions, decode};
use motorwire_translate::{AngleUnit, MoteusCommand};
use motorwire_wia::MotorFeedback;

use super::frames::FrameRequests;
use super::moteus_bounds::{BoundsNews, OwnBounds};
use super::{DeviceId, Ended};

/// The bridge's own id on the bus (the replies' destination).
pub(crate) const SOURCE: u8 = 0;

/// The modes a reply reports that the driver acts on.
/// How often a stop is sent again while a frame sent before it may still
/// arrive (then at each poll).
const STOP_REPEAT: Duration = Duration::from_millis(5);

const MODE_STOPPED: i64 = 0;
const MODE_FAULT: i64 = 1;
const MODE_BRAKE: i64 = 15;
const MODE_POSITION: i64 = 10;
const MODE_TIMEOUT: i64 = 11;

/// The registers the bridge asks for with every command and poll: the
/// library's default query (mode, position, velocity, torque as f32;
/// voltage, temperature, fault as int8) with the q current (f32) and the
/// trajectory's completion (int8).
pub(crate) fn resolutions() -> Resolutions {
    let mut r = Resolutions::default();
    r.query.q_current = Resolution::Float;
    r.query.trajectory_complete = Resolution::Int8;
    r
}

/// The watchdog of a held command: five poll periods, at least 0.25 s
/// (a controller whose bridge dies stops within that; a late poll or two
/// does not time it out).
pub(crate) fn hold_watchdog(period: Duration) -> f64 {
    (5.0 * period.as_secs_f64()).max(0.25)
}

/// A moteus fault code's name (the controller's reference manual).
pub(crate) fn fault_name(code: i64) -> &'static str {
    match code {
        32 => "calibration fault",
        33 => "motor driver fault",
        34 => "over voltage",
        35 => "encoder fault",
        36 => "motor not configured",
        37 => "pwm cycle overrun",
        38 => "over temperature",
        39 => "outside limit",
        40 => "under voltage",
        41 => "config changed",
        42 => "theta invalid",
        43 => "position invalid",
        44 => "driver enable fault",
        45 => "stop position deprecated",
        46 => "timing violation",
        _ => "fault",
    }
}

fn can_frame(can_id: u32, data: &[u8]) -> Result<Frame, DeviceError> {
    let id = CanId::extended(can_id).map_err(DeviceError::Frame)?;
    Frame::fd(id, &motorwire_moteus::padded(data)).map_err(DeviceError::Frame)
}

/// `cmd` as its frame for controller `id` on prefix `bus`, with the
/// bridge's query; a held command (`hold`: its watchdog, s) carries that
/// watchdog where the command has none.
///
/// # Errors
/// The codec's refusal (a frame over 64 bytes).
pub(crate) fn command_frame(
    id: u8,
    bus: u16,
    cmd: &MoteusCommand,
    hold: Option<f64>,
) -> Result<Frame, DeviceError> {
    let command = match *cmd {
        MoteusCommand::Position(mut args) => {
            if args.watchdog_timeout.is_none() {
                args.watchdog_timeout = hold;
            }
            Command::Position(args)
        }
        MoteusCommand::Stop => Command::Stop,
        MoteusCommand::Brake => Command::Brake,
    };
    let call = Call {
        id,
        source: SOURCE,
        can_prefix: bus,
        command,
        query: true,
        query_override: None,
        resolutions: resolutions(),
    };
    let f = call.encode().map_err(DeviceError::MoteusCall)?;
    can_frame(f.can_id, &f.data)
}

/// The bridge's query for controller `id` on prefix `bus`.
pub(crate) fn query_frame(id: u8, bus: u16) -> Result<Frame, DeviceError> {
    let call = Call {
        id,
        source: SOURCE,
        can_prefix: bus,
        command: Command::Query,
        query: true,
        query_override: None,
        resolutions: resolutions(),
    };
    let f = call.encode().map_err(DeviceError::MoteusCall)?;
    can_frame(f.can_id, &f.data)
}

/// Whether `cmd` is held by the driver (sent again at each poll): a
/// position move, and any command that carries no watchdog of its own.
pub(crate) fn held(cmd: &MoteusCommand) -> bool {
    match cmd {
        MoteusCommand::Position(a) => {
            a.position.is_some_and(f64::is_finite) || a.watchdog_timeout.is_none()
        }
        MoteusCommand::Stop | MoteusCommand::Brake => false,
    }
}

/// Whose a reply from the bus is: `Some(true)` from controller (`id`,
/// `bus`) to the bridge, `Some(false)` the bridge's own frame to it
/// (heard back), `None` neither.
pub(crate) fn addressed(raw: u32, id: u8, bus: u16) -> Option<bool> {
    if (raw >> 16) & 0x1FFF != u32::from(bus) {
        return None;
    }
    let source = (raw >> 8) & 0x7F;
    let destination = raw & 0x7F;
    if source == u32::from(id) && destination == u32::from(SOURCE) {
        Some(true)
    } else if source == u32::from(SOURCE) && destination == u32::from(id) {
        Some(false)
    } else {
        None
    }
}

/// A reply read for controller `id`.
///
/// # Errors
/// The codec's refusal of the frame, as a bad-frame event says it.
pub(crate) fn reply(frame: &Frame) -> Result<Reply, DeviceError> {
    decode(frame.id().raw(), frame.data()).map_err(DeviceError::MoteusReply)
}

/// `r` if a controller could have sent it: its mode one of moteus's (0 to
/// 15). A reply in a mode no controller has is a bad frame: it neither
/// reports nor acknowledges anything.
///
/// # Errors
/// What is wrong with it, as a bad-frame event says it.
pub(crate) fn plausible(r: Reply) -> Result<Reply, DeviceError> {
    match r.get(0x000) {
        Some(motorwire_moteus::Scaled::Int(m)) if !(0..=15).contains(&m) => {
            Err(DeviceError::NoMoteusMode(m))
        }
        _ => Ok(r),
    }
}

/// What a reply says of the controller's own stop, if it stopped itself:
/// its fault by name, or its watchdog.
pub(crate) fn stopped_itself(r: &Reply) -> Option<(String, u16)> {
    match r.int(0x000)? {
        MODE_FAULT => {
            let code = r.int(0x00f).unwrap_or(0);
            Some((
                format!("moteus fault {code}: {}", fault_name(code)),
                u16::try_from(code).unwrap_or(0),
            ))
        }
        MODE_TIMEOUT => Some((
            "moteus watchdog timeout (mode 11): no command within its watchdog_timeout".to_owned(),
            11,
        )),
        _ => None,
    }
}

/// A reply's position and velocity in degrees, if it has them.
pub(crate) fn motion(r: &Reply) -> Option<(f64, f64)> {
    let (p, v) = (r.float(0x001)?, r.float(0x002)?);
    // NaN or an infinity is no position: the device's motion is unknown.
    (p.is_finite() && v.is_finite()).then_some((p * 360.0, v * 360.0))
}

/// A reply as WIA MotorFeedback (positions in the motor's own unit).
pub(crate) fn feedback_to_wia(
    motor: &str,
    timestamp: f64,
    unit: AngleUnit,
    r: &Reply,
) -> MotorFeedback {
    let mode = r.int(0x000);
    let in_unit = |rev: Option<f64>| rev.map_or(f64::NAN, |v| unit.from_degrees(v * 360.0));
    let mut f = MotorFeedback {
        motor_id: motor.to_owned(),
        timestamp,
        position: in_unit(r.float(0x001)),
        velocity: in_unit(r.float(0x002)),
        acceleration: None,
        torque: r.float(0x003).unwrap_or(f64::NAN),
        current: r.float(0x004),
        voltage: r.float(0x00d),
        temperature: r.float(0x00e),
        power: None,
        position_error: None,
        velocity_error: None,
        control_effort: None,
        status: motorwire_wia::MotorStatus::default(),
        health: None,
        extra: serde_json::Map::new(),
    };
    f.status.enabled = mode.map(|m| !matches!(m, 0 | MODE_FAULT | MODE_TIMEOUT | 15));
    f.status.fault = mode.map(|m| m == MODE_FAULT);
    f.status.warning = mode.map(|m| m == MODE_TIMEOUT);
    f.status.in_motion = r.float(0x002).map(|v| v.abs() > 1e-4);
    f.status.at_target = match (mode, r.int(0x00b)) {
        (Some(MODE_POSITION), Some(done)) => Some(done == 1),
        _ => None,
    };
    f
}

/// A controller's polling.
#[derive(Debug)]
struct Poll {
    /// Its id and bus.
    id: u8,
    bus: u16,
    next: Duration,
    period: Duration,
    /// The held command, sent in place of the query.
    hold: Option<PositionArgs>,
    /// The held command's "hold where it stands" form (position NaN,
    /// velocity 0, its torque limit), which replaces it once the controller
    /// reports its move complete, the limits change, or the bridge gives
    /// the command up.
    still: Option<PositionArgs>,
    /// The mode of its last reply.
    mode: Option<i64>,
    /// The torque limit in force (a SafetyLimits line's), which every
    /// frame carries at most.
    torque_cap: Option<f64>,
    /// The stop (or brake) last sent, repeated in place of the query
    /// until another command: a late copy of a frame sent before it (a
    /// bus that delays, duplicates or reorders) cannot move the
    /// controller on for more than a poll, and a reply that shows it in
    /// another mode is answered with the stop at once.
    stopping: Option<MoteusCommand>,
    /// Until when the stop is repeated every [`STOP_REPEAT`] rather than
    /// every poll: the time a frame sent before it may still be on its
    /// way (the watchdog a held move's frames carry).
    repeat_until: Duration,
    /// Replies that showed the controller moving again after its stop.
    pub(crate) resumed: u64,
    /// Its own position bounds, kept at the limits in force.
    bounds: OwnBounds,
}

impl Poll {
    /// How long to the next poll from `now`: [`STOP_REPEAT`] while a stop
    /// just sent is repeated, else the poll period.
    fn every(&self, now: Duration) -> Duration {
        if self.stopping.is_some() && now < self.repeat_until {
            self.period.min(STOP_REPEAT)
        } else {
            self.period
        }
    }

    /// `args` with at most the torque limit in force.
    fn capped(&self, mut args: PositionArgs) -> PositionArgs {
        if let Some(cap) = self.torque_cap {
            args.maximum_torque = Some(args.maximum_torque.map_or(cap, |t| t.min(cap)));
        }
        args
    }

    /// From now on, held where it stands (what was held made still), or
    /// nothing held.
    fn hold_still(&mut self) {
        self.hold = self
            .still
            .take()
            .or_else(|| self.hold.map(|h| still_of(&h)));
    }
}

/// `args` held where the controller stands: position NaN (its target where
/// it is), velocity 0, the same torque limit.
fn still_of(args: &PositionArgs) -> PositionArgs {
    PositionArgs {
        position: Some(f64::NAN),
        velocity: Some(0.0),
        maximum_torque: args.maximum_torque,
        ..PositionArgs::default()
    }
}

/// The moteus controllers' requests in flight, polls and frames to send,
/// by device.
#[derive(Debug)]
pub(crate) struct MoteusDriver {
    requests: FrameRequests,
    polls: BTreeMap<DeviceId, Poll>,
}

impl MoteusDriver {
    /// A driver whose commands wait `timeout` for their reply and are
    /// sent again up to `retries` times.
    pub(crate) fn new(timeout: Duration, retries: u8) -> Self {
        Self {
            requests: FrameRequests::new(timeout, retries),
            polls: BTreeMap::new(),
        }
    }

    /// Device `device`, controller `id` on `bus`, is polled every `period`
    /// from the start.
    pub(crate) fn poll_every(&mut self, device: DeviceId, id: u8, bus: u16, period: Duration) {
        self.polls.insert(
            device,
            Poll {
                id,
                bus,
                next: Duration::ZERO,
                period,
                hold: None,
                still: None,
                mode: None,
                torque_cap: None,
                stopping: None,
                repeat_until: Duration::ZERO,
                resumed: 0,
                bounds: OwnBounds::new(),
            },
        );
    }

    /// Queues `cmd` for `device` and awaits its reply; returns its id.
    ///
    /// # Errors
    /// [`command_frame`]'s; nothing is queued.
    pub(crate) fn send(
        &mut self,
        now: Duration,
        device: DeviceId,
        cmd: &MoteusCommand,
    ) -> Result<u32, DeviceError> {
        let Some(poll) = self.polls.get(&device) else {
            return Err(DeviceError::NotMoteus(device));
        };
        let (id, bus, period) = (poll.id, poll.bus, poll.period);
        let cmd = &match *cmd {
            MoteusCommand::Position(a) => MoteusCommand::Position(poll.capped(a)),
            other => other,
        };
        let frame = command_frame(id, bus, cmd, Some(hold_watchdog(period)))?;
        if let Some(p) = self.polls.get_mut(&device) {
            (p.hold, p.still) = match cmd {
                MoteusCommand::Position(a) if held(cmd) => (
                    Some(*a),
                    a.position.is_some_and(f64::is_finite).then(|| still_of(a)),
                ),
                _ => (None, None),
            };
            p.stopping = matches!(cmd, MoteusCommand::Stop | MoteusCommand::Brake).then_some(*cmd);
            p.repeat_until = if p.stopping.is_some() {
                now.saturating_add(Duration::from_secs_f64(hold_watchdog(p.period)))
            } else {
                Duration::ZERO
            };
            p.next = now.saturating_add(p.every(now));
        }
        Ok(self.requests.send(now, device, frame))
    }

    /// A reply came from `device` at `now`: the command it waited for, if
    /// any, is acknowledged.
    pub(crate) fn acknowledged(&mut self, device: DeviceId, now: Duration) -> Option<Ended> {
        self.requests.acknowledged(device, now)
    }

    /// `device`'s reply `r`, taken: whether its mode is a new one (the
    /// first reply's, or a change). A controller that stopped itself holds
    /// nothing any more; one whose move is complete is held where it
    /// stands from now on (its target is not sent again: a limit made
    /// tighter since may no longer allow it).
    pub(crate) fn observe(&mut self, device: DeviceId, r: &Reply) -> bool {
        let mode = r.int(0x000);
        let awaits = self.requests.awaits(device);
        let Some(p) = self.polls.get_mut(&device) else {
            return false;
        };
        let changed = p.mode != mode;
        p.mode = mode;
        if let Some(at) = r.float(0x001) {
            p.bounds.at(at);
        }
        // Stopped, and now in another mode (a late frame from before the
        // stop took it back): stopped again at once (when in doubt, stop).
        if let (Some(stop), Some(m)) = (p.stopping, mode)
            && !matches!(m, MODE_STOPPED | MODE_BRAKE | MODE_FAULT | MODE_TIMEOUT)
        {
            p.resumed += 1;
            if let Ok(f) = command_frame(p.id, p.bus, &stop, None) {
                self.requests.push(f);
            }
        }
        if matches!(mode, Some(MODE_FAULT | MODE_TIMEOUT)) {
            p.hold = None;
            p.still = None;
        } else if mode == Some(MODE_POSITION)
            && r.int(0x00b) == Some(1)
            && !awaits
            && p.still.is_some()
        {
            p.hold_still();
        }
        changed
    }

    /// `device`'s command is given up (its reply no longer awaited): a
    /// held command is held still from now on (when in doubt, stop).
    pub(crate) fn forget(&mut self, device: DeviceId) {
        self.requests.forget(device);
        if let Some(p) = self.polls.get_mut(&device) {
            p.hold_still();
        }
    }

    /// The limits in force on `device` changed to `limits` (degrees, Nm):
    /// a held move they no longer allow (its target outside them, or its
    /// velocity limit above theirs: the engine takes a line only once the
    /// move it would break has ended, but the controller may not have said
    /// so yet) is held where it stands, never sent again; and every frame
    /// from now on, held or new, carries at most their torque limit.
    pub(crate) fn limits_changed(&mut self, device: DeviceId, limits: &super::InForce) {
        let Some(p) = self.polls.get_mut(&device) else {
            return;
        };
        let rev = |deg: Option<f64>| deg.map_or(f64::NAN, |d| d / 360.0);
        p.bounds
            .want(rev(limits.min_position), rev(limits.max_position));
        p.torque_cap = limits.max_torque;
        let broken = p.hold.is_some_and(|h| {
            let outside = h.position.filter(|x| x.is_finite()).is_some_and(|x| {
                let deg = x * 360.0;
                limits.min_position.is_some_and(|lo| deg < lo - 1e-6)
                    || limits.max_position.is_some_and(|hi| deg > hi + 1e-6)
            });
            let faster = h
                .velocity_limit
                .or(h
                    .velocity
                    .filter(|v| v.is_finite() && !h.position.is_some_and(f64::is_finite)))
                .is_some_and(|v| {
                    limits
                        .max_velocity
                        .is_some_and(|m| v.abs() * 360.0 > m + 1e-6)
                });
            outside || faster
        });
        if broken {
            p.hold_still();
        }
    }

    /// `device`'s command, if its first sending is still queued: taken out
    /// of the queue and forgotten (and no longer held). Whether it was.
    pub(crate) fn take_back_unsent(&mut self, device: DeviceId) -> bool {
        if !self.requests.take_back_unsent(device) {
            return false;
        }
        if let Some(poll) = self.polls.get_mut(&device) {
            poll.hold = None;
            poll.still = None;
        }
        true
    }

    /// Commands whose reply is overdue at `now`: each sent again until its
    /// retries are spent; those given up, by device.
    /// A command given up is held still from now on, as [`Self::forget`].
    pub(crate) fn timeouts(&mut self, now: Duration) -> Vec<(DeviceId, Ended)> {
        let ended = self.requests.timeouts(now);
        for (device, _) in &ended {
            if let Some(p) = self.polls.get_mut(device) {
                p.hold_still();
            }
        }
        ended
    }

    /// The polls due at `now`: each controller without a command in
    /// flight is sent its held command or the query.
    pub(crate) fn polls_due(&mut self, now: Duration) {
        for (&device, p) in &mut self.polls {
            if p.next > now {
                continue;
            }
            let every = p.every(now);
            let next = p.next.saturating_add(every);
            p.next = if next > now {
                next
            } else {
                now.saturating_add(every)
            };
            // The controller's own bounds: text to write and answers to
            // read go beside the poll, whatever is in flight (they ask for
            // no register and acknowledge nothing).
            for f in p.bounds.frames(now, p.id, p.bus) {
                if let Ok(f) = can_frame(f.can_id, &f.data) {
                    self.requests.push(f);
                }
            }
            if self.requests.awaits(device) {
                continue;
            }
            let frame = match (&p.hold, p.stopping) {
                (Some(h), _) => command_frame(
                    p.id,
                    p.bus,
                    &MoteusCommand::Position(p.capped(*h)),
                    Some(hold_watchdog(p.period)),
                ),
                (None, Some(stop)) => command_frame(p.id, p.bus, &stop, None),
                (None, None) => query_frame(p.id, p.bus),
            };
            if let Ok(f) = frame {
                self.requests.push(f);
            }
        }
    }

    /// An answer on `device`'s diagnostic stream, at `now`.
    pub(crate) fn diagnostic_answer(
        &mut self,
        device: DeviceId,
        now: Duration,
        answer: &motorwire_moteus::diagnostic::Answer,
    ) {
        if let Some(p) = self.polls.get_mut(&device) {
            p.bounds.answer(now, answer);
        }
    }

    /// What became of each controller's own bounds since last asked.
    pub(crate) fn bounds_news(&mut self) -> Vec<(DeviceId, BoundsNews)> {
        let mut out = Vec::new();
        for (&device, p) in &mut self.polls {
            out.extend(p.bounds.take_news().into_iter().map(|n| (device, n)));
        }
        out
    }

    /// `device`'s own bounds taken as read and set, nothing more asked
    /// (for tests of the rest of the driver's frames).
    #[cfg(test)]
    pub(crate) fn bounds_settled(&mut self, device: DeviceId) {
        if let Some(p) = self.polls.get_mut(&device) {
            p.bounds = OwnBounds::settled();
        }
    }

    /// The next reply deadline or poll (the engine reads the two apart,
    /// as timers of their own).
    #[cfg(test)]
    pub(crate) fn deadline(&self) -> Option<Duration> {
        [self.requests_deadline(), self.polls_deadline()]
            .into_iter()
            .flatten()
            .min()
    }

    /// The next resend or time-out of a request in flight.
    pub(crate) fn requests_deadline(&self) -> Option<Duration> {
        self.requests.deadline()
    }

    /// The next controller's poll.
    pub(crate) fn polls_deadline(&self) -> Option<Duration> {
        self.polls.values().map(|p| p.next).min()
    }

    /// The next frame to send.
    pub(crate) fn poll_transmit(&mut self) -> Option<Frame> {
        self.requests.poll_transmit()
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing, clippy::panic)]
    use super::*;
    use crate::device::Outcome;

    fn position(p: f64) -> MoteusCommand {
        MoteusCommand::Position(PositionArgs {
            position: Some(p),
            velocity: Some(0.0),
            velocity_limit: Some(0.5),
            ..PositionArgs::default()
        })
    }

    /// The frames are the ones mjbots' Python library builds for the same
    /// calls (moteus 1.1.1: `Controller(2, can_prefix=1, query_resolution=qr)`
    /// with `qr.q_current = F32`, `qr.trajectory_complete = INT8`), padded
    /// with 0x50 as its transports pad.
    #[test]
    fn frames_are_the_librarys_padded() {
        // make_position(position=0.25, velocity=0.0, velocity_limit=0.5,
        // watchdog_timeout=0.3, query=True)
        let f = command_frame(2, 1, &position(0.25), Some(0.3)).unwrap();
        assert_eq!(f.id().raw(), 0x0001_8002);
        assert_eq!(
            motorwire_moteus::hex(f.data()),
            "01000a0e200000803e000000000e279a99993e0000003f11001c0401110b130d"
        );
        // make_stop(query=True): 12 bytes, an FD length.
        let f = command_frame(2, 1, &MoteusCommand::Stop, None).unwrap();
        assert_eq!(motorwire_moteus::hex(f.data()), "01000011001c0401110b130d");
        // make_query(): 9 bytes, padded to 12.
        let f = query_frame(2, 1).unwrap();
        assert_eq!(f.id().raw(), 0x0001_8002);
        assert_eq!(motorwire_moteus::hex(f.data()), "11001c0401110b130d505050");
    }

    #[test]
    fn a_held_move_is_sent_again_at_each_poll_and_a_reply_acknowledges() {
        let ms = Duration::from_millis;
        let mut d = MoteusDriver::new(ms(100), 1);
        d.poll_every(DeviceId(0), 1, 0, ms(20));
        d.bounds_settled(DeviceId(0));
        d.polls_due(ms(0));
        let q = d.poll_transmit().unwrap();
        assert_eq!(q, query_frame(1, 0).unwrap());
        let id = d.send(ms(5), DeviceId(0), &position(0.1)).unwrap();
        let sent = d.poll_transmit().unwrap();
        // Not polled while the command waits.
        d.polls_due(ms(25));
        assert_eq!(d.poll_transmit(), None);
        assert_eq!(
            d.acknowledged(DeviceId(0), ms(26))
                .map(|e| (e.msg_id, e.outcome)),
            Some((id, Outcome::Acked))
        );
        // Held: the move itself at the next poll, not the query.
        d.polls_due(ms(45));
        assert_eq!(d.poll_transmit(), Some(sent));
        // Complete (mode 10, trajectory complete): held where it stands.
        let done = Frame::fd(
            CanId::extended(0x100).unwrap(),
            &[0x21, 0x00, 0x0a, 0x21, 0x0b, 0x01],
        )
        .unwrap();
        assert!(d.observe(DeviceId(0), &reply(&done).unwrap()));
        d.polls_due(ms(47));
        d.polls_due(ms(65));
        let still = d.poll_transmit().unwrap();
        assert_ne!(still, sent);
        let r = decode(still.id().raw(), still.data()).unwrap();
        assert!(r.values.is_empty(), "a command, not a reply");
        assert!(motorwire_moteus::hex(still.data()).starts_with("01000a0e200000c07f00000000"));
        // A stop is sent again in place of the query: every 5 ms while
        // a frame from before it may still come, then at each poll.
        d.send(ms(50), DeviceId(0), &MoteusCommand::Stop).unwrap();
        let stop = d.poll_transmit().unwrap();
        assert_eq!(
            stop,
            command_frame(1, 0, &MoteusCommand::Stop, None).unwrap()
        );
        d.acknowledged(DeviceId(0), ms(51));
        d.polls_due(ms(55));
        assert_eq!(d.poll_transmit(), Some(stop));
        assert_eq!(d.deadline(), Some(ms(60)));
        // A reply in position mode after it (a late frame took the
        // controller on): the stop again at once.
        let moving = Frame::fd(CanId::extended(0x100).unwrap(), &[0x21, 0x00, 0x0a]).unwrap();
        d.observe(DeviceId(0), &reply(&moving).unwrap());
        assert_eq!(d.poll_transmit(), Some(stop));
        assert_eq!(d.polls[&DeviceId(0)].resumed, 1);
        // Stopped: no second stop at once; past the watchdog, each poll.
        let stopped = Frame::fd(CanId::extended(0x100).unwrap(), &[0x21, 0x00, 0x00]).unwrap();
        d.observe(DeviceId(0), &reply(&stopped).unwrap());
        assert_eq!(d.poll_transmit(), None);
        d.polls_due(ms(400));
        assert_eq!(d.poll_transmit(), Some(stop));
        assert_eq!(d.deadline(), Some(ms(420)));
        // Unanswered: sent again once, then given up.
        d.send(ms(80), DeviceId(0), &position(0.2)).unwrap();
        d.poll_transmit();
        assert_eq!(d.timeouts(ms(180)), []);
        assert!(d.poll_transmit().is_some());
        assert_eq!(d.timeouts(ms(280)).len(), 1);
    }

    #[test]
    fn replies_are_addressed_and_read() {
        assert_eq!(addressed(0x0001_0200, 2, 1), Some(true));
        assert_eq!(addressed(0x0001_8002, 2, 1), Some(false));
        assert_eq!(addressed(0x0000_0200, 2, 1), None);
        assert_eq!(addressed(0x0001_0300, 2, 1), None);
        // Mode 1 (fault) with fault 39; then mode 11.
        let fault = Frame::fd(
            CanId::extended(0x200).unwrap(),
            &[0x21, 0x00, 0x01, 0x21, 0x0f, 39, 0x50, 0x50],
        )
        .unwrap();
        let r = reply(&fault).unwrap();
        assert_eq!(
            stopped_itself(&r),
            Some(("moteus fault 39: outside limit".to_owned(), 39))
        );
        let timeout = Frame::fd(CanId::extended(0x200).unwrap(), &[0x21, 0x00, 11]).unwrap();
        assert_eq!(
            stopped_itself(&reply(&timeout).unwrap()).map(|s| s.1),
            Some(11)
        );
        // Position 0.25 rev and velocity -0.5 rev/s as f32, in radians.
        let mut data = vec![0x2e, 0x01];
        data.extend_from_slice(&0.25f32.to_le_bytes());
        data.extend_from_slice(&(-0.5f32).to_le_bytes());
        let r = reply(&Frame::fd(CanId::extended(0x200).unwrap(), &data).unwrap()).unwrap();
        assert_eq!(motion(&r), Some((90.0, -180.0)));
        // Found by a hostile test: a NaN position was a motion (a trajectory
        // "starting where the joint stands" was taken at NaN).
        let mut nan = vec![0x2e, 0x01];
        nan.extend_from_slice(&f32::NAN.to_le_bytes());
        nan.extend_from_slice(&0f32.to_le_bytes());
        let unknown = reply(&Frame::fd(CanId::extended(0x200).unwrap(), &nan).unwrap()).unwrap();
        assert_eq!(motion(&unknown), None);
        // A mode no controller has is a bad frame.
        let odd = reply(&Frame::fd(CanId::extended(0x200).unwrap(), &[0x21, 0x00, 0xff]).unwrap())
            .unwrap();
        assert_eq!(
            plausible(odd).unwrap_err().to_string(),
            "mode -1 is no moteus mode (0 to 15)"
        );
        let f = feedback_to_wia("knee", 1.0, AngleUnit::Radians, &r);
        assert!((f.position - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        assert!((f.velocity + std::f64::consts::PI).abs() < 1e-12);
    }
}

#[cfg(test)]
mod hold_tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;
    use motorwire_moteus::Scaled;
    use motorwire_moteus::protocol::{Subframe, SubframeType, parse_frame};

    /// The position (revolutions) and torque limit a frame writes.
    fn written(f: &Frame) -> (Option<f64>, Option<f64>) {
        let mut out = (None, None);
        for s in parse_frame(f.data()) {
            if let Subframe::Register {
                subframe_type: SubframeType::Write,
                register,
                value: Some(v),
                ..
            } = s
            {
                let Ok(Scaled::Float(x)) = motorwire_moteus::scale(register, v) else {
                    continue;
                };
                match register {
                    0x020 => out.0 = Some(x),
                    0x025 => out.1 = Some(x),
                    _ => {}
                }
            }
        }
        out
    }

    fn driver() -> MoteusDriver {
        let mut d = MoteusDriver::new(Duration::from_millis(100), 1);
        d.poll_every(DeviceId(0), 1, 0, Duration::from_millis(20));
        d.bounds_settled(DeviceId(0));
        d
    }

    fn hip_to_50() -> MoteusCommand {
        MoteusCommand::Position(PositionArgs {
            position: Some(50.0 / 360.0),
            velocity: Some(0.0),
            velocity_limit: Some(10.0 / 360.0),
            maximum_torque: Some(3.0),
            ..PositionArgs::default()
        })
    }

    /// The register frame a poll at `ms` sends (the frames of the
    /// controller's own bounds, which go beside it, passed over).
    fn poll(d: &mut MoteusDriver, ms: u64) -> Frame {
        d.polls_due(Duration::from_millis(ms));
        loop {
            let f = d.poll_transmit().unwrap();
            if !matches!(f.data().first(), Some(0x40 | 0x42)) {
                return f;
            }
        }
    }

    /// Found by a hostile test: a SafetyLimits line taken (max 20) while a
    /// held move to 50 was still sent again at each poll sent 50 after the
    /// line's result; its torque limit (2) did not bind what was held.
    #[test]
    fn new_limits_make_a_held_move_still_and_cap_its_torque() {
        let mut d = driver();
        d.send(Duration::ZERO, DeviceId(0), &hip_to_50()).unwrap();
        d.poll_transmit();
        d.acknowledged(DeviceId(0), Duration::from_millis(1));
        // The frame's f32 of 50/360 revolution.
        #[allow(clippy::cast_possible_truncation)]
        let fifty = f64::from((50.0f64 / 360.0) as f32);
        assert_eq!(written(&poll(&mut d, 20)), (Some(fifty), Some(3.0)));
        // Limits that still allow it: the move goes on, its torque capped.
        let allow = crate::device::InForce {
            min_position: Some(-60.0),
            max_position: Some(60.0),
            max_velocity: Some(60.0),
            max_torque: Some(2.0),
        };
        d.limits_changed(DeviceId(0), &allow);
        assert_eq!(written(&poll(&mut d, 40)), (Some(fifty), Some(2.0)));
        // Found by a hostile test: the next move (a trajectory's segment)
        // went out with the old torque limit.
        d.send(Duration::from_millis(45), DeviceId(0), &hip_to_50())
            .unwrap();
        assert_eq!(written(&d.poll_transmit().unwrap()).1, Some(2.0));
        d.acknowledged(DeviceId(0), Duration::from_millis(46));
        // Limits that do not: held where it stands.
        d.limits_changed(
            DeviceId(0),
            &crate::device::InForce {
                max_position: Some(20.0),
                ..allow
            },
        );
        let (position, torque) = written(&poll(&mut d, 80));
        assert!(position.unwrap().is_nan());
        assert_eq!(torque, Some(2.0));
    }

    /// Found by a hostile test: a move given up (never answered) was still
    /// sent again at each poll after its line was answered
    /// `outcome_unknown`.
    #[test]
    fn a_move_given_up_or_forgotten_is_held_still() {
        let mut d = driver();
        d.send(Duration::ZERO, DeviceId(0), &hip_to_50()).unwrap();
        d.poll_transmit();
        assert_eq!(d.timeouts(Duration::from_millis(100)), []);
        d.poll_transmit();
        assert_eq!(d.timeouts(Duration::from_millis(200)).len(), 1);
        assert!(written(&poll(&mut d, 220)).0.unwrap().is_nan());
        d.send(Duration::from_millis(230), DeviceId(0), &hip_to_50())
            .unwrap();
        d.poll_transmit();
        d.forget(DeviceId(0));
        assert!(written(&poll(&mut d, 260)).0.unwrap().is_nan());
    }
}
