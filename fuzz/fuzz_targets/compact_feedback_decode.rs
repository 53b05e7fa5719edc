#![no_main]

use libfuzzer_sys::fuzz_target;
use motorwire_compact::{FEEDBACK_LEN, FeedbackRecord};

fuzz_target!(|data: &[u8]| {
    if let Ok(record) = FeedbackRecord::decode(data) {
        assert!(record.health <= 100);
        let bytes = record.encode().expect("a decoded record encodes");
        // The record's 44 bytes come back exactly; the padding was zero.
        assert_eq!(&bytes[..FEEDBACK_LEN], &data[..FEEDBACK_LEN]);
        assert!(bytes[FEEDBACK_LEN..].iter().all(|&b| b == 0));
    }
});
