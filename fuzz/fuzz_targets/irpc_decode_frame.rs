#![no_main]

use libfuzzer_sys::fuzz_target;
use motorwire_irpc::WireVersion;

fuzz_target!(|data: &[u8]| {
    for v in WireVersion::ALL {
        motorwire_fuzz::check_frame(v, data);
    }
});
