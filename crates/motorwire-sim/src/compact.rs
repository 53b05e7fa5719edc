//! A simulated compact device: a motor commanded by the 24-byte WIA compact
//! command on CAN-FD, as WIRE-FACTS §2.1 lays it down.
//!
//! Sans-IO like [`SimJoint`](crate::SimJoint):
//! [`SimCompactDevice::handle_frame`] and [`SimCompactDevice::handle_timeout`]
//! take frames and the time, [`SimCompactDevice::poll_transmit`] gives frames
//! to send, and [`SimCompactDevice::poll_timeout`] says when it next needs the
//! time. [`SimCompactDevice::serve`] runs one pass on a simulated bus and
//! [`SimCompactDevice::run`] drives it on a blocking bus in real time.
//!
//! ## Behaviour
//!
//! - **Frames**: it listens on the standard CAN id `node`. A frame there that
//!   is not a 24-byte CAN-FD frame, or whose 24 bytes do not decode
//!   ([`CompactCommand::decode`]), is dropped and counted in
//!   [`CompactDeviceStats::bad_frames`]. A command whose motor hash is not
//!   the device's own is dropped and counted in
//!   [`CompactDeviceStats::ignored`]. Other CAN ids are not for it and are
//!   not counted. The BROADCAST and PRIORITY_HIGH flags change nothing: a
//!   command must carry the device's own hash.
//! - **Control modes** (setpoints in the units of the motor's commands:
//!   degrees or radians, per second, Nm; the device does not care which):
//!   - *position*: a time-optimal trapezoidal move (motorwire-planner) from
//!     the current position and velocity to the setpoint, at most the
//!     command's `velocity_limit` if it carries one and never faster than
//!     the device's `max_velocity` (the tighter of the two), at the device's
//!     `max_acceleration`. It ends at rest on the setpoint.
//!   - *velocity*: ramps at `max_acceleration` to the setpoint velocity and
//!     runs there. It never runs through a position limit: the run is
//!     planned toward the limit it heads for, so it brakes in time and stops
//!     on the limit (`position_limit` is then set). A setpoint of 0 brakes
//!     to rest at `max_acceleration`.
//!   - *torque*: there is no load model. The device records the torque
//!     setpoint and reports it (and a current of torque /
//!     [`TORQUE_CONSTANT`]); its velocity decays to rest at
//!     `max_acceleration`, as if the load held it.
//!   - *disabled*: brakes to rest at `max_acceleration`, reports zero
//!     torque, and clears `enabled`.
//!
//!   Any other mode (impedance, admittance, trajectory, gravity_comp,
//!   force_ctrl, hybrid) is refused.
//! - **Refusals** (a safety net behind the bridge's gate): a setpoint
//!   outside the device's limits is **not executed**, and what was running
//!   runs on. A position outside `[min_position, max_position]`, a velocity
//!   whose magnitude exceeds `max_velocity` or the command's own
//!   `velocity_limit`, a torque whose magnitude exceeds `max_torque` or the
//!   command's own `torque_limit`, a position move with a `velocity_limit`
//!   of 0 (it could never arrive), and a move whose path from the current
//!   velocity would pass a limit (or go further past one the device is
//!   already beyond) are refused ([`CompactRefusal`]). A refusal
//!   sets the `warning` status bit (and `position_limit` for a position
//!   refusal) until the next command that executes; it is logged and
//!   counted in [`CompactDeviceStats::refused`]. It is answered like any
//!   command (with REQUIRE_ACK, one feedback frame), so the warning bit is
//!   how the sender learns of it. A refused command is not remembered as the
//!   last one executed, so a resend is refused again.
//! - **Duplicates** (§2.1): a command whose 24 bytes equal the last command
//!   executed is not executed again but still answered (one feedback frame
//!   when it carries REQUIRE_ACK), and counted in
//!   [`CompactDeviceStats::duplicates`]. The memory holds one command.
//! - **Emergency stop**: a command with the EMERGENCY_STOP flag (0x01)
//!   stops the device whatever its mode and setpoint (it is never refused):
//!   with [`CompactDeviceConfig::emergency_deceleration`] `None` (the
//!   default) the velocity is zero at once; with `Some(d)` it brakes at `d`.
//!   A deceleration gentler than `max_acceleration` may carry it past a
//!   position limit (the status then says `position_limit`): a stop is
//!   never refused. It then holds ([`SimCompactDevice::stopped`], `enabled`
//!   clear) until a command without the flag is executed; that command is
//!   executed as usual. A refused command does not release it. The device
//!   cannot tell a late copy of a command sent before the stop from a new
//!   one (its memory of one holds the stop), so a sender must not resend a
//!   command from before a stop after it.
//! - **Feedback** (§2.1): the WIA Phase 3 record ([`FeedbackRecord`]),
//!   zero-padded to 48 bytes, on the standard CAN id `feedback_node`, every
//!   [`CompactDeviceConfig::feedback_period`] (the first at time zero; zero:
//!   never) and once at once after each command that carries REQUIRE_ACK,
//!   refused and duplicate ones included. The answer does not move the
//!   periodic schedule. The record's timestamp is the device's clock (the
//!   `now` it is given) in µs. Its status: `enabled` (a position, velocity
//!   or torque command is executing and no emergency stop holds),
//!   `warning` (the last command was refused), `calibrated` and `homed`
//!   (always: a simulation knows its position), `in_motion` (a move, run or
//!   brake is under way), `at_target` (enabled and: at rest on the position
//!   setpoint, at the velocity setpoint, or applying the torque setpoint),
//!   `position_limit` (at or past a position limit, or a position refusal).
//!   `fault`, `over_temperature`, `over_current` and `encoder_error` are
//!   never set. Voltage is [`SUPPLY_VOLTAGE`], temperature [`TEMPERATURE`],
//!   health 100.

