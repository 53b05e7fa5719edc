//! Differential test against Ruckig itself (the C++ library, through its
//! Python package 0.19.4): motorwire's `plan_scurve` duration on seeded
//! random full-state requests (start and target velocities anywhere in
//! ±max_velocity, deceleration equal to acceleration) must never exceed
//! Ruckig's time-optimal duration by more than 1e-9 relative; where it is
//! shorter, the profile is sampled and checked against every limit and the
//! target. Each request rounded to f32 is planned in f32 and in f64 (from
//! the same rounded inputs): the f32 duration must not exceed the f64 one
//! by more than 1e-5.
//!
//! Ruckig's durations come from a file `tools/ruckig_reference.py` writes:
//!
//! ```sh
//! python3 -m venv target/ruckig-venv && target/ruckig-venv/bin/pip install ruckig==0.19.4
//! target/ruckig-venv/bin/python crates/motorwire-planner/tools/ruckig_reference.py \
//!     --seed 17 --count 100000 > target/ruckig.csv
//! MOTORWIRE_RUCKIG_PY_REFERENCE=target/ruckig.csv \
//!     cargo test --release -p motorwire-planner --test ruckig_reference -- --ignored --nocapture
//! ```
//!
//! The test is ignored by default (a machine without Python has no
//! reference), and run with `--ignored` it fails when the variable is not
//! set: it never reports a comparison it did not make. `.ci/run` runs it on
//! 100,000 requests.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing
)]

mod common;

use motorwire_planner::{Profile, Request, plan_scurve};

/// How much longer than Ruckig motorwire may be, relative.
const LONGER: f64 = 1e-9;

/// How much longer an f32 profile may be than the f64 one of the same
/// (rounded) request: f32 finds its roots to a few of its ulps.
const LONGER_F32: f64 = 1e-5;

/// One line of the reference file.
struct Case {
    req: Request<f64>,
    ruckig: f64,
}

fn parse(line: &str, number: usize) -> Option<Case> {
    let line = line.trim();
    if line.is_empty() || line.starts_with('#') {
        return None;
    }
    let fields: Vec<f64> = line
        .split(',')
        .map(|f| {
            f.parse()
                .unwrap_or_else(|e| panic!("line {number}: {f:?}: {e}"))
        })
        .collect();
    let [p0, p1, v0, v1, vmax, acc, jerk, duration] = fields[..] else {
        panic!("line {number}: expected 8 fields, got {}", fields.len());
    };
    Some(Case {
        req: Request::new(p0, p1, vmax, acc)
            .with_velocities(v0, v1)
            .with_jerk(jerk),
        ruckig: duration,
    })
}

/// Samples `p` on 2,000 instants and its phase ends: velocity,
/// acceleration and jerk within the limits (relative 1e-9), position and
/// velocity continuous between consecutive samples as the limits allow, and
/// the end state the target.
fn sample_check(req: &Request<f64>, p: &Profile<f64>) {
    let (vmax, acc) = (req.max_velocity, req.max_acceleration);
    let jerk = req.max_jerk.unwrap();
    let tol = 1e-9;
    let t_end = p.duration();
    let n = 2000;
    let mut times: Vec<f64> = (0..=n)
        .map(|i| t_end * f64::from(i) / f64::from(n))
        .collect();
    for ph in p.phases() {
        times.push(ph.start_time);
        times.push(ph.start_time + ph.duration);
    }
    times.sort_by(f64::total_cmp);
    let mut prev: Option<(f64, motorwire_planner::State<f64>)> = None;
    for t in times {
        let s = p.sample(t);
        assert!(
            s.velocity.abs() <= vmax * (1.0 + tol),
            "{req:?} at {t}: {s:?}"
        );
        assert!(
            s.acceleration.abs() <= acc * (1.0 + tol),
            "{req:?} at {t}: {s:?}"
        );
        assert!(s.jerk.abs() <= jerk * (1.0 + tol), "{req:?} at {t}: {s:?}");
        if let Some((t0, s0)) = prev {
            let dt = t - t0;
            let dv = (s.velocity - s0.velocity).abs();
            let dp = (s.position - s0.position).abs();
            assert!(dv <= acc * dt * (1.0 + tol) + 1e-9 * vmax, "{req:?} at {t}");
            assert!(
                dp <= vmax * dt * (1.0 + tol) + 1e-9 * (1.0 + s.position.abs()),
                "{req:?} at {t}"
            );
        }
        prev = Some((t, s));
    }
    let end = p.sample(t_end);
    assert_eq!(
        (end.position, end.velocity),
        (req.target, req.target_velocity)
    );
    // The last phase, integrated, arrives where the end state says.
    common::check_scurve(req, p);
}

