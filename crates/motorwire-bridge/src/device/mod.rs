//! The device layer: one driver per dialect under the engine.
//!
//! A driver owns what is particular to its dialect: its encoding (built by
//! pure functions first, queued second, so each is tested with byte
//! vectors alone, as moteus's `make_*`/`set_*` split does), its requests in
//! flight with their acknowledgements and retries, and its feedback
//! decoding into WIA `MotorFeedback`. The engine keeps what is common to
//! every motor: admission, jobs (one request in flight per device,
//! supersede, busy), the gate at send time, the stop and its latch, the
//! deadman, arrival, drain and exit. A driver never decides admission,
//! limits or stops.
//!
//! A driver is a state machine with no access to the engine (quinn's
//! `Connection`, smoltcp's sockets): the engine calls it with the time and
//! what came in, and takes back what it has to send and what happened, in
//! one form for every dialect ([`Happened`]: a device heard, its reading,
//! its request ended, its lifecycle, its own stop, an answer a request line
//! waits for, a bad frame or line, a link lost, devices that may go); its
//! tests drive it with lines or frames alone.
//!
//! What the engine asks of a device is asked here, once, with one match
//! per question over the closed set of dialects (smoltcp's `enum Socket`):
//! - [`Device`]: which dialect a motor of the bus map is ([`Device::of`]),
//!   what it supports ([`Device::supports`]), the link it is reached over
//!   ([`Device::link`]), what a stop, the deadman, the release and an
//!   arm-wide command send it ([`Device::lifecycle_orders`],
//!   [`Device::hold_still`], [`Device::arm_order`]), and a command
//!   translated for it ([`Device::single_order`]);
//! - [`Order`]: one request for one device, and what it means to the
//!   engine: whether a newer move may replace it, whether it holds a
//!   setpoint the deadman watches, where and how fast it moves the device
//!   ([`Order::reach`], for the limits in force), what it did once
//!   acknowledged ([`Order::effect`]), and whether it goes out in one
//!   message with other devices' orders of its line ([`Order::joins`]);
//! - [`Drivers`]: the drivers behind one set of calls: send (alone or
//!   together), forget, take back, whether a link is free, frames and
//!   lines in, frames and lines out, timeouts, deadlines, and
//!   [`Drivers::poll`] for what happened.
//!
//! The engine (`engine/`, one `impl Bridge` a concern) asks no dialect question:
//! it reads the bus map into devices through [`Device::of`], sends what
//! its jobs hold through [`Drivers`], and acts on [`Happened`] the same
//! way for every device. The dialects' own vocabularies stay in their
//! drivers: iRPC's lifecycle payloads are the lifecycle the engine drives
//! (Configure, Activate, Deactivate, Reset), which each device translates
//! ([`Device::lifecycle_orders`]); request lines (telemetry, calibration)
//! exist for the devices that say [`Capability::Requests`], and their
//! payloads and answers are the iRPC driver's ([`irpc::request`],
//! [`Answer`]).
//!
//! The drivers: [`irpc`] (iRPC joints, through `motorwire_can`'s sans-IO
//! client), [`compact`] (WIA's 24-byte compact command), [`moteus`] (mjbots
//! moteus controllers: frames from `moteus-protocol`, polls, held moves
//! and the controller's own watchdog, faults by name) and [`orion`] (the
//! Orion arm controller: its link with the beacon, the loss and the stop
//! written first when it comes back, its one line in flight with resends,
//! its polls and its feedback decoding). The compact and moteus drivers
//! share their requests in flight (`frames::FrameRequests`).
//!
//! Adding a dialect (the recipe the moteus driver followed):
//! 1. a driver file here: its encoding as pure functions (tested with
//!    byte vectors), its requests in flight with their answers, resends and
//!    giving up, its feedback decoded into WIA `MotorFeedback`, all told
//!    to the engine as [`Happened`];
//! 2. a variant of [`Device`] and of [`Order`], each match in this file
//!    answered for it (the compiler lists them), and a field of
//!    [`Drivers`] (its frames routed in [`Drivers::handle_frame`], its
//!    deadline in [`Drivers::deadline`]);
//! 3. its bus map entry (`motorwire_translate::Target`) and its translation
//!    (`Device::single_order`);
//! 4. its simulated device (`motorwire_sim`, attached by
//!    `crate::sim::SimulatedArm`, the `sim` feature) and its fixtures.
//!
//! The engine is not touched. The every-dialect property test in
//! `tests/invariants.rs` then holds the new dialect to every invariant the
//! others keep.

use std::collections::{BTreeSet, HashMap, HashSet, VecDeque};
use std::time::Duration;

use motorwire_can::Frame;
use motorwire_can::client::ClientConfig;
use motorwire_compact::{CompactCommand, ControlMode as CompactMode, Flags, MotorHash};
use motorwire_irpc::{LifecycleState, Payload, PayloadKind, SetTargetPayloadV2, WireVersion};
use motorwire_orion::{ArmCommand, Motor, Quantity};
use motorwire_translate::{
    AngleUnit, BusMap, MoteusCommand, Refusal, Report, Target, to_compact, to_moteus,
    to_orion_motor,
};
use motorwire_wia::{MotorCommand, MotorFeedback};
use serde_json::Value;

use crate::output::Event;

/// What a driver reads of the devices the engine keeps, in the engine's
/// order: read only (the engine's registry implements it; a driver never
/// sees, nor writes, the engine's own state of a device).
pub(crate) trait Registry {
    /// How many devices there are.
    fn count(&self) -> usize;
    /// Device `k` as a driver sees it.
    fn view(&self, k: usize) -> Option<DeviceView<'_>>;
}

impl dyn Registry + '_ {
    /// Device `k`, if there is one.
    pub(crate) fn get(&self, k: usize) -> Option<DeviceView<'_>> {
        self.view(k)
    }

    /// Every device, in order.
    pub(crate) fn iter(&self) -> impl Iterator<Item = DeviceView<'_>> + '_ {
        (0..self.count()).filter_map(|k| self.view(k))
    }
}

/// One device as its driver sees it: who it is, where, in what dialect and
/// unit, whether it is heard, and what it last reported.
#[derive(Debug, Clone, Copy)]
pub(crate) struct DeviceView<'a> {
    /// Its place in the engine's order.
    pub(crate) index: usize,
    pub(crate) name: &'a str,
    /// Its CAN id (iRPC node, compact command id; [`orion::ORION_NODE`]
    /// for the Orion motors).
    pub(crate) node: u16,
    pub(crate) device: Device,
    /// The unit of its positions in the bus map.
    pub(crate) unit: AngleUnit,
    pub(crate) online: bool,
    pub(crate) feedback: Option<&'a MotorFeedback>,
}

/// Where a device is and how it moves: position, velocity and
/// acceleration (degrees, a second, a second squared). A jerk-limited iRPC
/// joint plans a new move from all three.
pub(crate) type Kinematics = (f64, f64, f64);

/// [`Kinematics`] in a motor's unit (its bus map's, in which the gate and
/// the path check read positions).
pub(crate) fn in_unit(unit: AngleUnit, (p, v, a): Kinematics) -> motorwire_translate::JointState {
    (
        unit.from_degrees(p),
        unit.from_degrees(v),
        unit.from_degrees(a),
    )
}

/// What a request line waits for from its joint.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum AwaitKind {
    /// A TelemetryStream.
    Telemetry,
    /// A PowerMetrics.
    PowerMetrics,
    /// A FaultHistory.
    FaultHistory,
    /// A CalibrationResult.
    CalibrationResult,
}

pub(crate) mod compact;
mod error;
mod frames;
pub(crate) mod irpc;
pub(crate) mod moteus;
mod moteus_bounds;
pub(crate) mod orion;

pub(crate) use error::DeviceError;

/// What a motor of the bus map is to the engine: the dialect that reaches
/// it, and what that dialect needs to address it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Device {
    /// An iRPC joint, spoken to in its wire version.
    Irpc {
        /// Its wire version.
        wire: WireVersion,
    },
    /// A WIA compact-command device (WIRE-FACTS §2.1).
    Compact {
        /// The CAN id its feedback records come from.
        feedback_node: u16,
        /// Its motor hash, in every command and record.
        hash: MotorHash,
    },
    /// One of the Orion arm controller's motors.
    Orion(Motor),
    /// An mjbots moteus controller.
    Moteus {
        /// Its id (1..=127).
        id: u8,
        /// Its bus's CAN prefix.
        bus: u16,
        /// How often it is polled (ms).
        period_ms: u16,
        /// Whether a stop puts it in brake mode.
        brake: bool,
    },
}

/// What a device can be asked to do beyond a motor command.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Capability {
    /// A lifecycle (configure, activate, deactivate), brought back by the
    /// release.
    Lifecycle,
    /// A WIA trajectory, planned by the bridge into timed targets.
    Trajectory,
    /// A reset of this one device.
    Reset,
    /// A request for telemetry, power metrics or the fault history, or a
    /// calibration (each also needs its wire version's message).
    Requests,
}

impl Device {
    /// Whether it can do `what`.
    pub(crate) const fn supports(self, what: Capability) -> bool {
        match self {
            Self::Irpc { .. } => matches!(
                what,
                Capability::Lifecycle
                    | Capability::Trajectory
                    | Capability::Reset
                    | Capability::Requests
            ),
            // A moteus controller's reset is its stop (the one command
            // that takes it out of a fault or the watchdog's timeout); a
            // trajectory's segments are its position-mode moves
            // ([`Device::segment_order`]).
            Self::Moteus { .. } => matches!(what, Capability::Reset | Capability::Trajectory),
            Self::Compact { .. } | Self::Orion(_) => false,
        }
    }

    /// Whether it has the message `kind` (an iRPC joint: in its wire
    /// version; a moteus controller: a reset; the others: none).
    pub(crate) fn speaks(self, kind: PayloadKind) -> bool {
        match self {
            Self::Irpc { wire } => wire.tag_of(kind).is_some(),
            Self::Moteus { .. } => kind == PayloadKind::Reset,
            Self::Compact { .. } | Self::Orion(_) => false,
        }
    }

    /// The wire version it is spoken to in (v2.0 for the devices that do
    /// not speak iRPC, as [`crate::JointView`] shows them).
    pub(crate) const fn wire(self) -> WireVersion {
        match self {
            Self::Irpc { wire } => wire,
            Self::Compact { .. } | Self::Orion(_) | Self::Moteus { .. } => WireVersion::V2_0,
        }
    }

    /// Whether it takes commands as it is from the start (no lifecycle to
    /// bring it up).
    pub(crate) const fn active_at_start(self) -> bool {
        !matches!(self, Self::Irpc { .. })
    }

    /// Whether it is online before anything is heard from it (the Orion
    /// controller's motors are online from its boot beacon on).
    pub(crate) const fn online_at_start(self) -> bool {
        !matches!(self, Self::Orion(_))
    }

