//! Encode an iRPC message with a real header into a CAN-FD frame, and
//! decode it back.
//!
//! ```sh
//! cargo run --example irpc_frame
//! ```
//!
//! The arm (node 0x0000) asks joint 0x10 for the iRPC document's S-curve
//! move as msg_id 42, in wire version v2.0: 37 bytes, zero-padded to the
//! CAN-FD length 48. The frame's 11-bit CAN id is the sender's node id;
//! the joint filters on the header's `target_id` and answers `Ack(42)`.

use std::io::Write;

use motorwire_irpc::{
    Header, IrpcMessage, MAX_FRAME_LEN, Payload, SetTargetPayloadV2, WireVersion,
};

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

fn run(out: &mut dyn Write) -> Result<(), Box<dyn std::error::Error>> {
    let wire = WireVersion::V2_0;
    let request = IrpcMessage {
        header: Header {
            source_id: 0x0000,
            target_id: 0x10,
            msg_id: 42,
        },
        payload: Payload::SetTargetV2(SetTargetPayloadV2::scurve(90.0, 100.0, 500.0, 2000.0)),
    };
    let mut frame = [0u8; MAX_FRAME_LEN];
    let len = request.encode_frame(wire, &mut frame)?;
    let frame = frame.get(..len).ok_or("frame length")?;
    writeln!(
        out,
        "can id 0x{:03x}, {len} bytes: {}",
        request.header.source_id,
        hex(frame)
    )?;

    // The receiving side: the frame's bytes back to the message (zero
    // padding accepted, anything else after the message refused).
    let decoded = IrpcMessage::decode_frame(wire, frame)?;
    assert_eq!(decoded, request);
    writeln!(out, "decoded: {decoded:?}")?;

    // Its JSON form, as `motorwire irpc decode` prints it.
    writeln!(out, "json: {}", serde_json::to_string(&decoded)?)?;

    // The joint's answer, and what a corrupt frame gets.
    let ack = IrpcMessage {
        header: Header {
            source_id: 0x10,
            target_id: 0x0000,
            msg_id: 42,
        },
        payload: Payload::Ack(42),
    };
    let mut buf = [0u8; MAX_FRAME_LEN];
    let n = ack.encode_frame(wire, &mut buf)?;
    writeln!(out, "ack: {}", hex(buf.get(..n).ok_or("frame length")?))?;
    let mut corrupt = frame.to_vec();
    if let Some(last) = corrupt.last_mut() {
        *last = 0x07;
    }
    match IrpcMessage::decode_frame(wire, &corrupt) {
        Ok(m) => writeln!(out, "corrupt frame decoded?! {m:?}")?,
        Err(e) => writeln!(out, "corrupt frame: {e}")?,
    }
    Ok(())
}

fn main() -> std::process::ExitCode {
    match run(&mut std::io::stdout()) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("irpc_frame: {e}");
            std::process::ExitCode::FAILURE
        }
    }
}

#[cfg(test)]
mod tests {
    /// The output, exactly.
    const EXPECTED: &str = r##"can id 0x000, 48 bytes: 00102a050000b4420000c842000000000000fa430000fa430000fa440100000000000000000000000000000000000000
decoded: Message { header: Header { source_id: 0, target_id: 16, msg_id: 42 }, payload: SetTargetV2(SetTargetPayloadV2 { target_angle: 90.0, max_velocity: 100.0, target_velocity: 0.0, max_acceleration: 500.0, max_deceleration: 500.0, max_jerk: 2000.0, profile: SCurve, max_current: 0.0, max_temperature: 0.0 }) }
json: {"header":{"source_id":0,"target_id":16,"msg_id":42},"payload":{"SetTargetV2":{"target_angle":90.0,"max_velocity":100.0,"target_velocity":0.0,"max_acceleration":500.0,"max_deceleration":500.0,"max_jerk":2000.0,"profile":"SCurve","max_current":0.0,"max_temperature":0.0}}}
ack: 10002a082a
corrupt frame: byte 47 after the message is not zero padding
"##;

    #[test]
    fn encodes_and_decodes_the_documents_example() {
        let mut out = Vec::new();
        assert!(super::run(&mut out).is_ok());
        assert_eq!(String::from_utf8_lossy(&out), EXPECTED);
    }
}
