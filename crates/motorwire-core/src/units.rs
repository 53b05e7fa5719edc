use core::fmt;
use core::str::FromStr;

use crate::CoreError;

/// The angle unit a deployment declares for a motor.
///
/// WIA messages carry no units ("deg or rad"); a bus map says which one each
/// motor uses (`motorwire_translate::AngleUnit` is this type).
///
/// ```
/// use motorwire_core::AngleUnit;
/// assert_eq!("deg".parse::<AngleUnit>()?, AngleUnit::Degrees);
/// assert_eq!(AngleUnit::Radians.to_string(), "rad");
/// # Ok::<(), motorwire_core::CoreError>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum AngleUnit {
    /// Degrees (and deg/s, deg/s², ...; iRPC's unit, and a bus map's when
    /// it names none).
    #[default]
    Degrees,
    /// Radians (and rad/s, rad/s², ...).
    Radians,
}

impl AngleUnit {
    /// `value` in this unit, in degrees.
    ///
    /// ```
    /// use motorwire_core::AngleUnit;
    /// assert_eq!(AngleUnit::Radians.to_degrees(core::f64::consts::PI), 180.0);
    /// assert_eq!(AngleUnit::Degrees.from_degrees(90.0), 90.0);
    /// ```
    pub fn to_degrees(self, value: f64) -> f64 {
        match self {
            Self::Degrees => value,
            Self::Radians => value.to_degrees(),
        }
    }

    /// `degrees` in this unit.
    pub fn from_degrees(self, degrees: f64) -> f64 {
        match self {
            Self::Degrees => degrees,
            Self::Radians => degrees.to_radians(),
        }
    }

    /// The short name: `"deg"` or `"rad"`.
    pub const fn name(self) -> &'static str {
        match self {
            Self::Degrees => "deg",
            Self::Radians => "rad",
        }
    }
}

impl FromStr for AngleUnit {
    type Err = CoreError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "deg" => Ok(Self::Degrees),
            "rad" => Ok(Self::Radians),
            _ => Err(CoreError::UnknownAngleUnit),
        }
    }
}

impl fmt::Display for AngleUnit {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}
