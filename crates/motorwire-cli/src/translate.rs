//! `motorwire translate`: WIA command lines in, one line out per input
//! with what the command becomes in one target dialect: iRPC CAN-FD frames,
//! compact-command frames, moteus frames, serial servo instruction packets
//! (Feetech, Dynamixel), or Orion direct-control JSON,
//! and the translation's loss report; or the refusal, with its rule.
//!
//! Every step is motorwire-translate's, as the bridge uses it: the gate,
//! the mapping (`to_irpc`, `multi_axis_to_irpc`, `to_compact`,
//! `multi_axis_to_compact`, `to_moteus`, `multi_axis_to_moteus`,
//! `to_orion_motor`, `to_orion`), the iRPC framing (`irpc_frames`) and
//! the bridge's moteus frames (`motorwire_bridge::moteus_frame`). Nothing is
//! sent anywhere.

use std::collections::HashMap;
use std::io::{self, Write};

use clap::ValueEnum;
use motorwire_irpc::WireVersion;
use motorwire_translate::{
    BusMap, Refusal, Report, Target, irpc_frames, multi_axis_to_compact, multi_axis_to_irpc,
    multi_axis_to_moteus, to_compact, to_irpc, to_moteus, to_orion, to_orion_motor,
};
use motorwire_wia::{Message, MotorCommand, MultiAxisCommand, Validator};
use serde::Serialize;
use serde_json::Value;
use serde_json::value::RawValue;

use crate::console::note;
use crate::input::{self, Live, Refused};
use crate::lines::to_hex;

#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// The bus map (TOML): which motor speaks which dialect, where it is,
    /// and its limits.
    #[arg(long, value_name = "FILE")]
    map: String,
    /// The target dialect. `irpc-V` encodes for wire version V whatever
    /// `wire` the map gives a joint.
    #[arg(long, value_enum, value_name = "TARGET")]
    to: To,
    /// The sender's iRPC node id: the header's source_id and the frames'
    /// CAN id (iRPC targets only).
    #[arg(long, value_parser = crate::sim::parse_node, default_value = "0x0000")]
    node: u16,
    /// The msg_id of the first iRPC frame; each frame takes the next one,
    /// across lines (iRPC targets only).
    #[arg(long, value_name = "ID", default_value_t = 1)]
    first_msg_id: u32,
    /// The joints' current positions, `motor=position,...` in each motor's
    /// unit (the map's `unit`, degrees by default), for synchronized
    /// multi-axis moves (iRPC targets only). A synchronized move of a joint
    /// not listed is refused `unknown_position`.
    #[arg(long, value_name = "MOTOR=POS,...")]
    positions: Option<String>,
    /// Take members a kind's schema does not name (WIA's schemas leave
    /// objects open). Without it each is refused `unknown-member`, naming
    /// the nearest known member, as the bridge and `motorwire validate`
    /// refuse it.
    #[arg(long)]
    allow_unknown_members: bool,
}

/// What `--to` names.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
enum To {
    /// iRPC wire version v1.
    #[value(name = "irpc-v1")]
    IrpcV1,
    /// iRPC wire version v2.0 (the document's).
    #[value(name = "irpc-v2.0")]
    IrpcV2_0,
    /// iRPC wire version v2.1.
    #[value(name = "irpc-v2.1")]
    IrpcV2_1,
    /// iRPC wire version v2.2.
    #[value(name = "irpc-v2.2")]
    IrpcV2_2,
    /// The 24-byte WIA compact command on CAN-FD.
    Compact,
    /// The Orion arm controller's direct-control JSON.
    Orion,
    /// mjbots moteus position-mode frames on CAN-FD, as the bridge sends
    /// them (with its query; mjbots' `moteus-protocol` builds them).
    Moteus,
    /// Feetech STS servo instruction packets on their serial bus, as the
    /// bridge writes them (a goal's sync write, the torque in it).
    Feetech,
    /// Dynamixel Protocol 2.0 instruction packets on their serial bus, as
    /// the bridge writes them (the goal, the torque on, the goal again).
    Dynamixel,
}

