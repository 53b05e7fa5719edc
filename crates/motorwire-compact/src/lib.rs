#![doc = include_str!("../README.md")]
#![no_std]
#![cfg_attr(docsrs, feature(doc_cfg))]

use core::fmt;

use crc::{CRC_32_ISO_HDLC, Crc};
pub use motorwire_core::{ControlMode, StatusFlag, StatusFlags};

mod feedback;
pub use feedback::{FEEDBACK_FRAME_LEN, FEEDBACK_LEN, FeedbackRecord, MAX_HEALTH};

/// Length of a compact command on the wire.
pub const LEN: usize = 24;

const CRC32: Crc<u32> = Crc::<u32>::new(&CRC_32_ISO_HDLC);

/// The 32-bit hash that stands for a motor id on the wire: CRC-32/ISO-HDLC
/// (zlib's `crc32`) of the id's UTF-8 bytes. It is one-way; a
/// [`NameRegistry`] resolves it back to a name.
///
/// ```
/// use motorwire_compact::MotorHash;
/// assert_eq!(MotorHash::of("shoulder_pitch"), MotorHash(0xF33B_43CF));
/// assert_eq!(MotorHash::of("elbow"), MotorHash(0x8157_CB22));
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(transparent)
)]
pub struct MotorHash(pub u32);

impl MotorHash {
    /// The hash of a motor id.
    pub fn of(motor_id: &str) -> Self {
        Self(CRC32.checksum(motor_id.as_bytes()))
    }
}

impl fmt::Display for MotorHash {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{:#010x}", self.0)
    }
}

/// The command's flag byte.
///
/// ```
/// use motorwire_compact::Flags;
/// let f = Flags::REQUIRE_ACK.union(Flags::PRIORITY_HIGH);
/// assert_eq!(f.bits(), 0xC0);
/// assert!(f.contains(Flags::REQUIRE_ACK));
/// assert!(Flags::from_bits(0x02).is_err());
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(transparent)
)]
pub struct Flags(u8);

impl Flags {
    /// No flag set.
    pub const NONE: Self = Self(0);
    /// High priority (WIA Phase 3).
    pub const PRIORITY_HIGH: Self = Self(0x80);
    /// The receiver must acknowledge (WIA Phase 3).
    pub const REQUIRE_ACK: Self = Self(0x40);
    /// For every motor (WIA Phase 3).
    pub const BROADCAST: Self = Self(0x20);
    /// The payload is encrypted (WIA Phase 3). motorwire has no encryption
    /// layer: a command with this flag is refused.
    pub const ENCRYPTED: Self = Self(0x10);
    /// Emergency stop (motorwire's extension).
    pub const EMERGENCY_STOP: Self = Self(0x01);
    /// Every bit that has a meaning; the others are reserved and must be zero.
    pub const DEFINED: u8 = 0xF1;

    /// The flags from a flag byte.
    ///
    /// # Errors
    /// [`Error::ReservedFlags`] when a reserved bit (0x02, 0x04, 0x08) is set.
    pub const fn from_bits(bits: u8) -> Result<Self, Error> {
        let reserved = bits & !Self::DEFINED;
        if reserved != 0 {
            Err(Error::ReservedFlags { bits: reserved })
        } else {
            Ok(Self(bits))
        }
    }

    /// The flag byte.
    pub const fn bits(self) -> u8 {
        self.0
    }

    /// Whether every flag of `other` is set.
    pub const fn contains(self, other: Self) -> bool {
        self.0 & other.0 == other.0
    }

    /// Both sets of flags.
    #[must_use]
    pub const fn union(self, other: Self) -> Self {
        Self(self.0 | other.0)
    }

    /// The names of the flags that are set, in bit order from the highest.
    pub fn names(self) -> impl Iterator<Item = &'static str> {
        [
            (Self::PRIORITY_HIGH, "PRIORITY_HIGH"),
            (Self::REQUIRE_ACK, "REQUIRE_ACK"),
            (Self::BROADCAST, "BROADCAST"),
            (Self::ENCRYPTED, "ENCRYPTED"),
            (Self::EMERGENCY_STOP, "EMERGENCY_STOP"),
        ]
        .into_iter()
        .filter(move |(f, _)| self.contains(*f))
        .map(|(_, n)| n)
    }
}

