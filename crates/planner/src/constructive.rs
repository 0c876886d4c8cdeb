//! A warm start: a valid plan built layer by layer, so the search starts beside one.
//!
//! Each layer is covered by as few weld paths as a small SAT solve of that layer alone
//! finds (one on most layers: a serpentine on a plate, a loop on a ring). The first path
//! of a layer starts on the block above where the layer below ended, so one weld path
//! climbs on through the part, and each layer's ends are steered to blocks whose block
//! above can start the next layer. A layer is a grid graph, so a checkerboard count tells
//! which starts a single path can have at all, and how many paths a layer needs at least.
//!
//! The plan is a hint, never a claim: a layer solve that takes too long is given up, and
//! so is the plan when it needs more than k weld paths. The global search decides what is
//! feasible, best or impossible.

use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::{Duration, Instant};

use waam_part::graph::WeldGraph;
use waam_part::plan::Plan;
use waam_part::Part;

use crate::encoding::Acyclicity;
use crate::sat::{Backend, Lit};
use crate::search::Search;

/// When to give up, shared by every layer solve.
pub struct Limits {
    pub deadline: Option<Instant>,
    pub cancel: Option<Arc<AtomicBool>>,
}

impl Limits {
    fn stopped(&self) -> bool {
        self.deadline.is_some_and(|d| Instant::now() >= d)
            || self
                .cancel
                .as_ref()
                .is_some_and(|c| c.load(std::sync::atomic::Ordering::Relaxed))
    }

    /// The deadline of one layer attempt: short, so a hard layer costs little.
    fn attempt(&self, blocks: usize) -> Instant {
        let own = Instant::now() + Duration::from_millis(500 + 2 * blocks as u64);
        self.deadline.map_or(own, |d| d.min(own))
    }
}

/// A valid plan of `part` with at most `k` fragments, built layer by layer; `None` when
/// this construction does not find one in time.
pub fn layered_plan(
    part: &Part,
    graph: &WeldGraph,
    k: usize,
    backend: Backend,
    limits: &Limits,
) -> Option<Vec<Vec<usize>>> {
    let layers = layer_ranges(part);
    let mut plan: Vec<Vec<usize>> = Vec::new();
    for (l, range) in layers.iter().enumerate() {
        if limits.stopped() {
            return None;
        }
        // Where the weld path arriving from below would start this layer.
        let arriving = plan
            .last()
            .and_then(|f| graph.above(*f.last()?))
            .filter(|b| range.contains(b))
            .map(|b| b - range.start);
        // A layer like the one below, entered above its path's end: that path walked
        // back (a serpentine up a wall), with no solve.
        if let (Some(below), Some(_)) = (l.checked_sub(1).map(|b| &layers[b]), arriving) {
            let same = below.len() == range.len()
                && part.blocks()[below.clone()]
                    .iter()
                    .zip(&part.blocks()[range.clone()])
                    .all(|(a, b)| a[..2] == b[..2]);
            let last = plan.last().expect("arriving from a weld path");
            if same && last.len() >= below.len() {
                let walked = &last[last.len() - below.len()..];
                if walked.iter().all(|b| below.contains(b)) {
                    let back: Vec<usize> = walked
                        .iter()
                        .rev()
                        .map(|b| b - below.start + range.start)
                        .collect();
                    plan.last_mut().expect("checked").extend(back);
                    continue;
                }
            }
        }
        let layer = Layer::new(part, range.clone());
        // Ends whose block above can start the next layer's single path.
        let ends: Option<Vec<bool>> = layers.get(l + 1).map(|next| {
            let next = Layer::new(part, next.clone());
            range
                .clone()
                .map(|b| {
                    graph
                        .above(b)
                        .is_some_and(|a| next.single_path_may_start(a - next.first))
                })
                .collect()
        });
        let ends = ends.filter(|e| e.iter().any(|&ok| ok));
        let new_fragments_left = k.saturating_sub(plan.len());
        let pieces = layer.solve(
            arriving,
            ends.as_deref(),
            new_fragments_left,
            backend,
            limits,
        )?;
        let mut pieces = pieces.into_iter();
        if arriving.is_some_and(|s| pieces.as_slice()[0][0] == range.start + s) {
            let first = pieces.next().expect("a layer has a piece");
            plan.last_mut()
                .expect("arriving from a weld path")
                .extend(first);
        }
        plan.extend(pieces);
        if plan.len() > k {
            return None;
        }
    }
    // Trust, but verify: a warm start must be a plan the rules allow (with k fragments,
    // which an override may set above the part's own).
    let widened;
    let rules = if k > part.max_fragments {
        let mut p = part.clone();
        p.max_fragments = k;
        widened = p;
        &widened
    } else {
        part
    };
    match Plan::from_indices(part, &plan).validate(rules, graph) {
        Ok(_) => Some(plan),
        Err(e) => {
            tracing::warn!("the layer-by-layer warm start built an invalid plan ({e}); not used");
            None
        }
    }
}