    /// The lifecycle `steps` as the device takes them: an iRPC joint its
    /// lifecycle payloads (telemetry where its wire version has it). The
    /// other dialects have no lifecycle: a Deactivate (or a Reset) is their
    /// stop (a compact device's emergency-stop flag, held until a command
    /// without it; the Orion controller's stop command, one line for all
    /// its motors) and the rest is nothing to send. `now_ms`: the compact
    /// command's timestamp.
    pub(crate) fn lifecycle_orders(self, steps: &[Lifecycle], now_ms: u64) -> Vec<Order> {
        let stops = || {
            steps
                .iter()
                .filter(|p| matches!(p, Lifecycle::Deactivate | Lifecycle::Reset))
                .take(1)
        };
        match self {
            Self::Irpc { .. } => steps
                .iter()
                .map(|s| s.payload())
                .filter(|p| self.speaks(p.kind()))
                .map(Order::Irpc)
                .collect(),
            Self::Compact { hash, .. } => stops()
                .map(|_| {
                    Order::Compact(CompactCommand {
                        motor: hash,
                        timestamp_ms: now_ms,
                        control_mode: CompactMode::Disabled,
                        flags: Flags::EMERGENCY_STOP
                            .union(Flags::REQUIRE_ACK)
                            .union(Flags::PRIORITY_HIGH),
                        setpoint: 0.0,
                        velocity_limit: None,
                        torque_limit: None,
                    })
                })
                .collect(),
            Self::Orion(_) => stops()
                .map(|_| Order::Orion(OrionOrder::Command(ArmCommand::Stop)))
                .collect(),
            Self::Moteus { brake, .. } => {
                stops().map(|_| Order::Moteus(moteus_stop(brake))).collect()
            }
        }
    }

    /// What the deadman (and the end of input) sends a device holding a
    /// velocity or torque setpoint: that setpoint brought to 0. `None`
    /// for a device that holds none (an iRPC joint takes position moves).
    pub(crate) fn hold_still(self, now_ms: u64) -> Option<Order> {
        match self {
            Self::Irpc { .. } => None,
            Self::Compact { hash, .. } => Some(Order::Compact(CompactCommand {
                motor: hash,
                timestamp_ms: now_ms,
                control_mode: CompactMode::Velocity,
                flags: Flags::REQUIRE_ACK.union(Flags::PRIORITY_HIGH),
                setpoint: 0.0,
                velocity_limit: None,
                torque_limit: None,
            })),
            Self::Orion(m) => Some(Order::Orion(OrionOrder::Set(m, 0.0))),
            // Its stop (or brake), as the map says.
            Self::Moteus { brake, .. } => Some(Order::Moteus(moteus_stop(brake))),
        }
    }

    /// Its stop before a position limit, braked at `decel` (degrees a
    /// second squared) where the device takes a deceleration: a moteus
    /// controller's velocity 0 within it (position NaN), held until its
    /// next command; `None` for the others (their own stop serves).
    pub(crate) fn limit_brake(self, decel: Option<f64>) -> Option<Order> {
        match (self, decel) {
            (Self::Moteus { .. }, Some(d)) => Some(Order::Moteus(MoteusCommand::Position(
                motorwire_moteus::PositionArgs {
                    position: Some(f64::NAN),
                    velocity: Some(0.0),
                    accel_limit: Some(d / 360.0),
                    ..motorwire_moteus::PositionArgs::default()
                },
            ))),
            _ => None,
        }
    }

    /// What a motor line (`{"motor":action,...}`) sends the device, by its
    /// dialect's own means ([`MotorOrder`]). `decel`: the limits'
    /// deceleration in force (degrees a second squared); `max_torque`: the
    /// torque limit in force (Nm), a moteus hold's; `now_ms`: the compact
    /// command's timestamp.
    ///
    /// - hold: a compact device's velocity 0, a moteus controller's
    ///   velocity 0 within the deceleration (position NaN: it holds where
    ///   it stops), an Orion speed motor's 0; the Orion servo holds its
    ///   last angle by itself (the controller moves it there at once), so
    ///   nothing is sent; an iRPC joint's is planned by the engine (a move
    ///   to where it can stop);
    /// - free: iRPC Deactivate, moteus stop mode, compact disabled; the
    ///   Orion controller has no torque off: a speed motor is brought to 0
    ///   (said), the servo is refused;
    /// - stop: what the emergency stop sends it, for it alone (iRPC
    ///   Deactivate, moteus stop or brake as the map says, the compact
    ///   emergency-stop flag), an Orion motor as held (the controller's
    ///   own stop is the whole arm's).
    ///
    /// # Errors
    /// What the device cannot do at all, said for a person.
    pub(crate) fn motor_order(
        self,
        action: crate::classify::MotorAction,
        decel: Option<f64>,
        max_torque: Option<f64>,
        now_ms: u64,
    ) -> Result<MotorOrder, DeviceError> {
        use crate::classify::MotorAction::{Free, Hold, Stop};
        let compact = |hash, mode, flags: Flags| {
            Order::Compact(CompactCommand {
                motor: hash,
                timestamp_ms: now_ms,
                control_mode: mode,
                flags: flags.union(Flags::REQUIRE_ACK).union(Flags::PRIORITY_HIGH),
                setpoint: 0.0,
                velocity_limit: None,
                torque_limit: None,
            })
        };
        let order = match (self, action) {
            (Self::Irpc { .. }, Hold) => return Ok(MotorOrder::Planned),
            (Self::Irpc { .. }, Free | Stop) => Order::Irpc(Payload::Deactivate),
            (Self::Compact { hash, .. }, Hold) => compact(hash, CompactMode::Velocity, Flags::NONE),
            (Self::Compact { hash, .. }, Free) => compact(hash, CompactMode::Disabled, Flags::NONE),
            (Self::Compact { hash, .. }, Stop) => {
                compact(hash, CompactMode::Disabled, Flags::EMERGENCY_STOP)
            }
            (Self::Moteus { .. }, Hold) => {
                Order::Moteus(MoteusCommand::Position(motorwire_moteus::PositionArgs {
                    position: Some(f64::NAN),
                    velocity: Some(0.0),
                    accel_limit: decel.map(|d| d / 360.0),
                    maximum_torque: max_torque,
                    ..motorwire_moteus::PositionArgs::default()
                }))
            }
            (Self::Moteus { .. }, Free) => Order::Moteus(MoteusCommand::Stop),
            (Self::Moteus { brake, .. }, Stop) => Order::Moteus(moteus_stop(brake)),
            (Self::Orion(m), _) if m.quantity() != Quantity::PositionDegrees => {
                let loss = (action == Free).then(|| {
                    "the Orion arm controller has no torque off: the motor was brought to 0"
                        .to_owned()
                });
                return Ok(MotorOrder::Send(
                    Order::Orion(OrionOrder::Set(m, 0.0)),
                    loss,
                ));
            }
            (Self::Orion(m), Free) => return Err(DeviceError::NoTorqueOff(m.key())),
            (Self::Orion(m), Hold | Stop) => {
                return Ok(MotorOrder::Nothing(format!(
                    "the Orion servo {} holds the angle it was last sent by itself: nothing was sent",
                    m.key()
                )));
            }
        };
        Ok(MotorOrder::Send(order, None))
    }

    /// Whether its moves are planned by the bridge from its state, with
    /// the other such devices of a multi-axis line (an iRPC joint's
    /// SetTargetV2); the others take a command on its own
    /// ([`Device::single_order`]).
    pub(crate) const fn planned_together(self) -> bool {
        matches!(self, Self::Irpc { .. })
    }

    /// `cmd` gated against `map`'s limits in force and translated into
    /// the device's one order, for a device that takes a command on its
    /// own; `None` for one whose moves are planned together (an iRPC
    /// joint).
    pub(crate) fn single_order(
        self,
        map: &BusMap,
        cmd: &MotorCommand,
    ) -> Option<Result<Single, Refusal>> {
        match self {
            Self::Irpc { .. } => None,
            Self::Compact { .. } => Some(to_compact(map, cmd).map(|t| {
                let mut c = t.value;
                c.flags = c.flags.union(Flags::REQUIRE_ACK);
                let unit = map
                    .motor(&cmd.motor_id)
                    .map_or(AngleUnit::Degrees, |m| m.unit);
                Single {
                    order: Order::Compact(c),
                    target: (c.control_mode == CompactMode::Position)
                        .then(|| unit.to_degrees(f64::from(c.setpoint))),
                    report: t.report,
                }
            })),
            Self::Orion(motor) => Some(to_orion_motor(map, cmd).map(|t| {
                let order = match t.value {
                    motorwire_orion::Input::DirectControl(values) => {
                        OrionOrder::Set(motor, values.get(motor).unwrap_or(0.0))
                    }
                    motorwire_orion::Input::Command(_) => OrionOrder::Command(ArmCommand::Stop),
                };
                let target = match order {
                    OrionOrder::Set(m, v) if m.quantity() == Quantity::PositionDegrees => Some(v),
                    _ => None,
                };
                Single {
                    order: Order::Orion(order),
                    target,
                    report: t.report,
                }
            })),
            Self::Moteus { .. } => Some(to_moteus(map, cmd).map(|t| Single {
                order: Order::Moteus(t.value),
                target: match t.value {
                    MoteusCommand::Position(a) => {
                        a.position.filter(|p| p.is_finite()).map(|p| p * 360.0)
                    }
                    MoteusCommand::Stop | MoteusCommand::Brake => None,
                },
                report: t.report,
            })),
        }
    }

    /// A planned trajectory's segment (degrees; its target, the velocity
    /// to pass it at and the limits to reach it within) as the device takes
    /// it: an iRPC joint the SetTargetV2 itself, a moteus controller a
    /// position-mode move (its own trapezoid within the segment's velocity
    /// and acceleration, ending at its velocity; `max_torque` the limit in
    /// force). `None` for a device that takes no trajectory.
    pub(crate) fn segment_order(
        self,
        p: SetTargetPayloadV2,
        max_torque: Option<f64>,
    ) -> Option<Order> {
        let rev = |deg: f32| f64::from(deg) / 360.0;
        match self {
            Self::Irpc { .. } => Some(Order::Irpc(Payload::SetTargetV2(p))),
            Self::Moteus { .. } => Some(Order::Moteus(MoteusCommand::Position(
                motorwire_moteus::PositionArgs {
                    position: Some(rev(p.target_angle)),
                    velocity: Some(rev(p.target_velocity)),
                    velocity_limit: Some(rev(p.max_velocity)),
                    // moteus has one limit for speeding up and braking:
                    // the tighter (a deceleration of 0 or less is "as the
                    // acceleration", as iRPC reads it).
                    accel_limit: Some(rev(if p.max_deceleration > 0.0 {
                        p.max_acceleration.min(p.max_deceleration)
                    } else {
                        p.max_acceleration
                    })),
                    maximum_torque: max_torque,
                    ..motorwire_moteus::PositionArgs::default()
                },
            ))),
            Self::Compact { .. } | Self::Orion(_) => None,
        }
    }

