//! The bridge as a Zenoh participant: queries in, replies, publications
//! and the liveliness token out, on a runtime of its own.

use std::collections::{BTreeSet, HashMap};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

use motorwire_bridge::route::{Delivery, Owed, Routing};
use motorwire_bridge::{
    ErrorBody, ErrorKind, InputSender, LineResult, Origin, Output, ReadLine, asks_for_stop,
    read_line,
};
use serde_json::Value;
use tokio::sync::mpsc;
use zenoh::bytes::Encoding;
use zenoh::query::Query;

use crate::ZenohError;
use crate::ids::{
    CONTROLLER_IDLE, CONTROLLERS, Controller, IDS_PER_CONTROLLER, IdMemory, Recalled,
};
use crate::keys::{FLEET_ESTOP, RobotKeys, controller_of};

/// The first origin of a command query; every query gets the next one.
/// The line interface's origins (standard input 0, clients from 1) stay
/// far below.
pub const QUERY_ORIGINS: u64 = 1 << 62;

/// The first origin of a stop put (and of a stop for a lost session).
pub const STOP_ORIGINS: u64 = QUERY_ORIGINS | (1 << 61);

/// The line every stop put (and a lost session) hands to the bridge: the
/// line interface's emergency stop.
pub const STOP_LINE: &str = r#"{"emergency_stop":true}"#;

/// The default of [`FleetConfig::session_timeout`]: a bridge whose session
/// has had no router or peer for this long while joints move stops them.
pub const DEFAULT_SESSION_TIMEOUT: Duration = Duration::from_millis(500);

/// Command queries in progress at once; beyond this a query is answered
/// `busy` at once and nothing is handed to the bridge.
pub const MAX_QUERIES_IN_PROGRESS: usize = 2048;

/// Feedback and event lines waiting to be published; beyond this they are
/// dropped (counted in [`Participant::dropped`]), never the engine held up.
pub const PUBLISH_QUEUE: usize = 4096;

/// How long to wait before trying to open the session again.
pub const RETRY_OPEN: Duration = Duration::from_secs(1);

/// How long a starting bridge waits for the answers of the bridges that
/// already answer for its robot name.
pub const ALIVE_CHECK: Duration = Duration::from_secs(1);

/// How often the session's links are looked at.
const WATCH_PERIOD: Duration = Duration::from_millis(20);

/// A selector parameter and a request id longer than this are refused.
const MAX_NAME: usize = 256;

/// How a bridge joins the fleet.
#[derive(Debug)]
pub struct FleetConfig {
    /// The robot's keys (`motorwire/<robot>/...`).
    pub keys: RobotKeys,
    /// The Zenoh session's configuration (mode, endpoints, TLS,
    /// authentication, access control).
    pub zenoh: zenoh::Config,
    /// How long the session may have no router or peer while joints move
    /// before the bridge stops them ([`DEFAULT_SESSION_TIMEOUT`]).
    pub session_timeout: Duration,
    /// Ids remembered per controller ([`IDS_PER_CONTROLLER`]).
    pub ids_per_controller: usize,
    /// Controllers remembered ([`CONTROLLERS`]).
    pub controllers: usize,
}

impl FleetConfig {
    /// `robot` on a session configured by `zenoh`, with the defaults.
    ///
    /// # Errors
    /// [`ZenohError::RobotName`] when `robot` cannot be a key chunk.
    pub fn new(robot: &str, zenoh: zenoh::Config) -> Result<Self, ZenohError> {
        Ok(Self {
            keys: RobotKeys::new(robot)?,
            zenoh,
            session_timeout: DEFAULT_SESSION_TIMEOUT,
            ids_per_controller: IDS_PER_CONTROLLER,
            controllers: CONTROLLERS,
        })
    }
}

/// Reads a Zenoh configuration file (JSON5, YAML or JSON, by extension).
///
/// # Errors
/// [`ZenohError::Config`] when it cannot be read or is not valid.
pub fn config_from_file(path: &str) -> Result<zenoh::Config, ZenohError> {
    zenoh::Config::from_file(path).map_err(|e| ZenohError::Config(format!("{path}: {e}")))
}

/// What the engine's outputs become for the participant's task.
#[derive(Debug)]
enum Msg {
    Output(Box<Output>),
    Close,
}

/// The bridge as a Zenoh participant; see the crate's documentation.
///
/// [`Participant::route`] takes every output of the engine and never
/// waits; the queries, replies and publications run on the participant's
/// own threads, never the engine's.
#[derive(Debug)]
pub struct Participant {
    replies: mpsc::UnboundedSender<Msg>,
    publish: mpsc::Sender<Msg>,
    dropped: Arc<AtomicU64>,
    runtime: Option<tokio::runtime::Runtime>,
    task: Option<tokio::task::JoinHandle<()>>,
}

impl Participant {
    /// Starts the participant and returns at once: on its own threads it
    /// opens the session (trying again every [`RETRY_OPEN`] while no router
    /// or peer can be reached, so the bridge runs meanwhile), declares the
    /// queryable and the stop subscribers, and last the liveliness token
    /// (so a controller that sees the token can command). Each command is
    /// handed to `input`. `note` is told, for a person, when the session is
    /// open and why an attempt failed.
    ///
    /// # Errors
    /// [`ZenohError::Runtime`] when the threads cannot be started.
    pub fn start(
        config: FleetConfig,
        input: InputSender,
        note: impl Fn(&str) + Send + Sync + 'static,
    ) -> Result<Self, ZenohError> {
        let runtime = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(1)
            .thread_name("motorwire-zenoh")
            .enable_all()
            .build()?;
        let (replies, replies_rx) = mpsc::unbounded_channel();
        let (publish, publish_rx) = mpsc::channel(PUBLISH_QUEUE);
        let FleetConfig {
            keys,
            zenoh,
            session_timeout,
            ids_per_controller,
            controllers,
        } = config;
        // The first try at the session is made here: a robot name another
        // bridge answers already is refused before anything is declared.
        // When no router or peer can be reached yet, the bridge runs and
        // the session is tried again on the participant's threads (and the
        // same check made there: a bridge that finds its name taken then
        // stays out of the fleet and says so).
        let first = runtime.block_on(async {
            match zenoh::open(zenoh.clone()).await {
                Ok(session) => match others_named(&session, &keys).await {
                    Ok(others) if others.is_empty() => Ok(Some(session)),
                    Ok(others) => {
                        let _ = session.close().await;
                        Err(ZenohError::RobotTaken {
                            robot: keys.robot().to_owned(),
                            bridges: others,
                        })
                    }
                    Err(e) => {
                        let _ = session.close().await;
                        Err(e)
                    }
                },
                Err(e) => {
                    note(&format!(
                        "zenoh: {e}; trying again every {RETRY_OPEN:?} (the bridge runs meanwhile)"
                    ));
                    Ok(None)
                }
            }
        })?;
        let task = runtime.spawn(async move {
            let session = match first {
                Some(session) => session,
                None => loop {
                    tokio::time::sleep(RETRY_OPEN).await;
                    let Ok(session) = zenoh::open(zenoh.clone()).await else {
                        continue; // said once, above
                    };
                    match others_named(&session, &keys).await {
                        Ok(others) if others.is_empty() => break session,
                        Ok(others) => {
                            note(&format!(
                                "{}; this bridge stays out of the fleet",
                                ZenohError::RobotTaken {
                                    robot: keys.robot().to_owned(),
                                    bridges: others
                                }
                            ));
                        }
                        Err(e) => note(&format!("{e}; the bridge is not in the fleet")),
                    }
                    let _ = session.close().await;
                    return;
                },
            };
            let stops = Arc::new(AtomicU64::new(STOP_ORIGINS));
            let declared = declare(&session, &keys, &input, &stops).await;
            let (queryable, subscribers, token) = match declared {
                Ok(d) => d,
                Err(e) => {
                    note(&format!("{e}; the bridge is not in the fleet"));
                    let _ = session.close().await;
                    return;
                }
            };
            let bridge = session.zid().to_string();
            note(&format!(
                "in the fleet as motorwire/{} (bridge {bridge})",
                keys.robot()
            ));
            let state = State {
                robot: Value::String(keys.robot().to_owned()).to_string(),
                bridge,
                keys,
                input,
                next_origin: QUERY_ORIGINS,
                stops,
                pending: HashMap::new(),
                ids: IdMemory::new(ids_per_controller, controllers, CONTROLLER_IDLE),
                moving: BTreeSet::new(),
                timeout: session_timeout,
                note: Box::new(note),
            };
            state
                .run(
                    session,
                    queryable,
                    subscribers,
                    token,
                    replies_rx,
                    publish_rx,
                )
                .await;
        });
        Ok(Self {
            replies,
            publish,
            dropped: Arc::default(),
            runtime: Some(runtime),
            task: Some(task),
        })
    }

