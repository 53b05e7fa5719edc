//! Simulated serial bus servos: Feetech STS/SMS and SCS, Dynamixel X
//! series, on one half-duplex bus, sans-IO.
//!
//! A [`ServoBus`] takes the bytes a host writes ([`ServoBus::write`], at a
//! time the caller gives) and answers with the bytes its servos send back,
//! each after its return delay. Each servo keeps its model's control table
//! as the wire has it (little- or big-endian, Feetech's sign-magnitude or
//! two's complement) and answers every instruction of its protocol: ping
//! (a broadcast ping answered by every servo in id order), read, write,
//! reg write and action, sync read and sync write, and for Dynamixel
//! reboot, factory reset, bulk read and bulk write. It moves: with torque
//! on, its position goes to its goal position at its goal (Feetech) or
//! profile (Dynamixel) velocity and acceleration, and its present
//! position, velocity and load follow; its homing offset is applied as the
//! model applies it (Feetech: present = actual - offset; Dynamixel:
//! present = actual + offset). A Dynamixel servo refuses an EEPROM write
//! while its torque is on (access error), as the servo does; a write to a
//! read-only register is refused likewise. Its status return level is
//! obeyed. Faults are seeded: a status packet dropped, corrupted (one bit
//! flipped) or late.
//!
//! ```
//! use std::time::Duration;
//! use motorwire_servo::{Instruction, Protocol, decode_status, encode, table};
//! use motorwire_sim::servo::ServoBus;
//!
//! let mut bus = ServoBus::new(table::model("sts3215").unwrap(), &[1, 2]).unwrap();
//! let ping = encode(Protocol::Scs0, &Instruction::Ping { id: 2 }).unwrap();
//! let answers = bus.write(Duration::ZERO, &ping);
//! let status = decode_status(Protocol::Scs0, &answers[0].bytes, None).unwrap().status;
//! assert_eq!((status.id, status.error), (2, 0));
//! ```

use std::time::Duration;

use motorwire_servo::table::{Access, Model, Register};
use motorwire_servo::{
    BROADCAST_ID, Instruction, InstructionError, Protocol, Status, decode_instruction,
    encode_status,
};

/// The bytes of a control table the simulation keeps (every register of
/// the models it knows lies below).
const TABLE: usize = 256;

/// The gap after which the bytes of an unfinished packet are let go.
pub const PACKET_GAP: Duration = Duration::from_millis(20);

/// The longest a simulated move is integrated in one go: past it, the
/// servo is where its goal is (a caller that came back after seconds).
const MAX_STEP: Duration = Duration::from_secs(10);

/// Why a bus cannot be made.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum ServoSimError {
    /// An id no servo can have, or the same id twice.
    #[error("servo id {0} is not 0 to 252, or is given twice")]
    Id(u8),
    /// No servo at all.
    #[error("a servo bus needs at least one servo")]
    Empty,
    /// Two models that speak different protocols on one bus.
    #[error("a {0} and a {1} speak different protocols: one bus, one protocol")]
    Protocols(&'static str, &'static str),
}

/// Faults of the simulated bus, each a probability for each status packet.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ServoFaults {
    /// The answer is never sent.
    pub drop: f64,
    /// One bit of the answer is flipped.
    pub corrupt: f64,
    /// The answer comes `late_by` after its return delay.
    pub late: f64,
    /// How late a late answer is.
    pub late_by: Duration,
}

/// Bytes a servo sends back, after `delay` from the write that asked.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ServoAnswer {
    /// The status packet (or a corrupted one).
    pub bytes: Vec<u8>,
    /// How long after the instruction it is sent.
    pub delay: Duration,
}

/// One simulated servo.
#[derive(Debug, Clone)]
pub struct SimServo {
    model: &'static Model,
    protocol: Protocol,
    memory: Vec<u8>,
    /// Where it is (steps, before its homing offset).
    actual: f64,
    /// How fast it moves (steps a second).
    speed: f64,
    /// A reg write waiting for its action.
    registered: Option<(u16, Vec<u8>)>,
}

impl SimServo {
    fn new(model: &'static Model, id: u8) -> Self {
        let mut s = Self {
            model,
            protocol: model.protocol,
            memory: vec![0; TABLE],
            actual: f64::from(model.resolution / 2),
            speed: 0.0,
            registered: None,
        };
        s.factory(id);
        s
    }

