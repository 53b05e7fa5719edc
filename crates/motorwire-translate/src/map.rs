//! The bus map: which motor speaks which dialect, where it is, its angle
//! unit, its safety limits and its motion defaults.

use std::collections::BTreeMap;
use std::fmt;
use std::str::FromStr;

use motorwire_irpc::{MotionProfile, WireVersion};
use serde::Deserialize;

/// A bus map that could not be read.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum MapError {
    /// Not valid TOML, or a key the map does not have, or a value of the
    /// wrong type (toml's message, with line and column).
    #[error("bus map: {message}")]
    Toml {
        /// What the TOML parser reported.
        message: String,
    },
    /// A motor name WIA cannot address (`^[a-zA-Z0-9_-]+$`, at most 64
    /// bytes).
    #[error(
        "bus map: motor name {name:?} is not a WIA motor_id (letters, digits, _ and -, at most 64 bytes)"
    )]
    BadName {
        /// The name.
        name: String,
    },
    /// A field with an invalid value.
    #[error("bus map: motors.{motor}.{field}: {problem}")]
    Invalid {
        /// The motor.
        motor: String,
        /// The field.
        field: &'static str,
        /// What is wrong with it.
        problem: String,
    },
    /// A field the motor's dialect needs is absent.
    #[error("bus map: motors.{motor} speaks {dialect} and needs {field}")]
    Missing {
        /// The motor.
        motor: String,
        /// Its dialect.
        dialect: &'static str,
        /// The field.
        field: &'static str,
    },
    /// A field that means nothing for the motor's dialect.
    #[error("bus map: motors.{motor}.{field} means nothing for a {dialect} motor")]
    NotForDialect {
        /// The motor.
        motor: String,
        /// Its dialect.
        dialect: &'static str,
        /// The field.
        field: &'static str,
    },
    /// Two motors at the same address.
    #[error("bus map: motors.{first} and motors.{second} are both {address}")]
    SharedAddress {
        /// The first motor (in name order).
        first: String,
        /// The second.
        second: String,
        /// The address they share.
        address: String,
    },
    /// The file could not be read ([`BusMap::from_path`]).
    #[error("bus map {path}: {message}")]
    Read {
        /// The file, as given.
        path: String,
        /// What kind of I/O error it was.
        kind: std::io::ErrorKind,
        /// The operating system's message.
        message: String,
    },
    /// The file is larger than [`BusMap::MAX_FILE_SIZE`]
    /// ([`BusMap::from_path`]): no more than that is read.
    #[error("bus map {path}: larger than {limit} bytes")]
    TooLarge {
        /// The file, as given.
        path: String,
        /// The limit in bytes.
        limit: u64,
    },
    /// The file is not UTF-8 ([`BusMap::from_path`]).
    #[error("bus map {path}: not UTF-8 (at byte {offset})")]
    NotUtf8 {
        /// The file, as given.
        path: String,
        /// The offset of the first byte that is not UTF-8.
        offset: usize,
    },
}

/// How a motor is reached.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Target {
    /// An iRPC joint on CAN-FD.
    Irpc {
        /// Its node id (not 0x0000 or 0xFFFF, the broadcast ids).
        node: u16,
        /// The wire version it speaks.
        wire: WireVersion,
    },
    /// A compact device: a device taking the WIA compact command on CAN-FD
    /// (WIRE-FACTS §2.1).
    Compact {
        /// The CAN id its commands are sent on (11 bits, not 0x000: the
        /// arm's iRPC id).
        node: u16,
        /// The CAN id it sends its feedback on: the map's `feedback_node`,
        /// by default `node | 0x400`; never `node`.
        feedback_node: u16,
    },
    /// One of the Orion arm controller's motors.
    Orion {
        /// Which.
        motor: motorwire_orion::Motor,
    },
    /// An mjbots moteus controller on CAN-FD (its register protocol,
    /// `motorwire_moteus`).
    Moteus {
        /// Its id (1..=127).
        id: u8,
        /// The CAN prefix of its bus (13 bits; the map's `bus`, 0 by
        /// default).
        bus: u16,
        /// How often the bridge queries it for feedback (Hz; the map's
        /// `query_rate_hz`, 50 by default).
        query_rate_hz: u16,
        /// Whether a stop puts it in brake mode (its windings shorted: the
        /// map's `stop = "brake"`) rather than stopped (no output, the
        /// default `stop = "stop"`).
        brake: bool,
    },
    /// A serial bus servo (Feetech or Dynamixel) on one of the map's
    /// serial ports ([`BusMap::servo_ports`]).
    Servo(crate::servo::ServoTarget),
}

impl Target {
    /// The dialect's name as the bus map spells it.
    pub const fn dialect(&self) -> &'static str {
        match self {
            Target::Irpc { .. } => "irpc",
            Target::Compact { .. } => "compact",
            Target::Orion { .. } => "orion",
            Target::Moteus { .. } => "moteus",
            Target::Servo(s) => s.vendor.name(),
        }
    }
}

