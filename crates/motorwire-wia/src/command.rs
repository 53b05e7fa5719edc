//! MotorCommand (WIA §3.1), the multi-axis command (§3.2) and their parts.

use std::collections::HashMap;

use motorwire_core::{ControlMode, FilterKind, check};
use serde::{Deserialize, Serialize};
use serde_json::{Map, Value};

use crate::Rule;
use crate::check::Sink;
use crate::path::Path;
use crate::serde_util::{control_mode, number, opt_filter_kind, opt_integer, some, string_enum};
use crate::setters::with_setters;

/// PID gains as a WIA command carries them. In a command every gain is
/// optional (an absent gain leaves the controller's current one in place);
/// [`PidGains::to_core`] gives the complete `motorwire-core` value when
/// `kp`, `ki` and `kd` are all present.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct PidGains {
    /// Proportional gain, `> 0`.
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
    /// Members the schema does not name, kept as given.
    #[serde(flatten)]
    pub extra: Map<String, Value>,
}

impl PidGains {
    /// The complete gains, when `kp`, `ki` and `kd` are all given
    /// (`feedforward` defaults to 0).
    pub fn to_core(&self) -> Option<motorwire_core::PidGains> {
        Some(motorwire_core::PidGains {
            kp: self.kp?,
            ki: self.ki?,
            kd: self.kd?,
            ki_limit: self.ki_limit,
            feedforward: self.feedforward.unwrap_or(0.0),
        })
    }

    pub(crate) fn check(&self, at: &Path<'_>, s: &mut Sink) {
        let (kp, ki, kd) = (at.key("kp"), at.key("ki"), at.key("kd"));
        s.opt_minimum(&kp, self.kp, 0.0);
        s.opt_minimum(&ki, self.ki, 0.0);
        s.opt_minimum(&kd, self.kd, 0.0);
        if let Some(v) = self.kp.filter(|v| v.is_finite()) {
            s.core(&kp, Rule::KpPositive, check::positive("kp", v));
        }
        let limit = at.key("ki_limit");
        if let Some(v) = s.opt_num(&limit, self.ki_limit) {
            s.core(
                &limit,
                Rule::KiLimitPositive,
                check::positive("ki_limit", v),
            );
        }
        s.opt_num(&at.key("feedforward"), self.feedforward);
    }
}

/// Impedance (and admittance) parameters as a WIA command carries them.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct ImpedanceParams {
    /// Virtual stiffness, `>= 0`.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub stiffness: Option<f64>,
    /// Virtual damping, `>= 0`.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub damping: Option<f64>,
    /// Virtual inertia, `>= 0`.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub inertia: Option<f64>,
    /// Members the schema does not name, kept as given.
    #[serde(flatten)]
    pub extra: Map<String, Value>,
}

impl ImpedanceParams {
    /// The complete parameters, when all three are given.
    pub fn to_core(&self) -> Option<motorwire_core::ImpedanceParams> {
        Some(motorwire_core::ImpedanceParams {
            stiffness: self.stiffness?,
            damping: self.damping?,
            inertia: self.inertia?,
        })
    }

    fn check(&self, at: &Path<'_>, s: &mut Sink) {
        s.opt_minimum(&at.key("stiffness"), self.stiffness, 0.0);
        s.opt_minimum(&at.key("damping"), self.damping, 0.0);
        s.opt_minimum(&at.key("inertia"), self.inertia, 0.0);
    }
}

/// A command's filter configuration.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct FilterConfig {
    /// The filter type (`none`, `lowpass`, `notch`, `butterworth`).
    #[serde(
        rename = "type",
        default,
        with = "opt_filter_kind",
        skip_serializing_if = "Option::is_none"
    )]
    pub kind: Option<FilterKind>,
    /// Cut-off frequency (Hz), `> 0` when given.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub cutoff_frequency: Option<f64>,
    /// Filter order, `>= 1`.
    #[serde(
        default,
        deserialize_with = "opt_integer",
        skip_serializing_if = "Option::is_none"
    )]
    pub order: Option<i64>,
    /// Members the schema does not name, kept as given.
    #[serde(flatten)]
    pub extra: Map<String, Value>,
}

