//! The bridge on simulated joints: in real time ([`RealTimeArm`], what
//! `motorwire bridge --bus sim` runs) or stepped in simulated time
//! ([`SimulatedArm`], exact and as fast as the machine, for tests and
//! benchmarks).

use std::collections::{BTreeSet, HashMap};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::{self, JoinHandle};
use std::time::{Duration, Instant};

use motorwire_can::{CanBus, Clock, Frame, SimBus, SimConfig, SimPort};
use motorwire_sim::moteus::{MoteusConfig, SimMoteus};
use motorwire_sim::{
    CompactDeviceConfig, CompactDeviceLimits, JointConfig, SimCompactDevice, SimError, SimJoint,
};
use motorwire_translate::{BusMap, MappedMotor, Target};

use crate::engine::Bridge;
use crate::error::BridgeError;
use crate::output::{Origin, Output};

mod servos;

use servos::{SimServoPort, servo_buses};
pub use servos::{servo_links, servo_links_with};

/// Rounds of work at one simulated instant, at most: each answers what
/// the round before it sent (a frame and its answer, a line and its
/// frames), so a chain this long is a timer that stays due once handled.
const MAX_ROUNDS_AT_ONCE: u32 = 10_000;

/// Frames a [`RealTimeArm`]'s devices take from the bus before they look
/// at their timers again, at most.
const MAX_FRAMES_AT_ONCE: usize = 256;

/// A joint for `motor` if it is an iRPC joint: the map's wire version, its
/// `emergency_deceleration` (the joint's own default otherwise), and a
/// start at 0° or, when 0 is outside the map's range, its nearest end.
pub fn joint_config(motor: &MappedMotor) -> Option<JointConfig> {
    let Target::Irpc { node, wire } = motor.target else {
        return None;
    };
    let mut config = JointConfig::new(node);
    config.wire = wire;
    let lo = motor
        .limits
        .min_position
        .map_or(f64::MIN, |p| motor.unit.to_degrees(p));
    let hi = motor
        .limits
        .max_position
        .map_or(f64::MAX, |p| motor.unit.to_degrees(p));
    #[allow(clippy::cast_possible_truncation)]
    let start = 0.0f64.max(lo).min(hi) as f32;
    config.initial_position = start;
    if let Some(d) = motor.limits.emergency_deceleration {
        #[allow(clippy::cast_possible_truncation)]
        let d = motor.unit.to_degrees(d) as f32;
        config.emergency_deceleration = d;
    }
    Some(config)
}

/// A simulated compact device for `motor` if the map gives it the compact
/// dialect: its CAN ids, and the map's limits as its own (in the motor's
/// unit), starting at 0 or the nearest end of its range.
pub fn compact_config(motor: &MappedMotor) -> Option<CompactDeviceConfig> {
    let Target::Compact {
        node,
        feedback_node,
    } = motor.target
    else {
        return None;
    };
    let mut config = CompactDeviceConfig::new(node, &motor.name);
    config.feedback_node = feedback_node;
    let d = CompactDeviceLimits::default();
    let l = motor.limits;
    #[allow(clippy::cast_possible_truncation)]
    let f = |v: Option<f64>, default: f32| v.map_or(default, |v| v as f32);
    config.limits = CompactDeviceLimits {
        min_position: f(l.min_position, d.min_position),
        max_position: f(l.max_position, d.max_position),
        max_velocity: f(l.max_velocity, d.max_velocity),
        max_acceleration: f(l.max_acceleration, d.max_acceleration),
        max_torque: f(l.max_torque, d.max_torque),
    };
    config.initial_position = 0.0f32
        .max(config.limits.min_position)
        .min(config.limits.max_position);
    Some(config)
}

/// A simulated moteus controller for `motor` if the map gives it the
/// moteus dialect: its id and prefix, the map's position range as its
/// position bounds and its velocity, acceleration and torque limits as its
/// defaults (in revolutions), starting at 0 or the nearest bound.
pub fn moteus_config(motor: &MappedMotor) -> Option<MoteusConfig> {
    let Target::Moteus { id, bus, .. } = motor.target else {
        return None;
    };
    let mut config = MoteusConfig::new(id);
    config.prefix = bus;
    let rev = |v: f64| motorwire_translate::revolutions(motor.unit, v);
    let l = motor.limits;
    if let Some(lo) = l.min_position {
        config.position_min = rev(lo);
    }
    if let Some(hi) = l.max_position {
        config.position_max = rev(hi);
    }
    if config.position_min >= config.position_max {
        config.position_max = config.position_min + 1.0;
    }
    if let Some(v) = l.max_velocity {
        config.default_velocity_limit = rev(v);
    }
    if let Some(a) = l.max_acceleration {
        config.default_accel_limit = rev(a);
    }
    if let Some(t) = l.max_torque {
        config.max_torque = t;
    }
    config.initial_position = 0.0f64.max(config.position_min).min(config.position_max);
    Some(config)
}

/// Told of every request a simulated joint executes: its name, its node id and the execution.
pub type ExecutionLog = Arc<dyn Fn(&str, u16, &motorwire_sim::Execution) + Send + Sync>;

