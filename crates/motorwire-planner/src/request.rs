use crate::{Float, PlanError};

/// What to do when the target cannot be reached without passing it (a
/// start velocity too fast to brake in time, or a target velocity pointing
/// back towards the start).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Overshoot {
    /// Plan the time-optimal profile that passes the target and comes back;
    /// [`Profile::overshoot`](crate::Profile::overshoot) says by how much.
    #[default]
    Allow,
    /// Refuse with [`PlanError::OvershootForbidden`].
    Forbid,
}

/// A 1-D move: where from and to, how fast it starts and ends, and the
/// limits it must respect. Units are the caller's (degrees or radians, and
/// per second, per second squared); time is in seconds.
///
/// ```
/// use motorwire_planner::{Overshoot, Request};
/// let r = Request::new(0.0, 90.0, 100.0, 500.0)
///     .with_velocities(0.0, 20.0)
///     .with_max_deceleration(250.0)
///     .with_overshoot(Overshoot::Forbid);
/// assert_eq!(r.max_deceleration, Some(250.0));
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Request<F> {
    /// Start position.
    pub start: F,
    /// Target position.
    pub target: F,
    /// Velocity at the start (default 0). It may exceed `max_velocity`: the
    /// profile then brakes to it first, within `max_deceleration`.
    pub start_velocity: F,
    /// Velocity on arrival (default 0); `|target_velocity| <= max_velocity`.
    pub target_velocity: F,
    /// Largest speed, `> 0`.
    pub max_velocity: F,
    /// Largest acceleration while speeding up, `> 0`.
    pub max_acceleration: F,
    /// Largest deceleration while slowing down, `> 0`; `None` is
    /// `max_acceleration`.
    pub max_deceleration: Option<F>,
    /// What to do when the target cannot be reached without passing it.
    pub overshoot: Overshoot,
}

impl<F: Float> Request<F> {
    /// A rest-to-rest move with symmetric limits, overshoot allowed.
    pub fn new(start: F, target: F, max_velocity: F, max_acceleration: F) -> Self {
        Self {
            start,
            target,
            start_velocity: F::ZERO,
            target_velocity: F::ZERO,
            max_velocity,
            max_acceleration,
            max_deceleration: None,
            overshoot: Overshoot::Allow,
        }
    }

    /// Sets the start and target velocities.
    #[must_use]
    pub fn with_velocities(mut self, start_velocity: F, target_velocity: F) -> Self {
        self.start_velocity = start_velocity;
        self.target_velocity = target_velocity;
        self
    }

    /// Sets a deceleration limit different from the acceleration limit.
    #[must_use]
    pub fn with_max_deceleration(mut self, max_deceleration: F) -> Self {
        self.max_deceleration = Some(max_deceleration);
        self
    }

    /// Sets the overshoot policy.
    #[must_use]
    pub fn with_overshoot(mut self, overshoot: Overshoot) -> Self {
        self.overshoot = overshoot;
        self
    }

    /// Checks every field, returning `(max_velocity, max_acceleration,
    /// max_deceleration)`.
    pub(crate) fn limits(&self) -> Result<(F, F, F), PlanError> {
        for (field, v) in [
            ("start", self.start),
            ("target", self.target),
            ("start_velocity", self.start_velocity),
            ("target_velocity", self.target_velocity),
            ("max_velocity", self.max_velocity),
            ("max_acceleration", self.max_acceleration),
        ] {
            if !v.is_finite() {
                return Err(PlanError::NonFinite { field });
            }
        }
        let decel = self.max_deceleration.unwrap_or(self.max_acceleration);
        if !decel.is_finite() {
            return Err(PlanError::NonFinite {
                field: "max_deceleration",
            });
        }
        for (field, v) in [
            ("max_velocity", self.max_velocity),
            ("max_acceleration", self.max_acceleration),
            ("max_deceleration", decel),
        ] {
            if v.partial_cmp(&F::ZERO) != Some(core::cmp::Ordering::Greater) {
                return Err(PlanError::NotPositive {
                    field,
                    value: v.to_f64(),
                });
            }
        }
        if self.target_velocity.abs() > self.max_velocity {
            return Err(PlanError::TargetVelocityTooHigh {
                value: self.target_velocity.abs().to_f64(),
                max: self.max_velocity.to_f64(),
            });
        }
        Ok((self.max_velocity, self.max_acceleration, decel))
    }
}
