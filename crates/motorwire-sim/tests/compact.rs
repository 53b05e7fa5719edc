//! The simulated compact device (WIRE-FACTS §2.1), command by command: sans-IO
//! at exact times, and on the in-memory bus in simulated time.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing
)]

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use motorwire_can::{CanBus, CanId, Clock, Frame, SimBus, SimConfig, SimPort};
use motorwire_compact::{
    CompactCommand, ControlMode, FeedbackRecord, Flags, MotorHash, StatusFlag, TorqueLimit,
    VelocityLimit,
};
use motorwire_sim::{
    CompactDeviceConfig, CompactDeviceLimits, CompactOutcome, CompactRefusal, SimCompactDevice,
    SimError,
};

const NODE: u16 = 0x20;
const FEEDBACK: u16 = 0x420;

fn ms(n: u64) -> Duration {
    Duration::from_millis(n)
}

fn hex(s: &str) -> Vec<u8> {
    s.split_whitespace()
        .map(|b| u8::from_str_radix(b, 16).unwrap())
        .collect()
}

/// The "elbow" device on 0x20, at 10.0, feedback only when asked.
fn elbow() -> SimCompactDevice {
    let config = CompactDeviceConfig {
        initial_position: 10.0,
        feedback_period: Duration::ZERO,
        ..CompactDeviceConfig::new(NODE, "elbow")
    };
    let mut d = SimCompactDevice::new(config).unwrap();
    d.keep_log();
    d
}

fn command(mode: ControlMode, setpoint: f32, flags: Flags, timestamp_ms: u64) -> CompactCommand {
    CompactCommand {
        motor: MotorHash::of("elbow"),
        timestamp_ms,
        control_mode: mode,
        flags,
        setpoint,
        velocity_limit: None,
        torque_limit: None,
    }
}

fn frame(cmd: &CompactCommand) -> Frame {
    Frame::fd(CanId::standard(NODE).unwrap(), &cmd.encode().unwrap()).unwrap()
}

fn drain(d: &mut SimCompactDevice) -> Vec<Frame> {
    std::iter::from_fn(|| d.poll_transmit()).collect()
}

fn only_record(d: &mut SimCompactDevice) -> FeedbackRecord {
    let frames = drain(d);
    assert_eq!(frames.len(), 1, "{frames:?}");
    assert_eq!(frames[0].id(), CanId::standard(FEEDBACK).unwrap());
    FeedbackRecord::decode(frames[0].data()).unwrap()
}

#[test]
fn require_ack_is_answered_with_exact_feedback_bytes() {
    // Torque: applied at once, at target, at rest.
    let mut d = elbow();
    let t = Duration::from_micros(1_500_000);
    let torque = command(ControlMode::Torque, 1.5, Flags::REQUIRE_ACK, 1);
    assert!(
        d.handle_frame(t, &frame(&torque))
            .unwrap()
            .outcome
            .is_executed()
    );
    let frames = drain(&mut d);
    assert_eq!(frames.len(), 1);
    assert_eq!(frames[0].id(), CanId::standard(FEEDBACK).unwrap());
    assert!(frames[0].is_fd());
    assert_eq!(
        frames[0].data(),
        hex("22 cb 57 81 \
             60 e3 16 00 00 00 00 00 \
             00 00 20 41 \
             00 00 00 00 \
             00 00 00 00 \
             00 00 c0 3f \
             00 00 70 41 \
             00 00 c0 41 \
             00 00 c8 41 \
             59 00 64 00 \
             00 00 00 00"),
        "elbow, 1.5 s, at 10.0, torque 1.5 Nm, 15 A, 24 V, 25 °C, \
         enabled|calibrated|homed|at_target, health 100"
    );

    // Position: the answer shows the move starting (accelerating at 5000).
    let mut d = elbow();
    let mv = command(ControlMode::Position, 90.0, Flags::REQUIRE_ACK, 2);
    d.handle_frame(t, &frame(&mv)).unwrap();
    assert_eq!(
        drain(&mut d)[0].data(),
        hex("22 cb 57 81 \
             60 e3 16 00 00 00 00 00 \
             00 00 20 41 \
             00 00 00 00 \
             00 40 9c 45 \
             00 00 00 00 \
             00 00 00 00 \
             00 00 c0 41 \
             00 00 c8 41 \
             39 00 64 00 \
             00 00 00 00"),
        "enabled|calibrated|homed|in_motion"
    );

    // Without REQUIRE_ACK a command is a datagram: no answer.
    let mut d = elbow();
    let quiet = command(ControlMode::Position, 20.0, Flags::NONE, 3);
    d.handle_frame(t, &frame(&quiet)).unwrap();
    assert!(d.poll_transmit().is_none());
    assert_eq!(d.stats().feedback_sent, 0);
}