    /// Who it is, as a message about an unanswered request says it.
    pub(crate) fn who(self, node: u16) -> String {
        match self {
            Self::Irpc { .. } | Self::Compact { .. } => format!("node 0x{node:02X}"),
            Self::Orion(_) => orion::LABEL.to_owned(),
            Self::Moteus { id, bus, .. } => format!("moteus id {id} on bus {bus}"),
        }
    }
}

/// A moteus controller's stop: stop mode, or brake mode.
impl Device {
    /// The dialect's name as a person reads it (`iRPC`, `compact`,
    /// `Orion`, `moteus`).
    /// The version of its dialect it is spoken to in, where the dialect
    /// has versions (an iRPC joint's wire version).
    pub(crate) const fn version(self) -> Option<&'static str> {
        match self {
            Self::Irpc { wire } => Some(wire.name()),
            Self::Compact { .. } | Self::Orion(_) | Self::Moteus { .. } => None,
        }
    }

    pub(crate) const fn dialect_name(self) -> &'static str {
        match self {
            Self::Irpc { .. } => "iRPC",
            Self::Compact { .. } => "compact",
            Self::Orion(_) => "Orion",
            Self::Moteus { .. } => "moteus",
        }
    }
}

const fn moteus_stop(brake: bool) -> MoteusCommand {
    if brake {
        MoteusCommand::Brake
    } else {
        MoteusCommand::Stop
    }
}

/// What a motor line sends its device ([`Device::motor_order`]). (Made
/// once a motor line and matched at once: its size does not matter.)
#[derive(Debug, Clone, PartialEq)]
#[allow(clippy::large_enum_variant)]
pub(crate) enum MotorOrder {
    /// This order, with what it does otherwise than asked (said in the
    /// result's losses).
    Send(Order, Option<String>),
    /// A move the engine plans from the device's state (an iRPC hold).
    Planned,
    /// Nothing: the device does it by itself (why, said in the losses).
    Nothing(String),
}

/// A command translated for a device that takes it on its own.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Single {
    pub(crate) order: Order,
    /// The target of a position move (degrees), watched for arrival.
    pub(crate) target: Option<f64>,
    /// What the translation could not carry, or defaulted.
    pub(crate) report: Report,
}

/// One request for a device: an iRPC payload for a joint, a compact
/// command for a compact device, or a value or command for the Orion arm
/// controller.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Order {
    Irpc(Payload),
    Compact(CompactCommand),
    Orion(OrionOrder),
    Moteus(MoteusCommand),
}

/// One Orion motor's part of a line to the arm controller.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum OrionOrder {
    /// Direct control: the motor's new value (already within its range).
    Set(Motor, f64),
    /// Command mode: stop, fold or unfold.
    Command(ArmCommand),
}

/// Where an order takes its device, and how fast (degrees, degrees a
/// second): what the limits in force are held against.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub(crate) struct Reach {
    /// The position it moves the device to.
    pub(crate) target: Option<f64>,
    /// The speed it moves (or lets it move) at, at most.
    pub(crate) speed: Option<f64>,
}

/// What the engine knows of a device when one of its orders is
/// acknowledged, for [`Order::effect`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Context {
    /// When it was acknowledged.
    pub(crate) at: Duration,
    /// Its kinematics when the order was sent (or as last reported).
    pub(crate) motion: Option<Kinematics>,
    /// The motor's unit.
    pub(crate) unit: AngleUnit,
    /// The limits in force (degrees).
    pub(crate) max_velocity: Option<f64>,
    pub(crate) max_acceleration: Option<f64>,
    /// The motor's command timeout (the deadman's), if any.
    pub(crate) command_timeout: Option<Duration>,
    /// The gate's plan for a move: from its kinematics, the target and how
    /// long it takes (reused when the acknowledged order is it).
    pub(crate) planned: Option<(Kinematics, SetTargetPayloadV2, Duration)>,
}

/// The limits in force on a device, in degrees (and Nm), as a driver that
/// sends by itself holds to them ([`Drivers::limits_changed`]).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub(crate) struct InForce {
    pub(crate) min_position: Option<f64>,
    pub(crate) max_position: Option<f64>,
    pub(crate) max_velocity: Option<f64>,
    pub(crate) max_torque: Option<f64>,
}

impl InForce {
    /// `limits` of a motor in `unit`, in degrees.
    pub(crate) fn of(unit: AngleUnit, limits: &motorwire_translate::Limits) -> Self {
        let deg = |v: Option<f64>| v.map(|v| unit.to_degrees(v));
        Self {
            min_position: deg(limits.min_position),
            max_position: deg(limits.max_position),
            max_velocity: deg(limits.max_velocity),
            max_torque: limits.max_torque,
        }
    }
}

/// Until when a device moves, after an order's effect.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Moving {
    /// As before.
    Unchanged,
    /// Until then.
    Until(Duration),
    /// No later than then (a stop: it brakes).
    AtMost(Duration),
}

/// What an acknowledged order did to its device, as the engine tracks it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Effect {
    /// Its new target (degrees): `Some(None)`, none any more; `None`, as
    /// before.
    pub(crate) target: Option<Option<f64>>,
    /// Until when it moves.
    pub(crate) moving: Moving,
    /// When the setpoint it now holds must be renewed by, or the deadman
    /// stops it (`None`: it holds none).
    pub(crate) deadman: Option<Duration>,
    /// Whether it is now active (`None`: as before).
    pub(crate) active: Option<bool>,
    /// A move whose outcome was unknown is settled by this one.
    pub(crate) settles: bool,
}

impl Effect {
    const NONE: Self = Self {
        target: None,
        moving: Moving::Unchanged,
        deadman: None,
        active: None,
        settles: false,
    };
}

impl Order {
    /// Whether it is a position move (which a newer one may replace while
    /// it waits, and whose arrival is watched).
    pub(crate) fn is_position_move(&self) -> bool {
        match self {
            Self::Irpc(p) => matches!(p, Payload::SetTargetV2(_) | Payload::SetTarget(_)),
            Self::Compact(c) => c.control_mode == CompactMode::Position,
            Self::Orion(OrionOrder::Set(m, _)) => m.quantity() == Quantity::PositionDegrees,
            Self::Orion(OrionOrder::Command(_)) => false,
            Self::Moteus(MoteusCommand::Position(a)) => a.position.is_some_and(f64::is_finite),
            Self::Moteus(_) => false,
        }
    }

    /// Whether it is a motor command's setpoint (a position move, a
    /// velocity or a torque), which a stream's newer setpoint replaces
    /// while it waits; a stop, a lifecycle step or an arm-wide command is
    /// not.
    pub(crate) fn is_setpoint(&self) -> bool {
        match self {
            Self::Irpc(p) => matches!(p, Payload::SetTargetV2(_) | Payload::SetTarget(_)),
            Self::Compact(c) => {
                matches!(
                    c.control_mode,
                    CompactMode::Position | CompactMode::Velocity | CompactMode::Torque
                ) && !c.flags.contains(Flags::EMERGENCY_STOP)
            }
            Self::Orion(OrionOrder::Set(..)) => true,
            Self::Orion(OrionOrder::Command(_)) => false,
            Self::Moteus(c) => matches!(c, MoteusCommand::Position(_)),
        }
    }

    /// Whether it leaves its device holding a setpoint that does not end
    /// by itself (a compact velocity or torque, an Orion speed or actuator
    /// value, other than 0): what the deadman watches.
    pub(crate) fn holds_setpoint(&self) -> bool {
        match self {
            Self::Irpc(_) => false,
            Self::Compact(c) => {
                matches!(c.control_mode, CompactMode::Velocity | CompactMode::Torque)
                    && c.setpoint != 0.0
                    && !c.flags.contains(Flags::EMERGENCY_STOP)
            }
            Self::Orion(OrionOrder::Set(m, v)) => {
                m.quantity() != Quantity::PositionDegrees && *v != 0.0
            }
            Self::Orion(OrionOrder::Command(_)) => false,
            // A velocity (position NaN) or a torque other than 0.
            Self::Moteus(MoteusCommand::Position(a)) => {
                !a.position.is_some_and(f64::is_finite)
                    && (a.velocity.is_some_and(|v| v != 0.0)
                        || a.feedforward_torque.is_some_and(|t| t != 0.0))
            }
            Self::Moteus(_) => false,
        }
    }

    /// Whether it stops a device whose acknowledgement cannot be tied to
    /// it (a compact command: the device's next feedback record, whatever
    /// caused it, acknowledges it), and how its feedback shows it taken:
    /// `Some(true)`, the `enabled` status cleared (disabled, or the
    /// emergency-stop flag); `Some(false)`, slowing to rest (velocity 0).
    pub(crate) fn unconfirmed_stop(&self) -> Option<bool> {
        match self {
            Self::Compact(c)
                if c.flags.contains(Flags::EMERGENCY_STOP)
                    || c.control_mode == CompactMode::Disabled =>
            {
                Some(true)
            }
            Self::Compact(c) if c.control_mode == CompactMode::Velocity && c.setpoint == 0.0 => {
                Some(false)
            }
            _ => None,
        }
    }

    /// Whether it ends a velocity or torque setpoint its device holds (a
    /// stop of the device's own, or a velocity 0): the deadman has nothing
    /// to add to one in flight.
    pub(crate) fn ends_setpoint(&self) -> bool {
        match self {
            Self::Irpc(_) | Self::Orion(OrionOrder::Command(_)) => false,
            Self::Compact(_) => self.unconfirmed_stop().is_some(),
            Self::Orion(OrionOrder::Set(m, v)) => {
                m.quantity() != Quantity::PositionDegrees && *v == 0.0
            }
            Self::Moteus(MoteusCommand::Stop | MoteusCommand::Brake) => true,
            Self::Moteus(MoteusCommand::Position(a)) => {
                !a.position.is_some_and(f64::is_finite)
                    && a.velocity == Some(0.0)
                    && a.feedforward_torque.is_none_or(|t| t == 0.0)
            }
        }
    }

    /// Whether it is a device's emergency stop (a compact command's flag):
    /// what may still go while the emergency stop is latched.
    pub(crate) fn is_emergency_stop(&self) -> bool {
        matches!(self, Self::Compact(c) if c.flags.contains(Flags::EMERGENCY_STOP))
    }

    /// The same order with `now_ms` as its timestamp where it carries one
    /// (a compact command sent again is new bytes: a device executes it
    /// even if it took the first).
    #[must_use]
    pub(crate) fn restamped(self, now_ms: u64) -> Self {
        match self {
            Self::Compact(c) => Self::Compact(CompactCommand {
                timestamp_ms: now_ms,
                ..c
            }),
            other => other,
        }
    }

    /// The velocity setpoint it leaves its device holding, in the
    /// motor's `unit` a second: a compact velocity command's (in that unit
    /// already), a moteus velocity's (position NaN; revolutions on the
    /// wire); `None` for anything else.
    pub(crate) fn held_velocity(&self, unit: AngleUnit) -> Option<f64> {
        match self {
            Self::Compact(c) if c.control_mode == CompactMode::Velocity => {
                Some(f64::from(c.setpoint))
            }
            Self::Moteus(MoteusCommand::Position(a)) if !a.position.is_some_and(f64::is_finite) => {
                a.velocity
                    .filter(|v| v.is_finite())
                    .map(|v| unit.from_degrees(v * 360.0))
            }
            _ => None,
        }
    }

