//! The Orion arm controller behind the bridge (WIRE-FACTS §4.1): one JSON
//! object per line each way on a byte stream.
//!
//! - The map's Orion motors are devices of the bridge like joints: gated,
//!   queued, stopped, watched by the deadman. Their orders become lines to
//!   the one controller, one line in flight at a time: direct-control
//!   `DATA` with only the keys whose value changes (the controller
//!   remembers the rest), or a command (`MODE` 2: stop, fold, unfold).
//! - Orders of one input line for several Orion motors go out as one
//!   `DATA` line; a stop for all of them is one stop command.
//! - The controller answers every line: direct control with its feedback
//!   (`MODE` 1), a command with `CMDF` once it has run. The answer of the
//!   mode awaited acknowledges the line in flight (the controller answers
//!   in order); one of the other mode answers a line given up before, and
//!   is feedback only. A line unanswered within the Ack timeout is sent
//!   again (a direct-control value set twice is set once), then its
//!   outcome is unknown.
//! - Nothing but a stop is sent before the boot beacon `{"ID":32}` is
//!   heard. While idle the bridge asks for feedback with an empty `DATA`
//!   every [`POLL`], which also keeps the controller from being taken as
//!   silent.
//! - An emergency stop goes out at once, whatever is in flight.

use std::collections::VecDeque;
use std::time::Duration;

use motorwire_can::client::Outcome;
use motorwire_irpc::NackCode;
use motorwire_orion::{ArmCommand, CONTROLLER_ID, Motor, MotorValues, Output, Quantity};
use motorwire_translate::Report;

use super::Bridge;
use crate::job::{Axis, AxisState, Order, OrionOrder};
use crate::joints::StepRef;
use crate::output::{Event, Output as BridgeOutput};

/// The node id the bridge gives Orion motors: beyond CAN's 11 bits, so no
/// frame is ever taken for theirs.
pub(crate) const ORION_NODE: u16 = 0xFFFF;

/// How often an idle bridge asks the controller for its feedback.
pub const POLL: Duration = Duration::from_millis(100);

/// The longest line taken from the controller (bytes); its feedback is
/// under 300.
pub const MAX_ORION_LINE: usize = 4096;

/// Bad lines from the controller reported as events per second, at most;
/// the rest are counted, and the next event says how many were not
/// reported (a flooding controller cannot flood the bridge's output).
pub const MAX_BAD_LINE_EVENTS: u32 = 10;

/// A line to the controller waiting for its answer.
#[derive(Debug)]
pub(super) struct Pending {
    msg_id: u32,
    /// The devices whose steps it carries (none: a poll, or a line whose
    /// steps were given up).
    joints: Vec<usize>,
    line: String,
    /// The mode of the answer that acknowledges it.
    mode: u8,
    attempts: u8,
    retries: u8,
    timeout: Duration,
    deadline: Duration,
    /// The values the line sets (its answer must report each of them).
    sets: Vec<(Motor, f64)>,
}

impl Pending {
    /// Device `ji`'s step was given up: the answer no longer acknowledges
    /// it.
    pub(super) fn forget(&mut self, ji: usize) {
        self.joints.retain(|&k| k != ji);
    }
}

/// The link to the controller.
#[derive(Debug, Default)]
pub(super) struct Link {
    /// The boot beacon was heard.
    ready: bool,
    /// Nothing more comes from the controller: nothing but a stop is sent.
    lost: bool,
    /// Lines came again after the link was lost: a stop was sent first,
    /// and until it is answered the motors stay offline.
    recovering: bool,
    pub(super) pending: Option<Pending>,
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
}

impl Link {
    /// Whether the bridge should report one more bad line now (at most
    /// [`MAX_BAD_LINE_EVENTS`] a second); `Some(n)` with the number not
    /// reported before it.
    fn report_bad(&mut self, now: Duration) -> Option<u64> {
        if now.saturating_sub(self.bad_window) >= Duration::from_secs(1) {
            self.bad_window = now;
            self.bad_in_window = 0;
        }
        if self.bad_in_window >= MAX_BAD_LINE_EVENTS {
            self.bad_suppressed += 1;
            return None;
        }
        self.bad_in_window += 1;
        Some(std::mem::take(&mut self.bad_suppressed))
    }

