//! `motorwire sim`: simulated devices.

use std::io;
use std::time::Duration;

use clap::{Subcommand, ValueEnum};
use motorwire_orion::FeedbackKeys;
use motorwire_sim::orion::OrionConfig;

use crate::console::note;

#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    #[command(subcommand)]
    device: Device,
}

#[derive(Debug, Subcommand)]
enum Device {
    /// The Orion arm controller on stdin/stdout: the boot beacon {"ID":32}
    /// until the first command, then one feedback line per command line.
    /// A line that is not an Orion command changes nothing, prints nothing
    /// on stdout and one message on stderr; every clamp is reported on
    /// stderr. Exits 0 at the end of input, 2 when stdout closes.
    Orion(OrionArgs),
    /// A simulated iRPC joint on a CAN bus, in real time, until interrupted:
    /// the document's lifecycle, Ack for SetTargetV2, planned motion,
    /// Encoder and JointStatus feedback, a watchdog. Each request it acts
    /// on is logged on stderr.
    Joint(JointArgs),
    /// A simulated compact device (WIRE-FACTS §2.1) on a CAN-FD bus, in
    /// real time, until interrupted: 24-byte compact commands on its node
    /// (position, velocity, torque, disabled), the WIA Phase 3 feedback
    /// record on its feedback node at its rate and after every REQUIRE_ACK,
    /// refusals for setpoints outside its limits, a duplicate memory of one
    /// command, an emergency stop that holds until a command without the
    /// flag. Each command it acts on is logged on stderr.
    Compact(CompactArgs),
    /// A simulated mjbots moteus controller, in real time, until
    /// interrupted (or, with `--bus sim`, until the end of input): it
    /// answers the register protocol (queries at the resolutions asked;
    /// position mode within its velocity and acceleration limits, velocity
    /// with position NaN, torque with kp and kd scale 0; stop; brake; the
    /// watchdog into mode 11; a start outside its bounds as fault 39).
    /// With `--bus socketcan:IFACE` it is on a CAN-FD interface; with
    /// `--bus sim` it reads frames as `{"can_id":N,"data":"hex"}` lines on
    /// stdin (what `motorwire moteus encode` prints) and prints its
    /// replies the same way (what `motorwire moteus decode` reads). Each
    /// command it acts on is logged on stderr.
    Moteus(MoteusArgs),
    /// Simulated serial bus servos (Feetech STS/SMS and SCS, Dynamixel X)
    /// on a pseudo-terminal linked at `--pty`, in real time, until
    /// interrupted: each answers every instruction of its protocol with its
    /// model's control table (torque enable, goal position reached at the
    /// goal velocity and acceleration, present position, velocity, load,
    /// voltage, temperature, return delay, status return level), with
    /// seeded faults if asked. LeRobot's `FeetechMotorsBus` and
    /// `DynamixelMotorsBus` and the vendors' SDKs open `--pty` as a
    /// serial port.
    Servos(crate::sim_servos::ServosArgs),
}

#[derive(Debug, clap::Args)]
struct MoteusArgs {
    /// `socketcan:IFACE` (a Linux CAN-FD interface, e.g. vcan0), or `sim`
    /// (frames as JSON lines on stdin and stdout).
    #[arg(long, value_name = "BUS")]
    bus: String,
    /// Its id, 1..=127.
    #[arg(long, value_parser = clap::value_parser!(u8).range(1..=127))]
    id: u8,
    /// The CAN prefix it answers on (13 bits).
    #[arg(long, default_value_t = 0, value_parser = clap::value_parser!(u16).range(0..=0x1FFF))]
    prefix: u16,
    /// Lowest position (revolutions; servopos.position_min).
    #[arg(long, default_value_t = -0.5, allow_negative_numbers = true)]
    min_position: f64,
    /// Highest position (revolutions; servopos.position_max).
    #[arg(long, default_value_t = 0.5, allow_negative_numbers = true)]
    max_position: f64,
    /// The velocity limit of a move that sends none (rev/s).
    #[arg(long, default_value_t = 2.0)]
    velocity_limit: f64,
    /// The acceleration limit of a move that sends none (rev/s²).
    #[arg(long, default_value_t = 10.0)]
    accel_limit: f64,
    /// The watchdog of a command that sends none (s; `nan`: none).
    #[arg(long, default_value_t = 0.1)]
    timeout: f64,
    /// The largest torque (Nm).
    #[arg(long, default_value_t = 5.0)]
    max_torque: f64,
    /// Where it starts (revolutions, at rest, stopped).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    initial_position: f64,
}