impl To {
    fn wire(self) -> Option<WireVersion> {
        match self {
            Self::IrpcV1 => Some(WireVersion::V1),
            Self::IrpcV2_0 => Some(WireVersion::V2_0),
            Self::IrpcV2_1 => Some(WireVersion::V2_1),
            Self::IrpcV2_2 => Some(WireVersion::V2_2),
            Self::Compact | Self::Orion | Self::Moteus | Self::Feetech | Self::Dynamixel => None,
        }
    }

    /// The dialect as the bus map spells it.
    fn dialect(self) -> &'static str {
        match self {
            Self::Compact => "compact",
            Self::Orion => "orion",
            Self::Moteus => "moteus",
            Self::Feetech => "feetech",
            Self::Dynamixel => "dynamixel",
            _ => "irpc",
        }
    }

    /// As `--to` spells it.
    fn name(self) -> String {
        self.to_possible_value()
            .map_or_else(String::new, |v| v.get_name().to_owned())
    }
}

/// `{"ok":true,"line":N,"frames":[...]|"orion":{...},"report":[...]}`.
#[derive(Serialize)]
struct Translation {
    ok: bool,
    line: usize,
    #[serde(skip_serializing_if = "Option::is_none")]
    frames: Option<Vec<FrameLine>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    orion: Option<Box<RawValue>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    packets: Option<Vec<PacketLine>>,
    /// Each loss as the bridge prints its `losses`: `field: kind: detail`.
    report: Vec<String>,
}

/// One CAN-FD frame.
#[derive(Serialize)]
struct FrameLine {
    /// The motor it is for.
    motor_id: String,
    /// The CAN id: a standard id as `0x` and three lowercase hex digits,
    /// an extended one (moteus) as `0x` and eight.
    can_id: String,
    /// The frame's data (padding included), lowercase hex.
    data: String,
}

impl FrameLine {
    fn new(motor_id: &str, can_id: u16, data: &[u8]) -> Self {
        Self {
            motor_id: motor_id.to_owned(),
            can_id: format!("{can_id:#05x}"),
            data: to_hex(data),
        }
    }

    fn extended(motor_id: &str, can_id: u32, data: &[u8]) -> Self {
        Self {
            motor_id: motor_id.to_owned(),
            can_id: format!("{can_id:#010x}"),
            data: to_hex(data),
        }
    }
}

/// One instruction packet for a serial servo's bus.
#[derive(Serialize)]
struct PacketLine {
    /// The motor it is for.
    motor_id: String,
    /// The serial port of its bus, as the map names it.
    port: String,
    /// The packet, lowercase hex.
    bytes: String,
}

/// `{"ok":false,"line":N,"error":{"rule":...,"message":...}}`.
#[derive(Serialize)]
struct RefusalLine {
    ok: bool,
    line: usize,
    error: ErrorLine,
}

#[derive(Serialize)]
struct ErrorLine {
    /// `invalid`, `unreadable`, `unsupported_kind`, `dialect_mismatch`, or
    /// the gate's refusal ([`Refusal::rule`]).
    rule: &'static str,
    message: String,
    /// The gate's values, as the bridge's results carry them: the
    /// member, its value, the limit, its name and where it came from.
    #[serde(flatten, skip_serializing_if = "Option::is_none")]
    broke: Option<Box<motorwire_bridge::Broke>>,
    /// The WIA validator's violations, for `invalid` (at most
    /// `motorwire_wia::MAX_VIOLATIONS`).
    #[serde(skip_serializing_if = "Option::is_none")]
    violations: Option<Value>,
    /// Violations found beyond those listed.
    #[serde(skip_serializing_if = "Option::is_none")]
    more_violations: Option<usize>,
}

impl ErrorLine {
    fn new(rule: &'static str, message: impl Into<String>) -> Self {
        Self {
            rule,
            message: message.into(),
            broke: None,
            violations: None,
            more_violations: None,
        }
    }
}

impl From<Refusal> for ErrorLine {
    fn from(r: Refusal) -> Self {
        Self {
            broke: motorwire_bridge::Broke::of(&r),
            ..Self::new(r.rule(), r.to_string())
        }
    }
}

/// What a translation produced, before its line number.
enum Produced {
    Frames(Vec<FrameLine>),
    Orion(String),
    Packets(Vec<PacketLine>),
}

