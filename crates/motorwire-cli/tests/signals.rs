//! `motorwire bridge` ended by a signal, as a service manager or a closed
//! terminal ends it: SIGINT, SIGTERM and SIGHUP each stop and deactivate
//! the joints, and the exit status names the signal (130, 143, 129); a
//! second signal exits at once.
#![allow(clippy::unwrap_used, clippy::panic, clippy::indexing_slicing)]

mod common;

use std::io::{BufRead, BufReader, Read};
use std::process::{Child, ChildStdin, Command, ExitStatus};
use std::sync::mpsc::{self, Receiver};
use std::thread;
use std::time::{Duration, Instant};

use serde_json::Value;

const MAP: &str = "fixtures/maps/demo-arm.toml";

/// A running bridge: stdin kept open (so only a signal can end it), its
/// stdout lines arriving on a channel.
struct Bridge {
    child: Child,
    _stdin: ChildStdin,
    lines: Receiver<Value>,
    seen: Vec<Value>,
}

impl Bridge {
    fn start(extra: &[&str]) -> Self {
        let mut args = vec!["bridge", "--map", MAP, "--bus", "sim", "--feedback-hz", "0"];
        args.extend_from_slice(extra);
        let mut child = common::spawn(&args);
        let stdin = child.stdin.take().unwrap();
        let stdout = BufReader::new(child.stdout.take().unwrap());
        let (tx, lines) = mpsc::channel();
        thread::spawn(move || {
            for line in stdout.lines() {
                let Ok(line) = line else { return };
                let v: Value = serde_json::from_str(&line).unwrap_or(Value::String(line));
                if tx.send(v).is_err() {
                    return;
                }
            }
        });
        // Keep stderr from filling up.
        let mut stderr = child.stderr.take().unwrap();
        thread::spawn(move || {
            let mut sink = Vec::new();
            let _ = stderr.read_to_end(&mut sink);
        });
        Self {
            child,
            _stdin: stdin,
            lines,
            seen: Vec::new(),
        }
    }

    /// Waits for the event named `event`.
    fn wait_for(&mut self, event: &str) -> Value {
        let end = Instant::now() + Duration::from_secs(20);
        loop {
            let left = end.saturating_duration_since(Instant::now());
            let v = self
                .lines
                .recv_timeout(left)
                .unwrap_or_else(|_| panic!("no {event:?} event; saw {:?}", self.seen));
            self.seen.push(v.clone());
            if v["event"] == event {
                return v;
            }
        }
    }

    fn kill(&self, signal: &str) {
        let status = Command::new("kill")
            .args(["-s", signal, &self.child.id().to_string()])
            .status()
            .unwrap();
        assert!(status.success(), "kill -s {signal}");
    }

    /// The exit status, within `limit`; then every line it printed.
    fn exit_within(&mut self, limit: Duration) -> (ExitStatus, Vec<Value>) {
        let end = Instant::now() + limit;
        let status = loop {
            if let Some(s) = self.child.try_wait().unwrap() {
                break s;
            }
            if Instant::now() > end {
                let _ = self.child.kill();
                panic!(
                    "still running {limit:?} after the signal; saw {:?}",
                    self.seen
                );
            }
            thread::sleep(Duration::from_millis(10));
        };
        while let Ok(v) = self.lines.recv_timeout(Duration::from_secs(5)) {
            self.seen.push(v);
        }
        (status, self.seen.clone())
    }
}

impl Drop for Bridge {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

#[test]
fn each_signal_stops_and_deactivates_the_joints_and_sets_the_exit_status() {
    let cases = [("INT", 130), ("TERM", 143), ("HUP", 129)];
    // The three bridges run side by side: one is not helped by another.
    let mut bridges: Vec<(&str, i32, Bridge)> = cases
        .into_iter()
        .map(|(signal, status)| (signal, status, Bridge::start(&[])))
        .collect();
    for (signal, _, bridge) in &mut bridges {
        let ready = bridge.wait_for("ready");
        // The three joints and the compact gripper.
        assert_eq!(ready["joints"].as_array().unwrap().len(), 4, "{ready}");
        bridge.kill(signal);
    }
    for (signal, status, bridge) in &mut bridges {
        let (exit, lines) = bridge.exit_within(Duration::from_secs(20));
        assert_eq!(exit.code(), Some(*status), "SIG{signal}: {lines:?}");
        let stopping = lines.iter().find(|v| v["event"] == "stopping");
        assert_eq!(
            stopping.map(|v| &v["reason"]),
            Some(&Value::from("interrupted")),
            "SIG{signal}: {lines:?}"
        );
        let stopped = lines
            .iter()
            .find(|v| v["event"] == "stopped")
            .unwrap_or_else(|| panic!("SIG{signal}: no stopped event: {lines:?}"));
        assert_eq!(
            stopped["deactivated"],
            serde_json::json!(["elbow", "gripper_axis", "shoulder_pitch", "shoulder_roll"]),
            "SIG{signal}: {stopped}"
        );
        assert_eq!(stopped["failures"], serde_json::json!([]), "{stopped}");
    }
}

#[test]
fn a_second_signal_exits_at_once_with_its_status() {
    // Joints that never answer: the stop after the first signal would wait
    // 3 s for each of four tries.
    let mut bridge = Bridge::start(&[
        "--no-activate",
        "--sim-faults",
        "drop=1",
        "--ack-timeout",
        "3000",
    ]);
    bridge.wait_for("ready");
    bridge.kill("INT");
    bridge.wait_for("stopping");
    let sent = Instant::now();
    bridge.kill("TERM");
    let (exit, lines) = bridge.exit_within(Duration::from_secs(5));
    assert_eq!(exit.code(), Some(143), "{lines:?}");
    assert!(
        sent.elapsed() < Duration::from_secs(2),
        "{:?} after the second signal",
        sent.elapsed()
    );
    assert!(
        !lines.iter().any(|v| v["event"] == "stopped"),
        "it did not wait for the stop: {lines:?}"
    );
}
