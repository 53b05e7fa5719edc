//! Shared by the iRPC tests: a strategy for every message of every version,
//! and mirror types that let real postcard encode the same messages.
#![allow(
    dead_code,
    unreachable_pub,
    missing_docs,
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing
)]

use motorwire_irpc::*;
use proptest::prelude::*;
use serde::Serialize;

pub fn hex(s: &str) -> Vec<u8> {
    s.split_whitespace()
        .map(|b| u8::from_str_radix(b, 16).unwrap())
        .collect()
}

pub fn to_hex(b: &[u8]) -> String {
    b.iter()
        .map(|x| format!("{x:02x}"))
        .collect::<Vec<_>>()
        .join(" ")
}

pub fn f() -> impl Strategy<Value = f32> {
    prop_oneof![
        any::<f32>().prop_filter("finite", |x| x.is_finite()),
        Just(0.0f32),
        Just(-0.0f32),
        Just(f32::MAX),
        Just(f32::MIN_POSITIVE),
    ]
}

fn state(v: WireVersion) -> impl Strategy<Value = LifecycleState> {
    let mut states = vec![
        LifecycleState::Unconfigured,
        LifecycleState::Inactive,
        LifecycleState::Active,
        LifecycleState::Error,
    ];
    if v.has_calibrating_state() {
        states.push(LifecycleState::Calibrating);
    }
    prop::sample::select(states)
}

fn pick<T: Copy + std::fmt::Debug + 'static>(all: &'static [T]) -> impl Strategy<Value = T> {
    prop::sample::select(all.to_vec())
}

