//! The error codes a `Nack` carries, and what they mean.

use core::fmt;

/// The `error` of a [`Payload::Nack`](crate::Payload::Nack), with its meaning.
///
/// Codes 1 to 4 and 255 are the ones the public joint firmware sends; the
/// document names none. Codes 16 to 20 are motorwire's own (its simulated
/// joint sends them), for refusals the firmware does not make: it executes
/// non-finite and out-of-limit targets. Any other code is kept as it came.
///
/// ```
/// use motorwire_irpc::NackCode;
/// assert_eq!(NackCode::from(4), NackCode::SET_TARGET_WRONG_STATE);
/// assert_eq!(NackCode::SET_TARGET_WRONG_STATE.meaning(), Some("set target while not active"));
/// assert_eq!(NackCode(77).to_string(), "77 (unknown code)");
/// assert_eq!(NackCode(16).to_string(), "16 (target outside the joint's limits)");
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(transparent))]
pub struct NackCode(pub u16);

impl NackCode {
    /// Configure in a state that cannot be configured.
    pub const CONFIGURE_WRONG_STATE: Self = Self(1);
    /// Activate in a state that cannot be activated.
    pub const ACTIVATE_WRONG_STATE: Self = Self(2);
    /// Deactivate in a state that cannot be deactivated.
    pub const DEACTIVATE_WRONG_STATE: Self = Self(3);
    /// A motion command while the joint is not active.
    pub const SET_TARGET_WRONG_STATE: Self = Self(4);
    /// A target or limit outside what the joint allows (motorwire).
    pub const OUT_OF_LIMITS: Self = Self(16);
    /// A NaN or infinite value (motorwire).
    pub const NON_FINITE: Self = Self(17);
    /// A message whose header decoded but whose payload did not (motorwire).
    pub const MALFORMED: Self = Self(18);
    /// A motion request older than the sender's last lifecycle request
    /// (its msg_id comes before the Activate or Deactivate that followed it):
    /// a late copy from before an emergency stop, never executed (motorwire).
    pub const STALE_REQUEST: Self = Self(19);
    /// StartCalibration in a state that cannot calibrate (a joint
    /// calibrates from Inactive), or StopCalibration while not calibrating
    /// (motorwire).
    pub const CALIBRATION_WRONG_STATE: Self = Self(20);
    /// A payload the joint does not handle.
    pub const UNKNOWN_PAYLOAD: Self = Self(255);

    /// What the code means, or `None` for a code no one has defined.
    pub const fn meaning(self) -> Option<&'static str> {
        Some(match self.0 {
            1 => "configure in the wrong state",
            2 => "activate in the wrong state",
            3 => "deactivate in the wrong state",
            4 => "set target while not active",
            16 => "target outside the joint's limits",
            17 => "non-finite value",
            18 => "malformed payload",
            19 => "a motion request from before the last lifecycle change",
            20 => "calibration started or stopped in the wrong state",
            255 => "unknown payload",
            _ => return None,
        })
    }
}

impl From<u16> for NackCode {
    fn from(code: u16) -> Self {
        Self(code)
    }
}

impl fmt::Display for NackCode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.meaning() {
            Some(m) => write!(f, "{} ({m})", self.0),
            None => write!(f, "{} (unknown code)", self.0),
        }
    }
}
