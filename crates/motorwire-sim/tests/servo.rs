//! Simulated serial bus servos answering as the servos do, each protocol:
//! what LeRobot's motor buses ask of an SO-101 (STS3215) or a Koch arm
//! (XL330, XL430) at connection and in a control loop.
#![allow(clippy::unwrap_used, clippy::indexing_slicing)]

use std::time::Duration;

use motorwire_servo::{Instruction, Protocol, Status, decode_status, encode, table};
use motorwire_sim::servo::{ServoBus, ServoFaults};

fn ms(n: u64) -> Duration {
    Duration::from_millis(n)
}

/// Writes `i` at `at`; every status packet that comes back, decoded.
fn ask(bus: &mut ServoBus, at: Duration, i: &Instruction) -> Vec<Status> {
    let p = bus.protocol();
    bus.write(at, &encode(p, i).unwrap())
        .iter()
        .map(|a| decode_status(p, &a.bytes, None).unwrap().status)
        .collect()
}

fn read(bus: &mut ServoBus, at: Duration, id: u8, name: &str) -> i64 {
    let model = bus.servo(id).unwrap().model();
    let r = model.register(name).unwrap();
    let s = ask(
        bus,
        at,
        &Instruction::Read {
            id,
            address: r.address,
            length: u16::from(r.size),
        },
    );
    assert_eq!(s.len(), 1);
    let b = &s[0].params;
    let raw = match (b.len(), bus.protocol().big_endian()) {
        (1, _) => u32::from(b[0]),
        (2, false) => u32::from(u16::from_le_bytes([b[0], b[1]])),
        (2, true) => u32::from(u16::from_be_bytes([b[0], b[1]])),
        _ => u32::from_le_bytes([b[0], b[1], b[2], b[3]]),
    };
    r.from_raw(raw)
}

/// An SO-101's servos: found by ping, their model read, torque on, a
/// sync write of goal positions, then sync reads while they move at the
/// goal velocity and after they arrived.
#[test]
fn sts3215_servos_move_to_their_goals_at_their_velocity() {
    let sts = table::model("sts3215").unwrap();
    let mut bus = ServoBus::new(sts, &[1, 2, 3, 4, 5, 6]).unwrap();
    for id in 1..=6 {
        let s = ask(&mut bus, ms(0), &Instruction::Ping { id });
        assert_eq!((s.len(), s[0].id, s[0].error), (1, id, 0));
        assert_eq!(read(&mut bus, ms(0), id, "Model_Number"), 777);
    }
    assert!(
        ask(&mut bus, ms(0), &Instruction::Ping { id: 7 }).is_empty(),
        "nobody at 7"
    );
    let goal = sts.register("Goal_Velocity").unwrap();
    let at = |id: u8, v: i64| {
        (
            id,
            Protocol::Scs0
                .value_bytes(goal.to_raw(v).unwrap(), 2)
                .unwrap(),
        )
    };
    let sync_write = |address, entries| Instruction::SyncWrite {
        address,
        length: 2,
        entries,
    };
    ask(
        &mut bus,
        ms(0),
        &sync_write(46, vec![at(1, 1000), at(2, 1000)]),
    );
    ask(
        &mut bus,
        ms(0),
        &Instruction::Write {
            id: 0xFE,
            address: 40,
            data: vec![1],
        },
    );
    let pos = |v: i64| {
        Protocol::Scs0
            .value_bytes(u32::try_from(v).unwrap(), 2)
            .unwrap()
    };
    assert!(
        ask(
            &mut bus,
            ms(0),
            &sync_write(42, vec![(1, pos(3000)), (2, pos(1000))])
        )
        .is_empty()
    );
    // Half a second in: about 500 steps each way (the acceleration is
    // the servo's fastest).
    let s = ask(
        &mut bus,
        ms(500),
        &Instruction::SyncRead {
            address: 56,
            length: 2,
            ids: vec![1, 2],
        },
    );
    let present: Vec<i64> = s
        .iter()
        .map(|s| i64::from(u16::from_le_bytes([s.params[0], s.params[1]])))
        .collect();
    assert_eq!(s.iter().map(|s| s.id).collect::<Vec<_>>(), [1, 2]);
    assert!((2530..=2550).contains(&present[0]), "{present:?}");
    assert!((1546..=1566).contains(&present[1]), "{present:?}");
    assert_eq!(read(&mut bus, ms(500), 1, "Present_Velocity"), 1000);
    assert_eq!(read(&mut bus, ms(500), 2, "Present_Velocity"), -1000);
    assert_eq!(read(&mut bus, ms(3000), 1, "Present_Position"), 3000);
    assert_eq!(read(&mut bus, ms(3000), 2, "Present_Position"), 1000);
    assert_eq!(read(&mut bus, ms(3000), 2, "Moving"), 0);
    // Servo 3 kept its torque off... no: the broadcast turned every
    // servo's on; its goal was never written, so it holds its position.
    assert_eq!(read(&mut bus, ms(3000), 3, "Present_Position"), 2048);
}