#[derive(Debug, clap::Args)]
struct CompactArgs {
    /// The bus: `socketcan:IFACE` (a Linux CAN-FD interface, e.g. vcan0).
    #[arg(long, value_name = "BUS")]
    bus: String,
    /// The node id its commands come on (hex with 0x, or decimal), at most
    /// 0x7FF.
    #[arg(long, value_parser = parse_node)]
    node: u16,
    /// The motor id; commands must carry its CRC-32 hash.
    #[arg(long, value_parser = parse_motor_name)]
    name: String,
    /// The node id it sends feedback on [default: node | 0x400].
    #[arg(long, value_parser = parse_node)]
    feedback_node: Option<u16>,
    /// Periodic feedback rate in Hz, at most 1000 (0: only after commands
    /// with REQUIRE_ACK).
    #[arg(long, value_name = "HZ", default_value_t = 50, value_parser = clap::value_parser!(u32).range(0..=1000))]
    rate_hz: u32,
    /// Lowest position (the commands' unit: degrees or radians).
    #[arg(long, default_value_t = -180.0, allow_negative_numbers = true)]
    min_position: f32,
    /// Highest position.
    #[arg(long, default_value_t = 180.0, allow_negative_numbers = true)]
    max_position: f32,
    /// Fastest speed (units/s).
    #[arg(long, default_value_t = 360.0)]
    max_velocity: f32,
    /// Largest acceleration and deceleration (units/s²).
    #[arg(long, default_value_t = 5000.0)]
    max_acceleration: f32,
    /// Largest torque (Nm).
    #[arg(long, default_value_t = 10.0)]
    max_torque: f32,
    /// Brake at this deceleration (units/s²) on an emergency stop
    /// [default: stop at once].
    #[arg(long, value_name = "UNITS_PER_S2")]
    emergency_deceleration: Option<f32>,
    /// Where it starts (at rest, disabled).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    initial_position: f32,
}

/// A motor id as the bus map and WIA spell it (at most 64 bytes of
/// `[a-zA-Z0-9_-]`).
fn parse_motor_name(s: &str) -> Result<String, String> {
    motorwire_core::MotorId::validate(s).map_err(|e| format!("{s:?} is not a motor id: {e}"))?;
    Ok(s.to_owned())
}

#[derive(Debug, clap::Args)]
struct JointArgs {
    /// The bus: `socketcan:IFACE` (a Linux CAN-FD interface, e.g. vcan0).
    #[arg(long, value_name = "BUS")]
    bus: String,
    /// The joint's node id (hex with 0x, or decimal), at most 0x7FF.
    #[arg(long, value_parser = parse_node)]
    node: u16,
    /// The iRPC wire version: v1, v2.0, v2.1 or v2.2.
    #[arg(long, value_parser = crate::irpc::parse_wire, default_value = "v2.0")]
    wire: motorwire_irpc::WireVersion,
    /// Lowest position (degrees).
    #[arg(long, default_value_t = -180.0, allow_negative_numbers = true)]
    min_angle: f32,
    /// Highest position (degrees).
    #[arg(long, default_value_t = 180.0, allow_negative_numbers = true)]
    max_angle: f32,
    /// Fastest speed (deg/s).
    #[arg(long, default_value_t = 360.0)]
    max_velocity: f32,
    /// Largest acceleration (deg/s²).
    #[arg(long, default_value_t = 5000.0)]
    max_acceleration: f32,
    /// Brake when nothing is heard for this many ms while moving (0: never).
    #[arg(long, value_name = "MS", default_value_t = 200)]
    watchdog: u64,
    /// Encoder feedback period in ms (0: none).
    #[arg(long, value_name = "MS", default_value_t = 10)]
    encoder_period: u64,
    /// JointStatus period in ms (0: only on changes).
    #[arg(long, value_name = "MS", default_value_t = 100)]
    status_period: u64,
    /// A fault that happens as the joint starts (repeatable, in order; for
    /// testing what a host does about faults): the joint starts in Error
    /// with each one in its fault history (v2.2 RequestFaultHistory) and
    /// its PowerMetrics counters, and a v2.2 joint reports an
    /// EmergencyStop for each.
    #[arg(long = "fault", value_enum, value_name = "KIND")]
    faults: Vec<FaultKind>,
}

/// A fault `motorwire sim joint --fault` makes happen.
#[derive(Debug, Clone, Copy, ValueEnum)]
enum FaultKind {
    /// The motor overheated (EmergencyReason 4).
    Overtemperature,
    /// The motor driver failed (EmergencyReason 5).
    DriverFault,
}

/// `0x10`, `0X10` or `16`.
pub(crate) fn parse_node(s: &str) -> Result<u16, String> {
    let n = match s.strip_prefix("0x").or_else(|| s.strip_prefix("0X")) {
        Some(hex) => u16::from_str_radix(hex, 16),
        None => s.parse(),
    }
    .map_err(|_| format!("{s:?} is not a node id (0x10 or 16)"))?;
    if n > 0x7FF {
        return Err(format!(
            "node id {n:#x} is above 0x7FF (it is the frames' 11-bit CAN id)"
        ));
    }
    Ok(n)
}

