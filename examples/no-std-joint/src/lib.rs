//! A joint's firmware loop on `motorwire-irpc` and `motorwire-planner`:
//! no_std, no allocation, no clock and no I/O of its own. It builds for a
//! Cortex-M4F (`thumbv7em-none-eabihf`) as it is; your firmware brings the
//! CAN-FD peripheral, the timer and the current loop, and calls two
//! functions:
//!
//! - [`Joint::on_frame`] with every frame received (the frame's bytes and
//!   the time in microseconds): it decodes the iRPC message, keeps the ones
//!   addressed to this node, runs the lifecycle (Configure, Activate,
//!   Deactivate, Reset), plans a `SetTargetV2` with the S-curve planner
//!   through [`SetTargetPayloadV2::planner_request`] (the conversion the
//!   simulated joint and the bridge use) and writes the Ack or Nack frame
//!   to send back;
//! - [`Joint::tick`] from the control interrupt: the position setpoint (and
//!   velocity feed-forward) for the current loop at that instant, sampled
//!   from the planned profile (about 30 bytes of state, no waypoint table).
//!
//! ```
//! use motorwire_example_joint::Joint;
//! use motorwire_irpc::{Header, Message, Payload, SetTargetPayloadV2, WireVersion};
//!
//! let mut joint = Joint::new(0x10, 0.0);
//! let mut reply = [0u8; 64];
//! for (msg_id, payload) in [
//!     (1, Payload::Configure),
//!     (2, Payload::Activate),
//!     (3, Payload::SetTargetV2(SetTargetPayloadV2::scurve(90.0, 100.0, 500.0, 2000.0))),
//! ] {
//!     let mut frame = [0u8; 64];
//!     let message = Message { header: Header { source_id: 0, target_id: 0x10, msg_id }, payload };
//!     let len = message.encode_frame(WireVersion::V2_0, &mut frame)?;
//!     let answer = joint.on_frame(0, &frame[..len], &mut reply).unwrap();
//!     // Each request is acked: 0x10 -> 0x0000, Ack(msg_id).
//!     assert_eq!(Message::decode_frame(WireVersion::V2_0, &reply[..answer])?.payload, Payload::Ack(msg_id));
//! }
//! // Half-way through the 1.347 s move it is half-way to 90°; at the end, there.
//! assert!((joint.tick(673_607).position - 45.0).abs() < 0.01);
//! assert_eq!(joint.tick(2_000_000).position, 90.0);
//! # Ok::<(), motorwire_irpc::Error>(())
//! ```
#![no_std]

use motorwire_irpc::{
    Header, LifecycleState, MAX_FRAME_LEN, Message, NackCode, Payload, SetTargetPayloadV2,
    WireVersion,
};
use motorwire_planner::{Profile, State, plan};

/// The wire version this joint speaks.
pub const WIRE: WireVersion = WireVersion::V2_0;

/// The joint's travel: a target outside it is refused with Nack 16.
pub const TRAVEL_DEG: (f32, f32) = (-180.0, 180.0);

/// One joint: its node id, lifecycle state and the motion it is making.
#[derive(Debug, Clone)]
pub struct Joint {
    node: u16,
    state: LifecycleState,
    /// The motion under way and when it started (µs).
    motion: Profile<f32>,
    started_us: u64,
}

impl Joint {
    /// A joint with node id `node`, unconfigured, at rest at `position`
    /// degrees.
    pub fn new(node: u16, position: f32) -> Self {
        Self {
            node,
            state: LifecycleState::Unconfigured,
            motion: Profile::at_rest(position),
            started_us: 0,
        }
    }

    /// The lifecycle state.
    pub fn state(&self) -> LifecycleState {
        self.state
    }

    /// The setpoint at `now_us` (the same clock as [`Joint::on_frame`]'s):
    /// position (degrees), velocity (deg/s), acceleration and jerk, exactly
    /// the target once the move is over.
    pub fn tick(&self, now_us: u64) -> State<f32> {
        let elapsed_us = now_us.saturating_sub(self.started_us);
        // f32 seconds hold a µs for the first 16 s of a move; a longer one
        // loses sub-µs precision, never correctness.
        self.motion.sample(elapsed_us as f32 * 1e-6)
    }

    /// Handles one received CAN-FD frame at `now_us`; when it asks for an
    /// answer, writes the answer frame into `reply` and returns its length.
    ///
    /// A frame that does not decode, or is addressed to another node, is
    /// ignored (`None`): iRPC receivers take every frame on the bus and
    /// filter on the header's target (0x0000 and 0xFFFF are broadcast).
    pub fn on_frame(
        &mut self,
        now_us: u64,
        frame: &[u8],
        reply: &mut [u8; MAX_FRAME_LEN],
    ) -> Option<usize> {
        let message = Message::decode_frame(WIRE, frame).ok()?;
        let target = message.header.target_id;
        if target != self.node {
            return None;
        }
        let id = message.header.msg_id;
        let answer = match self.handle(now_us, &message.payload) {
            Ok(()) => Payload::Ack(id),
            Err(code) => Payload::Nack { id, error: code.0 },
        };
        let out = Message {
            header: Header {
                source_id: self.node,
                target_id: message.header.source_id,
                msg_id: id,
            },
            payload: answer,
        };
        out.encode_frame(WIRE, reply).ok()
    }

