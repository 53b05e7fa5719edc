//! The one harness of the bridge's integration tests: a bridge on the
//! simulated arm in simulated time (the sans-IO engine and its devices,
//! stepped together, as quinn's tests step a `Pair`), and the lines and
//! readings every test file uses. Each test file takes it with
//! `mod common;`; none writes its own.
#![allow(dead_code, clippy::unwrap_used, clippy::expect_used)]

use std::time::Duration;

use motorwire_bridge::sim::SimulatedArm;
use motorwire_bridge::{Bridge, BridgeConfig, Origin, Output};
use motorwire_can::{Faults, SimConfig};
use motorwire_orion::{ArmController, FeedbackKeys};
use motorwire_translate::BusMap;
use serde_json::Value;

/// `n` milliseconds.
pub(crate) fn ms(n: u64) -> Duration {
    Duration::from_millis(n)
}

/// A bridge on `map` with `config`, on simulated devices as `sim` says,
/// run until it is ready (at most 3 s of simulated time; it must be).
pub(crate) fn ready(map: &str, config: BridgeConfig, sim: SimConfig) -> SimulatedArm {
    let bridge = Bridge::new(BusMap::from_toml(map).unwrap(), config).unwrap();
    let mut arm = SimulatedArm::new(bridge, sim).unwrap();
    assert!(
        arm.run_while(Duration::from_secs(3), |a| a.bridge().is_ready())
            .unwrap(),
        "the bridge was not ready within 3 s"
    );
    arm
}

/// [`ready`] with the default bridge, on a bus with `faults` drawn from
/// `seed`.
pub(crate) fn arm(map: &str, faults: Faults, seed: u64) -> SimulatedArm {
    let sim = SimConfig {
        seed,
        faults,
        ..SimConfig::default()
    };
    ready(map, BridgeConfig::default(), sim)
}

/// A position command line for `motor` to `setpoint` (its unit).
pub(crate) fn command(motor: &str, setpoint: f64) -> String {
    format!(
        r#"{{"motor_id":"{motor}","timestamp":1,"control_mode":"position","setpoint":{setpoint}}}"#
    )
}

/// A velocity command line for `motor` at `speed` (its unit a second).
pub(crate) fn velocity(motor: &str, speed: f64) -> String {
    format!(
        r#"{{"motor_id":"{motor}","timestamp":1,"control_mode":"velocity","setpoint":{speed}}}"#
    )
}

/// Runs until `n` results are in (at most `limit`), returning them.
pub(crate) fn results(arm: &mut SimulatedArm, n: usize, limit: Duration) -> Vec<Value> {
    let mut got = Vec::new();
    let end = arm.now() + limit;
    while got.len() < n && arm.now() < end {
        arm.step(Duration::from_millis(10)).unwrap();
        got.extend(arm.take_results());
    }
    got
}

/// Runs for `d`, returning every output as JSON.
pub(crate) fn run_for(arm: &mut SimulatedArm, d: Duration) -> Vec<Value> {
    arm.run_until(arm.now() + d).unwrap();
    arm.take_outputs().iter().map(Output::to_value).collect()
}

/// The results and completions so far, taken, as JSON.
pub(crate) fn answers(arm: &mut SimulatedArm) -> Vec<Value> {
    arm.take_outputs()
        .into_iter()
        .filter(|o| matches!(o, Output::Result { .. } | Output::Arrival { .. }))
        .map(|o| o.to_value())
        .collect()
}

/// Every output so far but feedback, taken, as JSON.
pub(crate) fn outputs(arm: &mut SimulatedArm) -> Vec<Value> {
    arm.take_outputs()
        .iter()
        .filter(|o| !matches!(o, Output::Feedback(_)))
        .map(Output::to_value)
        .collect()
}

/// A bridge and the Orion arm controller on its link, on one simulated
/// clock (the controller's own model answers each line the bridge writes).
pub(crate) struct OrionRig {
    pub(crate) bridge: Bridge,
    pub(crate) arm: ArmController,
    pub(crate) now: Duration,
    /// Every line the bridge wrote to the controller.
    pub(crate) sent: Vec<String>,
    /// Answers held back (the controller is slow): delivered by `release`.
    pub(crate) held: Vec<String>,
    /// Whether the controller answers (false: it hears nothing).
    pub(crate) answering: bool,
    /// Whether answers are held back.
    pub(crate) holding: bool,
    pub(crate) out: Vec<Value>,
}

impl OrionRig {
    pub(crate) fn new(map: &str) -> Self {
        let config = BridgeConfig {
            line_link: true,
            activate_on_start: false,
            ..BridgeConfig::default()
        };
        let mut bridge = Bridge::new(BusMap::from_toml(map).unwrap(), config).unwrap();
        bridge.start(Duration::ZERO);
        let mut rig = Self {
            bridge,
            arm: ArmController::new(),
            now: Duration::ZERO,
            sent: Vec::new(),
            held: Vec::new(),
            answering: true,
            holding: false,
            out: Vec::new(),
        };
        rig.pump();
        rig
    }

    /// The controller boots: its beacon.
    pub(crate) fn boot(&mut self) {
        self.bridge.handle_link_line(self.now, r#"{"ID":32}"#);
        self.pump();
    }

    pub(crate) fn pump(&mut self) {
        loop {
            let mut any = false;
            while let Some(line) = self.bridge.poll_link_line() {
                any = true;
                self.sent.push(line.clone());
                if !self.answering {
                    continue;
                }
                let answer = self
                    .arm
                    .handle_line(&line)
                    .unwrap()
                    .output
                    .to_json(FeedbackKeys::Table);
                if self.holding {
                    self.held.push(answer);
                } else {
                    self.bridge.handle_link_line(self.now, &answer);
                }
            }
            while self.bridge.poll_transmit().is_some() {}
            self.bridge.flushed(self.now);
            while let Some(o) = self.bridge.poll_output() {
                any = true;
                self.out.push(o.to_value());
            }
            if !any {
                break;
            }
        }
    }

    pub(crate) fn release(&mut self) {
        for answer in std::mem::take(&mut self.held) {
            self.bridge.handle_link_line(self.now, &answer);
        }
        self.pump();
    }

    pub(crate) fn line(&mut self, text: &str) {
        self.bridge.handle_line(self.now, Origin(0), text);
        self.pump();
    }

    pub(crate) fn advance(&mut self, by: Duration) {
        let end = self.now + by;
        while self.now < end {
            self.now = (self.now + Duration::from_millis(5)).min(end);
            self.bridge.handle_timeout(self.now);
            self.pump();
        }
    }

    /// The lines written since `from`, polls (empty DATA) left out.
    pub(crate) fn commands_since(&self, from: usize) -> Vec<&str> {
        self.sent[from..]
            .iter()
            .map(String::as_str)
            .filter(|l| *l != r#"{"ID":32,"MODE":1,"DATA":{}}"#)
            .collect()
    }

    pub(crate) fn result(&self, line: u64) -> Option<&Value> {
        self.out
            .iter()
            .find(|v| v["line"] == line && v.get("ok").is_some())
    }
}
