//! Feetech's serial bus servo protocol (STS, SMS and SCS series).
//!
//! An instruction packet is `FF FF ID LEN INST PARAMS... CHK`, a status
//! packet `FF FF ID LEN ERR PARAMS... CHK`: `LEN` counts what follows it
//! (the instruction or error byte, the parameters and the checksum), and
//! `CHK` is the low byte of the complement of the sum of every byte from
//! `ID` to the last parameter. Addresses and lengths are one byte; a
//! multi-byte value is little-endian on the STS/SMS series and big-endian
//! on the SCS series (the SDK's `SCS_END`; [`crate::Protocol::value_bytes`]).
//! The whole packet is at most 250 bytes, as the SDK's
//! `TXPACKET_MAX_LEN` and `RXPACKET_MAX_LEN` say.

use alloc::vec::Vec;

use crate::{
    BROADCAST_ID, DecodeError, Decoded, EncodeError, Instruction, InstructionError, Reader, Status,
    any, byte_at, check_lists, instruction_of, one, with_entries,
};

/// The longest packet, instruction or status (bytes).
pub const MAX_PACKET: usize = 250;

const PING: u8 = 0x01;
const READ: u8 = 0x02;
const WRITE: u8 = 0x03;
const REG_WRITE: u8 = 0x04;
const ACTION: u8 = 0x05;
const SYNC_READ: u8 = 0x82;
const SYNC_WRITE: u8 = 0x83;

/// The bits of a Feetech status packet's error byte.
pub mod error_bits {
    /// The supply voltage is outside its limits.
    pub const VOLTAGE: u8 = 0x01;
    /// The position sensor failed.
    pub const ANGLE: u8 = 0x02;
    /// The temperature is above its limit.
    pub const OVERHEAT: u8 = 0x04;
    /// The current is above its limit.
    pub const OVERCURRENT: u8 = 0x08;
    /// The load is above its limit for too long.
    pub const OVERLOAD: u8 = 0x20;
}

/// `instruction` as a Feetech instruction packet (the SDK's byte order for
/// multi-byte addresses and lengths does not arise: each is one byte).
///
/// # Errors
/// [`EncodeError`]: a Dynamixel-only instruction, an id, address or length
/// beyond the protocol's, or a packet over [`MAX_PACKET`] bytes.
pub fn encode(instruction: &Instruction) -> Result<Vec<u8>, EncodeError> {
    let name = instruction.name();
    // An instruction Feetech has not is refused as such, before its list
    // is looked at.
    if !matches!(
        instruction,
        Instruction::Reboot { .. }
            | Instruction::FactoryReset { .. }
            | Instruction::BulkRead { .. }
            | Instruction::BulkWrite { .. }
    ) {
        check_lists(instruction)?;
    }
    let (id, inst, params) = match instruction {
        Instruction::Ping { id } => (any(*id, name)?, PING, Vec::new()),
        Instruction::Read {
            id,
            address,
            length,
        } => (
            one(*id, name)?,
            READ,
            alloc::vec![byte("address", *address)?, byte("length", *length)?],
        ),
        Instruction::Write { id, address, data } => {
            (any(*id, name)?, WRITE, addressed(*address, data)?)
        }
        Instruction::RegWrite { id, address, data } => {
            (any(*id, name)?, REG_WRITE, addressed(*address, data)?)
        }
        Instruction::Action { id } => (any(*id, name)?, ACTION, Vec::new()),
        Instruction::SyncRead {
            address,
            length,
            ids,
        } => {
            let mut p = alloc::vec![byte("address", *address)?, byte("length", *length)?];
            p.extend_from_slice(ids);
            (BROADCAST_ID, SYNC_READ, p)
        }
        Instruction::SyncWrite {
            address,
            length,
            entries,
        } => (
            BROADCAST_ID,
            SYNC_WRITE,
            sync_write(*address, *length, entries)?,
        ),
        Instruction::Reboot { .. }
        | Instruction::FactoryReset { .. }
        | Instruction::BulkRead { .. }
        | Instruction::BulkWrite { .. } => {
            return Err(EncodeError::NotInProtocol {
                instruction: name,
                protocol: "Feetech",
            });
        }
    };
    packet(id, inst, &params)
}

/// A status packet: `FF FF id LEN error params CHK`.
pub(crate) fn status_packet(status: &Status) -> Result<Vec<u8>, EncodeError> {
    packet(status.id, status.error, &status.params)
}

/// `FF FF id LEN inst params CHK`.
fn packet(id: u8, inst: u8, params: &[u8]) -> Result<Vec<u8>, EncodeError> {
    let total = params.len() + 6;
    if total > MAX_PACKET {
        return Err(EncodeError::TooLong {
            length: total,
            max: MAX_PACKET,
        });
    }
    let len = u8::try_from(params.len() + 2).map_err(|_| EncodeError::TooLong {
        length: total,
        max: MAX_PACKET,
    })?;
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(&[0xFF, 0xFF, id, len, inst]);
    out.extend_from_slice(params);
    out.push(checksum(out.get(2..).unwrap_or(&[])));
    Ok(out)
}

