//! Keeping a moving joint within the limits in force: the limit brake, and its renewal.

use super::*;

impl Bridge {
    /// Devices holding a velocity or torque setpoint that would carry them
    /// past a position limit in force before they could stop (braked at
    /// [`Self::braking`], from where their feedback says they are now and
    /// how fast they go, [`BRAKE_LOOKAHEAD`] ahead): brought to a stop now,
    /// with that deceleration where the device takes one (a moteus
    /// controller's velocity 0 within it; the others their own stop), a
    /// `limit_brake` event each.
    pub(super) fn keep_within_limits(&mut self, now: Duration) {
        if self.stop.is_latched() {
            return;
        }
        let mut brake = Vec::new();
        for (ji, j) in self.joints.with_ids() {
            let Some((at, limit_name, limit)) = self.brake_due(j) else {
                continue;
            };
            if at > now {
                continue;
            }
            let (Some(f), Some(m)) = (j.motion.feedback(), self.map.motor(j.identity.name()))
            else {
                continue;
            };
            let decel = Self::braking(&m.limits).map(|d| m.unit.to_degrees(d));
            brake.push((
                ji,
                decel,
                limit_name,
                Event::LimitBrake {
                    motor_id: j.identity.name().to_owned(),
                    position: f.position,
                    velocity: f.velocity,
                    limit_name,
                    limit,
                },
            ));
        }
        let now_ms = self.unix_ms(now) as u64;
        for (ji, decel, limit_name, event) in brake {
            let Some(j) = self.joints.get_mut(ji) else {
                continue;
            };
            let speed = j.motion.reported_speed();
            j.motion.braked(limit_name, now, speed);
            let order = j
                .identity
                .device()
                .limit_brake(decel)
                .or_else(|| j.identity.device().hold_still(now_ms));
            match order {
                Some(order) => self.stop_setpoint(now, ji, order, Some(event)),
                None => {
                    if let Some(j) = self.joints.get_mut(ji) {
                        j.liveness.disarm_deadman();
                        j.motion.brake_sent();
                    }
                }
            }
        }
    }

    /// When device `j`, holding a velocity or torque setpoint, must be
    /// braked to stop short of a position limit in force, and which limit:
    /// from its last feedback (where it was, how fast it went, when it was
    /// heard), the time it reaches the limit less its stopping distance
    /// ([`Self::braking`]) and [`BRAKE_LOOKAHEAD`]. `None` for a device
    /// holding no setpoint, at rest, or moving away from its limits.
    pub(super) fn brake_due(&self, j: &Joint) -> Option<(Duration, &'static str, f64)> {
        if j.liveness.deadman().is_none() {
            return self.brake_again(j);
        }
        let f = j.motion.feedback()?;
        let m = self.map.motor(j.identity.name())?;
        // As fast as it goes, or as it is told to go where that is faster
        // (its feedback may not show the speed it is getting up to).
        let v = j
            .motion
            .held_velocity()
            .filter(|h| h.is_finite() && h.abs() > f.velocity.abs())
            .unwrap_or(f.velocity);
        let p = f.position;
        if !p.is_finite() || !v.is_finite() || v == 0.0 {
            return None;
        }
        // Speeding up outward (a torque, or a velocity it is still getting
        // up to): as fast as it will go [`BRAKE_LOOKAHEAD`] on at the
        // acceleration its reports show, and as far as it gets by then.
        let (reach_v, travel) = Self::lookahead(j, m, v);
        let stopping = Self::stopping(&m.limits, reach_v);
        let (limit_name, limit, room) = if v > 0.0 {
            let hi = m.limits.max_position?;
            ("max_position", hi, hi - p - stopping - travel)
        } else {
            let lo = m.limits.min_position?;
            ("min_position", lo, p - lo - stopping - travel)
        };
        let heard = j.liveness.last_heard().unwrap_or(self.now);
        let in_s = (room / reach_v).clamp(0.0, 3600.0);
        let at = heard.saturating_add(Duration::from_secs_f64(in_s));
        Some((at, limit_name, limit))
    }