struct Translator {
    map: BusMap,
    to: To,
    source: u16,
    msg_id: u32,
    positions: HashMap<String, f64>,
    validator: Validator,
}

impl Translator {
    fn translate(&mut self, text: &str) -> Result<(Produced, Report), ErrorLine> {
        let message = self.validator.parse_any(text).map_err(|e| {
            // "invalid motor-command" (or "invalid document" when the kind
            // could not be told), then the first violation.
            let summary = e.to_string();
            let head = summary.split(':').next().unwrap_or("invalid");
            let v = e.violations();
            let message = match v {
                [] => head.to_owned(),
                [one] if e.more() == 0 => format!("{head}: {one}"),
                [first, rest @ ..] => format!(
                    "{head}: {first}; and {} more",
                    rest.len().saturating_add(e.more())
                ),
            };
            ErrorLine {
                violations: serde_json::to_value(v).ok(),
                more_violations: (e.more() > 0).then_some(e.more()),
                ..ErrorLine::new("invalid", message)
            }
        })?;
        match message {
            Message::MotorCommand(cmd) => {
                self.same_dialect(&cmd.motor_id)?;
                self.motor_command(&cmd)
            }
            Message::MultiAxisCommand(cmd) => {
                for axis in &cmd.motors {
                    if self.map.motor(&axis.motor_id).is_none() {
                        // The translation refuses it, in axis order.
                        break;
                    }
                    self.same_dialect(&axis.motor_id)?;
                }
                self.multi_axis(&cmd)
            }
            other => Err(ErrorLine::new(
                "unsupported_kind",
                format!(
                    "a {} is valid WIA, but translate takes motor-command and multi-axis-command lines",
                    other.kind()
                ),
            )),
        }
    }

    /// Refuses a motor the map gives another dialect than `--to`'s.
    fn same_dialect(&self, motor: &str) -> Result<(), ErrorLine> {
        match self.map.motor(motor) {
            Some(m) if m.target.dialect() != self.to.dialect() => Err(ErrorLine::new(
                "dialect_mismatch",
                format!(
                    "{motor}: the bus map says it speaks {}, not {} (--to {})",
                    m.target.dialect(),
                    self.to.dialect(),
                    self.to.name()
                ),
            )),
            _ => Ok(()),
        }
    }

    /// The compact device's command CAN id.
    fn compact_node(&self, motor: &str) -> Result<u16, ErrorLine> {
        match self.map.motor(motor).map(|m| m.target) {
            Some(Target::Compact { node, .. }) => Ok(node),
            _ => Err(ErrorLine::new(
                "dialect_mismatch",
                format!("{motor}: not a compact device in the bus map"),
            )),
        }
    }

    fn compact_frame(
        &self,
        motor: &str,
        command: &motorwire_compact::CompactCommand,
    ) -> Result<FrameLine, ErrorLine> {
        let node = self.compact_node(motor)?;
        let bytes = command.encode().map_err(|e| {
            ErrorLine::from(Refusal::NotRepresentable {
                motor: motor.to_owned(),
                field: "compact command",
                problem: e.to_string(),
            })
        })?;
        Ok(FrameLine::new(motor, node, &bytes))
    }

    /// A moteus controller's frame for `command`, as the bridge sends it.
    fn moteus_frame(
        &self,
        motor: &str,
        command: &motorwire_translate::MoteusCommand,
    ) -> Result<FrameLine, ErrorLine> {
        let target = self.map.motor(motor).map(|m| m.target).ok_or_else(|| {
            ErrorLine::new("dialect_mismatch", format!("{motor}: not in the bus map"))
        })?;
        let (can_id, data) = motorwire_bridge::moteus_frame(&target, command).map_err(|e| {
            ErrorLine::from(Refusal::NotRepresentable {
                motor: motor.to_owned(),
                field: "moteus frame",
                problem: e.to_string(),
            })
        })?;
        Ok(FrameLine::extended(motor, can_id, &data))
    }