pub fn payload(kind: PayloadKind, v: WireVersion) -> BoxedStrategy<Payload> {
    use PayloadKind as K;
    match kind {
        K::SetTarget => (f(), f())
            .prop_map(|(a, b)| {
                Payload::SetTarget(SetTargetPayload {
                    target_angle: a,
                    velocity_limit: b,
                })
            })
            .boxed(),
        K::Configure => Just(Payload::Configure).boxed(),
        K::Activate => Just(Payload::Activate).boxed(),
        K::Deactivate => Just(Payload::Deactivate).boxed(),
        K::Reset => Just(Payload::Reset).boxed(),
        K::SetTargetV2 => (
            f(),
            f(),
            f(),
            f(),
            f(),
            f(),
            pick(MotionProfile::ALL),
            f(),
            f(),
        )
            .prop_map(|(a, b, c, d, e, g, p, h, i)| {
                Payload::SetTargetV2(SetTargetPayloadV2 {
                    target_angle: a,
                    max_velocity: b,
                    target_velocity: c,
                    max_acceleration: d,
                    max_deceleration: e,
                    max_jerk: g,
                    profile: p,
                    max_current: h,
                    max_temperature: i,
                })
            })
            .boxed(),
        K::Encoder => (f(), f())
            .prop_map(|(a, b)| {
                Payload::Encoder(EncoderTelemetry {
                    position: a,
                    velocity: b,
                })
            })
            .boxed(),
        K::JointStatus => (state(v), any::<u16>())
            .prop_map(|(state, error_code)| Payload::JointStatus { state, error_code })
            .boxed(),
        K::TelemetryStream => (
            any::<u64>(),
            [f(), f(), f(), f(), f(), f(), f(), f(), f(), f()],
            any::<u16>(),
            f(),
            any::<u16>(),
            any::<bool>(),
        )
            .prop_map(|(t, x, loop_us, temp, warn, active)| {
                Payload::TelemetryStream(TelemetryStream {
                    timestamp_us: t,
                    position: x[0],
                    velocity: x[1],
                    acceleration: x[2],
                    current_d: x[3],
                    current_q: x[4],
                    voltage_d: x[5],
                    voltage_q: x[6],
                    torque_estimate: x[7],
                    power: x[8],
                    load_percent: x[9],
                    foc_loop_time_us: loop_us,
                    temperature_c: temp,
                    warnings: warn,
                    trajectory_active: active,
                })
            })
            .boxed(),
        K::ConfigureTelemetry => (pick(TelemetryMode::ALL), any::<u16>(), f())
            .prop_map(|(mode, rate_hz, change_threshold)| {
                Payload::ConfigureTelemetry(ConfigureTelemetryPayload {
                    mode,
                    rate_hz,
                    change_threshold,
                })
            })
            .boxed(),
        K::RequestTelemetry => Just(Payload::RequestTelemetry).boxed(),
        K::ConfigureAdaptive => (any::<[bool; 3]>(), [f(), f(), f(), f(), f(), f()])
            .prop_map(|(b, x)| {
                Payload::ConfigureAdaptive(ConfigureAdaptivePayload {
                    coolstep_enable: b[0],
                    coolstep_min_current: x[0],
                    coolstep_threshold: x[1],
                    dcstep_enable: b[1],
                    dcstep_threshold: x[2],
                    dcstep_max_derating: x[3],
                    stallguard_enable: b[2],
                    stallguard_current_threshold: x[4],
                    stallguard_velocity_threshold: x[5],
                })
            })
            .boxed(),
        K::RequestAdaptiveStatus => Just(Payload::RequestAdaptiveStatus).boxed(),
        K::AdaptiveStatus => (
            any::<[bool; 4]>(),
            [f(), f(), f(), f(), f(), f()],
            pick(StallStatus::ALL),
        )
            .prop_map(|(b, x, stall)| {
                Payload::AdaptiveStatus(AdaptiveStatusPayload {
                    load_percent: x[0],
                    current_scale: x[1],
                    coolstep_enabled: b[0],
                    power_savings_percent: x[2],
                    energy_saved_wh: x[3],
                    velocity_scale: x[4],
                    dcstep_enabled: b[1],
                    dcstep_derating: b[2],
                    stall_status: stall,
                    stallguard_enabled: b[3],
                    stall_confidence: x[5],
                })
            })
            .boxed(),
        K::StartCalibration => (any::<u8>(), [f(), f(), f(), f()], any::<bool>())
            .prop_map(|(phases, x, return_home)| {
                Payload::StartCalibration(CalibrationRequest {
                    phases,
                    max_current: x[0],
                    max_velocity: x[1],
                    max_position_range: x[2],
                    phase_timeout: x[3],
                    return_home,
                })
            })
            .boxed(),
        K::StopCalibration => Just(Payload::StopCalibration).boxed(),
        K::CalibrationStatus => (pick(CalibrationPhase::ALL), [f(), f(), f(), f(), f()])
            .prop_map(|(phase, x)| {
                Payload::CalibrationStatus(CalibrationStatus {
                    phase,
                    progress: x[0],
                    time_remaining: x[1],
                    current_position: x[2],
                    current_velocity: x[3],
                    current_iq: x[4],
                })
            })
            .boxed(),
        K::CalibrationResult => (
            any::<bool>(),
            [f(), f(), f(), f(), f(), f(), f()],
            [f(), f(), f(), f(), f()],
            f(),
            any::<u16>(),
        )
            .prop_map(|(success, p, c, total_time, error_code)| {
                Payload::CalibrationResult(CalibrationResult {
                    success,
                    parameters: MotorParameters {
                        inertia: p[0],
                        torque_constant: p[1],
                        damping: p[2],
                        friction_coulomb: p[3],
                        friction_stribeck: p[4],
                        friction_vstribeck: p[5],
                        friction_viscous: p[6],
                    },
                    confidence: CalibrationConfidence {
                        overall: c[0],
                        inertia: c[1],
                        friction: c[2],
                        torque_constant: c[3],
                        validation_rms: c[4],
                    },
                    total_time,
                    error_code,
                })
            })
            .boxed(),
        K::PowerMetrics => (
            any::<[u32; 5]>(),
            any::<[i32; 2]>(),
            [f(), f(), f()],
            any::<[u16; 6]>(),
        )
            .prop_map(|(u, i, x, c)| {
                Payload::PowerMetrics(PowerMetrics {
                    vbus_mv: u[0],
                    ia_ma: i[0],
                    ib_ma: i[1],
                    i_rms_ma: x[0],
                    power_mw: u[1],
                    mcu_temp_c: x[1],
                    throttle_factor: x[2],
                    energy_mwh: u[2],
                    charge_mah: u[3],
                    active_time_ms: u[4],
                    faults: FaultCounters {
                        overcurrent: c[0],
                        overvoltage: c[1],
                        undervoltage: c[2],
                        overtemp: c[3],
                        driver_fault: c[4],
                        emergency_stops: c[5],
                    },
                })
            })
            .boxed(),
        K::EmergencyStop => (
            pick(EmergencyReason::ALL),
            any::<u32>(),
            any::<i32>(),
            f(),
            any::<u32>(),
        )
            .prop_map(|(reason, vbus_mv, current_ma, temp_c, timestamp_ms)| {
                Payload::EmergencyStop(EmergencyStop {
                    reason,
                    vbus_mv,
                    current_ma,
                    temp_c,
                    timestamp_ms,
                })
            })
            .boxed(),
        K::ConfigurePower | K::PowerConfigResponse => {
            (any::<[u32; 2]>(), any::<[u16; 2]>(), any::<[u8; 3]>())
                .prop_map(move |(a, b, c)| {
                    let p = PowerConfig {
                        vbus_overvoltage_mv: a[0],
                        vbus_undervoltage_mv: a[1],
                        max_rms_current_ma: b[0],
                        max_peak_current_ma: b[1],
                        temp_throttle_start_c: c[0],
                        temp_shutdown_c: c[1],
                        telemetry_rate_hz: c[2],
                    };
                    if kind == K::ConfigurePower {
                        Payload::ConfigurePower(p)
                    } else {
                        Payload::PowerConfigResponse(p)
                    }
                })
                .boxed()
        }
        K::RequestPowerConfig => Just(Payload::RequestPowerConfig).boxed(),
        K::RequestFaultHistory => Just(Payload::RequestFaultHistory).boxed(),
        K::FaultHistory => (
            prop::array::uniform10((
                any::<u8>(),
                any::<u32>(),
                any::<u16>(),
                any::<u16>(),
                any::<i8>(),
            )),
            any::<u32>(),
            any::<u8>(),
        )
            .prop_map(|(r, total_faults, valid_count)| {
                Payload::FaultHistory(FaultHistory {
                    records: r.map(|(fault_type, timestamp_sec, vbus_mv, current_ma, temp_c)| {
                        FaultRecord {
                            fault_type,
                            timestamp_sec,
                            vbus_mv,
                            current_ma,
                            temp_c,
                        }
                    }),
                    total_faults,
                    valid_count,
                })
            })
            .boxed(),
        K::Ack => any::<u32>().prop_map(Payload::Ack).boxed(),
        K::Nack => (any::<u32>(), any::<u16>())
            .prop_map(|(id, error)| Payload::Nack { id, error })
            .boxed(),
        K::ArmReady => Just(Payload::ArmReady).boxed(),
    }
}

