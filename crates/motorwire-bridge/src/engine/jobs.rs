//! Jobs: opened, superseded, their steps sent one by one per device, taken and tracked.

use std::ops::ControlFlow;

use super::*;

impl Bridge {
    pub(super) fn open_job(
        &mut self,
        line: Option<LineMeta>,
        kind: JobKind,
        now: Duration,
        axes: Vec<Axis>,
        report: Report,
        problems: Vec<String>,
    ) {
        let id = self.jobs.new_id();
        if kind.is_stop() {
            self.cancel_everything("cancelled by the stop");
        }
        let mut axes = axes;
        if kind == JobKind::Command {
            self.activate_freed(&mut axes);
        }
        // A stream's setpoint replaces any setpoint waiting for its motor
        // (position, velocity, torque); an ordinary position move, a
        // waiting position move.
        let stream = line.as_ref().is_some_and(|l| l.stream);
        // What each step takes over on its device: `Some(replaces)` for a
        // motion step that goes as soon as it can (one that waits for a
        // sequence takes its device when its turn comes:
        // `Self::sequence_progress`); `replaces`, a position move or a
        // stream's setpoint.
        // (Collected into a list kept from the last job: a line's job is
        // opened for every line.)
        let mut steps = std::mem::take(&mut self.steps_scratch);
        steps.clear();
        steps.extend(axes.iter().enumerate().map(|(axis, a)| {
            let replaces = a.is_position_move() || (stream && a.is_setpoint());
            let motion = a.first_asked().is_some_and(Order::is_setpoint);
            // A trajectory's steps are timed: it replaces a waiting
            // sequential axis, and otherwise queues behind what is
            // there (one running, one scheduled), as it always did.
            let timed = !a.due.is_empty();
            let takes =
                (a.after.is_none() && (replaces || motion)).then_some(Takes { replaces, timed });
            (a.joint, StepRef { job: id, axis }, takes)
        }));
        self.jobs.open(
            id,
            Box::new(Job::new(line, kind, now, axes, report, problems)),
        );
        for &(ji, step, takes) in &steps {
            let scheduled = match takes {
                Some(Takes { replaces, timed }) if kind == JobKind::Command => {
                    self.supersede(ji, stream, replaces, timed, None)
                }
                _ => None,
            };
            if let Some(j) = self.joints.get_mut(ji) {
                j.schedule.wait(step);
                // A trajectory scheduled to start later goes at its time,
                // after this step.
                j.schedule.wait_all(scheduled);
            }
        }
        // Every step queued before any is sent: the Orion motors of one
        // line go out as one line.
        for &(ji, _, _) in &steps {
            self.pump(ji);
        }
        // Kept for the next job (one opened meanwhile found it empty and
        // made its own: the larger is kept).
        if steps.capacity() >= self.steps_scratch.capacity() {
            self.steps_scratch = steps;
        }
        self.finish_jobs();
    }

    /// A command line's axes for joints a line left inactive (`disabled`,
    /// `free`, `stop`): a motion is preceded by an Activate, so the next
    /// command undoes them (a joint inactive for another reason, a fault,
    /// waits for a reset line). An axis that deactivates its joint marks
    /// it so.
    pub(super) fn activate_freed(&mut self, axes: &mut [Axis]) {
        for a in axes {
            let Some(j) = self.joints.get_mut(a.joint) else {
                continue;
            };
            if !j.identity.device().supports(Capability::Lifecycle) {
                continue;
            }
            let deactivates = a
                .payloads
                .iter()
                .any(|o| o.lifecycle() == Some(Lifecycle::Deactivate));
            // Only a joint the bridge had up (or a line had freed): one
            // never started, or whose start failed, waits for a reset.
            if deactivates {
                j.lifecycle.freed_by_a_line();
            } else if j.lifecycle.is_freed() && a.payloads.front().is_some_and(Order::is_setpoint) {
                for activate in j
                    .identity
                    .device()
                    .lifecycle_orders(&[Lifecycle::Activate], 0)
                {
                    a.payloads.push_front(activate);
                    if let Some(&first) = a.due.front() {
                        a.due.push_front(first);
                    }
                }
            }
        }
    }

