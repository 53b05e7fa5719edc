#![doc = include_str!("../README.md")]

mod controller;
mod error;
mod message;
mod motor;
mod node;

pub use controller::{ArmController, Posture, Response};
pub use error::Error;
pub use message::{
    ArmCommand, CONTROLLER_ID, Clamp, CommandNumber, Feedback, FeedbackKeys, Input, MotorFeedback,
    MotorValues, Output, PerMotor,
};
pub use motor::{Motor, Quantity};
