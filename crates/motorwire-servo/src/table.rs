//! The control tables of the servos people own, as data: each register's
//! address, size, access, how its sign is written and its unit.
//!
//! The addresses and sizes are the vendors' e-manuals' (and LeRobot's
//! `tables.py`, which agrees with them for these models); the Feetech
//! sign-magnitude bits are the ones LeRobot's `STS_SMS_SERIES_ENCODINGS_TABLE`
//! lists; a Dynamixel X register that can be negative is two's complement
//! over its size. Where the e-manual gives a unit, [`Unit`] says it; the
//! others are [`Unit::Raw`].
//!
//! ```
//! use motorwire_servo::table::{self, Sign};
//! let sts = table::model("sts3215").unwrap();
//! let goal = sts.register("Goal_Velocity").unwrap();
//! assert_eq!((goal.address, goal.size, goal.sign), (46, 2, Sign::SignMagnitude { bit: 15 }));
//! // -100 steps a second: the sign bit and 100.
//! assert_eq!(goal.to_raw(-100), Ok(0x8064));
//! assert_eq!(goal.from_raw(0x8064), -100);
//! let xm = table::model("xm430-w350").unwrap();
//! assert_eq!(xm.register("Present_Position").map(|r| r.from_raw(0xFFFF_FFFF)), Some(-1));
//! ```

use crate::Protocol;

/// Whether a register can be written.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Access {
    /// Read only.
    Read,
    /// Read and written.
    ReadWrite,
}

/// How a register's value is signed on the wire.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Sign {
    /// Never negative.
    Unsigned,
    /// Two's complement over the register's size (Dynamixel).
    TwosComplement,
    /// Feetech's sign-magnitude: bit `bit` set for a negative value, the
    /// magnitude in the bits below it.
    SignMagnitude {
        /// The sign bit.
        bit: u8,
    },
}

/// What one step of a register's value is.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Unit {
    /// No unit the table states (a mode, a flag, a gain, an id).
    Raw,
    /// A position: `per_turn` steps a full turn.
    Steps {
        /// Steps a turn.
        per_turn: u32,
    },
    /// A velocity: steps a second, `per_turn` steps a turn.
    StepsPerSecond {
        /// Steps a turn.
        per_turn: u32,
    },
    /// An acceleration: this many steps a second squared a step.
    StepsPerSecondSquared(f64),
    /// A velocity: this many revolutions a minute a step.
    Rpm(f64),
    /// An acceleration: this many revolutions a minute squared a step.
    RpmPerMinute(f64),
    /// This many volts a step.
    Volts(f64),
    /// This many degrees Celsius a step.
    Celsius(f64),
    /// This many milliamperes a step.
    Milliamps(f64),
    /// This many percent (of the maximum) a step.
    Percent(f64),
}

/// One register of a control table.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Register {
    /// Its name, as LeRobot and the e-manual name it (`Goal_Position`).
    pub name: &'static str,
    /// Its address.
    pub address: u16,
    /// Its size (bytes: 1, 2 or 4).
    pub size: u8,
    /// Whether it is written.
    pub access: Access,
    /// How its sign is written.
    pub sign: Sign,
    /// Its unit.
    pub unit: Unit,
}

/// Why a value is not written to a register.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("{value} does not fit {register} ({size} bytes, {sign:?})")]
pub struct OutOfRange {
    /// The register.
    pub register: &'static str,
    /// Its size.
    pub size: u8,
    /// Its sign.
    pub sign: Sign,
    /// The value.
    pub value: i64,
}

impl Register {
    const fn rw(name: &'static str, address: u16, size: u8) -> Self {
        Self {
            name,
            address,
            size,
            access: Access::ReadWrite,
            sign: Sign::Unsigned,
            unit: Unit::Raw,
        }
    }

    const fn ro(self) -> Self {
        Self {
            access: Access::Read,
            ..self
        }
    }

    const fn signed(self, sign: Sign) -> Self {
        Self { sign, ..self }
    }

    const fn unit(self, unit: Unit) -> Self {
        Self { unit, ..self }
    }

    /// The largest raw value its size holds.
    const fn mask(&self) -> u32 {
        match self.size {
            1 => 0xFF,
            2 => 0xFFFF,
            _ => 0xFFFF_FFFF,
        }
    }

