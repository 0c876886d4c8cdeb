//! A portfolio of warm starts: when the layer-by-layer plan breaks a t8/5 window, the same
//! construction is set off from other places, each variant simulated, and the best
//! feasible one becomes the warm start.
//!
//! Why the start: a weld path that walks each layer back over the one below leaves a seam
//! where a layer starts, and a block's distance from that seam decides how soon the block
//! above it is deposited and reheats it. On a tall tube that moves a windowed block's
//! t8/5 by hundreds of seconds (measured in the README), while the builder's other
//! choices stay valid. The variants start at places spread evenly along the base plan's
//! first layer (halves, then quarters, eighths, ...), setting off both ways; they are
//! judged in rounds of a fixed size on all cores, and the first round with a feasible
//! variant gives the one with the largest margin (ties: the earlier variant), so the
//! answer does not depend on the number of cores or on which thread finishes first.
//!
//! Why the cover: on a layer that needs several paths (a T, two rings) a first move fixes
//! only where the first path starts, and on a branching layer no path can start inside a
//! branch, so those variants cannot be built at all. Which path takes a junction decides
//! which blocks climb together and so when each is reheated. When no start keeps every
//! window, the portfolio varies the first layer's cover: the base's, and each the weld
//! graph allows with a path end moved on to a neighbour (another branch takes the
//! junction), each with every way round and every order of its paths, judged in the same
//! rounds, the covers taking turns. A feasible variant's simulation after its last deposit
//! goes with it, so the search's verdict on it simulates only the cooldown.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

use waam_part::graph::WeldGraph;
use waam_part::Part;
use waam_thermal::{self as thermal, Snapshot, ThermalModel};

use crate::constructive::{self, Limits};
use crate::repair::Repaired;
use crate::sat::Backend;

/// Variants judged together; fixed, so the choice is the same on any machine.
const ROUND: usize = 8;
/// Places along the first layer tried at most (each set off both ways): 32, a start every
/// 3% of the way (on a generated 26 x 18 tube whose windows are those of a hidden plan, 16
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
    /// Threads judging a round's variants (1 in a race: the other racers have the rest).
    pub workers: usize,
}

/// How a variant's first layer begins: its paths' first blocks (a first move: one path's
/// first two; a cover: every path whole), as [`constructive::layered_plan_from`] takes them.
type Variant = Vec<Vec<usize>>;

/// A variant built and simulated (`None` in a round's slot: it could not be built, or the
/// run stopped its simulation).
#[derive(Debug, Clone, PartialEq)]
struct Judged {
    plan: Vec<Vec<usize>>,
    /// Its margin, or `Err((blocks welded before a window breaks, the broken block))`.
    margin: Result<f64, (usize, usize)>,
    /// A feasible variant's simulation after its last deposit (see [`Repaired`]).
    end: Option<Snapshot>,
}

/// The best raster variant: `Ok` when one keeps every window, else the one that keeps them
/// longest, as `Err((plan, blocks welded before a window breaks, the broken block))`.
pub type Rastered = Result<Repaired, (Vec<Vec<usize>>, usize, usize)>;

