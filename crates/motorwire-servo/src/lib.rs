#![doc = include_str!("../README.md")]
#![no_std]

extern crate alloc;
#[cfg(test)]
extern crate std;

use alloc::vec::Vec;

pub mod dynamixel;
pub mod feetech;
pub mod table;

/// The id every servo of a bus takes an instruction for (and answers none).
pub const BROADCAST_ID: u8 = 0xFE;

/// The largest id a single servo can have.
pub const MAX_ID: u8 = 0xFC;

/// A serial bus servo protocol, as the vendors' SDKs name them.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Protocol {
    /// Feetech's protocol with little-endian words (STS and SMS series,
    /// the STS3215): the SDK's `PacketHandler(0)`, LeRobot's protocol 0.
    Scs0,
    /// Feetech's protocol with big-endian words (SCS series, the
    /// SCS0009): the SDK's `PacketHandler(1)`, LeRobot's protocol 1.
    Scs1,
    /// Dynamixel Protocol 2.0 (X series: XL330, XL430, XM430): CRC-16,
    /// byte stuffing.
    Dxl2,
}

impl Protocol {
    /// Its name as the command line writes it: `scs0`, `scs1`, `dxl2`.
    ///
    /// ```
    /// use motorwire_servo::Protocol;
    /// assert_eq!(Protocol::Scs1.name(), "scs1");
    /// assert_eq!(Protocol::from_name("dxl2"), Some(Protocol::Dxl2));
    /// assert_eq!(Protocol::from_name("dxl1"), None);
    /// ```
    #[must_use]
    pub const fn name(self) -> &'static str {
        match self {
            Self::Scs0 => "scs0",
            Self::Scs1 => "scs1",
            Self::Dxl2 => "dxl2",
        }
    }

    /// The protocol named `name` (`scs0`, `scs1`, `dxl2`).
    #[must_use]
    pub fn from_name(name: &str) -> Option<Self> {
        [Self::Scs0, Self::Scs1, Self::Dxl2]
            .into_iter()
            .find(|p| p.name() == name)
    }

    /// Whether its multi-byte values are big-endian on the wire (Feetech's
    /// SCS series); the others are little-endian.
    #[must_use]
    pub const fn big_endian(self) -> bool {
        matches!(self, Self::Scs1)
    }

    /// `value`'s low `length` bytes (1, 2 or 4) as this protocol writes
    /// them, as the SDKs' `write1ByteTxOnly`, `write2ByteTxOnly` and
    /// `write4ByteTxOnly` do: little-endian, or for Feetech's big-endian
    /// series each 16-bit word big-endian, the low word first.
    ///
    /// ```
    /// use motorwire_servo::Protocol;
    /// assert_eq!(Protocol::Dxl2.value_bytes(0x1234_5678, 4), Ok(vec![0x78, 0x56, 0x34, 0x12]));
    /// assert_eq!(Protocol::Scs1.value_bytes(0x1234_5678, 4), Ok(vec![0x56, 0x78, 0x12, 0x34]));
    /// assert_eq!(Protocol::Scs0.value_bytes(0x0800, 2), Ok(vec![0x00, 0x08]));
    /// ```
    ///
    /// # Errors
    /// [`EncodeError::ValueLength`] for a length other than 1, 2 or 4, and
    /// [`EncodeError::ValueTooLarge`] for a value that does not fit.
    pub fn value_bytes(self, value: u32, length: u8) -> Result<Vec<u8>, EncodeError> {
        let fits = match length {
            1 => value <= 0xFF,
            2 => value <= 0xFFFF,
            4 => true,
            _ => return Err(EncodeError::ValueLength { length }),
        };
        if !fits {
            return Err(EncodeError::ValueTooLarge { value, length });
        }
        let word = |w: u32| -> [u8; 2] {
            let [lo, hi, ..] = w.to_le_bytes();
            if self.big_endian() {
                [hi, lo]
            } else {
                [lo, hi]
            }
        };
        Ok(match length {
            1 => alloc::vec![value.to_le_bytes()[0]],
            2 => word(value).to_vec(),
            _ => {
                let mut v = word(value & 0xFFFF).to_vec();
                v.extend_from_slice(&word(value >> 16));
                v
            }
        })
    }

    /// The value of 1, 2 or 4 `bytes` as this protocol writes them (the
    /// inverse of [`Protocol::value_bytes`], as the SDKs' `read1ByteTxRx`,
    /// `read2ByteTxRx` and `read4ByteTxRx` read them); `None` for another
    /// length.
    ///
    /// ```
    /// use motorwire_servo::Protocol;
    /// assert_eq!(Protocol::Scs1.value_of(&[0x56, 0x78, 0x12, 0x34]), Some(0x1234_5678));
    /// assert_eq!(Protocol::Dxl2.value_of(&[0x78, 0x56, 0x34, 0x12]), Some(0x1234_5678));
    /// assert_eq!(Protocol::Scs0.value_of(&[0x00, 0x08]), Some(0x0800));
    /// assert_eq!(Protocol::Scs0.value_of(&[1, 2, 3]), None);
    /// ```
    #[must_use]
    pub fn value_of(self, bytes: &[u8]) -> Option<u32> {
        let word = |a: u8, b: u8| -> u32 {
            if self.big_endian() {
                u32::from(a) << 8 | u32::from(b)
            } else {
                u32::from(b) << 8 | u32::from(a)
            }
        };
        match *bytes {
            [b] => Some(u32::from(b)),
            [a, b] => Some(word(a, b)),
            [a, b, c, d] => Some(word(a, b) | word(c, d) << 16),
            _ => None,
        }
    }
}

