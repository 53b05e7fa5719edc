//! The stop: the emergency stop and its latch, what it cancels, the release, the deadman, and the bridge's own stops confirmed.

use super::*;

impl Bridge {
    /// An emergency stop, asked by the line `meta` (or by the bridge
    /// itself: `None`) because of `cause`.
    pub(super) fn emergency_stop(
        &mut self,
        now: Duration,
        meta: Option<LineMeta>,
        problems: Vec<String>,
        cause: String,
    ) {
        if matches!(self.phase, Phase::Finished) {
            return self.stop_after_the_end(meta, problems);
        }
        // Every stop counts for what was written before it, a stop that
        // rides on another one too.
        let unix_ms = self
            .config
            .epoch_unix_ms
            .map(|e| e + now.as_secs_f64() * 1000.0);
        self.stop.stopped(now, unix_ms);
        // A stop already under way (latched, not released since) answers
        // this line too: its Deactivates are in flight or queued first, and
        // sending them again would only add frames ahead of nothing.
        if self.stop.is_latched()
            && let Some(job) = self
                .jobs
                .values_mut()
                .rev()
                .find(|j| j.kind == JobKind::EmergencyStop)
        {
            self.stats.stops_coalesced += 1;
            if let Some(line) = meta {
                job.riders.push(Rider {
                    line,
                    problems,
                    received: now,
                });
            }
            return;
        }
        self.stats.emergency_stops += 1;
        let resume = self.to_resume();
        self.stop.latch(resume);
        self.fail_watches(|_| true, "stopped by the emergency stop");
        let cancelled = self.cancel_everything("cancelled by the emergency stop");
        self.out
            .push_back(Output::Event(Event::EmergencyStop { cause, cancelled }));
        let axes = self.every_joint(&[Lifecycle::Deactivate]);
        self.open_job(
            meta,
            JobKind::EmergencyStop,
            now,
            axes,
            Report::default(),
            problems,
        );
        if matches!(self.phase, Phase::Starting(_)) {
            // The startup was cancelled: lines are served (and refused
            // while latched).
            self.enter(Phase::Running);
        }
    }

    /// A stop after the end: nothing runs any more, the joints were
    /// deactivated. The line `meta` (if any, with its `problems`) is told
    /// so.
    fn stop_after_the_end(&mut self, meta: Option<LineMeta>, problems: Vec<String>) {
        if let Some(meta) = meta {
            let r = LineResult {
                ok: false,
                line: meta.number,
                emergency_stop: true,
                problems,
                error: Some(Refusal::AlreadyStopped.into()),
                ..LineResult::default()
            };
            self.answer(&meta, r);
        } else {
            self.stats.failed += 1;
        }
    }

    /// What the release brings back: the joints active now, and those
    /// whose startup or release a stop now interrupts (the lifecycle steps
    /// it had yet to take).
    fn to_resume(&self) -> Vec<(DeviceId, Vec<Lifecycle>)> {
        let mut resume = Vec::new();
        for (i, j) in self.joints.with_ids() {
            let starting = j.schedule.steps().find_map(|s| {
                let job = self.jobs.get(&s.job)?;
                matches!(job.kind, JobKind::Startup | JobKind::Release).then(|| {
                    let a = job.axes.get(s.axis)?;
                    let step = Order::lifecycle;
                    let mut p: Vec<Lifecycle> = a.payloads.iter().filter_map(step).collect();
                    if let AxisState::InFlight { payload, .. } = a.state
                        && let Some(first) = step(&payload)
                    {
                        p.insert(0, first);
                    }
                    Some(p)
                })?
            });
            if let Some(p) = starting {
                resume.push((i, p));
            } else if j.lifecycle.is_active() {
                resume.push((i, vec![Lifecycle::Activate]));
            }
        }
        resume
    }

    /// Cancels every step queued or in flight (never sent again); returns
    /// the input lines affected.
    pub(super) fn cancel_everything(&mut self, why: &str) -> Vec<LineRef> {
        self.cancel_where(why, |_| true)
    }