/// The index ranges of the part's layers (blocks are sorted by z, y, x).
fn layer_ranges(part: &Part) -> Vec<std::ops::Range<usize>> {
    let mut out = Vec::new();
    let mut start = 0;
    for i in 1..=part.len() {
        if i == part.len() || part.block(i)[2] != part.block(start)[2] {
            out.push(start..i);
            start = i;
        }
    }
    out
}

/// One layer as a part of its own (its blocks keep their order: local i is global
/// `first + i`).
struct Layer {
    first: usize,
    part: Part,
    /// Checkerboard colour (x + y parity) of each block.
    colour: Vec<bool>,
    /// Blocks of either colour.
    count: [usize; 2],
}

impl Layer {
    fn new(part: &Part, range: std::ops::Range<usize>) -> Layer {
        let blocks: Vec<_> = part.blocks()[range.clone()]
            .iter()
            .map(|b| [b[0], b[1], 0])
            .collect();
        let colour: Vec<bool> = blocks.iter().map(|b| (b[0] + b[1]) % 2 == 1).collect();
        let odd = colour.iter().filter(|&&c| c).count();
        let layer = Part::from_blocks(part.name.clone(), part.block_mm, [0.0; 3], 1, blocks)
            .expect("a layer of a valid part is a valid part");
        Layer {
            first: range.start,
            part: layer,
            count: [colour.len() - odd, odd],
            colour,
        }
    }

    /// Whether one path through every block may start at local block `b`: a path
    /// alternates colours, so with one colour in the majority it starts (and ends) there.
    fn single_path_may_start(&self, b: usize) -> bool {
        let [even, odd] = self.count;
        match even.cmp(&odd) {
            std::cmp::Ordering::Equal => true,
            std::cmp::Ordering::Greater => !self.colour[b],
            std::cmp::Ordering::Less => self.colour[b],
        }
    }

    /// The fewest paths that can cover the layer: per component of its moves, the dead
    /// ends (two per path at most) and the colour surplus (one per path at most).
    fn fewest_paths(&self, graph: &WeldGraph) -> usize {
        let n = self.part.len();
        let mut seen = vec![false; n];
        let mut total = 0;
        for s in 0..n {
            if seen[s] {
                continue;
            }
            seen[s] = true;
            let (mut stack, mut ends, mut count) = (vec![s], 0usize, [0i64; 2]);
            while let Some(i) = stack.pop() {
                count[usize::from(self.colour[i])] += 1;
                if graph.successors(i).len() == 1 {
                    ends += 1;
                }
                for &j in graph.successors(i) {
                    if !std::mem::replace(&mut seen[j as usize], true) {
                        stack.push(j as usize);
                    }
                }
            }
            let surplus = (count[0] - count[1]).unsigned_abs() as usize;
            total += ends.div_ceil(2).max(surplus).max(1);
        }
        total
    }

