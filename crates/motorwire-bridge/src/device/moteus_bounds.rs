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
//! widen a controller past the bounds it was configured with. Each answer
//! (`OK`, a value, `ERR ...`) is read by polling the stream; a controller
//! that refuses, or does not answer within [`ANSWER_WITHIN`], is reported.

use std::collections::VecDeque;
use std::time::Duration;

use motorwire_moteus::diagnostic;

/// The diagnostic channel of the controller's console.
const CHANNEL: u8 = 1;
/// The most text a poll asks for (the library's default).
const READ: u8 = 48;
/// How long the bridge waits for an answer to a line before it reports the
/// controller's bounds as not set.
pub(crate) const ANSWER_WITHIN: Duration = Duration::from_secs(2);
/// The most text of an answer not yet a line that is kept.
const LINE_MAX: usize = 256;

const MIN: &str = "servopos.position_min";
const MAX: &str = "servopos.position_max";

/// A line written, awaiting its answer.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Asked {
    /// `conf get` of the lower (false) or upper (true) bound.
    Get(bool),
    /// `conf set` of a bound to a value (revolutions; NaN none); `last`
    /// for the second of a pair.
    Set { upper: bool, value: f64, last: bool },
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

fn same(a: Pair, b: Pair) -> bool {
    let eq = |x: f64, y: f64| (x.is_nan() && y.is_nan()) || x.to_bits() == y.to_bits();
    eq(a.0, b.0) && eq(a.1, b.1)
}

/// One controller's bounds over its diagnostic stream.
#[derive(Debug)]
pub(crate) struct OwnBounds {
    /// Its own, as read at start (`None` until both are read).
    original: Option<Pair>,
    got_min: Option<f64>,
    /// The limits in force (revolutions; NaN none).
    wanted: Pair,
    /// The pair last written (`None`: none yet).
    written: Option<Pair>,
    asked: VecDeque<Asked>,
    to_write: VecDeque<u8>,
    /// An answer's text, not yet a whole line.
    line: Vec<u8>,
    /// Since when the first line of `asked` has waited.
    waiting_since: Option<Duration>,
    news: Vec<BoundsNews>,
}

impl OwnBounds {
    /// Bounds not yet read: the first polls ask for them.
    pub(crate) fn new() -> Self {
        let mut b = Self {
            original: None,
            got_min: None,
            wanted: (f64::NAN, f64::NAN),
            written: None,
            asked: VecDeque::new(),
            to_write: VecDeque::new(),
            line: Vec::new(),
            waiting_since: None,
            news: Vec::new(),
        };
        b.ask(&diagnostic::conf_get(MIN), Asked::Get(false));
        b.ask(&diagnostic::conf_get(MAX), Asked::Get(true));
        b
    }

    /// Bounds read and set, nothing asked (for tests of the driver's other
    /// frames).
    #[cfg(test)]
    pub(crate) fn settled() -> Self {
        let mut b = Self::new();
        b.asked.clear();
        b.to_write.clear();
        b.original = Some((f64::NAN, f64::NAN));
        b
    }

    fn ask(&mut self, line: &str, asked: Asked) {
        self.to_write.extend(line.bytes());
        self.asked.push_back(asked);
    }

    /// The limits in force are now `min` to `max` (revolutions; NaN none).
    pub(crate) fn want(&mut self, min: f64, max: f64) {
        self.wanted = (min, max);
        if self.original.is_none() && self.asked.is_empty() {
            // Its own were never read (the controller did not answer):
            // asked again.
            self.got_min = None;
            self.ask(&diagnostic::conf_get(MIN), Asked::Get(false));
            self.ask(&diagnostic::conf_get(MAX), Asked::Get(true));
        }
        self.write_if_changed();
    }

    /// The pair the controller should hold: the tighter of its own and the
    /// limits in force; `None` until its own are read.
    fn target(&self) -> Option<Pair> {
        let (lo, hi) = self.original?;
        Some((
            tighter_min(lo, self.wanted.0),
            tighter_max(hi, self.wanted.1),
        ))
    }

