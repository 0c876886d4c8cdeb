//! The layer's thermal model and trails: torch positions, heat loads, the time schedule
//! of a trail and its objective.
//!
//! Time is discrete (the process time step). Welding segment s takes `weld_steps(s)`
//! steps; during step k of n the torch is at the midpoint of the k-th n-th of the segment,
//! so a segment welded backwards meets the same positions in reverse order. A
//! deadheading move takes `transit_steps` steps with the arc off. All trails are scored
//! over one horizon (all weld steps plus the longest possible deadheading per move),
//! shorter trails cooling with the arc off until the horizon, so trails compare fairly.
//! Objective: Σ over steps n = 1..H and mesh nodes i of |T_i^n − T_target| (K·steps).

use nalgebra::Point3;
use serde::Serialize;

use super::fem::{Heat, Matrices};
use super::format::{dist, Layer};
use super::mesh::Mesh;
use waam_motion::toolpath::WeldPass;

/// One weld of a segment in a trail.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
pub struct Move {
    pub segment: usize,
    /// Welded from the segment's second node to its first.
    pub reversed: bool,
    /// A deadheading move (arc off) leads to this weld.
    pub deadhead_before: bool,
}

impl Move {
    /// Directed segment d (segment d / 2, reversed when d is odd), without deadheading.
    pub fn directed(d: usize) -> Move {
        Move {
            segment: d / 2,
            reversed: d % 2 == 1,
            deadhead_before: false,
        }
    }
}

/// A trail: the segments in weld order with directions; deadheading between sub-trails.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Trail {
    pub moves: Vec<Move>,
}

/// What the torch does in one time step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum StepKind {
    /// Welding at torch position index `position` on move `move_index`.
    Weld { position: usize, move_index: usize },
    /// Deadheading towards move `move_index` (arc off).
    Transit { move_index: usize },
    /// After the trail, cooling until the common horizon (arc off).
    Cool,
}

/// The assembled model of a layer, ready to score trails.
#[derive(Debug, Clone)]
pub struct Model {
    pub layer: Layer,
    pub mesh: Mesh,
    pub heat: Heat,
    /// Torch positions (mm): segment s owns positions offset[s] .. offset[s] + steps[s].
    pub positions: Vec<[f64; 2]>,
    pub offset: Vec<usize>,
    pub steps: Vec<usize>,
    /// Heat load of each torch position: (mesh node, ∫ q φ_i with lumped mass).
    pub loads: Vec<Vec<(usize, f64)>>,
    /// The minimum number of deadheading moves (Chinese-postman bound).
    pub deadheads: usize,
    /// Time steps every trail is scored over.
    pub horizon: usize,
    /// Steps of the longest possible deadheading move (the layer's bounding-box diagonal).
    pub longest_transit: usize,
    /// Initial deviation from ambient (K): the smallest over the mesh nodes.
    pub initial: f64,
    /// Initial deviation from ambient (K) at every mesh node: the layer's `initial_c`
    /// everywhere, or the heat a part's layer below left ([`Model::set_initial_field`]).
    pub initial_field: Vec<f64>,
    /// Target minus ambient (K).
    pub target: f64,
}

impl Model {
    pub fn new(layer: &Layer) -> Result<Model, crate::ModelError> {
        Model::with_mesh(layer, Mesh::new(layer))
    }

