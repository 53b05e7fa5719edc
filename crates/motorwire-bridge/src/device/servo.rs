//! The serial bus servo driver: Feetech STS and Dynamixel X servos, each
//! serial port one half-duplex bus with one transaction at a time.
//!
//! Each port runs cycles: the orders waiting for its servos go out in one
//! sync write per register block (a Feetech goal turns the torque on in
//! the same write; a Dynamixel goal is followed by a sync write of its
//! torque), then one sync read of the feedback block of every servo of
//! the port (position, velocity, load or current, voltage, temperature),
//! at the port's feedback period and whenever an order was written. A
//! sync write has no status: a servo's order is acknowledged by its next
//! status, which comes after the servo took the write (the bus is in
//! order). A status that does not come, or comes corrupt, is asked for
//! again within the cycle (the missing servos only), up to the retries,
//! and counted; a servo that never answers is told to nobody: the engine
//! takes it offline when it has not been heard for its time.
//!
//! Everything here is sans-IO: bytes out ([`ServoDriver::poll_transmit`],
//! with their port), bytes in ([`ServoDriver::handle_bytes`]), the time.

use std::collections::VecDeque;
use std::time::Duration;

use motorwire_servo::table::{Model, Unit};
use motorwire_servo::{DecodeError, Instruction, Protocol, Status, decode_status, encode};
use motorwire_translate::{ServoCommand, ServoPort, ServoTarget, ServoVendor, goal_block};
use motorwire_wia::MotorFeedback;

use super::{DeviceId, Ended, Outcome};

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
    /// Whether its torque is on, as the bridge last wrote it.
    pub(crate) torque: Option<bool>,
}

/// The feedback block each vendor's servos are read in: its first
/// address and length (Feetech STS 56..=70: position, velocity, load,
/// voltage, temperature, status, moving, current; Dynamixel X 126..=146:
/// current or load, velocity, position, trajectories, voltage,
/// temperature).
const fn feedback_block(vendor: ServoVendor) -> (u16, u16) {
    match vendor {
        ServoVendor::Feetech => (56, 15),
        ServoVendor::Dynamixel => (126, 21),
    }
}

/// `bytes` as one value of the protocol's byte order.
fn value_of(protocol: Protocol, bytes: &[u8]) -> u32 {
    let fold = |acc: u32, b: &u8| (acc << 8) | u32::from(*b);
    if protocol.big_endian() {
        bytes.iter().fold(0, fold)
    } else {
        bytes.iter().rev().fold(0, fold)
    }
}

/// Register `name` of `model` read from `block` (read from `start`), in
/// its signed steps; `None` when the model has no such register in the
/// block.
fn field(model: &Model, start: u16, block: &[u8], name: &str) -> Option<(i64, Unit)> {
    let r = model.register(name)?;
    let from = usize::from(r.address.checked_sub(start)?);
    let bytes = block.get(from..from + usize::from(r.size))?;
    Some((r.from_raw(value_of(model.protocol, bytes)), r.unit))
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
        torque,
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
    /// Its order written and not yet acknowledged (by its next status):
    /// its number, the order and how many times it was written.
    written: Option<(u32, ServoCommand, u8)>,
    /// Its last present position (raw steps).
    present: Option<i64>,
    /// Its torque, as last written.
    torque: Option<bool>,
}

/// What a port waits for: the statuses of a read.
#[derive(Debug)]
struct Awaiting {
    /// The ids whose status has not come.
    ids: Vec<u8>,
    deadline: Duration,
    /// The reads sent for it so far.
    attempts: u8,
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
    awaiting: Option<Awaiting>,
    /// Bytes received and not yet read as a status.
    rx: Vec<u8>,
    /// How long a read's statuses are waited for.
    wait: Duration,
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
    /// The time of the call in progress (bad packets are reported within
    /// a rate).
    now: Duration,
}

/// The bytes a port receives at most between two reads of them (a
/// stream with no packet in it is let go beyond it).
const MAX_RX: usize = 4096;

