//! The crate's one error type.

use std::time::Duration;

use thiserror::Error;

/// Everything that can go wrong in motorwire-can, as values a caller can
/// match on.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[non_exhaustive]
pub enum Error {
    /// A CAN identifier too large for its kind.
    #[error("CAN id {id:#X} is too large for {}", if *extended { "an extended (29-bit) identifier" } else { "a standard (11-bit) identifier" })]
    InvalidId {
        /// The value.
        id: u32,
        /// Whether an extended identifier was asked for.
        extended: bool,
    },
    /// A payload length the frame kind cannot have.
    #[error("{len} bytes is not a valid {} payload length", if *fd { "CAN-FD" } else { "classic CAN" })]
    InvalidLength {
        /// The length.
        len: usize,
        /// Whether an FD frame was asked for.
        fd: bool,
    },
    /// Nothing arrived within the timeout.
    #[error("no frame within {0:?}")]
    Timeout(Duration),
    /// The bus, or this port of it, was closed.
    #[error("the bus is closed")]
    Closed,
    /// The network interface does not exist.
    #[error("no CAN interface named {iface:?}")]
    NoSuchInterface {
        /// Its name.
        iface: String,
    },
    /// The interface is down (ENETDOWN).
    #[error("CAN interface {iface:?} is down")]
    InterfaceDown {
        /// Its name.
        iface: String,
    },
    /// An FD frame on an interface without CAN-FD (MTU 16).
    #[error("CAN interface {iface:?} does not carry CAN-FD frames (set its mtu to 72)")]
    FdNotSupported {
        /// Its name.
        iface: String,
    },
    /// The controller went bus-off.
    #[error("bus off")]
    BusOff,
    /// The controller is error-passive (an error counter reached 128).
    #[error("controller error-passive (tx errors {tx}, rx errors {rx})")]
    ErrorPassive {
        /// Transmit error counter.
        tx: u8,
        /// Receive error counter.
        rx: u8,
    },
    /// The controller reached the error-warning level (a counter reached 96).
    #[error("controller error-warning (tx errors {tx}, rx errors {rx})")]
    ErrorWarning {
        /// Transmit error counter.
        tx: u8,
        /// Receive error counter.
        rx: u8,
    },
    /// Arbitration was lost (bit 0 means unspecified).
    #[error("arbitration lost at bit {bit}")]
    LostArbitration {
        /// The bit after which it was lost.
        bit: u8,
    },
    /// A transmitted frame was not acknowledged by any node.
    #[error("no node acknowledged the frame")]
    NoAck,
    /// The driver timed out transmitting.
    #[error("transmit timeout in the driver")]
    TransmitTimeout,
    /// The controller was restarted after bus-off.
    #[error("controller restarted")]
    Restarted,
    /// Another error frame (controller, protocol or transceiver problem), as
    /// the kernel described it.
    #[error("CAN error frame: {0}")]
    ErrorFrame(String),
    /// An fdcanusb adapter refused a line (`ERR ...`), or said something
    /// that is not its protocol.
    #[error("the fdcanusb adapter: {0}")]
    Adapter(String),
    /// Any other operating-system error.
    #[error("{op}: {message}")]
    Io {
        /// What was being done.
        op: &'static str,
        /// The error's kind.
        kind: std::io::ErrorKind,
        /// The system's message.
        message: String,
    },
    /// A request the client has no record of (never made, or already completed and taken).
    #[error("no request with msg_id {msg_id} is in flight")]
    UnknownRequest {
        /// The msg_id asked about.
        msg_id: u32,
    },
    /// A request to a node that already has as many requests in flight as
    /// [`crate::client::ClientConfig::max_in_flight`] allows: the joint's
    /// duplicate memory could not cover another one's retries.
    #[error("node 0x{target:02X} already has {in_flight} request(s) in flight")]
    InFlightLimit {
        /// The node.
        target: u16,
        /// How many are in flight to it.
        in_flight: usize,
    },
    /// A fault-injection rate outside 0..=1.
    #[error("fault rate {name} = {value} is outside 0..=1")]
    InvalidFaultRate {
        /// Which rate.
        name: &'static str,
        /// Its value.
        value: String,
    },
    /// A line of a candump log that is not in the `-L` format.
    #[error("candump log line {line}: {reason}")]
    Log {
        /// The line number, from 1.
        line: usize,
        /// What is wrong with it.
        reason: String,
    },
    /// A node id a segmented transfer cannot name: its 29-bit CAN id
    /// carries both ends in 11 bits each ([`crate::segmented::segmented_ids`]).
    #[error(
        "node id {node:#x} is above 0x7FF: a segmented transfer's CAN id carries each node id in 11 bits"
    )]
    SegmentedNode {
        /// The node id.
        node: u16,
    },
    /// An ISO-TP (ISO 15765-2) transfer failed.
    #[error("ISO-TP: {0}")]
    IsoTp(#[from] crate::isotp::IsoTpError),
    /// An iRPC message could not be encoded.
    #[error("iRPC: {0}")]
    Irpc(#[from] motorwire_irpc::Error),
}

impl Error {
    /// Wraps an operating-system error.
    pub fn io(op: &'static str, e: &std::io::Error) -> Self {
        Self::Io {
            op,
            kind: e.kind(),
            message: e.to_string(),
        }
    }
}