/// One instruction to the servos of a bus. Each protocol takes the
/// instructions it has ([`encode`] refuses the others): Feetech has no
/// reboot, factory reset, bulk read or bulk write.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Instruction {
    /// Is servo `id` there (its status answers); the broadcast id asks
    /// every servo, each answering in turn (the SDKs' `broadcastPing`).
    Ping {
        /// The servo, or every servo ([`BROADCAST_ID`]).
        id: u8,
    },
    /// `length` bytes of servo `id`'s control table from `address`.
    Read {
        /// The servo.
        id: u8,
        /// The first address.
        address: u16,
        /// How many bytes.
        length: u16,
    },
    /// `data` into servo `id`'s control table from `address`, at once.
    Write {
        /// The servo, or every servo ([`BROADCAST_ID`]).
        id: u8,
        /// The first address.
        address: u16,
        /// The bytes.
        data: Vec<u8>,
    },
    /// `data` held by servo `id` until an [`Instruction::Action`].
    RegWrite {
        /// The servo, or every servo ([`BROADCAST_ID`]).
        id: u8,
        /// The first address.
        address: u16,
        /// The bytes.
        data: Vec<u8>,
    },
    /// The held writes of servo `id` (or of every servo, broadcast) done.
    Action {
        /// The servo, or every servo ([`BROADCAST_ID`]).
        id: u8,
    },
    /// `length` bytes from `address` of each of `ids`, each answering in
    /// turn.
    SyncRead {
        /// The first address.
        address: u16,
        /// How many bytes of each.
        length: u16,
        /// The servos, in the order they answer.
        ids: Vec<u8>,
    },
    /// `length` bytes from `address` into each servo: each entry its id
    /// and its `length` bytes.
    SyncWrite {
        /// The first address.
        address: u16,
        /// How many bytes each.
        length: u16,
        /// Each servo and its bytes.
        entries: Vec<(u8, Vec<u8>)>,
    },
    /// Servo `id` restarted (Dynamixel).
    Reboot {
        /// The servo, or every servo ([`BROADCAST_ID`]).
        id: u8,
    },
    /// Servo `id` back to its factory settings (Dynamixel).
    FactoryReset {
        /// The servo, or every servo ([`BROADCAST_ID`]).
        id: u8,
        /// What is reset: 0xFF everything, 0x01 all but its id, 0x02 all
        /// but its id and baud rate.
        option: u8,
    },
    /// Several servos read at once, each its own address and length
    /// (Dynamixel).
    BulkRead {
        /// Each read: the servo, the first address, how many bytes.
        reads: Vec<(u8, u16, u16)>,
    },
    /// Several servos written at once, each its own address and data
    /// (Dynamixel).
    BulkWrite {
        /// Each write: the servo, the first address, the bytes.
        writes: Vec<(u8, u16, Vec<u8>)>,
    },
}

