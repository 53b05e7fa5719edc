//! `motorwire demo`: the bridge on a simulated arm, end to end.

// Only `serde_json::Value` is indexed here: a missing key or a non-object
// gives `Null`, never a panic.
#![allow(clippy::indexing_slicing)]

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::mpsc::{self, Receiver, RecvTimeoutError};
use std::time::{Duration, Instant};

use motorwire_bridge::sim::RealTimeArm;
use motorwire_bridge::{Bridge, BridgeConfig, Origin, Output, Runner};
use motorwire_translate::BusMap;
use serde_json::Value;

use crate::console::{note, say};

/// Runs the bridge on the simulated arm of `fixtures/maps/demo-arm.toml`:
/// the WIA document's multi-axis example, a move, a synchronized move, an
/// unsafe command refused, an emergency stop and its release. Prints each
/// step, a summary, and writes an SVG of the joints' positions and
/// velocities from their feedback. Exits 0 only if every expectation held.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// Where to write the plot of positions and velocities against time.
    #[arg(long, value_name = "FILE", default_value = "motorwire-demo.svg")]
    svg: PathBuf,
}

const MAP: &str = include_str!("../demo/demo-arm.toml");
/// The SO-101 arm's six Feetech servos, beside the demo arm.
const SO101: &str = include_str!("../demo/so101.toml");
const MULTI: &str = include_str!("../demo/doc-3.2-multi-axis-command.json");
const ORIGIN: Origin = Origin(1);
/// How close a joint must come to its target (degrees).
const AT_TARGET: f64 = 0.05;