    /// A newer motion step for device `ji` (a position move or a stream's
    /// setpoint: `replaces`; a trajectory's timed step: `timed`), other
    /// than `except`, is about to go: what
    /// waits for the device and would run before it is replaced. A
    /// position move waiting is replaced by a newer position move; any
    /// setpoint by a stream's (`stream`); an axis of a sequential line
    /// waiting for its turn by any newer motion (it would hold the device
    /// for another motor's arrival). A trajectory running on the device is
    /// replaced by a position move or a stream's setpoint: its later
    /// segments are not sent (between segments it ends now and frees the
    /// device; with a segment in flight, once that is answered). A
    /// trajectory scheduled to start later and not begun is not replaced:
    /// it is taken off the device and returned, to be queued again after
    /// the newer step (it starts at its time).
    pub(super) fn supersede(
        &mut self,
        ji: DeviceId,
        stream: bool,
        replaces: bool,
        timed: bool,
        except: Option<StepRef>,
    ) -> Option<StepRef> {
        let joint = self.joints.get_mut(ji)?;
        // Only what is older than the newer step: queued before it. Kept
        // in place, in order (the queue keeps its room: no allocation a
        // line).
        let mut newer = false;
        joint.schedule.retain_waiting(|s| {
            newer |= Some(s) == except;
            let replaced = !newer && self.jobs.supersede_waiting(s, stream, replaces);
            if replaced {
                self.stats.superseded += 1;
            }
            !replaced
        });
        // A trajectory (`timed`) waits its turn behind what holds the device.
        if timed {
            return None;
        }
        let running = joint.schedule.busy()?;
        match self.jobs.supersede_running(running, replaces) {
            Running::Kept => None,
            // Scheduled, not begun: it waits for its time, holding the
            // device.
            Running::Rescheduled => {
                joint.schedule.release();
                Some(running)
            }
            Running::Replaced { freed } => {
                self.stats.superseded += 1;
                if freed {
                    joint.schedule.release();
                }
                None
            }
        }
    }

    /// Device `ji` took a move or setpoint of job `by`, of `line` (`None`:
    /// the bridge's own): the lines watched on it for an earlier move will
    /// not arrive (superseded by `line`), and a sequential line whose axis
    /// on it was sent and has not arrived ends at once
    /// ([`Self::end_sequences_on`]).
    pub(super) fn taken(&mut self, ji: DeviceId, by: u64, line: Option<LineRef>) {
        if let Some(j) = self.joints.get_mut(ji) {
            j.schedule.taken_from(line);
        }
        let Some(line) = line else { return };
        let why = || crate::output::json::superseded_by(line);
        self.fail_watches_with(|w| w.line.at() != line && w.waits_on(ji), why);
        self.end_sequences_on(ji, by, line);
    }

    /// A newer line (job `by`, `line`) moved device `ji`: a sequential
    /// line whose axis on `ji` was sent and has not arrived will not see
    /// it arrive (its target is replaced), so the axes waiting for that
    /// arrival (and those waiting for them) are not sent, at once (not
    /// when the arrival's time runs out), and leave their devices' queues;
    /// the line then ends, and its completion says it was superseded.
    pub(super) fn end_sequences_on(&mut self, ji: DeviceId, by: u64, line: LineRef) {
        let (number, origin) = (line.line, line.origin.0);
        let mut ended: Vec<StepRef> = Vec::new();
        for (&id, job) in self.jobs.iter_mut() {
            if id == by || job.kind != JobKind::Command {
                continue;
            }
            // Its axes on `ji` that went out and have not arrived.
            let replaced = |a: &Axis| a.joint == ji && !a.arrived && a.state != AxisState::Queued;
            let mut cut: Vec<usize> = job
                .axes
                .iter()
                .enumerate()
                .filter(|(_, a)| replaced(a))
                .map(|(k, _)| k)
                .collect();
            // Every axis waiting on one of them, and on those in turn.
            let mut k = 0;
            while let Some(&b) = cut.get(k) {
                k += 1;
                let waiting: Vec<usize> = job
                    .axes
                    .iter()
                    .enumerate()
                    .filter(|(_, a)| a.state == AxisState::Queued && a.after == Some(b))
                    .map(|(w, _)| w)
                    .collect();
                for w in waiting {
                    if let Some(a) = job.axes.get_mut(w) {
                        a.finish(
                            StepOutcome::NotSent,
                            None,
                            format!(
                                "not sent: the axis before it was replaced by line {number} of client {origin} before it arrived"
                            ),
                        );
                        ended.push(StepRef { job: id, axis: w });
                        cut.push(w);
                    }
                }
            }
            // Nothing waits for them now.
            for a in job.axes.iter_mut().filter(|a| replaced(a)) {
                a.arrive_by = None;
            }
        }
        for step in ended {
            for j in self.joints.iter_mut() {
                j.schedule.retain_waiting(|s| s != step);
            }
        }
    }

