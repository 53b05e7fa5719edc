//! The iRPC driver: the bus map's iRPC joints, each spoken to in its own
//! wire version, through `motorwire_can`'s sans-IO client (postcard
//! frames, msg_ids, Ack and Nack, retries with the same msg_id, segmented
//! transfers).
//!
//! It owns the client, which request in flight is which device's, the
//! heartbeat (ArmReady, feeding the joints' watchdogs while one moves),
//! and the translation of the client's events into the device layer's:
//! an [`Ended`] request for its device (a Deactivate refused because the
//! joint is already stopped is a stop done), a joint heard, a message that
//! is feedback, a frame that is not for the bridge. It also says what an
//! acknowledged payload did to its joint ([`effect`]). The engine decides
//! what is sent and when; this says how, and what came back.

use super::DeviceError;
use std::collections::HashMap;
use std::time::Duration;

use motorwire_can::Frame;
use motorwire_can::client::{Client, ClientConfig, Event as ClientEvent, Outcome as ClientOutcome};
use motorwire_irpc::{
    EmergencyReason, LifecycleState, Message, NackCode, Payload, PayloadKind, SetTargetPayloadV2,
    WireVersion,
};

use motorwire_irpc::{CalibrationPhase, CalibrationRequest};
use motorwire_translate::{BusMap, feedback_from_irpc};

use super::AwaitKind;
use super::{
    Answer, Ask, Context, DeviceId, DeviceState, Effect, Ended, Happened, Moving, Needs, Order,
    Outcome,
};
use crate::classify::RequestKind;
use crate::output::Event;

/// What the driver has to tell the engine.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum IrpcEvent {
    /// Joint `node` was heard at `at` (an answer, even a late one).
    Heard { node: u16, at: Duration },
    /// Joint `node` answered a request at `at` (an Ack or a Nack): it
    /// was heard, and the request ended for the device it went to
    /// (`None`: one the bridge no longer waits for).
    Answered {
        node: u16,
        at: Duration,
        ended: Option<(DeviceId, Ended)>,
    },
    /// The request in flight for device `device` ended.
    Ended { device: DeviceId, ended: Ended },
    /// A message from a joint that is not an answer (its status, encoder,
    /// telemetry, an answer to a request line, its own emergency stop).
    Feedback { message: Message, at: Duration },
    /// A frame that is not an iRPC message for the bridge.
    BadFrame { can_id: String, error: String },
}

/// The iRPC joints' client, and which device each request in flight is
/// for.
#[derive(Debug)]
pub(crate) struct IrpcDriver {
    client: Client,
    /// Each msg_id in flight and the device it went to: at most one a
    /// joint (the client's rule), so a short list looked through.
    by_msg: Vec<(u32, DeviceId)>,
    /// The time of the last frame or timeout handled.
    now: Duration,
    /// Whether any joint was given ([`IrpcDriver::set_wire`]): the
    /// heartbeat is theirs.
    joints: bool,
}

impl IrpcDriver {
    /// A driver speaking as `config` says.
    ///
    /// # Errors
    /// The client's refusal of `config` (a node id beyond 11 bits).
    pub(crate) fn new(config: ClientConfig) -> Result<Self, motorwire_can::Error> {
        Ok(Self {
            client: Client::new(config)?,
            by_msg: Vec::new(),
            now: Duration::ZERO,
            joints: false,
        })
    }

    /// Joint `node` is spoken to, and heard, in `wire`.
    pub(crate) fn set_wire(&mut self, node: u16, wire: WireVersion) {
        self.client.set_wire(node, wire);
        self.joints = true;
    }

    /// Sends `payload` to joint `node` (device `device`) and awaits its
    /// Ack; returns its msg_id.
    ///
    /// # Errors
    /// The client's refusal (one request in flight per joint, a payload
    /// its wire version lacks), as text; nothing was queued.
    pub(crate) fn send(
        &mut self,
        now: Duration,
        device: DeviceId,
        node: u16,
        payload: Payload,
    ) -> Result<u32, DeviceError> {
        let msg_id = self
            .client
            .request(now, node, payload)
            .map_err(DeviceError::Client)?;
        // A msg_id comes round again only long after its request ended;
        // a leftover entry for it is replaced, as a map's would be.
        self.take_device(msg_id);
        self.by_msg.push((msg_id, device));
        Ok(msg_id)
    }