    /// The target of a move (degrees) where the order alone says it (an
    /// iRPC target is in degrees; the others are in the motor's unit and
    /// are given their target by the engine, which knows it).
    pub(crate) fn own_target(&self) -> Option<f64> {
        match self {
            Self::Irpc(Payload::SetTargetV2(p)) => Some(f64::from(p.target_angle)),
            Self::Irpc(Payload::SetTarget(p)) => Some(f64::from(p.target_angle)),
            // Revolutions on the wire, whatever the motor's unit.
            Self::Moteus(MoteusCommand::Position(a)) => {
                a.position.filter(|p| p.is_finite()).map(|p| p * 360.0)
            }
            _ => None,
        }
    }

    /// The motion the device plans for this order from `from` (its
    /// kinematics, degrees), where the bridge plans it as the device does
    /// (an iRPC `SetTargetV2`: the joint plans it from where it is, how
    /// fast it moves and how that changes, with motorwire's planner).
    /// `planned`: the gate's plan of a move from the same state, taken
    /// when it is this order's.
    pub(crate) fn device_plan(
        &self,
        from: Kinematics,
        planned: Option<(SetTargetPayloadV2, Box<motorwire_planner::Profile<f64>>)>,
    ) -> Option<Box<motorwire_planner::Profile<f64>>> {
        match self {
            Self::Irpc(Payload::SetTargetV2(p)) => match planned {
                Some((q, profile)) if q == *p => Some(profile),
                _ => motorwire_planner::plan(
                    &p.planner_request(from.0, from.1)
                        .with_start_acceleration(from.2),
                )
                .ok()
                .map(Box::new),
            },
            _ => None,
        }
    }

    /// Whether the path this order sends its motor along, planned as the
    /// device plans it from `from` (its kinematics, degrees), stays
    /// within the limits in force (`in_force`: the motor and its limits,
    /// looked up only when there is a path to check); `checked`: a move
    /// whose path was already checked from that state (the gate's, when
    /// the line came), which is not planned again. Only for the orders
    /// the bridge plans as the device does (an iRPC `SetTargetV2`); the
    /// others are held to the limits by their targets alone.
    pub(crate) fn path_refusal<'m>(
        &self,
        from: Kinematics,
        checked: Option<(Kinematics, SetTargetPayloadV2)>,
        in_force: impl FnOnce() -> Option<(
            &'m motorwire_translate::MappedMotor,
            motorwire_translate::Effective,
        )>,
    ) -> Option<motorwire_translate::Refusal> {
        let Self::Irpc(Payload::SetTargetV2(p)) = self else {
            return None;
        };
        if checked == Some((from, *p)) {
            return None;
        }
        let (motor, limits) = in_force()?;
        motorwire_translate::check_path_from(motor, &limits, p, in_unit(motor.unit, from)).err()
    }

    /// Where it takes the device and how fast, in degrees (`unit`: the
    /// motor's, in which compact commands are written).
    pub(crate) fn reach(&self, unit: AngleUnit) -> Reach {
        match self {
            Self::Irpc(Payload::SetTargetV2(p)) => Reach {
                target: Some(f64::from(p.target_angle)),
                speed: Some(f64::from(p.max_velocity)),
            },
            Self::Irpc(Payload::SetTarget(p)) => Reach {
                target: Some(f64::from(p.target_angle)),
                speed: Some(f64::from(p.velocity_limit)),
            },
            Self::Compact(c) if c.control_mode == CompactMode::Position => Reach {
                target: Some(unit.to_degrees(f64::from(c.setpoint))),
                speed: c.velocity_limit.map(|l| unit.to_degrees(l.units_per_s())),
            },
            Self::Compact(c) if c.control_mode == CompactMode::Velocity => Reach {
                target: None,
                speed: Some(unit.to_degrees(f64::from(c.setpoint))),
            },
            Self::Orion(OrionOrder::Set(m, v)) if m.quantity() == Quantity::PositionDegrees => {
                Reach {
                    target: Some(*v),
                    speed: None,
                }
            }
            // Revolutions on the wire, whatever the motor's unit.
            Self::Moteus(MoteusCommand::Position(a)) => {
                match a.position.filter(|p| p.is_finite()) {
                    Some(p) => Reach {
                        target: Some(p * 360.0),
                        speed: a.velocity_limit.map(|v| v.abs() * 360.0),
                    },
                    None => Reach {
                        target: None,
                        speed: a
                            .velocity
                            .filter(|v| v.is_finite())
                            .map(|v| v.abs() * 360.0),
                    },
                }
            }
            _ => Reach::default(),
        }
    }

    /// What it did to its device once acknowledged, in `cx`.
    pub(crate) fn effect(&self, cx: &Context) -> Effect {
        let at = cx.at;
        match *self {
            Self::Irpc(p) => irpc::effect(p, cx),
            Self::Compact(c) => {
                if c.flags.contains(Flags::EMERGENCY_STOP) {
                    // Its move abandoned.
                    return Effect {
                        target: Some(None),
                        moving: Moving::AtMost(at),
                        ..Effect::NONE
                    };
                }
                match c.control_mode {
                    CompactMode::Position => {
                        let target = cx.unit.to_degrees(f64::from(c.setpoint));
                        let from = cx.motion.map_or(target, |(p, ..)| p);
                        let v = c
                            .velocity_limit
                            .map(|l| cx.unit.to_degrees(l.units_per_s()))
                            .or(cx.max_velocity)
                            .unwrap_or(60.0)
                            .max(1e-3);
                        let a = cx.max_acceleration.unwrap_or(500.0).max(1e-3);
                        // A trapezoid's duration, a bound on the device's move.
                        let secs = (target - from).abs() / v + v / a;
                        Effect {
                            target: Some(Some(target)),
                            moving: Moving::Until(
                                at.saturating_add(Duration::from_secs_f64(secs.min(3600.0))),
                            ),
                            ..Effect::NONE
                        }
                    }
                    CompactMode::Velocity | CompactMode::Torque => self.holding(cx),
                    _ => Effect {
                        moving: Moving::Until(at),
                        ..Effect::NONE
                    },
                }
            }
            Self::Orion(OrionOrder::Set(m, v)) => match m.quantity() {
                Quantity::PositionDegrees => Effect {
                    target: Some(Some(v)),
                    moving: Moving::Until(at),
                    ..Effect::NONE
                },
                Quantity::Speed | Quantity::Actuator => self.holding(cx),
            },
            // A stop abandons the move; fold and unfold move the servo
            // where the controller takes it.
            Self::Orion(OrionOrder::Command(_)) => Effect {
                target: Some(None),
                moving: Moving::Until(at),
                ..Effect::NONE
            },
            Self::Moteus(MoteusCommand::Stop | MoteusCommand::Brake) => Effect {
                target: Some(None),
                moving: Moving::AtMost(at),
                ..Effect::NONE
            },
            Self::Moteus(MoteusCommand::Position(a)) => {
                match a.position.filter(|p| p.is_finite()) {
                    Some(p) => {
                        let target = p * 360.0;
                        let from = cx.motion.map_or(target, |(p, ..)| p);
                        let v = a
                            .velocity_limit
                            .map(|v| v.abs() * 360.0)
                            .or(cx.max_velocity)
                            .unwrap_or(60.0)
                            .max(1e-3);
                        let acc = a
                            .accel_limit
                            .map(|v| v.abs() * 360.0)
                            .or(cx.max_acceleration)
                            .unwrap_or(500.0)
                            .max(1e-3);
                        // A trapezoid's duration, a bound on the controller's move.
                        let secs = (target - from).abs() / v + v / acc;
                        Effect {
                            target: Some(Some(target)),
                            moving: Moving::Until(
                                at.saturating_add(Duration::from_secs_f64(secs.min(3600.0))),
                            ),
                            ..Effect::NONE
                        }
                    }
                    None => self.holding(cx),
                }
            }
        }
    }

    /// A velocity or torque setpoint's effect: no target; one other than
    /// 0 is watched by the deadman (and moves until then), 0 holds the
    /// device still.
    fn holding(&self, cx: &Context) -> Effect {
        let deadman = if self.holds_setpoint() {
            cx.command_timeout.map(|t| cx.at.saturating_add(t))
        } else {
            None
        };
        Effect {
            target: Some(None),
            moving: Moving::Until(deadman.unwrap_or(cx.at)),
            deadman,
            ..Effect::NONE
        }
    }
}

impl Order {
    /// The lifecycle step it is, if it is one (what the release sends a
    /// joint again).
    pub(crate) fn lifecycle(&self) -> Option<Lifecycle> {
        match self {
            Self::Irpc(p) => Lifecycle::of(p),
            Self::Compact(_) | Self::Orion(_) | Self::Moteus(_) => None,
        }
    }
}

/// A step of a device's lifecycle as the engine drives it, in no
/// dialect's terms: each device takes it as [`Device::lifecycle_orders`]
/// says (an iRPC joint its lifecycle payloads; the others their stop, or
/// nothing).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Lifecycle {
    /// Back from a fault or a reboot.
    Reset,
    /// Configured (its parameters loaded).
    Configure,
    /// Up: it takes motion.
    Activate,
    /// Down: its torque off (the stop).
    Deactivate,
    /// Its telemetry reported periodically at `rate_hz`, where it can.
    Telemetry {
        /// How often.
        rate_hz: u16,
    },
}

impl Lifecycle {
    /// An iRPC joint's payload for it.
    const fn payload(self) -> Payload {
        match self {
            Self::Reset => Payload::Reset,
            Self::Configure => Payload::Configure,
            Self::Activate => Payload::Activate,
            Self::Deactivate => Payload::Deactivate,
            Self::Telemetry { rate_hz } => {
                Payload::ConfigureTelemetry(motorwire_irpc::ConfigureTelemetryPayload {
                    mode: motorwire_irpc::TelemetryMode::Periodic,
                    rate_hz,
                    change_threshold: 0.0,
                })
            }
        }
    }

    /// The step an iRPC payload is, if it is one the engine sends.
    fn of(p: &Payload) -> Option<Self> {
        match p {
            Payload::Reset => Some(Self::Reset),
            Payload::Configure => Some(Self::Configure),
            Payload::Activate => Some(Self::Activate),
            Payload::Deactivate => Some(Self::Deactivate),
            Payload::ConfigureTelemetry(t) if t.mode == motorwire_irpc::TelemetryMode::Periodic => {
                Some(Self::Telemetry { rate_hz: t.rate_hz })
            }
            _ => None,
        }
    }
}

/// Whose a frame from the bus is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Route {
    /// A compact device's feedback record: device `.0`'s.
    CompactFeedback(usize),
    /// A compact command (the bridge's own, heard back on a second
    /// socket): nothing to act on.
    CompactCommand,
    /// A moteus controller's reply: device `.0`'s.
    MoteusReply(usize),
    /// A moteus command (the bridge's own, heard back): nothing to act on.
    MoteusCommand,
    /// Anything else: the iRPC driver's to read (or to call bad).
    Irpc,
}