    fn handle(&mut self, now_us: u64, payload: &Payload) -> Result<(), NackCode> {
        use LifecycleState::{Active, Inactive, Unconfigured};
        match (payload, self.state) {
            (Payload::Configure, Unconfigured) => self.state = Inactive,
            (Payload::Configure, _) => return Err(NackCode::CONFIGURE_WRONG_STATE),
            (Payload::Activate, Inactive) => self.state = Active,
            (Payload::Activate, _) => return Err(NackCode::ACTIVATE_WRONG_STATE),
            (Payload::Deactivate, Active) => {
                self.hold(now_us);
                self.state = Inactive;
            }
            (Payload::Deactivate, _) => return Err(NackCode::DEACTIVATE_WRONG_STATE),
            (Payload::Reset, _) => {
                self.hold(now_us);
                self.state = Unconfigured;
            }
            (Payload::SetTargetV2(target), Active) => self.start(now_us, target)?,
            (Payload::SetTargetV2(_), _) => return Err(NackCode::SET_TARGET_WRONG_STATE),
            _ => return Err(NackCode::UNKNOWN_PAYLOAD),
        }
        Ok(())
    }

    /// Stops where the motion is now (a real joint would brake).
    fn hold(&mut self, now_us: u64) {
        let here = self.tick(now_us).position;
        self.motion = Profile::at_rest(here);
        self.started_us = now_us;
    }

    /// Plans the move from the state the joint is in now, so a new target
    /// mid-motion blends from the current position and velocity.
    fn start(&mut self, now_us: u64, target: &SetTargetPayloadV2) -> Result<(), NackCode> {
        let fields = [
            target.target_angle,
            target.max_velocity,
            target.target_velocity,
            target.max_acceleration,
            target.max_deceleration,
            target.max_jerk,
        ];
        if fields.iter().any(|x| !x.is_finite()) {
            return Err(NackCode::NON_FINITE);
        }
        if target.target_angle < TRAVEL_DEG.0 || target.target_angle > TRAVEL_DEG.1 {
            return Err(NackCode::OUT_OF_LIMITS);
        }
        let now = self.tick(now_us);
        let request = target.planner_request(now.position, now.velocity);
        let profile = plan(&request).map_err(|_| NackCode::OUT_OF_LIMITS)?;
        self.motion = profile;
        self.started_us = now_us;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(target_id: u16, msg_id: u32, payload: Payload) -> ([u8; MAX_FRAME_LEN], usize) {
        let mut buf = [0u8; MAX_FRAME_LEN];
        let message = Message {
            header: Header {
                source_id: 0,
                target_id,
                msg_id,
            },
            payload,
        };
        let len = message.encode_frame(WIRE, &mut buf).unwrap_or(0);
        (buf, len)
    }

    fn send(joint: &mut Joint, now_us: u64, msg_id: u32, payload: Payload) -> Option<Vec<u8>> {
        let (buf, len) = frame(0x10, msg_id, payload);
        let mut reply = [0u8; MAX_FRAME_LEN];
        let n = joint.on_frame(now_us, buf.get(..len)?, &mut reply)?;
        reply.get(..n).map(<[u8]>::to_vec)
    }

    extern crate std;
    use std::vec::Vec;

    #[test]
    fn set_target_before_activate_is_nacked_4_then_acked_after() {
        let mut joint = Joint::new(0x10, 0.0);
        let target = Payload::SetTargetV2(SetTargetPayloadV2::scurve(90.0, 100.0, 500.0, 2000.0));
        // 0x10 -> 0x0000, msg_id 7, Nack {7, 4}: tag 9, id 7, error 4.
        assert_eq!(
            send(&mut joint, 0, 7, target),
            Some(std::vec![0x10, 0x00, 0x07, 0x09, 0x07, 0x04])
        );
        assert_eq!(
            send(&mut joint, 0, 8, Payload::Configure),
            Some(std::vec![0x10, 0x00, 0x08, 0x08, 0x08])
        );
        assert_eq!(
            send(&mut joint, 0, 9, Payload::Activate),
            Some(std::vec![0x10, 0x00, 0x09, 0x08, 0x09])
        );
        assert_eq!(
            send(&mut joint, 0, 10, target),
            Some(std::vec![0x10, 0x00, 0x0a, 0x08, 0x0a])
        );
        assert_eq!(joint.state(), LifecycleState::Active);
        assert_eq!(joint.tick(0).position, 0.0);
        assert_eq!(joint.tick(5_000_000).position, 90.0);
    }

    #[test]
    fn frames_for_another_node_or_garbage_are_ignored() {
        let mut joint = Joint::new(0x10, 0.0);
        let mut reply = [0u8; MAX_FRAME_LEN];
        let (buf, len) = frame(0x11, 1, Payload::Configure);
        assert_eq!(
            joint.on_frame(0, buf.get(..len).unwrap_or(&[]), &mut reply),
            None
        );
        assert_eq!(joint.on_frame(0, &[0xff; 9], &mut reply), None);
        assert_eq!(joint.state(), LifecycleState::Unconfigured);
    }

    #[test]
    fn a_target_outside_travel_is_nacked_16_and_not_moved() {
        let mut joint = Joint::new(0x10, 0.0);
        send(&mut joint, 0, 1, Payload::Configure);
        send(&mut joint, 0, 2, Payload::Activate);
        let far = Payload::SetTargetV2(SetTargetPayloadV2::trapezoidal(270.0, 100.0, 500.0));
        assert_eq!(
            send(&mut joint, 0, 3, far),
            Some(std::vec![0x10, 0x00, 0x03, 0x09, 0x03, 0x10])
        );
        assert_eq!(joint.tick(10_000_000).position, 0.0);
    }
}