/// A host port and the device's port on one simulated bus.
struct Bench {
    bus: SimBus,
    host: SimPort,
    port: SimPort,
    device: SimCompactDevice,
    /// Every frame the host heard, with when.
    heard: Vec<(Duration, Frame)>,
}

impl Bench {
    fn new(config: CompactDeviceConfig) -> Self {
        let bus = SimBus::default();
        let (host, port) = (bus.port(), bus.port());
        let mut device = SimCompactDevice::new(config).unwrap();
        device.keep_log();
        Self {
            bus,
            host,
            port,
            device,
            heard: Vec::new(),
        }
    }

    fn send(&mut self, cmd: &CompactCommand) {
        self.host.send(&frame(cmd)).unwrap();
    }

    /// Runs to `t` in 1 ms steps (and to every time the device asks for).
    fn run_to(&mut self, t: Duration) {
        loop {
            let now = self.bus.now();
            while self.device.serve(&mut self.port, now).unwrap() {}
            while let Some(r) = self.host.try_recv() {
                self.heard.push((now, r.frame));
            }
            if now >= t {
                break;
            }
            let next = self
                .device
                .poll_timeout()
                .filter(|&w| w > now)
                .map_or(now + ms(1), |w| w.min(now + ms(1)))
                .min(t);
            self.bus.advance_to(next);
        }
    }

    fn records(&self) -> Vec<FeedbackRecord> {
        self.heard
            .iter()
            .map(|(_, f)| {
                assert_eq!(f.id(), CanId::standard(FEEDBACK).unwrap());
                FeedbackRecord::decode(f.data()).unwrap()
            })
            .collect()
    }
}

#[test]
fn a_position_move_reaches_its_target() {
    let mut b = Bench::new(CompactDeviceConfig::new(NODE, "elbow"));
    let mut cmd = command(ControlMode::Position, 90.0, Flags::NONE, 1);
    cmd.velocity_limit = Some(VelocityLimit::from_units_per_s(100.0).unwrap());
    b.send(&cmd);
    b.run_to(ms(500));
    let d = &b.device;
    assert!(d.is_moving() && d.enabled());
    assert!(
        (d.velocity() - 100.0).abs() < 1e-9,
        "cruising at the command's limit"
    );
    assert!(!d.status().contains(StatusFlag::AtTarget));
    // 90 at 100/s with 5000/s² takes 0.9 + 0.02 s.
    b.run_to(ms(1000));
    let d = &b.device;
    assert!((d.position() - 90.0).abs() < 1e-6, "{}", d.position());
    assert_eq!(d.velocity(), 0.0);
    assert!(!d.is_moving());
    let status = d.status();
    assert!(status.contains(StatusFlag::AtTarget) && !status.contains(StatusFlag::InMotion));
    // Every periodic record on the way respected the limits.
    let records = b.records();
    assert!(records.len() >= 50);
    assert!(records.iter().all(|r| r.velocity.abs() <= 100.0 + 1e-3));
    assert!(
        records
            .iter()
            .all(|r| r.acceleration.abs() <= 5000.0 + 1e-3)
    );
    assert!(records.windows(2).all(|w| w[0].position <= w[1].position));
    let last = records.last().unwrap();
    assert!(last.status.contains(StatusFlag::AtTarget));
    assert_eq!(b.device.stats().executed, 1);

    // Without a velocity limit it moves at the device's own (360 by default).
    let mut b = Bench::new(CompactDeviceConfig::new(NODE, "elbow"));
    b.send(&command(ControlMode::Position, -90.0, Flags::NONE, 1));
    b.run_to(ms(200));
    assert!((b.device.velocity() + 360.0).abs() < 1e-9);
    b.run_to(ms(400));
    assert!((b.device.position() + 90.0).abs() < 1e-6);
}

