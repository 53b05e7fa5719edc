//! Where `motorwire bridge`'s lines come from and where its output goes:
//! standard input and output, a local socket or TCP. Nothing here ever
//! makes the engine wait: every output goes into a bounded queue that a
//! thread of its own writes out, and a reader that floods waits for the
//! engine ([`motorwire_bridge::MAX_QUEUED_PER_ORIGIN`]), never the other way.
//!
//! - A reader that reads more slowly than the bridge answers (standard
//!   output, a client) is slowed, not cut off: once its lines waiting and
//!   twice the results it is owed reach half its queue, its input is no
//!   longer handed over (nor, beyond [`motorwire_bridge::MAX_READ_AHEAD`]
//!   lines, read) until it is down to a quarter, and its feedback is left
//!   out meanwhile (counted, said on standard error). A stop it sends is
//!   still read ahead of its other lines and acted on at once.
//! - A reader that takes nothing for [`STALLED_AFTER`] while behind, or
//!   whose queue fills, has stopped reading: a client is disconnected and
//!   its pending commands are cancelled, said on the event stream
//!   (`client_dropped`); standard output stops the joints and ends the
//!   bridge with status 74, as one that fails (closed pipe) does. At the
//!   end of input, what standard output holds is written out first, as
//!   long as it is read.
//! - `unix:PATH` is a socket only its owner can connect to (mode 0600, made
//!   in a private directory first, so there is no moment it is open to
//!   others). `tcp:ADDR` is loopback only and needs `--token-file` (the
//!   first line of a connection is the token) unless `--insecure-no-auth`.
//!   A connection whose first line looks like HTTP is closed without
//!   executing anything, so a web page cannot reach the bridge.

use std::collections::BTreeMap;
use std::fs;
use std::io::{self, BufReader, Read, Write};
use std::net::{Shutdown, SocketAddr, TcpListener, TcpStream, ToSocketAddrs};
use std::os::unix::fs::{DirBuilderExt, FileTypeExt, MetadataExt, PermissionsExt};
use std::os::unix::net::{UnixListener, UnixStream};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::mpsc::{self, Receiver, SyncSender, TrySendError};
use std::sync::{Arc, Condvar, Mutex, PoisonError};
use std::thread;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use motorwire_bridge::route::{Delivery, Owed, Routing};
use motorwire_bridge::{
    Gate, InputSender, Origin, Output, ReadLine, Secret, feed_gated, read_line,
};

/// The origin of standard input's lines.
pub(crate) const STDIN: Origin = Origin(0);

/// Exit status when standard output stopped being read or failed.
pub(crate) const EXIT_OUTPUT_FAILED: u8 = 74;

/// Lines standard output may hold waiting to be written.
const STDOUT_QUEUE: usize = 4096;

/// How long a reader held back (its input no longer read) or with half its
/// queue waiting may go without a byte written to it before it counts as
/// no longer reading: standard output then stops the joints and ends the
/// bridge (74), a client is disconnected. (A pipe takes a write of
/// [`WRITE_CHUNK`] once that much room is free: a reader of standard output
/// that reads less than that in this time is taken as not reading.)
pub(crate) const STALLED_AFTER: Duration = Duration::from_secs(5);

/// The most written to a reader in one call: a reader that reads slowly
/// shows it is reading at least this often.
const WRITE_CHUNK: usize = 4096;

/// The most a socket write waits with nothing taken before it is tried
/// again (so a write taken in part shows as progress).
const SOCKET_WRITE_WAIT: Duration = Duration::from_millis(500);

/// The longest token file read (bytes).
const MAX_TOKEN_FILE: u64 = 4096;

/// Why a line that is the token (again, after a connection's first; or
/// on standard input) is refused: it is not recorded, shown or read.
const TOKEN_AGAIN: &str = "the bridge's token in a line: it is never part of a command (a connection sends it once, first, alone on its line); the line was neither read nor recorded";

/// The `token`, as what no line may carry to the bridge, a recording or
/// the live view.
fn secret(token: Option<&str>) -> Option<Secret<'_>> {
    token.and_then(|t| Secret::new(t, TOKEN_AGAIN))
}

/// The shortest token accepted (bytes).
const MIN_TOKEN: usize = 16;

/// Where lines come from.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) enum Listen {
    /// Standard input; the bridge stops at its end.
    Stdin,
    /// No local input (lines come from the fleet alone); the bridge runs
    /// until a signal.
    Nothing,
    /// A TCP address on loopback.
    Tcp(SocketAddr),
    /// A local socket at a path.
    Unix(PathBuf),
}

/// Parses `--input`: `-`, `tcp:ADDR` (loopback only) or `unix:PATH`.
pub(crate) fn parse_listen(spec: &str) -> Result<Listen, String> {
    if spec == "-" {
        return Ok(Listen::Stdin);
    }
    if spec == "none" {
        return Ok(Listen::Nothing);
    }
    if let Some(path) = spec.strip_prefix("unix:") {
        if path.is_empty() {
            return default_socket(
                std::env::var_os("XDG_RUNTIME_DIR").filter(|d| !d.is_empty()),
                &std::env::temp_dir(),
            )
            .map(Listen::Unix);
        }
        if Path::new(path).parent() == Some(Path::new("/")) {
            // `unix:$XDG_RUNTIME_DIR/motorwire.sock` with the variable unset.
            return Err(format!(
                "--input unix:{path}: a socket at the root of the file system (was a variable such as XDG_RUNTIME_DIR unset?); `--input unix:` alone picks a directory of your own"
            ));
        }
        return Ok(Listen::Unix(PathBuf::from(path)));
    }
    if let Some(addr) = spec.strip_prefix("tcp:") {
        let addrs: Vec<SocketAddr> = addr
            .to_socket_addrs()
            .map_err(|e| format!("--input {spec}: {e}"))?
            .collect();
        let Some(first) = addrs.first().copied() else {
            return Err(format!("--input {spec}: the address resolves to nothing"));
        };
        if let Some(a) = addrs.iter().find(|a| !a.ip().is_loopback()) {
            return Err(format!(
                "--input {spec}: {a} is not a loopback address; the bridge listens on 127.0.0.1 or ::1 only (use unix:PATH for local clients, and a tunnel you trust for remote ones)"
            ));
        }
        return Ok(Listen::Tcp(first));
    }
    Err(format!(
        "--input {spec:?}: expected - (stdin), unix:PATH, tcp:ADDR (e.g. tcp:127.0.0.1:7878) or none (the fleet's commands alone)"
    ))
}

/// The socket of `--input unix:` alone: `motorwire.sock` in `runtime`
/// (`$XDG_RUNTIME_DIR`, this user's own), or, without one, in
/// `<tmp>/motorwire-<uid>`, made with mode 0700; a directory already there
/// must be this user's and open to no one else.
///
/// # Errors
/// Why the directory cannot be used, naming it.
pub(crate) fn default_socket(
    runtime: Option<std::ffi::OsString>,
    tmp: &Path,
) -> Result<PathBuf, String> {
    if let Some(dir) = runtime {
        return Ok(PathBuf::from(dir).join("motorwire.sock"));
    }
    // This process's user: the owner of its /proc entry.
    let uid = fs::metadata("/proc/self")
        .map(|m| m.uid())
        .map_err(|e| format!("--input unix: XDG_RUNTIME_DIR is unset and this user's id cannot be read (/proc/self: {e}); give a path, unix:PATH"))?;
    let dir = tmp.join(format!("motorwire-{uid}"));
    let shown = dir.display();
    match fs::DirBuilder::new().mode(0o700).create(&dir) {
        Ok(()) => {}
        Err(e) if e.kind() == io::ErrorKind::AlreadyExists => {}
        Err(e) => {
            return Err(format!(
                "--input unix: XDG_RUNTIME_DIR is unset, and {shown} cannot be made: {e}; give a path, unix:PATH"
            ));
        }
    }
    let meta = fs::symlink_metadata(&dir).map_err(|e| format!("--input unix: {shown}: {e}"))?;
    if !meta.is_dir() || meta.uid() != uid || meta.mode() & 0o077 != 0 {
        return Err(format!(
            "--input unix: XDG_RUNTIME_DIR is unset, and {shown} is not a directory of this user's that only it can open (mode 0700); remove it or give a path, unix:PATH"
        ));
    }
    Ok(dir.join("motorwire.sock"))
}

