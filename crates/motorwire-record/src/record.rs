//! The flight recorder: everything a bridge session took in and gave out,
//! in the field's formats, written beside the session without ever making
//! it wait.
//!
//! A [`Recorder`] writes, into its directory:
//! - `frames.log`: every CAN frame the bridge sent or received, as
//!   `candump -L` writes them (`(1733212345.123456) can0 012##1DEADBEEF`),
//!   which can-utils' `canplayer` and python-can's `LogReader` read
//!   unchanged; the timestamp is the wall clock;
//! - `lines.jsonl`: one JSON object per line, in the order the bridge took
//!   or gave them, each with `t_us` (when it came or went: microseconds on
//!   one monotonic clock from the start of the recording; a frame or a line
//!   is stamped when it arrived, so it may be a little earlier than the
//!   record before it) and `wall_ms` (Unix milliseconds): every input line
//!   with its client and number, and when the bridge took it (`"in"`,
//!   `taken_us`), every output line as it was
//!   given (`"out"`: results, completions, feedback, events), every frame
//!   again with its direction (`"frame"`: `"dir":"tx"|"rx"`, the id and
//!   the data in hex; a frame received also says when the bridge took it,
//!   `taken_us`), and every line to or from the Orion arm controller
//!   (`"orion"`);
//! - `session.json`: when the recording started (both clocks), how the
//!   bridge was set up, and how much was written and how much was dropped
//!   (`written`, `dropped`, `bytes`; where records were dropped, the
//!   `t_us` of the first and the last, `dropped_first_us` and
//!   `dropped_last_us`). Written at the start, the counts zero and
//!   `"complete": false`, and kept in place: rewritten when the first
//!   record is dropped, at most once a second while the counts change, and
//!   at the end, which adds `ended_wall_ms` (and `"complete": true` when
//!   nothing was dropped). The file is made at its largest at the start
//!   (padded with white space after the JSON), and each rewrite overwrites
//!   only its counts in place, within the bytes it already holds: a disk
//!   that has filled since still takes them. A recording whose counts say
//!   records were dropped, or without `ended_wall_ms` (its writer was
//!   killed or never finished), is incomplete, whatever became of the
//!   disk.
//!
//! Bounded: each of the two files is rotated (to `frames.1.log`,
//! `lines.1.jsonl`) when it reaches a quarter of the recorder's limit, so
//! the recording never holds more than the limit (`--record-max-mb`).
//! Never waiting: a record goes into a bounded queue a thread of its own
//! writes out (it looks for records every 2 ms while they come, and sleeps
//! after 20 ms without one until the next wakes it: an idle recording
//! costs one look a second); when the queue is full (a slow disk) or the disk failed (a
//! full disk), the record is dropped and counted, and the bridge goes on.
//! A stop is never behind the recorder: the [`motorwire_bridge::Runner`] hands a line
//! and the frames it sent to its taps once those frames are out.
//!
//! The records are made on the bridge's thread and freed on the writer's.
//! With glibc's malloc, that memory went back to the kernel and was
//! faulted in again on the bridge's thread, in the middle of a stop: a
//! program that records should use an allocator that keeps it, as the
//! `motorwire` binary does (its `jemalloc` feature; BENCHMARKS.md has the
//! stop's latency under both).

use std::fmt::Write as _;
use std::fs::{self, File};
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::mpsc::{self, Receiver, Sender};
use std::thread::{self, JoinHandle};
use std::time::{Duration, Instant};

use motorwire_can::Frame;
use motorwire_can::candump::LogEntry;

use motorwire_bridge::tap::{Direction, Mark, Tap, Unreadable};
use motorwire_bridge::{Origin, Output};

/// Records waiting to be written, at most: beyond, records are dropped.
pub const RECORD_QUEUE: usize = 65_536;

/// Records the writer takes before it pauses.
const BATCH: usize = 64;

/// How often the writer looks for records while they come (it sleeps
/// where a record would have to wake it only after `IDLE_POLLS` looks
/// found nothing).
const POLL: Duration = Duration::from_millis(2);

/// Polls that find nothing before the writer goes to sleep until a record
/// wakes it (20 ms without a record): an idle session costs the writer's
/// look at the end of each `IDLE_SLEEP`, and nothing else.
const IDLE_POLLS: u32 = 10;

/// The longest the writer sleeps when idle before it looks again on its
/// own (it is woken by the first record; this only bounds the cost of a
/// wake-up that never came).
const IDLE_SLEEP: Duration = Duration::from_secs(1);

/// Where the writer can be watched and steered, the test seam of its
/// thread: at each round, before each record it takes, between its last
/// look at the queue and its sleep, and how long it sleeps. A recorder's
/// own is [`Unwatched`], which does nothing (a call a round).
pub(crate) trait WriterProbe: Send + Sync + std::fmt::Debug {
    /// A round begins (a look at the queue).
    fn round(&self) {}
    /// Before it takes a record: it may be held here (a disk that does
    /// not answer).
    fn before_take(&self) {}
    /// It found the queue empty and is about to sleep.
    fn before_sleep(&self) {}
    /// How long it sleeps when idle, if nothing wakes it.
    fn idle_sleep(&self) -> Duration {
        IDLE_SLEEP
    }
}

/// The writer watched by nobody.
#[derive(Debug)]
pub(crate) struct Unwatched;

impl WriterProbe for Unwatched {}

/// How long [`Recorder::finish_within`] waits, once told to give up, for
/// the writer to drop what is left and complete `session.json`.
const ABANDON_GRACE: Duration = Duration::from_secs(2);

/// The default bound of a recording (bytes on disk): 100 MiB.
pub const DEFAULT_RECORD_MAX: u64 = 100 * 1024 * 1024;

/// One thing to write.
#[derive(Debug)]
enum Record {
    Frame {
        at: Instant,
        /// A frame received: when the bridge took it.
        taken: Option<Instant>,
        dir: Direction,
        frame: Frame,
    },
    Input {
        at: Instant,
        /// When the bridge took it (`at` is when it came).
        taken: Instant,
        origin: Origin,
        number: u64,
        text: String,
    },
    Unreadable {
        at: Instant,
        origin: Origin,
        number: u64,
        reason: String,
        stop: bool,
        bytes: Option<(Vec<u8>, u64)>,
    },
    Mark {
        at: Instant,
        mark: Mark,
    },
    /// Rendered by the writer, off the bridge's thread. Held as it is,
    /// not boxed: an `Output` keeps its large lines boxed already, so a
    /// box here would be a second allocation on the bridge's thread (and
    /// a free on the writer's) for every output.
    Output {
        at: Instant,
        output: Output,
    },
    /// An output as its line, rendered once on the bridge's thread for the
    /// runner's sink and shared with it: the output itself was let go
    /// there, so a recording holds a few hundred bytes for it, not the
    /// output's boxes (a burst of results kept whole, waiting for the
    /// writer, pushed the stop's own code and data out of the bridge
    /// core's cache: BENCHMARKS.md).
    OutputLine {
        at: Instant,
        /// The client it went to, when it was one client's.
        to: Option<Origin>,
        line: Arc<str>,
    },
    Orion {
        at: Instant,
        dir: Direction,
        line: String,
    },
}

impl Record {
    /// When it came.
    const fn at(&self) -> Instant {
        match self {
            Self::Frame { at, .. }
            | Self::Input { at, .. }
            | Self::Unreadable { at, .. }
            | Self::Mark { at, .. }
            | Self::Output { at, .. }
            | Self::OutputLine { at, .. }
            | Self::Orion { at, .. } => *at,
        }
    }
}

impl Tap for Recorder {
    fn hush(&self, on: bool) {
        self.hushed.store(on, Ordering::Relaxed);
    }
    fn input(&self, at: Instant, origin: Origin, number: u64, text: &str) {
        Recorder::input(self, at, origin, number, text);
    }
    fn input_owned(&self, at: Instant, taken: Instant, origin: Origin, number: u64, text: String) {
        self.put(Record::Input {
            at,
            taken,
            origin,
            number,
            text,
        });
    }
    fn unreadable(&self, line: &Unreadable<'_>) {
        Recorder::unreadable(self, line);
    }
    fn output(&self, at: Instant, output: &Output) {
        Recorder::output(self, at, output);
    }
    fn output_owned(&self, at: Instant, output: Output) {
        Recorder::output_owned(self, at, output);
    }
    fn output_line(&self, at: Instant, output: &Output, line: &Arc<str>) {
        self.put(Record::OutputLine {
            at,
            to: output.reader(),
            line: Arc::clone(line),
        });
    }
    fn output_line_owned(&self, at: Instant, output: Output, line: &Arc<str>) {
        Tap::output_line(self, at, &output, line);
    }
    fn frame(&self, at: Instant, dir: Direction, frame: &Frame) {
        Recorder::frame(self, at, dir, frame);
    }
    fn frame_taken(&self, at: Instant, taken: Instant, frame: &Frame) {
        self.put(Record::Frame {
            at,
            taken: Some(taken),
            dir: Direction::Rx,
            frame: *frame,
        });
    }
    fn orion(&self, at: Instant, dir: Direction, line: &str) {
        Recorder::orion(self, at, dir, line);
    }
    fn mark(&self, at: Instant, mark: Mark) {
        Recorder::mark(self, at, mark);
    }
}