/// The unit a motor's WIA positions are in (velocities per second,
/// accelerations per second squared): motorwire-core's, declared once.
pub use motorwire_core::AngleUnit;

/// A motor's safety limits, in its [`AngleUnit`] (and newton-metres).
/// `None` is "no limit from the map".
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Limits {
    /// Lowest position.
    pub min_position: Option<f64>,
    /// Highest position.
    pub max_position: Option<f64>,
    /// Largest speed.
    pub max_velocity: Option<f64>,
    /// Largest acceleration (speeding up).
    pub max_acceleration: Option<f64>,
    /// Largest deceleration (slowing down); `None` is `max_acceleration`.
    pub max_deceleration: Option<f64>,
    /// Largest jerk.
    pub max_jerk: Option<f64>,
    /// Largest torque magnitude (Nm).
    pub max_torque: Option<f64>,
    /// How hard the motor brakes on an emergency stop (its unit per s²);
    /// the simulated joint brakes at it, real joints at their own.
    pub emergency_deceleration: Option<f64>,
}

/// One motor of the map.
#[derive(Debug, Clone, PartialEq)]
pub struct MappedMotor {
    /// The WIA `motor_id`.
    pub name: String,
    /// How it is reached.
    pub target: Target,
    /// The unit its WIA positions are in.
    pub unit: AngleUnit,
    /// Its safety limits.
    pub limits: Limits,
    /// Where `limits` come from, as a refusal names it: `"bus map"`, or
    /// what [`BusMap::set_limits`] was told.
    pub limits_source: &'static str,
    /// The deadman: a velocity or torque setpoint with no new command for
    /// this long is brought to a stop. The map's `command_timeout_ms`; by
    /// default 200 ms (the WIA controller-to-motor watchdog) for compact
    /// devices and Orion motors, which hold such setpoints; `None` for iRPC
    /// joints (they take position moves and keep their own watchdog) or
    /// where the map says `command_timeout_ms = 0`.
    pub command_timeout: Option<std::time::Duration>,
    /// The motion profile its iRPC moves use.
    pub profile: MotionProfile,
    /// How close to its target (in its unit) a position move must come
    /// to have arrived: the map's `arrival_tolerance`, by default 0.1°
    /// (0.1° in radians for a motor in `rad`).
    pub arrival_tolerance: f64,
}

