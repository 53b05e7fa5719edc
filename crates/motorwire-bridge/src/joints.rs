//! The joint registry: who each joint is, whether it is heard, what it is
//! doing, and the queue of steps waiting for it.

use std::collections::VecDeque;
use std::time::Duration;

use motorwire_planner::Profile;
use motorwire_translate::AngleUnit;
use motorwire_wia::MotorFeedback;

use crate::device::plan::Move;
use crate::device::{Device, DeviceId, DeviceState, DeviceView, Moving, Order, Registry};
pub(crate) use crate::device::{Kinematics, in_unit};
use crate::output::Origin;

/// A step of a job waiting for (or running on) a joint.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct StepRef {
    pub(crate) job: u64,
    pub(crate) axis: usize,
}

/// A part sent and never answered: the joint may have executed it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Unresolved {
    pub(crate) origin: Option<Origin>,
    pub(crate) line: u64,
    /// The move's target (degrees).
    pub(crate) target: f64,
}

/// A limit brake a joint was given.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct LimitBraked {
    /// The limit it was braked short of: `min_position` or `max_position`.
    pub(crate) side: &'static str,
    /// When, and how fast it went then (its unit a second).
    pub(crate) at: Duration,
    pub(crate) speed: f64,
    /// The brake is on its way to the driver (sending it does not forget
    /// what it was braked short of).
    pub(crate) sending: bool,
}

#[derive(Debug)]
pub(crate) struct Joint {
    /// Who it is: its name, where and how it is addressed, its unit, its
    /// arrival tolerance and pace.
    pub(crate) identity: Identity,
    /// Whether it is heard, and the deadman of a setpoint it holds.
    pub(crate) liveness: Liveness,
    /// Where it is in its lifecycle, as the bridge knows it.
    pub(crate) lifecycle: JointLifecycle,
    /// How it moves, as reported and as the bridge models it.
    pub(crate) motion: Motion,
    /// What it does and waits to do.
    pub(crate) schedule: Schedule,
    /// A stop its feedback has yet to confirm, and how often it was sent
    /// again.
    pub(crate) stop_check: StopCheck,
}

/// Who a joint is: fixed by the bus map when the bridge starts, but for
/// its pace, which follows the limits in force.
#[derive(Debug)]
pub(crate) struct Identity {
    /// Its name in the bus map.
    name: String,
    /// Its CAN id (iRPC node, compact command id; the Orion motors'
    /// [`crate::device::orion::ORION_NODE`], which no frame has).
    node: u16,
    /// Its dialect, and what addresses it there.
    device: Device,
    /// The unit of its positions in the bus map (and in WIA lines).
    unit: AngleUnit,
    /// How close to its target a move must come to have arrived
    /// (degrees): the bus map's `arrival_tolerance`.
    tolerance: f64,
    /// The limits in force that say how long its moves take and how long
    /// a setpoint holds (kept as the bus map's change: [`Pace::of`]).
    pace: Pace,
}

impl Identity {
    /// Its name in the bus map.
    pub(crate) fn name(&self) -> &str {
        &self.name
    }

    /// Its CAN id.
    pub(crate) fn node(&self) -> u16 {
        self.node
    }

    /// Its dialect, and what addresses it there.
    pub(crate) fn device(&self) -> Device {
        self.device
    }

    /// The unit of its positions in the bus map.
    pub(crate) fn unit(&self) -> AngleUnit {
        self.unit
    }

    /// How close to its target a move must come to have arrived
    /// (degrees).
    pub(crate) fn tolerance(&self) -> f64 {
        self.tolerance
    }

    /// The limits in force that say how long its moves take and how long
    /// a setpoint holds.
    pub(crate) fn pace(&self) -> Pace {
        self.pace
    }

    /// The bus map's limits for it changed (`m` as it now has them).
    pub(crate) fn limits_changed(&mut self, m: &motorwire_translate::MappedMotor) {
        self.pace = Pace::of(m);
    }
}

/// A stop taken on an acknowledgement its device cannot tie to it (a
/// compact device acknowledges a command with whatever feedback comes
/// next): its feedback judges it until a newer setpoint or move is taken;
/// one lost on the bus is sent again, a few times at most.
#[derive(Debug, Default)]
pub(crate) struct StopCheck {
    /// The stop: the order, when it was acked, and how fast the motor
    /// went then (its unit a second).
    unconfirmed: Option<(Order, Duration, f64)>,
    /// How often that stop was sent again (back to 0 once another order
    /// is taken).
    resends: u8,
}

impl StopCheck {
    /// The stop its feedback has yet to confirm: the order, when it was
    /// acked, how fast the motor went then.
    pub(crate) fn unconfirmed(&self) -> Option<(Order, Duration, f64)> {
        self.unconfirmed
    }

    /// Stop `order` was taken at `at`, the motor going at `speed`: its
    /// feedback judges it.
    pub(crate) fn taken(&mut self, order: Order, at: Duration, speed: f64) {
        self.unconfirmed = Some((order, at, speed));
    }

