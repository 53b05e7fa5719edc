//! The WIA Phase 3 feedback record a compact device sends on CAN-FD
//! (WIRE-FACTS §2.1).

use motorwire_core::StatusFlags;

use crate::{Error, MotorHash};

/// Length of the feedback record: the sum of its fields (the Phase 3
/// document says 52; its own fields add up to 44).
pub const FEEDBACK_LEN: usize = 44;

/// Length of the CAN-FD frame that carries a feedback record: the record
/// zero-padded to the next CAN-FD length.
pub const FEEDBACK_FRAME_LEN: usize = 48;

/// The largest health score.
pub const MAX_HEALTH: u8 = 100;

/// The names of the seven f32 fields, in wire order (offsets 12 to 36).
const FLOAT_FIELDS: [&str; 7] = [
    "position",
    "velocity",
    "acceleration",
    "torque",
    "current",
    "voltage",
    "temperature",
];

/// The WIA Phase 3 feedback record of a compact device, as motorwire lays it
/// out on CAN-FD (WIRE-FACTS §2.1): 44 bytes little-endian, zero-padded to a
/// 48-byte frame.
///
/// | offset | size | field |
/// |---|---|---|
/// | 0 | 4 | motor id hash ([`MotorHash`]) |
/// | 4 | 8 | timestamp, µs of the device's clock |
/// | 12 | 4 | position, f32 |
/// | 16 | 4 | velocity, f32 |
/// | 20 | 4 | acceleration, f32 |
/// | 24 | 4 | torque, f32, Nm |
/// | 28 | 4 | current, f32, A |
/// | 32 | 4 | voltage, f32, V |
/// | 36 | 4 | temperature, f32, °C |
/// | 40 | 2 | status flags ([`StatusFlags`], the bits of WIRE-FACTS §2) |
/// | 42 | 1 | health score, 0..=100 |
/// | 43 | 1 | reserved, zero |
/// | 44 | 4 | padding to the CAN-FD length 48, zero |
///
/// Position, velocity and acceleration are in the units of the motor's
/// commands (degrees or radians, per second, per second squared).
///
/// ```
/// use motorwire_compact::{FeedbackRecord, MotorHash, StatusFlag, StatusFlags};
///
/// let record = FeedbackRecord {
///     motor: MotorHash::of("elbow"),
///     timestamp_us: 1_500_000,
///     position: 45.0,
///     velocity: -2.5,
///     acceleration: 0.0,
///     torque: 1.5,
///     current: 2.0,
///     voltage: 24.0,
///     temperature: 25.0,
///     status: StatusFlags::EMPTY.with(StatusFlag::Enabled).with(StatusFlag::AtTarget),
///     health: 100,
/// };
/// let bytes = record.encode()?;
/// assert_eq!(bytes, [
///     0x22, 0xcb, 0x57, 0x81,                         // motor hash 0x8157CB22
///     0x60, 0xe3, 0x16, 0x00, 0x00, 0x00, 0x00, 0x00, // 1.5 s in µs
///     0x00, 0x00, 0x34, 0x42,                         // position 45.0
///     0x00, 0x00, 0x20, 0xc0,                         // velocity -2.5
///     0x00, 0x00, 0x00, 0x00,                         // acceleration 0.0
///     0x00, 0x00, 0xc0, 0x3f,                         // torque 1.5
///     0x00, 0x00, 0x00, 0x40,                         // current 2.0
///     0x00, 0x00, 0xc0, 0x41,                         // voltage 24.0
///     0x00, 0x00, 0xc8, 0x41,                         // temperature 25.0
///     0x41, 0x00, 0x64, 0x00,                         // enabled | at_target, health 100, reserved
///     0x00, 0x00, 0x00, 0x00,                         // padding
/// ]);
/// assert_eq!(FeedbackRecord::decode(&bytes)?, record);
/// # Ok::<(), motorwire_compact::Error>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FeedbackRecord {
    /// Hash of the motor id.
    pub motor: MotorHash,
    /// When the device sampled the record, microseconds of its own clock.
    pub timestamp_us: u64,
    /// Position (degrees or radians); finite.
    pub position: f32,
    /// Velocity (units/s); finite.
    pub velocity: f32,
    /// Acceleration (units/s²); finite.
    pub acceleration: f32,
    /// Torque (Nm); finite.
    pub torque: f32,
    /// Current (A); finite.
    pub current: f32,
    /// Supply voltage (V); finite.
    pub voltage: f32,
    /// Temperature (°C); finite.
    pub temperature: f32,
    /// Status flags.
    pub status: StatusFlags,
    /// Health score, 0..=100.
    pub health: u8,
}

