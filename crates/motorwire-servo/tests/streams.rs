//! The status decoders on hostile streams: any bytes at all never panic,
//! and a servo's packet after noise, split anywhere or followed by the
//! next packet, is read as it was sent.
#![allow(clippy::unwrap_used, clippy::indexing_slicing)]

use motorwire_servo::{
    DecodeError, Instruction, Protocol, Status, decode_instruction, decode_status, encode,
    encode_status,
};
use proptest::prelude::*;

const PROTOCOLS: [Protocol; 3] = [Protocol::Scs0, Protocol::Scs1, Protocol::Dxl2];

fn status() -> impl Strategy<Value = Status> {
    (
        0u8..=252,
        0u8..=0x7F,
        prop::collection::vec(any::<u8>(), 0..40),
    )
        .prop_map(|(id, error, params)| Status { id, error, params })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 2000, ..ProptestConfig::default() })]

    /// Any bytes: an answer or a typed error, never a panic; what was
    /// read is never more than was given.
    #[test]
    fn any_bytes_are_read_or_refused(bytes in prop::collection::vec(any::<u8>(), 0..300), asked in prop::option::of(0usize..64)) {
        for p in PROTOCOLS {
            if let Ok(d) = decode_status(p, &bytes, asked) {
                prop_assert!(d.consumed <= bytes.len());
                if let Some(a) = asked {
                    prop_assert_eq!(d.status.params.len(), a);
                }
            }
        }
    }

    /// Bytes with no 0xFF before a servo's packet are skipped; the packet
    /// is read whole (stuffed parameters included), and a second packet
    /// behind it is left for the next read.
    #[test]
    fn a_packet_after_noise_is_read_as_sent(s in status(), noise in prop::collection::vec(0u8..0xFF, 0..30), next in status()) {
        for p in PROTOCOLS {
            let packet = encode_status(p, &s).unwrap();
            let mut stream = noise.clone();
            stream.extend_from_slice(&packet);
            let behind = stream.len();
            stream.extend_from_slice(&encode_status(p, &next).unwrap());
            let d = decode_status(p, &stream, None).unwrap();
            prop_assert_eq!(&d.status, &s, "{:?}", p);
            prop_assert_eq!(d.consumed, behind);
            let rest = decode_status(p, &stream[d.consumed..], None).unwrap();
            prop_assert_eq!(rest.status, next.clone());
        }
    }

    /// A packet cut short anywhere is incomplete; a flipped bit in its
    /// check byte is a wrong check.
    #[test]
    fn a_cut_or_corrupted_packet_is_typed(s in status(), cut in any::<prop::sample::Index>()) {
        for p in PROTOCOLS {
            let packet = encode_status(p, &s).unwrap();
            let at = cut.index(packet.len());
            let e = decode_status(p, &packet[..at], None).unwrap_err();
            prop_assert!(matches!(e, DecodeError::Incomplete { .. } | DecodeError::Timeout), "{:?} {:?}", p, e);
            let mut bad = packet.clone();
            let last = bad.len() - 1;
            bad[last] ^= 0x10;
            prop_assert!(matches!(decode_status(p, &bad, None), Err(DecodeError::Check { .. })), "{:?}", p);
        }
    }
}

