//! The real-time runner: an emergency stop overtakes every line queued
//! before it, and nothing queued before it runs after it.
#![allow(clippy::unwrap_used, clippy::panic, clippy::indexing_slicing)]

use std::sync::mpsc;
use std::thread;
use std::time::Duration;

use motorwire_bridge::sim::RealTimeArm;
use motorwire_bridge::{Bridge, BridgeConfig, InputSender, Origin, Output, Runner};
use motorwire_can::{CanBus, SimConfig};
use motorwire_translate::BusMap;
use serde_json::Value;

const MAP: &str = include_str!("../../../fixtures/maps/demo-arm.toml");

type Handle = thread::JoinHandle<Result<Bridge, motorwire_bridge::BridgeError>>;

/// The demo arm in real time, its bridge run by a [`Runner`] without
/// feedback; results come on the receiver.
fn start() -> (RealTimeArm, InputSender, mpsc::Receiver<Value>, Handle) {
    start_with(BridgeConfig {
        feedback_period: None,
        ..BridgeConfig::default()
    })
}

/// [`start`] with `config`.
fn start_with(config: BridgeConfig) -> (RealTimeArm, InputSender, mpsc::Receiver<Value>, Handle) {
    start_on(config, SimConfig::default(), false)
}

/// [`start`] with `config`, the arm's bus made hostile by `bus`'s faults;
/// with `blocking`, the bridge's receiving half is a bus that cannot wake
/// the runner ([`Blocking`]), read on a thread of its own as SocketCAN is.
fn start_on(
    config: BridgeConfig,
    bus: SimConfig,
    blocking: bool,
) -> (RealTimeArm, InputSender, mpsc::Receiver<Value>, Handle) {
    let map = BusMap::from_toml(MAP).unwrap();
    let bridge = Bridge::new(map, config).unwrap();
    let arm = RealTimeArm::start_with(bridge.map(), bus, None).unwrap();
    let runner = Runner::new();
    let input = runner.input();
    let (tx, rx) = mpsc::channel();
    let sink = move |o: &Output| {
        if let Output::Result { .. } = o {
            let _ = tx.send(o.to_value());
        }
    };
    let handle = if blocking {
        let (send, receive) = arm.ports();
        thread::spawn(move || runner.run(bridge, send, Blocking(receive), sink))
    } else {
        arm.spawn(runner, bridge, sink)
    };
    (arm, input, rx, handle)
}

/// A bus that only blocks in `recv` and cannot wake the runner (the
/// default of [`CanBus::set_waker`]), as SocketCAN and fdcanusb: the
/// runner reads it on a thread of its own.
struct Blocking(motorwire_can::SimPort);

impl CanBus for Blocking {
    fn send(&mut self, frame: &motorwire_can::Frame) -> Result<(), motorwire_can::Error> {
        self.0.send(frame)
    }
    fn recv(&mut self, timeout: Duration) -> Result<motorwire_can::Received, motorwire_can::Error> {
        self.0.recv(timeout)
    }
}

/// Ready first: one move of the elbow, answered. On a loaded machine the
/// simulated devices' thread may not have been heard from by the time the
/// bridge is ready (the settle time passed): the move is then refused
/// `offline`, rightly, and sent again once they are.
fn ready(input: &InputSender, rx: &mpsc::Receiver<Value>) {
    let end = std::time::Instant::now() + Duration::from_secs(10);
    loop {
        input.line(
            Origin(3),
            r#"{"motor_id":"elbow","timestamp":1,"control_mode":"position","setpoint":5}"#,
        );
        let r = rx.recv_timeout(Duration::from_secs(10)).unwrap();
        if r["error"]["kind"] == "offline" && std::time::Instant::now() < end {
            thread::sleep(Duration::from_millis(50));
            continue;
        }
        assert_eq!(r["ok"], true, "{r}");
        return;
    }
}

#[test]
fn a_stop_overtakes_the_lines_queued_before_it() {
    stop_overtakes(false);
}

