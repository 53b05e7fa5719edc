use crate::{CoreError, check};

/// One of the eleven WIA motor status flags.
///
/// The bit values are WIA Phase 3's feedback status word, in the order of the
/// MotorFeedback schema's `status` object.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[repr(u16)]
pub enum StatusFlag {
    /// The motor is enabled (0x0001).
    Enabled = 0x0001,
    /// A fault is active (0x0002).
    Fault = 0x0002,
    /// A warning is active (0x0004).
    Warning = 0x0004,
    /// The motor is calibrated (0x0008).
    Calibrated = 0x0008,
    /// The motor is homed (0x0010).
    Homed = 0x0010,
    /// The motor is moving (0x0020).
    InMotion = 0x0020,
    /// The motor is at its target (0x0040).
    AtTarget = 0x0040,
    /// Over temperature (0x0080).
    OverTemperature = 0x0080,
    /// Over current (0x0100).
    OverCurrent = 0x0100,
    /// A position limit is reached (0x0200).
    PositionLimit = 0x0200,
    /// The encoder reports an error (0x0400).
    EncoderError = 0x0400,
}

impl StatusFlag {
    /// All eleven flags in bit order.
    pub const ALL: [StatusFlag; 11] = [
        Self::Enabled,
        Self::Fault,
        Self::Warning,
        Self::Calibrated,
        Self::Homed,
        Self::InMotion,
        Self::AtTarget,
        Self::OverTemperature,
        Self::OverCurrent,
        Self::PositionLimit,
        Self::EncoderError,
    ];

    /// The flag's bit in the status word.
    pub const fn bit(self) -> u16 {
        self as u16
    }

    /// The flag's key in the WIA MotorFeedback `status` object.
    pub const fn name(self) -> &'static str {
        match self {
            Self::Enabled => "enabled",
            Self::Fault => "fault",
            Self::Warning => "warning",
            Self::Calibrated => "calibrated",
            Self::Homed => "homed",
            Self::InMotion => "in_motion",
            Self::AtTarget => "at_target",
            Self::OverTemperature => "over_temperature",
            Self::OverCurrent => "over_current",
            Self::PositionLimit => "position_limit",
            Self::EncoderError => "encoder_error",
        }
    }
}

/// A set of [`StatusFlag`]s, as the 16-bit status word of WIA Phase 3.
///
/// ```
/// use motorwire_core::{CoreError, StatusFlag, StatusFlags};
///
/// let s = StatusFlags::EMPTY.with(StatusFlag::Enabled).with(StatusFlag::InMotion);
/// assert_eq!(s.bits(), 0x0021);
/// assert!(s.contains(StatusFlag::InMotion));
/// assert_eq!(StatusFlags::from_bits(0x0800), Err(CoreError::ReservedStatusBits { bits: 0x0800 }));
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct StatusFlags(u16);

impl StatusFlags {
    /// No flag set.
    pub const EMPTY: Self = Self(0);
    /// The bits that carry a flag; the others are reserved.
    pub const DEFINED_BITS: u16 = 0x07FF;

    /// The set from a status word.
    ///
    /// # Errors
    /// [`CoreError::ReservedStatusBits`] when any bit above 0x0400 is set.
    pub const fn from_bits(bits: u16) -> Result<Self, CoreError> {
        let reserved = bits & !Self::DEFINED_BITS;
        if reserved != 0 {
            Err(CoreError::ReservedStatusBits { bits: reserved })
        } else {
            Ok(Self(bits))
        }
    }

    /// The status word.
    pub const fn bits(self) -> u16 {
        self.0
    }

    /// Whether `flag` is set.
    pub const fn contains(self, flag: StatusFlag) -> bool {
        self.0 & flag.bit() != 0
    }

    /// The set with `flag` added.
    #[must_use]
    pub const fn with(self, flag: StatusFlag) -> Self {
        Self(self.0 | flag.bit())
    }

    /// The set with `flag` set to `on`.
    #[must_use]
    pub const fn set(self, flag: StatusFlag, on: bool) -> Self {
        if on {
            Self(self.0 | flag.bit())
        } else {
            Self(self.0 & !flag.bit())
        }
    }

    /// The flags that are set, in bit order.
    pub fn iter(self) -> impl Iterator<Item = StatusFlag> {
        StatusFlag::ALL
            .into_iter()
            .filter(move |f| self.contains(*f))
    }
}

/// Health of a motor, as WIA MotorFeedback's `health` object reports it.
///
/// ```
/// use motorwire_core::{CoreError, Health};
///
/// let h = Health { overall_score: Some(95.5), hours_operated: Some(1250.5), cycles_completed: Some(458_920),
///                  maintenance_due: Some(false), estimated_lifetime: Some(8500.0) };
/// assert_eq!(h.check(), Ok(()));
/// let bad = Health { overall_score: Some(101.0), ..h };
/// assert_eq!(bad.check(), Err(CoreError::OutOfRange { field: "overall_score", value: 101.0, min: 0.0, max: 100.0 }));
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Health {
    /// Overall health, 0 to 100.
    pub overall_score: Option<f64>,
    /// Hours in operation (h).
    pub hours_operated: Option<f64>,
    /// Motion cycles completed.
    pub cycles_completed: Option<u64>,
    /// Whether maintenance is due.
    pub maintenance_due: Option<bool>,
    /// Estimated remaining lifetime (h).
    pub estimated_lifetime: Option<f64>,
}

impl Health {
    /// Checks the score range and that hours and lifetime are non-negative.
    ///
    /// # Errors
    /// The first offending field.
    pub fn check(&self) -> Result<(), CoreError> {
        if let Some(s) = self.overall_score {
            check::within("overall_score", s, 0.0, 100.0)?;
        }
        if let Some(h) = self.hours_operated {
            check::non_negative("hours_operated", h)?;
        }
        if let Some(l) = self.estimated_lifetime {
            check::non_negative("estimated_lifetime", l)?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bits_follow_wire_facts_order() {
        let bits: [u16; 11] = StatusFlag::ALL.map(StatusFlag::bit);
        assert_eq!(
            bits,
            [
                0x0001, 0x0002, 0x0004, 0x0008, 0x0010, 0x0020, 0x0040, 0x0080, 0x0100, 0x0200,
                0x0400
            ]
        );
        assert_eq!(StatusFlag::OverCurrent.name(), "over_current");
    }

    #[test]
    fn set_round_trips_and_refuses_reserved_bits() {
        let s = StatusFlags::from_bits(0x07FF).unwrap();
        assert_eq!(s.iter().count(), 11);
        let s = s.set(StatusFlag::Fault, false);
        assert_eq!(s.bits(), 0x07FD);
        assert!(!s.contains(StatusFlag::Fault));
        assert_eq!(
            StatusFlags::from_bits(0xF801),
            Err(CoreError::ReservedStatusBits { bits: 0xF800 })
        );
    }
}
