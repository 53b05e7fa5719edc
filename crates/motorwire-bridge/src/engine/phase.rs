//! The bridge's phase: starting (greeting the devices, waiting for them to settle), running, finishing, finished; the ready event and the greeting of clients.

use super::*;

impl Bridge {
    /// Anchors a bridge that keeps a wall clock
    /// ([`BridgeConfig::epoch_unix_ms`] given) at `unix_ms` for its time
    /// zero: the runner calls it where its clock starts, so the Unix time
    /// the bridge reckons (a stop's, which commands stamped before it are
    /// held to; feedback timestamps) is the host's, not behind it by the
    /// time it took to start.
    pub(crate) fn anchor_epoch(&mut self, unix_ms: f64) {
        self.changed();
        if self.config.epoch_unix_ms.is_some() && unix_ms.is_finite() {
            self.config.epoch_unix_ms = Some(unix_ms);
            self.drivers.set_epoch(unix_ms);
        }
    }

    pub(super) fn ready_event(&self) -> Event {
        Event::Ready {
            joints: self
                .joints
                .iter()
                .map(|j| j.identity.name().to_owned())
                .collect(),
            state: self.state(),
        }
    }

    /// A client that connected (and authenticated) at `now` is greeted,
    /// for it alone ([`Output::ToOne`]), exactly once: with `ready` and
    /// the state now once the bridge is ready (at once, or when it becomes
    /// ready), or with `stopping` when the bridge is past serving. A
    /// runner holds everyone's feedback and events from such a client
    /// until its greeting, so the greeting is its first line.
    pub(super) fn on_greet(&mut self, origin: Origin) {
        match &mut self.phase {
            Phase::Starting(s) => s.to_greet.push(origin),
            Phase::Running | Phase::Draining { .. } => {
                let event = self.ready_event();
                self.out.push_back(Output::ToOne { origin, event });
            }
            Phase::Stopping | Phase::Finished => {
                let event = Event::Stopping {
                    reason: "the bridge is stopping the joints".to_owned(),
                };
                self.out.push_back(Output::ToOne { origin, event });
            }
        }
    }

    /// The clients `to_greet` (those that waited for `ready`) greeted with
    /// `event`.
    fn greet_all(&mut self, to_greet: Vec<Origin>, event: &Event) {
        for origin in to_greet {
            self.out.push_back(Output::ToOne {
                origin,
                event: event.clone(),
            });
        }
    }

    /// Started and every device that answers read (or silent past the
    /// offline time): ready.
    pub(super) fn try_ready(&mut self) {
        let Phase::Starting(Starting {
            settle_until: Some(until),
            ..
        }) = self.phase
        else {
            return;
        };
        let read = self
            .joints
            .iter()
            .all(|j| !j.liveness.is_online() || j.motion.reported().is_some());
        if read || self.now >= until {
            self.enter(Phase::Running);
        }
    }

    // ---- phases ---------------------------------------------------------

    /// The one place the phase changes: each change [`Phase::allows`]
    /// lists, with what it does. Any other is a bug; it is never ignored:
    /// when in doubt, stop ([`Bridge::illegal_transition`]).
    pub(super) fn enter(&mut self, to: Phase) {
        if !self.phase.allows(&to) {
            return self.illegal_transition(IllegalTransition {
                from: self.phase.name(),
                to: to.name(),
            });
        }
        // What the starting phase kept, now the bridge's to finish.
        let started = match std::mem::replace(&mut self.phase, Phase::Finished) {
            Phase::Starting(s) => s,
            from => {
                self.phase = from;
                Starting::default()
            }
        };
        match to {
            Phase::Running => {
                self.phase = Phase::Running;
                let ready = self.ready_event();
                // Everyone's first, then the greetings: a runner holds
                // everyone's lines from a client until its greeting, so
                // each waiting client has one ready, as its first line.
                self.out.push_back(Output::Event(ready.clone()));
                self.greet_all(started.to_greet, &ready);
                for w in started.waiting {
                    self.take_line(w.at, w.meta, &w.text);
                }
                if let Some(deadline) = started.drain_after {
                    self.enter(Phase::Draining {
                        deadline,
                        recheck: false,
                    });
                }
            }
            Phase::Draining { .. } => {
                self.phase = to;
                self.out.push_back(Output::Event(Event::Stopping {
                    reason: "end of input".to_owned(),
                }));
                self.end_open_motion();
            }
            Phase::Stopping => {
                self.phase = Phase::Stopping;
                // Stopping before ever running (interrupted, or a bug): the
                // clients still waiting are told, and each line still
                // waiting for the start is refused, not dropped.
                let stopping = Event::Stopping {
                    reason: "the bridge is stopping the joints".to_owned(),
                };
                self.greet_all(started.to_greet, &stopping);
                for w in started.waiting {
                    self.stats.lines += 1;
                    self.refuse(&w.meta, Refusal::ShuttingDown);
                }
                self.fail_watches(|_| true, "the bridge is stopping the joints");
                let axes = self.every_joint(&[Lifecycle::Deactivate]);
                self.open_job(
                    None,
                    JobKind::Shutdown,
                    self.now,
                    axes,
                    Report::default(),
                    Vec::new(),
                );
            }
            Phase::Finished => self.phase = Phase::Finished,
            // `allows` has no change into starting.
            Phase::Starting(_) => {}
        }
    }