    /// Whether `origin` is one of the participant's (a command query's or
    /// a stop put's).
    pub fn owns(origin: Origin) -> bool {
        origin.0 >= QUERY_ORIGINS
    }

    /// Takes one output of the engine; never waits. Returns whether it was
    /// the participant's own (a result or completion of one of its
    /// origins), which nobody else should be given. Feedback and events are
    /// published (and returned `false`: others want them too).
    pub fn route(&self, o: &Output) -> bool {
        // The bridge's routing says where each output goes; a fleet
        // controller reads feedback from its key expression as published.
        match Routing::delivery(o) {
            Delivery::ToReader {
                origin,
                owed: Owed::Result { .. } | Owed::Arrival,
            } => {
                if !Self::owns(origin) {
                    return false;
                }
                let _ = self.replies.send(Msg::Output(Box::new(o.clone())));
                true
            }
            // A greeting for a local client: not the fleet's.
            Delivery::ToReader {
                owed: Owed::Greeting,
                ..
            } => false,
            Delivery::Feedback { .. } | Delivery::ToEvery => {
                if self
                    .publish
                    .try_send(Msg::Output(Box::new(o.clone())))
                    .is_err()
                {
                    self.dropped.fetch_add(1, Ordering::Relaxed);
                }
                false
            }
        }
    }

    /// Feedback and event lines dropped because the publication queue was
    /// full ([`PUBLISH_QUEUE`]).
    pub fn dropped(&self) -> u64 {
        self.dropped.load(Ordering::Relaxed)
    }

    /// Withdraws the liveliness token and closes the session (queries in
    /// progress are ended without further replies).
    pub fn close(mut self) {
        self.shut();
    }

    fn shut(&mut self) {
        let _ = self.replies.send(Msg::Close);
        if let (Some(rt), Some(task)) = (self.runtime.take(), self.task.take()) {
            let _ = rt.block_on(async { tokio::time::timeout(Duration::from_secs(2), task).await });
            rt.shutdown_timeout(Duration::from_millis(200));
        }
    }
}

impl Drop for Participant {
    fn drop(&mut self) {
        self.shut();
    }
}

/// `line` (a JSON object) with `robot` (a JSON string) and `bridge` (a
/// Zenoh id) last: which robot and which bridge answered.
fn signed(line: &str, robot: &str, bridge: &str) -> String {
    match line.trim_end().strip_suffix('}') {
        Some(rest) if line.starts_with('{') => {
            let comma = if rest.trim_end().ends_with('{') {
                ""
            } else {
                ","
            };
            format!(r#"{rest}{comma}"robot":{robot},"bridge":"{bridge}"}}"#)
        }
        _ => line.to_owned(),
    }
}

/// Whether a token's last chunk can be a bridge's Zenoh id (up to 32 hex
/// digits, as Zenoh writes one): anything else (a token declared by hand)
/// is no bridge, and neither keeps a bridge out nor makes one leave.
fn is_zid(chunk: &str) -> bool {
    (1..=32).contains(&chunk.len()) && chunk.bytes().all(|b| b.is_ascii_hexdigit())
}

/// The Zenoh ids of the other bridges that answer for `keys`' robot now:
/// their per-bridge liveliness tokens (`motorwire/<robot>/alive/<zid>`).
async fn others_named(
    session: &zenoh::Session,
    keys: &RobotKeys,
) -> Result<Vec<String>, ZenohError> {
    let replies = session
        .liveliness()
        .get(keys.alive_bridges())
        .timeout(ALIVE_CHECK)
        .await
        .map_err(ZenohError::zenoh)?;
    let mine = session.zid().to_string();
    let mut others = Vec::new();
    while let Ok(reply) = replies.recv_async().await {
        if let Ok(sample) = reply.result()
            && let Some(zid) = sample.key_expr().as_str().rsplit('/').next()
            && zid != mine
            && is_zid(zid)
            && !others.iter().any(|o| o == zid)
        {
            others.push(zid.to_owned());
        }
    }
    others.sort();
    Ok(others)
}

/// The queryable, the stop subscribers (each put a stop on a fresh
/// origin: a stop never waits behind another origin's lines) and the
/// liveliness token, in that order.
async fn declare(
    session: &zenoh::Session,
    keys: &RobotKeys,
    input: &InputSender,
    stops: &Arc<AtomicU64>,
) -> Result<
    (
        zenoh::query::Queryable<zenoh::handlers::FifoChannelHandler<Query>>,
        Vec<zenoh::pubsub::Subscriber<()>>,
        [zenoh::liveliness::LivelinessToken; 2],
    ),
    ZenohError,
> {
    let queryable = session
        .declare_queryable(keys.cmd_any())
        .await
        .map_err(ZenohError::zenoh)?;
    let mut subscribers = Vec::new();
    for key in [FLEET_ESTOP.to_owned(), keys.estop()] {
        let input = input.clone();
        let stops = Arc::clone(stops);
        let s = session
            .declare_subscriber(key)
            .callback(move |_sample| {
                let origin = Origin(stops.fetch_add(1, Ordering::Relaxed));
                input.line(origin, STOP_LINE);
            })
            .await
            .map_err(ZenohError::zenoh)?;
        subscribers.push(s);
    }
    let bridge = session
        .liveliness()
        .declare_token(keys.alive_bridge(&session.zid().to_string()))
        .await
        .map_err(ZenohError::zenoh)?;
    let token = session
        .liveliness()
        .declare_token(keys.alive())
        .await
        .map_err(ZenohError::zenoh)?;
    Ok((queryable, subscribers, [bridge, token]))
}

/// A command query's line in progress.
#[derive(Debug)]
struct Pending {
    /// The queries waiting for its replies (the first, and its retries:
    /// the same controller's, so replied to on the same key).
    queries: Vec<Query>,
    /// The key its replies go on.
    on: String,
    /// `(controller, id, body)` when it carried an id (the id as the
    /// memory keys it: [`CommandId`]'s type and value).
    id: Option<(Controller, String, Arc<str>)>,
    /// The replies so far.
    sent: Vec<Arc<str>>,
}

/// What a query's payload asks.
#[derive(Debug, PartialEq)]
enum Command {
    /// A line to hand over, with its id when it has one.
    Line { text: String, id: Option<Keyed> },
    /// A line the bridge must refuse (it names a stop: it stops).
    Refused { reason: String, stop: bool },
}

/// A command's id as the controller sent it: the string `"42"` and the
/// integer `42` are two ids.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) enum CommandId {
    /// A string id.
    Text(String),
    /// An unsigned integer id.
    Number(u64),
}

