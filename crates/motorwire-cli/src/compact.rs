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
use motorwire_compact::{CompactCommand, Flags, MotorHash, TorqueLimit, VelocityLimit};
use motorwire_wia::{MotorCommand, Validator};

use crate::lines::{filter, from_hex, to_hex};

/// WIA priority from which PRIORITY_HIGH is set.
pub(crate) const HIGH_PRIORITY: i64 = 75;

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
    /// A file of motor ids, one per line, to resolve the hashes back to names.
    #[arg(long, value_name = "FILE")]
    names: Option<String>,
}

pub(crate) fn run(args: &Args) -> u8 {
    match &args.command {
        Command::Encode(a) => {
            let validator = crate::validate::with_clock(Validator::new(), a.now);
            filter(|line| {
                let cmd: MotorCommand = validator.parse(line).map_err(|e| e.to_string())?;
                let (compact, dropped) = to_compact(&cmd)?;
                if !dropped.is_empty() {
                    eprintln!(
                        "motorwire compact encode: {}: the compact command has no place for {}",
                        cmd.motor_id,
                        dropped.join(", ")
                    );
                }
                compact
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
                        eprintln!("motorwire compact decode: {path}: {e}");
                        return 2;
                    }
                },
            };
            filter(|line| decode(line, names.as_ref()))
        }
    }
}

/// The compact command for a valid WIA MotorCommand, and the names of the
/// members it had to leave out.
pub(crate) fn to_compact(
    cmd: &MotorCommand,
) -> Result<(CompactCommand, Vec<&'static str>), String> {
    let t = cmd.timestamp;
    if !(t >= 0.0 && t.fract() == 0.0 && t < 18_446_744_073_709_551_616.0) {
        return Err(format!(
            "timestamp {t} is not a whole number of ms that fits 64 bits"
        ));
    }
    #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)] // checked just above
    let timestamp_ms = t as u64;
    let setpoint = CompactCommand::setpoint_from_f64(cmd.setpoint).map_err(|e| e.to_string())?;
    let velocity_limit = cmd
        .velocity_limit
        .map(VelocityLimit::from_units_per_s)
        .transpose()
        .map_err(|e| e.to_string())?;
    let torque_limit = cmd
        .torque_limit
        .map(TorqueLimit::from_nm)
        .transpose()
        .map_err(|e| e.to_string())?;
    let mut flags = Flags::NONE;
    let estop = cmd.safety_limits.as_ref().and_then(|l| l.emergency_stop) == Some(true);
    if estop {
        flags = flags.union(Flags::EMERGENCY_STOP);
    }
    if cmd.priority.is_some_and(|p| p >= HIGH_PRIORITY) {
        flags = flags.union(Flags::PRIORITY_HIGH);
    }
    let mut dropped = Vec::new();
    for (name, present) in [
        ("acceleration_limit", cmd.acceleration_limit.is_some()),
        ("pid_gains", cmd.pid_gains.is_some()),
        ("impedance_params", cmd.impedance_params.is_some()),
        ("filter_config", cmd.filter_config.is_some()),
        (
            "safety_limits (other than emergency_stop)",
            cmd.safety_limits.as_ref().is_some_and(|l| {
                l.min_position.is_some()
                    || l.max_position.is_some()
                    || l.max_velocity.is_some()
                    || l.max_torque.is_some()
                    || !l.extra.is_empty()
            }),
        ),
        ("priority (beyond PRIORITY_HIGH)", cmd.priority.is_some()),
        ("metadata", cmd.metadata.is_some()),
        ("unknown members", !cmd.extra.is_empty()),
    ] {
        if present {
            dropped.push(name);
        }
    }
    let compact = CompactCommand {
        motor: MotorHash::of(&cmd.motor_id),
        timestamp_ms,
        control_mode: cmd.control_mode,
        flags,
        setpoint,
        velocity_limit,
        torque_limit,
    };
    Ok((compact, dropped))
}

fn read_names(path: &str) -> std::io::Result<HashMap<MotorHash, String>> {
    let text = std::fs::read_to_string(path)?;
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
            return Err(std::io::Error::other(format!(
                "{other:?} and {name:?} share the hash {hash}; the wire cannot tell them apart"
            )));
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
    };
    serde_json::to_string(&decoded).map_err(|e| e.to_string())
}

#[derive(serde::Serialize)]
struct Decoded<'a> {
    #[serde(flatten)]
    command: &'a CompactCommand,
    #[serde(skip_serializing_if = "Option::is_none")]
    motor_id: Option<Option<&'a str>>,
}