#[derive(Debug, clap::Args)]
struct OrionArgs {
    /// Direct-control feedback keys: `table` (TRMF ..., the document's
    /// table) or `example` (TRM ..., its example output).
    #[arg(long, value_enum, default_value_t = Keys::Table)]
    feedback_keys: Keys,
    /// Milliseconds between boot beacons until the first command; 0 sends
    /// the beacon exactly once.
    #[arg(long, value_name = "MS", default_value_t = 1000)]
    beacon_interval: u64,
}

#[derive(Debug, Clone, Copy, ValueEnum)]
enum Keys {
    Table,
    Example,
}

pub(crate) fn run(args: &Args) -> u8 {
    match &args.device {
        Device::Orion(a) => orion(a),
        Device::Joint(a) => joint(a),
        Device::Compact(a) => compact(a),
        Device::Moteus(a) => moteus(a),
        Device::Servos(a) => crate::sim_servos::servos(a),
    }
}

fn moteus(args: &MoteusArgs) -> u8 {
    use motorwire_sim::moteus::{MoteusActed, MoteusConfig, SimMoteus};
    let config = MoteusConfig {
        prefix: args.prefix,
        position_min: args.min_position,
        position_max: args.max_position,
        default_velocity_limit: args.velocity_limit,
        default_accel_limit: args.accel_limit,
        default_timeout: args.timeout,
        max_torque: args.max_torque,
        initial_position: args.initial_position,
        ..MoteusConfig::new(args.id)
    };
    let mut device = match SimMoteus::new(config) {
        Ok(d) => d,
        Err(e) => {
            note!("motorwire: {e}");
            return 2;
        }
    };
    note!(
        "motorwire sim moteus: id {} prefix {:#x} on {}, bounds [{}, {}] rev",
        args.id,
        args.prefix,
        args.bus,
        args.min_position,
        args.max_position
    );
    let log = |e: &MoteusActed| {
        if let Some(m) = e.commanded {
            note!(
                "t={:.3}s mode {m} commanded -> mode {}{}",
                e.at.as_secs_f64(),
                e.mode,
                if e.replied { ", replied" } else { "" }
            );
        }
    };
    if args.bus == "sim" {
        return moteus_on_lines(&mut device, log);
    }
    let mut bus = match crate::bus::open(&args.bus) {
        Ok(b) => b,
        Err(e) => {
            note!("motorwire: {e}");
            return 2;
        }
    };
    // Runs until the process is interrupted (SIGINT's default action).
    let stop = std::sync::atomic::AtomicBool::new(false);
    match device.run(&mut bus, &stop, log) {
        Ok(()) => 0,
        Err(e) => {
            note!("motorwire: {e}");
            1
        }
    }
}

/// `--bus sim`: frames as `{"can_id":N,"data":"hex"}` lines in, replies out,
/// on the real clock from the start.
fn moteus_on_lines(
    device: &mut motorwire_sim::moteus::SimMoteus,
    log: impl Fn(&motorwire_sim::moteus::MoteusActed),
) -> u8 {
    use motorwire_can::{CanId, Frame};
    let start = std::time::Instant::now();
    crate::lines::filter(|line| {
        #[derive(serde::Deserialize)]
        #[serde(deny_unknown_fields)]
        struct Sent {
            can_id: u32,
            data: String,
        }
        let sent: Sent = serde_json::from_str(line).map_err(|e| e.to_string())?;
        let data = crate::lines::from_hex(&sent.data)?;
        let id = CanId::extended(sent.can_id).map_err(|e| e.to_string())?;
        let padded = motorwire_moteus::padded(&data);
        let frame = Frame::fd(id, &padded).map_err(|e| e.to_string())?;
        let now = start.elapsed();
        device.handle_timeout(now);
        if let Some(acted) = device.handle_frame(now, &frame) {
            log(&acted);
        }
        let mut replies = Vec::new();
        while let Some(f) = device.poll_transmit() {
            replies.push(
                serde_json::json!({ "can_id": f.id().raw(), "data": crate::lines::to_hex(f.data()) })
                    .to_string(),
            );
        }
        if replies.is_empty() {
            // One output line per input line: a frame it does not answer.
            return Ok(serde_json::json!({ "can_id": null, "data": null }).to_string());
        }
        Ok(replies.join("\n"))
    })
}

fn orion(args: &OrionArgs) -> u8 {
    let keys = match args.feedback_keys {
        Keys::Table => FeedbackKeys::Table,
        Keys::Example => FeedbackKeys::Example,
    };
    let config = OrionConfig {
        keys,
        beacon_interval: (args.beacon_interval > 0)
            .then(|| Duration::from_millis(args.beacon_interval)),
    };
    let stdout = io::stdout();
    match motorwire_sim::orion::serve(io::stdin(), stdout.lock(), config, |n| {
        note!("motorwire sim orion: {n}");
    }) {
        Ok(()) => 0,
        // stdin failed, or stdout closed: nobody hears the arm any more.
        Err(e) => {
            note!("motorwire sim orion: {e}");
            2
        }
    }
}

