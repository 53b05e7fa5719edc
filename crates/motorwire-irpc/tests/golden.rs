//! Golden bytes: every vector of WIRE-FACTS §1.4, and one message of every
//! payload in every wire version (the bytes were produced by postcard 1.x
//! from serde mirror types in each version's variant order).
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing
)]

mod common;

use common::*;
use motorwire_irpc::*;

const ARM: u16 = 0x0000;
const JOINT: u16 = 0x0010;

fn test_one(v: WireVersion, msg: Message, expected: &str) {
    let expected = hex(expected);
    let mut buf = [0u8; 256];
    let n = msg.encode(v, &mut buf).unwrap();
    assert_eq!(to_hex(&buf[..n]), to_hex(&expected), "{v} {msg:?}");
    assert_eq!(msg.encoded_len(v).unwrap(), expected.len());
    assert_eq!(Message::decode(v, &expected).unwrap(), msg, "{v}");
}

fn set_target_v2(profile: MotionProfile, jerk: f32) -> Payload {
    Payload::SetTargetV2(SetTargetPayloadV2 {
        target_angle: 90.0,
        max_velocity: 100.0,
        target_velocity: 0.0,
        max_acceleration: 500.0,
        max_deceleration: 500.0,
        max_jerk: jerk,
        profile,
        max_current: 0.0,
        max_temperature: 0.0,
    })
}

fn msg(source_id: u16, target_id: u16, msg_id: u32, payload: Payload) -> Message {
    Message {
        header: Header {
            source_id,
            target_id,
            msg_id,
        },
        payload,
    }
}

#[test]
fn wire_facts_vectors() {
    use WireVersion::*;
    test_one(
        V2_0,
        msg(ARM, JOINT, 42, set_target_v2(MotionProfile::SCurve, 2000.0)),
        "00 10 2a 05 00 00 b4 42 00 00 c8 42 00 00 00 00 00 00 fa 43 00 00 fa 43 00 00 fa 44 01 00 00 00 00 00 00 00 00",
    );
    test_one(
        V2_0,
        msg(
            ARM,
            JOINT,
            42,
            set_target_v2(MotionProfile::Trapezoidal, 0.0),
        ),
        "00 10 2a 05 00 00 b4 42 00 00 c8 42 00 00 00 00 00 00 fa 43 00 00 fa 43 00 00 00 00 00 00 00 00 00 00 00 00 00",
    );
    test_one(
        V2_0,
        msg(
            ARM,
            JOINT,
            5,
            Payload::SetTarget(SetTargetPayload {
                target_angle: 90.0,
                velocity_limit: 150.0,
            }),
        ),
        "00 10 05 00 00 00 b4 42 00 00 16 43",
    );
    test_one(V2_0, msg(ARM, JOINT, 1, Payload::Configure), "00 10 01 01");
    test_one(
        V2_0,
        msg(JOINT, ARM, 42, Payload::Ack(42)),
        "10 00 2a 08 2a",
    );
    test_one(
        V2_1,
        msg(JOINT, ARM, 42, Payload::Ack(42)),
        "10 00 2a 12 2a",
    );
    test_one(
        V2_0,
        msg(JOINT, ARM, 42, Payload::Nack { id: 42, error: 255 }),
        "10 00 2a 09 2a ff 01",
    );
    test_one(
        V2_0,
        msg(ARM, 0xFFFF, 0, Payload::ArmReady),
        "00 ff ff 03 00 0a",
    );
    test_one(
        V2_1,
        msg(ARM, 0xFFFF, 0, Payload::ArmReady),
        "00 ff ff 03 00 14",
    );
}

