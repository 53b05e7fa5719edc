//! Timers: what is due, when the engine must be woken next.

use super::*;

impl Timer {
    /// The order [`Bridge::on_timeout`] takes the timers in, each once.
    /// What one timer's work queues is there for those after it: the
    /// drivers' time-outs are taken first, the deadman's stops and the
    /// limits' brakes are queued before the Orion link picks what to send
    /// next, and the drain is looked at last, once everything else has
    /// had its turn.
    pub(super) const FIRING: [Self; 14] = [
        Self::Requests,
        Self::Settle,
        Self::Commands,
        Self::LimitBrake,
        Self::Deadman,
        Self::Link,
        Self::Answer,
        Self::Segment,
        Self::Sequence,
        Self::Arrival,
        Self::Liveness,
        Self::Feedback,
        Self::Heartbeat,
        Self::Drain,
    ];

    /// Whether the timer's work is done only when its deadline is due:
    /// where, not due, that work does nothing. The others' work is done
    /// at every timeout, as its own checks differ from the deadline's.
    fn only_when_due(self) -> bool {
        match self {
            // Only the joints whose brake point is past (a latched stop
            // brakes nothing); the deadline is the earliest of those.
            Self::LimitBrake
            // Only the requests whose answer is overdue.
            | Self::Answer
            // Only the joints whose segment is due.
            | Self::Segment
            // Only the watched lines past their time.
            | Self::Arrival
            // Only the joints online and silent for the offline time
            // (one offline already stays so, unchanged).
            | Self::Liveness
            // Only at the feedback's own time.
            | Self::Feedback => true,
            // The iRPC client takes the time as its clock, due or not,
            // and a stale resend is withdrawn on the client's own word.
            Self::Requests
            // Ready as soon as every device is read, before the settle
            // time the deadline names.
            | Self::Settle
            // The compact and moteus drivers' own checks stand: not
            // shown to match the deadline here.
            | Self::Commands
            // Latched, every deadman is disarmed, due or not.
            | Self::Deadman
            // The Orion controller's housekeeping and the moteus polls
            // keep their own times; what the drivers queued is drained.
            | Self::Link
            // Any waiting step of an idle device is sent, not only one
            // whose predecessor is overdue.
            | Self::Sequence
            // Nothing moving, its time is cleared; where no joint hears
            // it, its deadline is unset but its time is kept.
            | Self::Heartbeat
            // A job's end is looked at once: the recheck is cleared.
            | Self::Drain => false,
        }
    }
}

impl Bridge {
    /// Advances to `now`: each timer of [`Timer::FIRING`] in its turn,
    /// its work done where it is due (or always, see
    /// [`Timer::only_when_due`]), then the bookkeeping that follows it.
    pub(super) fn on_timeout(&mut self) {
        let now = self.now;
        for t in Timer::FIRING {
            if !t.only_when_due() || self.deadline(t).is_some_and(|d| d <= now) {
                self.fire(t, now);
            }
            self.after_firing(t);
        }
    }

    /// Timer `t`'s work at `now`.
    fn fire(&mut self, t: Timer, now: Duration) {
        match t {
            Timer::Requests => {
                self.withdraw_stale_resends(now);
                self.drivers.handle_timeout(now);
            }
            Timer::Settle => self.try_ready(),
            Timer::Commands => self.drivers.command_timeouts(now),
            Timer::LimitBrake => self.keep_within_limits(now),
            Timer::Deadman => self.deadman(now),
            Timer::Link => self.link_timeouts(now),
            Timer::Answer => self.awaiting_timeouts(now),
            Timer::Segment => self.send_due_segments(now),
            // Sequential axes whose predecessor is overdue give up.
            Timer::Sequence => {
                for ji in self.joints.ids() {
                    self.pump(ji);
                }
            }
            Timer::Arrival => self.arrivals_timed_out(now),
            Timer::Liveness => self.offline_timeouts(now),
            Timer::Feedback => {
                if let (Some(period), Some(at)) =
                    (self.config.feedback_period, self.timers.feedback)
                    && now >= at
                {
                    self.emit_feedback(now);
                    self.timers.feedback = Some(now.saturating_add(period));
                }
            }
            Timer::Heartbeat => self.heartbeat_due(now),
            Timer::Drain => self.drain_ended(now),
        }
    }

