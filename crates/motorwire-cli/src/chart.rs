//! A session drawn for a person: one panel per motor (its position with
//! its target and its limits as bands, its velocity with its speed limit),
//! the events as numbered marks across every panel with a key below, the
//! units on the axes. `motorwire plot` draws a recording with it; the demo
//! draws its own session with it.
//!
//! The session is given as what the bridge took and gave, each at its
//! time, reduced as it is read to what the chart draws ([`Digest`]: the
//! motors' samples and targets, the marks): a long recording is never held
//! whole. [`Session`] keeps a session's lines for a caller that has them
//! already (the demo). The map says each motor's unit and limits.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

use motorwire_orion::Quantity;
use motorwire_translate::{AngleUnit, BusMap, MappedMotor, Target};
use serde_json::Value;

/// What a session took and gave, each at its time (seconds from its
/// start).
#[derive(Debug, Default)]
pub(crate) struct Session {
    /// Input lines: time, client, line number, text.
    pub(crate) inputs: Vec<(f64, u64, u64, String)>,
    /// Output lines: time, whose (`None`: every reader's), the line.
    pub(crate) outputs: Vec<(f64, Option<u64>, Value)>,
    /// Marks of the caller's own (the demo's steps), with their labels.
    pub(crate) steps: Vec<(f64, String)>,
}

/// What a mark is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum MarkKind {
    /// A step of the caller's.
    Step,
    /// The emergency stop.
    Stop,
    /// Its release.
    Release,
    /// A line refused.
    Refused,
    /// A deadman stop.
    Deadman,
    /// A device or a link lost, a fault.
    Lost,
}

impl MarkKind {
    /// Every kind, in the order the key counts those not drawn.
    const ALL: [Self; 6] = [
        Self::Step,
        Self::Stop,
        Self::Release,
        Self::Refused,
        Self::Deadman,
        Self::Lost,
    ];

    const fn index(self) -> usize {
        self as usize
    }

    /// What marks of this kind are, in the key's count of those not drawn.
    const fn plural(self) -> &'static str {
        match self {
            Self::Step => "steps",
            Self::Stop => "emergency stops",
            Self::Release => "releases",
            Self::Refused => "refused lines",
            Self::Deadman => "deadman stops",
            Self::Lost => "devices or links lost and faults",
        }
    }

    const fn color(self) -> (u8, u8, u8) {
        match self {
            Self::Step => (120, 120, 120),
            Self::Stop => (200, 0, 0),
            Self::Release => (0, 140, 60),
            Self::Refused => (213, 94, 0),
            Self::Deadman => (150, 60, 170),
            Self::Lost => (90, 90, 200),
        }
    }
}

/// A mark on the time axis.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Mark {
    pub(crate) t: f64,
    pub(crate) kind: MarkKind,
    pub(crate) label: String,
}

/// What a motor's value is, for its axes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Shown {
    /// A position with its velocity, in degrees or radians.
    Angle(AngleUnit),
    /// An Orion speed motor: its commanded speed in the controller's
    /// units (it reports no position).
    OrionSpeed,
    /// An Orion actuator: its command, -1 to 1 (no position).
    OrionActuator,
}

impl Shown {
    /// What `m`'s value is, and its range: an Orion speed or actuator
    /// motor's is the controller's own range, a position's the map's
    /// limits.
    pub(crate) fn of(m: &MappedMotor) -> (Self, (Option<f64>, Option<f64>)) {
        let map_limits = (m.limits.min_position, m.limits.max_position);
        match m.target {
            Target::Orion { motor } => {
                let (lo, hi) = motor.range();
                match motor.quantity() {
                    Quantity::Speed => (Self::OrionSpeed, (Some(lo), Some(hi))),
                    Quantity::Actuator => (Self::OrionActuator, (Some(lo), Some(hi))),
                    Quantity::PositionDegrees => (Self::Angle(AngleUnit::Degrees), map_limits),
                }
            }
            _ => (Self::Angle(m.unit), map_limits),
        }
    }

    /// The quantity's name (`position`, `speed`, `actuator`).
    pub(crate) const fn quantity(self) -> &'static str {
        match self {
            Self::Angle(_) => "position",
            Self::OrionSpeed => "speed",
            Self::OrionActuator => "actuator",
        }
    }

    /// Its unit, as a person reads it.
    pub(crate) const fn unit(self) -> &'static str {
        match self {
            Self::Angle(AngleUnit::Degrees) => "°",
            Self::Angle(AngleUnit::Radians) => "rad",
            Self::OrionSpeed => "controller units",
            Self::OrionActuator => "-1 to 1",
        }
    }
}

/// One motor's panel.
#[derive(Debug, Clone)]
struct Track {
    motor: String,
    shown: Shown,
    /// (t, position, velocity)
    samples: Vec<(f64, f64, f64)>,
    /// Each target from its time (`None`: no target from then on).
    targets: Vec<(f64, Option<f64>)>,
    position_limits: (Option<f64>, Option<f64>),
    max_velocity: Option<f64>,
}

impl Track {
    fn value_name(&self) -> String {
        match self.shown {
            Shown::Angle(AngleUnit::Degrees) => "position (°)".to_owned(),
            Shown::Angle(AngleUnit::Radians) => "position (rad)".to_owned(),
            Shown::OrionSpeed => "speed (controller units, ±400)".to_owned(),
            Shown::OrionActuator => "actuator command (-1 to 1)".to_owned(),
        }
    }

    fn velocity_name(&self) -> Option<&'static str> {
        match self.shown {
            Shown::Angle(AngleUnit::Degrees) => Some("velocity (°/s)"),
            Shown::Angle(AngleUnit::Radians) => Some("velocity (rad/s)"),
            Shown::OrionSpeed | Shown::OrionActuator => None,
        }
    }

    /// The value the left chart draws: an angle's position, an Orion
    /// motor's commanded value (its feedback's velocity).
    fn value(&self, s: &(f64, f64, f64)) -> f64 {
        match self.shown {
            Shown::Angle(_) => s.1,
            Shown::OrionSpeed | Shown::OrionActuator => s.2,
        }
    }
}

impl Session {
    /// What [`draw`] draws of it: its steps, then its outputs, in order.
    pub(crate) fn digest(&self) -> Digest {
        let mut d = Digest::default();
        for (t, label) in &self.steps {
            d.step(*t, label.clone());
        }
        for (t, to, v) in &self.outputs {
            d.output(*t, *to, v);
        }
        for i in &self.inputs {
            d.at(i.0);
        }
        d
    }
}

