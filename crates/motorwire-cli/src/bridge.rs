//! `motorwire bridge`: WIA JSON lines in, iRPC frames on a CAN bus out.

use std::io::{self, Write};
use std::sync::atomic::{AtomicBool, AtomicU8, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::thread;
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use motorwire_bridge::sim::{ExecutionLog, RealTimeArm};
use motorwire_bridge::{Bridge, BridgeConfig, InputSender, Output, Runner};
use motorwire_can::client::ClientConfig;
use motorwire_can::{Faults, SimConfig};
use motorwire_sim::Execution;
use motorwire_translate::BusMap;

use crate::console::note;

#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// The bus map (TOML): which motor is which joint, and its limits.
    #[arg(long, value_name = "FILE")]
    map: String,
    /// `sim` (the map's devices simulated in this process, in real time:
    /// CAN devices on an in-memory bus, serial servos on in-memory ports),
    /// `socketcan:IFACE` (a Linux CAN-FD interface, e.g. vcan0),
    /// `fdcanusb:PATH` (mjbots' fdcanusb adapter, e.g. /dev/ttyACM0) or
    /// `none` (no CAN bus: a map of serial servos alone). Except with
    /// `sim`, the map's serial servos are on the serial ports it names.
    #[arg(long, value_name = "BUS")]
    bus: String,
    /// Where lines come from: `-` (stdin; the bridge stops at its end),
    /// `unix:PATH` (a local socket only this user can connect to: the
    /// recommended local input), `tcp:ADDR` (a loopback address, e.g.
    /// tcp:127.0.0.1:7878, with `--token-file`) or `none` (the fleet's
    /// commands alone). With a socket or `none` the bridge runs until
    /// interrupted; each client gets its own results, and every client the
    /// feedback and events. Default: `-`, or `none` with `--zenoh`.
    #[arg(long, value_name = "INPUT")]
    input: Option<String>,
    /// A file holding the token (one line, at least 16 bytes, mode 0600)
    /// that a connection's first line must be. Required with `tcp:`.
    #[arg(long, value_name = "FILE")]
    token_file: Option<String>,
    /// Accept TCP connections without a token: any local process can then
    /// move the motors.
    #[arg(long)]
    insecure_no_auth: bool,
    /// Authenticated connections served at once; more are refused with an
    /// error line (a stop from one more is still taken). Connections still
    /// authenticating do not count.
    #[arg(long, value_name = "N", default_value_t = 8)]
    max_clients: usize,
    /// How long a new connection has to send its first line (the token,
    /// or without one its first command) before it is closed.
    #[arg(long, value_name = "MS", default_value_t = 1000)]
    auth_timeout_ms: u64,
    /// Output lines a client may have waiting. A client that reads more
    /// slowly than the bridge answers is slowed: once its lines waiting and
    /// twice the results it is owed reach half of this, its lines wait (a
    /// stop it sends within 1,024 lines of them goes ahead at once) until
    /// it is down to a quarter, and it misses feedback meanwhile. One that reads nothing for 5 s while
    /// behind, or lets this many pile up, has stopped reading: it is
    /// disconnected and its pending commands cancelled. At least 2048: a
    /// stop can answer every line in progress (up to 1024, and 256 more on
    /// their way) at once.
    #[arg(long, value_name = "LINES", default_value_t = 4096)]
    client_queue: usize,
    /// Feedback lines per joint per second (0: none).
    #[arg(long, value_name = "N", default_value_t = 10.0)]
    feedback_hz: f64,
    /// Subscribe the v2.1 and v2.2 joints to their TelemetryStream at N Hz
    /// (0: none): their feedback then carries acceleration, torque,
    /// current, voltage, temperature, power and load.
    #[arg(long, value_name = "N", default_value_t = 0)]
    telemetry_hz: u16,
    /// Do not configure and activate the joints on startup.
    #[arg(long)]
    no_activate: bool,
    /// A joint silent for this many ms is reported offline.
    #[arg(long, value_name = "MS", default_value_t = 500)]
    offline_after: u64,
    /// How long to wait for a joint's Ack or Nack before sending again (ms).
    #[arg(long, value_name = "MS", default_value_t = 100)]
    ack_timeout: u64,
    /// How many times to send again before reporting a command failed.
    #[arg(long, value_name = "N", default_value_t = 3)]
    retries: u8,
    /// WIA §10.1's clock skew: a command whose timestamp is further than
    /// this many ms in the past or future is refused `stale` (0: not checked).
    #[arg(long, value_name = "MS", default_value_t = motorwire_bridge::DEFAULT_MAX_AGE_MS)]
    max_age: u64,
    /// The longest input line taken, in bytes (at most 16777216, 16 MiB),
    /// on every input: a longer one is refused (`unreadable`), and taken
    /// as a stop if it names `emergency_stop`. The same limit and default
    /// as `motorwire validate --max-size`.
    #[arg(long, value_name = "BYTES", default_value_t = motorwire_bridge::DEFAULT_MAX_LINE,
          value_parser = crate::validate::parse_max_size)]
    max_size: usize,
    /// Take command lines with members their WIA schema does not name,
    /// reporting each as a loss (`dropped`). Without it such a line is
    /// refused `invalid`, naming the member and the nearest known one.
    #[arg(long)]
    allow_unknown_members: bool,
    /// With `--bus sim`: faults on the simulated bus, as
    /// `drop=R,duplicate=R,corrupt=R,delay=R,reorder=R,max-delay-ms=MS`
    /// (rates 0 to 1, any subset; e.g. `drop=0.1,duplicate=0.1,reorder=0.1`).
    #[arg(long, value_name = "SPEC", default_value = "")]
    sim_faults: String,
    /// With `--bus sim`: the fault generator's seed (the same seed and
    /// traffic give the same faults).
    #[arg(long, value_name = "N", default_value_t = 0)]
    sim_seed: u64,
    /// With `--bus sim`: write every request a simulated joint executes to
    /// FILE, one JSON line each: `{"joint","node","source","msg_id","payload","answer","at_us"}`.
    #[arg(long, value_name = "FILE")]
    sim_log: Option<String>,
    /// The Orion arm controller of the map's Orion motors: `serial:PATH[@BAUD]`
    /// (USB CDC or UART, default 115200 baud, 8N1), `tcp:ADDR`, or `sim`
    /// (motorwire's simulated controller, in this process). Without it
    /// the map's Orion motors are refused.
    #[arg(long, value_name = "LINK")]
    orion: Option<String>,
    /// The bridge's own iRPC node id (its frames' CAN id).
    #[arg(long, value_parser = crate::sim::parse_node, default_value = "0x0000")]
    node: u16,
    /// Record the session into DIR: every CAN frame to `frames.log` (as
    /// `candump -L` writes it), every input and output line, frame and
    /// Orion line to `lines.jsonl`, both clocks; never making the bridge
    /// wait (what cannot be written in time is dropped and counted). A
    /// recording that lost records is marked incomplete in its
    /// `session.json`, and the bridge then exits with status 73.
    #[arg(long, value_name = "DIR")]
    record: Option<String>,
    /// With `--record`: the most the recording holds on disk (MiB); each
    /// file is rotated at a quarter of it.
    #[arg(long, value_name = "MIB", default_value_t = 100)]
    record_max_mb: u64,
    /// Serve a live view of the session at ADDR (e.g. 127.0.0.1:8080; port
    /// 0 picks one, printed on standard error): a page plotting each
    /// motor's last 30 s with its target and limits, its state, the events
    /// as marks and the input lines as they come. Read-only. A loopback
    /// address unless `--view-token-file` is given: then the page is opened
    /// as http://ADDR/?token=TOKEN.
    #[arg(long, value_name = "ADDR")]
    view: Option<std::net::SocketAddr>,
    /// A file holding the live view's own token (one line, at least 16
    /// bytes, mode 0600): every request to the view then needs
    /// `?token=TOKEN`. Required for a `--view` address other than loopback.
    /// Never the control token (`--token-file`'s): a page's address is
    /// seen and kept (a browser's history, a screen shared), and whoever
    /// held that token could move the motors.
    #[arg(long, value_name = "FILE", requires = "view")]
    view_token_file: Option<String>,
    /// A name the live view also answers to (repeatable; e.g. the
    /// machine's name when `--view` listens beyond loopback). The view
    /// answers only requests whose `Host` is its own address (or
    /// `localhost` on loopback) or such a name, and refuses requests sent
    /// from another site's page (`Origin`, `Sec-Fetch-Site`): a web page
    /// cannot read the session by a name of its own that resolves to this
    /// machine (DNS rebinding).
    #[arg(long, value_name = "NAME", requires = "view")]
    view_host: Vec<String>,
    #[command(flatten)]
    zenoh: crate::fleet::ZenohArgs,
}