    /// The stop is no longer judged (a newer step goes, or it is sent
    /// again and judged once taken); how often it was sent again is kept.
    pub(crate) fn stop_judging(&mut self) {
        self.unconfirmed = None;
    }

    /// Nothing is left to judge (the stop confirmed, given up on, or
    /// another order taken): its count of resends starts over.
    pub(crate) fn settle(&mut self) {
        self.unconfirmed = None;
        self.resends = 0;
    }

    /// Whether the stop may be sent again, counted, or has been `most`
    /// times already: then the count starts over.
    pub(crate) fn resend(&mut self, most: u8) -> bool {
        if self.resends >= most {
            self.resends = 0;
            return false;
        }
        self.resends += 1;
        true
    }
}

/// How a joint moves: as last reported, as the bridge models the move it
/// makes (and plans the one it sends), and what holds or brakes it.
/// [`Joint::state_at`] reads it; [`Joint::set_motion`],
/// [`Joint::set_model`] and the methods here change it.
#[derive(Debug, Default)]
pub(crate) struct Motion {
    /// Its last feedback (positions in the motor's unit).
    feedback: Option<MotorFeedback>,
    /// Its position and velocity (degrees) as last reported.
    reported: Option<(f64, f64)>,
    /// When that was reported, and its acceleration then (degrees/s²,
    /// from the last two reports): where it is now is reckoned from them
    /// ([`Joint::state_at`]).
    reported_at: Option<(Duration, f64)>,
    /// The move it makes now as the bridge planned it, where the bridge
    /// plans as the device does (an iRPC `SetTargetV2`): when it began,
    /// and its profile. Where it is now is read from it while its reports
    /// agree with it ([`Joint::state_at`]).
    model: Option<(Duration, Box<Profile<f64>>)>,
    /// [`Joint::state_at`] as last read, and when for.
    kept: std::cell::Cell<Option<(Duration, Option<Kinematics>)>>,
    /// The move being sent: when, and the state it starts from.
    sending: Option<(Duration, Kinematics)>,
    /// The last move the gate planned for it: from its kinematics, the
    /// payload, and how long the joint's plan takes. When
    /// its Ack comes from the same state, its arrival time is this plan's
    /// (the same inputs make the same plan), not a second planning.
    planned: Option<(Kinematics, Move, Duration)>,
    /// That move's profile (the bridge's model of it once it is acked).
    planned_profile: Option<Box<Profile<f64>>>,
    /// When that move's path was checked.
    planned_at: Duration,
    /// The velocity setpoint it holds (its unit a second), where the
    /// order says one: what it goes at once it is up to speed, judged
    /// against its position limits before its feedback shows it.
    held_velocity: Option<f64>,
    /// The limit the bridge last braked it short of, until a setpoint or
    /// move is taken: while it still moves toward that limit, a velocity
    /// or torque toward it is refused, and it is braked again if it goes
    /// on as fast.
    limit_braked: Option<LimitBraked>,
    /// The largest acceleration its reports showed while it held a
    /// velocity or torque setpoint (degrees/s², a magnitude): how fast a
    /// torque may speed it up, for judging one toward a limit.
    peak_accel: f64,
}

impl Motion {
    /// Its last feedback (positions in the motor's unit).
    pub(crate) fn feedback(&self) -> Option<&MotorFeedback> {
        self.feedback.as_ref()
    }

    /// How fast its last feedback says it goes (its unit a second; 0
    /// before any).
    pub(crate) fn reported_speed(&self) -> f64 {
        self.feedback.as_ref().map_or(0.0, |f| f.velocity.abs())
    }

    /// Its feedback `f` came.
    pub(crate) fn feedback_came(&mut self, f: MotorFeedback) {
        self.feedback = Some(f);
    }

    /// Its position and velocity (degrees) as last reported.
    pub(crate) fn reported(&self) -> Option<(f64, f64)> {
        self.reported
    }

    /// When that was reported, and its acceleration then.
    pub(crate) fn reported_at(&self) -> Option<(Duration, f64)> {
        self.reported_at
    }

    /// The bridge's model of the move it makes now: when it began, and
    /// its profile.
    pub(crate) fn model(&self) -> Option<&(Duration, Box<Profile<f64>>)> {
        self.model.as_ref()
    }

    /// The state the move being sent starts from.
    pub(crate) fn sent_from(&self) -> Option<Kinematics> {
        self.sending.map(|(_, from)| from)
    }

    /// The last move the gate planned for it.
    pub(crate) fn planned(&self) -> Option<(Kinematics, Move, Duration)> {
        self.planned
    }

    /// When that move's path was checked.
    pub(crate) fn planned_at(&self) -> Duration {
        self.planned_at
    }

    /// The velocity setpoint it holds (its unit a second), if the order
    /// says one.
    pub(crate) fn held_velocity(&self) -> Option<f64> {
        self.held_velocity
    }

    /// The limit the bridge last braked it short of, if any still binds.
    pub(crate) fn limit_braked(&self) -> Option<LimitBraked> {
        self.limit_braked
    }

