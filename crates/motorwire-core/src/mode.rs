use core::fmt;
use core::str::FromStr;

use crate::CoreError;

/// How a motor is controlled: the ten modes of the WIA `control_mode` enum.
///
/// Each mode has a string name (the JSON Schema's enum value, [`ControlMode::name`])
/// and a numeric code (the compact binary command's `control_mode` byte,
/// [`ControlMode::code`]). Codes 0 to 3 are WIA Phase 3's; 4 to 9 are
/// motorwire's extension, in the schema's order.
///
/// ```
/// use motorwire_core::ControlMode;
///
/// let mode: ControlMode = "gravity_comp".parse()?;
/// assert_eq!(mode, ControlMode::GravityComp);
/// assert_eq!(mode.code(), 7);
/// assert_eq!(ControlMode::from_code(1)?, ControlMode::Position);
/// assert_eq!(ControlMode::Position.to_string(), "position");
/// # Ok::<(), motorwire_core::CoreError>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[repr(u8)]
pub enum ControlMode {
    /// Motor disabled (code 0).
    Disabled = 0,
    /// Position control, setpoint in degrees or radians (code 1).
    Position = 1,
    /// Velocity control, setpoint in deg/s or rad/s (code 2).
    Velocity = 2,
    /// Torque or force control, setpoint in Nm or N (code 3).
    Torque = 3,
    /// Impedance control; needs impedance parameters (code 4).
    Impedance = 4,
    /// Admittance control; needs impedance parameters (code 5).
    Admittance = 5,
    /// Trajectory following (code 6).
    Trajectory = 6,
    /// Gravity compensation (code 7).
    GravityComp = 7,
    /// Force control (code 8).
    ForceCtrl = 8,
    /// Hybrid position/force control (code 9).
    Hybrid = 9,
}

impl ControlMode {
    /// All ten modes, in the order of the WIA schema's enum.
    pub const ALL: [ControlMode; 10] = [
        Self::Position,
        Self::Velocity,
        Self::Torque,
        Self::Impedance,
        Self::Admittance,
        Self::Trajectory,
        Self::GravityComp,
        Self::ForceCtrl,
        Self::Hybrid,
        Self::Disabled,
    ];

    /// The mode's name in WIA JSON (`"position"`, `"gravity_comp"`, ...).
    pub const fn name(self) -> &'static str {
        match self {
            Self::Disabled => "disabled",
            Self::Position => "position",
            Self::Velocity => "velocity",
            Self::Torque => "torque",
            Self::Impedance => "impedance",
            Self::Admittance => "admittance",
            Self::Trajectory => "trajectory",
            Self::GravityComp => "gravity_comp",
            Self::ForceCtrl => "force_ctrl",
            Self::Hybrid => "hybrid",
        }
    }

    /// The mode's code in the compact binary command.
    ///
    /// ```
    /// # use motorwire_core::ControlMode;
    /// assert_eq!(ControlMode::Disabled.code(), 0);
    /// assert_eq!(ControlMode::Hybrid.code(), 9);
    /// ```
    pub const fn code(self) -> u8 {
        self as u8
    }

    /// The mode with the given compact-command code.
    ///
    /// ```
    /// # use motorwire_core::{ControlMode, CoreError};
    /// assert_eq!(ControlMode::from_code(3), Ok(ControlMode::Torque));
    /// assert_eq!(ControlMode::from_code(10), Err(CoreError::UnknownControlModeCode { code: 10 }));
    /// ```
    pub const fn from_code(code: u8) -> Result<Self, CoreError> {
        Ok(match code {
            0 => Self::Disabled,
            1 => Self::Position,
            2 => Self::Velocity,
            3 => Self::Torque,
            4 => Self::Impedance,
            5 => Self::Admittance,
            6 => Self::Trajectory,
            7 => Self::GravityComp,
            8 => Self::ForceCtrl,
            9 => Self::Hybrid,
            _ => return Err(CoreError::UnknownControlModeCode { code }),
        })
    }

    /// The mode with the given WIA name; names are case-sensitive.
    pub fn from_name(name: &str) -> Result<Self, CoreError> {
        Ok(match name {
            "disabled" => Self::Disabled,
            "position" => Self::Position,
            "velocity" => Self::Velocity,
            "torque" => Self::Torque,
            "impedance" => Self::Impedance,
            "admittance" => Self::Admittance,
            "trajectory" => Self::Trajectory,
            "gravity_comp" => Self::GravityComp,
            "force_ctrl" => Self::ForceCtrl,
            "hybrid" => Self::Hybrid,
            _ => return Err(CoreError::UnknownControlMode),
        })
    }

    /// Whether a command in this mode needs impedance parameters
    /// (stiffness, damping and inertia) to be executable: impedance and
    /// admittance control do.
    ///
    /// ```
    /// # use motorwire_core::ControlMode;
    /// assert!(ControlMode::Impedance.needs_impedance_params());
    /// assert!(!ControlMode::Position.needs_impedance_params());
    /// ```
    pub const fn needs_impedance_params(self) -> bool {
        matches!(self, Self::Impedance | Self::Admittance)
    }
}

impl FromStr for ControlMode {
    type Err = CoreError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Self::from_name(s)
    }
}

impl fmt::Display for ControlMode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn codes_follow_wire_facts() {
        let expected = [
            ("disabled", 0u8),
            ("position", 1),
            ("velocity", 2),
            ("torque", 3),
            ("impedance", 4),
            ("admittance", 5),
            ("trajectory", 6),
            ("gravity_comp", 7),
            ("force_ctrl", 8),
            ("hybrid", 9),
        ];
        for (name, code) in expected {
            let mode = ControlMode::from_name(name).unwrap();
            assert_eq!(mode.code(), code);
            assert_eq!(mode.name(), name);
            assert_eq!(ControlMode::from_code(code).unwrap(), mode);
        }
    }

    #[test]
    fn all_lists_every_mode_once_in_schema_order() {
        let names: [&str; 10] = ControlMode::ALL.map(ControlMode::name);
        assert_eq!(
            names,
            [
                "position",
                "velocity",
                "torque",
                "impedance",
                "admittance",
                "trajectory",
                "gravity_comp",
                "force_ctrl",
                "hybrid",
                "disabled"
            ]
        );
    }

    #[test]
    fn unknown_names_and_codes_are_refused() {
        assert_eq!(
            ControlMode::from_name("Position"),
            Err(CoreError::UnknownControlMode)
        );
        assert_eq!(
            ControlMode::from_name(""),
            Err(CoreError::UnknownControlMode)
        );
        for code in 10..=255u8 {
            assert_eq!(
                ControlMode::from_code(code),
                Err(CoreError::UnknownControlModeCode { code })
            );
        }
    }
}
