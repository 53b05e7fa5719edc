//! Unit tests.

use super::*;
use std::sync::atomic::AtomicUsize;
use std::sync::mpsc::RecvTimeoutError;
use std::time::Duration;

/// A secret is found anywhere in a line, and in an unreadable line's
/// first bytes whole or cut at their end (8 of its bytes or more).
#[test]
#[allow(clippy::unwrap_used)]
fn a_secret_is_found_whole_in_a_line_or_cut_at_a_heads_end() {
    assert!(Secret::new("", "r").is_none());
    let k = Secret::new("correct-horse-battery", "r").unwrap();
    assert!(k.in_line("correct-horse-battery"));
    assert!(k.in_line(r#"{"token":"correct-horse-battery"}"#));
    assert!(!k.in_line("correct-horse-batter"));
    assert!(k.in_head(b"\xff correct-horse-battery \xff"));
    assert!(k.in_head(b"\xff\xff correct-h"));
    assert!(!k.in_head(b"\xff\xff correct"));
    assert!(!k.in_head(b"\xff horse-battery"));
    assert!(!k.in_head(b""));
}

/// The bridge's wall clock is read with its monotonic one: the pair
/// lies between readings taken before and after, and many pairs agree
/// with each other to well under a millisecond (a pair 1 ms apart
/// made a command stamped after a stop's release `stale_before_stop`).
#[test]
#[allow(clippy::unwrap_used)]
fn the_wall_clock_is_read_with_the_monotonic_clock() {
    use std::time::{SystemTime, UNIX_EPOCH};
    let wall = || {
        SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .unwrap()
            .as_secs_f64()
            * 1000.0
    };
    let ms = |wall: Option<Duration>| wall.unwrap().as_secs_f64() * 1000.0;
    let (first_at, first) = clocks_together();
    let first_ms = ms(first);
    for _ in 0..1000 {
        let before_ms = wall();
        let before = Instant::now();
        let (at, pair) = clocks_together();
        let after = Instant::now();
        let after_ms = wall();
        let ms = ms(pair);
        assert!(before <= at && at <= after);
        assert!(
            before_ms <= ms && ms <= after_ms,
            "{before_ms} {ms} {after_ms}"
        );
        // The same offset between the clocks as the first pair's.
        let offset = (ms - first_ms) - at.duration_since(first_at).as_secs_f64() * 1000.0;
        assert!(offset.abs() < 0.5, "{offset} ms");
    }
}

/// One client's waiting lines are bounded in bytes as well as in
/// number: a line that would take them past
/// [`MAX_QUEUED_BYTES_PER_ORIGIN`] waits until the runner takes one,
/// and a line alone always fits.
#[test]
fn an_origins_queue_is_bounded_in_bytes() {
    let budget = Arc::new(Budget::default());
    let o = Origin(7);
    let big = MAX_QUEUED_BYTES_PER_ORIGIN - 1000;
    budget.take(o, false, big);
    // Another origin, and a stop of the same one, are not held.
    budget.take(Origin(8), false, big);
    budget.take(o, true, big);
    let (done, taken) = mpsc::channel();
    let waiter = {
        let budget = Arc::clone(&budget);
        thread::spawn(move || {
            budget.take(o, false, 2000);
            let _ = done.send(());
        })
    };
    assert_eq!(
        taken.recv_timeout(Duration::from_millis(200)),
        Err(RecvTimeoutError::Timeout),
        "2000 bytes more would pass the bound: the sender waits"
    );
    budget.give(o, false, big);
    taken.recv_timeout(Duration::from_secs(10)).unwrap();
    waiter.join().unwrap();
    // A line over the bound alone is let in.
    budget.give(o, false, 2000);
    budget.take(o, false, MAX_QUEUED_BYTES_PER_ORIGIN * 2);
    let q = budget.queued.lock().unwrap();
    assert_eq!(
        q.get(&(o, false)),
        Some(&(1, MAX_QUEUED_BYTES_PER_ORIGIN * 2))
    );
}

/// A gate shut until opened, or for good.
#[derive(Default)]
struct Shut {
    open: Mutex<Option<bool>>,
    changed: Condvar,
    admitted: AtomicUsize,
    stops: AtomicUsize,
}

impl Shut {
    fn set(&self, open: bool) {
        *self.open.lock().unwrap_or_else(PoisonError::into_inner) = Some(open);
        self.changed.notify_all();
    }
}

impl Gate for Shut {
    fn admit(&self) -> bool {
        let mut open = self.open.lock().unwrap_or_else(PoisonError::into_inner);
        while open.is_none() {
            open = self
                .changed
                .wait(open)
                .unwrap_or_else(PoisonError::into_inner);
        }
        let go = *open == Some(true);
        if go {
            self.admitted.fetch_add(1, Ordering::SeqCst);
        }
        go
    }

    fn admit_stop(&self) {
        self.stops.fetch_add(1, Ordering::SeqCst);
    }
}

/// What a message handed to the runner is: (number, text or reason).
fn handed(msg: Msg) -> Option<(u64, String)> {
    match msg {
        Msg::Line { number, text, .. } => Some((number, text)),
        Msg::Refused { number, reason, .. } => Some((number, reason)),
        _ => None,
    }
}

/// Lines fed through a shut gate wait for it, read ahead and numbered
/// in the order they were read; a stop read behind them is handed over
/// at once, with its own number; once the gate opens the others follow
/// in order.
#[test]
#[allow(clippy::unwrap_used)]
fn a_stop_read_behind_held_lines_is_handed_over_at_once() {
    let runner = Runner::new();
    let input = runner.input();
    let gate = Arc::new(Shut::default());
    let text: &[u8] = b"{\"a\":1}\n\n{\"a\":2}\n{\"emergency_stop\":true}\n\xff\n{\"a\":3}";
    let feeder = {
        let gate = Arc::clone(&gate);
        thread::spawn(move || {
            let mut r = io::Cursor::new(text.to_vec());
            feed_gated(&input, Origin(4), &mut r, true, None, &*gate)
        })
    };
    let (number, stop) =
        handed(runner.urgent.recv_timeout(Duration::from_secs(10)).unwrap()).unwrap();
    assert_eq!((number, stop.as_str()), (3, "{\"emergency_stop\":true}"));
    assert_eq!(gate.stops.load(Ordering::SeqCst), 1);
    // Nothing else went while the gate was shut (a wake for the stop).
    thread::sleep(Duration::from_millis(100));
    assert!(runner.rx.try_iter().all(|m| matches!(m, Msg::Wake)));
    gate.set(true);
    feeder.join().unwrap().unwrap();
    let rest: Vec<(u64, String)> = runner.rx.try_iter().filter_map(handed).collect();
    assert_eq!(
        rest,
        vec![
            (1, "{\"a\":1}".to_owned()),
            (2, "{\"a\":2}".to_owned()),
            (4, "the line is not UTF-8".to_owned()),
            (5, "{\"a\":3}".to_owned()),
        ]
    );
    assert_eq!(gate.admitted.load(Ordering::SeqCst), 4);
}

/// A gate that cuts the origin off: nothing more of it is handed over,
/// and the feed ends without reading the rest.
#[test]
#[allow(clippy::unwrap_used)]
fn an_origin_cut_off_hands_over_nothing_more() {
    let runner = Runner::new();
    let input = runner.input();
    let gate = Shut::default();
    gate.set(false);
    let lines: String = (0..3000).map(|i| format!("{{\"a\":{i}}}\n")).collect();
    let mut r = io::Cursor::new(lines.into_bytes());
    feed_gated(&input, Origin(4), &mut r, false, None, &gate).unwrap();
    assert_eq!(runner.rx.try_iter().filter_map(handed).count(), 0);
    // It stopped reading once the feeder stopped: not every line was
    // read ahead.
    assert!(r.position() < r.get_ref().len() as u64);
}
