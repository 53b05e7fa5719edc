//! The serial bus servo driver: Feetech STS and Dynamixel X servos, each
//! serial port one half-duplex bus with one transaction at a time.
//!
//! Each port runs cycles. A stop (torque off, or a hold) goes first, as
//! single writes each answered by its servo's own status (sent again until
//! it is, or given up after the retries): a stop is acknowledged only by
//! the servo that took it, and it never waits behind a read, which it cuts
//! short. A Dynamixel goal whose servo's torque is off is written the same
//! way (the goal, the torque on, the goal again: a servo may take its
//! present position for its goal as its torque comes on). The other goals
//! go out in one sync write (no status), then one sync read of every
//! servo's feedback block (the goal registers, position, velocity, load
//! or current, voltage, temperature; Feetech's torque register too),
//! which acknowledges each goal only when the servo reads it back
//! (written again otherwise, then refused), at the port's feedback period
//! and whenever a goal was written. A status that does not come, or comes
//! corrupt, is asked for again within the cycle (the missing servos only),
//! up to the retries, and counted; a servo that never answers is told to
//! nobody: the engine takes it offline when it has not been heard for its
//! time.
//!
//! Everything here is sans-IO: bytes out ([`ServoDriver::poll_transmit`],
//! with their port), bytes in ([`ServoDriver::handle_bytes`]), the time.

use std::collections::VecDeque;

mod port;
use std::time::Duration;

use motorwire_servo::table::{Model, Unit};
use motorwire_servo::{DecodeError, Instruction, Protocol, Status, decode_status, encode};
use motorwire_translate::{ServoCommand, ServoPort, ServoTarget, ServoVendor, goal_block};
use motorwire_wia::MotorFeedback;

use super::{DeviceError, DeviceId, Ended, Outcome};

/// What the driver tells: a servo heard, its reading, its order ended, a
/// bad packet.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum ServoNews {
    /// Servo `device` answered at `at`.
    Heard { device: DeviceId, at: Duration },
    /// Its feedback block, read at `at`.
    Reading {
        device: DeviceId,
        at: Duration,
        reading: Reading,
    },
    /// Its order ended.
    Ended { device: DeviceId, ended: Ended },
    /// Bytes on a port that were no status packet the driver waited for
    /// (noise, a wrong check, a servo it did not ask): why, and whether it
    /// is reported (with the bad packets left unreported before it: at
    /// most ten are reported a second).
    Bad {
        port: u8,
        error: String,
        report: Option<u64>,
    },
}

/// A servo's feedback block, read.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Reading {
    /// Its present position (raw steps).
    pub(crate) raw: i64,
    /// Its present position (degrees, through its calibration).
    pub(crate) position: f64,
    /// Its velocity (degrees a second).
    pub(crate) velocity: f64,
    /// Its load (percent of its maximum), where it reports one.
    pub(crate) load: Option<f64>,
    /// Its current (A), where it reports one.
    pub(crate) current: Option<f64>,
    /// Its supply (V).
    pub(crate) voltage: Option<f64>,
    /// Its temperature (°C).
    pub(crate) temperature: Option<f64>,
    /// Whether it says it is moving (Feetech's Moving register).
    pub(crate) moving: Option<bool>,
    /// Its status packet's error byte.
    pub(crate) error: u8,
    /// Whether its torque is on: its torque register where the block has
    /// it (Feetech), else as the bridge last wrote it.
    pub(crate) torque: Option<bool>,
    /// Its goal position register (raw steps).
    pub(crate) goal: Option<i64>,
}

/// The feedback block each vendor's servos are read in: its first
/// address and length (Feetech STS 40..=70: torque, acceleration, goal
/// position, goal time, goal velocity, ..., position, velocity, load,
/// voltage, temperature, status, moving, current; Dynamixel X 116..=146:
/// goal position, ..., current or load, velocity, position, trajectories,
/// voltage, temperature).
const fn feedback_block(vendor: ServoVendor) -> (u16, u16) {
    match vendor {
        ServoVendor::Feetech => (40, 31),
        ServoVendor::Dynamixel => (116, 31),
    }
}

