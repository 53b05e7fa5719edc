#![doc = include_str!("../README.md")]
#![no_std]
#![cfg_attr(docsrs, feature(doc_cfg))]

mod duration;
mod error;
#[cfg(feature = "fixed")]
#[cfg_attr(docsrs, doc(cfg(feature = "fixed")))]
pub mod fixed_point;
mod float;
mod plan;
mod profile;
mod request;
mod scurve;
mod sync;
mod trapezoid;

pub use duration::{
    MAX_DURATION_ITERATIONS, minimum_duration, plan_with_duration, synchronize_time,
};
pub use error::PlanError;
pub use float::Float;
pub use plan::plan;
pub use profile::{MAX_PHASES, Phase, PositionExtrema, Profile, State, Ticks};
/// [`MotionProfile`] under a name that cannot be mistaken for
/// `motorwire_irpc::MotionProfile` (the wire enum of `SetTargetV2.profile`,
/// also `motorwire_irpc::IrpcMotionProfile`) in code that uses both: the
/// same type.
pub use request::MotionProfile as PlannerMotionProfile;
pub use request::{MotionProfile, Overshoot, Request};
pub use scurve::{MAX_ROOT_ITERATIONS, SCAN_POINTS, plan_scurve};
pub use sync::synchronize_phases;
pub use trapezoid::plan_trapezoidal;
