//! `motorwire bridge --view ADDR` over HTTP as a browser (or anyone else)
//! reaches it: the page, its event stream, and what it refuses (issue 28
//! part 3; the page in a real browser: `.ci/view-test.py`).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod common;

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::time::Duration;

/// The address the bridge printed for its view.
fn view_addr(child: &mut std::process::Child) -> (String, BufReader<std::process::ChildStderr>) {
    let mut err = BufReader::new(child.stderr.take().unwrap());
    let mut line = String::new();
    loop {
        line.clear();
        assert!(err.read_line(&mut line).unwrap() > 0, "no view address");
        if let Some(rest) = line.split("the live view at http://").nth(1) {
            let addr = rest.split('/').next().unwrap().to_owned();
            return (addr, err);
        }
    }
}

/// A bridge on the demo arm with its view on a loopback port (and
/// `extra`): the bridge, the view's address, its standard error.
fn bridge_with_view(
    extra: &[&str],
) -> (
    std::process::Child,
    String,
    BufReader<std::process::ChildStderr>,
) {
    let mut args = common::sim_bridge(&["--feedback-hz", "0", "--view", "127.0.0.1:0"]);
    args.extend_from_slice(extra);
    let mut child = common::spawn(&args);
    let (addr, err) = view_addr(&mut child);
    (child, addr, err)
}

fn get(addr: &str, request: &str) -> String {
    let mut s = TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
    s.write_all(request.as_bytes()).unwrap();
    let mut out = String::new();
    let _ = s.read_to_string(&mut out);
    out
}

/// The page and its stream on a loopback port: the page is whole (its
/// script inside, nothing fetched from elsewhere), the stream starts with
/// the map's motors and the bridge's `ready`, then carries the lines as
/// they come (an input line and its result); anything but a GET of the
/// page or the stream is refused.
#[test]
fn the_view_serves_its_page_and_stream_and_only_reads() {
    let (mut child, addr, _err) = bridge_with_view(&[]);
    let page = get(&addr, &format!("GET / HTTP/1.1\r\nHost: {addr}\r\n\r\n"));
    assert!(page.starts_with("HTTP/1.1 200 OK\r\n"), "{page}");
    assert!(page.contains("Content-Type: text/html; charset=utf-8"));
    assert!(page.contains("new EventSource(\"events\""));
    assert!(!page.contains("src=\"http"), "an external asset");
    for (request, status) in [
        (
            "POST / HTTP/1.1\r\nHost: {addr}\r\n\r\n",
            "405 Method Not Allowed",
        ),
        (
            "GET /etc/passwd HTTP/1.1\r\nHost: {addr}\r\n\r\n",
            "404 Not Found",
        ),
        ("nonsense\r\n\r\n", "400 Bad Request"),
    ] {
        let request = request.replace("{addr}", &addr);
        let r = get(&addr, &request);
        assert!(
            r.starts_with(&format!("HTTP/1.1 {status}\r\n")),
            "{request:?}: {r}"
        );
    }
    let mut stream = TcpStream::connect(&addr).unwrap();
    stream
        .set_read_timeout(Some(Duration::from_secs(10)))
        .unwrap();
    stream
        .write_all(format!("GET /events HTTP/1.1\r\nHost: {addr}\r\n\r\n").as_bytes())
        .unwrap();
    let mut events = BufReader::new(stream);
    let mut head = String::new();
    events.read_line(&mut head).unwrap();
    assert_eq!(head, "HTTP/1.1 200 OK\r\n");
    let mut data = Vec::new();
    let mut line = String::new();
    let mut stdin = child.stdin.take().unwrap();
    let mut sent = false;
    while data.len() < 40 {
        line.clear();
        if events.read_line(&mut line).unwrap() == 0 {
            break;
        }
        if let Some(d) = line.strip_prefix("data: ") {
            let v: serde_json::Value = serde_json::from_str(d.trim_end()).unwrap();
            let ready = v["line"]["event"] == "ready";
            let answered = v["kind"] == "out" && v["line"]["line"] == 1;
            data.push(v);
            if ready && !sent {
                stdin.write_all(b"{\"emergency_stop\":true}\n").unwrap();
                sent = true;
            }
            if answered {
                break;
            }
        }
    }
    assert_eq!(data[0]["kind"], "hello");
    let elbow = data[0]["motors"]
        .as_array()
        .unwrap()
        .iter()
        .find(|m| m["motor_id"] == "elbow")
        .unwrap();
    assert_eq!(
        *elbow,
        serde_json::json!({"motor_id": "elbow", "dialect": "irpc", "quantity": "position", "unit": "°",
            "min_position": 0.0, "max_position": 150.0, "max_velocity": 120.0})
    );
    let turntable = data[0]["motors"]
        .as_array()
        .unwrap()
        .iter()
        .find(|m| m["motor_id"] == "turntable")
        .unwrap();
    assert_eq!(turntable["quantity"], "speed");
    assert_eq!(turntable["unit"], "controller units");
    let input = data
        .iter()
        .find(|v| v["kind"] == "in")
        .expect("the input line");
    assert_eq!(input["text"], "{\"emergency_stop\":true}");
    assert_eq!(input["line"], 1);
    assert!(data.iter().any(|v| v["line"]["event"] == "emergency_stop"));
    let result = data.last().unwrap();
    assert_eq!(result["line"]["emergency_stop"], true, "{result}");
    assert_eq!(result["to"], 0);
    assert!(result["t"].as_f64().unwrap() >= input["t"].as_f64().unwrap());
    drop(stdin);
    let out = child.wait_with_output().unwrap();
    assert_eq!(out.status.code(), Some(0));
}

