//! The per-part constants of the model ([`ThermalModel`]), the t8/5 thresholds and the
//! step counts of the spec's time tests.

use waam_part::graph::{WeldGraph, NONE};
use waam_part::{Block, Part, ThermalParams, Window};

use crate::graph::{GraphError, GraphModel, NodeGeometry};
use crate::kernel::Simd;
use crate::violation::Crossing;

/// Above this a block is hot again and its t8/5 counter restarts, °C.
pub const HOT_C: f64 = 800.0;
/// Below this a block has finished its t8/5 cooling, °C.
pub const WARM_C: f64 = 500.0;
/// Tolerance of every t8/5 comparison, seconds.
pub const TOLERANCE_S: f64 = 1e-9;

/// The least t8/5 count c (whole steps) with `c as f64 * dt > max_s + TOLERANCE_S`, the
/// spec's test of a maximum: c ↦ c·dt rounds monotonically (c < 2^53 converts exactly), so
/// the test holds exactly for the counts from this one on. `u64::MAX` where no count
/// reaches it.
pub(crate) fn steps_beyond(max_s: f64, dt: f64) -> u64 {
    let limit = max_s + TOLERANCE_S;
    let over = |c: u64| c as f64 * dt > limit;
    let guess = limit / dt;
    // Also a NaN limit, which no count passes.
    if guess.is_nan() || guess >= 2f64.powi(52) {
        return u64::MAX;
    }
    let mut c = guess.floor().max(0.0) as u64;
    while c > 0 && over(c - 1) {
        c -= 1;
    }
    while !over(c) {
        c += 1;
    }
    c
}

/// Rounds a non-negative step count, halves away from zero.
pub(crate) fn round_steps(x: f64) -> u64 {
    (x + 0.5).floor() as u64
}

/// The per-part constants of the model, computed once and shared by every simulation.
#[derive(Debug, Clone)]
pub struct ThermalModel {
    pub params: ThermalParams,
    pub dt: f64,
    pub transit_steps: u64,
    pub cooldown_steps: u64,
    /// (ambient + 273.15)^4.
    pub(crate) ambient_k4: f64,
    pub(crate) faces: Vec<[u32; 6]>,
    pub(crate) on_substrate: Vec<bool>,
    /// Per block: its window, if any.
    pub(crate) windows: Vec<Option<Window>>,
    pub(crate) blocks: Vec<Block>,
    /// The z = 0 blocks are the first `substrate_slots` (blocks are sorted by z).
    pub(crate) substrate_slots: usize,
    /// Per slot its ±y / ±z neighbour slots, and where four in a row are consecutive: see
    /// [`neighbour_runs`].
    pub(crate) near: Vec<[u32; 4]>,
    pub(crate) runs: Vec<u8>,
    pub(crate) simd: Simd,
    /// A graph part's model (`docs/graph-thermal-model.md`): then the simulation steps it
    /// instead of the block model, and `faces` are all `NONE`.
    pub(crate) graph: Option<GraphModel>,
}

/// The ±y / ±z neighbour slots of every slot as the part lays them out, and per slot `s`
/// the bits d (-y, +y, -z, +z) where slots `s..s + 4` have the consecutive neighbours
/// `near[s][d] + 0..4`. In a part whose layers repeat and whose rows span alike, most runs
/// are consecutive: a vector kernel then reads the four neighbours with one load instead of
/// a gather (slow on some CPUs) and keeps the slot's own value where the neighbour is not
/// welded. A missing neighbour gets a stand-in slot that continues the run of the slot
/// before it (its value is never used, only its place).
pub(crate) fn neighbour_runs(faces: &[[u32; 6]]) -> (Vec<[u32; 4]>, Vec<u8>) {
    let n = faces.len();
    let mut near = vec![[0u32; 4]; n];
    for s in 0..n {
        for d in 0..4 {
            near[s][d] = match faces[s][d + 2] {
                NONE => match s.checked_sub(1).map(|p| near[p][d] as usize + 1) {
                    Some(next) if next < n => next as u32,
                    _ => s as u32,
                },
                j => j,
            };
        }
    }
    let runs = (0..n)
        .map(|s| {
            (0..4)
                .filter(|&d| s + 4 <= n && (1..4).all(|j| near[s + j][d] == near[s][d] + j as u32))
                .fold(0u8, |bits, d| bits | 1 << d)
        })
        .collect();
    (near, runs)
}

impl ThermalModel {
    /// The model of `part`: the block model, or for a graph part the graph model of its
    /// nodes and contacts.
    ///
    /// # Panics
    /// If `part` is a graph part the graph model rejects (see [`ThermalModel::try_new`],
    /// which callers that take graph parts from outside use; `BeadPart::parse` already
    /// rejects most such parts).
    pub fn new(part: &Part, graph: &WeldGraph) -> ThermalModel {
        match ThermalModel::try_new(part, graph) {
            Ok(model) => model,
            Err(e) => panic!("graph part {:?}: {e}", part.name),
        }
    }