/// Reads the token in `path` (given as `flag`, which errors name): at
/// most 4 KiB, trimmed, at least 16 bytes, in a file only its owner can
/// read.
pub(crate) fn read_token(flag: &str, path: &str) -> Result<String, String> {
    let meta = fs::metadata(path).map_err(|e| format!("{flag} {path}: {e}"))?;
    if !meta.is_file() {
        return Err(format!("{flag} {path}: not a regular file"));
    }
    if meta.permissions().mode() & 0o077 != 0 {
        return Err(format!(
            "{flag} {path}: others than its owner can read it (mode {:o}); chmod 600 it",
            meta.permissions().mode() & 0o777
        ));
    }
    let mut text = String::new();
    fs::File::open(path)
        .and_then(|f| f.take(MAX_TOKEN_FILE + 1).read_to_string(&mut text))
        .map_err(|e| format!("{flag} {path}: {e}"))?;
    if text.len() as u64 > MAX_TOKEN_FILE {
        return Err(format!(
            "{flag} {path}: over {MAX_TOKEN_FILE} bytes; a token is one line"
        ));
    }
    let token = text.trim().to_owned();
    if token.len() < MIN_TOKEN || token.contains(char::is_control) {
        return Err(format!(
            "{flag} {path}: the token must be one line of at least {MIN_TOKEN} bytes, with no control characters"
        ));
    }
    Ok(token)
}

/// Whether `a` and `b` are equal, in time that does not depend on where
/// they differ.
fn same_secret(a: &[u8], b: &[u8]) -> bool {
    let mut diff = u8::from(a.len() != b.len());
    for i in 0..a.len().max(b.len()) {
        diff |= a.get(i).copied().unwrap_or(0) ^ b.get(i).copied().unwrap_or(0xFF);
    }
    diff == 0
}

/// Whether `line` looks like the start of an HTTP request (a request line)
/// or one of its headers: a browser or `curl` talking to the bridge.
pub(crate) fn looks_like_http(line: &str) -> bool {
    const METHODS: [&str; 10] = [
        "GET", "POST", "PUT", "DELETE", "HEAD", "OPTIONS", "PATCH", "CONNECT", "TRACE", "PRI",
    ];
    let t = line.trim_start();
    let upper = t.to_ascii_uppercase();
    let mut words = upper.split_whitespace();
    let first = words.next().unwrap_or_default();
    if (METHODS.contains(&first) && words.next().is_some()) || upper.contains("HTTP/") {
        return true;
    }
    // `Name: value` with a header's name (letters, digits and dashes).
    t.split_once(':').is_some_and(|(name, _)| {
        !name.is_empty() && name.chars().all(|c| c.is_ascii_alphanumeric() || c == '-')
    })
}

/// One connection's socket, either kind.
#[derive(Debug)]
enum Conn {
    Tcp(TcpStream),
    Unix(UnixStream),
}

impl Conn {
    fn try_clone(&self) -> io::Result<Self> {
        Ok(match self {
            Self::Tcp(s) => Self::Tcp(s.try_clone()?),
            Self::Unix(s) => Self::Unix(s.try_clone()?),
        })
    }

    fn shutdown(&self) {
        let _ = match self {
            Self::Tcp(s) => s.shutdown(Shutdown::Both),
            Self::Unix(s) => s.shutdown(Shutdown::Both),
        };
    }

    fn shutdown_write(&self) {
        let _ = match self {
            Self::Tcp(s) => s.shutdown(Shutdown::Write),
            Self::Unix(s) => s.shutdown(Shutdown::Write),
        };
    }

    fn set_read_timeout(&self, t: Duration) {
        let _ = match self {
            Self::Tcp(s) => s.set_read_timeout(Some(t)),
            Self::Unix(s) => s.set_read_timeout(Some(t)),
        };
    }

    fn clear_read_timeout(&self) {
        let _ = match self {
            Self::Tcp(s) => s.set_read_timeout(None),
            Self::Unix(s) => s.set_read_timeout(None),
        };
    }

    fn set_write_timeout(&self, t: Duration) {
        let _ = match self {
            Self::Tcp(s) => s.set_write_timeout(Some(t)),
            Self::Unix(s) => s.set_write_timeout(Some(t)),
        };
    }
}

impl Read for Conn {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        match self {
            Self::Tcp(s) => s.read(buf),
            Self::Unix(s) => s.read(buf),
        }
    }
}

impl Write for Conn {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        match self {
            Self::Tcp(s) => s.write(buf),
            Self::Unix(s) => s.write(buf),
        }
    }

    fn flush(&mut self) -> io::Result<()> {
        match self {
            Self::Tcp(s) => s.flush(),
            Self::Unix(s) => s.flush(),
        }
    }
}

/// A connection's reading half, held to a deadline while it
/// authenticates: each read waits at most until the deadline, so a peer
/// dripping a byte at a time cannot hold its place for longer.
struct Timed {
    conn: Conn,
    deadline: Option<Instant>,
}

impl Timed {
    /// No deadline from now on (the connection authenticated).
    fn lift(&mut self) {
        if self.deadline.take().is_some() {
            self.conn.clear_read_timeout();
        }
    }
}

impl Read for Timed {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        if let Some(d) = self.deadline {
            let left = d.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return Err(io::Error::new(io::ErrorKind::TimedOut, "past the deadline"));
            }
            self.conn.set_read_timeout(left);
        }
        self.conn.read(buf)
    }
}

/// Whether `e` is a read that waited past its timeout.
fn timed_out(e: &io::Error) -> bool {
    matches!(
        e.kind(),
        io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut
    )
}

/// Connections authenticating at once, at most: beyond, the one that has
/// been authenticating longest is closed (`too_many_clients`) for the new
/// one, so that a flood of connections cannot keep out a client that sends
/// its token at once. Each has [`ServeConfig::auth_timeout`] to
/// authenticate, and none counts against [`ServeConfig::max_clients`].
pub(crate) const MAX_AUTHENTICATING: usize = 64;

/// Counts a connection as authenticating until done or dropped.
struct Authenticating<'a> {
    router: Option<&'a Router>,
    id: u64,
}

impl Authenticating<'_> {
    fn done(&mut self) {
        if let Some(r) = self.router.take() {
            r.waiting
                .lock()
                .unwrap_or_else(PoisonError::into_inner)
                .retain(|(id, _)| *id != self.id);
            r.authenticating.fetch_sub(1, Ordering::SeqCst);
        }
    }
}

impl Drop for Authenticating<'_> {
    fn drop(&mut self) {
        self.done();
    }
}

/// What a line to a reader (a client, standard output) is.
#[derive(Debug, Clone, Copy)]
enum Sent {
    /// The result of one of its lines; whether a completion line follows.
    Result(bool),
    /// A completion line of one of its lines.
    Arrival,
    /// An event (for a client, sent to it alone: its greeting), or another
    /// input's line: owed nothing, never dropped.
    Event,
    /// Feedback: left out while the reader is behind.
    Feedback,
}

/// How a reader keeps up with its lines: what it has waiting and is owed,
/// and when it last took some. Its input is held back while it is behind
/// ([`Outlet::admit`]) and cut off once it takes nothing for
/// [`STALLED_AFTER`].
#[derive(Debug)]
struct Outlet {
    flow: Mutex<Flow>,
    /// Lines were written out (or the reader was cut off).
    drained: Condvar,
    /// Its queue's length: the high mark is half of it, the low a quarter.
    capacity: usize,
}

#[derive(Debug)]
struct Flow {
    /// Lines in its queue, not yet written out.
    queued: usize,
    /// When bytes were last written to it; with nothing waiting, when a
    /// line was last queued.
    progress: Instant,
    /// Its lines handed to the bridge and not yet answered.
    owed_results: u64,
    /// Completion lines announced and not yet queued.
    owed_arrivals: u64,
    /// Its input is held back until what it is behind by is down to the
    /// low mark.
    held: bool,
    /// It was cut off: no more of its input is handed over.
    cut: bool,
    /// Feedback lines left out while it was behind.
    feedback_dropped: u64,
}

