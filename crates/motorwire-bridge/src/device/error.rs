//! Why the device layer could not send an order or read a frame: one typed
//! error, said for a person where it is told (a step's report, a bad-frame
//! event).

use motorwire_compact::MotorHash;

use super::DeviceId;

/// Why an order could not be sent (nothing was queued), or a frame could
/// not be read for its device.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub(crate) enum DeviceError {
    /// The iRPC client's refusal: a payload its wire version lacks, a
    /// non-finite value, its in-flight limit.
    #[error("{0}")]
    Client(motorwire_can::Error),
    /// A CAN id or frame the bus cannot carry.
    #[error("{0}")]
    Frame(motorwire_can::Error),
    /// The compact codec's refusal of a command or a record.
    #[error("{0}")]
    Compact(motorwire_compact::Error),
    /// moteus's codec's refusal of a call.
    #[error("{0}")]
    MoteusCall(motorwire_moteus::CallError),
    /// moteus's codec's refusal of a reply.
    #[error("{0}")]
    MoteusReply(motorwire_moteus::ReplyError),
    /// A reply in a mode no moteus controller has.
    #[error("mode {0} is no moteus mode (0 to 15)")]
    NoMoteusMode(i64),
    /// A compact feedback record of another motor.
    #[error("feedback for motor hash {:08x}, not {motor}'s {:08x}", .got.0, .want.0)]
    OtherMotor {
        /// Whose it is.
        got: MotorHash,
        /// The device's motor.
        motor: String,
        /// Its hash.
        want: MotorHash,
    },
    /// An order for a moteus controller to a device that is none.
    #[error("device {0} is not a moteus controller")]
    NotMoteus(DeviceId),
    /// The link to the Orion controller is lost: only its stop goes.
    #[error("the link to the Orion controller is lost")]
    OrionLinkLost,
    /// Orders sent together that are not all the Orion controller's.
    #[error("only the Orion controller takes orders together")]
    NotTogether,
    /// The Orion controller has no torque off for its servo.
    #[error(
        "the Orion arm controller has no torque off for its servo {0}: it holds it where it was sent (hold or stop it where it stands)"
    )]
    NoTorqueOff(&'static str),
    /// A servo's write the bridge cannot build: the servo codec's refusal,
    /// a goal its registers cannot hold, or a hold of a servo whose
    /// position is not known.
    #[error("{0}")]
    ServoWrite(String),
}
