//! Each client's clock against the bridge's, learned from its lines, so
//! that what a stop cancels does not depend on a client's clock being
//! right.
//!
//! A client whose clock runs `d` ms ahead stamps a line written at `w`
//! (the bridge's clock) `w + d`; the line reaches the bridge at `a ≥ w`.
//! The least `a − timestamp` over its lines is `−d + l`, with `l` the
//! quickest delivery seen, so `timestamp + least` is `w + l`: back on the
//! bridge's clock, off by a delivery time at most. Only a clock that runs
//! ahead is taken back: a least offset above zero (a clock behind, or
//! lines that waited) is not added, which would make old lines look new.

use std::collections::BTreeMap;
use std::time::{Duration, Instant};

use crate::output::Origin;

/// Clients remembered at most; beyond, the oldest (lowest origin: origins
/// only grow) is forgotten first.
const MAX_CLIENTS: usize = 4096;

/// Each client's least (arrival − timestamp), in ms.
#[derive(Debug, Default, Clone)]
pub(crate) struct ClockOffsets {
    least: BTreeMap<Origin, f64>,
}

impl ClockOffsets {
    /// One line of `origin`'s: it reached the bridge `offset` ms after
    /// its timestamp (negative: before it, the client's clock ahead).
    pub(crate) fn learn(&mut self, origin: Origin, offset: f64) {
        if !offset.is_finite() {
            return;
        }
        if let Some(least) = self.least.get_mut(&origin) {
            *least = least.min(offset);
            return;
        }
        if self.least.len() >= MAX_CLIENTS {
            self.least.pop_first();
        }
        self.least.insert(origin, offset);
    }

    /// How many ms `origin`'s timestamps are taken back: its clock's lead
    /// over the bridge's as its lines show it, or 0 (a correct clock, one
    /// behind, or nothing learned yet). Never positive.
    pub(crate) fn behind(&self, origin: Origin) -> f64 {
        self.least.get(&origin).map_or(0.0, |l| l.min(0.0))
    }

    /// A client that left.
    pub(crate) fn forget(&mut self, origin: Origin) {
        self.least.remove(&origin);
    }
}

/// The monotonic clock and the host's wall clock (since the Unix epoch)
/// at the same moment, to within a few microseconds: the wall clock is
/// read on both sides of the monotonic one, and the pair whose two wall
/// readings are closest gives the middle of its two. Read one after the
/// other, a thread preempted between the two readings puts a wall clock
/// reckoned from them ahead of the host's by that time (the bridge's: a
/// command stamped just after a stop's release came out before the stop;
/// a recording's: its wall times late). `None` for a wall clock before
/// 1970.
#[must_use]
pub fn clocks_together() -> (Instant, Option<Duration>) {
    use std::time::{SystemTime, UNIX_EPOCH};
    let mut best: Option<(Duration, Instant, Duration)> = None;
    for _ in 0..8 {
        let before = SystemTime::now().duration_since(UNIX_EPOCH);
        let at = Instant::now();
        let after = SystemTime::now().duration_since(UNIX_EPOCH);
        let (Ok(before), Ok(after)) = (before, after) else {
            return (at, None);
        };
        let gap = after.saturating_sub(before);
        if best.is_none_or(|(g, ..)| gap < g) {
            best = Some((gap, at, before + gap / 2));
        }
        if gap <= Duration::from_micros(20) {
            break;
        }
    }
    match best {
        Some((_, at, wall)) => (at, Some(wall)),
        None => (Instant::now(), None),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_clock_ahead_is_taken_back_by_its_least_lead() {
        let mut c = ClockOffsets::default();
        let a = Origin(7);
        assert_eq!(c.behind(a), 0.0);
        // 120 s ahead; lines delivered in 3, 1 and 40 ms.
        for offset in [-120_000.0 + 3.0, -120_000.0 + 1.0, -120_000.0 + 40.0] {
            c.learn(a, offset);
        }
        assert_eq!(c.behind(a), -119_999.0);
        // Another client, a clock behind: never taken forward.
        c.learn(Origin(8), 5_000.0);
        assert_eq!(c.behind(Origin(8)), 0.0);
        c.learn(Origin(8), f64::NAN);
        assert_eq!(c.behind(Origin(8)), 0.0);
        c.forget(a);
        assert_eq!(c.behind(a), 0.0);
    }

    #[test]
    fn clients_remembered_are_bounded_and_the_oldest_go_first() {
        let mut c = ClockOffsets::default();
        for o in 0..(MAX_CLIENTS as u64 + 10) {
            c.learn(Origin(o), -1_000.0);
        }
        assert_eq!(c.least.len(), MAX_CLIENTS);
        assert_eq!(c.behind(Origin(0)), 0.0);
        assert_eq!(c.behind(Origin(9)), 0.0);
        assert_eq!(c.behind(Origin(10)), -1_000.0);
    }
}
