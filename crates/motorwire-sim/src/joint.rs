//! A simulated iRPC joint.
//!
//! Sans-IO like the client: [`SimJoint::handle_frame`] and
//! [`SimJoint::handle_timeout`] take frames and the time,
//! [`SimJoint::poll_transmit`] gives frames to send, and
//! [`SimJoint::poll_timeout`] says when it next needs the time. [`SimJoint::run`]
//! drives it on a blocking bus in real time.
//!
//! ## Behaviour
//!
//! - **Lifecycle** (the document's): `Configure` takes Unconfigured or
//!   Inactive to Inactive (else Nack 1); `Activate` takes Inactive or Active
//!   to Active (else Nack 2); `Deactivate` takes Active or Inactive to
//!   Inactive, braking any motion (else Nack 3); `Reset` brakes and returns
//!   to Unconfigured from any state. Motion commands only when Active (else
//!   Nack 4).
//! - **Motion**: `SetTargetV2` is answered with **Ack** (the public firmware
//!   Nacks it and moves anyway) and planned by motorwire-planner from the
//!   joint's current position and velocity, with every limit it carries
//!   (`max_deceleration <= 0` means "as `max_acceleration`"; `max_jerk <= 0`
//!   means no jerk limit). v1 `SetTarget` moves trapezoidally at its velocity
//!   limit and the joint's acceleration limit.
//! - **Refusals**: a target outside `[min_angle, max_angle]`, a limit above
//!   the joint's own or not positive, or a plan that would leave the range
//!   (a replan from high speed that must overshoot) is `Nack 16`; a message
//!   carrying NaN or infinity is `Nack 17` (the header is still read). A
//!   payload the joint does not handle is `Nack 255`. A frame that does not
//!   decode at all is dropped and counted in [`JointStats::bad_frames`]: its
//!   msg_id cannot be trusted, and the client will send it again.
//! - **Duplicates**: the answers to the last [`DEDUP_WINDOW`] (256)
//!   requests of each sender (up to [`MAX_SENDERS`], the longest silent
//!   forgotten first) are kept by msg_id; a repeat is answered the same way
//!   and never executed again. A client that keeps at most one request in
//!   flight per joint (motorwire's does) can only resend a request within
//!   that window, so no resend is ever executed twice.
//! - **Stale requests**: a request whose msg_id comes before the sender's
//!   last lifecycle request (Configure, Activate, Deactivate, Reset) is
//!   refused `Nack 19` and not executed: a late copy of a move sent before
//!   an emergency stop cannot run after the stop or after its release.
//!   So is a request older than every answer remembered while the memory
//!   is full (a late copy whose first answer was forgotten: an anti-replay
//!   window, as IPsec keeps). msg_ids are compared as serial numbers (RFC
//!   1982); a Configure or Reset more than [`RESTART_SPAN`] behind the last
//!   lifecycle request is a sender that started again, whose memory is
//!   forgotten.
//! - **Watchdog**: while moving, a joint that hears nothing from its host for
//!   [`JointConfig::watchdog`] (200 ms) brakes to a stop at its acceleration
//!   limit and reports [`WATCHDOG_STOP`] in `JointStatus.error_code` until
//!   the next motion command. Any frame addressed to it counts, so a host
//!   keeps a long move alive by re-sending it (an identical `SetTargetV2`
//!   during its own motion, or after it completed with nothing since, is
//!   acked and does not replan).
//! - **Feedback**: `Encoder` every [`JointConfig::encoder_period`] once
//!   configured, `JointStatus` every [`JointConfig::status_period`] and on
//!   every state change, and from v2.1 `TelemetryStream` at the rate a
//!   `ConfigureTelemetry` asks (`OnChange` and `Adaptive` are sent at that
//!   rate too) or once per `RequestTelemetry`. Feedback goes to the last
//!   node that commanded the joint (the arm, 0x0000, before any).
//!
//! ```
//! use std::time::Duration;
//! use motorwire_can::{CanBus, SimBus, client::{Client, ClientConfig, Event, Outcome}};
//! use motorwire_irpc::{MotionProfile, SetTargetPayloadV2};
//! use motorwire_sim::{JointConfig, SimJoint};
//!
//! let bus = SimBus::default();
//! let mut joint = SimJoint::new(JointConfig::new(0x10))?;
//! let mut client = Client::new(ClientConfig::default())?;
//! let (mut arm_port, mut joint_port) = (bus.port(), bus.port());
//!
//! // One step of a deterministic simulation: everyone handles what is due.
//! let mut step = |client: &mut Client, joint: &mut SimJoint| -> Result<(), motorwire_can::Error> {
//!     let now = bus.now();
//!     while let Some(f) = client.poll_transmit() { arm_port.send(&f)?; }
//!     while let Some(r) = joint_port.try_recv() { joint.handle_frame(now, &r.frame); }
//!     joint.handle_timeout(now);
//!     while let Some(f) = joint.poll_transmit() { joint_port.send(&f)?; }
//!     while let Some(r) = arm_port.try_recv() { client.handle_frame(now, &r.frame); }
//!     client.handle_timeout(now);
//!     bus.advance_to(now + Duration::from_millis(1));
//!     Ok(())
//! };
//! for payload in [motorwire_irpc::Payload::Configure, motorwire_irpc::Payload::Activate] {
//!     client.request(bus.now(), 0x10, payload)?;
//!     step(&mut client, &mut joint)?;
//! }
//! client.set_target_v2(bus.now(), 0x10, SetTargetPayloadV2 {
//!     target_angle: 90.0, max_velocity: 100.0, target_velocity: 0.0,
//!     max_acceleration: 500.0, max_deceleration: 500.0, max_jerk: 2000.0,
//!     profile: MotionProfile::SCurve, max_current: 0.0, max_temperature: 0.0,
//! })?;
//! // 1.35 s of motion, the host re-sending nothing: the watchdog would brake
//! // it, so this joint's watchdog is long enough for the example.
//! # joint.set_watchdog(Duration::from_secs(5));
//! for _ in 0..1400 { step(&mut client, &mut joint)?; }
//! assert_eq!(joint.position(), 90.0);
//! let acked = std::iter::from_fn(|| client.poll_event())
//!     .filter(|e| matches!(e, Event::Completed(c) if c.outcome == Outcome::Acked))
//!     .count();
//! assert_eq!(acked, 3);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use std::collections::{HashMap, VecDeque};
use std::sync::atomic::AtomicBool;
use std::time::Duration;

