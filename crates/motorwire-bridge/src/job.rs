//! One job per input line (and per startup, stop, release and shutdown):
//! its per-joint steps and what became of each.

use std::collections::VecDeque;
use std::time::Duration;

use motorwire_translate::Report;

use crate::device::DeviceId;
pub(crate) use crate::device::{AwaitKind, Lifecycle, Order};
use crate::joints::StepRef;
use crate::output::{Label, LineRef, Origin, StepOutcome, StepReport};

/// One input line's identity as it travels from its reading to its
/// result: who sent it, its number among their lines, and what its result
/// is labelled with (set once the line is read far enough to know).
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct LineMeta {
    pub(crate) origin: Origin,
    pub(crate) number: u64,
    pub(crate) label: Option<Label>,
    /// A setpoint of a stream (`"stream":true`): no completion line
    /// follows it, and a newer setpoint replacing it before it was sent is
    /// what a stream does, not a failure.
    pub(crate) stream: bool,
}

impl LineMeta {
    /// Line `number` of `origin`, not yet labelled.
    pub(crate) const fn new(origin: Origin, number: u64) -> Self {
        Self {
            origin,
            number,
            label: None,
            stream: false,
        }
    }

    /// The same line, labelled.
    pub(crate) fn labelled(&self, label: Label) -> Self {
        Self {
            label: Some(label),
            ..self.clone()
        }
    }

    /// The same line with `label` (when the line named one).
    pub(crate) fn with(&self, label: Option<Label>) -> Self {
        Self {
            label,
            ..self.clone()
        }
    }

    /// Its origin and number, as events name it.
    pub(crate) const fn at(&self) -> LineRef {
        LineRef {
            origin: self.origin,
            line: self.number,
        }
    }
}

/// What a job is for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum JobKind {
    /// A WIA command line.
    Command,
    /// Configure and activate every joint.
    Startup,
    /// An emergency stop: Deactivate every joint.
    EmergencyStop,
    /// The release: Activate the joints that were active.
    Release,
    /// The end: Deactivate every joint.
    Shutdown,
    /// The deadman stopping a device whose setpoint was not renewed.
    Deadman,
    /// A reset line: Reset, Configure and Activate for one joint.
    Reset,
}

impl JobKind {
    /// Jobs that go ahead of every queued step and cancel what is in flight.
    pub(crate) fn is_stop(self) -> bool {
        matches!(self, Self::EmergencyStop | Self::Shutdown)
    }
}

/// Where one axis of a job stands.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum AxisState {
    /// Waiting in its joint's queue.
    Queued,
    /// A request is in flight.
    InFlight {
        /// Its msg_id (for a compact command, the bridge's own number).
        msg_id: u32,
        /// What it asks.
        payload: Order,
    },
    /// Finished.
    Done(StepReport),
}

/// One joint's part of a job: its payloads, sent one after another.
#[derive(Debug)]
pub(crate) struct Axis {
    pub(crate) motor: String,
    /// The joint's device.
    pub(crate) joint: DeviceId,
    pub(crate) payloads: VecDeque<Order>,
    pub(crate) state: AxisState,
    /// Times the request in flight was sent, for the report.
    pub(crate) attempts: u8,
    /// A trajectory's: when each payload is due (bridge time), in order;
    /// empty for a command (sent one after another as they are acked).
    pub(crate) due: VecDeque<Duration>,
    /// A trajectory that loops forever: refilled from its cycle when it
    /// runs out, until a stop.
    pub(crate) cycle: Option<Cycle>,
    /// Something of it was sent (a trajectory whose start is still to
    /// come has sent nothing).
    pub(crate) begun: bool,
    /// The target of its last move (degrees), watched for arrival once
    /// acked.
    pub(crate) target: Option<f64>,
    /// `sync_mode: sequential`: the axis of the same job that must have
    /// arrived before this one is sent.
    pub(crate) after: Option<usize>,
    /// It has arrived at its target (watched while a later axis waits).
    pub(crate) arrived: bool,
    /// A later axis waits for it: past this, it did not arrive in time.
    pub(crate) arrive_by: Option<Duration>,
    /// Its requests acknowledged so far (a trajectory's segments).
    pub(crate) acked: u32,
    /// A step whose later payloads were replaced while one of them was in
    /// flight (a running trajectory by a newer position command, anything
    /// by a motor line): why. Once that payload is answered, the rest is
    /// not sent.
    pub(crate) replaced: Option<&'static str>,
}