    /// The device request `msg_id` went to, no longer in flight.
    fn take_device(&mut self, msg_id: u32) -> Option<DeviceId> {
        let i = self.by_msg.iter().position(|(m, _)| *m == msg_id)?;
        Some(self.by_msg.swap_remove(i).1)
    }

    /// Whether request `msg_id` is due to be sent again at `now`.
    pub(crate) fn resend_due(&self, msg_id: u32, now: Duration) -> bool {
        self.client.resend_due(msg_id, now)
    }

    /// Request `msg_id` is given up: never sent again, its answer not
    /// awaited.
    pub(crate) fn forget(&mut self, msg_id: u32) {
        self.client.cancel(msg_id);
        self.take_device(msg_id);
    }

    /// ArmReady to every joint, each in its own wire version (a broadcast
    /// when they all speak the bridge's). Whether it was queued.
    /// Whether the bus has iRPC joints to hear a heartbeat.
    pub(crate) fn beats(&self) -> bool {
        self.joints
    }

    pub(crate) fn heartbeat(&mut self) -> bool {
        // A bus without iRPC joints (moteus controllers alone) hears no
        // iRPC broadcast.
        self.joints && self.client.arm_ready().is_ok()
    }

    /// A frame from the bus.
    pub(crate) fn handle_frame(&mut self, now: Duration, frame: &Frame) {
        self.now = self.now.max(now);
        self.client.handle_frame(now, frame);
    }

    /// Resends and time-outs due at `now`.
    pub(crate) fn handle_timeout(&mut self, now: Duration) {
        self.now = self.now.max(now);
        self.client.handle_timeout(now);
    }

    /// The next frame to send.
    pub(crate) fn poll_transmit(&mut self) -> Option<Frame> {
        self.client.poll_transmit()
    }

    /// The client's next deadline.
    pub(crate) fn deadline(&self) -> Option<Duration> {
        self.client.poll_timeout()
    }

    /// The next thing to tell the engine.
    pub(crate) fn poll_event(&mut self) -> Option<IrpcEvent> {
        let event = self.client.poll_event()?;
        Some(match event {
            ClientEvent::Completed(c) => {
                let outcome = match c.outcome {
                    ClientOutcome::Acked => Outcome::Acked,
                    ClientOutcome::Nacked(code) => Outcome::Nacked {
                        code: Some(code.0),
                        why: format!("nacked: {code}"),
                        // A Deactivate refused in the wrong state: the
                        // joint is not active, so it is stopped already.
                        already_stopped: c.kind == PayloadKind::Deactivate
                            && code == NackCode::DEACTIVATE_WRONG_STATE,
                    },
                    ClientOutcome::TimedOut => Outcome::TimedOut,
                };
                let timed_out = outcome == Outcome::TimedOut;
                let ended = self.take_device(c.msg_id).map(|device| {
                    let ended = Ended {
                        msg_id: c.msg_id,
                        outcome,
                        attempts: c.attempts,
                        at: c.finished_at,
                    };
                    (device, ended)
                });
                if timed_out {
                    // Nothing was heard. A request the bridge gave up (a
                    // heartbeat): nothing to say.
                    return match ended {
                        Some((device, ended)) => Some(IrpcEvent::Ended { device, ended }),
                        None => self.poll_event(),
                    };
                }
                IrpcEvent::Answered {
                    node: c.target,
                    at: c.finished_at,
                    ended,
                }
            }
            ClientEvent::Feedback { message, at } => IrpcEvent::Feedback { message, at },
            ClientEvent::StrayReply { message } => IrpcEvent::Heard {
                node: message.header.source_id,
                at: self.now,
            },
            ClientEvent::Undecodable { can_id, error } => IrpcEvent::BadFrame {
                can_id: can_id.to_string(),
                error: error.to_string(),
            },
            ClientEvent::Misaddressed { can_id, message } => IrpcEvent::BadFrame {
                can_id: can_id.to_string(),
                error: format!(
                    "the CAN id is not the sender's node id 0x{:02X}",
                    message.header.source_id
                ),
            },
        })
    }
}

