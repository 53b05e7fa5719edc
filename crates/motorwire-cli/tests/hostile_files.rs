//! Every file the CLI reads, made hostile: `/dev/zero` (endless, no
//! newline), bytes that are not UTF-8, lines over the limit. Each run ends
//! quickly with a clear error and exit status, in 1 GiB of address space
//! (a regression fails on its time limit or its memory, never hangs), and
//! `candump decode` prints each line as it comes.
#![allow(clippy::unwrap_used, clippy::panic, clippy::indexing_slicing)]

mod common;

use std::fs::File;
use std::io::{BufRead, BufReader, Read, Write};
use std::process::{Child, Command, Output, Stdio};
use std::sync::mpsc;
use std::thread;
use std::time::{Duration, Instant};

/// `motorwire ARGS` with stdin from `stdin` (`None`: empty), in at most
/// 1 GiB of address space, killed and failed after `limit`.
fn run_bounded(args: &[&str], stdin: Option<File>, limit: Duration) -> Output {
    let child = Command::new("sh")
        .arg("-c")
        .arg(r#"ulimit -v 1048576 && exec "$0" "$@""#)
        .arg(env!("CARGO_BIN_EXE_motorwire"))
        .args(args)
        .current_dir(common::root())
        .stdin(stdin.map_or_else(Stdio::null, Stdio::from))
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    wait_bounded(child, limit, args)
}

fn wait_bounded(mut child: Child, limit: Duration, what: &[&str]) -> Output {
    let end = Instant::now() + limit;
    // Drain the pipes (those not taken) while waiting, so a chatty child
    // cannot block.
    let drain = |pipe: Option<Box<dyn Read + Send>>| {
        thread::spawn(move || {
            let mut b = Vec::new();
            if let Some(mut p) = pipe {
                let _ = p.read_to_end(&mut b);
            }
            b
        })
    };
    let out = drain(child.stdout.take().map(|p| Box::new(p) as _));
    let err = drain(child.stderr.take().map(|p| Box::new(p) as _));
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if Instant::now() > end {
            let _ = child.kill();
            let _ = child.wait();
            panic!("motorwire {what:?} still running after {limit:?}");
        }
        thread::sleep(Duration::from_millis(10));
    };
    Output {
        status,
        stdout: out.join().unwrap(),
        stderr: err.join().unwrap(),
    }
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

fn zero() -> Option<File> {
    Some(File::open("/dev/zero").unwrap())
}

#[test]
fn dev_zero_as_every_file_argument_ends_at_once_with_a_clear_error() {
    let limit = Duration::from_secs(20);
    // (args, stdin, exit status, what stdout or stderr must say)
    let cases: [(&[&str], Option<File>, i32, &str); 10] = [
        (
            &["bridge", "--map", "/dev/zero", "--bus", "sim"],
            None,
            2,
            "--map /dev/zero: the file is over 1048576 bytes, the limit",
        ),
        (
            &["candump", "decode", "--wire", "v2.0", "/dev/zero"],
            None,
            2,
            "reading /dev/zero: line 1 is over 4096 bytes and has no end within 16 MiB more",
        ),
        (
            &["candump", "decode", "--compact", "-"],
            zero(),
            2,
            "reading -: line 1 is over 4096 bytes",
        ),
        (
            &["validate", "/dev/zero"],
            None,
            1,
            "[document-too-large]  the document is over 1048576 bytes, the maximum",
        ),
        (
            &["validate", "--lines", "--max-size", "16777216", "/dev/zero"],
            None,
            2,
            "/dev/zero: line 1 is over 16777216 bytes and has no end within 16 MiB more",
        ),
        (
            &["validate", "--max-size", "16777217", "/dev/zero"],
            None,
            2,
            "16777217 is over 16777216 (16 MiB), the largest line or document motorwire reads",
        ),
        (
            &["validate", "--max-size", "18446744073709551615", "-"],
            zero(),
            2,
            "is over 16777216 (16 MiB)",
        ),
        (
            &["compact", "decode", "--names", "/dev/zero"],
            None,
            2,
            "/dev/zero: the file is over 1048576 bytes, the limit",
        ),
        (
            &["irpc", "decode", "--wire", "v2.0"],
            zero(),
            2,
            "reading standard input: line 1 is over 1048576 bytes",
        ),
        (
            &["plan"],
            zero(),
            2,
            "reading standard input: line 1 is over 1048576 bytes",
        ),
    ];
    for (args, stdin, status, says) in cases {
        let started = Instant::now();
        let out = run_bounded(args, stdin, limit);
        let (stdout, stderr) = (text(&out.stdout), text(&out.stderr));
        assert_eq!(
            out.status.code(),
            Some(status),
            "{args:?}\nstdout: {stdout}\nstderr: {stderr}"
        );
        assert!(
            stdout.contains(says) || stderr.contains(says),
            "{args:?}: expected {says:?}\nstdout: {stdout}\nstderr: {stderr}"
        );
        eprintln!("{args:?}: {:?}", started.elapsed());
    }
}

#[test]
fn candump_decode_prints_each_line_while_its_input_stays_open() {
    let log =
        std::fs::read_to_string(common::root().join("fixtures/candump/vcan0-session.log")).unwrap();
    let good: Vec<&str> = log.lines().take(2).collect();
    let mut child = common::spawn(&["candump", "decode", "--wire", "v2.0", "-"]);
    let mut stdin = child.stdin.take().unwrap();
    let (tx, rx) = mpsc::channel();
    let stdout = BufReader::new(child.stdout.take().unwrap());
    thread::spawn(move || {
        for line in stdout.lines() {
            if tx.send(line.unwrap()).is_err() {
                return;
            }
        }
    });
    let next = || -> serde_json::Value {
        let line = rx
            .recv_timeout(Duration::from_secs(10))
            .expect("a decoded line while stdin is still open");
        serde_json::from_str(&line).unwrap()
    };
    writeln!(stdin, "{}", good[0]).unwrap();
    stdin.flush().unwrap();
    let first = next();
    assert_eq!(first["line"], 1, "{first}");
    assert!(first["message"].is_object(), "{first}");
    // One byte that is not UTF-8 costs its line; an over-long line is one
    // error line; the next line decodes.
    stdin.write_all(b"(1.000000) vcan0 010##5\xff\n").unwrap();
    stdin.write_all(&vec![b'7'; 10_000]).unwrap();
    writeln!(stdin, "\n{}", good[1]).unwrap();
    stdin.flush().unwrap();
    let bad = next();
    assert_eq!(
        (bad["line"].as_u64(), bad["error"].as_str()),
        (Some(2), Some("the line is not UTF-8"))
    );
    let long = next();
    assert_eq!(
        (long["line"].as_u64(), long["error"].as_str()),
        (Some(3), Some("the line is over 4096 bytes"))
    );
    let after = next();
    assert_eq!(after["line"], 4, "{after}");
    assert!(after["message"].is_object(), "{after}");
    drop(stdin);
    let out = wait_bounded(child, Duration::from_secs(10), &["candump", "decode"]);
    assert_eq!(out.status.code(), Some(1), "a line did not decode");
}

#[test]
fn validate_lines_one_bad_byte_costs_one_line() {
    let path =
        std::env::temp_dir().join(format!("motorwire-bad-byte-{}.jsonl", std::process::id()));
    let good =
        r#"{"motor_id":"elbow","timestamp":1704067200000,"control_mode":"position","setpoint":10}"#;
    let mut bytes = Vec::new();
    bytes.extend_from_slice(good.as_bytes());
    bytes.extend_from_slice(b"\n{\"motor_id\":\"el\xffbow\"}\n");
    bytes.extend_from_slice(good.as_bytes());
    bytes.push(b'\n');
    std::fs::write(&path, &bytes).unwrap();
    let file = path.to_str().unwrap();
    let out = run_bounded(
        &["validate", "--lines", "--format", "json", file],
        None,
        Duration::from_secs(20),
    );
    let _ = std::fs::remove_file(&path);
    assert_eq!(out.status.code(), Some(1), "{}", text(&out.stderr));
    let results: Vec<serde_json::Value> = text(&out.stdout)
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    let valid: Vec<(u64, bool)> = results
        .iter()
        .map(|r| (r["line"].as_u64().unwrap(), r["valid"].as_bool().unwrap()))
        .collect();
    assert_eq!(valid, [(1, true), (2, false), (3, true)]);
    assert_eq!(
        results[1]["errors"][0]["rule"], "json-syntax",
        "{}",
        results[1]
    );
}

/// The bridge fed `/dev/zero`: the endless line is given up after 16 MiB,
/// the joints are stopped, and the exit status says the input failed.
#[test]
fn the_bridge_gives_up_an_endless_standard_input() {
    let out = run_bounded(
        &common::sim_bridge(&[]),
        Some(File::open("/dev/zero").unwrap()),
        Duration::from_secs(20),
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("reading standard input: a line over 1048576 bytes has no end within 16 MiB more; the input was given up; the joints were stopped"),
        "{err}"
    );
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains(r#""event":"stopped""#), "{text}");
}
