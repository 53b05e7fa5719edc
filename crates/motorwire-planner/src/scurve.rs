//! Time-optimal jerk-limited (S-curve) profiles.
//!
//! Both boundary accelerations are zero (iRPC's `SetTargetV2` has none), so
//! a time-optimal profile is: change velocity from `v0` to a peak `x` (an
//! *S-ramp*: jerk `±J`, then constant acceleration if the change is large
//! enough to reach the limit, then jerk back to zero acceleration), cruise
//! at `x` if `x` is `±max_velocity`, and change velocity from `x` to `v1`.
//! That is at most 3 + 1 + 3 = 7 constant-jerk phases.
//!
//! An S-ramp of a velocity change `Δ` with acceleration limit `L` lasts
//! `T(Δ) = Δ/L + L/J` when `Δ >= L²/J` (it reaches the limit) and
//! `T(Δ) = 2 sqrt(Δ/J)` otherwise; its velocity is point-symmetric about
//! its midpoint, so it covers `(va + vb)/2 · T(Δ)`. The distance `d(x)` the
//! two ramps through a peak `x` cover, and their duration `τ(x)`, are
//! therefore explicit, and the time-optimal profile is the candidate of
//! least duration among the peaks with `d(x) = D` and the cruises at
//! `±max_velocity`. Which candidate that is follows from the shape of `d`
//! and `τ` in three regions (`lo = min(v0, v1)`, `hi = max(v0, v1)`):
//!
//! - **above** (`x >= hi`): `τ` increases with `x`. With `w` a ramp's
//!   change, `d'(x) = Σ x g(w) + h(w)`, where `g(w) = 1/sqrt(J w)` (or
//!   `1/L` saturated) and `h(w) = sqrt(w/J)/2` (or `L/2J`) are positive:
//!   `d` increases for `x >= 0`, and below 0 every velocity is negative
//!   and `d < 0 <= D`. So there is at most one peak, the smallest one.
//! - **below** (`x <= lo`): `τ` decreases with `x`, and
//!   `d'(x) = Σ -x g(w) + h(w)`: `d` increases up to 0 and is concave
//!   on `(0, lo]` with slope `-∞` at `lo` (when `lo > 0`), so it rises
//!   and then falls: the best peak is the largest root, and when
//!   `D < d(lo)` it is the only one on the rising side.
//! - **between** (`lo < x < hi`): the velocity passes monotonically from
//!   `v0` to `v1` with a pause in acceleration at `x`. Unsaturated, its jerk
//!   switches three times with no acceleration limit in between, which
//!   Pontryagin's principle excludes (the jerk's switching function is a
//!   quadratic on such an arc); no such peak was the fastest on 300,000
//!   random requests compared with Ruckig 0.19.4 either.
//!
//! Hence, with `|v0| <= max_velocity` (`d(lo) = d(hi)` is the distance of
//! the direct change from `v0` to `v1`):
//!
//! 1. `d(max_velocity) <= D`: peak at `max_velocity`, cruise for the rest
//!    (closed form).
//! 2. Otherwise, if `d(b) <= D` with `b = max(v0, v1, 0)`: the peak above,
//!    where `d` increases from `b` up. Rest-to-rest, the root is closed
//!    form in each saturation regime: both ramps short
//!    (`x = cbrt(D² J / 4)`), both reaching the limits (a quadratic), one
//!    reaching its limit `L` and the other not (`d` is then a perfect
//!    square in `u = sqrt(x)`, which leaves the quadratic
//!    `u² + u L/sqrt(J) = sqrt(2 L D)`); quadratics are solved without
//!    cancellation. Non-zero velocities use the bounded root search below,
//!    bracketed by the saturated closed form.
//! 3. Otherwise `D < d(lo)` (the target is too close for the boundary
//!    velocities: brake to a lower velocity, or back up, or pass the
//!    target): the largest peak below `lo`, if `d(-max_velocity) <= D`;
//!    the ramps change velocity past `lo` and come back to it. Near `lo`
//!    the returning ramp of depth `w` lasts `2 sqrt(w/J)` and `d` has an
//!    infinite slope, so a root may lie within 1e-10 of `lo` (a return
//!    ramp of microseconds): the search runs in `s = sqrt(w/J)`,
//!    `x = lo - J s²`, where `d` is smooth, bracketed by `[0,
//!    sqrt((lo + max_velocity)/J)]`, which holds exactly one root.
//! 4. Otherwise even `-max_velocity` covers too much: the profile cruises
//!    backwards at it.
//!
//! Why the first applicable case is the fastest: a peak below, of depth
//! `w = lo - x`, has the duration of the peak `hi + w` above (the same two
//! changes, `W + w` and `w` with `W = hi - lo`, in the other order), which
//! covers `(W + w) T(w) + w T(W + w)` more distance; so when case 2 has
//! a root, it lies below `hi + w` and is no slower. When case 1 applies,
//! `hi + w > max_velocity`, and comparing the distance lost to each
//! profile's ramps shows the cruise covers `D` no later either.
//!
//! A start velocity above the limit (`|v0| > max_velocity`, braked first)
//! leaves the peaks between `v1` and `max_velocity` as the only ones, and
//! the largest root below `b` is found by scanning at most
//! [`SCAN_POINTS`] points downwards, then the root search in the first
//! bracket. If even `-max_velocity` covers too much distance, the profile
//! cruises backwards at it.
//!
//! The root search is Newton's method safeguarded by bisection: each step
//! keeps a bracket `[lo, hi]` with `d(lo) <= D < d(hi)`, takes the Newton
//! step when it lands inside the bracket, and bisects otherwise and on
//! every fourth step. It stops when the bracket or the step is within a
//! few ulps, and after at most [`MAX_ROOT_ITERATIONS`] steps whatever
//! happens (typically it takes 3 to 8).
//!
//! **Acceleration limits.** Acceleration towards the target is bounded by
//! `max_acceleration` and away from it by `max_deceleration`. While the
//! velocity points at the target (or is zero) these are exactly "speeding
//! up" and "slowing down". When some part of the motion moves away from the
//! target (a start or target velocity pointing away, or the way back after
//! an overshoot) and the two limits differ, the profile uses the smaller
//! of the two for both: it is then within both limits whichever way one
//! reads them, at some cost in time.

