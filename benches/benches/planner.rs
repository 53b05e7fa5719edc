//! The planner: `sample` against a bare cubic (the arithmetic any sampler
//! must do) in the same run; `plan_trapezoidal` on seeded random inputs; and
//! `plan_scurve` against rsruckig (the pure-Rust port of Ruckig) on the same
//! random inputs, rest-to-rest and full-state sets separately; Ruckig
//! itself (C++, through its Python package) on the same full-state
//! requests when `MOTORWIRE_RUCKIG_PYTHON` names a Python that has
//! `ruckig` 0.19.4; and the latency distribution of exact-duration planning
//! (p50, p99, p99.9 and max of 100,000 seeded requests, each timed alone).
//!
//! `cargo bench -p motorwire-benches --bench planner`
//! (`MOTORWIRE_RUCKIG_PYTHON=target/ruckig-venv/bin/python` to add Ruckig)
#![allow(
    missing_docs,
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use std::hint::black_box;
use std::io::Write;
use std::process::{Command, Stdio};
use std::time::Instant;

use criterion::{Criterion, criterion_group, criterion_main};
use motorwire_planner::{
    PlanError, Request, minimum_duration, plan_scurve, plan_trapezoidal, plan_with_duration,
};
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
    fn unit(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }
    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }
}

/// Whether criterion measures (`cargo bench`) rather than runs each
/// benchmark once (`cargo test --benches` passes no `--bench`).
fn measuring() -> bool {
    std::env::args().any(|a| a == "--bench")
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
    let mut full_jerky = Vec::new();
    for (name, set) in [("rest_to_rest", &rest), ("full_state", &full)] {
        let jerky: Vec<Request<f64>> = set
            .iter()
            .enumerate()
            .map(|(i, r)| r.with_jerk(1000.0 + 19.0 * i as f64))
            .collect();
        let inputs: Vec<InputParameter<1>> = jerky.iter().map(ruckig_input).collect();
        if name == "full_state" {
            full_jerky.clone_from(&jerky);
        }
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
    ruckig_python(&full_jerky);
    exact_duration_latency(if measuring() { 100_000 } else { 2_000 });
}

/// Times Ruckig (C++, through its Python package) on `requests` with
/// `tools/ruckig_reference.py --time`, when `MOTORWIRE_RUCKIG_PYTHON` names
/// a Python that has it; prints the script's line (the time per call
/// includes Python's overhead of the call and of building Ruckig's result).
fn ruckig_python(requests: &[Request<f64>]) {
    let Ok(python) = std::env::var("MOTORWIRE_RUCKIG_PYTHON") else {
        println!("planner/ruckig_python_full_state: not measured (set MOTORWIRE_RUCKIG_PYTHON)");
        return;
    };
    let script = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../crates/motorwire-planner/tools/ruckig_reference.py"
    );
    let passes = if measuring() { "200" } else { "1" };
    let mut child = Command::new(python)
        .args([script, "--time", passes])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .spawn()
        .expect("MOTORWIRE_RUCKIG_PYTHON runs");
    let mut stdin = child.stdin.take().unwrap();
    for r in requests {
        let i = ruckig_input(r);
        writeln!(
            stdin,
            "{:?},{:?},{:?},{:?},{:?},{:?},{:?},{:?}",
            i.current_position[0],
            i.target_position[0],
            i.current_velocity[0],
            i.target_velocity[0],
            i.max_velocity[0],
            i.max_acceleration[0],
            i.min_acceleration.as_ref().unwrap()[0],
            i.max_jerk[0]
        )
        .unwrap();
    }
    drop(stdin);
    let out = child.wait_with_output().unwrap();
    assert!(out.status.success(), "{script} --time failed");
    print!("planner/{}", String::from_utf8_lossy(&out.stdout));
}

/// The latency distribution of `plan_with_duration`: `n` seeded random
/// full-state S-curve requests (the full-state set's ranges, jerk 1000 to
/// 20,000), each asked for its minimum duration times a factor uniform in
/// [1, 4]; each call timed alone, three times, the fastest kept (so a
/// preemption of the benchmark is not counted as the planner's).
fn exact_duration_latency(n: usize) {
    let mut rng = Rng(17);
    let mut ns = Vec::with_capacity(n);
    let (mut met, mut blocked) = (0usize, 0usize);
    for _ in 0..n {
        let vmax = rng.range(10.0, 200.0);
        let req = Request::new(
            rng.range(-180.0, 180.0),
            rng.range(-180.0, 180.0),
            vmax,
            rng.range(50.0, 2000.0),
        )
        .with_max_deceleration(rng.range(50.0, 2000.0))
        .with_velocities(rng.range(-vmax, vmax), rng.range(-vmax, vmax))
        .with_jerk(rng.range(1000.0, 20000.0));
        let t = minimum_duration(&req).unwrap() * (1.0 + 3.0 * rng.unit());
        let mut best = u128::MAX;
        for _ in 0..3 {
            let start = Instant::now();
            let r = plan_with_duration(black_box(&req), black_box(t));
            best = best.min(start.elapsed().as_nanos());
            match black_box(r) {
                Ok(_) => met += 1,
                Err(PlanError::DurationBlocked { .. }) => blocked += 1,
                Err(e) => panic!("{req:?} in {t} s: {e}"),
            }
        }
        ns.push(best);
    }
    ns.sort_unstable();
    let at = |q: f64| ns[((ns.len() - 1) as f64 * q).round() as usize];
    let (p50, max) = (at(0.5), ns[ns.len() - 1]);
    println!(
        "planner/plan_with_duration latency over {n} requests ({} met, {} blocked): p50 {p50} ns, p99 {} ns, p99.9 {} ns, max {max} ns ({:.1}x the median)",
        met / 3,
        blocked / 3,
        at(0.99),
        at(0.999),
        max as f64 / p50.max(1) as f64
    );
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