    /// A move in flight whose answer is late is sent again by its
    /// driver's retries; sent again, it goes now: its path is held to the
    /// limits in force from where the device is now, as a move's is when
    /// it is first sent. One that would leave them is withdrawn instead:
    /// never sent again, its outcome unknown (its first sending may have
    /// been taken).
    pub(super) fn withdraw_stale_resends(&mut self, now: Duration) {
        for ji in self.joints.ids() {
            let Some(step) = self.joints.get(ji).and_then(|j| j.schedule.busy()) else {
                continue;
            };
            let Some(&AxisState::InFlight { msg_id, payload }) =
                self.jobs.axis(step).map(|a| &a.state)
            else {
                continue;
            };
            if !self.drivers.resend_due(msg_id, &payload, now) {
                continue;
            }
            let Some(why) = self.path_at_send(ji, &payload) else {
                continue;
            };
            self.drivers.forget(ji, msg_id, payload);
            self.stats.refused_at_send += 1;
            if let Some(j) = self.joints.get_mut(ji) {
                j.schedule.clear_busy();
                j.motion.not_sending();
            }
            if let Some(a) = self.jobs.axis_mut(step) {
                let why = why.replacen(
                    "not sent:",
                    "sent once and not answered; not sent again:",
                    1,
                );
                a.finish(
                    StepOutcome::OutcomeUnknown,
                    None,
                    format!("{why}; the joint may or may not have taken its first sending"),
                );
            }
            self.pump(ji);
        }
        self.finish_jobs();
    }

    /// Why `order` may not go to device `ji` now: its path, planned from
    /// where the device is now, leaves the limits in force (`None` when
    /// it stays within them, or nothing is known to plan from: the
    /// device's own check stands).
    pub(super) fn path_at_send(&self, ji: DeviceId, order: &Order) -> Option<String> {
        let j = self.joints.get(ji)?;
        let from = j.state_at(self.now)?;
        // Checked already when its line came, this instant, from there.
        let checked = j
            .motion
            .planned()
            .filter(|_| j.motion.planned_at() == self.now)
            .map(|(from, p, _)| (from, p));
        let refusal = order.path_refusal(from, checked, || {
            let motor = self.map.motor(j.identity.name())?;
            Some((motor, motorwire_translate::Effective::from_bus_map(motor)))
        })?;
        Some(format!(
            "not sent: from where it was when its turn came ({} at {} a second), {refusal}",
            short_unit(j.identity.unit().from_degrees(from.0)),
            short_unit(j.identity.unit().from_degrees(from.1))
        ))
    }

    /// The step at the front of device `ji`'s queue, if none of its
    /// steps is in flight.
    pub(super) fn waiting_front(&self, ji: DeviceId) -> Option<StepRef> {
        let j = self.joints.get(ji)?;
        if j.schedule.busy().is_some() {
            return None;
        }
        j.schedule.next_waiting()
    }

    /// Sends the next waiting step of joint `ji` if none is in flight.
    pub(super) fn pump(&mut self, ji: DeviceId) {
        let now = self.now;
        loop {
            let Some(front) = self.waiting_front(ji) else {
                return;
            };
            if self.waits_for_arrival(front, now) {
                return; // sequential: the axis before it has not arrived
            }
            if !self.link_free(front) {
                return; // one line in flight to the Orion controller
            }
            let Some(joint) = self.joints.get_mut(ji) else {
                return;
            };
            let Some(step) = joint.schedule.take_next() else {
                return;
            };
            let node = joint.identity.node();
            if self.send_step(now, ji, node, step) {
                return;
            }
        }
    }