    /// Its factory settings, with `id`.
    fn factory(&mut self, id: u8) {
        self.memory.fill(0);
        let number = i64::from(self.model.number);
        let top = i64::from(self.model.resolution) - 1;
        let defaults: &[(&str, i64)] = if self.protocol == Protocol::Dxl2 {
            &[
                ("Model_Number", number),
                ("Firmware_Version", 52),
                ("ID", i64::from(id)),
                ("Baud_Rate", 3),
                ("Return_Delay_Time", 250),
                ("Operating_Mode", 3),
                ("Temperature_Limit", 80),
                ("Max_Voltage_Limit", 140),
                ("Min_Voltage_Limit", 35),
                ("PWM_Limit", 885),
                ("Velocity_Limit", 445),
                ("Max_Position_Limit", top),
                ("Min_Position_Limit", 0),
                ("Status_Return_Level", 2),
                ("Position_P_Gain", 800),
                ("Present_Input_Voltage", 120),
                ("Present_Temperature", 30),
            ]
        } else {
            &[
                ("Firmware_Major_Version", 3),
                ("Firmware_Minor_Version", 10),
                ("Model_Number", number),
                ("ID", i64::from(id)),
                ("Baud_Rate", 0),
                ("Return_Delay_Time", 0),
                ("Response_Status_Level", 1),
                ("Min_Position_Limit", 0),
                ("Max_Position_Limit", top),
                ("Max_Temperature_Limit", 70),
                ("Max_Voltage_Limit", 140),
                ("Min_Voltage_Limit", 40),
                ("Max_Torque_Limit", 1000),
                ("P_Coefficient", 32),
                ("Torque_Limit", 1000),
                ("Present_Voltage", 120),
                ("Present_Temperature", 30),
            ]
        };
        for (name, v) in defaults {
            self.set(name, *v);
        }
        self.refresh();
        self.hold_here();
    }

    /// Its id.
    #[must_use]
    pub fn id(&self) -> u8 {
        self.memory
            .get(usize::from(self.address_of("ID")))
            .copied()
            .unwrap_or(0)
    }

