//! The simulated joint's behaviour, request by request, on the rig.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing
)]

use std::time::Duration;

use motorwire_can::client::{ClientConfig, Event, Outcome};
use motorwire_can::{CanId, Frame, SimConfig};
use motorwire_irpc::{
    LifecycleState, NackCode, Payload, SetTargetPayloadV2, TelemetryMode, WireVersion,
};
use motorwire_sim::rig::Rig;
use motorwire_sim::{JointConfig, WATCHDOG_STOP};

const J: u16 = 0x10;

fn rig(wire: WireVersion) -> Rig {
    let client = ClientConfig {
        wire,
        ..ClientConfig::default()
    };
    let joint = JointConfig {
        wire,
        ..JointConfig::new(J)
    };
    Rig::new(SimConfig::default(), client, [joint]).unwrap()
}

fn outcome(rig: &mut Rig, p: Payload) -> Outcome {
    rig.request(J, p).unwrap().outcome
}

fn nack(code: NackCode) -> Outcome {
    Outcome::Nacked(code)
}

fn to(target: f32) -> Payload {
    Payload::SetTargetV2(SetTargetPayloadV2::scurve(target, 100.0, 500.0, 2000.0))
}

#[test]
fn the_lifecycle_and_its_nack_codes() {
    let mut r = rig(WireVersion::V2_0);
    assert_eq!(
        outcome(&mut r, Payload::Activate),
        nack(NackCode::ACTIVATE_WRONG_STATE)
    );
    assert_eq!(
        outcome(&mut r, Payload::Deactivate),
        nack(NackCode::DEACTIVATE_WRONG_STATE)
    );
    assert_eq!(
        outcome(&mut r, to(10.0)),
        nack(NackCode::SET_TARGET_WRONG_STATE)
    );
    assert_eq!(outcome(&mut r, Payload::Configure), Outcome::Acked);
    assert_eq!(r.joint(J).unwrap().state(), LifecycleState::Inactive);
    assert_eq!(
        outcome(&mut r, to(10.0)),
        nack(NackCode::SET_TARGET_WRONG_STATE)
    );
    assert_eq!(outcome(&mut r, Payload::Activate), Outcome::Acked);
    assert_eq!(
        outcome(&mut r, Payload::Configure),
        nack(NackCode::CONFIGURE_WRONG_STATE)
    );
    assert_eq!(
        outcome(&mut r, Payload::ArmReady),
        Outcome::TimedOut,
        "a broadcast gets no answer"
    );
    assert_eq!(
        outcome(
            &mut r,
            Payload::Encoder(motorwire_irpc::EncoderTelemetry {
                position: 0.0,
                velocity: 0.0
            })
        ),
        Outcome::TimedOut,
        "telemetry is not a request: no answer"
    );
    assert_eq!(outcome(&mut r, Payload::Reset), Outcome::Acked);
    assert_eq!(r.joint(J).unwrap().state(), LifecycleState::Unconfigured);
    // A request the joint does not implement (v2.1's adaptive status).
    let mut r = rig(WireVersion::V2_1);
    assert_eq!(
        outcome(&mut r, Payload::RequestAdaptiveStatus),
        nack(NackCode::UNKNOWN_PAYLOAD)
    );
}

#[test]
fn moves_are_acked_planned_and_refused_outside_the_limits() {
    let mut r = rig(WireVersion::V2_0);
    r.joint_mut(J).unwrap().set_watchdog(Duration::ZERO);
    for p in [Payload::Configure, Payload::Activate] {
        assert_eq!(outcome(&mut r, p), Outcome::Acked);
    }
    assert_eq!(outcome(&mut r, to(90.0)), Outcome::Acked);
    let t0 = r.bus().now();
    r.run_until(t0 + Duration::from_millis(700)).unwrap();
    let mid = r.joint(J).unwrap().position();
    assert!(mid > 10.0 && mid < 80.0, "{mid}");
    r.run_until(t0 + Duration::from_secs(2)).unwrap();
    assert_eq!(r.joint(J).unwrap().position(), 90.0);
    assert!(!r.joint(J).unwrap().is_moving());
    // Outside ±180, faster than 360 deg/s, a zero acceleration: Nack 16.
    assert_eq!(outcome(&mut r, to(181.0)), nack(NackCode::OUT_OF_LIMITS));
    let Payload::SetTargetV2(mut fast) = to(0.0) else {
        unreachable!()
    };
    fast.max_velocity = 400.0;
    assert_eq!(
        outcome(&mut r, Payload::SetTargetV2(fast)),
        nack(NackCode::OUT_OF_LIMITS)
    );
    fast.max_velocity = 100.0;
    fast.max_acceleration = 0.0;
    assert_eq!(
        outcome(&mut r, Payload::SetTargetV2(fast)),
        nack(NackCode::OUT_OF_LIMITS)
    );
    assert_eq!(r.joint(J).unwrap().stats().executed, 1);
}

