//! WIA motor commands for serial bus servos: Feetech STS (the SO-100 and
//! SO-101 arms' STS3215) and Dynamixel X (XL330-M288, XL430-W250,
//! XM430-W350: the Koch arm's), through each servo's calibration.
//!
//! A servo's WIA position is its present position register read through
//! its calibration as LeRobot reads it in degrees: `(raw - mid) * 360 /
//! (resolution - 1)`, `mid` the middle of the calibrated range
//! (`range_min`, `range_max`, raw steps). The drive mode and the homing
//! offset are the servo's own registers, which it applies itself (the
//! calibration writes them); the bridge reads and writes positions as the
//! servo reports them.

use motorwire_core::ControlMode;
use motorwire_servo::Protocol;
use motorwire_servo::table::{self, Model};
use motorwire_wia::{MotorCommand, MultiAxisCommand};

use crate::command::{each_axis, emergency, gate_unless_emergency, own_or_default, report_unused};
use crate::gate::Refusal;
use crate::map::{AngleUnit, BusMap, MappedMotor, Target};
use crate::report::{LossKind, Report, Translated};

/// Who made a serial bus servo: which protocol family it speaks.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ServoVendor {
    /// Feetech STS/SMS (and SCS) servos.
    Feetech,
    /// Dynamixel X series servos (Protocol 2.0).
    Dynamixel,
}

impl ServoVendor {
    /// Its name as the bus map spells the dialect (`feetech`,
    /// `dynamixel`).
    #[must_use]
    pub const fn name(self) -> &'static str {
        match self {
            Self::Feetech => "feetech",
            Self::Dynamixel => "dynamixel",
        }
    }
}

/// A servo's calibration, as LeRobot keeps it: its homing offset (the
/// servo's own register), the range of motion it was swept through (raw
/// steps of its present position), and its drive mode (the servo's own
/// direction register).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Calibration {
    /// The servo's Homing_Offset register (raw steps).
    pub homing_offset: i32,
    /// The lowest present position of its range (raw steps).
    pub range_min: u32,
    /// The highest present position of its range (raw steps).
    pub range_max: u32,
    /// The servo's drive mode (0: as built; 1: reversed, applied by the
    /// servo itself).
    pub drive_mode: u8,
}

impl Calibration {
    /// The whole turn of a servo of `resolution` steps, no offset: what a
    /// servo without a calibration in the map is read with.
    #[must_use]
    pub const fn whole_turn(resolution: u32) -> Self {
        Self {
            homing_offset: 0,
            range_min: 0,
            range_max: resolution.saturating_sub(1),
            drive_mode: 0,
        }
    }

    /// The middle of the range (raw steps).
    #[must_use]
    pub fn middle(&self) -> f64 {
        (f64::from(self.range_min) + f64::from(self.range_max)) / 2.0
    }

    /// `raw` steps of present position in degrees (LeRobot's `DEGREES`
    /// normalisation: `(raw - mid) * 360 / (resolution - 1)`).
    ///
    /// ```
    /// use motorwire_translate::Calibration;
    /// let c = Calibration { homing_offset: 0, range_min: 1000, range_max: 3000, drive_mode: 0 };
    /// assert_eq!(c.degrees(2000, 4096), 0.0);
    /// assert!((c.degrees(3000, 4096) - 87.9120879).abs() < 1e-6);
    /// assert_eq!(c.raw(c.degrees(2731, 4096), 4096), 2731);
    /// ```
    #[must_use]
    pub fn degrees(&self, raw: i64, resolution: u32) -> f64 {
        #[allow(clippy::cast_precision_loss)]
        let raw = raw as f64;
        (raw - self.middle()) * 360.0 / f64::from(resolution.saturating_sub(1).max(1))
    }

    /// The raw steps nearest `degrees` (the inverse of
    /// [`Calibration::degrees`]).
    #[must_use]
    pub fn raw(&self, degrees: f64, resolution: u32) -> i64 {
        let steps =
            degrees * f64::from(resolution.saturating_sub(1).max(1)) / 360.0 + self.middle();
        #[allow(clippy::cast_possible_truncation)]
        let r = steps.round().clamp(-2e9, 2e9) as i64;
        r
    }
}

