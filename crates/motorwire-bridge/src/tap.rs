//! What a [`crate::Runner`] tells whoever watches a session (a recorder, a
//! live view): the [`Tap`] trait and what it is told. It lives beside the
//! runtime that calls it; the recorder (`motorwire-record`) implements it.

use std::sync::Arc;
use std::time::Instant;

use motorwire_can::Frame;

use crate::output::{Origin, Output};

/// Which way a frame or a device line went.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Direction {
    /// The bridge sent it.
    Tx,
    /// The bridge received it.
    Rx,
}

impl Direction {
    /// Its name in a recording (`tx`, `rx`).
    pub const fn name(self) -> &'static str {
        match self {
            Self::Tx => "tx",
            Self::Rx => "rx",
        }
    }
}

/// An input line the bridge could not read (too long, not UTF-8), as a
/// [`Tap`] is told of it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Unreadable<'a> {
    /// When it came.
    pub at: Instant,
    /// Whose it is.
    pub origin: Origin,
    /// Its number among its origin's lines.
    pub number: u64,
    /// Why it could not be read.
    pub reason: &'a str,
    /// It named `emergency_stop` and was taken as a stop.
    pub stop: bool,
    /// Its first bytes (at most [`crate::UNREADABLE_HEAD`]) and its
    /// length, where the reader kept them.
    pub bytes: Option<(&'a [u8], u64)>,
}

/// What a [`crate::Runner`] tells whoever watches the session (a
/// `motorwire_record`'s recorder, a live view): every line and frame, as it happens, from
/// the bridge's own thread. An implementation must never make it wait
/// (queue and return; drop and count when its queue is full): a stop is
/// never behind a watcher. Every method does nothing unless implemented.
pub trait Tap: Send + Sync + std::fmt::Debug {
    /// Input line `number` of `origin`, received at `at` (and taken now).
    fn input(&self, at: Instant, origin: Origin, number: u64, text: &str) {
        let _ = (at, origin, number, text);
    }
    /// The same, the line given to keep and told once the bridge has
    /// handled it (`taken`: when it began to): a tap that keeps lines takes
    /// it without a copy. The bridge's runner tells its taps of each line
    /// this way.
    fn input_owned(&self, at: Instant, taken: Instant, origin: Origin, number: u64, text: String) {
        let _ = taken;
        self.input(at, origin, number, &text);
    }
    /// An input line that could not be read.
    fn unreadable(&self, line: &Unreadable<'_>) {
        let _ = line;
    }
    /// An output line given at `at`.
    fn output(&self, at: Instant, output: &Output) {
        let _ = (at, output);
    }
    /// The same, the output given to keep: a tap that keeps outputs takes
    /// it without a copy. The bridge's runner tells its taps of each output
    /// this way, once the caller's sink has had it.
    fn output_owned(&self, at: Instant, output: Output) {
        self.output(at, &output);
    }
    /// An output given at `at` with its JSON line (`output.to_json()`),
    /// rendered once by [`crate::Runner::run_rendered`] for its sink and
    /// its taps alike: a tap that writes outputs as text keeps the line
    /// (shared, not copied) rather than the output.
    fn output_line(&self, at: Instant, output: &Output, line: &Arc<str>) {
        let _ = line;
        self.output(at, output);
    }
    /// The same, the output given to keep (the runner has no more use for
    /// it): a tap that keeps only the line lets the output go here, on the
    /// bridge's thread, where it was made.
    fn output_line_owned(&self, at: Instant, output: Output, line: &Arc<str>) {
        let _ = line;
        self.output_owned(at, output);
    }
    /// A frame sent or received at `at`.
    fn frame(&self, at: Instant, dir: Direction, frame: &Frame) {
        let _ = (at, dir, frame);
    }
    /// A frame received at `at` and taken by the bridge at `taken` (what a
    /// replay hands its bridge then).
    fn frame_taken(&self, at: Instant, taken: Instant, frame: &Frame) {
        let _ = taken;
        self.frame(at, Direction::Rx, frame);
    }
    /// A line to or from the Orion arm controller.
    fn orion(&self, at: Instant, dir: Direction, line: &str) {
        let _ = (at, dir, line);
    }
    /// Something else the bridge was told.
    fn mark(&self, at: Instant, mark: Mark) {
        let _ = (at, mark);
    }
    /// The bridge is handling a stop (`true`) until its frames are out
    /// (`false`): a tap with a thread of its own pauses its work meanwhile,
    /// so the stop has the machine's cores.
    fn hush(&self, on: bool) {
        let _ = on;
    }
}

/// Several taps as one: each told in turn.
#[derive(Debug)]
pub(crate) struct Taps(pub(crate) Vec<Arc<dyn Tap>>);