    /// Whether `step` (a sequential axis) must wait for the axis before it
    /// to arrive. When that axis failed, or did not arrive in time, `step`
    /// is finished `not_sent` here and need not wait.
    pub(super) fn waits_for_arrival(&mut self, step: StepRef, now: Duration) -> bool {
        let Some(job) = self.jobs.get(&step.job) else {
            return false;
        };
        // An axis already finished waits for nothing: it leaves its queue.
        let Some(before) = job
            .axes
            .get(step.axis)
            .filter(|a| !a.is_done())
            .and_then(|a| a.after)
        else {
            return false;
        };
        let Some(b) = job.axes.get(before) else {
            return false;
        };
        if b.arrived {
            return false;
        }
        let failed = match &b.state {
            AxisState::Done(r) if r.outcome != StepOutcome::Acked => Some(format!(
                "not sent: {} before it did not complete ({})",
                b.motor,
                r.outcome.name()
            )),
            AxisState::Done(_) => {
                let by = b.arrive_by.unwrap_or_else(|| {
                    let end = self
                        .joints
                        .get(b.joint)
                        .map_or(now, |j| j.schedule.moving_until())
                        .max(now);
                    end.saturating_add(
                        (end.saturating_sub(now) / 4).max(Duration::from_millis(500)),
                    )
                });
                if now >= by {
                    Some(format!(
                        "not sent: {} before it did not arrive in time",
                        b.motor
                    ))
                } else {
                    if let Some(a) = self.jobs.axis_mut(StepRef {
                        job: step.job,
                        axis: before,
                    }) {
                        a.arrive_by = Some(by);
                    }
                    None
                }
            }
            _ => None,
        };
        let Some(why) = failed else {
            return true;
        };
        if let Some(a) = self.jobs.axis_mut(step) {
            a.finish(StepOutcome::NotSent, None, why);
        }
        false
    }

    /// Joint `ji` is at `position` moving at `velocity` (degrees): the
    /// sequential axes on it that have arrived let the next ones go.
    pub(super) fn sequence_progress(&mut self, ji: DeviceId, position: f64, velocity: f64) {
        let mut freed = Vec::new();
        for (&id, job) in self.jobs.iter_mut() {
            if !job.sequential {
                // No axis of it waits on another (a startup's, a stop's).
                continue;
            }
            // (the axis waited for, and the one waiting: its device, its
            // step, whether it is a position move)
            let waited: Vec<(usize, DeviceId, StepRef, bool)> = job
                .axes
                .iter()
                .enumerate()
                .filter_map(|(w, x)| {
                    Some((
                        x.after?,
                        x.joint,
                        StepRef { job: id, axis: w },
                        x.is_position_move(),
                    ))
                })
                .collect();
            for (k, a) in job.axes.iter_mut().enumerate() {
                let Some(&(_, joint, step, replaces)) = waited.iter().find(|(b, ..)| *b == k)
                else {
                    continue;
                };
                let next = (joint, step, replaces);
                let Some(target) = a.target else { continue };
                if a.joint != ji
                    || a.arrived
                    || !matches!(&a.state, AxisState::Done(r) if r.outcome == StepOutcome::Acked)
                {
                    continue;
                }
                let tolerance = self
                    .map
                    .motor(&a.motor)
                    .map_or(0.1, |m| m.unit.to_degrees(m.arrival_tolerance));
                if (position - target).abs() <= tolerance && velocity.abs() <= tolerance * 10.0 {
                    a.arrived = true;
                    freed.push(next);
                }
            }
        }
        for (ji, step, replaces) in freed {
            // Its turn: it takes its device now, as a line's step that
            // goes at once does when it is queued.
            if let Some(scheduled) = self.supersede(ji, false, replaces, false, Some(step))
                && let Some(j) = self.joints.get_mut(ji)
            {
                j.schedule.wait(scheduled);
            }
            self.pump(ji);
        }
        self.finish_jobs();
    }

    /// Sends the next payload of `step`; returns whether a request is now in
    /// flight for it.
    pub(super) fn send_step(
        &mut self,
        now: Duration,
        ji: DeviceId,
        node: u16,
        step: StepRef,
    ) -> bool {
        let payload = match self.next_payload(now, ji, step) {
            ControlFlow::Continue(payload) => payload,
            ControlFlow::Break(in_flight) => return in_flight,
        };
        // Its path from where the device is now, within the limits in
        // force: the line's own check was when it came, and by its turn
        // the device may move otherwise (a move in flight, a slow Ack).
        if let Some(why) = self.path_at_send(ji, &payload) {
            self.stats.refused_at_send += 1;
            if let Some(a) = self.jobs.axis_mut(step) {
                a.finish(StepOutcome::NotSent, None, why);
            }
            return false;
        }
        let Some(flushed_before) = self.mark_in_flight(now, ji, step, payload) else {
            return false;
        };
        let sent = if payload.sent_together() {
            self.send_together(now, ji, step, payload)
        } else {
            self.drivers.send(now, ji, node, payload)
        };
        self.after_send(ji, step, payload, sent, flushed_before)
    }