impl CommandId {
    /// The id in the memory: its type and its value.
    fn key(&self) -> String {
        match self {
            Self::Text(s) => format!("s:{s}"),
            Self::Number(n) => format!("n:{n}"),
        }
    }
}

impl std::fmt::Display for CommandId {
    /// As JSON writes it: a string quoted, an integer bare.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Text(s) => write!(f, "{}", Value::String(s.clone())),
            Self::Number(n) => write!(f, "{n}"),
        }
    }
}

/// A command's id and its body: the command's members without its
/// `request_id` and its `timestamp` (a retry may be stamped anew), in
/// order and with repeats, as one text: what a retry must repeat for the
/// id to name the same command.
#[derive(Debug, Clone, PartialEq, Eq)]
struct Keyed {
    id: CommandId,
    body: Arc<str>,
}

/// Where a byte of JSON text stands: inside a string or between tokens.
#[derive(Debug, Default)]
struct Strings {
    inside: bool,
    escaped: bool,
}

impl Strings {
    /// Takes the next byte; whether it stands between tokens (a quote that
    /// opens or closes a string counts as inside it).
    fn between_tokens(&mut self, b: u8) -> bool {
        if self.inside {
            if self.escaped {
                self.escaped = false;
            } else if b == b'\\' {
                self.escaped = true;
            } else if b == b'"' {
                self.inside = false;
            }
            false
        } else {
            self.inside = b == b'"';
            !self.inside
        }
    }
}

/// The body of a command (`text`, whose top-level members lie at
/// `spans`): its members as written (nested repeats and spellings kept;
/// whitespace between tokens dropped), but `request_id`, and each
/// `timestamp` member's value (a retry may be stamped anew; how many there
/// are still counts).
fn body_of(text: &str, spans: &[(String, std::ops::Range<usize>)]) -> Arc<str> {
    let inner: Vec<String> = spans
        .iter()
        .filter(|(k, _)| k != "request_id")
        .map(|(k, at)| {
            if k == "timestamp" {
                "\"timestamp\":_".to_owned()
            } else {
                tokens_only(text.get(at.clone()).unwrap_or_default())
            }
        })
        .collect();
    Arc::from(format!("{{{}}}", inner.join(",")))
}

/// JSON text without the whitespace between its tokens.
fn tokens_only(json: &str) -> String {
    let mut at = Strings::default();
    let bytes: Vec<u8> = json
        .bytes()
        .filter(|&b| !(at.between_tokens(b) && b.is_ascii_whitespace()))
        .collect();
    // Only ASCII whitespace was taken out: still UTF-8.
    String::from_utf8(bytes).unwrap_or_else(|_| json.to_owned())
}

/// Where each top-level member of the JSON object `text` lies (from its
/// key's opening quote to its value's end), with its key decoded; `None`
/// when `text` is not one object.
fn member_spans(text: &str) -> Option<Vec<(String, std::ops::Range<usize>)>> {
    fn skip_ws(b: &[u8], mut i: usize) -> usize {
        while b
            .get(i)
            .is_some_and(|c| matches!(c, b' ' | b'\t' | b'\n' | b'\r'))
        {
            i += 1;
        }
        i
    }
    /// The key at the start of `s`, and the bytes it took.
    fn key(s: &str) -> Option<(String, usize)> {
        let mut values = serde_json::Deserializer::from_str(s).into_iter::<String>();
        let v = values.next()?.ok()?;
        Some((v, values.byte_offset()))
    }
    /// The bytes the JSON value at the start of `s` takes.
    fn value(s: &str) -> Option<usize> {
        let mut values = serde_json::Deserializer::from_str(s).into_iter::<Value>();
        values.next()?.ok()?;
        Some(values.byte_offset())
    }
    let b = text.as_bytes();
    let mut i = skip_ws(b, 0);
    if b.get(i) != Some(&b'{') {
        return None;
    }
    i = skip_ws(b, i + 1);
    let mut spans = Vec::new();
    if b.get(i) == Some(&b'}') {
        return Some(spans);
    }
    loop {
        let start = i;
        let (key, n) = key(text.get(i..)?)?;
        i = skip_ws(b, i + n);
        if b.get(i) != Some(&b':') {
            return None;
        }
        i = skip_ws(b, i + 1);
        i += value(text.get(i..)?)?;
        spans.push((key, start..i));
        i = skip_ws(b, i);
        match b.get(i) {
            Some(b',') => i = skip_ws(b, i + 1),
            Some(b'}') => return Some(spans),
            _ => return None,
        }
    }
}

/// `text` (whose top-level members lie at `spans`) with its one
/// `request_id` member cut out (and the comma that joined it to a
/// neighbour); every other byte as it came.
fn without_request_id(text: &str, spans: &[(String, std::ops::Range<usize>)]) -> Option<String> {
    let at = spans.iter().position(|(k, _)| k == "request_id")?;
    let cut = match (
        at.checked_sub(1).and_then(|p| spans.get(p)),
        spans.get(at + 1),
    ) {
        // Up to the next member: the member, its comma and the space.
        (_, Some((_, next))) => spans.get(at)?.1.start..next.start,
        // The last of several: from the end of the one before it.
        (Some((_, before)), None) => before.end..spans.get(at)?.1.end,
        (None, None) => spans.get(at)?.1.clone(),
    };
    let mut out = String::with_capacity(text.len());
    out.push_str(text.get(..cut.start)?);
    out.push_str(text.get(cut.end..)?);
    Some(out)
}

/// A payload as one line: a line break between JSON tokens (pretty-printed
/// JSON) becomes a space; one inside a string (which JSON does not allow)
/// stays a raw control character there (a line feed becomes a carriage
/// return, so the payload stays one line), and the bridge reads the line
/// as it reads such a line on standard input: not JSON, a stop when it
/// names one.
fn one_line(payload: &[u8]) -> Vec<u8> {
    let mut at = Strings::default();
    payload
        .iter()
        .map(|&b| {
            let between = at.between_tokens(b);
            match b {
                b'\n' | b'\r' if between => b' ',
                b'\n' => b'\r',
                _ => b,
            }
        })
        .collect()
}