use std::collections::VecDeque;
use std::fmt;
use std::sync::atomic::AtomicBool;
use std::time::Duration;

use motorwire_can::{CanBus, CanId, Frame, SimPort};
use motorwire_compact::{
    CompactCommand, ControlMode, FeedbackRecord, Flags, LEN, MotorHash, StatusFlag, StatusFlags,
};
use motorwire_planner::{Profile, Request};

use crate::SimError;

/// The bit a feedback CAN id adds to its device's `node` by default
/// (WIRE-FACTS §2.1: `feedback_node` is `node | 0x400`).
pub const FEEDBACK_NODE_BIT: u16 = 0x400;

/// The default feedback period: 50 Hz.
pub const DEFAULT_FEEDBACK_PERIOD: Duration = Duration::from_millis(20);

/// The supply voltage the device reports (V).
pub const SUPPLY_VOLTAGE: f32 = 24.0;

/// The temperature the device reports (°C).
pub const TEMPERATURE: f32 = 25.0;

/// The torque constant the reported current is derived with (Nm/A):
/// current = torque / `TORQUE_CONSTANT`.
pub const TORQUE_CONSTANT: f32 = 0.1;

/// How close (in the position's unit, or units/s) the device must be to its
/// setpoint for `at_target`.
const AT_TARGET_TOLERANCE: f64 = 1e-6;

/// How far past a position limit (in the position's unit) a planned path
/// may reach by rounding alone.
const PATH_TOLERANCE: f64 = 1e-9;

/// The device's own limits, in the units of its commands (degrees or
/// radians, per second, per second squared; Nm).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CompactDeviceLimits {
    /// Lowest position.
    pub min_position: f32,
    /// Highest position.
    pub max_position: f32,
    /// Fastest speed.
    pub max_velocity: f32,
    /// Largest acceleration and deceleration.
    pub max_acceleration: f32,
    /// Largest torque magnitude (Nm).
    pub max_torque: f32,
}

impl Default for CompactDeviceLimits {
    /// ±180, 360 units/s, 5000 units/s², 10 Nm.
    fn default() -> Self {
        Self {
            min_position: -180.0,
            max_position: 180.0,
            max_velocity: 360.0,
            max_acceleration: 5000.0,
            max_torque: 10.0,
        }
    }
}