impl Instruction {
    /// Its name, as the command line and the SDKs' packet names say it.
    #[must_use]
    pub const fn name(&self) -> &'static str {
        match self {
            Self::Ping { .. } => "ping",
            Self::Read { .. } => "read",
            Self::Write { .. } => "write",
            Self::RegWrite { .. } => "reg_write",
            Self::Action { .. } => "action",
            Self::SyncRead { .. } => "sync_read",
            Self::SyncWrite { .. } => "sync_write",
            Self::Reboot { .. } => "reboot",
            Self::FactoryReset { .. } => "factory_reset",
            Self::BulkRead { .. } => "bulk_read",
            Self::BulkWrite { .. } => "bulk_write",
        }
    }
}

/// Why an instruction cannot be written.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum EncodeError {
    /// The protocol has no such instruction.
    #[error("{protocol} has no {instruction} instruction")]
    NotInProtocol {
        /// The instruction.
        instruction: &'static str,
        /// The protocol.
        protocol: &'static str,
    },
    /// An id no servo can have (above 252 and not the broadcast 254), or
    /// the broadcast id where the instruction addresses one servo.
    #[error("id {id} is not a servo's id (0 to 252) for {instruction}")]
    Id {
        /// The id.
        id: u8,
        /// The instruction.
        instruction: &'static str,
    },
    /// An address or length beyond what the protocol's field holds
    /// (Feetech: one byte each).
    #[error("{field} {value} does not fit the protocol's {bits}-bit field")]
    Field {
        /// The field: `address` or `length`.
        field: &'static str,
        /// Its value.
        value: u32,
        /// The field's width.
        bits: u8,
    },
    /// A sync write entry whose data is not the instruction's length.
    #[error("sync write: servo {id}'s data is {got} bytes, not the length {length}")]
    EntryLength {
        /// The servo.
        id: u8,
        /// Its data's length.
        got: usize,
        /// The instruction's length.
        length: u16,
    },
    /// A servo listed twice in one sync or bulk instruction (the SDKs'
    /// group classes keep the first and drop the second: which was meant
    /// is not known).
    #[error("{instruction} lists servo {id} twice")]
    Duplicate {
        /// The servo.
        id: u8,
        /// The instruction.
        instruction: &'static str,
    },
    /// A sync read or write of no bytes.
    #[error("{instruction} of length 0 reads or writes nothing")]
    ZeroLength {
        /// The instruction.
        instruction: &'static str,
    },
    /// A list instruction (sync read, sync write, bulk read, bulk write)
    /// with nothing in it.
    #[error("{instruction} lists no servo")]
    Empty {
        /// The instruction.
        instruction: &'static str,
    },
    /// The whole packet is longer than the servos (and the SDK) take.
    #[error("the packet would be {length} bytes, longer than the {max} the protocol takes")]
    TooLong {
        /// Its length.
        length: usize,
        /// The protocol's longest.
        max: usize,
    },
    /// A value to write in a length that is not 1, 2 or 4 bytes.
    #[error("a value is written in 1, 2 or 4 bytes, not {length}")]
    ValueLength {
        /// The length asked for.
        length: u8,
    },
    /// A value that does not fit its length.
    #[error("value {value} does not fit in {length} bytes")]
    ValueTooLarge {
        /// The value.
        value: u32,
        /// The length.
        length: u8,
    },
}

/// What a servo answered: its id, its error byte and its parameters (a
/// read's data, a ping's model number).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Status {
    /// The servo's id.
    pub id: u8,
    /// Its error byte (Feetech: the error bits; Dynamixel: the alert bit
    /// and the error number).
    pub error: u8,
    /// Its parameters.
    pub params: Vec<u8>,
}

