//! The simulated joint's v2.1/v2.2 messages, end to end through the
//! client on the in-memory bus: segmented when over 64 bytes, decoded with
//! exact values, through a faulty bus, to several joints at once.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing
)]

use std::time::Duration;

use motorwire_can::client::{ClientConfig, Event, Outcome};
use motorwire_can::segmented::{LinkEvent, Links};
use motorwire_can::{Faults, SimConfig};
use motorwire_irpc::{
    CalibrationConfidence, CalibrationPhase, CalibrationRequest, CalibrationResult, FaultCounters,
    FaultHistory, Header, LifecycleState, Message, NackCode, Payload, PowerConfig,
    SetTargetPayloadV2, WireVersion,
};
use motorwire_sim::joint::{
    BUS_VOLTAGE_MV, CALIBRATION_ABORTED, CALIBRATION_PHASE_TIMEOUT, DEFAULT_POWER_CONFIG,
    FOC_LOOP_TIME_US, INERTIA, SIM_MOTOR_PARAMETERS, TORQUE_CONSTANT, WINDING_RESISTANCE,
};
use motorwire_sim::rig::Rig;
use motorwire_sim::{JointConfig, JointFault, SimJoint};

fn secs(s: f64) -> Duration {
    Duration::from_secs_f64(s)
}

fn rig(wire: WireVersion, client_node: u16, joints: &[JointConfig]) -> Rig {
    let client = ClientConfig {
        node_id: client_node,
        wire,
        ..ClientConfig::default()
    };
    Rig::new(SimConfig::default(), client, joints.iter().copied()).unwrap()
}

fn acked(rig: &mut Rig, node: u16, p: Payload) {
    assert_eq!(
        rig.request(node, p).unwrap().outcome,
        Outcome::Acked,
        "{p:?}"
    );
}

fn feedback(rig: &mut Rig) -> Vec<Message> {
    rig.take_events()
        .into_iter()
        .filter_map(|e| match e {
            Event::Feedback { message, .. } => Some(message),
            _ => None,
        })
        .filter(|m| {
            !matches!(
                m.payload,
                Payload::Encoder(_) | Payload::JointStatus { .. } | Payload::EmergencyStop(_)
            )
        })
        .collect()
}

fn len(m: &Message, wire: WireVersion) -> usize {
    m.encoded_len(wire).unwrap()
}

/// Twelve faults, one a second, every third an overtemperature.
fn twelve_faults(rig: &mut Rig, node: u16) {
    for k in 1..=12u64 {
        rig.run_until(Duration::from_secs(k)).unwrap();
        let now = rig.bus().now();
        let kind = if k.is_multiple_of(3) {
            JointFault::Overtemperature
        } else {
            JointFault::DriverFault
        };
        rig.joint_mut(node).unwrap().fault(now, kind);
    }
}