#[test]
fn a_duplicate_is_answered_not_executed() {
    let mut d = elbow();
    let mv = command(ControlMode::Position, 90.0, Flags::REQUIRE_ACK, 7);
    assert!(d.handle_frame(ms(0), &frame(&mv)).is_some());
    assert_eq!(drain(&mut d).len(), 1);
    d.handle_timeout(ms(100));
    let at = d.position();
    // The resend: answered, not executed (the move is not restarted).
    assert!(d.handle_frame(ms(100), &frame(&mv)).is_none());
    let answer = only_record(&mut d);
    assert_eq!(answer.timestamp_us, 100_000);
    assert!(answer.status.contains(StatusFlag::InMotion));
    let s = d.stats();
    assert_eq!((s.executed, s.duplicates, s.feedback_sent), (1, 1, 2));
    assert_eq!(d.log().len(), 1);
    assert_eq!(d.log()[0].bytes, mv.encode().unwrap());
    assert_eq!(d.log()[0].at, ms(0));
    // After arrival a resend does not move it either.
    d.handle_timeout(ms(1000));
    assert_eq!(d.position(), 90.0);
    assert!(d.handle_frame(ms(1000), &frame(&mv)).is_none());
    assert!(only_record(&mut d).status.contains(StatusFlag::AtTarget));
    d.handle_timeout(ms(1100));
    assert_eq!(d.position(), 90.0);
    assert!(at < 90.0);
    // A datagram duplicate is not answered.
    let quiet = command(ControlMode::Position, 50.0, Flags::NONE, 8);
    assert!(d.handle_frame(ms(1100), &frame(&quiet)).is_some());
    assert!(d.handle_frame(ms(1101), &frame(&quiet)).is_none());
    assert!(d.poll_transmit().is_none());
    // The same setpoint with a new timestamp is a new command.
    let again = command(ControlMode::Position, 50.0, Flags::NONE, 9);
    assert!(d.handle_frame(ms(1102), &frame(&again)).is_some());
    let s = d.stats();
    assert_eq!((s.executed, s.duplicates), (3, 3));
}

#[test]
fn an_emergency_stop_holds_until_a_command_without_the_flag() {
    let mut d = elbow();
    let run = command(ControlMode::Velocity, 100.0, Flags::NONE, 1);
    d.handle_frame(ms(0), &frame(&run)).unwrap();
    d.handle_timeout(ms(500));
    assert!((d.velocity() - 100.0).abs() < 1e-9);
    let stop = command(ControlMode::Disabled, 0.0, Flags::EMERGENCY_STOP, 2);
    let e = d.handle_frame(ms(500), &frame(&stop)).unwrap();
    assert_eq!(e.outcome, CompactOutcome::Executed);
    // At once: no velocity, no motion, disabled, held.
    assert_eq!(d.velocity(), 0.0);
    assert!(d.stopped() && !d.enabled() && !d.is_moving());
    let held_at = d.position();
    d.handle_timeout(ms(2000));
    assert_eq!(d.position(), held_at);
    // A stop with a velocity setpoint is still a stop; a refused command
    // does not release it.
    let stop_again = command(ControlMode::Velocity, 100.0, Flags::EMERGENCY_STOP, 3);
    d.handle_frame(ms(2000), &frame(&stop_again)).unwrap();
    let refused = command(ControlMode::Position, 1000.0, Flags::NONE, 4);
    assert!(matches!(
        d.handle_frame(ms(2001), &frame(&refused)).unwrap().outcome,
        CompactOutcome::Refused(CompactRefusal::PositionOutsideLimits { .. })
    ));
    d.handle_timeout(ms(3000));
    assert!(d.stopped());
    assert_eq!(d.position(), held_at);
    // The release: a command without the flag, executed as usual.
    let release = command(ControlMode::Position, 0.0, Flags::REQUIRE_ACK, 5);
    assert!(
        d.handle_frame(ms(3000), &frame(&release))
            .unwrap()
            .outcome
            .is_executed()
    );
    assert!(!d.stopped() && d.enabled() && d.is_moving());
    d.handle_timeout(ms(5000));
    assert!(d.position().abs() < 1e-6);
    let s = d.stats();
    assert_eq!((s.emergency_stops, s.executed, s.refused), (2, 4, 1));

    // With an emergency deceleration it brakes at that rate.
    let config = CompactDeviceConfig {
        emergency_deceleration: Some(1000.0),
        ..CompactDeviceConfig::new(NODE, "elbow")
    };
    let mut d = SimCompactDevice::new(config).unwrap();
    d.handle_frame(ms(0), &frame(&run)).unwrap();
    d.handle_timeout(ms(500));
    d.handle_frame(ms(500), &frame(&stop)).unwrap();
    assert!(d.stopped() && d.is_moving());
    d.handle_timeout(ms(550));
    assert!((d.velocity() - 50.0).abs() < 1e-9, "{}", d.velocity());
    d.handle_timeout(ms(600));
    assert_eq!(d.velocity(), 0.0);
    assert!(!d.is_moving() && d.stopped());
}