pub(crate) fn run(args: &Args) -> u8 {
    match bridge(args) {
        Ok(code) => code,
        Err(e) => {
            note!("motorwire bridge: {e}");
            2
        }
    }
}

/// The feedback period for `hz` lines per second (`None` for 0).
pub(crate) fn feedback_period(hz: f64) -> Result<Option<Duration>, String> {
    if hz == 0.0 {
        return Ok(None);
    }
    if !(hz.is_finite() && hz > 0.0 && hz <= 1000.0) {
        return Err(format!(
            "--feedback-hz {hz}: expected 0 (none) or a rate up to 1000"
        ));
    }
    Duration::try_from_secs_f64(1.0 / hz)
        .map(Some)
        .map_err(|e| e.to_string())
}

/// The largest bus map read (1 MiB; the demo arm's is 1.4 KiB).
pub(crate) const MAX_MAP_SIZE: usize = 1 << 20;

/// The bus map at `path`, reading at most [`MAX_MAP_SIZE`] bytes of it.
pub(crate) fn load_map(path: &str) -> Result<BusMap, String> {
    load_map_text(path).map(|(map, _)| map)
}

/// The bus map at `path` and its text; a map with more motors than a
/// bridge serves ([`Bridge::MAX_DEVICES`]) is refused here, as the bridge
/// would refuse it, by every command that reads one.
pub(crate) fn load_map_text(path: &str) -> Result<(BusMap, String), String> {
    let text = crate::input::read_text_file(path, MAX_MAP_SIZE)
        .map_err(|e| format!("--map {path}: {e}"))?;
    let map = BusMap::from_toml(&text).map_err(|e| format!("--map {path}: {e}"))?;
    Bridge::check_map(&map).map_err(|e| format!("--map {path}: {e}"))?;
    Ok((map, text))
}