/// How a [`SimCompactDevice`] is built.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CompactDeviceConfig {
    /// The standard CAN id its commands come on (the bus map's `node`).
    pub node: u16,
    /// The standard CAN id it sends feedback on; must differ from `node`.
    pub feedback_node: u16,
    /// The hash of its motor id: the commands it executes carry it.
    pub motor: MotorHash,
    /// Its limits.
    pub limits: CompactDeviceLimits,
    /// Periodic feedback period (zero: feedback only after REQUIRE_ACK).
    pub feedback_period: Duration,
    /// How an emergency stop stops it: `None` sets the velocity to zero at
    /// once; `Some(d)` brakes at `d` units/s² (finite, positive).
    pub emergency_deceleration: Option<f32>,
    /// Where it starts, at rest and disabled.
    pub initial_position: f32,
}

impl CompactDeviceConfig {
    /// The device for motor `name` on `node`: feedback on `node | 0x400`
    /// every 20 ms (50 Hz), default limits, an emergency stop at once,
    /// starting at 0.
    ///
    /// A `node` that already has the 0x400 bit needs another
    /// `feedback_node`: [`SimCompactDevice::new`] refuses two equal ids.
    pub fn new(node: u16, name: &str) -> Self {
        Self {
            node,
            feedback_node: node | FEEDBACK_NODE_BIT,
            motor: MotorHash::of(name),
            limits: CompactDeviceLimits::default(),
            feedback_period: DEFAULT_FEEDBACK_PERIOD,
            emergency_deceleration: None,
            initial_position: 0.0,
        }
    }
}

/// What the device has done.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct CompactDeviceStats {
    /// Commands executed (emergency stops included).
    pub executed: u64,
    /// Commands equal to the last one executed, answered without executing.
    pub duplicates: u64,
    /// Commands for another motor (another hash), dropped.
    pub ignored: u64,
    /// Commands refused (outside the limits, or a mode it does not run).
    pub refused: u64,
    /// Emergency stops executed.
    pub emergency_stops: u64,
    /// Frames on its CAN id that are not a 24-byte CAN-FD frame or do not
    /// decode, dropped.
    pub bad_frames: u64,
    /// Feedback frames sent (periodic and answers).
    pub feedback_sent: u64,
}

/// Why a command was not executed.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub enum CompactRefusal {
    /// A control mode the device does not run.
    UnsupportedMode {
        /// The mode.
        mode: ControlMode,
    },
    /// A position setpoint outside `[min_position, max_position]`.
    PositionOutsideLimits {
        /// The setpoint.
        setpoint: f32,
        /// The device's lowest position.
        min: f32,
        /// The device's highest position.
        max: f32,
    },
    /// A velocity setpoint faster than the device's `max_velocity` or the
    /// command's `velocity_limit`.
    VelocityAboveLimit {
        /// The setpoint.
        setpoint: f32,
        /// The tighter of the two limits.
        limit: f64,
    },
    /// A torque setpoint larger than the device's `max_torque` or the
    /// command's `torque_limit`.
    TorqueAboveLimit {
        /// The setpoint.
        setpoint: f32,
        /// The tighter of the two limits.
        limit: f64,
    },
    /// A position move with a `velocity_limit` of 0: it could never arrive.
    ZeroVelocityLimit,
    /// A move whose path from the current position and velocity would pass
    /// a position limit (it could not brake in time).
    PathOutsideLimits {
        /// The farthest position past a limit the path would reach.
        reach: f64,
    },
}

impl CompactRefusal {
    /// Whether the refusal is about a position limit (and so sets the
    /// `position_limit` status bit as well as `warning`).
    pub fn is_position(&self) -> bool {
        matches!(
            self,
            Self::PositionOutsideLimits { .. } | Self::PathOutsideLimits { .. }
        )
    }
}

impl fmt::Display for CompactRefusal {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Self::UnsupportedMode { mode } => {
                write!(
                    f,
                    "control mode {} is not run by a compact device",
                    mode.name()
                )
            }
            Self::PositionOutsideLimits { setpoint, min, max } => {
                write!(f, "position {setpoint} is outside [{min}, {max}]")
            }
            Self::VelocityAboveLimit { setpoint, limit } => {
                write!(f, "velocity {setpoint} is faster than the limit {limit}")
            }
            Self::TorqueAboveLimit { setpoint, limit } => {
                write!(f, "torque {setpoint} is larger than the limit {limit}")
            }
            Self::ZeroVelocityLimit => {
                f.write_str("a position move with velocity_limit 0 could never arrive")
            }
            Self::PathOutsideLimits { reach } => write!(
                f,
                "the move from the current velocity would reach {reach}, past a position limit"
            ),
        }
    }
}

