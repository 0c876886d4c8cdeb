//! Exhaustive branch and bound over trails, with a proven lower bound.
//!
//! The search tree branches on the next directed segment (continuing from the torch, or
//! after a deadheading move while the minimum count allows one). A child's field is
//! stepped from its parent's (shared-prefix simulation: every tree edge is simulated
//! once). A child is dropped when its lower bound reaches the best trail found.
//!
//! Lower bound of a child at step n with field u (deviation from ambient), R steps and
//! W weld steps left, from the exact split |x| = −x + 2·max(0, x) per node and step:
//! * cold part, linear and so exact up to the torch positions: Σ_j Σ_i (T* − T_i^j) =
//!   R·N·(T*−T_amb) − Σ_j 1ᵀGʲu − (heat the future welds add to the node sums); the last
//!   term is at most the W largest "heat sums" a single weld step can add with the steps
//!   left after it (precomputed by an adjoint recursion for every torch position), and at
//!   most the assignment bound: every remaining torch position is welded exactly once, in
//!   its own step, so the dual of the position-to-step assignment solved once at the root
//!   ([`crate::assignment`]) bounds it for every node (a torch at a wall crossing keeps
//!   more of its heat than one beside an outline: the first bound charges every step the
//!   best position, this one charges each position once).
//! * hot part, only when each step is monotone (A⁻¹ ≥ 0, see `fem`) and T* ≥ T_amb: every
//!   future field is at least the free decay of u plus, during the weld of each remaining
//!   segment, the heat of that segment and of the future welds just before it in its run;
//!   for T* ≥ T_amb overshoots of sums of non-negative parts add up, so 2·(overshoot of
//!   the free decay + Σ over remaining segments of their least overshoot after a walk of
//!   as many future predecessors as a trail must give them + the least overshoot of the
//!   arc-off steps after the runs still to end) is a lower bound.
//!
//! Symmetries of the layer and mesh prune children that are not the smallest of their
//! orbit under the stabilizer of the prefix (sound: some image of every trail passes).

use std::time::{Duration, Instant};

use serde::Serialize;

use super::assignment::max_assignment_dual;
use super::improve::improve;
use super::model::{trails_needed, Model, Move, Trail};
use super::symmetry::symmetries;

/// Search settings.
#[derive(Debug, Clone)]
pub struct SearchOptions {
    /// Stop after this long, once a first trail is known, and return the best trail with
    /// its proven gap.
    pub time_limit: Option<Duration>,
    /// Stop after this long even without a trail (then the result has none: see
    /// [`SearchResult::found`]). The first trail of a layer of hundreds of segments takes
    /// minutes; `waam layer plan --time-limit` sets both limits, a part's layers (which
    /// each need a trail) only `time_limit`.
    pub give_up: Option<Duration>,
    /// Prune symmetric trails.
    pub symmetry: bool,
    /// Free-decay steps used for the hot part of the bound (more: tighter, slower).
    pub free_decay_steps: usize,
    /// Prune by the lower bound (off: plain enumeration of every trail, for checking).
    pub bound: bool,
    /// Layer nodes the trail may not start at (a part's layer below started there).
    pub forbidden_starts: Vec<usize>,
    /// Deadheading moves the trail may not make, as node pairs in either direction (a
    /// part's layer below deadheaded between them).
    pub forbidden_deadheads: Vec<[usize; 2]>,
    /// Refuse a layer whose search needs more memory than this, MB, by
    /// [`estimated_memory_mb`] ([`check_size`]; the caller checks before searching).
    pub max_memory_mb: u64,
}

/// The default of [`SearchOptions::max_memory_mb`].
pub const DEFAULT_MAX_MEMORY_MB: u64 = 1024;

/// What a search of `model` holds at least, MB: the bound's free-decay sums (a field per
/// time step) and the root's children (a field each, up to four per segment). A layer of
/// 1,000 segments (20,000 mesh nodes, 8,900 steps) needs about 2 GB of them.
pub fn estimated_memory_mb(model: &Model) -> u64 {
    let n = model.heat.len() as u64;
    let fields = (model.horizon as u64 + 1) + 4 * model.layer.segments.len() as u64;
    fields.saturating_mul(n).saturating_mul(8) >> 20
}

/// A layer too large to search within the memory limit.
#[derive(Debug, Clone, thiserror::Error)]
#[error(
    "layer {name}: searching it needs about {estimate_mb} MB ({nodes} mesh nodes x {steps} time \
     steps, {segments} segments), more than max_memory_mb = {limit_mb} (raise it with \
     --max-memory-mb)"
)]
pub struct TooLarge {
    pub name: String,
    pub nodes: usize,
    pub steps: usize,
    pub segments: usize,
    pub estimate_mb: u64,
    pub limit_mb: u64,
}

