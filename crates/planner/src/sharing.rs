//! Learned thermal clauses shared between the racers of [`crate::race`].
//!
//! Why it is sound: a clause learned from a violation says "no plan that begins with this
//! prefix keeps its windows" — a fact about the part and its windows, whatever solver,
//! seed or warm start found it, and (shortened) only where the shortening is proven. The
//! racers encode the same part with the same k and acyclicity, so the same literals mean
//! the same moves in every one of them, and the race judges by the part's own windows
//! (never narrowed: an optimizing racer stops publishing once it narrows its windows, see
//! [`Sharing::stop_publishing`]). Cycle cuts and blocked plans are not shared: only
//! violations. Taking clauses in stays sound under narrowed windows: a plan that breaks a
//! window of the part breaks the narrowed window too.

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};

use crate::lit::Lit;

/// Every shared clause with the racer that learned it.
#[derive(Default)]
pub struct ClausePool {
    clauses: Mutex<Vec<(usize, Vec<Lit>)>>,
    /// The length of `clauses`, read without the lock on every propagation.
    len: AtomicUsize,
}

/// One racer's handle on the pool: what it publishes is marked as its own, and it reads
/// on from where it last read.
#[derive(Clone)]
pub struct Sharing {
    pool: Arc<ClausePool>,
    me: usize,
    seen: usize,
    /// False: publish only (the default racer, whose "no plan" and its reasons must be
    /// those of a run on its own).
    import: bool,
    /// False once the search judges by narrowed windows: its clauses are then no longer
    /// facts about the part's own windows. Shared by the clones of one handle (the search
    /// and its propagator).
    publishing: Arc<AtomicBool>,
}

impl Sharing {
    pub fn new(pool: Arc<ClausePool>, me: usize) -> Sharing {
        Sharing {
            pool,
            me,
            seen: 0,
            import: true,
            publishing: Arc::new(AtomicBool::new(true)),
        }
    }

    /// This handle publishes, but takes nothing in.
    pub fn publish_only(self) -> Sharing {
        Sharing {
            import: false,
            ..self
        }
    }

    /// This handle and its clones publish nothing from now on.
    pub fn stop_publishing(&self) {
        self.publishing.store(false, Ordering::Relaxed);
    }

    pub fn publish(&self, clause: &[Lit]) {
        if !self.publishing.load(Ordering::Relaxed) {
            return;
        }
        let mut clauses = self.pool.clauses.lock().expect("no racer panics");
        clauses.push((self.me, clause.to_vec()));
        self.pool.len.store(clauses.len(), Ordering::Release);
    }

    /// The clauses the other racers published since the last call, appended to `into`.
    pub fn take_new(&mut self, into: &mut Vec<Vec<Lit>>) -> usize {
        if !self.import || self.pool.len.load(Ordering::Acquire) == self.seen {
            return 0;
        }
        let clauses = self.pool.clauses.lock().expect("no racer panics");
        let before = into.len();
        into.extend(
            clauses[self.seen..]
                .iter()
                .filter(|(owner, _)| *owner != self.me)
                .map(|(_, c)| c.clone()),
        );
        self.seen = clauses.len();
        into.len() - before
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_racer_reads_the_others_clauses_once_and_never_its_own() {
        let pool = Arc::new(ClausePool::default());
        let (mut a, mut b) = (Sharing::new(pool.clone(), 0), Sharing::new(pool, 1));
        a.publish(&[Lit::positive(1)]);
        b.publish(&[Lit::positive(2)]);
        let (mut got_a, mut got_b) = (Vec::new(), Vec::new());
        assert_eq!(a.take_new(&mut got_a), 1);
        assert_eq!(b.take_new(&mut got_b), 1);
        assert_eq!(got_a, vec![vec![Lit::positive(2)]]);
        assert_eq!(got_b, vec![vec![Lit::positive(1)]]);
        assert_eq!(a.take_new(&mut got_a), 0, "read once");
        a.publish(&[Lit::positive(3)]);
        assert_eq!(b.take_new(&mut got_b), 1);
        assert_eq!(got_b.last(), Some(&vec![Lit::positive(3)]));
        let mut quiet = b.clone().publish_only();
        b.publish(&[Lit::positive(4)]);
        a.publish(&[Lit::positive(5)]);
        assert_eq!(quiet.take_new(&mut got_b), 0, "publishes only");
    }

    #[test]
    fn a_handle_that_stopped_publishing_still_reads() {
        let pool = Arc::new(ClausePool::default());
        let (mut a, mut b) = (Sharing::new(pool.clone(), 0), Sharing::new(pool, 1));
        let a_inside = a.clone();
        a.stop_publishing();
        a_inside.publish(&[Lit::positive(1)]);
        let mut got_b = Vec::new();
        assert_eq!(b.take_new(&mut got_b), 0, "its clones stopped too");
        b.publish(&[Lit::positive(2)]);
        let mut got_a = Vec::new();
        assert_eq!(a.take_new(&mut got_a), 1);
    }
}
