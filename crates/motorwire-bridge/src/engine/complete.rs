//! A job's completion: its result and its arrival watch.

use super::*;

/// What became of a finished job's steps: the motors acked, the moves
/// acked (to watch for arrival), the rest's reports, and whether a
/// stream's setpoint was replaced.
struct Tally {
    acked: Vec<String>,
    moved: Vec<WatchAxis>,
    failures: Vec<StepReport>,
    superseded: bool,
}

impl Bridge {
    pub(super) fn complete(&mut self, job: Box<Job>) {
        let mut job = *job;
        if let Some(since) = job.answered {
            return self.complete_answered(job, since);
        }
        // A stream's setpoint replaced by a newer one before it was sent
        // is what a stream does: no failure.
        let stream = job.line.as_ref().is_some_and(|l| l.stream);
        // Only a reset needs every joint it moved.
        let moved_joints: Vec<DeviceId> = if job.kind == JobKind::Reset {
            job.axes.iter().map(|a| a.joint).collect()
        } else {
            Vec::new()
        };
        let tally = self.tally(std::mem::take(&mut job.axes), stream);
        match job.kind {
            JobKind::Startup => return self.started(tally),
            JobKind::Shutdown => {
                self.out.push_back(Output::Event(Event::Stopped {
                    deactivated: tally.acked,
                    failures: tally.failures,
                }));
                self.enter(Phase::Finished);
                return;
            }
            JobKind::Reset => self.reset_done(&moved_joints, tally.failures.is_empty()),
            JobKind::Deadman if !tally.failures.is_empty() && !self.stop.is_latched() => {
                return self.deadman_failed(&tally.failures);
            }
            JobKind::Command | JobKind::EmergencyStop | JobKind::Release | JobKind::Deadman => {}
        }
        self.answer_job(job, tally, stream);
    }

    /// The finished steps of `axes`, in one pass, each name moved, not
    /// copied; a superseded step of a `stream` is no failure.
    fn tally(&self, axes: Vec<Axis>, stream: bool) -> Tally {
        let mut t = Tally {
            acked: Vec::with_capacity(axes.len()),
            moved: Vec::with_capacity(axes.len()),
            failures: Vec::new(),
            superseded: false,
        };
        for a in axes {
            let AxisState::Done(r) = a.state else {
                continue;
            };
            match r.outcome {
                StepOutcome::Acked => {
                    if let Some(target) = a.target {
                        t.moved.push(self.watch_axis(a.joint, a.motor, target));
                    }
                    t.acked.push(r.motor);
                }
                StepOutcome::Superseded if stream => t.superseded = true,
                _ => t.failures.push(r),
            }
        }
        t
    }

    /// The startup's job ended: an event for each motor, and ready once
    /// the joints settle.
    fn started(&mut self, tally: Tally) {
        for name in tally.acked {
            self.out.push_back(Output::Event(Event::Startup {
                motor_id: name,
                ok: true,
                error: None,
            }));
        }
        for f in tally.failures {
            self.out.push_back(Output::Event(Event::Startup {
                motor_id: f.motor.clone(),
                ok: false,
                error: Some(f),
            }));
        }
        let settle = self.now.saturating_add(self.config.offline_after);
        if let Phase::Starting(Starting { settle_until, .. }) = &mut self.phase {
            // Ready once every device that answers has been read
            // (its position known from the first line on), or
            // after the offline time for those that do not.
            *settle_until = Some(settle);
            self.try_ready();
        }
    }

    /// A reset's job ended: the `joints` it moved are no longer resetting,
    /// and need no reset once it all went (`ok`).
    fn reset_done(&mut self, joints: &[DeviceId], ok: bool) {
        for a in joints {
            if let Some(j) = self.joints.get_mut(*a) {
                j.lifecycle.reset_ended(ok);
            }
        }
    }

    /// The deadman could not stop a device (its stop was never answered,
    /// `failures`): when in doubt, stop everything.
    fn deadman_failed(&mut self, failures: &[StepReport]) {
        let why = failures
            .iter()
            .map(|f| format!("{} ({})", f.motor, f.outcome.name()))
            .collect::<Vec<_>>()
            .join(", ");
        self.emergency_stop(
            self.now,
            None,
            Vec::new(),
            format!("deadman: could not stop {why}"),
        );
    }

