//! `motorwire bridge` driving serial bus servos as a user runs it: the
//! SO-101 and Koch maps on the simulated servos (`--bus sim`), and a map
//! whose port is the pseudo-terminal of `motorwire sim servos` (`--bus
//! none`), moved, held to the calibrated range and stopped.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use std::io::Write;
use std::time::{Duration, Instant};

use serde_json::Value;

fn command(motor: &str, setpoint: f64) -> String {
    format!(
        "{{\"motor_id\":\"{motor}\",\"timestamp\":{},\"control_mode\":\"position\",\"setpoint\":{setpoint}}}\n",
        common::now_ms()
    )
}

/// Runs `motorwire ARGS`, sends `lines` one at a time (each after the
/// answer `wait` names for the one before), then the emergency stop, and
/// returns every line it wrote.
fn drive(args: &[&str], lines: &[(String, &str)]) -> Vec<Value> {
    let mut child = common::spawn(args);
    let mut stdin = child.stdin.take().unwrap();
    let mut out = common::Lines::of(child.stdout.take().unwrap());
    out.until("ready", Duration::from_secs(20), |l| {
        l.contains("\"ready\"")
    });
    for (line, wait) in lines {
        stdin.write_all(line.as_bytes()).unwrap();
        let wait = (*wait).to_owned();
        out.until(&wait, Duration::from_secs(20), |l| l.contains(&wait));
    }
    stdin.write_all(b"{\"emergency_stop\":true}\n").unwrap();
    out.until("the stop's result", Duration::from_secs(20), |l| {
        l.contains("\"emergency_stop\":true")
    });
    drop(stdin);
    let status = child.wait().unwrap();
    assert!(status.success(), "{status:?}");
    out.finish()
        .iter()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

#[test]
fn the_so101_and_koch_maps_move_and_stop_on_the_simulated_servos() {
    for (map, motor, target) in [
        ("fixtures/maps/so101.toml", "elbow_flex", 40.0),
        ("fixtures/maps/koch.toml", "elbow_flex", -40.0),
    ] {
        let out = drive(
            &[
                "bridge",
                "--map",
                map,
                "--bus",
                "sim",
                "--feedback-hz",
                "50",
            ],
            &[
                (command(motor, target), "\"arrived\""),
                // Beyond the calibrated range (±87.9° for both).
                (command(motor, 120.0), "outside_limit"),
            ],
        );
        let arrived = out.iter().find(|v| v["arrived"] == true).unwrap();
        assert_eq!(arrived["motor_id"], motor, "{map}");
        let refused = out
            .iter()
            .find(|v| v["ok"] == false)
            .unwrap_or_else(|| panic!("{map}: {out:?}"));
        assert_eq!(refused["error"]["rule"], "outside_limit", "{map}");
        // Arrived where it was sent, as the servo's own position reads
        // through its calibration; its feedback is WIA MotorFeedback.
        let error = arrived["motors"][0]["error"].as_f64().unwrap();
        assert!(error < 0.1, "{map}: {arrived}");
        assert!(
            out.iter()
                .any(|v| v["feedback"]["motor_id"] == motor && v["feedback"]["voltage"] == 12.0),
            "{map}"
        );
        // The stop is acknowledged by every servo.
        let stop = out.iter().find(|v| v["emergency_stop"] == true).unwrap();
        assert_eq!(stop["acked"].as_array().unwrap().len(), 6, "{map}: {stop}");
    }
}

#[test]
fn the_bridge_drives_servos_on_a_pseudo_terminal() {
    let dir = std::env::temp_dir().join(format!("mw-servo-bridge-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let link = dir.join("ttyFEETECH");
    let link_s = link.to_str().unwrap().to_owned();
    let mut servos = common::spawn(&[
        "sim",
        "servos",
        "--protocol",
        "scs0",
        "--model",
        "sts3215",
        "--ids",
        "1,2",
        "--pty",
        &link_s,
    ]);
    let start = Instant::now();
    while !link.exists() && start.elapsed() < Duration::from_secs(10) {
        std::thread::sleep(Duration::from_millis(20));
    }
    let map = dir.join("map.toml");
    std::fs::write(
        &map,
        format!(
            "[motors.pan]\ndialect = \"feetech\"\nport = \"{link_s}\"\nid = 1\nmodel = \"sts3215\"\n\
             calibration = {{ homing_offset = 0, range_min = 1048, range_max = 3048, drive_mode = 0 }}\n\
             limits = {{ max_velocity = 360, max_acceleration = 3600 }}\n\n\
             [motors.lift]\ndialect = \"feetech\"\nport = \"{link_s}\"\nid = 2\nmodel = \"sts3215\"\n"
        ),
    )
    .unwrap();
    let out = drive(
        &["bridge", "--map", map.to_str().unwrap(), "--bus", "none"],
        &[(command("pan", 25.0), "\"arrived\"")],
    );
    servos.kill().unwrap();
    let _ = servos.wait();
    let result = out
        .iter()
        .find(|v| v["line"] == 1 && v.get("ok").is_some())
        .unwrap();
    assert_eq!(result["ok"], true, "{out:?}");
    assert!(
        out.iter()
            .any(|v| v["arrived"] == true && v["motor_id"] == "pan")
    );
    let stop = out.iter().find(|v| v["emergency_stop"] == true).unwrap();
    assert_eq!(stop["acked"], serde_json::json!(["lift", "pan"]), "{stop}");
    // A map with a CAN device is refused on --bus none, naming it.
    let o = common::run(
        &[
            "bridge",
            "--map",
            "fixtures/maps/demo-arm.toml",
            "--bus",
            "none",
        ],
        b"",
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(err.contains("--bus none: motors."), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}