/// Reads a query's payload as the line interface reads a line, with the
/// bridge's own reading of its members ([`motorwire_bridge::members`]:
/// repeats kept): its `request_id` (cut out of the line, every other byte
/// as it came) or else its `command_id` is its id. The bridge then reads
/// the line exactly as a line on standard input without that member: a
/// repeated member, a typo or a stop form gets the same result.
fn command(payload: &[u8], max_line: usize) -> Command {
    let mut bytes = one_line(payload);
    bytes.push(b'\n');
    let text = match read_line(&mut std::io::Cursor::new(bytes), max_line) {
        // A blank line would get no result at all: refused instead.
        Ok(ReadLine::Line(s)) if !s.trim().is_empty() => s,
        Ok(ReadLine::TooLong { names_stop, .. }) => {
            return Command::Refused {
                reason: format!("the command is over {max_line} bytes (the bridge's --max-size)"),
                stop: names_stop,
            };
        }
        Ok(ReadLine::NotUtf8 { names_stop, .. }) => {
            return Command::Refused {
                reason: "the command is not UTF-8".to_owned(),
                stop: names_stop,
            };
        }
        Ok(ReadLine::Line(_) | ReadLine::Partial(_) | ReadLine::End) | Err(_) => {
            return Command::Refused {
                reason: "the query carried no command".to_owned(),
                stop: false,
            };
        }
    };
    // A stop always acts: nothing about its id can refuse it, and a stop
    // (or a release) is never remembered (a repeated release is answered
    // `not_latched`).
    let stop = asks_for_stop(text.trim());
    let Ok(members) = motorwire_bridge::members(&text) else {
        // Not one object serde_json holds: the bridge says why (or stops).
        return Command::Line { text, id: None };
    };
    let Some(spans) = member_spans(&text) else {
        // members() read it, so this does not happen; when in doubt, the
        // line as it came (a stop stops).
        return Command::Line { text, id: None };
    };
    let ids: Vec<&Value> = members
        .iter()
        .filter(|(k, _)| k == "request_id")
        .map(|(_, v)| v)
        .collect();
    // The line without its request_id, when it had one.
    let (cut, id) = match ids.as_slice() {
        [] => {
            let command_ids: Vec<&Value> = members
                .iter()
                .filter(|(k, _)| k == "command_id")
                .map(|(_, v)| v)
                .collect();
            let id = match command_ids.as_slice() {
                [Value::String(s)] if !s.is_empty() && s.len() <= MAX_NAME => {
                    Some(CommandId::Text(s.clone()))
                }
                // None, repeated (the bridge refuses a repeat), or not an
                // id this memory keeps: the line runs as a line does.
                _ => None,
            };
            (None, id)
        }
        [v] => {
            let Some(line) = without_request_id(&text, &spans) else {
                return Command::Line { text, id: None };
            };
            let id = match v {
                Value::String(s) if !s.is_empty() && s.len() <= MAX_NAME => {
                    Ok(CommandId::Text(s.clone()))
                }
                Value::Number(n) if n.is_u64() => {
                    Ok(CommandId::Number(n.as_u64().unwrap_or_default()))
                }
                _ => Err(format!(
                    "request_id {v} is not a non-empty string of at most {MAX_NAME} bytes or an unsigned integer; nothing was sent"
                )),
            };
            match id {
                Ok(id) => (Some(line), Some(id)),
                Err(_) if stop => {
                    return Command::Line {
                        text: line,
                        id: None,
                    };
                }
                Err(reason) => {
                    return Command::Refused {
                        reason,
                        stop: false,
                    };
                }
            }
        }
        many => {
            if stop {
                return Command::Line { text, id: None };
            }
            return Command::Refused {
                reason: format!(
                    "request_id appears {} times: a command has one id; nothing was sent",
                    many.len()
                ),
                stop: false,
            };
        }
    };
    if stop || members.iter().any(|(k, _)| k == "emergency_stop") {
        return Command::Line {
            text: cut.unwrap_or(text),
            id: None,
        };
    }
    let id = id.map(|id| Keyed {
        id,
        body: body_of(&text, &spans),
    });
    Command::Line {
        text: cut.unwrap_or(text),
        id,
    }
}

/// The most of the first command that a refused reuse of its id shows.
const SHOWN_OF_FIRST: usize = 256;

/// The result line of a query this participant refuses itself (nothing
/// reaches the bridge): `line` 0.
fn refusal(kind: ErrorKind, message: String) -> String {
    Output::Result {
        origin: Origin(0),
        result: Box::new(LineResult {
            ok: false,
            error: Some(ErrorBody::new(kind, message)),
            ..LineResult::default()
        }),
    }
    .to_json()
}

/// The result line of a query whose id named another command.
fn id_reused(id: &CommandId, first: &str) -> String {
    let mut shown = first;
    if shown.len() > SHOWN_OF_FIRST {
        let mut end = SHOWN_OF_FIRST;
        while !shown.is_char_boundary(end) {
            end -= 1;
        }
        shown = shown.get(..end).unwrap_or_default();
    }
    let cut = if shown.len() < first.len() { "..." } else { "" };
    refusal(
        ErrorKind::IdReused,
        format!(
            "the id {id} is this controller's id of another command, {shown}{cut}; a retry carries the same command as its first try, a new command a new id; nothing was sent"
        ),
    )
}

/// The participant's state, owned by its one task.
struct State {
    /// The robot's name as a JSON string, and this bridge's Zenoh id: in
    /// every reply.
    robot: String,
    bridge: String,
    keys: RobotKeys,
    input: InputSender,
    next_origin: u64,
    stops: Arc<AtomicU64>,
    pending: HashMap<Origin, Pending>,
    ids: IdMemory,
    /// Motors whose last feedback said `in_motion`.
    moving: BTreeSet<String>,
    timeout: Duration,
    /// Tells a person what happened to the session's links.
    note: Box<dyn Fn(&str) + Send + Sync>,
}