use crate::profile::{Builder, RampShape};
use crate::{Float, Overshoot, PlanError, Profile, Request};

/// The most steps the S-curve root search takes (it stops as soon as the
/// root is known to a few ulps; usually after 3 to 8 steps).
pub const MAX_ROOT_ITERATIONS: u32 = 128;

/// The most points the S-curve planner evaluates when it scans for the
/// peak velocity below `max(v0, v1, 0)`.
pub const SCAN_POINTS: usize = 12;

/// The move, in the frame where it goes forward, and its limits.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Model<F> {
    pub(crate) vmax: F,
    pub(crate) acc: F,
    pub(crate) dec: F,
    pub(crate) jerk: F,
    pub(crate) v0: F,
    pub(crate) v1: F,
    inv_acc: F,
    inv_dec: F,
    inv_jerk: F,
}

/// A planned peak velocity `base + offset` and how long to cruise at it.
/// The peak is kept as an offset from a velocity the ramps' changes are
/// known exactly from, so a small change of a large velocity keeps its
/// precision (in f32 especially).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Peak<F> {
    pub(crate) base: F,
    pub(crate) offset: F,
    pub(crate) cruise: F,
}

impl<F: Float> Peak<F> {
    pub(crate) fn at(x: F, cruise: F) -> Self {
        Self {
            base: x,
            offset: F::ZERO,
            cruise,
        }
    }

    pub(crate) fn x(&self) -> F {
        self.base + self.offset
    }
}

fn infinity<F: Float>() -> F {
    F::from_f64(f64::INFINITY)
}

impl<F: Float> Model<F> {
    /// The model of a move; divisions by the limits become multiplications
    /// by reciprocals computed once here.
    pub(crate) fn new(vmax: F, acc: F, dec: F, jerk: F, v0: F, v1: F) -> Self {
        Self {
            vmax,
            acc,
            dec,
            jerk,
            v0,
            v1,
            inv_acc: F::ONE / acc,
            inv_dec: F::ONE / dec,
            inv_jerk: F::ONE / jerk,
        }
    }

    /// The acceleration limit of a velocity change of sign `delta`, and its
    /// reciprocal.
    #[inline]
    fn limit(&self, delta: F) -> (F, F) {
        if delta >= F::ZERO {
            (self.acc, self.inv_acc)
        } else {
            (self.dec, self.inv_dec)
        }
    }

