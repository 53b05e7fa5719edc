//! The sans-IO bridge: lines and frames in, frames and output lines out.
//!
//! The engine is split along its seams, after quinn-proto's `Connection`:
//! [`classify`](crate::classify) decides what a line asks for; admission
//! ([`Bridge::admit`]) refuses what must not run (shutting down, latched,
//! stale, offline, busy); each admitted line becomes one job
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

pub use crate::device::orion::{MAX_BAD_LINE_EVENTS, MAX_ORION_LINE, POLL as ORION_POLL};

use motorwire_can::Frame;
use motorwire_can::client::ClientConfig;
use motorwire_irpc::{CalibrationRequest, LifecycleState, Payload, PayloadKind};
use motorwire_orion::ArmCommand;
use motorwire_translate::{
    AngleUnit, BusMap, Limits, LossKind, Report, multi_axis_to_irpc_from, trajectory_to_irpc,
};
use motorwire_wia::{
    Message, MotorCommand, MotorFeedback, MultiAxisCommand, SafetyLimits, SyncMode, Trajectory,
    Validator,
};
use serde_json::Value;

use crate::arrival::{Watch, WatchAxis};
use crate::classify::{Input, MotorAction, RequestKind, classify};
use crate::clocks::ClockOffsets;
use crate::device::{
    Answer, Capability, Context, Device, Drivers, Ended, Happened, InForce, MotorOrder, Moving,
    Outcome,
};
use crate::error::BridgeError;
use crate::job::{
    AwaitKind, Awaiting, Axis, AxisState, Cycle, Job, JobKind, Jobs, LineMeta, Order,
    REPLACED_TRAJECTORY, Rider, axis_mut,
};
use crate::joints::{Joint, StepRef, Unresolved};
use crate::output::{
    BridgeRule, BridgeState, Broke, ErrorBody, ErrorKind, Event, FeedbackLine, Label, LineRef,
    LineResult, MotorState, Origin, Output, StepOutcome, StepReport, shortest,
};

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
    /// An Orion arm controller is attached (its lines through
    /// [`Bridge::poll_orion_line`] and [`Bridge::handle_orion_line`]): the
    /// map's Orion motors are devices of the bridge. Default: false (they
    /// are refused).
    pub orion: bool,
    /// How long the Orion controller may take to answer a fold or unfold
    /// command, which it answers once it has run (default: 30 s).
    pub orion_command_timeout: Duration,
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
            orion: false,
            orion_command_timeout: Duration::from_secs(30),
            telemetry_hz: None,
            allow_unknown_members: false,
        }
    }
}

/// What the bridge knows about one iRPC joint.
#[derive(Debug, Clone, PartialEq)]
pub struct JointView {
    /// Its name in the bus map.
    pub name: String,
    /// Its node id.
    pub node: u16,
    /// The wire version it is spoken to in.
    pub wire: motorwire_irpc::WireVersion,
    /// Whether it was heard from within [`BridgeConfig::offline_after`].
    pub online: bool,
    /// Its lifecycle state as its last JointStatus said.
    pub state: Option<LifecycleState>,
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

/// The bridge's phases. Every change goes through [`Bridge::enter`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Phase {
    /// Configuring and activating the joints; lines wait.
    Starting,
    Running,
    /// End of input: finishing lines and moves.
    Draining {
        deadline: Duration,
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
    /// The drivers' own: an iRPC or compact request's Ack timeout and
    /// resend, the Orion line in flight, the Orion link's poll.
    Drivers,
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
    const ALL: [Self; 12] = [
        Self::Drivers,
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
#[derive(Debug)]
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
    joints: Vec<Joint>,
    jobs: Jobs,
    next_job: u64,
    waiting: VecDeque<Waiting>,
    line_numbers: BTreeMap<Origin, u64>,
    latched: bool,
    /// Unix ms of the last emergency stop, on the bridge's clock (with
    /// [`BridgeConfig::epoch_unix_ms`]): with [`BridgeConfig::max_age`] in
    /// force, a command stamped before it was written before the stop, and
    /// is refused `stale_before_stop`.
    last_stop_unix_ms: Option<f64>,
    /// When the last emergency stop was taken, on the bridge's own clock
    /// (any stop, the bridge's own too): a line that had reached the
    /// bridge before it was written before it, whatever its timestamp
    /// says, and is refused `stale_before_stop`.
    last_stop_at: Option<Duration>,
    /// Each client's clock against the bridge's, learned from its lines:
    /// the least (arrival on the bridge's clock − timestamp), in ms. A
    /// client whose clock runs ahead has its timestamps judged in its own
    /// clock ([`ClockOffsets`]).
    clocks: ClockOffsets,
    /// For each joint, what the release sends it (those active, or being
    /// started, when the stop came).
    resume: BTreeMap<usize, Vec<Payload>>,
    phase: Phase,
    /// When the latest stop line arrived: a release that arrived before it
    /// is not obeyed.
    last_stop_arrival: Option<Duration>,
    /// Motion lines whose moves are watched for arrival.
    arrivals: Vec<Watch>,
    /// Each motor's limits as the bus map gives them (SafetyLimits lines
    /// tighten `map`'s, never beyond these).
    base_limits: BTreeMap<String, Limits>,
    /// Emergency decelerations given by SafetyLimits lines (recorded and
    /// reported; iRPC cannot carry them).
    emergency_decel: BTreeMap<String, f64>,
    /// The input ended during startup: drain (until this deadline) once ready.
    drain_after_start: Option<Duration>,
    /// Draining, a line just finished: whether the drain may end is
    /// looked at once.
    drain_recheck: bool,
    /// The ids of the jobs [`Self::finish_jobs`] found done, kept between
    /// calls so that finding them allocates nothing.
    done_scratch: Vec<u64>,
    /// [`Bridge::open_job`]'s list of the steps it queues, kept between
    /// jobs.
    steps_scratch: Vec<(usize, StepRef, Option<Takes>)>,
    /// Started: ready once every online device has been read, or then.
    settle_until: Option<Duration>,
    /// Clients that connected during startup, greeted when it ends.
    to_greet: Vec<Origin>,
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
        if config.feedback_period == Some(Duration::ZERO) {
            return Err(BridgeError::Config("the feedback period must not be zero"));
        }
        if config.offline_after.is_zero() || config.heartbeat_period.is_zero() {
            return Err(BridgeError::Config(
                "the offline timeout and the heartbeat period must not be zero",
            ));
        }
        if config.epoch_unix_ms.is_some_and(|e| !e.is_finite()) {
            return Err(BridgeError::Config("the epoch must be a finite number"));
        }
        if config.max_pending_lines == 0 || config.max_queue_per_joint == 0 {
            return Err(BridgeError::Config(
                "max_pending_lines and max_queue_per_joint must be at least 1",
            ));
        }
        // The client's configuration is judged first (a node id beyond 11
        // bits), whatever the map holds.
        motorwire_can::client::Client::new(config.client)?;
        Self::check_map(&map)?;
        let joints: Vec<Joint> = map
            .motors()
            .filter_map(|m| {
                let (node, device) = Device::of(m, config.orion)?;
                Some(Joint::of(m, node, device))
            })
            .collect();
        if joints.is_empty() {
            return Err(BridgeError::NoJoints);
        }
        let mut drivers = Drivers::new(
            config.client,
            config.orion_command_timeout,
            config.epoch_unix_ms.unwrap_or(0.0),
            &joints,
        )?;
        // The map's limits are in force from the start: a driver that
        // sends by itself, and a device that holds bounds of its own,
        // follow them.
        for (ji, j) in joints.iter().enumerate() {
            if let Some(m) = map.motor(&j.name) {
                drivers.limits_changed(ji, &InForce::of(m.unit, &m.limits));
            }
        }
        let base_limits = map.motors().map(|m| (m.name.clone(), m.limits)).collect();
        let validator = Validator::new().deny_unknown_members(!config.allow_unknown_members);
        // Warm the paths a stop takes: the first invalid command the
        // schema reports on builds its error machinery lazily (hash seeds
        // drawn from the OS on first use). Better here, before any joint
        // moves, than inside the first emergency stop: on a machine whose
        // random pool is not yet initialised (early boot) that first draw
        // can wait.
        let _ = classify(
            &validator,
            r#"{"motor_id":"-","control_mode":"warp","safety_limits":{"emergency_stop":true}}"#,
        );
        Ok(Self {
            next_deadline: std::cell::Cell::new(None),
            map,
            config,
            validator,
            drivers,
            joints,
            jobs: Jobs::default(),
            next_job: 0,
            waiting: VecDeque::new(),
            line_numbers: BTreeMap::new(),
            latched: false,
            last_stop_unix_ms: None,
            last_stop_at: None,
            clocks: ClockOffsets::default(),
            resume: BTreeMap::new(),
            phase: Phase::Starting,
            drain_after_start: None,
            drain_recheck: false,
            done_scratch: Vec::new(),
            steps_scratch: Vec::new(),
            settle_until: None,
            to_greet: Vec::new(),
            last_stop_arrival: None,
            arrivals: Vec::new(),
            base_limits,
            emergency_decel: BTreeMap::new(),
            timers: Timers::default(),
            out: VecDeque::new(),
            now: Duration::ZERO,
            stats: BridgeStats::default(),
        })
    }

    /// Anchors a bridge that keeps a wall clock
    /// ([`BridgeConfig::epoch_unix_ms`] given) at `unix_ms` for its time
    /// zero: the runner calls it where its clock starts, so the Unix time
    /// the bridge reckons (a stop's, which commands stamped before it are
    /// held to; feedback timestamps) is the host's, not behind it by the
    /// time it took to start.
    pub(crate) fn anchor_epoch(&mut self, unix_ms: f64) {
        self.changed();
        if self.config.epoch_unix_ms.is_some() && unix_ms.is_finite() {
            self.config.epoch_unix_ms = Some(unix_ms);
            self.drivers.set_epoch(unix_ms);
        }
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
        self.latched
    }

    /// Whether startup is over and lines are being served.
    pub fn is_ready(&self) -> bool {
        matches!(self.phase, Phase::Running | Phase::Draining { .. })
    }

    /// Whether the bridge has stopped the joints and has nothing more to do.
    pub fn is_finished(&self) -> bool {
        self.phase == Phase::Finished
    }

    /// Input lines accepted and not yet answered.
    pub fn pending_lines(&self) -> usize {
        self.waiting.len()
            + self
                .jobs
                .values()
                .filter(|j| j.kind == JobKind::Command)
                .count()
    }

    /// The joints, in the bus map's order.
    pub fn joints(&self) -> impl Iterator<Item = JointView> + '_ {
        self.joints.iter().map(|j| JointView {
            name: j.name.clone(),
            node: j.node,
            wire: j.device.wire(),
            online: j.online,
            state: j.state,
            active: j.active,
            feedback: j.feedback.clone(),
            target: j.target,
            queued: j.queue.len() + usize::from(j.busy.is_some()),
        })
    }

    /// What the bridge knows of its motors now: latched or not, and each
    /// motor's state (online, active, position and velocity as last
    /// reported, the target of its last move, whether it moves, a fault),
    /// positions in each motor's unit. `ready`, `{"query":"state"}` and
    /// [`Bridge::greet`] say it.
    pub fn state(&self) -> BridgeState {
        BridgeState {
            latched: self.latched,
            motors: self.joints.iter().map(|j| self.motor_state(j)).collect(),
        }
    }

    fn motor_state(&self, j: &Joint) -> MotorState {
        let unit = self
            .map
            .motor(&j.name)
            .map_or(AngleUnit::Degrees, |m| m.unit);
        // Read once it reported where it is (a status alone says not).
        let read = j.feedback.as_ref().filter(|_| j.motion.is_some());
        MotorState {
            motor_id: j.name.clone(),
            online: j.online,
            active: j.active,
            position: read.map(|f| shortest(f.position)),
            velocity: read.map(|f| shortest(f.velocity)),
            target: j.target.map(|t| short_unit(unit.from_degrees(t))),
            moving: j.moving_until > self.now,
            fault: j.needs_reset.clone(),
        }
    }

    fn ready_event(&self) -> Event {
        Event::Ready {
            joints: self.joints.iter().map(|j| j.name.clone()).collect(),
            state: self.state(),
        }
    }

    /// A client that connected (and authenticated) at `now` is greeted,
    /// for it alone ([`Output::ToOne`]), exactly once: with `ready` and
    /// the state now once the bridge is ready (at once, or when it becomes
    /// ready), or with `stopping` when the bridge is past serving. A
    /// runner holds everyone's feedback and events from such a client
    /// until its greeting, so the greeting is its first line.
    pub fn greet(&mut self, now: Duration, origin: Origin) {
        self.changed();
        self.now = self.now.max(now);
        match self.phase {
            Phase::Starting => self.to_greet.push(origin),
            Phase::Running | Phase::Draining { .. } => {
                let event = self.ready_event();
                self.out.push_back(Output::ToOne { origin, event });
            }
            Phase::Stopping | Phase::Finished => {
                let event = Event::Stopping {
                    reason: "the bridge is stopping the joints".to_owned(),
                };
                self.out.push_back(Output::ToOne { origin, event });
            }
        }
    }

    /// The clients waiting for `ready` greeted with `event`.
    fn greet_waiting(&mut self, event: &Event) {
        for origin in std::mem::take(&mut self.to_greet) {
            self.out.push_back(Output::ToOne {
                origin,
                event: event.clone(),
            });
        }
    }

    /// Started and every device that answers read (or silent past the
    /// offline time): ready.
    fn try_ready(&mut self) {
        let Some(until) = self.settle_until else {
            return;
        };
        let read = self.joints.iter().all(|j| !j.online || j.motion.is_some());
        if self.phase == Phase::Starting && (read || self.now >= until) {
            self.enter(Phase::Running);
        }
    }

    // ---- phases ---------------------------------------------------------

    /// The one place the phase changes.
    fn enter(&mut self, to: Phase) {
        let from = self.phase;
        match (from, to) {
            (Phase::Finished, _) => {}
            (_, Phase::Running) => {
                self.phase = Phase::Running;
                self.settle_until = None;
                let ready = self.ready_event();
                // Everyone's first, then the greetings: a runner holds
                // everyone's lines from a client until its greeting, so
                // each waiting client has one ready, as its first line.
                self.out.push_back(Output::Event(ready.clone()));
                self.greet_waiting(&ready);
                while let Some(w) = self.waiting.pop_front() {
                    self.take_line(w.at, w.meta, &w.text);
                }
                if let Some(deadline) = self.drain_after_start.take() {
                    self.enter(Phase::Draining { deadline });
                }
            }
            (Phase::Starting | Phase::Running, Phase::Draining { .. }) => {
                self.phase = to;
                self.out.push_back(Output::Event(Event::Stopping {
                    reason: "end of input".to_owned(),
                }));
                self.end_open_motion();
            }
            (Phase::Stopping, Phase::Draining { .. }) => {}
            (_, Phase::Stopping) if from != Phase::Stopping => {
                self.phase = Phase::Stopping;
                self.fail_watches(|_| true, "the bridge is stopping the joints");
                let axes = self.every_joint(&[Payload::Deactivate]);
                self.open_job(
                    None,
                    JobKind::Shutdown,
                    self.now,
                    axes,
                    Report::default(),
                    Vec::new(),
                );
            }
            (_, Phase::Finished) => self.phase = Phase::Finished,
            _ => {}
        }
    }

    /// Starts: configures and activates every joint (unless
    /// [`BridgeConfig::activate_on_start`] is false). Lines that arrive
    /// before the joints are ready wait for them (an emergency stop does
    /// not: it is acted on at once).
    pub fn start(&mut self, now: Duration) {
        self.changed();
        self.now = now;
        self.timers.feedback = self.config.feedback_period.map(|_| now);
        if !self.config.activate_on_start {
            self.enter(Phase::Running);
            return;
        }
        let mut axes = self.every_joint(&[Payload::Configure, Payload::Activate]);
        for a in &mut axes {
            if let Some(t) = self.telemetry_subscription(a.joint) {
                a.payloads.push_back(Order::from(t));
            }
        }
        self.open_job(
            None,
            JobKind::Startup,
            now,
            axes,
            Report::default(),
            Vec::new(),
        );
    }

    /// End of input: lines in flight and moves in progress finish (up to
    /// [`BridgeConfig::drain_timeout`]), then every joint is deactivated.
    pub fn finish(&mut self, now: Duration) {
        self.changed();
        self.now = self.now.max(now);
        if matches!(self.phase, Phase::Starting | Phase::Running) {
            // Lines still waiting for startup are served first.
            let deadline = self.now.saturating_add(self.config.drain_timeout);
            if self.phase == Phase::Starting {
                // Served once the joints are ready, then drained.
                self.drain_after_start = Some(deadline);
            } else {
                self.enter(Phase::Draining { deadline });
            }
        }
        self.handle_timeout(self.now);
    }

    /// At the end of input, motion that would not end by itself stops at
    /// once: a trajectory looping forever (it ends with the segment under
    /// way), one whose start is still to come (never started), and a
    /// velocity or torque setpoint (brought to velocity 0, as the deadman
    /// does). Finite moves may finish within the drain.
    fn end_open_motion(&mut self) {
        let now = self.now;
        let open = |job: &Job| {
            job.kind == JobKind::Command
                && (job.axes.iter().any(|a| a.cycle.is_some() && !a.is_done())
                    || job
                        .axes
                        .iter()
                        .all(|a| !a.begun && a.due.front().is_some_and(|due| *due > now))
                    // A velocity or torque setpoint still to be sent, or
                    // sent and not answered (the deadman then watches it).
                    || job.axes.iter().any(|a| {
                        !a.is_done()
                            && (a.payloads.iter().any(Order::holds_setpoint)
                                || matches!(a.state, AxisState::InFlight { payload, .. } if payload.holds_setpoint()))
                    }))
        };
        self.cancel_where(
            "cancelled by the end of input: it would not end by itself",
            open,
        );
        let held = self.joints_where(|j| j.deadman.is_some());
        for &ji in &held {
            if let Some(j) = self.joints.get_mut(ji) {
                j.deadman = None;
            }
        }
        self.hold_still(now, held, false);
        self.finish_jobs();
    }

    /// Interrupted (a signal): everything queued or in flight is cancelled
    /// and every joint deactivated now.
    pub fn interrupt(&mut self, now: Duration) {
        self.changed();
        self.now = self.now.max(now);
        if matches!(self.phase, Phase::Stopping | Phase::Finished) {
            return;
        }
        let stopping = Event::Stopping {
            reason: "interrupted".to_owned(),
        };
        self.out.push_back(Output::Event(stopping.clone()));
        self.greet_waiting(&stopping);
        let waiting: Vec<Waiting> = self.waiting.drain(..).collect();
        for w in waiting {
            self.stats.lines += 1;
            self.refuse(
                &w.meta,
                ErrorBody::new(
                    ErrorKind::Cancelled,
                    "the bridge was interrupted before the line was served",
                ),
            );
        }
        self.cancel_everything("cancelled: the bridge was interrupted");
        self.enter(Phase::Stopping);
    }

    // ---- input ----------------------------------------------------------

    /// Takes one input line received at `now` from `origin`. Blank lines
    /// are ignored; every other line gets exactly one result.
    ///
    /// Results carry `"line"`: the line's number among its origin's
    /// non-blank lines (from 1), so a reader can pair every result, an
    /// unlabelled refusal included, with what it sent.
    pub fn handle_line(&mut self, now: Duration, origin: Origin, line: &str) {
        self.changed();
        self.now = self.now.max(now);
        let line = line.trim();
        if line.is_empty() {
            return;
        }
        let number = self.number(origin);
        self.take_line(now, LineMeta::new(origin, number), line);
    }

    /// [`Bridge::handle_line`] for a line its runner already numbered (a
    /// runner that lets emergency stops overtake the lines queued before
    /// them numbers lines as they arrive). The bridge's own count for
    /// `origin` is not used.
    pub fn handle_numbered_line(&mut self, now: Duration, origin: Origin, number: u64, line: &str) {
        self.changed();
        self.now = self.now.max(now);
        let line = line.trim();
        if line.is_empty() {
            return;
        }
        self.take_line(now, LineMeta::new(origin, number), line);
    }

    /// [`Bridge::handle_numbered_line`] for a line its runner already read
    /// ([`classify`] with this bridge's validator, on the reader's thread),
    /// or not (`None`).
    pub(crate) fn handle_read_line(
        &mut self,
        now: Duration,
        origin: Origin,
        number: u64,
        line: &str,
        input: Option<Box<Input>>,
    ) {
        self.changed();
        self.now = self.now.max(now);
        let line = line.trim();
        if line.is_empty() {
            return;
        }
        let meta = LineMeta::new(origin, number);
        match input {
            Some(input) => self.take_input(now, meta, line, *input),
            None => self.take_line(now, meta, line),
        }
    }

    /// The validator lines are read with.
    pub(crate) const fn validator(&self) -> &Validator {
        &self.validator
    }

    /// [`Bridge::handle_unreadable`] for a line its runner already numbered.
    pub fn handle_numbered_unreadable(
        &mut self,
        now: Duration,
        origin: Origin,
        number: u64,
        reason: &str,
    ) {
        self.changed();
        self.now = self.now.max(now);
        self.stats.lines += 1;
        self.refuse(
            &LineMeta::new(origin, number),
            ErrorBody::new(ErrorKind::Unreadable, reason),
        );
    }

    /// A line that could not be read (not UTF-8, too long) but names
    /// `emergency_stop` (a runner finds it while skipping the line): the
    /// bridge cannot tell what it asks, and when in doubt it stops. It is
    /// answered as a stop, `reason` among its problems.
    pub fn handle_numbered_unreadable_stop(
        &mut self,
        now: Duration,
        origin: Origin,
        number: u64,
        reason: &str,
    ) {
        self.changed();
        self.now = self.now.max(now);
        self.take_stop(
            now,
            LineMeta::new(origin, number),
            vec![format!(
                "{reason}; it names emergency_stop, so it is taken as a stop"
            )],
        );
    }

    /// A stop line (`meta`, labelled when it names a motor or a
    /// command).
    fn take_stop(&mut self, now: Duration, meta: LineMeta, problems: Vec<String>) {
        self.last_stop_arrival = Some(self.last_stop_arrival.map_or(now, |t| t.max(now)));
        self.stats.lines += 1;
        let cause = match &meta.label {
            Some(Label::Motor(v) | Label::Command(v) | Label::Orion(v)) => v.clone(),
            None => "input".to_owned(),
        };
        self.emergency_stop(now, Some(meta), problems, cause);
    }

    /// A line that could not be read as text (not UTF-8, too long): it
    /// counts as a line of `origin` and is answered
    /// `{"ok":false,"error":{"kind":"unreadable",...}}`.
    pub fn handle_unreadable(&mut self, now: Duration, origin: Origin, reason: &str) {
        self.changed();
        self.now = self.now.max(now);
        self.stats.lines += 1;
        let number = self.number(origin);
        self.refuse(
            &LineMeta::new(origin, number),
            ErrorBody::new(ErrorKind::Unreadable, reason),
        );
    }

    /// Forgets `origin`'s line count (a client that left); its lines in
    /// progress are still answered.
    pub fn forget_origin(&mut self, origin: Origin) {
        self.changed();
        self.line_numbers.remove(&origin);
        self.clocks.forget(origin);
        self.to_greet.retain(|o| *o != origin);
    }