    /// The largest acceleration its reports showed while it held a
    /// velocity or torque setpoint (degrees/s², a magnitude).
    pub(crate) fn peak_accel(&self) -> f64 {
        self.peak_accel
    }

    /// Its reports showed `acceleration` while it held a torque setpoint.
    pub(crate) fn saw_acceleration(&mut self, acceleration: f64) {
        self.peak_accel = self.peak_accel.max(acceleration.abs());
    }

    /// The move planned for it (`planned`, its `profile`), its path
    /// checked at `at`.
    pub(crate) fn keep_plan(
        &mut self,
        planned: Option<(Kinematics, Move, Duration)>,
        profile: Option<Box<Profile<f64>>>,
        at: Duration,
    ) {
        self.planned = planned;
        self.planned_profile = profile;
        self.planned_at = at;
    }

    /// Nothing is being sent to it.
    pub(crate) fn not_sending(&mut self) {
        self.sending = None;
    }

    /// It holds `velocity` (its unit a second; `None`: no velocity
    /// setpoint).
    pub(crate) fn holds(&mut self, velocity: Option<f64>) {
        self.held_velocity = velocity;
    }

    /// It is braked short of its limit `side` at `at`, going at `speed`
    /// (its unit a second); the brake is on its way to the driver.
    pub(crate) fn braked(&mut self, side: &'static str, at: Duration, speed: f64) {
        self.limit_braked = Some(LimitBraked {
            side,
            at,
            speed,
            sending: true,
        });
    }

    /// The limit brake is no longer on its way (sent, or none was).
    pub(crate) fn brake_sent(&mut self) {
        if let Some(b) = self.limit_braked.as_mut() {
            b.sending = false;
        }
    }

    /// An order was taken: the limit brake itself going out keeps what it
    /// was braked short of; a new setpoint or move (`moves`) forgets it
    /// (one toward the limit it was braked short of only once it had
    /// stopped).
    pub(crate) fn order_taken(&mut self, moves: bool) {
        if let Some(b) = self.limit_braked.as_mut().filter(|b| b.sending) {
            b.sending = false;
        } else if moves {
            self.limit_braked = None;
        }
    }
}

/// How far a report may be from the bridge's model of the move before the
/// model is set aside (degrees; degrees a second): a report is an f32, and
/// besides, as old as [`REPORT_AGE`] at most, by as much as the model moves
/// in that time.
const MODEL_AGREES: (f64, f64) = (0.01, 0.5);

/// How much older than its time of arrival a report may be (the joint
/// wrote it, the bus and the reader's thread carried it; and the joint
/// started the move a frame's latency after the bridge sent it).
const REPORT_AGE: f64 = 0.005;

/// How far a report is carried forward to `now` at the most: beyond, the
/// last report stands as it is (the device is silent, or stands still).
const RECKONED_AT_MOST: Duration = Duration::from_millis(50);

/// A motor's limits in force that say how long its moves take and how
/// long a setpoint holds, in degrees: what tracking an acknowledged order
/// reads from the bus map, kept on the joint.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub(crate) struct Pace {
    pub(crate) max_velocity: Option<f64>,
    pub(crate) max_acceleration: Option<f64>,
    /// Its command timeout (the deadman's), if any.
    pub(crate) command_timeout: Option<Duration>,
}

impl Pace {
    /// `m`'s, as the bus map now has them.
    pub(crate) fn of(m: &motorwire_translate::MappedMotor) -> Self {
        Self {
            max_velocity: m.limits.max_velocity.map(|v| m.unit.to_degrees(v)),
            max_acceleration: m.limits.max_acceleration.map(|a| m.unit.to_degrees(a)),
            command_timeout: m.command_timeout,
        }
    }
}

/// What a joint does and waits to do: the steps waiting for it, the one
/// that holds it (in flight, or a trajectory's between two segments) and
/// when that one sends next; its last acked move (where to, until when,
/// taken from which line) and a part sent and never answered.
#[derive(Debug, Default)]
pub(crate) struct Schedule {
    /// Steps waiting to be sent, oldest first.
    queue: VecDeque<StepRef>,
    /// The step whose request is in flight (or that holds the device
    /// between a trajectory's segments).
    busy: Option<StepRef>,
    /// Its busy step (a trajectory's) sends its next payload then.
    wake: Option<Duration>,
    /// The target of its last acked move (degrees).
    target: Option<f64>,
    /// Until when its last acked move runs (as the bridge plans it).
    moving_until: Duration,
    /// The line whose move or setpoint the device last took (`None`: the
    /// bridge's own, a stop): a line watched on it whose move came before
    /// will not arrive.
    moved_by: Option<crate::output::LineRef>,
    /// A part sent and never answered: the joint may have executed it.
    unresolved: Option<Unresolved>,
}

impl Schedule {
    /// The step that holds the device, if one does.
    pub(crate) fn busy(&self) -> Option<StepRef> {
        self.busy
    }

    /// When the busy step (a trajectory's) sends its next payload.
    pub(crate) fn wake(&self) -> Option<Duration> {
        self.wake
    }