/// Register `name` of `model` read from `block` (read from `start`), in
/// its signed steps; `None` when the model has no such register in the
/// block.
fn field(model: &Model, start: u16, block: &[u8], name: &str) -> Option<(i64, Unit)> {
    let r = model.register(name)?;
    let from = usize::from(r.address.checked_sub(start)?);
    let bytes = block.get(from..from + usize::from(r.size))?;
    Some((r.from_raw(model.protocol.value_of(bytes)?), r.unit))
}

/// A feedback block of `target`'s servo, read.
fn read_block(
    target: &ServoTarget,
    block: &[u8],
    error: u8,
    torque: Option<bool>,
) -> Option<Reading> {
    let model = target.table()?;
    let (start, _) = feedback_block(target.vendor);
    let (raw, _) = field(model, start, block, "Present_Position")?;
    let per_step = 360.0 / f64::from(model.resolution);
    #[allow(clippy::cast_precision_loss)]
    let scaled = |v: Option<(i64, Unit)>| {
        v.map(|(v, unit)| {
            let v = v as f64;
            match unit {
                Unit::StepsPerSecond { .. } => v * per_step,
                Unit::Rpm(k) => v * k * 6.0,
                Unit::Volts(k) | Unit::Celsius(k) | Unit::Percent(k) => v * k,
                Unit::Milliamps(k) => v * k / 1000.0,
                _ => v,
            }
        })
    };
    Some(Reading {
        raw,
        position: target.degrees(raw),
        velocity: scaled(field(model, start, block, "Present_Velocity")).unwrap_or(f64::NAN),
        load: scaled(field(model, start, block, "Present_Load")),
        current: scaled(field(model, start, block, "Present_Current")),
        voltage: scaled(
            field(model, start, block, "Present_Voltage")
                .or_else(|| field(model, start, block, "Present_Input_Voltage")),
        ),
        temperature: scaled(field(model, start, block, "Present_Temperature")),
        moving: field(model, start, block, "Moving").map(|(v, _)| v != 0),
        error,
        torque: field(model, start, block, "Torque_Enable")
            .map(|(v, _)| v != 0)
            .or(torque),
        goal: field(model, start, block, "Goal_Position").map(|(v, _)| v),
    })
}

/// A reading as WIA feedback for motor `motor`, in `unit`, at
/// `timestamp` (Unix ms). The load is the feedback's control effort
/// (percent); the torque in N·m is not known (NaN).
pub(crate) fn feedback_to_wia(
    motor: &str,
    timestamp: f64,
    unit: motorwire_translate::AngleUnit,
    r: &Reading,
    vendor: ServoVendor,
) -> MotorFeedback {
    let mut f = MotorFeedback::new(
        motor,
        timestamp,
        unit.from_degrees(r.position),
        unit.from_degrees(r.velocity),
        f64::NAN,
        motorwire_wia::MotorStatus::default(),
    );
    f.current = r.current;
    f.voltage = r.voltage;
    f.temperature = r.temperature;
    f.control_effort = r.load;
    f.status.enabled = r.torque;
    f.status.in_motion = Some(r.moving.unwrap_or(r.velocity.abs() > 1e-6));
    // Feetech: the error bits (voltage, angle, overheat, overcurrent,
    // overload); Dynamixel: the hardware alert bit.
    let fault = match vendor {
        ServoVendor::Feetech => r.error != 0,
        ServoVendor::Dynamixel => r.error & 0x80 != 0,
    };
    f.status.fault = Some(fault);
    f
}

/// One servo of a port.
#[derive(Debug)]
struct Servo {
    device: DeviceId,
    target: ServoTarget,
    /// Its order not yet written: its number, the order and how many
    /// times it was written before.
    waiting: Option<(u32, ServoCommand, u8)>,
    /// Its goal written by a sync write, to be read back.
    written: Option<Written>,
    /// Its last present position (raw steps).
    present: Option<i64>,
    /// Its torque, as last written or read.
    torque: Option<bool>,
    /// A stop its servo never answered: written again every cycle until
    /// it is, or until the servo's next order.
    sticky: Option<ServoCommand>,
    /// When the sticky stop is written again next.
    sticky_next: Duration,
    /// The stop (its number) whose torque off went out in the port's
    /// sync write of every servo's torque off, ahead of its answered write.
    blasted: Option<u32>,
}

