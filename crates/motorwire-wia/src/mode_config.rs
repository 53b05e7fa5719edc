//! The control-mode configuration (WIA Phase 1 §2.2; its schema is motorwire's).

use motorwire_core::{ControlMode, check};
use serde::{Deserialize, Serialize};
use serde_json::{Map, Value};

use crate::Rule;
use crate::check::Sink;
use crate::path::Path;
use crate::serde_util::{control_mode, some};
use crate::setters::with_setters;

/// Controller parameters of a mode.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct ModeParameters {
    /// Proportional gain, `> 0` when given.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub kp: Option<f64>,
    /// Integral gain, `>= 0`.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub ki: Option<f64>,
    /// Derivative gain, `>= 0`.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub kd: Option<f64>,
    /// Feed-forward gain.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub feedforward: Option<f64>,
    /// Error band within which the controller does not act, `>= 0`.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub deadband: Option<f64>,
    /// Members the schema does not name, kept as given.
    #[serde(flatten)]
    pub extra: Map<String, Value>,
}

/// Limits of a mode.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct ModeLimits {
    /// Largest tolerated tracking error, `>= 0`.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub max_error: Option<f64>,
    /// Maximum speed, `>= 0`.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub max_velocity: Option<f64>,
    /// Maximum acceleration, `>= 0`.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub max_acceleration: Option<f64>,
    /// Maximum jerk, `>= 0`.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub max_jerk: Option<f64>,
    /// Members the schema does not name, kept as given.
    #[serde(flatten)]
    pub extra: Map<String, Value>,
}

/// The configuration of a control mode (WIA Phase 1 §2.2).
///
/// ```
/// use motorwire_core::ControlMode;
/// use motorwire_wia::{ControlModeConfig, Validator};
///
/// let c: ControlModeConfig = Validator::new().parse(r#"{"mode": "velocity", "limits": {"max_velocity": 180}}"#)?;
/// assert_eq!(c.mode, ControlMode::Velocity);
/// # Ok::<(), motorwire_wia::Error>(())
/// ```
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ControlModeConfig {
    /// The motor it applies to, when the channel does not say.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub motor_id: Option<String>,
    /// The mode configured.
    #[serde(with = "control_mode")]
    pub mode: ControlMode,
    /// Controller parameters.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub parameters: Option<ModeParameters>,
    /// Limits.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub limits: Option<ModeLimits>,
    /// Members the schema does not name, kept as given.
    #[serde(flatten)]
    pub extra: Map<String, Value>,
}

with_setters!(ControlModeConfig {
    with_parameters: parameters: ModeParameters,
    with_limits: limits: ModeLimits,
});

impl ControlModeConfig {
    /// A control-mode configuration of its one required member, the mode;
    /// the `with_*` setters give the motor, the parameters and the
    /// limits. Nothing is checked here: [`Validator::check`] says what a
    /// value breaks.
    ///
    /// ```
    /// use motorwire_wia::core::ControlMode;
    /// use motorwire_wia::{ControlModeConfig, ModeLimits, Validator};
    ///
    /// let c = ControlModeConfig::new(ControlMode::Velocity)
    ///     .with_motor_id("elbow")
    ///     .with_limits(ModeLimits { max_velocity: Some(180.0), ..ModeLimits::default() });
    /// assert!(Validator::new().check(&c).is_empty());
    /// assert_eq!(
    ///     serde_json::to_string(&c)?,
    ///     r#"{"motor_id":"elbow","mode":"velocity","limits":{"max_velocity":180.0}}"#
    /// );
    /// # Ok::<(), serde_json::Error>(())
    /// ```
    ///
    /// [`Validator::check`]: crate::Validator::check
    #[must_use]
    pub fn new(mode: ControlMode) -> Self {
        Self {
            motor_id: None,
            mode,
            parameters: None,
            limits: None,
            extra: Map::new(),
        }
    }

    /// This configuration with [`motor_id`](Self::motor_id) set
    /// (unchecked: see [`Validator::check`]).
    ///
    /// [`Validator::check`]: crate::Validator::check
    #[must_use]
    pub fn with_motor_id(mut self, motor_id: impl Into<String>) -> Self {
        self.motor_id = Some(motor_id.into());
        self
    }

    pub(crate) fn check(&self, s: &mut Sink) {
        let root = Path::ROOT;
        if let Some(id) = &self.motor_id {
            let at = root.key("motor_id");
            s.id_pattern(&at, id);
            s.motor_id(&at, id);
        }
        if let Some(p) = &self.parameters {
            let at = root.key("parameters");
            let kp = at.key("kp");
            s.opt_minimum(&kp, p.kp, 0.0);
            s.opt_minimum(&at.key("ki"), p.ki, 0.0);
            s.opt_minimum(&at.key("kd"), p.kd, 0.0);
            s.opt_minimum(&at.key("deadband"), p.deadband, 0.0);
            s.opt_num(&at.key("feedforward"), p.feedforward);
            if let Some(v) = p.kp.filter(|v| v.is_finite()) {
                s.core(&kp, Rule::KpPositive, check::positive("kp", v));
            }
        }
        if let Some(l) = &self.limits {
            let at = root.key("limits");
            s.opt_minimum(&at.key("max_error"), l.max_error, 0.0);
            s.opt_minimum(&at.key("max_velocity"), l.max_velocity, 0.0);
            s.opt_minimum(&at.key("max_acceleration"), l.max_acceleration, 0.0);
            s.opt_minimum(&at.key("max_jerk"), l.max_jerk, 0.0);
        }
    }
}
