use core::fmt;

/// Everything the planner refuses. Fields are named as in
/// [`Request`](crate::Request); values are given as `f64` whatever the
/// float type planned in.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub enum PlanError {
    /// An input is NaN or infinite.
    NonFinite {
        /// The field.
        field: &'static str,
    },
    /// A field the chosen profile needs is absent (`max_jerk` for an S-curve).
    Missing {
        /// The field.
        field: &'static str,
    },
    /// A limit is zero or negative.
    NotPositive {
        /// The field.
        field: &'static str,
        /// The value given.
        value: f64,
    },
    /// The target velocity is faster than `max_velocity`: the move could
    /// never end within its limits.
    TargetVelocityTooHigh {
        /// |target_velocity|.
        value: f64,
        /// max_velocity.
        max: f64,
    },
    /// The target cannot be reached without passing it, and the request
    /// forbids overshoot.
    OvershootForbidden {
        /// How far past the target the time-optimal profile would go.
        overshoot: f64,
    },
    /// The requested duration is shorter than the fastest profile.
    DurationTooShort {
        /// The duration asked for (s).
        requested: f64,
        /// The time-optimal duration (s).
        minimum: f64,
    },
    /// The requested duration lies in an interval no profile can take:
    /// longer than the longest profile that cruises towards the target, and
    /// shorter than the shortest that passes the target and comes back.
    DurationBlocked {
        /// The duration asked for (s).
        requested: f64,
        /// The blocked interval's start (s).
        from: f64,
        /// The blocked interval's end: the shortest feasible duration above it (s).
        to: f64,
    },
    /// The exact-duration search did not find a profile of the requested
    /// duration. Its grid scan should always find one (none was missed in
    /// the tests' random sweeps), but the result is checked rather than
    /// trusted: nothing is returned rather than a profile of another
    /// duration.
    DurationNotFound {
        /// The duration asked for (s).
        requested: f64,
    },
    /// A multi-axis call got a different number of output slots than requests.
    AxisCountMismatch {
        /// How many requests.
        requests: usize,
        /// How many output profiles.
        profiles: usize,
    },
    /// Phase synchronization is for rest-to-rest moves; this axis has a
    /// non-zero start or target velocity.
    NotAtRest {
        /// The axis's index in the request slice.
        axis: usize,
    },
    /// Exact-duration planning of a jerk-limited move starts from zero
    /// acceleration; this request starts from another
    /// ([`Request::start_acceleration`](crate::Request::start_acceleration)).
    /// [`plan`](crate::plan) plans it from there.
    StartAcceleration {
        /// The start acceleration given.
        value: f64,
    },
    /// The numbers are finite but so extreme that the profile's durations,
    /// positions or velocities would not be, at some instant (for example a
    /// distance of 1e300 at 1e-300 per second).
    Unrepresentable,
}

impl fmt::Display for PlanError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Self::NonFinite { field } => write!(f, "{field} must be a finite number"),
            Self::Missing { field } => write!(f, "{field} is required for an S-curve profile"),
            Self::NotPositive { field, value } => write!(f, "{field} must be > 0 (got {value})"),
            Self::TargetVelocityTooHigh { value, max } => {
                write!(f, "|target_velocity| {value} exceeds max_velocity {max}")
            }
            Self::OvershootForbidden { overshoot } => write!(
                f,
                "the target cannot be reached without passing it by {overshoot}, and overshoot is forbidden"
            ),
            Self::DurationTooShort { requested, minimum } => write!(
                f,
                "a duration of {requested} s is shorter than the fastest profile, {minimum} s"
            ),
            Self::DurationBlocked {
                requested,
                from,
                to,
            } => write!(
                f,
                "no profile takes {requested} s: durations between {from} s and {to} s are infeasible for this move"
            ),
            Self::DurationNotFound { requested } => {
                write!(f, "no profile of {requested} s was found for this move")
            }
            Self::AxisCountMismatch { requests, profiles } => write!(
                f,
                "{requests} request(s) but room for {profiles} profile(s)"
            ),
            Self::NotAtRest { axis } => write!(
                f,
                "axis {axis} does not start and end at rest; phase synchronization needs rest-to-rest moves"
            ),
            Self::StartAcceleration { value } => write!(
                f,
                "a jerk-limited move of a given duration starts from zero acceleration, not {value}"
            ),
            Self::Unrepresentable => {
                f.write_str("the profile's durations or positions are not finite numbers")
            }
        }
    }
}

impl core::error::Error for PlanError {}
