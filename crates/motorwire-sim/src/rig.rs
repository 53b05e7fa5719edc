//! A deterministic test rig: an iRPC [`Client`] and simulated joints on one
//! in-memory bus in simulated time, stepped from event to event (quinn's
//! `Pair`, for CAN). Protocol tests run exactly, reproducibly and fast.
//!
//! ```
//! use motorwire_can::{SimConfig, client::{ClientConfig, Outcome}};
//! use motorwire_irpc::Payload;
//! use motorwire_sim::{JointConfig, rig::Rig};
//!
//! let mut rig = Rig::new(SimConfig::default(), ClientConfig::default(), [JointConfig::new(0x10)])?;
//! assert_eq!(rig.request(0x10, Payload::Activate)?.outcome, Outcome::Nacked(2.into())); // not configured
//! assert_eq!(rig.request(0x10, Payload::Configure)?.outcome, Outcome::Acked);
//! assert_eq!(rig.request(0x10, Payload::Activate)?.outcome, Outcome::Acked);
//! # Ok::<(), motorwire_sim::SimError>(())
//! ```

use std::time::Duration;

use motorwire_can::client::{Client, ClientConfig, Completion, Event};
use motorwire_can::{CanBus, SimBus, SimConfig, SimPort};
use motorwire_irpc::Payload;

use crate::{JointConfig, SimError, SimJoint};

/// A client and joints on a simulated bus.
#[derive(Debug)]
pub struct Rig {
    bus: SimBus,
    arm: SimPort,
    /// The client (make requests on it, or use [`Rig::request`]).
    pub client: Client,
    joints: Vec<(SimPort, SimJoint)>,
    events: Vec<Event>,
}

impl Rig {
    /// A bus with `bus` settings (its clock is made simulated), a client and
    /// one simulated joint per configuration.
    ///
    /// # Errors
    /// An invalid configuration.
    pub fn new(
        bus: SimConfig,
        client: ClientConfig,
        joints: impl IntoIterator<Item = JointConfig>,
    ) -> Result<Self, SimError> {
        let bus = SimBus::new(SimConfig {
            clock: motorwire_can::Clock::Simulated,
            ..bus
        })?;
        let arm = bus.port();
        let joints = joints
            .into_iter()
            .map(|c| Ok((bus.port(), SimJoint::new(c)?)))
            .collect::<Result<Vec<_>, SimError>>()?;
        Ok(Self {
            client: Client::new(client)?,
            bus,
            arm,
            joints,
            events: Vec::new(),
        })
    }

    /// The bus (its clock, its fault statistics).
    pub fn bus(&self) -> &SimBus {
        &self.bus
    }

    /// The joint with node id `node`.
    pub fn joint(&self, node: u16) -> Option<&SimJoint> {
        self.joints
            .iter()
            .map(|(_, j)| j)
            .find(|j| j.config().node_id == node)
    }

    /// The joint with node id `node`, mutable.
    pub fn joint_mut(&mut self, node: u16) -> Option<&mut SimJoint> {
        self.joints
            .iter_mut()
            .map(|(_, j)| j)
            .find(|j| j.config().node_id == node)
    }

    /// Takes the events the client reported that no [`Rig::request`] consumed
    /// (feedback, stray replies, undecodable frames).
    pub fn take_events(&mut self) -> Vec<Event> {
        std::mem::take(&mut self.events)
    }

    /// Handles everything due at the current time, then moves the clock to
    /// the next thing anyone has to do (or by at most `max`).
    ///
    /// # Errors
    /// The bus's errors.
    pub fn step(&mut self, max: Duration) -> Result<(), SimError> {
        let now = self.bus.now();
        // Until quiet: frames sent now with no latency are due now too.
        loop {
            let mut busy = false;
            while let Some(f) = self.client.poll_transmit() {
                self.arm.send(&f)?;
                busy = true;
            }
            for (port, joint) in &mut self.joints {
                busy |= joint.serve(port, now)?;
            }
            while let Some(r) = self.arm.try_recv() {
                self.client.handle_frame(now, &r.frame);
                busy = true;
            }
            if self.client.poll_timeout().is_some_and(|t| t <= now) {
                self.client.handle_timeout(now);
                busy = true;
            }
            if !busy {
                break;
            }
        }
        let next = [
            self.client.poll_timeout(),
            self.bus.next_delivery(),
            self.joints
                .iter()
                .filter_map(|(_, j)| j.poll_timeout())
                .min(),
        ]
        .into_iter()
        .flatten()
        .min()
        .map_or(now.saturating_add(max), |t| t.min(now.saturating_add(max)));
        self.bus
            .advance_to(next.max(now.saturating_add(Duration::from_nanos(1))));
        Ok(())
    }

    /// Runs until the bus clock reaches `t`.
    ///
    /// # Errors
    /// The bus's errors.
    pub fn run_until(&mut self, t: Duration) -> Result<(), SimError> {
        while self.bus.now() < t {
            let left = t - self.bus.now();
            self.step(left)?;
            self.drain();
        }
        Ok(())
    }

    fn drain(&mut self) {
        while let Some(e) = self.client.poll_event() {
            self.events.push(e);
        }
    }

    /// Sends `payload` to `node` and runs until it completes (acked, nacked,
    /// or timed out after its retries).
    ///
    /// # Errors
    /// The client's encode errors; the bus's errors.
    pub fn request(&mut self, node: u16, payload: Payload) -> Result<Completion, SimError> {
        let id = self.client.request(self.bus.now(), node, payload)?;
        loop {
            self.step(Duration::from_secs(1))?;
            while let Some(e) = self.client.poll_event() {
                match e {
                    Event::Completed(c) if c.msg_id == id => return Ok(c),
                    other => self.events.push(other),
                }
            }
        }
    }
}