    fn write_if_changed(&mut self) {
        let Some(t) = self.target() else { return };
        if self.written.is_some_and(|w| same(w, t)) {
            return;
        }
        if t.0 > t.1 {
            self.news.push(BoundsNews::Failed(format!(
                "the limits in force ({} to {} rev) lie outside the controller's own bounds \
                 ({} to {} rev): its bounds are left as they are",
                self.wanted.0,
                self.wanted.1,
                self.original.map_or(f64::NAN, |o| o.0),
                self.original.map_or(f64::NAN, |o| o.1),
            )));
            return;
        }
        let before = self.written.unwrap_or_else(|| self.current());
        self.written = Some(t);
        // The upper bound first when the new lower one lies above the old
        // upper one (else the lower first): the controller never holds a
        // minimum above its maximum between the two lines.
        let upper_first = !before.1.is_nan() && !t.0.is_nan() && t.0 > before.1;
        let order = if upper_first {
            [true, false]
        } else {
            [false, true]
        };
        for (k, upper) in order.into_iter().enumerate() {
            let (name, value) = if upper { (MAX, t.1) } else { (MIN, t.0) };
            self.ask(
                &diagnostic::conf_set(name, value),
                Asked::Set {
                    upper,
                    value,
                    last: k == 1,
                },
            );
        }
    }

    /// What the controller holds as far as its answers said, or its own.
    fn current(&self) -> Pair {
        self.original.unwrap_or((f64::NAN, f64::NAN))
    }

    /// The frames to send at a poll at `now` for controller `id` on `bus`:
    /// the next piece of text, and a poll for the answer while one is
    /// awaited.
    pub(crate) fn frames(
        &mut self,
        now: Duration,
        id: u8,
        bus: u16,
    ) -> Vec<motorwire_moteus::Frame> {
        let mut out = Vec::new();
        if !self.to_write.is_empty() {
            let n = self.to_write.len().min(diagnostic::MAX_WRITE);
            let text: Vec<u8> = self.to_write.drain(..n).collect();
            if let Ok(f) = diagnostic::write(id, bus, CHANNEL, &text) {
                out.push(f);
            }
        }
        if !self.asked.is_empty() {
            let since = *self.waiting_since.get_or_insert(now);
            if now.saturating_sub(since) > ANSWER_WITHIN {
                self.give_up(format!(
                    "the controller did not answer `{}` within {} s",
                    self.describe_first(),
                    ANSWER_WITHIN.as_secs()
                ));
            } else if let Ok(f) = diagnostic::read(id, bus, CHANNEL, READ) {
                out.push(f);
            }
        }
        out
    }

    fn describe_first(&self) -> String {
        match self.asked.front() {
            Some(Asked::Get(upper)) => format!("conf get {}", if *upper { MAX } else { MIN }),
            Some(Asked::Set { upper, value, .. }) => {
                diagnostic::conf_set(if *upper { MAX } else { MIN }, *value)
                    .trim_end()
                    .to_owned()
            }
            None => String::new(),
        }
    }

    /// Nothing more is awaited: what was asked is forgotten, and the next
    /// change of the limits in force writes both bounds again.
    fn give_up(&mut self, why: String) {
        self.asked.clear();
        self.to_write.clear();
        self.line.clear();
        self.waiting_since = None;
        self.written = None;
        self.news.push(BoundsNews::Failed(why));
    }

