//! Dynamixel Protocol 2.0 (the X series: XL330, XL430, XM430 and others).
//!
//! A packet is `FF FF FD 00 ID LEN_L LEN_H INST PARAMS... CRC_L CRC_H`:
//! `LEN` (little-endian) counts what follows it (the instruction, the
//! parameters and the CRC); a status packet's instruction is 0x55,
//! followed by its error byte. The CRC is CRC-16 with polynomial 0x8005,
//! initial value 0, not reflected (the `crc` crate's `CRC_16_UMTS`), over
//! every byte before it. So that a header never appears inside a packet,
//! the sender puts `FD` after every `FF FF FD` from the instruction on
//! (byte stuffing), counted in `LEN`, and the receiver takes it out. A
//! packet is at most 1,024 bytes, as the SDK's `TXPACKET_MAX_LEN` and
//! `RXPACKET_MAX_LEN` say.
//!
//! One difference from the ROBOTIS Python SDK (`dynamixel-sdk` 4.1.0) is
//! deliberate: its `txPacket` computes the stuffed packet and then sends
//! the unstuffed one (the result of `addStuffing` is not kept), so a
//! packet whose parameters hold `FF FF FD` goes out unstuffed with its
//! original length, which a servo reads as a header. This crate sends the
//! stuffed packet, byte for byte what `addStuffing` returns, with its CRC.

use alloc::vec::Vec;

use crc::{CRC_16_UMTS, Crc};

use crate::{
    BROADCAST_ID, DecodeError, Decoded, EncodeError, Instruction, InstructionError, MAX_ID, Reader,
    Status, any, byte_at, check_lists, instruction_of, one, with_entries,
};

/// The longest packet, instruction or status (bytes).
pub const MAX_PACKET: usize = 1024;

/// The CRC of Protocol 2.0.
pub const CRC16: Crc<u16> = Crc::<u16>::new(&CRC_16_UMTS);

const PING: u8 = 0x01;
const READ: u8 = 0x02;
const WRITE: u8 = 0x03;
const REG_WRITE: u8 = 0x04;
const ACTION: u8 = 0x05;
const FACTORY_RESET: u8 = 0x06;
const REBOOT: u8 = 0x08;
/// A status packet's instruction byte.
pub const STATUS: u8 = 0x55;
const SYNC_READ: u8 = 0x82;
const SYNC_WRITE: u8 = 0x83;
const BULK_READ: u8 = 0x92;
const BULK_WRITE: u8 = 0x93;

