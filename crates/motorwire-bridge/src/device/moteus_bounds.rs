//! A moteus controller's own position bounds (`servopos.position_min` and
//! `servopos.position_max`), kept at the limits in force over its
//! diagnostic stream, so that the controller itself holds a motor the
//! bridge can no longer reach (a dead bridge, a stream cut while a
//! velocity is held) within them.
//!
//! At start the controller's own bounds are read (`conf get`); from then on
//! it is given the tighter of them and the limits in force (`conf set`, its
//! running configuration only: nothing is written to its flash), at start
//! and whenever a SafetyLimits line changes them. Limits in force never
//! widen a controller past the bounds it was configured with. A bound never
//! excludes where the motor stands (moteus refuses to enter position mode
//! outside its bounds: fault 39): while the motor is outside the limits in
//! force it is widened to take the motor in, with a margin, and tightened
//! once the motor is inside.
//!
//! The stream is spoken one batch at a time (the reads, or a pair of
//! writes), each line in a frame of its own (never a line cut between two
//! writes), each answer (`OK`, a value, `ERR ...`) read by polling. Before
//! the first batch, and after one that failed, the stream is drained (polled
//! until the controller has nothing more to say), so no answer is ever
//! credited to a line it does not answer. Only the latest target is ever
//! written: a change while a batch is under way is written after it. What
//! was written is read back every [`VERIFY_EVERY`] (a controller that
//! rebooted has lost it) and written again where it differs; a batch
//! refused, or not answered within [`ANSWER_WITHIN`], is reported and tried
//! again after [`VERIFY_EVERY`].

use std::collections::VecDeque;
use std::time::Duration;

use motorwire_moteus::diagnostic;

/// The diagnostic channel of the controller's console.
const CHANNEL: u8 = 1;
/// The most text a poll asks for (the library's default).
const READ: u8 = 48;
/// How long the bridge waits for an answer to a line (or for the stream
/// to drain) before it reports the controller's bounds as not known set.
pub(crate) const ANSWER_WITHIN: Duration = Duration::from_secs(2);
/// How often what was written is read back, and how long after a failure
/// the bridge tries again.
pub(crate) const VERIFY_EVERY: Duration = Duration::from_secs(5);
/// The most text of an answer not yet a line that is kept.
const LINE_MAX: usize = 256;
/// Bounds are written to 1e-9 revolution, rounded inward; beyond 1e9
/// revolutions a bound is none (NaN).
const DECIMALS: f64 = 1e9;
const FARTHEST: f64 = 1e9;
/// Where the motor stands outside the limits in force, the bound on that
/// side takes it in with this margin (revolutions), on a grid of
/// [`POSITION_STEP`] so that a motor moving inward does not rewrite it at
/// every poll.
const POSITION_MARGIN: f64 = 0.005;
const POSITION_STEP: f64 = 0.01;
/// How far (revolutions) a bound read back may lie from the one written
/// (the controller stores a 32-bit float and prints it its own way).
const READ_BACK_TOLERANCE: f64 = 1e-5;

const MIN: &str = "servopos.position_min";
const MAX: &str = "servopos.position_max";

/// A line written, awaiting its answer.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Asked {
    /// `conf get` of a bound (the lower first, then the upper).
    Get,
    /// `conf set` of a bound.
    Set,
}

/// What a batch is for.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Purpose {
    /// The controller's own bounds, read at start.
    Own,
    /// The pair written, read back.
    Verify,
    /// The pair being written.
    Write(Pair),
}

/// Lines in flight.
#[derive(Debug)]
struct Batch {
    purpose: Purpose,
    /// Whole lines still to write, one a frame.
    to_write: VecDeque<String>,
    asked: VecDeque<Asked>,
    /// The values read so far (a Get's).
    read: Vec<f64>,
    /// The last progress (sent, or a line answered).
    since: Duration,
}