/// What one of a joint's messages that is not an answer says, in the
/// layer's terms (for the engine to act on once, as it does for every
/// dialect's feedback).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub(crate) struct Heard {
    /// Its position and velocity (degrees), where the message reports
    /// them (Encoder, TelemetryStream).
    pub(crate) motion: Option<(f64, f64)>,
    /// Its lifecycle state and error code (JointStatus).
    pub(crate) status: Option<(DeviceState, u16)>,
    /// It stopped itself (its own EmergencyStop): the reason and its code.
    pub(crate) stopped_itself: Option<(EmergencyReason, u16)>,
    /// It answers a request line (telemetry, power metrics, the fault
    /// history, a calibration's status or result).
    pub(crate) answers: bool,
}

/// What `payload`, from a joint, says.
pub(crate) fn heard(payload: &Payload) -> Heard {
    let mut h = Heard {
        answers: matches!(
            payload,
            Payload::TelemetryStream(_)
                | Payload::PowerMetrics(_)
                | Payload::FaultHistory(_)
                | Payload::CalibrationStatus(_)
                | Payload::CalibrationResult(_)
        ),
        ..Heard::default()
    };
    match payload {
        Payload::JointStatus { state, error_code } => {
            h.status = Some((device_state(*state), *error_code));
        }
        Payload::EmergencyStop(e) => {
            h.stopped_itself = Some((
                e.reason,
                u16::try_from(e.reason.index()).unwrap_or(u16::MAX),
            ));
        }
        Payload::Encoder(e) => h.motion = Some((f64::from(e.position), f64::from(e.velocity))),
        Payload::TelemetryStream(t) => {
            h.motion = Some((f64::from(t.position), f64::from(t.velocity)));
        }
        _ => {}
    }
    h
}

/// What the driver's `event` tells the engine, each given to `tell` in
/// order: its device (found by its node in `by_node`, its place among
/// `devices`, the engine's), what its message says in the layer's terms,
/// its WIA feedback built on the device's last (`map` for the motor's
/// unit, `epoch` for the timestamp).
pub(crate) fn tell(
    event: IrpcEvent,
    map: &BusMap,
    devices: &dyn super::Registry,
    by_node: &HashMap<u16, DeviceId>,
    epoch: f64,
    mut tell: impl FnMut(Happened),
) {
    let index = |node: u16| by_node.get(&node).copied();
    match event {
        IrpcEvent::Heard { node, at } => {
            if let Some(device) = index(node) {
                tell(Happened::Heard {
                    device,
                    at,
                    up: true,
                });
            }
        }
        IrpcEvent::Answered { node, at, ended } => {
            if let Some(device) = index(node) {
                tell(Happened::Heard {
                    device,
                    at,
                    up: true,
                });
            }
            if let Some((device, ended)) = ended {
                tell(Happened::Ended { device, ended });
            }
        }
        IrpcEvent::Ended { device, ended } => tell(Happened::Ended { device, ended }),
        IrpcEvent::BadFrame { can_id, error } => tell(Happened::Bad {
            report: Some(Event::BadFrame { can_id, error }),
        }),
        IrpcEvent::Feedback { message, at } => {
            let node = message.header.source_id;
            let Some(device) = index(node) else { return };
            let Some(j) = devices.get(device) else { return };
            tell(Happened::Heard {
                device,
                at,
                up: true,
            });
            let said = heard(&message.payload);
            if said.answers
                && let Some(answer) = answer(j.name, &message.payload)
            {
                tell(Happened::Answer { device, answer });
            }
            let ts = super::unix_ms(epoch, at);
            let feedback = feedback_from_irpc(map, node, &message.payload, ts, j.feedback)
                .ok()
                .map(|t| Box::new(t.value));
            if said.motion.is_some() || feedback.is_some() {
                tell(Happened::Reading {
                    device,
                    at,
                    motion: said.motion,
                    feedback,
                });
            }
            if let Some((state, code)) = said.status {
                tell(Happened::Lifecycle {
                    device,
                    state,
                    code,
                });
            }
            if let Some((reason, code)) = said.stopped_itself {
                tell(Happened::StoppedItself {
                    device,
                    at,
                    reason: format!("{reason:?}"),
                    code,
                });
            }
        }
    }
}

