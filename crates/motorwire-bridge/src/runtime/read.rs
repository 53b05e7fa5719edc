//! Reading input: lines read, bounded and numbered on the reader's thread (a stop found even in a line too long to read), secrets checked, and handed to the runner in order.

use super::*;

/// A line read from an input, numbered and timed (its arrival) when it
/// was read, not yet handed to the runner ([`InputSender::stamp`],
/// [`InputSender::hand`]): a reader may read ahead of what it hands over,
/// and each line keeps its place and its arrival.
#[derive(Debug)]
pub struct Stamped {
    pub(super) origin: Origin,
    pub(super) number: u64,
    pub(super) at: Instant,
    /// A stop: it overtakes the lines handed before it.
    pub(super) urgent: bool,
    pub(super) what: Stamp,
}

/// What a [`Stamped`] line is.
#[derive(Debug)]
pub(super) enum Stamp {
    Line(String),
    /// Not taken (`reason`); its first bytes and length, if read.
    Refused {
        reason: String,
        bytes: Option<(Vec<u8>, u64)>,
    },
}

impl Stamped {
    /// Its number among its origin's lines (from 1), as its result says.
    #[must_use]
    pub const fn number(&self) -> u64 {
        self.number
    }

    /// Whether it is taken as a stop (it asks for one, or it could not be
    /// read and names `emergency_stop`): it never waits behind the lines
    /// read before it.
    #[must_use]
    pub const fn is_stop(&self) -> bool {
        self.urgent
    }

    /// The bytes it holds against its origin's budgets.
    pub(super) fn bytes(&self) -> usize {
        match &self.what {
            Stamp::Line(text) => text.len(),
            Stamp::Refused { .. } => 0,
        }
    }
}

/// How many of an unreadable line's first bytes are kept for the
/// recording ([`ReadLine::TooLong`], [`ReadLine::NotUtf8`]).
pub const UNREADABLE_HEAD: usize = 4096;

/// A line read by [`read_line`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ReadLine {
    /// A whole line (without its newline).
    Line(String),
    /// A line over the limit read with, skipped to its end.
    TooLong {
        /// The skipped bytes contain `emergency_stop`.
        names_stop: bool,
        /// Its first bytes (at most [`UNREADABLE_HEAD`]).
        head: Vec<u8>,
        /// Its length in bytes (without its newline).
        length: u64,
    },
    /// A line that is not UTF-8.
    NotUtf8 {
        /// Its bytes contain `emergency_stop`.
        names_stop: bool,
        /// Its first bytes (at most [`UNREADABLE_HEAD`]).
        head: Vec<u8>,
        /// Its length in bytes (without its newline).
        length: u64,
    },
    /// Bytes at the end of input with no newline after them.
    Partial(String),
    /// End of input.
    End,
}

/// Reads one line of at most `max_line` bytes, never holding more (an
/// [`InputSender`]'s [`max_line`](InputSender::max_line), or
/// [`DEFAULT_MAX_LINE`]).
///
/// ```
/// use motorwire_bridge::{ReadLine, read_line};
/// let mut r = std::io::Cursor::new(b"{\"emergency_stop\":true}\nxxxxxxxxxxxx\n".to_vec());
/// assert_eq!(read_line(&mut r, 32).unwrap(), ReadLine::Line(r#"{"emergency_stop":true}"#.into()));
/// assert_eq!(
///     read_line(&mut r, 8).unwrap(),
///     ReadLine::TooLong { names_stop: false, head: b"xxxxxxxxxxxx".to_vec(), length: 12 }
/// );
/// assert_eq!(read_line(&mut r, 8).unwrap(), ReadLine::End);
/// ```
///
/// # Errors
/// The reader's errors.
pub fn read_line(reader: &mut impl BufRead, max_line: usize) -> io::Result<ReadLine> {
    let mut line = Reading::default();
    loop {
        if line.skipped > MAX_SKIP {
            return Err(io::Error::new(
                io::ErrorKind::InvalidData,
                format!(
                    "a line over {max_line} bytes has no end within {} MiB more; the input was given up",
                    MAX_SKIP / (1024 * 1024)
                ),
            ));
        }
        let (consumed, done) = {
            let buf = match reader.fill_buf() {
                Ok(b) => b,
                Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                Err(e) => return Err(e),
            };
            if buf.is_empty() {
                return Ok(line.ended());
            }
            match buf.iter().position(|&b| b == b'\n') {
                Some(i) => {
                    line.take(buf.get(..i).unwrap_or_default());
                    (i + 1, true)
                }
                None => {
                    line.take(buf);
                    (buf.len(), false)
                }
            }
        };
        reader.consume(consumed);
        if line.too_long {
            line.skipped += consumed as u64;
        }
        line.check_length(max_line);
        if done {
            return Ok(line.finished());
        }
    }
}