    /// The steps waiting, oldest first.
    pub(crate) fn waiting(&self) -> std::collections::vec_deque::Iter<'_, StepRef> {
        self.queue.iter()
    }

    /// The step that holds the device, then those waiting.
    pub(crate) fn steps(&self) -> impl Iterator<Item = &StepRef> {
        self.busy.iter().chain(self.queue.iter())
    }

    /// The oldest step waiting.
    pub(crate) fn next_waiting(&self) -> Option<StepRef> {
        self.queue.front().copied()
    }

    /// How many steps wait.
    pub(crate) fn waiting_len(&self) -> usize {
        self.queue.len()
    }

    /// Whether any step waits.
    pub(crate) fn has_waiting(&self) -> bool {
        !self.queue.is_empty()
    }

    /// `step` waits, behind the rest.
    pub(crate) fn wait(&mut self, step: StepRef) {
        self.queue.push_back(step);
    }

    /// `steps` wait, in order, behind the rest.
    pub(crate) fn wait_all(&mut self, steps: impl IntoIterator<Item = StepRef>) {
        self.queue.extend(steps);
    }

    /// The oldest step waiting, no longer waiting.
    pub(crate) fn take_next(&mut self) -> Option<StepRef> {
        self.queue.pop_front()
    }

    /// Only the steps waiting that `keep` keeps wait on, in order (each
    /// looked at once, oldest first).
    pub(crate) fn retain_waiting(&mut self, mut keep: impl FnMut(StepRef) -> bool) {
        self.queue.retain(|s| keep(*s));
    }

    /// The steps waiting that `pick` chooses, no longer waiting (the rest
    /// wait on in order).
    pub(crate) fn take_waiting_where(&mut self, pick: impl Fn(&StepRef) -> bool) -> Vec<StepRef> {
        let (taken, kept): (Vec<StepRef>, Vec<StepRef>) = self.queue.drain(..).partition(pick);
        self.queue.extend(kept);
        taken
    }

    /// Every step waiting, no longer waiting.
    pub(crate) fn take_all_waiting(&mut self) -> Vec<StepRef> {
        self.queue.drain(..).collect()
    }

    /// `step`'s request is in flight: it holds the device.
    pub(crate) fn start(&mut self, step: StepRef) {
        self.busy = Some(step);
    }

    /// `step` (a trajectory's) holds the device until `due`, when it sends
    /// its next payload.
    pub(crate) fn hold_until(&mut self, step: StepRef, due: Duration) {
        self.busy = Some(step);
        self.wake = Some(due);
    }

    /// The step that held the device, no longer holding it.
    pub(crate) fn take_busy(&mut self) -> Option<StepRef> {
        self.busy.take()
    }

    /// The step that holds the device, if `pick` chooses it, no longer
    /// holding it.
    pub(crate) fn take_busy_if(&mut self, pick: impl FnOnce(&StepRef) -> bool) -> Option<StepRef> {
        self.busy.take_if(|s| pick(s))
    }

    /// No step holds the device.
    pub(crate) fn clear_busy(&mut self) {
        self.busy = None;
    }

    /// Nothing is woken for.
    pub(crate) fn clear_wake(&mut self) {
        self.wake = None;
    }

    /// No step holds the device, and nothing is woken for.
    pub(crate) fn release(&mut self) {
        self.busy = None;
        self.wake = None;
    }

    /// The target of its last acked move (degrees).
    pub(crate) fn target(&self) -> Option<f64> {
        self.target
    }

    /// Until when its last acked move runs (as the bridge plans it).
    pub(crate) fn moving_until(&self) -> Duration {
        self.moving_until
    }

    /// Whether its last acked move still runs at `now`.
    pub(crate) fn is_moving(&self, now: Duration) -> bool {
        self.moving_until > now
    }

    /// The line whose move or setpoint it last took (`None`: the bridge's
    /// own, a stop).
    pub(crate) fn moved_by(&self) -> Option<crate::output::LineRef> {
        self.moved_by
    }

    /// The part sent and never answered, if any.
    pub(crate) fn unresolved(&self) -> Option<Unresolved> {
        self.unresolved
    }

    /// It took a move or setpoint of `line` (`None`: the bridge's own).
    pub(crate) fn taken_from(&mut self, line: Option<crate::output::LineRef>) {
        self.moved_by = line;
    }

    /// An acked order's effect on its move: its new `target`, if it says
    /// one (`Some(None)`: it has none now), and until when it moves.
    pub(crate) fn acked(&mut self, target: Option<Option<f64>>, moving: Moving) {
        if let Some(target) = target {
            self.target = target;
        }
        match moving {
            Moving::Unchanged => {}
            Moving::Until(t) => self.moving_until = t,
            Moving::AtMost(t) => self.moving_until = self.moving_until.min(t),
        }
    }

    /// A part `u` was sent and never answered.
    pub(crate) fn left_unresolved(&mut self, u: Unresolved) {
        self.unresolved = Some(u);
    }

    /// What it does now settles the part never answered.
    pub(crate) fn settle(&mut self) {
        self.unresolved = None;
    }
}