    /// Whether a line may go now (a stop always may).
    pub(super) fn free(&self) -> bool {
        self.ready && !self.lost && !self.recovering && self.pending.is_none()
    }

    /// Whether the controller may be polled now: also while the link is
    /// lost (a link that connects again answers, and is then stopped
    /// before anything else).
    fn may_poll(&self) -> bool {
        self.ready && !self.recovering && self.pending.is_none()
    }

    /// The line waiting for its answer, if it was never handed out (its
    /// first sending still waits in the queue) and every device whose step
    /// it carries is `picked`: taken back (out of the queue, no answer
    /// awaited); the devices whose steps it carried. A line already handed
    /// out, or sent again, may have run, and stays.
    pub(super) fn take_back_unsent(
        &mut self,
        picked: impl Fn(usize) -> bool,
    ) -> Option<Vec<usize>> {
        let p = self.pending.as_ref()?;
        if p.attempts != 1 || p.joints.is_empty() || !p.joints.iter().all(|&ji| picked(ji)) {
            return None;
        }
        let at = self.tx.iter().position(|l| *l == p.line)?;
        self.tx.remove(at);
        self.pending.take().map(|p| p.joints)
    }

    /// The next deadline.
    pub(super) fn deadline(&self) -> Option<Duration> {
        match &self.pending {
            Some(p) => Some(p.deadline),
            None if self.recovering => Some(Duration::ZERO),
            None if self.ready => self.next_poll,
            None => None,
        }
    }
}

fn line_of(values: &MotorValues) -> String {
    motorwire_orion::Input::DirectControl(*values).to_json()
}

impl Bridge {
    /// Whether device `ji` is an Orion motor.
    pub(super) fn is_orion(&self, ji: usize) -> bool {
        self.joints.get(ji).is_some_and(|j| j.orion.is_some())
    }

    /// Whether `step` is a sequential line's axis whose earlier axis has
    /// not arrived: it cannot go yet, so it does not keep the controller
    /// from being polled (unpolled, the controller would fall silent).
    fn after_earlier_axis(&self, step: StepRef) -> bool {
        self.jobs
            .get(&step.job)
            .and_then(|job| {
                let before = job.axes.get(job.axes.get(step.axis)?.after?)?;
                Some(!before.arrived)
            })
            .unwrap_or(false)
    }

    /// Whether `step`, waiting for an Orion motor, may be sent now.
    pub(super) fn orion_may_send(&self, step: StepRef) -> bool {
        let Some(job) = self.jobs.get(&step.job) else {
            return true;
        };
        // Nothing to send (startup has nothing for the controller), or a
        // stop: it goes now.
        let orders = job
            .axes
            .get(step.axis)
            .is_some_and(|a| matches!(a.payloads.front(), Some(Order::Orion(_))));
        !orders || job.kind.is_stop() || self.orion.lost || self.orion.free()
    }

