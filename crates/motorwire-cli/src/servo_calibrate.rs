//! `motorwire servo calibrate --map M`: the servos of a bus map calibrated
//! as LeRobot's calibration does it, and the result written into the map
//! and into the servos.
//!
//! Torque off; the arm put in the middle of its range by hand (ENTER); each
//! servo's homing offset set so that it reads the middle of its turn there
//! (its offset and position limits first reset to none); every joint swept
//! through its whole range by hand while the positions are read (ENTER
//! ends it; a whole-turn joint's range is the whole turn); each servo's
//! position limit registers written; the map's `calibration` of each motor
//! written (its comments and layout kept), so that the bridge holds every
//! command inside the calibrated range.

use std::io::{BufRead, Read, Write};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use motorwire_servo::table::Model;
use motorwire_servo::{Instruction, Protocol, Status, decode_status, encode};
use motorwire_translate::{BusMap, ServoVendor, Target};
use serde_json::json;

use crate::console::{note, say};

/// What `calibrate` takes.
#[derive(Debug, clap::Args)]
pub(crate) struct CalibrateArgs {
    /// The bus map whose serial servos are calibrated; their calibration
    /// is written into it.
    #[arg(long, value_name = "FILE")]
    map: String,
    /// Motors that turn a whole turn (an SO arm's `wrist_roll`): their
    /// range is the whole turn, not swept.
    #[arg(long, value_name = "MOTORS", value_delimiter = ',')]
    full_turn: Vec<String>,
}

/// How long a status is waited for, and how many times an instruction is
/// sent.
const STATUS_WAIT: Duration = Duration::from_millis(100);
const TRIES: u32 = 3;

/// One serial port and its protocol.
struct Link {
    port: Box<dyn serialport::SerialPort>,
    protocol: Protocol,
    path: String,
}

impl Link {
    /// Sends `i` and waits for servo `id`'s status (`asked`: the bytes a
    /// read asks for), up to [`TRIES`] times.
    fn ask(&mut self, i: &Instruction, id: u8, asked: Option<usize>) -> Result<Status, String> {
        let bytes = encode(self.protocol, i).map_err(|e| e.to_string())?;
        let mut last = String::new();
        for _ in 0..TRIES {
            self.port
                .write_all(&bytes)
                .and_then(|()| self.port.flush())
                .map_err(|e| format!("{}: writing: {e}", self.path))?;
            let deadline = Instant::now() + STATUS_WAIT;
            let mut rx = Vec::new();
            let mut buf = [0u8; 256];
            while Instant::now() < deadline {
                match self.port.read(&mut buf) {
                    Ok(n) => rx.extend_from_slice(buf.get(..n).unwrap_or(&[])),
                    Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {}
                    Err(e) => return Err(format!("{}: reading: {e}", self.path)),
                }
                match decode_status(self.protocol, &rx, asked) {
                    Ok(d) if d.status.id == id => return Ok(d.status),
                    Ok(d) => {
                        rx.drain(..d.consumed.min(rx.len()));
                    }
                    Err(e) => last = e.to_string(),
                }
            }
        }
        Err(format!(
            "{}: servo {id} did not answer {} ({last})",
            self.path,
            i.name()
        ))
    }

    /// Writes `value` to register `name` of servo `id` of `model`.
    fn write(&mut self, model: &Model, id: u8, name: &str, value: i64) -> Result<(), String> {
        let r = model
            .register(name)
            .ok_or_else(|| format!("a {} has no {name}", model.name))?;
        let raw = r.to_raw(value).map_err(|e| e.to_string())?;
        let data = self
            .protocol
            .value_bytes(raw, r.size)
            .map_err(|e| e.to_string())?;
        let status = self.ask(
            &Instruction::Write {
                id,
                address: r.address,
                data,
            },
            id,
            None,
        )?;
        // A Dynamixel error number (bits 0..=6) is a refusal.
        if self.protocol == Protocol::Dxl2 && status.error & 0x7F != 0 {
            return Err(format!(
                "servo {id} refused {name} = {value} (error {:#04x})",
                status.error
            ));
        }
        Ok(())
    }

