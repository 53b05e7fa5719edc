//! ISO-TP: the exact frames of ISO 15765-2 (as Linux's CAN_ISOTP sends and
//! expects them), and transfers through the in-memory bus.
#![allow(clippy::unwrap_used, clippy::panic, clippy::indexing_slicing)]

use std::time::Duration;

use motorwire_can::isotp::{IsoTpConfig, IsoTpError, Receiver, Sender};
use motorwire_can::{CanId, Frame};

fn ids() -> (CanId, CanId) {
    (
        CanId::standard(0x123).unwrap(),
        CanId::standard(0x321).unwrap(),
    )
}

fn data(n: usize) -> Vec<u8> {
    (0..n).map(|i| i as u8).collect()
}

fn drain(tx: &mut Sender, now: Duration) -> Vec<Frame> {
    std::iter::from_fn(|| tx.poll_transmit(now)).collect()
}

#[test]
fn classic_single_frame() {
    let (a, b) = ids();
    let mut tx = Sender::new(IsoTpConfig::classic(a, b)).unwrap();
    tx.start(Duration::ZERO, &[0xAA, 0xBB, 0xCC]).unwrap();
    let frames = drain(&mut tx, Duration::ZERO);
    assert_eq!(frames.len(), 1);
    assert_eq!(frames[0].data(), &[0x03, 0xAA, 0xBB, 0xCC]);
    assert!(!frames[0].is_fd());
    assert_eq!(tx.poll_done(), Some(Ok(())));
}

#[test]
fn classic_padding_fills_eight_bytes() {
    let (a, b) = ids();
    let mut tx = Sender::new(IsoTpConfig {
        padding: Some(0x55),
        ..IsoTpConfig::classic(a, b)
    })
    .unwrap();
    tx.start(Duration::ZERO, &[1]).unwrap();
    assert_eq!(
        drain(&mut tx, Duration::ZERO)[0].data(),
        &[0x01, 0x01, 0x55, 0x55, 0x55, 0x55, 0x55, 0x55]
    );
}

#[test]
fn classic_first_frame_flow_control_and_consecutive_frames() {
    let (a, b) = ids();
    let mut tx = Sender::new(IsoTpConfig::classic(a, b)).unwrap();
    let msg = data(20);
    tx.start(Duration::ZERO, &msg).unwrap();
    let first = drain(&mut tx, Duration::ZERO);
    assert_eq!(first.len(), 1, "nothing more before flow control");
    assert_eq!(first[0].data(), &[0x10, 0x14, 0, 1, 2, 3, 4, 5]);

    let mut rx = Receiver::new(IsoTpConfig::classic(b, a)).unwrap();
    assert_eq!(rx.handle_frame(Duration::ZERO, &first[0]), None);
    let fc = rx.poll_transmit().unwrap();
    assert_eq!((fc.id(), fc.data()), (b, &[0x30, 0x00, 0x00][..]));

    tx.handle_frame(Duration::ZERO, &fc);
    let rest = drain(&mut tx, Duration::ZERO);
    assert_eq!(rest.len(), 2);
    assert_eq!(rest[0].data(), &[0x21, 6, 7, 8, 9, 10, 11, 12]);
    assert_eq!(rest[1].data(), &[0x22, 13, 14, 15, 16, 17, 18, 19]);
    assert_eq!(tx.poll_done(), Some(Ok(())));
    assert_eq!(rx.handle_frame(Duration::ZERO, &rest[0]), None);
    assert_eq!(rx.handle_frame(Duration::ZERO, &rest[1]), Some(Ok(msg)));
}