/// The complement of the sum of `bytes`, its low byte.
fn checksum(bytes: &[u8]) -> u8 {
    !bytes.iter().fold(0u8, |s, b| s.wrapping_add(*b))
}

fn addressed(address: u16, data: &[u8]) -> Result<Vec<u8>, EncodeError> {
    let mut p = Vec::with_capacity(data.len() + 1);
    p.push(byte("address", address)?);
    p.extend_from_slice(data);
    Ok(p)
}

fn sync_write(
    address: u16,
    length: u16,
    entries: &[(u8, Vec<u8>)],
) -> Result<Vec<u8>, EncodeError> {
    let head = alloc::vec![byte("address", address)?, byte("length", length)?];
    Ok(with_entries(head, entries))
}

/// A one-byte field.
fn byte(field: &'static str, value: u16) -> Result<u8, EncodeError> {
    u8::try_from(value).map_err(|_| EncodeError::Field {
        field,
        value: u32::from(value),
        bits: 8,
    })
}

/// The first status packet in `stream`, read as the SDK's `rxPacket` reads
/// one: it takes six bytes (the shortest packet), finds `FF FF` (skipping
/// what comes before), skips one byte where the id is above 253, the
/// length above 250 or the error byte above 0x7F, then takes the packet's
/// length and checks its checksum.
///
/// ```
/// use motorwire_servo::{DecodeError, feetech};
/// // Noise, then servo 3's answer to a write (no parameters).
/// let d = feetech::read_status(&[0x00, 0xFF, 0xFF, 0xFF, 0x03, 0x02, 0x00, 0xFA])?;
/// assert_eq!((d.status.id, d.status.params.len(), d.consumed), (3, 0, 8));
/// // Its checksum wrong.
/// assert_eq!(
///     feetech::read_status(&[0xFF, 0xFF, 0x03, 0x02, 0x00, 0xFB]),
///     Err(DecodeError::Check { expected: 0xFA, got: 0xFB })
/// );
/// # Ok::<(), DecodeError>(())
/// ```
///
/// # Errors
/// [`DecodeError::Timeout`] (nothing), [`DecodeError::Incomplete`],
/// [`DecodeError::Check`].
pub fn read_status(stream: &[u8]) -> Result<Decoded, DecodeError> {
    let mut r = Reader::new(stream);
    let mut wait = 6;
    loop {
        r.fill(wait);
        if r.window.len() < wait {
            return Err(r.ended(wait));
        }
        let w = &r.window;
        let at = (0..w.len() - 1)
            .find(|&i| byte_at(w, i) == 0xFF && byte_at(w, i + 1) == 0xFF)
            .unwrap_or(w.len() - 2);
        if at != 0 {
            r.window.drain(..at);
            continue;
        }
        let (id, len, error) = (byte_at(w, 2), byte_at(w, 3), byte_at(w, 4));
        if id > 0xFD || usize::from(len) > MAX_PACKET || error > 0x7F {
            r.window.remove(0);
            continue;
        }
        let need = usize::from(len) + 4;
        if wait != need {
            wait = need;
            continue;
        }
        let expected = checksum(w.get(2..need - 1).unwrap_or(&[]));
        let got = byte_at(w, need - 1);
        if got != expected {
            return Err(DecodeError::Check {
                expected: u16::from(expected),
                got: u16::from(got),
            });
        }
        let params = w.get(5..need - 1).map(<[u8]>::to_vec).unwrap_or_default();
        return Ok(Decoded {
            status: Status { id, error, params },
            consumed: r.read,
        });
    }
}

/// The first instruction packet in `stream` (see
/// [`crate::decode_instruction`]).
///
/// # Errors
/// [`InstructionError`].
pub fn read_instruction(stream: &[u8]) -> Result<(Instruction, usize), InstructionError> {
    let at = (0..stream.len().saturating_sub(1))
        .find(|&i| byte_at(stream, i) == 0xFF && byte_at(stream, i + 1) == 0xFF)
        .unwrap_or(stream.len().saturating_sub(1));
    let p = stream.get(at..).unwrap_or(&[]);
    let incomplete = InstructionError::Incomplete { skip: at };
    if p.len() < 4 {
        return Err(incomplete);
    }
    // A header whose id no servo has (0xFF) or whose length no packet
    // has is noise: its first byte is let go, and the search goes on.
    let need = usize::from(byte_at(p, 3)) + 4;
    if byte_at(p, 2) == 0xFF || !(6..=MAX_PACKET).contains(&need) {
        return Err(InstructionError::Malformed {
            instruction: byte_at(p, 4),
            params: 0,
            consumed: at + 1,
        });
    }
    if p.len() < need {
        return Err(incomplete);
    }
    let consumed = at + need;
    if checksum(p.get(2..need - 1).unwrap_or(&[])) != byte_at(p, need - 1) {
        return Err(InstructionError::Check { consumed });
    }
    let params = p.get(5..need - 1).unwrap_or(&[]);
    let i = instruction_of(byte_at(p, 2), byte_at(p, 4), params, false, consumed)?;
    Ok((i, consumed))
}