    /// Register `name` of servo `id` of `model`, read.
    fn read(&mut self, model: &Model, id: u8, name: &str) -> Result<i64, String> {
        let r = model
            .register(name)
            .ok_or_else(|| format!("a {} has no {name}", model.name))?;
        let status = self.ask(
            &Instruction::Read {
                id,
                address: r.address,
                length: u16::from(r.size),
            },
            id,
            Some(usize::from(r.size)),
        )?;
        let value = self.protocol.value_of(&status.params).ok_or_else(|| {
            format!(
                "servo {id} answered {name} with {} bytes",
                status.params.len()
            )
        })?;
        Ok(r.from_raw(value))
    }
}

/// One servo to calibrate.
struct Servo {
    name: String,
    port: usize,
    id: u8,
    model: &'static Model,
    vendor: ServoVendor,
    drive_mode: u8,
    full_turn: bool,
    offset: i64,
    min: i64,
    max: i64,
}

/// Runs the calibration; its exit status.
pub(crate) fn calibrate(args: &CalibrateArgs) -> u8 {
    match run(args) {
        Ok(()) => 0,
        Err(e) => {
            note!("motorwire servo calibrate: {e}");
            1
        }
    }
}

/// Waits for ENTER on standard input, after saying `prompt`.
fn enter(prompt: &str) -> Result<(), String> {
    note!("{prompt}, then press ENTER");
    let mut line = String::new();
    match std::io::stdin().lock().read_line(&mut line) {
        Ok(0) => Err("standard input ended before ENTER".to_owned()),
        Ok(_) => Ok(()),
        Err(e) => Err(format!("reading standard input: {e}")),
    }
}

