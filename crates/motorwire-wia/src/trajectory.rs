//! Trajectory (WIA Phase 1 §5).
//!
//! Units, which the document leaves mixed: a waypoint's `time` is in
//! **seconds** from the trajectory's start, `timing.start_time` is Unix
//! **milliseconds**, and `timing.total_duration` is **milliseconds** (the
//! document's example: waypoints to 6.0 s, total_duration 6000). The
//! `trajectory-duration` rule requires
//! `|total_duration - 1000 * last_waypoint.time| <= 1 ms`.

use serde::{Deserialize, Serialize};
use serde_json::{Map, Value};

use crate::Rule;
use crate::check::Sink;
use crate::path::Path;
use crate::serde_util::{opt_integer, opt_number, some, string_enum};
use crate::setters::with_setters;

/// Tolerance of the `trajectory-duration` rule, in milliseconds.
pub const DURATION_TOLERANCE_MS: f64 = 1.0;

string_enum! {
    /// The kind of trajectory.
    pub enum TrajectoryType {
        /// From one point to another.
        PointToPoint = "point_to_point",
        /// Continuous path.
        Continuous = "continuous",
        /// Repeating path.
        Periodic = "periodic",
        /// Spline through the waypoints.
        Spline = "spline",
    }
}

string_enum! {
    /// How positions between waypoints are interpolated.
    pub enum Interpolation {
        /// Linear.
        Linear = "linear",
        /// Cubic polynomial.
        Cubic = "cubic",
        /// Quintic polynomial.
        Quintic = "quintic",
        /// Trapezoidal velocity.
        Trapezoidal = "trapezoidal",
    }
}

/// One waypoint.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Waypoint {
    /// Position (deg or rad).
    pub position: f64,
    /// Velocity at the waypoint.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub velocity: Option<f64>,
    /// Acceleration at the waypoint.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub acceleration: Option<f64>,
    /// Time from the trajectory's start, in seconds.
    pub time: f64,
    /// Torque at the waypoint (Nm).
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub torque: Option<f64>,
    /// Members the schema does not name, kept as given.
    #[serde(flatten)]
    pub extra: Map<String, Value>,
}

impl Waypoint {
    /// A waypoint of its required members alone: `position` and `time`
    /// (seconds from the trajectory's start); the `with_*` setters give
    /// the velocity, acceleration and torque at it. Nothing is checked
    /// here: the [`Validator`](crate::Validator) judges the trajectory
    /// that holds it.
    ///
    /// ```
    /// use motorwire_wia::Waypoint;
    ///
    /// let w = Waypoint::new(45.0, 1.5).with_velocity(0.0);
    /// assert_eq!(serde_json::to_string(&w)?, r#"{"position":45.0,"velocity":0.0,"time":1.5}"#);
    /// # Ok::<(), serde_json::Error>(())
    /// ```
    #[must_use]
    pub fn new(position: f64, time: f64) -> Self {
        Self {
            position,
            velocity: None,
            acceleration: None,
            time,
            torque: None,
            extra: Map::new(),
        }
    }
}

with_setters!(Waypoint {
    with_velocity: velocity: f64,
    with_acceleration: acceleration: f64,
    with_torque: torque: f64,
});

/// When the trajectory runs.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Timing {
    /// Start, Unix milliseconds.
    #[serde(
        default,
        deserialize_with = "some",
        serialize_with = "opt_number",
        skip_serializing_if = "Option::is_none"
    )]
    pub start_time: Option<f64>,
    /// Total duration, milliseconds.
    #[serde(
        default,
        deserialize_with = "some",
        serialize_with = "opt_number",
        skip_serializing_if = "Option::is_none"
    )]
    pub total_duration: Option<f64>,
    /// Interpolation between waypoints.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub interpolation: Option<Interpolation>,
    /// Members the schema does not name, kept as given.
    #[serde(flatten)]
    pub extra: Map<String, Value>,
}

/// Limits the trajectory must respect.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct TrajectoryConstraints {
    /// Maximum speed.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub max_velocity: Option<f64>,
    /// Maximum acceleration magnitude.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub max_acceleration: Option<f64>,
    /// Maximum jerk magnitude.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub max_jerk: Option<f64>,
    /// Maximum torque magnitude (Nm).
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub max_torque: Option<f64>,
    /// Members the schema does not name, kept as given.
    #[serde(flatten)]
    pub extra: Map<String, Value>,
}