    /// The signed value a raw reading of it means.
    #[must_use]
    pub fn from_raw(&self, raw: u32) -> i64 {
        let raw = raw & self.mask();
        match self.sign {
            Sign::Unsigned => i64::from(raw),
            Sign::TwosComplement => {
                let bits = u32::from(self.size) * 8;
                let v = i64::from(raw);
                if bits < 64 && v >= 1 << (bits - 1) {
                    v - (1 << bits)
                } else {
                    v
                }
            }
            Sign::SignMagnitude { bit } => {
                let sign = 1u32 << bit;
                let magnitude = i64::from(raw & (sign - 1));
                if raw & sign == 0 {
                    magnitude
                } else {
                    -magnitude
                }
            }
        }
    }

    /// `value` as it is written to it.
    ///
    /// # Errors
    /// [`OutOfRange`]: a value its size and sign cannot hold.
    pub fn to_raw(&self, value: i64) -> Result<u32, OutOfRange> {
        let bad = OutOfRange {
            register: self.name,
            size: self.size,
            sign: self.sign,
            value,
        };
        let mask = i64::from(self.mask());
        match self.sign {
            Sign::Unsigned if (0..=mask).contains(&value) => u32::try_from(value).map_err(|_| bad),
            Sign::TwosComplement => {
                let half = (mask + 1) / 2;
                if (-half..half).contains(&value) {
                    u32::try_from(value & mask).map_err(|_| bad)
                } else {
                    Err(bad)
                }
            }
            Sign::SignMagnitude { bit } => {
                let limit = (1i64 << bit) - 1;
                if value.abs() > limit {
                    return Err(bad);
                }
                let m = u32::try_from(value.abs()).map_err(|_| bad)?;
                Ok(if value < 0 { m | (1 << bit) } else { m })
            }
            Sign::Unsigned => Err(bad),
        }
    }
}

/// A servo model: its name, model number, protocol, resolution and
/// control table.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Model {
    /// Its name, lower case as LeRobot writes it (`sts3215`).
    pub name: &'static str,
    /// The model number it answers a ping (Dynamixel) or a read of
    /// `Model_Number` (Feetech) with.
    pub number: u16,
    /// Its protocol.
    pub protocol: Protocol,
    /// Position steps a turn.
    pub resolution: u32,
    /// The first address of its RAM (below: EEPROM, written only with
    /// torque off, and on Feetech with the lock open).
    pub ram_start: u16,
    /// Its registers, by address.
    pub registers: &'static [Register],
}

impl Model {
    /// Its register named `name`.
    #[must_use]
    pub fn register(&self, name: &str) -> Option<&'static Register> {
        self.registers.iter().find(|r| r.name == name)
    }
}

const SM15: Sign = Sign::SignMagnitude { bit: 15 };
const STS_STEPS: Unit = Unit::Steps { per_turn: 4096 };
const STS_SPEED: Unit = Unit::StepsPerSecond { per_turn: 4096 };

/// A Feetech table: the EEPROM registers both series have at the same
/// addresses (`$steps`: the unit of their position limits), then `$rest`.
macro_rules! feetech {
    ($steps:expr; $($rest:expr),* $(,)?) => {
        &[
            Register::rw("Firmware_Major_Version", 0, 1).ro(),
            Register::rw("Firmware_Minor_Version", 1, 1).ro(),
            Register::rw("Model_Number", 3, 2).ro(),
            Register::rw("ID", 5, 1),
            Register::rw("Baud_Rate", 6, 1),
            Register::rw("Return_Delay_Time", 7, 1),
            Register::rw("Response_Status_Level", 8, 1),
            Register::rw("Min_Position_Limit", 9, 2).unit($steps),
            Register::rw("Max_Position_Limit", 11, 2).unit($steps),
            Register::rw("Max_Temperature_Limit", 13, 1).unit(Unit::Celsius(1.0)),
            Register::rw("Max_Voltage_Limit", 14, 1).unit(Unit::Volts(0.1)),
            Register::rw("Min_Voltage_Limit", 15, 1).unit(Unit::Volts(0.1)),
            Register::rw("Max_Torque_Limit", 16, 2).unit(Unit::Percent(0.1)),
            Register::rw("Phase", 18, 1),
            Register::rw("Unloading_Condition", 19, 1),
            Register::rw("LED_Alarm_Condition", 20, 1),
            Register::rw("P_Coefficient", 21, 1),
            Register::rw("D_Coefficient", 22, 1),
            Register::rw("I_Coefficient", 23, 1),
            Register::rw("Minimum_Startup_Force", 24, 2),
            Register::rw("CW_Dead_Zone", 26, 1),
            Register::rw("CCW_Dead_Zone", 27, 1),
            $($rest),*
        ]
    };
}