fn instruction() -> impl Strategy<Value = Instruction> {
    let id = 0u8..=252;
    let data = prop::collection::vec(any::<u8>(), 0..20);
    prop_oneof![
        id.clone().prop_map(|id| Instruction::Ping { id }),
        (id.clone(), 0u16..256, 0u16..256).prop_map(|(id, address, length)| Instruction::Read {
            id,
            address,
            length
        }),
        (id.clone(), 0u16..256, data.clone()).prop_map(|(id, address, data)| Instruction::Write {
            id,
            address,
            data
        }),
        (id.clone(), 0u16..256, data).prop_map(|(id, address, data)| Instruction::RegWrite {
            id,
            address,
            data
        }),
        id.clone().prop_map(|id| Instruction::Action { id }),
        (
            0u16..256,
            1u16..16,
            prop::collection::btree_set(id.clone(), 1..8)
        )
            .prop_map(|(address, length, ids)| Instruction::SyncRead {
                address,
                length,
                ids: ids.into_iter().collect()
            }),
        (0u16..256, 1u16..5, prop::collection::btree_set(id, 1..8)).prop_flat_map(
            |(address, length, ids)| {
                let n = ids.len();
                prop::collection::vec(prop::collection::vec(any::<u8>(), usize::from(length)), n)
                    .prop_map(move |datas| Instruction::SyncWrite {
                        address,
                        length,
                        entries: ids.iter().copied().zip(datas).collect(),
                    })
            }
        ),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 2000, ..ProptestConfig::default() })]

    /// What the host writes, a servo reads back as the same instruction,
    /// after noise without a header; any bytes at all never panic.
    #[test]
    fn an_instruction_is_read_as_it_was_written(i in instruction(), noise in prop::collection::vec(0u8..0xFF, 0..10), junk in prop::collection::vec(any::<u8>(), 0..80)) {
        for p in PROTOCOLS {
            let bytes = encode(p, &i).unwrap();
            let mut stream = noise.clone();
            stream.extend_from_slice(&bytes);
            prop_assert_eq!(decode_instruction(p, &stream), Ok((i.clone(), stream.len())), "{:?}", p);
            let _ = decode_instruction(p, &junk);
        }
    }
}

/// A servo listed twice in one sync or bulk instruction, or a sync
/// instruction of no bytes, is refused: the SDKs' group classes drop the
/// second silently.
#[test]
fn duplicates_and_empty_lengths_are_refused() {
    use motorwire_servo::EncodeError;
    for p in PROTOCOLS {
        assert_eq!(
            encode(
                p,
                &Instruction::SyncRead {
                    address: 42,
                    length: 2,
                    ids: vec![1, 2, 1]
                }
            ),
            Err(EncodeError::Duplicate {
                id: 1,
                instruction: "sync_read"
            })
        );
        assert_eq!(
            encode(
                p,
                &Instruction::SyncWrite {
                    address: 42,
                    length: 0,
                    entries: vec![(1, vec![])]
                }
            ),
            Err(EncodeError::ZeroLength {
                instruction: "sync_write"
            })
        );
    }
    assert_eq!(
        encode(
            Protocol::Dxl2,
            &Instruction::BulkWrite {
                writes: vec![(1, 2, vec![1]), (1, 4, vec![2, 3])]
            }
        ),
        Err(EncodeError::Duplicate {
            id: 1,
            instruction: "bulk_write"
        })
    );
}

/// A servo reading the bus: an impossible header (id 0xFF, a length no
/// packet has) is one byte of noise, and the packet behind it is read.
#[test]
fn an_impossible_header_is_noise_to_a_servo() {
    let ping = |p| encode(p, &Instruction::Ping { id: 1 }).unwrap();
    for (p, junk) in [
        (Protocol::Scs0, vec![0xFF, 0xFF, 0xFF, 0xFF]),
        (Protocol::Scs0, vec![0xFF, 0xFF, 0x01, 0xFF]),
        (
            Protocol::Dxl2,
            vec![0xFF, 0xFF, 0xFD, 0x00, 0xFF, 0x03, 0x00],
        ),
        (
            Protocol::Dxl2,
            vec![0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x00, 0x04],
        ),
    ] {
        let mut stream = junk.clone();
        stream.extend_from_slice(&ping(p));
        let mut at = 0;
        let read = loop {
            match decode_instruction(p, &stream[at..]) {
                Ok((i, _)) => break i,
                Err(motorwire_servo::InstructionError::Malformed { consumed, .. }) => {
                    at += consumed
                }
                Err(e) => panic!("{p:?} {junk:02x?}: {e:?}"),
            }
        };
        assert_eq!(read, Instruction::Ping { id: 1 }, "{p:?} {junk:02x?}");
    }
}