/// Repetition of the trajectory.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct LoopConfig {
    /// Whether the trajectory repeats.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub enabled: Option<bool>,
    /// How many times it runs; -1 is forever.
    #[serde(
        default,
        deserialize_with = "opt_integer",
        skip_serializing_if = "Option::is_none"
    )]
    pub count: Option<i64>,
    /// Whether every other run goes backwards.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub reverse_on_loop: Option<bool>,
    /// Members the schema does not name, kept as given.
    #[serde(flatten)]
    pub extra: Map<String, Value>,
}

/// A trajectory for one motor or motor group (WIA Phase 1 §5).
///
/// ```
/// use motorwire_wia::{Trajectory, Validator};
///
/// let t: Trajectory = Validator::new().parse(r#"{
///     "trajectory_id": "t1", "motor_id": "elbow",
///     "waypoints": [{"position": 0, "time": 0}, {"position": 10, "time": 1.0}],
///     "timing": {"total_duration": 1000}
/// }"#)?;
/// assert_eq!(t.waypoints.len(), 2);
/// # Ok::<(), motorwire_wia::Error>(())
/// ```
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Trajectory {
    /// Trajectory identifier.
    pub trajectory_id: String,
    /// Target motor or motor group.
    pub motor_id: String,
    /// Trajectory type.
    #[serde(
        rename = "type",
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub kind: Option<TrajectoryType>,
    /// At least two waypoints, times strictly increasing.
    pub waypoints: Vec<Waypoint>,
    /// Timing.
    pub timing: Timing,
    /// Constraints every waypoint and segment must respect.
    #[serde(
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub constraints: Option<TrajectoryConstraints>,
    /// Repetition.
    #[serde(
        rename = "loop",
        default,
        deserialize_with = "some",
        skip_serializing_if = "Option::is_none"
    )]
    pub loop_config: Option<LoopConfig>,
    /// Members the schema does not name, kept as given.
    #[serde(flatten)]
    pub extra: Map<String, Value>,
}

with_setters!(Trajectory {
    with_kind: kind: TrajectoryType,
    with_constraints: constraints: TrajectoryConstraints,
    with_loop_config: loop_config: LoopConfig,
});

impl Trajectory {
    /// A trajectory of its required members alone: `trajectory_id`,
    /// `motor_id`, the waypoints and the timing (a required member whose
    /// own members are all optional: `Timing::default()` is `{}`); the
    /// `with_*` setters give the optional members. Nothing is checked
    /// here (one waypoint, or times that go back, make a trajectory all
    /// the same): [`Validator::check`] says what a value breaks.
    ///
    /// ```
    /// use motorwire_wia::{Timing, Trajectory, TrajectoryConstraints, Validator, Waypoint};
    ///
    /// let t = Trajectory::new(
    ///     "t1",
    ///     "elbow",
    ///     vec![Waypoint::new(0.0, 0.0), Waypoint::new(10.0, 1.0)],
    ///     Timing { total_duration: Some(1000.0), ..Timing::default() },
    /// )
    /// .with_constraints(TrajectoryConstraints { max_velocity: Some(20.0), ..TrajectoryConstraints::default() });
    /// assert!(Validator::new().check(&t).is_empty());
    /// assert_eq!(
    ///     serde_json::to_string(&t)?,
    ///     r#"{"trajectory_id":"t1","motor_id":"elbow","waypoints":[{"position":0.0,"time":0.0},{"position":10.0,"time":1.0}],"timing":{"total_duration":1000},"constraints":{"max_velocity":20.0}}"#
    /// );
    /// # Ok::<(), serde_json::Error>(())
    /// ```
    ///
    /// [`Validator::check`]: crate::Validator::check
    #[must_use]
    pub fn new(
        trajectory_id: impl Into<String>,
        motor_id: impl Into<String>,
        waypoints: Vec<Waypoint>,
        timing: Timing,
    ) -> Self {
        Self {
            trajectory_id: trajectory_id.into(),
            motor_id: motor_id.into(),
            kind: None,
            waypoints,
            timing,
            constraints: None,
            loop_config: None,
            extra: Map::new(),
        }
    }

