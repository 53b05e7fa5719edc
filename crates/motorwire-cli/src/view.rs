//! `motorwire bridge --view ADDR`: a live view of the session in a
//! browser. One page (its script and style inside it, no external asset)
//! and one Server-Sent Events stream: the bus map's motors with their
//! units and limits, then every input and output line as it happens, each
//! with its time (seconds from the view's start). The page plots the last
//! 30 s of each motor and marks the events; it only reads.
//!
//! Never in the bridge's way: the bridge hands each line to a bounded
//! queue and goes on ([`ViewTap`]); a thread of the view's own renders
//! them and hands them to each page's own thread, through a queue of
//! [`PAGE_QUEUE`] lines: a page that does not keep up (its queue full) is
//! cut, and a page that does not read holds only its own thread, never
//! the other pages. Bound: at most [`MAX_PAGES`] pages at once, a request's head at
//! most 8 KiB read within 2 s.

use std::collections::VecDeque;
use std::io::{BufRead, BufReader, Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError, SyncSender, TrySendError};
use std::thread;
use std::time::{Duration, Instant};

use motorwire_bridge::tap::Tap;
use motorwire_bridge::{Origin, Output};
use motorwire_translate::BusMap;
use serde_json::{Value, json};

/// The page.
const PAGE: &str = include_str!("view/index.html");

/// Pages served at once, at most.
pub(crate) const MAX_PAGES: usize = 16;

/// Requests being read at once, at most.
const MAX_REQUESTS: usize = 32;

/// Lines waiting for the view's thread, at most; beyond, dropped (and
/// counted in the next line the pages get).
const QUEUE: usize = 4096;

/// Of an input line, the view keeps this much (the page shows 300
/// characters of it): a client's long lines cost the view little.
const MAX_INPUT_KEPT: usize = 4096;

/// A rendered line longer than this is not sent to the pages (counted as
/// dropped).
const MAX_RENDERED: usize = 64 * 1024;

/// The history a page that opens gets, at most, in bytes.
const HISTORY_BYTES: usize = 16 * 1024 * 1024;

/// How much of the session a page that opens gets at once.
const HISTORY: Duration = Duration::from_secs(30);

/// Lines kept for a page that opens, at most.
const HISTORY_LINES: usize = 100_000;

/// A request's head, at most.
const MAX_HEAD: usize = 8192;

/// The pause after an accept that failed (no file descriptor left).
const ACCEPT_BACKOFF: Duration = Duration::from_millis(50);

/// Lines waiting for one page, at most: a page further behind is cut.
const PAGE_QUEUE: usize = 4096;

/// One line for the pages.
#[derive(Debug)]
enum Item {
    In {
        at: Instant,
        origin: Origin,
        number: u64,
        text: String,
    },
    /// An output as its line: the runner's, rendered once for its sink
    /// (shared, not rendered again).
    Out {
        at: Instant,
        /// The client it went to, when it was one client's.
        to: Option<u64>,
        line: Arc<str>,
        /// It is the `ready` event (kept for pages that open later).
        ready: bool,
    },
}

/// What the bridge tells the view: queued, never waited on.
#[derive(Debug)]
pub(crate) struct ViewTap {
    queue: SyncSender<Item>,
    dropped: Arc<AtomicU64>,
}

impl ViewTap {
    fn put(&self, item: Item) {
        match self.queue.try_send(item) {
            Ok(()) => {}
            Err(TrySendError::Full(_) | TrySendError::Disconnected(_)) => {
                self.dropped.fetch_add(1, Ordering::Relaxed);
            }
        }
    }
}

impl Tap for ViewTap {
    fn input(&self, at: Instant, origin: Origin, number: u64, text: &str) {
        let mut end = text.len().min(MAX_INPUT_KEPT);
        while !text.is_char_boundary(end) {
            end -= 1;
        }
        self.put(Item::In {
            at,
            origin,
            number,
            text: text.get(..end).unwrap_or_default().to_owned(),
        });
    }

    /// An output told without its line (a runner that does not render):
    /// rendered here.
    fn output(&self, at: Instant, output: &Output) {
        self.output_line(at, output, &Arc::from(output.to_json()));
    }