/// As [`a_stop_overtakes_the_lines_queued_before_it`], the bus read by a
/// thread of the runner's (the way SocketCAN is read) instead of polled.
#[test]
fn a_stop_overtakes_the_lines_queued_before_it_on_a_bus_read_by_a_thread() {
    stop_overtakes(true);
}

/// Frames the bus delays (every one, by up to 5 ms, and reordered) reach
/// the runner: such a bus cannot wake it when they fall due, so it is read
/// by a thread (given as a bus that could wake it, and as one that
/// cannot): every move is answered, and answered once.
#[test]
fn frames_the_bus_delays_reach_the_runner() {
    let faults = motorwire_can::Faults {
        delay: 1.0,
        max_delay: Duration::from_millis(5),
        reorder: 0.2,
        ..motorwire_can::Faults::default()
    };
    let bus = SimConfig {
        seed: 11,
        faults,
        ..SimConfig::default()
    };
    let config = BridgeConfig {
        feedback_period: None,
        ..BridgeConfig::default()
    };
    for blocking in [false, true] {
        let (_arm, input, rx, handle) = start_on(config, bus, blocking);
        ready(&input, &rx);
        let n = 200u64;
        for i in 0..n {
            input.line(
                Origin(1),
                format!(
                    r#"{{"motor_id":"elbow","timestamp":1,"control_mode":"position","setpoint":{}}}"#,
                    10 + i % 40
                ),
            );
            let r = rx.recv_timeout(Duration::from_secs(10)).unwrap();
            assert_eq!(r["ok"], true, "blocking {blocking}: {r}");
            assert_eq!(r["line"], i + 1, "blocking {blocking}: {r}");
        }
        input.interrupt();
        handle.join().unwrap().unwrap();
        assert!(rx.try_recv().is_err(), "one result a line");
    }
}