/// Whose a frame from the bus is, looked up by its CAN id among the
/// devices the router was made for: what a frame costs does not grow with
/// the devices (every frame of every device passes here).
#[derive(Debug, Default)]
pub(crate) struct Router {
    /// Compact devices by the CAN id of their feedback (the first device,
    /// in the engine's order, of each).
    compact_feedback: HashMap<u32, usize>,
    /// The CAN ids of compact commands.
    compact_command: HashSet<u32>,
    /// Moteus controllers by (CAN prefix, id): the first of each.
    moteus: HashMap<(u16, u8), usize>,
}

impl Router {
    /// A router for `devices` (each device's CAN id and dialect, in the
    /// engine's order).
    pub(crate) fn new(devices: impl Iterator<Item = (u16, Device)>) -> Self {
        let mut router = Self::default();
        for (k, (node, device)) in devices.enumerate() {
            match device {
                Device::Compact { feedback_node, .. } => {
                    router
                        .compact_feedback
                        .entry(u32::from(feedback_node))
                        .or_insert(k);
                    router.compact_command.insert(u32::from(node));
                }
                Device::Moteus { id, bus, .. } => {
                    router.moteus.entry((bus, id)).or_insert(k);
                }
                Device::Irpc { .. } | Device::Orion(_) => {}
            }
        }
        router
    }

    /// Whose `frame` is: a compact device's feedback before anything else
    /// on its CAN id; a moteus controller's reply before a command to one.
    pub(crate) fn route(&self, frame: &Frame) -> Route {
        let id = frame.id();
        let raw = id.raw();
        if id.is_extended() {
            if self.moteus.is_empty() {
                return Route::Irpc;
            }
            let Ok(bus) = u16::try_from((raw >> 16) & 0x1FFF) else {
                return Route::Irpc;
            };
            let end = |shift: u32| u8::try_from((raw >> shift) & 0x7F).unwrap_or(0);
            let (source, destination) = (end(8), end(0));
            if destination == moteus::SOURCE
                && let Some(&k) = self.moteus.get(&(bus, source))
            {
                return Route::MoteusReply(k);
            }
            if source == moteus::SOURCE && self.moteus.contains_key(&(bus, destination)) {
                return Route::MoteusCommand;
            }
            return Route::Irpc;
        }
        if let Some(&k) = self.compact_feedback.get(&raw) {
            return Route::CompactFeedback(k);
        }
        if self.compact_command.contains(&raw) {
            return Route::CompactCommand;
        }
        Route::Irpc
    }
}

/// How a request of any driver ended.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) enum Outcome {
    /// The device took it.
    Acked,
    /// The device refused it: its code, where its dialect has codes, and
    /// why, said for a person. `already_stopped`: it refused a stop
    /// because it is stopped already (which a stop takes as done).
    Nacked {
        code: Option<u16>,
        why: String,
        already_stopped: bool,
    },
    /// No answer after every try: the device may or may not have run it.
    TimedOut,
}

/// A request of a driver that ended, in one form for every dialect.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct Ended {
    /// The driver's number for it.
    pub(crate) msg_id: u32,
    pub(crate) outcome: Outcome,
    /// How many times it was sent.
    pub(crate) attempts: u8,
    /// When it ended.
    pub(crate) at: Duration,
}

/// What a driver tells the engine, in one form for every dialect: the
/// engine acts on each the same way whatever the device
/// ([`Drivers::poll`] hands them out in the order they happened).
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Happened {
    /// Device `device` was heard from at `at`. `up`: its link lets it be
    /// online (the Orion controller's motors only from its boot beacon on,
    /// and after a lost link only once its stop was answered).
    Heard {
        device: usize,
        at: Duration,
        up: bool,
    },
    /// Device `device` reported at `at`: its position and velocity
    /// (degrees) where the report has them, and its WIA feedback.
    Reading {
        device: usize,
        at: Duration,
        motion: Option<(f64, f64)>,
        feedback: Option<Box<MotorFeedback>>,
    },
    /// Device `device`'s request in flight ended.
    Ended { device: usize, ended: Ended },
    /// Device `device` reported its lifecycle state and error code.
    Lifecycle {
        device: usize,
        state: LifecycleState,
        code: u16,
    },
    /// Device `device` stopped itself at `at`: why, and its code.
    StoppedItself {
        device: usize,
        at: Duration,
        reason: String,
        code: u16,
    },
    /// A message from device `device` that a request line may wait for.
    Answer { device: usize, answer: Answer },
    /// Something on a driver's link that is none of its devices' messages:
    /// counted, and reported when `report` is there (drivers bound how
    /// often).
    Bad { report: Option<Event> },
    /// An event of a driver's link to pass on as it is (the Orion
    /// controller's boot beacon, its link lost).
    Event(Event),
    /// The link to `devices` is lost: they are offline (`offline` says
    /// why, with the link's error), and lines waiting on them will not
    /// arrive (`arrival` says why).
    LinkLost {
        devices: Vec<usize>,
        offline: String,
        arrival: String,
    },
    /// What waits for `devices` may go now: their link is free, or up.
    MayGo { devices: Vec<usize> },
}

/// A message a request line may wait for, in the engine's terms.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Answer {
    /// Progress to report while the line waits (a calibration's phase).
    Progress(Event),
    /// The message of `kind` a request line waits for, as its result's
    /// `data`, and the line's error when the message says the request
    /// failed.
    Data {
        kind: AwaitKind,
        data: Value,
        error: Option<String>,
    },
}

/// What the drivers queue for the engine: something to tell it, or a step
/// of their own to take once the engine has taken what came before.
#[derive(Debug)]
enum Queued {
    Tell(Happened),
    /// The Orion controller's recovery stop was answered and its answer
    /// taken: its motors are up again.
    EndOrionRecovery {
        at: Duration,
    },
    /// A compact device's valid record acknowledges its command in
    /// flight, once the engine has taken the record (which may have sent
    /// that command).
    CompactAck {
        device: usize,
        at: Duration,
        /// The record says the device is not driving (`enabled` clear):
        /// only such a record acknowledges an emergency stop (a record the
        /// device sent before the stop reached it says nothing of it).
        stopped: bool,
    },
    /// A moteus controller's reply acknowledges its command in flight,
    /// once the engine has taken the reply.
    MoteusAck {
        device: usize,
        at: Duration,
    },
}

/// The link a device is reached over, as far as sending goes: the CAN bus
/// (a request in flight per device) or the Orion controller's line (one
/// line in flight for all its motors).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Link {
    Bus,
    Controller,
}

impl Device {
    /// The device a motor of the bus map is to the bridge, with its CAN
    /// id; `None` for an Orion motor when no controller is attached
    /// (`orion`).
    pub(crate) fn of(motor: &motorwire_translate::MappedMotor, orion: bool) -> Option<(u16, Self)> {
        Some(match motor.target {
            Target::Irpc { node, wire } => (node, Self::Irpc { wire }),
            Target::Compact {
                node,
                feedback_node,
            } => (
                node,
                Self::Compact {
                    feedback_node,
                    hash: MotorHash::of(&motor.name),
                },
            ),
            Target::Orion { motor } if orion => (orion::ORION_NODE, Self::Orion(motor)),
            Target::Orion { .. } => return None,
            Target::Moteus {
                id,
                bus,
                query_rate_hz,
                brake,
            } => (
                u16::from(id),
                Self::Moteus {
                    id,
                    bus,
                    period_ms: (1000 / query_rate_hz.max(1)).max(1),
                    brake,
                },
            ),
        })
    }

    /// The link it is reached over.
    pub(crate) const fn link(self) -> Link {
        match self {
            Self::Irpc { .. } | Self::Compact { .. } | Self::Moteus { .. } => Link::Bus,
            Self::Orion(_) => Link::Controller,
        }
    }

    /// Its order for an arm-wide `command` (fold, unfold), if it takes one.
    pub(crate) const fn arm_order(self, command: ArmCommand) -> Option<Order> {
        match self {
            Self::Orion(_) => Some(Order::Orion(OrionOrder::Command(command))),
            Self::Irpc { .. } | Self::Compact { .. } | Self::Moteus { .. } => None,
        }
    }
}

/// The refusal of a line for one of `motors` whose driver is not attached
/// (an Orion motor when no controller is: `orion`).
pub(crate) fn unattached<'a>(
    map: &BusMap,
    orion: bool,
    mut motors: impl Iterator<Item = &'a str>,
) -> Option<crate::output::Refusal> {
    if orion {
        return None;
    }
    let m = motors.find(|m| {
        map.motor(m)
            .is_some_and(|m| matches!(m.target, Target::Orion { .. }))
    })?;
    Some(crate::output::Refusal::OrionMotorNotAttached {
        motor: m.to_owned(),
    })
}

impl Order {
    /// Whether it goes out in one message with the like orders of its
    /// line for the other devices of its link (the Orion controller takes
    /// every motor's value, or one command for all, in one line).
    pub(crate) const fn sent_together(&self) -> bool {
        matches!(self, Self::Orion(_))
    }

    /// Whether `other`, another device's order of the same line, goes in
    /// one message with this one.
    pub(crate) fn joins(&self, other: &Self) -> bool {
        match (self, other) {
            (Self::Orion(OrionOrder::Set(..)), Self::Orion(OrionOrder::Set(..))) => true,
            (Self::Orion(OrionOrder::Command(c)), Self::Orion(OrionOrder::Command(d))) => c == d,
            _ => false,
        }
    }
}

impl From<Payload> for Order {
    fn from(p: Payload) -> Self {
        Self::Irpc(p)
    }
}

/// `now` on the bridge's clock as Unix ms (`epoch`: the Unix ms of its
/// zero). The engine's clock is read through this one too.
pub(crate) fn unix_ms(epoch: f64, now: Duration) -> f64 {
    let ms = u64::try_from(now.as_millis()).unwrap_or(u64::MAX);
    #[allow(clippy::cast_precision_loss)]
    let ms = ms as f64;
    (epoch + ms).floor()
}

/// The drivers, one per dialect: a closed set, each operation one match.
/// Every driver's news reaches the engine as [`Happened`], through
/// [`Drivers::poll`].
#[derive(Debug)]
pub(crate) struct Drivers {
    irpc: irpc::IrpcDriver,
    compact: compact::CompactDriver,
    orion: orion::OrionDriver,
    moteus: moteus::MoteusDriver,
    queued: VecDeque<Queued>,
    /// The Unix ms of the bridge's zero (feedback timestamps).
    epoch: f64,
    /// Whose each frame is.
    router: Router,
    /// The devices by CAN id or node id (the first of each, in the
    /// engine's order): whose an iRPC message is.
    by_node: HashMap<u16, usize>,
}