/// A goal written by a sync write and not yet read back.
#[derive(Debug, Clone, Copy)]
struct Written {
    msg: u32,
    cmd: ServoCommand,
    /// How many times it was written.
    attempts: u8,
    /// The goal step it wrote.
    goal: i64,
}

/// An order written as single writes, each answered by its servo's
/// status: what is left of it.
#[derive(Debug)]
struct Steps {
    device: DeviceId,
    id: u8,
    /// Its number (`None`: given up by the engine, nothing to tell).
    msg: Option<u32>,
    /// The write on the wire, and how many times it was sent.
    current: Vec<u8>,
    sends: u8,
    /// The writes after it.
    rest: VecDeque<Vec<u8>>,
    /// Every send of the order, and the torque once it is done.
    total: u8,
    torque_after: bool,
    deadline: Duration,
    /// The order it writes.
    cmd: ServoCommand,
}

/// What a port waits for.
#[derive(Debug)]
enum Await {
    /// The statuses of a read: the ids still to answer, until when, and
    /// the reads sent for it.
    Read {
        ids: Vec<u8>,
        deadline: Duration,
        attempts: u8,
    },
    /// The status of one write of an order.
    Steps(Steps),
}

impl Await {
    const fn deadline(&self) -> Duration {
        match self {
            Self::Read { deadline, .. } => *deadline,
            Self::Steps(s) => s.deadline,
        }
    }
}

/// One serial port: its servos, its cycle, its transaction in flight.
#[derive(Debug)]
struct Port {
    protocol: Protocol,
    vendor: ServoVendor,
    servos: Vec<Servo>,
    /// The feedback period, and the next read.
    period: Duration,
    next_read: Duration,
    awaiting: Option<Await>,
    /// Bytes received and not yet read as a status.
    rx: Vec<u8>,
    /// How long a read's statuses, and a write's, are waited for.
    read_wait: Duration,
    write_wait: Duration,
}

/// The driver of every servo port.
#[derive(Debug)]
pub(crate) struct ServoDriver {
    ports: Vec<Port>,
    retries: u8,
    next_msg: u32,
    out: VecDeque<(u8, Vec<u8>)>,
    news: VecDeque<ServoNews>,
    /// Statuses asked again (a retry within a cycle), and servos whose
    /// status never came in a cycle.
    pub(crate) retried: u64,
    pub(crate) missed: u64,
    /// When the last bad packet was reported, and those left unreported
    /// since.
    bad_reported: Option<Duration>,
    bad_suppressed: u64,
    /// The time of the call in progress.
    now: Duration,
}

/// The bytes a port receives at most between two reads of them (a
/// stream with no packet in it is let go beyond it).
const MAX_RX: usize = 4096;

/// What a status is waited for beyond its bytes' time on the wire: a USB
/// serial adapter's latency timer (16 ms on an FTDI chip) and the host's.
const SLACK: Duration = Duration::from_millis(20);

/// `bytes` at `baud` (10 bits a byte), and [`SLACK`].
fn wait_for(bytes: u64, baud: u32) -> Duration {
    Duration::from_micros(bytes * 10 * 1_000_000 / u64::from(baud.max(1))).saturating_add(SLACK)
}

