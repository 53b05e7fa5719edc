use core::fmt;

use crate::{PayloadKind, WireVersion};

/// Everything the iRPC codec refuses. Every decoding error says which field
/// (as `Payload.field`, e.g. `"SetTargetV2.max_velocity"`) and at which byte
/// offset.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum Error {
    /// The output buffer is too small for the message.
    BufferTooSmall {
        /// Bytes the message needs.
        needed: usize,
        /// Bytes the buffer has.
        available: usize,
    },
    /// The message is over 64 bytes, too large for one CAN-FD frame.
    FrameTooLarge {
        /// The encoded length.
        len: usize,
    },
    /// The payload does not exist in the chosen wire version.
    PayloadNotInVersion {
        /// The payload.
        payload: PayloadKind,
        /// The version.
        version: WireVersion,
    },
    /// An enum value does not exist in the chosen wire version
    /// (`LifecycleState::Calibrating` before v2.1).
    ValueNotInVersion {
        /// The field.
        field: &'static str,
        /// The version.
        version: WireVersion,
    },
    /// A float is NaN or infinite.
    NonFinite {
        /// The field.
        field: &'static str,
        /// Offset of the float in the message.
        offset: usize,
    },
    /// The input ends inside a field.
    Truncated {
        /// The field.
        field: &'static str,
        /// Where the input ended.
        offset: usize,
    },
    /// The payload tag is not a variant of the chosen wire version.
    UnknownTag {
        /// The tag.
        tag: u32,
        /// The version.
        version: WireVersion,
        /// Offset of the tag.
        offset: usize,
    },
    /// An enum index is out of range.
    InvalidEnum {
        /// The field.
        field: &'static str,
        /// The index found.
        index: u32,
        /// Offset of the index.
        offset: usize,
    },
    /// A varint is longer than its type allows or holds a value too large
    /// for it.
    VarintOverflow {
        /// The field.
        field: &'static str,
        /// Offset of the varint.
        offset: usize,
    },
    /// A varint has a redundant trailing zero group (postcard never writes
    /// one; accepting it would give one message two encodings).
    NonCanonicalVarint {
        /// The field.
        field: &'static str,
        /// Offset of the varint.
        offset: usize,
    },
    /// A bool byte is neither 0 nor 1.
    InvalidBool {
        /// The field.
        field: &'static str,
        /// The byte.
        byte: u8,
        /// Its offset.
        offset: usize,
    },
    /// Bytes follow the message ([`decode`](crate::Message::decode) takes
    /// exactly one message).
    TrailingBytes {
        /// Where the message ended.
        offset: usize,
        /// How many bytes follow it.
        count: usize,
    },
    /// A CAN-FD frame carries non-zero bytes after the message.
    NonZeroPadding {
        /// Offset of the first non-zero byte.
        offset: usize,
    },
    /// A frame's length is not a CAN-FD length (0-8, 12, 16, 20, 24, 32, 48, 64).
    InvalidFrameLength {
        /// The length.
        len: usize,
    },
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Self::BufferTooSmall { needed, available } => write!(
                f,
                "the message needs {needed} bytes but the buffer has {available}"
            ),
            Self::FrameTooLarge { len } => write!(
                f,
                "the message is {len} bytes, more than one 64-byte CAN-FD frame holds"
            ),
            Self::PayloadNotInVersion { payload, version } => {
                write!(f, "{payload} does not exist in iRPC {version}")
            }
            Self::ValueNotInVersion { field, version } => {
                write!(f, "the value of {field} does not exist in iRPC {version}")
            }
            Self::NonFinite { field, offset } => {
                write!(f, "{field} at byte {offset} is NaN or infinite")
            }
            Self::Truncated { field, offset } => {
                write!(f, "the input ends at byte {offset}, inside {field}")
            }
            Self::UnknownTag {
                tag,
                version,
                offset,
            } => write!(
                f,
                "payload tag {tag} at byte {offset} is not a payload of iRPC {version}"
            ),
            Self::InvalidEnum {
                field,
                index,
                offset,
            } => write!(f, "{field} at byte {offset} has no variant {index}"),
            Self::VarintOverflow { field, offset } => {
                write!(
                    f,
                    "the varint of {field} at byte {offset} overflows its type"
                )
            }
            Self::NonCanonicalVarint { field, offset } => write!(
                f,
                "the varint of {field} at byte {offset} has a redundant trailing zero group"
            ),
            Self::InvalidBool {
                field,
                byte,
                offset,
            } => write!(
                f,
                "{field} at byte {offset} is {byte:#04x}, not a bool (0 or 1)"
            ),
            Self::TrailingBytes { offset, count } => write!(
                f,
                "{count} byte(s) follow the message, which ends at byte {offset}"
            ),
            Self::NonZeroPadding { offset } => {
                write!(f, "byte {offset} after the message is not zero padding")
            }
            Self::InvalidFrameLength { len } => write!(
                f,
                "{len} is not a CAN-FD frame length (0-8, 12, 16, 20, 24, 32, 48, 64)"
            ),
        }
    }
}

impl core::error::Error for Error {}