/// Whether a joint is heard, and the deadman of a setpoint it holds.
#[derive(Debug)]
pub(crate) struct Liveness {
    /// When it was last heard from.
    last_heard: Option<Duration>,
    /// Whether it was heard from within the offline time.
    online: bool,
    /// The deadman: when a velocity or torque setpoint it holds must be
    /// renewed by, or it is brought to a stop.
    deadman: Option<Duration>,
}

impl Liveness {
    /// A joint not heard from yet: `online` as its device starts.
    fn new(online: bool) -> Self {
        Self {
            last_heard: None,
            online,
            deadman: None,
        }
    }

    /// When it was last heard from.
    pub(crate) fn last_heard(&self) -> Option<Duration> {
        self.last_heard
    }

    /// Whether it was heard from within the offline time.
    pub(crate) fn is_online(&self) -> bool {
        self.online
    }

    /// When the setpoint it holds must be renewed by, if it holds one.
    pub(crate) fn deadman(&self) -> Option<Duration> {
        self.deadman
    }

    /// It was heard from at `at` (a report older than the last one heard
    /// leaves that one the last).
    pub(crate) fn heard(&mut self, at: Duration) {
        self.last_heard = Some(at.max(self.last_heard.unwrap_or(Duration::ZERO)));
    }

    /// It is online; whether it was not.
    pub(crate) fn back_online(&mut self) -> bool {
        !std::mem::replace(&mut self.online, true)
    }

    /// It is offline; whether it was online.
    pub(crate) fn went_offline(&mut self) -> bool {
        std::mem::replace(&mut self.online, false)
    }

    /// The setpoint it holds must be renewed by `at` (`None`: it holds
    /// none the deadman watches).
    pub(crate) fn deadman_at(&mut self, at: Option<Duration>) {
        self.deadman = at;
    }

    /// Nothing it holds is watched by the deadman any more.
    pub(crate) fn disarm_deadman(&mut self) {
        self.deadman = None;
    }
}

/// Where a joint is in its lifecycle, as the bridge knows it: what it
/// last reported, whether the bridge holds it active, whether a line left
/// it inactive, whether it is lost until a reset, and whether a reset is
/// under way. Changed only as each of these happens.
#[derive(Debug)]
pub(crate) struct JointLifecycle {
    /// Its lifecycle state as it last said.
    state: Option<DeviceState>,
    /// Whether the bridge last made it Active (its own acked Activate or
    /// Deactivate, or the joint's JointStatus, whichever came last).
    active: bool,
    /// A line left it inactive (`disabled`, `free`, `stop`): its next
    /// command is preceded by an Activate (a joint inactive for any other
    /// reason, a fault or a failed start, waits for a reset line).
    freed: bool,
    /// It faulted or rebooted (why): nothing but a reset line is sent to it.
    needs_reset: Option<String>,
    /// A Reset the bridge sent is under way (its `Unconfigured` is no
    /// reboot).
    resetting: bool,
}

impl JointLifecycle {
    /// A joint's lifecycle before anything is heard of it: `active` as its
    /// device starts.
    fn new(active: bool) -> Self {
        Self {
            state: None,
            active,
            freed: false,
            needs_reset: None,
            resetting: false,
        }
    }

    /// Its lifecycle state as it last said.
    pub(crate) fn state(&self) -> Option<DeviceState> {
        self.state
    }

    /// Whether the bridge holds it Active.
    pub(crate) fn is_active(&self) -> bool {
        self.active
    }

    /// Whether a line left it inactive (its next command activates it
    /// first).
    pub(crate) fn is_freed(&self) -> bool {
        self.freed
    }

    /// Why it takes nothing but a reset (it faulted or rebooted), if so.
    pub(crate) fn needs_reset(&self) -> Option<&str> {
        self.needs_reset.as_deref()
    }

    /// Whether a Reset the bridge sent is under way.
    pub(crate) fn is_resetting(&self) -> bool {
        self.resetting
    }

    /// It reported `state`: active only when that is Active. Returns the
    /// state reported before.
    pub(crate) fn reported(&mut self, state: DeviceState) -> Option<DeviceState> {
        self.active = state.takes_motion();
        self.state.replace(state)
    }

    /// It faulted or rebooted (`why`): inactive, and lost until a reset.
    pub(crate) fn lost(&mut self, why: String) {
        self.needs_reset = Some(why);
        self.active = false;
    }

    /// A line deactivates it: freed, if the bridge had it up (one never
    /// started, or whose start failed, waits for a reset).
    pub(crate) fn freed_by_a_line(&mut self) {
        self.freed |= self.active;
    }

    /// An acked order made it `active` or not. Active again with no line
    /// waiting to deactivate it (`deactivation_waits`), its next command
    /// needs no Activate first.
    pub(crate) fn made_active(&mut self, active: bool, deactivation_waits: bool) {
        self.active = active;
        if active && !deactivation_waits {
            self.freed = false;
        }
    }