use motorwire_can::client::ARM_NODE;
use motorwire_can::{CanBus, CanId, Frame, SimPort};
use motorwire_irpc::{
    EmergencyReason, EmergencyStop, EncoderTelemetry, Error as WireError, Header, LifecycleState,
    MAX_FRAME_LEN, Message, MotionProfile, NackCode, Payload, SetTargetPayloadV2, TelemetryMode,
    TelemetryStream, WireVersion,
};
use motorwire_planner::Profile;

use crate::SimError;

/// `JointStatus.error_code` after the watchdog braked a motion.
pub const WATCHDOG_STOP: u16 = 1;

/// How many answered requests of each sender are remembered for duplicate
/// suppression.
pub const DEDUP_WINDOW: usize = 256;

/// How many senders' answers are remembered (the longest silent is
/// forgotten first).
pub const MAX_SENDERS: usize = 8;

/// How far (in msg_ids) behind its last lifecycle request a sender's
/// request may be before it counts as a sender that started again rather
/// than a late copy.
pub const RESTART_SPAN: u32 = 1 << 16;

/// What the joint remembers of one sender.
#[derive(Debug, Default)]
struct Sender {
    answers: HashMap<u32, Payload>,
    order: VecDeque<u32>,
    /// The msg_id of its last lifecycle request.
    epoch: Option<u32>,
    last_heard: Duration,
}

/// `a` comes before `b` as serial numbers (RFC 1982).
fn serial_before(a: u32, b: u32) -> bool {
    let d = b.wrapping_sub(a);
    d != 0 && d < (1 << 31)
}

fn is_lifecycle(p: &Payload) -> bool {
    matches!(
        p,
        Payload::Configure | Payload::Activate | Payload::Deactivate | Payload::Reset
    )
}

/// The joint's own limits (degrees, deg/s, deg/s², deg/s³).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointLimits {
    /// Lowest position.
    pub min_angle: f32,
    /// Highest position.
    pub max_angle: f32,
    /// Fastest speed.
    pub max_velocity: f32,
    /// Largest acceleration and deceleration.
    pub max_acceleration: f32,
    /// Largest jerk.
    pub max_jerk: f32,
}

impl Default for JointLimits {
    /// ±180°, 360 deg/s, 5000 deg/s², 100000 deg/s³.
    fn default() -> Self {
        Self {
            min_angle: -180.0,
            max_angle: 180.0,
            max_velocity: 360.0,
            max_acceleration: 5000.0,
            max_jerk: 100_000.0,
        }
    }
}

