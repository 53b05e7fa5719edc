//! Translated iRPC commands as addressed CAN-FD frames.

use motorwire_irpc::{Header, MAX_FRAME_LEN, Message};

use crate::{IrpcCommand, Refusal};

/// One iRPC message as the CAN-FD frame that carries it (WIRE-FACTS §1.5).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct IrpcFrame {
    /// The frame's standard 11-bit CAN id: the sender's node id (the
    /// header's `source_id`; receivers filter on the header's `target_id`).
    pub can_id: u16,
    /// The message's `msg_id` (its Ack or Nack carries it back).
    pub msg_id: u32,
    /// The encoded message, zero-padded to the next CAN-FD length (0–8,
    /// 12, 16, 20, 24, 32, 48, 64).
    pub data: Vec<u8>,
}

/// The frames that carry `command`'s payloads, in order, from node
/// `source` to the joint's node, each message encoded in the joint's wire
/// version. `msg_id` is the first frame's `msg_id`; each next frame takes
/// the next one (wrapping past `u32::MAX` to 1, as the iRPC client does:
/// 0 is ArmReady's), and on success `msg_id` is left at the one after the
/// last frame, so a stream of commands numbers its frames without a gap.
/// On a refusal it is left unchanged.
///
/// `motor` names the joint in a refusal.
///
/// ```
/// use motorwire_irpc::{Payload, SetTargetPayloadV2, WireVersion};
/// use motorwire_translate::{IrpcCommand, irpc_frames};
/// // The iRPC document's example: SetTargetV2 {90, 100, 0, 500, 500, 2000, SCurve, 0, 0}
/// // from the arm (0x0000) to node 0x10 as msg_id 42 (WIRE-FACTS §1.4).
/// let command = IrpcCommand {
///     node: 0x10,
///     wire: WireVersion::V2_0,
///     payloads: vec![Payload::SetTargetV2(SetTargetPayloadV2::scurve(90.0, 100.0, 500.0, 2000.0))],
/// };
/// let mut msg_id = 42;
/// let frames = irpc_frames("shoulder_pitch", &command, 0x0000, &mut msg_id)?;
/// assert_eq!((frames[0].can_id, frames[0].msg_id, msg_id), (0x000, 42, 43));
/// // 37 bytes, zero-padded to the CAN-FD length 48.
/// assert_eq!(frames[0].data[..37], [
///     0x00, 0x10, 0x2a, 0x05, 0x00, 0x00, 0xb4, 0x42, 0x00, 0x00, 0xc8, 0x42, 0x00,
///     0x00, 0x00, 0x00, 0x00, 0x00, 0xfa, 0x43, 0x00, 0x00, 0xfa, 0x43, 0x00, 0x00,
///     0xfa, 0x44, 0x01, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
/// ]);
/// assert_eq!(frames[0].data[37..], [0u8; 11]);
/// # Ok::<(), motorwire_translate::Refusal>(())
/// ```
///
/// # Errors
/// [`Refusal::NotRepresentable`] for a `source` above 0x7FF (it is the
/// frames' 11-bit CAN id), or a payload that cannot be encoded in the
/// joint's wire version or does not fit one frame (the message names the
/// payload).
pub fn irpc_frames(
    motor: &str,
    command: &IrpcCommand,
    source: u16,
    msg_id: &mut u32,
) -> Result<Vec<IrpcFrame>, Refusal> {
    if source > 0x7FF {
        return Err(Refusal::NotRepresentable {
            motor: motor.to_owned(),
            field: "source",
            problem: format!(
                "source node {source:#05x} is above 0x7FF: it is the frames' 11-bit CAN id"
            ),
        });
    }
    let mut next = *msg_id;
    let mut frames = Vec::with_capacity(command.payloads.len());
    for payload in &command.payloads {
        let message = Message {
            header: Header {
                source_id: source,
                target_id: command.node,
                msg_id: next,
            },
            payload: *payload,
        };
        let mut buf = [0u8; MAX_FRAME_LEN];
        let len = message.encode_frame(command.wire, &mut buf).map_err(|e| {
            Refusal::NotRepresentable {
                motor: motor.to_owned(),
                field: "payload",
                problem: format!("{} in iRPC {}: {e}", payload.kind(), command.wire),
            }
        })?;
        frames.push(IrpcFrame {
            can_id: source,
            msg_id: next,
            data: buf.get(..len).unwrap_or(&buf).to_vec(),
        });
        next = next.wrapping_add(1).max(1);
    }
    *msg_id = next;
    Ok(frames)
}