    /// A servo's packets for `command`, as the bridge writes them.
    fn servo_packets(
        &self,
        motor: &str,
        command: &motorwire_translate::ServoCommand,
    ) -> Result<Vec<PacketLine>, ErrorLine> {
        let Some(Target::Servo(target)) = self.map.motor(motor).map(|m| m.target) else {
            return Err(ErrorLine::new(
                "dialect_mismatch",
                format!("{motor}: not a serial servo in the bus map"),
            ));
        };
        let port = self
            .map
            .servo_ports()
            .get(usize::from(target.port))
            .map_or_else(String::new, |p| p.path.clone());
        Ok(motorwire_translate::servo_packets(motor, &target, command)?
            .iter()
            .map(|b| PacketLine {
                motor_id: motor.to_owned(),
                port: port.clone(),
                bytes: to_hex(b),
            })
            .collect())
    }

    fn motor_command(&mut self, cmd: &MotorCommand) -> Result<(Produced, Report), ErrorLine> {
        match self.to {
            To::Feetech | To::Dynamixel => {
                let t = motorwire_translate::to_servo(&self.map, cmd)?;
                let packets = self.servo_packets(&cmd.motor_id, &t.value)?;
                Ok((Produced::Packets(packets), t.report))
            }
            To::Moteus => {
                let t = to_moteus(&self.map, cmd)?;
                let frame = self.moteus_frame(&cmd.motor_id, &t.value)?;
                Ok((Produced::Frames(vec![frame]), t.report))
            }
            To::Compact => {
                let t = to_compact(&self.map, cmd)?;
                let frame = self.compact_frame(&cmd.motor_id, &t.value)?;
                Ok((Produced::Frames(vec![frame]), t.report))
            }
            To::Orion => {
                let t = to_orion_motor(&self.map, cmd)?;
                Ok((Produced::Orion(t.value.to_json()), t.report))
            }
            _ => {
                let t = to_irpc(&self.map, cmd)?;
                let frames = irpc_frames(&cmd.motor_id, &t.value, self.source, &mut self.msg_id)?;
                let lines = frames
                    .iter()
                    .map(|f| FrameLine::new(&cmd.motor_id, f.can_id, &f.data))
                    .collect();
                Ok((Produced::Frames(lines), t.report))
            }
        }
    }

    fn multi_axis(&mut self, cmd: &MultiAxisCommand) -> Result<(Produced, Report), ErrorLine> {
        match self.to {
            To::Feetech | To::Dynamixel => {
                let t = motorwire_translate::multi_axis_to_servo(&self.map, cmd)?;
                let mut packets = Vec::new();
                for (axis, c) in cmd.motors.iter().zip(&t.value) {
                    packets.extend(self.servo_packets(&axis.motor_id, c)?);
                }
                Ok((Produced::Packets(packets), t.report))
            }
            To::Moteus => {
                let t = multi_axis_to_moteus(&self.map, cmd)?;
                let frames = cmd
                    .motors
                    .iter()
                    .zip(&t.value)
                    .map(|(axis, c)| self.moteus_frame(&axis.motor_id, c))
                    .collect::<Result<_, _>>()?;
                Ok((Produced::Frames(frames), t.report))
            }
            To::Compact => {
                let t = multi_axis_to_compact(&self.map, cmd)?;
                let frames = cmd
                    .motors
                    .iter()
                    .zip(&t.value)
                    .map(|(axis, c)| self.compact_frame(&axis.motor_id, c))
                    .collect::<Result<_, _>>()?;
                Ok((Produced::Frames(frames), t.report))
            }
            To::Orion => {
                let t = to_orion(&self.map, cmd)?;
                Ok((Produced::Orion(t.value.to_json()), t.report))
            }
            _ => {
                let positions = &self.positions;
                let t = multi_axis_to_irpc(&self.map, cmd, &|m| positions.get(m).copied())?;
                // Numbered from a copy: a refused line uses no msg_id.
                let mut msg_id = self.msg_id;
                let mut lines = Vec::new();
                for (axis, command) in cmd.motors.iter().zip(&t.value.commands) {
                    for f in irpc_frames(&axis.motor_id, command, self.source, &mut msg_id)? {
                        lines.push(FrameLine::new(&axis.motor_id, f.can_id, &f.data));
                    }
                }
                self.msg_id = msg_id;
                Ok((Produced::Frames(lines), t.report))
            }
        }
    }
}