/// Refuses a layer whose search would need more than `options.max_memory_mb`.
pub fn check_size(model: &Model, options: &SearchOptions) -> Result<(), TooLarge> {
    let estimate_mb = estimated_memory_mb(model);
    if estimate_mb > options.max_memory_mb {
        return Err(TooLarge {
            name: model.layer.name.clone(),
            nodes: model.heat.len(),
            steps: model.horizon,
            segments: model.layer.segments.len(),
            estimate_mb,
            limit_mb: options.max_memory_mb,
        });
    }
    Ok(())
}

impl SearchOptions {
    /// True when the options forbid no start and no deadheading move.
    pub fn unconstrained(&self) -> bool {
        self.forbidden_starts.is_empty() && self.forbidden_deadheads.is_empty()
    }

    /// Whether a deadheading move between nodes a and b (either way) is forbidden.
    pub fn forbids_deadhead(&self, a: usize, b: usize) -> bool {
        self.forbidden_deadheads
            .iter()
            .any(|&[x, y]| (x == a && y == b) || (x == b && y == a))
    }

    /// Whether a trail keeps the forbidden starts and deadheading moves.
    pub fn allows(&self, model: &Model, trail: &Trail) -> bool {
        let mut at: Option<usize> = None;
        for m in &trail.moves {
            let (from, to) = model.ends(m);
            match at {
                None if self.forbidden_starts.contains(&from) => return false,
                Some(prev) if m.deadhead_before && self.forbids_deadhead(prev, from) => {
                    return false
                }
                _ => {}
            }
            at = Some(to);
        }
        true
    }
}

impl Default for SearchOptions {
    fn default() -> Self {
        SearchOptions {
            time_limit: None,
            give_up: None,
            symmetry: true,
            free_decay_steps: 10,
            bound: true,
            forbidden_starts: Vec::new(),
            forbidden_deadheads: Vec::new(),
            max_memory_mb: DEFAULT_MAX_MEMORY_MB,
        }
    }
}

/// The answer of a search.
#[derive(Debug, Clone, Serialize)]
pub struct SearchResult {
    #[serde(skip)]
    pub trail: Trail,
    /// Objective of the trail (K·steps).
    pub objective: f64,
    /// Proven lower bound on the optimum.
    pub lower_bound: f64,
    pub proven_optimal: bool,
    /// objective − lower_bound (0 when proven optimal).
    pub gap: f64,
    /// gap / objective.
    pub relative_gap: f64,
    /// Search nodes evaluated (each a simulated segment).
    pub nodes_explored: u64,
    /// Complete trails reached.
    pub leaves: u64,
    pub seconds: f64,
    /// Size of the symmetry group used.
    pub symmetries: usize,
    /// Whether the hot part of the bound was usable (monotone steps, T* ≥ T_amb).
    pub hot_bound: bool,
    /// Lower bound at the root.
    pub root_bound: f64,
}

/// Precomputed pieces of the lower bound.
struct Bound {
    n: usize,
    /// free_sum[R] = Σ_{j=1..R} (Gᵀ)ʲ 1, flattened (R = 0..=H).
    free_sum: Vec<f64>,
    /// heat_prefix[m] = Σ_{k<m} g[k], g[m] = largest node-sum heat one weld step adds
    /// over the m+1 steps from it on; used for the W largest of g[0..R).
    gains: Vec<f64>,
    gains_sorted_by_m: bool,
    gains_prefix: Vec<f64>,
    /// Dual of assigning every torch position to its own weld slot (see
    /// [`Bound::max_heat`]): per segment, the sum of its positions' row values; per slot
    /// m, prefix sums of the column values made non-decreasing in m.
    segment_heat: Vec<f64>,
    slot_heat_prefix: Vec<f64>,
    /// history[j][d]: least overshoot while welding directed segment d (index
    /// 2 s + reversed) from cold right after j other segments welded in one run (any walk
    /// of j distinct segments ending where d starts); level j falls back to level j − 1
    /// where no such walk exists.
    history: Vec<Vec<f64>>,
    /// tail[d]: least overshoot over the `tail_steps` arc-off steps right after welding
    /// directed segment d from cold (a run end before deadheading or the final cooling).
    tail: Vec<f64>,
    /// The fewest arc-off steps of a deadheading move (between two distinct nodes).
    tail_steps: usize,
    /// The longest deadheading move (steps), as in the horizon: the slack for cooling after
    /// the last weld is what the horizon leaves when every move left takes this long.
    longest_transit: usize,
    hot: bool,
    /// Free-decay steps used for the hot part.
    decay_steps: usize,
}