/// What a chart is drawn from, taken from a session one line at a time:
/// each motor's feedback samples and targets, the stops, the marks, and
/// the session's end. Memory grows with the samples and marks (a few
/// numbers each), never with the lines themselves.
#[derive(Debug, Default)]
pub(crate) struct Digest {
    /// Each motor's (t, position, velocity).
    samples: BTreeMap<String, Vec<(f64, f64, f64)>>,
    /// Each motor's targets, each from its time (`None`: none from then).
    targets: BTreeMap<String, Vec<(f64, Option<f64>)>>,
    /// The motors drawn, when known before the session is read (a map's):
    /// samples, targets and deadman stops of others are not kept.
    motors: Option<BTreeSet<String>>,
    /// When each line was accepted: its targets start then. At most
    /// [`MAX_ACCEPTED`], the oldest let go first (`accepted_order`).
    accepted: BTreeMap<(Option<u64>, u64), f64>,
    accepted_order: std::collections::VecDeque<(Option<u64>, u64)>,
    /// The emergency stops.
    stops: Vec<f64>,
    /// The motors a deadman stopped.
    deadman: BTreeSet<String>,
    /// The marks, in the order they came: at most [`MAX_MARKS_OF_A_KIND`]
    /// of each kind, each label at most [`KEY_CHARS`] characters.
    marks: Vec<Mark>,
    /// Of each kind ([`MarkKind::index`]): the marks kept, and those not
    /// (counted only).
    kept: [usize; MarkKind::ALL.len()],
    not_kept: [u64; MarkKind::ALL.len()],
    /// The latest time seen.
    end: f64,
    /// The session is not all there (a recording that lost records or did
    /// not end cleanly): what to say above the panels, and when the
    /// records lost came, where known (seconds from the start).
    incomplete: Option<(String, Option<(f64, f64)>)>,
}

impl Digest {
    /// A digest that keeps the samples, targets and deadman stops of
    /// `motors` only (a map's: no other is drawn).
    pub(crate) fn of_motors<'a>(motors: impl IntoIterator<Item = &'a str>) -> Self {
        Self {
            motors: Some(motors.into_iter().map(str::to_owned).collect()),
            ..Self::default()
        }
    }

    /// Whether `motor`'s samples and targets are kept.
    fn drawn(&self, motor: &str) -> bool {
        self.motors.as_ref().is_none_or(|m| m.contains(motor))
    }

    /// Something happened at `t` (an input line): the time axis reaches it.
    pub(crate) fn at(&mut self, t: f64) {
        self.end = self.end.max(t);
    }

    /// The session is not all there: `notice` says what it lacks, above
    /// the panels, and `lost` (seconds from the start) is shaded on each
    /// chart, which reaches it.
    pub(crate) fn incomplete(&mut self, notice: String, lost: Option<(f64, f64)>) {
        let lost = lost.and_then(|(a, b)| Some((drawable(a)?.max(0.0), drawable(b)?.max(0.0))));
        if let Some((_, b)) = lost {
            self.at(b);
        }
        self.incomplete = Some((notice, lost));
    }

    /// A step of the caller's, labelled.
    pub(crate) fn step(&mut self, t: f64, label: String) {
        self.at(t);
        self.keep(Mark {
            t,
            kind: MarkKind::Step,
            label,
        });
    }

    /// `m` kept, its label cut to what the key shows, while fewer than
    /// [`MAX_MARKS_OF_A_KIND`] of its kind are; else counted only (a
    /// flood of refused lines neither grows the chart without end nor
    /// hides the stops among them).
    fn keep(&mut self, mut m: Mark) {
        let k = m.kind.index();
        let (Some(kept), Some(not_kept)) = (self.kept.get_mut(k), self.not_kept.get_mut(k)) else {
            return;
        };
        if *kept >= MAX_MARKS_OF_A_KIND {
            *not_kept += 1;
            return;
        }
        *kept += 1;
        if m.label.len() > KEY_CHARS {
            m.label = cut(&m.label, KEY_CHARS);
        }
        self.marks.push(m);
    }

    /// An output line `v` given at `t` (to client `to`, `None`: every
    /// reader's).
    pub(crate) fn output(&mut self, t: f64, to: Option<u64>, v: &Value) {
        self.at(t);
        self.mark(t, v);
        self.track(t, to, v);
    }

    /// The mark `v` makes, if any: an emergency stop or its release, a
    /// refusal (with its rule), a deadman stop, a device or link lost, a
    /// fault.
    fn mark(&mut self, t: f64, v: &Value) {
        let motor = v.get("motor_id").and_then(Value::as_str).unwrap_or("");
        let mark = |kind, label: String| Mark { t, kind, label };
        if v.get("ok") == Some(&Value::Bool(false)) {
            let rule = v
                .get("error")
                .and_then(|e| e.get("rule"))
                .and_then(Value::as_str)
                .unwrap_or("refused");
            let line = v.get("line").and_then(Value::as_u64).unwrap_or(0);
            let who = if motor.is_empty() {
                String::new()
            } else {
                format!(" {motor}")
            };
            self.keep(mark(
                MarkKind::Refused,
                format!("line {line}{who} refused: {rule}"),
            ));
            return;
        }
        let Some(event) = v.get("event").and_then(Value::as_str) else {
            return;
        };
        let made = match event {
            "emergency_stop" => mark(
                MarkKind::Stop,
                format!(
                    "emergency stop ({})",
                    v.get("cause").and_then(Value::as_str).unwrap_or("?")
                ),
            ),
            "released" => mark(MarkKind::Release, "released".to_owned()),
            "deadman" => mark(
                MarkKind::Deadman,
                format!("deadman: {motor} stopped, no command within its timeout"),
            ),
            "offline" => mark(
                MarkKind::Lost,
                format!(
                    "{motor} offline: {}",
                    v.get("reason").and_then(Value::as_str).unwrap_or("silent")
                ),
            ),
            "orion_link_lost" => mark(
                MarkKind::Lost,
                "the Orion controller's link lost".to_owned(),
            ),
            "joint_fault" => mark(MarkKind::Lost, format!("{motor}: fault")),
            "rebooted" => mark(MarkKind::Lost, format!("{motor}: rebooted")),
            _ => return,
        };
        self.keep(made);
    }

    /// What `v` says of the motors' panels: a feedback sample, a line
    /// accepted, a move's target (from when its line was accepted), a
    /// stop, a deadman.
    fn track(&mut self, t: f64, to: Option<u64>, v: &Value) {
        // A deadman names its motor whatever else its line holds.
        if v.get("event").and_then(Value::as_str) == Some("deadman")
            && let Some(m) = v.get("motor_id").and_then(Value::as_str)
            && self.drawn(m)
        {
            self.deadman.insert(m.to_owned());
        }
        if let Some(f) = v.get("feedback") {
            let (Some(motor), Some(p), Some(vel)) = (
                f.get("motor_id").and_then(Value::as_str),
                f.get("position").and_then(Value::as_f64),
                f.get("velocity").and_then(Value::as_f64),
            ) else {
                return;
            };
            // Not a number, or beyond any motor's reach: drawn at the
            // edge, never an axis with no end.
            let (Some(p), Some(vel)) = (drawable(p), drawable(vel)) else {
                return;
            };
            if !self.drawn(motor) {
                return;
            }
            match self.samples.get_mut(motor) {
                Some(s) => s.push((t, p, vel)),
                None => {
                    self.samples.insert(motor.to_owned(), vec![(t, p, vel)]);
                }
            }
            return;
        }
        if v.get("ok") == Some(&Value::Bool(true))
            && let Some(line) = v.get("line").and_then(Value::as_u64)
        {
            if self.accepted.insert((to, line), t).is_none() {
                self.accepted_order.push_back((to, line));
            }
            // A completion comes soon after its acceptance: the oldest
            // let go (a completion of one is drawn from its own time).
            while self.accepted_order.len() > MAX_ACCEPTED {
                if let Some(k) = self.accepted_order.pop_front() {
                    self.accepted.remove(&k);
                }
            }
        }
        if v.get("arrived").is_some() {
            let line = v.get("line").and_then(Value::as_u64).unwrap_or(0);
            let from = self.accepted.get(&(to, line)).copied().unwrap_or(t);
            for m in v
                .get("motors")
                .and_then(Value::as_array)
                .into_iter()
                .flatten()
            {
                if let (Some(motor), Some(target)) = (
                    m.get("motor_id").and_then(Value::as_str),
                    m.get("target").and_then(Value::as_f64).and_then(drawable),
                ) && self.drawn(motor)
                {
                    self.targets
                        .entry(motor.to_owned())
                        .or_default()
                        .push((from, Some(target)));
                }
            }
        }
        if v.get("event").and_then(Value::as_str) == Some("emergency_stop") {
            self.stops.push(t);
        }
    }

    /// The session's end on the time axis (at least a millisecond).
    fn end(&self) -> f64 {
        self.end.max(1e-3)
    }
}

