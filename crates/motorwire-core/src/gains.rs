use core::fmt;
use core::str::FromStr;

use crate::{CoreError, check};

/// PID controller gains, as every dialect understands them.
///
/// WIA §10.4: all gains are non-negative, `kp > 0` for stable control, and
/// `ki_limit` (the integral wind-up limit) is positive when given.
///
/// ```
/// use motorwire_core::{CoreError, PidGains};
///
/// let gains = PidGains { kp: 50.0, ki: 0.1, kd: 2.5, ki_limit: None, feedforward: 0.0 };
/// assert_eq!(gains.check(), Ok(()));
/// let unstable = PidGains { kp: 0.0, ..gains };
/// assert_eq!(unstable.check(), Err(CoreError::NotPositive { field: "kp", value: 0.0 }));
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PidGains {
    /// Proportional gain; must be `> 0`.
    pub kp: f64,
    /// Integral gain; must be `>= 0`.
    pub ki: f64,
    /// Derivative gain; must be `>= 0`.
    pub kd: f64,
    /// Integral wind-up limit, in the controller's output units; `> 0` when given.
    pub ki_limit: Option<f64>,
    /// Feed-forward gain; any finite value.
    pub feedforward: f64,
}

impl PidGains {
    /// Checks the WIA §10.4 rules, reporting the first field that breaks one
    /// (in the order kp, ki, kd, ki_limit, feedforward).
    ///
    /// # Errors
    /// [`CoreError::NotPositive`] for `kp` or `ki_limit`, [`CoreError::Negative`]
    /// for `ki` or `kd`, [`CoreError::NonFinite`] for any non-finite value.
    pub fn check(&self) -> Result<(), CoreError> {
        check::positive("kp", self.kp)?;
        check::non_negative("ki", self.ki)?;
        check::non_negative("kd", self.kd)?;
        if let Some(limit) = self.ki_limit {
            check::positive("ki_limit", limit)?;
        }
        check::finite("feedforward", self.feedforward)?;
        Ok(())
    }
}

/// Impedance (and admittance) control parameters: a virtual spring, damper
/// and mass. All three are non-negative.
///
/// ```
/// use motorwire_core::{CoreError, ImpedanceParams};
///
/// let p = ImpedanceParams { stiffness: 200.0, damping: 10.0, inertia: 0.5 };
/// assert_eq!(p.check(), Ok(()));
/// assert_eq!(
///     ImpedanceParams { damping: -1.0, ..p }.check(),
///     Err(CoreError::Negative { field: "damping", value: -1.0 })
/// );
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImpedanceParams {
    /// Virtual stiffness (Nm/rad or N/m).
    pub stiffness: f64,
    /// Virtual damping (Nm·s/rad or N·s/m).
    pub damping: f64,
    /// Virtual inertia (kg·m² or kg).
    pub inertia: f64,
}

impl ImpedanceParams {
    /// Checks that every parameter is finite and non-negative.
    ///
    /// # Errors
    /// The first offending field, as [`CoreError::Negative`] or [`CoreError::NonFinite`].
    pub fn check(&self) -> Result<(), CoreError> {
        check::non_negative("stiffness", self.stiffness)?;
        check::non_negative("damping", self.damping)?;
        check::non_negative("inertia", self.inertia)?;
        Ok(())
    }
}

/// The setpoint or feedback filter types WIA names.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum FilterKind {
    /// No filtering.
    None,
    /// A low-pass filter.
    Lowpass,
    /// A notch filter.
    Notch,
    /// A Butterworth filter.
    Butterworth,
}

impl FilterKind {
    /// The name in WIA JSON.
    pub const fn name(self) -> &'static str {
        match self {
            Self::None => "none",
            Self::Lowpass => "lowpass",
            Self::Notch => "notch",
            Self::Butterworth => "butterworth",
        }
    }

    /// The filter type with the given WIA name.
    ///
    /// ```
    /// # use motorwire_core::FilterKind;
    /// assert_eq!(FilterKind::from_name("notch"), Ok(FilterKind::Notch));
    /// assert!(FilterKind::from_name("kalman").is_err());
    /// ```
    ///
    /// # Errors
    /// [`CoreError::UnknownFilterKind`].
    pub fn from_name(name: &str) -> Result<Self, CoreError> {
        Ok(match name {
            "none" => Self::None,
            "lowpass" => Self::Lowpass,
            "notch" => Self::Notch,
            "butterworth" => Self::Butterworth,
            _ => return Err(CoreError::UnknownFilterKind),
        })
    }
}

impl FromStr for FilterKind {
    type Err = CoreError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Self::from_name(s)
    }
}

impl fmt::Display for FilterKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A filter applied to a motor's command or measurement.
///
/// ```
/// use motorwire_core::{CoreError, FilterConfig, FilterKind};
///
/// let f = FilterConfig { kind: FilterKind::Lowpass, cutoff_frequency: Some(50.0), order: Some(2) };
/// assert_eq!(f.check(), Ok(()));
/// let bad = FilterConfig { cutoff_frequency: Some(0.0), ..f };
/// assert_eq!(bad.check(), Err(CoreError::NotPositive { field: "cutoff_frequency", value: 0.0 }));
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FilterConfig {
    /// The filter type.
    pub kind: FilterKind,
    /// Cut-off (or notch centre) frequency in Hz; `> 0` when given.
    pub cutoff_frequency: Option<f64>,
    /// Filter order, `>= 1`.
    pub order: Option<u32>,
}

impl FilterConfig {
    /// Checks that a cut-off frequency, when given, is positive.
    ///
    /// # Errors
    /// [`CoreError::NotPositive`] or [`CoreError::NonFinite`] for `cutoff_frequency`.
    pub fn check(&self) -> Result<(), CoreError> {
        if let Some(fc) = self.cutoff_frequency {
            check::positive("cutoff_frequency", fc)?;
        }
        Ok(())
    }
}
