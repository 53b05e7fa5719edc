//! A planned motion: up to seven constant-jerk phases, sampled analytically.

use core::num::NonZeroU64;

use crate::Float;

/// The most phases a profile has: a jerk-limited profile's seven, and one
/// more to bring a start acceleration to zero first
/// ([`Request::start_acceleration`](crate::Request::start_acceleration)).
pub const MAX_PHASES: usize = 8;

/// Position, velocity, acceleration and jerk at one instant.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct State<F> {
    /// Position.
    pub position: F,
    /// Velocity (position units per second).
    pub velocity: F,
    /// Acceleration (units/s²).
    pub acceleration: F,
    /// Jerk (units/s³); 0 in a trapezoidal profile, whose acceleration steps.
    pub jerk: F,
}

/// The lowest and highest positions along a profile's whole path, and when
/// it reaches them ([`Profile::position_extrema`]). Times are seconds from
/// the start; where an extreme is reached more than once, one of the
/// times it is.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PositionExtrema<F> {
    /// The lowest position.
    pub min: F,
    /// When the lowest position is reached (s).
    pub t_min: F,
    /// The highest position.
    pub max: F,
    /// When the highest position is reached (s).
    pub t_max: F,
}

impl<F: Float> PositionExtrema<F> {
    /// How far the path goes below `lower`, and when it is lowest:
    /// `Some((lower - min, t_min))`, or `None` if it never goes below.
    ///
    /// ```
    /// use motorwire_planner::PositionExtrema;
    /// let e = PositionExtrema { min: -1.5f32, t_min: 0.25, max: 3.0, t_max: 1.0 };
    /// assert_eq!(e.below(-1.0), Some((0.5, 0.25)));
    /// assert_eq!(e.below(-1.5), None); // reaching a limit is not passing it
    /// ```
    pub fn below(&self, lower: F) -> Option<(F, F)> {
        (self.min < lower).then(|| (lower - self.min, self.t_min))
    }

    /// How far the path goes above `upper`, and when it is highest:
    /// `Some((max - upper, t_max))`, or `None` if it never goes above.
    ///
    /// ```
    /// use motorwire_planner::PositionExtrema;
    /// let e = PositionExtrema { min: -1.5f64, t_min: 0.25, max: 3.0, t_max: 1.0 };
    /// assert_eq!(e.above(2.0), Some((1.0, 1.0)));
    /// assert_eq!(e.above(3.0), None);
    /// ```
    pub fn above(&self, upper: F) -> Option<(F, F)> {
        (self.max > upper).then(|| (self.max - upper, self.t_max))
    }
}

/// One phase of a profile, as [`Profile::phases`] yields it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Phase<F> {
    /// When the phase starts (s).
    pub start_time: F,
    /// How long it lasts (s).
    pub duration: F,
    /// The state at its start (jerk included: constant over the phase).
    pub start: State<F>,
}

/// A planned 1-D motion: a sequence of constant-jerk phases.
///
/// Every phase stores its start state, so [`Profile::sample`] is a lookup
/// and one Horner evaluation, `p + t(v + t(a/2 + t j/6))`, from the start of
/// the phase the time falls in: no accumulated error. At and after the end
/// it returns the target state exactly.
///
/// The layout is packed so that `Profile<f32>` is at most 144 bytes and
/// `Profile<f64>` at most 288.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Profile<F> {
    /// Each phase's own duration, kept exactly (not as end times, whose
    /// differences would lose a short phase after a long one in f32).
    durations: [F; MAX_PHASES],
    p: [F; MAX_PHASES],
    v: [F; MAX_PHASES],
    a: [F; MAX_PHASES],
    /// Jerk magnitude; each phase's jerk is -1, 0 or +1 times it.
    jerk: F,
    /// Two bits per phase: 0 no jerk, 1 positive, 2 negative.
    jerk_signs: u16,
    count: u8,
    end_position: F,
    end_velocity: F,
}

impl<F: Float> Profile<F> {
    /// A profile that stays at rest at `position`.
    #[inline]
    pub fn at_rest(position: F) -> Self {
        Self {
            durations: [F::ZERO; MAX_PHASES],
            p: [F::ZERO; MAX_PHASES],
            v: [F::ZERO; MAX_PHASES],
            a: [F::ZERO; MAX_PHASES],
            jerk: F::ZERO,
            jerk_signs: 0,
            count: 0,
            end_position: position,
            end_velocity: F::ZERO,
        }
    }