/// Why a running trajectory's later segments were not sent.
pub(crate) const REPLACED_TRAJECTORY: &str = "a newer position command for the joint replaced the rest of the trajectory: its later segments were not sent";

impl Axis {
    /// An axis of orders; the target of a compact position command is set
    /// by the caller (it knows the motor's unit).
    pub(crate) fn of(
        motor: String,
        joint: DeviceId,
        orders: impl IntoIterator<Item = Order>,
    ) -> Self {
        let payloads: VecDeque<Order> = orders.into_iter().collect();
        let target = payloads.iter().rev().find_map(Order::own_target);
        Self {
            motor,
            joint,
            payloads,
            state: AxisState::Queued,
            attempts: 0,
            due: VecDeque::new(),
            cycle: None,
            begun: false,
            target,
            after: None,
            arrived: false,
            arrive_by: None,
            acked: 0,
            replaced: None,
        }
    }

    /// Its orders after the Activate the bridge puts before a freed
    /// joint's next motion (`Engine::activate_freed`): what the line asked.
    fn asked(&self) -> impl Iterator<Item = &Order> {
        self.payloads
            .iter()
            .skip_while(|o| o.lifecycle() == Some(Lifecycle::Activate))
    }

    /// The first order the line asked of it.
    pub(crate) fn first_asked(&self) -> Option<&Order> {
        self.asked().next()
    }

    /// The one order the line asked of it, if it asked one.
    fn one_asked(&self) -> Option<&Order> {
        let mut asked = self.asked();
        let one = asked.next()?;
        asked.next().is_none().then_some(one)
    }

    /// Whether it is one position move (behind a freed joint's Activate
    /// or not), which a newer one may replace while it waits.
    pub(crate) fn is_position_move(&self) -> bool {
        self.one_asked().is_some_and(Order::is_position_move)
    }

    /// Whether it is one setpoint (position, velocity or torque), which a
    /// stream's newer setpoint may replace while it waits.
    pub(crate) fn is_setpoint(&self) -> bool {
        self.one_asked().is_some_and(Order::is_setpoint)
    }

    pub(crate) fn finish(
        &mut self,
        outcome: StepOutcome,
        code: Option<u16>,
        message: impl Into<std::borrow::Cow<'static, str>>,
    ) {
        // Nothing of a finished axis is sent again: not its payloads, nor
        // a looping trajectory's next cycle.
        self.payloads.clear();
        self.cycle = None;
        self.state = AxisState::Done(StepReport {
            motor: self.motor.clone(),
            outcome,
            code,
            message: message.into(),
        });
    }

    /// Whether it is a trajectory under way: segments timed, or a cycle
    /// to come, and something of it sent.
    pub(crate) fn is_running_trajectory(&self) -> bool {
        self.begun && !self.is_done() && (!self.due.is_empty() || self.cycle.is_some())
    }

    pub(crate) fn is_done(&self) -> bool {
        matches!(self.state, AxisState::Done(_))
    }
}

/// One cycle of a trajectory that loops forever.
#[derive(Debug)]
pub(crate) struct Cycle {
    /// Its orders, each with its offset from the cycle's start.
    pub(crate) payloads: Vec<(Duration, Order)>,
    /// How long a cycle is.
    pub(crate) period: Duration,
    /// When the current cycle started.
    pub(crate) started: Duration,
}

