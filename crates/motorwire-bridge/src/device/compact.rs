//! The compact driver: WIA's 24-byte compact command on CAN-FD
//! (WIRE-FACTS §2.1), each device answering with its Phase 3 feedback
//! record on its own feedback id.
//!
//! It owns the dialect's encoding (a command's frame, built by a pure
//! function first and queued second), its requests in flight (one per
//! device: the first valid feedback record after a command acknowledges
//! it; a command not acknowledged in time is sent again, then given up),
//! and its feedback decoding into WIA `MotorFeedback`. The engine decides
//! what is sent and when; this says how, and what came back.

use super::DeviceError;
use motorwire_can::{CanId, Frame};
use motorwire_compact::{CompactCommand, FeedbackRecord, MotorHash, StatusFlag};
use motorwire_wia::MotorFeedback;

/// `c` as its CAN-FD frame on `node` (WIRE-FACTS §2.1: the 24 bytes, no
/// padding).
///
/// # Errors
/// The codec's refusal of the command, or a node beyond 11 bits.
pub(crate) fn command_frame(node: u16, c: CompactCommand) -> Result<Frame, DeviceError> {
    let bytes = c.encode().map_err(DeviceError::Compact)?;
    let id = CanId::standard(node).map_err(DeviceError::Frame)?;
    Frame::fd(id, &bytes).map_err(DeviceError::Frame)
}

/// A frame from a device's feedback id, read for the device whose motor
/// hash is `hash`.
///
/// # Errors
/// What is wrong with it, as a bad-frame event says it: not a feedback
/// record, or another motor's.
pub(crate) fn feedback_record(
    frame: &Frame,
    motor: &str,
    hash: MotorHash,
) -> Result<FeedbackRecord, DeviceError> {
    match FeedbackRecord::decode(frame.data()) {
        Ok(r) if r.motor == hash => Ok(r),
        Ok(r) => Err(DeviceError::OtherMotor {
            got: r.motor,
            motor: motor.to_owned(),
            want: hash,
        }),
        Err(e) => Err(DeviceError::Compact(e)),
    }
}

/// Whether `frame` is a compact command with the EMERGENCY_STOP flag.
pub(crate) fn is_stop(frame: &Frame) -> bool {
    CompactCommand::decode(frame.data())
        .is_ok_and(|c| c.flags.contains(motorwire_compact::Flags::EMERGENCY_STOP))
}

/// A device's feedback record as WIA MotorFeedback (positions in the
/// motor's own unit, as the device reports them).
pub(crate) fn feedback_to_wia(motor: &str, timestamp: f64, r: &FeedbackRecord) -> MotorFeedback {
    let s = r.status;
    let mut f = MotorFeedback {
        motor_id: motor.to_owned(),
        timestamp,
        position: f64::from(r.position),
        velocity: f64::from(r.velocity),
        acceleration: Some(f64::from(r.acceleration)),
        torque: f64::from(r.torque),
        current: Some(f64::from(r.current)),
        voltage: Some(f64::from(r.voltage)),
        temperature: Some(f64::from(r.temperature)),
        power: None,
        position_error: None,
        velocity_error: None,
        control_effort: None,
        status: motorwire_wia::MotorStatus::default(),
        health: None,
        extra: serde_json::Map::new(),
    };
    f.status.enabled = Some(s.contains(StatusFlag::Enabled));
    f.status.fault = Some(s.contains(StatusFlag::Fault));
    f.status.warning = Some(s.contains(StatusFlag::Warning));
    f.status.in_motion = Some(s.contains(StatusFlag::InMotion));
    f.status.at_target = Some(s.contains(StatusFlag::AtTarget));
    f
}