    /// What `step` (of device `ji`) has to send at `now`: its next
    /// payload, taken from it; or what [`Self::send_step`] returns without
    /// sending: `true` for nothing yet (a trajectory's next segment not
    /// due: the joint stays the step's until then, woken at its time),
    /// `false` for nothing more (the step done).
    fn next_payload(
        &mut self,
        now: Duration,
        ji: DeviceId,
        step: StepRef,
    ) -> ControlFlow<bool, Order> {
        let Some(a) = self.jobs.axis_mut(step) else {
            return ControlFlow::Break(false);
        };
        // A trajectory looping forever: its next cycle.
        if a.payloads.is_empty()
            && let Some(c) = a.cycle.as_mut()
        {
            c.started = c.started.saturating_add(c.period);
            for (offset, p) in &c.payloads {
                a.payloads.push_back(*p);
                a.due.push_back(c.started.saturating_add(*offset));
            }
        }
        // A trajectory's next segment, not due yet: the joint stays this
        // step's until then.
        if let Some(&due) = a.due.front()
            && due > now
            && !a.payloads.is_empty()
        {
            a.state = AxisState::Queued;
            if let Some(j) = self.joints.get_mut(ji) {
                j.schedule.hold_until(step, due);
            }
            return ControlFlow::Break(true);
        }
        a.due.pop_front();
        let Some(payload) = a.payloads.pop_front() else {
            if !a.is_done() {
                a.finish(StepOutcome::Acked, None, "acked");
            }
            return ControlFlow::Break(false);
        };
        ControlFlow::Continue(payload)
    }

    /// `step`'s `payload` in flight on device `ji` before it is handed to
    /// its driver (an Orion line may carry other motors' steps, and reads
    /// their state first): the device the step's, where its move starts
    /// from kept. Whether its job had nothing unflushed before, or `None`
    /// when the step is gone.
    fn mark_in_flight(
        &mut self,
        now: Duration,
        ji: DeviceId,
        step: StepRef,
        payload: Order,
    ) -> Option<bool> {
        let job = self.jobs.get_mut(&step.job)?;
        let a = job.axes.get_mut(step.axis)?;
        a.begun = true;
        a.state = AxisState::InFlight { msg_id: 0, payload };
        a.attempts = 1;
        let flushed_before = !job.unflushed;
        job.unflushed = true;
        if let Some(j) = self.joints.get_mut(ji) {
            j.schedule.start(step);
            // Where the move starts from, for the model of it once acked.
            j.start_sending(now);
            // A stop waiting to be confirmed is not sent again over a newer
            // step (sent again itself, it is judged again once taken).
            j.stop_check.stop_judging();
        }
        Some(flushed_before)
    }

    /// `step`'s `payload` handed to its driver, as `sent` says: in flight
    /// under its message id, or not sent (nothing of it written: its job
    /// waits for no flush it did not before, `flushed_before`; device `ji`
    /// free). Whether it is in flight.
    fn after_send(
        &mut self,
        ji: DeviceId,
        step: StepRef,
        payload: Order,
        sent: Result<u32, DeviceError>,
        flushed_before: bool,
    ) -> bool {
        let Some(job) = self.jobs.get_mut(&step.job) else {
            return false;
        };
        let Some(a) = job.axes.get_mut(step.axis) else {
            return false;
        };
        match sent {
            Ok(msg_id) => {
                a.state = AxisState::InFlight { msg_id, payload };
                true
            }
            Err(e) => {
                a.finish(StepOutcome::NotSent, None, format!("not sent: {e}"));
                // Nothing of it was written: it waits for no flush.
                if flushed_before {
                    job.unflushed = false;
                }
                if let Some(j) = self.joints.get_mut(ji) {
                    j.schedule.clear_busy();
                }
                false
            }
        }
    }