impl FilterConfig {
    fn check(&self, at: &Path<'_>, s: &mut Sink) {
        let fc = at.key("cutoff_frequency");
        if let Some(v) = s.opt_num(&fc, self.cutoff_frequency)
            && self.kind != Some(FilterKind::None)
        {
            s.positive(&fc, "cutoff_frequency", Some(v));
        }
        if let Some(order) = self.order {
            s.int_range(&at.key("order"), order, 1, None);
        }
    }
}

/// The safety limits a command carries for itself.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct CommandSafetyLimits {
    /// Lowest allowed position.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub min_position: Option<f64>,
    /// Highest allowed position.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub max_position: Option<f64>,
    /// Largest allowed speed (a magnitude).
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub max_velocity: Option<f64>,
    /// Largest allowed torque (a magnitude).
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub max_torque: Option<f64>,
    /// `true` asks for an emergency stop.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub emergency_stop: Option<bool>,
    /// Members the schema does not name, kept as given.
    #[serde(flatten)]
    pub extra: Map<String, Value>,
}

impl CommandSafetyLimits {
    fn check(&self, at: &Path<'_>, s: &mut Sink) {
        let min = at.key("min_position");
        let min_v = s.opt_num(&min, self.min_position);
        let max_v = s.opt_num(&at.key("max_position"), self.max_position);
        s.ordered(
            Rule::PositionLimitsOrder,
            (&min, "min_position", min_v),
            ("max_position", max_v),
        );
        let v = at.key("max_velocity");
        let v_v = s.opt_num(&v, self.max_velocity);
        s.non_negative(&v, "max_velocity", v_v);
        let t = at.key("max_torque");
        let t_v = s.opt_num(&t, self.max_torque);
        s.non_negative(&t, "max_torque", t_v);
    }
}

/// A borrowed view of what MotorCommand and AxisCommand share, so both are
/// checked by the same code.
pub(crate) struct CommandBody<'a> {
    pub(crate) control_mode: ControlMode,
    pub(crate) setpoint: f64,
    pub(crate) velocity_limit: Option<f64>,
    pub(crate) acceleration_limit: Option<f64>,
    pub(crate) torque_limit: Option<f64>,
    pub(crate) pid_gains: Option<&'a PidGains>,
    pub(crate) impedance_params: Option<&'a ImpedanceParams>,
    pub(crate) filter_config: Option<&'a FilterConfig>,
    pub(crate) safety_limits: Option<&'a CommandSafetyLimits>,
    pub(crate) priority: Option<i64>,
}