/// What [`Outlet::put`] did with a line.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Put {
    Queued,
    /// Feedback left out: the reader is behind.
    LeftOut,
    /// Nothing written to it for [`STALLED_AFTER`] while it was behind, with
    /// this many lines waiting.
    Stalled(usize),
    /// Its queue is full.
    Full,
    /// Its writer is gone (its connection failed).
    Gone,
}

impl Outlet {
    fn new(capacity: usize) -> Self {
        Self {
            flow: Mutex::new(Flow {
                queued: 0,
                progress: Instant::now(),
                owed_results: 0,
                owed_arrivals: 0,
                held: false,
                cut: false,
                feedback_dropped: 0,
            }),
            drained: Condvar::new(),
            capacity,
        }
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Flow> {
        self.flow.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Half its queue: beyond, its input is held back and its feedback
    /// left out.
    const fn high(&self) -> usize {
        self.capacity / 2
    }

    /// A quarter of its queue: its input is read again once it is no
    /// further behind.
    const fn low(&self) -> usize {
        self.capacity / 4
    }

    /// The lines it has waiting and may yet be sent by what it asked: each
    /// result owed may announce a completion line.
    fn behind(f: &Flow) -> u64 {
        (f.queued as u64)
            .saturating_add(f.owed_results.saturating_mul(2))
            .saturating_add(f.owed_arrivals)
    }

    /// Whether it is behind (held back, or half its queue waiting) and
    /// nothing was written to it for [`STALLED_AFTER`].
    fn stalled(&self, f: &Flow, now: Instant) -> bool {
        f.queued > 0
            && (f.held || f.queued >= self.high())
            && now.saturating_duration_since(f.progress) >= STALLED_AFTER
    }

    /// Queues `line` for the reader without waiting: feedback is left out
    /// while half its queue waits; what it is owed is counted.
    fn put(&self, queue: &SyncSender<Arc<str>>, line: Arc<str>, sent: Sent) -> Put {
        let mut f = self.lock();
        let now = Instant::now();
        if f.queued >= self.high() || f.held {
            if self.stalled(&f, now) {
                return Put::Stalled(f.queued);
            }
            if matches!(sent, Sent::Feedback) && f.queued >= self.high() {
                f.feedback_dropped += 1;
                return Put::LeftOut;
            }
        }
        match queue.try_send(line) {
            Ok(()) => {
                if f.queued == 0 {
                    f.progress = now;
                }
                f.queued += 1;
                match sent {
                    Sent::Result(arrival_follows) => {
                        f.owed_results = f.owed_results.saturating_sub(1);
                        f.owed_arrivals += u64::from(arrival_follows);
                    }
                    Sent::Arrival => f.owed_arrivals = f.owed_arrivals.saturating_sub(1),
                    Sent::Event | Sent::Feedback => {}
                }
                Put::Queued
            }
            Err(TrySendError::Full(_)) => Put::Full,
            Err(TrySendError::Disconnected(_)) => Put::Gone,
        }
    }

    /// Bytes were written to the reader.
    fn progressed(&self) {
        self.lock().progress = Instant::now();
    }

    /// `lines` of its queue were written out: its input is read again once
    /// it is down to the low mark.
    fn written(&self, lines: usize) {
        let mut f = self.lock();
        f.queued = f.queued.saturating_sub(lines);
        f.progress = Instant::now();
        if f.held && Self::behind(&f) <= self.low() as u64 {
            self.drained.notify_all();
        }
    }

    /// It is cut off: its input is no longer handed over.
    fn cut(&self) {
        self.lock().cut = true;
        self.drained.notify_all();
    }

    /// Waits until every line queued was written out (or it was cut off);
    /// `Err` with the lines waiting once nothing was written for
    /// [`STALLED_AFTER`].
    fn wait_empty(&self) -> Result<(), usize> {
        let mut f = self.lock();
        loop {
            if f.queued == 0 || f.cut {
                return Ok(());
            }
            if Instant::now().saturating_duration_since(f.progress) >= STALLED_AFTER {
                return Err(f.queued);
            }
            f = self
                .drained
                .wait_timeout(f, Duration::from_millis(20))
                .unwrap_or_else(PoisonError::into_inner)
                .0;
        }
    }

    /// Feedback lines left out so far.
    fn feedback_dropped(&self) -> u64 {
        self.lock().feedback_dropped
    }

    /// Waits while the reader is behind by the high mark (until it is down
    /// to the low one), then counts one more line of its as owed a result.
    /// `Err` with the lines waiting when it took nothing for
    /// [`STALLED_AFTER`] meanwhile (it is then cut), `Ok(false)` when it
    /// was cut off already.
    fn admit(&self) -> Result<bool, usize> {
        let mut f = self.lock();
        loop {
            if f.cut {
                return Ok(false);
            }
            let behind = Self::behind(&f);
            if f.held && behind <= self.low() as u64 {
                f.held = false;
            } else if !f.held && behind >= self.high() as u64 {
                f.held = true;
            }
            if !f.held {
                f.owed_results += 1;
                return Ok(true);
            }
            f = self
                .drained
                .wait_timeout(f, Duration::from_millis(100))
                .unwrap_or_else(PoisonError::into_inner)
                .0;
            if self.stalled(&f, Instant::now()) {
                f.cut = true;
                return Err(f.queued);
            }
        }
    }

    /// A stop of the reader's is handed over (it never waits): it is owed
    /// its result.
    fn admit_stop(&self) {
        self.lock().owed_results += 1;
    }
}

/// Writes `lines` (whole lines, as many as wait, up to 64 KiB at a time, in
/// writes of at most [`WRITE_CHUNK`]) to `out` until the queue closes or a
/// write fails, telling `outlet` what was written.
fn write_lines(
    out: &mut impl Write,
    lines: &Receiver<Arc<str>>,
    outlet: &Outlet,
) -> io::Result<()> {
    let mut buf = Vec::new();
    while let Ok(line) = lines.recv() {
        buf.clear();
        buf.extend_from_slice(line.as_bytes());
        buf.push(b'\n');
        let mut taken = 1;
        while buf.len() < 64 * 1024 {
            let Ok(more) = lines.try_recv() else { break };
            buf.extend_from_slice(more.as_bytes());
            buf.push(b'\n');
            taken += 1;
        }
        let mut rest = buf.as_slice();
        while !rest.is_empty() {
            let chunk = rest.get(..WRITE_CHUNK.min(rest.len())).unwrap_or(rest);
            match out.write(chunk) {
                Ok(0) => return Err(io::Error::from(io::ErrorKind::WriteZero)),
                Ok(n) => {
                    rest = rest.get(n..).unwrap_or_default();
                    outlet.progressed();
                }
                // A socket's write that waited its time with nothing taken,
                // or a signal: tried again.
                Err(e) if timed_out(&e) || e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) => return Err(e),
            }
        }
        out.flush()?;
        outlet.written(taken);
    }
    Ok(())
}

/// A connected, authenticated client: its queue and its socket.
#[derive(Debug)]
struct Client {
    queue: SyncSender<Arc<str>>,
    /// How it keeps up with its queue.
    outlet: Arc<Outlet>,
    conn: Conn,
    /// Results sent to it.
    delivered: u64,
    /// Completion lines announced (`arrival_follows`) and sent.
    arrivals_owed: u64,
    arrivals_sent: u64,
    /// Once its input ended: how many results it is owed. It is let go
    /// (its queue drained, then its socket closed) when it has them all,
    /// and the completion lines they announced.
    owed: Option<u64>,
    /// It was greeted (`ready` and the state, or `stopping`): everyone's
    /// feedback and events reach it from then on, so its greeting is its
    /// first line; it is not let go before it.
    greeted: bool,
}

impl Client {
    fn settled(&self) -> bool {
        self.greeted
            && self
                .owed
                .is_some_and(|n| self.delivered >= n && self.arrivals_sent >= self.arrivals_owed)
    }
}

/// How the server is set up.
#[derive(Debug, Clone)]
pub(crate) struct ServeConfig {
    /// The token a connection's first line must be (`None`: no token).
    pub(crate) token: Option<String>,
    /// Authenticated connections at once (a stop from one more is still
    /// taken).
    pub(crate) max_clients: usize,
    /// How long a connection has to authenticate (its first line, the
    /// token, or without a token its first command) before it is closed.
    pub(crate) auth_timeout: Duration,
    /// Lines a client may have waiting before it counts as not reading.
    pub(crate) client_queue: usize,
}

/// Routes the engine's outputs to standard output and the clients without
/// ever blocking; see the module's documentation.
#[derive(Debug)]
pub(crate) struct Router {
    input: InputSender,
    stdout: SyncSender<Arc<str>>,
    /// How standard output keeps up with its queue.
    stdout_outlet: Outlet,
    clients: Mutex<BTreeMap<u64, Client>>,
    /// Results go to the clients (a socket input), not to standard output.
    sockets: bool,
    failure: Mutex<Option<String>>,
    input_failure: Mutex<Option<String>>,
    connected: AtomicUsize,
    authenticating: AtomicUsize,
    /// The connections authenticating, oldest first.
    waiting: Mutex<std::collections::VecDeque<(u64, Conn)>>,
    /// Who gets which output: the bridge's routing, with each reader's
    /// own feedback rate (standard output's is standard input's).
    routing: Mutex<Routing>,
}

impl Router {
    /// A router, and the thread that writes standard output.
    pub(crate) fn new(input: InputSender, sockets: bool) -> Arc<Self> {
        let (stdout, lines) = mpsc::sync_channel(STDOUT_QUEUE);
        let router = Arc::new(Self {
            input,
            stdout,
            stdout_outlet: Outlet::new(STDOUT_QUEUE),
            clients: Mutex::default(),
            sockets,
            failure: Mutex::default(),
            input_failure: Mutex::default(),
            connected: AtomicUsize::new(0),
            authenticating: AtomicUsize::new(0),
            waiting: Mutex::default(),
            routing: Mutex::new({
                // Standard output reads standard input's lines.
                let mut r = Routing::default();
                r.add(STDIN);
                r
            }),
        });
        let r = Arc::clone(&router);
        thread::spawn(move || r.write_stdout(&lines));
        router
    }