impl FeedbackRecord {
    /// The seven f32 fields in wire order.
    const fn floats(&self) -> [f32; 7] {
        [
            self.position,
            self.velocity,
            self.acceleration,
            self.torque,
            self.current,
            self.voltage,
            self.temperature,
        ]
    }

    /// Encodes the record as the 48-byte CAN-FD payload (the 44 bytes of
    /// the record, then four zero bytes of padding).
    ///
    /// # Errors
    /// [`Error::NonFinite`] naming the first NaN or infinite field in wire
    /// order, [`Error::HealthOutOfRange`] for a health score over 100.
    pub fn encode(&self) -> Result<[u8; FEEDBACK_FRAME_LEN], Error> {
        let mut out = [0u8; FEEDBACK_FRAME_LEN];
        self.encode_into(&mut out)?;
        Ok(out)
    }

    /// Encodes the 44 bytes of the record into the start of `buf` (the
    /// padding, if any, is the caller's).
    ///
    /// # Errors
    /// As [`FeedbackRecord::encode`], and [`Error::WrongFeedbackLength`]
    /// when `buf` is shorter than 44 bytes.
    pub fn encode_into(&self, buf: &mut [u8]) -> Result<(), Error> {
        let len = buf.len();
        let out: &mut [u8; FEEDBACK_LEN] = buf
            .get_mut(..FEEDBACK_LEN)
            .and_then(|b| b.try_into().ok())
            .ok_or(Error::WrongFeedbackLength { len })?;
        for (field, value) in FLOAT_FIELDS.into_iter().zip(self.floats()) {
            if !value.is_finite() {
                return Err(Error::NonFinite { field });
            }
        }
        if self.health > MAX_HEALTH {
            return Err(Error::HealthOutOfRange {
                health: self.health,
            });
        }
        let mut w = Writer { out, at: 0 };
        w.put(&self.motor.0.to_le_bytes());
        w.put(&self.timestamp_us.to_le_bytes());
        for value in self.floats() {
            w.put(&value.to_le_bytes());
        }
        w.put(&self.status.bits().to_le_bytes());
        w.put(&[self.health, 0]);
        Ok(())
    }

