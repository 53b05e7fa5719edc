//! The sans-IO bridge: lines and frames in, frames and output lines out.
//!
//! The engine is split along its seams, after quinn-proto's `Connection`:
//! [`classify`](crate::classify) decides what a line asks for; admission
//! (`Admission`, through [`Bridge::admit`]) refuses what must not run
//! (shutting down, latched, stale, offline, busy); motion is built from
//! the line (`MotionBuilder`: gated and planned against the limits in
//! force); each admitted line becomes one job
//! ([`crate::job`]) with one step per joint, queued on the joint registry
//! ([`crate::joints`]) which keeps one request in flight per joint; phase
//! changes happen in [`Bridge::enter`] only; and every kind of deadline is
//! one entry of the timer table ([`Timer`], [`Bridge::deadline`]).
//!
//! The invariants, each tested under faults and random interleavings:
//! - every input line gets exactly one result;
//! - no request is executed twice (one request in flight per joint, so every
//!   resend falls within the joint's duplicate memory);
//! - an emergency stop goes ahead of everything queued, cancels what is in
//!   flight (never sent again) and answers the lines it cancelled; nothing
//!   commanded before it moves a joint after it;
//! - nothing outside the bus map's limits reaches a frame;
//! - nothing waits without bound: lines beyond [`BridgeConfig::max_pending_lines`]
//!   or a joint's [`BridgeConfig::max_queue_per_joint`] are refused `busy`.

use std::collections::{BTreeMap, BTreeSet, VecDeque};
use std::time::Duration;

use motorwire_can::Frame;
use motorwire_can::client::ClientConfig;
use motorwire_translate::{AngleUnit, BusMap, Limits, LossKind, Report};
use motorwire_wia::{
    Message, MotorCommand, MotorFeedback, MultiAxisCommand, SafetyLimits, SyncMode, Trajectory,
    Validator,
};
use serde_json::Value;

use crate::arrival::{Watch, WatchAxis};
use crate::classify::{ArmAction, Line, MotorAction, RequestKind, classify};
use crate::clocks::ClockOffsets;
use crate::device::plan::{self, Move, Plan};
use crate::device::{
    Answer, Capability, Context, Device, DeviceError, DeviceId, DeviceState, Drivers, Ended,
    Happened, InForce, Lifecycle, MotorOrder, Needs, Outcome,
};
use crate::error::BridgeError;
use crate::job::{
    AwaitKind, Awaiting, Axis, AxisState, Cycle, Job, JobKind, Jobs, LineMeta, Order, Rider,
    Running,
};
use crate::joints::{Joint, Joints, StepRef, Unresolved};
use crate::output::{
    BridgeState, ErrorKind, Event, FeedbackLine, Label, LineRef, LineResult, MotorState, Origin,
    Output, Refusal, StepOutcome, StepReport, Wider, shortest,
};

mod admit;
mod complete;
mod feedback;
mod input;
mod latch;

pub use input::{Classified, Input};
use latch::StopLatch;
use phase::Starting;
mod jobs;
mod limits;
mod links;
mod motion;
mod motor_line;
mod phase;
mod queries;
mod stop;
mod timers;
mod watch;