impl State {
    async fn run(
        mut self,
        session: zenoh::Session,
        queryable: zenoh::query::Queryable<zenoh::handlers::FifoChannelHandler<Query>>,
        subscribers: Vec<zenoh::pubsub::Subscriber<()>>,
        token: [zenoh::liveliness::LivelinessToken; 2],
        mut replies: mpsc::UnboundedReceiver<Msg>,
        mut publish: mpsc::Receiver<Msg>,
    ) {
        // Another bridge that joins under this robot's name (both started
        // at once, or found when their sessions met): the one with the
        // greater Zenoh id stops its joints and leaves, so that one bridge
        // answers for the name.
        let twins = match session
            .liveliness()
            .declare_subscriber(self.keys.alive_bridges())
            .history(true)
            .await
        {
            Ok(t) => t,
            Err(e) => {
                (self.note)(&format!("zenoh: {e}; the bridge leaves the fleet"));
                let _ = session.close().await;
                return;
            }
        };
        let mut watch = tokio::time::interval(WATCH_PERIOD);
        watch.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
        let mut had_link = false;
        let mut lost_since: Option<Instant> = None;
        let mut stopped_for_loss = false;
        loop {
            tokio::select! {
                biased;
                msg = replies.recv() => match msg {
                    Some(Msg::Output(o)) => self.answer(&session, *o).await,
                    Some(Msg::Close) | None => break,
                },
                twin = twins.recv_async() => {
                    let Ok(twin) = twin else { break };
                    let zid = twin.key_expr().as_str().rsplit('/').next().unwrap_or_default().to_owned();
                    if twin.kind() == zenoh::sample::SampleKind::Put && zid != self.bridge && is_zid(&zid) {
                        if self.bridge > zid {
                            (self.note)(&format!(
                                "zenoh: bridge {zid} also answers for motorwire/{}: two bridges would run every command sent to it; this bridge ({}, the greater Zenoh id) stops its joints and leaves the fleet",
                                self.keys.robot(), self.bridge
                            ));
                            let origin = Origin(self.stops.fetch_add(1, Ordering::Relaxed));
                            self.input.line(origin, STOP_LINE);
                            break;
                        }
                        (self.note)(&format!(
                            "zenoh: bridge {zid} also answers for motorwire/{}; it has the greater Zenoh id and leaves the fleet",
                            self.keys.robot()
                        ));
                    }
                }
                q = queryable.recv_async() => match q {
                    Ok(q) => self.query(q).await,
                    Err(_) => break,
                },
                msg = publish.recv() => {
                    if let Some(Msg::Output(o)) = msg {
                        self.publish(&session, &o).await;
                    }
                }
                _ = watch.tick() => {
                    let linked = session.info().routers_zid().await.next().is_some()
                        || session.info().peers_zid().await.next().is_some();
                    if linked {
                        if lost_since.is_some() {
                            (self.note)("zenoh: a router or peer is reachable again");
                        }
                        had_link = true;
                        lost_since = None;
                        stopped_for_loss = false;
                    } else if had_link {
                        if lost_since.is_none() {
                            (self.note)(&format!(
                                "zenoh: no router or peer is reachable; moving joints stop after {:?}",
                                self.timeout
                            ));
                        }
                        let since = *lost_since.get_or_insert_with(Instant::now);
                        if !stopped_for_loss && since.elapsed() >= self.timeout && self.is_moving() {
                            stopped_for_loss = true;
                            let origin = Origin(self.stops.fetch_add(1, Ordering::Relaxed));
                            self.input.line(origin, STOP_LINE);
                        }
                    }
                }
            }
        }
        drop(token);
        drop(twins);
        drop(subscribers);
        drop(queryable);
        // Queries in progress end here, without more replies.
        self.pending.clear();
        let _ = session.close().await;
    }

    /// Joints move, or may be about to: a command query in progress, or a
    /// motor whose last feedback said `in_motion`.
    fn is_moving(&self) -> bool {
        !self.pending.is_empty() || !self.moving.is_empty()
    }

    async fn query(&mut self, q: Query) {
        let payload = q
            .payload()
            .map(|p| p.to_bytes().into_owned())
            .unwrap_or_default();
        let parameter = q.parameters().get("controller");
        let controller = match parameter {
            Some(p) if p.len() > MAX_NAME => {
                Err(format!("the controller parameter is over {MAX_NAME} bytes"))
            }
            _ => controller_of(q.key_expr().as_str(), parameter),
        };
        // Every reply goes on the robot's own key of the controller the
        // query names, or on the query's own key when it names no one.
        let on = match &controller {
            Ok(c) => self.keys.reply_key(c),
            Err(_) => q.key_expr().to_string(),
        };
        let (command, controller) = match controller {
            Ok(c) => (command(&payload, self.input.max_line()), Some(c)),
            // A query that names no one controller is refused here, nothing
            // sent; when it names a stop, it stops (the bridge refuses it
            // as a line and stops). A refused query has no id.
            Err(reason) => {
                if !asks_for_stop(&String::from_utf8_lossy(&payload)) {
                    let text = refusal(ErrorKind::Invalid, format!("{reason}; nothing was sent"));
                    self.reply(&q, &on, &text).await;
                    return;
                }
                (Command::Refused { reason, stop: true }, None)
            }
        };
        if let Command::Line {
            id: Some(keyed), ..
        } = &command
            && let Some(controller) = &controller
        {
            if !self.ids.admit(controller, Instant::now()) {
                let text = refusal(
                    ErrorKind::Busy,
                    format!(
                        "the ids of {} controllers are remembered, each heard within the last {} s: a new controller's command with an id waits until one is silent that long (a command without an id is taken); nothing was sent",
                        self.ids.bound(),
                        CONTROLLER_IDLE.as_secs()
                    ),
                );
                self.reply(&q, &on, &text).await;
                return;
            }
            match self.ids.recall(controller, &keyed.id.key()) {
                Some((first, _)) if first != keyed.body => {
                    self.reply(&q, &on, &id_reused(&keyed.id, &first)).await;
                    return;
                }
                Some((_, Recalled::Done(lines))) => {
                    for line in &lines {
                        self.reply(&q, &on, line).await;
                    }
                    return; // dropping the query ends its replies
                }
                Some((_, Recalled::InProgress(origin))) => {
                    if let Some(p) = self.pending.get_mut(&origin) {
                        for line in p.sent.clone() {
                            self.reply(&q, &on, &line).await;
                        }
                        if let Some(p) = self.pending.get_mut(&origin) {
                            p.queries.push(q);
                        }
                        return;
                    }
                }
                None => {}
            }
        }
        // A stop always acts: never refused for the commands in progress
        // (it ends them).
        let stop = match &command {
            Command::Line { text, .. } => asks_for_stop(text.trim()),
            Command::Refused { stop, .. } => *stop,
        };
        if self.pending.len() >= MAX_QUERIES_IN_PROGRESS && !stop {
            let text = refusal(
                ErrorKind::Busy,
                format!(
                    "{MAX_QUERIES_IN_PROGRESS} commands are in progress on this bridge; nothing was sent"
                ),
            );
            self.reply(&q, &on, &text).await;
            return;
        }
        let origin = Origin(self.next_origin);
        self.next_origin += 1;
        let id = match (&command, controller) {
            (
                Command::Line {
                    id: Some(keyed), ..
                },
                Some(controller),
            ) => {
                let key = keyed.id.key();
                self.ids.remember(
                    &controller,
                    &key,
                    Arc::clone(&keyed.body),
                    Recalled::InProgress(origin),
                );
                Some((controller, key, Arc::clone(&keyed.body)))
            }
            _ => None,
        };
        self.pending.insert(
            origin,
            Pending {
                queries: vec![q],
                on,
                id,
                sent: Vec::new(),
            },
        );
        match command {
            Command::Line { text, .. } => self.input.line(origin, text),
            Command::Refused { reason, stop: true } => self.input.refused_stop(origin, reason),
            Command::Refused {
                reason,
                stop: false,
            } => self.input.refused(origin, reason),
        }
    }

    /// Replies `line` to `q` on the key `on`.
    async fn reply(&self, q: &Query, on: &str, line: &str) {
        let line = signed(line, &self.robot, &self.bridge);
        let _ = q.reply(on, line).encoding(Encoding::APPLICATION_JSON).await;
    }

