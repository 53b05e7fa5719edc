//! PIDConfig (WIA Phase 1 §6).

use motorwire_core::{ControlMode, check};
use serde::{Deserialize, Serialize};
use serde_json::{Map, Value};

use crate::Rule;
use crate::check::Sink;
use crate::path::Path;
use crate::serde_util::{control_mode, some};
use crate::setters::with_setters;

/// The complete gains of a PID configuration.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PidConfigGains {
    /// Proportional gain, `> 0`.
    pub kp: f64,
    /// Integral gain, `>= 0`.
    pub ki: f64,
    /// Derivative gain, `>= 0`.
    pub kd: f64,
    /// Integral wind-up limit, `> 0` when given.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub ki_limit: Option<f64>,
    /// Feed-forward gain.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub feedforward: Option<f64>,
    /// Derivative filter coefficient.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub derivative_filter: Option<f64>,
    /// Members the schema does not name, kept as given.
    #[serde(flatten)]
    pub extra: Map<String, Value>,
}

with_setters!(PidConfigGains {
    with_ki_limit: ki_limit: f64,
    with_feedforward: feedforward: f64,
    with_derivative_filter: derivative_filter: f64,
});

impl PidConfigGains {
    /// The gains `kp`, `ki` and `kd` alone; the `with_*` setters give the
    /// rest. Nothing is checked here (`kp` 0 makes gains all the same):
    /// the [`Validator`](crate::Validator) judges the [`PidConfig`] that
    /// holds them.
    ///
    /// ```
    /// use motorwire_wia::PidConfigGains;
    ///
    /// let g = PidConfigGains::new(40.0, 0.05, 1.8).with_ki_limit(10.0);
    /// assert_eq!(serde_json::to_string(&g)?, r#"{"kp":40.0,"ki":0.05,"kd":1.8,"ki_limit":10.0}"#);
    /// # Ok::<(), serde_json::Error>(())
    /// ```
    #[must_use]
    pub fn new(kp: f64, ki: f64, kd: f64) -> Self {
        Self {
            kp,
            ki,
            kd,
            ki_limit: None,
            feedforward: None,
            derivative_filter: None,
            extra: Map::new(),
        }
    }

    /// As `motorwire-core` gains (`feedforward` defaults to 0).
    pub fn to_core(&self) -> motorwire_core::PidGains {
        motorwire_core::PidGains {
            kp: self.kp,
            ki: self.ki,
            kd: self.kd,
            ki_limit: self.ki_limit,
            feedforward: self.feedforward.unwrap_or(0.0),
        }
    }
}

/// Output clamp of the controller.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct OutputLimits {
    /// Lowest output.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub min: Option<f64>,
    /// Highest output.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub max: Option<f64>,
    /// Members the schema does not name, kept as given.
    #[serde(flatten)]
    pub extra: Map<String, Value>,
}

/// First-order filter on the setpoint.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct SetpointFilter {
    /// Whether the filter is on.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub enabled: Option<bool>,
    /// Time constant (s), `>= 0`.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub time_constant: Option<f64>,
    /// Members the schema does not name, kept as given.
    #[serde(flatten)]
    pub extra: Map<String, Value>,
}

/// PID controller configuration of one motor (WIA Phase 1 §6).
///
/// ```
/// use motorwire_wia::{PidConfig, Validator};
///
/// let c: PidConfig = Validator::new().parse(r#"{
///     "motor_id": "elbow", "control_mode": "position",
///     "gains": {"kp": 40, "ki": 0.05, "kd": 1.8}
/// }"#)?;
/// assert_eq!(c.gains.to_core().kp, 40.0);
/// # Ok::<(), motorwire_wia::Error>(())
/// ```
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PidConfig {
    /// Motor identifier.
    pub motor_id: String,
    /// `position`, `velocity` or `torque`.
    #[serde(with = "control_mode")]
    pub control_mode: ControlMode,
    /// The gains.
    pub gains: PidConfigGains,
    /// Output clamp.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub output_limits: Option<OutputLimits>,
    /// Setpoint filter.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub setpoint_filter: Option<SetpointFilter>,
    /// Members the schema does not name, kept as given.
    #[serde(flatten)]
    pub extra: Map<String, Value>,
}