/// `instruction` as a Protocol 2.0 instruction packet, stuffed.
///
/// ```
/// use motorwire_servo::{Instruction, dynamixel};
/// // Write 0x01 to address 64 (Torque_Enable) of servo 1.
/// let b = dynamixel::encode(&Instruction::Write { id: 1, address: 64, data: vec![1] })?;
/// assert_eq!(b, [0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x06, 0x00, 0x03, 0x40, 0x00, 0x01, 0xDB, 0x66]);
/// // Parameters holding a header are stuffed: FF FF FD becomes FF FF FD FD.
/// let b = dynamixel::encode(&Instruction::Write { id: 1, address: 116, data: vec![0xFF, 0xFF, 0xFD, 0x01] })?;
/// assert_eq!(&b[5..7], &[0x0A, 0x00]);
/// assert_eq!(&b[10..15], &[0xFF, 0xFF, 0xFD, 0xFD, 0x01]);
/// # Ok::<(), motorwire_servo::EncodeError>(())
/// ```
///
/// # Errors
/// [`EncodeError`]: an id out of range, a sync write entry of another
/// length, an empty list, a bulk write's data longer than a length field
/// holds, or a packet over [`MAX_PACKET`] bytes once stuffed.
pub fn encode(instruction: &Instruction) -> Result<Vec<u8>, EncodeError> {
    check_lists(instruction)?;
    let name = instruction.name();
    let (id, inst, params) = match instruction {
        Instruction::Ping { id } => (any(*id, name)?, PING, Vec::new()),
        Instruction::Read {
            id,
            address,
            length,
        } => (one(*id, name)?, READ, words(&[*address, *length])),
        Instruction::Write { id, address, data } => {
            (any(*id, name)?, WRITE, with_data(&words(&[*address]), data))
        }
        Instruction::RegWrite { id, address, data } => (
            any(*id, name)?,
            REG_WRITE,
            with_data(&words(&[*address]), data),
        ),
        Instruction::Action { id } => (any(*id, name)?, ACTION, Vec::new()),
        Instruction::Reboot { id } => (any(*id, name)?, REBOOT, Vec::new()),
        Instruction::FactoryReset { id, option } => {
            (any(*id, name)?, FACTORY_RESET, alloc::vec![*option])
        }
        Instruction::SyncRead {
            address,
            length,
            ids,
        } => {
            let mut p = words(&[*address, *length]);
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
            with_entries(words(&[*address, *length]), entries),
        ),
        Instruction::BulkRead { reads } => {
            let mut p = Vec::with_capacity(reads.len() * 5);
            for (id, address, length) in reads {
                p.push(*id);
                p.extend_from_slice(&words(&[*address, *length]));
            }
            (BROADCAST_ID, BULK_READ, p)
        }
        Instruction::BulkWrite { writes } => (BROADCAST_ID, BULK_WRITE, bulk_write(writes)?),
    };
    packet(id, inst, &params)
}

/// Each of `values` little-endian.
fn words(values: &[u16]) -> Vec<u8> {
    values.iter().flat_map(|v| v.to_le_bytes()).collect()
}

fn with_data(head: &[u8], data: &[u8]) -> Vec<u8> {
    let mut p = Vec::with_capacity(head.len() + data.len());
    p.extend_from_slice(head);
    p.extend_from_slice(data);
    p
}

fn bulk_write(writes: &[(u8, u16, Vec<u8>)]) -> Result<Vec<u8>, EncodeError> {
    let mut p = Vec::new();
    for (id, address, data) in writes {
        let length = u16::try_from(data.len()).map_err(|_| EncodeError::Field {
            field: "length",
            value: u32::try_from(data.len()).unwrap_or(u32::MAX),
            bits: 16,
        })?;
        p.push(*id);
        p.extend_from_slice(&words(&[*address, length]));
        p.extend_from_slice(data);
    }
    Ok(p)
}

/// A status packet: instruction 0x55, the error byte first of its
/// parameters, stuffed.
pub(crate) fn status_packet(status: &Status) -> Result<Vec<u8>, EncodeError> {
    let mut params = Vec::with_capacity(status.params.len() + 1);
    params.push(status.error);
    params.extend_from_slice(&status.params);
    packet(status.id, STATUS, &params)
}

/// The packet: header, id, length, instruction and parameters stuffed,
/// CRC.
fn packet(id: u8, inst: u8, params: &[u8]) -> Result<Vec<u8>, EncodeError> {
    // The length before stuffing (the instruction, parameters and CRC), as
    // the stuffing reads it: its two bytes are looked back at.
    let too_long = |length: usize| EncodeError::TooLong {
        length,
        max: MAX_PACKET,
    };
    let raw_len = u16::try_from(params.len() + 3).map_err(|_| too_long(params.len() + 10))?;
    let mut raw = Vec::with_capacity(params.len() + 8);
    raw.extend_from_slice(&[0xFF, 0xFF, 0xFD, 0x00, id]);
    raw.extend_from_slice(&raw_len.to_le_bytes());
    raw.push(inst);
    raw.extend_from_slice(params);
    let mut out = Vec::with_capacity(raw.len() + 8);
    out.extend_from_slice(raw.get(..7).unwrap_or(&[]));
    for i in 7..raw.len() {
        let b = byte_at(&raw, i);
        out.push(b);
        if b == 0xFD && byte_at(&raw, i - 1) == 0xFF && byte_at(&raw, i - 2) == 0xFF {
            out.push(0xFD);
        }
    }
    let total = out.len() + 2;
    if total > MAX_PACKET {
        return Err(too_long(total));
    }
    let len = u16::try_from(total - 7).map_err(|_| too_long(total))?;
    if let Some(l) = out.get_mut(5..7) {
        l.copy_from_slice(&len.to_le_bytes());
    }
    let crc = CRC16.checksum(&out);
    out.extend_from_slice(&crc.to_le_bytes());
    Ok(out)
}