/// What the device did with a command it acted on.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum CompactOutcome {
    /// Executed (an emergency stop included).
    Executed,
    /// Not executed.
    Refused(CompactRefusal),
}

impl CompactOutcome {
    /// Whether the command was executed.
    pub fn is_executed(&self) -> bool {
        matches!(self, Self::Executed)
    }
}

/// A command the device acted on (executed or refused; not a duplicate), as
/// its log keeps it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CompactExecution {
    /// When (the device's clock).
    pub at: Duration,
    /// The command's 24 bytes, as they came.
    pub bytes: [u8; LEN],
    /// The command they decode to.
    pub command: CompactCommand,
    /// What the device did.
    pub outcome: CompactOutcome,
}

#[derive(Debug, Clone, Copy)]
#[allow(clippy::large_enum_variant)] // one per device, never moved in a hot loop
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

/// A simulated compact device (see the [module docs](self) for its
/// behaviour).
///
/// ```
/// use std::time::Duration;
/// use motorwire_can::{CanId, Frame};
/// use motorwire_compact::{CompactCommand, ControlMode, FeedbackRecord, Flags, MotorHash, StatusFlag};
/// use motorwire_sim::{CompactDeviceConfig, SimCompactDevice};
///
/// let config = CompactDeviceConfig::new(0x20, "gripper_axis");
/// let mut gripper = SimCompactDevice::new(config)?;
/// let close = CompactCommand {
///     motor: MotorHash::of("gripper_axis"),
///     timestamp_ms: 1_704_067_200_000,
///     control_mode: ControlMode::Position,
///     flags: Flags::REQUIRE_ACK,
///     setpoint: 45.0,
///     velocity_limit: None,
///     torque_limit: None,
/// };
/// let frame = Frame::fd(CanId::standard(0x20)?, &close.encode()?)?;
/// let t = Duration::from_millis(5);
/// let executed = gripper.handle_frame(t, &frame).expect("executed");
/// assert!(executed.outcome.is_executed());
///
/// // The acknowledgement: a 48-byte feedback frame on 0x20 | 0x400.
/// let ack = gripper.poll_transmit().expect("feedback");
/// assert_eq!((ack.id(), ack.len()), (CanId::standard(0x420)?, 48));
/// let record = FeedbackRecord::decode(ack.data())?;
/// assert_eq!((record.motor, record.timestamp_us), (MotorHash::of("gripper_axis"), 5_000));
/// assert!(record.status.contains(StatusFlag::Enabled));
///
/// // Half a second later it is there, at rest.
/// gripper.handle_timeout(Duration::from_millis(505));
/// assert_eq!(gripper.position(), 45.0);
/// assert!(gripper.status().contains(StatusFlag::AtTarget));
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Debug)]
pub struct SimCompactDevice {
    config: CompactDeviceConfig,
    can_id: CanId,
    feedback_id: CanId,
    /// The mode of the last command executed (disabled before any).
    mode: ControlMode,
    /// Its setpoint.
    setpoint: f64,
    /// Held by an emergency stop.
    held: bool,
    /// Why the last command was refused, until one executes.
    refusal: Option<CompactRefusal>,
    last_executed: Option<[u8; LEN]>,
    motion: Motion,
    position: f64,
    velocity: f64,
    acceleration: f64,
    now: Duration,
    next_feedback: Duration,
    out: VecDeque<Frame>,
    stats: CompactDeviceStats,
    log: Option<Vec<CompactExecution>>,
}

fn positive_finite(x: f32) -> bool {
    x.is_finite() && x > 0.0
}