impl Bound {
    /// `None` when `deadline` passed first (a layer of 1,000 segments takes minutes here).
    fn new(model: &Model, decay_steps: usize, deadline: Option<Instant>) -> Option<Bound> {
        let late = || deadline.is_some_and(|d| Instant::now() >= d);
        let n = model.heat.len();
        let h = model.horizon;
        let mut a = vec![1.0; n];
        let mut free_sum = vec![0.0; (h + 1) * n];
        let mut gains = vec![0.0f64; h];
        let positions = model.positions.len();
        let mut cum = vec![0.0; positions];
        // gain_at[q * h + m]: node-sum heat a weld step at position q adds over the m + 1
        // steps from it on.
        let mut gain_at = vec![0.0; positions * h];
        for k in 0..h {
            if late() {
                return None;
            }
            // c_k = A⁻¹ a_k; node-sum response at lag k of a weld at q is dt c_kᵀ F_q.
            let mut c = a.clone();
            model.heat.solve(&mut c);
            let mut best = 0.0f64;
            for (q, load) in model.loads.iter().enumerate() {
                let s: f64 = load.iter().map(|&(i, f)| c[i] * f).sum::<f64>() * model.heat.dt;
                cum[q] += s;
                gain_at[q * h + k] = cum[q];
                best = best.max(cum[q]);
            }
            gains[k] = best;
            for (ai, (ci, m)) in a.iter_mut().zip(c.iter().zip(&model.heat.lumped_mass)) {
                *ai = ci * m;
            }
            // a is now a_{k+1}; free_sum[k+1] = free_sum[k] + a_{k+1}.
            let (lo, hi) = free_sum.split_at_mut((k + 1) * n);
            let prev = &lo[k * n..];
            for ((dst, p), ai) in hi[..n].iter_mut().zip(prev).zip(&a) {
                *dst = p + ai;
            }
        }
        let gains_sorted_by_m = gains.windows(2).all(|w| w[0] <= w[1]);
        let mut gains_prefix = vec![0.0; h + 1];
        for m in 0..h {
            gains_prefix[m + 1] = gains_prefix[m] + gains[m];
        }
        let (segment_heat, slot_heat_prefix) = assignment_heat(model, &gain_at, h, late)?;
        let hot = model.heat.monotone && model.target >= 0.0 && model.initial >= 0.0;
        let tail_steps = shortest_transit(model);
        let tail = if hot {
            tail_overshoots(model, tail_steps, late)?
        } else {
            vec![0.0; 2 * model.layer.segments.len()]
        };
        let history = if hot {
            history_overshoots(model, HISTORY_DEPTH, deadline)?
        } else {
            vec![vec![0.0; 2 * model.layer.segments.len()]]
        };
        Some(Bound {
            n,
            free_sum,
            gains,
            gains_sorted_by_m,
            gains_prefix,
            segment_heat,
            slot_heat_prefix,
            history,
            tail,
            tail_steps,
            longest_transit: model.longest_transit,
            hot,
            decay_steps,
        })
    }

    /// Largest total node-sum heat the W weld steps of the `left` segments can add within
    /// the last R steps: the lesser of two upper bounds.
    /// * Any W slots, each with the best torch position for it: the W largest g[m].
    /// * Each position welded once, in its own slot: by the assignment dual, position q in
    ///   slot m adds at most row[q] + col[m], so the total is at most Σ row over the
    ///   positions left plus the W largest col[m] of the slots left (col non-decreasing
    ///   in m: the last W of them).
    fn max_heat(&self, r: usize, w: usize, left: &[usize]) -> f64 {
        let w = w.min(r);
        let any_position = if self.gains_sorted_by_m {
            self.gains_prefix[r] - self.gains_prefix[r - w]
        } else {
            let mut g = self.gains[..r].to_vec();
            g.sort_by(|a, b| b.total_cmp(a));
            g[..w].iter().sum()
        };
        let each_once = left.iter().map(|&s| self.segment_heat[s]).sum::<f64>()
            + self.slot_heat_prefix[r]
            - self.slot_heat_prefix[r - w];
        any_position.min(each_once)
    }

