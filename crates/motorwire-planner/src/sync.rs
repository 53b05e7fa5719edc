//! Multi-axis synchronization.

use crate::profile::Builder;
use crate::{Float, PlanError, Profile, Request, plan_trapezoidal};

/// Plans rest-to-rest moves of several axes as one straight line in joint
/// space (phase synchronization): every axis starts, accelerates, cruises,
/// decelerates and stops at the same instants, so the joint vector moves
/// along the segment from the starts to the targets.
///
/// All axes share one normalized profile `s(t)` from 0 to 1; axis `i` is at
/// `start_i + (target_i - start_i) s(t)`. `s` is planned time-optimally
/// with the tightest of the axes' limits scaled by their distances, so
/// every axis stays within its own limits and the slowest axis moves as fast
/// as it can. Axes that do not move stay at rest. Nothing is allocated: the
/// caller passes `out`, one profile per request.
///
/// ```
/// use motorwire_planner::{Profile, Request, plan_trapezoidal, synchronize_phases};
///
/// // The WIA document's 3-joint move: shoulder_pitch 0 -> 45, shoulder_roll 0 -> 15, elbow 0 -> 90.
/// let axes = [
///     Request::new(0.0f64, 45.0, 60.0, 120.0),
///     Request::new(0.0, 15.0, 60.0, 120.0),
///     Request::new(0.0, 90.0, 90.0, 180.0),
/// ];
/// let mut out = [Profile::at_rest(0.0); 3];
/// let duration = synchronize_phases(&axes, &mut out)?;
/// // All three arrive together, no sooner than the slowest alone could.
/// let slowest = axes.iter().map(|r| plan_trapezoidal(r).unwrap().duration()).fold(0.0, f64::max);
/// assert!((duration - slowest).abs() < 1e-12);
/// for p in &out {
///     assert!((p.duration() - duration).abs() < 1e-12);
/// }
/// // Halfway in time, every joint is at the same fraction of its move.
/// let f = out[0].sample(duration / 2.0).position / 45.0;
/// assert!((out[2].sample(duration / 2.0).position / 90.0 - f).abs() < 1e-12);
/// # Ok::<(), motorwire_planner::PlanError>(())
/// ```
///
/// # Errors
/// [`PlanError::AxisCountMismatch`] when `out` is not as long as
/// `requests`; [`PlanError::NotAtRest`] for a request with a non-zero start
/// or target velocity or start acceleration (phase synchronization is defined for rest-to-rest
/// moves); and any error of the request itself, from the first axis that has one.
pub fn synchronize_phases<F: Float>(
    requests: &[Request<F>],
    out: &mut [Profile<F>],
) -> Result<F, PlanError> {
    if out.len() != requests.len() {
        return Err(PlanError::AxisCountMismatch {
            requests: requests.len(),
            profiles: out.len(),
        });
    }
    // The normalized limits: s' <= vmax_i / |D_i| for every moving axis.
    let mut limits: Option<(F, F, F)> = None;
    for (axis, req) in requests.iter().enumerate() {
        let (vmax, acc, dec) = req.limits()?;
        if req.start_velocity != F::ZERO
            || req.target_velocity != F::ZERO
            || req.start_acceleration != F::ZERO
        {
            return Err(PlanError::NotAtRest { axis });
        }
        let d = (req.target - req.start).abs();
        if d == F::ZERO {
            continue;
        }
        let scaled = (vmax / d, acc / d, dec / d);
        if !(scaled.0.is_finite() && scaled.1.is_finite() && scaled.2.is_finite()) {
            return Err(PlanError::Unrepresentable);
        }
        limits = Some(match limits {
            None => scaled,
            Some((v, a, b)) => (v.min(scaled.0), a.min(scaled.1), b.min(scaled.2)),
        });
    }
    let Some((v, a, b)) = limits else {
        // Nothing moves.
        for (slot, req) in out.iter_mut().zip(requests) {
            *slot = Profile::at_rest(req.start);
        }
        return Ok(F::ZERO);
    };
    let unit = plan_trapezoidal(&Request::new(F::ZERO, F::ONE, v, a).with_max_deceleration(b))?;
    for (slot, req) in out.iter_mut().zip(requests) {
        let d = req.target - req.start;
        if d == F::ZERO {
            *slot = Profile::at_rest(req.start);
            continue;
        }
        let mut builder = Builder::new(slot, req.start, F::ZERO, F::ZERO);
        let phases = unit.phases();
        let mut previous: Option<crate::Phase<F>> = None;
        for ph in phases {
            if let Some(prev) = previous {
                let end_v = prev.start.velocity + prev.start.acceleration * prev.duration;
                builder.constant_acceleration(
                    prev.duration,
                    prev.start.acceleration * d,
                    end_v * d,
                );
            }
            previous = Some(ph);
        }
        if let Some(last) = previous {
            // The last phase ends at rest, exactly.
            builder.constant_acceleration(last.duration, last.start.acceleration * d, F::ZERO);
        }
        builder.finish(req.target, F::ZERO);
        if !slot.representable() {
            return Err(PlanError::Unrepresentable);
        }
    }
    Ok(unit.duration())
}
