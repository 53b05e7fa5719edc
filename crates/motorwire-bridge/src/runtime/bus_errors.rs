//! What the runner says of a failing bus: each error it can go on after
//! (an error frame, a frame no node acknowledged, a full queue) is said
//! at most every [`REPORT_EVERY`], the others counted into the next
//! report, and a bus failing at every look is looked at again only after
//! [`ERROR_PAUSE`]. A bus in an error state gives thousands of errors a
//! second: said one by one they grew the runner's queue without bound
//! and held the lines behind them, and looked at at once they took a
//! core.

use std::time::{Duration, Instant};

use motorwire_can::Error as CanError;

/// A bus error is said at most this often; those between are counted.
pub(super) const REPORT_EVERY: Duration = Duration::from_millis(100);

/// After the second error in a row, the bus is looked at again only
/// after this long.
pub(super) const ERROR_PAUSE: Duration = Duration::from_millis(1);

/// A receive error after which the handle will never receive again.
pub(super) fn fatal_to_receive(e: &CanError) -> bool {
    matches!(
        e,
        CanError::Closed
            | CanError::NoSuchInterface { .. }
            | CanError::InterfaceDown { .. }
            | CanError::Io { .. }
    )
}

/// A send error after which no frame will ever go: the bus closed or
/// gone (its connection broken: an adapter unplugged), or a frame it can
/// never carry (an FD frame on a classic interface). Any other (no node
/// acknowledged, bus-off, a full queue, another operating-system error)
/// loses that frame only, as a bus that drops it: the bridge sends again
/// what waits for an answer.
pub(super) fn fatal_to_send(e: &CanError) -> bool {
    use std::io::ErrorKind as K;
    match e {
        CanError::Closed
        | CanError::NoSuchInterface { .. }
        | CanError::InterfaceDown { .. }
        | CanError::FdNotSupported { .. } => true,
        CanError::Io { kind, .. } => matches!(
            kind,
            K::BrokenPipe
                | K::NotConnected
                | K::UnexpectedEof
                | K::ConnectionReset
                | K::ConnectionAborted
                | K::NotFound
                | K::PermissionDenied
        ),
        _ => false,
    }
}

/// The errors of one side of a bus (receiving or sending) since the last
/// report.
#[derive(Debug, Default)]
pub(super) struct BusErrors {
    /// When the last report was said.
    said: Option<Instant>,
    /// Errors since, not said.
    unsaid: u64,
    /// Errors in a row, with no frame between.
    streak: u32,
}

impl BusErrors {
    /// `e` at `now`: what to say of it now, if anything (`what` is what
    /// was being done: "sending a frame").
    pub(super) fn failed(&mut self, what: &str, e: &CanError, now: Instant) -> Option<String> {
        self.streak = self.streak.saturating_add(1);
        if self
            .said
            .is_some_and(|t| now.saturating_duration_since(t) < REPORT_EVERY)
        {
            self.unsaid += 1;
            return None;
        }
        self.said = Some(now);
        let more = std::mem::take(&mut self.unsaid);
        Some(if more == 0 {
            format!("{what}: {e}")
        } else {
            format!("{what}: {e} ({more} more bus errors since the last said)")
        })
    }

    /// A frame went (or came): the errors in a row end. What to say of the
    /// errors counted and not yet said, if any.
    pub(super) fn worked(&mut self) -> Option<String> {
        self.streak = 0;
        (self.unsaid > 0).then(|| {
            let n = std::mem::take(&mut self.unsaid);
            self.said = None;
            format!("{n} more bus errors before the bus worked again")
        })
    }

    /// How long to wait before the bus is looked at again: not at all
    /// after one error (the frames behind it are read at once),
    /// [`ERROR_PAUSE`] from the second in a row.
    pub(super) fn pause(&self) -> Duration {
        if self.streak > 1 {
            ERROR_PAUSE
        } else {
            Duration::ZERO
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Errors a millisecond apart for a second are said ten times, the
    /// others counted into the next; a frame ends the streak and says the
    /// count left.
    #[test]
    fn a_flood_of_errors_is_said_every_tenth_of_a_second_and_counted() {
        let start = Instant::now();
        let mut errors = BusErrors::default();
        let mut said = Vec::new();
        for ms in 0..1000u64 {
            let now = start + Duration::from_millis(ms);
            if let Some(s) = errors.failed("receiving", &CanError::BusOff, now) {
                said.push(s);
            }
        }
        assert_eq!(said.len(), 10);
        assert_eq!(said[0], "receiving: bus off");
        assert_eq!(
            said[1],
            "receiving: bus off (99 more bus errors since the last said)"
        );
        assert_eq!(errors.pause(), ERROR_PAUSE);
        assert_eq!(
            errors.worked().as_deref(),
            Some("99 more bus errors before the bus worked again")
        );
        assert_eq!(errors.pause(), Duration::ZERO);
        assert_eq!(errors.worked(), None);
        // Said at once after the bus worked.
        let later = start + Duration::from_millis(1000);
        assert_eq!(
            errors
                .failed("receiving", &CanError::NoAck, later)
                .as_deref(),
            Some("receiving: no node acknowledged the frame")
        );
        assert_eq!(errors.pause(), Duration::ZERO);
    }

    #[test]
    fn only_a_bus_gone_or_a_frame_it_cannot_carry_ends_the_sending() {
        assert!(fatal_to_send(&CanError::Closed));
        assert!(fatal_to_send(&CanError::FdNotSupported {
            iface: "can0".to_owned()
        }));
        assert!(!fatal_to_send(&CanError::NoAck));
        let io = |kind| CanError::Io {
            op: "writing to the adapter",
            kind,
            message: String::new(),
        };
        assert!(fatal_to_send(&io(std::io::ErrorKind::BrokenPipe)));
        assert!(fatal_to_send(&io(std::io::ErrorKind::NotFound)));
        assert!(!fatal_to_send(&io(std::io::ErrorKind::WouldBlock)));
        assert!(!fatal_to_send(&io(std::io::ErrorKind::Other)));
        assert!(!fatal_to_send(&CanError::BusOff));
        assert!(!fatal_to_send(&CanError::TransmitTimeout));
    }
}
