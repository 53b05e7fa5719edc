//! Replay: a recorded session's inputs fed again into the bridge on the
//! simulated bus, at their recorded times, and what comes out compared
//! with what was recorded.
//!
//! A recording ([`crate::record`]) holds every input line with its client
//! and time, what else the bridge was told (a client greeted or gone, the
//! end of input, a signal: [`Mark`]), every output line, every frame the
//! bridge sent and every line it wrote to the Orion controller, and in
//! `session.json` how the bridge was set up ([`Setup`]: its map, its
//! options, its first msg_id and its wall clock). [`replay`] makes the same
//! bridge, on a [`SimulatedArm`] in simulated time, and tells it the same
//! things at the same times (relative to its start), and sends what each
//! line set going before the next is taken. The simulated devices answer
//! where the recorded ones did, at once; an iRPC joint's answer to a
//! request (counted: [`motorwire_bridge::sim::AnswerKey`]) is handed to the bridge
//! when the recorded bridge took the recorded one (`taken_us` of a frame
//! received), with what the joint said with it, so a line taken between a
//! request and its answer finds the bridge as the recorded line did.
//! [`compare`] then looks for the first
//! difference, stream by stream:
//! - each line's answers (its result, its completion), per client and line;
//! - each client's own lines (its greeting);
//! - the events, in order: each device's in a stream of its own (and
//!   whether it is heard, `online`/`offline`, in another), the rest in
//!   one;
//! - the frames sent to each device, in order, each read in its dialect
//!   ([`frame_key`]): what the frame says, without what the clock decides
//!   (a request's msg_id, a compact command's timestamp), without the
//!   heartbeat (its count follows the clock) and without a request sent
//!   again (the same msg_id: a retry, which timing decides); a moteus
//!   controller's commands alone (its polls, which only query, follow the
//!   clock), and a command the same as the one before it once (a held
//!   move sent again at each poll, a stop repeated: how often, the clock
//!   decides);
//! - the lines written to the Orion controller, in order, without its
//!   polls (one every [`motorwire_bridge::ORION_POLL`] while idle).
//!
//! Values are compared as JSON (and the numbers within a text as numbers),
//! within a [`Tolerance`]: by default 0.05 (a number printed with
//! decimals, a unit of its last place), 2 units for a motor's position and
//! 5 units a second for its velocity caught in motion (a session recorded
//! in real time stops or reads a joint a few milliseconds off its replay);
//! without the members that measure time: `latency_us`, `ack_us`,
//! `stop_latency_us`, `after_ms`, and a device's clock in a request's
//! answer (`timestamp_us`, `active_time_ms`, `timestamp_ms`,
//! `timestamp_sec`). Feedback lines are not compared (their number follows
//! the clock); what they show is in the frames and the answers.
//!
//! Time is aligned at `ready`: what came before the recorded bridge was
//! ready comes before the simulated one is, what came after comes as long
//! after its `ready` (their startups take their own time).
//!
//! What a replay does not reproduce, by its nature: a session on a
//! simulated bus with faults (`--sim-faults`) replays with the same rates
//! and seed, but the faults fall on other frames (the heartbeats and polls
//! that draw them follow the clock); what the clock decides on the
//! simulated joints stays theirs: their telemetry, which says when a
//! stopped joint is at rest, and a lifecycle report sent apart from its
//! Ack (a query right after a stop or a release may find a joint moving,
//! active or inactive a few milliseconds off); the compact, moteus and Orion
//! devices answer at once; a recording made before frames received said
//! `taken_us` holds their answers to when they came off the bus.

use std::collections::{BTreeMap, HashMap, HashSet};
use std::fs;
use std::path::{Path, PathBuf};
use std::thread;
use std::time::{Duration, Instant};

use motorwire_can::candump::LogEntry;
use motorwire_can::{CanId, Faults, Frame, SimConfig};
use motorwire_irpc::{Header, Message, Payload, WireVersion};
use motorwire_translate::{BusMap, Target};
use serde::{Deserialize, Serialize};
use serde_json::Value;

use motorwire_bridge::sim::SimulatedArm;
use motorwire_bridge::tap::{Direction, Mark};
use motorwire_bridge::{Bridge, BridgeConfig, BridgeError, Origin, Output};

/// How the recorded bridge was set up: what a replay needs to make the
/// same bridge. `motorwire bridge --record` writes it into `session.json`
/// as `setup`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Setup {
    /// The bus map, as its TOML text.
    pub map: String,
    /// The bus the session ran on (`sim`, `socketcan:can0`).
    pub bus: String,
    /// The bridge's iRPC node id.
    pub node: u16,
    /// The wire version the bridge speaks by default.
    pub wire: String,
    /// Ack timeout (µs).
    pub ack_timeout_us: u64,
    /// Retries.
    pub retries: u8,
    /// The first msg_id.
    pub first_msg_id: u32,
    /// Whether the joints were configured and activated at start.
    pub activate_on_start: bool,
    /// The feedback period (µs; `None`: no feedback).
    pub feedback_period_us: Option<u64>,
    /// When a silent device is offline (µs).
    pub offline_after_us: u64,
    /// The heartbeat's period (µs).
    pub heartbeat_period_us: u64,
    /// How long the end of input waits for moves (µs).
    pub drain_timeout_us: u64,
    /// Unix milliseconds at the bridge's time zero.
    pub epoch_unix_ms: Option<f64>,
    /// The clock skew allowed (µs; `None`: not checked).
    pub max_age_us: Option<u64>,
    /// Lines in progress, at most.
    pub max_pending_lines: usize,
    /// Steps waiting for one joint, at most.
    pub max_queue_per_joint: usize,
    /// An Orion controller was attached.
    pub orion: bool,
    /// How long an Orion fold or unfold may take (µs).
    pub orion_command_timeout_us: u64,
    /// The telemetry subscription's rate.
    pub telemetry_hz: Option<u16>,
    /// Unknown members were taken as losses.
    pub allow_unknown_members: bool,
    /// With `bus` `sim`: the fault generator's seed.
    pub sim_seed: u64,
    /// With `bus` `sim`: the fault rates (`drop`, `duplicate`, `corrupt`,
    /// `delay`, `reorder`) and `max_delay_us`.
    pub sim_faults: BTreeMap<String, f64>,
}

fn us(d: Duration) -> u64 {
    u64::try_from(d.as_micros()).unwrap_or(u64::MAX)
}

impl Setup {
    /// The setup of a bridge made with `map_text` and `config`, on `bus`
    /// (with `sim` its simulated bus's `sim` configuration).
    pub fn of(map_text: &str, bus: &str, config: &BridgeConfig, sim: &SimConfig) -> Self {
        let f = sim.faults;
        Self {
            map: map_text.to_owned(),
            bus: bus.to_owned(),
            node: config.client.node_id,
            wire: config.client.wire.to_string(),
            ack_timeout_us: us(config.client.timeout),
            retries: config.client.retries,
            first_msg_id: config.client.first_msg_id,
            activate_on_start: config.activate_on_start,
            feedback_period_us: config.feedback_period.map(us),
            offline_after_us: us(config.offline_after),
            heartbeat_period_us: us(config.heartbeat_period),
            drain_timeout_us: us(config.drain_timeout),
            epoch_unix_ms: config.epoch_unix_ms,
            max_age_us: config.max_age.map(us),
            max_pending_lines: config.max_pending_lines,
            max_queue_per_joint: config.max_queue_per_joint,
            orion: config.line_link,
            orion_command_timeout_us: us(config.arm_command_timeout),
            telemetry_hz: config.telemetry_hz,
            allow_unknown_members: config.allow_unknown_members,
            sim_seed: sim.seed,
            sim_faults: [
                ("drop", f.drop),
                ("duplicate", f.duplicate),
                ("corrupt", f.corrupt),
                ("delay", f.delay),
                ("reorder", f.reorder),
                ("max_delay_us", f.max_delay.as_secs_f64() * 1e6),
            ]
            .into_iter()
            .map(|(k, v)| (k.to_owned(), v))
            .collect(),
        }
    }

    /// The bridge's configuration as recorded.
    ///
    /// # Errors
    /// The recorded wire version is not one motorwire knows.
    pub fn bridge_config(&self) -> Result<BridgeConfig, ReplayError> {
        let wire: WireVersion = self.wire.parse().map_err(|_| ReplayError::Setup {
            reason: format!("wire version {:?} is not one motorwire knows", self.wire),
        })?;
        let d = BridgeConfig::default();
        Ok(BridgeConfig {
            client: motorwire_can::client::ClientConfig {
                node_id: self.node,
                wire,
                timeout: Duration::from_micros(self.ack_timeout_us),
                retries: self.retries,
                first_msg_id: self.first_msg_id,
                ..d.client
            },
            activate_on_start: self.activate_on_start,
            feedback_period: self.feedback_period_us.map(Duration::from_micros),
            offline_after: Duration::from_micros(self.offline_after_us),
            heartbeat_period: Duration::from_micros(self.heartbeat_period_us),
            drain_timeout: Duration::from_micros(self.drain_timeout_us),
            epoch_unix_ms: self.epoch_unix_ms,
            max_age: self.max_age_us.map(Duration::from_micros),
            max_pending_lines: self.max_pending_lines,
            max_queue_per_joint: self.max_queue_per_joint,
            line_link: self.orion,
            arm_command_timeout: Duration::from_micros(self.orion_command_timeout_us),
            telemetry_hz: self.telemetry_hz,
            allow_unknown_members: self.allow_unknown_members,
        })
    }

    /// The simulated bus of the recorded session: its seed and faults
    /// (none unless it ran on `sim` with faults), simulated time.
    ///
    /// # Errors
    /// A recorded fault rate is out of range.
    pub fn sim_config(&self) -> Result<SimConfig, ReplayError> {
        let rate = |k: &str| self.sim_faults.get(k).copied().unwrap_or(0.0);
        let faults = if self.bus == "sim" {
            Faults {
                drop: rate("drop"),
                duplicate: rate("duplicate"),
                corrupt: rate("corrupt"),
                delay: rate("delay"),
                reorder: rate("reorder"),
                max_delay: Duration::try_from_secs_f64(rate("max_delay_us") / 1e6).map_err(
                    |e| ReplayError::Setup {
                        reason: format!("max_delay_us: {e}"),
                    },
                )?,
            }
        } else {
            // Answers from real devices are replaced by the simulator's,
            // without faults.
            Faults::default()
        };
        faults.validate().map_err(|e| ReplayError::Setup {
            reason: format!("sim_faults: {e}"),
        })?;
        Ok(SimConfig {
            seed: self.sim_seed,
            faults,
            ..SimConfig::default()
        })
    }
}

/// Why a recording could not be replayed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ReplayError {
    /// A file of the recording could not be read.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// A line of `lines.jsonl` is not a record.
    #[error("{path}:{line}: {reason}")]
    Record {
        /// The file.
        path: PathBuf,
        /// Its line number (from 1).
        line: usize,
        /// Why.
        reason: String,
    },
    /// The recording lost its beginning to rotation, or records to a full
    /// queue or disk: its inputs are not all there.
    #[error("{0}")]
    Incomplete(String),
    /// `session.json` has no usable setup.
    #[error("the recording's setup: {reason}")]
    Setup {
        /// Why.
        reason: String,
    },
    /// The bus map could not be read.
    #[error("the bus map: {0}")]
    Map(String),
    /// The bridge failed while replaying.
    #[error(transparent)]
    Bridge(#[from] BridgeError),
}