    /// The duration of an S-ramp changing velocity by `delta`, and its
    /// derivative with respect to `|delta|`.
    fn ramp_time(&self, delta: F) -> (F, F) {
        let (lim, inv) = self.limit(delta);
        let d = delta.abs();
        if d * self.jerk >= lim * lim {
            (d * inv + lim * self.inv_jerk, inv)
        } else {
            let r = (d * self.inv_jerk).sqrt();
            let slope = if r > F::ZERO {
                F::ONE / (r * self.jerk)
            } else {
                infinity()
            };
            (r + r, slope)
        }
    }

    pub(crate) fn shape(&self, delta: F, dir: F) -> RampShape<F> {
        let (lim, inv) = self.limit(delta);
        let d = delta.abs();
        let sign = if delta * dir > F::ZERO {
            1
        } else if delta * dir < F::ZERO {
            -1
        } else {
            0
        };
        if d * self.jerk >= lim * lim {
            let t_jerk = lim * self.inv_jerk;
            let t_flat = d * inv - t_jerk;
            // At the boundary between the two shapes, a flat phase of a
            // rounding error's length is no phase at all.
            let t_flat = if t_flat <= F::from_f64(4.0) * F::EPSILON * t_jerk {
                F::ZERO
            } else {
                t_flat
            };
            RampShape {
                t_jerk,
                t_flat,
                peak: lim,
                sign,
            }
        } else {
            let t = (d * self.inv_jerk).sqrt();
            RampShape {
                t_jerk: t,
                t_flat: F::ZERO,
                peak: self.jerk * t,
                sign,
            }
        }
    }

    /// The duration of an S-ramp changing velocity by `delta`.
    #[inline]
    fn ramp_duration(&self, delta: F) -> F {
        let (lim, inv) = self.limit(delta);
        let d = delta.abs();
        if d * self.jerk >= lim * lim {
            d * inv + lim * self.inv_jerk
        } else {
            F::TWO * (d * self.inv_jerk).sqrt()
        }
    }

    /// The time of the two ramps through peak `x`, without cruise.
    pub(crate) fn ramps_duration(&self, x: F) -> F {
        self.ramp_duration(x - self.v0) + self.ramp_duration(self.v1 - x)
    }

    /// The distance the two ramps through peak `x` cover (without the
    /// derivative [`Self::distance_from`] also gives).
    #[inline]
    pub(crate) fn distance(&self, x: F) -> F {
        let t1 = self.ramp_duration(x - self.v0);
        let t2 = self.ramp_duration(self.v1 - x);
        ((self.v0 + x) * t1 + (x + self.v1) * t2) * F::HALF
    }

    /// [`Self::distance`] at the peak `base + y`, with the ramps' velocity
    /// changes computed from `base` and `y` separately.
    #[inline(always)]
    pub(crate) fn distance_from(&self, base: F, y: F) -> (F, F) {
        let x = base + y;
        let (d1, d2) = ((base - self.v0) + y, (self.v1 - base) - y);
        let (t1, s1) = self.ramp_time(d1);
        let (t2, s2) = self.ramp_time(d2);
        let (m1, m2) = ((self.v0 + x) * F::HALF, (x + self.v1) * F::HALF);
        let term = |m: F, s: F, sign: F| {
            if m == F::ZERO { F::ZERO } else { m * s * sign }
        };
        let sgn = |d: F| {
            if d > F::ZERO {
                F::ONE
            } else if d < F::ZERO {
                -F::ONE
            } else {
                F::ONE
            }
        };
        let slope = (t1 + t2) * F::HALF + term(m1, s1, sgn(d1)) - term(m2, s2, sgn(d2));
        (m1 * t1 + m2 * t2, slope)
    }

    /// The offset `x` in `[lo, hi]` with `d(base + x) = target`, given
    /// `d(base + lo) <= target < d(base + hi)` (or within rounding of it).
    #[inline(always)]
    fn root(&self, base: F, mut lo: F, mut hi: F, start: F, target: F) -> F {
        let eps = F::EPSILON * F::TWO;
        let mut x = start;
        for i in 0..MAX_ROOT_ITERATIONS {
            let (y, slope) = self.distance_from(base, x);
            let g = y - target;
            if g == F::ZERO {
                return x;
            }
            if g > F::ZERO {
                hi = x;
            } else {
                lo = x;
            }
            let scale = lo.abs().max(hi.abs());
            if hi - lo <= eps * scale {
                return x;
            }
            let newton = x - g / slope;
            let next = if i % 4 != 3 && newton.is_finite() && newton > lo && newton < hi {
                if (newton - x).abs() <= eps * scale {
                    return newton;
                }
                newton
            } else {
                lo + (hi - lo) * F::HALF
            };
            x = next;
        }
        x
    }