    /// Its model.
    #[must_use]
    pub fn model(&self) -> &'static Model {
        self.model
    }

    /// The value of its register `name` (signed as the register is), if
    /// its model has one.
    #[must_use]
    pub fn get(&self, name: &str) -> Option<i64> {
        let r = self.model.register(name)?;
        Some(r.from_raw(self.raw(r)))
    }

    /// Whether its torque is on.
    #[must_use]
    pub fn torque_on(&self) -> bool {
        self.get("Torque_Enable").unwrap_or(0) != 0
    }

    fn address_of(&self, name: &str) -> u16 {
        self.model.register(name).map_or(0, |r| r.address)
    }

    fn raw(&self, r: &Register) -> u32 {
        let at = usize::from(r.address);
        let bytes = self.memory.get(at..at + usize::from(r.size)).unwrap_or(&[]);
        self.protocol.value_of(bytes).unwrap_or(0)
    }

    /// Sets register `name` to `value` (clamped to what it holds).
    fn set(&mut self, name: &str, value: i64) {
        let Some(r) = self.model.register(name) else {
            return;
        };
        let raw = r
            .to_raw(value)
            .or_else(|_| r.to_raw(value.clamp(-(1 << 30), 1 << 30)))
            .unwrap_or(0);
        if let Ok(bytes) = self.protocol.value_bytes(raw, r.size) {
            let at = usize::from(r.address);
            if let Some(m) = self.memory.get_mut(at..at + bytes.len()) {
                m.copy_from_slice(&bytes);
            }
        }
    }

    /// Its goal is where it is (as at power-up, and when its torque comes
    /// on: it holds its position).
    fn hold_here(&mut self) {
        let present = self.get("Present_Position").unwrap_or(0);
        self.set("Goal_Position", present);
    }

    /// Its steps a turn.
    fn turn(&self) -> f64 {
        f64::from(self.model.resolution)
    }

    /// Where it is told to go, in steps before its homing offset.
    fn target(&self) -> f64 {
        let offset = self.get("Homing_Offset").unwrap_or(0) as f64;
        let goal = self.get("Goal_Position").unwrap_or(0) as f64;
        let lo = self.get("Min_Position_Limit").unwrap_or(0) as f64;
        let hi = self.get("Max_Position_Limit").unwrap_or(0) as f64;
        let goal = if hi > lo { goal.clamp(lo, hi) } else { goal };
        if self.protocol == Protocol::Dxl2 {
            goal - offset
        } else {
            goal + offset
        }
    }

    /// Its velocity and acceleration limits (steps a second, a second
    /// squared) from its registers (0: as fast as it goes).
    fn limits(&self) -> (f64, f64) {
        let (fastest, hardest) = (4.0 * self.turn(), 40.0 * self.turn());
        let or = |v: f64, max: f64| if v > 0.0 { v.min(max) } else { max };
        if self.protocol == Protocol::Dxl2 {
            let rpm = self.get("Profile_Velocity").unwrap_or(0) as f64 * 0.229;
            let rpm2 = self.get("Profile_Acceleration").unwrap_or(0) as f64 * 214.577;
            (
                or(rpm / 60.0 * self.turn(), fastest),
                or(rpm2 / 3600.0 * self.turn(), hardest),
            )
        } else {
            let v = self.get("Goal_Velocity").unwrap_or(0).abs() as f64;
            let a = self.get("Acceleration").unwrap_or(0) as f64 * 100.0;
            (or(v, fastest), or(a, hardest))
        }
    }

    /// Moves it for `dt` toward its target within its limits.
    fn advance(&mut self, dt: Duration) {
        if !self.torque_on() {
            self.speed = 0.0;
            return;
        }
        let target = self.target();
        let (vmax, amax) = self.limits();
        let mut left = dt.min(MAX_STEP).as_secs_f64();
        let h = 0.001;
        while left > 0.0 {
            let step = left.min(h);
            left -= step;
            let to_go = target - self.actual;
            if to_go.abs() < 0.5 && self.speed.abs() < amax * h {
                self.actual = target;
                self.speed = 0.0;
                break;
            }
            let stop = (2.0 * amax * to_go.abs()).sqrt();
            let want = to_go.signum() * vmax.min(stop);
            let dv = (want - self.speed).clamp(-amax * step, amax * step);
            self.speed += dv;
            let before = to_go.signum();
            self.actual += self.speed * step;
            if (target - self.actual).signum() != before {
                self.actual = target;
                self.speed = 0.0;
            }
        }
        if dt > MAX_STEP {
            self.actual = target;
            self.speed = 0.0;
        }
    }

    /// Its present registers from its motion.
    fn refresh(&mut self) {
        let offset = self.get("Homing_Offset").unwrap_or(0) as f64;
        let turn = self.turn();
        let (present, speed) = if self.protocol == Protocol::Dxl2 {
            let rpm = self.speed / turn * 60.0 / 0.229;
            (self.actual + offset, rpm)
        } else {
            ((self.actual - offset).rem_euclid(turn), self.speed)
        };
        self.set("Present_Position", present.round() as i64);
        self.set("Present_Velocity", speed.round() as i64);
        let moving = i64::from(self.speed.abs() > 0.0);
        self.set("Moving", moving);
        let load = (self.speed.abs() / (4.0 * turn) * 300.0).round() as i64;
        self.set("Present_Load", load * self.speed.signum() as i64);
        self.set("Present_Current", load / 3);
    }

    /// Writes `data` at `address`; the error byte of its answer.
    fn write(&mut self, address: u16, data: &[u8]) -> u8 {
        let end = usize::from(address) + data.len();
        if end > TABLE {
            return self.access_error();
        }
        let touched = |r: &&Register| {
            let (a, b) = (
                usize::from(r.address),
                usize::from(r.address) + usize::from(r.size),
            );
            a < end && usize::from(address) < b
        };
        let regs: Vec<&Register> = self.model.registers.iter().filter(touched).collect();
        if regs.iter().any(|r| r.access == Access::Read) {
            return self.access_error();
        }
        // An id no servo can take: refused (Dynamixel: data range error).
        let id_at = usize::from(self.address_of("ID"));
        if let Some(new) = data
            .get(id_at.wrapping_sub(usize::from(address)))
            .filter(|_| (usize::from(address)..end).contains(&id_at))
            && *new > 252
        {
            return if self.protocol == Protocol::Dxl2 {
                4
            } else {
                0
            };
        }
        // A Dynamixel servo's EEPROM is written only with its torque off.
        if self.protocol == Protocol::Dxl2
            && address < self.model.ram_start
            && self.torque_on()
            && !regs.is_empty()
        {
            return self.access_error();
        }
        let was_on = self.torque_on();
        if let Some(m) = self.memory.get_mut(usize::from(address)..end) {
            m.copy_from_slice(data);
        }
        // Torque coming on holds the position it finds, unless this very
        // write also set the goal.
        let goal = self
            .model
            .register("Goal_Position")
            .map_or(0, |r| r.address);
        if !was_on && self.torque_on() && !(usize::from(address)..end).contains(&usize::from(goal))
        {
            self.hold_here();
        }
        0
    }

    const fn access_error(&self) -> u8 {
        match self.protocol {
            // Access error (7).
            Protocol::Dxl2 => 7,
            // Feetech has no access error: the servo ignores the write.
            Protocol::Scs0 | Protocol::Scs1 => 0,
        }
    }

    /// `length` bytes of its table from `address` (zeros past it).
    fn read(&self, address: u16, length: u16) -> Vec<u8> {
        (usize::from(address)..usize::from(address) + usize::from(length))
            .map(|i| self.memory.get(i).copied().unwrap_or(0))
            .collect()
    }

    /// Whether it sends a status for `instruction` (its status return
    /// level).
    fn answers(&self, instruction: &Instruction) -> bool {
        let is_read = matches!(
            instruction,
            Instruction::Read { .. } | Instruction::SyncRead { .. } | Instruction::BulkRead { .. }
        );
        if matches!(instruction, Instruction::Ping { .. }) {
            return true;
        }
        if self.protocol == Protocol::Dxl2 {
            match self.get("Status_Return_Level").unwrap_or(2) {
                0 => false,
                1 => is_read,
                _ => true,
            }
        } else {
            is_read || self.get("Response_Status_Level").unwrap_or(1) != 0
        }
    }

    /// Its return delay.
    fn delay(&self) -> Duration {
        Duration::from_micros(2 * self.get("Return_Delay_Time").unwrap_or(0).unsigned_abs())
    }
}