/// Milliseconds since the Unix epoch, now.
pub(crate) fn unix_ms() -> f64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0.0, |d| d.as_secs_f64() * 1000.0)
}

/// `drop=0.1,duplicate=0.05,...` as fault rates.
pub(crate) fn parse_faults(spec: &str) -> Result<Faults, String> {
    let mut f = Faults::default();
    for part in spec.split(',').map(str::trim).filter(|p| !p.is_empty()) {
        let (key, value) = part
            .split_once('=')
            .ok_or_else(|| format!("--sim-faults {part:?}: expected NAME=VALUE"))?;
        let number: f64 = value
            .parse()
            .map_err(|_| format!("--sim-faults {part:?}: {value:?} is not a number"))?;
        match key {
            "drop" => f.drop = number,
            "duplicate" => f.duplicate = number,
            "corrupt" => f.corrupt = number,
            "delay" => f.delay = number,
            "reorder" => f.reorder = number,
            "max-delay-ms" => {
                f.max_delay = Duration::try_from_secs_f64(number / 1000.0)
                    .map_err(|e| format!("--sim-faults {part:?}: {e}"))?;
            }
            other => {
                return Err(format!(
                    "--sim-faults: unknown fault {other:?} (drop, duplicate, corrupt, delay, reorder, max-delay-ms)"
                ));
            }
        }
    }
    f.validate().map_err(|e| format!("--sim-faults: {e}"))?;
    Ok(f)
}

/// Writes each execution as a JSON line to `path`, flushed at once.
fn execution_log(path: &str) -> Result<ExecutionLog, String> {
    let file = std::fs::File::create(path).map_err(|e| format!("--sim-log {path}: {e}"))?;
    let file = Mutex::new(io::BufWriter::new(file));
    Ok(Arc::new(move |joint: &str, node: u16, e: &Execution| {
        let line = serde_json::json!({
            "joint": joint,
            "node": node,
            "source": e.source,
            "msg_id": e.msg_id,
            "payload": e.payload,
            "answer": e.answer,
            "at_us": u64::try_from(e.at.as_micros()).unwrap_or(u64::MAX),
        });
        let mut f = file.lock().unwrap_or_else(PoisonError::into_inner);
        let _ = writeln!(f, "{line}");
        let _ = f.flush();
    }))
}

