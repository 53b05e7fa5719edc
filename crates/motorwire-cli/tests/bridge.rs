//! `motorwire bridge` as a user runs it: on the simulated arm, fed by stdin
//! or by TCP clients.
#![allow(clippy::unwrap_used, clippy::panic, clippy::indexing_slicing)]

mod common;

use std::io::{BufRead, BufReader, Write};
use std::net::TcpStream;
use std::process::Command;
use std::thread;
use std::time::{Duration, Instant};

use serde_json::Value;

const MAP: &str = "fixtures/maps/demo-arm.toml";

fn command(motor: &str, setpoint: f64) -> String {
    format!(
        r#"{{"motor_id":"{motor}","timestamp":{},"control_mode":"position","setpoint":{setpoint}}}"#,
        now_ms()
    )
}

/// Unix milliseconds now: the bridge refuses commands outside WIA's 5-minute skew.
fn now_ms() -> u128 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .as_millis()
}

fn lines(bytes: &[u8]) -> Vec<Value> {
    String::from_utf8_lossy(bytes)
        .lines()
        .map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("{l:?}: {e}")))
        .collect()
}

/// `motorwire ARGS` fed `input`, run to its end (exit 0): every line it
/// printed.
fn run_to_its_end(args: &[&str], input: &str) -> Vec<Value> {
    let out = common::run(args, input.as_bytes());
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    lines(&out.stdout)
}

#[test]
fn stdin_lines_get_one_result_each_then_the_joints_are_stopped() {
    let input = format!(
        "{}\nnot json\n{}\n\n{}\n",
        command("elbow", 20.0),
        command("elbow", 170.0),
        command("shoulder_pitch", -10.0)
    );
    let all = run_to_its_end(
        &[
            "bridge",
            "--map",
            MAP,
            "--bus",
            "sim",
            "--feedback-hz",
            "20",
        ],
        &input,
    );
    // Results come as their lines complete; "line" pairs them with input.
    let mut results: Vec<&Value> = all
        .iter()
        .filter(|v| v.get("ok").is_some() && v.get("event").is_none())
        .collect();
    results.sort_by_key(|v| v["line"].as_u64());
    assert_eq!(results.len(), 4, "{all:?}");
    for (i, r) in results.iter().enumerate() {
        assert_eq!(r["line"], i + 1, "blank lines are not counted");
    }
    assert_eq!(results[0]["motor_id"], "elbow");
    assert_eq!(results[0]["ok"], true);
    assert_eq!(results[1]["error"]["kind"], "invalid");
    assert_eq!(results[2]["error"]["kind"], "refused");
    assert_eq!(results[3]["motor_id"], "shoulder_pitch");
    assert_eq!(results[3]["ok"], true);
    // Feedback is marked, and the moves finished before the joints were
    // stopped: each said arrived before `stopped` (the last feedback line
    // may come up to a feedback period before the elbow is at rest, so it
    // is not the measure).
    assert!(
        all.iter()
            .any(|v| v["motor_id"] == "elbow" && v.get("feedback").is_some())
    );
    let stopped_at = all.iter().position(|v| v["event"] == "stopped").unwrap();
    for line in [1, 4] {
        let arrived = all
            .iter()
            .position(|v| v.get("arrived").is_some() && v["line"] == line)
            .unwrap_or_else(|| panic!("line {line} has no completion: {all:?}"));
        assert_eq!(all[arrived]["arrived"], true, "{}", all[arrived]);
        assert!(
            arrived < stopped_at,
            "line {line} arrived after the joints were stopped"
        );
    }
    let elbow = all
        .iter()
        .find(|v| v.get("arrived").is_some() && v["line"] == 1)
        .unwrap();
    assert!(
        elbow["motors"][0]["error"].as_f64().unwrap().abs() < 0.1,
        "{elbow}"
    );
    let stopped = all.iter().find(|v| v["event"] == "stopped").unwrap();
    // The three joints and the compact gripper.
    assert_eq!(stopped["deactivated"].as_array().unwrap().len(), 4);
    assert_eq!(all.last().unwrap()["event"], "stopped");
}

