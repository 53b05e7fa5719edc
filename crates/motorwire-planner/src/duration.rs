//! Exact-duration planning and time synchronization of several axes.
//!
//! A move that must take exactly `T >= T_min` cruises at a lower velocity
//! `vc` with the same limits: ramp from `v0` to `vc`, cruise, ramp from `vc`
//! to `v1`. Its duration is `T(vc) = τ(vc) + (D - d(vc)) / vc`, where `τ`
//! and `d` are the two ramps' time and distance. As `vc` falls towards 0,
//! `T(vc)` grows without bound when stopping and starting again covers less
//! than `D`; then every `T >= T_min` is reachable. When stopping covers
//! more than `D` (a fast start close to the target), the forward family
//! ends where the cruise shrinks to nothing, and longer moves must pass the
//! target and come back, cruising backwards: the durations in between are
//! infeasible, and [`PlanError::DurationBlocked`] names that interval.
//!
//! `vc` is found by bisection on `T(vc) - T`, at most
//! [`MAX_DURATION_ITERATIONS`] steps, stopping when the bracket is a few
//! ulps wide.
//!
//! **Where the duration is monotone.** With `c` the cruise time and
//! `K = Σ (T(w) - w T'(w))/2 >= 0` over the two ramps (`T` is concave with
//! `T(0) = 0`), the S-curve module's identity `d' = vc τ' + K` gives
//! `T'(vc) = -(K + c)/vc`: the duration falls as `|vc|` grows, in each
//! family, wherever the cruise is feasible. So a cell whose ends are both
//! feasible and whose cruises are all feasible is monotone, and bisection
//! finds any duration between its ends. The cruise is infeasible where the
//! ramps cover more than the distance (forward) or less (backward), and by
//! the S-curve module's regions the infeasible cruises within one region
//! form a single interval: `d` increases above `max(v0, v1, 0)` and below
//! `min(v0, v1, 0)`; it has one maximum on `(0, min(v0, v1)]` and on the
//! positive part of `(min(v0, v1), max(v0, v1))`, and one minimum on the
//! negative part of that and on `[max(v0, v1), 0)`, where `d'` increases
//! (the two parts between `v0` and `v1` checked numerically on 20,000
//! random velocity pairs and limits, the others derived in the S-curve
//! module). The families never cross 0, so
//! an island of feasible cruises between two infeasible cell ends can
//! only lie in a cell that holds `v0` or `v1`: only those (at most two per
//! family) are rescanned for islands, in `SUB_CELLS` (32) parts, and so is a
//! cell whose bisection result fails its check (a gap of infeasible cruises
//! between two feasible ends).
//!
//! **Worst case.** Per family, 64 grid points; one bisection of at most
//! [`MAX_DURATION_ITERATIONS`] steps (about 55 in practice) in the cell
//! whose durations span the request, plus one for the feasibility boundary;
//! at most two island rescans of 32 points. On 100,000 seeded random
//! full-state requests (the planner benchmark's `plan_with_duration`
//! latency), the slowest took at most 6.6 times the median in three runs
//! (4.2 to 5.1 µs against 0.74 to 0.77 µs; before this bound, rescanning
//! every infeasible cell, 51 times: 38.8 µs).

use crate::scurve::{Model, Peak, build, solve};
use crate::{Float, PlanError, Profile, Request};

/// The most bisection steps exact-duration planning takes per search.
pub const MAX_DURATION_ITERATIONS: u32 = 200;

/// The limits model and time-optimal peak of a request in its forward
/// frame: jerk-limited for an S-curve, unbounded jerk (every ramp a single
/// constant-acceleration phase) otherwise.
fn model<F: Float>(
    req: &Request<F>,
    dist: F,
    v0: F,
    v1: F,
) -> Result<(Model<F>, Peak<F>), PlanError> {
    let (vmax, acc, dec) = req.limits()?;
    let jerk = if req.wants_scurve() {
        req.jerk()?
    } else {
        F::from_f64(f64::INFINITY)
    };
    Ok(solve(dist, v0, v1, vmax, acc, dec, jerk))
}

/// The shortest duration [`plan_with_duration`] can plan for `req` (the
/// S-curve planner's duration; for a trapezoidal request, the trapezoidal
/// planner's, except when part of the motion moves away from the target
/// with different acceleration and deceleration limits: then the smaller
/// limit bounds both ways, as in the S-curve planner).
///
/// # Errors
/// The request's own errors.
pub fn minimum_duration<F: Float>(req: &Request<F>) -> Result<F, PlanError> {
    let (_, dist, v0, v1) = req.forward_frame();
    let (m, peak) = model(req, dist, v0, v1)?;
    if req.start_acceleration != F::ZERO && req.wants_scurve() {
        return crate::plan_scurve(req).map(|p| p.duration());
    }
    if dist == F::ZERO && v0 == F::ZERO && v1 == F::ZERO {
        return Ok(F::ZERO);
    }
    Ok(m.ramps_duration(peak.x()) + peak.cruise)
}

