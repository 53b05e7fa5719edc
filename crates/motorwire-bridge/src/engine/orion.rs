//! The engine's side of the Orion arm controller (WIRE-FACTS §4.1): its
//! motors as devices of the bridge, the controller itself behind
//! [`OrionDriver`] (its lines, its link, its line in flight).
//!
//! - The map's Orion motors are devices of the bridge like joints: gated,
//!   queued, stopped, watched by the deadman. Their orders become lines to
//!   the one controller, one line in flight at a time.
//! - Orders of one input line for several Orion motors go out as one
//!   `DATA` line; a stop for all of them is one stop command.
//! - An emergency stop goes out at once, whatever is in flight.

use std::time::Duration;

use motorwire_orion::{ArmCommand, Quantity};
use motorwire_translate::Report;

use super::Bridge;
use crate::device::Device;
use crate::device::orion::{BadLine, Done};
pub use crate::device::orion::{MAX_BAD_LINE_EVENTS, MAX_ORION_LINE, POLL};
pub(crate) use crate::device::orion::{ORION_NODE, OrionDriver};
use crate::job::LineMeta;
use crate::job::{Axis, AxisState, Order, OrionOrder};
use crate::joints::StepRef;
use crate::output::Label;
use crate::output::{Event, Output as BridgeOutput};

impl Bridge {
    /// Whether device `ji` is an Orion motor.
    pub(super) fn is_orion(&self, ji: usize) -> bool {
        self.joints
            .get(ji)
            .is_some_and(|j| matches!(j.device, Device::Orion(_)))
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
        !orders || job.kind.is_stop() || self.drivers.orion.lost() || self.drivers.orion.free()
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
        if let Some(e) = self.drivers.orion.refuses(order) {
            return Err(e);
        }
        // Others of the same job, same kind of order.
        let mut orders = vec![(ji, order)];
        let mut others = Vec::new();
        for k in 0..self.joints.len() {
            if k == ji {
                continue;
            }
            let Some(j) = self.joints.get(k) else {
                continue;
            };
            if !matches!(j.device, Device::Orion(_)) || j.busy.is_some() {
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
                orders.push((k, o));
            }
            if let Some(j) = self.joints.get_mut(k) {
                j.queue.pop_front();
                j.busy = Some(front);
            }
            others.push((front, payload));
        }
        let id = self.drivers.orion.send(now, &orders);
        for (front, payload) in others {
            if let Some(a) = self
                .jobs
                .get_mut(&front.job)
                .and_then(|job| job.axes.get_mut(front.axis))
            {
                a.state = AxisState::InFlight {
                    msg_id: id,
                    payload,
                };
                a.attempts = 1;
            }
        }
        Ok(id)
    }

    /// The next line for the Orion controller (without its newline).
    pub fn poll_orion_line(&mut self) -> Option<String> {
        self.drivers.orion.poll_line()
    }

    /// One line from the Orion controller, received at `now`.
    pub fn handle_orion_line(&mut self, now: Duration, line: &str) {
        self.now = self.now.max(now);
        let now = self.now;
        // Its motors held offline (it fell silent): heard again, it is
        // made safe and known before they are online.
        let offline = self
            .joints
            .iter()
            .any(|j| matches!(j.device, Device::Orion(_)) && !j.online);
        let output = match self.drivers.orion.read(now, line, offline) {
            Ok(o) => o,
            Err(bad) => return self.orion_bad_line(bad),
        };
        self.orion_heard(now);
        let ts = self.unix_ms(now);
        let applied = self.drivers.orion.apply(now, &output, &self.map, ts);
        if let Some(bad) = applied.bad {
            return self.orion_bad_line(bad);
        }
        if let Some((first, reported)) = applied.beacon {
            if reported {
                self.out
                    .push_back(BridgeOutput::Event(Event::OrionBeacon { first }));
            }
            self.orion_heard(now);
            if first {
                for ji in 0..self.joints.len() {
                    if self.is_orion(ji) {
                        self.pump(ji);
                    }
                }
                self.finish_jobs();
            }
        }
        self.orion_feedback(applied.feedback, now);
        if let Some(done) = applied.done {
            self.orion_done(done);
        }
        if applied.recovered {
            // Stopped and known: online again, nothing resumed.
            self.drivers.orion.end_recovery();
            self.orion_heard(now);
        }
    }

