//! The bridge's one error type.

/// Why a bridge could not be made or could not go on.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum BridgeError {
    /// The bus map names no motor the bridge drives: there is nothing
    /// to bridge to.
    #[error("the bus map has no motor to bridge to")]
    NoJoints,
    /// The bus map names more motors than one bridge serves
    /// ([`crate::Bridge::MAX_DEVICES`]): refused before anything is sent.
    #[error(
        "the bus map has {count} motors; a bridge serves at most {limit} \
         (one CAN bus carries no more at their feedback rates): split them across buses, a bridge each"
    )]
    TooManyDevices {
        /// The motors the map names.
        count: usize,
        /// The most a bridge serves.
        limit: usize,
    },
    /// A configuration value that cannot work.
    #[error("invalid bridge configuration: {0}")]
    Config(&'static str),
    /// A thread of the runner (the bus's reader, the Orion link's reader
    /// or writer) could not be started.
    #[error("starting the {0} thread: {1}")]
    Thread(&'static str, std::io::Error),
    /// The bus failed (sending, or the client's configuration).
    #[error("bus: {0}")]
    Bus(#[from] motorwire_can::Error),
    /// A simulated joint could not be made.
    #[cfg(feature = "sim")]
    #[error("simulated joint: {0}")]
    Sim(#[from] motorwire_sim::SimError),
    /// The simulated servos of a serial port could not be made.
    #[cfg(feature = "sim")]
    #[error("simulated servos: {0}")]
    SimServos(String),
    /// The simulated arm found work due at one instant again and again
    /// without the bridge's clock moving on (a timer that stays due after
    /// it was handled): given up rather than spun on forever.
    #[error(
        "the simulated arm made no progress at {at_ms} ms: work was still due after {rounds} rounds at that instant"
    )]
    Stalled {
        /// The simulated time, in ms.
        at_ms: u64,
        /// The rounds run at that instant.
        rounds: u32,
    },
}