    /// Sends `order` of `step` for Orion motor `ji`, with the orders of
    /// the same job waiting at the front of the other Orion motors (one
    /// line for one input line). Returns the line's number.
    pub(super) fn orion_send(
        &mut self,
        now: Duration,
        ji: usize,
        step: StepRef,
        order: OrionOrder,
    ) -> Result<u32, String> {
        // Nothing is heard from a lost link; a stop is still written, in
        // case the controller still reads (it cannot be answered).
        if self.orion.lost && order != OrionOrder::Command(ArmCommand::Stop) {
            return Err("the link to the Orion controller is lost".to_owned());
        }
        let id = self.orion.next_id;
        self.orion.next_id = self.orion.next_id.wrapping_add(1);
        // Others of the same job, same kind of order.
        let mut joints = vec![ji];
        let mut orders = vec![order];
        for k in 0..self.joints.len() {
            if k == ji {
                continue;
            }
            let Some(j) = self.joints.get(k) else {
                continue;
            };
            if j.orion.is_none() || j.busy.is_some() {
                continue;
            }
            let Some(&front) = j.queue.front() else {
                continue;
            };
            if front.job != step.job {
                continue;
            }
            let Some(a) = self
                .jobs
                .get_mut(&front.job)
                .and_then(|job| job.axes.get_mut(front.axis))
            else {
                continue;
            };
            let fits = match (a.payloads.front(), order) {
                (Some(Order::Orion(OrionOrder::Set(..))), OrionOrder::Set(..)) => a.after.is_none(),
                (Some(Order::Orion(OrionOrder::Command(c))), OrionOrder::Command(d)) => *c == d,
                _ => false,
            };
            if !fits || !a.due.is_empty() {
                continue;
            }
            let Some(payload) = a.payloads.pop_front() else {
                continue;
            };
            a.begun = true;
            if let Order::Orion(o) = payload {
                orders.push(o);
            }
            a.state = AxisState::InFlight {
                msg_id: id,
                payload,
            };
            a.attempts = 1;
            if let Some(j) = self.joints.get_mut(k) {
                j.queue.pop_front();
                j.busy = Some(front);
            }
            joints.push(k);
        }
        let (line, mode, timeout, retries) = match order {
            OrionOrder::Command(c) => {
                let (timeout, retries) = match c {
                    // A stop is quick and may be sent again.
                    ArmCommand::Stop => (self.config.client.timeout, self.config.client.retries),
                    // Fold and unfold are answered once they have run.
                    _ => (self.config.orion_command_timeout, 0),
                };
                let line = motorwire_orion::Input::Command(c.into()).to_json();
                (line, 2, timeout, retries)
            }
            OrionOrder::Set(..) => {
                let mut values = MotorValues::new();
                for o in &orders {
                    if let OrionOrder::Set(m, v) = *o
                        && (v == 0.0
                            || self.orion.commanded.get(m.index()).copied().flatten() != Some(v))
                    {
                        values.set(m, v);
                    }
                }
                (
                    line_of(&values),
                    1,
                    self.config.client.timeout,
                    self.config.client.retries,
                )
            }
        };
        let sets = match order {
            OrionOrder::Set(..) => orders
                .iter()
                .filter_map(|o| match *o {
                    OrionOrder::Set(m, v) => Some((m, v)),
                    OrionOrder::Command(_) => None,
                })
                .collect(),
            OrionOrder::Command(_) => Vec::new(),
        };
        self.orion.tx.push_back(line.clone());
        self.orion.pending = Some(Pending {
            msg_id: id,
            joints,
            line,
            mode,
            attempts: 1,
            retries,
            timeout,
            deadline: now.saturating_add(timeout),
            sets,
        });
        Ok(id)
    }

    /// The next line for the Orion controller (without its newline).
    pub fn poll_orion_line(&mut self) -> Option<String> {
        self.orion.tx.pop_front()
    }

