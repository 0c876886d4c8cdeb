//! Thick-wall parts: a stack of layers (sliced from a mesh, [`crate::slice`]) planned one
//! after the other, each starting from the heat the layer below left
//! (`docs/layer-format.md`, "Parts").
//!
//! Heat carried over: the field at the end of layer n's horizon cools with the arc off for
//! the interlayer time in layer n's own model (its Robin loss stands for the conduction
//! into the layers below); every mesh node of layer n+1 then starts at the temperature of
//! the nearest mesh node of layer n (ambient where layer n has no material within a wall
//! width). Layer n+1 is searched from that field ([`Model::set_initial_field`]).
//!
//! Variation: layer n+1 may not start where layer n started, nor deadhead between the same
//! two places (either way) as layer n, so arc starts and stops do not pile up on one spot
//! of the part. Places are matched by position (within a quarter wall width). These are
//! constraints of the search; when they leave no trail, the layer is planned without them
//! and its result says so.

use std::path::Path;
use std::time::Duration;

use serde::{Deserialize, Serialize};
use thiserror::Error;

use super::format::{dist, Layer};
use super::model::{Model, Trail};
use super::search::{search, SearchOptions, SearchResult};

/// The manifest `part.yaml` of a sliced part directory.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PartManifest {
    /// The part's name.
    pub name: String,
    /// Where the layers came from (the mesh file as given to `waam layer slice`).
    pub source: String,
    pub layer_height_mm: f64,
    /// Bottom layer first.
    pub layers: Vec<ManifestLayer>,
}

/// One layer of a part manifest.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ManifestLayer {
    /// The layer file, relative to the manifest's directory.
    pub file: String,
    /// Height of the layer's cutting plane (mm); the torch welds the layer at this z.
    pub z_mm: f64,
}

/// Why a part cannot be planned.
#[derive(Debug, Error)]
pub enum PartError {
    #[error("the part has no layers")]
    Empty,
    #[error("layer {index} ({name}): {message}")]
    Model {
        index: usize,
        name: String,
        message: String,
    },
    #[error("interlayer time: expected a finite number of seconds >= 0, got {0}")]
    Interlayer(f64),
    #[error("cannot read {path}: {message}")]
    Read { path: String, message: String },
}

impl PartManifest {
    /// Reads `DIR/part.yaml` and its layers (z and layer, bottom first).
    pub fn read_dir(dir: &Path) -> Result<(PartManifest, Vec<(f64, Layer)>), PartError> {
        let path = dir.join("part.yaml");
        let read_err = |p: &Path, m: String| PartError::Read {
            path: p.display().to_string(),
            message: m,
        };
        let text = std::fs::read_to_string(&path).map_err(|e| read_err(&path, e.to_string()))?;
        let manifest: PartManifest =
            serde_yaml::from_str(&text).map_err(|e| read_err(&path, e.to_string()))?;
        let mut layers = Vec::with_capacity(manifest.layers.len());
        for l in &manifest.layers {
            let p = dir.join(&l.file);
            let bytes = std::fs::read(&p).map_err(|e| read_err(&p, e.to_string()))?;
            let layer = Layer::from_bytes(&bytes).map_err(|e| read_err(&p, e.to_string()))?;
            layers.push((l.z_mm, layer));
        }
        Ok((manifest, layers))
    }
}

/// How to plan a part.
#[derive(Debug, Clone)]
pub struct PartOptions {
    /// Arc-off time between the end of one layer's horizon and the next layer's start (s).
    pub interlayer_s: f64,
    /// The search of every layer (its time limit applies per layer).
    pub search: SearchOptions,
    /// Forbid the layer below's start and deadheading moves (on by default).
    pub vary: bool,
}

impl Default for PartOptions {
    fn default() -> Self {
        PartOptions {
            interlayer_s: 2.0,
            search: SearchOptions {
                time_limit: Some(Duration::from_secs(10)),
                ..SearchOptions::default()
            },
            vary: true,
        }
    }
}

/// One planned layer of a part.
#[derive(Debug, Clone)]
pub struct PlannedLayer {
    pub z_mm: f64,
    /// The layer's model; its `initial_field` is the heat carried over from below.
    pub model: Model,
    pub result: SearchResult,
    /// The field (deviation from ambient, K) at the end of the layer's horizon.
    pub end_field: Vec<f64>,
    /// Nodes this layer was forbidden to start at, and node pairs it was forbidden to
    /// deadhead between (matched from the layer below).
    pub forbidden_starts: Vec<usize>,
    pub forbidden_deadheads: Vec<[usize; 2]>,
    /// False when the variation constraints left no trail and were dropped.
    pub varied: bool,
}

impl PlannedLayer {
    /// Node the trail starts at.
    pub fn start_node(&self) -> Option<usize> {
        self.result
            .trail
            .moves
            .first()
            .map(|m| self.model.ends(m).0)
    }