    /// The request in flight for device `ji` ended as `c` says (any
    /// driver's).
    pub(super) fn step_done(&mut self, ji: DeviceId, c: Ended) {
        let Some(step) = self.joints.get_mut(ji).and_then(|j| j.schedule.take_busy()) else {
            return;
        };
        let Some(e) = self.end_request(ji, step, &c) else {
            return;
        };
        if c.outcome == Outcome::TimedOut {
            self.never_answered(ji, &e);
        }
        // A setpoint whose answer never came may be running: the deadman
        // watches it as if it were acked.
        if c.outcome == Outcome::Acked
            || (c.outcome == Outcome::TimedOut && e.payload.holds_setpoint())
        {
            self.track(ji, e.payload, c.at);
            // A line's stop of the device (a motor line's free or stop, a
            // `disabled`) takes it as a move does.
            let stops = e.kind == JobKind::Command
                && (e.payload.ends_setpoint()
                    || e.payload.lifecycle() == Some(Lifecycle::Deactivate));
            if e.payload.is_setpoint() || stops {
                self.taken(
                    ji,
                    step.job,
                    (e.kind == JobKind::Command).then_some(e.line).flatten(),
                );
            }
        }
        self.answer_early(step.job);
        // A stop never answered by a device whose feedback may never come
        // to judge it by (a compact device answers a command and not much
        // else): when in doubt, stop again, unless a newer step waits.
        let stop_again = c.outcome == Outcome::TimedOut
            && e.payload.unconfirmed_stop().is_some()
            && self
                .joints
                .get(ji)
                .is_some_and(|j| !j.schedule.has_waiting());
        if e.more {
            let node = self.joints.get(ji).map_or(0, |j| j.identity.node());
            if !self.send_step(self.now, ji, node, step) {
                self.pump(ji);
            }
        } else {
            self.pump(ji);
        }
        if stop_again {
            self.stop_again(ji, e.payload, c.at.max(self.now), "answered");
        }
        self.finish_jobs();
    }

    /// `step`'s request in flight on device `ji` ended as `c` says: its
    /// axis queued again, or finished as the answer says; `None` when the
    /// step had nothing in flight.
    fn end_request(&mut self, ji: DeviceId, step: StepRef, c: &Ended) -> Option<RequestEnded> {
        let job = self.jobs.get_mut(&step.job)?;
        let (kind, line) = (job.kind, job.line_ref());
        let a = job.axes.get_mut(step.axis)?;
        let AxisState::InFlight { payload, .. } = a.state else {
            return None;
        };
        let target = a.target.filter(|_| payload.is_position_move());
        a.state = AxisState::Queued;
        let joints = &self.joints;
        answered(a, kind, c, || {
            joints
                .get(ji)
                .map_or_else(String::new, |j| j.identity.device().who(j.identity.node()))
        });
        Some(RequestEnded {
            kind,
            line,
            payload,
            target,
            more: !a.is_done(),
        })
    }

    /// A request to device `ji` never answered (`e`): a command's target
    /// left unresolved, and the joint offline (its watches failed).
    fn never_answered(&mut self, ji: DeviceId, e: &RequestEnded) {
        let Some(j) = self.joints.get_mut(ji) else {
            return;
        };
        if let (JobKind::Command, Some(target)) = (e.kind, e.target) {
            j.schedule.left_unresolved(Unresolved {
                origin: e.line.map(|l| l.origin),
                line: e.line.map_or(0, |l| l.line),
                target,
            });
        }
        if j.liveness.went_offline() {
            self.out.push_back(Output::Event(Event::Offline {
                motor_id: j.identity.name().to_owned(),
                node: j.identity.node(),
                reason: "a request timed out".to_owned(),
            }));
            self.fail_watches(|w| w.waits_on(ji), "the joint went offline");
        }
    }