/// `T(vc)`: the duration of the profile cruising at `vc`, or `None` when
/// the cruise would be negative.
fn duration_at<F: Float>(m: &Model<F>, dist: F, vc: F) -> Option<F> {
    let cruise = (dist - m.distance(vc)) / vc;
    (cruise >= F::ZERO && cruise.is_finite()).then(|| m.ramps_duration(vc) + cruise)
}

/// Bisection for the `x` in `[lo, hi]` where `g` crosses zero, `g`
/// increasing (`rising`) or decreasing over the bracket; `None` counts as
/// +infinity. The end points need not have opposite signs: when rounding
/// puts the crossing at an end, the bisection converges to that end.
fn bisect<F: Float>(mut lo: F, mut hi: F, rising: bool, g: impl Fn(F) -> Option<F>) -> F {
    for _ in 0..MAX_DURATION_ITERATIONS {
        let mid = lo + (hi - lo) * F::HALF;
        if mid <= lo || mid >= hi {
            break;
        }
        let above = g(mid).is_none_or(|v| v > F::ZERO);
        if above == rising {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    lo + (hi - lo) * F::HALF
}

/// How the cruise velocity search ended.
enum Search<F> {
    Found(F),
    Blocked { from: F, to: F },
    NotFound,
}

/// The number of cells the cruise-velocity range of each family is cut
/// into: a geometric grid towards zero velocity, where the duration grows
/// without bound.
const GRID: i32 = 64;

/// The number of equal sub-cells a cell is cut into when its durations
/// span the request but bisection across it misses (the duration is not
/// monotone there, or the cruise is infeasible inside it).
const SUB_CELLS: i32 = 32;

/// The relative tolerance a found duration must meet.
fn met<F: Float>(t: F, duration: F) -> bool {
    (t - duration).abs() <= F::from_f64(1e-9) * duration
}

/// The scan over one family of profiles (forward or backward cruises).
struct Scan<'a, F> {
    m: &'a Model<F>,
    dist: F,
    duration: F,
    forward: bool,
    /// The longest duration reached so far by the durations scanned, in
    /// order: a request above it and below the next feasible duration is
    /// blocked.
    reached: F,
}

impl<F: Float> Scan<'_, F> {
    fn duration_at(&self, vc: F) -> Option<F> {
        if vc == F::ZERO {
            None
        } else {
            duration_at(self.m, self.dist, vc)
        }
    }

    /// Whether cruising at `vc` takes the requested duration, as
    /// [`plan_with_duration`] builds it: a cruise negative by a rounding
    /// error (at the feasibility boundary) counts as none. The ramps'
    /// distance is a sum of terms up to the largest speed times their
    /// duration, which may cancel, so its rounding error scales with
    /// those, not with the distance.
    fn found(&self, vc: F) -> bool {
        if vc == F::ZERO {
            return false;
        }
        let ramps = self.m.ramps_duration(vc);
        let gap = self.dist - self.m.distance(vc);
        let speed = vc.abs() + self.m.v0.abs() + self.m.v1.abs();
        let rounding = F::from_f64(64.0) * F::EPSILON * (self.dist.abs() + speed * ramps);
        let cruise = gap / vc;
        (cruise >= F::ZERO || gap.abs() <= rounding)
            && met(ramps + cruise.max(F::ZERO), self.duration)
    }

    /// Whether the cell between `a` and `b` holds `v0` or `v1` strictly
    /// inside: where the regions of the module docs meet, the only places
    /// an island of feasible cruises can hide between two infeasible ends.
    fn holds_a_boundary_velocity(&self, a: F, b: F) -> bool {
        let (lo, hi) = (a.min(b), a.max(b));
        let inside = |v: F| v > lo && v < hi;
        inside(self.m.v0) || inside(self.m.v1)
    }

    /// A blocked interval, if `duration` lies between what was reached and
    /// `lo`, the shortest duration of the cell at hand.
    fn blocked(&self, lo: F) -> Option<Search<F>> {
        (lo > self.reached && self.duration > self.reached && self.duration < lo).then_some(
            Search::Blocked {
                from: self.reached,
                to: lo,
            },
        )
    }

    /// The cell between `prev` and `next` (`|next| < |prev|`), with the
    /// durations at both ends (`None`: the cruise is infeasible there).
    /// `refine` cuts a cell that spans the request but whose bisection
    /// misses into [`SUB_CELLS`] cells, once.
    fn cell(
        &mut self,
        (prev, t_prev): (F, Option<F>),
        (next, t_next): (F, Option<F>),
        refine: bool,
    ) -> Option<Search<F>> {
        let (m, dist, duration) = (self.m, self.dist, self.duration);
        let (lo, hi, vc) = match (t_prev, t_next) {
            (Some(a), Some(b)) => {
                let (lo, hi) = if a <= b { (a, b) } else { (b, a) };
                if let Some(b) = self.blocked(lo) {
                    return Some(b);
                }
                if duration < lo || duration > hi {
                    self.reached = self.reached.max(hi);
                    return None;
                }
                let g = |vc: F| self.duration_at(vc).map(|t| t - duration);
                let vc = if self.forward {
                    bisect(next, prev, a > b, g)
                } else {
                    bisect(prev, next, a < b, g)
                };
                (lo, hi, vc)
            }
            (Some(a), None) | (None, Some(a)) => {
                // The feasibility boundary, where the cruise vanishes.
                let (lo_v, hi_v) = if prev < next {
                    (prev, next)
                } else {
                    (next, prev)
                };
                let feasible_low = lo_v != F::ZERO && duration_at(m, dist, lo_v).is_some();
                // Forward, the cruise is feasible where d <= dist; backward,
                // where d >= dist.
                let c = bisect(lo_v, hi_v, feasible_low == self.forward, |vc| {
                    Some(m.distance(vc) - dist)
                });
                let tc = m.ramps_duration(c);
                let (lo, hi) = if a <= tc { (a, tc) } else { (tc, a) };
                if let Some(b) = self.blocked(lo) {
                    return Some(b);
                }
                if duration < lo || duration > hi {
                    self.reached = self.reached.max(hi);
                    return None;
                }
                let g = |vc: F| {
                    Some(
                        m.ramps_duration(vc) + ((dist - m.distance(vc)) / vc).max(F::ZERO)
                            - duration,
                    )
                };
                let feasible = if t_prev.is_some() { prev } else { next };
                let (x0, x1) = if feasible < c {
                    (feasible, c)
                } else {
                    (c, feasible)
                };
                let rising = g(x1).unwrap_or(F::ZERO) > g(x0).unwrap_or(F::ZERO);
                (lo, hi, bisect(x0, x1, rising, g))
            }
            (None, None) => {
                // An island of feasible cruises can lie inside only a cell
                // that holds v0 or v1 (module docs): elsewhere the
                // infeasible cruises of the cell's region form one
                // interval, which holds both ends and so the whole cell.
                if !refine || !self.holds_a_boundary_velocity(prev, next) {
                    return None;
                }
                (self.reached, self.reached, F::ZERO)
            }
        };
        if vc != F::ZERO && self.found(vc) {
            return Some(Search::Found(vc));
        }
        if refine {
            let mut p = (prev, t_prev);
            for i in 1..=SUB_CELLS {
                let n = if i == SUB_CELLS {
                    (next, t_next)
                } else {
                    #[allow(clippy::cast_precision_loss)]
                    let f = F::from_f64(f64::from(i) / f64::from(SUB_CELLS));
                    let v = prev + (next - prev) * f;
                    (v, self.duration_at(v))
                };
                if let Some(s) = self.cell(p, n, false) {
                    return Some(s);
                }
                p = n;
            }
            return None;
        }
        self.reached = self.reached.max(hi).max(lo);
        None
    }
}

