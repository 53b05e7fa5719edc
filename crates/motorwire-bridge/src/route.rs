//! Who gets which output of the engine: one routing for every front end of
//! the bridge (the CLI's standard output and sockets, the Zenoh
//! participant, a program that embeds the bridge).
//!
//! A *reader* is whoever reads what an [`Origin`] is owed: the client that
//! sent its lines. [`Routing::route`] says where each [`Output`] goes:
//! - a line's result and its completion, and a greeting, to the reader of
//!   its origin alone ([`Delivery::ToReader`]);
//! - an event to every reader ([`Delivery::ToEvery`]);
//! - a motor's feedback to each reader whose own feedback rate takes it
//!   ([`Delivery::Feedback`], [`Routing::takes_feedback`]). A reader sets its
//!   rate with `{"feedback_hz":N}`: once the bridge has answered it (with
//!   the rate it gets, `feedback_every`), the routing counts from the next
//!   feedback line.
//!
//! Sans-IO and never waiting: the front end delivers (queues, sockets,
//! replies) as it does; what it owes a reader before closing (a result
//! for each line, the completion that follows, its greeting) is
//! [`Owed`].

use std::collections::BTreeMap;

use crate::output::{Origin, Output};

/// What a line delivered to one reader is, for what the front end owes it
/// (every line's result, the completion a result says follows, its
/// greeting).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Owed {
    /// A line's result; `arrival_follows`: its completion comes later.
    Result {
        /// The result said a completion follows.
        arrival_follows: bool,
    },
    /// A motion line's completion.
    Arrival,
    /// The reader's own greeting (`ready` or `stopping`).
    Greeting,
}

/// Where one output goes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Delivery<'a> {
    /// To the reader of `origin` alone.
    ToReader {
        /// Whose it is.
        origin: Origin,
        /// What it is.
        owed: Owed,
    },
    /// To every reader: an event.
    ToEvery,
    /// `motor`'s feedback: to each reader whose rate takes it.
    Feedback {
        /// The motor.
        motor: &'a str,
    },
}

/// A reader's own feedback rate: each motor's every `every`-th feedback
/// line (1: all, the default; 0: none), counted per motor.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FeedbackRate {
    every: u32,
    seen: BTreeMap<String, u32>,
}

impl Default for FeedbackRate {
    fn default() -> Self {
        Self {
            every: 1,
            seen: BTreeMap::new(),
        }
    }
}

impl FeedbackRate {
    /// Whether this feedback line of `motor` is the reader's (and counts
    /// it).
    pub fn takes(&mut self, motor: &str) -> bool {
        match self.every {
            0 => false,
            1 => true,
            k => {
                let n = match self.seen.get_mut(motor) {
                    Some(n) => n,
                    None => self.seen.entry(motor.to_owned()).or_insert(0),
                };
                let take = *n % k == 0;
                *n = n.wrapping_add(1);
                take
            }
        }
    }

    /// From now on, every `every`-th line (counted afresh).
    pub fn set(&mut self, every: u32) {
        self.every = every;
        self.seen.clear();
    }

    /// The rate: every how many lines of a motor one is taken (0: none).
    #[must_use]
    pub const fn every(&self) -> u32 {
        self.every
    }
}

/// The routing of a bridge's outputs to its readers; see the module's
/// documentation. A reader is known from [`Routing::add`] until
/// [`Routing::forget`]: only a known reader's rate is kept (a
/// `feedback_hz` answered after its reader left keeps nothing), so what
/// it holds is bounded by the readers there are.
///
/// ```
/// use motorwire_bridge::route::{Delivery, Owed, Routing};
/// use motorwire_bridge::{FeedbackLine, LineResult, Origin, Output};
///
/// let mut routing = Routing::default();
/// routing.add(Origin(7));
/// // The client asks for every 2nd feedback line of each motor, and is answered.
/// let answer = Output::Result {
///     origin: Origin(7),
///     result: Box::new(LineResult { ok: true, line: 1, feedback_every: Some(2), ..LineResult::default() }),
/// };
/// assert_eq!(
///     routing.route(&answer),
///     Delivery::ToReader { origin: Origin(7), owed: Owed::Result { arrival_follows: false } }
/// );
/// let feedback = Output::Feedback(Box::new(FeedbackLine { feedback: None, motor_id: "elbow".into(), online: true }));
/// assert_eq!(routing.route(&feedback), Delivery::Feedback { motor: "elbow" });
/// let taken: Vec<bool> = (0..4).map(|_| routing.takes_feedback(Origin(7), "elbow")).collect();
/// assert_eq!(taken, [true, false, true, false]);
/// // Another reader takes every line.
/// assert!(routing.takes_feedback(Origin(8), "elbow"));
/// ```
#[derive(Debug, Clone, Default)]
pub struct Routing {
    /// The readers there are, each with its rate (every line unless it
    /// set one).
    rates: BTreeMap<Origin, FeedbackRate>,
}

