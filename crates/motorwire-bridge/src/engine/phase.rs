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
        match self.phase {
            Phase::Starting { .. } => self.to_greet.push(origin),
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

    /// The clients waiting for `ready` greeted with `event`.
    pub(super) fn greet_waiting(&mut self, event: &Event) {
        for origin in std::mem::take(&mut self.to_greet) {
            self.out.push_back(Output::ToOne {
                origin,
                event: event.clone(),
            });
        }
    }

    /// Started and every device that answers read (or silent past the
    /// offline time): ready.
    pub(super) fn try_ready(&mut self) {
        let Phase::Starting {
            settle_until: Some(until),
            ..
        } = self.phase
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
        let from = self.phase;
        if !from.allows(to) {
            return self.illegal_transition(IllegalTransition {
                from: from.name(),
                to: to.name(),
            });
        }
        match to {
            Phase::Running => {
                self.phase = Phase::Running;
                let ready = self.ready_event();
                // Everyone's first, then the greetings: a runner holds
                // everyone's lines from a client until its greeting, so
                // each waiting client has one ready, as its first line.
                self.out.push_back(Output::Event(ready.clone()));
                self.greet_waiting(&ready);
                while let Some(w) = self.waiting.pop_front() {
                    self.take_line(w.at, w.meta, &w.text);
                }
                if let Phase::Starting {
                    drain_after: Some(deadline),
                    ..
                } = from
                {
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
            Phase::Starting { .. } => {}
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
            Phase::Starting { drain_after, .. } => *drain_after = Some(deadline),
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
        self.greet_waiting(&stopping);
        let waiting: Vec<Waiting> = self.waiting.drain(..).collect();
        for w in waiting {
            self.stats.lines += 1;
            self.refuse(&w.meta, Refusal::Interrupted);
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
    pub(super) const fn allows(self, to: Self) -> bool {
        matches!(
            (self, to),
            (Self::Starting { .. }, Self::Running | Self::Stopping)
                | (Self::Running, Self::Draining { .. } | Self::Stopping)
                | (Self::Draining { .. }, Self::Stopping)
                | (Self::Stopping, Self::Finished)
        )
    }

    /// Its name, as an illegal change says it.
    pub(super) const fn name(self) -> &'static str {
        match self {
            Self::Starting { .. } => "starting",
            Self::Running => "running",
            Self::Draining { .. } => "draining",
            Self::Stopping => "stopping",
            Self::Finished => "finished",
        }
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
