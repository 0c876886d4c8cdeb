//! The layer file format (`docs/layer-format.md`): nodes in mm, weld segments between
//! them, wall width, process, material, temperature and torch-source parameters.
//!
//! Reading is strict: unknown keys, wrong types and every broken rule give a
//! [`LayerError`] naming the key (with its line where the YAML parser knows it), the node
//! or the segment. Any byte string gives a result or an error, never a panic.

use std::collections::HashMap;

use serde::{Deserialize, Serialize};
use thiserror::Error;

/// Smallest angle (degrees) two walls may meet at: sharper corners cannot be meshed with
/// the junction fans used here, and real WAAM beads would fuse into one anyway.
pub const MIN_JUNCTION_ANGLE_DEG: f64 = 60.0;
/// Largest coordinate magnitude accepted (mm): a layer wider than 10 m is an input error.
pub const MAX_COORD_MM: f64 = 10_000.0;
/// Largest number of torch time steps in one layer (bounds memory of the precomputation).
pub const MAX_STEPS: usize = 20_000;
/// Largest number of segments.
pub const MAX_SEGMENTS: usize = 2_000;
/// Narrowest wall accepted (mm): the mesh merges points closer than 1e-5 mm, so walls
/// far thinner than a bead degenerate (and the FEM factorization fails).
pub const MIN_WALL_WIDTH_MM: f64 = 0.1;
/// Largest torch heating rate accepted (K/s); the paper's is 8000. Near f64's range the
/// temperatures overflow and every trail's objective becomes infinite.
pub const MAX_PEAK_K_S: f64 = 1e7;

/// A layer file that breaks a rule of the format.
#[derive(Debug, Error, PartialEq)]
pub enum LayerError {
    #[error("the layer file is not UTF-8 text (first bad byte at offset {0})")]
    NotUtf8(usize),
    #[error("{0}")]
    Yaml(String),
    #[error("{0}")]
    Rule(String),
}

fn rule(msg: impl Into<String>) -> LayerError {
    LayerError::Rule(msg.into())
}

/// One node of the layer graph: an intersection or end point of walls.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Node {
    pub id: String,
    pub x: f64,
    pub y: f64,
}

/// Process settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Process {
    /// Torch speed while welding (mm/s).
    pub weld_speed_mm_s: f64,
    /// Implicit-Euler time step (s); the torch advances weld_speed * time_step per step.
    pub time_step_s: f64,
    /// Torch speed while deadheading, arc off (mm/s).
    pub transit_speed_mm_s: f64,
    /// Uniform refinements of the base mesh (each splits every triangle in 4).
    #[serde(default)]
    pub mesh_refinement: u32,
}

/// Material constants of the 2-D heat equation dT/dt = a ΔT + q, -a dT/dn = b (T - T_amb).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Material {
    /// Thermal diffusivity a (mm²/s).
    pub diffusivity_mm2_s: f64,
    /// Robin (heat-transfer) coefficient b over the wall edges (mm/s).
    pub robin_mm_s: f64,
}

/// Temperatures in °C.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Temperatures {
    pub ambient_c: f64,
    pub initial_c: f64,
    pub target_c: f64,
}

/// The torch: a piecewise-constant radial (Goldak-type, flattened to 2-D) heat source.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Source {
    /// Peak heating rate q0 (K/s) at the torch centre.
    pub peak_k_s: f64,
    /// Outer radii of the rings (mm), strictly increasing.
    pub radii_mm: Vec<f64>,
    /// Fraction of q0 inside each ring (same length as radii_mm).
    pub weights: Vec<f64>,
}