impl Drivers {
    /// The drivers for `devices` (the engine's, in its order): the iRPC
    /// client as `client` says, each joint in its own wire version; every
    /// driver's requests wait `client.timeout` and are sent again up to
    /// `client.retries` times (an Orion command waits `orion_command_timeout`).
    ///
    /// # Errors
    /// The iRPC client's refusal of `client` (a node id beyond 11 bits).
    /// The Unix ms of the bridge's time zero, set again where the clock
    /// starts ([`crate::Bridge::anchor_epoch`]).
    pub(crate) fn set_epoch(&mut self, epoch: f64) {
        self.epoch = epoch;
    }

    pub(crate) fn new(
        client: ClientConfig,
        orion_command_timeout: Duration,
        epoch: f64,
        devices: &dyn Registry,
    ) -> Result<Self, motorwire_can::Error> {
        let mut irpc = irpc::IrpcDriver::new(client)?;
        let mut moteus = moteus::MoteusDriver::new(client.timeout, client.retries);
        for (k, j) in devices.iter().enumerate() {
            match j.device {
                Device::Irpc { wire } => irpc.set_wire(j.node, wire),
                Device::Moteus {
                    id, bus, period_ms, ..
                } => moteus.poll_every(k, id, bus, Duration::from_millis(u64::from(period_ms))),
                Device::Compact { .. } | Device::Orion(_) => {}
            }
        }
        let mut by_node = HashMap::new();
        for (k, j) in devices.iter().enumerate() {
            by_node.entry(j.node).or_insert(k);
        }
        Ok(Self {
            irpc,
            compact: compact::CompactDriver::new(client.timeout, client.retries),
            orion: orion::OrionDriver::new(client.timeout, client.retries, orion_command_timeout),
            moteus,
            queued: VecDeque::new(),
            epoch,
            router: Router::new(devices.iter().map(|j| (j.node, j.device))),
            by_node,
        })
    }

    /// Sends `order` for device `device` on CAN id `node` and awaits its
    /// answer; returns the driver's number for it. An order sent together
    /// with others ([`Order::sent_together`]) goes through
    /// [`Drivers::send_together`].
    ///
    /// # Errors
    /// Why it could not be sent, said for a person; nothing was queued.
    pub(crate) fn send(
        &mut self,
        now: Duration,
        device: usize,
        node: u16,
        order: Order,
    ) -> Result<u32, DeviceError> {
        match order {
            Order::Irpc(p) => self.irpc.send(now, device, node, p),
            Order::Compact(c) => {
                compact::command_frame(node, c).map(|f| self.compact.send(now, device, f))
            }
            Order::Orion(o) => self.send_together(now, &[(device, Order::Orion(o))]),
            Order::Moteus(c) => self.moteus.send(now, device, &c),
        }
    }

    /// Whether `order` cannot be sent now, and why (an Orion value or
    /// command before the controller's beacon).
    pub(crate) fn refuses(&self, order: &Order) -> Option<DeviceError> {
        match order {
            Order::Orion(o) => self.orion.refuses(*o),
            Order::Irpc(_) | Order::Compact(_) | Order::Moteus(_) => None,
        }
    }

    /// Sends `orders` (each device's, all of one line and joining the
    /// first: [`Order::joins`]) in one message; returns its number.
    ///
    /// # Errors
    /// Why it could not be sent; nothing was queued.
    pub(crate) fn send_together(
        &mut self,
        now: Duration,
        orders: &[(usize, Order)],
    ) -> Result<u32, DeviceError> {
        if let Some(e) = orders.first().and_then(|(_, o)| self.refuses(o)) {
            return Err(e);
        }
        let orion: Vec<(usize, OrionOrder)> = orders
            .iter()
            .filter_map(|(d, o)| match o {
                Order::Orion(o) => Some((*d, *o)),
                Order::Irpc(_) | Order::Compact(_) | Order::Moteus(_) => None,
            })
            .collect();
        if orion.len() != orders.len() || orion.is_empty() {
            return Err(DeviceError::NotTogether);
        }
        Ok(self.orion.send(now, &orion))
    }

    /// Whether the link `order` goes over is free for it now (the Orion
    /// controller takes one line at a time; a lost link takes the stop
    /// that is all it is written). `None`: a step with nothing to send.
    pub(crate) const fn link_free(&self, order: Option<&Order>) -> bool {
        match order {
            Some(Order::Orion(_)) => self.orion.lost() || self.orion.free(),
            Some(Order::Irpc(_) | Order::Compact(_) | Order::Moteus(_)) | None => true,
        }
    }

    /// The limits in force on device `device` changed (a SafetyLimits
    /// line taken): what a driver sends from now on, and what it sends
    /// again by itself (a moteus controller's held move), follows them.
    pub(crate) fn limits_changed(&mut self, device: usize, limits: &InForce) {
        self.moteus.limits_changed(device, limits);
    }

    /// Device `device`'s request in flight (`msg_id`, `order`) is given
    /// up: its answer, if it comes, is no longer awaited, and it is never
    /// sent again.
    pub(crate) fn forget(&mut self, device: usize, msg_id: u32, order: Order) {
        match order {
            Order::Irpc(_) => self.irpc.forget(msg_id),
            Order::Compact(_) => self.compact.forget(device),
            Order::Orion(_) => self.orion.forget(device),
            Order::Moteus(_) => self.moteus.forget(device),
        }
    }

    /// Takes back what `picked` devices had made and not yet handed out
    /// (a compact frame, an Orion line all of whose devices are picked):
    /// the devices whose request was taken back, and so never sent. An
    /// iRPC request is handed to the client, which puts it on the bus at
    /// once: never taken back.
    pub(crate) fn take_back_unsent(&mut self, picked: &BTreeSet<usize>) -> BTreeSet<usize> {
        let mut unsent: BTreeSet<usize> = picked
            .iter()
            .copied()
            .filter(|&d| self.compact.take_back_unsent(d) || self.moteus.take_back_unsent(d))
            .collect();
        if let Some(devices) = self.orion.take_back_unsent(|d| picked.contains(&d)) {
            unsent.extend(devices);
        }
        unsent
    }

    /// The next frame to put on the bus.
    pub(crate) fn poll_transmit(&mut self) -> Option<Frame> {
        self.irpc
            .poll_transmit()
            .or_else(|| self.compact.poll_transmit())
            .or_else(|| self.moteus.poll_transmit())
    }

    /// The next line for the Orion controller (without its newline).
    pub(crate) fn poll_line(&mut self) -> Option<String> {
        self.orion.poll_line()
    }

    /// The heartbeat to the bus's joints (iRPC's ArmReady). Whether it was
    /// queued (never on a bus without iRPC joints).
    pub(crate) fn heartbeat(&mut self) -> bool {
        self.irpc.heartbeat()
    }

    /// Whether any device hears the arm's heartbeat (iRPC joints).
    pub(crate) fn beats(&self) -> bool {
        self.irpc.beats()
    }

