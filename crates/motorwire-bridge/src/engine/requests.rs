//! Lines that ask a joint for something and wait for its answer:
//! telemetry, power metrics, the fault history (`{"request":...}`) and
//! calibration (`{"calibration":"start"|"stop",...}`).
//!
//! A request line is one job: its request is sent like any command (one in
//! flight per joint, retried with its msg_id, acked), and the line's
//! result waits for the message it asked for, which comes back in
//! `data` (iRPC's field names). The joint may send it before or after its
//! Ack. Nothing within the wait (see [`Bridge::answer_wait`]) is the error
//! `no_answer`. A calibration's `CalibrationStatus` messages are
//! `calibration` events while it runs; its `CalibrationResult` ends the
//! start line (`ok` only when it succeeded).

use std::time::Duration;

use motorwire_irpc::{CalibrationPhase, CalibrationRequest, Payload, PayloadKind};
use motorwire_translate::Report;

use super::Bridge;
use crate::classify::RequestKind;
use crate::device::Capability;
use crate::job::LineMeta;
use crate::job::{AwaitKind, Awaiting, Axis};
use crate::output::Label;
use crate::output::{ErrorBody, ErrorKind, Event, Output};

/// How long past its Ack timeouts a request line waits for its answer.
const ANSWER_MARGIN: Duration = Duration::from_millis(500);

/// How long a calibration may run, past its phases' own timeouts.
const CALIBRATION_MARGIN: Duration = Duration::from_secs(5);

fn phase_name(p: CalibrationPhase) -> &'static str {
    match p {
        CalibrationPhase::Idle => "idle",
        CalibrationPhase::InertiaTest => "inertia_test",
        CalibrationPhase::FrictionTest => "friction_test",
        CalibrationPhase::TorqueConstantVerification => "torque_constant_verification",
        CalibrationPhase::DampingTest => "damping_test",
        CalibrationPhase::Validation => "validation",
        CalibrationPhase::Complete => "complete",
        CalibrationPhase::Failed => "failed",
    }
}

/// Every float in `v` written as the shortest decimal that is the same
/// f32 (the joint's values are f32: `0.01`, not `0.009999999776482582`).
fn shortest_floats(v: &mut serde_json::Value) {
    match v {
        serde_json::Value::Number(n) if n.is_f64() => {
            if let Some(x) = n.as_f64()
                && let Some(m) = serde_json::Number::from_f64(super::shortest(x))
            {
                *n = m;
            }
        }
        serde_json::Value::Array(a) => a.iter_mut().for_each(shortest_floats),
        serde_json::Value::Object(o) => o.values_mut().for_each(shortest_floats),
        _ => {}
    }
}

impl Bridge {
    /// How long a request line waits for its answer after it is sent:
    /// every attempt's Ack timeout and a margin.
    fn answer_wait(&self) -> Duration {
        self.config
            .client
            .timeout
            .saturating_mul(u32::from(self.config.client.retries) + 1)
            .saturating_add(ANSWER_MARGIN)
    }

    /// The device `motor` names if it can do `needs_to` and has the
    /// message `needs` (an iRPC joint, in its wire version), or the
    /// refusal to answer with.
    pub(super) fn joint_for(
        &self,
        motor: &str,
        needs_to: Capability,
        needs: PayloadKind,
        what: &str,
    ) -> Result<usize, ErrorBody> {
        let Some(ji) = self.joint_index(motor).filter(|&ji| {
            self.joints
                .get(ji)
                .is_some_and(|j| j.device.supports(needs_to))
        }) else {
            return Err(ErrorBody::refused(
                crate::output::BridgeRule::NotAnIrpcJoint,
                format!("{motor} is not an iRPC joint of the bus map"),
            )
            .about(motor));
        };
        let device = self.joints.get(ji).map(|j| j.device);
        if device.is_none_or(|d| !d.speaks(needs)) {
            let wire = device.map(crate::device::Device::wire);
            return Err(ErrorBody::new(
                ErrorKind::Unsupported,
                format!(
                    "{motor} speaks iRPC {}, which has no {what}",
                    wire.map_or("?", |w| w.name())
                ),
            )
            .about(motor));
        }
        if self.joints.get(ji).is_some_and(|j| !j.online) {
            return Err(
                ErrorBody::new(ErrorKind::Offline, format!("{motor} is offline")).about(motor),
            );
        }
        Ok(ji)
    }

    /// `{"request":K,"motor_id":M}`.
    pub(super) fn request_line(
        &mut self,
        now: Duration,
        meta: LineMeta,
        kind: RequestKind,
        motor: &str,
    ) {
        let meta = meta.labelled(Label::Motor(motor.to_owned()));
        let (needs, payload, awaits, what) = match kind {
            RequestKind::Telemetry => (
                PayloadKind::RequestTelemetry,
                Payload::RequestTelemetry,
                AwaitKind::Telemetry,
                "TelemetryStream (v2.1 on)",
            ),
            RequestKind::PowerMetrics => (
                PayloadKind::PowerMetrics,
                Payload::RequestTelemetry,
                AwaitKind::PowerMetrics,
                "PowerMetrics (v2.2)",
            ),
            RequestKind::FaultHistory => (
                PayloadKind::RequestFaultHistory,
                Payload::RequestFaultHistory,
                AwaitKind::FaultHistory,
                "FaultHistory (v2.2)",
            ),
        };
        let ji = match self.joint_for(motor, Capability::Requests, needs, what) {
            Ok(ji) => ji,
            Err(e) => return self.refuse(&meta, e),
        };
        let deadline = now.saturating_add(self.answer_wait());
        self.open_waiting(
            now,
            meta,
            Axis::new(motor.to_owned(), ji, [payload]),
            Awaiting {
                joint: ji,
                kind: awaits,
                deadline,
            },
        );
    }