impl ServoDriver {
    /// A driver for `ports` (the map's), with `servos` (each device and
    /// its servo), reading every `period` and asking again up to
    /// `retries` times.
    pub(crate) fn new(
        ports: &[ServoPort],
        servos: impl Iterator<Item = (DeviceId, ServoTarget)>,
        period: Duration,
        retries: u8,
    ) -> Self {
        let mut out: Vec<Port> = ports
            .iter()
            .map(|p| {
                let vendor = if p.protocol == Protocol::Dxl2 {
                    ServoVendor::Dynamixel
                } else {
                    ServoVendor::Feetech
                };
                Port {
                    protocol: p.protocol,
                    vendor,
                    servos: Vec::new(),
                    period,
                    next_read: Duration::ZERO,
                    awaiting: None,
                    rx: Vec::new(),
                    // A read of 16 servos' blocks with their packets; a
                    // write of a goal block and its status.
                    read_wait: wait_for(16 * (31 + 12) + 30, p.baud),
                    write_wait: wait_for(40, p.baud),
                }
            })
            .collect();
        for (device, target) in servos {
            if let Some(p) = out.get_mut(usize::from(target.port)) {
                p.servos.push(Servo {
                    device,
                    target,
                    waiting: None,
                    written: None,
                    present: None,
                    torque: None,
                    sticky: None,
                    sticky_next: Duration::ZERO,
                    blasted: None,
                });
            }
        }
        for p in &mut out {
            p.servos.sort_by_key(|s| s.target.id);
        }
        Self {
            ports: out,
            retries,
            next_msg: 1,
            out: VecDeque::new(),
            news: VecDeque::new(),
            retried: 0,
            missed: 0,
            bad_reported: None,
            bad_suppressed: 0,
            now: Duration::ZERO,
        }
    }

    /// A bad packet on port `port`: told, and reported at most ten times a
    /// second.
    fn bad(&mut self, port: usize, error: String) {
        let due = self
            .bad_reported
            .is_none_or(|t| self.now.saturating_sub(t) >= Duration::from_millis(100));
        let report = if due {
            self.bad_reported = Some(self.now);
            Some(std::mem::take(&mut self.bad_suppressed))
        } else {
            self.bad_suppressed += 1;
            None
        };
        self.news.push_back(ServoNews::Bad {
            port: u8::try_from(port).unwrap_or(u8::MAX),
            error,
            report,
        });
    }

    fn servo_mut(&mut self, device: DeviceId) -> Option<(usize, &mut Servo)> {
        self.ports.iter_mut().enumerate().find_map(|(k, p)| {
            p.servos
                .iter_mut()
                .find(|s| s.device == device)
                .map(|s| (k, s))
        })
    }

    /// Sends `cmd` to servo `device`: written with its port's next writes
    /// (built when the bytes are asked for, [`ServoDriver::poll_transmit`]:
    /// until then it can be taken back); its number.
    pub(crate) fn send(&mut self, now: Duration, device: DeviceId, cmd: ServoCommand) -> u32 {
        self.now = now;
        let msg = self.next_msg;
        self.next_msg = self.next_msg.wrapping_add(1).max(1);
        if let Some((_, s)) = self.servo_mut(device) {
            s.waiting = Some((msg, cmd, 0));
            s.sticky = None;
        }
        msg
    }

    /// Servo `device`'s order is given up: not written if it waits, not
    /// acknowledged if it was.
    pub(crate) fn forget(&mut self, device: DeviceId) {
        for p in &mut self.ports {
            if let Some(Await::Steps(s)) = &mut p.awaiting
                && s.device == device
            {
                s.msg = None;
            }
        }
        if let Some((_, s)) = self.servo_mut(device) {
            s.waiting = None;
            s.written = None;
        }
    }

    /// Takes back servo `device`'s order if it was not written yet.
    pub(crate) fn take_back_unsent(&mut self, device: DeviceId) -> bool {
        // (A sticky stop's write again, number 0, is the driver's own.)
        self.servo_mut(device)
            .is_some_and(|(_, s)| s.waiting.take_if(|w| w.0 != 0).is_some())
    }

    /// The next bytes to write, and the port (its index in the map's
    /// servo ports) to write them on: each port's next transaction is
    /// built now, from what waits for it at the time of the last call (a
    /// stop cuts a read in progress short).
    pub(crate) fn poll_transmit(&mut self) -> Option<(u8, Vec<u8>)> {
        if self.out.is_empty() {
            for k in 0..self.ports.len() {
                self.preempt(k);
                self.pump(self.now, k);
            }
        }
        self.out.pop_front()
    }