impl SimCompactDevice {
    /// A device, disabled, at rest at its initial position.
    ///
    /// # Errors
    /// [`SimError::InvalidConfig`] for a node or feedback node above 0x7FF,
    /// the two equal, limits that are not finite, positive and ordered, a
    /// start outside them, or an emergency deceleration that is not finite
    /// and positive.
    pub fn new(config: CompactDeviceConfig) -> Result<Self, SimError> {
        let bad = |field: &'static str, reason: String| SimError::InvalidConfig { field, reason };
        let can_id = CanId::standard(config.node).map_err(|e| bad("node", e.to_string()))?;
        let feedback_id = CanId::standard(config.feedback_node)
            .map_err(|e| bad("feedback_node", e.to_string()))?;
        if config.feedback_node == config.node {
            return Err(bad(
                "feedback_node",
                format!(
                    "{:#05x} is the node itself; CAN ids must differ per transmitter",
                    config.node
                ),
            ));
        }
        let l = config.limits;
        if !(l.min_position.is_finite()
            && l.max_position.is_finite()
            && l.min_position < l.max_position)
        {
            return Err(bad(
                "limits",
                "min_position and max_position must be finite with min < max".to_owned(),
            ));
        }
        for (field, v) in [
            ("limits.max_velocity", l.max_velocity),
            ("limits.max_acceleration", l.max_acceleration),
            ("limits.max_torque", l.max_torque),
        ] {
            if !positive_finite(v) {
                return Err(bad(field, "must be finite and positive".to_owned()));
            }
        }
        if !(l.min_position..=l.max_position).contains(&config.initial_position) {
            return Err(bad(
                "initial_position",
                "must lie within the limits".to_owned(),
            ));
        }
        if config
            .emergency_deceleration
            .is_some_and(|d| !positive_finite(d))
        {
            return Err(bad(
                "emergency_deceleration",
                "must be finite and positive".to_owned(),
            ));
        }
        Ok(Self {
            config,
            can_id,
            feedback_id,
            mode: ControlMode::Disabled,
            setpoint: 0.0,
            held: false,
            refusal: None,
            last_executed: None,
            motion: Motion::Holding,
            position: f64::from(config.initial_position),
            velocity: 0.0,
            acceleration: 0.0,
            now: Duration::ZERO,
            next_feedback: Duration::ZERO,
            out: VecDeque::new(),
            stats: CompactDeviceStats::default(),
            log: None,
        })
    }

    /// Keeps a log of every command acted on (for tests; it grows).
    pub fn keep_log(&mut self) {
        self.log.get_or_insert_with(Vec::new);
    }

    /// The commands acted on (executed or refused), oldest first, if
    /// [`SimCompactDevice::keep_log`] was called.
    pub fn log(&self) -> &[CompactExecution] {
        self.log.as_deref().unwrap_or(&[])
    }

    /// The configuration.
    pub fn config(&self) -> &CompactDeviceConfig {
        &self.config
    }

    /// The device's clock: the latest time it was given.
    pub fn now(&self) -> Duration {
        self.now
    }

    /// Position at the last time handled.
    pub fn position(&self) -> f64 {
        self.position
    }

    /// Velocity at the last time handled.
    pub fn velocity(&self) -> f64 {
        self.velocity
    }

    /// Acceleration at the last time handled.
    pub fn acceleration(&self) -> f64 {
        self.acceleration
    }

    /// The torque it applies (Nm): the setpoint in torque mode, else 0.
    pub fn torque(&self) -> f64 {
        if self.mode == ControlMode::Torque && !self.held {
            self.setpoint
        } else {
            0.0
        }
    }

    /// The mode of the last command executed (disabled before any; an
    /// emergency stop keeps the mode it interrupted, see
    /// [`SimCompactDevice::stopped`]).
    pub fn mode(&self) -> ControlMode {
        self.mode
    }

    /// Whether it is enabled: a position, velocity or torque command is
    /// executing and no emergency stop holds.
    pub fn enabled(&self) -> bool {
        !self.held && self.mode != ControlMode::Disabled
    }

    /// Whether an emergency stop holds it (until a command without the flag
    /// is executed).
    pub fn stopped(&self) -> bool {
        self.held
    }

    /// Whether a move, a run or a brake is under way.
    pub fn is_moving(&self) -> bool {
        !matches!(self.motion, Motion::Holding)
    }