impl CommandBody<'_> {
    pub(crate) fn check(&self, at: &Path<'_>, s: &mut Sink) {
        let setpoint = at.key("setpoint");
        let setpoint_ok = s.num(&setpoint, self.setpoint);
        let vl = at.key("velocity_limit");
        s.opt_minimum(&vl, self.velocity_limit, 0.0);
        s.opt_minimum(&at.key("acceleration_limit"), self.acceleration_limit, 0.0);
        let tl = at.key("torque_limit");
        s.opt_minimum(&tl, self.torque_limit, 0.0);
        if let Some(p) = self.priority {
            s.int_range(&at.key("priority"), p, 0, Some(100));
        }
        if let Some(g) = self.pid_gains {
            g.check(&at.key("pid_gains"), s);
        }
        let ip = at.key("impedance_params");
        if let Some(p) = self.impedance_params {
            p.check(&ip, s);
        }
        if let Some(f) = self.filter_config {
            f.check(&at.key("filter_config"), s);
        }
        let sl = at.key("safety_limits");
        if let Some(l) = self.safety_limits {
            l.check(&sl, s);
        }

        // §10.2: modes that need parameters have them.
        if self.control_mode.needs_impedance_params() {
            match self.impedance_params {
                None => s.push(
                    &ip,
                    Rule::ModeParameters,
                    format!(
                        "{} control needs impedance_params (stiffness, damping, inertia)",
                        self.control_mode
                    ),
                ),
                Some(p) => {
                    for (name, v) in [
                        ("stiffness", p.stiffness),
                        ("damping", p.damping),
                        ("inertia", p.inertia),
                    ] {
                        if v.is_none() {
                            s.push(
                                &ip.key(name),
                                Rule::ModeParameters,
                                format!(
                                    "{} control needs impedance_params.{name}",
                                    self.control_mode
                                ),
                            );
                        }
                    }
                }
            }
        }

        // §10.3: the setpoint within the command's own limits for its mode.
        if setpoint_ok {
            self.check_setpoint(&setpoint, s);
        }

        // The command's own limits must not exceed its safety limits.
        if let Some(l) = self.safety_limits {
            for (path, name, value, limit_name, limit) in [
                (
                    &vl,
                    "velocity_limit",
                    self.velocity_limit,
                    "max_velocity",
                    l.max_velocity,
                ),
                (
                    &tl,
                    "torque_limit",
                    self.torque_limit,
                    "max_torque",
                    l.max_torque,
                ),
            ] {
                if let (Some(v), Some(lim)) = (value, limit)
                    && v.is_finite()
                    && lim.is_finite()
                    && v > lim
                {
                    s.push(
                        path,
                        Rule::LimitWithinSafety,
                        format!("{name} ({v}) exceeds safety_limits.{limit_name} ({lim})"),
                    );
                }
            }
        }
    }

    fn check_setpoint(&self, at: &Path<'_>, s: &mut Sink) {
        let sp = self.setpoint;
        let limits = self.safety_limits;
        let finite = |v: Option<f64>| v.filter(|v| v.is_finite());
        match self.control_mode {
            ControlMode::Position => {
                let min = finite(limits.and_then(|l| l.min_position));
                let max = finite(limits.and_then(|l| l.max_position));
                if let Some(min) = min.filter(|m| sp < *m) {
                    s.push(
                        at,
                        Rule::SetpointWithinLimits,
                        format!(
                            "position setpoint {sp} is below safety_limits.min_position ({min})"
                        ),
                    );
                }
                if let Some(max) = max.filter(|m| sp > *m) {
                    s.push(
                        at,
                        Rule::SetpointWithinLimits,
                        format!(
                            "position setpoint {sp} is above safety_limits.max_position ({max})"
                        ),
                    );
                }
            }
            ControlMode::Velocity => {
                let candidates = [
                    (
                        "safety_limits.max_velocity",
                        finite(limits.and_then(|l| l.max_velocity)),
                    ),
                    ("velocity_limit", finite(self.velocity_limit)),
                ];
                Self::magnitude(at, s, "velocity", sp, &candidates);
            }
            ControlMode::Torque => {
                let candidates = [
                    (
                        "safety_limits.max_torque",
                        finite(limits.and_then(|l| l.max_torque)),
                    ),
                    ("torque_limit", finite(self.torque_limit)),
                ];
                Self::magnitude(at, s, "torque", sp, &candidates);
            }
            _ => {}
        }
    }

    fn magnitude(at: &Path<'_>, s: &mut Sink, what: &str, sp: f64, limits: &[(&str, Option<f64>)]) {
        for (name, limit) in limits {
            if let Some(limit) = limit.filter(|l| sp.abs() > *l) {
                s.push(
                    at,
                    Rule::SetpointWithinLimits,
                    format!("|{what} setpoint| {} exceeds {name} ({limit})", sp.abs()),
                );
            }
        }
    }
}

