#![no_main]

use libfuzzer_sys::fuzz_target;

// Any bytes as a reply from controller 1: a typed error or a reply, never a
// panic (moteus-protocol's parser is run only on what `decode` checked); and
// as an answer on its diagnostic stream.
fuzz_target!(|data: &[u8]| {
    if let Ok(reply) = motorwire_moteus::decode(0x100, data) {
        assert!(data.len() <= 64);
        assert_eq!(reply.source, 1);
        // One value per register, as the Python library's dict keeps them.
        let mut registers: Vec<u16> = reply.values.iter().map(|v| v.register).collect();
        registers.sort_unstable();
        registers.dedup();
        assert_eq!(registers.len(), reply.values.len());
    }
    // The same bytes as an answer on the diagnostic stream: its text lies
    // within the frame, after the channel and the length.
    if let Ok(answer) = motorwire_moteus::diagnostic::decode(0x100, data) {
        assert_eq!(answer.source, 1);
        assert!(answer.data.len() + 3 <= data.len());
    }
});
