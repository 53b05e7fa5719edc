//! The iRPC client: the arm's side of the conversation with its joints.
//!
//! Sans-IO, after quinn: it never touches a bus or a clock. Give it frames
//! ([`Client::handle_frame`]) and the time ([`Client::handle_timeout`]); take
//! frames to send ([`Client::poll_transmit`]), results and feedback
//! ([`Client::poll_event`]) and its next deadline ([`Client::poll_timeout`]).
//! [`Client::drive`] does all of that on a blocking [`CanBus`].
//!
//! Every request gets a fresh `msg_id`; the joint answers `Ack(msg_id)` or
//! `Nack { id: msg_id, error }`. A request unanswered after
//! [`ClientConfig::timeout`] is sent again **with the same msg_id** (so the
//! joint can discard the duplicate and answer again), at most
//! [`ClientConfig::retries`] times, then reported timed out.
//!
//! **Exactly once.** A joint remembers the answers to a bounded number of
//! each sender's last requests (motorwire's simulated joint: 256). The
//! client keeps at most [`ClientConfig::max_in_flight`] requests (default 1)
//! in flight to each node, so between a request's first send and its last
//! resend no other new request reaches that node: every resend falls
//! inside the joint's memory and is answered, never executed again. A
//! request the caller gives up on ([`Client::cancel`]) is never sent again.
//!
//! **Wire versions.** Each node is spoken to in its own wire version
//! ([`Client::set_wire`]; [`ClientConfig::wire`] for the rest): requests are
//! encoded in the target's version and frames decoded in the sender's (the
//! CAN id is the sender's node id).
//!
//! **Messages over one frame** (WIRE-FACTS §1.5: TelemetryStream,
//! PowerMetrics, CalibrationResult, FaultHistory can exceed 64 bytes)
//! travel as ISO-TP over CAN-FD on 29-bit CAN ids that name both ends,
//! motorwire's decision described in [`crate::segmented`]: data from
//! `source` to `target` on `0x1000_0000 | (target << 11) | source`
//! ([`segmented_ids`]), flow control on the swapped id. A message that fits
//! 64 bytes is one plain frame, as always. The client reassembles what
//! joints send it (one transfer per joint at a time, at most
//! [`ClientConfig::max_message_len`] bytes, [`ClientConfig::transfer_timeout`]
//! between a joint's frames), answers with flow control from
//! [`Client::poll_transmit`], and reports the message like any other
//! (Ack, Nack, [`Event::Feedback`]); a transfer that fails or does not
//! decode is an [`Event::Undecodable`] naming why ([`FrameError`]). A
//! request over 64 bytes goes out the same way, one transfer per target at
//! a time; a retry sends the same bytes, same msg_id, from a new first
//! frame. [`Client::poll_timeout`] and [`Client::handle_timeout`] drive the
//! transfers' timeouts and pacing.
//!
//! ```
//! use std::time::Duration;
//! use motorwire_can::{CanBus, SimBus, client::{Client, ClientConfig, Event, Outcome}};
//! use motorwire_irpc::{Header, Message, Payload, WireVersion};
//!
//! let bus = SimBus::default();
//! let (mut arm, mut joint) = (bus.port(), bus.port());
//! let mut client = Client::new(ClientConfig::default())?;
//! let id = client.configure(bus.now(), 0x10)?;
//! arm.send(&client.poll_transmit().unwrap())?;
//!
//! // The joint (here by hand) answers Ack(msg_id) from node 0x10.
//! let got = Message::decode_frame(WireVersion::V2_0, joint.recv(Duration::ZERO)?.frame.data())?;
//! assert_eq!(got.payload, Payload::Configure);
//! let ack = Message { header: Header { source_id: 0x10, target_id: 0, msg_id: id }, payload: Payload::Ack(id) };
//! let mut buf = [0u8; 64];
//! let n = ack.encode_frame(WireVersion::V2_0, &mut buf)?;
//! joint.send(&motorwire_can::Frame::fd(motorwire_can::CanId::standard(0x10)?, &buf[..n])?)?;
//!
//! let r = arm.recv(Duration::ZERO)?;
//! client.handle_frame(r.timestamp, &r.frame);
//! match client.poll_event() {
//!     Some(Event::Completed(c)) => assert_eq!((c.msg_id, c.outcome, c.attempts), (id, Outcome::Acked, 1)),
//!     other => panic!("{other:?}"),
//! }
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use std::collections::{BTreeMap, VecDeque};
use std::fmt;
use std::time::Duration;