    /// Why the last command was refused, until one is executed.
    pub fn refusal(&self) -> Option<CompactRefusal> {
        self.refusal
    }

    /// The counters.
    pub fn stats(&self) -> CompactDeviceStats {
        self.stats
    }

    /// The status word its feedback carries now (see the [module
    /// docs](self)).
    pub fn status(&self) -> StatusFlags {
        let l = self.config.limits;
        let enabled = self.enabled();
        let at_target = enabled
            && match self.mode {
                ControlMode::Position => {
                    !self.is_moving()
                        && (self.position - self.setpoint).abs() <= AT_TARGET_TOLERANCE
                }
                ControlMode::Velocity => {
                    (self.velocity - self.setpoint).abs() <= AT_TARGET_TOLERANCE
                }
                ControlMode::Torque => true,
                _ => false,
            };
        let at_limit = self.position <= f64::from(l.min_position)
            || self.position >= f64::from(l.max_position);
        let flags = [
            (StatusFlag::Enabled, enabled),
            (StatusFlag::Warning, self.refusal.is_some()),
            (StatusFlag::Calibrated, true),
            (StatusFlag::Homed, true),
            (StatusFlag::InMotion, self.is_moving()),
            (StatusFlag::AtTarget, at_target),
            (
                StatusFlag::PositionLimit,
                at_limit || self.refusal.is_some_and(|r| r.is_position()),
            ),
        ];
        flags
            .into_iter()
            .filter(|(_, on)| *on)
            .fold(StatusFlags::EMPTY, |s, (flag, _)| s.with(flag))
    }

    /// The feedback record it would send now.
    pub fn feedback_record(&self) -> FeedbackRecord {
        #[allow(clippy::cast_possible_truncation)]
        let f = |x: f64| x as f32;
        let torque = f(self.torque());
        FeedbackRecord {
            motor: self.config.motor,
            timestamp_us: u64::try_from(self.now.as_micros()).unwrap_or(u64::MAX),
            position: f(self.position),
            velocity: f(self.velocity),
            acceleration: f(self.acceleration),
            torque,
            current: torque / TORQUE_CONSTANT,
            voltage: SUPPLY_VOLTAGE,
            temperature: TEMPERATURE,
            status: self.status(),
            health: 100,
        }
    }

    /// Takes a frame from the bus at `now`. Returns the command it acted on
    /// (executed or refused), if the frame was a new command for it; a
    /// duplicate is answered and returns `None`.
    pub fn handle_frame(&mut self, now: Duration, frame: &Frame) -> Option<CompactExecution> {
        self.update(now);
        if frame.id() != self.can_id {
            return None;
        }
        let bytes: [u8; LEN] = match frame.data().try_into() {
            Ok(b) if frame.is_fd() => b,
            _ => {
                self.stats.bad_frames += 1;
                return None;
            }
        };
        let [h0, h1, h2, h3, ..] = bytes;
        if MotorHash(u32::from_le_bytes([h0, h1, h2, h3])) != self.config.motor {
            self.stats.ignored += 1;
            return None;
        }
        let Ok(command) = CompactCommand::decode(&bytes) else {
            self.stats.bad_frames += 1;
            return None;
        };
        let require_ack = command.flags.contains(Flags::REQUIRE_ACK);
        if self.last_executed == Some(bytes) {
            self.stats.duplicates += 1;
            if require_ack {
                self.send_feedback();
            }
            return None;
        }
        let outcome = self.execute(&command);
        // The new motion's state at its first instant (a move starts
        // accelerating now; a move to where it already is is over).
        self.update(self.now);
        match outcome {
            CompactOutcome::Executed => {
                self.stats.executed += 1;
                self.last_executed = Some(bytes);
                self.refusal = None;
            }
            CompactOutcome::Refused(r) => {
                self.stats.refused += 1;
                self.refusal = Some(r);
            }
        }
        let execution = CompactExecution {
            at: self.now,
            bytes,
            command,
            outcome,
        };
        if let Some(log) = self.log.as_mut() {
            log.push(execution);
        }
        if require_ack {
            self.send_feedback();
        }
        Some(execution)
    }

