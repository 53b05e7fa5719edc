#![no_main]

use libfuzzer_sys::fuzz_target;
use motorwire_irpc::WireVersion;

fuzz_target!(|data: &[u8]| {
    motorwire_fuzz::check_decode(WireVersion::V2_2, data);
});
