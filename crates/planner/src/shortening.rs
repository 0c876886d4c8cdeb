//! Proven clause shortening: a violating prefix is cut back while every allowed next step
//! from the shorter prefix breaks a window within that step too. Then the shorter prefix
//! already forces a violation, and its clause is learned instead. Every step tried is one the
//! weld-graph rules allow (a successor of the last block, or a new fragment at any block
//! whose support is welded), so no feasible plan is cut off. The thermal loop and the
//! check inside the search both learn through it.

use waam_part::graph::WeldGraph;
use waam_thermal::{Interrupt, Simulation};

/// A doomed prefix after shortening.
pub struct Shortened {
    /// Blocks in it, and whether its last fragment is closed.
    pub len: usize,
    pub closed: bool,
    /// Steps dropped, and block-steps simulated to prove it.
    pub dropped: u64,
    pub cost: u64,
}

/// Shortens the doomed prefix `seq[..len]` (its last fragment closed or not) within
/// `budget` block-steps; `state_after(l)`: the simulation after `seq[..l]` (None: give up).
/// Stops where it is when `interrupt` says so: a transit of 10^9 steps is simulated here
/// once per step tried, and the deadline must hold inside it.
#[allow(clippy::too_many_arguments)]
pub fn shorten<'m>(
    graph: &WeldGraph,
    max_fragments: usize,
    seq: &[(usize, bool)],
    mut len: usize,
    mut closed: bool,
    budget: usize,
    interrupt: &Interrupt,
    mut state_after: impl FnMut(usize) -> Option<Simulation<'m>>,
) -> Shortened {
    let n = graph.len();
    let mut budget = budget as i64;
    let (mut dropped, mut spent) = (0, 0);
    // An empty doomed prefix (len 0) proves that no plan is feasible: its clause is empty.
    while budget > 0 && len > 0 && !interrupt.reached() {
        if closed && len == n {
            closed = false; // a complete plan is the same whether closed or not
            continue;
        }
        // The shorter target, the step from it that is known doomed, and which kinds
        // of step remain to be tried from it.
        let (target_len, target_closed, skip, try_continue, try_new) = if closed {
            (len, false, None, true, false)
        } else {
            let (b, new) = seq[len - 1];
            if new {
                (len - 1, true, Some((b, true)), false, true)
            } else {
                (len - 1, false, Some((b, false)), true, true)
            }
        };
        let Some(base) = state_after(target_len) else {
            break;
        };
        let (proven, cost) = all_steps_violate(
            graph,
            max_fragments,
            &base.interrupted_by(interrupt),
            &seq[..target_len],
            skip,
            try_continue,
            try_new,
        );
        budget -= cost as i64;
        spent += cost;
        if !proven {
            break;
        }
        dropped += 1;
        len = target_len;
        closed = target_closed;
    }
    Shortened {
        len,
        closed,
        dropped,
        cost: spent,
    }
}

/// Whether every allowed next step after `prefix` (state `base`) breaks a window within
/// its own steps, and the block-steps simulated to find out. `skip`: a step (block,
/// new fragment) already proven doomed. The steps are: moving on to a successor of the last
/// block (`try_continue`), or closing the fragment and starting a new one at any block
/// whose support is welded (`try_new`, if fragments remain). A complete prefix has one
/// continuation: the cooldown. A step stopped by `base`'s interrupt proves nothing.
pub fn all_steps_violate(
    graph: &WeldGraph,
    max_fragments: usize,
    base: &Simulation<'_>,
    prefix: &[(usize, bool)],
    skip: Option<(usize, bool)>,
    try_continue: bool,
    try_new: bool,
) -> (bool, u64) {
    let n = graph.len();
    let placed = |b: usize| base.is_welded(b);
    let allowed = |b: usize, new: bool| {
        !placed(b)
            && Some((b, new)) != skip
            && graph.supports(b).iter().all(|&s| placed(s as usize))
    };
    let start = base.snapshot();
    let mut sim = base.clone();
    let mut cost = 0u64;
    let mut spent = |sim: &Simulation<'_>| {
        cost += (sim.steps() - base.steps()) * sim.welded() as u64;
    };
    if prefix.len() == n {
        let r = sim.finish();
        spent(&sim);
        return (!sim.cancelled() && matches!(r, Ok(Err(_))), cost);
    }
    if try_continue {
        if let Some(&(last, _)) = prefix.last() {
            for &c in graph.successors(last) {
                if !allowed(c as usize, false) {
                    continue;
                }
                sim.restore(&start);
                let r = sim.deposit(c as usize, false);
                spent(&sim);
                if r.is_ok() || sim.cancelled() {
                    return (false, cost);
                }
            }
        }
    }
    if try_new && base.fragments() < max_fragments {
        sim.restore(&start);
        let transit = sim.transit();
        spent(&sim);
        if sim.cancelled() {
            return (false, cost);
        }
        if transit.is_ok() {
            let after = sim.snapshot();
            for c in (0..n).filter(|&c| allowed(c, true)) {
                sim.restore(&after);
                let r = sim.deposit_after_transit(c);
                spent(&sim);
                if r.is_ok() || sim.cancelled() {
                    return (false, cost);
                }
            }
        }
    }
    (true, cost)
}
