//! The Orion driver: the Orion arm controller (WIRE-FACTS §4.1), one JSON
//! object per line each way on a byte stream, as one link to all of its
//! motors.
//!
//! It owns the dialect's encoding (direct-control `DATA` with only the
//! keys whose value changes, since the controller remembers the rest; a
//! command, `MODE` 2: stop, fold, unfold), the link (the boot beacon, a
//! lost link, and the stop it writes first when the link comes back),
//! its one line in flight with its answer, resends and giving up, the
//! polls of an idle link, and the decoding of the controller's feedback
//! into WIA `MotorFeedback`. The engine decides what is sent and when,
//! and what an answer means for its jobs; this says how, and what came
//! back.
//!
//! - The controller answers every line: direct control with its feedback
//!   (`MODE` 1), a command with `CMDF` once it has run. The answer of the
//!   mode awaited acknowledges the line in flight (the controller answers
//!   in order); one of the other mode answers a line given up before, and
//!   is feedback only. A line unanswered within its timeout is sent again
//!   (a direct-control value set twice is set once), then its outcome is
//!   unknown.
//! - Nothing but a stop is sent before the boot beacon `{"ID":32}` is
//!   heard. While idle the driver asks for feedback with an empty `DATA`
//!   every [`POLL`], which also keeps the controller from being taken as
//!   silent.
//! - Lines heard again after the link was lost (or went silent): what the
//!   controller runs is unknown, so a stop goes first, and the motors are
//!   up again only once it is answered; nothing under way is resumed.

use super::DeviceError;
use std::collections::VecDeque;
use std::time::Duration;

use motorwire_can::retry::{Attempts, Expiry};
use motorwire_orion::{ArmCommand, Motor, MotorValues, Output};
use motorwire_translate::BusMap;
use motorwire_wia::MotorFeedback;

use super::{DeviceId, Ended, OrionOrder, Outcome};

/// The node id the bridge gives Orion motors: beyond CAN's 11 bits, so no
/// frame is ever taken for theirs.
pub(crate) const ORION_NODE: u16 = 0xFFFF;

/// The controller, as messages name it (its id is
/// [`motorwire_orion::CONTROLLER_ID`]).
pub(crate) const LABEL: &str = "the Orion arm controller (ID 32)";

/// How often an idle bridge asks the controller for its feedback.
pub const POLL: Duration = Duration::from_millis(100);

/// The longest line taken from the controller (bytes); its feedback is
/// under 300.
pub const MAX_ORION_LINE: usize = 4096;

/// Bad lines from the controller reported as events per second, at most;
/// the rest are counted, and the next event says how many were not
/// reported (a flooding controller cannot flood the bridge's output).
pub const MAX_BAD_LINE_EVENTS: u32 = 10;

/// `values` as a direct-control line (without its newline).
pub(crate) fn direct_control_line(values: &MotorValues) -> String {
    motorwire_orion::Input::DirectControl(*values).to_json()
}

/// `command` as a command-mode line (without its newline).
pub(crate) fn command_line(command: ArmCommand) -> String {
    motorwire_orion::Input::Command(command.into()).to_json()
}

/// A line to the controller waiting for its answer.
#[derive(Debug)]
struct Pending {
    msg_id: u32,
    /// The devices whose steps it carries (none: a poll, or a line whose
    /// steps were given up).
    joints: Vec<DeviceId>,
    line: String,
    /// The mode of the answer that acknowledges it.
    mode: u8,
    attempts: Attempts,
    /// The values the line sets (its answer must report each of them).
    sets: Vec<(Motor, f64)>,
}

/// A line of the driver's that ended: its number, the devices whose steps
/// it carried, how it ended and how many times it was sent.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Done {
    pub(crate) msg_id: u32,
    pub(crate) joints: Vec<DeviceId>,
    pub(crate) outcome: Outcome,
    pub(crate) attempts: u8,
}