/// The marks of a session, in time order (those at one time in the
/// order they came).
fn marks(d: &mut Digest) -> Vec<Mark> {
    let mut out = std::mem::take(&mut d.marks);
    out.sort_by(|a, b| a.t.total_cmp(&b.t));
    out
}

/// The motors' panels: every motor of `map` that moved, had a target or
/// was named by a deadman (or those of `only`, when given).
fn tracks(d: &mut Digest, map: &BusMap, only: &[String]) -> Vec<Track> {
    let mut out = Vec::new();
    d.stops.sort_by(f64::total_cmp);
    for m in map.motors() {
        let mut s = d.samples.remove(&m.name).unwrap_or_default();
        // In time order (a record is stamped when it came, so it may be a
        // little earlier than the one before it): a line through time.
        s.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut targets = d.targets.remove(&m.name).unwrap_or_default();
        targets.sort_by(|a, b| a.0.total_cmp(&b.0));
        // A stop ends every target (a move's completion, and so its
        // target, may come after the stop that cut it short): each target,
        // and the first stop after it before the next target.
        let mut tg = Vec::with_capacity(targets.len() * 2);
        for (k, target) in targets.iter().enumerate() {
            tg.push(*target);
            let next = targets.get(k + 1).map_or(f64::INFINITY, |n| n.0);
            let first = d.stops.partition_point(|t| *t < target.0);
            if let Some(stop) = d.stops.get(first).filter(|t| **t < next) {
                tg.push((*stop, None));
            }
        }
        let moved = s
            .first()
            .is_some_and(|f| s.iter().any(|x| x.1 != f.1 || x.2 != f.2));
        let wanted = if only.is_empty() {
            moved || tg.iter().any(|x| x.1.is_some()) || d.deadman.contains(&m.name)
        } else {
            only.contains(&m.name)
        };
        if !wanted {
            continue;
        }
        let (shown, (lo, hi)) = Shown::of(m);
        out.push(Track {
            motor: m.name.clone(),
            shown,
            samples: s,
            targets: tg,
            position_limits: (lo, hi),
            max_velocity: m.limits.max_velocity,
        });
    }
    out
}

/// The row of each label at `xs` (pixels, in time order): the first row
/// where it clears the label before it by that label's width
/// ([`label_width`]: more for more digits), so no two overlap.
/// At most [`MAX_LABEL_ROWS`] rows: a label that clears none is not
/// shown above the charts (`None`; its mark is drawn and listed in the
/// key).
fn label_rows(xs: impl Iterator<Item = f64>) -> Vec<Option<usize>> {
    // Where each row's last number ends.
    let mut rows: Vec<f64> = Vec::new();
    let mut placed = Vec::new();
    for (i, x) in xs.enumerate() {
        let row = rows.iter().position(|end| x >= *end).or_else(|| {
            (rows.len() < MAX_LABEL_ROWS).then(|| {
                rows.push(f64::NEG_INFINITY);
                rows.len() - 1
            })
        });
        if let Some(r) = row.and_then(|row| rows.get_mut(row)) {
            *r = x + label_width(i + 1);
        }
        placed.push(row);
    }
    placed
}

/// Rows of mark numbers above the charts, at most.
const MAX_LABEL_ROWS: usize = 6;

/// `text` fit for an SVG's text: control characters (which XML forbids)
/// as U+FFFD.
fn printable(text: &str) -> String {
    // XML 1.0 forbids the control characters (but tab and line ends, which
    // a label has no use for) and U+FFFE and U+FFFF.
    text.chars()
        .map(|c| {
            if c.is_control() || matches!(c, '\u{FFFE}' | '\u{FFFF}') {
                '\u{FFFD}'
            } else {
                c
            }
        })
        .collect()
}

/// The largest magnitude drawn: beyond, a value is drawn at it (no motor
/// moves that far; an axis over it would have no ticks to compute).
const MAX_DRAWN: f64 = 1e9;

fn drawable(v: f64) -> Option<f64> {
    v.is_finite().then(|| v.clamp(-MAX_DRAWN, MAX_DRAWN))
}

/// What [`draw`] drew.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Drawn {
    pub(crate) panels: usize,
    pub(crate) marks: usize,
}

/// Acceptances remembered, at most, for the targets of the completions
/// that follow them.
const MAX_ACCEPTED: usize = 65_536;

/// Marks of one kind drawn, at most; the key counts the rest.
const MAX_MARKS_OF_A_KIND: usize = 100;

/// Points of a line drawn in one pixel column, at most: its first, its
/// lowest, its highest and its last (what a person sees of a line there).
const POINTS_A_COLUMN: usize = 4;

const WIDTH: u32 = 1200;
const PANEL: u32 = 230;
const KEY_LINE: u32 = 18;
/// The room a mark's number takes above the charts: 22 pixels for up to
/// two digits (12-pixel type, and a gap), 7 more for each more digit.
fn label_width(n: usize) -> f64 {
    let digits = n.checked_ilog10().map_or(1, |d| d + 1);
    22.0 + 7.0 * f64::from(digits.saturating_sub(2))
}

/// A line of the key: at most this many characters (its column is 590
/// pixels wide, about 7 a character at 13 pixels).
const KEY_CHARS: usize = 80;