/// The bus map, read from TOML.
///
/// ```
/// use motorwire_translate::{BusMap, Target};
/// let map = BusMap::from_toml(r#"
///     [motors.elbow]
///     dialect = "irpc"
///     node = 0x12
///     limits = { min_position = 0, max_position = 150, max_velocity = 120, max_acceleration = 500 }
///
///     [motors.turntable]
///     dialect = "orion"
///     key = "TRM"
/// "#)?;
/// assert!(matches!(map.motor("elbow").unwrap().target, Target::Irpc { node: 0x12, .. }));
/// assert_eq!(map.motors().count(), 2);
/// # Ok::<(), motorwire_translate::MapError>(())
/// ```
///
/// Per motor: `dialect` (`irpc`, `compact`, `orion`, `moteus`, `feetech` or
/// `dynamixel`); for a serial bus servo `port`, `id`, `model` and optionally
/// `baud`, `calibration` and `stop` (`torque_off` or `hold`), its position
/// limits by default its calibrated range; for iRPC `node`
/// and optionally `wire` (`v1`, `v2.0` the default, `v2.1`, `v2.2`) and
/// `profile` (`trapezoidal`, `scurve` the default, `adaptive`); for a
/// compact device `node` (the CAN id of its commands, 0x001..=0x7FF) and
/// optionally `feedback_node` (the CAN id of its feedback, by default
/// `node | 0x400`); for Orion
/// `key` (`TRM` ...); for a moteus controller `id` (1..=127) and optionally
/// `bus` (its CAN prefix), `query_rate_hz` (50 by default) and `stop`
/// (`stop` the default, or `brake`); `unit` (`deg` the default, or `rad`);
/// `arrival_tolerance` (how close a position move must come to its target
/// to have arrived, in the motor's unit; 0.1° by default);
/// `command_timeout_ms` (the deadman for velocity and torque setpoints: 200
/// by default for compact and Orion motors, 0 to disable); and `limits`
/// (`min_position`, `max_position`, `max_velocity`, `max_acceleration`,
/// `max_deceleration`, `max_jerk`, `max_torque`, `emergency_deceleration`),
/// all in the motor's unit.
///
/// A map is one bus's devices: the bridge serves at most 64 motors
/// (`motorwire_bridge::Bridge::MAX_DEVICES`, what one CAN-FD bus carries
/// at their feedback rates) and refuses a larger map at once, naming the
/// count and the limit.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct BusMap {
    motors: BTreeMap<String, MappedMotor>,
    /// The iRPC motors' names by node id ([`BusMap::irpc_node`], asked
    /// for every frame a joint sends).
    irpc: BTreeMap<u16, String>,
    /// The serial ports of its servos, each once, in the order the map
    /// names them first (by motor name).
    servo_ports: Vec<crate::servo::ServoPort>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawMap {
    #[serde(default)]
    motors: BTreeMap<String, RawMotor>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawMotor {
    dialect: String,
    node: Option<i64>,
    feedback_node: Option<i64>,
    wire: Option<String>,
    key: Option<String>,
    unit: Option<String>,
    profile: Option<String>,
    arrival_tolerance: Option<f64>,
    command_timeout_ms: Option<u64>,
    id: Option<i64>,
    bus: Option<i64>,
    query_rate_hz: Option<i64>,
    stop: Option<String>,
    port: Option<String>,
    baud: Option<i64>,
    model: Option<String>,
    calibration: Option<RawCalibration>,
    #[serde(default)]
    limits: RawLimits,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawCalibration {
    homing_offset: i64,
    range_min: i64,
    range_max: i64,
    #[serde(default)]
    drive_mode: i64,
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct RawLimits {
    min_position: Option<f64>,
    max_position: Option<f64>,
    max_velocity: Option<f64>,
    max_acceleration: Option<f64>,
    max_deceleration: Option<f64>,
    max_jerk: Option<f64>,
    max_torque: Option<f64>,
    emergency_deceleration: Option<f64>,
}

fn invalid(motor: &str, field: &'static str, problem: impl fmt::Display) -> MapError {
    MapError::Invalid {
        motor: motor.to_owned(),
        field,
        problem: problem.to_string(),
    }
}

/// A compact device's CAN ids (WIRE-FACTS §2.1): `node` required, in
/// 0x001..=0x7FF (an 11-bit id; 0x000 is the arm's iRPC id);
/// `feedback_node` by default `node | 0x400`, in the same range and never
/// `node` itself.
fn compact_target(
    name: &str,
    node: Option<i64>,
    feedback_node: Option<i64>,
) -> Result<Target, MapError> {
    let can_id = |field: &'static str, v: i64| {
        u16::try_from(v)
            .ok()
            .filter(|n| (1..=0x7FF).contains(n))
            .ok_or_else(|| {
                invalid(
                    name,
                    field,
                    format!("{v} is not a CAN id in 0x001..=0x7FF (11 bits; 0x000 is the arm's)"),
                )
            })
    };
    let node = node.ok_or(MapError::Missing {
        motor: name.to_owned(),
        dialect: "compact",
        field: "node",
    })?;
    let node = can_id("node", node)?;
    let feedback_node = match feedback_node {
        Some(f) => can_id("feedback_node", f)?,
        None => node | 0x400,
    };
    if feedback_node == node {
        return Err(invalid(
            name,
            "feedback_node",
            format!(
                "{feedback_node:#05x} is the node itself (the device and its commands need different CAN ids; \
                 the default node | 0x400 is the node for nodes from 0x400)"
            ),
        ));
    }
    Ok(Target::Compact {
        node,
        feedback_node,
    })
}

/// A moteus controller's entry: `id` required (1..=127); `bus` (the CAN
/// prefix, 0..=0x1FFF), `query_rate_hz` (1..=1000, 50 by default) and
/// `stop` (`stop` or `brake`) optional; no iRPC, compact or Orion field.
fn moteus_target(
    name: &str,
    m: &RawMotor,
    not_for: impl Fn(&'static str, &'static str) -> MapError,
) -> Result<Target, MapError> {
    for (field, present) in [
        ("node", m.node.is_some()),
        ("feedback_node", m.feedback_node.is_some()),
        ("wire", m.wire.is_some()),
        ("key", m.key.is_some()),
        ("profile", m.profile.is_some()),
    ] {
        if present {
            return Err(not_for(field, "moteus"));
        }
    }
    let id = m.id.ok_or(MapError::Missing {
        motor: name.to_owned(),
        dialect: "moteus",
        field: "id",
    })?;
    let id = u8::try_from(id)
        .ok()
        .filter(|i| (1..=127).contains(i))
        .ok_or_else(|| invalid(name, "id", format!("{id} is not a moteus id in 1..=127")))?;
    let bus = match m.bus {
        None => 0,
        Some(b) => u16::try_from(b)
            .ok()
            .filter(|b| *b <= 0x1FFF)
            .ok_or_else(|| {
                invalid(
                    name,
                    "bus",
                    format!("{b} is not a CAN prefix in 0..=0x1FFF (13 bits)"),
                )
            })?,
    };
    let query_rate_hz = match m.query_rate_hz {
        None => 50,
        Some(r) => u16::try_from(r)
            .ok()
            .filter(|r| (1..=1000).contains(r))
            .ok_or_else(|| invalid(name, "query_rate_hz", format!("{r} is not in 1..=1000")))?,
    };
    let brake = match m.stop.as_deref() {
        None | Some("stop") => false,
        Some("brake") => true,
        Some(other) => {
            return Err(invalid(
                name,
                "stop",
                format!("{other:?} is not stop or brake"),
            ));
        }
    };
    Ok(Target::Moteus {
        id,
        bus,
        query_rate_hz,
        brake,
    })
}

/// The bus map's spelling of a dialect other than a servo's.
fn static_dialect(dialect: &str) -> &'static str {
    match dialect {
        "irpc" => "irpc",
        "compact" => "compact",
        "moteus" => "moteus",
        _ => "orion",
    }
}

/// A serial bus servo's entry: `port` (its serial port), `id` (0..=252)
/// and `model` required; `baud` (1,000,000 by default; one per port),
/// `calibration` (`homing_offset`, `range_min`, `range_max` in raw steps,
/// `drive_mode` 0 or 1; by default the whole turn) and `stop`
/// (`torque_off`, the default, or `hold`) optional. The servos of one port
/// speak one protocol at one baud rate.
fn servo_target(
    name: &str,
    m: &RawMotor,
    not_for: impl Fn(&'static str, &'static str) -> MapError,
    ports: &mut Vec<crate::servo::ServoPort>,
) -> Result<Target, MapError> {
    use crate::servo::{Calibration, ServoPort, ServoTarget, ServoVendor};
    let (vendor, dialect) = if m.dialect == "feetech" {
        (ServoVendor::Feetech, "feetech")
    } else {
        (ServoVendor::Dynamixel, "dynamixel")
    };
    for (field, present) in [
        ("node", m.node.is_some()),
        ("feedback_node", m.feedback_node.is_some()),
        ("wire", m.wire.is_some()),
        ("key", m.key.is_some()),
        ("profile", m.profile.is_some()),
        ("bus", m.bus.is_some()),
        ("query_rate_hz", m.query_rate_hz.is_some()),
    ] {
        if present {
            return Err(not_for(field, dialect));
        }
    }
    let missing = |field| MapError::Missing {
        motor: name.to_owned(),
        dialect,
        field,
    };
    let port = m.port.clone().ok_or_else(|| missing("port"))?;
    if port.is_empty() {
        return Err(invalid(name, "port", "an empty path is no serial port"));
    }
    let id = m.id.ok_or_else(|| missing("id"))?;
    let id = u8::try_from(id)
        .ok()
        .filter(|i| *i <= motorwire_servo::MAX_ID)
        .ok_or_else(|| invalid(name, "id", format!("{id} is not a servo id in 0..=252")))?;
    let model_name = m.model.as_deref().ok_or_else(|| missing("model"))?;
    let models: &[&str] = match vendor {
        ServoVendor::Feetech => &["sts3215"],
        ServoVendor::Dynamixel => &["xl330-m288", "xl430-w250", "xm430-w350"],
    };
    let Some(model) =
        motorwire_servo::table::model(model_name).filter(|t| models.contains(&t.name))
    else {
        return Err(invalid(
            name,
            "model",
            format!(
                "{model_name:?} is not a {dialect} model the bridge drives ({})",
                models.join(", ")
            ),
        ));
    };
    let baud = match m.baud {
        None => 1_000_000,
        Some(b) => u32::try_from(b)
            .ok()
            .filter(|b| (9600..=4_500_000).contains(b))
            .ok_or_else(|| {
                invalid(
                    name,
                    "baud",
                    format!("{b} is not a baud rate in 9600..=4500000"),
                )
            })?,
    };
    let top = i64::from(model.resolution) - 1;
    let calibration = match &m.calibration {
        None => Calibration::whole_turn(model.resolution),
        Some(c) => {
            let step = |field: &'static str, v: i64| {
                u32::try_from(v)
                    .ok()
                    .filter(|v| i64::from(*v) <= top)
                    .ok_or_else(|| {
                        invalid(
                            name,
                            field,
                            format!("{v} is not a step of a {model_name} (0..={top})"),
                        )
                    })
            };
            let range_min = step("calibration.range_min", c.range_min)?;
            let range_max = step("calibration.range_max", c.range_max)?;
            if range_min >= range_max {
                return Err(invalid(
                    name,
                    "calibration",
                    format!("range_min {range_min} is not below range_max {range_max}"),
                ));
            }
            let offset = model
                .register("Homing_Offset")
                .ok_or_else(|| invalid(name, "model", "no Homing_Offset register"))?;
            if offset.to_raw(c.homing_offset).is_err() {
                return Err(invalid(
                    name,
                    "calibration.homing_offset",
                    format!(
                        "{} does not fit the servo's Homing_Offset register",
                        c.homing_offset
                    ),
                ));
            }
            let drive_mode = u8::try_from(c.drive_mode)
                .ok()
                .filter(|d| *d <= 1)
                .ok_or_else(|| {
                    invalid(
                        name,
                        "calibration.drive_mode",
                        format!("{} is not 0 or 1", c.drive_mode),
                    )
                })?;
            Calibration {
                homing_offset: i32::try_from(c.homing_offset).unwrap_or(0),
                range_min,
                range_max,
                drive_mode,
            }
        }
    };
    let stop_holds = match m.stop.as_deref() {
        None | Some("torque_off") => false,
        Some("hold") => true,
        Some(other) => {
            return Err(invalid(
                name,
                "stop",
                format!("{other:?} is not torque_off or hold"),
            ));
        }
    };
    let index = match ports.iter().position(|p| p.path == port) {
        Some(k) => {
            let p = ports.get(k).ok_or_else(|| invalid(name, "port", "lost"))?;
            if p.baud != baud {
                return Err(invalid(
                    name,
                    "baud",
                    format!(
                        "{baud}, where another servo of {port} says {}: one bus, one baud rate",
                        p.baud
                    ),
                ));
            }
            if p.protocol != model.protocol {
                return Err(invalid(
                    name,
                    "model",
                    format!(
                        "a {model_name} speaks {}, where another servo of {port} speaks {}: one bus, one protocol",
                        model.protocol.name(),
                        p.protocol.name()
                    ),
                ));
            }
            k
        }
        None => {
            ports.push(ServoPort {
                path: port.clone(),
                baud,
                protocol: model.protocol,
            });
            ports.len() - 1
        }
    };
    let port = u8::try_from(index)
        .map_err(|_| invalid(name, "port", "more than 255 serial ports in one map"))?;
    Ok(Target::Servo(ServoTarget {
        vendor,
        port,
        id,
        model: model.name,
        calibration,
        stop_holds,
    }))
}

