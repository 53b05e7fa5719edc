//! The planner: `sample` against a bare cubic (the arithmetic any sampler
//! must do) in the same run, and `plan_trapezoidal` on seeded random inputs.
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
use motorwire_planner::{Request, plan_trapezoidal};

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
    g.finish();
}

criterion_group!(benches, planner);
criterion_main!(benches);