    /// Why `device` is offline, where its driver's link says so (the
    /// Orion controller before its beacon, lost, or being stopped after
    /// it came back).
    pub(crate) fn offline_reason(&self, device: Device) -> Option<&'static str> {
        match device {
            Device::Irpc { .. } | Device::Compact { .. } | Device::Moteus { .. } => None,
            Device::Orion(_) => self.orion.offline_reason(),
        }
    }

    /// The drivers' next deadline.
    pub(crate) fn deadline(&self) -> Option<Duration> {
        [
            self.irpc.deadline(),
            self.compact.deadline(),
            self.orion.deadline(),
            self.moteus.deadline(),
        ]
        .into_iter()
        .flatten()
        .min()
    }

    /// A frame from the bus at `now`, for whichever of `devices` it is.
    pub(crate) fn handle_frame(&mut self, now: Duration, frame: &Frame, devices: &dyn Registry) {
        match self.router.route(frame) {
            Route::CompactFeedback(ji) => {
                let Some(j) = devices.get(ji) else { return };
                let Device::Compact { hash, .. } = j.device else {
                    return;
                };
                match compact::feedback_record(frame, j.name, hash) {
                    Err(error) => self.tell(Happened::Bad {
                        report: Some(Event::BadFrame {
                            can_id: frame.id().to_string(),
                            error: error.to_string(),
                        }),
                    }),
                    Ok(record) => {
                        self.tell(Happened::Heard {
                            device: ji,
                            at: now,
                            up: true,
                        });
                        let motion = (
                            j.unit.to_degrees(f64::from(record.position)),
                            j.unit.to_degrees(f64::from(record.velocity)),
                        );
                        let ts = unix_ms(self.epoch, now);
                        let feedback = compact::feedback_to_wia(j.name, ts, &record);
                        self.tell(Happened::Reading {
                            device: ji,
                            at: now,
                            motion: Some(motion),
                            feedback: Some(Box::new(feedback)),
                        });
                        self.queued.push_back(Queued::CompactAck {
                            device: ji,
                            at: now,
                            stopped: !record
                                .status
                                .contains(motorwire_compact::StatusFlag::Enabled),
                        });
                    }
                }
            }
            Route::MoteusReply(ji) => self.moteus_reply(now, frame, ji, devices),
            // A compact or moteus command (ours, heard back on a second
            // socket): nothing to act on.
            Route::CompactCommand | Route::MoteusCommand => {}
            Route::Irpc => self.irpc.handle_frame(now, frame),
        }
    }

    /// Resends and time-outs of the iRPC client's requests due at `now`.
    pub(crate) fn handle_timeout(&mut self, now: Duration) {
        self.irpc.handle_timeout(now);
    }

    /// Whether `order`, in flight as request `msg_id`, is due to be sent
    /// again at `now` by its driver's retries (the iRPC client's: the
    /// orders whose path the engine holds to the limits when they go).
    pub(crate) fn resend_due(&self, msg_id: u32, order: &Order, now: Duration) -> bool {
        match order {
            Order::Irpc(_) => self.irpc.resend_due(msg_id, now),
            Order::Compact(_) | Order::Orion(_) | Order::Moteus(_) => false,
        }
    }

    /// Resends and time-outs of the compact commands due at `now` (after
    /// the iRPC client's have been taken, as the engine orders them).
    pub(crate) fn command_timeouts(&mut self, now: Duration) {
        for (device, ended) in self.compact.timeouts(now) {
            self.tell(Happened::Ended { device, ended });
        }
        for (device, ended) in self.moteus.timeouts(now) {
            self.tell(Happened::Ended { device, ended });
        }
    }

    /// The links' requests due at `now`: the Orion line in flight sent
    /// again or given up.
    pub(crate) fn link_timeouts(&mut self, now: Duration, devices: &dyn Registry) {
        if let Some(done) = self.orion.expire(now) {
            self.orion_done(&done, now, devices);
        }
    }

    /// The links' own lines due at `now`, once the engine has taken what
    /// [`Drivers::link_timeouts`] told: a recovery's stop, and a poll when
    /// none of `devices` on the controller's link is `busy` (a step of
    /// theirs in flight or ready to go).
    pub(crate) fn link_housekeeping(
        &mut self,
        now: Duration,
        devices: &dyn Registry,
        busy: impl Fn(usize) -> bool,
    ) {
        let on_link = |j: &DeviceView<'_>| j.device.link() == Link::Controller;
        let idle = devices.iter().any(|j| on_link(&j))
            && !devices.iter().filter(on_link).any(|j| busy(j.index));
        self.orion.housekeeping(now, idle);
        // Each moteus controller's poll: its held command, or the query.
        self.moteus.polls_due(now);
        self.tell_bounds_news(devices);
    }

    /// What became of each moteus controller's own bounds, told as events.
    fn tell_bounds_news(&mut self, devices: &dyn Registry) {
        for (device, news) in self.moteus.bounds_news() {
            let Some(j) = devices.get(device) else {
                continue;
            };
            let unit = |rev: f64| (!rev.is_nan()).then(|| j.unit.from_degrees(rev * 360.0));
            let event = match news {
                moteus_bounds::BoundsNews::Set { min, max } => Event::DeviceBounds {
                    motor_id: j.name.to_owned(),
                    min_position: unit(min),
                    max_position: unit(max),
                    error: None,
                },
                moteus_bounds::BoundsNews::Failed(error) => Event::DeviceBounds {
                    motor_id: j.name.to_owned(),
                    min_position: None,
                    max_position: None,
                    error: Some(error),
                },
            };
            self.tell(Happened::Event(event));
        }
    }

    /// One line from the Orion controller, received at `now`.
    pub(crate) fn handle_line(
        &mut self,
        now: Duration,
        line: &str,
        devices: &dyn Registry,
        map: &BusMap,
    ) {
        // Its motors held offline (it fell silent): heard again, it is
        // made safe and known before they are online.
        let offline = devices
            .iter()
            .any(|j| j.device.link() == Link::Controller && !j.online);
        let output = match self.orion.read(now, line, offline) {
            Ok(o) => o,
            Err(bad) => return self.orion_bad(bad),
        };
        self.orion_heard(now, devices);
        let applied = self
            .orion
            .apply(now, &output, map, unix_ms(self.epoch, now));
        if let Some(bad) = applied.bad {
            return self.orion_bad(bad);
        }
        if let Some((first, reported)) = applied.beacon {
            if reported {
                self.tell(Happened::Event(Event::OrionBeacon { first }));
            }
            self.orion_heard(now, devices);
            if first {
                self.tell(Happened::MayGo {
                    devices: orion_devices(devices),
                });
            }
        }
        for f in applied.feedback {
            let Some((ji, j)) = devices
                .iter()
                .enumerate()
                .find(|(_, j)| j.name == f.motor_id)
            else {
                continue;
            };
            let Device::Orion(motor) = j.device else {
                continue;
            };
            let degrees = j.unit.to_degrees(f.position);
            let motion = match motor.quantity() {
                Quantity::PositionDegrees => (degrees, 0.0),
                Quantity::Speed | Quantity::Actuator => (0.0, f.velocity),
            };
            self.tell(Happened::Reading {
                device: ji,
                at: now,
                motion: Some(motion),
                feedback: Some(Box::new(f)),
            });
        }
        if let Some(done) = applied.done {
            self.orion_done(&done, now, devices);
        }
        if applied.recovered {
            // Stopped and known: online again once what came before is
            // taken, nothing resumed.
            self.queued.push_back(Queued::EndOrionRecovery { at: now });
        }
    }

    /// A line from the Orion controller that could not be read (too long,
    /// not UTF-8), at `now`: reported like a bad line.
    pub(crate) fn handle_unreadable(&mut self, now: Duration, reason: &str) {
        let bad = self.orion.unreadable(now, reason);
        self.orion_bad(bad);
    }

    /// The link to the Orion controller ended at `now` (`error` says how):
    /// its motors are offline, and what was in flight has an unknown
    /// outcome. Whether it was up: nothing happens when it was lost
    /// already.
    pub(crate) fn link_lost(&mut self, now: Duration, error: &str, devices: &dyn Registry) -> bool {
        let Some(in_flight) = self.orion.link_lost(now) else {
            return false;
        };
        self.tell(Happened::Event(Event::OrionLinkLost {
            error: error.to_owned(),
        }));
        if let Some(done) = in_flight {
            self.orion_done(&done, now, devices);
        }
        self.tell(Happened::LinkLost {
            devices: orion_devices(devices),
            offline: format!("the link to the Orion controller is lost: {error}"),
            arrival: "the link to the Orion controller is lost".to_owned(),
        });
        true
    }

    /// The next thing to tell the engine. `map` and `devices`: the
    /// engine's, as they are now (an iRPC joint's feedback builds on its
    /// last).
    pub(crate) fn poll(&mut self, map: &BusMap, devices: &dyn Registry) -> Option<Happened> {
        loop {
            match self.queued.pop_front() {
                Some(Queued::Tell(h)) => return Some(h),
                Some(Queued::EndOrionRecovery { at }) => {
                    self.orion.end_recovery();
                    self.orion_heard(at, devices);
                }
                Some(Queued::CompactAck {
                    device,
                    at,
                    stopped,
                }) => {
                    // An emergency stop in flight waits for a record that
                    // shows it (sent again at its time-out otherwise).
                    if !stopped && self.compact.in_flight(device).is_some_and(compact::is_stop) {
                        continue;
                    }
                    if let Some(ended) = self.compact.acknowledged(device, at) {
                        return Some(Happened::Ended { device, ended });
                    }
                }
                Some(Queued::MoteusAck { device, at }) => {
                    if let Some(ended) = self.moteus.acknowledged(device, at) {
                        return Some(Happened::Ended { device, ended });
                    }
                }
                None => {
                    let event = self.irpc.poll_event()?;
                    // The first thing it tells is told now (nothing is
                    // queued before it); the rest wait their turn.
                    let mut first = None;
                    let queued = &mut self.queued;
                    let by_node = &self.by_node;
                    irpc::tell(event, map, devices, by_node, self.epoch, |h| {
                        if first.is_none() {
                            first = Some(h);
                        } else {
                            queued.push_back(Queued::Tell(h));
                        }
                    });
                    if first.is_some() {
                        return first;
                    }
                }
            }
        }
    }

    fn tell(&mut self, h: Happened) {
        self.queued.push_back(Queued::Tell(h));
    }

    /// A moteus controller's reply, device `ji`'s, at `now`: heard; its
    /// own stop if it just stopped itself (a fault by name, its
    /// watchdog); its reading; its command in flight acknowledged.
    fn moteus_reply(&mut self, now: Duration, frame: &Frame, ji: usize, devices: &dyn Registry) {
        let Some(j) = devices.get(ji) else { return };
        if frame.data().first() == Some(&motorwire_moteus::diagnostic::SERVER_DATA) {
            // Its diagnostic stream's answer: heard, and read for its
            // bounds; it reports no register and acknowledges nothing.
            match motorwire_moteus::diagnostic::decode(frame.id().raw(), frame.data()) {
                Ok(answer) => {
                    self.tell(Happened::Heard {
                        device: ji,
                        at: now,
                        up: true,
                    });
                    self.moteus.diagnostic_answer(ji, now, &answer);
                    self.tell_bounds_news(devices);
                }
                Err(e) => self.tell(Happened::Bad {
                    report: Some(Event::BadFrame {
                        can_id: frame.id().to_string(),
                        error: e.to_string(),
                    }),
                }),
            }
            return;
        }
        let reply = match moteus::reply(frame).and_then(moteus::plausible) {
            Ok(r) => r,
            Err(error) => {
                return self.tell(Happened::Bad {
                    report: Some(Event::BadFrame {
                        can_id: frame.id().to_string(),
                        error: error.to_string(),
                    }),
                });
            }
        };
        self.tell(Happened::Heard {
            device: ji,
            at: now,
            up: true,
        });
        if self.moteus.observe(ji, &reply)
            && let Some((reason, code)) = moteus::stopped_itself(&reply)
        {
            self.tell(Happened::StoppedItself {
                device: ji,
                at: now,
                reason,
                code,
            });
        }
        let ts = unix_ms(self.epoch, now);
        let feedback = moteus::feedback_to_wia(j.name, ts, j.unit, &reply);
        self.tell(Happened::Reading {
            device: ji,
            at: now,
            motion: moteus::motion(&reply),
            feedback: Some(Box::new(feedback)),
        });
        self.queued.push_back(Queued::MoteusAck {
            device: ji,
            at: now,
        });
    }

    /// Every Orion motor heard at `at`, online if the link is up.
    fn orion_heard(&mut self, at: Duration, devices: &dyn Registry) {
        let up = self.orion.up();
        for device in orion_devices(devices) {
            self.tell(Happened::Heard { device, at, up });
        }
    }

    /// A line of the controller's ended: each device whose step it carried
    /// is done, and what waits for the controller may go.
    fn orion_done(&mut self, done: &orion::Done, now: Duration, devices: &dyn Registry) {
        let ended = done.ended(now);
        for &device in &done.joints {
            self.tell(Happened::Ended {
                device,
                ended: ended.clone(),
            });
        }
        self.tell(Happened::MayGo {
            devices: orion_devices(devices),
        });
    }

    fn orion_bad(&mut self, bad: orion::BadLine) {
        let report = bad.report.map(|suppressed| Event::BadOrionLine {
            error: bad.error,
            suppressed,
        });
        self.tell(Happened::Bad { report });
    }
}

