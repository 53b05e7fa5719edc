//! One entry point for every kind of profile.

use crate::{Float, PlanError, Profile, Request, plan_scurve, plan_trapezoidal};

/// Plans `req` with the profile it asks for: [`plan_trapezoidal`] or
/// [`plan_scurve`]; [`MotionProfile::Adaptive`](crate::MotionProfile::Adaptive) is an S-curve when
/// `max_jerk` is given and positive, trapezoidal otherwise.
///
/// ```
/// use motorwire_planner::{MotionProfile, Request, plan};
///
/// let trapezoidal = plan(&Request::new(0.0f64, 90.0, 100.0, 500.0))?;
/// let s_curve = plan(&Request::new(0.0f64, 90.0, 100.0, 500.0).with_jerk(2000.0))?;
/// assert!(s_curve.duration() > trapezoidal.duration()); // the price of bounded jerk
/// # Ok::<(), motorwire_planner::PlanError>(())
/// ```
///
/// # Errors
/// Those of [`plan_trapezoidal`] or [`plan_scurve`].
pub fn plan<F: Float>(req: &Request<F>) -> Result<Profile<F>, PlanError> {
    if req.wants_scurve() {
        plan_scurve(req)
    } else {
        plan_trapezoidal(req)
    }
}