#[test]
fn a_nan_target_is_nacked_by_its_msg_id() {
    let mut joint = motorwire_sim::SimJoint::new(JointConfig::new(J)).unwrap();
    // SetTarget {NaN, 150} from the arm, msg_id 5 (WIRE-FACTS' vector with the angle made NaN).
    let bytes = [
        0x00, 0x10, 0x05, 0x00, 0x00, 0x00, 0xc0, 0x7f, 0x00, 0x00, 0x16, 0x43,
    ];
    let frame = Frame::fd(CanId::standard(0).unwrap(), &bytes).unwrap();
    assert_eq!(joint.handle_frame(Duration::ZERO, &frame), None);
    // Nack {5, 17} from 0x10 to the arm.
    assert_eq!(
        joint.poll_transmit().unwrap().data(),
        &[0x10, 0x00, 0x05, 0x09, 0x05, 0x11]
    );
    // A frame that does not decode at all is dropped and counted.
    let junk = Frame::fd(CanId::standard(0).unwrap(), &[0x00, 0x10, 0x06, 0x7f]).unwrap();
    assert_eq!(joint.handle_frame(Duration::ZERO, &junk), None);
    assert!(joint.poll_transmit().is_none());
    assert_eq!(joint.stats().bad_frames, 1);
}

#[test]
fn a_repeated_msg_id_is_answered_again_and_not_executed_again() {
    let mut joint = motorwire_sim::SimJoint::new(JointConfig::new(J)).unwrap();
    let arm = CanId::standard(0).unwrap();
    let frame = |bytes: &[u8]| Frame::fd(arm, bytes).unwrap();
    // Configure (msg_id 1) twice: one state change, two identical Acks.
    let first = joint.handle_frame(Duration::ZERO, &frame(&[0x00, 0x10, 0x01, 0x01]));
    assert_eq!(first.map(|e| e.answer), Some(Payload::Ack(1)));
    let out: Vec<Frame> = std::iter::from_fn(|| joint.poll_transmit()).collect();
    assert_eq!(out.len(), 2, "JointStatus (state changed) and the Ack");
    assert_eq!(
        joint.handle_frame(Duration::ZERO, &frame(&[0x00, 0x10, 0x01, 0x01])),
        None
    );
    assert_eq!(
        joint.poll_transmit().unwrap().data(),
        &[0x10, 0x00, 0x01, 0x08, 0x01]
    );
    assert!(joint.poll_transmit().is_none());
    assert_eq!(joint.stats().duplicates, 1);
    assert_eq!(joint.stats().acked, 1);
}

#[test]
fn the_watchdog_brakes_a_move_the_host_stopped_feeding() {
    let mut r = rig(WireVersion::V2_0);
    for p in [Payload::Configure, Payload::Activate] {
        assert_eq!(outcome(&mut r, p), Outcome::Acked);
    }
    let moved = r.request(J, to(150.0)).unwrap();
    assert_eq!(moved.outcome, Outcome::Acked);
    // The joint heard the command when it acked it.
    let t0 = moved.finished_at;
    r.run_until(t0 + Duration::from_millis(199)).unwrap();
    assert_eq!(r.joint(J).unwrap().stats().watchdog_stops, 0);
    r.run_until(t0 + Duration::from_millis(400)).unwrap();
    let j = r.joint(J).unwrap();
    assert_eq!(j.stats().watchdog_stops, 1);
    assert!(!j.is_moving(), "stopped within 200 ms of braking");
    let stopped_at = j.position();
    assert!(stopped_at > 0.0 && stopped_at < 30.0, "{stopped_at}");
    let statuses: Vec<u16> = r
        .take_events()
        .into_iter()
        .filter_map(|e| match e {
            Event::Feedback { message, .. } => match message.payload {
                Payload::JointStatus { error_code, .. } => Some(error_code),
                _ => None,
            },
            _ => None,
        })
        .collect();
    assert!(statuses.contains(&WATCHDOG_STOP), "{statuses:?}");
    // Re-sending the move in progress is the keep-alive: a fed move arrives.
    assert_eq!(outcome(&mut r, to(20.0)), Outcome::Acked);
    let t1 = r.bus().now();
    while r.bus().now() < t1 + Duration::from_secs(2) {
        assert_eq!(outcome(&mut r, to(20.0)), Outcome::Acked);
        let next = r.bus().now() + Duration::from_millis(100);
        r.run_until(next).unwrap();
    }
    assert_eq!(r.joint(J).unwrap().position(), 20.0);
    assert_eq!(r.joint(J).unwrap().stats().watchdog_stops, 1);
    assert_eq!(
        r.joint(J).unwrap().stats().executed,
        2,
        "keep-alives do not replan"
    );
}