/// The clock's microseconds, as a msg_id (RFC 793's way of choosing a
/// starting sequence number): a bridge started after another starts past
/// its msg_ids unless that one sent over a million requests a second.
fn first_msg_id() -> u32 {
    let us = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(1, |d| d.as_micros());
    #[allow(clippy::cast_possible_truncation)]
    let id = (us & 0xFFFF_FFFF) as u32;
    id.max(1)
}

/// The interface named in the recording's `frames.log` for the bus `spec`:
/// a SocketCAN interface's own name, `sim` for the simulated bus, and
/// `fdcanusb` for an fdcanusb adapter (its device path, which `canplayer`
/// and python-can cannot read as an interface, is in `session.json`'s
/// setup); `canplayer -I frames.log can0=fdcanusb` plays it on can0.
fn frames_log_interface(spec: &str) -> String {
    if spec.starts_with("fdcanusb:") {
        return "fdcanusb".to_owned();
    }
    spec.strip_prefix("socketcan:").unwrap_or(spec).to_owned()
}

/// How long the end of a session waits for the recording's writer to put
/// what is queued on disk, once the joints are stopped; past it, the rest
/// is dropped and counted (a slow or stuck disk never holds the exit).
const RECORD_FINISH_LIMIT: Duration = Duration::from_secs(5);

/// The exit status of a session whose recording lost records (its queue
/// full, its disk full, failed or too slow): sysexits' `EX_CANTCREAT`, the
/// output asked for could not be made whole. It takes the place of every
/// other status (the lines before the last on stderr say what else
/// happened).
pub(crate) const EXIT_RECORDING_LOST: u8 = 73;

/// The bridge has ended and its joints are stopped: a signal then ends the
/// process at once (what is left is the recording's writer).
static BRIDGE_ENDED: AtomicBool = AtomicBool::new(false);

/// The exit status a signal gives: 128 plus its number, as a shell reports
/// a process the signal ended (SIGHUP 129, SIGINT 130, SIGTERM 143).
pub(crate) type SignalStatus = Arc<AtomicU8>;

/// Stops the bridge on SIGINT, SIGTERM or SIGHUP: the first signal
/// interrupts `input` (the joints are stopped and deactivated, then the
/// bridge ends) and its status is kept for the exit; a second signal, of
/// any of the three, ends the process at once with its own status. The
/// handlers are in place when this returns.
#[cfg(unix)]
fn on_signals(input: InputSender) -> Result<SignalStatus, String> {
    use tokio::signal::unix::{SignalKind, signal};
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_io()
        .build()
        .map_err(|e| format!("listening for signals: {e}"))?;
    let listen = |kind: SignalKind, name: &'static str| {
        let status = u8::try_from(128 + kind.as_raw_value()).unwrap_or(u8::MAX);
        signal(kind)
            .map(|s| (s, name, status))
            .map_err(|e| format!("listening for {name}: {e}"))
    };
    let (mut int, mut term, mut hup) = {
        let _in_runtime = rt.enter();
        (
            listen(SignalKind::interrupt(), "SIGINT")?,
            listen(SignalKind::terminate(), "SIGTERM")?,
            listen(SignalKind::hangup(), "SIGHUP")?,
        )
    };
    let ended = SignalStatus::default();
    let seen = Arc::clone(&ended);
    thread::spawn(move || {
        rt.block_on(async move {
            loop {
                let (name, status) = tokio::select! {
                    Some(()) = int.0.recv() => (int.1, int.2),
                    Some(()) = term.0.recv() => (term.1, term.2),
                    Some(()) = hup.0.recv() => (hup.1, hup.2),
                    else => return,
                };
                if BRIDGE_ENDED.load(Ordering::SeqCst) {
                    note!(
                        "motorwire bridge: {name}: the joints are stopped; exiting without waiting for the recording's last records"
                    );
                    std::process::exit(i32::from(status));
                }
                if seen
                    .compare_exchange(0, status, Ordering::SeqCst, Ordering::SeqCst)
                    .is_err()
                {
                    note!(
                        "motorwire bridge: {name}, a second signal: exiting now, the joints may not be stopped"
                    );
                    std::process::exit(i32::from(status));
                }
                note!(
                    "motorwire bridge: {name}: stopping and deactivating the joints (a second signal exits at once)"
                );
                input.interrupt();
            }
        });
    });
    Ok(ended)
}

