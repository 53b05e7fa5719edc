#![doc = include_str!("../README.md")]
#![no_std]

mod error;
mod float;
mod profile;
mod request;
mod sync;
mod trapezoid;

pub use error::PlanError;
pub use float::Float;
pub use profile::{MAX_PHASES, Phase, Profile, State, Ticks};
pub use request::{Overshoot, Request};
pub use sync::synchronize_phases;
pub use trapezoid::plan_trapezoidal;