#[test]
fn telemetry_streams_at_the_subscribed_rate_from_v2_1() {
    let mut r = rig(WireVersion::V2_1);
    for p in [Payload::Configure, Payload::Activate] {
        assert_eq!(outcome(&mut r, p), Outcome::Acked);
    }
    let now = r.bus().now();
    let id = r
        .client
        .subscribe_telemetry(now, J, TelemetryMode::Periodic, 100, 0.0)
        .unwrap();
    r.run_until(now + Duration::from_millis(500)).unwrap();
    let events = r.take_events();
    assert!(events.iter().any(
        |e| matches!(e, Event::Completed(c) if c.msg_id == id && c.outcome == Outcome::Acked)
    ));
    let samples = events
        .iter()
        .filter(|e| matches!(e, Event::Feedback { message, .. } if matches!(message.payload, Payload::TelemetryStream(_))))
        .count();
    assert!(
        (49..=51).contains(&samples),
        "{samples} samples in 500 ms at 100 Hz"
    );
    assert_eq!(outcome(&mut r, Payload::RequestTelemetry), Outcome::Acked);
    let rate = Payload::ConfigureTelemetry(motorwire_irpc::ConfigureTelemetryPayload {
        mode: TelemetryMode::Streaming,
        rate_hz: 5000,
        change_threshold: 0.0,
    });
    assert_eq!(outcome(&mut r, rate), nack(NackCode::OUT_OF_LIMITS));
}

/// Two joints on one bus: each one's Acks and Encoder frames go to the arm
/// (node 0x0000), which the other also takes as broadcast. Neither answers
/// them (an earlier version Nacked them with 255, and the two joints then
/// Nacked each other's Nacks without end).
#[test]
fn joints_never_answer_each_others_answers_or_telemetry() {
    let joints = [JointConfig::new(0x10), JointConfig::new(0x11)];
    let mut r = Rig::new(SimConfig::default(), ClientConfig::default(), joints).unwrap();
    for node in [0x10, 0x11] {
        assert_eq!(
            r.request(node, Payload::Configure).unwrap().outcome,
            Outcome::Acked
        );
        assert_eq!(
            r.request(node, Payload::Activate).unwrap().outcome,
            Outcome::Acked
        );
    }
    r.run_until(Duration::from_millis(500)).unwrap();
    for node in [0x10, 0x11] {
        let stats = r.joint(node).unwrap().stats();
        assert_eq!((stats.acked, stats.nacked), (2, 0), "node {node:#x}");
    }
    let strays = r
        .take_events()
        .into_iter()
        .filter(|e| matches!(e, Event::StrayReply { .. }))
        .count();
    assert_eq!(strays, 0);
}

/// Sends `payload` from the arm with `msg_id` straight to `joint`; the
/// answer it gives (executed or not), and whether it executed.
fn raw(joint: &mut motorwire_sim::SimJoint, msg_id: u32, payload: Payload) -> (Payload, bool) {
    use motorwire_irpc::{Header, MAX_FRAME_LEN, Message};
    let msg = Message {
        header: Header {
            source_id: 0,
            target_id: J,
            msg_id,
        },
        payload,
    };
    let mut buf = [0u8; MAX_FRAME_LEN];
    let len = msg.encode_frame(WireVersion::V2_0, &mut buf).unwrap();
    let frame = Frame::fd(CanId::standard(0).unwrap(), &buf[..len]).unwrap();
    let executed = joint.handle_frame(Duration::ZERO, &frame).is_some();
    let mut answer = None;
    while let Some(f) = joint.poll_transmit() {
        if let Ok(m) = Message::decode_frame(WireVersion::V2_0, f.data())
            && matches!(m.payload, Payload::Ack(_) | Payload::Nack { .. })
        {
            answer = Some(m.payload);
        }
    }
    (answer.unwrap(), executed)
}