/// The issue's case as a user meets it: `"velocity_limt":5` is refused
/// naming `velocity_limit`, and with `--allow-unknown-members` it runs with
/// the loss said.
#[test]
fn a_misspelled_member_is_refused_unless_the_bridge_is_told_to_take_it() {
    let line = format!(
        r#"{{"motor_id":"elbow","timestamp":{},"control_mode":"position","setpoint":20,"velocity_limt":5}}"#,
        now_ms()
    );
    for allow in [false, true] {
        let mut args = vec!["bridge", "--map", MAP, "--bus", "sim", "--feedback-hz", "0"];
        if allow {
            args.push("--allow-unknown-members");
        }
        let all = run_to_its_end(&args, &format!("{line}\n"));
        let r = all
            .iter()
            .find(|v| v["line"] == 1 && v.get("ok").is_some())
            .unwrap();
        if allow {
            assert_eq!(r["ok"], true, "{r}");
            assert!(
                r["losses"].to_string().contains(
                    "velocity_limt: dropped: an unknown member; SetTargetV2 has no place for it"
                ),
                "{r}"
            );
        } else {
            assert_eq!(r["ok"], false, "{r}");
            assert_eq!(r["error"]["kind"], "invalid", "{r}");
            assert_eq!(
                r["error"]["violations"][0]["pointer"], "/velocity_limt",
                "{r}"
            );
            assert_eq!(r["error"]["violations"][0]["rule"], "unknown-member", "{r}");
            assert_eq!(
                r["error"]["message"],
                "not a valid WIA message: /velocity_limt: \"velocity_limt\" is not a member motor-command has here; did you mean velocity_limit? (motorwire takes unknown members only when told to: `Validator::lenient`, `--allow-unknown-members`, `validate --allow-unknown`) (unknown-member)",
                "{r}"
            );
            assert!(!all.iter().any(|v| v.get("arrived").is_some()), "{all:?}");
        }
    }
}