    /// Why standard output failed, if it did.
    pub(crate) fn failure(&self) -> Option<String> {
        self.failure
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .clone()
    }

    fn fail(&self, why: String) {
        let mut f = self.failure.lock().unwrap_or_else(PoisonError::into_inner);
        if f.is_none() {
            *f = Some(why);
            // Nobody sees the results any more: stop the joints.
            self.input.interrupt();
        }
    }

    fn write_stdout(&self, lines: &Receiver<Arc<str>>) {
        // Locked for each write, not for good: nothing else in the process
        // is kept from standard output.
        let mut out = io::stdout();
        if let Err(e) = write_lines(&mut out, lines, &self.stdout_outlet) {
            self.stdout_outlet.cut();
            self.fail(format!("standard output failed: {e}"));
        }
    }

    /// With standard input as the input: waits until standard output has
    /// written out every line queued for it, or took nothing for
    /// [`STALLED_AFTER`] (then it failed, as not read), or failed.
    pub(crate) fn drain_stdout(&self) {
        if self.sockets || self.failure().is_some() {
            return;
        }
        if let Err(waiting) = self.stdout_outlet.wait_empty() {
            self.stdout_stalled(waiting);
        }
    }

    /// Feedback lines left out of standard output while it was behind.
    pub(crate) fn stdout_feedback_dropped(&self) -> u64 {
        self.stdout_outlet.feedback_dropped()
    }

    /// Standard output took nothing for [`STALLED_AFTER`] while it was
    /// behind, with `waiting` lines queued: the joints are stopped.
    fn stdout_stalled(&self, waiting: usize) {
        self.stdout_outlet.cut();
        self.fail(format!(
            "standard output is not being read ({waiting} lines waiting, nothing written for {} s)",
            STALLED_AFTER.as_secs()
        ));
    }

    /// Takes one output of the engine, with its line (`o.to_json()`, rendered
    /// once by the runner); never waits.
    pub(crate) fn route(&self, o: &Output, line: &Arc<str>) {
        // The bridge's routing decides; this says where that is here:
        // standard output, or the socket clients. Standard output's share
        // of a feedback line is counted under the same lock (once a line).
        let (delivery, stdout_takes) = {
            let mut routing = self.routing.lock().unwrap_or_else(PoisonError::into_inner);
            let delivery = routing.route(o);
            let stdout_takes = match delivery {
                Delivery::Feedback { motor } if !self.sockets => {
                    routing.takes_feedback(STDIN, motor)
                }
                _ => false,
            };
            (delivery, stdout_takes)
        };
        let line = Arc::clone(line);
        match delivery {
            Delivery::ToReader { origin, owed } => {
                let sent = match owed {
                    Owed::Result { arrival_follows } => Sent::Result(arrival_follows),
                    Owed::Arrival => Sent::Arrival,
                    Owed::Greeting => Sent::Event,
                };
                if origin == STDIN || !self.sockets {
                    match owed {
                        // Standard input had it with everyone's.
                        Owed::Greeting => {}
                        _ if origin == STDIN => self.to_stdout(line, sent),
                        _ => self.to_stdout(line, Sent::Event),
                    }
                } else {
                    self.to_client(origin.0, line, sent);
                }
            }
            Delivery::ToEvery => {
                if self.sockets {
                    self.to_every_client(&line, None);
                }
                self.to_stdout(line, Sent::Event);
            }
            Delivery::Feedback { motor } if self.sockets => {
                self.to_every_client(&line, Some(motor));
            }
            Delivery::Feedback { .. } => {
                if stdout_takes {
                    self.to_stdout(line, Sent::Feedback);
                }
            }
        }
    }

    fn to_stdout(&self, line: Arc<str>, sent: Sent) {
        if self.failure().is_some() {
            return; // already failed: nothing can be delivered there
        }
        match self.stdout_outlet.put(&self.stdout, line, sent) {
            Put::Queued | Put::LeftOut => {}
            Put::Stalled(waiting) => self.stdout_stalled(waiting),
            Put::Full => {
                self.stdout_outlet.cut();
                self.fail(format!(
                    "standard output is not being read ({STDOUT_QUEUE} lines waiting)"
                ));
            }
            // Its writer failed, and said why.
            Put::Gone => self.stdout_outlet.cut(),
        }
    }

    /// `sent`: what the line is, counted towards what the client is owed
    /// once its input ends.
    fn to_client(&self, id: u64, line: Arc<str>, sent: Sent) {
        let mut clients = self.clients.lock().unwrap_or_else(PoisonError::into_inner);
        let Some(c) = clients.get_mut(&id) else {
            return; // gone: its lines were cancelled when it went
        };
        match c.outlet.put(&c.queue, line, sent) {
            Put::Queued => {
                match sent {
                    Sent::Result(arrival_follows) => {
                        c.delivered += 1;
                        c.arrivals_owed += u64::from(arrival_follows);
                    }
                    Sent::Arrival => c.arrivals_sent += 1,
                    Sent::Event => c.greeted = true,
                    Sent::Feedback => {}
                }
                if c.settled() {
                    self.remove_client(&mut clients, id); // the writer drains, then closes
                }
            }
            Put::LeftOut => {}
            Put::Stalled(waiting) => {
                self.drop_client(&mut clients, id, &stalled_client(waiting));
            }
            Put::Full => {
                let why = "it stopped reading its results (its queue is full)";
                self.drop_client(&mut clients, id, why);
            }
            Put::Gone => self.drop_client(&mut clients, id, "its connection failed"),
        }
    }