/// The map's simulated devices (iRPC joints, compact devices, moteus
/// controllers) on an in-memory bus in real time, until dropped: all on
/// one thread and one connection to the bus, so that a map of many
/// devices costs one thread and one queue, not one of each per device
/// with every frame copied to all of them.
#[derive(Debug)]
pub struct RealTimeArm {
    bus: SimBus,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl RealTimeArm {
    /// Starts a simulated device for every iRPC joint, compact device and
    /// moteus controller of `map`.
    ///
    /// # Errors
    /// [`SimError::InvalidConfig`] for a device the simulator cannot be
    /// (a start outside its own ±180° range).
    pub fn start(map: &BusMap) -> Result<Self, SimError> {
        Self::start_with(map, SimConfig::default(), None)
    }

    /// Starts the devices on a bus made hostile by `config`'s seeded faults
    /// (its clock is made real; the faults fall on the devices' one
    /// connection, so each frame to a device meets them once).
    /// `on_execution`, when given, is told of every request a joint acts on
    /// for the first time (the joint's name and the execution), from the
    /// devices' thread.
    ///
    /// # Errors
    /// As [`RealTimeArm::start`]; the bus's refusal of a fault rate outside 0..=1.
    pub fn start_with(
        map: &BusMap,
        config: SimConfig,
        on_execution: Option<ExecutionLog>,
    ) -> Result<Self, SimError> {
        let bus = SimBus::new(SimConfig {
            clock: Clock::Real,
            ..config
        })
        .map_err(SimError::from)?;
        let hub = Hub::of(map, on_execution)?;
        let stop = Arc::new(AtomicBool::new(false));
        let mut port = bus.port();
        let thread = {
            let stop = Arc::clone(&stop);
            thread::Builder::new()
                .name("mw-sim-devices".to_owned())
                .spawn(move || {
                    let _ = hub.run(&mut port, &stop);
                })
                .map_err(|e| SimError::Thread(e.to_string()))?
        };
        Ok(Self {
            bus,
            stop,
            thread: Some(thread),
        })
    }

    /// A new port on the arm's bus that sends and never receives
    /// ([`SimBus::send_only_port`]): the bridge's sending half. Nothing is
    /// queued for it, where a second [`RealTimeArm::port`] that is never
    /// read would keep every joint frame (about 60 KB/s with three joints).
    pub fn sender(&self) -> SimPort {
        self.bus.send_only_port()
    }

    /// The bridge's two halves on the arm's bus, (sending, receiving): the
    /// receiving half hears the devices but not the bridge's own frames
    /// ([`SimPort::sending_half`]), as a SocketCAN socket and its clone do.
    /// What [`RealTimeArm::spawn`] runs the bridge on.
    pub fn ports(&self) -> (SimPort, SimPort) {
        let rx = self.bus.port();
        (rx.sending_half(), rx)
    }

    /// A new port on the arm's bus that receives every frame sent after it
    /// was made, until dropped: the bridge's receiving half (its sending
    /// half is [`RealTimeArm::sender`]).
    pub fn port(&self) -> SimPort {
        self.bus.port()
    }

    /// Runs `bridge` on this arm's bus with `runner`, on a thread of its
    /// own; `sink` is given every output. Feed it with `runner.input()`
    /// (taken before) and end it with [`crate::InputSender::finish`] or
    /// [`crate::InputSender::interrupt`].
    ///
    /// ```
    /// use motorwire_bridge::sim::RealTimeArm;
    /// use motorwire_bridge::{Bridge, BridgeConfig, Output, Runner};
    /// use motorwire_translate::BusMap;
    /// let map = BusMap::from_toml(
    ///     r#"
    ///     [motors.elbow]
    ///     dialect = "irpc"
    ///     node = 0x12
    ///     wire = "v2.0"
    ///     profile = "scurve"
    ///     limits = { min_position = 0, max_position = 150, max_velocity = 120, max_acceleration = 500, max_jerk = 2000 }
    ///     "#,
    /// )?;
    /// let bridge = Bridge::new(map, BridgeConfig::default())?;
    /// let arm = RealTimeArm::start(bridge.map())?;
    /// let runner = Runner::new();
    /// let input = runner.input();
    /// let handle = arm.spawn(runner, bridge, |o: &Output| println!("{}", o.to_json()));
    /// input.finish();
    /// let bridge = handle.join().expect("the runner thread")?;
    /// assert!(bridge.is_finished());
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn spawn(
        &self,
        runner: crate::runtime::Runner,
        bridge: Bridge,
        mut sink: impl FnMut(&Output) + Send + 'static,
    ) -> JoinHandle<Result<Bridge, BridgeError>> {
        let (tx, rx) = self.ports();
        thread::spawn(move || runner.run(bridge, tx, rx, |o| sink(o)))
    }

    /// [`RealTimeArm::spawn`] with [`crate::Runner::run_rendered`]: `sink`
    /// is given each output with its JSON line, rendered once.
    pub fn spawn_rendered(
        &self,
        runner: crate::runtime::Runner,
        bridge: Bridge,
        mut sink: impl FnMut(&Output, &std::sync::Arc<str>) + Send + 'static,
    ) -> JoinHandle<Result<Bridge, BridgeError>> {
        let (tx, rx) = self.ports();
        thread::spawn(move || runner.run_rendered(bridge, tx, rx, |o, l| sink(o, l)))
    }
}

impl Drop for RealTimeArm {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// One simulated device of a [`Hub`].
#[derive(Debug)]
enum Hosted {
    /// An iRPC joint, with its name in the map (for the execution log).
    Joint(Box<SimJoint>, String),
    Compact(Box<SimCompactDevice>),
    Moteus(Box<SimMoteus>),
}

impl Hosted {
    /// Takes a frame at `now`; an iRPC joint's execution of a request
    /// goes to `log`.
    fn handle_frame(&mut self, now: Duration, frame: &Frame, log: Option<&ExecutionLog>) {
        match self {
            Hosted::Joint(joint, name) => {
                if let Some(e) = joint.handle_frame(now, frame)
                    && let Some(log) = log
                {
                    log(name, joint.config().node_id, &e);
                }
            }
            Hosted::Compact(d) => {
                let _ = d.handle_frame(now, frame);
            }
            Hosted::Moteus(d) => {
                let _ = d.handle_frame(now, frame);
            }
        }
    }

    fn handle_timeout(&mut self, now: Duration) {
        match self {
            Hosted::Joint(j, _) => j.handle_timeout(now),
            Hosted::Compact(d) => d.handle_timeout(now),
            Hosted::Moteus(d) => d.handle_timeout(now),
        }
    }

    fn poll_transmit(&mut self) -> Option<Frame> {
        match self {
            Hosted::Joint(j, _) => j.poll_transmit(),
            Hosted::Compact(d) => d.poll_transmit(),
            Hosted::Moteus(d) => d.poll_transmit(),
        }
    }