/// One job.
#[derive(Debug)]
pub(crate) struct Job {
    /// The input line it serves (none for the bridge's own: startup, a
    /// deadman, a stop no line asked for, the shutdown).
    pub(crate) line: Option<LineMeta>,
    pub(crate) kind: JobKind,
    pub(crate) received: Duration,
    pub(crate) axes: Vec<Axis>,
    pub(crate) report: Report,
    /// Problems of a stop line, reported alongside.
    pub(crate) problems: Vec<String>,
    pub(crate) last_frame: Option<Duration>,
    pub(crate) unflushed: bool,
    /// Stop lines that came while this stop was under way: they ride on it
    /// and are answered with its outcome, so a flood of stops costs one
    /// Deactivate per joint, not one per line.
    pub(crate) riders: Vec<Rider>,
    /// Why a stop (or the end, a reset, a lost joint) cancelled some of it.
    pub(crate) cut: Option<String>,
    /// A request line: what it waits for once its request is acked.
    pub(crate) awaiting: Option<Awaiting>,
    /// What a request line got: `{"<kind>": {...}}`.
    pub(crate) data: Option<serde_json::Value>,
    /// Why a request line got nothing (or a calibration failed).
    pub(crate) data_error: Option<String>,
    /// A trajectory line: answered as soon as each motor's first segment
    /// is acknowledged (its later segments' fate comes in its completion
    /// line); when it was.
    pub(crate) answered: Option<Duration>,
    /// Whether an axis of it waits on another's arrival (`sync_mode`
    /// sequential): the jobs every reading of a device is looked at for.
    pub(crate) sequential: bool,
}

impl Job {
    /// A job of `kind` for `line` (`None`: the bridge's own), received at
    /// `received`: its axes, what its translation lost, a stop line's
    /// problems; nothing of it sent yet.
    pub(crate) fn new(
        line: Option<LineMeta>,
        kind: JobKind,
        received: Duration,
        axes: Vec<Axis>,
        report: Report,
        problems: Vec<String>,
    ) -> Self {
        Self {
            line,
            kind,
            received,
            sequential: axes.iter().any(|a| a.after.is_some()),
            axes,
            report,
            problems,
            last_frame: None,
            unflushed: false,
            riders: Vec::new(),
            cut: None,
            awaiting: None,
            data: None,
            data_error: None,
            answered: None,
        }
    }

    /// Whether it is a trajectory line, answered when it is under way.
    pub(crate) fn answers_early(&self) -> bool {
        self.kind == JobKind::Command && self.axes.iter().any(|a| !a.due.is_empty())
    }
}

/// A request line's wait.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Awaiting {
    pub(crate) joint: DeviceId,
    pub(crate) kind: AwaitKind,
    /// Past this, nothing came.
    pub(crate) deadline: Duration,
}

/// A stop line answered by a stop already under way.
#[derive(Debug)]
pub(crate) struct Rider {
    pub(crate) line: LineMeta,
    pub(crate) problems: Vec<String>,
    pub(crate) received: Duration,
}

impl Job {
    /// The number of the line it serves (0: none).
    pub(crate) fn number(&self) -> u64 {
        self.line.as_ref().map_or(0, |l| l.number)
    }

    /// The line it serves, as events name it.
    pub(crate) fn line_ref(&self) -> Option<LineRef> {
        self.line.as_ref().map(LineMeta::at)
    }

    /// Whether it serves a line of `origin`.
    pub(crate) fn is_of(&self, origin: Origin) -> bool {
        self.line.as_ref().is_some_and(|l| l.origin == origin)
    }

    pub(crate) fn is_done(&self) -> bool {
        // Cheapest first: a job is looked at after every event.
        !self.unflushed
            && self.axes.iter().all(Axis::is_done)
            && (self.awaiting.is_none()
                || self.axes.iter().any(
                    |a| matches!(&a.state, AxisState::Done(r) if r.outcome != StepOutcome::Acked),
                ))
    }
}

/// The open jobs by id, oldest first, and their own bookkeeping: the ids
/// they take, a newer step superseding what they hold, a waiting step
/// cancelled, the jobs done found and taken out (what needs the bridge,
/// the drivers and the outputs, stays with the bridge). A list kept in
/// order of id (ids only grow, so a new job goes at the end), looked up
/// by halving. A job
/// taken out leaves its place empty, and the list is closed up once more
/// than half of it is empty, so that a stop finishing a thousand jobs
/// moves the list a few times, not once for each. A bridge has a few
/// jobs open at a time and looks at them after every event, which a tree
/// of nodes does more slowly.
#[derive(Debug, Default)]
pub(crate) struct Jobs {
    list: Vec<(u64, Option<Box<Job>>)>,
    /// The places not empty.
    open: usize,
    /// The id the next job takes: each once, growing.
    next: u64,
}