    /// The rest-to-rest peak below `max_velocity`, in closed form.
    fn rest_to_rest_peak(&self, dist: F) -> F {
        let (s_acc, s_dec) = (
            self.acc * self.acc * self.inv_jerk,
            self.dec * self.dec * self.inv_jerk,
        );
        let (s_lo, s_hi) = (s_acc.min(s_dec), s_acc.max(s_dec));
        // Both ramps short: d = 2 x sqrt(x / J).
        let short = (dist * dist * self.jerk * F::from_f64(0.25)).cbrt();
        if short <= s_lo {
            return short;
        }
        let long = self.saturated_peak(dist);
        if long >= s_hi {
            return long;
        }
        // Mixed: the ramp with the smaller limit L reaches it, the other
        // does not. With u = sqrt(x), d = u⁴/2L + u³/sqrt(J) + u² L/2J =
        // (u²/sqrt(2L) + u sqrt(L/2J))², so u² + u L/sqrt(J) = sqrt(2 L d):
        // a quadratic, solved without cancellation.
        let lim = self.acc.min(self.dec);
        let p = lim * self.inv_jerk.sqrt();
        let q = (F::TWO * lim * dist).sqrt();
        let u = F::TWO * q / (p + (p * p + F::from_f64(4.0) * q).sqrt());
        (u * u).max(s_lo).min(s_hi).min(self.vmax)
    }

    /// The peak if both ramps reached their acceleration limits:
    /// `(x² - v0²)/2A + (x + v0) A/2J + (x² - v1²)/2D + (x + v1) D/2J = dist`.
    /// It is a lower bound of the true peak when `v0, v1 >= 0` (a ramp
    /// that does not reach its limit is shorter).
    fn saturated_peak(&self, dist: F) -> F {
        let (a, d) = (self.acc, self.dec);
        let (ia, id, ij) = (self.inv_acc, self.inv_dec, self.inv_jerk);
        let qa = (ia + id) * F::HALF;
        let qb = (a + d) * F::HALF * ij;
        let qc = -(dist + (self.v0 * self.v0 * ia + self.v1 * self.v1 * id) * F::HALF
            - (self.v0 * a + self.v1 * d) * F::HALF * ij);
        // qa x² + qb x + qc = 0, qa > 0, qb > 0: the positive root without
        // cancellation.
        let disc = (qb * qb - F::from_f64(4.0) * qa * qc).max(F::ZERO);
        if qc <= F::ZERO {
            -F::TWO * qc / (qb + disc.sqrt())
        } else {
            (-qb + disc.sqrt()) / (F::TWO * qa)
        }
    }

