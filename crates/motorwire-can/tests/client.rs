//! The iRPC client against a scripted joint: msg_ids, matching, retries
//! with the same msg_id, timeouts, and what it makes of odd frames.
#![allow(clippy::unwrap_used, clippy::panic, clippy::indexing_slicing)]

use std::time::Duration;

use motorwire_can::client::{Client, ClientConfig, Completion, Event, FrameError, Outcome};
use motorwire_can::{CanBus, CanId, Error, Frame, SimBus};
use motorwire_irpc::{Header, Message, NackCode, Payload, PayloadKind, TelemetryMode, WireVersion};

fn reply(source: u16, msg_id: u32, payload: Payload) -> Frame {
    let m = Message {
        header: Header {
            source_id: source,
            target_id: 0,
            msg_id,
        },
        payload,
    };
    let mut buf = [0u8; 64];
    let n = m.encode_frame(WireVersion::V2_0, &mut buf).unwrap();
    Frame::fd(CanId::standard(source).unwrap(), &buf[..n]).unwrap()
}

fn completion(client: &mut Client) -> Completion {
    loop {
        match client.poll_event() {
            Some(Event::Completed(c)) => return c,
            Some(_) => {}
            None => panic!("no completion"),
        }
    }
}

fn ms(n: u64) -> Duration {
    Duration::from_millis(n)
}

#[test]
fn requests_get_fresh_ids_and_exact_bytes() {
    let mut c = Client::new(ClientConfig::default()).unwrap();
    assert_eq!(c.configure(ms(0), 0x10).unwrap(), 1);
    // One request in flight per node: the joint's duplicate memory covers its retries.
    assert_eq!(
        c.activate(ms(0), 0x10),
        Err(motorwire_can::Error::InFlightLimit {
            target: 0x10,
            in_flight: 1
        })
    );
    assert_eq!(c.activate(ms(0), 0x11).unwrap(), 2);
    assert_eq!(c.arm_ready().unwrap(), 3);
    assert_eq!(c.poll_transmit().unwrap().data(), &[0x00, 0x10, 0x01, 0x01]);
    assert_eq!(c.poll_transmit().unwrap().data(), &[0x00, 0x11, 0x02, 0x02]);
    // WIRE-FACTS §1.4 has ArmReady with msg_id 0: `00 ff ff 03 00 0a`; here msg_id 3.
    assert_eq!(
        c.poll_transmit().unwrap().data(),
        &[0x00, 0xff, 0xff, 0x03, 0x03, 0x0a]
    );
    assert_eq!(c.in_flight(), 2, "ArmReady expects no answer");
}

#[test]
fn a_retry_keeps_its_msg_id_and_the_fourth_silence_times_out() {
    let mut c = Client::new(ClientConfig::default()).unwrap();
    let id = c.reset(ms(0), 0x10).unwrap();
    let first = c.poll_transmit().unwrap();
    for attempt in 1..=3u64 {
        assert_eq!(c.poll_timeout(), Some(ms(100 * attempt)));
        c.handle_timeout(ms(100 * attempt - 1));
        assert!(c.poll_transmit().is_none(), "not before the deadline");
        c.handle_timeout(ms(100 * attempt));
        assert_eq!(
            c.poll_transmit().unwrap(),
            first,
            "the same frame, the same msg_id"
        );
    }
    c.handle_timeout(ms(400));
    let done = completion(&mut c);
    assert_eq!(
        done,
        Completion {
            msg_id: id,
            target: 0x10,
            kind: PayloadKind::Reset,
            outcome: Outcome::TimedOut,
            attempts: 4,
            sent_at: ms(0),
            finished_at: ms(400)
        }
    );
    assert_eq!(c.stats().retransmissions, 3);
    assert_eq!(c.in_flight(), 0);
}