/// A servo's position limits: within its calibrated range, which they
/// are by default.
fn servo_limits(
    name: &str,
    t: &crate::servo::ServoTarget,
    unit: AngleUnit,
    l: &mut RawLimits,
) -> Result<(), MapError> {
    let (lo, hi) = crate::servo::calibrated_range(t, unit);
    for (field, value, bound) in [
        ("limits.min_position", &mut l.min_position, lo),
        ("limits.max_position", &mut l.max_position, hi),
    ] {
        match *value {
            None => *value = Some(bound),
            Some(v) if v.is_finite() && (v < lo - 1e-9 || v > hi + 1e-9) => {
                return Err(invalid(
                    name,
                    field,
                    format!("{v} is outside the servo's calibrated range {lo}..={hi}"),
                ));
            }
            Some(_) => {}
        }
    }
    Ok(())
}

fn valid_name(name: &str) -> bool {
    !name.is_empty()
        && name.len() <= 64
        && name
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || b == b'_' || b == b'-')
}

impl BusMap {
    /// The largest bus map file [`BusMap::from_path`] reads: 1 MiB (the
    /// `motorwire` command's limit too). A device or pipe that never ends
    /// (`/dev/zero`) is refused after this many bytes, not read forever.
    pub const MAX_FILE_SIZE: u64 = 1 << 20;