    fn poll_timeout(&self) -> Option<Duration> {
        match self {
            Hosted::Joint(j, _) => j.poll_timeout(),
            Hosted::Compact(d) => d.poll_timeout(),
            Hosted::Moteus(d) => d.poll_timeout(),
        }
    }
}

/// A [`RealTimeArm`]'s devices on one connection to the bus, driven by
/// one thread. Each frame heard is handed only to the devices it is
/// addressed to, found by address (an iRPC header's target, or every
/// joint for a broadcast; a segmented transfer's target; a compact
/// device's CAN id; a moteus controller's id and prefix), and the devices'
/// timers are kept in one ordered set: a frame or a timer costs the same
/// however many devices there are. The devices do not hear each other,
/// which none of them listens to (answers and reports are for the bridge).
struct Hub {
    devices: Vec<Hosted>,
    /// iRPC joints by node id.
    joints: HashMap<u16, Vec<usize>>,
    /// Every iRPC joint (a broadcast's receivers).
    all_joints: Vec<usize>,
    /// Compact devices by the CAN id of their commands.
    compact: HashMap<u32, Vec<usize>>,
    /// Moteus controllers by their CAN prefix and id.
    moteus: HashMap<(u32, u32), Vec<usize>>,
    /// When each device next has work (`next`), ordered.
    due: BTreeSet<(Duration, usize)>,
    next: Vec<Option<Duration>>,
    log: Option<ExecutionLog>,
    /// The receivers of the frame being handed over (kept between frames).
    scratch: Vec<usize>,
}

impl Hub {
    /// A device for every iRPC joint, compact device and moteus controller
    /// of `map`.
    fn of(map: &BusMap, log: Option<ExecutionLog>) -> Result<Self, SimError> {
        let mut hub = Self {
            devices: Vec::new(),
            joints: HashMap::new(),
            all_joints: Vec::new(),
            compact: HashMap::new(),
            moteus: HashMap::new(),
            due: BTreeSet::new(),
            next: Vec::new(),
            log,
            scratch: Vec::new(),
        };
        for motor in map.motors() {
            let i = hub.devices.len();
            if let Some(config) = joint_config(motor) {
                hub.joints.entry(config.node_id).or_default().push(i);
                hub.all_joints.push(i);
                let joint = SimJoint::new(config)?;
                hub.devices
                    .push(Hosted::Joint(Box::new(joint), motor.name.clone()));
            } else if let Some(config) = compact_config(motor) {
                hub.compact
                    .entry(u32::from(config.node))
                    .or_default()
                    .push(i);
                hub.devices
                    .push(Hosted::Compact(Box::new(SimCompactDevice::new(config)?)));
            } else if let Some(config) = moteus_config(motor) {
                let key = (u32::from(config.prefix), u32::from(config.id));
                hub.moteus.entry(key).or_default().push(i);
                hub.devices
                    .push(Hosted::Moteus(Box::new(SimMoteus::new(config)?)));
            }
        }
        hub.next = vec![None; hub.devices.len()];
        for i in 0..hub.devices.len() {
            hub.schedule(i);
        }
        Ok(hub)
    }

    /// The devices `frame` is addressed to, into `to`.
    fn receivers(&self, frame: &Frame, to: &mut Vec<usize>) {
        let id = frame.id();
        let raw = id.raw();
        let mut add = |found: Option<&Vec<usize>>| to.extend(found.into_iter().flatten());
        if id.is_extended() {
            add(self.moteus.get(&((raw >> 16) & 0x1FFF, raw & 0x7F)));
            if let Some((_, target)) = motorwire_can::segmented::segmented_ends(id) {
                add(self.joints.get(&target));
            }
            return;
        }
        add(self.compact.get(&raw));
        if let Ok((header, _)) =
            motorwire_irpc::Header::decode_prefix(motorwire_irpc::WireVersion::V2_0, frame.data())
        {
            match header.target_id {
                motorwire_can::client::BROADCAST | motorwire_can::client::ARM_NODE => {
                    to.extend_from_slice(&self.all_joints);
                }
                node => add(self.joints.get(&node)),
            }
        }
    }

    /// Device `i`'s next timer, put in its place.
    fn schedule(&mut self, i: usize) {
        let Some(device) = self.devices.get(i) else {
            return;
        };
        let at = device.poll_timeout();
        let Some(slot) = self.next.get_mut(i) else {
            return;
        };
        if *slot != at {
            if let Some(old) = slot.take() {
                self.due.remove(&(old, i));
            }
            if let Some(t) = at {
                self.due.insert((t, i));
            }
            *slot = at;
        }
    }

    /// Puts on the bus what device `i` has to send, then schedules it.
    fn flush(&mut self, i: usize, port: &mut SimPort) -> Result<(), SimError> {
        if let Some(device) = self.devices.get_mut(i) {
            while let Some(f) = device.poll_transmit() {
                port.send(&f)?;
            }
        }
        self.schedule(i);
        Ok(())
    }

    /// Runs the devices on `port` in real time until `stop` is set: each
    /// frame as it comes, each timer when due. The frames that came while
    /// the thread was not running are handed over before the timers due
    /// by then (a joint's watchdog hears the heartbeat that came in time,
    /// however late the thread woke), as [`SimulatedArm`] steps them.
    fn run(mut self, port: &mut SimPort, stop: &AtomicBool) -> Result<(), SimError> {
        let start = Instant::now();
        let tick = Duration::from_millis(10);
        let mut due = Vec::new();
        while !stop.load(Ordering::Relaxed) {
            // At most this many at once: a flood of frames never holds
            // the timers.
            for _ in 0..MAX_FRAMES_AT_ONCE {
                let Some(r) = port.try_recv() else { break };
                self.hand_over(start.elapsed(), &r.frame, port)?;
            }
            let now = start.elapsed();
            // Each device due now acts once: one whose timer stays due
            // waits for the next pass, never holds the others.
            due.extend(
                self.due
                    .iter()
                    .take_while(|(t, _)| *t <= now)
                    .map(|(_, i)| *i),
            );
            for i in due.drain(..) {
                if let Some(device) = self.devices.get_mut(i) {
                    device.handle_timeout(now);
                }
                self.flush(i, port)?;
            }
            let wait = self
                .due
                .first()
                .map_or(tick, |(t, _)| t.saturating_sub(start.elapsed()))
                .min(tick);
            match port.recv(wait) {
                Ok(r) => self.hand_over(start.elapsed(), &r.frame, port)?,
                Err(motorwire_can::Error::Timeout(_)) => {}
                Err(e) => return Err(e.into()),
            }
        }
        Ok(())
    }

