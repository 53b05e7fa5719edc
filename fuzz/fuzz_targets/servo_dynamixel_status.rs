#![no_main]

use libfuzzer_sys::fuzz_target;
use motorwire_servo::{DecodeError, Protocol, decode_status};

// Any bytes as what a Dynamixel Protocol 2.0 bus gave: a status packet or
// a typed error, never a panic; what was read lies within the bytes, and
// a packet's parameters are never more than its bytes.
fuzz_target!(|data: &[u8]| {
    let asked = data.first().map(|b| usize::from(*b % 8));
    match decode_status(Protocol::Dxl2, data, None) {
        Ok(d) => {
            assert!(d.consumed <= data.len());
            assert!(d.status.params.len() + 11 <= d.consumed);
        }
        Err(DecodeError::Short { .. }) => unreachable!("nothing was asked"),
        Err(_) => {}
    }
    let _ = decode_status(Protocol::Dxl2, data, asked);
});
