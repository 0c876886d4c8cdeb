//! Seeded benchmark parts whose windows a known plan keeps.
//!
//! Each family is built from its seed: its sizes (so that it has about the asked number of
//! blocks), then a *random* valid plan of it (the witness: where each layer starts, which
//! way each ring is walked, where a second weld path takes over), then 1 to 4 windowed
//! blocks at random places. The witness is simulated with those blocks' windows opened
//! wide, and each window is set to ±10 % around the t8/5 times the witness gives the block;
//! a final simulation with the windows checks that the witness keeps them (a block whose
//! window it would still break — a reheat that keeps it between 800 and 500 °C longer
//! than any crossing shows — loses its window). So every part has a feasible plan, and
//! the planner does not know it: its own warm start walks each layer back over the one
//! below, the witness turns at random.

use waam_part::graph::WeldGraph;
use waam_part::plan::Plan;
use waam_part::{Block, Part, PartError, Window};
use waam_thermal::{self as thermal, Interrupt, ThermalModel};

use crate::rng::Rng;

/// The shapes a cell welds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Family {
    /// A rectangular (sometimes square) tube, one block thick.
    Tube,
    /// An open-top box: a one-layer floor, then its rim as a wall.
    Box,
    /// Two concentric tubes with a one-block gap: two rings per layer.
    DoubleTube,
    /// A one-block wall bent at a right angle.
    LWall,
    /// A one-block wall with a stem: three ends per layer, two weld paths.
    TWall,
    /// A square cup: a two-layer floor, then its rim as a wall.
    Cup,
}

impl Family {
    pub const ALL: [Family; 6] = [
        Family::Tube,
        Family::Box,
        Family::DoubleTube,
        Family::LWall,
        Family::TWall,
        Family::Cup,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Family::Tube => "tube",
            Family::Box => "box",
            Family::DoubleTube => "double-tube",
            Family::LWall => "l-wall",
            Family::TWall => "t-wall",
            Family::Cup => "cup",
        }
    }

    /// The family of a name as [`Family::name`] gives it.
    pub fn parse(name: &str) -> Result<Family, GenerateError> {
        Family::ALL
            .into_iter()
            .find(|f| f.name() == name)
            .ok_or_else(|| GenerateError::UnknownFamily(name.to_string()))
    }

    /// The fewest weld paths its witness needs (two rings or a T need two).
    pub fn min_fragments(self) -> usize {
        match self {
            Family::DoubleTube | Family::TWall => 2,
            _ => 1,
        }
    }
}

/// What to generate.
#[derive(Debug, Clone, Copy)]
pub struct Spec {
    pub family: Family,
    /// About this many blocks (the shape's sizes are whole numbers).
    pub blocks: usize,
    /// The part's max_fragments.
    pub k: usize,
    /// Windowed blocks, 1 to 4 (`None`: chosen from the seed).
    pub windows: Option<usize>,
    pub seed: u64,
}

/// Smallest and largest sizes generated.
pub const MIN_BLOCKS: usize = 200;
pub const MAX_BLOCKS: usize = 1_000_000;

