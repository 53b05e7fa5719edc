//! Differential test against `rsruckig`, the pure-Rust port of Ruckig, the
//! field's time-optimal jerk-limited reference: on the moves both planners
//! define the same way (rest-to-rest in both directions, and forward moves
//! with non-negative start and target velocities that need no overshoot),
//! the durations must agree to 1e-9 relative.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing
)]

mod common;

use common::Rng;
use motorwire_planner::{Request, plan_scurve};
use rsruckig::prelude::*;

/// Ruckig's duration for a 1-DoF move, or `None` when it fails. Acceleration
/// towards the target is `acc`, away from it `dec` (Ruckig's
/// `min_acceleration` is the lower bound in absolute terms, so it depends
/// on the direction of the move).
fn ruckig_duration(req: &Request<f64>) -> Option<f64> {
    let (p0, p1, v0, v1) = (
        req.start,
        req.target,
        req.start_velocity,
        req.target_velocity,
    );
    let (vmax, acc, jerk) = (req.max_velocity, req.max_acceleration, req.max_jerk?);
    let dec = req.max_deceleration.unwrap_or(acc);
    let mut otg = Ruckig::<1, ThrowErrorHandler>::new(None, 0.001);
    let mut input = InputParameter::new(None);
    input.current_position[0] = p0;
    input.target_position[0] = p1;
    input.current_velocity[0] = v0;
    input.target_velocity[0] = v1;
    input.max_velocity[0] = vmax;
    let (up, down) = if p1 >= p0 { (acc, dec) } else { (dec, acc) };
    input.max_acceleration[0] = up;
    input.min_acceleration = Some(daov_stack![-down]);
    input.max_jerk[0] = jerk;
    let mut traj = Trajectory::new(None);
    otg.calculate(&input, &mut traj).ok()?;
    Some(traj.get_duration())
}

fn cases() -> usize {
    std::env::var("MOTORWIRE_RUCKIG_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(20_000)
}

struct Stats {
    compared: usize,
    /// Cases where motorwire's profile is shorter than Ruckig's by more
    /// than 1e-9 (each is checked against every limit).
    shorter: usize,
    ruckig_failed: usize,
    worst: f64,
}

fn compare(rng: &mut Rng, stats: &mut Stats, with_velocities: bool) {
    let vmax = rng.log_uniform(-2.0, 3.0);
    let acc = rng.log_uniform(-1.0, 4.0);
    let dec = if rng.unit() < 0.3 {
        acc
    } else {
        rng.log_uniform(-1.0, 4.0)
    };
    let jerk = rng.log_uniform(0.0, 6.0);
    let p0 = rng.range(-100.0, 100.0);
    let dist = rng.log_uniform(-4.0, 3.0);
    let (v0, v1, dir) = if with_velocities {
        (rng.range(0.0, vmax), rng.range(0.0, vmax), 1.0)
    } else {
        (0.0, 0.0, rng.signed())
    };
    let p1 = p0 + dir * dist;
    let req = Request::new(p0, p1, vmax, acc)
        .with_max_deceleration(dec)
        .with_velocities(dir * v0, dir * v1)
        .with_jerk(jerk);
    let ours = plan_scurve(&req).unwrap_or_else(|e| panic!("{req:?}: {e}"));
    if with_velocities {
        // Only moves that need no overshoot and never reverse are compared.
        let (lo, hi) = ours.position_extremes();
        if ours.overshoot().is_some()
            || lo.0 < p0.min(p1) - 1e-12 * (1.0 + dist)
            || hi.0 > p1 + 1e-9
        {
            return;
        }
        if ours.phases().any(|ph| ph.start.velocity < 0.0) {
            return;
        }
    }
    let Some(theirs) = ruckig_duration(&req) else {
        stats.ruckig_failed += 1;
        if stats.ruckig_failed <= 2 {
            eprintln!(
                "Ruckig fails, motorwire plans {} s: {req:?}",
                ours.duration()
            );
        }
        return;
    };
    let rel = (ours.duration() - theirs) / theirs.max(1e-300);
    stats.compared += 1;
    assert!(
        rel <= 1e-9,
        "{req:?}: motorwire {} s, Ruckig {theirs} s (relative {rel:e})",
        ours.duration()
    );
    if rel < -1e-9 {
        // Shorter than the reference: it must still respect every limit.
        common::check_scurve(&req, &ours);
        stats.shorter += 1;
        if stats.shorter <= 3 {
            eprintln!(
                "shorter than Ruckig: {req:?}: {} s vs {theirs} s",
                ours.duration()
            );
        }
    } else {
        stats.worst = stats.worst.max(rel.abs());
    }
}

#[test]
fn rest_to_rest_durations_equal_ruckigs() {
    let mut rng = Rng(0x5eed_0001);
    let mut stats = Stats {
        compared: 0,
        shorter: 0,
        ruckig_failed: 0,
        worst: 0.0,
    };
    for _ in 0..cases() {
        compare(&mut rng, &mut stats, false);
    }
    eprintln!(
        "rest-to-rest: {} compared, Ruckig failed {}, motorwire shorter (and within every limit) {}, worst relative difference otherwise {:e}",
        stats.compared, stats.ruckig_failed, stats.shorter, stats.worst
    );
    assert_eq!(stats.shorter, 0);
    assert!(stats.compared * 10 >= cases() * 9);
}

#[test]
fn forward_moves_with_velocities_equal_ruckigs() {
    let mut rng = Rng(0x5eed_0002);
    let mut stats = Stats {
        compared: 0,
        shorter: 0,
        ruckig_failed: 0,
        worst: 0.0,
    };
    for _ in 0..cases() {
        compare(&mut rng, &mut stats, true);
    }
    eprintln!(
        "with velocities: {} compared, Ruckig failed {}, motorwire shorter (and within every limit) {}, worst relative difference otherwise {:e}",
        stats.compared, stats.ruckig_failed, stats.shorter, stats.worst
    );
    // Ruckig is not time-optimal on a few moves with very unequal
    // acceleration and deceleration limits (a 2e-5 fraction here).
    assert!(stats.shorter * 1000 <= stats.compared);
    assert!(stats.compared * 2 >= cases());
}
