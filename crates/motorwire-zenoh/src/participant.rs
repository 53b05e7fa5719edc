//! The bridge as a Zenoh participant: queries in, replies, publications
//! and the liveliness token out, on a runtime of its own.

use std::collections::{BTreeSet, HashMap};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

use motorwire_bridge::{
    ErrorBody, ErrorKind, InputSender, LineResult, Origin, Output, ReadLine, asks_for_stop,
    read_line,
};
use serde_json::Value;
use tokio::sync::mpsc;
use zenoh::bytes::Encoding;
use zenoh::query::Query;

use crate::ZenohError;
use crate::ids::{CONTROLLERS, IDS_PER_CONTROLLER, IdMemory, Recalled};
use crate::keys::{FLEET_ESTOP, RobotKeys};

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
        let task = runtime.spawn(async move {
            let FleetConfig {
                keys,
                zenoh,
                session_timeout,
                ids_per_controller,
                controllers,
            } = config;
            let mut failed = false;
            let session = loop {
                match zenoh::open(zenoh.clone()).await {
                    Ok(s) => break s,
                    Err(e) => {
                        // Said once, not every second.
                        if !failed {
                            note(&format!(
                                "zenoh: {e}; trying again every {RETRY_OPEN:?} (the bridge runs meanwhile)"
                            ));
                            failed = true;
                        }
                        tokio::time::sleep(RETRY_OPEN).await;
                    }
                }
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
            note(&format!("in the fleet as motorwire/{}", keys.robot()));
            let state = State {
                keys,
                input,
                next_origin: QUERY_ORIGINS,
                stops,
                pending: HashMap::new(),
                ids: IdMemory::new(ids_per_controller, controllers),
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
        match o {
            Output::Result { origin, .. } | Output::Arrival { origin, .. } => {
                if !Self::owns(*origin) {
                    return false;
                }
                let _ = self.replies.send(Msg::Output(Box::new(o.clone())));
                true
            }
            Output::Feedback(_) | Output::Event(_) => {
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
        zenoh::liveliness::LivelinessToken,
    ),
    ZenohError,
> {
    let queryable = session
        .declare_queryable(keys.cmd())
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
    let token = session
        .liveliness()
        .declare_token(keys.alive())
        .await
        .map_err(ZenohError::zenoh)?;
    Ok((queryable, subscribers, token))
}

/// A command query's line in progress.
#[derive(Debug)]
struct Pending {
    /// The queries waiting for its replies (the first, and its retries).
    queries: Vec<Query>,
    /// `(controller, id)` when it carried an id.
    id: Option<(String, String)>,
    /// The replies so far.
    sent: Vec<Arc<str>>,
}

/// What a query's payload asks.
#[derive(Debug, PartialEq)]
enum Command {
    /// A line to hand over, with its id when it has one.
    Line { text: String, id: Option<String> },
    /// A line the bridge must refuse (it names a stop: it stops).
    Refused { reason: String, stop: bool },
}

/// Reads a query's payload as the line interface reads a line; takes its
/// `request_id` (removed from the line) or its `command_id`.
fn command(payload: &[u8]) -> Command {
    // A pretty-printed command is one line once its newlines are spaces
    // (JSON allows no raw newline inside a string anyway).
    let mut bytes: Vec<u8> = payload
        .iter()
        .map(|b| if matches!(b, b'\n' | b'\r') { b' ' } else { *b })
        .collect();
    bytes.push(b'\n');
    let text = match read_line(&mut std::io::Cursor::new(bytes)) {
        // A blank line would get no result at all: refused instead.
        Ok(ReadLine::Line(s)) if !s.trim().is_empty() => s,
        Ok(ReadLine::TooLong { names_stop }) => {
            return Command::Refused {
                reason: format!("the command is over {} bytes", motorwire_bridge::MAX_LINE),
                stop: names_stop,
            };
        }
        Ok(ReadLine::NotUtf8 { names_stop }) => {
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
    // Stops and the release are handed over exactly as they came, and are
    // never remembered: a stop always acts, and a release repeated is
    // answered `not_latched`.
    if asks_for_stop(text.trim()) || text.contains("emergency_stop") {
        return Command::Line { text, id: None };
    }
    let Ok(Value::Object(mut members)) = serde_json::from_str::<Value>(&text) else {
        return Command::Line { text, id: None }; // the bridge says why
    };
    match members.remove("request_id") {
        None => {
            let id = match members.get("command_id") {
                Some(Value::String(s)) => Some(s.clone()),
                _ => None,
            };
            Command::Line { text, id }
        }
        Some(Value::String(s)) if !s.is_empty() && s.len() <= MAX_NAME => Command::Line {
            text: Value::Object(members).to_string(),
            id: Some(s),
        },
        Some(Value::Number(n)) if n.is_u64() => Command::Line {
            text: Value::Object(members).to_string(),
            id: Some(n.to_string()),
        },
        Some(_) => Command::Refused {
            reason: format!(
                "request_id must be a non-empty string of at most {MAX_NAME} bytes or an unsigned integer"
            ),
            stop: false,
        },
    }
}

/// The participant's state, owned by its one task.
struct State {
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
        token: zenoh::liveliness::LivelinessToken,
        mut replies: mpsc::UnboundedReceiver<Msg>,
        mut publish: mpsc::Receiver<Msg>,
    ) {
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
        let controller = q.parameters().get("controller").unwrap_or("").to_owned();
        let command = if controller.len() > MAX_NAME {
            Command::Refused {
                reason: format!("the controller parameter is over {MAX_NAME} bytes"),
                stop: asks_for_stop(&String::from_utf8_lossy(&payload)),
            }
        } else {
            command(&payload)
        };
        if let Command::Line { id: Some(id), .. } = &command {
            match self.ids.recall(&controller, id) {
                Some(Recalled::Done(lines)) => {
                    for line in &lines {
                        self.reply(&q, line).await;
                    }
                    return; // dropping the query ends its replies
                }
                Some(Recalled::InProgress(origin)) => {
                    if let Some(p) = self.pending.get_mut(&origin) {
                        for line in p.sent.clone() {
                            self.reply(&q, &line).await;
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
        if self.pending.len() >= MAX_QUERIES_IN_PROGRESS {
            let busy = LineResult {
                ok: false,
                error: Some(ErrorBody::new(
                    ErrorKind::Busy,
                    format!(
                        "{MAX_QUERIES_IN_PROGRESS} commands are in progress on this bridge; nothing was sent"
                    ),
                )),
                ..LineResult::default()
            };
            let text = Output::Result {
                origin: Origin(0),
                result: busy,
            }
            .to_json();
            self.reply(&q, &text).await;
            return;
        }
        let origin = Origin(self.next_origin);
        self.next_origin += 1;
        let id = match &command {
            Command::Line { id: Some(id), .. } => {
                self.ids
                    .remember(&controller, id, Recalled::InProgress(origin));
                Some((controller, id.clone()))
            }
            _ => None,
        };
        self.pending.insert(
            origin,
            Pending {
                queries: vec![q],
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

    async fn reply(&self, q: &Query, line: &str) {
        let _ = q
            .reply(self.keys.cmd(), line)
            .encoding(Encoding::APPLICATION_JSON)
            .await;
    }

    /// A result or completion for one of the participant's origins.
    async fn answer(&mut self, session: &zenoh::Session, o: Output) {
        let (origin, last, busy) = match &o {
            Output::Result { origin, result } => (
                *origin,
                !result.arrival_follows,
                result
                    .error
                    .as_ref()
                    .is_some_and(|e| e.kind == ErrorKind::Busy),
            ),
            Output::Arrival { origin, .. } => (*origin, true, false),
            Output::Feedback(_) | Output::Event(_) => return,
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
        for q in &queries {
            self.reply(q, &line).await;
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
            id: Some((controller, id)),
            sent,
            ..
        }) = self.pending.remove(&origin)
        {
            if busy {
                self.ids.forget(&controller, &id);
            } else {
                self.ids.remember(&controller, &id, Recalled::Done(sent));
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
            Output::Result { .. } | Output::Arrival { .. } => None,
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

    fn line(text: &str, id: Option<&str>) -> Command {
        Command::Line {
            text: text.to_owned(),
            id: id.map(str::to_owned),
        }
    }

    #[test]
    fn request_id_is_taken_out_of_the_line() {
        assert_eq!(
            command(br#"{"motor_id":"elbow","setpoint":3,"request_id":"r-1"}"#),
            line(r#"{"motor_id":"elbow","setpoint":3}"#, Some("r-1"))
        );
        assert_eq!(
            command(br#"{"request_id":42,"motor_id":"elbow"}"#),
            line(r#"{"motor_id":"elbow"}"#, Some("42"))
        );
    }

    #[test]
    fn command_id_is_the_id_of_a_multi_axis_command_and_the_line_is_unchanged() {
        let text = r#"{"command_id":"c1","motors":[]}"#;
        assert_eq!(command(text.as_bytes()), line(text, Some("c1")));
        // request_id wins, and is removed.
        assert_eq!(
            command(br#"{"command_id":"c1","request_id":"r"}"#),
            line(r#"{"command_id":"c1"}"#, Some("r"))
        );
    }

    #[test]
    fn stops_and_releases_are_handed_over_exactly_and_carry_no_id() {
        for text in [
            r#"{"emergency_stop":true,"request_id":"x"}"#,
            r#"{"emergency_stop": false}"#,
            r#"{"emergency_stop": false, "request_id":"x"}"#,
            r#"{"motor_id":"elbow","safety_limits":{"emergency_stop":true},"request_id":"x"}"#,
        ] {
            assert_eq!(command(text.as_bytes()), line(text, None), "{text}");
        }
    }

    #[test]
    fn a_pretty_printed_command_is_one_line() {
        assert_eq!(
            command(b"{\n  \"motor_id\": \"elbow\"\r\n}\n"),
            line("{   \"motor_id\": \"elbow\"  } ", None)
        );
    }

    #[test]
    fn a_bad_request_id_or_an_unreadable_payload_is_refused() {
        assert!(matches!(
            command(br#"{"motor_id":"elbow","request_id":""}"#),
            Command::Refused { stop: false, .. }
        ));
        assert!(matches!(
            command(br#"{"motor_id":"elbow","request_id":[1]}"#),
            Command::Refused { stop: false, .. }
        ));
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
        assert!(matches!(
            command(long.as_bytes()),
            Command::Refused { stop: true, .. }
        ));
    }

    #[test]
    fn json_that_is_not_an_object_goes_to_the_bridge_as_it_is() {
        assert_eq!(command(b"[1,2]"), line("[1,2]", None));
        assert_eq!(command(b"not json"), line("not json", None));
    }
}