/// A request line's ask of an iRPC joint.
pub(crate) const fn request(kind: RequestKind) -> Ask {
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
    Ask {
        needs: Needs(needs),
        order: Order::Irpc(payload),
        awaits,
        what,
    }
}

/// A calibration line's ask of an iRPC joint: started as `start` says
/// (the line then waits for its result), or stopped.
pub(crate) const fn calibration(start: Option<&CalibrationRequest>) -> Ask {
    Ask {
        needs: Needs(PayloadKind::StartCalibration),
        order: Order::Irpc(match start {
            Some(r) => Payload::StartCalibration(*r),
            None => Payload::StopCalibration,
        }),
        awaits: AwaitKind::CalibrationResult,
        what: "calibration (v2.1 on)",
    }
}

/// How long calibration `start` of `motor` may take, its phases each to
/// their time-out, once its own limits are held to `map`'s limits in
/// force.
///
/// # Errors
/// The gate's refusal: a limit of the calibration's beyond the map's.
pub(crate) fn calibration_time(
    map: &motorwire_translate::BusMap,
    motor: &str,
    start: &CalibrationRequest,
) -> Result<Duration, motorwire_translate::Refusal> {
    motorwire_translate::gate_calibration(map, motor, start)?;
    let phases = start.phases.count_ones().max(1);
    let per_phase = Duration::try_from_secs_f32(start.phase_timeout).unwrap_or(Duration::ZERO);
    Ok(per_phase.saturating_mul(phases))
}

/// The name of calibration phase `p`, as a `calibration` event says it.
const fn phase_name(p: CalibrationPhase) -> &'static str {
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
                && let Some(m) = serde_json::Number::from_f64(crate::output::shortest(x))
            {
                *n = m;
            }
        }
        serde_json::Value::Array(a) => a.iter_mut().for_each(shortest_floats),
        serde_json::Value::Object(o) => o.values_mut().for_each(shortest_floats),
        _ => {}
    }
}

/// What `payload`, from joint `motor`, answers of a request line: a
/// calibration's progress, or the message a line waits for as its `data`
/// (iRPC's field names).
fn answer(motor: &str, payload: &Payload) -> Option<Answer> {
    if let Payload::CalibrationStatus(s) = payload {
        return Some(Answer::Progress(Event::Calibration {
            motor_id: motor.to_owned(),
            phase: phase_name(s.phase).to_owned(),
            progress: f64::from(s.progress),
            time_remaining: f64::from(s.time_remaining),
        }));
    }
    let (kind, key, value) = match payload {
        Payload::TelemetryStream(t) => (AwaitKind::Telemetry, "telemetry", serde_json::to_value(t)),
        Payload::PowerMetrics(p) => (
            AwaitKind::PowerMetrics,
            "power_metrics",
            serde_json::to_value(p),
        ),
        Payload::FaultHistory(f) => (
            AwaitKind::FaultHistory,
            "fault_history",
            serde_json::to_value(f),
        ),
        Payload::CalibrationResult(r) => (
            AwaitKind::CalibrationResult,
            "calibration_result",
            serde_json::to_value(r),
        ),
        _ => return None,
    };
    let mut value = value.ok()?;
    shortest_floats(&mut value);
    let error = match payload {
        Payload::CalibrationResult(r) if !r.success => Some(format!(
            "{motor}: the calibration failed (error code 0x{:X})",
            r.error_code
        )),
        _ => None,
    };
    Some(Answer::Data {
        kind,
        data: serde_json::json!({ key: value }),
        error,
    })
}

