//! `motorwire bridge --orion`: the Orion arm controller over a serial line
//! (a pseudo-terminal pair) and over TCP, with `motorwire sim orion` on the
//! other end, run as a user runs them.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing
)]

use std::io::{self, BufRead, BufReader, Read, Write};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::sync::{Arc, Mutex};
use std::thread;
use std::time::{Duration, Instant};

mod common;

/// The demo arm's map, from inside this crate (the packaged crate has it).
const MAP: &str = include_str!("../demo/demo-arm.toml");

fn map_file(name: &str) -> String {
    let path = std::env::temp_dir().join(format!(
        "motorwire-orion-{name}-{}.toml",
        std::process::id()
    ));
    std::fs::write(&path, MAP).unwrap();
    path.to_str().unwrap().to_owned()
}

/// `motorwire sim orion`, its stdin and stdout piped.
fn sim_orion() -> Child {
    Command::new(env!("CARGO_BIN_EXE_motorwire"))
        .args(["sim", "orion", "--beacon-interval", "200"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap()
}

/// Copies `from` to `to` until `from` ends, keeping each line that passes
/// in `seen`; reads that time out (a serial port's) are tried again.
fn relay(
    mut from: impl Read + Send + 'static,
    mut to: impl Write + Send + 'static,
    seen: Arc<Mutex<Vec<u8>>>,
) {
    thread::spawn(move || {
        let mut buf = [0u8; 4096];
        loop {
            let n = match from.read(&mut buf) {
                Ok(0) => return,
                Ok(n) => n,
                Err(e) if e.kind() == io::ErrorKind::TimedOut => continue,
                Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                Err(_) => return,
            };
            seen.lock().unwrap().extend_from_slice(&buf[..n]);
            if to.write_all(&buf[..n]).and_then(|()| to.flush()).is_err() {
                return;
            }
        }
    });
}

/// Runs the bridge with `--orion SPEC` on the demo map (the joints on the
/// simulated bus), feeds it `lines` one by one, each once the previous
/// one's result came, and returns every output line.
fn bridge_with(spec: &str, map: &str, lines: &[&str]) -> Vec<serde_json::Value> {
    let mut bridge = Command::new(env!("CARGO_BIN_EXE_motorwire"))
        .args([
            "bridge",
            "--map",
            map,
            "--bus",
            "sim",
            "--orion",
            spec,
            "--max-age",
            "0",
            "--feedback-hz",
            "0",
        ])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stdin = bridge.stdin.take().unwrap();
    let stdout = bridge.stdout.take().unwrap();
    let (tx, rx) = mpsc::channel();
    thread::spawn(move || {
        for line in BufReader::new(stdout).lines() {
            let Ok(line) = line else { return };
            if tx.send(line).is_err() {
                return;
            }
        }
    });
    let mut out: Vec<serde_json::Value> = Vec::new();
    let wait_for = |out: &mut Vec<serde_json::Value>, pick: &dyn Fn(&serde_json::Value) -> bool| {
        let end = Instant::now() + Duration::from_secs(20);
        loop {
            if out.iter().any(pick) {
                return;
            }
            let left = end.saturating_duration_since(Instant::now());
            let line = rx
                .recv_timeout(left)
                .unwrap_or_else(|_| panic!("nothing more within 20 s: {out:?}"));
            out.push(serde_json::from_str(&line).unwrap());
        }
    };
    // The controller's boot beacon first: commands before it would wait.
    wait_for(&mut out, &|v| v["event"] == "orion_beacon");
    for (i, line) in lines.iter().enumerate() {
        stdin.write_all(line.as_bytes()).unwrap();
        stdin.write_all(b"\n").unwrap();
        let n = i as u64 + 1;
        wait_for(&mut out, &|v| v["line"] == n && v.get("ok").is_some());
    }
    drop(stdin);
    let end = Instant::now() + Duration::from_secs(20);
    while bridge.try_wait().unwrap().is_none() {
        assert!(Instant::now() < end, "the bridge did not end: {out:?}");
        thread::sleep(Duration::from_millis(20));
    }
    out.extend(rx.try_iter().map(|l| serde_json::from_str(&l).unwrap()));
    let status = bridge.wait().unwrap();
    let mut err = String::new();
    bridge
        .stderr
        .take()
        .unwrap()
        .read_to_string(&mut err)
        .unwrap();
    assert_eq!(status.code(), Some(0), "{err}\n{out:?}");
    out
}

/// `motorwire bridge` on the demo map (its joints on the simulated bus)
/// with the Orion controller at `tcp:ADDR`, and its output lines as they
/// come.
fn tcp_bridge(addr: std::net::SocketAddr, map: &str) -> (Child, std::process::ChildStdin, Lines) {
    let mut bridge = Command::new(env!("CARGO_BIN_EXE_motorwire"))
        .args([
            "bridge",
            "--map",
            map,
            "--bus",
            "sim",
            "--orion",
            &format!("tcp:{addr}"),
            "--max-age",
            "0",
            "--feedback-hz",
            "0",
        ])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let stdin = bridge.stdin.take().unwrap();
    let stdout = bridge.stdout.take().unwrap();
    let (tx, rx) = mpsc::channel();
    thread::spawn(move || {
        for line in BufReader::new(stdout).lines() {
            let Ok(line) = line else { return };
            let _ = tx.send(serde_json::from_str::<serde_json::Value>(&line).unwrap());
        }
    });
    (
        bridge,
        stdin,
        Lines {
            rx,
            seen: Vec::new(),
        },
    )
}

/// A bridge's output lines: those seen so far, and those to come.
#[derive(Debug)]
struct Lines {
    rx: mpsc::Receiver<serde_json::Value>,
    seen: Vec<serde_json::Value>,
}

impl Lines {
    /// Waits (at most 20 s) until a line after the first `from` is one
    /// `pick` takes.
    fn until(&mut self, from: usize, pick: impl Fn(&serde_json::Value) -> bool) {
        let end = Instant::now() + Duration::from_secs(20);
        while !self.seen[from.min(self.seen.len())..].iter().any(&pick) {
            let left = end.saturating_duration_since(Instant::now());
            let Ok(v) = self.rx.recv_timeout(left) else {
                panic!("nothing more within 20 s: {:?}", self.seen);
            };
            self.seen.push(v);
        }
    }

    /// The next line that `pick` takes (at most `limit` away).
    fn next(
        &mut self,
        limit: Duration,
        pick: impl Fn(&serde_json::Value) -> bool,
    ) -> serde_json::Value {
        let end = Instant::now() + limit;
        loop {
            let left = end.saturating_duration_since(Instant::now());
            let Ok(v) = self.rx.recv_timeout(left) else {
                panic!("nothing within {limit:?}: {:?}", self.seen);
            };
            self.seen.push(v.clone());
            if pick(&v) {
                return v;
            }
        }
    }
}

const TURN: &str =
    r#"{"motor_id":"turntable","timestamp":0,"control_mode":"velocity","setpoint":150}"#;
const SERVO: &str = r#"{"motor_id":"grasper_horizontal_servo","timestamp":0,"control_mode":"position","setpoint":-45}"#;
const TOO_FAST: &str =
    r#"{"motor_id":"turntable","timestamp":0,"control_mode":"velocity","setpoint":-401}"#;
const STOP: &str = r#"{"emergency_stop":true}"#;

fn result(out: &[serde_json::Value], line: u64) -> &serde_json::Value {
    out.iter()
        .find(|v| v["line"] == line && v.get("ok").is_some())
        .unwrap_or_else(|| panic!("no result for line {line}: {out:?}"))
}

/// What every run must show: the moves acked by the controller, the clamp
/// refused before the controller, the stop reaching it.
fn check(out: &[serde_json::Value], to_controller: &str) {
    assert_eq!(result(out, 1)["acked"], serde_json::json!(["turntable"]));
    assert_eq!(
        result(out, 2)["acked"],
        serde_json::json!(["grasper_horizontal_servo"])
    );
    let arrived = out
        .iter()
        .find(|v| v["line"] == 2 && v["arrived"].is_boolean())
        .unwrap();
    assert_eq!(arrived["arrived"], true, "{arrived}");
    assert_eq!(result(out, 3)["error"]["kind"], "refused");
    assert_eq!(
        result(out, 3)["error"]["message"],
        "turntable: setpoint -401 is outside max_velocity (Orion range) 400"
    );
    let stop = result(out, 4);
    assert_eq!(stop["emergency_stop"], true);
    assert!(
        stop["acked"]
            .as_array()
            .unwrap()
            .iter()
            .any(|m| m == "turntable"),
        "{stop}"
    );
    let sent: Vec<&str> = to_controller.lines().collect();
    assert!(
        sent.contains(&r#"{"ID":32,"MODE":1,"DATA":{"TRM":150}}"#),
        "{sent:?}"
    );
    assert!(
        sent.contains(&r#"{"ID":32,"MODE":1,"DATA":{"GHS":-45}}"#),
        "{sent:?}"
    );
    assert!(sent.contains(&r#"{"ID":32,"MODE":2,"DATA":1}"#), "{sent:?}");
    assert!(!to_controller.contains("401"), "{sent:?}");
}

#[cfg(unix)]
#[test]
fn the_orion_controller_over_a_pseudo_terminal() {
    let (master, slave) = serialport::TTYPort::pair().unwrap();
    let path = serialport::SerialPort::name(&slave).unwrap();
    let mut sim = sim_orion();
    let to_controller = Arc::new(Mutex::new(Vec::new()));
    relay(
        master.try_clone_native().unwrap(),
        sim.stdin.take().unwrap(),
        Arc::clone(&to_controller),
    );
    relay(sim.stdout.take().unwrap(), master, Arc::default());
    let map = map_file("pty");
    let out = bridge_with(
        &format!("serial:{path}@115200"),
        &map,
        &[TURN, SERVO, TOO_FAST, STOP],
    );
    drop(slave);
    let _ = sim.kill();
    let _ = sim.wait();
    let sent = String::from_utf8(to_controller.lock().unwrap().clone()).unwrap();
    check(&out, &sent);
}

#[test]
fn the_orion_controller_over_tcp() {
    let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = listener.local_addr().unwrap();
    let to_controller = Arc::new(Mutex::new(Vec::new()));
    let seen = Arc::clone(&to_controller);
    let server = thread::spawn(move || {
        let (stream, _) = listener.accept().unwrap();
        let mut sim = sim_orion();
        relay(stream.try_clone().unwrap(), sim.stdin.take().unwrap(), seen);
        relay(sim.stdout.take().unwrap(), stream, Arc::default());
        sim
    });
    let map = map_file("tcp");
    let out = bridge_with(&format!("tcp:{addr}"), &map, &[TURN, SERVO, TOO_FAST, STOP]);
    let mut sim = server.join().unwrap();
    let _ = sim.kill();
    let _ = sim.wait();
    let sent = String::from_utf8(to_controller.lock().unwrap().clone()).unwrap();
    check(&out, &sent);
}

#[test]
fn the_simulated_controller_in_process_and_bad_links_are_refused() {
    let map = map_file("sim");
    let out = bridge_with("sim", &map, &[TURN, SERVO, TOO_FAST, STOP]);
    assert_eq!(result(&out, 1)["acked"], serde_json::json!(["turntable"]));
    assert_eq!(result(&out, 4)["emergency_stop"], true);
    // A link that cannot be opened ends the bridge before anything moves.
    let o = Command::new(env!("CARGO_BIN_EXE_motorwire"))
        .args([
            "bridge",
            "--map",
            &map,
            "--bus",
            "sim",
            "--orion",
            "serial:/nonexistent/tty",
        ])
        .stdin(Stdio::null())
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.starts_with("motorwire bridge: --orion serial:/nonexistent/tty: "),
        "{err}"
    );
    let o = Command::new(env!("CARGO_BIN_EXE_motorwire"))
        .args(["bridge", "--map", &map, "--bus", "sim", "--orion", "usb0"])
        .stdin(Stdio::null())
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    assert_eq!(
        String::from_utf8_lossy(&o.stderr),
        "motorwire bridge: --orion usb0: expected serial:PATH[@BAUD], tcp:ADDR or sim\n"
    );
}

/// The issue's promise: `motorwire bridge --map fixtures/maps/demo-arm.toml
/// --bus sim --orion sim` moves every motor of the map, here in one
/// multi-axis line (iRPC joints, the compact gripper, the seven Orion
/// motors), acked by each.
#[test]
fn one_multi_axis_line_moves_every_motor_of_the_map() {
    let map = map_file("all");
    let every = r#"{"command_id":"all","timestamp":0,"motors":[
        {"motor_id":"shoulder_pitch","control_mode":"position","setpoint":10},
        {"motor_id":"shoulder_roll","control_mode":"position","setpoint":-10},
        {"motor_id":"elbow","control_mode":"position","setpoint":20},
        {"motor_id":"gripper_axis","control_mode":"position","setpoint":30},
        {"motor_id":"turntable","control_mode":"velocity","setpoint":100},
        {"motor_id":"lower_arm_actuator","control_mode":"velocity","setpoint":1},
        {"motor_id":"upper_arm_actuator","control_mode":"velocity","setpoint":-1},
        {"motor_id":"arm_extension","control_mode":"velocity","setpoint":200},
        {"motor_id":"grasper_vertical","control_mode":"velocity","setpoint":-50},
        {"motor_id":"grasper_rotation","control_mode":"velocity","setpoint":25},
        {"motor_id":"grasper_horizontal_servo","control_mode":"position","setpoint":15}]}"#
        .lines()
        .map(str::trim)
        .collect::<String>();
    let out = bridge_with("sim", &map, &[&every, STOP]);
    let r = result(&out, 1);
    assert_eq!(r["ok"], true, "{r}");
    let mut acked: Vec<&str> = r["acked"]
        .as_array()
        .unwrap()
        .iter()
        .map(|m| m.as_str().unwrap())
        .collect();
    acked.sort_unstable();
    assert_eq!(
        acked,
        [
            "arm_extension",
            "elbow",
            "grasper_horizontal_servo",
            "grasper_rotation",
            "grasper_vertical",
            "gripper_axis",
            "lower_arm_actuator",
            "shoulder_pitch",
            "shoulder_roll",
            "turntable",
            "upper_arm_actuator"
        ]
    );
    // Mixing dialects is said: only the iRPC joints share a planned duration.
    assert_eq!(
        r["losses"].as_array().unwrap().last().unwrap(),
        "sync_mode: converted: compact and Orion axes are sent at the same time as the others, but only iRPC joints are planned to a common duration",
        "{r}"
    );
    assert_eq!(result(&out, 2)["emergency_stop"], true);
}

/// A TCP link that breaks (the controller's gateway restarts) is made
/// again: the next command reaches the new connection's controller.
#[test]
fn a_broken_tcp_link_is_made_again() {
    let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = listener.local_addr().unwrap();
    let (drop_tx, drop_rx) = mpsc::channel::<()>();
    let server = thread::spawn(move || {
        let mut sims = Vec::new();
        for round in 0..2 {
            let (stream, _) = listener.accept().unwrap();
            let mut sim = sim_orion();
            relay(
                stream.try_clone().unwrap(),
                sim.stdin.take().unwrap(),
                Arc::default(),
            );
            relay(
                sim.stdout.take().unwrap(),
                stream.try_clone().unwrap(),
                Arc::default(),
            );
            if round == 0 {
                drop_rx.recv().unwrap();
                let _ = stream.shutdown(std::net::Shutdown::Both);
                let _ = sim.kill();
            }
            sims.push(sim);
        }
        sims
    });
    let map = map_file("reconnect");
    let (mut bridge, mut stdin, mut out) = tcp_bridge(addr, &map);
    out.until(0, |v| v["event"] == "orion_beacon");
    stdin.write_all(format!("{TURN}\n").as_bytes()).unwrap();
    out.until(0, |v| v["line"] == 1 && v.get("ok").is_some());
    drop_tx.send(()).unwrap();
    // The new connection's controller boots: its beacon is heard.
    out.until(0, |v| v["event"] == "orion_beacon" && v["first"] == false);
    stdin.write_all(format!("{SERVO}\n").as_bytes()).unwrap();
    out.until(0, |v| v["line"] == 2 && v.get("ok").is_some());
    drop(stdin);
    let status = bridge.wait().unwrap();
    assert_eq!(status.code(), Some(0));
    assert_eq!(result(&out.seen, 1)["ok"], true, "{out:?}");
    assert_eq!(result(&out.seen, 2)["ok"], true, "{out:?}");
    for mut sim in server.join().unwrap() {
        let _ = sim.kill();
        let _ = sim.wait();
    }
}

/// The same controller (it did not restart) behind a TCP link that drops
/// for 0.8 s, a moment after a move started: when the link is back the
/// bridge stops it before anything else (the deadman's stop was lost with
/// the link, and the turntable still turns), reports its motors online
/// only then, resumes nothing, and still writes its stop at exit.
#[cfg(unix)]
#[test]
fn a_controller_heard_again_after_an_outage_is_stopped_first() {
    use std::net::{Shutdown, TcpListener, TcpStream};
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = listener.local_addr().unwrap();
    let mut sim = sim_orion();
    let sim_in = Arc::new(Mutex::new(sim.stdin.take().unwrap()));
    let current: Arc<Mutex<Option<TcpStream>>> = Arc::default();
    // Every byte the bridge wrote, and where the second connection's begin.
    let to_sim: Arc<Mutex<Vec<u8>>> = Arc::default();
    let second_from = Arc::new(Mutex::new(usize::MAX));
    {
        let current = Arc::clone(&current);
        let out = sim.stdout.take().unwrap();
        thread::spawn(move || {
            for line in BufReader::new(out).lines() {
                let Ok(line) = line else { return };
                if let Some(s) = current.lock().unwrap().as_mut() {
                    let _ = writeln!(s, "{line}");
                }
            }
        });
    }
    let (drop_tx, drop_rx) = mpsc::channel::<()>();
    let server = {
        let (current, sim_in, to_sim, second_from) = (
            Arc::clone(&current),
            Arc::clone(&sim_in),
            Arc::clone(&to_sim),
            Arc::clone(&second_from),
        );
        thread::spawn(move || {
            let mut listener = Some(listener);
            for round in 0..2 {
                let l = listener
                    .take()
                    .unwrap_or_else(|| TcpListener::bind(addr).unwrap());
                let (stream, _) = l.accept().unwrap();
                if round == 1 {
                    *second_from.lock().unwrap() = to_sim.lock().unwrap().len();
                }
                *current.lock().unwrap() = Some(stream.try_clone().unwrap());
                let (sim_in, to_sim) = (Arc::clone(&sim_in), Arc::clone(&to_sim));
                let mut reader = stream.try_clone().unwrap();
                thread::spawn(move || {
                    let mut buf = [0u8; 4096];
                    while let Ok(n @ 1..) = reader.read(&mut buf) {
                        to_sim.lock().unwrap().extend_from_slice(&buf[..n]);
                        let _ = sim_in.lock().unwrap().write_all(&buf[..n]);
                    }
                });
                if round == 0 {
                    drop_rx.recv().unwrap();
                    *current.lock().unwrap() = None;
                    let _ = stream.shutdown(Shutdown::Both);
                    // The outage: nothing listens for 0.8 s.
                    drop(l);
                    thread::sleep(Duration::from_millis(800));
                } else {
                    listener = Some(l);
                }
            }
            listener
        })
    };
    let map = map_file("outage");
    let (mut bridge, mut stdin, mut out) = tcp_bridge(addr, &map);
    out.until(0, |v| v["event"] == "orion_beacon");
    stdin.write_all(format!("{TURN}\n").as_bytes()).unwrap();
    out.until(0, |v| v["line"] == 1 && v.get("ok").is_some());
    let before = out.seen.len();
    drop_tx.send(()).unwrap();
    out.until(before, |v| {
        v["event"] == "offline" && v["motor_id"] == "turntable"
    });
    let offline_at = out.seen.len();
    out.until(offline_at, |v| {
        v["event"] == "online" && v["motor_id"] == "turntable"
    });
    // Online only once the stop was answered: the second connection's
    // first command is the stop, and TRM 150 never went again.
    let from = *second_from.lock().unwrap();
    let sent = String::from_utf8(to_sim.lock().unwrap().clone()).unwrap();
    let second: Vec<&str> = sent[from..]
        .lines()
        .filter(|l| *l != r#"{"ID":32,"MODE":1,"DATA":{}}"#)
        .collect();
    assert_eq!(
        second.first(),
        Some(&r#"{"ID":32,"MODE":2,"DATA":1}"#),
        "{second:?}"
    );
    assert!(!second.iter().any(|l| l.contains("150")), "{second:?}");
    assert!(
        out.seen[offline_at..]
            .iter()
            .all(|v| v["event"] != "orion_beacon"),
        "it did not restart"
    );
    // Served again; the stop at exit reaches it.
    stdin.write_all(format!("{SERVO}\n").as_bytes()).unwrap();
    out.until(0, |v| v["line"] == 2 && v.get("ok").is_some());
    assert_eq!(result(&out.seen, 2)["ok"], true, "{out:?}");
    drop(stdin);
    let status = bridge.wait().unwrap();
    assert_eq!(status.code(), Some(0));
    let sent = String::from_utf8(to_sim.lock().unwrap().clone()).unwrap();
    let last = sent
        .lines()
        .rfind(|l| *l != r#"{"ID":32,"MODE":1,"DATA":{}}"#)
        .unwrap()
        .to_owned();
    assert_eq!(
        last, r#"{"ID":32,"MODE":2,"DATA":1}"#,
        "the stop at exit: {sent}"
    );
    drop(server.join().unwrap());
    let _ = sim.kill();
    let _ = sim.wait();
}

/// An Orion controller that floods its link (as fast as the socket takes
/// it) costs the bridge neither its memory nor the iRPC joints' service:
/// the elbow's lines are served at once meanwhile, and the end is prompt.
/// The flood lasts 5 s (`MOTORWIRE_FLOOD_SECS` for longer: BENCHMARKS.md
/// has a minute of it, in release); the latencies and the peak are
/// printed (`--nocapture`).
#[cfg(unix)]
#[test]
fn a_flooding_controller_costs_neither_memory_nor_the_joints_latency() {
    let flood_for = std::env::var("MOTORWIRE_FLOOD_SECS")
        .ok()
        .and_then(|s| s.parse().ok())
        .map_or(Duration::from_secs(5), Duration::from_secs);
    use std::net::TcpListener;
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = listener.local_addr().unwrap();
    let flooding = Arc::new(std::sync::atomic::AtomicBool::new(true));
    let server = {
        let flooding = Arc::clone(&flooding);
        thread::spawn(move || {
            let (mut stream, _) = listener.accept().unwrap();
            let mut junk = String::from("{\"ID\":32}\n");
            for i in 0..200 {
                junk.push_str(&format!(
                    "{{\"ID\":32,\"MODE\":1,\"DATA\":{{\"TRMF\":[{i},0,0]}}}}\nnot json {i}\n"
                ));
            }
            let mut sent: u64 = 0;
            while flooding.load(std::sync::atomic::Ordering::Relaxed) {
                if stream.write_all(junk.as_bytes()).is_err() {
                    break;
                }
                sent += junk.len() as u64;
            }
            sent
        })
    };
    let map = map_file("flood");
    let (mut bridge, mut stdin, mut out) = tcp_bridge(addr, &map);
    // Lines from `ready` on: a line sent before it waits for the startup
    // (the controller's motors, heard but never answering a poll, are
    // waited for up to the offline time), which is not the flood's cost.
    out.next(Duration::from_secs(5), |v| v["event"] == "ready");
    let started = Instant::now();
    let mut peak = 0;
    let mut answers = Vec::new();
    let mut line = 0u64;
    while started.elapsed() < flood_for {
        line += 1;
        let setpoint = if line.is_multiple_of(2) { 10 } else { 20 };
        let sent = Instant::now();
        writeln!(
            stdin,
            r#"{{"motor_id":"elbow","timestamp":0,"control_mode":"position","setpoint":{setpoint}}}"#
        )
        .unwrap();
        let r = out.next(Duration::from_secs(5), |v| {
            v["line"] == line && v.get("ok").is_some()
        });
        answers.push((sent.elapsed(), r));
        peak = peak.max(common::rss_kib(bridge.id()));
        thread::sleep(Duration::from_millis(100));
    }
    flooding.store(false, std::sync::atomic::Ordering::Relaxed);
    let ending = Instant::now();
    drop(stdin);
    let status = bridge.wait().unwrap();
    let took = ending.elapsed();
    let bytes = server.join().unwrap();
    let mut latencies: Vec<u64> = answers
        .iter()
        .filter_map(|(_, r)| r["latency_us"].as_u64())
        .collect();
    latencies.sort_unstable();
    let at = |q: usize| {
        let i = (latencies.len() * q / 100).min(latencies.len().saturating_sub(1));
        latencies.get(i).copied().unwrap_or(0)
    };
    eprintln!(
        "orion flood for {flood_for:?} ({} MB sent): {} elbow lines, latency to the bus median {} us, p99 {} us, max {} us; the bridge's peak RSS {peak} KiB; the end took {took:?}",
        bytes / 1_000_000,
        latencies.len(),
        at(50),
        at(99),
        at(100),
    );
    assert_eq!(status.code(), Some(0));
    assert!(bytes > 10_000_000, "the controller sent only {bytes} bytes");
    assert!(peak < 100 * 1024, "the bridge grew to {peak} KiB");
    for (waited, r) in &answers {
        assert_eq!(r["ok"], true, "{r}");
        assert!(
            r["latency_us"].as_u64().unwrap() < 50_000,
            "latency to the bus {} µs: {r}",
            r["latency_us"]
        );
        assert!(
            *waited < Duration::from_secs(1),
            "answered after {waited:?}"
        );
    }
    assert!(took < Duration::from_secs(5), "the end took {took:?}");
}
