//! The one rule every request in flight is sent again by, whatever its
//! dialect: the iRPC client's requests, and (in `motorwire-bridge`'s
//! device layer) the compact commands and the Orion controller's lines.
//!
//! A request is sent once; when its answer is `timeout` late it is sent
//! again, up to `retries` more times; when the last one is `timeout` late
//! too, it is given up (its outcome unknown). Each driver keeps one
//! [`Attempts`] per request and asks it at each deadline what to do.
//!
//! ```
//! use std::time::Duration;
//! use motorwire_can::retry::{Attempts, Expiry};
//!
//! let ms = Duration::from_millis;
//! let mut a = Attempts::first(ms(0), ms(100), 1);
//! assert_eq!(a.expire(ms(50), true), Expiry::Waiting);
//! assert_eq!(a.expire(ms(100), true), Expiry::Resend);
//! assert_eq!((a.sent(), a.deadline()), (2, ms(200)));
//! assert_eq!(a.expire(ms(200), true), Expiry::GiveUp);
//! ```

use std::time::Duration;

/// One request's sendings: how many, when its answer is due, and how
/// many more it may have.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Attempts {
    sent: u8,
    deadline: Duration,
    timeout: Duration,
    retries: u8,
}

/// What a request's deadline asks of its driver.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Expiry {
    /// Not due yet.
    Waiting,
    /// Send it again now (counted, and its next deadline set).
    Resend,
    /// Its last sending went unanswered: give it up.
    GiveUp,
}

impl Attempts {
    /// A request sent for the first time at `now`, answered within
    /// `timeout` or sent again, up to `retries` more times.
    #[must_use]
    pub const fn first(now: Duration, timeout: Duration, retries: u8) -> Self {
        Self {
            sent: 1,
            deadline: now.saturating_add(timeout),
            timeout,
            retries,
        }
    }

    /// How many times it was sent.
    #[must_use]
    pub const fn sent(&self) -> u8 {
        self.sent
    }

    /// When its answer is due.
    #[must_use]
    pub const fn deadline(&self) -> Duration {
        self.deadline
    }

    /// Whether at `now` it is due to be sent again (not waiting, and not
    /// to be given up): what [`Attempts::expire`] would answer `Resend`
    /// to, without counting it.
    #[must_use]
    pub const fn resend_due(&self, now: Duration) -> bool {
        now.as_nanos() >= self.deadline.as_nanos() && self.sent <= self.retries
    }

    /// What to do with it at `now`: wait, send it again (when it has
    /// retries left and `may_resend`: a driver gives up early a request
    /// it has no reason to repeat), or give it up.
    pub const fn expire(&mut self, now: Duration, may_resend: bool) -> Expiry {
        if now.as_nanos() < self.deadline.as_nanos() {
            return Expiry::Waiting;
        }
        if may_resend && self.sent <= self.retries {
            self.sent += 1;
            self.deadline = now.saturating_add(self.timeout);
            return Expiry::Resend;
        }
        Expiry::GiveUp
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: Duration = Duration::from_millis(1);

    /// Three retries: four sendings 100 ms apart (each deadline from the
    /// sending before it), then given up at the fourth's deadline.
    #[test]
    fn a_request_is_sent_retries_more_times_then_given_up() {
        let mut a = Attempts::first(10 * MS, 100 * MS, 3);
        let mut resent_at = Vec::new();
        let mut t = 10 * MS;
        let gave_up = loop {
            t += MS;
            match a.expire(t, true) {
                Expiry::Waiting => {}
                Expiry::Resend => resent_at.push(t),
                Expiry::GiveUp => break t,
            }
        };
        assert_eq!(resent_at, [110 * MS, 210 * MS, 310 * MS]);
        assert_eq!(gave_up, 410 * MS);
        assert_eq!(a.sent(), 4);
    }

    /// A request the driver will not repeat is given up at its first
    /// deadline; with no retries, the same.
    #[test]
    fn no_resend_means_giving_up_at_the_deadline() {
        let mut a = Attempts::first(Duration::ZERO, 100 * MS, 3);
        assert_eq!(a.expire(99 * MS, false), Expiry::Waiting);
        assert_eq!(a.expire(100 * MS, false), Expiry::GiveUp);
        let mut b = Attempts::first(Duration::ZERO, 100 * MS, 0);
        assert_eq!(b.expire(100 * MS, true), Expiry::GiveUp);
        assert_eq!(b.sent(), 1);
    }
}