    /// Lower bound on the cost still to come from field u with what is left to do.
    fn remaining(&self, model: &Model, u: &[f64], rest: &Rest, scratch: &mut Vec<f64>) -> f64 {
        let (r, w, left) = (rest.steps, rest.weld_steps, rest.segments);
        if r == 0 {
            return 0.0;
        }
        let fs = &self.free_sum[r * self.n..(r + 1) * self.n];
        let free: f64 = fs.iter().zip(u).map(|(a, b)| a * b).sum();
        let cold = r as f64 * self.n as f64 * model.target - free - self.max_heat(r, w, left);
        if !self.hot {
            return cold;
        }
        // In a trail, at most `run_starts` remaining segments begin a run and at most
        // `run_starts + 1` are the j-th of theirs (j ≥ 1, the current run may add one), so
        // at most A_j = (j + 1)·run_starts + j have fewer than j + 1 predecessors: charge
        // everything the deepest level and give back the A_{j−1} largest level differences.
        let levels = self.history.len();
        let best = |j: usize, s: usize| self.history[j][2 * s].min(self.history[j][2 * s + 1]);
        let mut hot: f64 = left.iter().map(|&s| best(levels - 1, s)).sum();
        let mut diffs = Vec::with_capacity(left.len());
        for j in 1..levels {
            let allowed = j * rest.run_starts + (j - 1);
            if allowed == 0 {
                continue;
            }
            diffs.clear();
            diffs.extend(left.iter().map(|&s| best(j, s) - best(j - 1, s)));
            if allowed < diffs.len() {
                diffs.select_nth_unstable_by(allowed, |a, b| b.total_cmp(a));
            }
            hot -= diffs.iter().take(allowed).sum::<f64>();
        }
        hot += self.run_end_tails(rest);
        scratch.clear();
        scratch.extend_from_slice(u);
        for _ in 0..r.min(self.decay_steps) {
            model.heat.step(scratch, &[]);
            let o = overshoot(scratch, model.target);
            if o <= 0.0 {
                break;
            }
            hot += o;
        }
        cold + 2.0 * hot
    }
}

impl SearchResult {
    /// [`SearchOptions::give_up`] came before a first trail: no trail, nothing proven.
    fn no_trail(start: Instant) -> SearchResult {
        SearchResult {
            trail: Trail::default(),
            objective: f64::INFINITY,
            lower_bound: f64::NEG_INFINITY,
            proven_optimal: false,
            gap: f64::INFINITY,
            relative_gap: f64::INFINITY,
            nodes_explored: 0,
            leaves: 0,
            seconds: start.elapsed().as_secs_f64(),
            symmetries: 1,
            hot_bound: false,
            root_bound: f64::NEG_INFINITY,
        }
    }

    /// Whether the search found a trail (false only when `give_up` came first).
    pub fn found(&self) -> bool {
        !self.trail.moves.is_empty()
    }
}

/// The assignment dual of the heat the welds add (see [`Bound::max_heat`]): per segment the
/// sum of its positions' row values, and prefix sums of the slot values made
/// non-decreasing (raising a slot value keeps every gain covered). `None` once `late` says
/// so.
fn assignment_heat(
    model: &Model,
    gain_at: &[f64],
    h: usize,
    late: impl Fn() -> bool,
) -> Option<(Vec<f64>, Vec<f64>)> {
    let positions = model.positions.len();
    if positions > h {
        // Cannot happen (the horizon holds every weld step); no usable dual then.
        return Some((vec![f64::INFINITY; model.steps.len()], vec![0.0; h + 1]));
    }
    let dual = max_assignment_dual(gain_at, positions, h, late)?;
    let mut col = dual.col;
    for m in 1..h {
        col[m] = col[m].max(col[m - 1]);
    }
    // Rows again against the raised columns: the least values that still cover.
    let row: Vec<f64> = (0..positions)
        .map(|q| {
            (0..h)
                .map(|m| gain_at[q * h + m] - col[m])
                .fold(f64::NEG_INFINITY, f64::max)
        })
        .collect();
    let segment_heat = (0..model.steps.len())
        .map(|s| {
            row[model.offset[s]..model.offset[s] + model.steps[s]]
                .iter()
                .sum()
        })
        .collect();
    let mut prefix = vec![0.0; h + 1];
    for m in 0..h {
        prefix[m + 1] = prefix[m] + col[m];
    }
    Some((segment_heat, prefix))
}

impl Bound {
    /// Overshoot of the arc-off steps that follow the ends of future runs: every deadheading
    /// move left follows a run end (a future segment's weld, except perhaps the first when
    /// the current run may end where the torch is) and takes at least `tail_steps` steps;
    /// the last weld is followed by cooling when the horizon leaves room for it whatever
    /// the deadheading moves take. Those run ends are distinct remaining segments, so the
    /// sum of that many smallest tails bounds their overshoot (times apart from the weld
    /// steps, heat pieces apart from the free decay: the overshoots add up).
    fn run_end_tails(&self, rest: &Rest) -> f64 {
        let left = rest.segments;
        let mut count = if rest.run_open {
            rest.deadheads.saturating_sub(1)
        } else {
            rest.deadheads
        };
        let future_transit = rest.deadheads * self.longest_transit;
        let slack = rest.steps.saturating_sub(rest.weld_steps + future_transit);
        if slack >= self.tail_steps && self.tail_steps > 0 {
            count += 1;
        }
        let count = count.min(left.len());
        if count == 0 {
            return 0.0;
        }
        let mut tails: Vec<f64> = left
            .iter()
            .map(|&s| self.tail[2 * s].min(self.tail[2 * s + 1]))
            .collect();
        if count < tails.len() {
            tails.select_nth_unstable_by(count, |a, b| a.total_cmp(b));
        }
        tails[..count].iter().sum()
    }
}

