//! Admission: a line read into admitted work or a typed refusal (numbering, the clock learnt from a line, the stop that jumps the queue, the lines that wait for the start).

use super::*;

impl Bridge {
    /// Takes one input line received at `now` from `origin`. Blank lines
    /// are ignored; every other line gets exactly one result.
    ///
    /// Results carry `"line"`: the line's number among its origin's
    /// non-blank lines (from 1), so a reader can pair every result, an
    /// unlabelled refusal included, with what it sent.
    pub(super) fn on_line(&mut self, now: Duration, origin: Origin, line: &str) {
        let line = line.trim();
        if line.is_empty() {
            return;
        }
        let number = self.number(origin);
        self.take_line(now, LineMeta::new(origin, number), line);
    }

    /// [`Bridge::handle_numbered_line`] for a line its runner already read
    /// ([`classify`] with this bridge's validator, on the reader's thread),
    /// or not (`None`).
    pub(super) fn on_read_line(
        &mut self,
        now: Duration,
        origin: Origin,
        number: u64,
        line: &str,
        input: Option<Box<Line>>,
    ) {
        let line = line.trim();
        if line.is_empty() {
            return;
        }
        let meta = LineMeta::new(origin, number);
        match input {
            Some(input) => self.take_input(now, meta, line, *input),
            None => self.take_line(now, meta, line),
        }
    }

    /// [`Bridge::handle_unreadable`] for a line its runner already numbered.
    pub(super) fn on_numbered_unreadable(&mut self, origin: Origin, number: u64, reason: &str) {
        self.stats.lines += 1;
        self.refuse(
            &LineMeta::new(origin, number),
            Refusal::Unreadable {
                reason: reason.to_owned(),
            },
        );
    }

    /// A line that could not be read (not UTF-8, too long) but names
    /// `emergency_stop` (a runner finds it while skipping the line): the
    /// bridge cannot tell what it asks, and when in doubt it stops. It is
    /// answered as a stop, `reason` among its problems.
    pub(super) fn on_unreadable_stop(
        &mut self,
        now: Duration,
        origin: Origin,
        number: u64,
        reason: &str,
    ) {
        self.take_stop(
            now,
            LineMeta::new(origin, number),
            vec![format!(
                "{reason}; it names emergency_stop, so it is taken as a stop"
            )],
        );
    }

    /// A stop line (`meta`, labelled when it names a motor or a
    /// command).
    pub(super) fn take_stop(&mut self, now: Duration, meta: LineMeta, problems: Vec<String>) {
        self.stop.line_arrived(now);
        self.stats.lines += 1;
        let cause = match &meta.label {
            Some(Label::Motor(v) | Label::Command(v) | Label::Orion(v)) => v.clone(),
            None => "input".to_owned(),
        };
        self.emergency_stop(now, Some(meta), problems, cause);
    }

    /// A line that could not be read as text (not UTF-8, too long): it
    /// counts as a line of `origin` and is answered
    /// `{"ok":false,"error":{"kind":"unreadable",...}}`.
    pub(super) fn on_unreadable(&mut self, origin: Origin, reason: &str) {
        self.stats.lines += 1;
        let number = self.number(origin);
        self.refuse(
            &LineMeta::new(origin, number),
            Refusal::Unreadable {
                reason: reason.to_owned(),
            },
        );
    }

    /// Forgets `origin`'s line count (a client that left); its lines in
    /// progress are still answered.
    pub(super) fn on_forget(&mut self, origin: Origin) {
        self.line_numbers.remove(&origin);
        self.clocks.forget(origin);
        if let Phase::Starting(s) = &mut self.phase {
            s.to_greet.retain(|o| *o != origin);
        }
    }

    pub(super) fn number(&mut self, origin: Origin) -> u64 {
        let n = self.line_numbers.entry(origin).or_insert(0);
        *n += 1;
        *n
    }

    pub(super) fn take_line(&mut self, now: Duration, meta: LineMeta, line: &str) {
        let input = classify(&self.validator, line);
        self.take_input(now, meta, line, input);
    }

