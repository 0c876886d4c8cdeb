//! A warm start: a valid plan built layer by layer, so the search starts beside one.
//!
//! Each layer is covered by as few weld paths as a small SAT solve of that layer alone
//! finds (one on most layers: a serpentine on a plate, a loop on a ring); a layer of whole
//! rows that one path can cover is given its serpentine directly, since the solve of a
//! plate of 10^4 blocks takes minutes (the floor of a box at 10^5). The first path
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
use waam_thermal as thermal;

/// When to give up, shared by every layer solve.
#[derive(Clone)]
pub struct Limits {
    pub deadline: Option<Instant>,
    pub cancel: Option<Arc<AtomicBool>>,
}

impl Limits {
    pub(crate) fn stopped(&self) -> bool {
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
///
/// Every weld path that crosses a layer climbs on: the next layer's pieces start above
/// where this layer's pieces end, as far as the layer solve allows, so a wall that needs m
/// paths per layer is built by m weld paths climbing side by side (each welded whole
/// before the next, which only ever stands beside, never under, the one before).
pub fn layered_plan(
    part: &Part,
    graph: &WeldGraph,
    k: usize,
    backend: Backend,
    limits: &Limits,
) -> Option<Vec<Vec<usize>>> {
    layered_plan_from(part, graph, k, backend, limits, &[])
}

/// The first weld path's first move `(from, to)` (global block indices, both in the first
/// layer): where the construction starts and which way it sets off.
pub type FirstMove = (usize, usize);

/// How the first layer's weld paths begin: path i starts with the blocks `first[i]` (global
/// indices, in weld order; empty: as the solve likes). A first move is the first path's
/// first two blocks; a whole cover of the layer fixes every path, its way and its order.
///
/// [`layered_plan`] with its first layer set off so (when the first layer's solve allows
/// it; else `None`). Where a layer starts decides where its seam lies and so when each
/// block gets the block above it; on a layer that needs several paths, which of them takes
/// a junction decides which blocks climb together: the warm-start portfolio
/// (`crate::portfolio`) varies both.
pub fn layered_plan_from(
    part: &Part,
    graph: &WeldGraph,
    k: usize,
    backend: Backend,
    limits: &Limits,
    first: &[Vec<usize>],
) -> Option<Vec<Vec<usize>>> {
    let layers = layer_ranges(part);
    let mut plan: Vec<Vec<usize>> = Vec::new();
    // The pieces of the layer below: (fragment, its blocks in weld order).
    let mut below: Vec<(usize, Vec<usize>)> = Vec::new();
    for (l, range) in layers.iter().enumerate() {
        if limits.stopped() {
            return None;
        }
        // A layer like the one below: each of its pieces walked back above itself (a
        // serpentine up a wall), with no solve.
        if let Some(prev) = l.checked_sub(1).map(|b| &layers[b]) {
            if same_footprint(part, prev, range) && !below.is_empty() {
                for (f, piece) in &mut below {
                    piece.reverse();
                    for b in piece.iter_mut() {
                        *b = *b - prev.start + range.start;
                    }
                    plan[*f].extend_from_slice(piece);
                }
                continue;
            }
        }
        let layer = Layer::new(part, range.clone());
        // Where the weld paths arriving from below would start this layer (local blocks).
        let arriving: Vec<(usize, usize)> = below
            .iter()
            .filter_map(|(f, piece)| {
                let up = graph.above(*piece.last()?)?;
                range.contains(&up).then(|| (*f, up - range.start))
            })
            .collect();
        // The layers above with this footprint will be this one walked back and forth, so
        // steer the pieces to end (or, below an even number of such layers, to start)
        // under blocks that can start a path of the first different layer above.
        let top = (l..layers.len())
            .take_while(|&t| t == l || same_footprint(part, &layers[t - 1], &layers[t]))
            .last()
            .expect("l itself");
        let steer: Option<Steer> = layers.get(top + 1).map(|next| {
            let next = Layer::new(part, next.clone());
            let allowed = layers[top]
                .clone()
                .map(|b| {
                    graph
                        .above(b)
                        .is_some_and(|a| next.path_may_start(a - next.first))
                })
                .collect();
            Steer {
                allowed,
                ends: (top - l) % 2 == 0,
            }
        });
        let steer = steer.filter(|s| s.allowed.iter().any(|&ok| ok));
        let starts: Vec<usize> = arriving.iter().map(|&(_, b)| b).collect();
        let new_fragments_left = k.saturating_sub(plan.len());
        let first_here: Vec<Vec<usize>> = if l == 0 {
            first
                .iter()
                .map(|p| p.iter().map(|&b| b - range.start).collect())
                .collect()
        } else {
            Vec::new()
        };
        let Some((pieces, continued)) = layer.solve(
            &starts,
            &first_here,
            steer.as_ref(),
            new_fragments_left,
            backend,
            limits,
        ) else {
            tracing::debug!(
                "warm start: no cover of layer z = {} with {} arriving and {new_fragments_left} new weld path(s)",
                part.block(range.start)[2],
                starts.len()
            );
            return None;
        };
        below.clear();
        for (i, piece) in pieces.into_iter().enumerate() {
            let f = if i < continued {
                plan[arriving[i].0].extend_from_slice(&piece);
                arriving[i].0
            } else {
                plan.push(piece.clone());
                plan.len() - 1
            };
            below.push((f, piece));
        }
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
    // A weld path that climbed on may stand on a piece another path began later, lower
    // down: weld the paths in an order where each stands only on paths welded before it.
    let Some(plan) = in_support_order(graph, plan) else {
        tracing::debug!("warm start: its weld paths stand on each other in a cycle; not used");
        return None;
    };
    match Plan::from_indices(part, &plan).validate(rules, graph) {
        Ok(_) => Some(plan),
        Err(e) => {
            tracing::warn!("the layer-by-layer warm start built an invalid plan ({e}); not used");
            None
        }
    }
}

/// Whether the first layer has a cover by at most `k` paths that begin as `first` says
/// (global blocks, as [`layered_plan_from`] takes them): the first solve of that build,
/// without the layers above. A start inside a branch of a T has none: the portfolio skips
/// such starts at the cost of one small solve each, not a build. `None` when the part
/// has no layer.
pub fn first_layer_allows<'l>(
    part: &Part,
    k: usize,
    backend: Backend,
    limits: &'l Limits,
) -> Option<impl Fn(&[Vec<usize>]) -> bool + 'l> {
    let range = layer_ranges(part).into_iter().next()?;
    let layer = Layer::new(part, range.clone());
    Some(move |first: &[Vec<usize>]| {
        let local: Option<Vec<Vec<usize>>> = first
            .iter()
            .map(|p| {
                p.iter()
                    .map(|b| range.contains(b).then(|| b - range.start))
                    .collect()
            })
            .collect();
        local.is_some_and(|local| layer.solve(&[], &local, None, k, backend, limits).is_some())
    })
}

/// The covers of the first layer by as many paths as `base` (its pieces, global blocks in
/// weld order): `base` first, then each cover in which an end of one of its pieces welds on
/// to a neighbour it does not weld to in `base`, so that some path ends elsewhere (on a
/// branching layer another branch takes the junction; on a ring the seam moves) and, where
/// that neighbour is a junction, each such cover going on from it along each other arm (the
/// solve picks one; on a T-wall the cover that kept every window was another). Each cover
/// once (as its set of welded pairs), in a fixed order, paths in the solve's order; fewer
/// when the run stops.
pub fn first_layer_covers(
    part: &Part,
    backend: Backend,
    limits: &Limits,
    base: &[Vec<usize>],
) -> Vec<Vec<Vec<usize>>> {
    let mut out = vec![base.to_vec()];
    let Some(range) = layer_ranges(part).into_iter().next() else {
        return out;
    };
    if base.iter().flatten().any(|b| !range.contains(b)) {
        return out;
    }
    let local: Vec<Vec<usize>> = base
        .iter()
        .map(|p| p.iter().map(|&b| b - range.start).collect())
        .collect();
    let layer = Layer::new(part, range.clone());
    let graph = WeldGraph::new(&layer.part);
    let pairs = |pieces: &[Vec<usize>]| -> std::collections::BTreeSet<(usize, usize)> {
        pieces
            .iter()
            .flat_map(|p| p.windows(2).map(|w| (w[0].min(w[1]), w[0].max(w[1]))))
            .collect()
    };
    let mut seen = vec![pairs(&local)];
    let Some(mut search) = layer.search(&graph, local.len().max(1), backend, limits) else {
        return out;
    };
    // A cover with `assumed` welded, if any and not seen yet: kept (global blocks).
    let mut cover_with = |search: &mut Search, assumed: &[Lit]| -> Option<Vec<Vec<usize>>> {
        let deadline = limits.attempt(layer.part.len());
        search.set_interrupt(Some(deadline), limits.cancel.clone());
        let pieces = search.next_candidate(assumed)?;
        let key = pairs(&pieces);
        if !seen.contains(&key) {
            seen.push(key);
            out.push(
                pieces
                    .iter()
                    .map(|p| p.iter().map(|&b| range.start + b).collect())
                    .collect(),
            );
        }
        Some(pieces)
    };
    for piece in &local {
        let (Some(&head), Some(&tail)) = (piece.first(), piece.last()) else {
            continue;
        };
        // Each end with the block it welds to in its piece (none on a one-block piece).
        let n = piece.len();
        let mut ends = vec![(head, piece.get(1).copied())];
        if n > 1 {
            ends.push((tail, Some(piece[n - 2])));
        }
        for (end, along) in ends {
            for &next in graph.successors(end) {
                let next = next as usize;
                if Some(next) == along {
                    continue;
                }
                for (a, b) in [(end, next), (next, end)] {
                    if limits.stopped() {
                        return out;
                    }
                    let Some(welded) = search.enc.edge(a, b) else {
                        continue;
                    };
                    let Some(pieces) = cover_with(&mut search, &[welded]) else {
                        continue;
                    };
                    // At a junction the path goes on from `next` one way of several, as the
                    // solver chose: each other way is a cover of its own (on a T, the path
                    // that takes the junction goes on along either arm).
                    let onward = |u: usize, v: usize| if a == end { (u, v) } else { (v, u) };
                    let taken = pieces.iter().find_map(|p| {
                        let at = p.iter().position(|&x| x == next)?;
                        if a == end {
                            p.get(at + 1)
                        } else {
                            at.checked_sub(1).map(|i| &p[i])
                        }
                        .copied()
                    });
                    for &other in graph.successors(next) {
                        let other = other as usize;
                        if other == end || Some(other) == taken {
                            continue;
                        }
                        if limits.stopped() {
                            return out;
                        }
                        let (u, v) = onward(next, other);
                        if let Some(on) = search.enc.edge(u, v) {
                            cover_with(&mut search, &[welded, on]);
                        }
                    }
                }
            }
        }
    }
    out
}

/// Raster covers of the first layer by `paths` paths, when it has area (a block with all
/// four sideways neighbours; a ring has none): rows along x, then along y, each set off
/// from each of the layer's four corners along its rows. As in a raster, a path crosses to
/// another row only from a row's end to a row's end (a block without a neighbour on one
/// side along the rows) and then welds along that row to its other end; a layer whose rows
/// do not allow that from some corner or in some direction gets no cover there. Each cover
/// once, global blocks in weld order; fewer when the run stops.
///
/// Why: on a plate a raster's direction and corner decide how soon each block's
/// neighbours in the next row are welded (a row's length later, or at once at a turn),
/// and so the block's t8/5; the layer solve picks one direction for every plan it builds.
pub fn raster_covers(
    part: &Part,
    backend: Backend,
    limits: &Limits,
    paths: usize,
) -> Vec<Vec<Vec<usize>>> {
    let mut out: Vec<Vec<Vec<usize>>> = Vec::new();
    let Some(range) = layer_ranges(part).into_iter().next() else {
        return out;
    };
    let layer = Layer::new(part, range.clone());
    let graph = WeldGraph::new(&layer.part);
    let at = |b: usize| layer.part.block(b);
    let has = |x: i64, y: i64| layer.part.index_of([x, y, 0]).is_some();
    let area = (0..layer.part.len()).any(|b| {
        let [x, y, _] = at(b);
        has(x - 1, y) && has(x + 1, y) && has(x, y - 1) && has(x, y + 1)
    });
    if !area || paths == 0 {
        return out;
    }
    // The corners: the blocks furthest along each diagonal (the first on a tie).
    let corners: Vec<usize> = [(1, 1), (-1, 1), (1, -1), (-1, -1)]
        .iter()
        .filter_map(|&(sx, sy)| {
            (0..layer.part.len()).min_by_key(|&b| {
                let [x, y, _] = at(b);
                sx * x + sy * y
            })
        })
        .collect();
    let serpentines = if paths == 1 {
        layer.serpentines()
    } else {
        Vec::new()
    };
    for axis in [0, 1] {
        // On a layer of whole rows the one-path rasters are its serpentines: no solve.
        let along: Vec<&Vec<usize>> = serpentines
            .iter()
            .filter(|p| at(p[0])[axis] != at(p[1])[axis])
            .collect();
        if !along.is_empty() {
            for path in along {
                out.push(vec![path.iter().map(|&b| range.start + b).collect()]);
            }
            continue;
        }
        let Some(mut search) = layer.search(&graph, paths, backend, limits) else {
            return out;
        };
        // Along the rows: +1 / -1 in `axis`; a row's end lacks a neighbour on one side.
        let step = |b: usize, d: i64| {
            let mut p = at(b);
            p[axis] += d;
            layer.part.index_of(p)
        };
        let row_end = |b: usize| step(b, -1).is_none() || step(b, 1).is_none();
        // A move across the rows only between two row ends, and never two in a row: each
        // row entered is welded to its other end.
        let turns: Vec<(usize, usize, crate::sat::Lit)> = search
            .enc
            .edges()
            .filter(|&(u, v, _)| at(u)[axis] == at(v)[axis])
            .collect();
        let mut clauses: Vec<Vec<crate::sat::Lit>> = turns
            .iter()
            .filter(|&&(u, v, _)| !(row_end(u) && row_end(v)))
            .map(|&(_, _, e)| vec![!e])
            .collect();
        let mut turns_from: Vec<Vec<(usize, crate::sat::Lit)>> = vec![Vec::new(); layer.part.len()];
        for &(u, v, e) in &turns {
            turns_from[u].push((v, e));
        }
        for &(u, v, e) in &turns {
            for &(_, f) in turns_from[v].iter().filter(|&&(w, _)| w != u) {
                clauses.push(vec![!e, !f]);
            }
        }
        search.add_clauses(&clauses);
        for &corner in &corners {
            if limits.stopped() {
                return out;
            }
            // Off along the row, into the layer.
            let Some(next) = step(corner, 1).or_else(|| step(corner, -1)) else {
                continue;
            };
            let Some(first) = search.enc.edge(corner, next) else {
                continue;
            };
            let deadline = limits.attempt(layer.part.len());
            search.set_interrupt(Some(deadline), limits.cancel.clone());
            let start = search.enc.starts_fragment(corner, 0);
            let Some(pieces) = search.next_candidate(&[start, first]) else {
                continue;
            };
            let cover: Vec<Vec<usize>> = pieces
                .into_iter()
                .map(|p| p.into_iter().map(|b| range.start + b).collect())
                .collect();
            if !out.contains(&cover) {
                out.push(cover);
            }
        }
    }
    out
}

/// The fragments reordered so that each stands only on fragments welded before it (the
/// earliest such fragment first, so an order that already allows this is kept); `None` when
/// two fragments stand on each other.
fn in_support_order(graph: &WeldGraph, plan: Vec<Vec<usize>>) -> Option<Vec<Vec<usize>>> {
    let mut fragment_of = vec![usize::MAX; graph.len()];
    for (f, blocks) in plan.iter().enumerate() {
        for &b in blocks {
            fragment_of[b] = f;
        }
    }
    // stands_on[f]: the other fragments some block of f stands on.
    let stands_on: Vec<std::collections::BTreeSet<usize>> = plan
        .iter()
        .enumerate()
        .map(|(f, blocks)| {
            blocks
                .iter()
                .flat_map(|&b| graph.supports(b))
                .map(|&s| fragment_of[s as usize])
                .filter(|&g| g != f)
                .collect()
        })
        .collect();
    let mut placed = vec![false; plan.len()];
    let mut order = Vec::with_capacity(plan.len());
    while order.len() < plan.len() {
        let next =
            (0..plan.len()).find(|&f| !placed[f] && stands_on[f].iter().all(|&g| placed[g]))?;
        placed[next] = true;
        order.push(next);
    }
    let mut plan: Vec<Option<Vec<usize>>> = plan.into_iter().map(Some).collect();
    Some(
        order
            .into_iter()
            .map(|f| plan[f].take().expect("each once"))
            .collect(),
    )
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

/// Whether two layers cover the same (x, y) cells (blocks are sorted by z, y, x, so their
/// blocks then pair up in order).
fn same_footprint(part: &Part, a: &std::ops::Range<usize>, b: &std::ops::Range<usize>) -> bool {
    a.len() == b.len()
        && part.blocks()[a.clone()]
            .iter()
            .zip(&part.blocks()[b.clone()])
            .all(|(p, q)| p[..2] == q[..2])
}

/// Where a layer's pieces should end (or start), per local block.
struct Steer {
    allowed: Vec<bool>,
    /// Steer the ends (else the starts).
    ends: bool,
}

/// One layer as a part of its own (its blocks keep their order: local i is global
/// `first + i`).
struct Layer {
    first: usize,
    part: Part,
    /// Whether a path through the layer, as few as it needs, may start at each block.
    may_start: Vec<bool>,
}

impl Layer {
    fn new(part: &Part, range: std::ops::Range<usize>) -> Layer {
        let blocks: Vec<_> = part.blocks()[range.clone()]
            .iter()
            .map(|b| [b[0], b[1], 0])
            .collect();
        let layer = Part::from_blocks(part.name.clone(), part.block_mm, [0.0; 3], 1, blocks)
            .expect("a layer of a valid part is a valid part");
        let may_start = starts_of_fewest_paths(&layer);
        Layer {
            first: range.start,
            part: layer,
            may_start,
        }
    }

    fn path_may_start(&self, b: usize) -> bool {
        self.may_start[b]
    }

    /// A search of the layer's covers by at most `paths` paths (`graph`: the layer's); the
    /// encoding of a big layer takes seconds, so it is built within the run's limits.
    fn search<'a>(
        &'a self,
        graph: &'a WeldGraph,
        paths: usize,
        backend: Backend,
        limits: &Limits,
    ) -> Option<Search<'a>> {
        let run_limits = thermal::Interrupt {
            deadline: limits.deadline,
            cancel: limits.cancel.clone(),
        };
        Search::new(
            &self.part,
            graph,
            paths,
            Acyclicity::Lazy,
            0,
            backend,
            run_limits,
        )
    }

