//! `motorwire replay DIR` as a user runs it: a session recorded on the
//! simulated bus replays to the same answers, events, frames and Orion
//! lines in simulated time; a changed map shows where it changes the
//! session; a recording that cannot be replayed says why (issue 28 part
//! 2); the recording drawn (part 4).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod common;

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Duration;

use serde_json::Value;

use common::now_ms;

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("motorwire-replay-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

/// Records a session on `--bus sim` with the Orion controller simulated:
/// a move, a refused line, a compact gripper move, the Orion turntable
/// turned until the deadman stops it, a trajectory through a waypoint at
/// speed, an emergency stop cutting it short, a line refused while the
/// stop is latched, the release, a move back; then the end of input.
fn record_session(dir: &Path) {
    let t = now_ms();
    let cmd = |motor: &str, mode: &str, v: f64| {
        format!(
            "{{\"motor_id\":\"{motor}\",\"timestamp\":{t},\"control_mode\":\"{mode}\",\"setpoint\":{v}}}\n"
        )
    };
    let steps: Vec<(String, u64)> = vec![
        (cmd("elbow", "position", 30.0), 100),
        (cmd("elbow", "position", 170.0), 100),
        (cmd("gripper_axis", "position", 20.0), 100),
        (cmd("turntable", "velocity", 20.0), 700),
        (
            "{\"trajectory_id\":\"wave\",\"motor_id\":\"elbow\",\"waypoints\":[{\"position\":30,\"velocity\":0,\"time\":0},{\"position\":70,\"velocity\":40,\"time\":1.1},{\"position\":40,\"velocity\":0,\"time\":2.5}],\"timing\":{}}\n".to_owned(),
            700,
        ),
        ("{\"emergency_stop\":true}\n".to_owned(), 200),
        (cmd("shoulder_pitch", "position", 10.0), 100),
        ("{\"emergency_stop\":false}\n".to_owned(), 200),
    ];
    let mut child = common::spawn(&common::sim_bridge(&[
        "--orion",
        "sim",
        "--feedback-hz",
        "10",
        "--record",
        dir.to_str().unwrap(),
    ]));
    let mut pipe = child.stdin.take().unwrap();
    // After `ready`: the lines then come at the times the session says.
    std::thread::sleep(Duration::from_millis(300));
    for (line, pause) in &steps {
        pipe.write_all(line.as_bytes()).unwrap();
        std::thread::sleep(Duration::from_millis(*pause));
    }
    // The move back: two new lines after the release (a line's timestamp
    // must be after the stop).
    let t2 = now_ms();
    let back = format!(
        "{{\"motor_id\":\"elbow\",\"timestamp\":{t2},\"control_mode\":\"position\",\"setpoint\":0}}\n"
    );
    pipe.write_all(back.as_bytes()).unwrap();
    drop(pipe);
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{stderr}");
    assert!(stderr.contains(", 0 dropped"), "{stderr}");
    // The session is what it says: the refusals, the stop, the trajectory
    // cut short, the deadman.
    let printed = String::from_utf8(out.stdout).unwrap();
    for needle in [
        "\"rule\":\"outside_limit\"",
        "\"rule\":\"emergency_stop_latched\"",
        "\"event\":\"emergency_stop\"",
        "\"event\":\"deadman\"",
        "cancelled by the emergency stop: the rest of the trajectory was not sent",
        "\"event\":\"released\"",
    ] {
        assert!(printed.contains(needle), "{needle} not in\n{printed}");
    }
}

/// `motorwire plot DIR --svg SVG`.
fn plot(dir: &Path, svg: &Path) -> std::process::Output {
    common::run(
        &[
            "plot",
            dir.to_str().unwrap(),
            "--svg",
            svg.to_str().unwrap(),
        ],
        b"",
    )
}

fn replay_json(dir: &Path, extra: &[&str]) -> (Option<i32>, Value, String) {
    let mut args = vec!["replay", dir.to_str().unwrap(), "--json"];
    args.extend_from_slice(extra);
    let out = common::run(&args, b"");
    let stdout = String::from_utf8(out.stdout).unwrap();
    let stderr = String::from_utf8(out.stderr).unwrap();
    let v = serde_json::from_str(stdout.trim()).unwrap_or(Value::Null);
    (out.status.code(), v, stderr)
}

/// A recording of a session on the simulated bus replays, in simulated
/// time and faster than it was recorded, to the same answers (each line's
/// result and completion), events, frames to each device (read in its
/// dialect) and lines to the Orion controller; then, with the elbow's
/// range cut to 20°, the replay diverges at the first line that moved it
/// past 20°, printing both sides.
#[test]
fn a_sim_session_replays_the_same_and_a_changed_map_diverges_where_it_changes() {
    let dir = scratch("same");
    record_session(&dir);

    // The recording holds what a replay needs: the setup and the marks.
    let session: Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("session.json")).unwrap()).unwrap();
    let setup = &session["setup"];
    assert_eq!(setup["bus"], "sim");
    assert!(setup["map"].as_str().unwrap().contains("[motors.elbow]"));
    assert!(setup["first_msg_id"].as_u64().unwrap() > 0);
    assert_eq!(setup["orion"], true);
    let lines = std::fs::read_to_string(dir.join("lines.jsonl")).unwrap();
    let marks: Vec<Value> = lines
        .lines()
        .filter_map(|l| {
            serde_json::from_str::<Value>(l)
                .unwrap()
                .get("mark")
                .cloned()
        })
        .collect();
    assert_eq!(
        marks,
        vec![
            serde_json::json!({"kind": "start"}),
            serde_json::json!({"kind": "finish"})
        ]
    );

    let (code, v, stderr) = replay_json(&dir, &[]);
    assert_eq!(code, Some(0), "{v}\n{stderr}");
    assert_eq!(v["same"], true, "{v}");
    assert_eq!(v["ended_cleanly"], true, "{v}");
    assert_eq!(
        (&v["complete"], &v["dropped"], &v["incomplete"]),
        (&Value::Bool(true), &Value::from(0), &Value::Null),
        "{v}"
    );
    assert_eq!(session["complete"], true, "{session}");
    assert_eq!(v["divergence"], Value::Null);
    assert_eq!(v["inputs"], 11, "9 lines, the start and the end: {v}");
    // Every line's answers: 9 results and 4 completions (the first move,
    // the gripper's, the trajectory cut short, the move back).
    assert!(v["compared"]["answers"].as_u64().unwrap() >= 13, "{v}");
    assert!(v["compared"]["events"].as_u64().unwrap() >= 10, "{v}");
    assert!(v["compared"]["frames"].as_u64().unwrap() >= 15, "{v}");
    assert!(v["compared"]["orion_lines"].as_u64().unwrap() >= 2, "{v}");
    // Simulated time: faster than the ~3 s it took.
    assert!(
        v["took_us"].as_u64().unwrap() < v["simulated_us"].as_u64().unwrap(),
        "{v}"
    );

    // Drawn for a person (issue 28 part 4): a panel per motor that
    // moved, in its units, the marks with their key.
    let svg = dir.join("session.svg");
    let out = plot(&dir, &svg);
    let said = String::from_utf8(out.stdout).unwrap();
    assert_eq!(out.status.code(), Some(0), "{said}");
    // The elbow, the gripper and the turntable (shoulder_pitch's only
    // line was refused); two refusals, the deadman, the stop, the release.
    assert!(said.ends_with(": 3 motors, 5 marks\n"), "{said}");
    let drawing = std::fs::read_to_string(&svg).unwrap();
    for needle in [
        "elbow: position (°)",
        "gripper_axis: velocity (°/s)",
        "turntable: speed (controller units, ±400)",
        "line 2 elbow refused: outside_limit",
        "deadman: turntable stopped, no command within its timeout",
        "emergency stop (input)",
        "line 7 shoulder_pitch refused: emergency_stop_latched",
        "released",
    ] {
        assert!(drawing.contains(needle), "{needle} not in the plot");
    }
    let out = common::run(
        &[
            "plot",
            dir.to_str().unwrap(),
            "--svg",
            svg.to_str().unwrap(),
            "--motor",
            "nose",
        ],
        b"",
    );
    assert_eq!(out.status.code(), Some(2));
    assert!(
        String::from_utf8(out.stderr)
            .unwrap()
            .contains("--motor nose: not a motor of the map")
    );

    // The same session against a map whose elbow stops at 20°.
    let map = std::fs::read_to_string(common::root().join("fixtures/maps/demo-arm.toml"))
        .unwrap()
        .replace(
            "limits = { min_position = 0, max_position = 150,",
            "limits = { min_position = 0, max_position = 20,",
        );
    let map_path = dir.join("narrow.toml");
    std::fs::write(&map_path, map).unwrap();
    let (code, v, stderr) = replay_json(&dir, &["--map", map_path.to_str().unwrap()]);
    assert_eq!(code, Some(1), "{v}\n{stderr}");
    assert_eq!(v["same"], false);
    let d = &v["divergence"];
    assert_eq!(d["stream"], "client 0 line 1", "{v}");
    assert_eq!(d["recorded"]["ok"], true, "{v}");
    assert_eq!(d["replayed"]["ok"], false, "{v}");
    assert_eq!(d["replayed"]["error"]["rule"], "outside_limit", "{v}");
    assert_eq!(d["replayed"]["error"]["limit"], 20.0, "{v}");

    // As text: the first divergence with both sides and its time.
    let out = common::run(
        &[
            "replay",
            dir.to_str().unwrap(),
            "--map",
            map_path.to_str().unwrap(),
        ],
        b"",
    );
    assert_eq!(out.status.code(), Some(1));
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(text.contains("first divergence at "), "{text}");
    assert!(text.contains(", in client 0 line 1:"), "{text}");
    assert!(text.contains("  recorded: (at "), "{text}");
    assert!(text.contains("  replayed: (at "), "{text}");

    // Edited after the fact: refused (exit 2), never "the same". A frame
    // of frames.log changed, frames.log cut, a count that is not a number.
    let log = std::fs::read_to_string(dir.join("frames.log")).unwrap();
    let first = log.lines().next().unwrap();
    let (head, data) = first.rsplit_once('#').unwrap();
    let flipped = format!(
        "{head}#{}",
        if data.starts_with('0') { "1" } else { "0" }.to_owned() + &data[1..]
    );
    let session_text = std::fs::read_to_string(dir.join("session.json")).unwrap();
    let cases: Vec<(&str, String, &str)> = vec![
        (
            "frames.log",
            log.replacen(first, &flipped, 1),
            "frames.log:1: not the frame lines.jsonl has there",
        ),
        (
            "frames.log",
            log.lines().skip(1).map(|l| format!("{l}\n")).collect(),
            "frames.log:1: not the frame lines.jsonl has there",
        ),
        (
            "frames.log",
            log.lines().take(3).map(|l| format!("{l}\n")).collect(),
            "frames.log holds 3 frames, lines.jsonl",
        ),
        ("frames.log", "garbage\n".to_owned(), "frames.log:1:"),
        (
            "session.json",
            {
                let mut v: Value = serde_json::from_str(&session_text).unwrap();
                v["written"] = Value::from(v["written"].to_string());
                v.to_string()
            },
            "session.json:1: written is \"",
        ),
    ];
    for (file, text, says) in cases {
        std::fs::write(dir.join(file), &text).unwrap();
        let out = common::run(&["replay", dir.to_str().unwrap()], b"");
        let stderr = String::from_utf8(out.stderr).unwrap();
        assert_eq!(out.status.code(), Some(2), "{file}: {stderr}");
        assert!(stderr.contains(says), "{says} not in {stderr}");
        std::fs::write(dir.join("frames.log"), &log).unwrap();
        std::fs::write(dir.join("session.json"), &session_text).unwrap();
    }
    // The bridge killed in the middle of a write: session.json without its
    // end (its counts as last rewritten, `complete` false, no
    // `ended_wall_ms`), lines.jsonl's last line cut short. Refused as
    // incomplete; with --allow-incomplete, what came before it replays,
    // and plots, and both say what was left out.
    let lines = std::fs::read_to_string(dir.join("lines.jsonl")).unwrap();
    let mut killed: Value = serde_json::from_str(&session_text).unwrap();
    killed.as_object_mut().unwrap().remove("ended_wall_ms");
    killed["complete"] = Value::Bool(false);
    std::fs::write(dir.join("session.json"), killed.to_string()).unwrap();
    std::fs::write(dir.join("lines.jsonl"), &lines[..lines.len() - 20]).unwrap();
    let out = common::run(&["replay", dir.to_str().unwrap()], b"");
    let stderr = String::from_utf8(out.stderr).unwrap();
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains(": an incomplete recording: the recording did not end cleanly (session.json has no end: the bridge was killed, or its disk stopped answering); not replayed (--allow-incomplete replays it as far as it goes)"),
        "{stderr}"
    );
    let out = common::run(
        &["replay", dir.to_str().unwrap(), "--allow-incomplete"],
        b"",
    );
    let stderr = String::from_utf8(out.stderr).unwrap();
    assert_eq!(out.status.code(), Some(0), "{stderr}");
    assert!(
        stderr.contains(": an incomplete recording, replayed as far as it goes (--allow-incomplete): the recording did not end cleanly (session.json has no end: the bridge was killed, or its disk stopped answering); lines.jsonl's last line, cut in the middle of its write, left out"),
        "{stderr}"
    );
    assert!(
        String::from_utf8(out.stdout)
            .unwrap()
            .contains("the same: no divergence, as far as the incomplete recording goes"),
        "killed and cut: not the same"
    );
    let (code, v, stderr) = replay_json(&dir, &["--allow-incomplete"]);
    assert_eq!(code, Some(0), "{stderr}");
    assert_eq!(
        (&v["complete"], &v["ended_cleanly"], &v["dropped"]),
        (&Value::Bool(false), &Value::Bool(false), &Value::from(0)),
        "{v}"
    );
    assert!(
        v["incomplete"]
            .as_str()
            .unwrap()
            .starts_with("the recording did not end cleanly"),
        "{v}"
    );
    let svg = dir.join("killed.svg");
    let out = plot(&dir, &svg);
    let stderr = String::from_utf8(out.stderr).unwrap();
    assert_eq!(out.status.code(), Some(0), "{stderr}");
    assert!(
        stderr.contains("the recording did not end cleanly: its last line, cut in the middle of its write, is left out"),
        "{stderr}"
    );
    let drawn = std::fs::read_to_string(&svg).unwrap();
    assert!(drawn.contains("elbow"));
    assert!(
        drawn.contains("incomplete recording: it did not end cleanly"),
        "the chart says it"
    );
    std::fs::write(dir.join("lines.jsonl"), &lines).unwrap();
    std::fs::write(dir.join("session.json"), &session_text).unwrap();
    std::fs::remove_file(dir.join("frames.log")).unwrap();
    let out = common::run(&["replay", dir.to_str().unwrap()], b"");
    assert_eq!(out.status.code(), Some(2));
    let _ = std::fs::remove_dir_all(&dir);
}