#[derive(Debug, Clone, Copy, PartialEq)]
enum Expect {
    /// Acked; then every listed joint reaches its target (deg) in time.
    Arrive(&'static [(&'static str, f64)]),
    /// Acked; the next step follows after this long.
    AckedThenWait(Duration),
    /// Refused with this `error.kind`.
    Refused(&'static str),
    /// The emergency stop: acked by every joint; they come to rest.
    Stop,
    /// The release: acked by every joint.
    Release,
    /// Acked; the motor runs at this speed; then, with no command renewing
    /// it, the deadman brings it to rest.
    Deadman(&'static str, f64),
}

struct Step {
    title: &'static str,
    line: String,
    expect: Expect,
}

fn command(motor: &str, setpoint: f64, velocity: f64) -> String {
    format!(
        r#"{{"motor_id":"{motor}","timestamp":0,"control_mode":"position","setpoint":{setpoint},"velocity_limit":{velocity}}}"#
    )
}

fn script() -> Vec<Step> {
    let multi: String = MULTI.lines().map(str::trim).collect();
    vec![
        Step {
            title: "WIA §3.2 multi-axis example: 3 joints, synchronized, 2 s",
            line: multi,
            expect: Expect::Arrive(&[("shoulder_pitch", 45.0), ("shoulder_roll", 15.0), ("elbow", 90.0)]),
        },
        Step {
            title: "move: elbow to 30° at up to 120°/s",
            line: command("elbow", 30.0, 120.0),
            expect: Expect::Arrive(&[("elbow", 30.0)]),
        },
        Step {
            title: "synchronized move: pitch -30°, roll 20°, elbow 60°",
            line: r#"{"command_id":"demo-sync","timestamp":0,"sync_mode":"simultaneous","motors":[{"motor_id":"shoulder_pitch","control_mode":"position","setpoint":-30},{"motor_id":"shoulder_roll","control_mode":"position","setpoint":20},{"motor_id":"elbow","control_mode":"position","setpoint":60}]}"#.to_owned(),
            expect: Expect::Arrive(&[("shoulder_pitch", -30.0), ("shoulder_roll", 20.0), ("elbow", 60.0)]),
        },
        Step {
            title: "trajectory: the elbow through 100° at 40°/s at 1.1 s, to rest at 70° at 2.5 s",
            line: r#"{"trajectory_id":"demo-wave","motor_id":"elbow","waypoints":[{"position":60,"velocity":0,"time":0},{"position":100,"velocity":40,"time":1.1},{"position":70,"velocity":0,"time":2.5}],"timing":{"interpolation":"quintic"}}"#.to_owned(),
            expect: Expect::Arrive(&[("elbow", 70.0)]),
        },
        Step {
            title: "compact command: close the gripper to 45° (CAN id 0x20, acked by its feedback)",
            line: r#"{"motor_id":"gripper_axis","timestamp":0,"control_mode":"position","setpoint":45,"velocity_limit":60}"#.to_owned(),
            expect: Expect::Arrive(&[("gripper_axis", 45.0)]),
        },
        Step {
            title: "SO-101: elbow_flex to 40° (a Feetech STS3215 on a serial bus: one sync write, read back by one sync read)",
            line: r#"{"motor_id":"elbow_flex","timestamp":0,"control_mode":"position","setpoint":40}"#.to_owned(),
            expect: Expect::Arrive(&[("elbow_flex", 40.0)]),
        },
        Step {
            title: "unsafe: SO-101 wrist_flex to 120° (its calibrated range ends at 102.4°)",
            line: r#"{"motor_id":"wrist_flex","timestamp":0,"control_mode":"position","setpoint":120}"#.to_owned(),
            expect: Expect::Refused("refused"),
        },
        Step {
            title: "Orion: turn the turntable at 150 (its controller over a line link), then send nothing more",
            line: r#"{"motor_id":"turntable","timestamp":0,"control_mode":"velocity","setpoint":150}"#.to_owned(),
            expect: Expect::Deadman("turntable", 150.0),
        },
        Step {
            title: "unsafe: elbow to 170° (its limit is 150°)",
            line: command("elbow", 170.0, 60.0),
            expect: Expect::Refused("refused"),
        },
        Step {
            title: "SO-101: shoulder_lift to 60°, under way...",
            line: r#"{"motor_id":"shoulder_lift","timestamp":0,"control_mode":"position","setpoint":60,"velocity_limit":90}"#.to_owned(),
            expect: Expect::AckedThenWait(Duration::from_millis(100)),
        },
        Step {
            title: "move: shoulder_pitch to 80°, interrupted...",
            line: command("shoulder_pitch", 80.0, 120.0),
            expect: Expect::AckedThenWait(Duration::from_millis(400)),
        },
        Step {
            title: "...by an emergency stop",
            line: r#"{"emergency_stop": true}"#.to_owned(),
            expect: Expect::Stop,
        },
        Step {
            title: "while latched: elbow to 10°",
            line: command("elbow", 10.0, 60.0),
            expect: Expect::Refused("emergency_stop_latched"),
        },
        Step {
            title: "release the emergency stop",
            line: r#"{"emergency_stop": false}"#.to_owned(),
            expect: Expect::Release,
        },
        Step {
            title: "move: shoulder_pitch back to 0°",
            line: command("shoulder_pitch", 0.0, 120.0),
            expect: Expect::Arrive(&[("shoulder_pitch", 0.0)]),
        },
        Step {
            title: "SO-101: shoulder_lift, stopped with its torque off, back to 0°",
            line: r#"{"motor_id":"shoulder_lift","timestamp":0,"control_mode":"position","setpoint":0,"velocity_limit":120}"#.to_owned(),
            expect: Expect::Arrive(&[("shoulder_lift", 0.0)]),
        },
        Step {
            title: "compact command: open the gripper to 0°",
            line: r#"{"motor_id":"gripper_axis","timestamp":0,"control_mode":"position","setpoint":0,"velocity_limit":60}"#.to_owned(),
            expect: Expect::Arrive(&[("gripper_axis", 0.0)]),
        },
    ]
}

struct Watch {
    rx: Receiver<(Instant, Output)>,
    /// Motors the demo never moves (the Orion motors but the turntable),
    /// left out of the summary.
    unplotted: Vec<String>,
    started: Instant,
    latest: BTreeMap<String, (f64, f64)>,
    /// Everything the bridge gave, for the plot.
    session: crate::chart::Session,
    events: Vec<Value>,
}

impl Watch {
    fn take(&mut self, (at, o): (Instant, Output)) -> Option<Value> {
        let v = o.to_value();
        let t = at.saturating_duration_since(self.started).as_secs_f64();
        let to = o.reader().map(|r| r.0);
        self.session.outputs.push((t, to, v.clone()));
        match o {
            Output::Result { .. } => return Some(v),
            Output::Feedback(_) => {
                let (Some(motor), Some(pos), Some(vel)) = (
                    v["motor_id"].as_str(),
                    v["feedback"]["position"].as_f64(),
                    v["feedback"]["velocity"].as_f64(),
                ) else {
                    return None;
                };
                self.latest.insert(motor.to_owned(), (pos, vel));
            }
            Output::Event(_) | Output::ToOne { .. } | Output::Arrival { .. } => self.events.push(v),
        }
        None
    }

    /// The next result, within `limit`.
    fn result(&mut self, limit: Duration) -> Option<Value> {
        let end = Instant::now() + limit;
        loop {
            let left = end.saturating_duration_since(Instant::now());
            match self.rx.recv_timeout(left) {
                Ok(o) => {
                    if let Some(r) = self.take(o) {
                        return Some(r);
                    }
                }
                Err(_) => return None,
            }
        }
    }

    /// Consumes output until `done` holds on the latest feedback, or `limit`.
    fn until(
        &mut self,
        limit: Duration,
        done: impl Fn(&BTreeMap<String, (f64, f64)>) -> bool,
    ) -> bool {
        let end = Instant::now() + limit;
        while !done(&self.latest) {
            let left = end.saturating_duration_since(Instant::now());
            match self.rx.recv_timeout(left) {
                Ok(o) => {
                    let _ = self.take(o);
                }
                Err(RecvTimeoutError::Timeout | RecvTimeoutError::Disconnected) => return false,
            }
        }
        true
    }

    /// Consumes output for `d`.
    fn wait(&mut self, d: Duration) {
        let end = Instant::now() + d;
        while let Ok(o) = self
            .rx
            .recv_timeout(end.saturating_duration_since(Instant::now()))
        {
            let _ = self.take(o);
        }
    }
}

fn at(latest: &BTreeMap<String, (f64, f64)>, targets: &[(&str, f64)]) -> bool {
    targets.iter().all(|(m, t)| {
        latest
            .get(*m)
            .is_some_and(|(p, v)| (p - t).abs() < AT_TARGET && v.abs() < 1e-3)
    })
}

pub(crate) fn run(args: &Args) -> u8 {
    match demo(args) {
        Ok(true) => 0,
        Ok(false) => 1,
        Err(e) => {
            note!("motorwire demo: {e}");
            2
        }
    }
}

/// Why the demo ended early: its stdout closed.
fn stdout_closed(e: std::io::Error) -> String {
    format!("writing standard output: {e}")
}

#[allow(clippy::too_many_lines)]
fn demo(args: &Args) -> Result<bool, String> {
    let started = Instant::now();
    let map = BusMap::from_toml(&format!("{MAP}\n{SO101}")).map_err(|e| e.to_string())?;
    let epoch_ms = crate::bridge::unix_ms();
    let config = BridgeConfig {
        feedback_period: Some(Duration::from_millis(20)),
        epoch_unix_ms: Some(epoch_ms),
        line_link: true,
        ..BridgeConfig::default()
    };
    let plot_map = map.clone();
    let unplotted: Vec<String> = map
        .motors()
        .filter(|m| match m.target {
            motorwire_translate::Target::Orion { .. } => m.name != "turntable",
            // The SO-101's joints the demo does not move.
            motorwire_translate::Target::Servo(_) => {
                !matches!(m.name.as_str(), "elbow_flex" | "shoulder_lift")
            }
            _ => false,
        })
        .map(|m| m.name.clone())
        .collect();
    let devices = map.motors().count();
    let bridge = Bridge::new(map, config).map_err(|e| e.to_string())?;
    let arm = RealTimeArm::start(bridge.map()).map_err(|e| e.to_string())?;
    say!("motorwire demo: the bridge on a simulated 3-joint arm, its gripper, the Orion rover arm and an SO-101 arm\n  (fixtures/maps/demo-arm.toml and fixtures/maps/so101.toml)")
        .map_err(stdout_closed)?;
    say!(
        "  shoulder_pitch 0x10, shoulder_roll 0x11, elbow 0x12: iRPC v2.0; gripper_axis 0x20: the WIA compact command;\n  over an in-memory CAN-FD bus, in real time; the Orion arm's seven motors through its simulated controller\n  (one JSON line each way, as over its serial link); the SO-101's six Feetech STS3215 servos on a simulated\n  serial bus at 1 Mbit/s, all under one emergency stop\n"
    ).map_err(stdout_closed)?;
    let orion = crate::orion_link::open(&crate::orion_link::OrionSpec::Sim)?;
    let servos = motorwire_bridge::sim::servo_links(bridge.map()).map_err(|e| e.to_string())?;
    let runner = Runner::new().with_orion(orion).with_servo_links(servos);
    let input = runner.input();
    let (tx, rx) = mpsc::channel();
    let handle = arm.spawn(runner, bridge, move |o| {
        let _ = tx.send((Instant::now(), o.clone()));
    });
    let mut watch = Watch {
        rx,
        unplotted,
        started: Instant::now(),
        latest: BTreeMap::new(),
        session: crate::chart::Session::default(),
        events: Vec::new(),
    };
    let steps = script();
    let mut held = true;
    let mut rows = Vec::new();
    let mut targets: BTreeMap<&str, f64> = BTreeMap::new();
    for (i, step) in steps.iter().enumerate() {
        let sent_s = watch.started.elapsed().as_secs_f64();
        watch
            .session
            .steps
            .push((sent_s, format!("step {}: {}", i + 1, step.title)));
        input.line(ORIGIN, stamped(&step.line));
        let result = watch.result(Duration::from_secs(3));
        let (ok, detail) = match (&result, step.expect) {
            (None, _) => (false, "no result within 3 s".to_owned()),
            (Some(r), Expect::Refused(kind)) => (
                r["ok"] == false && r["error"]["kind"] == kind,
                format!(
                    "refused ({}): {}",
                    r["error"]["kind"].as_str().unwrap_or("?"),
                    r["error"]["message"].as_str().unwrap_or("")
                ),
            ),
            (Some(r), Expect::Arrive(ts)) => {
                let acked = r["ok"] == true;
                let arrived = acked && watch.until(Duration::from_secs(4), |l| at(l, ts));
                for (m, t) in ts {
                    targets.insert(m, *t);
                }
                (
                    acked && arrived,
                    format!(
                        "acked by {} in {} µs ({} µs to the bus){}",
                        r["acked"].as_array().map_or(0, Vec::len),
                        r["ack_us"],
                        r["latency_us"],
                        if arrived {
                            ", arrived"
                        } else {
                            ", DID NOT ARRIVE"
                        }
                    ),
                )
            }
            (Some(r), Expect::AckedThenWait(d)) => {
                watch.wait(d);
                (
                    r["ok"] == true,
                    format!("acked in {} µs; moving", r["ack_us"]),
                )
            }
            (Some(r), Expect::Stop) => {
                // Every device of the map: the three joints, the gripper
                // and the Orion arm's motors.
                let acked =
                    r["ok"] == true && r["acked"].as_array().is_some_and(|a| a.len() == devices);
                let rest = watch.until(Duration::from_secs(2), |l| {
                    l.len() == devices && l.values().all(|(_, v)| v.abs() < 1e-3)
                });
                if let Some((p, _)) = watch.latest.get("shoulder_pitch") {
                    targets.insert("shoulder_pitch", *p);
                }
                (
                    acked && rest,
                    format!(
                        "latched; stop frames on the bus {} µs after the line; every joint at rest: {rest}",
                        r["stop_latency_us"]
                    ),
                )
            }
            (Some(r), Expect::Deadman(motor, speed)) => {
                let acked = r["ok"] == true;
                let turning = acked
                    && watch.until(Duration::from_secs(2), |l| {
                        l.get(motor).is_some_and(|(_, v)| (v - speed).abs() < 1e-9)
                    });
                let stopped = turning
                    && watch.until(Duration::from_secs(2), |l| {
                        l.get(motor).is_some_and(|(_, v)| *v == 0.0)
                    });
                let deadman = watch
                    .events
                    .iter()
                    .any(|e| e["event"] == "deadman" && e["motor_id"] == motor);
                targets.insert(motor, 0.0);
                (
                    acked && turning && stopped && deadman,
                    if acked {
                        format!(
                            "acked in {} µs; turning at {speed}: {turning}; the deadman stopped it 200 ms after the last command: {}",
                            r["ack_us"],
                            stopped && deadman
                        )
                    } else {
                        format!("not taken: {}", r["error"])
                    },
                )
            }
            (Some(r), Expect::Release) => (
                r["ok"] == true && r["released"] == true,
                format!(
                    "released; {} joints active again",
                    r["acked"].as_array().map_or(0, Vec::len)
                ),
            ),
        };
        held &= ok;
        let mark = if ok { "ok  " } else { "FAIL" };
        say!(
            "[{}/{}] {mark} {}\n          {detail}",
            i + 1,
            steps.len(),
            step.title
        )
        .map_err(stdout_closed)?;
        rows.push((step.title, ok));
    }
    input.finish();
    let bridge = handle
        .join()
        .map_err(|_| "the bridge thread failed".to_owned())?
        .map_err(|e| e.to_string())?;
    while let Ok(o) = watch.rx.try_recv() {
        let _ = watch.take(o);
    }
    drop(arm);
    let stopped = watch
        .events
        .iter()
        .any(|e| e["event"] == "stopped" && e["failures"] == serde_json::json!([]));
    held &= stopped;

    say!("\nsummary:").map_err(stdout_closed)?;
    let passed = rows.iter().filter(|(_, ok)| *ok).count();
    say!("  {passed} of {} steps as expected", rows.len()).map_err(stdout_closed)?;
    say!(
        "  {:<16} {:>10} {:>10} {:>8}",
        "joint",
        "final (°)",
        "target (°)",
        ""
    )
    .map_err(stdout_closed)?;
    for j in bridge.joints() {
        let pos = j.feedback.as_ref().map(|f| f.position);
        let target = targets.get(j.name.as_str()).copied();
        if target.is_none() && watch.unplotted.contains(&j.name) {
            continue; // an Orion motor the demo does not move
        }
        let ok = matches!((pos, target), (Some(p), Some(t)) if (p - t).abs() < AT_TARGET);
        held &= ok;
        say!(
            "  {:<16} {:>10} {:>10} {:>8}",
            j.name,
            pos.map_or("?".to_owned(), |p| format!("{p:.3}")),
            target.map_or("?".to_owned(), |t| format!("{t:.3}")),
            if ok { "ok" } else { "FAIL" }
        )
        .map_err(stdout_closed)?;
    }
    let s = bridge.stats();
    say!(
        "  bridge: {} lines ({} ok, {} refused or failed), {} frames sent, {} feedback lines; joints stopped and deactivated: {stopped}",
        s.lines, s.ok, s.failed, s.frames_sent, s.feedback_lines
    ).map_err(stdout_closed)?;
    let drawn = crate::chart::draw(
        watch.session.digest(),
        &plot_map,
        &[],
        "motorwire demo: the bridge on a simulated arm, its gripper and the Orion rover arm",
        &args.svg,
    );
    match drawn {
        Ok(_) => say!(
            "  plot of positions, velocities, targets, limits and events: {}",
            args.svg.display()
        )
        .map_err(stdout_closed)?,
        Err(e) => {
            held = false;
            say!("  plot FAILED: {e}").map_err(stdout_closed)?;
        }
    }
    say!("  {:.1} s", started.elapsed().as_secs_f64()).map_err(stdout_closed)?;
    if held {
        say!("all expectations held").map_err(stdout_closed)?;
    } else {
        say!("an expectation did not hold (see FAIL above)").map_err(stdout_closed)?;
    }
    Ok(held)
}

/// `line` with its `timestamp` set to now (the bridge refuses commands
/// outside WIA's 5-minute clock skew).
fn stamped(line: &str) -> String {
    match serde_json::from_str::<Value>(line) {
        Ok(mut v) if v.get("timestamp").is_some() => {
            let now = crate::bridge::unix_ms().floor();
            v["timestamp"] = Value::from(now);
            v.to_string()
        }
        _ => line.to_owned(),
    }
}