use motorwire_irpc::{
    ConfigureTelemetryPayload, Header, MAX_FRAME_LEN, Message, NackCode, Payload, PayloadKind,
    SetTargetPayload, SetTargetPayloadV2, TelemetryMode, WireVersion,
};

use crate::isotp::IsoTpError;
use crate::retry::{Attempts, Expiry};
use crate::segmented::{LinkEvent, Links};
pub use crate::segmented::{SegmentedIds, segmented_ids};
use crate::{CanBus, CanId, Error, Frame};

/// The node id iRPC gives the arm.
pub const ARM_NODE: u16 = 0x0000;
/// The broadcast target ArmReady is sent to (0x0000 is also accepted as broadcast).
pub const BROADCAST: u16 = 0xFFFF;

/// How a [`Client`] behaves.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ClientConfig {
    /// This node's id: the header's source and the CAN id of its frames.
    pub node_id: u16,
    /// The wire version spoken.
    pub wire: WireVersion,
    /// How long to wait for an Ack or Nack before sending again.
    pub timeout: Duration,
    /// How many times to send again before giving up.
    pub retries: u8,
    /// The most requests in flight to one node at once (default 1; at least
    /// 1). More than one lets a joint's duplicate memory fall behind a
    /// resend and a bus that reorders run requests out of order.
    pub max_in_flight: usize,
    /// The msg_id of the first request (default 1). A new client talking to
    /// joints that heard an earlier one should start past that one's ids:
    /// `motorwire bridge` starts from the clock's microseconds.
    pub first_msg_id: u32,
    /// How long a segmented transfer waits for the peer's next frame
    /// (flow control, consecutive frame) before it fails (default 1 s,
    /// ISO 15765-2's N_Bs and N_Cr).
    pub transfer_timeout: Duration,
    /// The longest message accepted in a segmented transfer (default
    /// [`crate::segmented::DEFAULT_MAX_LEN`], 256 bytes; the longest iRPC
    /// message is 148). A longer first frame is refused with flow status
    /// overflow.
    pub max_message_len: usize,
}

impl Default for ClientConfig {
    /// The arm (node 0x0000), v2.0, 100 ms, 3 retries, one request in
    /// flight per node, msg_ids from 1; segmented transfers of up to 256
    /// bytes, 1 s between frames.
    fn default() -> Self {
        Self {
            node_id: ARM_NODE,
            wire: WireVersion::V2_0,
            timeout: Duration::from_millis(100),
            retries: 3,
            max_in_flight: 1,
            first_msg_id: 1,
            transfer_timeout: Duration::from_secs(1),
            max_message_len: crate::segmented::DEFAULT_MAX_LEN,
        }
    }
}

/// How a request ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Outcome {
    /// The joint accepted it.
    Acked,
    /// The joint refused it, saying why.
    Nacked(NackCode),
    /// No answer after every try.
    TimedOut,
}

impl fmt::Display for Outcome {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Acked => write!(f, "acked"),
            Self::Nacked(code) => write!(f, "nacked: {code}"),
            Self::TimedOut => write!(f, "timed out"),
        }
    }
}

/// A finished request.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Completion {
    /// Its msg_id.
    pub msg_id: u32,
    /// The node it was sent to.
    pub target: u16,
    /// What it asked.
    pub kind: PayloadKind,
    /// How it ended.
    pub outcome: Outcome,
    /// How many times it was sent.
    pub attempts: u8,
    /// When it was first handed out to send.
    pub sent_at: Duration,
    /// When it ended.
    pub finished_at: Duration,
}