#[test]
fn a_command_for_another_motor_is_ignored() {
    let mut d = elbow();
    let mut other = command(ControlMode::Position, 45.0, Flags::REQUIRE_ACK, 1);
    other.motor = MotorHash::of("wrist");
    assert!(d.handle_frame(ms(0), &frame(&other)).is_none());
    assert!(d.poll_transmit().is_none(), "not answered");
    d.handle_timeout(ms(500));
    assert_eq!(d.position(), 10.0);
    let s = d.stats();
    assert_eq!((s.ignored, s.executed, s.bad_frames), (1, 0, 0));
    assert!(d.log().is_empty());
    // Its own command on another CAN id is not for it either (and not counted).
    let own = command(ControlMode::Position, 45.0, Flags::REQUIRE_ACK, 2);
    let elsewhere = Frame::fd(CanId::standard(0x21).unwrap(), &own.encode().unwrap()).unwrap();
    assert!(d.handle_frame(ms(1), &elsewhere).is_none());
    assert_eq!(d.stats(), s);
}

#[test]
fn frames_that_are_not_24_bytes_are_bad_frames() {
    let mut d = elbow();
    let id = CanId::standard(NODE).unwrap();
    let bytes = command(ControlMode::Position, 45.0, Flags::REQUIRE_ACK, 1)
        .encode()
        .unwrap();
    // CAN-FD has no 23-byte frame: 23 bytes go out as 24 (zero-padded), and
    // a 23-byte frame cannot be built. The lengths next to 24 are 20 and 32.
    assert!(Frame::fd_exact(id, &bytes[..23], true, false).is_err());
    assert_eq!(Frame::fd(id, &bytes[..23]).unwrap().len(), 24);
    let mut long = bytes.to_vec();
    long.resize(32, 0);
    for f in [
        Frame::fd_exact(id, &bytes[..20], true, false).unwrap(),
        Frame::fd_exact(id, &long, true, false).unwrap(),
        Frame::classic(id, &bytes[..8]).unwrap(),
        Frame::fd(id, &[]).unwrap(),
    ] {
        assert!(d.handle_frame(ms(0), &f).is_none());
    }
    assert_eq!(d.stats().bad_frames, 4);
    // 24 bytes that do not decode (a reserved flag bit) are bad too.
    let mut reserved = bytes;
    reserved[13] |= 0x02;
    assert!(
        d.handle_frame(ms(0), &Frame::fd(id, &reserved).unwrap())
            .is_none()
    );
    let s = d.stats();
    assert_eq!((s.bad_frames, s.executed, s.feedback_sent), (5, 0, 0));
    assert!(d.poll_transmit().is_none());
    // The intact command is executed.
    assert!(
        d.handle_frame(ms(0), &Frame::fd(id, &bytes).unwrap())
            .is_some()
    );
}