/// The compact devices' requests in flight and frames to send: a
/// command's frame ([`command_frame`]) sent for its device, acknowledged
/// by the device's first valid feedback record after it.
pub(crate) type CompactDriver = super::frames::FrameRequests;

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;
    use crate::device::{DeviceId, Ended, Outcome};
    use motorwire_compact::{ControlMode, Flags};
    use std::time::Duration;

    fn command(setpoint: f32) -> CompactCommand {
        CompactCommand {
            motor: MotorHash(0x1122_3344),
            timestamp_ms: 7,
            control_mode: ControlMode::Position,
            flags: Flags::REQUIRE_ACK,
            setpoint,
            velocity_limit: None,
            torque_limit: None,
        }
    }

    #[test]
    fn a_command_is_its_24_bytes_on_its_node() {
        let c = command(1.5);
        let f = command_frame(0x20, c).unwrap();
        assert_eq!(f.id(), CanId::standard(0x20).unwrap());
        assert_eq!(f.data(), c.encode().unwrap().as_slice());
        assert_eq!(f.data().len(), 24);
        assert_eq!(
            command_frame(0x800, c).unwrap_err().to_string(),
            CanId::standard(0x800).unwrap_err().to_string()
        );
    }

    #[test]
    fn a_command_is_sent_again_then_given_up_and_a_record_acknowledges_it() {
        let ms = Duration::from_millis;
        let mut d = CompactDriver::new(ms(100), 2);
        assert_eq!(
            d.send(
                ms(0),
                DeviceId(3),
                command_frame(0x20, command(1.0)).unwrap()
            ),
            1
        );
        let first = d.poll_transmit().unwrap();
        assert_eq!(d.poll_transmit(), None);
        assert_eq!(d.deadline(), Some(ms(100)));
        assert_eq!(d.timeouts(ms(99)), []);
        // Two more sendings of the same frame, then given up.
        assert_eq!(d.timeouts(ms(100)), []);
        assert_eq!(d.poll_transmit(), Some(first));
        assert_eq!(d.timeouts(ms(200)), []);
        assert_eq!(d.poll_transmit(), Some(first));
        assert_eq!(
            d.timeouts(ms(300)),
            [(
                DeviceId(3),
                Ended {
                    msg_id: 1,
                    outcome: Outcome::TimedOut,
                    attempts: 3,
                    at: ms(300)
                }
            )]
        );
        assert_eq!((d.deadline(), d.poll_transmit()), (None, None));
        // The next command: acknowledged by the device's record.
        assert_eq!(
            d.send(
                ms(300),
                DeviceId(3),
                command_frame(0x20, command(2.0)).unwrap()
            ),
            2
        );
        assert_eq!(
            d.acknowledged(DeviceId(3), ms(310)),
            Some(Ended {
                msg_id: 2,
                outcome: Outcome::Acked,
                attempts: 1,
                at: ms(310)
            })
        );
        assert_eq!(d.acknowledged(DeviceId(3), ms(311)), None);
    }

    #[test]
    fn only_a_first_sending_still_queued_is_taken_back() {
        let ms = Duration::from_millis;
        let mut d = CompactDriver::new(ms(100), 3);
        d.send(
            ms(0),
            DeviceId(1),
            command_frame(0x20, command(1.0)).unwrap(),
        );
        d.send(
            ms(0),
            DeviceId(2),
            command_frame(0x21, command(1.0)).unwrap(),
        );
        assert!(d.take_back_unsent(DeviceId(1)));
        // Device 2's frame is the only one left.
        assert_eq!(d.poll_transmit().map(|f| f.id().raw()), Some(0x21));
        // Handed out: it stays (it may have run).
        assert!(!d.take_back_unsent(DeviceId(2)));
        assert!(d.acknowledged(DeviceId(2), ms(1)).is_some());
    }

    #[test]
    fn feedback_for_another_motor_is_said_so() {
        let r = FeedbackRecord {
            motor: MotorHash(0xAABB_CCDD),
            timestamp_us: 1_500_000,
            position: 45.0,
            velocity: -2.5,
            acceleration: 0.0,
            torque: 1.5,
            current: 2.0,
            voltage: 24.0,
            temperature: 25.0,
            status: motorwire_compact::StatusFlags::EMPTY.with(StatusFlag::Enabled),
            health: 100,
        };
        let frame = Frame::fd(CanId::standard(0x420).unwrap(), &r.encode().unwrap()).unwrap();
        assert_eq!(
            feedback_record(&frame, "gripper_axis", MotorHash(0x1122_3344))
                .unwrap_err()
                .to_string(),
            "feedback for motor hash aabbccdd, not gripper_axis's 11223344"
        );
        assert_eq!(
            feedback_record(&frame, "gripper_axis", MotorHash(0xAABB_CCDD)).unwrap(),
            r
        );
        let f = feedback_to_wia("gripper_axis", 12.0, &r);
        assert_eq!(
            (
                f.position,
                f.velocity,
                f.voltage,
                f.status.enabled,
                f.status.fault
            ),
            (45.0, -2.5, Some(24.0), Some(true), Some(false))
        );
    }
}