    /// Reads a bus map from a TOML file (at most [`BusMap::MAX_FILE_SIZE`]
    /// bytes of it).
    ///
    /// ```
    /// use motorwire_translate::{BusMap, MapError, Target};
    /// use motorwire_irpc::WireVersion;
    ///
    /// let path = std::env::temp_dir().join("motorwire-doctest-map.toml");
    /// std::fs::write(&path, "[motors.elbow]\ndialect = \"irpc\"\nnode = 0x12\n")?;
    /// let map = BusMap::from_path(&path)?;
    /// assert_eq!(map.motor("elbow").map(|m| m.target), Some(Target::Irpc { node: 0x12, wire: WireVersion::V2_0 }));
    ///
    /// let missing = BusMap::from_path("no/such/map.toml").unwrap_err();
    /// assert!(matches!(missing, MapError::Read { kind: std::io::ErrorKind::NotFound, .. }));
    /// # std::fs::remove_file(&path)?;
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    ///
    /// # Errors
    /// [`MapError::Read`] when the file cannot be opened or read,
    /// [`MapError::TooLarge`], [`MapError::NotUtf8`], or as
    /// [`BusMap::from_toml`].
    pub fn from_path(path: impl AsRef<std::path::Path>) -> Result<BusMap, MapError> {
        use std::io::Read as _;
        let path = path.as_ref();
        let shown = || path.display().to_string();
        let read_error = |e: std::io::Error| MapError::Read {
            path: shown(),
            kind: e.kind(),
            message: e.to_string(),
        };
        let file = std::fs::File::open(path).map_err(read_error)?;
        let mut bytes = Vec::new();
        file.take(Self::MAX_FILE_SIZE + 1)
            .read_to_end(&mut bytes)
            .map_err(read_error)?;
        if bytes.len() as u64 > Self::MAX_FILE_SIZE {
            return Err(MapError::TooLarge {
                path: shown(),
                limit: Self::MAX_FILE_SIZE,
            });
        }
        let text = String::from_utf8(bytes).map_err(|e| MapError::NotUtf8 {
            path: shown(),
            offset: e.utf8_error().valid_up_to(),
        })?;
        Self::from_toml(&text)
    }