pub fn header() -> impl Strategy<Value = Header> {
    (any::<u16>(), any::<u16>(), any::<u32>()).prop_map(|(source_id, target_id, msg_id)| Header {
        source_id,
        target_id,
        msg_id,
    })
}

/// Any message of any payload of `v`.
pub fn message(v: WireVersion) -> impl Strategy<Value = Message> {
    let kinds: Vec<BoxedStrategy<Payload>> = v.payloads().iter().map(|k| payload(*k, v)).collect();
    (header(), prop::strategy::Union::new(kinds))
        .prop_map(|(header, payload)| Message { header, payload })
}

/// A version and a message of it.
pub fn versioned_message() -> impl Strategy<Value = (WireVersion, Message)> {
    prop::sample::select(WireVersion::ALL.to_vec()).prop_flat_map(|v| (Just(v), message(v)))
}

// ---- Mirror types: serde derives in each version's variant order, so that
// real postcard produces the reference bytes. -----------------------------

#[derive(Serialize)]
pub enum StateV1 {
    Unconfigured,
    Inactive,
    Active,
    Error,
}

fn state_v1(s: LifecycleState) -> StateV1 {
    match s {
        LifecycleState::Unconfigured => StateV1::Unconfigured,
        LifecycleState::Inactive => StateV1::Inactive,
        LifecycleState::Active => StateV1::Active,
        LifecycleState::Error => StateV1::Error,
        LifecycleState::Calibrating => panic!("no Calibrating before v2.1"),
    }
}

