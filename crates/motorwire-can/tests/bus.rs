//! Frames, candump lines and the in-memory bus.
#![allow(clippy::unwrap_used, clippy::panic, clippy::indexing_slicing)]

use std::time::Duration;

use motorwire_can::candump::{LogEntry, read_log};
use motorwire_can::{CanBus, CanId, Clock, Error, Faults, Frame, SimBus, SimConfig};

fn id(n: u16) -> CanId {
    CanId::standard(n).unwrap()
}

#[test]
fn fd_frames_pad_to_the_next_length_with_zeros() {
    for (len, padded) in [
        (0, 0),
        (8, 8),
        (9, 12),
        (13, 16),
        (21, 24),
        (25, 32),
        (33, 48),
        (49, 64),
    ] {
        let f = Frame::fd(id(1), &vec![0xFF; len]).unwrap();
        assert_eq!(f.len(), padded);
        assert!(f.data()[len..].iter().all(|b| *b == 0));
    }
    assert_eq!(
        Frame::fd(id(1), &[0; 65]),
        Err(Error::InvalidLength { len: 65, fd: true })
    );
    assert_eq!(
        Frame::fd_exact(id(1), &[0; 9], false, false),
        Err(Error::InvalidLength { len: 9, fd: true })
    );
    assert_eq!(
        CanId::extended(0x2000_0000),
        Err(Error::InvalidId {
            id: 0x2000_0000,
            extended: true
        })
    );
}

#[test]
fn candump_lines_round_trip() {
    for line in [
        "(1700000000.000001) vcan0 010#",
        "(1700000000.123456) can1 7FF#0102030405060708",
        "(0.000000) vcan0 12345678#AA",
        "(1700000000.500000) vcan0 010##3000102",
        "(1700000000.500000) vcan0 010##0",
    ] {
        assert_eq!(LogEntry::parse(line).unwrap().to_string(), line);
    }
    // Lowercase hex and a direction flag are read; written back canonical.
    let e = LogEntry::parse("(1.5) vcan0 01a#ab R").unwrap();
    assert_eq!(e.to_string(), "(1.500000) vcan0 01A#AB");
    // The FDF flag of newer candump versions (4) is accepted.
    assert!(LogEntry::parse("(1.0) vcan0 010##5AA").unwrap().frame.brs());
}

#[test]
fn bad_candump_lines_say_what_is_wrong() {
    let cases = [
        ("", "empty line"),
        (
            "1.0 vcan0 010#00",
            "timestamp \"1.0\" is not in parentheses",
        ),
        ("(1) vcan0 010#00", "timestamp \"1\" has no fractional part"),
        ("(1.0) vcan0", "no frame after the interface"),
        (
            "(1.0) vcan0 0100#00",
            "CAN id \"0100\" has 4 digits (3 or 8 expected)",
        ),
        (
            "(1.0) vcan0 800#00",
            "CAN id 0x800 is too large for a standard (11-bit) identifier",
        ),
        ("(1.0) vcan0 010#R", "\"010#R\" is a remote frame"),
        (
            "(1.0) vcan0 20000004#0000000000000000",
            "\"20000004#0000000000000000\" is an error frame",
        ),
        ("(1.0) vcan0 010#0G", "data \"0G\" is not hex"),
        (
            "(1.0) vcan0 010#000102030405060708",
            "9 bytes is not a valid classic CAN payload length",
        ),
        (
            "(1.0) vcan0 010##1000102030405060708",
            "9 bytes is not a valid CAN-FD payload length",
        ),
        (
            "(1.0) vcan0 010#00 extra",
            "unexpected \"extra\" after the frame",
        ),
    ];
    for (line, reason) in cases {
        assert_eq!(LogEntry::parse(line).unwrap_err(), reason, "{line}");
    }
    let all: Vec<_> = read_log("(1.0) vcan0 010#00\n(2.0) vcan0 x\n").collect();
    assert!(all[0].is_ok());
    assert_eq!(
        all[1],
        Err(Error::Log {
            line: 2,
            reason: "frame \"x\" has no '#'".into()
        })
    );
}