impl Routing {
    /// Where `o` goes. A result that answers a reader's `feedback_hz`
    /// sets its rate, from the next feedback line on.
    pub fn route<'a>(&mut self, o: &'a Output) -> Delivery<'a> {
        if let Output::Result { origin, result } = o
            && result.ok
            && let Some(every) = result.feedback_every
            && let Some(rate) = self.rates.get_mut(origin)
        {
            rate.set(every);
        }
        Self::delivery(o)
    }

    /// `reader` is there (it connected): it takes every feedback line
    /// until it sets a rate.
    pub fn add(&mut self, reader: Origin) {
        self.rates.entry(reader).or_default();
    }

    /// Where `o` goes, for a front end that keeps no feedback rates (the
    /// Zenoh participant publishes feedback as it comes).
    #[must_use]
    pub fn delivery(o: &Output) -> Delivery<'_> {
        match o {
            Output::Result { origin, result } => Delivery::ToReader {
                origin: *origin,
                owed: Owed::Result {
                    arrival_follows: result.arrival_follows == Some(true),
                },
            },
            Output::Arrival { origin, .. } => Delivery::ToReader {
                origin: *origin,
                owed: Owed::Arrival,
            },
            Output::ToOne { origin, .. } => Delivery::ToReader {
                origin: *origin,
                owed: Owed::Greeting,
            },
            Output::Event(_) => Delivery::ToEvery,
            Output::Feedback(f) => Delivery::Feedback { motor: &f.motor_id },
        }
    }

    /// Whether `reader` takes this feedback line of `motor` (and counts
    /// it): every line unless it set a rate (a reader not known takes
    /// every line).
    pub fn takes_feedback(&mut self, reader: Origin, motor: &str) -> bool {
        self.rates.get_mut(&reader).is_none_or(|r| r.takes(motor))
    }

    /// `reader`'s feedback rate (every how many lines of a motor: 1 unless
    /// it set one).
    #[must_use]
    pub fn feedback_every(&self, reader: Origin) -> u32 {
        self.rates.get(&reader).map_or(1, FeedbackRate::every)
    }

    /// `reader` is gone: it and its rate are forgotten.
    pub fn forget(&mut self, reader: Origin) {
        self.rates.remove(&reader);
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use crate::output::{ArrivalLine, Event, FeedbackLine, LineResult};

    fn result(origin: u64, every: Option<u32>, ok: bool, follows: Option<bool>) -> Output {
        Output::Result {
            origin: Origin(origin),
            result: Box::new(LineResult {
                ok,
                line: 1,
                feedback_every: every,
                arrival_follows: follows,
                ..LineResult::default()
            }),
        }
    }

    fn feedback(motor: &str) -> Output {
        Output::Feedback(Box::new(FeedbackLine {
            feedback: None,
            motor_id: motor.into(),
            online: true,
        }))
    }

    #[test]
    fn each_output_goes_where_it_is_owed() {
        let mut r = Routing::default();
        assert_eq!(
            r.route(&result(3, None, true, Some(true))),
            Delivery::ToReader {
                origin: Origin(3),
                owed: Owed::Result {
                    arrival_follows: true
                }
            }
        );
        let arrival = Output::Arrival {
            origin: Origin(3),
            arrival: ArrivalLine {
                arrived: true,
                line: 1,
                motor_id: None,
                command_id: None,
                reason: None,
                after_ms: 0,
                motors: Vec::new(),
            },
        };
        assert_eq!(
            r.route(&arrival),
            Delivery::ToReader {
                origin: Origin(3),
                owed: Owed::Arrival
            }
        );
        let event = Output::Event(Event::Stopping {
            reason: "end".into(),
        });
        assert_eq!(r.route(&event), Delivery::ToEvery);
        let greeting = Output::ToOne {
            origin: Origin(4),
            event: Event::Stopping {
                reason: "end".into(),
            },
        };
        assert_eq!(
            r.route(&greeting),
            Delivery::ToReader {
                origin: Origin(4),
                owed: Owed::Greeting
            }
        );
        assert_eq!(
            r.route(&feedback("knee")),
            Delivery::Feedback { motor: "knee" }
        );
    }

    /// Each reader's rate is its own, counted per motor, set from the
    /// answer on, never by a refused line, and forgotten with the reader.
    #[test]
    fn a_readers_feedback_rate_is_its_own() {
        let mut r = Routing::default();
        for reader in [1, 2, 5] {
            r.add(Origin(reader));
        }
        r.route(&result(1, Some(3), true, None));
        r.route(&result(2, Some(0), true, None));
        // A refused feedback_hz changes nothing.
        r.route(&result(5, Some(9), false, None));
        let take = |r: &mut Routing, o: u64, m: &str, n: usize| -> Vec<bool> {
            (0..n).map(|_| r.takes_feedback(Origin(o), m)).collect()
        };
        assert_eq!(take(&mut r, 1, "knee", 4), [true, false, false, true]);
        assert_eq!(take(&mut r, 1, "hip", 2), [true, false]);
        assert_eq!(take(&mut r, 2, "knee", 2), [false, false]);
        assert_eq!(take(&mut r, 5, "knee", 2), [true, true]);
        assert_eq!(
            (r.feedback_every(Origin(1)), r.feedback_every(Origin(5))),
            (3, 1)
        );
        // Set again: counted afresh.
        r.route(&result(1, Some(2), true, None));
        assert_eq!(take(&mut r, 1, "knee", 3), [true, false, true]);
        r.forget(Origin(1));
        assert_eq!(take(&mut r, 1, "knee", 2), [true, true]);
        // A rate answered after its reader left keeps nothing: what the
        // routing holds is its readers'.
        r.route(&result(1, Some(4), true, None));
        r.route(&result(77, Some(4), true, None));
        assert_eq!(r.rates.len(), 2, "{:?}", r.rates.keys());
        assert_eq!(take(&mut r, 77, "knee", 2), [true, true]);
    }
}