/// Ctrl-C where there are no Unix signals: as SIGINT.
#[cfg(not(unix))]
fn on_signals(input: InputSender) -> Result<SignalStatus, String> {
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_io()
        .build()
        .map_err(|e| format!("listening for Ctrl-C: {e}"))?;
    let ended = SignalStatus::default();
    let seen = Arc::clone(&ended);
    thread::spawn(move || {
        rt.block_on(async {
            while tokio::signal::ctrl_c().await.is_ok() {
                if seen
                    .compare_exchange(0, 130, Ordering::SeqCst, Ordering::SeqCst)
                    .is_err()
                {
                    std::process::exit(130);
                }
                input.interrupt();
            }
        });
    });
    Ok(ended)
}

fn bridge(args: &Args) -> Result<u8, String> {
    crate::fleet::check(&args.zenoh)?;
    let (map, map_text) = load_map_text(&args.map)?;
    let orion = match &args.orion {
        Some(spec) => Some(crate::orion_link::parse(spec)?),
        None => None,
    };
    let config = BridgeConfig {
        client: ClientConfig {
            node_id: args.node,
            timeout: Duration::from_millis(args.ack_timeout.max(1)),
            retries: args.retries,
            // Past any earlier bridge's msg_ids: the joints refuse requests
            // older than the last lifecycle request they heard.
            first_msg_id: first_msg_id(),
            ..ClientConfig::default()
        },
        activate_on_start: !args.no_activate,
        feedback_period: feedback_period(args.feedback_hz)?,
        offline_after: Duration::from_millis(args.offline_after.max(1)),
        epoch_unix_ms: Some(unix_ms()),
        max_age: (args.max_age > 0).then(|| Duration::from_millis(args.max_age)),
        line_link: orion.is_some(),
        telemetry_hz: (args.telemetry_hz > 0).then_some(args.telemetry_hz),
        allow_unknown_members: args.allow_unknown_members,
        ..BridgeConfig::default()
    };
    let sim_config = SimConfig {
        seed: args.sim_seed,
        faults: parse_faults(&args.sim_faults)?,
        ..SimConfig::default()
    };
    let setup = motorwire_record::replay::Setup::of(&map_text, &args.bus, &config, &sim_config);
    let bridge = Bridge::new(map, config).map_err(|e| e.to_string())?;
    let mut runner = Runner::new().max_line(args.max_size);
    if let Some(spec) = &orion {
        runner = runner.with_orion(crate::orion_link::open(spec)?);
    }
    let recorder = match &args.record {
        Some(dir) => {
            if args.record_max_mb == 0 {
                return Err("--record-max-mb must be at least 1".to_owned());
            }
            if dir.is_empty() {
                return Err("--record needs a directory (an empty path would record into the working directory)".to_owned());
            }
            let interface = frames_log_interface(&args.bus);
            let r =
                motorwire_record::record::Recorder::start(motorwire_record::record::RecordConfig {
                    dir: dir.into(),
                    max_bytes: args.record_max_mb.saturating_mul(1024 * 1024),
                    interface,
                    setup: serde_json::to_value(&setup).ok(),
                })
                .map_err(|e| format!("--record {dir}: {e}"))?;
            let r = std::sync::Arc::new(r);
            runner = runner.with_recorder(r.clone());
            Some(r)
        }
        None => None,
    };
    // The control token, read once: the view's must differ from it.
    let control_token = args
        .token_file
        .as_deref()
        .map(|path| crate::serve::read_token("--token-file", path))
        .transpose()?;
    if let Some(addr) = args.view {
        let token = match &args.view_token_file {
            Some(path) => {
                let token = crate::serve::read_token("--view-token-file", path)?;
                if control_token.as_ref() == Some(&token) {
                    return Err(format!(
                        "--view-token-file {path}: the control token (--token-file's): whoever has the page's address could move the motors with it; give the view a token of its own"
                    ));
                }
                Some(token)
            }
            None if !crate::view::is_loopback(&addr) => {
                return Err(format!(
                    "--view {addr}: not a loopback address: anyone who reaches it would see the session; give --view-token-file FILE (a token of the view's own; the page is then opened with ?token=TOKEN), or use 127.0.0.1"
                ));
            }
            None => None,
        };
        let tokened = token.is_some();
        let view = crate::view::start(
            crate::view::ViewConfig {
                addr,
                token,
                hosts: args.view_host.clone(),
            },
            bridge.map(),
        )?;
        note!(
            "motorwire bridge: the live view at http://{}/{}",
            view.addr,
            if tokened {
                "?token=TOKEN (the view's token file's)"
            } else {
                ""
            }
        );
        runner = runner.with_tap(view.tap);
    }
    let input = runner.input();
    let signalled = on_signals(input.clone())?;

    // A fleet bridge reads no standard input unless told to: started by a
    // service manager or in the background, its standard input is closed
    // or not a terminal, and its end would end the bridge.
    let input_spec = args
        .input
        .clone()
        .unwrap_or_else(|| if args.zenoh.enabled() { "none" } else { "-" }.to_owned());
    let listen = crate::serve::parse_listen(&input_spec)?;
    let token = match (&listen, control_token) {
        (_, Some(token)) => Some(token),
        (crate::serve::Listen::Tcp(_), None) if !args.insecure_no_auth => {
            return Err(format!(
                "--input {input_spec}: TCP needs --token-file FILE (a connection's first line is the token), or --insecure-no-auth to let any local process move the motors; unix:PATH needs neither"
            ));
        }
        _ => None,
    };
    if args.max_clients == 0 {
        return Err("--max-clients must be at least 1".to_owned());
    }
    if args.auth_timeout_ms == 0 {
        return Err("--auth-timeout-ms must be at least 1".to_owned());
    }
    if args.client_queue < 2048 {
        return Err(format!(
            "--client-queue {}: at least 2048 (a stop can answer that many lines at once)",
            args.client_queue
        ));
    }
    // Files are opened before the first connection is taken: clients that
    // use up the descriptors the moment the bridge listens (a flood, or a
    // low `ulimit -n`) cannot then keep it from starting (it exited: `--sim-log
    // ...: Too many open files`).
    let sim_log = match (&args.sim_log, args.bus.as_str()) {
        (Some(path), "sim") => Some(execution_log(path)?),
        _ => None,
    };
    let router = crate::serve::Router::new(input.clone(), listen != crate::serve::Listen::Stdin);
    let socket_path = router.serve(
        &listen,
        crate::serve::ServeConfig {
            token,
            max_clients: args.max_clients,
            auth_timeout: Duration::from_millis(args.auth_timeout_ms),
            client_queue: args.client_queue,
        },
    )?;
    let fleet = crate::fleet::start(&args.zenoh, input.clone())?;
    let sink = {
        let router = std::sync::Arc::clone(&router);
        let fleet = fleet.as_ref();
        move |o: &Output, line: &std::sync::Arc<str>| {
            if !fleet.is_some_and(|f| f.route(o)) {
                router.route(o, line);
            }
        }
    };
    if args.bus == "none"
        && let Some(m) = bridge.map().motors().find(|m| {
            !matches!(
                m.target,
                motorwire_translate::Target::Servo(_) | motorwire_translate::Target::Orion { .. }
            )
        })
    {
        return Err(format!(
            "--bus none: motors.{} is a {} device on a CAN bus; give its bus (socketcan:IFACE, fdcanusb:PATH or sim)",
            m.name,
            m.target.dialect()
        ));
    }
    if !bridge.map().servo_ports().is_empty() {
        let links = if args.bus == "sim" {
            // The bus's faults on the servos' answers too: a frame dropped,
            // corrupted or delayed is a status packet dropped, corrupted or
            // late.
            let f = &sim_config.faults;
            let faults = motorwire_sim::servo::ServoFaults {
                drop: f.drop,
                corrupt: f.corrupt,
                late: f.delay,
                late_by: f.max_delay,
            };
            motorwire_bridge::sim::servo_links_with(bridge.map(), faults, sim_config.seed)
                .map_err(|e| e.to_string())?
        } else {
            crate::bus::servo_links(bridge.map())?
        };
        runner = runner.with_servo_links(links);
    }
    let result = match args.bus.as_str() {
        "sim" => {
            let arm = RealTimeArm::start_with(bridge.map(), sim_config, sim_log)
                .map_err(|e| e.to_string())?;
            // The sending half never receives, and the receiving half
            // does not hear the bridge's own frames.
            let (tx, rx) = arm.ports();
            runner.run_rendered(bridge, tx, rx, sink)
        }
        spec => {
            let (tx, rx) = crate::bus::open_pair(spec)?;
            runner.run_rendered(bridge, tx, rx, sink)
        }
    };
    if let Some(path) = socket_path {
        let _ = std::fs::remove_file(path);
    }
    if let Some(fleet) = fleet {
        fleet.close();
    }
    // The joints are stopped: from now on a signal ends the process at
    // once, without waiting for standard output or the recording's writer.
    BRIDGE_ENDED.store(true, Ordering::SeqCst);
    // At the end of standard input, what standard output still holds is
    // written out while its reader takes it (a reader held back has up to
    // half its queue waiting); a signal ends the bridge without it.
    if signalled.load(Ordering::SeqCst) == 0 {
        router.drain_stdout();
    }
    let lost = recorder
        .and_then(|r| std::sync::Arc::try_unwrap(r).ok())
        .and_then(|r| finish_recording(r, args.record.as_deref().unwrap_or_default()));
    let status = session_status(result, &router, &signalled);
    // Said last, whatever else happened: what was recorded is what is
    // kept of the session.
    match lost {
        Some(why) => {
            if let Err(e) = status {
                note!("motorwire bridge: {e}");
            }
            note!("motorwire bridge: {why}");
            Ok(EXIT_RECORDING_LOST)
        }
        None => status,
    }
}