/// What became of the step holding a device when a newer motion step
/// for it came ([`Jobs::supersede_running`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Running {
    /// It goes on.
    Kept,
    /// A trajectory scheduled to start later, not begun: it is not
    /// replaced, but leaves the device, to be queued behind the newer
    /// step.
    Rescheduled,
    /// A running trajectory, replaced: its later segments are not sent.
    /// `freed`: between segments, it ended now and frees the device; else
    /// it ends once its segment in flight is answered.
    Replaced { freed: bool },
}

impl Jobs {
    /// An id for a job about to be opened ([`Jobs::open`]): each once,
    /// growing (taken before the job is made, as its steps name it).
    pub(crate) fn new_id(&mut self) -> u64 {
        let id = self.next;
        self.next += 1;
        id
    }

    /// The id [`Jobs::new_id`] gives next.
    pub(crate) fn next_id(&self) -> u64 {
        self.next
    }

    /// Opens job `id` (one [`Jobs::new_id`] gave).
    pub(crate) fn open(&mut self, id: u64, job: Box<Job>) {
        debug_assert!(id < self.next, "job {id} opened without its id taken");
        self.insert(id, job);
    }

    /// The axis `step` names, if its job is still open.
    pub(crate) fn axis(&self, step: StepRef) -> Option<&Axis> {
        self.get(&step.job)?.axes.get(step.axis)
    }

    /// The axis `step` names, if its job is still open.
    pub(crate) fn axis_mut(&mut self, step: StepRef) -> Option<&mut Axis> {
        self.get_mut(&step.job)?.axes.get_mut(step.axis)
    }

    /// A newer motion step (a position move or a stream's setpoint:
    /// `replaces`; a stream's: `stream`) is about to go on the device
    /// step `s` waits for: whether `s`, a command's step not sent, is
    /// replaced by it (then finished as superseded, saying why). A
    /// position move is replaced by a newer position move; any setpoint
    /// by a stream's; an axis of a sequential line waiting for its turn
    /// by any newer motion (it would hold the device for another motor's
    /// arrival).
    pub(crate) fn supersede_waiting(&mut self, s: StepRef, stream: bool, replaces: bool) -> bool {
        let Some(a) = self
            .get_mut(&s.job)
            .filter(|job| job.kind == JobKind::Command)
            .and_then(|job| job.axes.get_mut(s.axis))
        else {
            return false;
        };
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
    }

    /// A newer motion step (a position move or a stream's setpoint:
    /// `replaces`) is about to go on the device step `running` holds:
    /// what becomes of `running`. A command's trajectory scheduled to
    /// start later and not begun is rescheduled; one under way is replaced
    /// by a step that `replaces`; anything else goes on.
    pub(crate) fn supersede_running(&mut self, running: StepRef, replaces: bool) -> Running {
        let Some(a) = self
            .get_mut(&running.job)
            .filter(|job| job.kind == JobKind::Command)
            .and_then(|job| job.axes.get_mut(running.axis))
        else {
            return Running::Kept;
        };
        if a.state == AxisState::Queued && !a.begun && !a.due.is_empty() {
            return Running::Rescheduled;
        }
        if !replaces || !a.is_running_trajectory() {
            return Running::Kept;
        }
        if a.state == AxisState::Queued {
            a.finish(StepOutcome::Superseded, None, REPLACED_TRAJECTORY);
            Running::Replaced { freed: true }
        } else {
            a.replaced = Some(REPLACED_TRAJECTORY);
            Running::Replaced { freed: false }
        }
    }

    /// Cancels step `s`, waiting for its device (cut by `why`): never
    /// sent, and its job says why. `Some(line)` where its job was open:
    /// the line it serves, if any.
    pub(crate) fn cancel_waiting(&mut self, s: StepRef, why: &str) -> Option<Option<LineRef>> {
        let job = self.get_mut(&s.job)?;
        let a = job.axes.get_mut(s.axis)?;
        a.finish(
            StepOutcome::Cancelled,
            None,
            format!("{why} before it was sent"),
        );
        job.cut.get_or_insert_with(|| why.to_owned());
        Some(job.line_ref())
    }