/// How a [`SimJoint`] is built.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointConfig {
    /// Its node id (and the CAN id of its frames).
    pub node_id: u16,
    /// The wire version it speaks.
    pub wire: WireVersion,
    /// Its limits.
    pub limits: JointLimits,
    /// Brake when nothing was heard for this long while moving (zero: never).
    pub watchdog: Duration,
    /// The deceleration a Deactivate or Reset brakes at (deg/s², > 0): a
    /// stop is physical, not instant. 1000 deg/s² by default (a joint at
    /// 100 deg/s stops within 0.1 s and 5°); the watchdog brakes at
    /// `limits.max_acceleration`.
    pub emergency_deceleration: f32,
    /// Encoder feedback period (zero: none).
    pub encoder_period: Duration,
    /// JointStatus period (zero: only on changes).
    pub status_period: Duration,
    /// Where it starts (degrees).
    pub initial_position: f32,
}

impl JointConfig {
    /// Node `node_id`, v2.0, default limits, 200 ms watchdog, Encoder every
    /// 10 ms, JointStatus every 100 ms, starting at 0°.
    pub fn new(node_id: u16) -> Self {
        Self {
            node_id,
            wire: WireVersion::V2_0,
            limits: JointLimits::default(),
            watchdog: Duration::from_millis(200),
            emergency_deceleration: 1000.0,
            encoder_period: Duration::from_millis(10),
            status_period: Duration::from_millis(100),
            initial_position: 0.0,
        }
    }
}

/// A fault [`SimJoint::fault`] makes happen.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum JointFault {
    /// The motor overheated (v2.2 `EmergencyStop`, error code 4).
    Overtemperature,
    /// The motor driver failed (v2.2 `EmergencyStop`, error code 5).
    DriverFault,
    /// The joint's controller started again (power glitch, watchdog).
    Reboot,
}

/// What the joint has done.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct JointStats {
    /// Requests answered Ack.
    pub acked: u64,
    /// Requests answered Nack.
    pub nacked: u64,
    /// Motion commands executed (planned and started).
    pub executed: u64,
    /// Repeated requests answered again without executing.
    pub duplicates: u64,
    /// Requests from before their sender's last lifecycle request, refused
    /// (Nack 19) without executing.
    pub stale: u64,
    /// Frames that did not decode, dropped.
    pub bad_frames: u64,
    /// Motions braked by the watchdog.
    pub watchdog_stops: u64,
    /// Feedback messages too large for one frame, not sent.
    pub oversized: u64,
}

/// A request the joint acted on (the first time it saw its msg_id), as its
/// log keeps it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Execution {
    /// Who sent it.
    pub source: u16,
    /// Its msg_id.
    pub msg_id: u32,
    /// What it asked.
    pub payload: Payload,
    /// How the joint answered: `Ack` or `Nack`.
    pub answer: Payload,
    /// When.
    pub at: Duration,
}

#[derive(Debug, Clone, Copy)]
#[allow(clippy::large_enum_variant)] // one per joint, never moved in a hot loop
enum Motion {
    Holding,
    Profile {
        profile: Profile<f64>,
        start: Duration,
    },
    Braking {
        start: Duration,
        position: f64,
        velocity: f64,
        deceleration: f64,
    },
}

/// A simulated iRPC joint (see the [module docs](self)).
#[derive(Debug)]
pub struct SimJoint {
    config: JointConfig,
    can_id: CanId,
    state: LifecycleState,
    error_code: u16,
    motion: Motion,
    /// The motion command being executed, or completed with nothing since.
    current: Option<SetTargetPayloadV2>,
    position: f64,
    velocity: f64,
    acceleration: f64,
    now: Duration,
    host: u16,
    last_heard: Duration,
    senders: HashMap<u16, Sender>,
    out: VecDeque<Frame>,
    next_msg_id: u32,
    next_encoder: Duration,
    next_status: Duration,
    telemetry_period: Option<Duration>,
    next_telemetry: Duration,
    stats: JointStats,
    log: Option<Vec<Execution>>,
}

fn positive_finite(x: f32) -> bool {
    x.is_finite() && x > 0.0
}

