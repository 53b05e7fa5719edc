//! Messages over one CAN-FD frame: the segmented transfer's exact frames,
//! the client's send and receive paths, and every way a transfer can go
//! wrong.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing
)]

use std::time::Duration;

use motorwire_can::client::{Client, ClientConfig, Event, FrameError, Outcome};
use motorwire_can::isotp::IsoTpError;
use motorwire_can::segmented::{LinkEvent, Links, segmented_ids};
use motorwire_can::{CanId, Error, Frame};
use motorwire_irpc::{
    FaultHistory, FaultRecord, Header, Message, Payload, PayloadKind, WireVersion,
};

fn ms(n: u64) -> Duration {
    Duration::from_millis(n)
}

/// The longest FaultHistory node 0x33 can send the arm: every varint at
/// its widest (144 bytes; the 148 of WIRE-FACTS §1.5 needs node ids over
/// 0x7FF, which a CAN id cannot carry).
fn longest_fault_history() -> Message {
    let mut records = [FaultRecord::default(); 10];
    for (i, r) in records.iter_mut().enumerate() {
        *r = FaultRecord {
            fault_type: 4 + (i as u8 % 2),
            timestamp_sec: u32::MAX - i as u32,
            vbus_mv: u16::MAX,
            current_ma: u16::MAX - i as u16,
            temp_c: -1 - i as i8,
        };
    }
    Message {
        header: Header {
            source_id: 0x33,
            target_id: 0x0000,
            msg_id: 0xF000_0001,
        },
        payload: Payload::FaultHistory(FaultHistory {
            records,
            total_faults: u32::MAX,
            valid_count: 10,
        }),
    }
}

fn encode(m: &Message, wire: WireVersion) -> Vec<u8> {
    let mut buf = vec![0u8; 256];
    let n = m.encode(wire, &mut buf).unwrap();
    buf.truncate(n);
    buf
}

fn hex(f: &Frame) -> String {
    f.to_string()
}

fn v22_client() -> Client {
    Client::new(ClientConfig {
        wire: WireVersion::V2_2,
        ..ClientConfig::default()
    })
    .unwrap()
}

#[test]
fn the_longest_fault_history_travels_in_exactly_these_frames() {
    let message = longest_fault_history();
    let bytes = encode(&message, WireVersion::V2_2);
    assert_eq!(bytes.len(), 144);
    let mut joint = Links::new(0x33, Duration::from_secs(1)).unwrap();
    let mut arm = v22_client();
    joint
        .send_message(Duration::ZERO, 0x0000, bytes.clone(), None)
        .unwrap();

    // First frame: 0x1000_0000 | (0x000 << 11) | 0x033, PCI 0x1 and the
    // 12-bit length 0x090, then the first 62 bytes: the header 33 00
    // 81 80 80 80 0F (msg_id 0xF000_0001), tag 0x18 (v2.2 FaultHistory),
    // the records (04, FF FF FF FF 0F, FF FF 03, FF FF 03, FF)...
    let first = joint.poll_transmit().unwrap();
    assert_eq!(joint.poll_transmit(), None, "nothing before flow control");
    assert_eq!(first.id(), CanId::extended(0x1000_0033).unwrap());
    assert!(first.is_fd() && first.len() == 64);
    assert_eq!(
        hex(&first),
        "10000033##110903300818080800F1804FFFFFFFF0FFFFF03FFFF03FF05FEFFFFFF0FFFFF03FEFF03FE04FDFFFFFF0FFFFF03FDFF03FD05FCFFFFFF0FFFFF03FCFF03FC04FB"
    );
    assert_eq!(&first.data()[2..], &bytes[..62]);

    // The arm answers with flow control on the swapped id:
    // 0x1000_0000 | (0x033 << 11) | 0x000; continue, no block size, no
    // separation time; a 3-byte FD frame.
    arm.handle_frame(ms(1), &first);
    let fc = arm.poll_transmit().unwrap();
    assert_eq!(arm.poll_transmit(), None);
    assert_eq!(hex(&fc), "10019800##1300000");
    assert_eq!(fc.id(), segmented_ids(0x33, 0).unwrap().flow_control);

    // Two consecutive frames: 63 bytes, then the last 19 (20 with the PCI,
    // an FD length: no padding).
    joint.handle_frame(ms(2), &fc);
    let cf1 = joint.poll_transmit().unwrap();
    let cf2 = joint.poll_transmit().unwrap();
    assert_eq!(joint.poll_transmit(), None);
    assert_eq!(
        hex(&cf1),
        "10000033##121FFFFFF0FFFFF03FBFF03FB05FAFFFFFF0FFFFF03FAFF03FA04F9FFFFFF0FFFFF03F9FF03F905F8FFFFFF0FFFFF03F8FF03F804F7FFFFFF0FFFFF03F7FF03F7"
    );
    assert_eq!(
        hex(&cf2),
        "10000033##12205F6FFFFFF0FFFFF03F6FF03F6FFFFFFFF0F0A"
    );
    assert_eq!(
        [&first.data()[2..], &cf1.data()[1..], &cf2.data()[1..]].concat(),
        bytes
    );
    assert_eq!(
        joint.poll_event(),
        Some(LinkEvent::Sent { peer: 0, tag: None })
    );

    arm.handle_frame(ms(3), &cf1);
    assert_eq!(arm.poll_event(), None);
    arm.handle_frame(ms(3), &cf2);
    match arm.poll_event() {
        Some(Event::Feedback { message: m, at }) => {
            assert_eq!(m, message);
            assert_eq!(at, ms(3));
        }
        other => panic!("{other:?}"),
    }
    assert_eq!(arm.stats().segmented_received, 1);
    assert_eq!(arm.stats().bad_frames, 0);
    assert_eq!(arm.poll_timeout(), None, "nothing left in progress");
}