/// What became of the bounds, for the engine to report.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum BoundsNews {
    /// The controller took both bounds (revolutions; NaN: none).
    Set { min: f64, max: f64 },
    /// It refused a line, or did not answer: the bounds it holds are not
    /// known to be the limits in force.
    Failed(String),
}

/// A lower bound and an upper (revolutions), NaN for none.
type Pair = (f64, f64);

/// The tighter of two lower bounds (NaN: none).
fn tighter_min(a: f64, b: f64) -> f64 {
    if a.is_nan() {
        b
    } else if b.is_nan() {
        a
    } else {
        a.max(b)
    }
}

/// The tighter of two upper bounds (NaN: none).
fn tighter_max(a: f64, b: f64) -> f64 {
    if a.is_nan() {
        b
    } else if b.is_nan() {
        a
    } else {
        a.min(b)
    }
}

fn close(a: f64, b: f64, by: f64) -> bool {
    (a.is_nan() && b.is_nan()) || (a - b).abs() <= by
}

fn same(a: Pair, b: Pair) -> bool {
    close(a.0, b.0, 0.0) && close(a.1, b.1, 0.0)
}

/// `v` (revolutions) as the bound written: to 1e-9 revolution, rounded
/// inward (a lower bound up, an upper down), none beyond 1e9 revolutions.
fn rounded(v: f64, upper: bool) -> f64 {
    if !v.is_finite() || v.abs() >= FARTHEST {
        return f64::NAN;
    }
    let r = if upper {
        (v * DECIMALS).floor() / DECIMALS
    } else {
        (v * DECIMALS).ceil() / DECIMALS
    };
    if r == 0.0 { 0.0 } else { r }
}

/// A bound as the console line writes it: NaN as `nan`, else at most nine
/// decimals, trailing zeros dropped (never an exponent).
fn text(v: f64) -> String {
    if v.is_nan() {
        return "nan".to_owned();
    }
    let t = format!("{v:.9}");
    let t = t.trim_end_matches('0').trim_end_matches('.');
    if t == "-0" {
        "0".to_owned()
    } else {
        t.to_owned()
    }
}

/// One controller's bounds over its diagnostic stream.
#[derive(Debug)]
pub(crate) struct OwnBounds {
    /// Its own, as read at start (`None` until read).
    original: Option<Pair>,
    /// The limits in force (revolutions; NaN none).
    wanted: Pair,
    /// Where the motor stands (revolutions), as its replies say.
    position: Option<f64>,
    /// The pair last written and confirmed (`None`: none, or not known).
    written: Option<Pair>,
    /// The pair it holds as last read or confirmed (`None`: not known).
    held: Option<Pair>,
    batch: Option<Batch>,
    /// Polling until the controller has nothing more to say (since the
    /// first such poll, once sent).
    draining: bool,
    drain_since: Option<Duration>,
    /// No batch is begun before then (after a failure).
    retry_at: Duration,
    /// When what was written is next read back.
    verify_at: Duration,
    /// An answer's text, not yet a whole line.
    line: Vec<u8>,
    news: Vec<BoundsNews>,
}

impl OwnBounds {
    /// Bounds not yet read: the first polls drain the stream, then ask.
    pub(crate) fn new() -> Self {
        Self {
            original: None,
            wanted: (f64::NAN, f64::NAN),
            position: None,
            written: None,
            held: None,
            batch: None,
            draining: true,
            drain_since: None,
            retry_at: Duration::ZERO,
            verify_at: Duration::ZERO,
            line: Vec::new(),
            news: Vec::new(),
        }
    }

    /// Bounds read and set, nothing asked (for tests of the driver's other
    /// frames).
    #[cfg(test)]
    pub(crate) fn settled() -> Self {
        Self {
            original: Some((f64::NAN, f64::NAN)),
            written: Some((f64::NAN, f64::NAN)),
            held: Some((f64::NAN, f64::NAN)),
            draining: false,
            verify_at: Duration::MAX,
            ..Self::new()
        }
    }

    /// The limits in force are now `min` to `max` (revolutions; NaN none):
    /// written once the batch under way (if any) is done.
    pub(crate) fn want(&mut self, min: f64, max: f64) {
        self.wanted = (min, max);
    }

