#![no_main]

use libfuzzer_sys::fuzz_target;
use motorwire_wia::{MessageKind, Validator};

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let v = Validator::new().max_depth(16);
    let auto = v.validate_auto(text);
    for kind in MessageKind::ALL {
        let full = v.validate(kind, text);
        if full.is_valid() {
            assert!(v.validate_schema_only(kind, text).is_valid());
        }
    }
    let _ = auto;
});