/// A velocity limit in the command's fixed point: 0.1 units/s per step.
///
/// Built from a physical value with [`VelocityLimit::from_units_per_s`], which
/// rounds **down** (the wire never carries a looser limit than the one
/// given) and refuses what does not fit.
///
/// ```
/// use motorwire_compact::{Error, VelocityLimit};
/// assert_eq!(VelocityLimit::from_units_per_s(60.0), Ok(VelocityLimit(600)));
/// assert_eq!(VelocityLimit::from_units_per_s(60.06), Ok(VelocityLimit(600)));
/// assert_eq!(VelocityLimit(601).units_per_s(), 60.1);
/// assert_eq!(
///     VelocityLimit::from_units_per_s(7000.0),
///     Err(Error::LimitTooLarge { field: "velocity_limit", value: 7000.0, max: 6553.4 })
/// );
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(transparent)
)]
pub struct VelocityLimit(pub u16);

/// A torque limit in the command's fixed point: 0.01 Nm per step.
///
/// ```
/// use motorwire_compact::TorqueLimit;
/// assert_eq!(TorqueLimit::from_nm(12.5), Ok(TorqueLimit(1250)));
/// assert_eq!(TorqueLimit(1250).nm(), 12.5);
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(transparent)
)]
pub struct TorqueLimit(pub u16);

/// 0xFFFF on the wire means "no limit", so the largest limit is 0xFFFE steps.
const NO_LIMIT: u16 = 0xFFFF;

fn scale_down(field: &'static str, value: f64, steps_per_unit: f64) -> Result<u16, Error> {
    if !value.is_finite() {
        return Err(Error::NonFinite { field });
    }
    if value < 0.0 {
        return Err(Error::NegativeLimit { field, value });
    }
    let max = f64::from(NO_LIMIT - 1) / steps_per_unit;
    let steps = value * steps_per_unit;
    // Tolerate the representation error of decimal inputs such as 0.3 * 10.
    let steps = steps + steps * f64::EPSILON * 4.0;
    if steps >= f64::from(NO_LIMIT) {
        return Err(Error::LimitTooLarge { field, value, max });
    }
    // `steps` is in [0, 65535): the cast truncates toward zero, i.e. rounds down.
    #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
    Ok(steps as u16)
}

impl VelocityLimit {
    /// The largest velocity limit the wire carries, in units/s.
    pub const MAX_UNITS_PER_S: f64 = 6553.4;

    /// From units/s (deg/s or rad/s), rounded down to 0.1.
    ///
    /// # Errors
    /// [`Error::NonFinite`], [`Error::NegativeLimit`], [`Error::LimitTooLarge`].
    pub fn from_units_per_s(value: f64) -> Result<Self, Error> {
        scale_down("velocity_limit", value, 10.0).map(Self)
    }

    /// The limit in units/s.
    pub fn units_per_s(self) -> f64 {
        f64::from(self.0) / 10.0
    }
}

impl TorqueLimit {
    /// The largest torque limit the wire carries, in Nm.
    pub const MAX_NM: f64 = 655.34;

    /// From Nm, rounded down to 0.01.
    ///
    /// # Errors
    /// [`Error::NonFinite`], [`Error::NegativeLimit`], [`Error::LimitTooLarge`].
    pub fn from_nm(value: f64) -> Result<Self, Error> {
        scale_down("torque_limit", value, 100.0).map(Self)
    }

    /// The limit in Nm.
    pub fn nm(self) -> f64 {
        f64::from(self.0) / 100.0
    }
}