    fn output_line(&self, at: Instant, output: &Output, line: &Arc<str>) {
        self.put(Item::Out {
            at,
            to: output.reader().map(|r| r.0),
            line: Arc::clone(line),
            ready: matches!(output, Output::Event(motorwire_bridge::Event::Ready { .. })),
        });
    }
}

/// Where the view listens, and who may look.
#[derive(Debug, Clone)]
pub(crate) struct ViewConfig {
    pub(crate) addr: SocketAddr,
    /// Required in the page's address (`?token=...`) when set.
    pub(crate) token: Option<String>,
    /// Names the view also answers to in a request's `Host` (and its
    /// `Origin`), besides the address it listens on (`--view-host`).
    pub(crate) hosts: Vec<String>,
}

/// Who the view answers: requests for its own address (or a name it was
/// given), never one a browser sent on another site's behalf.
///
/// A page of another site can reach a loopback view two ways: by a name
/// of its own that it makes resolve to 127.0.0.1 (DNS rebinding: the
/// browser then sends `Host: that.name:PORT` and lets the page read the
/// answer as its own), or by a request sent across sites (the browser
/// sends `Origin` and `Sec-Fetch-Site`). Both are refused.
#[derive(Debug, Clone)]
struct Answers {
    /// The address listened on (its port is every `Host`'s port).
    addr: SocketAddr,
    /// `--view-host` names, lowercase.
    names: Vec<String>,
}

impl Answers {
    /// Whether a `Host` header's value (or an `Origin`'s authority) names
    /// this view: its port is the view's (80 when none is given), and its
    /// name is the address listened on (any IP address when that is
    /// unspecified: an address written as a number cannot be rebound),
    /// `localhost` on a loopback or unspecified address, or a name given
    /// with `--view-host`.
    fn host(&self, host: &str) -> bool {
        // `[v6]:port`, `[v6]`, `name:port` or `name`.
        let (name, port, bracketed) = match host.strip_prefix('[') {
            Some(rest) => {
                let Some((inner, after)) = rest.split_once(']') else {
                    return false;
                };
                let port = match after {
                    "" => Some(80),
                    p => p.strip_prefix(':').and_then(|p| p.parse::<u16>().ok()),
                };
                (inner, port, true)
            }
            None => match host.split_once(':') {
                Some((name, port)) => (name, port.parse::<u16>().ok(), false),
                None => (host, Some(80), false),
            },
        };
        if port != Some(self.addr.port()) || name.is_empty() {
            return false;
        }
        let listened = self.addr.ip();
        match name.parse::<std::net::IpAddr>() {
            Ok(ip) if ip.is_ipv6() == bracketed => ip == listened || listened.is_unspecified(),
            Ok(_) => false,
            Err(_) if bracketed => false,
            Err(_) => {
                let name = name.to_ascii_lowercase();
                (name == "localhost" && (listened.is_loopback() || listened.is_unspecified()))
                    || self.names.contains(&name)
            }
        }
    }

    /// Why a request with this head is refused, or `None`.
    fn refuses(&self, head: &Head) -> Option<&'static str> {
        let Some(host) = head.host.as_deref() else {
            return Some("a request without Host (the view answers only its own address)");
        };
        if !self.host(host) {
            return Some("Host is not this view's address (give the name with --view-host)");
        }
        if let Some(origin) = head.origin.as_deref() {
            let own = origin.strip_prefix("http://").is_some_and(|a| self.host(a));
            if !own {
                return Some("a request from another site (Origin)");
            }
        }
        if let Some(site) = head.fetch_site.as_deref()
            && site != "same-origin"
            && site != "none"
        {
            return Some("a request from another site (Sec-Fetch-Site)");
        }
        None
    }
}

/// The view, serving.
#[derive(Debug)]
pub(crate) struct View {
    /// Where it listens (the port chosen when 0 was asked for).
    pub(crate) addr: SocketAddr,
    pub(crate) tap: Arc<ViewTap>,
}

