#![no_main]

use libfuzzer_sys::fuzz_target;
use motorwire_orion::{ArmController, FeedbackKeys, Input, Output};

// Any text: parsing never panics; whatever parses re-parses to itself from
// its own JSON, and the controller handles it.
fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    if let Ok(input) = Input::parse(text) {
        assert_eq!(Input::parse(&input.to_json()).ok(), Some(input));
        let mut arm = ArmController::new();
        let response = arm.handle(&input);
        for keys in [FeedbackKeys::Table, FeedbackKeys::Example] {
            let line = response.output.to_json(keys);
            assert_eq!(Output::parse(&line).ok(), Some(response.output));
        }
    }
    if let Ok(output) = Output::parse(text) {
        for keys in [FeedbackKeys::Table, FeedbackKeys::Example] {
            assert_eq!(Output::parse(&output.to_json(keys)).ok(), Some(output));
        }
    }
});