impl Done {
    /// The request as the device layer says every request ended, at `at`.
    pub(crate) fn ended(&self, at: Duration) -> Ended {
        Ended {
            msg_id: self.msg_id,
            outcome: self.outcome.clone(),
            attempts: self.attempts,
            at,
        }
    }

    fn of(p: Pending, outcome: Outcome) -> Self {
        Self {
            msg_id: p.msg_id,
            joints: p.joints,
            outcome,
            attempts: p.attempts.sent(),
        }
    }
}

/// A line from the controller that is not one of its messages (or holds a
/// value that is not a number): counted; `report` is `Some(n)` when it is
/// to be reported now, with the number not reported before it
/// ([`MAX_BAD_LINE_EVENTS`] a second).
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct BadLine {
    pub(crate) error: String,
    pub(crate) report: Option<u64>,
}

/// What one of the controller's messages did, for the engine to act on.
#[derive(Debug, Default)]
pub(crate) struct Applied {
    /// A boot beacon: whether it was the first, and whether it is
    /// reported (the first, or one after the controller was commanded: it
    /// started again, every value 0).
    pub(crate) beacon: Option<(bool, bool)>,
    /// The feedback it carried, as WIA `MotorFeedback` of the map's motors
    /// (positions in each motor's own unit).
    pub(crate) feedback: Vec<MotorFeedback>,
    /// The line in flight it answered.
    pub(crate) done: Option<Done>,
    /// It answered the stop that makes a link heard again safe and known:
    /// once the engine has taken `done`, [`OrionDriver::end_recovery`].
    pub(crate) recovered: bool,
    /// It was no answer after all: a value in it is not a finite number.
    pub(crate) bad: Option<BadLine>,
}

/// The link to the controller, and its one line in flight.
#[derive(Debug)]
pub(crate) struct OrionDriver {
    /// The boot beacon was heard.
    ready: bool,
    /// Nothing more comes from the controller: nothing but a stop is sent.
    lost: bool,
    /// Lines came again after the link was lost: a stop was sent first,
    /// and until it is answered the motors stay offline.
    recovering: bool,
    pending: Option<Pending>,
    tx: VecDeque<String>,
    /// What the bridge last set each motor to, answered by the controller
    /// (never its feedback, which reports what the motor does now): a key
    /// whose new value equals it is not sent again, unless the value is 0
    /// (a stop always goes out).
    commanded: [Option<f64>; 7],
    /// Lines from the controller reported as bad in the current second,
    /// when that second began, and how many were not reported since.
    bad_in_window: u32,
    bad_window: Duration,
    bad_suppressed: u64,
    next_poll: Option<Duration>,
    next_id: u32,
    /// How long a line (a stop, a direct-control line, a poll) waits for
    /// its answer, and how many times it is sent again.
    timeout: Duration,
    retries: u8,
    /// How long a fold or unfold may take: it is answered once it has run.
    command_timeout: Duration,
}

impl OrionDriver {
    /// A driver whose lines wait `timeout` for their answer and are sent
    /// again up to `retries` times; a fold or unfold waits
    /// `command_timeout`, and is never sent again.
    pub(crate) const fn new(timeout: Duration, retries: u8, command_timeout: Duration) -> Self {
        Self {
            ready: false,
            lost: false,
            recovering: false,
            pending: None,
            tx: VecDeque::new(),
            commanded: [None; 7],
            bad_in_window: 0,
            bad_window: Duration::ZERO,
            bad_suppressed: 0,
            next_poll: None,
            next_id: 0,
            timeout,
            retries,
            command_timeout,
        }
    }

    /// Whether the link is lost (nothing is heard; only a stop is written).
    pub(crate) const fn lost(&self) -> bool {
        self.lost
    }

    /// Whether a line may go now (a stop always may).
    pub(crate) const fn free(&self) -> bool {
        self.ready && !self.lost && !self.recovering && self.pending.is_none()
    }