/// A serial bus servo: its vendor, the bus (serial port) it is on, its
/// id, model and calibration, and what its stop does.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ServoTarget {
    /// Its vendor (and so its protocol family).
    pub vendor: ServoVendor,
    /// Its bus: an index into [`BusMap::servo_ports`].
    pub port: u8,
    /// Its id on the bus (0..=252).
    pub id: u8,
    /// Its model's name (`sts3215`, `xl330-m288`, ...), in
    /// [`motorwire_servo::table::MODELS`].
    pub model: &'static str,
    /// Its calibration.
    pub calibration: Calibration,
    /// Whether its stop (the emergency stop, the deadman, a motor line's
    /// stop) holds its position with torque on (the map's `stop = "hold"`)
    /// rather than turning its torque off (`stop = "torque_off"`, the
    /// default).
    pub stop_holds: bool,
}

impl ServoTarget {
    /// Its model's control table.
    #[must_use]
    pub fn table(&self) -> Option<&'static Model> {
        table::model(self.model)
    }

    /// Its position steps a turn.
    #[must_use]
    pub fn resolution(&self) -> u32 {
        self.table().map_or(4096, |m| m.resolution)
    }

    /// `raw` present position in degrees, through its calibration.
    #[must_use]
    pub fn degrees(&self, raw: i64) -> f64 {
        self.calibration.degrees(raw, self.resolution())
    }
}

/// A serial port the map's servos share: one bus, one transaction at a
/// time.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ServoPort {
    /// The serial port (`/dev/ttyACM0`, `COM3`; any name on the simulated
    /// bus).
    pub path: String,
    /// Its baud rate (the map's `baud`, 1,000,000 by default).
    pub baud: u32,
    /// The protocol its servos speak (one per bus).
    pub protocol: Protocol,
}

/// What a serial bus servo is sent for one WIA command.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ServoCommand {
    /// Torque on and a move to `position` (degrees, through the
    /// calibration), at most `velocity` (degrees a second) and
    /// `acceleration` (degrees a second squared) where given, the
    /// servo's own maximum otherwise.
    Goal {
        /// The goal (degrees).
        position: f64,
        /// The speed limit (degrees a second).
        velocity: Option<f64>,
        /// The acceleration limit (degrees a second squared).
        acceleration: Option<f64>,
    },
    /// Torque on, holding where it stands (its goal set to its present
    /// position).
    Hold,
    /// Torque off: it turns freely.
    TorqueOff,
}

/// A servo's goal registers, laid out for one write from `address`:
/// Feetech STS `Torque_Enable`, `Acceleration`, `Goal_Position`,
/// `Goal_Time` (0) and `Goal_Velocity` (40..=47, one block: the torque
/// comes on with the goal); Dynamixel `Profile_Acceleration`,
/// `Profile_Velocity` and `Goal_Position` (108..=119), its
/// `Torque_Enable` (64) written after them.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct GoalBlock {
    /// The first register's address.
    pub address: u16,
    /// The bytes from it, as the servo's protocol writes them.
    pub data: Vec<u8>,
    /// Whether the torque is turned on by this block itself (Feetech) or
    /// needs [`TORQUE_ON`] written after it (Dynamixel).
    pub torque_included: bool,
    /// The goal step it writes (what the servo reads back once it took it).
    pub position: u32,
}

/// The goal position raw steps of `degrees` for `target`, refused when
/// outside its calibrated range.
///
/// # Errors
/// [`Refusal::NotRepresentable`]: outside the servo's calibrated range.
pub fn goal_steps(motor: &str, target: &ServoTarget, degrees: f64) -> Result<i64, Refusal> {
    let raw = target.calibration.raw(degrees, target.resolution());
    let c = target.calibration;
    if !degrees.is_finite() || raw < i64::from(c.range_min) || raw > i64::from(c.range_max) {
        return Err(Refusal::NotRepresentable {
            motor: motor.to_owned(),
            field: "setpoint",
            problem: format!(
                "{degrees}° is step {raw}, outside the servo's calibrated range {}..={}",
                c.range_min, c.range_max
            ),
        });
    }
    Ok(raw)
}

