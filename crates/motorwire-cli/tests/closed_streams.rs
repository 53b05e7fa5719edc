//! A closed stderr or stdout (a pipe whose reader has gone: a closed
//! terminal, `| head`) never panics a subcommand (exit status 101): a
//! closed stderr is ignored, a closed stdout ends the subcommand with a
//! non-zero status of its own.
#![allow(clippy::unwrap_used, clippy::panic)]

mod common;

use std::io;
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

/// A pipe whose read end is already closed: every write to it fails (EPIPE).
fn closed_pipe() -> Stdio {
    let (reader, writer) = io::pipe().unwrap();
    drop(reader);
    Stdio::from(writer)
}

enum Closed {
    Stdout,
    Stderr,
}

fn run(args: &[&str], closed: &Closed) -> Output {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_motorwire"));
    cmd.args(args)
        .current_dir(common::root())
        .stdin(Stdio::null());
    match closed {
        Closed::Stdout => cmd.stdout(closed_pipe()).stderr(Stdio::piped()),
        Closed::Stderr => cmd.stdout(Stdio::piped()).stderr(closed_pipe()),
    };
    let mut child = cmd.spawn().unwrap();
    let end = Instant::now() + Duration::from_secs(60);
    while child.try_wait().unwrap().is_none() {
        if Instant::now() > end {
            let _ = child.kill();
            panic!("motorwire {args:?} still running");
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    child.wait_with_output().unwrap()
}

#[test]
fn a_closed_stderr_is_not_a_panic() {
    let cases: [(&[&str], i32); 6] = [
        (&["validate", "/no/such/file.json"], 2),
        (&["validate", "--lines", "/dev/zero"], 2),
        (
            &["candump", "decode", "--wire", "v2.0", "/no/such/file.log"],
            2,
        ),
        (&["bridge", "--map", "/no/such/map.toml", "--bus", "sim"], 2),
        (&["compact", "decode", "--names", "/no/such/names"], 2),
        (&["plan", "--sample", "-1"], 2),
    ];
    for (args, status) in cases {
        let out = run(args, &Closed::Stderr);
        assert_eq!(out.status.code(), Some(status), "{args:?}");
    }
}

#[test]
fn a_closed_stdout_ends_with_a_non_zero_status_not_a_panic() {
    let cases: [&[&str]; 4] = [
        &[
            "validate",
            "fixtures/wia/valid/doc-3.2-multi-axis-command.json",
        ],
        &[
            "candump",
            "decode",
            "--wire",
            "v2.0",
            "fixtures/candump/vcan0-session.log",
        ],
        &["demo", "--svg", "/dev/null"],
        &["sim", "orion", "--beacon-interval", "0"],
    ];
    for args in cases {
        let out = run(args, &Closed::Stdout);
        assert_eq!(
            out.status.code(),
            Some(2),
            "{args:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
}