/// How a [`Bridge`] behaves.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BridgeConfig {
    /// The iRPC client: the bridge's node id, the default wire version
    /// (each joint is spoken to in its bus map `wire`), Ack timeout and
    /// retries (default: node 0x0000, v2.0, 100 ms, 3 retries, one request
    /// in flight per joint).
    pub client: ClientConfig,
    /// Configure and activate every mapped joint on start (default: true).
    pub activate_on_start: bool,
    /// How often each joint's WIA MotorFeedback is emitted (`None`: never).
    /// Default: every 100 ms (10 Hz).
    pub feedback_period: Option<Duration>,
    /// A joint that sent nothing for this long is offline (default: 500 ms,
    /// five of a joint's 100 ms status periods).
    pub offline_after: Duration,
    /// How often ArmReady is broadcast while a joint moves, feeding the
    /// joints' watchdogs (default: 50 ms, a quarter of their 200 ms).
    pub heartbeat_period: Duration,
    /// At the end of input, how long to wait for moves in progress to end
    /// before stopping the joints anyway (default: 30 s).
    pub drain_timeout: Duration,
    /// Unix time in milliseconds at the bridge's time zero: feedback
    /// timestamps, and the age of commands. `None` (the default): the
    /// bridge has no wall clock, feedback timestamps count from zero and
    /// command ages are not checked.
    pub epoch_unix_ms: Option<f64>,
    /// WIA §10.1's clock skew: a command whose timestamp is further than
    /// this in the past or the future is refused `stale` (default: 5
    /// minutes; `None`: not checked). Needs [`BridgeConfig::epoch_unix_ms`].
    pub max_age: Option<Duration>,
    /// Input lines accepted and not yet answered, at most (default 1024);
    /// beyond, a line is refused `busy` at once.
    pub max_pending_lines: usize,
    /// Steps waiting for one joint, at most (default 16); beyond, a line is
    /// refused `busy`. A newer position command replaces a waiting one
    /// (`superseded`), so a stream of moves never fills it.
    pub max_queue_per_joint: usize,
    /// A device link of lines is attached (the Orion arm controller's: its
    /// lines through [`Bridge::poll_link_line`] and
    /// [`Bridge::handle_link_line`]): the map's motors reached over it are
    /// devices of the bridge. Default: false (they are refused, not
    /// attached).
    pub line_link: bool,
    /// How long the line link's controller may take to answer an arm-wide
    /// command (fold, unfold), which it answers once it has run (default:
    /// 30 s).
    pub arm_command_timeout: Duration,
    /// Subscribe every v2.1 and v2.2 joint to its TelemetryStream at this
    /// rate (Hz) when it is configured (`ConfigureTelemetry`, `Periodic`):
    /// its WIA feedback then carries acceleration, torque, current,
    /// voltage, temperature, power and load. `None` (the default): no
    /// subscription (v1 and v2.0 joints have none).
    pub telemetry_hz: Option<u16>,
    /// Take command lines with members their WIA schema does not name
    /// (each reported as a loss, `dropped`), as a lenient reader would.
    /// `false` (the default): such a line is refused `invalid`, naming the
    /// member and the nearest known one (`velocity_limt`: did you mean
    /// velocity_limit?): in a motor command a typo is a safety problem.
    pub allow_unknown_members: bool,
}

/// The default clock skew of [`BridgeConfig::max_age`] (ms): WIA §10.1's
/// five minutes, applied both ways; `motorwire validate --now` judges with
/// the same window by default.
pub const DEFAULT_MAX_AGE_MS: u64 = 300_000;

impl Default for BridgeConfig {
    fn default() -> Self {
        Self {
            client: ClientConfig::default(),
            activate_on_start: true,
            feedback_period: Some(Duration::from_millis(100)),
            offline_after: Duration::from_millis(500),
            heartbeat_period: Duration::from_millis(50),
            drain_timeout: Duration::from_secs(30),
            epoch_unix_ms: None,
            max_age: Some(Duration::from_millis(DEFAULT_MAX_AGE_MS)),
            max_pending_lines: 1024,
            max_queue_per_joint: 16,
            line_link: false,
            arm_command_timeout: Duration::from_secs(30),
            telemetry_hz: None,
            allow_unknown_members: false,
        }
    }
}

/// What the bridge knows about one device (a motor of the bus map).
#[derive(Debug, Clone, PartialEq)]
pub struct JointView {
    /// Its name in the bus map.
    pub name: String,
    /// Its CAN id (an iRPC node, a compact command id; 0 for an Orion
    /// motor, which no frame carries).
    pub node: u16,
    /// Its dialect: `iRPC`, `compact`, `moteus` or `Orion`.
    pub dialect: &'static str,
    /// The version of its dialect it is spoken to in, where the dialect
    /// has versions (an iRPC joint's wire version, `v2.1`).
    pub version: Option<&'static str>,
    /// Whether it was heard from within [`BridgeConfig::offline_after`].
    pub online: bool,
    /// Its lifecycle state as it last said, in no dialect's terms (only
    /// iRPC joints say theirs; `None` for the others and before a report).
    pub state: Option<DeviceState>,
    /// Whether the bridge holds it Active.
    pub active: bool,
    /// Its last feedback (positions in the motor's unit).
    pub feedback: Option<MotorFeedback>,
    /// The target of its last acked move (degrees, iRPC's unit).
    pub target: Option<f64>,
    /// Steps waiting for it, and whether one is in flight.
    pub queued: usize,
}