    /// A line from the controller that is not one of its messages: counted,
    /// and reported when the driver says so (at most
    /// [`MAX_BAD_LINE_EVENTS`] a second).
    fn orion_bad_line(&mut self, bad: BadLine) {
        self.stats.bad_frames += 1;
        if let Some(suppressed) = bad.report {
            self.out.push_back(BridgeOutput::Event(Event::BadOrionLine {
                error: bad.error,
                suppressed,
            }));
        }
    }

    /// A line from the controller that could not be read (too long, not
    /// UTF-8), at `now`: reported like a bad line.
    pub fn handle_orion_unreadable(&mut self, now: Duration, reason: &str) {
        self.now = self.now.max(now);
        let bad = self.drivers.orion.unreadable(self.now, reason);
        self.orion_bad_line(bad);
    }

    /// The link to the controller ended (`error` says how): its motors
    /// are offline, and what was in flight has an unknown outcome.
    pub fn orion_link_lost(&mut self, now: Duration, error: &str) {
        self.now = self.now.max(now);
        let Some(in_flight) = self.drivers.orion.link_lost(now) else {
            return;
        };
        self.out
            .push_back(BridgeOutput::Event(Event::OrionLinkLost {
                error: error.to_owned(),
            }));
        if let Some(done) = in_flight {
            self.orion_done(done);
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

    /// Something was heard from the controller at `at`; its motors are
    /// online once its boot beacon was heard (and, after a lost link, its
    /// stop answered).
    fn orion_heard(&mut self, at: Duration) {
        let orion: Vec<usize> = (0..self.joints.len())
            .filter(|&k| self.is_orion(k))
            .collect();
        let up = self.drivers.orion.up();
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

    /// Direct-control feedback, decoded by the driver: each mapped motor's
    /// WIA feedback, its motion and its arrival.
    fn orion_feedback(&mut self, list: Vec<motorwire_wia::MotorFeedback>, now: Duration) {
        for f in list {
            let Some(ji) = self.joint_index(&f.motor_id) else {
                continue;
            };
            let Some(Device::Orion(motor)) = self.joints.get(ji).map(|j| j.device) else {
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
            self.reading(ji, now, Some(motion), Some(f));
        }
    }

    /// A line of the controller's ended: each device whose step it carried
    /// is done, and what waits for the controller may go.
    fn orion_done(&mut self, done: Done) {
        let ended = done.ended(self.now);
        for &ji in &done.joints {
            self.step_done(ji, ended.clone());
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
        if let Some(done) = self.drivers.orion.expire(now) {
            self.orion_done(done);
        }
        // A poll never takes the link from a step waiting for it.
        let orion = |j: &crate::joints::Joint| matches!(j.device, Device::Orion(_));
        let idle = self.joints.iter().any(orion)
            && !self.joints.iter().any(|j| {
                orion(j)
                    && (j.busy.is_some()
                        || j.queue
                            .front()
                            .is_some_and(|s| !self.after_earlier_axis(*s)))
            });
        self.drivers.orion.housekeeping(now, idle);
    }

    /// `{"orion":"fold"}` or `{"orion":"unfold"}`: the controller's command
    /// mode, for every Orion motor of the map (one line).
    pub(super) fn orion_command(&mut self, now: Duration, meta: LineMeta, command: ArmCommand) {
        let name = match command {
            ArmCommand::Fold => "fold",
            ArmCommand::Unfold => "unfold",
            ArmCommand::Stop => "stop",
        };
        let meta = meta.labelled(Label::Orion(name.to_owned()));
        let motors: Vec<(usize, String)> = self
            .joints
            .iter()
            .enumerate()
            .filter(|(_, j)| matches!(j.device, Device::Orion(_)))
            .map(|(i, j)| (i, j.name.clone()))
            .collect();
        if motors.is_empty() {
            let e = crate::output::ErrorBody::refused(
                crate::output::BridgeRule::OrionNotAttached,
                "no Orion arm controller is attached (motorwire bridge --orion ...)",
            );
            self.refuse(&meta, e);
            return;
        }
        if let Err(e) = self.admit_now(motors.iter().map(|(_, n)| n.as_str())) {
            self.refuse(&meta, e);
            return;
        }
        let axes = motors
            .into_iter()
            .map(|(ji, name)| Axis::of(name, ji, [Order::Orion(OrionOrder::Command(command))]))
            .collect();
        self.command_job(now, meta, axes, Report::default());
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
}