/// A command to one motor (WIA Phase 1 §3.1).
///
/// ```
/// use motorwire_wia::{MotorCommand, Validator};
///
/// let cmd: MotorCommand = Validator::new().parse(r#"{
///     "motor_id": "shoulder_pitch", "timestamp": 1704067200000,
///     "control_mode": "position", "setpoint": 45.0,
///     "pid_gains": {"kp": 50, "ki": 0.1, "kd": 2.5}
/// }"#)?;
/// assert_eq!(cmd.setpoint, 45.0);
/// # Ok::<(), motorwire_wia::Error>(())
/// ```
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MotorCommand {
    /// Motor identifier (`^[a-zA-Z0-9_-]+$`, at most 64 bytes).
    pub motor_id: String,
    /// Command time, Unix milliseconds.
    #[serde(serialize_with = "number")]
    pub timestamp: f64,
    /// The control mode.
    #[serde(with = "control_mode")]
    pub control_mode: ControlMode,
    /// Target value in the mode's unit (deg or rad, deg/s or rad/s, Nm).
    pub setpoint: f64,
    /// Maximum velocity (deg/s or rad/s), `>= 0`.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub velocity_limit: Option<f64>,
    /// Maximum acceleration (deg/s² or rad/s²), `>= 0`.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub acceleration_limit: Option<f64>,
    /// Maximum torque (Nm), `>= 0`.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub torque_limit: Option<f64>,
    /// PID gains to apply.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub pid_gains: Option<PidGains>,
    /// Impedance parameters (needed by impedance and admittance control).
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub impedance_params: Option<ImpedanceParams>,
    /// Filter configuration.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub filter_config: Option<FilterConfig>,
    /// The command's own safety limits.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub safety_limits: Option<CommandSafetyLimits>,
    /// Priority, 0 (lowest) to 100 (highest).
    #[serde(
        default,
        deserialize_with = "opt_integer",
        skip_serializing_if = "Option::is_none"
    )]
    pub priority: Option<i64>,
    /// Additional metadata, kept as given.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub metadata: Option<Map<String, Value>>,
    /// Members the schema does not name, kept as given.
    #[serde(flatten)]
    pub extra: Map<String, Value>,
}

impl MotorCommand {
    /// A command of its required members alone: every optional member is
    /// absent, and the `with_*` setters give those a command needs.
    /// `timestamp` is Unix milliseconds, read from the caller's clock (this
    /// crate reads none).
    ///
    /// Nothing is checked or clamped here: a NaN setpoint or a malformed
    /// id makes a command all the same, which [`Validator::check`] (and
    /// [`Validator::to_json`], and the bridge) refuses as it refuses the
    /// same JSON.
    ///
    /// ```
    /// use motorwire_wia::core::ControlMode;
    /// use motorwire_wia::{CommandSafetyLimits, MotorCommand, Validator};
    ///
    /// let cmd = MotorCommand::new("shoulder_pitch", 1_704_067_200_000.0, ControlMode::Position, 45.0)
    ///     .with_velocity_limit(60.0)
    ///     .with_acceleration_limit(120.0)
    ///     .with_safety_limits(CommandSafetyLimits {
    ///         min_position: Some(-90.0),
    ///         max_position: Some(90.0),
    ///         ..CommandSafetyLimits::default()
    ///     });
    /// assert!(Validator::new().check(&cmd).is_empty());
    /// assert_eq!(
    ///     serde_json::to_string(&cmd)?,
    ///     r#"{"motor_id":"shoulder_pitch","timestamp":1704067200000,"control_mode":"position","setpoint":45.0,"velocity_limit":60.0,"acceleration_limit":120.0,"safety_limits":{"min_position":-90.0,"max_position":90.0}}"#
    /// );
    /// # Ok::<(), serde_json::Error>(())
    /// ```
    ///
    /// [`Validator::check`]: crate::Validator::check
    /// [`Validator::to_json`]: crate::Validator::to_json
    #[must_use]
    pub fn new(
        motor_id: impl Into<String>,
        timestamp: f64,
        control_mode: ControlMode,
        setpoint: f64,
    ) -> Self {
        Self {
            motor_id: motor_id.into(),
            timestamp,
            control_mode,
            setpoint,
            velocity_limit: None,
            acceleration_limit: None,
            torque_limit: None,
            pid_gains: None,
            impedance_params: None,
            filter_config: None,
            safety_limits: None,
            priority: None,
            metadata: None,
            extra: Map::new(),
        }
    }

    pub(crate) fn body(&self) -> CommandBody<'_> {
        CommandBody {
            control_mode: self.control_mode,
            setpoint: self.setpoint,
            velocity_limit: self.velocity_limit,
            acceleration_limit: self.acceleration_limit,
            torque_limit: self.torque_limit,
            pid_gains: self.pid_gains.as_ref(),
            impedance_params: self.impedance_params.as_ref(),
            filter_config: self.filter_config.as_ref(),
            safety_limits: self.safety_limits.as_ref(),
            priority: self.priority,
        }
    }

    pub(crate) fn check(&self, s: &mut Sink) {
        let root = Path::ROOT;
        let id = root.key("motor_id");
        s.id_pattern(&id, &self.motor_id);
        s.motor_id(&id, &self.motor_id);
        let ts = root.key("timestamp");
        s.command_timestamp(&ts, self.timestamp);
        check_stream(&self.extra, s);
        self.body().check(&root, s);
    }
}