/// Counters for what the bridge has done.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct BridgeStats {
    /// Input lines taken.
    pub lines: u64,
    /// Lines answered `ok: true`.
    pub ok: u64,
    /// Lines answered `ok: false`.
    pub failed: u64,
    /// Frames handed out to send.
    pub frames_sent: u64,
    /// Frames received that were not iRPC messages for this bridge.
    pub bad_frames: u64,
    /// Feedback lines emitted.
    pub feedback_lines: u64,
    /// Emergency stops acted on (Deactivate sent to every joint).
    pub emergency_stops: u64,
    /// Stop lines that came while a stop was under way and were answered
    /// by it (no frames of their own).
    pub stops_coalesced: u64,
    /// Lines refused `busy`.
    pub busy: u64,
    /// Steps replaced by a newer position command before being sent.
    pub superseded: u64,
    /// Steps cancelled by an emergency stop or an interrupt.
    pub cancelled: u64,
    /// Moves not sent because, from where the device was when their turn
    /// came, their path would have left the limits in force.
    pub refused_at_send: u64,
    /// Stops sent again because the device's feedback showed the first
    /// lost on the bus (a compact device acknowledges a command with
    /// whatever feedback comes next).
    pub stops_sent_again: u64,
}

/// The bridge's phases, each with what it alone keeps. Every change goes
/// through [`Bridge::enter`], which takes only the changes
/// [`Phase::allows`] lists.
#[derive(Debug, PartialEq)]
enum Phase {
    /// Configuring and activating the joints; lines wait.
    Starting(Starting),
    Running,
    /// End of input: finishing lines and moves.
    Draining {
        /// Past this, the joints are stopped whatever runs.
        deadline: Duration,
        /// A job ended: whether the drain is over is looked at once, by
        /// its timer, now.
        recheck: bool,
    },
    /// Stop frames sent; waiting for their answers.
    Stopping,
    Finished,
}

/// Every kind of deadline the bridge keeps: [`Bridge::poll_timeout`] is
/// the earliest of them, and [`Bridge::handle_timeout`] acts on each that
/// is due. Each is read where its state lives ([`Bridge::deadline`]), so
/// no copy of it can go stale.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Timer {
    /// An iRPC request's resend or Ack timeout.
    Requests,
    /// A compact or moteus command's resend or timeout.
    Commands,
    /// The links' own: the Orion line in flight, its recovery and poll, a
    /// moteus controller's poll.
    Link,
    /// The next feedback lines.
    Feedback,
    /// A device silent for [`BridgeConfig::offline_after`] goes offline.
    Liveness,
    /// ArmReady to the joints while one moves.
    Heartbeat,
    /// The end of the drain after the end of input.
    Drain,
    /// A watched line past its time has not arrived.
    Arrival,
    /// A sequential axis waits on one that must arrive by then.
    Sequence,
    /// A held setpoint not renewed within its command timeout.
    Deadman,
    /// A held setpoint must be braked to stay within a position limit.
    LimitBrake,
    /// A trajectory's next segment is due.
    Segment,
    /// A request line's answer is overdue.
    Answer,
    /// Started: the devices not yet read are taken as silent, and the
    /// bridge is ready.
    Settle,
}

impl Timer {
    const ALL: [Self; 14] = [
        Self::Requests,
        Self::Commands,
        Self::Link,
        Self::Feedback,
        Self::Liveness,
        Self::Heartbeat,
        Self::Drain,
        Self::Arrival,
        Self::Sequence,
        Self::Deadman,
        Self::LimitBrake,
        Self::Segment,
        Self::Answer,
        Self::Settle,
    ];
}

/// The deadlines the bridge sets itself (the others are read from the
/// state they belong to).
#[derive(Debug, Clone, Copy, Default)]
struct Timers {
    feedback: Option<Duration>,
    heartbeat: Option<Duration>,
}

/// A line that waits for startup to end.
#[derive(Debug, PartialEq)]
struct Waiting {
    at: Duration,
    meta: LineMeta,
    text: String,
}