#[test]
fn a_message_that_fits_64_bytes_stays_one_plain_frame() {
    let mut c = v22_client();
    // RequestFaultHistory to 0x33: 4 bytes, the standard id of the sender.
    c.request(Duration::ZERO, 0x33, Payload::RequestFaultHistory)
        .unwrap();
    let f = c.poll_transmit().unwrap();
    assert_eq!(hex(&f), "000##100330117");
    assert_eq!(c.poll_transmit(), None);
}

/// A client and a bare peer (Links) at node 0x20 that acks what it
/// reassembles.
#[test]
fn a_long_request_is_segmented_and_its_retry_resends_the_same_bytes_from_a_new_first_frame() {
    let mut c = v22_client();
    let mut peer = Links::new(0x20, Duration::from_secs(1)).unwrap();
    let mut history = longest_fault_history();
    history.header = Header {
        source_id: 0,
        target_id: 0x20,
        msg_id: 1,
    };
    let id = c.request(Duration::ZERO, 0x20, history.payload).unwrap();
    assert_eq!(id, 1);
    let expected = encode(&history, WireVersion::V2_2);
    assert!(expected.len() > 64);
    // The first try's first frame is lost.
    let lost = c.poll_transmit().unwrap();
    assert_eq!(lost.id(), CanId::extended(0x1001_0000).unwrap());
    assert_eq!(c.poll_transmit(), None);
    assert_eq!(c.poll_timeout(), Some(ms(100)));
    // Its timeout: the same bytes again, from a new first frame.
    c.handle_timeout(ms(100));
    let again = c.poll_transmit().unwrap();
    assert_eq!(again, lost);
    peer.handle_frame(ms(101), &again);
    let fc = peer.poll_transmit().unwrap();
    c.handle_frame(ms(102), &fc);
    let mut n = 0;
    while let Some(cf) = c.poll_transmit() {
        peer.handle_frame(ms(103), &cf);
        n += 1;
    }
    assert_eq!(n, 2);
    match peer.poll_event() {
        Some(LinkEvent::Message {
            source,
            can_id,
            bytes,
        }) => {
            assert_eq!((source, can_id.raw()), (0, 0x1001_0000));
            assert_eq!(bytes, expected, "the same msg_id, the same bytes");
        }
        other => panic!("{other:?}"),
    }
    let ack = Message {
        header: Header {
            source_id: 0x20,
            target_id: 0,
            msg_id: 1,
        },
        payload: Payload::Ack(1),
    };
    let mut buf = [0u8; 64];
    let n = ack.encode_frame(WireVersion::V2_2, &mut buf).unwrap();
    c.handle_frame(
        ms(104),
        &Frame::fd(CanId::standard(0x20).unwrap(), &buf[..n]).unwrap(),
    );
    match c.poll_event() {
        Some(Event::Completed(done)) => {
            assert_eq!(
                (done.msg_id, done.kind, done.outcome, done.attempts),
                (1, PayloadKind::FaultHistory, Outcome::Acked, 2)
            );
        }
        other => panic!("{other:?}"),
    }
    let s = c.stats();
    assert_eq!((s.segmented_sent, s.retransmissions, s.acked), (1, 1, 1));
}