/// The fewest steps of a deadheading move between two distinct layer nodes (a move back
/// to the same node would save a deadheading move, so a minimum trail never makes one).
fn shortest_transit(model: &Model) -> usize {
    let n = model.layer.nodes.len();
    (0..n)
        .flat_map(|a| (a + 1..n).map(move |b| (a, b)))
        .map(|(a, b)| model.layer.transit_steps(a, b))
        .min()
        .unwrap_or(0)
}

/// tail[d] for every directed segment (see [`Bound`]); `None` once `late` says so (a
/// layer of 420 segments simulates 840 welds here).
fn tail_overshoots(model: &Model, steps: usize, late: impl Fn() -> bool) -> Option<Vec<f64>> {
    (0..2 * model.layer.segments.len())
        .map(|d| {
            if late() {
                return None;
            }
            let mv = Move::directed(d);
            let mut u = vec![0.0; model.heat.len()];
            for k in 0..model.steps[mv.segment] {
                model
                    .heat
                    .step(&mut u, &model.loads[model.position(&mv, k)]);
            }
            let mut o = 0.0;
            for _ in 0..steps {
                model.heat.step(&mut u, &[]);
                o += overshoot(&u, model.target);
            }
            Some(o)
        })
        .collect()
}

/// Predecessors considered in the hot part of the bound.
const HISTORY_DEPTH: usize = 3;

/// history[j][d] for j = 0..=depth (see [`Bound`]); `None` when `deadline` passed first.
///
/// The walks are visited depth first in weld order, so each is simulated once, from its
/// prefix's field: a segment's overshoot after j predecessors is a candidate for
/// history[j] of that segment (the same fields as welding every walk from cold).
fn history_overshoots(
    model: &Model,
    depth: usize,
    deadline: Option<Instant>,
) -> Option<Vec<Vec<f64>>> {
    let dirs = 2 * model.layer.segments.len();
    // Directed segments starting at each node.
    let mut starting: Vec<Vec<usize>> = vec![Vec::new(); model.layer.nodes.len()];
    for d in 0..dirs {
        starting[model.ends(&Move::directed(d)).0].push(d);
    }
    let mut walks = Walks {
        model,
        starting,
        depth,
        deadline,
        history: vec![vec![f64::INFINITY; dirs]; depth + 1],
        walk: Vec::new(),
    };
    let cold = vec![0.0; model.heat.len()];
    for d in 0..dirs {
        walks.extend(d, &cold)?;
    }
    let mut history = walks.history;
    // A segment with no walk of j predecessors keeps its value for fewer.
    for level in 1..=depth {
        let (shorter, rest) = history.split_at_mut(level);
        for (value, &fewer) in rest[0].iter_mut().zip(&shorter[level - 1]) {
            if value.is_infinite() {
                *value = fewer;
            }
        }
    }
    Some(history)
}

/// The depth-first walk of [`history_overshoots`].
struct Walks<'a> {
    model: &'a Model,
    starting: Vec<Vec<usize>>,
    depth: usize,
    deadline: Option<Instant>,
    history: Vec<Vec<f64>>,
    /// The walk so far, in weld order.
    walk: Vec<usize>,
}

impl Walks<'_> {
    /// Welds directed segment `d` after the walk (whose field is `u`), records its
    /// overshoot, and goes on to every segment that can follow it (`None`: too late).
    fn extend(&mut self, d: usize, u: &[f64]) -> Option<()> {
        if self.deadline.is_some_and(|t| Instant::now() >= t) {
            return None;
        }
        let model = self.model;
        let mv = Move::directed(d);
        let mut v = u.to_vec();
        let mut o = 0.0;
        for k in 0..model.steps[mv.segment] {
            model
                .heat
                .step(&mut v, &model.loads[model.position(&mv, k)]);
            o += overshoot(&v, model.target);
        }
        let level = self.walk.len();
        self.history[level][d] = self.history[level][d].min(o);
        if level == self.depth {
            return Some(());
        }
        self.walk.push(d);
        let end = model.ends(&mv).1;
        for i in 0..self.starting[end].len() {
            let p = self.starting[end][i];
            if !self.walk.iter().any(|&q| q / 2 == p / 2) {
                self.extend(p, &v)?;
            }
        }
        self.walk.pop();
        Some(())
    }
}