/// Finds the cruise velocity for `duration`. The durations the profiles
/// take, in order of increasing duration, are: forward cruises from the
/// optimal peak `x_opt` down towards 0, then backward cruises from
/// `-max_velocity` up towards 0. Each family is scanned on a geometric grid
/// (the cruise is feasible where the ramps cover no more than the
/// distance); the first cell whose durations span `duration` is bisected,
/// and the result checked. Where the duration is not monotone in a cell,
/// or the cruise is infeasible inside it, the check fails and the cell is
/// scanned again in [`SUB_CELLS`] equal parts. A gap between the durations
/// reached so far and the next feasible ones that contains `duration` is a
/// blocked interval.
fn search<F: Float>(
    m_forward: &Model<F>,
    m_backward: &Model<F>,
    dist: F,
    duration: F,
    x_opt: F,
    minimum: F,
) -> Search<F> {
    let ratio = F::from_f64(0.75);
    let mut reached = minimum;
    // When the optimum itself cruises backwards (or has no cruise and a
    // negative peak), the backward family comes first, and forward cruises
    // (between 0 and the larger boundary velocity, where the ramps can
    // cover less than the distance) may still meet durations it blocks.
    let order = if x_opt > F::ZERO {
        [Some(true), Some(false)]
    } else {
        [Some(false), Some(true)]
    };
    let mut blocked = None;
    for forward in order.into_iter().flatten() {
        let m = if forward { m_forward } else { m_backward };
        let mut scan = Scan {
            m,
            dist,
            duration,
            forward,
            reached,
        };
        // Backwards from -max_velocity, or from the optimum when it
        // cruises backwards itself.
        let top = if forward == (x_opt > F::ZERO) {
            x_opt
        } else if forward {
            m.vmax
        } else {
            -m.vmax
        };
        if top == F::ZERO {
            continue;
        }
        // Walk cells [next, prev] with |next| < |prev|, towards 0.
        let mut prev = (
            top,
            duration_at(m, dist, top)
                .or_else(|| (m.distance(top) == dist).then(|| m.ramps_duration(top))),
        );
        for k in 1..=GRID {
            let next = if k == GRID {
                // Towards 0 the duration grows without bound if the cruise
                // stays feasible: stopping and starting again covers no
                // more than the distance (forward), or no less (backward).
                let stop_and_go = dist - m.distance(F::ZERO);
                let feasible = if forward {
                    stop_and_go >= F::ZERO
                } else {
                    stop_and_go <= F::ZERO
                };
                (F::ZERO, feasible.then(|| F::from_f64(f64::INFINITY)))
            } else {
                let v = prev.0 * ratio;
                (v, duration_at(m, dist, v))
            };
            match scan.cell(prev, next, true) {
                Some(Search::Found(vc)) => return Search::Found(vc),
                Some(b @ Search::Blocked { .. }) if x_opt > F::ZERO => return b,
                Some(b @ Search::Blocked { .. }) => {
                    // Forward cruises may still meet it.
                    blocked = blocked.or(Some(b));
                    break;
                }
                Some(Search::NotFound) | None => {}
            }
            prev = next;
        }
        reached = scan.reached;
    }
    blocked.unwrap_or(Search::NotFound)
}

