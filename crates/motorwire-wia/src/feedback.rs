//! MotorFeedback (WIA Phase 1 §4).

use motorwire_core::{StatusFlag, StatusFlags};
use serde::{Deserialize, Serialize};
use serde_json::{Map, Value};

use crate::check::Sink;
use crate::path::Path;
use crate::serde_util::{number, opt_integer, some};
use crate::setters::with_setters;

/// The eleven status flags of a feedback message; a flag that is absent is
/// unknown (the schema requires none of them).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[allow(missing_docs)] // each flag is documented by `motorwire_core::StatusFlag`
pub struct MotorStatus {
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub enabled: Option<bool>,
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub fault: Option<bool>,
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub warning: Option<bool>,
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub calibrated: Option<bool>,
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub homed: Option<bool>,
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub in_motion: Option<bool>,
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub at_target: Option<bool>,
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub over_temperature: Option<bool>,
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub over_current: Option<bool>,
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub position_limit: Option<bool>,
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub encoder_error: Option<bool>,
    /// Members the schema does not name, kept as given.
    #[serde(flatten)]
    pub extra: Map<String, Value>,
}

impl MotorStatus {
    fn slots(&self) -> [(StatusFlag, Option<bool>); 11] {
        [
            (StatusFlag::Enabled, self.enabled),
            (StatusFlag::Fault, self.fault),
            (StatusFlag::Warning, self.warning),
            (StatusFlag::Calibrated, self.calibrated),
            (StatusFlag::Homed, self.homed),
            (StatusFlag::InMotion, self.in_motion),
            (StatusFlag::AtTarget, self.at_target),
            (StatusFlag::OverTemperature, self.over_temperature),
            (StatusFlag::OverCurrent, self.over_current),
            (StatusFlag::PositionLimit, self.position_limit),
            (StatusFlag::EncoderError, self.encoder_error),
        ]
    }

    /// The status word; absent flags count as clear.
    ///
    /// ```
    /// use motorwire_wia::MotorStatus;
    /// let s = MotorStatus { enabled: Some(true), in_motion: Some(true), ..Default::default() };
    /// assert_eq!(s.to_flags().bits(), 0x0021);
    /// ```
    pub fn to_flags(&self) -> StatusFlags {
        self.slots()
            .into_iter()
            .fold(StatusFlags::EMPTY, |acc, (f, v)| {
                acc.set(f, v == Some(true))
            })
    }

    /// All eleven flags, present, from a status word.
    pub fn from_flags(flags: StatusFlags) -> Self {
        let on = |f| Some(flags.contains(f));
        Self {
            enabled: on(StatusFlag::Enabled),
            fault: on(StatusFlag::Fault),
            warning: on(StatusFlag::Warning),
            calibrated: on(StatusFlag::Calibrated),
            homed: on(StatusFlag::Homed),
            in_motion: on(StatusFlag::InMotion),
            at_target: on(StatusFlag::AtTarget),
            over_temperature: on(StatusFlag::OverTemperature),
            over_current: on(StatusFlag::OverCurrent),
            position_limit: on(StatusFlag::PositionLimit),
            encoder_error: on(StatusFlag::EncoderError),
            extra: Map::new(),
        }
    }
}

/// Motor health (WIA Phase 1 §4.1).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct MotorHealth {
    /// Overall health score, 0 to 100.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub overall_score: Option<f64>,
    /// Hours in operation (h).
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub hours_operated: Option<f64>,
    /// Motion cycles completed.
    #[serde(
        default,
        deserialize_with = "opt_integer",
        skip_serializing_if = "Option::is_none"
    )]
    pub cycles_completed: Option<i64>,
    /// Whether maintenance is due.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub maintenance_due: Option<bool>,
    /// Estimated remaining lifetime (h).
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub estimated_lifetime: Option<f64>,
    /// Members the schema does not name, kept as given.
    #[serde(flatten)]
    pub extra: Map<String, Value>,
}

impl MotorHealth {
    fn check(&self, at: &Path<'_>, s: &mut Sink) {
        if let Some(v) = self.overall_score {
            s.range(&at.key("overall_score"), v, 0.0, 100.0);
        }
        let h = at.key("hours_operated");
        let hv = s.opt_num(&h, self.hours_operated);
        s.non_negative(&h, "hours_operated", hv);
        if let Some(c) = self.cycles_completed.filter(|c| *c < 0) {
            #[allow(clippy::cast_precision_loss)]
            s.non_negative(
                &at.key("cycles_completed"),
                "cycles_completed",
                Some(c as f64),
            );
        }
        let l = at.key("estimated_lifetime");
        let lv = s.opt_num(&l, self.estimated_lifetime);
        s.non_negative(&l, "estimated_lifetime", lv);
    }
}