    /// How many phases the profile has (0 for a move of zero length).
    pub fn phase_count(&self) -> usize {
        usize::from(self.count)
    }

    fn phase_durations(&self) -> &[F] {
        self.durations.get(..usize::from(self.count)).unwrap_or(&[])
    }

    /// The duration (s).
    pub fn duration(&self) -> F {
        self.phase_durations().iter().fold(F::ZERO, |t, d| t + *d)
    }

    /// The state at the end: the target position and velocity, at rest in
    /// acceleration.
    pub fn end_state(&self) -> State<F> {
        State {
            position: self.end_position,
            velocity: self.end_velocity,
            acceleration: F::ZERO,
            jerk: F::ZERO,
        }
    }

    /// Phase `i`'s jerk sign (-1, 0 or 1) and duration, if it exists.
    pub(crate) fn phase_shape(&self, i: usize) -> Option<(i8, F)> {
        if i >= usize::from(self.count) {
            return None;
        }
        let sign = match (self.jerk_signs >> (2 * i)) & 0b11 {
            1 => 1,
            2 => -1,
            _ => 0,
        };
        self.durations.get(i).map(|d| (sign, *d))
    }

    /// Appends phase `i` of `other` (same jerk magnitude) as it is: its
    /// duration and stored start state, not re-integrated. Returns whether
    /// there was room.
    pub(crate) fn push_phase_of(&mut self, other: &Self, i: usize) -> bool {
        let (Some((sign, d)), Some(&p), Some(&v), Some(&a)) = (
            other.phase_shape(i),
            other.p.get(i),
            other.v.get(i),
            other.a.get(i),
        ) else {
            return false;
        };
        self.push_phase(d, p, v, a, sign)
    }

    /// Appends a phase of `duration` from the start state `(p, v, a)` with
    /// jerk sign `sign`; returns whether there was room (a phase of zero
    /// duration is dropped, and counts as room).
    #[inline(always)]
    pub(crate) fn push_phase(&mut self, duration: F, p: F, v: F, a: F, sign: i8) -> bool {
        if duration.partial_cmp(&F::ZERO) != Some(core::cmp::Ordering::Greater) {
            return true;
        }
        let i = usize::from(self.count);
        let (Some(d_slot), Some(p_slot), Some(v_slot), Some(a_slot)) = (
            self.durations.get_mut(i),
            self.p.get_mut(i),
            self.v.get_mut(i),
            self.a.get_mut(i),
        ) else {
            return false;
        };
        *d_slot = duration;
        *p_slot = p;
        *v_slot = v;
        *a_slot = a;
        let code: u16 = match sign {
            1 => 1,
            -1 => 2,
            _ => 0,
        };
        self.jerk_signs |= code << (2 * i);
        self.count += 1;
        true
    }

    /// An empty profile with jerk magnitude `jerk`, ending at `(position,
    /// velocity)`: phases are appended with [`Self::push_phase`].
    pub(crate) fn empty(jerk: F, position: F, velocity: F) -> Self {
        let mut p = Self::at_rest(position);
        p.jerk = jerk;
        p.end_velocity = velocity;
        p
    }

    /// The jerk magnitude the phases' signs scale.
    pub(crate) fn jerk_magnitude(&self) -> F {
        self.jerk
    }

    /// Whether its jerk is limited (an S-curve): its acceleration is
    /// continuous, so a motion that replaces it mid-way starts from its
    /// acceleration ([`Request::start_acceleration`](crate::Request::start_acceleration)).
    /// A trapezoidal profile's acceleration steps, and so may the next.
    ///
    /// ```
    /// use motorwire_planner::{Request, plan};
    /// assert!(plan(&Request::new(0.0f64, 90.0, 100.0, 500.0).with_jerk(2000.0))?.is_jerk_limited());
    /// assert!(!plan(&Request::new(0.0f64, 90.0, 100.0, 500.0))?.is_jerk_limited());
    /// # Ok::<(), motorwire_planner::PlanError>(())
    /// ```
    pub fn is_jerk_limited(&self) -> bool {
        self.jerk > F::ZERO
    }