#[test]
fn acks_and_nacks_match_by_msg_id_and_node() {
    let mut c = Client::new(ClientConfig::default()).unwrap();
    let a = c.configure(ms(0), 0x10).unwrap();
    let b = c.activate(ms(0), 0x11).unwrap();
    // From the wrong node: stray.
    c.handle_frame(ms(1), &reply(0x11, a, Payload::Ack(a)));
    assert!(matches!(c.poll_event(), Some(Event::StrayReply { .. })));
    // Header and payload disagree: stray (one flipped bit cannot fake an Ack).
    c.handle_frame(ms(1), &reply(0x10, a ^ 4, Payload::Ack(a)));
    assert!(matches!(c.poll_event(), Some(Event::StrayReply { .. })));
    c.handle_frame(ms(2), &reply(0x11, b, Payload::Nack { id: b, error: 2 }));
    let nb = completion(&mut c);
    assert_eq!(
        (nb.msg_id, nb.outcome),
        (b, Outcome::Nacked(NackCode::ACTIVATE_WRONG_STATE))
    );
    assert_eq!(
        nb.outcome.to_string(),
        "nacked: 2 (activate in the wrong state)"
    );
    c.handle_frame(ms(3), &reply(0x10, a, Payload::Ack(a)));
    let na = completion(&mut c);
    assert_eq!(
        (na.msg_id, na.outcome, na.finished_at),
        (a, Outcome::Acked, ms(3))
    );
    // A late duplicate Ack: stray, counted.
    c.handle_frame(ms(4), &reply(0x10, a, Payload::Ack(a)));
    assert!(matches!(c.poll_event(), Some(Event::StrayReply { .. })));
    assert_eq!(c.stats().stray_replies, 3);
}

#[test]
fn feedback_undecodable_and_misaddressed_frames_are_events() {
    let mut c = Client::new(ClientConfig::default()).unwrap();
    let enc = Payload::Encoder(motorwire_irpc::EncoderTelemetry {
        position: 1.5,
        velocity: 0.0,
    });
    c.handle_frame(ms(5), &reply(0x10, 9, enc));
    match c.poll_event() {
        Some(Event::Feedback { message, at }) => assert_eq!((message.payload, at), (enc, ms(5))),
        other => panic!("{other:?}"),
    }
    c.handle_frame(
        ms(5),
        &Frame::fd(CanId::standard(0x10).unwrap(), &[0x10, 0x00, 0x01, 0x7f]).unwrap(),
    );
    assert!(matches!(
        c.poll_event(),
        Some(Event::Undecodable {
            error: FrameError::Irpc(motorwire_irpc::Error::UnknownTag { tag: 127, .. }),
            ..
        })
    ));
    let mut wrong_id = reply(0x10, 9, enc);
    wrong_id = Frame::fd(CanId::standard(0x12).unwrap(), wrong_id.data()).unwrap();
    c.handle_frame(ms(5), &wrong_id);
    assert!(matches!(c.poll_event(), Some(Event::Misaddressed { .. })));
    assert_eq!(c.stats().bad_frames, 2);
    // Our own frames heard back (a v2.2 request a v2.0 reading calls bad):
    // counted apart, never reported.
    c.handle_frame(
        ms(5),
        &Frame::fd(CanId::standard(0).unwrap(), &[0x00, 0x33, 0x01, 0x14]).unwrap(),
    );
    assert!(c.poll_event().is_none());
    assert_eq!((c.stats().bad_frames, c.stats().own_frames), (2, 1));
}

#[test]
fn what_a_version_lacks_and_bad_values_are_refused_before_the_bus() {
    let mut c = Client::new(ClientConfig::default()).unwrap();
    let err = c
        .subscribe_telemetry(ms(0), 0x10, TelemetryMode::Periodic, 100, 0.0)
        .unwrap_err();
    assert!(
        matches!(
            err,
            Error::Irpc(motorwire_irpc::Error::PayloadNotInVersion { .. })
        ),
        "{err}"
    );
    let nan = motorwire_irpc::SetTargetPayload {
        target_angle: f32::NAN,
        velocity_limit: 10.0,
    };
    assert!(matches!(
        c.set_target(ms(0), 0x10, nan),
        Err(Error::Irpc(motorwire_irpc::Error::NonFinite { .. }))
    ));
    assert!(c.poll_transmit().is_none());
    assert_eq!(c.in_flight(), 0);
    assert!(
        Client::new(ClientConfig {
            node_id: 0x800,
            ..ClientConfig::default()
        })
        .is_err()
    );
    // v2.1 has telemetry.
    let mut c21 = Client::new(ClientConfig {
        wire: WireVersion::V2_1,
        ..ClientConfig::default()
    })
    .unwrap();
    c21.subscribe_telemetry(ms(0), 0x10, TelemetryMode::Periodic, 100, 0.0)
        .unwrap();
}

