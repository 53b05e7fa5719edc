//! The trapezoidal planner: named cases with known answers, and a seeded
//! random sweep checking every limit, the exact end state and optimality
//! where an independent formula exists.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing
)]

mod common;

use common::{Rng, cases, random_request};
use motorwire_planner::*;

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol * (1.0 + a.abs().max(b.abs()))
}

#[test]
fn the_documents_trapezoidal_example() {
    let p = plan_trapezoidal(&Request::new(0.0f64, 90.0, 100.0, 500.0)).unwrap();
    assert!(close(p.duration(), 1.1, 1e-14), "{}", p.duration());
    assert_eq!(p.phase_count(), 3);
    let phases: Vec<Phase<f64>> = p.phases().collect();
    assert!(close(phases[0].duration, 0.2, 1e-14));
    assert!(close(phases[1].duration, 0.7, 1e-14));
    assert!(close(phases[2].duration, 0.2, 1e-14));
    assert_eq!(phases[0].start.acceleration, 500.0);
    assert_eq!(phases[1].start.acceleration, 0.0);
    assert_eq!(phases[2].start.acceleration, -500.0);
    let s = p.sample(0.1);
    assert!(close(s.position, 2.5, 1e-14) && close(s.velocity, 50.0, 1e-14));
    assert_eq!(p.peak_velocity().0, 100.0);
    assert_eq!(p.peak_acceleration(), 500.0);
    let end = p.sample(1.1);
    assert_eq!(
        (end.position, end.velocity, end.acceleration),
        (90.0, 0.0, 0.0)
    );
    assert_eq!(p.overshoot(), None);
}

#[test]
fn triangular_asymmetric_and_reverse_moves() {
    // Too short to reach max velocity: vp = sqrt(D A), T = 2 sqrt(D/A).
    let p = plan_trapezoidal(&Request::new(0.0f64, 1.0, 10.0, 1.0)).unwrap();
    assert!(close(p.duration(), 2.0, 1e-14));
    assert!(close(p.peak_velocity().0, 1.0, 1e-14));
    // Asymmetric: A = 2, D = 1, distance 3 -> vp² (1/4 + 1/2) = 3 -> vp = 2, T = 1 + 2.
    let p =
        plan_trapezoidal(&Request::new(0.0f64, 3.0, 10.0, 2.0).with_max_deceleration(1.0)).unwrap();
    assert!(close(p.duration(), 3.0, 1e-14), "{}", p.duration());
    let ph: Vec<Phase<f64>> = p.phases().collect();
    assert_eq!(
        (ph[0].start.acceleration, ph[1].start.acceleration),
        (2.0, -1.0)
    );
    // Backwards: the mirror image.
    let p = plan_trapezoidal(&Request::new(5.0f64, -85.0, 100.0, 500.0)).unwrap();
    assert!(close(p.duration(), 1.1, 1e-14));
    assert_eq!(p.phases().next().unwrap().start.acceleration, -500.0);
    assert_eq!(p.sample(2.0).position, -85.0);
}

#[test]
fn zero_moves() {
    let p = plan_trapezoidal(&Request::new(7.0f64, 7.0, 1.0, 1.0)).unwrap();
    assert_eq!((p.phase_count(), p.duration()), (0, 0.0));
    assert_eq!(p.sample(0.0).position, 7.0);
    assert_eq!(p.sample(f64::NAN).position, 7.0);
    // Zero distance but moving: it must go out and come back.
    let p =
        plan_trapezoidal(&Request::new(0.0f64, 0.0, 1.0, 1.0).with_velocities(1.0, 0.0)).unwrap();
    assert!(p.duration() > 0.0);
    assert!(close(p.overshoot().unwrap(), 0.5, 1e-12));
}