#[test]
#[ignore = "needs Ruckig's durations: MOTORWIRE_RUCKIG_PY_REFERENCE=file (see the module docs)"]
fn never_longer_than_ruckig() {
    let path = std::env::var("MOTORWIRE_RUCKIG_PY_REFERENCE")
        .expect("MOTORWIRE_RUCKIG_PY_REFERENCE names the file tools/ruckig_reference.py wrote");
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
    let (mut cases, mut longer, mut shorter, mut ruckig_failed) = (0usize, 0usize, 0usize, 0usize);
    let (mut worst, mut worst_case) = (0.0f64, None);
    let (mut worst_f32, mut longer_f32) = (0.0f64, 0usize);
    let mut failures = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let Some(case) = parse(line, i + 1) else {
            continue;
        };
        cases += 1;
        let req = case.req;
        let ours = plan_scurve(&req).unwrap_or_else(|e| panic!("{req:?}: {e}"));
        if !case.ruckig.is_finite() {
            // Ruckig found no profile; motorwire's must still be valid.
            ruckig_failed += 1;
            sample_check(&req, &ours);
            continue;
        }
        // f32: the request rounded to f32 is another request (a distance of
        // 2e-4 at position 50 moves by 2%), whose time-optimal duration is
        // that of the f64 planner, just checked against Ruckig: the f32
        // planner must find the same profile, to f32's precision.
        let req32 = common::to_f32(&req);
        if let (Ok(p32), Ok(p64)) = (plan_scurve(&req32), plan_scurve(&common::to_f64(&req32))) {
            let r32 = f64::from(p32.duration()) / p64.duration();
            worst_f32 = worst_f32.max(r32);
            if r32 > 1.0 + LONGER_F32 {
                longer_f32 += 1;
                if failures.len() < 20 {
                    failures.push(format!(
                        "f32 {req32:?}: motorwire {} s in f32, {} s in f64",
                        p32.duration(),
                        p64.duration()
                    ));
                }
            }
        }
        let ratio = ours.duration() / case.ruckig;
        if ratio > worst {
            worst = ratio;
            worst_case = Some((req, ours.duration(), case.ruckig));
        }
        if ratio > 1.0 + LONGER {
            longer += 1;
            if failures.len() < 20 {
                failures.push(format!(
                    "{req:?}: motorwire {} s, Ruckig {} s",
                    ours.duration(),
                    case.ruckig
                ));
            }
        } else if ratio < 1.0 - LONGER {
            shorter += 1;
            sample_check(&req, &ours);
        }
    }
    #[allow(clippy::cast_precision_loss)]
    let share = |n: usize| 100.0 * n as f64 / cases.max(1) as f64;
    println!(
        "ruckig reference: {cases} cases, worst ratio motorwire/Ruckig {worst:.15}, longer than Ruckig by more than 1e-9: {longer} ({:.3}%), shorter (and checked by sampling): {shorter} ({:.3}%), Ruckig failed: {ruckig_failed}",
        share(longer),
        share(shorter),
    );
    println!(
        "ruckig reference: f32 against f64 on the rounded requests: worst ratio {worst_f32:.9}, longer by more than {LONGER_F32:e}: {longer_f32}"
    );
    if let Some((req, ours, theirs)) = worst_case {
        println!("ruckig reference: worst case {req:?}: motorwire {ours} s, Ruckig {theirs} s");
    }
    for f in &failures {
        println!("longer: {f}");
    }
    assert!(cases >= 1, "{path} holds no cases");
    assert_eq!(
        longer, 0,
        "{longer} of {cases} requests are longer than Ruckig's"
    );
}