/// A line being read by [`read_line`].
#[derive(Default)]
struct Reading {
    /// Its bytes so far (while it is not too long).
    bytes: Vec<u8>,
    too_long: bool,
    /// While a too-long line is skipped: whether it named a stop, and its
    /// last bytes (a name split between two reads), and the bytes skipped.
    names_stop: bool,
    tail: Vec<u8>,
    skipped: u64,
    /// A too-long line's first bytes and its length, for the recording.
    head: Vec<u8>,
    length: u64,
}

impl Reading {
    /// A segment of the line (no newline in it).
    fn take(&mut self, seg: &[u8]) {
        self.length += seg.len() as u64;
        if self.too_long {
            self.names_stop |= scan(&mut self.tail, seg);
        } else {
            self.bytes.extend_from_slice(seg);
        }
    }

    /// Past `max_line`: the line is too long, its first bytes kept.
    fn check_length(&mut self, max_line: usize) {
        if self.bytes.len() > max_line {
            self.too_long = true;
            self.names_stop |= scan(&mut self.tail, &self.bytes);
            self.bytes.truncate(UNREADABLE_HEAD);
            self.head = std::mem::take(&mut self.bytes);
        }
    }

    /// The input ended before a newline.
    fn ended(self) -> ReadLine {
        if self.too_long {
            self.into_too_long()
        } else if self.bytes.is_empty() {
            ReadLine::End
        } else {
            ReadLine::Partial(String::from_utf8_lossy(&self.bytes).into_owned())
        }
    }

    fn into_too_long(self) -> ReadLine {
        ReadLine::TooLong {
            names_stop: self.names_stop,
            head: self.head,
            length: self.length,
        }
    }

    /// The line's newline came.
    fn finished(self) -> ReadLine {
        if self.too_long {
            return self.into_too_long();
        }
        let length = self.length;
        match String::from_utf8(self.bytes) {
            Ok(mut s) => {
                if s.ends_with('\r') {
                    s.pop();
                }
                ReadLine::Line(s)
            }
            Err(e) => {
                let mut head = e.into_bytes();
                let names_stop = head.windows(14).any(|w| w == b"emergency_stop")
                    || crate::classify::names_a_stop(&String::from_utf8_lossy(&head));
                head.truncate(UNREADABLE_HEAD);
                ReadLine::NotUtf8 {
                    names_stop,
                    head,
                    length,
                }
            }
        }
    }
}

/// Whether `emergency_stop` (or any `\u` escape, which may spell it) is
/// in `tail` followed by `seg`; keeps the last bytes of the two in `tail`
/// for the next segment.
pub(super) fn scan(tail: &mut Vec<u8>, seg: &[u8]) -> bool {
    const NAME: &[u8] = b"emergency_stop";
    let keep = NAME.len() - 1;
    let head = seg.get(..keep.min(seg.len())).unwrap_or_default();
    tail.extend_from_slice(head);
    // A `\u` escape may spell the name (`emergency\u005fstop`): a line
    // too long to read that has one is taken as naming a stop too.
    let found = tail.windows(NAME.len()).any(|w| w == NAME)
        || seg.windows(NAME.len()).any(|w| w == NAME)
        || tail.windows(2).any(|w| w == b"\\u")
        || seg.windows(2).any(|w| w == b"\\u");
    if seg.len() >= keep {
        tail.clear();
        tail.extend_from_slice(seg.get(seg.len() - keep..).unwrap_or_default());
    } else if tail.len() > keep {
        tail.drain(..tail.len() - keep);
    }
    found
}

/// Feeds `reader`'s lines to `input` as `origin` until it ends. With
/// `partial_is_line` a last line without a newline is taken (a file);
/// otherwise it is dropped, and reported (a client that went away
/// mid-line). Returns how the input ended.
pub fn feed(
    input: &InputSender,
    origin: Origin,
    reader: &mut impl BufRead,
    partial_is_line: bool,
) -> io::Result<()> {
    feed_withholding(input, origin, reader, partial_is_line, None)
}

/// A secret that no line may carry past the reader (a connection's token):
/// a line that holds it anywhere is refused with its `reason` and goes no
/// further ([`feed_withholding`]).
#[derive(Debug, Clone, Copy)]
pub struct Secret<'a> {
    pub(super) text: &'a str,
    pub(super) reason: &'static str,
}

