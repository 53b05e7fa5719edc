//! The emergency stop's latch: whether the stop holds, when the last stop
//! came (the line's arrival, the bridge's clock, its Unix time), what the
//! release brings back, and what a stop cancels of the lines written
//! before it. One type with its own behaviour; the engine asks it.

use std::collections::BTreeMap;
use std::time::Duration;

use crate::device::{DeviceId, Lifecycle};
use crate::output::Refusal;

/// The stop's state; see the module's documentation.
#[derive(Debug, Default)]
pub(super) struct StopLatch {
    latched: bool,
    /// Unix ms of the last emergency stop, on the bridge's clock (with
    /// `BridgeConfig::epoch_unix_ms`): with `BridgeConfig::max_age` in
    /// force, a command stamped before it was written before the stop, and
    /// is refused `stale_before_stop`.
    unix_ms: Option<f64>,
    /// When the last emergency stop was taken, on the bridge's own clock
    /// (any stop, the bridge's own too): a line that had reached the
    /// bridge before it was written before it, whatever its timestamp
    /// says, and is refused `stale_before_stop`.
    at: Option<Duration>,
    /// When the latest stop line arrived: a release that arrived before it
    /// is not obeyed.
    line_arrived: Option<Duration>,
    /// For each joint, what the release sends it (those active, or being
    /// started, when the stop came).
    resume: BTreeMap<DeviceId, Vec<Lifecycle>>,
}

impl StopLatch {
    /// Whether the stop holds.
    pub(super) const fn is_latched(&self) -> bool {
        self.latched
    }

    /// A stop line arrived at `now`.
    pub(super) fn line_arrived(&mut self, now: Duration) {
        self.line_arrived = Some(self.line_arrived.map_or(now, |t| t.max(now)));
    }

    /// Whether a release that arrived at `now` came before the latest stop
    /// line (acted on first): releasing would let what followed the
    /// release run after the stop.
    pub(super) fn overtaken(&self, now: Duration) -> bool {
        self.line_arrived.is_some_and(|t| now < t)
    }

    /// A stop (any, a rider's too) taken at `now`, `unix_ms` on the
    /// bridge's wall clock where it keeps one: it counts for what was
    /// written before it.
    pub(super) fn stopped(&mut self, now: Duration, unix_ms: Option<f64>) {
        if let Some(at) = unix_ms {
            self.unix_ms = Some(self.unix_ms.map_or(at, |t| t.max(at)));
        }
        self.at = Some(self.at.map_or(now, |t| t.max(now)));
    }

    /// The stop latches, the release to bring back `resume` (each joint's
    /// steps). A stop over a stop still latched keeps what the first had
    /// to bring back, and adds this one's.
    pub(super) fn latch(&mut self, resume: impl IntoIterator<Item = (DeviceId, Vec<Lifecycle>)>) {
        if !self.latched {
            self.resume.clear();
        }
        self.resume.extend(resume);
        self.latched = true;
    }

    /// The release: what it brings back, each joint's steps (`None`: there
    /// is no stop to release).
    pub(super) fn release(&mut self) -> Option<BTreeMap<DeviceId, Vec<Lifecycle>>> {
        if !self.latched {
            return None;
        }
        self.latched = false;
        Some(std::mem::take(&mut self.resume))
    }

    /// What a stop cancels: a line that reached the bridge at `arrived`,
    /// stamped `timestamp` (`written` on the bridge's clock, as far as its
    /// client's clock is known), refused when it was written before the
    /// last stop. Its timestamp is judged only where timestamps are held to
    /// the bridge's clock (`held_to_clock`: a max age in force), to the
    /// millisecond (one stamped in the millisecond the stop came in may
    /// have been written after it); its arrival always (a client's clock
    /// may run ahead).
    pub(super) fn written_before(
        &self,
        arrived: Duration,
        timestamp: f64,
        written: f64,
        held_to_clock: bool,
    ) -> Option<Refusal> {
        if let Some(stop) = self.at
            && arrived < stop
        {
            return Some(Refusal::ArrivedBeforeStop {
                early: stop - arrived,
            });
        }
        if let Some(stop_ms) = self.unix_ms.map(f64::floor)
            && held_to_clock
            && written < stop_ms
        {
            // Written before the stop (another client's, still on its
            // way): the stop came after it, so it must not run after the
            // release.
            return Some(Refusal::StampedBeforeStop { timestamp, stop_ms });
        }
        None
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn ms(n: u64) -> Duration {
        Duration::from_millis(n)
    }

    #[test]
    fn a_latch_holds_until_released_and_brings_back_what_it_kept() {
        let mut l = StopLatch::default();
        assert!(!l.is_latched());
        assert_eq!(l.release(), None, "nothing to release");
        l.latch([(DeviceId::at(0), vec![Lifecycle::Activate])]);
        // A second stop over the first adds, never forgets.
        l.latch([(
            DeviceId::at(2),
            vec![Lifecycle::Configure, Lifecycle::Activate],
        )]);
        assert!(l.is_latched());
        let back = l.release().unwrap();
        assert_eq!(
            back.keys().copied().collect::<Vec<_>>(),
            [DeviceId::at(0), DeviceId::at(2)]
        );
        assert!(!l.is_latched());
        // A fresh stop after a release starts afresh.
        l.latch([(DeviceId::at(1), vec![Lifecycle::Activate])]);
        assert_eq!(
            l.release().unwrap().keys().copied().collect::<Vec<_>>(),
            [DeviceId::at(1)]
        );
    }

    #[test]
    fn what_was_written_before_the_stop_is_refused() {
        let mut l = StopLatch::default();
        assert_eq!(l.written_before(ms(5), 1.0, 1.0, true), None);
        l.stopped(ms(100), Some(10_000.4));
        // Reached the bridge before the stop, whatever its stamp.
        assert_eq!(
            l.written_before(ms(90), 20_000.0, 20_000.0, true),
            Some(Refusal::ArrivedBeforeStop { early: ms(10) })
        );
        // Stamped before it, where stamps are held to the clock; in its
        // millisecond, not.
        assert_eq!(
            l.written_before(ms(150), 9_999.0, 9_999.0, true),
            Some(Refusal::StampedBeforeStop {
                timestamp: 9_999.0,
                stop_ms: 10_000.0
            })
        );
        assert_eq!(l.written_before(ms(150), 10_000.0, 10_000.0, true), None);
        assert_eq!(l.written_before(ms(150), 9_999.0, 9_999.0, false), None);
        // The latest stop counts, never an earlier one after it.
        l.stopped(ms(50), Some(5_000.0));
        assert_eq!(
            l.written_before(ms(90), 1.0, 1.0, false),
            Some(Refusal::ArrivedBeforeStop { early: ms(10) })
        );
    }

    #[test]
    fn a_release_that_arrived_before_the_latest_stop_line_is_overtaken() {
        let mut l = StopLatch::default();
        assert!(!l.overtaken(ms(10)));
        l.line_arrived(ms(20));
        l.line_arrived(ms(15));
        assert!(l.overtaken(ms(19)));
        assert!(!l.overtaken(ms(20)));
    }
}
