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
//!   joint's current position, velocity and acceleration (an S-curve
//!   continues a jerk-limited motion it replaces without a step in
//!   acceleration, so a stream of targets is followed within the jerk
//!   limit; after a trapezoidal motion or a brake, whose acceleration
//!   steps, from zero acceleration), with every limit it carries
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
//! - **Messages over 64 bytes** (a FaultHistory with its faults, a
//!   TelemetryStream or PowerMetrics with long varints, a failed
//!   CalibrationResult with a long header) go as segmented transfers, and
//!   segmented requests are taken, as motorwire decides in
//!   [`motorwire_can::segmented`]: ISO-TP over CAN-FD on the 29-bit ids
//!   [`segmented_ids`](motorwire_can::segmented::segmented_ids) makes.
//!   Everything the joint sends to one node keeps its order: a frame made
//!   after a long message waits for its transfer. A transfer waits
//!   [`JointConfig::transfer_timeout`] (250 ms) for the host's flow control.
//!
//! ## The motion model behind the telemetry
//!
//! The joint's load is a pure inertia [`INERTIA`] (kg·m²) driven through a
//! motor of torque constant [`TORQUE_CONSTANT`] (Nm/A, also its back-EMF
//! constant in V·s/rad), winding resistance [`WINDING_RESISTANCE`] (Ω),
//! inductance [`WINDING_INDUCTANCE`] (H) and [`POLE_PAIRS`] pole pairs, on a
//! [`BUS_VOLTAGE_MV`] bus, under field-oriented control with `i_d = 0`.
//! With α the planned acceleration and ω the velocity, both in rad/s:
//!
//! - `torque_estimate = INERTIA · α`, `current_q = torque / TORQUE_CONSTANT`
//!   (proportional to the acceleration), `current_d = 0`;
//! - `voltage_q = R · i_q + TORQUE_CONSTANT · ω`,
//!   `voltage_d = −POLE_PAIRS · ω · L · i_q`;
//! - `power = voltage_q · i_q` (W, negative while braking regenerates);
//! - `load_percent = 100 · |torque| / (INERTIA · max_acceleration)`;
//! - the winding temperature follows a first-order model, from
//!   [`AMBIENT_TEMPERATURE`] towards `ambient + THERMAL_RESISTANCE · R · i_q²`
//!   with time constant [`THERMAL_TIME_CONSTANT`]: it rises slowly with the
//!   current and cools at rest;
//! - `foc_loop_time_us` is [`FOC_LOOP_TIME_US`]; `warnings` bit 0x0001 is
//!   set at or above the power configuration's throttle temperature;
//! - the clock (`timestamp_us`, fault times) is the joint's uptime:
//!   [`JointConfig::uptime`] plus the bus time.
//!
//! ## Calibration (v2.1 on)
//!
//! `StartCalibration` is taken from **Inactive** only (a joint must be
//! deactivated, so no motion is cut short, and configured), else
//! `Nack 20` ([`NackCode::CALIBRATION_WRONG_STATE`]); limits that are not
//! positive are `Nack 16`. The joint then reports `Calibrating` and runs
//! the phases its mask selects (bit 0 InertiaTest, 1 FrictionTest, 2
//! TorqueConstantVerification, 3 DampingTest, 4 Validation; a mask with
//! none of them set runs all five), [`CALIBRATION_PHASE_TIME`] each,
//! without moving. Every [`CALIBRATION_STATUS_PERIOD`] it sends a
//! `CalibrationStatus` (phase, overall progress 0 to 1, time remaining in
//! s, `current_iq` half the request's `max_current`); at the end a
//! `CalibrationStatus` `Complete` and a `CalibrationResult` with `success`,
//! the parameters of [`SIM_MOTOR_PARAMETERS`] its phases measured (the
//! others zero), their confidences (`overall` the lowest), `total_time`,
//! and back to Inactive. Meanwhile motion commands are `Nack 4`, Configure
//! and Activate `Nack 1` and `2`. `StopCalibration` (else `Nack 20`),
//! `Deactivate` and `Reset` abort it: a `CalibrationStatus` `Failed`, a
//! `CalibrationResult` with `success: false`, `error_code`
//! [`CALIBRATION_ABORTED`], and Inactive (Unconfigured after a Reset). A
//! `phase_timeout` shorter than a phase fails it with
//! [`CALIBRATION_PHASE_TIMEOUT`], a fault with [`CALIBRATION_FAULTED`].
//!
//! ## Power and faults (v2.2)
//!
//! - `RequestFaultHistory` is answered with a `FaultHistory` of the joint's
//!   faults ([`SimJoint::fault`]: type 4 overtemperature, 5 driver fault,
//!   the `EmergencyReason` numbers), the last ten, oldest first, with
//!   `total_faults` since boot and `valid_count`.
//! - `RequestPowerConfig` is answered with a `PowerConfigResponse`;
//!   `ConfigurePower` is acked and kept (`Nack 16` unless undervoltage <
//!   overvoltage and throttle start < shutdown temperature). Its
//!   `telemetry_rate_hz`, when not 0, sends `PowerMetrics` at that rate.
//! - v2.2 has no request for `PowerMetrics`, so **motorwire's decision**: a
//!   v2.2 joint answers `RequestTelemetry` with a `TelemetryStream`
//!   followed by a `PowerMetrics` (phase currents from `i_q` at the
//!   electrical angle, energy and charge drawn since boot, time Active,
//!   [`FaultCounters`] counting its faults and emergency stops).
//! - These requests, and the telemetry ones, are answered in every state
//!   (Error included: they are how a host finds out why).
//! - `ConfigureAdaptive` and `RequestAdaptiveStatus` are `Nack 255`: the
//!   simulated joint has no adaptive current control.
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
use motorwire_can::segmented::{LinkEvent, Links};
use motorwire_can::{CanBus, CanId, Frame, SimPort};
use motorwire_irpc::{
    CalibrationConfidence, CalibrationPhase, CalibrationRequest, CalibrationResult,
    CalibrationStatus, EmergencyReason, EmergencyStop, EncoderTelemetry, Error as WireError,
    FaultCounters, FaultHistory, FaultRecord, Header, LifecycleState, MAX_FRAME_LEN, Message,
    MotionProfile, MotorParameters, NackCode, Payload, PowerConfig, PowerMetrics,
    SetTargetPayloadV2, TelemetryMode, TelemetryStream, WireVersion,
};
use motorwire_planner::Profile;