    /// A trajectory line under way: once each of its motors' first
    /// segment is acknowledged (and nothing of it failed), its result is
    /// given (`ok:true`, `arrival_follows:true`); the fate of its later
    /// segments comes in its completion line.
    pub(super) fn answer_early(&mut self, id: u64) {
        let now = self.now;
        let Some(job) = self.jobs.get_mut(&id) else {
            return;
        };
        if job.answered.is_some() || !job.answers_early() {
            return;
        }
        let failed = job
            .axes
            .iter()
            .any(|a| matches!(&a.state, AxisState::Done(r) if r.outcome != StepOutcome::Acked));
        if failed || !job.axes.iter().all(|a| a.acked > 0) {
            return;
        }
        let Some(meta) = job.line.clone() else {
            return;
        };
        job.answered = Some(now);
        let r = LineResult {
            ok: true,
            line: meta.number,
            acked: Some(job.axes.iter().map(|a| a.motor.clone()).collect()),
            arrival_follows: Some(true),
            latency_us: job.last_frame.map(|t| us(t.saturating_sub(job.received))),
            ack_us: Some(us(now.saturating_sub(job.received))),
            losses: std::mem::take(&mut job.report.losses),
            ..LineResult::default()
        };
        self.answer(&meta, r);
    }

    /// Remembers an acked request's effect on its device
    /// ([`Order::effect`]): its lifecycle, a move's target and (as
    /// planned from the last feedback) when it ends, the deadman of a
    /// setpoint it holds.
    pub(super) fn track(&mut self, ji: DeviceId, order: Order, at: Duration) {
        let Some(j) = self.joints.get(ji) else { return };
        // A line that leaves it inactive again waits behind this order
        // (looked for only behind an Activate: every ack comes here).
        let deactivation_waits =
            order.lifecycle() == Some(Lifecycle::Activate) && self.deactivation_waits(j);
        // Planned from where it was when the order was sent, as the
        // device plans it.
        let sent_from = j.motion.sent_from();
        let cx = Context {
            at,
            motion: sent_from.or(j.motion.reported().map(|(p, v)| (p, v, 0.0))),
            unit: j.identity.unit(),
            max_velocity: j.identity.pace().max_velocity,
            max_acceleration: j.identity.pace().max_acceleration,
            command_timeout: j.identity.pace().command_timeout,
            planned: j.motion.planned(),
        };
        let effect = order.effect(&cx);
        let Some(j) = self.joints.get_mut(ji) else {
            return;
        };
        j.model_acked(order);
        j.liveness.deadman_at(effect.deadman);
        let held = effect
            .deadman
            .and_then(|_| order.held_velocity(j.identity.unit()));
        j.motion.holds(held);
        j.motion
            .order_taken(effect.deadman.is_some() || effect.target.is_some());
        if order.unconfirmed_stop().is_some() {
            let speed = j.motion.reported_speed();
            j.stop_check.taken(order, at, speed);
        } else {
            j.stop_check.settle();
        }
        j.schedule.acked(effect.target, effect.moving);
        if let Some(active) = effect.active {
            j.lifecycle.made_active(active, deactivation_waits);
        }
        if effect.settles {
            j.schedule.settle();
        }
    }

    /// Whether a step waiting for joint `j` deactivates it.
    fn deactivation_waits(&self, j: &Joint) -> bool {
        j.schedule.waiting().any(|s| {
            self.jobs.axis(*s).is_some_and(|a| {
                a.payloads
                    .iter()
                    .any(|o| o.lifecycle() == Some(Lifecycle::Deactivate))
            })
        })
    }

    /// Emits the result of every job that is done.
    pub(super) fn finish_jobs(&mut self) {
        // Looked at after every event, and most find nothing done.
        if self.jobs.finished().next().is_none() {
            return;
        }
        let mut done = std::mem::take(&mut self.done_scratch);
        done.clear();
        done.extend(self.jobs.finished());
        for &id in &done {
            if let Some(job) = self.jobs.close(id) {
                self.complete(job);
                // The drain may end now: looked at once, by its timer.
                if let Phase::Draining { recheck, .. } = &mut self.phase {
                    *recheck = true;
                }
            }
        }
        // Kept for the next call (a nested call, from a completion, found
        // it empty and allocated its own: the larger is kept).
        if done.capacity() >= self.done_scratch.capacity() {
            self.done_scratch = done;
        }
    }

    /// Whether `step` (queued for a device) may go now as far as its
    /// device's link goes: a stop always; a step with nothing to send;
    /// else as the driver says (the Orion controller takes one line at a
    /// time).
    pub(super) fn link_free(&self, step: StepRef) -> bool {
        let Some(job) = self.jobs.get(&step.job) else {
            return true;
        };
        let order = job.axes.get(step.axis).and_then(|a| a.payloads.front());
        job.kind.is_stop() || self.drivers.link_free(order)
    }