    /// What follows timer `t`'s turn, whether it fired or not: what the
    /// drivers told is taken in, and finished jobs are answered.
    fn after_firing(&mut self, t: Timer) {
        match t {
            Timer::Requests | Timer::Commands => self.drain_drivers(),
            Timer::Segment | Timer::Sequence => self.finish_jobs(),
            Timer::Settle
            | Timer::LimitBrake
            | Timer::Deadman
            | Timer::Link
            | Timer::Answer
            | Timer::Arrival
            | Timer::Liveness
            | Timer::Feedback
            | Timer::Heartbeat
            | Timer::Drain => {}
        }
    }

    /// Draining: over once nothing is left to do and nothing moves, or at
    /// its deadline.
    fn drain_ended(&mut self, now: Duration) {
        if let Phase::Draining { deadline, recheck } = &mut self.phase {
            *recheck = false;
            let deadline = *deadline;
            let idle = self.jobs.is_empty() && !self.any_moving(now);
            if idle || now >= deadline {
                self.enter(Phase::Stopping);
            }
        }
    }

    /// Trajectory segments now due: each sent.
    fn send_due_segments(&mut self, now: Duration) {
        let due = self.joints_where(|j| j.schedule.wake().is_some_and(|w| now >= w));
        for ji in due {
            let Some(j) = self.joints.get_mut(ji) else {
                continue;
            };
            j.schedule.clear_wake();
            let node = j.identity.node();
            if let Some(step) = j.schedule.take_busy()
                && !self.send_step(now, ji, node, step)
            {
                self.pump(ji);
            }
        }
    }

    /// Watched lines past their time: not arrived, saying how far off
    /// each motor that did not arrive was.
    fn arrivals_timed_out(&mut self, now: Duration) {
        let late: Vec<usize> = self
            .arrivals
            .iter()
            .enumerate()
            .filter(|(_, w)| now >= w.deadline)
            .map(|(i, _)| i)
            .collect();
        for i in late.into_iter().rev() {
            let w = self.arrivals.remove(i);
            let far = w
                .axes
                .iter()
                .filter(|a| a.arrived.is_none())
                .map(|a| match a.last_error {
                    Some(e) => format!("{} {} away", a.motor, short_unit(a.unit.from_degrees(e))),
                    None => format!("{} never reported its position", a.motor),
                })
                .collect::<Vec<_>>()
                .join(", ");
            let origin = w.line.origin;
            let arrival = w.verdict(now, Some(format!("timed out: {far}")));
            self.out.push_back(Output::Arrival { origin, arrival });
        }
    }

    /// Joints heard from no longer: offline, their watches failed and the
    /// commands waiting for them cancelled.
    fn offline_timeouts(&mut self, now: Duration) {
        let offline_after = self.config.offline_after;
        let mut went_offline = Vec::new();
        for (ji, j) in self.joints.with_ids_mut() {
            let since = j.liveness.last_heard().unwrap_or(Duration::ZERO);
            let silent = now.saturating_sub(since);
            if silent >= offline_after && j.liveness.went_offline() {
                went_offline.push(ji);
                self.out.push_back(Output::Event(Event::Offline {
                    motor_id: j.identity.name().to_owned(),
                    node: j.identity.node(),
                    reason: format!("nothing heard for {} ms", silent.as_millis()),
                }));
            }
        }
        for ji in went_offline {
            self.fail_watches(|w| w.waits_on(ji), "the joint went offline");
            // What waits for it is not held to run once it is heard again.
            let name = self
                .joints
                .get(ji)
                .map(|j| j.identity.name().to_owned())
                .unwrap_or_default();
            self.cancel_where(
                &format!("cancelled: {name} went offline before it was sent"),
                |job| {
                    job.kind == JobKind::Command
                        && job
                            .axes
                            .iter()
                            .any(|a| a.joint == ji && a.state == AxisState::Queued)
                },
            );
        }
    }

    /// The heartbeat, while anything moves: due again a period on, whether
    /// a beat could be queued or not (none on a bus without iRPC joints):
    /// never due at the time it was handled, so nothing waiting for it
    /// spins.
    fn heartbeat_due(&mut self, now: Duration) {
        if self.any_moving(now) {
            if self.timers.heartbeat.is_none_or(|t| now >= t) {
                let _ = self.drivers.heartbeat();
                self.timers.heartbeat = Some(now.saturating_add(self.config.heartbeat_period));
            }
        } else {
            self.timers.heartbeat = None;
        }
    }