/// Whether `name` can stand as the interface of a `candump -L` line that
/// can-utils' `canplayer` (at most 15 bytes, the kernel's `IFNAMSIZ` less
/// its terminator; `=` maps one name to another) and python-can's
/// `LogReader` (split on white space) read, and that a Linux interface
/// could have: 1 to 15 printable ASCII characters, none of them white
/// space, `/`, `:` or `=`.
///
/// ```
/// use motorwire_record::record::is_interface_name;
///
/// assert!(is_interface_name("can0"));
/// assert!(is_interface_name("fdcanusb"));
/// assert!(!is_interface_name("fdcanusb:/dev/ttyACM0"));
/// assert!(!is_interface_name("my port"));
/// assert!(!is_interface_name(""));
/// assert!(!is_interface_name("a_name_of_16_chr"));
/// ```
#[must_use]
pub fn is_interface_name(name: &str) -> bool {
    (1..=15).contains(&name.len())
        && name
            .bytes()
            .all(|b| b.is_ascii_graphic() && !matches!(b, b'/' | b':' | b'='))
}

/// The part of `session.json` that never changes (when the recording
/// started, how the bridge was set up), without its closing brace: the
/// counts ([`session_counts`]) follow it.
fn session_head(interface: &str, setup: Option<&serde_json::Value>, wall0: Duration) -> String {
    let mut v = serde_json::json!({
        "recorder": "motorwire",
        "version": env!("CARGO_PKG_VERSION"),
        "started_wall_ms": u64::try_from(wall0.as_millis()).unwrap_or(u64::MAX),
        "interface": interface,
        "files": ["frames.log", "lines.jsonl"],
    });
    if let (Some(setup), Some(m)) = (setup, v.as_object_mut()) {
        m.insert("setup".to_owned(), setup.clone());
    }
    let mut text = v.to_string();
    // An object with members: it ends in its closing brace.
    text.pop();
    text
}

/// What `session.json` says of the recording so far.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
struct Progress {
    written: u64,
    dropped: u64,
    bytes: u64,
    /// The `t_us` of the first and the last record dropped.
    dropped_span: Option<(u64, u64)>,
    /// When it ended cleanly (Unix milliseconds); `None` while it runs.
    ended_wall_ms: Option<u64>,
}

impl Progress {
    /// The largest counts there can be: what `session.json` makes room for.
    const LARGEST: Self = Self {
        written: u64::MAX,
        dropped: u64::MAX,
        bytes: u64::MAX,
        dropped_span: Some((u64::MAX, u64::MAX)),
        ended_wall_ms: Some(u64::MAX),
    };
}

/// The members of `session.json` that change, after its head
/// ([`session_head`]), with the object's closing brace.
fn session_counts(p: &Progress) -> String {
    let complete = p.ended_wall_ms.is_some() && p.dropped == 0;
    let mut text = format!(
        r#","complete":{complete},"written":{},"dropped":{},"bytes":{}"#,
        p.written, p.dropped, p.bytes
    );
    if let Some((first, last)) = p.dropped_span {
        let _ = write!(
            text,
            r#","dropped_first_us":{first},"dropped_last_us":{last}"#
        );
    }
    if let Some(ended) = p.ended_wall_ms {
        let _ = write!(text, r#","ended_wall_ms":{ended}"#);
    }
    text.push('}');
    text
}

/// How often `session.json`'s counts are rewritten, at most, while they
/// change (and at once when the first record is dropped).
const SESSION_EVERY: Duration = Duration::from_secs(1);

/// `session.json`, open for the whole recording: written whole at the
/// start at its largest (its counts padded with white space to the room
/// their largest values take), then only its counts, in place.
#[derive(Debug)]
struct SessionFile {
    file: File,
    /// Where the counts begin (the head's length).
    at: u64,
    /// The counts' room: their largest text's length.
    room: usize,
}

impl SessionFile {
    /// What the file takes on disk for a head of `head` bytes.
    fn size(head: usize) -> u64 {
        u64::try_from(head + session_counts(&Progress::LARGEST).len() + 1).unwrap_or(u64::MAX)
    }

    /// Makes `path` anew (as [`fresh`]) holding `head` and `progress`.
    fn create(path: &Path, head: &str, progress: &Progress) -> io::Result<Self> {
        let mut file = fresh(path)?;
        let room = session_counts(&Progress::LARGEST).len();
        let mut text = String::with_capacity(head.len() + room + 1);
        text.push_str(head);
        text.push_str(&Self::padded(progress, room));
        file.write_all(text.as_bytes())?;
        Ok(Self {
            file,
            at: u64::try_from(head.len()).unwrap_or(u64::MAX),
            room,
        })
    }

    /// The counts, padded with spaces to `room`, and the file's last
    /// newline.
    fn padded(progress: &Progress, room: usize) -> String {
        let mut text = session_counts(progress);
        let pad = room.saturating_sub(text.len());
        text.extend(std::iter::repeat_n(' ', pad));
        text.push('\n');
        text
    }

    /// Overwrites the counts in place: the same bytes of the file, never
    /// more (no block the file does not already hold is needed).
    fn rewrite(&mut self, progress: &Progress) -> io::Result<()> {
        use std::io::Seek;
        let text = Self::padded(progress, self.room);
        self.file.seek(io::SeekFrom::Start(self.at))?;
        self.file.write_all(text.as_bytes())
    }
}

/// The least a rotated file may hold.
const MIN_FILE: u64 = 4096;

/// What the bridge's side tells the writer.
#[derive(Debug)]
struct WriterFlags {
    hushed: Arc<AtomicBool>,
    abandon: Arc<AtomicBool>,
    asleep: Arc<AtomicBool>,
    probe: Arc<dyn WriterProbe>,
}

/// What a recording came to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct RecordSummary {
    /// Records written.
    pub written: u64,
    /// Records dropped (the queue full, or the disk failed).
    pub dropped: u64,
    /// Bytes written, rotated files included.
    pub bytes: u64,
    /// `session.json` holds these counts and the end (its last rewrite
    /// succeeded); `false`: it still says what it said before, without
    /// the end (the recording reads as one that did not end cleanly).
    pub session: bool,
}

/// The records a recording lost: how many, and when the first and the
/// last of them came (on the recording's clock), shared by the bridge's
/// side (a full queue) and the writer (a failed disk).
#[derive(Debug)]
struct Losses {
    /// The recording's time zero (`t_us` 0).
    t0: Instant,
    count: AtomicU64,
    /// The least `t_us` of a record lost (`u64::MAX`: none yet).
    first_us: AtomicU64,
    /// The greatest.
    last_us: AtomicU64,
}

impl Losses {
    fn new(t0: Instant) -> Self {
        Self {
            t0,
            count: AtomicU64::new(0),
            first_us: AtomicU64::new(u64::MAX),
            last_us: AtomicU64::new(0),
        }
    }

    fn us(&self, at: Instant) -> u64 {
        u64::try_from(at.saturating_duration_since(self.t0).as_micros()).unwrap_or(u64::MAX)
    }

    /// `n` records lost, that came from `from` to `to`.
    fn lose(&self, n: u64, from: Instant, to: Instant) {
        if n == 0 {
            return;
        }
        self.first_us.fetch_min(self.us(from), Ordering::Relaxed);
        self.last_us.fetch_max(self.us(to), Ordering::Relaxed);
        // After the times: whoever sees the count sees them.
        self.count.fetch_add(n, Ordering::Release);
    }

    fn count(&self) -> u64 {
        self.count.load(Ordering::Acquire)
    }

    /// The `t_us` of the first and the last record lost, once one was.
    fn span(&self) -> Option<(u64, u64)> {
        let first = self.first_us.load(Ordering::Relaxed);
        (first != u64::MAX).then(|| (first, self.last_us.load(Ordering::Relaxed).max(first)))
    }
}

/// How a recording is made.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RecordConfig {
    /// The directory (made if missing; files of an earlier recording in it
    /// are replaced).
    pub dir: PathBuf,
    /// The most bytes the recording holds on disk.
    pub max_bytes: u64,
    /// The CAN interface name written in `frames.log` (`canplayer` maps
    /// it: `canplayer -I frames.log vcan0=can0`); only a name
    /// [`is_interface_name`] takes, or [`Recorder::start`] refuses it.
    pub interface: String,
    /// How the bridge was set up, written into `session.json` as `setup`
    /// so the session can be replayed as it ran
    /// ([`crate::replay::Setup`]); `None`: not written.
    pub setup: Option<serde_json::Value>,
}