#[test]
fn an_out_of_limit_setpoint_is_refused() {
    let config = CompactDeviceConfig {
        limits: CompactDeviceLimits {
            min_position: 0.0,
            max_position: 90.0,
            max_velocity: 60.0,
            max_acceleration: 500.0,
            max_torque: 2.0,
        },
        feedback_period: Duration::ZERO,
        ..CompactDeviceConfig::new(NODE, "elbow")
    };
    let mut d = SimCompactDevice::new(config).unwrap();
    d.keep_log();
    let ack = Flags::REQUIRE_ACK;
    // Something running, which a refusal leaves running.
    d.handle_frame(ms(0), &frame(&command(ControlMode::Position, 45.0, ack, 1)))
        .unwrap();
    drain(&mut d);

    let refusal = |d: &mut SimCompactDevice, cmd: CompactCommand| match d
        .handle_frame(ms(10), &frame(&cmd))
        .unwrap()
        .outcome
    {
        CompactOutcome::Refused(r) => r,
        CompactOutcome::Executed => panic!("{cmd:?} executed"),
    };
    assert_eq!(
        refusal(&mut d, command(ControlMode::Position, 300.0, ack, 2)),
        CompactRefusal::PositionOutsideLimits {
            setpoint: 300.0,
            min: 0.0,
            max: 90.0
        }
    );
    let answer = only_record(&mut d);
    assert!(answer.status.contains(StatusFlag::Warning));
    assert!(answer.status.contains(StatusFlag::PositionLimit));
    assert!(
        answer.status.contains(StatusFlag::InMotion),
        "still moving to 45"
    );
    assert_eq!(
        refusal(&mut d, command(ControlMode::Position, -0.5, ack, 3)),
        CompactRefusal::PositionOutsideLimits {
            setpoint: -0.5,
            min: 0.0,
            max: 90.0
        }
    );
    assert_eq!(
        refusal(&mut d, command(ControlMode::Velocity, -61.0, ack, 4)),
        CompactRefusal::VelocityAboveLimit {
            setpoint: -61.0,
            limit: 60.0
        }
    );
    let mut own_limit = command(ControlMode::Velocity, 30.0, ack, 5);
    own_limit.velocity_limit = Some(VelocityLimit(200)); // 20 units/s
    assert_eq!(
        refusal(&mut d, own_limit),
        CompactRefusal::VelocityAboveLimit {
            setpoint: 30.0,
            limit: 20.0
        }
    );
    assert_eq!(
        refusal(&mut d, command(ControlMode::Torque, 2.5, ack, 6)),
        CompactRefusal::TorqueAboveLimit {
            setpoint: 2.5,
            limit: 2.0
        }
    );
    let mut torque_limit = command(ControlMode::Torque, 1.5, ack, 7);
    torque_limit.torque_limit = Some(TorqueLimit(100)); // 1 Nm
    assert_eq!(
        refusal(&mut d, torque_limit),
        CompactRefusal::TorqueAboveLimit {
            setpoint: 1.5,
            limit: 1.0
        }
    );
    let mut standstill = command(ControlMode::Position, 20.0, ack, 8);
    standstill.velocity_limit = Some(VelocityLimit(0));
    assert_eq!(
        refusal(&mut d, standstill),
        CompactRefusal::ZeroVelocityLimit
    );
    assert_eq!(
        refusal(&mut d, command(ControlMode::Impedance, 20.0, ack, 9)),
        CompactRefusal::UnsupportedMode {
            mode: ControlMode::Impedance
        }
    );
    let answers = drain(&mut d);
    assert_eq!(answers.len(), 7, "each refusal is answered");
    let s = d.stats();
    assert_eq!((s.executed, s.refused), (1, 8));
    assert_eq!(d.log().len(), 9);

    // None of them moved it: the first move arrives.
    d.handle_timeout(ms(2000));
    assert_eq!(d.position(), 45.0);
    assert!(d.status().contains(StatusFlag::Warning));
    // A command that executes clears the warning.
    d.handle_frame(
        ms(2000),
        &frame(&command(ControlMode::Position, 90.0, ack, 10)),
    )
    .unwrap();
    let status = only_record(&mut d).status;
    assert!(!status.contains(StatusFlag::Warning));
    assert!(!status.contains(StatusFlag::PositionLimit));
    assert_eq!(d.refusal(), None);

    // A velocity run brakes in time for the limit it heads for and stops on
    // it: from 80 at 60/s with 500/s², it cruises from 0.12 s and brakes
    // from 86.4.
    let mut d = SimCompactDevice::new(CompactDeviceConfig {
        initial_position: 80.0,
        ..config
    })
    .unwrap();
    let run = command(ControlMode::Velocity, 60.0, ack, 1);
    d.handle_frame(ms(0), &frame(&run)).unwrap();
    d.handle_timeout(ms(150));
    assert!((d.velocity() - 60.0).abs() < 1e-9);
    d.handle_timeout(ms(200));
    assert!(d.velocity() < 60.0, "braking for the limit");
    d.handle_timeout(ms(1000));
    assert!((d.position() - 90.0).abs() < 1e-6, "{}", d.position());
    assert_eq!(d.velocity(), 0.0);
    assert!(d.status().contains(StatusFlag::PositionLimit));

    // A move whose path would pass a limit is refused: an emergency stop
    // braking gently (100/s²) toward 90, then a move that even at 500/s²
    // could not stop short of it.
    let mut d = SimCompactDevice::new(CompactDeviceConfig {
        initial_position: 80.0,
        emergency_deceleration: Some(100.0),
        ..config
    })
    .unwrap();
    d.handle_frame(ms(0), &frame(&run)).unwrap();
    d.handle_timeout(ms(200));
    let stop = command(ControlMode::Disabled, 0.0, Flags::EMERGENCY_STOP, 2);
    d.handle_frame(ms(200), &frame(&stop)).unwrap();
    d.handle_timeout(ms(220));
    let mut late = command(ControlMode::Position, 40.0, ack, 3);
    let r = match d.handle_frame(ms(220), &frame(&late)).unwrap().outcome {
        CompactOutcome::Refused(r) => r,
        CompactOutcome::Executed => panic!("executed"),
    };
    assert!(
        matches!(r, CompactRefusal::PathOutsideLimits { reach } if reach > 90.5),
        "{r:?}"
    );
    assert!(d.stopped(), "a refusal does not release the stop");
    // The gentle brake itself is not refused: it carries the device past
    // the limit, and the status says so.
    d.handle_timeout(ms(1000));
    assert!(d.position() > 90.0 && d.velocity() == 0.0);
    assert!(d.status().contains(StatusFlag::PositionLimit));
    // From rest the same move executes and releases the stop.
    late.timestamp_ms = 4;
    assert!(
        d.handle_frame(ms(1000), &frame(&late))
            .unwrap()
            .outcome
            .is_executed()
    );
    assert!(!d.stopped());
}