/// Plans `req` to arrive exactly `duration` seconds after the start, with
/// the same limits, by cruising slower than the time-optimal profile. A
/// move of zero length with zero velocities stays at rest (duration 0).
/// As in the S-curve planner, when part of the motion moves away from the
/// target and the acceleration and deceleration limits differ, the smaller
/// bounds both ways.
///
/// ```
/// use motorwire_planner::{Request, plan_with_duration, PlanError};
///
/// // 0 -> 90 deg takes at least 1.1 s at 100 deg/s and 500 deg/s²; take 2 s.
/// let req = Request::new(0.0f64, 90.0, 100.0, 500.0);
/// let p = plan_with_duration(&req, 2.0)?;
/// assert!((p.duration() - 2.0).abs() < 1e-12);
/// assert!(p.peak_velocity().0 < 100.0);
/// assert_eq!(
///     plan_with_duration(&req, 1.0),
///     Err(PlanError::DurationTooShort { requested: 1.0, minimum: 1.1 })
/// );
/// # Ok::<(), PlanError>(())
/// ```
///
/// # Errors
/// The request's own errors; [`PlanError::NonFinite`] for a NaN or infinite
/// `duration`; [`PlanError::DurationTooShort`] below the minimum;
/// [`PlanError::DurationBlocked`] inside an infeasible interval;
/// [`PlanError::OvershootForbidden`] when the profile for that duration
/// passes the target and the request forbids it;
/// [`PlanError::StartAcceleration`] for a jerk-limited request with a
/// non-zero start acceleration.
pub fn plan_with_duration<F: Float>(
    req: &Request<F>,
    duration: F,
) -> Result<Profile<F>, PlanError> {
    if !duration.is_finite() {
        return Err(PlanError::NonFinite { field: "duration" });
    }
    let (dir, dist, v0, v1) = req.forward_frame();
    let (m, peak) = model(req, dist, v0, v1)?;
    if req.start_acceleration != F::ZERO && req.wants_scurve() {
        return Err(PlanError::StartAcceleration {
            value: req.start_acceleration.to_f64(),
        });
    }
    if dist == F::ZERO && v0 == F::ZERO && v1 == F::ZERO {
        // Nothing moves: at rest for as long as asked.
        return Ok(Profile::at_rest(req.target));
    }
    let x_opt = peak.x();
    let minimum = m.ramps_duration(x_opt) + peak.cruise;
    let tol = F::from_f64(1e-12) * minimum.max(F::EPSILON);
    if duration < minimum - tol {
        return Err(PlanError::DurationTooShort {
            requested: duration.to_f64(),
            minimum: minimum.to_f64(),
        });
    }
    if duration <= minimum + tol {
        let mut profile = Profile::at_rest(req.target);
        build(req, &m, peak, dir, &mut profile)?;
        return finish(req, profile);
    }
    // Cruising backwards moves away from the target: with different
    // acceleration and deceleration limits, the smaller bounds both ways.
    let m_backward = if m.acc == m.dec {
        m
    } else {
        let low = m.acc.min(m.dec);
        Model::new(m.vmax, low, low, m.jerk, v0, v1)
    };
    let vc = match search(&m, &m_backward, dist, duration, x_opt, minimum) {
        Search::Found(vc) => vc,
        Search::Blocked { from, to } => {
            return Err(PlanError::DurationBlocked {
                requested: duration.to_f64(),
                from: from.to_f64(),
                to: to.to_f64(),
            });
        }
        Search::NotFound => {
            return Err(PlanError::DurationNotFound {
                requested: duration.to_f64(),
            });
        }
    };
    let m = if vc < F::ZERO { m_backward } else { m };
    let cruise = ((dist - m.distance(vc)) / vc).max(F::ZERO);
    let mut profile = Profile::at_rest(req.target);
    build(req, &m, Peak::at(vc, cruise), dir, &mut profile)?;
    // The search assumes the duration is monotone in the cruise velocity
    // within each family; where it is not (some moves starting away from
    // the target), the result is checked rather than trusted.
    let error = (profile.duration() - duration).abs();
    if error > F::from_f64(1e-9) * duration {
        return Err(PlanError::DurationNotFound {
            requested: duration.to_f64(),
        });
    }
    finish(req, profile)
}