/// A recording under way; see the module's documentation.
#[derive(Debug)]
pub struct Recorder {
    /// Lock-free (a bounded `sync_channel` takes a lock the writer may
    /// hold while it is descheduled: the bridge's thread would wait for
    /// it); bounded by `queued`.
    queue: Option<Sender<Record>>,
    /// Records in the queue.
    queued: Arc<AtomicUsize>,
    /// Records dropped, and when.
    losses: Arc<Losses>,
    /// A stop is being handled: the writer waits.
    hushed: Arc<AtomicBool>,
    /// The session is over and its end may not wait longer: the writer
    /// drops (and counts) what is left instead of writing it.
    abandon: Arc<AtomicBool>,
    /// The writer found nothing to write for a while and sleeps until the
    /// next record wakes it (a record that finds it set clears it and wakes
    /// the writer; the writer clears it when it wakes on its own).
    asleep: Arc<AtomicBool>,
    writer: Option<JoinHandle<RecordSummary>>,
}

impl Recorder {
    /// Starts recording as `config` says.
    ///
    /// # Errors
    /// The directory or its files could not be made.
    pub fn start(config: RecordConfig) -> io::Result<Self> {
        Self::start_watched(config, Arc::new(Unwatched))
    }

    /// [`Recorder::start`], its writer watched by `probe`.
    pub(crate) fn start_watched(
        config: RecordConfig,
        probe: Arc<dyn WriterProbe>,
    ) -> io::Result<Self> {
        if !is_interface_name(&config.interface) {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                format!(
                    "{:?} cannot be the interface of a candump log: 1 to 15 printable ASCII characters, none of them '/', ':' or '=' (canplayer and python-can read no other)",
                    config.interface
                ),
            ));
        }
        fs::create_dir_all(&config.dir)?;
        // Stale from a recorder of an earlier version, which wrote
        // `session.json` beside and renamed it.
        match fs::remove_file(config.dir.join("session.json.part")) {
            Err(e) if e.kind() != io::ErrorKind::NotFound => return Err(e),
            _ => {}
        }
        // The two clocks read together, as the bridge's are.
        let (t0, wall0) = motorwire_bridge::clocks_together();
        let wall0 = wall0.unwrap_or_default();
        let files = Files::open(&config, t0, wall0)?;
        let (queue, records) = mpsc::channel();
        let queued = Arc::new(AtomicUsize::new(0));
        let q = Arc::clone(&queued);
        let losses = Arc::new(Losses::new(t0));
        let d = Arc::clone(&losses);
        let hushed = Arc::new(AtomicBool::new(false));
        let abandon = Arc::new(AtomicBool::new(false));
        let asleep = Arc::new(AtomicBool::new(false));
        let flags = WriterFlags {
            hushed: Arc::clone(&hushed),
            abandon: Arc::clone(&abandon),
            asleep: Arc::clone(&asleep),
            probe,
        };
        let writer = thread::Builder::new()
            .name("motorwire-recorder".to_owned())
            .spawn(move || files.write_all(&records, &q, &d, &flags))?;
        Ok(Self {
            queue: Some(queue),
            queued,
            losses,
            hushed,
            abandon,
            asleep,
            writer: Some(writer),
        })
    }

    fn put(&self, r: Record) {
        let Some(q) = &self.queue else { return };
        if self.queued.load(Ordering::Relaxed) >= RECORD_QUEUE {
            let at = r.at();
            self.losses.lose(1, at, at);
            return;
        }
        // Counted before the writer is looked at, in one order with the
        // writer's own (it says it sleeps, then looks at the count): either
        // it sees this record, or this sees it asleep and wakes it.
        self.queued.fetch_add(1, Ordering::SeqCst);
        if let Err(mpsc::SendError(r)) = q.send(r) {
            self.queued.fetch_sub(1, Ordering::Relaxed);
            let at = r.at();
            self.losses.lose(1, at, at);
        }
        // Only the first record after a quiet spell makes the system call.
        if self.asleep.load(Ordering::SeqCst) && self.asleep.swap(false, Ordering::SeqCst) {
            self.wake();
        }
    }

    /// Wakes the writer from its sleep.
    fn wake(&self) {
        if let Some(w) = &self.writer {
            w.thread().unpark();
        }
    }

    /// Whether the writer has written everything it was handed and sleeps
    /// until the next record: nothing was recorded for a while (about
    /// 20 ms), and until the next record the recording costs the session
    /// one look of its writer a second. The next record wakes it.
    ///
    /// ```
    /// use std::time::{Duration, Instant};
    /// use motorwire_record::record::{Recorder, RecordConfig, DEFAULT_RECORD_MAX};
    ///
    /// let dir = std::env::temp_dir().join(format!("motorwire-doc-idle-{}", std::process::id()));
    /// let recorder = Recorder::start(RecordConfig {
    ///     dir: dir.clone(),
    ///     max_bytes: DEFAULT_RECORD_MAX,
    ///     interface: "can0".to_owned(),
    ///     setup: None,
    /// })?;
    /// let begun = Instant::now();
    /// while !recorder.is_idle() && begun.elapsed() < Duration::from_secs(10) {
    ///     std::thread::sleep(Duration::from_millis(5));
    /// }
    /// assert!(recorder.is_idle());
    /// recorder.finish();
    /// # std::fs::remove_dir_all(&dir)?;
    /// # Ok::<(), std::io::Error>(())
    /// ```
    #[must_use]
    pub fn is_idle(&self) -> bool {
        // The count first: asleep with nothing queued after it. (Asleep is
        // said before the writer looks at the count, so alone it may be
        // true while a record just put waits for the writer's look.)
        self.queued.load(Ordering::SeqCst) == 0 && self.asleep.load(Ordering::SeqCst)
    }

    /// A frame sent or received at `at`.
    pub fn frame(&self, at: Instant, dir: Direction, frame: &Frame) {
        self.put(Record::Frame {
            at,
            taken: None,
            dir,
            frame: *frame,
        });
    }

    /// Input line `number` of `origin`, received at `at` and taken by the
    /// bridge now (both are written: `t_us` and `taken_us`).
    pub fn input(&self, at: Instant, origin: Origin, number: u64, text: &str) {
        Tap::input_owned(self, at, Instant::now(), origin, number, text.to_owned());
    }

    /// An input line that could not be read: its bytes (where the reader
    /// kept them) written in hex as `bytes`, with `length`.
    pub fn unreadable(&self, line: &Unreadable<'_>) {
        self.put(Record::Unreadable {
            at: line.at,
            origin: line.origin,
            number: line.number,
            reason: line.reason.to_owned(),
            stop: line.stop,
            bytes: line.bytes.map(|(b, n)| (b.to_vec(), n)),
        });
    }

    /// Something the bridge was told at `at` that is neither a line nor a
    /// frame.
    pub fn mark(&self, at: Instant, mark: Mark) {
        self.put(Record::Mark { at, mark });
    }

    /// An output line given at `at`.
    pub fn output(&self, at: Instant, output: &Output) {
        self.output_owned(at, output.clone());
    }

    /// An output line given at `at`, kept as it is (no copy).
    pub fn output_owned(&self, at: Instant, output: Output) {
        self.put(Record::Output { at, output });
    }

    /// A line to or from the Orion arm controller.
    pub fn orion(&self, at: Instant, dir: Direction, line: &str) {
        self.put(Record::Orion {
            at,
            dir,
            line: line.to_owned(),
        });
    }

    /// Records dropped so far.
    pub fn dropped(&self) -> u64 {
        self.losses.count()
    }

    /// Ends the recording: what is queued is written, the files closed
    /// and `session.json` completed.
    pub fn finish(mut self) -> RecordSummary {
        self.end(None).unwrap_or_default()
    }

    /// [`Recorder::finish`], waiting at most about `limit` for the writer
    /// (a disk that is slow or does not answer must not hold the end of a
    /// session that has already stopped its joints): past `limit`, what is
    /// still queued is dropped and counted, and `session.json` completed
    /// with those counts. `None` when even that did not end within two
    /// seconds more (the writer is blocked in a write): the writer is left
    /// to end on its own (or with the process), the recording lacks its
    /// end and [`crate::replay`] says so; [`Recorder::dropped`], read
    /// before, says what was dropped until then.
    ///
    /// ```
    /// use std::time::Duration;
    /// use motorwire_record::record::{Recorder, RecordConfig, DEFAULT_RECORD_MAX};
    ///
    /// let dir = std::env::temp_dir().join(format!("motorwire-doc-finish-{}", std::process::id()));
    /// let recorder = Recorder::start(RecordConfig {
    ///     dir: dir.clone(),
    ///     max_bytes: DEFAULT_RECORD_MAX,
    ///     interface: "can0".to_owned(),
    ///     setup: None,
    /// })?;
    /// let summary = recorder.finish_within(Duration::from_secs(5)).expect("a disk that answers");
    /// assert_eq!(summary.dropped, 0);
    /// # std::fs::remove_dir_all(&dir)?;
    /// # Ok::<(), std::io::Error>(())
    /// ```
    #[must_use]
    pub fn finish_within(mut self, limit: Duration) -> Option<RecordSummary> {
        self.end(Some(limit))
    }

    /// Ends the recording: the writer is waited for until it has written
    /// what is queued, or, with a `limit`, as [`Recorder::finish_within`]
    /// says.
    fn end(&mut self, limit: Option<Duration>) -> Option<RecordSummary> {
        drop(self.queue.take());
        // Never left waiting for a stop that ended with the session, nor
        // asleep: it finds the queue closed.
        self.hushed.store(false, Ordering::Relaxed);
        self.asleep.store(false, Ordering::SeqCst);
        self.wake();
        let dropped = || self.losses.count();
        let Some(writer) = self.writer.take() else {
            return Some(RecordSummary {
                dropped: dropped(),
                ..RecordSummary::default()
            });
        };
        if let Some(limit) = limit {
            let begun = Instant::now();
            while !writer.is_finished() {
                let waited = begun.elapsed();
                if waited >= limit {
                    self.abandon.store(true, Ordering::Relaxed);
                }
                if waited >= limit.saturating_add(ABANDON_GRACE) {
                    // Detached: it ends when its write returns, or with
                    // the process.
                    return None;
                }
                thread::sleep(Duration::from_millis(5));
            }
        }
        let mut s = writer.join().ok().unwrap_or_default();
        // Every record dropped, by either side (the queue is closed: no
        // more come).
        s.dropped = dropped();
        Some(s)
    }
}