/// A WIA compact motor command (Phase 1 §11.1), 24 bytes little-endian:
///
/// | offset | size | field |
/// |---|---|---|
/// | 0 | 4 | motor id hash ([`MotorHash`]) |
/// | 4 | 8 | timestamp, Unix ms |
/// | 12 | 1 | control mode code ([`ControlMode::code`]) |
/// | 13 | 1 | [`Flags`] |
/// | 14 | 2 | reserved, zero |
/// | 16 | 4 | setpoint, f32 |
/// | 20 | 2 | velocity limit, 0.1 units/s, 0xFFFF = none |
/// | 22 | 2 | torque limit, 0.01 Nm, 0xFFFF = none |
///
/// ```
/// use motorwire_compact::{CompactCommand, ControlMode, Flags, MotorHash, VelocityLimit};
///
/// let cmd = CompactCommand {
///     motor: MotorHash::of("shoulder_pitch"),
///     timestamp_ms: 1_704_067_200_000,
///     control_mode: ControlMode::Position,
///     flags: Flags::REQUIRE_ACK,
///     setpoint: 45.0,
///     velocity_limit: Some(VelocityLimit(600)),
///     torque_limit: None,
/// };
/// let bytes = cmd.encode()?;
/// assert_eq!(bytes, [
///     0xcf, 0x43, 0x3b, 0xf3,                         // motor hash
///     0x00, 0xf4, 0x51, 0xc2, 0x8c, 0x01, 0x00, 0x00, // timestamp
///     0x01, 0x40, 0x00, 0x00,                         // position, REQUIRE_ACK, reserved
///     0x00, 0x00, 0x34, 0x42,                         // 45.0
///     0x58, 0x02, 0xff, 0xff,                         // 60.0 units/s, no torque limit
/// ]);
/// assert_eq!(CompactCommand::decode(&bytes)?, cmd);
/// # Ok::<(), motorwire_compact::Error>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct CompactCommand {
    /// Hash of the motor id.
    pub motor: MotorHash,
    /// Command time, Unix milliseconds.
    pub timestamp_ms: u64,
    /// Control mode.
    #[cfg_attr(feature = "serde", serde(with = "mode_name"))]
    pub control_mode: ControlMode,
    /// Flags.
    pub flags: Flags,
    /// Target value in the mode's unit; finite.
    pub setpoint: f32,
    /// Velocity limit; `None` is "no limit" (0xFFFF).
    pub velocity_limit: Option<VelocityLimit>,
    /// Torque limit; `None` is "no limit" (0xFFFF).
    pub torque_limit: Option<TorqueLimit>,
}

fn limit_raw(field: &'static str, raw: Option<u16>) -> Result<u16, Error> {
    match raw {
        None => Ok(NO_LIMIT),
        Some(NO_LIMIT) => Err(Error::LimitTooLarge {
            field,
            value: f64::from(NO_LIMIT),
            max: f64::from(NO_LIMIT - 1),
        }),
        Some(raw) => Ok(raw),
    }
}

impl CompactCommand {
    /// Encodes the command.
    ///
    /// # Errors
    /// [`Error::NonFinite`] for a NaN or infinite setpoint,
    /// [`Error::Encrypted`] when the ENCRYPTED flag is set (motorwire has no
    /// encryption layer), [`Error::ReservedFlags`] for reserved flag bits, and
    /// [`Error::LimitTooLarge`] for a raw limit of 0xFFFF (that value means
    /// "no limit"; use `None`).
    #[inline]
    pub fn encode(&self) -> Result<[u8; LEN], Error> {
        let mut out = [0u8; LEN];
        self.encode_into(&mut out)?;
        Ok(out)
    }

