use core::fmt;
use core::str::FromStr;

use crate::CoreError;

/// The angle unit a deployment declares for a motor.
///
/// WIA messages carry no units ("deg or rad"); a bus map says which one each
/// motor uses. Conversion between them happens only in `motorwire-translate`.
///
/// ```
/// use motorwire_core::AngleUnit;
/// assert_eq!("deg".parse::<AngleUnit>()?, AngleUnit::Degrees);
/// assert_eq!(AngleUnit::Radians.to_string(), "rad");
/// # Ok::<(), motorwire_core::CoreError>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum AngleUnit {
    /// Degrees (and deg/s, deg/s², ...).
    Degrees,
    /// Radians (and rad/s, rad/s², ...).
    Radians,
}

impl AngleUnit {
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