impl Source {
    /// Heating rate (K/s) at distance r from the torch centre.
    pub fn rate_at(&self, r: f64) -> f64 {
        match self.radii_mm.iter().position(|&rad| r <= rad) {
            Some(i) => self.peak_k_s * self.weights[i],
            None => 0.0,
        }
    }
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawLayer {
    name: String,
    wall_width_mm: f64,
    nodes: Vec<Node>,
    segments: Vec<[String; 2]>,
    process: Process,
    material: Material,
    temperatures: Temperatures,
    source: Source,
}

/// A layer read and checked: the graph of weld segments and all model parameters.
#[derive(Debug, Clone)]
pub struct Layer {
    pub name: String,
    pub wall_width_mm: f64,
    pub nodes: Vec<Node>,
    /// Segments as pairs of node indices, in file order (segment i = file entry i).
    pub segments: Vec<[usize; 2]>,
    pub process: Process,
    pub material: Material,
    pub temperatures: Temperatures,
    pub source: Source,
}

impl Layer {
    /// Reads a layer file given as raw bytes.
    pub fn from_bytes(bytes: &[u8]) -> Result<Layer, LayerError> {
        let text = std::str::from_utf8(bytes).map_err(|e| LayerError::NotUtf8(e.valid_up_to()))?;
        Layer::parse(text)
    }

    /// Parses and checks layer-file text.
    pub fn parse(text: &str) -> Result<Layer, LayerError> {
        if text.trim().is_empty() {
            return Err(rule("the layer file is empty: expected a YAML mapping"));
        }
        waam_part::yaml::check(text).map_err(|e| LayerError::Yaml(e.to_string()))?;
        let raw: RawLayer =
            serde_yaml::from_str(text).map_err(|e| LayerError::Yaml(format!("{e}")))?;
        let layer = Layer::from_raw(raw)?;
        layer.check_geometry()?;
        layer.check_size()?;
        Ok(layer)
    }