    /// `feedback_of`: the line is that motor's feedback, for the clients
    /// whose rate takes it.
    fn to_every_client(&self, line: &Arc<str>, feedback_of: Option<&str>) {
        let mut clients = self.clients.lock().unwrap_or_else(PoisonError::into_inner);
        let mut gone = Vec::new();
        // Locked for feedback only (an event goes to every client).
        let mut routing =
            feedback_of.map(|_| self.routing.lock().unwrap_or_else(PoisonError::into_inner));
        for (id, c) in clients.iter_mut().filter(|(_, c)| c.greeted) {
            if let (Some(motor), Some(routing)) = (feedback_of, routing.as_mut())
                && !routing.takes_feedback(Origin(*id), motor)
            {
                continue;
            }
            let sent = if feedback_of.is_some() {
                Sent::Feedback
            } else {
                Sent::Event
            };
            match c.outlet.put(&c.queue, Arc::clone(line), sent) {
                Put::Queued | Put::LeftOut => {}
                Put::Stalled(waiting) => gone.push((*id, stalled_client(waiting))),
                Put::Full => {
                    gone.push((*id, "it stopped reading (its queue is full)".to_owned()));
                }
                Put::Gone => gone.push((*id, "its connection failed".to_owned())),
            }
        }
        drop(routing);
        for (id, why) in gone {
            self.drop_client(&mut clients, id, &why);
        }
    }

    fn drop_client(&self, clients: &mut BTreeMap<u64, Client>, id: u64, why: &str) {
        if let Some(c) = self.remove_client(clients, id) {
            c.outlet.cut();
            c.conn.shutdown();
            self.input.drop_origin(Origin(id), why);
        }
    }

    /// A client took nothing for [`STALLED_AFTER`] while it was behind: it
    /// is disconnected (from its input's thread).
    fn client_stalled(&self, id: u64, waiting: usize) {
        let mut clients = self.clients.lock().unwrap_or_else(PoisonError::into_inner);
        self.drop_client(&mut clients, id, &stalled_client(waiting));
    }

    /// Registers an authenticated connection; its writer thread sends its
    /// queue out: whole lines, all that are waiting in one write (in
    /// pieces of [`WRITE_CHUNK`], each one progress).
    /// `greet`: it is greeted by the engine ([`InputSender::greet`], asked
    /// here) before anyone's feedback and events reach it. Returns how it
    /// keeps up, which holds back its input.
    fn add_client(
        &self,
        id: u64,
        conn: Conn,
        queue_len: usize,
        greet: bool,
    ) -> io::Result<Arc<Outlet>> {
        let (queue, lines) = mpsc::sync_channel::<Arc<str>>(queue_len);
        let mut writer = conn.try_clone()?;
        writer.set_write_timeout(SOCKET_WRITE_WAIT);
        let outlet = Arc::new(Outlet::new(queue_len));
        let mut clients = self.clients.lock().unwrap_or_else(PoisonError::into_inner);
        // Known to the routing while it is a client (its feedback rate).
        self.routing
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .add(Origin(id));
        clients.insert(
            id,
            Client {
                queue,
                outlet: Arc::clone(&outlet),
                conn,
                delivered: 0,
                arrivals_owed: 0,
                arrivals_sent: 0,
                owed: None,
                greeted: !greet,
            },
        );
        drop(clients);
        if greet {
            // After it is registered: its greeting finds it.
            self.input.greet(Origin(id));
        }
        let writing = Arc::clone(&outlet);
        thread::spawn(move || {
            // Whole lines only, and as many as are waiting at once (up to
            // 64 KiB): a client reading as fast as it can keeps up with a
            // flood of its own results. A failed write drops its queue: the
            // router sees it gone.
            let _ = write_lines(&mut writer, &lines, &writing);
            let left_out = writing.feedback_dropped();
            if left_out > 0 {
                say(&format!(
                    "motorwire bridge: client {id} fell behind its lines: {left_out} feedback lines were left out"
                ));
            }
        });
        Ok(outlet)
    }

    /// Standard input fed to the bridge, which stops at its end. A line
    /// that holds the `token` (`--token-file`'s, when given) is refused and
    /// withheld, as on a connection: it is never recorded or shown.
    pub(crate) fn serve_stdin(self: &Arc<Self>, token: Option<String>) {
        let r = Arc::clone(self);
        thread::spawn(move || {
            let mut reader = BufReader::new(io::stdin());
            let secret = secret(token.as_deref());
            let gate = StdoutGate(&r);
            if let Err(e) = feed_gated(&r.input, STDIN, &mut reader, true, secret, &gate) {
                *r.input_failure
                    .lock()
                    .unwrap_or_else(PoisonError::into_inner) =
                    Some(format!("reading standard input: {e}"));
            }
            r.input.finish();
        });
    }

    /// Why standard input was given up, if it was (an endless line, a read
    /// error): the bridge finished what it had and stopped the joints.
    pub(crate) fn input_failure(&self) -> Option<String> {
        self.input_failure
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .clone()
    }

    /// Listens on `at` for clients, each one's lines its own origin (from
    /// 1); returns once listening. For a local socket, the path to remove
    /// at the end.
    pub(crate) fn serve(
        self: &Arc<Self>,
        at: &Listen,
        config: ServeConfig,
    ) -> Result<Option<PathBuf>, String> {
        match at {
            Listen::Stdin => {
                self.serve_stdin(config.token);
                Ok(None)
            }
            Listen::Nothing => {
                say(
                    "motorwire bridge: no local input (--input none): lines come from the fleet; a signal ends the bridge",
                );
                Ok(None)
            }
            Listen::Tcp(addr) => {
                let listener =
                    TcpListener::bind(addr).map_err(|e| format!("--input tcp:{addr}: {e}"))?;
                let shown = listener.local_addr().map_or(*addr, |a| a);
                say(&format!("motorwire bridge: listening on tcp:{shown}"));
                let r = Arc::clone(self);
                thread::spawn(move || {
                    r.accept_loop(
                        || {
                            listener.accept().map(|(s, _)| {
                                let _ = s.set_nodelay(true);
                                Conn::Tcp(s)
                            })
                        },
                        &config,
                    );
                });
                Ok(None)
            }
            Listen::Unix(path) => {
                let listener = bind_private(path)?;
                say(&format!(
                    "motorwire bridge: listening on unix:{}",
                    path.display()
                ));
                let r = Arc::clone(self);
                thread::spawn(move || {
                    r.accept_loop(|| listener.accept().map(|(s, _)| Conn::Unix(s)), &config);
                });
                Ok(Some(path.clone()))
            }
        }
    }

    /// Accepts connections until the process ends. Accept errors (out of
    /// descriptors) back off from 10 ms to 1 s and are never spun on; a
    /// thread that cannot be started closes its connection and backs off
    /// the same way. Trouble is reported when it starts, then at most every
    /// 10 s with how many attempts failed meanwhile, so a bridge that stays
    /// short of descriptors does not fill its standard error.
    fn accept_loop(
        self: &Arc<Self>,
        mut accept: impl FnMut() -> io::Result<Conn>,
        config: &ServeConfig,
    ) {
        let mut next = 1u64;
        let mut trouble = Trouble::default();
        loop {
            let conn = match accept() {
                Ok(c) => c,
                Err(e) => {
                    trouble.failed("accepting a connection", &e);
                    continue;
                }
            };
            let id = next;
            next += 1;
            if self.authenticating.load(Ordering::SeqCst) >= MAX_AUTHENTICATING {
                let oldest = self
                    .waiting
                    .lock()
                    .unwrap_or_else(PoisonError::into_inner)
                    .pop_front();
                if let Some((_, old)) = oldest {
                    // Its thread's read ends, and gives its place back.
                    refuse_now(
                        old,
                        "too_many_clients",
                        &format!(
                            "closed unauthenticated: {MAX_AUTHENTICATING} connections were authenticating, this one the longest"
                        ),
                    );
                }
            }
            self.authenticating.fetch_add(1, Ordering::SeqCst);
            if let Ok(c) = conn.try_clone() {
                self.waiting
                    .lock()
                    .unwrap_or_else(PoisonError::into_inner)
                    .push_back((id, c));
            }
            let r = Arc::clone(self);
            let config = config.clone();
            // The connection is moved into the thread only once it runs:
            // should it not start, it is still here to be refused.
            let (hand, take) = mpsc::sync_channel::<Conn>(1);
            let started = thread::Builder::new().spawn(move || {
                if let Ok(conn) = take.recv() {
                    r.client(id, conn, &config);
                }
            });
            match started {
                Ok(_) => {
                    let _ = hand.send(conn);
                    trouble.ok();
                }
                Err(e) => {
                    drop(Authenticating {
                        router: Some(self),
                        id,
                    });
                    refuse(
                        conn,
                        "unavailable",
                        "the bridge could not start a thread for this connection; try again",
                    );
                    trouble.failed("starting a connection's thread", &e);
                }
            }
        }
    }

