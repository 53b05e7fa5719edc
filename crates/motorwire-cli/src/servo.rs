//! `motorwire servo encode|decode`: serial bus servo packets (Feetech
//! STS/SMS and SCS, Dynamixel Protocol 2.0) on JSON lines in the vendors'
//! own terms, built and read by motorwire-servo.

use clap::{Args as ClapArgs, Subcommand, ValueEnum};
use motorwire_servo::{Instruction, Protocol, decode_status, encode};
use serde::Deserialize;
use serde::de::{Deserializer, MapAccess, Visitor};
use serde_json::json;

use crate::lines::{filter, from_hex, to_hex};

/// Encode and decode serial bus servo packets.
#[derive(Debug, ClapArgs)]
pub(crate) struct Args {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Read instruction lines (`{"instruction":"write","id":1,
    /// "address":42,"data":"0008"}`): `ping`, `read` (`length`), `write`
    /// and `reg_write` (`data` as hex, or `value` with `length` 1, 2 or 4
    /// written as the SDK's `writeNByteTxOnly` writes it), `action`,
    /// `sync_read` (`address`, `length`, `ids`), `sync_write` (`address`,
    /// `length`, `data` an object of ids to hex, in its order), and for
    /// `dxl2` `reboot`, `factory_reset` (`option`), `bulk_read` (`reads`:
    /// `[[id,address,length],...]`) and `bulk_write` (`writes`:
    /// `[[id,address,"hex"],...]`); print each packet as `{"bytes":"hex"}`.
    Encode(Which),
    /// Read status packets as `{"bytes":"hex"}` (what the port gave, noise
    /// and all), with `"length":N` for a read's answer (the bytes it asked
    /// for); print the first packet found as `{"id":N,"error":E,
    /// "params":"hex"}`, or why there is none (`timeout`, `incomplete`,
    /// `check`, `short`).
    Decode(Which),
    /// Print a bus map (TOML) from a LeRobot calibration file: each
    /// motor's id and calibration as the file has them, on `--port`, its
    /// model from `--robot` (so100, so101, koch) or `--model`. The bridge
    /// then reads and gates the arm as LeRobot calibrated it.
    ImportLerobot(crate::servo_import::ImportArgs),
    /// Calibrate a bus map's serial servos as LeRobot does (torque off,
    /// the arm in the middle of its range, each joint swept through its
    /// range; ENTER after each), writing each servo's homing offset and
    /// position limits into it and its calibration into the map.
    Calibrate(crate::servo_calibrate::CalibrateArgs),
}

#[derive(Debug, ClapArgs)]
struct Which {
    /// The protocol: `scs0` (Feetech STS/SMS, little-endian), `scs1`
    /// (Feetech SCS, big-endian), `dxl2` (Dynamixel Protocol 2.0).
    #[arg(long, value_enum)]
    protocol: ProtocolArg,
}

#[derive(Debug, Clone, Copy, ValueEnum)]
enum ProtocolArg {
    Scs0,
    Scs1,
    Dxl2,
}

impl ProtocolArg {
    const fn protocol(self) -> Protocol {
        match self {
            Self::Scs0 => Protocol::Scs0,
            Self::Scs1 => Protocol::Scs1,
            Self::Dxl2 => Protocol::Dxl2,
        }
    }
}

pub(crate) fn run(args: &Args) -> u8 {
    match &args.command {
        Command::Encode(w) => {
            let p = w.protocol.protocol();
            filter(|line| {
                let bytes = encode(p, &instruction(p, line)?).map_err(|e| e.to_string())?;
                Ok(json!({ "bytes": to_hex(&bytes) }).to_string())
            })
        }
        Command::Decode(w) => {
            let p = w.protocol.protocol();
            filter(|line| decode_line(p, line))
        }
        Command::Calibrate(a) => crate::servo_calibrate::calibrate(a),
        Command::ImportLerobot(a) => match crate::servo_import::import(a) {
            Ok(map) => match crate::console::say!("{}", map.trim_end()) {
                Ok(()) => 0,
                Err(_) => 1,
            },
            Err(e) => {
                crate::console::note!("motorwire servo import-lerobot: {e}");
                1
            }
        },
    }
}

/// An instruction line, every member by the vendors' names.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Line {
    instruction: String,
    id: Option<u8>,
    address: Option<u16>,
    length: Option<u16>,
    data: Option<Data>,
    value: Option<i64>,
    ids: Option<Vec<u8>>,
    reads: Option<Vec<(u8, u16, u16)>>,
    writes: Option<Vec<(u8, u16, String)>>,
    option: Option<u8>,
}

/// `data`: hex, or a sync write's servos and their hex in their order.
#[derive(Debug)]
enum Data {
    Hex(String),
    Entries(Vec<(String, String)>),
}

impl<'de> Deserialize<'de> for Data {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = Data;
            fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str("hex, or an object of servo ids to hex")
            }
            fn visit_str<E: serde::de::Error>(self, v: &str) -> Result<Data, E> {
                Ok(Data::Hex(v.to_owned()))
            }
            fn visit_map<A: MapAccess<'de>>(self, mut m: A) -> Result<Data, A::Error> {
                let mut entries = Vec::new();
                while let Some(entry) = m.next_entry::<String, String>()? {
                    entries.push(entry);
                }
                Ok(Data::Entries(entries))
            }
        }
        d.deserialize_any(V)
    }
}