/// Another address than loopback only with the view's own token, and
/// then the page and its stream only for who has it; never the control
/// token (it would let whoever has the page's address move the motors).
#[test]
fn a_view_beyond_loopback_needs_a_token_of_its_own() {
    let dir = std::env::temp_dir().join(format!("motorwire-view-token-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let write_token = |name: &str, text: &str| {
        let path = dir.join(name);
        std::fs::write(&path, text).unwrap();
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o600)).unwrap();
        }
        path.to_str().unwrap().to_owned()
    };
    let control = write_token("control", "control-token-0123456789\n");
    let same = write_token("same", "control-token-0123456789\n");
    let token = write_token("view", "0123456789abcdef0123\n");
    for (args, needle) in [
        (
            vec!["--view", "0.0.0.0:0"],
            "--view 0.0.0.0:0: not a loopback address: anyone who reaches it would see the session; give --view-token-file FILE",
        ),
        // The control token does not open a view beyond loopback.
        (
            vec!["--view", "0.0.0.0:0", "--token-file", &control],
            "--view 0.0.0.0:0: not a loopback address",
        ),
        (
            vec![
                "--view",
                "127.0.0.1:0",
                "--token-file",
                &control,
                "--view-token-file",
                &same,
            ],
            "the control token (--token-file's): whoever has the page's address could move the motors with it",
        ),
    ] {
        let out = common::run(&common::sim_bridge(&args), b"");
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        let err = String::from_utf8(out.stderr).unwrap();
        assert!(err.contains(needle), "{args:?}: {err}");
    }
    let (mut child, addr, _err) =
        bridge_with_view(&["--token-file", &control, "--view-token-file", &token]);
    for path in [
        "/",
        "/events",
        "/?token=0123456789abcdef012",
        "/?token=wrong",
        "/?token=control-token-0123456789",
    ] {
        let r = get(
            &addr,
            &format!("GET {path} HTTP/1.1\r\nHost: {addr}\r\n\r\n"),
        );
        assert!(r.starts_with("HTTP/1.1 403 Forbidden\r\n"), "{path}: {r}");
    }
    let r = get(
        &addr,
        &format!("GET /?token=0123456789abcdef0123 HTTP/1.1\r\nHost: {addr}\r\n\r\n"),
    );
    assert!(r.starts_with("HTTP/1.1 200 OK\r\n"), "{r}");
    drop(child.stdin.take());
    let out = child.wait_with_output().unwrap();
    assert_eq!(out.status.code(), Some(0));
    let _ = std::fs::remove_dir_all(&dir);
}