    fn from_raw(raw: RawLayer) -> Result<Layer, LayerError> {
        if raw.name.trim().is_empty() {
            return Err(rule("name: must not be empty"));
        }
        positive("wall_width_mm", raw.wall_width_mm)?;
        if raw.wall_width_mm < MIN_WALL_WIDTH_MM {
            return Err(rule(format!(
                "wall_width_mm: {:e} mm is not a weld bead width (min {MIN_WALL_WIDTH_MM})",
                raw.wall_width_mm
            )));
        }
        if raw.wall_width_mm > 1000.0 {
            return Err(rule(format!(
                "wall_width_mm: {} mm is not a weld bead width (max 1000)",
                raw.wall_width_mm
            )));
        }
        if raw.nodes.is_empty() {
            return Err(rule("nodes: the layer has no nodes"));
        }
        let mut index: HashMap<&str, usize> = HashMap::new();
        for (i, n) in raw.nodes.iter().enumerate() {
            if n.id.trim().is_empty() {
                return Err(rule(format!("nodes[{i}]: id must not be empty")));
            }
            for (axis, v) in [("x", n.x), ("y", n.y)] {
                if !v.is_finite() || v.abs() > MAX_COORD_MM {
                    return Err(rule(format!(
                        "nodes[{i}] (id {}): {axis} = {v} is not a finite coordinate within ±{MAX_COORD_MM} mm",
                        n.id
                    )));
                }
            }
            if let Some(j) = index.insert(n.id.as_str(), i) {
                return Err(rule(format!(
                    "nodes[{i}]: id {} is used twice (also nodes[{j}])",
                    n.id
                )));
            }
        }
        if raw.segments.is_empty() {
            return Err(rule("segments: the layer has no segments"));
        }
        if raw.segments.len() > MAX_SEGMENTS {
            return Err(rule(format!(
                "segments: {} segments, at most {MAX_SEGMENTS} are supported",
                raw.segments.len()
            )));
        }
        let mut segments = Vec::with_capacity(raw.segments.len());
        let mut seen: HashMap<[usize; 2], usize> = HashMap::new();
        for (i, [a, b]) in raw.segments.iter().enumerate() {
            let lookup = |id: &String| {
                index.get(id.as_str()).copied().ok_or_else(|| {
                    rule(format!(
                        "segments[{i}] ({a} -> {b}): node {id} is not in 'nodes'"
                    ))
                })
            };
            let (ia, ib) = (lookup(a)?, lookup(b)?);
            if ia == ib {
                return Err(rule(format!(
                    "segments[{i}] ({a} -> {b}): a segment needs two different nodes"
                )));
            }
            let key = [ia.min(ib), ia.max(ib)];
            if let Some(j) = seen.insert(key, i) {
                return Err(rule(format!(
                    "segments[{i}] ({a} -> {b}): the same wall as segments[{j}]"
                )));
            }
            segments.push([ia, ib]);
        }
        let mut used = vec![false; raw.nodes.len()];
        for s in &segments {
            used[s[0]] = true;
            used[s[1]] = true;
        }
        if let Some(i) = used.iter().position(|u| !u) {
            return Err(rule(format!(
                "nodes[{i}] (id {}): the node is on no segment",
                raw.nodes[i].id
            )));
        }
        let p = &raw.process;
        positive("process.weld_speed_mm_s", p.weld_speed_mm_s)?;
        positive("process.time_step_s", p.time_step_s)?;
        positive("process.transit_speed_mm_s", p.transit_speed_mm_s)?;
        if p.mesh_refinement > 3 {
            return Err(rule(format!(
                "process.mesh_refinement: {} is too fine (0 to 3)",
                p.mesh_refinement
            )));
        }
        positive("material.diffusivity_mm2_s", raw.material.diffusivity_mm2_s)?;
        non_negative("material.robin_mm_s", raw.material.robin_mm_s)?;
        let t = &raw.temperatures;
        for (key, v) in [
            ("temperatures.ambient_c", t.ambient_c),
            ("temperatures.initial_c", t.initial_c),
            ("temperatures.target_c", t.target_c),
        ] {
            if !v.is_finite() || !(-273.15..=10_000.0).contains(&v) {
                return Err(rule(format!(
                    "{key}: {v} is not a temperature between -273.15 and 10000 °C"
                )));
            }
        }
        let s = &raw.source;
        non_negative("source.peak_k_s", s.peak_k_s)?;
        if s.peak_k_s > MAX_PEAK_K_S {
            return Err(rule(format!(
                "source.peak_k_s: {:e} K/s is beyond {MAX_PEAK_K_S:e} K/s (the temperatures would overflow)",
                s.peak_k_s
            )));
        }
        if s.radii_mm.is_empty() {
            return Err(rule("source.radii_mm: give at least one ring radius"));
        }
        if s.radii_mm.len() != s.weights.len() {
            return Err(rule(format!(
                "source.weights: {} weights for {} radii (one weight per ring)",
                s.weights.len(),
                s.radii_mm.len()
            )));
        }
        let mut last = 0.0;
        for (i, &r) in s.radii_mm.iter().enumerate() {
            positive(&format!("source.radii_mm[{i}]"), r)?;
            if r <= last {
                return Err(rule(format!(
                    "source.radii_mm[{i}]: {r} must be larger than the previous radius {last}"
                )));
            }
            last = r;
        }
        for (i, &w) in s.weights.iter().enumerate() {
            non_negative(&format!("source.weights[{i}]"), w)?;
        }
        Ok(Layer {
            name: raw.name,
            wall_width_mm: raw.wall_width_mm,
            nodes: raw.nodes,
            segments,
            process: raw.process,
            material: raw.material,
            temperatures: raw.temperatures,
            source: raw.source,
        })
    }

    /// Position of node i (mm).
    pub fn point(&self, i: usize) -> [f64; 2] {
        [self.nodes[i].x, self.nodes[i].y]
    }

    /// Length of segment s (mm).
    pub fn length(&self, s: usize) -> f64 {
        let [a, b] = self.segments[s];
        dist(self.point(a), self.point(b))
    }

    /// Human-readable name of segment s, as in error messages: `segments[3] (B -> C)`.
    pub fn segment_name(&self, s: usize) -> String {
        let [a, b] = self.segments[s];
        format!(
            "segments[{s}] ({} -> {})",
            self.nodes[a].id, self.nodes[b].id
        )
    }

    /// Segments incident to each node.
    pub fn incidence(&self) -> Vec<Vec<usize>> {
        let mut inc = vec![Vec::new(); self.nodes.len()];
        for (s, &[a, b]) in self.segments.iter().enumerate() {
            inc[a].push(s);
            inc[b].push(s);
        }
        inc
    }