    fn jerk_of(&self, i: usize) -> F {
        match (self.jerk_signs >> (2 * i)) & 0b11 {
            1 => self.jerk,
            2 => -self.jerk,
            _ => F::ZERO,
        }
    }

    /// The state at time `t` seconds after the start. Before the start (and
    /// for a NaN `t`) it is the start state; at and after the end, exactly
    /// the end state.
    #[inline]
    pub fn sample(&self, t: F) -> State<F> {
        let mut t0 = F::ZERO;
        for (i, d) in self.phase_durations().iter().enumerate() {
            let end = t0 + *d;
            if t < end {
                let dt = if t > t0 { t - t0 } else { F::ZERO };
                return self.eval(i, dt);
            }
            t0 = end;
        }
        if self.count == 0 || t >= t0 {
            return self.end_state();
        }
        // Only a NaN `t` gets here: it compares false with every phase end.
        self.eval(0, F::ZERO)
    }

    #[inline]
    fn eval(&self, i: usize, dt: F) -> State<F> {
        let (p, v, a) = (
            self.p.get(i).copied().unwrap_or(F::ZERO),
            self.v.get(i).copied().unwrap_or(F::ZERO),
            self.a.get(i).copied().unwrap_or(F::ZERO),
        );
        let j = self.jerk_of(i);
        let sixth = F::from_f64(1.0 / 6.0);
        State {
            position: p + dt * (v + dt * (a * F::HALF + dt * j * sixth)),
            velocity: v + dt * (a + dt * j * F::HALF),
            acceleration: a + dt * j,
            jerk: j,
        }
    }