/// `text` cut to `max` characters, its end marked with `…` where cut.
fn cut(text: &str, max: usize) -> String {
    if text.chars().count() <= max {
        return text.to_owned();
    }
    let mut s: String = text.chars().take(max.saturating_sub(1)).collect();
    s.push('…');
    s
}

/// A pixel column's first, lowest, highest and last points, each with its
/// place in the line.
type Column = [(usize, (f64, f64)); POINTS_A_COLUMN];

/// The points of a line through `points` (`len` of them, in time order)
/// that a chart `columns` pixels wide over `0..end` shows: all of them
/// while there are at most [`POINTS_A_COLUMN`] a column; else, in each
/// column, its first, lowest, highest and last point, in time order (the
/// line a person sees there is the same; a long recording's SVG is not
/// as long as the recording).
fn thinned(
    points: impl Iterator<Item = (f64, f64)>,
    len: usize,
    end: f64,
    columns: usize,
) -> Vec<(f64, f64)> {
    if len <= POINTS_A_COLUMN * columns || columns == 0 {
        return points.collect();
    }
    let mut out = Vec::with_capacity(POINTS_A_COLUMN * (columns + 1));
    // The column being read: its number, and its first, lowest, highest
    // and last points with their places in the line.
    let mut open: Option<(usize, Column)> = None;
    let flush = |out: &mut Vec<(f64, f64)>, mut four: Column| {
        four.sort_by_key(|p| p.0);
        let mut last = None;
        for (i, p) in four {
            if last != Some(i) {
                out.push(p);
                last = Some(i);
            }
        }
    };
    #[allow(
        clippy::cast_possible_truncation,
        clippy::cast_sign_loss,
        clippy::cast_precision_loss
    )]
    let column_of = |t: f64| ((t / end).clamp(0.0, 1.0) * columns as f64) as usize;
    for (i, p) in points.enumerate() {
        let c = column_of(p.0);
        match &mut open {
            Some((col, four)) if *col == c => {
                if p.1 < four[1].1.1 {
                    four[1] = (i, p);
                }
                if p.1 > four[2].1.1 {
                    four[2] = (i, p);
                }
                four[3] = (i, p);
            }
            _ => {
                if let Some((_, four)) = open.take() {
                    flush(&mut out, four);
                }
                open = Some((c, [(i, p); POINTS_A_COLUMN]));
            }
        }
    }
    if let Some((_, four)) = open {
        flush(&mut out, four);
    }
    out
}