#[test]
fn a_start_velocity_above_the_limit_brakes_first() {
    // 150 -> 100 at D = 50 takes 1 s and 125 units; then coast; then 100 -> 0 in 2 s, 100 units.
    let req = Request::new(0.0f64, 1000.0, 100.0, 500.0)
        .with_max_deceleration(50.0)
        .with_velocities(150.0, 0.0);
    let p = plan_trapezoidal(&req).unwrap();
    let ph: Vec<Phase<f64>> = p.phases().collect();
    assert_eq!(ph[0].start.acceleration, -50.0);
    assert!(close(ph[0].duration, 1.0, 1e-14));
    assert!(close(ph[1].duration, 7.75, 1e-14), "{}", ph[1].duration);
    assert!(close(p.duration(), 10.75, 1e-14));
    assert_eq!(p.overshoot(), None);
}

#[test]
fn overshoot_is_planned_or_refused() {
    // 10 units/s, 1 unit to go, braking at 1: stops 49 past the target, comes back.
    let req = Request::new(0.0f64, 1.0, 10.0, 1.0).with_velocities(10.0, 0.0);
    let p = plan_trapezoidal(&req).unwrap();
    assert!(close(p.overshoot().unwrap(), 49.0, 1e-12));
    let ((_, _), (hi, t_hi)) = p.position_extremes();
    assert!(close(hi, 50.0, 1e-12) && close(t_hi, 10.0, 1e-12));
    assert_eq!(p.sample(p.duration()).position, 1.0);
    match plan_trapezoidal(&req.with_overshoot(Overshoot::Forbid)) {
        Err(PlanError::OvershootForbidden { overshoot }) => assert!(close(overshoot, 49.0, 1e-12)),
        other => panic!("{other:?}"),
    }
    // A target velocity pointing back towards the start must pass the target.
    let back = Request::new(0.0f64, 1.0, 10.0, 1.0).with_velocities(0.0, -1.0);
    assert!(plan_trapezoidal(&back).unwrap().overshoot().is_some());
    assert!(matches!(
        plan_trapezoidal(&back.with_overshoot(Overshoot::Forbid)),
        Err(PlanError::OvershootForbidden { .. })
    ));
}

#[test]
fn a_run_up_backs_up_first_without_overshooting() {
    // Reaching 10 from rest takes 50 units at A = 1; the target is 1 away.
    let req = Request::new(0.0f64, 1.0, 20.0, 1.0).with_velocities(0.0, 10.0);
    let p = plan_trapezoidal(&req.with_overshoot(Overshoot::Forbid)).unwrap();
    let ((lo, _), _) = p.position_extremes();
    // It needs 50 units of run-up: back to -49 (accelerating 24.5, braking
    // 24.5), then 50 forward to arrive at 1 with 10.
    assert!(close(lo, -49.0, 1e-12), "{lo}");
    assert_eq!(p.overshoot(), None);
    let end = p.sample(p.duration());
    assert_eq!((end.position, end.velocity), (1.0, 10.0));
}

#[test]
fn invalid_requests_name_the_field() {
    let ok = Request::new(0.0f64, 1.0, 1.0, 1.0);
    let cases = [
        (
            Request {
                start: f64::NAN,
                ..ok
            },
            PlanError::NonFinite { field: "start" },
        ),
        (
            Request {
                target_velocity: f64::INFINITY,
                ..ok
            },
            PlanError::NonFinite {
                field: "target_velocity",
            },
        ),
        (
            Request {
                max_deceleration: Some(f64::NAN),
                ..ok
            },
            PlanError::NonFinite {
                field: "max_deceleration",
            },
        ),
        (
            Request {
                max_velocity: 0.0,
                ..ok
            },
            PlanError::NotPositive {
                field: "max_velocity",
                value: 0.0,
            },
        ),
        (
            Request {
                max_acceleration: -1.0,
                ..ok
            },
            PlanError::NotPositive {
                field: "max_acceleration",
                value: -1.0,
            },
        ),
        (
            ok.with_max_deceleration(0.0),
            PlanError::NotPositive {
                field: "max_deceleration",
                value: 0.0,
            },
        ),
        (
            ok.with_velocities(0.0, 1.5),
            PlanError::TargetVelocityTooHigh {
                value: 1.5,
                max: 1.0,
            },
        ),
    ];
    for (req, err) in cases {
        assert_eq!(plan_trapezoidal(&req), Err(err));
    }
    assert_eq!(
        PlanError::NotPositive {
            field: "max_velocity",
            value: 0.0
        }
        .to_string(),
        "max_velocity must be > 0 (got 0)"
    );
    // Finite inputs whose profile is not: a huge distance at a tiny speed.
    assert_eq!(
        plan_trapezoidal(&Request::new(-1e300f64, 1e300, 1e-300, 1.0)),
        Err(PlanError::Unrepresentable)
    );
}