use crate::SimError;

/// `JointStatus.error_code` after the watchdog braked a motion.
pub const WATCHDOG_STOP: u16 = 1;

/// The motor's torque constant (Nm/A), also its back-EMF constant (V·s/rad).
pub const TORQUE_CONSTANT: f64 = 0.08;
/// The joint's inertia as the motor sees it (kg·m²).
pub const INERTIA: f64 = 0.01;
/// The motor's winding resistance (Ω).
pub const WINDING_RESISTANCE: f64 = 0.5;
/// The motor's winding inductance (H).
pub const WINDING_INDUCTANCE: f64 = 0.0005;
/// The motor's pole pairs.
pub const POLE_PAIRS: f64 = 7.0;
/// The supply voltage (mV).
pub const BUS_VOLTAGE_MV: u32 = 24_000;
/// The temperature of the joint's surroundings and of a cold motor (°C).
pub const AMBIENT_TEMPERATURE: f64 = 25.0;
/// The motor's thermal resistance to ambient (K/W).
pub const THERMAL_RESISTANCE: f64 = 2.0;
/// The motor's thermal time constant (s).
pub const THERMAL_TIME_CONSTANT: f64 = 60.0;
/// The field-oriented control loop's period reported in telemetry (µs).
pub const FOC_LOOP_TIME_US: u16 = 50;
/// The temperature an overtemperature fault reports (°C).
pub const OVERTEMPERATURE_C: f64 = 95.0;

/// How long each calibration phase takes.
pub const CALIBRATION_PHASE_TIME: Duration = Duration::from_millis(500);
/// How often a calibrating joint sends `CalibrationStatus`.
pub const CALIBRATION_STATUS_PERIOD: Duration = Duration::from_millis(100);
/// `CalibrationResult.error_code` of a calibration stopped by
/// StopCalibration, Deactivate or Reset.
pub const CALIBRATION_ABORTED: u16 = 0x0101;
/// `CalibrationResult.error_code` of a calibration whose phase took longer
/// than the request's `phase_timeout`.
pub const CALIBRATION_PHASE_TIMEOUT: u16 = 0x0102;
/// `CalibrationResult.error_code` of a calibration a fault ended.
pub const CALIBRATION_FAULTED: u16 = 0x0103;

/// What the simulated motor is, and what a full calibration finds:
/// inertia kg·m², torque constant Nm/A, damping Nm·s/rad, Coulomb and
/// Stribeck friction Nm, Stribeck velocity rad/s, viscous friction
/// Nm·s/rad.
pub const SIM_MOTOR_PARAMETERS: MotorParameters = MotorParameters {
    inertia: 0.01,
    torque_constant: 0.08,
    damping: 0.002,
    friction_coulomb: 0.03,
    friction_stribeck: 0.01,
    friction_vstribeck: 0.05,
    friction_viscous: 0.001,
};