impl Portfolio<'_> {
    /// A feasible variant of `base` (a layer-by-layer plan that breaks a window), the best
    /// of the first round that has one; `None` when no variant keeps every window (or the
    /// run stopped first).
    pub fn varied_start(&self, base: &[Vec<usize>]) -> Option<Repaired> {
        let moves = first_moves(self.part, self.graph, base);
        let starts: Vec<Variant> = moves.iter().map(|&(a, b)| vec![vec![a, b]]).collect();
        let rounds = starts.len().div_ceil(ROUND);
        if let Some(found) = self.first_feasible(&starts, 0) {
            return Some(found);
        }
        // No start keeps every window: other covers of the first layer, judged in rounds
        // numbered on from the starts' (the solves of the covers cost little beside them).
        if self.limits.stopped() {
            return None;
        }
        let covers = cover_variants(self, base, &moves);
        tracing::debug!(
            "warm-start portfolio: {} variants of the first layer's cover",
            covers.len()
        );
        self.first_feasible(&covers, rounds)
    }

    /// The first layer welded as a raster ([`constructive::raster_covers`], as many paths
    /// as `base` starts there), each way and from each corner, judged in one round: the
    /// best feasible variant, else the one that keeps every window longest; `None` when the
    /// first layer has no area (or no raster is built, or the run stopped).
    pub fn rasters(&self, base: &[Vec<usize>]) -> Option<Rastered> {
        let own = first_layer_pieces(self.part, base);
        let covers = constructive::raster_covers(self.part, self.backend, self.limits, own.len());
        let variants: Vec<Variant> = covers.into_iter().filter(|c| *c != own).collect();
        if variants.is_empty() {
            return None;
        }
        let judged = self.judge_round(&variants, self.workers);
        let built = judged.iter().filter(|j| j.is_some()).count();
        // Largest margin, else furthest before a window breaks; on a tie the earlier
        // variant (max_by keeps the last maximum: the judged ones are walked back).
        let rank = |j: &Judged| match j.margin {
            Ok(margin) => (1, margin),
            Err((blocks, _)) => (0, blocks as f64),
        };
        let best = judged.into_iter().flatten().rev().max_by(|a, b| {
            let (a, b) = (rank(a), rank(b));
            a.0.cmp(&b.0).then(a.1.total_cmp(&b.1))
        })?;
        tracing::debug!(
            "warm-start portfolio: {} of {} rasters of the first layer built; the best {}",
            built,
            variants.len(),
            match &best.margin {
                Ok(m) => format!("keeps every window, margin {m:.2} s"),
                Err((blocks, _)) => format!("breaks a window after {blocks} blocks"),
            }
        );
        Some(match best.margin {
            Ok(_) => Ok(Repaired {
                plan: best.plan,
                end: best.end,
            }),
            Err((blocks, block)) => Err((best.plan, blocks, block)),
        })
    }

    /// The best feasible variant of the first round (of [`ROUND`]) that has one; rounds are
    /// numbered from `first_round` in the log.
    fn first_feasible(&self, variants: &[Variant], first_round: usize) -> Option<Repaired> {
        for (r, round) in variants.chunks(ROUND).enumerate() {
            if self.limits.stopped() {
                return None;
            }
            let judged = self.judge_round(round, self.workers);
            let tried = judged.iter().filter(|j| j.is_some()).count();
            let best = judged
                .into_iter()
                .enumerate()
                .filter_map(|(i, j)| j.and_then(|j| Some((i, j.margin.ok()?, j))))
                // Largest margin; on a tie the earlier variant (max_by keeps the last maximum).
                .max_by(|a, b| a.1.total_cmp(&b.1).then(b.0.cmp(&a.0)));
            tracing::debug!(
                "warm-start portfolio: round {} ({} variants built and judged): {}",
                first_round + r + 1,
                tried,
                best.as_ref()
                    .map_or("none feasible".to_string(), |(i, m, _)| {
                        format!(
                            "variant {} feasible, margin {m:.2} s",
                            (first_round + r) * ROUND + i
                        )
                    })
            );
            if let Some((_, _, j)) = best {
                return Some(Repaired {
                    plan: j.plan,
                    end: j.end,
                });
            }
        }
        None
    }

    /// Each variant of a round built and simulated by `workers` threads; slot i holds
    /// variant i whichever thread judged it, and whenever.
    fn judge_round(&self, round: &[Variant], workers: usize) -> Vec<Option<Judged>> {
        let next = AtomicUsize::new(0);
        let results: Mutex<Vec<Option<Judged>>> = Mutex::new(vec![None; round.len()]);
        std::thread::scope(|scope| {
            for _ in 0..workers.clamp(1, round.len().max(1)) {
                scope.spawn(|| loop {
                    let i = next.fetch_add(1, Ordering::Relaxed);
                    let Some(first) = round.get(i) else { break };
                    let judged = self.judge_variant(first);
                    results.lock().expect("no worker panics")[i] = judged;
                });
            }
        });
        results.into_inner().expect("no worker panics")
    }

    /// One variant built and simulated (on one thread: the variants are the parallel work).
    fn judge_variant(&self, first: &[Vec<usize>]) -> Option<Judged> {
        let Portfolio {
            part,
            graph,
            k,
            backend,
            limits,
            model,
            workers: _,
        } = *self;
        let name = describe(part, first);
        let Some(plan) = constructive::layered_plan_from(part, graph, k, backend, limits, first)
        else {
            tracing::debug!("warm-start variant {name}: not built");
            return None;
        };
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
/// variant takes minutes, so a deadline may leave time for the first round only (on a
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

/// The available cores (a run on all cores judges a round on all of them).
pub fn cores() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}