#[test]
fn every_port_but_the_sender_receives() {
    let bus = SimBus::default();
    let (mut a, mut b, mut c) = (bus.port(), bus.port(), bus.port());
    a.send(&Frame::classic(id(1), &[1]).unwrap()).unwrap();
    assert!(matches!(a.recv(Duration::ZERO), Err(Error::Timeout(_))));
    assert_eq!(b.recv(Duration::ZERO).unwrap().frame.data(), &[1]);
    assert_eq!(c.recv(Duration::ZERO).unwrap().frame.data(), &[1]);
    drop(c);
    b.send(&Frame::classic(id(2), &[2]).unwrap()).unwrap();
    assert_eq!(bus.stats().delivered, 3);
}

#[test]
fn faults_are_reproducible_and_counted() {
    let faults = Faults {
        drop: 0.2,
        duplicate: 0.2,
        corrupt: 0.2,
        delay: 0.2,
        reorder: 0.2,
        ..Faults::default()
    };
    let run = |seed| {
        let bus = SimBus::new(SimConfig {
            seed,
            faults,
            ..SimConfig::default()
        })
        .unwrap();
        let (mut a, mut b) = (bus.port(), bus.port());
        for i in 0..1000u16 {
            a.send(&Frame::fd(id(1), &i.to_le_bytes()).unwrap())
                .unwrap();
        }
        let mut got = Vec::new();
        while let Ok(r) = b.recv(Duration::from_secs(1)) {
            got.push((r.timestamp, r.frame));
        }
        (got, bus.stats())
    };
    let (x, sx) = run(3);
    let (y, sy) = run(3);
    assert_eq!(x, y);
    assert_eq!(sx, sy);
    let (z, _) = run(4);
    assert_ne!(x, z);
    // Every rate lands near its expectation, and the counts add up.
    for n in [sx.dropped, sx.duplicated, sx.corrupted, sx.delayed] {
        assert!((120..=280).contains(&n), "{sx:?}");
    }
    assert_eq!(x.len() as u64, sx.sent - sx.dropped + sx.duplicated);
    assert!(sx.reordered > 50);
    // Frames come out in time order, and a corrupted one differs in one bit.
    assert!(x.windows(2).all(|w| w[0].0 <= w[1].0));
}

#[test]
fn corruption_flips_exactly_one_bit() {
    let bus = SimBus::new(SimConfig {
        faults: Faults {
            corrupt: 1.0,
            ..Faults::default()
        },
        ..SimConfig::default()
    })
    .unwrap();
    let (mut a, mut b) = (bus.port(), bus.port());
    let sent = Frame::fd(id(1), &[0x55; 16]).unwrap();
    for _ in 0..100 {
        a.send(&sent).unwrap();
        let got = b.recv(Duration::ZERO).unwrap().frame;
        let flipped: u32 = sent
            .data()
            .iter()
            .zip(got.data())
            .map(|(x, y)| (x ^ y).count_ones())
            .sum();
        assert_eq!(flipped, 1);
        assert_eq!(got.id(), sent.id());
    }
}

#[test]
fn simulated_time_moves_only_when_waiting() {
    let bus = SimBus::new(SimConfig {
        latency: Duration::from_millis(2),
        ..SimConfig::default()
    })
    .unwrap();
    let (mut a, mut b) = (bus.port(), bus.port());
    a.send(&Frame::classic(id(1), &[]).unwrap()).unwrap();
    assert!(b.try_recv().is_none(), "not due before its latency");
    assert_eq!(bus.next_delivery(), Some(Duration::from_millis(2)));
    assert!(matches!(
        b.recv(Duration::from_millis(1)),
        Err(Error::Timeout(_))
    ));
    assert_eq!(bus.now(), Duration::from_millis(1));
    assert_eq!(
        b.recv(Duration::from_secs(5)).unwrap().timestamp,
        Duration::from_millis(2)
    );
    assert_eq!(bus.now(), Duration::from_millis(2));
    bus.advance_to(Duration::from_millis(1));
    assert_eq!(bus.now(), Duration::from_millis(2), "never back");
}