/// What is left to do after a search node.
struct Rest<'a> {
    /// Time steps to the horizon.
    steps: usize,
    /// Of them, weld steps.
    weld_steps: usize,
    /// Segments not yet welded.
    segments: &'a [usize],
    /// How many of them may have no *future* predecessor in their run: one per
    /// deadheading move left, plus the first (which continues the current run, whose
    /// past is already in the field, or starts the trail).
    run_starts: usize,
    /// Deadheading moves left (exactly: every trail has the minimum count).
    deadheads: usize,
    /// A past segment ends the current run (false only before the first weld): the next
    /// deadheading move may follow it rather than a future segment.
    run_open: bool,
}

fn overshoot(u: &[f64], target: f64) -> f64 {
    u.iter().map(|&x| (x - target).max(0.0)).sum()
}

struct Child {
    mv: Move,
    u: Vec<f64>,
    cost: f64,
    steps_done: usize,
    lb: f64,
}

struct Frame {
    children: Vec<Child>,
    next: usize,
    /// Group elements that fix the prefix up to this frame's parent.
    stabilizer: Vec<usize>,
    /// The parent's lower bound: valid for every child too.
    parent_lb: f64,
}

/// Finds the trail of least objective (or the best within the time limit, with its gap).
pub fn search(model: &Model, options: &SearchOptions) -> SearchResult {
    let start = Instant::now();
    // Giving up also acts before the first trail: then there is no trail.
    let deadline = options.give_up.and_then(|t| start.checked_add(t));
    let late = || deadline.is_some_and(|d| Instant::now() >= d);
    let Some(bound) = Bound::new(model, options.free_decay_steps, deadline) else {
        return SearchResult::no_trail(start);
    };
    let stopped = std::cell::Cell::new(false);
    // Forbidden starts and deadheading moves are not symmetric: no symmetry pruning then.
    let group = if options.symmetry && options.unconstrained() {
        symmetries(model)
    } else {
        Vec::new()
    };
    let segs = model.layer.segments.len();
    let total_weld: usize = model.steps.iter().sum();
    let mut used = vec![false; segs];
    let mut path: Vec<Move> = Vec::new();
    let mut best: Option<(f64, Trail)> = None;
    let mut nodes: u64 = 0;
    let mut leaves: u64 = 0;
    let mut scratch = Vec::new();
    let mut timed_out = false;

    // State of the node being expanded: its field and cost; root = initial field.
    let root_u = model.initial_field.clone();
    let all: Vec<usize> = (0..segs).collect();
    let root_bound = bound.remaining(
        model,
        &root_u,
        &Rest {
            steps: model.horizon,
            weld_steps: total_weld,
            segments: &all,
            run_starts: model.deadheads + 1,
            deadheads: model.deadheads,
            run_open: false,
        },
        &mut scratch,
    );
    let mut expand = |u: &[f64],
                      cost: f64,
                      steps_done: usize,
                      at: Option<usize>,
                      deadheads_left: usize,
                      used: &[bool],
                      stabilizer: &[usize],
                      incumbent: f64,
                      nodes: &mut u64,
                      leaves: &mut u64,
                      best: &mut Option<(f64, Trail)>,
                      path: &[Move]|
     -> Vec<Child> {
        let mut children = Vec::new();
        let left: Vec<usize> = (0..segs).filter(|&s| !used[s]).collect();
        let weld_done: usize = (0..segs).filter(|&s| used[s]).map(|s| model.steps[s]).sum();
        let mut incumbent = incumbent;
        for &s in &left {
            if best.is_none() && late() {
                stopped.set(true);
                break;
            }
            for reversed in [false, true] {
                let d = 2 * s + reversed as usize;
                if stabilizer.iter().any(|&g| group[g][d] < d) {
                    continue;
                }
                let probe = Move {
                    segment: s,
                    reversed,
                    deadhead_before: false,
                };
                let (from, to) = model.ends(&probe);
                let rest: Vec<usize> = left.iter().copied().filter(|&t| t != s).collect();
                for deadhead in [false, true] {
                    let (needs_deadhead, dl) = match at {
                        None if deadhead => continue,
                        None if options.forbidden_starts.contains(&from) => continue,
                        None => (false, deadheads_left),
                        Some(v) if deadhead && options.forbids_deadhead(v, from) => continue,
                        Some(v) if !deadhead && v != from => continue,
                        Some(_) if deadhead && deadheads_left == 0 => continue,
                        Some(_) if deadhead => (true, deadheads_left - 1),
                        Some(_) => (false, deadheads_left),
                    };
                    if trails_needed(&model.layer, &rest, Some(to)) > dl {
                        continue;
                    }
                    let mv = Move {
                        segment: s,
                        reversed,
                        deadhead_before: needs_deadhead,
                    };
                    let mut v = u.to_vec();
                    let mut c = cost;
                    let mut steps = steps_done;
                    if let (true, Some(prev)) = (needs_deadhead, at) {
                        for _ in 0..model.layer.transit_steps(prev, from) {
                            model.heat.step(&mut v, &[]);
                            c += model.deviation(&v);
                            steps += 1;
                        }
                    }
                    for k in 0..model.steps[s] {
                        model
                            .heat
                            .step(&mut v, &model.loads[model.position(&mv, k)]);
                        c += model.deviation(&v);
                        steps += 1;
                    }
                    *nodes += 1;
                    if rest.is_empty() {
                        // A complete trail: cool to the horizon for its exact objective.
                        while steps < model.horizon {
                            model.heat.step(&mut v, &[]);
                            c += model.deviation(&v);
                            steps += 1;
                        }
                        *leaves += 1;
                        if c < incumbent {
                            incumbent = c;
                            let mut moves = path.to_vec();
                            moves.push(mv);
                            *best = Some((c, Trail { moves }));
                        }
                        continue;
                    }
                    let w = total_weld - weld_done - model.steps[s];
                    let lb = if !options.bound {
                        f64::NEG_INFINITY
                    } else {
                        c + bound.remaining(
                            model,
                            &v,
                            &Rest {
                                steps: model.horizon - steps,
                                weld_steps: w,
                                segments: &rest,
                                run_starts: dl + 1,
                                deadheads: dl,
                                run_open: true,
                            },
                            &mut scratch,
                        )
                    };
                    if lb < incumbent {
                        children.push(Child {
                            mv,
                            u: v,
                            cost: c,
                            steps_done: steps,
                            lb,
                        });
                    }
                }
            }
        }
        children.sort_by(|a, b| a.lb.total_cmp(&b.lb));
        children
    };

    let identity: Vec<usize> = (0..group.len()).collect();
    let root_children = expand(
        &root_u,
        0.0,
        0,
        None,
        model.deadheads,
        &used,
        &identity,
        f64::INFINITY,
        &mut nodes,
        &mut leaves,
        &mut best,
        &path,
    );
    if stopped.get() {
        return SearchResult::no_trail(start);
    }
    let mut stack = vec![Frame {
        children: root_children,
        next: 0,
        stabilizer: identity,
        parent_lb: root_bound,
    }];
    let mut deadheads_used_stack: Vec<usize> = Vec::new();
    let mut improved = false;
    while let Some(frame) = stack.last_mut() {
        // Under a time limit, polish the first trail by local search for a quarter of it:
        // a better incumbent prunes more and shrinks the gap (it proves nothing itself).
        if let (Some(limit), false, Some((value, trail))) =
            (options.time_limit, improved, best.clone())
        {
            improved = true;
            let (t, v) = improve(model, &trail, value, start + limit / 4);
            tracing::debug!(
                "local search: {value:.6e} -> {v:.6e} at {:.1} s",
                start.elapsed().as_secs_f64()
            );
            if v < value && options.allows(model, &t) {
                best = Some((v, t));
            }
            continue;
        }
        // The time limit applies once a first complete trail is known.
        if let (Some(limit), true) = (options.time_limit, best.is_some()) {
            if start.elapsed() >= limit {
                timed_out = true;
                break;
            }
        }
        let incumbent = best.as_ref().map_or(f64::INFINITY, |b| b.0);
        if frame.next >= frame.children.len() || frame.children[frame.next].lb >= incumbent {
            // Exhausted (children are sorted by bound, so the rest cannot win either).
            frame.next = frame.children.len();
            stack.pop();
            if let Some(mv) = path.pop() {
                used[mv.segment] = false;
                deadheads_used_stack.pop();
            }
            continue;
        }
        let idx = frame.next;
        frame.next += 1;
        let child = &frame.children[idx];
        let mv = child.mv;
        let d = 2 * mv.segment + mv.reversed as usize;
        let stabilizer: Vec<usize> = frame
            .stabilizer
            .iter()
            .copied()
            .filter(|&g| group[g][d] == d)
            .collect();
        let (u, cost, steps_done, child_lb) =
            (child.u.clone(), child.cost, child.steps_done, child.lb);
        used[mv.segment] = true;
        path.push(mv);
        let used_dh =
            deadheads_used_stack.last().copied().unwrap_or(0) + mv.deadhead_before as usize;
        deadheads_used_stack.push(used_dh);
        let at = model.ends(&mv).1;
        let children = expand(
            &u,
            cost,
            steps_done,
            Some(at),
            model.deadheads - used_dh,
            &used,
            &stabilizer,
            incumbent,
            &mut nodes,
            &mut leaves,
            &mut best,
            &path,
        );
        if stopped.get() {
            return SearchResult::no_trail(start);
        }
        stack.push(Frame {
            children,
            next: 0,
            stabilizer,
            parent_lb: child_lb,
        });
    }
    let (objective, trail) = best.unwrap_or((f64::INFINITY, Trail::default()));
    let mut lower = objective;
    if timed_out {
        // Unexplored children (sorted, so the next is the least) bound what is left.
        // Every ancestor's bound holds for the whole subtree below it too.
        let mut inherited = f64::NEG_INFINITY;
        for frame in &stack {
            inherited = inherited.max(frame.parent_lb);
            if let Some(c) = frame.children.get(frame.next) {
                lower = lower.min(c.lb.max(inherited));
            }
        }
    }
    let gap = (objective - lower).max(0.0);
    SearchResult {
        trail,
        objective,
        lower_bound: lower,
        proven_optimal: !timed_out || gap == 0.0,
        gap,
        relative_gap: if objective > 0.0 {
            gap / objective
        } else {
            0.0
        },
        nodes_explored: nodes,
        leaves,
        seconds: start.elapsed().as_secs_f64(),
        symmetries: group.len().max(1),
        hot_bound: bound.hot,
        root_bound,
    }
}