/// Lines taken before a joint's answer to the line ahead of them (a move
/// and a query written together, for two joints, six times; a multi-axis
/// command followed by a query; then a stop and its release) replay as
/// recorded: the simulated joints answer at once, and the replay hands
/// their answers (and what came with them) to the bridge when the
/// recorded bridge took the recorded ones, so each query finds the bridge
/// as it was. Such queries used to diverge in every recording of this
/// session. No query follows the stop or the release: a joint's lifecycle
/// report may come apart from its Ack, and the replay does not place it
/// (the replay module says so).
#[test]
fn lines_taken_before_a_devices_answer_replay_as_recorded() {
    let dir = scratch("racing");
    let t = now_ms();
    let mut child = common::spawn(&common::sim_bridge(&["--record", dir.to_str().unwrap()]));
    let mut pipe = child.stdin.take().unwrap();
    std::thread::sleep(Duration::from_millis(300));
    for j in 1..=6 {
        let pair = format!(
            "{{\"motor_id\":\"elbow\",\"timestamp\":{t},\"control_mode\":\"position\",\"setpoint\":{}}}\n{{\"query\":\"state\"}}\n{{\"motor_id\":\"shoulder_pitch\",\"timestamp\":{t},\"control_mode\":\"position\",\"setpoint\":{}}}\n{{\"query\":\"state\",\"motor_id\":\"shoulder_pitch\"}}\n",
            j * 7,
            j * 3
        );
        pipe.write_all(pair.as_bytes()).unwrap();
        std::thread::sleep(Duration::from_millis(10 * j));
    }
    let multi = format!(
        "{{\"command_id\":\"m\",\"timestamp\":{t},\"motors\":[{{\"motor_id\":\"elbow\",\"control_mode\":\"position\",\"setpoint\":5}},{{\"motor_id\":\"shoulder_pitch\",\"control_mode\":\"position\",\"setpoint\":2}}]}}\n{{\"query\":\"state\"}}\n"
    );
    pipe.write_all(multi.as_bytes()).unwrap();
    std::thread::sleep(Duration::from_millis(50));
    pipe.write_all(b"{\"emergency_stop\":true}\n").unwrap();
    std::thread::sleep(Duration::from_millis(100));
    pipe.write_all(b"{\"emergency_stop\":false}\n").unwrap();
    std::thread::sleep(Duration::from_millis(200));
    drop(pipe);
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{stderr}");
    assert!(stderr.contains(", 0 dropped"), "{stderr}");
    // The recording says when the bridge took each frame it received.
    let lines = std::fs::read_to_string(dir.join("lines.jsonl")).unwrap();
    assert!(
        lines
            .lines()
            .any(|l| l.contains(r#""dir":"rx""#) && l.contains(r#""taken_us":"#)),
        "{lines}"
    );
    for _ in 0..2 {
        let (code, v, stderr) = replay_json(&dir, &[]);
        assert_eq!(code, Some(0), "{v} {stderr}");
        assert_eq!(v["same"], true, "{v}");
        assert_eq!(v["divergence"], Value::Null, "{v}");
        // 28 lines, the start and the end; every line answered.
        assert_eq!(v["inputs"], 30, "{v}");
        assert!(v["compared"]["answers"].as_u64().unwrap() >= 28, "{v}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// A recording that cannot be replayed faithfully is refused with the
/// reason and exit status 2: no setup, its beginning rotated away,
/// records dropped, a line that is not a record, fewer records than it
/// says it wrote, a FIFO in place of a file, a damaged clock.
#[test]
fn a_recording_that_cannot_be_replayed_says_why() {
    let dir = scratch("refused");
    std::fs::create_dir_all(&dir).unwrap();
    let session = |extra: &str| {
        format!(
            r#"{{"recorder":"motorwire","version":"0.2.0","started_wall_ms":1,"interface":"sim","files":["frames.log","lines.jsonl"]{extra}}}"#
        )
    };
    std::fs::write(dir.join("lines.jsonl"), "").unwrap();
    let cases: Vec<(String, Option<&str>, &str)> = vec![
        (session(""), None, "session.json has no setup"),
        (
            session(r#","dropped":3"#),
            None,
            "the recording dropped 3 records",
        ),
        (
            session(""),
            Some("{\"t_us\":5,\"wall_ms\":1,\"what\":1}\n"),
            "lines.jsonl:1: not an in, out, mark, frame or orion record",
        ),
        (
            session(r#","written":5,"dropped":0"#),
            None,
            "session.json says 5 records were written, lines.jsonl holds 0: the recording was cut short or edited",
        ),
    ];
    for (s, lines, says) in cases {
        std::fs::write(dir.join("session.json"), s).unwrap();
        std::fs::write(dir.join("lines.jsonl"), lines.unwrap_or("")).unwrap();
        let out = common::run(&["replay", dir.to_str().unwrap()], b"");
        let stderr = String::from_utf8(out.stderr).unwrap();
        assert_eq!(out.status.code(), Some(2), "{stderr}");
        assert!(stderr.contains(says), "{says} not in {stderr}");
    }
    // A FIFO in place of a file is never read (it would be forever).
    std::fs::write(dir.join("session.json"), session("")).unwrap();
    std::fs::remove_file(dir.join("lines.jsonl")).unwrap();
    let made = std::process::Command::new("mkfifo")
        .arg(dir.join("lines.jsonl"))
        .status()
        .unwrap();
    assert!(made.success());
    let out = common::run(&["replay", dir.to_str().unwrap()], b"");
    let stderr = String::from_utf8(out.stderr).unwrap();
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("lines.jsonl: not a regular file"),
        "{stderr}"
    );
    std::fs::remove_file(dir.join("lines.jsonl")).unwrap();
    // A damaged clock: one record a million seconds on. A recording
    // without its setup is refused first, so the setup of a real one.
    let real = scratch("real-setup");
    std::fs::create_dir_all(&real).unwrap();
    let setup = serde_json::json!({
        "recorder": "motorwire", "files": ["frames.log", "lines.jsonl"],
        "setup": {
            "map": "[motors.elbow]\ndialect = \"irpc\"\nnode = 0x12\n",
            "bus": "sim", "node": 0, "wire": "v2.0", "ack_timeout_us": 100000, "retries": 3,
            "first_msg_id": 1, "activate_on_start": true, "feedback_period_us": null,
            "offline_after_us": 500000, "heartbeat_period_us": 50000, "drain_timeout_us": 30000000,
            "epoch_unix_ms": null, "max_age_us": null, "max_pending_lines": 1024,
            "max_queue_per_joint": 16, "orion": false, "orion_command_timeout_us": 30000000,
            "telemetry_hz": null, "allow_unknown_members": false, "sim_seed": 0, "sim_faults": {}
        }
    });
    std::fs::write(real.join("session.json"), setup.to_string()).unwrap();
    std::fs::write(
        real.join("lines.jsonl"),
        "{\"t_us\":0,\"wall_ms\":1,\"mark\":{\"kind\":\"start\"}}\n\
         {\"t_us\":1000000000000,\"wall_ms\":1,\"in\":{\"origin\":0,\"line\":1,\"text\":\"{}\"}}\n",
    )
    .unwrap();
    // (It has no end either: replayed only when allowed.)
    let out = common::run(
        &["replay", real.to_str().unwrap(), "--allow-incomplete"],
        b"",
    );
    let stderr = String::from_utf8(out.stderr).unwrap();
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("the recording spans 1000000 s, more than the 21600 s a replay runs"),
        "{stderr}"
    );
    let _ = std::fs::remove_dir_all(&real);
    std::fs::write(dir.join("lines.jsonl"), "").unwrap();
    std::fs::write(dir.join("lines.1.jsonl"), "").unwrap();
    let out = common::run(&["replay", dir.to_str().unwrap()], b"");
    let stderr = String::from_utf8(out.stderr).unwrap();
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("rotated"), "{stderr}");
    let out = common::run(&["replay", "/nonexistent/recording"], b"");
    assert_eq!(out.status.code(), Some(2));
    let _ = std::fs::remove_dir_all(&dir);
}

/// `motorwire replay DIR` run to its end, or killed after `limit`: its
/// exit status (`None`: it was still running) and what it printed
/// (standard output, then standard error).
fn replay_within(dir: &Path, limit: Duration) -> (Option<i32>, String) {
    let mut child = common::spawn(&["replay", dir.to_str().unwrap()]);
    drop(child.stdin.take());
    let began = std::time::Instant::now();
    while began.elapsed() < limit {
        if child.try_wait().unwrap().is_some() {
            let out = child.wait_with_output().unwrap();
            return (
                out.status.code(),
                format!(
                    "{}{}",
                    String::from_utf8_lossy(&out.stdout),
                    String::from_utf8_lossy(&out.stderr)
                ),
            );
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let _ = child.kill();
    let out = child.wait_with_output().unwrap();
    (None, String::from_utf8_lossy(&out.stderr).into_owned())
}

/// Records one session on `map` (`--bus sim`): each of `lines` after
/// `ready`, `pause_ms` before it, stamped now; then the end of input.
fn record_on(map: &str, dir: &Path, lines: &[(u64, String)]) {
    let mut child = common::spawn(&[
        "bridge",
        "--map",
        map,
        "--bus",
        "sim",
        "--feedback-hz",
        "0",
        "--record",
        dir.to_str().unwrap(),
    ]);
    let mut pipe = child.stdin.take().unwrap();
    std::thread::sleep(Duration::from_millis(300));
    for (pause, line) in lines {
        std::thread::sleep(Duration::from_millis(*pause));
        let line = line.replace("NOW", &now_ms().to_string());
        pipe.write_all(format!("{line}\n").as_bytes()).unwrap();
    }
    drop(pipe);
    let out = child.wait_with_output().unwrap();
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// Replay ends, and reproduces what the bridge did, on every dialect
/// (issue 58 part 6): a moteus-only map with one position move (its
/// replay spun at one instant forever: the heartbeat's timer stayed due
/// on a bus without iRPC joints), and the mixed iRPC, compact and moteus
/// map with commands a few milliseconds either side of the controllers'
/// polls (a poll and a command that swapped places were a divergence:
/// the polls are the clock's, not compared).
#[test]
fn every_dialects_recording_replays_the_same_and_ends() {
    let pos = |motor: &str, v: f64| {
        format!(
            r#"{{"motor_id":"{motor}","timestamp":NOW,"control_mode":"position","setpoint":{v}}}"#
        )
    };
    let dir = scratch("moteus-only");
    record_on(
        "fixtures/maps/moteus-leg.toml",
        &dir,
        &[(0, pos("hip", 20.0)), (600, pos("knee", 30.0))],
    );
    let (code, stderr) = replay_within(&dir, Duration::from_secs(60));
    assert_eq!(code, Some(0), "moteus-only: {stderr}");
    let _ = std::fs::remove_dir_all(&dir);
    for j in 0..8u64 {
        let dir = scratch(&format!("mixed-{j}"));
        record_on(
            "fixtures/maps/demo-arm-and-leg.toml",
            &dir,
            &[
                (0, pos("elbow", 20.0)),
                (3 + 2 * j, pos("hip", 10.0 + j as f64)),
                (7 + 3 * j, pos("knee", 20.0)),
                (11 + j, pos("gripper_axis", 10.0)),
                (400, pos("hip", -5.0)),
                (5 + j, "{\"emergency_stop\":true}".to_owned()),
                (100, "{\"emergency_stop\":false}".to_owned()),
            ],
        );
        let (code, stderr) = replay_within(&dir, Duration::from_secs(60));
        assert_eq!(code, Some(0), "mixed session {j}: {stderr}");
        let _ = std::fs::remove_dir_all(&dir);
    }
}

/// A recording (`fixtures/recordings/line-before-beacon`, made by the
/// command-line acceptance's session: three lines on stdin, the Orion
/// controller simulated) whose lines came before the Orion controller's
/// boot beacon and were taken after it (what the devices say goes ahead
/// of the lines waiting) replays the same: the controller is booted
/// before the first line taken after its beacon. Replay booted it by the
/// lines' arrival, after them, and the turntable's line was refused
/// offline where the recorded bridge moved it.
#[test]
fn a_line_taken_after_the_controllers_beacon_replays_after_it() {
    let dir = common::root().join("fixtures/recordings/line-before-beacon");
    let (code, out) = replay_within(&dir, Duration::from_secs(60));
    assert_eq!(code, Some(0), "{out}");
    assert!(out.contains("the same: no divergence"), "{out}");
    assert!(
        out.contains("compared 5 answers, 24 events, 15 frames, 4 Orion lines"),
        "{out}"
    );
}