/// Draws a session (its digest `d`; its motors' units and limits from
/// `map`; only the motors `only` names, when it names any) as an SVG at
/// `path`, titled `title`.
///
/// # Errors
/// The file cannot be written.
#[allow(clippy::too_many_lines)]
pub(crate) fn draw(
    mut d: Digest,
    map: &BusMap,
    only: &[String],
    title: &str,
    path: &Path,
) -> Result<Drawn, String> {
    use plotters::prelude::*;
    // Taken out of the digest, not copied: a long recording's samples and
    // marks are held once.
    let tracks = tracks(&mut d, map, only);
    let marks = marks(&mut d);
    let end = d.end();
    // The marks' numbers, in rows above the panels, never overlapping:
    // each goes in the first row where it clears the number before it.
    // As ChartBuilder lays a chart out: its margin, then its y labels.
    let plot_left = 12.0 + 58.0;
    let plot_right = f64::from(WIDTH) / 2.0 - 12.0;
    let px = |t: f64| plot_left + (t / end) * (plot_right - plot_left);
    // The plots' width in pixels: a measured line is thinned to it.
    #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
    let columns = (plot_right - plot_left) as usize;
    let placed = label_rows(marks.iter().map(|m| px(m.t)));
    let rows = placed.iter().flatten().max().map_or(0, |r| r + 1);
    // An incomplete session's notice: a line of its own under the title.
    let banner: u32 = if d.incomplete.is_some() { 22 } else { 0 };
    let header = 40 + banner + 16 * u32::try_from(rows).unwrap_or(0);
    let panels = u32::try_from(tracks.len().max(1)).unwrap_or(1);
    // Marks not drawn: a line of the key for each kind that had some.
    let not_drawn: Vec<String> = MarkKind::ALL
        .iter()
        .filter_map(|k| {
            let n = d.not_kept.get(k.index()).copied().unwrap_or(0);
            (n > 0).then(|| {
                format!(
                    "{n} more {} not drawn (the first {MAX_MARKS_OF_A_KIND} of each kind are)",
                    k.plural()
                )
            })
        })
        .collect();
    let key_rows = u32::try_from(marks.len()).unwrap_or(0).div_ceil(2)
        + u32::try_from(not_drawn.len()).unwrap_or(0);
    let height = header + panels * PANEL + 40 + key_rows * KEY_LINE;
    let root = SVGBackend::new(path, (WIDTH, height)).into_drawing_area();
    let err = |e: DrawingAreaErrorKind<_>| e.to_string();
    root.fill(&WHITE).map_err(err)?;
    root.draw(&Text::new(
        printable(title),
        (12, 8),
        ("sans-serif", 18).into_font().color(&BLACK),
    ))
    .map_err(err)?;
    let gap = RGBColor(110, 110, 110).mix(0.3);
    let lost = d
        .incomplete
        .as_ref()
        .and_then(|(_, lost)| *lost)
        .map(|(a, b)| {
            // At least a pixel and a half wide: a single record lost is seen.
            let least = 1.5 * end / (plot_right - plot_left);
            let mid = f64::midpoint(a, b);
            (
                a.min(mid - least / 2.0).max(0.0),
                b.max(mid + least / 2.0).min(end),
            )
        });
    if let Some((notice, _)) = &d.incomplete {
        root.draw(&Text::new(
            printable(notice),
            (12, 32),
            ("sans-serif", 14).into_font().color(&RGBColor(190, 30, 30)),
        ))
        .map_err(err)?;
    }
    let (top, rest) = root.split_vertically(header);
    let (body, key) = rest.split_vertically(panels * PANEL);
    let rgb = |(r, g, b): (u8, u8, u8)| RGBColor(r, g, b);
    // The numbers, both halves (position and velocity columns).
    for (i, (m, row)) in marks.iter().zip(&placed).enumerate() {
        let Some(row) = row else { continue };
        for half in [0.0, f64::from(WIDTH) / 2.0] {
            #[allow(clippy::cast_possible_truncation)]
            let x = (px(m.t) + half) as i32 - 6;
            let y = 34 + i32::try_from(banner).unwrap_or(0) + 16 * i32::try_from(*row).unwrap_or(0);
            top.draw(&Text::new(
                format!("{}", i + 1),
                (x, y),
                ("sans-serif", 12).into_font().color(&rgb(m.kind.color())),
            ))
            .map_err(err)?;
        }
    }
    let areas = body.split_evenly((tracks.len().max(1), 1));
    let blue = RGBColor(0, 114, 178);
    let band = RGBColor(230, 80, 80).mix(0.12);
    for (track, area) in tracks.iter().zip(&areas) {
        let (left, right) = area.split_horizontally(WIDTH / 2);
        let charts: Vec<(&DrawingArea<_, _>, String, bool)> = match track.velocity_name() {
            Some(v) => vec![
                (&left, track.value_name(), false),
                (&right, v.to_owned(), true),
            ],
            None => vec![(&left, track.value_name(), false)],
        };
        if track.velocity_name().is_none() {
            right
                .draw(&Text::new(
                    format!(
                        "{}: the controller reports no position; its value is what it was last told",
                        track.motor
                    ),
                    (10, i32::try_from(PANEL / 2).unwrap_or(100)),
                    ("sans-serif", 13).into_font().color(&RGBColor(90, 90, 90)),
                ))
                .map_err(err)?;
        }
        for (chart_area, name, is_velocity) in charts {
            let pick = |s: &(f64, f64, f64)| if is_velocity { s.2 } else { track.value(s) };
            let limits = if is_velocity {
                (track.max_velocity.map(|v| -v), track.max_velocity)
            } else {
                track.position_limits
            };
            let values = track
                .samples
                .iter()
                .map(pick)
                .chain(if is_velocity {
                    Vec::new()
                } else {
                    track.targets.iter().filter_map(|t| t.1).collect()
                })
                .chain([limits.0, limits.1].into_iter().flatten());
            let (lo, hi) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
                (lo.min(v), hi.max(v))
            });
            let (lo, hi) = if lo.is_finite() {
                (lo, hi)
            } else {
                (-1.0, 1.0)
            };
            let pad = ((hi - lo) * 0.08).max(0.05);
            let (ylo, yhi) = (lo - pad, hi + pad);
            let mut chart = ChartBuilder::on(chart_area)
                .margin(12)
                .caption(
                    printable(&format!("{}: {name}", track.motor)),
                    ("sans-serif", 15),
                )
                .x_label_area_size(30)
                .y_label_area_size(58)
                .build_cartesian_2d(0.0..end, ylo..yhi)
                .map_err(err)?;
            chart
                .configure_mesh()
                .x_desc("time (s)")
                .y_desc(name.as_str())
                .label_style(("sans-serif", 11))
                .draw()
                .map_err(err)?;
            // Beyond the limits: a band.
            if let Some(h) = limits.1 {
                chart
                    .draw_series(std::iter::once(Rectangle::new(
                        [(0.0, h), (end, yhi)],
                        band.filled(),
                    )))
                    .map_err(err)?;
            }
            if let Some(l) = limits.0 {
                chart
                    .draw_series(std::iter::once(Rectangle::new(
                        [(0.0, ylo), (end, l)],
                        band.filled(),
                    )))
                    .map_err(err)?;
            }
            // The records lost: a grey band over their span.
            if let Some((a, b)) = lost {
                chart
                    .draw_series(std::iter::once(Rectangle::new(
                        [(a, ylo), (b, yhi)],
                        gap.filled(),
                    )))
                    .map_err(err)?;
            }
            for m in &marks {
                chart
                    .draw_series(DashedLineSeries::new(
                        [(m.t, ylo), (m.t, yhi)],
                        3,
                        3,
                        rgb(m.kind.color()).stroke_width(1),
                    ))
                    .map_err(err)?;
            }
            if !is_velocity {
                // The target: a dashed step line while there is one.
                for (k, (from, target)) in track.targets.iter().enumerate() {
                    let Some(target) = target else { continue };
                    let until = track.targets.get(k + 1).map_or(end, |n| n.0);
                    chart
                        .draw_series(DashedLineSeries::new(
                            [(*from, *target), (until, *target)],
                            6,
                            4,
                            RGBColor(0, 0, 0).stroke_width(1),
                        ))
                        .map_err(err)?;
                }
            }
            chart
                .draw_series(LineSeries::new(
                    thinned(
                        track.samples.iter().map(|s| (s.0, pick(s))),
                        track.samples.len(),
                        end,
                        columns,
                    ),
                    blue.stroke_width(2),
                ))
                .map_err(err)?;
        }
    }
    // The key: what each line and each number is.
    let legend = [
        ("measured (feedback)", blue, false),
        ("target", RGBColor(0, 0, 0), true),
    ];
    for (i, (label, color, dashed)) in legend.iter().enumerate() {
        let x = 12 + 220 * i32::try_from(i).unwrap_or(0);
        if *dashed {
            // As on the charts: 6 on, 4 off.
            for from in [x, x + 10, x + 20] {
                key.draw(&PathElement::new(
                    vec![(from, 14), (from + 6, 14)],
                    color.stroke_width(1),
                ))
                .map_err(err)?;
            }
        } else {
            key.draw(&PathElement::new(
                vec![(x, 14), (x + 28, 14)],
                color.stroke_width(2),
            ))
            .map_err(err)?;
        }
        key.draw(&Text::new(
            (*label).to_owned(),
            (x + 34, 7),
            ("sans-serif", 13),
        ))
        .map_err(err)?;
    }
    key.draw(&Rectangle::new([(452, 8), (480, 20)], band.filled()))
        .map_err(err)?;
    key.draw(&Text::new(
        "beyond the limits in the bus map".to_owned(),
        (486, 7),
        ("sans-serif", 13),
    ))
    .map_err(err)?;
    if lost.is_some() {
        key.draw(&Rectangle::new([(720, 8), (748, 20)], gap.filled()))
            .map_err(err)?;
        key.draw(&Text::new(
            "records lost: the recording is incomplete there".to_owned(),
            (754, 7),
            ("sans-serif", 13),
        ))
        .map_err(err)?;
    }
    for (i, m) in marks.iter().enumerate() {
        let col = i32::try_from(i % 2).unwrap_or(0);
        let row = i32::try_from(i / 2).unwrap_or(0);
        key.draw(&Text::new(
            printable(&cut(
                &format!("{}  {:.2} s  {}", i + 1, m.t, m.label),
                KEY_CHARS,
            )),
            (
                12 + col * 590,
                34 + row * i32::try_from(KEY_LINE).unwrap_or(18),
            ),
            ("sans-serif", 13).into_font().color(&rgb(m.kind.color())),
        ))
        .map_err(err)?;
    }
    let first = u32::try_from(marks.len()).unwrap_or(0).div_ceil(2);
    for (i, line) in not_drawn.iter().enumerate() {
        let row = first + u32::try_from(i).unwrap_or(0);
        key.draw(&Text::new(
            line.clone(),
            (12, 34 + i32::try_from(row * KEY_LINE).unwrap_or(0)),
            ("sans-serif", 13).into_font().color(&RGBColor(90, 90, 90)),
        ))
        .map_err(err)?;
    }
    root.present().map_err(err)?;
    Ok(Drawn {
        panels: tracks.len(),
        marks: marks.len(),
    })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;
    use serde_json::json;

    const MAP: &str = r#"
