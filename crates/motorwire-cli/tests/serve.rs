//! `motorwire bridge` under load and attack, as real processes: clients that
//! flood or stop reading, a standard output nobody reads, HTTP, tokens,
//! the local socket, the connection limit and running out of descriptors.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing
)]

mod common;

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::os::unix::fs::PermissionsExt;
use std::os::unix::net::UnixStream;
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStderr, Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, mpsc};
use std::thread;
use std::time::{Duration, Instant};

use serde_json::Value;

const MAP: &str = "fixtures/maps/demo-arm.toml";

fn now_ms() -> u128 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .as_millis()
}

fn command(motor: &str, setpoint: f64) -> String {
    format!(
        r#"{{"motor_id":"{motor}","timestamp":{},"control_mode":"position","setpoint":{setpoint}}}"#,
        now_ms()
    )
}

/// A fresh directory for this test's files.
fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("motorwire-serve-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A token file in `dir` holding `token`, readable by its owner only.
fn token_file(dir: &Path, token: &str) -> PathBuf {
    let path = dir.join("token");
    std::fs::write(&path, format!("{token}\n")).unwrap();
    std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o600)).unwrap();
    path
}

/// The bridge process, killed when dropped.
struct Bridge(Child);

impl Drop for Bridge {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// Waits for the bridge to say where it listens; returns its stderr.
fn listening(child: &mut Child) -> (String, BufReader<ChildStderr>) {
    let mut stderr = BufReader::new(child.stderr.take().unwrap());
    let mut said = String::new();
    stderr.read_line(&mut said).unwrap();
    assert!(said.contains("listening on"), "{said}");
    (said.trim().to_owned(), stderr)
}

fn tcp_port(said: &str) -> u16 {
    said.rsplit(':').next().unwrap().parse().unwrap()
}

/// The next line of `r` that is a result (not feedback, not an event).
fn next_result(r: &mut impl BufRead) -> Value {
    loop {
        let mut line = String::new();
        assert!(r.read_line(&mut line).unwrap() > 0, "connection closed");
        let v: Value = serde_json::from_str(&line).unwrap();
        if v.get("ok").is_some() && v.get("event").is_none() {
            return v;
        }
    }
}

/// Reads stdout lines into a channel (so a test can wait for an event).
fn stdout_lines(child: &mut Child) -> mpsc::Receiver<Value> {
    let out = child.stdout.take().unwrap();
    let (tx, rx) = mpsc::channel();
    thread::spawn(move || {
        for line in BufReader::new(out).lines() {
            let Ok(line) = line else { return };
            if let Ok(v) = serde_json::from_str::<Value>(&line)
                && tx.send(v).is_err()
            {
                return;
            }
        }
    });
    rx
}

fn wait_for(rx: &mpsc::Receiver<Value>, limit: Duration, what: impl Fn(&Value) -> bool) -> Value {
    let end = Instant::now() + limit;
    loop {
        let left = end.saturating_duration_since(Instant::now());
        match rx.recv_timeout(left) {
            Ok(v) if what(&v) => return v,
            Ok(_) => {}
            Err(e) => panic!("not seen within {limit:?}: {e}"),
        }
    }
}

fn exit_within(child: &mut Child, limit: Duration) -> Option<i32> {
    let end = Instant::now() + limit;
    loop {
        if let Some(s) = child.try_wait().unwrap() {
            return s.code();
        }
        assert!(
            Instant::now() < end,
            "the bridge did not exit within {limit:?}"
        );
        thread::sleep(Duration::from_millis(20));
    }
}

/// The executions the simulated joints logged.
fn executions(log: &Path) -> Vec<Value> {
    std::fs::read_to_string(log)
        .unwrap_or_default()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

fn moves(log: &Path) -> usize {
    executions(log)
        .iter()
        .filter(|e| e["payload"].get("SetTargetV2").is_some())
        .count()
}

/// A client of the bridge at `sock` that waits at most 10 s for a line:
/// its writing and reading halves.
/// Clients on `sock` that each write as fast as the bridge takes it (client
/// `k`'s `i`th write is `line(k, i)`), reading what they are sent and
/// throwing it away (so they are never dropped), until stopped or the
/// bridge goes.
struct Flood {
    stop: Arc<AtomicBool>,
    clients: Vec<thread::JoinHandle<u64>>,
}

impl Flood {
    fn start(
        sock: &Path,
        clients: usize,
        line: impl Fn(usize, u64) -> String + Send + Sync + 'static,
    ) -> Self {
        let stop = Arc::new(AtomicBool::new(false));
        let line = Arc::new(line);
        let clients = (0..clients)
            .map(|k| {
                let sock = sock.to_path_buf();
                let stop = Arc::clone(&stop);
                let line = Arc::clone(&line);
                thread::spawn(move || {
                    let mut s = UnixStream::connect(&sock).unwrap();
                    let mut r = s.try_clone().unwrap();
                    thread::spawn(move || std::io::copy(&mut r, &mut std::io::sink()));
                    let mut sent = 0u64;
                    while !stop.load(Ordering::Relaxed)
                        && s.write_all(line(k, sent).as_bytes()).is_ok()
                    {
                        sent += 1;
                    }
                    sent
                })
            })
            .collect();
        Self { stop, clients }
    }

    /// Stops the clients; how many writes they made in all.
    fn stop(self) -> u64 {
        self.stop.store(true, Ordering::Relaxed);
        self.clients.into_iter().map(|c| c.join().unwrap()).sum()
    }
}

fn operator(sock: &Path) -> (UnixStream, BufReader<UnixStream>) {
    let op = UnixStream::connect(sock).unwrap();
    op.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
    (op.try_clone().unwrap(), BufReader::new(op))
}

/// `motorwire bridge` on the simulated arm listening on the local socket
/// `sock`, with `extra` arguments.
fn unix_bridge(sock: &Path, extra: &[&str]) -> Child {
    let input = format!("unix:{}", sock.display());
    let mut args = vec!["bridge", "--map", MAP, "--bus", "sim", "--input", &input];
    args.extend_from_slice(extra);
    common::spawn(&args)
}

#[test]
fn a_flooding_and_a_non_reading_client_do_not_delay_anothers_stop() {
    let dir = scratch("flood");
    let sock = dir.join("bridge.sock");
    let mut child = unix_bridge(&sock, &["--feedback-hz", "1000", "--client-queue", "2048"]);
    let _ = listening(&mut child);
    let events = stdout_lines(&mut child);
    let pid = child.id();
    let bridge = Bridge(child);
    // The sleeper (origin 1): one command, then never reads.
    let mut sleeper = UnixStream::connect(&sock).unwrap();
    writeln!(sleeper, "{}", command("shoulder_roll", 5.0)).unwrap();
    thread::sleep(Duration::from_millis(100));
    // The flooder (origin 2): writes as fast as it can, reading what it is
    // sent, so it is never dropped.
    let line = format!("{}\n", command("elbow", 20.0));
    let flooder = Flood::start(&sock, 1, move |_, _| line.clone());
    // The sleeper is disconnected once its queue is full, and said so.
    let dropped = wait_for(&events, Duration::from_secs(30), |v| {
        v["event"] == "client_dropped"
    });
    assert!(
        dropped["reason"]
            .as_str()
            .unwrap()
            .contains("stopped reading"),
        "{dropped}"
    );
    assert_eq!(dropped["origin"], 1, "{dropped}");
    // The operator, while the flood goes on: its stop is acted on at once.
    let (mut w, mut r) = operator(&sock);
    let mut stop_latencies = Vec::new();
    let mut round_trips = Vec::new();
    for _ in 0..200 {
        let sent = Instant::now();
        writeln!(w, r#"{{"emergency_stop": true}}"#).unwrap();
        let res = next_result(&mut r);
        round_trips.push(sent.elapsed());
        assert_eq!(res["ok"], true, "{res}");
        assert_eq!(res["emergency_stop"], true, "{res}");
        stop_latencies.push(res["stop_latency_us"].as_u64().unwrap_or(0));
        writeln!(w, r#"{{"emergency_stop": false}}"#).unwrap();
        let rel = next_result(&mut r);
        assert_eq!(rel["released"], true, "{rel}");
    }
    let flooded = flooder.stop();
    // The flooder reads what it is sent, and the operator too: neither was
    // dropped.
    let late: Vec<Value> = events
        .try_iter()
        .filter(|v| v["event"] == "client_dropped")
        .collect();
    assert!(late.is_empty(), "{late:?}");
    assert!(flooded > 1000, "the flooder sent only {flooded} lines");
    stop_latencies.sort_unstable();
    round_trips.sort_unstable();
    let worst_stop = *stop_latencies.last().unwrap();
    let worst_trip = *round_trips.last().unwrap();
    let p99 = |n: usize| (n - 1) * 99 / 100;
    eprintln!(
        "flooded {flooded} lines; stop line-to-last-frame median {} µs, p99 {} µs, worst {worst_stop} µs; round trip median {:?}, p99 {:?}, worst {worst_trip:?}",
        stop_latencies[stop_latencies.len() / 2],
        stop_latencies[p99(stop_latencies.len())],
        round_trips[round_trips.len() / 2],
        round_trips[p99(round_trips.len())]
    );
    // Generous bounds for a loaded 2-core CI machine; BENCHMARKS.md has the
    // measured figures.
    assert!(
        worst_stop < 50_000,
        "a stop took {worst_stop} µs to reach the bus"
    );
    assert!(worst_trip < Duration::from_secs(1), "{worst_trip:?}");
    // Nothing grew without bound.
    let rss = common::rss_kib(pid);
    assert!(rss < 200 * 1024, "the bridge holds {rss} KiB");
    drop(bridge);
}

#[test]
fn a_full_stdout_stops_the_joints_and_ends_with_74() {
    let dir = scratch("full");
    let log = dir.join("exec.jsonl");
    let mut child = Command::new(env!("CARGO_BIN_EXE_motorwire"))
        .args([
            "bridge",
            "--map",
            MAP,
            "--bus",
            "sim",
            "--feedback-hz",
            "1000",
            "--sim-log",
            log.to_str().unwrap(),
        ])
        .current_dir(common::root())
        .stdin(Stdio::piped())
        .stdout(Stdio::piped()) // never read
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stdin = child.stdin.take().unwrap();
    writeln!(stdin, "{}", command("elbow", 30.0)).unwrap();
    let code = exit_within(&mut child, Duration::from_secs(60));
    let mut err = String::new();
    child
        .stderr
        .take()
        .unwrap()
        .read_to_string(&mut err)
        .unwrap();
    assert_eq!(code, Some(74), "{err}");
    assert!(err.contains("standard output is not being read"), "{err}");
    let deactivated: Vec<String> = executions(&log)
        .iter()
        .filter(|e| e["payload"] == "Deactivate")
        .map(|e| e["joint"].as_str().unwrap().to_owned())
        .collect();
    for j in ["shoulder_pitch", "shoulder_roll", "elbow"] {
        assert!(deactivated.iter().any(|d| d == j), "{j}: {deactivated:?}");
    }
    drop(stdin);
}

#[test]
fn a_closed_stdout_stops_the_joints_and_ends_with_74() {
    let mut child = common::spawn(&["bridge", "--map", MAP, "--bus", "sim"]);
    drop(child.stdout.take()); // EPIPE on the first write
    let mut stdin = child.stdin.take().unwrap();
    writeln!(stdin, "{}", command("elbow", 30.0)).unwrap();
    let code = exit_within(&mut child, Duration::from_secs(30));
    let mut err = String::new();
    child
        .stderr
        .take()
        .unwrap()
        .read_to_string(&mut err)
        .unwrap();
    assert_eq!(code, Some(74), "{err}");
    assert!(err.contains("standard output failed"), "{err}");
    assert!(err.contains("the joints were stopped"), "{err}");
    drop(stdin);
}

/// A TCP bridge with a sim log; `extra` are more arguments.
fn tcp_bridge(dir: &Path, extra: &[&str]) -> (Bridge, u16, PathBuf) {
    let log = dir.join("exec.jsonl");
    let mut args = vec![
        "bridge",
        "--map",
        MAP,
        "--bus",
        "sim",
        "--input",
        "tcp:127.0.0.1:0",
        "--sim-log",
        log.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    let mut child = common::spawn(&args);
    let (said, _) = listening(&mut child);
    let port = tcp_port(&said);
    (Bridge(child), port, log)
}

/// Everything the bridge says on a connection until it closes it.
fn until_closed(s: TcpStream) -> Vec<Value> {
    s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
    BufReader::new(s)
        .lines()
        .map_while(Result::ok)
        .map(|l| serde_json::from_str(&l).unwrap())
        .collect()
}

#[test]
fn an_http_post_moves_nothing_even_without_a_token() {
    let dir = scratch("http");
    let (_bridge, port, log) = tcp_bridge(&dir, &["--insecure-no-auth"]);
    thread::sleep(Duration::from_millis(300)); // the joints are started
    let body = command("elbow", 120.0);
    let mut s = TcpStream::connect(("127.0.0.1", port)).unwrap();
    // The bridge may close before all of it is written.
    let _ = s.write_all(
        format!(
            "POST / HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nContent-Type: application/json\r\nContent-Length: {}\r\n\r\n{body}\n",
            body.len() + 1
        )
        .as_bytes(),
    );
    let said = until_closed(s);
    assert_eq!(said.len(), 1, "{said:?}");
    assert_eq!(said[0]["ok"], false);
    assert_eq!(said[0]["error"]["kind"], "http_refused");
    assert_eq!(said[0]["error"]["rule"], "http_refused");
    // Blank lines first, a lower-case method, tabs: HTTP all the same.
    for request in [
        "\r\n\r\nPOST / HTTP/1.1\r\n",
        "post / http/1.1\r\n",
        "POST\t/\tHTTP/1.1\r\n",
    ] {
        let mut s = TcpStream::connect(("127.0.0.1", port)).unwrap();
        // The bridge may close before all of it is written.
        let _ = s.write_all(format!("{request}Host: x\r\n\r\n{body}\n").as_bytes());
        let said = until_closed(s);
        assert_eq!(said[0]["error"]["kind"], "http_refused", "{request:?}");
    }
    thread::sleep(Duration::from_millis(300));
    assert_eq!(moves(&log), 0, "the elbow moved");
}

#[test]
fn a_wrong_or_missing_token_is_refused_and_the_right_one_is_served() {
    let dir = scratch("token");
    let token = token_file(&dir, "correct-horse-battery-staple");
    let record = dir.join("recording");
    let (_bridge, port, log) = tcp_bridge(
        &dir,
        &[
            "--token-file",
            token.to_str().unwrap(),
            "--record",
            record.to_str().unwrap(),
        ],
    );
    // A wrong token, then a move: one error line, closed, nothing moved.
    let mut s = TcpStream::connect(("127.0.0.1", port)).unwrap();
    writeln!(s, "correct-horse-battery-stapler").unwrap();
    let _ = writeln!(s, "{}", command("elbow", 100.0));
    let said = until_closed(s);
    assert_eq!(said.len(), 1, "{said:?}");
    assert_eq!(said[0]["error"]["kind"], "unauthorized");
    assert_eq!(said[0]["error"]["rule"], "unauthorized");
    // No token at all: the move is the first line, so it is the token.
    let mut s = TcpStream::connect(("127.0.0.1", port)).unwrap();
    writeln!(s, "{}", command("elbow", 100.0)).unwrap();
    let said = until_closed(s);
    assert_eq!(said[0]["error"]["kind"], "unauthorized");
    thread::sleep(Duration::from_millis(300));
    assert_eq!(moves(&log), 0, "the elbow moved");
    // The right token: served.
    let s = TcpStream::connect(("127.0.0.1", port)).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
    let mut w = s.try_clone().unwrap();
    writeln!(w, "correct-horse-battery-staple").unwrap();
    writeln!(w, "{}", command("elbow", 10.0)).unwrap();
    let mut r = BufReader::new(s);
    let first = next_result(&mut r);
    assert_eq!(first["ok"], true, "{first}");
    assert_eq!(first["line"], 1, "the token is not a line: {first}");
    assert_eq!(moves(&log), 1);
    // The token again (a client's mistake): refused, and neither the
    // recording nor anything else holds it.
    writeln!(w, " correct-horse-battery-staple").unwrap();
    let again = next_result(&mut r);
    assert_eq!(again["ok"], false, "{again}");
    assert_eq!(again["line"], 2, "{again}");
    assert!(
        again
            .to_string()
            .contains("the bridge's token in a line: it is never part of a command"),
        "{again}"
    );
    thread::sleep(Duration::from_millis(300));
    let lines = std::fs::read_to_string(record.join("lines.jsonl")).unwrap();
    assert!(lines.contains("the bridge's token in a line"), "{lines}");
    assert!(
        !lines.contains("battery-staple"),
        "the token recorded:\n{lines}"
    );
}

/// A line of standard input that holds `--token-file`'s token (alone, in
/// a command, behind a byte-order mark, or in a line that is not UTF-8)
/// is refused and withheld as on a connection: neither the output nor the
/// recording ever holds it, in text or in the hex of a line's first bytes.
#[test]
fn the_token_on_standard_input_is_refused_and_not_recorded() {
    let dir = scratch("stdin-token");
    let token = token_file(&dir, "correct-horse-battery-staple");
    let record = dir.join("recording");
    let out = common::run(
        &common::sim_bridge(&[
            "--token-file",
            token.to_str().unwrap(),
            "--record",
            record.to_str().unwrap(),
        ]),
        b"correct-horse-battery-staple\r\n\
          {\"motor_id\":\"elbow\",\"token\":\"correct-horse-battery-staple\"}\n\
          \xef\xbb\xbfcorrect-horse-battery-staple\n\
          \xff correct-horse-battery-staple\n\
          \xff not the token\n",
    );
    assert_eq!(out.status.code(), Some(0));
    let printed = String::from_utf8(out.stdout).unwrap();
    let result = |n: u64| {
        printed
            .lines()
            .map(|l| serde_json::from_str::<Value>(l).unwrap())
            .find(|v| v["line"] == n)
            .unwrap()
    };
    for n in 1..=3 {
        let r = result(n);
        assert_eq!(r["ok"], false, "{r}");
        assert!(
            r.to_string().contains("the bridge's token in a line"),
            "{r}"
        );
    }
    for n in 4..=5 {
        let r = result(n);
        assert!(r.to_string().contains("the line is not UTF-8"), "{r}");
    }
    let lines = std::fs::read_to_string(record.join("lines.jsonl")).unwrap();
    assert_eq!(
        lines.matches("the bridge's token in a line").count(),
        6,
        "three refusals, each as its input and its result:\n{lines}"
    );
    let hex: String = b"battery-staple"
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect();
    assert!(
        !lines.contains("battery-staple") && !lines.contains(&hex),
        "the token recorded:\n{lines}"
    );
    // The line without the token keeps its first bytes for the recording.
    let not_the_token: String = b" not the token"
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect();
    assert!(lines.contains(&not_the_token), "{lines}");
    assert!(!printed.contains("battery-staple"), "{printed}");
}

#[test]
fn tcp_needs_a_token_and_loopback_and_the_token_file_its_owner() {
    let dir = scratch("args");
    let run = |args: &[&str]| {
        let mut all = vec!["bridge", "--map", MAP, "--bus", "sim"];
        all.extend_from_slice(args);
        common::run(&all, b"")
    };
    let out = run(&["--input", "tcp:127.0.0.1:0"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("TCP needs --token-file FILE"),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let out = run(&["--input", "tcp:0.0.0.0:0", "--insecure-no-auth"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("is not a loopback address"));
    let out = run(&["--input", "tcp:127.0.0.1:0", "--token-file", "/dev/zero"]);
    assert_eq!(out.status.code(), Some(2));
    // A file others can read; two lines split by a carriage return (not
    // one token).
    for (name, text, mode, needle) in [
        (
            "open-token",
            "0123456789abcdef0123",
            0o644,
            "others than its owner can read it (mode 644)",
        ),
        (
            "split-token",
            "0123456789abcdef\rsecond-line-0123\n",
            0o600,
            "must be one line of at least 16 bytes, with no control characters",
        ),
    ] {
        let token = dir.join(name);
        std::fs::write(&token, text).unwrap();
        std::fs::set_permissions(&token, std::fs::Permissions::from_mode(mode)).unwrap();
        let out = run(&[
            "--input",
            "tcp:127.0.0.1:0",
            "--token-file",
            token.to_str().unwrap(),
        ]);
        assert_eq!(out.status.code(), Some(2), "{name}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(needle), "{name}: {err}");
    }
}

#[test]
fn the_local_socket_is_its_owners_alone_and_removed_at_the_end() {
    let dir = scratch("unix");
    let sock = dir.join("bridge.sock");
    let mut child = unix_bridge(&sock, &[]);
    let _ = listening(&mut child);
    let mode = std::fs::metadata(&sock).unwrap().permissions().mode() & 0o777;
    assert_eq!(mode, 0o600);
    // No leftover private directory beside it.
    let entries: Vec<_> = std::fs::read_dir(&dir).unwrap().flatten().collect();
    assert_eq!(entries.len(), 1, "{entries:?}");
    let s = UnixStream::connect(&sock).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
    let mut w = s.try_clone().unwrap();
    writeln!(w, "{}", command("elbow", 10.0)).unwrap();
    assert_eq!(next_result(&mut BufReader::new(s))["ok"], true);
    // A second bridge on the same path is refused while the first lives.
    let mut second = unix_bridge(&sock, &[]);
    drop(second.stdin.take());
    let out = second.wait_with_output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("another process is listening"));
    Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    exit_within(&mut child, Duration::from_secs(10));
    assert!(!sock.exists(), "the socket was left behind");
}

#[test]
fn connections_beyond_the_limit_are_refused_but_a_stop_is_taken() {
    let dir = scratch("limit");
    let (_bridge, port, _) = tcp_bridge(
        &dir,
        &[
            "--insecure-no-auth",
            "--max-clients",
            "2",
            "--auth-timeout-ms",
            "500",
        ],
    );
    thread::sleep(Duration::from_millis(300)); // the joints are started
    let connect = || {
        let s = TcpStream::connect(("127.0.0.1", port)).unwrap();
        s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
        s
    };
    // Two clients, each served its first command: the limit.
    let mut served = Vec::new();
    for setpoint in [10.0, 20.0] {
        let s = connect();
        let mut w = s.try_clone().unwrap();
        writeln!(w, "{}", command("elbow", setpoint)).unwrap();
        let mut r = BufReader::new(s);
        assert_eq!(next_result(&mut r)["ok"], true);
        served.push((w, r));
    }
    // A third's command: refused for room, nothing run.
    let mut s = connect();
    writeln!(s, "{}", command("elbow", 30.0)).unwrap();
    let said = until_closed(s);
    assert_eq!(said.len(), 1, "{said:?}");
    assert_eq!(said[0]["error"]["kind"], "too_many_clients");
    assert_eq!(
        said[0]["error"]["message"],
        "the bridge serves 2 clients at once (a stop is still taken)"
    );
    // A third's stop: taken and answered (the stop's event comes to every
    // client too), then the connection ends.
    let mut s = connect();
    writeln!(s, r#"{{"emergency_stop": true}}"#).unwrap();
    let said = until_closed(s);
    let results: Vec<&Value> = said.iter().filter(|v| v.get("ok").is_some()).collect();
    assert_eq!(results.len(), 1, "{said:?}");
    assert_eq!(results[0]["ok"], true, "{said:?}");
    assert_eq!(results[0]["emergency_stop"], true, "{said:?}");
    // A served client releases it.
    let (w, r) = &mut served[0];
    writeln!(w, r#"{{"emergency_stop": false}}"#).unwrap();
    assert_eq!(next_result(r)["released"], true);
    // One leaves: a new one is served.
    drop(served.remove(1));
    thread::sleep(Duration::from_millis(200));
    let s = connect();
    let mut w = s.try_clone().unwrap();
    writeln!(w, "{}", command("elbow", 10.0)).unwrap();
    assert_eq!(next_result(&mut BufReader::new(s))["ok"], true);
}

/// Connections that never authenticate are closed after the timeout and
/// never count against the limit: seventy idle ones (more than the 64 that
/// may authenticate at once: the oldest are closed for the newest), and the
/// token holder's stop is taken at once.
#[test]
fn idle_connections_are_closed_unauthenticated_and_never_keep_a_stop_out() {
    let dir = scratch("idle");
    let token = token_file(&dir, "correct-horse-battery-staple");
    let (_bridge, port, _) = tcp_bridge(
        &dir,
        &[
            "--token-file",
            token.to_str().unwrap(),
            "--max-clients",
            "2",
            "--auth-timeout-ms",
            "800",
        ],
    );
    let opened = Instant::now();
    let idle: Vec<TcpStream> = (0..70)
        .map(|_| TcpStream::connect(("127.0.0.1", port)).unwrap())
        .collect();
    // A client dripping its token a byte at a time is held to the same
    // deadline.
    let mut drip = TcpStream::connect(("127.0.0.1", port)).unwrap();
    thread::sleep(Duration::from_millis(100));
    let s = TcpStream::connect(("127.0.0.1", port)).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
    let mut w = s.try_clone().unwrap();
    writeln!(w, "correct-horse-battery-staple").unwrap();
    writeln!(w, r#"{{"emergency_stop": true}}"#).unwrap();
    let r = next_result(&mut BufReader::new(s));
    assert_eq!(r["ok"], true, "{r}");
    assert_eq!(r["emergency_stop"], true, "{r}");
    for b in b"correct-horse" {
        let _ = drip.write_all(&[*b]);
        thread::sleep(Duration::from_millis(100));
    }
    let mut closed_for_newer = 0;
    for s in idle.into_iter().chain([drip]) {
        let said = until_closed(s);
        assert_eq!(said.len(), 1, "{said:?}");
        if said[0]["error"]["kind"] == "too_many_clients" {
            closed_for_newer += 1;
            continue;
        }
        assert_eq!(said[0]["error"]["kind"], "unauthorized", "{said:?}");
        assert_eq!(
            said[0]["error"]["message"],
            "nothing authenticated within 800 ms; the connection is closed"
        );
    }
    // 72 connections, 64 at most authenticating: the 8 oldest were closed
    // as the newer came.
    assert_eq!(closed_for_newer, 8);
    let took = opened.elapsed();
    assert!(took < Duration::from_secs(3), "closed after {took:?}");
}

/// CPU time (user + system, in clock ticks) the process has used.
fn cpu_ticks(pid: u32) -> u64 {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).unwrap();
    let after = stat.rsplit_once(')').unwrap().1;
    let f: Vec<&str> = after.split_whitespace().collect();
    f[11].parse::<u64>().unwrap() + f[12].parse::<u64>().unwrap()
}

#[test]
fn out_of_descriptors_the_accept_loop_backs_off_instead_of_spinning() {
    let log = scratch("fds").join("exec.jsonl");
    // 40 descriptors: the bridge's own need fewer; the clients take the rest.
    let mut child = Command::new("sh")
        .arg("-c")
        .arg(format!(
            "ulimit -n 40 && exec '{}' bridge --map {MAP} --bus sim --input tcp:127.0.0.1:0 --insecure-no-auth --max-clients 1000 --feedback-hz 0 --sim-log '{}'",
            env!("CARGO_BIN_EXE_motorwire"),
            log.display()
        ))
        .current_dir(common::root())
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let (said, mut stderr) = listening(&mut child);
    let port = tcp_port(&said);
    let pid = child.id();
    let bridge = Bridge(child);
    let mut held = Vec::new();
    for _ in 0..60 {
        if let Ok(s) = TcpStream::connect(("127.0.0.1", port)) {
            held.push(s);
        }
    }
    let mut line = String::new();
    stderr.read_line(&mut line).unwrap();
    assert!(line.contains("accepting a connection failed"), "{line}");
    // A second of being out of descriptors costs little CPU.
    let before = cpu_ticks(pid);
    thread::sleep(Duration::from_secs(1));
    let used = cpu_ticks(pid) - before;
    assert!(
        used < 30,
        "{used} ticks in one second: the accept loop spins"
    );
    // Descriptors back: it serves again.
    held.clear();
    thread::sleep(Duration::from_millis(1500));
    let s = match TcpStream::connect(("127.0.0.1", port)) {
        Ok(s) => s,
        Err(e) => {
            let mut bridge = bridge;
            let status = bridge.0.try_wait();
            let _ = bridge.0.kill();
            let mut rest = String::new();
            let _ = stderr.read_to_string(&mut rest);
            panic!(
                "connecting once descriptors are back: {e}; the bridge: {status:?}; its stderr:\n{rest}"
            );
        }
    };
    s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
    let mut w = s.try_clone().unwrap();
    writeln!(w, "{}", command("elbow", 10.0)).unwrap();
    assert_eq!(next_result(&mut BufReader::new(s))["ok"], true);
    drop(bridge);
    // The run of failures was reported when it began (the first line, read
    // above), not once per connection taken between failures (there were
    // about 50 such lines before): at most one more run, while the queued
    // connections, closed by now, are taken all at once.
    let mut rest = String::new();
    stderr.read_to_string(&mut rest).unwrap();
    let reports = rest.lines().filter(|l| l.contains("failed")).count();
    assert!(reports <= 1, "{rest}");
}

/// Results reach a TCP client as soon as they are decided, with feedback
/// flowing: no Nagle delay (a 40 ms stall behind a small write would show
/// in the median). `--nocapture` prints the figures BENCHMARKS.md records.
#[test]
fn tcp_results_come_back_without_delay_with_feedback_on() {
    let dir = scratch("nodelay");
    let token = token_file(&dir, "a-token-for-the-latency-test");
    let (_bridge, port, _) = tcp_bridge(
        &dir,
        &[
            "--token-file",
            token.to_str().unwrap(),
            "--feedback-hz",
            "100",
        ],
    );
    let s = TcpStream::connect(("127.0.0.1", port)).unwrap();
    s.set_nodelay(true).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
    let mut w = s.try_clone().unwrap();
    let mut r = BufReader::new(s);
    writeln!(w, "a-token-for-the-latency-test").unwrap();
    let mut stops = Vec::new();
    let mut moves = Vec::new();
    for i in 0..200 {
        let t = Instant::now();
        writeln!(w, "{}", command("elbow", f64::from(i % 50))).unwrap();
        let res = next_result(&mut r);
        assert_eq!(res["ok"], true, "move {i}: {res}");
        moves.push(t.elapsed());
        let t = Instant::now();
        writeln!(w, r#"{{"emergency_stop": true}}"#).unwrap();
        assert_eq!(next_result(&mut r)["emergency_stop"], true);
        stops.push(t.elapsed());
        writeln!(w, r#"{{"emergency_stop": false}}"#).unwrap();
        assert_eq!(next_result(&mut r)["released"], true);
    }
    stops.sort_unstable();
    moves.sort_unstable();
    let p = |v: &[Duration], q: f64| v[((v.len() - 1) as f64 * q) as usize];
    eprintln!(
        "tcp round trip, feedback 100 Hz: stop median {:?} p99 {:?}; move (to its Ack) median {:?} p99 {:?}",
        p(&stops, 0.5),
        p(&stops, 0.99),
        p(&moves, 0.5),
        p(&moves, 0.99)
    );
    assert!(
        p(&stops, 0.5) < Duration::from_millis(5),
        "{:?}",
        p(&stops, 0.5)
    );
    assert!(
        p(&moves, 0.5) < Duration::from_millis(10),
        "{:?}",
        p(&moves, 0.5)
    );
}

/// A client that connects once the bridge is ready is greeted with
/// `ready` and every motor's state, as its first line (it was printed on
/// standard output only), and can ask for the state again.
#[test]
fn a_client_connecting_after_ready_is_greeted_with_the_state() {
    let dir = scratch("greet");
    let sock = dir.join("bridge.sock");
    let mut child = unix_bridge(&sock, &["--feedback-hz", "0"]);
    let _ = listening(&mut child);
    let events = stdout_lines(&mut child);
    let _bridge = Bridge(child);
    let ready = wait_for(&events, Duration::from_secs(10), |v| v["event"] == "ready");
    assert_eq!(ready["motors"].as_array().unwrap().len(), 4, "{ready}");
    let s = UnixStream::connect(&sock).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
    let mut w = s.try_clone().unwrap();
    let mut r = BufReader::new(s);
    let mut first = String::new();
    r.read_line(&mut first).unwrap();
    let greeting: Value = serde_json::from_str(&first).unwrap();
    assert_eq!(greeting["event"], "ready", "{greeting}");
    assert_eq!(greeting["latched"], false);
    let elbow = greeting["motors"]
        .as_array()
        .unwrap()
        .iter()
        .find(|m| m["motor_id"] == "elbow")
        .unwrap()
        .clone();
    assert_eq!(elbow["online"], true, "{elbow}");
    assert_eq!(elbow["position"], 0.0, "{elbow}");
    writeln!(w, r#"{{"query":"state","motor_id":"elbow"}}"#).unwrap();
    let answer = next_result(&mut r);
    assert_eq!(answer["ok"], true, "{answer}");
    assert_eq!(answer["line"], 1);
    assert_eq!(answer["state"]["motors"][0]["motor_id"], "elbow");
}

/// The first line of a client's connection is its greeting, whatever else
/// flows: at 1,000 feedback lines a second, clients connecting one after
/// another each see `ready` first (feedback reached some before it); those
/// connecting during the startup see exactly one `ready` (some saw the
/// broadcast and their greeting); a listener that closes its sending side
/// at once is still greeted before the connection ends (it was let go
/// first, owing nothing).
#[test]
fn a_clients_greeting_is_its_first_line_and_comes_exactly_once() {
    let dir = scratch("greet-first");
    let sock = dir.join("bridge.sock");
    let mut child = unix_bridge(&sock, &["--feedback-hz", "1000", "--max-clients", "64"]);
    let _ = listening(&mut child);
    let events = stdout_lines(&mut child);
    let _bridge = Bridge(child);
    let first_lines = |s: UnixStream, n: usize| -> Vec<Value> {
        s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
        BufReader::new(s)
            .lines()
            .take(n)
            .map(|l| serde_json::from_str(&l.unwrap()).unwrap())
            .collect()
    };
    // During the startup (the socket listens before the joints are read).
    let early: Vec<UnixStream> = (0..20)
        .map(|_| UnixStream::connect(&sock).unwrap())
        .collect();
    wait_for(&events, Duration::from_secs(10), |v| v["event"] == "ready");
    for s in early {
        let lines = first_lines(s, 200);
        assert_eq!(lines[0]["event"], "ready", "{:?}", &lines[..3]);
        let readies = lines.iter().filter(|v| v["event"] == "ready").count();
        assert_eq!(readies, 1, "one ready: {:?}", &lines[..3]);
    }
    // After it, one after another, with feedback flowing.
    for _ in 0..40 {
        let lines = first_lines(UnixStream::connect(&sock).unwrap(), 1);
        assert_eq!(lines[0]["event"], "ready", "{}", lines[0]);
    }
    // A listener that closes its sending side at once.
    for _ in 0..10 {
        let s = UnixStream::connect(&sock).unwrap();
        s.shutdown(std::net::Shutdown::Write).unwrap();
        let lines = first_lines(s, 1);
        assert_eq!(lines.len(), 1, "greeted before the end");
        assert_eq!(lines[0]["event"], "ready", "{}", lines[0]);
    }
}

/// Clients flooding the bridge with queries do not make a stop fail: the
/// joints' acknowledgements are read ahead of the lines (they waited
/// behind thousands of queued queries, past their timeouts, and the stop
/// came back `outcome_unknown` with the joints flapping offline).
#[test]
fn a_flood_of_queries_does_not_keep_the_joints_answers_from_a_stop() {
    let dir = scratch("query-flood");
    let sock = dir.join("bridge.sock");
    let mut child = unix_bridge(&sock, &[]);
    let _ = listening(&mut child);
    let events = stdout_lines(&mut child);
    let _bridge = Bridge(child);
    wait_for(&events, Duration::from_secs(10), |v| v["event"] == "ready");
    let batch = "{\"query\":\"state\"}\n".repeat(2000);
    let flood = Flood::start(&sock, 7, move |_, _| batch.clone());
    thread::sleep(Duration::from_millis(1500));
    let (mut w, mut r) = operator(&sock);
    for _ in 0..3 {
        writeln!(w, r#"{{"emergency_stop":true}}"#).unwrap();
        let stop = next_result(&mut r);
        assert_eq!(stop["ok"], true, "{stop}");
        assert_eq!(stop["acked"].as_array().unwrap().len(), 4, "{stop}");
        // Its Acks are read as they come, not after the queued queries:
        // within the Ack timeout (100 ms), past which a request is sent
        // again and then given up (they took 250 ms and more).
        assert!(stop["ack_us"].as_u64().unwrap() < 100_000, "{stop}");
        writeln!(w, r#"{{"emergency_stop":false}}"#).unwrap();
        let release = next_result(&mut r);
        assert_eq!(release["ok"], true, "{release}");
    }
    flood.stop();
}

/// Clients flooding the bridge with heavy lines (stream setpoints with
/// 20 KB of metadata) do not keep the Orion controller's answers from
/// the bridge: they are read ahead of the clients' lines, as the bus's
/// frames are. Its motors stay online, and a stop stops every motor (the
/// controller's answers waited behind the flood: its motors went offline
/// and the stop came back outcome_unknown).
#[test]
fn a_flood_of_lines_does_not_keep_the_orion_controllers_answers_from_a_stop() {
    let dir = scratch("orion-flood");
    let sock = dir.join("bridge.sock");
    let mut child = unix_bridge(&sock, &["--orion", "sim", "--feedback-hz", "0"]);
    let _ = listening(&mut child);
    let events = stdout_lines(&mut child);
    let _bridge = Bridge(child);
    wait_for(&events, Duration::from_secs(10), |v| v["event"] == "ready");
    let t = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .as_millis();
    let pad = "x".repeat(20_000);
    let flood = Flood::start(&sock, 2, move |k, i| {
        format!(
            "{{\"motor_id\":\"elbow\",\"timestamp\":{t},\"control_mode\":\"position\",\"setpoint\":{},\"stream\":true,\"metadata\":{{\"pad\":\"{pad}\"}}}}\n",
            40 + (i + 1 + k as u64) % 20
        )
    });
    thread::sleep(Duration::from_millis(2000));
    let (mut w, mut r) = operator(&sock);
    for _ in 0..2 {
        writeln!(w, r#"{{"emergency_stop":true}}"#).unwrap();
        let stop = next_result(&mut r);
        assert_eq!(stop["ok"], true, "{stop}");
        // Every motor: the four on the bus and the controller's seven.
        assert_eq!(stop["acked"].as_array().unwrap().len(), 11, "{stop}");
        writeln!(w, r#"{{"emergency_stop":false}}"#).unwrap();
        let release = next_result(&mut r);
        assert_eq!(release["ok"], true, "{release}");
    }
    flood.stop();
    let offline: Vec<Value> = events
        .try_iter()
        .filter(|v| v["event"] == "offline")
        .collect();
    assert!(offline.is_empty(), "{offline:?}");
}

/// Each client's own feedback rate: on a bridge at 50 Hz, a client that
/// asks `{"feedback_hz":10}` gets each motor's every fifth feedback line
/// (told so: `"feedback_hz":10.0`), one that asks 0 gets none, one that
/// asks nothing gets all, at the same time; 20 Hz is answered with the
/// rate it gets (16.67: the bridge's divided by 3), and a rate above the
/// bridge's is refused with the bridge's rate as its limit.
#[test]
fn each_client_gets_feedback_at_its_own_rate() {
    let dir = scratch("feedback-rate");
    let sock = dir.join("bridge.sock");
    let mut child = unix_bridge(&sock, &["--feedback-hz", "50"]);
    let _ = listening(&mut child);
    let events = stdout_lines(&mut child);
    let _bridge = Bridge(child);
    wait_for(&events, Duration::from_secs(10), |v| v["event"] == "ready");
    let ask = |line: &str| {
        let (mut w, mut r) = operator(&sock);
        if !line.is_empty() {
            writeln!(w, "{line}").unwrap();
            let answer = next_result(&mut r);
            return (w, r, Some(answer));
        }
        (w, r, None)
    };
    let (_w10, mut r10, a10) = ask(r#"{"feedback_hz":10}"#);
    let a10 = a10.unwrap();
    assert_eq!(a10["ok"], true, "{a10}");
    assert_eq!(a10["feedback_hz"], 10.0, "{a10}");
    let (_w0, mut r0, a0) = ask(r#"{"feedback_hz":0}"#);
    assert_eq!(a0.unwrap()["feedback_hz"], 0.0);
    let (_wall, mut rall, _) = ask("");
    let (_w20, _r20, a20) = ask(r#"{"feedback_hz":20}"#);
    // Not above what was asked: the bridge's 50 Hz over 3.
    assert_eq!(a20.unwrap()["feedback_hz"], 50.0 / 3.0);
    let (_wx, _rx, too_fast) = ask(r#"{"feedback_hz":51}"#);
    let too_fast = too_fast.unwrap();
    assert_eq!(too_fast["ok"], false, "{too_fast}");
    assert_eq!(too_fast["error"]["kind"], "invalid", "{too_fast}");
    assert_eq!(too_fast["error"]["field"], "feedback_hz", "{too_fast}");
    assert_eq!(too_fast["error"]["value"], 51.0, "{too_fast}");
    assert_eq!(too_fast["error"]["limit"], 50.0, "{too_fast}");
    let (_wb, _rb, bad) = ask(r#"{"feedback_hz":"fast"}"#);
    assert_eq!(bad.unwrap()["error"]["kind"], "invalid");
    // The elbow's feedback lines each client reads in the same two seconds.
    let elbow_lines = |r: &mut BufReader<UnixStream>, until: Instant| {
        r.get_ref()
            .set_read_timeout(Some(Duration::from_millis(100)))
            .unwrap();
        let mut n = 0u32;
        let mut line = String::new();
        while Instant::now() < until {
            line.clear();
            if r.read_line(&mut line).is_ok_and(|k| k > 0)
                && let Ok(v) = serde_json::from_str::<Value>(&line)
                && v["motor_id"] == "elbow"
                && v.get("feedback").is_some()
            {
                n += 1;
            }
        }
        n
    };
    let until = Instant::now() + Duration::from_secs(2);
    let (all, ten) = thread::scope(|s| {
        let all = s.spawn(|| elbow_lines(&mut rall, until));
        let ten = s.spawn(|| elbow_lines(&mut r10, until));
        (all.join().unwrap(), ten.join().unwrap())
    });
    let none = elbow_lines(&mut r0, Instant::now() + Duration::from_millis(300));
    assert_eq!(none, 0, "a client at 0 Hz gets no feedback");
    assert!(
        (80..=110).contains(&all),
        "at 50 Hz for 2 s: {all} elbow lines"
    );
    // Every fifth of the same lines (the counts started at different lines).
    assert!(
        (all / 5).abs_diff(ten) <= 2,
        "at 10 Hz: {ten} elbow lines where the full rate had {all}"
    );
}

/// What a stop cancels does not depend on a client's clock (issue 58
/// part 2): a policy client whose clock runs 120 s ahead (inside the
/// allowed 5 min) streams setpoints faster than the bridge takes them, so
/// thousands of its lines wait in its socket; another client stops and
/// releases. No line the policy had written before the stop runs after
/// the release (each is refused: `emergency_stop_latched` while latched,
/// `stale_before_stop` after), and its lines written after the release
/// are taken.
#[test]
fn a_clients_clock_ahead_does_not_decide_what_a_stop_cancels() {
    use std::sync::atomic::AtomicU64;
    let dir = scratch("skew");
    let sock = dir.join("bridge.sock");
    let mut child = unix_bridge(&sock, &["--feedback-hz", "0"]);
    let _ = listening(&mut child);
    let _events = stdout_lines(&mut child);
    let bridge = Bridge(child);
    let policy = UnixStream::connect(&sock).unwrap();
    let written = Arc::new(AtomicU64::new(0));
    let done = Arc::new(AtomicBool::new(false));
    // When each line's write returned.
    let times = Arc::new(std::sync::Mutex::new(Vec::with_capacity(40_000)));
    let writer = {
        let mut w = policy.try_clone().unwrap();
        let (written, done) = (Arc::clone(&written), Arc::clone(&done));
        let times = Arc::clone(&times);
        thread::spawn(move || {
            let mut n = 0u64;
            while !done.load(Ordering::SeqCst) && n < 40_000 {
                let setpoint = if n.is_multiple_of(2) { 10.0 } else { 20.0 };
                let line = format!(
                    r#"{{"motor_id":"elbow","timestamp":{},"control_mode":"position","setpoint":{setpoint}}}"#,
                    now_ms() + 120_000
                );
                if writeln!(w, "{line}").is_err() {
                    break;
                }
                times.lock().unwrap().push(Instant::now());
                n += 1;
                written.store(n, Ordering::SeqCst);
            }
            let _ = w.shutdown(std::net::Shutdown::Write);
        })
    };
    let reader = thread::spawn(move || {
        let mut r = BufReader::new(policy);
        let mut results = Vec::new();
        let mut line = String::new();
        while r.read_line(&mut line).unwrap_or(0) > 0 {
            let v: Value = serde_json::from_str(&line).unwrap();
            if v.get("ok").is_some() {
                results.push(v);
            }
            line.clear();
        }
        results
    });
    // The policy's socket fills: its lines wait for the bridge.
    while written.load(Ordering::SeqCst) < 3_000 {
        thread::sleep(Duration::from_millis(10));
    }
    let (mut w, mut r) = operator(&sock);
    let before_stop = written.load(Ordering::SeqCst);
    let stop_sent = Instant::now();
    writeln!(w, r#"{{"emergency_stop": true}}"#).unwrap();
    assert_eq!(next_result(&mut r)["emergency_stop"], true);
    writeln!(w, r#"{{"emergency_stop": false}}"#).unwrap();
    assert_eq!(next_result(&mut r)["released"], true);
    // Lines written after the release, then the policy ends.
    let after_release = written.load(Ordering::SeqCst);
    while written.load(Ordering::SeqCst) < after_release + 200 {
        thread::sleep(Duration::from_millis(5));
    }
    done.store(true, Ordering::SeqCst);
    writer.join().unwrap();
    let total = written.load(Ordering::SeqCst);
    let results = reader.join().unwrap();
    assert_eq!(results.len() as u64, total, "one result a line");
    // From the first line the stop refused on, no line written before the
    // stop is taken: none written 5 ms or more before it (timestamps are
    // whole milliseconds, and the stop is timed when the bridge reads it,
    // so a line written in its last millisecond may pass as written after
    // it, whatever the clocks).
    let times = times.lock().unwrap().clone();
    let first = results
        .iter()
        .position(|v| v["ok"] == false && v["error"]["kind"] == "emergency_stop_latched")
        .expect("a line refused while latched");
    let mut stale = 0;
    for v in &results[first..] {
        let n = v["line"].as_u64().unwrap();
        let at = times[usize::try_from(n).unwrap() - 1];
        if n <= before_stop && at + Duration::from_millis(5) <= stop_sent {
            assert_eq!(
                v["ok"], false,
                "written before the stop, taken after it: {v}"
            );
            let kind = v["error"]["kind"].as_str().unwrap();
            assert!(
                [
                    "emergency_stop_latched",
                    "stale_before_stop",
                    "cancelled",
                    "superseded"
                ]
                .contains(&kind),
                "{v}"
            );
            stale += usize::from(kind == "stale_before_stop");
        }
    }
    // The window was there: lines written before the stop came after the
    // release (with the client's clock ahead, each stamped after the stop).
    assert!(
        stale > 0,
        "no line written before the stop came after the release"
    );
    // Lines written after the release were taken.
    assert!(
        results
            .iter()
            .any(|v| v["ok"] == true && v["line"].as_u64().unwrap() > after_release),
        "nothing written after the release was taken"
    );
    eprintln!(
        "{total} lines; {before_stop} written before the stop; {stale} of them refused stale_before_stop after the release"
    );
    drop(bridge);
}

/// One bad line never holds a stop (issue 58 part 3): a client sends
/// 1 MiB trajectory lines whose waypoints are all `{}` (about 700,000
/// violations each; before, each refusal listed them all, 68 MB a line,
/// and another client's stop waited 4.2 to 5.6 s behind it while healthy
/// joints were reported offline). Now each refusal lists the first 100
/// violations and counts the rest, the line is read on its own client's
/// thread, and the other client's stops are taken at once meanwhile.
#[test]
fn huge_invalid_lines_never_hold_another_clients_stop() {
    let dir = scratch("huge");
    let sock = dir.join("bridge.sock");
    let mut child = unix_bridge(&sock, &["--feedback-hz", "0"]);
    let _ = listening(&mut child);
    let events = stdout_lines(&mut child);
    let pid = child.id();
    let bridge = Bridge(child);
    // Ready: the joints answered, so an offline event is a real one.
    let (mut w, mut r) = operator(&sock);
    let greeting = next_result_or_event(&mut r);
    assert_eq!(greeting["event"], "ready", "{greeting}");
    // In a debug build a 1 MiB line takes seconds of a core to read (and
    // the other tests run beside this one): one line of 256 KiB; in
    // release (CI's release step, alone) eight of 1 MiB.
    let (lines, bytes): (usize, usize) = if cfg!(debug_assertions) {
        (1, 1 << 18)
    } else {
        (8, 1 << 20)
    };
    let waypoints = bytes / 3 - 40;
    let huge = format!(
        r#"{{"trajectory_id":"t","motor_id":"elbow","waypoints":[{}],"timing":{{}}}}"#,
        vec!["{}"; waypoints].join(",")
    );
    assert!(huge.len() <= bytes);
    let hostile = UnixStream::connect(&sock).unwrap();
    // It writes from one thread and reads what it is sent on another (a
    // client that stops reading is cut off, rightly).
    let writer = {
        let mut hw = hostile.try_clone().unwrap();
        thread::spawn(move || {
            for _ in 0..lines {
                writeln!(hw, "{huge}").unwrap();
            }
        })
    };
    let answers = thread::spawn(move || {
        let mut results = Vec::new();
        let mut hr = BufReader::new(hostile);
        let mut line = String::new();
        while results.len() < lines && hr.read_line(&mut line).unwrap() > 0 {
            if line.starts_with("{\"ok\"") {
                results.push(line.clone());
            }
            line.clear();
        }
        results
    });
    let mut stop_latencies = Vec::new();
    while !answers.is_finished() || stop_latencies.len() < 50 {
        writeln!(w, r#"{{"emergency_stop": true}}"#).unwrap();
        let res = next_result(&mut r);
        assert_eq!(res["emergency_stop"], true, "{res}");
        stop_latencies.push(res["stop_latency_us"].as_u64().unwrap());
        writeln!(w, r#"{{"emergency_stop": false}}"#).unwrap();
        assert_eq!(next_result(&mut r)["released"], true);
        // An operator's pace, not a flood of its own.
        thread::sleep(Duration::from_millis(2));
    }
    writer.join().unwrap();
    let answers = answers.join().unwrap();
    assert_eq!(answers.len(), lines);
    for a in &answers {
        assert!(a.len() < 64 * 1024, "a refusal of {} bytes", a.len());
        let v: Value = serde_json::from_str(a).unwrap();
        assert_eq!(v["error"]["kind"], "invalid", "{v}");
        assert_eq!(v["error"]["violations"].as_array().unwrap().len(), 100);
        let more = v["error"]["more_violations"].as_u64().unwrap();
        assert_eq!(more as usize + 100, 2 * waypoints, "{}", &a[..300]);
    }
    // No healthy joint was reported offline meanwhile.
    let offline: Vec<Value> = events
        .try_iter()
        .filter(|v| v["event"] == "offline")
        .collect();
    assert!(offline.is_empty(), "{offline:?}");
    stop_latencies.sort_unstable();
    let p99 = stop_latencies[(stop_latencies.len() - 1) * 99 / 100];
    let rss = common::rss_kib(pid);
    eprintln!(
        "{} stops while {lines} lines of {} KiB came: median {} µs, p99 {p99} µs, worst {} µs; bridge {rss} KiB",
        stop_latencies.len(),
        bytes / 1024,
        stop_latencies[stop_latencies.len() / 2],
        stop_latencies.last().unwrap()
    );
    // Under 1 ms at the p99 in release (CI's release step); a debug build
    // on a loaded 2-core machine is held to 20 ms (it was seconds).
    let bound = if cfg!(debug_assertions) {
        20_000
    } else {
        1_000
    };
    assert!(p99 < bound, "p99 {p99} µs");
    // Each line is parsed whole to be judged (a JSON tree of 350,000
    // members, its schema errors counted): the reader's peak, kept by the
    // allocator. Measured 783 MB in release with eight lines (it was 1.3
    // to 2.1 GiB with every violation listed).
    let most = if cfg!(debug_assertions) { 300 } else { 1024 };
    assert!(rss < most * 1024, "the bridge holds {rss} KiB");
    drop(bridge);
}

/// The next line a client reads (a result or an event).
fn next_result_or_event(r: &mut impl BufRead) -> Value {
    let mut line = String::new();
    assert!(r.read_line(&mut line).unwrap() > 0, "the bridge closed");
    serde_json::from_str(&line).unwrap()
}

/// Lines in all of a slow controller's session, in bursts of
/// [`BURST`], then its stop.
const SESSION: u64 = 35_000;
const BURST: u64 = 5_000;
/// The slow controller reads this many lines, then sleeps 1 ms: slower
/// than the bridge answers a burst (a debug build answers about 4,000
/// lines a second; each setpoint has its result and its completion).
const READ_BETWEEN_NAPS: u64 = 2;

/// What a slow controller saw: how many lines it could write, how many
/// results each got (1-based), its stop's result, and how long the
/// session took.
struct SlowSession {
    written: u64,
    results: Vec<u32>,
    stop: Option<Value>,
    took: Duration,
}

/// A controller that writes [`SESSION`] elbow setpoints (timestamp now)
/// in bursts of [`BURST`] from one thread, then a stop, then ends its
/// input (`end`), while another thread reads every line it is sent, but
/// slowly (a nap of 1 ms every [`READ_BETWEEN_NAPS`] lines), to the end.
fn slow_controller<W: Write + Send + 'static>(
    input: W,
    end: impl FnOnce(W) + Send + 'static,
    output: impl Read + Send + 'static,
) -> SlowSession {
    let start = Instant::now();
    let writer = thread::spawn(move || {
        let mut w = std::io::BufWriter::with_capacity(1 << 16, input);
        let mut n = 0u64;
        while n < SESSION {
            for _ in 0..BURST.min(SESSION - n) {
                let setpoint = 10.0 + (n % 20) as f64;
                if writeln!(w, "{}", command("elbow", setpoint)).is_err() {
                    return n; // the bridge went away
                }
                n += 1;
            }
            if w.flush().is_err() {
                return n;
            }
            thread::sleep(Duration::from_millis(100));
        }
        let _ = writeln!(w, r#"{{"emergency_stop": true}}"#);
        let _ = w.flush();
        if let Ok(inner) = w.into_inner() {
            end(inner);
        }
        n
    });
    let reader = thread::spawn(move || {
        let mut results = vec![0u32; SESSION as usize + 1];
        let mut stop = None;
        let mut read = 0u64;
        for line in BufReader::new(output).lines() {
            let Ok(line) = line else { break };
            read += 1;
            if read.is_multiple_of(READ_BETWEEN_NAPS) {
                thread::sleep(Duration::from_millis(1));
            }
            // A line cut short: the bridge closed the connection.
            let Ok(v) = serde_json::from_str::<Value>(&line) else {
                break;
            };
            if v.get("ok").is_none() || v.get("event").is_some() {
                continue;
            }
            let n = v["line"].as_u64().unwrap();
            if n == SESSION + 1 {
                stop = Some(v.clone());
            }
            if let Some(c) = results.get_mut(n as usize - 1) {
                *c += 1;
            }
        }
        (results, stop)
    });
    let written = writer.join().unwrap();
    let (results, stop) = reader.join().unwrap();
    SlowSession {
        written,
        results,
        stop,
        took: start.elapsed(),
    }
}

/// Lines that did not get exactly one result: (line, results), the first
/// ten.
fn not_one_result(results: &[u32]) -> Vec<(usize, u32)> {
    results
        .iter()
        .enumerate()
        .filter(|&(_, &c)| c != 1)
        .map(|(i, &c)| (i + 1, c))
        .take(10)
        .collect()
}

/// A controller on standard input that reads every result, but more
/// slowly than the bridge answers its bursts of 5,000 lines, is slowed
/// down, not cut off (issue 58 part 9: it was taken for one that stopped
/// reading, `standard output is not being read (4096 lines waiting)`, the
/// joints stopped and exit 74): each of its 35,000 lines and its stop
/// gets exactly one result, and the bridge ends with 0.
#[test]
fn a_slow_reader_on_standard_input_is_slowed_not_cut_off() {
    let mut child = common::spawn(&[
        "bridge",
        "--map",
        MAP,
        "--bus",
        "sim",
        "--feedback-hz",
        "10",
    ]);
    let stdin = child.stdin.take().unwrap();
    let stdout = child.stdout.take().unwrap();
    let mut stderr = child.stderr.take().unwrap();
    let bridge = Bridge(child);
    let session = slow_controller(stdin, drop, stdout);
    let mut bridge = bridge;
    let code = exit_within(&mut bridge.0, Duration::from_secs(30));
    let mut err = String::new();
    stderr.read_to_string(&mut err).unwrap();
    assert!(!err.contains("not being read"), "{err}");
    assert_eq!(code, Some(0), "{err}");
    assert_eq!(session.written, SESSION, "the bridge stopped taking lines");
    let wrong = not_one_result(&session.results);
    assert!(
        wrong.is_empty(),
        "lines without exactly one result: {wrong:?}\n{err}"
    );
    let stop = session.stop.expect("the stop was answered");
    assert_eq!(stop["ok"], true, "{stop}");
    assert_eq!(stop["emergency_stop"], true, "{stop}");
    eprintln!(
        "{} lines and a stop, read slowly, in {:?}",
        SESSION, session.took
    );
}

/// An operator's stops on `sock`, each released, every 20 ms, until
/// `done`: each stop's `stop_latency_us` (its line to its last frame on the
/// bus) and its round trip, sorted.
fn operator_stops(sock: &Path, done: impl Fn(usize) -> bool) -> (Vec<u64>, Vec<Duration>) {
    let (mut w, mut r) = operator(sock);
    let mut stop_latencies = Vec::new();
    let mut round_trips = Vec::new();
    while !done(stop_latencies.len()) {
        let sent = Instant::now();
        writeln!(w, r#"{{"emergency_stop": true}}"#).unwrap();
        let res = next_result(&mut r);
        round_trips.push(sent.elapsed());
        assert_eq!(res["emergency_stop"], true, "{res}");
        stop_latencies.push(res["stop_latency_us"].as_u64().unwrap());
        writeln!(w, r#"{{"emergency_stop": false}}"#).unwrap();
        let rel = next_result(&mut r);
        // Another client's stop, read after this release and acted on
        // first, keeps the stop latched.
        assert!(
            rel["released"] == true || rel["error"]["kind"] == "cancelled",
            "{rel}"
        );
        thread::sleep(Duration::from_millis(20));
    }
    stop_latencies.sort_unstable();
    round_trips.sort_unstable();
    (stop_latencies, round_trips)
}

/// The p99 of sorted `v` (the value below which 99 % of them lie).
fn p99<T: Copy>(v: &[T]) -> T {
    v[(v.len() - 1) * 99 / 100]
}

/// The same slow controller on a local socket, while an operator on a
/// second connection stops and releases in a loop: the controller is
/// slowed, never dropped, and each of its lines gets exactly one result;
/// the operator's stops are not held up by it. Its stops are measured
/// alone first, on the same machine at the same time, then during the
/// session (`stop_latency_us`: each stop's line to its last frame on the
/// bus; and its round trip; `--nocapture` prints them). In a release build
/// the p99 during the session is held under 1 ms, or, on a machine loaded
/// so that the stops alone miss it, to twice the p99 of those alone.
#[test]
fn a_slow_reader_on_a_socket_is_slowed_not_dropped_and_anothers_stops_stay_fast() {
    let dir = scratch("slow-reader");
    let sock = dir.join("bridge.sock");
    let mut child = unix_bridge(&sock, &["--feedback-hz", "10"]);
    let _ = listening(&mut child);
    let events = stdout_lines(&mut child);
    let bridge = Bridge(child);
    wait_for(&events, Duration::from_secs(10), |v| v["event"] == "ready");
    let (alone, _) = operator_stops(&sock, |n| n >= 200);
    let controller = UnixStream::connect(&sock).unwrap();
    let input = controller.try_clone().unwrap();
    let done = Arc::new(AtomicBool::new(false));
    let operator_thread = {
        let sock = sock.clone();
        let done = Arc::clone(&done);
        thread::spawn(move || operator_stops(&sock, |_| done.load(Ordering::SeqCst)))
    };
    let session = slow_controller(
        input,
        // Ends its input; its results still come, then the bridge closes
        // the connection.
        |w: UnixStream| {
            let _ = w.shutdown(std::net::Shutdown::Write);
        },
        controller,
    );
    done.store(true, Ordering::SeqCst);
    let (stop_latencies, round_trips) = operator_thread.join().unwrap();
    let dropped: Vec<Value> = events
        .try_iter()
        .filter(|v| v["event"] == "client_dropped")
        .collect();
    assert!(dropped.is_empty(), "{dropped:?}");
    assert_eq!(session.written, SESSION, "the bridge stopped taking lines");
    let wrong = not_one_result(&session.results);
    assert!(
        wrong.is_empty(),
        "lines without exactly one result: {wrong:?}"
    );
    let stop = session.stop.expect("the controller's stop was answered");
    assert_eq!(stop["emergency_stop"], true, "{stop}");
    let n = stop_latencies.len();
    assert!(n >= 50, "only {n} stops");
    let p99_stop = p99(&stop_latencies);
    eprintln!(
        "stops alone: line to last frame median {} µs, p99 {} µs, worst {} µs",
        alone[alone.len() / 2],
        p99(&alone),
        alone[alone.len() - 1],
    );
    eprintln!(
        "{SESSION} lines read slowly in {:?}; {n} stops meanwhile: line to last frame median {} µs, p99 {p99_stop} µs, worst {} µs; round trip median {:?}, p99 {:?}, worst {:?}",
        session.took,
        stop_latencies[n / 2],
        stop_latencies[n - 1],
        round_trips[n / 2],
        p99(&round_trips),
        round_trips[n - 1],
    );
    // A loaded debug build gets the bound the flood test has.
    let bound = if cfg!(debug_assertions) {
        50_000
    } else {
        1_000.max(2 * p99(&alone))
    };
    assert!(
        p99_stop < bound,
        "the stop's p99 took {p99_stop} µs (alone: {} µs)",
        p99(&alone)
    );
    drop(bridge);
}