/// Real-time feedback from one motor (WIA Phase 1 §4).
///
/// ```
/// use motorwire_wia::{MotorFeedback, Validator};
///
/// let fb: MotorFeedback = Validator::new().parse(r#"{
///     "motor_id": "elbow", "timestamp": 1704067200150, "position": 44.95,
///     "velocity": 12.3, "torque": 8.5, "status": {"enabled": true, "in_motion": true}
/// }"#)?;
/// assert_eq!(fb.status.to_flags().bits(), 0x0021);
/// # Ok::<(), motorwire_wia::Error>(())
/// ```
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MotorFeedback {
    /// Motor identifier.
    pub motor_id: String,
    /// Feedback time, Unix milliseconds.
    #[serde(serialize_with = "number")]
    pub timestamp: f64,
    /// Current position (deg or rad).
    pub position: f64,
    /// Current velocity (deg/s or rad/s).
    pub velocity: f64,
    /// Current acceleration.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub acceleration: Option<f64>,
    /// Current torque (Nm).
    pub torque: f64,
    /// Motor current (A).
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub current: Option<f64>,
    /// Motor voltage (V).
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub voltage: Option<f64>,
    /// Motor temperature (°C).
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub temperature: Option<f64>,
    /// Power consumption (W).
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub power: Option<f64>,
    /// Position tracking error.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub position_error: Option<f64>,
    /// Velocity tracking error.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub velocity_error: Option<f64>,
    /// Control effort (%).
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub control_effort: Option<f64>,
    /// Status flags.
    pub status: MotorStatus,
    /// Health.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub health: Option<MotorHealth>,
    /// Members the schema does not name, kept as given.
    #[serde(flatten)]
    pub extra: Map<String, Value>,
}

with_setters!(MotorFeedback {
    with_acceleration: acceleration: f64,
    with_current: current: f64,
    with_voltage: voltage: f64,
    with_temperature: temperature: f64,
    with_power: power: f64,
    with_position_error: position_error: f64,
    with_velocity_error: velocity_error: f64,
    with_control_effort: control_effort: f64,
    with_health: health: MotorHealth,
});

impl MotorFeedback {
    /// Feedback of its required members alone: `motor_id`, `timestamp`
    /// (Unix milliseconds, from the caller's clock), `position`,
    /// `velocity`, `torque` and the status flags (a required member whose
    /// flags are all optional: `MotorStatus::default()` is `{}`); the
    /// `with_*` setters give the other readings. Nothing is checked here:
    /// [`Validator::check`] says what a value breaks.
    ///
    /// ```
    /// use motorwire_wia::{MotorFeedback, MotorStatus, Validator};
    ///
    /// let status = MotorStatus { enabled: Some(true), in_motion: Some(true), ..MotorStatus::default() };
    /// let fb = MotorFeedback::new("elbow", 1_704_067_200_150.0, 44.95, 12.3, 8.5, status)
    ///     .with_temperature(42.0);
    /// assert!(Validator::new().check(&fb).is_empty());
    /// assert_eq!(
    ///     serde_json::to_string(&fb)?,
    ///     r#"{"motor_id":"elbow","timestamp":1704067200150,"position":44.95,"velocity":12.3,"torque":8.5,"temperature":42.0,"status":{"enabled":true,"in_motion":true}}"#
    /// );
    /// # Ok::<(), serde_json::Error>(())
    /// ```
    ///
    /// [`Validator::check`]: crate::Validator::check
    #[must_use]
    pub fn new(
        motor_id: impl Into<String>,
        timestamp: f64,
        position: f64,
        velocity: f64,
        torque: f64,
        status: MotorStatus,
    ) -> Self {
        Self {
            motor_id: motor_id.into(),
            timestamp,
            position,
            velocity,
            acceleration: None,
            torque,
            current: None,
            voltage: None,
            temperature: None,
            power: None,
            position_error: None,
            velocity_error: None,
            control_effort: None,
            status,
            health: None,
            extra: Map::new(),
        }
    }

    pub(crate) fn check(&self, s: &mut Sink) {
        let root = Path::ROOT;
        s.motor_id(&root.key("motor_id"), &self.motor_id);
        s.timestamp(&root.key("timestamp"), self.timestamp);
        for (name, v) in [
            ("position", self.position),
            ("velocity", self.velocity),
            ("torque", self.torque),
        ] {
            s.num(&root.key(name), v);
        }
        for (name, v) in [
            ("acceleration", self.acceleration),
            ("current", self.current),
            ("voltage", self.voltage),
            ("temperature", self.temperature),
            ("power", self.power),
            ("position_error", self.position_error),
            ("velocity_error", self.velocity_error),
            ("control_effort", self.control_effort),
        ] {
            s.opt_num(&root.key(name), v);
        }
        if let Some(h) = &self.health {
            h.check(&root.key("health"), s);
        }
    }
}