/// The map's motors as the page needs them: name, dialect, what its
/// value is, its unit, its limits.
fn motors_json(map: &BusMap) -> Value {
    let motors: Vec<Value> = map
        .motors()
        .map(|m| {
            // As the plots show it.
            let (shown, (lo, hi)) = crate::chart::Shown::of(m);
            json!({
                "motor_id": m.name,
                "dialect": m.target.dialect(),
                "quantity": shown.quantity(),
                "unit": shown.unit(),
                "min_position": lo,
                "max_position": hi,
                "max_velocity": m.limits.max_velocity,
            })
        })
        .collect();
    Value::Array(motors)
}

/// Starts the view of a bridge on `map`.
///
/// # Errors
/// The address cannot be listened on.
pub(crate) fn start(config: ViewConfig, map: &BusMap) -> Result<View, String> {
    let listener =
        TcpListener::bind(config.addr).map_err(|e| format!("--view {}: {e}", config.addr))?;
    let addr = listener
        .local_addr()
        .map_err(|e| format!("--view {}: {e}", config.addr))?;
    let (queue, items) = mpsc::sync_channel(QUEUE);
    let dropped = Arc::new(AtomicU64::new(0));
    let started = Instant::now();
    let hello = json!({"kind": "hello", "motors": motors_json(map)}).to_string();
    let (pages_tx, pages_rx) = mpsc::channel::<TcpStream>();
    let open = Arc::new(AtomicUsize::new(0));
    {
        let dropped = Arc::clone(&dropped);
        let open = Arc::clone(&open);
        thread::Builder::new()
            .name("motorwire-view".to_owned())
            .spawn(move || hub(&items, &pages_rx, &dropped, &open, started, &hello))
            .map_err(|e| e.to_string())?;
    }
    let token = config.token.map(Arc::new);
    let answers = Arc::new(Answers {
        addr,
        names: config
            .hosts
            .iter()
            .map(|h| h.to_ascii_lowercase())
            .collect(),
    });
    thread::Builder::new()
        .name("motorwire-view-accept".to_owned())
        .spawn(move || {
            let busy = Arc::new(AtomicUsize::new(0));
            for stream in listener.incoming() {
                let Ok(stream) = stream else {
                    // Out of file descriptors (or another failed accept):
                    // a pause, never a loop that spins on a core.
                    thread::sleep(ACCEPT_BACKOFF);
                    continue;
                };
                // Requests being read, at most: more are closed at once.
                if busy.load(Ordering::SeqCst) >= MAX_REQUESTS {
                    drop(stream);
                    continue;
                }
                busy.fetch_add(1, Ordering::SeqCst);
                let pages = pages_tx.clone();
                let token = token.clone();
                let answers = Arc::clone(&answers);
                let open = Arc::clone(&open);
                let done = Arc::clone(&busy);
                let spawned = thread::Builder::new()
                    .name("motorwire-view-request".to_owned())
                    .spawn(move || {
                        serve(
                            stream,
                            &answers,
                            token.as_deref().map(String::as_str),
                            &pages,
                            &open,
                        );
                        done.fetch_sub(1, Ordering::SeqCst);
                    });
                if spawned.is_err() {
                    busy.fetch_sub(1, Ordering::SeqCst);
                }
            }
        })
        .map_err(|e| e.to_string())?;
    Ok(View {
        addr,
        tap: Arc::new(ViewTap { queue, dropped }),
    })
}

/// A stream read against one deadline for the whole head (a per-read
/// timeout lets a client dripping a byte at a time hold a slot for hours).
struct Deadline<'a> {
    stream: &'a TcpStream,
    until: Instant,
}

impl Read for Deadline<'_> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let left = self.until.saturating_duration_since(Instant::now());
        if left.is_zero() {
            return Err(std::io::Error::new(
                std::io::ErrorKind::TimedOut,
                "the request's head took too long",
            ));
        }
        self.stream.set_read_timeout(Some(left))?;
        (&mut &*self.stream).read(buf)
    }
}

/// How long a request's head may take, whole.
const HEAD_WITHIN: Duration = Duration::from_secs(2);