    /// `frame` to the devices it is addressed to, at `now`, and what they
    /// answer on the bus.
    fn hand_over(
        &mut self,
        now: Duration,
        frame: &Frame,
        port: &mut SimPort,
    ) -> Result<(), SimError> {
        let mut to = std::mem::take(&mut self.scratch);
        self.receivers(frame, &mut to);
        let mut result = Ok(());
        for &i in &to {
            if let Some(device) = self.devices.get_mut(i) {
                device.handle_frame(now, frame, self.log.as_ref());
            }
            result = self.flush(i, port);
            if result.is_err() {
                break;
            }
        }
        to.clear();
        self.scratch = to;
        result
    }
}

/// A line the bridge wrote to the simulated Orion arm controller of a
/// [`SimulatedArm`], and what the controller made of it.
#[derive(Debug, Clone, PartialEq)]
pub struct OrionWrite {
    /// When (simulated time).
    pub at: Duration,
    /// The line.
    pub line: String,
    /// Values the controller clamped into its range (a value outside it
    /// reached the controller): none for every line the gate passed.
    pub clamps: usize,
    /// Every motor's value after the line, in `motorwire_orion::Motor::ALL`
    /// order (speeds, actuator commands, the servo's angle).
    pub values: [f64; 7],
}

/// The Orion arm controller of a [`SimulatedArm`] whose bridge has
/// [`crate::BridgeConfig::line_link`]: it boots with the bridge (its beacon at
/// time zero) and answers each line at once.
#[derive(Debug, Default)]
struct SimOrion {
    controller: motorwire_orion::ArmController,
    log: Vec<OrionWrite>,
}

/// A bridge and the simulated devices of its map (iRPC joints, compact
/// devices and, when the bridge has [`crate::BridgeConfig::line_link`], the
/// Orion arm controller) on one in-memory bus, stepped together in
/// simulated time: one harness for every dialect, as quinn's `Pair` is.
///
/// ```
/// use std::time::Duration;
/// use motorwire_bridge::{Bridge, BridgeConfig, Origin};
/// use motorwire_bridge::sim::SimulatedArm;
/// use motorwire_can::SimConfig;
/// use motorwire_translate::BusMap;
///
/// let map = BusMap::from_toml(
///     "[motors.elbow]\ndialect = \"irpc\"\nnode = 0x12\n\
///      limits = { max_velocity = 120, max_acceleration = 500 }",
/// )?;
/// let bridge = Bridge::new(map, BridgeConfig::default())?;
/// let mut arm = SimulatedArm::new(bridge, SimConfig::default())?;
/// arm.run_until(Duration::from_millis(50))?; // configured and activated
/// arm.line(Origin(1), r#"{"motor_id":"elbow","timestamp":0,"control_mode":"position","setpoint":30}"#);
/// arm.run_until(Duration::from_secs(2))?;
/// let result = arm.take_results().remove(0);
/// assert_eq!(result["ok"], true);
/// assert!((arm.joint(0x12).unwrap().position() - 30.0).abs() < 1e-3);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Debug)]
pub struct SimulatedArm {
    bus: SimBus,
    port: SimPort,
    bridge: Bridge,
    joints: Vec<(SimJoint, Option<SimPort>)>,
    compact: Vec<(SimCompactDevice, SimPort)>,
    moteus: Vec<(SimMoteus, SimPort)>,
    orion: Option<SimOrion>,
    /// The simulated servos of each of the map's serial ports.
    servos: Vec<SimServoPort>,
    /// Every packet the bridge wrote to a servo port, with when and the
    /// port, once asked for ([`SimulatedArm::keep_sent`]).
    serial_sent: Vec<(Duration, u8, Vec<u8>)>,
    /// Every frame the bridge sent, with when, once asked for.
    sent: Option<Vec<(Duration, motorwire_can::Frame)>>,
    outputs: Vec<Output>,
    /// Joints' answers held to given times, once asked for
    /// ([`SimulatedArm::count_requests`], [`SimulatedArm::hold_answers`]).
    holding: Option<Holding>,
}

/// What a replay's arm keeps to hand joints' answers to the bridge when
/// the recorded ones were taken.
#[derive(Debug)]
struct Holding {
    /// The requests sent, counted.
    counter: AnswerCounter,
    /// When each answer is handed over, at the earliest: the times of the
    /// answers to one request, in order.
    times: std::collections::HashMap<AnswerKey, std::collections::VecDeque<Duration>>,
    /// Frames from a device waiting to be handed to the bridge, each with
    /// when, per CAN id in the order they came (one held holds those of
    /// its device behind it).
    held: std::collections::BTreeMap<
        u32,
        std::collections::VecDeque<(Duration, motorwire_can::Frame)>,
    >,
}

impl Holding {
    /// The frames the bridge's port received at `now`, in order: those
    /// handed over now; the others are held. A device's frames that came
    /// together (what one request made it say: a lifecycle report, then
    /// its answer) are handed over together, at the latest time any answer
    /// among them is held to, and behind any of that device's still held.
    fn receive(
        &mut self,
        now: Duration,
        batch: Vec<motorwire_can::Frame>,
    ) -> Vec<motorwire_can::Frame> {
        let mut at: std::collections::BTreeMap<u32, Duration> = std::collections::BTreeMap::new();
        for frame in &batch {
            let id = frame.id().raw();
            let own = self
                .counter
                .answer(frame)
                .and_then(|k| {
                    let times = self.times.get_mut(&k)?;
                    let t = times.pop_front();
                    if times.is_empty() {
                        self.times.remove(&k);
                    }
                    t
                })
                .unwrap_or(Duration::ZERO);
            let behind = self
                .held
                .get(&id)
                .and_then(|q| q.back())
                .map_or(Duration::ZERO, |(t, _)| *t);
            let t = at.entry(id).or_default();
            *t = (*t).max(own).max(behind);
        }
        let mut now_due = Vec::new();
        for frame in batch {
            let id = frame.id().raw();
            match at.get(&id) {
                Some(t) if *t > now => self.held.entry(id).or_default().push_back((*t, frame)),
                _ => now_due.push(frame),
            }
        }
        now_due
    }