    /// An answer to a poll, at `now`: its text read line by line.
    pub(crate) fn answer(&mut self, now: Duration, answer: &diagnostic::Answer) {
        if answer.channel != u32::from(CHANNEL) {
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
        let Some(&asked) = self.asked.front() else {
            // Text nobody asked for (another tool's, or telemetry): not ours.
            return;
        };
        if line.starts_with("ERR") {
            let what = self.describe_first();
            return self.give_up(format!("the controller refused `{what}`: {line}"));
        }
        match asked {
            Asked::Get(upper) => {
                let value = match line.to_ascii_lowercase().as_str() {
                    "nan" => f64::NAN,
                    other => match other.parse::<f64>() {
                        Ok(v) if v.is_finite() => v,
                        _ => return, // not the value: another line of the stream
                    },
                };
                if upper {
                    self.original = Some((self.got_min.unwrap_or(f64::NAN), value));
                } else {
                    self.got_min = Some(value);
                }
            }
            Asked::Set { upper, value, last } => {
                if line != "OK" {
                    return;
                }
                if last
                    && let Some(w) = self.written
                    && (if upper { w.1 } else { w.0 }).to_bits() == value.to_bits()
                    && self.asked.len() == 1
                {
                    self.news.push(BoundsNews::Set { min: w.0, max: w.1 });
                }
            }
        }
        self.asked.pop_front();
        self.waiting_since = if self.asked.is_empty() {
            None
        } else {
            Some(now)
        };
        if matches!(asked, Asked::Get(true)) {
            self.write_if_changed();
        }
    }

    /// What became of the bounds since last asked.
    pub(crate) fn take_news(&mut self) -> Vec<BoundsNews> {
        std::mem::take(&mut self.news)
    }

    /// Whether lines are awaited or text is still to be written.
    #[cfg(test)]
    pub(crate) fn busy(&self) -> bool {
        !self.asked.is_empty() || !self.to_write.is_empty()
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
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
                diagnostic::CLIENT_DATA => text.push_str(&String::from_utf8_lossy(&f.data[3..])),
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

    /// Everything written until nothing is left to write.
    fn written(b: &mut OwnBounds, now: Duration) -> String {
        let mut all = String::new();
        while !b.to_write.is_empty() {
            all.push_str(&step(b, now).0);
        }
        all
    }

    #[test]
    fn its_own_bounds_are_read_then_the_tighter_set_and_told() {
        let mut b = OwnBounds::new();
        b.want(0.0, 60.0 / 360.0);
        assert_eq!(
            written(&mut b, ms(0)),
            "conf get servopos.position_min\nconf get servopos.position_max\n"
        );
        // Its own: -0.25 to nan (no upper bound); answered over two polls,
        // the second line cut between them.
        say(&mut b, ms(10), "-0.25\r\nna");
        say(&mut b, ms(20), "n\r\n");
        assert_eq!(
            written(&mut b, ms(20)),
            "conf set servopos.position_min 0\nconf set servopos.position_max 0.16666666666666666\n"
        );
        assert!(b.take_news().is_empty());
        say(&mut b, ms(30), "OK\r\nOK\r\n");
        assert_eq!(
            b.take_news(),
            [BoundsNews::Set {
                min: 0.0,
                max: 60.0 / 360.0
            }]
        );
        assert!(!b.busy());
        // Widened past its own lower bound: held at its own (-0.25).
        b.want(-1.0, f64::NAN);
        assert_eq!(
            written(&mut b, ms(40)),
            "conf set servopos.position_min -0.25\nconf set servopos.position_max nan\n"
        );
        say(&mut b, ms(50), "OK\r\nOK\r\n");
        let news = b.take_news();
        assert!(
            matches!(news[..], [BoundsNews::Set { min, max }] if min == -0.25 && max.is_nan()),
            "{news:?}"
        );
        // The same again: nothing written.
        b.want(-1.0, f64::NAN);
        assert_eq!(written(&mut b, ms(60)), "");
    }

    #[test]
    fn a_window_moved_above_the_old_one_writes_the_upper_bound_first() {
        let mut b = OwnBounds::new();
        b.want(0.0, 0.1);
        written(&mut b, ms(0));
        say(&mut b, ms(1), "nan\r\nnan\r\n");
        written(&mut b, ms(1));
        say(&mut b, ms(2), "OK\r\nOK\r\n");
        b.take_news();
        b.want(0.2, 0.3);
        assert_eq!(
            written(&mut b, ms(3)),
            "conf set servopos.position_max 0.3\nconf set servopos.position_min 0.2\n"
        );
        say(&mut b, ms(4), "OK\r\nOK\r\n");
        assert_eq!(b.take_news(), [BoundsNews::Set { min: 0.2, max: 0.3 }]);
    }

    #[test]
    fn a_refusal_or_silence_is_told_and_the_next_change_tries_again() {
        let mut b = OwnBounds::new();
        b.want(0.0, 0.1);
        written(&mut b, ms(0));
        say(&mut b, ms(1), "ERR unknown configuration\r\n");
        assert_eq!(
            b.take_news(),
            [BoundsNews::Failed(
                "the controller refused `conf get servopos.position_min`: ERR unknown configuration"
                    .to_owned()
            )]
        );
        assert!(!b.busy());
        // The next change asks for its own again; this time nobody answers.
        b.want(0.0, 0.2);
        assert_eq!(
            written(&mut b, ms(100)),
            "conf get servopos.position_min\nconf get servopos.position_max\n"
        );
        assert_eq!(step(&mut b, ms(100)), (String::new(), true));
        assert_eq!(step(&mut b, ms(2100)), (String::new(), true));
        assert_eq!(step(&mut b, ms(2101)), (String::new(), false));
        assert_eq!(
            b.take_news(),
            [BoundsNews::Failed(
                "the controller did not answer `conf get servopos.position_min` within 2 s"
                    .to_owned()
            )]
        );
    }

    #[test]
    fn limits_wholly_outside_its_own_bounds_are_not_written() {
        let mut b = OwnBounds::new();
        b.want(0.5, 0.6);
        written(&mut b, ms(0));
        say(&mut b, ms(1), "-0.25\r\n0.25\r\n");
        assert_eq!(written(&mut b, ms(1)), "");
        assert_eq!(
            b.take_news(),
            [BoundsNews::Failed(
                "the limits in force (0.5 to 0.6 rev) lie outside the controller's own bounds \
                 (-0.25 to 0.25 rev): its bounds are left as they are"
                    .to_owned()
            )]
        );
    }
}