/// A speed or acceleration limit in the servo's steps of it, rounded
/// down (never faster than asked); refused where a limit is given and
/// rounds to 0, which the servo reads as no limit at all.
fn limit_steps(
    motor: &str,
    field: &'static str,
    v: Option<f64>,
    per_step: f64,
) -> Result<u32, Refusal> {
    let Some(v) = v else { return Ok(0) };
    let steps = (v.abs() / per_step).floor();
    if steps < 1.0 {
        return Err(Refusal::NotRepresentable {
            motor: motor.to_owned(),
            field,
            problem: format!(
                "{v} is below the servo's smallest step of it ({per_step} a step), and 0 is no limit to the servo"
            ),
        });
    }
    #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
    Ok(steps.min(f64::from(u32::MAX)) as u32)
}

/// What one step of a servo's speed and acceleration registers is, in
/// degrees a second and degrees a second squared, and their largest
/// values.
fn motion_units(target: &ServoTarget) -> (f64, f64, u32, u32) {
    let per_step = 360.0 / f64::from(target.resolution());
    match target.vendor {
        // Goal_Velocity in steps a second (15 bits of magnitude);
        // Acceleration in 100 steps a second squared (one byte).
        ServoVendor::Feetech => (per_step, 100.0 * per_step, 0x7FFF, 254),
        // Profile_Velocity 0.229 rpm; Profile_Acceleration 214.577 rev/min².
        ServoVendor::Dynamixel => (0.229 * 6.0, 214.577 * 360.0 / 3600.0, 32767, 32767),
    }
}

/// The goal registers that move `target` to `degrees` within `velocity`
/// and `acceleration` (degrees a second and a second squared; `None`: the
/// servo's own maximum).
///
/// ```
/// use motorwire_translate::{Calibration, ServoTarget, ServoVendor, goal_block};
/// let t = ServoTarget {
///     vendor: ServoVendor::Feetech, port: 0, id: 1, model: "sts3215",
///     calibration: Calibration { homing_offset: 0, range_min: 1047, range_max: 3047, drive_mode: 0 },
///     stop_holds: false,
/// };
/// // 0° is the middle of the range (step 2047), at 90°/s (1024 steps/s)
/// // and 900°/s² (102 of 100 steps/s², rounded down), the torque on in
/// // the same write.
/// let b = goal_block("wrist", &t, 0.0, Some(90.0), Some(900.0))?;
/// assert_eq!((b.address, b.data), (40, vec![1, 102, 0xFF, 0x07, 0, 0, 0x00, 0x04]));
/// # Ok::<(), motorwire_translate::Refusal>(())
/// ```
///
/// # Errors
/// [`Refusal::NotRepresentable`]: a goal outside the calibrated range, a
/// limit the servo's registers cannot hold.
pub fn goal_block(
    motor: &str,
    target: &ServoTarget,
    degrees: f64,
    velocity: Option<f64>,
    acceleration: Option<f64>,
) -> Result<GoalBlock, Refusal> {
    let raw = goal_steps(motor, target, degrees)?;
    let (v_unit, a_unit, v_max, a_max) = motion_units(target);
    let v = limit_steps(motor, "velocity_limit", velocity, v_unit)?.min(v_max);
    let a = limit_steps(motor, "acceleration_limit", acceleration, a_unit)?.min(a_max);
    let position = u32::try_from(raw).map_err(|_| Refusal::NotRepresentable {
        motor: motor.to_owned(),
        field: "setpoint",
        problem: format!("step {raw} is below 0"),
    })?;
    layout(target, position, v, a).map_err(|e| Refusal::NotRepresentable {
        motor: motor.to_owned(),
        field: "setpoint",
        problem: e.to_string(),
    })
}

/// The goal registers that hold `target`'s servo at step `position` (where
/// it stands, read from it), torque on, at its own speed and acceleration
/// (it does not move): a hold. Not gated: a servo pushed past its
/// calibrated range is held where it is.
///
/// # Errors
/// A step the goal register cannot hold.
pub fn hold_block(
    target: &ServoTarget,
    position: u32,
) -> Result<GoalBlock, motorwire_servo::EncodeError> {
    layout(target, position, 0, 0)
}