    /// The motor stands at `position` (revolutions), as a reply says.
    pub(crate) fn at(&mut self, position: f64) {
        if position.is_finite() {
            self.position = Some(position);
        }
    }

    /// The pair the controller should hold: the tighter of its own and the
    /// limits in force, taking in where the motor stands; `None` until its
    /// own are read.
    fn target(&self) -> Option<Pair> {
        let (lo, hi) = self.original?;
        let mut min = rounded(tighter_min(lo, self.wanted.0), false);
        let mut max = rounded(tighter_max(hi, self.wanted.1), true);
        if let Some(p) = self.position {
            // Never past its own bounds, though: outside those, the
            // controller's own configuration holds it.
            if !min.is_nan() && p < min {
                let at = ((p - POSITION_MARGIN) / POSITION_STEP).floor() * POSITION_STEP;
                min = rounded(tighter_min(lo, at), false);
            }
            if !max.is_nan() && p > max {
                let at = ((p + POSITION_MARGIN) / POSITION_STEP).ceil() * POSITION_STEP;
                max = rounded(tighter_max(hi, at), true);
            }
        }
        Some((min, max))
    }

    fn begin(&mut self, now: Duration, purpose: Purpose) {
        let (to_write, asked): (VecDeque<String>, VecDeque<Asked>) = match purpose {
            Purpose::Own | Purpose::Verify => (
                [diagnostic::conf_get(MIN), diagnostic::conf_get(MAX)].into(),
                [Asked::Get, Asked::Get].into(),
            ),
            Purpose::Write((min, max)) => {
                // The upper bound first when the new lower one lies above
                // what it holds as its upper (else the lower first): the
                // controller never holds a minimum above its maximum.
                let held = self.held.unwrap_or((f64::NAN, f64::NAN));
                let set_min = format!("conf set {MIN} {}\n", text(min));
                let set_max = format!("conf set {MAX} {}\n", text(max));
                let upper_first = !held.1.is_nan() && !min.is_nan() && min > held.1;
                let lines = if upper_first {
                    [set_max, set_min]
                } else {
                    [set_min, set_max]
                };
                (lines.into(), [Asked::Set, Asked::Set].into())
            }
        };
        self.batch = Some(Batch {
            purpose,
            to_write,
            asked,
            read: Vec::new(),
            since: now,
        });
    }

    /// The frames to send at a poll at `now` for controller `id` on `bus`:
    /// the next line, and a poll for the answer while one is awaited.
    pub(crate) fn frames(
        &mut self,
        now: Duration,
        id: u8,
        bus: u16,
    ) -> Vec<motorwire_moteus::Frame> {
        let poll = |out: &mut Vec<motorwire_moteus::Frame>| {
            if let Ok(f) = diagnostic::read(id, bus, CHANNEL, READ) {
                out.push(f);
            }
        };
        let mut out = Vec::new();
        if self.draining {
            let since = *self.drain_since.get_or_insert(now);
            if now.saturating_sub(since) > ANSWER_WITHIN {
                self.fail(
                    now,
                    format!(
                        "the controller's diagnostic stream did not answer within {} s",
                        ANSWER_WITHIN.as_secs()
                    ),
                );
            } else {
                poll(&mut out);
            }
            return out;
        }
        if self.batch.is_none() && now >= self.retry_at {
            match (self.original, self.target()) {
                (None, _) => self.begin(now, Purpose::Own),
                // Not known what it holds (a write failed): read first, so
                // the pair is written in an order it takes.
                _ if self.held.is_none() => self.begin(now, Purpose::Verify),
                (Some(_), Some(t)) if !self.written.is_some_and(|w| same(w, t)) => {
                    self.begin(now, Purpose::Write(t));
                }
                _ if now >= self.verify_at => self.begin(now, Purpose::Verify),
                _ => {}
            }
        }
        let Some(b) = self.batch.as_mut() else {
            return out;
        };
        if now.saturating_sub(b.since) > ANSWER_WITHIN {
            let what = b.to_write.front().cloned().unwrap_or_default();
            let purpose = b.purpose;
            self.fail(
                now,
                format!(
                    "the controller did not answer {} within {} s{}",
                    match purpose {
                        Purpose::Own => "the reading of its own bounds",
                        Purpose::Verify => "the reading back of its bounds",
                        Purpose::Write(_) => "the setting of its bounds",
                    },
                    ANSWER_WITHIN.as_secs(),
                    if what.is_empty() {
                        String::new()
                    } else {
                        format!(" (`{}` not yet sent)", what.trim_end())
                    }
                ),
            );
            return out;
        }
        if let Some(line) = b.to_write.pop_front() {
            if let Ok(f) = diagnostic::write(id, bus, CHANNEL, line.as_bytes()) {
                out.push(f);
            }
            b.since = now;
        }
        poll(&mut out);
        out
    }

