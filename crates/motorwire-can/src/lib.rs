#![doc = include_str!("../README.md")]

mod bus;
pub mod candump;
pub mod client;
mod error;
mod frame;
pub mod isotp;
mod sim;
#[cfg(all(feature = "socketcan", target_os = "linux"))]
pub mod socketcan;

pub use bus::{AsyncCanBus, CanBus, Received};
pub use error::Error;
pub use frame::{CLASSIC_MAX_LEN, CanId, FD_LENGTHS, FD_MAX_LEN, Frame, fd_len};
pub use sim::{Clock, FaultStats, Faults, SimBus, SimConfig, SimPort};