#[test]
fn fd_escape_single_frame_and_padding() {
    let (a, b) = ids();
    let mut tx = Sender::new(IsoTpConfig::fd(a, b)).unwrap();
    let msg = data(30);
    tx.start(Duration::ZERO, &msg).unwrap();
    let f = drain(&mut tx, Duration::ZERO);
    // 2 + 30 bytes: exactly the FD length 32.
    assert_eq!(f[0].len(), 32);
    assert_eq!(&f[0].data()[..3], &[0x00, 30, 0]);
    tx.start(Duration::ZERO, &data(9)).unwrap();
    let f = drain(&mut tx, Duration::ZERO);
    // 11 bytes padded to 12 with 0xCC, as Linux pads.
    assert_eq!(f[0].len(), 12);
    assert_eq!(&f[0].data()[..2], &[0x00, 9]);
    assert_eq!(f[0].data()[11], 0xCC);
    let mut rx = Receiver::new(IsoTpConfig::fd(b, a)).unwrap();
    assert_eq!(rx.handle_frame(Duration::ZERO, &f[0]), Some(Ok(data(9))));
}

#[test]
fn fd_multi_frame_with_block_size_and_long_length() {
    let (a, b) = ids();
    let mut tx = Sender::new(IsoTpConfig::fd(a, b)).unwrap();
    let mut rx = Receiver::new(IsoTpConfig {
        block_size: 2,
        ..IsoTpConfig::fd(b, a)
    })
    .unwrap();
    // Over 4095 bytes: the 32-bit first-frame length.
    let msg = data(5000);
    tx.start(Duration::ZERO, &msg).unwrap();
    let ff = drain(&mut tx, Duration::ZERO);
    assert_eq!(&ff[0].data()[..6], &[0x10, 0x00, 0x00, 0x00, 0x13, 0x88]);
    assert_eq!(ff[0].len(), 64);
    let mut got = rx.handle_frame(Duration::ZERO, &ff[0]);
    let mut flow_controls = 0;
    let mut consecutive = 0;
    while got.is_none() {
        let fc = rx.poll_transmit().expect("flow control after each block");
        flow_controls += 1;
        assert_eq!(fc.data()[..3], [0x30, 2, 0]);
        tx.handle_frame(Duration::ZERO, &fc);
        for f in drain(&mut tx, Duration::ZERO) {
            consecutive += 1;
            assert!(got.is_none());
            got = rx.handle_frame(Duration::ZERO, &f);
        }
    }
    // 5000 - 58 in the first frame, 63 per consecutive frame.
    assert_eq!(consecutive, (5000 - 58usize).div_ceil(63));
    assert_eq!(flow_controls, consecutive.div_ceil(2));
    assert_eq!(got, Some(Ok(msg)));
}

#[test]
fn separation_time_paces_consecutive_frames() {
    let (a, b) = ids();
    let mut tx = Sender::new(IsoTpConfig::classic(a, b)).unwrap();
    tx.start(Duration::ZERO, &data(30)).unwrap();
    drain(&mut tx, Duration::ZERO);
    // CTS, no block limit, STmin 0xF5 = 500 us.
    tx.handle_frame(
        Duration::ZERO,
        &Frame::classic(b, &[0x30, 0, 0xF5]).unwrap(),
    );
    assert!(tx.poll_transmit(Duration::ZERO).is_some());
    assert!(tx.poll_transmit(Duration::from_micros(499)).is_none());
    assert_eq!(tx.poll_timeout(), Some(Duration::from_micros(500)));
    assert!(tx.poll_transmit(Duration::from_micros(500)).is_some());
}

#[test]
fn overflow_wait_and_timeout_end_a_send() {
    let (a, b) = ids();
    let cfg = IsoTpConfig {
        max_waits: 1,
        ..IsoTpConfig::classic(a, b)
    };
    let mut tx = Sender::new(cfg).unwrap();
    tx.start(Duration::ZERO, &data(30)).unwrap();
    drain(&mut tx, Duration::ZERO);
    tx.handle_frame(Duration::ZERO, &Frame::classic(b, &[0x32, 0, 0]).unwrap());
    assert_eq!(tx.poll_done(), Some(Err(IsoTpError::Overflow)));

    tx.start(Duration::ZERO, &data(30)).unwrap();
    drain(&mut tx, Duration::ZERO);
    let wait = Frame::classic(b, &[0x31, 0, 0]).unwrap();
    tx.handle_frame(Duration::ZERO, &wait);
    tx.handle_frame(Duration::ZERO, &wait);
    assert_eq!(tx.poll_done(), Some(Err(IsoTpError::TooManyWaits)));

    tx.start(Duration::ZERO, &data(30)).unwrap();
    drain(&mut tx, Duration::ZERO);
    tx.handle_timeout(Duration::from_millis(999));
    assert_eq!(tx.poll_done(), None);
    tx.handle_timeout(Duration::from_secs(1));
    assert_eq!(
        tx.poll_done(),
        Some(Err(IsoTpError::Timeout {
            waiting_for: "flow control"
        }))
    );
}