    /// The next thing to tell.
    pub(crate) fn poll(&mut self) -> Option<ServoNews> {
        self.news.pop_front()
    }

    /// When the driver next has work: a status's wait ending, or a port's
    /// next read (what is due is built at the next
    /// [`ServoDriver::poll_transmit`]).
    pub(crate) fn deadline(&self) -> Option<Duration> {
        self.ports
            .iter()
            .filter(|p| !p.servos.is_empty())
            .map(|p| p.awaiting.as_ref().map_or(p.next_read, Await::deadline))
            .min()
    }

    /// The work due at `now`: statuses that did not all come (asked again,
    /// or given up and counted).
    pub(crate) fn expire(&mut self, now: Duration) {
        self.now = now;
        for k in 0..self.ports.len() {
            let due = self
                .ports
                .get(k)
                .and_then(|p| p.awaiting.as_ref())
                .is_some_and(|a| a.deadline() <= now);
            if due {
                self.timed_out(now, k);
            }
        }
    }

    /// Bytes received on port `port` at `now`.
    pub(crate) fn handle_bytes(&mut self, now: Duration, port: u8, bytes: &[u8]) {
        self.now = now;
        let k = usize::from(port);
        let Some(p) = self.ports.get_mut(k) else {
            return;
        };
        p.rx.extend_from_slice(bytes);
        loop {
            let Some(p) = self.ports.get_mut(k) else {
                return;
            };
            match decode_status(p.protocol, &p.rx, None) {
                Ok(d) => {
                    p.rx.drain(..d.consumed.min(p.rx.len()));
                    self.status(now, k, &d.status);
                }
                Err(DecodeError::Incomplete { .. }) if p.rx.len() <= MAX_RX => break,
                Err(DecodeError::Timeout) => {
                    // No header in what came: keep what may be the start
                    // of one.
                    let keep = p.rx.len().saturating_sub(3);
                    p.rx.drain(..keep);
                    break;
                }
                Err(e) => {
                    p.rx.drain(..1);
                    self.bad(k, e.to_string());
                }
            }
        }
    }

