//! iRPC messages longer than one CAN-FD frame (motorwire's decision).
//!
//! WIRE-FACTS §1.5: some v2.1/v2.2 messages do not always fit one 64-byte
//! frame (TelemetryStream, PowerMetrics, CalibrationResult, FaultHistory).
//! motorwire carries them as follows, and every motorwire node (the
//! [`Client`](crate::client::Client), the simulated joint, the bridge)
//! speaks it:
//!
//! - A message whose encoding fits 64 bytes is **one plain frame**, exactly
//!   as before: standard 11-bit CAN id = the sender's node id, zero padding.
//! - A longer message travels as **ISO-TP (ISO 15765-2) over CAN-FD**
//!   (64-byte frames, normal addressing, no block size, no separation
//!   time, padding 0xCC as Linux pads) on **29-bit extended CAN ids that
//!   name both ends**: the sender's first and consecutive frames on
//!   `0x1000_0000 | (target << 11) | source`, the receiver's flow control
//!   on the swapped id `0x1000_0000 | (source << 11) | target`
//!   ([`segmented_ids`]). Both node ids must be 11-bit (at most 0x7FF);
//!   a larger one is [`Error::SegmentedNode`]. The id a node sends flow
//!   control on is the one it sends its own long messages on, so one pair
//!   of ids is one full-duplex ISO-TP link, as a Linux `CAN_ISOTP` socket
//!   bound to those ids keeps it; the protocol control byte tells the
//!   frames apart.
//! - The reassembled bytes are one iRPC message, exactly (no padding),
//!   decoded in the sender's wire version; its header must name the same
//!   source and target as the CAN id.
//! - One transfer at a time per direction and pair: a node queues a second
//!   long message to the same peer (and, to keep its order, every frame
//!   to that peer after it) until the first is sent.
//!
//! Bit 28 keeps the range clear of the ids an 11-bit node id could make
//! (extended ids 0 to 0x7FF are unused, and a plain frame is never
//! extended); the base id of every segmented frame is then at least 0x400,
//! so plain frames of nodes below 0x400 win arbitration over them.
//!
//! [`Links`] is the sans-IO engine both ends use: per-peer ISO-TP
//! [`Sender`]s and [`Receiver`]s, bounded (one transfer per peer and
//! direction, [`Links::max_len`] bytes at most), paced by the time given.
//!
//! ```
//! use motorwire_can::segmented::{segmented_ends, segmented_ids};
//! // FaultHistory from joint 0x33 to the arm (0x000).
//! let ids = segmented_ids(0x33, 0x000)?;
//! assert_eq!((ids.data.raw(), ids.flow_control.raw()), (0x1000_0033, 0x1001_9800));
//! assert!(ids.data.is_extended());
//! assert_eq!(segmented_ends(ids.data), Some((0x33, 0x000)));
//! assert_eq!(segmented_ends(ids.flow_control), Some((0x000, 0x33)));
//! assert!(segmented_ids(0x800, 0).is_err());
//! # Ok::<(), motorwire_can::Error>(())
//! ```

use std::collections::{BTreeMap, VecDeque};
use std::time::Duration;

use crate::isotp::{IsoTpConfig, IsoTpError, Receiver, Sender};
use crate::{CanId, Error, FD_MAX_LEN, Frame};

/// Bit 28: set in every segmented transfer's extended CAN id.
pub const SEGMENTED_BASE: u32 = 0x1000_0000;

/// The largest node id a segmented transfer can name (11 bits).
pub const MAX_NODE: u16 = 0x7FF;

/// The longest message a [`Links`] accepts by default: the longest iRPC
/// message is 148 bytes (FaultHistory, WIRE-FACTS §1.5).
pub const DEFAULT_MAX_LEN: usize = 256;

/// How many frames and messages a [`Links`] holds for one peer behind a
/// transfer in progress; more are refused.
pub const MAX_QUEUED: usize = 64;

/// The CAN ids of a segmented transfer from one node to another.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SegmentedIds {
    /// The sender's first and consecutive frames:
    /// `0x1000_0000 | (target << 11) | source`.
    pub data: CanId,
    /// The receiver's flow control: `0x1000_0000 | (source << 11) | target`
    /// (the data id of the other direction).
    pub flow_control: CanId,
}

