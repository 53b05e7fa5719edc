#![doc = include_str!("../README.md")]

mod engine;
mod error;
mod runtime;
pub mod sim;

pub use engine::{Bridge, BridgeConfig, BridgeStats, JointView, Origin, Output};
pub use error::BridgeError;
pub use runtime::{InputSender, MAX_LINE, ReadLine, Runner, feed, read_line};
