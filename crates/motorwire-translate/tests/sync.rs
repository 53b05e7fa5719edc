//! Synchronized multi-axis moves on iRPC joints.
#![allow(clippy::unwrap_used, clippy::panic, clippy::indexing_slicing)]

use motorwire_irpc::Payload;
use motorwire_planner::{Request, plan};
use motorwire_translate::*;
use motorwire_wia::MultiAxisCommand;

fn demo() -> BusMap {
    BusMap::from_toml(include_str!("../../../fixtures/maps/demo-arm.toml")).unwrap()
}

fn doc_example() -> MultiAxisCommand {
    serde_json::from_str(include_str!(
        "../../../fixtures/wia/valid/doc-3.2-multi-axis-command.json"
    ))
    .unwrap()
}

fn at_zero(_: &str) -> Option<f64> {
    Some(0.0)
}

/// The duration each joint's own f32 plan takes for its SetTargetV2.
fn arrivals(m: &MultiAxisMove, starts: &[f32]) -> Vec<f64> {
    m.commands
        .iter()
        .zip(starts)
        .map(|(c, &start)| {
            let Payload::SetTargetV2(p) = c.payloads[0] else {
                panic!()
            };
            let mut r = Request::new(start, p.target_angle, p.max_velocity, p.max_acceleration)
                .with_max_deceleration(p.max_deceleration);
            if p.max_jerk > 0.0 {
                r = r.with_jerk(p.max_jerk);
            }
            f64::from(plan(&r).unwrap().duration())
        })
        .collect()
}

#[test]
fn the_documents_example_arrives_together_in_2_s() {
    let t = multi_axis_to_irpc(&demo(), &doc_example(), &at_zero).unwrap();
    let m = &t.value;
    assert_eq!(m.duration, Some(2.0));
    let nodes: Vec<u16> = m.commands.iter().map(|c| c.node).collect();
    assert_eq!(nodes, [0x10, 0x11, 0x12]);
    for a in arrivals(m, &[0.0, 0.0, 0.0]) {
        assert!((a - 2.0).abs() <= SYNC_TOLERANCE_S, "{a}");
    }
    // Every joint cruises slower than it was allowed to, and that is said.
    for (c, limit) in m.commands.iter().zip([60.0f32, 60.0, 90.0]) {
        let Payload::SetTargetV2(p) = c.payloads[0] else {
            panic!()
        };
        assert!(p.max_velocity < limit, "{}", p.max_velocity);
    }
    let lowered = t
        .report
        .losses
        .iter()
        .filter(|l| l.field.ends_with(".max_velocity"))
        .count();
    assert_eq!(lowered, 3);
    assert!(t.report.losses.iter().any(|l| l.to_string()
        == "coordination.acceleration_profile: dropped: each joint plans its own profile; only the arrival time is shared"));
}

#[test]
fn without_a_duration_the_slowest_joint_sets_it() {
    let mut cmd = doc_example();
    cmd.coordination = None;
    let starts = |m: &str| match m {
        "shoulder_pitch" => Some(-80.0),
        "shoulder_roll" => Some(10.0),
        _ => Some(5.0),
    };
    let t = multi_axis_to_irpc(&demo(), &cmd, &starts).unwrap();
    let d = t.value.duration.unwrap();
    let got = arrivals(&t.value, &[-80.0, 10.0, 5.0]);
    for a in &got {
        assert!((a - d).abs() <= SYNC_TOLERANCE_S, "{got:?} vs {d}");
    }
    // shoulder_pitch moves 125 deg at 60 deg/s: the slowest, unchanged.
    let Payload::SetTargetV2(p) = t.value.commands[0].payloads[0] else {
        panic!()
    };
    assert_eq!(p.max_velocity, 60.0);
    assert!(d > 125.0 / 60.0);
}

#[test]
fn infeasible_and_unknown_are_refused() {
    let mut cmd = doc_example();
    cmd.coordination.as_mut().unwrap().total_duration_ms = Some(500.0);
    let err = multi_axis_to_irpc(&demo(), &cmd, &at_zero).unwrap_err();
    // The elbow's 90 deg at 90 deg/s (500 up, 400 down, jerk 2000) is the
    // slowest.
    assert_eq!(
        err.to_string(),
        "coordination.total_duration_ms 500 is shorter than elbow needs: 1424.6 ms"
    );
    let unknown = multi_axis_to_irpc(&demo(), &doc_example(), &|m| (m != "elbow").then_some(0.0))
        .unwrap_err();
    assert_eq!(
        unknown,
        Refusal::UnknownPosition {
            motor: "elbow".into()
        }
    );
    let mut outside = doc_example();
    outside.motors[2].setpoint = 170.0;
    assert_eq!(
        multi_axis_to_irpc(&demo(), &outside, &at_zero)
            .unwrap_err()
            .to_string(),
        "elbow: setpoint 170 is outside max_position (bus map) 150"
    );
}