    /// When the first request line's answer is overdue, if one waits.
    pub(crate) fn answer_due(&self) -> Option<Duration> {
        self.values()
            .filter_map(|j| j.awaiting.map(|a| a.deadline))
            .min()
    }

    /// The ids of the jobs done, to be answered, oldest first.
    pub(crate) fn finished(&self) -> impl Iterator<Item = u64> + '_ {
        self.iter().filter(|(_, j)| j.is_done()).map(|(id, _)| *id)
    }

    /// Takes job `id` out, to be answered (`None`: it was taken already).
    pub(crate) fn close(&mut self, id: u64) -> Option<Box<Job>> {
        self.remove(&id)
    }

    fn at(&self, id: u64) -> Result<usize, usize> {
        self.list.binary_search_by_key(&id, |(i, _)| *i)
    }

    pub(crate) fn get(&self, id: &u64) -> Option<&Job> {
        let i = self.at(*id).ok()?;
        self.list.get(i)?.1.as_deref()
    }

    pub(crate) fn get_mut(&mut self, id: &u64) -> Option<&mut Job> {
        let i = self.at(*id).ok()?;
        self.list.get_mut(i)?.1.as_deref_mut()
    }

    /// Puts job `id` in (replacing one of that id, as a map would).
    fn insert(&mut self, id: u64, job: Box<Job>) {
        if self.list.last().is_none_or(|(last, _)| *last < id) {
            self.list.push((id, Some(job)));
            self.open += 1;
            return;
        }
        match self.at(id) {
            Ok(i) => {
                if let Some(slot) = self.list.get_mut(i) {
                    if slot.1.is_none() {
                        self.open += 1;
                    }
                    slot.1 = Some(job);
                }
            }
            Err(i) => {
                self.list.insert(i, (id, Some(job)));
                self.open += 1;
            }
        }
    }

    fn remove(&mut self, id: &u64) -> Option<Box<Job>> {
        let i = self.at(*id).ok()?;
        let job = self.list.get_mut(i)?.1.take()?;
        self.open -= 1;
        if self.open == 0 {
            self.list.clear();
        } else if self.list.len() > 2 * self.open + 8 {
            self.list.retain(|(_, j)| j.is_some());
        }
        Some(job)
    }

    pub(crate) fn is_empty(&self) -> bool {
        self.open == 0
    }

    /// Each job with its id, oldest first.
    pub(crate) fn iter(&self) -> impl DoubleEndedIterator<Item = (&u64, &Job)> {
        self.list
            .iter()
            .filter_map(|(i, j)| Some((i, j.as_deref()?)))
    }

    /// Each job with its id, oldest first.
    pub(crate) fn iter_mut(&mut self) -> impl DoubleEndedIterator<Item = (&u64, &mut Job)> {
        self.list
            .iter_mut()
            .filter_map(|(i, j)| Some((&*i, j.as_deref_mut()?)))
    }

    pub(crate) fn values(&self) -> impl DoubleEndedIterator<Item = &Job> {
        self.list.iter().filter_map(|(_, j)| j.as_deref())
    }

    pub(crate) fn values_mut(&mut self) -> impl DoubleEndedIterator<Item = &mut Job> {
        self.list.iter_mut().filter_map(|(_, j)| j.as_deref_mut())
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn job(received_ms: u64) -> Box<Job> {
        Box::new(Job::new(
            None,
            JobKind::Command,
            Duration::from_millis(received_ms),
            Vec::new(),
            Report::default(),
            Vec::new(),
        ))
    }

    fn ids(jobs: &Jobs) -> Vec<(u64, u64)> {
        jobs.iter()
            .map(|(id, j)| (*id, u64::try_from(j.received.as_millis()).unwrap()))
            .collect()
    }

    /// Thousands of jobs opened and finished in a scrambled order, and
    /// all finished at once as a stop finishes them: the same jobs, in
    /// the same order, as a map keeps.
    #[test]
    fn jobs_agree_with_a_map_however_many_and_in_any_order() {
        let mut jobs = Jobs::default();
        let mut map = std::collections::BTreeMap::new();
        let mut next = 0u64;
        let mut x = 0x9E37_79B9_7F4A_7C15u64;
        for round in 0..20_000u64 {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            if !x.is_multiple_of(3) || map.is_empty() {
                jobs.insert(next, job(next));
                map.insert(next, next);
                next += 1;
            } else {
                let id = x % next;
                assert_eq!(
                    jobs.remove(&id).map(|j| j.received),
                    map.remove(&id).map(Duration::from_millis),
                    "remove {id} in round {round}"
                );
            }
            if round.is_multiple_of(997) {
                assert_eq!(
                    ids(&jobs),
                    map.iter().map(|(k, v)| (*k, *v)).collect::<Vec<_>>()
                );
            }
        }
        assert!(jobs.list.len() <= 2 * jobs.open + 8);
        let all: Vec<u64> = map.keys().copied().collect();
        for id in all {
            assert_eq!(
                jobs.remove(&id).unwrap().received,
                Duration::from_millis(id)
            );
            assert!(jobs.get(&id).is_none());
        }
        assert!(jobs.is_empty() && jobs.list.is_empty());
    }

    #[test]
    fn jobs_are_kept_by_id_as_a_map_keeps_them() {
        let mut jobs = Jobs::default();
        assert!(jobs.is_empty());
        for id in [3, 5, 9] {
            jobs.insert(id, job(id * 10));
        }
        // Out of order, and over an id already open.
        jobs.insert(4, job(40));
        jobs.insert(1, job(10));
        jobs.insert(5, job(55));
        assert_eq!(ids(&jobs), [(1, 10), (3, 30), (4, 40), (5, 55), (9, 90)]);
        assert_eq!(jobs.get(&4).unwrap().received, Duration::from_millis(40));
        assert!(jobs.get(&2).is_none() && jobs.get(&10).is_none());
        jobs.get_mut(&9).unwrap().unflushed = true;
        assert!(jobs.values().filter(|j| j.unflushed).count() == 1);
        assert_eq!(jobs.remove(&3).unwrap().received, Duration::from_millis(30));
        assert!(jobs.remove(&3).is_none());
        assert_eq!(
            jobs.values_mut()
                .rev()
                .map(|j| j.received.as_millis())
                .collect::<Vec<_>>(),
            [90, 55, 40, 10]
        );
        for id in [1, 4, 5, 9] {
            jobs.remove(&id).unwrap();
        }
        assert!(jobs.is_empty());
    }

    /// A request line's answer is due at the earliest of the waits.
    #[test]
    fn the_first_answer_waited_for_is_due() {
        let mut jobs = Jobs::default();
        assert_eq!(jobs.answer_due(), None);
        for ms in [None, Some(300), Some(120)] {
            let id = jobs.new_id();
            jobs.open(id, move_job(JobKind::Command, "elbow", None));
            jobs.get_mut(&id).unwrap().awaiting = ms.map(|ms| Awaiting {
                joint: DeviceId::at(0),
                kind: AwaitKind::Telemetry,
                deadline: Duration::from_millis(ms),
            });
        }
        assert_eq!(jobs.answer_due(), Some(Duration::from_millis(120)));
        jobs.get_mut(&2).unwrap().awaiting = None;
        assert_eq!(jobs.answer_due(), Some(Duration::from_millis(300)));
    }

    /// A command's job of one axis moving `motor` (a position move), for
    /// line `number` of client 2 where one is given.
    fn move_job(kind: JobKind, motor: &str, number: Option<u64>) -> Box<Job> {
        let order = Order::Irpc(motorwire_irpc::Payload::SetTarget(
            motorwire_irpc::SetTargetPayload {
                target_angle: 10.0,
                velocity_limit: 5.0,
            },
        ));
        let axis = Axis::of(motor.to_owned(), DeviceId::at(0), [order]);
        Box::new(Job::new(
            number.map(|n| LineMeta::new(Origin(2), n)),
            kind,
            Duration::ZERO,
            vec![axis],
            Report::default(),
            Vec::new(),
        ))
    }

    fn step(job: u64) -> StepRef {
        StepRef { job, axis: 0 }
    }

    fn done(motor: &str, outcome: StepOutcome, message: &'static str) -> AxisState {
        AxisState::Done(StepReport {
            motor: motor.to_owned(),
            outcome,
            code: None,
            message: message.into(),
        })
    }

    /// Ids are taken before a job is opened, each once and growing; a job
    /// opened late (after one taken later) keeps its place by id.
    #[test]
    fn jobs_open_with_the_ids_they_took() {
        let mut jobs = Jobs::default();
        assert_eq!(jobs.next_id(), 0);
        let (a, b) = (jobs.new_id(), jobs.new_id());
        assert_eq!((a, b, jobs.next_id()), (0, 1, 2));
        jobs.open(b, move_job(JobKind::Command, "wrist", Some(4)));
        jobs.open(a, move_job(JobKind::Command, "elbow", Some(3)));
        let open: Vec<(u64, &str)> = jobs
            .iter()
            .map(|(id, j)| (*id, j.axes[0].motor.as_str()))
            .collect();
        assert_eq!(open, [(0, "elbow"), (1, "wrist")]);
        assert_eq!(jobs.axis(step(1)).unwrap().motor, "wrist");
        assert!(jobs.axis(StepRef { job: 1, axis: 1 }).is_none());
        assert!(jobs.axis(step(2)).is_none());
        assert_eq!(jobs.new_id(), 2);
    }

    /// A waiting position move is replaced by a newer one, a setpoint by a
    /// stream's, a sequential axis waiting for its turn by any motion; a
    /// stop's step, one sent, or one replaced already is not.
    #[test]
    fn a_waiting_step_is_superseded_by_what_replaces_it() {
        let mut jobs = Jobs::default();
        for kind in [JobKind::Command, JobKind::EmergencyStop, JobKind::Command] {
            let id = jobs.new_id();
            jobs.open(id, move_job(kind, "elbow", None));
        }
        // Neither a position move replacing it nor a stream's setpoint.
        assert!(!jobs.supersede_waiting(step(0), false, false));
        assert_eq!(jobs.axis(step(0)).unwrap().state, AxisState::Queued);
        assert!(jobs.supersede_waiting(step(0), false, true));
        assert_eq!(
            jobs.axis(step(0)).unwrap().state,
            done(
                "elbow",
                StepOutcome::Superseded,
                "a newer position command for the joint replaced it before it was sent"
            )
        );
        // Finished already: not again.
        assert!(!jobs.supersede_waiting(step(0), true, true));
        // A stop's step.
        assert!(!jobs.supersede_waiting(step(1), true, true));
        assert_eq!(jobs.axis(step(1)).unwrap().state, AxisState::Queued);
        // A stream's setpoint.
        assert!(jobs.supersede_waiting(step(2), true, false));
        assert_eq!(
            jobs.axis(step(2)).unwrap().state,
            done(
                "elbow",
                StepOutcome::Superseded,
                "a newer setpoint of a stream for the motor replaced it before it was sent"
            )
        );
        // A sequential axis waiting for its turn, by any motion.
        let id = jobs.new_id();
        jobs.open(id, move_job(JobKind::Command, "wrist", None));
        jobs.axis_mut(step(id)).unwrap().after = Some(1);
        assert!(jobs.supersede_waiting(step(id), false, false));
        assert_eq!(
            jobs.axis(step(id)).unwrap().state,
            done(
                "wrist",
                StepOutcome::Superseded,
                "a newer line for the motor replaced it while it waited for its turn"
            )
        );
        // A job taken out already.
        assert!(!jobs.supersede_waiting(step(9), true, true));
    }

    /// The step holding a device: a trajectory scheduled and not begun is
    /// rescheduled; one under way is replaced by a position move (ended
    /// now between segments, after its segment in flight otherwise);
    /// anything else goes on.
    #[test]
    fn a_running_trajectory_is_superseded_by_a_position_move() {
        let mut jobs = Jobs::default();
        for _ in 0..3 {
            let id = jobs.new_id();
            jobs.open(id, move_job(JobKind::Command, "elbow", None));
            jobs.axis_mut(step(id))
                .unwrap()
                .due
                .push_back(Duration::from_millis(50));
        }
        // A move, not a trajectory: goes on.
        let id = jobs.new_id();
        jobs.open(id, move_job(JobKind::Command, "elbow", None));
        assert_eq!(jobs.supersede_running(step(id), true), Running::Kept);
        // Scheduled, not begun.
        assert_eq!(jobs.supersede_running(step(0), true), Running::Rescheduled);
        assert_eq!(jobs.axis(step(0)).unwrap().state, AxisState::Queued);
        // Begun, between segments.
        jobs.axis_mut(step(1)).unwrap().begun = true;
        assert_eq!(jobs.supersede_running(step(1), false), Running::Kept);
        assert_eq!(
            jobs.supersede_running(step(1), true),
            Running::Replaced { freed: true }
        );
        assert_eq!(
            jobs.axis(step(1)).unwrap().state,
            done("elbow", StepOutcome::Superseded, REPLACED_TRAJECTORY)
        );
        // Begun, a segment in flight: it ends once that is answered.
        let a = jobs.axis_mut(step(2)).unwrap();
        a.begun = true;
        let payload = a.payloads.pop_front().unwrap();
        a.state = AxisState::InFlight { msg_id: 3, payload };
        assert_eq!(
            jobs.supersede_running(step(2), true),
            Running::Replaced { freed: false }
        );
        let a = jobs.axis(step(2)).unwrap();
        assert_eq!(a.replaced, Some(REPLACED_TRAJECTORY));
        assert!(matches!(a.state, AxisState::InFlight { msg_id: 3, .. }));
        assert_eq!(jobs.supersede_running(step(9), true), Running::Kept);
    }

    /// A waiting step cancelled is never sent: its job says the first
    /// reason it was cut, and the line it serves is named.
    #[test]
    fn a_waiting_step_is_cancelled_with_its_line_named() {
        let mut jobs = Jobs::default();
        for number in [Some(9), None] {
            let id = jobs.new_id();
            jobs.open(id, move_job(JobKind::Command, "elbow", number));
        }
        assert_eq!(
            jobs.cancel_waiting(step(0), "cancelled by the stop"),
            Some(Some(LineRef {
                origin: Origin(2),
                line: 9
            }))
        );
        assert_eq!(
            jobs.axis(step(0)).unwrap().state,
            done(
                "elbow",
                StepOutcome::Cancelled,
                "cancelled by the stop before it was sent"
            )
        );
        assert_eq!(
            jobs.get(&0).unwrap().cut.as_deref(),
            Some("cancelled by the stop")
        );
        // The bridge's own job: no line; its first reason kept.
        assert_eq!(jobs.cancel_waiting(step(1), "first"), Some(None));
        jobs.axis_mut(step(1)).unwrap().state = AxisState::Queued;
        assert_eq!(jobs.cancel_waiting(step(1), "second"), Some(None));
        assert_eq!(jobs.get(&1).unwrap().cut.as_deref(), Some("first"));
        assert_eq!(jobs.cancel_waiting(step(9), "gone"), None);
        assert_eq!(
            jobs.cancel_waiting(StepRef { job: 0, axis: 1 }, "gone"),
            None
        );
    }

    /// The jobs done are found oldest first, and each is taken out once.
    #[test]
    fn finished_jobs_are_found_and_closed_once() {
        let mut jobs = Jobs::default();
        for _ in 0..3 {
            let id = jobs.new_id();
            jobs.open(id, move_job(JobKind::Command, "elbow", None));
        }
        assert_eq!(jobs.finished().count(), 0);
        for id in [2, 0] {
            jobs.axis_mut(step(id))
                .unwrap()
                .finish(StepOutcome::Acked, None, "acked");
        }
        // Not flushed yet: not done.
        jobs.get_mut(&2).unwrap().unflushed = true;
        assert_eq!(jobs.finished().collect::<Vec<_>>(), [0]);
        jobs.get_mut(&2).unwrap().unflushed = false;
        assert_eq!(jobs.finished().collect::<Vec<_>>(), [0, 2]);
        assert_eq!(jobs.close(0).unwrap().axes[0].motor, "elbow");
        assert!(jobs.close(0).is_none());
        assert_eq!(jobs.finished().collect::<Vec<_>>(), [2]);
        jobs.close(2).unwrap();
        assert_eq!(jobs.iter().map(|(id, _)| *id).collect::<Vec<_>>(), [1]);
        assert!(!jobs.is_empty());
    }
}