#[test]
fn fault_history_with_ten_records_and_power_metrics_reach_the_client_exactly() {
    let wire = WireVersion::V2_2;
    let joint = JointConfig {
        wire,
        uptime: Duration::from_secs(1_700_000_000),
        ..JointConfig::new(0x33)
    };
    let mut rig = rig(wire, 0x000, &[joint]);
    acked(&mut rig, 0x33, Payload::Configure);
    twelve_faults(&mut rig, 0x33);
    rig.take_events();

    acked(&mut rig, 0x33, Payload::RequestFaultHistory);
    let got = feedback(&mut rig);
    let [message] = got.as_slice() else {
        panic!("{got:?}")
    };
    let Payload::FaultHistory(history) = message.payload else {
        panic!("{message:?}")
    };
    assert_eq!(
        message.header,
        Header {
            source_id: 0x33,
            target_id: 0,
            msg_id: message.header.msg_id
        }
    );
    // The last ten of twelve, oldest first: faults 3 to 12, at the joint's
    // clock (its uptime); an overtemperature at 95 °C, the motor cooling
    // from there at rest (25 + 70·e^(−t/60)).
    assert_eq!((history.total_faults, history.valid_count), (12, 10));
    let temps = [95, 94, 93, 95, 94, 93, 95, 94, 93, 95];
    for (i, r) in history.records.iter().enumerate() {
        let k = i as u32 + 3;
        assert_eq!(
            r.fault_type,
            if k.is_multiple_of(3) { 4 } else { 5 },
            "record {i}"
        );
        assert_eq!(r.timestamp_sec, 1_700_000_000 + k, "record {i}");
        assert_eq!((r.vbus_mv, r.current_ma), (24_000, 0), "record {i}");
        assert_eq!(r.temp_c, temps[i], "record {i}");
    }
    // Header 4 (msg_id 1346), tag 1, ten records of 11, total 1, count 1.
    assert_eq!(len(message, wire), 117, "a segmented transfer");
    assert_eq!(rig.joint(0x33).unwrap().fault_history(), history);
    assert!(rig.client.stats().segmented_received >= 1);
    assert!(rig.joint(0x33).unwrap().stats().segmented_sent >= 1);

    // v2.2's RequestTelemetry: a TelemetryStream, then PowerMetrics.
    acked(&mut rig, 0x33, Payload::RequestTelemetry);
    let got = feedback(&mut rig);
    let joint = rig.joint(0x33).unwrap();
    assert_eq!(
        got.iter().map(|m| m.payload).collect::<Vec<_>>(),
        [
            Payload::TelemetryStream(joint.telemetry()),
            Payload::PowerMetrics(joint.power_metrics())
        ]
    );
    let Payload::PowerMetrics(p) = got[1].payload else {
        panic!()
    };
    assert_eq!(
        p.faults,
        FaultCounters {
            overcurrent: 0,
            overvoltage: 0,
            undervoltage: 0,
            overtemp: 4,
            driver_fault: 8,
            emergency_stops: 12
        }
    );
    assert_eq!(
        (p.vbus_mv, p.ia_ma, p.ib_ma, p.i_rms_ma, p.power_mw),
        (BUS_VOLTAGE_MV, 0, 0, 0.0, 0)
    );
    assert_eq!(
        (p.mcu_temp_c, p.throttle_factor),
        (35.0, 0.0),
        "94 °C: above shutdown"
    );
    assert_eq!((p.energy_mwh, p.charge_mah, p.active_time_ms), (0, 0, 0));

    // The power configuration: kept, answered, checked.
    acked(&mut rig, 0x33, Payload::RequestPowerConfig);
    assert_eq!(
        feedback(&mut rig)[0].payload,
        Payload::PowerConfigResponse(DEFAULT_POWER_CONFIG)
    );
    let config = PowerConfig {
        telemetry_rate_hz: 10,
        temp_throttle_start_c: 60,
        ..DEFAULT_POWER_CONFIG
    };
    acked(&mut rig, 0x33, Payload::ConfigurePower(config));
    assert_eq!(rig.joint(0x33).unwrap().power_config(), config);
    let bad = PowerConfig {
        vbus_undervoltage_mv: 40_000,
        ..config
    };
    assert_eq!(
        rig.request(0x33, Payload::ConfigurePower(bad))
            .unwrap()
            .outcome,
        Outcome::Nacked(NackCode::OUT_OF_LIMITS)
    );
    // Its telemetry_rate_hz: PowerMetrics every 100 ms.
    let t = rig.bus().now();
    rig.take_events();
    rig.run_until(t + secs(1.0)).unwrap();
    let periodic = feedback(&mut rig);
    assert_eq!(periodic.len(), 10, "{periodic:?}");
    assert!(
        periodic
            .iter()
            .all(|m| matches!(m.payload, Payload::PowerMetrics(_)))
    );
}

/// Node ids with two-byte varints and a joint far into its msg_ids: a
/// 9-byte header, the longest 11-bit node ids allow.
fn long_header_rig(wire: WireVersion) -> Rig {
    let joint = JointConfig {
        wire,
        first_msg_id: 0xF000_0000,
        // 2^63 µs: a ten-byte timestamp varint.
        uptime: Duration::from_micros(1 << 63),
        watchdog: Duration::ZERO,
        ..JointConfig::new(0x7F0)
    };
    rig(wire, 0x7E0, &[joint])
}