/// The STS/SMS series table (the STS3215 of the SO-100 and SO-101 arms).
const STS: &[Register] = feetech!(STS_STEPS;
    Register::rw("Protection_Current", 28, 2),
    Register::rw("Angular_Resolution", 30, 1),
    Register::rw("Homing_Offset", 31, 2)
        .signed(Sign::SignMagnitude { bit: 11 })
        .unit(STS_STEPS),
    Register::rw("Operating_Mode", 33, 1),
    Register::rw("Protective_Torque", 34, 1),
    Register::rw("Protection_Time", 35, 1),
    Register::rw("Overload_Torque", 36, 1),
    Register::rw("Velocity_closed_loop_P_proportional_coefficient", 37, 1),
    Register::rw("Over_Current_Protection_Time", 38, 1),
    Register::rw("Velocity_closed_loop_I_integral_coefficient", 39, 1),
    Register::rw("Torque_Enable", 40, 1),
    Register::rw("Acceleration", 41, 1).unit(Unit::StepsPerSecondSquared(100.0)),
    Register::rw("Goal_Position", 42, 2)
        .signed(SM15)
        .unit(STS_STEPS),
    Register::rw("Goal_Time", 44, 2),
    Register::rw("Goal_Velocity", 46, 2)
        .signed(SM15)
        .unit(STS_SPEED),
    Register::rw("Torque_Limit", 48, 2).unit(Unit::Percent(0.1)),
    Register::rw("Lock", 55, 1),
    Register::rw("Present_Position", 56, 2)
        .ro()
        .signed(SM15)
        .unit(STS_STEPS),
    Register::rw("Present_Velocity", 58, 2)
        .ro()
        .signed(SM15)
        .unit(STS_SPEED),
    Register::rw("Present_Load", 60, 2)
        .ro()
        .signed(Sign::SignMagnitude { bit: 10 })
        .unit(Unit::Percent(0.1)),
    Register::rw("Present_Voltage", 62, 1)
        .ro()
        .unit(Unit::Volts(0.1)),
    Register::rw("Present_Temperature", 63, 1)
        .ro()
        .unit(Unit::Celsius(1.0)),
    Register::rw("Status", 65, 1).ro(),
    Register::rw("Moving", 66, 1).ro(),
    Register::rw("Present_Current", 69, 2)
        .ro()
        .unit(Unit::Milliamps(6.5)),
    Register::rw("Goal_Position_2", 71, 2).ro(),
);

/// The SCS series table (the SCS0009).
const SCS: &[Register] = feetech!(Unit::Steps { per_turn: 1024 };
    Register::rw("Protective_Torque", 37, 1),
    Register::rw("Protection_Time", 38, 1),
    Register::rw("Torque_Enable", 40, 1),
    Register::rw("Acceleration", 41, 1),
    Register::rw("Goal_Position", 42, 2).unit(Unit::Steps { per_turn: 1024 }),
    Register::rw("Running_Time", 44, 2),
    Register::rw("Goal_Velocity", 46, 2),
    Register::rw("Lock", 48, 1),
    Register::rw("Present_Position", 56, 2)
        .ro()
        .unit(Unit::Steps { per_turn: 1024 }),
    Register::rw("Present_Velocity", 58, 2).ro(),
    Register::rw("Present_Load", 60, 2).ro(),
    Register::rw("Present_Voltage", 62, 1)
        .ro()
        .unit(Unit::Volts(0.1)),
    Register::rw("Present_Temperature", 63, 1)
        .ro()
        .unit(Unit::Celsius(1.0)),
    Register::rw("Sync_Write_Flag", 64, 1).ro(),
    Register::rw("Status", 65, 1).ro(),
    Register::rw("Moving", 66, 1).ro(),
);