#[derive(Serialize)]
pub enum MirrorV1 {
    SetTarget(SetTargetPayload),
    Configure,
    Activate,
    Deactivate,
    Reset,
    Encoder(EncoderTelemetry),
    JointStatus { state: StateV1, error_code: u16 },
    Ack(u32),
    Nack { id: u32, error: u16 },
    ArmReady,
}

#[derive(Serialize)]
pub enum MirrorV20 {
    SetTarget(SetTargetPayload),
    Configure,
    Activate,
    Deactivate,
    Reset,
    SetTargetV2(SetTargetPayloadV2),
    Encoder(EncoderTelemetry),
    JointStatus { state: StateV1, error_code: u16 },
    Ack(u32),
    Nack { id: u32, error: u16 },
    ArmReady,
}

#[derive(Serialize)]
pub enum MirrorV21 {
    SetTarget(SetTargetPayload),
    Configure,
    Activate,
    Deactivate,
    Reset,
    SetTargetV2(SetTargetPayloadV2),
    Encoder(EncoderTelemetry),
    JointStatus {
        state: LifecycleState,
        error_code: u16,
    },
    TelemetryStream(TelemetryStream),
    ConfigureTelemetry(ConfigureTelemetryPayload),
    RequestTelemetry,
    ConfigureAdaptive(ConfigureAdaptivePayload),
    RequestAdaptiveStatus,
    AdaptiveStatus(AdaptiveStatusPayload),
    StartCalibration(CalibrationRequest),
    StopCalibration,
    CalibrationStatus(CalibrationStatus),
    CalibrationResult(CalibrationResult),
    Ack(u32),
    Nack {
        id: u32,
        error: u16,
    },
    ArmReady,
}

#[derive(Serialize)]
pub enum MirrorV22 {
    SetTarget(SetTargetPayload),
    Configure,
    Activate,
    Deactivate,
    Reset,
    SetTargetV2(SetTargetPayloadV2),
    Encoder(EncoderTelemetry),
    JointStatus {
        state: LifecycleState,
        error_code: u16,
    },
    TelemetryStream(TelemetryStream),
    ConfigureTelemetry(ConfigureTelemetryPayload),
    RequestTelemetry,
    ConfigureAdaptive(ConfigureAdaptivePayload),
    RequestAdaptiveStatus,
    AdaptiveStatus(AdaptiveStatusPayload),
    StartCalibration(CalibrationRequest),
    StopCalibration,
    CalibrationStatus(CalibrationStatus),
    CalibrationResult(CalibrationResult),
    PowerMetrics(PowerMetrics),
    EmergencyStop(EmergencyStop),
    ConfigurePower(PowerConfig),
    RequestPowerConfig,
    PowerConfigResponse(PowerConfig),
    RequestFaultHistory,
    FaultHistory(FaultHistory),
    Ack(u32),
    Nack {
        id: u32,
        error: u16,
    },
    ArmReady,
}

#[derive(Serialize)]
pub struct Mirror<P> {
    pub header: Header,
    pub payload: P,
}

macro_rules! common_arms {
    ($m:ident, $p:expr, $state:expr, $more:ident) => {
        match $p {
            Payload::SetTarget(x) => $m::SetTarget(x),
            Payload::Configure => $m::Configure,
            Payload::Activate => $m::Activate,
            Payload::Deactivate => $m::Deactivate,
            Payload::Reset => $m::Reset,
            Payload::Encoder(x) => $m::Encoder(x),
            Payload::JointStatus { state, error_code } => $m::JointStatus {
                state: $state(state),
                error_code,
            },
            Payload::Ack(x) => $m::Ack(x),
            Payload::Nack { id, error } => $m::Nack { id, error },
            Payload::ArmReady => $m::ArmReady,
            other => return $more(other),
        }
    };
}

