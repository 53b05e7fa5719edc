//! Any finite numbers at all: the planner returns a typed error or a profile
//! whose every phase, sample and extreme is finite. Never a panic, never NaN.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing
)]

use motorwire_planner::*;
use proptest::prelude::*;

fn any_finite() -> impl Strategy<Value = f64> {
    prop_oneof![
        any::<f64>().prop_filter("finite", |v| v.is_finite()),
        Just(0.0),
        Just(-0.0),
        Just(f64::MAX),
        Just(-f64::MAX),
        Just(f64::MIN_POSITIVE),
        Just(5e-324),
        Just(1e-300),
        Just(1e300),
        (-1e3..1e3f64),
    ]
}

fn check(p: &Profile<f64>) {
    assert!(p.duration().is_finite() && p.duration() >= 0.0);
    for ph in p.phases() {
        assert!(ph.duration.is_finite() && ph.duration > 0.0);
        let s = ph.start;
        assert!(s.position.is_finite() && s.velocity.is_finite() && s.acceleration.is_finite());
    }
    for k in 0..=8 {
        let s = p.sample(p.duration() * f64::from(k) / 8.0);
        assert!(
            s.position.is_finite() && s.velocity.is_finite() && s.acceleration.is_finite(),
            "{s:?}"
        );
    }
    let ((lo, _), (hi, _)) = p.position_extremes();
    assert!(lo.is_finite() && hi.is_finite());
    assert!(p.peak_velocity().0.is_finite() && p.peak_acceleration().is_finite());
}

/// Cases per property: all of them in an optimized build (CI runs this file
/// with `--release`), a tenth in a debug build, so that the README's
/// `cargo test` stays quick.
const fn cases(all: u32) -> u32 {
    if cfg!(debug_assertions) {
        all / 10
    } else {
        all
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(cases(20_000)))]

    #[test]
    fn any_finite_request_plans_or_refuses(
        start in any_finite(), target in any_finite(), v0 in any_finite(), v1 in any_finite(),
        vmax in any_finite(), acc in any_finite(), dec in any_finite(), forbid in any::<bool>(),
    ) {
        let req = Request::new(start, target, vmax, acc)
            .with_max_deceleration(dec)
            .with_velocities(v0, v1)
            .with_overshoot(if forbid { Overshoot::Forbid } else { Overshoot::Allow });
        if let Ok(p) = plan_trapezoidal(&req) {
            check(&p);
        }
        let req32 = Request::<f32>::new(start as f32, target as f32, vmax as f32, acc as f32)
            .with_max_deceleration(dec as f32)
            .with_velocities(v0 as f32, v1 as f32);
        if let Ok(p) = plan_trapezoidal(&req32) {
            assert!(p.duration().is_finite());
            for ph in p.phases() {
                assert!(ph.duration.is_finite() && ph.start.position.is_finite() && ph.start.velocity.is_finite());
            }
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(cases(20_000)))]

    #[test]
    fn any_finite_scurve_request_plans_or_refuses(
        start in any_finite(), target in any_finite(), v0 in any_finite(), v1 in any_finite(),
        vmax in any_finite(), acc in any_finite(), dec in any_finite(), jerk in any_finite(),
        forbid in any::<bool>(),
    ) {
        let req = Request::new(start, target, vmax, acc)
            .with_max_deceleration(dec)
            .with_velocities(v0, v1)
            .with_jerk(jerk)
            .with_overshoot(if forbid { Overshoot::Forbid } else { Overshoot::Allow });
        if let Ok(p) = plan_scurve(&req) {
            check(&p);
        }
        let req32 = Request::<f32>::new(start as f32, target as f32, vmax as f32, acc as f32)
            .with_max_deceleration(dec as f32)
            .with_velocities(v0 as f32, v1 as f32)
            .with_jerk(jerk as f32);
        if let Ok(p) = plan_scurve(&req32) {
            assert!(p.duration().is_finite());
            for ph in p.phases() {
                assert!(ph.duration.is_finite() && ph.start.position.is_finite() && ph.start.velocity.is_finite());
            }
        }
    }
}
