//! The ids of recent commands, per controller: what makes a retried query
//! answer with its first result instead of running again.

use std::borrow::Borrow;
use std::collections::{BTreeMap, HashMap};
use std::hash::Hash;
use std::sync::Arc;
use std::time::{Duration, Instant};

use motorwire_bridge::Origin;

/// Ids remembered per controller: the most recently used this many.
pub const IDS_PER_CONTROLLER: usize = 1024;

/// Controllers remembered: at most this many (a controller forgotten has
/// all its ids forgotten). One is forgotten only when it has been idle for
/// [`CONTROLLER_IDLE`]: another controller cannot push it out sooner.
pub const CONTROLLERS: usize = 64;

/// How long a controller must have been silent before a new controller
/// may take its place in a full memory (until then the newcomer's
/// commands with ids are refused `busy`).
pub const CONTROLLER_IDLE: Duration = Duration::from_secs(600);

/// Whose ids a command's id is among: two namespaces that never meet, so a
/// name in a selector parameter can never reach the ids of a controller
/// the key expression names.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub(crate) enum Controller {
    /// The controller the key expression names,
    /// `motorwire/<robot>/cmd/<controller>`: with the router's access
    /// control granting each controller's Zenoh user only its own chunk
    /// (`config/router.json5`), the authenticated user.
    Key(String),
    /// What the controller says it is: the selector parameter `controller`
    /// of a query on `motorwire/<robot>/cmd` (none is `""`).
    Named(String),
}

/// What is remembered of one id.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) enum Recalled {
    /// Its line is in progress, as this origin.
    InProgress(Origin),
    /// Its line is done: these were its replies (its result, then its
    /// completion when one followed).
    Done(Vec<Arc<str>>),
}

/// A least-recently-used map with a bound.
#[derive(Debug)]
struct Lru<K, V> {
    bound: usize,
    tick: u64,
    entries: HashMap<K, (u64, V)>,
    order: BTreeMap<u64, K>,
}

impl<K: Hash + Eq + Clone, V> Lru<K, V> {
    fn new(bound: usize) -> Self {
        Self {
            bound: bound.max(1),
            tick: 0,
            entries: HashMap::new(),
            order: BTreeMap::new(),
        }
    }

    fn get_mut<Q>(&mut self, key: &Q) -> Option<&mut V>
    where
        K: Borrow<Q>,
        Q: Hash + Eq + ?Sized,
    {
        self.tick += 1;
        let tick = self.tick;
        let (used, value) = self.entries.get_mut(key)?;
        if let Some(k) = self.order.remove(used) {
            self.order.insert(tick, k);
        }
        *used = tick;
        Some(value)
    }

    fn insert(&mut self, key: K, value: V) {
        self.tick += 1;
        if let Some((used, _)) = self.entries.remove(&key) {
            self.order.remove(&used);
        }
        while self.entries.len() >= self.bound {
            let Some((_, oldest)) = self.order.pop_first() else {
                break;
            };
            self.entries.remove(&oldest);
        }
        self.order.insert(self.tick, key.clone());
        self.entries.insert(key, (self.tick, value));
    }

    fn contains<Q>(&self, key: &Q) -> bool
    where
        K: Borrow<Q>,
        Q: Hash + Eq + ?Sized,
    {
        self.entries.contains_key(key)
    }

    fn remove<Q>(&mut self, key: &Q)
    where
        K: Borrow<Q>,
        Q: Hash + Eq + ?Sized,
    {
        if let Some((used, _)) = self.entries.remove(key) {
            self.order.remove(&used);
        }
    }

    #[cfg(test)]
    fn len(&self) -> usize {
        self.entries.len()
    }
}

/// Recent command ids: [`IDS_PER_CONTROLLER`] per controller, for the
/// [`CONTROLLERS`] most recently heard controllers.
#[derive(Debug)]
pub(crate) struct IdMemory {
    per_controller: usize,
    bound: usize,
    idle: Duration,
    controllers: Lru<Controller, Lru<String, (Arc<str>, Recalled)>>,
    /// When each remembered controller was last heard.
    heard: HashMap<Controller, Instant>,
}