    /// One connection: authenticated by its first line (within
    /// [`ServeConfig::auth_timeout`]), then fed. Beyond
    /// [`ServeConfig::max_clients`] authenticated connections, a client's
    /// stop is still taken (its first command, within the timeout too);
    /// anything else is refused `too_many_clients`.
    fn client(&self, id: u64, conn: Conn, config: &ServeConfig) {
        let mut authenticating = Authenticating {
            router: Some(self),
            id,
        };
        let read_half = match conn.try_clone() {
            Ok(r) => r,
            Err(e) => {
                authenticating.done();
                refuse(
                    conn,
                    "unavailable",
                    &format!("the bridge could not take this connection ({e}); try again"),
                );
                return;
            }
        };
        let mut reader = BufReader::new(Timed {
            conn: read_half,
            deadline: Some(Instant::now() + config.auth_timeout),
        });
        // A refused connection is no longer authenticating: its place is
        // given back before the refusal's linger.
        let late = |conn: Conn, authenticating: &mut Authenticating<'_>| {
            authenticating.done();
            refuse(
                conn,
                "unauthorized",
                &format!(
                    "nothing authenticated within {} ms; the connection is closed",
                    config.auth_timeout.as_millis()
                ),
            );
        };
        // A local socket is its owner's alone (mode 0600, in a private
        // directory): without a token, connecting is authenticating. The
        // client is registered and greeted at once, so one that only
        // listens sees `ready` and the state; its lines are read as they
        // come. (Full: as below, a stop is still taken.)
        if matches!(conn, Conn::Unix(_))
            && config.token.is_none()
            && let Some(slot) = self.slot(config)
        {
            reader.get_mut().lift();
            authenticating.done();
            let _slot = slot;
            let Ok(outlet) = self.add_client(id, conn, config.client_queue, true) else {
                return;
            };
            self.feed_rest(id, &outlet, &mut reader, None);
            return;
        }
        // The first line that is not blank (HTTP allows empty lines before
        // its request line).
        let mut first_read = read_line(&mut reader, self.input.max_line());
        for _ in 0..16 {
            match &first_read {
                Ok(ReadLine::Line(s)) if s.trim().is_empty() => {
                    first_read = read_line(&mut reader, self.input.max_line())
                }
                _ => break,
            }
        }
        let first = match first_read {
            Ok(ReadLine::Line(s)) if s.trim().is_empty() => {
                authenticating.done();
                refuse(conn, "unauthorized", "only blank lines");
                return;
            }
            Ok(ReadLine::Line(s)) => s,
            Err(e) if timed_out(&e) => return late(conn, &mut authenticating),
            Ok(ReadLine::Partial(_) | ReadLine::End) | Err(_) => return,
            Ok(unreadable @ (ReadLine::TooLong { .. } | ReadLine::NotUtf8 { .. })) => {
                if config.token.is_some() {
                    authenticating.done();
                    refuse(conn, "unauthorized", "the first line could not be read");
                    return;
                }
                reader.get_mut().lift();
                authenticating.done();
                let Some(_slot) = self.slot(config) else {
                    return refuse_full(conn, config);
                };
                let Ok(outlet) = self.add_client(id, conn, config.client_queue, true) else {
                    return;
                };
                // Answered as any unreadable line is (and a stop if it
                // names one).
                let origin = Origin(id);
                let gate = ClientGate {
                    router: self,
                    id,
                    outlet: &outlet,
                };
                match &unreadable {
                    ReadLine::TooLong {
                        names_stop: true, ..
                    }
                    | ReadLine::NotUtf8 {
                        names_stop: true, ..
                    } => gate.admit_stop(),
                    _ => {
                        if !gate.admit() {
                            return;
                        }
                    }
                }
                match unreadable {
                    ReadLine::TooLong {
                        names_stop,
                        head,
                        length,
                    } => {
                        let why = self.input.too_long();
                        self.input.unreadable(origin, why, names_stop, head, length);
                    }
                    ReadLine::NotUtf8 {
                        names_stop,
                        head,
                        length,
                    } => self.input.unreadable(
                        origin,
                        "the line is not UTF-8",
                        names_stop,
                        head,
                        length,
                    ),
                    _ => self.input.refused(origin, "the line is not UTF-8"),
                }
                self.feed_rest(id, &outlet, &mut reader, None);
                return;
            }
        };
        if looks_like_http(&first) {
            authenticating.done();
            refuse(
                conn,
                "http_refused",
                "this is not an HTTP server; nothing was executed",
            );
            return;
        }
        let first_is_command = match &config.token {
            Some(token) => {
                if !same_secret(first.trim().as_bytes(), token.as_bytes()) {
                    authenticating.done();
                    refuse(
                        conn,
                        "unauthorized",
                        "the first line must be the bridge's token",
                    );
                    return;
                }
                false
            }
            None => true,
        };
        let slot = self.slot(config);
        if slot.is_none() {
            // Full: only a stop is taken, its first command, and then the
            // connection ends once it has its result.
            let command = if first_is_command {
                Some(first)
            } else {
                match read_line(&mut reader, self.input.max_line()) {
                    Ok(ReadLine::Line(s)) => Some(s),
                    Err(e) if timed_out(&e) => return late(conn, &mut authenticating),
                    _ => None,
                }
            };
            authenticating.done();
            let Some(stop) = command.filter(|c| motorwire_bridge::asks_for_stop(c)) else {
                return refuse_full(conn, config);
            };
            self.connected.fetch_add(1, Ordering::SeqCst);
            let _over = Slot(&self.connected);
            // Only its stop is taken: not greeted.
            let Ok(outlet) = self.add_client(id, conn, config.client_queue, false) else {
                return;
            };
            outlet.admit_stop();
            self.input.line(Origin(id), stop);
            self.let_go(id);
            return;
        }
        reader.get_mut().lift();
        authenticating.done();
        let _slot = slot;
        let Ok(outlet) = self.add_client(id, conn, config.client_queue, true) else {
            return;
        };
        if first_is_command {
            let gate = ClientGate {
                router: self,
                id,
                outlet: &outlet,
            };
            if motorwire_bridge::asks_for_stop(first.trim()) {
                gate.admit_stop();
            } else if !gate.admit() {
                return;
            }
            self.input.line(Origin(id), first);
        }
        self.feed_rest(id, &outlet, &mut reader, config.token.as_deref());
    }

