//! The bridge: a WIA MotorCommand line in, its result out.
//!
//! - In simulated time (criterion): the whole path, line -> validate ->
//!   gate -> translate -> iRPC client -> in-memory bus -> simulated joint
//!   (which plans the move) -> Ack -> result line, against the same exchange
//!   without the bridge (the client asking the joint directly), in the same
//!   run. Its inverse is the sustained commands per second.
//! - In real time (printed after criterion): the `Runner` on the real-time
//!   simulated arm (`motorwire bridge --bus sim`), each line's latency from
//!   its arrival to its frame on the bus, as its result reports it (median,
//!   p99), and the sustained rate with 16 lines in flight.
//!
//! `cargo bench -p motorwire-benches --bench bridge`
#![allow(
    missing_docs,
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing
)]

/// The allocator of the `motorwire` binary (the `jemalloc` feature, on by
/// default), so that the bridge is measured as it runs there.
#[cfg(all(feature = "jemalloc", not(target_env = "msvc")))]
#[global_allocator]
static ALLOCATOR: tikv_jemallocator::Jemalloc = tikv_jemallocator::Jemalloc;

use std::hint::black_box;
use std::sync::mpsc;
use std::time::{Duration, Instant};

use criterion::{Criterion, Throughput};
use motorwire_bridge::sim::{RealTimeArm, SimulatedArm};
use motorwire_bridge::tap::{Direction, Tap};
use motorwire_bridge::{Bridge, BridgeConfig, InputSender, Origin, Output, Runner};
use motorwire_can::SimConfig;
use motorwire_can::client::{ClientConfig, Outcome};
use motorwire_irpc::{Payload, SetTargetPayloadV2};
use motorwire_sim::JointConfig;
use motorwire_sim::rig::Rig;
use motorwire_translate::BusMap;
use serde_json::Value;

const MAP: &str = include_str!("../../fixtures/maps/demo-arm.toml");

fn line(i: u64) -> String {
    format!(
        r#"{{"motor_id":"elbow","timestamp":1704067200000,"control_mode":"position","setpoint":{},"velocity_limit":100}}"#,
        10 + (i % 100)
    )
}

fn simulated_arm(map: &str) -> SimulatedArm {
    let map = BusMap::from_toml(map).unwrap();
    let config = BridgeConfig {
        feedback_period: None,
        ..BridgeConfig::default()
    };
    let mut arm =
        SimulatedArm::new(Bridge::new(map, config).unwrap(), SimConfig::default()).unwrap();
    assert!(
        arm.run_while(Duration::from_secs(1), |a| a.bridge().is_ready())
            .unwrap()
    );
    arm.take_outputs();
    arm
}

/// The demo map's elbow alone: the bridge in front of the one joint the
/// baseline's client asks, on a bus with nothing else on it.
const ELBOW_ALONE: &str = r#"
[motors.elbow]
dialect = "irpc"
node = 0x12
wire = "v2.0"
profile = "scurve"
limits = { min_position = 0, max_position = 150, max_velocity = 120, max_acceleration = 500, max_deceleration = 400, max_jerk = 2000 }
"#;

/// One line for the elbow through the bridge on `arm`, until its result.
/// Not inlined, so that an instruction counter (callgrind) sees each call.
///
/// The line is made before the call (`LINES`), as the baseline's request
/// is: writing the controller's text is the controller's work.
#[inline(never)]
fn line_to_result(arm: &mut SimulatedArm, line: &str) {
    arm.line(Origin(1), line);
    loop {
        arm.step(Duration::from_millis(1)).unwrap();
        // Each output as the line a runner prints; the result's `ok` read
        // from the typed result, not by parsing the line back (which is
        // the reader's work, not the bridge's).
        let mut done = false;
        for o in arm.drain_outputs() {
            let text = black_box(o.to_json());
            if let Some(r) = o.result() {
                assert!(r.ok, "{text}");
                done = true;
            }
        }
        if done {
            break;
        }
    }
}

fn benches(c: &mut Criterion) {
    let mut g = c.benchmark_group("bridge");
    g.throughput(Throughput::Elements(1));
    // The whole demo map on the bus: three joints, the compact gripper
    // (each simulated device is served every step).
    let mut arm = simulated_arm(MAP);
    // The hundred setpoints the benchmark cycles through, written once.
    let lines: Vec<String> = (0..100).map(line).collect();
    let mut i = 0usize;
    g.bench_function("a_bridge_line_to_result", |b| {
        b.iter(|| {
            i += 1;
            line_to_result(&mut arm, &lines[i % 100]);
        });
    });
    // The same line with the elbow alone on the bus, as in the baseline.
    let mut arm = simulated_arm(ELBOW_ALONE);
    g.bench_function("a1_bridge_line_to_result_elbow_alone", |b| {
        b.iter(|| {
            i += 1;
            line_to_result(&mut arm, &lines[i % 100]);
        });
    });
    // Baseline: the same move asked of the same joint by the client alone.
    let mut joint = JointConfig::new(0x12);
    joint.limits.max_velocity = 120.0;
    let mut rig = Rig::new(SimConfig::default(), ClientConfig::default(), [joint]).unwrap();
    for p in [Payload::Configure, Payload::Activate] {
        assert_eq!(rig.request(0x12, p).unwrap().outcome, Outcome::Acked);
    }
    let mut k = 0u32;
    g.bench_function("b_client_request_to_ack_without_bridge", |b| {
        b.iter(|| {
            k += 1;
            client_request_to_ack(&mut rig, k);
        });
    });
    g.finish();
}