/// LeRobot's calibration writes a homing offset so that the middle pose
/// reads 2047: Feetech subtracts it (present = actual - offset), and the
/// sign-magnitude bit 11 carries a negative one.
#[test]
fn a_feetech_homing_offset_is_subtracted_and_signed_by_its_bit() {
    let mut bus = ServoBus::new(table::model("sts3215").unwrap(), &[1]).unwrap();
    assert_eq!(read(&mut bus, ms(0), 1, "Present_Position"), 2048);
    // -100: bit 11 and 100.
    ask(
        &mut bus,
        ms(0),
        &Instruction::Write {
            id: 1,
            address: 31,
            data: vec![100, 0x08],
        },
    );
    assert_eq!(read(&mut bus, ms(0), 1, "Homing_Offset"), -100);
    assert_eq!(read(&mut bus, ms(0), 1, "Present_Position"), 2148);
}

/// The SCS series writes its words big-endian.
#[test]
fn scs0009_words_are_big_endian() {
    let mut bus = ServoBus::new(table::model("scs0009").unwrap(), &[3]).unwrap();
    let s = ask(
        &mut bus,
        ms(0),
        &Instruction::Read {
            id: 3,
            address: 3,
            length: 2,
        },
    );
    assert_eq!(s[0].params, [0x05, 0x04], "1284");
    assert_eq!(read(&mut bus, ms(0), 3, "Present_Position"), 512);
}

/// A Koch arm's Dynamixels: a broadcast ping answered by each in id order
/// with its model number and firmware; an EEPROM write with torque on is
/// an access error; the homing offset is added; a status return level of
/// 1 answers reads only.
#[test]
fn dynamixels_answer_as_x_series_servos_do() {
    let xl = table::model("xl330-m288").unwrap();
    let mut bus = ServoBus::new(xl, &[2, 1]).unwrap();
    let s = ask(&mut bus, ms(0), &Instruction::Ping { id: 0xFE });
    assert_eq!(
        s.iter()
            .map(|s| (s.id, s.params.clone()))
            .collect::<Vec<_>>(),
        [(2, vec![0xB0, 0x04, 52]), (1, vec![0xB0, 0x04, 52])]
    );
    ask(
        &mut bus,
        ms(0),
        &Instruction::Write {
            id: 1,
            address: 64,
            data: vec![1],
        },
    );
    let s = ask(
        &mut bus,
        ms(0),
        &Instruction::Write {
            id: 1,
            address: 11,
            data: vec![1],
        },
    );
    assert_eq!(s[0].error, 7, "EEPROM with torque on");
    let s = ask(
        &mut bus,
        ms(0),
        &Instruction::Write {
            id: 1,
            address: 132,
            data: vec![0; 4],
        },
    );
    assert_eq!(s[0].error, 7, "a read-only register");
    ask(
        &mut bus,
        ms(0),
        &Instruction::Write {
            id: 1,
            address: 64,
            data: vec![0],
        },
    );
    ask(
        &mut bus,
        ms(0),
        &Instruction::Write {
            id: 1,
            address: 20,
            data: 300i32.to_le_bytes().to_vec(),
        },
    );
    assert_eq!(read(&mut bus, ms(0), 1, "Present_Position"), 2048 + 300);
    ask(
        &mut bus,
        ms(0),
        &Instruction::Write {
            id: 1,
            address: 68,
            data: vec![1],
        },
    );
    assert!(
        ask(
            &mut bus,
            ms(0),
            &Instruction::Write {
                id: 1,
                address: 65,
                data: vec![1]
            }
        )
        .is_empty()
    );
    assert_eq!(read(&mut bus, ms(0), 1, "LED"), 1);
    // Bulk read of two registers of two servos.
    let s = ask(
        &mut bus,
        ms(0),
        &Instruction::BulkRead {
            reads: vec![(1, 146, 1), (2, 0, 2)],
        },
    );
    assert_eq!(
        s.iter()
            .map(|s| (s.id, s.params.clone()))
            .collect::<Vec<_>>(),
        [(1, vec![30]), (2, vec![0xB0, 0x04])]
    );
}