    /// The held frames whose time has come, by device, each in order.
    fn release(&mut self, now: Duration) -> Vec<motorwire_can::Frame> {
        let mut due = Vec::new();
        self.held.retain(|_, q| {
            while q.front().is_some_and(|(t, _)| *t <= now) {
                if let Some((_, f)) = q.pop_front() {
                    due.push(f);
                }
            }
            !q.is_empty()
        });
        due
    }

    /// When the next held frame is due.
    fn next(&self) -> Option<Duration> {
        self.held
            .values()
            .filter_map(|q| q.front())
            .map(|(t, _)| *t)
            .min()
    }
}

/// What names a joint's answer to a request on the bus, the same in a
/// recording and in its replay: the node that gave it and which of the
/// requests the bridge sent that node it answers (counted from 0 in the
/// order they were first sent; a request sent again is the same request).
/// Counted, not named by msg_id: a replay's msg_ids follow the clock (the
/// heartbeat takes them too).
pub type AnswerKey = (u16, usize);

/// The requests the bridge sent each iRPC joint, in order: the
/// [`AnswerKey`] of a joint's answer, as a recording and its replay both
/// count it.
#[derive(Debug, Default, Clone)]
pub struct AnswerCounter {
    /// The iRPC joints' nodes.
    nodes: std::collections::HashSet<u16>,
    /// Each (node, msg_id) sent, with its place among that node's.
    sent: std::collections::HashMap<(u16, u32), usize>,
    /// How many requests each node was sent.
    per_node: std::collections::HashMap<u16, usize>,
}

impl AnswerCounter {
    /// A counter for the iRPC joints of `map`.
    pub fn new(map: &BusMap) -> Self {
        Self {
            nodes: map
                .motors()
                .filter_map(|m| match m.target {
                    Target::Irpc { node, .. } => Some(node),
                    _ => None,
                })
                .collect(),
            ..Self::default()
        }
    }

    /// A frame the bridge sent: counted when it is an iRPC request to one
    /// joint (not a broadcast).
    pub fn sent(&mut self, frame: &motorwire_can::Frame) {
        let Ok((header, _)) =
            motorwire_irpc::Header::decode_prefix(motorwire_irpc::WireVersion::V2_0, frame.data())
        else {
            return;
        };
        if header.source_id != 0 || !self.nodes.contains(&header.target_id) {
            return;
        }
        let per_node = &mut self.per_node;
        self.sent
            .entry((header.target_id, header.msg_id))
            .or_insert_with(|| {
                let n = per_node.entry(header.target_id).or_default();
                *n += 1;
                *n - 1
            });
    }

    /// The key of a frame the bridge received, when it is a joint's answer
    /// to a request counted: its header's source is the CAN id it came on
    /// and names a request sent to it.
    pub fn answer(&self, frame: &motorwire_can::Frame) -> Option<AnswerKey> {
        let (header, _) =
            motorwire_irpc::Header::decode_prefix(motorwire_irpc::WireVersion::V2_0, frame.data())
                .ok()?;
        if !self.nodes.contains(&header.source_id)
            || u32::from(header.source_id) != frame.id().raw()
        {
            return None;
        }
        self.sent
            .get(&(header.source_id, header.msg_id))
            .map(|i| (header.source_id, *i))
    }
}

impl SimulatedArm {
    /// The bridge, a simulated joint for each iRPC joint of its map, on a
    /// bus made with `config` (its clock is made simulated); the bridge is
    /// started at time zero.
    ///
    /// # Errors
    /// The bus's and the joints' configuration errors.
    pub fn new(bridge: Bridge, config: SimConfig) -> Result<Self, BridgeError> {
        let mut arm = Self::new_unbooted(bridge, config)?;
        arm.orion_boot();
        Ok(arm)
    }

    /// As [`SimulatedArm::new`], but the simulated Orion controller (with
    /// [`crate::BridgeConfig::line_link`]) has not sent its boot beacon yet:
    /// [`SimulatedArm::orion_boot`] sends it (a replay sends it when the
    /// recorded controller did).
    ///
    /// # Errors
    /// The bus's and the joints' configuration errors.
    pub fn new_unbooted(mut bridge: Bridge, config: SimConfig) -> Result<Self, BridgeError> {
        let bus = SimBus::new(SimConfig {
            clock: Clock::Simulated,
            ..config
        })?;
        let port = bus.port();
        let mut joints = Vec::new();
        for c in bridge.map().motors().filter_map(joint_config) {
            let mut joint = SimJoint::new(c)?;
            joint.keep_log();
            joints.push((joint, Some(bus.port())));
        }
        let mut compact = Vec::new();
        for c in bridge.map().motors().filter_map(compact_config) {
            let mut device = SimCompactDevice::new(c)?;
            device.keep_log();
            compact.push((device, bus.port()));
        }
        let mut moteus = Vec::new();
        for c in bridge.map().motors().filter_map(moteus_config) {
            moteus.push((SimMoteus::new(c)?, bus.port()));
        }
        let servos = servo_buses(bridge.map())?;
        bridge.start(Duration::ZERO);
        let orion = bridge.config().line_link.then(SimOrion::default);
        Ok(Self {
            bus,
            port,
            bridge,
            joints,
            compact,
            moteus,
            orion,
            servos,
            serial_sent: Vec::new(),
            sent: None,
            outputs: Vec::new(),
            holding: None,
        })
    }