    /// The phases, in order.
    pub fn phases(&self) -> impl Iterator<Item = Phase<F>> + '_ {
        self.phase_durations()
            .iter()
            .enumerate()
            .scan(F::ZERO, move |t0, (i, d)| {
                let start_time = *t0;
                *t0 = start_time + *d;
                Some(Phase {
                    start_time,
                    duration: *d,
                    start: self.eval(i, F::ZERO),
                })
            })
    }

    /// The largest |velocity| reached, and when.
    pub fn peak_velocity(&self) -> (F, F) {
        let mut best = (self.end_velocity.abs(), self.duration());
        for ph in self.phases() {
            let mut consider = |t: F| {
                if t >= F::ZERO && t <= ph.duration {
                    let v = self.eval_phase(&ph, t).velocity.abs();
                    if v > best.0 {
                        best = (v, ph.start_time + t);
                    }
                }
            };
            consider(F::ZERO);
            consider(ph.duration);
            // Velocity is extreme inside a phase where acceleration crosses 0.
            if ph.start.jerk != F::ZERO {
                consider(-ph.start.acceleration / ph.start.jerk);
            }
        }
        best
    }

    /// The largest |acceleration| reached.
    pub fn peak_acceleration(&self) -> F {
        let mut best = F::ZERO;
        for ph in self.phases() {
            let a0 = ph.start.acceleration.abs();
            let a1 = (ph.start.acceleration + ph.start.jerk * ph.duration).abs();
            best = best.max(a0).max(a1);
        }
        best
    }

    fn eval_phase(&self, ph: &Phase<F>, t: F) -> State<F> {
        let s = ph.start;
        let sixth = F::from_f64(1.0 / 6.0);
        State {
            position: s.position
                + t * (s.velocity + t * (s.acceleration * F::HALF + t * s.jerk * sixth)),
            velocity: s.velocity + t * (s.acceleration + t * s.jerk * F::HALF),
            acceleration: s.acceleration + t * s.jerk,
            jerk: s.jerk,
        }
    }

    /// The lowest and highest positions along the whole path, each with
    /// the time it is reached: [`PositionExtrema`]. Exact, not sampled:
    /// each phase's position is a cubic whose extremes lie at the phase's
    /// ends or where its velocity crosses zero (the roots of
    /// `v + a t + j t²/2`), so an overshoot past the target, or a start
    /// moving away from it, is found however short it is. The start and the
    /// end count (a move that never reverses has its extrema there). A
    /// safety gate compares these with a motor's position limits.
    ///
    /// ```
    /// use motorwire_planner::{Request, plan_scurve};
    ///
    /// // 110 units/s towards a target 7.43 away, to arrive at -54.28 units/s
    /// // (issue 17's example): the path passes the target by 4.12.
    /// let req = Request::new(7.568808115350748f64, 15.002252214259556, 178.86060348763993, 1536.4613817844474)
    ///     .with_velocities(110.01997366326663, -54.28459435217094)
    ///     .with_jerk(8919.108436621469);
    /// let e = plan_scurve(&req)?.position_extrema();
    /// assert_eq!((e.min, e.t_min), (7.568808115350748, 0.0)); // the start
    /// assert!((e.max - 19.126339397731826).abs() < 1e-12); // Ruckig's, to 1e-12
    /// assert!((e.t_max - 0.1611204936725121).abs() < 1e-12);
    /// // Against limits [-10, 18]: 1.126 past the upper one, at 0.161 s.
    /// let (by, at) = e.above(18.0).unwrap();
    /// assert!((by - 1.126339397731826).abs() < 1e-12 && at == e.t_max);
    /// assert_eq!(e.below(-10.0), None);
    /// # Ok::<(), motorwire_planner::PlanError>(())
    /// ```
    pub fn position_extrema(&self) -> PositionExtrema<F> {
        let ((min, t_min), (max, t_max)) = self.position_extremes();
        PositionExtrema {
            min,
            t_min,
            max,
            t_max,
        }
    }

    /// The lowest and highest positions the motion reaches, each with the
    /// time it is reached: `((min, t_min), (max, t_max))`, as
    /// [`Self::position_extrema`] has them.
    pub fn position_extremes(&self) -> ((F, F), (F, F)) {
        self.extremes_from(F::ZERO)
    }

    /// [`Profile::position_extrema`] of what is left of the move from
    /// `from` seconds after its start (the position then counts; before
    /// the start, the whole path; after the end, the end).
    ///
    /// ```
    /// use motorwire_planner::{Request, plan};
    /// // 10 deg/s towards a target 1 deg away, braking at 10 deg/s²: 5 past it at 1 s.
    /// let p = plan(&Request::new(0.0f64, 1.0, 10.0, 10.0).with_velocities(10.0, 0.0))?;
    /// let whole = p.position_extrema();
    /// assert_eq!((whole.min, whole.max), (0.0, 5.0));
    /// // From 1.5 s on, the way back from 3.75 to the target.
    /// let rest = p.position_extrema_from(1.5);
    /// assert!((rest.max - 3.75).abs() < 1e-9 && rest.t_max == 1.5, "{rest:?}");
    /// assert_eq!(rest.min, 1.0);
    /// # Ok::<(), motorwire_planner::PlanError>(())
    /// ```
    pub fn position_extrema_from(&self, from: F) -> PositionExtrema<F> {
        let ((min, t_min), (max, t_max)) = self.extremes_from(from);
        PositionExtrema {
            min,
            t_min,
            max,
            t_max,
        }
    }

    fn extremes_from(&self, from: F) -> ((F, F), (F, F)) {
        let end = (self.end_position, self.duration());
        let mut lo = end;
        let mut hi = end;
        if from > F::ZERO && from < end.1 {
            let here = (self.sample(from).position, from);
            if here.0 < lo.0 {
                lo = here;
            }
            if here.0 > hi.0 {
                hi = here;
            }
        }
        for ph in self.phases() {
            let mut consider = |t: F| {
                if t >= F::ZERO && t <= ph.duration && ph.start_time + t >= from {
                    let p = self.eval_phase(&ph, t).position;
                    let at = ph.start_time + t;
                    if p < lo.0 {
                        lo = (p, at);
                    }
                    if p > hi.0 {
                        hi = (p, at);
                    }
                }
            };
            consider(F::ZERO);
            consider(ph.duration);
            // Position is extreme where velocity crosses 0:
            // v + a t + j t²/2 = 0.
            let (v, a, j) = (ph.start.velocity, ph.start.acceleration, ph.start.jerk);
            if j == F::ZERO {
                if a != F::ZERO {
                    consider(-v / a);
                }
            } else {
                let disc = a * a - F::TWO * j * v;
                if disc >= F::ZERO {
                    let r = disc.sqrt();
                    consider((-a + r) / j);
                    consider((-a - r) / j);
                }
            }
        }
        (lo, hi)
    }

    /// How far the motion passes the target in the direction of travel
    /// before it arrives (`None` when it does not; a move of zero length
    /// counts any excursion from the target). Rounding-level excursions are
    /// not overshoot.
    ///
    /// ```
    /// use motorwire_planner::{Request, plan_trapezoidal};
    /// // 10 units/s towards a target 1 unit away, braking at 1 unit/s²: 49 past it.
    /// let p = plan_trapezoidal(&Request::new(0.0f64, 1.0, 10.0, 1.0).with_velocities(10.0, 0.0))?;
    /// assert!((p.overshoot().unwrap() - 49.0).abs() < 1e-9);
    /// # Ok::<(), motorwire_planner::PlanError>(())
    /// ```
    pub fn overshoot(&self) -> Option<F> {
        let start = match self.count {
            0 => self.end_position,
            _ => self.p.first().copied().unwrap_or(self.end_position),
        };
        let target = self.end_position;
        let ((lo, _), (hi, _)) = self.position_extremes();
        let past = if target > start {
            hi - target
        } else if target < start {
            target - lo
        } else {
            (hi - target).max(target - lo)
        };
        let scale = start.abs().max(target.abs()).max((target - start).abs());
        let tol = F::from_f64(1024.0) * F::EPSILON * scale.max(F::EPSILON);
        (past > tol).then_some(past)
    }

    /// Whether every value the profile can produce is finite, with headroom:
    /// each phase's duration and start state, and a bound on the magnitude
    /// of its position, velocity and acceleration over the whole phase
    /// (`|p| + d(|v| + d(|a|/2 + d|j|/6))` and the like), within a quarter
    /// of the float's range, so evaluating any instant cannot overflow.
    pub(crate) fn representable(&self) -> bool {
        let limit = F::from_f64(f64::MAX) * F::from_f64(0.25);
        let ok = |v: F| v.is_finite() && v.abs() <= limit;
        let sixth = F::from_f64(1.0 / 6.0);
        let mut total = F::ZERO;
        for i in 0..usize::from(self.count).min(MAX_PHASES) {
            let (Some(&d), Some(&p), Some(&v), Some(&a)) = (
                self.durations.get(i),
                self.p.get(i),
                self.v.get(i),
                self.a.get(i),
            ) else {
                return false;
            };
            let j = self.jerk_of(i).abs();
            let (v, a) = (v.abs(), a.abs());
            let bound_p = p.abs() + d * (v + d * (a * F::HALF + d * j * sixth));
            let bound_v = v + d * (a + d * j * F::HALF);
            let bound_a = a + d * j;
            total = total + d;
            if !(ok(d) && ok(bound_p) && ok(bound_v) && ok(bound_a)) {
                return false;
            }
        }
        ok(total) && ok(self.end_position) && ok(self.end_velocity)
    }

    /// Samples on an integer tick: the state every `tick_us` microseconds
    /// from 0 until the first tick at or after the end (which is the end
    /// state). Time is computed from the tick count, so long moves do not
    /// drift.
    ///
    /// ```
    /// use core::num::NonZeroU64;
    /// use motorwire_planner::{Request, plan_trapezoidal};
    /// let p = plan_trapezoidal(&Request::new(0.0f64, 1.0, 1.0, 1.0))?; // 2 s
    /// let ticks: Vec<u64> = p.ticks(NonZeroU64::new(500_000).unwrap()).map(|(t, _)| t).collect();
    /// assert_eq!(ticks, [0, 500_000, 1_000_000, 1_500_000, 2_000_000]);
    /// # Ok::<(), motorwire_planner::PlanError>(())
    /// ```
    pub fn ticks(&self, tick_us: NonZeroU64) -> Ticks<'_, F> {
        Ticks {
            profile: self,
            tick_us: tick_us.get(),
            next: 0,
            done: false,
        }
    }
}