/// Applies the overshoot policy.
fn finish<F: Float>(req: &Request<F>, profile: Profile<F>) -> Result<Profile<F>, PlanError> {
    if req.overshoot == crate::Overshoot::Forbid
        && let Some(by) = profile.overshoot()
    {
        return Err(PlanError::OvershootForbidden {
            overshoot: by.to_f64(),
        });
    }
    Ok(profile)
}

/// Time synchronization: plans every axis to finish at the same instant,
/// the earliest at which all can (at least the slowest axis's minimum, and
/// outside every axis's blocked interval). Each axis keeps its own
/// boundary velocities; nothing is allocated: the caller passes `out`, one
/// profile per request. Returns the common duration.
///
/// ```
/// use motorwire_planner::{Profile, Request, synchronize_time};
///
/// let axes = [
///     Request::new(0.0f64, 45.0, 60.0, 120.0).with_jerk(600.0),
///     Request::new(0.0, -15.0, 60.0, 120.0).with_jerk(600.0).with_velocities(0.0, -5.0),
///     Request::new(0.0, 90.0, 90.0, 180.0).with_jerk(900.0),
/// ];
/// let mut out = [Profile::at_rest(0.0); 3];
/// let t = synchronize_time(&axes, &mut out)?;
/// for (p, r) in out.iter().zip(&axes) {
///     assert!((p.duration() - t).abs() < 1e-9);
///     assert_eq!(p.sample(t).position, r.target);
/// }
/// # Ok::<(), motorwire_planner::PlanError>(())
/// ```
///
/// # Errors
/// [`PlanError::AxisCountMismatch`] when `out` is not as long as
/// `requests`; any axis's own error.
pub fn synchronize_time<F: Float>(
    requests: &[Request<F>],
    out: &mut [Profile<F>],
) -> Result<F, PlanError> {
    if out.len() != requests.len() {
        return Err(PlanError::AxisCountMismatch {
            requests: requests.len(),
            profiles: out.len(),
        });
    }
    let mut t = F::ZERO;
    for req in requests {
        t = t.max(minimum_duration(req)?);
    }
    // Each blocked interval can push t at most once per axis.
    for _ in 0..=requests.len() {
        let mut moved = false;
        for (slot, req) in out.iter_mut().zip(requests) {
            match plan_with_duration(req, t) {
                Ok(p) => *slot = p,
                Err(PlanError::DurationBlocked { to, .. }) => {
                    // Just past the interval's end, whatever the rounding to F.
                    t = F::from_f64(to) * (F::ONE + F::from_f64(4.0) * F::EPSILON);
                    moved = true;
                    break;
                }
                Err(e) => return Err(e),
            }
        }
        if !moved {
            return Ok(t);
        }
    }
    Err(PlanError::Unrepresentable)
}
