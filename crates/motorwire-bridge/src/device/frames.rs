//! One request in flight per device, on a CAN bus: what the compact and
//! moteus drivers share. A request is a frame sent and awaited; the first
//! answer from its device acknowledges it (each driver says what an answer
//! is); one not answered in time is sent again (the device executes a
//! repeat of its last command once), then given up, by the one retry rule
//! of every driver ([`motorwire_can::retry::Attempts`]).

use std::collections::{BTreeMap, VecDeque};
use std::time::Duration;

use motorwire_can::Frame;
use motorwire_can::retry::{Attempts, Expiry};

use super::{DeviceId, Ended, Outcome};

/// A frame sent and not yet answered.
#[derive(Debug)]
struct Pending {
    msg_id: u32,
    frame: Frame,
    attempts: Attempts,
}

/// The requests in flight (one per device, keyed by it) and the frames
/// to send.
#[derive(Debug)]
pub(crate) struct FrameRequests {
    pending: BTreeMap<DeviceId, Pending>,
    tx: VecDeque<Frame>,
    next_id: u32,
    timeout: Duration,
    retries: u8,
}

impl FrameRequests {
    /// Requests that wait `timeout` for their answer and are sent again up
    /// to `retries` times.
    pub(crate) fn new(timeout: Duration, retries: u8) -> Self {
        Self {
            pending: BTreeMap::new(),
            tx: VecDeque::new(),
            next_id: 1,
            timeout,
            retries,
        }
    }

    /// Queues `frame` for `device` and awaits its answer; returns its id.
    pub(crate) fn send(&mut self, now: Duration, device: DeviceId, frame: Frame) -> u32 {
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
        msg_id
    }

    /// Queues `frame`, awaiting nothing (a poll).
    pub(crate) fn push(&mut self, frame: Frame) {
        self.tx.push_back(frame);
    }

    /// Whether `device` has a request in flight.
    pub(crate) fn awaits(&self, device: DeviceId) -> bool {
        self.pending.contains_key(&device)
    }

    /// An answer came from `device` at `now`: the request it waited for,
    /// if any, is acknowledged.
    /// The frame of `device`'s request in flight, if one is.
    pub(crate) fn in_flight(&self, device: DeviceId) -> Option<&Frame> {
        self.pending.get(&device).map(|p| &p.frame)
    }

    pub(crate) fn acknowledged(&mut self, device: DeviceId, now: Duration) -> Option<Ended> {
        self.pending.remove(&device).map(|p| Ended {
            msg_id: p.msg_id,
            outcome: Outcome::Acked,
            attempts: p.attempts.sent(),
            at: now,
        })
    }

    /// `device`'s request is given up (sent; its outcome no longer
    /// awaited).
    pub(crate) fn forget(&mut self, device: DeviceId) {
        self.pending.remove(&device);
    }

    /// `device`'s request, if it was never handed out (its first sending
    /// still queued): taken out of the queue and forgotten. Whether it was.
    pub(crate) fn take_back_unsent(&mut self, device: DeviceId) -> bool {
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

    /// Requests whose answer is overdue at `now`: each sent again until
    /// its retries are spent; those given up, by device.
    pub(crate) fn timeouts(&mut self, now: Duration) -> Vec<(DeviceId, Ended)> {
        let mut given_up = Vec::new();
        for (&device, p) in &mut self.pending {
            match p.attempts.expire(now, true) {
                Expiry::Waiting => {}
                Expiry::Resend => self.tx.push_back(p.frame),
                Expiry::GiveUp => given_up.push(device),
            }
        }
        given_up
            .into_iter()
            .filter_map(|device| {
                let p = self.pending.remove(&device)?;
                Some((
                    device,
                    Ended {
                        msg_id: p.msg_id,
                        outcome: Outcome::TimedOut,
                        attempts: p.attempts.sent(),
                        at: now,
                    },
                ))
            })
            .collect()
    }

    /// The next answer's deadline.
    pub(crate) fn deadline(&self) -> Option<Duration> {
        self.pending.values().map(|p| p.attempts.deadline()).min()
    }

    /// The next frame to send.
    pub(crate) fn poll_transmit(&mut self) -> Option<Frame> {
        self.tx.pop_front()
    }
}