    /// A Reset the bridge sent is under way.
    pub(crate) fn reset_sent(&mut self) {
        self.resetting = true;
    }

    /// The reset ended; `ok`: every part of it went, so it is no longer
    /// lost.
    pub(crate) fn reset_ended(&mut self, ok: bool) {
        self.resetting = false;
        if ok {
            self.needs_reset = None;
        }
    }
}

impl Joint {
    /// Its position, velocity and acceleration at `now` (degrees),
    /// read from the bridge's model of its move, else reckoned from its
    /// last report and the acceleration then, with the acceleration taken
    /// as zero (as before a model existed; a device reports every few
    /// milliseconds; a move planned now must start from where it is, not
    /// where it was). A velocity that would change sign is taken to stop.
    ///
    /// Kept for the instant it was last read at until the model or the
    /// report changes ([`Joint::set_model`], [`Joint::set_motion`]): a
    /// line reads it when it is gated and again when it is sent. Debug
    /// builds check every kept value against a fresh reading.
    pub(crate) fn state_at(&self, now: Duration) -> Option<Kinematics> {
        if let Some((at, kept)) = self.motion.kept.get()
            && at == now
        {
            debug_assert!(
                same_state(kept, self.state_now(now)),
                "{}: the state changed without set_model or set_motion",
                self.identity.name
            );
            return kept;
        }
        let s = self.state_now(now);
        self.motion.kept.set(Some((now, s)));
        s
    }

    /// Its model of the move it makes now (when it began, its profile).
    pub(crate) fn set_model(&mut self, model: Option<(Duration, Box<Profile<f64>>)>) {
        self.motion.model = model;
        self.motion.kept.set(None);
    }

    /// Its report: position and velocity, when, and its acceleration then.
    pub(crate) fn set_motion(&mut self, motion: (f64, f64), at: Duration, acceleration: f64) {
        self.motion.reported = Some(motion);
        self.motion.reported_at = Some((at, acceleration));
        self.motion.kept.set(None);
    }

    /// [`Joint::state_at`], computed.
    fn state_now(&self, now: Duration) -> Option<Kinematics> {
        if let Some((start, profile)) = &self.motion.model {
            let t = now.saturating_sub(*start).as_secs_f64();
            if t <= profile.duration() {
                let s = profile.sample(t);
                // As the device plans from it: a jerk-limited move's
                // acceleration carries on; a trapezoidal one's steps.
                let a = if profile.is_jerk_limited() {
                    s.acceleration
                } else {
                    0.0
                };
                return Some((s.position, s.velocity, a));
            }
            let end = profile.end_state();
            if end.velocity == 0.0 {
                return Some((end.position, 0.0, 0.0));
            }
        }
        let (p, v) = self.motion.reported?;
        let Some((at, a)) = self.motion.reported_at else {
            return Some((p, v, 0.0));
        };
        let dt = now.saturating_sub(at);
        if a == 0.0 && v == 0.0 {
            return Some((p, v, 0.0));
        }
        if dt > RECKONED_AT_MOST {
            // Reports missing (dropped, late): carried forward as far as
            // the acceleration reckons, then at that velocity, up to
            // half a second (a device silent for longer is offline).
            let t = RECKONED_AT_MOST.as_secs_f64();
            let (p1, v1) = if a != 0.0 && (v + a * t) * v <= 0.0 {
                let t = -v / a;
                (p + v * t + 0.5 * a * t * t, 0.0)
            } else {
                (p + v * t + 0.5 * a * t * t, v + a * t)
            };
            let rest = dt
                .min(Duration::from_millis(500))
                .saturating_sub(RECKONED_AT_MOST);
            return Some((p1 + v1 * rest.as_secs_f64(), v1, 0.0));
        }
        let mut t = dt.as_secs_f64();
        // At rest (`v` 0) with an acceleration reckoned from the report
        // before: the velocity reached zero, and would change sign (a joint
        // braked to rest was reckoned moving back, and a move from there,
        // at a limit, refused for the path's dip below it).
        if a != 0.0 && (v + a * t) * v <= 0.0 {
            // It comes to rest on the way.
            t = -v / a;
            return Some((p + v * t + 0.5 * a * t * t, 0.0, 0.0));
        }
        // The acceleration reckoned from two reports is carried into the
        // position and velocity, not passed on: it is an average over their
        // interval, and under late or reordered reports no more than a
        // guess, which a plan from it would turn into a path it is not.
        Some((p + v * t + 0.5 * a * t * t, v + a * t, 0.0))
    }

    /// A report of `position` and `velocity` at `at`: the model stands
    /// while the report agrees with it.
    pub(crate) fn check_model(&mut self, at: Duration, position: f64, velocity: f64) {
        if let Some((start, profile)) = &self.motion.model {
            let t = at.saturating_sub(*start).as_secs_f64();
            let s = if t <= profile.duration() {
                profile.sample(t)
            } else {
                profile.end_state()
            };
            let position_slack = MODEL_AGREES.0 + s.velocity.abs() * REPORT_AGE;
            let velocity_slack = MODEL_AGREES.1 + s.acceleration.abs() * REPORT_AGE;
            if (s.position - position).abs() > position_slack
                || (s.velocity - velocity).abs() > velocity_slack
            {
                self.set_model(None);
            }
        }
    }