    /// The largest peak `x <= lo = min(v0, v1)` with `d(x) = dist`, given
    /// `d(-max_velocity) <= dist < d(lo)` (module docs, case 3): the ramps
    /// first change velocity past `lo`, then come back to it. `d` has an
    /// infinite slope at `lo` (the ramp that returns to `lo` lasts
    /// `2 sqrt(w/J)` for a depth `w`), so the root is searched in
    /// `s = sqrt(w/J)`, half that ramp's duration, where `d` is smooth:
    /// `x = lo - J s²`. Its bracket `[0, sqrt((lo + max_velocity)/J)]`
    /// holds exactly one root (`d` rises then falls along it, and
    /// `d(lo) > dist`). With unbounded jerk (trapezoidal ramps) `d` is
    /// smooth in `x` and the search runs there.
    #[inline(never)]
    fn peak_below(&self, dist: F) -> Peak<F> {
        let lo = self.v0.min(self.v1);
        let span = (lo + self.vmax).max(F::ZERO);
        if !self.jerk.is_finite() {
            let offset = self.root(lo, -span, F::ZERO, -span * F::HALF, dist);
            return Peak {
                base: lo,
                offset,
                cruise: F::ZERO,
            };
        }
        let eps = F::EPSILON * F::TWO;
        let (mut s_lo, mut s_hi) = (F::ZERO, (span * self.inv_jerk).sqrt());
        let depth = |s: F| (self.jerk * s * s).min(span);
        // Near s = 0, d(lo - J s²) = d(lo) + 2 lo s + O(s²): from below
        // zero it falls at once, the first Newton step from 0.
        let mut s = if lo < F::ZERO {
            let g0 = self.distance_from(lo, F::ZERO).0 - dist;
            (g0 / (-F::TWO * lo)).min(s_hi)
        } else {
            s_hi
        };
        // Newton while it stays inside the bracket and at least halves
        // the residual each step (it converges from one side, so the
        // bracket need not shrink), bisection otherwise.
        let mut last = infinity::<F>();
        for _ in 0..MAX_ROOT_ITERATIONS {
            let (y, slope_x) = self.distance_from(lo, -depth(s));
            let g = y - dist;
            if g == F::ZERO {
                break;
            }
            if g > F::ZERO {
                s_lo = s;
            } else {
                s_hi = s;
            }
            if s_hi - s_lo <= eps * s_hi {
                break;
            }
            // dd/ds = d'(x) dx/ds = -2 J s d'(x).
            let slope = -F::TWO * self.jerk * s * slope_x;
            let newton = s - g / slope;
            let stalled = g.abs() > last * F::HALF;
            last = g.abs();
            if (newton - s).abs() <= eps * s {
                // Converged (the step may not even leave `s`, the end of
                // the bracket it just set).
                break;
            }
            s = if !stalled && newton > s_lo && newton < s_hi {
                newton
            } else {
                s_lo + (s_hi - s_lo) * F::HALF
            };
        }
        Peak {
            base: lo,
            offset: -depth(s),
            cruise: F::ZERO,
        }
    }

    /// The time-optimal peak velocity and cruise for a forward distance
    /// `dist >= 0`.
    pub(crate) fn peak(&self, dist: F) -> Peak<F> {
        let vmax = self.vmax;
        // `d(x)` covers no more than `dist`, up to its rounding error.
        let covers = |d: F| d <= dist + F::from_f64(64.0) * F::EPSILON * (dist.abs() + d.abs());
        let d_top = self.distance(vmax);
        if covers(d_top) {
            return Peak::at(vmax, ((dist - d_top) / vmax).max(F::ZERO));
        }
        let (v0, v1) = (self.v0, self.v1);
        let b = if v0 > vmax {
            vmax
        } else {
            v0.max(v1).max(F::ZERO)
        };
        // Rest-to-rest, b = 0 and d(0) = 0.
        let at_rest = v0 == F::ZERO && v1 == F::ZERO;
        if b < vmax && (at_rest || covers(self.distance(b))) {
            if at_rest {
                return Peak::at(self.rest_to_rest_peak(dist), F::ZERO);
            }
            let room = vmax - b;
            // The saturated peak bounds the root from below; rounding
            // (cancellation in its quadratic) could put it above, so it
            // is checked before it narrows the bracket.
            let mut lo = F::ZERO;
            if v0 >= F::ZERO && v1 >= F::ZERO {
                let guess = (self.saturated_peak(dist) - b).max(F::ZERO).min(room);
                if self.distance_from(b, guess).0 <= dist {
                    lo = guess;
                }
            }
            return Peak {
                base: b,
                offset: self.root(b, lo, room, room, dist),
                cruise: F::ZERO,
            };
        }
        if v0.abs() <= vmax {
            // Here D < d(b) = d(min(v0, v1)) (module docs, case 3): the
            // largest root below min(v0, v1), or a backward cruise.
            let d_bottom = self.distance(-vmax);
            if covers(d_bottom) {
                return self.peak_below(dist);
            }
            return Peak::at(-vmax, ((d_bottom - dist) / vmax).max(F::ZERO));
        }
        self.peak_scan(dist, b)
    }