/// What an acknowledged `payload` did to its joint: a move's target and,
/// as planned from the joint's last report, when it ends (the gate's own
/// plan when it is the same move from the same state); the lifecycle.
pub(crate) fn effect(payload: Payload, cx: &Context) -> Effect {
    let (pos, vel, acc) = cx.motion.unwrap_or((0.0, 0.0, 0.0));
    let planned = |p: &SetTargetPayloadV2| {
        if let Some((from, q, d)) = cx.planned
            && from == (pos, vel, acc)
            && q.terms() == *p
        {
            return d;
        }
        motorwire_planner::plan(&p.planner_request(pos, vel).with_start_acceleration(acc))
            .ok()
            .and_then(|plan| Duration::try_from_secs_f64(plan.duration()).ok())
            .unwrap_or(Duration::from_secs(1))
    };
    let moving_to = |target: f32, p: &SetTargetPayloadV2| Effect {
        target: Some(Some(f64::from(target))),
        moving: Moving::Until(cx.at.saturating_add(planned(p))),
        settles: true,
        ..Effect::NONE
    };
    match payload {
        Payload::SetTargetV2(p) => moving_to(p.target_angle, &p),
        Payload::SetTarget(p) => {
            #[allow(clippy::cast_possible_truncation)]
            let acc = cx.max_acceleration.unwrap_or(1000.0) as f32;
            let v2 = SetTargetPayloadV2::trapezoidal(p.target_angle, p.velocity_limit, acc);
            moving_to(p.target_angle, &v2)
        }
        Payload::Activate => Effect {
            active: Some(true),
            ..Effect::NONE
        },
        // The joint brakes (its move abandoned); give it a moment before
        // calling it idle.
        Payload::Deactivate | Payload::Reset => Effect {
            active: Some(false),
            target: Some(None),
            moving: Moving::AtMost(cx.at.saturating_add(Duration::from_millis(100))),
            ..Effect::NONE
        },
        _ => Effect::NONE,
    }
}

/// An iRPC joint's lifecycle state in the engine's terms.
const fn device_state(state: LifecycleState) -> DeviceState {
    match state {
        LifecycleState::Unconfigured => DeviceState::Unconfigured,
        LifecycleState::Inactive => DeviceState::Inactive,
        LifecycleState::Active => DeviceState::Active,
        LifecycleState::Calibrating => DeviceState::Calibrating,
        LifecycleState::Error => DeviceState::Error,
    }
}