    /// Whether `step` is a sequential line's axis whose earlier axis has
    /// not arrived: it cannot go yet, so it does not keep its link from
    /// its own work (an Orion controller unpolled would fall silent).
    pub(super) fn after_earlier_axis(jobs: &Jobs, step: StepRef) -> bool {
        jobs.get(&step.job)
            .and_then(|job| {
                let before = job.axes.get(job.axes.get(step.axis)?.after?)?;
                Some(!before.arrived)
            })
            .unwrap_or(false)
    }

    /// Sends `order` of `step` for device `ji` in one message with the
    /// orders that join it ([`Order::joins`]) waiting at the front of the
    /// other devices for the same line (the Orion motors of one input
    /// line: one line to the controller). Returns the message's number.
    pub(super) fn send_together(
        &mut self,
        now: Duration,
        ji: DeviceId,
        step: StepRef,
        order: Order,
    ) -> Result<u32, DeviceError> {
        if let Some(e) = self.drivers.refuses(&order) {
            return Err(e);
        }
        let mut orders = vec![(ji, order)];
        let mut others = Vec::new();
        for k in self.joints.ids() {
            if k == ji {
                continue;
            }
            let Some(front) = self.waiting_front(k) else {
                continue;
            };
            if front.job != step.job {
                continue;
            }
            let Some(a) = self.jobs.axis_mut(front) else {
                continue;
            };
            let fits = a.after.is_none() && a.payloads.front().is_some_and(|o| order.joins(o));
            if !fits || !a.due.is_empty() {
                continue;
            }
            let Some(payload) = a.payloads.pop_front() else {
                continue;
            };
            a.begun = true;
            orders.push((k, payload));
            if let Some(j) = self.joints.get_mut(k) {
                j.schedule.take_next();
                j.schedule.start(front);
            }
            others.push((front, payload));
        }
        let sent = self.drivers.send_together(now, &orders);
        for (front, payload) in others {
            let Some(a) = self.jobs.axis_mut(front) else {
                continue;
            };
            match &sent {
                Ok(id) => {
                    a.state = AxisState::InFlight {
                        msg_id: *id,
                        payload,
                    };
                    a.attempts = 1;
                }
                Err(e) => a.finish(StepOutcome::NotSent, None, format!("not sent: {e}")),
            }
        }
        if sent.is_err() {
            for (k, _) in orders.iter().skip(1) {
                if let Some(j) = self.joints.get_mut(*k) {
                    j.schedule.clear_busy();
                }
            }
        }
        sent
    }
}

/// A step's request that ended ([`Bridge::step_done`]).
struct RequestEnded {
    /// Its job's kind.
    kind: JobKind,
    /// The line its job serves.
    line: Option<LineRef>,
    /// What was sent.
    payload: Order,
    /// Its axis's target, for a position move.
    target: Option<f64>,
    /// Whether more of the step is to send.
    more: bool,
}

/// Axis `a` (of a job of `kind`) as the answer `c` to its request says:
/// acked (finished once nothing more is to send), nacked, or never
/// answered by the device `who` names.
fn answered(a: &mut Axis, kind: JobKind, c: &Ended, who: impl FnOnce() -> String) {
    match &c.outcome {
        Outcome::Acked => {
            a.acked += 1;
            if let Some(why) = a.replaced {
                a.finish(StepOutcome::Superseded, None, why);
            } else if a.payloads.is_empty() && a.cycle.is_none() {
                // A trajectory looping forever has its next cycle to come.
                a.finish(StepOutcome::Acked, None, "acked");
            }
        }
        // Stopping a device that is already stopped is a stop.
        Outcome::Nacked {
            already_stopped: true,
            ..
        } if kind.is_stop() => {
            a.finish(StepOutcome::Acked, None, "already stopped");
        }
        Outcome::Nacked { code, why, .. } => {
            a.finish(StepOutcome::Nacked, *code, why.clone());
        }
        Outcome::TimedOut => {
            let who = who();
            a.finish(
                StepOutcome::OutcomeUnknown,
                None,
                format!(
                    "sent {} times, never answered: {who} may or may not have executed it",
                    c.attempts
                ),
            );
        }
    }
}