    /// Counts, from now, the requests the bridge sends each device, as
    /// [`SimulatedArm::hold_answers`] names their answers: asked for
    /// before the bridge sends anything (at its start), so that they are
    /// counted as a recording counts them.
    pub fn count_requests(&mut self) {
        if self.holding.is_none() {
            self.holding = Some(Holding {
                counter: AnswerCounter::new(self.bridge.map()),
                times: std::collections::HashMap::new(),
                held: std::collections::BTreeMap::new(),
            });
        }
    }

    /// Hands each device's answer to a request to the bridge no earlier
    /// than the time `times` gives it ([`AnswerKey`]: the node and which
    /// of its requests; the times of its answers, in order), and the
    /// frames of that device that follow it behind it: what a replay uses
    /// so that its devices answer when the recorded ones did (the
    /// simulated ones answer at once). An answer not named, or named for
    /// a time already past, is handed over as it comes. The requests are
    /// counted from the first call of this or of
    /// [`SimulatedArm::count_requests`].
    pub fn hold_answers(&mut self, times: impl IntoIterator<Item = (AnswerKey, Duration)>) {
        self.count_requests();
        if let Some(h) = &mut self.holding {
            for (key, t) in times {
                h.times.entry(key).or_default().push_back(t);
            }
        }
    }

    /// The simulated Orion controller sends its boot beacon `{"ID":32}`
    /// now (nothing without one).
    pub fn orion_boot(&mut self) {
        if self.orion.is_some() {
            let now = self.bus.now();
            self.bridge.handle_link_line(now, r#"{"ID":32}"#);
        }
    }

    /// The simulated time.
    pub fn now(&self) -> Duration {
        self.bus.now()
    }

    /// The bus (for its fault statistics).
    pub fn bus(&self) -> &SimBus {
        &self.bus
    }

    /// The bridge.
    pub fn bridge(&self) -> &Bridge {
        &self.bridge
    }

    /// The bridge, to call directly.
    pub fn bridge_mut(&mut self) -> &mut Bridge {
        &mut self.bridge
    }

    /// The joint with node id `node`.
    pub fn joint(&self, node: u16) -> Option<&SimJoint> {
        self.joints
            .iter()
            .map(|(j, _)| j)
            .find(|j| j.config().node_id == node)
    }

    /// Makes joint `node` suffer `fault` now ([`SimJoint::fault`]).
    pub fn fault(&mut self, node: u16, fault: motorwire_sim::JointFault) {
        let now = self.bus.now();
        for (j, _) in &mut self.joints {
            if j.config().node_id == node {
                j.fault(now, fault);
            }
        }
    }

    /// Every line the bridge wrote to the simulated Orion arm controller
    /// (empty without [`crate::BridgeConfig::line_link`]).
    pub fn orion_log(&self) -> &[OrionWrite] {
        self.orion.as_ref().map_or(&[], |o| o.log.as_slice())
    }

    /// From now on, keep every frame the bridge sends ([`SimulatedArm::sent`]).
    pub fn keep_sent(&mut self) {
        self.sent.get_or_insert_with(Vec::new);
    }

    /// Every packet the bridge wrote to a servo port since
    /// [`SimulatedArm::keep_sent`], with when and the port (its index among
    /// the map's servo ports).
    pub fn serial_sent(&self) -> &[(Duration, u8, Vec<u8>)] {
        &self.serial_sent
    }

    /// Every frame the bridge sent since [`SimulatedArm::keep_sent`], with
    /// when.
    pub fn sent(&self) -> &[(Duration, motorwire_can::Frame)] {
        self.sent.as_deref().unwrap_or(&[])
    }

    /// The compact device on CAN id `node`.
    pub fn compact_device(&self, node: u16) -> Option<&SimCompactDevice> {
        self.compact
            .iter()
            .map(|(d, _)| d)
            .find(|d| d.config().node == node)
    }

    /// The moteus controller with id `id`.
    pub fn moteus(&self, id: u8) -> Option<&SimMoteus> {
        self.moteus
            .iter()
            .map(|(d, _)| d)
            .find(|d| d.config().id == id)
    }

    /// Makes moteus controller `id` fault now with `code`
    /// ([`SimMoteus::inject_fault`]).
    pub fn moteus_fault(&mut self, id: u8, code: u8) {
        let now = self.bus.now();
        for (d, _) in &mut self.moteus {
            if d.config().id == id {
                d.inject_fault(now, code);
            }
        }
    }

    /// Sets moteus controller `id`'s own position bounds (revolutions;
    /// NaN: none), as a `conf set` from another tool would
    /// ([`SimMoteus::set_bounds`]).
    pub fn moteus_bounds(&mut self, id: u8, min: f64, max: f64) {
        for (d, _) in &mut self.moteus {
            if d.config().id == id {
                d.set_bounds(min, max);
            }
        }
    }

    /// Cuts the joint with node id `node` off the bus (a cable pulled): it
    /// neither hears nor is heard any more.
    pub fn disconnect(&mut self, node: u16) {
        for (j, port) in &mut self.joints {
            if j.config().node_id == node {
                *port = None;
            }
        }
    }

    /// One input line from `origin`, now.
    pub fn line(&mut self, origin: Origin, text: &str) {
        let now = self.bus.now();
        self.bridge.handle_line(now, origin, text);
    }

    /// Every output so far, oldest first, taken.
    pub fn take_outputs(&mut self) -> Vec<Output> {
        self.pump_outputs();
        std::mem::take(&mut self.outputs)
    }

    /// Every output so far, oldest first, drained: the arm keeps its room
    /// for the next ones (what a caller taking outputs after every step
    /// uses, as a runner hands each to its sink without collecting them).
    ///
    /// ```
    /// use std::time::Duration;
    /// use motorwire_bridge::{Bridge, BridgeConfig, Origin, sim::SimulatedArm};
    /// use motorwire_can::SimConfig;
    /// use motorwire_translate::BusMap;
    /// let map = BusMap::from_toml("[motors.elbow]\ndialect = \"irpc\"\nnode = 0x12\nlimits = { max_velocity = 60, max_acceleration = 200 }")?;
    /// let mut arm = SimulatedArm::new(Bridge::new(map, BridgeConfig::default())?, SimConfig::default())?;
    /// arm.run_while(Duration::from_secs(1), |a| a.bridge().is_ready())?;
    /// arm.drain_outputs().for_each(drop);
    /// arm.line(Origin(1), r#"{"motor_id":"elbow","timestamp":1704067200000,"control_mode":"position","setpoint":10}"#);
    /// arm.step(Duration::from_millis(5))?;
    /// let results: Vec<bool> = arm.drain_outputs().filter_map(|o| o.result().map(|r| r.ok)).collect();
    /// assert_eq!(results, [true]);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn drain_outputs(&mut self) -> std::vec::Drain<'_, Output> {
        self.pump_outputs();
        self.outputs.drain(..)
    }

