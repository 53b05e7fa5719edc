use core::fmt;

/// Everything a dialect-free check in `motorwire-core` can refuse.
///
/// Every variant names the offending field (as the field's name in the WIA
/// vocabulary, e.g. `"kp"` or `"soft_min"`) and carries the offending value
/// and, where there is one, the limit it broke, so a caller can point a user
/// at the exact problem.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub enum CoreError {
    /// A number is NaN or infinite.
    NonFinite {
        /// The field holding the number.
        field: &'static str,
    },
    /// A number that must be zero or more is negative.
    Negative {
        /// The field holding the number.
        field: &'static str,
        /// The value given.
        value: f64,
    },
    /// A number that must be strictly greater than zero is not.
    NotPositive {
        /// The field holding the number.
        field: &'static str,
        /// The value given.
        value: f64,
    },
    /// Two bounds are in the wrong order (`lower` must be `<= upper`).
    OutOfOrder {
        /// The field that must be the smaller one.
        lower: &'static str,
        /// Its value.
        lower_value: f64,
        /// The field that must be the larger one.
        upper: &'static str,
        /// Its value.
        upper_value: f64,
    },
    /// A value lies outside the closed range `[min, max]`.
    OutOfRange {
        /// The field holding the value.
        field: &'static str,
        /// The value given.
        value: f64,
        /// The smallest allowed value.
        min: f64,
        /// The largest allowed value.
        max: f64,
    },
    /// A motor id is empty.
    MotorIdEmpty,
    /// A motor id is longer than [`MotorId::MAX_LEN`](crate::MotorId::MAX_LEN) bytes.
    MotorIdTooLong {
        /// Its length in bytes.
        len: usize,
        /// The maximum, [`MotorId::MAX_LEN`](crate::MotorId::MAX_LEN).
        max: usize,
    },
    /// A motor id holds a character outside `[a-zA-Z0-9_-]`.
    MotorIdInvalidChar {
        /// Byte offset of the character.
        index: usize,
        /// The character.
        ch: char,
    },
    /// A control-mode name is not one of the ten WIA names.
    UnknownControlMode,
    /// A numeric control-mode code is not one of the ten codes (0..=9).
    UnknownControlModeCode {
        /// The code given.
        code: u8,
    },
    /// A filter-type name is not one of the four WIA names.
    UnknownFilterKind,
    /// An angle-unit name is neither `deg` nor `rad`.
    UnknownAngleUnit,
    /// A status word has bits set that no WIA status flag uses.
    ReservedStatusBits {
        /// The bits that are set but reserved.
        bits: u16,
    },
}

impl fmt::Display for CoreError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Self::NonFinite { field } => write!(f, "{field} must be a finite number"),
            Self::Negative { field, value } => {
                write!(f, "{field} must be >= 0 (got {value})")
            }
            Self::NotPositive { field, value } => {
                write!(f, "{field} must be > 0 (got {value})")
            }
            Self::OutOfOrder {
                lower,
                lower_value,
                upper,
                upper_value,
            } => write!(
                f,
                "{lower} ({lower_value}) must be <= {upper} ({upper_value})"
            ),
            Self::OutOfRange {
                field,
                value,
                min,
                max,
            } => write!(f, "{field} ({value}) must lie within [{min}, {max}]"),
            Self::MotorIdEmpty => f.write_str("motor id must not be empty"),
            Self::MotorIdTooLong { len, max } => {
                write!(f, "motor id is {len} bytes long; the maximum is {max}")
            }
            Self::MotorIdInvalidChar { index, ch } => write!(
                f,
                "motor id has {ch:?} at byte {index}; only ASCII letters, digits, '_' and '-' are allowed"
            ),
            Self::UnknownControlMode => f.write_str(
                "unknown control mode; expected one of position, velocity, torque, impedance, \
                 admittance, trajectory, gravity_comp, force_ctrl, hybrid, disabled",
            ),
            Self::UnknownControlModeCode { code } => {
                write!(f, "unknown control mode code {code}; expected 0..=9")
            }
            Self::UnknownFilterKind => f.write_str(
                "unknown filter type; expected one of none, lowpass, notch, butterworth",
            ),
            Self::UnknownAngleUnit => f.write_str("unknown angle unit; expected deg or rad"),
            Self::ReservedStatusBits { bits } => {
                write!(f, "status bits {bits:#06x} are reserved and must be zero")
            }
        }
    }
}

impl core::error::Error for CoreError {}
