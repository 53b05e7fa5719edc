//! Links and requests: the Orion controller's link, request lines and their answers, the drivers' news taken in.

use super::*;

impl Bridge {
    /// The links' own work due at `now` (the Orion controller's line in
    /// flight, its recovery stop, its poll when no step waits for it).
    pub(super) fn link_timeouts(&mut self, now: Duration) {
        self.drivers.link_timeouts(now, &self.joints);
        self.drain_drivers();
        let jobs = &self.jobs;
        let joints = &self.joints;
        let busy = |k: DeviceId| {
            joints.get(k).is_some_and(|j| {
                j.schedule.busy().is_some()
                    || j.schedule
                        .next_waiting()
                        .is_some_and(|s| !Self::after_earlier_axis(jobs, s))
            })
        };
        self.drivers.link_housekeeping(now, &self.joints, busy);
    }

    /// One line from the Orion controller, received at `now`.
    pub(super) fn on_link_line(&mut self, line: &str) {
        self.drivers
            .handle_line(self.now, line, &self.joints, &self.map);
        self.drain_drivers();
    }

    /// Bytes from serial servo port `port`, received at `now`.
    pub(super) fn on_serial_bytes(&mut self, port: u8, bytes: &[u8]) {
        self.drivers
            .handle_serial(self.now, port, bytes, &self.joints);
        self.drain_drivers();
    }

    /// A line from the Orion controller that could not be read (too long,
    /// not UTF-8), at `now`: counted, and reported at most
    /// [`crate::MAX_BAD_LINE_EVENTS`] times a second.
    pub(super) fn on_link_unreadable(&mut self, reason: &str) {
        self.drivers.handle_unreadable(self.now, reason);
        self.drain_drivers();
    }

    /// The link to the Orion controller ended (`error` says how): its
    /// motors are offline, and what was in flight has an unknown outcome.
    pub(super) fn on_link_lost(&mut self, now: Duration, error: &str) {
        if !self.drivers.link_lost(now, error, &self.joints) {
            return;
        }
        self.drain_drivers();
        self.on_timeout();
    }

    /// `{"orion":"fold"}` or `{"orion":"unfold"}`: an arm-wide command, for
    /// every device that takes one (the Orion controller's motors: one
    /// line).
    pub(super) fn arm_command(&mut self, now: Duration, meta: LineMeta, command: ArmAction) {
        let name = crate::classify::arm_action_name(command);
        let meta = meta.labelled(Label::Orion(name.to_owned()));
        let axes: Vec<Axis> = self
            .joints
            .with_ids()
            .filter_map(|(ji, j)| {
                let order = j.identity.device().arm_order(command)?;
                Some(Axis::of(j.identity.name().to_owned(), ji, [order]))
            })
            .collect();
        if axes.is_empty() {
            self.refuse(&meta, Refusal::OrionNotAttached);
            return;
        }
        if let Err(e) = self
            .admission()
            .admit_now(axes.iter().map(|a| a.motor.as_str()))
        {
            self.refuse(&meta, e);
            return;
        }
        self.command_job(now, meta, axes, Report::default());
    }

