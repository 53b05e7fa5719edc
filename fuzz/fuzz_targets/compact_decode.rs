#![no_main]

use libfuzzer_sys::fuzz_target;
use motorwire_compact::CompactCommand;

fuzz_target!(|data: &[u8]| {
    if let Ok(cmd) = CompactCommand::decode(data) {
        assert!(cmd.setpoint.is_finite());
        assert_eq!(&cmd.encode().expect("a decoded command encodes")[..], data);
    }
});