    /// Node the trail ends at.
    pub fn end_node(&self) -> Option<usize> {
        self.result.trail.moves.last().map(|m| self.model.ends(m).1)
    }

    /// The deadheading moves as (from, to) nodes.
    pub fn deadheads(&self) -> Vec<[usize; 2]> {
        deadhead_pairs(&self.model, &self.result.trail)
    }
}

/// The deadheading moves of a trail as (from, to) nodes.
pub fn deadhead_pairs(model: &Model, trail: &Trail) -> Vec<[usize; 2]> {
    let mut at = None;
    let mut out = Vec::new();
    for m in &trail.moves {
        let (a, b) = model.ends(m);
        if let (true, Some(prev)) = (m.deadhead_before, at) {
            out.push([prev, a]);
        }
        at = Some(b);
    }
    out
}

/// The field at the end of a trail's horizon (deviation from ambient, K).
pub fn end_field(model: &Model, trail: &Trail) -> Vec<f64> {
    let mut u = model.initial_field.clone();
    for kind in model.schedule(trail) {
        let load: &[(usize, f64)] = match kind {
            super::model::StepKind::Weld { position, .. } => &model.loads[position],
            _ => &[],
        };
        model.heat.step(&mut u, load);
    }
    u
}

/// The field `below` (on `from`'s mesh) after `seconds` of free cooling in `from`'s model,
/// carried onto `to`'s mesh: nearest mesh node within a wall width, else ambient (0).
pub fn carry(from: &Model, below: &[f64], seconds: f64, to: &Model) -> Vec<f64> {
    let mut u = below.to_vec();
    let steps = (seconds / from.heat.dt).round() as usize;
    for _ in 0..steps {
        from.heat.step(&mut u, &[]);
    }
    let reach = to.layer.wall_width_mm.max(from.layer.wall_width_mm);
    to.mesh
        .points
        .iter()
        .map(|&p| {
            let j = from.mesh.nearest(p);
            if dist(p, from.mesh.points[j]) <= reach {
                u[j]
            } else {
                0.0
            }
        })
        .collect()
}

/// Node of `to` at the position of node `v` of `from` (within a quarter wall width).
fn same_place(from: &Layer, v: usize, to: &Layer) -> Option<usize> {
    let p = from.point(v);
    (0..to.nodes.len()).find(|&k| dist(p, to.point(k)) <= 0.25 * to.wall_width_mm)
}

/// Plans every layer of a part, bottom first, calling `progress` after each.
pub fn plan_part(
    layers: &[(f64, Layer)],
    options: &PartOptions,
    mut progress: impl FnMut(usize, &PlannedLayer),
) -> Result<Vec<PlannedLayer>, PartError> {
    if layers.is_empty() {
        return Err(PartError::Empty);
    }
    if !(options.interlayer_s.is_finite() && options.interlayer_s >= 0.0) {
        return Err(PartError::Interlayer(options.interlayer_s));
    }
    let mut out: Vec<PlannedLayer> = Vec::with_capacity(layers.len());
    for (index, (z, layer)) in layers.iter().enumerate() {
        let mut model = Model::new(layer).map_err(|e| PartError::Model {
            index,
            name: layer.name.clone(),
            message: e.to_string(),
        })?;
        // Each layer before its search: a layer too large fails at once, not after minutes.
        crate::search::check_size(&model, &options.search).map_err(|e| PartError::Model {
            index,
            name: layer.name.clone(),
            message: e.to_string(),
        })?;
        let (mut starts, mut pairs) = (Vec::new(), Vec::new());
        if let Some(below) = out.last() {
            let u = carry(&below.model, &below.end_field, options.interlayer_s, &model);
            model.set_initial_field(u);
            if options.vary {
                let from = &below.model.layer;
                starts.extend(below.start_node().and_then(|v| same_place(from, v, layer)));
                for [a, b] in below.deadheads() {
                    if let (Some(a), Some(b)) =
                        (same_place(from, a, layer), same_place(from, b, layer))
                    {
                        pairs.push([a, b]);
                    }
                }
            }
        }
        let constrained = SearchOptions {
            forbidden_starts: starts.clone(),
            forbidden_deadheads: pairs.clone(),
            ..options.search.clone()
        };
        let mut result = search(&model, &constrained);
        let mut varied = true;
        if result.trail.moves.is_empty() {
            tracing::warn!(
                "layer {index} ({}): no trail avoids the layer below's start and \
                 deadheading moves; planned without that rule",
                layer.name
            );
            varied = false;
            result = search(&model, &options.search);
        }
        let end = end_field(&model, &result.trail);
        let planned = PlannedLayer {
            z_mm: *z,
            model,
            result,
            end_field: end,
            forbidden_starts: starts,
            forbidden_deadheads: pairs,
            varied,
        };
        progress(index, &planned);
        out.push(planned);
    }
    Ok(out)
}