    /// [`ThermalModel::new`], with the graph model's error for a graph part whose numbers
    /// it cannot take (a node whose volume would take more than `MAX_STEPS` deposit steps,
    /// say, which the part file's rules alone do not exclude).
    pub fn try_new(part: &Part, graph: &WeldGraph) -> Result<ThermalModel, GraphError> {
        let params = part.thermal;
        let dt = params.dt();
        // The step reads the ±x neighbours of slot i at i ∓ 1 and the substrate blocks as a
        // prefix: both need the part's (z, y, x) order.
        assert!(
            part.blocks()
                .windows(2)
                .all(|w| (w[0][2], w[0][1], w[0][0]) < (w[1][2], w[1][1], w[1][0])),
            "part blocks must be sorted by (z, y, x)"
        );
        let mut windows = vec![None; part.len()];
        for &(i, w) in part.windows() {
            windows[i] = Some(w);
        }
        let faces: Vec<[u32; 6]> = (0..part.len()).map(|i| graph.faces(i)).collect();
        let (near, runs) = neighbour_runs(&faces);
        let graph_model = match part.bead_part() {
            None => None,
            Some(beads) => {
                let nodes: Vec<NodeGeometry> = beads
                    .nodes
                    .iter()
                    .map(|d| NodeGeometry {
                        volume: d.volume_mm3,
                        surface: d.surface_mm2,
                        substrate: d.substrate_mm2,
                    })
                    .collect();
                // File order: the doc's order of summation.
                let contacts: Vec<(u32, u32, f64)> = beads
                    .contacts
                    .iter()
                    .map(|c| (c.a as u32, c.b as u32, c.area_mm2))
                    .collect();
                let [w, h] = beads.bead_mm;
                Some(GraphModel::new(params, w, h, &nodes, &contacts)?)
            }
        };
        Ok(ThermalModel {
            params,
            dt,
            transit_steps: round_steps(params.transit_time_s / dt),
            cooldown_steps: round_steps(params.max_cooldown_s / dt),
            // powf, not powi: the same libm pow the reference checker uses.
            ambient_k4: (params.ambient_c + 273.15).powf(4.0),
            faces,
            on_substrate: part.blocks().iter().map(|b| b[2] == 0).collect(),
            windows,
            blocks: part.blocks().to_vec(),
            substrate_slots: part.blocks().partition_point(|b| b[2] == 0),
            near,
            runs,
            simd: Simd::detect(),
            graph: graph_model,
        })
    }

    /// The graph model of a graph part (`None` for a block part).
    pub fn graph(&self) -> Option<&GraphModel> {
        self.graph.as_ref()
    }

    /// Euler steps that follow the deposit of block (node) `i`: `substeps`, or for a graph
    /// part the node's [`GraphModel::deposit_steps`].
    pub fn deposit_steps(&self, i: usize) -> u64 {
        match &self.graph {
            Some(g) => g.deposit_steps(i),
            None => self.params.substeps as u64,
        }
    }

    /// The same model stepped by `simd` (the scalar kernel if the CPU lacks it).
    pub fn with_simd(mut self, simd: Simd) -> ThermalModel {
        self.simd = if simd <= Simd::detect() {
            simd
        } else {
            Simd::Scalar
        };
        self
    }

    /// The step kernel in use.
    pub fn simd(&self) -> Simd {
        self.simd
    }

    /// Number of blocks of the part.
    pub fn len(&self) -> usize {
        self.faces.len()
    }

    /// True for a model of no blocks.
    pub fn is_empty(&self) -> bool {
        self.faces.is_empty()
    }

    /// The window of block `i`, if it has one.
    pub fn window(&self, i: usize) -> Option<Window> {
        self.windows[i]
    }

    /// True when some block has a t8/5 window. Without one no plan can break a window, so
    /// every valid plan is feasible with an infinite margin.
    pub fn has_windows(&self) -> bool {
        self.windows.iter().any(Option::is_some)
    }

    /// The same model with every window narrowed by `margin` seconds on both sides: a
    /// plan keeps these windows exactly when every t8/5 value keeps that margin.
    pub fn narrowed(&self, margin: f64) -> ThermalModel {
        let mut m = self.clone();
        for w in m.windows.iter_mut().flatten() {
            w.min_s += margin;
            w.max_s -= margin;
        }
        m
    }

    /// The smallest distance of any t8/5 value to its window's bounds (+inf without
    /// windows): the plan's worst-case margin.
    pub fn margin(&self, crossings: &[Crossing]) -> f64 {
        crossings
            .iter()
            .filter_map(|c| {
                self.windows[c.block].map(|w| (c.t85_s - w.min_s).min(w.max_s - c.t85_s))
            })
            .fold(f64::INFINITY, f64::min)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// The integer threshold of a maximum is the spec's float test, count for count.
        #[test]
        fn steps_beyond_is_the_float_test(
            max_s in prop_oneof![0.0f64..400.0, -5.0f64..0.0, Just(f64::INFINITY)],
            dt in 1e-4f64..2.0,
        ) {
            let c = steps_beyond(max_s, dt);
            let over = |c: u64| c as f64 * dt > max_s + TOLERANCE_S;
            if c == u64::MAX {
                prop_assert!(!over(1 << 52));
            } else {
                prop_assert!(over(c));
                prop_assert!(c == 0 || !over(c - 1));
                for k in c.saturating_sub(50)..c + 50 {
                    prop_assert_eq!(over(k), k >= c);
                }
            }
        }
    }
}