/// The baseline's one exchange: the move asked of the joint by the client
/// alone, until its Ack. Not inlined, as [`line_to_result`].
#[inline(never)]
fn client_request_to_ack(rig: &mut Rig, k: u32) {
    let p = SetTargetPayloadV2::scurve(10.0 + (k % 100) as f32, 100.0, 500.0, 2000.0)
        .with_deceleration(400.0);
    let done = rig.request(0x12, Payload::SetTargetV2(p)).unwrap();
    assert_eq!(done.outcome, Outcome::Acked);
    black_box(done);
}

/// The `p` quantile of `sorted` (zero for none): latencies in µs, ratios.
fn percentile<T: Copy + Default>(sorted: &[T], p: f64) -> T {
    if sorted.is_empty() {
        return T::default();
    }
    let i = ((sorted.len() as f64 - 1.0) * p).round() as usize;
    sorted[i.min(sorted.len() - 1)]
}

type Handle = std::thread::JoinHandle<Result<Bridge, motorwire_bridge::BridgeError>>;

/// The bridge for `map` (no feedback), its real-time simulated devices
/// and a `Runner` for it, recording the session with `recorder` when
/// given. With `orion`, the map's Orion motors are reached through
/// motorwire's simulated controller on a pipe, as `--orion sim` does.
fn prepared(
    map: &str,
    orion: bool,
    recorder: Option<std::sync::Arc<dyn motorwire_bridge::tap::Tap>>,
) -> (Bridge, RealTimeArm, Runner) {
    let map = BusMap::from_toml(map).unwrap();
    let config = BridgeConfig {
        feedback_period: None,
        line_link: orion,
        ..BridgeConfig::default()
    };
    let bridge = Bridge::new(map, config).unwrap();
    let arm = RealTimeArm::start(bridge.map()).unwrap();
    let mut runner = Runner::new();
    if let Some(r) = recorder {
        runner = runner.with_tap(r);
    }
    if orion {
        let (reader, writer) =
            motorwire_sim::orion::spawn_in_process(motorwire_sim::orion::OrionConfig::default())
                .unwrap();
        runner = runner.with_orion(motorwire_bridge::OrionPort {
            reader: Box::new(reader),
            writer: Box::new(writer),
        });
    }
    (bridge, arm, runner)
}

/// [`prepared`] and run, without recording; every result comes on the
/// receiver.
fn started(map: &str, orion: bool) -> (RealTimeArm, InputSender, mpsc::Receiver<Value>, Handle) {
    let (bridge, arm, runner) = prepared(map, orion, None);
    let input = runner.input();
    let (tx, rx) = mpsc::channel();
    let handle = arm.spawn(runner, bridge, move |o| {
        if let Output::Result { .. } = o {
            let _ = tx.send(o.to_value());
        }
    });
    (arm, input, rx, handle)
}

/// What [`started_lean`]'s sink hands the benchmark: results counted,
/// and the stops' and releases' results themselves.
struct Lean {
    /// Results given so far.
    results: std::sync::Arc<std::sync::atomic::AtomicU64>,
    /// The stops' and releases' results.
    stops: mpsc::Receiver<Value>,
}

impl Lean {
    /// Waits until `n` results in all were given.
    fn wait_results(&self, n: u64) {
        let end = Instant::now() + Duration::from_secs(10);
        while self.results.load(std::sync::atomic::Ordering::Acquire) < n {
            assert!(Instant::now() < end, "results: {n} not given in 10 s");
            std::thread::sleep(Duration::from_micros(200));
        }
    }
}

/// [`prepared`] and run with the sink a controller's reader would be:
/// each output rendered as its JSON line once on the bridge's thread
/// (`run_rendered`, as the CLI runs it; the recording keeps the same
/// line), the results counted, and only the stops' and releases' handed to
/// the benchmark's thread. [`started`] hands every result over as a
/// `Value`: behind a stop, the benchmark's thread took a thousand of them
/// at once, for 600 µs and more, on the core the bridge's thread had just
/// been woken on (the other one idle: a thread that ran within the last
/// half millisecond is not moved), and the stop waited for it
/// (`perf sched timehist`). That is the benchmark's own work, not the
/// bridge's, and it fell on either side of a comparison.
fn started_lean(
    map: &str,
    recorder: Option<std::sync::Arc<dyn motorwire_bridge::tap::Tap>>,
) -> (RealTimeArm, InputSender, Lean, Handle) {
    let (bridge, arm, runner) = prepared(map, false, recorder);
    let input = runner.input();
    let results = std::sync::Arc::new(std::sync::atomic::AtomicU64::new(0));
    let given = std::sync::Arc::clone(&results);
    let (tx, stops) = mpsc::channel();
    let handle = arm.spawn_rendered(runner, bridge, move |o, line| {
        if let Output::Result { result, .. } = o {
            let text = black_box(line);
            // Counted before it is handed over: a round that begins once
            // the release's result came counts it in.
            given.fetch_add(1, std::sync::atomic::Ordering::Release);
            if result.emergency_stop || result.released {
                let _ = tx.send(serde_json::from_str(text).unwrap());
            }
        }
    });
    (arm, input, Lean { results, stops }, handle)
}