/// The optional members of a command, of a MotorCommand and of one axis of
/// a multi-axis command alike.
macro_rules! command_setters {
    ($ty:ident) => {
        with_setters!($ty {
            with_velocity_limit: velocity_limit: f64,
            with_acceleration_limit: acceleration_limit: f64,
            with_torque_limit: torque_limit: f64,
            with_pid_gains: pid_gains: PidGains,
            with_impedance_params: impedance_params: ImpedanceParams,
            with_filter_config: filter_config: FilterConfig,
            with_safety_limits: safety_limits: CommandSafetyLimits,
            with_priority: priority: i64,
        });
    };
}

command_setters!(MotorCommand);
command_setters!(AxisCommand);

/// motorwire's `stream` member, where a command carries it: a boolean.
fn check_stream(extra: &Map<String, Value>, s: &mut Sink) {
    if let Some(v) = extra.get(crate::members::STREAM)
        && !v.is_boolean()
    {
        s.push(
            &Path::ROOT.key(crate::members::STREAM),
            Rule::Stream,
            format!("stream is {v}: it is true (the command is a setpoint of a stream) or false"),
        );
    }
}

/// One motor's part of a [`MultiAxisCommand`]: a MotorCommand without its
/// own timestamp (the multi-axis command's timestamp applies).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AxisCommand {
    /// Motor identifier.
    pub motor_id: String,
    /// The control mode.
    #[serde(with = "control_mode")]
    pub control_mode: ControlMode,
    /// Target value in the mode's unit.
    pub setpoint: f64,
    /// Maximum velocity, `>= 0`.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub velocity_limit: Option<f64>,
    /// Maximum acceleration, `>= 0`.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub acceleration_limit: Option<f64>,
    /// Maximum torque (Nm), `>= 0`.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub torque_limit: Option<f64>,
    /// PID gains to apply.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub pid_gains: Option<PidGains>,
    /// Impedance parameters.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub impedance_params: Option<ImpedanceParams>,
    /// Filter configuration.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub filter_config: Option<FilterConfig>,
    /// The axis's own safety limits.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub safety_limits: Option<CommandSafetyLimits>,
    /// Priority, 0 to 100.
    #[serde(
        default,
        deserialize_with = "opt_integer",
        skip_serializing_if = "Option::is_none"
    )]
    pub priority: Option<i64>,
    /// Additional metadata, kept as given.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub metadata: Option<Map<String, Value>>,
    /// Members the schema does not name, kept as given.
    #[serde(flatten)]
    pub extra: Map<String, Value>,
}

impl AxisCommand {
    /// One motor's part of a multi-axis command, of its required members
    /// alone (it has no timestamp of its own); the `with_*` setters give
    /// the optional ones. Nothing is checked or clamped here: the
    /// [`Validator`](crate::Validator) judges the multi-axis command that
    /// holds it.
    ///
    /// ```
    /// use motorwire_wia::core::ControlMode;
    /// use motorwire_wia::{AxisCommand, MultiAxisCommand, Validator};
    ///
    /// let axis = AxisCommand::new("elbow", ControlMode::Velocity, 15.0).with_torque_limit(8.0);
    /// let cmd = MultiAxisCommand::new("cmd_1", 1_704_067_200_000.0, vec![axis]);
    /// assert!(Validator::new().check(&cmd).is_empty());
    /// assert_eq!(
    ///     serde_json::to_string(&cmd.motors[0])?,
    ///     r#"{"motor_id":"elbow","control_mode":"velocity","setpoint":15.0,"torque_limit":8.0}"#
    /// );
    /// # Ok::<(), serde_json::Error>(())
    /// ```
    #[must_use]
    pub fn new(motor_id: impl Into<String>, control_mode: ControlMode, setpoint: f64) -> Self {
        Self {
            motor_id: motor_id.into(),
            control_mode,
            setpoint,
            velocity_limit: None,
            acceleration_limit: None,
            torque_limit: None,
            pid_gains: None,
            impedance_params: None,
            filter_config: None,
            safety_limits: None,
            priority: None,
            metadata: None,
            extra: Map::new(),
        }
    }