    /// A place among the authenticated clients, if one is free: held until
    /// the returned guard drops.
    fn slot(&self, config: &ServeConfig) -> Option<Slot<'_>> {
        if self.connected.fetch_add(1, Ordering::SeqCst) >= config.max_clients {
            self.connected.fetch_sub(1, Ordering::SeqCst);
            return None;
        }
        Some(Slot(&self.connected))
    }

    /// Feeds the rest of a client's lines, held back while it is behind on
    /// its results (`outlet`); lets it go once it has all its results. A
    /// line that holds the `token` again (alone or inside it) is refused
    /// and withheld: neither the recording nor the live view ever holds
    /// the token.
    fn feed_rest(
        &self,
        id: u64,
        outlet: &Outlet,
        reader: &mut BufReader<Timed>,
        token: Option<&str>,
    ) {
        let gate = ClientGate {
            router: self,
            id,
            outlet,
        };
        // A client that goes away mid-line: its partial line is not taken.
        let _ = feed_gated(&self.input, Origin(id), reader, false, secret(token), &gate);
        self.let_go(id);
    }

    /// A client's input ended: it is let go once it has all its results.
    fn let_go(&self, id: u64) {
        let owed = self.input.lines_of(Origin(id));
        self.input.forget(Origin(id));
        // Its results still go out (it may have closed only its sending
        // side); it is let go once it has them all.
        let mut clients = self.clients.lock().unwrap_or_else(PoisonError::into_inner);
        if let Some(c) = clients.get_mut(&id) {
            c.owed = Some(owed);
            if c.settled() {
                self.remove_client(&mut clients, id);
            }
        }
    }

    /// Client `id` taken out of `clients`, its feedback rate forgotten
    /// (nothing of a client is kept once it is gone).
    fn remove_client(&self, clients: &mut BTreeMap<u64, Client>, id: u64) -> Option<Client> {
        self.routing
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .forget(Origin(id));
        clients.remove(&id)
    }
}

/// Why a client that took nothing for [`STALLED_AFTER`] while behind was
/// disconnected, with the lines it had waiting.
fn stalled_client(waiting: usize) -> String {
    format!(
        "it stopped reading its results ({waiting} lines waiting, none read for {} s)",
        STALLED_AFTER.as_secs()
    )
}

/// Standard input's lines go on while standard output keeps up: held back
/// while it is behind, cut off (the joints stopped, 74) once it took
/// nothing for [`STALLED_AFTER`].
struct StdoutGate<'a>(&'a Router);

impl Gate for StdoutGate<'_> {
    fn admit(&self) -> bool {
        match self.0.stdout_outlet.admit() {
            Ok(go) => go,
            Err(waiting) => {
                self.0.stdout_stalled(waiting);
                false
            }
        }
    }

    fn admit_stop(&self) {
        self.0.stdout_outlet.admit_stop();
    }
}

/// A client's lines go on while it keeps up with its results: held back
/// while it is behind, disconnected once it took nothing for
/// [`STALLED_AFTER`].
struct ClientGate<'a> {
    router: &'a Router,
    id: u64,
    outlet: &'a Outlet,
}

impl Gate for ClientGate<'_> {
    fn admit(&self) -> bool {
        match self.outlet.admit() {
            Ok(go) => go,
            Err(waiting) => {
                self.router.client_stalled(self.id, waiting);
                false
            }
        }
    }

    fn admit_stop(&self) {
        self.outlet.admit_stop();
    }
}

/// Holds one place among the authenticated clients until dropped.
struct Slot<'a>(&'a AtomicUsize);

impl Drop for Slot<'_> {
    fn drop(&mut self) {
        self.0.fetch_sub(1, Ordering::SeqCst);
    }
}

/// Refused for room: every authenticated place is taken.
fn refuse_full(conn: Conn, config: &ServeConfig) {
    refuse(
        conn,
        "too_many_clients",
        &format!(
            "the bridge serves {} clients at once (a stop is still taken)",
            config.max_clients
        ),
    );
}

/// A run of failures of the accept loop: reported when it starts, then at
/// most every [`Trouble::EVERY`] with a count, and its end once; each
/// failure backs off (10 ms doubling to 1 s).
#[derive(Debug, Default)]
struct Trouble {
    backoff: Duration,
    /// When the run was last reported, while it lasts.
    said: Option<Instant>,
    /// Failures since then.
    unsaid: u64,
}

impl Trouble {
    const EVERY: Duration = Duration::from_secs(10);

    fn failed(&mut self, doing: &str, e: &io::Error) {
        match self.said {
            Some(at) if at.elapsed() < Self::EVERY => self.unsaid += 1,
            Some(_) => {
                say(&format!(
                    "motorwire bridge: {doing} failed: {e}; {} more failures in the last {} s; retrying with back-off",
                    self.unsaid,
                    Self::EVERY.as_secs()
                ));
                self.said = Some(Instant::now());
                self.unsaid = 0;
            }
            None => {
                say(&format!(
                    "motorwire bridge: {doing} failed: {e}; retrying with back-off"
                ));
                self.said = Some(Instant::now());
            }
        }
        self.backoff = (self.backoff * 2).clamp(Duration::from_millis(10), Duration::from_secs(1));
        thread::sleep(self.backoff);
    }

    /// A connection was taken: the back-off starts again from 10 ms. The
    /// run is reported over once a second has passed without a failure
    /// reported (a connection at a time taken between failures is still
    /// the same run).
    fn ok(&mut self) {
        self.backoff = Duration::ZERO;
        if self
            .said
            .is_some_and(|at| at.elapsed() >= Duration::from_secs(1))
        {
            say(&format!(
                "motorwire bridge: accepting connections again ({} more failures since the last report)",
                self.unsaid
            ));
            self.said = None;
            self.unsaid = 0;
        }
    }
}

/// A line on standard error; a broken standard error is ignored.
fn say(msg: &str) {
    let _ = writeln!(io::stderr(), "{msg}");
}

/// One error line, then the connection closed.
fn refuse(mut conn: Conn, kind: &str, message: &str) {
    conn.set_write_timeout(Duration::from_millis(200));
    let line = serde_json::json!({
        "ok": false,
        "error": { "kind": kind, "rule": kind, "message": message },
    });
    let _ = conn.write_all(format!("{line}\n").as_bytes());
    // A lingering close: what the peer still sends is read and dropped
    // (at most 64 KiB, 200 ms), so closing does not reset the connection
    // and discard the error line before the peer reads it.
    conn.shutdown_write();
    // 200 ms in all: a peer dripping bytes cannot hold the thread longer.
    let end = Instant::now() + Duration::from_millis(200);
    let mut sink = [0u8; 4096];
    let mut left: usize = 64 * 1024;
    while left > 0 {
        let wait = end.saturating_duration_since(Instant::now());
        if wait.is_zero() {
            break;
        }
        conn.set_read_timeout(wait);
        match conn.read(&mut sink) {
            Ok(0) | Err(_) => break,
            Ok(n) => left = left.saturating_sub(n),
        }
    }
    conn.shutdown();
}

/// One error line, then the connection closed at once, both ways (the
/// accept loop cannot wait for the peer; a thread reading it wakes and
/// ends; what the peer sent unread may reset it).
fn refuse_now(mut conn: Conn, kind: &str, message: &str) {
    conn.set_write_timeout(Duration::from_millis(50));
    let line = serde_json::json!({
        "ok": false,
        "error": { "kind": kind, "rule": kind, "message": message },
    });
    let _ = conn.write_all(format!("{line}\n").as_bytes());
    conn.shutdown();
}