/// Bounded against hostile clients: a request's head has 2 s in all (a
/// client dripping a byte a second is closed, not served for hours), and
/// of 24 pages opening at once, 16 get their stream and the rest 503.
#[test]
fn slow_heads_are_cut_and_pages_are_bounded() {
    let (mut child, addr, _err) = bridge_with_view(&[]);
    let mut drip = TcpStream::connect(&addr).unwrap();
    let began = std::time::Instant::now();
    let mut closed = None;
    for b in b"GET / HTTP/1.1\r\nX-Slow: aaaaaaaaaaaaaaaaaaaa" {
        if drip.write_all(&[*b]).is_err() {
            closed = Some(began.elapsed());
            break;
        }
        std::thread::sleep(Duration::from_millis(300));
    }
    if closed.is_none() {
        drip.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
        let mut got = String::new();
        let _ = drip.read_to_string(&mut got);
        assert!(got.is_empty() || got.starts_with("HTTP/1.1 400"), "{got}");
        closed = Some(began.elapsed());
    }
    let closed = closed.unwrap();
    assert!(closed < Duration::from_secs(8), "held {closed:?}");

    let streams: Vec<std::thread::JoinHandle<String>> = (0..24)
        .map(|_| {
            let addr = addr.clone();
            std::thread::spawn(move || {
                let mut s = TcpStream::connect(&addr).unwrap();
                s.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
                s.write_all(format!("GET /events HTTP/1.1\r\nHost: {addr}\r\n\r\n").as_bytes())
                    .unwrap();
                // The status line, whole.
                let mut head = Vec::new();
                let mut byte = [0u8; 1];
                while !head.ends_with(b"\r\n") && s.read(&mut byte).unwrap_or(0) == 1 {
                    head.push(byte[0]);
                }
                // Held open a moment, as a page is.
                std::thread::sleep(Duration::from_millis(500));
                String::from_utf8_lossy(&head).into_owned()
            })
        })
        .collect();
    let heads: Vec<String> = streams.into_iter().map(|h| h.join().unwrap()).collect();
    let served = heads
        .iter()
        .filter(|h| h.starts_with("HTTP/1.1 200"))
        .count();
    let refused = heads
        .iter()
        .filter(|h| h.starts_with("HTTP/1.1 503"))
        .count();
    assert_eq!((served, refused), (16, 8), "{heads:?}");
    drop(child.stdin.take());
    let out = child.wait_with_output().unwrap();
    assert_eq!(out.status.code(), Some(0));
}

/// Pages that never read hold up only themselves (found by a hostile
/// test: each stuck page held the view's one thread for its write
/// time-out, and 15 of them kept a stop from an honest page for seconds):
/// with 4 MB of history that no stuck page takes, an honest page opened
/// after them gets its history and then the stop at once.
#[test]
fn pages_that_never_read_never_hold_up_an_honest_one() {
    let (mut child, addr, _err) = bridge_with_view(&[]);
    let mut stdin = child.stdin.take().unwrap();
    let mut stdout = BufReader::new(child.stdout.take().unwrap());
    // History: a thousand long lines (each refused, each kept 4 KiB).
    let long = format!("{{\"note\":\"{}\"}}\n", "x".repeat(4_000));
    for _ in 0..1_000 {
        stdin.write_all(long.as_bytes()).unwrap();
    }
    stdin.flush().unwrap();
    let mut line = String::new();
    let mut answered = 0;
    while answered < 1_000 {
        line.clear();
        assert!(stdout.read_line(&mut line).unwrap() > 0);
        if line.starts_with("{\"ok\":") {
            answered += 1;
        }
    }
    // Fifteen pages that ask for the stream and never read it.
    let stuck: Vec<TcpStream> = (0..15)
        .map(|_| {
            let mut s = TcpStream::connect(&addr).unwrap();
            s.write_all(format!("GET /events HTTP/1.1\r\nHost: {addr}\r\n\r\n").as_bytes())
                .unwrap();
            s
        })
        .collect();
    std::thread::sleep(Duration::from_millis(300));
    let mut honest = TcpStream::connect(&addr).unwrap();
    honest
        .set_read_timeout(Some(Duration::from_secs(10)))
        .unwrap();
    honest
        .write_all(format!("GET /events HTTP/1.1\r\nHost: {addr}\r\n\r\n").as_bytes())
        .unwrap();
    let mut events = BufReader::new(honest);
    // Its history, to the last of the thousand lines.
    let mut seen = 0;
    while seen < 1_000 {
        line.clear();
        assert!(events.read_line(&mut line).unwrap() > 0);
        if line.starts_with("data: {\"kind\":\"in\"") && line.contains("xxxx") {
            seen += 1;
        }
    }
    let began = std::time::Instant::now();
    stdin.write_all(b"{\"emergency_stop\":true}\n").unwrap();
    stdin.flush().unwrap();
    loop {
        line.clear();
        assert!(events.read_line(&mut line).unwrap() > 0, "the page was cut");
        if line.starts_with("data: {\"kind\":\"out\"") && line.contains("\"emergency_stop\":true") {
            break;
        }
    }
    let waited = began.elapsed();
    assert!(
        waited < Duration::from_millis(500),
        "the stop reached the page after {waited:?}"
    );
    drop(stuck);
    drop(stdin);
    assert_eq!(child.wait().unwrap().code(), Some(0));
}