/// The first moves to try: from places spread evenly along the base plan's first layer
/// (in the order the first weld path welds it: 1/2, 1/4, 3/4, 1/8, ... of the way), each
/// setting off forwards and backwards along that order, where the weld graph allows; the
/// base plan's own first move left out.
fn first_moves(part: &Part, graph: &WeldGraph, base: &[Vec<usize>]) -> Vec<(usize, usize)> {
    let Some(first) = base.first() else {
        return Vec::new();
    };
    let z0 = part.block(first[0])[2];
    let layer: Vec<usize> = first
        .iter()
        .copied()
        .take_while(|&b| part.block(b)[2] == z0)
        .collect();
    let n = layer.len();
    let own = (layer[0], layer.get(1).copied().unwrap_or(layer[0]));
    let mut moves = Vec::new();
    for i in 0..MAX_STARTS.min(n) {
        let p = (van_der_corput(i) * n as f64) as usize;
        for q in [p + 1, p + n - 1] {
            let m = (layer[p], layer[q % n]);
            if m != own && graph.has_edge(m.0, m.1) && !moves.contains(&m) {
                moves.push(m);
            }
        }
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
        let moves = first_moves(&part, &graph, &base);
        assert!(moves.len() >= 8, "{} first moves", moves.len());
        let limits = no_limits();
        let portfolio = on_one_path(&part, &graph, &limits, &model);
        let variants: Vec<Variant> = moves.iter().map(|&(a, b)| vec![vec![a, b]]).collect();
        let judged = portfolio.judge_round(&variants, 2);
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
    fn a_round_judges_the_same_on_any_number_of_threads() {
        // Each variant lands in its own slot whatever thread judged it and when.
        let (part, graph, model, base) = ring_and_base(10, 1e6);
        let moves: Vec<Variant> = first_moves(&part, &graph, &base)
            .into_iter()
            .map(|(a, b)| vec![vec![a, b]])
            .collect();
        let limits = no_limits();
        let portfolio = on_one_path(&part, &graph, &limits, &model);
        let judge = |workers| portfolio.judge_round(&moves, workers);
        let one = judge(1);
        assert!(one.iter().all(|j| j
            .as_ref()
            .is_some_and(|j| j.margin.is_ok() && j.end.is_some())));
        for workers in [2, 3, 8] {
            assert_eq!(judge(workers), one, "{workers} threads");
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
        let moves: Vec<Variant> = first_moves(&part, &graph, &base)
            .into_iter()
            .map(|(a, b)| vec![vec![a, b]])
            .collect();
        assert!(portfolio.judge_round(&moves, 2).iter().all(Option::is_none));
        assert!(portfolio.varied_start(&base).is_none());
    }

    #[test]
    fn every_cover_takes_its_turn_before_any_comes_again() {
        // A T layer has three covers by two paths (the junction with either half of the
        // bar, or the bar whole and the stem alone), each in 2 orders x 4 ways.
        let blocks = (0..6)
            .flat_map(|z| {
                (0..7)
                    .map(move |x| [x, 0, z])
                    .chain((1..4).map(move |y| [2, y, z]))
            })
            .collect();
        let part = Part::from_blocks("t".into(), [6.0, 6.0, 2.5], [0.0; 3], 2, blocks)
            .expect("a valid part");
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