/// One record of a session.
#[derive(Debug, Clone, PartialEq)]
pub enum Recorded {
    /// An input line.
    Line {
        /// When the bridge took it, from its start (it came at the
        /// record's time): `None` in a recording that does not say.
        taken: Option<Duration>,
        /// Its client.
        origin: Origin,
        /// Its number.
        number: u64,
        /// Its text.
        text: String,
    },
    /// An input line that could not be read.
    Unreadable {
        /// Its client.
        origin: Origin,
        /// Its number.
        number: u64,
        /// Why.
        reason: String,
        /// It named `emergency_stop` and was taken as a stop.
        stop: bool,
    },
    /// Something else the bridge was told.
    Mark(Mark),
    /// An output line, and whose it was (`None`: every reader's).
    Output {
        /// Whose.
        to: Option<u64>,
        /// The line.
        value: Value,
    },
    /// A frame.
    Frame {
        /// Sent or received.
        dir: Direction,
        /// The frame.
        frame: Frame,
        /// A frame received: when the bridge took it (`taken_us`), where
        /// the recording says (the record's own time is when it came off
        /// the bus).
        taken: Option<Duration>,
    },
    /// A line to or from the Orion controller.
    Orion {
        /// Written or read.
        dir: Direction,
        /// The line.
        line: String,
    },
}

impl Recorded {
    /// Whether the bridge was told this (a replay tells it again).
    pub const fn is_input(&self) -> bool {
        matches!(
            self,
            Self::Line { .. } | Self::Unreadable { .. } | Self::Mark(_)
        )
    }

    /// Whether this is a feedback line (a motor's `feedback`, an Orion
    /// motor's `motor_status`): what a replay's comparison leaves out (the
    /// simulated devices' motion is their own).
    pub fn is_feedback(&self) -> bool {
        matches!(self, Self::Output { value, .. }
            if value.get("feedback").is_some() || value.get("motor_status").is_some())
    }
}

/// Records before a recording's start mark held until it comes, at most:
/// beyond, the start is found by reading the file once first.
const HELD_BEFORE_START: usize = 4_096;

/// A line of `lines.jsonl` (its end, `\n` or `\r\n`, left out) as JSON.
fn parse_line(piece: &[u8]) -> serde_json::Result<Value> {
    let line = piece.strip_suffix(b"\n").unwrap_or(piece);
    let line = line.strip_suffix(b"\r").unwrap_or(line);
    serde_json::from_slice(line)
}

/// The time of the first start mark in `lines` (`None`: none before the
/// end or the first line that cannot be read, which the full reading
/// then refuses or leaves out as cut).
fn first_start(mut lines: impl std::io::BufRead) -> Option<u64> {
    let mut piece = Vec::new();
    loop {
        piece.clear();
        if lines.read_until(b'\n', &mut piece).ok()? == 0 {
            return None;
        }
        let v = parse_line(&piece).ok()?;
        if parse_record(&v).ok()? == Recorded::Mark(Mark::Start) {
            return v.get("t_us").and_then(Value::as_u64);
        }
    }
}

/// What [`Recording::scan_partial`] found besides the records it handed
/// out.
#[derive(Debug, Clone)]
pub struct Scanned {
    /// How the bridge was set up (`None`: the recording does not say).
    pub setup: Option<Setup>,
    /// The recording ended cleanly (see [`Recording::ended`]).
    pub ended: bool,
    /// Its last line was cut (see [`Recording::cut`]).
    pub cut: bool,
    /// Records it lost (see [`Recording::dropped`]).
    pub dropped: u64,
    /// When they came (see [`Recording::dropped_span`]).
    pub dropped_span: Option<(Duration, Duration)>,
}

impl Scanned {
    /// Why the recording is not the whole session, if it is not (see
    /// [`Recording::incomplete`]).
    #[must_use]
    pub fn incomplete(&self) -> Option<String> {
        incompleteness(self.ended, self.dropped, self.dropped_span)
    }
}

/// Why a recording that `ended` (or not) and lost `dropped` records, from
/// `span`, is not the whole session; `None` when it is.
fn incompleteness(ended: bool, dropped: u64, span: Option<(Duration, Duration)>) -> Option<String> {
    let lost = (dropped > 0).then(|| {
        let when = span.map_or_else(String::new, |(a, b)| {
            format!(
                ", from {:.3} s to {:.3} s",
                a.as_secs_f64(),
                b.as_secs_f64()
            )
        });
        format!(
            "the recording dropped {dropped} records (its queue or its disk could not take them{when}): its inputs and outputs may not all be there"
        )
    });
    let unended = (!ended).then(|| {
        "the recording did not end cleanly (session.json has no end: the bridge was killed, or its disk stopped answering)".to_owned()
    });
    match (lost, unended) {
        (Some(a), Some(b)) => Some(format!("{a}; {b}")),
        (a, b) => a.or(b),
    }
}

/// A recording read back: its setup and its records, each at its time
/// from the bridge's start.
#[derive(Debug, Clone)]
pub struct Recording {
    /// How the bridge was set up (`None`: the recording does not say).
    pub setup: Option<Setup>,
    /// The records, in the order they were written.
    pub records: Vec<(Duration, Recorded)>,
    /// The recording ended cleanly (`session.json` has its end,
    /// `ended_wall_ms`; from a recorder before it, its counts): one that
    /// did not (the bridge was killed, its disk stopped answering) is
    /// compared up to its last record.
    pub ended: bool,
    /// The last line of `lines.jsonl` was cut in the middle of its write
    /// (a recording that did not end cleanly, or whose disk failed: the
    /// process was killed, the machine lost power, the disk filled) and
    /// was left out; every record before it is read.
    pub cut: bool,
    /// Records the recording lost (`session.json`'s `dropped`: its queue
    /// was full, its disk failed or filled); 0 in a whole recording.
    pub dropped: u64,
    /// When the first and the last of them came, from the bridge's start,
    /// where the recording says.
    pub dropped_span: Option<(Duration, Duration)>,
}

/// The largest `session.json` read (its map is at most 1 MiB).
pub const MAX_SESSION_FILE: u64 = 4 << 20;

/// The largest `lines.jsonl` read: 1 GiB (a recording holds at most a
/// quarter of its `--record-max-mb` there).
pub const MAX_LINES_FILE: u64 = 1 << 30;

/// The file at `path` opened to read at most `max` bytes: a regular file
/// only (a FIFO or a device would be read forever), and no larger than a
/// recording makes.
fn open_capped(path: &Path, max: u64) -> Result<std::io::Take<fs::File>, ReplayError> {
    let io = |source| ReplayError::Io {
        path: path.to_owned(),
        source,
    };
    let meta = fs::metadata(path).map_err(io)?;
    let refuse = |why: String| ReplayError::Io {
        path: path.to_owned(),
        source: std::io::Error::other(why),
    };
    if !meta.is_file() {
        return Err(refuse("not a regular file".to_owned()));
    }
    if meta.len() > max {
        return Err(refuse(format!(
            "{} bytes, more than a recording holds ({max})",
            meta.len()
        )));
    }
    let f = fs::File::open(path).map_err(io)?;
    Ok(std::io::Read::take(f, max))
}

/// The text of the file at `path`, as [`open_capped`] opens it.
fn read_capped(path: &Path, max: u64) -> Result<String, ReplayError> {
    let mut text = String::new();
    std::io::Read::read_to_string(&mut open_capped(path, max)?, &mut text).map_err(|source| {
        ReplayError::Io {
            path: path.to_owned(),
            source,
        }
    })?;
    Ok(text)
}

/// The recording's `session.json` in `dir`: its path and what it says.
fn session_of(dir: &Path) -> Result<(PathBuf, Value), ReplayError> {
    let path = dir.join("session.json");
    let text = read_capped(&path, MAX_SESSION_FILE)?;
    let session = serde_json::from_str(&text).map_err(|e| ReplayError::Record {
        path: path.clone(),
        line: e.line(),
        reason: e.to_string(),
    })?;
    Ok((path, session))
}

/// The `setup` a `session.json` holds, if it holds one.
fn setup_in(session: &Value) -> Result<Option<Setup>, ReplayError> {
    session.get("setup").map_or(Ok(None), |s| {
        serde_json::from_value(s.clone())
            .map(Some)
            .map_err(|e| ReplayError::Setup {
                reason: e.to_string(),
            })
    })
}

/// How a recording is read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Reading {
    /// To replay: whole and checked against its own counts; refused when
    /// rotated or when it dropped records.
    Whole,
    /// To replay, records dropped or not: checked against its counts only
    /// when it lost none and ended cleanly.
    WholeLossy,
    /// To look at: as far as it goes.
    Partial,
}

impl Recording {
    fn of(scanned: Scanned, records: Vec<(Duration, Recorded)>) -> Self {
        Self {
            setup: scanned.setup,
            records,
            ended: scanned.ended,
            cut: scanned.cut,
            dropped: scanned.dropped,
            dropped_span: scanned.dropped_span,
        }
    }

    /// Whether the recording is the whole session: it ended cleanly and
    /// lost no record.
    #[must_use]
    pub const fn is_complete(&self) -> bool {
        self.ended && self.dropped == 0
    }

    /// Why the recording is not the whole session (records dropped, no
    /// clean end), to say to a person; `None` when it is.
    ///
    /// ```
    /// # let dir = std::env::temp_dir().join(format!("motorwire-doc-incomplete-{}", std::process::id()));
    /// # std::fs::create_dir_all(&dir)?;
    /// std::fs::write(
    ///     dir.join("session.json"),
    ///     r#"{"recorder":"motorwire","complete":false,"written":2,"dropped":3,"bytes":90,"ended_wall_ms":1}"#,
    /// )?;
    /// std::fs::write(dir.join("lines.jsonl"), "")?;
    /// let r = motorwire_record::replay::Recording::read_partial(&dir).expect("readable");
    /// assert!(!r.is_complete());
    /// assert!(r.incomplete().expect("incomplete").starts_with("the recording dropped 3 records"));
    /// # std::fs::remove_dir_all(&dir)?;
    /// # Ok::<(), std::io::Error>(())
    /// ```
    #[must_use]
    pub fn incomplete(&self) -> Option<String> {
        incompleteness(self.ended, self.dropped, self.dropped_span)
    }

    /// How the bridge of the recording in `dir` was set up, from its
    /// `session.json` alone (`None`: it does not say): what a reader needs
    /// before the records (`motorwire plot` keeps only the map's motors).
    ///
    /// # Errors
    /// [`ReplayError::Io`] and [`ReplayError::Record`] for a `session.json`
    /// that cannot be read; [`ReplayError::Setup`] for a setup that is not
    /// one.
    pub fn setup_of(dir: &Path) -> Result<Option<Setup>, ReplayError> {
        setup_in(&session_of(dir)?.1)
    }

    /// Reads the recording in `dir`. One that did not end cleanly is read
    /// up to its last record ([`Recording::ended`] says so).
    ///
    /// # Errors
    /// [`ReplayError::Io`] and [`ReplayError::Record`] for a file that
    /// cannot be read; [`ReplayError::Incomplete`] when the recording was
    /// rotated (`lines.1.jsonl`: its beginning is gone) or dropped records.
    pub fn read(dir: &Path) -> Result<Self, ReplayError> {
        Self::read_as(dir, Reading::Whole)
    }