#[cfg(test)]
mod tests {
    use super::*;
    use alloc::vec;

    /// Golden bytes, each worked by hand from the packet layout.
    #[test]
    fn instructions_are_their_bytes() {
        let cases: [(Instruction, &[u8]); 6] = [
            (
                Instruction::Ping { id: 1 },
                &[0xFF, 0xFF, 0x01, 0x02, 0x01, 0xFB],
            ),
            (
                // Goal_Position (42) of servo 1 to 2048, little-endian.
                Instruction::Write {
                    id: 1,
                    address: 42,
                    data: vec![0x00, 0x08],
                },
                &[0xFF, 0xFF, 0x01, 0x05, 0x03, 0x2A, 0x00, 0x08, 0xC4],
            ),
            (
                Instruction::RegWrite {
                    id: 2,
                    address: 40,
                    data: vec![1],
                },
                &[0xFF, 0xFF, 0x02, 0x04, 0x04, 0x28, 0x01, 0xCC],
            ),
            (
                Instruction::Action { id: BROADCAST_ID },
                &[0xFF, 0xFF, 0xFE, 0x02, 0x05, 0xFA],
            ),
            (
                Instruction::SyncRead {
                    address: 56,
                    length: 2,
                    ids: vec![1, 2],
                },
                &[0xFF, 0xFF, 0xFE, 0x06, 0x82, 0x38, 0x02, 0x01, 0x02, 0x3C],
            ),
            (
                Instruction::SyncWrite {
                    address: 42,
                    length: 2,
                    entries: vec![(1, vec![0x00, 0x08]), (2, vec![0xFF, 0x07])],
                },
                &[
                    0xFF, 0xFF, 0xFE, 0x0A, 0x83, 0x2A, 0x02, 0x01, 0x00, 0x08, 0x02, 0xFF, 0x07,
                    0x37,
                ],
            ),
        ];
        for (i, bytes) in cases {
            assert_eq!(encode(&i).as_deref(), Ok(bytes), "{i:?}");
        }
    }

    #[test]
    fn what_the_protocol_cannot_carry_is_refused() {
        assert_eq!(
            encode(&Instruction::Reboot { id: 1 }),
            Err(EncodeError::NotInProtocol {
                instruction: "reboot",
                protocol: "Feetech"
            })
        );
        assert_eq!(
            encode(&Instruction::Read {
                id: 1,
                address: 256,
                length: 2
            }),
            Err(EncodeError::Field {
                field: "address",
                value: 256,
                bits: 8
            })
        );
        assert_eq!(
            encode(&Instruction::Read {
                id: BROADCAST_ID,
                address: 1,
                length: 2
            }),
            Err(EncodeError::Id {
                id: BROADCAST_ID,
                instruction: "read"
            })
        );
        assert_eq!(
            encode(&Instruction::Write {
                id: 1,
                address: 0,
                data: vec![0; 244]
            }),
            Err(EncodeError::TooLong {
                length: 251,
                max: 250
            })
        );
        assert_eq!(
            encode(&Instruction::Write {
                id: 1,
                address: 0,
                data: vec![0; 243]
            })
            .map(|b| b.len()),
            Ok(250)
        );
        assert_eq!(
            encode(&Instruction::SyncWrite {
                address: 42,
                length: 2,
                entries: vec![(1, vec![0])]
            }),
            Err(EncodeError::EntryLength {
                id: 1,
                got: 1,
                length: 2
            })
        );
    }

    #[test]
    fn a_hostile_stream_is_read_as_the_sdk_reads_it() {
        let ok = [0xFF, 0xFF, 0x01, 0x04, 0x00, 0x00, 0x08, 0xF2];
        assert_eq!(read_status(&[]), Err(DecodeError::Timeout));
        assert_eq!(
            read_status(&ok[..5]),
            Err(DecodeError::Incomplete { have: 5, need: 6 })
        );
        assert_eq!(
            read_status(&ok[..7]),
            Err(DecodeError::Incomplete { have: 7, need: 8 })
        );
        // An id of 0xFE is no answer: its first byte is skipped, and the
        // packet that follows is read.
        let mut s = vec![0xFF, 0xFF, 0xFE];
        s.extend_from_slice(&ok);
        let d = read_status(&s).unwrap();
        assert_eq!(
            (d.status.id, d.status.params, d.consumed),
            (1, vec![0x00, 0x08], 11)
        );
        // Two packets: the first is read, the second left.
        let mut two = ok.to_vec();
        two.extend_from_slice(&ok);
        assert_eq!(read_status(&two).map(|d| d.consumed), Ok(8));
        // Noise without a header: incomplete, never a panic.
        assert_eq!(
            read_status(&[0x12; 40]),
            Err(DecodeError::Incomplete { have: 4, need: 6 })
        );
    }
}