impl<'a> Secret<'a> {
    /// `text` (not empty: an empty secret is none, `None`), withheld with
    /// `reason`.
    #[must_use]
    pub fn new(text: &'a str, reason: &'static str) -> Option<Self> {
        (!text.is_empty()).then_some(Self { text, reason })
    }

    /// Whether `line` holds the secret.
    #[must_use]
    pub fn in_line(&self, line: &str) -> bool {
        line.contains(self.text)
    }

    /// Whether the first bytes kept of an unreadable line hold the secret,
    /// or end with its first 8 bytes or more (the line was cut in the
    /// middle of it).
    #[must_use]
    pub fn in_head(&self, head: &[u8]) -> bool {
        let s = self.text.as_bytes();
        let whole = head.windows(s.len()).any(|w| w == s);
        // Where a cut secret could begin: within its length of the end.
        let from = head.len().saturating_sub(s.len().saturating_sub(1));
        let cut = (from..head.len())
            .filter_map(|i| head.get(i..))
            .any(|rest| rest.len() >= 8 && s.starts_with(rest));
        whole || cut
    }
}

/// [`feed`], except that a line holding `secret` is refused with the
/// secret's reason and goes no further: the bridge never reads it, and its
/// taps (a recording, the live view) are told only the reason, never its
/// text; an unreadable line's first bytes are kept (for the recording)
/// only where they hold no part of it ([`Secret::in_head`]). A TCP
/// client's token sent again, alone or inside a line, is withheld so
/// (`motorwire bridge --input tcp:`): a secret never reaches a recording.
pub fn feed_withholding(
    input: &InputSender,
    origin: Origin,
    reader: &mut impl BufRead,
    partial_is_line: bool,
    secret: Option<Secret<'_>>,
) -> io::Result<()> {
    read_stamped(input, origin, reader, partial_is_line, secret, |read| {
        input.hand(read);
        true
    })
}

/// Reads `reader`'s lines as [`feed_withholding`] does, each stamped as it
/// is read and given to `put`, until the input ends or `put` says `false`
/// (nothing more is read).
pub(super) fn read_stamped(
    input: &InputSender,
    origin: Origin,
    reader: &mut impl BufRead,
    partial_is_line: bool,
    secret: Option<Secret<'_>>,
    mut put: impl FnMut(Stamped) -> bool,
) -> io::Result<()> {
    let take = |s: String| match secret.filter(|k| k.in_line(&s)) {
        Some(k) => Some(input.stamp_refused(origin, k.reason.to_owned(), false, None)),
        None => input.stamp(origin, s),
    };
    let head = |h: Vec<u8>| {
        if secret.is_some_and(|k| k.in_head(&h)) {
            Vec::new()
        } else {
            h
        }
    };
    loop {
        let (read, last) = match read_line(reader, input.max_line)? {
            ReadLine::Line(s) => (take(s), false),
            ReadLine::TooLong {
                names_stop,
                head: h,
                length,
            } => (
                Some(input.stamp_unreadable(origin, input.too_long(), names_stop, head(h), length)),
                false,
            ),
            ReadLine::NotUtf8 {
                names_stop,
                head: h,
                length,
            } => (
                Some(input.stamp_unreadable(
                    origin,
                    "the line is not UTF-8".to_owned(),
                    names_stop,
                    head(h),
                    length,
                )),
                false,
            ),
            ReadLine::Partial(s) if partial_is_line => (take(s), true),
            ReadLine::Partial(s) => (
                Some(input.stamp_refused(
                    origin,
                    format!(
                        "the input ended in the middle of a line ({} bytes without a newline); it was not taken",
                        s.len()
                    ),
                    false,
                    None,
                )),
                true,
            ),
            ReadLine::End => return Ok(()),
        };
        if let Some(read) = read
            && !put(read)
        {
            return Ok(());
        }
        if last {
            return Ok(());
        }
    }
}

/// Lines of one origin read ahead of what [`feed_gated`] hands over, at
/// most (and their bytes within [`MAX_QUEUED_BYTES_PER_ORIGIN`], a line
/// alone always taken): a stop read behind them is handed over at once.
pub const MAX_READ_AHEAD: usize = 1024;

/// Whether an origin's lines may go on to the runner: [`feed_gated`] asks
/// before each. The bridge's owner holds back a reader that is behind on
/// its results (its input is not read meanwhile, so it is slowed to the
/// pace it reads at), and cuts off one that stopped reading.
pub trait Gate: Sync {
    /// Before the origin's next line that is not a stop: waits while it
    /// must, and counts the line as handed over (it is owed a result).
    /// `false`: the origin is cut off; this line and those after it are
    /// not handed over.
    fn admit(&self) -> bool;

    /// A stop of the origin's is handed over now: it never waits.
    fn admit_stop(&self) {}
}