fn need<T>(value: Option<T>, member: &str, instruction: &str) -> Result<T, String> {
    value.ok_or_else(|| format!("{instruction} needs \"{member}\""))
}

/// The line's instruction.
fn instruction(p: Protocol, line: &str) -> Result<Instruction, String> {
    let l: Line = serde_json::from_str(line).map_err(|e| e.to_string())?;
    let name = l.instruction.as_str();
    let id = || need(l.id, "id", name);
    let address = || need(l.address, "address", name);
    let length = || need(l.length, "length", name);
    Ok(match name {
        "ping" => Instruction::Ping { id: id()? },
        "read" => Instruction::Read {
            id: id()?,
            address: address()?,
            length: length()?,
        },
        "write" | "reg_write" => {
            let data = written(p, &l)?;
            let (id, address) = (id()?, address()?);
            if name == "write" {
                Instruction::Write { id, address, data }
            } else {
                Instruction::RegWrite { id, address, data }
            }
        }
        "action" => Instruction::Action { id: id()? },
        "reboot" => Instruction::Reboot { id: id()? },
        "factory_reset" => Instruction::FactoryReset {
            id: id()?,
            option: need(l.option, "option", name)?,
        },
        "sync_read" => Instruction::SyncRead {
            address: address()?,
            length: length()?,
            ids: need(l.ids.clone(), "ids", name)?,
        },
        "sync_write" => sync_write(&l, address()?, length()?)?,
        "bulk_read" => Instruction::BulkRead {
            reads: need(l.reads.clone(), "reads", name)?,
        },
        "bulk_write" => Instruction::BulkWrite {
            writes: need(l.writes.as_ref(), "writes", name)?
                .iter()
                .map(|(id, a, hex)| Ok((*id, *a, from_hex(hex)?)))
                .collect::<Result<_, String>>()?,
        },
        other => {
            return Err(format!(
                "unknown instruction {other:?} (ping, read, write, reg_write, action, sync_read, sync_write, reboot, factory_reset, bulk_read, bulk_write)"
            ));
        }
    })
}

/// A write's data: its hex (its length, where given, the same), or its
/// value in `length` bytes as the SDK writes it (two's complement for a
/// negative value).
fn written(p: Protocol, l: &Line) -> Result<Vec<u8>, String> {
    match (&l.data, l.value) {
        (Some(Data::Hex(hex)), None) => {
            let data = from_hex(hex)?;
            match l.length {
                Some(n) if usize::from(n) != data.len() => Err(format!(
                    "\"length\" is {n} and \"data\" is {} bytes",
                    data.len()
                )),
                _ => Ok(data),
            }
        }
        (None, Some(v)) => {
            let n = need(l.length, "length", &l.instruction)?;
            let length = u8::try_from(n)
                .ok()
                .filter(|n| matches!(n, 1 | 2 | 4))
                .ok_or_else(|| format!("a value is written in 1, 2 or 4 bytes, not {n}"))?;
            let bits = u32::from(length) * 8;
            let (min, max) = (-(1i64 << (bits - 1)), (1i64 << bits) - 1);
            if !(min..=max).contains(&v) {
                return Err(format!(
                    "value {v} does not fit in {length} bytes ({min} to {max})"
                ));
            }
            let raw = u32::try_from(v & max).map_err(|e| e.to_string())?;
            p.value_bytes(raw, length).map_err(|e| e.to_string())
        }
        (Some(Data::Entries(_)), _) => Err("a write's \"data\" is hex".to_owned()),
        (Some(_), Some(_)) => Err("give \"data\" or \"value\", not both".to_owned()),
        (None, None) => Err(format!("{} needs \"data\" or \"value\"", l.instruction)),
    }
}

fn sync_write(l: &Line, address: u16, length: u16) -> Result<Instruction, String> {
    let Some(Data::Entries(entries)) = &l.data else {
        return Err("sync_write needs \"data\" as an object of servo ids to hex".to_owned());
    };
    let entries = entries
        .iter()
        .map(|(id, hex)| {
            let id: u8 = id
                .parse()
                .map_err(|_| format!("sync_write: {id:?} is not a servo id (0 to 252)"))?;
            Ok((id, from_hex(hex)?))
        })
        .collect::<Result<_, String>>()?;
    Ok(Instruction::SyncWrite {
        address,
        length,
        entries,
    })
}

fn decode_line(p: Protocol, line: &str) -> Result<String, String> {
    #[derive(Deserialize)]
    #[serde(deny_unknown_fields)]
    struct Received {
        bytes: String,
        length: Option<usize>,
    }
    let r: Received = serde_json::from_str(line).map_err(|e| e.to_string())?;
    let bytes = from_hex(&r.bytes)?;
    let d = decode_status(p, &bytes, r.length).map_err(|e| format!("{}: {e}", e.kind()))?;
    Ok(json!({
        "id": d.status.id,
        "error": d.status.error,
        "params": to_hex(&d.status.params),
    })
    .to_string())
}