    /// `origin` is gone (disconnected by its runner: it stopped reading,
    /// or its connection failed). Its lines not yet done are cancelled:
    /// steps waiting are never sent, requests in flight never sent again
    /// (the joint may have taken one; a stop still stops it). Said on the
    /// event stream as `client_dropped`, since the client cannot be told.
    /// Its line count is forgotten.
    pub(super) fn on_client_left(&mut self, origin: Origin, reason: &str) {
        self.line_numbers.remove(&origin);
        self.clocks.forget(origin);
        let gone = match &mut self.phase {
            Phase::Starting(s) => s.forget(origin),
            _ => Vec::new(),
        };
        self.stats.cancelled += gone.len() as u64;
        let mut cancelled: Vec<LineRef> = gone
            .iter()
            .map(|w| LineRef {
                origin,
                line: w.meta.number,
            })
            .collect();
        let why = format!("cancelled: the client was disconnected ({reason})");
        cancelled.extend(self.cancel_where(&why, |job| {
            job.is_of(origin) && job.kind == JobKind::Command
        }));
        cancelled.sort_by_key(|r| r.line);
        cancelled.dedup();
        self.arrivals.retain(|w| w.line.origin != origin);
        self.out.push_back(Output::Event(Event::ClientDropped {
            origin,
            reason: reason.to_owned(),
            cancelled,
        }));
        for ji in self.joints.ids() {
            self.pump(ji);
        }
        self.finish_jobs();
    }

    /// Cancels the steps (queued or in flight) of the jobs `pick` chooses;
    /// returns the input lines affected.
    pub(super) fn cancel_where(&mut self, why: &str, pick: impl Fn(&Job) -> bool) -> Vec<LineRef> {
        let mut touched = Vec::new();
        // Setpoints sent and never answered: they may be running.
        let mut maybe_held = Vec::new();
        // Steps whose frame or line was made and never handed out (still
        // waiting in poll_transmit's or poll_link_line's queue): taken
        // back, so what is cancelled never reaches a device after the
        // cancel (a stop goes ahead of them, not behind).
        let picked = |b: &Bridge, ji: DeviceId| {
            b.joints
                .get(ji)
                .and_then(|j| j.schedule.busy())
                .is_some_and(|s| b.jobs.get(&s.job).is_some_and(&pick))
        };
        let chosen: BTreeSet<DeviceId> = self.joints.ids().filter(|&ji| picked(self, ji)).collect();
        let unsent = self.drivers.take_back_unsent(&chosen);
        for ji in self.joints.ids() {
            let Some(joint) = self.joints.get_mut(ji) else {
                continue;
            };
            let busy = joint
                .schedule
                .take_busy_if(|s| self.jobs.get(&s.job).is_some_and(&pick));
            let queued = joint
                .schedule
                .take_waiting_where(|s| self.jobs.get(&s.job).is_some_and(&pick));
            if let Some(s) = busy {
                let taken_back = unsent.contains(&ji);
                self.cancel_busy(ji, s, why, taken_back, &mut maybe_held, &mut touched);
            }
            for s in queued {
                if let Some(line) = self.jobs.cancel_waiting(s, why) {
                    self.stats.cancelled += 1;
                    touched.extend(line);
                }
            }
        }
        // The deadman watches what may be running, as if it were acked.
        for (ji, payload) in maybe_held {
            self.track(ji, payload, self.now);
        }
        touched.sort_by_key(|r| (r.origin, r.line));
        touched.dedup();
        self.finish_jobs();
        touched
    }

    /// Cancels step `s`, the one device `ji` is busy with (cut by `why`):
    /// its request forgotten by its driver, the device woken for nothing.
    /// A step `taken_back` (its frame or line never handed out) is
    /// cancelled before it was sent; one in flight may have run (a
    /// setpoint it holds is added to `maybe_held`). Its line is added to
    /// `touched`.
    fn cancel_busy(
        &mut self,
        ji: DeviceId,
        s: StepRef,
        why: &str,
        taken_back: bool,
        maybe_held: &mut Vec<(DeviceId, Order)>,
        touched: &mut Vec<LineRef>,
    ) {
        let Some(job) = self.jobs.get_mut(&s.job) else {
            return;
        };
        let Some(a) = job.axes.get_mut(s.axis) else {
            return;
        };
        if let AxisState::InFlight { msg_id, payload } = a.state {
            self.drivers.forget(ji, msg_id, payload);
        }
        if let Some(joint) = self.joints.get_mut(ji) {
            joint.schedule.clear_wake();
        }
        if taken_back {
            a.finish(
                StepOutcome::Cancelled,
                None,
                format!("{why} before it was sent"),
            );
            // Its frame or line was taken back: nothing of the job
            // waits to be written unless another of its steps is
            // in flight (whose answer comes after its writing).
            if !job
                .axes
                .iter()
                .any(|x| matches!(x.state, AxisState::InFlight { .. }))
            {
                job.unflushed = false;
            }
        } else {
            if let AxisState::InFlight { payload, .. } = a.state
                && payload.holds_setpoint()
            {
                maybe_held.push((ji, payload));
            }
            cut_after_sending(a, why);
        }
        job.cut.get_or_insert_with(|| why.to_owned());
        self.stats.cancelled += 1;
        touched.extend(job.line_ref());
    }