    /// Encodes the command into the first 24 bytes of `buf`.
    ///
    /// # Errors
    /// As [`CompactCommand::encode`], and [`Error::WrongLength`] when `buf`
    /// is shorter than 24 bytes.
    #[inline]
    pub fn encode_into(&self, buf: &mut [u8]) -> Result<(), Error> {
        let len = buf.len();
        let out: &mut [u8; LEN] = buf
            .get_mut(..LEN)
            .and_then(|b| b.try_into().ok())
            .ok_or(Error::WrongLength { len })?;
        if !self.setpoint.is_finite() {
            return Err(Error::NonFinite { field: "setpoint" });
        }
        let flags = Flags::from_bits(self.flags.bits())?;
        if flags.contains(Flags::ENCRYPTED) {
            return Err(Error::Encrypted);
        }
        let velocity = limit_raw("velocity_limit", self.velocity_limit.map(|l| l.0))?;
        let torque = limit_raw("torque_limit", self.torque_limit.map(|l| l.0))?;
        let [m0, m1, m2, m3] = self.motor.0.to_le_bytes();
        let [t0, t1, t2, t3, t4, t5, t6, t7] = self.timestamp_ms.to_le_bytes();
        let [s0, s1, s2, s3] = self.setpoint.to_le_bytes();
        let [v0, v1] = velocity.to_le_bytes();
        let [q0, q1] = torque.to_le_bytes();
        *out = [
            m0,
            m1,
            m2,
            m3,
            t0,
            t1,
            t2,
            t3,
            t4,
            t5,
            t6,
            t7,
            self.control_mode.code(),
            flags.bits(),
            0,
            0,
            s0,
            s1,
            s2,
            s3,
            v0,
            v1,
            q0,
            q1,
        ];
        Ok(())
    }

    /// Decodes exactly 24 bytes, checking everything: the control-mode code,
    /// reserved flag bits and bytes, the ENCRYPTED flag, a finite setpoint.
    ///
    /// ```
    /// use motorwire_compact::{CompactCommand, Error};
    /// let mut bytes = [0u8; 24];
    /// bytes[12] = 10;
    /// assert_eq!(CompactCommand::decode(&bytes), Err(Error::UnknownControlMode { code: 10 }));
    /// assert_eq!(CompactCommand::decode(&bytes[..23]), Err(Error::WrongLength { len: 23 }));
    /// ```
    ///
    /// # Errors
    /// The first problem found, in wire order.
    #[inline]
    pub fn decode(bytes: &[u8]) -> Result<Self, Error> {
        let b: &[u8; LEN] = bytes
            .try_into()
            .map_err(|_| Error::WrongLength { len: bytes.len() })?;
        let [
            m0,
            m1,
            m2,
            m3,
            t0,
            t1,
            t2,
            t3,
            t4,
            t5,
            t6,
            t7,
            mode,
            flags,
            r0,
            r1,
            s0,
            s1,
            s2,
            s3,
            v0,
            v1,
            q0,
            q1,
        ] = *b;
        let setpoint = f32::from_le_bytes([s0, s1, s2, s3]);
        // One branch for every check on the hot path; the cold path finds
        // which one failed, in wire order.
        let accepted_flags = Flags::DEFINED & !Flags::ENCRYPTED.0;
        let valid =
            mode <= 9 && flags & !accepted_flags == 0 && (r0 | r1) == 0 && setpoint.is_finite();
        if !valid {
            return Err(Self::refusal(mode, flags, u16::from_le_bytes([r0, r1])));
        }
        let Ok(control_mode) = ControlMode::from_code(mode) else {
            return Err(Error::UnknownControlMode { code: mode });
        };
        let flags = Flags(flags);
        let limit = |raw: u16| (raw != NO_LIMIT).then_some(raw);
        Ok(Self {
            motor: MotorHash(u32::from_le_bytes([m0, m1, m2, m3])),
            timestamp_ms: u64::from_le_bytes([t0, t1, t2, t3, t4, t5, t6, t7]),
            control_mode,
            flags,
            setpoint,
            velocity_limit: limit(u16::from_le_bytes([v0, v1])).map(VelocityLimit),
            torque_limit: limit(u16::from_le_bytes([q0, q1])).map(TorqueLimit),
        })
    }

    /// Why a command that failed the combined check is refused, checking
    /// the fields in wire order.
    #[cold]
    fn refusal(mode: u8, flags: u8, reserved: u16) -> Error {
        if ControlMode::from_code(mode).is_err() {
            return Error::UnknownControlMode { code: mode };
        }
        match Flags::from_bits(flags) {
            Err(e) => return e,
            Ok(f) if f.contains(Flags::ENCRYPTED) => return Error::Encrypted,
            Ok(_) => {}
        }
        if reserved != 0 {
            return Error::ReservedBytes { value: reserved };
        }
        Error::NonFinite { field: "setpoint" }
    }