/// The bridge, sans-IO: feed it input lines ([`Bridge::handle_line`]),
/// frames from the bus ([`Bridge::handle_frame`]) and the time
/// ([`Bridge::handle_timeout`]); put [`Bridge::poll_transmit`]'s frames on
/// the bus, then call [`Bridge::flushed`]; print [`Bridge::poll_output`]'s
/// lines. [`crate::Runner`] does all that in real time.
///
/// ```
/// use std::time::Duration;
/// use motorwire_bridge::{Bridge, BridgeConfig, ErrorKind, Origin};
/// use motorwire_translate::BusMap;
///
/// let map = BusMap::from_toml(
///     "[motors.elbow]\ndialect = \"irpc\"\nnode = 0x12\n\
///      limits = { max_velocity = 120, max_acceleration = 500 }",
/// )?;
/// let config = BridgeConfig { activate_on_start: false, ..BridgeConfig::default() };
/// let mut bridge = Bridge::new(map, config)?;
/// bridge.start(Duration::ZERO);
/// // A line that is not JSON never reaches the bus: it is answered at once.
/// bridge.handle_line(Duration::ZERO, Origin(0), "{oops");
/// let result = std::iter::from_fn(|| bridge.poll_output()).find_map(|o| o.result().cloned()).unwrap();
/// assert_eq!(result.error.unwrap().kind, ErrorKind::Invalid);
/// assert!(bridge.poll_transmit().is_none());
/// // A move: SetTargetV2 (variant 5) from 0x0000 to 0x12, msg_id 1.
/// bridge.handle_line(
///     Duration::ZERO,
///     Origin(0),
///     r#"{"motor_id":"elbow","timestamp":0,"control_mode":"position","setpoint":90}"#,
/// );
/// let frame = bridge.poll_transmit().unwrap();
/// assert_eq!(frame.data()[..4], [0x00, 0x12, 0x01, 0x05]);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Debug)]
pub struct Bridge {
    /// [`Bridge::poll_timeout`] as last computed, until the bridge next
    /// changes (`None`: to be computed). Every `&mut self` entry point
    /// clears it; in debug builds each read is checked against a fresh
    /// computation.
    next_deadline: std::cell::Cell<Option<Option<Duration>>>,
    map: BusMap,
    config: BridgeConfig,
    validator: Validator,
    /// One driver per dialect: every request in flight, every frame and
    /// line to send.
    drivers: Drivers,
    joints: Joints,
    jobs: Jobs,
    line_numbers: BTreeMap<Origin, u64>,
    /// The emergency stop's latch.
    stop: StopLatch,
    /// Each client's clock against the bridge's, learned from its lines:
    /// the least (arrival on the bridge's clock − timestamp), in ms. A
    /// client whose clock runs ahead has its timestamps judged in its own
    /// clock ([`ClockOffsets`]).
    clocks: ClockOffsets,
    phase: Phase,
    /// Motion lines whose moves are watched for arrival.
    arrivals: Vec<Watch>,
    /// Each motor's limits as the bus map gives them (SafetyLimits lines
    /// tighten `map`'s, never beyond these).
    base_limits: BTreeMap<String, Limits>,
    /// Emergency decelerations given by SafetyLimits lines (recorded and
    /// reported; iRPC cannot carry them).
    emergency_decel: BTreeMap<String, f64>,
    /// The ids of the jobs [`Self::finish_jobs`] found done, kept between
    /// calls so that finding them allocates nothing.
    done_scratch: Vec<u64>,
    /// [`Bridge::open_job`]'s list of the steps it queues, kept between
    /// jobs.
    steps_scratch: Vec<(DeviceId, StepRef, Option<Takes>)>,
    timers: Timers,
    out: VecDeque<Output>,
    now: Duration,
    stats: BridgeStats,
}

/// How long past its Ack timeouts a request line waits for its answer.
const ANSWER_MARGIN: Duration = Duration::from_millis(500);

/// How long a calibration may run, past its phases' own timeouts.
const CALIBRATION_MARGIN: Duration = Duration::from_secs(5);

/// How far ahead of a motor's last feedback a velocity setpoint is judged
/// against a position limit (the motor goes on until the next feedback is
/// heard and its stop is sent): a poll of a 50 Hz query rate and a little.
const BRAKE_LOOKAHEAD: Duration = Duration::from_millis(25);
/// How fast a motor going at speed `v` and speeding up at `a` goes `t`
/// seconds on, and how far it gets meanwhile.
fn ahead(v: f64, a: f64, t: f64) -> (f64, f64) {
    (v + a * t, v * t + a * t * t / 2.0)
}

/// How long after a limit brake a motor's reports may still show it going
/// on toward the limit as fast before it is braked again.
const REBRAKE_AFTER: Duration = Duration::from_millis(50);

/// How long a stop taken on an acknowledgement that may have been another
/// frame's is judged by the device's feedback ([`Bridge::confirm_stop`]).
const CONFIRM_STOP_FOR: Duration = Duration::from_secs(1);

/// How often such a stop is sent again before the emergency stop.
const MAX_STOP_RESENDS: u8 = 5;