#[test]
fn profiles_are_small() {
    assert!(
        core::mem::size_of::<Profile<f32>>() <= 144,
        "{}",
        core::mem::size_of::<Profile<f32>>()
    );
    assert!(
        core::mem::size_of::<Profile<f64>>() <= 288,
        "{}",
        core::mem::size_of::<Profile<f64>>()
    );
}

#[test]
fn ticks_cover_the_move_without_drift() {
    let p = plan_trapezoidal(&Request::new(0.0f64, 90.0, 100.0, 500.0)).unwrap();
    let tick = core::num::NonZeroU64::new(1000).unwrap(); // 1 ms
    let samples: Vec<(u64, State<f64>)> = p.ticks(tick).collect();
    assert_eq!(samples.len(), 1101);
    assert_eq!(samples[0].0, 0);
    assert_eq!(samples[1100].0, 1_100_000);
    assert_eq!(samples[1100].1.position, 90.0);
    // Each tick's time is exact, not accumulated.
    assert_eq!(samples[700].1, p.sample(0.7));
}

// ---- a seeded random sweep ------------------------------------------------

/// The time-optimal rest-to-rest duration, derived independently.
fn rest_to_rest_duration(dist: f64, vmax: f64, acc: f64, dec: f64) -> f64 {
    let c = 0.5 / acc + 0.5 / dec;
    if dist >= vmax * vmax * c {
        vmax / acc + vmax / dec + (dist - vmax * vmax * c) / vmax
    } else {
        let vp = (dist / c).sqrt();
        vp / acc + vp / dec
    }
}

fn check(req: &Request<f64>, p: &Profile<f64>) {
    let (vmax, acc) = (req.max_velocity, req.max_acceleration);
    let dec = req.max_deceleration.unwrap_or(acc);
    let rel = 1e-9;
    let scale = req.start.abs().max(req.target.abs()).max(1.0);
    let ((lo, _), (hi, _)) = p.position_extremes();
    let extent = scale.max(lo.abs()).max(hi.abs());
    let mut state = State {
        position: req.start,
        velocity: req.start_velocity,
        ..State::default()
    };
    let mut braking_from_above = req.start_velocity.abs() > vmax;
    for ph in p.phases() {
        let s = ph.start;
        assert!(ph.duration > 0.0 && ph.duration.is_finite(), "{req:?}");
        // Continuity with the previous phase's end.
        assert!(
            (s.position - state.position).abs() <= 1e-12 * extent,
            "{req:?}"
        );
        assert!(close(s.velocity, state.velocity, 1e-9), "{req:?}");
        let end_v = s.velocity + s.acceleration * ph.duration;
        // Phases never cross zero velocity, so each is speeding up or slowing down.
        assert!(
            s.velocity * end_v >= -1e-12 * vmax * vmax,
            "{req:?} {s:?} -> {end_v}"
        );
        let speeding = end_v.abs() > s.velocity.abs();
        let limit = if speeding { acc } else { dec };
        assert!(s.acceleration.abs() <= limit * (1.0 + rel), "{req:?} {s:?}");
        if braking_from_above {
            assert!(!speeding, "{req:?}");
            if end_v.abs() <= vmax * (1.0 + rel) {
                braking_from_above = false;
            }
        } else {
            assert!(end_v.abs() <= vmax * (1.0 + rel), "{req:?}");
            assert!(s.velocity.abs() <= vmax * (1.0 + rel), "{req:?}");
        }
        state = State {
            position: s.position + ph.duration * (s.velocity + ph.duration * s.acceleration * 0.5),
            velocity: end_v,
            ..State::default()
        };
    }
    // The integrated end is the target, to 1e-8 of the motion's extent (a
    // move that brakes from 1000 at 0.01 spans 5e7 units; f64 resolves 1e-8
    // of that, not 1e-8 absolute).
    let tol_p = 1e-8 * extent;
    assert!(
        (state.position - req.target).abs() <= tol_p,
        "{req:?}: {} vs {}",
        state.position,
        req.target
    );
    assert!(close(state.velocity, req.target_velocity, 1e-8), "{req:?}");
    let end = p.sample(p.duration());
    assert_eq!(
        (end.position, end.velocity),
        (req.target, req.target_velocity)
    );
}