fn check_node(node: u16) -> Result<u32, Error> {
    if node > MAX_NODE {
        return Err(Error::SegmentedNode { node });
    }
    Ok(u32::from(node))
}

/// The CAN ids a message longer than one frame travels on from `source`
/// to `target` (see the [module docs](self)).
///
/// ```
/// use motorwire_can::{Error, segmented::segmented_ids};
/// let ids = segmented_ids(0x000, 0x10)?; // the arm to joint 0x10
/// assert_eq!(ids.data.raw(), 0x1000_8000);
/// assert_eq!(ids.flow_control.raw(), 0x1000_0010);
/// assert_eq!(segmented_ids(0x10, 0xFFFF), Err(Error::SegmentedNode { node: 0xFFFF }));
/// # Ok::<(), Error>(())
/// ```
///
/// # Errors
/// [`Error::SegmentedNode`] for a node id above 0x7FF (broadcast 0xFFFF
/// included: a segmented transfer has one receiver).
pub fn segmented_ids(source: u16, target: u16) -> Result<SegmentedIds, Error> {
    let (s, t) = (check_node(source)?, check_node(target)?);
    Ok(SegmentedIds {
        data: CanId::extended(SEGMENTED_BASE | (t << 11) | s)?,
        flow_control: CanId::extended(SEGMENTED_BASE | (s << 11) | t)?,
    })
}

/// The `(source, target)` an id of [`segmented_ids`] names as its data id,
/// or `None` for any other id (standard ids, extended ids outside the
/// range).
///
/// ```
/// use motorwire_can::{CanId, segmented::segmented_ends};
/// assert_eq!(segmented_ends(CanId::extended(0x1000_8000)?), Some((0x000, 0x10)));
/// assert_eq!(segmented_ends(CanId::extended(0x0000_8000)?), None);
/// assert_eq!(segmented_ends(CanId::standard(0x10)?), None);
/// # Ok::<(), motorwire_can::Error>(())
/// ```
pub fn segmented_ends(id: CanId) -> Option<(u16, u16)> {
    let CanId::Extended(raw) = id else {
        return None;
    };
    if raw & !0x003F_FFFF != SEGMENTED_BASE {
        return None;
    }
    let source = u16::try_from(raw & 0x7FF).ok()?;
    let target = u16::try_from((raw >> 11) & 0x7FF).ok()?;
    Some((source, target))
}

/// The ISO-TP configuration of `node`'s side of its link with `peer`:
/// it sends on `segmented_ids(node, peer).data` and hears
/// `segmented_ids(peer, node).data`; CAN-FD, 64-byte frames, no block
/// size, no separation time, `timeout` for the peer's next frame,
/// messages up to `max_len`.
///
/// # Errors
/// [`Error::SegmentedNode`].
pub fn link_config(
    node: u16,
    peer: u16,
    timeout: Duration,
    max_len: usize,
) -> Result<IsoTpConfig, Error> {
    let ids = segmented_ids(node, peer)?;
    Ok(IsoTpConfig {
        timeout,
        max_len,
        ..IsoTpConfig::fd(ids.data, ids.flow_control)
    })
}

/// What a [`Links`] reports.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum LinkEvent {
    /// A message arrived whole.
    Message {
        /// Its sender (from the CAN id).
        source: u16,
        /// The CAN id its data came on.
        can_id: CanId,
        /// The reassembled bytes.
        bytes: Vec<u8>,
    },
    /// A transfer from `peer` failed or was malformed (timeout, sequence,
    /// a length over the limit, a frame that is not ISO-TP).
    ReceiveFailed {
        /// Its sender.
        peer: u16,
        /// The CAN id of its data.
        can_id: CanId,
        /// Why.
        error: IsoTpError,
    },
    /// A transfer to `peer` failed (no flow control, overflow refused).
    SendFailed {
        /// Its receiver.
        peer: u16,
        /// The tag it was sent with ([`Links::send_message`]).
        tag: Option<u32>,
        /// Why.
        error: IsoTpError,
    },
    /// A transfer to `peer` was sent whole.
    Sent {
        /// Its receiver.
        peer: u16,
        /// The tag it was sent with.
        tag: Option<u32>,
    },
}

/// Something waiting to go to a peer behind a transfer in progress.
#[derive(Debug)]
enum Queued {
    Frame(Frame),
    Message { bytes: Vec<u8>, tag: Option<u32> },
}