impl BridgeConfig {
    /// Whether the configuration can run: no zero period, timeout or
    /// bound, a finite epoch.
    fn check(&self) -> Result<(), BridgeError> {
        if self.feedback_period == Some(Duration::ZERO) {
            return Err(BridgeError::Config("the feedback period must not be zero"));
        }
        if self.offline_after.is_zero() || self.heartbeat_period.is_zero() {
            return Err(BridgeError::Config(
                "the offline timeout and the heartbeat period must not be zero",
            ));
        }
        if self.epoch_unix_ms.is_some_and(|e| !e.is_finite()) {
            return Err(BridgeError::Config("the epoch must be a finite number"));
        }
        if self.max_pending_lines == 0 || self.max_queue_per_joint == 0 {
            return Err(BridgeError::Config(
                "max_pending_lines and max_queue_per_joint must be at least 1",
            ));
        }
        Ok(())
    }
}

/// The validator `config` asks for, with the paths a stop takes warmed:
/// the first invalid command the schema reports on builds its error
/// machinery lazily (hash seeds drawn from the OS on first use). Better
/// when the bridge is made, before any joint moves, than inside the first
/// emergency stop: on a machine whose random pool is not yet initialised
/// (early boot) that first draw can wait.
fn warmed_validator(config: &BridgeConfig) -> Validator {
    let validator = Validator::new().deny_unknown_members(!config.allow_unknown_members);
    let _ = classify(
        &validator,
        r#"{"motor_id":"-","control_mode":"warp","safety_limits":{"emergency_stop":true}}"#,
    );
    validator
}

fn us(d: Duration) -> u64 {
    u64::try_from(d.as_micros()).unwrap_or(u64::MAX)
}

impl Bridge {
    /// The most motors one bridge serves, every dialect counted: what one
    /// CAN-FD bus carries with room to spare. A simulated iRPC joint
    /// reports its position every 10 ms and its state every 100 ms, about
    /// 110 frames a second; 64 of them take some 7,000 of the roughly
    /// 10,000 frames a second a CAN-FD bus carries at 5 Mbit/s, leaving
    /// the rest for commands, heartbeats and retries. Startup is linear in
    /// the motors: at this many, `motorwire bridge --bus sim` is ready well
    /// within a second. A larger map is refused at once
    /// ([`BridgeError::TooManyDevices`]); its motors belong on more buses,
    /// a bridge each.
    pub const MAX_DEVICES: usize = 64;

    /// Whether a bridge serves `map`: at most [`Bridge::MAX_DEVICES`]
    /// motors. [`Bridge::new`] asks it first; a tool that reads a map for
    /// the bridge asks it to refuse the map as the bridge would.
    ///
    /// ```
    /// use motorwire_bridge::{Bridge, BridgeError};
    /// use motorwire_translate::BusMap;
    /// let one = BusMap::from_toml("[motors.elbow]\ndialect = \"irpc\"\nnode = 0x12")?;
    /// assert!(Bridge::check_map(&one).is_ok());
    /// let many: String = (0..=Bridge::MAX_DEVICES)
    ///     .map(|i| format!("[motors.j{i}]\ndialect = \"irpc\"\nnode = {}\n", 0x10 + i))
    ///     .collect();
    /// let err = Bridge::check_map(&BusMap::from_toml(&many)?).unwrap_err();
    /// assert!(matches!(err, BridgeError::TooManyDevices { count: 65, limit: 64 }));
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    ///
    /// # Errors
    /// [`BridgeError::TooManyDevices`], naming the count and the limit.
    pub fn check_map(map: &BusMap) -> Result<(), BridgeError> {
        let count = map.motors().count();
        if count > Self::MAX_DEVICES {
            return Err(BridgeError::TooManyDevices {
                count,
                limit: Self::MAX_DEVICES,
            });
        }
        Ok(())
    }