impl Drop for Recorder {
    fn drop(&mut self) {
        if self.writer.is_some() {
            let _ = self.end(None);
        }
    }
}

/// A file of the recording, made anew at `path`: what stands there (an
/// earlier recording's file, a symbolic link, a FIFO) is removed first, and
/// the file is created only if nothing is there then, so the recording
/// never writes through a link to another file nor blocks on a FIFO.
///
/// # Errors
/// A directory stands there, or it could not be removed or created.
fn fresh(path: &Path) -> io::Result<File> {
    match fs::symlink_metadata(path) {
        Ok(m) if m.is_dir() => {
            return Err(io::Error::other(format!(
                "{} is a directory",
                path.display()
            )));
        }
        Ok(_) => fs::remove_file(path)?,
        Err(e) if e.kind() == io::ErrorKind::NotFound => {}
        Err(e) => return Err(e),
    }
    fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(path)
}

/// One of the two rotated files.
#[derive(Debug)]
struct Rotated {
    path: PathBuf,
    old: PathBuf,
    out: BufWriter<File>,
    len: u64,
    limit: u64,
}

impl Rotated {
    fn create(dir: &Path, name: &str, old: &str, limit: u64) -> io::Result<Self> {
        let path = dir.join(name);
        let old = dir.join(old);
        match fs::remove_file(&old) {
            Err(e) if e.kind() != io::ErrorKind::NotFound => return Err(e),
            _ => {}
        }
        Ok(Self {
            out: BufWriter::new(fresh(&path)?),
            path,
            old,
            len: 0,
            limit,
        })
    }

    /// Writes `s` as one line; its bytes, or `None` when it is longer
    /// than the file may hold (not written: the recording stays within
    /// its limit).
    /// Whether the file written is still the one at its path (the
    /// directory removed or the file replaced under the recorder: what is
    /// written goes nowhere anyone can read).
    fn still_there(&self) -> bool {
        let Ok(at_path) = fs::metadata(&self.path) else {
            return false;
        };
        #[cfg(unix)]
        {
            use std::os::unix::fs::MetadataExt;
            self.out
                .get_ref()
                .metadata()
                .is_ok_and(|open| open.ino() == at_path.ino() && open.dev() == at_path.dev())
        }
        #[cfg(not(unix))]
        {
            at_path.is_file()
        }
    }

    fn line(&mut self, s: &str) -> io::Result<Option<u64>> {
        let n = s.len() as u64 + 1;
        if n > self.limit {
            return Ok(None);
        }
        if self.len > 0 && self.len + n > self.limit {
            self.out.flush()?;
            fs::rename(&self.path, &self.old)?;
            self.out = BufWriter::new(fresh(&self.path)?);
            self.len = 0;
        }
        self.out.write_all(s.as_bytes())?;
        self.out.write_all(b"\n")?;
        self.len += n;
        Ok(Some(n))
    }
}

#[derive(Debug)]
struct Files {
    interface: String,
    session: SessionFile,
    frames: Rotated,
    lines: Rotated,
    t0: Instant,
    wall0: Duration,
}

impl Files {
    fn open(config: &RecordConfig, t0: Instant, wall0: Duration) -> io::Result<Self> {
        // `session.json` counts against the limit (it holds the map's
        // text): what it takes (made at its largest at the start), then
        // two files, each with its rotated copy, a quarter of the rest each.
        let head = session_head(&config.interface, config.setup.as_ref(), wall0);
        let session = SessionFile::size(head.len());
        let room = config
            .max_bytes
            .checked_sub(session)
            .filter(|room| *room >= 4 * MIN_FILE)
            .ok_or_else(|| {
                io::Error::new(
                    io::ErrorKind::InvalidInput,
                    format!(
                        "the recording's limit of {} bytes leaves too little room: its session.json (how the bridge was set up, the map's text with it) takes {session} bytes, and the frames and lines need at least {} more",
                        config.max_bytes,
                        4 * MIN_FILE
                    ),
                )
            })?;
        let quarter = room / 4;
        Ok(Self {
            interface: config.interface.clone(),
            // First: a recording that has files has the session that says
            // whether it is whole.
            session: SessionFile::create(
                &config.dir.join("session.json"),
                &head,
                &Progress::default(),
            )?,
            frames: Rotated::create(&config.dir, "frames.log", "frames.1.log", quarter)?,
            lines: Rotated::create(&config.dir, "lines.jsonl", "lines.1.jsonl", quarter)?,
            t0,
            wall0,
        })
    }

    /// Rewrites `session.json`'s counts in place: `s` and the records
    /// `losses` counts, and the end when `ended`.
    fn progress(&mut self, s: &RecordSummary, losses: &Losses, ended: bool) -> io::Result<()> {
        let ended_wall_ms = ended.then(|| {
            let wall = self.wall0.saturating_add(self.t0.elapsed());
            u64::try_from(wall.as_millis()).unwrap_or(u64::MAX)
        });
        self.session.rewrite(&Progress {
            written: s.written,
            dropped: losses.count(),
            bytes: s.bytes,
            dropped_span: losses.span(),
            ended_wall_ms,
        })
    }

    /// (`t_us`, wall microseconds) of `at`.
    fn clocks(&self, at: Instant) -> (u64, u64) {
        let t = at.saturating_duration_since(self.t0);
        let t_us = u64::try_from(t.as_micros()).unwrap_or(u64::MAX);
        let wall = u64::try_from(self.wall0.saturating_add(t).as_micros()).unwrap_or(u64::MAX);
        (t_us, wall)
    }