#[derive(Debug, Default)]
struct Peer {
    rx: Option<Receiver>,
    tx: Option<(Sender, Option<u32>)>,
    queue: VecDeque<Queued>,
}

/// The sans-IO engine of one node's segmented transfers with every peer.
///
/// Give it the node's frames to send ([`Links::send_frame`] for plain
/// frames, [`Links::send_message`] for long messages), every extended
/// frame heard ([`Links::handle_frame`]) and the time
/// ([`Links::handle_timeout`]); take frames ([`Links::poll_transmit`]),
/// events ([`Links::poll_event`]) and the next deadline
/// ([`Links::poll_timeout`]).
///
/// ```
/// use std::time::Duration;
/// use motorwire_can::segmented::{LinkEvent, Links};
///
/// let (mut a, mut b) = (Links::new(0x10, Duration::from_secs(1))?, Links::new(0x00, Duration::from_secs(1))?);
/// let message: Vec<u8> = (0..100).collect();
/// a.send_message(Duration::ZERO, 0x00, message.clone(), None)?;
/// // Frames go back and forth until nothing is left to send.
/// loop {
///     let mut quiet = true;
///     while let Some(f) = a.poll_transmit() { b.handle_frame(Duration::ZERO, &f); quiet = false; }
///     while let Some(f) = b.poll_transmit() { a.handle_frame(Duration::ZERO, &f); quiet = false; }
///     if quiet { break; }
/// }
/// assert_eq!(b.poll_event(), Some(LinkEvent::Message {
///     source: 0x10, can_id: motorwire_can::CanId::extended(0x1000_0010)?, bytes: message,
/// }));
/// assert_eq!(a.poll_event(), Some(LinkEvent::Sent { peer: 0x00, tag: None }));
/// # Ok::<(), motorwire_can::Error>(())
/// ```
#[derive(Debug)]
pub struct Links {
    node: u16,
    timeout: Duration,
    max_len: usize,
    now: Duration,
    peers: BTreeMap<u16, Peer>,
    out: VecDeque<Frame>,
    events: VecDeque<LinkEvent>,
}

impl Links {
    /// The links of node `node`, waiting `timeout` for a peer's next frame
    /// (ISO 15765-2's N_Bs and N_Cr), accepting messages up to
    /// [`DEFAULT_MAX_LEN`] bytes.
    ///
    /// # Errors
    /// [`Error::SegmentedNode`] above 0x7FF.
    pub fn new(node: u16, timeout: Duration) -> Result<Self, Error> {
        check_node(node)?;
        Ok(Self {
            node,
            timeout,
            max_len: DEFAULT_MAX_LEN,
            now: Duration::ZERO,
            peers: BTreeMap::new(),
            out: VecDeque::new(),
            events: VecDeque::new(),
        })
    }

    /// Accepts messages up to `max_len` bytes (a longer first frame is
    /// refused with flow status overflow).
    #[must_use]
    pub fn with_max_len(mut self, max_len: usize) -> Self {
        self.max_len = max_len;
        self
    }

    /// The longest message accepted.
    pub fn max_len(&self) -> usize {
        self.max_len
    }

    /// This node's id.
    pub fn node(&self) -> u16 {
        self.node
    }

    fn config(&self, peer: u16) -> Result<IsoTpConfig, Error> {
        link_config(self.node, peer, self.timeout, self.max_len)
    }

    /// Whether anything is being sent to or queued for `peer`.
    pub fn is_busy(&self, peer: u16) -> bool {
        self.peers
            .get(&peer)
            .is_some_and(|p| p.tx.is_some() || !p.queue.is_empty())
    }

    /// Queues a plain frame for `peer`: at once, or behind the transfers
    /// to `peer` already in progress or queued, so the peer hears this
    /// node's messages in the order they were made. Returns `false`, the
    /// frame dropped, when [`MAX_QUEUED`] wait for `peer` already.
    pub fn send_frame(&mut self, peer: u16, frame: Frame) -> bool {
        match self.peers.get_mut(&peer) {
            Some(p) if p.queue.len() >= MAX_QUEUED => false,
            Some(p) if p.tx.is_some() || !p.queue.is_empty() => {
                p.queue.push_back(Queued::Frame(frame));
                true
            }
            _ => {
                self.out.push_back(frame);
                true
            }
        }
    }