    /// Answers a finished job's line (and the stop lines that rode on it)
    /// with what became of it; a command that moved is watched until it
    /// arrives.
    fn answer_job(&mut self, mut job: Job, tally: Tally, stream: bool) {
        // A stop the bridge made itself (the deadman's, a joint's own)
        // answers no line, but the stop lines that rode on it are answered.
        if job.line.is_none() && job.riders.is_empty() {
            return;
        }
        let now = self.now;
        let latency = job.last_frame.map(|t| us(t.saturating_sub(job.received)));
        let watched = job.kind == JobKind::Command && !tally.moved.is_empty();
        let mut r = line_result(&mut job, tally.acked, tally.failures, latency, now);
        r.arrival_follows = if stream {
            Some(false)
        } else {
            watched.then_some(true)
        };
        r.superseded = tally.superseded;
        // The riders' results come before the line's own, as they did
        // when each was pushed as it was built.
        for rider in job.riders {
            let rr = LineResult {
                line: rider.line.number,
                problems: rider.problems,
                // The stop frames went out before this line came.
                latency_us: latency.map(|_| 0),
                stop_latency_us: latency.map(|_| 0),
                ack_us: Some(us(now.saturating_sub(rider.received))),
                arrival_follows: None,
                ..LineResult::clone(&r)
            };
            self.answer(&rider.line, rr);
        }
        let Some(meta) = job.line else { return };
        self.answer(&meta, r);
        // (Lines watched on the motors it moved were superseded when each
        // took its setpoint: [`Self::taken`].)
        if watched && !stream {
            self.watch(meta, tally.moved, now);
        }
    }

    /// A trajectory line answered when it got under way ends: every
    /// segment acknowledged, it is watched until it arrives; otherwise its
    /// completion line says at once which motor's later segments did not
    /// go, and why.
    pub(super) fn complete_answered(&mut self, job: Job, since: Duration) {
        let Some(meta) = job.line else { return };
        let targets: Vec<WatchAxis> = job
            .axes
            .iter()
            .filter_map(|a| Some(self.watch_axis(a.joint, a.motor.clone(), a.target?)))
            .collect();
        let failures: Vec<&StepReport> = job
            .axes
            .iter()
            .filter_map(|a| match &a.state {
                AxisState::Done(r) if r.outcome != StepOutcome::Acked => Some(r),
                _ => None,
            })
            .collect();
        if failures.is_empty() {
            return self.watch(meta, targets, since);
        }
        let said = failures
            .iter()
            .map(|f| format!("{}: {} ({})", f.motor, f.outcome.name(), f.message))
            .collect::<Vec<_>>()
            .join("; ");
        let reason = match &job.cut {
            Some(why) => format!("{why}: the rest of the trajectory was not sent"),
            None => format!("a later segment did not go: {said}"),
        };
        let mut w = self.watch_of(meta, targets, since);
        for (ji, j) in self.joints.with_ids() {
            if let Some((pos, vel)) = j.motion.reported()
                && w.axes.iter().any(|a| a.joint == ji)
            {
                w.observe(ji, pos, vel, self.now);
            }
        }
        let origin = w.line.origin;
        let arrival = w.verdict(self.now, Some(reason));
        self.out.push_back(Output::Arrival { origin, arrival });
    }

    // ---- links ------------------------------------------------------------
}

/// The result of a finished `job`'s line, at `now`: the motors `acked`,
/// the `failures`, the time from its receipt to its last frame
/// (`latency`).
fn line_result(
    job: &mut Job,
    acked: Vec<String>,
    failures: Vec<StepReport>,
    latency: Option<u64>,
    now: Duration,
) -> Box<LineResult> {
    let number = job.line.as_ref().map_or(0, |l| l.number);
    let ok = failures.is_empty() && job.data_error.is_none();
    let error = if !failures.is_empty() {
        Some(Refusal::failed(&failures, job.cut.as_deref()).into())
    } else {
        job.data_error
            .clone()
            .map(|why| Refusal::NoAnswer { why }.into())
    };
    Box::new(LineResult {
        ok,
        line: number,
        emergency_stop: job.kind == JobKind::EmergencyStop,
        released: job.kind == JobKind::Release,
        error,
        acked: Some(acked),
        outcomes: failures,
        problems: std::mem::take(&mut job.problems),
        latency_us: latency,
        ack_us: Some(us(now.saturating_sub(job.received))),
        stop_latency_us: if job.kind == JobKind::EmergencyStop {
            latency
        } else {
            None
        },
        losses: std::mem::take(&mut job.report.losses),
        data: job.data.clone(),
        ..LineResult::default()
    })
}