    pub(super) fn release(&mut self, now: Duration, meta: LineMeta) {
        let Some(resume) = self.stop.release() else {
            self.refuse(&meta, Refusal::NotLatched);
            return;
        };
        let reactivated = resume
            .keys()
            .filter_map(|i| self.joints.get(*i))
            .map(|j| j.identity.name().to_owned())
            .collect();
        let left_inactive = self
            .joints
            .with_ids()
            .filter(|(i, j)| {
                !resume.contains_key(i) && j.identity.device().supports(Capability::Lifecycle)
            })
            .map(|(_, j)| j.identity.name().to_owned())
            .collect();
        self.out.push_back(Output::Event(Event::Released {
            reactivated,
            left_inactive,
        }));
        let axes = resume
            .into_iter()
            .filter_map(|(i, p)| {
                let orders = self.orders_for(i, &p);
                Some(Axis::of(
                    self.joints.get(i)?.identity.name().to_owned(),
                    i,
                    orders,
                ))
            })
            .collect();
        self.open_job(
            Some(meta),
            JobKind::Release,
            now,
            axes,
            Report::default(),
            Vec::new(),
        );
    }

    /// `payloads`, in order, for every joint.
    pub(super) fn every_joint(&self, steps: &[Lifecycle]) -> Vec<Axis> {
        self.joints
            .with_ids()
            .map(|(i, j)| Axis::of(j.identity.name().to_owned(), i, self.orders_for(i, steps)))
            .collect()
    }

    /// Lifecycle `payloads` as device `ji` takes them
    /// ([`Device::lifecycle_orders`]).
    pub(super) fn orders_for(&self, ji: DeviceId, steps: &[Lifecycle]) -> Vec<Order> {
        let now_ms = self.unix_ms(self.now) as u64;
        self.joints
            .get(ji)
            .map(|j| j.identity.device().lifecycle_orders(steps, now_ms))
            .unwrap_or_default()
    }

    // ---- jobs and the joint queues -------------------------------------------

    /// Devices holding a velocity or torque setpoint that was not renewed
    /// within their command timeout are brought to a stop (velocity 0),
    /// and an event says so.
    pub(super) fn deadman(&mut self, now: Duration) {
        // Latched, every device was sent its stop: a setpoint's deadman
        // (one armed by an answer that came after the stop) has nothing
        // to stop, and nothing but stops goes out.
        if self.stop.is_latched() {
            for j in self.joints.iter_mut() {
                j.liveness.disarm_deadman();
            }
            return;
        }
        let mut due = self.joints_where(|j| j.liveness.deadman().is_some_and(|d| now >= d));
        // A device whose stop is in flight (a motor line's hold, free or
        // stop) is being stopped: the deadman's own stop behind it would
        // only undo a hold (a moteus controller's stop mode is torque off).
        // It looks again [`REBRAKE_AFTER`] on: the stop taken disarms it;
        // one lost, answered no or not sent leaves it to stop the device.
        due.retain(|&ji| {
            let stopping = self
                .joints
                .get(ji)
                .and_then(|j| j.schedule.busy())
                .and_then(|s| self.jobs.axis(s))
                .is_some_and(|a| {
                    matches!(a.state, AxisState::InFlight { payload, .. } if payload.ends_setpoint())
                });
            if stopping && let Some(j) = self.joints.get_mut(ji) {
                j.liveness.deadman_at(Some(now.saturating_add(REBRAKE_AFTER)));
            }
            !stopping
        });
        self.hold_still(now, due, true);
    }