/// A burst of lines on the three joints, a release and then a stop queued
/// behind them: the stop overtakes them, and nothing queued before it is
/// acked after it.
fn stop_overtakes(blocking: bool) {
    let config = BridgeConfig {
        feedback_period: None,
        ..BridgeConfig::default()
    };
    let (_arm, input, rx, handle) = start_on(config, SimConfig::default(), blocking);
    ready(&input, &rx);
    let n = 2000;
    for i in 0..n {
        let motor = ["shoulder_pitch", "shoulder_roll", "elbow"][i % 3];
        input.line(
            Origin(1),
            format!(
                r#"{{"motor_id":"{motor}","timestamp":1,"control_mode":"position","setpoint":{}}}"#,
                i % 40
            ),
        );
    }
    // A release queued before the stop must not undo it.
    input.line(Origin(1), r#"{"emergency_stop": false}"#);
    input.line(Origin(2), r#"{"emergency_stop": true, "from": "operator"}"#);
    let mut results: Vec<Value> = Vec::new();
    while results.len() < n + 2 {
        results.push(rx.recv_timeout(Duration::from_secs(10)).unwrap());
    }
    input.interrupt();
    handle.join().unwrap().unwrap();
    let stop_at = results
        .iter()
        .position(|r| r["emergency_stop"] == true)
        .unwrap();
    assert_eq!(results[stop_at]["ok"], true, "{}", results[stop_at]);
    assert_eq!(results[stop_at]["line"], 1);
    assert!(!results[stop_at]["problems"].as_array().unwrap().is_empty());
    // Nothing queued before the stop was acked after it.
    for r in &results[stop_at + 1..] {
        assert_eq!(r["ok"], false, "{r}");
    }
    let release = results.iter().find(|r| r["line"] == n as u64 + 1).unwrap();
    assert_eq!(release["ok"], false, "{release}");
    // Lines the stop overtook are refused latched: most of the burst.
    let latched = results
        .iter()
        .filter(|r| r["error"]["kind"] == "emergency_stop_latched")
        .count();
    // The sender waits while MAX_QUEUED_PER_ORIGIN lines are queued, so
    // that many at most were waiting when the stop came.
    assert!(
        latched > motorwire_bridge::MAX_QUEUED_PER_ORIGIN / 2,
        "only {latched} of {n} lines came after the stop: it did not overtake them"
    );
    let mut lines: Vec<u64> = results
        .iter()
        .filter(|r| r["line"].as_u64().is_some() && r["emergency_stop"] != true)
        .map(|r| r["line"].as_u64().unwrap())
        .collect();
    lines.sort_unstable();
    assert_eq!(
        lines,
        (1..=n as u64 + 1).collect::<Vec<_>>(),
        "one result per line"
    );
}

/// A line too long to read (or not UTF-8) that names `emergency_stop`
/// stops: the bridge cannot tell what it asks, and when in doubt it stops.
#[test]
fn an_unreadable_line_that_names_a_stop_stops() {
    use std::io::BufReader;
    let (_arm, input, rx, handle) = start();
    let long_stop = format!(
        "{{\"pad\":\"{}\",\"emergency_stop\":true}}\n",
        "x".repeat(motorwire_bridge::DEFAULT_MAX_LINE)
    );
    let mut text = Vec::new();
    text.extend_from_slice(
        b"{\"motor_id\":\"elbow\",\"timestamp\":1,\"control_mode\":\"position\",\"setpoint\":5}\n",
    );
    text.extend_from_slice(long_stop.as_bytes());
    text.extend_from_slice(
        b"{\"motor_id\":\"elbow\",\"timestamp\":1,\"control_mode\":\"position\",\"setpoint\":9}\n",
    );
    motorwire_bridge::feed(&input, Origin(1), &mut BufReader::new(&text[..]), true).unwrap();
    let mut results: Vec<Value> = (0..3)
        .map(|_| rx.recv_timeout(Duration::from_secs(10)).unwrap())
        .collect();
    input.interrupt();
    handle.join().unwrap().unwrap();
    results.sort_by_key(|r| r["line"].as_u64());
    let stop = &results[1];
    assert_eq!(stop["line"], 2, "{stop}");
    assert_eq!(stop["ok"], true, "{stop}");
    assert_eq!(stop["emergency_stop"], true, "{stop}");
    assert_eq!(
        stop["problems"],
        serde_json::json!([
            "the line is over 1048576 bytes (the bridge's --max-size); it names emergency_stop, so it is taken as a stop"
        ])
    );
    assert_eq!(
        results[2]["error"]["kind"], "emergency_stop_latched",
        "{}",
        results[2]
    );
}

/// The bridge's wall clock is the host's from the moment the runner
/// starts, whatever epoch its config was built with (here one a whole
/// second behind, as a bridge slow to start would have had): a command
/// stamped half a second before a stop, by the host's clock, was written
/// before it and does not run after the release; one stamped after it
/// does.
#[test]
fn the_stop_is_timed_on_the_hosts_clock() {
    let host_ms = || {
        std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .unwrap()
            .as_secs_f64()
            * 1000.0
    };
    let (_arm, input, rx, handle) = start_with(BridgeConfig {
        feedback_period: None,
        epoch_unix_ms: Some(host_ms() - 1000.0),
        max_age: Some(Duration::from_secs(60)),
        ..BridgeConfig::default()
    });
    let command = |stamp: f64| {
        format!(
            r#"{{"motor_id":"elbow","timestamp":{},"control_mode":"position","setpoint":5}}"#,
            stamp.floor()
        )
    };
    input.line(Origin(1), command(host_ms()));
    let first = rx.recv_timeout(Duration::from_secs(10)).unwrap();
    assert_eq!(first["ok"], true, "{first}");
    let before_stop = host_ms();
    input.line(Origin(1), r#"{"emergency_stop": true}"#);
    assert_eq!(
        rx.recv_timeout(Duration::from_secs(10)).unwrap()["ok"],
        true
    );
    thread::sleep(Duration::from_millis(5));
    let after_stop = host_ms();
    input.line(Origin(1), r#"{"emergency_stop": false}"#);
    assert_eq!(
        rx.recv_timeout(Duration::from_secs(10)).unwrap()["released"],
        true
    );
    input.line(Origin(2), command(before_stop - 500.0));
    let stale = rx.recv_timeout(Duration::from_secs(10)).unwrap();
    assert_eq!(stale["error"]["kind"], "stale_before_stop", "{stale}");
    input.line(Origin(2), command(after_stop + 1.0));
    let fresh = rx.recv_timeout(Duration::from_secs(10)).unwrap();
    assert_eq!(fresh["ok"], true, "{fresh}");
    input.interrupt();
    handle.join().unwrap().unwrap();
}

/// What a tap was told and what went on the bus, in the order it happened.
#[derive(Debug, Clone, PartialEq)]
enum Seen {
    /// A frame the runner sent on the bus (only their count matters).
    OnBus,
    /// A tap was told of an input line (its number and text).
    Line(u64, String),
    /// A tap was told of a frame the bridge sent.
    TappedTx,
}

/// A tap that writes what it is told into `log`.
#[derive(Debug)]
struct OrderTap(std::sync::Arc<std::sync::Mutex<Vec<Seen>>>);

impl motorwire_bridge::tap::Tap for OrderTap {
    fn input_owned(
        &self,
        _at: std::time::Instant,
        _taken: std::time::Instant,
        _origin: Origin,
        number: u64,
        text: String,
    ) {
        self.0.lock().unwrap().push(Seen::Line(number, text));
    }
    fn frame(
        &self,
        _at: std::time::Instant,
        dir: motorwire_bridge::tap::Direction,
        _frame: &motorwire_can::Frame,
    ) {
        if dir == motorwire_bridge::tap::Direction::Tx {
            self.0.lock().unwrap().push(Seen::TappedTx);
        }
    }
}

/// The bridge's sending half of the simulated bus, writing each frame it
/// sends into `log` as it goes.
struct LoggedSender {
    port: motorwire_can::SimPort,
    log: std::sync::Arc<std::sync::Mutex<Vec<Seen>>>,
}

impl motorwire_can::CanBus for LoggedSender {
    fn send(&mut self, frame: &motorwire_can::Frame) -> Result<(), motorwire_can::Error> {
        self.port.send(frame)?;
        self.log.lock().unwrap().push(Seen::OnBus);
        Ok(())
    }
    fn recv(&mut self, timeout: Duration) -> Result<motorwire_can::Received, motorwire_can::Error> {
        self.port.recv(timeout)
    }
}

/// A stop's frames go on the bus before the taps (a recorder, a live view)
/// are told of its line or of those frames: the stop never waits for its
/// recording. Checked with a burst of moves in flight, so the stop's line
/// is handled while other lines and frames are being told.
#[test]
fn a_stop_is_on_the_bus_before_its_taps_are_told() {
    let log = std::sync::Arc::new(std::sync::Mutex::new(Vec::new()));
    let map = BusMap::from_toml(MAP).unwrap();
    let bridge = Bridge::new(
        map,
        BridgeConfig {
            feedback_period: None,
            ..BridgeConfig::default()
        },
    )
    .unwrap();
    let arm = RealTimeArm::start(bridge.map()).unwrap();
    let runner = Runner::new().with_tap(std::sync::Arc::new(OrderTap(std::sync::Arc::clone(&log))));
    let input = runner.input();
    let (tx, rx) = mpsc::channel();
    let sender = LoggedSender {
        port: arm.sender(),
        log: std::sync::Arc::clone(&log),
    };
    let port = arm.port();
    let handle = thread::spawn(move || {
        runner.run(bridge, sender, port, move |o: &Output| {
            if let Output::Result { .. } = o {
                let _ = tx.send(o.to_value());
            }
        })
    });
    ready(&input, &rx);
    let n = 200;
    for i in 0..n {
        input.line(
            Origin(1),
            format!(
                r#"{{"motor_id":"elbow","timestamp":1,"control_mode":"position","setpoint":{}}}"#,
                10 + i % 40
            ),
        );
    }
    let stop = r#"{"emergency_stop": true}"#;
    input.line(Origin(2), stop);
    let mut stop_result = None;
    for _ in 0..=n {
        let r = rx.recv_timeout(Duration::from_secs(10)).unwrap();
        if r["emergency_stop"] == true {
            stop_result = Some(r);
        }
    }
    input.interrupt();
    handle.join().unwrap().unwrap();
    let stop_result = stop_result.expect("the stop's result");
    assert_eq!(stop_result["ok"], true, "{stop_result}");
    let log = log.lock().unwrap().clone();
    let told = log
        .iter()
        .position(|s| *s == Seen::Line(1, stop.to_owned()))
        .expect("the taps were told of the stop's line");
    // Every frame on the bus was told to the taps, once each, and never
    // before it was on the bus.
    let (mut on_bus, mut tapped) = (0usize, 0usize);
    for s in &log {
        match s {
            Seen::OnBus => on_bus += 1,
            Seen::TappedTx => {
                tapped += 1;
                assert!(tapped <= on_bus, "a frame told before it was sent");
            }
            Seen::Line(..) => {}
        }
    }
    assert_eq!(tapped, on_bus);
    // The stop's frames (a Deactivate for each of the map's lifecycle
    // devices, at least the three iRPC joints) went on the bus before its
    // line was told: the frames sent just before the line was told.
    let before: Vec<&Seen> = log[..told]
        .iter()
        .rev()
        .take_while(|s| !matches!(s, Seen::Line(..)))
        .collect();
    let sent_just_before = before.iter().filter(|s| ***s == Seen::OnBus).count();
    assert!(
        sent_just_before >= 3,
        "the stop's frames were not on the bus before its line was told: {before:?}"
    );
}

/// What a [`Flaky`] bus's `recv` gives on its `n`-th call (from 1):
/// an error, or the port's frame.
type FailOn = fn(u64) -> Option<motorwire_can::Error>;

/// The arm's port, with `recv` failing as `fail` says; it takes the
/// runner's waker when `polled` (so the runner polls it) and refuses it
/// otherwise (so a thread reads it).
struct Flaky {
    port: motorwire_can::SimPort,
    calls: u64,
    fail: FailOn,
    polled: bool,
}

impl CanBus for Flaky {
    fn send(&mut self, frame: &motorwire_can::Frame) -> Result<(), motorwire_can::Error> {
        self.port.send(frame)
    }
    fn recv(&mut self, timeout: Duration) -> Result<motorwire_can::Received, motorwire_can::Error> {
        self.calls += 1;
        match (self.fail)(self.calls) {
            Some(e) => Err(e),
            None => self.port.recv(timeout),
        }
    }
    fn set_waker(&mut self, waker: motorwire_can::FrameWaker) -> bool {
        self.polled && self.port.set_waker(waker)
    }
}

/// The demo arm's bridge (no feedback) run on its two halves of the
/// bus as `send` and `receive` make them of the arm's ports; every output
/// (results and events) comes on the receiver as its JSON value.
fn start_halves<S, R>(
    send: impl FnOnce(motorwire_can::SimPort) -> S,
    receive: impl FnOnce(motorwire_can::SimPort) -> R,
) -> (RealTimeArm, InputSender, mpsc::Receiver<Value>, Handle)
where
    S: CanBus + Send + 'static,
    R: CanBus + Send + 'static,
{
    let map = BusMap::from_toml(MAP).unwrap();
    let config = BridgeConfig {
        feedback_period: None,
        ..BridgeConfig::default()
    };
    let bridge = Bridge::new(map, config).unwrap();
    let arm = RealTimeArm::start(bridge.map()).unwrap();
    let runner = Runner::new();
    let input = runner.input();
    let (tx, rx) = mpsc::channel();
    let (tx_port, rx_port) = arm.ports();
    let (send, receive) = (send(tx_port), receive(rx_port));
    let handle = thread::spawn(move || {
        runner.run(bridge, send, receive, move |o: &Output| {
            let _ = tx.send(o.to_value());
        })
    });
    (arm, input, rx, handle)
}

/// [`start_halves`] with a [`Flaky`] receiving half.
fn start_flaky(
    fail: FailOn,
    polled: bool,
) -> (RealTimeArm, InputSender, mpsc::Receiver<Value>, Handle) {
    start_halves(
        |p| p,
        move |port| Flaky {
            port,
            calls: 0,
            fail,
            polled,
        },
    )
}

/// The next result on `rx`, the events before it counted by kind.
fn next_result(rx: &mpsc::Receiver<Value>, bus_errors: &mut Vec<String>) -> Value {
    loop {
        let v = rx.recv_timeout(Duration::from_secs(10)).unwrap();
        if v["event"] == "bus_error" {
            bus_errors.push(v["error"].as_str().unwrap().to_owned());
        } else if v.get("ok").is_some() && v.get("line").is_some() {
            return v;
        }
    }
}

/// A bus that fails every other receive (an error it can go on after)
/// loses no frame: whether the runner polls it or a thread reads it, the
/// frame behind each error is read at once, and 200 moves are each
/// answered ok (polled, the frames behind an error waited for the next
/// wake, and the joints went offline).
#[test]
fn frames_behind_a_receive_error_are_read_at_once() {
    let fail: FailOn =
        |n| (n % 2 == 0).then_some(motorwire_can::Error::ErrorPassive { tx: 130, rx: 0 });
    for polled in [true, false] {
        let (_arm, input, rx, handle) = start_flaky(fail, polled);
        let mut errors = Vec::new();
        for i in 0..200u64 {
            input.line(
                Origin(1),
                format!(
                    r#"{{"motor_id":"elbow","timestamp":1,"control_mode":"position","setpoint":{}}}"#,
                    10 + i % 40
                ),
            );
            let r = next_result(&rx, &mut errors);
            assert_eq!(r["ok"], true, "polled {polled}, line {}: {r}", i + 1);
        }
        input.interrupt();
        handle.join().unwrap().unwrap();
        assert!(!errors.is_empty(), "polled {polled}: the errors were said");
        assert!(
            errors[0].starts_with("receiving: controller error-passive"),
            "{errors:?}"
        );
    }
}

/// A bus that fails every receive (bus-off, for as long as the test
/// lasts) is said about ten times a second, its other errors counted,
/// neither polled nor read in a loop: a line is still answered (its
/// device silent), and an interrupt ends the run at once.
#[test]
fn a_bus_that_fails_every_receive_is_said_ten_times_a_second() {
    let fail: FailOn = |_| Some(motorwire_can::Error::BusOff);
    for polled in [true, false] {
        let (_arm, input, rx, handle) = start_flaky(fail, polled);
        let began = std::time::Instant::now();
        let mut errors = Vec::new();
        input.line(
            Origin(1),
            r#"{"motor_id":"elbow","timestamp":1,"control_mode":"position","setpoint":10}"#,
        );
        let r = next_result(&rx, &mut errors);
        assert_eq!(r["ok"], false, "polled {polled}: {r}");
        std::thread::sleep(Duration::from_millis(500));
        input.interrupt();
        handle.join().unwrap().unwrap();
        let ran = began.elapsed();
        errors.extend(
            rx.try_iter()
                .filter(|v| v["event"] == "bus_error")
                .map(|v| v["error"].as_str().unwrap().to_owned()),
        );
        #[allow(clippy::cast_possible_truncation)]
        let most = (ran.as_millis() / 100) as usize + 2;
        assert!(
            (2..=most).contains(&errors.len()),
            "polled {polled}: {} bus errors said in {ran:?}: {errors:?}",
            errors.len()
        );
        assert_eq!(errors[0], "receiving: bus off", "{errors:?}");
        assert!(
            errors[1].contains("more bus errors since the last said"),
            "{errors:?}"
        );
    }
}

/// The arm's sending half, failing its `n`-th send (from the first after
/// `armed`) as `fail` says.
struct FailingSender {
    port: motorwire_can::SimPort,
    armed: std::sync::Arc<std::sync::atomic::AtomicBool>,
    sent: u64,
}

impl CanBus for FailingSender {
    fn send(&mut self, frame: &motorwire_can::Frame) -> Result<(), motorwire_can::Error> {
        if self.armed.load(std::sync::atomic::Ordering::SeqCst) {
            self.sent += 1;
            if self.sent == 1 {
                return Err(motorwire_can::Error::NoAck);
            }
        }
        self.port.send(frame)
    }
    fn recv(&mut self, timeout: Duration) -> Result<motorwire_can::Received, motorwire_can::Error> {
        self.port.recv(timeout)
    }
}

/// A send that fails (no node acknowledged the frame) loses that frame
/// only, as a bus that drops it: the stop's other frames go, the lost one
/// is sent again, the stop is answered ok and the run goes on (it ended,
/// with no result for the stop and the other joints not stopped).
#[test]
fn a_failed_send_loses_that_frame_only_and_the_stop_still_stops() {
    let armed = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let arming = std::sync::Arc::clone(&armed);
    let (_arm, input, rx, handle) = start_halves(
        move |port| FailingSender {
            port,
            armed: arming,
            sent: 0,
        },
        |p| p,
    );
    let mut errors = Vec::new();
    input.line(
        Origin(1),
        r#"{"motor_id":"elbow","timestamp":1,"control_mode":"position","setpoint":5}"#,
    );
    assert_eq!(next_result(&rx, &mut errors)["ok"], true);
    armed.store(true, std::sync::atomic::Ordering::SeqCst);
    input.line(Origin(2), r#"{"emergency_stop": true}"#);
    let stop = next_result(&rx, &mut errors);
    assert_eq!(stop["emergency_stop"], true, "{stop}");
    assert_eq!(stop["ok"], true, "{stop}");
    assert_eq!(
        errors,
        ["sending a frame (taken as lost): no node acknowledged the frame"]
    );
    input.line(Origin(2), r#"{"emergency_stop": false}"#);
    assert_eq!(next_result(&rx, &mut errors)["released"], true);
    input.line(
        Origin(1),
        r#"{"motor_id":"elbow","timestamp":1,"control_mode":"position","setpoint":8}"#,
    );
    assert_eq!(next_result(&rx, &mut errors)["ok"], true);
    input.interrupt();
    handle.join().unwrap().unwrap();
}

/// A sending half whose every send fails as a bus in trouble says (no
/// node acknowledged the frame).
struct NeverAcked(motorwire_can::SimPort);

impl CanBus for NeverAcked {
    fn send(&mut self, _frame: &motorwire_can::Frame) -> Result<(), motorwire_can::Error> {
        Err(motorwire_can::Error::NoAck)
    }
    fn recv(&mut self, timeout: Duration) -> Result<motorwire_can::Received, motorwire_can::Error> {
        self.0.recv(timeout)
    }
}

/// Once receiving has failed for good (the bus closed), a send that fails
/// ends the run with the bus's error, polled or read by a thread: the bus
/// is gone both ways, and the bridge says so rather than running on
/// without it.
#[test]
fn a_bus_gone_both_ways_ends_the_run() {
    let fail: FailOn = |_| Some(motorwire_can::Error::Closed);
    for polled in [true, false] {
        let (_arm, input, rx, handle) = start_halves(NeverAcked, move |port| Flaky {
            port,
            calls: 0,
            fail,
            polled,
        });
        // Receiving fails for good (said once, unless the run ends first);
        // the sends before it (the start's) are each taken as lost.
        while let Ok(v) = rx.recv_timeout(Duration::from_secs(10)) {
            if v["event"] == "bus_error" && v["error"] == "receiving: the bus is closed" {
                break;
            }
            if v["event"] == "bus_error" {
                assert_eq!(
                    v["error"], "sending a frame (taken as lost): no node acknowledged the frame",
                    "{v}"
                );
            }
        }
        input.line(
            Origin(1),
            r#"{"motor_id":"elbow","timestamp":1,"control_mode":"position","setpoint":10}"#,
        );
        let ended = handle.join().unwrap();
        assert!(
            matches!(
                ended,
                Err(motorwire_bridge::BridgeError::Bus(
                    motorwire_can::Error::NoAck
                ))
            ),
            "polled {polled}: {ended:?}"
        );
    }
}