    /// The layer's paths (global indices, in order): the first starting at `arriving`
    /// when it can, ends where `ends` allows when they can. Paths beyond the arriving
    /// one each take one of `new_fragments_left`.
    fn solve(
        &self,
        arriving: Option<usize>,
        ends: Option<&[bool]>,
        new_fragments_left: usize,
        backend: Backend,
        limits: &Limits,
    ) -> Option<Vec<Vec<usize>>> {
        let graph = WeldGraph::new(&self.part);
        let most = new_fragments_left + usize::from(arriving.is_some());
        for paths in self.fewest_paths(&graph)..=most {
            let mut search = Search::new(&self.part, &graph, paths, Acyclicity::Lazy, 0, backend);
            // (start at the arriving block?, steer the ends?), best first.
            let mut tries = Vec::new();
            if arriving.is_some_and(|s| paths > 1 || self.single_path_may_start(s)) {
                tries.extend([(true, true), (true, false)]);
            }
            if paths <= new_fragments_left {
                tries.extend([(false, true), (false, false)]);
            }
            for (from_arriving, steer) in tries {
                if steer && ends.is_none() {
                    continue;
                }
                let mut assume: Vec<Lit> = Vec::new();
                if from_arriving {
                    assume.push(search.enc.starts_fragment(arriving?, 0));
                }
                if let (true, Some(ends)) = (steer, ends) {
                    let enc = &search.enc;
                    assume.extend(
                        (0..ends.len())
                            .filter(|&b| !ends[b])
                            .map(|b| !enc.ends_at(b)),
                    );
                }
                search.set_interrupt(Some(limits.attempt(self.part.len())), limits.cancel.clone());
                if let Some(pieces) = search.next_candidate(&assume) {
                    return Some(
                        pieces
                            .into_iter()
                            .map(|p| p.into_iter().map(|b| self.first + b).collect())
                            .collect(),
                    );
                }
                if limits.stopped() {
                    return None;
                }
            }
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plate_tower(w: i64, d: i64, h: i64, k: usize) -> Part {
        let blocks = (0..h)
            .flat_map(|z| (0..d).flat_map(move |y| (0..w).map(move |x| [x, y, z])))
            .collect();
        Part::from_blocks("t".into(), [6.0, 6.0, 2.5], [0.0; 3], k, blocks).unwrap()
    }

    fn unlimited() -> Limits {
        Limits {
            deadline: None,
            cancel: None,
        }
    }

    #[test]
    fn a_solid_block_is_one_weld_path_climbing_layer_by_layer() {
        for (w, d) in [(4, 4), (5, 5), (3, 6)] {
            let part = plate_tower(w, d, 5, 1);
            let graph = WeldGraph::new(&part);
            let plan = layered_plan(&part, &graph, 1, Backend::Cadical, &unlimited())
                .unwrap_or_else(|| panic!("{w}x{d}: no plan"));
            assert_eq!(plan.len(), 1);
            assert_eq!(plan[0].len(), part.len());
        }
    }

    #[test]
    fn a_layer_in_two_pieces_takes_two_weld_paths_or_none() {
        // Two separate columns of 3 x 1 rows: each layer has two components.
        let blocks: Vec<_> = (0..3)
            .flat_map(|z| (0..3).flat_map(move |x| [[x, 0, z], [x, 2, z]]))
            .collect();
        let part = Part::from_blocks("two".into(), [6.0, 6.0, 2.5], [0.0; 3], 2, blocks).unwrap();
        let graph = WeldGraph::new(&part);
        // Layer by layer needs a new weld path for every layer's second piece.
        assert!(layered_plan(&part, &graph, 2, Backend::Cadical, &unlimited()).is_none());
        let plan = layered_plan(&part, &graph, 6, Backend::Varisat, &unlimited()).unwrap();
        assert!(plan.len() <= 6);
    }
}
