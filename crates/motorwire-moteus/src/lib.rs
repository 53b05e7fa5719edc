#![doc = include_str!("../README.md")]

mod call;
pub mod diagnostic;
mod registers;
mod reply;

pub use call::{
    COMMANDS, Call, CallError, Command, PositionArgs, QUERY_FIELDS, Resolutions, StayWithinArgs,
    resolution_by_name,
};
pub use moteus_protocol as protocol;
pub use registers::{
    NotAnInteger, REGISTERS, Scale, Scaled, register_by_name, register_name, register_scale, scale,
};
pub use reply::{RegisterError, RegisterValue, Reply, ReplyError, check_structure, decode};

/// A frame for a controller: its CAN id and its data (not padded: the
/// transport pads to the CAN-FD length, with 0x50, the protocol's no-op).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Frame {
    /// The 29-bit CAN id.
    pub can_id: u32,
    /// The data, at most 64 bytes.
    pub data: Vec<u8>,
}

/// `data` padded with the protocol's no-op (0x50) to its CAN-FD length
/// (`moteus-protocol`'s DLC rounding), as mjbots' transports pad a frame;
/// data over 64 bytes is left as it is.
///
/// ```
/// assert_eq!(motorwire_moteus::padded(&[0x11, 0x00]), [0x11, 0x00]);
/// assert_eq!(motorwire_moteus::padded(&[0x01; 9]).len(), 12);
/// assert_eq!(motorwire_moteus::padded(&[0x01; 9])[9..], [0x50, 0x50, 0x50]);
/// ```
pub fn padded(data: &[u8]) -> Vec<u8> {
    let mut v = data.to_vec();
    if data.len() <= 64 {
        v.resize(protocol::CanFdFrame::round_up_dlc(data.len()), 0x50);
    }
    v
}

/// Lowercase hex, no separators.
pub fn hex(bytes: &[u8]) -> String {
    use std::fmt::Write;
    bytes
        .iter()
        .fold(String::with_capacity(bytes.len() * 2), |mut s, b| {
            let _ = write!(s, "{b:02x}");
            s
        })
}
