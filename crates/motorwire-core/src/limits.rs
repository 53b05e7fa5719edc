use crate::{CoreError, check};

/// Position limits of one motor, in the motor's declared angle unit.
///
/// The hard limits `min..=max` bound everything; the optional soft limits lie
/// inside them (`min <= soft_min <= soft_max <= max`), and the home position
/// lies inside the hard limits.
///
/// ```
/// use motorwire_core::{CoreError, PositionLimits};
///
/// let limits = PositionLimits { min: -90.0, max: 90.0, soft_min: Some(-85.0), soft_max: Some(85.0), home: Some(0.0) };
/// assert_eq!(limits.check(), Ok(()));
/// assert!(limits.contains(45.0));
/// let bad = PositionLimits { soft_min: Some(-95.0), ..limits };
/// assert_eq!(
///     bad.check(),
///     Err(CoreError::OutOfOrder { lower: "min", lower_value: -90.0, upper: "soft_min", upper_value: -95.0 })
/// );
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PositionLimits {
    /// Hard lower limit.
    pub min: f64,
    /// Hard upper limit.
    pub max: f64,
    /// Soft lower limit (a warning zone begins here).
    pub soft_min: Option<f64>,
    /// Soft upper limit.
    pub soft_max: Option<f64>,
    /// Home position.
    pub home: Option<f64>,
}

impl PositionLimits {
    /// Hard limits only.
    pub const fn new(min: f64, max: f64) -> Self {
        Self {
            min,
            max,
            soft_min: None,
            soft_max: None,
            home: None,
        }
    }

    /// Checks `min <= soft_min <= soft_max <= max` (over the bounds that are
    /// given) and that `home` lies in `[min, max]`.
    ///
    /// # Errors
    /// The first violated pair as [`CoreError::OutOfOrder`], a home position
    /// outside as [`CoreError::OutOfRange`], or [`CoreError::NonFinite`].
    pub fn check(&self) -> Result<(), CoreError> {
        let chain = [
            ("min", Some(self.min)),
            ("soft_min", self.soft_min),
            ("soft_max", self.soft_max),
            ("max", Some(self.max)),
        ];
        let mut lower: Option<(&'static str, f64)> = None;
        for (name, value) in chain {
            if let Some(value) = value {
                let value = check::finite(name, value)?;
                if let Some(prev) = lower {
                    check::ordered(prev, (name, value))?;
                }
                lower = Some((name, value));
            }
        }
        if let Some(home) = self.home {
            check::within("home_position", home, self.min, self.max)?;
        }
        Ok(())
    }

    /// Whether `position` lies within the hard limits (inclusive).
    pub fn contains(&self, position: f64) -> bool {
        position >= self.min && position <= self.max
    }
}

/// Motion limits of one motor; each is a magnitude, and `None` means "no limit".
///
/// ```
/// use motorwire_core::{CoreError, MotionLimits};
///
/// let l = MotionLimits { max_velocity: Some(120.0), ..MotionLimits::NONE };
/// assert_eq!(l.check(), Ok(()));
/// assert_eq!(
///     MotionLimits { max_jerk: Some(-1.0), ..l }.check(),
///     Err(CoreError::NotPositive { field: "max_jerk", value: -1.0 })
/// );
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MotionLimits {
    /// Maximum speed (deg/s or rad/s).
    pub max_velocity: Option<f64>,
    /// Maximum acceleration (deg/s² or rad/s²).
    pub max_acceleration: Option<f64>,
    /// Maximum jerk (deg/s³ or rad/s³).
    pub max_jerk: Option<f64>,
    /// Maximum torque magnitude (Nm).
    pub max_torque: Option<f64>,
}

impl MotionLimits {
    /// No limits at all.
    pub const NONE: Self = Self {
        max_velocity: None,
        max_acceleration: None,
        max_jerk: None,
        max_torque: None,
    };

    /// Checks that every limit that is given is finite and `> 0`.
    ///
    /// # Errors
    /// The first offending limit as [`CoreError::NotPositive`] or [`CoreError::NonFinite`].
    pub fn check(&self) -> Result<(), CoreError> {
        for (name, value) in [
            ("max_velocity", self.max_velocity),
            ("max_acceleration", self.max_acceleration),
            ("max_jerk", self.max_jerk),
            ("max_torque", self.max_torque),
        ] {
            if let Some(v) = value {
                check::positive(name, v)?;
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn position_limits_report_the_first_broken_pair() {
        let l = PositionLimits {
            min: -10.0,
            max: 10.0,
            soft_min: None,
            soft_max: Some(11.0),
            home: None,
        };
        assert_eq!(
            l.check(),
            Err(CoreError::OutOfOrder {
                lower: "soft_max",
                lower_value: 11.0,
                upper: "max",
                upper_value: 10.0
            })
        );
        let l = PositionLimits::new(5.0, -5.0);
        assert_eq!(
            l.check(),
            Err(CoreError::OutOfOrder {
                lower: "min",
                lower_value: 5.0,
                upper: "max",
                upper_value: -5.0
            })
        );
        let l = PositionLimits {
            home: Some(20.0),
            ..PositionLimits::new(-10.0, 10.0)
        };
        assert_eq!(
            l.check(),
            Err(CoreError::OutOfRange {
                field: "home_position",
                value: 20.0,
                min: -10.0,
                max: 10.0
            })
        );
        let l = PositionLimits::new(f64::NAN, 1.0);
        assert_eq!(l.check(), Err(CoreError::NonFinite { field: "min" }));
    }

    #[test]
    fn position_limits_contain_their_bounds() {
        let l = PositionLimits::new(-1.0, 1.0);
        assert!(l.contains(-1.0) && l.contains(1.0) && !l.contains(1.0000001));
        assert!(!l.contains(f64::NAN));
    }
}