/// What the client has to tell.
#[derive(Debug, Clone, PartialEq)]
pub enum Event {
    /// A request ended.
    Completed(Completion),
    /// A message from a joint that is not an answer (Encoder, JointStatus,
    /// TelemetryStream...).
    Feedback {
        /// The message.
        message: Message,
        /// When it arrived.
        at: Duration,
    },
    /// An Ack or Nack for no request in flight (a late answer to a retried
    /// request, or a joint's answer to another node).
    StrayReply {
        /// The message.
        message: Message,
    },
    /// A frame that is not a valid iRPC message, or a segmented transfer
    /// that failed or did not reassemble into one.
    Undecodable {
        /// Its CAN id (for a transfer, the id of its data frames).
        can_id: CanId,
        /// Why.
        error: FrameError,
    },
    /// A frame whose CAN id is not its header's source (WIRE-FACTS §1.5:
    /// the CAN id is the sender's node id), dropped.
    Misaddressed {
        /// Its CAN id.
        can_id: CanId,
        /// The message it carried.
        message: Message,
    },
}

/// Why a frame or a segmented transfer did not give an iRPC message.
///
/// ```
/// use motorwire_can::client::FrameError;
/// use motorwire_can::isotp::IsoTpError;
/// let e = FrameError::Irpc(motorwire_irpc::Error::InvalidFrameLength { len: 9 });
/// assert_eq!(e.to_string(), motorwire_irpc::Error::InvalidFrameLength { len: 9 }.to_string());
/// let t = FrameError::Transfer(IsoTpError::WrongSequence { expected: 2, got: 3 });
/// assert_eq!(t.to_string(), "segmented transfer: consecutive frame 3 out of sequence (expected 2)");
/// ```
#[derive(Debug, Clone, PartialEq, Eq)]
#[non_exhaustive]
pub enum FrameError {
    /// The bytes are not a valid iRPC message (a plain frame's, or a
    /// reassembled message's).
    Irpc(motorwire_irpc::Error),
    /// The segmented transfer failed: a timeout, a frame out of sequence,
    /// a length over [`ClientConfig::max_message_len`], a frame that is not
    /// ISO-TP.
    Transfer(IsoTpError),
}

impl fmt::Display for FrameError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Irpc(e) => write!(f, "{e}"),
            Self::Transfer(e) => write!(f, "segmented transfer: {e}"),
        }
    }
}

impl std::error::Error for FrameError {}

impl From<motorwire_irpc::Error> for FrameError {
    fn from(e: motorwire_irpc::Error) -> Self {
        Self::Irpc(e)
    }
}

/// Counters for what the client has seen.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ClientStats {
    /// Requests made.
    pub requests: u64,
    /// Frames sent again after a timeout.
    pub retransmissions: u64,
    /// Requests acked.
    pub acked: u64,
    /// Requests nacked.
    pub nacked: u64,
    /// Requests timed out.
    pub timed_out: u64,
    /// Stray replies.
    pub stray_replies: u64,
    /// Undecodable or misaddressed frames.
    pub bad_frames: u64,
    /// Frames sent from this client's own CAN id, heard back (a second
    /// socket on the same interface receives what the first sends): not
    /// decoded, not reported.
    pub own_frames: u64,
    /// Segmented transfers sent whole (requests over 64 bytes).
    pub segmented_sent: u64,
    /// Messages received by segmented transfer (decoded or not).
    pub segmented_received: u64,
    /// Segmented transfers from a peer that failed (reported as
    /// [`Event::Undecodable`]).
    pub failed_transfers: u64,
    /// Segmented transfers to a peer that failed (no flow control, or
    /// refused): the request is sent again at its timeout.
    pub failed_sends: u64,
}

/// How a request goes on the bus.
#[derive(Debug, Clone, PartialEq, Eq)]
enum Wire {
    /// One plain frame.
    Frame(Frame),
    /// A segmented transfer of these bytes.
    Segmented(Vec<u8>),
}

#[derive(Debug)]
struct Pending {
    target: u16,
    kind: PayloadKind,
    wire: Wire,
    attempts: Attempts,
    sent_at: Duration,
}

/// The sans-IO iRPC client.
#[derive(Debug)]
pub struct Client {
    config: ClientConfig,
    can_id: CanId,
    next_id: u32,
    pending: BTreeMap<u32, Pending>,
    /// Requests in flight per node.
    in_flight: BTreeMap<u16, usize>,
    /// The wire version of every node given one with [`Client::set_wire`]
    /// (the others speak `config.wire`).
    wires: BTreeMap<u16, WireVersion>,
    out: VecDeque<Frame>,
    links: Links,
    events: VecDeque<Event>,
    stats: ClientStats,
}