    /// A bridge for the iRPC joints of `map`, each spoken to in its own
    /// wire version.
    ///
    /// # Errors
    /// [`BridgeError::TooManyDevices`] when the map names more motors than
    /// [`Bridge::MAX_DEVICES`]; [`BridgeError::NoJoints`] when the map has
    /// no iRPC joint;
    /// [`BridgeError::Config`] for a zero period, timeout or bound, a
    /// non-finite epoch, or a client node id beyond 11 bits.
    pub fn new(map: BusMap, config: BridgeConfig) -> Result<Self, BridgeError> {
        config.check()?;
        // The client's configuration is judged first (a node id beyond 11
        // bits), whatever the map holds.
        motorwire_can::client::Client::new(config.client)?;
        Self::check_map(&map)?;
        let joints = Joints::new(
            map.motors()
                .filter_map(|m| {
                    let (node, device) = Device::of(m, config.line_link)?;
                    Some(Joint::of(m, node, device))
                })
                .collect(),
        );
        if joints.is_empty() {
            return Err(BridgeError::NoJoints);
        }
        let mut drivers = Drivers::new(
            config.client,
            config.arm_command_timeout,
            config.epoch_unix_ms.unwrap_or(0.0),
            &joints,
            crate::device::ServoSetup {
                map: &map,
                // At the feedback rate, and often enough that a servo that
                // answers is never taken offline between two reads.
                period: config
                    .feedback_period
                    .unwrap_or(Duration::from_millis(100))
                    .min(config.offline_after / 4)
                    .max(Duration::from_millis(1)),
            },
        )?;
        // The map's limits are in force from the start: a driver that
        // sends by itself, and a device that holds bounds of its own,
        // follow them.
        for (ji, j) in joints.with_ids() {
            if let Some(m) = map.motor(j.identity.name()) {
                drivers.limits_changed(ji, &InForce::of(m.unit, &m.limits));
            }
        }
        let base_limits = map.motors().map(|m| (m.name.clone(), m.limits)).collect();
        let validator = warmed_validator(&config);
        Ok(Self {
            next_deadline: std::cell::Cell::new(None),
            map,
            config,
            validator,
            drivers,
            joints,
            jobs: Jobs::default(),
            line_numbers: BTreeMap::new(),
            stop: StopLatch::default(),
            clocks: ClockOffsets::default(),
            phase: Phase::Starting(Starting::default()),
            done_scratch: Vec::new(),
            steps_scratch: Vec::new(),
            arrivals: Vec::new(),
            base_limits,
            emergency_decel: BTreeMap::new(),
            timers: Timers::default(),
            out: VecDeque::new(),
            now: Duration::ZERO,
            stats: BridgeStats::default(),
        })
    }

    /// The bus map.
    pub fn map(&self) -> &BusMap {
        &self.map
    }

    /// How the bridge was configured.
    pub fn config(&self) -> &BridgeConfig {
        &self.config
    }

    /// Counters for what the bridge has done.
    pub fn stats(&self) -> BridgeStats {
        self.stats
    }

    /// Whether the emergency stop is latched.
    pub fn is_latched(&self) -> bool {
        self.stop.is_latched()
    }

    /// Whether startup is over and lines are being served.
    pub fn is_ready(&self) -> bool {
        matches!(self.phase, Phase::Running | Phase::Draining { .. })
    }

    /// Whether the bridge has stopped the joints and has nothing more to do.
    pub fn is_finished(&self) -> bool {
        matches!(self.phase, Phase::Finished)
    }

    /// The validator lines are read with.
    pub(crate) const fn validator(&self) -> &Validator {
        &self.validator
    }

    /// The next frame to put on the bus.
    pub fn poll_transmit(&mut self) -> Option<Frame> {
        let f = self.drivers.poll_transmit()?;
        self.changed();
        self.stats.frames_sent += 1;
        Some(f)
    }

    /// Tells the bridge that every frame [`Bridge::poll_transmit`] gave
    /// out is on the bus as of `now`: the lines that sent them take `now`
    /// as their input-to-bus latency.
    pub(super) fn on_flushed(&mut self, now: Duration) {
        for job in self.jobs.values_mut() {
            if job.unflushed {
                job.unflushed = false;
                job.last_frame = Some(now);
            }
        }
        self.finish_jobs();
    }

    /// The next line to print.
    pub fn poll_output(&mut self) -> Option<Output> {
        self.out.pop_front()
    }
}

/// What a newer motion step takes over on its device when it is queued
/// (`Bridge::supersede`): `replaces`, a position move or a stream's
/// setpoint; `timed`, a trajectory's step.
#[derive(Debug, Clone, Copy)]
struct Takes {
    replaces: bool,
    timed: bool,
}

/// `v` as the shortest decimal of the nearest f32 (for what is said, not
/// measured).
fn short_unit(v: f64) -> f64 {
    #[allow(clippy::cast_possible_truncation)]
    shortest(f64::from(v as f32))
}

fn shortest_feedback(mut f: MotorFeedback) -> MotorFeedback {
    f.position = shortest(f.position);
    f.velocity = shortest(f.velocity);
    f.torque = shortest(f.torque);
    for x in [
        &mut f.acceleration,
        &mut f.current,
        &mut f.voltage,
        &mut f.temperature,
        &mut f.power,
        &mut f.control_effort,
    ] {
        *x = x.map(shortest);
    }
    f
}

#[cfg(test)]
mod tests;
