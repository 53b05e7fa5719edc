//! Every payload struct and enum of iRPC v1 to v2.2, fields in wire order.

use crate::wire::{Out, Reader, Stop, Wire, put_varint, wire_enum, wire_struct};
use crate::{Error, WireVersion};

wire_struct! {
    /// v1 motion command.
    pub struct SetTargetPayload as "SetTarget" {
        /// Target position (degrees).
        target_angle: f32,
        /// Velocity limit (deg/s).
        velocity_limit: f32,
    }
}

wire_enum! {
    /// How a joint moves to a `SetTargetV2` target.
    pub enum MotionProfile {
        /// Constant acceleration and deceleration phases.
        Trapezoidal = 0,
        /// Jerk-limited, up to seven constant-jerk phases.
        SCurve = 1,
        /// Load-adaptive (the document reserves it for the future).
        Adaptive = 2,
    }
}

wire_struct! {
    /// v2 motion command with a motion profile.
    ///
    /// `max_jerk <= 0` means "no jerk limit"; `max_current` and
    /// `max_temperature` of 0 mean "disabled".
    pub struct SetTargetPayloadV2 as "SetTargetV2" {
        /// Target position (degrees).
        target_angle: f32,
        /// Maximum velocity (deg/s).
        max_velocity: f32,
        /// Velocity on arrival (deg/s), for fly-by waypoints.
        target_velocity: f32,
        /// Maximum acceleration (deg/s²).
        max_acceleration: f32,
        /// Maximum deceleration (deg/s²).
        max_deceleration: f32,
        /// Maximum jerk (deg/s³); `<= 0` disables jerk limiting.
        max_jerk: f32,
        /// Motion profile.
        profile: MotionProfile,
        /// Current limit (A); 0 disables it.
        max_current: f32,
        /// Temperature limit (°C); 0 disables it.
        max_temperature: f32,
    }
}

impl SetTargetPayloadV2 {
    /// A jerk-limited (S-curve) move to `target_angle` coming to rest there,
    /// decelerating as fast as it accelerates, with no current or
    /// temperature limit. The iRPC document's example:
    ///
    /// ```
    /// use motorwire_irpc::{Header, Message, Payload, SetTargetPayloadV2, WireVersion};
    ///
    /// let p = SetTargetPayloadV2::scurve(90.0, 100.0, 500.0, 2000.0);
    /// let m = Message { header: Header { source_id: 0, target_id: 0x10, msg_id: 42 }, payload: Payload::SetTargetV2(p) };
    /// let mut buf = [0u8; 64];
    /// let n = m.encode(WireVersion::V2_0, &mut buf)?;
    /// assert_eq!(&buf[..n], &[
    ///     0x00, 0x10, 0x2a, 0x05, 0x00, 0x00, 0xb4, 0x42, 0x00, 0x00, 0xc8, 0x42, 0x00, 0x00, 0x00, 0x00,
    ///     0x00, 0x00, 0xfa, 0x43, 0x00, 0x00, 0xfa, 0x43, 0x00, 0x00, 0xfa, 0x44, 0x01, 0x00, 0x00, 0x00,
    ///     0x00, 0x00, 0x00, 0x00, 0x00,
    /// ]);
    /// # Ok::<(), motorwire_irpc::Error>(())
    /// ```
    pub const fn scurve(
        target_angle: f32,
        max_velocity: f32,
        max_acceleration: f32,
        max_jerk: f32,
    ) -> Self {
        Self {
            target_angle,
            max_velocity,
            target_velocity: 0.0,
            max_acceleration,
            max_deceleration: max_acceleration,
            max_jerk,
            profile: MotionProfile::SCurve,
            max_current: 0.0,
            max_temperature: 0.0,
        }
    }

    /// A trapezoidal move (jerk 0), otherwise as [`SetTargetPayloadV2::scurve`].
    ///
    /// ```
    /// use motorwire_irpc::{MotionProfile, SetTargetPayloadV2};
    /// let p = SetTargetPayloadV2::trapezoidal(90.0, 100.0, 500.0).with_deceleration(400.0);
    /// assert_eq!((p.profile, p.max_jerk, p.max_deceleration), (MotionProfile::Trapezoidal, 0.0, 400.0));
    /// ```
    pub const fn trapezoidal(target_angle: f32, max_velocity: f32, max_acceleration: f32) -> Self {
        let mut p = Self::scurve(target_angle, max_velocity, max_acceleration, 0.0);
        p.profile = MotionProfile::Trapezoidal;
        p
    }

    /// The same move with its own deceleration limit (deg/s²).
    #[must_use]
    pub const fn with_deceleration(mut self, max_deceleration: f32) -> Self {
        self.max_deceleration = max_deceleration;
        self
    }
}