/// The view answers only its own address (issue 58 part 7): a web page
/// that makes a name of its own resolve to 127.0.0.1 (DNS rebinding)
/// sends `Host: that.name:PORT` and would read the session as its own;
/// a page of another site sends `Origin` and `Sec-Fetch-Site`. Each is
/// refused, before it can take one of the 16 page slots, and the view's
/// own address, `localhost` and a `--view-host` name are served.
#[test]
fn the_view_answers_only_its_own_address() {
    let (mut child, addr, _err) = bridge_with_view(&["--view-host", "Arm.Lab"]);
    let port = addr.rsplit(':').next().unwrap().to_owned();
    let status = |path: &str, headers: &str| {
        let r = get(&addr, &format!("GET {path} HTTP/1.1\r\n{headers}\r\n"));
        r.split("\r\n").next().unwrap().to_owned()
    };
    // Twenty streams asked for by a rebound name: none takes a slot.
    for _ in 0..20 {
        assert_eq!(
            status("/events", &format!("Host: rebind.attacker.test:{port}\r\n")),
            "HTTP/1.1 403 Forbidden"
        );
    }
    for (path, headers, expected) in [
        (
            "/",
            format!("Host: rebind.attacker.test:{port}\r\n"),
            "403 Forbidden",
        ),
        ("/", "Host: 127.0.0.1\r\n".to_owned(), "403 Forbidden"),
        ("/", format!("Host: 127.0.0.2:{port}\r\n"), "403 Forbidden"),
        (
            "/",
            format!("Host: localhost.attacker.test:{port}\r\n"),
            "403 Forbidden",
        ),
        ("/", String::new(), "403 Forbidden"),
        (
            "/",
            format!("Host: {addr}\r\nHost: rebind.attacker.test:{port}\r\n"),
            "400 Bad Request",
        ),
        (
            "/events",
            format!("Host: {addr}\r\nOrigin: http://rebind.attacker.test:{port}\r\n"),
            "403 Forbidden",
        ),
        (
            "/events",
            format!("Host: {addr}\r\nOrigin: null\r\n"),
            "403 Forbidden",
        ),
        (
            "/events",
            format!("Host: {addr}\r\nSec-Fetch-Site: cross-site\r\n"),
            "403 Forbidden",
        ),
        (
            "/",
            format!("Host: {addr}\r\nSec-Fetch-Site: same-site\r\n"),
            "403 Forbidden",
        ),
        ("/", format!("Host: {addr}\r\n"), "200 OK"),
        ("/", format!("host:   LOCALHOST:{port}\r\n"), "200 OK"),
        ("/", format!("Host: arm.lab:{port}\r\n"), "200 OK"),
        (
            "/",
            format!("Host: {addr}\r\nSec-Fetch-Site: none\r\n"),
            "200 OK",
        ),
    ] {
        assert_eq!(
            status(path, &headers),
            format!("HTTP/1.1 {expected}"),
            "{path} {headers:?}"
        );
    }
    // The page's own stream, as a browser asks for it: served.
    let mut s = TcpStream::connect(&addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
    s.write_all(
        format!(
            "GET /events HTTP/1.1\r\nHost: {addr}\r\nOrigin: http://{addr}\r\nSec-Fetch-Site: same-origin\r\n\r\n"
        )
        .as_bytes(),
    )
    .unwrap();
    let mut head = String::new();
    BufReader::new(&s).read_line(&mut head).unwrap();
    assert_eq!(head, "HTTP/1.1 200 OK\r\n");
    drop(s);
    drop(child.stdin.take());
    let out = child.wait_with_output().unwrap();
    assert_eq!(out.status.code(), Some(0));
}