    /// One line from the Orion controller, received at `now`.
    pub fn handle_orion_line(&mut self, now: Duration, line: &str) {
        self.now = self.now.max(now);
        let now = self.now;
        // The controller's lines are under 300 bytes: a longer one is not
        // parsed (a hostile one would cost every device's time).
        if line.len() > MAX_ORION_LINE {
            self.orion_bad_line(now, format!("a line over {MAX_ORION_LINE} bytes"));
            return;
        }
        let output = match Output::parse(line.trim()) {
            Ok(o) => o,
            Err(e) => {
                self.orion_bad_line(now, e.to_string());
                return;
            }
        };
        // Heard again after the link was lost or went silent: its state is
        // made safe and known before its motors are online.
        let offline =
            self.orion.ready && self.joints.iter().any(|j| j.orion.is_some() && !j.online);
        if (self.orion.lost || offline) && !self.orion.recovering {
            self.orion_link_back(now);
        }
        self.orion_heard(now);
        match output {
            Output::Beacon => {
                let first = !self.orion.ready;
                if first || self.orion.next_poll.is_some() {
                    // The first beacon, or one after the controller had
                    // been commanded: it started again, every value 0.
                    self.orion.commanded = [None; 7];
                    self.out
                        .push_back(BridgeOutput::Event(Event::OrionBeacon { first }));
                }
                self.orion.ready = true;
                // Its motors are online from its boot beacon on: a
                // controller that (re)started has every value at 0, its
                // state known, stopped or not.
                self.orion.recovering = false;
                self.orion_heard(now);
                // Answered by the first poll, which ends the beacons.
                self.orion.next_poll = Some(now);
                if first {
                    for ji in 0..self.joints.len() {
                        if self.is_orion(ji) {
                            self.pump(ji);
                        }
                    }
                    self.finish_jobs();
                }
            }
            Output::DirectControl(fb) => {
                if !self.orion_feedback(&fb, now) {
                    return;
                }
                // It answers the line in flight only if it reports every
                // motor that line set.
                let answers = self.orion.pending.as_ref().is_some_and(|p| {
                    p.mode == 1 && p.sets.iter().all(|(m, _)| fb.get(*m).is_some())
                });
                if answers {
                    if let Some(p) = self.orion.pending.as_ref() {
                        for &(m, v) in &p.sets {
                            if let Some(slot) = self.orion.commanded.get_mut(m.index()) {
                                *slot = Some(v);
                            }
                        }
                    }
                    self.orion_answered(now, 1, Outcome::Acked);
                }
            }
            Output::Command { succeeded } => {
                let outcome = if succeeded {
                    Outcome::Acked
                } else {
                    Outcome::Nacked(NackCode(0))
                };
                let recovered = succeeded
                    && self.orion.recovering
                    && self
                        .orion
                        .pending
                        .as_ref()
                        .is_some_and(|p| p.mode == 2 && p.joints.is_empty());
                if self.orion.pending.as_ref().is_some_and(|p| p.mode == 2) {
                    // Stop, fold and unfold leave the speeds and actuators
                    // at 0 and move the servo: send every value again.
                    self.orion.commanded = [None; 7];
                }
                self.orion_answered(now, 2, outcome);
                if recovered {
                    // Stopped and known: online again, nothing resumed.
                    self.orion.recovering = false;
                    self.orion_heard(now);
                }
            }
        }
    }

    /// A line from the controller that is not one of its messages: counted,
    /// and reported (at most [`MAX_BAD_LINE_EVENTS`] a second).
    fn orion_bad_line(&mut self, now: Duration, error: String) {
        self.stats.bad_frames += 1;
        if let Some(suppressed) = self.orion.report_bad(now) {
            self.out.push_back(BridgeOutput::Event(Event::BadOrionLine {
                error,
                suppressed,
            }));
        }
    }

    /// A line from the controller that could not be read (too long, not
    /// UTF-8), at `now`: reported like a bad line.
    pub fn handle_orion_unreadable(&mut self, now: Duration, reason: &str) {
        self.now = self.now.max(now);
        self.orion_bad_line(self.now, reason.to_owned());
    }

    /// The link to the controller ended (`error` says how): its motors
    /// are offline, and what was in flight has an unknown outcome.
    pub fn orion_link_lost(&mut self, now: Duration, error: &str) {
        self.now = self.now.max(now);
        if self.orion.lost {
            return;
        }
        self.orion.lost = true;
        self.orion.recovering = false;
        // Polled on: a link that connects again answers.
        self.orion.next_poll = Some(now.saturating_add(POLL));
        self.out
            .push_back(BridgeOutput::Event(Event::OrionLinkLost {
                error: error.to_owned(),
            }));
        if let Some(p) = self.orion.pending.take() {
            self.orion_done(p, Outcome::TimedOut);
        }
        let orion: Vec<usize> = (0..self.joints.len())
            .filter(|&k| self.is_orion(k))
            .collect();
        for &ji in &orion {
            if let Some(j) = self.joints.get_mut(ji) {
                j.deadman = None;
                if j.online {
                    j.online = false;
                    self.out.push_back(BridgeOutput::Event(Event::Offline {
                        motor_id: j.name.clone(),
                        node: j.node,
                        reason: format!("the link to the Orion controller is lost: {error}"),
                    }));
                }
            }
        }
        self.fail_watches(
            |w| orion.iter().any(|&ji| w.waits_on(ji)),
            "the link to the Orion controller is lost",
        );
        // What waits for the controller is not sent.
        for ji in orion {
            self.pump(ji);
        }
        self.finish_jobs();
        self.handle_timeout(now);
    }