/// A status packet found in a byte stream, and how many bytes of the
/// stream were read to find it (as the SDK reads them: what comes after
/// belongs to the next packet).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Decoded {
    /// The packet.
    pub status: Status,
    /// The bytes of the stream read.
    pub consumed: usize,
}

/// Why no status packet was read from a byte stream.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum DecodeError {
    /// Nothing came: the servo did not answer (the SDK's
    /// `COMM_RX_TIMEOUT`).
    #[error("no status packet: nothing came")]
    Timeout,
    /// The stream ended inside a packet, or no packet header came in what
    /// did (the SDK's `COMM_RX_CORRUPT`).
    #[error("the status packet is incomplete: {have} of its {need} bytes came")]
    Incomplete {
        /// The bytes of the packet so far.
        have: usize,
        /// The bytes it needs.
        need: usize,
    },
    /// The packet's checksum (Feetech) or CRC (Dynamixel) is not its
    /// bytes' (the SDK's `COMM_RX_CORRUPT`).
    #[error("the status packet's check is {got:#06x}, its bytes' is {expected:#06x}")]
    Check {
        /// Its bytes' check.
        expected: u16,
        /// The check it carries.
        got: u16,
    },
    /// The packet carries fewer parameters than the read asked for (the
    /// SDK would hand over its checksum and what follows as data).
    #[error("the status packet carries {params} parameter bytes, the read asked for {asked}")]
    Short {
        /// The parameters it carries.
        params: usize,
        /// The bytes the read asked for.
        asked: usize,
    },
}

impl DecodeError {
    /// Its kind in one word: `timeout`, `incomplete`, `check`, `short`.
    #[must_use]
    pub const fn kind(&self) -> &'static str {
        match self {
            Self::Timeout => "timeout",
            Self::Incomplete { .. } => "incomplete",
            Self::Check { .. } => "check",
            Self::Short { .. } => "short",
        }
    }
}

/// `instruction` as `protocol` writes it on the wire.
///
/// ```
/// use motorwire_servo::{Instruction, Protocol, encode};
/// // Feetech: read 2 bytes of servo 1's Present_Position (address 56).
/// let read = Instruction::Read { id: 1, address: 56, length: 2 };
/// assert_eq!(encode(Protocol::Scs0, &read)?, [0xFF, 0xFF, 0x01, 0x04, 0x02, 0x38, 0x02, 0xBE]);
/// // Dynamixel 2.0: ping servo 1 (the e-manual's example).
/// assert_eq!(
///     encode(Protocol::Dxl2, &Instruction::Ping { id: 1 })?,
///     [0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x03, 0x00, 0x01, 0x19, 0x4E]
/// );
/// # Ok::<(), motorwire_servo::EncodeError>(())
/// ```
///
/// # Errors
/// [`EncodeError`]: an instruction the protocol does not have, an id,
/// address or length out of range, a sync write entry of another length,
/// an empty list, or a packet longer than the protocol takes.
pub fn encode(protocol: Protocol, instruction: &Instruction) -> Result<Vec<u8>, EncodeError> {
    match protocol {
        Protocol::Scs0 | Protocol::Scs1 => feetech::encode(instruction),
        Protocol::Dxl2 => dynamixel::encode(instruction),
    }
}

/// The first instruction packet in `stream`, as a servo reads one: bytes
/// before a header skipped, the packet's check verified, its parameters
/// read as its instruction lays them out. What a simulated servo (and a
/// bus monitor) reads.
///
/// ```
/// use motorwire_servo::{Instruction, Protocol, decode_instruction, encode};
/// let sync = Instruction::SyncWrite { address: 42, length: 2, entries: vec![(1, vec![0, 8]), (2, vec![0, 4])] };
/// for p in [Protocol::Scs0, Protocol::Dxl2] {
///     let bytes = encode(p, &sync)?;
///     let (read, consumed) = decode_instruction(p, &bytes).expect("a packet");
///     assert_eq!((read, consumed), (sync.clone(), bytes.len()));
/// }
/// # Ok::<(), motorwire_servo::EncodeError>(())
/// ```
///
/// # Errors
/// [`InstructionError`]: nothing or an incomplete packet, a wrong check,
/// an instruction the protocol does not have, or parameters that do not
/// lay out as the instruction's.
pub fn decode_instruction(
    protocol: Protocol,
    stream: &[u8],
) -> Result<(Instruction, usize), InstructionError> {
    match protocol {
        Protocol::Scs0 | Protocol::Scs1 => feetech::read_instruction(stream),
        Protocol::Dxl2 => dynamixel::read_instruction(stream),
    }
}