#[test]
fn a_telemetry_stream_over_64_bytes_carries_the_motion_model() {
    let wire = WireVersion::V2_1;
    let mut rig = long_header_rig(wire);
    acked(&mut rig, 0x7F0, Payload::Configure);
    acked(&mut rig, 0x7F0, Payload::Activate);
    acked(
        &mut rig,
        0x7F0,
        Payload::SetTargetV2(SetTargetPayloadV2::scurve(90.0, 100.0, 500.0, 2000.0)),
    );
    // 0.1 s in: accelerating.
    let t = rig.bus().now();
    rig.run_until(t + secs(0.1)).unwrap();
    rig.take_events();
    acked(&mut rig, 0x7F0, Payload::RequestTelemetry);
    let got = feedback(&mut rig);
    let [message] = got.as_slice() else {
        panic!("{got:?}")
    };
    let Payload::TelemetryStream(s) = message.payload else {
        panic!("{message:?}")
    };
    assert_eq!(s, rig.joint(0x7F0).unwrap().telemetry());
    assert_eq!(len(message, wire), 67, "over one frame");
    assert_eq!(message.header.source_id, 0x7F0);
    assert_eq!(message.header.target_id, 0x7E0);
    assert!(message.header.msg_id >= 0xF000_0000);
    assert!(s.timestamp_us >= 1 << 63);
    assert_eq!(s.foc_loop_time_us, FOC_LOOP_TIME_US);
    assert!(s.trajectory_active);
    // The model (module docs), to f32 rounding.
    let close = |a: f32, b: f64| (f64::from(a) - b).abs() <= 1e-5 * b.abs().max(1.0);
    let (acc, vel) = (f64::from(s.acceleration), f64::from(s.velocity));
    assert!(acc > 100.0 && vel > 1.0, "{s:?}");
    let torque = INERTIA * acc.to_radians();
    let iq = torque / TORQUE_CONSTANT;
    let vq = WINDING_RESISTANCE * iq + TORQUE_CONSTANT * vel.to_radians();
    assert!(close(s.torque_estimate, torque), "{s:?}");
    assert!(close(s.current_q, iq), "{s:?}");
    assert!(close(s.voltage_q, vq), "{s:?}");
    assert!(close(s.power, vq * iq), "{s:?}");
    assert!(close(
        s.load_percent,
        100.0 * torque / (INERTIA * 5000f64.to_radians())
    ));
    assert_eq!(s.current_d, 0.0);
    assert!(s.voltage_d < 0.0, "{s:?}");
    assert!(s.temperature_c > 25.0 && s.temperature_c < 26.0, "{s:?}");
    assert_eq!(s.warnings, 0);
}

fn calibration(phases: u8, phase_timeout: f32) -> Payload {
    Payload::StartCalibration(CalibrationRequest {
        phases,
        max_current: 2.0,
        max_velocity: 30.0,
        max_position_range: 20.0,
        phase_timeout,
        return_home: true,
    })
}

fn nacked(rig: &mut Rig, p: Payload, code: NackCode) {
    assert_eq!(
        rig.request(0x7F0, p).unwrap().outcome,
        Outcome::Nacked(code),
        "{p:?}"
    );
}