    /// A line, read as `input`.
    pub(super) fn take_input(&mut self, now: Duration, meta: LineMeta, line: &str, input: Line) {
        // The stop is acted on in every phase but the last, ahead of all.
        if let Line::Stop { label, problems } = input {
            self.take_stop(now, meta.with(label), problems);
            return;
        }
        match self.phase {
            Phase::Starting(_) => return self.wait_for_start(now, meta, line),
            Phase::Running => {}
            Phase::Draining { .. } | Phase::Stopping | Phase::Finished => {
                self.stats.lines += 1;
                self.refuse(&meta, Refusal::ShuttingDown);
                return;
            }
        }
        self.stats.lines += 1;
        self.serve(now, meta, input);
    }

    /// A line that came while the joints start: it waits for them (its
    /// text kept), unless as many lines wait as the bridge keeps.
    fn wait_for_start(&mut self, now: Duration, meta: LineMeta, line: &str) {
        let Phase::Starting(s) = &mut self.phase else {
            return;
        };
        let line = Waiting {
            at: now,
            meta,
            text: line.to_owned(),
        };
        if let Err(line) = s.wait(line, self.config.max_pending_lines) {
            self.stats.lines += 1;
            self.busy(&line.meta, Refusal::WaitingForStart);
        }
    }

    /// A line of the running bridge, read as `input`: each form to what
    /// serves it.
    fn serve(&mut self, now: Duration, meta: LineMeta, input: Line) {
        match input {
            Line::Stop { .. } => {}
            // A stop that arrived after this release was acted on first (it
            // overtook the queue, or the release waited for startup):
            // releasing now would let what followed the release run after
            // the stop.
            Line::Release if self.stop.overtaken(now) => {
                self.refuse(&meta, Refusal::StopOvertookRelease)
            }
            Line::Release => self.release(now, meta),
            Line::BadRelease { reason } => {
                self.refuse(&meta, Refusal::BadRelease { reason });
            }
            Line::Invalid {
                message,
                violations,
                more,
                label,
            } => {
                self.refuse(
                    &meta.with(label),
                    Refusal::Invalid {
                        message,
                        violations,
                        more,
                    },
                );
            }
            Line::QueryLimits { motor_id } => self.query_limits(meta, &motor_id),
            Line::QueryState { motor_id } => self.query_state(meta, motor_id),
            Line::FeedbackRate { hz } => self.feedback_rate(meta, hz),
            Line::OrionCommand { command } => self.arm_command(now, meta, command),
            Line::Request { kind, motor_id } => {
                self.request_line(now, meta, kind, &motor_id);
            }
            Line::Calibration { motor_id, start } => {
                self.calibration_line(now, meta, &motor_id, start);
            }
            Line::Reset { motor_id } => self.reset_joint(now, meta, &motor_id),
            Line::Trajectories { id, trajectories } => {
                self.trajectories(now, meta, &id, &trajectories);
            }
            Line::Stream(mut cmd) => {
                let meta = LineMeta {
                    stream: true,
                    ..meta
                };
                self.motor_command(now, meta, &mut cmd);
            }
            Line::StreamAxes(cmd) => {
                let meta = LineMeta {
                    stream: true,
                    ..meta
                };
                self.multi_axis(now, meta, &cmd);
            }
            Line::Motor { action, motor_id } => self.motor_line(now, meta, action, &motor_id),
            // Read where it lies: a command is the largest message, and
            // every line is one.
            Line::Message(mut m) => self.serve_message(now, meta, m.as_mut()),
        }
    }

    /// A WIA message: a command, SafetyLimits or a trajectory served; the
    /// kinds the bridge does not take refused.
    fn serve_message(&mut self, now: Duration, meta: LineMeta, m: &mut Message) {
        match m {
            Message::MotorCommand(cmd) => self.motor_command(now, meta, cmd),
            Message::MultiAxisCommand(cmd) => self.multi_axis(now, meta, cmd),
            Message::SafetyLimits(l) => self.safety_limits(meta, l),
            Message::Trajectory(t) => {
                let id = t.trajectory_id.clone();
                self.trajectories(now, meta, &id, std::slice::from_ref(t));
            }
            Message::PidConfig(p) => self.refuse(
                &meta.labelled(Label::Motor(p.motor_id.clone())),
                Refusal::PidGains,
            ),
            Message::ControlModeConfig(_) => self.refuse(&meta, Refusal::ControlModeConfig),
            other => self.refuse(&meta, Refusal::UnsupportedKind { kind: other.kind() }),
        }
    }

