//! Device feedback back to WIA MotorFeedback.

use motorwire_irpc::{LifecycleState, Payload};
use motorwire_orion::Quantity;
use motorwire_wia::{MotorFeedback, MotorStatus};

use crate::report::{LossKind, Report, Translated};
use crate::{BusMap, MappedMotor};

/// A feedback message that cannot become WIA feedback.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum FeedbackError {
    /// No motor of the bus map is at that address.
    #[error("no motor of the bus map is {address}")]
    Unmapped {
        /// The address (`iRPC node 0x12`, `Orion TRM`).
        address: String,
    },
    /// The payload is not feedback.
    #[error("{payload} is not feedback (Encoder, JointStatus or TelemetryStream)")]
    NotFeedback {
        /// The payload's name.
        payload: &'static str,
    },
    /// A reported value is NaN or infinite.
    #[error("{motor}: the reported {field} is not a finite number")]
    NonFinite {
        /// The motor.
        motor: String,
        /// The field.
        field: &'static str,
    },
}

/// A feedback with nothing known yet: zero position, velocity and torque,
/// every status flag absent (unknown).
fn blank(motor: &MappedMotor, timestamp_ms: f64) -> MotorFeedback {
    MotorFeedback::new(
        motor.name.clone(),
        timestamp_ms,
        0.0,
        0.0,
        0.0,
        MotorStatus::default(),
    )
}

fn finite(motor: &str, field: &'static str, v: f32) -> Result<f64, FeedbackError> {
    let v = f64::from(v);
    if v.is_finite() {
        Ok(v)
    } else {
        Err(FeedbackError::NonFinite {
            motor: motor.to_owned(),
            field,
        })
    }
}

/// Updates a motor's WIA feedback with one iRPC message from `node`:
/// `Encoder` sets position and velocity, `TelemetryStream` those and
/// acceleration, torque, current (the q-axis current), voltage (the
/// magnitude of d and q), power, temperature, control effort (load) and
/// `in_motion`, `JointStatus` the status flags (`enabled` when Active,
/// `fault` in Error or with a non-zero error code, `calibrated` false while
/// calibrating). Positions are converted from degrees to the motor's unit.
/// `previous` is the motor's last feedback (`None`: fields no message has
/// reported yet are 0 and reported as filled).
///
/// # Errors
/// [`FeedbackError`] for an unmapped node, a payload that is not feedback,
/// or a non-finite value.
pub fn feedback_from_irpc(
    map: &BusMap,
    node: u16,
    payload: &Payload,
    timestamp_ms: f64,
    previous: Option<&MotorFeedback>,
) -> Result<Translated<MotorFeedback>, FeedbackError> {
    let motor = map.irpc_node(node).ok_or_else(|| FeedbackError::Unmapped {
        address: format!("iRPC node 0x{node:02X}"),
    })?;
    let name = motor.name.as_str();
    let mut report = Report::default();
    let mut fb = match previous {
        Some(p) => p.clone(),
        None => {
            for field in ["position", "velocity", "torque"] {
                report.push(field, LossKind::Filled, "not reported yet; 0");
            }
            blank(motor, timestamp_ms)
        }
    };
    fb.timestamp = timestamp_ms;
    let unit = motor.unit;
    let radians = unit != crate::AngleUnit::Degrees;
    match payload {
        Payload::Encoder(e) => {
            fb.position = unit.from_degrees(finite(name, "position", e.position)?);
            fb.velocity = unit.from_degrees(finite(name, "velocity", e.velocity)?);
        }
        Payload::TelemetryStream(t) => {
            fb.position = unit.from_degrees(finite(name, "position", t.position)?);
            fb.velocity = unit.from_degrees(finite(name, "velocity", t.velocity)?);
            fb.acceleration =
                Some(unit.from_degrees(finite(name, "acceleration", t.acceleration)?));
            fb.torque = finite(name, "torque_estimate", t.torque_estimate)?;
            fb.current = Some(finite(name, "current_q", t.current_q)?);
            let (vd, vq) = (
                finite(name, "voltage_d", t.voltage_d)?,
                finite(name, "voltage_q", t.voltage_q)?,
            );
            // In the joint's f32, as its other values are: an f64 hypot
            // of two f32s is no f32, and would print as f64 noise.
            #[allow(clippy::cast_possible_truncation)]
            let v = (vd as f32).hypot(vq as f32);
            fb.voltage = Some(f64::from(v));
            fb.power = Some(finite(name, "power", t.power)?);
            fb.temperature = Some(finite(name, "temperature_c", t.temperature_c)?);
            fb.control_effort = Some(finite(name, "load_percent", t.load_percent)?);
            fb.status.in_motion = Some(t.trajectory_active);
            fb.status.warning = Some(t.warnings != 0);
            report.push(
                "current",
                LossKind::Converted,
                "the q-axis current (current_d dropped)",
            );
            report.push(
                "voltage",
                LossKind::Converted,
                "sqrt(voltage_d² + voltage_q²)",
            );
            for field in [
                "timestamp_us",
                "foc_loop_time_us",
                "warnings (beyond the warning flag)",
            ] {
                report.push(
                    field,
                    LossKind::Dropped,
                    "WIA MotorFeedback has no place for it",
                );
            }
        }
        Payload::JointStatus { state, error_code } => {
            fb.status.enabled = Some(*state == LifecycleState::Active);
            fb.status.fault = Some(*state == LifecycleState::Error || *error_code != 0);
            if *state == LifecycleState::Calibrating {
                fb.status.calibrated = Some(false);
            }
            if *error_code != 0 {
                report.push(
                    "error_code",
                    LossKind::Converted,
                    format!("{error_code} becomes the fault flag"),
                );
            }
        }
        other => {
            return Err(FeedbackError::NotFeedback {
                payload: other.kind().name(),
            });
        }
    }
    if radians && matches!(payload, Payload::Encoder(_) | Payload::TelemetryStream(_)) {
        report.push(
            "position",
            LossKind::Converted,
            "degrees (iRPC's unit) to radians",
        );
    }
    Ok(Translated { value: fb, report })
}

