//! A motor line: one motor held, freed or stopped alone, and a joint's reset.

use super::*;

impl Bridge {
    /// `{"motor":action,"motor_id":M}`: motor M held, freed or stopped
    /// alone, by its dialect's own means ([`Device::motor_order`]; an
    /// iRPC joint's hold, a move to where it can stop within the limits in
    /// force, planned here). What waited to be sent to it from earlier
    /// lines is given up first (their results say so), and a trajectory
    /// running on it sends nothing more: nothing older moves it after
    /// this. Refused while the emergency stop is latched (every motor is
    /// stopped already), for a motor that needs a reset or is offline.
    /// Never refused as busy: it clears the motor's queue before it joins
    /// it, so a flood of them holds one step a motor.
    pub(super) fn motor_line(
        &mut self,
        now: Duration,
        meta: LineMeta,
        action: MotorAction,
        motor: &str,
    ) {
        let meta = meta.labelled(Label::Motor(motor.to_owned()));
        let now_ms = self.unix_ms(now);
        match self
            .admission()
            .admit(now, None, now_ms, std::iter::once(motor))
        {
            Err(e) if e.kind() != ErrorKind::Busy => return self.refuse(&meta, e),
            _ => {}
        }
        let Some((ji, device)) = self
            .joint_index(motor)
            .and_then(|ji| Some((ji, self.joints.get(ji)?.identity.device())))
        else {
            let e =
                self.unattached(std::iter::once(motor))
                    .unwrap_or_else(|| Refusal::UnknownMotor {
                        motor: motor.to_owned(),
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
            Ok(MotorOrder::Planned) => match self.planned_hold(ji, motor, unit, &limits, now_ms) {
                Ok((axis, loss)) => {
                    if let Some(loss) = loss {
                        said(loss);
                    }
                    Some(axis)
                }
                Err(e) => return self.refuse(&meta, e),
            },
            Err(why) => {
                let e = Refusal::ActionNotExpressible {
                    motor: motor.to_owned(),
                    why: why.to_string(),
                    not_active: false,
                };
                return self.refuse(&meta, e);
            }
        };
        // (The deadman stays armed until the motor line's order is taken:
        // if it is lost, the deadman's own stop follows.)
        self.give_up_for_motor_line(ji, action);
        self.command_job(now, meta, axis.into_iter().collect(), report);
    }

    /// Motor `motor`'s hold planned here ([`Self::hold_move`]) as device
    /// `ji`'s axis. A hold that cannot be planned is the joint's own stop
    /// (when in doubt, stop), and why is said; a joint not up (never
    /// started: its lifecycle left to the user, or its start failed) has
    /// no torque to keep on, and nothing to stop: refused.
    fn planned_hold(
        &mut self,
        ji: DeviceId,
        motor: &str,
        unit: AngleUnit,
        limits: &Limits,
        now_ms: f64,
    ) -> Result<(Axis, Option<String>), Refusal> {
        match self.hold_move(ji, motor, unit, limits, now_ms) {
            Ok(order) => Ok((Axis::of(motor.to_owned(), ji, [order]), None)),
            Err(why)
                if !self
                    .joints
                    .get(ji)
                    .is_some_and(|j| j.lifecycle.is_active() || j.lifecycle.is_freed()) =>
            {
                Err(Refusal::ActionNotExpressible {
                    motor: motor.to_owned(),
                    why: why.to_string(),
                    not_active: true,
                })
            }
            Err(why) => {
                let said = format!("{why}: the joint was deactivated (its own stop) instead");
                let stop = self.orders_for(ji, &[Lifecycle::Deactivate]);
                Ok((Axis::of(motor.to_owned(), ji, stop), Some(said)))
            }
        }
    }

    /// An iRPC joint's hold: a move to where it comes to rest from how it
    /// moves now (position, velocity and acceleration), as the joint
    /// itself plans with the limits in force (its deceleration and jerk):
    /// the farthest point of the joint's own plan back to where it is now,
    /// which passes it and comes back, is where it can stop. Within the
    /// position limits in force, gated and planned as any move is; why
    /// not, said for a person.
    pub(super) fn hold_move(
        &mut self,
        ji: DeviceId,
        motor: &str,
        unit: AngleUnit,
        limits: &Limits,
        now_ms: f64,
    ) -> Result<Order, HoldError> {
        let Some((p, v, a)) = self.joints.get(ji).and_then(|j| j.state_at(self.now)) else {
            return Err(HoldError::PositionUnknown);
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
        let here = self.move_to(motor, unit, within(p), now_ms)?;
        // Moving: where the joint's own plan back to here turns.
        let stop_at = if v == 0.0 && a == 0.0 {
            p
        } else {
            let req = here.planner_request(p, v).with_start_acceleration(a);
            let e = motorwire_planner::plan(&req)
                .map_err(HoldError::Unplannable)?
                .position_extrema();
            if v > 0.0 || (v == 0.0 && a > 0.0) {
                e.max
            } else {
                e.min
            }
        };
        let gated = plan::gate(
            &self.map,
            &Self::position_command(motor, unit.from_degrees(within(stop_at)), now_ms),
        )
        .map_err(HoldError::Refused)?;
        let from = self.joints.get(ji).and_then(|j| j.state_at(self.now));
        let planned = gated.plan_from(from).map_err(HoldError::Refused)?;
        let order = gated.into_parts().0.next().ok_or(HoldError::NoMove)?;
        self.keep_plan(ji, planned);
        Ok(order)
    }

    /// The move a position command to `deg` makes for `motor`, with the
    /// limits in force.
    pub(super) fn move_to(
        &self,
        motor: &str,
        unit: AngleUnit,
        deg: f64,
        now_ms: f64,
    ) -> Result<Move, HoldError> {
        plan::gate(
            &self.map,
            &Self::position_command(motor, unit.from_degrees(deg), now_ms),
        )
        .map_err(HoldError::Refused)?
        .first_move()
        .ok_or(HoldError::NoMove)
    }

    /// A position command for `motor` to `setpoint` (its unit), nothing
    /// else given: the limits in force apply.
    pub(super) fn position_command(motor: &str, setpoint: f64, now_ms: f64) -> MotorCommand {
        MotorCommand::new(
            motor,
            now_ms,
            motorwire_core::ControlMode::Position,
            setpoint,
        )
    }

    /// What waits for joint `ji` from command lines, given up for a motor
    /// line (its results say so), and a trajectory running on it stopped
    /// from sending more: nothing older moves it after the motor line.
    pub(super) fn give_up_for_motor_line(&mut self, ji: DeviceId, action: MotorAction) {
        let why: &'static str = match action {
            MotorAction::Hold => "a hold of the motor came before it was sent: it was never sent",
            MotorAction::Free => "a free of the motor came before it was sent: it was never sent",
            MotorAction::Stop => "a stop of the motor came before it was sent: it was never sent",
        };
        let Some(joint) = self.joints.get_mut(ji) else {
            return;
        };
        let mut given_up = 0;
        joint.schedule.retain_waiting(|s| {
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
        if let Some(running) = joint.schedule.busy()
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
                joint.schedule.release();
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
    pub(super) fn reset_joint(&mut self, now: Duration, meta: LineMeta, motor: &str) {
        let meta = meta.labelled(Label::Motor(motor.to_owned()));
        if self.stop.is_latched() {
            self.refuse(&meta, Refusal::LatchedReset);
            return;
        }
        // A device that takes a reset (an iRPC joint, a moteus controller):
        // it goes to that device alone (an Orion motor's would be the
        // broadcast node, rebooting every joint).
        let ji = match self.joint_for(motor, Capability::Reset, Needs::RESET, "Reset") {
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
            j.lifecycle.reset_sent();
        }
        // As the device takes a reset (an iRPC joint: these payloads; a
        // moteus controller: its stop, which clears a fault or a timeout).
        let payloads: Vec<Lifecycle> =
            [Lifecycle::Reset, Lifecycle::Configure, Lifecycle::Activate]
                .into_iter()
                .chain(self.telemetry_subscription())
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
}

/// Why no hold could be planned for a joint the bridge plans for.
#[derive(Debug, thiserror::Error)]
pub(super) enum HoldError {
    /// Nothing heard of where it is.
    #[error("its position is not known yet (no feedback), so no hold could be planned")]
    PositionUnknown,
    /// The planner found no stop from how it moves.
    #[error("the joint cannot plan a stop: {0}")]
    Unplannable(motorwire_planner::PlanError),
    /// The gate refused the move to where it stops.
    #[error("{0}")]
    Refused(motorwire_translate::Refusal),
    /// Translation made no move.
    #[error("no move was made")]
    NoMove,
}
