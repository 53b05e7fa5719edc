//! Time-optimal profiles with bounded acceleration (infinite jerk).
//!
//! With acceleration bounded by `A` while speeding up and `D` while slowing
//! down, the time-optimal motion is bang–coast–bang: change velocity to a
//! peak `vp` as hard as the limits allow, coast at `vp` only if it is
//! `max_velocity`, then change to the target velocity. In the frame where the
//! move goes forward, either `vp >= lo = max(v0, v1, 0)` (the usual case) or,
//! when that cannot cover the distance, `vp <= min(v0, v1, 0)` (the motion
//! passes the target, or first backs up for a run-up). Raising the peak from
//! `lo` to `lo + x` covers `c x (x + 2 lo)` more distance, `c = 1/2A + 1/2D`,
//! so `x` has a closed form, solved as `x = (R/c) / (lo + sqrt(lo² + R/c))`
//! to avoid the cancellation of the textbook quadratic formula: no iteration
//! at all.

use crate::profile::Builder;
use crate::{Float, Overshoot, PlanError, Profile, Request};

/// Up to two constant-acceleration pieces change the velocity (two when it
/// crosses zero, where the limit switches between A and D), plus a cruise.
const PIECES: usize = 5;

#[derive(Clone, Copy)]
struct Pieces<F> {
    accel: [F; PIECES],
    duration: [F; PIECES],
    /// The velocity each piece ends at, as planned (not as integrated).
    end_velocity: [F; PIECES],
    len: usize,
}

impl<F: Float> Pieces<F> {
    fn new() -> Self {
        Self {
            accel: [F::ZERO; PIECES],
            duration: [F::ZERO; PIECES],
            end_velocity: [F::ZERO; PIECES],
            len: 0,
        }
    }

    fn push(&mut self, accel: F, duration: F, end_velocity: F) {
        if let (Some(a), Some(d), Some(v)) = (
            self.accel.get_mut(self.len),
            self.duration.get_mut(self.len),
            self.end_velocity.get_mut(self.len),
        ) {
            *a = accel;
            *d = duration;
            *v = end_velocity;
            self.len += 1;
        }
    }

    /// Changes velocity from `va` to `vb` as fast as the limits allow;
    /// `delta` is `vb - va`, passed in so that a small change of a large
    /// velocity keeps its precision.
    fn ramp(&mut self, va: F, vb: F, delta: F, acc: F, dec: F) {
        if (va < F::ZERO && vb > F::ZERO) || (va > F::ZERO && vb < F::ZERO) {
            self.ramp(va, F::ZERO, -va, acc, dec);
            self.ramp(F::ZERO, vb, vb, acc, dec);
            return;
        }
        if delta == F::ZERO {
            return;
        }
        let magnitude = if vb.abs() > va.abs() { acc } else { dec };
        let accel = if delta > F::ZERO {
            magnitude
        } else {
            -magnitude
        };
        self.push(accel, delta.abs() / magnitude, vb);
    }
}

/// Distance covered while changing velocity from `va` to `vb`.
fn ramp_distance<F: Float>(va: F, vb: F, acc: F, dec: F) -> F {
    if (va < F::ZERO && vb > F::ZERO) || (va > F::ZERO && vb < F::ZERO) {
        return ramp_distance(va, F::ZERO, acc, dec) + ramp_distance(F::ZERO, vb, acc, dec);
    }
    let magnitude = if vb.abs() > va.abs() { acc } else { dec };
    let signed = if vb > va { magnitude } else { -magnitude };
    if va == vb {
        F::ZERO
    } else {
        // (vb² - va²) / 2a, factored so nearby velocities do not cancel.
        (vb - va) * (vb + va) / (F::TWO * signed)
    }
}