#[test]
fn random_requests_respect_every_limit_and_end_exactly() {
    let mut rng = Rng(0x7472_6170_657a_6f69);
    let n = cases();
    let (mut overshoots, mut rest) = (0, 0);
    for _ in 0..n {
        let req = random_request(&mut rng);
        let p = match plan_trapezoidal(&req) {
            Ok(p) => p,
            Err(e) => panic!("{req:?}: {e}"),
        };
        check(&req, &p);
        let forbid = plan_trapezoidal(&req.with_overshoot(Overshoot::Forbid));
        match p.overshoot() {
            Some(by) => {
                overshoots += 1;
                assert_eq!(forbid, Err(PlanError::OvershootForbidden { overshoot: by }));
            }
            None => assert_eq!(forbid, Ok(p)),
        }
        if req.start_velocity == 0.0 && req.target_velocity == 0.0 {
            rest += 1;
            let d = (req.target - req.start).abs();
            let t = rest_to_rest_duration(
                d,
                req.max_velocity,
                req.max_acceleration,
                req.max_deceleration.unwrap(),
            );
            assert!(
                close(p.duration(), t, 1e-12),
                "{req:?}: {} vs {t}",
                p.duration()
            );
            assert_eq!(p.overshoot(), None);
        }
    }
    eprintln!("{n} random requests: {overshoots} overshoot, {rest} rest-to-rest");
    assert!(overshoots > n / 50 && rest > n / 20);
}

#[test]
fn f32_profiles_end_within_relative_1e_5() {
    let mut rng = Rng(0x6633_3220_7461_7065);
    for _ in 0..20_000 {
        let r = random_request(&mut rng);
        let req = common::to_f32(&r);
        let p = plan_trapezoidal(&req).unwrap();
        let ((lo, _), (hi, _)) = p.position_extremes();
        let extent = f64::from(
            req.start
                .abs()
                .max(req.target.abs())
                .max(lo.abs())
                .max(hi.abs()),
        )
        .max(1.0);
        let tol = 1e-5 * extent;
        // Each phase, evaluated to its end from its stored start state, meets
        // the next phase's start; the last one meets the target.
        let phases: Vec<Phase<f32>> = p.phases().collect();
        for (i, ph) in phases.iter().enumerate() {
            let (d, s) = (f64::from(ph.duration), ph.start);
            let end_p = f64::from(s.position)
                + d * (f64::from(s.velocity) + d * f64::from(s.acceleration) * 0.5);
            let end_v = f64::from(s.velocity) + d * f64::from(s.acceleration);
            let (want_p, want_v) = match phases.get(i + 1) {
                Some(next) => (
                    f64::from(next.start.position),
                    f64::from(next.start.velocity),
                ),
                None => (f64::from(req.target), f64::from(req.target_velocity)),
            };
            assert!(
                (end_p - want_p).abs() <= tol,
                "{req:?}: phase {i} ends at {end_p}, not {want_p}"
            );
            let v_scale = f64::from(req.max_velocity.max(req.start_velocity.abs()));
            assert!(
                (end_v - want_v).abs() <= 1e-5 * v_scale,
                "{req:?}: phase {i} velocity {end_v} vs {want_v}"
            );
        }
        assert!(p.duration().is_finite());
    }
}