    /// [`Recording::read`] for a replay: every record but the feedback
    /// lines, which neither [`replay`] nor [`compare`] reads (most of a
    /// long recording's lines, and most of its memory once read), except
    /// one that is later than every record after it (the recording's span
    /// is the same).
    ///
    /// # Errors
    /// As [`Recording::read`].
    pub fn read_to_replay(dir: &Path) -> Result<Self, ReplayError> {
        Self::read_to_replay_as(dir, Reading::Whole)
    }

    /// [`Recording::read_to_replay`] for a recording that may have lost
    /// records (`motorwire replay --allow-incomplete`): one that dropped
    /// records is read as far as it goes, its last line left out where a
    /// failed write cut it, and [`Recording::incomplete`] says what it
    /// lacks. A recording that lost nothing and ended cleanly is checked as
    /// [`Recording::read`] checks it.
    ///
    /// # Errors
    /// As [`Recording::read`], but for records dropped.
    pub fn read_to_replay_lossy(dir: &Path) -> Result<Self, ReplayError> {
        Self::read_to_replay_as(dir, Reading::WholeLossy)
    }

    fn read_to_replay_as(dir: &Path, reading: Reading) -> Result<Self, ReplayError> {
        let mut records: Vec<(Duration, Recorded)> = Vec::new();
        // The latest time of the records kept for good, and that of the
        // last record kept when it is a feedback line kept only while
        // nothing later comes.
        let mut latest = Duration::ZERO;
        let mut tail: Option<Duration> = None;
        let scanned = Self::scan_as(dir, reading, &mut |t, r| {
            let at = match &r {
                Recorded::Line { taken: Some(k), .. } => t.max(*k),
                _ => t,
            };
            if r.is_feedback() {
                if at > latest.max(tail.unwrap_or_default()) || records.is_empty() {
                    if tail.is_some() {
                        records.pop();
                    }
                    records.push((t, r));
                    tail = Some(at);
                }
                return;
            }
            if let Some(kept) = tail.take() {
                if at >= kept {
                    records.pop();
                } else {
                    latest = latest.max(kept);
                }
            }
            latest = latest.max(at);
            records.push((t, r));
        })?;
        Ok(Self::of(scanned, records))
    }

    /// Reads the recording in `dir` as far as it goes: one rotated, or
    /// that dropped records, is read too (what it holds; to look at, not
    /// to replay).
    ///
    /// # Errors
    /// [`ReplayError::Io`] and [`ReplayError::Record`] for a file that
    /// cannot be read.
    pub fn read_partial(dir: &Path) -> Result<Self, ReplayError> {
        Self::read_as(dir, Reading::Partial)
    }

    /// [`Recording::read_partial`] a record at a time: each record is
    /// handed to `each` with its time from the bridge's start, in the
    /// order it was written, and none is kept. What reads a long
    /// recording to summarize it (`motorwire plot`) holds only its
    /// summary, never the recording's records all at once.
    ///
    /// # Errors
    /// As [`Recording::read_partial`]; the records before the one that
    /// could not be read have been handed to `each`.
    pub fn scan_partial(
        dir: &Path,
        mut each: impl FnMut(Duration, Recorded),
    ) -> Result<Scanned, ReplayError> {
        Self::scan_as(dir, Reading::Partial, &mut each)
    }

    fn read_as(dir: &Path, reading: Reading) -> Result<Self, ReplayError> {
        let mut records = Vec::new();
        let scanned = Self::scan_as(dir, reading, &mut |t, r| records.push((t, r)))?;
        Ok(Self::of(scanned, records))
    }

    #[allow(clippy::too_many_lines)]
    fn scan_as(
        dir: &Path,
        reading: Reading,
        each: &mut dyn FnMut(Duration, Recorded),
    ) -> Result<Scanned, ReplayError> {
        let whole = reading != Reading::Partial;
        let io = |path: PathBuf| move |source| ReplayError::Io { path, source };
        let (session_path, session) = session_of(dir)?;
        if whole && dir.join("lines.1.jsonl").exists() {
            return Err(ReplayError::Incomplete(
                "the recording was rotated (lines.1.jsonl): its beginning is gone; record with a larger --record-max-mb to replay".to_owned(),
            ));
        }
        // The end's counts, where there: whole numbers, or the file was
        // edited.
        let count = |name: &str| -> Result<Option<u64>, ReplayError> {
            session.get(name).map_or(Ok(None), |v| {
                v.as_u64().map(Some).ok_or_else(|| ReplayError::Record {
                    path: session_path.clone(),
                    line: 1,
                    reason: format!("{name} is {v}, not a whole number"),
                })
            })
        };
        let (written, dropped) = (count("written")?, count("dropped")?);
        count("bytes")?;
        let ended_wall_ms = count("ended_wall_ms")?;
        let dropped_first = count("dropped_first_us")?;
        let dropped_last = count("dropped_last_us")?;
        let dropped = dropped.unwrap_or(0);
        // Since `complete` (counts written from the start, kept in place),
        // a recording ended cleanly has its end; before, its counts.
        let ended = if session.get("complete").is_some() {
            ended_wall_ms.is_some()
        } else {
            written.is_some()
        };
        if dropped > 0 && reading == Reading::Whole {
            return Err(ReplayError::Incomplete(
                incompleteness(true, dropped, None).unwrap_or_default(),
            ));
        }
        // Checked against its files: a recording that lost nothing and
        // ended cleanly.
        let whole_and_complete = whole && ended && dropped == 0;
        let setup = setup_in(&session)?;
        let lines_path = dir.join("lines.jsonl");
        // Times from the start; a record's `taken` too.
        let hand =
            |start: u64, t: u64, mut r: Recorded, each: &mut dyn FnMut(Duration, Recorded)| {
                let since = |t: u64| Duration::from_micros(t.saturating_sub(start));
                if let Recorded::Line { taken, .. } | Recorded::Frame { taken, .. } = &mut r {
                    *taken = taken.map(|k| since(u64::try_from(k.as_micros()).unwrap_or(u64::MAX)));
                }
                each(since(t), r);
            };
        // Time zero once known: from the start mark (a recording's first
        // record), or, when more than HELD_BEFORE_START records come
        // before it (or there is none), from reading the file once first,
        // so those need not all be held.
        let mut known_start = None;
        let (count, frames, cut, start) = 'read: loop {
            let mut lines = std::io::BufReader::new(open_capped(&lines_path, MAX_LINES_FILE)?);
            // The records before the start mark, held until it comes.
            let mut before_start = Vec::new();
            let mut start = known_start;
            let mut cut = false;
            let (mut count, mut frames) = (0u64, Vec::new());
            let mut piece = Vec::new();
            for i in 0.. {
                piece.clear();
                if std::io::BufRead::read_until(&mut lines, b'\n', &mut piece)
                    .map_err(io(lines_path.clone()))?
                    == 0
                {
                    break;
                }
                let bad = |reason: String| ReplayError::Record {
                    path: lines_path.clone(),
                    line: i + 1,
                    reason,
                };
                let complete = piece.ends_with(b"\n");
                let v: Value = match parse_line(&piece) {
                    Ok(v) => v,
                    // The last line of a recording that never ended or
                    // whose disk failed, with no newline: a write the kill
                    // or the disk cut short. What came before it is the
                    // recording; anywhere else a line that is not JSON is
                    // damage, and refused.
                    Err(_) if (!ended || dropped > 0) && !complete => {
                        cut = true;
                        break;
                    }
                    Err(e) => return Err(bad(e.to_string())),
                };
                let t = v
                    .get("t_us")
                    .and_then(Value::as_u64)
                    .ok_or_else(|| bad("no t_us".to_owned()))?;
                let r = parse_record(&v).map_err(|e| bad(e.to_string()))?;
                count += 1;
                if whole_and_complete && let Recorded::Frame { frame, .. } = &r {
                    frames.push(*frame);
                }
                match start {
                    Some(start) => hand(start, t, r, each),
                    None if r == Recorded::Mark(Mark::Start) => {
                        start = Some(t);
                        for (before, r) in before_start.drain(..) {
                            hand(t, before, r, each);
                        }
                        hand(t, t, r, each);
                    }
                    None if before_start.len() < HELD_BEFORE_START => {
                        before_start.push((t, r));
                    }
                    None => {
                        // Read again from the top, time zero known (none
                        // was handed out yet).
                        known_start = Some(
                            first_start(std::io::BufReader::new(open_capped(
                                &lines_path,
                                MAX_LINES_FILE,
                            )?))
                            .unwrap_or(0),
                        );
                        continue 'read;
                    }
                }
            }
            // No start mark: times as they were written.
            for (t, r) in before_start {
                hand(0, t, r, each);
            }
            break (count, frames, cut, start.unwrap_or(0));
        };
        // A recording that ended cleanly says how many records it wrote:
        // fewer in the file is a recording cut short.
        if whole_and_complete
            && let Some(n) = written
            && n != count
        {
            return Err(ReplayError::Incomplete(format!(
                "session.json says {n} records were written, lines.jsonl holds {count}: the recording was cut short or edited"
            )));
        }
        if whole_and_complete {
            let frames_path = dir.join("frames.log");
            let log = read_capped(&frames_path, MAX_LINES_FILE)?;
            same_frames(
                &frames_path,
                &log,
                frames,
                dir.join("frames.1.log").exists(),
            )?;
        }
        let since = |t: u64| Duration::from_micros(t.saturating_sub(start));
        let dropped_span = match (dropped_first, dropped_last) {
            (Some(a), Some(b)) if dropped > 0 => Some((since(a), since(b.max(a)))),
            _ => None,
        };
        Ok(Scanned {
            setup,
            ended,
            cut,
            dropped,
            dropped_span,
        })
    }

    /// The input records (lines and marks), in the order the bridge took
    /// them.
    pub fn inputs(&self) -> impl Iterator<Item = &(Duration, Recorded)> {
        self.records.iter().filter(|(_, r)| r.is_input())
    }
}

/// Checks that `frames.log` (its text `log`) holds the frames of
/// `lines.jsonl` (`frames`), in their order: all of them, or, where it
/// was rotated, the last of them.
///
/// # Errors
/// [`ReplayError::Record`] naming the first line of `frames.log` that is
/// not a candump line or not the frame `lines.jsonl` has there, or
/// [`ReplayError::Incomplete`] when the two hold different numbers of
/// frames.
fn same_frames(
    path: &Path,
    log: &str,
    frames: Vec<Frame>,
    rotated: bool,
) -> Result<(), ReplayError> {
    let logged = log
        .lines()
        .enumerate()
        .map(|(i, line)| {
            LogEntry::parse(line)
                .map(|e| e.frame)
                .map_err(|reason| ReplayError::Record {
                    path: path.to_owned(),
                    line: i + 1,
                    reason,
                })
        })
        .collect::<Result<Vec<_>, _>>()?;
    let skip = if rotated {
        frames.len().saturating_sub(logged.len())
    } else {
        0
    };
    let expected = frames.get(skip..).unwrap_or_default();
    if let Some(i) = logged.iter().zip(expected).position(|(a, b)| a != b) {
        return Err(ReplayError::Record {
            path: path.to_owned(),
            line: i + 1,
            reason: "not the frame lines.jsonl has there: the recording was edited".to_owned(),
        });
    }
    if logged.len() != expected.len() {
        return Err(ReplayError::Incomplete(format!(
            "{} holds {} frames, lines.jsonl {}: the recording was cut short or edited",
            path.display(),
            logged.len(),
            expected.len()
        )));
    }
    Ok(())
}

