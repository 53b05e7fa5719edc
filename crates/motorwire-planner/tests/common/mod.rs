//! Shared by the planner's tests: a small seeded generator, so every random
//! sweep is reproducible from its seed.
#![allow(dead_code, unreachable_pub, missing_docs)]

use motorwire_planner::{Profile, Request, State};

/// SplitMix64.
pub struct Rng(pub u64);

impl Rng {
    pub fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    pub fn unit(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Uniform in [lo, hi).
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }

    /// 10^x with x uniform in [lo, hi).
    pub fn log_uniform(&mut self, lo: f64, hi: f64) -> f64 {
        10f64.powf(self.range(lo, hi))
    }

    /// +1 or -1.
    pub fn signed(&mut self) -> f64 {
        if self.next() & 1 == 0 { 1.0 } else { -1.0 }
    }
}

/// How many random cases a sweep runs: `MOTORWIRE_PLANNER_CASES`, or
/// 100,000 (CI runs a million in release).
pub fn cases() -> usize {
    std::env::var("MOTORWIRE_PLANNER_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(100_000)
}

/// A random move: limits over many decades, separate deceleration two
/// times in three, a zero move one time in ten, start velocities up to
/// twice the limit, either direction.
pub fn random_request(rng: &mut Rng) -> Request<f64> {
    let vmax = rng.log_uniform(-3.0, 3.0);
    let acc = rng.log_uniform(-2.0, 5.0);
    let dec = if rng.next().is_multiple_of(3) {
        acc
    } else {
        rng.log_uniform(-2.0, 5.0)
    };
    let start = rng.signed() * rng.log_uniform(-3.0, 3.0);
    let dist = match rng.next() % 10 {
        0 => 0.0,
        _ => rng.signed() * rng.log_uniform(-6.0, 4.0),
    };
    let v0 = match rng.next() % 4 {
        0 => 0.0,
        1 => rng.signed() * vmax * 2.0 * rng.unit(),
        _ => rng.signed() * vmax * rng.unit(),
    };
    let v1 = match rng.next() % 3 {
        0 => 0.0,
        _ => rng.signed() * vmax * rng.unit(),
    };
    Request::new(start, start + dist, vmax, acc)
        .with_max_deceleration(dec)
        .with_velocities(v0, v1)
}

/// The same request in f32 (each field rounded to nearest).
pub fn to_f32(r: &Request<f64>) -> Request<f32> {
    Request {
        start: r.start as f32,
        target: r.target as f32,
        start_velocity: r.start_velocity as f32,
        target_velocity: r.target_velocity as f32,
        start_acceleration: r.start_acceleration as f32,
        max_velocity: r.max_velocity as f32,
        max_acceleration: r.max_acceleration as f32,
        max_deceleration: r.max_deceleration.map(|d| d as f32),
        max_jerk: r.max_jerk.map(|j| j as f32),
        profile: r.profile,
        overshoot: r.overshoot,
    }
}

/// The same request in f64 (each field exactly).
pub fn to_f64(r: &Request<f32>) -> Request<f64> {
    Request {
        start: f64::from(r.start),
        target: f64::from(r.target),
        start_velocity: f64::from(r.start_velocity),
        target_velocity: f64::from(r.target_velocity),
        start_acceleration: f64::from(r.start_acceleration),
        max_velocity: f64::from(r.max_velocity),
        max_acceleration: f64::from(r.max_acceleration),
        max_deceleration: r.max_deceleration.map(f64::from),
        max_jerk: r.max_jerk.map(f64::from),
        profile: r.profile,
        overshoot: r.overshoot,
    }
}

/// Checks a jerk-limited profile against its request, phase by phase,
/// analytically: jerk in {-J, 0, J}; acceleration within max_acceleration
/// towards the target and max_deceleration away from it (and, where the
/// velocity is not zero, within the speeding-up or slowing-down limit);
/// velocity within max_velocity (after braking from a start above it);
/// continuity; and the integrated end equal to the target.
pub fn check_scurve(req: &Request<f64>, p: &Profile<f64>) {
    let (vmax, acc) = (req.max_velocity, req.max_acceleration);
    let dec = req.max_deceleration.unwrap_or(acc);
    let rel = 1e-9;
    let dir = if req.target < req.start { -1.0 } else { 1.0 };
    let scale = req.start.abs().max(req.target.abs()).max(1.0);
    let ((lo, _), (hi, _)) = p.position_extremes();
    let extent = scale.max(lo.abs()).max(hi.abs());
    let vscale = vmax.max(req.start_velocity.abs());
    let state = State {
        position: req.start,
        velocity: req.start_velocity,
        ..State::default()
    };
    let mut above = req.start_velocity.abs() > vmax;
    assert!(p.phase_count() <= 7, "{req:?}");
    let tolerance = Continuity {
        position: 1e-11 * extent,
        velocity: 1e-9 * vscale,
        acceleration: 1e-9 * acc.max(dec),
    };
    let state = walk_phases(req, p, state, tolerance, |s, end, d| {
        // Acceleration is linear in a phase: its ends bound it.
        for (a, v) in [
            (s.acceleration, s.velocity),
            (end.acceleration, end.velocity),
        ] {
            let towards = if a * dir >= 0.0 { acc } else { dec };
            assert!(a.abs() <= towards * (1.0 + rel), "{req:?} {s:?}: a = {a}");
            if a * v > 0.0 {
                assert!(a.abs() <= acc * (1.0 + rel), "{req:?} speeding up at {a}");
            } else if a * v < 0.0 {
                assert!(a.abs() <= dec * (1.0 + rel), "{req:?} slowing down at {a}");
            }
        }
        // Velocity is extreme at the ends or where acceleration crosses 0.
        let mut vs = vec![s.velocity, end.velocity];
        if s.jerk != 0.0 {
            let t = -s.acceleration / s.jerk;
            if t > 0.0 && t < d {
                vs.push(s.velocity + t * (s.acceleration + t * s.jerk / 2.0));
            }
        }
        for v in vs {
            let bound = if above {
                req.start_velocity.abs()
            } else {
                vmax
            };
            assert!(
                v.abs() <= bound * (1.0 + rel) + 1e-12,
                "{req:?} {s:?}: v = {v}"
            );
        }
        if above && end.velocity.abs() <= vmax * (1.0 + rel) {
            above = false;
        }
    });
    assert!(
        (state.position - req.target).abs() <= 1e-8 * extent,
        "{req:?}: ends at {} not {}",
        state.position,
        req.target
    );
    assert!(
        (state.velocity - req.target_velocity).abs() <= 1e-8 * vscale,
        "{req:?}: ends at velocity {}",
        state.velocity
    );
    assert!(state.acceleration.abs() <= 1e-8 * acc.max(dec), "{req:?}");
    let end = p.sample(p.duration());
    assert_eq!(
        (end.position, end.velocity, end.acceleration),
        (req.target, req.target_velocity, 0.0)
    );
}

/// How far a phase's start may be from where the phase before it ended.
pub struct Continuity {
    pub position: f64,
    pub velocity: f64,
    pub acceleration: f64,
}

/// Walks `p`'s phases from `state`: each lasts a positive, finite time,
/// its jerk is 0 or ±`req`'s max_jerk, and it starts where the one before
/// ended (within `tolerance`). `each` is given each phase's start, its
/// end (integrated analytically) and its duration; the end of the last is
/// returned.
pub fn walk_phases(
    req: &Request<f64>,
    p: &Profile<f64>,
    mut state: State<f64>,
    tolerance: Continuity,
    mut each: impl FnMut(&State<f64>, &State<f64>, f64),
) -> State<f64> {
    let jerk = req.max_jerk.unwrap();
    for ph in p.phases() {
        let s = ph.start;
        let d = ph.duration;
        assert!(d > 0.0 && d.is_finite(), "{req:?}");
        assert!(s.jerk == 0.0 || s.jerk.abs() == jerk, "{req:?} {s:?}");
        assert!(
            (s.position - state.position).abs() <= tolerance.position,
            "{req:?} {s:?} vs {state:?}"
        );
        assert!(
            (s.velocity - state.velocity).abs() <= tolerance.velocity,
            "{req:?} {s:?} vs {state:?}"
        );
        assert!(
            (s.acceleration - state.acceleration).abs() <= tolerance.acceleration,
            "{req:?} {s:?} vs {state:?}"
        );
        let end = State {
            position: s.position + d * (s.velocity + d * (s.acceleration / 2.0 + d * s.jerk / 6.0)),
            velocity: s.velocity + d * (s.acceleration + d * s.jerk / 2.0),
            acceleration: s.acceleration + d * s.jerk,
            jerk: s.jerk,
        };
        each(&s, &end, d);
        state = end;
    }
    state
}
