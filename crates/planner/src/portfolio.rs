//! A portfolio of warm starts: when the layer-by-layer plan breaks a t8/5 window, the same
//! construction is set off from other places, each variant simulated, and the best
//! feasible one becomes the warm start.
//!
//! Why the start: a weld path that walks each layer back over the one below leaves a seam
//! where a layer starts, and a block's distance from that seam decides how soon the block
//! above it is deposited and reheats it. On a tall tube that moves a windowed block's
//! t8/5 by hundreds of seconds (measured in the README), while the builder's other
//! choices stay valid. The variants start at places spread evenly along the base plan's
//! first layer (every path's piece there; halves, then quarters, eighths, ...), setting
//! off both ways, at places where the first layer can be covered so. They are
//! judged in that order, several at once on the run's threads, and the first feasible one
//! in the order wins: every variant before it is judged whole and those after it are
//! stopped or never built, so the answer does not depend on the number of threads or on
//! which finishes first, and a run does not judge variants it will not use (in a race the
//! portfolio has one thread: rounds of eight, the best margin of a round, made a run judge
//! up to seven more after a feasible one, a minute each at 10^5 blocks).
//!
//! Why the cover: on a layer that needs several paths (a T, two rings) a first move fixes
//! only where the first path starts, and on a branching layer no path can start inside a
//! branch, so those variants cannot be built at all. Which path takes a junction decides
//! which blocks climb together and so when each is reheated. When no start keeps every
//! window, the portfolio varies the first layer's cover: the base's, and each the weld
//! graph allows with a path end moved on to a neighbour (another branch takes the
//! junction) and, at a junction, on along each arm, each with every way round and every
//! order of its paths, judged in the same
//! way, the covers taking turns. A feasible variant's simulation after its last deposit
//! goes with it, so the search's verdict on it simulates only the cooldown.

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use waam_part::graph::WeldGraph;
use waam_part::Part;
use waam_thermal::{self as thermal, Snapshot, ThermalModel};

use crate::constructive::{self, Limits};
use crate::prefix_cache::deposits;
use crate::repair::Repaired;
use crate::sat::Backend;

/// Variants judged at once at most (each holds a simulation of the whole part).
const AT_ONCE: usize = 8;
/// Places along the first layer tried at most (each set off both ways; only places with a
/// start the layer can be covered from count): 32, on a ring a start every 3% of the way (on a generated 26 x 18 tube whose windows are those of a hidden plan, 16
/// places found no feasible variant and 32 did; see the README).
const MAX_STARTS: usize = 32;

/// What every variant is built and judged with.
pub struct Portfolio<'a> {
    pub part: &'a Part,
    pub graph: &'a WeldGraph,
    pub k: usize,
    pub backend: Backend,
    pub limits: &'a Limits,
    pub model: &'a ThermalModel,
    /// Threads judging variants (1 in a race: the other racers have the rest).
    pub workers: usize,
}

/// How a variant's first layer begins: its paths' first blocks (a first move: one path's
/// first two; a cover: every path whole), as [`constructive::layered_plan_from`] takes them.
type Variant = Vec<Vec<usize>>;

/// A variant built and simulated (`None` in a slot of [`Portfolio::judge_in_order`]: it
/// could not be built, it came after a feasible one, or the run stopped).
#[derive(Debug, Clone, PartialEq)]
struct Judged {
    plan: Vec<Vec<usize>>,
    /// Its margin, or `Err((blocks welded before a window breaks, the broken block))`.
    margin: Result<f64, (usize, usize)>,
    /// A feasible variant's simulation after its last deposit (see [`Repaired`]).
    end: Option<Snapshot>,
}

impl Judged {
    /// The variant as the portfolio hands it on.
    fn tried(self) -> Tried {
        match self.margin {
            Ok(_) => Ok(Repaired {
                plan: self.plan,
                end: self.end,
            }),
            Err((blocks, block)) => Err((self.plan, blocks, block)),
        }
    }
}

/// The prefixes that broke a window in the variants judged so far: a variant whose plan
/// begins with one breaks that window the same way (the simulation up to the break is the
/// same), so it is not simulated again. The prefix is the one the search learns a clause
/// from: the deposits up to the break, and when the window broke after a weld path ended
/// (in the transit), that the path ended there. Starts and covers meet in the same
/// prefixes: on a generated T-wall 4 of the 12 cover variants before the feasible one
/// began as a start or an earlier cover had (2 s of simulation each), and skipping them
/// brought the feasible one inside the portfolio's time.
#[derive(Default)]
struct Seen(Mutex<Vec<BrokenPrefix>>);