/// Why no instruction was read from a byte stream.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum InstructionError {
    /// The packet is not all there (or nothing is): `skip` bytes before
    /// its header can be let go.
    #[error("the instruction packet is incomplete")]
    Incomplete {
        /// Bytes before the first header (noise) that no packet starts in.
        skip: usize,
    },
    /// The packet's check is wrong; `consumed` bytes are the packet.
    #[error("the instruction packet's check is wrong")]
    Check {
        /// The packet's bytes.
        consumed: usize,
    },
    /// An instruction the protocol does not have, or parameters that do
    /// not lay out as it says; `consumed` bytes are the packet.
    #[error(
        "instruction {instruction:#04x} with {params} parameter bytes is not one the servo takes"
    )]
    Malformed {
        /// The instruction byte.
        instruction: u8,
        /// Its parameter bytes.
        params: usize,
        /// The packet's bytes.
        consumed: usize,
    },
}

/// The instruction an instruction byte and its parameters make (`id` the
/// packet's).
pub(crate) fn instruction_of(
    id: u8,
    inst: u8,
    p: &[u8],
    wide: bool,
    consumed: usize,
) -> Result<Instruction, InstructionError> {
    let bad = || InstructionError::Malformed {
        instruction: inst,
        params: p.len(),
        consumed,
    };
    // Addresses and lengths: one byte (Feetech) or two little-endian.
    let w = if wide { 2 } else { 1 };
    let field = |at: usize| -> Option<u16> {
        if wide {
            Some(u16::from_le_bytes([*p.get(at)?, *p.get(at + 1)?]))
        } else {
            p.get(at).map(|b| u16::from(*b))
        }
    };
    let rest = |at: usize| p.get(at..).map(<[u8]>::to_vec).unwrap_or_default();
    Ok(match (inst, wide) {
        (0x01, _) if p.is_empty() => Instruction::Ping { id },
        (0x02, _) if p.len() == 2 * w => Instruction::Read {
            id,
            address: field(0).ok_or_else(bad)?,
            length: field(w).ok_or_else(bad)?,
        },
        (0x03, _) if p.len() >= w => Instruction::Write {
            id,
            address: field(0).ok_or_else(bad)?,
            data: rest(w),
        },
        (0x04, _) if p.len() >= w => Instruction::RegWrite {
            id,
            address: field(0).ok_or_else(bad)?,
            data: rest(w),
        },
        (0x05, _) if p.is_empty() => Instruction::Action { id },
        (0x06, true) if p.len() == 1 => Instruction::FactoryReset {
            id,
            option: *p.first().ok_or_else(bad)?,
        },
        (0x08, true) if p.is_empty() => Instruction::Reboot { id },
        (0x82, _) if p.len() >= 2 * w => Instruction::SyncRead {
            address: field(0).ok_or_else(bad)?,
            length: field(w).ok_or_else(bad)?,
            ids: rest(2 * w),
        },
        (0x83, _) if p.len() >= 2 * w => {
            let length = field(w).ok_or_else(bad)?;
            let each = usize::from(length) + 1;
            let body = rest(2 * w);
            if !body.len().is_multiple_of(each) {
                return Err(bad());
            }
            Instruction::SyncWrite {
                address: field(0).ok_or_else(bad)?,
                length,
                entries: body
                    .chunks(each)
                    .map(|c| {
                        (
                            c.first().copied().unwrap_or(0),
                            c.get(1..).unwrap_or(&[]).to_vec(),
                        )
                    })
                    .collect(),
            }
        }
        (0x92, true) if p.len().is_multiple_of(5) => Instruction::BulkRead {
            reads: p
                .chunks(5)
                .map(|c| {
                    let b = |i: usize| c.get(i).copied().unwrap_or(0);
                    (
                        b(0),
                        u16::from_le_bytes([b(1), b(2)]),
                        u16::from_le_bytes([b(3), b(4)]),
                    )
                })
                .collect(),
        },
        (0x93, true) => {
            let mut writes = Vec::new();
            let mut at = 0;
            while at < p.len() {
                let b = |i: usize| p.get(at + i).copied();
                let (Some(id), Some(a0), Some(a1), Some(l0), Some(l1)) =
                    (b(0), b(1), b(2), b(3), b(4))
                else {
                    return Err(bad());
                };
                let n = usize::from(u16::from_le_bytes([l0, l1]));
                let data = p.get(at + 5..at + 5 + n).ok_or_else(bad)?.to_vec();
                writes.push((id, u16::from_le_bytes([a0, a1]), data));
                at += 5 + n;
            }
            Instruction::BulkWrite { writes }
        }
        _ => return Err(bad()),
    })
}

