//! `motorwire bridge --zenoh`: bridges as separate processes on loopback,
//! each with its simulated arm, one controller (this test), and a router
//! in this process: commands reach only their robot, a retried query runs
//! once, the fleet stop reaches every bridge, a killed bridge leaves the
//! liveliness tokens within its lease, and a bridge that loses its session
//! stops its joints.
//!
//! With the `fleet` feature only: `cargo test -p motorwire-cli --features
//! fleet --test fleet` (CI runs it in release).
#![cfg(feature = "fleet")]
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing
)]

mod common;

use std::io::{BufRead, BufReader};
use std::net::TcpListener;
use std::path::{Path, PathBuf};
use std::process::Child;
use std::sync::mpsc;
use std::thread;
use std::time::{Duration, Instant};

use motorwire_zenoh::zenoh::{self, Wait};
use serde_json::{Value, json};
use zenoh::query::ConsolidationMode;

const MAP: &str = "fixtures/maps/demo-arm.toml";

/// The lease every participant here announces (ms): a killed bridge is
/// forgotten within it (Zenoh's default is 10 s). Not shorter: a process
/// starved of CPU that long on a loaded machine would lose its link, and
/// its queries in progress with it.
const LEASE_MS: u64 = 3000;

fn now_ms() -> u128 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .as_millis()
}

fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("motorwire-fleet-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

/// What every participant here shares: no multicast, a short lease.
fn common_config(mode: &str) -> String {
    format!(
        r#"mode: "{mode}",
  scouting: {{ multicast: {{ enabled: false }}, gossip: {{ enabled: false }} }},
  transport: {{ link: {{ tx: {{ lease: {LEASE_MS}, keep_alive: 4 }} }} }},"#
    )
}

/// A router on `port` in this process (as `zenohd` would be).
fn router(port: u16) -> zenoh::Session {
    let text = format!(
        r#"{{ {} listen: {{ endpoints: ["tcp/127.0.0.1:{port}"] }} }}"#,
        common_config("router")
    );
    zenoh::open(zenoh::Config::from_json5(&text).unwrap())
        .wait()
        .unwrap()
}

/// A client of the router on `port` (the controller).
fn client(port: u16) -> zenoh::Session {
    zenoh::open(zenoh::Config::from_json5(&client_config(port)).unwrap())
        .wait()
        .unwrap()
}

fn client_config(port: u16) -> String {
    format!(
        r#"{{ {} connect: {{ endpoints: ["tcp/127.0.0.1:{port}"], timeout_ms: 5000 }} }}"#,
        common_config("client")
    )
}

/// A bridge process, killed when dropped; its standard input held open.
struct Bridge {
    child: Child,
    robot: String,
    log: PathBuf,
    events: mpsc::Receiver<Value>,
    /// Its standard error so far.
    stderr: std::sync::Arc<std::sync::Mutex<Vec<String>>>,
}

impl Drop for Bridge {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// `motorwire bridge --bus sim --zenoh --robot ROBOT` connected to the
/// router on `port`, its executions logged in `dir`.
fn bridge(dir: &Path, port: u16, robot: &str, extra: &[&str]) -> Bridge {
    bridge_with(dir, &client_config(port), robot, extra)
}

/// `motorwire bridge --bus sim --zenoh --robot ROBOT` with the Zenoh
/// configuration `config`.
fn bridge_with(dir: &Path, config: &str, robot: &str, extra: &[&str]) -> Bridge {
    let config_text = config;
    let config = dir.join(format!("{robot}.json5"));
    std::fs::write(&config, config_text).unwrap();
    let log = dir.join(format!("{robot}.log"));
    let (config_s, log_s) = (config.display().to_string(), log.display().to_string());
    let mut args = vec![
        "bridge",
        "--map",
        MAP,
        "--bus",
        "sim",
        "--sim-log",
        &log_s,
        "--zenoh",
        "--robot",
        robot,
        "--zenoh-config",
        &config_s,
    ];
    args.extend_from_slice(extra);
    let mut child = common::spawn(&args);
    let out = child.stdout.take().unwrap();
    let (tx, events) = mpsc::channel();
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
    let err = child.stderr.take().unwrap();
    let name = robot.to_owned();
    let stderr: std::sync::Arc<std::sync::Mutex<Vec<String>>> = std::sync::Arc::default();
    let kept = std::sync::Arc::clone(&stderr);
    thread::spawn(move || {
        for line in BufReader::new(err).lines() {
            let Ok(line) = line else { return };
            eprintln!("[{name}] {line}");
            if let Ok(mut kept) = kept.lock() {
                kept.push(line);
            }
        }
    });
    Bridge {
        child,
        robot: robot.to_owned(),
        log,
        events,
        stderr,
    }
}

/// The robots whose liveliness token the controller sees now.
fn alive(session: &zenoh::Session) -> Vec<String> {
    let replies = session
        .liveliness()
        .get("motorwire/*/alive")
        .timeout(Duration::from_secs(2))
        .wait()
        .unwrap();
    let mut robots: Vec<String> = std::iter::from_fn(|| replies.recv().ok())
        .filter_map(|r| r.result().ok().map(|s| s.key_expr().as_str().to_owned()))
        .filter_map(|k| k.split('/').nth(1).map(str::to_owned))
        .collect();
    robots.sort();
    robots
}

/// Waits until the controller sees exactly `robots` alive and ready (the
/// joints' startup done: `ready` on the bridge's standard output).
fn wait_alive(session: &zenoh::Session, robots: &[&str], limit: Duration) {
    let end = Instant::now() + limit;
    loop {
        let seen = alive(session);
        if seen == robots {
            return;
        }
        assert!(Instant::now() < end, "alive: {seen:?}, expected {robots:?}");
        thread::sleep(Duration::from_millis(50));
    }
}

fn wait_ready(b: &Bridge) {
    wait_event(b, Duration::from_secs(20), |v| v["event"] == "ready");
}

fn wait_event(b: &Bridge, limit: Duration, what: impl Fn(&Value) -> bool) -> Value {
    let end = Instant::now() + limit;
    loop {
        let left = end.saturating_duration_since(Instant::now());
        match b.events.recv_timeout(left) {
            Ok(v) if what(&v) => return v,
            Ok(v) => {
                if v.get("feedback").is_none() {
                    eprintln!("[{}] {v}", b.robot);
                }
            }
            Err(e) => panic!("{}: not seen within {limit:?}: {e}", b.robot),
        }
    }
}

/// Sends `payload` as a query on `robot`'s cmd; every reply, in order.
fn query(session: &zenoh::Session, robot: &str, payload: &str, limit: Duration) -> Vec<Value> {
    query_on(
        session,
        &format!("motorwire/{robot}/cmd?controller=test"),
        &format!("motorwire/{robot}/cmd"),
        payload,
        limit,
    )
}

/// Sends `payload` as a query on `selector`; every reply, in order, each
/// on the key `replied_on`.
fn query_on(
    session: &zenoh::Session,
    selector: &str,
    replied_on: &str,
    payload: &str,
    limit: Duration,
) -> Vec<Value> {
    let replies = session
        .get(selector)
        .payload(payload)
        .consolidation(ConsolidationMode::None)
        .timeout(limit)
        .wait()
        .unwrap();
    std::iter::from_fn(|| replies.recv().ok())
        .map(|r| {
            let s = r.result().unwrap();
            assert_eq!(s.key_expr().as_str(), replied_on, "{selector}");
            serde_json::from_str(&s.payload().try_to_string().unwrap()).unwrap()
        })
        .collect()
}

/// As a controller should over a network that may break: sends the query,
/// and while its replies end before the completion (a session lost and
/// made again drops the query in progress; a query sent while the session
/// has no route to the robot is answered by nobody at once), waits until
/// the robot is alive again in its session and sends it again with the
/// same id, at most five times. The replies of the last try, and the
/// tries. The query is on `key` (`motorwire/<robot>/cmd/<controller>`),
/// and so are its replies.
fn query_to_completion(
    session: &zenoh::Session,
    key: &str,
    payload: &str,
    limit: Duration,
) -> (Vec<Value>, usize) {
    let robot = key.split('/').nth(1).expect("motorwire/<robot>/...");
    let mut tries = 0;
    loop {
        tries += 1;
        let started = Instant::now();
        let replies = query_on(session, key, key, payload, limit);
        let complete = replies.last().is_some_and(|r| r.get("arrived").is_some());
        if complete || tries == 5 {
            return (replies, tries);
        }
        eprintln!(
            "try {tries}: {replies:?} after {:?}; again with the same id once {robot} is alive",
            started.elapsed()
        );
        let end = Instant::now() + limit;
        while !alive(session).iter().any(|r| r == robot) {
            assert!(
                Instant::now() < end,
                "{robot} not alive again within {limit:?}"
            );
            thread::sleep(Duration::from_millis(100));
        }
        // The robot's token and its queryable travel separately.
        thread::sleep(Duration::from_millis(200));
    }
}

fn move_line(motor: &str, setpoint: f64, request_id: &str) -> String {
    format!(
        r#"{{"motor_id":"{motor}","timestamp":{},"control_mode":"position","setpoint":{setpoint},"request_id":"{request_id}"}}"#,
        now_ms()
    )
}

/// The targets the simulated joints were sent (`SetTargetV2`), from the log.
fn moves(log: &Path) -> Vec<f64> {
    std::fs::read_to_string(log)
        .unwrap_or_default()
        .lines()
        .filter_map(|l| serde_json::from_str::<Value>(l).ok())
        .filter_map(|e| e["payload"]["SetTargetV2"]["target_angle"].as_f64())
        .collect()
}

#[test]
fn commands_reach_only_their_robot_and_a_retried_query_runs_once() {
    let dir = scratch("route");
    let port = free_port();
    let _router = router(port);
    let a = bridge(&dir, port, "a", &[]);
    let b = bridge(&dir, port, "b", &[]);
    let controller = client(port);
    wait_alive(&controller, &["a", "b"], Duration::from_secs(20));
    wait_ready(&a);
    wait_ready(&b);

    let line = move_line("elbow", 30.0, "move-1");
    let first = query(&controller, "a", &line, Duration::from_secs(10));
    assert_eq!(first.len(), 2, "{first:?}");
    assert_eq!(first[0]["ok"], json!(true));
    assert_eq!(first[0]["motor_id"], json!("elbow"));
    assert_eq!(first[0]["acked"], json!(["elbow"]));
    assert_eq!(first[0]["arrival_follows"], json!(true));
    assert_eq!(first[1]["arrived"], json!(true));
    assert_eq!(first[1]["motors"][0]["target"], json!(30.0));
    // The retry (same controller, same request_id, even a newer
    // timestamp) is answered with the first replies, exactly.
    let again = query(
        &controller,
        "a",
        &move_line("elbow", 30.0, "move-1"),
        Duration::from_secs(10),
    );
    assert_eq!(again, first);
    // Executed once, on a alone.
    assert_eq!(moves(&a.log), vec![30.0]);
    assert_eq!(moves(&b.log), Vec::<f64>::new());

    // A query and its retry while the first is in progress: one
    // execution, both answered the same.
    let line = move_line("elbow", 60.0, "move-2");
    let retry = {
        let line = line.clone();
        let port2 = port;
        thread::spawn(move || {
            thread::sleep(Duration::from_millis(5));
            let c = client(port2);
            let replies = c
                .get("motorwire/a/cmd?controller=test")
                .payload(line)
                .consolidation(ConsolidationMode::None)
                .timeout(Duration::from_secs(10))
                .wait()
                .unwrap();
            std::iter::from_fn(|| replies.recv().ok())
                .map(|r| {
                    serde_json::from_str::<Value>(
                        &r.result().unwrap().payload().try_to_string().unwrap(),
                    )
                    .unwrap()
                })
                .collect::<Vec<_>>()
        })
    };
    let first = query(&controller, "a", &line, Duration::from_secs(10));
    let second = retry.join().unwrap();
    assert_eq!(first.len(), 2, "{first:?}");
    assert_eq!(first[1]["arrived"], json!(true));
    assert_eq!(second, first);
    assert_eq!(moves(&a.log), vec![30.0, 60.0]);

    // The same id from another controller is another command.
    let other = controller
        .get("motorwire/b/cmd?controller=other")
        .payload(move_line("elbow", 20.0, "move-1"))
        .consolidation(ConsolidationMode::None)
        .timeout(Duration::from_secs(10))
        .wait()
        .unwrap();
    let n = std::iter::from_fn(|| other.recv().ok()).count();
    assert_eq!(n, 2);
    assert_eq!(moves(&b.log), vec![20.0]);
    assert_eq!(moves(&a.log), vec![30.0, 60.0]);

    // A multi-axis command's command_id is its id.
    let multi = format!(
        r#"{{"command_id":"multi-1","timestamp":{},"motors":[{{"motor_id":"shoulder_pitch","control_mode":"position","setpoint":10}}],"sync_mode":"independent"}}"#,
        now_ms()
    );
    let first = query(&controller, "b", &multi, Duration::from_secs(10));
    assert_eq!(first[0]["command_id"], json!("multi-1"), "{first:?}");
    let again = query(&controller, "b", &multi, Duration::from_secs(10));
    assert_eq!(again, first);
    assert_eq!(moves(&b.log), vec![20.0, 10.0]);
}

/// The kind of a refused result's error.
fn refused(replies: &[Value]) -> &Value {
    assert_eq!(replies.len(), 1, "{replies:?}");
    assert_eq!(replies[0]["ok"], json!(false), "{replies:?}");
    &replies[0]["error"]["kind"]
}

#[test]
fn a_controller_is_named_by_its_key_and_a_parameter_never_reaches_its_ids() {
    let (_router, a, controller, _, _) = fleet_of_one("key-bound");
    let limit = Duration::from_secs(10);
    let alice = "motorwire/a/cmd/alice";

    // A command of the controller cmd/alice, answered on its key; its
    // retry on the robot wildcard is answered from alice's memory.
    let first = query_on(
        &controller,
        alice,
        alice,
        &move_line("elbow", 20.0, "k1"),
        limit,
    );
    assert_eq!(first.len(), 2, "{first:?}");
    assert_eq!(first[0]["ok"], json!(true), "{first:?}");
    assert_eq!(first[1]["arrived"], json!(true), "{first:?}");
    let again = query_on(
        &controller,
        "motorwire/*/cmd/alice",
        alice,
        &move_line("elbow", 20.0, "k1"),
        limit,
    );
    assert_eq!(again, first);
    assert_eq!(moves(&a.log), vec![20.0]);

    // `?controller=alice` is another namespace: the same id with another
    // body is not alice's reused id, it is another controller's command;
    // and its own retry is answered from its own memory.
    let named = query_on(
        &controller,
        "motorwire/a/cmd?controller=alice",
        "motorwire/a/cmd",
        &move_line("elbow", 30.0, "k1"),
        limit,
    );
    assert_eq!(named.len(), 2, "{named:?}");
    assert_eq!(named[0]["ok"], json!(true), "{named:?}");
    assert_eq!(moves(&a.log), vec![20.0, 30.0]);
    // ...and alice's memory is untouched by it: her retry still runs
    // nothing, her reuse is still refused naming her first command.
    let again = query_on(
        &controller,
        alice,
        alice,
        &move_line("elbow", 20.0, "k1"),
        limit,
    );
    assert_eq!(again, first);
    let reused = query_on(
        &controller,
        alice,
        alice,
        &move_line("elbow", 30.0, "k1"),
        limit,
    );
    assert_eq!(refused(&reused), &json!("id_reused"));
    assert_eq!(moves(&a.log), vec![20.0, 30.0]);

    // A query that names no one controller is refused, nothing sent.
    let no_one = [
        (
            "motorwire/a/cmd/alice?controller=bob",
            alice,
            r#"the key motorwire/a/cmd/alice names the controller "alice" and the `controller` parameter names one too; name it once, by the key"#,
        ),
        (
            "motorwire/a/cmd/*",
            "motorwire/a/cmd/*",
            r#"the controller chunk "*" of the key motorwire/a/cmd/*: a key-expression chunk cannot hold `/`, `*`, `$`, `?`, `#`, spaces or control characters; a command is asked on motorwire/<robot>/cmd/<controller>, one controller by its name"#,
        ),
        (
            "motorwire/a/cmd/alice/x",
            "motorwire/a/cmd/alice/x",
            "the key motorwire/a/cmd/alice/x names no one controller: a command is asked on motorwire/<robot>/cmd/<controller> (or motorwire/<robot>/cmd)",
        ),
        (
            "motorwire/a/**",
            "motorwire/a/**",
            "the key motorwire/a/** names no one controller: a command is asked on motorwire/<robot>/cmd/<controller> (or motorwire/<robot>/cmd)",
        ),
    ];
    for (selector, replied_on, why) in no_one {
        let replies = query_on(
            &controller,
            selector,
            replied_on,
            &move_line("elbow", 40.0, "k1"),
            limit,
        );
        assert_eq!(refused(&replies), &json!("invalid"), "{selector}");
        assert_eq!(
            replies[0]["error"]["message"],
            json!(format!("{why}; nothing was sent")),
            "{selector}: {replies:?}"
        );
    }
    assert_eq!(moves(&a.log), vec![20.0, 30.0]);

    // A stop refused for the key it names still stops.
    let stop = query_on(
        &controller,
        "motorwire/a/cmd/*",
        "motorwire/a/cmd/*",
        r#"{"emergency_stop":true}"#,
        limit,
    );
    assert_eq!(stop[0]["ok"], json!(true), "{stop:?}");
    assert_eq!(stop[0]["emergency_stop"], json!(true), "{stop:?}");
    assert_eq!(
        stop[0]["problems"],
        json!([
            "the controller chunk \"*\" of the key motorwire/a/cmd/*: a key-expression chunk cannot hold `/`, `*`, `$`, `?`, `#`, spaces or control characters; a command is asked on motorwire/<robot>/cmd/<controller>, one controller by its name; it names emergency_stop, so it is taken as a stop"
        ]),
        "{stop:?}"
    );
    wait_event(&a, limit, |v| v["event"] == "emergency_stop");
    let release = query_on(
        &controller,
        alice,
        alice,
        r#"{"emergency_stop":false}"#,
        limit,
    );
    assert_eq!(release[0]["released"], json!(true), "{release:?}");
}

/// A fleet bridge started with its standard input closed (a service
/// manager, a shell's `&`) stays in the fleet and takes its commands: with
/// `--zenoh` and no `--input` it reads no standard input.
#[test]
fn a_fleet_bridge_with_its_standard_input_closed_stays_in_the_fleet() {
    let dir = scratch("no-stdin");
    let port = free_port();
    let _router = router(port);
    let mut a = bridge(&dir, port, "a", &[]);
    drop(a.child.stdin.take());
    let controller = client(port);
    wait_alive(&controller, &["a"], Duration::from_secs(20));
    wait_ready(&a);
    thread::sleep(Duration::from_millis(500));
    assert!(a.child.try_wait().unwrap().is_none(), "the bridge ended");
    let replies = query(
        &controller,
        "a",
        &move_line("elbow", 25.0, "n1"),
        Duration::from_secs(10),
    );
    assert_eq!(replies.len(), 2, "{replies:?}");
    assert_eq!(replies[1]["arrived"], json!(true), "{replies:?}");
    assert_eq!(moves(&a.log), vec![25.0]);
    assert!(a.child.try_wait().unwrap().is_none(), "the bridge ended");
    let said = a.stderr.lock().unwrap().join("\n");
    assert!(
        said.contains(
            "no local input (--input none): lines come from the fleet; a signal ends the bridge"
        ),
        "{said}"
    );
}

/// A router, one bridge `a` on it, ready, and a controller: the router,
/// the bridge, the controller, the scratch folder and the router's port.
fn fleet_of_one(name: &str) -> (zenoh::Session, Bridge, zenoh::Session, PathBuf, u16) {
    let dir = scratch(name);
    let port = free_port();
    let router = router(port);
    let a = bridge(&dir, port, "a", &[]);
    let controller = client(port);
    wait_alive(&controller, &["a"], Duration::from_secs(20));
    wait_ready(&a);
    (router, a, controller, dir, port)
}

#[test]
fn a_query_is_read_as_a_local_line_and_an_id_names_one_command() {
    let (_router, a, controller, _, _) = fleet_of_one("one-reading");
    let limit = Duration::from_secs(10);
    let stamp = now_ms();

    // A repeated member is refused, as on standard input, id or not.
    for payload in [
        format!(
            r#"{{"motor_id":"elbow","timestamp":{stamp},"control_mode":"position","setpoint":20,"setpoint":140,"request_id":"d1"}}"#
        ),
        format!(
            r#"{{"motor_id":"elbow","motor_id":"shoulder_pitch","timestamp":{stamp},"control_mode":"position","setpoint":20,"request_id":"d2"}}"#
        ),
    ] {
        let replies = query(&controller, "a", &payload, limit);
        assert_eq!(refused(&replies), &json!("invalid"), "{payload}");
        assert!(
            replies[0]["error"]["violations"]
                .to_string()
                .contains("duplicate field"),
            "{replies:?}"
        );
        // Its retry is answered the same, from the memory.
        assert_eq!(query(&controller, "a", &payload, limit), replies);
    }
    assert_eq!(moves(&a.log), Vec::<f64>::new());

    // A command naming emergency_stop (false) keeps its id: its retry,
    // stamped anew, is answered with the first replies and runs nothing.
    let limited = |setpoint: f64, id: &str| {
        format!(
            r#"{{"motor_id":"elbow","timestamp":{},"control_mode":"position","setpoint":{setpoint},"safety_limits":{{"emergency_stop":false}},"request_id":"{id}"}}"#,
            now_ms()
        )
    };
    let first = query(&controller, "a", &limited(60.0, "es-1"), limit);
    let es_first = first.clone();
    assert_eq!(first.len(), 2, "{first:?}");
    assert_eq!(first[0]["ok"], json!(true), "{first:?}");
    assert!(
        first[0]
            .get("losses")
            .is_none_or(|l| !l.to_string().contains("request_id")),
        "{first:?}"
    );
    let again = query(&controller, "a", &limited(60.0, "es-1"), limit);
    assert_eq!(again, first);
    assert_eq!(moves(&a.log), vec![60.0]);

    // The same id with another command is refused, naming the first.
    let reused = query(&controller, "a", &limited(70.0, "es-1"), limit);
    assert_eq!(refused(&reused), &json!("id_reused"));
    let message = reused[0]["error"]["message"].as_str().unwrap_or_default();
    assert!(message.contains(r#""setpoint":60"#), "{message}");
    assert_eq!(moves(&a.log), vec![60.0]);

    // An integer id is not the string with its digits.
    let numbered = |setpoint: f64, id: &str| {
        format!(
            r#"{{"motor_id":"elbow","timestamp":{},"control_mode":"position","setpoint":{setpoint},"request_id":{id}}}"#,
            now_ms()
        )
    };
    let first = query(&controller, "a", &numbered(15.0, "42"), limit);
    assert_eq!(first[0]["ok"], json!(true), "{first:?}");
    let other = query(&controller, "a", &numbered(25.0, r#""42""#), limit);
    assert_eq!(other[0]["ok"], json!(true), "{other:?}");
    let again = query(&controller, "a", &numbered(15.0, "42"), limit);
    assert_eq!(again, first);
    assert_eq!(moves(&a.log), vec![60.0, 15.0, 25.0]);

    // A multi-axis command whose motor names emergency_stop: once.
    let multi = format!(
        r#"{{"command_id":"m-es","timestamp":{},"motors":[{{"motor_id":"shoulder_pitch","control_mode":"position","setpoint":12,"safety_limits":{{"emergency_stop":false}}}}],"sync_mode":"independent"}}"#,
        now_ms()
    );
    let first = query(&controller, "a", &multi, limit);
    assert_eq!(first[0]["ok"], json!(true), "{first:?}");
    let again = query(&controller, "a", &multi, limit);
    assert_eq!(again, first);
    assert_eq!(moves(&a.log), vec![60.0, 15.0, 25.0, 12.0]);

    // Invented controller names cannot push this controller's ids out:
    // 63 more fill the memory (64), the rest are refused `busy`, and the
    // retry of es-1 still runs nothing.
    let mut kinds = Vec::new();
    for n in 0..70 {
        let replies = controller
            .get(format!("motorwire/a/cmd?controller=invented-{n}"))
            .payload(r#"{"query":"limits","motor_id":"elbow","request_id":"x"}"#)
            .consolidation(ConsolidationMode::None)
            .timeout(limit)
            .wait()
            .unwrap();
        let first: Value = std::iter::from_fn(|| replies.recv().ok())
            .map(|r| {
                serde_json::from_str(&r.result().unwrap().payload().try_to_string().unwrap())
                    .unwrap()
            })
            .next()
            .unwrap();
        kinds.push(first["error"]["kind"].as_str().unwrap_or("ok").to_owned());
    }
    assert_eq!(kinds.iter().filter(|k| *k == "ok").count(), 63, "{kinds:?}");
    assert_eq!(
        kinds.iter().filter(|k| *k == "busy").count(),
        7,
        "{kinds:?}"
    );
    let again = query(&controller, "a", &limited(60.0, "es-1"), limit);
    assert_eq!(again, es_first);
    assert_eq!(moves(&a.log), vec![60.0, 15.0, 25.0, 12.0]);

    // A stop carrying an id stops (and is never remembered: a second
    // stop is a second stop); the release with an id releases.
    for payload in [
        r#"{"emergency_stop":true,"request_id":"s"}"#,
        r#"{"emergency_stop":true,"request_id":"s"}"#,
        r#"{"emergency_stop":false,"request_id":"s"}"#,
    ] {
        let replies = query(&controller, "a", payload, limit);
        assert_eq!(replies[0]["ok"], json!(true), "{payload}: {replies:?}");
    }
}

/// `motorwire bridge --zenoh --robot ROBOT` with the Zenoh configuration
/// file `config`, which must exit 2 at start: its standard error.
fn refused_at_start(robot: &str, config: &str) -> String {
    let out = common::run(
        &[
            "bridge",
            "--map",
            MAP,
            "--bus",
            "sim",
            "--zenoh",
            "--robot",
            robot,
            "--zenoh-config",
            config,
        ],
        b"",
    );
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    stderr
}

#[test]
fn a_robot_name_is_one_robot_and_every_reply_names_its_bridge() {
    let (_router, a, controller, dir, port) = fleet_of_one("one-name");
    let limit = Duration::from_secs(10);

    let first = query(&controller, "a", &move_line("elbow", 5.0, "n1"), limit);
    assert_eq!(first.len(), 2, "{first:?}");
    let zid = first[0]["bridge"].as_str().unwrap_or_default().to_owned();
    // A Zenoh id: up to 32 hex digits (without leading zeros).
    assert!(
        !zid.is_empty() && zid.len() <= 32 && zid.chars().all(|c| c.is_ascii_hexdigit()),
        "{first:?}"
    );
    for reply in &first {
        assert_eq!(
            (&reply["robot"], &reply["bridge"]),
            (&json!("a"), &json!(zid))
        );
    }

    // A second bridge with the same name refuses to join: exit 2, naming
    // the bridge that has it, before it answers anything.
    let config = dir.join("second.json5");
    std::fs::write(&config, client_config(port)).unwrap();
    let config = config.display().to_string();
    let stderr = refused_at_start("a", &config);
    assert!(
        stderr.contains(&format!(
            "robot name \"a\" is taken: bridge {zid} answers for motorwire/a already (its Zenoh id); give this bridge another --robot, or stop that one"
        )),
        "{stderr}"
    );
    // One robot, one bridge: one token, and a command answered once.
    assert_eq!(alive(&controller), ["a"]);
    let next = query(&controller, "a", &move_line("elbow", 6.0, "n2"), limit);
    assert_eq!(next.len(), 2, "{next:?}");
    assert_eq!(moves(&a.log), vec![5.0, 6.0]);

    // A name no wildcard finds is refused at start.
    let stderr = refused_at_start("@lab", &config);
    assert!(
        stderr.contains("--robot robot name \"@lab\": a chunk that starts with `@` is verbatim: no wildcard finds it (`motorwire/*/alive` would not)"),
        "{stderr}"
    );
}

/// The Zenoh ids of the bridges whose own token for `robot` the
/// controller sees now.
fn bridges_of(session: &zenoh::Session, robot: &str) -> Vec<String> {
    let replies = session
        .liveliness()
        .get(format!("motorwire/{robot}/alive/*"))
        .timeout(Duration::from_secs(2))
        .wait()
        .unwrap();
    std::iter::from_fn(|| replies.recv().ok())
        .filter_map(|r| r.result().ok().map(|s| s.key_expr().as_str().to_owned()))
        .filter_map(|k| k.rsplit('/').next().map(str::to_owned))
        .collect()
}

#[test]
fn two_bridges_started_at_once_under_one_name_leave_one_in_the_fleet() {
    let dir = scratch("twins");
    let port = free_port();
    // Both start before the router: their sessions open on the same retry.
    let dir1 = dir.join("1");
    let dir2 = dir.join("2");
    std::fs::create_dir_all(&dir1).unwrap();
    std::fs::create_dir_all(&dir2).unwrap();
    let first = bridge(&dir1, port, "twin", &[]);
    let second = bridge(&dir2, port, "twin", &[]);
    let retrying = |b: &Bridge| {
        b.stderr
            .lock()
            .is_ok_and(|l| l.iter().any(|l| l.contains("trying again every")))
    };
    let end = Instant::now() + Duration::from_secs(20);
    while !(retrying(&first) && retrying(&second)) {
        assert!(Instant::now() < end, "the bridges never tried the session");
        thread::sleep(Duration::from_millis(20));
    }
    let _router = router(port);
    let controller = client(port);
    let end = Instant::now() + Duration::from_secs(15);
    let said = |b: &Bridge| {
        b.stderr.lock().is_ok_and(|l| {
            l.iter().any(|l| {
                l.contains("leaves the fleet") && l.contains("this bridge")
                    || l.contains("stays out of the fleet")
            })
        })
    };
    loop {
        let out = [said(&first), said(&second)];
        let seen = bridges_of(&controller, "twin");
        if seen.len() == 1 && out.iter().filter(|o| **o).count() == 1 {
            break;
        }
        assert!(Instant::now() < end, "tokens {seen:?}, left {out:?}");
        thread::sleep(Duration::from_millis(100));
    }
    assert_eq!(alive(&controller), ["twin"]);
    // Stays so: the one that left does not come back.
    thread::sleep(Duration::from_millis(1500));
    assert_eq!(bridges_of(&controller, "twin").len(), 1);
}

#[test]
fn many_commands_in_flight_each_retried_at_once_run_at_most_once() {
    let dir = scratch("inflight");
    let port = free_port();
    let _router = router(port);
    let b = bridge(&dir, port, "busy", &[]);
    let controller = std::sync::Arc::new(client(port));
    wait_alive(&controller, &["busy"], Duration::from_secs(20));
    wait_ready(&b);
    // 20 moves of the shoulder, each sent twice at once (a controller
    // that retried at once): 40 queries in flight.
    let handles: Vec<_> = (0..40)
        .map(|i| {
            let c = std::sync::Arc::clone(&controller);
            let setpoint = f64::from(1 + i / 2);
            let line = move_line("shoulder_pitch", setpoint, &format!("burst-{}", i / 2));
            thread::spawn(move || (i / 2, query(&c, "busy", &line, Duration::from_secs(20))))
        })
        .collect();
    let mut answers: Vec<(i32, Vec<Value>)> =
        handles.into_iter().map(|h| h.join().unwrap()).collect();
    answers.sort_by_key(|(id, _)| *id);
    let mut acked = Vec::new();
    for pair in answers.chunks(2) {
        let [(id, first), (_, second)] = pair else {
            panic!("{pair:?}")
        };
        assert!(!first.is_empty(), "burst-{id}: no reply");
        // Both queries of a pair got the same replies.
        assert_eq!(first, second, "burst-{id}");
        if first[0]["acked"] == json!(["shoulder_pitch"]) {
            acked.push(f64::from(1 + id));
        }
    }
    // Every move the bridge acked was executed exactly once; the rest
    // (superseded by a newer one while waiting) never.
    let mut executed = moves(&b.log);
    executed.sort_by(f64::total_cmp);
    acked.sort_by(f64::total_cmp);
    assert_eq!(executed, acked);
    assert!(!acked.is_empty());
}

#[test]
fn the_fleet_stop_reaches_every_bridge_and_the_release_is_per_robot() {
    let dir = scratch("estop");
    let port = free_port();
    let _router = router(port);
    let robots = ["r1", "r2", "r3"];
    let bridges: Vec<Bridge> = robots.iter().map(|r| bridge(&dir, port, r, &[])).collect();
    let controller = client(port);
    wait_alive(&controller, &robots, Duration::from_secs(20));
    bridges.iter().for_each(wait_ready);
    let results = controller
        .declare_subscriber("motorwire/*/estop/result")
        .wait()
        .unwrap();
    thread::sleep(Duration::from_millis(200));
    controller
        .put("motorwire/fleet/estop", "{}")
        .wait()
        .unwrap();
    let mut stopped = Vec::new();
    for _ in &robots {
        let s = results
            .recv_timeout(Duration::from_secs(5))
            .unwrap()
            .unwrap();
        let v: Value = serde_json::from_str(&s.payload().try_to_string().unwrap()).unwrap();
        assert_eq!(v["ok"], json!(true), "{v}");
        assert_eq!(v["emergency_stop"], json!(true), "{v}");
        assert!(v["stop_latency_us"].as_u64().is_some(), "{v}");
        stopped.push(s.key_expr().as_str().split('/').nth(1).unwrap().to_owned());
    }
    stopped.sort();
    assert_eq!(stopped, robots);
    for b in &bridges {
        wait_event(b, Duration::from_secs(5), |v| {
            v["event"] == "emergency_stop"
        });
    }
    // Latched everywhere: a move is refused.
    for r in robots {
        let replies = query(
            &controller,
            r,
            &move_line("elbow", 40.0, "after-stop"),
            Duration::from_secs(5),
        );
        assert_eq!(replies.len(), 1, "{replies:?}");
        assert_eq!(replies[0]["error"]["kind"], json!("emergency_stop_latched"));
    }
    // Released on r2 alone: r2 moves, r1 and r3 are still latched.
    let released = query(
        &controller,
        "r2",
        r#"{"emergency_stop": false}"#,
        Duration::from_secs(5),
    );
    assert_eq!(released[0]["released"], json!(true), "{released:?}");
    let moved = query(
        &controller,
        "r2",
        &move_line("elbow", 40.0, "after-release"),
        Duration::from_secs(10),
    );
    assert_eq!(moved[0]["ok"], json!(true), "{moved:?}");
    let refused = query(
        &controller,
        "r1",
        &move_line("elbow", 40.0, "after-release"),
        Duration::from_secs(5),
    );
    assert_eq!(refused[0]["error"]["kind"], json!("emergency_stop_latched"));
    assert_eq!(moves(&bridges[0].log), Vec::<f64>::new());
    assert_eq!(moves(&bridges[1].log), vec![40.0]);
    assert_eq!(moves(&bridges[2].log), Vec::<f64>::new());

    // One robot's own stop reaches it alone.
    controller.put("motorwire/r2/estop", "").wait().unwrap();
    let s = results
        .recv_timeout(Duration::from_secs(5))
        .unwrap()
        .unwrap();
    assert_eq!(s.key_expr().as_str(), "motorwire/r2/estop/result");
    assert!(
        results
            .recv_timeout(Duration::from_millis(500))
            .unwrap()
            .is_none()
    );
}

#[test]
fn a_killed_bridge_leaves_the_liveliness_tokens_within_its_lease() {
    let dir = scratch("kill");
    let port = free_port();
    let _router = router(port);
    let a = bridge(&dir, port, "ka", &[]);
    let mut b = bridge(&dir, port, "kb", &[]);
    let c = bridge(&dir, port, "kc", &[]);
    let controller = client(port);
    wait_alive(&controller, &["ka", "kb", "kc"], Duration::from_secs(20));
    // With its history: the three tokens come first, so the router has
    // the subscription before anything is killed (a subscription still on
    // its way would miss the withdrawal).
    let gone = controller
        .liveliness()
        .declare_subscriber("motorwire/*/alive")
        .history(true)
        .wait()
        .unwrap();
    let mut present: Vec<String> = (0..3)
        .map(|_| {
            let s = gone.recv_timeout(Duration::from_secs(5)).unwrap().unwrap();
            assert_eq!(s.kind(), zenoh::sample::SampleKind::Put);
            s.key_expr().as_str().to_owned()
        })
        .collect();
    present.sort();
    assert_eq!(
        present,
        [
            "motorwire/ka/alive",
            "motorwire/kb/alive",
            "motorwire/kc/alive"
        ]
    );
    // SIGKILL: its socket is closed, the router sees it at once.
    let killed = Instant::now();
    b.child.kill().unwrap();
    let s = gone.recv_timeout(Duration::from_secs(5)).unwrap().unwrap();
    let after = killed.elapsed();
    assert_eq!(s.key_expr().as_str(), "motorwire/kb/alive");
    assert_eq!(s.kind(), zenoh::sample::SampleKind::Delete);
    assert!(after <= Duration::from_millis(500), "{after:?}");
    // The others stay: no withdrawal of theirs comes (the next sample on
    // `gone` is kc's, below), and a query finds both. One query alone can
    // come back empty while the router is busy with the closed session
    // (seen once with the whole suite running in parallel), so it is
    // asked again for a while.
    wait_alive(&controller, &["ka", "kc"], Duration::from_secs(5));
    // SIGSTOP: a machine that froze or whose cable is out; its socket
    // stays open and only the lease tells.
    let frozen = Instant::now();
    let status = std::process::Command::new("kill")
        .args(["-STOP", &c.child.id().to_string()])
        .status()
        .unwrap();
    assert!(status.success());
    let s = gone.recv_timeout(Duration::from_secs(10)).unwrap().unwrap();
    let after = frozen.elapsed();
    assert_eq!(s.key_expr().as_str(), "motorwire/kc/alive");
    assert_eq!(s.kind(), zenoh::sample::SampleKind::Delete);
    assert!(
        after >= Duration::from_millis(LEASE_MS / 2)
            && after <= Duration::from_millis(LEASE_MS + 1000),
        "{after:?}"
    );
    wait_alive(&controller, &["ka"], Duration::from_secs(5));
    drop(a);
    drop(c); // killed (SIGKILL ends a stopped process too)
}

#[test]
fn a_bridge_that_loses_its_session_while_joints_move_stops_them() {
    let dir = scratch("lost");
    let port = free_port();
    let router = router(port);
    let b = bridge(&dir, port, "lost", &["--zenoh-session-timeout", "300"]);
    let controller = client(port);
    wait_alive(&controller, &["lost"], Duration::from_secs(20));
    wait_ready(&b);
    // A long, slow move: the query stays in progress until it arrives.
    let line = format!(
        r#"{{"motor_id":"elbow","timestamp":{},"control_mode":"position","setpoint":140,"velocity_limit":10,"request_id":"slow"}}"#,
        now_ms()
    );
    let replies = controller
        .get("motorwire/lost/cmd?controller=test")
        .payload(line)
        .consolidation(ConsolidationMode::None)
        .timeout(Duration::from_secs(30))
        .wait()
        .unwrap();
    let result: Value = serde_json::from_str(
        &replies
            .recv()
            .unwrap()
            .result()
            .unwrap()
            .payload()
            .try_to_string()
            .unwrap(),
    )
    .unwrap();
    assert_eq!(result["ok"], json!(true), "{result}");
    assert_eq!(result["arrival_follows"], json!(true), "{result}");
    // The network goes: the router is gone.
    let lost = Instant::now();
    router.close().wait().unwrap();
    let stop = wait_event(&b, Duration::from_secs(5), |v| {
        v["event"] == "emergency_stop"
    });
    let after = lost.elapsed();
    assert_eq!(stop["cause"], json!("input"), "{stop}");
    // Not before the timeout; well within Zenoh's default lease (10 s),
    // with room for a loaded machine.
    assert!(
        after >= Duration::from_millis(300) && after <= Duration::from_millis(2000),
        "stopped {after:?} after the session was lost"
    );
    // The joint was sent its move, then the stop (Deactivate: it brakes),
    // which it logs once it has executed it.
    assert_eq!(moves(&b.log), vec![140.0]);
    let elbow = || -> Vec<Value> {
        std::fs::read_to_string(&b.log)
            .unwrap()
            .lines()
            .map(|l| serde_json::from_str::<Value>(l).unwrap())
            .filter(|e| e["joint"] == "elbow")
            .map(|e| e["payload"].clone())
            .collect()
    };
    let end = Instant::now() + Duration::from_secs(5);
    while elbow().last() != Some(&json!("Deactivate")) && Instant::now() < end {
        thread::sleep(Duration::from_millis(20));
    }
    let elbow = elbow();
    assert_eq!(elbow.last(), Some(&json!("Deactivate")), "{elbow:?}");
}

/// The documented deployment configuration `name` (crates/motorwire-zenoh/
/// config/NAME.json5) made to run here: the test-only certificate, the
/// passwords of `dir`, the router on `port`.
fn deployment(name: &str, dir: &Path, port: u16) -> String {
    let certs = common::root().join("crates/motorwire-cli/tests/fleet-test-certs");
    std::fs::read_to_string(
        common::root().join(format!("crates/motorwire-zenoh/config/{name}.json5")),
    )
    .unwrap()
    .replace(
        "/etc/motorwire/zenoh/passwords.txt",
        &dir.join("passwords.txt").display().to_string(),
    )
    .replace("/etc/motorwire/zenoh/", &format!("{}/", certs.display()))
    .replace("tls/0.0.0.0:7447", &format!("tls/127.0.0.1:{port}"))
    .replace(
        "tls/fleet-router.example:7447",
        &format!("tls/127.0.0.1:{port}"),
    )
    .replace("CHANGE-ME-controller", "controller-secret")
    .replace("CHANGE-ME-bridge", "bridge-secret")
    .replace("CHANGE-ME-observer", "observer-secret")
}

/// Opens a session as an intruder would: `Ok` when it got one (it may
/// still reach nobody).
fn try_open(config: &str) -> Option<zenoh::Session> {
    // Give up on the router after a second instead of trying forever.
    let config = config.replace("timeout_ms: -1", "timeout_ms: 1000");
    zenoh::open(zenoh::Config::from_json5(&config).unwrap())
        .wait()
        .ok()
}

#[test]
fn without_the_controllers_credentials_no_participant_moves_a_joint() {
    let dir = scratch("secure");
    std::fs::write(
        dir.join("passwords.txt"),
        "controller:controller-secret\nbridge:bridge-secret\nobserver:observer-secret\n",
    )
    .unwrap();
    let port = free_port();
    let _router =
        zenoh::open(zenoh::Config::from_json5(&deployment("router", &dir, port)).unwrap())
            .wait()
            .unwrap();
    let b = bridge_with(&dir, &deployment("bridge", &dir, port), "secure", &[]);
    let controller =
        zenoh::open(zenoh::Config::from_json5(&deployment("controller", &dir, port)).unwrap())
            .wait()
            .unwrap();
    wait_alive(&controller, &["secure"], Duration::from_secs(20));
    wait_ready(&b);
    let line = |id: &str| move_line("elbow", 50.0, id);

    // An observer, with its own credentials: it hears the feedback, and
    // its commands and stops go nowhere.
    let observer = try_open(&deployment("observer", &dir, port)).unwrap();
    let feedback = observer
        .declare_subscriber("motorwire/secure/feedback/elbow")
        .wait()
        .unwrap();
    let heard = feedback
        .recv_timeout(Duration::from_secs(5))
        .unwrap()
        .unwrap();
    let heard: Value = serde_json::from_str(&heard.payload().try_to_string().unwrap()).unwrap();
    assert_eq!(heard["motor_id"], json!("elbow"));
    for selector in [
        "motorwire/secure/cmd/controller",
        "motorwire/secure/cmd/observer",
        "motorwire/secure/cmd?controller=controller",
    ] {
        assert_eq!(
            query_on(
                &observer,
                selector,
                selector,
                &line("observer"),
                Duration::from_secs(2)
            ),
            Vec::<Value>::new(),
            "{selector}"
        );
    }
    observer.put("motorwire/fleet/estop", "{}").wait().unwrap();
    observer.put("motorwire/secure/estop", "{}").wait().unwrap();

    // No password, a wrong password, the bridge's password (a bridge
    // serves, it does not command), and no TLS: nothing.
    let controller_doc = deployment("controller", &dir, port);
    let intruders = [
        controller_doc.replace(
            r#"usrpwd: { user: "controller", password: "controller-secret" },"#,
            "",
        ),
        controller_doc.replace("controller-secret", "guessed"),
        controller_doc
            .replace(r#"user: "controller""#, r#"user: "bridge""#)
            .replace("controller-secret", "bridge-secret"),
        controller_doc
            .replace(
                &format!("tls/127.0.0.1:{port}"),
                &format!("tcp/127.0.0.1:{port}"),
            )
            .replace(r#"protocols: ["tls"]"#, r#"protocols: ["tcp"]"#),
    ];
    assert!(intruders.iter().all(|i| *i != controller_doc));
    for (n, config) in intruders.iter().enumerate() {
        if let Some(s) = try_open(config) {
            let replies = query_on(
                &s,
                "motorwire/secure/cmd/controller",
                "motorwire/secure/cmd/controller",
                &line(&format!("intruder-{n}")),
                Duration::from_secs(2),
            );
            assert_eq!(replies, Vec::<Value>::new(), "intruder {n}");
            s.put("motorwire/fleet/estop", "{}").wait().unwrap();
        }
    }
    thread::sleep(Duration::from_millis(300));
    assert_eq!(moves(&b.log), Vec::<f64>::new());
    while let Ok(v) = b.events.try_recv() {
        assert_ne!(v["event"], json!("emergency_stop"), "{v}");
    }

    // The controller moves the joint, and stops the fleet.
    let sent = Instant::now();
    let (replies, tries) = query_to_completion(
        &controller,
        "motorwire/secure/cmd/controller",
        &line("controller"),
        Duration::from_secs(10),
    );
    let took = sent.elapsed();
    let seen: Vec<Value> = std::iter::from_fn(|| b.events.try_recv().ok())
        .filter(|v| v.get("feedback").is_none())
        .collect();
    assert_eq!(
        replies.len(),
        2,
        "{replies:?} after {took:?} and {tries} tries; events {seen:?}"
    );
    assert_eq!(replies[0]["ok"], json!(true));
    assert_eq!(replies[1]["arrived"], json!(true));
    assert_eq!(moves(&b.log), vec![50.0]);
    controller
        .put("motorwire/fleet/estop", "{}")
        .wait()
        .unwrap();
    wait_event(&b, Duration::from_secs(5), |v| {
        v["event"] == "emergency_stop"
    });
}

/// The deployment's router with a second controller, `planner`, added as
/// config/README.md says: its own rules on motorwire/*/cmd/planner, a
/// subject and a policy.
fn router_with_planner(dir: &Path, port: u16) -> String {
    let doc = deployment("router", dir, port);
    let with = doc
        .replacen(
            "    rules: [\n",
            r#"    rules: [
      { id: "command_planner", messages: ["query"], flows: ["ingress"], permission: "allow",
        key_exprs: ["motorwire/*/cmd/planner"] },
      { id: "answers_planner", messages: ["reply"], flows: ["egress"], permission: "allow",
        key_exprs: ["motorwire/*/cmd/planner"] },
"#,
            1,
        )
        .replacen(
            "    subjects: [\n",
            "    subjects: [\n      { id: \"planner\", usernames: [\"planner\"] },\n",
            1,
        )
        .replacen(
            "    policies: [\n",
            "    policies: [\n      { rules: [\"command_planner\", \"stop\", \"listen\", \"hear\", \"answers_planner\"], subjects: [\"planner\"] },\n",
            1,
        );
    assert_eq!(
        with.matches("planner").count(),
        doc.matches("planner").count() + 9
    );
    with
}

#[test]
fn with_access_control_a_controllers_ids_are_its_users_own() {
    let dir = scratch("per-user");
    std::fs::write(
        dir.join("passwords.txt"),
        "controller:controller-secret\nplanner:planner-secret\nbridge:bridge-secret\nobserver:observer-secret\n",
    )
    .unwrap();
    let port = free_port();
    let _router = zenoh::open(zenoh::Config::from_json5(&router_with_planner(&dir, port)).unwrap())
        .wait()
        .unwrap();
    let b = bridge_with(&dir, &deployment("bridge", &dir, port), "secure", &[]);
    let controller_doc = deployment("controller", &dir, port);
    let controller = try_open(&controller_doc).unwrap();
    let planner = try_open(
        &controller_doc
            .replace(r#"user: "controller""#, r#"user: "planner""#)
            .replace("controller-secret", "planner-secret"),
    )
    .unwrap();
    wait_alive(&controller, &["secure"], Duration::from_secs(20));
    wait_ready(&b);
    let limit = Duration::from_secs(10);
    let mine = "motorwire/secure/cmd/controller";
    let theirs = "motorwire/secure/cmd/planner";

    // The controller's command, on its own key.
    // Each query is retried with its id while its replies end early (the
    // TLS session lost and remade ends a query in progress), as a
    // controller should; the joint moves once whatever the tries.
    let (first, tries) =
        query_to_completion(&controller, mine, &move_line("elbow", 50.0, "d1"), limit);
    assert_eq!(first.len(), 2, "{first:?} after {tries} tries");
    assert_eq!(first[1]["arrived"], json!(true), "{first:?}");
    assert_eq!(moves(&b.log), vec![50.0]);

    // The planner's own d1, another command: it runs, not `id_reused`.
    let (planners, tries) =
        query_to_completion(&planner, theirs, &move_line("elbow", 60.0, "d1"), limit);
    assert_eq!(planners.len(), 2, "{planners:?} after {tries} tries");
    assert_eq!(planners[0]["ok"], json!(true), "{planners:?}");
    assert_eq!(moves(&b.log), vec![50.0, 60.0]);

    // The planner cannot reach the controller's memory: not on its key
    // (a retry of d1 would get the controller's replies, a new body would
    // be refused naming the controller's command), not through a wildcard,
    // not through the plain cmd under the controller's name. Nothing
    // answers, nothing runs.
    for selector in [
        mine.to_owned(),
        "motorwire/*/cmd/controller".to_owned(),
        "motorwire/secure/cmd/*".to_owned(),
        "motorwire/secure/cmd/**".to_owned(),
        "motorwire/secure/cmd?controller=controller".to_owned(),
        "motorwire/secure/**".to_owned(),
    ] {
        for body in [
            move_line("elbow", 50.0, "d1"),
            move_line("elbow", 70.0, "d1"),
        ] {
            let replies = planner
                .get(&selector)
                .payload(body)
                .consolidation(ConsolidationMode::None)
                .timeout(Duration::from_secs(2))
                .wait()
                .unwrap();
            let got: Vec<String> = std::iter::from_fn(|| replies.recv().ok())
                .map(|r| match r.result() {
                    Ok(s) => s.payload().try_to_string().unwrap().into_owned(),
                    Err(e) => format!("error reply {:?}", e.payload().try_to_string()),
                })
                .collect();
            assert_eq!(got, Vec::<String>::new(), "{selector}");
        }
    }
    thread::sleep(Duration::from_millis(300));
    assert_eq!(moves(&b.log), vec![50.0, 60.0]);

    // Each one's retry is answered from its own memory.
    let (again, _) = query_to_completion(&controller, mine, &move_line("elbow", 50.0, "d1"), limit);
    assert_eq!(again, first);
    let (again, _) = query_to_completion(&planner, theirs, &move_line("elbow", 60.0, "d1"), limit);
    assert_eq!(again, planners);
    assert_eq!(moves(&b.log), vec![50.0, 60.0]);
}

fn percentile(sorted: &[f64], p: f64) -> f64 {
    let i = ((sorted.len() as f64 - 1.0) * p).round() as usize;
    sorted[i.min(sorted.len() - 1)]
}

/// BENCHMARKS.md's fleet numbers: the fleet stop's latency for 1, 4 and 16
/// bridges, and command round trips through Zenoh and the local socket of
/// the same bridge. `cargo test --release -p motorwire-cli --features fleet --test fleet --
/// --ignored --nocapture fleet_numbers`
#[test]
#[ignore = "a benchmark: run it by name, in release"]
fn fleet_numbers() {
    let dir = scratch("numbers");
    let port = free_port();
    let _router = router(port);
    let controller = client(port);
    let results = controller
        .declare_subscriber("motorwire/*/estop/result")
        .wait()
        .unwrap();
    let sock = dir.join("b00.sock");
    let sock_input = format!("unix:{}", sock.display());
    let mut bridges: Vec<Bridge> = Vec::new();
    println!(
        "| bridges | stops | put → last stop result, median | p99 | max | bridges' line → last stop frame, median of the slowest | p99 |"
    );
    println!("| --- | --- | --- | --- | --- | --- | --- |");
    for (n, trials) in [(1usize, 200usize), (4, 200), (16, 100)] {
        while bridges.len() < n {
            let name = format!("b{:02}", bridges.len());
            let extra: Vec<&str> = if bridges.is_empty() {
                vec!["--input", &sock_input]
            } else {
                vec![]
            };
            bridges.push(bridge(&dir, port, &name, &extra));
        }
        let names: Vec<String> = (0..n).map(|i| format!("b{i:02}")).collect();
        let want: Vec<&str> = names.iter().map(String::as_str).collect();
        wait_alive(&controller, &want, Duration::from_secs(60));
        thread::sleep(Duration::from_secs(1));
        let mut put_to_last = Vec::new();
        let mut frame = Vec::new();
        for _ in 0..trials {
            let t0 = Instant::now();
            controller
                .put("motorwire/fleet/estop", "{}")
                .wait()
                .unwrap();
            let mut slowest = 0u64;
            for _ in 0..n {
                let s = results
                    .recv_timeout(Duration::from_secs(10))
                    .unwrap()
                    .unwrap();
                let v: Value = serde_json::from_str(&s.payload().try_to_string().unwrap()).unwrap();
                slowest = slowest.max(v["stop_latency_us"].as_u64().unwrap());
            }
            put_to_last.push(t0.elapsed().as_secs_f64() * 1000.0);
            frame.push(slowest as f64 / 1000.0);
            for r in &names {
                let replies = query(
                    &controller,
                    r,
                    r#"{"emergency_stop": false}"#,
                    Duration::from_secs(5),
                );
                assert_eq!(replies[0]["released"], json!(true), "{replies:?}");
            }
            thread::sleep(Duration::from_millis(10));
        }
        put_to_last.sort_by(f64::total_cmp);
        frame.sort_by(f64::total_cmp);
        println!(
            "| {n} | {trials} | {:.2} ms | {:.2} ms | {:.2} ms | {:.3} ms | {:.3} ms |",
            percentile(&put_to_last, 0.5),
            percentile(&put_to_last, 0.99),
            put_to_last[put_to_last.len() - 1],
            percentile(&frame, 0.5),
            percentile(&frame, 0.99),
        );
    }
    // Round trips, one at a time, for 3 s each, to bridge b00 (16 bridges
    // running): through Zenoh (controller → router → bridge and back) and
    // through its local socket.
    let line = r#"{"query":"limits","motor_id":"elbow"}"#;
    let window = Duration::from_secs(3);
    let t0 = Instant::now();
    let mut zenoh_n = 0u64;
    while t0.elapsed() < window {
        let replies = query(&controller, "b00", line, Duration::from_secs(5));
        assert_eq!(replies[0]["ok"], json!(true), "{replies:?}");
        zenoh_n += 1;
    }
    let zenoh_rate = zenoh_n as f64 / t0.elapsed().as_secs_f64();
    let mut s = std::os::unix::net::UnixStream::connect(&sock).unwrap();
    let mut r = BufReader::new(s.try_clone().unwrap());
    let t0 = Instant::now();
    let mut unix_n = 0u64;
    while t0.elapsed() < window {
        use std::io::Write;
        writeln!(s, "{line}").unwrap();
        loop {
            let mut l = String::new();
            r.read_line(&mut l).unwrap();
            if l.starts_with(r#"{"ok""#) {
                break;
            }
        }
        unix_n += 1;
    }
    let unix_rate = unix_n as f64 / t0.elapsed().as_secs_f64();
    println!();
    println!("| path (16 bridges running) | round trips | per second |");
    println!("| --- | --- | --- |");
    println!("| Zenoh query (controller → router → bridge → back) | {zenoh_n} | {zenoh_rate:.0} |");
    println!("| local socket (unix:) | {unix_n} | {unix_rate:.0} |");
}

/// The control for the test above: the same deployment with its access
/// control turned off lets the observer move the joint, so it is the
/// rules, not the TLS or the passwords, that keep it out.
#[test]
fn without_the_access_control_the_observer_could_move_a_joint() {
    let dir = scratch("no-acl");
    std::fs::write(
        dir.join("passwords.txt"),
        "controller:controller-secret\nbridge:bridge-secret\nobserver:observer-secret\n",
    )
    .unwrap();
    let port = free_port();
    let router_doc = deployment("router", &dir, port);
    let open_doc = router_doc.replacen("enabled: true", "enabled: false", 1);
    assert_ne!(open_doc, router_doc);
    let _router = zenoh::open(zenoh::Config::from_json5(&open_doc).unwrap())
        .wait()
        .unwrap();
    let b = bridge_with(&dir, &deployment("bridge", &dir, port), "open", &[]);
    let observer = try_open(&deployment("observer", &dir, port)).unwrap();
    wait_alive(&observer, &["open"], Duration::from_secs(20));
    wait_ready(&b);
    let (replies, tries) = query_to_completion(
        &observer,
        "motorwire/open/cmd/controller",
        &move_line("elbow", 50.0, "observer"),
        Duration::from_secs(10),
    );
    let seen: Vec<Value> = std::iter::from_fn(|| b.events.try_recv().ok())
        .filter(|v| v.get("feedback").is_none())
        .collect();
    assert_eq!(
        replies.len(),
        2,
        "{replies:?} after {tries} tries; events {seen:?}"
    );
    assert_eq!(replies[0]["ok"], json!(true));
    assert_eq!(replies[1]["arrived"], json!(true));
    assert_eq!(moves(&b.log), vec![50.0]);
}
