//! The joint registry: who each joint is, whether it is heard, what it is
//! doing, and the queue of steps waiting for it.

use std::collections::VecDeque;
use std::time::Duration;

use motorwire_irpc::LifecycleState;
use motorwire_translate::AngleUnit;
use motorwire_wia::MotorFeedback;

use crate::device::Device;
use crate::output::Origin;

/// A step of a job waiting for (or running on) a joint.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct StepRef {
    pub(crate) job: u64,
    pub(crate) axis: usize,
}

/// A part sent and never answered: the joint may have executed it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Unresolved {
    pub(crate) origin: Option<Origin>,
    pub(crate) line: u64,
    /// The move's target (degrees).
    pub(crate) target: f64,
}

#[derive(Debug)]
pub(crate) struct Joint {
    pub(crate) name: String,
    /// Its CAN id (iRPC node, compact command id; the Orion motors'
    /// [`crate::device::orion::ORION_NODE`], which no frame has).
    pub(crate) node: u16,
    /// Its dialect, and what addresses it there.
    pub(crate) device: Device,
    /// The unit of its positions in the bus map (and in WIA lines).
    pub(crate) unit: AngleUnit,
    pub(crate) last_heard: Option<Duration>,
    pub(crate) online: bool,
    pub(crate) state: Option<LifecycleState>,
    /// Whether the bridge last made it Active (its own acked Activate or
    /// Deactivate, or the joint's JointStatus, whichever came last).
    pub(crate) active: bool,
    pub(crate) feedback: Option<MotorFeedback>,
    /// Its position and velocity (degrees) as last reported.
    pub(crate) motion: Option<(f64, f64)>,
    /// The target of its last acked move (degrees).
    pub(crate) target: Option<f64>,
    /// Until when its last acked move runs (as the bridge plans it).
    pub(crate) moving_until: Duration,
    /// Steps waiting to be sent, oldest first.
    pub(crate) queue: VecDeque<StepRef>,
    /// The step whose request is in flight.
    pub(crate) busy: Option<StepRef>,
    pub(crate) unresolved: Option<Unresolved>,
    /// The deadman: when a velocity or torque setpoint it holds must be
    /// renewed by, or it is brought to a stop.
    pub(crate) deadman: Option<Duration>,
    /// It faulted or rebooted (why): nothing but a reset line is sent to it.
    pub(crate) needs_reset: Option<String>,
    /// A Reset the bridge sent is under way (its `Unconfigured` is no
    /// reboot).
    pub(crate) resetting: bool,
    /// Its busy step (a trajectory's) sends its next payload then.
    pub(crate) wake: Option<Duration>,
    /// The last move the gate planned for it: from (position, velocity)
    /// in degrees, the payload, and how long the joint's plan takes. When
    /// its Ack comes from the same state, its arrival time is this plan's
    /// (the same inputs make the same plan), not a second planning.
    pub(crate) planned: Option<((f64, f64), motorwire_irpc::SetTargetPayloadV2, Duration)>,
}

impl Joint {
    pub(crate) fn new(name: String, node: u16, device: Device, unit: AngleUnit) -> Self {
        Self {
            name,
            node,
            device,
            unit,
            last_heard: None,
            online: device.online_at_start(),
            state: None,
            active: device.active_at_start(),
            feedback: None,
            motion: None,
            target: None,
            moving_until: Duration::ZERO,
            queue: VecDeque::new(),
            busy: None,
            unresolved: None,
            deadman: None,
            needs_reset: None,
            resetting: false,
            wake: None,
            planned: None,
        }
    }
}