    pub fn with_mesh(layer: &Layer, mesh: Mesh) -> Result<Model, crate::ModelError> {
        let mats = Matrices::assemble(
            &mesh,
            layer.material.diffusivity_mm2_s,
            layer.material.robin_mm_s,
        );
        let heat = Heat::new(&mats, layer.process.time_step_s)?;
        let mut positions = Vec::new();
        let mut offset = Vec::new();
        let mut steps = Vec::new();
        for s in 0..layer.segments.len() {
            let n = layer.weld_steps(s);
            let [a, b] = layer.segments[s];
            let (pa, pb) = (layer.point(a), layer.point(b));
            offset.push(positions.len());
            steps.push(n);
            for k in 0..n {
                let t = (k as f64 + 0.5) / n as f64;
                positions.push([pa[0] + t * (pb[0] - pa[0]), pa[1] + t * (pb[1] - pa[1])]);
            }
        }
        let reach = layer.source.radii_mm.last().copied().unwrap_or(0.0);
        let loads = positions
            .iter()
            .map(|&p| {
                (0..mesh.points.len())
                    .filter_map(|i| {
                        let r = dist(p, mesh.points[i]);
                        (r <= reach)
                            .then(|| (i, heat.lumped_mass[i] * layer.source.rate_at(r)))
                            .filter(|&(_, f)| f > 0.0)
                    })
                    .collect()
            })
            .collect();
        let deadheads = min_deadheads(layer);
        let weld: usize = steps.iter().sum();
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for n in &layer.nodes {
            lo = [lo[0].min(n.x), lo[1].min(n.y)];
            hi = [hi[0].max(n.x), hi[1].max(n.y)];
        }
        let diag = dist(lo, hi);
        let transit_step = layer.process.transit_speed_mm_s * layer.process.time_step_s;
        let longest_transit = ((diag / transit_step).ceil() as usize).max(1);
        let mesh_len = mesh.points.len();
        Ok(Model {
            layer: layer.clone(),
            mesh,
            heat,
            positions,
            offset,
            steps,
            loads,
            deadheads,
            horizon: weld + deadheads * longest_transit,
            longest_transit,
            initial: layer.temperatures.initial_c - layer.temperatures.ambient_c,
            initial_field: vec![
                layer.temperatures.initial_c - layer.temperatures.ambient_c;
                mesh_len
            ],
            target: layer.temperatures.target_c - layer.temperatures.ambient_c,
        })
    }

    /// Starts the layer from a given field (deviation from ambient, K, one value per mesh
    /// node), e.g. the heat the layer below left. The search's bound stays valid: it
    /// needs only the smallest initial value to be ≥ 0 for its overshoot part.
    pub fn set_initial_field(&mut self, u: Vec<f64>) {
        assert_eq!(u.len(), self.heat.len(), "one initial value per mesh node");
        self.initial = u.iter().copied().fold(f64::INFINITY, f64::min);
        self.initial_field = u;
    }

    /// Node a move starts from and the node it ends at.
    pub fn ends(&self, m: &Move) -> (usize, usize) {
        let [a, b] = self.layer.segments[m.segment];
        if m.reversed {
            (b, a)
        } else {
            (a, b)
        }
    }

    /// Torch position index of step k (0-based) of a move.
    pub fn position(&self, m: &Move, k: usize) -> usize {
        let n = self.steps[m.segment];
        self.offset[m.segment] + if m.reversed { n - 1 - k } else { k }
    }

    /// The step-by-step schedule of a trail, padded with cooling to the horizon.
    pub fn schedule(&self, trail: &Trail) -> Vec<StepKind> {
        let mut out = Vec::with_capacity(self.horizon);
        let mut at: Option<usize> = None;
        for (i, m) in trail.moves.iter().enumerate() {
            let (start, end) = self.ends(m);
            if let (Some(prev), true) = (at, m.deadhead_before) {
                for _ in 0..self.layer.transit_steps(prev, start) {
                    out.push(StepKind::Transit { move_index: i });
                }
            }
            for k in 0..self.steps[m.segment] {
                out.push(StepKind::Weld {
                    position: self.position(m, k),
                    move_index: i,
                });
            }
            at = Some(end);
        }
        while out.len() < self.horizon {
            out.push(StepKind::Cool);
        }
        out
    }

    /// Deviation of one field (deviation from ambient) from the target, summed over nodes.
    pub fn deviation(&self, u: &[f64]) -> f64 {
        let t = self.target;
        u.iter().map(|&x| (x - t).abs()).sum()
    }

    /// Scores a trail: the objective, and, when `record` is given, every step's field.
    pub fn simulate(&self, trail: &Trail, mut record: Option<&mut Vec<Vec<f64>>>) -> f64 {
        let mut u = self.initial_field.clone();
        let mut total = 0.0;
        for kind in self.schedule(trail) {
            let load: &[(usize, f64)] = match kind {
                StepKind::Weld { position, .. } => &self.loads[position],
                _ => &[],
            };
            self.heat.step(&mut u, load);
            total += self.deviation(&u);
            if let Some(rec) = record.as_deref_mut() {
                rec.push(u.clone());
            }
        }
        total
    }