    fn number(&mut self, origin: Origin) -> u64 {
        let n = self.line_numbers.entry(origin).or_insert(0);
        *n += 1;
        *n
    }

    fn take_line(&mut self, now: Duration, meta: LineMeta, line: &str) {
        let input = classify(&self.validator, line);
        self.take_input(now, meta, line, input);
    }

    /// A line, read as `input`.
    fn take_input(&mut self, now: Duration, meta: LineMeta, line: &str, input: Input) {
        // The stop is acted on in every phase but the last, ahead of all.
        if let Input::Stop { label, problems } = input {
            self.take_stop(now, meta.with(label), problems);
            return;
        }
        match self.phase {
            Phase::Starting => {
                if self.waiting.len() >= self.config.max_pending_lines {
                    self.stats.lines += 1;
                    self.busy(&meta, "too many lines are waiting for the joints to start");
                } else {
                    self.waiting.push_back(Waiting {
                        at: now,
                        meta,
                        text: line.to_owned(),
                    });
                }
                return;
            }
            Phase::Running => {}
            Phase::Draining { .. } | Phase::Stopping | Phase::Finished => {
                self.stats.lines += 1;
                self.refuse(
                    &meta,
                    ErrorBody::new(ErrorKind::ShuttingDown, "the bridge is shutting down"),
                );
                return;
            }
        }
        self.stats.lines += 1;
        match input {
            Input::Stop { .. } => {}
            // A stop that arrived after this release was acted on first (it
            // overtook the queue, or the release waited for startup):
            // releasing now would let what followed the release run after
            // the stop.
            Input::Release if self.last_stop_arrival.is_some_and(|t| now < t) => self.refuse(&meta, ErrorBody::new(
                    ErrorKind::Cancelled,
                    "an emergency stop sent after this release was acted on before it; the emergency stop stays latched",
                ),
            ),
            Input::Release => self.release(now, meta),
            Input::BadRelease { reason } => {
                self.refuse(&meta, ErrorBody::new(ErrorKind::InvalidRelease, reason));
            }
            Input::Invalid { message, violations, more, label } => {
                let mut e = ErrorBody::new(ErrorKind::Invalid, message);
                e.violations = violations;
                e.more_violations =
                    (more > 0).then(|| u32::try_from(more).unwrap_or(u32::MAX));
                self.refuse(&meta.with(label), e);
            }
            Input::QueryLimits { motor_id } => self.query_limits(meta, &motor_id),
            Input::QueryState { motor_id } => self.query_state(meta, motor_id),
            Input::FeedbackRate { hz } => self.feedback_rate(meta, hz),
            Input::OrionCommand { command } => self.arm_command(now, meta, command),
            Input::Request { kind, motor_id } => {
                self.request_line(now, meta, kind, &motor_id);
            }
            Input::Calibration { motor_id, start } => {
                self.calibration_line(now, meta, &motor_id, start);
            }
            Input::Reset { motor_id } => self.reset_joint(now, meta, &motor_id),
            Input::Trajectories { id, trajectories } => {
                self.trajectories(now, meta, &id, &trajectories);
            }
            Input::Stream(mut cmd) => {
                let meta = LineMeta {
                    stream: true,
                    ..meta
                };
                self.motor_command(now, meta, &mut cmd);
            }
            Input::StreamAxes(cmd) => {
                let meta = LineMeta {
                    stream: true,
                    ..meta
                };
                self.multi_axis(now, meta, &cmd);
            }
            Input::Motor { action, motor_id } => self.motor_line(now, meta, action, &motor_id),
            // Read where it lies: a command is the largest message, and
            // every line is one.
            Input::Message(mut m) => match m.as_mut() {
                Message::MotorCommand(cmd) => self.motor_command(now, meta, cmd),
                Message::MultiAxisCommand(cmd) => self.multi_axis(now, meta, cmd),
                Message::SafetyLimits(l) => self.safety_limits(meta, l),
                Message::Trajectory(t) => {
                    let id = t.trajectory_id.clone();
                    self.trajectories(now, meta, &id, std::slice::from_ref(t));
                }
                Message::PidConfig(p) => self.refuse(
                    &meta.labelled(Label::Motor(p.motor_id.clone())),
                    ErrorBody::new(
                        ErrorKind::Unsupported,
                        "iRPC carries no PID gains (its joints run their own control loops): nothing was sent",
                    ),
                ),
                Message::ControlModeConfig(_) => self.refuse(&meta, ErrorBody::new(
                        ErrorKind::Unsupported,
                        "iRPC carries no control-mode configuration (a joint takes position moves and lifecycle requests): nothing was sent",
                    ),
                ),
                other => self.refuse(&meta, ErrorBody::new(
                        ErrorKind::UnsupportedKind,
                        format!(
                            "a {} is valid WIA, but the bridge takes motor-command and multi-axis-command lines",
                            other.kind()
                        ),
                    ),
                ),
            },
        }
    }

    // ---- trajectories -----------------------------------------------------------

    /// WIA Trajectories for iRPC joints (one, or several on one time base):
    /// each planned and checked whole ([`trajectory_to_irpc`]) before
    /// anything is sent, then each segment sent at its time
    /// (`timing.start_time` in the future schedules the start). Each joint
    /// must stand at its first waypoint.
    fn trajectories(&mut self, now: Duration, meta: LineMeta, id: &str, all: &[Trajectory]) {
        // One trajectory: labelled by its motor; several: by their id.
        let meta = meta.labelled(match all {
            [one] => Label::Motor(one.motor_id.clone()),
            _ => Label::Command(id.to_owned()),
        });
        let now_ms = self.unix_ms(now);
        // One time base: the first `start_time` given, or now.
        let start_ms = all
            .iter()
            .find_map(|t| t.timing.start_time)
            .unwrap_or(now_ms);
        if let Err(e) = self.admit(
            now,
            Some(meta.origin),
            start_ms.min(now_ms),
            all.iter().map(|t| t.motor_id.as_str()),
        ) {
            self.refuse(&meta, e);
            return;
        }
        if let (Some(_), Some(max_age)) = (self.config.epoch_unix_ms, self.config.max_age)
            && start_ms - now_ms > max_age.as_secs_f64() * 1000.0
        {
            let e = ErrorBody::new(
                ErrorKind::Stale,
                format!(
                    "timing.start_time {start_ms} is {:.1} s ahead; a trajectory starts within the allowed clock skew, {} s (WIA §10.1)",
                    (start_ms - now_ms) / 1000.0,
                    max_age.as_secs_f64()
                ),
            );
            self.refuse(&meta, e);
            return;
        }
        // A start_time so far ahead that no clock reaches it (1e300) is
        // refused, never a panic.
        let Ok(delay) = Duration::try_from_secs_f64(((start_ms - now_ms) / 1000.0).max(0.0)) else {
            let e = ErrorBody::refused(
                BridgeRule::TimeUnreachable,
                format!("timing.start_time {start_ms} is beyond any time the bridge can wait for"),
            );
            self.refuse(&meta, e);
            return;
        };
        let start = now.saturating_add(delay);
        let mut axes = Vec::new();
        let mut report = Report::default();
        let mut seen = std::collections::BTreeSet::new();
        for t in all {
            if !seen.insert(t.motor_id.as_str()) {
                let e = ErrorBody::refused(
                    BridgeRule::MotorTwice,
                    format!("{} has two trajectories in one line", t.motor_id),
                );
                self.refuse(&meta, e);
                return;
            }
            let plan = match trajectory_to_irpc(&self.map, t) {
                Ok(p) => p,
                Err(r) => {
                    let e = ErrorBody::gate(&r);
                    self.refuse(&meta, e);
                    return;
                }
            };
            let Some(ji) = self.joint_index(&t.motor_id).filter(|&ji| {
                self.joints
                    .get(ji)
                    .is_some_and(|j| j.device.supports(Capability::Trajectory))
            }) else {
                let e = ErrorBody::refused(
                    BridgeRule::NotAnIrpcJoint,
                    format!("{} is not an iRPC joint", t.motor_id),
                );
                self.refuse(&meta, e);
                return;
            };
            let (unit, tolerance) = self
                .map
                .motor(&t.motor_id)
                .map_or((AngleUnit::Degrees, 0.1), |m| {
                    (m.unit, m.unit.to_degrees(m.arrival_tolerance))
                });
            let first = t
                .waypoints
                .first()
                .map_or(0.0, |w| unit.to_degrees(w.position));
            let here = self.joints.get(ji).and_then(|j| j.motion).map(|(p, _)| p);
            if here.is_none_or(|p| !p.is_finite() || (p - first).abs() > tolerance) {
                let at = here.map_or_else(
                    || "at an unknown position".to_owned(),
                    |p| format!("at {}", short_unit(unit.from_degrees(p))),
                );
                let e = ErrorBody::refused(
                    BridgeRule::NotAtStart,
                    format!(
                        "{}: the trajectory starts at {} and the joint is {at}: move it there first",
                        t.motor_id,
                        short_unit(unit.from_degrees(first))
                    ),
                );
                self.refuse(&meta, e);
                return;
            }
            for loss in plan.report.losses {
                report.losses.push(if all.len() > 1 {
                    loss.under(&t.motor_id)
                } else {
                    loss
                });
            }
            // Times no clock reaches are refused, never a panic.
            let timeable = |secs: f64| Duration::try_from_secs_f64(secs.max(0.0)).is_ok();
            if !plan.value.segments.iter().all(|s| timeable(s.at)) || !timeable(plan.value.duration)
            {
                let e = ErrorBody::refused(
                    BridgeRule::TimeUnreachable,
                    format!(
                        "{}: a waypoint's time is beyond any time the bridge can wait for",
                        t.motor_id
                    ),
                );
                self.refuse(&meta, e);
                return;
            }
            // Each segment as the device takes it (an iRPC joint its
            // SetTargetV2; a moteus controller a position-mode move within
            // the segment's limits, its torque limit the map's in force).
            let device = self.joints.get(ji).map(|j| j.device);
            let max_torque = self
                .map
                .motor(&t.motor_id)
                .and_then(|m| m.limits.max_torque);
            let orders: Vec<Order> = plan
                .value
                .segments
                .iter()
                .filter_map(|s| device.and_then(|d| d.segment_order(s.payload, max_torque)))
                .collect();
            let mut axis = Axis::of(t.motor_id.clone(), ji, orders.iter().copied());
            axis.due = plan
                .value
                .segments
                .iter()
                .map(|s| start.saturating_add(Duration::from_secs_f64(s.at.max(0.0))))
                .collect();
            if plan.value.forever {
                axis.cycle = Some(Cycle {
                    payloads: plan
                        .value
                        .segments
                        .iter()
                        .zip(orders)
                        .map(|(s, o)| (Duration::from_secs_f64(s.at.max(0.0)), o))
                        .collect(),
                    period: Duration::from_secs_f64(plan.value.duration),
                    started: start,
                });
            }
            axes.push(axis);
        }
        self.command_job(now, meta, axes, report);
    }

    // ---- one motor held, freed or stopped ---------------------------------------

    /// `{"motor":action,"motor_id":M}`: motor M held, freed or stopped
    /// alone, by its dialect's own means ([`Device::motor_orders`]; an
    /// iRPC joint's hold, a move to where it can stop within the limits in
    /// force, planned here). What waited to be sent to it from earlier
    /// lines is given up first (their results say so), and a trajectory
    /// running on it sends nothing more: nothing older moves it after
    /// this. Refused while the emergency stop is latched (every motor is
    /// stopped already), for a motor that needs a reset or is offline.
    /// Never refused as busy: it clears the motor's queue before it joins
    /// it, so a flood of them holds one step a motor.
    fn motor_line(&mut self, now: Duration, meta: LineMeta, action: MotorAction, motor: &str) {
        let meta = meta.labelled(Label::Motor(motor.to_owned()));
        let now_ms = self.unix_ms(now);
        match self.admit(now, None, now_ms, std::iter::once(motor)) {
            Err(e) if e.kind != ErrorKind::Busy => return self.refuse(&meta, e),
            _ => {}
        }
        let Some((ji, device)) = self
            .joint_index(motor)
            .and_then(|ji| Some((ji, self.joints.get(ji)?.device)))
        else {
            let e = self.unattached(std::iter::once(motor)).unwrap_or_else(|| {
                ErrorBody::gate(&motorwire_translate::Refusal::UnknownMotor {
                    motor: motor.to_owned(),
                })
            });
            return self.refuse(&meta, e);
        };
        let Some(m) = self.map.motor(motor) else {
            return;
        };
        let (unit, limits) = (m.unit, m.limits);
        let decel = Self::braking(&limits).map(|d| unit.to_degrees(d));
        let mut report = Report::default();
        let mut said = |loss: String| {
            report.losses.push(motorwire_translate::Loss {
                field: action.name().into(),
                kind: LossKind::Converted,
                detail: loss.into(),
            });
        };
        let axis = match device.motor_order(action, decel, limits.max_torque, now_ms as u64) {
            Ok(MotorOrder::Send(order, loss)) => {
                if let Some(loss) = loss {
                    said(loss);
                }
                Some(Axis::of(motor.to_owned(), ji, [order]))
            }
            Ok(MotorOrder::Nothing(why)) => {
                said(why);
                None
            }
            Ok(MotorOrder::Planned) => {
                Some(match self.hold_move(ji, motor, unit, &limits, now_ms) {
                    Ok(payload) => Axis::new(motor.to_owned(), ji, [payload]),
                    // A joint not up (never started: its lifecycle left to
                    // the user, or its start failed) has no torque to keep
                    // on, and nothing to stop.
                    Err(why) if !self.joints.get(ji).is_some_and(|j| j.active || j.freed) => {
                        let e = ErrorBody::refused(
                            BridgeRule::ActionNotExpressible,
                            format!(
                                "{motor} is not active (never started: --no-activate, or its start failed) and {why}; {{\"reset\":\"{motor}\"}} starts it"
                            ),
                        )
                        .about(motor);
                        return self.refuse(&meta, e);
                    }
                    Err(why) => {
                        // When in doubt, stop: a hold that cannot be planned
                        // is the joint's own stop.
                        said(format!(
                            "{why}: the joint was deactivated (its own stop) instead"
                        ));
                        let stop = self.orders_for(ji, &[Payload::Deactivate]);
                        Axis::of(motor.to_owned(), ji, stop)
                    }
                })
            }
            Err(why) => {
                let e = ErrorBody::refused(BridgeRule::ActionNotExpressible, why).about(motor);
                return self.refuse(&meta, e);
            }
        };
        // (The deadman stays armed until the motor line's order is taken:
        // if it is lost, the deadman's own stop follows.)
        self.give_up_for_motor_line(ji, action);
        self.command_job(now, meta, axis.into_iter().collect(), report);
    }

    /// An iRPC joint's hold: a move to where it comes to rest from how it
    /// moves now (position, velocity and acceleration), as the joint
    /// itself plans with the limits in force (its deceleration and jerk):
    /// the farthest point of the joint's own plan back to where it is now,
    /// which passes it and comes back, is where it can stop. Within the
    /// position limits in force, gated and planned as any move is; why
    /// not, said for a person.
    fn hold_move(
        &mut self,
        ji: usize,
        motor: &str,
        unit: AngleUnit,
        limits: &Limits,
        now_ms: f64,
    ) -> Result<Payload, String> {
        let Some((p, v, a)) = self.joints.get(ji).and_then(|j| j.state_at(self.now)) else {
            return Err(
                "its position is not known yet (no feedback), so no hold could be planned"
                    .to_owned(),
            );
        };
        let within = |deg: f64| {
            let mut x = deg;
            if let Some(max) = limits.max_position {
                x = x.min(unit.to_degrees(max));
            }
            if let Some(min) = limits.min_position {
                x = x.max(unit.to_degrees(min));
            }
            x
        };
        let here = self.hold_payload(motor, unit, within(p), now_ms)?;
        // Moving: where the joint's own plan back to here turns.
        let stop_at = if v == 0.0 && a == 0.0 {
            p
        } else {
            let req = here.planner_request(p, v).with_start_acceleration(a);
            let e = motorwire_planner::plan(&req)
                .map_err(|e| format!("the joint cannot plan a stop: {e}"))?
                .position_extrema();
            if v > 0.0 || (v == 0.0 && a > 0.0) {
                e.max
            } else {
                e.min
            }
        };
        let (t, m, effective) = motorwire_translate::to_irpc_gated(
            &self.map,
            &Self::position_command(motor, unit.from_degrees(within(stop_at)), now_ms),
        )
        .map_err(|r| r.to_string())?;
        let planned = planned_within_limits(
            self.joints.get(ji),
            self.now,
            m,
            &effective,
            &t.value.payloads,
        )
        .map_err(|r| r.to_string())?;
        let payload = t
            .value
            .payloads
            .first()
            .copied()
            .ok_or_else(|| "no move was made".to_owned())?;
        self.keep_plan(ji, planned);
        Ok(payload)
    }

    /// The `SetTargetV2` a position command to `deg` makes for `motor`,
    /// with the limits in force.
    fn hold_payload(
        &self,
        motor: &str,
        unit: AngleUnit,
        deg: f64,
        now_ms: f64,
    ) -> Result<motorwire_irpc::SetTargetPayloadV2, String> {
        let (t, ..) = motorwire_translate::to_irpc_gated(
            &self.map,
            &Self::position_command(motor, unit.from_degrees(deg), now_ms),
        )
        .map_err(|r| r.to_string())?;
        match t.value.payloads.first() {
            Some(Payload::SetTargetV2(p)) => Ok(*p),
            _ => Err("no move was made".to_owned()),
        }
    }

    /// A position command for `motor` to `setpoint` (its unit), nothing
    /// else given: the limits in force apply.
    fn position_command(motor: &str, setpoint: f64, now_ms: f64) -> MotorCommand {
        MotorCommand {
            motor_id: motor.to_owned(),
            timestamp: now_ms,
            control_mode: motorwire_core::ControlMode::Position,
            setpoint,
            velocity_limit: None,
            acceleration_limit: None,
            torque_limit: None,
            pid_gains: None,
            impedance_params: None,
            filter_config: None,
            safety_limits: None,
            priority: None,
            metadata: None,
            extra: serde_json::Map::new(),
        }
    }

