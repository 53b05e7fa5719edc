//! SafetyLimits (WIA Phase 1 §7).

use motorwire_core::PositionLimits as CorePositionLimits;
use serde::{Deserialize, Serialize};
use serde_json::{Map, Value};

use crate::Rule;
use crate::check::Sink;
use crate::path::Path;
use crate::serde_util::some;
use crate::setters::with_setters;

/// Position limits: hard `min`/`max`, optional soft limits and home.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PositionLimits {
    /// Hard lower limit.
    pub min: f64,
    /// Hard upper limit.
    pub max: f64,
    /// Soft lower limit.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub soft_min: Option<f64>,
    /// Soft upper limit.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub soft_max: Option<f64>,
    /// Home position, inside `[min, max]`.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub home_position: Option<f64>,
    /// Members the schema does not name, kept as given.
    #[serde(flatten)]
    pub extra: Map<String, Value>,
}

with_setters!(PositionLimits {
    with_soft_min: soft_min: f64,
    with_soft_max: soft_max: f64,
    with_home_position: home_position: f64,
});

impl PositionLimits {
    /// Hard limits `min` and `max` alone (no soft limits, no home); the
    /// `with_*` setters give the rest. Nothing is checked here (`min`
    /// above `max` makes limits all the same): the
    /// [`Validator`](crate::Validator) judges the [`SafetyLimits`] that
    /// hold them.
    ///
    /// ```
    /// use motorwire_wia::PositionLimits;
    ///
    /// let l = PositionLimits::new(0.0, 150.0).with_home_position(90.0);
    /// assert_eq!(serde_json::to_string(&l)?, r#"{"min":0.0,"max":150.0,"home_position":90.0}"#);
    /// # Ok::<(), serde_json::Error>(())
    /// ```
    #[must_use]
    pub fn new(min: f64, max: f64) -> Self {
        Self {
            min,
            max,
            soft_min: None,
            soft_max: None,
            home_position: None,
            extra: Map::new(),
        }
    }

    /// As `motorwire-core` position limits.
    pub fn to_core(&self) -> CorePositionLimits {
        CorePositionLimits {
            min: self.min,
            max: self.max,
            soft_min: self.soft_min,
            soft_max: self.soft_max,
            home: self.home_position,
        }
    }
}

/// Velocity limits.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct VelocityLimits {
    /// Largest speed, `>= 0`.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub max_velocity: Option<f64>,
    /// Deceleration used for an emergency stop, `>= 0`.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub emergency_decel: Option<f64>,
    /// Members the schema does not name, kept as given.
    #[serde(flatten)]
    pub extra: Map<String, Value>,
}

/// Torque limits (Nm).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct TorqueLimits {
    /// Torque sustainable indefinitely, `<= peak_torque`.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub continuous_torque: Option<f64>,
    /// Short-term peak torque.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub peak_torque: Option<f64>,
    /// How long the peak may last (ms).
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub peak_duration_ms: Option<f64>,
    /// Members the schema does not name, kept as given.
    #[serde(flatten)]
    pub extra: Map<String, Value>,
}

/// Thermal limits (°C).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct ThermalLimits {
    /// Shutdown temperature.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub max_temperature: Option<f64>,
    /// Warning temperature, `<= max_temperature`.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub warning_temperature: Option<f64>,
    /// Whether output is derated as temperature rises.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub thermal_derating: Option<bool>,
    /// Members the schema does not name, kept as given.
    #[serde(flatten)]
    pub extra: Map<String, Value>,
}

/// Current limits (A).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct CurrentLimits {
    /// Current sustainable indefinitely, `<= peak_current`.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub continuous_current: Option<f64>,
    /// Short-term peak current.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub peak_current: Option<f64>,
    /// Members the schema does not name, kept as given.
    #[serde(flatten)]
    pub extra: Map<String, Value>,
}

/// Collision detection.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct CollisionDetection {
    /// Whether detection is on.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub enabled: Option<bool>,
    /// Sensitivity, 0 to 100.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub sensitivity: Option<f64>,
    /// Detection threshold.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub threshold: Option<f64>,
    /// Members the schema does not name, kept as given.
    #[serde(flatten)]
    pub extra: Map<String, Value>,
}

/// The safety configuration of one motor (WIA Phase 1 §7).
///
/// ```
/// use motorwire_wia::{SafetyLimits, Validator};
///
/// let l: SafetyLimits = Validator::new().parse(r#"{
///     "motor_id": "elbow", "position_limits": {"min": 0, "max": 150},
///     "velocity_limits": {"max_velocity": 120}, "torque_limits": {}
/// }"#)?;
/// assert!(l.position_limits.to_core().contains(90.0));
/// # Ok::<(), motorwire_wia::Error>(())
/// ```
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SafetyLimits {
    /// Motor identifier.
    pub motor_id: String,
    /// Position limits.
    pub position_limits: PositionLimits,
    /// Velocity limits.
    pub velocity_limits: VelocityLimits,
    /// Torque limits.
    pub torque_limits: TorqueLimits,
    /// Thermal limits.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub thermal_limits: Option<ThermalLimits>,
    /// Current limits.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub current_limits: Option<CurrentLimits>,
    /// Collision detection.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub collision_detection: Option<CollisionDetection>,
    /// Members the schema does not name, kept as given.
    #[serde(flatten)]
    pub extra: Map<String, Value>,
}

with_setters!(SafetyLimits {
    with_thermal_limits: thermal_limits: ThermalLimits,
    with_current_limits: current_limits: CurrentLimits,
    with_collision_detection: collision_detection: CollisionDetection,
});