    /// Torch steps to weld segment s: its length over the step length, at least one.
    pub fn weld_steps(&self, s: usize) -> usize {
        let step = self.process.weld_speed_mm_s * self.process.time_step_s;
        ((self.length(s) / step).round() as usize).max(1)
    }

    /// Steps of a deadheading move from node a to node b (arc off, at least one).
    pub fn transit_steps(&self, a: usize, b: usize) -> usize {
        let step = self.process.transit_speed_mm_s * self.process.time_step_s;
        ((dist(self.point(a), self.point(b)) / step).ceil() as usize).max(1)
    }

    /// Walls must meet at a node at no less than [`MIN_JUNCTION_ANGLE_DEG`], be long enough
    /// for their junctions, and keep a wall width apart where they do not meet.
    fn check_geometry(&self) -> Result<(), LayerError> {
        let w = self.wall_width_mm;
        for v in 0..self.nodes.len() {
            let angles = self.sorted_angles(v);
            for k in 0..angles.len() {
                if angles.len() < 2 {
                    break;
                }
                let gap = angle_gap(&angles, k).to_degrees();
                if gap < MIN_JUNCTION_ANGLE_DEG - 1e-9 {
                    return Err(rule(format!(
                        "{} and {} meet at node {} at {gap:.1}°, less than the {MIN_JUNCTION_ANGLE_DEG}° minimum",
                        self.segment_name(angles[k].1),
                        self.segment_name(angles[(k + 1) % angles.len()].1),
                        self.nodes[v].id
                    )));
                }
            }
        }
        for s in 0..self.segments.len() {
            let need = self.junction_depth(self.segments[s][0])
                + self.junction_depth(self.segments[s][1])
                + 0.25 * w;
            if self.length(s) < need {
                return Err(rule(format!(
                    "{}: {:.3} mm is too short for walls {w} mm wide (needs at least {need:.3} mm)",
                    self.segment_name(s),
                    self.length(s)
                )));
            }
        }
        for s in 0..self.segments.len() {
            for t in s + 1..self.segments.len() {
                let [a, b] = self.segments[s];
                let [c, d] = self.segments[t];
                if a == c || a == d || b == c || b == d {
                    continue;
                }
                let gap =
                    segment_distance(self.point(a), self.point(b), self.point(c), self.point(d));
                if gap < w - 1e-9 {
                    return Err(rule(format!(
                        "{} and {} come {gap:.3} mm close without sharing a node (walls need {w} mm; split a wall at the junction)",
                        self.segment_name(s),
                        self.segment_name(t)
                    )));
                }
            }
        }
        Ok(())
    }

    /// Bounds the time steps before anything is sized by them. Counted in f64: a tiny
    /// speed or time step makes the counts overflow any integer (1e-300 did).
    fn check_size(&self) -> Result<(), LayerError> {
        let p = &self.process;
        let weld_step = p.weld_speed_mm_s * p.time_step_s;
        let steps: f64 = (0..self.segments.len())
            .map(|s| (self.length(s) / weld_step).round().max(1.0))
            .sum();
        if steps.is_nan() || steps > MAX_STEPS as f64 {
            return Err(rule(format!(
                "process: the layer needs {steps:.3e} weld time steps, more than {MAX_STEPS}; \
                 raise weld_speed_mm_s ({:e}) or time_step_s ({:e})",
                p.weld_speed_mm_s, p.time_step_s
            )));
        }
        // The longest deadheading move crosses the layer's bounding box.
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for n in &self.nodes {
            lo = [lo[0].min(n.x), lo[1].min(n.y)];
            hi = [hi[0].max(n.x), hi[1].max(n.y)];
        }
        let transit = (dist(lo, hi) / (p.transit_speed_mm_s * p.time_step_s)).ceil();
        if transit.is_nan() || transit > MAX_STEPS as f64 {
            return Err(rule(format!(
                "process: a deadheading move across the layer takes {transit:.3e} time steps, \
                 more than {MAX_STEPS}; raise transit_speed_mm_s ({:e}) or time_step_s ({:e})",
                p.transit_speed_mm_s, p.time_step_s
            )));
        }
        Ok(())
    }