/// `motor=position,...`, each motor in the map and each position finite.
fn parse_positions(text: &str, map: &BusMap) -> Result<HashMap<String, f64>, String> {
    let mut out = HashMap::new();
    for item in text.split(',').map(str::trim).filter(|s| !s.is_empty()) {
        let (motor, value) = item
            .split_once('=')
            .ok_or_else(|| format!("{item:?} is not motor=position"))?;
        let (motor, value) = (motor.trim(), value.trim());
        if map.motor(motor).is_none() {
            return Err(format!("{motor:?} is not in the bus map"));
        }
        let position: f64 = value
            .parse()
            .ok()
            .filter(|v: &f64| v.is_finite())
            .ok_or_else(|| format!("{motor}: {value:?} is not a finite number"))?;
        if out.insert(motor.to_owned(), position).is_some() {
            return Err(format!("{motor} is given twice"));
        }
    }
    Ok(out)
}

/// The line for one input line's outcome.
fn line_for(line: usize, outcome: Result<(Produced, Report), ErrorLine>) -> (String, bool) {
    let (json, ok) = match outcome {
        Ok((produced, report)) => {
            let report = report.losses.iter().map(ToString::to_string).collect();
            let (frames, orion, packets) = match produced {
                Produced::Frames(f) => (Some(f), None, None),
                Produced::Packets(p) => (None, None, Some(p)),
                Produced::Orion(json) => match RawValue::from_string(json) {
                    Ok(raw) => (None, Some(raw), None),
                    Err(e) => {
                        return line_for(
                            line,
                            Err(ErrorLine::new(
                                "internal_error",
                                format!("the Orion JSON is not JSON: {e}"),
                            )),
                        );
                    }
                },
            };
            let t = Translation {
                ok: true,
                line,
                frames,
                orion,
                packets,
                report,
            };
            (serde_json::to_string(&t), true)
        }
        Err(error) => {
            let r = RefusalLine {
                ok: false,
                line,
                error,
            };
            (serde_json::to_string(&r), false)
        }
    };
    // Serializing these cannot fail: strings, integers and JSON values only.
    let json = json.unwrap_or_else(|e| {
        format!(
            r#"{{"ok":false,"line":{line},"error":{{"rule":"internal_error","message":"{e}"}}}}"#
        )
    });
    (json, ok)
}

pub(crate) fn run(args: &Args) -> u8 {
    let map = match crate::bridge::load_map(&args.map) {
        Ok(map) => map,
        Err(e) => {
            note!("motorwire translate: {e}");
            return 2;
        }
    };
    let positions = match args.positions.as_deref().map(|p| parse_positions(p, &map)) {
        None => HashMap::new(),
        Some(Ok(p)) => p,
        Some(Err(e)) => {
            note!("motorwire translate: --positions: {e}");
            return 2;
        }
    };
    let mut translator = Translator {
        map: match args.to.wire() {
            Some(wire) => map.with_wire(wire),
            None => map,
        },
        to: args.to,
        source: args.node,
        msg_id: args.first_msg_id,
        positions,
        validator: Validator::new().deny_unknown_members(!args.allow_unknown_members),
    };
    let out = io::BufWriter::new(io::stdout().lock());
    let mut reader = Live::new(Box::new(io::stdin().lock()), out);
    let mut line_no = 0;
    let mut refused = false;
    loop {
        let doc = match input::next_line(
            &mut reader,
            motorwire_bridge::DEFAULT_MAX_LINE,
            &mut line_no,
        ) {
            Ok(Some(doc)) => doc,
            Ok(None) => break,
            Err(e) => {
                if !reader.out_failed() {
                    let _ = reader.out().flush();
                    note!("motorwire translate: reading standard input: {e}");
                }
                return 2;
            }
        };
        let n = doc.line.unwrap_or(line_no);
        let outcome = match doc.text {
            Ok(text) => translator.translate(text.trim()),
            Err(Refused::TooLarge { limit }) => Err(ErrorLine::new(
                "unreadable",
                format!("the line is over {limit} bytes"),
            )),
            Err(Refused::NotUtf8) => Err(ErrorLine::new("unreadable", "the line is not UTF-8")),
        };
        let (json, ok) = line_for(n, outcome);
        refused |= !ok;
        if writeln!(reader.out(), "{json}").is_err() {
            return 2;
        }
    }
    if reader.out().flush().is_err() {
        return 2;
    }
    u8::from(refused)
}