wire_struct! {
    /// Encoder reading.
    pub struct EncoderTelemetry as "Encoder" {
        /// Position (degrees).
        position: f32,
        /// Velocity (deg/s).
        velocity: f32,
    }
}

/// A joint's lifecycle state. Its wire index depends on the version:
/// v1 and v2.0 have no `Calibrating` (and `Error` is 3); from v2.1
/// `Calibrating` is 3 and `Error` is 4.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum LifecycleState {
    /// Not configured.
    Unconfigured,
    /// Configured, not active.
    Inactive,
    /// Active: motion commands are executed.
    Active,
    /// Calibrating (v2.1 on).
    Calibrating,
    /// Fault.
    Error,
}

impl LifecycleState {
    /// The state's index on the wire in `version`, or `None` where it does
    /// not exist.
    pub const fn index(self, version: WireVersion) -> Option<u32> {
        let calibrating = version.has_calibrating_state();
        match self {
            Self::Unconfigured => Some(0),
            Self::Inactive => Some(1),
            Self::Active => Some(2),
            Self::Calibrating if calibrating => Some(3),
            Self::Calibrating => None,
            Self::Error if calibrating => Some(4),
            Self::Error => Some(3),
        }
    }
}

impl Wire for LifecycleState {
    fn put<O: Out>(&self, o: &mut O, field: &'static str, v: WireVersion) -> Result<(), Stop> {
        match self.index(v) {
            Some(index) => put_varint(o, u64::from(index)),
            None => Err(o.fail(Error::ValueNotInVersion { field, version: v })),
        }
    }

    fn take(r: &mut Reader<'_>, field: &'static str, v: WireVersion) -> Result<Self, Stop> {
        let offset = r.position();
        let index = r.varint(field, 5, u64::from(u32::MAX))?;
        let calibrating = v.has_calibrating_state();
        Ok(match (index, calibrating) {
            (0, _) => Self::Unconfigured,
            (1, _) => Self::Inactive,
            (2, _) => Self::Active,
            (3, true) => Self::Calibrating,
            (3, false) | (4, true) => Self::Error,
            _ => {
                return Err(r.fail(Error::InvalidEnum {
                    field,
                    index: u32::try_from(index).unwrap_or(u32::MAX),
                    offset,
                }));
            }
        })
    }
}

wire_struct! {
    /// High-rate telemetry (v2.1 on). At 71 bytes in the worst case it can
    /// exceed one CAN-FD frame.
    pub struct TelemetryStream as "TelemetryStream" {
        /// Sample time (µs).
        timestamp_us: u64,
        /// Position (degrees).
        position: f32,
        /// Velocity (deg/s).
        velocity: f32,
        /// Acceleration (deg/s²).
        acceleration: f32,
        /// d-axis current (A).
        current_d: f32,
        /// q-axis current (A).
        current_q: f32,
        /// d-axis voltage (V).
        voltage_d: f32,
        /// q-axis voltage (V).
        voltage_q: f32,
        /// Estimated torque (Nm).
        torque_estimate: f32,
        /// Power (W).
        power: f32,
        /// Load (%).
        load_percent: f32,
        /// FOC loop time (µs).
        foc_loop_time_us: u16,
        /// Temperature (°C).
        temperature_c: f32,
        /// Warning bits.
        warnings: u16,
        /// Whether a trajectory is running.
        trajectory_active: bool,
    }
}

wire_enum! {
    /// When telemetry is sent.
    pub enum TelemetryMode {
        /// Only when requested.
        OnDemand = 0,
        /// At `rate_hz`.
        Periodic = 1,
        /// As fast as possible.
        Streaming = 2,
        /// When a value changes by more than `change_threshold`.
        OnChange = 3,
        /// Chosen by the joint.
        Adaptive = 4,
    }
}

wire_struct! {
    /// Telemetry configuration (v2.1 on).
    pub struct ConfigureTelemetryPayload as "ConfigureTelemetry" {
        /// Mode.
        mode: TelemetryMode,
        /// Rate (Hz).
        rate_hz: u16,
        /// Change threshold for `OnChange`.
        change_threshold: f32,
    }
}

wire_struct! {
    /// Adaptive control configuration (v2.1 on).
    pub struct ConfigureAdaptivePayload as "ConfigureAdaptive" {
        /// Enable CoolStep.
        coolstep_enable: bool,
        /// CoolStep minimum current scale.
        coolstep_min_current: f32,
        /// CoolStep threshold.
        coolstep_threshold: f32,
        /// Enable DcStep.
        dcstep_enable: bool,
        /// DcStep threshold.
        dcstep_threshold: f32,
        /// DcStep maximum derating.
        dcstep_max_derating: f32,
        /// Enable StallGuard.
        stallguard_enable: bool,
        /// StallGuard current threshold.
        stallguard_current_threshold: f32,
        /// StallGuard velocity threshold.
        stallguard_velocity_threshold: f32,
    }
}