    /// Decodes a feedback record: exactly the 48-byte CAN-FD payload (whose
    /// last four bytes must be zero), or the 44-byte record alone. Checks
    /// everything: finite floats, defined status bits, a health score of at
    /// most 100, a zero reserved byte and zero padding.
    ///
    /// ```
    /// use motorwire_compact::{Error, FeedbackRecord};
    /// let mut bytes = [0u8; 48];
    /// assert!(FeedbackRecord::decode(&bytes).is_ok());
    /// bytes[42] = 101;
    /// assert_eq!(FeedbackRecord::decode(&bytes), Err(Error::HealthOutOfRange { health: 101 }));
    /// bytes[42] = 100;
    /// bytes[47] = 1;
    /// assert_eq!(FeedbackRecord::decode(&bytes), Err(Error::FeedbackPadding { offset: 47, value: 1 }));
    /// assert_eq!(FeedbackRecord::decode(&bytes[..40]), Err(Error::WrongFeedbackLength { len: 40 }));
    /// ```
    ///
    /// # Errors
    /// [`Error::WrongFeedbackLength`] for any length but 44 or 48, then the
    /// first problem in wire order: [`Error::NonFinite`],
    /// [`Error::ReservedStatusBits`], [`Error::HealthOutOfRange`],
    /// [`Error::FeedbackReserved`], [`Error::FeedbackPadding`].
    pub fn decode(bytes: &[u8]) -> Result<Self, Error> {
        let len = bytes.len();
        let (record, padding) = match len {
            FEEDBACK_LEN => (bytes, &[][..]),
            FEEDBACK_FRAME_LEN => bytes.split_at(FEEDBACK_LEN),
            _ => return Err(Error::WrongFeedbackLength { len }),
        };
        let b: &[u8; FEEDBACK_LEN] = record
            .try_into()
            .map_err(|_| Error::WrongFeedbackLength { len })?;
        let mut r = Reader { bytes: b, at: 0 };
        let motor = MotorHash(u32::from_le_bytes(r.take()));
        let timestamp_us = u64::from_le_bytes(r.take());
        let mut floats = [0f32; 7];
        for value in &mut floats {
            *value = f32::from_le_bytes(r.take());
        }
        let status = u16::from_le_bytes(r.take());
        let [health, reserved] = r.take();
        // One branch for every check on the hot path; the cold path finds
        // which one failed, in wire order.
        let valid = floats.iter().all(|v| v.is_finite())
            && status & !StatusFlags::DEFINED_BITS == 0
            && health <= MAX_HEALTH
            && reserved == 0
            && padding.iter().all(|&p| p == 0);
        if !valid {
            return Err(Self::refusal(&floats, status, health, reserved, padding));
        }
        let [
            position,
            velocity,
            acceleration,
            torque,
            current,
            voltage,
            temperature,
        ] = floats;
        let status = StatusFlags::from_bits(status).map_err(|_| Error::ReservedStatusBits {
            bits: status & !StatusFlags::DEFINED_BITS,
        })?;
        Ok(Self {
            motor,
            timestamp_us,
            position,
            velocity,
            acceleration,
            torque,
            current,
            voltage,
            temperature,
            status,
            health,
        })
    }

    /// Why a record that failed the combined check is refused, checking the
    /// fields in wire order.
    #[cold]
    fn refusal(floats: &[f32; 7], status: u16, health: u8, reserved: u8, padding: &[u8]) -> Error {
        if let Some((field, _)) = FLOAT_FIELDS
            .into_iter()
            .zip(floats)
            .find(|(_, v)| !v.is_finite())
        {
            return Error::NonFinite { field };
        }
        let reserved_bits = status & !StatusFlags::DEFINED_BITS;
        if reserved_bits != 0 {
            return Error::ReservedStatusBits {
                bits: reserved_bits,
            };
        }
        if health > MAX_HEALTH {
            return Error::HealthOutOfRange { health };
        }
        if reserved != 0 {
            return Error::FeedbackReserved { value: reserved };
        }
        match padding.iter().position(|&p| p != 0) {
            Some(i) => Error::FeedbackPadding {
                offset: FEEDBACK_LEN + i,
                value: padding.get(i).copied().unwrap_or(0),
            },
            // Not reached: `decode` calls this only when a check failed.
            // Naming the padding's first byte keeps it total without a panic.
            None => Error::FeedbackPadding {
                offset: FEEDBACK_LEN,
                value: 0,
            },
        }
    }
}

/// Writes consecutive fields into the record, never out of bounds.
struct Writer<'a> {
    out: &'a mut [u8; FEEDBACK_LEN],
    at: usize,
}

impl Writer<'_> {
    fn put(&mut self, bytes: &[u8]) {
        let end = self.at + bytes.len();
        if let Some(dst) = self.out.get_mut(self.at..end) {
            dst.copy_from_slice(bytes);
        }
        self.at = end;
    }
}

/// Reads consecutive fields of the record, never out of bounds.
struct Reader<'a> {
    bytes: &'a [u8; FEEDBACK_LEN],
    at: usize,
}

impl Reader<'_> {
    fn take<const N: usize>(&mut self) -> [u8; N] {
        let mut out = [0u8; N];
        if let Some(src) = self.bytes.get(self.at..self.at + N) {
            out.copy_from_slice(src);
        }
        self.at += N;
        out
    }
}