    /// A phase change no path of the engine makes was asked for: a bug.
    /// When in doubt, stop: every joint is stopped (the phase the bridge
    /// stops in), and the reason is said.
    pub(super) fn illegal_transition(&mut self, e: IllegalTransition) {
        self.out.push_back(Output::Event(Event::Stopping {
            reason: e.to_string(),
        }));
        if !matches!(self.phase, Phase::Stopping | Phase::Finished) {
            self.enter(Phase::Stopping);
        }
    }

    /// Starts: configures and activates every joint (unless
    /// [`BridgeConfig::activate_on_start`] is false). Lines that arrive
    /// before the joints are ready wait for them (an emergency stop does
    /// not: it is acted on at once).
    pub(super) fn on_start(&mut self, now: Duration) {
        self.now = now;
        self.timers.feedback = self.config.feedback_period.map(|_| now);
        if !self.config.activate_on_start {
            self.enter(Phase::Running);
            return;
        }
        let mut axes = self.every_joint(&[Lifecycle::Configure, Lifecycle::Activate]);
        for a in &mut axes {
            if let Some(t) = self.telemetry_subscription() {
                a.payloads.extend(self.orders_for(a.joint, &[t]));
            }
        }
        self.open_job(
            None,
            JobKind::Startup,
            now,
            axes,
            Report::default(),
            Vec::new(),
        );
    }

    /// End of input: lines in flight and moves in progress finish (up to
    /// [`BridgeConfig::drain_timeout`]), then every joint is deactivated.
    pub(super) fn on_finish(&mut self) {
        let deadline = self.now.saturating_add(self.config.drain_timeout);
        match &mut self.phase {
            // Lines still waiting for startup are served first: once the
            // joints are ready, then drained.
            Phase::Starting(s) => s.drain_after = Some(deadline),
            Phase::Running => self.enter(Phase::Draining {
                deadline,
                recheck: false,
            }),
            Phase::Draining { .. } | Phase::Stopping | Phase::Finished => {}
        }
        self.on_timeout();
    }

    /// At the end of input, motion that would not end by itself stops at
    /// once: a trajectory looping forever (it ends with the segment under
    /// way), one whose start is still to come (never started), and a
    /// velocity or torque setpoint (brought to velocity 0, as the deadman
    /// does). Finite moves may finish within the drain.
    pub(super) fn end_open_motion(&mut self) {
        let now = self.now;
        let open = |job: &Job| {
            job.kind == JobKind::Command
                && (job.axes.iter().any(|a| a.cycle.is_some() && !a.is_done())
                    || job
                        .axes
                        .iter()
                        .all(|a| !a.begun && a.due.front().is_some_and(|due| *due > now))
                    // A velocity or torque setpoint still to be sent, or
                    // sent and not answered (the deadman then watches it).
                    || job.axes.iter().any(|a| {
                        !a.is_done()
                            && (a.payloads.iter().any(Order::holds_setpoint)
                                || matches!(a.state, AxisState::InFlight { payload, .. } if payload.holds_setpoint()))
                    }))
        };
        self.cancel_where(
            "cancelled by the end of input: it would not end by itself",
            open,
        );
        let held = self.joints_where(|j| j.liveness.deadman().is_some());
        for &ji in &held {
            if let Some(j) = self.joints.get_mut(ji) {
                j.liveness.disarm_deadman();
            }
        }
        self.hold_still(now, held, false);
        self.finish_jobs();
    }

    /// Interrupted (a signal): everything queued or in flight is cancelled
    /// and every joint deactivated now.
    pub(super) fn on_interrupt(&mut self) {
        if matches!(self.phase, Phase::Stopping | Phase::Finished) {
            return;
        }
        let stopping = Event::Stopping {
            reason: "interrupted".to_owned(),
        };
        self.out.push_back(Output::Event(stopping.clone()));
        if let Phase::Starting(s) = &mut self.phase {
            let (to_greet, waiting) = (std::mem::take(&mut s.to_greet), s.take_waiting());
            self.greet_all(to_greet, &stopping);
            for w in waiting {
                self.stats.lines += 1;
                self.refuse(&w.meta, Refusal::Interrupted);
            }
        }
        self.cancel_everything("cancelled: the bridge was interrupted");
        self.enter(Phase::Stopping);
    }

    // ---- input ----------------------------------------------------------
}

impl Phase {
    /// The changes the engine makes, all of them: starting to running (or
    /// straight to draining or stopping), running to draining or stopping,
    /// draining to stopping, and to finished once the stop is answered.
    pub(super) const fn allows(&self, to: &Self) -> bool {
        matches!(
            (self, to),
            (Self::Starting(_), Self::Running | Self::Stopping)
                | (Self::Running, Self::Draining { .. } | Self::Stopping)
                | (Self::Draining { .. }, Self::Stopping)
                | (Self::Stopping, Self::Finished)
        )
    }