    /// Converts a setpoint to the wire's f32, refusing what f32 cannot hold
    /// (NaN, infinity, or a magnitude beyond `f32::MAX`). Values round to
    /// the nearest f32.
    ///
    /// ```
    /// use motorwire_compact::{CompactCommand, Error};
    /// assert_eq!(CompactCommand::setpoint_from_f64(45.0), Ok(45.0));
    /// assert_eq!(CompactCommand::setpoint_from_f64(1e39), Err(Error::NonFinite { field: "setpoint" }));
    /// ```
    ///
    /// # Errors
    /// [`Error::NonFinite`].
    #[allow(clippy::cast_possible_truncation)]
    pub fn setpoint_from_f64(value: f64) -> Result<f32, Error> {
        let v = value as f32;
        if v.is_finite() {
            Ok(v)
        } else {
            Err(Error::NonFinite { field: "setpoint" })
        }
    }
}

#[cfg(feature = "serde")]
mod mode_name {
    use motorwire_core::ControlMode;
    use serde::de::{Error as _, Unexpected};
    use serde::{Deserialize, Deserializer, Serializer};

    pub(crate) fn serialize<S: Serializer>(m: &ControlMode, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(m.name())
    }

    pub(crate) fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<ControlMode, D::Error> {
        let name = <&str>::deserialize(d)?;
        ControlMode::from_name(name)
            .map_err(|_| D::Error::invalid_value(Unexpected::Str(name), &"a WIA control mode name"))
    }
}

/// A fixed-capacity table from motor-id hashes back to names.
///
/// ```
/// use motorwire_compact::{MotorHash, NameRegistry};
///
/// let mut names = NameRegistry::<8>::new();
/// names.insert("shoulder_pitch")?;
/// names.insert("elbow")?;
/// assert_eq!(names.resolve(MotorHash(0x8157_CB22)), Some("elbow"));
/// assert_eq!(names.resolve(MotorHash(1)), None);
/// # Ok::<(), motorwire_compact::Error>(())
/// ```
#[derive(Debug, Clone)]
pub struct NameRegistry<'a, const N: usize> {
    entries: [(MotorHash, &'a str); N],
    len: usize,
}

impl<'a, const N: usize> Default for NameRegistry<'a, N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<'a, const N: usize> NameRegistry<'a, N> {
    /// An empty registry.
    pub const fn new() -> Self {
        Self {
            entries: [(MotorHash(0), ""); N],
            len: 0,
        }
    }

    /// Adds a name. Adding a name twice is a no-op.
    ///
    /// # Errors
    /// [`Error::HashCollision`] when another name has the same hash (the
    /// hash could not tell them apart on the wire), [`Error::RegistryFull`].
    pub fn insert(&mut self, name: &'a str) -> Result<(), Error> {
        let hash = MotorHash::of(name);
        if let Some(existing) = self.resolve(hash) {
            return if existing == name {
                Ok(())
            } else {
                Err(Error::HashCollision { hash: hash.0 })
            };
        }
        let slot = self
            .entries
            .get_mut(self.len)
            .ok_or(Error::RegistryFull { capacity: N })?;
        *slot = (hash, name);
        self.len += 1;
        Ok(())
    }

    /// The name with this hash, if registered.
    pub fn resolve(&self, hash: MotorHash) -> Option<&'a str> {
        self.entries
            .get(..self.len)?
            .iter()
            .find(|(h, _)| *h == hash)
            .map(|(_, n)| *n)
    }

    /// How many names are registered.
    pub const fn len(&self) -> usize {
        self.len
    }

    /// Whether no name is registered.
    pub const fn is_empty(&self) -> bool {
        self.len == 0
    }
}