/// What the view reads of a request's head.
#[derive(Debug, Default)]
struct Head {
    method: String,
    target: String,
    host: Option<String>,
    origin: Option<String>,
    fetch_site: Option<String>,
}

impl Head {
    /// Takes one header line (`Name: value`); a second `Host`, `Origin`
    /// or `Sec-Fetch-Site` is a bad request (which one counts would be
    /// a guess).
    fn header(&mut self, line: &str) -> Result<(), &'static str> {
        let line = line.trim_end_matches(['\r', '\n']);
        let Some((name, value)) = line.split_once(':') else {
            return Err("400 Bad Request");
        };
        let slot = match name.to_ascii_lowercase().as_str() {
            "host" => &mut self.host,
            "origin" => &mut self.origin,
            "sec-fetch-site" => &mut self.fetch_site,
            _ => return Ok(()),
        };
        if slot.is_some() {
            return Err("400 Bad Request");
        }
        *slot = Some(value.trim_matches([' ', '\t']).to_owned());
        Ok(())
    }
}

/// The request's head: its method, target and the headers that say who
/// sent it, or why not.
fn read_head(stream: &TcpStream) -> Result<Head, &'static str> {
    let deadline = Deadline {
        stream,
        until: Instant::now() + HEAD_WITHIN,
    };
    let mut reader = BufReader::new(deadline.take(MAX_HEAD as u64));
    let mut first = String::new();
    reader
        .read_line(&mut first)
        .map_err(|_| "400 Bad Request")?;
    // The rest of the head, up to its blank line.
    let mut head = Head::default();
    loop {
        let mut line = String::new();
        match reader.read_line(&mut line) {
            Ok(0) => return Err("400 Bad Request"),
            Ok(_) if line == "\r\n" || line == "\n" => break,
            Ok(_) => head.header(&line)?,
            Err(_) => return Err("400 Bad Request"),
        }
    }
    // `METHOD TARGET HTTP/1.x`, one space apart, nothing else.
    let first = first.strip_suffix('\n').unwrap_or(&first);
    let first = first.strip_suffix('\r').unwrap_or(first);
    let parts: Vec<&str> = first.split(' ').collect();
    match parts.as_slice() {
        [m, t, v]
            if !m.is_empty() && t.starts_with('/') && (*v == "HTTP/1.1" || *v == "HTTP/1.0") =>
        {
            head.method = (*m).to_owned();
            head.target = (*t).to_owned();
            Ok(head)
        }
        _ => Err("400 Bad Request"),
    }
}

/// Whether `query` carries `token`, compared in constant time (its
/// length too: every byte of the longer is looked at). The value is read
/// as a browser writes it in a URL: `%XX` is the byte XX and `+` a space
/// (a token may hold any character but a line's end).
fn has_token(query: &str, token: &str) -> bool {
    query.split('&').fold(false, |found, kv| {
        let Some(given) = kv.strip_prefix("token=") else {
            return found;
        };
        let given = percent_decoded(given);
        let (g, t) = (given.as_slice(), token.as_bytes());
        let mut diff = u8::from(g.len() != t.len());
        for i in 0..g.len().max(t.len()) {
            diff |= g.get(i).copied().unwrap_or(0) ^ t.get(i).copied().unwrap_or(0xff);
        }
        found | (diff == 0)
    })
}

/// `text` with each `%XX` made the byte XX and each `+` a space (a `%`
/// not followed by two hex digits is kept as it is).
fn percent_decoded(text: &str) -> Vec<u8> {
    let bytes = text.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while let Some(&b) = bytes.get(i) {
        let hex = |at: usize| bytes.get(at).and_then(|c| char::from(*c).to_digit(16));
        match (b, hex(i + 1), hex(i + 2)) {
            (b'%', Some(hi), Some(lo)) => {
                // Two hex digits: at most 0xFF.
                out.push(u8::try_from(hi * 16 + lo).unwrap_or(u8::MAX));
                i += 3;
            }
            (b'+', _, _) => {
                out.push(b' ');
                i += 1;
            }
            _ => {
                out.push(b);
                i += 1;
            }
        }
    }
    out
}