/// A packet written in pieces is answered once it is whole; a corrupt one
/// is ignored and counted; faults drop, corrupt and delay answers as
/// drawn from the seed.
#[test]
fn pieces_corruption_and_faults() {
    let sts = table::model("sts3215").unwrap();
    let mut bus = ServoBus::new(sts, &[1]).unwrap();
    let ping = encode(Protocol::Scs0, &Instruction::Ping { id: 1 }).unwrap();
    assert!(bus.write(ms(0), &ping[..3]).is_empty());
    assert_eq!(bus.write(ms(1), &ping[3..]).len(), 1);
    let mut bad = ping.clone();
    bad[5] ^= 1;
    assert!(bus.write(ms(2), &bad).is_empty());
    assert_eq!(bus.bad_packets(), 1);
    assert_eq!(bus.write(ms(3), &ping).len(), 1, "the next packet is read");
    let faulty = |faults| ServoBus::new(sts, &[1]).unwrap().with_faults(faults, 7);
    let mut dropped = faulty(ServoFaults {
        drop: 1.0,
        ..ServoFaults::default()
    });
    assert!(dropped.write(ms(0), &ping).is_empty());
    let mut corrupt = faulty(ServoFaults {
        corrupt: 1.0,
        ..ServoFaults::default()
    });
    let a = corrupt.write(ms(0), &ping);
    assert!(
        decode_status(Protocol::Scs0, &a[0].bytes, None).is_err()
            || a[0].bytes != encode_status_of(1)
    );
    let mut late = faulty(ServoFaults {
        late: 1.0,
        late_by: ms(30),
        ..ServoFaults::default()
    });
    assert_eq!(late.write(ms(0), &ping)[0].delay, ms(30));
}

fn encode_status_of(id: u8) -> Vec<u8> {
    motorwire_servo::encode_status(
        Protocol::Scs0,
        &Status {
            id,
            error: 0,
            params: vec![],
        },
    )
    .unwrap()
}

/// Stray bytes cost at most the packet they cut: a servo that heard half
/// a packet, or an impossible header, answers the next whole one.
#[test]
fn stray_bytes_cost_at_most_the_packet_they_cut() {
    for (model, junk) in [
        ("sts3215", vec![0xFF, 0xFF]),
        ("sts3215", vec![0xFF, 0xFF, 0x01]),
        ("sts3215", vec![0xFF; 1000]),
        ("sts3215", vec![0xFF, 0xFF, 0x01, 0xFF]),
        ("sts3215", vec![0xFF, 0xFF, 0x01, 0xF0]),
        ("xl330-m288", vec![0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x00, 0x04]),
        ("xl330-m288", vec![0xFF, 0xFF, 0xFD, 0x00, 0x01, 0xF5, 0x03]),
    ] {
        let mut bus = ServoBus::new(table::model(model).unwrap(), &[1]).unwrap();
        assert!(bus.write(ms(0), &junk).is_empty());
        let s = ask(&mut bus, ms(50), &Instruction::Ping { id: 1 });
        assert_eq!(s.len(), 1, "{model} after {junk:02x?}");
    }
}

/// A factory reset is answered from the id the servo had; an id no servo
/// can take is refused (Dynamixel: data range error).
#[test]
fn a_factory_reset_answers_from_its_old_id_and_ids_stay_in_range() {
    let mut bus = ServoBus::new(table::model("xm430-w350").unwrap(), &[3]).unwrap();
    let s = ask(
        &mut bus,
        ms(0),
        &Instruction::FactoryReset {
            id: 3,
            option: 0xFF,
        },
    );
    assert_eq!((s.len(), s[0].id), (1, 3));
    assert!(
        bus.servo(1).is_some() && bus.servo(3).is_none(),
        "reset to id 1"
    );
    let s = ask(
        &mut bus,
        ms(0),
        &Instruction::Write {
            id: 1,
            address: 7,
            data: vec![253],
        },
    );
    assert_eq!(s[0].error, 4);
    assert!(bus.servo(1).is_some());
}