    /// Lines come again after the link was lost (a link that connected
    /// again): what the controller runs now is unknown (it may still turn
    /// at what it was last told), so a stop goes first, nothing under way
    /// is resumed, and its motors are online once the stop is answered.
    fn orion_link_back(&mut self, now: Duration) {
        self.orion.lost = false;
        self.orion.recovering = true;
        self.orion.commanded = [None; 7];
        if self.orion.pending.is_none() {
            self.orion_recovery_stop(now);
        }
    }

    /// The stop that makes a controller heard again safe and known: sent
    /// again (each time the one before went unanswered) until answered.
    fn orion_recovery_stop(&mut self, now: Duration) {
        let line = motorwire_orion::Input::Command(ArmCommand::Stop.into()).to_json();
        self.orion_own_line(now, line, 2);
    }

    /// Writes a line of the bridge's own (a poll, a recovery's stop), no
    /// device's step: awaited once, in `mode`, within the Ack timeout.
    fn orion_own_line(&mut self, now: Duration, line: String, mode: u8) {
        let id = self.orion.next_id;
        self.orion.next_id = self.orion.next_id.wrapping_add(1);
        self.orion.tx.push_back(line.clone());
        let timeout = self.config.client.timeout;
        self.orion.pending = Some(Pending {
            msg_id: id,
            joints: Vec::new(),
            line,
            mode,
            attempts: 1,
            retries: 0,
            timeout,
            deadline: now.saturating_add(timeout),
            sets: Vec::new(),
        });
    }