/// Checks the lower bound against brute force on a small layer: for every prefix of every
/// trail, the bound must not exceed the best objective of the prefix's completions.
/// Returns the number of prefixes checked, or the first violation. For tests; the number
/// of trails grows exponentially with the segments.
pub fn check_bound(model: &Model) -> Result<usize, crate::ModelError> {
    struct Walk<'a> {
        model: &'a Model,
        bound: Bound,
        used: Vec<bool>,
        checked: usize,
        scratch: Vec<f64>,
    }
    impl Walk<'_> {
        /// Best objective over completions of the state; checks every child's bound.
        fn best(
            &mut self,
            u: &[f64],
            cost: f64,
            steps: usize,
            at: Option<usize>,
            deadheads_left: usize,
        ) -> Result<f64, crate::ModelError> {
            let model = self.model;
            let segs = model.layer.segments.len();
            let left: Vec<usize> = (0..segs).filter(|&s| !self.used[s]).collect();
            let mut best = f64::INFINITY;
            for &s in &left {
                for reversed in [false, true] {
                    for deadhead in [false, true] {
                        let probe = Move {
                            segment: s,
                            reversed,
                            deadhead_before: deadhead,
                        };
                        let (from, to) = model.ends(&probe);
                        let dl = match at {
                            None if deadhead => continue,
                            None => deadheads_left,
                            Some(v) if !deadhead && v != from => continue,
                            Some(_) if deadhead && deadheads_left == 0 => continue,
                            Some(_) => deadheads_left - deadhead as usize,
                        };
                        let rest: Vec<usize> = left.iter().copied().filter(|&t| t != s).collect();
                        if trails_needed(&model.layer, &rest, Some(to)) > dl {
                            continue;
                        }
                        let mut v = u.to_vec();
                        let (mut c, mut n) = (cost, steps);
                        if let (true, Some(prev)) = (deadhead, at) {
                            for _ in 0..model.layer.transit_steps(prev, from) {
                                model.heat.step(&mut v, &[]);
                                c += model.deviation(&v);
                                n += 1;
                            }
                        }
                        for k in 0..model.steps[s] {
                            model
                                .heat
                                .step(&mut v, &model.loads[model.position(&probe, k)]);
                            c += model.deviation(&v);
                            n += 1;
                        }
                        let weld: usize = rest.iter().map(|&t| model.steps[t]).sum();
                        let lb = c + self.bound.remaining(
                            model,
                            &v,
                            &Rest {
                                steps: model.horizon - n,
                                weld_steps: weld,
                                segments: &rest,
                                run_starts: dl + 1,
                                deadheads: dl,
                                run_open: true,
                            },
                            &mut self.scratch,
                        );
                        let exact = if rest.is_empty() {
                            while n < model.horizon {
                                model.heat.step(&mut v, &[]);
                                c += model.deviation(&v);
                                n += 1;
                            }
                            c
                        } else {
                            self.used[s] = true;
                            let b = self.best(&v, c, n, Some(to), dl);
                            self.used[s] = false;
                            b?
                        };
                        self.checked += 1;
                        if lb > exact * (1.0 + 1e-12) + 1e-9 {
                            return Err(crate::ModelError(format!(
                                "bound {lb} above the best completion {exact} after welding {} at step {n}",
                                model.layer.segment_name(s)
                            )));
                        }
                        best = best.min(exact);
                    }
                }
            }
            Ok(best)
        }
    }
    let mut walk = Walk {
        model,
        bound: Bound::new(model, SearchOptions::default().free_decay_steps, None)
            .expect("no deadline"),
        used: vec![false; model.layer.segments.len()],
        checked: 0,
        scratch: Vec::new(),
    };
    let u = model.initial_field.clone();
    walk.best(&u, 0.0, 0, None, model.deadheads)?;
    Ok(walk.checked)
}