/// `status` as the servo sends it: what a simulated servo answers, and
/// what tests feed a decoder.
///
/// ```
/// use motorwire_servo::{Protocol, Status, decode_status, encode_status};
/// let s = Status { id: 1, error: 0, params: vec![0x00, 0x08] };
/// let bytes = encode_status(Protocol::Scs0, &s)?;
/// assert_eq!(bytes, [0xFF, 0xFF, 0x01, 0x04, 0x00, 0x00, 0x08, 0xF2]);
/// assert_eq!(decode_status(Protocol::Scs0, &bytes, None).map(|d| d.status), Ok(s));
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
/// [`EncodeError::TooLong`]: more parameters than a packet holds.
pub fn encode_status(protocol: Protocol, status: &Status) -> Result<Vec<u8>, EncodeError> {
    match protocol {
        Protocol::Scs0 | Protocol::Scs1 => feetech::status_packet(status),
        Protocol::Dxl2 => dynamixel::status_packet(status),
    }
}

/// A sync or bulk instruction's list, checked once for every protocol
/// (the encoders only lay its bytes out): not empty, each servo a servo's
/// id and listed once, a sync instruction's length not 0, each sync write
/// entry that length.
pub(crate) fn check_lists(instruction: &Instruction) -> Result<(), EncodeError> {
    let name = instruction.name();
    let ids: Vec<u8> = match instruction {
        Instruction::SyncRead { ids, length, .. } => {
            if *length == 0 {
                return Err(EncodeError::ZeroLength { instruction: name });
            }
            ids.clone()
        }
        Instruction::SyncWrite {
            entries, length, ..
        } => {
            if *length == 0 {
                return Err(EncodeError::ZeroLength { instruction: name });
            }
            if let Some((id, data)) = entries
                .iter()
                .find(|(_, d)| d.len() != usize::from(*length))
            {
                return Err(EncodeError::EntryLength {
                    id: *id,
                    got: data.len(),
                    length: *length,
                });
            }
            entries.iter().map(|(id, _)| *id).collect()
        }
        Instruction::BulkRead { reads } => reads.iter().map(|(id, ..)| *id).collect(),
        Instruction::BulkWrite { writes } => writes.iter().map(|(id, ..)| *id).collect(),
        _ => return Ok(()),
    };
    if ids.is_empty() {
        return Err(EncodeError::Empty { instruction: name });
    }
    for (k, id) in ids.iter().enumerate() {
        one(*id, name)?;
        if ids.get(..k).is_some_and(|before| before.contains(id)) {
            return Err(EncodeError::Duplicate {
                id: *id,
                instruction: name,
            });
        }
    }
    Ok(())
}