    /// Writes `r`: its bytes, or `None` when it is too long for the
    /// recording's limit (not written).
    fn write(&mut self, r: Record) -> io::Result<Option<u64>> {
        let (t_us, wall_us) = self.clocks(r.at());
        let head =
            |kind: &str| format!(r#"{{"t_us":{t_us},"wall_ms":{},"{kind}":"#, wall_us / 1000);
        let line = match r {
            Record::Frame {
                dir, frame, taken, ..
            } => {
                let entry = LogEntry {
                    timestamp: Duration::from_micros(wall_us),
                    interface: self.interface.clone(),
                    frame,
                };
                let Some(logged) = self.frames.line(&entry.to_string())? else {
                    return Ok(None);
                };
                let id = frame.id();
                let mut line = head("frame");
                let _ = write!(
                    line,
                    r#"{{"dir":"{}","id":{},"extended":{},"fd":{},"data":""#,
                    dir.name(),
                    id.raw(),
                    id.is_extended(),
                    frame.is_fd()
                );
                for b in frame.data() {
                    let _ = write!(line, "{b:02x}");
                }
                line.push('"');
                if let Some(taken) = taken {
                    let _ = write!(line, r#","taken_us":{}"#, self.clocks(taken).0);
                }
                line.push_str("}}");
                return Ok(self.lines.line(&line)?.map(|n| n + logged));
            }
            Record::Input {
                origin,
                number,
                text,
                taken,
                ..
            } => {
                let body = serde_json::json!({"origin": origin.0, "line": number, "text": text, "taken_us": self.clocks(taken).0});
                format!("{}{body}}}", head("in"))
            }
            Record::Unreadable {
                origin,
                number,
                reason,
                stop,
                bytes,
                ..
            } => {
                let mut body = serde_json::Map::new();
                body.insert("origin".into(), origin.0.into());
                body.insert("line".into(), number.into());
                body.insert("unreadable".into(), reason.into());
                if stop {
                    body.insert("stop".into(), true.into());
                }
                if let Some((b, length)) = bytes {
                    body.insert("bytes".into(), motorwire_can::candump::bytes_hex(&b).into());
                    body.insert("length".into(), length.into());
                }
                let body = serde_json::Value::Object(body);
                format!("{}{body}}}", head("in"))
            }
            Record::Mark { mark, .. } => format!("{}{}}}", head("mark"), mark.to_value()),
            // The line as it was given, whole, and to whom when it was
            // one client's (a result, a completion, a greeting).
            Record::Output { output, .. } => {
                let to = output
                    .reader()
                    .map_or_else(String::new, |o| format!(r#","to":{}"#, o.0));
                format!("{}{}{to}}}", head("out"), output.to_json())
            }
            Record::OutputLine { to, line, .. } => {
                let to = to.map_or_else(String::new, |o| format!(r#","to":{}"#, o.0));
                format!("{}{line}{to}}}", head("out"))
            }
            Record::Orion { dir, line, .. } => {
                let body = serde_json::json!({"dir": dir.name(), "line": line});
                format!("{}{body}}}", head("orion"))
            }
        };
        self.lines.line(&line)
    }

    /// Puts the files' buffers on disk: the records `pending` handed to
    /// them are counted written, or, when that fails or the files are no
    /// longer where they are read (or the disk failed before), lost.
    fn settle(
        &mut self,
        s: &mut RecordSummary,
        pending: &mut Pending,
        losses: &Losses,
        failed: &mut bool,
    ) {
        let flushed = self
            .frames
            .out
            .flush()
            .and_then(|()| self.lines.out.flush());
        // Written where it can be read: the files are still there.
        let there = pending.count == 0 || (self.frames.still_there() && self.lines.still_there());
        let p = std::mem::take(pending);
        if flushed.is_ok() && there && !*failed {
            s.written += p.count;
            s.bytes += p.bytes;
        } else {
            *failed = true;
            if let Some((from, to)) = p.span {
                losses.lose(p.count, from, to);
            }
        }
    }

    fn write_all(
        mut self,
        records: &Receiver<Record>,
        queued: &AtomicUsize,
        losses: &Losses,
        flags: &WriterFlags,
    ) -> RecordSummary {
        let mut s = RecordSummary::default();
        let mut failed = false;
        // Records handed to the files' buffers, counted written once the
        // buffers are on disk (dropped when that fails: a full disk).
        let mut pending = Pending::default();
        // What `session.json` says, and since when.
        let mut shown = (0u64, 0u64);
        let mut shown_at = Instant::now();
        // The writer polls rather than sleeping in `recv`: a record handed
        // over then never has to wake it (a system call on the bridge's
        // thread, for every frame and line). Only after a quiet spell
        // (`IDLE_POLLS` rounds without a record) does it sleep until woken,
        // and then only the first record after it makes that call.
        // Polls in a row that found nothing.
        let mut idle: u32 = 0;
        'session: loop {
            // At most a batch at a time, then a pause: the writer takes a
            // share of a core, never a core the bridge's thread needs when
            // a stop comes (its work is spread out; the queue holds the
            // rest).
            idle = idle.saturating_add(1);
            flags.probe.round();
            for _ in 0..BATCH {
                // A stop under way: its frames first (at most a stop's
                // handling, the runner says when it is done).
                while flags.hushed.load(Ordering::Relaxed) {
                    thread::sleep(Duration::from_micros(100));
                }
                flags.probe.before_take();
                let r = match records.try_recv() {
                    Ok(r) => {
                        // In one order with `is_idle`'s look at the count.
                        queued.fetch_sub(1, Ordering::SeqCst);
                        idle = 0;
                        r
                    }
                    Err(mpsc::TryRecvError::Empty) => break,
                    Err(mpsc::TryRecvError::Disconnected) => break 'session,
                };
                let at = r.at();
                if failed || flags.abandon.load(Ordering::Relaxed) {
                    // The disk failed, or the session's end may not wait
                    // for it: counted, never waited on.
                    losses.lose(1, at, at);
                    continue;
                }
                match self.write(r) {
                    Ok(Some(n)) => pending.add(at, n),
                    // Longer than the recording may hold: left out, counted.
                    Ok(None) => losses.lose(1, at, at),
                    Err(_) => {
                        failed = true;
                        pending.add(at, 0);
                        let p = std::mem::take(&mut pending);
                        if let Some((from, to)) = p.span {
                            losses.lose(p.count, from, to);
                        }
                    }
                }
            }
            // Nothing more waiting: out on disk (a crash loses little).
            self.settle(&mut s, &mut pending, losses, &mut failed);
            // `session.json` told at once of the first record dropped, and
            // of what changes after at most once a second.
            let now = (s.written, losses.count());
            if now != shown && ((shown.1 == 0 && now.1 > 0) || shown_at.elapsed() >= SESSION_EVERY)
            {
                // Failing, it says what it said before; the end tries again.
                let _ = self.progress(&s, losses, false);
                (shown, shown_at) = (now, Instant::now());
            }
            if flags.abandon.load(Ordering::Relaxed) {
                continue;
            }
            if idle >= IDLE_POLLS {
                // Asleep until a record wakes it: said first, then the
                // queue looked at (the other half of `Recorder::put`'s
                // order), so a record handed over meanwhile is never left
                // waiting.
                // Woken without a record (by its own timeout), it looks once
                // and goes back to sleep: `idle` stays where it is.
                flags.asleep.store(true, Ordering::SeqCst);
                if queued.load(Ordering::SeqCst) == 0 {
                    flags.probe.before_sleep();
                    thread::park_timeout(flags.probe.idle_sleep());
                }
                flags.asleep.store(false, Ordering::SeqCst);
            } else {
                thread::sleep(POLL);
            }
        }
        self.settle(&mut s, &mut pending, losses, &mut failed);
        s.session = self.progress(&s, losses, true).is_ok();
        s.dropped = losses.count();
        s
    }
}

/// Records handed to the files' buffers and not yet on disk.
#[derive(Debug, Default)]
struct Pending {
    count: u64,
    bytes: u64,
    /// When the earliest and the latest of them came.
    span: Option<(Instant, Instant)>,
}

impl Pending {
    fn add(&mut self, at: Instant, bytes: u64) {
        self.count += 1;
        self.bytes += bytes;
        self.span = Some(self.span.map_or((at, at), |(a, b)| (a.min(at), b.max(at))));
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use motorwire_can::CanId;

    /// The writer as a test steers it: stalled as on a disk that does not
    /// answer, its rounds counted, held between its last look and its
    /// sleep (and saying so), asleep a minute (long enough that a missed
    /// wake-up fails the test waiting for its record).
    #[derive(Debug, Default)]
    struct Steered {
        stall: Arc<AtomicBool>,
        rounds: AtomicU64,
        hold: AtomicBool,
        held: AtomicBool,
    }

    impl WriterProbe for Steered {
        fn round(&self) {
            self.rounds.fetch_add(1, Ordering::Relaxed);
        }
        fn before_take(&self) {
            while self.stall.load(Ordering::Relaxed) {
                thread::sleep(Duration::from_millis(1));
            }
        }
        fn before_sleep(&self) {
            if self.hold.load(Ordering::SeqCst) {
                self.held.store(true, Ordering::SeqCst);
                while self.hold.load(Ordering::SeqCst) {
                    thread::sleep(Duration::from_millis(1));
                }
            }
        }
        fn idle_sleep(&self) -> Duration {
            Duration::from_secs(60)
        }
    }

    /// A recorder into `dir` on `can0`, holding at most `max_bytes`, its
    /// writer steered by the test.
    fn steered(dir: &Path, max_bytes: u64) -> (Recorder, Arc<Steered>) {
        let probe = Arc::new(Steered::default());
        let config = RecordConfig {
            dir: dir.to_owned(),
            max_bytes,
            interface: "can0".to_owned(),
            setup: None,
        };
        let watched: Arc<dyn WriterProbe> = probe.clone();
        (Recorder::start_watched(config, watched).unwrap(), probe)
    }

    /// A recorder into `dir` on `can0`, holding at most `max_bytes` (its
    /// writer asleep a minute when idle, as [`Steered`] has it).
    fn recording(dir: &Path, max_bytes: u64) -> Recorder {
        steered(dir, max_bytes).0
    }

    fn scratch(name: &str) -> PathBuf {
        let d =
            std::env::temp_dir().join(format!("motorwire-record-{name}-{}", std::process::id()));
        let _ = fs::remove_dir_all(&d);
        d
    }

    /// A recording whose directory is removed under it counts what it
    /// writes from then on as dropped (written to files nobody can read),
    /// never as written.
    #[test]
    fn a_directory_removed_mid_session_counts_the_rest_dropped() {
        let dir = scratch("removed");
        let rec = recording(&dir, DEFAULT_RECORD_MAX);
        rec.input(Instant::now(), Origin(1), 1, "{}");
        thread::sleep(Duration::from_millis(100));
        fs::remove_dir_all(&dir).unwrap();
        for n in 2..=11 {
            rec.input(Instant::now(), Origin(1), n, "{}");
        }
        let s = rec.finish();
        assert_eq!((s.written, s.dropped), (1, 10));
    }

    /// While the bridge handles a stop, the writer writes nothing (the
    /// stop has the cores); once told, it goes on, nothing lost.
    #[test]
    fn a_hushed_recorder_waits_for_the_stop_then_writes_everything() {
        let dir = scratch("hush");
        let rec = recording(&dir, DEFAULT_RECORD_MAX);
        Tap::hush(&rec, true);
        rec.input(Instant::now(), Origin(1), 1, r#"{"emergency_stop":true}"#);
        thread::sleep(Duration::from_millis(100));
        assert_eq!(fs::read_to_string(dir.join("lines.jsonl")).unwrap(), "");
        Tap::hush(&rec, false);
        let s = rec.finish();
        assert_eq!((s.written, s.dropped), (1, 0));
        assert!(
            fs::read_to_string(dir.join("lines.jsonl"))
                .unwrap()
                .contains(r#""text":"{\"emergency_stop\":true}""#)
        );
    }

    /// Waits until `done` (at most 10 s, then fails saying `what`).
    fn within_10s(what: &str, mut done: impl FnMut() -> bool) {
        let begun = Instant::now();
        while !done() {
            assert!(begun.elapsed() < Duration::from_secs(10), "{what}");
            thread::sleep(Duration::from_micros(200));
        }
    }

    /// Waits until `rec` is idle (at most 10 s).
    fn until_idle(rec: &Recorder) {
        within_10s("never idle", || rec.is_idle());
    }

    /// Whether `dir`'s `lines.jsonl` holds at least `n` lines, the last
    /// one containing `text`.
    fn written(dir: &Path, n: usize, text: &str) -> bool {
        let lines = fs::read_to_string(dir.join("lines.jsonl")).unwrap();
        lines.lines().count() >= n && lines.lines().last().is_some_and(|l| l.contains(text))
    }

    /// An idle recording costs nothing: its writer sleeps (no rounds
    /// while nothing comes), and the next record wakes it.
    #[test]
    fn an_idle_writer_sleeps_until_the_next_record_wakes_it() {
        let dir = scratch("idle");
        let (rec, probe) = steered(&dir, DEFAULT_RECORD_MAX);
        until_idle(&rec);
        let rounds = probe.rounds.load(Ordering::Relaxed);
        thread::sleep(Duration::from_millis(200));
        // Polling every 2 ms, it would have looked 100 times.
        assert_eq!(probe.rounds.load(Ordering::Relaxed), rounds);
        assert!(rec.is_idle());
        rec.input(Instant::now(), Origin(1), 1, "{}");
        // Woken at once (asleep, it would not look again for a minute in
        // tests): written well within the test's patience.
        within_10s("not woken", || written(&dir, 1, r#""text":"{}""#));
        until_idle(&rec);
        let s = rec.finish();
        assert_eq!((s.written, s.dropped), (1, 0));
    }

    /// The window a wake-up could be lost in, forced: the writer has said
    /// it sleeps and found the queue empty, and is held there; a record
    /// put then finds it asleep and wakes it, so the sleep it then goes to
    /// ends at once (asleep, it would not look again for a minute in
    /// tests).
    #[test]
    fn a_record_put_as_the_writer_goes_to_sleep_wakes_it() {
        let dir = scratch("asleep-window");
        let (rec, probe) = steered(&dir, DEFAULT_RECORD_MAX);
        probe.hold.store(true, Ordering::SeqCst);
        within_10s("never held", || probe.held.load(Ordering::SeqCst));
        assert!(rec.is_idle());
        rec.input(Instant::now(), Origin(1), 1, "{}");
        // Not idle with a record queued, whatever the writer said.
        assert!(!rec.is_idle());
        probe.hold.store(false, Ordering::SeqCst);
        within_10s("left asleep", || written(&dir, 1, r#""text":"{}""#));
        let s = rec.finish();
        assert_eq!((s.written, s.dropped), (1, 0));
    }

    /// Records from four threads after quiet spells of every length about
    /// the writer's idle time (every other round once it sleeps, for
    /// certain): each round is written before the next.
    #[test]
    fn records_after_quiet_spells_of_any_length_are_each_written() {
        let dir = scratch("quiet-spells");
        let rec = Arc::new(recording(&dir, DEFAULT_RECORD_MAX));
        let mut seed = 0x9e37_79b9_u32;
        for round in 0..60u64 {
            if round % 2 == 0 {
                until_idle(&rec);
            } else {
                // 15 to 25 ms: around the writer's 20 ms without a record.
                seed ^= seed << 13;
                seed ^= seed >> 17;
                seed ^= seed << 5;
                thread::sleep(Duration::from_micros(15_000 + u64::from(seed % 10_000)));
            }
            let writers: Vec<_> = (0..4u64)
                .map(|k| {
                    let rec = Arc::clone(&rec);
                    thread::spawn(move || rec.input(Instant::now(), Origin(k), round, "{}"))
                })
                .collect();
            for w in writers {
                w.join().unwrap();
            }
            let want = 4 * (round as usize + 1);
            within_10s(&format!("round {round} left asleep"), || {
                written(&dir, want, &format!(r#""line":{round},"#))
            });
        }
        let s = Arc::try_unwrap(rec).unwrap().finish();
        assert_eq!((s.written, s.dropped), (240, 0));
    }

    /// A disk that does not answer never holds the end of a session past
    /// its limit: what is queued is dropped and counted, `session.json`
    /// says so, and nothing queued is counted twice or lost uncounted.
    #[test]
    fn a_stalled_writer_is_given_up_at_the_limit_and_its_records_counted_dropped() {
        let dir = scratch("stalled");
        let (rec, probe) = steered(&dir, DEFAULT_RECORD_MAX);
        probe.stall.store(true, Ordering::Relaxed);
        let t = Instant::now();
        for n in 0..1_000 {
            rec.input(t, Origin(1), n, r#"{"emergency_stop":false}"#);
        }
        // The disk answers again only after the limit: past it, nothing
        // more is written.
        let stall = Arc::clone(&probe.stall);
        let unstall = thread::spawn(move || {
            thread::sleep(Duration::from_millis(300));
            stall.store(false, Ordering::Relaxed);
        });
        let begun = Instant::now();
        let s = rec.finish_within(Duration::from_millis(100)).unwrap();
        let waited = begun.elapsed();
        unstall.join().unwrap();
        assert!(waited < Duration::from_secs(2), "{waited:?}");
        // The writer may have taken one record before it stalled.
        assert!(s.written <= 1, "{s:?}");
        assert_eq!(s.written + s.dropped, 1_000, "{s:?}");
        let session: serde_json::Value =
            serde_json::from_str(&fs::read_to_string(dir.join("session.json")).unwrap()).unwrap();
        assert_eq!(session["dropped"], s.dropped, "{session}");
        let _ = fs::remove_dir_all(&dir);
    }

    /// A writer still blocked after the grace is left behind: the end
    /// returns, at about the limit and the grace, with `None`.
    #[test]
    fn a_writer_blocked_past_the_grace_is_left_behind() {
        let dir = scratch("blocked");
        let (rec, probe) = steered(&dir, DEFAULT_RECORD_MAX);
        probe.stall.store(true, Ordering::Relaxed);
        rec.input(Instant::now(), Origin(1), 1, r#"{"emergency_stop":false}"#);
        rec.input(Instant::now(), Origin(1), 2, r#"{"emergency_stop":false}"#);
        let stall = Arc::clone(&probe.stall);
        let begun = Instant::now();
        assert_eq!(rec.finish_within(Duration::from_millis(50)), None);
        let waited = begun.elapsed();
        assert!(
            waited >= ABANDON_GRACE && waited < ABANDON_GRACE + Duration::from_secs(1),
            "{waited:?}"
        );
        // Let the detached writer end.
        stall.store(false, Ordering::Relaxed);
        let _ = fs::remove_dir_all(&dir);
    }

    /// An output told with its line (as [`motorwire_bridge::Runner::run_rendered`]
    /// tells it) is written as the same record as the output itself: the
    /// line as given, and to whom.
    #[test]
    fn an_output_told_as_its_line_is_recorded_as_the_output_is() {
        let result = || Output::Result {
            origin: Origin(3),
            result: Box::new(motorwire_bridge::LineResult {
                ok: true,
                line: 7,
                ..motorwire_bridge::LineResult::default()
            }),
        };
        let event = || {
            Output::Event(motorwire_bridge::Event::BusError {
                error: "bus off".to_owned(),
            })
        };
        let mut written = Vec::new();
        for as_line in [false, true] {
            let dir = scratch(if as_line { "as-line" } else { "as-output" });
            // Before the recording's start: written at 0 µs.
            let t = Instant::now();
            let rec = recording(&dir, DEFAULT_RECORD_MAX);
            for o in [result(), event()] {
                if as_line {
                    let line: Arc<str> = Arc::from(o.to_json());
                    Tap::output_line_owned(&rec, t, o, &line);
                } else {
                    Tap::output_owned(&rec, t, o);
                }
            }
            let s = rec.finish();
            assert_eq!((s.written, s.dropped), (2, 0));
            let text = fs::read_to_string(dir.join("lines.jsonl")).unwrap();
            // Each line but its wall clock (the two recorders started apart).
            let lines: Vec<serde_json::Value> = text
                .lines()
                .map(|l| {
                    let mut v: serde_json::Value = serde_json::from_str(l).unwrap();
                    v.as_object_mut().unwrap().remove("wall_ms");
                    v
                })
                .collect();
            written.push(lines);
            let _ = fs::remove_dir_all(&dir);
        }
        assert_eq!(written[0], written[1]);
        assert_eq!(
            written[1][0],
            serde_json::json!({"t_us": 0, "out": {"ok": true, "line": 7}, "to": 3})
        );
        assert_eq!(
            written[1][1],
            serde_json::json!({"t_us": 0, "out": {"event": "bus_error", "error": "bus off"}})
        );
    }

    /// Frames go to `frames.log` as candump writes them and, with their
    /// direction, to `lines.jsonl` among the input and output lines, in
    /// the order they happened.
    #[test]
    fn a_session_is_written_in_both_files_in_order() {
        let dir = scratch("order");
        let rec = recording(&dir, DEFAULT_RECORD_MAX);
        let t = Instant::now();
        rec.input(t, Origin(2), 1, r#"{"emergency_stop":true}"#);
        let f = Frame::fd(CanId::standard(0x12).unwrap(), &[0x00, 0x12, 0x01, 0x03]).unwrap();
        rec.frame(t, Direction::Tx, &f);
        rec.orion(t, Direction::Tx, r#"{"ID":32,"MODE":2,"DATA":1}"#);
        rec.unreadable(&Unreadable {
            at: t,
            origin: Origin(2),
            number: 2,
            reason: "the line is not UTF-8",
            stop: false,
            bytes: Some((&[0x7b, 0xff, 0x0d], 3)),
        });
        let s = rec.finish();
        assert_eq!((s.written, s.dropped), (4, 0));
        let frames = fs::read_to_string(dir.join("frames.log")).unwrap();
        // As candump writes it, and reads back as the same frame.
        let entry = LogEntry::parse(frames.trim_end()).unwrap();
        assert_eq!((entry.interface.as_str(), entry.frame), ("can0", f));
        let lines: Vec<serde_json::Value> = fs::read_to_string(dir.join("lines.jsonl"))
            .unwrap()
            .lines()
            .map(|l| serde_json::from_str(l).unwrap())
            .collect();
        assert_eq!(frames.lines().count(), 1);
        assert!(frames.ends_with(" can0 012##100120103\n"), "{frames}");
        assert_eq!(lines.len(), 4);
        assert_eq!(lines[0]["in"]["text"], r#"{"emergency_stop":true}"#);
        assert_eq!(
            (
                lines[0]["in"]["origin"].as_u64(),
                lines[0]["in"]["line"].as_u64()
            ),
            (Some(2), Some(1))
        );
        assert_eq!(lines[1]["frame"]["dir"], "tx");
        assert_eq!(lines[1]["frame"]["id"], 0x12);
        assert_eq!(lines[1]["frame"]["data"], "00120103");
        assert_eq!(lines[2]["orion"]["line"], r#"{"ID":32,"MODE":2,"DATA":1}"#);
        assert_eq!(lines[3]["in"]["unreadable"], "the line is not UTF-8");
        // Its bytes, which no text can hold, in hex (as a frame's data),
        // and its length.
        assert_eq!(lines[3]["in"]["bytes"], "7bff0d");
        assert_eq!(lines[3]["in"]["length"], 3);
        let session: serde_json::Value =
            serde_json::from_str(&fs::read_to_string(dir.join("session.json")).unwrap()).unwrap();
        assert_eq!(
            (session["written"].as_u64(), session["dropped"].as_u64()),
            (Some(4), Some(0))
        );
        let _ = fs::remove_dir_all(dir);
    }

    /// Rotated at a quarter of the limit per file: however long the
    /// session, the recording holds at most its limit.
    #[test]
    fn a_recording_never_holds_more_than_its_limit() {
        let dir = scratch("bound");
        let limit = 64 * 1024;
        let rec = recording(&dir, limit);
        let f = Frame::fd(CanId::standard(0x12).unwrap(), &[0xAB; 64]).unwrap();
        let t = Instant::now();
        for _ in 0..5_000 {
            rec.frame(t, Direction::Rx, &f);
        }
        let s = rec.finish();
        assert_eq!(s.written + s.dropped, 5_000);
        assert!(s.bytes > 4 * limit, "{s:?}");
        let on_disk: u64 = fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().metadata().unwrap().len())
            .sum();
        assert!(on_disk <= limit, "{on_disk} bytes on disk");
        assert!(dir.join("frames.1.log").exists());
        let _ = fs::remove_dir_all(dir);
    }

    /// `session.json` holds the map's text: it counts against the limit,
    /// and a setup that leaves too little room is refused at the start.
    #[test]
    fn the_setup_counts_against_the_limit() {
        let dir = scratch("setup");
        let limit = 64 * 1024;
        let start = |setup_len: usize| {
            Recorder::start(RecordConfig {
                dir: dir.clone(),
                max_bytes: limit,
                interface: "can0".to_owned(),
                setup: Some(serde_json::json!({ "map": "#".repeat(setup_len) })),
            })
        };
        let rec = start(30_000).unwrap();
        let f = Frame::fd(CanId::standard(0x12).unwrap(), &[0xAB; 64]).unwrap();
        for _ in 0..5_000 {
            rec.frame(Instant::now(), Direction::Rx, &f);
        }
        let s = rec.finish();
        assert_eq!(s.written + s.dropped, 5_000);
        let on_disk: u64 = fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().metadata().unwrap().len())
            .sum();
        assert!(on_disk <= limit, "{on_disk} bytes on disk");
        assert!(fs::metadata(dir.join("session.json")).unwrap().len() > 30_000);
        let e = start(60_000).unwrap_err();
        assert_eq!(e.kind(), io::ErrorKind::InvalidInput);
        assert!(
            e.to_string().starts_with(
                "the recording's limit of 65536 bytes leaves too little room: its session.json"
            ),
            "{e}"
        );
        let _ = fs::remove_dir_all(dir);
    }

    /// Only a name `canplayer` and python-can read stands as the
    /// interface: anything else is refused before anything is made.
    #[test]
    fn an_interface_the_log_readers_cannot_read_is_refused() {
        let dir = scratch("iface");
        for bad in [
            "fdcanusb:/dev/ttyACM0",
            "my port",
            "",
            "can0=vcan0",
            "sixteen_chars_ab",
        ] {
            let e = Recorder::start(RecordConfig {
                dir: dir.clone(),
                max_bytes: DEFAULT_RECORD_MAX,
                interface: bad.to_owned(),
                setup: None,
            })
            .unwrap_err();
            assert_eq!(e.kind(), io::ErrorKind::InvalidInput, "{bad}");
            assert!(!dir.exists(), "{bad}");
        }
    }

    /// A recorder whose disk is gone drops and counts; the caller never
    /// waits.
    #[test]
    fn a_failed_disk_drops_and_counts_and_never_waits() {
        let dir = scratch("gone");
        let rec = recording(&dir, 64 * 1024);
        fs::remove_dir_all(&dir).unwrap();
        let f = Frame::fd(CanId::standard(0x12).unwrap(), &[0x11; 64]).unwrap();
        let t = Instant::now();
        for _ in 0..200_000 {
            rec.frame(t, Direction::Tx, &f);
        }
        let s = rec.finish();
        assert_eq!(s.written + s.dropped, 200_000);
        assert!(s.dropped > 0, "{s:?}");
    }

    /// What stands where a file of the recording goes is removed, never
    /// written through: a symbolic link to another file (that file is left
    /// as it was), a FIFO nobody reads (the recording neither blocks at
    /// its start nor at its end).
    #[test]
    fn a_link_or_a_fifo_in_the_directory_is_replaced_not_followed() {
        let dir = scratch("links");
        fs::create_dir_all(&dir).unwrap();
        let precious = dir.join("precious.txt");
        fs::write(&precious, "keep me\n").unwrap();
        std::os::unix::fs::symlink(&precious, dir.join("frames.log")).unwrap();
        std::os::unix::fs::symlink(dir.join("elsewhere.txt"), dir.join("lines.jsonl")).unwrap();
        let made = std::process::Command::new("mkfifo")
            .arg(dir.join("session.json"))
            .status()
            .unwrap();
        assert!(made.success());
        let rec = recording(&dir, DEFAULT_RECORD_MAX);
        let f = Frame::fd(CanId::standard(0x12).unwrap(), &[1, 2, 3]).unwrap();
        rec.frame(Instant::now(), Direction::Rx, &f);
        let s = rec.finish();
        assert_eq!((s.written, s.dropped), (1, 0));
        assert_eq!(fs::read_to_string(&precious).unwrap(), "keep me\n");
        assert!(!dir.join("elsewhere.txt").exists());
        for name in ["frames.log", "lines.jsonl", "session.json"] {
            let m = fs::symlink_metadata(dir.join(name)).unwrap();
            assert!(m.file_type().is_file(), "{name} is a plain file");
        }
        assert!(!dir.join("session.json.part").exists());
        let _ = fs::remove_dir_all(dir);
    }

    /// `session.json` read as JSON.
    fn session_of(dir: &Path) -> serde_json::Value {
        serde_json::from_str(&fs::read_to_string(dir.join("session.json")).unwrap()).unwrap()
    }

    /// `session.json` is there from the start, its counts zero, not
    /// complete and without an end (what a recording whose writer was
    /// killed keeps); at the end its counts are rewritten in place: the
    /// same file, the same length, never a second file beside it.
    #[test]
    fn session_json_is_written_at_the_start_and_rewritten_in_place() {
        use std::os::unix::fs::MetadataExt;
        let dir = scratch("in-place");
        fs::create_dir_all(&dir).unwrap();
        // A recorder of an earlier version left one.
        fs::write(dir.join("session.json.part"), "").unwrap();
        let rec = recording(&dir, DEFAULT_RECORD_MAX);
        let at_start = fs::metadata(dir.join("session.json")).unwrap();
        let text = fs::read_to_string(dir.join("session.json")).unwrap();
        let v = session_of(&dir);
        assert_eq!(
            (&v["complete"], &v["written"], &v["dropped"], &v["bytes"]),
            (
                &serde_json::json!(false),
                &serde_json::json!(0),
                &serde_json::json!(0),
                &serde_json::json!(0)
            ),
            "{v}"
        );
        assert!(v.get("ended_wall_ms").is_none(), "{v}");
        assert!(v.get("dropped_first_us").is_none(), "{v}");
        assert_eq!(v["recorder"], "motorwire");
        // At its largest from the start: white space after the JSON, a
        // newline at its end.
        assert!(text.ends_with(" \n"), "{text:?}");
        assert!(!dir.join("session.json.part").exists());
        for n in 1..=3 {
            rec.input(Instant::now(), Origin(1), n, "{}");
        }
        let s = rec.finish();
        assert_eq!((s.written, s.dropped, s.session), (3, 0, true));
        let at_end = fs::metadata(dir.join("session.json")).unwrap();
        assert_eq!(at_end.ino(), at_start.ino(), "rewritten in place");
        assert_eq!(at_end.len(), at_start.len());
        let v = session_of(&dir);
        assert_eq!(v["complete"], true, "{v}");
        assert_eq!(
            (v["written"].as_u64(), v["dropped"].as_u64()),
            (Some(3), Some(0))
        );
        assert!(v["ended_wall_ms"].as_u64().unwrap() >= v["started_wall_ms"].as_u64().unwrap());
        assert!(!dir.join("session.json.part").exists());
        let _ = fs::remove_dir_all(&dir);
    }

    /// The largest counts there can be fit the room made at the start:
    /// no rewrite ever grows the file.
    #[test]
    fn the_largest_counts_fit_the_room_made_at_the_start() {
        let dir = scratch("largest");
        fs::create_dir_all(&dir).unwrap();
        let path = dir.join("session.json");
        let head = session_head("can0", None, Duration::from_secs(1));
        let mut f = SessionFile::create(&path, &head, &Progress::default()).unwrap();
        let len = fs::metadata(&path).unwrap().len();
        assert_eq!(len, SessionFile::size(head.len()));
        for p in [
            Progress::LARGEST,
            Progress {
                written: 7,
                ..Progress::default()
            },
            Progress {
                dropped: 1,
                dropped_span: Some((5, 5)),
                ended_wall_ms: Some(9),
                ..Progress::default()
            },
        ] {
            f.rewrite(&p).unwrap();
            assert_eq!(fs::metadata(&path).unwrap().len(), len);
            let v = session_of(&dir);
            assert_eq!(v["written"], p.written, "{v}");
            assert_eq!(v["dropped"], p.dropped, "{v}");
            assert_eq!(
                v["complete"],
                p.ended_wall_ms.is_some() && p.dropped == 0,
                "{v}"
            );
        }
        let _ = fs::remove_dir_all(&dir);
    }

    /// The first record dropped is in `session.json` at once, with when it
    /// came, while the recording goes on (a writer killed after it leaves
    /// a recording that says it lost records); at the end, the count and
    /// the span of every record dropped, and not complete.
    #[test]
    fn the_first_record_dropped_is_in_session_json_at_once() {
        let dir = scratch("first-drop");
        let (rec, probe) = steered(&dir, DEFAULT_RECORD_MAX);
        probe.stall.store(true, Ordering::Relaxed);
        let t = Instant::now();
        // The queue full, and 10 more: dropped on the bridge's side.
        for n in 0..(RECORD_QUEUE as u64 + 10) {
            rec.input(t + Duration::from_micros(n), Origin(1), n, "{}");
        }
        assert_eq!(rec.dropped(), 10);
        probe.stall.store(false, Ordering::Relaxed);
        within_10s("the drop never reached session.json", || {
            session_of(&dir)["dropped"].as_u64() == Some(10)
        });
        let v = session_of(&dir);
        assert_eq!(v["complete"], false, "{v}");
        assert!(v.get("ended_wall_ms").is_none(), "{v}");
        let first = v["dropped_first_us"].as_u64().unwrap();
        let last = v["dropped_last_us"].as_u64().unwrap();
        assert_eq!(last - first, 9, "{v}");
        let s = rec.finish();
        assert_eq!((s.written, s.dropped), (RECORD_QUEUE as u64, 10));
        let v = session_of(&dir);
        assert_eq!(v["complete"], false, "{v}");
        assert_eq!(v["dropped"], 10, "{v}");
        assert_eq!(v["written"], RECORD_QUEUE, "{v}");
        assert!(v["ended_wall_ms"].is_u64(), "{v}");
        let _ = fs::remove_dir_all(&dir);
    }

    /// A tmpfs of `kib` KiB mounted at `dir` (root only), unmounted and
    /// removed when dropped; `None` where mounting is not allowed.
    struct Tmpfs(PathBuf);

    impl Tmpfs {
        fn mount(dir: &Path, kib: u32) -> Option<Self> {
            fs::create_dir_all(dir).unwrap();
            let ok = std::process::Command::new("mount")
                .args(["-t", "tmpfs", "-o", &format!("size={kib}k"), "tmpfs"])
                .arg(dir)
                .output()
                .is_ok_and(|o| o.status.success());
            if ok {
                Some(Self(dir.to_owned()))
            } else {
                let _ = fs::remove_dir_all(dir);
                None
            }
        }
    }

    impl Drop for Tmpfs {
        fn drop(&mut self) {
            let _ = std::process::Command::new("umount").arg(&self.0).output();
            let _ = fs::remove_dir_all(&self.0);
        }
    }

    /// A disk that fills mid-session: what no longer fits is dropped and
    /// counted, and `session.json`, rewritten in place in the bytes it
    /// already holds, still says so, with the end; nothing is left beside
    /// it. (Needs a tmpfs of its own: root; elsewhere the process test of
    /// the CLI fills a disk by a file size limit.)
    #[test]
    fn a_full_disk_still_marks_the_recording_incomplete() {
        let dir = scratch("full");
        let Some(_disk) = Tmpfs::mount(&dir, 256) else {
            eprintln!("no tmpfs could be mounted (not root?): not run");
            return;
        };
        let rec = recording(&dir.join("rec"), DEFAULT_RECORD_MAX);
        let f = Frame::fd(CanId::standard(0x12).unwrap(), &[0x5A; 64]).unwrap();
        // About 430 bytes a frame in the two files: 256 KiB fill after
        // about 600; the queue never fills (a slow pace).
        for n in 0..2_000u32 {
            rec.frame(Instant::now(), Direction::Rx, &f);
            if n % 64 == 0 {
                thread::sleep(Duration::from_millis(2));
            }
        }
        let s = rec.finish();
        assert!(s.dropped > 0 && s.written > 0, "{s:?}");
        assert_eq!(s.written + s.dropped, 2_000, "{s:?}");
        assert!(s.session, "{s:?}");
        let v = session_of(&dir.join("rec"));
        assert_eq!(v["complete"], false, "{v}");
        assert_eq!(
            (v["written"].as_u64(), v["dropped"].as_u64()),
            (Some(s.written), Some(s.dropped))
        );
        assert!(v["ended_wall_ms"].is_u64(), "{v}");
        assert!(
            v["dropped_first_us"].as_u64().unwrap() <= v["dropped_last_us"].as_u64().unwrap(),
            "{v}"
        );
        assert!(!dir.join("rec/session.json.part").exists());
    }

    /// A record longer than a file of the recording may hold is left out
    /// and counted: the recording stays within its limit.
    #[test]
    fn a_record_longer_than_the_limit_allows_is_left_out_and_counted() {
        let dir = scratch("long");
        // A quarter of what session.json leaves of it: about 5,060 bytes.
        let limit = 20 * 1024;
        let rec = recording(&dir, limit);
        let t = Instant::now();
        rec.input(t, Origin(1), 1, &"x".repeat(6_000));
        rec.input(t, Origin(1), 2, "{}");
        let s = rec.finish();
        assert_eq!((s.written, s.dropped), (1, 1));
        let lines = fs::read_to_string(dir.join("lines.jsonl")).unwrap();
        assert_eq!(lines.lines().count(), 1);
        assert!(lines.contains(r#""line":2"#), "{lines}");
        let _ = fs::remove_dir_all(dir);
    }
}