/// The goal block of `target`'s vendor: goal step `position`, speed `v`
/// and acceleration `a` in the servo's own steps (0: its maximum).
fn layout(
    target: &ServoTarget,
    position: u32,
    v: u32,
    a: u32,
) -> Result<GoalBlock, motorwire_servo::EncodeError> {
    let protocol = target.table().map_or(Protocol::Scs0, |m| m.protocol);
    let bytes = |value: u32, length: u8| protocol.value_bytes(value, length);
    Ok(match target.vendor {
        ServoVendor::Feetech => {
            let mut data = vec![1, u8::try_from(a).unwrap_or(u8::MAX)];
            data.extend(bytes(position, 2)?);
            data.extend(bytes(0, 2)?);
            data.extend(bytes(v, 2)?);
            GoalBlock {
                address: 40,
                data,
                torque_included: true,
                position,
            }
        }
        ServoVendor::Dynamixel => {
            let mut data = bytes(a, 4)?;
            data.extend(bytes(v, 4)?);
            data.extend(bytes(position, 4)?);
            GoalBlock {
                address: 108,
                data,
                torque_included: false,
                position,
            }
        }
    })
}

/// The torque register of a servo of `vendor`: its address (Feetech 40,
/// Dynamixel 64; one byte).
#[must_use]
pub const fn torque_address(vendor: ServoVendor) -> u16 {
    match vendor {
        ServoVendor::Feetech => 40,
        ServoVendor::Dynamixel => 64,
    }
}

/// The torque register's value for "on".
pub const TORQUE_ON: u8 = 1;

/// `cmd` for a serial bus servo of the bus map, behind the safety gate
/// (the limits in force, in the motor's unit, within its calibrated
/// range):
/// - position: torque on and a move to the setpoint (degrees through the
///   calibration), within the command's velocity and acceleration limits,
///   else the limits in force (said so), else the servo's own maximum
///   (said so);
/// - disabled: torque off;
/// - an emergency stop: torque off, or a hold where the map says `stop =
///   "hold"`.
///
/// Velocity and torque commands are refused: a servo's wheel mode turns
/// past its calibrated range with nothing to stop it there.
///
/// ```
/// use motorwire_translate::{BusMap, ServoCommand, to_servo};
/// let map = BusMap::from_toml(r#"
///     [motors.wrist]
///     dialect = "feetech"
///     port = "/dev/ttyACM0"
///     id = 5
///     model = "sts3215"
///     calibration = { homing_offset = 0, range_min = 1047, range_max = 3047, drive_mode = 0 }
///     limits = { max_velocity = 90 }
/// "#)?;
/// let cmd = serde_json::from_str(r#"{"motor_id":"wrist","timestamp":0,"control_mode":"position","setpoint":30}"#)?;
/// let t = to_servo(&map, &cmd)?;
/// assert_eq!(t.value, ServoCommand::Goal { position: 30.0, velocity: Some(90.0), acceleration: None });
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
/// The gate's refusals, a motor of another dialect, a mode a servo is not
/// driven in, a goal or limit its registers cannot hold.
pub fn to_servo(map: &BusMap, cmd: &MotorCommand) -> Result<Translated<ServoCommand>, Refusal> {
    let (motor, effective) = gate_unless_emergency(map, cmd)?;
    let Target::Servo(target) = motor.target else {
        return Err(Refusal::ModeNotExpressible {
            motor: motor.name.clone(),
            mode: cmd.control_mode.name(),
            dialect: "a serial bus servo (the bus map says this motor is not one)",
        });
    };
    let mut report = Report::default();
    if emergency(cmd) {
        return Ok(Translated {
            value: if target.stop_holds {
                ServoCommand::Hold
            } else {
                ServoCommand::TorqueOff
            },
            report,
        });
    }
    match cmd.control_mode {
        ControlMode::Disabled => {
            report_unused(cmd, &[], "a servo's torque off", &mut report);
            Ok(Translated {
                value: ServoCommand::TorqueOff,
                report,
            })
        }
        ControlMode::Position => {
            report_unused(
                cmd,
                &["velocity_limit", "acceleration_limit"],
                "a servo's goal position",
                &mut report,
            );
            if cmd.safety_limits.is_some() {
                report.push(
                    "safety_limits",
                    LossKind::Dropped,
                    "only emergency_stop has a place (the servo's stop)",
                );
            }
            let deg = |v: f64| motor.unit.to_degrees(v);
            let position = deg(cmd.setpoint);
            let velocity = own_or_default(
                "velocity_limit",
                cmd.velocity_limit,
                effective.max_velocity,
                &mut report,
            )
            .map(deg);
            let acceleration = own_or_default(
                "acceleration_limit",
                cmd.acceleration_limit,
                effective.max_acceleration,
                &mut report,
            )
            .map(deg);
            for (field, v) in [
                ("velocity_limit", velocity),
                ("acceleration_limit", acceleration),
            ] {
                if v.is_none() {
                    report.push(
                        field,
                        LossKind::Defaulted,
                        "none given or in force: the servo's own maximum",
                    );
                }
            }
            // Refused here, not at send time, when the registers cannot
            // hold it.
            goal_block(&motor.name, &target, position, velocity, acceleration)?;
            Ok(Translated {
                value: ServoCommand::Goal {
                    position,
                    velocity,
                    acceleration,
                },
                report,
            })
        }
        mode => Err(Refusal::ModeNotExpressible {
            motor: motor.name.clone(),
            mode: mode.name(),
            dialect: "a serial bus servo (position and disabled only: its wheel mode turns past its calibrated range unwatched)",
        }),
    }
}