/// The forward family (`vp >= max(v0, v1, 0)`, or `vp = vmax` when
/// `v0 > vmax`): the pieces, or `None` when it cannot cover `dist`. With
/// `force`, the closest it gets (for a distance a rounding error away).
fn forward<F: Float>(
    dist: F,
    v0: F,
    v1: F,
    vmax: F,
    acc: F,
    dec: F,
    force: bool,
) -> Option<Pieces<F>> {
    let mut pieces = Pieces::new();
    let tol = F::from_f64(64.0) * F::EPSILON;
    if v0 > vmax {
        // Brake to max_velocity first; the distance to v1 does not depend
        // on the peak, so coast at max_velocity for what remains.
        let braking = ramp_distance(v0, vmax, acc, dec) + ramp_distance(vmax, v1, acc, dec);
        if dist < braking - tol * braking.abs().max(dist.abs()) && !force {
            return None;
        }
        pieces.ramp(v0, vmax, vmax - v0, acc, dec);
        pieces.push(F::ZERO, ((dist - braking) / vmax).max(F::ZERO), vmax);
        pieces.ramp(vmax, v1, v1 - vmax, acc, dec);
        return Some(pieces);
    }
    // The lowest peak of the family, and the distance its profile covers.
    let lo = v0.max(v1).max(F::ZERO);
    let g_lo = ramp_distance(v0, lo, acc, dec) + ramp_distance(lo, v1, acc, dec);
    let rest = dist - g_lo;
    if rest < -tol * g_lo.abs().max(dist.abs()) && !force {
        return None;
    }
    let rest = rest.max(F::ZERO);
    // Raising the peak from `lo` by `x` covers c x (x + 2 lo) more.
    let c = F::HALF / acc + F::HALF / dec;
    let room = vmax - lo;
    let at_vmax = c * room * (vmax + lo);
    let (x, cruise) = if rest >= at_vmax {
        (room, (rest - at_vmax) / vmax)
    } else {
        // x² + 2 lo x - rest/c = 0, in the form without cancellation.
        let q = rest / c;
        let den = lo + (lo * lo + q).sqrt();
        let x = if den > F::ZERO { q / den } else { F::ZERO };
        (x.min(room), F::ZERO)
    };
    let vp = lo + x;
    // Velocity differences from what is known exactly, not from `vp`.
    pieces.ramp(v0, vp, (lo - v0) + x, acc, dec);
    pieces.push(F::ZERO, cruise.max(F::ZERO), vp);
    pieces.ramp(vp, v1, (v1 - lo) - x, acc, dec);
    Some(pieces)
}

/// Plans the time-optimal trapezoidal profile (acceleration steps, jerk
/// unbounded) for `req`.
///
/// ```
/// use motorwire_planner::{Request, plan_trapezoidal};
///
/// // The iRPC document's Example 1: 0 -> 90 deg at 100 deg/s, 500 deg/s².
/// let p = plan_trapezoidal(&Request::new(0.0f64, 90.0, 100.0, 500.0))?;
/// assert!((p.duration() - 1.1).abs() < 1e-12);      // 0.2 s up, 0.7 s cruise, 0.2 s down
/// assert_eq!(p.sample(0.1).velocity, 50.0);
/// assert_eq!(p.sample(5.0).position, 90.0);
/// # Ok::<(), motorwire_planner::PlanError>(())
/// ```
///
/// # Errors
/// [`PlanError::NonFinite`], [`PlanError::NotPositive`] and
/// [`PlanError::TargetVelocityTooHigh`] for bad input;
/// [`PlanError::OvershootForbidden`] when the target cannot be reached
/// without passing it and the request forbids that;
/// [`PlanError::Unrepresentable`] when finite inputs give a non-finite profile.
pub fn plan_trapezoidal<F: Float>(req: &Request<F>) -> Result<Profile<F>, PlanError> {
    let (vmax, acc, dec) = req.limits()?;
    let (dir, dist, v0, v1) = req.forward_frame();
    let (pieces, sign) = match forward(dist, v0, v1, vmax, acc, dec, false) {
        Some(p) => (p, dir),
        None => match forward(-dist, -v0, -v1, vmax, acc, dec, false) {
            Some(p) => (p, -dir),
            // Both families missed by a rounding error: the forward one is
            // within it.
            None => match forward(dist, v0, v1, vmax, acc, dec, true) {
                Some(p) => (p, dir),
                None => return Err(PlanError::Unrepresentable),
            },
        },
    };
    let mut profile = Profile::at_rest(req.target);
    let mut b = Builder::new(&mut profile, req.start, req.start_velocity, F::ZERO);
    for i in 0..pieces.len.min(PIECES) {
        let (Some(a), Some(d), Some(v)) = (
            pieces.accel.get(i),
            pieces.duration.get(i),
            pieces.end_velocity.get(i),
        ) else {
            break;
        };
        if !d.is_finite() {
            return Err(PlanError::Unrepresentable);
        }
        b.constant_acceleration(*d, *a * sign, *v * sign);
    }
    b.finish(req.target, req.target_velocity);
    if !profile.representable() {
        return Err(PlanError::Unrepresentable);
    }
    if req.overshoot == Overshoot::Forbid
        && let Some(by) = profile.overshoot()
    {
        return Err(PlanError::OvershootForbidden {
            overshoot: by.to_f64(),
        });
    }
    Ok(profile)
}