fn joint(args: &JointArgs) -> u8 {
    use motorwire_sim::{JointConfig, JointLimits, SimJoint};
    let config = JointConfig {
        wire: args.wire,
        limits: JointLimits {
            min_angle: args.min_angle,
            max_angle: args.max_angle,
            max_velocity: args.max_velocity,
            max_acceleration: args.max_acceleration,
            ..JointLimits::default()
        },
        watchdog: Duration::from_millis(args.watchdog),
        encoder_period: Duration::from_millis(args.encoder_period),
        status_period: Duration::from_millis(args.status_period),
        ..JointConfig::new(args.node)
    };
    let mut joint = match SimJoint::new(config) {
        Ok(j) => j,
        Err(e) => {
            note!("motorwire: {e}");
            return 2;
        }
    };
    for kind in &args.faults {
        joint.fault(
            Duration::ZERO,
            match kind {
                FaultKind::Overtemperature => motorwire_sim::JointFault::Overtemperature,
                FaultKind::DriverFault => motorwire_sim::JointFault::DriverFault,
            },
        );
    }
    let mut bus = match crate::bus::open(&args.bus) {
        Ok(b) => b,
        Err(e) => {
            note!("motorwire: {e}");
            return 2;
        }
    };
    note!(
        "motorwire sim joint: node {:#05x} on {} ({}), limits [{}, {}] deg",
        args.node,
        args.bus,
        args.wire,
        args.min_angle,
        args.max_angle
    );
    // Runs until the process is interrupted (SIGINT's default action).
    let stop = std::sync::atomic::AtomicBool::new(false);
    let log = |e: &motorwire_sim::Execution| {
        note!(
            "t={:.3}s from {:#05x} msg_id {}: {:?} -> {:?}",
            e.at.as_secs_f64(),
            e.source,
            e.msg_id,
            e.payload,
            e.answer
        );
    };
    match joint.run(&mut bus, &stop, log) {
        Ok(()) => 0,
        Err(e) => {
            note!("motorwire: {e}");
            1
        }
    }
}

fn compact(args: &CompactArgs) -> u8 {
    use motorwire_sim::{
        CompactDeviceConfig, CompactDeviceLimits, CompactExecution, CompactOutcome,
        SimCompactDevice,
    };
    let base = CompactDeviceConfig::new(args.node, &args.name);
    let config = CompactDeviceConfig {
        feedback_node: args.feedback_node.unwrap_or(base.feedback_node),
        limits: CompactDeviceLimits {
            min_position: args.min_position,
            max_position: args.max_position,
            max_velocity: args.max_velocity,
            max_acceleration: args.max_acceleration,
            max_torque: args.max_torque,
        },
        feedback_period: if args.rate_hz == 0 {
            Duration::ZERO
        } else {
            Duration::from_micros(1_000_000 / u64::from(args.rate_hz))
        },
        emergency_deceleration: args.emergency_deceleration,
        initial_position: args.initial_position,
        ..base
    };
    let mut device = match SimCompactDevice::new(config) {
        Ok(d) => d,
        Err(e) => {
            note!("motorwire: {e}");
            return 2;
        }
    };
    let mut bus = match crate::bus::open(&args.bus) {
        Ok(b) => b,
        Err(e) => {
            note!("motorwire: {e}");
            return 2;
        }
    };
    note!(
        "motorwire sim compact: {} (hash {}) on node {:#05x}, feedback on {:#05x} at {} Hz, on {}, limits [{}, {}]",
        args.name,
        config.motor,
        config.node,
        config.feedback_node,
        args.rate_hz,
        args.bus,
        args.min_position,
        args.max_position
    );
    // Runs until the process is interrupted (SIGINT's default action).
    let stop = std::sync::atomic::AtomicBool::new(false);
    let log = |e: &CompactExecution| {
        let c = &e.command;
        let flags: Vec<&str> = c.flags.names().collect();
        let outcome = match e.outcome {
            CompactOutcome::Executed => "executed".to_owned(),
            CompactOutcome::Refused(r) => format!("refused: {r}"),
        };
        note!(
            "t={:.3}s {} {} flags [{}] timestamp_ms {}: {outcome}",
            e.at.as_secs_f64(),
            c.control_mode.name(),
            c.setpoint,
            flags.join(" "),
            c.timestamp_ms,
        );
    };
    match device.run(&mut bus, &stop, log) {
        Ok(()) => 0,
        Err(e) => {
            note!("motorwire: {e}");
            1
        }
    }
}