#[test]
fn calibration_streams_its_phases_and_ends_with_a_result_or_an_abort() {
    let wire = WireVersion::V2_1;
    let mut rig = long_header_rig(wire);
    let wrong = NackCode::CALIBRATION_WRONG_STATE;
    assert_eq!(wrong, NackCode(20));
    nacked(&mut rig, calibration(0, 1.0), wrong); // Unconfigured
    acked(&mut rig, 0x7F0, Payload::Configure);
    acked(&mut rig, 0x7F0, Payload::Activate);
    nacked(&mut rig, calibration(0, 1.0), wrong); // Active
    acked(&mut rig, 0x7F0, Payload::Deactivate);
    nacked(&mut rig, Payload::StopCalibration, wrong);
    nacked(&mut rig, calibration(0, 0.0), NackCode::OUT_OF_LIMITS);
    rig.take_events();

    // All five phases (mask 0), 0.5 s each.
    acked(&mut rig, 0x7F0, calibration(0, 1.0));
    let start = rig.bus().now();
    assert_eq!(
        rig.joint(0x7F0).unwrap().state(),
        LifecycleState::Calibrating
    );
    nacked(
        &mut rig,
        Payload::SetTargetV2(SetTargetPayloadV2::scurve(10.0, 100.0, 500.0, 2000.0)),
        NackCode::SET_TARGET_WRONG_STATE,
    );
    nacked(&mut rig, Payload::Activate, NackCode::ACTIVATE_WRONG_STATE);
    nacked(&mut rig, calibration(0, 1.0), wrong);
    rig.run_until(start + secs(3.0)).unwrap();
    let events = rig.take_events();
    let states: Vec<LifecycleState> = events
        .iter()
        .filter_map(|e| match e {
            Event::Feedback { message, .. } => match message.payload {
                Payload::JointStatus { state, .. } => Some(state),
                _ => None,
            },
            _ => None,
        })
        .collect();
    assert_eq!(states.last(), Some(&LifecycleState::Inactive));
    let got: Vec<Message> = events
        .into_iter()
        .filter_map(|e| match e {
            Event::Feedback { message, .. }
                if matches!(
                    message.payload,
                    Payload::CalibrationStatus(_) | Payload::CalibrationResult(_)
                ) =>
            {
                Some(message)
            }
            _ => None,
        })
        .collect();
    let statuses: Vec<_> = got
        .iter()
        .filter_map(|m| match m.payload {
            Payload::CalibrationStatus(s) => Some(s),
            _ => None,
        })
        .collect();
    use CalibrationPhase::*;
    let phases: Vec<CalibrationPhase> = statuses.iter().map(|s| s.phase).collect();
    let mut expected = Vec::new();
    for p in [
        InertiaTest,
        FrictionTest,
        TorqueConstantVerification,
        DampingTest,
        Validation,
    ] {
        expected.extend([p; 5]);
    }
    expected.push(Complete);
    assert_eq!(phases, expected);
    // Every 100 ms: progress k/25 of 2.5 s.
    for (k, s) in statuses.iter().enumerate().take(25) {
        assert!((s.progress - k as f32 / 25.0).abs() < 1e-6, "{k}: {s:?}");
        assert!(
            (s.time_remaining - (2.5 - k as f32 * 0.1)).abs() < 1e-5,
            "{k}: {s:?}"
        );
        assert_eq!((s.current_iq, s.current_velocity), (1.0, 0.0), "{k}");
    }
    assert_eq!((statuses[25].progress, statuses[25].current_iq), (1.0, 0.0));
    let result = got.last().unwrap();
    assert_eq!(
        result.payload,
        Payload::CalibrationResult(CalibrationResult {
            success: true,
            parameters: SIM_MOTOR_PARAMETERS,
            confidence: CalibrationConfidence {
                overall: 0.92,
                inertia: 0.97,
                friction: 0.92,
                torque_constant: 0.99,
                validation_rms: 0.015,
            },
            total_time: 2.5,
            error_code: 0,
        })
    );
    assert_eq!(len(result, wire), 64, "one full frame");
    assert_eq!(rig.joint(0x7F0).unwrap().state(), LifecycleState::Inactive);

    // Inertia and friction only, stopped 0.7 s in.
    acked(&mut rig, 0x7F0, calibration(0b11, 1.0));
    let start = rig.bus().now();
    rig.run_until(start + secs(0.7)).unwrap();
    rig.take_events();
    let received_before = rig.client.stats().segmented_received;
    acked(&mut rig, 0x7F0, Payload::StopCalibration);
    let stopped = rig.bus().now();
    let got = feedback(&mut rig);
    let [status, result] = got.as_slice() else {
        panic!("{got:?}")
    };
    let Payload::CalibrationStatus(s) = status.payload else {
        panic!("{status:?}")
    };
    assert_eq!(s.phase, Failed);
    let elapsed = (stopped - start).as_secs_f32();
    assert_eq!(
        result.payload,
        Payload::CalibrationResult(CalibrationResult {
            success: false,
            parameters: motorwire_irpc::MotorParameters {
                inertia: 0.0,
                torque_constant: 0.0,
                damping: 0.0,
                friction_coulomb: 0.0,
                friction_stribeck: 0.0,
                friction_vstribeck: 0.0,
                friction_viscous: 0.0,
            },
            confidence: CalibrationConfidence {
                overall: 0.0,
                inertia: 0.0,
                friction: 0.0,
                torque_constant: 0.0,
                validation_rms: 0.0,
            },
            total_time: elapsed,
            error_code: CALIBRATION_ABORTED,
        })
    );
    assert_eq!(len(result, wire), 65, "over one frame: segmented");
    assert_eq!(rig.client.stats().segmented_received, received_before + 1);
    assert_eq!(rig.joint(0x7F0).unwrap().state(), LifecycleState::Inactive);

    // A phase_timeout shorter than a phase fails it.
    acked(&mut rig, 0x7F0, calibration(0b1, 0.2));
    rig.run_until(rig.bus().now() + secs(1.0)).unwrap();
    let got = feedback(&mut rig);
    match got.last().map(|m| m.payload) {
        Some(Payload::CalibrationResult(r)) => {
            assert_eq!(
                (r.success, r.error_code),
                (false, CALIBRATION_PHASE_TIMEOUT)
            );
            assert!((r.total_time - 0.2).abs() < 1e-6, "{r:?}");
        }
        other => panic!("{other:?}"),
    }
    assert_eq!(rig.joint(0x7F0).unwrap().stats().calibrations, 3);
}