    /// A result or completion for one of the participant's origins.
    async fn answer(&mut self, session: &zenoh::Session, mut o: Output) {
        // A feedback rate is a socket or standard-input reader's: a fleet
        // controller takes feedback from its key expression as published.
        if let Output::Result { result, .. } = &mut o
            && result.ok
            && result.feedback_every.is_some()
        {
            **result = LineResult {
                ok: false,
                line: result.line,
                error: Some(ErrorBody::new(
                    ErrorKind::Unsupported,
                    "feedback_hz sets a socket or standard-input client's feedback rate; a fleet controller takes each motor's feedback from the fleet's feedback key expression, at the rate the bridge publishes it",
                )),
                ..LineResult::default()
            };
        }
        let (origin, last, busy) = match &o {
            Output::Result { origin, result } => (
                *origin,
                result.arrival_follows != Some(true),
                result
                    .error
                    .as_ref()
                    .is_some_and(|e| e.kind == ErrorKind::Busy),
            ),
            Output::Arrival { origin, .. } => (*origin, true, false),
            Output::Feedback(_) | Output::Event(_) | Output::ToOne { .. } => return,
        };
        let line: Arc<str> = Arc::from(o.to_json());
        if origin.0 >= STOP_ORIGINS {
            // A stop put's result: for whoever measures or watches stops.
            self.input.forget(origin);
            let _ = session
                .put(self.keys.estop_result(), &*line)
                .encoding(Encoding::APPLICATION_JSON)
                .await;
            return;
        }
        let Some(p) = self.pending.get_mut(&origin) else {
            self.input.forget(origin);
            return;
        };
        p.sent.push(Arc::clone(&line));
        let queries = std::mem::take(&mut p.queries);
        let on = p.on.clone();
        for q in &queries {
            self.reply(q, &on, &line).await;
        }
        if !last {
            if let Some(p) = self.pending.get_mut(&origin) {
                p.queries = queries;
            }
            return;
        }
        drop(queries); // their replies are complete
        self.input.forget(origin);
        if let Some(Pending {
            id: Some((controller, id, body)),
            sent,
            ..
        }) = self.pending.remove(&origin)
        {
            if busy {
                self.ids.forget(&controller, &id);
            } else {
                self.ids
                    .remember(&controller, &id, body, Recalled::Done(sent));
            }
        }
    }