/// The first status packet in `stream`, read as the SDK's `rxPacket` reads
/// one: it takes eleven bytes (the shortest packet), finds `FF FF FD` not
/// followed by `FD` (skipping what comes before), skips one byte where
/// the reserved byte is not 0, the id above 252, the length above 1,024
/// or the instruction not 0x55, then takes the packet's length, checks
/// its CRC and takes the stuffing out.
///
/// ```
/// use motorwire_servo::{DecodeError, dynamixel};
/// // Servo 1 answers a ping: model 1200 (XL330-M288), firmware 46.
/// let answer = [0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x07, 0x00, 0x55, 0x00, 0xB0, 0x04, 0x2E, 0xED, 0x54];
/// let d = dynamixel::read_status(&answer)?;
/// assert_eq!((d.status.id, d.status.error, d.status.params), (1, 0, vec![0xB0, 0x04, 0x2E]));
/// # Ok::<(), DecodeError>(())
/// ```
///
/// # Errors
/// [`DecodeError::Timeout`] (nothing), [`DecodeError::Incomplete`],
/// [`DecodeError::Check`].
pub fn read_status(stream: &[u8]) -> Result<Decoded, DecodeError> {
    let mut r = Reader::new(stream);
    let mut wait = 11;
    loop {
        r.fill(wait);
        if r.window.len() < wait {
            return Err(r.ended(wait));
        }
        let w = &r.window;
        let at = (0..w.len() - 3)
            .find(|&i| {
                byte_at(w, i) == 0xFF
                    && byte_at(w, i + 1) == 0xFF
                    && byte_at(w, i + 2) == 0xFD
                    && byte_at(w, i + 3) != 0xFD
            })
            .unwrap_or(w.len() - 4);
        if at != 0 {
            r.window.drain(..at);
            continue;
        }
        let len = usize::from(u16::from_le_bytes([byte_at(w, 5), byte_at(w, 6)]));
        if byte_at(w, 3) != 0
            || byte_at(w, 4) > MAX_ID
            || len > MAX_PACKET
            || byte_at(w, 7) != STATUS
        {
            r.window.remove(0);
            continue;
        }
        let need = len + 7;
        if wait != need {
            wait = need;
            continue;
        }
        let expected = CRC16.checksum(w.get(..need - 2).unwrap_or(&[]));
        let got = u16::from_le_bytes([byte_at(w, need - 2), byte_at(w, need - 1)]);
        if got != expected {
            return Err(DecodeError::Check { expected, got });
        }
        let consumed = r.read;
        let len_out = unstuff(&mut r.window, len);
        let w = &r.window;
        let params = w
            .get(9..(9 + len_out.saturating_sub(4)).max(9))
            .map(<[u8]>::to_vec)
            .unwrap_or_default();
        return Ok(Decoded {
            status: Status {
                id: byte_at(w, 4),
                error: byte_at(w, 8),
                params,
            },
            consumed,
        });
    }
}