    /// Whether the controller's motors are up: its boot beacon heard, the
    /// link not lost, and a link that came back stopped.
    pub(crate) const fn up(&self) -> bool {
        self.ready && !self.recovering && !self.lost
    }

    /// Why the motors are offline now, if the link says so: before the
    /// boot beacon, and while a link that came back is being stopped.
    pub(crate) const fn offline_reason(&self) -> Option<&'static str> {
        if !self.ready {
            Some("the Orion arm controller has not sent its boot beacon")
        } else if self.recovering {
            Some("the link to the Orion arm controller came back, and its stop is not answered yet")
        } else if self.lost {
            Some("the link to the Orion arm controller is lost")
        } else {
            None
        }
    }

    /// Whether the controller may be polled now: also while the link is
    /// lost (a link that connects again answers, and is then stopped
    /// before anything else).
    const fn may_poll(&self) -> bool {
        self.ready && !self.recovering && self.pending.is_none()
    }

    /// The next deadline.
    pub(crate) fn deadline(&self) -> Option<Duration> {
        match &self.pending {
            Some(p) => Some(p.attempts.deadline()),
            None if self.recovering => Some(Duration::ZERO),
            None if self.ready => self.next_poll,
            None => None,
        }
    }

    /// The next line for the controller (without its newline).
    pub(crate) fn poll_line(&mut self) -> Option<String> {
        self.tx.pop_front()
    }

    /// Device `ji`'s step was given up: the answer to the line in flight
    /// no longer acknowledges it.
    pub(crate) fn forget(&mut self, ji: DeviceId) {
        if let Some(p) = self.pending.as_mut() {
            p.joints.retain(|&k| k != ji);
        }
    }

    /// The line waiting for its answer, if it was never handed out (its
    /// first sending still waits in the queue) and every device whose step
    /// it carries is `picked`: taken back (out of the queue, no answer
    /// awaited); the devices whose steps it carried. A line already handed
    /// out, or sent again, may have run, and stays.
    pub(crate) fn take_back_unsent(
        &mut self,
        picked: impl Fn(DeviceId) -> bool,
    ) -> Option<Vec<DeviceId>> {
        let p = self.pending.as_ref()?;
        if p.attempts.sent() != 1 || p.joints.is_empty() || !p.joints.iter().all(|&ji| picked(ji)) {
            return None;
        }
        let at = self.tx.iter().position(|l| *l == p.line)?;
        self.tx.remove(at);
        self.pending.take().map(|p| p.joints)
    }

    /// Whether one more bad line is reported now; counts it either way.
    fn bad(&mut self, now: Duration, error: String) -> BadLine {
        if now.saturating_sub(self.bad_window) >= Duration::from_secs(1) {
            self.bad_window = now;
            self.bad_in_window = 0;
        }
        let report = if self.bad_in_window >= MAX_BAD_LINE_EVENTS {
            self.bad_suppressed += 1;
            None
        } else {
            self.bad_in_window += 1;
            Some(std::mem::take(&mut self.bad_suppressed))
        };
        BadLine { error, report }
    }

    /// A line from the controller that could not be read (too long, not
    /// UTF-8): a bad line.
    pub(crate) fn unreadable(&mut self, now: Duration, reason: &str) -> BadLine {
        self.bad(now, reason.to_owned())
    }

    /// Why `order` cannot be written now, if it cannot: nothing is heard
    /// from a lost link, so only a stop is still written (in case the
    /// controller still reads; it cannot be answered).
    pub(crate) fn refuses(&self, order: OrionOrder) -> Option<DeviceError> {
        (self.lost && order != OrionOrder::Command(ArmCommand::Stop))
            .then_some(DeviceError::OrionLinkLost)
    }

    /// Writes one line for `orders` (devices and their orders, all of one
    /// kind: values to set, or one command) and awaits its answer. Returns
    /// the line's number.
    pub(crate) fn send(&mut self, now: Duration, orders: &[(DeviceId, OrionOrder)]) -> u32 {
        let first = orders
            .first()
            .map_or(OrionOrder::Command(ArmCommand::Stop), |&(_, o)| o);
        let (line, mode, timeout, retries) = match first {
            OrionOrder::Command(c) => {
                let (timeout, retries) = match c {
                    // A stop is quick and may be sent again.
                    ArmCommand::Stop => (self.timeout, self.retries),
                    // Fold and unfold are answered once they have run.
                    _ => (self.command_timeout, 0),
                };
                (command_line(c), 2, timeout, retries)
            }
            OrionOrder::Set(..) => {
                let mut values = MotorValues::new();
                for &(_, o) in orders {
                    if let OrionOrder::Set(m, v) = o
                        && (v == 0.0 || self.commanded.get(m.index()).copied().flatten() != Some(v))
                    {
                        values.set(m, v);
                    }
                }
                (direct_control_line(&values), 1, self.timeout, self.retries)
            }
        };
        let sets = orders
            .iter()
            .filter_map(|&(_, o)| match o {
                OrionOrder::Set(m, v) => Some((m, v)),
                OrionOrder::Command(_) => None,
            })
            .collect();
        let id = self.own_line(now, line, mode, timeout, retries);
        if let Some(p) = self.pending.as_mut() {
            p.joints = orders.iter().map(|&(ji, _)| ji).collect();
            p.sets = sets;
        }
        id
    }

    /// Writes a line and awaits its answer in `mode`: a poll or a
    /// recovery's stop (no device's step) unless [`OrionDriver::send`]
    /// gives it steps.
    fn own_line(
        &mut self,
        now: Duration,
        line: String,
        mode: u8,
        timeout: Duration,
        retries: u8,
    ) -> u32 {
        let id = self.next_id;
        self.next_id = self.next_id.wrapping_add(1);
        self.tx.push_back(line.clone());
        self.pending = Some(Pending {
            msg_id: id,
            joints: Vec::new(),
            line,
            mode,
            attempts: Attempts::first(now, timeout, retries),
            sets: Vec::new(),
        });
        id
    }

    /// One line from the controller, received at `now`, read: one of its
    /// messages, or a bad line. `offline`: the engine holds the
    /// controller's motors offline (it fell silent). Heard again after
    /// the link was lost or went silent, the driver first makes its state
    /// safe and known: a stop goes out, and the motors are up once it is
    /// answered.
    pub(crate) fn read(
        &mut self,
        now: Duration,
        line: &str,
        offline: bool,
    ) -> Result<Output, BadLine> {
        // The controller's lines are under 300 bytes: a longer one is not
        // parsed (a hostile one would cost every device's time).
        if line.len() > MAX_ORION_LINE {
            return Err(self.bad(now, format!("a line over {MAX_ORION_LINE} bytes")));
        }
        let output = Output::parse(line.trim()).map_err(|e| self.bad(now, e.to_string()))?;
        if (self.lost || (self.ready && offline)) && !self.recovering {
            self.lost = false;
            self.recovering = true;
            self.commanded = [None; 7];
            if self.pending.is_none() {
                self.recovery_stop(now);
            }
        }
        Ok(output)
    }

    /// What a message [`OrionDriver::read`] returned does: the beacon's
    /// link state, the feedback's values (decoded with `map`, stamped
    /// `timestamp_ms`), the answer to the line in flight.
    pub(crate) fn apply(
        &mut self,
        now: Duration,
        output: &Output,
        map: &BusMap,
        timestamp_ms: f64,
    ) -> Applied {
        let mut applied = Applied::default();
        match output {
            Output::Beacon => {
                let first = !self.ready;
                let reported = first || self.next_poll.is_some();
                if reported {
                    self.commanded = [None; 7];
                }
                applied.beacon = Some((first, reported));
                self.ready = true;
                // Its motors are up from its boot beacon on: a controller
                // that (re)started has every value at 0, its state known,
                // stopped or not.
                self.recovering = false;
                // Answered by the first poll, which ends the beacons.
                self.next_poll = Some(now);
            }
            Output::DirectControl(fb) => {
                let Ok(list) = motorwire_translate::feedback_from_orion(map, fb, timestamp_ms)
                else {
                    applied.bad = Some(self.bad(
                        now,
                        "feedback with a value that is not a finite number".to_owned(),
                    ));
                    return applied;
                };
                applied.feedback = list.into_iter().map(|t| t.value).collect();
                // It answers the line in flight only if it reports every
                // motor that line set.
                let answers = self.pending.as_ref().is_some_and(|p| {
                    p.mode == 1 && p.sets.iter().all(|(m, _)| fb.get(*m).is_some())
                });
                if answers {
                    if let Some(p) = self.pending.as_ref() {
                        for &(m, v) in &p.sets {
                            if let Some(slot) = self.commanded.get_mut(m.index()) {
                                *slot = Some(v);
                            }
                        }
                    }
                    applied.done = self.answered(now, 1, Outcome::Acked);
                }
            }
            Output::Command { succeeded } => {
                let outcome = if *succeeded {
                    Outcome::Acked
                } else {
                    Outcome::Nacked {
                        code: None,
                        why: "the controller answered CMDF 0: the command failed".to_owned(),
                        already_stopped: false,
                    }
                };
                applied.recovered = *succeeded
                    && self.recovering
                    && self
                        .pending
                        .as_ref()
                        .is_some_and(|p| p.mode == 2 && p.joints.is_empty());
                if self.pending.as_ref().is_some_and(|p| p.mode == 2) {
                    // Stop, fold and unfold leave the speeds and actuators
                    // at 0 and move the servo: send every value again.
                    self.commanded = [None; 7];
                }
                applied.done = self.answered(now, 2, outcome);
            }
        }
        applied
    }

    /// The stop that made a link heard again safe and known was answered
    /// (and its answer taken): the motors are up again, nothing resumed.
    pub(crate) const fn end_recovery(&mut self) {
        self.recovering = false;
    }

    /// An answer of `mode`: it acknowledges the line in flight if that
    /// awaits this mode.
    fn answered(&mut self, now: Duration, mode: u8, outcome: Outcome) -> Option<Done> {
        if self.pending.as_ref().is_none_or(|p| p.mode != mode) {
            return None;
        }
        let p = self.pending.take()?;
        self.next_poll = Some(now.saturating_add(POLL));
        Some(Done::of(p, outcome))
    }

    /// The link ended: nothing but a stop is written from now on, polls go
    /// on (a link that connects again answers), and the line in flight,
    /// if any, ends with an unknown outcome. `None` when it was lost
    /// already.
    pub(crate) fn link_lost(&mut self, now: Duration) -> Option<Option<Done>> {
        if self.lost {
            return None;
        }
        self.lost = true;
        self.recovering = false;
        self.next_poll = Some(now.saturating_add(POLL));
        Some(self.pending.take().map(|p| Done::of(p, Outcome::TimedOut)))
    }

    /// The line in flight past its deadline: sent again while it has
    /// retries (and device steps, and a link), else given up.
    pub(crate) fn expire(&mut self, now: Duration) -> Option<Done> {
        let p = self.pending.as_mut()?;
        // A poll or a line whose steps were given up is not repeated, nor
        // anything while the link is lost.
        let may_resend = !p.joints.is_empty() && !self.lost;
        match p.attempts.expire(now, may_resend) {
            Expiry::Waiting => return None,
            Expiry::Resend => {
                let line = p.line.clone();
                self.tx.push_back(line);
                return None;
            }
            Expiry::GiveUp => {}
        }
        let p = self.pending.take()?;
        self.next_poll = Some(now);
        Some(Done::of(p, Outcome::TimedOut))
    }

    /// The driver's own lines once nothing is in flight: a recovery's stop
    /// again, or, when the poll is due and `idle` (no device step waits
    /// for the link), a poll.
    pub(crate) fn housekeeping(&mut self, now: Duration, idle: bool) {
        if self.recovering && self.pending.is_none() {
            self.recovery_stop(now);
        }
        if self.may_poll() && idle && self.next_poll.is_some_and(|t| now >= t) {
            let timeout = self.timeout;
            self.own_line(now, direct_control_line(&MotorValues::new()), 1, timeout, 0);
            self.next_poll = None;
        }
    }

    /// The stop that makes a controller heard again safe and known: sent
    /// again (each time the one before went unanswered) until answered.
    fn recovery_stop(&mut self, now: Duration) {
        let timeout = self.timeout;
        self.own_line(now, command_line(ArmCommand::Stop), 2, timeout, 0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: Duration = Duration::from_millis(1);

    fn driver() -> OrionDriver {
        OrionDriver::new(100 * MS, 2, Duration::from_secs(30))
    }

    fn map() -> BusMap {
        BusMap::from_toml(
            r#"
[motors.turntable]
dialect = "orion"
key = "TRM"
"#,
        )
        .unwrap()
    }

    fn lines(d: &mut OrionDriver) -> Vec<String> {
        std::iter::from_fn(|| d.poll_line()).collect()
    }

    /// Before its beacon nothing is polled; the beacon brings the link up,
    /// and an idle link is polled at once, then every [`POLL`] after an
    /// answer.
    #[test]
    fn the_beacon_brings_the_link_up_and_an_idle_link_is_polled() {
        let mut d = driver();
        let m = map();
        assert_eq!(
            d.offline_reason(),
            Some("the Orion arm controller has not sent its boot beacon")
        );
        d.housekeeping(Duration::ZERO, true);
        assert_eq!(lines(&mut d), Vec::<String>::new());
        let out = d.read(5 * MS, r#"{"ID":32}"#, false).unwrap();
        let a = d.apply(5 * MS, &out, &m, 0.0);
        assert_eq!(a.beacon, Some((true, true)));
        assert!(d.up() && d.free());
        d.housekeeping(5 * MS, true);
        assert_eq!(lines(&mut d), [r#"{"ID":32,"MODE":1,"DATA":{}}"#]);
        assert_eq!(d.deadline(), Some(105 * MS));
    }

    /// A direct-control line carries only the values that change (and a
    /// 0 always); its answer must report every value it set.
    #[test]
    fn a_line_sets_what_changes_and_is_answered_by_feedback_reporting_it() {
        let mut d = driver();
        let m = map();
        let out = d.read(Duration::ZERO, r#"{"ID":32}"#, false).unwrap();
        d.apply(Duration::ZERO, &out, &m, 0.0);
        let id = d.send(
            MS,
            &[(DeviceId(3), OrionOrder::Set(Motor::Turntable, 200.0))],
        );
        assert_eq!(lines(&mut d), [r#"{"ID":32,"MODE":1,"DATA":{"TRM":200}}"#]);
        assert!(!d.free());
        let fb = d
            .read(
                2 * MS,
                r#"{"ID":32,"MODE":1,"DATA":{"TRMF":[200,0.5,0]}}"#,
                false,
            )
            .unwrap();
        let a = d.apply(2 * MS, &fb, &m, 1000.0);
        assert_eq!(
            a.done,
            Some(Done {
                msg_id: id,
                joints: vec![DeviceId(3)],
                outcome: Outcome::Acked,
                attempts: 1
            })
        );
        assert_eq!(a.feedback.len(), 1);
        assert_eq!(a.feedback[0].motor_id, "turntable");
        // The same value again is not sent; the line is an empty DATA.
        d.send(
            3 * MS,
            &[(DeviceId(3), OrionOrder::Set(Motor::Turntable, 200.0))],
        );
        assert_eq!(lines(&mut d), [r#"{"ID":32,"MODE":1,"DATA":{}}"#]);
    }

    /// Unanswered, a line is sent again up to its retries and then given
    /// up with an unknown outcome.
    #[test]
    fn an_unanswered_line_is_sent_again_then_given_up() {
        let mut d = driver();
        let m = map();
        let out = d.read(Duration::ZERO, r#"{"ID":32}"#, false).unwrap();
        d.apply(Duration::ZERO, &out, &m, 0.0);
        let id = d.send(
            Duration::ZERO,
            &[(DeviceId(1), OrionOrder::Set(Motor::Turntable, 50.0))],
        );
        lines(&mut d);
        assert_eq!(d.expire(100 * MS), None);
        assert_eq!(d.expire(200 * MS), None);
        assert_eq!(lines(&mut d).len(), 2, "sent twice more");
        assert_eq!(
            d.expire(300 * MS),
            Some(Done {
                msg_id: id,
                joints: vec![DeviceId(1)],
                outcome: Outcome::TimedOut,
                attempts: 3
            })
        );
        assert!(d.free());
    }

    /// A link heard again after it was lost writes a stop first and is
    /// up only once the stop is answered.
    #[test]
    fn a_link_heard_again_is_stopped_before_it_is_up() {
        let mut d = driver();
        let m = map();
        let out = d.read(Duration::ZERO, r#"{"ID":32}"#, false).unwrap();
        d.apply(Duration::ZERO, &out, &m, 0.0);
        assert_eq!(d.link_lost(MS), Some(None));
        assert_eq!(d.link_lost(2 * MS), None, "lost once");
        assert_eq!(
            d.refuses(OrionOrder::Set(Motor::Turntable, 1.0))
                .map(|e| e.to_string())
                .as_deref(),
            Some("the link to the Orion controller is lost")
        );
        assert_eq!(d.refuses(OrionOrder::Command(ArmCommand::Stop)), None);
        let fb = d
            .read(
                10 * MS,
                r#"{"ID":32,"MODE":1,"DATA":{"TRMF":[200,0.5,0]}}"#,
                false,
            )
            .unwrap();
        assert_eq!(lines(&mut d), [r#"{"ID":32,"MODE":2,"DATA":1}"#]);
        let a = d.apply(10 * MS, &fb, &m, 0.0);
        assert_eq!(a.done, None, "feedback does not answer the stop");
        assert!(!d.up());
        let cmdf = d
            .read(11 * MS, r#"{"ID":32,"MODE":2,"DATA":{"CMDF":1}}"#, false)
            .unwrap();
        let a = d.apply(11 * MS, &cmdf, &m, 0.0);
        assert!(a.recovered);
        assert_eq!(a.done.map(|d| d.joints), Some(vec![]));
        d.end_recovery();
        assert!(d.up());
    }

    /// The label names the controller by its id.
    #[test]
    fn the_label_names_the_controllers_id() {
        assert_eq!(
            LABEL,
            format!(
                "the Orion arm controller (ID {})",
                motorwire_orion::CONTROLLER_ID
            )
        );
    }

    /// Bad lines are counted; at most [`MAX_BAD_LINE_EVENTS`] a second are
    /// reported, and the next report says how many were not.
    #[test]
    fn bad_lines_are_reported_ten_a_second() {
        let mut d = driver();
        let reports: Vec<Option<u64>> = (0..12)
            .map(|_| d.read(MS, "garbage", false).unwrap_err().report)
            .collect();
        assert_eq!(reports[..10], [Some(0); 10]);
        assert_eq!(reports[10..], [None, None]);
        let long = "x".repeat(MAX_ORION_LINE + 1);
        let e = d.read(Duration::from_secs(2), &long, false).unwrap_err();
        assert_eq!(
            e,
            BadLine {
                error: "a line over 4096 bytes".to_owned(),
                report: Some(2)
            }
        );
    }
}