    pub(crate) fn check(&self, s: &mut Sink) {
        let root = Path::ROOT;
        s.motor_id(&root.key("motor_id"), &self.motor_id);
        let wps = root.key("waypoints");
        s.min_items(&wps, self.waypoints.len(), 2);

        let c = self.constraints.as_ref();
        let cp = root.key("constraints");
        let limit = |name: &'static str, v: Option<f64>, s: &mut Sink| {
            let at = cp.key(name);
            let v = s.opt_num(&at, v);
            s.positive(&at, name, v);
            v.filter(|v| *v > 0.0)
        };
        let max_v = limit("max_velocity", c.and_then(|c| c.max_velocity), s);
        let max_a = limit("max_acceleration", c.and_then(|c| c.max_acceleration), s);
        limit("max_jerk", c.and_then(|c| c.max_jerk), s);
        let max_t = limit("max_torque", c.and_then(|c| c.max_torque), s);

        let mut prev: Option<(f64, f64)> = None; // (time, position) of the last finite waypoint
        for (i, w) in self.waypoints.iter().enumerate() {
            let at = wps.index(i);
            let time = at.key("time");
            let t_ok = s.num(&time, w.time);
            let p_ok = s.num(&at.key("position"), w.position);
            if t_ok && i == 0 && w.time < 0.0 {
                s.push(
                    &time,
                    Rule::WaypointTimeOrder,
                    format!(
                        "the first waypoint's time ({}) is before the start (0 s)",
                        w.time
                    ),
                );
            }
            if let (true, Some((pt, pp))) = (t_ok, prev) {
                if w.time <= pt {
                    s.push(
                        &time,
                        Rule::WaypointTimeOrder,
                        format!(
                            "time {} s is not after the previous waypoint's {} s",
                            w.time, pt
                        ),
                    );
                } else if let (true, Some(vmax)) = (p_ok, max_v) {
                    let speed = (w.position - pp).abs() / (w.time - pt);
                    if speed > vmax {
                        s.push(
                            &at.key("position"),
                            Rule::SegmentVelocity,
                            format!(
                                "reaching {} from {} in {} s needs {speed} on average, above max_velocity ({vmax})",
                                w.position,
                                pp,
                                w.time - pt
                            ),
                        );
                    }
                }
            }
            for (name, v, max, rule) in [
                ("velocity", w.velocity, max_v, Rule::WaypointVelocity),
                (
                    "acceleration",
                    w.acceleration,
                    max_a,
                    Rule::WaypointAcceleration,
                ),
                ("torque", w.torque, max_t, Rule::WaypointTorque),
            ] {
                let p = at.key(name);
                if let (Some(v), Some(max)) = (s.opt_num(&p, v), max)
                    && v.abs() > max
                {
                    s.push(
                        &p,
                        rule,
                        format!(
                            "|{name}| {} exceeds constraints.max_{name} ({max})",
                            v.abs()
                        ),
                    );
                }
            }
            if t_ok && p_ok {
                prev = Some((w.time, w.position));
            }
        }

        let timing = root.key("timing");
        if let Some(t) = s.opt_num(&timing.key("start_time"), self.timing.start_time) {
            s.timestamp(&timing.key("start_time"), t);
        }
        let td = timing.key("total_duration");
        if let Some(d) = s.opt_num(&td, self.timing.total_duration) {
            s.positive(&td, "total_duration", Some(d));
            let last = self
                .waypoints
                .last()
                .map(|w| w.time)
                .filter(|t| t.is_finite());
            if let Some(last) = last.filter(|_| self.waypoints.len() >= 2) {
                let expected = last * 1000.0;
                if (d - expected).abs() > DURATION_TOLERANCE_MS {
                    s.push(
                        &td,
                        Rule::TrajectoryDuration,
                        format!(
                            "total_duration {d} ms disagrees with the last waypoint at {last} s \
                             ({expected} ms); waypoint times are seconds, total_duration is milliseconds"
                        ),
                    );
                }
            }
        }

        if let Some(l) = &self.loop_config
            && let Some(count) = l.count
        {
            let lp = root.key("loop");
            let at = lp.key("count");
            s.int_range(&at, count, -1, None);
            if l.enabled == Some(true) && count == 0 {
                s.push(
                    &at,
                    Rule::LoopCount,
                    "an enabled loop runs -1 (forever) or at least 1 times, not 0".to_owned(),
                );
            }
        }
    }
}