    /// A start above the limit: scans down from `b` for the first point
    /// that covers no more than `dist`, through the places where d changes
    /// shape, then searches the root in that bracket. Kept out of line, as
    /// [`Self::peak_below`] is, so the common cases stay small.
    #[inline(never)]
    fn peak_scan(&self, dist: F, b: F) -> Peak<F> {
        let (vmax, v0, v1) = (self.vmax, self.v0, self.v1);
        let covers = |d: F| d <= dist + F::from_f64(64.0) * F::EPSILON * (dist.abs() + d.abs());
        let mut anchors = [b, vmax, vmax, -vmax];
        let mut n = 1;
        for p in [v0.min(v1), F::ZERO] {
            let last = anchors.get(n - 1).copied().unwrap_or(b);
            if p < last && p > -vmax {
                if let Some(slot) = anchors.get_mut(n) {
                    *slot = p;
                }
                n += 1;
            }
        }
        if let Some(slot) = anchors.get_mut(n) {
            *slot = -vmax;
        }
        let mut prev = b;
        let pieces = (SCAN_POINTS / n).max(1);
        for w in 0..n {
            let (Some(&top), Some(&bottom)) = (anchors.get(w), anchors.get(w + 1)) else {
                break;
            };
            for k in 1..=pieces {
                #[allow(clippy::cast_precision_loss)]
                let f = F::from_f64(k as f64 / pieces as f64);
                let p = if k == pieces {
                    bottom
                } else {
                    top + (bottom - top) * f
                };
                // Between anchors, strictly: a scan point a rounding
                // error's worth too far would be taken as the root.
                let d = self.distance(p);
                if d <= dist || (k == pieces && covers(d)) {
                    // The peak is kept relative to the nearest exactly
                    // known velocity (the segment's top or bottom: b,
                    // min(v0, v1), 0 or -max_velocity), never to a scan
                    // point in between: a root close to one of them then
                    // keeps its precision (in f32 above all), whichever
                    // end it is near.
                    let (lo, hi) = (p - top, prev - top);
                    let y = self.root(top, lo, hi, hi, dist);
                    if k == pieces && y - lo < -y {
                        let (hi, start) = (prev - bottom, y - lo);
                        return Peak {
                            base: bottom,
                            offset: self.root(bottom, F::ZERO, hi, start.min(hi), dist),
                            cruise: F::ZERO,
                        };
                    }
                    return Peak {
                        base: top,
                        offset: y,
                        cruise: F::ZERO,
                    };
                }
                prev = p;
            }
        }
        // Even at -max_velocity the ramps cover too much: cruise backwards.
        let d_bottom = self.distance(-vmax);
        Peak::at(-vmax, ((d_bottom - dist) / vmax).max(F::ZERO))
    }
}

