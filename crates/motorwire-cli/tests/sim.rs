//! `motorwire sim orion` and `motorwire sim compact`, run as a user runs them.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing
)]

mod common;

use std::io::{BufRead, BufReader, Write};
use std::process::Output;
use std::time::{Duration, Instant};

fn sim(args: &[&str], stdin: &str) -> Output {
    let mut all = vec!["sim", "orion"];
    all.extend_from_slice(args);
    common::run(&all, stdin.as_bytes())
}

fn lines(bytes: &[u8]) -> Vec<String> {
    String::from_utf8(bytes.to_vec())
        .unwrap()
        .lines()
        .map(str::to_owned)
        .collect()
}

#[test]
fn answers_each_command_line_and_ignores_what_is_not_one() {
    let input = [
        r#"{"ID":32,"MODE":1,"DATA":{"TRM":200,"LAA":1,"UAA":1,"AEM":400}}"#,
        "this is not JSON",
        r#"{"ID":32,"MODE":1,"DATA":{"TRM":5,"XYZ":1}}"#,
        r#"{"ID":32,"MODE":1,"DATA":{"GHS":-999}}"#,
        r#"{"ID":32,"MODE":2,"DATA":3}"#,
        r#"{"ID":32,"MODE":2,"DATA":0}"#,
        r#"{"ID":32,"MODE":1,"DATA":{}}"#,
    ]
    .join("\n");
    let out = sim(&["--beacon-interval", "0"], &format!("{input}\n"));
    assert_eq!(out.status.code(), Some(0));
    assert_eq!(
        lines(&out.stdout),
        [
            r#"{"ID":32}"#,
            r#"{"ID":32,"MODE":1,"DATA":{"TRMF":[200,35,0],"LAAF":[1,50,0],"UAAF":[1,50,0],"AEMF":[400,65,0],"GVMF":[0,0,0],"GRMF":[0,0,0],"GHSF":[0,0,0]}}"#,
            r#"{"ID":32,"MODE":1,"DATA":{"TRMF":[200,35,0],"LAAF":[1,50,0],"UAAF":[1,50,0],"AEMF":[400,65,0],"GVMF":[0,0,0],"GRMF":[0,0,0],"GHSF":[-180,10,0]}}"#,
            r#"{"ID":32,"MODE":2,"DATA":{"CMDF":1}}"#,
            r#"{"ID":32,"MODE":2,"DATA":{"CMDF":0}}"#,
            r#"{"ID":32,"MODE":1,"DATA":{"TRMF":[0,0,0],"LAAF":[0,0,0],"UAAF":[0,0,0],"AEMF":[0,0,0],"GVMF":[0,0,0],"GRMF":[0,0,0],"GHSF":[0,0,0]}}"#,
        ]
    );
    assert_eq!(
        lines(&out.stderr),
        [
            "motorwire sim orion: line 2: not valid JSON: expected ident at line 1 column 2; ignored",
            r#"motorwire sim orion: line 3: unknown key "XYZ" in DATA; ignored"#,
            "motorwire sim orion: line 4: GHS -999 is outside [-180, 180]; clamped to -180",
        ]
    );
}

#[test]
fn example_keys_on_request() {
    let out = sim(
        &["--beacon-interval", "0", "--feedback-keys", "example"],
        "{\"ID\":32,\"MODE\":1,\"DATA\":{\"GRM\":-20}}\n",
    );
    assert_eq!(
        lines(&out.stdout),
        [
            r#"{"ID":32}"#,
            r#"{"ID":32,"MODE":1,"DATA":{"TRM":[0,0,0],"LAA":[0,0,0],"UAA":[0,0,0],"AEM":[0,0,0],"GVM":[0,0,0],"GRM":[-20,8,0],"GHS":[0,0,0]}}"#,
        ]
    );
}