    /// The batch under way failed (`why`): told, the stream drained before
    /// anything more is asked, nothing begun again before [`VERIFY_EVERY`].
    fn fail(&mut self, now: Duration, why: String) {
        if matches!(
            self.batch.as_ref().map(|b| b.purpose),
            Some(Purpose::Write(_))
        ) {
            // What it holds is not known.
            self.written = None;
            self.held = None;
        }
        self.batch = None;
        self.line.clear();
        self.draining = true;
        self.drain_since = None;
        self.retry_at = now.saturating_add(VERIFY_EVERY);
        self.news.push(BoundsNews::Failed(why));
    }

    /// An answer to a poll, at `now`: its text read line by line.
    pub(crate) fn answer(&mut self, now: Duration, answer: &diagnostic::Answer) {
        if answer.channel != u32::from(CHANNEL) {
            return;
        }
        if self.draining {
            // Whatever was left from before is not ours; an empty answer
            // says there is nothing more.
            if answer.data.is_empty() {
                self.draining = false;
                self.drain_since = None;
                self.line.clear();
            }
            return;
        }
        for &b in &answer.data {
            if b == b'\n' || b == b'\r' {
                let line = String::from_utf8_lossy(&std::mem::take(&mut self.line))
                    .trim()
                    .to_owned();
                if !line.is_empty() {
                    self.line_answered(now, &line);
                }
            } else if self.line.len() < LINE_MAX {
                self.line.push(b);
            }
        }
    }

    fn line_answered(&mut self, now: Duration, line: &str) {
        let Some(b) = self.batch.as_mut() else {
            // Nothing asked: not ours (another tool's, or telemetry).
            return;
        };
        let Some(&asked) = b.asked.front() else {
            return;
        };
        if line.starts_with("ERR") {
            return self.fail(now, format!("the controller refused its bounds: {line}"));
        }
        match asked {
            Asked::Get => {
                let value = match line.to_ascii_lowercase().as_str() {
                    "nan" => f64::NAN,
                    other => match other.parse::<f64>() {
                        Ok(v) if v.is_finite() => v,
                        // Not the value: another line of the stream.
                        _ => return,
                    },
                };
                b.read.push(value);
            }
            Asked::Set => {
                if line != "OK" {
                    return;
                }
            }
        }
        b.asked.pop_front();
        b.since = now;
        if !b.asked.is_empty() || !b.to_write.is_empty() {
            return;
        }
        let Some(b) = self.batch.take() else { return };
        let got = (
            b.read.first().copied().unwrap_or(f64::NAN),
            b.read.get(1).copied().unwrap_or(f64::NAN),
        );
        match b.purpose {
            Purpose::Own => {
                self.original = Some(got);
                self.held = Some(got);
            }
            Purpose::Verify => {
                let held = self.written.is_some_and(|w| {
                    close(w.0, got.0, READ_BACK_TOLERANCE) && close(w.1, got.1, READ_BACK_TOLERANCE)
                });
                self.held = Some(got);
                if held {
                    self.verify_at = now.saturating_add(VERIFY_EVERY);
                } else {
                    // It no longer holds them (it rebooted, or another tool
                    // set them): written again at once.
                    self.written = None;
                }
            }
            Purpose::Write(pair) => {
                self.written = Some(pair);
                self.held = Some(pair);
                self.verify_at = now.saturating_add(VERIFY_EVERY);
                self.news.push(BoundsNews::Set {
                    min: pair.0,
                    max: pair.1,
                });
            }
        }
    }