const TC: Sign = Sign::TwosComplement;
const X_STEPS: Unit = Unit::Steps { per_turn: 4096 };
const X_RPM: Unit = Unit::Rpm(0.229);

/// The X series table up to the current registers, which differ by model
/// (`current`: the unit of Current_Limit, Goal_Current and
/// Present_Current; `None` for the XL430, which has none and reports
/// Present_Load at 126).
macro_rules! x_series {
    ($current:expr, $at126:expr) => {
        &[
            Register::rw("Model_Number", 0, 2).ro(),
            Register::rw("Model_Information", 2, 4).ro(),
            Register::rw("Firmware_Version", 6, 1).ro(),
            Register::rw("ID", 7, 1),
            Register::rw("Baud_Rate", 8, 1),
            Register::rw("Return_Delay_Time", 9, 1),
            Register::rw("Drive_Mode", 10, 1),
            Register::rw("Operating_Mode", 11, 1),
            Register::rw("Secondary_ID", 12, 1),
            Register::rw("Protocol_Type", 13, 1),
            Register::rw("Homing_Offset", 20, 4)
                .signed(TC)
                .unit(X_STEPS),
            Register::rw("Moving_Threshold", 24, 4).unit(X_RPM),
            Register::rw("Temperature_Limit", 31, 1).unit(Unit::Celsius(1.0)),
            Register::rw("Max_Voltage_Limit", 32, 2).unit(Unit::Volts(0.1)),
            Register::rw("Min_Voltage_Limit", 34, 2).unit(Unit::Volts(0.1)),
            Register::rw("PWM_Limit", 36, 2),
            Register::rw("Current_Limit", 38, 2).unit($current),
            Register::rw("Acceleration_Limit", 40, 4),
            Register::rw("Velocity_Limit", 44, 4).unit(X_RPM),
            Register::rw("Max_Position_Limit", 48, 4).unit(X_STEPS),
            Register::rw("Min_Position_Limit", 52, 4).unit(X_STEPS),
            Register::rw("Shutdown", 63, 1),
            Register::rw("Torque_Enable", 64, 1),
            Register::rw("LED", 65, 1),
            Register::rw("Status_Return_Level", 68, 1),
            Register::rw("Registered_Instruction", 69, 1).ro(),
            Register::rw("Hardware_Error_Status", 70, 1).ro(),
            Register::rw("Velocity_I_Gain", 76, 2),
            Register::rw("Velocity_P_Gain", 78, 2),
            Register::rw("Position_D_Gain", 80, 2),
            Register::rw("Position_I_Gain", 82, 2),
            Register::rw("Position_P_Gain", 84, 2),
            Register::rw("Feedforward_2nd_Gain", 88, 2),
            Register::rw("Feedforward_1st_Gain", 90, 2),
            Register::rw("Bus_Watchdog", 98, 1),
            Register::rw("Goal_PWM", 100, 2).signed(TC),
            Register::rw("Goal_Current", 102, 2)
                .signed(TC)
                .unit($current),
            Register::rw("Goal_Velocity", 104, 4).signed(TC).unit(X_RPM),
            Register::rw("Profile_Acceleration", 108, 4).unit(Unit::RpmPerMinute(214.577)),
            Register::rw("Profile_Velocity", 112, 4).unit(X_RPM),
            Register::rw("Goal_Position", 116, 4)
                .signed(TC)
                .unit(X_STEPS),
            Register::rw("Realtime_Tick", 120, 2).ro(),
            Register::rw("Moving", 122, 1).ro(),
            Register::rw("Moving_Status", 123, 1).ro(),
            Register::rw("Present_PWM", 124, 2).ro().signed(TC),
            $at126,
            Register::rw("Present_Velocity", 128, 4)
                .ro()
                .signed(TC)
                .unit(X_RPM),
            Register::rw("Present_Position", 132, 4)
                .ro()
                .signed(TC)
                .unit(X_STEPS),
            Register::rw("Velocity_Trajectory", 136, 4)
                .ro()
                .signed(TC)
                .unit(X_RPM),
            Register::rw("Position_Trajectory", 140, 4)
                .ro()
                .signed(TC)
                .unit(X_STEPS),
            Register::rw("Present_Input_Voltage", 144, 2)
                .ro()
                .unit(Unit::Volts(0.1)),
            Register::rw("Present_Temperature", 146, 1)
                .ro()
                .unit(Unit::Celsius(1.0)),
        ]
    };
}