#[test]
fn velocity_and_torque_and_disabled() {
    let mut d = elbow();
    d.handle_frame(
        ms(0),
        &frame(&command(ControlMode::Velocity, -50.0, Flags::NONE, 1)),
    )
    .unwrap();
    // Ramped at 5000/s²: -50 after 10 ms.
    d.handle_timeout(ms(5));
    assert!((d.velocity() + 25.0).abs() < 1e-9);
    d.handle_timeout(ms(100));
    assert!((d.velocity() + 50.0).abs() < 1e-9);
    assert!(d.status().contains(StatusFlag::AtTarget));
    // Torque: the setpoint is applied; the velocity decays at 5000/s².
    d.handle_frame(
        ms(100),
        &frame(&command(ControlMode::Torque, -3.0, Flags::NONE, 2)),
    )
    .unwrap();
    assert_eq!(d.torque(), -3.0);
    d.handle_timeout(ms(105));
    assert!((d.velocity() + 25.0).abs() < 1e-9);
    d.handle_timeout(ms(200));
    assert_eq!(d.velocity(), 0.0);
    assert_eq!(d.feedback_record().torque, -3.0);
    assert_eq!(d.feedback_record().current, -30.0);
    // Disabled: zero torque, not enabled.
    d.handle_frame(
        ms(200),
        &frame(&command(ControlMode::Disabled, 0.0, Flags::NONE, 3)),
    )
    .unwrap();
    assert!(!d.enabled());
    assert_eq!(d.torque(), 0.0);
    assert!(!d.status().contains(StatusFlag::Enabled));
    // A velocity of zero brakes to rest.
    d.handle_frame(
        ms(200),
        &frame(&command(ControlMode::Velocity, 80.0, Flags::NONE, 4)),
    )
    .unwrap();
    d.handle_timeout(ms(300));
    d.handle_frame(
        ms(300),
        &frame(&command(ControlMode::Velocity, 0.0, Flags::NONE, 5)),
    )
    .unwrap();
    d.handle_timeout(ms(308));
    assert!((d.velocity() - 40.0).abs() < 1e-9);
    d.handle_timeout(ms(400));
    assert_eq!(d.velocity(), 0.0);
    assert!(d.status().contains(StatusFlag::AtTarget));
}

