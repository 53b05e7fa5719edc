//! I16F16 conversions at the boundary (feature `fixed`, on in tests).

use motorwire_planner::fixed_point::{FixedRangeError, I16F16, from_i16f16, to_i16f16};
use motorwire_planner::{Request, State, plan};

#[test]
fn conversions_round_to_nearest_and_are_exact_into_f64() {
    // 1.57 * 65536 = 102891.52 -> 102892.
    assert_eq!(to_i16f16(1.57f64, "x"), Ok(I16F16::from_bits(102_892)));
    assert_eq!(to_i16f16(-1.57f32, "x"), Ok(I16F16::from_bits(-102_892)));
    // Ties to even: 0.5 / 65536 -> 0, 1.5 / 65536 -> 2.
    assert_eq!(to_i16f16(0.5f64 / 65536.0, "x"), Ok(I16F16::ZERO));
    assert_eq!(to_i16f16(1.5f64 / 65536.0, "x"), Ok(I16F16::from_bits(2)));
    assert_eq!(
        from_i16f16::<f64>(I16F16::from_bits(102_892)),
        102_892.0 / 65_536.0
    );
    assert_eq!(from_i16f16::<f64>(I16F16::MIN), -32_768.0);
    assert_eq!(from_i16f16::<f64>(I16F16::MAX), 32_768.0 - 1.0 / 65_536.0);
    // f32 keeps 24 significant bits: 32767.99998 rounds to 32768.
    assert_eq!(from_i16f16::<f32>(I16F16::MAX), 32_768.0);
}

#[test]
fn out_of_range_and_non_finite_values_are_refused_naming_the_field() {
    assert_eq!(
        to_i16f16(32_768.0f64, "velocity"),
        Err(FixedRangeError {
            field: "velocity",
            value: 32_768.0
        })
    );
    assert_eq!(to_i16f16(-32_768.0f64, "v"), Ok(I16F16::MIN));
    assert!(
        to_i16f16(f64::NAN, "position").is_err_and(|e| e.field == "position" && e.value.is_nan())
    );
    assert_eq!(
        to_i16f16(f32::INFINITY, "jerk"),
        Err(FixedRangeError {
            field: "jerk",
            value: f64::INFINITY
        })
    );
    let state = State {
        position: 1.0f64,
        velocity: 2.0,
        acceleration: 3.0,
        jerk: 1e5,
    };
    let err = state.to_i16f16().unwrap_err();
    assert_eq!(
        err,
        FixedRangeError {
            field: "jerk",
            value: 1e5
        }
    );
    assert_eq!(
        err.to_string(),
        "jerk = 100000 does not fit I16F16 (finite, within [-32768, 32768))"
    );
}

#[test]
fn a_request_in_i16f16_plans_in_float_and_samples_back() {
    let req = Request::<f64>::from_i16f16(
        I16F16::ZERO,
        I16F16::from_num(1.57),
        I16F16::from_num(1.74),
        I16F16::from_num(8.72),
    )
    .with_jerk(50.0);
    assert_eq!(req.target, 102_892.0 / 65_536.0);
    assert_eq!(req.max_velocity, I16F16::from_num(1.74).to_num::<f64>());
    let profile = plan(&req).unwrap();
    let end = profile.end_state().to_i16f16().unwrap();
    assert_eq!(
        end,
        State {
            position: I16F16::from_bits(102_892),
            velocity: I16F16::ZERO,
            acceleration: I16F16::ZERO,
            jerk: I16F16::ZERO
        }
    );
    // Every sample on a 1 ms tick converts, and matches the float state to
    // within half a step.
    for (_, s) in profile.ticks(core::num::NonZeroU64::new(1000).unwrap()) {
        let f = s.to_i16f16().unwrap();
        assert!((f.position.to_num::<f64>() - s.position).abs() <= 0.5 / 65_536.0);
        assert!((f.velocity.to_num::<f64>() - s.velocity).abs() <= 0.5 / 65_536.0);
        assert_eq!(f.jerk.to_num::<f64>(), s.jerk);
    }
}
