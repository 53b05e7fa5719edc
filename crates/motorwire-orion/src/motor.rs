//! The arm's seven motors, their keys and ranges.

use std::fmt;

/// One of the arm controller's seven motors, in the document's order
/// (LV1-MM-101 to 107).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Motor {
    /// `TRM`: turntable motor speed, [-400, 400]; positive is clockwise.
    Turntable,
    /// `LAA`: lower arm actuator, [-1, 1]; negative retracts.
    LowerArmActuator,
    /// `UAA`: upper arm actuator, [-1, 1]; negative retracts.
    UpperArmActuator,
    /// `AEM`: arm extending motor speed, [-400, 400]; positive extends.
    ArmExtension,
    /// `GVM`: grasper vertical movement motor speed, [-400, 400]; positive
    /// moves up.
    GrasperVertical,
    /// `GRM`: grasper rotation motor speed, [-400, 400]; positive is
    /// clockwise.
    GrasperRotation,
    /// `GHS`: grasper horizontal servo position in degrees, [-180, 180];
    /// positive moves right.
    GrasperHorizontalServo,
}

/// What a motor's value means.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Quantity {
    /// A speed (and direction), in the controller's own units.
    Speed,
    /// An actuator command: -1 retracts, 1 extends, 0 holds (the document
    /// does not say whether values in between are meaningful; they are
    /// accepted as given).
    Actuator,
    /// A servo position in degrees.
    PositionDegrees,
}

impl Motor {
    /// All seven, in the document's order.
    pub const ALL: [Motor; 7] = [
        Motor::Turntable,
        Motor::LowerArmActuator,
        Motor::UpperArmActuator,
        Motor::ArmExtension,
        Motor::GrasperVertical,
        Motor::GrasperRotation,
        Motor::GrasperHorizontalServo,
    ];

    /// The motor's position in [`Motor::ALL`].
    pub const fn index(self) -> usize {
        self as usize
    }

    /// The direct-control key (`"TRM"` ...).
    pub const fn key(self) -> &'static str {
        match self {
            Motor::Turntable => "TRM",
            Motor::LowerArmActuator => "LAA",
            Motor::UpperArmActuator => "UAA",
            Motor::ArmExtension => "AEM",
            Motor::GrasperVertical => "GVM",
            Motor::GrasperRotation => "GRM",
            Motor::GrasperHorizontalServo => "GHS",
        }
    }

    /// The feedback key of the document's table (`"TRMF"` ...).
    pub const fn feedback_key(self) -> &'static str {
        match self {
            Motor::Turntable => "TRMF",
            Motor::LowerArmActuator => "LAAF",
            Motor::UpperArmActuator => "UAAF",
            Motor::ArmExtension => "AEMF",
            Motor::GrasperVertical => "GVMF",
            Motor::GrasperRotation => "GRMF",
            Motor::GrasperHorizontalServo => "GHSF",
        }
    }

    /// The motor of a direct-control key.
    pub fn from_key(key: &str) -> Option<Motor> {
        Motor::ALL.into_iter().find(|m| m.key() == key)
    }

    /// The motor of a feedback key (`"TRMF"`).
    pub fn from_feedback_key(key: &str) -> Option<Motor> {
        Motor::ALL.into_iter().find(|m| m.feedback_key() == key)
    }

    /// The document's value range, `(min, max)`; values outside are clamped
    /// to it.
    pub const fn range(self) -> (f64, f64) {
        match self.quantity() {
            Quantity::Speed => (-400.0, 400.0),
            Quantity::Actuator => (-1.0, 1.0),
            Quantity::PositionDegrees => (-180.0, 180.0),
        }
    }

    /// What the value means.
    pub const fn quantity(self) -> Quantity {
        match self {
            Motor::LowerArmActuator | Motor::UpperArmActuator => Quantity::Actuator,
            Motor::GrasperHorizontalServo => Quantity::PositionDegrees,
            _ => Quantity::Speed,
        }
    }

    /// A readable name, as bus maps use them (`"turntable"` ...).
    pub const fn name(self) -> &'static str {
        match self {
            Motor::Turntable => "turntable",
            Motor::LowerArmActuator => "lower_arm_actuator",
            Motor::UpperArmActuator => "upper_arm_actuator",
            Motor::ArmExtension => "arm_extension",
            Motor::GrasperVertical => "grasper_vertical",
            Motor::GrasperRotation => "grasper_rotation",
            Motor::GrasperHorizontalServo => "grasper_horizontal_servo",
        }
    }

    /// The motor of a readable name.
    pub fn from_name(name: &str) -> Option<Motor> {
        Motor::ALL.into_iter().find(|m| m.name() == name)
    }
}

impl fmt::Display for Motor {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.key())
    }
}