#[test]
fn a_long_message_to_a_node_over_0x7ff_is_refused_before_the_bus() {
    let mut c = v22_client();
    let payload = longest_fault_history().payload;
    assert_eq!(
        c.request(Duration::ZERO, 0x800, payload),
        Err(Error::SegmentedNode { node: 0x800 })
    );
    assert_eq!(
        c.send(0xFFFF, payload),
        Err(Error::SegmentedNode { node: 0xFFFF })
    );
    assert_eq!(c.poll_transmit(), None);
    assert_eq!(c.in_flight(), 0);
}

#[test]
fn a_segmented_request_that_is_never_answered_times_out_and_stops() {
    let mut c = v22_client();
    let id = c
        .request(Duration::ZERO, 0x20, longest_fault_history().payload)
        .unwrap();
    let mut t = Duration::ZERO;
    let mut first_frames = 0;
    loop {
        while let Some(f) = c.poll_transmit() {
            assert_eq!(
                f.data()[0] >> 4,
                1,
                "only first frames: no flow control came"
            );
            first_frames += 1;
        }
        if let Some(Event::Completed(done)) = c.poll_event() {
            assert_eq!(
                (done.msg_id, done.outcome, done.attempts),
                (id, Outcome::TimedOut, 4)
            );
            break;
        }
        t = c.poll_timeout().unwrap();
        c.handle_timeout(t);
    }
    assert_eq!(first_frames, 4);
    assert_eq!(t, ms(400));
    assert_eq!(
        c.poll_timeout(),
        None,
        "the abandoned transfer is forgotten"
    );
    assert_eq!(c.poll_transmit(), None);
}

fn first_frame(len: usize, data: &[u8]) -> Frame {
    let mut d = vec![0x10 | (len >> 8) as u8, len as u8];
    d.extend_from_slice(&data[..62]);
    Frame::fd(CanId::extended(0x1000_0033).unwrap(), &d).unwrap()
}

fn consecutive(sn: u8, data: &[u8]) -> Frame {
    let mut d = vec![0x20 | sn];
    d.extend_from_slice(data);
    Frame::fd(CanId::extended(0x1000_0033).unwrap(), &d).unwrap()
}

fn undecodable(c: &mut Client) -> FrameError {
    loop {
        match c.poll_event() {
            Some(Event::Undecodable { can_id, error }) => {
                assert_eq!(can_id.raw(), 0x1000_0033);
                return error;
            }
            Some(_) => {}
            None => panic!("no Undecodable event"),
        }
    }
}