    fn execute(&mut self, cmd: &CompactCommand) -> CompactOutcome {
        if cmd.flags.contains(Flags::EMERGENCY_STOP) {
            self.emergency_stop();
            return CompactOutcome::Executed;
        }
        match self.admit(cmd) {
            Ok(motion) => {
                self.motion = motion;
                self.mode = cmd.control_mode;
                self.setpoint = f64::from(cmd.setpoint);
                self.held = false;
                CompactOutcome::Executed
            }
            Err(r) => CompactOutcome::Refused(r),
        }
    }

    /// The motion a command asks for, or why it is refused.
    fn admit(&self, cmd: &CompactCommand) -> Result<Motion, CompactRefusal> {
        let l = self.config.limits;
        let setpoint = f64::from(cmd.setpoint);
        let amax = f64::from(l.max_acceleration);
        let velocity_limit = cmd.velocity_limit.map_or(f64::from(l.max_velocity), |v| {
            v.units_per_s().min(f64::from(l.max_velocity))
        });
        match cmd.control_mode {
            ControlMode::Disabled => Ok(self.braking(amax)),
            ControlMode::Position => {
                if !(l.min_position..=l.max_position).contains(&cmd.setpoint) {
                    return Err(CompactRefusal::PositionOutsideLimits {
                        setpoint: cmd.setpoint,
                        min: l.min_position,
                        max: l.max_position,
                    });
                }
                if velocity_limit <= 0.0 {
                    return Err(CompactRefusal::ZeroVelocityLimit);
                }
                self.planned(setpoint, velocity_limit, amax)
            }
            ControlMode::Velocity => {
                if setpoint.abs() > velocity_limit {
                    return Err(CompactRefusal::VelocityAboveLimit {
                        setpoint: cmd.setpoint,
                        limit: velocity_limit,
                    });
                }
                if setpoint == 0.0 {
                    return Ok(self.braking(amax));
                }
                // A run toward the limit it heads for, ending at rest there.
                let limit = if setpoint > 0.0 {
                    l.max_position
                } else {
                    l.min_position
                };
                self.planned(f64::from(limit), setpoint.abs(), amax)
            }
            ControlMode::Torque => {
                let limit = cmd.torque_limit.map_or(f64::from(l.max_torque), |t| {
                    t.nm().min(f64::from(l.max_torque))
                });
                if setpoint.abs() > limit {
                    return Err(CompactRefusal::TorqueAboveLimit {
                        setpoint: cmd.setpoint,
                        limit,
                    });
                }
                Ok(self.braking(amax))
            }
            mode => Err(CompactRefusal::UnsupportedMode { mode }),
        }
    }

    /// A trapezoidal move from the current state to `target` at rest,
    /// refused if it would pass a position limit on the way (or go further
    /// past one it is already beyond).
    fn planned(&self, target: f64, vmax: f64, amax: f64) -> Result<Motion, CompactRefusal> {
        let l = self.config.limits;
        let (lo, hi) = (f64::from(l.min_position), f64::from(l.max_position));
        let req = Request::new(self.position, target, vmax, amax)
            .with_velocities(self.velocity, 0.0)
            .with_profile(motorwire_planner::MotionProfile::Trapezoidal);
        let Ok(profile) = motorwire_planner::plan(&req) else {
            // The limits are finite and positive and the state is finite:
            // a plan that fails is a path the device will not take.
            return Err(CompactRefusal::PathOutsideLimits {
                reach: self.position,
            });
        };
        let ((min, _), (max, _)) = profile.position_extremes();
        // Rounding may put the end of a move onto a limit a hair past it;
        // and a device already past a limit (a gentle emergency brake took
        // it there) may move back in, not further out.
        let lo = lo.min(self.position) - PATH_TOLERANCE;
        let hi = hi.max(self.position) + PATH_TOLERANCE;
        if min < lo {
            return Err(CompactRefusal::PathOutsideLimits { reach: min });
        }
        if max > hi {
            return Err(CompactRefusal::PathOutsideLimits { reach: max });
        }
        Ok(Motion::Profile {
            profile,
            start: self.now,
        })
    }