struct BrokenPrefix {
    deposits: Vec<(usize, bool)>,
    /// The weld path ended after the prefix (the next deposit begins one, or none comes).
    closed: bool,
    /// Blocks welded before the window broke, and the broken block.
    broken: (usize, usize),
}

impl Seen {
    /// Where `plan` breaks a window, if it begins with a prefix seen breaking one.
    fn broken(&self, plan: &[Vec<usize>]) -> Option<(usize, usize)> {
        let seq = deposits(plan);
        let seen = self.0.lock().expect("no worker panics");
        seen.iter()
            .find(|p| {
                seq.starts_with(&p.deposits)
                    && (!p.closed || seq.get(p.deposits.len()).is_none_or(|&(_, new)| new))
            })
            .map(|p| p.broken)
    }

    fn remember(&self, plan: &[Vec<usize>], v: &thermal::Violation) {
        let mut seq = deposits(plan);
        seq.truncate(v.prefix_len);
        let prefix = BrokenPrefix {
            deposits: seq,
            closed: v.phase != thermal::Phase::Deposit,
            broken: (v.prefix_len, v.block),
        };
        self.0.lock().expect("no worker panics").push(prefix);
    }
}

/// A plan the portfolio built and judged (the best raster variant, or varisat's
/// layer-by-layer plan): `Ok` when it keeps every window, else `Err((plan, blocks welded
/// before a window breaks, the broken block))`, for the repair.
pub type Tried = Result<Repaired, (Vec<Vec<usize>>, usize, usize)>;