/// The confidence each calibration phase reports, in phase order
/// (InertiaTest, FrictionTest, TorqueConstantVerification, DampingTest,
/// Validation).
pub const CALIBRATION_CONFIDENCE: [f32; 5] = [0.97, 0.92, 0.99, 0.95, 0.98];

/// The validation RMS error a calibration with a Validation phase reports.
pub const CALIBRATION_VALIDATION_RMS: f32 = 0.015;

/// The power configuration a joint starts with: 30 V over, 18 V under,
/// 10 A RMS, 20 A peak, throttling from 70 °C, shutdown at 90 °C, no
/// periodic PowerMetrics.
pub const DEFAULT_POWER_CONFIG: PowerConfig = PowerConfig {
    vbus_overvoltage_mv: 30_000,
    vbus_undervoltage_mv: 18_000,
    max_rms_current_ma: 10_000,
    max_peak_current_ma: 20_000,
    temp_throttle_start_c: 70,
    temp_shutdown_c: 90,
    telemetry_rate_hz: 0,
};

/// How many faults a FaultHistory holds.
pub const FAULT_RECORDS: usize = 10;

const DEFAULT_COUNTERS: FaultCounters = FaultCounters {
    overcurrent: 0,
    overvoltage: 0,
    undervoltage: 0,
    overtemp: 0,
    driver_fault: 0,
    emergency_stops: 0,
};

const PHASES: [CalibrationPhase; 5] = [
    CalibrationPhase::InertiaTest,
    CalibrationPhase::FrictionTest,
    CalibrationPhase::TorqueConstantVerification,
    CalibrationPhase::DampingTest,
    CalibrationPhase::Validation,
];

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
    /// How long the joint has been running when the bus starts: its clock
    /// (TelemetryStream.timestamp_us, fault times) reads this at bus time
    /// zero. Zero by default.
    pub uptime: Duration,
    /// The msg_id of its first feedback message (default 1).
    pub first_msg_id: u32,
    /// How long a segmented transfer of its waits for the host's flow
    /// control, and a host's transfer for its next frame (250 ms).
    pub transfer_timeout: Duration,
}

impl JointConfig {
    /// Node `node_id`, v2.0, default limits, 200 ms watchdog, Encoder every
    /// 10 ms, JointStatus every 100 ms, starting at 0°, uptime zero,
    /// feedback msg_ids from 1, 250 ms segmented transfer timeout.
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
            uptime: Duration::ZERO,
            first_msg_id: 1,
            transfer_timeout: Duration::from_millis(250),
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
    /// Messages that could not be sent: over 64 bytes to a node a
    /// segmented transfer cannot name (above 0x7FF), or with too many
    /// waiting for that node already.
    pub oversized: u64,
    /// Segmented transfers sent whole.
    pub segmented_sent: u64,
    /// Messages received by segmented transfer.
    pub segmented_received: u64,
    /// Segmented transfers that failed, either way (also counted in
    /// `bad_frames` when received).
    pub failed_transfers: u64,
    /// Calibrations run to their end (successful or failed).
    pub calibrations: u64,
}

/// A calibration in progress.
#[derive(Debug, Clone)]
struct Calibration {
    request: CalibrationRequest,
    phases: Vec<usize>,
    start: Duration,
    next_status: Duration,
}

impl Calibration {
    fn total(&self) -> Duration {
        CALIBRATION_PHASE_TIME.saturating_mul(u32::try_from(self.phases.len()).unwrap_or(5))
    }

    /// When a phase times out, if the request's phase_timeout is shorter
    /// than a phase.
    fn timeout_at(&self) -> Option<Duration> {
        let t = Duration::try_from_secs_f32(self.request.phase_timeout).ok()?;
        (t < CALIBRATION_PHASE_TIME).then(|| self.start.saturating_add(t))
    }
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
    links: Links,
    next_msg_id: u32,
    next_encoder: Duration,
    next_status: Duration,
    telemetry_period: Option<Duration>,
    next_telemetry: Duration,
    stats: JointStats,
    log: Option<Vec<Execution>>,
    /// Winding temperature (°C).
    temperature: f64,
    /// Energy drawn since boot (mWh).
    energy_mwh: f64,
    /// Charge drawn since boot (mAh).
    charge_mah: f64,
    /// Time spent Active since boot.
    active_time: Duration,
    faults: VecDeque<FaultRecord>,
    total_faults: u32,
    counters: FaultCounters,
    power_config: PowerConfig,
    next_power: Duration,
    calibration: Option<Calibration>,
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
        let invalid_node = |e: motorwire_can::Error| SimError::InvalidConfig {
            field: "node_id",
            reason: e.to_string(),
        };
        let can_id = CanId::standard(config.node_id).map_err(invalid_node)?;
        let links = Links::new(config.node_id, config.transfer_timeout).map_err(invalid_node)?;
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
            links,
            next_msg_id: config.first_msg_id.max(1),
            next_encoder: Duration::ZERO,
            next_status: Duration::ZERO,
            telemetry_period: None,
            next_telemetry: Duration::ZERO,
            stats: JointStats::default(),
            log: None,
            temperature: AMBIENT_TEMPERATURE,
            energy_mwh: 0.0,
            charge_mah: 0.0,
            active_time: Duration::ZERO,
            faults: VecDeque::new(),
            total_faults: 0,
            counters: DEFAULT_COUNTERS,
            power_config: DEFAULT_POWER_CONFIG,
            next_power: Duration::ZERO,
            calibration: None,
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

