#![doc = include_str!("../README.md")]

mod command;
mod feedback;
mod frames;
mod gate;
mod map;
mod moteus;
mod path;
mod report;
mod servo;
mod sync;
mod trajectory;

pub use command::{
    HIGH_PRIORITY, IrpcCommand, compact_command, lifecycle, multi_axis_to_compact, to_compact,
    to_irpc, to_irpc_gated, to_orion, to_orion_motor,
};
pub use feedback::{FeedbackError, feedback_from_irpc, feedback_from_orion};
pub use frames::{IrpcFrame, irpc_frames};
pub use gate::{Bound, Effective, Refusal, RefusalDetail, gate, gate_calibration};
pub use map::{AngleUnit, BusMap, Limits, MapError, MappedMotor, Target};
pub use moteus::{
    MoteusCommand, WATCHDOG_MARGIN_S, f32_within, multi_axis_to_moteus, revolutions, to_moteus,
};
pub use path::{JointState, PathExtent, check_path, check_path_from, check_trajectory};
/// [`Report`] (what a translation lost or filled in) under a name that
/// cannot be mistaken for `motorwire_wia::Report` (a validation verdict,
/// also `motorwire_wia::ValidationReport`): the same type.
pub use report::Report as TranslationReport;
pub use report::{Loss, LossKind, LossText, Report, Translated};
pub use servo::{
    Calibration, GoalBlock, ServoCommand, ServoPort, ServoTarget, ServoVendor, TORQUE_ON,
    calibrated_range, goal_block, goal_steps, hold_block, is_servo, multi_axis_to_servo,
    servo_packets, to_servo, torque_address,
};
pub use sync::{MultiAxisMove, SYNC_TOLERANCE_S, multi_axis_to_irpc, multi_axis_to_irpc_from};
pub use trajectory::{
    MAX_TRAJECTORY_SEGMENTS, TRAJECTORY_LEAD_S, TrajectoryPlan, TrajectorySegment,
    WAYPOINT_TOLERANCE_S, trajectory_to_irpc,
};