    /// Sends `bytes` to `peer` as one segmented transfer (at once, or after
    /// the ones before it to that peer). `tag` comes back in
    /// [`LinkEvent::Sent`] or [`LinkEvent::SendFailed`]. A message already
    /// queued (not yet started) with the same bytes is not queued twice.
    ///
    /// # Errors
    /// [`Error::SegmentedNode`] for a peer above 0x7FF;
    /// [`Error::IsoTp`] for an empty message, or [`IsoTpError::Busy`] when
    /// [`MAX_QUEUED`] wait for `peer` already.
    pub fn send_message(
        &mut self,
        now: Duration,
        peer: u16,
        bytes: Vec<u8>,
        tag: Option<u32>,
    ) -> Result<(), Error> {
        self.now = self.now.max(now);
        let config = self.config(peer)?;
        if bytes.is_empty() {
            return Err(IsoTpError::Empty.into());
        }
        let p = self.peers.entry(peer).or_default();
        if p.tx.is_some() || !p.queue.is_empty() {
            let dup = p
                .queue
                .iter()
                .any(|q| matches!(q, Queued::Message { bytes: b, .. } if *b == bytes));
            if !dup {
                if p.queue.len() >= MAX_QUEUED {
                    return Err(IsoTpError::Busy.into());
                }
                p.queue.push_back(Queued::Message { bytes, tag });
            }
            return Ok(());
        }
        let mut sender = Sender::new(config)?;
        sender.start(self.now, &bytes)?;
        p.tx = Some((sender, tag));
        self.pump(peer);
        Ok(())
    }

    /// Sends `bytes` to `peer` again from its first frame: the transfer in
    /// progress with the same `tag` is abandoned (its receiver starts over
    /// on the new first frame), or the message is queued as by
    /// [`Links::send_message`].
    ///
    /// # Errors
    /// As [`Links::send_message`].
    pub fn resend_message(
        &mut self,
        now: Duration,
        peer: u16,
        bytes: Vec<u8>,
        tag: Option<u32>,
    ) -> Result<(), Error> {
        if let Some(p) = self.peers.get_mut(&peer)
            && p.tx
                .as_ref()
                .is_some_and(|(_, t)| *t == tag && tag.is_some())
        {
            p.tx = None;
        }
        self.send_message(now, peer, bytes, tag)
    }

    /// Forgets what is queued or in progress to `peer` under `tag`: it is
    /// not sent (further). Returns whether there was any.
    pub fn cancel(&mut self, peer: u16, tag: u32) -> bool {
        let Some(p) = self.peers.get_mut(&peer) else {
            return false;
        };
        let before = p.queue.len();
        p.queue
            .retain(|q| !matches!(q, Queued::Message { tag: Some(t), .. } if *t == tag));
        let mut found = p.queue.len() != before;
        if p.tx.as_ref().is_some_and(|(_, t)| *t == Some(tag)) {
            p.tx = None;
            found = true;
        }
        self.pump(peer);
        found
    }

    /// Moves what `peer`'s sender has to send to the output, and starts
    /// what is queued behind it once it is done.
    fn pump(&mut self, peer: u16) {
        let now = self.now;
        loop {
            let config = self.config(peer);
            let Some(p) = self.peers.get_mut(&peer) else {
                return;
            };
            if let Some((tx, tag)) = p.tx.as_mut() {
                while let Some(f) = tx.poll_transmit(now) {
                    self.out.push_back(f);
                }
                match tx.poll_done() {
                    Some(Ok(())) => {
                        self.events.push_back(LinkEvent::Sent { peer, tag: *tag });
                        p.tx = None;
                    }
                    Some(Err(error)) => {
                        self.events.push_back(LinkEvent::SendFailed {
                            peer,
                            tag: *tag,
                            error,
                        });
                        p.tx = None;
                    }
                    None => return,
                }
            }
            // Idle: the queue's frames go out up to its next message.
            match p.queue.pop_front() {
                Some(Queued::Frame(f)) => self.out.push_back(f),
                Some(Queued::Message { bytes, tag }) => {
                    let started = config.and_then(|c| {
                        let mut s = Sender::new(c)?;
                        s.start(now, &bytes)?;
                        Ok(s)
                    });
                    match started {
                        Ok(s) => p.tx = Some((s, tag)),
                        Err(e) => {
                            let error = match e {
                                Error::IsoTp(e) => e,
                                _ => IsoTpError::InvalidConfig {
                                    reason: "segmented ids",
                                },
                            };
                            self.events
                                .push_back(LinkEvent::SendFailed { peer, tag, error });
                        }
                    }
                }
                None => {
                    if p.rx.is_none() {
                        self.peers.remove(&peer);
                    }
                    return;
                }
            }
        }
    }

