//! The arm controller's state model.

use crate::{
    ArmCommand, Clamp, Error, Feedback, Input, Motor, MotorFeedback, MotorValues, Output, Quantity,
};

/// Where the arm's command mode last left it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Posture {
    /// As booted: no fold or unfold command yet.
    #[default]
    AsBooted,
    /// Folded for transport (command 2).
    Folded,
    /// Unfolded to the default position (command 3).
    Unfolded,
}

/// What the controller did with one input.
#[derive(Debug, Clone, PartialEq)]
pub struct Response {
    /// The feedback message it sends.
    pub output: Output,
    /// Every value it clamped into range (direct control only).
    pub clamps: Vec<Clamp>,
}

/// The arm controller as the Orion document describes it: it remembers the
/// last value of each motor, applies partial direct-control updates (values
/// out of range clamped, and each clamp reported), runs the stop, fold and
/// unfold commands, and answers any other command number with `CMDF: 0`.
///
/// **Commands and stop.** The document says a running command cannot yet be
/// stopped ("TODO"). Here every command completes before the next input is
/// handled, so there is never a running command to interrupt: "stop" stops
/// the motors that direct control set moving (every speed and actuator to 0;
/// the servo holds its position). Fold and unfold also leave every speed and
/// actuator at 0 and centre the servo (0 deg).
///
/// **Feedback.** Element 0 is the value each motor now runs at. The current
/// draw (element 1) is simulated, as the document's own example says its
/// figures are: 0 at rest, otherwise 5 + 0.15 per speed unit, 50 per unit
/// of actuator command, and 10 for the servo holding a position off centre.
/// The error flag is 0.
///
/// ```
/// use motorwire_orion::{ArmController, FeedbackKeys, Input, Motor};
/// let mut arm = ArmController::new();
/// let r = arm.handle(&Input::parse(r#"{"ID":32,"MODE":1,"DATA":{"TRM":-1000}}"#)?);
/// assert_eq!(r.clamps.len(), 1);
/// assert_eq!(arm.value(Motor::Turntable), -400.0);
/// let r = arm.handle(&Input::parse(r#"{"ID":32,"MODE":2,"DATA":1}"#)?);
/// assert_eq!(r.output.to_json(FeedbackKeys::Table), r#"{"ID":32,"MODE":2,"DATA":{"CMDF":1}}"#);
/// assert_eq!(arm.value(Motor::Turntable), 0.0);
/// # Ok::<(), motorwire_orion::Error>(())
/// ```
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ArmController {
    values: [f64; 7],
    posture: Posture,
    commanded: bool,
}

impl ArmController {
    /// A controller as booted: every motor at 0, waiting for its first
    /// command (and sending the beacon until then).
    pub fn new() -> Self {
        Self::default()
    }

    /// Whether no command has been handled yet (the beacon repeats until
    /// one is).
    pub fn awaiting_first_command(&self) -> bool {
        !self.commanded
    }

    /// The value `motor` runs at.
    pub fn value(&self, motor: Motor) -> f64 {
        self.values.get(motor.index()).copied().unwrap_or(0.0)
    }

    /// Every motor's value.
    pub fn values(&self) -> MotorValues {
        let mut v = MotorValues::new();
        for m in Motor::ALL {
            v.set(m, self.value(m));
        }
        v
    }

    /// Where command mode last left the arm.
    pub fn posture(&self) -> Posture {
        self.posture
    }

    /// Handles one input and returns the controller's answer.
    pub fn handle(&mut self, input: &Input) -> Response {
        self.commanded = true;
        match input {
            Input::DirectControl(values) => {
                let (clamped, clamps) = values.clamped();
                for (motor, v) in clamped.iter() {
                    self.set(motor, v);
                }
                Response {
                    output: Output::DirectControl(self.feedback()),
                    clamps,
                }
            }
            Input::Command(number) => {
                let succeeded = match number.command() {
                    Some(command) => {
                        self.run(command);
                        true
                    }
                    None => false,
                };
                Response {
                    output: Output::Command { succeeded },
                    clamps: Vec::new(),
                }
            }
        }
    }

    /// Parses and handles one line; a line that is not an Orion input
    /// changes nothing.
    ///
    /// # Errors
    /// [`Input::parse`]'s.
    pub fn handle_line(&mut self, line: &str) -> Result<Response, Error> {
        let input = Input::parse(line)?;
        Ok(self.handle(&input))
    }

    /// Every motor's feedback as it stands.
    pub fn feedback(&self) -> Feedback {
        let mut fb = Feedback::new();
        for m in Motor::ALL {
            let value = self.value(m);
            let current = match m.quantity() {
                _ if value == 0.0 => 0.0,
                Quantity::Speed => 5.0 + 0.15 * value.abs(),
                Quantity::Actuator => 50.0 * value.abs(),
                Quantity::PositionDegrees => 10.0,
            };
            fb.set(
                m,
                MotorFeedback {
                    value,
                    current,
                    error: 0,
                },
            );
        }
        fb
    }

    fn set(&mut self, motor: Motor, value: f64) {
        if let Some(slot) = self.values.get_mut(motor.index()) {
            *slot = value;
        }
    }

    fn stop_motion(&mut self) {
        for m in Motor::ALL {
            if m.quantity() != Quantity::PositionDegrees {
                self.set(m, 0.0);
            }
        }
    }

    fn run(&mut self, command: ArmCommand) {
        self.stop_motion();
        match command {
            ArmCommand::Stop => {}
            ArmCommand::Fold => {
                self.set(Motor::GrasperHorizontalServo, 0.0);
                self.posture = Posture::Folded;
            }
            ArmCommand::Unfold => {
                self.set(Motor::GrasperHorizontalServo, 0.0);
                self.posture = Posture::Unfolded;
            }
        }
    }
}