impl SimJoint {
    /// A joint, Unconfigured, at rest at its initial position.
    ///
    /// # Errors
    /// [`SimError::InvalidConfig`] for a node id above 0x7FF, limits that are
    /// not finite, positive and ordered, or a start outside them.
    pub fn new(config: JointConfig) -> Result<Self, SimError> {
        let can_id = CanId::standard(config.node_id).map_err(|e| SimError::InvalidConfig {
            field: "node_id",
            reason: e.to_string(),
        })?;
        let l = config.limits;
        let bad = |field: &'static str, reason: &str| {
            Err(SimError::InvalidConfig {
                field,
                reason: reason.to_owned(),
            })
        };
        if !(l.min_angle.is_finite() && l.max_angle.is_finite() && l.min_angle < l.max_angle) {
            return bad(
                "limits",
                "min_angle and max_angle must be finite with min < max",
            );
        }
        for (field, v) in [
            ("limits.max_velocity", l.max_velocity),
            ("limits.max_acceleration", l.max_acceleration),
            ("limits.max_jerk", l.max_jerk),
            ("emergency_deceleration", config.emergency_deceleration),
        ] {
            if !positive_finite(v) {
                return bad(field, "must be finite and positive");
            }
        }
        if !(l.min_angle..=l.max_angle).contains(&config.initial_position) {
            return bad("initial_position", "must lie within the limits");
        }
        Ok(Self {
            config,
            can_id,
            state: LifecycleState::Unconfigured,
            error_code: 0,
            motion: Motion::Holding,
            current: None,
            position: f64::from(config.initial_position),
            velocity: 0.0,
            acceleration: 0.0,
            now: Duration::ZERO,
            host: ARM_NODE,
            last_heard: Duration::ZERO,
            senders: HashMap::new(),
            out: VecDeque::new(),
            next_msg_id: 1,
            next_encoder: Duration::ZERO,
            next_status: Duration::ZERO,
            telemetry_period: None,
            next_telemetry: Duration::ZERO,
            stats: JointStats::default(),
            log: None,
        })
    }

    /// Keeps a log of every request acted on (for tests; it grows).
    pub fn keep_log(&mut self) {
        self.log.get_or_insert_with(Vec::new);
    }

    /// The requests acted on, oldest first, if [`SimJoint::keep_log`] was called.
    pub fn log(&self) -> &[Execution] {
        self.log.as_deref().unwrap_or(&[])
    }

    /// Changes the watchdog timeout (zero: off).
    pub fn set_watchdog(&mut self, timeout: Duration) {
        self.config.watchdog = timeout;
    }

    /// The configuration.
    pub fn config(&self) -> &JointConfig {
        &self.config
    }

    /// The lifecycle state.
    pub fn state(&self) -> LifecycleState {
        self.state
    }

    /// Position (degrees) at the last time handled.
    pub fn position(&self) -> f64 {
        self.position
    }

    /// Velocity (deg/s) at the last time handled.
    pub fn velocity(&self) -> f64 {
        self.velocity
    }

    /// Whether a motion (or a brake) is in progress.
    pub fn is_moving(&self) -> bool {
        !matches!(self.motion, Motion::Holding)
    }

    /// The counters.
    pub fn stats(&self) -> JointStats {
        self.stats
    }

    /// Where the joint is at `t` (degrees) on the motion it runs now, without
    /// advancing it: [`SimJoint::position`] is as of the last event it
    /// handled (an Encoder tick at most 10 ms ago), this is exact. For a
    /// `t` before its last event, the position then.
    pub fn position_at(&self, t: Duration) -> f64 {
        let t = t.max(self.now);
        match self.motion {
            Motion::Holding => self.position,
            Motion::Profile { profile, start } => {
                let s = t
                    .saturating_sub(start)
                    .as_secs_f64()
                    .min(profile.duration());
                profile.sample(s).position
            }
            Motion::Braking {
                start,
                position,
                velocity,
                deceleration,
            } => {
                let stop = velocity.abs() / deceleration;
                let s = t.saturating_sub(start).as_secs_f64().min(stop);
                let a = -velocity.signum() * deceleration;
                position + velocity * s + a * s * s / 2.0
            }
        }
    }

    /// Advances the motion to `now`.
    fn update(&mut self, now: Duration) {
        self.now = self.now.max(now);
        let now = self.now;
        match self.motion {
            Motion::Holding => {
                self.velocity = 0.0;
                self.acceleration = 0.0;
            }
            Motion::Profile { profile, start, .. } => {
                let t = now.saturating_sub(start).as_secs_f64();
                let s = profile.sample(t);
                self.position = s.position;
                self.velocity = s.velocity;
                self.acceleration = s.acceleration;
                if t >= profile.duration() {
                    self.motion = Motion::Holding;
                }
            }
            Motion::Braking {
                start,
                position,
                velocity,
                deceleration,
            } => {
                let stop = velocity.abs() / deceleration;
                let t = now.saturating_sub(start).as_secs_f64().min(stop);
                let a = -velocity.signum() * deceleration;
                self.position = position + velocity * t + a * t * t / 2.0;
                self.velocity = velocity + a * t;
                self.acceleration = a;
                if t >= stop {
                    self.velocity = 0.0;
                    self.acceleration = 0.0;
                    self.motion = Motion::Holding;
                }
            }
        }
    }

    fn brake(&mut self, deceleration: f32) {
        self.current = None;
        if matches!(self.motion, Motion::Holding) {
            return;
        }
        self.motion = if self.velocity == 0.0 {
            Motion::Holding
        } else {
            Motion::Braking {
                start: self.now,
                position: self.position,
                velocity: self.velocity,
                deceleration: f64::from(deceleration),
            }
        };
    }

    fn emit(&mut self, target: u16, msg_id: u32, payload: Payload) {
        let message = Message {
            header: Header {
                source_id: self.config.node_id,
                target_id: target,
                msg_id,
            },
            payload,
        };
        let mut buf = [0u8; MAX_FRAME_LEN];
        match message.encode_frame(self.config.wire, &mut buf) {
            Ok(len) => {
                if let Ok(f) = Frame::fd(self.can_id, buf.get(..len).unwrap_or(&buf)) {
                    self.out.push_back(f);
                }
            }
            Err(_) => self.stats.oversized += 1,
        }
    }

    fn feedback(&mut self, payload: Payload) {
        let id = self.next_msg_id;
        self.next_msg_id = self.next_msg_id.wrapping_add(1).max(1);
        self.emit(self.host, id, payload);
    }

    /// Makes a fault happen now (for tests of what a host does about it):
    ///
    /// - [`JointFault::Overtemperature`] and [`JointFault::DriverFault`]:
    ///   the joint brakes at its emergency deceleration, enters `Error`
    ///   with the fault's code in `JointStatus.error_code` (4 and 5, the
    ///   v2.2 `EmergencyReason` numbers) and, speaking v2.2, reports an
    ///   `EmergencyStop` to its host. It takes nothing but `Reset` until
    ///   then.
    /// - [`JointFault::Reboot`]: the joint starts again: at rest where it
    ///   stood, `Unconfigured`, every sender forgotten; it says so with a
    ///   `JointStatus`.
    pub fn fault(&mut self, now: Duration, fault: JointFault) {
        self.now = self.now.max(now);
        match fault {
            JointFault::Overtemperature | JointFault::DriverFault => {
                let (code, reason) = match fault {
                    JointFault::Overtemperature => (4, EmergencyReason::Overtemperature),
                    _ => (5, EmergencyReason::DriverFault),
                };
                self.brake(self.config.emergency_deceleration);
                self.error_code = code;
                if self.config.wire == WireVersion::V2_2 {
                    #[allow(clippy::cast_possible_truncation)]
                    let ms = self.now.as_millis() as u32;
                    self.feedback(Payload::EmergencyStop(EmergencyStop {
                        reason,
                        vbus_mv: 24_000,
                        current_ma: 0,
                        temp_c: if code == 4 { 95.0 } else { 40.0 },
                        timestamp_ms: ms,
                    }));
                }
                self.state = LifecycleState::Error;
                self.send_status();
            }
            JointFault::Reboot => {
                self.current = None;
                self.motion = Motion::Holding;
                self.velocity = 0.0;
                self.acceleration = 0.0;
                self.error_code = 0;
                self.telemetry_period = None;
                self.senders.clear();
                self.state = LifecycleState::Unconfigured;
                self.send_status();
            }
        }
    }

    fn set_state(&mut self, state: LifecycleState) {
        if self.state != state {
            self.state = state;
            self.send_status();
        }
    }

    fn send_status(&mut self) {
        self.feedback(Payload::JointStatus {
            state: self.state,
            error_code: self.error_code,
        });
    }

    fn telemetry(&self) -> TelemetryStream {
        #[allow(clippy::cast_possible_truncation)]
        let f = |x: f64| x as f32;
        TelemetryStream {
            timestamp_us: u64::try_from(self.now.as_micros()).unwrap_or(u64::MAX),
            position: f(self.position),
            velocity: f(self.velocity),
            acceleration: f(self.acceleration),
            current_d: 0.0,
            current_q: 0.0,
            voltage_d: 0.0,
            voltage_q: 0.0,
            torque_estimate: 0.0,
            power: 0.0,
            load_percent: 0.0,
            foc_loop_time_us: 0,
            temperature_c: 25.0,
            warnings: 0,
            trajectory_active: matches!(self.motion, Motion::Profile { .. }),
        }
    }

    /// Takes a frame from the bus at `now`. Returns the request it acted on
    /// for the first time (executed or refused), if the frame was one.
    pub fn handle_frame(&mut self, now: Duration, frame: &Frame) -> Option<Execution> {
        self.update(now);
        if frame.id().is_extended() {
            return None;
        }
        let wire = self.config.wire;
        let message = match Message::decode_frame(wire, frame.data()) {
            Ok(m) => m,
            Err(WireError::NonFinite { .. }) => {
                // The header is sound; the value is not: refuse it by name.
                match Header::decode_prefix(wire, frame.data()) {
                    Ok((h, _)) if self.is_for_me(h.target_id) && valid_source(&h, frame) => {
                        self.last_heard = self.now;
                        self.answer(
                            h,
                            Payload::Nack {
                                id: h.msg_id,
                                error: NackCode::NON_FINITE.0,
                            },
                        );
                    }
                    _ => self.stats.bad_frames += 1,
                }
                return None;
            }
            Err(_) => {
                self.stats.bad_frames += 1;
                return None;
            }
        };
        let h = message.header;
        if !self.is_for_me(h.target_id) {
            return None;
        }
        if !valid_source(&h, frame) {
            self.stats.bad_frames += 1;
            return None;
        }
        if matches!(message.payload, Payload::ArmReady) {
            self.last_heard = self.now;
            return None;
        }
        if h.source_id == self.config.node_id {
            return None;
        }
        // Answers and telemetry are never requests: on a shared bus other
        // joints send them to the arm (node 0x0000), which a joint also
        // takes as broadcast. Answering them would start a Nack storm.
        if !is_request(&message.payload) {
            return None;
        }
        self.last_heard = self.now;
        if let Some(answer) = self.sender(h.source_id).answers.get(&h.msg_id).copied() {
            self.stats.duplicates += 1;
            self.emit(h.source_id, h.msg_id, answer);
            return None;
        }
        let lifecycle = is_lifecycle(&message.payload);
        let restart = matches!(message.payload, Payload::Configure | Payload::Reset);
        let sender = self.sender(h.source_id);
        // Older than every answer remembered (with the memory full): a late
        // copy whose first answer was forgotten, never executed again.
        let forgotten = sender.order.len() >= DEDUP_WINDOW
            && sender.order.iter().all(|&id| serial_before(h.msg_id, id));
        let behind_epoch = sender.epoch.filter(|&e| serial_before(h.msg_id, e));
        if forgotten || behind_epoch.is_some() {
            let far = behind_epoch.is_some_and(|e| e.wrapping_sub(h.msg_id) > RESTART_SPAN);
            if restart && far {
                // Not a late copy: the sender started again (a host starts
                // with Configure).
                *sender = Sender {
                    last_heard: sender.last_heard,
                    ..Sender::default()
                };
            } else {
                self.stats.stale += 1;
                self.answer(
                    h,
                    Payload::Nack {
                        id: h.msg_id,
                        error: NackCode::STALE_REQUEST.0,
                    },
                );
                return None;
            }
        }
        if lifecycle {
            self.sender(h.source_id).epoch = Some(h.msg_id);
        }
        self.host = h.source_id;
        let answer = self.execute(&message);
        let execution = Execution {
            source: h.source_id,
            msg_id: h.msg_id,
            payload: message.payload,
            answer,
            at: self.now,
        };
        if let Some(log) = self.log.as_mut() {
            log.push(execution);
        }
        self.answer(h, answer);
        Some(execution)
    }

    /// What the joint remembers of `source`, made (forgetting the longest
    /// silent sender when [`MAX_SENDERS`] are known) if new.
    fn sender(&mut self, source: u16) -> &mut Sender {
        if !self.senders.contains_key(&source) && self.senders.len() >= MAX_SENDERS {
            let oldest = self
                .senders
                .iter()
                .min_by_key(|(_, s)| s.last_heard)
                .map(|(id, _)| *id);
            if let Some(id) = oldest {
                self.senders.remove(&id);
            }
        }
        let now = self.now;
        let s = self.senders.entry(source).or_default();
        s.last_heard = now;
        s
    }

    fn is_for_me(&self, target: u16) -> bool {
        target == self.config.node_id || target == 0xFFFF || target == ARM_NODE
    }

    fn answer(&mut self, h: Header, answer: Payload) {
        match answer {
            Payload::Ack(_) => self.stats.acked += 1,
            _ => self.stats.nacked += 1,
        }
        let sender = self.sender(h.source_id);
        if sender.answers.insert(h.msg_id, answer).is_none() {
            sender.order.push_back(h.msg_id);
        }
        while sender.order.len() > DEDUP_WINDOW {
            if let Some(old) = sender.order.pop_front() {
                sender.answers.remove(&old);
            }
        }
        self.emit(h.source_id, h.msg_id, answer);
    }

    fn execute(&mut self, message: &Message) -> Payload {
        use LifecycleState::{Active, Inactive, Unconfigured};
        let id = message.header.msg_id;
        let nack = |code: NackCode| Payload::Nack { id, error: code.0 };
        match message.payload {
            Payload::Configure => match self.state {
                Unconfigured | Inactive => {
                    self.set_state(Inactive);
                    Payload::Ack(id)
                }
                _ => nack(NackCode::CONFIGURE_WRONG_STATE),
            },
            Payload::Activate => match self.state {
                Inactive | Active => {
                    self.set_state(Active);
                    Payload::Ack(id)
                }
                _ => nack(NackCode::ACTIVATE_WRONG_STATE),
            },
            Payload::Deactivate => match self.state {
                Active | Inactive => {
                    self.brake(self.config.emergency_deceleration);
                    self.set_state(Inactive);
                    Payload::Ack(id)
                }
                _ => nack(NackCode::DEACTIVATE_WRONG_STATE),
            },
            Payload::Reset => {
                self.brake(self.config.emergency_deceleration);
                self.error_code = 0;
                self.telemetry_period = None;
                self.set_state(Unconfigured);
                Payload::Ack(id)
            }
            Payload::SetTargetV2(cmd) => self.move_to(message, cmd),
            Payload::SetTarget(cmd) => {
                let l = self.config.limits;
                let v2 = SetTargetPayloadV2 {
                    target_angle: cmd.target_angle,
                    max_velocity: cmd.velocity_limit,
                    target_velocity: 0.0,
                    max_acceleration: l.max_acceleration,
                    max_deceleration: l.max_acceleration,
                    max_jerk: 0.0,
                    profile: MotionProfile::Trapezoidal,
                    max_current: 0.0,
                    max_temperature: 0.0,
                };
                self.move_to(message, v2)
            }
            Payload::ConfigureTelemetry(c) => {
                let hz = c.rate_hz;
                if matches!(c.mode, TelemetryMode::OnDemand) || hz == 0 {
                    self.telemetry_period = None;
                } else if hz > 1000 {
                    return nack(NackCode::OUT_OF_LIMITS);
                } else {
                    let period = Duration::from_micros(1_000_000 / u64::from(hz));
                    self.telemetry_period = Some(period);
                    self.next_telemetry = self.now.saturating_add(period);
                }
                Payload::Ack(id)
            }
            Payload::RequestTelemetry => {
                let t = self.telemetry();
                self.feedback(Payload::TelemetryStream(t));
                Payload::Ack(id)
            }
            _ => nack(NackCode::UNKNOWN_PAYLOAD),
        }
    }

    fn move_to(&mut self, message: &Message, cmd: SetTargetPayloadV2) -> Payload {
        let id = message.header.msg_id;
        let nack = |code: NackCode| Payload::Nack { id, error: code.0 };
        if self.state != LifecycleState::Active {
            return nack(NackCode::SET_TARGET_WRONG_STATE);
        }
        // A keep-alive: the motion in progress (or completed undisturbed),
        // asked again.
        if self.current == Some(cmd) {
            return Payload::Ack(id);
        }
        let l = self.config.limits;
        let decel = if cmd.max_deceleration > 0.0 {
            cmd.max_deceleration
        } else {
            cmd.max_acceleration
        };
        let jerk_limited = cmd.max_jerk > 0.0 && !matches!(cmd.profile, MotionProfile::Trapezoidal);
        let within = (l.min_angle..=l.max_angle).contains(&cmd.target_angle)
            && positive_finite(cmd.max_velocity)
            && cmd.max_velocity <= l.max_velocity
            && positive_finite(cmd.max_acceleration)
            && cmd.max_acceleration <= l.max_acceleration
            && decel <= l.max_acceleration
            && cmd.target_velocity.abs() <= cmd.max_velocity
            && (!jerk_limited || cmd.max_jerk <= l.max_jerk);
        if !within {
            return nack(NackCode::OUT_OF_LIMITS);
        }
        let req = cmd.planner_request(self.position, self.velocity);
        let Ok(planned) = motorwire_planner::plan(&req) else {
            return nack(NackCode::OUT_OF_LIMITS);
        };
        let ((lo, _), (hi, _)) = planned.position_extremes();
        if lo < f64::from(l.min_angle) || hi > f64::from(l.max_angle) {
            return nack(NackCode::OUT_OF_LIMITS);
        }
        self.motion = Motion::Profile {
            profile: planned,
            start: self.now,
        };
        self.current = Some(cmd);
        self.error_code = 0;
        self.stats.executed += 1;
        Payload::Ack(id)
    }

    /// Advances to `now`: motion, the watchdog, periodic feedback.
    pub fn handle_timeout(&mut self, now: Duration) {
        self.update(now);
        let now = self.now;
        let wd = self.config.watchdog;
        if matches!(self.motion, Motion::Profile { .. })
            && !wd.is_zero()
            && now.saturating_sub(self.last_heard) >= wd
        {
            self.brake(self.config.limits.max_acceleration);
            self.stats.watchdog_stops += 1;
            self.error_code = WATCHDOG_STOP;
            self.send_status();
        }
        let enc = self.config.encoder_period;
        if !enc.is_zero() && now >= self.next_encoder {
            if self.state != LifecycleState::Unconfigured {
                #[allow(clippy::cast_possible_truncation)]
                let e = EncoderTelemetry {
                    position: self.position as f32,
                    velocity: self.velocity as f32,
                };
                self.feedback(Payload::Encoder(e));
            }
            self.next_encoder = now.saturating_add(enc);
        }
        let st = self.config.status_period;
        if !st.is_zero() && now >= self.next_status {
            self.send_status();
            self.next_status = now.saturating_add(st);
        }
        if let Some(period) = self.telemetry_period
            && now >= self.next_telemetry
        {
            let t = self.telemetry();
            self.feedback(Payload::TelemetryStream(t));
            self.next_telemetry = now.saturating_add(period);
        }
    }

    /// The next frame to put on the bus.
    pub fn poll_transmit(&mut self) -> Option<Frame> {
        self.out.pop_front()
    }

    /// When [`SimJoint::handle_timeout`] next has work: feedback, the
    /// watchdog, or the end of a motion.
    pub fn poll_timeout(&self) -> Option<Duration> {
        let on = |period: Duration, at: Duration| (!period.is_zero()).then_some(at);
        let (motion_end, watchdog) = match self.motion {
            Motion::Profile { profile, start, .. } => (
                Some(after(start, profile.duration())),
                on(
                    self.config.watchdog,
                    self.last_heard.saturating_add(self.config.watchdog),
                ),
            ),
            Motion::Braking {
                start,
                velocity,
                deceleration,
                ..
            } => (Some(after(start, velocity.abs() / deceleration)), None),
            Motion::Holding => (None, None),
        };
        [
            on(self.config.encoder_period, self.next_encoder),
            on(self.config.status_period, self.next_status),
            self.telemetry_period.map(|_| self.next_telemetry),
            motion_end,
            watchdog,
        ]
        .into_iter()
        .flatten()
        .min()
    }

    /// One pass on a simulated bus at simulated time `now`: takes every
    /// frame already due on `port`, handles the timers that are due, and
    /// sends what it has to. Returns whether it received or sent anything
    /// (a stepper runs passes until none is busy, then moves the clock).
    ///
    /// # Errors
    /// The bus's errors.
    pub fn serve(&mut self, port: &mut SimPort, now: Duration) -> Result<bool, SimError> {
        crate::device::serve(self, port, now)
    }

    /// Runs the joint on `bus` in real time until `stop` is set, handling
    /// frames as they arrive and its timers when due; `on_request` sees each
    /// request acted on.
    ///
    /// # Errors
    /// The bus's errors, other than receive timeouts.
    pub fn run(
        &mut self,
        bus: &mut impl CanBus,
        stop: &AtomicBool,
        on_request: impl FnMut(&Execution),
    ) -> Result<(), SimError> {
        crate::device::run(self, bus, stop, on_request)
    }
}