    /// Brings devices `which` (each holding a velocity or torque setpoint)
    /// to a stop, velocity 0, as the deadman does; `timed_out`: it is the
    /// deadman, and an event says so (at the end of input the `stopping`
    /// event does).
    pub(super) fn hold_still(&mut self, now: Duration, which: Vec<DeviceId>, timed_out: bool) {
        let now_ms = self.unix_ms(now) as u64;
        for ji in which {
            let Some(j) = self.joints.get_mut(ji) else {
                continue;
            };
            let name = j.identity.name().to_owned();
            let Some(order) = j.identity.device().hold_still(now_ms) else {
                j.liveness.disarm_deadman();
                continue;
            };
            let event = timed_out.then(|| Event::Deadman {
                motor_id: name.clone(),
                timeout_ms: self
                    .map
                    .motor(&name)
                    .and_then(|m| m.command_timeout)
                    .map_or(0, |t| u64::try_from(t.as_millis()).unwrap_or(u64::MAX)),
            });
            self.stop_setpoint(now, ji, order, event);
        }
    }

    /// Device `ji`'s velocity or torque setpoint ended by `order` (its
    /// stop), ahead of anything waiting for the device, `event` said.
    pub(super) fn stop_setpoint(
        &mut self,
        now: Duration,
        ji: DeviceId,
        order: Order,
        event: Option<Event>,
    ) {
        let Some(j) = self.joints.get_mut(ji) else {
            return;
        };
        j.liveness.disarm_deadman();
        let name = j.identity.name().to_owned();
        let axis = Axis::of(name, ji, [order]);
        if let Some(e) = event {
            self.out.push_back(Output::Event(e));
        }
        // Ahead of anything waiting for the device.
        if let Some(j) = self.joints.get_mut(ji) {
            for s in j.schedule.take_all_waiting() {
                if let Some(a) = self.jobs.axis_mut(s) {
                    a.finish(
                        StepOutcome::Cancelled,
                        None,
                        "cancelled: the deadman stopped the device first",
                    );
                }
            }
        }
        self.own_stop(now, axis);
    }

    /// The deceleration a motor is braked with before a position limit
    /// (its unit a second squared): the lesser of the limits' deceleration
    /// and acceleration in force, `None` when they give neither.
    pub(super) fn braking(limits: &Limits) -> Option<f64> {
        match (limits.max_deceleration, limits.max_acceleration) {
            (Some(d), Some(a)) => Some(d.min(a)),
            (d, a) => d.or(a),
        }
        .filter(|d| d.is_finite() && *d > 0.0)
    }

    /// How far a motor going at `v` goes before it stops, braked at
    /// [`Self::braking`] (0 when the limits give no deceleration).
    /// How fast (its unit a second, a magnitude) a joint going at `v` goes
    /// [`BRAKE_LOOKAHEAD`] on, and how far it gets meanwhile: faster where
    /// its reports show it speeding up the way it goes (a torque drives
    /// it, or a velocity it is still getting up to), at that acceleration.
    pub(super) fn lookahead(j: &Joint, m: &motorwire_translate::MappedMotor, v: f64) -> (f64, f64) {
        let t = BRAKE_LOOKAHEAD.as_secs_f64();
        let a = j
            .motion
            .reported_at()
            .map(|(_, a)| m.unit.from_degrees(a))
            .filter(|a| a.is_finite() && a * v > 0.0)
            .map_or(0.0, f64::abs);
        ahead(v.abs(), a, t)
    }

    pub(super) fn stopping(limits: &Limits, v: f64) -> f64 {
        Self::braking(limits).map_or(0.0, |d| v * v / (2.0 * d))
    }