fn run(args: &CalibrateArgs) -> Result<(), String> {
    let text = std::fs::read_to_string(&args.map).map_err(|e| format!("{}: {e}", args.map))?;
    let map = BusMap::from_toml(&text).map_err(|e| e.to_string())?;
    for name in &args.full_turn {
        if !map.motor(name).is_some_and(motorwire_translate::is_servo) {
            return Err(format!("--full-turn {name}: not a serial servo of the map"));
        }
    }
    let mut servos: Vec<Servo> = map
        .motors()
        .filter_map(|m| match m.target {
            Target::Servo(t) => Some(Servo {
                name: m.name.clone(),
                port: usize::from(t.port),
                id: t.id,
                model: t.table()?,
                vendor: t.vendor,
                drive_mode: t.calibration.drive_mode,
                full_turn: args.full_turn.contains(&m.name),
                offset: 0,
                min: 0,
                max: 0,
            }),
            _ => None,
        })
        .collect();
    if servos.is_empty() {
        return Err(format!("{}: no serial servo in the map", args.map));
    }
    let mut links = map
        .servo_ports()
        .iter()
        .map(|p| {
            let port = serialport::new(&p.path, p.baud)
                .timeout(Duration::from_millis(5))
                .open()
                .map_err(|e| format!("{} at {} baud: {e}", p.path, p.baud))?;
            Ok(Link {
                port,
                protocol: p.protocol,
                path: p.path.clone(),
            })
        })
        .collect::<Result<Vec<_>, String>>()?;
    // Torque off (and, on Feetech, the EEPROM lock open): the arm is moved
    // by hand, and the offsets and limits are EEPROM.
    for s in &servos {
        let l = links.get_mut(s.port).ok_or("a servo port is missing")?;
        l.write(s.model, s.id, "Torque_Enable", 0)?;
        if s.vendor == ServoVendor::Feetech {
            l.write(s.model, s.id, "Lock", 0)?;
        }
    }
    enter(
        "motorwire servo calibrate: the servos' torque is off. Move the arm to the middle of its range of motion",
    )?;
    // As LeRobot: offsets and limits reset, then the offset that makes the
    // present position the middle of the turn.
    for s in &mut servos {
        let l = links.get_mut(s.port).ok_or("a servo port is missing")?;
        let top = i64::from(s.model.resolution) - 1;
        l.write(s.model, s.id, "Homing_Offset", 0)?;
        l.write(s.model, s.id, "Min_Position_Limit", 0)?;
        l.write(s.model, s.id, "Max_Position_Limit", top)?;
        let at = l.read(s.model, s.id, "Present_Position")?;
        let half = top / 2;
        s.offset = match s.vendor {
            // Feetech: present = actual - offset.
            ServoVendor::Feetech => at - half,
            // Dynamixel: present = actual + offset.
            ServoVendor::Dynamixel => half - at,
        };
        l.write(s.model, s.id, "Homing_Offset", s.offset)?;
        let now = l.read(s.model, s.id, "Present_Position")?;
        s.min = now;
        s.max = now;
    }
    note!("motorwire servo calibrate: homing offsets written; recording the ranges of motion");
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        let mut line = String::new();
        let _ = std::io::stdin().lock().read_line(&mut line);
        let _ = tx.send(());
    });
    note!("Move every joint through its whole range of motion, then press ENTER");
    while rx.try_recv() == Err(mpsc::TryRecvError::Empty) {
        for s in servos.iter_mut().filter(|s| !s.full_turn) {
            let l = links.get_mut(s.port).ok_or("a servo port is missing")?;
            let at = l.read(s.model, s.id, "Present_Position")?;
            s.min = s.min.min(at);
            s.max = s.max.max(at);
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    for s in &mut servos {
        if s.full_turn {
            s.min = 0;
            s.max = i64::from(s.model.resolution) - 1;
        }
        if s.min >= s.max {
            return Err(format!(
                "{}: its range was not swept (it read {} throughout): sweep every joint and calibrate again; the homing offsets are written, the map is not",
                s.name, s.min
            ));
        }
    }
    for s in &servos {
        let l = links.get_mut(s.port).ok_or("a servo port is missing")?;
        l.write(s.model, s.id, "Min_Position_Limit", s.min)?;
        l.write(s.model, s.id, "Max_Position_Limit", s.max)?;
    }
    write_map(&args.map, &text, &servos)?;
    for s in &servos {
        say!(
            "{}",
            json!({"motor_id": s.name, "homing_offset": s.offset, "range_min": s.min, "range_max": s.max, "drive_mode": s.drive_mode})
        )
        .map_err(|e| e.to_string())?;
    }
    Ok(())
}

/// Each servo's calibration written into the map `path` (whose text is
/// `text`), its comments and layout kept; checked as a bus map first.
fn write_map(path: &str, text: &str, servos: &[Servo]) -> Result<(), String> {
    let mut doc: toml_edit::DocumentMut = text.parse().map_err(|e| format!("{path}: {e}"))?;
    for s in servos {
        let motor = doc
            .get_mut("motors")
            .and_then(|m| m.get_mut(&s.name))
            .and_then(toml_edit::Item::as_table_like_mut)
            .ok_or_else(|| format!("{path}: motors.{} is not a table", s.name))?;
        let mut c = toml_edit::InlineTable::new();
        c.insert("homing_offset", s.offset.into());
        c.insert("range_min", s.min.into());
        c.insert("range_max", s.max.into());
        c.insert("drive_mode", i64::from(s.drive_mode).into());
        motor.insert("calibration", toml_edit::value(c));
    }
    let new = doc.to_string();
    if let Err(e) = BusMap::from_toml(&new) {
        let aside = format!("{path}.calibrated");
        std::fs::write(&aside, &new).map_err(|e| format!("{aside}: {e}"))?;
        return Err(format!(
            "the calibrated map is not a bus map ({e}): written to {aside} for you to mend; {path} is as it was"
        ));
    }
    let tmp = format!("{path}.tmp");
    std::fs::File::create(&tmp)
        .and_then(|mut f| f.write_all(new.as_bytes()).and_then(|()| f.sync_all()))
        .map_err(|e| format!("{tmp}: {e}"))?;
    std::fs::rename(&tmp, path).map_err(|e| format!("{path}: {e}"))
}