[motors.elbow]
dialect = "irpc"
node = 0x12
limits = { min_position = 0, max_position = 150, max_velocity = 120 }

[motors.wrist]
dialect = "irpc"
node = 0x13
unit = "rad"
limits = { min_position = -1, max_position = 1 }

[motors.turntable]
dialect = "orion"
key = "TRM"
"#;

    fn feedback(motor: &str, p: f64, v: f64) -> Value {
        json!({"feedback": {"motor_id": motor, "timestamp": 0, "position": p, "velocity": v}, "motor_id": motor, "online": true})
    }

    fn session() -> Session {
        let mut s = Session::default();
        for i in 0..20 {
            let t = f64::from(i) * 0.1;
            s.outputs.push((t, None, feedback("elbow", t * 10.0, 10.0)));
            s.outputs.push((t, None, feedback("wrist", 0.0, 0.0)));
            s.outputs.push((
                t,
                None,
                feedback("turntable", 0.0, if i < 5 { 150.0 } else { 0.0 }),
            ));
        }
        s.outputs.push((
            0.2,
            Some(1),
            json!({"ok": true, "line": 1, "motor_id": "elbow"}),
        ));
        s.outputs.push((0.3, Some(1), json!({"ok": false, "line": 2, "motor_id": "elbow", "error": {"kind": "refused", "rule": "outside_limit"}})));
        s.outputs.push((
            0.6,
            None,
            json!({"event": "deadman", "motor_id": "turntable", "timeout_ms": 200}),
        ));
        s.outputs.push((
            1.0,
            None,
            json!({"event": "emergency_stop", "cause": "input", "cancelled": []}),
        ));
        s.outputs.push((1.5, Some(1), json!({"arrived": false, "line": 1, "motor_id": "elbow", "motors": [{"motor_id": "elbow", "arrived": false, "target": 30.0}]})));
        s.outputs.push((
            1.8,
            None,
            json!({"event": "released", "reactivated": ["elbow"]}),
        ));
        s
    }

    /// Taken a line at a time, a session is what it was taken whole: a
    /// deadman names its motor whatever else its line holds, and every
    /// completion of a line draws its target from the line's acceptance.
    #[test]
    fn a_digest_keeps_what_the_whole_session_said() {
        let map = BusMap::from_toml(MAP).unwrap();
        let mut d = Digest::default();
        d.output(
            0.1,
            None,
            &json!({"event": "deadman", "motor_id": "wrist", "feedback": null}),
        );
        d.output(0.2, Some(0), &json!({"ok": true, "line": 1}));
        for (t, target) in [(0.3, 30.0), (0.6, 60.0)] {
            d.output(
                t,
                Some(0),
                &json!({"arrived": true, "line": 1, "motors": [{"motor_id": "elbow", "target": target}]}),
            );
        }
        let t = tracks(&mut d, &map, &[]);
        let names: Vec<&str> = t.iter().map(|t| t.motor.as_str()).collect();
        assert_eq!(names, ["elbow", "wrist"]);
        assert_eq!(t[0].targets, vec![(0.2, Some(30.0)), (0.2, Some(60.0))]);
        assert_eq!(d.end(), 0.6);
    }

    /// A motor that moved, had a target or was stopped by its deadman has
    /// a panel (one that never moved has none); an Orion speed motor is
    /// drawn as its speed in the controller's units within ±400; a target
    /// starts when its line was accepted and ends at the stop; the marks
    /// are the refusal with its rule, the deadman, the stop, the release.
    #[test]
    fn a_session_becomes_panels_and_marks() {
        let map = BusMap::from_toml(MAP).unwrap();
        let s = session();
        let t = tracks(&mut s.digest(), &map, &[]);
        let names: Vec<&str> = t.iter().map(|t| t.motor.as_str()).collect();
        assert_eq!(names, ["elbow", "turntable"]);
        assert_eq!(t[0].shown, Shown::Angle(AngleUnit::Degrees));
        assert_eq!(t[0].targets, vec![(0.2, Some(30.0)), (1.0, None)]);
        assert_eq!(t[0].position_limits, (Some(0.0), Some(150.0)));
        assert_eq!(t[0].max_velocity, Some(120.0));
        assert_eq!(t[1].shown, Shown::OrionSpeed);
        assert_eq!(t[1].position_limits, (Some(-400.0), Some(400.0)));
        assert_eq!(
            t[1].value(&t[1].samples[0]),
            150.0,
            "its speed, not a flat 0"
        );
        assert_eq!(t[1].value_name(), "speed (controller units, ±400)");
        assert_eq!(t[1].velocity_name(), None);
        // Asked for: the wrist too, in radians.
        let t = tracks(&mut s.digest(), &map, &["wrist".to_owned()]);
        assert_eq!(t.len(), 1);
        assert_eq!(t[0].value_name(), "position (rad)");
        assert_eq!(t[0].velocity_name(), Some("velocity (rad/s)"));
        let m = marks(&mut s.digest());
        let labels: Vec<(&str, MarkKind)> = m.iter().map(|m| (m.label.as_str(), m.kind)).collect();
        assert_eq!(
            labels,
            [
                ("line 2 elbow refused: outside_limit", MarkKind::Refused),
                (
                    "deadman: turntable stopped, no command within its timeout",
                    MarkKind::Deadman
                ),
                ("emergency stop (input)", MarkKind::Stop),
                ("released", MarkKind::Release),
            ]
        );
    }

    /// Labels close together go to rows of their own; in each row, every
    /// label clears the one before it.
    #[test]
    fn mark_labels_never_overlap() {
        let xs = [10.0, 12.0, 14.0, 40.0, 41.0, 90.0, 91.0, 92.0, 93.0];
        let rows = label_rows(xs.iter().copied());
        assert_eq!(rows, [0, 1, 2, 0, 1, 0, 1, 2, 3].map(Some));
        for r in 0..4 {
            let in_row: Vec<f64> = xs
                .iter()
                .zip(&rows)
                .filter(|(_, row)| **row == Some(r))
                .map(|(x, _)| *x)
                .collect();
            assert!(in_row.windows(2).all(|w| w[1] - w[0] >= 22.0), "{in_row:?}");
        }
    }

    /// A number of five digits takes more room than one of two (found by
    /// a hostile test: with 12,000 marks, 10202 and 11002 were drawn over
    /// each other): marks 22 pixels apart share a row up to 99, not past.
    #[test]
    fn long_mark_numbers_take_their_room() {
        assert_eq!(label_width(9), 22.0);
        assert_eq!(label_width(99), 22.0);
        assert_eq!(label_width(100), 29.0);
        assert_eq!(label_width(10_202), 43.0);
        // Marks 1..=12000, each 22 px after the one before: every label in
        // a row clears the one before it by its own width.
        let xs: Vec<f64> = (0..12_000).map(|i| f64::from(i) * 22.0).collect();
        let rows = label_rows(xs.iter().copied());
        let mut ends: Vec<f64> = vec![f64::NEG_INFINITY; MAX_LABEL_ROWS];
        for (i, (x, row)) in xs.iter().zip(&rows).enumerate() {
            let Some(r) = row else { continue };
            assert!(*x >= ends[*r], "mark {} at {x} overlaps", i + 1);
            ends[*r] = x + label_width(i + 1);
        }
        assert_eq!(rows[98], Some(0));
        // Past 99 the numbers no longer fit one row.
        assert!(rows[100..].contains(&Some(1)));
    }

    /// A key line is cut to its column, its end marked.
    #[test]
    fn a_long_key_line_is_cut_to_its_column() {
        assert_eq!(cut("short", KEY_CHARS), "short");
        let long = format!("1  0.35 s  refused unknown_motor {}", "a".repeat(400));
        let got = cut(&long, KEY_CHARS);
        assert_eq!(got.chars().count(), KEY_CHARS);
        assert!(got.ends_with("a…"), "{got}");
    }

    /// 300 marks at one moment: six rows of numbers, the rest in the key
    /// only (the header does not grow without end).
    #[test]
    fn too_many_marks_at_once_keep_to_six_rows() {
        let rows = label_rows(std::iter::repeat_n(100.0, 300));
        assert_eq!(rows.iter().flatten().count(), MAX_LABEL_ROWS);
        assert_eq!(rows[..6], [0, 1, 2, 3, 4, 5].map(Some));
        assert!(rows[6..].iter().all(Option::is_none));
    }

    /// Control characters (in a refused line's motor id, say) are not
    /// written into the SVG (XML forbids them); values beyond any motor's
    /// reach or not numbers are drawn at the edge or left out, and the
    /// plot ends.
    #[test]
    fn hostile_text_and_values_make_a_well_formed_svg() {
        assert_eq!(printable("a\u{1}\u{1b}[31m"), "a\u{FFFD}\u{FFFD}[31m");
        let map = BusMap::from_toml(MAP).unwrap();
        let mut s = session();
        s.outputs
            .push((0.5, None, feedback("elbow", 1.7e308, -1.7e308)));
        s.outputs.push((0.6, Some(1), json!({"ok": false, "line": 9, "motor_id": "a\u{1}\u{1b}[31m", "error": {"rule": "unknown_motor"}})));
        let path = std::env::temp_dir().join(format!(
            "motorwire-chart-hostile-{}.svg",
            std::process::id()
        ));
        draw(s.digest(), &map, &[], "a\u{0}session", &path).unwrap();
        let svg = std::fs::read_to_string(&path).unwrap();
        assert!(
            !svg.chars().any(|c| c.is_control() && c != '\n'),
            "a control character in the SVG"
        );
        assert!(svg.contains("line 9 a\u{FFFD}\u{FFFD}[31m refused: unknown_motor"));
        let _ = std::fs::remove_file(&path);
    }

    /// A flood of refused lines with long motor ids (a hostile client's):
    /// the digest keeps the first 100 refusals, each label cut to what the
    /// key shows, and counts the rest; the stops among them are all kept
    /// and drawn, and the key says how many refusals are not.
    #[test]
    fn a_flood_of_refusals_is_counted_not_kept_and_the_stops_stay() {
        let map = BusMap::from_toml(MAP).unwrap();
        let mut d = Digest::default();
        let long = "m".repeat(10_000);
        for i in 0..5_000_u64 {
            #[allow(clippy::cast_precision_loss)]
            let t = i as f64 * 1e-3;
            d.output(t, Some(1), &json!({"ok": false, "line": i, "motor_id": long, "error": {"rule": "unknown_motor"}}));
            if i % 1_000 == 500 {
                d.output(
                    t,
                    None,
                    &json!({"event": "emergency_stop", "cause": "input", "cancelled": []}),
                );
            }
        }
        assert_eq!(d.marks.len(), MAX_MARKS_OF_A_KIND + 5);
        assert!(d.marks.iter().all(|m| m.label.chars().count() <= KEY_CHARS));
        assert_eq!(d.not_kept[MarkKind::Refused.index()], 4_900);
        assert_eq!(d.not_kept[MarkKind::Stop.index()], 0);
        let path =
            std::env::temp_dir().join(format!("motorwire-chart-flood-{}.svg", std::process::id()));
        let drawn = draw(d, &map, &[], "a flood", &path).unwrap();
        assert_eq!(drawn.marks, MAX_MARKS_OF_A_KIND + 5);
        let svg = std::fs::read_to_string(&path).unwrap();
        assert!(svg.contains("4900 more refused lines not drawn (the first 100 of each kind are)"));
        assert_eq!(svg.matches("emergency stop (input)").count(), 5);
        let _ = std::fs::remove_file(&path);
    }

    /// What no chart draws is not kept: samples, targets and deadman
    /// stops of motors not in the map; acceptances beyond the last
    /// [`MAX_ACCEPTED`]. A stop is kept once, not once for every motor with
    /// a target: each target ends at the first stop after it.
    #[test]
    fn what_no_chart_draws_is_not_kept() {
        let map = BusMap::from_toml(MAP).unwrap();
        let mut d = Digest::of_motors(map.motors().map(|m| m.name.as_str()));
        for i in 0..1_000_u32 {
            let t = f64::from(i) * 1e-3;
            let stranger = format!("stranger-{i}-{}", "x".repeat(1_000));
            d.output(t, None, &feedback(&stranger, 1.0, 1.0));
            d.output(t, None, &json!({"event": "deadman", "motor_id": stranger}));
            d.output(t, Some(1), &json!({"arrived": true, "line": 1, "motors": [{"motor_id": stranger, "target": 3.0}]}));
        }
        assert!(d.samples.is_empty() && d.targets.is_empty() && d.deadman.is_empty());
        for line in 0..(MAX_ACCEPTED as u64 + 10) {
            d.output(1.0, Some(1), &json!({"ok": true, "line": line}));
        }
        assert_eq!(d.accepted.len(), MAX_ACCEPTED);
        assert_eq!(d.accepted_order.len(), MAX_ACCEPTED);
        assert!(!d.accepted.contains_key(&(Some(1), 9)));
        assert!(d.accepted.contains_key(&(Some(1), 10)));
        // Targets at 2 and 5 s; stops at 1, 3, 4 and 6 s: the first ends at
        // the stop at 3, the second at the stop at 6.
        for (t, line) in [(2.0, 100), (5.0, 101)] {
            d.output(t, Some(1), &json!({"ok": true, "line": line}));
            d.output(t + 0.5, Some(1), &json!({"arrived": true, "line": line, "motors": [{"motor_id": "elbow", "target": line}]}));
        }
        for t in [6.0, 1.0, 4.0, 3.0] {
            d.output(
                t,
                None,
                &json!({"event": "emergency_stop", "cause": "input", "cancelled": []}),
            );
        }
        let tracks = tracks(&mut d, &map, &[]);
        let elbow = tracks.iter().find(|t| t.motor == "elbow").unwrap();
        assert_eq!(
            elbow.targets,
            [
                (2.0, Some(100.0)),
                (3.0, None),
                (5.0, Some(101.0)),
                (6.0, None)
            ]
        );
    }

    /// Samples out of time order are drawn in time order, and a long line
    /// of them is thinned all the same; a label's characters that XML
    /// forbids are replaced.
    #[test]
    fn samples_out_of_order_are_drawn_in_order_and_thinned() {
        let map = BusMap::from_toml(MAP).unwrap();
        let mut d = Digest::of_motors(map.motors().map(|m| m.name.as_str()));
        // Every other sample stamped a second late.
        for i in 0..100_000_u32 {
            let t = f64::from(i) * 1e-3 + if i % 2 == 0 { 1.0 } else { 0.0 };
            d.output(t, None, &feedback("elbow", f64::from(i % 150), 1.0));
        }
        d.output(0.5, Some(1), &json!({"ok": false, "line": 1, "motor_id": "a\u{ffff}b\u{fffe}", "error": {"rule": "invalid"}}));
        let tracks = tracks(&mut d, &map, &[]);
        let elbow = tracks.iter().find(|t| t.motor == "elbow").unwrap();
        assert!(elbow.samples.windows(2).all(|w| w[0].0 <= w[1].0));
        let n = elbow.samples.len();
        let drawn = thinned(elbow.samples.iter().map(|s| (s.0, s.1)), n, 101.0, 518);
        assert!(drawn.len() <= POINTS_A_COLUMN * 519, "{}", drawn.len());
        assert_eq!(printable("a\u{ffff}b\u{fffe}"), "a\u{FFFD}b\u{FFFD}");
    }

    /// A line with more points than its chart has pixel columns (four a
    /// column) keeps, in each column, its first, lowest, highest and last
    /// points in time order; a shorter one is drawn whole.
    #[test]
    fn a_long_line_keeps_each_columns_first_lowest_highest_and_last() {
        let few: Vec<(f64, f64)> = (0..8).map(|i| (f64::from(i), f64::from(i % 3))).collect();
        assert_eq!(thinned(few.iter().copied(), few.len(), 8.0, 2), few);
        // Nine points in each of two columns over 0..2 (t 0 to 0.8, then
        // 1 to 1.8); the second column's values 100 higher.
        let values = [5.0, 1.0, 9.0, 3.0, 0.5, 7.0, 2.0, 8.0, 4.0];
        let many: Vec<(f64, f64)> = (0..18_u32)
            .map(|i| {
                let (col, k) = (f64::from(i / 9), i % 9);
                (col + f64::from(k) / 10.0, values[k as usize] + 100.0 * col)
            })
            .collect();
        assert_eq!(
            thinned(many.iter().copied(), many.len(), 2.0, 2),
            [
                (0.0, 5.0),
                (0.2, 9.0),
                (0.4, 0.5),
                (0.8, 4.0),
                (1.0, 105.0),
                (1.2, 109.0),
                (1.4, 100.5),
                (1.8, 104.0),
            ]
        );
    }

    /// The SVG has a panel per motor with its units, the limit band and
    /// the target in its key, and every mark's line in the key.
    #[test]
    fn the_svg_names_units_marks_and_key() {
        let map = BusMap::from_toml(MAP).unwrap();
        let path = std::env::temp_dir().join(format!("motorwire-chart-{}.svg", std::process::id()));
        let drawn = draw(session().digest(), &map, &[], "a session", &path).unwrap();
        assert_eq!(
            drawn,
            Drawn {
                panels: 2,
                marks: 4
            }
        );
        let svg = std::fs::read_to_string(&path).unwrap();
        for needle in [
            "elbow: position (°)",
            "elbow: velocity (°/s)",
            "turntable: speed (controller units, ±400)",
            "time (s)",
            "measured (feedback)",
            "beyond the limits in the bus map",
            "0.30 s  line 2 elbow refused: outside_limit",
            "1.00 s  emergency stop (input)",
            "1.80 s  released",
        ] {
            assert!(svg.contains(needle), "{needle} not in the SVG");
        }
        let _ = std::fs::remove_file(&path);
    }

    /// A session that is not all there says so above its panels, and the
    /// span of the records it lost is shaded on every chart (the time axis
    /// reaching it, past the last record kept) and named in the key; a
    /// whole session has neither.
    #[test]
    fn an_incomplete_session_names_its_gap_on_the_chart() {
        let map = BusMap::from_toml(
            "[motors.elbow]\ndialect = \"irpc\"\nnode = 0x12\nlimits = { min_position = 0, max_position = 150, max_velocity = 120 }\n",
        )
        .unwrap();
        let path = |name: &str| {
            std::env::temp_dir().join(format!("motorwire-chart-{name}-{}.svg", std::process::id()))
        };
        let digest = || {
            let mut d = Digest::of_motors(["elbow"]);
            for i in 0..20 {
                let t = f64::from(i) * 0.1;
                d.output(t, None, &feedback("elbow", t * 10.0, 10.0));
            }
            d
        };
        let notice = "incomplete recording: 812 records lost from 1.90 s to 3.00 s (shaded)";
        let mut d = digest();
        d.incomplete(notice.to_owned(), Some((1.9, 3.0)));
        assert!((d.end() - 3.0).abs() < 1e-9, "the axis reaches the gap");
        draw(d, &map, &[], "a session", &path("gap")).unwrap();
        let svg = std::fs::read_to_string(path("gap")).unwrap();
        assert!(svg.contains(notice), "the notice");
        assert!(
            svg.contains("records lost: the recording is incomplete there"),
            "the key"
        );
        // The band on both charts (position, velocity) and in the key.
        let bands = svg.matches(r##"fill="#6E6E6E""##).count();
        assert_eq!(bands, 3, "{svg}");
        // Lost, with no time known: said, nothing shaded.
        let mut d = digest();
        d.incomplete(
            "incomplete recording: it did not end cleanly".to_owned(),
            None,
        );
        draw(d, &map, &[], "a session", &path("unended")).unwrap();
        let svg = std::fs::read_to_string(path("unended")).unwrap();
        assert!(svg.contains("incomplete recording: it did not end cleanly"));
        assert!(!svg.contains(r##"fill="#6E6E6E""##));
        draw(digest(), &map, &[], "a session", &path("whole")).unwrap();
        let svg = std::fs::read_to_string(path("whole")).unwrap();
        assert!(!svg.contains("incomplete") && !svg.contains(r##"fill="#6E6E6E""##));
        for name in ["gap", "unended", "whole"] {
            let _ = std::fs::remove_file(path(name));
        }
    }
}
