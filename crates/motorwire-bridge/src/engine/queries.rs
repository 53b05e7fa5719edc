//! What the bridge answers of itself: its state, its joints, the limits in force, feedback rates.

use super::*;

impl Bridge {
    /// Input lines accepted and not yet answered.
    pub fn pending_lines(&self) -> usize {
        let waiting = match &self.phase {
            Phase::Starting(s) => s.waiting(),
            _ => 0,
        };
        waiting
            + self
                .jobs
                .values()
                .filter(|j| j.kind == JobKind::Command)
                .count()
    }

    /// The joints, in the bus map's order.
    pub fn joints(&self) -> impl Iterator<Item = JointView> + '_ {
        self.joints.iter().map(|j| JointView {
            name: j.identity.name().to_owned(),
            node: j.identity.node(),
            dialect: j.identity.device().dialect_name(),
            version: j.identity.device().version(),
            online: j.liveness.is_online(),
            state: j.lifecycle.state(),
            active: j.lifecycle.is_active(),
            feedback: j.motion.feedback().cloned(),
            target: j.schedule.target(),
            queued: j.schedule.waiting_len() + usize::from(j.schedule.busy().is_some()),
        })
    }

    /// What the bridge knows of its motors now: latched or not, and each
    /// motor's state (online, active, position and velocity as last
    /// reported, the target of its last move, whether it moves, a fault),
    /// positions in each motor's unit. `ready`, `{"query":"state"}` and
    /// [`Bridge::greet`] say it.
    pub fn state(&self) -> BridgeState {
        BridgeState {
            latched: self.stop.is_latched(),
            motors: self.joints.iter().map(|j| self.motor_state(j)).collect(),
        }
    }

    pub(super) fn motor_state(&self, j: &Joint) -> MotorState {
        let unit = self
            .map
            .motor(j.identity.name())
            .map_or(AngleUnit::Degrees, |m| m.unit);
        // Read once it reported where it is (a status alone says not).
        let read = j
            .motion
            .feedback()
            .filter(|_| j.motion.reported().is_some());
        MotorState {
            motor_id: j.identity.name().to_owned(),
            online: j.liveness.is_online(),
            active: j.lifecycle.is_active(),
            position: read.map(|f| shortest(f.position)),
            velocity: read.map(|f| shortest(f.velocity)),
            target: j
                .schedule
                .target()
                .map(|t| short_unit(unit.from_degrees(t))),
            moving: j.schedule.is_moving(self.now),
            fault: j.lifecycle.needs_reset().map(str::to_owned),
        }
    }

    /// The limits of `motor` in force and the bus map's, as JSON.
    pub(super) fn limits_value(&self, motor: &str) -> Option<Value> {
        let now = self.map.motor(motor)?;
        let base = self.base_limits.get(motor)?;
        let as_json = |l: &Limits| {
            let mut m = serde_json::Map::new();
            for (k, v) in [
                ("min_position", l.min_position),
                ("max_position", l.max_position),
                ("max_velocity", l.max_velocity),
                ("max_acceleration", l.max_acceleration),
                ("max_deceleration", l.max_deceleration),
                ("max_jerk", l.max_jerk),
                ("max_torque", l.max_torque),
                ("emergency_deceleration", l.emergency_deceleration),
            ] {
                if let Some(v) = v {
                    m.insert(k.to_owned(), serde_json::json!(v));
                }
            }
            Value::Object(m)
        };
        let mut effective = as_json(&now.limits);
        if let (Some(d), Value::Object(m)) = (self.emergency_decel.get(motor), &mut effective) {
            m.insert("emergency_decel".to_owned(), serde_json::json!(d));
        }
        Some(serde_json::json!({ "effective": effective, "bus_map": as_json(base) }))
    }

    /// `{"query":"state"}`, or one motor's with `"motor_id"`: answered at
    /// once (a line before `ready` waits for it, as every line does).
    pub(super) fn query_state(&mut self, meta: LineMeta, motor: Option<String>) {
        let mut state = self.state();
        let meta = match motor {
            None => meta,
            Some(m) => {
                state.motors.retain(|s| s.motor_id == m);
                let meta = meta.labelled(Label::Motor(m.clone()));
                if let Some(e) = self.unattached(std::iter::once(m.as_str())) {
                    self.refuse(&meta, e);
                    return;
                }
                if state.motors.is_empty() {
                    self.refuse(&meta, Refusal::UnknownMotor { motor: m });
                    return;
                }
                meta
            }
        };
        let r = LineResult {
            ok: true,
            line: meta.number,
            state: Some(state),
            ..LineResult::default()
        };
        self.answer(&meta, r);
    }

    /// `{"feedback_hz":N}`: the client's own feedback rate, answered with
    /// the rate it gets: the bridge's rate divided by a whole number k
    /// (each motor's every k-th feedback line is sent to it), the highest
    /// such rate not above N (what it gets is said, never silently
    /// changed); 0 for none. A rate above the bridge's, or any but 0 with
    /// no feedback at all, is refused.
    pub(super) fn feedback_rate(&mut self, meta: LineMeta, hz: f64) {
        let bridge_hz = self
            .config
            .feedback_period
            .filter(|p| !p.is_zero())
            .map(|p| 1.0 / p.as_secs_f64());
        let refusal = Refusal::FeedbackRate {
            asked: hz,
            bridge_hz,
        };
        let every = match bridge_hz {
            _ if hz.is_nan() || hz < 0.0 => {
                return self.refuse(&meta, refusal);
            }
            _ if hz == 0.0 => 0,
            None => {
                return self.refuse(&meta, refusal);
            }
            // Beyond the rounding of the bridge's rate from its period.
            Some(b) if hz > b * (1.0 + 1e-9) => {
                return self.refuse(&meta, refusal);
            }
            // Every k-th line for a k that fits the count (2^32 - 1): a
            // slower rate than that would be answered with a faster one.
            Some(b) if b / hz - 1e-9 > f64::from(u32::MAX) => {
                return self.refuse(&meta, refusal);
            }
            #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
            Some(b) => ((b / hz - 1e-9).ceil() as u32).max(1),
        };
        let r = LineResult {
            ok: true,
            line: meta.number,
            feedback_every: Some(every),
            feedback_hz: Some(match (bridge_hz, every) {
                (Some(b), k) if k > 0 => b / f64::from(k),
                _ => 0.0,
            }),
            ..LineResult::default()
        };
        self.answer(&meta, r);
    }

    pub(super) fn query_limits(&mut self, meta: LineMeta, motor: &str) {
        let meta = meta.labelled(Label::Motor(motor.to_owned()));
        let Some(limits) = self.limits_value(motor) else {
            self.refuse(
                &meta,
                Refusal::UnknownMotor {
                    motor: motor.to_owned(),
                },
            );
            return;
        };
        let r = LineResult {
            ok: true,
            line: meta.number,
            limits: Some(limits),
            ..LineResult::default()
        };
        self.answer(&meta, r);
    }
}