/// What the reader of [`feed_gated`] read and the feeder has not handed
/// over yet.
#[derive(Debug, Default)]
pub(super) struct Held {
    pub(super) lines: std::collections::VecDeque<Stamped>,
    pub(super) bytes: usize,
    /// Nothing more comes: the input ended.
    pub(super) ended: bool,
    /// The feeder stopped (the origin was cut off): nothing more is taken.
    pub(super) closed: bool,
    /// The reader or the feeder waits for the other.
    pub(super) reader_waits: bool,
    pub(super) feeder_waits: bool,
}

/// [`Held`], shared by the reader and the feeder.
#[derive(Debug, Default)]
pub(super) struct ReadAhead {
    pub(super) state: Mutex<Held>,
    pub(super) moved: Condvar,
}

impl ReadAhead {
    /// Waits for room, then queues `read`; `false` once the feeder stopped.
    pub(super) fn push(&self, read: Stamped) -> bool {
        let mut a = self.state.lock().unwrap_or_else(PoisonError::into_inner);
        while !a.closed
            && !a.lines.is_empty()
            && (a.lines.len() >= MAX_READ_AHEAD
                || a.bytes.saturating_add(read.bytes()) > MAX_QUEUED_BYTES_PER_ORIGIN)
        {
            a.reader_waits = true;
            a = self.moved.wait(a).unwrap_or_else(PoisonError::into_inner);
        }
        a.reader_waits = false;
        if a.closed {
            return false;
        }
        a.bytes = a.bytes.saturating_add(read.bytes());
        a.lines.push_back(read);
        if a.feeder_waits {
            self.moved.notify_all();
        }
        true
    }

    /// The next line, waiting for one; `None` once the input ended and
    /// every line was taken.
    pub(super) fn pop(&self) -> Option<Stamped> {
        let mut a = self.state.lock().unwrap_or_else(PoisonError::into_inner);
        loop {
            if let Some(read) = a.lines.pop_front() {
                a.bytes = a.bytes.saturating_sub(read.bytes());
                a.feeder_waits = false;
                if a.reader_waits {
                    self.moved.notify_all();
                }
                return Some(read);
            }
            if a.ended {
                return None;
            }
            a.feeder_waits = true;
            a = self.moved.wait(a).unwrap_or_else(PoisonError::into_inner);
        }
    }

    /// The input ended (the reader is done).
    pub(super) fn end(&self) {
        let mut a = self.state.lock().unwrap_or_else(PoisonError::into_inner);
        a.ended = true;
        self.moved.notify_all();
    }

    /// The feeder stopped: what is queued is dropped, and the reader stops.
    pub(super) fn close(&self) {
        let mut a = self.state.lock().unwrap_or_else(PoisonError::into_inner);
        a.closed = true;
        a.lines.clear();
        a.bytes = 0;
        self.moved.notify_all();
    }
}

/// [`feed_withholding`] through a [`Gate`]: each line is numbered and
/// timed (its arrival) as it is read; a stop is handed over at once, and
/// every other line in order once `gate` admits it. The input is read up
/// to [`MAX_READ_AHEAD`] lines ahead of what the gate lets through (then
/// it waits), so a stop a held-back client sends behind its lines still
/// overtakes them. A line the gate refuses, and those after it, are
/// dropped, and reading ends. Returns once every line read was handed
/// over or dropped.
///
/// # Errors
/// The reader's, once the lines read before were handed over.
pub fn feed_gated(
    input: &InputSender,
    origin: Origin,
    reader: &mut impl BufRead,
    partial_is_line: bool,
    secret: Option<Secret<'_>>,
    gate: &dyn Gate,
) -> io::Result<()> {
    let ahead = ReadAhead::default();
    thread::scope(|scope| {
        let feeder = thread::Builder::new().spawn_scoped(scope, || {
            while let Some(read) = ahead.pop() {
                if !gate.admit() {
                    ahead.close();
                    return;
                }
                input.hand(read);
            }
        });
        if feeder.is_err() {
            // No thread for the feeder: each line waits for the gate as it
            // is read (a stop then waits behind the line before it).
            return read_stamped(input, origin, reader, partial_is_line, secret, |read| {
                if read.is_stop() {
                    gate.admit_stop();
                } else if !gate.admit() {
                    return false;
                }
                input.hand(read);
                true
            });
        }
        let read = read_stamped(input, origin, reader, partial_is_line, secret, |read| {
            if read.is_stop() {
                gate.admit_stop();
                input.hand(read);
                true
            } else {
                ahead.push(read)
            }
        });
        ahead.end();
        read
    })
}
