//! Phase synchronization: one straight line in joint space, every axis within
//! its own limits, all arriving together.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing
)]

mod common;

use common::Rng;
use motorwire_planner::*;

#[test]
fn random_groups_move_on_a_line_within_every_limit() {
    let mut rng = Rng(0x7379_6e63);
    for _ in 0..5_000 {
        let n = 1 + (rng.next() % 6) as usize;
        let axes: Vec<Request<f64>> = (0..n)
            .map(|_| {
                let start = rng.range(-180.0, 180.0);
                let target = if rng.next().is_multiple_of(8) {
                    start
                } else {
                    rng.range(-180.0, 180.0)
                };
                let acc = rng.range(10.0, 1000.0);
                Request::new(start, target, rng.range(1.0, 200.0), acc)
                    .with_max_deceleration(rng.range(10.0, 1000.0))
            })
            .collect();
        let mut out = vec![Profile::at_rest(0.0); n];
        let duration = synchronize_phases(&axes, &mut out).unwrap();
        let slowest = axes
            .iter()
            .map(|r| plan_trapezoidal(r).unwrap().duration())
            .fold(0.0, f64::max);
        assert!(
            duration >= slowest * (1.0 - 1e-12),
            "{duration} < {slowest}"
        );
        for (req, p) in axes.iter().zip(&out) {
            let d = req.target - req.start;
            if d == 0.0 {
                assert_eq!(p.phase_count(), 0);
                continue;
            }
            assert!((p.duration() - duration).abs() <= 1e-9 * duration);
            let end = p.sample(duration);
            assert_eq!((end.position, end.velocity), (req.target, 0.0));
            let (peak_v, _) = p.peak_velocity();
            assert!(peak_v <= req.max_velocity * (1.0 + 1e-9));
            for ph in p.phases() {
                let a = ph.start.acceleration;
                let v_end = ph.start.velocity + a * ph.duration;
                let limit = if v_end.abs() > ph.start.velocity.abs() {
                    req.max_acceleration
                } else {
                    req.max_deceleration.unwrap()
                };
                assert!(a.abs() <= limit * (1.0 + 1e-9), "{a} > {limit}");
            }
        }
        // The same fraction of every move at every instant: a straight line.
        for k in 0..=20 {
            let t = duration * f64::from(k) / 20.0;
            let mut fraction: Option<f64> = None;
            for (req, p) in axes.iter().zip(&out) {
                let d = req.target - req.start;
                if d == 0.0 {
                    continue;
                }
                let f = (p.sample(t).position - req.start) / d;
                match fraction {
                    None => fraction = Some(f),
                    Some(g) => assert!((f - g).abs() < 1e-9, "t={t}: {f} vs {g}"),
                }
            }
        }
    }
}

#[test]
fn mismatched_slots_moving_starts_and_bad_axes_are_refused() {
    let axes = [
        Request::new(0.0f64, 1.0, 1.0, 1.0),
        Request::new(0.0, 2.0, 1.0, 1.0),
    ];
    let mut one = [Profile::at_rest(0.0)];
    assert_eq!(
        synchronize_phases(&axes, &mut one),
        Err(PlanError::AxisCountMismatch {
            requests: 2,
            profiles: 1
        })
    );
    let moving = [axes[0], axes[1].with_velocities(0.5, 0.0)];
    let mut two = [Profile::at_rest(0.0); 2];
    assert_eq!(
        synchronize_phases(&moving, &mut two),
        Err(PlanError::NotAtRest { axis: 1 })
    );
    let bad = [
        axes[0],
        Request {
            max_velocity: -1.0,
            ..axes[1]
        },
    ];
    assert_eq!(
        synchronize_phases(&bad, &mut two),
        Err(PlanError::NotPositive {
            field: "max_velocity",
            value: -1.0
        })
    );
}

#[test]
fn nothing_to_move_takes_no_time() {
    let axes = [
        Request::new(3.0f64, 3.0, 1.0, 1.0),
        Request::new(-1.0, -1.0, 1.0, 1.0),
    ];
    let mut out = [Profile::at_rest(0.0); 2];
    assert_eq!(synchronize_phases(&axes, &mut out), Ok(0.0));
    assert_eq!(out[0].sample(1.0).position, 3.0);
    assert_eq!(out[1].sample(1.0).position, -1.0);
    assert_eq!(synchronize_phases::<f64>(&[], &mut []), Ok(0.0));
}

#[test]
fn the_binding_limits_can_come_from_different_axes() {
    // Axis 0 is limited by velocity, axis 1 by acceleration: together they
    // are slower than either alone, and each still respects its own limits.
    let axes = [
        Request::new(0.0f64, 100.0, 10.0, 1000.0),
        Request::new(0.0, 100.0, 1000.0, 10.0),
    ];
    let mut out = [Profile::at_rest(0.0); 2];
    let d = synchronize_phases(&axes, &mut out).unwrap();
    let alone: Vec<f64> = axes
        .iter()
        .map(|r| plan_trapezoidal(r).unwrap().duration())
        .collect();
    assert!(d > alone[0] && d > alone[1], "{d} {alone:?}");
    // Normalized limits: v 0.1/s, a 0.1/s²: 1 s up, 9 s cruise, 1 s down.
    assert!((d - 11.0).abs() < 1e-12, "{d}");
}