    /// A motor braked short of a limit whose reports, [`REBRAKE_AFTER`] on,
    /// show it going on toward that limit as fast as when it was braked:
    /// braked again now (the brake was lost on the bus: a compact device
    /// acknowledges a command with whatever feedback comes next).
    pub(super) fn brake_again(&self, j: &Joint) -> Option<(Duration, &'static str, f64)> {
        let crate::joints::LimitBraked {
            side, at, speed, ..
        } = j.motion.limit_braked()?;
        let f = j.motion.feedback()?;
        let m = self.map.motor(j.identity.name())?;
        let heard = j.liveness.last_heard()?;
        let (toward, limit) = if side == "max_position" {
            (f.velocity, m.limits.max_position?)
        } else {
            (-f.velocity, m.limits.min_position?)
        };
        (heard >= at.saturating_add(REBRAKE_AFTER) && toward > 0.0 && toward >= 0.9 * speed)
            .then_some((heard, side, limit))
    }

    /// Why a velocity or torque `setpoint` for `motor` is refused: it
    /// points past a position limit in force from where the motor stands,
    /// nearer than it could stop from that speed ([`Self::braking`],
    /// [`BRAKE_LOOKAHEAD`] ahead), or at the limit for a torque.
    pub(super) fn outward_at_limit(
        &self,
        motor: &str,
        mode: motorwire_core::ControlMode,
        setpoint: f64,
    ) -> Option<Refusal> {
        if !matches!(
            mode,
            motorwire_core::ControlMode::Velocity | motorwire_core::ControlMode::Torque
        ) || setpoint == 0.0
        {
            return None;
        }
        let j = self.joints.get(self.joint_index(motor)?)?;
        let f = j.motion.feedback()?;
        let m = self.map.motor(motor)?;
        let p = f.position;
        let toward = if setpoint > 0.0 {
            "max_position"
        } else {
            "min_position"
        };
        // Still on its way toward that limit: faster than a 1,000th of its
        // velocity limit (a motor at rest reports noise).
        let still = m
            .limits
            .max_velocity
            .map_or(1e-3, |v| (v.abs() * 1e-3).max(1e-9));
        let reach = if j.motion.limit_braked().is_some_and(|b| b.side == toward)
            && f.velocity * setpoint.signum() > still
        {
            // Braked short of that limit and still on its way to it: no
            // setpoint toward it until it has stopped.
            f64::INFINITY
        } else if mode == motorwire_core::ControlMode::Velocity {
            setpoint.abs() * BRAKE_LOOKAHEAD.as_secs_f64() + Self::stopping(&m.limits, setpoint)
        } else {
            // A torque toward the limit: as far as it would get before a
            // brake could stop it, from its speed toward the limit (none
            // if it goes the other way: the torque turns it), speeding up
            // as fast as a torque has driven it before, and no slower than
            // the limits' acceleration, over two lookaheads (one to its
            // next report, one for the brake to go).
            let t = 2.0 * BRAKE_LOOKAHEAD.as_secs_f64();
            let a = m
                .unit
                .from_degrees(j.motion.peak_accel())
                .abs()
                .max(m.limits.max_acceleration.unwrap_or(0.0));
            let (reach_v, travel) = ahead((f.velocity * setpoint.signum()).max(0.0), a, t);
            travel + Self::stopping(&m.limits, reach_v)
        };
        let (limit_name, limit) = if setpoint > 0.0 {
            (
                "max_position",
                m.limits.max_position.filter(|hi| p + reach >= *hi)?,
            )
        } else {
            (
                "min_position",
                m.limits.min_position.filter(|lo| p - reach <= *lo)?,
            )
        };
        Some(Refusal::OutwardAtLimit {
            motor: motor.to_owned(),
            at: p,
            mode: if mode == motorwire_core::ControlMode::Velocity {
                "velocity"
            } else {
                "torque"
            },
            setpoint,
            limit_name,
            source: m.limits_source,
            limit,
        })
    }
}