/// One servo's id (not the broadcast).
pub(crate) fn one(id: u8, instruction: &'static str) -> Result<u8, EncodeError> {
    if id <= MAX_ID {
        Ok(id)
    } else {
        Err(EncodeError::Id { id, instruction })
    }
}

/// A servo's id or the broadcast.
pub(crate) fn any(id: u8, instruction: &'static str) -> Result<u8, EncodeError> {
    if id == BROADCAST_ID {
        Ok(id)
    } else {
        one(id, instruction)
    }
}

/// A sync write's entries laid out after `head`: each servo's id, then its
/// bytes (checked by [`check_lists`]).
pub(crate) fn with_entries(mut head: Vec<u8>, entries: &[(u8, Vec<u8>)]) -> Vec<u8> {
    for (id, data) in entries {
        head.push(*id);
        head.extend_from_slice(data);
    }
    head
}

/// The byte at `i` of `w` (0 past its end: never read where the caller
/// has not made sure it is there).
pub(crate) fn byte_at(w: &[u8], i: usize) -> u8 {
    w.get(i).copied().unwrap_or(0)
}

/// A window on a byte stream that is read as the SDKs read their port:
/// only as many bytes as the packet so far needs.
pub(crate) struct Reader<'a> {
    stream: &'a [u8],
    /// Bytes taken from the stream.
    pub(crate) read: usize,
    pub(crate) window: Vec<u8>,
}

impl<'a> Reader<'a> {
    pub(crate) fn new(stream: &'a [u8]) -> Self {
        Self {
            stream,
            read: 0,
            window: Vec::new(),
        }
    }

    /// Reads from the stream until the window holds `wait` bytes, or the
    /// stream ends.
    pub(crate) fn fill(&mut self, wait: usize) {
        let want = wait.saturating_sub(self.window.len());
        let rest = self.stream.get(self.read..).unwrap_or(&[]);
        let take = want.min(rest.len());
        self.window
            .extend_from_slice(rest.get(..take).unwrap_or(&[]));
        self.read += take;
    }

    /// The stream ended with `wait` bytes wanted.
    pub(crate) fn ended(&self, wait: usize) -> DecodeError {
        if self.window.is_empty() {
            DecodeError::Timeout
        } else {
            DecodeError::Incomplete {
                have: self.window.len(),
                need: wait,
            }
        }
    }
}

/// The first status packet in `stream`, read as the vendor's SDK reads
/// one (`rxPacket`): bytes before a header skipped, a header whose id,
/// length or error byte no packet has taken as noise (one byte skipped),
/// the stream's end before the packet's as incomplete, a wrong check as
/// corrupt. `asked`: the parameter bytes a read asked for (a shorter
/// packet is [`DecodeError::Short`]), whose first `asked` bytes are the
/// parameters; `None` takes all the packet carries.
///
/// ```
/// use motorwire_servo::{Protocol, decode_status};
/// // Servo 1 answers a 2-byte read with 0x0800 (2048, little-endian).
/// let d = decode_status(Protocol::Scs0, &[0xFF, 0xFF, 0x01, 0x04, 0x00, 0x00, 0x08, 0xF2], Some(2))?;
/// assert_eq!((d.status.id, d.status.error, d.status.params), (1, 0, vec![0x00, 0x08]));
/// # Ok::<(), motorwire_servo::DecodeError>(())
/// ```
///
/// # Errors
/// [`DecodeError`]: nothing came, an incomplete packet, a wrong check, or
/// fewer parameters than asked for.
pub fn decode_status(
    protocol: Protocol,
    stream: &[u8],
    asked: Option<usize>,
) -> Result<Decoded, DecodeError> {
    let mut d = match protocol {
        Protocol::Scs0 | Protocol::Scs1 => feetech::read_status(stream)?,
        Protocol::Dxl2 => dynamixel::read_status(stream)?,
    };
    if let Some(asked) = asked {
        if d.status.params.len() < asked {
            return Err(DecodeError::Short {
                params: d.status.params.len(),
                asked,
            });
        }
        d.status.params.truncate(asked);
    }
    Ok(d)
}