/// Binds a local socket at `path` that only this user can connect to: it
/// is made in a new directory of mode 0700, given mode 0600, then moved to
/// `path`. A stale socket at `path` (nothing listening) is replaced; a
/// live one or any other file is an error.
fn bind_private(path: &Path) -> Result<UnixListener, String> {
    let shown = path.display();
    if let Ok(meta) = fs::symlink_metadata(path) {
        if !meta.file_type().is_socket() {
            return Err(format!(
                "--input unix:{shown}: the path exists and is not a socket"
            ));
        }
        if UnixStream::connect(path).is_ok() {
            return Err(format!(
                "--input unix:{shown}: another process is listening there"
            ));
        }
        fs::remove_file(path).map_err(|e| format!("--input unix:{shown}: {e}"))?;
    }
    let parent = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let nanos = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.subsec_nanos());
    let dir = parent.join(format!(".motorwire-{}-{nanos}", std::process::id()));
    fs::DirBuilder::new()
        .mode(0o700)
        .create(&dir)
        .map_err(|e| format!("--input unix:{shown}: making {}: {e}", dir.display()))?;
    let inner = dir.join("s");
    let result = UnixListener::bind(&inner)
        .and_then(|l| {
            fs::set_permissions(&inner, fs::Permissions::from_mode(0o600))?;
            fs::rename(&inner, path)?;
            Ok(l)
        })
        .map_err(|e| format!("--input unix:{shown}: {e}"));
    let _ = fs::remove_file(&inner);
    let _ = fs::remove_dir(&dir);
    result
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    /// A reader behind by half its queue (lines waiting, and twice the
    /// results it is owed) has its input held back until it is down to a
    /// quarter; feedback is left out (counted) while half its queue waits,
    /// never a result or an event.
    #[test]
    fn a_reader_behind_is_held_back_until_it_catches_up() {
        let outlet = Arc::new(Outlet::new(16));
        let (queue, lines) = mpsc::sync_channel::<Arc<str>>(16);
        // Four lines owed: eight behind, the high mark.
        for _ in 0..4 {
            assert_eq!(outlet.admit(), Ok(true));
        }
        let (tx, admitted) = mpsc::channel();
        let waiter = {
            let outlet = Arc::clone(&outlet);
            thread::spawn(move || {
                let _ = tx.send(outlet.admit());
            })
        };
        assert!(
            admitted.recv_timeout(Duration::from_millis(300)).is_err(),
            "the fifth line waits"
        );
        let line: Arc<str> = Arc::from("{}");
        for _ in 0..4 {
            assert_eq!(
                outlet.put(&queue, Arc::clone(&line), Sent::Result(false)),
                Put::Queued
            );
        }
        // Four waiting, nothing owed: down to the low mark once it is
        // written out.
        for _ in 0..2 {
            let _ = lines.recv();
        }
        outlet.written(2);
        assert_eq!(admitted.recv_timeout(Duration::from_secs(10)), Ok(Ok(true)));
        waiter.join().unwrap();
        // Half the queue waiting: feedback is left out, events are not.
        for _ in 0..6 {
            assert_eq!(
                outlet.put(&queue, Arc::clone(&line), Sent::Event),
                Put::Queued
            );
        }
        assert_eq!(
            outlet.put(&queue, Arc::clone(&line), Sent::Feedback),
            Put::LeftOut
        );
        assert_eq!(
            outlet.put(&queue, Arc::clone(&line), Sent::Arrival),
            Put::Queued
        );
        assert_eq!(outlet.feedback_dropped(), 1);
    }

    /// A reader behind that took nothing for [`STALLED_AFTER`] is stalled,
    /// both to the router (a line for it) and to its input (held back); a
    /// reader that takes a little now and then is not.
    #[test]
    fn a_reader_behind_that_takes_nothing_is_stalled() {
        let outlet = Outlet::new(16);
        let (queue, _lines) = mpsc::sync_channel::<Arc<str>>(16);
        let line: Arc<str> = Arc::from("{}");
        for _ in 0..8 {
            assert_eq!(
                outlet.put(&queue, Arc::clone(&line), Sent::Event),
                Put::Queued
            );
        }
        outlet.lock().progress = Instant::now()
            .checked_sub(STALLED_AFTER - Duration::from_millis(500))
            .unwrap();
        assert_eq!(
            outlet.put(&queue, Arc::clone(&line), Sent::Feedback),
            Put::LeftOut
        );
        outlet.progressed();
        outlet.lock().progress -= STALLED_AFTER;
        assert_eq!(
            outlet.put(&queue, Arc::clone(&line), Sent::Event),
            Put::Stalled(8)
        );
        assert_eq!(outlet.admit(), Err(8));
        assert_eq!(outlet.admit(), Ok(false), "cut off");
        // Nothing waiting: nothing to take, however long ago the last line.
        let idle = Outlet::new(16);
        idle.lock().progress -= STALLED_AFTER * 2;
        assert_eq!(idle.put(&queue, line, Sent::Event), Put::Queued);
    }

    #[test]
    fn http_is_recognised_and_json_is_not() {
        for l in [
            "POST / HTTP/1.1",
            "GET /x HTTP/1.0",
            "OPTIONS * HTTP/1.1",
            "Host: 127.0.0.1:7878",
            "Content-Type: application/json",
            "PRI * HTTP/2.0",
            "post / http/1.1",
            "POST\t/\tHTTP/1.1",
            "Get /",
        ] {
            assert!(looks_like_http(l), "{l}");
        }
        for l in [
            r#"{"emergency_stop": true}"#,
            r#"{"motor_id":"elbow","timestamp":1}"#,
            "a-token-of-sixteen-bytes",
        ] {
            assert!(!looks_like_http(l), "{l}");
        }
    }

    #[test]
    fn secrets_compare_whole() {
        assert!(same_secret(b"0123456789abcdef", b"0123456789abcdef"));
        assert!(!same_secret(b"0123456789abcdef", b"0123456789abcdeF"));
        assert!(!same_secret(b"0123456789abcdef", b"0123456789abcde"));
        assert!(!same_secret(b"", b"\xff"));
        assert!(same_secret(b"", b""));
    }

    #[test]
    fn unix_alone_is_the_runtime_directory_or_a_private_one_of_this_user() {
        let tmp = std::env::temp_dir().join(format!("mw-default-socket-{}", std::process::id()));
        let _ = fs::remove_dir_all(&tmp);
        fs::create_dir_all(&tmp).unwrap();
        assert_eq!(
            default_socket(Some("/run/user/7".into()), &tmp).unwrap(),
            PathBuf::from("/run/user/7/motorwire.sock")
        );
        let uid = fs::metadata("/proc/self").unwrap().uid();
        let dir = tmp.join(format!("motorwire-{uid}"));
        assert_eq!(
            default_socket(None, &tmp).unwrap(),
            dir.join("motorwire.sock")
        );
        let mode = fs::metadata(&dir).unwrap().mode() & 0o777;
        assert_eq!(mode, 0o700);
        // Again: the directory is there, and still fine.
        assert_eq!(
            default_socket(None, &tmp).unwrap(),
            dir.join("motorwire.sock")
        );
        // Opened to others: refused, naming it.
        fs::set_permissions(&dir, fs::Permissions::from_mode(0o755)).unwrap();
        assert_eq!(
            default_socket(None, &tmp).unwrap_err(),
            format!(
                "--input unix: XDG_RUNTIME_DIR is unset, and {} is not a directory of this user's that only it can open (mode 0700); remove it or give a path, unix:PATH",
                dir.display()
            )
        );
        // A file in its place: refused too.
        fs::remove_dir(&dir).unwrap();
        fs::write(&dir, "").unwrap();
        assert!(default_socket(None, &tmp).is_err());
        // A temporary directory that cannot hold it: named.
        let err = default_socket(None, Path::new("/proc/self/nonexistent")).unwrap_err();
        assert!(err.contains("/proc/self/nonexistent/motorwire-"), "{err}");
        let _ = fs::remove_dir_all(&tmp);
    }

    #[test]
    fn only_loopback_addresses_are_listened_on() {
        assert_eq!(
            parse_listen("tcp:127.0.0.1:0").unwrap(),
            Listen::Tcp("127.0.0.1:0".parse().unwrap())
        );
        assert_eq!(
            parse_listen("tcp:0.0.0.0:7878").unwrap_err(),
            "--input tcp:0.0.0.0:7878: 0.0.0.0:7878 is not a loopback address; the bridge listens on 127.0.0.1 or ::1 only (use unix:PATH for local clients, and a tunnel you trust for remote ones)"
        );
        assert!(parse_listen("udp:1").is_err());
        assert_eq!(
            parse_listen("unix:/run/x.sock").unwrap(),
            Listen::Unix(PathBuf::from("/run/x.sock"))
        );
        assert_eq!(parse_listen("none").unwrap(), Listen::Nothing);
        assert_eq!(
            parse_listen("unix:/motorwire.sock").unwrap_err(),
            "--input unix:/motorwire.sock: a socket at the root of the file system (was a variable such as XDG_RUNTIME_DIR unset?); `--input unix:` alone picks a directory of your own"
        );
        assert_eq!(parse_listen("-").unwrap(), Listen::Stdin);
        assert_eq!(
            parse_listen("stdin").unwrap_err(),
            r#"--input "stdin": expected - (stdin), unix:PATH, tcp:ADDR (e.g. tcp:127.0.0.1:7878) or none (the fleet's commands alone)"#
        );
    }
}
