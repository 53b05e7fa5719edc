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
//! way for every device. A driver sees the engine's devices read-only,
//! through [`Registry`] ([`DeviceView`]: name, address, dialect, unit,
//! whether heard, last feedback), never the engine's own state. The
//! dialects' own vocabularies stay in their drivers: the lifecycle the
//! engine drives is its own ([`Lifecycle`]: reset, configure, activate,
//! deactivate, telemetry), which each device says in its terms
//! ([`Device::lifecycle_orders`]: iRPC payloads, a compact or moteus stop,
//! the Orion stop, or nothing); the state a device says it is in is
//! the engine's own too ([`DeviceState`], mapped from an iRPC joint's
//! `JointStatus` by its driver); the moves the bridge plans (an iRPC
//! joint's, planned together across a multi-axis line, and a trajectory's
//! segments) are [`plan::Move`]s, gated, planned and checked by [`plan`]
//! over motorwire-translate's gate; what cannot be sent is a typed
//! [`DeviceError`]; request lines (telemetry, calibration)
//! exist for the devices that say [`Capability::Requests`], and their
//! orders ([`Ask`], the message a device must have for them a [`Needs`])
//! and answers are the iRPC driver's ([`irpc::request`], [`Answer`]).
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
//! 2. a variant of [`Device`] and of [`Order`], each match of this module
//!    answered for it (the compiler lists them: `mod.rs` for the device,
//!    `order.rs` for its orders, [`Device::lifecycle_orders`] for the
//!    lifecycle), and a field of [`Drivers`] (`drivers.rs`: its frames
//!    routed in [`Drivers::handle_frame`], its deadlines in
//!    [`Drivers::requests_deadline`], [`Drivers::commands_deadline`] or
//!    [`Drivers::link_deadline`]), reading the devices through [`Registry`];
//!    what it cannot send or read is a variant of [`DeviceError`];
//! 3. its bus map entry (`motorwire_translate::Target`) and its translation
//!    (`Device::single_order`);
//! 4. its simulated device (`motorwire_sim`, attached by
//!    `crate::sim::SimulatedArm`, the `sim` feature) and its fixtures.
//!
//! The engine is not touched. The every-dialect property test in
//! `tests/invariants.rs` then holds the new dialect to every invariant the
//! others keep.

use std::collections::{BTreeSet, HashMap, HashSet, VecDeque};
use std::fmt;
use std::time::Duration;

use motorwire_can::Frame;
use motorwire_can::client::ClientConfig;
use motorwire_compact::{CompactCommand, ControlMode as CompactMode, Flags, MotorHash};
use motorwire_irpc::{Payload, PayloadKind, WireVersion};
use motorwire_orion::{ArmCommand, Motor, Quantity};
use motorwire_translate::{
    AngleUnit, BusMap, MoteusCommand, Refusal, Report, ServoCommand, Target, to_compact, to_moteus,
    to_orion_motor, to_servo,
};
use motorwire_wia::{MotorCommand, MotorFeedback};
use serde_json::Value;

use crate::output::Event;

/// A device: its place in the engine's order, which is also its view's
/// in the [`Registry`]. It lives here, with the registry a driver reads,
/// so that the drivers (which key what they have in flight by device) and
/// the engine (which holds the devices' state) name a device by one type
/// below both; and a count, a line number or an axis's place in its job
/// cannot be taken for one. Made by the holder of the devices (and the
/// registry's walk over them) for the places there are.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub(crate) struct DeviceId(usize);

impl DeviceId {
    /// The device at place `index` of the engine's order (the holder of
    /// the devices, and tests, make them).
    pub(crate) const fn at(index: usize) -> Self {
        Self(index)
    }

    /// Its place in the engine's order.
    pub(crate) const fn index(self) -> usize {
        self.0
    }
}

impl fmt::Display for DeviceId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        self.0.fmt(f)
    }
}

/// What a driver reads of the devices the engine keeps, in the engine's
/// order: read only (the engine's registry implements it; a driver never
/// sees, nor writes, the engine's own state of a device).
pub(crate) trait Registry {
    /// How many devices there are.
    fn count(&self) -> usize;
    /// Device `id` as a driver sees it.
    fn view(&self, id: DeviceId) -> Option<DeviceView<'_>>;
}

impl dyn Registry + '_ {
    /// Device `id`, if there is one.
    pub(crate) fn get(&self, id: DeviceId) -> Option<DeviceView<'_>> {
        self.view(id)
    }

    /// Every device, in order.
    pub(crate) fn iter(&self) -> impl Iterator<Item = DeviceView<'_>> + '_ {
        (0..self.count()).filter_map(|k| self.view(DeviceId(k)))
    }
}