    /// Brakes from the current velocity at `deceleration` (holding if at
    /// rest).
    fn braking(&self, deceleration: f64) -> Motion {
        if self.velocity == 0.0 {
            Motion::Holding
        } else {
            Motion::Braking {
                start: self.now,
                position: self.position,
                velocity: self.velocity,
                deceleration,
            }
        }
    }

    fn emergency_stop(&mut self) {
        self.stats.emergency_stops += 1;
        self.held = true;
        self.motion = match self.config.emergency_deceleration {
            Some(d) => self.braking(f64::from(d)),
            None => {
                self.velocity = 0.0;
                self.acceleration = 0.0;
                Motion::Holding
            }
        };
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
            Motion::Profile { profile, start } => {
                let t = now.saturating_sub(start).as_secs_f64();
                let s = profile.sample(t);
                self.position = s.position;
                self.velocity = s.velocity;
                self.acceleration = s.acceleration;
                if t >= profile.duration() {
                    self.velocity = 0.0;
                    self.acceleration = 0.0;
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

    fn send_feedback(&mut self) {
        // Every reading is finite (positions stay within finite limits, or
        // within a brake's finite reach of them) and the health is 100, so
        // the record always encodes.
        if let Ok(bytes) = self.feedback_record().encode()
            && let Ok(frame) = Frame::fd(self.feedback_id, &bytes)
        {
            self.out.push_back(frame);
            self.stats.feedback_sent += 1;
        }
    }

    /// Advances to `now`: motion, periodic feedback.
    pub fn handle_timeout(&mut self, now: Duration) {
        self.update(now);
        let now = self.now;
        let period = self.config.feedback_period;
        if !period.is_zero() && now >= self.next_feedback {
            self.send_feedback();
            // On schedule; a device handled late starts a new one from now.
            let next = self.next_feedback.saturating_add(period);
            self.next_feedback = if next > now {
                next
            } else {
                now.saturating_add(period)
            };
        }
    }

    /// The next frame to put on the bus.
    pub fn poll_transmit(&mut self) -> Option<Frame> {
        self.out.pop_front()
    }

    /// When [`SimCompactDevice::handle_timeout`] next has work: feedback, or
    /// the end of a motion.
    pub fn poll_timeout(&self) -> Option<Duration> {
        let feedback = (!self.config.feedback_period.is_zero()).then_some(self.next_feedback);
        let motion_end = match self.motion {
            Motion::Profile { profile, start } => Some(after(start, profile.duration())),
            Motion::Braking {
                start,
                velocity,
                deceleration,
                ..
            } => Some(after(start, velocity.abs() / deceleration)),
            Motion::Holding => None,
        };
        [feedback, motion_end].into_iter().flatten().min()
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

    /// Runs the device on `bus` in real time until `stop` is set, handling
    /// frames as they arrive and its timers when due; `on_execution` sees
    /// each command acted on (executed or refused).
    ///
    /// # Errors
    /// The bus's errors, other than receive timeouts.
    pub fn run(
        &mut self,
        bus: &mut impl CanBus,
        stop: &AtomicBool,
        on_execution: impl FnMut(&CompactExecution),
    ) -> Result<(), SimError> {
        crate::device::run(self, bus, stop, on_execution)
    }
}

/// `start` plus `secs` seconds, saturating.
fn after(start: Duration, secs: f64) -> Duration {
    Duration::try_from_secs_f64(secs.max(0.0)).map_or(Duration::MAX, |d| start.saturating_add(d))
}

impl crate::device::Device for SimCompactDevice {
    type Acted = CompactExecution;
    fn handle_frame(&mut self, now: Duration, frame: &Frame) -> Option<CompactExecution> {
        SimCompactDevice::handle_frame(self, now, frame)
    }
    fn handle_timeout(&mut self, now: Duration) {
        SimCompactDevice::handle_timeout(self, now);
    }
    fn poll_transmit(&mut self) -> Option<Frame> {
        SimCompactDevice::poll_transmit(self)
    }
    fn poll_timeout(&self) -> Option<Duration> {
        SimCompactDevice::poll_timeout(self)
    }
}