#[derive(Debug, thiserror::Error)]
pub enum GenerateError {
    #[error("unknown family {0:?} (expected one of tube, box, double-tube, l-wall, t-wall, cup)")]
    UnknownFamily(String),
    #[error("blocks: {0} is outside {MIN_BLOCKS}..={MAX_BLOCKS}")]
    Size(usize),
    #[error("windows: {0} is outside 1..=4")]
    Windows(usize),
    #[error("{family}: needs k >= {needs} (got k = {k})")]
    TooFewFragments {
        family: &'static str,
        needs: usize,
        k: usize,
    },
    #[error("stopped (deadline or cancel) while simulating the witness plan")]
    Stopped,
    #[error("the generated part is refused: {0}")]
    Part(#[from] PartError),
    #[error(transparent)]
    NotCooled(#[from] thermal::NotCooled),
    #[error("internal: the witness plan of {name} is not valid: {why}")]
    InvalidWitness { name: String, why: String },
}

/// A generated part and the plan that keeps its windows.
#[derive(Debug, Clone)]
pub struct Generated {
    pub part: Part,
    /// Fragments of block indices, in weld order: valid and feasible.
    pub witness: Vec<Vec<usize>>,
}

impl Generated {
    pub fn witness_plan(&self) -> Plan {
        Plan::from_indices(&self.part, &self.witness)
    }
}

/// How far around the witness's t8/5 a window reaches.
const WINDOW_SLACK: f64 = 0.10;

/// Generates the part of `spec` (the same part for the same spec, on any machine);
/// `interrupt` stops the witness's simulations (on 10^5 blocks they take minutes).
pub fn generate(spec: &Spec, interrupt: &Interrupt) -> Result<Generated, GenerateError> {
    if !(MIN_BLOCKS..=MAX_BLOCKS).contains(&spec.blocks) {
        return Err(GenerateError::Size(spec.blocks));
    }
    if let Some(w) = spec.windows.filter(|w| !(1..=4).contains(w)) {
        return Err(GenerateError::Windows(w));
    }
    let needs = spec.family.min_fragments();
    if spec.k < needs {
        return Err(GenerateError::TooFewFragments {
            family: spec.family.name(),
            needs,
            k: spec.k,
        });
    }
    // Different families from one seed should not share their numbers.
    let mut rng = Rng::new(spec.seed ^ (spec.family as u64).wrapping_mul(0x2545_f491_4f6c_dd1d));
    let witness = shape(spec, &mut rng);
    let name = format!("{}-{}-s{}", spec.family.name(), spec.blocks, spec.seed);
    let blocks: Vec<Block> = witness.iter().flatten().copied().collect();
    let plain = Part::from_blocks(name.clone(), [6.0, 6.0, 2.5], [0.0; 3], spec.k, blocks)?;
    let graph = WeldGraph::new(&plain);
    let fragments: Vec<Vec<usize>> = witness
        .iter()
        .map(|f| {
            f.iter()
                .map(|&b| plain.index_of(b).expect("a block of the part"))
                .collect()
        })
        .collect();
    Plan::from_indices(&plain, &fragments)
        .validate(&plain, &graph)
        .map_err(|e| GenerateError::InvalidWitness {
            name: name.clone(),
            why: e.to_string(),
        })?;
    let count = spec.windows.unwrap_or_else(|| rng.range(1, 4) as usize);
    let mut chosen: Vec<usize> = Vec::new();
    while chosen.len() < count.min(plain.len()) {
        let b = rng.below(plain.len());
        if !chosen.contains(&b) {
            chosen.push(b);
        }
    }
    // The witness's t8/5 at the chosen blocks, their windows opened wide.
    let mut open = plain.clone();
    for &b in &chosen {
        open.set_window(
            b,
            Window {
                min_s: 0.0,
                max_s: 1e9,
            },
        );
    }
    let outcome = simulate(&open, &graph, &fragments, interrupt)?;
    let mut windows: Vec<(usize, Window)> = chosen
        .iter()
        .filter_map(|&b| {
            let t85 = outcome
                .crossings
                .iter()
                .filter(|c| c.block == b)
                .map(|c| c.t85_s);
            let lo = t85.clone().fold(f64::INFINITY, f64::min);
            let hi = t85.fold(0.0, f64::max);
            lo.is_finite().then(|| {
                let window = Window {
                    min_s: lo * (1.0 - WINDOW_SLACK),
                    max_s: hi * (1.0 + WINDOW_SLACK),
                };
                (b, window)
            })
        })
        .collect();
    // The windows as set: the witness must keep them (the last word is the simulator's).
    loop {
        let mut part = plain.clone();
        for &(b, w) in &windows {
            part.set_window(b, w);
        }
        if windows.is_empty() {
            return Ok(Generated {
                part,
                witness: fragments,
            });
        }
        match simulate(&part, &graph, &fragments, interrupt)?.violation {
            None => {
                return Ok(Generated {
                    part,
                    witness: fragments,
                })
            }
            Some(v) => windows.retain(|&(b, _)| b != v.block),
        }
    }
}

fn simulate(
    part: &Part,
    graph: &WeldGraph,
    fragments: &[Vec<usize>],
    interrupt: &Interrupt,
) -> Result<thermal::Outcome, GenerateError> {
    let model = ThermalModel::new(part, graph);
    thermal::simulate_until(
        &model,
        fragments,
        interrupt.deadline,
        interrupt.cancel.clone(),
    )?
    .ok_or(GenerateError::Stopped)
}

/// The family's sizes from the seed, and its random witness plan as fragments of blocks.
fn shape(spec: &Spec, rng: &mut Rng) -> Vec<Vec<Block>> {
    let b = spec.blocks as f64;
    let lo = ((b.sqrt() / 6.0) as i64).max(4);
    let hi = ((b.sqrt() / 2.0) as i64 + 4).max(lo);
    let layers = |per_layer: i64, rest: f64| ((rest / per_layer as f64).round() as i64).max(2);
    let split = spec.k >= 2;
    match spec.family {
        Family::Tube => {
            let (w, d) = (rng.range(lo, hi), rng.range(lo, hi));
            let ring = ring(0, 0, w, d);
            let h = layers(ring.len() as i64, b);
            climbing_rings(&ring, 0, h, split, rng, Vec::new())
        }
        Family::Box | Family::Cup => {
            let floors = if spec.family == Family::Box { 1 } else { 2 };
            // A floor of at most a third of the blocks, so the wall stands a while.
            let top = ((b / (3.0 * floors as f64)).sqrt() as i64).clamp(3, hi);
            let lo = lo.min(top);
            let (w, d) = match spec.family {
                Family::Box => (rng.range(lo, top), rng.range(lo, top)),
                _ => {
                    let s = rng.range(lo, top);
                    (s, s)
                }
            };
            let mut floor = Vec::new();
            let mut corner = (rng.coin(), rng.coin());
            for z in 0..floors {
                let (layer, end) = serpentine(w, d, z, corner, rng.coin());
                floor.extend(layer);
                corner = end;
            }
            let ring = ring(0, 0, w, d);
            let wall = (b - (w * d * floors) as f64).max(ring.len() as f64);
            let h = floors + layers(ring.len() as i64, wall);
            climbing_rings(&ring, floors, h, split, rng, floor)
        }
        Family::DoubleTube => {
            let (w, d) = (
                rng.range(lo.max(7), hi.max(7)),
                rng.range(lo.max(7), hi.max(7)),
            );
            let outer = ring(0, 0, w, d);
            let inner = ring(2, 2, w - 4, d - 4);
            let h = layers((outer.len() + inner.len()) as i64, b);
            let mut rings = [outer, inner];
            if rng.coin() {
                rings.swap(0, 1);
            }
            rings
                .iter()
                .flat_map(|r| climbing_rings(r, 0, h, false, rng, Vec::new()))
                .collect()
        }
        Family::LWall => {
            let (a, c) = (rng.range(lo, hi), rng.range(lo, hi));
            // From the end of the x arm to the corner, then along y.
            let mut path: Vec<(i64, i64)> = (0..a).rev().map(|x| (x, 0)).collect();
            path.extend((1..c).map(|y| (0, y)));
            let h = layers(path.len() as i64, b);
            climbing_paths(&path, h, split, rng)
        }
        Family::TWall => {
            let a = rng.range(lo.max(5), hi.max(5));
            let stem = rng.range((lo / 2).max(2), hi);
            let j = rng.range(1, a - 2);
            // One piece runs from a bar's end through the junction down the stem; the other
            // is the rest of the bar. Either half of the bar may take the junction.
            let left: Vec<(i64, i64)> = (0..=j).map(|x| (x, 0)).collect();
            let right: Vec<(i64, i64)> = (j + 1..a).rev().map(|x| (x, 0)).collect();
            let (mut through, rest) = if rng.coin() {
                (left, right)
            } else {
                let through: Vec<_> = (j..a).rev().map(|x| (x, 0)).collect();
                (through, (0..j).map(|x| (x, 0)).collect())
            };
            through.extend((1..=stem).map(|y| (j, y)));
            let h = layers(a + stem, b);
            let mut pieces = [through, rest];
            if rng.coin() {
                pieces.swap(0, 1);
            }
            pieces
                .iter()
                .flat_map(|p| climbing_paths(p, h, false, rng))
                .collect()
        }
    }
}

/// The blocks of a w x d rectangle's rim at (x0, y0), in order around it.
fn ring(x0: i64, y0: i64, w: i64, d: i64) -> Vec<(i64, i64)> {
    let mut out: Vec<(i64, i64)> = (0..w).map(|x| (x0 + x, y0)).collect();
    out.extend((1..d).map(|y| (x0 + w - 1, y0 + y)));
    out.extend((0..w - 1).rev().map(|x| (x0 + x, y0 + d - 1)));
    out.extend((1..d - 1).rev().map(|y| (x0, y0 + y)));
    out
}

/// A w x d layer at height z walked in rows from `corner` (x at its end when .0, y at its
/// end when .1), rows along x when `along_x`; the layer and the corner it ends at.
fn serpentine(
    w: i64,
    d: i64,
    z: i64,
    corner: (bool, bool),
    along_x: bool,
) -> (Vec<Block>, (bool, bool)) {
    let (rows, len) = if along_x { (d, w) } else { (w, d) };
    let (row_end, mut col_end) = if along_x {
        (corner.1, corner.0)
    } else {
        (corner.0, corner.1)
    };
    let mut out = Vec::new();
    for r in 0..rows {
        let row = if row_end { rows - 1 - r } else { r };
        for c in 0..len {
            let col = if col_end { len - 1 - c } else { c };
            let (x, y) = if along_x { (col, row) } else { (row, col) };
            out.push([x, y, z]);
        }
        col_end = !col_end;
    }
    let [x, y, _] = *out.last().expect("a layer has blocks");
    (out, (x == w - 1, y == d - 1))
}

/// A ring walked up from layer `from` to `to` (exclusive), after `first` (blocks of the
/// first fragment so far, ending below the ring or empty). Each layer starts above where
/// the one below ended and sets off either way at random; with `split`, a second weld
/// path may take over at a random layer, starting anywhere on the ring.
fn climbing_rings(
    ring: &[(i64, i64)],
    from: i64,
    to: i64,
    split: bool,
    rng: &mut Rng,
    first: Vec<Block>,
) -> Vec<Vec<Block>> {
    let n = ring.len();
    let mut pos = match first.last() {
        Some(&[x, y, _]) => ring
            .iter()
            .position(|&p| p == (x, y))
            .expect("a floor ends on its rim"),
        None => rng.below(n),
    };
    let take_over = (split && rng.coin() && to - from >= 2).then(|| rng.range(from + 1, to - 1));
    let mut fragments = vec![first];
    for z in from..to {
        if Some(z) == take_over {
            fragments.push(Vec::new());
            pos = rng.below(n);
        }
        let step = if rng.coin() { 1 } else { n - 1 };
        let fragment = fragments.last_mut().expect("one at least");
        for i in 0..n {
            let (x, y) = ring[(pos + i * step) % n];
            fragment.push([x, y, z]);
        }
        pos = (pos + (n - 1) * step) % n;
    }
    fragments.retain(|f| !f.is_empty());
    fragments
}

/// An open path walked up `h` layers: each layer back over the one below (the only way
/// up from its end), from a random end; with `split`, a second weld path may take over at
/// a random layer, from either end.
fn climbing_paths(path: &[(i64, i64)], h: i64, split: bool, rng: &mut Rng) -> Vec<Vec<Block>> {
    let take_over = (split && rng.coin() && h >= 2).then(|| rng.range(1, h - 1));
    let mut forward = rng.coin();
    let mut fragments = vec![Vec::new()];
    for z in 0..h {
        if Some(z) == take_over {
            fragments.push(Vec::new());
            forward = rng.coin();
        }
        let fragment = fragments.last_mut().expect("one at least");
        let layer = path.iter().map(|&(x, y)| [x, y, z]);
        if forward {
            fragment.extend(layer);
        } else {
            fragment.extend(layer.rev());
        }
        forward = !forward;
    }
    fragments
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_ring_goes_round_once() {
        let r = ring(0, 0, 4, 3);
        assert_eq!(r.len(), 2 * (4 + 3) - 4);
        for i in 0..r.len() {
            let (a, b) = (r[i], r[(i + 1) % r.len()]);
            assert_eq!((a.0 - b.0).abs() + (a.1 - b.1).abs(), 1, "{a:?} -> {b:?}");
        }
    }

    #[test]
    fn a_serpentine_covers_its_layer_and_says_where_it_ends() {
        for corner in [(false, false), (true, false), (false, true), (true, true)] {
            for along_x in [false, true] {
                for (w, d) in [(3, 4), (4, 4), (5, 3)] {
                    let (layer, end) = serpentine(w, d, 0, corner, along_x);
                    assert_eq!(layer.len() as i64, w * d);
                    let first = layer[0];
                    assert_eq!((first[0] == w - 1, first[1] == d - 1), corner);
                    let last = layer[layer.len() - 1];
                    assert_eq!((last[0] == w - 1, last[1] == d - 1), end);
                    assert!(last[0] == 0 || last[0] == w - 1);
                    assert!(last[1] == 0 || last[1] == d - 1);
                }
            }
        }
    }
}