    /// The layer's paths (global indices, in order) and how many of them start at the
    /// first of `arriving` (in that order: path i starts at `arriving[i]`), as many as
    /// the solve allows; steered where `steer` allows when they can. Paths beyond those each
    /// take one of `new_fragments_left`. `first` (local blocks): how the new paths begin
    /// (path i with `first[i]`), when no path arrives.
    fn solve(
        &self,
        arriving: &[usize],
        first: &[Vec<usize>],
        steer: Option<&Steer>,
        new_fragments_left: usize,
        backend: Backend,
        limits: &Limits,
    ) -> Option<(Vec<Vec<usize>>, usize)> {
        let graph = WeldGraph::new(&self.part);
        let fewest = crate::layer_path_bound(&self.part, &graph)[0].1;
        // Steered where that can work, else not.
        let steerings: Vec<Option<&Steer>> = steer.map(Some).into_iter().chain([None]).collect();
        let serpentines = self.serpentines();
        // Continue as many arriving paths as possible, then fewer (the last ones first).
        for continued in (0..=arriving.len()).rev() {
            let starts = &arriving[..continued];
            let own: &[Vec<usize>] = if starts.is_empty() { first } else { &[] };
            let low = fewest.max(continued).max(own.len()).max(1);
            for paths in low..=new_fragments_left + continued {
                // With as few paths as the colours allow, a start on the minority colour
                // is impossible, and a SAT solver is slow to prove parity: skip it.
                let own_starts = own.iter().filter_map(|p| p.first());
                if paths == fewest
                    && !starts
                        .iter()
                        .chain(own_starts)
                        .all(|&b| self.path_may_start(b))
                {
                    continue;
                }
                let mut cached = None;
                for steer in &steerings {
                    // One path on a layer of whole rows: a serpentine, built directly (a
                    // SAT solve of a plate of 10^4 blocks takes minutes).
                    if paths == 1 {
                        let first = starts.first().or(own.first().and_then(|p| p.first()));
                        let begins = own.first().map_or(&[][..], |p| &p[..]);
                        if let Some(path) = serpentines.iter().find(|p| {
                            first.is_none_or(|&b| p[0] == b)
                                && p.starts_with(begins)
                                && steer.is_none_or(|s| {
                                    let at = if s.ends { p[p.len() - 1] } else { p[0] };
                                    s.allowed[at] || (!s.ends && continued == 1)
                                })
                        }) {
                            let path = path.iter().map(|b| self.first + b).collect();
                            return Some((vec![path], continued));
                        }
                    }
                    let search = match &mut cached {
                        Some(search) => search,
                        None => cached.insert(self.search(&graph, paths, backend, limits)?),
                    };
                    let enc = &search.enc;
                    let mut assume: Vec<Lit> = starts
                        .iter()
                        .enumerate()
                        .map(|(i, &b)| enc.starts_fragment(b, i))
                        .collect();
                    for (i, piece) in own.iter().enumerate() {
                        let Some(&from) = piece.first() else { continue };
                        assume.push(enc.starts_fragment(from, i));
                        for w in piece.windows(2) {
                            assume.push(enc.edge(w[0], w[1])?);
                        }
                    }
                    if let Some(steer) = steer {
                        let barred = (0..steer.allowed.len()).filter(|&b| !steer.allowed[b]);
                        if steer.ends {
                            assume.extend(barred.map(|b| !enc.ends_at(b)));
                        } else {
                            // Only new paths choose their start; arriving ones have theirs.
                            for b in barred {
                                assume.extend(
                                    (starts.len()..paths).map(|i| !enc.starts_fragment(b, i)),
                                );
                            }
                        }
                    }
                    let deadline = limits.attempt(self.part.len());
                    search.set_interrupt(Some(deadline), limits.cancel.clone());
                    if let Some(pieces) = search.next_candidate(&assume) {
                        let pieces = pieces
                            .into_iter()
                            .map(|p| p.into_iter().map(|b| self.first + b).collect())
                            .collect();
                        return Some((pieces, continued));
                    }
                    if limits.stopped() {
                        return None;
                    }
                    // A solve given up at its attempt's deadline leaves the solver lost in
                    // that question: the next one gets a fresh search. On box s8015 the
                    // steered floor was given up, and the unsteered solve after it on the
                    // same search failed too for 12 of 13 start variants whose floor the
                    // portfolio's filter had covered in about 0.5 s; fresh, for 4 of 26.
                    if search.interrupted {
                        cached = None;
                    }
                }
            }
        }
        None
    }
}