/// The indices of the Orion controller's motors among `devices`.
fn orion_devices(devices: &dyn Registry) -> Vec<usize> {
    devices
        .iter()
        .enumerate()
        .filter(|(_, j)| j.device.link() == Link::Controller)
        .map(|(i, _)| i)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use motorwire_compact::VelocityLimit;

    /// The engine's sources, every file of `engine/` but its tests.
    const ENGINE: [&str; 15] = [
        include_str!("../engine/mod.rs"),
        include_str!("../engine/input.rs"),
        include_str!("../engine/admit.rs"),
        include_str!("../engine/complete.rs"),
        include_str!("../engine/feedback.rs"),
        include_str!("../engine/jobs.rs"),
        include_str!("../engine/limits.rs"),
        include_str!("../engine/links.rs"),
        include_str!("../engine/motion.rs"),
        include_str!("../engine/motor_line.rs"),
        include_str!("../engine/phase.rs"),
        include_str!("../engine/queries.rs"),
        include_str!("../engine/stop.rs"),
        include_str!("../engine/timers.rs"),
        include_str!("../engine/watch.rs"),
    ];

    /// `Bridge::poll_timeout` keeps its deadline until an input comes,
    /// held against the engine's own source: every input goes through
    /// `Bridge::handle`, which clears it first (once, for all of them);
    /// every other `&mut self` method the engine's users can call is a
    /// way into `handle`, but those that only hand out what is queued
    /// (and clear it when they hand something out).
    #[test]
    fn every_entry_point_that_changes_the_bridge_forgets_its_next_deadline() {
        let engine = ENGINE.concat();
        let engine = engine.as_str();
        let mut entry_points = 0;
        let mut rest = engine;
        while let Some(at) = rest.find("\n    pub") {
            rest = rest.get(at + 1..).unwrap_or("");
            let head = rest.split('{').next().unwrap_or("");
            // `pub(super)`: the engine's own parts, not an entry point.
            if !head.contains("fn ")
                || !head.contains("&mut self")
                || head.trim_start().starts_with("pub(super)")
            {
                continue;
            }
            let name = head
                .split("fn ")
                .nth(1)
                .and_then(|n| n.split(['(', '<']).next())
                .unwrap_or("");
            let body = rest.get(head.len() + 1..).unwrap_or("");
            let own = body.split("\n    }").next().unwrap_or("");
            entry_points += 1;
            match name {
                "poll_output" => assert!(!own.contains("changed()"), "{name}"),
                "poll_transmit" | "poll_link_line" => assert!(
                    own.contains("self.changed();"),
                    "{name} clears the deadline when it hands something out"
                ),
                "handle" => assert!(
                    own.trim_start().starts_with("self.changed();"),
                    "Bridge::handle takes an input without clearing its next deadline"
                ),
                // A crate-private setting, before the start.
                "anchor_epoch" => assert!(own.trim_start().starts_with("self.changed();")),
                _ => assert!(
                    own.trim_start().starts_with("self.handle("),
                    "Bridge::{name} changes the bridge other than through Bridge::handle"
                ),
            }
        }
        // Nothing else forgets the deadline: it is done where inputs come.
        assert_eq!(engine.matches("self.changed();").count(), 4);
        assert!(entry_points >= 20, "{entry_points} entry points found");
    }

    /// The layering this module promises, held against the engine's own
    /// source: it names no dialect (no variant of [`Device`], [`Order`]
    /// or the bus map's `Target`, no driver of [`Drivers`] by name), and
    /// it is one `impl Bridge` in one file.
    #[test]
    fn the_engine_asks_no_dialect_question() {
        let code: String = ENGINE
            .concat()
            .lines()
            .map(|l| l.split("//").next().unwrap_or(""))
            .collect::<Vec<_>>()
            .join("\n");
        for dialect in ["Irpc", "Compact", "Orion"] {
            for name in [
                format!("Device::{dialect}"),
                format!("Order::{dialect}"),
                format!("Target::{dialect}"),
            ] {
                assert!(!code.contains(&name), "the engine names {name}");
            }
        }
        // The lifecycle it drives is its own ([`Lifecycle`]), said in each
        // dialect's terms by the device layer.
        for payload in [
            "Reset",
            "Configure",
            "Activate",
            "Deactivate",
            "ConfigureTelemetry",
        ] {
            let named = format!("Payload::{payload}");
            assert!(!code.contains(&named), "the engine names {named}");
        }
        for driver in [".irpc", ".compact", ".orion"] {
            let named = format!("drivers{driver}");
            assert!(!code.contains(&named), "the engine reaches {named}");
        }
        // One `impl Bridge` a file of the engine, each its concern.
        for file in ENGINE {
            assert_eq!(file.matches(concat!("impl ", "Bridge {")).count(), 1);
        }
        for other in [
            include_str!("../job.rs"),
            include_str!("../joints.rs"),
            include_str!("../arrival.rs"),
            include_str!("mod.rs"),
            include_str!("irpc.rs"),
            include_str!("compact.rs"),
            include_str!("orion.rs"),
        ] {
            assert!(!other.contains(concat!("impl ", "Bridge {")));
        }
    }

    const HASH: MotorHash = MotorHash(0x1234_5678);

    fn compact() -> Device {
        Device::Compact {
            feedback_node: 0x31,
            hash: HASH,
        }
    }

    /// A stop is each dialect's own: Deactivate for a joint, the
    /// emergency-stop flag for a compact device, the stop command for the
    /// Orion controller; what the release brings back goes to joints only.
    #[test]
    fn each_dialect_is_stopped_in_its_own_way() {
        let irpc = Device::Irpc {
            wire: WireVersion::V2_1,
        };
        let stop = [Lifecycle::Deactivate];
        assert_eq!(
            irpc.lifecycle_orders(&stop, 7),
            [Order::Irpc(Payload::Deactivate)]
        );
        // Telemetry where the wire version has it (v2.1 on), nothing on v2.0.
        let telemetry = [Lifecycle::Telemetry { rate_hz: 50 }];
        let [Order::Irpc(Payload::ConfigureTelemetry(t))] =
            irpc.lifecycle_orders(&telemetry, 7)[..]
        else {
            panic!("one ConfigureTelemetry");
        };
        assert_eq!(
            (t.mode, t.rate_hz),
            (motorwire_irpc::TelemetryMode::Periodic, 50)
        );
        let v20 = Device::Irpc {
            wire: WireVersion::V2_0,
        };
        assert_eq!(v20.lifecycle_orders(&telemetry, 7), []);
        assert_eq!(
            Order::Irpc(Payload::ConfigureTelemetry(t)).lifecycle(),
            Some(telemetry[0])
        );
        let [Order::Compact(c)] = compact().lifecycle_orders(&stop, 7)[..] else {
            panic!("one compact order");
        };
        assert_eq!(c.motor, HASH);
        assert_eq!(c.timestamp_ms, 7);
        assert_eq!(c.control_mode, CompactMode::Disabled);
        assert!(c.flags.contains(Flags::EMERGENCY_STOP));
        assert_eq!(
            Device::Orion(Motor::Turntable)
                .lifecycle_orders(&[Lifecycle::Reset, Lifecycle::Deactivate], 7),
            [Order::Orion(OrionOrder::Command(ArmCommand::Stop))]
        );
        // The release's Activate has nothing to send to either.
        assert_eq!(compact().lifecycle_orders(&[Lifecycle::Activate], 7), []);
        assert_eq!(
            Device::Orion(Motor::GrasperRotation).lifecycle_orders(&[Lifecycle::Activate], 7),
            []
        );
        // The deadman: a held setpoint to 0; a joint holds none.
        assert_eq!(irpc.hold_still(7), None);
        assert_eq!(
            Device::Orion(Motor::Turntable).hold_still(7),
            Some(Order::Orion(OrionOrder::Set(Motor::Turntable, 0.0)))
        );
        let Some(Order::Compact(h)) = compact().hold_still(9) else {
            panic!("a compact hold");
        };
        assert_eq!((h.control_mode, h.setpoint), (CompactMode::Velocity, 0.0));
        assert!(!h.flags.contains(Flags::EMERGENCY_STOP));
        assert!(irpc.supports(Capability::Reset) && irpc.speaks(PayloadKind::ConfigureTelemetry));
        assert!(!compact().supports(Capability::Trajectory));
        assert!(!Device::Orion(Motor::Turntable).supports(Capability::Reset));
        assert_eq!(irpc.who(0x12), "node 0x12");
        assert_eq!(
            Device::Orion(Motor::Turntable).who(orion::ORION_NODE),
            "the Orion arm controller (ID 32)"
        );
    }

    /// What an order reaches is read in degrees whatever the motor's unit:
    /// a compact command in radians at 1 rad, limited to 0.5 rad/s.
    #[test]
    fn an_orders_reach_is_in_degrees() {
        let c = CompactCommand {
            motor: HASH,
            timestamp_ms: 0,
            control_mode: CompactMode::Position,
            flags: Flags::REQUIRE_ACK,
            setpoint: 1.0,
            velocity_limit: Some(VelocityLimit::from_units_per_s(0.5).unwrap()),
            torque_limit: None,
        };
        let r = Order::Compact(c).reach(AngleUnit::Radians);
        assert!(
            (r.target.unwrap() - 1f64.to_degrees()).abs() < 1e-9,
            "{r:?}"
        );
        assert!(
            (r.speed.unwrap() - 0.5f64.to_degrees()).abs() < 1e-3,
            "{r:?}"
        );
        let set = Order::Orion(OrionOrder::Set(Motor::GrasperHorizontalServo, 30.0));
        assert_eq!(
            set.reach(AngleUnit::Degrees),
            Reach {
                target: Some(30.0),
                speed: None
            }
        );
        assert!(set.is_position_move() && !set.holds_setpoint());
        let spin = Order::Orion(OrionOrder::Set(Motor::Turntable, 200.0));
        assert!(spin.holds_setpoint() && !spin.is_position_move());
        assert_eq!(spin.reach(AngleUnit::Degrees), Reach::default());
    }

    /// A held setpoint arms the deadman for the motor's command timeout
    /// and moves until then; 0 holds the device still, with no deadman; a
    /// compact emergency stop cuts the move short.
    #[test]
    fn a_held_setpoint_arms_the_deadman_and_zero_does_not() {
        let cx = Context {
            at: Duration::from_millis(1000),
            motion: Some((10.0, 0.0, 0.0)),
            unit: AngleUnit::Degrees,
            max_velocity: Some(100.0),
            max_acceleration: Some(1000.0),
            command_timeout: Some(Duration::from_millis(200)),
            planned: None,
        };
        let spin = Order::Orion(OrionOrder::Set(Motor::Turntable, 200.0)).effect(&cx);
        assert_eq!(spin.deadman, Some(Duration::from_millis(1200)));
        assert_eq!(spin.moving, Moving::Until(Duration::from_millis(1200)));
        assert_eq!(spin.target, Some(None));
        let still = Order::Orion(OrionOrder::Set(Motor::Turntable, 0.0)).effect(&cx);
        assert_eq!(still.deadman, None);
        assert_eq!(still.moving, Moving::Until(Duration::from_millis(1000)));
        let Some(Order::Compact(stop)) = compact()
            .lifecycle_orders(&[Lifecycle::Deactivate], 0)
            .first()
            .copied()
        else {
            panic!("a compact stop");
        };
        let e = Order::Compact(stop).effect(&cx);
        assert_eq!(e.moving, Moving::AtMost(Duration::from_millis(1000)));
        assert_eq!(
            (e.deadman, e.target),
            (None, Some(None)),
            "no target any more"
        );
        // A compact move of 90 degrees at the limit's 100 deg/s and 1000
        // deg/s²: 0.9 s + 0.1 s.
        let mv = CompactCommand {
            setpoint: 100.0,
            control_mode: CompactMode::Position,
            flags: Flags::REQUIRE_ACK,
            ..stop
        };
        let e = Order::Compact(mv).effect(&cx);
        assert_eq!(e.target, Some(Some(100.0)));
        assert_eq!(e.moving, Moving::Until(Duration::from_millis(2000)));
    }

    /// A moteus segment brakes within the segment's deceleration where it
    /// is tighter than its acceleration (moteus has one limit for both).
    #[test]
    fn a_moteus_segment_brakes_within_the_tighter_limit() {
        let moteus = Device::Moteus {
            id: 1,
            bus: 0,
            period_ms: 10,
            brake: false,
        };
        let p = SetTargetPayloadV2::trapezoidal(36.0, 180.0, 720.0);
        let limit = |p: SetTargetPayloadV2| match moteus.segment_order(p, None) {
            Some(Order::Moteus(MoteusCommand::Position(a))) => a.accel_limit,
            other => panic!("{other:?}"),
        };
        assert_eq!(limit(p), Some(2.0));
        assert_eq!(limit(p.with_deceleration(360.0)), Some(1.0));
        assert_eq!(limit(p.with_deceleration(0.0)), Some(2.0));
    }
}