    pub(crate) fn body(&self) -> CommandBody<'_> {
        CommandBody {
            control_mode: self.control_mode,
            setpoint: self.setpoint,
            velocity_limit: self.velocity_limit,
            acceleration_limit: self.acceleration_limit,
            torque_limit: self.torque_limit,
            pid_gains: self.pid_gains.as_ref(),
            impedance_params: self.impedance_params.as_ref(),
            filter_config: self.filter_config.as_ref(),
            safety_limits: self.safety_limits.as_ref(),
            priority: self.priority,
        }
    }

    /// This axis as a stand-alone [`MotorCommand`] at `timestamp`.
    pub fn to_motor_command(&self, timestamp: f64) -> MotorCommand {
        MotorCommand {
            motor_id: self.motor_id.clone(),
            timestamp,
            control_mode: self.control_mode,
            setpoint: self.setpoint,
            velocity_limit: self.velocity_limit,
            acceleration_limit: self.acceleration_limit,
            torque_limit: self.torque_limit,
            pid_gains: self.pid_gains.clone(),
            impedance_params: self.impedance_params.clone(),
            filter_config: self.filter_config.clone(),
            safety_limits: self.safety_limits.clone(),
            priority: self.priority,
            metadata: self.metadata.clone(),
            extra: self.extra.clone(),
        }
    }
}

string_enum! {
    /// How the motors of a multi-axis command are synchronised.
    pub enum SyncMode {
        /// All motors start together and finish together.
        Simultaneous = "simultaneous",
        /// One motor after another, in array order.
        Sequential = "sequential",
        /// Each motor moves on its own limits.
        Independent = "independent",
    }
}

string_enum! {
    /// How a coordinated move is interpolated.
    pub enum CoordinationType {
        /// A straight line in joint space.
        LinearInterpolation = "linear_interpolation",
        /// Each axis on its own profile.
        Independent = "independent",
    }
}

string_enum! {
    /// The acceleration profile of a coordinated move.
    pub enum AccelerationProfile {
        /// Acceleration steps (constant acceleration phases).
        Trapezoidal = "trapezoidal",
        /// Jerk-limited.
        SCurve = "s_curve",
    }
}

/// Coordination of a multi-axis move.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Coordination {
    /// Interpolation type.
    #[serde(
        rename = "type",
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub kind: Option<CoordinationType>,
    /// Duration of the whole move (ms), `> 0`.
    #[serde(
        default,
        deserialize_with = "some",
        serialize_with = "crate::serde_util::opt_number",
        skip_serializing_if = "Option::is_none"
    )]
    pub total_duration_ms: Option<f64>,
    /// Acceleration profile.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub acceleration_profile: Option<AccelerationProfile>,
    /// Members the schema does not name, kept as given.
    #[serde(flatten)]
    pub extra: Map<String, Value>,
}

/// Coordinated control of several motors (WIA Phase 1 §3.2).
///
/// ```
/// use motorwire_wia::{MultiAxisCommand, SyncMode, Validator};
///
/// let cmd: MultiAxisCommand = Validator::new().parse(r#"{
///     "command_id": "cmd_1", "timestamp": 1704067200000, "sync_mode": "simultaneous",
///     "motors": [{"motor_id": "elbow", "control_mode": "position", "setpoint": 90.0}]
/// }"#)?;
/// assert_eq!(cmd.sync_mode, Some(SyncMode::Simultaneous));
/// # Ok::<(), motorwire_wia::Error>(())
/// ```
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MultiAxisCommand {
    /// Command identifier (non-empty).
    pub command_id: String,
    /// Command time, Unix milliseconds.
    #[serde(serialize_with = "number")]
    pub timestamp: f64,
    /// Synchronisation of the motors.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub sync_mode: Option<SyncMode>,
    /// One entry per motor (at least one; each motor at most once).
    pub motors: Vec<AxisCommand>,
    /// Coordination of the move.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub coordination: Option<Coordination>,
    /// Additional metadata, kept as given.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub metadata: Option<Map<String, Value>>,
    /// Members the schema does not name, kept as given.
    #[serde(flatten)]
    pub extra: Map<String, Value>,
}

