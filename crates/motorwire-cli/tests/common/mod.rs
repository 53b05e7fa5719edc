//! Running the `motorwire` binary as a user does, from the repository root.
#![allow(dead_code, unreachable_pub, clippy::unwrap_used, clippy::panic)] // each test file uses a part

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};

/// The repository root (fixtures are named relative to it).
pub fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// `motorwire ARGS` with its three standard streams piped, running.
pub fn spawn(args: &[&str]) -> Child {
    Command::new(env!("CARGO_BIN_EXE_motorwire"))
        .args(args)
        .current_dir(root())
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap()
}

/// `motorwire ARGS` fed `stdin` (then end of input), run to its end.
pub fn run(args: &[&str], stdin: &[u8]) -> Output {
    let mut child = spawn(args);
    let mut pipe = child.stdin.take().unwrap();
    // A command that refuses its arguments, or stops reading early, may
    // exit before taking all of its input.
    let _ = pipe.write_all(stdin);
    drop(pipe);
    child.wait_with_output().unwrap()
}

/// A process's resident memory, in KiB.
pub fn rss_kib(pid: u32) -> u64 {
    std::fs::read_to_string(format!("/proc/{pid}/status"))
        .unwrap()
        .lines()
        .find_map(|l| l.strip_prefix("VmRSS:"))
        .and_then(|v| v.trim().trim_end_matches(" kB").trim().parse().ok())
        .unwrap()
}

/// Now, in Unix milliseconds (a WIA command's timestamp).
pub fn now_ms() -> u128 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .as_millis()
}

/// The lines a child process writes on its standard output, read as they
/// come (a test waits for the line it needs rather than guessing how slow
/// the machine is).
pub struct Lines {
    rx: std::sync::mpsc::Receiver<String>,
    reader: std::thread::JoinHandle<()>,
    /// Every line read so far.
    pub seen: Vec<String>,
}

impl Lines {
    /// Reads `stdout` on a thread of its own.
    pub fn of(stdout: std::process::ChildStdout) -> Self {
        use std::io::BufRead;
        let (tx, rx) = std::sync::mpsc::channel();
        let reader = std::thread::spawn(move || {
            for line in std::io::BufReader::new(stdout).lines() {
                let Ok(line) = line else { break };
                if tx.send(line).is_err() {
                    break;
                }
            }
        });
        Self {
            rx,
            reader,
            seen: Vec::new(),
        }
    }

    /// Reads until a line satisfies `done`, within `limit`; panics with
    /// every line read (`what`: what it waited for) when none did.
    pub fn until(&mut self, what: &str, limit: std::time::Duration, done: impl Fn(&str) -> bool) {
        let deadline = std::time::Instant::now() + limit;
        while !self.seen.last().is_some_and(|l| done(l)) {
            let left = deadline.saturating_duration_since(std::time::Instant::now());
            match self.rx.recv_timeout(left) {
                Ok(line) => self.seen.push(line),
                Err(_) => panic!("no {what} within {limit:?}: {:?}", self.seen),
            }
        }
    }

    /// Every line, once the process has closed its output.
    pub fn finish(mut self) -> Vec<String> {
        let _ = self.reader.join();
        self.seen.extend(self.rx.try_iter());
        self.seen
    }
}

/// `motorwire bridge` on the demo map and the simulated bus, then `extra`:
/// the arguments of a bridge run as the README's first bridge command runs
/// it.
pub fn sim_bridge<'a>(extra: &[&'a str]) -> Vec<&'a str> {
    let mut args = vec![
        "bridge",
        "--map",
        "fixtures/maps/demo-arm.toml",
        "--bus",
        "sim",
    ];
    args.extend_from_slice(extra);
    args
}

/// Spawns `motorwire sim servos ARGS --pty DIR/NAME` and waits for its
/// link: the child and the link's path.
pub fn sim_servos(dir: &Path, name: &str, args: &[&str]) -> (Child, String) {
    let link = dir.join(name);
    let link_s = link.to_str().unwrap().to_owned();
    let mut all = vec!["sim", "servos"];
    all.extend_from_slice(args);
    all.extend_from_slice(&["--pty", &link_s]);
    let child = spawn(&all);
    let start = std::time::Instant::now();
    while !link.exists() && start.elapsed() < std::time::Duration::from_secs(10) {
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    (child, link_s)
}