/// `motorwire validate --now` and the bridge judge one line alike: the
/// same timestamp window (`--max-age`, 5 minutes either way by default)
/// and the same size limit (`--max-size`, 1 MiB by default), each a flag
/// of both.
#[test]
fn validate_and_the_bridge_share_one_timestamp_window_and_one_size_limit() {
    let now = now_ms();
    let dir = std::env::temp_dir().join(format!("mw-window-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    // Ten minutes old, and a 200 KB line (its metadata free-form).
    let old = format!(
        r#"{{"motor_id":"elbow","timestamp":{},"control_mode":"position","setpoint":20}}"#,
        now - 600_000
    );
    let big = format!(
        r#"{{"motor_id":"elbow","timestamp":{now},"control_mode":"position","setpoint":20,"metadata":{{"note":"{}"}}}}"#,
        "x".repeat(200_000)
    );
    let judge = |line: &str, flags: &[&str]| -> (bool, Value) {
        let file = dir.join("line.json");
        std::fs::write(&file, line).unwrap();
        let path = file.display().to_string();
        let now = now.to_string();
        let mut args = vec!["validate", "--now", &now, "--format", "json"];
        args.extend_from_slice(flags);
        args.push(&path);
        let v = common::run(&args, b"");
        let valid = lines(&v.stdout)[0]["valid"].as_bool().unwrap();
        let mut args = vec!["bridge", "--map", MAP, "--bus", "sim", "--feedback-hz", "0"];
        args.extend_from_slice(flags);
        let all = run_to_its_end(&args, &format!("{line}\n"));
        let result = all
            .iter()
            .find(|r| r["line"] == 1 && r.get("ok").is_some())
            .cloned()
            .unwrap();
        assert_eq!(
            result["ok"].as_bool().unwrap(),
            valid,
            "validate {flags:?} said valid={valid}, the bridge {result}"
        );
        (valid, result)
    };
    let (valid, r) = judge(&old, &[]);
    assert!(!valid);
    assert_eq!(r["error"]["kind"], "stale", "{r}");
    assert!(judge(&old, &["--max-age", "900000"]).0);
    assert!(judge(&old, &["--max-age", "0"]).0);
    assert!(judge(&big, &[]).0, "a 200 KB line is taken by default");
    let (valid, r) = judge(&big, &["--max-size", "100000"]);
    assert!(!valid);
    assert_eq!(r["error"]["kind"], "unreadable", "{r}");
    assert_eq!(
        r["error"]["message"], "the line is over 100000 bytes (the bridge's --max-size)",
        "{r}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

fn connect(port: u16) -> TcpStream {
    TcpStream::connect(("127.0.0.1", port)).unwrap()
}

/// The next result line a client gets (skipping feedback and events).
fn next_result(reader: &mut BufReader<TcpStream>) -> Value {
    loop {
        let mut line = String::new();
        assert!(
            reader.read_line(&mut line).unwrap() > 0,
            "connection closed"
        );
        let v: Value = serde_json::from_str(&line).unwrap();
        if v.get("ok").is_some() && v.get("event").is_none() {
            return v;
        }
    }
}

#[test]
fn tcp_clients_at_once_garbage_and_a_client_leaving_mid_line() {
    // Port 0: the bridge binds a free port and says which; clients connect
    // only once it listens (no race for a port, no connect before bind).
    let mut child = common::spawn(&[
        "bridge",
        "--map",
        MAP,
        "--bus",
        "sim",
        "--input",
        "tcp:127.0.0.1:0",
        // What this test is about is the clients; tokens are tested in
        // tests/serve.rs.
        "--insecure-no-auth",
    ]);
    let mut stderr = BufReader::new(child.stderr.take().unwrap());
    let mut said = String::new();
    stderr.read_line(&mut said).unwrap();
    let port: u16 = said
        .trim()
        .rsplit(':')
        .next()
        .and_then(|p| p.parse().ok())
        .unwrap_or_else(|| panic!("no port in {said:?}"));
    let motors = ["shoulder_pitch", "shoulder_roll", "elbow"];
    let clients: Vec<_> = motors
        .iter()
        .enumerate()
        .map(|(i, motor)| {
            let motor = (*motor).to_owned();
            thread::spawn(move || {
                let s = connect(port);
                s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
                let mut w = s.try_clone().unwrap();
                let mut r = BufReader::new(s);
                let mut got = Vec::new();
                for k in 0..5 {
                    let setpoint = 5.0 * (k as f64) + i as f64;
                    writeln!(w, "{}", command(&motor, setpoint)).unwrap();
                    got.push(next_result(&mut r));
                }
                (motor, got)
            })
        })
        .collect();
    // A client sending garbage gets its own errors; others are not disturbed.
    let garbage = thread::spawn(move || {
        let s = connect(port);
        s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
        let mut w = s.try_clone().unwrap();
        let mut r = BufReader::new(s);
        w.write_all(b"\xff\xfe\x00garbage\n{\"motor_id\":\n")
            .unwrap();
        w.write_all(&vec![b'x'; (1 << 20) + 100]).unwrap();
        w.write_all(b"\n").unwrap();
        let mut got: Vec<Value> = (0..3).map(|_| next_result(&mut r)).collect();
        got.sort_by_key(|v| v["line"].as_u64());
        got
    });
    for c in clients {
        let (motor, got) = c.join().unwrap();
        for r in &got {
            assert_eq!(r["ok"], true, "{r}");
            assert_eq!(r["motor_id"], motor.as_str(), "results go to their sender");
        }
    }
    let g = garbage.join().unwrap();
    assert_eq!(g[0]["error"]["kind"], "unreadable", "not UTF-8: {}", g[0]);
    assert_eq!(g[1]["error"]["kind"], "invalid", "{}", g[1]);
    assert_eq!(g[2]["error"]["kind"], "unreadable", "too long: {}", g[2]);
    // A client leaving in the middle of a line: the part is not taken,
    // even though it would be a valid emergency stop.
    {
        let mut s = connect(port);
        s.write_all(br#"{"emergency_stop": true}"#).unwrap();
    }
    thread::sleep(Duration::from_millis(300));
    let s = connect(port);
    s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
    let mut w = s.try_clone().unwrap();
    let mut r = BufReader::new(s);
    writeln!(w, "{}", command("elbow", 40.0)).unwrap();
    let after = next_result(&mut r);
    assert_eq!(after["ok"], true, "not latched: {after}");
    // SIGINT: the joints are stopped and deactivated, and the bridge ends.
    let status = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(status.success());
    let end = Instant::now() + Duration::from_secs(10);
    while child.try_wait().unwrap().is_none() {
        assert!(Instant::now() < end, "the bridge did not stop on SIGINT");
        thread::sleep(Duration::from_millis(20));
    }
    let out = child.wait_with_output().unwrap();
    assert_eq!(out.status.code(), Some(130), "SIGINT's exit status");
    let events = lines(&out.stdout);
    assert!(
        events
            .iter()
            .any(|e| e["event"] == "stopping" && e["reason"] == "interrupted"),
        "{events:?}"
    );
    let stopped = events.iter().find(|e| e["event"] == "stopped").unwrap();
    assert_eq!(
        stopped["deactivated"].as_array().unwrap().len(),
        4,
        "{stopped}"
    );
}

/// `--bus sim` made hostile from outside the process: seeded drops,
/// duplicates and reordering, every execution logged. Hundreds of lines
/// in flight with stops in hostile forms among them: one result per line,
/// no request executed twice, no move executed after a stop issued after it.
#[test]
fn a_hostile_simulated_bus_and_the_execution_log_prove_exactly_once() {
    let log = std::env::temp_dir().join(format!("motorwire-sim-log-{}.jsonl", std::process::id()));
    let mut input = String::new();
    let mut n = 0;
    for round in 0..4 {
        for i in 0..150 {
            let motor = ["shoulder_pitch", "shoulder_roll", "elbow"][i % 3];
            input.push_str(&command(motor, ((i * 7 + round) % 40) as f64));
            input.push('\n');
            n += 1;
        }
        input.push_str(
            [
                "{\"emergency_stop\": 1}",
                "{\"emergency_stop\": true, \"x\": 2}",
            ][round % 2],
        );
        input.push_str("\n{\"emergency_stop\": false}\n");
        n += 2;
    }
    let out = common::run(
        &[
            "bridge",
            "--map",
            MAP,
            "--bus",
            "sim",
            "--feedback-hz",
            "0",
            "--sim-faults",
            "drop=0.1,duplicate=0.1,reorder=0.1,max-delay-ms=10",
            "--sim-seed",
            "3",
            "--sim-log",
            log.to_str().unwrap(),
        ],
        input.as_bytes(),
    );
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let all = lines(&out.stdout);
    let mut numbers: Vec<u64> = all
        .iter()
        .filter(|v| v.get("ok").is_some() && v.get("event").is_none())
        .map(|v| v["line"].as_u64().unwrap())
        .collect();
    numbers.sort_unstable();
    assert_eq!(
        numbers,
        (1..=n).collect::<Vec<u64>>(),
        "one result per line"
    );
    let stops = all
        .iter()
        .filter(|v| v["emergency_stop"] == true && v["ok"].is_boolean())
        .count();
    assert_eq!(stops, 4);
    let executions: Vec<Value> = std::fs::read_to_string(&log)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    let _ = std::fs::remove_file(&log);
    // Most of each burst is superseded while it waits; what runs is logged.
    assert!(executions.len() > 10, "{}", executions.len());
    let mut seen = std::collections::BTreeSet::new();
    let mut last_stop: std::collections::BTreeMap<String, u64> = Default::default();
    for e in &executions {
        let joint = e["joint"].as_str().unwrap().to_owned();
        let id = e["msg_id"].as_u64().unwrap();
        assert!(
            seen.insert((joint.clone(), e["source"].as_u64(), id)),
            "{joint}: msg_id {id} executed twice"
        );
        let acked = e["answer"].get("Ack").is_some();
        if e["payload"] == "Deactivate" && acked {
            last_stop.insert(joint.clone(), id);
        }
        if e["payload"].get("SetTargetV2").is_some() && acked {
            // msg_ids start from the clock and grow: a move issued before a
            // stop has a smaller id than the stop's Deactivate.
            if let Some(stop) = last_stop.get(&joint) {
                #[allow(clippy::cast_possible_truncation)]
                let after = (id as u32).wrapping_sub(*stop as u32) < 1 << 31;
                assert!(after, "{joint}: move {id} ran after the stop {stop}");
            }
        }
    }
}

/// Every feedback object the bridge prints is a valid WIA MotorFeedback,
/// with a whole-millisecond timestamp and the f32 values in their shortest
/// form (30.1, not 30.100000381469727).
#[test]
fn every_feedback_line_is_valid_wia_with_whole_ms_and_short_floats() {
    let input = format!("{}\n", command("elbow", 30.1));
    let out = common::run(
        &[
            "bridge",
            "--map",
            MAP,
            "--bus",
            "sim",
            "--feedback-hz",
            "50",
        ],
        input.as_bytes(),
    );
    assert_eq!(out.status.code(), Some(0));
    let validator = motorwire_wia::Validator::new();
    let mut seen = 0;
    let mut last_elbow = None;
    for v in lines(&out.stdout) {
        let Some(fb) = v.get("feedback").filter(|f| !f.is_null()) else {
            continue;
        };
        seen += 1;
        let text = fb.to_string();
        let report = validator.validate_auto(&text);
        assert!(report.is_valid(), "{text}: {report:?}");
        let ts = fb["timestamp"].as_f64().unwrap();
        assert_eq!(ts.fract(), 0.0, "{text}");
        if v["motor_id"] == "elbow" {
            last_elbow = Some(fb["position"].clone());
        }
    }
    assert!(seen > 10, "{seen}");
    // The shortest decimal that reads back as the joint's f32.
    let text = last_elbow.unwrap().to_string();
    #[allow(clippy::cast_possible_truncation)]
    let f = text.parse::<f64>().unwrap() as f32;
    assert_eq!(f.to_string(), text.trim_end_matches(".0"), "{text}");
    assert!(text.len() <= 9, "{text}");
}

/// The second demo map, as its README section runs it: the iRPC elbow, the
/// compact gripper and the moteus leg on the simulated bus move, then one
/// emergency stop is acked by every one of them and stops them all (the
/// moteus ankle braked, as its map says), and the latched stop refuses a
/// move of the leg.
#[test]
fn one_emergency_stop_stops_irpc_compact_and_moteus_motors_alike() {
    let map = "fixtures/maps/demo-arm-and-leg.toml";
    // Slow moves (2 s and more): still under way when the stop comes,
    // however slow the machine is to start the bridge.
    let slow = |motor: &str, setpoint: f64, velocity: f64| {
        format!(
            r#"{{"motor_id":"{motor}","timestamp":{},"control_mode":"position","setpoint":{setpoint},"velocity_limit":{velocity}}}"#,
            now_ms()
        )
    };
    let moves = [
        slow("elbow", 40.0, 20.0),
        command("gripper_axis", 45.0),
        slow("hip", 50.0, 20.0),
        slow("knee", 120.0, 40.0),
        format!(
            r#"{{"motor_id":"ankle","timestamp":{},"control_mode":"velocity","setpoint":2}}"#,
            now_ms()
        ),
    ];
    let mut bridge = common::spawn(&["bridge", "--map", map, "--bus", "sim", "--feedback-hz", "0"]);
    let mut stdin = bridge.stdin.take().unwrap();
    for m in &moves {
        writeln!(stdin, "{m}").unwrap();
    }
    thread::sleep(Duration::from_millis(300));
    writeln!(stdin, r#"{{"emergency_stop":true}}"#).unwrap();
    writeln!(stdin, "{}", command("hip", 0.0)).unwrap();
    thread::sleep(Duration::from_millis(300));
    drop(stdin);
    let out = bridge.wait_with_output().unwrap();
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let all = lines(&out.stdout);
    let result = |line: u64| {
        all.iter()
            .find(|v| v["line"] == line && v.get("ok").is_some())
            .unwrap_or_else(|| panic!("no result for line {line}: {all:?}"))
    };
    for line in 1..=5 {
        assert_eq!(result(line)["ok"], true, "{all:?}");
    }
    let stop = result(6);
    assert_eq!(stop["emergency_stop"], true, "{stop}");
    let mut acked: Vec<&str> = stop["acked"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_str().unwrap())
        .collect();
    acked.sort_unstable();
    assert_eq!(
        acked,
        ["ankle", "elbow", "gripper_axis", "hip", "knee"],
        "{stop}"
    );
    assert_eq!(
        result(7)["error"]["kind"],
        "emergency_stop_latched",
        "{all:?}"
    );
    // Interrupted on the way: none of the three moves arrived.
    for line in [1, 3, 4] {
        let done = all
            .iter()
            .find(|v| v["line"] == line && v.get("arrived").is_some())
            .unwrap();
        assert_eq!(done["arrived"], false, "{done}");
    }
}

/// Standard input sets standard output's own feedback rate: after
/// `{"feedback_hz":0}` is answered, a move's whole run prints no feedback
/// (at 50 Hz without it, it printed some).
#[test]
fn standard_input_sets_its_own_feedback_rate() {
    for (rate_line, quiet) in [("{\"feedback_hz\":0}\n", true), ("", false)] {
        let input = format!("{rate_line}{}\n", command("elbow", 20.0));
        let all = run_to_its_end(
            &[
                "bridge",
                "--map",
                MAP,
                "--bus",
                "sim",
                "--feedback-hz",
                "50",
            ],
            &input,
        );
        let answered = if quiet {
            let at = all
                .iter()
                .position(|v| v["line"] == 1 && v.get("ok").is_some())
                .unwrap();
            assert_eq!(all[at]["feedback_hz"], 0.0, "{}", all[at]);
            at
        } else {
            0
        };
        let feedback = all[answered..]
            .iter()
            .filter(|v| v.get("feedback").is_some())
            .count();
        assert_eq!(
            feedback == 0,
            quiet,
            "{feedback} feedback lines after the rate's answer"
        );
    }
}

/// A bus map of `joints` iRPC joints (nodes from 0x10 on) in a file of
/// its own, named after `name`.
fn joints_map(joints: usize, name: &str) -> std::path::PathBuf {
    use std::fmt::Write as _;
    let mut text = String::new();
    for i in 0..joints {
        let _ = writeln!(
            text,
            "[motors.j{i}]\ndialect = \"irpc\"\nnode = {}\n\
             limits = {{ min_position = -90, max_position = 90, max_velocity = 120 }}",
            0x10 + i
        );
    }
    let path = std::env::temp_dir().join(format!(
        "motorwire-{name}-{joints}-{}.toml",
        std::process::id()
    ));
    std::fs::write(&path, text).unwrap();
    path
}

/// A map of as many devices as the bridge serves starts on the simulated
/// bus within a bound generous for a loaded debug build, every joint
/// online and active from the first line; one device more is refused at
/// once (exit status 2, naming the count and the limit), by the bridge
/// and by `translate` alike. A map of 500 joints once neither reached
/// `ready` in 15 s nor was refused, 366 MB resident by then.
#[test]
fn a_map_at_the_limit_is_ready_at_once_and_one_beyond_it_is_refused() {
    let limit = motorwire_bridge::Bridge::MAX_DEVICES;
    let at = joints_map(limit, "at-limit");
    let start = Instant::now();
    let mut child = common::spawn(&[
        "bridge",
        "--map",
        at.to_str().unwrap(),
        "--bus",
        "sim",
        "--feedback-hz",
        "0",
    ]);
    let mut out = common::Lines::of(child.stdout.take().unwrap());
    out.until("ready", Duration::from_secs(10), |l| {
        l.contains(r#""event":"ready""#)
    });
    let took = start.elapsed();
    let rss = common::rss_kib(child.id());
    drop(child.stdin.take());
    let status = child.wait().unwrap();
    let _ = std::fs::remove_file(&at);
    let lines: Vec<Value> = out
        .finish()
        .iter()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(status.code(), Some(0));
    let ready = lines.iter().position(|v| v["event"] == "ready").unwrap();
    assert!(
        lines[..ready].iter().all(|v| v["event"] != "offline"),
        "a joint went offline before ready ({took:?}): {:?}",
        &lines[..ready]
    );
    let motors = lines[ready]["motors"].as_array().unwrap();
    assert_eq!(motors.len(), limit);
    for m in motors {
        assert!(m["online"] == true && m["active"] == true, "{m}");
    }
    assert!(rss < 100 * 1024, "{rss} KiB resident at ready");
    eprintln!("{limit} joints ready in {took:?}, {rss} KiB resident");

    let over = joints_map(limit + 1, "over-limit");
    let over_path = over.to_str().unwrap();
    for args in [
        &["bridge", "--map", over_path, "--bus", "sim"][..],
        &["translate", "--map", over_path, "--to", "irpc-v2.0"][..],
    ] {
        let start = Instant::now();
        let out = common::run(args, b"");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(
            stderr.contains(&format!("{} motors", limit + 1))
                && stderr.contains(&format!("at most {limit}")),
            "{args:?}: {stderr}"
        );
        assert!(out.stdout.is_empty(), "{args:?}");
        assert!(start.elapsed() < Duration::from_secs(5), "{args:?}");
    }
    let _ = std::fs::remove_file(&over);
}