#[test]
fn the_beacon_repeats_until_the_first_command_and_stops_after_it() {
    let mut child = common::spawn(&["sim", "orion", "--beacon-interval", "20"]);
    let mut stdin = child.stdin.take().unwrap();
    let mut stdout = BufReader::new(child.stdout.take().unwrap());
    let mut read_line = || {
        let mut s = String::new();
        stdout.read_line(&mut s).unwrap();
        s.trim_end().to_owned()
    };
    // Three beacons arrive on their own; an invalid line does not stop them.
    for _ in 0..3 {
        assert_eq!(read_line(), r#"{"ID":32}"#);
    }
    writeln!(stdin, "{{\"ID\":7}}").unwrap();
    for _ in 0..2 {
        assert_eq!(read_line(), r#"{"ID":32}"#);
    }
    writeln!(stdin, r#"{{"ID":32,"MODE":2,"DATA":1}}"#).unwrap();
    // Beacons sent before the command was read may still be in the pipe.
    let answer = loop {
        let line = read_line();
        if line != r#"{"ID":32}"# {
            break line;
        }
    };
    assert_eq!(answer, r#"{"ID":32,"MODE":2,"DATA":{"CMDF":1}}"#);
    // No beacon after the first command: the next line is the next answer.
    let quiet = Instant::now();
    std::thread::sleep(Duration::from_millis(100));
    writeln!(stdin, r#"{{"ID":32,"MODE":2,"DATA":2}}"#).unwrap();
    assert_eq!(read_line(), r#"{"ID":32,"MODE":2,"DATA":{"CMDF":1}}"#);
    assert!(quiet.elapsed() >= Duration::from_millis(100));
    drop(stdin);
    let out = child.wait_with_output().unwrap();
    assert_eq!(out.status.code(), Some(0));
    assert!(out.stdout.is_empty());
    assert_eq!(
        lines(&out.stderr),
        [
            "motorwire sim orion: line 1: ID 7 is not the arm controller's 32 (7 is in the drive controllers' 0-31 range); ignored"
        ]
    );
}

#[test]
fn sim_compact_refuses_bad_arguments_clearly() {
    let refused = |args: &[&str], says: &str| {
        let mut all = vec!["sim", "compact"];
        all.extend_from_slice(args);
        let out = common::run(&all, b"");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(stderr.contains(says), "{args:?}: {stderr}");
    };
    let bus = ["--bus", "socketcan:vcan0"];
    let with = |extra: &[&'static str]| -> Vec<&'static str> {
        let mut v = bus.to_vec();
        v.extend_from_slice(extra);
        v
    };
    refused(
        &with(&["--node", "0x800", "--name", "gripper_axis"]),
        "above 0x7FF",
    );
    refused(
        &with(&["--node", "0x20", "--name", "gripper axis"]),
        "is not a motor id",
    );
    refused(&with(&["--node", "0x20"]), "--name");
    refused(
        &with(&["--node", "0x20", "--name", "g", "--rate-hz", "2000"]),
        "--rate-hz",
    );
    // The configuration is checked before the bus is opened.
    refused(
        &with(&["--node", "0x420", "--name", "gripper_axis"]),
        "feedback_node: 0x420 is the node itself",
    );
    refused(
        &with(&[
            "--node",
            "0x20",
            "--name",
            "g",
            "--min-position",
            "10",
            "--max-position",
            "-10",
        ]),
        "min_position and max_position",
    );
    refused(
        &["--bus", "can0", "--node", "0x20", "--name", "g"],
        "expected socketcan:IFACE",
    );
    refused(
        &[
            "--bus",
            "socketcan:nosuch0",
            "--node",
            "0x20",
            "--name",
            "g",
        ],
        "no CAN interface named \"nosuch0\"",
    );
}

/// `motorwire sim servos` puts its servos on a pseudo-terminal linked at
/// `--pty`: a ping written there is answered by that servo, a read of its
/// model number with 777 (an STS3215), through the terminal as a serial
/// port carries them; a bad model is refused by name.
#[test]
fn sim_servos_answer_on_their_pseudo_terminal() {
    use std::io::Read;
    let dir = std::env::temp_dir().join(format!("mw-sim-servos-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (mut child, link_s) = common::sim_servos(
        &dir,
        "so101",
        &["--protocol", "scs0", "--model", "sts3215", "--ids", "1,2"],
    );
    let link_s = link_s.as_str();
    let mut port = serialport::new(link_s, 1_000_000)
        .timeout(Duration::from_millis(500))
        .open_native()
        .unwrap();
    let mut exchange = |packet: &[u8], answer_len: usize| -> Vec<u8> {
        port.write_all(packet).unwrap();
        let mut got = vec![0; answer_len];
        port.read_exact(&mut got).unwrap();
        got
    };
    // Ping servo 2; read 2 bytes of servo 1 at 3 (Model_Number).
    assert_eq!(
        exchange(&[0xFF, 0xFF, 0x02, 0x02, 0x01, 0xFA], 6),
        [0xFF, 0xFF, 0x02, 0x02, 0x00, 0xFB]
    );
    assert_eq!(
        exchange(&[0xFF, 0xFF, 0x01, 0x04, 0x02, 0x03, 0x02, 0xF3], 8),
        [0xFF, 0xFF, 0x01, 0x04, 0x00, 0x09, 0x03, 0xEE]
    );
    child.kill().unwrap();
    let _ = child.wait();
    // A file that is not a link is left alone.
    let file = dir.join("precious");
    std::fs::write(&file, "keep").unwrap();
    let o = common::run(
        &[
            "sim",
            "servos",
            "--protocol",
            "scs0",
            "--model",
            "sts3215",
            "--ids",
            "1",
            "--pty",
            file.to_str().unwrap(),
        ],
        b"",
    );
    assert_eq!(o.status.code(), Some(2));
    assert_eq!(std::fs::read_to_string(&file).unwrap(), "keep");
    assert!(String::from_utf8_lossy(&o.stderr).contains("exists and is not a link"));
    let _ = std::fs::remove_dir_all(&dir);
    let o = common::run(
        &[
            "sim",
            "servos",
            "--protocol",
            "scs0",
            "--model",
            "sts9999",
            "--ids",
            "1",
            "--pty",
            "/nonexistent/x",
        ],
        b"",
    );
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains(
        "unknown model \"sts9999\" (sts3215, scs0009, xl330-m288, xl430-w250, xm430-w350)"
    ));
}