/// postcard's bytes for `msg` in `v`.
pub fn postcard_bytes(v: WireVersion, msg: &Message) -> Vec<u8> {
    let mut buf = [0u8; 512];
    let h = msg.header;
    let p = msg.payload;
    let used = match v {
        WireVersion::V1 => {
            let mirror_more = |_: Payload| -> MirrorV1 { panic!("not in v1") };
            let payload: MirrorV1 = (|| common_arms!(MirrorV1, p, state_v1, mirror_more))();
            postcard::to_slice(&Mirror { header: h, payload }, &mut buf)
                .unwrap()
                .len()
        }
        WireVersion::V2_0 => {
            let mirror_more = |o: Payload| -> MirrorV20 {
                match o {
                    Payload::SetTargetV2(x) => MirrorV20::SetTargetV2(x),
                    _ => panic!("not in v2.0"),
                }
            };
            let payload: MirrorV20 = (|| common_arms!(MirrorV20, p, state_v1, mirror_more))();
            postcard::to_slice(&Mirror { header: h, payload }, &mut buf)
                .unwrap()
                .len()
        }
        WireVersion::V2_1 => {
            let mirror_more = |o: Payload| -> MirrorV21 {
                match o {
                    Payload::SetTargetV2(x) => MirrorV21::SetTargetV2(x),
                    Payload::TelemetryStream(x) => MirrorV21::TelemetryStream(x),
                    Payload::ConfigureTelemetry(x) => MirrorV21::ConfigureTelemetry(x),
                    Payload::RequestTelemetry => MirrorV21::RequestTelemetry,
                    Payload::ConfigureAdaptive(x) => MirrorV21::ConfigureAdaptive(x),
                    Payload::RequestAdaptiveStatus => MirrorV21::RequestAdaptiveStatus,
                    Payload::AdaptiveStatus(x) => MirrorV21::AdaptiveStatus(x),
                    Payload::StartCalibration(x) => MirrorV21::StartCalibration(x),
                    Payload::StopCalibration => MirrorV21::StopCalibration,
                    Payload::CalibrationStatus(x) => MirrorV21::CalibrationStatus(x),
                    Payload::CalibrationResult(x) => MirrorV21::CalibrationResult(x),
                    _ => panic!("not in v2.1"),
                }
            };
            let same = |s: LifecycleState| s;
            let payload: MirrorV21 = (|| common_arms!(MirrorV21, p, same, mirror_more))();
            postcard::to_slice(&Mirror { header: h, payload }, &mut buf)
                .unwrap()
                .len()
        }
        WireVersion::V2_2 => {
            let mirror_more = |o: Payload| -> MirrorV22 {
                match o {
                    Payload::SetTargetV2(x) => MirrorV22::SetTargetV2(x),
                    Payload::TelemetryStream(x) => MirrorV22::TelemetryStream(x),
                    Payload::ConfigureTelemetry(x) => MirrorV22::ConfigureTelemetry(x),
                    Payload::RequestTelemetry => MirrorV22::RequestTelemetry,
                    Payload::ConfigureAdaptive(x) => MirrorV22::ConfigureAdaptive(x),
                    Payload::RequestAdaptiveStatus => MirrorV22::RequestAdaptiveStatus,
                    Payload::AdaptiveStatus(x) => MirrorV22::AdaptiveStatus(x),
                    Payload::StartCalibration(x) => MirrorV22::StartCalibration(x),
                    Payload::StopCalibration => MirrorV22::StopCalibration,
                    Payload::CalibrationStatus(x) => MirrorV22::CalibrationStatus(x),
                    Payload::CalibrationResult(x) => MirrorV22::CalibrationResult(x),
                    Payload::PowerMetrics(x) => MirrorV22::PowerMetrics(x),
                    Payload::EmergencyStop(x) => MirrorV22::EmergencyStop(x),
                    Payload::ConfigurePower(x) => MirrorV22::ConfigurePower(x),
                    Payload::RequestPowerConfig => MirrorV22::RequestPowerConfig,
                    Payload::PowerConfigResponse(x) => MirrorV22::PowerConfigResponse(x),
                    Payload::RequestFaultHistory => MirrorV22::RequestFaultHistory,
                    Payload::FaultHistory(x) => MirrorV22::FaultHistory(x),
                    _ => panic!("not in v2.2"),
                }
            };
            let same = |s: LifecycleState| s;
            let payload: MirrorV22 = (|| common_arms!(MirrorV22, p, same, mirror_more))();
            postcard::to_slice(&Mirror { header: h, payload }, &mut buf)
                .unwrap()
                .len()
        }
    };
    buf[..used].to_vec()
}
