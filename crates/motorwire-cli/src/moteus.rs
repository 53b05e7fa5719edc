//! `motorwire moteus encode|decode`: mjbots moteus frames, built and read by
//! mjbots' own codec (`moteus-protocol`), on JSON lines that use the names
//! of mjbots' Python library.

use clap::{Args as ClapArgs, Subcommand};
use motorwire_moteus::{Call, Scaled, decode};
use serde_json::{Value, json};

use crate::lines::{filter, from_hex};

/// Encode and decode mjbots moteus frames.
#[derive(Debug, ClapArgs)]
pub(crate) struct Args {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Read JSON lines naming a `Controller.make_*` call of mjbots' Python
    /// library (`{"command":"position","id":1,"position":0.5,
    /// "velocity":null,"maximum_torque":1.0,"query":true}`: the call without
    /// `make_`, every keyword argument it takes by the library's names, with
    /// Python's types (`query` and `ignore_position_bounds` may be true or
    /// false, `query_override` an object or null for None), `null` for
    /// NaN, optional `source`, `can_prefix` and the controller's
    /// `query_resolution`, `position_resolution`, `current_resolution`,
    /// `zero_velocity_resolution` as objects of resolutions `"int8"`,
    /// `"int16"`, `"int32"`, `"f32"`, `"ignore"`); print each frame as
    /// `{"can_id":N,"data":"hex"}` (the data not padded).
    Encode,
    /// Read reply frames as `{"can_id":N,"data":"hex"}`; print the
    /// controller's id and every register the reply holds, by the library's
    /// register number and name, scaled as the library scales it
    /// (`{"id":1,"values":[{"register":1,"name":"POSITION","value":0.5}],
    /// "errors":[]}`; NaN is null, infinities "inf" and "-inf").
    Decode,
}

pub(crate) fn run(args: &Args) -> u8 {
    match args.command {
        Command::Encode => filter(|line| {
            let frame = Call::from_json(line)
                .and_then(|c| c.encode())
                .map_err(|e| e.to_string())?;
            Ok(
                json!({ "can_id": frame.can_id, "data": motorwire_moteus::hex(&frame.data) })
                    .to_string(),
            )
        }),
        Command::Decode => filter(decode_line),
    }
}

fn decode_line(line: &str) -> Result<String, String> {
    #[derive(serde::Deserialize)]
    #[serde(deny_unknown_fields)]
    struct Received {
        can_id: u32,
        data: String,
    }
    let r: Received = serde_json::from_str(line).map_err(|e| e.to_string())?;
    if r.can_id >= 1 << 29 {
        return Err(format!("can_id {:#x} is over 29 bits", r.can_id));
    }
    let data = from_hex(&r.data)?;
    let reply = decode(r.can_id, &data).map_err(|e| e.to_string())?;
    let values: Vec<Value> = reply
        .values
        .iter()
        .map(|v| json!({ "register": v.register, "name": v.name(), "value": scaled(v.value) }))
        .collect();
    let errors: Vec<Value> = reply
        .errors
        .iter()
        .map(|e| json!({ "register": e.register, "code": e.code }))
        .collect();
    Ok(json!({ "id": reply.source, "values": values, "errors": errors }).to_string())
}

fn scaled(v: Scaled) -> Value {
    match v {
        Scaled::Int(i) => json!(i),
        Scaled::Float(f) if f.is_nan() => Value::Null,
        Scaled::Float(f) if f == f64::INFINITY => json!("inf"),
        Scaled::Float(f) if f == f64::NEG_INFINITY => json!("-inf"),
        Scaled::Float(f) => json!(f),
    }
}