/// Ends the recording `r` (into `dir`): its summary on stderr, and, when
/// it lost records, what to say last.
fn finish_recording(r: motorwire_record::record::Recorder, dir: &str) -> Option<String> {
    let dropped = r.dropped();
    match r.finish_within(RECORD_FINISH_LIMIT) {
        Some(s) => {
            note!(
                "motorwire bridge: recorded {} lines and frames ({} bytes), {} dropped",
                s.written,
                s.bytes,
                s.dropped
            );
            (s.dropped > 0).then(|| {
                format!(
                    "the recording lost {} records (its queue or its disk could not take them): {dir} is incomplete, {}",
                    s.dropped,
                    if s.session {
                        "as its session.json says"
                    } else {
                        "and its session.json, which could not be completed, says it did not end cleanly"
                    }
                )
            })
        }
        None => {
            note!(
                "motorwire bridge: the recording's disk did not take its last records within {} s",
                RECORD_FINISH_LIMIT.as_secs()
            );
            Some(format!(
                "the recording lost its last records, and {dropped} before them: {dir} is incomplete, its session.json says it did not end cleanly"
            ))
        }
    }
}

/// The session's exit status, once its recording is ended: its counts on
/// stderr, and what ended it.
fn session_status(
    result: Result<Bridge, motorwire_bridge::BridgeError>,
    router: &crate::serve::Router,
    signalled: &SignalStatus,
) -> Result<u8, String> {
    let bridge = result.map_err(|e| e.to_string())?;
    let s = bridge.stats();
    note!(
        "motorwire bridge: {} lines, {} ok, {} failed, {} frames sent, {} bad frames received",
        s.lines,
        s.ok,
        s.failed,
        s.frames_sent,
        s.bad_frames
    );
    let left_out = router.stdout_feedback_dropped();
    if left_out > 0 {
        note!(
            "motorwire bridge: standard output fell behind its lines: {left_out} feedback lines were left out"
        );
    }
    if let Some(why) = router.failure() {
        note!("motorwire bridge: {why}; the joints were stopped");
        return Ok(crate::serve::EXIT_OUTPUT_FAILED);
    }
    if let Some(why) = router.input_failure() {
        note!("motorwire bridge: {why}; the joints were stopped");
        return Ok(2);
    }
    // 0, or the status of the signal that ended the bridge.
    Ok(signalled.load(Ordering::SeqCst))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The interface a recording's `frames.log` names is one candump's
    /// readers take, for every kind of bus.
    #[test]
    fn every_bus_names_an_interface_the_log_readers_take() {
        for (spec, name) in [
            ("sim", "sim"),
            ("socketcan:can0", "can0"),
            ("socketcan:vcan12", "vcan12"),
            ("fdcanusb:/dev/ttyACM0", "fdcanusb"),
            ("fdcanusb:/tmp/my port", "fdcanusb"),
        ] {
            let got = frames_log_interface(spec);
            assert_eq!(got, name, "{spec}");
            assert!(motorwire_record::record::is_interface_name(&got), "{spec}");
        }
    }
}