    /// The refusal for a motor among `motors` whose driver is not
    /// attached (an Orion motor without `--orion`).
    pub(super) fn unattached<'a>(&self, motors: impl Iterator<Item = &'a str>) -> Option<Refusal> {
        crate::device::unattached(&self.map, self.config.line_link, motors)
    }

    // ---- request lines --------------------------------------------------
    //
    // Lines that ask a joint for something and wait for its answer:
    // telemetry, power metrics, the fault history (`{"request":...}`) and
    // calibration (`{"calibration":"start"|"stop",...}`). A request line is
    // one job: its request is sent like any command (one in flight per
    // joint, retried, acked), and the line's result waits for the message
    // it asked for, which comes back in `data`. The joint may send it
    // before or after its Ack. Nothing within the wait
    // ([`Bridge::answer_wait`]) is the error `no_answer`. A calibration's
    // status messages are `calibration` events while it runs; its result
    // ends the start line (`ok` only when it succeeded).

    /// How long a request line waits for its answer after it is sent:
    /// every attempt's Ack timeout and a margin.
    pub(super) fn answer_wait(&self) -> Duration {
        self.config
            .client
            .timeout
            .saturating_mul(u32::from(self.config.client.retries) + 1)
            .saturating_add(ANSWER_MARGIN)
    }

    /// The device `motor` names if it can do `needs_to` and has the
    /// message `needs` (an iRPC joint, in its wire version), or the
    /// refusal to answer with.
    pub(super) fn joint_for(
        &self,
        motor: &str,
        needs_to: Capability,
        needs: Needs,
        what: &str,
    ) -> Result<DeviceId, Refusal> {
        let Some(ji) = self.joint_index(motor).filter(|&ji| {
            self.joints
                .get(ji)
                .is_some_and(|j| j.identity.device().supports(needs_to))
        }) else {
            if self.joint_index(motor).is_none() {
                return Err(Refusal::UnknownMotor {
                    motor: motor.to_owned(),
                });
            }
            let motor = motor.to_owned();
            return Err(match needs_to {
                Capability::Reset => Refusal::NoReset { motor },
                _ => Refusal::NotAnIrpcJoint { motor },
            });
        };
        let device = self.joints.get(ji).map(|j| j.identity.device());
        if device.is_none_or(|d| !d.speaks(needs)) {
            return Err(Refusal::NoSuchMessage {
                motor: motor.to_owned(),
                wire: device.and_then(Device::version).unwrap_or("?"),
                what: what.to_owned(),
            });
        }
        if self.joints.get(ji).is_some_and(|j| !j.liveness.is_online()) {
            return Err(Refusal::Offline {
                motor: motor.to_owned(),
                why: None,
            });
        }
        Ok(ji)
    }

    /// `{"request":K,"motor_id":M}`.
    pub(super) fn request_line(
        &mut self,
        now: Duration,
        meta: LineMeta,
        kind: RequestKind,
        motor: &str,
    ) {
        let meta = meta.labelled(Label::Motor(motor.to_owned()));
        let ask = crate::device::irpc::request(kind);
        let ji = match self.joint_for(motor, Capability::Requests, ask.needs, ask.what) {
            Ok(ji) => ji,
            Err(e) => return self.refuse(&meta, e),
        };
        let deadline = now.saturating_add(self.answer_wait());
        self.open_waiting(now, meta, (motor, ji), ask.order, ask.awaits, deadline);
    }

    /// `{"calibration":"start"|"stop","motor_id":M,...}`.
    pub(super) fn calibration_line(
        &mut self,
        now: Duration,
        meta: LineMeta,
        motor: &str,
        start: Option<crate::classify::Calibration>,
    ) {
        let meta = meta.labelled(Label::Motor(motor.to_owned()));
        let ask = crate::device::irpc::calibration(start.as_ref());
        let ji = match self.joint_for(motor, Capability::Requests, ask.needs, ask.what) {
            Ok(ji) => ji,
            Err(e) => return self.refuse(&meta, e),
        };
        let Some(request) = start else {
            let axis = Axis::of(motor.to_owned(), ji, [ask.order]);
            self.command_job(now, meta, vec![axis], Report::default());
            return;
        };
        // A calibration moves the joint: refused as a motion is, and its
        // own limits held to the limits in force.
        if let Err(e) = self.admission().admit_now(std::iter::once(motor)) {
            return self.refuse(&meta, e);
        }
        let phases = match crate::device::irpc::calibration_time(&self.map, motor, &request) {
            Ok(t) => t,
            Err(r) => return self.refuse(&meta, Refusal::gate(r)),
        };
        let deadline = now
            .saturating_add(self.answer_wait())
            .saturating_add(phases)
            .saturating_add(CALIBRATION_MARGIN);
        self.open_waiting(now, meta, (motor, ji), ask.order, ask.awaits, deadline);
    }

    /// Line `meta`'s request `order` to `device` (its name and id),
    /// whose result waits for its answer of `kind` until `deadline`.
    pub(super) fn open_waiting(
        &mut self,
        now: Duration,
        meta: LineMeta,
        device: (&str, DeviceId),
        order: Order,
        kind: AwaitKind,
        deadline: Duration,
    ) {
        let (motor, ji) = device;
        let awaiting = Awaiting {
            joint: ji,
            kind,
            deadline,
        };
        let id = self.jobs.next_id();
        let axis = Axis::of(motor.to_owned(), ji, [order]);
        self.command_job(now, meta, vec![axis], Report::default());
        // Not done yet (a job is taken out once done): it waits.
        if let Some(job) = self.jobs.get_mut(&id) {
            job.awaiting = Some(awaiting);
        }
    }

    /// Device `ji` answered what a request line may wait for: progress
    /// is reported, and the oldest line waiting for this from this device
    /// gets its data.
    pub(super) fn answered(&mut self, ji: DeviceId, answer: Answer) {
        let (kind, data, error) = match answer {
            Answer::Progress(e) => {
                self.out.push_back(Output::Event(e));
                return;
            }
            Answer::Data { kind, data, error } => (kind, data, error),
        };
        let Some(job) = self
            .jobs
            .values_mut()
            .find(|j| j.awaiting.is_some_and(|a| a.joint == ji && a.kind == kind))
        else {
            return;
        };
        job.awaiting = None;
        job.data_error = error;
        job.data = Some(data);
        self.finish_jobs();
    }

    /// Request lines whose answer did not come in time.
    pub(super) fn awaiting_timeouts(&mut self, now: Duration) {
        let mut any = false;
        for job in self.jobs.values_mut() {
            let Some(a) = job.awaiting.filter(|a| now >= a.deadline) else {
                continue;
            };
            job.awaiting = None;
            let what = match a.kind {
                AwaitKind::Telemetry => "TelemetryStream",
                AwaitKind::PowerMetrics => "PowerMetrics",
                AwaitKind::FaultHistory => "FaultHistory",
                AwaitKind::CalibrationResult => "CalibrationResult",
            };
            let motor = job
                .axes
                .first()
                .map(|x| x.motor.clone())
                .unwrap_or_default();
            job.data_error = Some(format!(
                "{motor} acked the request, but no {what} came within {} ms",
                now.saturating_sub(job.received).as_millis()
            ));
            any = true;
        }
        if any {
            self.finish_jobs();
        }
    }

    // ---- arrival ----------------------------------------------------------

    /// Everything the drivers have to tell, acted on in order.
    pub(super) fn drain_drivers(&mut self) {
        while let Some(h) = self.drivers.poll(&self.map, &self.joints) {
            self.happened(h);
        }
        self.finish_jobs();
    }

    /// What a driver told, acted on the same way for every dialect.
    pub(super) fn happened(&mut self, h: Happened) {
        match h {
            Happened::Heard { device, at, up } => self.heard(device, at, up),
            Happened::Reading {
                device,
                at,
                motion,
                feedback,
            } => self.reading(device, at, motion, feedback.map(|f| *f)),
            Happened::Ended { device, ended } => self.step_done(device, ended),
            Happened::Lifecycle {
                device,
                state,
                code,
            } => self.lifecycle(device, state, code),
            Happened::StoppedItself {
                device,
                at,
                reason,
                code,
            } => {
                let Some(name) = self
                    .joints
                    .get(device)
                    .map(|j| j.identity.name().to_owned())
                else {
                    return;
                };
                self.joint_lost(
                    device,
                    format!("stopped itself ({reason})"),
                    Event::JointFault {
                        motor_id: name.clone(),
                        code,
                        reason: Some(reason.clone()),
                    },
                );
                // A joint's own emergency stop stops every joint: the arm is
                // not safe to move with one of them down.
                self.emergency_stop(at, None, Vec::new(), format!("{name}: {reason}"));
            }
            Happened::Answer { device, answer } => self.answered(device, answer),
            Happened::Bad { report } => {
                self.stats.bad_frames += 1;
                if let Some(e) = report {
                    self.out.push_back(Output::Event(e));
                }
            }
            Happened::Event(e) => self.out.push_back(Output::Event(e)),
            Happened::LinkLost {
                devices,
                offline,
                arrival,
            } => self.link_lost(&devices, &offline, &arrival),
            Happened::MayGo { devices } => {
                for ji in devices {
                    self.pump(ji);
                }
                self.finish_jobs();
            }
        }
    }

    /// The link to `devices` is lost: they are offline (`why`), no
    /// deadman watches them, and lines waiting on them will not arrive
    /// (`arrival`); what waits for them is not sent.
    pub(super) fn link_lost(&mut self, devices: &[DeviceId], why: &str, arrival: &str) {
        for &ji in devices {
            if let Some(j) = self.joints.get_mut(ji) {
                j.liveness.disarm_deadman();
                if j.liveness.went_offline() {
                    self.out.push_back(Output::Event(Event::Offline {
                        motor_id: j.identity.name().to_owned(),
                        node: j.identity.node(),
                        reason: why.to_owned(),
                    }));
                }
            }
        }
        self.fail_watches(|w| devices.iter().any(|&ji| w.waits_on(ji)), arrival);
        for &ji in devices {
            self.pump(ji);
        }
        self.finish_jobs();
        // Starting, a device lost is no longer waited for.
        self.try_ready();
    }
}