/// [`stops_behind_bursts_in_order`] on a [`started_lean`] bridge: the
/// benchmark's thread sleeps until the stop's result.
fn stops_behind_bursts_lean(input: &InputSender, lean: &Lean, rounds: usize) -> Vec<u64> {
    let mut loaded = Vec::new();
    for _ in 0..rounds {
        let before = lean.results.load(std::sync::atomic::Ordering::Acquire);
        for i in 0..BURST {
            input.line(Origin(2), line(i));
        }
        input.line(Origin(3), r#"{"emergency_stop": true}"#);
        let r = lean.stops.recv_timeout(Duration::from_secs(5)).unwrap();
        assert_eq!(r["emergency_stop"], true, "{r}");
        loaded.push(r["stop_latency_us"].as_u64().unwrap());
        // The burst answered (cut by the stop, most of it) before the release.
        lean.wait_results(before + BURST + 1);
        input.line(Origin(3), r#"{"emergency_stop": false}"#);
        let r = lean.stops.recv_timeout(Duration::from_secs(5)).unwrap();
        assert_eq!(r["released"], true, "{r}");
    }
    loaded
}

/// `n` emergency stops, each released; their latencies (line to the last
/// stop frame, µs), sorted.
fn stop_each_released(input: &InputSender, rx: &mpsc::Receiver<Value>, n: usize) -> Vec<u64> {
    let mut stops = Vec::new();
    for _ in 0..n {
        input.line(Origin(1), r#"{"emergency_stop": true}"#);
        let r = rx.recv_timeout(Duration::from_secs(5)).unwrap();
        assert_eq!(r["ok"], true, "{r}");
        assert_eq!(r["emergency_stop"], true, "{r}");
        stops.push(r["stop_latency_us"].as_u64().unwrap());
        input.line(Origin(1), r#"{"emergency_stop": false}"#);
        let r = rx.recv_timeout(Duration::from_secs(5)).unwrap();
        assert_eq!(r["released"], true, "{r}");
    }
    stops.sort_unstable();
    stops
}

/// The Runner in real time: `n` lines, each sent when the previous result
/// came (latency), then `n` lines with up to 16 in flight (rate).
fn real_time(n: u64) {
    let (_arm, input, rx, handle) = started(MAP, false);
    let mut latencies = Vec::new();
    for i in 0..n {
        input.line(Origin(1), line(i));
        let r = rx.recv_timeout(Duration::from_secs(5)).unwrap();
        assert_eq!(r["ok"], true, "{r}");
        latencies.push(r["latency_us"].as_u64().unwrap());
    }
    // Sustained: up to WINDOW lines in flight, as a controller pipelining
    // its commands would keep (thousands at once only queue up on the bus).
    const WINDOW: u64 = 16;
    let start = Instant::now();
    let (mut sent, mut done, mut failed) = (0, 0, 0);
    while done < n {
        while sent < n && sent - done < WINDOW {
            input.line(Origin(1), line(sent));
            sent += 1;
        }
        let r = rx.recv_timeout(Duration::from_secs(5)).unwrap();
        done += 1;
        // A newer move for a joint replaces one still waiting for it.
        if r["ok"] != true && r["error"]["kind"] != "superseded" {
            failed += 1;
        }
    }
    let rate = n as f64 / start.elapsed().as_secs_f64();
    assert_eq!(failed, 0, "{failed} of {n} lines failed");
    // The emergency stop: from its line to the last of its three
    // Deactivate frames on the bus; released after each.
    #[allow(clippy::cast_possible_truncation)]
    let stops = stop_each_released(&input, &rx, n.min(500) as usize);
    // The same with a burst of BURST lines in flight when the stop comes.
    #[allow(clippy::cast_possible_truncation)]
    let loaded = stops_behind_bursts(&input, &rx, n.min(50) as usize);
    input.interrupt();
    handle.join().unwrap().unwrap();
    latencies.sort_unstable();
    println!(
        "bridge/real_time: {} emergency stops; line to the last stop frame on the bus: median {} us, p99 {} us",
        stops.len(),
        percentile(&stops, 0.5),
        percentile(&stops, 0.99)
    );
    println!(
        "bridge/real_time: {} emergency stops with {BURST} lines in flight; line to the last stop frame: median {} us, p99 {} us",
        loaded.len(),
        percentile(&loaded, 0.5),
        percentile(&loaded, 0.99)
    );
    println!(
        "bridge/real_time: {n} lines; line to frame on the bus: median {} us, p99 {} us, max {} us; sustained ({WINDOW} in flight): {rate:.0} commands/s",
        percentile(&latencies, 0.5),
        percentile(&latencies, 0.99),
        latencies.last().unwrap()
    );
}

/// Lines sent at once before each stop of [`stops_behind_bursts`].
const BURST: u64 = 1000;

/// `rounds` emergency stops, each behind a burst of [`BURST`] lines in
/// flight, each released; their latencies (line to the last stop frame,
/// µs), sorted.
fn stops_behind_bursts(input: &InputSender, rx: &mpsc::Receiver<Value>, rounds: usize) -> Vec<u64> {
    let mut loaded = stops_behind_bursts_in_order(input, rx, rounds);
    loaded.sort_unstable();
    loaded
}

/// [`stops_behind_bursts`], each round's stop in the order they came.
fn stops_behind_bursts_in_order(
    input: &InputSender,
    rx: &mpsc::Receiver<Value>,
    rounds: usize,
) -> Vec<u64> {
    let mut loaded = Vec::new();
    for _ in 0..rounds {
        for i in 0..BURST {
            input.line(Origin(2), line(i));
        }
        input.line(Origin(3), r#"{"emergency_stop": true}"#);
        let mut left = BURST + 1;
        while left > 0 {
            let r = rx.recv_timeout(Duration::from_secs(5)).unwrap();
            left -= 1;
            if r["emergency_stop"] == true {
                loaded.push(r["stop_latency_us"].as_u64().unwrap());
            }
        }
        input.line(Origin(3), r#"{"emergency_stop": false}"#);
        let r = rx.recv_timeout(Duration::from_secs(5)).unwrap();
        assert_eq!(r["released"], true, "{r}");
    }
    loaded
}

/// A recorder as `--record DIR` starts it, into `dir` made anew.
fn recording_into(dir: &std::path::Path) -> std::sync::Arc<motorwire_record::record::Recorder> {
    let _ = std::fs::remove_dir_all(dir);
    std::sync::Arc::new(
        motorwire_record::record::Recorder::start(motorwire_record::record::RecordConfig {
            dir: dir.to_owned(),
            max_bytes: motorwire_record::record::DEFAULT_RECORD_MAX,
            interface: "sim".to_owned(),
            setup: None,
        })
        .unwrap(),
    )
}

/// The stop behind a burst with the session recorded (`--record`) and
/// without, alternated in the same run (`passes` of `rounds` each way),
/// the same map and lines: (median, p99) off, then on, in µs.
fn recording_cost(passes: usize, rounds: usize) {
    let dir = std::env::temp_dir().join(format!("motorwire-bench-record-{}", std::process::id()));
    // The first stops of each pass, after the bridge (and the recorder)
    // started, apart from the rest.
    const FIRST: usize = 3;
    let mut off: Vec<u64> = Vec::new();
    let mut on: Vec<u64> = Vec::new();
    let mut off_first: Vec<u64> = Vec::new();
    let mut on_first: Vec<u64> = Vec::new();
    let mut dropped = 0;
    // Each pass's median on over its median off: the machine's drift
    // between passes cancels in a pair.
    let mut ratios = Vec::new();
    for _ in 0..passes {
        let mut medians = [0u64; 2];
        for record in [false, true] {
            let recorder = record.then(|| recording_into(&dir));
            let (_arm, input, lean, handle) = started_lean(
                MAP,
                recorder
                    .as_ref()
                    .map(|r| std::sync::Arc::clone(r) as std::sync::Arc<dyn Tap>),
            );
            let stops = stops_behind_bursts_lean(&input, &lean, rounds);
            input.interrupt();
            handle.join().unwrap().unwrap();
            if let Some(r) = recorder.and_then(|r| std::sync::Arc::try_unwrap(r).ok()) {
                dropped += r.finish().dropped;
            }
            let (first, steady) = if record {
                (&mut on_first, &mut on)
            } else {
                (&mut off_first, &mut off)
            };
            first.extend(stops.iter().take(FIRST));
            steady.extend(stops.iter().skip(FIRST));
            let mut this: Vec<u64> = stops.iter().skip(FIRST).copied().collect();
            this.sort_unstable();
            medians[usize::from(record)] = percentile(&this, 0.5);
        }
        #[allow(clippy::cast_precision_loss)]
        ratios.push(medians[1] as f64 / medians[0].max(1) as f64);
    }
    ratios.sort_by(f64::total_cmp);
    let _ = std::fs::remove_dir_all(&dir);
    off.sort_unstable();
    on.sort_unstable();
    off_first.sort_unstable();
    on_first.sort_unstable();
    println!(
        "bridge/recording: the first {FIRST} stops of each pass ({} each way): median {} us, p99 {} us, max {} us without recording; median {} us, p99 {} us, max {} us recording",
        off_first.len(),
        percentile(&off_first, 0.5),
        percentile(&off_first, 0.99),
        off_first.last().copied().unwrap_or(0),
        percentile(&on_first, 0.5),
        percentile(&on_first, 0.99),
        on_first.last().copied().unwrap_or(0),
    );
    println!(
        "bridge/recording: {} stops behind {BURST} lines each way, after the first {FIRST} of each pass; line to the last stop frame: {} ({dropped} records dropped)",
        off.len(),
        off_and_on(&off, &on),
    );
    println!(
        "bridge/recording: each pass's median on over its median off ({} pairs): median {:.2}, quartiles {:.2} and {:.2}",
        ratios.len(),
        percentile(&ratios, 0.5),
        percentile(&ratios, 0.25),
        percentile(&ratios, 0.75),
    );
}

/// A recorder that records only while open: the paired comparison's
/// recording bridge, closed while the other bridge's round runs, so its
/// recorder (its devices' telemetry coming every 10 ms) is idle and asleep
/// then.
#[derive(Debug)]
struct Switched {
    open: std::sync::atomic::AtomicBool,
    recorder: std::sync::Arc<motorwire_record::record::Recorder>,
}

impl Switched {
    fn open(&self) -> bool {
        self.open.load(std::sync::atomic::Ordering::Relaxed)
    }
}

impl Tap for Switched {
    fn input(&self, at: Instant, origin: Origin, number: u64, text: &str) {
        if self.open() {
            Tap::input(&*self.recorder, at, origin, number, text);
        }
    }
    fn input_owned(&self, at: Instant, taken: Instant, origin: Origin, number: u64, text: String) {
        if self.open() {
            self.recorder.input_owned(at, taken, origin, number, text);
        }
    }
    fn unreadable(&self, line: &motorwire_bridge::tap::Unreadable<'_>) {
        if self.open() {
            Tap::unreadable(&*self.recorder, line);
        }
    }
    fn output_owned(&self, at: Instant, output: Output) {
        if self.open() {
            self.recorder.output_owned(at, output);
        }
    }
    fn output_line_owned(&self, at: Instant, output: Output, line: &std::sync::Arc<str>) {
        if self.open() {
            self.recorder.output_line_owned(at, output, line);
        }
    }
    fn output_line(&self, at: Instant, output: &Output, line: &std::sync::Arc<str>) {
        if self.open() {
            self.recorder.output_line(at, output, line);
        }
    }
    fn frame(&self, at: Instant, dir: Direction, frame: &motorwire_can::Frame) {
        if self.open() {
            Tap::frame(&*self.recorder, at, dir, frame);
        }
    }
    fn frame_taken(&self, at: Instant, taken: Instant, frame: &motorwire_can::Frame) {
        if self.open() {
            self.recorder.frame_taken(at, taken, frame);
        }
    }
    fn orion(&self, at: Instant, dir: Direction, line: &str) {
        if self.open() {
            Tap::orion(&*self.recorder, at, dir, line);
        }
    }
    fn mark(&self, at: Instant, mark: motorwire_bridge::tap::Mark) {
        if self.open() {
            Tap::mark(&*self.recorder, at, mark);
        }
    }
    fn hush(&self, on: bool) {
        self.recorder.hush(on);
    }
}

/// The recorder's cost on the stop behind a burst, with the machine's
/// drift cancelled stop by stop: two bridges at once, each on its own
/// simulated arm, one recording the session (`--record`) and one not,
/// their rounds (a burst, its stop, the release) alternated in the order
/// on, off, off, on, ... (so a steady drift falls on both alike). Before
/// every round the recorder has written all it was handed and its writer
/// sleeps (`Recorder::is_idle`): a round without recording runs with no
/// recorder at work beside it, and a round with one starts the same way
/// each time. `pairs` rounds each way after three warming ones each way.
///
/// [`recording_cost`] alternates whole passes (a bridge started for each);
/// the passes' medians moved by more than the 10 % looked for between runs
/// of one build (0.92 to 1.28, BENCHMARKS.md), which the pairing here
/// takes out of the comparison.
fn recording_paired(pairs: usize) {
    use std::sync::Arc;
    let dir = std::env::temp_dir().join(format!("motorwire-bench-paired-{}", std::process::id()));
    let recorder = recording_into(&dir);
    let switched = Arc::new(Switched {
        open: std::sync::atomic::AtomicBool::new(false),
        recorder: Arc::clone(&recorder),
    });
    let (arm_on, input_on, lean_on, handle_on) =
        started_lean(MAP, Some(Arc::clone(&switched) as Arc<dyn Tap>));
    let (arm_off, input_off, lean_off, handle_off) = started_lean(MAP, None);
    let until_idle = || {
        let end = Instant::now() + Duration::from_secs(30);
        while !recorder.is_idle() {
            assert!(Instant::now() < end, "the recorder never idle");
            std::thread::sleep(Duration::from_millis(1));
        }
    };
    let round = |record: bool| {
        until_idle();
        if record {
            switched
                .open
                .store(true, std::sync::atomic::Ordering::Relaxed);
            let stop = stops_behind_bursts_lean(&input_on, &lean_on, 1)[0];
            switched
                .open
                .store(false, std::sync::atomic::Ordering::Relaxed);
            stop
        } else {
            stops_behind_bursts_lean(&input_off, &lean_off, 1)[0]
        }
    };
    for _ in 0..3 {
        round(true);
        round(false);
    }
    let (mut on, mut off) = (Vec::with_capacity(pairs), Vec::with_capacity(pairs));
    for k in 0..pairs {
        let first = k % 2 == 0;
        let a = round(first);
        let b = round(!first);
        let (with, without) = if first { (a, b) } else { (b, a) };
        on.push(with);
        off.push(without);
    }
    input_on.interrupt();
    input_off.interrupt();
    handle_on.join().unwrap().unwrap();
    handle_off.join().unwrap().unwrap();
    drop((arm_on, arm_off, switched));
    let dropped = Arc::try_unwrap(recorder)
        .ok()
        .map_or(0, |r| r.finish().dropped);
    let _ = std::fs::remove_dir_all(&dir);

    // Every pair as measured, for runs pooled later or a look of one's own
    // (`MOTORWIRE_BENCH_RECORDING_SAMPLES=FILE`: "on off" in µs, a line a
    // pair, in the order run).
    if let Some(path) = std::env::var_os("MOTORWIRE_BENCH_RECORDING_SAMPLES") {
        let text: String = on
            .iter()
            .zip(&off)
            .map(|(a, b)| format!("{a} {b}\n"))
            .collect();
        std::fs::write(path, text).unwrap();
    }
    println!(
        "bridge/recording_paired: {pairs} stops behind {BURST} lines each way, two bridges alternated round by round ({dropped} records dropped)"
    );
    paired_report(on, off);
}

/// The pairs of several runs of [`recording_paired`] as one sample
/// (`MOTORWIRE_BENCH_RECORDING_POOL=FILE:FILE:...`, each file written by
/// `MOTORWIRE_BENCH_RECORDING_SAMPLES`): the intervals of one run are
/// wider than 10 %.
fn recording_pooled(files: &std::ffi::OsStr) {
    let (mut on, mut off) = (Vec::new(), Vec::new());
    for path in std::env::split_paths(files) {
        let text = std::fs::read_to_string(&path).unwrap();
        for l in text.lines() {
            let mut v = l.split(' ').map(|x| x.parse::<u64>().unwrap());
            on.push(v.next().unwrap());
            off.push(v.next().unwrap());
        }
    }
    println!(
        "bridge/recording_paired: {} pairs pooled from {}",
        on.len(),
        files.to_string_lossy()
    );
    paired_report(on, off);
}

/// The median, p95 and p99 of stops without recording (`off`) and with
/// (`on`), both sorted.
fn off_and_on(off: &[u64], on: &[u64]) -> String {
    let said = |v: &[u64]| {
        format!(
            "median {} us, p95 {} us, p99 {} us",
            percentile(v, 0.5),
            percentile(v, 0.95),
            percentile(v, 0.99)
        )
    };
    format!("{} without recording; {} recording", said(off), said(on))
}

/// The statistics of paired stops with recording (`on`) and without.
fn paired_report(on: Vec<u64>, off: Vec<u64>) {
    // On over off over the pairs `idx`: of the medians, the means, the
    // p95s and the p99s.
    #[allow(clippy::cast_precision_loss)]
    let ratios = |idx: &[usize]| -> [f64; 4] {
        let mut a: Vec<u64> = idx.iter().map(|&i| on[i]).collect();
        let mut b: Vec<u64> = idx.iter().map(|&i| off[i]).collect();
        a.sort_unstable();
        b.sort_unstable();
        let sum = |v: &[u64]| v.iter().sum::<u64>().max(1) as f64;
        let at = |p: f64| percentile(&a, p) as f64 / percentile(&b, p).max(1) as f64;
        [at(0.5), sum(&a) / sum(&b), at(0.95), at(0.99)]
    };
    let all: Vec<usize> = (0..on.len()).collect();
    let measured = ratios(&all);
    // Their 95 % intervals: the pairs resampled (a bootstrap of 2,000, a
    // fixed seed, so a run is repeatable from its samples).
    let mut seed = 0x2545_f491_4f6c_dd1d_u64;
    let mut next = |n: usize| {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        #[allow(clippy::cast_possible_truncation)]
        let i = (seed % n as u64) as usize;
        i
    };
    let mut resampled: [Vec<f64>; 4] = Default::default();
    for _ in 0..2000 {
        let idx: Vec<usize> = (0..on.len()).map(|_| next(on.len())).collect();
        for (k, r) in ratios(&idx).into_iter().enumerate() {
            resampled[k].push(r);
        }
    }
    for r in &mut resampled {
        r.sort_by(f64::total_cmp);
    }
    let (mut on, mut off) = (on, off);
    on.sort_unstable();
    off.sort_unstable();
    println!(
        "bridge/recording_paired: line to the last stop frame: {}",
        off_and_on(&off, &on)
    );
    let deciles = |v: &[u64]| {
        (1..10)
            .map(|d| percentile(v, f64::from(d) / 10.0).to_string())
            .collect::<Vec<_>>()
            .join(" ")
    };
    println!(
        "bridge/recording_paired: deciles without recording {} us; recording {} us",
        deciles(&off),
        deciles(&on)
    );
    let said: Vec<String> = ["median", "mean", "p95", "p99"]
        .iter()
        .zip(measured)
        .zip(&resampled)
        .map(|((name, m), r)| {
            format!(
                "{name} {m:.3} (95 % interval {:.3} to {:.3})",
                percentile(r, 0.025),
                percentile(r, 0.975)
            )
        })
        .collect();
    println!("bridge/recording_paired: on / off: {}", said.join(", "));
}

/// Emergency stop latency (line to the last stop frame on the bus) for a
/// map of one dialect: `n` stops, each released, on the real-time
/// simulated devices. (median, p99) in µs.
fn stop_latency(map: &str, orion: bool, n: usize) -> (u64, u64) {
    let (_arm, input, rx, handle) = started(map, orion);
    let stops = stop_each_released(&input, &rx, n);
    input.interrupt();
    handle.join().unwrap().unwrap();
    (percentile(&stops, 0.5), percentile(&stops, 0.99))
}

/// The demo map's motors of one dialect.
fn only(dialect: &str) -> String {
    MAP.split("\n[motors.")
        .enumerate()
        .filter(|(i, part)| *i == 0 || part.contains(&format!("dialect = \"{dialect}\"")))
        .map(|(i, part)| {
            if i == 0 {
                part.to_owned()
            } else {
                format!("[motors.{part}")
            }
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// The stop's latency per dialect: the three iRPC joints alone, the
/// compact gripper alone, the Orion arm alone, and the whole map.
fn stop_per_dialect(n: usize) {
    let (irpc, compact, orion) = (only("irpc"), only("compact"), only("orion"));
    for (name, map, with_orion) in [
        ("iRPC joints (3)", irpc.as_str(), false),
        ("compact device (1)", compact.as_str(), false),
        ("Orion arm (7 motors, 1 line)", orion.as_str(), true),
        ("whole map (3 + 1 + 7)", MAP, true),
    ] {
        let (median, p99) = stop_latency(map, with_orion, n);
        println!(
            "bridge/stop_per_dialect: {name}: {n} stops; line to the last stop frame: median {median} us, p99 {p99} us"
        );
    }
}

/// A policy streaming position setpoints (`"stream":true`) to the
/// simulated elbow at `hz` for `seconds`: a 0.5 Hz sine of amplitude 20
/// degrees about 60, in simulated time. Returns the tracking error's RMS
/// and maximum (degrees, the joint against the sine at each millisecond
/// after the first second), the lag (the shift of the sine, in ms, that
/// fits the joint best, up to 1.5 s), output lines per input line, and the wall-clock
/// time the run took (the bridge and the simulated joint together).
#[allow(clippy::type_complexity)]
fn stream_tracking(hz: u32, seconds: u32, stream: bool) -> (f64, f64, u32, f64, f64, Duration) {
    let mut arm = simulated_arm(MAP);
    let wave = |t: f64| 60.0 + 20.0 * (std::f64::consts::TAU * 0.5 * t).sin();
    // From where the stream starts.
    arm.line(
        Origin(1),
        r#"{"motor_id":"elbow","timestamp":1704067200000,"control_mode":"position","setpoint":60}"#,
    );
    arm.run_until(arm.now() + Duration::from_secs(3)).unwrap();
    arm.take_outputs();
    let t0 = arm.now();
    let period_us = 1_000_000 / u64::from(hz);
    let (mut inputs, mut outputs) = (0u64, 0u64);
    let mut track = Vec::new();
    let mut next_us = 0u64;
    let wall = Instant::now();
    for ms in 0..u64::from(seconds) * 1000 {
        let now_us = ms * 1000;
        while next_us <= now_us {
            #[allow(clippy::cast_precision_loss)]
            let t = next_us as f64 / 1e6;
            let extra = if stream { r#","stream":true"# } else { "" };
            arm.line(
                Origin(1),
                &format!(
                    r#"{{"motor_id":"elbow","timestamp":1704067200000,"control_mode":"position","setpoint":{}{extra}}}"#,
                    wave(t)
                ),
            );
            inputs += 1;
            next_us += period_us;
        }
        arm.run_until(t0 + Duration::from_millis(ms + 1)).unwrap();
        outputs += arm.take_outputs().len() as u64;
        #[allow(clippy::cast_precision_loss)]
        let t = (ms + 1) as f64 / 1000.0;
        track.push((t, arm.joint(0x12).unwrap().position()));
    }
    let wall = wall.elapsed();
    let error = |lag_ms: u32| {
        let lag = f64::from(lag_ms) / 1000.0;
        let e: Vec<f64> = track
            .iter()
            .filter(|(t, _)| *t > 1.0)
            .map(|(t, p)| p - wave(t - lag))
            .collect();
        #[allow(clippy::cast_precision_loss)]
        let rms = (e.iter().map(|x| x * x).sum::<f64>() / e.len() as f64).sqrt();
        (rms, e.iter().fold(0.0f64, |m, x| m.max(x.abs())))
    };
    let (rms, max) = error(0);
    let lag = (0..=1500)
        .min_by(|a, b| error(*a).0.total_cmp(&error(*b).0))
        .unwrap_or(0);
    #[allow(clippy::cast_precision_loss)]
    let per_line = outputs as f64 / inputs as f64;
    let (rms_lagged, _) = error(lag);
    (rms, max, lag, rms_lagged, per_line, wall)
}

fn stream_benches(seconds: u32) {
    for hz in [5, 30, 100, 500] {
        for stream in [true, false] {
            let (rms, max, lag, rms_lagged, per_line, wall) = stream_tracking(hz, seconds, stream);
            println!(
                "bridge/stream: {hz} Hz, {}: tracking error RMS {rms:.2} deg, max {max:.2} deg, lag {lag} ms (RMS {rms_lagged:.2} deg behind it), {per_line:.2} output lines per input line, {seconds} s simulated in {:.0} ms",
                if stream {
                    "\"stream\":true"
                } else {
                    "ordinary commands"
                },
                wall.as_secs_f64() * 1000.0
            );
        }
    }
}

/// Each thread's context switches so far (voluntary, involuntary), by its
/// id, with its name: read from `/proc/self/task` (Linux).
fn switches() -> std::collections::BTreeMap<u32, (String, u64, u64)> {
    let mut out = std::collections::BTreeMap::new();
    let Ok(tasks) = std::fs::read_dir("/proc/self/task") else {
        return out;
    };
    for task in tasks.flatten() {
        let Some(tid) = task.file_name().to_str().and_then(|t| t.parse().ok()) else {
            continue;
        };
        let dir = task.path();
        let name = std::fs::read_to_string(dir.join("comm")).unwrap_or_default();
        let status = std::fs::read_to_string(dir.join("status")).unwrap_or_default();
        let count = |key: &str| {
            status
                .lines()
                .find_map(|l| l.strip_prefix(key))
                .and_then(|v| v.trim().parse().ok())
                .unwrap_or(0)
        };
        out.insert(
            tid,
            (
                name.trim().to_owned(),
                count("voluntary_ctxt_switches:"),
                count("nonvoluntary_ctxt_switches:"),
            ),
        );
    }
    out
}

/// The context switches each thread made between `before` and now, per
/// line of `lines`, by thread name (the benchmark's own thread, which
/// sends the lines and waits for their results, is `bench`), and the sum
/// over the bridge's threads (every thread but the benchmark's).
fn switches_per_line(
    before: &std::collections::BTreeMap<u32, (String, u64, u64)>,
    lines: u64,
    bench: u32,
) -> (String, f64) {
    let after = switches();
    let mut by_name: std::collections::BTreeMap<String, (u64, u64)> =
        std::collections::BTreeMap::new();
    let mut bridge = 0;
    for (tid, (name, v, n)) in &after {
        let (v0, n0) = before.get(tid).map_or((0, 0), |(_, v, n)| (*v, *n));
        let (dv, dn) = (v - v0, n - n0);
        if dv + dn == 0 {
            continue;
        }
        let name = if *tid == bench {
            "bench".to_owned()
        } else {
            name.clone()
        };
        if *tid != bench {
            bridge += dv;
        }
        let e = by_name.entry(name).or_default();
        e.0 += dv;
        e.1 += dn;
    }
    #[allow(clippy::cast_precision_loss)]
    let per = |x: u64| x as f64 / lines as f64;
    let said = by_name
        .iter()
        .map(|(name, (v, n))| format!("{name} {:.2}+{:.2}", per(*v), per(*n)))
        .collect::<Vec<_>>()
        .join(", ");
    (said, per(bridge))
}

/// This thread's id (Linux).
fn thread_id() -> u32 {
    std::fs::read_link("/proc/thread-self")
        .ok()
        .and_then(|p| p.file_name()?.to_str()?.parse().ok())
        .unwrap_or(0)
}

/// The threads a line wakes and the stop behind a burst
/// (`MOTORWIRE_BENCH_WAKEUPS_ONLY=1`): on the real-time simulated demo
/// arm, `n` lines one at a time (each sent when the one before was
/// answered) and `n` with 16 in flight, each thread's voluntary and
/// involuntary context switches per line (from `/proc/self/task`); the
/// lines' line-to-frame time; then `stops` emergency stops, each behind a
/// burst of [`BURST`] lines, on the lean sink.
fn wakeups(n: u64, stops: usize) {
    let bench = thread_id();
    let (_arm, input, rx, handle) = started(MAP, false);
    // Warm: the first lines plan and allocate.
    for i in 0..100 {
        input.line(Origin(1), line(i));
        rx.recv_timeout(Duration::from_secs(5)).unwrap();
    }
    // The devices' own traffic (encoder and status frames, timers) with
    // no line: its rate is taken off the lines' counts below.
    let idle = Duration::from_secs(1);
    let before = switches();
    std::thread::sleep(idle);
    let (said, idle_rate) = switches_per_line(&before, 1, bench);
    println!("bridge/wakeups: idle, context switches a second: {said}");
    let before = switches();
    let began = Instant::now();
    let mut latencies = Vec::new();
    for i in 0..n {
        input.line(Origin(1), line(i));
        let r = rx.recv_timeout(Duration::from_secs(5)).unwrap();
        assert_eq!(r["ok"], true, "{r}");
        latencies.push(r["latency_us"].as_u64().unwrap());
    }
    let (said, bridge) = switches_per_line(&before, n, bench);
    #[allow(clippy::cast_precision_loss)]
    let idle_share = idle_rate * began.elapsed().as_secs_f64() / n as f64;
    latencies.sort_unstable();
    println!(
        "bridge/wakeups: {n} lines one at a time: context switches a line (voluntary+involuntary): {said}; the bridge's threads, voluntary: {bridge:.2} a line, {:.2} with the idle rate taken off; line to frame: median {} us, p99 {} us",
        bridge - idle_share,
        percentile(&latencies, 0.5),
        percentile(&latencies, 0.99)
    );
    const WINDOW: u64 = 16;
    let before = switches();
    let (mut sent, mut done) = (0, 0);
    let mut latencies = Vec::new();
    while done < n {
        while sent < n && sent - done < WINDOW {
            input.line(Origin(1), line(sent));
            sent += 1;
        }
        let r = rx.recv_timeout(Duration::from_secs(5)).unwrap();
        done += 1;
        if let Some(l) = r["latency_us"].as_u64() {
            latencies.push(l);
        }
    }
    let (said, bridge) = switches_per_line(&before, n, bench);
    latencies.sort_unstable();
    println!(
        "bridge/wakeups: {n} lines, {WINDOW} in flight: context switches a line: {said}; the bridge's threads, voluntary: {bridge:.2} a line; line to frame: median {} us, p99 {} us",
        percentile(&latencies, 0.5),
        percentile(&latencies, 0.99)
    );
    input.interrupt();
    handle.join().unwrap().unwrap();
    if stops == 0 {
        return;
    }
    let (_arm, input, lean, handle) = started_lean(MAP, None);
    let mut loaded = stops_behind_bursts_lean(&input, &lean, stops);
    input.interrupt();
    handle.join().unwrap().unwrap();
    loaded.sort_unstable();
    println!(
        "bridge/wakeups: {} stops, each behind a burst of {BURST} lines; line to the last stop frame: median {} us, p99 {} us, max {} us",
        loaded.len(),
        percentile(&loaded, 0.5),
        percentile(&loaded, 0.99),
        loaded.last().unwrap()
    );
}

fn main() {
    // `cargo bench` passes --bench; `cargo test --benches` does not (test mode).
    if std::env::var_os("MOTORWIRE_BENCH_STREAM_ONLY").is_some() {
        stream_benches(10);
        return;
    }
    let test_mode = !std::env::args().any(|a| a == "--bench");
    // `MOTORWIRE_BENCH_WAKEUPS_ONLY=1`: the threads a line wakes, and the
    // stop behind bursts (`MOTORWIRE_BENCH_WAKEUPS_STOPS`, 1,000 by default).
    if std::env::var_os("MOTORWIRE_BENCH_WAKEUPS_ONLY").is_some() {
        let stops = std::env::var("MOTORWIRE_BENCH_WAKEUPS_STOPS")
            .ok()
            .and_then(|p| p.parse().ok())
            .unwrap_or(1000);
        wakeups(
            if test_mode { 50 } else { 5000 },
            if test_mode { 3 } else { stops },
        );
        return;
    }
    if let Some(files) = std::env::var_os("MOTORWIRE_BENCH_RECORDING_POOL") {
        recording_pooled(&files);
        return;
    }
    let recording_only = std::env::var_os("MOTORWIRE_BENCH_RECORDING_ONLY").is_some();
    if !recording_only {
        let mut c = Criterion::default().configure_from_args();
        benches(&mut c);
        c.final_summary();
    }
    // Under an instruction counter, only the simulated-time benchmarks:
    // `MOTORWIRE_BENCH_SIMULATED_ONLY=1 valgrind --tool=callgrind ...`.
    if std::env::var_os("MOTORWIRE_BENCH_SIMULATED_ONLY").is_some() {
        return;
    }
    // `MOTORWIRE_BENCH_RECORDING_ONLY=1`: the recorder's cost alone.
    if !recording_only {
        real_time(if test_mode { 20 } else { 5000 });
        stop_per_dialect(if test_mode { 5 } else { 500 });
    }
    if test_mode {
        recording_paired(2);
        recording_cost(1, 4);
        return;
    }
    // `MOTORWIRE_BENCH_RECORDING_PAIRS`: stops each way of the paired
    // comparison (0: not run).
    let pairs = std::env::var("MOTORWIRE_BENCH_RECORDING_PAIRS")
        .ok()
        .and_then(|p| p.parse().ok())
        .unwrap_or(400);
    if pairs > 0 {
        recording_paired(pairs);
    }
    // More passes narrow the tail's run-to-run spread (the p99 of 200
    // stops is their third worst); 0: not run.
    let passes = std::env::var("MOTORWIRE_BENCH_RECORDING_PASSES")
        .ok()
        .and_then(|p| p.parse().ok())
        .unwrap_or(8);
    if passes > 0 {
        recording_cost(passes, 25);
    }
}
