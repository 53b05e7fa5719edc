//! What the devices tell: readings, lifecycle, liveness, and feedback given out.

use super::*;

impl Bridge {
    /// Joint `ji` faulted or rebooted (`why`): said with `event`, and
    /// everything waiting for it is cancelled; nothing but a reset line is
    /// sent to it from now on.
    pub(super) fn joint_lost(&mut self, ji: DeviceId, why: String, event: Event) {
        let Some(j) = self.joints.get_mut(ji) else {
            return;
        };
        if j.lifecycle.needs_reset().is_some() {
            return;
        }
        j.lifecycle.lost(why.clone());
        self.out.push_back(Output::Event(event));
        let because = format!("cancelled: the joint {why}");
        self.cancel_where(&because, |job| {
            job.kind == JobKind::Command && job.axes.iter().any(|a| a.joint == ji)
        });
        self.fail_watches(|w| w.waits_on(ji), &format!("the joint {why}"));
    }

    // ---- live limits --------------------------------------------------------

    /// Takes a frame from the bus.
    pub(super) fn on_frame(&mut self, frame: &Frame) {
        self.drivers.handle_frame(self.now, frame, &self.joints);
        self.drain_drivers();
    }

    /// Device `ji` (any dialect) reported at `at`: its position and
    /// velocity (degrees) where the report has them, and its WIA feedback.
    /// Lines that have now arrived are said so, sequential axes waiting
    /// on it may go, and a move whose outcome was unknown is said
    /// executed once the device stands at its target.
    pub(super) fn reading(
        &mut self,
        ji: DeviceId,
        at: Duration,
        motion: Option<(f64, f64)>,
        feedback: Option<MotorFeedback>,
    ) {
        let Some(j) = self.joints.get_mut(ji) else {
            return;
        };
        if let Some(f) = feedback {
            j.motion.feedback_came(f);
            self.confirm_stop(ji, at);
        }
        let Some(j) = self.joints.get_mut(ji) else {
            return;
        };
        let Some((pos, vel)) = motion else {
            return;
        };
        // Its acceleration, from this report and the one before.
        let acceleration = match (j.motion.reported(), j.motion.reported_at()) {
            (Some((_, v0)), Some((t0, _))) if at > t0 && at - t0 <= Duration::from_millis(100) => {
                (vel - v0) / (at - t0).as_secs_f64()
            }
            _ => 0.0,
        };
        // Its first reading may make the bridge ready; a later one cannot
        // (nor can any other device's reading but its first): what ready
        // waits for is looked at then, not on every report of every device.
        let first = j.motion.reported().is_none();
        // How fast a torque speeds it up: only while it holds a torque
        // setpoint, and only speeding up the way it goes (a stop, a fault
        // or a brake slows it down; a velocity setpoint ramps within the
        // limits).
        if j.liveness.deadman().is_some()
            && j.motion.held_velocity().is_none()
            && acceleration.is_finite()
            && acceleration * vel > 0.0
        {
            j.motion.saw_acceleration(acceleration);
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
        if let Some(u) = j.schedule.unresolved()
            && (pos - u.target).abs() < 0.5
            && vel.abs() < 1.0
        {
            j.schedule.settle();
            let position = self
                .map
                .motor(j.identity.name())
                .map_or(pos, |m| m.unit.from_degrees(pos));
            self.out.push_back(Output::Event(Event::Outcome {
                origin: u.origin,
                line: u.line,
                motor_id: j.identity.name().to_owned(),
                outcome: "executed",
                position: shortest(position),
            }));
        }
    }

    /// Joint `ji` reported its lifecycle `state` (with `code`, its error
    /// code): it is active or not; a fault, or a reboot the bridge did not
    /// ask for, loses it until a reset.
    pub(super) fn lifecycle(&mut self, ji: DeviceId, state: DeviceState, code: u16) {
        let Some(j) = self.joints.get_mut(ji) else {
            return;
        };
        let before = j.lifecycle.reported(state);
        if state == DeviceState::Error {
            let event = Event::JointFault {
                motor_id: j.identity.name().to_owned(),
                code,
                reason: None,
            };
            self.joint_lost(ji, format!("faulted (error code {code})"), event);
        } else if state == DeviceState::Unconfigured
            && !j.lifecycle.is_resetting()
            && matches!(before, Some(DeviceState::Active | DeviceState::Inactive))
        {
            let event = Event::Rebooted {
                motor_id: j.identity.name().to_owned(),
            };
            self.joint_lost(ji, "rebooted".to_owned(), event);
        }
    }

    /// Device `ji` was heard from at `at`; online, if it was not, when
    /// its link is `up`.
    pub(super) fn heard(&mut self, ji: DeviceId, at: Duration, up: bool) {
        if let Some(j) = self.joints.get_mut(ji) {
            j.liveness.heard(at);
            if up && j.liveness.back_online() {
                self.out.push_back(Output::Event(Event::Online {
                    motor_id: j.identity.name().to_owned(),
                    node: j.identity.node(),
                }));
            }
        }
    }

    // ---- time -----------------------------------------------------------

    pub(super) fn any_moving(&self, now: Duration) -> bool {
        self.joints.iter().any(|j| j.schedule.is_moving(now))
    }

    pub(super) fn emit_feedback(&mut self, now: Duration) {
        let ts = self.unix_ms(now);
        for j in self.joints.iter() {
            // Degrees: how close counts as there, and how slow as at rest.
            let tolerance = self
                .map
                .motor(j.identity.name())
                .map_or(0.1, |m| m.unit.to_degrees(m.arrival_tolerance));
            let fb = j.motion.feedback().cloned().map(|mut f| {
                f.timestamp = ts;
                if !j.liveness.is_online() {
                    f.status.fault = Some(true);
                }
                if let Some((pos, vel)) = j.motion.reported() {
                    f.status.in_motion = Some(vel.abs() > tolerance * 10.0);
                    if let Some(target) = j.schedule.target() {
                        f.status.at_target = Some((pos - target).abs() <= tolerance);
                    }
                }
                shortest_feedback(f)
            });
            if fb.is_none() && j.liveness.is_online() {
                continue; // nothing heard yet, and not yet overdue
            }
            self.stats.feedback_lines += 1;
            self.out.push_back(Output::Feedback(Box::new(FeedbackLine {
                feedback: fb,
                motor_id: j.identity.name().to_owned(),
                online: j.liveness.is_online(),
            })));
        }
    }

    /// Whole Unix milliseconds (or milliseconds since start without a wall clock).
    pub(super) fn unix_ms(&self, now: Duration) -> f64 {
        crate::device::unix_ms(self.config.epoch_unix_ms.unwrap_or(0.0), now)
    }
}