#[test]
fn the_feedback_period_is_respected() {
    let mut b = Bench::new(CompactDeviceConfig::new(NODE, "elbow"));
    b.run_to(ms(1000));
    // 50 Hz from time zero: 0, 20, ..., 1000 ms, stamped with the device's
    // clock and sent when stamped.
    let records = b.records();
    assert_eq!(records.len(), 51);
    for (i, (r, (at, _))) in records.iter().zip(&b.heard).enumerate() {
        let expected = 20_000 * u64::try_from(i).unwrap();
        assert_eq!(r.timestamp_us, expected);
        assert_eq!(u64::try_from(at.as_micros()).unwrap(), expected);
        assert_eq!(r.motor, MotorHash::of("elbow"));
        assert_eq!(r.health, 100);
    }
    // An answer comes at once and does not move the schedule.
    b.bus.advance_to(ms(1007));
    b.send(&command(ControlMode::Position, 5.0, Flags::REQUIRE_ACK, 1));
    b.run_to(ms(1100));
    let times: Vec<u64> = b.records()[51..].iter().map(|r| r.timestamp_us).collect();
    assert_eq!(
        times,
        [
            1_007_000, 1_020_000, 1_040_000, 1_060_000, 1_080_000, 1_100_000
        ]
    );
    assert_eq!(b.device.stats().feedback_sent, 57);

    // A period of zero: feedback only when asked.
    let mut b = Bench::new(CompactDeviceConfig {
        feedback_period: Duration::ZERO,
        ..CompactDeviceConfig::new(NODE, "elbow")
    });
    b.run_to(ms(100));
    assert!(b.heard.is_empty());
    assert_eq!(b.device.poll_timeout(), None);
}

#[test]
fn configurations_that_cannot_work_are_refused() {
    let field = |c: CompactDeviceConfig| match SimCompactDevice::new(c) {
        Err(SimError::InvalidConfig { field, .. }) => field,
        other => panic!("{other:?}"),
    };
    assert_eq!(
        field(CompactDeviceConfig::new(0x420, "elbow")),
        "feedback_node"
    );
    assert_eq!(field(CompactDeviceConfig::new(0x800, "elbow")), "node");
    let base = CompactDeviceConfig::new(NODE, "elbow");
    assert_eq!(
        field(CompactDeviceConfig {
            feedback_node: 0x800,
            ..base
        }),
        "feedback_node"
    );
    assert_eq!(
        field(CompactDeviceConfig {
            limits: CompactDeviceLimits {
                max_torque: f32::NAN,
                ..CompactDeviceLimits::default()
            },
            ..base
        }),
        "limits.max_torque"
    );
    assert_eq!(
        field(CompactDeviceConfig {
            initial_position: 200.0,
            ..base
        }),
        "initial_position"
    );
    assert_eq!(
        field(CompactDeviceConfig {
            emergency_deceleration: Some(0.0),
            ..base
        }),
        "emergency_deceleration"
    );
    // A node with the 0x400 bit works with a feedback node of its own.
    assert!(
        SimCompactDevice::new(CompactDeviceConfig {
            feedback_node: 0x421,
            ..CompactDeviceConfig::new(0x420, "elbow")
        })
        .is_ok()
    );
}

#[test]
fn run_serves_a_bus_in_real_time() {
    let bus = SimBus::new(SimConfig {
        clock: Clock::Real,
        ..SimConfig::default()
    })
    .unwrap();
    let (mut host, mut port) = (bus.port(), bus.port());
    let stop = Arc::new(AtomicBool::new(false));
    let seen = Arc::new(Mutex::new(Vec::new()));
    let device = {
        let (stop, seen) = (Arc::clone(&stop), Arc::clone(&seen));
        std::thread::spawn(move || {
            let mut d = SimCompactDevice::new(CompactDeviceConfig::new(NODE, "elbow")).unwrap();
            d.run(&mut port, &stop, |e| seen.lock().unwrap().push(*e))
                .unwrap();
            d
        })
    };
    host.send(&frame(&command(
        ControlMode::Position,
        30.0,
        Flags::REQUIRE_ACK,
        1,
    )))
    .unwrap();
    // Feedback until the move is over (it takes about 0.1 s).
    let deadline = std::time::Instant::now() + Duration::from_secs(5);
    let mut arrived = false;
    while std::time::Instant::now() < deadline && !arrived {
        if let Ok(r) = host.recv(ms(100)) {
            let rec = FeedbackRecord::decode(r.frame.data()).unwrap();
            arrived = rec.status.contains(StatusFlag::AtTarget) && rec.position == 30.0;
        }
    }
    stop.store(true, Ordering::Relaxed);
    let d = device.join().unwrap();
    assert!(arrived);
    assert_eq!(seen.lock().unwrap().len(), 1);
    assert_eq!(d.stats().executed, 1);
}
