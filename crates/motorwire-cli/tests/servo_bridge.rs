//! `motorwire bridge` driving serial bus servos as a user runs it: the
//! SO-101 and Koch maps on the simulated servos (`--bus sim`), and a map
//! whose port is the pseudo-terminal of `motorwire sim servos` (`--bus
//! none`), moved, held to the calibrated range and stopped.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use std::io::Write;
use std::time::Duration;

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
    let (mut servos, link_s) = common::sim_servos(
        &dir,
        "ttyFEETECH",
        &["--protocol", "scs0", "--model", "sts3215", "--ids", "1,2"],
    );
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

/// Register `address` (`length` bytes) of Feetech servo `id` on the port
/// at `path`, read as the SDK reads it.
fn read_register(path: &str, id: u8, address: u16, length: u16) -> i64 {
    use std::io::Read;
    let mut port = serialport::new(path, 1_000_000)
        .timeout(Duration::from_millis(500))
        .open_native()
        .unwrap();
    let ask = motorwire_servo::encode(
        motorwire_servo::Protocol::Scs0,
        &motorwire_servo::Instruction::Read {
            id,
            address,
            length,
        },
    )
    .unwrap();
    port.write_all(&ask).unwrap();
    let mut answer = vec![0; 6 + usize::from(length)];
    port.read_exact(&mut answer).unwrap();
    let status = motorwire_servo::decode_status(
        motorwire_servo::Protocol::Scs0,
        &answer,
        Some(usize::from(length)),
    )
    .unwrap()
    .status;
    i64::from(
        motorwire_servo::Protocol::Scs0
            .value_of(&status.params)
            .unwrap(),
    )
}

