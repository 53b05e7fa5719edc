//! The planner: `sample` against a bare cubic (the arithmetic any sampler
//! must do) in the same run; `plan_trapezoidal` on seeded random inputs; and
//! `plan_scurve` against rsruckig (the pure-Rust port of Ruckig) on the same
//! random inputs, rest-to-rest and full-state sets separately.
//!
//! `cargo bench -p motorwire-benches --bench planner`
#![allow(
    missing_docs,
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing
)]

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use motorwire_planner::{Request, plan_scurve, plan_trapezoidal};
use rsruckig::prelude::*;

struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * ((self.next() >> 11) as f64 / (1u64 << 53) as f64)
    }
}

fn requests(full_state: bool) -> Vec<Request<f64>> {
    let mut rng = Rng(if full_state { 2 } else { 1 });
    (0..1024)
        .map(|_| {
            let vmax = rng.range(10.0, 200.0);
            let r = Request::new(
                rng.range(-180.0, 180.0),
                rng.range(-180.0, 180.0),
                vmax,
                rng.range(50.0, 2000.0),
            )
            .with_max_deceleration(rng.range(50.0, 2000.0));
            if full_state {
                r.with_velocities(rng.range(-vmax, vmax), rng.range(-vmax, vmax))
            } else {
                r
            }
        })
        .collect()
}

fn planner(c: &mut Criterion) {
    let profile = plan_trapezoidal(&Request::new(0.0f64, 90.0, 100.0, 500.0)).unwrap();
    let times: Vec<f64> = (0..1024).map(|i| 1.1 * f64::from(i) / 1024.0).collect();
    let mut g = c.benchmark_group("planner");
    g.bench_function("cubic_horner_baseline", |b| {
        let mut i = 0usize;
        b.iter(|| {
            i = (i + 1) & 1023;
            let t = black_box(times[i]);
            let (p, v, a, j) = black_box((2.5, 50.0, 500.0, 0.0));
            black_box(p + t * (v + t * (a * 0.5 + t * j / 6.0)))
        })
    });
    g.bench_function("sample", |b| {
        let mut i = 0usize;
        b.iter(|| {
            i = (i + 1) & 1023;
            black_box(&profile).sample(black_box(times[i]))
        })
    });
    let rest = requests(false);
    g.bench_function("plan_trapezoidal_rest_to_rest", |b| {
        let mut i = 0usize;
        b.iter(|| {
            i = (i + 1) & 1023;
            plan_trapezoidal(black_box(&rest[i])).unwrap()
        })
    });
    let full = requests(true);
    g.bench_function("plan_trapezoidal_full_state", |b| {
        let mut i = 0usize;
        b.iter(|| {
            i = (i + 1) & 1023;
            plan_trapezoidal(black_box(&full[i])).unwrap()
        })
    });
    for (name, set) in [("rest_to_rest", &rest), ("full_state", &full)] {
        let jerky: Vec<Request<f64>> = set
            .iter()
            .enumerate()
            .map(|(i, r)| r.with_jerk(1000.0 + 19.0 * i as f64))
            .collect();
        let inputs: Vec<InputParameter<1>> = jerky.iter().map(ruckig_input).collect();
        g.bench_function(format!("plan_scurve_{name}"), |b| {
            let mut i = 0usize;
            b.iter(|| {
                i = (i + 1) & 1023;
                plan_scurve(black_box(&jerky[i])).unwrap()
            })
        });
        let mut otg = Ruckig::<1, IgnoreErrorHandler>::new(None, 0.001);
        let mut traj = Trajectory::new(None);
        g.bench_function(format!("rsruckig_{name}"), |b| {
            let mut i = 0usize;
            b.iter(|| {
                i = (i + 1) & 1023;
                let r = otg.calculate(black_box(&inputs[i]), &mut traj);
                black_box(traj.get_duration());
                r
            })
        });
    }
    g.finish();
}

/// The same move for Ruckig: acceleration towards the target is
/// `max_acceleration`, away from it `max_deceleration`.
fn ruckig_input(r: &Request<f64>) -> InputParameter<1> {
    let mut input = InputParameter::new(None);
    input.current_position[0] = r.start;
    input.target_position[0] = r.target;
    input.current_velocity[0] = r.start_velocity;
    input.target_velocity[0] = r.target_velocity;
    input.max_velocity[0] = r.max_velocity;
    let dec = r.max_deceleration.unwrap_or(r.max_acceleration);
    let (up, down) = if r.target >= r.start {
        (r.max_acceleration, dec)
    } else {
        (dec, r.max_acceleration)
    };
    input.max_acceleration[0] = up;
    input.min_acceleration = Some(daov_stack![-down]);
    input.max_jerk[0] = r.max_jerk.unwrap();
    input
}

criterion_group!(benches, planner);
criterion_main!(benches);
