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

/// Which kind of profile [`plan`](crate::plan) builds, as iRPC's
/// `SetTargetV2.profile` names them.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum MotionProfile {
    /// Acceleration steps between `+max_acceleration`, 0 and
    /// `-max_deceleration`; jerk is unbounded and `max_jerk` ignored.
    Trapezoidal,
    /// Jerk-limited: at most seven phases of jerk `+max_jerk`, 0 or
    /// `-max_jerk`; acceleration is continuous. Needs a positive `max_jerk`.
    SCurve,
    /// The iRPC document reserves `Adaptive` for "load-adaptive" motion it
    /// does not define. motorwire plans it as [`SCurve`](Self::SCurve) when
    /// `max_jerk` is given and positive, and as
    /// [`Trapezoidal`](Self::Trapezoidal) otherwise (the document: "max_jerk
    /// <= 0 disables jerk limiting"). It never adapts to load.
    #[default]
    Adaptive,
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
    /// Acceleration at the start (default 0): the acceleration of the motion
    /// in progress when this one replaces it. An S-curve continues from it
    /// (its acceleration does not step, so its jerk stays within
    /// `max_jerk`); a trapezoidal profile, whose acceleration steps anyway,
    /// ignores it. See [`with_start_acceleration`](Self::with_start_acceleration).
    pub start_acceleration: F,
    /// Largest speed, `> 0`.
    pub max_velocity: F,
    /// Largest acceleration while speeding up, `> 0`.
    pub max_acceleration: F,
    /// Largest deceleration while slowing down, `> 0`; `None` is
    /// `max_acceleration`.
    pub max_deceleration: Option<F>,
    /// Largest jerk, `> 0`; needed by [`MotionProfile::SCurve`], ignored
    /// by [`MotionProfile::Trapezoidal`].
    pub max_jerk: Option<F>,
    /// The kind of profile [`plan`](crate::plan) builds.
    pub profile: MotionProfile,
    /// What to do when the target cannot be reached without passing it.
    pub overshoot: Overshoot,
}