wire_enum! {
    /// Stall detection state.
    pub enum StallStatus {
        /// No stall.
        Normal = 0,
        /// Close to stalling.
        Warning = 1,
        /// Stalled.
        Stalled = 2,
    }
}

wire_struct! {
    /// Adaptive control status (v2.1 on).
    pub struct AdaptiveStatusPayload as "AdaptiveStatus" {
        /// Load (%).
        load_percent: f32,
        /// Current scale.
        current_scale: f32,
        /// CoolStep enabled.
        coolstep_enabled: bool,
        /// Power saved (%).
        power_savings_percent: f32,
        /// Energy saved (Wh).
        energy_saved_wh: f32,
        /// Velocity scale.
        velocity_scale: f32,
        /// DcStep enabled.
        dcstep_enabled: bool,
        /// DcStep derating active.
        dcstep_derating: bool,
        /// Stall state.
        stall_status: StallStatus,
        /// StallGuard enabled.
        stallguard_enabled: bool,
        /// Stall confidence.
        stall_confidence: f32,
    }
}

wire_struct! {
    /// Calibration request (v2.1 on).
    pub struct CalibrationRequest as "StartCalibration" {
        /// Phase bit mask.
        phases: u8,
        /// Current limit (A).
        max_current: f32,
        /// Velocity limit (deg/s).
        max_velocity: f32,
        /// Position range (degrees).
        max_position_range: f32,
        /// Timeout per phase (s).
        phase_timeout: f32,
        /// Return home afterwards.
        return_home: bool,
    }
}

wire_enum! {
    /// Calibration phase.
    pub enum CalibrationPhase {
        /// Not calibrating.
        Idle = 0,
        /// Measuring inertia.
        InertiaTest = 1,
        /// Measuring friction.
        FrictionTest = 2,
        /// Verifying the torque constant.
        TorqueConstantVerification = 3,
        /// Measuring damping.
        DampingTest = 4,
        /// Validating the model.
        Validation = 5,
        /// Done.
        Complete = 6,
        /// Failed.
        Failed = 7,
    }
}

wire_struct! {
    /// Calibration progress (v2.1 on).
    pub struct CalibrationStatus as "CalibrationStatus" {
        /// Phase.
        phase: CalibrationPhase,
        /// Progress (0 to 1).
        progress: f32,
        /// Time remaining (s).
        time_remaining: f32,
        /// Position (degrees).
        current_position: f32,
        /// Velocity (deg/s).
        current_velocity: f32,
        /// q-axis current (A).
        current_iq: f32,
    }
}

wire_struct! {
    /// Identified motor parameters.
    pub struct MotorParameters as "CalibrationResult.parameters" {
        /// Inertia. JSON also accepts the public implementation's name
        /// `inertia_J` (WIRE-FACTS §1.3).
        #[cfg_attr(feature = "serde", serde(alias = "inertia_J"))]
        inertia: f32,
        /// Torque constant. JSON also accepts `torque_constant_kt`.
        #[cfg_attr(feature = "serde", serde(alias = "torque_constant_kt"))]
        torque_constant: f32,
        /// Damping. JSON also accepts `damping_b`.
        #[cfg_attr(feature = "serde", serde(alias = "damping_b"))]
        damping: f32,
        /// Coulomb friction.
        friction_coulomb: f32,
        /// Stribeck friction.
        friction_stribeck: f32,
        /// Stribeck velocity.
        friction_vstribeck: f32,
        /// Viscous friction.
        friction_viscous: f32,
    }
}

wire_struct! {
    /// Confidence in identified parameters.
    pub struct CalibrationConfidence as "CalibrationResult.confidence" {
        /// Overall.
        overall: f32,
        /// Inertia.
        inertia: f32,
        /// Friction.
        friction: f32,
        /// Torque constant.
        torque_constant: f32,
        /// Validation RMS error.
        validation_rms: f32,
    }
}

wire_struct! {
    /// Calibration result (v2.1 on).
    pub struct CalibrationResult as "CalibrationResult" {
        /// Whether calibration succeeded.
        success: bool,
        /// Identified parameters.
        parameters: MotorParameters,
        /// Confidence.
        confidence: CalibrationConfidence,
        /// Total time (s).
        total_time: f32,
        /// Error code.
        error_code: u16,
    }
}

