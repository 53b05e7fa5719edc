//! `SetTargetV2` as the motion planner's request (feature `planner`).

use motorwire_planner::{Float, MotionProfile as Shape, Overshoot, Request};

use crate::{MotionProfile, SetTargetPayloadV2};

#[cfg_attr(docsrs, doc(cfg(feature = "planner")))]
impl SetTargetPayloadV2 {
    /// The planner's request for the move a joint makes on this command
    /// from `start` (degrees) at `start_velocity` (deg/s): the one reading
    /// of a `SetTargetV2` that the simulated joint, the bridge and the
    /// synchronization check all use, so they cannot drift apart.
    ///
    /// - A `max_deceleration` of zero or less means "as fast as it
    ///   accelerates" (`max_acceleration`).
    /// - The move is jerk-limited only when `max_jerk > 0` and the profile
    ///   is not `Trapezoidal` (iRPC: `max_jerk <= 0` is no jerk limit);
    ///   otherwise it is trapezoidal.
    /// - `target_velocity` is the velocity to arrive with; the joint may
    ///   overshoot the target when it must ([`Overshoot::Allow`]).
    ///
    /// Works in `f32` (as a joint's firmware plans) and `f64`.
    ///
    /// ```
    /// use motorwire_irpc::SetTargetPayloadV2;
    /// use motorwire_planner::{MotionProfile, plan};
    ///
    /// // The iRPC document's example, from rest at 0°.
    /// let req = SetTargetPayloadV2::scurve(90.0, 100.0, 500.0, 2000.0).planner_request(0.0f64, 0.0);
    /// assert_eq!((req.target, req.max_jerk, req.profile), (90.0, Some(2000.0), MotionProfile::SCurve));
    /// // 100 deg/s is reached before 500 deg/s² is: 2·2√(v/j) of jerk, the rest cruising.
    /// let profile = plan(&req)?;
    /// assert!((profile.duration() - (0.9 + 2.0 * 0.05f64.sqrt())).abs() < 1e-9);
    ///
    /// // No jerk limit: trapezoidal, decelerating as it accelerates.
    /// let req = SetTargetPayloadV2::scurve(90.0, 100.0, 500.0, 0.0).with_deceleration(0.0).planner_request(0.0f32, 0.0);
    /// assert_eq!((req.profile, req.max_deceleration, req.max_jerk), (MotionProfile::Trapezoidal, Some(500.0), None));
    /// # Ok::<(), motorwire_planner::PlanError>(())
    /// ```
    pub fn planner_request<F: Float>(&self, start: F, start_velocity: F) -> Request<F> {
        let f = |x: f32| F::from_f64(f64::from(x));
        let decel = if self.max_deceleration > 0.0 {
            self.max_deceleration
        } else {
            self.max_acceleration
        };
        let jerk_limited =
            self.max_jerk > 0.0 && !matches!(self.profile, MotionProfile::Trapezoidal);
        let shape = match self.profile {
            MotionProfile::Trapezoidal => Shape::Trapezoidal,
            MotionProfile::SCurve => Shape::SCurve,
            MotionProfile::Adaptive => Shape::Adaptive,
        };
        let req = Request::new(
            start,
            f(self.target_angle),
            f(self.max_velocity),
            f(self.max_acceleration),
        )
        .with_velocities(start_velocity, f(self.target_velocity))
        .with_max_deceleration(f(decel))
        .with_overshoot(Overshoot::Allow);
        if jerk_limited {
            req.with_jerk(f(self.max_jerk)).with_profile(shape)
        } else {
            req.with_profile(Shape::Trapezoidal)
        }
    }
}
