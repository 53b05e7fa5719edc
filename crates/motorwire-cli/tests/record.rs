//! `motorwire bridge --record DIR` as a user runs it: what the session took
//! in and gave out, in the field's formats (issue 28 part 1).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod common;

use std::io::Write;

use motorwire_can::candump::LogEntry;
use serde_json::Value;

use common::now_ms;

/// Every output line the bridge printed is in `lines.jsonl`, as printed
/// and in order; every input line with its client and number; every frame
/// both as `candump -L` writes it (read back by motorwire's own candump
/// reader, the same as can-utils writes them) and with its direction; the
/// Orion controller's lines both ways; nothing dropped.
#[test]
fn a_recorded_session_holds_every_line_and_frame_in_both_formats() {
    let dir = std::env::temp_dir().join(format!("motorwire-record-cli-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let t = now_ms();
    let moves = format!(
        "{{\"motor_id\":\"elbow\",\"timestamp\":{t},\"control_mode\":\"position\",\"setpoint\":20}}\n\
         {{\"motor_id\":\"elbow\",\"timestamp\":{t},\"control_mode\":\"position\",\"setpoint\":170}}\n\
         {{\"motor_id\":\"turntable\",\"timestamp\":{t},\"control_mode\":\"velocity\",\"setpoint\":100}}\n"
    );
    // A line that is not UTF-8: refused, and recorded by its bytes.
    let bad: &[u8] = b"{\"motor_id\":\"elbow\",\"x\":\"\xff\"}\n";
    let stop = "{\"emergency_stop\":true}\n";
    let input = format!("{moves}{stop}");
    let mut child = common::spawn(&common::sim_bridge(&[
        "--orion",
        "sim",
        "--feedback-hz",
        "5",
        "--record",
        dir.to_str().unwrap(),
    ]));
    let mut pipe = child.stdin.take().unwrap();
    pipe.write_all(moves.as_bytes()).unwrap();
    pipe.write_all(bad).unwrap();
    // The moves run before the stop comes (a stop overtakes the lines
    // queued before it).
    std::thread::sleep(std::time::Duration::from_millis(800));
    pipe.write_all(stop.as_bytes()).unwrap();
    drop(pipe);
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{stderr}");
    assert!(stderr.contains(" dropped"), "{stderr}");
    assert!(stderr.contains(", 0 dropped"), "{stderr}");
    let printed: Vec<Value> = String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    let lines: Vec<Value> = std::fs::read_to_string(dir.join("lines.jsonl"))
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    for l in &lines {
        assert!(l["t_us"].is_u64() && l["wall_ms"].is_u64(), "{l}");
    }
    // Every output line, as printed, in order.
    let outs: Vec<&Value> = lines.iter().filter_map(|l| l.get("out")).collect();
    assert_eq!(outs.len(), printed.len());
    assert!(outs.iter().zip(&printed).all(|(a, b)| *a == b));
    // Every input line, with its client and number, in the order the
    // bridge took them (a stop may overtake the lines queued before it).
    let mut ins: Vec<&Value> = lines.iter().filter_map(|l| l.get("in")).collect();
    ins.sort_by_key(|i| i["line"].as_u64());
    let unread = ins.remove(3);
    assert_eq!(unread["line"], 4);
    assert_eq!(unread["unreadable"], "the line is not UTF-8");
    assert_eq!(
        unread["bytes"],
        "7b226d6f746f725f6964223a22656c626f77222c2278223a22ff227d"
    );
    assert_eq!(unread["length"], bad.len() - 1);
    let sent: Vec<&str> = input.lines().collect();
    assert_eq!(ins.len(), sent.len());
    for (k, (i, text)) in ins.iter().zip(&sent).enumerate() {
        assert_eq!(i["origin"], 0);
        assert_eq!(i["line"], if k < 3 { k + 1 } else { k + 2 });
        assert_eq!(i["text"], *text);
    }
    // Every frame in both files, the same frame in the same order.
    let log = std::fs::read_to_string(dir.join("frames.log")).unwrap();
    let logged: Vec<LogEntry> = log.lines().map(|l| LogEntry::parse(l).unwrap()).collect();
    let framed: Vec<&Value> = lines.iter().filter_map(|l| l.get("frame")).collect();
    assert_eq!(logged.len(), framed.len());
    for (e, f) in logged.iter().zip(&framed) {
        assert_eq!(e.interface, "sim");
        assert_eq!(f["id"], e.frame.id().raw());
        assert_eq!(f["fd"], e.frame.is_fd());
        let hex: String = e.frame.data().iter().map(|b| format!("{b:02x}")).collect();
        assert_eq!(f["data"], hex);
    }
    let tx = framed.iter().filter(|f| f["dir"] == "tx").count();
    assert!(tx >= 4 && framed.len() > tx, "{tx} of {}", framed.len());
    // The Orion controller's lines, both ways: the beacon in, the
    // turntable's speed and the stop out.
    let orion: Vec<&Value> = lines.iter().filter_map(|l| l.get("orion")).collect();
    assert!(
        orion
            .iter()
            .any(|o| o["dir"] == "rx" && o["line"] == r#"{"ID":32}"#)
    );
    assert!(
        orion
            .iter()
            .any(|o| o["dir"] == "tx" && o["line"] == r#"{"ID":32,"MODE":1,"DATA":{"TRM":100}}"#),
        "{orion:?}"
    );
    assert!(
        orion
            .iter()
            .any(|o| o["dir"] == "tx" && o["line"] == r#"{"ID":32,"MODE":2,"DATA":1}"#)
    );
    let session: Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("session.json")).unwrap()).unwrap();
    assert_eq!(session["dropped"], 0);
    assert_eq!(session["written"], lines.len());
    assert_eq!(session["interface"], "sim");
    let _ = std::fs::remove_dir_all(&dir);
}

/// A directory that cannot be made is refused at start, named; nothing
/// runs.
#[test]
fn a_recording_that_cannot_be_made_is_refused_at_start() {
    let out = common::run(
        &common::sim_bridge(&["--record", "/proc/motorwire-record"]),
        b"",
    );
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("motorwire bridge: --record /proc/motorwire-record: "),
        "{stderr}"
    );
    let out = common::run(
        &common::sim_bridge(&["--record", "/tmp/x", "--record-max-mb", "0"]),
        b"",
    );
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("--record-max-mb must be at least 1"));
    // An empty path would record into the working directory.
    let out = common::run(&common::sim_bridge(&["--record", ""]), b"");
    assert_eq!(out.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("--record needs a directory"),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// A disk of 512 KiB for a recording: a tmpfs mounted for the test, or,
/// where mounting is not allowed, a limit on the size of each file the
/// bridge writes (its writes past it fail, as on a full disk). Unmounted
/// and removed when dropped.
struct SmallDisk {
    base: std::path::PathBuf,
    mounted: bool,
}

impl SmallDisk {
    fn new(name: &str) -> Self {
        let base = std::env::temp_dir().join(format!("motorwire-{name}-{}", std::process::id()));
        let _ = std::process::Command::new("umount").arg(&base).output();
        let _ = std::fs::remove_dir_all(&base);
        std::fs::create_dir_all(&base).unwrap();
        let mounted = std::process::Command::new("mount")
            .args(["-t", "tmpfs", "-o", "size=512k", "tmpfs"])
            .arg(&base)
            .output()
            .is_ok_and(|o| o.status.success());
        Self { base, mounted }
    }

    /// `motorwire ARGS`, its writes bounded as the disk says.
    fn spawn(&self, args: &[&str]) -> std::process::Child {
        if self.mounted {
            return common::spawn(args);
        }
        // Past the limit a write fails (EFBIG) and the kernel sends
        // SIGXFSZ, ignored here as the bridge inherits it; `ulimit -f`
        // counts 512-byte blocks (POSIX sh; bash counts KiB: 1 MiB then).
        std::process::Command::new("sh")
            .arg("-c")
            .arg(r#"trap '' XFSZ; ulimit -f 1024 && exec "$0" "$@""#)
            .arg(env!("CARGO_BIN_EXE_motorwire"))
            .args(args)
            .current_dir(common::root())
            .stdin(std::process::Stdio::piped())
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap()
    }
}

impl Drop for SmallDisk {
    fn drop(&mut self) {
        if self.mounted {
            let _ = std::process::Command::new("umount")
                .arg(&self.base)
                .output();
        }
        let _ = std::fs::remove_dir_all(&self.base);
    }
}

/// A recording onto a disk that fills (512 KiB, 3 s of feedback at
/// 250 Hz a joint, then an emergency stop and the end of input) loses
/// records, and says so everywhere: `session.json` counts them and marks
/// the recording incomplete (no stray `session.json.part`), the bridge's
/// last line on stderr and its exit status say records were lost,
/// `motorwire replay` refuses it (exit 2) unless `--allow-incomplete`,
/// and then replays it saying it is incomplete, and `motorwire plot`
/// names the gap on the chart. It used to end with exit 0, a
/// `session.json` without its counts beside an empty
/// `session.json.part`, a replay that was "the same: no divergence" and
/// a chart with no marks.
#[test]
fn a_recording_that_lost_records_says_so_everywhere() {
    let disk = SmallDisk::new("record-full");
    let dir = disk.base.join("rec");
    let mut child = disk.spawn(&common::sim_bridge(&[
        "--feedback-hz",
        "250",
        "--record",
        dir.to_str().unwrap(),
    ]));
    let mut pipe = child.stdin.take().unwrap();
    std::thread::sleep(std::time::Duration::from_secs(3));
    pipe.write_all(b"{\"emergency_stop\":true}\n").unwrap();
    drop(pipe);
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    let last = stderr.lines().last().unwrap_or("");
    // The bridge: the last line says what was lost, and so does its status.
    let session: Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("session.json")).unwrap()).unwrap();
    let dropped = session["dropped"].as_u64().unwrap_or(0);
    assert!(dropped > 0, "{session}\n{stderr}");
    assert_eq!(out.status.code(), Some(73), "{stderr}");
    assert!(
        last.starts_with(&format!(
            "motorwire bridge: the recording lost {dropped} records"
        )),
        "{stderr}"
    );
    // session.json: its counts and the mark, written in place.
    assert_eq!(session["complete"], false, "{session}");
    assert!(session["ended_wall_ms"].is_u64(), "{session}");
    assert!(session["written"].as_u64().unwrap() > 0, "{session}");
    assert!(
        session["dropped_first_us"].as_u64().unwrap()
            <= session["dropped_last_us"].as_u64().unwrap(),
        "{session}"
    );
    assert!(!dir.join("session.json.part").exists());
    // replay: refused, unless allowed; then replayed and said incomplete.
    let out = common::run(&["replay", dir.to_str().unwrap()], b"");
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains(&format!("the recording dropped {dropped} records"))
            && err.contains("--allow-incomplete"),
        "{err}"
    );
    let out = common::run(
        &["replay", dir.to_str().unwrap(), "--allow-incomplete"],
        b"",
    );
    let err = String::from_utf8_lossy(&out.stderr);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(matches!(out.status.code(), Some(0 | 1)), "{err}");
    assert!(err.contains("incomplete"), "{err}");
    assert!(text.contains("incomplete"), "{text}");
    let out = common::run(
        &[
            "replay",
            dir.to_str().unwrap(),
            "--allow-incomplete",
            "--json",
        ],
        b"",
    );
    let v: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["complete"], false, "{v}");
    assert_eq!(v["dropped"], dropped, "{v}");
    // plot: the gap named on the chart.
    let svg =
        std::env::temp_dir().join(format!("motorwire-record-full-{}.svg", std::process::id()));
    let out = common::run(
        &[
            "plot",
            dir.to_str().unwrap(),
            "--svg",
            svg.to_str().unwrap(),
        ],
        b"",
    );
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let drawn = std::fs::read_to_string(&svg).unwrap();
    assert!(
        drawn.contains(&format!("incomplete recording: {dropped} records lost")),
        "{drawn}"
    );
    let _ = std::fs::remove_file(&svg);
}