    /// The joint's acceleration at `t` (degrees/s²) on the motion it runs
    /// now, as [`SimJoint::position_at`] reads its position.
    pub fn acceleration_at(&self, t: Duration) -> f64 {
        let t = t.max(self.now);
        match self.motion {
            Motion::Holding => 0.0,
            Motion::Profile { profile, start } => {
                let s = t.saturating_sub(start).as_secs_f64();
                if s >= profile.duration() {
                    0.0
                } else {
                    profile.sample(s).acceleration
                }
            }
            Motion::Braking {
                start,
                velocity,
                deceleration,
                ..
            } => {
                let stop = velocity.abs() / deceleration;
                if t.saturating_sub(start).as_secs_f64() >= stop {
                    0.0
                } else {
                    -velocity.signum() * deceleration
                }
            }
        }
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
        let dt = now.saturating_sub(self.now);
        self.integrate(dt);
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

    /// Sends `payload` to `target`: one frame, or a segmented transfer
    /// over 64 bytes; in order behind what is already on its way there.
    fn emit(&mut self, target: u16, msg_id: u32, payload: Payload) {
        let message = Message {
            header: Header {
                source_id: self.config.node_id,
                target_id: target,
                msg_id,
            },
            payload,
        };
        let wire = self.config.wire;
        let mut buf = [0u8; MAX_FRAME_LEN];
        match message.encode_frame(wire, &mut buf) {
            Ok(len) => {
                if let Ok(f) = Frame::fd(self.can_id, buf.get(..len).unwrap_or(&buf))
                    && !self.links.send_frame(target, f)
                {
                    self.stats.oversized += 1;
                }
            }
            Err(WireError::FrameTooLarge { len }) => {
                let mut bytes = vec![0u8; len];
                let sent = message
                    .encode(wire, &mut bytes)
                    .map_err(motorwire_can::Error::from)
                    .and_then(|n| {
                        bytes.truncate(n);
                        self.links.send_message(self.now, target, bytes, None)
                    });
                if sent.is_err() {
                    self.stats.oversized += 1;
                }
                self.drain_links();
            }
            Err(_) => self.stats.oversized += 1,
        }
    }

    /// Handles what the segmented transfers reported; returns the last
    /// request a reassembled message carried.
    fn drain_links(&mut self) -> Option<Execution> {
        let mut acted = None;
        while let Some(event) = self.links.poll_event() {
            match event {
                LinkEvent::Message { source, bytes, .. } => {
                    self.stats.segmented_received += 1;
                    if let Some(e) = self.handle_bytes(&bytes, Origin::Segmented(source)) {
                        acted = Some(e);
                    }
                }
                LinkEvent::ReceiveFailed { .. } => {
                    self.stats.failed_transfers += 1;
                    self.stats.bad_frames += 1;
                }
                LinkEvent::SendFailed { .. } => self.stats.failed_transfers += 1,
                LinkEvent::Sent { .. } => self.stats.segmented_sent += 1,
            }
        }
        acted
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
    ///   The fault is recorded in its fault history (v2.2
    ///   `RequestFaultHistory`) and counted in `PowerMetrics.faults` (its
    ///   kind and `emergency_stops`); an overtemperature heats the motor
    ///   to [`OVERTEMPERATURE_C`]; a calibration in progress fails with
    ///   [`CALIBRATION_FAULTED`].
    /// - [`JointFault::Reboot`]: the joint starts again: at rest where it
    ///   stood, `Unconfigured`, every sender forgotten, its fault history,
    ///   counters, energy and power configuration as at boot (they live in
    ///   RAM); it says so with a `JointStatus`.
    pub fn fault(&mut self, now: Duration, fault: JointFault) {
        self.now = self.now.max(now);
        match fault {
            JointFault::Overtemperature | JointFault::DriverFault => {
                let (code, reason) = match fault {
                    JointFault::Overtemperature => (4, EmergencyReason::Overtemperature),
                    _ => (5, EmergencyReason::DriverFault),
                };
                if code == 4 {
                    self.temperature = self.temperature.max(OVERTEMPERATURE_C);
                }
                let current_ma = self.current_q().abs() * 1000.0;
                self.brake(self.config.emergency_deceleration);
                self.error_code = code;
                self.state = LifecycleState::Error;
                self.end_calibration(false, CALIBRATION_FAULTED);
                self.record_fault(reason, current_ma);
                if self.config.wire == WireVersion::V2_2 {
                    // A 32-bit millisecond counter, as firmware keeps it:
                    // it wraps every 49.7 days.
                    #[allow(clippy::cast_possible_truncation)]
                    let ms = self.clock().as_millis() as u32;
                    self.feedback(Payload::EmergencyStop(EmergencyStop {
                        reason,
                        vbus_mv: BUS_VOLTAGE_MV,
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
                self.calibration = None;
                self.faults.clear();
                self.total_faults = 0;
                self.counters = DEFAULT_COUNTERS;
                self.power_config = DEFAULT_POWER_CONFIG;
                self.energy_mwh = 0.0;
                self.charge_mah = 0.0;
                self.active_time = Duration::ZERO;
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

    /// The joint's own clock: its uptime.
    fn clock(&self) -> Duration {
        self.config.uptime.saturating_add(self.now)
    }

    /// Torque (Nm) the motor gives the load now.
    fn torque(&self) -> f64 {
        INERTIA * self.acceleration.to_radians()
    }

    /// q-axis current (A) now.
    fn current_q(&self) -> f64 {
        self.torque() / TORQUE_CONSTANT
    }

    /// q-axis voltage (V) now.
    fn voltage_q(&self) -> f64 {
        WINDING_RESISTANCE * self.current_q() + TORQUE_CONSTANT * self.velocity.to_radians()
    }

    /// Electrical power (W) into the windings now.
    fn power(&self) -> f64 {
        self.voltage_q() * self.current_q()
    }

    /// Advances the thermal and energy model over `dt` at the present
    /// current and power.
    fn integrate(&mut self, dt: Duration) {
        let secs = dt.as_secs_f64();
        if secs <= 0.0 {
            return;
        }
        let iq = self.current_q();
        let steady = AMBIENT_TEMPERATURE + THERMAL_RESISTANCE * WINDING_RESISTANCE * iq * iq;
        self.temperature =
            steady + (self.temperature - steady) * (-secs / THERMAL_TIME_CONSTANT).exp();
        let drawn = self.power().max(0.0);
        self.energy_mwh += drawn * secs / 3.6;
        self.charge_mah += drawn / (f64::from(BUS_VOLTAGE_MV) / 1000.0) * secs / 3.6;
        if self.state == LifecycleState::Active {
            self.active_time = self.active_time.saturating_add(dt);
        }
    }

    fn warnings(&self) -> u16 {
        u16::from(self.temperature >= f64::from(self.power_config.temp_throttle_start_c))
    }

    /// The TelemetryStream it sends now (see [the model](self#the-motion-model-behind-the-telemetry)).
    #[allow(clippy::cast_possible_truncation)]
    pub fn telemetry(&self) -> TelemetryStream {
        let f = |x: f64| x as f32;
        let iq = self.current_q();
        let omega = self.velocity.to_radians();
        let peak = INERTIA * f64::from(self.config.limits.max_acceleration).to_radians();
        TelemetryStream {
            timestamp_us: u64::try_from(self.clock().as_micros()).unwrap_or(u64::MAX),
            position: f(self.position),
            velocity: f(self.velocity),
            acceleration: f(self.acceleration),
            current_d: 0.0,
            current_q: f(iq),
            voltage_d: f(-POLE_PAIRS * omega * WINDING_INDUCTANCE * iq),
            voltage_q: f(self.voltage_q()),
            torque_estimate: f(self.torque()),
            power: f(self.power()),
            load_percent: f((100.0 * self.torque().abs() / peak).min(100.0)),
            foc_loop_time_us: FOC_LOOP_TIME_US,
            temperature_c: f(self.temperature),
            warnings: self.warnings(),
            trajectory_active: matches!(self.motion, Motion::Profile { .. }),
        }
    }

    /// The PowerMetrics it sends now (v2.2): phase currents from `i_q` at
    /// the electrical angle, RMS current, power drawn, the MCU at ambient
    /// plus 10 °C, the thermal throttle factor (1 below the throttle
    /// temperature, 0 at shutdown, linear between), energy and charge drawn
    /// and time Active since boot, its fault counters.
    #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
    pub fn power_metrics(&self) -> PowerMetrics {
        let iq = self.current_q();
        let theta = POLE_PAIRS * self.position.to_radians();
        let third = 2.0 * std::f64::consts::PI / 3.0;
        let ma = |a: f64| (a * 1000.0).round() as i32;
        let cfg = self.power_config;
        let (start, stop) = (
            f64::from(cfg.temp_throttle_start_c),
            f64::from(cfg.temp_shutdown_c),
        );
        let throttle = if self.temperature < start {
            1.0
        } else if stop > start {
            ((stop - self.temperature) / (stop - start)).clamp(0.0, 1.0)
        } else {
            0.0
        };
        PowerMetrics {
            vbus_mv: BUS_VOLTAGE_MV,
            ia_ma: ma(-iq * theta.sin()),
            ib_ma: ma(-iq * (theta - third).sin()),
            i_rms_ma: (iq.abs() * 1000.0 / std::f64::consts::SQRT_2) as f32,
            power_mw: (self.power().max(0.0) * 1000.0).round() as u32,
            mcu_temp_c: (AMBIENT_TEMPERATURE + 10.0) as f32,
            throttle_factor: throttle as f32,
            energy_mwh: self.energy_mwh as u32,
            charge_mah: self.charge_mah as u32,
            active_time_ms: self.active_time.as_millis().min(u128::from(u32::MAX)) as u32,
            faults: self.counters,
        }
    }

    #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
    fn record_fault(&mut self, reason: EmergencyReason, current_ma: f64) {
        let fault_type = match reason {
            EmergencyReason::Overtemperature => {
                self.counters.overtemp = self.counters.overtemp.saturating_add(1);
                4
            }
            _ => {
                self.counters.driver_fault = self.counters.driver_fault.saturating_add(1);
                5
            }
        };
        self.counters.emergency_stops = self.counters.emergency_stops.saturating_add(1);
        self.total_faults = self.total_faults.saturating_add(1);
        if self.faults.len() >= FAULT_RECORDS {
            self.faults.pop_front();
        }
        self.faults.push_back(FaultRecord {
            fault_type,
            timestamp_sec: self.clock().as_secs().min(u64::from(u32::MAX)) as u32,
            vbus_mv: u16::try_from(BUS_VOLTAGE_MV).unwrap_or(u16::MAX),
            current_ma: current_ma.min(f64::from(u16::MAX)) as u16,
            temp_c: self.temperature.round().clamp(-128.0, 127.0) as i8,
        });
    }

    /// The joint's fault history as `RequestFaultHistory` reports it.
    pub fn fault_history(&self) -> FaultHistory {
        let mut records = [FaultRecord::default(); FAULT_RECORDS];
        for (slot, r) in records.iter_mut().zip(self.faults.iter()) {
            *slot = *r;
        }
        FaultHistory {
            records,
            total_faults: self.total_faults,
            valid_count: u8::try_from(self.faults.len()).unwrap_or(u8::MAX),
        }
    }

    /// The power configuration it keeps (v2.2 `ConfigurePower`).
    pub fn power_config(&self) -> PowerConfig {
        self.power_config
    }

    /// The winding temperature (°C) of its thermal model.
    pub fn temperature(&self) -> f64 {
        self.temperature
    }

    /// Whether a calibration is in progress.
    pub fn is_calibrating(&self) -> bool {
        self.calibration.is_some()
    }

    fn start_calibration(&mut self, id: u32, request: CalibrationRequest) -> Payload {
        let nack = |code: NackCode| Payload::Nack { id, error: code.0 };
        if self.state != LifecycleState::Inactive {
            return nack(NackCode::CALIBRATION_WRONG_STATE);
        }
        let r = request;
        if !(positive_finite(r.max_current)
            && positive_finite(r.max_velocity)
            && positive_finite(r.max_position_range)
            && positive_finite(r.phase_timeout))
        {
            return nack(NackCode::OUT_OF_LIMITS);
        }
        let mask = if r.phases & 0x1F == 0 { 0x1F } else { r.phases };
        let phases = (0..PHASES.len()).filter(|i| mask & (1 << i) != 0).collect();
        self.calibration = Some(Calibration {
            request,
            phases,
            start: self.now,
            next_status: self.now,
        });
        self.set_state(LifecycleState::Calibrating);
        Payload::Ack(id)
    }

    /// The phase (index into PHASES) running `elapsed` into a calibration,
    /// and the overall progress.
    fn calibration_phase(c: &Calibration, elapsed: Duration) -> (Option<usize>, f32) {
        let total = c.total().as_secs_f64();
        let progress = if total > 0.0 {
            (elapsed.as_secs_f64() / total).clamp(0.0, 1.0)
        } else {
            1.0
        };
        let step = CALIBRATION_PHASE_TIME.as_secs_f64();
        #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
        let n = (elapsed.as_secs_f64() / step) as usize;
        #[allow(clippy::cast_possible_truncation)]
        (c.phases.get(n).copied(), progress as f32)
    }

    fn calibration_status(&mut self, phase: CalibrationPhase, progress: f32, remaining: f32) {
        let Some(c) = self.calibration.as_ref() else {
            return;
        };
        #[allow(clippy::cast_possible_truncation)]
        let status = CalibrationStatus {
            phase,
            progress,
            time_remaining: remaining,
            current_position: self.position as f32,
            current_velocity: self.velocity as f32,
            current_iq: if matches!(phase, CalibrationPhase::Failed | CalibrationPhase::Complete) {
                0.0
            } else {
                c.request.max_current / 2.0
            },
        };
        self.feedback(Payload::CalibrationStatus(status));
    }

    /// Sends what is due of the calibration in progress.
    fn calibrate(&mut self) {
        let Some(c) = self.calibration.as_ref() else {
            return;
        };
        let now = self.now;
        if c.timeout_at().is_some_and(|t| now >= t) {
            self.end_calibration(false, CALIBRATION_PHASE_TIMEOUT);
            return;
        }
        let elapsed = now.saturating_sub(c.start);
        if elapsed >= c.total() {
            self.end_calibration(true, 0);
            return;
        }
        if now >= c.next_status {
            let (phase, progress) = Self::calibration_phase(c, elapsed);
            let remaining = c.total().saturating_sub(elapsed).as_secs_f32();
            let phase = phase
                .and_then(|i| PHASES.get(i).copied())
                .unwrap_or(CalibrationPhase::Validation);
            self.calibration_status(phase, progress, remaining);
            if let Some(c) = self.calibration.as_mut() {
                c.next_status = now.saturating_add(CALIBRATION_STATUS_PERIOD);
            }
        }
    }

    /// Ends the calibration in progress, if any: its last status and its
    /// result, then Inactive (unless `success` is false because of a fault
    /// or a reset, whose caller sets the state).
    fn end_calibration(&mut self, success: bool, error_code: u16) {
        let Some(c) = self.calibration.as_ref() else {
            return;
        };
        let elapsed = self.now.saturating_sub(c.start).min(c.total());
        let (_, progress) = Self::calibration_phase(c, elapsed);
        let ran = |i: usize| success && c.phases.contains(&i);
        let pick = |i: usize, v: f32| if ran(i) { v } else { 0.0 };
        let conf = |i: usize| pick(i, CALIBRATION_CONFIDENCE.get(i).copied().unwrap_or(0.0));
        let p = SIM_MOTOR_PARAMETERS;
        #[allow(clippy::cast_possible_truncation)]
        let parameters = MotorParameters {
            inertia: pick(0, p.inertia),
            torque_constant: pick(2, p.torque_constant),
            damping: pick(3, p.damping),
            friction_coulomb: pick(1, p.friction_coulomb),
            friction_stribeck: pick(1, p.friction_stribeck),
            friction_vstribeck: pick(1, p.friction_vstribeck),
            friction_viscous: pick(1, p.friction_viscous),
        };
        let overall = if success {
            c.phases
                .iter()
                .filter_map(|&i| CALIBRATION_CONFIDENCE.get(i).copied())
                .fold(1.0f32, f32::min)
        } else {
            0.0
        };
        let result = CalibrationResult {
            success,
            parameters,
            confidence: CalibrationConfidence {
                overall,
                inertia: conf(0),
                friction: conf(1),
                torque_constant: conf(2),
                validation_rms: pick(4, CALIBRATION_VALIDATION_RMS),
            },
            total_time: elapsed.as_secs_f32(),
            error_code,
        };
        let phase = if success {
            CalibrationPhase::Complete
        } else {
            CalibrationPhase::Failed
        };
        self.calibration_status(phase, if success { 1.0 } else { progress }, 0.0);
        self.calibration = None;
        self.stats.calibrations += 1;
        self.feedback(Payload::CalibrationResult(result));
        if self.state == LifecycleState::Calibrating {
            self.set_state(LifecycleState::Inactive);
        }
    }

    /// Takes a frame from the bus at `now`. Returns the request it acted on
    /// for the first time (executed or refused), if the frame was one.
    pub fn handle_frame(&mut self, now: Duration, frame: &Frame) -> Option<Execution> {
        self.update(now);
        if frame.id().is_extended() {
            // A segmented transfer to this joint (flow control for its own,
            // or a host's message), or not for it at all.
            if self.links.handle_frame(self.now, frame) {
                return self.drain_links();
            }
            return None;
        }
        self.handle_bytes(frame.data(), Origin::Plain(frame.id()))
    }

    /// Takes one message's bytes: a plain frame's (padded; its CAN id must
    /// be the sender's) or a reassembled transfer's (exact; the header must
    /// name the ends its CAN ids named).
    fn handle_bytes(&mut self, bytes: &[u8], origin: Origin) -> Option<Execution> {
        let wire = self.config.wire;
        let node = self.config.node_id;
        let decoded = match origin {
            Origin::Plain(_) => Message::decode_frame(wire, bytes),
            Origin::Segmented(_) => Message::decode(wire, bytes),
        };
        let valid_source = |h: &Header| match origin {
            Origin::Plain(id) => u32::from(h.source_id) == id.raw(),
            Origin::Segmented(from) => h.source_id == from && h.target_id == node,
        };
        let message = match decoded {
            Ok(m) => m,
            Err(WireError::NonFinite { .. }) => {
                // The header is sound; the value is not: refuse it by name.
                match Header::decode_prefix(wire, bytes) {
                    Ok((h, _)) if self.is_for_me(h.target_id) && valid_source(&h) => {
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
        if !valid_source(&h) {
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
                LifecycleState::Calibrating => {
                    self.end_calibration(false, CALIBRATION_ABORTED);
                    Payload::Ack(id)
                }
                Active | Inactive => {
                    self.brake(self.config.emergency_deceleration);
                    self.set_state(Inactive);
                    Payload::Ack(id)
                }
                _ => nack(NackCode::DEACTIVATE_WRONG_STATE),
            },
            Payload::Reset => {
                self.end_calibration(false, CALIBRATION_ABORTED);
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
                if self.config.wire == WireVersion::V2_2 {
                    let p = self.power_metrics();
                    self.feedback(Payload::PowerMetrics(p));
                }
                Payload::Ack(id)
            }
            Payload::StartCalibration(request) => self.start_calibration(id, request),
            Payload::StopCalibration => {
                if self.calibration.is_some() {
                    self.end_calibration(false, CALIBRATION_ABORTED);
                    Payload::Ack(id)
                } else {
                    nack(NackCode::CALIBRATION_WRONG_STATE)
                }
            }
            Payload::RequestFaultHistory => {
                let h = self.fault_history();
                self.feedback(Payload::FaultHistory(h));
                Payload::Ack(id)
            }
            Payload::RequestPowerConfig => {
                self.feedback(Payload::PowerConfigResponse(self.power_config));
                Payload::Ack(id)
            }
            Payload::ConfigurePower(c) => {
                if c.vbus_undervoltage_mv >= c.vbus_overvoltage_mv
                    || c.temp_throttle_start_c >= c.temp_shutdown_c
                {
                    return nack(NackCode::OUT_OF_LIMITS);
                }
                self.power_config = c;
                self.next_power = self.now;
                Payload::Ack(id)
            }
            // ConfigureAdaptive, RequestAdaptiveStatus: no adaptive control here.
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
        // From where it is, how fast it moves and how its speed changes:
        // an S-curve continues a jerk-limited motion in progress without a
        // step in acceleration. After a trapezoidal motion or a brake,
        // whose acceleration steps, it starts from zero acceleration.
        let continuing =
            matches!(self.motion, Motion::Profile { profile, .. } if profile.is_jerk_limited());
        let req = cmd
            .planner_request(self.position, self.velocity)
            .with_start_acceleration(if continuing { self.acceleration } else { 0.0 });
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
        if let Some(period) = self.power_period()
            && now >= self.next_power
        {
            let p = self.power_metrics();
            self.feedback(Payload::PowerMetrics(p));
            self.next_power = now.saturating_add(period);
        }
        self.calibrate();
        self.links.handle_timeout(now);
        self.drain_links();
    }

    /// The period of PowerMetrics a v2.2 `ConfigurePower` asked for.
    fn power_period(&self) -> Option<Duration> {
        let hz = self.power_config.telemetry_rate_hz;
        (self.config.wire == WireVersion::V2_2 && hz > 0)
            .then(|| Duration::from_micros(1_000_000 / u64::from(hz)))
    }

    /// The next frame to put on the bus.
    pub fn poll_transmit(&mut self) -> Option<Frame> {
        self.links.poll_transmit()
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
        let calibration = self.calibration.as_ref().map(|c| {
            let end = c.start.saturating_add(c.total());
            c.next_status.min(end).min(c.timeout_at().unwrap_or(end))
        });
        [
            on(self.config.encoder_period, self.next_encoder),
            on(self.config.status_period, self.next_status),
            self.telemetry_period.map(|_| self.next_telemetry),
            self.power_period().map(|_| self.next_power),
            motion_end,
            watchdog,
            calibration,
            self.links.poll_timeout(),
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

/// Where a message's bytes came from.
#[derive(Debug, Clone, Copy)]
enum Origin {
    /// A plain frame with this CAN id (WIRE-FACTS §1.5: the sender's node id).
    Plain(CanId),
    /// A segmented transfer from this node.
    Segmented(u16),
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