impl Client {
    /// A client.
    ///
    /// # Errors
    /// [`Error::InvalidId`] for a node id above 0x7FF (it is the frames'
    /// standard CAN id).
    pub fn new(config: ClientConfig) -> Result<Self, Error> {
        let can_id = CanId::standard(config.node_id)?;
        Ok(Self {
            links: Links::new(config.node_id, config.transfer_timeout)?
                .with_max_len(config.max_message_len),
            can_id,
            next_id: config.first_msg_id.max(1),
            config,
            pending: BTreeMap::new(),
            in_flight: BTreeMap::new(),
            wires: BTreeMap::new(),
            out: VecDeque::new(),
            events: VecDeque::new(),
            stats: ClientStats::default(),
        })
    }

    /// The configuration.
    pub fn config(&self) -> &ClientConfig {
        &self.config
    }

    /// The counters.
    pub fn stats(&self) -> ClientStats {
        self.stats
    }

    /// Requests still waiting for an answer.
    pub fn in_flight(&self) -> usize {
        self.pending.len()
    }

    /// Requests still waiting for an answer from `node`.
    pub fn in_flight_to(&self, node: u16) -> usize {
        self.in_flight.get(&node).copied().unwrap_or(0)
    }

    /// Whether a request to `node` would be taken now
    /// ([`ClientConfig::max_in_flight`]).
    pub fn can_request(&self, node: u16) -> bool {
        self.in_flight_to(node) < self.config.max_in_flight.max(1)
    }

    /// Speaks `wire` to `node` from now on (requests to it are encoded, and
    /// its frames decoded, in that version).
    ///
    /// ```
    /// use std::time::Duration;
    /// use motorwire_can::client::{Client, ClientConfig};
    /// use motorwire_irpc::{Payload, WireVersion};
    ///
    /// let mut client = Client::new(ClientConfig::default())?;
    /// client.set_wire(0x11, WireVersion::V2_1);
    /// client.request(Duration::ZERO, 0x10, Payload::Reset)?; // v2.0: Reset is tag 4
    /// client.request(Duration::ZERO, 0x11, Payload::Reset)?; // v2.1: also 4
    /// client.send(0xFFFF, Payload::ArmReady)?;               // broadcast, v2.0: tag 10
    /// assert_eq!(client.poll_transmit().unwrap().data(), [0x00, 0x10, 0x01, 0x04]);
    /// assert_eq!(client.poll_transmit().unwrap().data(), [0x00, 0x11, 0x02, 0x04]);
    /// assert_eq!(client.poll_transmit().unwrap().data()[..6], [0x00, 0xff, 0xff, 0x03, 0x03, 0x0a]);
    /// assert_eq!(client.wire_of(0x11), WireVersion::V2_1);
    /// # Ok::<(), motorwire_can::Error>(())
    /// ```
    pub fn set_wire(&mut self, node: u16, wire: WireVersion) {
        self.wires.insert(node, wire);
    }

    /// The wire version spoken to `node`.
    pub fn wire_of(&self, node: u16) -> WireVersion {
        self.wires.get(&node).copied().unwrap_or(self.config.wire)
    }

    /// Whether request `msg_id` is due to be sent again at `now` (its
    /// answer is late and it has retries left): a caller that must judge
    /// each sending afresh (a move whose path depends on where the joint
    /// is when it goes) asks before [`Client::handle_timeout`] resends it,
    /// and [`Client::cancel`]s it rather than let it go.
    pub fn resend_due(&self, msg_id: u32, now: Duration) -> bool {
        self.pending
            .get(&msg_id)
            .is_some_and(|p| p.attempts.resend_due(now))
    }

    /// Forgets the request `msg_id`: it is never sent again and completes
    /// with no event (a late answer to it is a [`Event::StrayReply`]).
    /// Returns whether it was in flight. An emergency stop cancels what it
    /// supersedes this way.
    pub fn cancel(&mut self, msg_id: u32) -> bool {
        let Some(p) = self.pending.remove(&msg_id) else {
            return false;
        };
        self.release(p.target);
        match p.wire {
            Wire::Frame(frame) => self.out.retain(|f| *f != frame),
            Wire::Segmented(_) => {
                self.links.cancel(p.target, msg_id);
            }
        }
        true
    }