/// The iterator of [`Profile::ticks`].
#[derive(Debug, Clone)]
pub struct Ticks<'a, F> {
    profile: &'a Profile<F>,
    tick_us: u64,
    next: u64,
    done: bool,
}

impl<F: Float> Iterator for Ticks<'_, F> {
    type Item = (u64, State<F>);

    fn next(&mut self) -> Option<Self::Item> {
        if self.done {
            return None;
        }
        let t_us = self.next.checked_mul(self.tick_us)?;
        #[allow(clippy::cast_precision_loss)] // exact below 2^53 µs (285 years)
        let t = F::from_f64(t_us as f64 / 1e6);
        if t_us as f64 / 1e6 >= self.profile.duration().to_f64() {
            self.done = true;
        }
        self.next += 1;
        Some((t_us, self.profile.sample(t)))
    }
}

/// The three phase durations of a jerk-limited velocity change.
#[derive(Debug, Clone, Copy)]
pub(crate) struct RampShape<F> {
    pub(crate) t_jerk: F,
    pub(crate) t_flat: F,
    pub(crate) peak: F,
    pub(crate) sign: i8,
}

/// Builds a profile phase by phase from a start state, integrating each
/// phase's end state as the next one's start.
pub(crate) struct Builder<'a, F> {
    profile: &'a mut Profile<F>,
    state: State<F>,
}