with_setters!(PidConfig {
    with_output_limits: output_limits: OutputLimits,
    with_setpoint_filter: setpoint_filter: SetpointFilter,
});

impl PidConfig {
    /// A PID configuration of its required members alone: `motor_id`,
    /// `control_mode` (one of [`PidConfig::MODES`]) and the gains; the
    /// `with_*` setters give the output limits and the setpoint filter.
    /// Nothing is checked here (a mode outside [`PidConfig::MODES`] makes a
    /// configuration all the same): [`Validator::check`] says what a value
    /// breaks.
    ///
    /// ```
    /// use motorwire_wia::core::ControlMode;
    /// use motorwire_wia::{OutputLimits, PidConfig, PidConfigGains, Validator};
    ///
    /// let c = PidConfig::new("elbow", ControlMode::Position, PidConfigGains::new(40.0, 0.05, 1.8))
    ///     .with_output_limits(OutputLimits { min: Some(-10.0), max: Some(10.0), ..OutputLimits::default() });
    /// assert!(Validator::new().check(&c).is_empty());
    /// assert_eq!(
    ///     serde_json::to_string(&c)?,
    ///     r#"{"motor_id":"elbow","control_mode":"position","gains":{"kp":40.0,"ki":0.05,"kd":1.8},"output_limits":{"min":-10.0,"max":10.0}}"#
    /// );
    /// # Ok::<(), serde_json::Error>(())
    /// ```
    ///
    /// [`Validator::check`]: crate::Validator::check
    #[must_use]
    pub fn new(
        motor_id: impl Into<String>,
        control_mode: ControlMode,
        gains: PidConfigGains,
    ) -> Self {
        Self {
            motor_id: motor_id.into(),
            control_mode,
            gains,
            output_limits: None,
            setpoint_filter: None,
            extra: Map::new(),
        }
    }

    /// The control modes the PIDConfig schema allows.
    pub const MODES: [ControlMode; 3] = [
        ControlMode::Position,
        ControlMode::Velocity,
        ControlMode::Torque,
    ];

    pub(crate) fn check(&self, s: &mut Sink) {
        let root = Path::ROOT;
        s.motor_id(&root.key("motor_id"), &self.motor_id);
        s.one_of_names(
            &root.key("control_mode"),
            self.control_mode.name(),
            &["position", "velocity", "torque"],
        );
        let g = root.key("gains");
        let kp = g.key("kp");
        s.minimum(&kp, self.gains.kp, 0.0);
        s.minimum(&g.key("ki"), self.gains.ki, 0.0);
        s.minimum(&g.key("kd"), self.gains.kd, 0.0);
        if self.gains.kp.is_finite() {
            s.core(&kp, Rule::KpPositive, check::positive("kp", self.gains.kp));
        }
        let lim = g.key("ki_limit");
        if let Some(v) = s.opt_num(&lim, self.gains.ki_limit) {
            s.core(&lim, Rule::KiLimitPositive, check::positive("ki_limit", v));
        }
        s.opt_num(&g.key("feedforward"), self.gains.feedforward);
        s.opt_num(&g.key("derivative_filter"), self.gains.derivative_filter);
        if let Some(o) = &self.output_limits {
            let at = root.key("output_limits");
            let min = at.key("min");
            let lo = s.opt_num(&min, o.min);
            let hi = s.opt_num(&at.key("max"), o.max);
            s.ordered(Rule::OutputLimitsOrder, (&min, "min", lo), ("max", hi));
        }
        if let Some(f) = &self.setpoint_filter {
            let sf = root.key("setpoint_filter");
            let at = sf.key("time_constant");
            let tc = s.opt_num(&at, f.time_constant);
            s.non_negative(&at, "time_constant", tc);
        }
    }
}