impl Tap for Taps {
    fn input(&self, at: Instant, origin: Origin, number: u64, text: &str) {
        for t in &self.0 {
            t.input(at, origin, number, text);
        }
    }
    fn input_owned(&self, at: Instant, taken: Instant, origin: Origin, number: u64, text: String) {
        if let Some((last, others)) = self.0.split_last() {
            for t in others {
                t.input(at, origin, number, &text);
            }
            last.input_owned(at, taken, origin, number, text);
        }
    }
    fn unreadable(&self, line: &Unreadable<'_>) {
        for t in &self.0 {
            t.unreadable(line);
        }
    }
    fn output(&self, at: Instant, output: &Output) {
        for t in &self.0 {
            t.output(at, output);
        }
    }
    fn output_owned(&self, at: Instant, output: Output) {
        // Each but the last sees it; the last keeps it.
        if let Some((last, others)) = self.0.split_last() {
            for t in others {
                t.output(at, &output);
            }
            last.output_owned(at, output);
        }
    }
    fn output_line(&self, at: Instant, output: &Output, line: &Arc<str>) {
        for t in &self.0 {
            t.output_line(at, output, line);
        }
    }
    fn output_line_owned(&self, at: Instant, output: Output, line: &Arc<str>) {
        if let Some((last, others)) = self.0.split_last() {
            for t in others {
                t.output_line(at, &output, line);
            }
            last.output_line_owned(at, output, line);
        }
    }
    fn frame(&self, at: Instant, dir: Direction, frame: &Frame) {
        for t in &self.0 {
            t.frame(at, dir, frame);
        }
    }
    fn frame_taken(&self, at: Instant, taken: Instant, frame: &Frame) {
        for t in &self.0 {
            t.frame_taken(at, taken, frame);
        }
    }
    fn orion(&self, at: Instant, dir: Direction, line: &str) {
        for t in &self.0 {
            t.orion(at, dir, line);
        }
    }
    fn mark(&self, at: Instant, mark: Mark) {
        for t in &self.0 {
            t.mark(at, mark.clone());
        }
    }
    fn hush(&self, on: bool) {
        for t in &self.0 {
            t.hush(on);
        }
    }
}

/// Something the bridge was told that is neither a line nor a frame: a
/// replay (`motorwire_record::replay`) tells the bridge the same at the same time.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Mark {
    /// The bridge started: its time zero (`"start"`).
    Start,
    /// A client connected and was greeted (`"greet"`).
    Greet(Origin),
    /// A client went away; its pending lines were cancelled (`"dropped"`).
    Dropped(Origin, String),
    /// The input ended (`"finish"`).
    Finish,
    /// A signal asked the bridge to stop (`"interrupt"`).
    Interrupt,
    /// The link to the Orion controller was lost (`"orion_lost"`).
    OrionLost(String),
    /// A line from the Orion controller could not be read
    /// (`"orion_unreadable"`).
    OrionUnreadable(String),
}

impl Mark {
    /// The mark as its `lines.jsonl` object: `{"kind":...}` and, where it
    /// has them, `origin` and `reason`.
    pub fn to_value(&self) -> serde_json::Value {
        use serde_json::json;
        match self {
            Self::Start => json!({"kind": "start"}),
            Self::Greet(o) => json!({"kind": "greet", "origin": o.0}),
            Self::Dropped(o, why) => json!({"kind": "dropped", "origin": o.0, "reason": why}),
            Self::Finish => json!({"kind": "finish"}),
            Self::Interrupt => json!({"kind": "interrupt"}),
            Self::OrionLost(why) => json!({"kind": "orion_lost", "reason": why}),
            Self::OrionUnreadable(why) => json!({"kind": "orion_unreadable", "reason": why}),
        }
    }

    /// The mark a `lines.jsonl` object describes (`None`: not a mark this
    /// version knows).
    pub fn from_value(v: &serde_json::Value) -> Option<Self> {
        let origin = || {
            v.get("origin")
                .and_then(serde_json::Value::as_u64)
                .map(Origin)
        };
        let reason = || {
            v.get("reason")
                .and_then(serde_json::Value::as_str)
                .map(str::to_owned)
        };
        Some(match v.get("kind")?.as_str()? {
            "start" => Self::Start,
            "greet" => Self::Greet(origin()?),
            "dropped" => Self::Dropped(origin()?, reason()?),
            "finish" => Self::Finish,
            "interrupt" => Self::Interrupt,
            "orion_lost" => Self::OrionLost(reason()?),
            "orion_unreadable" => Self::OrionUnreadable(reason()?),
            _ => return None,
        })
    }
}