/// A joint's message to the bridge (node 0x0000) as its frame, in `wire`:
/// what the tests of the driver and of the engine feed in.
#[cfg(test)]
#[allow(clippy::unwrap_used)]
pub(crate) fn joint_frame(source: u16, msg_id: u32, payload: Payload, wire: WireVersion) -> Frame {
    let m = Message {
        header: motorwire_irpc::Header {
            source_id: source,
            target_id: 0x0000,
            msg_id,
        },
        payload,
    };
    let mut buf = [0u8; motorwire_irpc::MAX_FRAME_LEN];
    let n = m.encode_frame(wire, &mut buf).unwrap();
    Frame::fd(motorwire_can::CanId::standard(source).unwrap(), &buf[..n]).unwrap()
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: Duration = Duration::from_millis(1);

    fn reply(source: u16, msg_id: u32, payload: Payload) -> Frame {
        joint_frame(source, msg_id, payload, WireVersion::V2_0)
    }

    fn events(d: &mut IrpcDriver) -> Vec<IrpcEvent> {
        std::iter::from_fn(|| d.poll_event()).collect()
    }

    /// A request goes out as its bytes; its Ack says the joint was heard,
    /// then ends the request for the device that sent it.
    #[test]
    fn an_ack_is_heard_then_ends_the_devices_request() {
        let mut d = IrpcDriver::new(ClientConfig::default()).unwrap();
        let id = d
            .send(Duration::ZERO, DeviceId(4), 0x12, Payload::Activate)
            .unwrap();
        assert_eq!(id, 1);
        let f = d.poll_transmit().unwrap();
        // From 0x0000 to 0x12, msg_id 1, Activate (v2.0 tag 2).
        assert_eq!(f.data()[..4], [0x00, 0x12, 0x01, 0x02]);
        assert_eq!(d.deadline(), Some(100 * MS));
        d.handle_frame(3 * MS, &reply(0x12, id, Payload::Ack(id)));
        assert_eq!(
            events(&mut d),
            [IrpcEvent::Answered {
                node: 0x12,
                at: 3 * MS,
                ended: Some((
                    DeviceId(4),
                    Ended {
                        msg_id: id,
                        outcome: Outcome::Acked,
                        attempts: 1,
                        at: 3 * MS
                    }
                ))
            }]
        );
    }

    /// A Deactivate refused because the joint is already stopped says so
    /// (a stop takes it as done, a command does not); every Nack says
    /// its code.
    #[test]
    fn a_stop_of_a_stopped_joint_is_done_and_other_nacks_say_their_code() {
        let mut d = IrpcDriver::new(ClientConfig::default()).unwrap();
        let stop = d
            .send(Duration::ZERO, DeviceId(0), 0x12, Payload::Deactivate)
            .unwrap();
        let go = d
            .send(Duration::ZERO, DeviceId(1), 0x13, Payload::Activate)
            .unwrap();
        d.handle_frame(
            MS,
            &reply(
                0x12,
                stop,
                Payload::Nack {
                    id: stop,
                    error: NackCode::DEACTIVATE_WRONG_STATE.0,
                },
            ),
        );
        d.handle_frame(MS, &reply(0x13, go, Payload::Nack { id: go, error: 2 }));
        let ended: Vec<(DeviceId, Outcome)> = events(&mut d)
            .into_iter()
            .filter_map(|e| match e {
                IrpcEvent::Answered {
                    ended: Some((device, ended)),
                    ..
                } => Some((device, ended.outcome)),
                _ => None,
            })
            .collect();
        assert_eq!(
            ended,
            [
                (
                    DeviceId(0),
                    Outcome::Nacked {
                        code: Some(3),
                        why: "nacked: 3 (deactivate in the wrong state)".to_owned(),
                        already_stopped: true
                    }
                ),
                (
                    DeviceId(1),
                    Outcome::Nacked {
                        code: Some(2),
                        why: "nacked: 2 (activate in the wrong state)".to_owned(),
                        already_stopped: false
                    }
                )
            ]
        );
    }

    /// Unanswered, a request is sent again with its msg_id, then ends
    /// timed out (and says nothing was heard); a forgotten one ends
    /// nothing.
    #[test]
    fn an_unanswered_request_times_out_and_a_forgotten_one_says_nothing() {
        let mut d = IrpcDriver::new(ClientConfig::default()).unwrap();
        let id = d
            .send(Duration::ZERO, DeviceId(2), 0x12, Payload::Configure)
            .unwrap();
        for k in 1..=3u32 {
            d.handle_timeout(100 * MS * k);
        }
        // The first sending and three retries.
        assert_eq!(std::iter::from_fn(|| d.poll_transmit()).count(), 4);
        d.handle_timeout(400 * MS);
        assert_eq!(
            events(&mut d),
            [IrpcEvent::Ended {
                device: DeviceId(2),
                ended: Ended {
                    msg_id: id,
                    outcome: Outcome::TimedOut,
                    attempts: 4,
                    at: 400 * MS
                }
            }]
        );
        let gone = d
            .send(400 * MS, DeviceId(2), 0x12, Payload::Activate)
            .unwrap();
        d.forget(gone);
        d.handle_frame(401 * MS, &reply(0x12, gone, Payload::Ack(gone)));
        assert_eq!(
            events(&mut d),
            [IrpcEvent::Heard {
                node: 0x12,
                at: 401 * MS
            }],
            "a forgotten request ends nothing (its answer is a stray, heard)"
        );
    }
}