impl Portfolio<'_> {
    /// A feasible variant of `base` (a layer-by-layer plan that breaks a window), the first
    /// in order; `None` when no variant keeps every window (or the run stopped first).
    pub fn varied_start(&self, base: &[Vec<usize>]) -> Option<Repaired> {
        let Portfolio { part, k, .. } = *self;
        let allows = constructive::first_layer_allows(part, k, self.backend, self.limits);
        // One small solve of the first layer per start: on a big floor seconds each, so
        // the log says what they cost (box s8015 at 10^4: 27 s, benchmarks.md).
        let filtering = std::time::Instant::now();
        let moves = first_moves(part, self.graph, base, |first| {
            allows.as_ref().is_some_and(|allows| allows(first))
        });
        tracing::debug!(
            "warm-start portfolio: {} start(s) the first layer can be covered from, found in {:.2} s{}",
            moves.len(),
            filtering.elapsed().as_secs_f64(),
            if self.limits.stopped() { " (stopped)" } else { "" }
        );
        let starts: Vec<Variant> = moves.iter().map(|&(a, b)| vec![vec![a, b]]).collect();
        let seen = Seen::default();
        if let Some(found) = self.first_feasible(&starts, "start", &seen) {
            return Some(found);
        }
        // No start keeps every window: other covers of the first layer (the solves of the
        // covers cost little beside the simulations).
        if self.limits.stopped() {
            return None;
        }
        let covers = cover_variants(self, base, &moves);
        tracing::debug!(
            "warm-start portfolio: {} variants of the first layer's cover",
            covers.len()
        );
        self.first_feasible(&covers, "cover", &seen)
    }

    /// The layer-by-layer plan built with this portfolio's backend, simulated: `Ok` when it
    /// keeps every window, else `Err((plan, blocks welded before a window breaks, the broken
    /// block))`; `None` when it is `base` (nothing new), is not built, or the run stopped.
    /// Built with the other backend it is another plan: varisat covers the layers otherwise
    /// than CaDiCaL.
    pub fn layered(&self, base: &[Vec<usize>]) -> Option<Tried> {
        let Portfolio { part, graph, k, .. } = *self;
        let plan = constructive::layered_plan(part, graph, k, self.backend, self.limits)
            .filter(|plan| plan != base)?;
        let judged = self.judge_plan(plan, "the layer-by-layer plan", self.limits, None)?;
        tracing::debug!(
            "warm-start portfolio: the layer-by-layer plan of {:?}: {}",
            self.backend,
            match &judged.margin {
                Ok(m) => format!("feasible, margin {m:.2} s"),
                Err((blocks, _)) => format!("breaks a window after {blocks} blocks"),
            }
        );
        Some(judged.tried())
    }

    /// The first layer welded as a raster ([`constructive::raster_covers`], as many paths
    /// as `base` starts there), each way and from each corner: the first feasible variant,
    /// else the one that keeps every window longest (on a tie the earlier); `None` when the
    /// first layer has no area (or no raster is built, or the run stopped).
    pub fn rasters(&self, base: &[Vec<usize>]) -> Option<Tried> {
        let own = first_layer_pieces(self.part, base);
        let covers = constructive::raster_covers(self.part, self.backend, self.limits, own.len());
        let variants: Vec<Variant> = covers.into_iter().filter(|c| *c != own).collect();
        if variants.is_empty() {
            return None;
        }
        let judged = self.judge_in_order(&variants, &Seen::default());
        let built = judged.iter().filter(|j| j.is_some()).count();
        // The first feasible, else furthest before a window breaks (max_by keeps the last
        // maximum: the judged ones are walked back, so a tie goes to the earlier).
        let best = match judged
            .iter()
            .position(|j| j.as_ref().is_some_and(|j| j.margin.is_ok()))
        {
            Some(i) => judged.into_iter().nth(i).flatten(),
            None => judged
                .into_iter()
                .flatten()
                .rev()
                .max_by_key(|j| j.margin.err().map_or(0, |(blocks, _)| blocks)),
        }?;
        tracing::debug!(
            "warm-start portfolio: {} of {} rasters of the first layer built and judged; the chosen one {}",
            built,
            variants.len(),
            match &best.margin {
                Ok(m) => format!("keeps every window, margin {m:.2} s"),
                Err((blocks, _)) => format!("breaks a window after {blocks} blocks"),
            }
        );
        Some(best.tried())
    }

    /// The first feasible of `variants` in order (`kind` names them in the log).
    fn first_feasible(&self, variants: &[Variant], kind: &str, seen: &Seen) -> Option<Repaired> {
        if variants.is_empty() || self.limits.stopped() {
            return None;
        }
        let judged = self.judge_in_order(variants, seen);
        let tried = judged.iter().filter(|j| j.is_some()).count();
        let found = judged
            .into_iter()
            .enumerate()
            .find_map(|(i, j)| j.filter(|j| j.margin.is_ok()).map(|j| (i, j)));
        tracing::debug!(
            "warm-start portfolio: {tried} of {} {kind} variants built and judged{}: {}",
            variants.len(),
            if self.limits.stopped() {
                " before the deadline"
            } else {
                ""
            },
            found
                .as_ref()
                .map_or("none feasible".to_string(), |(i, j)| {
                    format!(
                        "{kind} variant {i} feasible, margin {:.2} s",
                        j.margin.unwrap_or(f64::NAN)
                    )
                })
        );
        found.map(|(_, j)| Repaired {
            plan: j.plan,
            end: j.end,
        })
    }

    /// The variants built and simulated in order by up to [`AT_ONCE`] of the run's threads,
    /// until one keeps every window: slot i holds variant i's verdict whichever thread
    /// judged it. Every variant before the first feasible one is judged whole; those after
    /// it are stopped or never built (`None`), so the first feasible slot is the same on
    /// any number of threads. Once the run stops no variant is started and those under way
    /// stop (`None`); a variant judged before it keeps its verdict.
    fn judge_in_order(&self, variants: &[Variant], seen: &Seen) -> Vec<Option<Judged>> {
        let next = AtomicUsize::new(0);
        // The first feasible variant found so far (`usize::MAX`: none yet).
        let first_feasible = AtomicUsize::new(usize::MAX);
        // One stop flag per variant: those after a feasible one are stopped, all of them
        // when the run is.
        let stops: Vec<Arc<AtomicBool>> = variants.iter().map(|_| Arc::default()).collect();
        let stop_from = |i: usize| {
            for stop in stops.iter().skip(i) {
                stop.store(true, Ordering::Relaxed);
            }
        };
        let results: Mutex<Vec<Option<Judged>>> = Mutex::new(vec![None; variants.len()]);
        let workers = self.workers.clamp(1, AT_ONCE).min(variants.len().max(1));
        std::thread::scope(|scope| {
            let handles: Vec<_> = (0..workers)
                .map(|_| {
                    scope.spawn(|| loop {
                        let i = next.fetch_add(1, Ordering::Relaxed);
                        if i >= variants.len()
                            || i > first_feasible.load(Ordering::Relaxed)
                            || self.limits.stopped()
                        {
                            break;
                        }
                        let limits = Limits {
                            deadline: self.limits.deadline,
                            cancel: Some(stops[i].clone()),
                        };
                        let judged = self.judge_variant(&variants[i], &limits, seen);
                        if judged.as_ref().is_some_and(|j| j.margin.is_ok()) {
                            first_feasible.fetch_min(i, Ordering::Relaxed);
                            stop_from(i + 1);
                        }
                        results.lock().expect("no worker panics")[i] = judged;
                    })
                })
                .collect();
            // The run's own cancel reaches the variants through their flags.
            while !handles.iter().all(|h| h.is_finished()) {
                if self.limits.stopped() {
                    stop_from(0);
                }
                std::thread::sleep(Duration::from_millis(10));
            }
        });
        results.into_inner().expect("no worker panics")
    }

    /// One variant built and simulated within `limits` (on one thread: the variants are
    /// the parallel work).
    fn judge_variant(&self, first: &[Vec<usize>], limits: &Limits, seen: &Seen) -> Option<Judged> {
        let Portfolio {
            part,
            graph,
            k,
            backend,
            ..
        } = *self;
        let name = describe(part, first);
        let Some(plan) = constructive::layered_plan_from(part, graph, k, backend, limits, first)
        else {
            tracing::debug!("warm-start variant {name}: not built");
            return None;
        };
        if let Some(broken) = seen.broken(&plan) {
            tracing::debug!(
                "warm-start variant {name}: begins as a variant judged before, which broke the window of {:?} after {} blocks",
                part.block(broken.1),
                broken.0
            );
            return Some(Judged {
                plan,
                margin: Err(broken),
                end: None,
            });
        }
        self.judge_plan(plan, &name, limits, Some(seen))
    }

    /// A plan simulated within `limits` on one thread (`name` for the log).
    /// A plan that breaks a window is remembered in `seen`.
    fn judge_plan(
        &self,
        plan: Vec<Vec<usize>>,
        name: &str,
        limits: &Limits,
        seen: Option<&Seen>,
    ) -> Option<Judged> {
        let Portfolio { part, model, .. } = *self;
        let sim = thermal::Simulation::new(model)
            .with_threads(1)
            .with_deadline(limits.deadline);
        let sim = match &limits.cancel {
            Some(c) => sim.with_cancel(c.clone()),
            None => sim,
        };
        let (outcome, end) = thermal::simulate_keeping_end(sim, &plan).ok()??;
        let margin = match &outcome.violation {
            Some(v) => {
                tracing::debug!(
                    "warm-start variant {name}: {:?} window of {:?} broken at {:.1} s (t8/5 {:.2} s)",
                    v.kind,
                    part.block(v.block),
                    v.time_s,
                    v.t85_s
                );
                if let Some(seen) = seen {
                    seen.remember(&plan, v);
                }
                Err((v.prefix_len, v.block))
            }
            None => {
                let m = model.margin(&outcome.crossings);
                tracing::debug!("warm-start variant {name}: feasible, margin {m:.2} s");
                Ok(m)
            }
        };
        Some(Judged { plan, margin, end })
    }
}