with_setters!(MultiAxisCommand {
    with_sync_mode: sync_mode: SyncMode,
    with_coordination: coordination: Coordination,
});

impl MultiAxisCommand {
    /// A multi-axis command of its required members alone: `command_id`,
    /// `timestamp` (Unix milliseconds, from the caller's clock) and one
    /// [`AxisCommand`] a motor; the `with_*` setters give the optional
    /// members. Nothing is checked here (no motors, or one motor twice,
    /// makes a command all the same): [`Validator::check`] says what a
    /// value breaks.
    ///
    /// ```
    /// use motorwire_wia::core::ControlMode;
    /// use motorwire_wia::{AxisCommand, MultiAxisCommand, SyncMode, Validator};
    ///
    /// let cmd = MultiAxisCommand::new(
    ///     "cmd_1",
    ///     1_704_067_200_000.0,
    ///     vec![
    ///         AxisCommand::new("shoulder_pitch", ControlMode::Position, 45.0),
    ///         AxisCommand::new("elbow", ControlMode::Position, 90.0).with_velocity_limit(30.0),
    ///     ],
    /// )
    /// .with_sync_mode(SyncMode::Simultaneous);
    /// assert!(Validator::new().check(&cmd).is_empty());
    /// assert_eq!(
    ///     serde_json::to_string(&cmd)?,
    ///     r#"{"command_id":"cmd_1","timestamp":1704067200000,"sync_mode":"simultaneous","motors":[{"motor_id":"shoulder_pitch","control_mode":"position","setpoint":45.0},{"motor_id":"elbow","control_mode":"position","setpoint":90.0,"velocity_limit":30.0}]}"#
    /// );
    /// # Ok::<(), serde_json::Error>(())
    /// ```
    ///
    /// [`Validator::check`]: crate::Validator::check
    #[must_use]
    pub fn new(command_id: impl Into<String>, timestamp: f64, motors: Vec<AxisCommand>) -> Self {
        Self {
            command_id: command_id.into(),
            timestamp,
            sync_mode: None,
            motors,
            coordination: None,
            metadata: None,
            extra: Map::new(),
        }
    }

    pub(crate) fn check(&self, s: &mut Sink) {
        let root = Path::ROOT;
        if self.command_id.is_empty() {
            s.push(
                &root.key("command_id"),
                Rule::MinLength,
                "\"\" is shorter than 1 character".to_owned(),
            );
        }
        let ts = root.key("timestamp");
        s.command_timestamp(&ts, self.timestamp);
        check_stream(&self.extra, s);
        if self.extra.get(crate::members::STREAM) == Some(&Value::Bool(true))
            && self.sync_mode == Some(SyncMode::Sequential)
        {
            s.push(
                &root.key("sync_mode"),
                Rule::Stream,
                crate::members::STREAM_SEQUENTIAL.to_owned(),
            );
        }
        let motors = root.key("motors");
        s.min_items(&motors, self.motors.len(), 1);
        // Where each motor first appears: one pass, not a search per axis
        // (8,192 axes fit in the default document size).
        let mut first_at: HashMap<&str, usize> = HashMap::with_capacity(self.motors.len());
        for (i, axis) in self.motors.iter().enumerate() {
            let at = motors.index(i);
            let id = at.key("motor_id");
            s.id_pattern(&id, &axis.motor_id);
            s.motor_id(&id, &axis.motor_id);
            let first = *first_at.entry(axis.motor_id.as_str()).or_insert(i);
            if first < i {
                s.push(
                    &id,
                    Rule::DuplicateMotor,
                    format!(
                        "motor {:?} already appears at /motors/{first}",
                        axis.motor_id
                    ),
                );
            }
            axis.body().check(&at, s);
        }
        if let Some(c) = &self.coordination
            && let Some(d) = c.total_duration_ms
        {
            s.exclusive_minimum(&root.key("coordination").key("total_duration_ms"), d, 0.0);
        }
    }
}