    /// Unit direction of segment s pointing away from its end node v.
    pub fn direction_from(&self, s: usize, v: usize) -> [f64; 2] {
        let [a, b] = self.segments[s];
        let other = if a == v { b } else { a };
        let (p, q) = (self.point(v), self.point(other));
        let l = dist(p, q);
        [(q[0] - p[0]) / l, (q[1] - p[1]) / l]
    }

    /// How far from node v the straight wall strips end and the junction patch begins (mm):
    /// half the wall width times cot(half the smallest angle between walls at v), so that
    /// neighbouring strips touch exactly at their inner corners (w/2 at a 90° joint, 0.29 w
    /// at a 120° joint), but at least w/4; a dead end gets w/2.
    pub fn junction_depth(&self, v: usize) -> f64 {
        let w = self.wall_width_mm;
        let angles = self.sorted_angles(v);
        if angles.len() < 2 {
            return 0.5 * w;
        }
        let min_gap = (0..angles.len())
            .map(|k| angle_gap(&angles, k))
            .fold(f64::INFINITY, f64::min);
        (0.5 * w / (0.5 * min_gap).tan()).max(0.25 * w)
    }

    /// Directions (radians) of the segments leaving node v, sorted counter-clockwise, with
    /// the segment of each.
    pub fn sorted_angles(&self, v: usize) -> Vec<(f64, usize)> {
        let mut angles: Vec<(f64, usize)> = self
            .segments
            .iter()
            .enumerate()
            .filter(|(_, seg)| seg.contains(&v))
            .map(|(s, _)| {
                let d = self.direction_from(s, v);
                (d[1].atan2(d[0]), s)
            })
            .collect();
        angles.sort_by(|a, b| a.0.total_cmp(&b.0));
        angles
    }
}

/// Counter-clockwise angle from entry k to entry k+1 (cyclic) of sorted angles, in (0, 2π].
pub fn angle_gap(angles: &[(f64, usize)], k: usize) -> f64 {
    let n = angles.len();
    let mut gap = angles[(k + 1) % n].0 - angles[k].0;
    if k + 1 == n {
        gap += 2.0 * std::f64::consts::PI;
    }
    gap
}

fn positive(key: &str, v: f64) -> Result<(), LayerError> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(rule(format!(
            "{key}: expected a finite number > 0, got {v}"
        )))
    }
}

fn non_negative(key: &str, v: f64) -> Result<(), LayerError> {
    if v.is_finite() && v >= 0.0 {
        Ok(())
    } else {
        Err(rule(format!(
            "{key}: expected a finite number >= 0, got {v}"
        )))
    }
}

/// Euclidean distance of two points.
pub fn dist(p: [f64; 2], q: [f64; 2]) -> f64 {
    ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2)).sqrt()
}

fn point_segment_distance(p: [f64; 2], a: [f64; 2], b: [f64; 2]) -> f64 {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let len2 = dx * dx + dy * dy;
    let t = if len2 > 0.0 {
        (((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    dist(p, [a[0] + t * dx, a[1] + t * dy])
}

/// Distance between two closed segments (zero when they cross).
fn segment_distance(a: [f64; 2], b: [f64; 2], c: [f64; 2], d: [f64; 2]) -> f64 {
    let cross = |o: [f64; 2], p: [f64; 2], q: [f64; 2]| {
        (p[0] - o[0]) * (q[1] - o[1]) - (p[1] - o[1]) * (q[0] - o[0])
    };
    let (d1, d2) = (cross(a, b, c), cross(a, b, d));
    let (d3, d4) = (cross(c, d, a), cross(c, d, b));
    if d1 * d2 < 0.0 && d3 * d4 < 0.0 {
        return 0.0;
    }
    point_segment_distance(a, c, d)
        .min(point_segment_distance(b, c, d))
        .min(point_segment_distance(c, a, b))
        .min(point_segment_distance(d, a, b))
}