/// A variant for the log: each path's first block, where it goes next and, for a whole
/// piece, where it ends.
fn describe(part: &Part, first: &[Vec<usize>]) -> String {
    let paths: Vec<String> = first
        .iter()
        .map(|p| match p.as_slice() {
            [a, b] => format!("{:?} -> {:?}", part.block(*a), part.block(*b)),
            [a, b, .., z] => format!(
                "{:?} -> {:?} .. {:?} ({} blocks)",
                part.block(*a),
                part.block(*b),
                part.block(*z),
                p.len()
            ),
            [a] => format!("{:?}", part.block(*a)),
            [] => "any".to_string(),
        })
        .collect();
    paths.join(" | ")
}

/// The first layer's covers (the base's and the others the weld graph allows), each with
/// every order of its paths (rotations) and every way round of each; the base's own first
/// layer left out, and on a one-path layer the variants whose first move was tried as a
/// start (a first move fixes a single path's start and way already). The covers take turns
/// (each one's first order and way, then each one's second, ...), so that every cover is
/// judged before any is judged again: which path takes a junction decides how long each
/// path's layer is, so how soon a block gets the block above, and at 10^5 blocks one
/// variant takes minutes, so a deadline may leave time for the first few variants only (on a
/// T-wall there, all seven variants of the base's own cover broke the same window by the
/// same 0.035 s).
fn cover_variants(p: &Portfolio, base: &[Vec<usize>], moves: &[(usize, usize)]) -> Vec<Variant> {
    let own = first_layer_pieces(p.part, base);
    if own.is_empty() {
        return Vec::new();
    }
    let covers = constructive::first_layer_covers(p.part, p.backend, p.limits, &own);
    let orders = |cover: &Vec<Vec<usize>>| -> Vec<Variant> {
        let m = cover.len();
        (0..m)
            .flat_map(|rotation| (0..1usize << m).map(move |ways| (rotation, ways)))
            .map(|(rotation, ways)| {
                (0..m)
                    .map(|i| {
                        let mut piece = cover[(i + rotation) % m].clone();
                        if (ways >> i) & 1 == 1 {
                            piece.reverse();
                        }
                        piece
                    })
                    .collect()
            })
            .collect()
    };
    let per_cover: Vec<Vec<Variant>> = covers.iter().map(orders).collect();
    let turns = per_cover.iter().map(Vec::len).max().unwrap_or(0);
    let mut out: Vec<Variant> = Vec::new();
    for variant in (0..turns).flat_map(|t| per_cover.iter().filter_map(move |c| c.get(t))) {
        let tried = variant.len() == 1 && variant[0].len() >= 2 && {
            let (a, b) = (variant[0][0], variant[0][1]);
            moves.contains(&(a, b)) || (base[0].len() >= 2 && (a, b) == (base[0][0], base[0][1]))
        };
        if *variant != own && !tried && !out.contains(variant) {
            out.push(variant.clone());
        }
    }
    out
}