fn parse_record(v: &Value) -> Result<Recorded, RecordError> {
    let origin = |b: &Value| {
        b.get("origin")
            .and_then(Value::as_u64)
            .map(Origin)
            .ok_or(RecordError::Missing("no origin"))
    };
    let number = |b: &Value| {
        b.get("line")
            .and_then(Value::as_u64)
            .ok_or(RecordError::Missing("no line number"))
    };
    let dir = |b: &Value| match b.get("dir").and_then(Value::as_str) {
        Some("tx") => Ok(Direction::Tx),
        Some("rx") => Ok(Direction::Rx),
        _ => Err(RecordError::Missing("no dir")),
    };
    if let Some(b) = v.get("in") {
        if let Some(text) = b.get("text").and_then(Value::as_str) {
            return Ok(Recorded::Line {
                taken: b
                    .get("taken_us")
                    .and_then(Value::as_u64)
                    .map(Duration::from_micros),
                origin: origin(b)?,
                number: number(b)?,
                text: text.to_owned(),
            });
        }
        let reason = b
            .get("unreadable")
            .and_then(Value::as_str)
            .ok_or(RecordError::Missing("an input without text or unreadable"))?;
        return Ok(Recorded::Unreadable {
            origin: origin(b)?,
            number: number(b)?,
            reason: reason.to_owned(),
            stop: b.get("stop").and_then(Value::as_bool).unwrap_or(false),
        });
    }
    if let Some(b) = v.get("mark") {
        return Mark::from_value(b)
            .map(Recorded::Mark)
            .ok_or_else(|| RecordError::UnknownMark(b.to_string()));
    }
    if let Some(b) = v.get("out") {
        return Ok(Recorded::Output {
            to: v.get("to").and_then(Value::as_u64),
            value: b.clone(),
        });
    }
    if let Some(b) = v.get("frame") {
        let raw = b
            .get("id")
            .and_then(Value::as_u64)
            .and_then(|n| u32::try_from(n).ok())
            .ok_or(RecordError::Missing("a frame without id"))?;
        let extended = b.get("extended").and_then(Value::as_bool).unwrap_or(false);
        let id = if extended {
            CanId::extended(raw)
        } else {
            // A standard id past 16 bits is past 11 too: refused as the
            // bus refuses one, naming the id as recorded.
            u16::try_from(raw)
                .map_err(|_| motorwire_can::Error::InvalidId {
                    id: raw,
                    extended: false,
                })
                .and_then(CanId::standard)
        }
        .map_err(|e| RecordError::FrameId(raw, e))?;
        let hex = b
            .get("data")
            .and_then(Value::as_str)
            .ok_or(RecordError::Missing("a frame without data"))?;
        let data = motorwire_can::candump::hex_bytes(hex)
            .map_err(|e| RecordError::FrameData(e.to_string()))?;
        let fd = b.get("fd").and_then(Value::as_bool).unwrap_or(true);
        let frame = if fd {
            Frame::fd(id, &data)
        } else {
            Frame::classic(id, &data)
        }
        .map_err(RecordError::Frame)?;
        return Ok(Recorded::Frame {
            dir: dir(b)?,
            frame,
            taken: b
                .get("taken_us")
                .and_then(Value::as_u64)
                .map(Duration::from_micros),
        });
    }
    if let Some(b) = v.get("orion") {
        return Ok(Recorded::Orion {
            dir: dir(b)?,
            line: b
                .get("line")
                .and_then(Value::as_str)
                .ok_or(RecordError::Missing("an Orion record without line"))?
                .to_owned(),
        });
    }
    Err(RecordError::Missing(
        "not an in, out, mark, frame or orion record",
    ))
}

/// What is wrong with a record of `session.jsonl`.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
enum RecordError {
    /// A member it must have (said as what is missing).
    #[error("{0}")]
    Missing(&'static str),
    /// A mark the recorder never writes.
    #[error("an unknown mark {0}")]
    UnknownMark(String),
    /// A frame id the bus cannot carry.
    #[error("frame id {0}: {1}")]
    FrameId(u32, motorwire_can::Error),
    /// A frame's data that is not hex bytes.
    #[error("frame {0}")]
    FrameData(String),
    /// A frame the bus cannot carry.
    #[error("frame: {0}")]
    Frame(motorwire_can::Error),
}

/// How a replay runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Pace {
    /// At the recorded pace (each simulated second takes a second), not
    /// as fast as the simulation goes.
    pub real_time: bool,
    /// After the last input, how long the bridge may take to finish (the
    /// end of input drains moves for up to 30 s).
    pub finish_within: Duration,
    /// The longest recording replayed (from its start to its last
    /// record): a longer one is refused rather than simulated for hours.
    pub max_span: Duration,
}

impl Default for Pace {
    /// As fast as it goes; a minute to finish; recordings up to 6 hours.
    fn default() -> Self {
        Self {
            real_time: false,
            finish_within: Duration::from_secs(60),
            max_span: Duration::from_secs(6 * 3600),
        }
    }
}

/// What a replay gave out: output lines, frames sent and Orion lines
/// written, each at its simulated time, in order.
#[derive(Debug, Clone, Default)]
pub struct Replayed {
    /// The records, as a recording holds them.
    pub records: Vec<(Duration, Recorded)>,
    /// Input records told to the bridge.
    pub inputs: usize,
    /// The simulated time the replay ran.
    pub simulated: Duration,
    /// The wall time it took.
    pub took: Duration,
}

/// Replays `recording`'s inputs into `bridge` (made as the recording's
/// [`Setup`] says, or with another map to see what it changes) on the
/// simulated bus `sim`, at `pace`.
///
/// # Errors
/// The simulated bus's errors.
pub fn replay(
    recording: &Recording,
    bridge: Bridge,
    sim: SimConfig,
    pace: Pace,
) -> Result<Replayed, ReplayError> {
    let began = Instant::now();
    // Its latest time (a damaged clock may put any record late).
    let span = recording
        .records
        .iter()
        .map(|(t, r)| match r {
            Recorded::Line { taken: Some(k), .. } => (*t).max(*k),
            _ => *t,
        })
        .max()
        .unwrap_or_default();
    if span > pace.max_span {
        return Err(ReplayError::Incomplete(format!(
            "the recording spans {:.0} s, more than the {:.0} s a replay runs (its clock may be damaged; a longer limit: --max-span)",
            span.as_secs_f64(),
            pace.max_span.as_secs_f64()
        )));
    }
    // The recorded bridge's `ready`: the simulated one starts up in its
    // own time, and what came after `ready` is told as long after the
    // simulated one's.
    let recorded_ready = recording.records.iter().find_map(|(t, r)| match r {
        Recorded::Output { to: None, value }
            if value.get("event") == Some(&Value::from("ready")) =>
        {
            Some(*t)
        }
        _ => None,
    });
    // The Orion controller's boot beacon, when the recorded one sent it
    // (its motors come online then, and the order of their events with
    // the others' follows).
    let beacon = recording.records.iter().find_map(|(t, r)| match r {
        Recorded::Orion {
            dir: Direction::Rx,
            line,
        } if serde_json::from_str::<Value>(line)
            .is_ok_and(|v| v == serde_json::json!({"ID": 32})) =>
        {
            Some(*t)
        }
        _ => None,
    });
    // Each answer the recorded devices gave a request, with when: the
    // simulated devices' are handed to the bridge no earlier (they answer
    // at once; a line taken between a request and its recorded answer
    // finds the bridge as it was then).
    let mut answers: Option<Vec<(motorwire_bridge::sim::AnswerKey, Duration)>> = {
        let mut counter = motorwire_bridge::sim::AnswerCounter::new(bridge.map());
        for (_, r) in &recording.records {
            if let Recorded::Frame {
                dir: Direction::Tx,
                frame,
                ..
            } = r
            {
                counter.sent(frame);
            }
        }
        // Received, in the order the bridge took them.
        let mut received: Vec<(Duration, &Frame)> = recording
            .records
            .iter()
            .filter_map(|(t, r)| match r {
                Recorded::Frame {
                    dir: Direction::Rx,
                    frame,
                    taken,
                } => Some((taken.unwrap_or(*t).max(*t), frame)),
                _ => None,
            })
            .collect();
        received.sort_by_key(|(t, _)| *t);
        Some(
            received
                .into_iter()
                .filter_map(|(t, frame)| Some((counter.answer(frame)?, t)))
                .collect(),
        )
    };
    let mut arm = SimulatedArm::new_unbooted(bridge, sim)?;
    arm.count_requests();
    if recorded_ready.is_none()
        && let Some(a) = answers.take()
    {
        arm.hold_answers(a);
    }
    let mut booted = false;
    // A controller heard before the recorded bridge was ready is there
    // from the start (the simulated startup takes no time); one that
    // booted later, when it did.
    if beacon.is_none_or(|b| recorded_ready.is_none_or(|r| b <= r)) {
        arm.orion_boot();
        booted = true;
    }
    arm.keep_sent();
    let mut out = Replayed::default();
    let mut outputs = Vec::new();
    let advance = |arm: &mut SimulatedArm,
                   outputs: &mut Vec<(Duration, Output)>,
                   t: Duration|
     -> Result<(), BridgeError> {
        while arm.now() < t {
            let left = t.saturating_sub(arm.now());
            // What a step gives out, it gives at its start (then the clock
            // moves on).
            let now = arm.now();
            // Feedback is not compared: not kept (a long replay's memory).
            let keep = |o: &Output| !matches!(o, Output::Feedback(_));
            outputs.extend(
                arm.take_outputs()
                    .into_iter()
                    .filter(keep)
                    .map(|o| (now, o)),
            );
            arm.step(left.min(Duration::from_millis(10)))?;
            outputs.extend(
                arm.take_outputs()
                    .into_iter()
                    .filter(keep)
                    .map(|o| (now, o)),
            );
            let now = arm.now();
            if pace.real_time {
                let wall = began.elapsed();
                if now > wall {
                    thread::sleep(now - wall);
                }
            }
        }
        Ok(())
    };
    let mut ends = false;
    let mut last = Duration::ZERO;
    // When the simulated bridge became ready.
    let mut ready_at: Option<Duration> = None;
    // Runs to `t` of the recording's clock: before its `ready`, as far as
    // `t` or the simulated `ready`, whichever comes first; after it, as
    // long after the simulated `ready`.
    let mut reach = |arm: &mut SimulatedArm,
                     outputs: &mut Vec<(Duration, Output)>,
                     t: Duration|
     -> Result<Duration, BridgeError> {
        let Some(r) = recorded_ready else {
            advance(arm, outputs, t)?;
            return Ok(t);
        };
        while ready_at.is_none() {
            if arm.bridge().is_ready() {
                ready_at = Some(arm.now());
                break;
            }
            if t <= r && arm.now() >= t {
                return Ok(arm.now());
            }
            // Startup in steps (a bridge that never gets ready is given
            // the recorded time and a minute more).
            if arm.now() > r.saturating_add(Duration::from_secs(60)) {
                ready_at = Some(arm.now());
                break;
            }
            let next = arm.now().saturating_add(Duration::from_millis(1));
            advance(arm, outputs, next)?;
        }
        let s = ready_at.unwrap_or_default();
        // Once ready: the answers after the recorded `ready`, as long
        // after the simulated one (those of the startup come in its own
        // time).
        if let Some(a) = answers.take() {
            arm.hold_answers(
                a.into_iter()
                    .filter(|(_, t)| *t > r)
                    .map(|(k, t)| (k, s.saturating_add(t - r))),
            );
        }
        let to = if t <= r {
            t.min(s)
        } else {
            s.saturating_add(t - r)
        };
        advance(arm, outputs, to)?;
        Ok(to)
    };
    for (t, r) in recording.inputs() {
        // A line is told when the bridge took it, as having come when it
        // came (as the bridge was told it).
        let taken = match r {
            Recorded::Line { taken: Some(k), .. } => (*k).max(*t),
            _ => *t,
        };
        // The controller's beacon before a line the bridge took after it,
        // though the line came first (what the devices say is taken
        // ahead of the lines waiting).
        if !booted && let Some(b) = beacon.filter(|b| *b <= taken) {
            reach(&mut arm, &mut outputs, b)?;
            arm.orion_boot();
            booted = true;
        }
        let came = reach(&mut arm, &mut outputs, *t)?;
        reach(&mut arm, &mut outputs, taken)?;
        // What is due by then (a device's answer held to its recorded
        // time) comes first, as it came before the line was taken.
        arm.settle()?;
        let now = arm.now();
        let t = &came;
        let b = arm.bridge_mut();
        match r {
            Recorded::Line {
                origin,
                number,
                text,
                ..
            } => b.handle_numbered_line((*t).min(now), *origin, *number, text),
            Recorded::Unreadable {
                origin,
                number,
                reason,
                stop: true,
            } => b.handle_numbered_unreadable_stop(now, *origin, *number, reason),
            Recorded::Unreadable {
                origin,
                number,
                reason,
                stop: false,
            } => b.handle_numbered_unreadable(now, *origin, *number, reason),
            Recorded::Mark(Mark::Start) => {}
            Recorded::Mark(Mark::Greet(o)) => b.greet(now, *o),
            Recorded::Mark(Mark::Dropped(o, why)) => b.drop_origin(now, *o, why),
            Recorded::Mark(Mark::Finish) => {
                ends = true;
                b.finish(now);
            }
            Recorded::Mark(Mark::Interrupt) => {
                ends = true;
                b.interrupt(now);
            }
            Recorded::Mark(Mark::OrionLost(why)) => b.handle_link_lost(now, why),
            Recorded::Mark(Mark::OrionUnreadable(why)) => b.handle_link_unreadable(now, why),
            Recorded::Output { .. } | Recorded::Frame { .. } | Recorded::Orion { .. } => {}
        }
        // What the line set going goes out before the next is taken, as
        // the recorded bridge sent it (a line taken right after finds it
        // sent).
        arm.settle()?;
        out.inputs += 1;
        last = *t;
    }
    // The recorded session's end: its last record, or the bridge's own
    // end once told the input ended.
    if !booted && let Some(b) = beacon {
        reach(&mut arm, &mut outputs, b)?;
        arm.orion_boot();
    }
    let end = reach(&mut arm, &mut outputs, span.max(last))?;
    if ends {
        let limit = end.max(arm.now()).saturating_add(pace.finish_within);
        while !arm.bridge().is_finished() && arm.now() < limit {
            let t = arm.now().saturating_add(Duration::from_millis(10));
            advance(&mut arm, &mut outputs, t)?;
        }
    } else {
        advance(&mut arm, &mut outputs, end)?;
    }
    let now = arm.now();
    outputs.extend(arm.take_outputs().into_iter().map(|o| (now, o)));
    let mut records: Vec<(Duration, Recorded)> = outputs
        .into_iter()
        .map(|(t, o)| {
            let to = o.reader().map(|r| r.0);
            (
                t,
                Recorded::Output {
                    to,
                    value: o.to_value(),
                },
            )
        })
        .collect();
    records.extend(arm.sent().iter().map(|(t, f)| {
        (
            *t,
            Recorded::Frame {
                dir: Direction::Tx,
                frame: *f,
                taken: None,
            },
        )
    }));
    records.extend(arm.orion_log().iter().map(|w| {
        (
            w.at,
            Recorded::Orion {
                dir: Direction::Tx,
                line: w.line.clone(),
            },
        )
    }));
    records.sort_by_key(|(t, _)| *t);
    out.records = records;
    out.simulated = arm.now();
    out.took = began.elapsed();
    Ok(out)
}

