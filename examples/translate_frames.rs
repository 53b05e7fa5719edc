//! A WIA command through a bus map into ready-to-send CAN-FD frames.
//!
//! ```sh
//! cargo run --example translate_frames
//! ```
//!
//! The bus map (`fixtures/maps/demo-arm.toml`) says which motor is which
//! joint on which node, in which wire version, with which limits.
//! `to_irpc` gates a MotorCommand against those limits (a refusal names the
//! limit and the value) and translates it to the joint's payloads, saying
//! what it lost or filled in; `irpc_frames` gives each payload its header
//! (from our node to the joint's), a msg_id (numbered on across commands,
//! as the iRPC client numbers them) and its zero-padded CAN-FD bytes. Send
//! `can_id` and `data` on any CAN-FD bus (`motorwire_can::Frame`), or give
//! the payloads to `motorwire_can::client::Client`, which numbers, retries and
//! matches the Acks itself.

use std::io::Write;

use motorwire_irpc::Payload;
use motorwire_translate::{
    BusMap, IrpcCommand, TranslationReport, irpc_frames, lifecycle, to_irpc,
};
use motorwire_wia::{MotorCommand, Validator};

/// This program's node id on the bus: the arm's, 0x0000.
const OUR_NODE: u16 = 0x0000;

const COMMANDS: [&str; 2] = [
    r#"{"motor_id":"elbow","timestamp":1704067200000,"control_mode":"position","setpoint":90,"velocity_limit":60}"#,
    // Outside the elbow's max_position (150 in the bus map): refused.
    r#"{"motor_id":"elbow","timestamp":1704067200000,"control_mode":"position","setpoint":170}"#,
];

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

fn print_report(out: &mut dyn Write, report: &TranslationReport) -> std::io::Result<()> {
    for loss in &report.losses {
        writeln!(out, "  lost or filled: {loss}")?;
    }
    Ok(())
}

fn run(out: &mut dyn Write) -> Result<(), Box<dyn std::error::Error>> {
    let map = BusMap::from_path(motorwire_examples::fixture("maps/demo-arm.toml"))?;
    let validator = Validator::new();
    // msg_id 0 is ArmReady's; requests start at 1.
    let mut msg_id = 1;

    // A joint moves only once configured and activated (the bridge does
    // this on start): the elbow's node and wire version from the map.
    let activate = IrpcCommand {
        payloads: vec![Payload::Configure, Payload::Activate],
        ..lifecycle(&map, "elbow", true)?
    };
    for frame in irpc_frames("elbow", &activate, OUR_NODE, &mut msg_id)? {
        writeln!(
            out,
            "lifecycle: can id 0x{:03x} msg_id {} data {}",
            frame.can_id,
            frame.msg_id,
            hex(&frame.data)
        )?;
    }

    for json in COMMANDS {
        let command: MotorCommand = validator.parse(json)?;
        match to_irpc(&map, &command) {
            Ok(translated) => {
                for frame in
                    irpc_frames(&command.motor_id, &translated.value, OUR_NODE, &mut msg_id)?
                {
                    writeln!(
                        out,
                        "{} -> {}: can id 0x{:03x} msg_id {} data {}",
                        command.motor_id,
                        command.setpoint,
                        frame.can_id,
                        frame.msg_id,
                        hex(&frame.data)
                    )?;
                }
                print_report(out, &translated.report)?;
            }
            Err(refusal) => writeln!(out, "refused ({}): {refusal}", refusal.rule())?,
        }
    }
    writeln!(out, "next msg_id: {msg_id}")?;
    Ok(())
}

fn main() -> std::process::ExitCode {
    match run(&mut std::io::stdout()) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("translate_frames: {e}");
            std::process::ExitCode::FAILURE
        }
    }
}

#[cfg(test)]
mod tests {
    /// The output, exactly.
    const EXPECTED: &str = r##"lifecycle: can id 0x000 msg_id 1 data 00120101
lifecycle: can id 0x000 msg_id 2 data 00120202
elbow -> 90: can id 0x000 msg_id 3 data 001203050000b44200007042000000000000fa430000c8430000fa440100000000000000000000000000000000000000
  lost or filled: max_acceleration: defaulted: 500 from the bus map
  lost or filled: max_deceleration: defaulted: 400 from the bus map
  lost or filled: max_jerk: defaulted: 2000 from the bus map
refused (outside_limit): elbow: setpoint 170 is outside max_position (bus map) 150
next msg_id: 4
"##;

    #[test]
    fn gates_translates_and_frames_the_commands() {
        let mut out = Vec::new();
        assert!(super::run(&mut out).is_ok());
        assert_eq!(String::from_utf8_lossy(&out), EXPECTED);
    }
}