fn respond(mut stream: TcpStream, status: &str, kind: &str, body: &str) {
    let _ = write!(
        stream,
        "HTTP/1.1 {status}\r\nContent-Type: {kind}\r\nContent-Length: {}\r\nCache-Control: no-store\r\nX-Content-Type-Options: nosniff\r\nContent-Security-Policy: default-src 'self'; script-src 'unsafe-inline'; style-src 'unsafe-inline'\r\nConnection: close\r\n\r\n{body}",
        body.len()
    );
}

/// One request: the page, its stream, or an error.
fn serve(
    stream: TcpStream,
    answers: &Answers,
    token: Option<&str>,
    pages: &mpsc::Sender<TcpStream>,
    open: &AtomicUsize,
) {
    let _ = stream.set_write_timeout(Some(Duration::from_secs(2)));
    let head = match read_head(&stream) {
        Ok(h) => h,
        Err(status) => return respond(stream, status, "text/plain", "a bad request\n"),
    };
    if let Some(why) = answers.refuses(&head) {
        return respond(stream, "403 Forbidden", "text/plain", &format!("{why}\n"));
    }
    let (method, target) = (head.method.as_str(), head.target.as_str());
    let (path, query) = target.split_once('?').unwrap_or((target, ""));
    if token.is_some_and(|t| !has_token(query, t)) {
        return respond(
            stream,
            "403 Forbidden",
            "text/plain",
            "this view needs its token: open it as /?token=TOKEN\n",
        );
    }
    if method != "GET" {
        return respond(
            stream,
            "405 Method Not Allowed",
            "text/plain",
            "the view only reads: GET / and GET /events\n",
        );
    }
    match path {
        "/" | "/index.html" => respond(stream, "200 OK", "text/html; charset=utf-8", PAGE),
        "/events" => {
            // Its place taken first (taken and checked at once: pages
            // opening together cannot pass the bound).
            if open.fetch_add(1, Ordering::SeqCst) >= MAX_PAGES {
                open.fetch_sub(1, Ordering::SeqCst);
                return respond(
                    stream,
                    "503 Service Unavailable",
                    "text/plain",
                    "too many pages are open\n",
                );
            }
            let mut stream = stream;
            let head = "HTTP/1.1 200 OK\r\nContent-Type: text/event-stream\r\nCache-Control: no-store\r\nX-Content-Type-Options: nosniff\r\nConnection: keep-alive\r\n\r\n";
            let _ = stream.set_write_timeout(Some(Duration::from_millis(250)));
            if stream.write_all(head.as_bytes()).is_err() || pages.send(stream).is_err() {
                open.fetch_sub(1, Ordering::SeqCst);
            }
        }
        _ => respond(
            stream,
            "404 Not Found",
            "text/plain",
            "not here: the view is at /\n",
        ),
    }
}

/// `item` as the page's JSON.
fn render(item: &Item, started: Instant) -> String {
    let t = |at: &Instant| at.saturating_duration_since(started).as_secs_f64();
    match item {
        Item::In {
            at,
            origin,
            number,
            text,
        } => json!({"kind": "in", "t": t(at), "origin": origin.0, "line": number, "text": text})
            .to_string(),
        Item::Out { at, to, line, .. } => format!(
            r#"{{"kind":"out","t":{},"to":{},"line":{line}}}"#,
            t(at),
            to.map_or_else(|| "null".to_owned(), |o| o.to_string()),
        ),
    }
}