/// Simulated servos on one half-duplex bus.
#[derive(Debug, Clone)]
pub struct ServoBus {
    protocol: Protocol,
    servos: Vec<SimServo>,
    faults: ServoFaults,
    rng: u64,
    now: Duration,
    pending: Vec<u8>,
    /// When the bytes still pending came.
    pending_at: Duration,
    /// Instruction packets that were corrupt or malformed (ignored, as a
    /// servo ignores them).
    bad: u64,
    /// A hand that sweeps every servo whose torque is off: how far each
    /// way from where it started (steps) and the sweep's period.
    hand: Option<(f64, Duration)>,
}

impl ServoBus {
    /// Servos of `model` with ids `ids`, at their middle position, torque
    /// off, factory settings.
    ///
    /// # Errors
    /// [`ServoSimError`]: no servo, an id above 252 or given twice.
    pub fn new(model: &'static Model, ids: &[u8]) -> Result<Self, ServoSimError> {
        let servos: Vec<(&'static Model, u8)> = ids.iter().map(|&id| (model, id)).collect();
        Self::mixed(&servos)
    }

    /// Servos of several models of one protocol (a Koch arm's XL430-W250
    /// and XL330-M288), each `(model, id)`, at their middle position,
    /// torque off, factory settings.
    ///
    /// # Errors
    /// [`ServoSimError`]: no servo, an id above 252 or given twice, models
    /// of different protocols.
    pub fn mixed(servos: &[(&'static Model, u8)]) -> Result<Self, ServoSimError> {
        let Some((first, _)) = servos.first() else {
            return Err(ServoSimError::Empty);
        };
        let mut seen = Vec::new();
        for &(model, id) in servos {
            if id > 252 || seen.contains(&id) {
                return Err(ServoSimError::Id(id));
            }
            if model.protocol != first.protocol {
                return Err(ServoSimError::Protocols(first.name, model.name));
            }
            seen.push(id);
        }
        Ok(Self {
            protocol: first.protocol,
            servos: servos.iter().map(|&(m, id)| SimServo::new(m, id)).collect(),
            faults: ServoFaults::default(),
            rng: 0x9E37_79B9_7F4A_7C15,
            now: Duration::ZERO,
            pending: Vec::new(),
            pending_at: Duration::ZERO,
            bad: 0,
            hand: None,
        })
    }

    /// With `faults`, drawn from `seed`.
    #[must_use]
    pub fn with_faults(mut self, faults: ServoFaults, seed: u64) -> Self {
        self.faults = faults;
        self.rng = seed | 1;
        self
    }

    /// With a hand that moves every servo whose torque is off through
    /// `degrees` each way from where it started (its middle), once every
    /// `period`, as a person sweeps an arm's joints to calibrate it.
    #[must_use]
    pub fn with_hand(mut self, degrees: f64, period: Duration) -> Self {
        self.hand = Some((degrees, period));
        self
    }

    /// Its protocol.
    #[must_use]
    pub fn protocol(&self) -> Protocol {
        self.protocol
    }

    /// Its servo `id`.
    #[must_use]
    pub fn servo(&self, id: u8) -> Option<&SimServo> {
        self.servos.iter().find(|s| s.id() == id)
    }

    /// Instruction packets it could not read (a wrong check, a malformed
    /// instruction): ignored, as servos ignore them.
    #[must_use]
    pub fn bad_packets(&self) -> u64 {
        self.bad
    }

    /// The servos move to `now`.
    pub fn advance_to(&mut self, now: Duration) {
        let dt = now.saturating_sub(self.now);
        self.now = self.now.max(now);
        let phase = self.hand.map(|(degrees, period)| {
            let t = self.now.as_secs_f64() / period.as_secs_f64().max(1e-3);
            (degrees, (t * std::f64::consts::TAU).sin())
        });
        for s in &mut self.servos {
            s.advance(dt);
            if let Some((degrees, sin)) = phase
                && !s.torque_on()
            {
                let turn = s.turn();
                s.actual = turn / 2.0 + degrees / 360.0 * turn * sin;
                s.speed = 0.0;
            }
            s.refresh();
        }
    }

    /// Takes `bytes` the host wrote at `now` (a packet may come in pieces);
    /// the answers to every whole instruction among them, in order.
    pub fn write(&mut self, now: Duration, bytes: &[u8]) -> Vec<ServoAnswer> {
        self.advance_to(now);
        // A packet's bytes come together: what was left of one that stopped
        // coming is let go (a servo restarts its reading after a gap), so
        // noise costs at most the packet it cut.
        if now.saturating_sub(self.pending_at) > PACKET_GAP {
            self.pending.clear();
        }
        self.pending_at = now;
        self.pending.extend_from_slice(bytes);
        let mut out = Vec::new();
        loop {
            match decode_instruction(self.protocol, &self.pending) {
                Ok((i, consumed)) => {
                    self.pending.drain(..consumed);
                    self.take(&i, &mut out);
                }
                Err(InstructionError::Incomplete { skip }) => {
                    self.pending.drain(..skip);
                    break;
                }
                Err(
                    InstructionError::Check { consumed }
                    | InstructionError::Malformed { consumed, .. },
                ) => {
                    self.bad += 1;
                    self.pending
                        .drain(..consumed.max(1).min(self.pending.len()));
                }
                Err(_) => {
                    self.pending.clear();
                    break;
                }
            }
        }
        out
    }

    /// The servos take `i`; their answers are added to `out`.
    fn take(&mut self, i: &Instruction, out: &mut Vec<ServoAnswer>) {
        let addressed = |s: &SimServo, id: u8| id == BROADCAST_ID || s.id() == id;
        match i {
            Instruction::Ping { id } => {
                for k in 0..self.servos.len() {
                    if self.servos.get(k).is_some_and(|s| addressed(s, *id)) {
                        let params = self.ping_params(k);
                        self.answer(k, i, 0, params, out);
                    }
                }
            }
            Instruction::Read {
                id,
                address,
                length,
            } => {
                self.read_for(*id, i, *address, *length, out);
            }
            Instruction::Write { id, address, data } => {
                self.each(i, *id, out, |s| s.write(*address, data));
            }
            Instruction::RegWrite { id, address, data } => {
                self.each(i, *id, out, |s| {
                    s.registered = Some((*address, data.clone()));
                    0
                });
            }
            Instruction::Action { id } => {
                self.each(i, *id, out, |s| match s.registered.take() {
                    Some((a, d)) => s.write(a, &d),
                    None => 0,
                });
            }
            Instruction::Reboot { id } => {
                self.each(i, *id, out, |s| {
                    s.set("Torque_Enable", 0);
                    s.speed = 0.0;
                    0
                });
            }
            Instruction::FactoryReset { id, option } => {
                // It answers from the id it has, then resets (0xFF: its id
                // too, to 1).
                self.each(i, *id, out, |_| 0);
                for s in self
                    .servos
                    .iter_mut()
                    .filter(|s| *id == BROADCAST_ID || s.id() == *id)
                {
                    let (own, baud) = (s.id(), s.get("Baud_Rate").unwrap_or(0));
                    s.factory(if *option == 0xFF { 1 } else { own });
                    if *option == 0x02 {
                        s.set("Baud_Rate", baud);
                    }
                }
            }
            Instruction::SyncRead {
                address,
                length,
                ids,
            } => {
                for id in ids {
                    self.read_for(*id, i, *address, *length, out);
                }
            }
            Instruction::BulkRead { reads } => {
                for (id, address, length) in reads {
                    self.read_for(*id, i, *address, *length, out);
                }
            }
            Instruction::SyncWrite {
                address, entries, ..
            } => {
                for (id, data) in entries {
                    if let Some(s) = self.servos.iter_mut().find(|s| s.id() == *id) {
                        s.write(*address, data);
                    }
                }
            }
            Instruction::BulkWrite { writes } => {
                for (id, address, data) in writes {
                    if let Some(s) = self.servos.iter_mut().find(|s| s.id() == *id) {
                        s.write(*address, data);
                    }
                }
            }
        }
        for s in &mut self.servos {
            s.refresh();
        }
    }

    /// Servo `id` (or each, broadcast) does `f`; one addressed alone
    /// answers with the error byte `f` gives.
    fn each(
        &mut self,
        i: &Instruction,
        id: u8,
        out: &mut Vec<ServoAnswer>,
        mut f: impl FnMut(&mut SimServo) -> u8,
    ) {
        for k in 0..self.servos.len() {
            let Some(s) = self.servos.get_mut(k) else {
                continue;
            };
            if id != BROADCAST_ID && s.id() != id {
                continue;
            }
            let error = f(s);
            if id != BROADCAST_ID {
                self.answer(k, i, error, Vec::new(), out);
            }
        }
    }

    /// Servo `id` (if there is one) answers `i` with `length` bytes of its
    /// table from `address`.
    fn read_for(
        &mut self,
        id: u8,
        i: &Instruction,
        address: u16,
        length: u16,
        out: &mut Vec<ServoAnswer>,
    ) {
        if let Some(k) = self.index(id) {
            let data = self
                .servos
                .get(k)
                .map(|s| s.read(address, length))
                .unwrap_or_default();
            self.answer(k, i, 0, data, out);
        }
    }

    fn index(&self, id: u8) -> Option<usize> {
        self.servos.iter().position(|s| s.id() == id)
    }

    /// A ping's answer: Dynamixel's model number and firmware; Feetech's
    /// nothing.
    fn ping_params(&self, k: usize) -> Vec<u8> {
        let Some(s) = self.servos.get(k) else {
            return Vec::new();
        };
        if self.protocol == Protocol::Dxl2 {
            let mut p = s.model.number.to_le_bytes().to_vec();
            p.push(u8::try_from(s.get("Firmware_Version").unwrap_or(0)).unwrap_or(0));
            p
        } else {
            Vec::new()
        }
    }

    /// Servo `k`'s status for `i` with `error` and `params`, where its
    /// status return level sends one, through the faults.
    fn answer(
        &mut self,
        k: usize,
        i: &Instruction,
        error: u8,
        params: Vec<u8>,
        out: &mut Vec<ServoAnswer>,
    ) {
        let Some(s) = self.servos.get(k) else {
            return;
        };
        if !s.answers(i) {
            return;
        }
        let status = Status {
            id: s.id(),
            error,
            params,
        };
        let Ok(mut bytes) = encode_status(self.protocol, &status) else {
            return;
        };
        let mut delay = s.delay();
        if self.chance(self.faults.drop) {
            return;
        }
        if self.chance(self.faults.corrupt) {
            let bit = usize::try_from(self.next() % (bytes.len() as u64 * 8)).unwrap_or(0);
            if let Some(b) = bytes.get_mut(bit / 8) {
                *b ^= 1 << (bit % 8);
            }
        }
        if self.chance(self.faults.late) {
            delay += self.faults.late_by;
        }
        out.push(ServoAnswer { bytes, delay });
    }

    fn next(&mut self) -> u64 {
        let mut x = self.rng;
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        self.rng = x;
        x
    }

    fn chance(&mut self, p: f64) -> bool {
        p > 0.0 && ((self.next() >> 11) as f64 / ((1u64 << 53) as f64)) < p
    }
}