/// What [`frame_key`] has met so far of a session's frames: the requests
/// (a request met again is a retry) and each moteus controller's last
/// command (the same again is a held move's refresh or a repeated stop).
#[derive(Debug, Default, Clone)]
pub struct FramesSeen {
    requests: HashSet<(u16, u32)>,
    moteus: HashMap<String, String>,
}

/// What a frame the bridge sent says, read in its device's dialect,
/// without what the clock decides: `None` for a frame a comparison leaves
/// out (the heartbeat, a retry, a moteus poll, a moteus command the same
/// as the one before it). `seen` holds what was met so far.
///
/// Returns the stream (whose it is) and what it says.
pub fn frame_key(
    map: &BusMap,
    wire: WireVersion,
    frame: &Frame,
    seen: &mut FramesSeen,
) -> Option<(String, String)> {
    let id = frame.id();
    let data = frame.data();
    if id.is_extended() {
        for m in map.motors() {
            if let Target::Moteus { id: node, bus, .. } = m.target
                && motorwire_bridge::moteus_addressed(id.raw(), node, bus) == Some(false)
            {
                // A subframe that writes registers comes first in a
                // command (type 0x0_); a poll only reads (0x1_).
                if data.first().is_none_or(|b| b >> 4 != 0) {
                    return None;
                }
                let key = hex(data);
                if seen.moteus.get(&m.name) == Some(&key) {
                    return None;
                }
                seen.moteus.insert(m.name.clone(), key.clone());
                return Some((format!("frames to {}", m.name), key));
            }
        }
        return Some((format!("frames on {:#x}", id.raw()), hex(data)));
    }
    for m in map.motors() {
        if let Target::Compact { node, .. } = m.target
            && u32::from(node) == id.raw()
        {
            return Some((
                format!("frames to {}", m.name),
                match motorwire_compact::CompactCommand::decode(data) {
                    Ok(c) => format!(
                        "compact {} setpoint {} flags {:?} velocity_limit {:?} torque_limit {:?}",
                        c.control_mode.name(),
                        c.setpoint,
                        c.flags,
                        c.velocity_limit,
                        c.torque_limit
                    ),
                    Err(e) => format!("compact, not read: {e}: {}", hex(data)),
                },
            ));
        }
    }
    let Ok((header, _)) = Header::decode_prefix(wire, data) else {
        return Some((format!("frames on {:#x}", id.raw()), hex(data)));
    };
    let target = header.target_id;
    let (name, v) = map.irpc_node(target).map_or_else(
        || (format!("{target:#06x}"), wire),
        |m| {
            let w = match m.target {
                Target::Irpc { wire, .. } => wire,
                _ => wire,
            };
            (m.name.clone(), w)
        },
    );
    let stream = format!("frames to {name}");
    match Message::decode_frame(v, data) {
        Ok(Message {
            payload: Payload::ArmReady,
            ..
        }) => None,
        Ok(msg) => {
            if !seen.requests.insert((target, msg.header.msg_id)) {
                return None;
            }
            Some((stream, format!("{:?}", msg.payload)))
        }
        Err(e) => Some((stream, format!("not read: {e}: {}", hex(data)))),
    }
}

fn hex(data: &[u8]) -> String {
    use std::fmt::Write as _;
    data.iter().fold(String::new(), |mut s, b| {
        let _ = write!(s, "{b:02x}");
        s
    })
}

/// Members that measure time, left out of a comparison: the bridge's, and
/// a device's clock in what it answers a request (a telemetry sample's
/// time, a power report's active time, a fault's time), which follows the
/// time the request reached it.
const TIMED: [&str; 8] = [
    "latency_us",
    "ack_us",
    "stop_latency_us",
    "after_ms",
    "timestamp_us",
    "active_time_ms",
    "timestamp_ms",
    "timestamp_sec",
];

/// `v` without the members that measure time.
fn untimed(v: &Value) -> Value {
    match v {
        Value::Object(m) => Value::Object(
            m.iter()
                .filter(|(k, _)| !TIMED.contains(&k.as_str()))
                .map(|(k, v)| (k.clone(), untimed(v)))
                .collect(),
        ),
        Value::Array(a) => Value::Array(a.iter().map(untimed).collect()),
        other => other.clone(),
    }
}

/// How far apart two numbers may be and still be the same.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tolerance {
    /// Any number: this much, plus [`Tolerance::relative`] of the larger.
    pub absolute: f64,
    /// Any number: this fraction of the larger, plus
    /// [`Tolerance::absolute`] (0 by default: a Unix time in milliseconds
    /// would be let off by far more than it should).
    pub relative: f64,
    /// A motor's position caught in motion (members `position` and an
    /// arrival's `error`), in its unit: a session
    /// recorded in real time takes its stop or its reading a few
    /// milliseconds off the replay's, and a joint moving at 120°/s is
    /// 0.6° further in 5 ms, and a reading is up to a feedback period
    /// old. Default: 2.
    pub motion: f64,
    /// A motor's velocity caught in motion (members `velocity` and
    /// `acceleration`), in its unit per second: a joint accelerating at
    /// 500°/s² is 2.5°/s faster 5 ms later. Default: 5.
    pub motion_rate: f64,
}

impl Default for Tolerance {
    /// 0.05; 2 for a motor's position in motion, 5 for its velocity.
    fn default() -> Self {
        Self {
            absolute: 0.05,
            relative: 0.0,
            motion: 2.0,
            motion_rate: 5.0,
        }
    }
}

/// Which tolerance a member's value takes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    Plain,
    /// A position caught in motion.
    Position,
    /// A velocity caught in motion.
    Rate,
}

impl Kind {
    fn of(member: &str) -> Self {
        match member {
            "position" | "error" => Self::Position,
            "velocity" | "acceleration" => Self::Rate,
            _ => Self::Plain,
        }
    }
}

/// Whether `a` and `b` are the same within `tol` (`kind`: what the
/// member holding them is).
fn same(a: &Value, b: &Value, tol: &Tolerance, kind: Kind) -> bool {
    let motion = kind;
    match (a, b) {
        (Value::Number(x), Value::Number(y)) => match (x.as_f64(), y.as_f64()) {
            (Some(x), Some(y)) => {
                let slack = tol.absolute + tol.relative * x.abs().max(y.abs());
                (x - y).abs()
                    <= match kind {
                        Kind::Plain => slack,
                        Kind::Position => slack.max(tol.motion),
                        Kind::Rate => slack.max(tol.motion_rate),
                    }
            }
            _ => x == y,
        },
        (Value::Array(x), Value::Array(y)) => {
            x.len() == y.len() && x.iter().zip(y).all(|(a, b)| same(a, b, tol, motion))
        }
        (Value::Object(x), Value::Object(y)) => {
            x.len() == y.len()
                && x.iter()
                    .all(|(k, a)| y.get(k).is_some_and(|b| same(a, b, tol, Kind::of(k))))
        }
        (Value::String(x), Value::String(y)) => same_text(x, y, tol, motion),
        _ => a == b,
    }
}

