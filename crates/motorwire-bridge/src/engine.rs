//! The sans-IO bridge: lines and frames in, frames and output lines out.

use std::collections::{BTreeMap, VecDeque};
use std::time::Duration;

use motorwire_can::Frame;
use motorwire_can::client::{Client, ClientConfig, Completion, Event, Outcome};
use motorwire_irpc::{LifecycleState, MotionProfile, NackCode, Payload, SetTargetPayloadV2};
use motorwire_planner::{Overshoot, Request};
use motorwire_translate::{
    BusMap, Report, Target, feedback_from_irpc, multi_axis_to_irpc, to_irpc,
};
use motorwire_wia::{Message, MotorCommand, MotorFeedback, MultiAxisCommand, Validator};
use serde_json::{Value, json};

use crate::BridgeError;

/// Who sent a line: the runner's name for an input (stdin, a TCP client).
/// Results go back to the origin of their line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Origin(pub u64);

/// How a [`Bridge`] behaves.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BridgeConfig {
    /// The iRPC client: the bridge's node id, wire version, Ack timeout
    /// and retries (default: node 0x0000, v2.0, 100 ms, 3 retries).
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
    /// Unix time in milliseconds at the bridge's time zero, for the
    /// feedback's timestamps.
    pub epoch_unix_ms: f64,
}

impl Default for BridgeConfig {
    fn default() -> Self {
        Self {
            client: ClientConfig::default(),
            activate_on_start: true,
            feedback_period: Some(Duration::from_millis(100)),
            offline_after: Duration::from_millis(500),
            heartbeat_period: Duration::from_millis(50),
            drain_timeout: Duration::from_secs(30),
            epoch_unix_ms: 0.0,
        }
    }
}

/// A line for someone to read.
#[derive(Debug, Clone, PartialEq)]
pub enum Output {
    /// The result of one input line, for its origin:
    /// `{"ok":true,...}` or `{"ok":false,"error":{...}}`.
    Result {
        /// Whose line it answers.
        origin: Origin,
        /// The JSON.
        json: Value,
    },
    /// One joint's feedback, for every reader:
    /// `{"feedback":{WIA MotorFeedback}|null,"motor_id":...,"online":bool}`.
    Feedback(Value),
    /// Something that happened, for every reader: `{"event":"...",...}`
    /// (`startup`, `ready`, `offline`, `online`, `bad_frame`,
    /// `emergency_stop`, `released`, `stopping`, `stopped`).
    Event(Value),
}

