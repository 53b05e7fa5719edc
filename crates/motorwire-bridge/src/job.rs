//! One job per input line (and per startup, stop, release and shutdown):
//! its per-joint steps and what became of each.

use std::collections::VecDeque;
use std::time::Duration;

use motorwire_irpc::Payload;
use motorwire_translate::Report;

use crate::device::DeviceId;
pub(crate) use crate::device::{AwaitKind, Lifecycle, Order};
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
    /// An axis of iRPC payloads for a joint.
    pub(crate) fn new(
        motor: String,
        joint: DeviceId,
        payloads: impl IntoIterator<Item = Payload>,
    ) -> Self {
        Self::of(motor, joint, payloads.into_iter().map(Order::Irpc))
    }

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

/// The open jobs by id, oldest first: a list kept in order of id (ids
/// only grow, so a new job goes at the end), looked up by halving. A job
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
}

impl Jobs {
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

    /// Opens job `id` (replacing one of that id, as a map would).
    pub(crate) fn insert(&mut self, id: u64, job: Box<Job>) {
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

    pub(crate) fn remove(&mut self, id: &u64) -> Option<Box<Job>> {
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

/// The axis `step` names, if its job is still open.
pub(crate) fn axis_mut(jobs: &mut Jobs, step: crate::joints::StepRef) -> Option<&mut Axis> {
    jobs.get_mut(&step.job)?.axes.get_mut(step.axis)
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
}