/// `motorwire servo calibrate` on servos a simulated hand sweeps 60° each
/// way: the swept range and the homing offset are written into the map
/// (its comments kept) and into the servos' registers, a whole-turn joint
/// gets the whole turn, and the bridge then refuses a goal beyond the
/// calibrated range.
#[test]
fn calibrate_writes_the_swept_ranges_into_the_map_and_the_servos() {
    let dir = std::env::temp_dir().join(format!("mw-servo-calibrate-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (mut servos, link) = common::sim_servos(
        &dir,
        "ttyARM",
        &[
            "--protocol",
            "scs0",
            "--model",
            "sts3215",
            "--ids",
            "1,2",
            "--sweep",
            "60",
            "--sweep-period-ms",
            "200",
        ],
    );
    let map = dir.join("arm.toml");
    std::fs::write(
        &map,
        format!(
            "# my arm\n[motors.pan]\ndialect = \"feetech\" # the base\nport = \"{link}\"\nid = 1\nmodel = \"sts3215\"\n\n\
             [motors.roll]\ndialect = \"feetech\"\nport = \"{link}\"\nid = 2\nmodel = \"sts3215\"\n"
        ),
    )
    .unwrap();
    let map_s = map.to_str().unwrap();
    let mut child = common::spawn(&["servo", "calibrate", "--map", map_s, "--full-turn", "roll"]);
    let mut stdin = child.stdin.take().unwrap();
    std::thread::sleep(Duration::from_millis(300));
    stdin.write_all(b"\n").unwrap();
    // Seven sweeps of the hand.
    std::thread::sleep(Duration::from_millis(1400));
    stdin.write_all(b"\n").unwrap();
    drop(stdin);
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    let told: Vec<Value> = String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    let pan = told.iter().find(|v| v["motor_id"] == "pan").unwrap();
    let (min, max) = (
        pan["range_min"].as_i64().unwrap(),
        pan["range_max"].as_i64().unwrap(),
    );
    // 60° each way is 682.5 steps of 4096 (1365 in all): read every 10
    // ms or so, the peaks are caught within a few steps (a loaded machine
    // reads less often: 88 % at least).
    assert!((1200..=1366).contains(&(max - min)), "{pan}");
    let roll = told.iter().find(|v| v["motor_id"] == "roll").unwrap();
    assert_eq!(
        (roll["range_min"].clone(), roll["range_max"].clone()),
        (0.into(), 4095.into())
    );
    let text = std::fs::read_to_string(&map).unwrap();
    assert!(
        text.starts_with("# my arm\n") && text.contains("# the base"),
        "{text}"
    );
    let expected = format!(
        "calibration = {{ homing_offset = {}, range_min = {min}, range_max = {max}, drive_mode = 0 }}",
        pan["homing_offset"]
    );
    assert!(text.contains(&expected), "{text}");
    // The servo holds them too: Min_Position_Limit (9), Max (11),
    // Homing_Offset (31, sign-magnitude bit 11).
    assert_eq!(read_register(&link, 1, 9, 2), min);
    assert_eq!(read_register(&link, 1, 11, 2), max);
    let offset = read_register(&link, 1, 31, 2);
    let offset = if offset & 0x800 != 0 {
        -(offset & 0x7FF)
    } else {
        offset
    };
    assert_eq!(offset, pan["homing_offset"].as_i64().unwrap());
    // The bridge then holds the pan inside its calibrated range.
    let beyond = 360.0 * ((max - min) as f64 / 2.0 + 20.0) / 4095.0;
    let o = common::run(
        &["bridge", "--map", map_s, "--bus", "none", "--max-age", "0"],
        format!(
            "{{\"motor_id\":\"pan\",\"timestamp\":0,\"control_mode\":\"position\",\"setpoint\":{beyond}}}\n"
        )
        .as_bytes(),
    );
    let text = String::from_utf8(o.stdout).unwrap();
    assert!(text.contains("\"rule\":\"outside_limit\""), "{text}");
    servos.kill().unwrap();
    let _ = servos.wait();
    let _ = std::fs::remove_dir_all(&dir);
}

/// A LeRobot calibration file is the same arm as a bus map: each motor's
/// id and calibration as LeRobot wrote them, its model from the robot,
/// and the bridge's goals read through them (10° from the middle of
/// 758..=3292 is step 2139).
#[test]
fn a_lerobot_calibration_file_imports_as_the_same_arm() {
    let dir = std::env::temp_dir().join(format!("mw-servo-import-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("so101_follower.json");
    std::fs::write(
        &file,
        r#"{"shoulder_pan": {"id": 1, "drive_mode": 0, "homing_offset": -1470, "range_min": 758, "range_max": 3292},
            "gripper": {"id": 6, "drive_mode": 0, "homing_offset": 1441, "range_min": 1980, "range_max": 3390}}"#,
    )
    .unwrap();
    let o = common::run(
        &[
            "servo",
            "import-lerobot",
            file.to_str().unwrap(),
            "--port",
            "/dev/ttyACM0",
            "--robot",
            "so101",
        ],
        b"",
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let map = String::from_utf8(o.stdout).unwrap();
    assert!(
        map.contains("calibration = { homing_offset = -1470, range_min = 758, range_max = 3292, drive_mode = 0 }"),
        "{map}"
    );
    let path = dir.join("so101.toml");
    std::fs::write(&path, &map).unwrap();
    let t = common::run(
        &[
            "translate",
            "--map",
            path.to_str().unwrap(),
            "--to",
            "feetech",
        ],
        br#"{"motor_id":"shoulder_pan","timestamp":0,"control_mode":"position","setpoint":10}
"#,
    );
    let v: Value = serde_json::from_str(String::from_utf8(t.stdout).unwrap().trim()).unwrap();
    // Goal_Position 2139 = 0x085B, little-endian, after the torque and the
    // acceleration (0: no limit in the map).
    let bytes = v["packets"][0]["bytes"].as_str().unwrap();
    assert!(
        bytes.starts_with("fffffe0d83280801010".to_owned().as_str()) && bytes.contains("5b08"),
        "{v}"
    );
    // A file that is not LeRobot's is refused, naming it.
    std::fs::write(&file, r#"{"pan": {"id": 1}}"#).unwrap();
    let o = common::run(
        &[
            "servo",
            "import-lerobot",
            file.to_str().unwrap(),
            "--port",
            "/dev/ttyACM0",
            "--model",
            "sts3215",
        ],
        b"",
    );
    assert_eq!(o.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&o.stderr).contains("not a LeRobot calibration file"));
    let _ = std::fs::remove_dir_all(&dir);
}

/// The servos' port fails (the simulated servos' process killed, as a USB
/// adapter pulled out) and comes back (started again on the same path):
/// the bridge says so, takes its servos offline, opens the port again and
/// drives them once they answer.
#[test]
fn a_servo_port_that_fails_is_opened_again() {
    let dir = std::env::temp_dir().join(format!("mw-servo-reopen-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let args = ["--protocol", "scs0", "--model", "sts3215", "--ids", "1"];
    let (mut servos, link) = common::sim_servos(&dir, "ttyREOPEN", &args);
    let map = dir.join("map.toml");
    std::fs::write(
        &map,
        format!(
            "[motors.pan]\ndialect = \"feetech\"\nport = \"{link}\"\nid = 1\nmodel = \"sts3215\"\n"
        ),
    )
    .unwrap();
    let mut child = common::spawn(&[
        "bridge",
        "--map",
        map.to_str().unwrap(),
        "--bus",
        "none",
        "--feedback-hz",
        "0",
    ]);
    let mut stdin = child.stdin.take().unwrap();
    let mut out = common::Lines::of(child.stdout.take().unwrap());
    out.until("ready", Duration::from_secs(20), |l| {
        l.contains("\"ready\"")
    });
    servos.kill().unwrap();
    let _ = servos.wait();
    out.until("offline", Duration::from_secs(20), |l| {
        l.contains("\"offline\"")
    });
    let (mut servos, _) = common::sim_servos(&dir, "ttyREOPEN", &args);
    out.until("online", Duration::from_secs(20), |l| {
        l.contains("\"online\"")
    });
    stdin.write_all(command("pan", 20.0).as_bytes()).unwrap();
    out.until("arrival", Duration::from_secs(20), |l| {
        l.contains("\"arrived\"")
    });
    drop(stdin);
    let _ = child.wait();
    servos.kill().unwrap();
    let _ = servos.wait();
    let seen = out.finish();
    assert!(
        seen.iter().any(|l| l.contains("servo port 0: open again")),
        "{seen:?}"
    );
    assert!(
        seen.iter().any(|l| l.contains("\"arrived\":true")),
        "{seen:?}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