    /// When [`Bridge::handle_timeout`] next has work.
    pub fn poll_timeout(&self) -> Option<Duration> {
        if let Some(next) = self.next_deadline.get() {
            debug_assert_eq!(
                next,
                self.next_deadline_now(),
                "the next deadline changed without an entry point clearing it"
            );
            return next;
        }
        let next = self.next_deadline_now();
        self.next_deadline.set(Some(next));
        next
    }

    /// [`Bridge::poll_timeout`], computed: the earliest deadline of the
    /// timer table.
    pub(super) fn next_deadline_now(&self) -> Option<Duration> {
        if matches!(self.phase, Phase::Finished) {
            return None;
        }
        Timer::ALL
            .into_iter()
            .filter_map(|t| self.deadline(t))
            .min()
    }

    /// The bridge is about to change: its next deadline is computed again.
    pub(super) fn changed(&mut self) {
        self.next_deadline.set(None);
    }

    /// When timer `t` is next due, if it is set: the timer table, one
    /// entry per kind of deadline, each read where its state lives.
    pub(super) fn deadline(&self, t: Timer) -> Option<Duration> {
        match t {
            Timer::Requests => self.drivers.requests_deadline(),
            Timer::Commands => self.drivers.commands_deadline(),
            Timer::Link => self.drivers.link_deadline(),
            Timer::Feedback => self.timers.feedback,
            Timer::Liveness => self
                .joints
                .iter()
                .filter(|j| j.liveness.is_online())
                .map(|j| {
                    j.liveness
                        .last_heard()
                        .unwrap_or(Duration::ZERO)
                        .saturating_add(self.config.offline_after)
                })
                .min(),
            // Only where a joint hears the beat (iRPC).
            Timer::Heartbeat => (self.drivers.beats() && self.any_moving(self.now))
                .then(|| self.timers.heartbeat.unwrap_or(self.now).max(self.now)),
            Timer::Drain => self.drain_due(),
            Timer::Arrival => self.arrivals.iter().map(|w| w.deadline).min(),
            Timer::Sequence => self.sequence_due(),
            Timer::Deadman => self
                .joints
                .iter()
                .filter_map(|j| j.liveness.deadman())
                .min(),
            Timer::LimitBrake => {
                if self.stop.is_latched() {
                    None
                } else {
                    self.joints
                        .iter()
                        .filter_map(|j| self.brake_due(j).map(|(at, ..)| at.max(self.now)))
                        .min()
                }
            }
            Timer::Segment => self.joints.iter().filter_map(|j| j.schedule.wake()).min(),
            Timer::Answer => self.jobs.answer_due(),
            Timer::Settle => match &self.phase {
                Phase::Starting(s) => s.settle_until,
                _ => None,
            },
        }
    }

    /// When the drain may end: once motion has ended, at once when nothing
    /// is left (or a line just finished: looked at once); while a line
    /// waits for its device, the device's own answer or time-out finishes
    /// it, and the deadline bounds it. Never due again at the time it was
    /// handled: a runner waiting for it does not spin. Not draining: never.
    fn drain_due(&self) -> Option<Duration> {
        match self.phase {
            Phase::Draining { deadline, recheck } => {
                let motion_ends = self.joints.iter().map(|j| j.schedule.moving_until()).max();
                Some(if recheck {
                    self.now
                } else if let Some(end) = motion_ends.filter(|e| *e > self.now) {
                    end.min(deadline)
                } else if !self.jobs.is_empty() {
                    deadline
                } else {
                    self.now
                })
            }
            _ => None,
        }
    }

    /// When a sequential axis gives up waiting, due only where pumping
    /// would act on it: an axis at the front of an idle device's queue,
    /// waiting for an axis that has not arrived (behind a busy device, the
    /// device's answer pumps it; a deadline there would be due and do
    /// nothing).
    fn sequence_due(&self) -> Option<Duration> {
        self.joints
            .iter()
            .filter(|j| j.schedule.busy().is_none())
            .filter_map(|j| j.schedule.next_waiting())
            .filter_map(|s| {
                let job = self.jobs.get(&s.job)?;
                let a = job.axes.get(s.axis).filter(|a| !a.is_done())?;
                let b = job.axes.get(a.after?)?;
                if b.arrived { None } else { b.arrive_by }
            })
            .min()
    }
}
