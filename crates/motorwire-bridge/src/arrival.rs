//! Watching a motion line's moves until they arrive, or until it is clear
//! they will not.

use std::time::Duration;

use motorwire_translate::AngleUnit;

use crate::device::DeviceId;
use crate::job::LineMeta;
use crate::output::{ArrivalLine, Label, MotorArrival};

/// A motor's speed (degrees per second) below which it counts as at rest,
/// per degree of its arrival tolerance: 0.1° of tolerance allows 1°/s.
const REST_PER_TOLERANCE: f64 = 10.0;

/// One motor of a watched line.
#[derive(Debug, Clone)]
pub(crate) struct WatchAxis {
    pub(crate) joint: DeviceId,
    pub(crate) motor: String,
    /// Degrees.
    pub(crate) target: f64,
    /// Degrees.
    pub(crate) tolerance: f64,
    /// The motor's unit.
    pub(crate) unit: AngleUnit,
    /// When it arrived, and how far off it was then (degrees).
    pub(crate) arrived: Option<(Duration, f64)>,
    /// How far off it was last reported (degrees).
    pub(crate) last_error: Option<f64>,
}

/// A motion line watched for arrival.
#[derive(Debug, Clone)]
pub(crate) struct Watch {
    pub(crate) line: LineMeta,
    /// When its result was given.
    pub(crate) since: Duration,
    /// After this it has not arrived (the planned end and a margin).
    pub(crate) deadline: Duration,
    pub(crate) axes: Vec<WatchAxis>,
}

impl Watch {
    /// Takes joint `joint`'s position and velocity (degrees) at `now`;
    /// whether the whole line has arrived.
    pub(crate) fn observe(
        &mut self,
        joint: DeviceId,
        position: f64,
        velocity: f64,
        now: Duration,
    ) -> bool {
        for a in self.axes.iter_mut().filter(|a| a.joint == joint) {
            let error = (position - a.target).abs();
            a.last_error = Some(error);
            if a.arrived.is_none()
                && error <= a.tolerance
                && velocity.abs() <= a.tolerance * REST_PER_TOLERANCE
            {
                a.arrived = Some((now, error));
            }
        }
        self.axes.iter().all(|a| a.arrived.is_some())
    }

    /// Whether it watches joint `joint` for a move not yet arrived.
    pub(crate) fn waits_on(&self, joint: DeviceId) -> bool {
        self.axes
            .iter()
            .any(|a| a.joint == joint && a.arrived.is_none())
    }

    /// Its completion line: arrived, or not with `reason`.
    pub(crate) fn verdict(self, now: Duration, reason: Option<String>) -> ArrivalLine {
        let since = self.since;
        let ms =
            |t: Duration| u64::try_from(t.saturating_sub(since).as_millis()).unwrap_or(u64::MAX);
        // The watch ends here: its names move into the line.
        let (motor_id, command_id) = match self.line.label {
            Some(Label::Motor(v)) => (Some(v), None),
            Some(Label::Command(v) | Label::Orion(v)) => (None, Some(v)),
            None => (None, None),
        };
        // A new vector, not the axes' own reused in place: that one is
        // larger and was shrunk by a `realloc` (about 460 instructions a
        // line, by callgrind) where a fresh allocation costs some 30.
        let mut motors = Vec::with_capacity(self.axes.len());
        motors.extend(self.axes.into_iter().map(|a| {
            MotorArrival {
                arrived: a.arrived.is_some(),
                target: short(a.unit.from_degrees(a.target)),
                error: a
                    .arrived
                    .map(|(_, e)| e)
                    .or(a.last_error)
                    .map(|e| short(a.unit.from_degrees(e))),
                after_ms: a.arrived.map(|(t, _)| ms(t)),
                motor_id: a.motor,
            }
        }));
        ArrivalLine {
            arrived: reason.is_none(),
            line: self.line.number,
            motor_id,
            command_id,
            reason,
            after_ms: ms(now),
            motors,
        }
    }
}

/// `v` as the nearest f32 (a report, not a measurement to the last bit;
/// JSON writes an f32 as its shortest decimal).
#[allow(clippy::cast_possible_truncation)]
const fn short(v: f64) -> f32 {
    v as f32
}
