#![no_main]

use libfuzzer_sys::fuzz_target;
use motorwire_wia::{Message, MessageKind, MotorCommand, Validator};

/// The same command, to the bit (`-0.0` is not `0.0` here).
fn same(a: &MotorCommand, b: &MotorCommand) -> bool {
    let bits = |v: Option<f64>| v.map(f64::to_bits);
    a.motor_id == b.motor_id
        && a.timestamp.to_bits() == b.timestamp.to_bits()
        && a.control_mode == b.control_mode
        && a.setpoint.to_bits() == b.setpoint.to_bits()
        && bits(a.velocity_limit) == bits(b.velocity_limit)
        && bits(a.acceleration_limit) == bits(b.acceleration_limit)
        && bits(a.torque_limit) == bits(b.torque_limit)
        && a.priority == b.priority
        && a.pid_gains == b.pid_gains
        && a.impedance_params == b.impedance_params
        && a.filter_config == b.filter_config
        && a.safety_limits == b.safety_limits
        && a.metadata == b.metadata
        && a.extra == b.extra
}

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    // Lenient (WIA's open schemas) and strict (the default): what the
    // strict one takes, the lenient one takes, and the schema too.
    let v = Validator::lenient().max_depth(16);
    let strict = Validator::new().max_depth(16);
    let auto = v.validate_auto(text);
    for kind in MessageKind::ALL {
        let full = v.validate(kind, text);
        if full.is_valid() {
            assert!(v.validate_schema_only(kind, text).is_valid());
        }
        if strict.validate(kind, text).is_valid() {
            assert!(full.is_valid(), "{text:?}: strict took it, lenient did not");
        }
    }
    let _ = auto;
    // A command the one-parse path reads (a flat one read byte by byte,
    // any other by serde) is the command the full validator reads.
    if let Some(plain) = v.parse_plain_command(text) {
        match v.parse_any(text) {
            Ok(Message::MotorCommand(full)) => {
                assert!(same(&plain, &full), "{text:?}: {plain:?} against {full:?}");
            }
            other => panic!("{text:?}: read plainly as {plain:?}, fully as {other:?}"),
        }
    }
});