    /// The result lines so far, taken (other outputs are dropped).
    pub fn take_results(&mut self) -> Vec<serde_json::Value> {
        self.take_outputs()
            .into_iter()
            .filter_map(|o| match &o {
                Output::Result { .. } => Some(o.to_value()),
                _ => None,
            })
            .collect()
    }

    fn pump_outputs(&mut self) {
        while let Some(o) = self.bridge.poll_output() {
            self.outputs.push(o);
        }
    }

    /// Handles everything due now, then moves the clock to the next thing
    /// anyone has to do (by at most `max`).
    ///
    /// # Errors
    /// The bus's errors.
    pub fn step(&mut self, max: Duration) -> Result<(), BridgeError> {
        let now = self.bus.now();
        let bridge_next = self.settled()?;
        let next = [
            bridge_next,
            self.bus.next_delivery(),
            self.holding.as_ref().and_then(Holding::next),
            self.joints
                .iter()
                .filter(|(_, p)| p.is_some())
                .filter_map(|(j, _)| j.poll_timeout())
                .min(),
            self.compact
                .iter()
                .filter_map(|(d, _)| d.poll_timeout())
                .min(),
            self.moteus
                .iter()
                .filter_map(|(d, _)| d.poll_timeout())
                .min(),
            self.servos
                .iter()
                .filter_map(|p| p.answers.front().map(|(t, _)| *t))
                .min(),
        ]
        .into_iter()
        .flatten()
        .min()
        .map_or(now.saturating_add(max), |t| t.min(now.saturating_add(max)));
        self.bus
            .advance_to(next.max(now.saturating_add(Duration::from_nanos(1))));
        Ok(())
    }

    /// Runs everything due now, without moving the clock: the bridge's
    /// frames and lines go out, the devices answer what they can, the
    /// bridge hears it; until nothing more happens.
    ///
    /// # Errors
    /// The bus's errors.
    pub fn settle(&mut self) -> Result<(), BridgeError> {
        self.settled().map(drop)
    }

    /// [`SimulatedArm::settle`], saying when the bridge next has work (its
    /// [`Bridge::poll_timeout`] once nothing more happens: taking its
    /// outputs does not change it).
    fn settled(&mut self) -> Result<Option<Duration>, BridgeError> {
        let now = self.bus.now();
        let mut rounds: u32 = 0;
        loop {
            // Each round at one instant answers something that came in it;
            // work still due after this many is a timer that never stops
            // being due: an error, never a spin.
            rounds += 1;
            if rounds > MAX_ROUNDS_AT_ONCE {
                return Err(BridgeError::Stalled {
                    at_ms: u64::try_from(now.as_millis()).unwrap_or(u64::MAX),
                    rounds: MAX_ROUNDS_AT_ONCE,
                });
            }
            let sent = self.send_frames(now)?;
            let mut busy = self.serve_orion(now);
            busy |= self.serve_servos(now);
            if sent {
                self.bridge.flushed(now);
                busy = true;
            }
            busy |= self.serve_devices(now)?;
            busy |= self.take_frames(now);
            let next = self.bridge.poll_timeout();
            if next.is_some_and(|t| t <= now) {
                self.bridge.handle_timeout(now);
                busy = true;
            }
            self.pump_outputs();
            if !busy {
                return Ok(next);
            }
        }
    }

    /// The bridge's frames onto the bus. Whether it sent any.
    fn send_frames(&mut self, now: Duration) -> Result<bool, BridgeError> {
        let mut sent = false;
        while let Some(f) = self.bridge.poll_transmit() {
            self.port.send(&f)?;
            if let Some(h) = &mut self.holding {
                h.counter.sent(&f);
            }
            if let Some(log) = &mut self.sent {
                log.push((now, f));
            }
            sent = true;
        }
        Ok(sent)
    }

    /// The bridge's lines to the simulated Orion controller, and its
    /// answers back. Whether any came back.
    fn serve_orion(&mut self, now: Duration) -> bool {
        let Some(orion) = &mut self.orion else {
            return false;
        };
        let mut answers = Vec::new();
        let mut wrote = false;
        while let Some(line) = self.bridge.poll_link_line() {
            wrote = true;
            let handled = orion.controller.handle_line(&line);
            let mut values = [0.0; 7];
            for (v, m) in values.iter_mut().zip(motorwire_orion::Motor::ALL) {
                *v = orion.controller.value(m);
            }
            orion.log.push(OrionWrite {
                at: now,
                line,
                clamps: handled.as_ref().map_or(0, |r| r.clamps.len()),
                values,
            });
            if let Ok(r) = handled {
                answers.push(r.output.to_json(motorwire_orion::FeedbackKeys::Table));
            }
        }
        if wrote {
            // Written: what waited for its lines to go out is told.
            self.bridge.flushed(now);
        }
        let answered = !answers.is_empty();
        for a in answers {
            self.bridge.handle_link_line(now, &a);
        }
        answered
    }