    /// `{"calibration":"start"|"stop","motor_id":M,...}`.
    pub(super) fn calibration_line(
        &mut self,
        now: Duration,
        meta: LineMeta,
        motor: &str,
        start: Option<CalibrationRequest>,
    ) {
        let meta = meta.labelled(Label::Motor(motor.to_owned()));
        let ji = match self.joint_for(
            motor,
            Capability::Requests,
            PayloadKind::StartCalibration,
            "calibration (v2.1 on)",
        ) {
            Ok(ji) => ji,
            Err(e) => return self.refuse(&meta, e),
        };
        let Some(request) = start else {
            let axis = Axis::new(motor.to_owned(), ji, [Payload::StopCalibration]);
            self.command_job(now, meta, vec![axis], Report::default());
            return;
        };
        // A calibration moves the joint: refused as a motion is.
        if let Err(e) = self.admit_now(std::iter::once(motor)) {
            return self.refuse(&meta, e);
        }
        let phases = request.phases.count_ones().max(1);
        let per_phase =
            Duration::try_from_secs_f32(request.phase_timeout).unwrap_or(Duration::ZERO);
        let deadline = now
            .saturating_add(self.answer_wait())
            .saturating_add(per_phase.saturating_mul(phases))
            .saturating_add(CALIBRATION_MARGIN);
        self.open_waiting(
            now,
            meta,
            Axis::new(motor.to_owned(), ji, [Payload::StartCalibration(request)]),
            Awaiting {
                joint: ji,
                kind: AwaitKind::CalibrationResult,
                deadline,
            },
        );
    }

    fn open_waiting(&mut self, now: Duration, meta: LineMeta, axis: Axis, awaiting: Awaiting) {
        let id = self.next_job;
        self.command_job(now, meta, vec![axis], Report::default());
        // Not done yet (a job is taken out once done): it waits.
        if let Some(job) = self.jobs.get_mut(&id) {
            job.awaiting = Some(awaiting);
        }
    }

    /// A message from joint `ji` that a request line may wait for.
    pub(super) fn answered(&mut self, ji: usize, payload: &Payload) {
        let motor = self
            .joints
            .get(ji)
            .map(|j| j.name.clone())
            .unwrap_or_default();
        if let Payload::CalibrationStatus(s) = payload {
            self.out.push_back(Output::Event(Event::Calibration {
                motor_id: motor,
                phase: phase_name(s.phase).to_owned(),
                progress: f64::from(s.progress),
                time_remaining: f64::from(s.time_remaining),
            }));
            return;
        }
        let (kind, key) = match payload {
            Payload::TelemetryStream(_) => (AwaitKind::Telemetry, "telemetry"),
            Payload::PowerMetrics(_) => (AwaitKind::PowerMetrics, "power_metrics"),
            Payload::FaultHistory(_) => (AwaitKind::FaultHistory, "fault_history"),
            Payload::CalibrationResult(_) => (AwaitKind::CalibrationResult, "calibration_result"),
            _ => return,
        };
        let value = match payload {
            Payload::TelemetryStream(t) => serde_json::to_value(t),
            Payload::PowerMetrics(p) => serde_json::to_value(p),
            Payload::FaultHistory(f) => serde_json::to_value(f),
            Payload::CalibrationResult(r) => serde_json::to_value(r),
            _ => return,
        };
        let Ok(mut value) = value else { return };
        shortest_floats(&mut value);
        // The oldest line waiting for this from this joint.
        let Some(job) = self
            .jobs
            .values_mut()
            .find(|j| j.awaiting.is_some_and(|a| a.joint == ji && a.kind == kind))
        else {
            return;
        };
        job.awaiting = None;
        if let Payload::CalibrationResult(r) = payload
            && !r.success
        {
            job.data_error = Some(format!(
                "{motor}: the calibration failed (error code 0x{:X})",
                r.error_code
            ));
        }
        job.data = Some(serde_json::json!({ key: value }));
        self.finish_jobs();
    }

    /// Request lines whose answer did not come in time.
    pub(super) fn awaiting_timeouts(&mut self, now: Duration) {
        let mut any = false;
        for job in self.jobs.values_mut() {
            let Some(a) = job.awaiting.filter(|a| now >= a.deadline) else {
                continue;
            };
            job.awaiting = None;
            let what = match a.kind {
                AwaitKind::Telemetry => "TelemetryStream",
                AwaitKind::PowerMetrics => "PowerMetrics",
                AwaitKind::FaultHistory => "FaultHistory",
                AwaitKind::CalibrationResult => "CalibrationResult",
            };
            let motor = job
                .axes
                .first()
                .map(|x| x.motor.clone())
                .unwrap_or_default();
            job.data_error = Some(format!(
                "{motor} acked the request, but no {what} came within {} ms",
                now.saturating_sub(job.received).as_millis()
            ));
            any = true;
        }
        if any {
            self.finish_jobs();
        }
    }
}