/// Whether a joint is asked something by `payload` (not an answer, not
/// telemetry).
fn is_request(payload: &Payload) -> bool {
    !matches!(
        payload,
        Payload::Ack(_)
            | Payload::Nack { .. }
            | Payload::Encoder(_)
            | Payload::JointStatus { .. }
            | Payload::TelemetryStream(_)
            | Payload::AdaptiveStatus(_)
            | Payload::CalibrationStatus(_)
            | Payload::CalibrationResult(_)
            | Payload::PowerMetrics(_)
            | Payload::EmergencyStop(_)
            | Payload::PowerConfigResponse(_)
            | Payload::FaultHistory(_)
    )
}

/// WIRE-FACTS §1.5: a frame's CAN id is its sender's node id.
fn valid_source(h: &Header, frame: &Frame) -> bool {
    u32::from(h.source_id) == frame.id().raw()
}

/// `start` plus `secs` seconds, saturating (a corrupted or absurd command
/// can plan a motion longer than any `Duration`).
fn after(start: Duration, secs: f64) -> Duration {
    Duration::try_from_secs_f64(secs.max(0.0)).map_or(Duration::MAX, |d| start.saturating_add(d))
}

impl crate::device::Device for SimJoint {
    type Acted = Execution;
    fn handle_frame(&mut self, now: Duration, frame: &Frame) -> Option<Execution> {
        SimJoint::handle_frame(self, now, frame)
    }
    fn handle_timeout(&mut self, now: Duration) {
        SimJoint::handle_timeout(self, now);
    }
    fn poll_transmit(&mut self) -> Option<Frame> {
        SimJoint::poll_transmit(self)
    }
    fn poll_timeout(&self) -> Option<Duration> {
        SimJoint::poll_timeout(self)
    }
}