/// Plans the time-optimal jerk-limited profile for `req`, whatever its
/// [`MotionProfile`](crate::MotionProfile): velocity, acceleration,
/// deceleration and jerk limits, non-zero start and target velocities, a
/// start velocity above the limit (braked first), and moves that must pass
/// the target (planned with overshoot, or refused under
/// [`Overshoot::Forbid`]). The crate README's "S-curve method" section
/// describes how.
///
/// ```
/// use motorwire_planner::{Request, plan_scurve};
///
/// // The iRPC document's SetTargetV2 example: 0 -> 90 deg at 100 deg/s,
/// // 500 deg/s², 2000 deg/s³.
/// let req = Request::new(0.0f64, 90.0, 100.0, 500.0).with_jerk(2000.0);
/// let p = plan_scurve(&req)?;
/// // 100 deg/s is reached before 500 deg/s² (500²/2000 > 100): each ramp
/// // is 2 sqrt(100/2000) s of pure jerk, and the cruise covers the rest.
/// assert!((p.duration() - (0.9 + 0.2f64.sqrt())).abs() < 1e-12);
/// assert_eq!(p.phase_count(), 5);
/// assert!(p.peak_velocity().0 <= 100.0);
/// assert_eq!(p.sample(p.duration()).position, 90.0);
/// # Ok::<(), motorwire_planner::PlanError>(())
/// ```
///
/// # Errors
/// [`PlanError::Missing`], [`PlanError::NonFinite`] or
/// [`PlanError::NotPositive`] naming the field for bad input (`max_jerk`
/// included); [`PlanError::TargetVelocityTooHigh`];
/// [`PlanError::OvershootForbidden`]; [`PlanError::Unrepresentable`] when
/// finite inputs give a non-finite profile.
pub fn plan_scurve<F: Float>(req: &Request<F>) -> Result<Profile<F>, PlanError> {
    let (vmax, acc, dec) = req.limits()?;
    let jerk = req.jerk()?;
    // Built in place (a profile is 288 bytes in f64: copying it is a
    // measurable share of planning a rest-to-rest move).
    let mut profile = Profile::at_rest(req.target);
    if req.start_acceleration == F::ZERO {
        plan_from_rest_acceleration(req, vmax, acc, dec, jerk, &mut profile)?;
    } else {
        profile = plan_from_acceleration(req, vmax, acc, dec, jerk)?;
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

/// The time-optimal profile of a request whose start acceleration is zero
/// (its limits already checked), without the overshoot policy, written
/// into `profile` (at rest at the target when nothing moves).
#[inline(always)]
fn plan_from_rest_acceleration<F: Float>(
    req: &Request<F>,
    vmax: F,
    acc: F,
    dec: F,
    jerk: F,
    profile: &mut Profile<F>,
) -> Result<(), PlanError> {
    let (dir, dist, v0, v1) = req.forward_frame();
    if !dist.is_finite() {
        return Err(PlanError::Unrepresentable);
    }
    if dist == F::ZERO && v0 == F::ZERO && v1 == F::ZERO {
        *profile = Profile::at_rest(req.target);
        return Ok(());
    }
    let (model, peak) = solve(dist, v0, v1, vmax, acc, dec, jerk);
    build(req, &model, peak, dir, profile)
}

/// A profile from a non-zero start acceleration `a0` (see the crate
/// README's "Start acceleration"). Two constructions, the first that
/// applies:
///
/// 1. **The motion continues.** The state `a0 / J` seconds earlier from
///    which jerk `sign(a0) J` from zero acceleration reaches the start
///    state exactly (the *virtual start*) is planned from; when that plan
///    begins with the same jerk for at least `a0 / J`, it passes through the
///    start state, and its remainder from there is the profile. This is the
///    case of a motion still building its acceleration towards where it is
///    going, which is what a stream of setpoints asks for.
/// 2. **The acceleration is brought to zero first**, at jerk `J`, and the
///    move planned from the state reached; the braking phase merges with
///    the plan's first when their jerks agree, so the profile has at most
///    eight phases.
///
/// Either way the acceleration is continuous at the start and every phase
/// is within the limits, except that a start acceleration above them is
/// brought down at `J` (it cannot step).
fn plan_from_acceleration<F: Float>(
    req: &Request<F>,
    vmax: F,
    acc: F,
    dec: F,
    jerk: F,
) -> Result<Profile<F>, PlanError> {
    let a0 = req.start_acceleration;
    let (p0, v0) = (req.start, req.start_velocity);
    let sign: i8 = if a0 > F::ZERO { 1 } else { -1 };
    let t = a0.abs() / jerk;
    let sixth = F::from_f64(1.0 / 6.0);
    // 1. The virtual start: p0 = pv + vv t + a0 t²/6, v0 = vv + a0 t/2.
    let vv = v0 - a0 * t * F::HALF;
    let pv = p0 - t * (vv + a0 * t * sixth);
    if pv.is_finite() && vv.is_finite() {
        let mut virt = *req;
        virt.start = pv;
        virt.start_velocity = vv;
        virt.start_acceleration = F::ZERO;
        let mut whole = Profile::at_rest(req.target);
        if plan_from_rest_acceleration(&virt, vmax, acc, dec, jerk, &mut whole).is_ok() {
            // A leading phase of a few ulps of the whole (a cruise of 1e-17 s
            // where rounding put the virtual start a hair short of the
            // braking point) is rounding, not a phase.
            let tiny = F::from_f64(64.0) * F::EPSILON * whole.duration();
            let lead = (0..whole.phase_count())
                .take_while(|&i| whole.phase_shape(i).is_some_and(|(_, d)| d <= tiny))
                .count();
            if let Some((first_sign, first)) = whole.phase_shape(lead)
                && first_sign == sign
                && first >= t
            {
                let mut profile =
                    Profile::empty(whole.jerk_magnitude(), req.target, req.target_velocity);
                let mut next = lead + 1;
                let mut room = true;
                if first - t > F::from_f64(64.0) * F::EPSILON * first {
                    room &= profile.push_phase(first - t, p0, v0, a0, sign);
                } else if let Some((s, d)) = whole.phase_shape(next) {
                    // The start state is where the next phase begins: it
                    // starts there exactly, as the request says.
                    room &= profile.push_phase(d, p0, v0, a0, s);
                    next += 1;
                }
                for i in next..whole.phase_count() {
                    room &= profile.push_phase_of(&whole, i);
                }
                if room {
                    return checked(req, profile);
                }
            }
        }
    }
    // 2. Acceleration to zero first: p1 = p0 + v0 t + a0 t²/3, v1 = v0 + a0 t/2.
    let mut rest = *req;
    rest.start = p0 + t * (v0 + a0 * t / F::from_f64(3.0));
    rest.start_velocity = v0 + a0 * t * F::HALF;
    rest.start_acceleration = F::ZERO;
    // Where that state is the target's to rounding (a motion ending with
    // its acceleration coming back to zero), nothing follows the braking.
    let ulps = F::from_f64(1024.0) * F::EPSILON;
    let position_scale = p0.abs().max(req.target.abs()).max((req.target - p0).abs());
    let velocity_scale = vmax.max(v0.abs());
    let mut then = Profile::at_rest(req.target);
    if (rest.start - req.target).abs() > ulps * position_scale
        || (rest.start_velocity - req.target_velocity).abs() > ulps * velocity_scale
    {
        plan_from_rest_acceleration(&rest, vmax, acc, dec, jerk, &mut then)?;
    }
    let mut profile = Profile::empty(jerk, req.target, req.target_velocity);
    let mut room = true;
    let merged = matches!(then.phase_shape(0), Some((s, _)) if s == -sign);
    if merged {
        let first = then.phase_shape(0).map_or(F::ZERO, |(_, d)| d);
        room &= profile.push_phase(t + first, p0, v0, a0, -sign);
        for i in 1..then.phase_count() {
            room &= profile.push_phase_of(&then, i);
        }
    } else {
        room &= profile.push_phase(t, p0, v0, a0, -sign);
        for i in 0..then.phase_count() {
            room &= profile.push_phase_of(&then, i);
        }
    }
    if !room {
        // Seven phases after one: never more than MAX_PHASES.
        return Err(PlanError::Unrepresentable);
    }
    checked(req, profile)
}

/// A built profile, if every value in it is finite with headroom.
fn checked<F: Float>(req: &Request<F>, profile: Profile<F>) -> Result<Profile<F>, PlanError> {
    if !req.moderate() && !profile.representable() {
        return Err(PlanError::Unrepresentable);
    }
    Ok(profile)
}

/// The model and time-optimal peak of a forward move: with `acc` and `dec`
/// as given, unless part of the motion moves away from the target and they
/// differ; then with the smaller of the two both ways (see the module
/// documentation). `jerk` may be infinite (trapezoidal ramps).
pub(crate) fn solve<F: Float>(
    dist: F,
    v0: F,
    v1: F,
    vmax: F,
    acc: F,
    dec: F,
    jerk: F,
) -> (Model<F>, Peak<F>) {
    let model = Model::new(vmax, acc, dec, jerk, v0, v1);
    let peak = model.peak(dist);
    if acc != dec && (v0 < F::ZERO || v1 < F::ZERO || peak.x() < F::ZERO) {
        let m = acc.min(dec);
        let model = Model::new(vmax, m, m, jerk, v0, v1);
        let peak = model.peak(dist);
        return (model, peak);
    }
    (model, peak)
}

/// Turns a peak into phases, in the caller's frame, written into `profile`.
#[inline(always)]
pub(crate) fn build<F: Float>(
    req: &Request<F>,
    model: &Model<F>,
    peak: Peak<F>,
    dir: F,
    profile: &mut Profile<F>,
) -> Result<(), PlanError> {
    let first = model.shape((peak.base - model.v0) + peak.offset, dir);
    let second = model.shape((model.v1 - peak.base) - peak.offset, dir);
    for t in [
        first.t_jerk,
        first.t_flat,
        second.t_jerk,
        second.t_flat,
        peak.cruise,
    ] {
        if !t.is_finite() {
            return Err(PlanError::Unrepresentable);
        }
    }
    // A model with unbounded jerk (trapezoidal) builds no jerk phases.
    let jerk = if model.jerk.is_finite() {
        model.jerk
    } else {
        F::ZERO
    };
    let mut b = Builder::new(profile, req.start, req.start_velocity, jerk);
    b.jerk_ramp(first, peak.x() * dir);
    b.constant_acceleration(peak.cruise, F::ZERO, peak.x() * dir);
    b.jerk_ramp(second, req.target_velocity);
    b.finish(req.target, req.target_velocity);
    if !req.moderate() && !profile.representable() {
        return Err(PlanError::Unrepresentable);
    }
    Ok(())
}