    /// A move is being sent to it, from where it is at `now`.
    pub(crate) fn start_sending(&mut self, now: Duration) {
        self.motion.sending = self.state_at(now).map(|s| (now, s));
    }

    /// `order`, acked: the move as the device plans it, from where it was
    /// sent (the gate's own plan when it is the same move from the same
    /// state), is its model; any other order leaves the device to its
    /// reports. The gate's plan is spent.
    pub(crate) fn model_acked(&mut self, order: Order) {
        let sent_from = self.motion.sent_from();
        let gate_plan = self
            .motion
            .planned
            .zip(self.motion.planned_profile.take())
            .filter(|((from, ..), _)| Some(*from) == sent_from)
            .map(|((_, p, _), profile)| (p, profile));
        let model = self
            .motion
            .sending
            .take()
            .and_then(|(t, from)| Some((t, order.device_plan(from, gate_plan)?)));
        self.set_model(model);
        self.motion.planned = None;
    }

    /// `tolerance`: the bus map's `arrival_tolerance`, in `unit`.
    /// A joint of the bus map: `m`'s name, unit, arrival tolerance and
    /// limits.
    pub(crate) fn of(m: &motorwire_translate::MappedMotor, node: u16, device: Device) -> Self {
        let mut j = Self::new(m.name.clone(), node, device, m.unit, m.arrival_tolerance);
        j.identity.limits_changed(m);
        j
    }

    pub(crate) fn new(
        name: String,
        node: u16,
        device: Device,
        unit: AngleUnit,
        tolerance: f64,
    ) -> Self {
        Self {
            identity: Identity {
                name,
                node,
                device,
                unit,
                tolerance: unit.to_degrees(tolerance),
                pace: Pace::default(),
            },
            liveness: Liveness::new(device.online_at_start()),
            lifecycle: JointLifecycle::new(device.active_at_start()),
            motion: Motion::default(),
            schedule: Schedule::default(),
            stop_check: StopCheck::default(),
        }
    }
}

/// Whether two readings are the same, to the bit (a NaN is itself).
fn same_state(a: Option<Kinematics>, b: Option<Kinematics>) -> bool {
    let bits = |k: Option<Kinematics>| k.map(|(p, v, a)| (p.to_bits(), v.to_bits(), a.to_bits()));
    bits(a) == bits(b)
}

/// The engine's devices, in its order: each named by its [`DeviceId`],
/// made here for the places there are.
#[derive(Debug, Default)]
pub(crate) struct Joints(Vec<Joint>);

impl Joints {
    /// The devices `joints`, in that order.
    pub(crate) fn new(joints: Vec<Joint>) -> Self {
        Self(joints)
    }

    /// Device `id`, if there is one.
    pub(crate) fn get(&self, id: DeviceId) -> Option<&Joint> {
        self.0.get(id.index())
    }

    /// Device `id`, to change, if there is one.
    pub(crate) fn get_mut(&mut self, id: DeviceId) -> Option<&mut Joint> {
        self.0.get_mut(id.index())
    }

    /// Whether there are none.
    pub(crate) fn is_empty(&self) -> bool {
        self.0.is_empty()
    }

    /// Every device's id, in order.
    pub(crate) fn ids(&self) -> impl Iterator<Item = DeviceId> + use<> {
        (0..self.0.len()).map(DeviceId::at)
    }

    /// Every device, in order.
    pub(crate) fn iter(&self) -> std::slice::Iter<'_, Joint> {
        self.0.iter()
    }

    /// Every device, to change, in order.
    pub(crate) fn iter_mut(&mut self) -> std::slice::IterMut<'_, Joint> {
        self.0.iter_mut()
    }

    /// Every device with its id, in order.
    pub(crate) fn with_ids(&self) -> impl Iterator<Item = (DeviceId, &Joint)> {
        self.0.iter().enumerate().map(|(k, j)| (DeviceId::at(k), j))
    }

    /// Every device with its id, to change, in order.
    pub(crate) fn with_ids_mut(&mut self) -> impl Iterator<Item = (DeviceId, &mut Joint)> {
        self.0
            .iter_mut()
            .enumerate()
            .map(|(k, j)| (DeviceId::at(k), j))
    }

    /// The first device `pick` chooses.
    pub(crate) fn find(&self, pick: impl Fn(&Joint) -> bool) -> Option<DeviceId> {
        self.0.iter().position(pick).map(DeviceId::at)
    }
}

impl Registry for Joints {
    fn count(&self) -> usize {
        self.0.len()
    }

