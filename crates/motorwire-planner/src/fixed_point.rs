//! `I16F16` at the boundary: requests in, states out (feature `fixed`).
//!
//! Firmware written against the iRPC document keeps positions, velocities
//! and accelerations in `I16F16` (16 integer bits, 16 fraction bits: range
//! [-32768, 32768), step 1/65536 ≈ 1.5e-5). That format is fine for storing
//! a value and useless for the planner's math: 1 ms is not representable,
//! and t² or t³ of a millisecond round to zero. So the planner computes in
//! `f32` or `f64` and only converts at the edges:
//!
//! - into a [`Request`]: [`from_i16f16`] and [`Request::from_i16f16`].
//!   Every `I16F16` is exact in `f64`; in `f32` (24-bit mantissa) values
//!   with magnitude of 256 or more round to the nearest `f32`.
//! - out of a [`State`]: [`to_i16f16`] and [`State::to_i16f16`] round to
//!   the nearest `I16F16` and refuse, with a [`FixedRangeError`] naming the
//!   field, a value outside the range or not finite. Nothing saturates
//!   silently: a jerk of 1e5 units/s³ does not fit and says so.
//!
//! ```
//! use motorwire_planner::fixed_point::I16F16;
//! use motorwire_planner::{Request, plan};
//!
//! // The iRPC document's trajectory example: 0 -> 1.57 rad, 1.74 rad/s, 8.72 rad/s².
//! let req = Request::<f32>::from_i16f16(
//!     I16F16::ZERO,
//!     I16F16::from_num(1.57),
//!     I16F16::from_num(1.74),
//!     I16F16::from_num(8.72),
//! );
//! let profile = plan(&req)?;
//! let mid = profile.sample(0.5).to_i16f16()?;
//! assert!(mid.velocity > I16F16::ONE);
//! let end = profile.end_state().to_i16f16()?;
//! assert_eq!(end.position, I16F16::from_num(1.57));
//! # Ok::<(), Box<dyn core::error::Error>>(())
//! ```

use core::fmt;

pub use fixed::types::I16F16;

use crate::{Float, Request, State};

/// A value that has no `I16F16` representation: outside [-32768, 32768)
/// once rounded, or not finite.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FixedRangeError {
    /// The field converted (`"position"`, `"velocity"`, `"acceleration"`,
    /// `"jerk"`, or the name the caller gave [`to_i16f16`]).
    pub field: &'static str,
    /// The value, as `f64`.
    pub value: f64,
}

impl fmt::Display for FixedRangeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} = {} does not fit I16F16 (finite, within [-32768, 32768))",
            self.field, self.value
        )
    }
}

impl core::error::Error for FixedRangeError {}

/// `value` as an `F`: exact for `f64`; for `f32`, exact below 256 in
/// magnitude and rounded to nearest above.
///
/// ```
/// use motorwire_planner::fixed_point::{I16F16, from_i16f16};
/// assert_eq!(from_i16f16::<f64>(I16F16::from_bits(1)), 1.0 / 65536.0);
/// // 300 + 2^-16 needs 25 significant bits: f32 rounds it to 300.
/// assert_eq!(from_i16f16::<f32>(I16F16::from_bits((300 << 16) + 1)), 300.0);
/// ```
pub fn from_i16f16<F: Float>(value: I16F16) -> F {
    F::from_f64(value.to_num::<f64>())
}

/// `value` rounded to the nearest `I16F16` (ties to even), or an error
/// naming `field` when it is not finite or out of range.
///
/// ```
/// use motorwire_planner::fixed_point::{I16F16, to_i16f16};
/// assert_eq!(to_i16f16(1.5_f64, "position")?, I16F16::from_num(1.5));
/// let err = to_i16f16(1e5_f64, "jerk").unwrap_err();
/// assert_eq!((err.field, err.value), ("jerk", 1e5));
/// assert!(to_i16f16(f32::NAN, "velocity").is_err());
/// # Ok::<(), motorwire_planner::fixed_point::FixedRangeError>(())
/// ```
pub fn to_i16f16<F: Float>(value: F, field: &'static str) -> Result<I16F16, FixedRangeError> {
    let value = value.to_f64();
    I16F16::checked_from_num(value).ok_or(FixedRangeError { field, value })
}

#[cfg_attr(docsrs, doc(cfg(feature = "fixed")))]
impl<F: Float> Request<F> {
    /// [`Request::new`] from `I16F16` inputs (a rest-to-rest move with
    /// symmetric limits, as the iRPC document's `TrapezoidalProfile::new`
    /// takes them). Set jerk, velocities and the rest with the usual
    /// builders and [`from_i16f16`].
    pub fn from_i16f16(
        start: I16F16,
        target: I16F16,
        max_velocity: I16F16,
        max_acceleration: I16F16,
    ) -> Self {
        Self::new(
            from_i16f16(start),
            from_i16f16(target),
            from_i16f16(max_velocity),
            from_i16f16(max_acceleration),
        )
    }
}

#[cfg_attr(docsrs, doc(cfg(feature = "fixed")))]
impl<F: Float> State<F> {
    /// Every field rounded to the nearest `I16F16`; the first that does not
    /// fit is the error.
    pub fn to_i16f16(&self) -> Result<State<I16F16>, FixedRangeError> {
        Ok(State {
            position: to_i16f16(self.position, "position")?,
            velocity: to_i16f16(self.velocity, "velocity")?,
            acceleration: to_i16f16(self.acceleration, "acceleration")?,
            jerk: to_i16f16(self.jerk, "jerk")?,
        })
    }
}