/// The first instruction packet in `stream` (see
/// [`crate::decode_instruction`]): a header `FF FF FD 00`, its CRC
/// verified, its stuffing taken out.
///
/// # Errors
/// [`InstructionError`].
pub fn read_instruction(stream: &[u8]) -> Result<(Instruction, usize), InstructionError> {
    let at = (0..stream.len().saturating_sub(3))
        .find(|&i| {
            byte_at(stream, i) == 0xFF
                && byte_at(stream, i + 1) == 0xFF
                && byte_at(stream, i + 2) == 0xFD
                && byte_at(stream, i + 3) == 0x00
        })
        .unwrap_or(stream.len().saturating_sub(3));
    let p = stream.get(at..).unwrap_or(&[]);
    if p.len() < 10 {
        return Err(InstructionError::Incomplete { skip: at });
    }
    let len = usize::from(u16::from_le_bytes([byte_at(p, 5), byte_at(p, 6)]));
    let need = len + 7;
    // A header whose id no servo has (0xFD, 0xFF) or whose length no
    // packet has is noise: its first byte is let go.
    let id = byte_at(p, 4);
    if id == 0xFD || id == 0xFF || !(3..=MAX_PACKET - 7).contains(&len) {
        return Err(InstructionError::Malformed {
            instruction: byte_at(p, 7),
            params: 0,
            consumed: at + 1,
        });
    }
    if p.len() < need {
        return Err(InstructionError::Incomplete { skip: at });
    }
    let consumed = at + need;
    let crc = u16::from_le_bytes([byte_at(p, need - 2), byte_at(p, need - 1)]);
    if CRC16.checksum(p.get(..need - 2).unwrap_or(&[])) != crc {
        return Err(InstructionError::Check { consumed });
    }
    let mut w = p.get(..need).unwrap_or(&[]).to_vec();
    let out_len = unstuff(&mut w, len);
    let params = w
        .get(8..(8 + out_len.saturating_sub(3)).max(8))
        .unwrap_or(&[]);
    let i = instruction_of(byte_at(&w, 4), byte_at(&w, 7), params, true, consumed)?;
    Ok((i, consumed))
}

/// Takes the stuffing out of the packet at the start of `w` whose length
/// field is `len`, in place, as the SDK's `removeStuffing` does (each
/// byte looked at where the bytes before it now stand); its length after.
fn unstuff(w: &mut [u8], len: usize) -> usize {
    let mut out_len = len;
    let mut index = 7;
    for i in 0..len.saturating_sub(2) {
        let here = byte_at(w, i + 7);
        if here == 0xFD
            && byte_at(w, i + 8) == 0xFD
            && byte_at(w, i + 6) == 0xFF
            && byte_at(w, i + 5) == 0xFF
        {
            out_len -= 1;
        } else {
            set(w, index, here);
            index += 1;
        }
    }
    // The CRC after what is kept.
    let (c0, c1) = (byte_at(w, 7 + len - 2), byte_at(w, 7 + len - 1));
    set(w, index, c0);
    set(w, index + 1, c1);
    out_len
}