/// The view's thread: renders each line once, keeps the last
/// [`HISTORY`] for pages that open, hands each line to every page's own
/// queue ([`PageQueue`]).
fn hub(
    items: &Receiver<Item>,
    new_pages: &Receiver<TcpStream>,
    dropped: &AtomicU64,
    open: &Arc<AtomicUsize>,
    started: Instant,
    hello: &str,
) {
    let hello: Arc<str> = Arc::from(hello);
    // Each page's own queue, written by a thread of its own: a page that
    // does not read holds only its own thread (until its write times out)
    // and is cut once its queue is full, never making the others wait.
    let mut pages: Vec<PageQueue> = Vec::new();
    // (when, rendered); and the last `ready`, kept past the history.
    let mut history: VecDeque<(Instant, Arc<str>)> = VecDeque::new();
    let mut history_bytes = 0usize;
    let mut ready: Option<Arc<str>> = None;
    let mut last_beat = Instant::now();
    let mut reported = 0;
    loop {
        while let Ok(page) = new_pages.try_recv() {
            let first: Vec<Arc<str>> = std::iter::once(Arc::clone(&hello))
                .chain(ready.clone())
                .chain(history.iter().map(|(_, l)| Arc::clone(l)))
                .collect();
            match PageQueue::start(page, first, Arc::clone(open)) {
                Some(q) => pages.push(q),
                None => {
                    open.fetch_sub(1, Ordering::SeqCst);
                }
            }
        }
        let item = match items.recv_timeout(Duration::from_millis(200)) {
            Ok(item) => Some(item),
            Err(RecvTimeoutError::Timeout) => None,
            Err(RecvTimeoutError::Disconnected) => return,
        };
        let mut lines: Vec<Arc<str>> = Vec::new();
        let lost = dropped.load(Ordering::Relaxed);
        if lost > reported {
            lines.push(Arc::from(
                json!({"kind": "dropped", "count": lost - reported}).to_string(),
            ));
            reported = lost;
        }
        if let Some(item) = item {
            let at = match &item {
                Item::In { at, .. } | Item::Out { at, .. } => *at,
            };
            let line = render(&item, started);
            if line.len() > MAX_RENDERED {
                dropped.fetch_add(1, Ordering::Relaxed);
                continue;
            }
            let line: Arc<str> = Arc::from(line);
            if matches!(&item, Item::Out { ready: true, .. }) {
                ready = Some(Arc::clone(&line));
            }
            history_bytes += line.len();
            history.push_back((at, Arc::clone(&line)));
            let now = Instant::now();
            while history.len() > HISTORY_LINES
                || history_bytes > HISTORY_BYTES
                || history
                    .front()
                    .is_some_and(|(t, _)| now.saturating_duration_since(*t) > HISTORY)
            {
                if let Some((_, old)) = history.pop_front() {
                    history_bytes -= old.len();
                }
            }
            lines.push(line);
        }
        if lines.is_empty() && last_beat.elapsed() >= Duration::from_secs(5) {
            // A comment: finds the pages that went away.
            lines.push(Arc::from(""));
            last_beat = Instant::now();
        }
        if lines.is_empty() {
            continue;
        }
        pages.retain(|page| lines.iter().all(|l| page.offer(l)));
    }
}

/// A page's queue and the thread that writes it.
struct PageQueue {
    queue: SyncSender<Arc<str>>,
    /// Set when the page is cut: its thread writes nothing more.
    cut: Arc<AtomicBool>,
}

impl PageQueue {
    /// The page's thread, which writes `first` (the greeting, `ready` and
    /// the history), then what it is offered, and counts the page out of
    /// `open` when it ends. `None` when no thread could be made.
    fn start(mut page: TcpStream, first: Vec<Arc<str>>, open: Arc<AtomicUsize>) -> Option<Self> {
        let (queue, lines) = mpsc::sync_channel::<Arc<str>>(PAGE_QUEUE);
        let cut = Arc::new(AtomicBool::new(false));
        let stop = Arc::clone(&cut);
        thread::Builder::new()
            .name("motorwire-view-page".to_owned())
            .spawn(move || {
                let live = |page: &mut TcpStream, line: &str| {
                    !stop.load(Ordering::Relaxed)
                        && if line.is_empty() {
                            page.write_all(b": alive\n\n").is_ok()
                        } else {
                            send(page, line)
                        }
                };
                if first.iter().all(|l| live(&mut page, l)) {
                    while let Ok(line) = lines.recv() {
                        if !live(&mut page, &line) {
                            break;
                        }
                    }
                }
                let _ = page.shutdown(std::net::Shutdown::Both);
                open.fetch_sub(1, Ordering::SeqCst);
            })
            .ok()?;
        Some(Self { queue, cut })
    }

