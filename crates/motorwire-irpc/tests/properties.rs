//! Properties over every variant of every wire version: motorwire's bytes are
//! real postcard's bytes, round trips are exact, hostile bytes never panic.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing
)]

mod common;

use common::*;
use motorwire_irpc::*;
use proptest::prelude::*;

/// Cases per property: all of them in an optimized build (CI runs this file
/// with `--release`), a tenth in a debug build, so that the README's
/// `cargo test` stays quick.
const fn cases(all: u32) -> u32 {
    if cfg!(debug_assertions) {
        all / 10
    } else {
        all
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(cases(20_000)))]

    #[test]
    fn bytes_equal_postcards_and_round_trip((v, msg) in versioned_message()) {
        let mut buf = [0u8; 256];
        let n = msg.encode(v, &mut buf).unwrap();
        prop_assert_eq!(to_hex(&buf[..n]), to_hex(&postcard_bytes(v, &msg)));
        prop_assert_eq!(msg.encoded_len(v).unwrap(), n);
        let back = Message::decode(v, &buf[..n]).unwrap();
        prop_assert_eq!(back, msg);
        // Frames: up to 64 bytes they pad and decode; above, FrameTooLarge.
        let mut frame = [0u8; 64];
        match msg.encode_frame(v, &mut frame) {
            Ok(len) => {
                prop_assert!(n <= 64);
                prop_assert_eq!(Some(len), can_fd_len(n));
                prop_assert_eq!(Message::decode_frame(v, &frame[..len]).unwrap(), msg);
            }
            Err(e) => {
                prop_assert!(n > 64);
                prop_assert_eq!(e, Error::FrameTooLarge { len: n });
            }
        }
        // Every strict prefix is truncated, never a panic nor a message.
        for cut in 0..n {
            prop_assert!(Message::decode(v, &buf[..cut]).is_err());
        }
    }

    #[test]
    fn arbitrary_bytes_never_panic_and_what_decodes_reencodes(bytes in prop::collection::vec(any::<u8>(), 0..96)) {
        for v in WireVersion::ALL {
            if let Ok(msg) = Message::decode(v, &bytes) {
                let mut buf = [0u8; 256];
                let n = msg.encode(v, &mut buf).unwrap();
                prop_assert_eq!(&buf[..n], &bytes[..]);
                assert_finite(&msg);
            }
            if let Ok(msg) = Message::decode_frame(v, &bytes) {
                assert_finite(&msg);
            }
        }
    }

    #[test]
    fn mutated_valid_frames_never_panic((v, msg) in versioned_message(), at in any::<prop::sample::Index>(), byte in any::<u8>()) {
        let mut buf = [0u8; 256];
        let n = msg.encode(v, &mut buf).unwrap();
        let i = at.index(n);
        buf[i] = byte;
        if let Ok(back) = Message::decode(v, &buf[..n]) {
            let mut again = [0u8; 256];
            let m = back.encode(v, &mut again).unwrap();
            prop_assert_eq!(&again[..m], &buf[..n]);
            assert_finite(&back);
        }
    }
}

/// Every float of a decoded message is finite: checked through its JSON form,
/// where a non-finite float would appear as `null`.
fn assert_finite(msg: &Message) {
    let json = serde_json::to_string(msg).unwrap();
    assert!(!json.contains("null"), "{json}");
}