    fn release(&mut self, target: u16) {
        if let Some(n) = self.in_flight.get_mut(&target) {
            *n = n.saturating_sub(1);
            if *n == 0 {
                self.in_flight.remove(&target);
            }
        }
    }

    fn allocate_id(&mut self) -> u32 {
        loop {
            let id = self.next_id;
            self.next_id = self.next_id.wrapping_add(1).max(1);
            if !self.pending.contains_key(&id) {
                return id;
            }
        }
    }

    /// One frame, or the bytes of a segmented transfer for a message over 64.
    fn encode(&self, wire: WireVersion, message: &Message) -> Result<Wire, Error> {
        let len = message.encoded_len(wire)?;
        if len <= MAX_FRAME_LEN {
            let mut buf = [0u8; MAX_FRAME_LEN];
            let len = message.encode_frame(wire, &mut buf)?;
            return Ok(Wire::Frame(Frame::fd(
                self.can_id,
                buf.get(..len).unwrap_or(&buf),
            )?));
        }
        segmented_ids(self.config.node_id, message.header.target_id)?;
        let mut bytes = vec![0u8; len];
        let n = message.encode(wire, &mut bytes)?;
        bytes.truncate(n);
        Ok(Wire::Segmented(bytes))
    }

    /// Sends `payload` to `target` and awaits its Ack or Nack. Returns the
    /// msg_id; the answer comes as [`Event::Completed`].
    ///
    /// A message over 64 bytes goes as a segmented transfer (see the
    /// [module docs](self)).
    ///
    /// # Errors
    /// [`Error::Irpc`]: the payload is not in the target's wire version or
    /// holds a non-finite value; [`Error::SegmentedNode`]: a message over
    /// 64 bytes to a node above 0x7FF (broadcasts included);
    /// [`Error::InFlightLimit`] when `target` already has
    /// [`ClientConfig::max_in_flight`] requests in flight.
    pub fn request(&mut self, now: Duration, target: u16, payload: Payload) -> Result<u32, Error> {
        if !self.can_request(target) {
            return Err(Error::InFlightLimit {
                target,
                in_flight: self.in_flight_to(target),
            });
        }
        let (msg_id, wire) = self.enqueue(now, self.wire_of(target), target, payload)?;
        *self.in_flight.entry(target).or_insert(0) += 1;
        self.pending.insert(
            msg_id,
            Pending {
                target,
                kind: payload.kind(),
                wire,
                attempts: Attempts::first(now, self.config.timeout, self.config.retries),
                sent_at: now,
            },
        );
        self.stats.requests += 1;
        Ok(msg_id)
    }

    /// Sends `payload` to `target` expecting no answer (broadcasts), in
    /// [`ClientConfig::wire`].
    ///
    /// # Errors
    /// As [`Client::request`].
    pub fn send(&mut self, target: u16, payload: Payload) -> Result<u32, Error> {
        self.send_in(self.config.wire, target, payload)
    }

    /// Sends `payload` to `target` in `wire`, expecting no answer (a
    /// broadcast to the joints of one wire version).
    ///
    /// # Errors
    /// As [`Client::request`].
    pub fn send_in(
        &mut self,
        wire: WireVersion,
        target: u16,
        payload: Payload,
    ) -> Result<u32, Error> {
        self.enqueue(Duration::ZERO, wire, target, payload)
            .map(|(msg_id, _)| msg_id)
    }

    /// Encodes `payload` to `target` under a fresh msg_id and queues its
    /// frame or transfer.
    fn enqueue(
        &mut self,
        now: Duration,
        wire: WireVersion,
        target: u16,
        payload: Payload,
    ) -> Result<(u32, Wire), Error> {
        let msg_id = self.allocate_id();
        let message = Message {
            header: Header {
                source_id: self.config.node_id,
                target_id: target,
                msg_id,
            },
            payload,
        };
        let encoded = self.encode(wire, &message)?;
        match &encoded {
            Wire::Frame(frame) => self.out.push_back(*frame),
            Wire::Segmented(bytes) => {
                self.links
                    .send_message(now, target, bytes.clone(), Some(msg_id))?;
            }
        }
        Ok((msg_id, encoded))
    }