impl<F: Float> Request<F> {
    /// A rest-to-rest move with symmetric limits, no jerk limit (so
    /// [`MotionProfile::Adaptive`] plans it trapezoidal), overshoot allowed.
    pub fn new(start: F, target: F, max_velocity: F, max_acceleration: F) -> Self {
        Self {
            start,
            target,
            start_velocity: F::ZERO,
            target_velocity: F::ZERO,
            start_acceleration: F::ZERO,
            max_velocity,
            max_acceleration,
            max_deceleration: None,
            max_jerk: None,
            profile: MotionProfile::Adaptive,
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

    /// Sets the acceleration at the start: a jerk-limited profile then
    /// continues the motion in progress without a step in acceleration.
    /// It may exceed the acceleration limits (a motion braked harder than
    /// this one allows): the profile then brings it within them at
    /// `max_jerk` first.
    ///
    /// ```
    /// use motorwire_planner::{Request, plan};
    /// // Mid-move: at 10 deg, 40 deg/s, still speeding up at 300 deg/s²,
    /// // a new target. The new profile starts where the old one was.
    /// let req = Request::new(10.0f64, 60.0, 120.0, 500.0)
    ///     .with_jerk(2000.0)
    ///     .with_velocities(40.0, 0.0)
    ///     .with_start_acceleration(300.0);
    /// let p = plan(&req)?;
    /// let s = p.sample(0.0);
    /// assert_eq!((s.position, s.velocity, s.acceleration), (10.0, 40.0, 300.0));
    /// assert_eq!(p.sample(p.duration()).position, 60.0);
    /// # Ok::<(), motorwire_planner::PlanError>(())
    /// ```
    #[must_use]
    pub fn with_start_acceleration(mut self, start_acceleration: F) -> Self {
        self.start_acceleration = start_acceleration;
        self
    }

    /// Sets a deceleration limit different from the acceleration limit.
    #[must_use]
    pub fn with_max_deceleration(mut self, max_deceleration: F) -> Self {
        self.max_deceleration = Some(max_deceleration);
        self
    }

    /// Sets the jerk limit and asks for an S-curve.
    #[must_use]
    pub fn with_jerk(mut self, max_jerk: F) -> Self {
        self.max_jerk = Some(max_jerk);
        self.profile = MotionProfile::SCurve;
        self
    }

    /// Sets the kind of profile.
    #[must_use]
    pub fn with_profile(mut self, profile: MotionProfile) -> Self {
        self.profile = profile;
        self
    }

    /// Sets the overshoot policy.
    #[must_use]
    pub fn with_overshoot(mut self, overshoot: Overshoot) -> Self {
        self.overshoot = overshoot;
        self
    }

    /// Whether [`plan`](crate::plan) takes this request's fields, without
    /// planning it: every field finite, the limits above zero (`max_jerk`
    /// too where an S-curve is planned), the target velocity within the
    /// velocity limit. What a plan can still refuse after this depends on
    /// the move itself (an overshoot forbidden, a profile beyond the float).
    ///
    /// ```
    /// use motorwire_planner::{PlanError, Request};
    /// assert!(Request::new(0.0, 90.0, 60.0, 200.0).check().is_ok());
    /// assert!(matches!(
    ///     Request::new(0.0, 90.0, 0.0f32, 200.0).check(),
    ///     Err(PlanError::NotPositive { field: "max_velocity", .. })
    /// ));
    /// ```
    ///
    /// # Errors
    /// The [`PlanError`] [`plan`](crate::plan) would give for the field.
    pub fn check(&self) -> Result<(), PlanError> {
        self.limits()?;
        if self.wants_scurve() {
            self.jerk()?;
        }
        Ok(())
    }

    /// Checks every field, returning `(max_velocity, max_acceleration,
    /// max_deceleration)`.
    pub(crate) fn limits(&self) -> Result<(F, F, F), PlanError> {
        for (field, v) in [
            ("start", self.start),
            ("target", self.target),
            ("start_velocity", self.start_velocity),
            ("target_velocity", self.target_velocity),
            ("start_acceleration", self.start_acceleration),
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

    /// Whether every input is zero or within `[1/MODERATE, MODERATE]` in
    /// magnitude (see [`Float::MODERATE`]): then durations are at most
    /// `~MODERATE²`, positions `~MODERATE³` and jerk terms `~MODERATE⁵`,
    /// all far below the float's range.
    pub(crate) fn moderate(&self) -> bool {
        let hi = F::MODERATE;
        let lo = F::ONE / hi;
        let in_range = |v: F| {
            let m = v.abs();
            m == F::ZERO || (m >= lo && m <= hi)
        };
        let limit = |v: F| {
            let m = v.abs();
            m >= lo && m <= hi
        };
        in_range(self.start)
            && in_range(self.target)
            && in_range(self.start_velocity)
            && in_range(self.target_velocity)
            && in_range(self.start_acceleration)
            && limit(self.max_velocity)
            && limit(self.max_acceleration)
            && self.max_deceleration.is_none_or(limit)
            && self.max_jerk.is_none_or(limit)
    }

    /// Whether [`plan`](crate::plan) builds an S-curve: asked for, or
    /// `Adaptive` with a jerk limit that is positive (or not finite, so that
    /// the S-curve planner refuses it by name rather than it being ignored).
    pub(crate) fn wants_scurve(&self) -> bool {
        match self.profile {
            MotionProfile::Trapezoidal => false,
            MotionProfile::SCurve => true,
            MotionProfile::Adaptive => self.max_jerk.is_some_and(|j| j > F::ZERO || !j.is_finite()),
        }
    }

    /// The move in the frame where it goes forward: `(dir, distance,
    /// start_velocity, target_velocity)` with `dir = ±1` and `distance >= 0`
    /// (a zero-length move counts as forward).
    pub(crate) fn forward_frame(&self) -> (F, F, F, F) {
        let distance = self.target - self.start;
        let dir = if distance < F::ZERO { -F::ONE } else { F::ONE };
        (
            dir,
            distance * dir,
            self.start_velocity * dir,
            self.target_velocity * dir,
        )
    }

    /// The jerk limit, checked: present, finite and positive.
    pub(crate) fn jerk(&self) -> Result<F, PlanError> {
        let Some(j) = self.max_jerk else {
            return Err(PlanError::Missing { field: "max_jerk" });
        };
        if !j.is_finite() {
            return Err(PlanError::NonFinite { field: "max_jerk" });
        }
        if j.partial_cmp(&F::ZERO) != Some(core::cmp::Ordering::Greater) {
            return Err(PlanError::NotPositive {
                field: "max_jerk",
                value: j.to_f64(),
            });
        }
        Ok(j)
    }
}