/// The base plan's first layer: the pieces of the weld paths that start in it, in weld
/// order (empty when a path starts above it first).
fn first_layer_pieces(part: &Part, base: &[Vec<usize>]) -> Vec<Vec<usize>> {
    let Some(z0) = base.iter().flatten().map(|&b| part.block(b)[2]).min() else {
        return Vec::new();
    };
    base.iter()
        .filter(|f| f.first().is_some_and(|&b| part.block(b)[2] == z0))
        .map(|f| {
            f.iter()
                .copied()
                .take_while(|&b| part.block(b)[2] == z0)
                .collect()
        })
        .collect()
}

/// The available cores (a run on all cores judges up to 8 variants at once).
pub fn cores() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}

/// The first moves to try: from places spread evenly along the base plan's first layer
/// (its weld paths' pieces there in weld order, one after the other: 1/2, 1/4, 3/4, 1/8,
/// ... of the way), each setting off forwards and backwards along its piece (round it, on
/// a ring), where the weld graph allows and `allows` says the first layer can be covered
/// so; the base plan's own first move left out; from at most [`MAX_STARTS`] places that
/// have such a move. Every piece, not only the first path's: on a layer of several paths
/// (a T, two rings) the first path may as well start in another's piece (on a T-wall the
/// plan that kept every window started in the base's second piece). Places count only
/// with a move that can be built: on a T most starts cannot (no two paths cover the rest),
/// and skipping them costs a small solve, not a simulation.
fn first_moves(
    part: &Part,
    graph: &WeldGraph,
    base: &[Vec<usize>],
    allows: impl Fn(&[Vec<usize>]) -> bool,
) -> Vec<(usize, usize)> {
    let pieces = first_layer_pieces(part, base);
    let Some(first) = pieces.first() else {
        return Vec::new();
    };
    let own = (first[0], first.get(1).copied().unwrap_or(first[0]));
    // Each place on the layer: its piece and where in it.
    let places: Vec<(&Vec<usize>, usize)> = pieces
        .iter()
        .flat_map(|piece| (0..piece.len()).map(move |o| (piece, o)))
        .collect();
    let n = places.len();
    let mut visited = vec![false; n];
    let mut moves = Vec::new();
    let mut counted = 0;
    for i in 0..n.next_power_of_two() {
        let p = (van_der_corput(i) * n as f64) as usize;
        if counted == MAX_STARTS {
            break;
        }
        if std::mem::replace(&mut visited[p], true) {
            continue;
        }
        let (piece, o) = places[p];
        let m = piece.len();
        let before = moves.len();
        for q in [o + 1, o + m - 1] {
            let mv = (piece[o], piece[q % m]);
            if mv != own
                && graph.has_edge(mv.0, mv.1)
                && !moves.contains(&mv)
                && allows(&[vec![mv.0, mv.1]])
            {
                moves.push(mv);
            }
        }
        counted += usize::from(moves.len() > before);
    }
    moves
}