impl IdMemory {
    pub(crate) fn new(per_controller: usize, controllers: usize, idle: Duration) -> Self {
        Self {
            per_controller,
            bound: controllers.max(1),
            idle,
            controllers: Lru::new(controllers),
            heard: HashMap::new(),
        }
    }

    /// Makes room for `controller`, heard at `now`: whether its ids can be
    /// remembered. A controller already remembered always can; a new one
    /// when there is room, or when the least recently heard controller has
    /// been silent for the idle time (it is then forgotten whole). Never
    /// does a new controller push out one heard more recently.
    pub(crate) fn admit(&mut self, controller: &Controller, now: Instant) -> bool {
        if self.controllers.contains(controller) {
            self.heard.insert(controller.clone(), now);
            return true;
        }
        if self.heard.len() >= self.bound {
            let Some((oldest, last)) = self
                .heard
                .iter()
                .min_by_key(|(_, t)| **t)
                .map(|(c, t)| (c.clone(), *t))
            else {
                return false;
            };
            if now.saturating_duration_since(last) < self.idle {
                return false;
            }
            self.controllers.remove(&oldest);
            self.heard.remove(&oldest);
        }
        self.controllers
            .insert(controller.clone(), Lru::new(self.per_controller));
        self.heard.insert(controller.clone(), now);
        true
    }

    /// What is remembered of `id` from `controller`: the body of the
    /// command it named, and where that command is (and it is now the most
    /// recently used).
    pub(crate) fn recall(
        &mut self,
        controller: &Controller,
        id: &str,
    ) -> Option<(Arc<str>, Recalled)> {
        self.controllers
            .get_mut(controller)?
            .get_mut(id)
            .map(|r| r.clone())
    }

    /// How many controllers are remembered at most.
    pub(crate) fn bound(&self) -> usize {
        self.bound
    }

    /// Remembers `id` from `controller` as the command `body`, now `what`
    /// (nothing when `controller` was not [`IdMemory::admit`]ted).
    pub(crate) fn remember(
        &mut self,
        controller: &Controller,
        id: &str,
        body: Arc<str>,
        what: Recalled,
    ) {
        if let Some(ids) = self.controllers.get_mut(controller) {
            ids.insert(id.to_owned(), (body, what));
        }
    }

    /// Forgets `id` from `controller` (a line refused `busy`: its retry is
    /// a new try).
    pub(crate) fn forget(&mut self, controller: &Controller, id: &str) {
        if let Some(ids) = self.controllers.get_mut(controller) {
            ids.remove(id);
        }
    }