    /// What became of the bounds since last asked.
    pub(crate) fn take_news(&mut self) -> Vec<BoundsNews> {
        std::mem::take(&mut self.news)
    }

    /// Whether a batch is under way, or the stream is being drained.
    #[cfg(test)]
    pub(crate) fn busy(&self) -> bool {
        self.batch.is_some() || self.draining
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing, clippy::panic)]
    use super::*;

    fn ms(n: u64) -> Duration {
        Duration::from_millis(n)
    }

    /// The text the frames at `now` write, and whether they poll.
    fn step(b: &mut OwnBounds, now: Duration) -> (String, bool) {
        let mut text = String::new();
        let mut polls = false;
        for f in b.frames(now, 2, 0) {
            match f.data[0] {
                diagnostic::CLIENT_DATA => {
                    assert!(f.data.len() <= 64);
                    let line = String::from_utf8_lossy(&f.data[3..]).into_owned();
                    // One whole line a frame.
                    assert_eq!(line.matches('\n').count(), 1, "{line:?}");
                    assert!(line.ends_with('\n'), "{line:?}");
                    text.push_str(&line);
                }
                diagnostic::CLIENT_POLL => polls = true,
                other => panic!("frame {other:#x}"),
            }
        }
        (text, polls)
    }

    fn say(b: &mut OwnBounds, now: Duration, text: &str) {
        b.answer(
            now,
            &diagnostic::Answer {
                source: 2,
                destination: 0,
                can_prefix: 0,
                channel: 1,
                data: text.as_bytes().to_vec(),
            },
        );
    }

    /// Drained: the first poll answered with nothing.
    fn drained(b: &mut OwnBounds, now: Duration) {
        assert_eq!(step(b, now), (String::new(), true));
        say(b, now, "");
    }

    /// The lines the next polls write (until one writes nothing).
    fn lines(b: &mut OwnBounds, now: Duration) -> String {
        let mut all = String::new();
        loop {
            let (text, _) = step(b, now);
            if text.is_empty() {
                return all;
            }
            all.push_str(&text);
        }
    }

    /// A controller whose own bounds are `own`, limits `min..max`, set.
    fn set_up(own: &str, min: f64, max: f64) -> OwnBounds {
        let mut b = OwnBounds::new();
        b.want(min, max);
        drained(&mut b, ms(0));
        assert_eq!(
            lines(&mut b, ms(1)),
            "conf get servopos.position_min\nconf get servopos.position_max\n"
        );
        say(&mut b, ms(2), own);
        b
    }

    #[test]
    fn its_own_bounds_are_read_then_the_tighter_set_and_told() {
        let mut b = OwnBounds::new();
        b.want(0.0, 60.0 / 360.0);
        // Stale text from before (another session's answers) is drained,
        // never taken for an answer.
        assert_eq!(step(&mut b, ms(0)), (String::new(), true));
        say(&mut b, ms(0), "OK\r\nOK\r\n");
        assert_eq!(step(&mut b, ms(1)), (String::new(), true));
        say(&mut b, ms(1), "");
        assert_eq!(
            lines(&mut b, ms(2)),
            "conf get servopos.position_min\nconf get servopos.position_max\n"
        );
        // Its own: -0.25 to nan (no upper bound); answered over two polls,
        // the second line cut between them.
        say(&mut b, ms(10), "-0.25\r\nna");
        say(&mut b, ms(20), "n\r\n");
        assert_eq!(
            lines(&mut b, ms(20)),
            "conf set servopos.position_min 0\nconf set servopos.position_max 0.166666666\n"
        );
        assert!(b.take_news().is_empty());
        say(&mut b, ms(30), "OK\r\nOK\r\n");
        assert_eq!(
            b.take_news(),
            [BoundsNews::Set {
                min: 0.0,
                max: 0.166666666
            }]
        );
        assert!(!b.busy());
        // Widened past its own lower bound: held at its own (-0.25).
        b.want(-1.0, f64::NAN);
        assert_eq!(
            lines(&mut b, ms(40)),
            "conf set servopos.position_min -0.25\nconf set servopos.position_max nan\n"
        );
        say(&mut b, ms(50), "OK\r\nOK\r\n");
        let news = b.take_news();
        assert!(
            matches!(news[..], [BoundsNews::Set { min, max }] if min == -0.25 && max.is_nan()),
            "{news:?}"
        );
        // The same again: nothing written, until the read-back is due.
        b.want(-1.0, f64::NAN);
        assert_eq!(step(&mut b, ms(60)), (String::new(), false));
    }

    #[test]
    fn only_the_latest_limits_are_written_and_a_window_above_writes_its_upper_bound_first() {
        let mut b = set_up("nan\r\nnan\r\n", 0.0, 0.1);
        assert_eq!(
            lines(&mut b, ms(3)),
            "conf set servopos.position_min 0\nconf set servopos.position_max 0.1\n"
        );
        // Three changes while the pair is under way: only the last is
        // written after it.
        b.want(0.5, 0.6);
        b.want(0.3, 0.4);
        b.want(0.2, 0.3);
        say(&mut b, ms(4), "OK\r\nOK\r\n");
        assert_eq!(
            lines(&mut b, ms(5)),
            "conf set servopos.position_max 0.3\nconf set servopos.position_min 0.2\n"
        );
        say(&mut b, ms(6), "OK\r\nOK\r\n");
        let news = b.take_news();
        assert_eq!(news.len(), 2, "{news:?}");
        assert_eq!(news[1], BoundsNews::Set { min: 0.2, max: 0.3 });
    }

    #[test]
    fn a_refusal_is_told_drained_and_tried_again_after_a_read() {
        let mut b = set_up("-0.5\r\n0.5\r\n", 0.0, 0.1);
        assert_eq!(step(&mut b, ms(3)).0, "conf set servopos.position_min 0\n");
        // Refused at once: the second line is never sent.
        say(&mut b, ms(4), "ERR bad value\r\n");
        assert_eq!(
            b.take_news(),
            [BoundsNews::Failed(
                "the controller refused its bounds: ERR bad value".to_owned()
            )]
        );
        // Drained (its late text is not ours), then nothing before 5 s.
        assert_eq!(step(&mut b, ms(5)), (String::new(), true));
        say(&mut b, ms(5), "OK\r\n");
        assert_eq!(step(&mut b, ms(6)), (String::new(), true));
        say(&mut b, ms(6), "");
        assert_eq!(step(&mut b, ms(7)), (String::new(), false));
        // Then what it holds is read first, and the pair written again.
        assert_eq!(
            lines(&mut b, ms(5004)),
            "conf get servopos.position_min\nconf get servopos.position_max\n"
        );
        say(&mut b, ms(5005), "0\r\n0.5\r\n");
        assert_eq!(
            lines(&mut b, ms(5006)),
            "conf set servopos.position_min 0\nconf set servopos.position_max 0.1\n"
        );
        say(&mut b, ms(5007), "OK\r\nOK\r\n");
        assert_eq!(b.take_news(), [BoundsNews::Set { min: 0.0, max: 0.1 }]);
    }

    #[test]
    fn a_silent_controller_is_told_and_asked_again_later() {
        let mut b = OwnBounds::new();
        b.want(0.0, 0.2);
        assert_eq!(step(&mut b, ms(0)), (String::new(), true));
        assert_eq!(step(&mut b, ms(2000)), (String::new(), true));
        assert_eq!(step(&mut b, ms(2001)), (String::new(), false));
        assert_eq!(
            b.take_news(),
            [BoundsNews::Failed(
                "the controller's diagnostic stream did not answer within 2 s".to_owned()
            )]
        );
        // It comes up late: drained, read, set.
        assert_eq!(step(&mut b, ms(7002)), (String::new(), true));
        say(&mut b, ms(7002), "");
        assert_eq!(
            lines(&mut b, ms(7003)),
            "conf get servopos.position_min\nconf get servopos.position_max\n"
        );
        say(&mut b, ms(7004), "nan\r\nnan\r\n");
        assert_eq!(
            lines(&mut b, ms(7005)),
            "conf set servopos.position_min 0\nconf set servopos.position_max 0.2\n"
        );
    }

    #[test]
    fn a_controller_that_lost_its_bounds_is_given_them_again() {
        let mut b = set_up("nan\r\nnan\r\n", 0.0, 0.1);
        lines(&mut b, ms(3));
        say(&mut b, ms(4), "OK\r\nOK\r\n");
        b.take_news();
        // Read back 5 s on: as written (its float's rounding taken).
        assert_eq!(step(&mut b, ms(5003)).0, "");
        assert_eq!(
            lines(&mut b, ms(5004)),
            "conf get servopos.position_min\nconf get servopos.position_max\n"
        );
        say(&mut b, ms(5005), "0\r\n0.099999994\r\n");
        assert_eq!(lines(&mut b, ms(5006)), "");
        // It rebooted: its own again. Written again at once.
        lines(&mut b, ms(10006));
        say(&mut b, ms(10007), "nan\r\nnan\r\n");
        assert_eq!(
            lines(&mut b, ms(10008)),
            "conf set servopos.position_min 0\nconf set servopos.position_max 0.1\n"
        );
    }

    #[test]
    fn a_bound_never_shuts_out_where_the_motor_stands() {
        // The motor stands at 0.3 rev when the limits narrow to 0..0.1:
        // the upper bound takes it in (0.31), and is tightened once the
        // motor is back inside.
        let mut b = set_up("-1\r\n1\r\n", 0.0, 0.1);
        b.at(0.3);
        assert_eq!(
            lines(&mut b, ms(3)),
            "conf set servopos.position_min 0\nconf set servopos.position_max 0.31\n"
        );
        say(&mut b, ms(4), "OK\r\nOK\r\n");
        b.at(0.298);
        assert_eq!(lines(&mut b, ms(5)), "");
        b.at(0.05);
        assert_eq!(
            lines(&mut b, ms(6)),
            "conf set servopos.position_min 0\nconf set servopos.position_max 0.1\n"
        );
        // Never past its own bound, though.
        let mut b = set_up("-1\r\n0.2\r\n", 0.0, 0.1);
        b.at(0.5);
        assert_eq!(
            lines(&mut b, ms(3)),
            "conf set servopos.position_min 0\nconf set servopos.position_max 0.2\n"
        );
    }

    #[test]
    fn bounds_are_written_inward_to_a_billionth_and_never_with_an_exponent() {
        assert_eq!(text(rounded(1.0 / 6.0, true)), "0.166666666");
        assert_eq!(text(rounded(-1.0 / 6.0, false)), "-0.166666666");
        assert_eq!(text(rounded(1.0 / 6.0, false)), "0.166666667");
        assert_eq!(text(rounded(1e-12, true)), "0");
        assert_eq!(text(rounded(-1e-12, false)), "0");
        assert_eq!(text(rounded(2e9, true)), "nan");
        assert_eq!(
            text(rounded(12_345.678_901_234_5, false)),
            "12345.678901235"
        );
        assert_eq!(text(rounded(12_345.678_901_234_5, true)), "12345.678901234");
        let longest = format!(
            "conf set {MIN} {}\n",
            text(rounded(-999_999_999.999, false))
        );
        assert!(longest.len() <= diagnostic::MAX_WRITE, "{longest}");
    }
}