/// 0, 1/2, 1/4, 3/4, 1/8, 3/8, ...: each prefix spread evenly over [0, 1).
fn van_der_corput(mut i: usize) -> f64 {
    let (mut x, mut scale) = (0.0, 0.5);
    while i > 0 {
        x += scale * (i & 1) as f64;
        i >>= 1;
        scale /= 2.0;
    }
    x
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A one-block 5 x 5 ring, `h` layers, with a window on a high corner block.
    fn ring(h: i64, window: waam_part::Window) -> Part {
        let blocks = (0..h)
            .flat_map(|z| {
                (0..5).flat_map(move |y| {
                    (0..5)
                        .filter(move |&x| y % 4 == 0 || x % 4 == 0)
                        .map(move |x| [x, y, z])
                })
            })
            .collect();
        let mut part = Part::from_blocks("ring".into(), [6.0, 6.0, 2.5], [0.0; 3], 1, blocks)
            .expect("a valid part");
        let corner = part.index_of([0, 0, h - 2]).expect("a corner block");
        part.set_window(corner, window);
        part
    }

    /// The ring of [`ring`] with a window of at most `max_s`, its weld graph, its thermal
    /// model and its layer-by-layer plan (the portfolio's base).
    fn ring_and_base(h: i64, max_s: f64) -> (Part, WeldGraph, ThermalModel, Vec<Vec<usize>>) {
        let part = ring(h, waam_part::Window { min_s: 0.0, max_s });
        let graph = WeldGraph::new(&part);
        let model = ThermalModel::new(&part, &graph);
        let base = constructive::layered_plan(&part, &graph, 1, Backend::Cadical, &no_limits())
            .expect("a ring has a layer-by-layer plan");
        (part, graph, model, base)
    }

    fn no_limits() -> Limits {
        Limits {
            deadline: None,
            cancel: None,
        }
    }

    fn on_one_path<'a>(
        part: &'a Part,
        graph: &'a WeldGraph,
        limits: &'a Limits,
        model: &'a ThermalModel,
    ) -> Portfolio<'a> {
        Portfolio {
            part,
            graph,
            k: 1,
            backend: Backend::Cadical,
            limits,
            model,
            workers: 2,
        }
    }

    #[test]
    fn every_variant_is_valid_and_judged_by_the_simulator() {
        // A window no start can keep (at most 1 s between 800 and 500 °C high on a wall):
        // every variant is built and simulated, and none is claimed.
        let (part, graph, model, base) = ring_and_base(12, 1.0);
        let moves = first_moves(&part, &graph, &base, |_| true);
        assert!(moves.len() >= 8, "{} first moves", moves.len());
        let limits = no_limits();
        let portfolio = on_one_path(&part, &graph, &limits, &model);
        let variants: Vec<Variant> = moves.iter().map(|&(a, b)| vec![vec![a, b]]).collect();
        let judged = portfolio.judge_in_order(&variants, &Seen::default());
        for (m, j) in moves.iter().zip(&judged) {
            let j = j.as_ref().expect("each start of a ring can be built");
            assert_eq!(j.plan[0][..2], [m.0, m.1], "the variant sets off as asked");
            waam_part::plan::Plan::from_indices(&part, &j.plan)
                .validate(&part, &graph)
                .expect("a valid plan");
            assert!(j.margin.is_err(), "no plan keeps a 1 s window");
            assert!(
                j.end.is_none(),
                "no end state of a plan that breaks a window"
            );
        }
        assert!(portfolio.varied_start(&base).is_none());
    }

    #[test]
    fn a_plan_that_begins_with_a_prefix_that_broke_a_window_breaks_it_the_same_way() {
        // A window of at most 1 s low on the ring: broken long before the last block.
        let mut part = ring(
            12,
            waam_part::Window {
                min_s: 0.0,
                max_s: 1e9,
            },
        );
        let low = part.index_of([0, 0, 2]).expect("a corner block");
        part.set_window(
            low,
            waam_part::Window {
                min_s: 0.0,
                max_s: 1.0,
            },
        );
        let graph = WeldGraph::new(&part);
        let model = ThermalModel::new(&part, &graph);
        let limits = no_limits();
        let base = constructive::layered_plan(&part, &graph, 1, Backend::Cadical, &limits)
            .expect("a ring has a layer-by-layer plan");
        let portfolio = on_one_path(&part, &graph, &limits, &model);
        let seen = Seen::default();
        let judged = portfolio
            .judge_plan(base.clone(), "the base", &limits, Some(&seen))
            .expect("judged");
        let Err((blocks, block)) = judged.margin else {
            panic!("no plan keeps a 1 s window");
        };
        assert_eq!(seen.broken(&base), Some((blocks, block)));
        // The same prefix, the rest welded otherwise: the simulator breaks the same window
        // after as many blocks, and the portfolio knows it without simulating.
        let mut other = base.clone();
        other[0][blocks..].reverse();
        assert!(
            blocks + 2 < base[0].len() && other != base,
            "the rest is welded otherwise"
        );
        assert_eq!(seen.broken(&other), Some((blocks, block)));
        let outcome = thermal::simulate(&model, &other).expect("simulated");
        let v = outcome.violation.expect("the window breaks");
        assert_eq!((v.prefix_len, v.block), (blocks, block));
        // Another first move is another prefix: simulated.
        let mut early = base.clone();
        early[0].swap(0, 1);
        assert_eq!(seen.broken(&early), None);
    }

    #[test]
    fn the_first_feasible_variant_in_order_wins_on_any_number_of_threads() {
        // Each start's least t8/5 of the windowed block, from a window that keeps them all.
        let h = 10;
        let part = ring(
            h,
            waam_part::Window {
                min_s: 0.0,
                max_s: 1e6,
            },
        );
        let graph = WeldGraph::new(&part);
        let limits = no_limits();
        let base = constructive::layered_plan(&part, &graph, 1, Backend::Cadical, &limits)
            .expect("a ring has a layer-by-layer plan");
        let moves: Vec<Variant> = first_moves(&part, &graph, &base, |_| true)
            .into_iter()
            .map(|(a, b)| vec![vec![a, b]])
            .collect();
        let model = ThermalModel::new(&part, &graph);
        let portfolio = on_one_path(&part, &graph, &limits, &model);
        let least: Vec<f64> = moves
            .iter()
            .map(|m| {
                let j = portfolio.judge_in_order(std::slice::from_ref(m), &Seen::default());
                j[0].as_ref()
                    .expect("each start is built")
                    .margin
                    .expect("kept")
            })
            .collect();
        // A least t8/5 the first start misses and a later one keeps.
        let most = least.iter().copied().fold(f64::MIN, f64::max);
        assert!(most > least[0] + 0.1, "the starts differ: {least:?}");
        let min_s = (least[0] + most) / 2.0;
        let expected = least.iter().position(|&t| t > min_s).expect("one keeps it");
        let mut part = part.clone();
        let corner = part.index_of([0, 0, h - 2]).expect("the corner block");
        part.set_window(corner, waam_part::Window { min_s, max_s: 1e6 });
        let model = ThermalModel::new(&part, &graph);
        for workers in [1, 2, 3, 8] {
            let portfolio = Portfolio {
                workers,
                ..on_one_path(&part, &graph, &limits, &model)
            };
            let judged = portfolio.judge_in_order(&moves, &Seen::default());
            for (i, j) in judged.iter().enumerate().take(expected) {
                let j = j.as_ref().expect("every start before it is judged whole");
                assert!(
                    j.margin.is_err(),
                    "start {i} misses {min_s} s ({workers} threads)"
                );
            }
            let found = portfolio
                .varied_start(&base)
                .expect("a start keeps the window");
            assert_eq!(
                found.plan[0][..2],
                moves[expected][0][..],
                "{workers} threads"
            );
            assert!(found.end.is_some());
        }
    }

    #[test]
    fn a_cancelled_run_builds_and_claims_nothing() {
        let (part, graph, model, base) = ring_and_base(10, 1.0);
        let limits = Limits {
            deadline: None,
            cancel: Some(std::sync::Arc::new(std::sync::atomic::AtomicBool::new(
                true,
            ))),
        };
        let portfolio = on_one_path(&part, &graph, &limits, &model);
        let moves: Vec<Variant> = first_moves(&part, &graph, &base, |_| true)
            .into_iter()
            .map(|(a, b)| vec![vec![a, b]])
            .collect();
        assert!(portfolio
            .judge_in_order(&moves, &Seen::default())
            .iter()
            .all(Option::is_none));
        assert!(portfolio.varied_start(&base).is_none());
    }

    #[test]
    fn a_cancel_during_the_run_stops_the_variant_under_way() {
        // One start of a tall ring, built and simulated nearly to its top (a window no
        // start keeps, two layers down); then the same again, cancelled an eighth of the
        // way through: the run's cancel reaches the variant's own flag.
        let (part, graph, model, base) = ring_and_base(300, 1.0);
        let moves = first_moves(&part, &graph, &base, |_| true);
        let one: Vec<Variant> = vec![vec![vec![moves[0].0, moves[0].1]]];
        let cancel = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
        let limits = Limits {
            deadline: None,
            cancel: Some(cancel.clone()),
        };
        let portfolio = on_one_path(&part, &graph, &limits, &model);
        let started = std::time::Instant::now();
        let whole = portfolio.judge_in_order(&one, &Seen::default());
        let took = started.elapsed();
        assert!(whole[0].as_ref().is_some_and(|j| j.margin.is_err()));
        let judged = std::thread::scope(|scope| {
            scope.spawn(|| {
                std::thread::sleep(took / 8);
                cancel.store(true, Ordering::Relaxed);
            });
            portfolio.judge_in_order(&one, &Seen::default())
        });
        assert!(judged[0].is_none(), "the variant under way is stopped");
    }

    /// A T-wall: a bar of 7 along x with a stem of 3 from x = 2, 6 layers, k = 2.
    fn t_wall() -> Part {
        let blocks = (0..6)
            .flat_map(|z| {
                (0..7)
                    .map(move |x| [x, 0, z])
                    .chain((1..4).map(move |y| [2, y, z]))
            })
            .collect();
        Part::from_blocks("t".into(), [6.0, 6.0, 2.5], [0.0; 3], 2, blocks).expect("a valid part")
    }

    #[test]
    fn starts_come_from_every_path_of_the_first_layer_and_each_can_be_built() {
        let part = t_wall();
        let graph = WeldGraph::new(&part);
        let limits = no_limits();
        let base = constructive::layered_plan(&part, &graph, 2, Backend::Cadical, &limits)
            .expect("a T has a layer-by-layer plan");
        let pieces = first_layer_pieces(&part, &base);
        assert_eq!(pieces.len(), 2, "two paths start in the first layer");
        let allows = constructive::first_layer_allows(&part, 2, Backend::Cadical, &limits)
            .expect("a part with a layer");
        let moves = first_moves(&part, &graph, &base, &allows);
        assert!(
            moves.iter().any(|&(a, _)| pieces[1].contains(&a)),
            "a start in the second path's piece: {moves:?}"
        );
        for &(a, b) in &moves {
            let plan = constructive::layered_plan_from(
                &part,
                &graph,
                2,
                Backend::Cadical,
                &limits,
                &[vec![a, b]],
            )
            .expect("each start is built");
            assert_eq!(plan[0][..2], [a, b]);
        }
        // Inside a branch no two paths cover the rest: such starts are left out.
        let every = first_moves(&part, &graph, &base, |_| true);
        assert!(every.len() > moves.len(), "{every:?} / {moves:?}");
    }

    #[test]
    fn every_cover_takes_its_turn_before_any_comes_again() {
        // A T layer has three covers by two paths (the junction with either half of the
        // bar, or the bar whole and the stem alone), each in 2 orders x 4 ways.
        let part = t_wall();
        let graph = WeldGraph::new(&part);
        let model = ThermalModel::new(&part, &graph);
        let limits = no_limits();
        let base = constructive::layered_plan(&part, &graph, 2, Backend::Cadical, &limits)
            .expect("a T has a layer-by-layer plan");
        let portfolio = Portfolio {
            k: 2,
            ..on_one_path(&part, &graph, &limits, &model)
        };
        let variants = cover_variants(&portfolio, &base, &[]);
        assert_eq!(
            variants.len(),
            3 * 8 - 1,
            "all but the base's own first layer"
        );
        let cover = |v: &Variant| {
            let mut pairs: Vec<(usize, usize)> = v
                .iter()
                .flat_map(|p| p.windows(2).map(|w| (w[0].min(w[1]), w[0].max(w[1]))))
                .collect();
            pairs.sort();
            pairs
        };
        let own = cover(&first_layer_pieces(&part, &base));
        // The two other covers first, then the base's own in another order or way.
        assert_ne!(cover(&variants[0]), own);
        assert_ne!(cover(&variants[1]), own);
        assert_ne!(cover(&variants[0]), cover(&variants[1]));
        assert_eq!(cover(&variants[2]), own);
        for (i, v) in variants.iter().enumerate().skip(3) {
            assert_eq!(cover(v), cover(&variants[i % 3]), "variant {i}");
        }
    }

    #[test]
    fn van_der_corput_halves_then_quarters() {
        let v: Vec<f64> = (0..6).map(van_der_corput).collect();
        assert_eq!(v, [0.0, 0.5, 0.25, 0.75, 0.125, 0.625]);
    }
}