    /// How many ids are remembered for `controller`.
    #[cfg(test)]
    fn ids_of(&mut self, controller: &Controller) -> usize {
        self.controllers
            .get_mut(controller)
            .map_or(0, |ids| ids.len())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn named(c: &str) -> Controller {
        Controller::Named(c.to_owned())
    }

    fn body() -> Arc<str> {
        Arc::from(r#"{"motor_id":"elbow"}"#)
    }

    /// `m` with `controllers` admitted now.
    fn admitted(mut m: IdMemory, controllers: &[&str]) -> IdMemory {
        for c in controllers {
            assert!(m.admit(&named(c), Instant::now()), "{c}");
        }
        m
    }

    fn done(s: &str) -> Recalled {
        Recalled::Done(vec![Arc::from(s)])
    }

    #[test]
    fn an_id_is_recalled_per_controller() {
        let mut m = admitted(IdMemory::new(4, 2, Duration::ZERO), &["a", "b"]);
        m.remember(&named("a"), "1", body(), Recalled::InProgress(Origin(7)));
        assert_eq!(
            m.recall(&named("a"), "1"),
            Some((body(), Recalled::InProgress(Origin(7))))
        );
        assert_eq!(m.recall(&named("b"), "1"), None);
        m.remember(&named("a"), "1", body(), done("r"));
        assert_eq!(m.recall(&named("a"), "1"), Some((body(), done("r"))));
        m.forget(&named("a"), "1");
        assert_eq!(m.recall(&named("a"), "1"), None);
        // The body is remembered with the id.
        m.remember(&named("a"), "2", Arc::from("{}"), done("r"));
        assert_eq!(
            m.recall(&named("a"), "2"),
            Some((Arc::from("{}"), done("r")))
        );
    }

    #[test]
    fn the_least_recently_used_id_goes_first_and_the_bound_holds() {
        let mut m = admitted(IdMemory::new(3, 2, Duration::ZERO), &["a"]);
        for id in ["1", "2", "3"] {
            m.remember(&named("a"), id, body(), done(id));
        }
        // "1" used again: "2" is now the oldest.
        assert_eq!(m.recall(&named("a"), "1"), Some((body(), done("1"))));
        m.remember(&named("a"), "4", body(), done("4"));
        assert_eq!(m.ids_of(&named("a")), 3);
        assert_eq!(m.recall(&named("a"), "2"), None);
        assert_eq!(m.recall(&named("a"), "1"), Some((body(), done("1"))));
        assert_eq!(m.recall(&named("a"), "3"), Some((body(), done("3"))));
        assert_eq!(m.recall(&named("a"), "4"), Some((body(), done("4"))));
        for n in 0..10_000 {
            m.remember(&named("a"), &n.to_string(), body(), done("x"));
        }
        assert_eq!(m.ids_of(&named("a")), 3);
    }

    #[test]
    fn a_silent_controller_is_forgotten_whole_and_only_a_silent_one() {
        let t0 = Instant::now();
        let idle = Duration::from_secs(600);
        let mut m = IdMemory::new(3, 2, idle);
        assert!(m.admit(&named("a"), t0));
        m.remember(&named("a"), "1", body(), done("a1"));
        assert!(m.admit(&named("b"), t0));
        m.remember(&named("b"), "1", body(), done("b1"));
        // Full: 64 (here 2) invented names cannot push out a controller
        // heard within the idle time, however many come.
        for n in 0..100 {
            assert!(!m.admit(
                &named(&format!("invented-{n}")),
                t0 + Duration::from_secs(599)
            ));
        }
        assert_eq!(m.recall(&named("a"), "1"), Some((body(), done("a1"))));
        assert_eq!(m.recall(&named("b"), "1"), Some((body(), done("b1"))));
        // A remembered controller is always admitted, and heard anew.
        assert!(m.admit(&named("a"), t0 + Duration::from_secs(300)));
        // b, silent for the idle time, makes room; a, heard at 300 s, not
        // yet.
        assert!(m.admit(&named("c"), t0 + Duration::from_secs(600)));
        m.remember(&named("c"), "1", body(), done("c1"));
        assert_eq!(m.recall(&named("b"), "1"), None);
        assert_eq!(m.recall(&named("a"), "1"), Some((body(), done("a1"))));
        assert!(!m.admit(&named("d"), t0 + Duration::from_secs(899)));
        assert!(m.admit(&named("d"), t0 + Duration::from_secs(900)));
        assert_eq!(m.recall(&named("a"), "1"), None);
        assert_eq!(m.recall(&named("c"), "1"), Some((body(), done("c1"))));
        // Nothing is remembered for a controller not admitted.
        m.remember(&named("e"), "1", body(), done("e1"));
        assert_eq!(m.recall(&named("e"), "1"), None);
    }

    #[test]
    fn a_name_in_a_parameter_never_reaches_the_ids_of_a_key_bound_controller() {
        let mut m = IdMemory::new(4, 4, Duration::ZERO);
        let bob = Controller::Key("bob".to_owned());
        assert!(m.admit(&bob, Instant::now()));
        m.remember(&bob, "s:d1", body(), done("bob's"));
        // `?controller=bob` is another controller: it neither recalls nor
        // overwrites nor forgets cmd/bob's ids.
        assert!(m.admit(&named("bob"), Instant::now()));
        assert_eq!(m.recall(&named("bob"), "s:d1"), None);
        m.remember(&named("bob"), "s:d1", Arc::from("{}"), done("named"));
        m.forget(&named("bob"), "s:d1");
        assert_eq!(m.recall(&bob, "s:d1"), Some((body(), done("bob's"))));
        assert_eq!(m.ids_of(&bob), 1);
        assert_eq!(m.ids_of(&named("bob")), 0);
    }
}