    /// Checks that a trail welds every segment once, in connected runs, with the minimum
    /// number of deadheading moves.
    pub fn check_trail(&self, trail: &Trail) -> Result<(), crate::ModelError> {
        let mut used = vec![false; self.layer.segments.len()];
        let mut at = None;
        let mut deadheads = 0;
        for (i, m) in trail.moves.iter().enumerate() {
            if m.segment >= used.len() || std::mem::replace(&mut used[m.segment], true) {
                return Err(crate::ModelError(format!(
                    "move {i}: segment {} welded twice or unknown",
                    m.segment
                )));
            }
            let (start, end) = self.ends(m);
            match at {
                Some(_) if m.deadhead_before => deadheads += 1,
                Some(prev) if prev != start => {
                    return Err(crate::ModelError(format!(
                        "move {i}: starts away from the torch without deadheading"
                    )))
                }
                _ => {}
            }
            at = Some(end);
        }
        if let Some(s) = used.iter().position(|u| !u) {
            return Err(crate::ModelError(format!(
                "{} is never welded",
                self.layer.segment_name(s)
            )));
        }
        if deadheads != self.deadheads {
            return Err(crate::ModelError(format!(
                "{deadheads} deadheading moves, the minimum is {}",
                self.deadheads
            )));
        }
        Ok(())
    }

    /// The trail as weld passes for the toolpath builder: each pass is the torch path
    /// (mm, layer frame, z = 0) from arc-on to arc-off, one point per time-step boundary
    /// (so every layer node on the way is a point); deadheading lies between passes, where
    /// the toolpath turns the arc off.
    pub fn passes(&self, trail: &Trail) -> Vec<WeldPass> {
        self.passes_with_segments(trail).0
    }

    /// [`Model::passes`], and for every point of every pass the segment welded to reach it
    /// (a pass's first point: the segment it starts), to name walls in motion errors.
    pub fn passes_with_segments(&self, trail: &Trail) -> (Vec<WeldPass>, Vec<Vec<usize>>) {
        let mut passes: Vec<WeldPass> = Vec::new();
        let mut segments: Vec<Vec<usize>> = Vec::new();
        for m in &trail.moves {
            let (a, b) = self.ends(m);
            let (pa, pb) = (self.layer.point(a), self.layer.point(b));
            if m.deadhead_before || passes.is_empty() {
                passes.push(WeldPass {
                    points_mm: vec![Point3::new(pa[0], pa[1], 0.0)],
                });
                segments.push(vec![m.segment]);
            }
            let pass = passes.last_mut().expect("a pass was just started");
            let owners = segments.last_mut().expect("a pass was just started");
            let n = self.steps[m.segment];
            for k in 1..=n {
                owners.push(m.segment);
                let t = k as f64 / n as f64;
                pass.points_mm.push(Point3::new(
                    pa[0] + t * (pb[0] - pa[0]),
                    pa[1] + t * (pb[1] - pa[1]),
                    0.0,
                ));
            }
        }
        (passes, segments)
    }
}

/// Minimum deadheading moves to weld every segment once: per connected component, half
/// its odd-degree nodes (at least one trail), all trails but the first need a move.
pub fn min_deadheads(layer: &Layer) -> usize {
    let all: Vec<usize> = (0..layer.segments.len()).collect();
    trails_needed(layer, &all, None).saturating_sub(1)
}

/// Fewest trails that weld the given segments, when one trail may continue from `at`
/// (a trail already running there costs nothing to extend).
pub fn trails_needed(layer: &Layer, segments: &[usize], at: Option<usize>) -> usize {
    let n = layer.nodes.len();
    let mut parent: Vec<usize> = (0..n).collect();
    fn find(p: &mut [usize], mut x: usize) -> usize {
        while p[x] != x {
            p[x] = p[p[x]];
            x = p[x];
        }
        x
    }
    let mut degree = vec![0usize; n];
    for &s in segments {
        let [a, b] = layer.segments[s];
        degree[a] += 1;
        degree[b] += 1;
        let (ra, rb) = (find(&mut parent, a), find(&mut parent, b));
        parent[ra] = rb;
    }
    let mut odd = vec![0usize; n];
    let mut has_edges = vec![false; n];
    for (v, &deg) in degree.iter().enumerate() {
        if deg > 0 {
            let r = find(&mut parent, v);
            has_edges[r] = true;
            odd[r] += deg % 2;
        }
    }
    let total: usize = (0..n)
        .filter(|&r| has_edges[r])
        .map(|r| (odd[r] / 2).max(1))
        .sum();
    match at {
        Some(v) if degree[v] > 0 => {
            let r = find(&mut parent, v);
            if degree[v] % 2 == 1 || odd[r] == 0 {
                total - 1
            } else {
                total
            }
        }
        _ => total,
    }
}