wire_struct! {
    /// Fault counters.
    pub struct FaultCounters as "PowerMetrics.faults" {
        /// Over-current events. JSON also accepts the public
        /// implementation's name `overcurrent_events` (WIRE-FACTS §1.3).
        #[cfg_attr(feature = "serde", serde(alias = "overcurrent_events"))]
        overcurrent: u16,
        /// Over-voltage events. JSON also accepts `overvoltage_events`.
        #[cfg_attr(feature = "serde", serde(alias = "overvoltage_events"))]
        overvoltage: u16,
        /// Under-voltage events. JSON also accepts `undervoltage_events`.
        #[cfg_attr(feature = "serde", serde(alias = "undervoltage_events"))]
        undervoltage: u16,
        /// Over-temperature events. JSON also accepts `overtemp_events`.
        #[cfg_attr(feature = "serde", serde(alias = "overtemp_events"))]
        overtemp: u16,
        /// Driver faults. JSON also accepts `driver_fault_events`.
        #[cfg_attr(feature = "serde", serde(alias = "driver_fault_events"))]
        driver_fault: u16,
        /// Emergency stops.
        emergency_stops: u16,
    }
}

wire_struct! {
    /// Power metrics (v2.2).
    pub struct PowerMetrics as "PowerMetrics" {
        /// Bus voltage (mV).
        vbus_mv: u32,
        /// Phase A current (mA).
        ia_ma: i32,
        /// Phase B current (mA).
        ib_ma: i32,
        /// RMS current (mA).
        i_rms_ma: f32,
        /// Power (mW).
        power_mw: u32,
        /// MCU temperature (°C).
        mcu_temp_c: f32,
        /// Thermal throttle factor.
        throttle_factor: f32,
        /// Energy (mWh).
        energy_mwh: u32,
        /// Charge (mAh).
        charge_mah: u32,
        /// Active time (ms).
        active_time_ms: u32,
        /// Fault counters.
        faults: FaultCounters,
    }
}

wire_enum! {
    /// Why an emergency stop happened.
    pub enum EmergencyReason {
        /// Bus over-voltage.
        Overvoltage = 0,
        /// Bus under-voltage.
        Undervoltage = 1,
        /// Peak over-current.
        PeakOvercurrent = 2,
        /// RMS over-current.
        RmsOvercurrent = 3,
        /// Over-temperature.
        Overtemperature = 4,
        /// Driver fault.
        DriverFault = 5,
        /// Watchdog reset.
        WatchdogReset = 6,
        /// Stopped by an operator.
        ManualStop = 7,
    }
}

wire_struct! {
    /// Emergency stop report (v2.2).
    pub struct EmergencyStop as "EmergencyStop" {
        /// Reason.
        reason: EmergencyReason,
        /// Bus voltage (mV).
        vbus_mv: u32,
        /// Current (mA).
        current_ma: i32,
        /// Temperature (°C).
        temp_c: f32,
        /// When (ms since boot).
        timestamp_ms: u32,
    }
}

wire_struct! {
    /// Power configuration (v2.2).
    pub struct PowerConfig as "PowerConfig" {
        /// Over-voltage threshold (mV).
        vbus_overvoltage_mv: u32,
        /// Under-voltage threshold (mV).
        vbus_undervoltage_mv: u32,
        /// RMS current limit (mA).
        max_rms_current_ma: u16,
        /// Peak current limit (mA).
        max_peak_current_ma: u16,
        /// Throttling starts (°C).
        temp_throttle_start_c: u8,
        /// Shutdown (°C).
        temp_shutdown_c: u8,
        /// Telemetry rate (Hz).
        telemetry_rate_hz: u8,
    }
}

wire_struct! {
    /// One recorded fault.
    pub struct FaultRecord as "FaultHistory.records" {
        /// Fault type.
        fault_type: u8,
        /// When (s since boot).
        timestamp_sec: u32,
        /// Bus voltage (mV).
        vbus_mv: u16,
        /// Current (mA).
        current_ma: u16,
        /// Temperature (°C).
        temp_c: i8,
    }
}

// `wire_struct!` declares the struct; only FaultRecord (an array element) needs a default.
#[allow(clippy::derivable_impls)]
impl Default for FaultRecord {
    fn default() -> Self {
        Self {
            fault_type: 0,
            timestamp_sec: 0,
            vbus_mv: 0,
            current_ma: 0,
            temp_c: 0,
        }
    }
}

wire_struct! {
    /// The last ten faults (v2.2). Over 64 bytes: needs a segmented transport.
    pub struct FaultHistory as "FaultHistory" {
        /// The records, oldest first.
        records: [FaultRecord; 10],
        /// Faults since boot.
        total_faults: u32,
        /// How many records are valid.
        valid_count: u8,
    }
}