    /// Tells that `device`'s order `msg` ended at `now` so.
    fn ended(&mut self, device: DeviceId, msg_id: u32, outcome: Outcome, attempts: u8) {
        // Number 0: a sticky stop's write again, the driver's own.
        if msg_id == 0 {
            return;
        }
        self.news.push_back(ServoNews::Ended {
            device,
            ended: Ended {
                msg_id,
                outcome,
                attempts,
                at: self.now,
            },
        });
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing, clippy::panic)]

    use super::*;
    use motorwire_translate::Calibration;

    fn sts(id: u8) -> ServoTarget {
        ServoTarget {
            vendor: ServoVendor::Feetech,
            port: 0,
            id,
            model: "sts3215",
            calibration: Calibration {
                homing_offset: 0,
                range_min: 1047,
                range_max: 3047,
                drive_mode: 0,
            },
            stop_holds: false,
        }
    }

    fn driver(ids: &[u8]) -> ServoDriver {
        let ports = [ServoPort {
            path: "/dev/ttyACM0".to_owned(),
            baud: 1_000_000,
            protocol: Protocol::Scs0,
        }];
        ServoDriver::new(
            &ports,
            ids.iter()
                .enumerate()
                .map(|(k, id)| (DeviceId::at(k), sts(*id))),
            Duration::from_millis(20),
            2,
        )
    }

    fn hex(b: &[u8]) -> String {
        b.iter().map(|b| format!("{b:02X}")).collect()
    }

    fn ms(n: u64) -> Duration {
        Duration::from_millis(n)
    }

    /// Servo `id`'s answer to the feedback read (the block from 40): its
    /// torque, its goal, at `raw`, 12.0 V, 31 °C.
    fn status(id: u8, torque: u8, goal: u16, raw: u16) -> Vec<u8> {
        let mut params = vec![0; 31];
        params[0] = torque;
        params[2..4].copy_from_slice(&goal.to_le_bytes());
        params[16..18].copy_from_slice(&raw.to_le_bytes());
        params[22] = 120;
        params[23] = 31;
        motorwire_servo::encode_status(
            Protocol::Scs0,
            &Status {
                id,
                error: 0,
                params,
            },
        )
        .unwrap()
    }

    /// Servo `id`'s answer to a write.
    fn write_status(id: u8) -> Vec<u8> {
        let status = Status {
            id,
            error: 0,
            params: Vec::new(),
        };
        motorwire_servo::encode_status(Protocol::Scs0, &status).unwrap()
    }

    fn sent(d: &mut ServoDriver) -> Vec<String> {
        std::iter::from_fn(|| d.poll_transmit())
            .map(|(_, b)| hex(&b))
            .collect()
    }

    fn ended(d: &mut ServoDriver) -> Vec<Ended> {
        std::iter::from_fn(|| d.poll())
            .filter_map(|n| match n {
                ServoNews::Ended { ended, .. } => Some(ended),
                _ => None,
            })
            .collect()
    }

    const READ_1: &str = "FFFFFE0582281F0132";
    const READ_12: &str = "FFFFFE0682281F01022F";

    #[test]
    fn a_goal_is_one_sync_write_acknowledged_when_its_servo_reads_it_back() {
        let mut d = driver(&[1]);
        // The first cycle's read (servo 1's block from 40, 31 bytes),
        // answered.
        assert_eq!(sent(&mut d), [READ_1]);
        d.handle_bytes(ms(1), 0, &status(1, 0, 2047, 2047));
        assert!(matches!(d.poll(), Some(ServoNews::Heard { .. })));
        let Some(ServoNews::Reading { reading, .. }) = d.poll() else {
            panic!("no reading")
        };
        assert_eq!((reading.raw, reading.position), (2047, 0.0));
        assert_eq!(
            (reading.voltage, reading.temperature),
            (Some(12.0), Some(31.0))
        );
        assert_eq!((reading.torque, reading.goal), (Some(false), Some(2047)));
        // 10° at 90°/s and 900°/s²: torque on, acceleration 102, step
        // 2161 (0x0871), goal time 0, 1024 steps/s, in one sync write from
        // 40; then the read that reads it back.
        let goal = ServoCommand::Goal {
            position: 10.0,
            velocity: Some(90.0),
            acceleration: Some(900.0),
        };
        let msg = d.send(ms(2), DeviceId::at(0), goal);
        assert_eq!(
            sent(&mut d),
            [
                "FFFFFE0D83280801".to_owned() + "01667108000000045C",
                READ_1.to_owned()
            ]
        );
        // Its answer in two pieces, with noise before it: the goal read
        // back, the torque on.
        let answer = status(1, 1, 2161, 2100);
        d.handle_bytes(ms(3), 0, &[0x00, 0xFF]);
        d.handle_bytes(ms(3), 0, &answer[..5]);
        d.handle_bytes(ms(4), 0, &answer[5..]);
        let e = ended(&mut d);
        assert_eq!(
            (e[0].msg_id, &e[0].outcome, e[0].attempts),
            (msg, &Outcome::Acked, 1)
        );
    }

    #[test]
    fn a_goal_the_servo_does_not_read_back_is_written_again_then_refused() {
        let mut d = driver(&[1]);
        sent(&mut d);
        d.handle_bytes(ms(1), 0, &status(1, 0, 2047, 2047));
        let goal = ServoCommand::Goal {
            position: 10.0,
            velocity: Some(90.0),
            acceleration: None,
        };
        let msg = d.send(ms(2), DeviceId::at(0), goal);
        for n in 0..3 {
            let out = sent(&mut d);
            assert_eq!(out.len(), 2, "the goal written again ({n}), then read");
            // The write was lost: the servo still holds its old goal.
            d.handle_bytes(ms(3 + n), 0, &status(1, 0, 2047, 2047));
        }
        let e = ended(&mut d);
        let Outcome::Nacked { why, .. } = &e[0].outcome else {
            panic!("{e:?}")
        };
        assert_eq!(e[0].msg_id, msg);
        assert_eq!(
            why,
            "servo 1 did not take the goal after 3 writes: it holds goal step 2047"
        );
    }

    #[test]
    fn a_stop_cuts_a_read_short_and_is_acknowledged_only_by_its_servo() {
        let mut d = driver(&[1, 2]);
        assert_eq!(sent(&mut d), [READ_12]);
        // Servo 2 is silent; the stop does not wait for the read's end.
        d.handle_bytes(ms(1), 0, &status(1, 1, 2047, 2047));
        let msg = d.send(ms(2), DeviceId::at(1), ServoCommand::TorqueOff);
        // Torque_Enable (40) 0 for servo 2 in a sync write at once, then
        // the same as a write its servo answers.
        assert_eq!(sent(&mut d), ["FFFFFE0683280102004D", "FFFF0204032800CE"]);
        // Lost: sent again at its wait's end (the wire's time and 20 ms).
        let wait = d.deadline().unwrap();
        assert!(wait <= ms(2) + ms(21), "{wait:?}");
        d.expire(wait);
        assert_eq!(sent(&mut d), ["FFFF0204032800CE"]);
        assert!(ended(&mut d).is_empty(), "no status: not acknowledged");
        d.handle_bytes(wait + ms(1), 0, &write_status(2));
        let e = ended(&mut d);
        assert_eq!(
            (e[0].msg_id, &e[0].outcome, e[0].attempts),
            (msg, &Outcome::Acked, 2)
        );
    }

    #[test]
    fn a_stop_never_answered_times_out_after_every_try() {
        let mut d = driver(&[1]);
        sent(&mut d);
        d.handle_bytes(ms(1), 0, &status(1, 1, 2047, 2047));
        let msg = d.send(ms(2), DeviceId::at(0), ServoCommand::TorqueOff);
        let mut writes = sent(&mut d)
            .iter()
            .filter(|p| p.starts_with("FFFF0104"))
            .count();
        for _ in 0..2 {
            let wait = d.deadline().unwrap();
            d.expire(wait);
            writes += sent(&mut d)
                .iter()
                .filter(|p| p.starts_with("FFFF0104"))
                .count();
        }
        assert_eq!(writes, 3, "the first write and two retries");
        let wait = d.deadline().unwrap();
        d.expire(wait);
        let e = ended(&mut d);
        assert_eq!(
            (e[0].msg_id, &e[0].outcome, e[0].attempts),
            (msg, &Outcome::TimedOut, 3)
        );
    }

    #[test]
    fn a_missing_status_is_asked_again_for_that_servo_alone_then_counted() {
        let mut d = driver(&[1, 2]);
        assert_eq!(sent(&mut d), [READ_12]);
        d.handle_bytes(ms(1), 0, &status(1, 0, 2047, 2047));
        // Servo 2 is silent: at the wait's end, asked again alone.
        let wait = d.deadline().unwrap();
        d.expire(wait);
        assert_eq!(sent(&mut d), ["FFFFFE0582281F0231"]);
        assert_eq!(d.retried, 1);
        for _ in 0..2 {
            let wait = d.deadline().unwrap();
            d.expire(wait);
        }
        assert_eq!((d.retried, d.missed), (2, 1));
        let next = d.deadline().unwrap();
        d.expire(next);
        assert_eq!(sent(&mut d).last().unwrap(), READ_12);
    }

    /// A goal and the stop that follows it at the same instant: the goal,
    /// taken back before its bytes were asked for, is never written; the
    /// stop (torque off) is.
    #[test]
    fn a_goal_taken_back_before_its_bytes_are_built_is_never_written() {
        let mut d = driver(&[1]);
        let goal = ServoCommand::Goal {
            position: 10.0,
            velocity: Some(90.0),
            acceleration: None,
        };
        d.send(Duration::ZERO, DeviceId::at(0), goal);
        assert!(d.take_back_unsent(DeviceId::at(0)));
        d.send(Duration::ZERO, DeviceId::at(0), ServoCommand::TorqueOff);
        assert_eq!(sent(&mut d), ["FFFFFE0683280101004E", "FFFF0104032800CF"]);
    }

    /// A stop its servo never answers is told as timed out once, and
    /// written again every cycle until the servo answers it.
    #[test]
    fn a_stop_never_answered_is_written_again_every_cycle_until_it_is() {
        let mut d = driver(&[1]);
        sent(&mut d);
        d.handle_bytes(ms(1), 0, &status(1, 1, 2047, 2047));
        let msg = d.send(ms(2), DeviceId::at(0), ServoCommand::TorqueOff);
        sent(&mut d);
        for _ in 0..3 {
            let wait = d.deadline().unwrap();
            d.expire(wait);
            sent(&mut d);
        }
        let e = ended(&mut d);
        assert_eq!((e[0].msg_id, &e[0].outcome), (msg, &Outcome::TimedOut));
        // The next cycles: the torque off again, before each read.
        let mut again = 0;
        for _ in 0..12 {
            let next = d.deadline().unwrap();
            d.expire(next);
            again += sent(&mut d)
                .iter()
                .filter(|p| *p == "FFFF0104032800CF")
                .count();
        }
        assert!(again >= 2, "written again {again} times");
        // Answered at last: written no more, and nothing more told.
        let next = d.deadline().unwrap();
        d.expire(next);
        let out = sent(&mut d);
        if out.iter().any(|p| p == "FFFF0104032800CF") {
            d.handle_bytes(next, 0, &write_status(1));
        }
        for _ in 0..6 {
            let next = d.deadline().unwrap();
            d.expire(next);
            let out = sent(&mut d);
            if out.iter().any(|p| p.starts_with("FFFFFE")) {
                d.handle_bytes(next, 0, &status(1, 0, 2047, 2047));
            }
            assert!(!out.iter().any(|p| p == "FFFF0104032800CF"), "{out:?}");
        }
        assert!(ended(&mut d).is_empty());
    }

    /// A Dynamixel goal written as answered writes (its torque off) waits
    /// behind another servo's stop, which does not wait for the goal's
    /// retries.
    #[test]
    fn a_stop_cuts_a_goals_answered_writes_short() {
        let xl = |id| ServoTarget {
            vendor: ServoVendor::Dynamixel,
            model: "xl330-m288",
            ..sts(id)
        };
        let ports = [ServoPort {
            path: "/dev/ttyUSB0".to_owned(),
            baud: 1_000_000,
            protocol: Protocol::Dxl2,
        }];
        let mut d = ServoDriver::new(
            &ports,
            [(DeviceId::at(0), xl(1)), (DeviceId::at(1), xl(2))].into_iter(),
            ms(20),
            2,
        );
        let goal = ServoCommand::Goal {
            position: 10.0,
            velocity: Some(90.0),
            acceleration: None,
        };
        d.send(Duration::ZERO, DeviceId::at(0), goal);
        // Its goal block to servo 1 (Write, instruction 3, from 108).
        let first = sent(&mut d);
        assert_eq!(
            first.len(),
            1,
            "{:?}",
            std::iter::from_fn(|| d.poll()).collect::<Vec<_>>()
        );
        assert!(
            first[0].starts_with("FFFFFD0001") && first[0].contains("036C00"),
            "{first:?}"
        );
        // Unanswered; a stop of servo 2 comes: it goes now.
        d.send(ms(1), DeviceId::at(1), ServoCommand::TorqueOff);
        let out = sent(&mut d);
        assert!(
            out[0].starts_with("FFFFFD00FE") && out[0].contains("834000"),
            "{out:?}"
        );
        assert!(
            out[1].starts_with("FFFFFD0002") && out[1].contains("034000"),
            "{out:?}"
        );
        assert_eq!(out.len(), 2, "{out:?}");
    }
}