#[test]
fn a_receiver_refuses_what_it_cannot_take() {
    let (a, b) = ids();
    let mut rx = Receiver::new(IsoTpConfig {
        max_len: 100,
        ..IsoTpConfig::classic(b, a)
    })
    .unwrap();
    // A 256-byte first frame: flow status overflow.
    let ff = Frame::classic(a, &[0x11, 0x00, 0, 1, 2, 3, 4, 5]).unwrap();
    assert_eq!(
        rx.handle_frame(Duration::ZERO, &ff),
        Some(Err(IsoTpError::TooLong { len: 256, max: 100 }))
    );
    assert_eq!(rx.poll_transmit().unwrap().data(), &[0x32, 0, 0]);
    // Out of sequence.
    let ff = Frame::classic(a, &[0x10, 0x14, 0, 1, 2, 3, 4, 5]).unwrap();
    assert_eq!(rx.handle_frame(Duration::ZERO, &ff), None);
    let cf2 = Frame::classic(a, &[0x22, 0, 0, 0, 0, 0, 0, 0]).unwrap();
    assert_eq!(
        rx.handle_frame(Duration::ZERO, &cf2),
        Some(Err(IsoTpError::WrongSequence {
            expected: 1,
            got: 2
        }))
    );
    // A consecutive frame with no transfer is ignored; a reserved PCI is not.
    assert_eq!(rx.handle_frame(Duration::ZERO, &cf2), None);
    let reserved = Frame::classic(a, &[0x40, 0]).unwrap();
    assert!(matches!(
        rx.handle_frame(Duration::ZERO, &reserved),
        Some(Err(IsoTpError::InvalidFrame { .. }))
    ));
    // Frames of other ids are not looked at.
    let other = Frame::classic(CanId::standard(0x7).unwrap(), &[0x40]).unwrap();
    assert_eq!(rx.handle_frame(Duration::ZERO, &other), None);
    // A stalled transfer times out.
    assert_eq!(rx.handle_frame(Duration::ZERO, &ff), None);
    assert_eq!(rx.poll_timeout(), Some(Duration::from_secs(1)));
    assert_eq!(
        rx.handle_timeout(Duration::from_secs(1)),
        Some(IsoTpError::Timeout {
            waiting_for: "consecutive frame"
        })
    );
}

#[test]
fn invalid_configurations_and_messages_are_errors() {
    let (a, b) = ids();
    assert!(
        Sender::new(IsoTpConfig {
            tx_dl: 12,
            ..IsoTpConfig::classic(a, b)
        })
        .is_err()
    );
    assert!(
        Sender::new(IsoTpConfig {
            tx_dl: 13,
            ..IsoTpConfig::fd(a, b)
        })
        .is_err()
    );
    let mut tx = Sender::new(IsoTpConfig::classic(a, b)).unwrap();
    assert_eq!(
        tx.start(Duration::ZERO, &[]).unwrap_err(),
        motorwire_can::Error::IsoTp(IsoTpError::Empty)
    );
    tx.start(Duration::ZERO, &data(20)).unwrap();
    assert_eq!(
        tx.start(Duration::ZERO, &data(20)).unwrap_err(),
        motorwire_can::Error::IsoTp(IsoTpError::Busy)
    );
}