    /// Why the Orion motors are offline now, if the link says so: before
    /// the boot beacon, and while a link that came back is being stopped.
    pub(super) fn orion_offline_reason(&self) -> Option<&'static str> {
        if !self.orion.ready {
            Some("the Orion arm controller has not sent its boot beacon")
        } else if self.orion.recovering {
            Some("the link to the Orion arm controller came back, and its stop is not answered yet")
        } else if self.orion.lost {
            Some("the link to the Orion arm controller is lost")
        } else {
            None
        }
    }

    /// Something was heard from the controller at `at`; its motors are
    /// online once its boot beacon was heard (and, after a lost link, its
    /// stop answered).
    fn orion_heard(&mut self, at: Duration) {
        let orion: Vec<usize> = (0..self.joints.len())
            .filter(|&k| self.is_orion(k))
            .collect();
        let up = self.orion.ready && !self.orion.recovering && !self.orion.lost;
        for ji in orion {
            let Some(j) = self.joints.get_mut(ji) else {
                continue;
            };
            j.last_heard = Some(at.max(j.last_heard.unwrap_or(Duration::ZERO)));
            if up && !j.online {
                j.online = true;
                self.out.push_back(BridgeOutput::Event(Event::Online {
                    motor_id: j.name.clone(),
                    node: j.node,
                }));
            }
        }
    }

    /// Direct-control feedback: each mapped motor's WIA feedback, its
    /// motion and its arrival. False (and reported) when a value is not a
    /// finite number: such a line is not an answer.
    fn orion_feedback(&mut self, fb: &motorwire_orion::Feedback, now: Duration) -> bool {
        let ts = self.unix_ms(now);
        let Ok(list) = motorwire_translate::feedback_from_orion(&self.map, fb, ts) else {
            self.orion_bad_line(
                now,
                "feedback with a value that is not a finite number".to_owned(),
            );
            return false;
        };
        for t in list {
            let f = t.value;
            let Some(ji) = self.joint_index(&f.motor_id) else {
                continue;
            };
            let Some(motor) = self.joints.get(ji).and_then(|j| j.orion) else {
                continue;
            };
            let degrees = self
                .map
                .motor(&f.motor_id)
                .map_or(f.position, |m| m.unit.to_degrees(f.position));
            let motion = match motor.quantity() {
                Quantity::PositionDegrees => (degrees, 0.0),
                Quantity::Speed | Quantity::Actuator => (0.0, f.velocity),
            };
            if let Some(j) = self.joints.get_mut(ji) {
                j.motion = Some(motion);
                j.feedback = Some(f);
            }
            if motor.quantity() == Quantity::PositionDegrees {
                if !self.arrivals.is_empty() {
                    self.observe(ji, motion.0, motion.1, now);
                }
                self.sequence_progress(ji, motion.0, motion.1);
            }
        }
        true
    }

    /// An answer of `mode`: it acknowledges the line in flight if that
    /// awaits this mode.
    fn orion_answered(&mut self, now: Duration, mode: u8, outcome: Outcome) {
        if self.orion.pending.as_ref().is_none_or(|p| p.mode != mode) {
            return;
        }
        let Some(p) = self.orion.pending.take() else {
            return;
        };
        self.orion.next_poll = Some(now.saturating_add(POLL));
        self.orion_done(p, outcome);
    }

    fn orion_done(&mut self, p: Pending, outcome: Outcome) {
        for ji in p.joints {
            self.device_done(ji, p.msg_id, ORION_NODE, outcome, p.attempts);
        }
        for ji in 0..self.joints.len() {
            if self.is_orion(ji) {
                self.pump(ji);
            }
        }
        self.finish_jobs();
    }

    /// Resends, gives up, and polls when idle.
    pub(super) fn orion_timeouts(&mut self, now: Duration) {
        if let Some(p) = self.orion.pending.as_mut()
            && now >= p.deadline
        {
            if p.attempts <= p.retries && !p.joints.is_empty() && !self.orion.lost {
                p.attempts += 1;
                p.deadline = now.saturating_add(p.timeout);
                let line = p.line.clone();
                self.orion.tx.push_back(line);
            } else if let Some(p) = self.orion.pending.take() {
                self.orion.next_poll = Some(now);
                self.orion_done(p, Outcome::TimedOut);
            }
        }
        if self.orion.recovering && self.orion.pending.is_none() {
            self.orion_recovery_stop(now);
        }
        // A poll never takes the link from a step waiting for it.
        if self.orion.may_poll()
            && self.orion.next_poll.is_some_and(|t| now >= t)
            && self.joints.iter().any(|j| j.orion.is_some())
            && !self.joints.iter().any(|j| {
                j.orion.is_some()
                    && (j.busy.is_some()
                        || j.queue
                            .front()
                            .is_some_and(|s| !self.after_earlier_axis(*s)))
            })
        {
            self.orion_own_line(now, line_of(&MotorValues::new()), 1);
            self.orion.next_poll = None;
        }
    }

    /// An acked Orion order's effect: a speed or actuator value other than
    /// 0 is watched by the deadman; the servo's value is its target.
    pub(super) fn track_orion(&mut self, ji: usize, order: OrionOrder, at: Duration) {
        let timeout = self
            .joints
            .get(ji)
            .and_then(|j| self.map.motor(&j.name))
            .and_then(|m| m.command_timeout);
        let Some(j) = self.joints.get_mut(ji) else {
            return;
        };
        j.deadman = None;
        match order {
            OrionOrder::Set(m, v) => match m.quantity() {
                Quantity::PositionDegrees => {
                    j.target = Some(v);
                    j.moving_until = at;
                }
                Quantity::Speed | Quantity::Actuator => {
                    j.target = None;
                    if v != 0.0 {
                        j.deadman = timeout.map(|t| at.saturating_add(t));
                    }
                    j.moving_until = j.deadman.unwrap_or(at);
                }
            },
            OrionOrder::Command(_) => {
                j.moving_until = at;
            }
        }
    }

    /// The deadman's stop for Orion motor `ji`: its value 0.
    pub(super) fn orion_deadman_axis(&self, ji: usize) -> Option<Axis> {
        let j = self.joints.get(ji)?;
        let m: Motor = j.orion?;
        Some(Axis::of(
            j.name.clone(),
            ji,
            [Order::Orion(OrionOrder::Set(m, 0.0))],
        ))
    }

    /// `cmd` for Orion motor `ji`, gated and translated, as its axis.
    pub(super) fn orion_axis(
        &self,
        ji: usize,
        cmd: &motorwire_wia::MotorCommand,
    ) -> Result<(Axis, Report), motorwire_translate::Refusal> {
        let t = motorwire_translate::to_orion_motor(&self.map, cmd)?;
        let motor = self
            .joints
            .get(ji)
            .and_then(|j| j.orion)
            .unwrap_or(Motor::Turntable);
        let order = match t.value {
            motorwire_orion::Input::DirectControl(values) => {
                OrionOrder::Set(motor, values.get(motor).unwrap_or(0.0))
            }
            motorwire_orion::Input::Command(_) => OrionOrder::Command(ArmCommand::Stop),
        };
        let mut axis = Axis::of(cmd.motor_id.clone(), ji, [Order::Orion(order)]);
        if let OrionOrder::Set(m, v) = order
            && m.quantity() == Quantity::PositionDegrees
        {
            axis.target = Some(v);
        }
        Ok((axis, t.report))
    }

    /// `{"orion":"fold"}` or `{"orion":"unfold"}`: the controller's command
    /// mode, for every Orion motor of the map (one line).
    pub(super) fn orion_command(
        &mut self,
        now: Duration,
        origin: crate::output::Origin,
        number: u64,
        command: ArmCommand,
    ) {
        let name = match command {
            ArmCommand::Fold => "fold",
            ArmCommand::Unfold => "unfold",
            ArmCommand::Stop => "stop",
        };
        let label = Some(("orion", name.to_owned()));
        let motors: Vec<(usize, String)> = self
            .joints
            .iter()
            .enumerate()
            .filter(|(_, j)| j.orion.is_some())
            .map(|(i, j)| (i, j.name.clone()))
            .collect();
        if motors.is_empty() {
            let e = crate::output::ErrorBody::refused(
                crate::output::BridgeRule::OrionNotAttached,
                "no Orion arm controller is attached (motorwire bridge --orion ...)",
            );
            self.refuse(origin, number, label, e);
            return;
        }
        if let Err(e) = self.admit_now(motors.iter().map(|(_, n)| n.as_str())) {
            self.refuse(origin, number, label, e);
            return;
        }
        let axes = motors
            .into_iter()
            .map(|(ji, name)| Axis::of(name, ji, [Order::Orion(OrionOrder::Command(command))]))
            .collect();
        self.command_job(now, origin, number, label, axes, Report::default());
    }

    /// The refusal for an Orion motor among `motors` when no controller
    /// is attached.
    pub(super) fn orion_unattached<'a>(
        &self,
        mut motors: impl Iterator<Item = &'a str>,
    ) -> Option<crate::output::ErrorBody> {
        if self.config.orion {
            return None;
        }
        let m = motors.find(|m| {
            self.map
                .motor(m)
                .is_some_and(|m| matches!(m.target, motorwire_translate::Target::Orion { .. }))
        })?;
        Some(
            crate::output::ErrorBody::refused(
                crate::output::BridgeRule::OrionNotAttached,
                format!(
                    "{m} is an Orion motor, and no Orion controller is attached (motorwire bridge --orion ...)"
                ),
            )
            .about(m),
        )
    }

    /// The Orion controller's id, for messages.
    pub(super) fn orion_label() -> String {
        format!("the Orion arm controller (ID {CONTROLLER_ID})")
    }
}