#[test]
fn drive_runs_a_request_to_its_end_on_a_blocking_bus() {
    let bus = SimBus::default();
    let (mut arm, mut joint) = (bus.port(), bus.port());
    let mut c = Client::new(ClientConfig::default()).unwrap();
    let id = c.configure(bus.now(), 0x10).unwrap();
    // Nobody answers: four sends, 400 ms of simulated time.
    let clock = || bus.now();
    let done = c.drive(&mut arm, clock, id).unwrap();
    assert_eq!(
        (done.outcome, done.attempts, done.finished_at),
        (Outcome::TimedOut, 4, ms(400))
    );
    let mut sent = 0;
    while joint.recv(Duration::ZERO).is_ok() {
        sent += 1;
    }
    assert_eq!(sent, 4);
    assert_eq!(
        c.drive(&mut arm, clock, id),
        Err(Error::UnknownRequest { msg_id: id })
    );
}

#[test]
fn a_cancelled_request_is_never_sent_again_and_its_answer_is_stray() {
    let mut c = Client::new(ClientConfig::default()).unwrap();
    let id = c.reset(ms(0), 0x10).unwrap();
    assert!(c.cancel(id));
    assert!(!c.cancel(id), "cancelled once");
    assert!(c.poll_transmit().is_none(), "its queued frame is gone too");
    c.handle_timeout(ms(1000));
    assert!(c.poll_transmit().is_none(), "never resent");
    assert!(c.poll_event().is_none(), "and never completed");
    assert!(c.can_request(0x10), "the node's slot is free again");
    let ack = Message {
        header: Header {
            source_id: 0x10,
            target_id: 0,
            msg_id: id,
        },
        payload: Payload::Ack(id),
    };
    c.handle_message(ms(1001), ack);
    assert!(matches!(c.poll_event(), Some(Event::StrayReply { .. })));
}

#[test]
fn each_node_is_spoken_to_and_heard_in_its_own_wire_version() {
    let mut c = Client::new(ClientConfig::default()).unwrap();
    c.set_wire(0x11, WireVersion::V2_1);
    c.set_wire(0x13, WireVersion::V1);
    let a = c.request(ms(0), 0x11, Payload::Activate).unwrap();
    // v1 has no SetTargetV2: refused before anything is queued.
    assert!(
        c.request(
            ms(0),
            0x13,
            Payload::SetTargetV2(motorwire_irpc::SetTargetPayloadV2::trapezoidal(
                1.0, 1.0, 1.0
            ))
        )
        .is_err()
    );
    assert_eq!(c.poll_transmit().unwrap().data(), &[0x00, 0x11, 0x01, 0x02]);
    // Ack(1) from 0x11 in v2.1 (tag 18, WIRE-FACTS §1.4: `10 00 2a 12 2a` for 0x10).
    let frame = Frame::fd(
        CanId::standard(0x11).unwrap(),
        &[0x11, 0x00, 0x01, 0x12, 0x01],
    )
    .unwrap();
    c.handle_frame(ms(1), &frame);
    let done = completion(&mut c);
    assert_eq!((done.msg_id, done.outcome), (a, Outcome::Acked));
    // With several versions spoken, ArmReady goes to each joint in its own
    // version, never as a broadcast: v2.0's broadcast ArmReady (tag 10) is a
    // RequestTelemetry to a v2.1 joint. A joint of the client's own version
    // (v2.0, tag 10) is one of them once named.
    c.set_wire(0x10, WireVersion::V2_0);
    c.arm_ready().unwrap();
    let sent: Vec<Vec<u8>> = std::iter::from_fn(|| c.poll_transmit())
        .map(|f| f.data().to_vec())
        .collect();
    assert_eq!(
        sent,
        [
            vec![0x00, 0x10, 0x03, 0x0a],
            vec![0x00, 0x11, 0x04, 0x14],
            vec![0x00, 0x13, 0x05, 0x09]
        ]
    );
}
