//! The bridge's one error type.

/// Why a bridge could not be made or could not go on.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum BridgeError {
    /// The bus map names no iRPC joint: there is nothing to bridge to.
    #[error("the bus map has no iRPC joint to bridge to")]
    NoJoints,
    /// A configuration value that cannot work.
    #[error("invalid bridge configuration: {0}")]
    Config(&'static str),
    /// The bus failed (sending, or the client's configuration).
    #[error("bus: {0}")]
    Bus(#[from] motorwire_can::Error),
    /// A simulated joint could not be made.
    #[error("simulated joint: {0}")]
    Sim(#[from] motorwire_sim::SimError),
}