    /// Lifecycle: configure `target` (Unconfigured to Inactive).
    ///
    /// # Errors
    /// As [`Client::request`].
    pub fn configure(&mut self, now: Duration, target: u16) -> Result<u32, Error> {
        self.request(now, target, Payload::Configure)
    }

    /// Lifecycle: activate `target` (Inactive to Active: it moves on command).
    ///
    /// # Errors
    /// As [`Client::request`].
    pub fn activate(&mut self, now: Duration, target: u16) -> Result<u32, Error> {
        self.request(now, target, Payload::Activate)
    }

    /// Lifecycle: deactivate `target` (Active to Inactive: it stops).
    ///
    /// # Errors
    /// As [`Client::request`].
    pub fn deactivate(&mut self, now: Duration, target: u16) -> Result<u32, Error> {
        self.request(now, target, Payload::Deactivate)
    }

    /// Lifecycle: reset `target` (back to Unconfigured).
    ///
    /// # Errors
    /// As [`Client::request`].
    pub fn reset(&mut self, now: Duration, target: u16) -> Result<u32, Error> {
        self.request(now, target, Payload::Reset)
    }

    /// Motion: a v2 target with a motion profile.
    ///
    /// # Errors
    /// As [`Client::request`]; `PayloadNotInVersion` on v1.
    pub fn set_target_v2(
        &mut self,
        now: Duration,
        target: u16,
        command: SetTargetPayloadV2,
    ) -> Result<u32, Error> {
        self.request(now, target, Payload::SetTargetV2(command))
    }

    /// Motion: a v1 target.
    ///
    /// # Errors
    /// As [`Client::request`].
    pub fn set_target(
        &mut self,
        now: Duration,
        target: u16,
        command: SetTargetPayload,
    ) -> Result<u32, Error> {
        self.request(now, target, Payload::SetTarget(command))
    }

    /// Subscribes to `target`'s telemetry (v2.1 on): the samples then arrive
    /// as [`Event::Feedback`].
    ///
    /// # Errors
    /// As [`Client::request`]; `PayloadNotInVersion` before v2.1.
    pub fn subscribe_telemetry(
        &mut self,
        now: Duration,
        target: u16,
        mode: TelemetryMode,
        rate_hz: u16,
        change_threshold: f32,
    ) -> Result<u32, Error> {
        self.request(
            now,
            target,
            Payload::ConfigureTelemetry(ConfigureTelemetryPayload {
                mode,
                rate_hz,
                change_threshold,
            }),
        )
    }

    /// Sends ArmReady (no answer expected), so that it means ArmReady to
    /// every joint: one broadcast (to 0xFFFF) while every node given a wire
    /// version ([`Client::set_wire`]) speaks the client's own; otherwise one
    /// ArmReady to each of those nodes, in its version. A broadcast is
    /// decoded by every joint in its own version, and ArmReady's tag in one
    /// version is another message in the next: v2.0's ArmReady (tag 10) is
    /// v2.1's RequestTelemetry. Returns the msg_id of the last frame.
    ///
    /// ```
    /// use motorwire_can::client::{Client, ClientConfig};
    /// use motorwire_irpc::WireVersion;
    ///
    /// let mut client = Client::new(ClientConfig::default())?; // speaks v2.0
    /// client.set_wire(0x10, WireVersion::V2_0);
    /// client.arm_ready()?;                                  // one broadcast, tag 10
    /// assert_eq!(client.poll_transmit().unwrap().data(), [0x00, 0xff, 0xff, 0x03, 0x01, 0x0a]);
    /// client.set_wire(0x11, WireVersion::V2_1);
    /// client.arm_ready()?;                                  // to each joint in its version
    /// assert_eq!(client.poll_transmit().unwrap().data(), [0x00, 0x10, 0x02, 0x0a]);
    /// assert_eq!(client.poll_transmit().unwrap().data(), [0x00, 0x11, 0x03, 0x14]);
    /// assert!(client.poll_transmit().is_none());
    /// # Ok::<(), motorwire_can::Error>(())
    /// ```
    ///
    /// # Errors
    /// As [`Client::request`].
    pub fn arm_ready(&mut self) -> Result<u32, Error> {
        let own = self.config.wire;
        if self.wires.values().all(|w| *w == own) {
            return self.send(BROADCAST, Payload::ArmReady);
        }
        let nodes: Vec<(u16, WireVersion)> = self.wires.iter().map(|(n, w)| (*n, *w)).collect();
        let mut last = 0;
        for (node, wire) in nodes {
            last = self.send_in(wire, node, Payload::ArmReady)?;
        }
        Ok(last)
    }