#[test]
fn a_late_copy_older_than_the_whole_memory_is_refused_never_executed() {
    use motorwire_sim::{DEDUP_WINDOW, RESTART_SPAN};
    let mut joint = motorwire_sim::SimJoint::new(JointConfig::new(J)).unwrap();
    assert_eq!(
        raw(&mut joint, 1, Payload::Configure),
        (Payload::Ack(1), true)
    );
    assert_eq!(
        raw(&mut joint, 2, Payload::Activate),
        (Payload::Ack(2), true)
    );
    let last = 2 + u32::try_from(DEDUP_WINDOW).unwrap() + 50;
    for id in 3..=last {
        assert_eq!(raw(&mut joint, id, to(10.0)), (Payload::Ack(id), true));
    }
    let stale = |id| Payload::Nack {
        id,
        error: NackCode::STALE_REQUEST.0,
    };
    // Its answer is forgotten, and it is older than every answer kept: a
    // late copy, refused.
    assert_eq!(raw(&mut joint, 10, to(-50.0)), (stale(10), false));
    // The newest is still remembered: answered again, not executed again.
    assert_eq!(raw(&mut joint, last, to(10.0)), (Payload::Ack(last), false));
    // A move far behind is still a late copy, never a restart.
    let far = 2u32.wrapping_sub(RESTART_SPAN + 10);
    assert_eq!(raw(&mut joint, far, to(-50.0)), (stale(far), false));
    assert_eq!(joint.stats().stale, 2);
    assert_eq!(joint.stats().duplicates, 1);
    // A Reset far behind the last lifecycle request is a sender that
    // started again: executed, and its new requests are obeyed.
    assert_eq!(
        raw(&mut joint, far - 1, Payload::Reset),
        (Payload::Ack(far - 1), true)
    );
    assert_eq!(
        raw(&mut joint, far, Payload::Configure),
        (Payload::Ack(far), true)
    );
    // A Reset only a little behind is a late copy.
    assert_eq!(
        raw(&mut joint, far - 5, Payload::Reset),
        (stale(far - 5), false)
    );
}

#[test]
fn a_deactivate_brakes_at_the_emergency_deceleration_not_at_once() {
    let mut joint = motorwire_sim::SimJoint::new(JointConfig {
        emergency_deceleration: 500.0,
        watchdog: Duration::ZERO, // no host heartbeats here
        ..JointConfig::new(J)
    })
    .unwrap();
    assert_eq!(
        raw(&mut joint, 1, Payload::Configure),
        (Payload::Ack(1), true)
    );
    assert_eq!(
        raw(&mut joint, 2, Payload::Activate),
        (Payload::Ack(2), true)
    );
    // A long move at 100 deg/s, reached after 0.2 s at 500 deg/s².
    assert_eq!(
        raw(
            &mut joint,
            3,
            Payload::SetTargetV2(SetTargetPayloadV2::trapezoidal(170.0, 100.0, 500.0))
        ),
        (Payload::Ack(3), true)
    );
    let mut t = Duration::ZERO;
    while t < Duration::from_millis(500) {
        t += Duration::from_millis(1);
        joint.handle_timeout(t);
        while joint.poll_transmit().is_some() {}
    }
    let at_stop = joint.position();
    assert!(
        (joint.velocity() - 100.0).abs() < 1e-6,
        "{}",
        joint.velocity()
    );
    let frame = |bytes: Vec<u8>| Frame::fd(CanId::standard(0).unwrap(), &bytes).unwrap();
    let mut buf = [0u8; motorwire_irpc::MAX_FRAME_LEN];
    let msg = motorwire_irpc::Message {
        header: motorwire_irpc::Header {
            source_id: 0,
            target_id: J,
            msg_id: 4,
        },
        payload: Payload::Deactivate,
    };
    let len = msg.encode_frame(WireVersion::V2_0, &mut buf).unwrap();
    joint.handle_frame(t, &frame(buf[..len].to_vec())).unwrap();
    // Still moving 0.1 s later, at half speed; at rest after 0.2 s, 10°
    // (v²/2a) past where the stop came.
    joint.handle_timeout(t + Duration::from_millis(100));
    assert!(
        (joint.velocity() - 50.0).abs() < 1e-6,
        "{}",
        joint.velocity()
    );
    joint.handle_timeout(t + Duration::from_millis(250));
    assert_eq!(joint.velocity(), 0.0);
    assert!(
        (joint.position() - (at_stop + 10.0)).abs() < 1e-6,
        "{} {}",
        joint.position(),
        at_stop
    );
}