impl SafetyLimits {
    /// A motor's safety limits of their required members alone:
    /// `motor_id`, the position limits, and the velocity and torque limits
    /// (required members whose own members are all optional:
    /// `VelocityLimits::default()` is `{}`); the `with_*` setters give the
    /// thermal, current and collision limits. Nothing is checked here:
    /// [`Validator::check`] says what a value breaks.
    ///
    /// ```
    /// use motorwire_wia::{PositionLimits, SafetyLimits, TorqueLimits, Validator, VelocityLimits};
    ///
    /// let l = SafetyLimits::new(
    ///     "elbow",
    ///     PositionLimits::new(0.0, 150.0),
    ///     VelocityLimits { max_velocity: Some(120.0), ..VelocityLimits::default() },
    ///     TorqueLimits::default(),
    /// );
    /// assert!(Validator::new().check(&l).is_empty());
    /// assert_eq!(
    ///     serde_json::to_string(&l)?,
    ///     r#"{"motor_id":"elbow","position_limits":{"min":0.0,"max":150.0},"velocity_limits":{"max_velocity":120.0},"torque_limits":{}}"#
    /// );
    /// # Ok::<(), serde_json::Error>(())
    /// ```
    ///
    /// [`Validator::check`]: crate::Validator::check
    #[must_use]
    pub fn new(
        motor_id: impl Into<String>,
        position_limits: PositionLimits,
        velocity_limits: VelocityLimits,
        torque_limits: TorqueLimits,
    ) -> Self {
        Self {
            motor_id: motor_id.into(),
            position_limits,
            velocity_limits,
            torque_limits,
            thermal_limits: None,
            current_limits: None,
            collision_detection: None,
            extra: Map::new(),
        }
    }

    pub(crate) fn check(&self, s: &mut Sink) {
        let root = Path::ROOT;
        s.motor_id(&root.key("motor_id"), &self.motor_id);

        let pl = root.key("position_limits");
        let p = &self.position_limits;
        let keys = ["min", "soft_min", "soft_max", "max"];
        let values = [Some(p.min), p.soft_min, p.soft_max, Some(p.max)];
        let paths = keys.map(|k| pl.key(k));
        let mut chain: Vec<(usize, f64)> = Vec::with_capacity(4);
        for (i, (path, v)) in paths.iter().zip(values).enumerate() {
            if let Some(v) = s.opt_num(path, v) {
                chain.push((i, v));
            }
        }
        // Every present pair in chain order: min <= soft_min <= soft_max <= max.
        for (n, &(i, lo)) in chain.iter().enumerate() {
            for &(j, hi) in chain.iter().skip(n + 1) {
                if lo > hi
                    && let (Some(path), Some(lo_name), Some(hi_name)) =
                        (paths.get(i), keys.get(i), keys.get(j))
                {
                    s.push(
                        path,
                        Rule::PositionLimitsOrder,
                        format!("{lo_name} ({lo}) must be <= {hi_name} ({hi})"),
                    );
                }
            }
        }
        let home = pl.key("home_position");
        if let Some(h) = s.opt_num(&home, p.home_position)
            && p.min.is_finite()
            && p.max.is_finite()
            && !(p.min..=p.max).contains(&h)
        {
            s.push(
                &home,
                Rule::HomePosition,
                format!(
                    "home_position {h} lies outside [min, max] = [{}, {}]",
                    p.min, p.max
                ),
            );
        }

        let vl = root.key("velocity_limits");
        s.opt_minimum(
            &vl.key("max_velocity"),
            self.velocity_limits.max_velocity,
            0.0,
        );
        s.opt_minimum(
            &vl.key("emergency_decel"),
            self.velocity_limits.emergency_decel,
            0.0,
        );

        let tl = root.key("torque_limits");
        let t = &self.torque_limits;
        let cont = tl.key("continuous_torque");
        let c = s.opt_num(&cont, t.continuous_torque);
        s.non_negative(&cont, "continuous_torque", c);
        let peak = tl.key("peak_torque");
        let pk = s.opt_num(&peak, t.peak_torque);
        s.non_negative(&peak, "peak_torque", pk);
        s.ordered(
            Rule::TorqueOrder,
            (&cont, "continuous_torque", c),
            ("peak_torque", pk),
        );
        let pd = tl.key("peak_duration_ms");
        let pdv = s.opt_num(&pd, t.peak_duration_ms);
        s.non_negative(&pd, "peak_duration_ms", pdv);

        if let Some(th) = &self.thermal_limits {
            let at = root.key("thermal_limits");
            let warn = at.key("warning_temperature");
            let w = s.opt_num(&warn, th.warning_temperature);
            let m = s.opt_num(&at.key("max_temperature"), th.max_temperature);
            s.ordered(
                Rule::TemperatureOrder,
                (&warn, "warning_temperature", w),
                ("max_temperature", m),
            );
        }
        if let Some(cl) = &self.current_limits {
            let at = root.key("current_limits");
            let cont = at.key("continuous_current");
            let c = s.opt_num(&cont, cl.continuous_current);
            s.non_negative(&cont, "continuous_current", c);
            let peak = at.key("peak_current");
            let pk = s.opt_num(&peak, cl.peak_current);
            s.non_negative(&peak, "peak_current", pk);
            s.ordered(
                Rule::CurrentOrder,
                (&cont, "continuous_current", c),
                ("peak_current", pk),
            );
        }
        if let Some(cd) = &self.collision_detection {
            let at = root.key("collision_detection");
            if let Some(v) = cd.sensitivity {
                s.range(&at.key("sensitivity"), v, 0.0, 100.0);
            }
            let th = at.key("threshold");
            let t = s.opt_num(&th, cd.threshold);
            s.non_negative(&th, "threshold", t);
        }
    }
}