    /// A stop taken on an acknowledgement that may have been another
    /// frame's (a compact device's: [`Order::unconfirmed_stop`]), judged by
    /// the feedback heard `at`, [`REBRAKE_AFTER`] after it was taken and
    /// for [`CONFIRM_STOP_FOR`]: still enabled after a disable or an
    /// emergency stop (seen disabled, it is confirmed), or going at least as
    /// fast as when it was taken (or, taken at rest, moving) after a
    /// velocity 0, it
    /// was lost on the bus and is sent again with this time's timestamp,
    /// unless a newer step waits for the device; while the emergency stop
    /// is latched only an emergency stop is. Sent [`MAX_STOP_RESENDS`]
    /// times and still contradicted: when in doubt, stop (the emergency
    /// stop). (A velocity 0 lost on a device held still by a torque against
    /// something shows nothing to judge by: the deadman is what stops it.)
    pub(super) fn confirm_stop(&mut self, ji: DeviceId, at: Duration) {
        // (Every feedback comes here: nothing is looked up for a device
        // with no stop to judge.)
        if self
            .joints
            .get(ji)
            .is_none_or(|j| j.stop_check.unconfirmed().is_none())
        {
            return;
        }
        let latched = self.stop.is_latched();
        let still = self
            .joints
            .get(ji)
            .and_then(|j| self.map.motor(j.identity.name()))
            .and_then(|m| m.limits.max_velocity)
            .map_or(1e-3, |v| (v.abs() * 1e-3).max(1e-9));
        let Some(j) = self.joints.get_mut(ji) else {
            return;
        };
        let (Some((order, acked, speed)), Some(f)) =
            (j.stop_check.unconfirmed(), j.motion.feedback())
        else {
            return;
        };
        let Some(disables) = order.unconfirmed_stop() else {
            return;
        };
        let emergency = order.is_emergency_stop();
        let lost = if disables {
            if f.status.enabled == Some(false) && at >= acked {
                j.stop_check.settle();
                return;
            }
            f.status.enabled == Some(true)
        } else {
            // Not slowing at all (a device braking, however gently, is
            // slower 50 ms on), or moving where it was taken at rest.
            f.velocity.abs() > (0.99 * speed).max(still)
        };
        if (latched && !emergency) || at > acked.saturating_add(CONFIRM_STOP_FOR) {
            j.stop_check.settle();
            return;
        }
        if !lost
            || at < acked.saturating_add(REBRAKE_AFTER)
            || j.schedule.busy().is_some()
            || j.schedule.has_waiting()
        {
            return;
        }
        j.stop_check.stop_judging();
        let seen = if disables {
            "shown enabled by its feedback"
        } else {
            "shown moving by its feedback"
        };
        self.stop_again(ji, order, at.max(self.now), seen);
    }

    /// The bridge's own stop of one device (the deadman's, a limit brake,
    /// a stop sent again), as a job of no line.
    pub(super) fn own_stop(&mut self, now: Duration, axis: Axis) {
        self.open_job(
            None,
            JobKind::Deadman,
            now,
            vec![axis],
            Report::default(),
            Vec::new(),
        );
    }

    /// A stop of device `ji` that its device was not seen to take (`why`:
    /// not answered, or contradicted by its feedback) sent again, with
    /// `now`'s timestamp; the [`MAX_STOP_RESENDS`]-th time, when in doubt,
    /// the emergency stop instead (latched already: nothing more).
    pub(super) fn stop_again(&mut self, ji: DeviceId, order: Order, now: Duration, why: &str) {
        let now_ms = self.unix_ms(now) as u64;
        let latched = self.stop.is_latched();
        let Some(j) = self.joints.get_mut(ji) else {
            return;
        };
        if latched && !order.is_emergency_stop() {
            return;
        }
        if !j.stop_check.resend(MAX_STOP_RESENDS) {
            if !latched {
                let cause = format!(
                    "{}: its stop was sent {} times and not taken ({why})",
                    j.identity.name(),
                    MAX_STOP_RESENDS + 1
                );
                self.emergency_stop(now, None, Vec::new(), cause);
            }
            return;
        }
        self.stats.stops_sent_again += 1;
        let axis = Axis::of(j.identity.name().to_owned(), ji, [order.restamped(now_ms)]);
        self.own_stop(now, axis);
    }
}

/// Axis `a`, sent and cut by `why` before it ended: a request in flight
/// not answered may have run, and is never sent again; a trajectory
/// between segments never sends the rest.
fn cut_after_sending(a: &mut Axis, why: &str) {
    if matches!(a.state, AxisState::InFlight { .. }) {
        // Sent and not answered: it may have run. Never sent again.
        a.finish(
            StepOutcome::OutcomeUnknown,
            None,
            format!(
                "{why}: it was sent before and not answered, so the joint may have started it; it is never sent again"
            ),
        );
    } else {
        // A trajectory between segments: the rest never sent.
        a.finish(
            StepOutcome::Cancelled,
            None,
            format!("{why}: the trajectory's remaining segments were never sent"),
        );
    }
}