impl Output {
    /// The JSON of the line.
    pub fn json(&self) -> &Value {
        match self {
            Self::Result { json, .. } | Self::Feedback(json) | Self::Event(json) => json,
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
    /// Whether it was heard from within [`BridgeConfig::offline_after`].
    pub online: bool,
    /// Its lifecycle state as its last JointStatus said.
    pub state: Option<LifecycleState>,
    /// Its last feedback (positions in the motor's unit).
    pub feedback: Option<MotorFeedback>,
    /// The target of its last acked move (degrees, iRPC's unit).
    pub target: Option<f64>,
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
    /// Emergency stops latched.
    pub emergency_stops: u64,
}

#[derive(Debug)]
struct Joint {
    name: String,
    node: u16,
    last_heard: Option<Duration>,
    online: bool,
    state: Option<LifecycleState>,
    feedback: Option<MotorFeedback>,
    target: Option<f64>,
    /// Until when its last acked move runs (as the bridge plans it).
    moving_until: Duration,
}

#[derive(Debug)]
struct Axis {
    motor: String,
    node: u16,
    queue: VecDeque<Payload>,
    in_flight: Option<(u32, Payload)>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum LineKind {
    Command,
    Startup,
    EmergencyStop,
    Release,
    Shutdown,
}

#[derive(Debug)]
struct PendingLine {
    origin: Option<Origin>,
    number: u64,
    /// `("motor_id"|"command_id", value)`, when the line had one.
    label: Option<(&'static str, String)>,
    kind: LineKind,
    received: Duration,
    axes: Vec<Axis>,
    acked: Vec<String>,
    failures: Vec<Value>,
    report: Report,
    last_frame: Option<Duration>,
    unflushed: bool,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Phase {
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

/// The bridge, sans-IO: feed it input lines ([`Bridge::handle_line`]),
/// frames from the bus ([`Bridge::handle_frame`]) and the time
/// ([`Bridge::handle_timeout`]); put [`Bridge::poll_transmit`]'s frames on
/// the bus, then call [`Bridge::flushed`]; print [`Bridge::poll_output`]'s
/// lines. [`crate::Runner`] does all that in real time.
///
/// ```
/// use std::time::Duration;
/// use motorwire_bridge::{Bridge, BridgeConfig, Origin};
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
/// let out = loop {
///     let o = bridge.poll_output().unwrap();
///     if o.json()["ok"] == false { break o; }
/// };
/// assert_eq!(out.json()["error"]["kind"], "invalid");
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
    map: BusMap,
    config: BridgeConfig,
    validator: Validator,
    client: Client,
    joints: Vec<Joint>,
    lines: BTreeMap<u64, PendingLine>,
    next_line: u64,
    by_msg: BTreeMap<u32, (u64, usize)>,
    waiting: VecDeque<(Duration, Origin, u64, String)>,
    line_numbers: BTreeMap<Origin, u64>,
    /// The number of the line being handled.
    line: u64,
    latched: bool,
    phase: Phase,
    out: VecDeque<Output>,
    next_feedback: Duration,
    next_heartbeat: Duration,
    now: Duration,
    stats: BridgeStats,
}

fn us(d: Duration) -> u64 {
    u64::try_from(d.as_micros()).unwrap_or(u64::MAX)
}

fn error(kind: &str, message: impl Into<String>) -> Value {
    json!({"kind": kind, "message": message.into()})
}

impl Bridge {
    /// A bridge for the iRPC joints of `map`.
    ///
    /// # Errors
    /// [`BridgeError::NoJoints`] when the map has no iRPC joint;
    /// [`BridgeError::Config`] for a zero period or timeout, or a client
    /// node id beyond 11 bits.
    pub fn new(map: BusMap, config: BridgeConfig) -> Result<Self, BridgeError> {
        if config.feedback_period == Some(Duration::ZERO) {
            return Err(BridgeError::Config("the feedback period must not be zero"));
        }
        if config.offline_after.is_zero() || config.heartbeat_period.is_zero() {
            return Err(BridgeError::Config(
                "the offline timeout and the heartbeat period must not be zero",
            ));
        }
        if !config.epoch_unix_ms.is_finite() {
            return Err(BridgeError::Config("the epoch must be a finite number"));
        }
        let client = Client::new(config.client)?;
        let joints: Vec<Joint> = map
            .motors()
            .filter_map(|m| match m.target {
                Target::Irpc { node, .. } => Some(Joint {
                    name: m.name.clone(),
                    node,
                    last_heard: None,
                    online: true,
                    state: None,
                    feedback: None,
                    target: None,
                    moving_until: Duration::ZERO,
                }),
                _ => None,
            })
            .collect();
        if joints.is_empty() {
            return Err(BridgeError::NoJoints);
        }
        Ok(Self {
            map,
            config,
            validator: Validator::new(),
            client,
            joints,
            lines: BTreeMap::new(),
            next_line: 0,
            by_msg: BTreeMap::new(),
            waiting: VecDeque::new(),
            line_numbers: BTreeMap::new(),
            line: 0,
            latched: false,
            phase: Phase::Starting,
            out: VecDeque::new(),
            next_feedback: Duration::ZERO,
            next_heartbeat: Duration::ZERO,
            now: Duration::ZERO,
            stats: BridgeStats::default(),
        })
    }

    /// The bus map.
    pub fn map(&self) -> &BusMap {
        &self.map
    }

    /// What the bridge has done.
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

    /// The joints, in the bus map's order.
    pub fn joints(&self) -> impl Iterator<Item = JointView> + '_ {
        self.joints.iter().map(|j| JointView {
            name: j.name.clone(),
            node: j.node,
            online: j.online,
            state: j.state,
            feedback: j.feedback.clone(),
            target: j.target,
        })
    }

    /// Starts: configures and activates every joint (unless
    /// [`BridgeConfig::activate_on_start`] is false). Lines that arrive
    /// before the joints are ready wait for them.
    pub fn start(&mut self, now: Duration) {
        self.now = now;
        self.next_feedback = now;
        if !self.config.activate_on_start {
            self.become_ready();
            return;
        }
        let axes = self.every_joint(&[Payload::Configure, Payload::Activate]);
        self.open_line(None, None, LineKind::Startup, now, axes, Report::default());
    }

    fn become_ready(&mut self) {
        // The input may have ended during startup: its lines are still
        // served, then the drain goes on.
        let after = match self.phase {
            Phase::Starting => Phase::Running,
            other => other,
        };
        self.phase = Phase::Running;
        let joints: Vec<&str> = self.joints.iter().map(|j| j.name.as_str()).collect();
        self.out
            .push_back(Output::Event(json!({"event": "ready", "joints": joints})));
        while let Some((at, origin, number, text)) = self.waiting.pop_front() {
            self.take_line(at, origin, number, &text);
        }
        if self.phase == Phase::Running {
            self.phase = after;
        }
    }

    /// Takes one input line received at `now` from `origin`. Blank lines
    /// are ignored; every other line gets exactly one result.
    ///
    /// Results carry `"line"`: the line's number among its origin's
    /// non-blank lines (from 1), so a reader can pair every result, an
    /// unlabelled refusal included, with what it sent.
    pub fn handle_line(&mut self, now: Duration, origin: Origin, line: &str) {
        self.now = self.now.max(now);
        let line = line.trim();
        if line.is_empty() {
            return;
        }
        let number = self.number(origin);
        if self.phase == Phase::Starting {
            self.waiting
                .push_back((now, origin, number, line.to_owned()));
            return;
        }
        self.take_line(now, origin, number, line);
    }

    /// A line that could not be read as text (not UTF-8, too long): it
    /// counts as a line of `origin` and is answered
    /// `{"ok":false,"error":{"kind":"unreadable",...}}`.
    pub fn handle_unreadable(&mut self, now: Duration, origin: Origin, reason: &str) {
        self.now = self.now.max(now);
        self.stats.lines += 1;
        self.line = self.number(origin);
        self.refuse(origin, None, error("unreadable", reason));
    }

    fn number(&mut self, origin: Origin) -> u64 {
        let n = self.line_numbers.entry(origin).or_insert(0);
        *n += 1;
        *n
    }

    fn take_line(&mut self, now: Duration, origin: Origin, number: u64, line: &str) {
        self.line = number;
        match self.phase {
            Phase::Starting => {
                self.waiting
                    .push_back((now, origin, number, line.to_owned()));
                return;
            }
            Phase::Running => {}
            Phase::Draining { .. } | Phase::Stopping | Phase::Finished => {
                self.stats.lines += 1;
                self.refuse(
                    origin,
                    None,
                    error("shutting_down", "the bridge is shutting down"),
                );
                return;
            }
        }
        self.stats.lines += 1;
        if let Some(stop) = control_message(line) {
            if stop {
                self.emergency_stop(now, Some(origin), "input");
            } else {
                self.release(now, origin);
            }
            return;
        }
        match self.validator.parse_any(line) {
            Ok(Message::MotorCommand(cmd)) => self.motor_command(now, origin, &cmd),
            Ok(Message::MultiAxisCommand(cmd)) => self.multi_axis(now, origin, &cmd),
            Ok(other) => self.refuse(
                origin,
                None,
                error(
                    "unsupported_kind",
                    format!(
                        "a {} is valid WIA, but the bridge takes motor-command and multi-axis-command lines",
                        other.kind()
                    ),
                ),
            ),
            Err(e) => {
                let violations = serde_json::to_value(e.violations()).unwrap_or(Value::Null);
                self.refuse(
                    origin,
                    None,
                    json!({"kind": "invalid", "message": "not a valid WIA message", "violations": violations}),
                );
            }
        }
    }

    fn refuse(&mut self, origin: Origin, label: Option<(&'static str, String)>, err: Value) {
        self.stats.failed += 1;
        let mut v = json!({"ok": false, "error": err, "line": self.line});
        if let (Some((key, value)), Some(obj)) = (label, v.as_object_mut()) {
            obj.insert(key.to_owned(), Value::String(value));
        }
        self.out.push_back(Output::Result { origin, json: v });
    }

    fn joint_index(&self, motor: &str) -> Option<usize> {
        self.joints.iter().position(|j| j.name == motor)
    }

    /// Refuses a motion line while latched or towards offline joints.
    fn motion_refusal<'a>(&self, mut motors: impl Iterator<Item = &'a str>) -> Option<Value> {
        if self.latched {
            return Some(error(
                "emergency_stop_latched",
                "the emergency stop is latched; send {\"emergency_stop\": false} to release it",
            ));
        }
        motors.find_map(|m| {
            let j = self.joints.get(self.joint_index(m)?)?;
            (!j.online).then(|| {
                json!({"kind": "offline", "motor": m, "message": format!("{m} is offline: nothing heard from node 0x{:02X}", j.node)})
            })
        })
    }

    fn motor_command(&mut self, now: Duration, origin: Origin, cmd: &MotorCommand) {
        let label = Some(("motor_id", cmd.motor_id.clone()));
        if cmd.safety_limits.as_ref().and_then(|l| l.emergency_stop) == Some(true) {
            self.emergency_stop(now, Some(origin), cmd.motor_id.as_str());
            return;
        }
        if let Some(err) = self.motion_refusal(std::iter::once(cmd.motor_id.as_str())) {
            self.refuse(origin, label, err);
            return;
        }
        match to_irpc(&self.map, cmd) {
            Ok(t) => {
                let axes = vec![Axis {
                    motor: cmd.motor_id.clone(),
                    node: t.value.node,
                    queue: t.value.payloads.into(),
                    in_flight: None,
                }];
                self.open_line(Some(origin), label, LineKind::Command, now, axes, t.report);
            }
            Err(r) => self.refuse(origin, label, refusal(&r)),
        }
    }

    fn multi_axis(&mut self, now: Duration, origin: Origin, cmd: &MultiAxisCommand) {
        let label = Some(("command_id", cmd.command_id.clone()));
        let emergency = cmd.motors.iter().any(|a| {
            a.to_motor_command(cmd.timestamp)
                .safety_limits
                .and_then(|l| l.emergency_stop)
                == Some(true)
        });
        if emergency {
            self.emergency_stop(now, Some(origin), cmd.command_id.as_str());
            return;
        }
        if let Some(err) = self.motion_refusal(cmd.motors.iter().map(|a| a.motor_id.as_str())) {
            self.refuse(origin, label, err);
            return;
        }
        let position = |m: &str| {
            let j = self.joints.get(self.joint_index(m)?)?;
            j.feedback.as_ref().map(|f| f.position)
        };
        match multi_axis_to_irpc(&self.map, cmd, &position) {
            Ok(t) => {
                let axes = cmd
                    .motors
                    .iter()
                    .zip(t.value.commands)
                    .map(|(a, c)| Axis {
                        motor: a.motor_id.clone(),
                        node: c.node,
                        queue: c.payloads.into(),
                        in_flight: None,
                    })
                    .collect();
                self.open_line(Some(origin), label, LineKind::Command, now, axes, t.report);
            }
            Err(r) => self.refuse(origin, label, refusal(&r)),
        }
    }

    fn emergency_stop(&mut self, now: Duration, origin: Option<Origin>, cause: &str) {
        self.stats.emergency_stops += 1;
        self.latched = true;
        // Everything not yet sent is cancelled; what is in flight completes.
        let mut cancelled = Vec::new();
        for line in self.lines.values_mut() {
            if line.kind == LineKind::Command {
                for a in &mut line.axes {
                    if !a.queue.is_empty() {
                        a.queue.clear();
                        line.failures.push(json!({"motor": a.motor, "kind": "emergency_stop", "message": "cancelled by the emergency stop before it was sent"}));
                        cancelled.push(a.motor.clone());
                    }
                }
            }
        }
        self.out.push_back(Output::Event(json!({
            "event": "emergency_stop", "cause": cause, "cancelled": cancelled,
        })));
        let axes = self.stop_axes();
        self.open_line(
            origin,
            None,
            LineKind::EmergencyStop,
            now,
            axes,
            Report::default(),
        );
        self.finish_lines();
    }

    /// `Deactivate` for every joint: iRPC executes motion only while
    /// Active, so leaving it is the stop every joint obeys, braking at its
    /// own deceleration limit.
    fn stop_axes(&self) -> Vec<Axis> {
        self.every_joint(&[Payload::Deactivate])
    }

    /// `payloads`, in order, for every joint.
    fn every_joint(&self, payloads: &[Payload]) -> Vec<Axis> {
        self.joints
            .iter()
            .map(|j| Axis {
                motor: j.name.clone(),
                node: j.node,
                queue: payloads.iter().copied().collect(),
                in_flight: None,
            })
            .collect()
    }

    fn release(&mut self, now: Duration, origin: Origin) {
        if !self.latched {
            self.refuse(
                origin,
                None,
                error("not_latched", "there is no emergency stop to release"),
            );
            return;
        }
        self.latched = false;
        self.out
            .push_back(Output::Event(json!({"event": "released"})));
        let axes = self.every_joint(&[Payload::Activate]);
        self.open_line(
            Some(origin),
            None,
            LineKind::Release,
            now,
            axes,
            Report::default(),
        );
    }

    fn open_line(
        &mut self,
        origin: Option<Origin>,
        label: Option<(&'static str, String)>,
        kind: LineKind,
        now: Duration,
        axes: Vec<Axis>,
        report: Report,
    ) {
        let id = self.next_line;
        self.next_line += 1;
        self.lines.insert(
            id,
            PendingLine {
                origin,
                number: self.line,
                label,
                kind,
                received: now,
                axes,
                acked: Vec::new(),
                failures: Vec::new(),
                report,
                last_frame: None,
                unflushed: false,
            },
        );
        let n = self.lines.get(&id).map_or(0, |l| l.axes.len());
        for axis in 0..n {
            self.send_next(id, axis);
        }
        self.finish_lines();
    }

    /// Sends the next payload of one axis of a line.
    fn send_next(&mut self, line_id: u64, axis: usize) {
        let now = self.now;
        let Some(line) = self.lines.get_mut(&line_id) else {
            return;
        };
        let Some(a) = line.axes.get_mut(axis) else {
            return;
        };
        let Some(payload) = a.queue.pop_front() else {
            return;
        };
        match self.client.request(now, a.node, payload) {
            Ok(msg_id) => {
                a.in_flight = Some((msg_id, payload));
                line.unflushed = true;
                self.by_msg.insert(msg_id, (line_id, axis));
            }
            Err(e) => {
                line.failures
                    .push(json!({"motor": a.motor, "kind": "encode", "message": e.to_string()}));
                a.queue.clear();
            }
        }
    }

    /// Emits the result of every line that is done.
    fn finish_lines(&mut self) {
        let done: Vec<u64> = self
            .lines
            .iter()
            .filter(|(_, l)| {
                l.axes
                    .iter()
                    .all(|a| a.in_flight.is_none() && a.queue.is_empty())
                    && !l.unflushed
            })
            .map(|(id, _)| *id)
            .collect();
        for id in done {
            if let Some(line) = self.lines.remove(&id) {
                self.complete(line);
            }
        }
    }

    fn complete(&mut self, line: PendingLine) {
        let now = self.now;
        let latency = line
            .last_frame
            .map(|t| Value::from(us(t.saturating_sub(line.received))));
        let ack = us(now.saturating_sub(line.received));
        let ok = line.failures.is_empty();
        match line.kind {
            LineKind::Startup => {
                for name in &line.acked {
                    self.out.push_back(Output::Event(
                        json!({"event": "startup", "motor_id": name, "ok": true}),
                    ));
                }
                for f in &line.failures {
                    self.out.push_back(Output::Event(
                        json!({"event": "startup", "motor_id": f["motor"], "ok": false, "error": f}),
                    ));
                }
                self.become_ready();
                return;
            }
            LineKind::Shutdown => {
                self.out.push_back(Output::Event(json!({
                    "event": "stopped", "deactivated": line.acked, "failures": line.failures,
                })));
                self.phase = Phase::Finished;
                return;
            }
            LineKind::Command | LineKind::EmergencyStop | LineKind::Release => {}
        }
        let Some(origin) = line.origin else {
            return;
        };
        let mut v = if ok {
            self.stats.ok += 1;
            json!({"ok": true, "acked": line.acked, "latency_us": latency, "ack_us": ack})
        } else {
            self.stats.failed += 1;
            json!({
                "ok": false,
                "error": {"kind": "joint_failed", "message": "not every joint accepted the command", "failures": line.failures},
                "acked": line.acked, "latency_us": latency, "ack_us": ack,
            })
        };
        if let Some(obj) = v.as_object_mut() {
            obj.insert("line".to_owned(), Value::from(line.number));
            if let Some((key, value)) = line.label {
                obj.insert(key.to_owned(), Value::String(value));
            }
            match line.kind {
                LineKind::EmergencyStop => {
                    obj.insert("emergency_stop".to_owned(), Value::Bool(true));
                    obj.insert("stop_latency_us".to_owned(), latency.unwrap_or(Value::Null));
                }
                LineKind::Release => {
                    obj.insert("released".to_owned(), Value::Bool(true));
                }
                _ => {}
            }
            if !line.report.losses.is_empty() {
                let losses: Vec<String> =
                    line.report.losses.iter().map(ToString::to_string).collect();
                obj.insert("losses".to_owned(), json!(losses));
            }
        }
        self.out.push_back(Output::Result { origin, json: v });
    }

    /// Takes a frame from the bus.
    pub fn handle_frame(&mut self, now: Duration, frame: &Frame) {
        self.now = self.now.max(now);
        self.client.handle_frame(self.now, frame);
        self.drain_client();
    }

    /// Advances to `now`: retransmissions and timeouts, feedback, liveness,
    /// heartbeats, the end of a drain.
    pub fn handle_timeout(&mut self, now: Duration) {
        self.now = self.now.max(now);
        let now = self.now;
        self.client.handle_timeout(now);
        self.drain_client();
        // Liveness.
        let offline_after = self.config.offline_after;
        let mut changes = Vec::new();
        for j in &mut self.joints {
            let since = j.last_heard.unwrap_or(Duration::ZERO);
            if j.online && now.saturating_sub(since) >= offline_after {
                j.online = false;
                changes.push(json!({"event": "offline", "motor_id": j.name, "node": j.node, "silent_ms": now.saturating_sub(since).as_millis()}));
            }
        }
        for c in changes {
            self.out.push_back(Output::Event(c));
        }
        if let Some(period) = self.config.feedback_period
            && now >= self.next_feedback
        {
            self.emit_feedback(now);
            self.next_feedback = now.saturating_add(period);
        }
        if self.any_moving(now) && now >= self.next_heartbeat && self.client.arm_ready().is_ok() {
            self.next_heartbeat = now.saturating_add(self.config.heartbeat_period);
        }
        if let Phase::Draining { deadline } = self.phase {
            let idle = self.lines.is_empty() && !self.any_moving(now);
            if idle || now >= deadline {
                self.stop_all(now);
            }
        }
    }

    fn any_moving(&self, now: Duration) -> bool {
        self.joints.iter().any(|j| j.moving_until > now)
    }

    fn emit_feedback(&mut self, now: Duration) {
        let ts = self.unix_ms(now);
        for j in &self.joints {
            let fb = j.feedback.clone().map(|mut f| {
                f.timestamp = ts;
                if !j.online {
                    f.status.fault = Some(true);
                }
                f
            });
            let fb = fb.map_or(Value::Null, |f| {
                serde_json::to_value(f).unwrap_or(Value::Null)
            });
            if fb.is_null() && j.online {
                continue; // nothing heard yet, and not yet overdue
            }
            self.stats.feedback_lines += 1;
            self.out.push_back(Output::Feedback(
                json!({"feedback": fb, "motor_id": j.name, "online": j.online}),
            ));
        }
    }

    fn unix_ms(&self, now: Duration) -> f64 {
        self.config.epoch_unix_ms + now.as_secs_f64() * 1000.0
    }

    fn drain_client(&mut self) {
        while let Some(event) = self.client.poll_event() {
            match event {
                Event::Completed(c) => self.completed(c),
                Event::Feedback { message, at } => {
                    let node = message.header.source_id;
                    self.heard(node, at);
                    let ts = self.unix_ms(at);
                    let Some(j) = self.joints.iter_mut().find(|j| j.node == node) else {
                        continue;
                    };
                    if let Payload::JointStatus { state, .. } = message.payload {
                        j.state = Some(state);
                    }
                    if let Ok(t) = feedback_from_irpc(
                        &self.map,
                        node,
                        &message.payload,
                        ts,
                        j.feedback.as_ref(),
                    ) {
                        j.feedback = Some(t.value);
                    }
                }
                Event::StrayReply { message } => {
                    self.heard(message.header.source_id, self.now);
                }
                Event::Undecodable { can_id, error } => {
                    self.stats.bad_frames += 1;
                    self.out.push_back(Output::Event(json!({
                        "event": "bad_frame", "can_id": can_id.to_string(), "error": error.to_string(),
                    })));
                }
                Event::Misaddressed { can_id, message } => {
                    self.stats.bad_frames += 1;
                    self.out.push_back(Output::Event(json!({
                        "event": "bad_frame", "can_id": can_id.to_string(),
                        "error": format!("the CAN id is not the sender's node id 0x{:02X}", message.header.source_id),
                    })));
                }
            }
        }
        self.finish_lines();
    }

    fn heard(&mut self, node: u16, at: Duration) {
        if let Some(j) = self.joints.iter_mut().find(|j| j.node == node) {
            j.last_heard = Some(at.max(j.last_heard.unwrap_or(Duration::ZERO)));
            if !j.online {
                j.online = true;
                self.out.push_back(Output::Event(
                    json!({"event": "online", "motor_id": j.name, "node": node}),
                ));
            }
        }
    }

    fn completed(&mut self, c: Completion) {
        if c.outcome != Outcome::TimedOut {
            self.heard(c.target, c.finished_at);
        }
        let Some((line_id, axis)) = self.by_msg.remove(&c.msg_id) else {
            return;
        };
        let Some(line) = self.lines.get_mut(&line_id) else {
            return;
        };
        let kind = line.kind;
        let Some(a) = line.axes.get_mut(axis) else {
            return;
        };
        let Some((_, payload)) = a.in_flight.take() else {
            return;
        };
        // Stopping a joint that is already stopped is a stop.
        let already = matches!(payload, Payload::Deactivate)
            && c.outcome == Outcome::Nacked(NackCode::DEACTIVATE_WRONG_STATE)
            && matches!(kind, LineKind::EmergencyStop | LineKind::Shutdown);
        match c.outcome {
            Outcome::Acked => {}
            _ if already => {}
            Outcome::Nacked(code) => {
                line.failures.push(json!({
                    "motor": a.motor, "kind": "nacked", "code": code.0, "message": code.meaning(),
                }));
                a.queue.clear();
            }
            Outcome::TimedOut => {
                line.failures.push(json!({
                    "motor": a.motor, "kind": "timed_out",
                    "message": format!("no answer from node 0x{:02X} after {} tries", a.node, c.attempts),
                }));
                a.queue.clear();
            }
        }
        let motor = a.motor.clone();
        let more = !a.queue.is_empty();
        if a.in_flight.is_none() && !more && (c.outcome == Outcome::Acked || already) {
            line.acked.push(motor.clone());
        }
        if c.outcome == Outcome::TimedOut
            && let Some(j) = self.joints.iter_mut().find(|j| j.node == c.target)
            && j.online
        {
            j.online = false;
            self.out.push_back(Output::Event(json!({
                "event": "offline", "motor_id": j.name, "node": j.node, "reason": "a request timed out",
            })));
        }
        if c.outcome == Outcome::Acked {
            self.track_motion(c.target, payload, c.finished_at);
        }
        if more {
            self.send_next(line_id, axis);
        }
    }

    /// Remembers an acked move: its target and (as planned from the last
    /// feedback) when it ends.
    fn track_motion(&mut self, node: u16, payload: Payload, at: Duration) {
        let Some(j) = self.joints.iter_mut().find(|j| j.node == node) else {
            return;
        };
        let unit = self.map.motor(&j.name).map(|m| m.unit);
        match payload {
            Payload::SetTargetV2(p) => {
                let (pos, vel) = j.feedback.as_ref().map_or((0.0, 0.0), |f| {
                    unit.map_or((f.position, f.velocity), |u| {
                        (u.to_degrees(f.position), u.to_degrees(f.velocity))
                    })
                });
                j.target = Some(f64::from(p.target_angle));
                j.moving_until = at.saturating_add(planned_duration(pos, vel, &p));
            }
            Payload::Deactivate | Payload::Reset => {
                // The joint brakes; give it a moment before calling it idle.
                j.moving_until = j
                    .moving_until
                    .min(at.saturating_add(Duration::from_millis(100)));
            }
            _ => {}
        }
    }

    /// End of input: lines in flight and moves in progress finish (up to
    /// [`BridgeConfig::drain_timeout`]), then every joint is stopped and
    /// deactivated.
    pub fn finish(&mut self, now: Duration) {
        self.now = self.now.max(now);
        if matches!(self.phase, Phase::Starting | Phase::Running) {
            self.phase = Phase::Draining {
                deadline: self.now.saturating_add(self.config.drain_timeout),
            };
            self.out.push_back(Output::Event(
                json!({"event": "stopping", "reason": "end of input"}),
            ));
        }
        self.handle_timeout(self.now);
    }

    /// Interrupted (SIGINT): stop every joint now and deactivate it.
    pub fn interrupt(&mut self, now: Duration) {
        self.now = self.now.max(now);
        if matches!(self.phase, Phase::Stopping | Phase::Finished) {
            return;
        }
        self.out.push_back(Output::Event(
            json!({"event": "stopping", "reason": "interrupted"}),
        ));
        self.stop_all(self.now);
    }

    fn stop_all(&mut self, now: Duration) {
        self.phase = Phase::Stopping;
        let axes = self.stop_axes();
        self.open_line(None, None, LineKind::Shutdown, now, axes, Report::default());
    }

    /// The next frame to put on the bus.
    pub fn poll_transmit(&mut self) -> Option<Frame> {
        let f = self.client.poll_transmit()?;
        self.stats.frames_sent += 1;
        Some(f)
    }

    /// Tells the bridge that every frame [`Bridge::poll_transmit`] gave
    /// out is on the bus as of `now`: the lines that sent them take `now`
    /// as their input-to-bus latency.
    pub fn flushed(&mut self, now: Duration) {
        self.now = self.now.max(now);
        for line in self.lines.values_mut() {
            if line.unflushed {
                line.unflushed = false;
                line.last_frame = Some(now);
            }
        }
        self.finish_lines();
    }

    /// The next line to print.
    pub fn poll_output(&mut self) -> Option<Output> {
        self.out.pop_front()
    }

    /// When [`Bridge::handle_timeout`] next has work.
    pub fn poll_timeout(&self) -> Option<Duration> {
        if self.phase == Phase::Finished {
            return None;
        }
        let liveness = self
            .joints
            .iter()
            .filter(|j| j.online)
            .map(|j| {
                j.last_heard
                    .unwrap_or(Duration::ZERO)
                    .saturating_add(self.config.offline_after)
            })
            .min();
        let heartbeat = self
            .any_moving(self.now)
            .then_some(self.next_heartbeat.max(self.now));
        let drain = match self.phase {
            Phase::Draining { deadline } => Some(
                self.joints
                    .iter()
                    .map(|j| j.moving_until)
                    .max()
                    .unwrap_or(deadline)
                    .min(deadline)
                    .max(self.now),
            ),
            _ => None,
        };
        [
            self.client.poll_timeout(),
            self.config.feedback_period.map(|_| self.next_feedback),
            liveness,
            heartbeat,
            drain,
        ]
        .into_iter()
        .flatten()
        .min()
    }
}

/// `{"emergency_stop": true|false}` and nothing else.
fn control_message(line: &str) -> Option<bool> {
    if !line.contains("emergency_stop") {
        return None;
    }
    let v: Value = serde_json::from_str(line).ok()?;
    let obj = v.as_object()?;
    if obj.len() != 1 {
        return None;
    }
    obj.get("emergency_stop")?.as_bool()
}

fn refusal(r: &motorwire_translate::Refusal) -> Value {
    json!({"kind": "refused", "message": r.to_string()})
}

/// How long a joint takes for `p` from `pos`/`vel` (degrees), planned as
/// the joint plans it; one second when it cannot be planned here.
fn planned_duration(pos: f64, vel: f64, p: &SetTargetPayloadV2) -> Duration {
    let decel = if p.max_deceleration > 0.0 {
        p.max_deceleration
    } else {
        p.max_acceleration
    };
    let mut req = Request::new(
        pos,
        f64::from(p.target_angle),
        f64::from(p.max_velocity),
        f64::from(p.max_acceleration),
    )
    .with_velocities(vel, f64::from(p.target_velocity))
    .with_max_deceleration(f64::from(decel))
    .with_overshoot(Overshoot::Allow);
    if p.max_jerk > 0.0 && !matches!(p.profile, MotionProfile::Trapezoidal) {
        req = req
            .with_jerk(f64::from(p.max_jerk))
            .with_profile(motorwire_planner::MotionProfile::SCurve);
    }
    motorwire_planner::plan(&req)
        .ok()
        .and_then(|plan| Duration::try_from_secs_f64(plan.duration()).ok())
        .unwrap_or(Duration::from_secs(1))
}