    /// Reads a bus map.
    ///
    /// # Errors
    /// A [`MapError`] naming the motor and field.
    pub fn from_toml(text: &str) -> Result<BusMap, MapError> {
        let raw: RawMap = toml::from_str(text).map_err(|e| MapError::Toml {
            message: e.to_string().trim_end().to_owned(),
        })?;
        let mut motors = BTreeMap::new();
        let mut servo_ports = Vec::new();
        for (name, m) in raw.motors {
            if !valid_name(&name) {
                return Err(MapError::BadName { name });
            }
            let motor = Self::motor_from(&name, m, &mut servo_ports)?;
            motors.insert(name, motor);
        }
        let irpc = motors
            .values()
            .filter_map(|m| match m.target {
                Target::Irpc { node, .. } => Some((node, m.name.clone())),
                _ => None,
            })
            .collect();
        let map = BusMap {
            motors,
            irpc,
            servo_ports,
        };
        map.check_addresses()?;
        Ok(map)
    }

    fn motor_from(
        name: &str,
        m: RawMotor,
        ports: &mut Vec<crate::servo::ServoPort>,
    ) -> Result<MappedMotor, MapError> {
        let not_for = |field: &'static str, dialect: &'static str| MapError::NotForDialect {
            motor: name.to_owned(),
            dialect,
            field,
        };
        if !matches!(m.dialect.as_str(), "feetech" | "dynamixel") {
            for (field, present) in [
                ("port", m.port.is_some()),
                ("baud", m.baud.is_some()),
                ("model", m.model.is_some()),
                ("calibration", m.calibration.is_some()),
            ] {
                if present && matches!(m.dialect.as_str(), "irpc" | "compact" | "orion" | "moteus")
                {
                    return Err(not_for(field, static_dialect(&m.dialect)));
                }
            }
        }
        if !matches!(m.dialect.as_str(), "moteus" | "feetech" | "dynamixel") {
            let dialect = match m.dialect.as_str() {
                "irpc" => "irpc",
                "compact" => "compact",
                _ => "orion",
            };
            for (field, present) in [
                ("id", m.id.is_some()),
                ("bus", m.bus.is_some()),
                ("query_rate_hz", m.query_rate_hz.is_some()),
                ("stop", m.stop.is_some()),
            ] {
                if present && matches!(m.dialect.as_str(), "irpc" | "compact" | "orion") {
                    return Err(not_for(field, dialect));
                }
            }
        }
        let target = match m.dialect.as_str() {
            "moteus" => moteus_target(name, &m, not_for)?,
            "feetech" | "dynamixel" => servo_target(name, &m, not_for, ports)?,
            "irpc" => {
                let node = m.node.ok_or(MapError::Missing {
                    motor: name.to_owned(),
                    dialect: "irpc",
                    field: "node",
                })?;
                let node = u16::try_from(node)
                    .ok()
                    .filter(|n| *n != 0 && *n != 0xFFFF)
                    .ok_or_else(|| {
                        invalid(name, "node", format!("{node} is not a node id in 0x0001..=0xFFFE (0x0000 and 0xFFFF are broadcast)"))
                    })?;
                let wire = match &m.wire {
                    None => WireVersion::V2_0,
                    Some(w) => WireVersion::from_str(w).map_err(|e| invalid(name, "wire", e))?,
                };
                if m.key.is_some() {
                    return Err(not_for("key", "irpc"));
                }
                if m.feedback_node.is_some() {
                    return Err(not_for("feedback_node", "irpc"));
                }
                Target::Irpc { node, wire }
            }
            "compact" | "orion" => {
                let dialect = if m.dialect == "compact" {
                    "compact"
                } else {
                    "orion"
                };
                for (field, present) in [
                    ("node", dialect == "orion" && m.node.is_some()),
                    (
                        "feedback_node",
                        dialect == "orion" && m.feedback_node.is_some(),
                    ),
                    ("wire", m.wire.is_some()),
                    ("profile", m.profile.is_some()),
                ] {
                    if present {
                        return Err(not_for(field, dialect));
                    }
                }
                if dialect == "compact" {
                    if m.key.is_some() {
                        return Err(not_for("key", "compact"));
                    }
                    compact_target(name, m.node, m.feedback_node)?
                } else {
                    let key = m.key.as_deref().ok_or(MapError::Missing {
                        motor: name.to_owned(),
                        dialect: "orion",
                        field: "key",
                    })?;
                    let motor = motorwire_orion::Motor::from_key(key).ok_or_else(|| {
                        invalid(name, "key", format!("{key:?} is not an Orion motor key (TRM, LAA, UAA, AEM, GVM, GRM, GHS)"))
                    })?;
                    Target::Orion { motor }
                }
            }
            other => {
                return Err(invalid(
                    name,
                    "dialect",
                    format!("{other:?} is not irpc, compact, orion, moteus, feetech or dynamixel"),
                ));
            }
        };
        let unit = match m.unit.as_deref() {
            None | Some("deg") => AngleUnit::Degrees,
            Some("rad") => AngleUnit::Radians,
            Some(other) => {
                return Err(invalid(
                    name,
                    "unit",
                    format!("{other:?} is not deg or rad"),
                ));
            }
        };
        let profile = match m.profile.as_deref() {
            None | Some("scurve") => MotionProfile::SCurve,
            Some("trapezoidal") => MotionProfile::Trapezoidal,
            Some("adaptive") => MotionProfile::Adaptive,
            Some(other) => {
                return Err(invalid(
                    name,
                    "profile",
                    format!("{other:?} is not trapezoidal, scurve or adaptive"),
                ));
            }
        };
        let mut l = m.limits;
        if let Target::Servo(t) = &target {
            servo_limits(name, t, unit, &mut l)?;
        }
        for (field, value, positive) in [
            ("limits.min_position", l.min_position, false),
            ("limits.max_position", l.max_position, false),
            ("limits.max_velocity", l.max_velocity, true),
            ("limits.max_acceleration", l.max_acceleration, true),
            ("limits.max_deceleration", l.max_deceleration, true),
            ("limits.max_jerk", l.max_jerk, true),
            ("limits.max_torque", l.max_torque, true),
            (
                "limits.emergency_deceleration",
                l.emergency_deceleration,
                true,
            ),
        ] {
            if let Some(v) = value {
                if !v.is_finite() {
                    return Err(invalid(name, field, format!("{v} is not a finite number")));
                }
                if positive && v <= 0.0 {
                    return Err(invalid(name, field, format!("{v} is not > 0")));
                }
            }
        }
        if let (Some(lo), Some(hi)) = (l.min_position, l.max_position)
            && lo > hi
        {
            return Err(invalid(
                name,
                "limits",
                format!("min_position {lo} is above max_position {hi}"),
            ));
        }
        let arrival_tolerance = match m.arrival_tolerance {
            None => unit.from_degrees(0.1),
            Some(t) if t.is_finite() && t > 0.0 => t,
            Some(t) => {
                return Err(invalid(
                    name,
                    "arrival_tolerance",
                    format!("{t} is not a finite number > 0"),
                ));
            }
        };
        let command_timeout = match (m.command_timeout_ms, &target) {
            (Some(0), _) | (None, Target::Irpc { .. } | Target::Servo(_)) => None,
            (Some(ms), _) => Some(std::time::Duration::from_millis(ms)),
            (None, _) => Some(std::time::Duration::from_millis(200)),
        };
        Ok(MappedMotor {
            name: name.to_owned(),
            arrival_tolerance,
            command_timeout,
            limits_source: "bus map",
            target,
            unit,
            limits: Limits {
                min_position: l.min_position,
                max_position: l.max_position,
                max_velocity: l.max_velocity,
                max_acceleration: l.max_acceleration,
                max_deceleration: l.max_deceleration,
                max_jerk: l.max_jerk,
                max_torque: l.max_torque,
                emergency_deceleration: l.emergency_deceleration,
            },
            profile,
        })
    }