/// Everything the compact codec refuses.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub enum Error {
    /// The input is not exactly 24 bytes (or the output buffer is shorter).
    WrongLength {
        /// The length given.
        len: usize,
    },
    /// The control-mode byte is not a code of [`ControlMode`] (0..=9).
    UnknownControlMode {
        /// The byte.
        code: u8,
    },
    /// Reserved flag bits (0x02, 0x04, 0x08) are set.
    ReservedFlags {
        /// The reserved bits that are set.
        bits: u8,
    },
    /// The ENCRYPTED flag is set; motorwire has no encryption layer.
    Encrypted,
    /// The two reserved bytes are not zero.
    ReservedBytes {
        /// Their little-endian value.
        value: u16,
    },
    /// A value is NaN or infinite (or beyond f32's range).
    NonFinite {
        /// The field.
        field: &'static str,
    },
    /// A limit is negative.
    NegativeLimit {
        /// The field.
        field: &'static str,
        /// The value given.
        value: f64,
    },
    /// A limit does not fit its 16-bit fixed point (0xFFFF means "none").
    LimitTooLarge {
        /// The field.
        field: &'static str,
        /// The value given.
        value: f64,
        /// The largest value the field carries.
        max: f64,
    },
    /// Two motor ids have the same hash.
    HashCollision {
        /// The shared hash.
        hash: u32,
    },
    /// A [`NameRegistry`] is full.
    RegistryFull {
        /// Its capacity.
        capacity: usize,
    },
    /// A feedback record is not 44 bytes (or its 48-byte CAN-FD frame), or
    /// the output buffer is shorter than 44 bytes.
    WrongFeedbackLength {
        /// The length given.
        len: usize,
    },
    /// A feedback record's status word sets bits above 0x0400, which carry
    /// no flag.
    ReservedStatusBits {
        /// The reserved bits that are set.
        bits: u16,
    },
    /// A feedback record's health score is over 100.
    HealthOutOfRange {
        /// The score.
        health: u8,
    },
    /// A feedback record's reserved byte (offset 43) is not zero.
    FeedbackReserved {
        /// Its value.
        value: u8,
    },
    /// A byte of the padding after a feedback record (offsets 44 to 47) is
    /// not zero.
    FeedbackPadding {
        /// The offset of the first byte that is not zero.
        offset: usize,
        /// Its value.
        value: u8,
    },
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Self::WrongLength { len } => {
                write!(f, "a compact command is exactly {LEN} bytes, not {len}")
            }
            Self::UnknownControlMode { code } => {
                write!(f, "control_mode code {code} is not one of 0..=9")
            }
            Self::ReservedFlags { bits } => {
                write!(f, "flags bits {bits:#04x} are reserved and must be zero")
            }
            Self::Encrypted => f.write_str(
                "the ENCRYPTED flag is set, and motorwire has no encryption layer to decrypt it",
            ),
            Self::ReservedBytes { value } => {
                write!(f, "the reserved bytes must be zero, not {value:#06x}")
            }
            Self::NonFinite { field } => write!(f, "{field} must be a finite f32"),
            Self::NegativeLimit { field, value } => {
                write!(f, "{field} must not be negative (got {value})")
            }
            Self::LimitTooLarge { field, value, max } => {
                write!(
                    f,
                    "{field} {value} does not fit the wire; the maximum is {max}"
                )
            }
            Self::HashCollision { hash } => {
                write!(f, "two motor ids share the hash {hash:#010x}")
            }
            Self::RegistryFull { capacity } => {
                write!(f, "the name registry is full ({capacity} names)")
            }
            Self::WrongFeedbackLength { len } => write!(
                f,
                "a feedback record is {FEEDBACK_LEN} bytes (or its {FEEDBACK_FRAME_LEN}-byte CAN-FD frame), not {len}"
            ),
            Self::ReservedStatusBits { bits } => {
                write!(f, "status bits {bits:#06x} are reserved and must be zero")
            }
            Self::HealthOutOfRange { health } => {
                write!(f, "health score {health} is over {MAX_HEALTH}")
            }
            Self::FeedbackReserved { value } => {
                write!(
                    f,
                    "the feedback record's reserved byte must be zero, not {value:#04x}"
                )
            }
            Self::FeedbackPadding { offset, value } => write!(
                f,
                "the feedback frame's padding must be zero, but byte {offset} is {value:#04x}"
            ),
        }
    }
}

impl core::error::Error for Error {}