/// One device as its driver sees it: who it is, where, in what dialect and
/// unit, whether it is heard, and what it last reported.
#[derive(Debug, Clone, Copy)]
pub(crate) struct DeviceView<'a> {
    /// Its place in the engine's order.
    pub(crate) id: DeviceId,
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
mod drivers;
mod error;
mod frames;
pub(crate) mod irpc;
pub(crate) mod moteus;
mod moteus_bounds;
mod order;
pub(crate) mod orion;
pub(crate) mod plan;
pub(crate) mod servo;

pub(crate) use drivers::*;

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
    /// A serial bus servo (Feetech or Dynamixel) on one of the map's
    /// serial ports.
    Servo(ServoAddress),
}

/// What the engine's questions need of a servo (its driver keeps its
/// model and calibration): who makes it, where it is, what its stop does.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct ServoAddress {
    pub(crate) vendor: motorwire_translate::ServoVendor,
    /// Its port's index among the map's servo ports.
    pub(crate) port: u8,
    pub(crate) id: u8,
    /// Whether its stop holds it (torque on) rather than turning its
    /// torque off.
    pub(crate) stop_holds: bool,
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
            Self::Compact { .. } | Self::Orion(_) | Self::Servo(_) => false,
        }
    }

    /// Whether it has the message a line's ask `needs` (an iRPC joint: in
    /// its wire version; a moteus controller: a reset; the others: none).
    pub(crate) fn speaks(self, needs: Needs) -> bool {
        match self {
            Self::Irpc { wire } => wire.tag_of(needs.0).is_some(),
            Self::Moteus { .. } => needs == Needs::RESET,
            Self::Compact { .. } | Self::Orion(_) | Self::Servo(_) => false,
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
                .filter(|p| self.speaks(Needs(p.kind())))
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
            Self::Servo(t) => stops().map(|_| Order::Servo(servo_stop(t))).collect(),
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
            // A servo holds no velocity or torque setpoint (it takes
            // position goals alone).
            Self::Servo(_) => None,
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
            (Self::Servo(_), Hold) => Order::Servo(ServoCommand::Hold),
            (Self::Servo(_), Free) => Order::Servo(ServoCommand::TorqueOff),
            (Self::Servo(t), Stop) => Order::Servo(servo_stop(t)),
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
            Self::Servo(_) => Some(to_servo(map, cmd).map(|t| Single {
                order: Order::Servo(t.value),
                target: match t.value {
                    ServoCommand::Goal { position, .. } => Some(position),
                    ServoCommand::Hold | ServoCommand::TorqueOff => None,
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
    pub(crate) fn segment_order(self, m: plan::Move, max_torque: Option<f64>) -> Option<Order> {
        let p = m.terms();
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
            Self::Compact { .. } | Self::Orion(_) | Self::Servo(_) => None,
        }
    }

    /// Who it is, as a message about an unanswered request says it.
    pub(crate) fn who(self, node: u16) -> String {
        match self {
            Self::Irpc { .. } | Self::Compact { .. } => format!("node 0x{node:02X}"),
            Self::Orion(_) => orion::LABEL.to_owned(),
            Self::Moteus { id, bus, .. } => format!("moteus id {id} on bus {bus}"),
            Self::Servo(t) => format!("{} servo id {} on port {}", t.vendor.name(), t.id, t.port),
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
            Self::Compact { .. } | Self::Orion(_) | Self::Moteus { .. } | Self::Servo(_) => None,
        }
    }

    pub(crate) const fn dialect_name(self) -> &'static str {
        match self {
            Self::Irpc { .. } => "iRPC",
            Self::Compact { .. } => "compact",
            Self::Orion(_) => "Orion",
            Self::Moteus { .. } => "moteus",
            Self::Servo(t) => match t.vendor {
                motorwire_translate::ServoVendor::Feetech => "Feetech",
                motorwire_translate::ServoVendor::Dynamixel => "Dynamixel",
            },
        }
    }
}

/// A servo's stop: its torque off, or a hold where the map says `stop =
/// "hold"`.
const fn servo_stop(t: ServoAddress) -> ServoCommand {
    if t.stop_holds {
        ServoCommand::Hold
    } else {
        ServoCommand::TorqueOff
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
    Servo(ServoCommand),
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
    pub(crate) planned: Option<(Kinematics, plan::Move, Duration)>,
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
    /// The lifecycle step it is, if it is one (what the release sends a
    /// joint again).
    pub(crate) fn lifecycle(&self) -> Option<Lifecycle> {
        match self {
            Self::Irpc(p) => Lifecycle::of(p),
            Self::Compact(_) | Self::Orion(_) | Self::Moteus(_) | Self::Servo(_) => None,
        }
    }
}

/// Where a device is in its lifecycle, as it last said, in no dialect's
/// terms: an iRPC joint's `JointStatus` state is mapped to it by its
/// driver; a dialect that reports no lifecycle leaves it unknown.
///
/// ```
/// use motorwire_bridge::DeviceState;
/// assert!(DeviceState::Active.takes_motion());
/// assert!(!DeviceState::Inactive.takes_motion());
/// assert_eq!(DeviceState::Error.name(), "error");
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum DeviceState {
    /// Not configured: just booted, or reset.
    Unconfigured,
    /// Configured, its torque off: it takes no motion.
    Inactive,
    /// Up: it takes motion.
    Active,
    /// Calibrating itself.
    Calibrating,
    /// Faulted.
    Error,
}

impl DeviceState {
    /// Whether a device in this state executes motion.
    #[must_use]
    pub const fn takes_motion(self) -> bool {
        matches!(self, Self::Active)
    }

    /// The state in one lower-case word: `unconfigured`, `inactive`,
    /// `active`, `calibrating` or `error`.
    #[must_use]
    pub const fn name(self) -> &'static str {
        match self {
            Self::Unconfigured => "unconfigured",
            Self::Inactive => "inactive",
            Self::Active => "active",
            Self::Calibrating => "calibrating",
            Self::Error => "error",
        }
    }
}

impl std::fmt::Display for DeviceState {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// The message a device must have for a line's ask of it (a reset, a
/// request, a calibration), in its dialect's terms: the engine passes it
/// to [`Device::speaks`] and reads nothing of it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Needs(PayloadKind);

impl Needs {
    /// A reset.
    pub(crate) const RESET: Self = Self(PayloadKind::Reset);
}

/// A line's ask of a device that it answers: the message the device must
/// have, the order asking for it, what the line waits for, and the
/// message's name for a refusal.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Ask {
    pub(crate) needs: Needs,
    pub(crate) order: Order,
    pub(crate) awaits: AwaitKind,
    pub(crate) what: &'static str,
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
    CompactFeedback(DeviceId),
    /// A compact command (the bridge's own, heard back on a second
    /// socket): nothing to act on.
    CompactCommand,
    /// A moteus controller's reply: device `.0`'s.
    MoteusReply(DeviceId),
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
    compact_feedback: HashMap<u32, DeviceId>,
    /// The CAN ids of compact commands.
    compact_command: HashSet<u32>,
    /// Moteus controllers by (CAN prefix, id): the first of each.
    moteus: HashMap<(u16, u8), DeviceId>,
}

impl Router {
    /// A router for `devices` (each device, its CAN id and dialect, in
    /// the engine's order).
    pub(crate) fn new(devices: impl Iterator<Item = (DeviceId, u16, Device)>) -> Self {
        let mut router = Self::default();
        for (k, node, device) in devices {
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
                Device::Irpc { .. } | Device::Orion(_) | Device::Servo(_) => {}
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
        device: DeviceId,
        at: Duration,
        up: bool,
    },
    /// Device `device` reported at `at`: its position and velocity
    /// (degrees) where the report has them, and its WIA feedback.
    Reading {
        device: DeviceId,
        at: Duration,
        motion: Option<(f64, f64)>,
        feedback: Option<Box<MotorFeedback>>,
    },
    /// Device `device`'s request in flight ended.
    Ended { device: DeviceId, ended: Ended },
    /// Device `device` reported its lifecycle state and error code.
    Lifecycle {
        device: DeviceId,
        state: DeviceState,
        code: u16,
    },
    /// Device `device` stopped itself at `at`: why, and its code.
    StoppedItself {
        device: DeviceId,
        at: Duration,
        reason: String,
        code: u16,
    },
    /// A message from device `device` that a request line may wait for.
    Answer { device: DeviceId, answer: Answer },
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
        devices: Vec<DeviceId>,
        offline: String,
        arrival: String,
    },
    /// What waits for `devices` may go now: their link is free, or up.
    MayGo { devices: Vec<DeviceId> },
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
        device: DeviceId,
        at: Duration,
        /// The record says the device is not driving (`enabled` clear):
        /// only such a record acknowledges an emergency stop (a record the
        /// device sent before the stop reached it says nothing of it).
        stopped: bool,
    },
    /// A moteus controller's reply acknowledges its command in flight,
    /// once the engine has taken the reply.
    MoteusAck {
        device: DeviceId,
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
            Target::Servo(t) => (
                u16::from(t.id),
                Self::Servo(ServoAddress {
                    vendor: t.vendor,
                    port: t.port,
                    id: t.id,
                    stop_holds: t.stop_holds,
                }),
            ),
        })
    }

    /// The link it is reached over.
    pub(crate) const fn link(self) -> Link {
        match self {
            Self::Irpc { .. } | Self::Compact { .. } | Self::Moteus { .. } | Self::Servo(_) => {
                Link::Bus
            }
            Self::Orion(_) => Link::Controller,
        }
    }

    /// Its order for an arm-wide `command` (fold, unfold), if it takes one.
    pub(crate) const fn arm_order(self, command: ArmCommand) -> Option<Order> {
        match self {
            Self::Orion(_) => Some(Order::Orion(OrionOrder::Command(command))),
            Self::Irpc { .. } | Self::Compact { .. } | Self::Moteus { .. } | Self::Servo(_) => None,
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

#[cfg(test)]
mod tests;