    /// Every motor at an address of its own: no two iRPC joints, compact
    /// devices or Orion motors at one node, key or CAN id (a compact
    /// device takes two CAN ids: its commands' and its feedback's).
    fn check_addresses(&self) -> Result<(), MapError> {
        #[derive(PartialEq, Eq, PartialOrd, Ord)]
        enum Address {
            Can(u16),
            Orion(&'static str),
            Moteus(u16, u8),
            Servo(u8, u8),
        }
        // Each address with the first motor there and whether it is an iRPC joint.
        let mut seen: BTreeMap<Address, (&str, bool)> = BTreeMap::new();
        for m in self.motors.values() {
            let (ids, irpc) = match m.target {
                Target::Irpc { node, .. } => ([Some(node), None], true),
                Target::Compact {
                    node,
                    feedback_node,
                } => ([Some(node), Some(feedback_node)], false),
                Target::Moteus { id, bus, .. } => {
                    if let Some((first, _)) = seen.get(&Address::Moteus(bus, id)) {
                        return Err(MapError::SharedAddress {
                            first: (*first).to_owned(),
                            second: m.name.clone(),
                            address: format!("moteus id {id} on bus {bus}"),
                        });
                    }
                    seen.insert(Address::Moteus(bus, id), (&m.name, false));
                    continue;
                }
                Target::Servo(t) => {
                    if let Some((first, _)) = seen.get(&Address::Servo(t.port, t.id)) {
                        return Err(MapError::SharedAddress {
                            first: (*first).to_owned(),
                            second: m.name.clone(),
                            address: format!(
                                "servo id {} on {}",
                                t.id,
                                self.servo_ports
                                    .get(usize::from(t.port))
                                    .map_or("its port", |p| p.path.as_str())
                            ),
                        });
                    }
                    seen.insert(Address::Servo(t.port, t.id), (&m.name, false));
                    continue;
                }
                Target::Orion { motor } => {
                    if let Some((first, _)) = seen.get(&Address::Orion(motor.key())) {
                        return Err(MapError::SharedAddress {
                            first: (*first).to_owned(),
                            second: m.name.clone(),
                            address: format!("Orion {}", motor.key()),
                        });
                    }
                    seen.insert(Address::Orion(motor.key()), (&m.name, false));
                    continue;
                }
            };
            for id in ids.into_iter().flatten() {
                if let Some((first, first_irpc)) = seen.get(&Address::Can(id)) {
                    return Err(MapError::SharedAddress {
                        first: (*first).to_owned(),
                        second: m.name.clone(),
                        address: if irpc && *first_irpc {
                            format!("iRPC node 0x{id:02X}")
                        } else {
                            format!("CAN id 0x{id:03X}")
                        },
                    });
                }
                seen.insert(Address::Can(id), (&m.name, irpc));
            }
        }
        Ok(())
    }

    /// The serial ports of the map's servos, each once: a servo's
    /// [`crate::ServoTarget::port`] is its index here.
    #[must_use]
    pub fn servo_ports(&self) -> &[crate::servo::ServoPort] {
        &self.servo_ports
    }

    /// The motor named `name`.
    pub fn motor(&self, name: &str) -> Option<&MappedMotor> {
        self.motors.get(name)
    }

    /// Replaces the limits of motor `name` (a runtime tightening, such as
    /// the bridge applies from a WIA SafetyLimits line), saying where they
    /// come from (`source`, named by refusals); `false` when there is no
    /// such motor. The caller checks the new limits against the old.
    ///
    /// ```
    /// use motorwire_translate::{BusMap, gate};
    /// let mut map = BusMap::from_toml(r#"
    ///     [motors.elbow]
    ///     dialect = "irpc"
    ///     node = 0x12
    ///     limits = { min_position = 0, max_position = 150 }
    /// "#)?;
    /// let limits = motorwire_translate::Limits { max_position: Some(100.0), ..map.motor("elbow").unwrap().limits };
    /// assert!(map.set_limits("elbow", limits, "safety limits"));
    /// let cmd: motorwire_wia::MotorCommand = serde_json::from_str(
    ///     r#"{"motor_id":"elbow","timestamp":0,"control_mode":"position","setpoint":120}"#)?;
    /// assert_eq!(gate(&map, &cmd).unwrap_err().to_string(),
    ///     "elbow: setpoint 120 is outside max_position (safety limits) 100");
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn set_limits(&mut self, name: &str, limits: Limits, source: &'static str) -> bool {
        match self.motors.get_mut(name) {
            Some(m) => {
                m.limits = limits;
                m.limits_source = source;
                true
            }
            None => false,
        }
    }

    /// Every motor, in name order.
    pub fn motors(&self) -> impl Iterator<Item = &MappedMotor> {
        self.motors.values()
    }

    /// The iRPC motor at `node`.
    pub fn irpc_node(&self, node: u16) -> Option<&MappedMotor> {
        self.irpc.get(&node).and_then(|name| self.motors.get(name))
    }

    /// This map with every iRPC joint speaking `wire`, whatever its own
    /// `wire` says: for translating a command into the bytes a joint of
    /// another wire version would get (`motorwire translate --to
    /// irpc-v1`). Nodes, units, limits and profiles are unchanged.
    ///
    /// ```
    /// use motorwire_irpc::WireVersion;
    /// use motorwire_translate::{BusMap, Target};
    /// let map = BusMap::from_toml("[motors.elbow]\ndialect = \"irpc\"\nnode = 0x12\nwire = \"v2.0\"")?;
    /// let v1 = map.with_wire(WireVersion::V1);
    /// assert_eq!(v1.motor("elbow").unwrap().target, Target::Irpc { node: 0x12, wire: WireVersion::V1 });
    /// # Ok::<(), motorwire_translate::MapError>(())
    /// ```
    #[must_use]
    pub fn with_wire(&self, wire: WireVersion) -> BusMap {
        let mut map = self.clone();
        for m in map.motors.values_mut() {
            if let Target::Irpc { node, .. } = m.target {
                m.target = Target::Irpc { node, wire };
            }
        }
        map
    }

    /// The motor mapped to Orion `motor`.
    pub fn orion_motor(&self, motor: motorwire_orion::Motor) -> Option<&MappedMotor> {
        self.motors
            .values()
            .find(|m| m.target == Target::Orion { motor })
    }
}
