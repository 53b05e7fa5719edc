#![no_main]

use libfuzzer_sys::fuzz_target;
use motorwire_servo::{DecodeError, Protocol, decode_status, encode_status};

// Any bytes as what a Feetech bus gave (little- and big-endian series): a
// status packet or a typed error, never a panic; what was read lies within
// the bytes, and a packet's parameters are never more than its bytes; a
// well-formed packet read is the one its servo would send (its encoding
// ends the bytes read).
fuzz_target!(|data: &[u8]| {
    for p in [Protocol::Scs0, Protocol::Scs1] {
        let asked = data.first().map(|b| usize::from(*b % 8));
        match decode_status(p, data, None) {
            Ok(d) => {
                assert!(d.consumed <= data.len());
                assert!(d.status.params.len() + 6 <= d.consumed);
                let again = encode_status(p, &d.status).unwrap_or_default();
                // A length byte of 0 or 1 is read as the SDK reads it (a
                // packet shorter than its header): only a packet of 6 bytes
                // or more is its own encoding.
                let read = data.get(..d.consumed).unwrap_or_default();
                assert!(
                    again.len() == 6 || read.ends_with(&again),
                    "{read:02x?} does not end with {again:02x?}"
                );
            }
            Err(DecodeError::Short { .. }) => unreachable!("nothing was asked"),
            Err(_) => {}
        }
        let _ = decode_status(p, data, asked);
    }
});