    /// Its name, as an illegal change says it.
    pub(super) const fn name(&self) -> &'static str {
        match self {
            Self::Starting(_) => "starting",
            Self::Running => "running",
            Self::Draining { .. } => "draining",
            Self::Stopping => "stopping",
            Self::Finished => "finished",
        }
    }
}

/// What the starting phase alone keeps: when the devices have settled,
/// whether the input already ended, the lines and the clients waiting for
/// the joints to be ready. Gone with the phase: a bridge past starting has
/// no line waiting for it, by construction.
#[derive(Debug, Default, PartialEq)]
pub(super) struct Starting {
    /// The startup answered: until when the devices may settle (their
    /// first reading) before the bridge is ready all the same.
    pub(super) settle_until: Option<Duration>,
    /// The end of input came while starting: once running, lines and
    /// moves finish by this deadline.
    pub(super) drain_after: Option<Duration>,
    /// Lines that came while the joints start, in their order, each with
    /// its text.
    waiting: VecDeque<Waiting>,
    /// Clients that connected while starting: greeted once ready (or told
    /// the bridge stops).
    pub(super) to_greet: Vec<Origin>,
}

impl Starting {
    /// Keeps `line` for the start's end, unless `max` lines wait already:
    /// then it is given back.
    pub(super) fn wait(&mut self, line: Waiting, max: usize) -> Result<(), Waiting> {
        if self.waiting.len() >= max {
            return Err(line);
        }
        self.waiting.push_back(line);
        Ok(())
    }

    /// How many lines wait.
    pub(super) fn waiting(&self) -> usize {
        self.waiting.len()
    }

    /// Every line waiting, in order, none kept.
    pub(super) fn take_waiting(&mut self) -> VecDeque<Waiting> {
        std::mem::take(&mut self.waiting)
    }

    /// `origin` is gone: it is not greeted, and its waiting lines are
    /// taken from the queue and given back, in order, to be counted
    /// cancelled (said in `client_dropped`: the client cannot be told).
    pub(super) fn forget(&mut self, origin: Origin) -> Vec<Waiting> {
        self.to_greet.retain(|o| *o != origin);
        let mut gone = Vec::new();
        for w in std::mem::take(&mut self.waiting) {
            if w.meta.origin == origin {
                gone.push(w);
            } else {
                self.waiting.push_back(w);
            }
        }
        gone
    }
}

/// A phase change no path of the engine makes: a bug, said as the bridge
/// stops.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error(
    "internal error: the bridge went from {from} to {to}, which it never does; it stops every joint"
)]
pub(super) struct IllegalTransition {
    pub(super) from: &'static str,
    pub(super) to: &'static str,
}

#[cfg(test)]
mod tests {
    use super::*;

    fn line(origin: u64, number: u64) -> Waiting {
        Waiting {
            at: Duration::from_millis(number),
            meta: LineMeta::new(Origin(origin), number),
            text: format!("line {number} of {origin}"),
        }
    }

    fn numbers(lines: &VecDeque<Waiting>) -> Vec<(u64, u64)> {
        lines
            .iter()
            .map(|w| (w.meta.origin.0, w.meta.number))
            .collect()
    }

    /// Lines wait in their order up to the bound; the one past it is
    /// given back whole, to be refused, and nothing already kept is lost.
    #[test]
    fn lines_wait_in_order_up_to_the_bound() {
        let mut s = Starting::default();
        for n in 1..=3 {
            assert_eq!(s.wait(line(1, n), 3), Ok(()));
        }
        assert_eq!(s.wait(line(2, 1), 3), Err(line(2, 1)));
        assert_eq!(s.waiting(), 3);
        assert_eq!(numbers(&s.take_waiting()), [(1, 1), (1, 2), (1, 3)]);
        assert_eq!(s.waiting(), 0);
        assert_eq!(s.wait(line(2, 1), 3), Ok(()));
    }

    /// A client gone takes its waiting lines (in their order) and its
    /// greeting with it; everyone else's stay as they were.
    #[test]
    fn a_client_gone_takes_only_its_own_lines_and_greeting() {
        let mut s = Starting::default();
        for (o, n) in [(1, 1), (2, 1), (1, 2), (3, 1), (1, 3)] {
            assert_eq!(s.wait(line(o, n), 10), Ok(()));
        }
        s.to_greet = vec![Origin(1), Origin(2), Origin(1)];
        let gone: Vec<u64> = s.forget(Origin(1)).iter().map(|w| w.meta.number).collect();
        assert_eq!(gone, [1, 2, 3]);
        assert_eq!(s.to_greet, [Origin(2)]);
        assert_eq!(numbers(&s.take_waiting()), [(2, 1), (3, 1)]);
        assert!(s.forget(Origin(9)).is_empty());
    }
}
