//! Profiles from a non-zero start acceleration (`Request::start_acceleration`):
//! a motion replaced mid-move continues without a step in acceleration.
//! Named cases, the principle that a plan from a state on a plan is that
//! plan's remainder, and a seeded random sweep that checks continuity at
//! the start, every phase's jerk, the acceleration bound, and the exact end.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing
)]

mod common;

use common::{Continuity, Rng, cases, walk_phases};
use motorwire_planner::*;

const J: f64 = 2000.0;

fn elbow(start: f64, target: f64) -> Request<f64> {
    // The demo map's elbow: 120 deg/s, 500 deg/s², 400 deg/s² braking, 2,000 deg/s³.
    Request::new(start, target, 120.0, 500.0)
        .with_max_deceleration(400.0)
        .with_jerk(J)
}

fn from_state(req: Request<f64>, s: State<f64>) -> Request<f64> {
    let mut r = req;
    r.start = s.position;
    r.start_velocity = s.velocity;
    r.start_acceleration = s.acceleration;
    r
}

/// Checks `p` against `req` analytically: it starts exactly in the start
/// state, its state is continuous from phase to phase, every jerk is 0 or
/// ±max_jerk, acceleration stays within the larger of the limit and the
/// start's magnitude, and it ends exactly at the target.
fn check(req: &Request<f64>, p: &Profile<f64>) {
    let amax = req
        .max_acceleration
        .max(req.max_deceleration.unwrap_or(0.0))
        .max(req.start_acceleration.abs());
    let scale = req.start.abs().max(req.target.abs()).max(1.0);
    let vscale = req
        .max_velocity
        .max(req.start_velocity.abs())
        .max(req.target_velocity.abs())
        .max(p.peak_velocity().0);
    assert!(p.phase_count() <= MAX_PHASES, "{req:?}");
    let s0 = p.sample(0.0);
    assert_eq!(
        (s0.position, s0.velocity, s0.acceleration),
        (req.start, req.start_velocity, req.start_acceleration),
        "{req:?}"
    );
    let ((lo, _), (hi, _)) = p.position_extremes();
    let extent = scale.max(lo.abs()).max(hi.abs());
    let tolerance = Continuity {
        position: 1e-9 * extent,
        velocity: 1e-9 * vscale,
        acceleration: 1e-9 * amax,
    };
    let state = walk_phases(req, p, s0, tolerance, |s, end, _| {
        for a in [s.acceleration, end.acceleration] {
            assert!(a.abs() <= amax * (1.0 + 1e-9), "{req:?} {s:?}: a = {a}");
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
        "{req:?}: ends at {} not {}",
        state.velocity,
        req.target_velocity
    );
    assert!(
        state.acceleration.abs() <= 1e-8 * amax,
        "{req:?}: {state:?}"
    );
    let e = p.end_state();
    assert_eq!((e.position, e.velocity), (req.target, req.target_velocity));
}

#[test]
fn a_plan_from_a_state_while_the_acceleration_builds_is_the_rest_of_that_plan() {
    // 0 -> 90 on the elbow, replanned 50 ms in (acceleration 100 deg/s²,
    // building): the same motion, 50 ms shorter, the same at every instant.
    let req = elbow(0.0, 90.0);
    let whole = plan(&req).unwrap();
    let at = whole.sample(0.05);
    assert!((at.acceleration - 100.0).abs() < 1e-9, "{at:?}");
    let rest = plan(&from_state(req, at)).unwrap();
    check(&from_state(req, at), &rest);
    assert!((rest.duration() - (whole.duration() - 0.05)).abs() < 1e-12);
    for i in 0..=100 {
        let t = rest.duration() * f64::from(i) / 100.0;
        let (a, b) = (rest.sample(t), whole.sample(t + 0.05));
        assert!((a.position - b.position).abs() < 1e-9, "{t}: {a:?} {b:?}");
        assert!((a.velocity - b.velocity).abs() < 1e-9, "{t}: {a:?} {b:?}");
        assert!((a.acceleration - b.acceleration).abs() < 1e-9, "{t}");
    }
}

#[test]
fn a_plan_from_a_state_on_a_plan_ends_no_later_than_that_plan() {
    // From every 10 ms of a long move (both directions, with and without a
    // separate braking limit), the plan from the state reached arrives no
    // later than the original and is within its limits: a motion replaced
    // by its own target goes on as it was.
    for (start, target) in [(0.0, 90.0), (60.0, -30.0), (0.0, 3.0)] {
        for dec in [500.0, 400.0] {
            let req = Request::new(start, target, 120.0, 500.0)
                .with_max_deceleration(dec)
                .with_jerk(J);
            let whole = plan(&req).unwrap();
            let mut t = 0.0;
            while t < whole.duration() {
                let at = whole.sample(t);
                let r = from_state(req, at);
                let rest = plan(&r).unwrap();
                check(&r, &rest);
                // To a microsecond: a residual velocity of 1e-13 deg/s left
                // by rounding takes two jerk phases of 1.5e-8 s to remove.
                assert!(
                    rest.duration() <= whole.duration() - t + 1e-6,
                    "{start} -> {target} at {t}: {} > {}",
                    rest.duration(),
                    whole.duration() - t
                );
                t += 0.01;
            }
        }
    }
}

#[test]
fn an_acceleration_away_from_the_target_is_brought_to_zero_first() {
    // At rest at 0 but accelerating at -300 deg/s² (away from 90): the
    // acceleration comes back to zero at the jerk limit (150 ms) and then
    // turns towards the target, without a step.
    let req = elbow(0.0, 90.0).with_start_acceleration(-300.0);
    let p = plan(&req).unwrap();
    check(&req, &p);
    let first = p.phases().next().unwrap();
    assert_eq!(first.start.jerk, J);
    assert!(first.duration > 0.15, "{first:?}");
    let s = p.sample(0.15);
    assert!(s.acceleration.abs() < 1e-9, "{s:?}");
    assert!((s.velocity - (-300.0 * 0.15 / 2.0)).abs() < 1e-9, "{s:?}");
}

#[test]
fn an_acceleration_above_the_limit_comes_down_at_the_jerk_limit() {
    // Braking at 1,000 deg/s² (an emergency brake) when a new target comes:
    // the acceleration cannot step back to 400; it comes down at 2,000 deg/s³.
    let req = elbow(10.0, 50.0)
        .with_velocities(-40.0, 0.0)
        .with_start_acceleration(1000.0);
    let p = plan(&req).unwrap();
    check(&req, &p);
    assert!(p.sample(0.1).acceleration < 1000.0 - 199.0);
}

#[test]
fn zero_start_acceleration_is_the_plan_it_always_was() {
    let req = elbow(0.0, 90.0);
    assert_eq!(plan(&req), plan(&req.with_start_acceleration(0.0)));
}

#[test]
fn a_trapezoidal_profile_ignores_the_start_acceleration() {
    let req = Request::new(0.0f64, 90.0, 120.0, 500.0);
    assert_eq!(plan(&req), plan(&req.with_start_acceleration(250.0)));
}

#[test]
fn bad_start_accelerations_are_refused_by_name() {
    for a in [f64::NAN, f64::INFINITY] {
        assert_eq!(
            plan(&elbow(0.0, 90.0).with_start_acceleration(a)),
            Err(PlanError::NonFinite {
                field: "start_acceleration"
            })
        );
    }
    let req = elbow(0.0, 90.0).with_start_acceleration(100.0);
    assert_eq!(
        plan_with_duration(&req, 2.0),
        Err(PlanError::StartAcceleration { value: 100.0 })
    );
    assert_eq!(
        PlanError::StartAcceleration { value: 100.0 }.to_string(),
        "a jerk-limited move of a given duration starts from zero acceleration, not 100"
    );
    let plan_time = plan(&req).unwrap().duration();
    assert_eq!(minimum_duration(&req), Ok(plan_time));
    let mut out = [Profile::at_rest(0.0); 1];
    assert_eq!(
        synchronize_phases(&[req], &mut out),
        Err(PlanError::NotAtRest { axis: 0 })
    );
}

#[test]
fn random_start_states_continue_without_a_step() {
    let mut rng = Rng(0x5eed_acce);
    let (mut continued, mut braked) = (0usize, 0usize);
    for _ in 0..cases() {
        let mut req = common::random_request(&mut rng);
        let jerk = rng.log_uniform(-1.0, 6.0);
        req = req.with_jerk(jerk);
        let limit = req.max_acceleration.min(req.max_deceleration.unwrap());
        let a0 = match rng.next() % 4 {
            0 => rng.signed() * limit * 3.0 * rng.unit(),
            _ => rng.signed() * limit * rng.unit(),
        };
        req = req.with_start_acceleration(a0);
        let Ok(p) = plan(&req) else {
            // Only the numbers' range refuses: every such case is extreme.
            assert!(
                matches!(plan(&req), Err(PlanError::Unrepresentable)),
                "{req:?}"
            );
            continue;
        };
        check(&req, &p);
        let first = p.phases().next();
        if first.is_some_and(|f| f.start.jerk * a0 > 0.0 || f.start.jerk == 0.0) {
            continued += 1;
        } else {
            braked += 1;
        }
    }
    // Both constructions are exercised.
    assert!(
        continued > cases() / 10,
        "{continued} continued, {braked} braked"
    );
    assert!(
        braked > cases() / 10,
        "{continued} continued, {braked} braked"
    );
}