    /// Takes a frame from the bus: a plain iRPC frame, or a frame of a
    /// segmented transfer to this node (other extended frames are ignored).
    pub fn handle_frame(&mut self, now: Duration, frame: &Frame) {
        if frame.id().is_extended() {
            if self.links.handle_frame(now, frame) {
                self.drain_links(now);
            } else if crate::segmented::segmented_ends(frame.id())
                .is_some_and(|(source, _)| source == self.config.node_id)
            {
                self.stats.own_frames += 1;
            }
            return;
        }
        if frame.id().raw() == u32::from(self.config.node_id) {
            // Our own request, heard back: each is in the wire of the joint
            // it was for, so decoding it in ours would call it bad.
            self.stats.own_frames += 1;
            return;
        }
        let wire = u16::try_from(frame.id().raw()).map_or(self.config.wire, |n| self.wire_of(n));
        match Message::decode_frame(wire, frame.data()) {
            Ok(message) if u32::from(message.header.source_id) != frame.id().raw() => {
                self.stats.bad_frames += 1;
                self.events.push_back(Event::Misaddressed {
                    can_id: frame.id(),
                    message,
                });
            }
            Ok(message) => self.handle_message(now, message),
            Err(error) => {
                self.stats.bad_frames += 1;
                self.events.push_back(Event::Undecodable {
                    can_id: frame.id(),
                    error: FrameError::Irpc(error),
                });
            }
        }
    }

    /// Handles what the segmented transfers reported.
    fn drain_links(&mut self, now: Duration) {
        while let Some(event) = self.links.poll_event() {
            match event {
                LinkEvent::Message {
                    source,
                    can_id,
                    bytes,
                } => {
                    self.stats.segmented_received += 1;
                    match Message::decode(self.wire_of(source), &bytes) {
                        Ok(message)
                            if message.header.source_id != source
                                || message.header.target_id != self.config.node_id =>
                        {
                            self.stats.bad_frames += 1;
                            self.events
                                .push_back(Event::Misaddressed { can_id, message });
                        }
                        Ok(message) => self.handle_message(now, message),
                        Err(error) => {
                            self.stats.bad_frames += 1;
                            self.events.push_back(Event::Undecodable {
                                can_id,
                                error: FrameError::Irpc(error),
                            });
                        }
                    }
                }
                LinkEvent::ReceiveFailed { can_id, error, .. } => {
                    self.stats.failed_transfers += 1;
                    self.events.push_back(Event::Undecodable {
                        can_id,
                        error: FrameError::Transfer(error),
                    });
                }
                LinkEvent::SendFailed { .. } => self.stats.failed_sends += 1,
                LinkEvent::Sent { .. } => self.stats.segmented_sent += 1,
            }
        }
    }

    /// Takes a message that arrived by other means (ISO-TP reassembly).
    pub fn handle_message(&mut self, now: Duration, message: Message) {
        let to = message.header.target_id;
        if to != self.config.node_id && to != BROADCAST && to != ARM_NODE {
            return; // for another node
        }
        let (id, outcome) = match message.payload {
            Payload::Ack(id) => (id, Outcome::Acked),
            Payload::Nack { id, error } => (id, Outcome::Nacked(NackCode(error))),
            _ => {
                self.events.push_back(Event::Feedback { message, at: now });
                return;
            }
        };
        // The answer names its request twice (header and payload) and comes
        // from the node asked: a single flipped bit cannot fake one.
        let matches = message.header.msg_id == id
            && self
                .pending
                .get(&id)
                .is_some_and(|p| p.target == message.header.source_id);
        if !matches {
            self.stats.stray_replies += 1;
            self.events.push_back(Event::StrayReply { message });
            return;
        }
        if let Some(p) = self.pending.remove(&id) {
            self.release(p.target);
            match outcome {
                Outcome::Acked => self.stats.acked += 1,
                Outcome::Nacked(_) => self.stats.nacked += 1,
                Outcome::TimedOut => {}
            }
            self.events.push_back(Event::Completed(Completion {
                msg_id: id,
                target: p.target,
                kind: p.kind,
                outcome,
                attempts: p.attempts.sent(),
                sent_at: p.sent_at,
                finished_at: now,
            }));
        }
    }