/// WIA feedback for every mapped motor in an Orion direct-control feedback.
/// Speed motors and actuators report a velocity (position unknown, 0), the
/// servo a position in degrees (converted to the motor's unit); current is
/// passed on as given (the document gives it no unit); the error flag
/// becomes `fault`. Torque is not reported (0). Motors the map does not
/// have are skipped, and listed in the report of the first entry.
///
/// # Errors
/// [`FeedbackError::NonFinite`] for a non-finite value.
pub fn feedback_from_orion(
    map: &BusMap,
    feedback: &motorwire_orion::Feedback,
    timestamp_ms: f64,
) -> Result<Vec<Translated<MotorFeedback>>, FeedbackError> {
    let mut out = Vec::new();
    let mut unmapped = Vec::new();
    for (orion, f) in feedback.iter() {
        let Some(motor) = map.orion_motor(orion) else {
            unmapped.push(orion.key());
            continue;
        };
        for (field, v) in [("value", f.value), ("current", f.current)] {
            if !v.is_finite() {
                return Err(FeedbackError::NonFinite {
                    motor: motor.name.clone(),
                    field,
                });
            }
        }
        let mut report = Report::default();
        let mut fb = blank(motor, timestamp_ms);
        report.push("torque", LossKind::Filled, "Orion reports no torque; 0");
        match orion.quantity() {
            Quantity::Speed | Quantity::Actuator => {
                fb.velocity = f.value;
                report.push(
                    "position",
                    LossKind::Filled,
                    "Orion reports a speed, not a position; 0",
                );
            }
            Quantity::PositionDegrees => {
                fb.position = motor.unit.from_degrees(f.value);
                report.push(
                    "velocity",
                    LossKind::Filled,
                    "Orion reports the servo's position only; 0",
                );
                if motor.unit != crate::AngleUnit::Degrees {
                    report.push("position", LossKind::Converted, "degrees to radians");
                }
            }
        }
        fb.current = Some(f.current);
        report.push(
            "current",
            LossKind::Converted,
            "passed on as given (the Orion document gives no unit)",
        );
        fb.status.fault = Some(f.error != 0);
        if f.error > 1 {
            report.push(
                "error flag",
                LossKind::Converted,
                format!("{} becomes the fault flag", f.error),
            );
        }
        out.push(Translated { value: fb, report });
    }
    if let Some(first) = out.first_mut()
        && !unmapped.is_empty()
    {
        first.report.push(
            unmapped.join(", "),
            LossKind::Dropped,
            "Orion motors the bus map does not have",
        );
    }
    Ok(out)
}