    fn view(&self, id: DeviceId) -> Option<DeviceView<'_>> {
        let j = self.get(id)?;
        Some(DeviceView {
            id,
            name: &j.identity.name,
            node: j.identity.node,
            device: j.identity.device,
            unit: j.identity.unit,
            online: j.liveness.is_online(),
            feedback: j.motion.feedback.as_ref(),
        })
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]

    use super::*;
    use crate::device::Device;

    fn joint() -> Joint {
        let map =
            motorwire_translate::BusMap::from_toml("[motors.j]\ndialect = \"irpc\"\nnode = 0x10\n")
                .unwrap();
        let (node, device) = Device::of(map.motor("j").unwrap(), false).unwrap();
        Joint::new("j".into(), node, device, AngleUnit::Degrees, 0.1)
    }

    /// Read twice at one instant, the state is the same; a report or a
    /// model that comes in that instant is read at once.
    #[test]
    fn a_state_kept_for_an_instant_gives_way_to_a_report_or_a_model() {
        let mut j = joint();
        let t = Duration::from_millis(100);
        assert_eq!(j.state_at(t), None);
        j.set_motion((10.0, 0.0), t, 0.0);
        assert_eq!(j.state_at(t), Some((10.0, 0.0, 0.0)));
        assert_eq!(j.state_at(t), Some((10.0, 0.0, 0.0)));
        j.set_motion((12.0, 5.0), t, 0.0);
        assert_eq!(j.state_at(t), Some((12.0, 5.0, 0.0)));
        let plan = motorwire_planner::plan(
            &motorwire_irpc::SetTargetPayloadV2::scurve(90.0, 100.0, 500.0, 2000.0)
                .planner_request(30.0, 0.0),
        )
        .unwrap();
        j.set_model(Some((t, Box::new(plan))));
        assert_eq!(j.state_at(t).map(|s| s.0), Some(30.0), "the model's start");
        j.set_model(None);
        assert_eq!(j.state_at(t), Some((12.0, 5.0, 0.0)));
    }

    /// From its reports: carried forward at the acceleration the last two
    /// gave, to rest where the velocity would change sign, and not beyond
    /// 50 ms; from the bridge's model of its move while reports agree.
    #[test]
    fn where_a_joint_is_now_is_reckoned_from_its_reports_or_its_move() {
        let mut j = joint();
        let ms = Duration::from_millis;
        assert_eq!(j.state_at(ms(5)), None, "nothing reported");
        j.set_motion((10.0, 20.0), ms(100), 100.0);
        // 10 ms on: 10 + 20 * 0.01 + 100 * 0.01² / 2, 20 + 100 * 0.01.
        let (p, v, _) = j.state_at(ms(110)).unwrap();
        assert!(
            (p - 10.205).abs() < 1e-12 && (v - 21.0).abs() < 1e-12,
            "{p} {v}"
        );
        // Beyond 50 ms (reports missing): reckoned to 50 ms, then at that
        // velocity (25), up to half a second.
        let (p, v, _) = j.state_at(ms(250)).unwrap();
        assert!(
            (p - (10.0 + 1.125 + 25.0 * 0.1)).abs() < 1e-9 && (v - 25.0).abs() < 1e-9,
            "{p} {v}"
        );
        assert_eq!(
            j.state_at(ms(700)),
            j.state_at(ms(600)),
            "not beyond half a second"
        );
        // Braking at 1,000: at rest after 20 ms, 0.2 further on.
        j.set_motion((10.0, 20.0), ms(100), -1000.0);
        let (p, v, _) = j.state_at(ms(140)).unwrap();
        assert!((p - 10.2).abs() < 1e-12 && v == 0.0, "{p} {v}");
        // Reported at rest, the braking that brought it there reckoned
        // from the report before: at rest where it is, not moving back
        // (within 50 ms and beyond it).
        j.set_motion((0.0, 0.0), ms(100), -0.1);
        assert_eq!(j.state_at(ms(130)), Some((0.0, 0.0, 0.0)));
        assert_eq!(j.state_at(ms(400)), Some((0.0, 0.0, 0.0)));
        j.set_motion((10.0, 20.0), ms(100), -1000.0);
        // A model of its move: read from it, until a report disagrees.
        let plan = motorwire_planner::plan(
            &motorwire_irpc::SetTargetPayloadV2::scurve(90.0, 100.0, 500.0, 2000.0)
                .planner_request(0.0, 0.0),
        )
        .unwrap();
        let at = plan.sample(0.3);
        j.set_model(Some((ms(1000), Box::new(plan))));
        let (p, v, _) = j.state_at(ms(1300)).unwrap();
        assert!((p - at.position).abs() < 1e-9 && (v - at.velocity).abs() < 1e-9);
        assert_eq!(
            j.state_at(ms(10_000)),
            Some((90.0, 0.0, 0.0)),
            "at rest at its end"
        );
        j.check_model(ms(1300), at.position + 0.001, at.velocity);
        assert!(
            j.motion.model().is_some(),
            "a report within an f32's reach agrees"
        );
        j.check_model(ms(1300), at.position + 1.0, at.velocity);
        assert!(
            j.motion.model().is_none(),
            "a report 1 degree off sets the model aside"
        );
    }
}