/// `text` in pieces: runs of digits (with a sign and a decimal point) as
/// numbers (with how many decimals they were printed with), the rest as
/// it is.
fn pieces(text: &str) -> Vec<Result<(f64, usize), &str>> {
    let mut out = Vec::new();
    let mut rest = text;
    while !rest.is_empty() {
        let start = rest
            .char_indices()
            .find(|&(i, c)| {
                c.is_ascii_digit()
                    || (c == '-'
                        && rest[i + 1..].starts_with(|d: char| d.is_ascii_digit())
                        && !rest[..i].ends_with(|p: char| p.is_alphanumeric()))
            })
            .map_or(rest.len(), |(i, _)| i);
        if start > 0 {
            out.push(Err(&rest[..start]));
            rest = &rest[start..];
            continue;
        }
        let end = rest
            .char_indices()
            .skip(1)
            .find(|&(i, c)| {
                !(c.is_ascii_digit()
                    || (c == '.' && rest[i + 1..].starts_with(|d: char| d.is_ascii_digit())))
            })
            .map_or(rest.len(), |(i, _)| i);
        let digits = &rest[..end];
        let decimals = digits.split_once('.').map_or(0, |(_, d)| d.len());
        match digits.parse::<f64>() {
            Ok(n) => out.push(Ok((n, decimals))),
            Err(_) => out.push(Err(&rest[..end])),
        }
        rest = &rest[end..];
    }
    out
}

/// Whether two texts say the same, the numbers in them within `tol` (a
/// message that names a time or a position the clock decided).
fn same_text(a: &str, b: &str, tol: &Tolerance, motion: Kind) -> bool {
    if a == b {
        return true;
    }
    let (x, y) = (pieces(a), pieces(b));
    x.len() == y.len()
        && x.iter().zip(&y).all(|(p, q)| match (p, q) {
            // A number printed with k decimals may be a unit of its last
            // place off (rounded on either side of a boundary).
            (Ok((p, dp)), Ok((q, dq))) => {
                let last_place = 10f64.powi(-i32::try_from((*dp).min(*dq)).unwrap_or(0));
                let tol = Tolerance {
                    // (plus the float's own rounding of a large number)
                    absolute: tol.absolute.max(if *dp > 0 || *dq > 0 {
                        last_place + 4.0 * f64::EPSILON * p.abs().max(q.abs())
                    } else {
                        0.0
                    }),
                    ..*tol
                };
                same(&Value::from(*p), &Value::from(*q), &tol, motion)
            }
            (Err(p), Err(q)) => p == q,
            _ => false,
        })
}

/// One thing compared: when, and what (as JSON, timing left out).
#[derive(Debug, Clone, PartialEq)]
struct Item {
    at: Duration,
    value: Value,
}

/// The first difference between a recording and its replay.
#[derive(Debug, Clone, PartialEq)]
pub struct Divergence {
    /// When (the earlier of the two sides' times).
    pub at: Duration,
    /// Which stream: `client 1 line 3`, `events`, `frames to elbow`, ...
    pub stream: String,
    /// The recorded side (`None`: nothing was recorded there).
    pub recorded: Option<Value>,
    /// The recorded side's time.
    pub recorded_at: Option<Duration>,
    /// The replayed side (`None`: the replay gave nothing there).
    pub replayed: Option<Value>,
    /// The replayed side's time.
    pub replayed_at: Option<Duration>,
}

/// What a comparison looked at, and the first difference.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Comparison {
    /// Answers compared (results, completions, greetings).
    pub answers: usize,
    /// Events compared.
    pub events: usize,
    /// Frames compared.
    pub frames: usize,
    /// Orion lines compared.
    pub orion_lines: usize,
    /// The earliest difference, if any.
    pub divergence: Option<Divergence>,
}

/// Is the Orion line an idle poll (an empty feedback request)?
fn orion_poll(line: &str) -> bool {
    serde_json::from_str::<Value>(line).is_ok_and(|v| {
        v.get("DATA")
            .is_some_and(|d| d.as_object().is_some_and(serde_json::Map::is_empty))
    })
}

/// The streams of `records` (sent frames, written Orion lines and output
/// lines only), each in order.
fn streams(
    records: &[(Duration, Recorded)],
    map: &BusMap,
    wire: WireVersion,
) -> BTreeMap<String, Vec<Item>> {
    let mut s: BTreeMap<String, Vec<Item>> = BTreeMap::new();
    let mut seen = FramesSeen::default();
    for (at, r) in records {
        let at = *at;
        match r {
            Recorded::Output { to, value } => {
                if r.is_feedback() {
                    continue;
                }
                let stream = match (to, value.get("line").and_then(Value::as_u64)) {
                    (Some(to), Some(line)) => format!("client {to} line {line}"),
                    (Some(to), None) => format!("client {to}"),
                    // A device's events in its own stream: the order of
                    // different devices' events follows the clock.
                    // (whether it is heard, in a stream of its own: a
                    // controller's boot and a startup race).
                    (None, _) => match value.get("motor_id").and_then(Value::as_str) {
                        None => "events".to_owned(),
                        Some(m)
                            if matches!(
                                value.get("event").and_then(Value::as_str),
                                Some("online" | "offline")
                            ) =>
                        {
                            format!("events of {m}: heard")
                        }
                        Some(m) => format!("events of {m}"),
                    },
                };
                s.entry(stream).or_default().push(Item {
                    at,
                    value: untimed(value),
                });
            }
            Recorded::Frame {
                dir: Direction::Tx,
                frame,
                ..
            } => {
                if let Some((stream, key)) = frame_key(map, wire, frame, &mut seen) {
                    s.entry(stream).or_default().push(Item {
                        at,
                        value: Value::String(key),
                    });
                }
            }
            Recorded::Orion {
                dir: Direction::Tx,
                line,
            } if !orion_poll(line) => {
                s.entry("lines to the Orion controller".to_owned())
                    .or_default()
                    .push(Item {
                        at,
                        value: serde_json::from_str(line)
                            .unwrap_or_else(|_| Value::String(line.clone())),
                    });
            }
            _ => {}
        }
    }
    s
}