impl ServoDriver {
    /// A driver for `ports` (the map's), with `servos` (each device and
    /// its servo), reading every `period`, waiting `timeout` at least for a
    /// read's statuses (more where the bytes take longer on the wire), and
    /// asking again up to `retries` times.
    pub(crate) fn new(
        ports: &[ServoPort],
        servos: impl Iterator<Item = (DeviceId, ServoTarget)>,
        period: Duration,
        timeout: Duration,
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
                    // 10 bits a byte: a sync read of 16 servos' 21 bytes
                    // and their packets, twice over, and the timeout.
                    wait: timeout.saturating_add(Duration::from_micros(
                        2 * 16 * 40 * 10 * 1_000_000 / u64::from(p.baud.max(1)),
                    )),
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
        }
        msg
    }

    /// Servo `device`'s order is given up: not written if it waits, not
    /// acknowledged if it was.
    pub(crate) fn forget(&mut self, device: DeviceId) {
        if let Some((_, s)) = self.servo_mut(device) {
            s.waiting = None;
            s.written = None;
        }
    }

    /// Takes back servo `device`'s order if it was not written yet.
    pub(crate) fn take_back_unsent(&mut self, device: DeviceId) -> bool {
        self.servo_mut(device)
            .is_some_and(|(_, s)| s.waiting.take().is_some())
    }

    /// The next bytes to write, and the port (its index in the map's
    /// servo ports) to write them on: each free port's next transaction is
    /// built now, from what waits for it at the time of the last call.
    pub(crate) fn poll_transmit(&mut self) -> Option<(u8, Vec<u8>)> {
        if self.out.is_empty() {
            for k in 0..self.ports.len() {
                self.pump(self.now, k);
            }
        }
        self.out.pop_front()
    }

    /// The next thing to tell.
    pub(crate) fn poll(&mut self) -> Option<ServoNews> {
        self.news.pop_front()
    }

    /// When the driver next has work: a read's wait ending, or a port's
    /// next read (what is due is built at the next
    /// [`ServoDriver::poll_transmit`]).
    pub(crate) fn deadline(&self) -> Option<Duration> {
        self.ports
            .iter()
            .filter(|p| !p.servos.is_empty())
            .map(|p| p.awaiting.as_ref().map_or(p.next_read, |a| a.deadline))
            .min()
    }

    /// The work due at `now`: reads whose statuses did not all come (asked
    /// again, or given up and counted), and each free port's cycle.
    pub(crate) fn expire(&mut self, now: Duration) {
        self.now = now;
        for k in 0..self.ports.len() {
            let Some(p) = self.ports.get_mut(k) else {
                continue;
            };
            if p.awaiting.as_ref().is_some_and(|a| a.deadline <= now) {
                self.read_timed_out(now, k);
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
        let (_, length) = feedback_block(p.vendor);
        loop {
            let Some(p) = self.ports.get_mut(k) else {
                return;
            };
            match decode_status(p.protocol, &p.rx, None) {
                Ok(d) => {
                    p.rx.drain(..d.consumed.min(p.rx.len()));
                    self.status(now, k, &d.status, usize::from(length));
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

    /// A status on port `k`.
    fn status(&mut self, now: Duration, k: usize, status: &Status, length: usize) {
        let Some(p) = self.ports.get_mut(k) else {
            return;
        };
        let asked = p
            .awaiting
            .as_ref()
            .is_some_and(|a| a.ids.contains(&status.id));
        let Some(s) = p.servos.iter_mut().find(|s| s.target.id == status.id) else {
            let error = format!(
                "a status packet from servo {}, which is none of the map's",
                status.id
            );
            return self.bad(k, error);
        };
        if !asked {
            // A late answer to a read given up, or noise that checks.
            let error = format!(
                "a status packet from servo {} that was not asked for",
                status.id
            );
            return self.bad(k, error);
        }
        let device = s.device;
        let reading = status
            .params
            .get(..length)
            .and_then(|block| read_block(&s.target, block, status.error, s.torque));
        // A Dynamixel instruction error (bits 0..=6): the read failed.
        let refused = p.vendor == ServoVendor::Dynamixel && status.error & 0x7F != 0;
        if let Some(a) = &mut p.awaiting {
            a.ids.retain(|id| *id != status.id);
        }
        self.news.push_back(ServoNews::Heard { device, at: now });
        match reading {
            Some(reading) if !refused => {
                s.present = Some(reading.raw);
                self.news.push_back(ServoNews::Reading {
                    device,
                    at: now,
                    reading,
                });
                if let Some((msg_id, _, attempts)) = s.written.take() {
                    self.news.push_back(ServoNews::Ended {
                        device,
                        ended: Ended {
                            msg_id,
                            outcome: Outcome::Acked,
                            attempts,
                            at: now,
                        },
                    });
                }
            }
            _ => {
                let error = format!(
                    "servo {} answered the feedback read with error {:#04x} and {} of its {length} bytes",
                    status.id,
                    status.error,
                    status.params.len()
                );
                if p.awaiting.as_ref().is_some_and(|a| a.ids.is_empty()) {
                    p.awaiting = None;
                    p.rx.clear();
                }
                return self.bad(k, error);
            }
        }
        if p.awaiting.as_ref().is_some_and(|a| a.ids.is_empty()) {
            p.awaiting = None;
            p.rx.clear();
        }
    }

    /// Port `k`'s read ended at `now` without every status: the missing
    /// servos are asked again, or given up (counted; their written orders
    /// written again, or timed out after every try).
    fn read_timed_out(&mut self, now: Duration, k: usize) {
        let retries = self.retries;
        let Some(p) = self.ports.get_mut(k) else {
            return;
        };
        let Some(a) = p.awaiting.take() else { return };
        p.rx.clear();
        if a.attempts <= retries {
            self.retried += 1;
            let (address, length) = feedback_block(p.vendor);
            if let Ok(bytes) = encode(
                p.protocol,
                &Instruction::SyncRead {
                    address,
                    length,
                    ids: a.ids.clone(),
                },
            ) {
                self.out
                    .push_back((u8::try_from(k).unwrap_or(u8::MAX), bytes));
                p.awaiting = Some(Awaiting {
                    ids: a.ids,
                    deadline: now.saturating_add(p.wait),
                    attempts: a.attempts + 1,
                });
                return;
            }
        }
        for id in a.ids {
            self.missed += 1;
            let Some(s) = p.servos.iter_mut().find(|s| s.target.id == id) else {
                continue;
            };
            if let Some((msg_id, cmd, attempts)) = s.written.take() {
                if attempts <= retries {
                    // Written again with the next cycle's writes.
                    if s.waiting.is_none() {
                        s.waiting = Some((msg_id, cmd, attempts));
                    }
                } else {
                    self.news.push_back(ServoNews::Ended {
                        device: s.device,
                        ended: Ended {
                            msg_id,
                            outcome: Outcome::TimedOut,
                            attempts,
                            at: now,
                        },
                    });
                }
            }
            // A hold whose servo's position is not known and that cannot
            // be read: given up.
            if let Some((msg_id, ServoCommand::Hold, attempts)) = s.waiting
                && s.present.is_none()
            {
                s.waiting = None;
                self.news.push_back(ServoNews::Ended {
                    device: s.device,
                    ended: Ended {
                        msg_id,
                        outcome: Outcome::TimedOut,
                        attempts: attempts.max(1),
                        at: now,
                    },
                });
            }
        }
    }

    /// Port `k`'s next transaction, if it is free: the orders waiting,
    /// written; then its read, when due or when an order was written.
    fn pump(&mut self, now: Duration, k: usize) {
        let free = self
            .ports
            .get(k)
            .is_some_and(|p| p.awaiting.is_none() && !p.servos.is_empty());
        if !free {
            return;
        }
        let wrote = self.write_orders(now, k);
        self.start_read(now, k, wrote);
    }

    /// The orders waiting on port `k`, written in one sync write per
    /// register block: torque off first (a stop), then goals, then the
    /// torque they need and those goals again (a servo may take its
    /// present position for its goal as its torque comes on). Whether any
    /// was written.
    fn write_orders(&mut self, now: Duration, k: usize) -> bool {
        let Some(p) = self.ports.get_mut(k) else {
            return false;
        };
        let mut blocks = Blocks::default();
        let mut refused = Vec::new();
        for s in &mut p.servos {
            let Some((msg, cmd, attempts)) = s.waiting else {
                continue;
            };
            let block = match cmd {
                ServoCommand::TorqueOff => {
                    blocks.off.push((s.target.id, vec![0]));
                    s.torque = Some(false);
                    None
                }
                ServoCommand::Goal {
                    position,
                    velocity,
                    acceleration,
                } => Some(goal_block("", &s.target, position, velocity, acceleration)),
                ServoCommand::Hold => match s.present {
                    // Where it stands, at its own speed (it does not move).
                    Some(raw) => Some(hold_block(&s.target, p.protocol, raw)),
                    None => continue,
                },
            };
            s.waiting = None;
            match block {
                Some(Ok(b)) => {
                    blocks.goal_address = b.address;
                    if !b.torque_included && s.torque != Some(true) {
                        blocks
                            .on
                            .push((s.target.id, vec![motorwire_translate::TORQUE_ON]));
                        blocks.again.push((s.target.id, b.data.clone()));
                    }
                    blocks.goals.push((s.target.id, b.data));
                    s.torque = Some(true);
                }
                Some(Err(e)) => {
                    // The gate let it through and the calibration did not
                    // change since: not reached; said as the servo's
                    // refusal all the same.
                    refused.push((s.device, msg, attempts, e.to_string()));
                    continue;
                }
                None => {}
            }
            s.written = Some((msg, cmd, attempts.saturating_add(1)));
        }
        for (device, msg_id, attempts, why) in refused {
            self.news.push_back(ServoNews::Ended {
                device,
                ended: Ended {
                    msg_id,
                    outcome: Outcome::Nacked {
                        code: None,
                        why,
                        already_stopped: false,
                    },
                    attempts,
                    at: now,
                },
            });
        }
        let (protocol, vendor) = (p.protocol, p.vendor);
        self.emit_writes(k, protocol, vendor, blocks)
    }

    /// `blocks` written on port `k`, in their order. Whether any was.
    fn emit_writes(
        &mut self,
        k: usize,
        protocol: Protocol,
        vendor: ServoVendor,
        blocks: Blocks,
    ) -> bool {
        let torque = motorwire_translate::torque_address(vendor);
        let port = u8::try_from(k).unwrap_or(u8::MAX);
        let mut wrote = false;
        for (address, entries) in [
            (torque, blocks.off),
            (blocks.goal_address, blocks.goals),
            (torque, blocks.on),
            (blocks.goal_address, blocks.again),
        ] {
            let Some(Ok(length)) = entries.first().map(|(_, d)| u16::try_from(d.len())) else {
                continue;
            };
            if let Ok(bytes) = encode(
                protocol,
                &Instruction::SyncWrite {
                    address,
                    length,
                    entries,
                },
            ) {
                self.out.push_back((port, bytes));
                wrote = true;
            }
        }
        wrote
    }

    /// Port `k`'s sync read of every servo's feedback block, when it is
    /// due, when orders were written (`wrote`: their acknowledgement) or
    /// when a hold waits for its servo's position.
    fn start_read(&mut self, now: Duration, k: usize, wrote: bool) {
        let Some(p) = self.ports.get_mut(k) else {
            return;
        };
        let holding = p
            .servos
            .iter()
            .any(|s| matches!(s.waiting, Some((_, ServoCommand::Hold, _))));
        if !(wrote || holding || now >= p.next_read) {
            return;
        }
        let (address, length) = feedback_block(p.vendor);
        let ids: Vec<u8> = p.servos.iter().map(|s| s.target.id).collect();
        if let Ok(bytes) = encode(
            p.protocol,
            &Instruction::SyncRead {
                address,
                length,
                ids: ids.clone(),
            },
        ) {
            self.out
                .push_back((u8::try_from(k).unwrap_or(u8::MAX), bytes));
            p.rx.clear();
            p.awaiting = Some(Awaiting {
                ids,
                deadline: now.saturating_add(p.wait),
                attempts: 1,
            });
            if now >= p.next_read {
                p.next_read = now.saturating_add(p.period);
            }
        }
    }
}

/// The sync writes of one cycle, by register block.
#[derive(Debug, Default)]
struct Blocks {
    off: Vec<(u8, Vec<u8>)>,
    goal_address: u16,
    goals: Vec<(u8, Vec<u8>)>,
    on: Vec<(u8, Vec<u8>)>,
    again: Vec<(u8, Vec<u8>)>,
}

/// The goal block that holds `target`'s servo at `raw` (its present
/// position), torque on, at the servo's own speed.
fn hold_block(
    target: &ServoTarget,
    protocol: Protocol,
    raw: i64,
) -> Result<motorwire_translate::GoalBlock, motorwire_translate::Refusal> {
    let refusal = |problem: String| motorwire_translate::Refusal::NotRepresentable {
        motor: String::new(),
        field: "position",
        problem,
    };
    let position = u32::try_from(raw).map_err(|_| refusal(format!("step {raw} is below 0")))?;
    let bytes = |v: u32, n: u8| {
        protocol
            .value_bytes(v, n)
            .map_err(|e| refusal(e.to_string()))
    };
    Ok(match target.vendor {
        ServoVendor::Feetech => {
            let mut data = vec![1, 0];
            data.extend(bytes(position, 2)?);
            data.extend([0; 4]);
            motorwire_translate::GoalBlock {
                address: 40,
                data,
                torque_included: true,
            }
        }
        ServoVendor::Dynamixel => {
            let mut data = vec![0; 8];
            data.extend(bytes(position, 4)?);
            motorwire_translate::GoalBlock {
                address: 108,
                data,
                torque_included: false,
            }
        }
    })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]

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
            Duration::from_millis(5),
            2,
        )
    }

    fn hex(b: &[u8]) -> String {
        b.iter().map(|b| format!("{b:02X}")).collect()
    }

    /// Servo `id`'s answer to the feedback read: at `raw`, 12.0 V, 31 °C.
    fn status(id: u8, raw: u16) -> Vec<u8> {
        let mut params = vec![0; 15];
        params[0..2].copy_from_slice(&raw.to_le_bytes());
        params[6] = 120;
        params[7] = 31;
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

    #[test]
    fn a_goal_is_one_sync_write_then_one_sync_read_acknowledges_it() {
        let mut d = driver(&[1]);
        d.expire(Duration::ZERO);
        // The first cycle's read, answered.
        let (port, read) = d.poll_transmit().unwrap();
        assert_eq!((port, hex(&read)), (0, "FFFFFE0582380F0132".to_owned()));
        d.handle_bytes(Duration::from_millis(1), 0, &status(1, 2047));
        assert!(matches!(d.poll(), Some(ServoNews::Heard { .. })));
        let Some(ServoNews::Reading { reading, .. }) = d.poll() else {
            panic!("no reading")
        };
        assert_eq!((reading.raw, reading.position), (2047, 0.0));
        assert_eq!(
            (reading.voltage, reading.temperature),
            (Some(12.0), Some(31.0))
        );
        // 0° at 90°/s and 900°/s²: torque on, acceleration 102, step
        // 0x07FF, goal time 0, 1024 steps/s, in one sync write from 40;
        // then the read that acknowledges it.
        let msg = d.send(
            Duration::from_millis(2),
            DeviceId::at(0),
            ServoCommand::Goal {
                position: 0.0,
                velocity: Some(90.0),
                acceleration: Some(900.0),
            },
        );
        let (_, write) = d.poll_transmit().unwrap();
        assert_eq!(
            hex(&write),
            "FFFFFE0D83280801".to_owned() + "0166FF0700000004CF"
        );
        let (_, read) = d.poll_transmit().unwrap();
        assert_eq!(hex(&read), "FFFFFE0582380F0132");
        assert_eq!(d.poll_transmit(), None, "one transaction at a time");
        // Its answer in two pieces, with noise before it.
        let answer = status(1, 2047);
        d.handle_bytes(Duration::from_millis(3), 0, &[0x00, 0xFF]);
        d.handle_bytes(Duration::from_millis(3), 0, &answer[..5]);
        d.handle_bytes(Duration::from_millis(4), 0, &answer[5..]);
        let news: Vec<ServoNews> = std::iter::from_fn(|| d.poll()).collect();
        assert!(news.iter().any(|n| matches!(
            n,
            ServoNews::Ended { ended: Ended { msg_id, outcome: Outcome::Acked, attempts: 1, .. }, .. } if *msg_id == msg
        )), "{news:?}");
    }

    #[test]
    fn a_missing_status_is_asked_again_for_that_servo_alone_then_counted() {
        let mut d = driver(&[1, 2]);
        d.expire(Duration::ZERO);
        let (_, read) = d.poll_transmit().unwrap();
        assert_eq!(hex(&read), "FFFFFE0682380F0102".to_owned() + "2F");
        d.handle_bytes(Duration::from_millis(1), 0, &status(1, 2047));
        // Servo 2 is silent: at the wait's end, asked again alone.
        let wait = d.deadline().unwrap();
        d.expire(wait);
        let (_, again) = d.poll_transmit().unwrap();
        assert_eq!(hex(&again), "FFFFFE0582380F0231");
        assert_eq!(d.retried, 1);
        // Twice more (the retries), then given up and counted; the next
        // cycle reads both again.
        for _ in 0..2 {
            let wait = d.deadline().unwrap();
            d.expire(wait);
        }
        assert_eq!((d.retried, d.missed), (2, 1));
        let next = d.deadline().unwrap();
        d.expire(next);
        let reads: Vec<String> = std::iter::from_fn(|| d.poll_transmit())
            .map(|(_, b)| hex(&b))
            .collect();
        assert_eq!(
            reads.last().unwrap(),
            &("FFFFFE0682380F0102".to_owned() + "2F")
        );
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
        let sent: Vec<String> = std::iter::from_fn(|| d.poll_transmit())
            .map(|(_, b)| hex(&b))
            .collect();
        // Torque_Enable (40) 0 for servo 1, then the read.
        assert_eq!(
            sent,
            [
                "FFFFFE0683280101".to_owned() + "004E",
                "FFFFFE0582380F0132".to_owned()
            ]
        );
    }
}