    /// The bridge's bytes to the simulated servos, and their answers back
    /// once due. Whether any came back.
    fn serve_servos(&mut self, now: Duration) -> bool {
        let mut wrote = false;
        while let Some((port, bytes)) = self.bridge.poll_serial() {
            wrote = true;
            if self.sent.is_some() {
                self.serial_sent.push((now, port, bytes.clone()));
            }
            if let Some(p) = self.servos.get_mut(usize::from(port)) {
                for a in p.bus.write(now, &bytes) {
                    let at = now.saturating_add(a.delay);
                    // In the order they are sent (a late one behind).
                    let k = p.answers.partition_point(|(t, _)| *t <= at);
                    p.answers.insert(k, (at, a.bytes));
                }
            }
        }
        if wrote {
            self.bridge.flushed(now);
        }
        let mut answered = false;
        for (k, p) in self.servos.iter_mut().enumerate() {
            while p.answers.front().is_some_and(|(t, _)| *t <= now) {
                if let Some((_, bytes)) = p.answers.pop_front() {
                    self.bridge
                        .handle_serial(now, u8::try_from(k).unwrap_or(u8::MAX), &bytes);
                    answered = true;
                }
            }
        }
        answered
    }

    /// The simulated servo `id` of serial port `port` (its index among the
    /// map's servo ports).
    pub fn servo(&self, port: u8, id: u8) -> Option<&motorwire_sim::servo::SimServo> {
        self.servos.get(usize::from(port))?.bus.servo(id)
    }

    /// Faults on serial port `port` from now on (answers dropped,
    /// corrupted, late), drawn from `seed`.
    pub fn servo_faults(&mut self, port: u8, faults: motorwire_sim::servo::ServoFaults, seed: u64) {
        if let Some(p) = self.servos.get_mut(usize::from(port)) {
            let bus = p.bus.clone();
            p.bus = bus.with_faults(faults, seed);
        }
    }

    /// Each simulated device takes what came for it and answers. Whether
    /// any did something.
    fn serve_devices(&mut self, now: Duration) -> Result<bool, BridgeError> {
        let mut busy = false;
        for (joint, port) in &mut self.joints {
            if let Some(port) = port {
                busy |= joint.serve(port, now)?;
            }
        }
        for (device, port) in &mut self.compact {
            busy |= device.serve(port, now)?;
        }
        for (device, port) in &mut self.moteus {
            busy |= device.serve(port, now)?;
        }
        Ok(busy)
    }

    /// The devices' frames to the bridge (held back first when answers
    /// are held). Whether any came.
    fn take_frames(&mut self, now: Duration) -> bool {
        let mut busy = false;
        if let Some(h) = &mut self.holding {
            let mut batch = Vec::new();
            while let Some(r) = self.port.try_recv() {
                batch.push(r.frame);
            }
            busy |= !batch.is_empty();
            let mut due = h.release(now);
            busy |= !due.is_empty();
            due.extend(h.receive(now, batch));
            for f in due {
                self.bridge.handle_frame(now, &f);
            }
        } else {
            while let Some(r) = self.port.try_recv() {
                self.bridge.handle_frame(now, &r.frame);
                busy = true;
            }
        }
        busy
    }

    /// Runs until the clock reaches `t`.
    ///
    /// # Errors
    /// The bus's errors.
    pub fn run_until(&mut self, t: Duration) -> Result<(), BridgeError> {
        while self.bus.now() < t {
            let left = t.saturating_sub(self.bus.now());
            self.step(left)?;
        }
        Ok(())
    }

    /// Runs until `done` holds or `limit` of simulated time has passed;
    /// returns whether `done` held.
    ///
    /// # Errors
    /// The bus's errors.
    pub fn run_while(
        &mut self,
        limit: Duration,
        mut done: impl FnMut(&Self) -> bool,
    ) -> Result<bool, BridgeError> {
        let end = self.bus.now().saturating_add(limit);
        while self.bus.now() < end {
            if done(self) {
                return Ok(true);
            }
            let left = end.saturating_sub(self.bus.now());
            self.step(left)?;
        }
        Ok(done(self))
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

    use super::*;
    use crate::BridgeConfig;

    fn ms(n: u64) -> Duration {
        Duration::from_millis(n)
    }

    /// When the result of a move comes: the arm's time before the step
    /// that gave it, the move sent at 50 ms, its Ack held to `hold` (ms
    /// after the start) when given.
    fn result_at(hold: Option<u64>) -> Duration {
        let map = BusMap::from_toml(
            "[motors.elbow]\ndialect = \"irpc\"\nnode = 0x12\nlimits = { max_velocity = 120, max_acceleration = 500 }",
        )
        .unwrap();
        let mut arm = SimulatedArm::new(
            Bridge::new(map, BridgeConfig::default()).unwrap(),
            SimConfig::default(),
        )
        .unwrap();
        arm.count_requests();
        arm.run_until(ms(50)).unwrap();
        arm.take_results();
        // The move is the elbow's next request.
        let next = arm.holding.as_ref().unwrap().counter.per_node[&0x12];
        if let Some(h) = hold {
            arm.hold_answers([((0x12, next), ms(h))]);
        }
        arm.line(
            Origin(1),
            r#"{"motor_id":"elbow","timestamp":0,"control_mode":"position","setpoint":30}"#,
        );
        while arm.now() < ms(100) {
            let t = arm.now();
            arm.step(ms(1)).unwrap();
            if let Some(r) = arm.take_results().first() {
                assert_eq!(r["ok"], true, "{r}");
                return t;
            }
        }
        panic!("no result by 100 ms");
    }

    /// A joint's Ack held to a later time reaches the bridge then (the
    /// arm's clock stops there), not before; not held, it comes at once.
    #[test]
    fn a_held_answer_reaches_the_bridge_at_its_time() {
        assert_eq!(result_at(None), ms(50));
        assert_eq!(result_at(Some(55)), ms(55));
        // Held to a time already past: at once.
        assert_eq!(result_at(Some(10)), ms(50));
    }
}
