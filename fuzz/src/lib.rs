//! What every iRPC fuzz target checks of a decoded message.
#![forbid(unsafe_code)]

use motorwire_irpc::{Message, WireVersion};

/// Decodes `data` as one message of `v`; anything that decodes must re-encode
/// to exactly the same bytes (so every float in it is finite: the encoder
/// refuses non-finite ones).
pub fn check_decode(v: WireVersion, data: &[u8]) {
    if let Ok(msg) = Message::decode(v, data) {
        let mut buf = [0u8; 256];
        let n = msg.encode(v, &mut buf).expect("a decoded message encodes");
        assert_eq!(&buf[..n], data, "decode then encode is not the identity");
        assert_eq!(msg.encoded_len(v), Ok(n));
    }
}

/// Decodes `data` as a CAN-FD frame of `v`: the message re-encodes to a
/// prefix of the frame and the rest is zero.
pub fn check_frame(v: WireVersion, data: &[u8]) {
    if let Ok(msg) = Message::decode_frame(v, data) {
        let mut buf = [0u8; 256];
        let n = msg.encode(v, &mut buf).expect("a decoded message encodes");
        assert_eq!(&buf[..n], &data[..n]);
        assert!(data[n..].iter().all(|b| *b == 0));
    }
}