    /// Takes a frame from the bus. Returns whether it was a segmented
    /// frame for this node (from a peer to it); every other frame is left
    /// alone.
    pub fn handle_frame(&mut self, now: Duration, frame: &Frame) -> bool {
        self.now = self.now.max(now);
        let Some((peer, target)) = segmented_ends(frame.id()) else {
            return false;
        };
        if target != self.node || peer == self.node {
            return false;
        }
        let Ok(config) = self.config(peer) else {
            return false;
        };
        let p = self.peers.entry(peer).or_default();
        // Flow control for this node's transfer to the peer.
        if let Some((tx, _)) = p.tx.as_mut() {
            tx.handle_frame(self.now, frame);
        }
        // First, consecutive or single frames of the peer's transfer.
        if frame.data().first().is_some_and(|pci| pci >> 4 != 3) {
            let rx = match p.rx.as_mut() {
                Some(rx) => rx,
                None => match Receiver::new(config) {
                    Ok(rx) => p.rx.insert(rx),
                    Err(_) => return true,
                },
            };
            let done = rx.handle_frame(self.now, frame);
            while let Some(f) = rx.poll_transmit() {
                self.out.push_back(f);
            }
            let idle = rx.poll_timeout().is_none();
            match done {
                Some(Ok(bytes)) => self.events.push_back(LinkEvent::Message {
                    source: peer,
                    can_id: frame.id(),
                    bytes,
                }),
                Some(Err(error)) => self.events.push_back(LinkEvent::ReceiveFailed {
                    peer,
                    can_id: frame.id(),
                    error,
                }),
                None => {}
            }
            if idle {
                p.rx = None;
            }
        } else if frame.data().is_empty() {
            self.events.push_back(LinkEvent::ReceiveFailed {
                peer,
                can_id: frame.id(),
                error: IsoTpError::InvalidFrame {
                    reason: "empty frame",
                },
            });
        }
        self.pump(peer);
        true
    }

    /// Ends the transfers whose peer fell silent, and lets paced frames go.
    pub fn handle_timeout(&mut self, now: Duration) {
        self.now = self.now.max(now);
        let now = self.now;
        let peers: Vec<u16> = self.peers.keys().copied().collect();
        for peer in peers {
            let Some(p) = self.peers.get_mut(&peer) else {
                continue;
            };
            if let Some(rx) = p.rx.as_mut()
                && let Some(error) = rx.handle_timeout(now)
            {
                p.rx = None;
                if let Ok(ids) = segmented_ids(peer, self.node) {
                    self.events.push_back(LinkEvent::ReceiveFailed {
                        peer,
                        can_id: ids.data,
                        error,
                    });
                }
            }
            if let Some((tx, _)) = p.tx.as_mut() {
                tx.handle_timeout(now);
            }
            self.pump(peer);
        }
    }

    /// The next frame to put on the bus.
    pub fn poll_transmit(&mut self) -> Option<Frame> {
        self.out.pop_front()
    }

    /// The next event.
    pub fn poll_event(&mut self) -> Option<LinkEvent> {
        self.events.pop_front()
    }

    /// The earliest deadline of a transfer in progress (a peer's next
    /// frame due, or a paced frame of this node's).
    pub fn poll_timeout(&self) -> Option<Duration> {
        self.peers
            .values()
            .flat_map(|p| {
                [
                    p.rx.as_ref().and_then(Receiver::poll_timeout),
                    p.tx.as_ref().and_then(|(tx, _)| tx.poll_timeout()),
                ]
            })
            .flatten()
            .min()
    }
}

/// Whether a message of `len` encoded bytes needs a segmented transfer.
///
/// ```
/// assert!(!motorwire_can::segmented::needs_segments(64));
/// assert!(motorwire_can::segmented::needs_segments(65));
/// ```
pub fn needs_segments(len: usize) -> bool {
    len > FD_MAX_LEN
}