const XL330: &[Register] = x_series!(
    Unit::Milliamps(1.0),
    Register::rw("Present_Current", 126, 2)
        .ro()
        .signed(TC)
        .unit(Unit::Milliamps(1.0))
);
const XM430: &[Register] = x_series!(
    Unit::Milliamps(2.69),
    Register::rw("Present_Current", 126, 2)
        .ro()
        .signed(TC)
        .unit(Unit::Milliamps(2.69))
);
const XL430: &[Register] = x_series!(
    Unit::Raw,
    Register::rw("Present_Load", 126, 2)
        .ro()
        .signed(TC)
        .unit(Unit::Percent(0.1))
);

/// Every model of the table, by name.
pub const MODELS: &[Model] = &[
    Model {
        name: "sts3215",
        number: 777,
        protocol: Protocol::Scs0,
        resolution: 4096,
        ram_start: 40,
        registers: STS,
    },
    Model {
        name: "scs0009",
        number: 1284,
        protocol: Protocol::Scs1,
        resolution: 1024,
        ram_start: 40,
        registers: SCS,
    },
    Model {
        name: "xl330-m288",
        number: 1200,
        protocol: Protocol::Dxl2,
        resolution: 4096,
        ram_start: 64,
        registers: XL330,
    },
    Model {
        name: "xl430-w250",
        number: 1060,
        protocol: Protocol::Dxl2,
        resolution: 4096,
        ram_start: 64,
        registers: XL430,
    },
    Model {
        name: "xm430-w350",
        number: 1020,
        protocol: Protocol::Dxl2,
        resolution: 4096,
        ram_start: 64,
        registers: XM430,
    },
];

/// The model named `name` (`sts3215`, `scs0009`, `xl330-m288`,
/// `xl430-w250`, `xm430-w350`).
#[must_use]
pub fn model(name: &str) -> Option<&'static Model> {
    MODELS.iter().find(|m| m.name == name)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each table is in address order, without overlaps, and each register
    /// is 1, 2 or 4 bytes.
    #[test]
    fn tables_are_ordered_and_do_not_overlap() {
        for m in MODELS {
            for pair in m.registers.windows(2) {
                let (a, b) = (&pair[0], &pair[1]);
                assert!(
                    a.address + u16::from(a.size) <= b.address,
                    "{}: {} and {}",
                    m.name,
                    a.name,
                    b.name
                );
            }
            assert!(
                m.registers.iter().all(|r| matches!(r.size, 1 | 2 | 4)),
                "{}",
                m.name
            );
        }
    }

    #[test]
    fn signs_round_trip_at_their_edges() {
        let sts = model("sts3215").unwrap();
        let offset = sts.register("Homing_Offset").unwrap();
        assert_eq!(offset.to_raw(-2047), Ok(0x0FFF));
        assert!(offset.to_raw(-2048).is_err());
        assert_eq!(offset.from_raw(0x0800), 0, "negative zero reads as zero");
        let x = model("xl430-w250")
            .unwrap()
            .register("Goal_Position")
            .unwrap();
        assert_eq!(x.to_raw(-1), Ok(0xFFFF_FFFF));
        assert_eq!(x.to_raw(i64::from(i32::MIN)), Ok(0x8000_0000));
        assert!(x.to_raw(i64::from(i32::MAX) + 1).is_err());
        for v in [-5000, -1, 0, 1, 4095, 1 << 20] {
            assert_eq!(x.from_raw(x.to_raw(v).unwrap()), v);
        }
        let torque = model("xm430-w350")
            .unwrap()
            .register("Torque_Enable")
            .unwrap();
        assert!(torque.to_raw(256).is_err() && torque.to_raw(-1).is_err());
        assert_eq!(
            model("xl430-w250").unwrap().register("Present_Current"),
            None
        );
    }
}