/// Compares a recording with its replay (see the module's documentation
/// for what is compared); `map` and `wire` read the frames.
pub fn compare(
    recording: &Recording,
    replayed: &Replayed,
    map: &BusMap,
    wire: WireVersion,
    tolerance: &Tolerance,
) -> Comparison {
    let a = streams(&recording.records, map, wire);
    let b = streams(&replayed.records, map, wire);
    let mut c = Comparison::default();
    let names: std::collections::BTreeSet<&String> = a.keys().chain(b.keys()).collect();
    let empty = Vec::new();
    for name in names {
        let (x, y) = (a.get(name).unwrap_or(&empty), b.get(name).unwrap_or(&empty));
        let n = x.len().max(y.len());
        let counted = x.len().min(y.len());
        if name.starts_with("client ") {
            c.answers += counted;
        } else if name == "events" || name.starts_with("events of ") {
            c.events += counted;
        } else if name.starts_with("frames ") {
            c.frames += counted;
        } else {
            c.orion_lines += counted;
        }
        for i in 0..n {
            let (p, q) = (x.get(i), y.get(i));
            if p.is_none() && !recording.is_complete() {
                // A recording that did not end (the bridge was killed) or
                // that lost records (its disk filled) is compared up to
                // its last record: what the replay gave after it has
                // nothing recorded to be compared with.
                break;
            }
            if let (Some(p), Some(q)) = (p, q)
                && same(&p.value, &q.value, tolerance, Kind::Plain)
            {
                continue;
            }
            let at = [p.map(|p| p.at), q.map(|q| q.at)]
                .into_iter()
                .flatten()
                .min()
                .unwrap_or_default();
            if c.divergence.as_ref().is_none_or(|d| at < d.at) {
                c.divergence = Some(Divergence {
                    at,
                    stream: name.clone(),
                    recorded: p.map(|p| p.value.clone()),
                    recorded_at: p.map(|p| p.at),
                    replayed: q.map(|q| q.value.clone()),
                    replayed_at: q.map(|q| q.at),
                });
            }
            break;
        }
    }
    c
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;
    use motorwire_compact::{CompactCommand, Flags, MotorHash};
    use motorwire_core::ControlMode;
    use serde_json::json;

    const MAP: &str = r#"
[motors.elbow]
dialect = "irpc"
node = 0x12
wire = "v2.0"

[motors.gripper]
dialect = "compact"
node = 0x20
"#;

    fn irpc(target: u16, msg_id: u32, payload: Payload) -> Frame {
        let m = Message {
            header: Header {
                source_id: 0,
                target_id: target,
                msg_id,
            },
            payload,
        };
        let mut buf = [0u8; motorwire_irpc::MAX_FRAME_LEN];
        let n = m.encode_frame(WireVersion::V2_0, &mut buf).unwrap();
        Frame::fd(CanId::standard(0).unwrap(), &buf[..n]).unwrap()
    }

    fn compact(timestamp_ms: u64, setpoint: f32) -> Frame {
        let c = CompactCommand {
            motor: MotorHash::of("gripper"),
            timestamp_ms,
            control_mode: ControlMode::Position,
            flags: Flags::default(),
            setpoint,
            velocity_limit: None,
            torque_limit: None,
        };
        Frame::fd(CanId::standard(0x20).unwrap(), &c.encode().unwrap()).unwrap()
    }

    /// A frame is read in its device's dialect, without what the clock
    /// decides: the msg_id and the compact timestamp are left out, a
    /// heartbeat and a request sent again are not compared, and a
    /// different payload or setpoint is a different key.
    #[test]
    fn a_frame_key_leaves_out_what_the_clock_decides() {
        let map = BusMap::from_toml(MAP).unwrap();
        let w = WireVersion::V2_0;
        let mut seen = FramesSeen::default();
        let key = |f: &Frame, seen: &mut FramesSeen| frame_key(&map, w, f, seen);
        let a = key(&irpc(0x12, 7, Payload::Activate), &mut seen).unwrap();
        assert_eq!(a, ("frames to elbow".to_owned(), "Activate".to_owned()));
        // The same request again (a retry): left out.
        assert_eq!(key(&irpc(0x12, 7, Payload::Activate), &mut seen), None);
        // Another msg_id, the same payload: the same key.
        assert_eq!(
            key(&irpc(0x12, 9, Payload::Activate), &mut seen).unwrap(),
            a
        );
        assert_ne!(
            key(&irpc(0x12, 10, Payload::Deactivate), &mut seen).unwrap(),
            a
        );
        // The heartbeat, to everyone: left out.
        assert_eq!(key(&irpc(0xFFFF, 11, Payload::ArmReady), &mut seen), None);
        // Compact: the timestamp left out, the setpoint kept.
        let g = key(&compact(1000, 20.0), &mut seen).unwrap();
        assert_eq!(g.0, "frames to gripper");
        assert!(g.1.starts_with("compact position setpoint 20 "), "{}", g.1);
        assert_eq!(key(&compact(2000, 20.0), &mut seen).unwrap(), g);
        assert_ne!(key(&compact(1000, 21.0), &mut seen).unwrap(), g);
        // A frame no dialect reads is compared as its bytes.
        let odd = Frame::fd(CanId::standard(0x7).unwrap(), &[0xff, 0xff, 0xff]).unwrap();
        assert_eq!(
            key(&odd, &mut seen).unwrap(),
            ("frames on 0x7".to_owned(), "ffffff".to_owned())
        );
    }

    /// A moteus controller's frames: its polls (reads alone) and a
    /// command the same as the one before it (a held move's refresh, a
    /// repeated stop) are the clock's and left out; a command that
    /// differs is kept, keyed to its motor.
    #[test]
    fn a_moteus_controllers_polls_and_refreshes_are_left_out() {
        let map = BusMap::from_toml(
            "[motors.hip]\ndialect = \"moteus\"\nid = 1\nlimits = { min_position = -90, max_position = 90, max_velocity = 180, max_acceleration = 720 }\n",
        )
        .unwrap();
        let mut seen = FramesSeen::default();
        let frame = |hex: &str| {
            let data: Vec<u8> = (0..hex.len())
                .step_by(2)
                .map(|i| u8::from_str_radix(&hex[i..i + 2], 16).unwrap())
                .collect();
            // From the bridge (source 0) to controller 1, asking a reply.
            Frame::fd(CanId::extended(0x8001).unwrap(), &data).unwrap()
        };
        let mut key = |hex: &str| frame_key(&map, WireVersion::V2_0, &frame(hex), &mut seen);
        let poll = "11001f01130d";
        let position = "01000a0e200000003e0000000011001f01130d50";
        let stop = "01000011001f01130d505050";
        assert_eq!(key(poll), None);
        let kept = key(position).unwrap();
        assert_eq!(kept, ("frames to hip".to_owned(), position.to_owned()));
        assert_eq!(key(poll), None);
        assert_eq!(key(position), None);
        assert_eq!(key(stop).unwrap().1, stop);
        assert_eq!(key(stop), None);
        assert_eq!(key(position).unwrap(), kept);
        // Another controller's id on the bus: read as its bytes.
        let other = Frame::fd(CanId::extended(0x8005).unwrap(), &[0x01, 0x00, 0x00]).unwrap();
        assert_eq!(
            frame_key(&map, WireVersion::V2_0, &other, &mut seen).unwrap(),
            ("frames on 0x8005".to_owned(), "010000".to_owned())
        );
    }

    /// Numbers are the same within the tolerance, a motor's state caught
    /// in motion within its own, and the numbers inside a text as
    /// numbers; the members that measure time are left out.
    #[test]
    fn values_are_compared_within_the_tolerance_and_without_timing() {
        let tol = Tolerance::default();
        let s = |a: &Value, b: &Value| same(&untimed(a), &untimed(b), &tol, Kind::Plain);
        assert!(s(
            &json!({"ok": true, "latency_us": 10}),
            &json!({"ok": true, "latency_us": 99})
        ));
        // A device's clock in a request's answer follows when the request
        // reached it; the rest of the answer is compared.
        assert!(s(
            &json!({"ok": true, "data": {"telemetry": {"timestamp_us": 389_135, "position": 1.0}}}),
            &json!({"ok": true, "data": {"telemetry": {"timestamp_us": 378_971, "position": 1.0}}})
        ));
        assert!(!s(
            &json!({"data": {"telemetry": {"timestamp_us": 1, "position": 1.0}}}),
            &json!({"data": {"telemetry": {"timestamp_us": 1, "position": 9.0}}})
        ));
        assert!(!s(&json!({"ok": true}), &json!({"ok": false})));
        assert!(!s(&json!({"ok": true}), &json!({"ok": true, "extra": 1})));
        assert!(s(&json!({"limit": 150.0}), &json!({"limit": 150.04})));
        assert!(!s(&json!({"limit": 150.0}), &json!({"limit": 150.06})));
        // In motion: a position within 2, a velocity within 5.
        assert!(s(&json!({"velocity": 58.9}), &json!({"velocity": 62.26})));
        assert!(!s(&json!({"velocity": 58.9}), &json!({"velocity": 64.0})));
        assert!(!s(&json!({"position": 58.9}), &json!({"position": 61.0})));
        assert!(s(
            &json!({"motors": [{"error": 19.7}]}),
            &json!({"motors": [{"error": 19.0}]})
        ));
        assert!(!s(
            &json!({"motors": [{"error": 19.7}]}),
            &json!({"motors": [{"error": 17.6}]})
        ));
        // A large number is not let off by its size.
        assert!(!s(
            &json!({"t": 1_796_295_440_966.0_f64}),
            &json!({"t": 1_796_295_440_967.0_f64})
        ));
        // Inside a text.
        assert!(s(
            &json!("timestamp 17 is 0.992 s before the stop (at 1796295440966.568)"),
            &json!("timestamp 17 is 0.992 s before the stop (at 1796295440966.5684)")
        ));
        assert!(!s(
            &json!("setpoint 170 is outside max_position 150"),
            &json!("setpoint 170 is outside max_position 20")
        ));
        assert!(!s(&json!("elbow: busy"), &json!("elbow: idle")));
        // A number printed to 0.1 may be rounded either side: one unit of
        // its last place; an integer is not let off beyond the tolerance.
        assert!(s(
            &json!("timestamp 1000 is 1796296047.2 s old"),
            &json!("timestamp 1000 is 1796296047.1 s old")
        ));
        assert!(!s(
            &json!("timestamp 1000 is 1796296047.3 s old"),
            &json!("timestamp 1000 is 1796296047.1 s old")
        ));
        assert!(!s(&json!("line 7"), &json!("line 8")));
        assert_eq!(
            pieces("-3.5 deg, node-2 at 10"),
            vec![
                Ok((-3.5, 1)),
                Err(" deg, node-"),
                Ok((2.0, 0)),
                Err(" at "),
                Ok((10.0, 0))
            ]
        );
    }

    /// A recording whose bridge was killed in the middle of a write ends
    /// in a line with no newline: it is left out and said, and everything
    /// before it is read. A recording that ended cleanly, or a bad line
    /// that has its newline, is damage and refused, naming the line.
    #[test]
    fn a_last_line_cut_by_a_kill_is_left_out_and_said() {
        let dir = std::env::temp_dir().join(format!("motorwire-replay-cut-{}", std::process::id()));
        fs::create_dir_all(&dir).unwrap();
        let session = r#"{"recorder":"motorwire","files":["frames.log","lines.jsonl"]}"#;
        let whole = "{\"t_us\":0,\"wall_ms\":1,\"mark\":{\"kind\":\"start\"}}\n\
                     {\"t_us\":5,\"wall_ms\":1,\"in\":{\"origin\":0,\"line\":1,\"text\":\"{}\"}}\n";
        let cut = format!("{whole}{{\"t_us\":9,\"wall_ms\":1,\"in\":{{\"origin\":0,\"li");
        fs::write(dir.join("session.json"), session).unwrap();
        fs::write(dir.join("lines.jsonl"), &cut).unwrap();
        let r = Recording::read(&dir).unwrap();
        assert!(!r.ended);
        assert!(r.cut);
        assert_eq!(r.records.len(), 2);
        assert_eq!(
            r.records[1],
            (
                Duration::from_micros(5),
                Recorded::Line {
                    taken: None,
                    origin: Origin(0),
                    number: 1,
                    text: "{}".to_owned()
                }
            )
        );
        // Cut at a line's end: nothing is left out.
        fs::write(dir.join("lines.jsonl"), whole).unwrap();
        let r = Recording::read_partial(&dir).unwrap();
        assert!(!r.cut);
        assert_eq!(r.records.len(), 2);
        // A bad line with its newline is not a cut write.
        fs::write(dir.join("lines.jsonl"), format!("{whole}{{\"t_us\":\n")).unwrap();
        let e = Recording::read(&dir).unwrap_err().to_string();
        assert!(e.contains("lines.jsonl:3: EOF while parsing"), "{e}");
        // A recording that ended cleanly was not cut by a kill.
        fs::write(
            dir.join("session.json"),
            r#"{"recorder":"motorwire","files":["frames.log","lines.jsonl"],"written":3,"dropped":0,"bytes":300}"#,
        )
        .unwrap();
        fs::write(dir.join("lines.jsonl"), &cut).unwrap();
        let e = Recording::read(&dir).unwrap_err().to_string();
        assert!(e.contains("lines.jsonl:3: EOF while parsing"), "{e}");
        let _ = fs::remove_dir_all(&dir);
    }

    /// A recording's `session.json` says whether it is whole: since the
    /// counts are written from the start, by its end (`ended_wall_ms`) and
    /// its `dropped`; before, by its counts alone. One that dropped
    /// records is refused for a replay, or read as far as it goes when
    /// allowed (its last line, cut by the failed disk, left out; its counts
    /// not checked against its files), saying what it lost and when, from
    /// the start mark.
    #[test]
    fn a_recording_that_lost_records_is_read_only_when_allowed() {
        let dir =
            std::env::temp_dir().join(format!("motorwire-replay-lossy-{}", std::process::id()));
        fs::create_dir_all(&dir).unwrap();
        let whole = "{\"t_us\":100,\"wall_ms\":1,\"mark\":{\"kind\":\"start\"}}\n\
                     {\"t_us\":150,\"wall_ms\":1,\"in\":{\"origin\":0,\"line\":1,\"text\":\"{}\"}}\n";
        let cut = format!("{whole}{{\"t_us\":200,\"wall_ms\":1,\"out\":{{\"fe");
        let session = |counts: &str| {
            format!(r#"{{"recorder":"motorwire","files":["frames.log","lines.jsonl"]{counts}}}   "#)
        };
        fs::write(dir.join("lines.jsonl"), &cut).unwrap();
        // Ended, three records dropped from 1.1 ms to 2.1 ms on the
        // recording's clock (1 ms to 2 ms from its start), one of the two
        // written records counted dropped (the flush that failed).
        fs::write(
            dir.join("session.json"),
            session(
                r#","complete":false,"written":1,"dropped":3,"bytes":9,"dropped_first_us":1100,"dropped_last_us":2100,"ended_wall_ms":5"#,
            ),
        )
        .unwrap();
        let e = Recording::read_to_replay(&dir).unwrap_err().to_string();
        assert!(e.starts_with("the recording dropped 3 records"), "{e}");
        let r = Recording::read_to_replay_lossy(&dir).unwrap();
        assert!(r.ended && r.cut && !r.is_complete());
        assert_eq!(r.records.len(), 2);
        assert_eq!(r.dropped, 3);
        assert_eq!(
            r.dropped_span,
            Some((Duration::from_millis(1), Duration::from_millis(2)))
        );
        assert_eq!(
            r.incomplete().unwrap(),
            "the recording dropped 3 records (its queue or its disk could not take them, from 0.001 s to 0.002 s): its inputs and outputs may not all be there"
        );
        let s = Recording::scan_partial(&dir, |_, _| {}).unwrap();
        assert_eq!((s.dropped, s.dropped_span), (r.dropped, r.dropped_span));
        assert_eq!(s.incomplete(), r.incomplete());
        // Written from the start, never ended (the writer killed): counts
        // there, the end not.
        fs::write(dir.join("lines.jsonl"), whole).unwrap();
        fs::write(
            dir.join("session.json"),
            session(r#","complete":false,"written":2,"dropped":0,"bytes":9"#),
        )
        .unwrap();
        let r = Recording::read_to_replay(&dir).unwrap();
        assert!(!r.ended && !r.is_complete() && r.dropped == 0);
        assert!(
            r.incomplete()
                .unwrap()
                .starts_with("the recording did not end cleanly"),
            "{:?}",
            r.incomplete()
        );
        // Ended and whole: complete, and checked against its counts.
        fs::write(dir.join("frames.log"), "").unwrap();
        fs::write(
            dir.join("session.json"),
            session(r#","complete":true,"written":2,"dropped":0,"bytes":9,"ended_wall_ms":5"#),
        )
        .unwrap();
        for r in [
            Recording::read_to_replay(&dir).unwrap(),
            Recording::read_to_replay_lossy(&dir).unwrap(),
        ] {
            assert!(r.is_complete() && r.incomplete().is_none());
        }
        fs::write(
            dir.join("session.json"),
            session(r#","complete":true,"written":3,"dropped":0,"bytes":9,"ended_wall_ms":5"#),
        )
        .unwrap();
        let e = Recording::read_to_replay_lossy(&dir)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("session.json says 3 records were written"),
            "{e}"
        );
        // Before the counts were written from the start: its counts are its
        // end.
        fs::write(
            dir.join("session.json"),
            session(r#","written":2,"dropped":0,"bytes":9"#),
        )
        .unwrap();
        assert!(Recording::read(&dir).unwrap().is_complete());
        let _ = fs::remove_dir_all(&dir);
    }

    /// Read for a replay, a recording leaves out its feedback lines but
    /// the one later than every record after it: what is compared is all
    /// there, and the span is the same.
    #[test]
    fn a_recording_read_to_replay_leaves_out_feedback_but_not_its_span() {
        let dir = std::env::temp_dir().join(format!("motorwire-replay-fb-{}", std::process::id()));
        fs::create_dir_all(&dir).unwrap();
        let session = r#"{"recorder":"motorwire","files":["frames.log","lines.jsonl"]}"#;
        let fb = |t: u64, p: u64| {
            format!(
                "{{\"t_us\":{t},\"wall_ms\":1,\"out\":{{\"feedback\":{{\"motor_id\":\"elbow\",\"position\":{p}}}}}}}\n"
            )
        };
        let lines = [
            "{\"t_us\":100,\"wall_ms\":1,\"mark\":{\"kind\":\"start\"}}\n".to_owned(),
            fb(200, 1),
            "{\"t_us\":300,\"wall_ms\":1,\"in\":{\"origin\":2,\"line\":1,\"text\":\"{}\",\"taken_us\":310}}\n".to_owned(),
            fb(400, 2),
            // Stamped before the feedback written ahead of it.
            "{\"t_us\":350,\"wall_ms\":1,\"out\":{\"ok\":true,\"line\":1},\"to\":2}\n".to_owned(),
            fb(380, 3),
            "{\"t_us\":450,\"wall_ms\":1,\"out\":{\"motor_status\":{\"turntable\":0}}}\n".to_owned(),
            fb(500, 4),
        ]
        .concat();
        fs::write(dir.join("session.json"), session).unwrap();
        fs::write(dir.join("lines.jsonl"), lines).unwrap();
        let all = Recording::read(&dir).unwrap().records;
        assert_eq!(all.len(), 8);
        let us = Duration::from_micros;
        let feedback = |p: u64| {
            out(
                None,
                json!({"feedback": {"motor_id": "elbow", "position": p}}),
            )
        };
        let got = Recording::read_to_replay(&dir).unwrap().records;
        assert_eq!(
            got,
            vec![
                (us(0), Recorded::Mark(Mark::Start)),
                first_line(200, 210),
                // Later than the line after it: kept.
                (us(300), feedback(2)),
                (us(250), out(Some(2), json!({"ok": true, "line": 1}))),
                // The last, and the latest.
                (us(400), feedback(4)),
            ]
        );
        let span = |r: &[(Duration, Recorded)]| r.iter().map(|(t, _)| *t).max();
        assert_eq!(span(&got), span(&all));
        let _ = fs::remove_dir_all(&dir);
    }

    /// Read a record at a time, a recording hands out what `read_partial`
    /// holds, in order, each at its time from the start mark (a record
    /// written before the mark at 0); a line that is not UTF-8 is named.
    #[test]
    fn a_recording_scanned_a_record_at_a_time_is_the_one_read_whole() {
        let dir =
            std::env::temp_dir().join(format!("motorwire-replay-scan-{}", std::process::id()));
        fs::create_dir_all(&dir).unwrap();
        let session = r#"{"recorder":"motorwire","files":["frames.log","lines.jsonl"]}"#;
        let lines = "{\"t_us\":40,\"wall_ms\":1,\"out\":{\"event\":\"ready\"}}\n\
                     {\"t_us\":100,\"wall_ms\":1,\"mark\":{\"kind\":\"start\"}}\n\
                     {\"t_us\":150,\"wall_ms\":1,\"in\":{\"origin\":2,\"line\":1,\"text\":\"{}\",\"taken_us\":160}}\n\
                     {\"t_us\":300,\"wall_ms\":1,\"out\":{\"ok\":true,\"line\":1},\"to\":2}\n";
        fs::write(dir.join("session.json"), session).unwrap();
        fs::write(dir.join("lines.jsonl"), lines).unwrap();
        let mut scanned = Vec::new();
        let s = Recording::scan_partial(&dir, |t, r| scanned.push((t, r))).unwrap();
        assert!(!s.ended && !s.cut && s.setup.is_none());
        let us = Duration::from_micros;
        assert_eq!(
            scanned,
            vec![
                (us(0), out(None, json!({"event": "ready"}))),
                (us(0), Recorded::Mark(Mark::Start)),
                first_line(50, 60),
                (us(200), out(Some(2), json!({"ok": true, "line": 1}))),
            ]
        );
        assert_eq!(Recording::read_partial(&dir).unwrap().records, scanned);
        // Bytes that are not UTF-8 in line 2: named, with what came before
        // handed out.
        let mut bad = lines.as_bytes().to_vec();
        let at = lines.find("start").unwrap();
        bad[at] = 0xff;
        fs::write(dir.join("lines.jsonl"), bad).unwrap();
        let mut n = 0;
        let e = Recording::scan_partial(&dir, |_, _| n += 1)
            .unwrap_err()
            .to_string();
        assert!(e.contains("lines.jsonl:2: invalid unicode"), "{e}");
        assert_eq!(n, 0, "before the start mark, held and not handed out");
        // More records before the start mark than are held: the start is
        // found first, and each is at its time from it all the same; with
        // no start mark, at its time as written.
        let many = HELD_BEFORE_START + 10;
        let mut text: String = (0..many)
            .map(|i| {
                format!(
                    "{{\"t_us\":{},\"wall_ms\":1,\"out\":{{\"n\":{i}}}}}\n",
                    1_000 + i
                )
            })
            .collect();
        let without_start = text.clone();
        text.push_str("{\"t_us\":3000,\"wall_ms\":1,\"mark\":{\"kind\":\"start\"}}\n");
        text.push_str("{\"t_us\":9000,\"wall_ms\":1,\"mark\":{\"kind\":\"finish\"}}\n");
        fs::write(dir.join("lines.jsonl"), &text).unwrap();
        let mut scanned = Vec::new();
        Recording::scan_partial(&dir, |t, r| scanned.push((t, r))).unwrap();
        assert_eq!(scanned.len(), many + 2);
        assert_eq!(scanned[0], (us(0), out(None, json!({"n": 0}))));
        assert_eq!(scanned[many], (us(0), Recorded::Mark(Mark::Start)));
        assert_eq!(scanned[many + 1], (us(6_000), Recorded::Mark(Mark::Finish)));
        assert_eq!(Recording::read_partial(&dir).unwrap().records, scanned);
        fs::write(dir.join("lines.jsonl"), &without_start).unwrap();
        let mut scanned = Vec::new();
        Recording::scan_partial(&dir, |t, r| scanned.push((t, r))).unwrap();
        assert_eq!(scanned.len(), many);
        assert_eq!(
            scanned[many - 1],
            (
                us(1_000 + many as u64 - 1),
                out(None, json!({"n": many - 1}))
            )
        );
        let _ = fs::remove_dir_all(&dir);
    }

    /// Client 2's line 1, `{}`, at `at` µs, taken at `taken` µs.
    fn first_line(at: u64, taken: u64) -> (Duration, Recorded) {
        let us = Duration::from_micros;
        (
            us(at),
            Recorded::Line {
                taken: Some(us(taken)),
                origin: Origin(2),
                number: 1,
                text: "{}".to_owned(),
            },
        )
    }

    fn out(to: Option<u64>, value: Value) -> Recorded {
        Recorded::Output { to, value }
    }

    /// The comparison names the earliest difference among the streams,
    /// with both sides; a line answered on one side only diverges; the
    /// order of different lines' answers does not matter, the order within
    /// one stream does.
    #[test]
    fn the_first_divergence_is_the_earliest_of_every_stream() {
        let map = BusMap::from_toml(MAP).unwrap();
        let ms = Duration::from_millis;
        let cmp = |r: &Recording, p: &Replayed| {
            compare(r, p, &map, WireVersion::V2_0, &Tolerance::default())
        };
        let recording = Recording {
            setup: None,
            ended: true,
            cut: false,
            dropped: 0,
            dropped_span: None,
            records: vec![
                (ms(1), out(Some(1), json!({"ok": true, "line": 1}))),
                (ms(2), out(Some(2), json!({"ok": true, "line": 1}))),
                (ms(3), out(None, json!({"event": "emergency_stop"}))),
                (ms(4), out(None, json!({"feedback": {"position": 1.0}}))),
                (
                    ms(5),
                    Recorded::Frame {
                        dir: Direction::Tx,
                        frame: irpc(0x12, 1, Payload::Activate),
                        taken: None,
                    },
                ),
            ],
        };
        let mut replayed = Replayed {
            records: vec![
                // Another order across clients, another msg_id, no
                // feedback: the same.
                (ms(1), out(Some(2), json!({"ok": true, "line": 1}))),
                (
                    ms(1),
                    out(Some(1), json!({"ok": true, "line": 1, "latency_us": 5})),
                ),
                (
                    ms(2),
                    Recorded::Frame {
                        dir: Direction::Tx,
                        frame: irpc(0x12, 40, Payload::Activate),
                        taken: None,
                    },
                ),
                (ms(3), out(None, json!({"event": "emergency_stop"}))),
            ],
            ..Replayed::default()
        };
        let c = cmp(&recording, &replayed);
        assert_eq!(c.divergence, None);
        assert_eq!((c.answers, c.events, c.frames, c.orion_lines), (2, 1, 1, 0));
        // Client 2's line refused in the replay, and an event more later.
        replayed.records[0].1 = out(Some(2), json!({"ok": false, "line": 1}));
        replayed
            .records
            .push((ms(9), out(None, json!({"event": "deadman"}))));
        let c = cmp(&recording, &replayed);
        let d = c.divergence.unwrap();
        assert_eq!(d.stream, "client 2 line 1");
        assert_eq!(d.at, ms(1));
        assert_eq!(d.recorded, Some(json!({"ok": true, "line": 1})));
        assert_eq!(d.recorded_at, Some(ms(2)));
        assert_eq!(d.replayed, Some(json!({"ok": false, "line": 1})));
        // Only the extra event left: it diverges at its time, with
        // nothing recorded there.
        replayed.records[0].1 = out(Some(2), json!({"ok": true, "line": 1}));
        let c = cmp(&recording, &replayed);
        let d = c.divergence.unwrap();
        assert_eq!((d.stream.as_str(), d.at), ("events", ms(9)));
        assert_eq!((d.recorded, d.recorded_at), (None, None));
        assert_eq!(d.replayed, Some(json!({"event": "deadman"})));
        // The same recording, had its bridge been killed: compared up to
        // its end, the replay's event after it has nothing to differ from;
        // a difference before its end still diverges.
        let mut killed = recording.clone();
        killed.ended = false;
        let c = cmp(&killed, &replayed);
        assert_eq!(c.divergence, None);
        assert_eq!((c.answers, c.events, c.frames, c.orion_lines), (2, 1, 1, 0));
        // So is one that ended but lost records (its disk filled).
        let mut lossy = recording.clone();
        lossy.dropped = 4;
        assert!(!lossy.is_complete());
        assert_eq!(cmp(&lossy, &replayed).divergence, None);
        replayed.records[3].1 = out(None, json!({"event": "released"}));
        let c = cmp(&killed, &replayed);
        let d = c.divergence.unwrap();
        assert_eq!((d.stream.as_str(), d.at), ("events", ms(3)));
    }
}