fn faulted_joints(wire: WireVersion, seed: u64, faults: Faults) -> Rig {
    let joints: Vec<JointConfig> = [0x21, 0x22, 0x23]
        .into_iter()
        .map(|n| JointConfig {
            wire,
            uptime: Duration::from_secs(1_700_000_000),
            ..JointConfig::new(n)
        })
        .collect();
    let mut rig = Rig::new(
        SimConfig {
            seed,
            faults,
            ..SimConfig::default()
        },
        ClientConfig {
            wire,
            ..ClientConfig::default()
        },
        joints,
    )
    .unwrap();
    for n in [0x21, 0x22, 0x23] {
        for k in 0..4u32 {
            let now = rig.bus().now();
            let kind = if k.is_multiple_of(2) {
                JointFault::Overtemperature
            } else {
                JointFault::DriverFault
            };
            rig.joint_mut(n).unwrap().fault(now, kind);
        }
    }
    rig
}

/// `n` RequestFaultHistory to each of three joints, one in flight to each
/// at all times; returns (acked, timed out, fault histories received, of
/// which equal to what the joint holds).
fn many_requests(rig: &mut Rig, n: usize) -> (usize, usize, usize, usize) {
    let nodes = [0x21u16, 0x22, 0x23];
    let expected: Vec<FaultHistory> = nodes
        .iter()
        .map(|&j| rig.joint(j).unwrap().fault_history())
        .collect();
    let mut sent = [0usize; 3];
    let (mut acked, mut timed_out, mut histories, mut exact) = (0, 0, 0, 0);
    let deadline = rig.bus().now() + Duration::from_secs(3600);
    while acked + timed_out < 3 * n {
        assert!(rig.bus().now() < deadline, "hung");
        for (i, &j) in nodes.iter().enumerate() {
            if sent[i] < n && rig.client.can_request(j) {
                let now = rig.bus().now();
                rig.client
                    .request(now, j, Payload::RequestFaultHistory)
                    .unwrap();
                sent[i] += 1;
            }
        }
        rig.step(Duration::from_millis(10)).unwrap();
        while let Some(e) = rig.client.poll_event() {
            match e {
                Event::Completed(c) => match c.outcome {
                    Outcome::Acked => acked += 1,
                    Outcome::TimedOut => timed_out += 1,
                    Outcome::Nacked(code) => panic!("nacked {code}"),
                },
                Event::Feedback { message, .. } => {
                    if let Payload::FaultHistory(h) = message.payload {
                        histories += 1;
                        let i = nodes
                            .iter()
                            .position(|&j| j == message.header.source_id)
                            .unwrap();
                        exact += usize::from(h == expected[i]);
                    }
                }
                _ => {}
            }
        }
    }
    (acked, timed_out, histories, exact)
}

#[test]
fn many_segmented_answers_from_three_joints_on_a_clean_bus() {
    let mut rig = faulted_joints(WireVersion::V2_2, 1, Faults::default());
    let (acked, timed_out, histories, exact) = many_requests(&mut rig, 50);
    assert_eq!((acked, timed_out, histories, exact), (150, 0, 150, 150));
}

#[test]
fn segmented_answers_through_drops_duplicates_reorders_and_delays_end_typed() {
    let faults = Faults {
        drop: 0.03,
        duplicate: 0.03,
        reorder: 0.03,
        delay: 0.03,
        ..Faults::default()
    };
    let mut rig = faulted_joints(WireVersion::V2_2, 7, faults);
    let (acked, timed_out, histories, exact) = many_requests(&mut rig, 100);
    assert_eq!(acked + timed_out, 300);
    // Without corruption every history that arrives is exact; most arrive.
    assert_eq!(histories, exact);
    assert!(histories >= 200, "{histories} of 300");
    assert!(acked >= 280, "{acked} acked, {timed_out} timed out");
    let s = rig.client.stats();
    assert!(s.retransmissions > 0, "{s:?}");
    let bus = rig.bus().stats();
    assert!(
        bus.dropped > 0 && bus.duplicated > 0 && bus.reordered > 0,
        "{bus:?}"
    );
}