impl Layer {
    /// The serpentines through the layer (local blocks in weld order): along x or y, from
    /// the first or the last row, setting off either way; each row is welded whole, and the
    /// next row is entered where the last one ended. None when the rows are not whole
    /// (a ring, a plate with a hole) or a row's end has no row end beside it.
    fn serpentines(&self) -> Vec<Vec<usize>> {
        let n = self.part.len();
        let mut out: Vec<Vec<usize>> = Vec::new();
        for axis in [0, 1] {
            let across = 1 - axis;
            // The rows in order across them, each as its (first, last) along the axis.
            let mut rows: std::collections::BTreeMap<i64, (i64, i64, usize)> = Default::default();
            for b in 0..n {
                let p = self.part.block(b);
                let row = rows.entry(p[across]).or_insert((p[axis], p[axis], 0));
                row.0 = row.0.min(p[axis]);
                row.1 = row.1.max(p[axis]);
                row.2 += 1;
            }
            let whole = rows
                .values()
                .all(|&(lo, hi, count)| (hi - lo + 1) as usize == count);
            let keys: Vec<i64> = rows.keys().copied().collect();
            let consecutive = keys.windows(2).all(|w| w[1] == w[0] + 1);
            if !whole || !consecutive {
                continue;
            }
            let at = |along: i64, row: i64| {
                let mut p = [0, 0, 0];
                p[axis] = along;
                p[across] = row;
                self.part.index_of(p).expect("a whole row has the block")
            };
            for reversed in [false, true] {
                let order: Vec<i64> = match reversed {
                    false => keys.clone(),
                    true => keys.iter().rev().copied().collect(),
                };
                'way: for ascending in [true, false] {
                    let mut path = Vec::with_capacity(n);
                    let mut up = ascending;
                    for (i, &row) in order.iter().enumerate() {
                        let (lo, hi, _) = rows[&row];
                        if i > 0 {
                            // Enter this row beside where the last one ended, at one of its ends.
                            let ended = self.part.block(*path.last().expect("a row before"))[axis];
                            up = match ended {
                                e if e == lo => true,
                                e if e == hi => false,
                                _ => continue 'way,
                            };
                        }
                        match up {
                            true => path.extend((lo..=hi).map(|a| at(a, row))),
                            false => path.extend((lo..=hi).rev().map(|a| at(a, row))),
                        }
                    }
                    if !out.contains(&path) {
                        out.push(path);
                    }
                }
            }
        }
        out
    }
}