#[test]
fn real_time_waits_really_wait() {
    let bus = SimBus::new(SimConfig {
        clock: Clock::Real,
        ..SimConfig::default()
    })
    .unwrap();
    let (mut a, mut b) = (bus.port(), bus.port());
    let t = std::thread::spawn(move || {
        b.recv(Duration::from_secs(5))
            .map(|r| r.frame.data().to_vec())
    });
    std::thread::sleep(Duration::from_millis(20));
    a.send(&Frame::classic(id(1), &[7]).unwrap()).unwrap();
    assert_eq!(t.join().unwrap().unwrap(), vec![7]);
}

#[test]
fn rates_outside_zero_to_one_are_refused() {
    let bad = Faults {
        corrupt: f64::NAN,
        ..Faults::default()
    };
    assert_eq!(
        SimBus::new(SimConfig {
            faults: bad,
            ..SimConfig::default()
        })
        .unwrap_err(),
        Error::InvalidFaultRate {
            name: "corrupt",
            value: "NaN".into()
        }
    );
}

// Needs the feature, which the workspace turns on for tests (a self
// dev-dependency) and a downloaded crate does with `--features tokio`.
#[cfg(feature = "tokio")]
#[tokio::test]
async fn the_async_trait_on_the_in_memory_bus() {
    use motorwire_can::AsyncCanBus;
    let bus = SimBus::new(SimConfig {
        clock: Clock::Real,
        ..SimConfig::default()
    })
    .unwrap();
    let (mut a, mut b) = (bus.port(), bus.port());
    let waiter = tokio::spawn(async move { AsyncCanBus::recv(&mut b).await.map(|r| r.frame) });
    tokio::time::sleep(Duration::from_millis(10)).await;
    AsyncCanBus::send(&mut a, &Frame::fd(id(3), &[1, 2]).unwrap())
        .await
        .unwrap();
    assert_eq!(waiter.await.unwrap().unwrap().data(), &[1, 2]);
}

/// A port that only sends costs nothing however much traffic the bus
/// carries; a receiving port nobody reads keeps every frame (what
/// `motorwire bridge --bus sim` did with its sending port, issue 15).
#[test]
fn a_send_only_port_never_queues_a_frame() {
    const N: usize = 10_000;
    let bus = SimBus::new(SimConfig {
        clock: Clock::Real,
        ..SimConfig::default()
    })
    .unwrap();
    let (mut tx, mut joint) = (bus.send_only_port(), bus.port());
    let unread = bus.port();
    let frame = Frame::fd(id(0x10), &[0xAB; 8]).unwrap();
    for _ in 0..N {
        joint.send(&frame).unwrap();
    }
    assert_eq!(tx.queued(), 0, "the send-only port keeps nothing");
    assert_eq!(
        unread.queued(),
        N,
        "an unread receiving port keeps everything"
    );
    assert!(matches!(
        tx.recv(Duration::from_millis(1)),
        Err(Error::Timeout(_))
    ));
    // It still sends to everyone else.
    tx.send(&Frame::fd(id(0x01), &[1]).unwrap()).unwrap();
    assert_eq!(joint.recv(Duration::ZERO).unwrap().frame.data(), &[1]);
    assert_eq!(unread.queued(), N + 1);
}

/// This thread's voluntary context switches so far (Linux).
#[cfg(target_os = "linux")]
fn voluntary_switches() -> u64 {
    std::fs::read_to_string("/proc/thread-self/status")
        .unwrap()
        .lines()
        .find_map(|l| l.strip_prefix("voluntary_ctxt_switches:"))
        .unwrap()
        .trim()
        .parse()
        .unwrap()
}