    // ---- trajectories -----------------------------------------------------------

    pub(super) fn refuse(&mut self, meta: &LineMeta, refusal: Refusal) {
        let r = LineResult {
            ok: false,
            line: meta.number,
            error: Some(refusal.into()),
            ..LineResult::default()
        };
        self.answer(meta, r);
    }

    /// Gives `r` to `meta`'s origin, labelled as `meta` is, counting it.
    /// (A result is some 460 bytes: one made in its box where it is built
    /// is not copied there.)
    pub(super) fn answer(&mut self, meta: &LineMeta, r: impl Into<Box<LineResult>>) {
        let mut r: Box<LineResult> = r.into();
        r.bound();
        if r.ok {
            self.stats.ok += 1;
        } else {
            self.stats.failed += 1;
        }
        if let Some(label) = meta.label.clone() {
            label.apply(&mut r);
        }
        self.out.push_back(Output::Result {
            origin: meta.origin,
            result: r,
        });
    }

    pub(super) fn busy(&mut self, meta: &LineMeta, refusal: Refusal) {
        self.stats.busy += 1;
        self.refuse(meta, refusal);
    }

    /// The telemetry a device gets when configured, if
    /// [`BridgeConfig::telemetry_hz`] asks (a device takes it where its
    /// dialect has it: [`Device::lifecycle_orders`]).
    pub(super) fn telemetry_subscription(&self) -> Option<Lifecycle> {
        let rate_hz = self.config.telemetry_hz.filter(|r| *r > 0)?;
        Some(Lifecycle::Telemetry { rate_hz })
    }

    /// Learns `origin`'s clock from a line stamped `timestamp` that
    /// reached the bridge at `now`: only where timestamps are held to the
    /// bridge's clock (an epoch and a max age), and only from a timestamp
    /// within the allowed skew (one outside it teaches nothing and is
    /// refused `stale`).
    pub(super) fn learn_clock(&mut self, now: Duration, origin: Origin, timestamp: f64) {
        if let (Some(epoch), Some(max_age)) = (self.config.epoch_unix_ms, self.config.max_age) {
            let arrived = epoch + now.as_secs_f64() * 1000.0;
            let offset = arrived - timestamp;
            if offset.is_finite() && offset.abs() <= max_age.as_secs_f64() * 1000.0 {
                self.clocks.learn(origin, offset);
            }
        }
    }

    /// Admission as the bridge stands now: what reads a motion line's
    /// right to run before anything is planned.
    #[inline]
    pub(super) fn admission(&self) -> Admission<'_> {
        Admission {
            now: self.now,
            config: &self.config,
            stop: &self.stop,
            clocks: &self.clocks,
            joints: &self.joints,
            drivers: &self.drivers,
            pending: self.pending_lines(),
        }
    }
}

/// Admission: what refuses a motion line before anything is planned, read
/// from the bridge as it stands (the stop's latch, the clocks it learned,
/// its devices' liveness and queues, the lines in progress). It changes
/// nothing: a line it refuses leaves no trace but its result.
pub(super) struct Admission<'a> {
    /// The bridge's clock.
    pub(super) now: Duration,
    pub(super) config: &'a BridgeConfig,
    pub(super) stop: &'a StopLatch,
    pub(super) clocks: &'a ClockOffsets,
    pub(super) joints: &'a Joints,
    pub(super) drivers: &'a Drivers,
    /// Lines accepted and not yet answered.
    pub(super) pending: usize,
}

