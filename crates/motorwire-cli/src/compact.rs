//! `motorwire compact encode|decode`.
//!
//! Encoding maps a WIA MotorCommand onto the 24-byte compact command:
//! the motor id becomes its CRC-32 hash, the timestamp a u64, the mode its
//! code, the setpoint an f32, and the velocity and torque limits their fixed
//! point (rounded down, so never looser). `safety_limits.emergency_stop: true`
//! sets EMERGENCY_STOP and a priority of 75 or more sets PRIORITY_HIGH. The
//! command is fully validated first; members the compact command has no place
//! for are named on stderr, never dropped silently.

use std::collections::HashMap;

use clap::{Args as ClapArgs, Subcommand};
use motorwire_compact::{CompactCommand, MotorHash, TorqueLimit, VelocityLimit};
use motorwire_translate::compact_command;
use motorwire_wia::{MotorCommand, Validator};

use crate::console::note;
use crate::lines::{filter, from_hex, to_hex};

/// Encode and decode the 24-byte WIA compact command.
#[derive(Debug, ClapArgs)]
pub(crate) struct Args {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Read WIA MotorCommand JSON lines on stdin; print each as 48 hex digits.
    Encode(EncodeArgs),
    /// Read 48-hex-digit lines on stdin; print each as JSON.
    Decode(DecodeArgs),
}

#[derive(Debug, ClapArgs)]
struct EncodeArgs {
    /// The current time (Unix ms) for the staleness rule.
    #[arg(long, value_name = "UNIX_MS")]
    now: Option<u64>,
}

#[derive(Debug, ClapArgs)]
struct DecodeArgs {
    /// A file of motor ids, one per line, to resolve the hashes back to
    /// names (at most 1 MiB).
    #[arg(long, value_name = "FILE")]
    names: Option<String>,
}

pub(crate) fn run(args: &Args) -> u8 {
    match &args.command {
        Command::Encode(a) => {
            let validator = crate::validate::with_clock(Validator::new(), a.now);
            filter(|line| {
                let cmd: MotorCommand = validator.parse(line).map_err(|e| e.to_string())?;
                let translated = compact_command(&cmd).map_err(|e| e.to_string())?;
                for loss in &translated.report.losses {
                    note!("motorwire compact encode: {}: {loss}", cmd.motor_id);
                }
                translated
                    .value
                    .encode()
                    .map(|b| to_hex(&b))
                    .map_err(|e| e.to_string())
            })
        }
        Command::Decode(a) => {
            let names = match &a.names {
                None => None,
                Some(path) => match read_names(path) {
                    Ok(n) => Some(n),
                    Err(e) => {
                        note!("motorwire compact decode: {path}: {e}");
                        return 2;
                    }
                },
            };
            filter(|line| decode(line, names.as_ref()))
        }
    }
}

/// The largest `--names` file read (1 MiB).
const MAX_NAMES_SIZE: usize = 1 << 20;

fn read_names(path: &str) -> Result<HashMap<MotorHash, String>, String> {
    let text = crate::input::read_text_file(path, MAX_NAMES_SIZE)?;
    let mut names: HashMap<MotorHash, String> = HashMap::new();
    for name in text
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty() && !l.starts_with('#'))
    {
        let hash = MotorHash::of(name);
        if let Some(other) = names.get(&hash)
            && other != name
        {
            return Err(format!(
                "{other:?} and {name:?} share the hash {hash}; the wire cannot tell them apart"
            ));
        }
        names.insert(hash, name.to_owned());
    }
    Ok(names)
}

fn decode(line: &str, names: Option<&HashMap<MotorHash, String>>) -> Result<String, String> {
    let bytes = from_hex(line)?;
    let cmd = CompactCommand::decode(&bytes).map_err(|e| e.to_string())?;
    let decoded = Decoded {
        command: &cmd,
        // With --names: the name, or null for a hash no name has.
        motor_id: names.map(|n| n.get(&cmd.motor).map(String::as_str)),
        flag_names: cmd.flags.names().collect(),
        velocity_limit_units_per_s: cmd.velocity_limit.map(VelocityLimit::units_per_s),
        torque_limit_nm: cmd.torque_limit.map(TorqueLimit::nm),
    };
    serde_json::to_string(&decoded).map_err(|e| e.to_string())
}

/// A decoded command: the wire's fields as they are (the raw steps:
/// `velocity_limit` in 0.1 units/s, `torque_limit` in 0.01 Nm, `flags` the
/// bits), then the same in physical units and by name.
#[derive(serde::Serialize)]
struct Decoded<'a> {
    #[serde(flatten)]
    command: &'a CompactCommand,
    #[serde(skip_serializing_if = "Option::is_none")]
    motor_id: Option<Option<&'a str>>,
    /// The flags set, by name (`PRIORITY_HIGH`, `EMERGENCY_STOP`, ...).
    flag_names: Vec<&'static str>,
    /// The velocity limit in the mode's unit per second (deg/s or rad/s);
    /// null: no limit.
    velocity_limit_units_per_s: Option<f64>,
    /// The torque limit in Nm; null: no limit.
    torque_limit_nm: Option<f64>,
}