/// Per block of a one-layer part: whether a path may start there when each piece (a
/// component of sideways moves) is covered by as few paths as its checkerboard colours
/// allow. A path alternates colours, so when a piece has s more blocks of one colour and
/// needs exactly s paths, every one of them starts (and ends) on that colour; and when it
/// has twice as many dead ends as it needs paths, every path starts at a dead end.
fn starts_of_fewest_paths(layer: &Part) -> Vec<bool> {
    let graph = WeldGraph::new(layer);
    let n = layer.len();
    let colour = |i: usize| {
        let [x, y, _] = layer.block(i);
        ((x + y) & 1) as usize
    };
    let mut out = vec![true; n];
    let mut seen = vec![false; n];
    for s in 0..n {
        if seen[s] {
            continue;
        }
        seen[s] = true;
        let (mut stack, mut piece, mut ends, mut count) =
            (vec![s], Vec::new(), 0usize, [0usize; 2]);
        while let Some(i) = stack.pop() {
            piece.push(i);
            count[colour(i)] += 1;
            let next = graph.successors(i);
            if next.len() == 1 {
                ends += 1;
            }
            for &j in next {
                if !std::mem::replace(&mut seen[j as usize], true) {
                    stack.push(j as usize);
                }
            }
        }
        let surplus = count[0].abs_diff(count[1]);
        let fewest = ends.div_ceil(2).max(surplus).max(1);
        let major = usize::from(count[1] > count[0]);
        for &i in &piece {
            // Fewest paths with a surplus: they all start on the majority colour.
            let colour_ok = surplus == 0 || fewest > surplus || colour(i) == major;
            // Every dead end ends a path: with twice as many dead ends as paths, every
            // path starts at one.
            let end_ok = ends < 2 * fewest || graph.successors(i).len() == 1;
            out[i] = colour_ok && end_ok;
        }
    }
    out
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
    fn a_plate_has_a_raster_each_way_from_each_corner_and_a_ring_has_none() {
        let part = plate_tower(5, 4, 2, 1);
        let covers = raster_covers(&part, Backend::Cadical, &unlimited(), 1);
        assert_eq!(covers.len(), 8, "two directions from four corners");
        for cover in &covers {
            let path = &cover[0];
            assert_eq!(path.len(), 20, "one path covers the first layer");
            // Moves along y: only the 3 turns between the 4 rows along x, or all but the 4
            // turns between the 5 columns along y.
            let along_y: Vec<bool> = path
                .windows(2)
                .map(|p| part.block(p[0])[0] == part.block(p[1])[0])
                .collect();
            let turns = match along_y[0] {
                false => along_y.iter().filter(|&&a| a).count(),
                true => along_y.iter().filter(|&&a| !a).count(),
            };
            assert_eq!(turns, if along_y[0] { 4 } else { 3 }, "{path:?}");
        }
        let ring: Vec<_> = (0..4)
            .flat_map(|y| (0..4).map(move |x| [x, y, 0]))
            .filter(|&[x, y, _]| x % 3 == 0 || y % 3 == 0)
            .collect();
        let ring = Part::from_blocks("ring".into(), [6.0, 6.0, 2.5], [0.0; 3], 1, ring).unwrap();
        assert!(raster_covers(&ring, Backend::Cadical, &unlimited(), 1).is_empty());
    }

    #[test]
    fn layers_of_two_pieces_are_two_weld_paths_climbing_side_by_side() {
        // Two separate columns of 3 x 1 rows: each layer has two pieces.
        let blocks: Vec<_> = (0..3)
            .flat_map(|z| (0..3).flat_map(move |x| [[x, 0, z], [x, 2, z]]))
            .collect();
        let part = Part::from_blocks("two".into(), [6.0, 6.0, 2.5], [0.0; 3], 2, blocks).unwrap();
        let graph = WeldGraph::new(&part);
        for backend in [Backend::Cadical, Backend::Varisat] {
            let plan = layered_plan(&part, &graph, 2, backend, &unlimited()).unwrap();
            assert_eq!(plan.len(), 2);
            for f in &plan {
                assert_eq!(f.len(), 9, "each weld path climbs its own column");
            }
        }
    }

    /// A bracket whose upper layers need a second weld path beside the first: the path that
    /// climbs on stands on the piece the later path began lower down, so the construction
    /// welds that one first (before, it built a plan breaking rule 4 and dropped it).
    #[test]
    fn weld_paths_are_ordered_so_that_each_stands_on_paths_welded_before_it() {
        let part = Part::parse(include_str!("../../../config/parts/ex2-bracket.yaml"))
            .expect("the bundled bracket");
        let graph = WeldGraph::new(&part);
        let first_layer = 0..part.blocks().iter().take_while(|b| b[2] == 0).count();
        let moves: Vec<FirstMove> = first_layer
            .clone()
            .flat_map(|a| graph.successors(a).iter().map(move |&b| (a, b as usize)))
            .filter(|(_, b)| first_layer.contains(b))
            .collect();
        let k = part.max_fragments;
        let limits = unlimited();
        let built: Vec<_> = moves
            .iter()
            .map(|&(a, b)| {
                layered_plan_from(&part, &graph, k, Backend::Cadical, &limits, &[vec![a, b]])
            })
            .collect();
        assert!(
            built.iter().all(Option::is_some),
            "a plan from every first move: {} of {}",
            built.iter().flatten().count(),
            moves.len()
        );
    }

    /// The covers of the first layer of a T (a bar of `bar` blocks along x with a stem of
    /// `stem` blocks along y from `[stem_x, 0]`, 3 layers, k = 2), each checked to build a
    /// plan that begins with it; and which arm the junction is welded without, per cover.
    fn t_layer_covers(bar: i64, stem_x: i64, stem: i64) -> (Vec<Vec<Vec<usize>>>, Vec<usize>) {
        let t: Vec<[i64; 2]> = (0..bar)
            .map(|x| [x, 0])
            .chain((1..=stem).map(|y| [stem_x, y]))
            .collect();
        let blocks: Vec<_> = (0..3)
            .flat_map(|z| t.iter().map(move |&[x, y]| [x, y, z]))
            .collect();
        let part = Part::from_blocks("t".into(), [6.0, 6.0, 2.5], [0.0; 3], 2, blocks).unwrap();
        let graph = WeldGraph::new(&part);
        let base = layered_plan(&part, &graph, 2, Backend::Cadical, &unlimited()).unwrap();
        let first: Vec<Vec<usize>> = base
            .iter()
            .map(|f| f.iter().copied().take_while(|&b| b < t.len()).collect())
            .collect();
        let covers = first_layer_covers(&part, Backend::Cadical, &unlimited(), &first);
        assert_eq!(covers[0], first, "the base's cover first");
        let junction = part.index_of([stem_x, 0, 0]).unwrap();
        let apart = covers
            .iter()
            .map(|c| {
                let with: Vec<usize> = c
                    .iter()
                    .flat_map(|p| p.windows(2))
                    .filter(|w| w.contains(&junction))
                    .map(|w| w[0] + w[1] - junction)
                    .collect();
                assert_eq!(with.len(), 2, "the junction joins two arms");
                graph
                    .successors(junction)
                    .iter()
                    .map(|&b| b as usize)
                    .filter(|&b| b < t.len())
                    .find(|b| !with.contains(b))
                    .unwrap()
            })
            .collect();
        for cover in &covers {
            let plan = layered_plan_from(&part, &graph, 2, Backend::Cadical, &unlimited(), cover)
                .expect("a plan from each cover");
            for (f, piece) in plan.iter().zip(cover) {
                assert_eq!(&f[..piece.len()], &piece[..], "each path as given");
            }
        }
        (covers, apart)
    }

    #[test]
    fn a_t_layer_has_three_covers_by_two_paths_and_each_is_built() {
        // Two paths per layer: the junction goes with the left half, the right half or the
        // stem, whichever arm the solve picks for a path that takes the junction (the
        // shapes of the generated T-walls' first layers among them).
        for (bar, stem_x, stem) in [
            (7, 3, 3),
            (44, 37, 30),
            (40, 10, 25),
            (40, 21, 17),
            (9, 1, 5),
        ] {
            let (covers, mut apart) = t_layer_covers(bar, stem_x, stem);
            apart.sort();
            apart.dedup();
            assert_eq!(
                apart.len(),
                3,
                "T {bar}/{stem_x}/{stem}: three covers: {covers:?}"
            );
        }
    }

    #[test]
    fn two_fragments_standing_on_each_other_have_no_order() {
        // Two columns side by side, each fragment taking the bottom of one and the top of
        // the other.
        let part = plate_tower(2, 1, 2, 2);
        let graph = WeldGraph::new(&part);
        let at = |p: [i64; 3]| part.blocks().iter().position(|b| *b == p).unwrap();
        let crossed = vec![
            vec![at([0, 0, 0]), at([1, 0, 1])],
            vec![at([1, 0, 0]), at([0, 0, 1])],
        ];
        assert!(in_support_order(&graph, crossed).is_none());
        let reversed = vec![
            vec![at([1, 0, 1])],
            vec![at([0, 0, 0]), at([1, 0, 0]), at([0, 0, 1])],
        ];
        let ordered = in_support_order(&graph, reversed).expect("an order exists");
        assert_eq!(ordered[0].len(), 3, "the fragment below first");
    }

    #[test]
    fn a_wall_that_needs_several_paths_per_layer_is_as_many_weld_paths_or_none() {
        // A cross with arms 2 long and a block beside its centre, 6 high: four dead ends,
        // so two paths per layer at least.
        let cross = [
            [2, 2],
            [0, 2],
            [1, 2],
            [3, 2],
            [4, 2],
            [2, 0],
            [2, 1],
            [2, 3],
            [2, 4],
            [1, 1],
        ];
        let blocks: Vec<_> = (0..6)
            .flat_map(|z| cross.iter().map(move |&[x, y]| [x, y, z]))
            .collect();
        let part = Part::from_blocks("cross".into(), [6.0, 6.0, 2.5], [0.0; 3], 3, blocks).unwrap();
        let graph = WeldGraph::new(&part);
        let need = crate::layer_path_bound(&part, &graph)[0].1;
        assert!(need >= 2, "the test part needs several paths per layer");
        let plan = layered_plan(&part, &graph, need, Backend::Cadical, &unlimited())
            .expect("one weld path per piece of the first layer, all climbing");
        assert_eq!(plan.len(), need);
        assert!(layered_plan(&part, &graph, need - 1, Backend::Cadical, &unlimited()).is_none());
    }

    /// A welded path: every block once, each move to a block beside the one before.
    fn assert_path_through(part: &Part, path: &[usize]) {
        let mut seen = path.to_vec();
        seen.sort_unstable();
        assert_eq!(
            seen,
            (0..part.len()).collect::<Vec<_>>(),
            "every block once"
        );
        for w in path.windows(2) {
            let (a, b) = (part.block(w[0]), part.block(w[1]));
            let apart: i64 = (0..3).map(|i| (a[i] - b[i]).abs()).sum();
            assert_eq!(apart, 1, "{a:?} -> {b:?} is not a move to a neighbour");
        }
    }

    #[test]
    fn a_layer_of_whole_rows_has_its_serpentines_and_others_none() {
        let plate = plate_tower(5, 4, 1, 1);
        let serpentines = Layer::new(&plate, 0..plate.len()).serpentines();
        assert_eq!(serpentines.len(), 8, "two directions from four corners");
        for path in &serpentines {
            assert_path_through(&plate, path);
        }
        // A staircase: a row ends beside the next row's end only one way round, from each
        // side (its columns give the same two paths).
        let stairs: Vec<_> = [(0, 0..3), (1, 2..5)]
            .into_iter()
            .flat_map(|(y, xs)| xs.map(move |x| [x, y, 0]))
            .collect();
        let stairs = Part::from_blocks("s".into(), [6.0; 3], [0.0; 3], 1, stairs).unwrap();
        let serpentines = Layer::new(&stairs, 0..stairs.len()).serpentines();
        assert_eq!(serpentines.len(), 2, "{serpentines:?}");
        for path in &serpentines {
            assert_path_through(&stairs, path);
        }
        let ring: Vec<_> = (0..4)
            .flat_map(|y| (0..4).map(move |x| [x, y, 0]))
            .filter(|&[x, y, _]| x % 3 == 0 || y % 3 == 0)
            .collect();
        let ring = Part::from_blocks("ring".into(), [6.0; 3], [0.0; 3], 1, ring).unwrap();
        assert!(Layer::new(&ring, 0..ring.len()).serpentines().is_empty());
    }

    #[test]
    fn a_floor_is_a_serpentine_that_ends_under_the_wall() {
        // An open box: a 9 x 8 floor, then a ring on its rim. The floor's path must end
        // under the rim, where the ring can go on.
        let (w, d) = (9, 8);
        let mut blocks: Vec<_> = (0..d)
            .flat_map(|y| (0..w).map(move |x| [x, y, 0]))
            .collect();
        for z in 1..4 {
            blocks.extend(
                (0..d)
                    .flat_map(|y| (0..w).map(move |x| [x, y, z]))
                    .filter(|&[x, y, _]| x == 0 || y == 0 || x == w - 1 || y == d - 1),
            );
        }
        let part = Part::from_blocks("box".into(), [6.0, 6.0, 2.5], [0.0; 3], 1, blocks).unwrap();
        let graph = WeldGraph::new(&part);
        let plan = layered_plan(&part, &graph, 1, Backend::Cadical, &unlimited()).expect("a plan");
        let floor = (w * d) as usize;
        let layer = Layer::new(&part, 0..floor);
        assert!(
            layer.serpentines().contains(&plan[0][..floor].to_vec()),
            "the floor is welded as a serpentine"
        );
        let [x, y, _] = part.block(plan[0][floor - 1]);
        assert!(
            x == 0 || y == 0 || x == w - 1 || y == d - 1,
            "it ends under the rim"
        );
    }
}