    /// What waits for joint `ji` from command lines, given up for a motor
    /// line (its results say so), and a trajectory running on it stopped
    /// from sending more: nothing older moves it after the motor line.
    fn give_up_for_motor_line(&mut self, ji: usize, action: MotorAction) {
        let why: &'static str = match action {
            MotorAction::Hold => "a hold of the motor came before it was sent: it was never sent",
            MotorAction::Free => "a free of the motor came before it was sent: it was never sent",
            MotorAction::Stop => "a stop of the motor came before it was sent: it was never sent",
        };
        let Some(joint) = self.joints.get_mut(ji) else {
            return;
        };
        let mut given_up = 0;
        joint.queue.retain(|s| {
            let Some(job) = self
                .jobs
                .get_mut(&s.job)
                .filter(|j| j.kind == JobKind::Command)
            else {
                return true;
            };
            if let Some(a) = job
                .axes
                .get_mut(s.axis)
                .filter(|a| a.state == AxisState::Queued)
            {
                a.finish(StepOutcome::Superseded, None, why);
                given_up += 1;
            }
            false
        });
        // What runs on it with more to send (a trajectory, looping or not;
        // a move behind its joint's Activate): between two sends it ends
        // now; with one in flight, once that is answered.
        if let Some(running) = joint.busy
            && let Some(a) = self
                .jobs
                .get_mut(&running.job)
                .filter(|job| job.kind == JobKind::Command)
                .and_then(|job| job.axes.get_mut(running.axis))
            && !a.is_done()
            && (!a.payloads.is_empty() || a.cycle.is_some())
        {
            given_up += 1;
            if a.state == AxisState::Queued {
                a.finish(StepOutcome::Superseded, None, why);
                joint.busy = None;
                joint.wake = None;
            } else {
                a.replaced = Some(why);
            }
        }
        self.stats.superseded += given_up;
        self.finish_jobs();
    }

    // ---- faults and resets ----------------------------------------------------

    /// A reset line: Reset, Configure and Activate for joint `motor`, after
    /// a fault or a reboot (or to start a joint afresh). Refused while the
    /// emergency stop is latched.
    fn reset_joint(&mut self, now: Duration, meta: LineMeta, motor: &str) {
        let meta = meta.labelled(Label::Motor(motor.to_owned()));
        if self.latched {
            let e = ErrorBody::new(
                ErrorKind::EmergencyStopLatched,
                "the emergency stop is latched; release it first, then reset",
            );
            self.refuse(&meta, e);
            return;
        }
        // A device that takes a reset (an iRPC joint, a moteus controller):
        // it goes to that device alone (an Orion motor's would be the
        // broadcast node, rebooting every joint).
        let ji = match self.joint_for(motor, Capability::Reset, PayloadKind::Reset, "Reset") {
            Ok(ji) => ji,
            Err(e) => {
                self.refuse(&meta, e);
                return;
            }
        };
        self.cancel_where("cancelled by a reset of its joint", |job| {
            job.kind == JobKind::Command && job.axes.iter().any(|a| a.joint == ji)
        });
        if let Some(j) = self.joints.get_mut(ji) {
            j.resetting = true;
        }
        // As the device takes a reset (an iRPC joint: these payloads; a
        // moteus controller: its stop, which clears a fault or a timeout).
        let payloads: Vec<Payload> = [Payload::Reset, Payload::Configure, Payload::Activate]
            .into_iter()
            .chain(self.telemetry_subscription(ji))
            .collect();
        let axes = vec![Axis::of(
            motor.to_owned(),
            ji,
            self.orders_for(ji, &payloads),
        )];
        self.open_job(
            Some(meta),
            JobKind::Reset,
            now,
            axes,
            Report::default(),
            Vec::new(),
        );
    }

    /// Joint `ji` faulted or rebooted (`why`): said with `event`, and
    /// everything waiting for it is cancelled; nothing but a reset line is
    /// sent to it from now on.
    fn joint_lost(&mut self, ji: usize, why: String, event: Event) {
        let Some(j) = self.joints.get_mut(ji) else {
            return;
        };
        if j.needs_reset.is_some() {
            return;
        }
        j.needs_reset = Some(why.clone());
        j.active = false;
        self.out.push_back(Output::Event(event));
        let because = format!("cancelled: the joint {why}");
        self.cancel_where(&because, |job| {
            job.kind == JobKind::Command && job.axes.iter().any(|a| a.joint == ji)
        });
        self.fail_watches(|w| w.waits_on(ji), &format!("the joint {why}"));
    }

    // ---- live limits --------------------------------------------------------

    /// The limits of `motor` in force and the bus map's, as JSON.
    fn limits_value(&self, motor: &str) -> Option<Value> {
        let now = self.map.motor(motor)?;
        let base = self.base_limits.get(motor)?;
        let as_json = |l: &Limits| {
            let mut m = serde_json::Map::new();
            for (k, v) in [
                ("min_position", l.min_position),
                ("max_position", l.max_position),
                ("max_velocity", l.max_velocity),
                ("max_acceleration", l.max_acceleration),
                ("max_deceleration", l.max_deceleration),
                ("max_jerk", l.max_jerk),
                ("max_torque", l.max_torque),
                ("emergency_deceleration", l.emergency_deceleration),
            ] {
                if let Some(v) = v {
                    m.insert(k.to_owned(), serde_json::json!(v));
                }
            }
            Value::Object(m)
        };
        let mut effective = as_json(&now.limits);
        if let (Some(d), Value::Object(m)) = (self.emergency_decel.get(motor), &mut effective) {
            m.insert("emergency_decel".to_owned(), serde_json::json!(d));
        }
        Some(serde_json::json!({ "effective": effective, "bus_map": as_json(base) }))
    }

    /// The first motion of device `ji` already accepted (its move under
    /// way, what is in flight, what waits to be sent, a trajectory's later
    /// segments and cycles) that positions `lo..=hi` or a `max_v` (the
    /// motor's unit) would not allow: what it is, said for a person.
    fn motion_outside(&self, ji: usize, lo: f64, hi: f64, max_v: Option<f64>) -> Option<String> {
        let j = self.joints.get(ji)?;
        let unit = self
            .map
            .motor(&j.name)
            .map_or(AngleUnit::Degrees, |m| m.unit);
        let (lo_d, hi_d) = (unit.to_degrees(lo), unit.to_degrees(hi));
        let max_d = max_v.map(|v| unit.to_degrees(v));
        const SLACK: f64 = 1e-6;
        let outside = |t: f64| t < lo_d - SLACK || t > hi_d + SLACK;
        let faster = |v: f64| max_d.is_some_and(|m| v.abs() > m + SLACK);
        let say = |d: f64| short_unit(unit.from_degrees(d));
        if j.moving_until > self.now {
            if let Some(t) = j.target.filter(|t| outside(*t)) {
                return Some(format!("its move under way goes to {}", say(t)));
            }
            if let Some((_, v)) = j.motion.filter(|(_, v)| faster(*v)) {
                return Some(format!("it moves at {} a second now", say(v.abs())));
            }
        }
        // The rest of the move under way (a move braking from speed
        // toward a target inside passes it): as the bridge planned it, or
        // without that plan, at least the stop from where the joint is at
        // its limits. A joint already past a new limit is held to going no
        // farther (as one standing there is: the limits bind what comes
        // next); going farther out is refused.
        if let Some((p_now, v_now, _)) = j.state_at(self.now) {
            let farther = |x: f64| {
                (x > hi_d + SLACK && x > p_now + SLACK) || (x < lo_d - SLACK && x < p_now - SLACK)
            };
            let rest = match &j.model {
                Some((start, profile)) => {
                    let t = self.now.saturating_sub(*start).as_secs_f64();
                    (t < profile.duration()).then(|| {
                        let e = profile.position_extrema_from(t);
                        [(e.max, e.t_max - t), (e.min, e.t_min - t)]
                    })
                }
                None if v_now != 0.0 => self.map.motor(&j.name).and_then(|m| {
                    let l = m.limits;
                    let deg = |x: Option<f64>| x.map(|v| unit.to_degrees(v));
                    let acc = deg(l.max_acceleration).unwrap_or(1000.0);
                    let mut req = motorwire_planner::Request::new(
                        p_now,
                        p_now,
                        deg(l.max_velocity).unwrap_or(v_now.abs()).max(v_now.abs()),
                        acc,
                    )
                    .with_velocities(v_now, 0.0)
                    .with_max_deceleration(deg(l.max_deceleration).unwrap_or(acc));
                    if let Some(jerk) = deg(l.max_jerk).filter(|j| *j > 0.0) {
                        req = req.with_jerk(jerk);
                    }
                    let e = motorwire_planner::plan(&req).ok()?.position_extrema();
                    Some([(e.max, e.t_max), (e.min, e.t_min)])
                }),
                None => None,
            };
            for (extreme, after) in rest.into_iter().flatten() {
                if farther(extreme) {
                    return Some(format!(
                        "its move under way reaches {} in {:.3} s",
                        say(extreme),
                        after.max(0.0)
                    ));
                }
            }
        }
        for step in j.busy.iter().chain(j.queue.iter()) {
            let Some(job) = self.jobs.get(&step.job) else {
                continue;
            };
            let Some(a) = job.axes.get(step.axis) else {
                continue;
            };
            let in_flight = match &a.state {
                AxisState::InFlight { payload, .. } => Some(*payload),
                _ => None,
            };
            let cycle = a
                .cycle
                .iter()
                .flat_map(|c| c.payloads.iter().map(|(_, p)| *p));
            for order in in_flight
                .into_iter()
                .chain(a.payloads.iter().copied())
                .chain(cycle)
            {
                let reach = order.reach(unit);
                let line = job.number();
                if let Some(t) = reach.target.filter(|t| outside(*t)) {
                    return Some(format!("line {line} moves it to {}", say(t)));
                }
                if let Some(v) = reach.speed.filter(|v| faster(*v)) {
                    return Some(format!("line {line} moves it at {} a second", say(v.abs())));
                }
            }
        }
        None
    }

    /// `{"query":"state"}`, or one motor's with `"motor_id"`: answered at
    /// once (a line before `ready` waits for it, as every line does).
    fn query_state(&mut self, meta: LineMeta, motor: Option<String>) {
        let mut state = self.state();
        let meta = match motor {
            None => meta,
            Some(m) => {
                state.motors.retain(|s| s.motor_id == m);
                let meta = meta.labelled(Label::Motor(m.clone()));
                if let Some(e) = self.unattached(std::iter::once(m.as_str())) {
                    self.refuse(&meta, e);
                    return;
                }
                if state.motors.is_empty() {
                    let e = ErrorBody::refused(
                        BridgeRule::UnknownMotor,
                        format!("motor {m:?} is not a device of the bridge"),
                    )
                    .about(&m);
                    self.refuse(&meta, e);
                    return;
                }
                meta
            }
        };
        let r = LineResult {
            ok: true,
            line: meta.number,
            state: Some(state),
            ..LineResult::default()
        };
        self.answer(&meta, r);
    }

    /// `{"feedback_hz":N}`: the client's own feedback rate, answered with
    /// the rate it gets: the bridge's rate divided by a whole number k
    /// (each motor's every k-th feedback line is sent to it), the highest
    /// such rate not above N (what it gets is said, never silently
    /// changed); 0 for none. A rate above the bridge's, or any but 0 with
    /// no feedback at all, is refused.
    fn feedback_rate(&mut self, meta: LineMeta, hz: f64) {
        let bridge_hz = self
            .config
            .feedback_period
            .filter(|p| !p.is_zero())
            .map(|p| 1.0 / p.as_secs_f64());
        let refusal = |message: String| {
            let mut e = ErrorBody::new(ErrorKind::Invalid, message);
            e.broke = Some(Box::new(Broke {
                field: Some("feedback_hz"),
                value: Some(hz),
                limit: Some(bridge_hz.unwrap_or(0.0)),
                limit_name: Some("feedback_hz"),
                limit_source: Some("the bridge's --feedback-hz"),
            }));
            e
        };
        // The number as a person reads it (1e308, not 309 digits).
        let asked = if hz != 0.0 && !(1e-4..1e6).contains(&hz.abs()) {
            format!("{hz:e}")
        } else {
            format!("{hz}")
        };
        let every = match bridge_hz {
            _ if hz.is_nan() || hz < 0.0 => {
                return self.refuse(
                    &meta,
                    refusal(format!(
                        "feedback_hz {asked} is not a rate: 0 (no feedback) or more"
                    )),
                );
            }
            _ if hz == 0.0 => 0,
            None => {
                return self.refuse(&meta, refusal(format!("feedback_hz {asked}: the bridge sends no feedback (--feedback-hz 0); 0 is the only rate")));
            }
            // Beyond the rounding of the bridge's rate from its period.
            Some(b) if hz > b * (1.0 + 1e-9) => {
                return self.refuse(
                    &meta,
                    refusal(format!(
                        "feedback_hz {asked} is above the bridge's own rate, {}",
                        crate::output::short_number(b)
                    )),
                );
            }
            // Every k-th line for a k that fits the count (2^32 - 1): a
            // slower rate than that would be answered with a faster one.
            Some(b) if b / hz - 1e-9 > f64::from(u32::MAX) => {
                return self.refuse(
                    &meta,
                    refusal(format!(
                        "feedback_hz {asked} is below the slowest rate, the bridge's divided by {} ({:e}); 0 turns feedback off",
                        u32::MAX,
                        b / f64::from(u32::MAX)
                    )),
                );
            }
            #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
            Some(b) => ((b / hz - 1e-9).ceil() as u32).max(1),
        };
        let r = LineResult {
            ok: true,
            line: meta.number,
            feedback_every: Some(every),
            feedback_hz: Some(match (bridge_hz, every) {
                (Some(b), k) if k > 0 => b / f64::from(k),
                _ => 0.0,
            }),
            ..LineResult::default()
        };
        self.answer(&meta, r);
    }

    fn query_limits(&mut self, meta: LineMeta, motor: &str) {
        let meta = meta.labelled(Label::Motor(motor.to_owned()));
        let Some(limits) = self.limits_value(motor) else {
            let e = ErrorBody::refused(
                BridgeRule::UnknownMotor,
                format!("motor {motor:?} is not in the bus map"),
            )
            .about(motor);
            self.refuse(&meta, e);
            return;
        };
        let r = LineResult {
            ok: true,
            line: meta.number,
            limits: Some(limits),
            ..LineResult::default()
        };
        self.answer(&meta, r);
    }

    /// A WIA SafetyLimits line: the motor's gate is held to these limits
    /// from now on (until another such line). Each limit must lie within
    /// the bus map's; a wider one refuses the whole line.
    fn safety_limits(&mut self, meta: LineMeta, l: &SafetyLimits) {
        let name = l.motor_id.clone();
        let meta = meta.labelled(Label::Motor(name.clone()));
        let Some(base) = self.base_limits.get(&name).copied() else {
            let e = ErrorBody::refused(
                BridgeRule::UnknownMotor,
                format!("motor {name:?} is not in the bus map"),
            )
            .about(&name);
            self.refuse(&meta, e);
            return;
        };
        let p = &l.position_limits;
        let v = &l.velocity_limits;
        let t = &l.torque_limits;
        let mut wider = Vec::new();
        let mut low = |field: &str, value: Option<f64>, map: Option<f64>, map_field: &str| {
            if let (Some(x), Some(b)) = (value, map)
                && x < b
            {
                wider.push(format!(
                    "{name}: {field} {x} is wider than the bus map's {map_field} {b}"
                ));
            }
        };
        low(
            "position_limits.min",
            Some(p.min),
            base.min_position,
            "min_position",
        );
        low(
            "position_limits.soft_min",
            p.soft_min,
            base.min_position,
            "min_position",
        );
        let mut high = |field: &str, value: Option<f64>, map: Option<f64>, map_field: &str| {
            if let (Some(x), Some(b)) = (value, map)
                && x > b
            {
                wider.push(format!(
                    "{name}: {field} {x} is wider than the bus map's {map_field} {b}"
                ));
            }
        };
        high(
            "position_limits.max",
            Some(p.max),
            base.max_position,
            "max_position",
        );
        high(
            "position_limits.soft_max",
            p.soft_max,
            base.max_position,
            "max_position",
        );
        high(
            "velocity_limits.max_velocity",
            v.max_velocity,
            base.max_velocity,
            "max_velocity",
        );
        high(
            "torque_limits.continuous_torque",
            t.continuous_torque,
            base.max_torque,
            "max_torque",
        );
        high(
            "torque_limits.peak_torque",
            t.peak_torque,
            base.max_torque,
            "max_torque",
        );
        if !wider.is_empty() {
            let e = ErrorBody::refused(BridgeRule::WiderThanBusMap, wider.join("; ")).about(&name);
            self.refuse(&meta, e);
            return;
        }
        // The soft limits, where given, are the gate's; the torque a
        // command may hold is the continuous one.
        let lo = p.soft_min.map_or(p.min, |s| s.max(p.min));
        let hi = p.soft_max.map_or(p.max, |s| s.min(p.max));
        // Motion already accepted is held to the new limits too: a line
        // it would break is refused, naming it, and nothing changes.
        if let Some(why) = self
            .joint_index(&name)
            .and_then(|ji| self.motion_outside(ji, lo, hi, v.max_velocity))
        {
            let e = ErrorBody::refused(
                BridgeRule::MotionOutsideNewLimits,
                format!(
                    "{name}: {why}, which these limits would not allow; send them once it has ended, or stop it first"
                ),
            )
            .about(&name);
            self.refuse(&meta, e);
            return;
        }
        let torque = match (t.continuous_torque, t.peak_torque) {
            (Some(c), Some(k)) => Some(c.min(k)),
            (c, k) => c.or(k).or(base.max_torque),
        };
        let limits = Limits {
            min_position: Some(lo),
            max_position: Some(hi),
            max_velocity: v.max_velocity.or(base.max_velocity),
            max_torque: torque,
            ..base
        };
        self.map
            .set_limits(&name, limits, "the SafetyLimits line in force");
        if let Some(ji) = self.joint_index(&name) {
            let motor = self.map.motor(&name);
            if let (Some(j), Some(m)) = (self.joints.get_mut(ji), motor) {
                j.pace = crate::joints::Pace::of(m);
            }
            let unit = motor.map_or(AngleUnit::Degrees, |m| m.unit);
            self.drivers.limits_changed(ji, &InForce::of(unit, &limits));
        }
        match v.emergency_decel {
            Some(d) => self.emergency_decel.insert(name.clone(), d),
            None => self.emergency_decel.remove(&name),
        };
        let mut losses = Vec::new();
        if v.emergency_decel.is_some() {
            losses.push(motorwire_translate::Loss {
                field: "velocity_limits.emergency_decel".into(),
                kind: LossKind::Dropped,
                detail: "recorded; an iRPC joint brakes from a Deactivate at its own rate".into(),
            });
        }
        for (field, given) in [
            ("thermal_limits", l.thermal_limits.is_some()),
            ("current_limits", l.current_limits.is_some()),
            ("collision_detection", l.collision_detection.is_some()),
            (
                "torque_limits.peak_duration_ms",
                t.peak_duration_ms.is_some(),
            ),
        ] {
            if given {
                losses.push(motorwire_translate::Loss {
                    field: field.into(),
                    kind: LossKind::Dropped,
                    detail: "iRPC has no such setting; the joint keeps its own".into(),
                });
            }
        }
        let r = LineResult {
            ok: true,
            line: meta.number,
            limits: self.limits_value(&name),
            losses,
            ..LineResult::default()
        };
        self.answer(&meta, r);
    }

    fn refuse(&mut self, meta: &LineMeta, error: ErrorBody) {
        let r = LineResult {
            ok: false,
            line: meta.number,
            error: Some(error),
            ..LineResult::default()
        };
        self.answer(meta, r);
    }

    /// Gives `r` to `meta`'s origin, labelled as `meta` is, counting it.
    /// (A result is some 460 bytes: one made in its box where it is built
    /// is not copied there.)
    fn answer(&mut self, meta: &LineMeta, r: impl Into<Box<LineResult>>) {
        let mut r: Box<LineResult> = r.into();
        r.bound();
        if r.ok {
            self.stats.ok += 1;
        } else {
            self.stats.failed += 1;
        }
        if let Some(label) = meta.label.clone() {
            label.apply(&mut r);
        }
        self.out.push_back(Output::Result {
            origin: meta.origin,
            result: r,
        });
    }

    fn busy(&mut self, meta: &LineMeta, why: &str) {
        self.stats.busy += 1;
        self.refuse(
            meta,
            ErrorBody::new(
                ErrorKind::Busy,
                format!("{why}; nothing was sent, send it again later"),
            ),
        );
    }

    fn joint_index(&self, motor: &str) -> Option<usize> {
        self.joints.iter().position(|j| j.name == motor)
    }

    /// The `ConfigureTelemetry` joint `ji` gets when configured, if
    /// [`BridgeConfig::telemetry_hz`] asks and its wire version has it.
    fn telemetry_subscription(&self, ji: usize) -> Option<Payload> {
        let rate_hz = self.config.telemetry_hz.filter(|r| *r > 0)?;
        let j = self.joints.get(ji)?;
        if !j.device.speaks(PayloadKind::ConfigureTelemetry) {
            return None;
        }
        Some(Payload::ConfigureTelemetry(
            motorwire_irpc::ConfigureTelemetryPayload {
                mode: motorwire_irpc::TelemetryMode::Periodic,
                rate_hz,
                change_threshold: 0.0,
            },
        ))
    }

    /// Learns `origin`'s clock from a line stamped `timestamp` that
    /// reached the bridge at `now`: only where timestamps are held to the
    /// bridge's clock (an epoch and a max age), and only from a timestamp
    /// within the allowed skew (one outside it teaches nothing and is
    /// refused `stale`).
    fn learn_clock(&mut self, now: Duration, origin: Origin, timestamp: f64) {
        if let (Some(epoch), Some(max_age)) = (self.config.epoch_unix_ms, self.config.max_age) {
            let arrived = epoch + now.as_secs_f64() * 1000.0;
            let offset = arrived - timestamp;
            if offset.is_finite() && offset.abs() <= max_age.as_secs_f64() * 1000.0 {
                self.clocks.learn(origin, offset);
            }
        }
    }

    /// [`Bridge::admit`] for a line that carries no timestamp (taken as
    /// sent now).
    fn admit_now<'a>(
        &self,
        motors: impl Iterator<Item = &'a str> + Clone,
    ) -> Result<(), ErrorBody> {
        let now_ms = self
            .config
            .epoch_unix_ms
            .map_or(0.0, |e| e + self.now.as_secs_f64() * 1000.0);
        self.admit(self.now, None, now_ms, motors)
    }

    /// Admission: what refuses a motion line before anything is planned.
    /// `arrived` is when the line reached the bridge, `origin` whose
    /// clock its `timestamp` is on (`None`: the bridge's own).
    fn admit<'a>(
        &self,
        arrived: Duration,
        origin: Option<Origin>,
        timestamp: f64,
        mut motors: impl Iterator<Item = &'a str> + Clone,
    ) -> Result<(), ErrorBody> {
        if self.latched {
            return Err(ErrorBody::new(
                ErrorKind::EmergencyStopLatched,
                "the emergency stop is latched; send {\"emergency_stop\": false} to release it",
            ));
        }
        // Only where timestamps are held to the bridge's clock (a max age
        // in force): without one they may be any number.
        // To the millisecond, the timestamps' resolution: one stamped in
        // the millisecond the stop came in may have been written after it.
        // Reached the bridge before the stop: written before it, whatever
        // its timestamp says (a client's clock may run ahead).
        if let Some(stop) = self.last_stop_at
            && arrived < stop
        {
            return Err(ErrorBody::new(
                ErrorKind::StaleBeforeStop,
                format!(
                    "the line reached the bridge {:.3} s before the last emergency stop: written before the stop, it does not run after the release",
                    (stop - arrived).as_secs_f64()
                ),
            ));
        }
        // The timestamp on the bridge's clock, as far as the client's
        // lines tell: a clock that runs ahead is taken back by as much
        // (never forward: a clock behind only refuses more).
        let written = timestamp + origin.map_or(0.0, |o| self.clocks.behind(o));
        if let Some(stop_ms) = self.last_stop_unix_ms.map(f64::floor)
            && self.config.max_age.is_some()
            && written < stop_ms
        {
            // Written before the stop (another client's, still on its
            // way): the stop came after it, so it must not run after the
            // release.
            return Err(ErrorBody::new(
                ErrorKind::StaleBeforeStop,
                format!(
                    "timestamp {timestamp} is {:.3} s before the last emergency stop (at {stop_ms}): written before the stop, it does not run after the release",
                    (stop_ms - timestamp) / 1000.0
                ),
            ));
        }
        if let (Some(epoch), Some(max_age)) = (self.config.epoch_unix_ms, self.config.max_age) {
            let now_ms = epoch + self.now.as_secs_f64() * 1000.0;
            let skew = max_age.as_secs_f64() * 1000.0;
            let age = now_ms - timestamp;
            if age > skew || -age > skew {
                let when = if age > 0.0 { "old" } else { "in the future" };
                // A timestamp in microseconds is a mistake often made: say
                // so when the value read in that unit would have been
                // within the skew. (One in seconds is the validator's
                // `timestamp-unit`, refused before it gets here.)
                let hint = if (now_ms * 1000.0 - timestamp).abs() / 1000.0 <= skew {
                    "; it looks like microseconds: WIA timestamps are Unix milliseconds (`date +%s%3N`)"
                } else {
                    ""
                };
                return Err(ErrorBody::new(
                    ErrorKind::Stale,
                    format!(
                        "timestamp {timestamp} is {:.1} s {when}; the allowed clock skew is {} s (WIA §10.1){hint}",
                        age.abs() / 1000.0,
                        max_age.as_secs_f64()
                    ),
                ));
            }
        }
        if let Some(err) = motors.clone().find_map(|m| {
            let j = self.joints.get(self.joint_index(m)?)?;
            let why = j.needs_reset.as_ref()?;
            Some(
                ErrorBody::new(
                    ErrorKind::NeedsReset,
                    format!("{m} {why}: send {{\"reset\":\"{m}\"}} to bring it back"),
                )
                .about(m),
            )
        }) {
            return Err(err);
        }
        if let Some(err) = motors.clone().find_map(|m| {
            let j = self.joints.get(self.joint_index(m)?)?;
            (!j.online).then(|| {
                ErrorBody::new(
                    ErrorKind::Offline,
                    match self.drivers.offline_reason(j.device) {
                        Some(why) => format!("{m} is offline: {why}"),
                        None => format!(
                            "{m} is offline: nothing heard from {}",
                            j.device.who(j.node)
                        ),
                    },
                )
                .about(m)
            })
        }) {
            return Err(err);
        }
        if self.pending_lines() >= self.config.max_pending_lines {
            return Err(ErrorBody::new(
                ErrorKind::Busy,
                format!(
                    "{} lines are in progress, the most the bridge takes; nothing was sent, send it again later",
                    self.config.max_pending_lines
                ),
            ));
        }
        if let Some(m) = motors.find(|m| {
            self.joint_index(m)
                .and_then(|i| self.joints.get(i))
                .is_some_and(|j| j.queue.len() >= self.config.max_queue_per_joint)
        }) {
            return Err(ErrorBody::new(
                ErrorKind::Busy,
                format!("{m} has {} steps waiting, the most it takes; nothing was sent, send it again later", self.config.max_queue_per_joint),
            )
            .about(m));
        }
        Ok(())
    }

    fn motor_command(&mut self, now: Duration, meta: LineMeta, cmd: &mut MotorCommand) {
        let meta = meta.labelled(Label::Motor(cmd.motor_id.clone()));
        self.learn_clock(now, meta.origin, cmd.timestamp);
        if let Err(e) = self.admit(
            now,
            Some(meta.origin),
            cmd.timestamp,
            std::iter::once(cmd.motor_id.as_str()),
        ) {
            if e.kind == ErrorKind::Busy {
                self.stats.busy += 1;
            }
            self.refuse(&meta, e);
            return;
        }
        // Its joint, looked for once.
        let ji = self.joint_index(&cmd.motor_id);
        let device = ji.and_then(|ji| Some((ji, self.joints.get(ji)?.device)));
        // A joint is attached (an Orion motor is one only with its
        // controller); anything else may be an Orion motor without one.
        if ji.is_none()
            && let Some(e) = self.unattached(std::iter::once(cmd.motor_id.as_str()))
        {
            self.refuse(&meta, e);
            return;
        }
        if cmd
            .safety_limits
            .as_ref()
            .is_none_or(|l| l.emergency_stop != Some(true))
            && let Some(e) = self.outward_at_limit(&cmd.motor_id, cmd.control_mode, cmd.setpoint)
        {
            self.refuse(&meta, e);
            return;
        }
        if let Some((ji, device)) = device
            && let Some(built) = self.single_axis(ji, device, cmd)
        {
            self.device_command(now, meta, cmd, built);
            return;
        }
        match motorwire_translate::to_irpc_gated(&self.map, cmd) {
            Ok((t, motor, limits)) => {
                let Some(joint) = ji else {
                    let e = ErrorBody::refused(
                        BridgeRule::NotAnIrpcJoint,
                        format!("{} is not an iRPC joint of the bus map", cmd.motor_id),
                    )
                    .about(cmd.motor_id.clone());
                    self.refuse(&meta, e);
                    return;
                };
                let planned = planned_within_limits(
                    self.joints.get(joint),
                    self.now,
                    motor,
                    &limits,
                    &t.value.payloads,
                );
                match planned {
                    Ok(planned) => self.keep_plan(joint, planned),
                    Err(r) => {
                        self.refuse(&meta, ErrorBody::gate(&r));
                        return;
                    }
                }
                // The line's motor name, moved: the command is not read again.
                let motor = std::mem::take(&mut cmd.motor_id);
                let axes = vec![Axis::new(motor, joint, t.value.payloads)];
                self.command_job(now, meta, axes, t.report);
            }
            Err(r) => self.refuse(&meta, ErrorBody::gate(&r)),
        }
    }

    /// `cmd` for device `ji`, gated and translated on its own, as its
    /// axis; `None` for an iRPC joint, whose moves are planned from its
    /// state (and with the other joints of a multi-axis line).
    fn single_axis(
        &self,
        ji: usize,
        device: Device,
        cmd: &MotorCommand,
    ) -> Option<Result<(Axis, Report), motorwire_translate::Refusal>> {
        let built = device.single_order(&self.map, cmd)?;
        Some(built.map(|one| {
            let mut axis = Axis::of(cmd.motor_id.clone(), ji, [one.order]);
            axis.target = one.target;
            (axis, one.report)
        }))
    }

    /// A multi-axis command: the iRPC joints' axes planned together
    /// (synchronized as the command asks), every compact device's and
    /// Orion motor's axis gated and translated on its own, all sent as one
    /// job. `sync_mode: sequential` runs them one after another, each once
    /// the one before arrived.
    fn multi_axis_jobs(&mut self, now: Duration, meta: LineMeta, cmd: &MultiAxisCommand) {
        let meta = meta.labelled(Label::Command(cmd.command_id.clone()));
        // One after another, or together in one duration: not both (each
        // axis took the duration, one after the other, and the result
        // promised them all after it).
        if cmd.sync_mode == Some(SyncMode::Sequential)
            && cmd
                .coordination
                .as_ref()
                .is_some_and(|c| c.total_duration_ms.is_some())
        {
            let e = ErrorBody::new(
                ErrorKind::Invalid,
                "sync_mode sequential runs the axes one after another; coordination.total_duration_ms has them all arrive together after it: a line has one or the other",
            );
            return self.refuse(&meta, e);
        }
        let (mut axes, report) = match self.mixed_axes(cmd) {
            Ok(x) => x,
            Err(e) => return self.refuse(&meta, e),
        };
        if cmd.sync_mode == Some(SyncMode::Sequential) {
            // One after another: each starts once the one before it
            // arrived, so each must be a move to a target.
            if let Some((a, i)) = axes
                .iter()
                .zip(&cmd.motors)
                .find(|(ax, _)| ax.target.is_none())
            {
                let e = ErrorBody::refused(
                    BridgeRule::SequentialWithoutArrival,
                    format!(
                        "{}: sync_mode sequential runs position moves one after another, each once the one before arrived; a {} command has no arrival to wait for",
                        a.motor,
                        i.control_mode.name()
                    ),
                )
                .about(a.motor.clone());
                return self.refuse(&meta, e);
            }
            for (k, a) in axes.iter_mut().enumerate().skip(1) {
                a.after = Some(k - 1);
            }
        }
        self.command_job(now, meta, axes, report);
    }

    /// Opens the job of a command line: `axes`, `report`'s losses.
    fn command_job(&mut self, now: Duration, meta: LineMeta, axes: Vec<Axis>, report: Report) {
        self.open_job(Some(meta), JobKind::Command, now, axes, report, Vec::new());
    }

    /// A MotorCommand for one compact device or Orion motor: its axis as
    /// `built`, or the refusal.
    fn device_command(
        &mut self,
        now: Duration,
        meta: LineMeta,
        cmd: &MotorCommand,
        built: Result<(Axis, Report), motorwire_translate::Refusal>,
    ) {
        let meta = meta.labelled(Label::Motor(cmd.motor_id.clone()));
        match built {
            Ok((axis, report)) => self.command_job(now, meta, vec![axis], report),
            Err(r) => {
                let e = ErrorBody::gate(&r);
                self.refuse(&meta, e);
            }
        }
    }

    fn mixed_axes(&self, cmd: &MultiAxisCommand) -> Result<(Vec<Axis>, Report), ErrorBody> {
        let refused = |motor: &str, r: &motorwire_translate::Refusal| {
            ErrorBody::gate(r).about(motor.to_owned())
        };
        let mut report = Report::default();
        // The iRPC joints' axes, planned together.
        let mut sub = cmd.clone();
        sub.motors.retain(|a| {
            self.joint_index(&a.motor_id).is_some_and(|ji| {
                self.joints
                    .get(ji)
                    .is_some_and(|j| j.device.planned_together())
            })
        });
        let mut irpc: Vec<Vec<Payload>> = Vec::new();
        if !sub.motors.is_empty() {
            // Each joint from where it is now, moving or not.
            let state = |m: &str| {
                let j = self.joints.get(self.joint_index(m)?)?;
                match j.state_at(self.now) {
                    Some(k) => Some(crate::joints::in_unit(j.unit, k)),
                    None => j.feedback.as_ref().map(|f| (f.position, 0.0, 0.0)),
                }
            };
            let t = multi_axis_to_irpc_from(&self.map, &sub, &state)
                .map_err(|r| ErrorBody::gate(&r))?;
            irpc = t.value.commands.into_iter().map(|c| c.payloads).collect();
            report.losses.extend(t.report.losses);
        }
        let mut irpc = irpc.into_iter();
        let mut axes = Vec::new();
        // The dialects of the axes not planned together, in the map's words.
        let mut others: Vec<&'static str> = Vec::new();
        for a in &cmd.motors {
            let Some(ji) = self.joint_index(&a.motor_id) else {
                return Err(ErrorBody::refused(
                    BridgeRule::UnknownMotor,
                    format!("{} is not a device of the bus map", a.motor_id),
                )
                .about(a.motor_id.clone()));
            };
            let single = a.to_motor_command(cmd.timestamp);
            let prefixed = |r: Report| r.losses.into_iter().map(|l| l.under(&a.motor_id));
            let device = self.joints.get(ji).map(|j| j.device);
            if let Some(built) = device.and_then(|d| self.single_axis(ji, d, &single)) {
                let (axis, r) = built.map_err(|r| refused(&a.motor_id, &r))?;
                report.losses.extend(prefixed(r));
                axes.push(axis);
                let dialect = device.map_or("iRPC", Device::dialect_name);
                if !others.contains(&dialect) {
                    others.push(dialect);
                }
            } else {
                let payloads = irpc.next().unwrap_or_default();
                axes.push(Axis::new(a.motor_id.clone(), ji, payloads));
            }
        }
        if !others.is_empty()
            && !sub.motors.is_empty()
            && cmd.sync_mode != Some(SyncMode::Sequential)
        {
            others.sort_by_key(|d| d.to_ascii_lowercase());
            let names = match others.as_slice() {
                [one] => (*one).to_owned(),
                [init @ .., last] => format!("{} and {last}", init.join(", ")),
                [] => String::new(),
            };
            report.losses.push(motorwire_translate::Loss {
                field: "sync_mode".into(),
                kind: motorwire_translate::LossKind::Converted,
                detail: format!(
                    "{names} axes are sent at the same time as the others, but only iRPC joints are planned to a common duration"
                )
                .into(),
            });
        }
        Ok((axes, report))
    }

    /// Keeps the plan [`planned_within_limits`] made for `joint`'s move.
    fn keep_plan(&mut self, joint: usize, planned: Option<Plan>) {
        let now = self.now;
        if let Some(j) = self.joints.get_mut(joint) {
            let (planned, profile) = planned.unzip();
            j.planned = planned;
            j.planned_profile = profile;
            j.planned_at = now;
        }
    }

    fn multi_axis(&mut self, now: Duration, meta: LineMeta, cmd: &MultiAxisCommand) {
        let meta = meta.labelled(Label::Command(cmd.command_id.clone()));
        self.learn_clock(now, meta.origin, cmd.timestamp);
        if let Err(e) = self.admit(
            now,
            Some(meta.origin),
            cmd.timestamp,
            cmd.motors.iter().map(|a| a.motor_id.as_str()),
        ) {
            if e.kind == ErrorKind::Busy {
                self.stats.busy += 1;
            }
            self.refuse(&meta, e);
            return;
        }
        if let Some(e) = cmd
            .motors
            .iter()
            .find_map(|a| self.outward_at_limit(&a.motor_id, a.control_mode, a.setpoint))
        {
            self.refuse(&meta, e);
            return;
        }
        if let Some(e) = self.unattached(cmd.motors.iter().map(|a| a.motor_id.as_str())) {
            self.refuse(&meta, e);
            return;
        }
        self.multi_axis_jobs(now, meta, cmd);
    }

    // ---- the emergency stop ------------------------------------------------

    /// An emergency stop, asked by the line `meta` (or by the bridge
    /// itself: `None`) because of `cause`.
    fn emergency_stop(
        &mut self,
        now: Duration,
        meta: Option<LineMeta>,
        problems: Vec<String>,
        cause: String,
    ) {
        if self.phase == Phase::Finished {
            // Nothing runs any more; the joints were deactivated.
            if let Some(meta) = meta {
                let r = LineResult {
                    ok: false,
                    line: meta.number,
                    emergency_stop: true,
                    problems,
                    error: Some(ErrorBody::new(
                        ErrorKind::ShuttingDown,
                        "the bridge has already deactivated every joint",
                    )),
                    ..LineResult::default()
                };
                self.answer(&meta, r);
            } else {
                self.stats.failed += 1;
            }
            return;
        }
        // Every stop counts for what was written before it, a stop that
        // rides on another one too.
        if let Some(e) = self.config.epoch_unix_ms {
            let at = e + now.as_secs_f64() * 1000.0;
            self.last_stop_unix_ms = Some(self.last_stop_unix_ms.map_or(at, |t| t.max(at)));
        }
        self.last_stop_at = Some(self.last_stop_at.map_or(now, |t| t.max(now)));
        // A stop already under way (latched, not released since) answers
        // this line too: its Deactivates are in flight or queued first, and
        // sending them again would only add frames ahead of nothing.
        if self.latched
            && let Some(job) = self
                .jobs
                .values_mut()
                .rev()
                .find(|j| j.kind == JobKind::EmergencyStop)
        {
            self.stats.stops_coalesced += 1;
            if let Some(line) = meta {
                job.riders.push(Rider {
                    line,
                    problems,
                    received: now,
                });
            }
            return;
        }
        self.stats.emergency_stops += 1;
        // What the release brings back: the joints active now, and those
        // whose startup or release this stop interrupts.
        if !self.latched {
            self.resume.clear();
        }
        for (i, j) in self.joints.iter().enumerate() {
            let starting = j.busy.iter().chain(j.queue.iter()).find_map(|s| {
                let job = self.jobs.get(&s.job)?;
                matches!(job.kind, JobKind::Startup | JobKind::Release).then(|| {
                    let a = job.axes.get(s.axis)?;
                    let irpc = Order::lifecycle_payload;
                    let mut p: Vec<Payload> = a.payloads.iter().filter_map(irpc).collect();
                    if let AxisState::InFlight { payload, .. } = a.state
                        && let Some(first) = irpc(&payload)
                    {
                        p.insert(0, first);
                    }
                    Some(p)
                })?
            });
            if let Some(p) = starting {
                self.resume.insert(i, p);
            } else if j.active {
                self.resume.insert(i, vec![Payload::Activate]);
            }
        }
        self.latched = true;
        self.fail_watches(|_| true, "stopped by the emergency stop");
        let cancelled = self.cancel_everything("cancelled by the emergency stop");
        self.out
            .push_back(Output::Event(Event::EmergencyStop { cause, cancelled }));
        let axes = self.every_joint(&[Payload::Deactivate]);
        self.open_job(
            meta,
            JobKind::EmergencyStop,
            now,
            axes,
            Report::default(),
            problems,
        );
        if self.phase == Phase::Starting {
            // The startup was cancelled: lines are served (and refused
            // while latched).
            self.enter(Phase::Running);
        }
    }

    /// Cancels every step queued or in flight (never sent again); returns
    /// the input lines affected.
    fn cancel_everything(&mut self, why: &str) -> Vec<LineRef> {
        self.cancel_where(why, |_| true)
    }

    /// `origin` is gone (disconnected by its runner: it stopped reading,
    /// or its connection failed). Its lines not yet done are cancelled:
    /// steps waiting are never sent, requests in flight never sent again
    /// (the joint may have taken one; a stop still stops it). Said on the
    /// event stream as `client_dropped`, since the client cannot be told.
    /// Its line count is forgotten.
    pub fn drop_origin(&mut self, now: Duration, origin: Origin, reason: &str) {
        self.changed();
        self.now = self.now.max(now);
        self.line_numbers.remove(&origin);
        self.clocks.forget(origin);
        self.to_greet.retain(|o| *o != origin);
        let before = self.waiting.len();
        let mut cancelled: Vec<LineRef> = Vec::new();
        self.waiting.retain(|w| {
            if w.meta.origin == origin {
                cancelled.push(LineRef {
                    origin,
                    line: w.meta.number,
                });
                false
            } else {
                true
            }
        });
        self.stats.cancelled += (before - self.waiting.len()) as u64;
        let why = format!("cancelled: the client was disconnected ({reason})");
        cancelled.extend(self.cancel_where(&why, |job| {
            job.is_of(origin) && job.kind == JobKind::Command
        }));
        cancelled.sort_by_key(|r| r.line);
        cancelled.dedup();
        self.arrivals.retain(|w| w.line.origin != origin);
        self.out.push_back(Output::Event(Event::ClientDropped {
            origin,
            reason: reason.to_owned(),
            cancelled,
        }));
        for ji in 0..self.joints.len() {
            self.pump(ji);
        }
        self.finish_jobs();
    }

    /// Cancels the steps (queued or in flight) of the jobs `pick` chooses;
    /// returns the input lines affected.
    fn cancel_where(&mut self, why: &str, pick: impl Fn(&Job) -> bool) -> Vec<LineRef> {
        let mut touched = Vec::new();
        // Setpoints sent and never answered: they may be running.
        let mut maybe_held = Vec::new();
        // Steps whose frame or line was made and never handed out (still
        // waiting in poll_transmit's or poll_orion_line's queue): taken
        // back, so what is cancelled never reaches a device after the
        // cancel (a stop goes ahead of them, not behind).
        let picked = |b: &Bridge, ji: usize| {
            b.joints
                .get(ji)
                .and_then(|j| j.busy)
                .is_some_and(|s| b.jobs.get(&s.job).is_some_and(&pick))
        };
        let chosen: BTreeSet<usize> = (0..self.joints.len())
            .filter(|&ji| picked(self, ji))
            .collect();
        let unsent = self.drivers.take_back_unsent(&chosen);
        for ji in 0..self.joints.len() {
            let Some(joint) = self.joints.get_mut(ji) else {
                continue;
            };
            let busy = joint
                .busy
                .take_if(|s| self.jobs.get(&s.job).is_some_and(&pick));
            let (queued, kept): (Vec<StepRef>, Vec<StepRef>) = joint
                .queue
                .drain(..)
                .partition(|s| self.jobs.get(&s.job).is_some_and(&pick));
            joint.queue.extend(kept);
            if let Some(s) = busy
                && let Some(job) = self.jobs.get_mut(&s.job)
                && let Some(a) = job.axes.get_mut(s.axis)
            {
                if let AxisState::InFlight { msg_id, payload } = a.state {
                    self.drivers.forget(ji, msg_id, payload);
                }
                joint.wake = None;
                if unsent.contains(&ji) {
                    a.finish(
                        StepOutcome::Cancelled,
                        None,
                        format!("{why} before it was sent"),
                    );
                    // Its frame or line was taken back: nothing of the job
                    // waits to be written unless another of its steps is
                    // in flight (whose answer comes after its writing).
                    if !job
                        .axes
                        .iter()
                        .any(|x| matches!(x.state, AxisState::InFlight { .. }))
                    {
                        job.unflushed = false;
                    }
                } else {
                    if let AxisState::InFlight { payload, .. } = a.state
                        && payload.holds_setpoint()
                    {
                        maybe_held.push((ji, payload));
                    }
                    if matches!(a.state, AxisState::InFlight { .. }) {
                        // Sent and not answered: it may have run. Never sent again.
                        a.finish(
                            StepOutcome::OutcomeUnknown,
                            None,
                            format!(
                                "{why}: it was sent before and not answered, so the joint may have started it; it is never sent again"
                            ),
                        );
                    } else {
                        // A trajectory between segments: the rest never sent.
                        a.finish(
                            StepOutcome::Cancelled,
                            None,
                            format!("{why}: the trajectory's remaining segments were never sent"),
                        );
                    }
                }
                job.cut.get_or_insert_with(|| why.to_owned());
                self.stats.cancelled += 1;
                touched.extend(job.line_ref());
            }
            for s in queued {
                if let Some(job) = self.jobs.get_mut(&s.job)
                    && let Some(a) = job.axes.get_mut(s.axis)
                {
                    a.finish(
                        StepOutcome::Cancelled,
                        None,
                        format!("{why} before it was sent"),
                    );
                    job.cut.get_or_insert_with(|| why.to_owned());
                    self.stats.cancelled += 1;
                    touched.extend(job.line_ref());
                }
            }
        }
        // The deadman watches what may be running, as if it were acked.
        for (ji, payload) in maybe_held {
            self.track(ji, payload, self.now);
        }
        touched.sort_by_key(|r| (r.origin, r.line));
        touched.dedup();
        self.finish_jobs();
        touched
    }

    fn release(&mut self, now: Duration, meta: LineMeta) {
        if !self.latched {
            self.refuse(
                &meta,
                ErrorBody::new(
                    ErrorKind::NotLatched,
                    "there is no emergency stop to release",
                ),
            );
            return;
        }
        self.latched = false;
        let resume = std::mem::take(&mut self.resume);
        let reactivated = resume
            .keys()
            .filter_map(|i| self.joints.get(*i))
            .map(|j| j.name.clone())
            .collect();
        let left_inactive = self
            .joints
            .iter()
            .enumerate()
            .filter(|(i, j)| !resume.contains_key(i) && j.device.supports(Capability::Lifecycle))
            .map(|(_, j)| j.name.clone())
            .collect();
        self.out.push_back(Output::Event(Event::Released {
            reactivated,
            left_inactive,
        }));
        let axes = resume
            .into_iter()
            .filter_map(|(i, p)| {
                let orders = self.orders_for(i, &p);
                Some(Axis::of(self.joints.get(i)?.name.clone(), i, orders))
            })
            .collect();
        self.open_job(
            Some(meta),
            JobKind::Release,
            now,
            axes,
            Report::default(),
            Vec::new(),
        );
    }

    /// `payloads`, in order, for every joint.
    fn every_joint(&self, payloads: &[Payload]) -> Vec<Axis> {
        self.joints
            .iter()
            .enumerate()
            .map(|(i, j)| Axis::of(j.name.clone(), i, self.orders_for(i, payloads)))
            .collect()
    }

    /// Lifecycle `payloads` as device `ji` takes them
    /// ([`Device::lifecycle_orders`]).
    fn orders_for(&self, ji: usize, payloads: &[Payload]) -> Vec<Order> {
        let now_ms = self.unix_ms(self.now) as u64;
        self.joints
            .get(ji)
            .map(|j| j.device.lifecycle_orders(payloads, now_ms))
            .unwrap_or_default()
    }

    // ---- jobs and the joint queues -------------------------------------------

    fn open_job(
        &mut self,
        line: Option<LineMeta>,
        kind: JobKind,
        now: Duration,
        axes: Vec<Axis>,
        report: Report,
        problems: Vec<String>,
    ) {
        let id = self.next_job;
        self.next_job += 1;
        if kind.is_stop() {
            self.cancel_everything("cancelled by the stop");
        }
        let mut axes = axes;
        if kind == JobKind::Command {
            self.activate_freed(&mut axes);
        }
        // A stream's setpoint replaces any setpoint waiting for its motor
        // (position, velocity, torque); an ordinary position move, a
        // waiting position move.
        let stream = line.as_ref().is_some_and(|l| l.stream);
        // What each step takes over on its device: `Some(replaces)` for a
        // motion step that goes as soon as it can (one that waits for a
        // sequence takes its device when its turn comes:
        // `Self::sequence_progress`); `replaces`, a position move or a
        // stream's setpoint.
        // (Collected into a list kept from the last job: a line's job is
        // opened for every line.)
        let mut steps = std::mem::take(&mut self.steps_scratch);
        steps.clear();
        steps.extend(axes.iter().enumerate().map(|(axis, a)| {
            let replaces = a.is_position_move() || (stream && a.is_setpoint());
            let motion = a.first_asked().is_some_and(Order::is_setpoint);
            // A trajectory's steps are timed: it replaces a waiting
            // sequential axis, and otherwise queues behind what is
            // there (one running, one scheduled), as it always did.
            let timed = !a.due.is_empty();
            let takes =
                (a.after.is_none() && (replaces || motion)).then_some(Takes { replaces, timed });
            (a.joint, StepRef { job: id, axis }, takes)
        }));
        self.jobs.insert(
            id,
            Box::new(Job::new(line, kind, now, axes, report, problems)),
        );
        for &(ji, step, takes) in &steps {
            let scheduled = match takes {
                Some(Takes { replaces, timed }) if kind == JobKind::Command => {
                    self.supersede(ji, stream, replaces, timed, None)
                }
                _ => None,
            };
            if let Some(j) = self.joints.get_mut(ji) {
                j.queue.push_back(step);
                // A trajectory scheduled to start later goes at its time,
                // after this step.
                j.queue.extend(scheduled);
            }
        }
        // Every step queued before any is sent: the Orion motors of one
        // line go out as one line.
        for &(ji, _, _) in &steps {
            self.pump(ji);
        }
        // Kept for the next job (one opened meanwhile found it empty and
        // made its own: the larger is kept).
        if steps.capacity() >= self.steps_scratch.capacity() {
            self.steps_scratch = steps;
        }
        self.finish_jobs();
    }

    /// A command line's axes for joints a line left inactive (`disabled`,
    /// `free`, `stop`): a motion is preceded by an Activate, so the next
    /// command undoes them (a joint inactive for another reason, a fault,
    /// waits for a reset line). An axis that deactivates its joint marks
    /// it so.
    fn activate_freed(&mut self, axes: &mut [Axis]) {
        for a in axes {
            let Some(j) = self.joints.get_mut(a.joint) else {
                continue;
            };
            if !j.device.supports(Capability::Lifecycle) {
                continue;
            }
            let deactivates = a
                .payloads
                .iter()
                .any(|o| o.lifecycle_payload() == Some(Payload::Deactivate));
            // Only a joint the bridge had up (or a line had freed): one
            // never started, or whose start failed, waits for a reset.
            if deactivates {
                j.freed |= j.active;
            } else if j.freed && a.payloads.front().is_some_and(Order::is_setpoint) {
                for activate in j.device.lifecycle_orders(&[Payload::Activate], 0) {
                    a.payloads.push_front(activate);
                    if let Some(&first) = a.due.front() {
                        a.due.push_front(first);
                    }
                }
            }
        }
    }

    /// A newer motion step for device `ji` (a position move or a stream's
    /// setpoint: `replaces`; a trajectory's timed step: `timed`), other
    /// than `except`, is about to go: what
    /// waits for the device and would run before it is replaced. A
    /// position move waiting is replaced by a newer position move; any
    /// setpoint by a stream's (`stream`); an axis of a sequential line
    /// waiting for its turn by any newer motion (it would hold the device
    /// for another motor's arrival). A trajectory running on the device is
    /// replaced by a position move or a stream's setpoint: its later
    /// segments are not sent (between segments it ends now and frees the
    /// device; with a segment in flight, once that is answered). A
    /// trajectory scheduled to start later and not begun is not replaced:
    /// it is taken off the device and returned, to be queued again after
    /// the newer step (it starts at its time).
    fn supersede(
        &mut self,
        ji: usize,
        stream: bool,
        replaces: bool,
        timed: bool,
        except: Option<StepRef>,
    ) -> Option<StepRef> {
        let joint = self.joints.get_mut(ji)?;
        // Only what is older than the newer step: queued before it. Kept
        // in place, in order (the queue keeps its room: no allocation a
        // line).
        let mut newer = false;
        joint.queue.retain_mut(|s| {
            let s = *s;
            newer |= Some(s) == except;
            let replaced = !newer
                && self.jobs.get_mut(&s.job).is_some_and(|job| {
                    job.kind == JobKind::Command
                        && job.axes.get_mut(s.axis).is_some_and(|a| {
                            let why = if a.state != AxisState::Queued {
                                None
                            } else if stream && a.is_setpoint() {
                                Some("a newer setpoint of a stream for the motor replaced it before it was sent")
                            } else if replaces && a.is_position_move() {
                                Some("a newer position command for the joint replaced it before it was sent")
                            } else if a.after.is_some() && !a.begun {
                                Some("a newer line for the motor replaced it while it waited for its turn")
                            } else {
                                None
                            };
                            if let Some(why) = why {
                                a.finish(StepOutcome::Superseded, None, why);
                            }
                            why.is_some()
                        })
                });
            if replaced {
                self.stats.superseded += 1;
            }
            !replaced
        });
        // A trajectory (`timed`) waits its turn behind what holds the device.
        if timed {
            return None;
        }
        let running = joint.busy?;
        let a = self
            .jobs
            .get_mut(&running.job)
            .filter(|job| job.kind == JobKind::Command)
            .and_then(|job| job.axes.get_mut(running.axis))?;
        // Scheduled, not begun: it waits for its time, holding the device.
        if a.state == AxisState::Queued && !a.begun && !a.due.is_empty() {
            joint.busy = None;
            joint.wake = None;
            return Some(running);
        }
        if !replaces || !a.is_running_trajectory() {
            return None;
        }
        self.stats.superseded += 1;
        if a.state == AxisState::Queued {
            a.finish(StepOutcome::Superseded, None, REPLACED_TRAJECTORY);
            joint.busy = None;
            joint.wake = None;
        } else {
            a.replaced = Some(REPLACED_TRAJECTORY);
        }
        None
    }

    /// Device `ji` took a move or setpoint of job `by`, of `line` (`None`:
    /// the bridge's own): the lines watched on it for an earlier move will
    /// not arrive (superseded by `line`), and a sequential line whose axis
    /// on it was sent and has not arrived ends at once
    /// ([`Self::end_sequences_on`]).
    fn taken(&mut self, ji: usize, by: u64, line: Option<LineRef>) {
        if let Some(j) = self.joints.get_mut(ji) {
            j.moved_by = line;
        }
        let Some(line) = line else { return };
        let why = || crate::output::json::superseded_by(line);
        self.fail_watches_with(|w| w.line.at() != line && w.waits_on(ji), why);
        self.end_sequences_on(ji, by, line);
    }

    /// A newer line (job `by`, `line`) moved device `ji`: a sequential
    /// line whose axis on `ji` was sent and has not arrived will not see
    /// it arrive (its target is replaced), so the axes waiting for that
    /// arrival (and those waiting for them) are not sent, at once (not
    /// when the arrival's time runs out), and leave their devices' queues;
    /// the line then ends, and its completion says it was superseded.
    fn end_sequences_on(&mut self, ji: usize, by: u64, line: LineRef) {
        let (number, origin) = (line.line, line.origin.0);
        let mut ended: Vec<StepRef> = Vec::new();
        for (&id, job) in self.jobs.iter_mut() {
            if id == by || job.kind != JobKind::Command {
                continue;
            }
            // Its axes on `ji` that went out and have not arrived.
            let replaced = |a: &Axis| a.joint == ji && !a.arrived && a.state != AxisState::Queued;
            let mut cut: Vec<usize> = job
                .axes
                .iter()
                .enumerate()
                .filter(|(_, a)| replaced(a))
                .map(|(k, _)| k)
                .collect();
            // Every axis waiting on one of them, and on those in turn.
            let mut k = 0;
            while let Some(&b) = cut.get(k) {
                k += 1;
                let waiting: Vec<usize> = job
                    .axes
                    .iter()
                    .enumerate()
                    .filter(|(_, a)| a.state == AxisState::Queued && a.after == Some(b))
                    .map(|(w, _)| w)
                    .collect();
                for w in waiting {
                    if let Some(a) = job.axes.get_mut(w) {
                        a.finish(
                            StepOutcome::NotSent,
                            None,
                            format!(
                                "not sent: the axis before it was replaced by line {number} of client {origin} before it arrived"
                            ),
                        );
                        ended.push(StepRef { job: id, axis: w });
                        cut.push(w);
                    }
                }
            }
            // Nothing waits for them now.
            for a in job.axes.iter_mut().filter(|a| replaced(a)) {
                a.arrive_by = None;
            }
        }
        for step in ended {
            for j in &mut self.joints {
                j.queue.retain(|s| *s != step);
            }
        }
    }

    /// A move in flight whose answer is late is sent again by its
    /// driver's retries; sent again, it goes now: its path is held to the
    /// limits in force from where the device is now, as a move's is when
    /// it is first sent. One that would leave them is withdrawn instead:
    /// never sent again, its outcome unknown (its first sending may have
    /// been taken).
    fn withdraw_stale_resends(&mut self, now: Duration) {
        for ji in 0..self.joints.len() {
            let Some(step) = self.joints.get(ji).and_then(|j| j.busy) else {
                continue;
            };
            let Some(&AxisState::InFlight { msg_id, payload }) = self
                .jobs
                .get(&step.job)
                .and_then(|job| job.axes.get(step.axis))
                .map(|a| &a.state)
            else {
                continue;
            };
            if !self.drivers.resend_due(msg_id, &payload, now) {
                continue;
            }
            let Some(why) = self.path_at_send(ji, &payload) else {
                continue;
            };
            self.drivers.forget(ji, msg_id, payload);
            self.stats.refused_at_send += 1;
            if let Some(j) = self.joints.get_mut(ji) {
                j.busy = None;
                j.sending = None;
            }
            if let Some(a) = axis_mut(&mut self.jobs, step) {
                let why = why.replacen(
                    "not sent:",
                    "sent once and not answered; not sent again:",
                    1,
                );
                a.finish(
                    StepOutcome::OutcomeUnknown,
                    None,
                    format!("{why}; the joint may or may not have taken its first sending"),
                );
            }
            self.pump(ji);
        }
        self.finish_jobs();
    }

    /// Why `order` may not go to device `ji` now: its path, planned from
    /// where the device is now, leaves the limits in force (`None` when
    /// it stays within them, or nothing is known to plan from: the
    /// device's own check stands).
    fn path_at_send(&self, ji: usize, order: &Order) -> Option<String> {
        let j = self.joints.get(ji)?;
        let from = j.state_at(self.now)?;
        // Checked already when its line came, this instant, from there.
        let checked = j
            .planned
            .filter(|_| j.planned_at == self.now)
            .map(|(from, p, _)| (from, p));
        let refusal = order.path_refusal(from, checked, || {
            let motor = self.map.motor(&j.name)?;
            Some((motor, motorwire_translate::Effective::from_bus_map(motor)))
        })?;
        Some(format!(
            "not sent: from where it was when its turn came ({} at {} a second), {refusal}",
            short_unit(j.unit.from_degrees(from.0)),
            short_unit(j.unit.from_degrees(from.1))
        ))
    }

    /// The step at the front of device `ji`'s queue, if none of its
    /// steps is in flight.
    fn waiting_front(&self, ji: usize) -> Option<StepRef> {
        let j = self.joints.get(ji)?;
        if j.busy.is_some() {
            return None;
        }
        j.queue.front().copied()
    }

    /// Sends the next waiting step of joint `ji` if none is in flight.
    fn pump(&mut self, ji: usize) {
        let now = self.now;
        loop {
            let Some(front) = self.waiting_front(ji) else {
                return;
            };
            if self.waits_for_arrival(front, now) {
                return; // sequential: the axis before it has not arrived
            }
            if !self.link_free(front) {
                return; // one line in flight to the Orion controller
            }
            let Some(joint) = self.joints.get_mut(ji) else {
                return;
            };
            let Some(step) = joint.queue.pop_front() else {
                return;
            };
            let node = joint.node;
            if self.send_step(now, ji, node, step) {
                return;
            }
        }
    }

    /// Whether `step` (a sequential axis) must wait for the axis before it
    /// to arrive. When that axis failed, or did not arrive in time, `step`
    /// is finished `not_sent` here and need not wait.
    fn waits_for_arrival(&mut self, step: StepRef, now: Duration) -> bool {
        let Some(job) = self.jobs.get(&step.job) else {
            return false;
        };
        // An axis already finished waits for nothing: it leaves its queue.
        let Some(before) = job
            .axes
            .get(step.axis)
            .filter(|a| !a.is_done())
            .and_then(|a| a.after)
        else {
            return false;
        };
        let Some(b) = job.axes.get(before) else {
            return false;
        };
        if b.arrived {
            return false;
        }
        let failed = match &b.state {
            AxisState::Done(r) if r.outcome != StepOutcome::Acked => Some(format!(
                "not sent: {} before it did not complete ({})",
                b.motor,
                r.outcome.name()
            )),
            AxisState::Done(_) => {
                let by = b.arrive_by.unwrap_or_else(|| {
                    let end = self
                        .joints
                        .get(b.joint)
                        .map_or(now, |j| j.moving_until)
                        .max(now);
                    end.saturating_add(
                        (end.saturating_sub(now) / 4).max(Duration::from_millis(500)),
                    )
                });
                if now >= by {
                    Some(format!(
                        "not sent: {} before it did not arrive in time",
                        b.motor
                    ))
                } else {
                    if let Some(a) = axis_mut(
                        &mut self.jobs,
                        StepRef {
                            job: step.job,
                            axis: before,
                        },
                    ) {
                        a.arrive_by = Some(by);
                    }
                    None
                }
            }
            _ => None,
        };
        let Some(why) = failed else {
            return true;
        };
        if let Some(a) = axis_mut(&mut self.jobs, step) {
            a.finish(StepOutcome::NotSent, None, why);
        }
        false
    }

    /// Joint `ji` is at `position` moving at `velocity` (degrees): the
    /// sequential axes on it that have arrived let the next ones go.
    fn sequence_progress(&mut self, ji: usize, position: f64, velocity: f64) {
        let mut freed = Vec::new();
        for (&id, job) in self.jobs.iter_mut() {
            if !job.sequential {
                // No axis of it waits on another (a startup's, a stop's).
                continue;
            }
            // (the axis waited for, and the one waiting: its device, its
            // step, whether it is a position move)
            let waited: Vec<(usize, usize, StepRef, bool)> = job
                .axes
                .iter()
                .enumerate()
                .filter_map(|(w, x)| {
                    Some((
                        x.after?,
                        x.joint,
                        StepRef { job: id, axis: w },
                        x.is_position_move(),
                    ))
                })
                .collect();
            for (k, a) in job.axes.iter_mut().enumerate() {
                let Some(&(_, joint, step, replaces)) = waited.iter().find(|(b, ..)| *b == k)
                else {
                    continue;
                };
                let next = (joint, step, replaces);
                let Some(target) = a.target else { continue };
                if a.joint != ji
                    || a.arrived
                    || !matches!(&a.state, AxisState::Done(r) if r.outcome == StepOutcome::Acked)
                {
                    continue;
                }
                let tolerance = self
                    .map
                    .motor(&a.motor)
                    .map_or(0.1, |m| m.unit.to_degrees(m.arrival_tolerance));
                if (position - target).abs() <= tolerance && velocity.abs() <= tolerance * 10.0 {
                    a.arrived = true;
                    freed.push(next);
                }
            }
        }
        for (ji, step, replaces) in freed {
            // Its turn: it takes its device now, as a line's step that
            // goes at once does when it is queued.
            if let Some(scheduled) = self.supersede(ji, false, replaces, false, Some(step))
                && let Some(j) = self.joints.get_mut(ji)
            {
                j.queue.push_back(scheduled);
            }
            self.pump(ji);
        }
        self.finish_jobs();
    }

    /// Sends the next payload of `step`; returns whether a request is now in
    /// flight for it.
    fn send_step(&mut self, now: Duration, ji: usize, node: u16, step: StepRef) -> bool {
        let Some(job) = self.jobs.get_mut(&step.job) else {
            return false;
        };
        let Some(a) = job.axes.get_mut(step.axis) else {
            return false;
        };
        // A trajectory looping forever: its next cycle.
        if a.payloads.is_empty()
            && let Some(c) = a.cycle.as_mut()
        {
            c.started = c.started.saturating_add(c.period);
            for (offset, p) in &c.payloads {
                a.payloads.push_back(*p);
                a.due.push_back(c.started.saturating_add(*offset));
            }
        }
        // A trajectory's next segment, not due yet: the joint stays this
        // step's until then.
        if let Some(&due) = a.due.front()
            && due > now
            && !a.payloads.is_empty()
        {
            a.state = AxisState::Queued;
            if let Some(j) = self.joints.get_mut(ji) {
                j.busy = Some(step);
                j.wake = Some(due);
            }
            return true;
        }
        a.due.pop_front();
        let Some(payload) = a.payloads.pop_front() else {
            if !a.is_done() {
                a.finish(StepOutcome::Acked, None, "acked");
            }
            return false;
        };
        // Its path from where the device is now, within the limits in
        // force: the line's own check was when it came, and by its turn
        // the device may move otherwise (a move in flight, a slow Ack).
        if let Some(why) = self.path_at_send(ji, &payload) {
            self.stats.refused_at_send += 1;
            if let Some(a) = axis_mut(&mut self.jobs, step) {
                a.finish(StepOutcome::NotSent, None, why);
            }
            return false;
        }
        let Some(job) = self.jobs.get_mut(&step.job) else {
            return false;
        };
        let Some(a) = job.axes.get_mut(step.axis) else {
            return false;
        };
        a.begun = true;
        // In flight before it is handed to its driver: an Orion line may
        // carry other motors' steps, and reads their state first.
        a.state = AxisState::InFlight { msg_id: 0, payload };
        a.attempts = 1;
        let flushed_before = !job.unflushed;
        job.unflushed = true;
        if let Some(j) = self.joints.get_mut(ji) {
            j.busy = Some(step);
            // Where the move starts from, for the model of it once acked.
            j.sending = j.state_at(now).map(|s| (now, s));
            // A stop waiting to be confirmed is not sent again over a newer
            // step (sent again itself, it is judged again once taken).
            j.unconfirmed_stop = None;
        }
        let sent = if payload.sent_together() {
            self.send_together(now, ji, step, payload)
        } else {
            self.drivers.send(now, ji, node, payload)
        };
        let Some(job) = self.jobs.get_mut(&step.job) else {
            return false;
        };
        let Some(a) = job.axes.get_mut(step.axis) else {
            return false;
        };
        match sent {
            Ok(msg_id) => {
                a.state = AxisState::InFlight { msg_id, payload };
                true
            }
            Err(e) => {
                a.finish(StepOutcome::NotSent, None, format!("not sent: {e}"));
                // Nothing of it was written: it waits for no flush.
                if flushed_before {
                    job.unflushed = false;
                }
                if let Some(j) = self.joints.get_mut(ji) {
                    j.busy = None;
                }
                false
            }
        }
    }

    /// The request in flight for device `ji` ended as `c` says (any
    /// driver's).
    fn step_done(&mut self, ji: usize, c: Ended) {
        let Some(step) = self.joints.get_mut(ji).and_then(|j| j.busy.take()) else {
            return;
        };
        let Some(job) = self.jobs.get_mut(&step.job) else {
            return;
        };
        let (kind, line) = (job.kind, job.line_ref());
        let Some(a) = job.axes.get_mut(step.axis) else {
            return;
        };
        let AxisState::InFlight { payload, .. } = a.state else {
            return;
        };
        let a_target = a.target.filter(|_| payload.is_position_move());
        a.state = AxisState::Queued;
        match &c.outcome {
            Outcome::Acked => {
                a.acked += 1;
                if let Some(why) = a.replaced {
                    a.finish(StepOutcome::Superseded, None, why);
                } else if a.payloads.is_empty() && a.cycle.is_none() {
                    // A trajectory looping forever has its next cycle to come.
                    a.finish(StepOutcome::Acked, None, "acked");
                }
            }
            // Stopping a device that is already stopped is a stop.
            Outcome::Nacked {
                already_stopped: true,
                ..
            } if kind.is_stop() => {
                a.finish(StepOutcome::Acked, None, "already stopped");
            }
            Outcome::Nacked { code, why, .. } => {
                a.finish(StepOutcome::Nacked, *code, why.clone());
            }
            Outcome::TimedOut => {
                let who = self
                    .joints
                    .get(ji)
                    .map_or_else(String::new, |j| j.device.who(j.node));
                a.finish(
                    StepOutcome::OutcomeUnknown,
                    None,
                    format!(
                        "sent {} times, never answered: {who} may or may not have executed it",
                        c.attempts
                    ),
                );
            }
        }
        let more = !a.is_done();
        if c.outcome == Outcome::TimedOut
            && let Some(j) = self.joints.get_mut(ji)
        {
            if let (JobKind::Command, Some(target)) = (kind, a_target) {
                j.unresolved = Some(Unresolved {
                    origin: line.map(|l| l.origin),
                    line: line.map_or(0, |l| l.line),
                    target,
                });
            }
            if j.online {
                j.online = false;
                self.out.push_back(Output::Event(Event::Offline {
                    motor_id: j.name.clone(),
                    node: j.node,
                    reason: "a request timed out".to_owned(),
                }));
                self.fail_watches(|w| w.waits_on(ji), "the joint went offline");
            }
        }
        // A setpoint whose answer never came may be running: the deadman
        // watches it as if it were acked.
        if c.outcome == Outcome::Acked
            || (c.outcome == Outcome::TimedOut && payload.holds_setpoint())
        {
            self.track(ji, payload, c.at);
            // A line's stop of the device (a motor line's free or stop, a
            // `disabled`) takes it as a move does.
            let stops = kind == JobKind::Command
                && (payload.ends_setpoint()
                    || payload.lifecycle_payload() == Some(Payload::Deactivate));
            if payload.is_setpoint() || stops {
                self.taken(
                    ji,
                    step.job,
                    (kind == JobKind::Command).then_some(line).flatten(),
                );
            }
        }
        self.answer_early(step.job);
        // A stop never answered by a device whose feedback may never come
        // to judge it by (a compact device answers a command and not much
        // else): when in doubt, stop again, unless a newer step waits.
        let stop_again = c.outcome == Outcome::TimedOut
            && payload.unconfirmed_stop().is_some()
            && self.joints.get(ji).is_some_and(|j| j.queue.is_empty());
        if more {
            let node = self.joints.get(ji).map_or(0, |j| j.node);
            if !self.send_step(self.now, ji, node, step) {
                self.pump(ji);
            }
        } else {
            self.pump(ji);
        }
        if stop_again {
            self.stop_again(ji, payload, c.at.max(self.now), "answered");
        }
        self.finish_jobs();
    }

    /// A trajectory line under way: once each of its motors' first
    /// segment is acknowledged (and nothing of it failed), its result is
    /// given (`ok:true`, `arrival_follows:true`); the fate of its later
    /// segments comes in its completion line.
    fn answer_early(&mut self, id: u64) {
        let now = self.now;
        let Some(job) = self.jobs.get_mut(&id) else {
            return;
        };
        if job.answered.is_some() || !job.answers_early() {
            return;
        }
        let failed = job
            .axes
            .iter()
            .any(|a| matches!(&a.state, AxisState::Done(r) if r.outcome != StepOutcome::Acked));
        if failed || !job.axes.iter().all(|a| a.acked > 0) {
            return;
        }
        let Some(meta) = job.line.clone() else {
            return;
        };
        job.answered = Some(now);
        let r = LineResult {
            ok: true,
            line: meta.number,
            acked: Some(job.axes.iter().map(|a| a.motor.clone()).collect()),
            arrival_follows: Some(true),
            latency_us: job.last_frame.map(|t| us(t.saturating_sub(job.received))),
            ack_us: Some(us(now.saturating_sub(job.received))),
            losses: std::mem::take(&mut job.report.losses),
            ..LineResult::default()
        };
        self.answer(&meta, r);
    }

    /// Remembers an acked request's effect on its device
    /// ([`Order::effect`]): its lifecycle, a move's target and (as
    /// planned from the last feedback) when it ends, the deadman of a
    /// setpoint it holds.
    fn track(&mut self, ji: usize, order: Order, at: Duration) {
        let Some(j) = self.joints.get(ji) else { return };
        // A line that leaves it inactive again waits behind this order
        // (looked for only behind an Activate: every ack comes here).
        let deactivation_waits = order.lifecycle_payload() == Some(Payload::Activate)
            && j.queue.iter().any(|s| {
                self.jobs
                    .get(&s.job)
                    .and_then(|job| job.axes.get(s.axis))
                    .is_some_and(|a| {
                        a.payloads
                            .iter()
                            .any(|o| o.lifecycle_payload() == Some(Payload::Deactivate))
                    })
            });
        // Planned from where it was when the order was sent, as the
        // device plans it.
        let sent_from = j.sending.map(|(_, from)| from);
        let cx = Context {
            at,
            motion: sent_from.or(j.motion.map(|(p, v)| (p, v, 0.0))),
            unit: j.unit,
            max_velocity: j.pace.max_velocity,
            max_acceleration: j.pace.max_acceleration,
            command_timeout: j.pace.command_timeout,
            planned: j.planned,
        };
        let effect = order.effect(&cx);
        let Some(j) = self.joints.get_mut(ji) else {
            return;
        };
        // The move as the device plans it, from where it was sent (the
        // gate's own plan when it is the same move from the same state);
        // any other order leaves the device to its reports.
        let gate_plan = j
            .planned
            .zip(j.planned_profile.take())
            .filter(|((from, ..), _)| Some(*from) == sent_from)
            .map(|((_, p, _), profile)| (p, profile));
        let model = j
            .sending
            .take()
            .and_then(|(t, from)| Some((t, order.device_plan(from, gate_plan)?)));
        j.set_model(model);
        j.planned = None;
        j.deadman = effect.deadman;
        j.held_velocity = effect.deadman.and_then(|_| order.held_velocity(j.unit));
        if let Some(b) = j.limit_braked.as_mut().filter(|b| b.sending) {
            // The limit brake itself going out: what it was braked short
            // of is kept.
            b.sending = false;
        } else if effect.deadman.is_some() || effect.target.is_some() {
            // A new setpoint or move taken (one toward the limit it was
            // braked short of only once it had stopped).
            j.limit_braked = None;
        }
        if order.unconfirmed_stop().is_some() {
            let speed = j.feedback.as_ref().map_or(0.0, |f| f.velocity.abs());
            j.unconfirmed_stop = Some((order, at, speed));
        } else {
            j.unconfirmed_stop = None;
            j.stop_resends = 0;
        }
        if let Some(target) = effect.target {
            j.target = target;
        }
        match effect.moving {
            Moving::Unchanged => {}
            Moving::Until(t) => j.moving_until = t,
            Moving::AtMost(t) => j.moving_until = j.moving_until.min(t),
        }
        if let Some(active) = effect.active {
            j.active = active;
            // Active again, and no line waits to leave it inactive: its
            // next command needs no Activate first.
            if active && !deactivation_waits {
                j.freed = false;
            }
        }
        if effect.settles {
            j.unresolved = None;
        }
    }

    /// Emits the result of every job that is done.
    fn finish_jobs(&mut self) {
        // Looked at after every event, and most find nothing done.
        if !self.jobs.values().any(|j| j.is_done()) {
            return;
        }
        let mut done = std::mem::take(&mut self.done_scratch);
        done.clear();
        done.extend(
            self.jobs
                .iter()
                .filter(|(_, j)| j.is_done())
                .map(|(id, _)| *id),
        );
        for &id in &done {
            if let Some(job) = self.jobs.remove(&id) {
                self.complete(job);
                // The drain may end now: looked at once, by its timer.
                self.drain_recheck = matches!(self.phase, Phase::Draining { .. });
            }
        }
        // Kept for the next call (a nested call, from a completion, found
        // it empty and allocated its own: the larger is kept).
        if done.capacity() >= self.done_scratch.capacity() {
            self.done_scratch = done;
        }
    }

    fn complete(&mut self, job: Box<Job>) {
        let job = *job;
        let now = self.now;
        if let Some(since) = job.answered {
            return self.complete_answered(job, since);
        }
        // A stream's setpoint replaced by a newer one before it was sent
        // is what a stream does: no failure.
        let stream = job.line.as_ref().is_some_and(|l| l.stream);
        // Only a reset needs every joint it moved.
        let moved_joints: Vec<usize> = if job.kind == JobKind::Reset {
            job.axes.iter().map(|a| a.joint).collect()
        } else {
            Vec::new()
        };
        // The motors acked, the moves acked (to watch for arrival), and
        // what became of the rest: one pass, each name moved, not copied.
        let mut acked: Vec<String> = Vec::with_capacity(job.axes.len());
        let mut moved: Vec<WatchAxis> = Vec::with_capacity(job.axes.len());
        let mut failures: Vec<StepReport> = Vec::new();
        let mut superseded = false;
        for a in job.axes {
            let AxisState::Done(r) = a.state else {
                continue;
            };
            match r.outcome {
                StepOutcome::Acked => {
                    if let Some(target) = a.target {
                        moved.push(self.watch_axis(a.joint, a.motor, target));
                    }
                    acked.push(r.motor);
                }
                StepOutcome::Superseded if stream => superseded = true,
                _ => failures.push(r),
            }
        }
        match job.kind {
            JobKind::Startup => {
                for name in acked {
                    self.out.push_back(Output::Event(Event::Startup {
                        motor_id: name,
                        ok: true,
                        error: None,
                    }));
                }
                for f in failures {
                    self.out.push_back(Output::Event(Event::Startup {
                        motor_id: f.motor.clone(),
                        ok: false,
                        error: Some(f),
                    }));
                }
                if self.phase == Phase::Starting {
                    // Ready once every device that answers has been read
                    // (its position known from the first line on), or
                    // after the offline time for those that do not.
                    self.settle_until = Some(now.saturating_add(self.config.offline_after));
                    self.try_ready();
                }
                return;
            }
            JobKind::Shutdown => {
                self.out.push_back(Output::Event(Event::Stopped {
                    deactivated: acked,
                    failures,
                }));
                self.enter(Phase::Finished);
                return;
            }
            JobKind::Reset => {
                for a in &moved_joints {
                    if let Some(j) = self.joints.get_mut(*a) {
                        j.resetting = false;
                        if failures.is_empty() {
                            j.needs_reset = None;
                        }
                    }
                }
            }
            JobKind::Deadman if !failures.is_empty() && !self.latched => {
                // The deadman could not stop a device (its stop was never
                // answered): when in doubt, stop everything.
                let why = failures
                    .iter()
                    .map(|f| format!("{} ({})", f.motor, f.outcome.name()))
                    .collect::<Vec<_>>()
                    .join(", ");
                self.emergency_stop(
                    now,
                    None,
                    Vec::new(),
                    format!("deadman: could not stop {why}"),
                );
                return;
            }
            JobKind::Command | JobKind::EmergencyStop | JobKind::Release | JobKind::Deadman => {}
        }
        // A stop the bridge made itself (the deadman's, a joint's own)
        // answers no line, but the stop lines that rode on it are answered.
        if job.line.is_none() && job.riders.is_empty() {
            return;
        }
        let number = job.line.as_ref().map_or(0, |l| l.number);
        let latency = job.last_frame.map(|t| us(t.saturating_sub(job.received)));
        let ok = failures.is_empty() && job.data_error.is_none();
        let error = if !failures.is_empty() {
            Some(failure_error(&failures, job.cut.as_deref()))
        } else {
            job.data_error
                .clone()
                .map(|why| ErrorBody::new(ErrorKind::NoAnswer, why))
        };
        let mut r = Box::new(LineResult {
            ok,
            line: number,
            emergency_stop: job.kind == JobKind::EmergencyStop,
            released: job.kind == JobKind::Release,
            error,
            acked: Some(acked),
            outcomes: failures,
            problems: job.problems,
            latency_us: latency,
            ack_us: Some(us(now.saturating_sub(job.received))),
            stop_latency_us: if job.kind == JobKind::EmergencyStop {
                latency
            } else {
                None
            },
            losses: job.report.losses,
            data: job.data.clone(),
            ..LineResult::default()
        });
        let watched = job.kind == JobKind::Command && !moved.is_empty();
        r.arrival_follows = if stream {
            Some(false)
        } else {
            watched.then_some(true)
        };
        r.superseded = superseded;
        // The riders' results come before the line's own, as they did
        // when each was pushed as it was built.
        for rider in job.riders {
            let rr = LineResult {
                line: rider.line.number,
                problems: rider.problems,
                // The stop frames went out before this line came.
                latency_us: latency.map(|_| 0),
                stop_latency_us: latency.map(|_| 0),
                ack_us: Some(us(now.saturating_sub(rider.received))),
                arrival_follows: None,
                ..LineResult::clone(&r)
            };
            self.answer(&rider.line, rr);
        }
        let Some(meta) = job.line else { return };
        self.answer(&meta, r);
        // (Lines watched on the motors it moved were superseded when each
        // took its setpoint: [`Self::taken`].)
        if watched && !stream {
            self.watch(meta, moved, now);
        }
    }

    /// A trajectory line answered when it got under way ends: every
    /// segment acknowledged, it is watched until it arrives; otherwise its
    /// completion line says at once which motor's later segments did not
    /// go, and why.
    fn complete_answered(&mut self, job: Job, since: Duration) {
        let Some(meta) = job.line else { return };
        let targets: Vec<WatchAxis> = job
            .axes
            .iter()
            .filter_map(|a| Some(self.watch_axis(a.joint, a.motor.clone(), a.target?)))
            .collect();
        let failures: Vec<&StepReport> = job
            .axes
            .iter()
            .filter_map(|a| match &a.state {
                AxisState::Done(r) if r.outcome != StepOutcome::Acked => Some(r),
                _ => None,
            })
            .collect();
        if failures.is_empty() {
            return self.watch(meta, targets, since);
        }
        let said = failures
            .iter()
            .map(|f| format!("{}: {} ({})", f.motor, f.outcome.name(), f.message))
            .collect::<Vec<_>>()
            .join("; ");
        let reason = match &job.cut {
            Some(why) => format!("{why}: the rest of the trajectory was not sent"),
            None => format!("a later segment did not go: {said}"),
        };
        let mut w = self.watch_of(meta, targets, since);
        for (ji, j) in self.joints.iter().enumerate() {
            if let Some((pos, vel)) = j.motion
                && w.axes.iter().any(|a| a.joint == ji)
            {
                w.observe(ji, pos, vel, self.now);
            }
        }
        let origin = w.line.origin;
        let arrival = w.verdict(self.now, Some(reason));
        self.out.push_back(Output::Arrival { origin, arrival });
    }

    // ---- links ------------------------------------------------------------

    /// Whether `step` (queued for a device) may go now as far as its
    /// device's link goes: a stop always; a step with nothing to send;
    /// else as the driver says (the Orion controller takes one line at a
    /// time).
    fn link_free(&self, step: StepRef) -> bool {
        let Some(job) = self.jobs.get(&step.job) else {
            return true;
        };
        let order = job.axes.get(step.axis).and_then(|a| a.payloads.front());
        job.kind.is_stop() || self.drivers.link_free(order)
    }

    /// Whether `step` is a sequential line's axis whose earlier axis has
    /// not arrived: it cannot go yet, so it does not keep its link from
    /// its own work (an Orion controller unpolled would fall silent).
    fn after_earlier_axis(jobs: &Jobs, step: StepRef) -> bool {
        jobs.get(&step.job)
            .and_then(|job| {
                let before = job.axes.get(job.axes.get(step.axis)?.after?)?;
                Some(!before.arrived)
            })
            .unwrap_or(false)
    }

    /// Sends `order` of `step` for device `ji` in one message with the
    /// orders that join it ([`Order::joins`]) waiting at the front of the
    /// other devices for the same line (the Orion motors of one input
    /// line: one line to the controller). Returns the message's number.
    fn send_together(
        &mut self,
        now: Duration,
        ji: usize,
        step: StepRef,
        order: Order,
    ) -> Result<u32, String> {
        if let Some(e) = self.drivers.refuses(&order) {
            return Err(e);
        }
        let mut orders = vec![(ji, order)];
        let mut others = Vec::new();
        for k in 0..self.joints.len() {
            if k == ji {
                continue;
            }
            let Some(front) = self.waiting_front(k) else {
                continue;
            };
            if front.job != step.job {
                continue;
            }
            let Some(a) = axis_mut(&mut self.jobs, front) else {
                continue;
            };
            let fits = a.after.is_none() && a.payloads.front().is_some_and(|o| order.joins(o));
            if !fits || !a.due.is_empty() {
                continue;
            }
            let Some(payload) = a.payloads.pop_front() else {
                continue;
            };
            a.begun = true;
            orders.push((k, payload));
            if let Some(j) = self.joints.get_mut(k) {
                j.queue.pop_front();
                j.busy = Some(front);
            }
            others.push((front, payload));
        }
        let sent = self.drivers.send_together(now, &orders);
        for (front, payload) in others {
            let Some(a) = axis_mut(&mut self.jobs, front) else {
                continue;
            };
            match &sent {
                Ok(id) => {
                    a.state = AxisState::InFlight {
                        msg_id: *id,
                        payload,
                    };
                    a.attempts = 1;
                }
                Err(e) => a.finish(StepOutcome::NotSent, None, format!("not sent: {e}")),
            }
        }
        if sent.is_err() {
            for (k, _) in orders.iter().skip(1) {
                if let Some(j) = self.joints.get_mut(*k) {
                    j.busy = None;
                }
            }
        }
        sent
    }

    /// The links' own work due at `now` (the Orion controller's line in
    /// flight, its recovery stop, its poll when no step waits for it).
    fn link_timeouts(&mut self, now: Duration) {
        self.drivers.link_timeouts(now, &self.joints);
        self.drain_drivers();
        let jobs = &self.jobs;
        let joints = &self.joints;
        let busy = |k: usize| {
            let j = &joints[k];
            j.busy.is_some()
                || j.queue
                    .front()
                    .is_some_and(|s| !Self::after_earlier_axis(jobs, *s))
        };
        self.drivers.link_housekeeping(now, &self.joints, busy);
    }

    /// The next line for the Orion controller (without its newline).
    pub fn poll_orion_line(&mut self) -> Option<String> {
        let line = self.drivers.poll_line()?;
        self.changed();
        Some(line)
    }

    /// One line from the Orion controller, received at `now`.
    pub fn handle_orion_line(&mut self, now: Duration, line: &str) {
        self.changed();
        self.now = self.now.max(now);
        self.drivers
            .handle_line(self.now, line, &self.joints, &self.map);
        self.drain_drivers();
    }

    /// A line from the Orion controller that could not be read (too long,
    /// not UTF-8), at `now`: counted, and reported at most
    /// [`MAX_BAD_LINE_EVENTS`] times a second.
    pub fn handle_orion_unreadable(&mut self, now: Duration, reason: &str) {
        self.changed();
        self.now = self.now.max(now);
        self.drivers.handle_unreadable(self.now, reason);
        self.drain_drivers();
    }

    /// The link to the Orion controller ended (`error` says how): its
    /// motors are offline, and what was in flight has an unknown outcome.
    pub fn orion_link_lost(&mut self, now: Duration, error: &str) {
        self.changed();
        self.now = self.now.max(now);
        if !self.drivers.link_lost(now, error, &self.joints) {
            return;
        }
        self.drain_drivers();
        self.handle_timeout(now);
    }

    /// `{"orion":"fold"}` or `{"orion":"unfold"}`: an arm-wide command, for
    /// every device that takes one (the Orion controller's motors: one
    /// line).
    fn arm_command(&mut self, now: Duration, meta: LineMeta, command: ArmCommand) {
        let name = match command {
            ArmCommand::Fold => "fold",
            ArmCommand::Unfold => "unfold",
            ArmCommand::Stop => "stop",
        };
        let meta = meta.labelled(Label::Orion(name.to_owned()));
        let axes: Vec<Axis> = self
            .joints
            .iter()
            .enumerate()
            .filter_map(|(ji, j)| {
                let order = j.device.arm_order(command)?;
                Some(Axis::of(j.name.clone(), ji, [order]))
            })
            .collect();
        if axes.is_empty() {
            let e = ErrorBody::refused(
                BridgeRule::OrionNotAttached,
                "no Orion arm controller is attached (motorwire bridge --orion ...)",
            );
            self.refuse(&meta, e);
            return;
        }
        if let Err(e) = self.admit_now(axes.iter().map(|a| a.motor.as_str())) {
            self.refuse(&meta, e);
            return;
        }
        self.command_job(now, meta, axes, Report::default());
    }

    /// The refusal for a motor among `motors` whose driver is not
    /// attached (an Orion motor without `--orion`).
    fn unattached<'a>(&self, motors: impl Iterator<Item = &'a str>) -> Option<ErrorBody> {
        crate::device::unattached(&self.map, self.config.orion, motors)
    }

    // ---- request lines --------------------------------------------------
    //
    // Lines that ask a joint for something and wait for its answer:
    // telemetry, power metrics, the fault history (`{"request":...}`) and
    // calibration (`{"calibration":"start"|"stop",...}`). A request line is
    // one job: its request is sent like any command (one in flight per
    // joint, retried, acked), and the line's result waits for the message
    // it asked for, which comes back in `data`. The joint may send it
    // before or after its Ack. Nothing within the wait
    // ([`Bridge::answer_wait`]) is the error `no_answer`. A calibration's
    // status messages are `calibration` events while it runs; its result
    // ends the start line (`ok` only when it succeeded).

    /// How long a request line waits for its answer after it is sent:
    /// every attempt's Ack timeout and a margin.
    fn answer_wait(&self) -> Duration {
        self.config
            .client
            .timeout
            .saturating_mul(u32::from(self.config.client.retries) + 1)
            .saturating_add(ANSWER_MARGIN)
    }

    /// The device `motor` names if it can do `needs_to` and has the
    /// message `needs` (an iRPC joint, in its wire version), or the
    /// refusal to answer with.
    fn joint_for(
        &self,
        motor: &str,
        needs_to: Capability,
        needs: PayloadKind,
        what: &str,
    ) -> Result<usize, ErrorBody> {
        let Some(ji) = self.joint_index(motor).filter(|&ji| {
            self.joints
                .get(ji)
                .is_some_and(|j| j.device.supports(needs_to))
        }) else {
            if self.joint_index(motor).is_none() {
                return Err(ErrorBody::refused(
                    BridgeRule::UnknownMotor,
                    format!("motor {motor:?} is not in the bus map"),
                )
                .about(motor));
            }
            let why = match needs_to {
                Capability::Reset => {
                    format!("{motor} takes no reset: only iRPC joints and moteus controllers do")
                }
                _ => format!("{motor} is not an iRPC joint of the bus map"),
            };
            return Err(ErrorBody::refused(BridgeRule::NotAnIrpcJoint, why).about(motor));
        };
        let device = self.joints.get(ji).map(|j| j.device);
        if device.is_none_or(|d| !d.speaks(needs)) {
            let wire = device.map(Device::wire);
            return Err(ErrorBody::new(
                ErrorKind::Unsupported,
                format!(
                    "{motor} speaks iRPC {}, which has no {what}",
                    wire.map_or("?", |w| w.name())
                ),
            )
            .about(motor));
        }
        if self.joints.get(ji).is_some_and(|j| !j.online) {
            return Err(
                ErrorBody::new(ErrorKind::Offline, format!("{motor} is offline")).about(motor),
            );
        }
        Ok(ji)
    }

    /// `{"request":K,"motor_id":M}`.
    fn request_line(&mut self, now: Duration, meta: LineMeta, kind: RequestKind, motor: &str) {
        let meta = meta.labelled(Label::Motor(motor.to_owned()));
        let (needs, payload, awaits, what) = crate::device::irpc::request(kind);
        let ji = match self.joint_for(motor, Capability::Requests, needs, what) {
            Ok(ji) => ji,
            Err(e) => return self.refuse(&meta, e),
        };
        let deadline = now.saturating_add(self.answer_wait());
        self.open_waiting(now, meta, (motor, ji), payload, awaits, deadline);
    }

    /// `{"calibration":"start"|"stop","motor_id":M,...}`.
    fn calibration_line(
        &mut self,
        now: Duration,
        meta: LineMeta,
        motor: &str,
        start: Option<CalibrationRequest>,
    ) {
        let meta = meta.labelled(Label::Motor(motor.to_owned()));
        let ji = match self.joint_for(
            motor,
            Capability::Requests,
            PayloadKind::StartCalibration,
            "calibration (v2.1 on)",
        ) {
            Ok(ji) => ji,
            Err(e) => return self.refuse(&meta, e),
        };
        let payload = crate::device::irpc::calibration(start);
        let Some(request) = start else {
            let axis = Axis::new(motor.to_owned(), ji, [payload]);
            self.command_job(now, meta, vec![axis], Report::default());
            return;
        };
        // A calibration moves the joint: refused as a motion is, and its
        // own limits held to the limits in force.
        if let Err(e) = self.admit_now(std::iter::once(motor)) {
            return self.refuse(&meta, e);
        }
        if let Err(r) = motorwire_translate::gate_calibration(&self.map, motor, &request) {
            return self.refuse(&meta, ErrorBody::gate(&r));
        }
        let phases = request.phases.count_ones().max(1);
        let per_phase =
            Duration::try_from_secs_f32(request.phase_timeout).unwrap_or(Duration::ZERO);
        let deadline = now
            .saturating_add(self.answer_wait())
            .saturating_add(per_phase.saturating_mul(phases))
            .saturating_add(CALIBRATION_MARGIN);
        let kind = AwaitKind::CalibrationResult;
        self.open_waiting(now, meta, (motor, ji), payload, kind, deadline);
    }

    /// Line `meta`'s request `payload` to `device` (its name and index),
    /// whose result waits for its answer of `kind` until `deadline`.
    fn open_waiting(
        &mut self,
        now: Duration,
        meta: LineMeta,
        device: (&str, usize),
        payload: Payload,
        kind: AwaitKind,
        deadline: Duration,
    ) {
        let (motor, ji) = device;
        let awaiting = Awaiting {
            joint: ji,
            kind,
            deadline,
        };
        let id = self.next_job;
        let axis = Axis::new(motor.to_owned(), ji, [payload]);
        self.command_job(now, meta, vec![axis], Report::default());
        // Not done yet (a job is taken out once done): it waits.
        if let Some(job) = self.jobs.get_mut(&id) {
            job.awaiting = Some(awaiting);
        }
    }

    /// Device `ji` answered what a request line may wait for: progress
    /// is reported, and the oldest line waiting for this from this device
    /// gets its data.
    fn answered(&mut self, ji: usize, answer: Answer) {
        let (kind, data, error) = match answer {
            Answer::Progress(e) => {
                self.out.push_back(Output::Event(e));
                return;
            }
            Answer::Data { kind, data, error } => (kind, data, error),
        };
        let Some(job) = self
            .jobs
            .values_mut()
            .find(|j| j.awaiting.is_some_and(|a| a.joint == ji && a.kind == kind))
        else {
            return;
        };
        job.awaiting = None;
        job.data_error = error;
        job.data = Some(data);
        self.finish_jobs();
    }

    /// Request lines whose answer did not come in time.
    fn awaiting_timeouts(&mut self, now: Duration) {
        let mut any = false;
        for job in self.jobs.values_mut() {
            let Some(a) = job.awaiting.filter(|a| now >= a.deadline) else {
                continue;
            };
            job.awaiting = None;
            let what = match a.kind {
                AwaitKind::Telemetry => "TelemetryStream",
                AwaitKind::PowerMetrics => "PowerMetrics",
                AwaitKind::FaultHistory => "FaultHistory",
                AwaitKind::CalibrationResult => "CalibrationResult",
            };
            let motor = job
                .axes
                .first()
                .map(|x| x.motor.clone())
                .unwrap_or_default();
            job.data_error = Some(format!(
                "{motor} acked the request, but no {what} came within {} ms",
                now.saturating_sub(job.received).as_millis()
            ));
            any = true;
        }
        if any {
            self.finish_jobs();
        }
    }

    // ---- arrival ----------------------------------------------------------

    /// Watches a motion line's acked moves until they arrive. A line that
    /// ends after a newer line moved one of its joints (a sequential line
    /// ends with its last axis), or after a stop, has its verdict at once.
    fn watch(&mut self, meta: LineMeta, moved: Vec<WatchAxis>, since: Duration) {
        let now = self.now;
        let line = meta.at();
        let replaced_by = moved.iter().find_map(|a| {
            self.joints
                .get(a.joint)
                .and_then(|j| j.moved_by)
                .filter(|by| *by != line)
        });
        let mut w = self.watch_of(meta, moved, since);
        let origin = w.line.origin;
        let verdict = if self.latched {
            Some("stopped by the emergency stop".to_owned())
        } else {
            replaced_by.map(crate::output::json::superseded_by)
        };
        if let Some(why) = verdict {
            let arrival = w.verdict(now, Some(why));
            self.out.push_back(Output::Arrival { origin, arrival });
            return;
        }
        // Already there (a move to where it stands)?
        let mut done = false;
        for (ji, j) in self.joints.iter().enumerate() {
            if let Some((pos, vel)) = j.motion
                && w.axes.iter().any(|a| a.joint == ji)
            {
                done = w.observe(ji, pos, vel, now) || done;
            }
        }
        if done && w.axes.iter().all(|a| a.arrived.is_some()) {
            let arrival = w.verdict(now, None);
            self.out.push_back(Output::Arrival { origin, arrival });
        } else {
            self.arrivals.push(w);
        }
    }

    /// Device `ji`'s part of a watch: `motor`'s move to `target`
    /// (degrees), within the map's arrival tolerance.
    fn watch_axis(&self, ji: usize, motor: String, target: f64) -> WatchAxis {
        let (unit, tolerance) = self
            .joints
            .get(ji)
            .map_or((AngleUnit::Degrees, 0.1), |j| (j.unit, j.tolerance));
        WatchAxis {
            joint: ji,
            motor,
            target,
            tolerance,
            unit,
            arrived: None,
            last_error: None,
        }
    }

    /// The watch of line `meta`'s moves (`axes`, [`Bridge::watch_axis`]),
    /// its result given at `since`: due by the end of the devices'
    /// planned motion and a margin.
    fn watch_of(&self, meta: LineMeta, axes: Vec<WatchAxis>, since: Duration) -> Watch {
        let now = self.now;
        let end = axes
            .iter()
            .filter_map(|a| self.joints.get(a.joint))
            .map(|j| j.moving_until)
            .fold(now, Duration::max);
        let planned = end.saturating_sub(now);
        let margin = (planned / 4).max(Duration::from_millis(500));
        Watch {
            line: meta,
            since,
            deadline: end.saturating_add(margin),
            axes,
        }
    }

    /// Joint `ji` is at `position` moving at `velocity` (degrees): the
    /// lines that have now arrived are said so.
    fn observe(&mut self, ji: usize, position: f64, velocity: f64, at: Duration) {
        let mut i = 0;
        while let Some(w) = self.arrivals.get_mut(i) {
            if w.axes.iter().any(|a| a.joint == ji) && w.observe(ji, position, velocity, at) {
                let w = self.arrivals.remove(i);
                let origin = w.line.origin;
                let arrival = w.verdict(at, None);
                self.out.push_back(Output::Arrival { origin, arrival });
            } else {
                i += 1;
            }
        }
    }

    /// The watched lines `pick` chooses will not arrive: said, with `why`.
    fn fail_watches(&mut self, pick: impl Fn(&Watch) -> bool, why: &str) {
        self.fail_watches_with(pick, || why.to_owned());
    }

    /// [`Self::fail_watches`] with the reason made only when a watch
    /// fails (a line's own supersession is looked for on every move).
    fn fail_watches_with(&mut self, pick: impl Fn(&Watch) -> bool, why: impl Fn() -> String) {
        let now = self.now;
        let mut i = 0;
        while let Some(w) = self.arrivals.get(i) {
            if pick(w) {
                let w = self.arrivals.remove(i);
                let origin = w.line.origin;
                let arrival = w.verdict(now, Some(why()));
                self.out.push_back(Output::Arrival { origin, arrival });
            } else {
                i += 1;
            }
        }
    }

    // ---- the bus --------------------------------------------------------

    /// Takes a frame from the bus.
    pub fn handle_frame(&mut self, now: Duration, frame: &Frame) {
        self.changed();
        self.now = self.now.max(now);
        self.drivers.handle_frame(self.now, frame, &self.joints);
        self.drain_drivers();
    }

    /// Device `ji` was reported at `position` moving at `velocity`
    /// (degrees) at `at`, by any driver: the lines that have now arrived
    /// are said so, and sequential axes waiting on it may go.
    fn moved(&mut self, ji: usize, position: f64, velocity: f64, at: Duration) {
        if !self.arrivals.is_empty() {
            self.observe(ji, position, velocity, at);
        }
        self.sequence_progress(ji, position, velocity);
    }

    /// The indices of the devices `pick` chooses.
    fn joints_where(&self, pick: impl Fn(&Joint) -> bool) -> Vec<usize> {
        self.joints
            .iter()
            .enumerate()
            .filter(|(_, j)| pick(j))
            .map(|(i, _)| i)
            .collect()
    }

    /// Devices holding a velocity or torque setpoint that was not renewed
    /// within their command timeout are brought to a stop (velocity 0),
    /// and an event says so.
    fn deadman(&mut self, now: Duration) {
        // Latched, every device was sent its stop: a setpoint's deadman
        // (one armed by an answer that came after the stop) has nothing
        // to stop, and nothing but stops goes out.
        if self.latched {
            for j in &mut self.joints {
                j.deadman = None;
            }
            return;
        }
        let mut due = self.joints_where(|j| j.deadman.is_some_and(|d| now >= d));
        // A device whose stop is in flight (a motor line's hold, free or
        // stop) is being stopped: the deadman's own stop behind it would
        // only undo a hold (a moteus controller's stop mode is torque off).
        // It looks again [`REBRAKE_AFTER`] on: the stop taken disarms it;
        // one lost, answered no or not sent leaves it to stop the device.
        due.retain(|&ji| {
            let stopping = self
                .joints
                .get(ji)
                .and_then(|j| j.busy)
                .and_then(|s| self.jobs.get(&s.job)?.axes.get(s.axis))
                .is_some_and(|a| {
                    matches!(a.state, AxisState::InFlight { payload, .. } if payload.ends_setpoint())
                });
            if stopping && let Some(j) = self.joints.get_mut(ji) {
                j.deadman = Some(now.saturating_add(REBRAKE_AFTER));
            }
            !stopping
        });
        self.hold_still(now, due, true);
    }

    /// Brings devices `which` (each holding a velocity or torque setpoint)
    /// to a stop, velocity 0, as the deadman does; `timed_out`: it is the
    /// deadman, and an event says so (at the end of input the `stopping`
    /// event does).
    fn hold_still(&mut self, now: Duration, which: Vec<usize>, timed_out: bool) {
        let now_ms = self.unix_ms(now) as u64;
        for ji in which {
            let Some(j) = self.joints.get_mut(ji) else {
                continue;
            };
            let name = j.name.clone();
            let Some(order) = j.device.hold_still(now_ms) else {
                j.deadman = None;
                continue;
            };
            let event = timed_out.then(|| Event::Deadman {
                motor_id: name.clone(),
                timeout_ms: self
                    .map
                    .motor(&name)
                    .and_then(|m| m.command_timeout)
                    .map_or(0, |t| u64::try_from(t.as_millis()).unwrap_or(u64::MAX)),
            });
            self.stop_setpoint(now, ji, order, event);
        }
    }

    /// Device `ji`'s velocity or torque setpoint ended by `order` (its
    /// stop), ahead of anything waiting for the device, `event` said.
    fn stop_setpoint(&mut self, now: Duration, ji: usize, order: Order, event: Option<Event>) {
        let Some(j) = self.joints.get_mut(ji) else {
            return;
        };
        j.deadman = None;
        let name = j.name.clone();
        let axis = Axis::of(name, ji, [order]);
        if let Some(e) = event {
            self.out.push_back(Output::Event(e));
        }
        // Ahead of anything waiting for the device.
        if let Some(j) = self.joints.get_mut(ji) {
            for s in j.queue.drain(..).collect::<Vec<_>>() {
                if let Some(a) = axis_mut(&mut self.jobs, s) {
                    a.finish(
                        StepOutcome::Cancelled,
                        None,
                        "cancelled: the deadman stopped the device first",
                    );
                }
            }
        }
        self.own_stop(now, axis);
    }

    /// The deceleration a motor is braked with before a position limit
    /// (its unit a second squared): the lesser of the limits' deceleration
    /// and acceleration in force, `None` when they give neither.
    fn braking(limits: &Limits) -> Option<f64> {
        match (limits.max_deceleration, limits.max_acceleration) {
            (Some(d), Some(a)) => Some(d.min(a)),
            (d, a) => d.or(a),
        }
        .filter(|d| d.is_finite() && *d > 0.0)
    }

    /// How far a motor going at `v` goes before it stops, braked at
    /// [`Self::braking`] (0 when the limits give no deceleration).
    /// How fast (its unit a second, a magnitude) a joint going at `v` goes
    /// [`BRAKE_LOOKAHEAD`] on, and how far it gets meanwhile: faster where
    /// its reports show it speeding up the way it goes (a torque drives
    /// it, or a velocity it is still getting up to), at that acceleration.
    fn lookahead(j: &Joint, m: &motorwire_translate::MappedMotor, v: f64) -> (f64, f64) {
        let t = BRAKE_LOOKAHEAD.as_secs_f64();
        let a = j
            .motion_at
            .map(|(_, a)| m.unit.from_degrees(a))
            .filter(|a| a.is_finite() && a * v > 0.0)
            .map_or(0.0, f64::abs);
        ahead(v.abs(), a, t)
    }

    fn stopping(limits: &Limits, v: f64) -> f64 {
        Self::braking(limits).map_or(0.0, |d| v * v / (2.0 * d))
    }

    /// Devices holding a velocity or torque setpoint that would carry them
    /// past a position limit in force before they could stop (braked at
    /// [`Self::braking`], from where their feedback says they are now and
    /// how fast they go, [`BRAKE_LOOKAHEAD`] ahead): brought to a stop now,
    /// with that deceleration where the device takes one (a moteus
    /// controller's velocity 0 within it; the others their own stop), a
    /// `limit_brake` event each.
    fn keep_within_limits(&mut self, now: Duration) {
        if self.latched {
            return;
        }
        let mut brake = Vec::new();
        for (ji, j) in self.joints.iter().enumerate() {
            let Some((at, limit_name, limit)) = self.brake_due(j) else {
                continue;
            };
            if at > now {
                continue;
            }
            let (Some(f), Some(m)) = (j.feedback.as_ref(), self.map.motor(&j.name)) else {
                continue;
            };
            let decel = Self::braking(&m.limits).map(|d| m.unit.to_degrees(d));
            brake.push((
                ji,
                decel,
                limit_name,
                Event::LimitBrake {
                    motor_id: j.name.clone(),
                    position: f.position,
                    velocity: f.velocity,
                    limit_name,
                    limit,
                },
            ));
        }
        let now_ms = self.unix_ms(now) as u64;
        for (ji, decel, limit_name, event) in brake {
            let Some(j) = self.joints.get_mut(ji) else {
                continue;
            };
            let speed = j.feedback.as_ref().map_or(0.0, |f| f.velocity.abs());
            j.limit_braked = Some(crate::joints::LimitBraked {
                side: limit_name,
                at: now,
                speed,
                sending: true,
            });
            let order = j
                .device
                .limit_brake(decel)
                .or_else(|| j.device.hold_still(now_ms));
            match order {
                Some(order) => self.stop_setpoint(now, ji, order, Some(event)),
                None => {
                    if let Some(j) = self.joints.get_mut(ji) {
                        j.deadman = None;
                        if let Some(b) = j.limit_braked.as_mut() {
                            b.sending = false;
                        }
                    }
                }
            }
        }
    }

    /// When device `j`, holding a velocity or torque setpoint, must be
    /// braked to stop short of a position limit in force, and which limit:
    /// from its last feedback (where it was, how fast it went, when it was
    /// heard), the time it reaches the limit less its stopping distance
    /// ([`Self::braking`]) and [`BRAKE_LOOKAHEAD`]. `None` for a device
    /// holding no setpoint, at rest, or moving away from its limits.
    fn brake_due(&self, j: &Joint) -> Option<(Duration, &'static str, f64)> {
        if j.deadman.is_none() {
            return self.brake_again(j);
        }
        let f = j.feedback.as_ref()?;
        let m = self.map.motor(&j.name)?;
        // As fast as it goes, or as it is told to go where that is faster
        // (its feedback may not show the speed it is getting up to).
        let v = j
            .held_velocity
            .filter(|h| h.is_finite() && h.abs() > f.velocity.abs())
            .unwrap_or(f.velocity);
        let p = f.position;
        if !p.is_finite() || !v.is_finite() || v == 0.0 {
            return None;
        }
        // Speeding up outward (a torque, or a velocity it is still getting
        // up to): as fast as it will go [`BRAKE_LOOKAHEAD`] on at the
        // acceleration its reports show, and as far as it gets by then.
        let (reach_v, travel) = Self::lookahead(j, m, v);
        let stopping = Self::stopping(&m.limits, reach_v);
        let (limit_name, limit, room) = if v > 0.0 {
            let hi = m.limits.max_position?;
            ("max_position", hi, hi - p - stopping - travel)
        } else {
            let lo = m.limits.min_position?;
            ("min_position", lo, p - lo - stopping - travel)
        };
        let heard = j.last_heard.unwrap_or(self.now);
        let in_s = (room / reach_v).clamp(0.0, 3600.0);
        let at = heard.saturating_add(Duration::from_secs_f64(in_s));
        Some((at, limit_name, limit))
    }

    /// A motor braked short of a limit whose reports, [`REBRAKE_AFTER`] on,
    /// show it going on toward that limit as fast as when it was braked:
    /// braked again now (the brake was lost on the bus: a compact device
    /// acknowledges a command with whatever feedback comes next).
    fn brake_again(&self, j: &Joint) -> Option<(Duration, &'static str, f64)> {
        let crate::joints::LimitBraked {
            side, at, speed, ..
        } = j.limit_braked?;
        let f = j.feedback.as_ref()?;
        let m = self.map.motor(&j.name)?;
        let heard = j.last_heard?;
        let (toward, limit) = if side == "max_position" {
            (f.velocity, m.limits.max_position?)
        } else {
            (-f.velocity, m.limits.min_position?)
        };
        (heard >= at.saturating_add(REBRAKE_AFTER) && toward > 0.0 && toward >= 0.9 * speed)
            .then_some((heard, side, limit))
    }

    /// Why a velocity or torque `setpoint` for `motor` is refused: it
    /// points past a position limit in force from where the motor stands,
    /// nearer than it could stop from that speed ([`Self::braking`],
    /// [`BRAKE_LOOKAHEAD`] ahead), or at the limit for a torque.
    fn outward_at_limit(
        &self,
        motor: &str,
        mode: motorwire_core::ControlMode,
        setpoint: f64,
    ) -> Option<ErrorBody> {
        if !matches!(
            mode,
            motorwire_core::ControlMode::Velocity | motorwire_core::ControlMode::Torque
        ) || setpoint == 0.0
        {
            return None;
        }
        let j = self.joints.get(self.joint_index(motor)?)?;
        let f = j.feedback.as_ref()?;
        let m = self.map.motor(motor)?;
        let p = f.position;
        let toward = if setpoint > 0.0 {
            "max_position"
        } else {
            "min_position"
        };
        // Still on its way toward that limit: faster than a 1,000th of its
        // velocity limit (a motor at rest reports noise).
        let still = m
            .limits
            .max_velocity
            .map_or(1e-3, |v| (v.abs() * 1e-3).max(1e-9));
        let reach = if j.limit_braked.is_some_and(|b| b.side == toward)
            && f.velocity * setpoint.signum() > still
        {
            // Braked short of that limit and still on its way to it: no
            // setpoint toward it until it has stopped.
            f64::INFINITY
        } else if mode == motorwire_core::ControlMode::Velocity {
            setpoint.abs() * BRAKE_LOOKAHEAD.as_secs_f64() + Self::stopping(&m.limits, setpoint)
        } else {
            // A torque toward the limit: as far as it would get before a
            // brake could stop it, from its speed toward the limit (none
            // if it goes the other way: the torque turns it), speeding up
            // as fast as a torque has driven it before, and no slower than
            // the limits' acceleration, over two lookaheads (one to its
            // next report, one for the brake to go).
            let t = 2.0 * BRAKE_LOOKAHEAD.as_secs_f64();
            let a = m
                .unit
                .from_degrees(j.peak_accel)
                .abs()
                .max(m.limits.max_acceleration.unwrap_or(0.0));
            let (reach_v, travel) = ahead((f.velocity * setpoint.signum()).max(0.0), a, t);
            travel + Self::stopping(&m.limits, reach_v)
        };
        let (limit_name, limit) = if setpoint > 0.0 {
            (
                "max_position",
                m.limits.max_position.filter(|hi| p + reach >= *hi)?,
            )
        } else {
            (
                "min_position",
                m.limits.min_position.filter(|lo| p - reach <= *lo)?,
            )
        };
        let what = if mode == motorwire_core::ControlMode::Velocity {
            "a velocity"
        } else {
            "a torque"
        };
        Some(
            ErrorBody::refused(
                BridgeRule::OutwardAtLimit,
                format!(
                    "{motor}: at {p}, {what} of {setpoint} toward its {limit_name} ({}) {limit} could not stop before it; command it away from the limit",
                    m.limits_source
                ),
            )
            .about(motor.to_owned()),
        )
    }

    /// Everything the drivers have to tell, acted on in order.
    fn drain_drivers(&mut self) {
        while let Some(h) = self.drivers.poll(&self.map, &self.joints) {
            self.happened(h);
        }
        self.finish_jobs();
    }

    /// What a driver told, acted on the same way for every dialect.
    fn happened(&mut self, h: Happened) {
        match h {
            Happened::Heard { device, at, up } => self.heard(device, at, up),
            Happened::Reading {
                device,
                at,
                motion,
                feedback,
            } => self.reading(device, at, motion, feedback.map(|f| *f)),
            Happened::Ended { device, ended } => self.step_done(device, ended),
            Happened::Lifecycle {
                device,
                state,
                code,
            } => self.lifecycle(device, state, code),
            Happened::StoppedItself {
                device,
                at,
                reason,
                code,
            } => {
                let Some(name) = self.joints.get(device).map(|j| j.name.clone()) else {
                    return;
                };
                self.joint_lost(
                    device,
                    format!("stopped itself ({reason})"),
                    Event::JointFault {
                        motor_id: name.clone(),
                        code,
                        reason: Some(reason.clone()),
                    },
                );
                // A joint's own emergency stop stops every joint: the arm is
                // not safe to move with one of them down.
                self.emergency_stop(at, None, Vec::new(), format!("{name}: {reason}"));
            }
            Happened::Answer { device, answer } => self.answered(device, answer),
            Happened::Bad { report } => {
                self.stats.bad_frames += 1;
                if let Some(e) = report {
                    self.out.push_back(Output::Event(e));
                }
            }
            Happened::Event(e) => self.out.push_back(Output::Event(e)),
            Happened::LinkLost {
                devices,
                offline,
                arrival,
            } => self.link_lost(&devices, &offline, &arrival),
            Happened::MayGo { devices } => {
                for ji in devices {
                    self.pump(ji);
                }
                self.finish_jobs();
            }
        }
    }

    /// The link to `devices` is lost: they are offline (`why`), no
    /// deadman watches them, and lines waiting on them will not arrive
    /// (`arrival`); what waits for them is not sent.
    fn link_lost(&mut self, devices: &[usize], why: &str, arrival: &str) {
        for &ji in devices {
            if let Some(j) = self.joints.get_mut(ji) {
                j.deadman = None;
                if j.online {
                    j.online = false;
                    self.out.push_back(Output::Event(Event::Offline {
                        motor_id: j.name.clone(),
                        node: j.node,
                        reason: why.to_owned(),
                    }));
                }
            }
        }
        self.fail_watches(|w| devices.iter().any(|&ji| w.waits_on(ji)), arrival);
        for &ji in devices {
            self.pump(ji);
        }
        self.finish_jobs();
        // Starting, a device lost is no longer waited for.
        self.try_ready();
    }

    /// Device `ji` (any dialect) reported at `at`: its position and
    /// velocity (degrees) where the report has them, and its WIA feedback.
    /// Lines that have now arrived are said so, sequential axes waiting
    /// on it may go, and a move whose outcome was unknown is said
    /// executed once the device stands at its target.
    fn reading(
        &mut self,
        ji: usize,
        at: Duration,
        motion: Option<(f64, f64)>,
        feedback: Option<MotorFeedback>,
    ) {
        let Some(j) = self.joints.get_mut(ji) else {
            return;
        };
        if feedback.is_some() {
            j.feedback = feedback;
            self.confirm_stop(ji, at);
        }
        let Some(j) = self.joints.get_mut(ji) else {
            return;
        };
        let Some((pos, vel)) = motion else {
            return;
        };
        // Its acceleration, from this report and the one before.
        let acceleration = match (j.motion, j.motion_at) {
            (Some((_, v0)), Some((t0, _))) if at > t0 && at - t0 <= Duration::from_millis(100) => {
                (vel - v0) / (at - t0).as_secs_f64()
            }
            _ => 0.0,
        };
        // Its first reading may make the bridge ready; a later one cannot
        // (nor can any other device's reading but its first): what ready
        // waits for is looked at then, not on every report of every device.
        let first = j.motion.is_none();
        // How fast a torque speeds it up: only while it holds a torque
        // setpoint, and only speeding up the way it goes (a stop, a fault
        // or a brake slows it down; a velocity setpoint ramps within the
        // limits).
        if j.deadman.is_some()
            && j.held_velocity.is_none()
            && acceleration.is_finite()
            && acceleration * vel > 0.0
        {
            j.peak_accel = j.peak_accel.max(acceleration.abs());
        }
        j.set_motion((pos, vel), at, acceleration);
        j.check_model(at, pos, vel);
        self.moved(ji, pos, vel, at);
        if first {
            self.try_ready();
        }
        let Some(j) = self.joints.get_mut(ji) else {
            return;
        };
        // A part whose outcome was unknown, shown executed by the device's position.
        if let Some(u) = j.unresolved
            && (pos - u.target).abs() < 0.5
            && vel.abs() < 1.0
        {
            j.unresolved = None;
            let position = self
                .map
                .motor(&j.name)
                .map_or(pos, |m| m.unit.from_degrees(pos));
            self.out.push_back(Output::Event(Event::Outcome {
                origin: u.origin,
                line: u.line,
                motor_id: j.name.clone(),
                outcome: "executed",
                position: shortest(position),
            }));
        }
    }

    /// A stop taken on an acknowledgement that may have been another
    /// frame's (a compact device's: [`Order::unconfirmed_stop`]), judged by
    /// the feedback heard `at`, [`REBRAKE_AFTER`] after it was taken and
    /// for [`CONFIRM_STOP_FOR`]: still enabled after a disable or an
    /// emergency stop (seen disabled, it is confirmed), or going at least as
    /// fast as when it was taken (or, taken at rest, moving) after a
    /// velocity 0, it
    /// was lost on the bus and is sent again with this time's timestamp,
    /// unless a newer step waits for the device; while the emergency stop
    /// is latched only an emergency stop is. Sent [`MAX_STOP_RESENDS`]
    /// times and still contradicted: when in doubt, stop (the emergency
    /// stop). (A velocity 0 lost on a device held still by a torque against
    /// something shows nothing to judge by: the deadman is what stops it.)
    fn confirm_stop(&mut self, ji: usize, at: Duration) {
        // (Every feedback comes here: nothing is looked up for a device
        // with no stop to judge.)
        if self
            .joints
            .get(ji)
            .is_none_or(|j| j.unconfirmed_stop.is_none())
        {
            return;
        }
        let latched = self.latched;
        let still = self
            .joints
            .get(ji)
            .and_then(|j| self.map.motor(&j.name))
            .and_then(|m| m.limits.max_velocity)
            .map_or(1e-3, |v| (v.abs() * 1e-3).max(1e-9));
        let Some(j) = self.joints.get_mut(ji) else {
            return;
        };
        let (Some((order, acked, speed)), Some(f)) = (j.unconfirmed_stop, j.feedback.as_ref())
        else {
            return;
        };
        let Some(disables) = order.unconfirmed_stop() else {
            return;
        };
        let emergency = order.is_emergency_stop();
        let lost = if disables {
            if f.status.enabled == Some(false) && at >= acked {
                j.unconfirmed_stop = None;
                j.stop_resends = 0;
                return;
            }
            f.status.enabled == Some(true)
        } else {
            // Not slowing at all (a device braking, however gently, is
            // slower 50 ms on), or moving where it was taken at rest.
            f.velocity.abs() > (0.99 * speed).max(still)
        };
        if (latched && !emergency) || at > acked.saturating_add(CONFIRM_STOP_FOR) {
            j.unconfirmed_stop = None;
            j.stop_resends = 0;
            return;
        }
        if !lost
            || at < acked.saturating_add(REBRAKE_AFTER)
            || j.busy.is_some()
            || !j.queue.is_empty()
        {
            return;
        }
        j.unconfirmed_stop = None;
        let seen = if disables {
            "shown enabled by its feedback"
        } else {
            "shown moving by its feedback"
        };
        self.stop_again(ji, order, at.max(self.now), seen);
    }

    /// The bridge's own stop of one device (the deadman's, a limit brake,
    /// a stop sent again), as a job of no line.
    fn own_stop(&mut self, now: Duration, axis: Axis) {
        self.open_job(
            None,
            JobKind::Deadman,
            now,
            vec![axis],
            Report::default(),
            Vec::new(),
        );
    }

    /// A stop of device `ji` that its device was not seen to take (`why`:
    /// not answered, or contradicted by its feedback) sent again, with
    /// `now`'s timestamp; the [`MAX_STOP_RESENDS`]-th time, when in doubt,
    /// the emergency stop instead (latched already: nothing more).
    fn stop_again(&mut self, ji: usize, order: Order, now: Duration, why: &str) {
        let now_ms = self.unix_ms(now) as u64;
        let latched = self.latched;
        let Some(j) = self.joints.get_mut(ji) else {
            return;
        };
        if latched && !order.is_emergency_stop() {
            return;
        }
        if j.stop_resends >= MAX_STOP_RESENDS {
            j.stop_resends = 0;
            if !latched {
                let cause = format!(
                    "{}: its stop was sent {} times and not taken ({why})",
                    j.name,
                    MAX_STOP_RESENDS + 1
                );
                self.emergency_stop(now, None, Vec::new(), cause);
            }
            return;
        }
        j.stop_resends += 1;
        self.stats.stops_sent_again += 1;
        let axis = Axis::of(j.name.clone(), ji, [order.restamped(now_ms)]);
        self.own_stop(now, axis);
    }

    /// Joint `ji` reported its lifecycle `state` (with `code`, its error
    /// code): it is active or not; a fault, or a reboot the bridge did not
    /// ask for, loses it until a reset.
    fn lifecycle(&mut self, ji: usize, state: LifecycleState, code: u16) {
        let Some(j) = self.joints.get_mut(ji) else {
            return;
        };
        let before = j.state;
        j.state = Some(state);
        j.active = state == LifecycleState::Active;
        if state == LifecycleState::Error {
            let event = Event::JointFault {
                motor_id: j.name.clone(),
                code,
                reason: None,
            };
            self.joint_lost(ji, format!("faulted (error code {code})"), event);
        } else if state == LifecycleState::Unconfigured
            && !j.resetting
            && matches!(
                before,
                Some(LifecycleState::Active | LifecycleState::Inactive)
            )
        {
            let event = Event::Rebooted {
                motor_id: j.name.clone(),
            };
            self.joint_lost(ji, "rebooted".to_owned(), event);
        }
    }

    /// Device `ji` was heard from at `at`; online, if it was not, when
    /// its link is `up`.
    fn heard(&mut self, ji: usize, at: Duration, up: bool) {
        if let Some(j) = self.joints.get_mut(ji) {
            j.last_heard = Some(at.max(j.last_heard.unwrap_or(Duration::ZERO)));
            if up && !j.online {
                j.online = true;
                self.out.push_back(Output::Event(Event::Online {
                    motor_id: j.name.clone(),
                    node: j.node,
                }));
            }
        }
    }

    // ---- time -----------------------------------------------------------

    /// Advances to `now`: retransmissions and timeouts, feedback, liveness,
    /// heartbeats, the end of a drain.
    pub fn handle_timeout(&mut self, now: Duration) {
        self.changed();
        self.now = self.now.max(now);
        let now = self.now;
        self.withdraw_stale_resends(now);
        self.drivers.handle_timeout(now);
        self.drain_drivers();
        self.try_ready();
        self.drivers.command_timeouts(now);
        self.drain_drivers();
        // The deadman's stops (and the limits' brakes) are queued before
        // the Orion link picks what to send next.
        self.keep_within_limits(now);
        self.deadman(now);
        self.link_timeouts(now);
        self.awaiting_timeouts(now);
        // Trajectory segments now due.
        let due = self.joints_where(|j| j.wake.is_some_and(|w| now >= w));
        for ji in due {
            let Some(j) = self.joints.get_mut(ji) else {
                continue;
            };
            j.wake = None;
            let node = j.node;
            if let Some(step) = j.busy.take()
                && !self.send_step(now, ji, node, step)
            {
                self.pump(ji);
            }
        }
        self.finish_jobs();
        // Sequential axes whose predecessor is overdue give up.
        for ji in 0..self.joints.len() {
            self.pump(ji);
        }
        self.finish_jobs();
        // Watched lines past their time: not arrived.
        let late: Vec<usize> = self
            .arrivals
            .iter()
            .enumerate()
            .filter(|(_, w)| now >= w.deadline)
            .map(|(i, _)| i)
            .collect();
        for i in late.into_iter().rev() {
            let w = self.arrivals.remove(i);
            let far = w
                .axes
                .iter()
                .filter(|a| a.arrived.is_none())
                .map(|a| match a.last_error {
                    Some(e) => format!("{} {} away", a.motor, short_unit(a.unit.from_degrees(e))),
                    None => format!("{} never reported its position", a.motor),
                })
                .collect::<Vec<_>>()
                .join(", ");
            let origin = w.line.origin;
            let arrival = w.verdict(now, Some(format!("timed out: {far}")));
            self.out.push_back(Output::Arrival { origin, arrival });
        }
        let offline_after = self.config.offline_after;
        let mut went_offline = Vec::new();
        for (ji, j) in self.joints.iter_mut().enumerate() {
            let since = j.last_heard.unwrap_or(Duration::ZERO);
            let silent = now.saturating_sub(since);
            if j.online && silent >= offline_after {
                went_offline.push(ji);
                j.online = false;
                self.out.push_back(Output::Event(Event::Offline {
                    motor_id: j.name.clone(),
                    node: j.node,
                    reason: format!("nothing heard for {} ms", silent.as_millis()),
                }));
            }
        }
        for ji in went_offline {
            self.fail_watches(|w| w.waits_on(ji), "the joint went offline");
            // What waits for it is not held to run once it is heard again.
            let name = self
                .joints
                .get(ji)
                .map(|j| j.name.clone())
                .unwrap_or_default();
            self.cancel_where(
                &format!("cancelled: {name} went offline before it was sent"),
                |job| {
                    job.kind == JobKind::Command
                        && job
                            .axes
                            .iter()
                            .any(|a| a.joint == ji && a.state == AxisState::Queued)
                },
            );
        }
        if let (Some(period), Some(at)) = (self.config.feedback_period, self.timers.feedback)
            && now >= at
        {
            self.emit_feedback(now);
            self.timers.feedback = Some(now.saturating_add(period));
        }
        if self.any_moving(now) {
            // Due again a period on, whether a beat could be queued or not
            // (none on a bus without iRPC joints): never due at the time
            // it was handled, so nothing waiting for it spins.
            if self.timers.heartbeat.is_none_or(|t| now >= t) {
                let _ = self.drivers.heartbeat();
                self.timers.heartbeat = Some(now.saturating_add(self.config.heartbeat_period));
            }
        } else {
            self.timers.heartbeat = None;
        }
        if let Phase::Draining { deadline } = self.phase {
            self.drain_recheck = false;
            let idle = self.jobs.is_empty() && self.waiting.is_empty() && !self.any_moving(now);
            if idle || now >= deadline {
                self.enter(Phase::Stopping);
            }
        }
    }

    fn any_moving(&self, now: Duration) -> bool {
        self.joints.iter().any(|j| j.moving_until > now)
    }

    fn emit_feedback(&mut self, now: Duration) {
        let ts = self.unix_ms(now);
        for j in &self.joints {
            // Degrees: how close counts as there, and how slow as at rest.
            let tolerance = self
                .map
                .motor(&j.name)
                .map_or(0.1, |m| m.unit.to_degrees(m.arrival_tolerance));
            let fb = j.feedback.clone().map(|mut f| {
                f.timestamp = ts;
                if !j.online {
                    f.status.fault = Some(true);
                }
                if let Some((pos, vel)) = j.motion {
                    f.status.in_motion = Some(vel.abs() > tolerance * 10.0);
                    if let Some(target) = j.target {
                        f.status.at_target = Some((pos - target).abs() <= tolerance);
                    }
                }
                shortest_feedback(f)
            });
            if fb.is_none() && j.online {
                continue; // nothing heard yet, and not yet overdue
            }
            self.stats.feedback_lines += 1;
            self.out.push_back(Output::Feedback(Box::new(FeedbackLine {
                feedback: fb,
                motor_id: j.name.clone(),
                online: j.online,
            })));
        }
    }

    /// Whole Unix milliseconds (or milliseconds since start without a wall clock).
    fn unix_ms(&self, now: Duration) -> f64 {
        crate::device::unix_ms(self.config.epoch_unix_ms.unwrap_or(0.0), now)
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
    pub fn flushed(&mut self, now: Duration) {
        self.changed();
        self.now = self.now.max(now);
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

    /// When [`Bridge::handle_timeout`] next has work.
    pub fn poll_timeout(&self) -> Option<Duration> {
        if let Some(next) = self.next_deadline.get() {
            debug_assert_eq!(
                next,
                self.next_deadline_now(),
                "the next deadline changed without an entry point clearing it"
            );
            return next;
        }
        let next = self.next_deadline_now();
        self.next_deadline.set(Some(next));
        next
    }

    /// [`Bridge::poll_timeout`], computed: the earliest deadline of the
    /// timer table.
    fn next_deadline_now(&self) -> Option<Duration> {
        if self.phase == Phase::Finished {
            return None;
        }
        Timer::ALL
            .into_iter()
            .filter_map(|t| self.deadline(t))
            .min()
    }

    /// The bridge is about to change: its next deadline is computed again.
    fn changed(&mut self) {
        self.next_deadline.set(None);
    }

    /// When timer `t` is next due, if it is set: the timer table, one
    /// entry per kind of deadline, each read where its state lives.
    fn deadline(&self, t: Timer) -> Option<Duration> {
        match t {
            Timer::Drivers => self.drivers.deadline(),
            Timer::Feedback => self.timers.feedback,
            Timer::Liveness => self
                .joints
                .iter()
                .filter(|j| j.online)
                .map(|j| {
                    j.last_heard
                        .unwrap_or(Duration::ZERO)
                        .saturating_add(self.config.offline_after)
                })
                .min(),
            // Only where a joint hears the beat (iRPC).
            Timer::Heartbeat => (self.drivers.beats() && self.any_moving(self.now))
                .then(|| self.timers.heartbeat.unwrap_or(self.now).max(self.now)),
            // Due when the drain may end: once motion has ended, at once
            // when nothing is left (or a line just finished: looked at
            // once); while a line waits for its device, the device's own
            // answer or time-out finishes it, and the deadline bounds it.
            // Never due again at the time it was handled: a runner
            // waiting for it does not spin.
            Timer::Drain => match self.phase {
                Phase::Draining { deadline } => {
                    let motion_ends = self.joints.iter().map(|j| j.moving_until).max();
                    Some(if self.drain_recheck {
                        self.now
                    } else if let Some(end) = motion_ends.filter(|e| *e > self.now) {
                        end.min(deadline)
                    } else if !self.jobs.is_empty() || !self.waiting.is_empty() {
                        deadline
                    } else {
                        self.now
                    })
                }
                _ => None,
            },
            Timer::Arrival => self.arrivals.iter().map(|w| w.deadline).min(),
            // Due only where pumping would act on it: a sequential axis at
            // the front of an idle device's queue, waiting for an axis that
            // has not arrived (behind a busy device, the device's answer
            // pumps it; a deadline there would be due and do nothing).
            Timer::Sequence => self
                .joints
                .iter()
                .filter(|j| j.busy.is_none())
                .filter_map(|j| j.queue.front())
                .filter_map(|s| {
                    let job = self.jobs.get(&s.job)?;
                    let a = job.axes.get(s.axis).filter(|a| !a.is_done())?;
                    let b = job.axes.get(a.after?)?;
                    if b.arrived { None } else { b.arrive_by }
                })
                .min(),
            Timer::Deadman => self.joints.iter().filter_map(|j| j.deadman).min(),
            Timer::LimitBrake => {
                if self.latched {
                    None
                } else {
                    self.joints
                        .iter()
                        .filter_map(|j| self.brake_due(j).map(|(at, ..)| at.max(self.now)))
                        .min()
                }
            }
            Timer::Segment => self.joints.iter().filter_map(|j| j.wake).min(),
            Timer::Answer => self
                .jobs
                .values()
                .filter_map(|j| j.awaiting.map(|a| a.deadline))
                .min(),
            Timer::Settle => self.settle_until.filter(|_| self.phase == Phase::Starting),
        }
    }
}

/// A joint's move as the bridge planned it: where it started, what it was
/// told, how long it takes, and its profile.
type Plan = (
    (
        crate::joints::Kinematics,
        motorwire_irpc::SetTargetPayloadV2,
        Duration,
    ),
    // Boxed where it is made: a profile is some 300 bytes, and a plan is
    // moved several times on its way to the joint.
    Box<motorwire_planner::Profile<f64>>,
);

/// A move's whole planned path, from where `joint` is `now`, how fast it
/// moves and how that changes (as the joint will plan it), stays within
/// the limits `limits` gated the command against (issue: a joint moving
/// fast toward a limit overshoots a target inside it); its plan, which
/// the bridge keeps. Without a report yet there is nothing to plan from:
/// the joint's own check stands.
fn planned_within_limits(
    joint: Option<&Joint>,
    now: Duration,
    motor: &motorwire_translate::MappedMotor,
    limits: &motorwire_translate::Effective,
    payloads: &[Payload],
) -> Result<Option<Plan>, motorwire_translate::Refusal> {
    // Where it is now (reckoned from its reports, or read from the move
    // it makes as the bridge planned it).
    let Some(from) = joint.and_then(|j| j.state_at(now)) else {
        return Ok(None);
    };
    let mut planned = None;
    for p in payloads {
        if let Payload::SetTargetV2(p) = p {
            let start = crate::joints::in_unit(motor.unit, from);
            let path = motorwire_translate::check_path_from(motor, limits, p, start)?;
            planned = Duration::try_from_secs_f64(path.duration)
                .ok()
                .map(|d| ((from, *p, d), Box::new(path.profile)));
        }
    }
    Ok(planned)
}

/// What a newer motion step takes over on its device when it is queued
/// (`Bridge::supersede`): `replaces`, a position move or a stream's
/// setpoint; `timed`, a trajectory's step.
#[derive(Debug, Clone, Copy)]
struct Takes {
    replaces: bool,
    timed: bool,
}

/// The error of a job whose parts did not all succeed: the gravest first
/// (an unknown outcome, then a refusal, then what was never sent).
/// `cut`: why a stop (or the end, a reset, a lost joint) cancelled the
/// line: its kind is then `cancelled`, and a part in flight when that came
/// is `outcome_unknown` in `outcomes`.
fn failure_error(failures: &[StepReport], cut: Option<&str>) -> ErrorBody {
    if let Some(why) = cut {
        let mut e = ErrorBody::new(
            ErrorKind::Cancelled,
            if failures
                .iter()
                .any(|f| f.outcome == StepOutcome::OutcomeUnknown)
            {
                format!(
                    "{why}: a part was sent before and not answered, so it may have started; nothing of it is sent again"
                )
            } else {
                format!("{why}; nothing of it is sent")
            },
        );
        if let [only] = failures {
            e.motor = Some(only.motor.clone());
        }
        return e;
    }
    let rank = |o: StepOutcome| match o {
        StepOutcome::OutcomeUnknown => 0,
        StepOutcome::Nacked => 1,
        StepOutcome::Cancelled => 2,
        StepOutcome::Superseded => 3,
        StepOutcome::NotSent => 4,
        StepOutcome::Acked => 5,
    };
    let worst = failures.iter().min_by_key(|f| rank(f.outcome));
    let (kind, message) = match worst.map(|f| f.outcome) {
        Some(StepOutcome::OutcomeUnknown) => (
            ErrorKind::OutcomeUnknown,
            "a joint never answered: it may or may not have executed the command",
        ),
        Some(StepOutcome::Nacked) => (ErrorKind::Nacked, "a joint refused the command"),
        Some(StepOutcome::Cancelled) => (
            ErrorKind::Cancelled,
            "cancelled by an emergency stop or the end; nothing of it runs after the stop",
        ),
        // What replaced it, as its step says (a newer move, a stream's
        // setpoint, a motor line).
        Some(StepOutcome::Superseded) => (
            ErrorKind::Superseded,
            worst.map_or(
                "a newer command for the motor replaced it before it was sent",
                |f| f.message.as_ref(),
            ),
        ),
        _ => (ErrorKind::NotSent, "not every part could be sent"),
    };
    let mut e = ErrorBody::new(kind, message.to_owned());
    if let [only] = failures {
        e.motor = Some(only.motor.clone());
    }
    e
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
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    /// After handle_timeout at the time poll_timeout gave, no timer is
    /// due at that time again: a runner waiting for poll_timeout never
    /// spins. Here at the end of input, with a request waiting for its
    /// Ack and nothing moving.
    #[test]
    fn no_timer_is_due_again_once_handled() {
        let map = BusMap::from_toml(
            "[motors.elbow]\ndialect = \"irpc\"\nnode = 0x12\n\
             limits = { max_velocity = 120, max_acceleration = 500 }",
        )
        .unwrap();
        let config = BridgeConfig {
            activate_on_start: false,
            ..BridgeConfig::default()
        };
        let mut b = Bridge::new(map, config).unwrap();
        let ms = Duration::from_millis;
        b.start(Duration::ZERO);
        b.handle_line(
            ms(1),
            Origin(0),
            r#"{"motor_id":"elbow","timestamp":0,"control_mode":"position","setpoint":10}"#,
        );
        while b.poll_transmit().is_some() {}
        b.flushed(ms(1));
        b.finish(ms(2));
        let mut now = ms(2);
        for _ in 0..500 {
            let Some(t) = b.poll_timeout() else { break };
            now = now.max(t);
            b.handle_timeout(now);
            while b.poll_transmit().is_some() {}
            b.flushed(now);
            let due: Vec<Timer> = Timer::ALL
                .into_iter()
                .filter(|t| b.deadline(*t).is_some_and(|d| d <= now))
                .collect();
            assert_eq!(due, [], "at {now:?}");
        }
        // The request timed out (4 sendings, 100 ms each), its line was
        // answered, and the drain ended then, not at its 30 s deadline.
        assert!(b.is_finished(), "{now:?}");
        assert!(now < ms(1000), "{now:?}");
        let r = std::iter::from_fn(|| b.poll_output())
            .find_map(|o| o.result().cloned())
            .unwrap();
        assert_eq!(r.error.unwrap().kind, ErrorKind::OutcomeUnknown);
    }

    /// A joint's frame to the bridge, in v2.2.
    fn from_joint(node: u16, msg_id: u32, payload: Payload) -> Frame {
        crate::device::irpc::joint_frame(node, msg_id, payload, motorwire_irpc::WireVersion::V2_2)
    }

    /// A stop line that comes while a stop the bridge made itself (a
    /// joint's own emergency stop) is under way rides on it and is
    /// answered when that stop ends: every line gets exactly one result,
    /// whoever started the stop. (Before, such a rider was never answered.)
    #[test]
    fn a_stop_line_riding_on_a_stop_the_bridge_made_is_answered() {
        use motorwire_irpc::{EmergencyReason, EmergencyStop, Message, WireVersion};
        let map = BusMap::from_toml(
            "[motors.elbow]\ndialect = \"irpc\"\nnode = 0x12\nwire = \"v2.2\"\n\
             limits = { max_velocity = 120, max_acceleration = 500 }",
        )
        .unwrap();
        let config = BridgeConfig {
            activate_on_start: false,
            ..BridgeConfig::default()
        };
        let mut b = Bridge::new(map, config).unwrap();
        let ms = Duration::from_millis;
        b.start(Duration::ZERO);
        let stop = EmergencyStop {
            reason: EmergencyReason::Overtemperature,
            vbus_mv: 24_000,
            current_ma: 0,
            temp_c: 90.0,
            timestamp_ms: 1,
        };
        b.handle_frame(ms(1), &from_joint(0x12, 9, Payload::EmergencyStop(stop)));
        assert!(b.is_latched());
        let deactivate =
            Message::decode_frame(WireVersion::V2_2, b.poll_transmit().unwrap().data()).unwrap();
        assert_eq!(deactivate.payload, Payload::Deactivate);
        b.flushed(ms(1));
        // A client's stop while the joint's is under way: it rides on it.
        b.handle_line(ms(2), Origin(7), r#"{"emergency_stop":true}"#);
        assert_eq!(b.stats().stops_coalesced, 1);
        assert!(b.poll_transmit().is_none(), "no second Deactivate");
        let id = deactivate.header.msg_id;
        b.handle_frame(ms(3), &from_joint(0x12, id, Payload::Ack(id)));
        let results: Vec<LineResult> = std::iter::from_fn(|| b.poll_output())
            .filter_map(|o| o.result().cloned())
            .collect();
        assert_eq!(results.len(), 1, "{results:?}");
        assert_eq!(
            (results[0].line, results[0].ok, results[0].emergency_stop),
            (1, true, true)
        );
        assert_eq!(results[0].acked.as_deref(), Some(&["elbow".to_owned()][..]));
    }
}