impl<'a, F: Float> Builder<'a, F> {
    /// Starts writing `profile` in place (a profile is 256 bytes in f64:
    /// building it where it will be returned saves copying it).
    #[inline]
    pub(crate) fn new(profile: &'a mut Profile<F>, position: F, velocity: F, jerk: F) -> Self {
        *profile = Profile::at_rest(position);
        profile.jerk = jerk;
        Self {
            profile,
            state: State {
                position,
                velocity,
                acceleration: F::ZERO,
                jerk: F::ZERO,
            },
        }
    }

    /// Appends a phase of `duration` with start acceleration `a` and jerk
    /// sign `sign` (-1, 0, 1); phases of zero duration are dropped.
    #[inline(always)]
    pub(crate) fn phase(&mut self, duration: F, a: F, sign: i8) {
        let before = self.profile.count;
        let s = self.state;
        // Drops zero, negative and NaN durations alike; the planners never
        // build more than MAX_PHASES phases.
        self.profile
            .push_phase(duration, s.position, s.velocity, a, sign);
        if self.profile.count == before {
            return;
        }
        let j = self.profile.jerk_of(usize::from(before));
        let sixth = F::from_f64(1.0 / 6.0);
        self.state = State {
            position: s.position
                + duration * (s.velocity + duration * (a * F::HALF + duration * j * sixth)),
            velocity: s.velocity + duration * (a + duration * j * F::HALF),
            acceleration: a + duration * j,
            jerk: j,
        };
    }

    /// Appends a constant-acceleration phase that ends at `end_velocity` as
    /// planned. The next phase starts from that velocity and from the
    /// position `p + duration (v + end_velocity) / 2`, exact for constant
    /// acceleration, rather than from re-integrated, rounded products.
    #[inline(always)]
    pub(crate) fn constant_acceleration(&mut self, duration: F, a: F, end_velocity: F) {
        let before = self.profile.count;
        let start = self.state;
        self.phase(duration, a, 0);
        if self.profile.count != before {
            self.state.position =
                start.position + duration * (start.velocity + end_velocity) * F::HALF;
            self.state.velocity = end_velocity;
        }
    }

    /// Appends a jerk-limited velocity change from `va` to `vb` starting and
    /// ending at zero acceleration: jerk for `t_jerk`, constant acceleration
    /// `peak` for `t_flat`, jerk back to zero for `t_jerk` (`sign` is the
    /// direction of the change). The next phase starts from `vb` and from
    /// the position `p + (va + vb) T / 2`, exact for this point-symmetric
    /// shape, rather than from re-integrated, rounded products.
    #[inline(always)]
    pub(crate) fn jerk_ramp(&mut self, shape: RampShape<F>, vb: F) {
        let start = self.state;
        let before = self.profile.count;
        let s = F::from_f64(f64::from(shape.sign));
        self.phase(shape.t_jerk, F::ZERO, shape.sign);
        self.phase(shape.t_flat, s * shape.peak, 0);
        self.phase(shape.t_jerk, s * shape.peak, -shape.sign);
        if self.profile.count != before {
            let total = shape.t_jerk + shape.t_flat + shape.t_jerk;
            self.state.position = start.position + total * (start.velocity + vb) * F::HALF;
            self.state.velocity = vb;
            self.state.acceleration = F::ZERO;
        }
    }

    /// Finishes with the exact end state the planner was asked for.
    #[inline]
    pub(crate) fn finish(self, position: F, velocity: F) {
        self.profile.end_position = position;
        self.profile.end_velocity = velocity;
    }
}