    /// Sends again, or gives up on, every request whose deadline is `now`
    /// or earlier; ends segmented transfers whose peer fell silent and
    /// lets paced frames go.
    pub fn handle_timeout(&mut self, now: Duration) {
        self.links.handle_timeout(now);
        self.drain_links(now);
        let due: Vec<u32> = self
            .pending
            .iter()
            .filter(|(_, p)| p.attempts.deadline() <= now)
            .map(|(id, _)| *id)
            .collect();
        for id in due {
            let Some(p) = self.pending.get_mut(&id) else {
                continue;
            };
            if p.attempts.expire(now, true) == Expiry::Resend {
                let target = p.target;
                match &p.wire {
                    Wire::Frame(frame) => self.out.push_back(*frame),
                    Wire::Segmented(bytes) => {
                        // Checked when the request was made: cannot fail.
                        let _ = self
                            .links
                            .resend_message(now, target, bytes.clone(), Some(id));
                    }
                }
                self.stats.retransmissions += 1;
            } else if let Some(p) = self.pending.remove(&id) {
                self.release(p.target);
                if matches!(p.wire, Wire::Segmented(_)) {
                    self.links.cancel(p.target, id);
                }
                self.stats.timed_out += 1;
                self.events.push_back(Event::Completed(Completion {
                    msg_id: id,
                    target: p.target,
                    kind: p.kind,
                    outcome: Outcome::TimedOut,
                    attempts: p.attempts.sent(),
                    sent_at: p.sent_at,
                    finished_at: now,
                }));
            }
        }
    }

    /// The next frame to put on the bus: a request's, or a segmented
    /// transfer's (flow control, first and consecutive frames).
    pub fn poll_transmit(&mut self) -> Option<Frame> {
        self.out.pop_front().or_else(|| self.links.poll_transmit())
    }

    /// The next event.
    pub fn poll_event(&mut self) -> Option<Event> {
        self.events.pop_front()
    }

    /// The earliest deadline of a request in flight or of a segmented
    /// transfer (a peer's next frame, a paced frame of ours).
    pub fn poll_timeout(&self) -> Option<Duration> {
        self.pending
            .values()
            .map(|p| p.attempts.deadline())
            .chain(self.links.poll_timeout())
            .min()
    }

    /// Drives the client on a blocking bus until `msg_id` completes,
    /// returning its completion; other events stay queued for
    /// [`Client::poll_event`]. `clock` gives the time (for SocketCAN, an
    /// `Instant`'s elapsed time; for a [`SimBus`](crate::SimBus), its `now`).
    ///
    /// # Errors
    /// The bus's errors other than timeouts.
    pub fn drive(
        &mut self,
        bus: &mut impl CanBus,
        clock: impl Fn() -> Duration,
        msg_id: u32,
    ) -> Result<Completion, Error> {
        loop {
            while let Some(f) = self.poll_transmit() {
                bus.send(&f)?;
            }
            let found = self
                .events
                .iter()
                .position(|e| matches!(e, Event::Completed(c) if c.msg_id == msg_id));
            if let Some(Event::Completed(c)) = found.and_then(|i| self.events.remove(i)) {
                return Ok(c);
            }
            if !self.pending.contains_key(&msg_id) {
                // Never requested, or its completion was already taken.
                return Err(Error::UnknownRequest { msg_id });
            }
            let now = clock();
            let wait = self
                .poll_timeout()
                .map_or(Duration::ZERO, |t| t.saturating_sub(now));
            match bus.recv(wait) {
                Ok(r) => self.handle_frame(clock(), &r.frame),
                Err(Error::Timeout(_)) => self.handle_timeout(clock()),
                Err(e) => return Err(e),
            }
        }
    }
}