/// A thread waiting on a port is woken by the frames queued for it, not
/// by every frame on the bus: here its own sending half sends 200 frames
/// (which it does not hear) while it waits, and it sleeps through them
/// until the one frame another node sends. (One condition variable for
/// the whole bus woke it for each of the 200.)
#[cfg(target_os = "linux")]
#[test]
fn a_waiting_port_is_woken_only_by_frames_for_it() {
    let bus = SimBus::new(SimConfig {
        clock: Clock::Real,
        ..SimConfig::default()
    })
    .unwrap();
    let mut rx = bus.port();
    let mut own = rx.sending_half();
    let mut other = bus.port();
    let (ready_tx, ready_rx) = std::sync::mpsc::channel();
    let waiter = std::thread::spawn(move || {
        let before = voluntary_switches();
        ready_tx.send(()).unwrap();
        let got = rx.recv(Duration::from_secs(10)).unwrap();
        (got.frame, voluntary_switches() - before)
    });
    ready_rx.recv().unwrap();
    // Let the waiter block in recv.
    std::thread::sleep(Duration::from_millis(50));
    for i in 0..200u8 {
        own.send(&Frame::classic(id(0x10), &[i]).unwrap()).unwrap();
        std::thread::sleep(Duration::from_micros(200));
    }
    assert_eq!(other.recv(Duration::ZERO).unwrap().frame.data(), &[0]);
    let last = Frame::classic(id(0x20), &[0xEE]).unwrap();
    other.send(&last).unwrap();
    let (frame, switches) = waiter.join().unwrap();
    assert_eq!(frame, last);
    // The ready handshake and the one wake (a few for the scheduler).
    assert!(switches <= 5, "woken {switches} times");
}

/// A waker is taken on a bus whose frames are due as they are sent, and
/// refused on one that may hold a frame for later (a latency, delays,
/// reordering): nothing would wake the port when that frame falls due.
#[test]
fn a_waker_is_refused_where_a_frame_can_fall_due_later() {
    let noop: motorwire_can::FrameWaker = std::sync::Arc::new(|| {});
    let takes = |config: SimConfig| {
        let bus = SimBus::new(config).unwrap();
        bus.port().set_waker(std::sync::Arc::clone(&noop))
    };
    assert!(takes(SimConfig::default()));
    assert!(takes(SimConfig {
        faults: Faults {
            drop: 0.5,
            duplicate: 0.5,
            corrupt: 0.5,
            ..Faults::default()
        },
        ..SimConfig::default()
    }));
    assert!(!takes(SimConfig {
        latency: Duration::from_micros(1),
        ..SimConfig::default()
    }));
    for faults in [
        Faults {
            delay: 0.1,
            ..Faults::default()
        },
        Faults {
            reorder: 0.1,
            ..Faults::default()
        },
    ] {
        assert!(!takes(SimConfig {
            faults,
            ..SimConfig::default()
        }));
    }
}

/// A bus whose ports come and go keeps as many places as it had ports at
/// once: a port made after one was dropped takes its place, so sending
/// does not walk every port the bus ever had; a sending half whose twin
/// was dropped reaches every port, the one in its twin's place too.
#[test]
fn a_dropped_ports_place_is_taken_by_the_next_port() {
    let bus = SimBus::default();
    let mut joint = bus.port();
    for _ in 0..10_000 {
        let rx = bus.port();
        let tx = rx.sending_half();
        drop(rx);
        drop(tx);
    }
    // The places of the 20,000 ports made and dropped were reused: a new
    // receiving port and a sending half made for it each take one.
    let mut rx = bus.port();
    let mut tx = rx.sending_half();
    let mut old_half = {
        let gone = bus.port();
        gone.sending_half()
        // `gone` dropped here: its sending half reaches every port now.
    };
    tx.send(&Frame::classic(id(1), &[1]).unwrap()).unwrap();
    assert_eq!(joint.recv(Duration::ZERO).unwrap().frame.data(), &[1]);
    assert!(
        rx.recv(Duration::ZERO).is_err(),
        "a node does not hear itself"
    );
    old_half
        .send(&Frame::classic(id(2), &[2]).unwrap())
        .unwrap();
    assert_eq!(rx.recv(Duration::ZERO).unwrap().frame.data(), &[2]);
    assert_eq!(joint.recv(Duration::ZERO).unwrap().frame.data(), &[2]);
    // A new port in the dropped one's place hears the old half.
    let mut again = bus.port();
    old_half
        .send(&Frame::classic(id(3), &[3]).unwrap())
        .unwrap();
    assert_eq!(again.recv(Duration::ZERO).unwrap().frame.data(), &[3]);
    assert_eq!(bus.ports(), 5);
}