#[test]
fn segmented_answers_through_corruption_end_typed_without_panics() {
    let faults = Faults {
        drop: 0.02,
        corrupt: 0.05,
        reorder: 0.02,
        ..Faults::default()
    };
    for seed in 0..3 {
        let mut rig = faulted_joints(WireVersion::V2_2, seed, faults);
        let (acked, timed_out, _, _) = many_requests(&mut rig, 30);
        assert_eq!(acked + timed_out, 90, "seed {seed}");
    }
}

#[test]
fn the_joint_takes_segmented_requests_and_survives_bad_ones() {
    let mut joint = SimJoint::new(JointConfig {
        wire: WireVersion::V2_2,
        encoder_period: Duration::ZERO,
        status_period: Duration::ZERO,
        uptime: Duration::from_secs(1_700_000_000),
        ..JointConfig::new(0x10)
    })
    .unwrap();
    joint.fault(Duration::ZERO, JointFault::DriverFault);
    joint.fault(Duration::ZERO, JointFault::Overtemperature);
    while joint.poll_transmit().is_some() {}
    let mut host = Links::new(0x000, Duration::from_secs(1)).unwrap();
    let encode = |m: &Message| {
        let mut b = vec![0u8; 256];
        let n = m.encode(WireVersion::V2_2, &mut b).unwrap();
        b.truncate(n);
        b
    };
    let exchange = |host: &mut Links, joint: &mut SimJoint| {
        let mut acted = Vec::new();
        loop {
            let mut quiet = true;
            while let Some(f) = host.poll_transmit() {
                acted.extend(joint.handle_frame(Duration::ZERO, &f));
                quiet = false;
            }
            while let Some(f) = joint.poll_transmit() {
                if f.id().is_extended() {
                    host.handle_frame(Duration::ZERO, &f);
                }
                quiet = false;
            }
            if quiet {
                return acted;
            }
        }
    };
    // A short request as a segmented transfer (an ISO-TP single frame on
    // the extended id, as Linux's isotpsend would send it).
    let request = Message {
        header: Header {
            source_id: 0,
            target_id: 0x10,
            msg_id: 5,
        },
        payload: Payload::RequestFaultHistory,
    };
    host.send_message(Duration::ZERO, 0x10, encode(&request), None)
        .unwrap();
    let acted = exchange(&mut host, &mut joint);
    assert_eq!(acted.len(), 1);
    assert_eq!(acted[0].answer, Payload::Ack(5));
    // Its answer came segmented: a FaultHistory of one real fault.
    let mut got = None;
    while let Some(e) = host.poll_event() {
        if let LinkEvent::Message {
            source: 0x10,
            bytes,
            ..
        } = e
        {
            got = Some(Message::decode(WireVersion::V2_2, &bytes).unwrap());
        }
    }
    let got = got.expect("a segmented FaultHistory");
    assert_eq!(got.payload, Payload::FaultHistory(joint.fault_history()));
    assert_eq!(joint.fault_history().valid_count, 2);
    // A long message that is not a request: reassembled, not answered.
    let mut history = got;
    history.header = Header {
        source_id: 0,
        target_id: 0x10,
        msg_id: 6,
    };
    host.send_message(Duration::ZERO, 0x10, encode(&history), None)
        .unwrap();
    assert!(exchange(&mut host, &mut joint).is_empty());
    // Garbage that reassembles, and a header naming another sender.
    host.send_message(Duration::ZERO, 0x10, vec![0xFF; 80], None)
        .unwrap();
    assert!(exchange(&mut host, &mut joint).is_empty());
    let mut forged = request;
    forged.header.source_id = 0x20;
    host.send_message(Duration::ZERO, 0x10, encode(&forged), None)
        .unwrap();
    assert!(exchange(&mut host, &mut joint).is_empty());
    let s = joint.stats();
    assert_eq!((s.segmented_received, s.bad_frames), (4, 2));
    assert!(s.segmented_sent >= 1);
}