fn set(w: &mut [u8], i: usize, b: u8) {
    if let Some(x) = w.get_mut(i) {
        *x = b;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use alloc::vec;

    /// The e-manual's examples (Protocol 2.0, "Instruction Details").
    #[test]
    fn instructions_are_the_e_manuals_bytes() {
        let cases: [(Instruction, &[u8]); 6] = [
            (
                Instruction::Ping { id: 1 },
                &[0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x03, 0x00, 0x01, 0x19, 0x4E],
            ),
            (
                // Present_Position (132), 4 bytes, of servo 1.
                Instruction::Read {
                    id: 1,
                    address: 132,
                    length: 4,
                },
                &[
                    0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x07, 0x00, 0x02, 0x84, 0x00, 0x04, 0x00, 0x1D,
                    0x15,
                ],
            ),
            (
                Instruction::Write {
                    id: 1,
                    address: 116,
                    data: vec![0x00, 0x02, 0x00, 0x00],
                },
                &[
                    0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x09, 0x00, 0x03, 0x74, 0x00, 0x00, 0x02, 0x00,
                    0x00, 0xCA, 0x89,
                ],
            ),
            (
                Instruction::Action { id: 1 },
                &[0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x03, 0x00, 0x05, 0x02, 0xCE],
            ),
            (
                Instruction::Reboot { id: 1 },
                &[0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x03, 0x00, 0x08, 0x2F, 0x4E],
            ),
            (
                Instruction::SyncRead {
                    address: 132,
                    length: 4,
                    ids: vec![1, 2],
                },
                &[
                    0xFF, 0xFF, 0xFD, 0x00, 0xFE, 0x09, 0x00, 0x82, 0x84, 0x00, 0x04, 0x00, 0x01,
                    0x02, 0xCE, 0xFA,
                ],
            ),
        ];
        for (i, bytes) in cases {
            assert_eq!(encode(&i).as_deref(), Ok(bytes), "{i:?}");
        }
    }

    #[test]
    fn what_the_protocol_cannot_carry_is_refused() {
        // A broadcast ping is every servo's (each answers in turn); a read
        // is one servo's.
        assert_eq!(
            encode(&Instruction::Ping { id: BROADCAST_ID }).map(|b| b[4]),
            Ok(BROADCAST_ID)
        );
        assert_eq!(
            encode(&Instruction::Read {
                id: BROADCAST_ID,
                address: 0,
                length: 2
            }),
            Err(EncodeError::Id {
                id: BROADCAST_ID,
                instruction: "read"
            })
        );
        assert_eq!(
            encode(&Instruction::BulkRead { reads: vec![] }),
            Err(EncodeError::Empty {
                instruction: "bulk_read"
            })
        );
        assert_eq!(
            encode(&Instruction::Write {
                id: 1,
                address: 0,
                data: vec![0; 1013]
            }),
            Err(EncodeError::TooLong {
                length: 1025,
                max: 1024
            })
        );
        assert_eq!(
            encode(&Instruction::Write {
                id: 1,
                address: 0,
                data: vec![0; 1012]
            })
            .map(|b| b.len()),
            Ok(1024)
        );
    }

    /// A status packet whose parameters were stuffed comes back as the
    /// servo meant it; noise, truncation and a wrong CRC are typed.
    #[test]
    fn a_hostile_stream_is_read_as_the_sdk_reads_it() {
        let status = |params: &[u8]| {
            let mut raw = vec![0xFF, 0xFF, 0xFD, 0x00, 0x01, 0, 0, STATUS, 0x00];
            let mut stuffed = Vec::new();
            for (k, b) in params.iter().enumerate() {
                stuffed.push(*b);
                if *b == 0xFD && k >= 2 && params[k - 1] == 0xFF && params[k - 2] == 0xFF {
                    stuffed.push(0xFD);
                }
            }
            raw.extend_from_slice(&stuffed);
            let len = u16::try_from(stuffed.len() + 4).unwrap();
            raw[5..7].copy_from_slice(&len.to_le_bytes());
            let crc = CRC16.checksum(&raw);
            raw.extend_from_slice(&crc.to_le_bytes());
            raw
        };
        let s = status(&[0x10, 0xFF, 0xFF, 0xFD, 0x20]);
        assert_eq!(s.len(), 11 + 6);
        let d = read_status(&s).unwrap();
        assert_eq!(d.status.params, vec![0x10, 0xFF, 0xFF, 0xFD, 0x20]);
        assert_eq!(d.consumed, s.len());
        assert_eq!(read_status(&[]), Err(DecodeError::Timeout));
        assert_eq!(
            read_status(&s[..12]),
            Err(DecodeError::Incomplete { have: 12, need: 17 })
        );
        let mut bad = s.clone();
        let last = bad.len() - 1;
        bad[last] ^= 0x01;
        assert!(matches!(read_status(&bad), Err(DecodeError::Check { .. })));
        let mut noisy = vec![0xFF, 0xFF, 0xFD, 0xFD, 0x00, 0xFF];
        noisy.extend_from_slice(&s);
        assert_eq!(read_status(&noisy).map(|d| d.status.params.len()), Ok(5));
        assert!(read_status(&[0xFF; 64]).is_err());
    }
}
