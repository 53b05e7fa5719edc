#![doc = include_str!("../README.md")]
//!
//! [`record::Recorder`] is a [`motorwire_bridge::tap::Tap`]: given to a
//! [`motorwire_bridge::Runner`] (`with_recorder`), it writes every line and
//! frame of the session in the field's formats (`candump -L` and JSON
//! Lines) from a thread of its own, bounded, never making the bridge wait.
//! [`replay::replay`] feeds a recording's inputs again into the same bridge
//! on the simulated arm, in simulated time, and [`replay::compare`] finds
//! the first difference between what came out and what was recorded.
//!
//! The recorder and replay are their own crate: an embedder of the engine
//! (the CLI's sockets, the Zenoh participant, a Python program) depends on
//! `motorwire-bridge` alone and taps the session with a `Tap` of its own.

pub mod record;
pub mod replay;

pub use motorwire_bridge::tap::{Direction, Mark, Tap, Unreadable};
