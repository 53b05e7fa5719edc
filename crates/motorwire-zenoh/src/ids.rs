//! The ids of recent commands, per controller: what makes a retried query
//! answer with its first result instead of running again.

use std::collections::{BTreeMap, HashMap};
use std::sync::Arc;

use motorwire_bridge::Origin;

/// Ids remembered per controller: the most recently used this many.
pub const IDS_PER_CONTROLLER: usize = 1024;

/// Controllers remembered: the most recently heard this many (a controller
/// forgotten has all its ids forgotten).
pub const CONTROLLERS: usize = 64;

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
struct Lru<V> {
    bound: usize,
    tick: u64,
    entries: HashMap<String, (u64, V)>,
    order: BTreeMap<u64, String>,
}

impl<V> Lru<V> {
    fn new(bound: usize) -> Self {
        Self {
            bound: bound.max(1),
            tick: 0,
            entries: HashMap::new(),
            order: BTreeMap::new(),
        }
    }

    fn get_mut(&mut self, key: &str) -> Option<&mut V> {
        self.tick += 1;
        let tick = self.tick;
        let (used, value) = self.entries.get_mut(key)?;
        self.order.remove(used);
        *used = tick;
        self.order.insert(tick, key.to_owned());
        Some(value)
    }

    fn insert(&mut self, key: &str, value: V) {
        self.tick += 1;
        if let Some((used, _)) = self.entries.remove(key) {
            self.order.remove(&used);
        }
        while self.entries.len() >= self.bound {
            let Some((_, oldest)) = self.order.pop_first() else {
                break;
            };
            self.entries.remove(&oldest);
        }
        self.entries.insert(key.to_owned(), (self.tick, value));
        self.order.insert(self.tick, key.to_owned());
    }

    fn remove(&mut self, key: &str) {
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
    controllers: Lru<Lru<Recalled>>,
}

impl IdMemory {
    pub(crate) fn new(per_controller: usize, controllers: usize) -> Self {
        Self {
            per_controller,
            controllers: Lru::new(controllers),
        }
    }

    /// What is remembered of `id` from `controller` (and it is now the
    /// most recently used).
    pub(crate) fn recall(&mut self, controller: &str, id: &str) -> Option<Recalled> {
        self.controllers
            .get_mut(controller)?
            .get_mut(id)
            .map(|r| r.clone())
    }

    /// Remembers `id` from `controller` as `what`.
    pub(crate) fn remember(&mut self, controller: &str, id: &str, what: Recalled) {
        if self.controllers.get_mut(controller).is_none() {
            self.controllers
                .insert(controller, Lru::new(self.per_controller));
        }
        if let Some(ids) = self.controllers.get_mut(controller) {
            ids.insert(id, what);
        }
    }

    /// Forgets `id` from `controller` (a line refused `busy`: its retry is
    /// a new try).
    pub(crate) fn forget(&mut self, controller: &str, id: &str) {
        if let Some(ids) = self.controllers.get_mut(controller) {
            ids.remove(id);
        }
    }

    /// How many ids are remembered for `controller`.
    #[cfg(test)]
    fn ids_of(&mut self, controller: &str) -> usize {
        self.controllers
            .get_mut(controller)
            .map_or(0, |ids| ids.len())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn done(s: &str) -> Recalled {
        Recalled::Done(vec![Arc::from(s)])
    }

    #[test]
    fn an_id_is_recalled_per_controller() {
        let mut m = IdMemory::new(4, 2);
        m.remember("a", "1", Recalled::InProgress(Origin(7)));
        assert_eq!(m.recall("a", "1"), Some(Recalled::InProgress(Origin(7))));
        assert_eq!(m.recall("b", "1"), None);
        m.remember("a", "1", done("r"));
        assert_eq!(m.recall("a", "1"), Some(done("r")));
        m.forget("a", "1");
        assert_eq!(m.recall("a", "1"), None);
    }

    #[test]
    fn the_least_recently_used_id_goes_first_and_the_bound_holds() {
        let mut m = IdMemory::new(3, 2);
        for id in ["1", "2", "3"] {
            m.remember("a", id, done(id));
        }
        // "1" used again: "2" is now the oldest.
        assert_eq!(m.recall("a", "1"), Some(done("1")));
        m.remember("a", "4", done("4"));
        assert_eq!(m.ids_of("a"), 3);
        assert_eq!(m.recall("a", "2"), None);
        assert_eq!(m.recall("a", "1"), Some(done("1")));
        assert_eq!(m.recall("a", "3"), Some(done("3")));
        assert_eq!(m.recall("a", "4"), Some(done("4")));
        for n in 0..10_000 {
            m.remember("a", &n.to_string(), done("x"));
        }
        assert_eq!(m.ids_of("a"), 3);
    }

    #[test]
    fn the_least_recently_heard_controller_is_forgotten_whole() {
        let mut m = IdMemory::new(3, 2);
        m.remember("a", "1", done("a1"));
        m.remember("b", "1", done("b1"));
        assert_eq!(m.recall("a", "1"), Some(done("a1")));
        m.remember("c", "1", done("c1"));
        assert_eq!(m.recall("b", "1"), None);
        assert_eq!(m.recall("a", "1"), Some(done("a1")));
        assert_eq!(m.recall("c", "1"), Some(done("c1")));
    }
}