#[test]
fn malformed_transfers_are_typed_events_and_the_client_keeps_working() {
    let mut c = v22_client();
    let bytes = encode(&longest_fault_history(), WireVersion::V2_2);

    // Truncated: the first frame and one consecutive frame, then silence.
    c.handle_frame(ms(0), &first_frame(bytes.len(), &bytes));
    assert_eq!(c.poll_transmit().unwrap().data(), [0x30, 0, 0]);
    c.handle_frame(ms(1), &consecutive(1, &bytes[62..125]));
    assert_eq!(c.poll_timeout(), Some(ms(1001)));
    c.handle_timeout(ms(1001));
    assert_eq!(
        undecodable(&mut c),
        FrameError::Transfer(IsoTpError::Timeout {
            waiting_for: "consecutive frame"
        })
    );

    // Out of sequence: consecutive frame 2 where 1 was due.
    c.handle_frame(ms(2000), &first_frame(bytes.len(), &bytes));
    c.handle_frame(ms(2001), &consecutive(2, &bytes[62..125]));
    assert_eq!(
        undecodable(&mut c),
        FrameError::Transfer(IsoTpError::WrongSequence {
            expected: 1,
            got: 2
        })
    );
    // A consecutive frame with no transfer in progress is ignored.
    c.handle_frame(ms(2002), &consecutive(1, &bytes[62..125]));
    assert_eq!(c.poll_event(), None);

    // A first frame claiming 4 GiB - 1: refused with flow status overflow.
    let mut huge = vec![0x10, 0x00, 0xFF, 0xFF, 0xFF, 0xFF];
    huge.extend_from_slice(&bytes[..58]);
    while c.poll_transmit().is_some() {}
    c.handle_frame(
        ms(3000),
        &Frame::fd(CanId::extended(0x1000_0033).unwrap(), &huge).unwrap(),
    );
    assert_eq!(
        undecodable(&mut c),
        FrameError::Transfer(IsoTpError::TooLong {
            len: 0xFFFF_FFFF,
            max: 256
        })
    );
    let overflow = c.poll_transmit().unwrap();
    assert_eq!(hex(&overflow), "10019800##1320000");

    // Garbage that reassembles: 100 bytes of 0xFF are no iRPC message.
    let garbage = [0xFFu8; 100];
    c.handle_frame(ms(4000), &first_frame(100, &garbage));
    c.handle_frame(ms(4001), &consecutive(1, &garbage[62..]));
    let error = Message::decode(WireVersion::V2_2, &garbage).unwrap_err();
    assert_eq!(undecodable(&mut c), FrameError::Irpc(error));
    assert!(error.to_string().contains("header.source_id"), "{error}");

    // A whole message whose header does not name the ids' ends.
    let mut other = longest_fault_history();
    other.header.source_id = 0x34;
    let b = encode(&other, WireVersion::V2_2);
    c.handle_frame(ms(5000), &first_frame(b.len(), &b));
    c.handle_frame(ms(5001), &consecutive(1, &b[62..125]));
    c.handle_frame(ms(5002), &consecutive(2, &b[125..]));
    assert!(
        matches!(c.poll_event(), Some(Event::Misaddressed { message, .. }) if message == other)
    );

    // An empty frame and a reserved PCI on a segmented id.
    c.handle_frame(
        ms(5003),
        &Frame::fd(CanId::extended(0x1000_0033).unwrap(), &[0x40, 1, 2]).unwrap(),
    );
    assert_eq!(
        undecodable(&mut c),
        FrameError::Transfer(IsoTpError::InvalidFrame {
            reason: "reserved protocol control information"
        })
    );

    // Still working: the real message arrives whole.
    while c.poll_transmit().is_some() {}
    c.handle_frame(ms(6000), &first_frame(bytes.len(), &bytes));
    c.handle_frame(ms(6001), &consecutive(1, &bytes[62..125]));
    c.handle_frame(ms(6002), &consecutive(2, &bytes[125..]));
    assert!(matches!(
        c.poll_event(),
        Some(Event::Feedback { message, .. }) if message == longest_fault_history()
    ));
    let s = c.stats();
    assert_eq!(
        (s.failed_transfers, s.segmented_received, s.bad_frames),
        (4, 3, 2)
    );
    assert_eq!(c.poll_transmit().unwrap().data(), [0x30, 0, 0]);
    // Transfers between other nodes, and to other nodes, are not ours.
    c.handle_frame(
        ms(7000),
        &Frame::fd(CanId::extended(0x1000_8033).unwrap(), &huge).unwrap(),
    );
    assert_eq!(c.poll_event(), None);
    assert_eq!(c.poll_transmit(), None);
}