impl Admission<'_> {
    /// The device named `motor` in the bus map.
    #[inline]
    fn joint(&self, motor: &str) -> Option<&Joint> {
        let ji = self.joints.find(|j| j.identity.name() == motor)?;
        self.joints.get(ji)
    }

    /// [`Admission::admit`] for a line that carries no timestamp (taken as
    /// sent now).
    #[inline]
    pub(super) fn admit_now<'a>(
        &self,
        motors: impl Iterator<Item = &'a str> + Clone,
    ) -> Result<(), Refusal> {
        let now_ms = self
            .config
            .epoch_unix_ms
            .map_or(0.0, |e| e + self.now.as_secs_f64() * 1000.0);
        self.admit(self.now, None, now_ms, motors)
    }

    /// Admission: what refuses a motion line before anything is planned.
    /// `arrived` is when the line reached the bridge, `origin` whose
    /// clock its `timestamp` is on (`None`: the bridge's own).
    #[inline]
    pub(super) fn admit<'a>(
        &self,
        arrived: Duration,
        origin: Option<Origin>,
        timestamp: f64,
        mut motors: impl Iterator<Item = &'a str> + Clone,
    ) -> Result<(), Refusal> {
        if self.stop.is_latched() {
            return Err(Refusal::Latched);
        }
        self.check_timestamp(arrived, origin, timestamp)?;
        self.check_motors(motors.clone())?;
        if self.pending >= self.config.max_pending_lines {
            return Err(Refusal::LinesInProgress {
                max: self.config.max_pending_lines,
            });
        }
        if let Some(m) = motors.find(|m| {
            self.joint(m)
                .is_some_and(|j| j.schedule.waiting_len() >= self.config.max_queue_per_joint)
        }) {
            return Err(Refusal::QueueFull {
                motor: m.to_owned(),
                max: self.config.max_queue_per_joint,
            });
        }
        Ok(())
    }

    /// Whether a line stamped `timestamp` (on `origin`'s clock), that
    /// reached the bridge at `arrived`, may run: not written before the
    /// last emergency stop, and within the allowed clock skew.
    #[inline]
    fn check_timestamp(
        &self,
        arrived: Duration,
        origin: Option<Origin>,
        timestamp: f64,
    ) -> Result<(), Refusal> {
        // The timestamp on the bridge's clock, as far as the client's
        // lines tell: a clock that runs ahead is taken back by as much
        // (never forward: a clock behind only refuses more). Held to the
        // bridge's clock only where a max age is in force: without one,
        // timestamps may be any number.
        let written = timestamp + origin.map_or(0.0, |o| self.clocks.behind(o));
        if let Some(r) =
            self.stop
                .written_before(arrived, timestamp, written, self.config.max_age.is_some())
        {
            return Err(r);
        }
        if let (Some(epoch), Some(max_age)) = (self.config.epoch_unix_ms, self.config.max_age) {
            let now_ms = epoch + self.now.as_secs_f64() * 1000.0;
            let skew = max_age.as_secs_f64() * 1000.0;
            let age = now_ms - timestamp;
            if age > skew || -age > skew {
                // A timestamp in microseconds is a mistake often made: said
                // when the value read in that unit would have been within
                // the skew. (One in seconds is the validator's
                // `timestamp-unit`, refused before it gets here.)
                return Err(Refusal::Stale {
                    timestamp,
                    age_ms: age,
                    max_age,
                    microseconds: (now_ms * 1000.0 - timestamp).abs() / 1000.0 <= skew,
                });
            }
        }
        Ok(())
    }

    /// Whether each of `motors` takes a line: none lost until a reset,
    /// none offline.
    #[inline]
    fn check_motors<'a>(
        &self,
        motors: impl Iterator<Item = &'a str> + Clone,
    ) -> Result<(), Refusal> {
        if let Some(err) = motors.clone().find_map(|m| {
            let j = self.joint(m)?;
            let why = j.lifecycle.needs_reset()?;
            Some(Refusal::NeedsReset {
                motor: m.to_owned(),
                why: why.to_owned(),
            })
        }) {
            return Err(err);
        }
        if let Some(err) = motors.clone().find_map(|m| {
            let j = self.joint(m)?;
            (!j.liveness.is_online()).then(|| Refusal::Offline {
                motor: m.to_owned(),
                why: Some(
                    self.drivers
                        .offline_reason(j.identity.device())
                        .map_or_else(
                            || {
                                format!(
                                    "nothing heard from {}",
                                    j.identity.device().who(j.identity.node())
                                )
                            },
                            str::to_owned,
                        ),
                ),
            })
        }) {
            return Err(err);
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    const MAP: &str = "[motors.elbow]\ndialect = \"irpc\"\nnode = 0x12\n\
                       [motors.wrist]\ndialect = \"irpc\"\nnode = 0x13\n";
    /// The bridge's wall clock at its time zero (Unix ms).
    const EPOCH: f64 = 1.7e12;

    /// A bridge on [`MAP`] that holds timestamps to its wall clock (one
    /// second of skew), started without activating its joints.
    fn bridge() -> Bridge {
        let config = BridgeConfig {
            activate_on_start: false,
            epoch_unix_ms: Some(EPOCH),
            max_age: Some(Duration::from_secs(1)),
            ..BridgeConfig::default()
        };
        let mut b = Bridge::new(BusMap::from_toml(MAP).unwrap(), config).unwrap();
        b.start(Duration::ZERO);
        b
    }

    /// A timestamp too old, or in the future, is refused `stale` with its
    /// age; one that would be within the skew read in microseconds is said
    /// to be so; one within the skew runs.
    #[test]
    fn timestamps_are_held_to_the_clock_and_microseconds_are_named() {
        let b = bridge();
        let a = b.admission();
        let max_age = Duration::from_secs(1);
        let admit = |t: f64| a.admit(Duration::ZERO, None, t, std::iter::empty());
        assert_eq!(admit(EPOCH - 999.0), Ok(()));
        assert_eq!(admit(EPOCH + 999.0), Ok(()));
        assert_eq!(
            admit(EPOCH - 5_000.0),
            Err(Refusal::Stale {
                timestamp: EPOCH - 5_000.0,
                age_ms: 5_000.0,
                max_age,
                microseconds: false,
            })
        );
        assert_eq!(
            admit(EPOCH * 1000.0),
            Err(Refusal::Stale {
                timestamp: EPOCH * 1000.0,
                age_ms: EPOCH - EPOCH * 1000.0,
                max_age,
                microseconds: true,
            })
        );
    }

    /// The latch refuses first, whatever else is wrong with the line (here
    /// a timestamp of 1970 and a motor nobody has); its release lets the
    /// same line through.
    #[test]
    fn the_latch_refuses_before_anything_else() {
        let mut b = bridge();
        b.stop.latch(std::iter::empty());
        let a = b.admission();
        assert_eq!(
            a.admit(Duration::ZERO, None, 0.0, ["nobody"].into_iter()),
            Err(Refusal::Latched)
        );
        let _ = b.stop.release();
        assert_eq!(b.admission().admit_now(["elbow"].into_iter()), Ok(()));
    }

    /// The bounds are the configuration's: at as many lines in progress as
    /// it takes, a line is refused `busy`; at as many steps waiting for a
    /// motor, a line for that motor is, and a line for another is not.
    #[test]
    fn the_bounds_are_the_configurations() {
        let b = bridge();
        let max = b.config.max_pending_lines;
        let full = Admission {
            pending: max,
            ..b.admission()
        };
        assert_eq!(
            full.admit_now(["elbow"].into_iter()),
            Err(Refusal::LinesInProgress { max })
        );
        let config = BridgeConfig {
            max_queue_per_joint: 0,
            ..b.config
        };
        let no_queue = Admission {
            config: &config,
            ..b.admission()
        };
        assert_eq!(
            no_queue.admit_now(["wrist", "elbow"].into_iter()),
            Err(Refusal::QueueFull {
                motor: "wrist".to_owned(),
                max: 0
            })
        );
        assert_eq!(
            b.admission().admit_now(["wrist", "elbow"].into_iter()),
            Ok(())
        );
    }

    /// A device lost until a reset is refused as such, before an offline
    /// one, whichever the line names first; an offline one says why.
    #[test]
    fn a_lost_device_is_named_before_an_offline_one() {
        let mut b = bridge();
        let elbow = b.joint_index("elbow").unwrap();
        let wrist = b.joint_index("wrist").unwrap();
        b.joints
            .get_mut(wrist)
            .unwrap()
            .lifecycle
            .lost("faulted (error code 5)".to_owned());
        let _ = b.joints.get_mut(elbow).unwrap().liveness.went_offline();
        assert_eq!(
            b.admission().admit_now(["elbow", "wrist"].into_iter()),
            Err(Refusal::NeedsReset {
                motor: "wrist".to_owned(),
                why: "faulted (error code 5)".to_owned(),
            })
        );
        assert_eq!(
            b.admission().admit_now(["elbow"].into_iter()),
            Err(Refusal::Offline {
                motor: "elbow".to_owned(),
                why: Some("nothing heard from node 0x12".to_owned()),
            })
        );
    }
}