#[test]
fn independent_axes_translate_one_by_one() {
    let mut cmd = doc_example();
    cmd.sync_mode = None;
    cmd.coordination = None;
    let t = multi_axis_to_irpc(&demo(), &cmd, &|_| None).unwrap();
    assert_eq!(t.value.duration, None);
    let Payload::SetTargetV2(p) = t.value.commands[2].payloads[0] else {
        panic!()
    };
    assert_eq!((p.target_angle, p.max_velocity), (90.0, 90.0));
    assert!(
        t.report
            .losses
            .iter()
            .any(|l| l.to_string() == "elbow.pid_gains: dropped: SetTargetV2 has no place for it")
    );
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig { cases: 256, failure_persistence: None, ..Default::default() })]
    /// From any state, moving or not (the demo arm's shoulder and elbow,
    /// anywhere in their range, at any velocity and acceleration within
    /// their limits), a
    /// simultaneous move is either refused or arrives together: each
    /// joint's own plan of its `SetTargetV2`, from the state it was given,
    /// takes the promised duration within `SYNC_TOLERANCE_S`.
    #[test]
    fn from_any_state_a_synchronized_move_arrives_together_or_is_refused(
        pitch in -80.0f64..80.0, pitch_v in -100.0f64..100.0, pitch_to in -85.0f64..85.0,
        elbow in 5.0f64..145.0, elbow_v in -100.0f64..100.0, elbow_to in 5.0f64..145.0,
        pitch_a in -400.0f64..400.0, elbow_a in -400.0f64..400.0,
    ) {
        arrives_together_or_is_refused((pitch, pitch_v, pitch_a, pitch_to), (elbow, elbow_v, elbow_a, elbow_to))?;
    }
}

/// A state the property test found: the elbow's velocity limit lowered to
/// 0.0016 deg/s, where its f32 plan (which the check used) took the
/// promised 1.2521 s and its f64 plan (the simulated joint's) 1.2532 s.
/// Both are checked now: it is refused.
#[test]
fn a_state_whose_f32_and_f64_plans_disagree_is_refused() {
    let pitch = (0.0, 88.37794325078501, 302.54455752177114, 0.0);
    let elbow = (
        90.60553973575252,
        71.33523397978058,
        -58.303768453875094,
        102.22483585314292,
    );
    arrives_together_or_is_refused(pitch, elbow).unwrap();
}

/// The property: from (position, velocity, acceleration) to a target for
/// the shoulder and the elbow, a simultaneous move is either refused or
/// arrives together: each joint's own plan of its `SetTargetV2`, from the
/// state it was given (in f64, as the simulated joint plans it), takes the
/// promised duration within `SYNC_TOLERANCE_S`.
fn arrives_together_or_is_refused(
    (pitch, pitch_v, pitch_a, pitch_to): (f64, f64, f64, f64),
    (elbow, elbow_v, elbow_a, elbow_to): (f64, f64, f64, f64),
) -> Result<(), proptest::test_runner::TestCaseError> {
    let cmd: MultiAxisCommand = serde_json::from_value(serde_json::json!({
        "command_id": "c", "timestamp": 1, "sync_mode": "simultaneous",
        "motors": [
            {"motor_id": "shoulder_pitch", "control_mode": "position", "setpoint": pitch_to},
            {"motor_id": "elbow", "control_mode": "position", "setpoint": elbow_to},
        ]
    }))
    .unwrap();
    let state = |m: &str| {
        Some(if m == "elbow" {
            (elbow, elbow_v, elbow_a)
        } else {
            (pitch, pitch_v, pitch_a)
        })
    };
    match multi_axis_to_irpc_from(&demo(), &cmd, &state) {
        Ok(t) => {
            let duration = t.value.duration.unwrap();
            for (c, (x, v, a)) in t
                .value
                .commands
                .iter()
                .zip([(pitch, pitch_v, pitch_a), (elbow, elbow_v, elbow_a)])
            {
                let Payload::SetTargetV2(p) = c.payloads[0] else {
                    panic!()
                };
                let own = plan(&p.planner_request(x, v).with_start_acceleration(a))
                    .unwrap()
                    .duration();
                proptest::prop_assert!(
                    (own - duration).abs() <= SYNC_TOLERANCE_S,
                    "{own} s, promised {duration} s: {p:?}"
                );
            }
        }
        Err(Refusal::Unsynchronizable { .. } | Refusal::PathOutsideLimit { .. }) => {}
        Err(other) => proptest::prop_assert!(false, "{other}"),
    }
    Ok(())
}