/// A WIA multi-axis command for serial bus servos: each axis as
/// [`to_servo`] translates it (behind the gate), in the command's order,
/// each axis's losses named `motor_id.field`. Each servo moves to its own
/// goal: `sync_mode`, `coordination` and `metadata` are reported dropped.
///
/// # Errors
/// The first axis's refusal, naming it.
pub fn multi_axis_to_servo(
    map: &BusMap,
    cmd: &MultiAxisCommand,
) -> Result<Translated<Vec<ServoCommand>>, Refusal> {
    each_axis(map, cmd, to_servo, "a servo's goal position")
}

/// The instruction packets the bridge writes a servo of `target` (its
/// torque off) for `cmd`, in order: a goal's sync write (Feetech: the
/// torque in the same write; Dynamixel: the goal, the torque on, and the
/// goal again, which a servo may have taken its present position for as
/// its torque came on), or the torque off. A hold has none here: its goal
/// is the servo's present position, which the bridge reads first.
///
/// # Errors
/// [`Refusal::NotRepresentable`]: a goal or limit the registers cannot
/// hold, or a packet the protocol cannot carry.
pub fn servo_packets(
    motor: &str,
    target: &ServoTarget,
    cmd: &ServoCommand,
) -> Result<Vec<Vec<u8>>, Refusal> {
    use motorwire_servo::{Instruction, encode};
    let protocol = target.table().map_or(Protocol::Scs0, |m| m.protocol);
    let packet = |address: u16, data: Vec<u8>| {
        let length = u16::try_from(data.len()).unwrap_or(u16::MAX);
        encode(
            protocol,
            &Instruction::SyncWrite {
                address,
                length,
                entries: vec![(target.id, data)],
            },
        )
        .map_err(|e| Refusal::NotRepresentable {
            motor: motor.to_owned(),
            field: "packet",
            problem: e.to_string(),
        })
    };
    match *cmd {
        ServoCommand::Goal {
            position,
            velocity,
            acceleration,
        } => {
            let b = goal_block(motor, target, position, velocity, acceleration)?;
            if b.torque_included {
                Ok(vec![packet(b.address, b.data)?])
            } else {
                Ok(vec![
                    packet(b.address, b.data.clone())?,
                    packet(torque_address(target.vendor), vec![TORQUE_ON])?,
                    packet(b.address, b.data)?,
                ])
            }
        }
        ServoCommand::TorqueOff => Ok(vec![packet(torque_address(target.vendor), vec![0])?]),
        ServoCommand::Hold => Ok(Vec::new()),
    }
}

/// The calibrated range of `target` in `unit` (lowest, highest).
#[must_use]
pub fn calibrated_range(target: &ServoTarget, unit: AngleUnit) -> (f64, f64) {
    let c = target.calibration;
    (
        unit.from_degrees(target.degrees(i64::from(c.range_min))),
        unit.from_degrees(target.degrees(i64::from(c.range_max))),
    )
}

/// Whether `motor` is a serial bus servo.
#[must_use]
pub fn is_servo(motor: &MappedMotor) -> bool {
    matches!(motor.target, Target::Servo(_))
}