    async fn publish(&mut self, session: &zenoh::Session, o: &Output) {
        let key = match o {
            Output::Feedback(f) => {
                let in_motion = f
                    .feedback
                    .as_ref()
                    .and_then(|m| m.status.in_motion)
                    .unwrap_or(false);
                if in_motion && f.online {
                    self.moving.insert(f.motor_id.clone());
                } else {
                    self.moving.remove(&f.motor_id);
                }
                self.keys.feedback(&f.motor_id)
            }
            Output::Event(_) => Some(self.keys.event()),
            Output::Result { .. } | Output::Arrival { .. } | Output::ToOne { .. } => None,
        };
        if let Some(key) = key {
            let _ = session
                .put(key, o.to_json())
                .encoding(Encoding::APPLICATION_JSON)
                .await;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A query's payload read as a bridge with the default `--max-size`
    /// reads it.
    fn command(payload: &[u8]) -> Command {
        super::command(payload, motorwire_bridge::DEFAULT_MAX_LINE)
    }
    use motorwire_bridge::motorwire_wia::Validator;
    use motorwire_bridge::{Line, classify};

    fn line(text: &str, id: Option<(CommandId, &str)>) -> Command {
        Command::Line {
            text: text.to_owned(),
            id: id.map(|(id, body)| Keyed {
                id,
                body: Arc::from(body),
            }),
        }
    }

    fn text(id: &str) -> CommandId {
        CommandId::Text(id.to_owned())
    }

    #[test]
    fn request_id_is_cut_out_and_every_other_byte_is_kept() {
        assert_eq!(
            command(br#"{"motor_id":"elbow","setpoint":3,"request_id":"r-1"}"#),
            line(
                r#"{"motor_id":"elbow","setpoint":3}"#,
                Some((text("r-1"), r#"{"motor_id":"elbow","setpoint":3}"#))
            )
        );
        assert_eq!(
            command(br#"{"request_id":42,"motor_id":"elbow"}"#),
            line(
                r#"{"motor_id":"elbow"}"#,
                Some((CommandId::Number(42), r#"{"motor_id":"elbow"}"#))
            )
        );
        // Spaces, a number's spelling and the order stay as they came.
        assert_eq!(
            command(br#"{ "motor_id" : "elbow" , "request_id" : "x" , "setpoint" : 1.50 }"#),
            line(
                r#"{ "motor_id" : "elbow" , "setpoint" : 1.50 }"#,
                Some((text("x"), r#"{"motor_id":"elbow","setpoint":1.50}"#))
            )
        );
        assert_eq!(
            command(br#"{"a":1 , "request_id":"x" }"#),
            line(r#"{"a":1 }"#, Some((text("x"), r#"{"a":1}"#)))
        );
        assert_eq!(
            command(br#"{"request_id":"x"}"#),
            line("{}", Some((text("x"), "{}")))
        );
        // The key as JSON reads it, escapes decoded.
        assert_eq!(
            command(br#"{"request\u005fid":"x","motor_id":"elbow"}"#),
            line(
                r#"{"motor_id":"elbow"}"#,
                Some((text("x"), r#"{"motor_id":"elbow"}"#))
            )
        );
    }

    #[test]
    fn a_repeated_member_stays_repeated_for_the_bridge_to_refuse() {
        assert_eq!(
            command(br#"{"motor_id":"elbow","setpoint":20,"setpoint":140,"request_id":"d1"}"#),
            line(
                r#"{"motor_id":"elbow","setpoint":20,"setpoint":140}"#,
                Some((
                    text("d1"),
                    r#"{"motor_id":"elbow","setpoint":20,"setpoint":140}"#
                ))
            )
        );
        let v = Validator::new();
        let Command::Line { text, .. } = command(
            br#"{"motor_id":"elbow","motor_id":"shoulder_pitch","timestamp":1,"control_mode":"position","setpoint":20,"request_id":"d2"}"#,
        ) else {
            panic!("not a line");
        };
        let Line::Invalid { message, .. } = classify(&v, &text) else {
            panic!("{text} was not refused");
        };
        assert_eq!(
            message,
            "not a valid WIA message: (document): the document satisfies the motor-command schema but motorwire cannot represent it: duplicate field `motor_id` at line 1 column 30 (unrepresentable)"
        );
    }

    #[test]
    fn a_string_id_and_an_integer_id_are_two_ids() {
        let (Command::Line { id: Some(a), .. }, Command::Line { id: Some(b), .. }) = (
            command(br#"{"motor_id":"elbow","request_id":42}"#),
            command(br#"{"motor_id":"elbow","request_id":"42"}"#),
        ) else {
            panic!("no ids");
        };
        assert_eq!(
            (a.id.key(), b.id.key()),
            ("n:42".to_owned(), "s:42".to_owned())
        );
        assert_eq!(
            (a.id.to_string(), b.id.to_string()),
            ("42".to_owned(), r#""42""#.to_owned())
        );
        assert_eq!(a.body, b.body);
        // A retry stamped anew is the same command.
        let (Command::Line { id: Some(a), .. }, Command::Line { id: Some(b), .. }) = (
            command(br#"{"motor_id":"elbow","timestamp":1,"setpoint":2,"request_id":"r"}"#),
            command(br#"{"motor_id":"elbow","timestamp":9,"setpoint":2,"request_id":"r"}"#),
        ) else {
            panic!("no ids");
        };
        assert_eq!(
            (&*a.body, &*b.body),
            (
                r#"{"motor_id":"elbow","timestamp":_,"setpoint":2}"#,
                r#"{"motor_id":"elbow","timestamp":_,"setpoint":2}"#
            )
        );
    }

    #[test]
    fn a_command_that_names_emergency_stop_false_keeps_its_id() {
        for (payload, body) in [
            (
                r#"{"motor_id":"elbow","setpoint":60,"safety_limits":{"emergency_stop":false},"request_id":"r"}"#,
                r#"{"motor_id":"elbow","setpoint":60,"safety_limits":{"emergency_stop":false}}"#,
            ),
            (
                r#"{"command_id":"m","motors":[{"motor_id":"elbow","safety_limits":{"emergency_stop":false}}]}"#,
                r#"{"command_id":"m","motors":[{"motor_id":"elbow","safety_limits":{"emergency_stop":false}}]}"#,
            ),
        ] {
            let Command::Line {
                id: Some(keyed), ..
            } = command(payload.as_bytes())
            else {
                panic!("{payload}: no id");
            };
            assert_eq!(&*keyed.body, body);
        }
    }

    #[test]
    fn stops_and_releases_carry_no_id_and_nothing_about_the_id_refuses_a_stop() {
        for (payload, handed) in [
            (
                r#"{"emergency_stop":true,"request_id":"x"}"#,
                r#"{"emergency_stop":true}"#,
            ),
            (
                r#"{"emergency_stop":true,"request_id":[1]}"#,
                r#"{"emergency_stop":true}"#,
            ),
            (
                r#"{"emergency_stop":true,"request_id":"a","request_id":"b"}"#,
                r#"{"emergency_stop":true,"request_id":"a","request_id":"b"}"#,
            ),
            (
                r#"{"emergency_stop": false}"#,
                r#"{"emergency_stop": false}"#,
            ),
            (
                r#"{"emergency_stop": false, "request_id":"x"}"#,
                r#"{"emergency_stop": false}"#,
            ),
            (
                r#"{"emergency_stop": false, "motor_id":"elbow", "request_id":"x"}"#,
                r#"{"emergency_stop": false, "motor_id":"elbow"}"#,
            ),
            (
                r#"{"motor_id":"elbow","safety_limits":{"emergency_stop":true},"request_id":"x"}"#,
                r#"{"motor_id":"elbow","safety_limits":{"emergency_stop":true}}"#,
            ),
            (
                r#"{"emergency_stop":true,"x":1e400,"request_id":"x"}"#,
                r#"{"emergency_stop":true,"x":1e400,"request_id":"x"}"#,
            ),
        ] {
            assert_eq!(command(payload.as_bytes()), line(handed, None), "{payload}");
        }
    }

    #[test]
    fn every_hostile_line_is_read_as_on_standard_input() {
        let v = Validator::new();
        // The bridge's stop forms (its invariants), repeats, typos, wrong
        // types, bad releases and lines that are no command at all.
        let objects = [
            r#"{"emergency_stop": true}"#,
            r#"{"emergency_stop": "true", "why": "hostile"}"#,
            r#"{"emergency_stop": false, "emergency_stop": true}"#,
            r#"{"emergency_stop": false, "emergency_stop": false}"#,
            r#"{"emergency_stop": 0}"#,
            r#"{"emergency_stop": null, "motor_id": "elbow"}"#,
            r#"{"motor_id":"elbow","timestamp":1,"control_mode":"warp","setpoint":1,"safety_limits":{"emergency_stop":true}}"#,
            r#"{"command_id":"c","timestamp":1,"motors":[{"motor_id":"elbow","control_mode":"position","setpoint":1,"safety_limits":{"emergency_stop":true}}]}"#,
            r#"{"motor_id":"elbow","timestamp":1,"control_mode":"position","setpoint":20,"setpoint":140}"#,
            r#"{"motor_id":"elbow","motor_id":"shoulder_pitch","timestamp":1,"control_mode":"position","setpoint":20}"#,
            r#"{"motor_id":"elbow","timestamp":1,"control_mode":"position","setpoint":20,"velocity_limt":5}"#,
            r#"{"motor_id":"elbow","timestamp":1,"control_mode":"position","setpoint":"20"}"#,
            r#"{"motor_id":"elbow","timestamp":1,"control_mode":"position","setpoint":20,"safety_limits":{"emergency_stop":false}}"#,
            r#"{"command_id":"c","command_id":"d","timestamp":1,"motors":[]}"#,
            r#"{"reset":"elbow"}"#,
            r#"{"reset":"elbow","reset":"wrist"}"#,
            r#"{"query":"limits","motor_id":"elbow"}"#,
            r#"{"orion":"fold","orion":"unfold"}"#,
            r#"{"request":"telemetry","motor_id":"elbow"}"#,
            r#"{"calibration":"start","motor_id":"elbow","phases":99}"#,
            r#"{"trajectory_id":"t","trajectories":[]}"#,
            r#"{"\u0065mergency_stop": true}"#,
            "{}",
        ];
        for form in objects {
            let payload = match form.strip_prefix('{') {
                Some(rest) if rest.starts_with('"') => format!(r#"{{"request_id":"h",{rest}"#),
                _ => format!(r#"{{"request_id":"h"{}"#, form.get(1..).unwrap_or_default()),
            };
            let Command::Line { text, .. } = command(payload.as_bytes()) else {
                panic!("{payload}: refused before the bridge");
            };
            assert_eq!(text, form, "{payload}");
            assert_eq!(classify(&v, &text), classify(&v, form), "{payload}");
        }
        // Lines that are not one object serde_json holds go to the bridge
        // as they came, with no id: it reads them as it reads a line.
        for form in [
            "[1,2]",
            "not json",
            r#"{"motor_id":"elbow""#,
            r#"{"motor_id":"elbow","setpoint":1e400}"#,
            r#"{"emergency_stop":true,"x":1e400}"#,
            r#"{"emergency_stop":true} trailing"#,
            r#"{"a":"\ud800","emergency_stop":true}"#,
        ] {
            assert_eq!(command(form.as_bytes()), line(form, None), "{form}");
        }
    }

    #[test]
    fn a_line_break_inside_a_string_stays_invalid_json_and_a_stop_in_it_stops() {
        let v = Validator::new();
        // Between tokens: a space.
        assert_eq!(one_line(b"{\n\"a\":\r\n1}"), b"{ \"a\":  1}");
        // Inside a string: a raw carriage return (a line feed becomes one),
        // escapes respected.
        assert_eq!(
            one_line(b"{\"a\":\"x\\\"\ny\"}\n"),
            b"{\"a\":\"x\\\"\ry\"} "
        );
        for raw in ["\r", "\n"] {
            let payload = format!(
                r#"{{"motor_id":"elbow","timestamp":1,"control_mode":"position","setpoint":20,"note":"a{raw}b","metadata":{{"emergency_stop":true}},"request_id":"r"}}"#
            );
            let Command::Line { text, id } = command(payload.as_bytes()) else {
                panic!("refused");
            };
            assert_eq!(id, None);
            // Not JSON: it goes on as it came (its request_id too), and
            // the bridge reads it as the same bytes on standard input.
            assert_eq!(text.trim_end(), payload.replace('\n', "\r"));
            assert!(matches!(classify(&v, &text), Line::Stop { .. }), "{text:?}");
            assert!(asks_for_stop(&text));
        }
    }

    #[test]
    fn the_body_keeps_nested_repeats_and_spellings_and_counts_timestamps() {
        let body = |p: &str| match command(p.as_bytes()) {
            Command::Line { id: Some(k), .. } => k.body,
            other => panic!("{other:?}"),
        };
        assert_eq!(
            &*body(
                r#"{"motor_id":"elbow","timestamp":1,"safety_limits":{"max_position":90,"max_position":10},"request_id":"k"}"#
            ),
            r#"{"motor_id":"elbow","timestamp":_,"safety_limits":{"max_position":90,"max_position":10}}"#
        );
        assert_ne!(
            body(r#"{"motor_id":"elbow","safety_limits":{"max_position":10},"request_id":"k"}"#),
            body(
                r#"{"motor_id":"elbow","safety_limits":{"max_position":90,"max_position":10},"request_id":"k"}"#
            )
        );
        // Whitespace between tokens is not the command; inside strings it is.
        assert_eq!(
            body(r#"{ "motor_id" : "elbow" , "setpoint" : [1, 2], "request_id":"k"}"#),
            body(r#"{"motor_id":"elbow","setpoint":[1,2],"request_id":"k"}"#)
        );
        assert_ne!(
            body(r#"{"motor_id":"el bow","request_id":"k"}"#),
            body(r#"{"motor_id":"elbow","request_id":"k"}"#)
        );
        // A timestamp twice is not the command with one.
        assert_ne!(
            body(r#"{"timestamp":1,"timestamp":2,"request_id":"k"}"#),
            body(r#"{"timestamp":3,"request_id":"k"}"#)
        );
        // 1.0 is not 1: the command as written.
        assert_ne!(
            body(r#"{"setpoint":1.0,"request_id":"k"}"#),
            body(r#"{"setpoint":1,"request_id":"k"}"#)
        );
    }

    #[test]
    fn a_long_or_empty_command_id_is_no_id() {
        let long = format!(r#"{{"command_id":"{}","motors":[]}}"#, "c".repeat(257));
        assert_eq!(command(long.as_bytes()), line(&long, None));
        let empty = r#"{"command_id":"","motors":[]}"#;
        assert_eq!(command(empty.as_bytes()), line(empty, None));
    }

    #[test]
    fn only_a_zenoh_id_is_a_bridge() {
        assert!(is_zid("4a753e271844afeb3f1d1450df42d3ab"));
        assert!(is_zid("f8c46323752c1dbaf10c60ee5959d6"));
        for not in ["", "!", "zz", "4a753e271844afeb3f1d1450df42d3ab0", "a b"] {
            assert!(!is_zid(not), "{not:?}");
        }
    }

    #[test]
    fn every_reply_says_which_robot_and_which_bridge_answered() {
        assert_eq!(
            signed(r#"{"ok":true,"line":1}"#, r#""arm-1""#, "a1b2"),
            r#"{"ok":true,"line":1,"robot":"arm-1","bridge":"a1b2"}"#
        );
        assert_eq!(signed("{}", r#""a""#, "z"), r#"{"robot":"a","bridge":"z"}"#);
        assert_eq!(signed("[1]", r#""a""#, "z"), "[1]");
    }

    #[test]
    fn a_pretty_printed_command_is_one_line() {
        assert_eq!(
            command(b"{\n  \"motor_id\": \"elbow\"\r\n}\n"),
            line("{   \"motor_id\": \"elbow\"  } ", None)
        );
    }

    #[test]
    fn a_bad_or_repeated_request_id_or_an_unreadable_payload_is_refused() {
        for (payload, reason) in [
            (
                r#"{"motor_id":"elbow","request_id":""}"#,
                r#"request_id "" is not a non-empty string of at most 256 bytes or an unsigned integer; nothing was sent"#,
            ),
            (
                r#"{"motor_id":"elbow","request_id":[1]}"#,
                "request_id [1] is not a non-empty string of at most 256 bytes or an unsigned integer; nothing was sent",
            ),
            (
                r#"{"motor_id":"elbow","request_id":-1}"#,
                "request_id -1 is not a non-empty string of at most 256 bytes or an unsigned integer; nothing was sent",
            ),
            (
                r#"{"motor_id":"elbow","request_id":"a","request_id":"a"}"#,
                "request_id appears 2 times: a command has one id; nothing was sent",
            ),
        ] {
            assert_eq!(
                command(payload.as_bytes()),
                Command::Refused {
                    reason: reason.to_owned(),
                    stop: false
                },
                "{payload}"
            );
        }
        assert!(matches!(command(b""), Command::Refused { stop: false, .. }));
        assert!(matches!(
            command(b" \n "),
            Command::Refused { stop: false, .. }
        ));
        assert!(matches!(
            command(b"{\"emergency_stop\":true,\"x\":\"\xff\"}"),
            Command::Refused { stop: true, .. }
        ));
        let long = format!(
            r#"{{"emergency_stop":true,"pad":"{}"}}"#,
            "x".repeat(70_000)
        );
        // Over the bridge's --max-size: refused, and a stop.
        assert_eq!(
            super::command(long.as_bytes(), 65_536),
            Command::Refused {
                reason: "the command is over 65536 bytes (the bridge's --max-size)".to_owned(),
                stop: true
            }
        );
        assert!(matches!(command(long.as_bytes()), Command::Line { .. }));
    }

    #[test]
    fn command_id_is_the_id_of_a_multi_axis_command_and_request_id_wins() {
        let t = r#"{"command_id":"c1","motors":[]}"#;
        assert_eq!(command(t.as_bytes()), line(t, Some((text("c1"), t))));
        assert_eq!(
            command(br#"{"command_id":"c1","request_id":"r"}"#),
            line(
                r#"{"command_id":"c1"}"#,
                Some((text("r"), r#"{"command_id":"c1"}"#))
            )
        );
    }

    #[test]
    fn a_reused_id_is_refused_naming_the_first_command() {
        let r: Value = serde_json::from_str(&id_reused(
            &text("d1"),
            r#"{"motor_id":"elbow","setpoint":20}"#,
        ))
        .unwrap_or_default();
        assert_eq!(
            r,
            serde_json::json!({
                "ok": false,
                "line": 0,
                "error": {
                    "kind": "id_reused",
                    "rule": "id_reused",
                    "message": r#"the id "d1" is this controller's id of another command, {"motor_id":"elbow","setpoint":20}; a retry carries the same command as its first try, a new command a new id; nothing was sent"#,
                },
            })
        );
        let long = format!(r#"{{"x":"{}"}}"#, "é".repeat(300));
        let r: Value =
            serde_json::from_str(&id_reused(&CommandId::Number(7), &long)).unwrap_or_default();
        let message = r["error"]["message"].as_str().unwrap_or_default();
        assert!(
            message.starts_with(r#"the id 7 is this controller's id of another command, {"x":""#)
        );
        assert!(message.contains("é...; a retry"), "{message}");
    }
}
