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

use std::collections::{BTreeMap, VecDeque};
use std::time::Duration;

use motorwire_can::retry::{Attempts, Expiry};

use motorwire_can::{CanId, Frame};
use motorwire_compact::{CompactCommand, FeedbackRecord, MotorHash, StatusFlag};
use motorwire_wia::MotorFeedback;

use super::{Ended, Outcome};

/// `c` as its CAN-FD frame on `node` (WIRE-FACTS §2.1: the 24 bytes, no
/// padding).
///
/// # Errors
/// The codec's refusal of the command, or a node beyond 11 bits, as text.
pub(crate) fn command_frame(node: u16, c: CompactCommand) -> Result<Frame, String> {
    let bytes = c.encode().map_err(|e| e.to_string())?;
    let id = CanId::standard(node).map_err(|e| e.to_string())?;
    Frame::fd(id, &bytes).map_err(|e| e.to_string())
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
) -> Result<FeedbackRecord, String> {
    match FeedbackRecord::decode(frame.data()) {
        Ok(r) if r.motor == hash => Ok(r),
        Ok(r) => Err(format!(
            "feedback for motor hash {:08x}, not {motor}'s {:08x}",
            r.motor.0, hash.0
        )),
        Err(e) => Err(e.to_string()),
    }
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

/// A command sent and not yet acknowledged by a feedback record.
#[derive(Debug)]
struct Pending {
    msg_id: u32,
    frame: Frame,
    attempts: Attempts,
}

/// The compact devices' requests in flight and frames to send, by device
/// index (the engine's).
#[derive(Debug)]
pub(crate) struct CompactDriver {
    pending: BTreeMap<usize, Pending>,
    tx: VecDeque<Frame>,
    next_id: u32,
    timeout: Duration,
    retries: u8,
}

impl CompactDriver {
    /// A driver whose commands wait `timeout` for their acknowledgement
    /// and are sent again up to `retries` times.
    pub(crate) fn new(timeout: Duration, retries: u8) -> Self {
        Self {
            pending: BTreeMap::new(),
            tx: VecDeque::new(),
            next_id: 1,
            timeout,
            retries,
        }
    }

    /// Queues `c` for `device` on CAN id `node` and awaits its
    /// acknowledgement; returns its id.
    ///
    /// # Errors
    /// [`command_frame`]'s; nothing is queued.
    pub(crate) fn send(
        &mut self,
        now: Duration,
        device: usize,
        node: u16,
        c: CompactCommand,
    ) -> Result<u32, String> {
        let frame = command_frame(node, c)?;
        let msg_id = self.next_id;
        self.next_id = self.next_id.wrapping_add(1);
        self.tx.push_back(frame);
        self.pending.insert(
            device,
            Pending {
                msg_id,
                frame,
                attempts: Attempts::first(now, self.timeout, self.retries),
            },
        );
        Ok(msg_id)
    }

    /// A valid feedback record came from `device` at `now`: the command
    /// it waited for, if any, is acknowledged.
    pub(crate) fn acknowledged(&mut self, device: usize, now: Duration) -> Option<Ended> {
        self.pending.remove(&device).map(|p| Ended {
            msg_id: p.msg_id,
            outcome: Outcome::Acked,
            attempts: p.attempts.sent(),
            at: now,
        })
    }

    /// `device`'s command is given up (sent; its outcome no longer
    /// awaited).
    pub(crate) fn forget(&mut self, device: usize) {
        self.pending.remove(&device);
    }

    /// `device`'s command, if it was never handed out (its first sending
    /// still queued): taken out of the queue and forgotten. Whether it was.
    pub(crate) fn take_back_unsent(&mut self, device: usize) -> bool {
        let Some(p) = self.pending.get(&device) else {
            return false;
        };
        if p.attempts.sent() != 1 {
            return false;
        }
        let Some(at) = self.tx.iter().position(|f| *f == p.frame) else {
            return false;
        };
        self.tx.remove(at);
        self.pending.remove(&device);
        true
    }

    /// Commands whose acknowledgement is overdue at `now`: each sent again
    /// (the device executes a repeat of its last command once) until its
    /// retries are spent; those given up, by device.
    pub(crate) fn timeouts(&mut self, now: Duration) -> Vec<(usize, Ended)> {
        let mut ended = Vec::new();
        let mut given_up = Vec::new();
        for (&device, p) in &mut self.pending {
            match p.attempts.expire(now, true) {
                Expiry::Waiting => {}
                Expiry::Resend => self.tx.push_back(p.frame),
                Expiry::GiveUp => given_up.push(device),
            }
        }
        for device in given_up {
            if let Some(p) = self.pending.remove(&device) {
                ended.push((
                    device,
                    Ended {
                        msg_id: p.msg_id,
                        outcome: Outcome::TimedOut,
                        attempts: p.attempts.sent(),
                        at: now,
                    },
                ));
            }
        }
        ended
    }

    /// The next acknowledgement deadline.
    pub(crate) fn deadline(&self) -> Option<Duration> {
        self.pending.values().map(|p| p.attempts.deadline()).min()
    }

    /// The next frame to send.
    pub(crate) fn poll_transmit(&mut self) -> Option<Frame> {
        self.tx.pop_front()
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;
    use motorwire_compact::{ControlMode, Flags};

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
            command_frame(0x800, c).unwrap_err(),
            CanId::standard(0x800).unwrap_err().to_string()
        );
    }

    #[test]
    fn a_command_is_sent_again_then_given_up_and_a_record_acknowledges_it() {
        let ms = Duration::from_millis;
        let mut d = CompactDriver::new(ms(100), 2);
        assert_eq!(d.send(ms(0), 3, 0x20, command(1.0)), Ok(1));
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
                3,
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
        assert_eq!(d.send(ms(300), 3, 0x20, command(2.0)), Ok(2));
        assert_eq!(
            d.acknowledged(3, ms(310)),
            Some(Ended {
                msg_id: 2,
                outcome: Outcome::Acked,
                attempts: 1,
                at: ms(310)
            })
        );
        assert_eq!(d.acknowledged(3, ms(311)), None);
    }

    #[test]
    fn only_a_first_sending_still_queued_is_taken_back() {
        let ms = Duration::from_millis;
        let mut d = CompactDriver::new(ms(100), 3);
        d.send(ms(0), 1, 0x20, command(1.0)).unwrap();
        d.send(ms(0), 2, 0x21, command(1.0)).unwrap();
        assert!(d.take_back_unsent(1));
        // Device 2's frame is the only one left.
        assert_eq!(d.poll_transmit().map(|f| f.id().raw()), Some(0x21));
        // Handed out: it stays (it may have run).
        assert!(!d.take_back_unsent(2));
        assert!(d.acknowledged(2, ms(1)).is_some());
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
            feedback_record(&frame, "gripper_axis", MotorHash(0x1122_3344)).unwrap_err(),
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
