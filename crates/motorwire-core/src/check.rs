//! Dialect-free checks on numbers, shared by every dialect so that a gain or
//! a limit is judged the same way whether it arrived as WIA JSON, an iRPC
//! frame or an Orion message.
//!
//! Each check returns the value on success, so checks compose with `?`:
//!
//! ```
//! use motorwire_core::{check, CoreError};
//!
//! assert_eq!(check::positive("kp", 50.0), Ok(50.0));
//! assert_eq!(
//!     check::positive("kp", 0.0),
//!     Err(CoreError::NotPositive { field: "kp", value: 0.0 })
//! );
//! assert_eq!(check::finite("setpoint", f64::NAN), Err(CoreError::NonFinite { field: "setpoint" }));
//! ```

use crate::CoreError;

/// Refuses NaN and infinities.
///
/// ```
/// # use motorwire_core::check;
/// assert!(check::finite("position", 1.5).is_ok());
/// assert!(check::finite("position", f64::INFINITY).is_err());
/// ```
pub fn finite(field: &'static str, value: f64) -> Result<f64, CoreError> {
    if value.is_finite() {
        Ok(value)
    } else {
        Err(CoreError::NonFinite { field })
    }
}

/// Requires a finite value `>= 0`.
///
/// ```
/// # use motorwire_core::{check, CoreError};
/// assert_eq!(check::non_negative("kd", 0.0), Ok(0.0));
/// assert_eq!(check::non_negative("kd", -1.0), Err(CoreError::Negative { field: "kd", value: -1.0 }));
/// ```
pub fn non_negative(field: &'static str, value: f64) -> Result<f64, CoreError> {
    let value = finite(field, value)?;
    if value >= 0.0 {
        Ok(value)
    } else {
        Err(CoreError::Negative { field, value })
    }
}

/// Requires a finite value `> 0`.
///
/// ```
/// # use motorwire_core::check;
/// assert!(check::positive("ki_limit", 10.0).is_ok());
/// assert!(check::positive("ki_limit", 0.0).is_err());
/// ```
pub fn positive(field: &'static str, value: f64) -> Result<f64, CoreError> {
    let value = finite(field, value)?;
    if value > 0.0 {
        Ok(value)
    } else {
        Err(CoreError::NotPositive { field, value })
    }
}

/// Requires `lower <= upper` (both finite).
///
/// ```
/// # use motorwire_core::{check, CoreError};
/// assert!(check::ordered(("min", -90.0), ("max", 90.0)).is_ok());
/// assert_eq!(
///     check::ordered(("min", 10.0), ("max", 5.0)),
///     Err(CoreError::OutOfOrder { lower: "min", lower_value: 10.0, upper: "max", upper_value: 5.0 })
/// );
/// ```
pub fn ordered(lower: (&'static str, f64), upper: (&'static str, f64)) -> Result<(), CoreError> {
    let lower_value = finite(lower.0, lower.1)?;
    let upper_value = finite(upper.0, upper.1)?;
    if lower_value <= upper_value {
        Ok(())
    } else {
        Err(CoreError::OutOfOrder {
            lower: lower.0,
            lower_value,
            upper: upper.0,
            upper_value,
        })
    }
}

/// Requires `min <= value <= max` (all finite).
///
/// ```
/// # use motorwire_core::check;
/// assert!(check::within("setpoint", 45.0, -90.0, 90.0).is_ok());
/// assert!(check::within("setpoint", 95.0, -90.0, 90.0).is_err());
/// ```
pub fn within(field: &'static str, value: f64, min: f64, max: f64) -> Result<f64, CoreError> {
    let value = finite(field, value)?;
    if value >= min && value <= max {
        Ok(value)
    } else {
        Err(CoreError::OutOfRange {
            field,
            value,
            min,
            max,
        })
    }
}

/// Requires `|value| <= limit` (all finite).
///
/// ```
/// # use motorwire_core::{check, CoreError};
/// assert!(check::magnitude_within("setpoint", -20.0, 30.0).is_ok());
/// assert_eq!(
///     check::magnitude_within("setpoint", -40.0, 30.0),
///     Err(CoreError::OutOfRange { field: "setpoint", value: -40.0, min: -30.0, max: 30.0 })
/// );
/// ```
pub fn magnitude_within(field: &'static str, value: f64, limit: f64) -> Result<f64, CoreError> {
    within(field, value, -limit, limit)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn non_finite_is_refused_by_every_check() {
        for v in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            assert_eq!(finite("x", v), Err(CoreError::NonFinite { field: "x" }));
            assert_eq!(
                non_negative("x", v),
                Err(CoreError::NonFinite { field: "x" })
            );
            assert_eq!(positive("x", v), Err(CoreError::NonFinite { field: "x" }));
            assert_eq!(
                within("x", v, -1.0, 1.0),
                Err(CoreError::NonFinite { field: "x" })
            );
            assert_eq!(
                ordered(("a", v), ("b", 1.0)),
                Err(CoreError::NonFinite { field: "a" })
            );
            assert_eq!(
                ordered(("a", 1.0), ("b", v)),
                Err(CoreError::NonFinite { field: "b" })
            );
        }
    }

    #[test]
    fn boundaries_are_inclusive_where_documented() {
        assert_eq!(non_negative("x", 0.0), Ok(0.0));
        assert_eq!(non_negative("x", -0.0), Ok(-0.0));
        assert_eq!(
            positive("x", -0.0),
            Err(CoreError::NotPositive {
                field: "x",
                value: -0.0
            })
        );
        assert_eq!(positive("x", f64::MIN_POSITIVE), Ok(f64::MIN_POSITIVE));
        assert_eq!(within("x", 90.0, -90.0, 90.0), Ok(90.0));
        assert_eq!(ordered(("a", 3.0), ("b", 3.0)), Ok(()));
    }
}