#[test]
fn the_documents_example_is_37_bytes_and_fits_a_48_byte_frame() {
    let m = msg(ARM, JOINT, 42, set_target_v2(MotionProfile::SCurve, 2000.0));
    assert_eq!(m.encoded_len(WireVersion::V2_0).unwrap(), 37);
    let mut frame = [0xEEu8; 64];
    assert_eq!(m.encode_frame(WireVersion::V2_0, &mut frame).unwrap(), 48);
    assert!(frame[37..48].iter().all(|b| *b == 0));
    assert_eq!(
        Message::decode_frame(WireVersion::V2_0, &frame[..48]).unwrap(),
        m
    );
    assert_eq!(
        Message::decode_frame(WireVersion::V2_0, &frame[..64]).unwrap_err(),
        Error::NonZeroPadding { offset: 48 }
    );
}

/// A fixed message for every payload, with values that exercise multi-byte
/// varints, negative zigzags and every field.
fn sample(kind: PayloadKind, v: WireVersion) -> Payload {
    use PayloadKind as K;
    match kind {
        K::SetTarget => Payload::SetTarget(SetTargetPayload {
            target_angle: -45.5,
            velocity_limit: 30.0,
        }),
        K::Configure => Payload::Configure,
        K::Activate => Payload::Activate,
        K::Deactivate => Payload::Deactivate,
        K::Reset => Payload::Reset,
        K::SetTargetV2 => set_target_v2(MotionProfile::Adaptive, -1.0),
        K::Encoder => Payload::Encoder(EncoderTelemetry {
            position: 12.5,
            velocity: -3.25,
        }),
        K::JointStatus => Payload::JointStatus {
            state: if v.has_calibrating_state() {
                LifecycleState::Calibrating
            } else {
                LifecycleState::Error
            },
            error_code: 300,
        },
        K::TelemetryStream => Payload::TelemetryStream(TelemetryStream {
            timestamp_us: 1_704_067_200_000_000,
            position: 1.0,
            velocity: 2.0,
            acceleration: 3.0,
            current_d: 4.0,
            current_q: 5.0,
            voltage_d: 6.0,
            voltage_q: 7.0,
            torque_estimate: 8.0,
            power: 9.0,
            load_percent: 10.0,
            foc_loop_time_us: 100,
            temperature_c: 42.5,
            warnings: 0x8001,
            trajectory_active: true,
        }),
        K::ConfigureTelemetry => Payload::ConfigureTelemetry(ConfigureTelemetryPayload {
            mode: TelemetryMode::OnChange,
            rate_hz: 1000,
            change_threshold: 0.5,
        }),
        K::RequestTelemetry => Payload::RequestTelemetry,
        K::ConfigureAdaptive => Payload::ConfigureAdaptive(ConfigureAdaptivePayload {
            coolstep_enable: true,
            coolstep_min_current: 0.25,
            coolstep_threshold: 0.5,
            dcstep_enable: false,
            dcstep_threshold: 1.0,
            dcstep_max_derating: 0.75,
            stallguard_enable: true,
            stallguard_current_threshold: 2.0,
            stallguard_velocity_threshold: 4.0,
        }),
        K::RequestAdaptiveStatus => Payload::RequestAdaptiveStatus,
        K::AdaptiveStatus => Payload::AdaptiveStatus(AdaptiveStatusPayload {
            load_percent: 55.0,
            current_scale: 0.8,
            coolstep_enabled: true,
            power_savings_percent: 12.0,
            energy_saved_wh: 1.5,
            velocity_scale: 1.0,
            dcstep_enabled: false,
            dcstep_derating: true,
            stall_status: StallStatus::Warning,
            stallguard_enabled: true,
            stall_confidence: 0.9,
        }),
        K::StartCalibration => Payload::StartCalibration(CalibrationRequest {
            phases: 0x1F,
            max_current: 3.0,
            max_velocity: 90.0,
            max_position_range: 180.0,
            phase_timeout: 5.0,
            return_home: true,
        }),
        K::StopCalibration => Payload::StopCalibration,
        K::CalibrationStatus => Payload::CalibrationStatus(CalibrationStatus {
            phase: CalibrationPhase::DampingTest,
            progress: 0.5,
            time_remaining: 2.0,
            current_position: 10.0,
            current_velocity: -1.0,
            current_iq: 0.125,
        }),
        K::CalibrationResult => Payload::CalibrationResult(CalibrationResult {
            success: true,
            parameters: MotorParameters {
                inertia: 0.001,
                torque_constant: 0.05,
                damping: 0.002,
                friction_coulomb: 0.01,
                friction_stribeck: 0.02,
                friction_vstribeck: 0.1,
                friction_viscous: 0.003,
            },
            confidence: CalibrationConfidence {
                overall: 0.95,
                inertia: 0.9,
                friction: 0.85,
                torque_constant: 0.99,
                validation_rms: 0.01,
            },
            total_time: 12.5,
            error_code: 0,
        }),
        K::PowerMetrics => Payload::PowerMetrics(PowerMetrics {
            vbus_mv: 48_000,
            ia_ma: -1500,
            ib_ma: 1500,
            i_rms_ma: 1060.5,
            power_mw: 72_000,
            mcu_temp_c: 45.0,
            throttle_factor: 1.0,
            energy_mwh: 123_456,
            charge_mah: 2_500,
            active_time_ms: 3_600_000,
            faults: FaultCounters {
                overcurrent: 1,
                overvoltage: 2,
                undervoltage: 3,
                overtemp: 4,
                driver_fault: 5,
                emergency_stops: 600,
            },
        }),
        K::EmergencyStop => Payload::EmergencyStop(EmergencyStop {
            reason: EmergencyReason::ManualStop,
            vbus_mv: 47_500,
            current_ma: -20_000,
            temp_c: 61.5,
            timestamp_ms: 99_999,
        }),
        K::ConfigurePower | K::PowerConfigResponse => {
            let p = PowerConfig {
                vbus_overvoltage_mv: 56_000,
                vbus_undervoltage_mv: 36_000,
                max_rms_current_ma: 8_000,
                max_peak_current_ma: 15_000,
                temp_throttle_start_c: 70,
                temp_shutdown_c: 90,
                telemetry_rate_hz: 100,
            };
            if kind == K::ConfigurePower {
                Payload::ConfigurePower(p)
            } else {
                Payload::PowerConfigResponse(p)
            }
        }
        K::RequestPowerConfig => Payload::RequestPowerConfig,
        K::RequestFaultHistory => Payload::RequestFaultHistory,
        K::FaultHistory => {
            let mut records = [FaultRecord::default(); 10];
            for (i, r) in records.iter_mut().enumerate() {
                *r = FaultRecord {
                    fault_type: i as u8,
                    timestamp_sec: 1000 * i as u32,
                    vbus_mv: 48_000,
                    current_ma: 200 * i as u16,
                    temp_c: -5 + 10 * i as i8,
                };
            }
            Payload::FaultHistory(FaultHistory {
                records,
                total_faults: 12,
                valid_count: 10,
            })
        }
        K::Ack => Payload::Ack(0xDEAD_BEEF),
        K::Nack => Payload::Nack { id: 7, error: 4 },
        K::ArmReady => Payload::ArmReady,
    }
}

const EVERY_VARIANT: &str = include_str!("every_variant.golden");

#[test]
fn every_variant_of_every_version() {
    let mut lines = EVERY_VARIANT
        .lines()
        .filter(|l| !l.trim().is_empty() && !l.starts_with('#'));
    let mut count = 0;
    for v in WireVersion::ALL {
        for kind in v.payloads() {
            let m = msg(0x0123, 0x4567, 0x89AB_CDEF, sample(*kind, v));
            let line = lines
                .next()
                .unwrap_or_else(|| panic!("no golden line for {v} {kind}"));
            let (label, bytes) = line.split_once(':').unwrap();
            assert_eq!(label.trim(), format!("{v} {kind}"));
            // The golden bytes are postcard's, too.
            assert_eq!(to_hex(&postcard_bytes(v, &m)), bytes.trim(), "{v} {kind}");
            test_one(v, m, bytes);
            count += 1;
        }
    }
    assert!(lines.next().is_none());
    assert_eq!(count, 10 + 11 + 21 + 28);
}
