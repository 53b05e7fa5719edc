//! `motorwire servo import-lerobot FILE`: a bus map from a LeRobot
//! calibration file (`{"shoulder_pan":{"id":1,"drive_mode":0,
//! "homing_offset":-1470,"range_min":758,"range_max":3292},...}`), the
//! same arm: each motor's id and calibration as the file has them, its
//! model and the bus's serial port from the command line.

use std::collections::BTreeMap;
use std::fmt::Write as _;

use serde::Deserialize;

/// The robots whose motors' models are known by name (LeRobot's own
/// follower and leader arms).
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum Robot {
    /// SO-100: six Feetech STS3215.
    So100,
    /// SO-101: six Feetech STS3215.
    So101,
    /// Koch: Dynamixel XL430-W250 at the shoulder, XL330-M288 beyond.
    Koch,
}

impl Robot {
    /// The model of motor `name` of this robot.
    fn model(self, name: &str) -> &'static str {
        match self {
            Self::So100 | Self::So101 => "sts3215",
            Self::Koch if matches!(name, "shoulder_pan" | "shoulder_lift") => "xl430-w250",
            Self::Koch => "xl330-m288",
        }
    }
}

/// What `import-lerobot` takes.
#[derive(Debug, clap::Args)]
pub(crate) struct ImportArgs {
    /// The LeRobot calibration file (JSON, as LeRobot writes it for a
    /// robot or teleoperator id).
    file: String,
    /// The serial port of the arm's bus (`/dev/ttyACM0`).
    #[arg(long, value_name = "PATH")]
    port: String,
    /// The robot, which names each motor's model: `so100`, `so101` or
    /// `koch`. Or `--model`.
    #[arg(
        long,
        value_enum,
        required_unless_present = "model",
        conflicts_with = "model"
    )]
    robot: Option<Robot>,
    /// The model of every motor (`sts3215`, `xl330-m288`, `xl430-w250`,
    /// `xm430-w350`).
    #[arg(long, value_name = "MODEL")]
    model: Option<String>,
    /// The bus's baud rate.
    #[arg(long, value_name = "BAUD", default_value_t = 1_000_000)]
    baud: u32,
}

/// One motor of a LeRobot calibration file.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Motor {
    id: i64,
    drive_mode: i64,
    homing_offset: i64,
    range_min: i64,
    range_max: i64,
}

/// The largest calibration file read (a real one is under 1 kB).
const MAX_FILE: u64 = 1 << 20;

/// The bus map for `args`, as TOML text, checked by reading it back as a
/// bus map.
pub(crate) fn import(args: &ImportArgs) -> Result<String, String> {
    use std::io::Read as _;
    let file = std::fs::File::open(&args.file).map_err(|e| format!("{}: {e}", args.file))?;
    let mut text = String::new();
    file.take(MAX_FILE + 1)
        .read_to_string(&mut text)
        .map_err(|e| format!("{}: {e}", args.file))?;
    if text.len() as u64 > MAX_FILE {
        return Err(format!("{}: larger than {MAX_FILE} bytes", args.file));
    }
    let motors: BTreeMap<String, Motor> = serde_json::from_str(&text)
        .map_err(|e| format!("{}: not a LeRobot calibration file: {e}", args.file))?;
    if motors.is_empty() {
        return Err(format!("{}: no motor in it", args.file));
    }
    let mut out = format!(
        "# Imported by `motorwire servo import-lerobot` from {}: each motor's id\n\
         # and calibration as LeRobot keeps them; positions in degrees, as LeRobot\n\
         # reads them in degrees (0: the middle of each calibrated range), limited\n\
         # to each calibrated range.\n",
        args.file.escape_debug()
    );
    for (name, m) in &motors {
        let model = match (&args.model, args.robot) {
            (Some(model), _) => model.as_str(),
            (None, Some(robot)) => robot.model(name),
            (None, None) => return Err("give --robot or --model".to_owned()),
        };
        let dialect = if model.starts_with("sts") || model.starts_with("scs") {
            "feetech"
        } else {
            "dynamixel"
        };
        // A JSON string is a TOML basic string (the same escapes).
        let quoted = |s: &str| serde_json::Value::String(s.to_owned()).to_string();
        let _ = write!(
            out,
            "\n[motors.{}]\ndialect = \"{dialect}\"\nport = {}\nbaud = {}\nid = {}\nmodel = {}\n\
             calibration = {{ homing_offset = {}, range_min = {}, range_max = {}, drive_mode = {} }}\n",
            quoted(name),
            quoted(&args.port),
            args.baud,
            m.id,
            quoted(model),
            m.homing_offset,
            m.range_min,
            m.range_max,
            m.drive_mode
        );
    }
    motorwire_translate::BusMap::from_toml(&out).map_err(|e| format!("{}: {e}", args.file))?;
    Ok(out)
}