    /// Hands `line` to the page; false (and the page cut) when it is gone
    /// or its queue is full: it does not keep up.
    fn offer(&self, line: &Arc<str>) -> bool {
        let kept = self.queue.try_send(Arc::clone(line)).is_ok();
        if !kept {
            self.cut.store(true, Ordering::Relaxed);
        }
        kept
    }
}

/// One event to a page; false when the page is gone or too slow.
fn send(page: &mut TcpStream, line: &str) -> bool {
    page.write_all(b"data: ")
        .and_then(|()| page.write_all(line.as_bytes()))
        .and_then(|()| page.write_all(b"\n\n"))
        .is_ok()
}

/// Whether `addr` is a loopback address (the view's default and, without
/// a token, its only choice).
pub(crate) fn is_loopback(addr: &SocketAddr) -> bool {
    addr.ip().is_loopback()
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn a_host_is_the_views_own_address_or_a_given_name() {
        let answers = |addr: &str, names: &[&str]| Answers {
            addr: addr.parse().unwrap(),
            names: names.iter().map(|n| (*n).to_owned()).collect(),
        };
        let v4 = answers("127.0.0.1:8080", &["arm.lab"]);
        for (host, ok) in [
            ("127.0.0.1:8080", true),
            ("localhost:8080", true),
            ("LocalHost:8080", true),
            ("arm.lab:8080", true),
            ("127.0.0.1", false),
            ("127.0.0.1:8081", false),
            ("127.0.0.2:8080", false),
            ("rebind.attacker.test:8080", false),
            ("localhost.attacker.test:8080", false),
            ("arm.lab.attacker.test:8080", false),
            (":8080", false),
            ("", false),
            ("127.0.0.1:80800", false),
        ] {
            assert_eq!(v4.host(host), ok, "{host}");
        }
        let v6 = answers("[::1]:80", &[]);
        for (host, ok) in [
            ("[::1]:80", true),
            ("[::1]", true),
            ("localhost", true),
            ("[::2]:80", false),
            ("::1", false),
        ] {
            assert_eq!(v6.host(host), ok, "{host}");
        }
        // Beyond loopback (with the view's token): any address written
        // as a number (it cannot be rebound), never `localhost` or a
        // name not given.
        let any = answers("0.0.0.0:9000", &["robot-1"]);
        for (host, ok) in [
            ("192.168.1.5:9000", true),
            ("robot-1:9000", true),
            ("localhost:9000", true),
            ("evil.test:9000", false),
        ] {
            assert_eq!(any.host(host), ok, "{host}");
        }
        let lan = answers("192.168.1.5:9000", &[]);
        assert!(!lan.host("localhost:9000"));
        assert!(!lan.host("10.0.0.1:9000"));
    }

    #[test]
    fn a_token_is_compared_whole() {
        assert!(has_token("token=abcdefabcdefabcd", "abcdefabcdefabcd"));
        assert!(has_token("x=1&token=abcdefabcdefabcd", "abcdefabcdefabcd"));
        assert!(!has_token("token=abcdefabcdefabc", "abcdefabcdefabcd"));
        assert!(!has_token("token=abcdefabcdefabcdX", "abcdefabcdefabcd"));
        assert!(!has_token("", "abcdefabcdefabcd"));
        assert!(!has_token("tok=abcdefabcdefabcd", "abcdefabcdefabcd"));
        assert!(has_token(
            "token=x&token=abcdefabcdefabcd",
            "abcdefabcdefabcd"
        ));
        // As a browser writes a token of any characters in a URL.
        let token = "abcdefghij klmnop&q#r%";
        for query in [
            "token=abcdefghij%20klmnop%26q%23r%25",
            "token=abcdefghij+klmnop%26q%23r%25",
        ] {
            assert!(has_token(query, token), "{query}");
        }
        assert!(!has_token("token=abcdefghij%2", "abcdefghij%2X"));
        assert_eq!(percent_decoded("a%2"), b"a%2");
        assert_eq!(percent_decoded("%zz%41"), b"%zzA");
    }
}
