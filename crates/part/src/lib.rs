//! Parts: the block file format of `shared/spec/part-format.md`.
//!
//! A part is a set of equal blocks on an integer grid. [`Part::parse`] enforces every
//! rule of the spec and answers each broken one with a [`PartError`] that names the key,
//! the line or the block. Blocks are kept sorted by (z, y, x): that order is the block
//! index used everywhere else (weld graph, thermal model, planner).
//!
//! Beside the part: [`ThermalParams`] (its `thermal:` keys), the [`graph::WeldGraph`] of
//! allowed moves, the [`plan::Plan`] format with its validity rules, and [`writer`], which
//! writes a part back as a part file.
//!
//! Graph parts ([`beads::BeadPart`]): a part as deposits along weld beads with their
//! contacts, for round parts that a grid of blocks cannot follow.

pub mod beads;
pub mod graph;
mod params;
pub mod plan;
pub mod writer;
/// The bounded YAML check (crate `waam-yaml`), run before a part file is parsed.
pub use waam_yaml as yaml;

pub use beads::{
    is_bead_part, Bead, BeadPart, BeadPartError, Contact, ContactKind, Deposit, GraphInvalid,
    GraphPlan, GraphPlanReadError, WeldMoves,
};
pub use params::{ThermalParams, ThermalParamsError, MAX_STEPS};

use std::collections::HashMap;
use std::fmt;

use rustc_hash::FxHashMap;

use serde_yaml::Value;
use thiserror::Error;

/// Integer grid coordinates of a block: x, y, z (z = layer, 0 rests on the substrate).
pub type Block = [i64; 3];

/// Formats a block as `[x,y,z]`, the way every message of the project names one.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BlockDisplay(pub Block);

impl fmt::Display for BlockDisplay {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "[{},{},{}]", self.0[0], self.0[1], self.0[2])
    }
}

/// A t8/5 cooling-time window: the time a block spends between 800 and 500 °C.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Window {
    pub min_s: f64,
    pub max_s: f64,
}

/// A part file that breaks a rule of the part format.
#[derive(Debug, Error, PartialEq)]
pub enum PartError {
    #[error("the part file is not UTF-8 text (first bad byte at offset {0})")]
    NotUtf8(usize),
    #[error("not valid YAML: {0}")]
    Yaml(String),
    #[error("{0}")]
    Rule(String),
}

fn rule(msg: impl Into<String>) -> PartError {
    PartError::Rule(msg.into())
}

/// A part read from a file or a message, with its blocks sorted by (z, y, x).
#[derive(Debug, Clone)]
pub struct Part {
    pub name: String,
    /// Block pitch along x, y, z in millimetres (bead width, bead width, layer height).
    pub block_mm: [f64; 3],
    /// Position of the min corner of block (0,0,0) in the part frame, millimetres.
    pub origin_mm: [f64; 3],
    /// k: the most weld paths (arc starts) a plan may use.
    pub max_fragments: usize,
    blocks: Vec<Block>,
    // Fx, not SipHash: the weld graph looks up six neighbours of every block.
    index: FxHashMap<Block, usize>,
    /// (block index, window), sorted by block index; one window per block.
    windows: Vec<(usize, Window)>,
    pub thermal: ThermalParams,
    /// Non-fatal remarks made while reading (e.g. a window overriding an earlier one).
    pub warnings: Vec<String>,
    /// For a graph part ([`Part::of_beads`]): its deposits, contacts and moves; the blocks
    /// are then stand-ins `[i, 0, layer]` (i: the deposit's rank in its layer) that give
    /// every stage its layers and indices, and the geometry comes from here.
    beads: Option<std::sync::Arc<BeadPart>>,
}

/// Farthest a part may reach from the part frame's origin along any axis, mm (1 km: far
/// beyond any cell, near enough that positions keep their sub-micrometre precision).
pub const MAX_EXTENT_MM: f64 = 1e6;

const TOP_KEYS: [&str; 8] = [
    "name",
    "block_mm",
    "origin_mm",
    "max_fragments",
    "layers",
    "blocks",
    "t85",
    "thermal",
];

impl Part {
    /// Reads a part file given as raw bytes (any bytes: garbage gives an error, never a panic).
    pub fn from_bytes(bytes: &[u8]) -> Result<Part, PartError> {
        let text = std::str::from_utf8(bytes).map_err(|e| PartError::NotUtf8(e.valid_up_to()))?;
        Part::parse(text)
    }

    /// Parses part-file text.
    pub fn parse(text: &str) -> Result<Part, PartError> {
        yaml::check(text).map_err(|e| PartError::Yaml(e.to_string()))?;
        let doc: Value = serde_yaml::from_str(text).map_err(|e| PartError::Yaml(e.to_string()))?;
        let map = match doc {
            Value::Mapping(map) => map,
            Value::Null => return Err(rule("the part file is empty: expected a YAML mapping")),
            _ => return Err(rule("a part file must be a YAML mapping")),
        };
        let mut fields: HashMap<&'static str, Value> = HashMap::new();
        for (key, value) in map {
            let name = match &key {
                Value::String(s) => TOP_KEYS.iter().find(|k| **k == s.as_str()).copied(),
                _ => None,
            };
            match name {
                Some(k) => {
                    fields.insert(k, value);
                }
                None => {
                    return Err(rule(format!(
                        "unknown top-level key {} (allowed: {})",
                        describe_key(&key),
                        TOP_KEYS.join(", ")
                    )))
                }
            }
        }
        for key in ["name", "block_mm", "max_fragments"] {
            if !fields.contains_key(key) {
                return Err(rule(format!("missing required key '{key}'")));
            }
        }
        let name = match &fields["name"] {
            Value::String(s) => s.clone(),
            Value::Number(n) => n.to_string(),
            other => {
                return Err(rule(format!(
                    "name: expected free text, got {}",
                    describe(other)
                )))
            }
        };
        let block_mm = real_triple(&fields["block_mm"], "block_mm")?;
        if block_mm.iter().any(|&v| v <= 0.0) {
            return Err(rule(format!(
                "block_mm: entries must be > 0, got {block_mm:?}"
            )));
        }
        let origin_mm = match fields.get("origin_mm") {
            Some(v) => real_triple(v, "origin_mm")?,
            None => [0.0; 3],
        };
        let max_fragments = match fields["max_fragments"].as_i64() {
            Some(k) if k >= 1 && !fields["max_fragments"].is_f64() => k as usize,
            _ => {
                return Err(rule(format!(
                    "max_fragments: expected an integer >= 1, got {}",
                    describe(&fields["max_fragments"])
                )))
            }
        };
        let blocks = match (fields.get("layers"), fields.get("blocks")) {
            (Some(layers), None) => parse_layers(layers)?,
            (None, Some(blocks)) => parse_blocks(blocks)?,
            _ => return Err(rule("give exactly one of 'layers' or 'blocks'")),
        };
        let mut part = Part::from_blocks(name, block_mm, origin_mm, max_fragments, blocks)?;
        if let Some(t85) = fields.get("t85") {
            part.parse_windows(t85)?;
        }
        part.thermal = ThermalParams::from_yaml(fields.get("thermal")).map_err(|e| rule(e.0))?;
        Ok(part)
    }

    /// Builds a part from block coordinates (any order; duplicates and negative
    /// coordinates are refused), with no windows and default thermal constants.
    pub fn from_blocks(
        name: String,
        block_mm: [f64; 3],
        origin_mm: [f64; 3],
        max_fragments: usize,
        mut blocks: Vec<Block>,
    ) -> Result<Part, PartError> {
        if blocks.is_empty() {
            return Err(rule("the part has no blocks"));
        }
        if max_fragments == 0 {
            return Err(rule("max_fragments: expected an integer >= 1, got 0"));
        }
        if let Some(b) = blocks.iter().find(|b| b.iter().any(|&c| c < 0)) {
            return Err(rule(format!(
                "block {}: negative coordinate",
                BlockDisplay(*b)
            )));
        }
        // The spec asks only for finite, positive pitches; a part whose blocks lie beyond
        // any cell (block_mm: 1e308 passes that) would be planned and only fail in the
        // motion stage, or overflow there: refused here, naming the axis.
        for axis in 0..3 {
            let top = blocks.iter().map(|b| b[axis]).max().unwrap_or(0);
            let far = origin_mm[axis] + (top as f64 + 1.0) * block_mm[axis];
            if !(origin_mm[axis].abs() <= MAX_EXTENT_MM && far.abs() <= MAX_EXTENT_MM) {
                return Err(rule(format!(
                    "block_mm / origin_mm: the part reaches {far:e} mm along {} (origin {:e} mm, \
                     pitch {:e} mm); a part must lie within ±{MAX_EXTENT_MM:e} mm",
                    ["x", "y", "z"][axis],
                    origin_mm[axis],
                    block_mm[axis]
                )));
            }
        }
        blocks.sort_by_key(|b| (b[2], b[1], b[0]));
        if let Some(w) = blocks.windows(2).find(|w| w[0] == w[1]) {
            return Err(rule(format!("duplicate block {}", BlockDisplay(w[0]))));
        }
        let index = blocks.iter().enumerate().map(|(i, b)| (*b, i)).collect();
        Ok(Part {
            name,
            block_mm,
            origin_mm,
            max_fragments,
            blocks,
            index,
            windows: Vec::new(),
            thermal: ThermalParams::default(),
            warnings: Vec::new(),
            beads: None,
        })
    }

    /// The planning view of a graph part: deposit i is block i, a stand-in `[rank in its
    /// layer, 0, layer]`, with the graph part's windows and thermal constants. Deposits
    /// must be listed layer by layer (as [`BeadPart::parse`] and the slicer give them).
    pub fn of_beads(beads: BeadPart) -> Result<Part, PartError> {
        if let Some(i) =
            (1..beads.nodes.len()).find(|&i| beads.nodes[i].layer < beads.nodes[i - 1].layer)
        {
            return Err(rule(format!(
                "nodes: node {i} (layer {}) comes after a node of layer {}: list nodes layer by layer",
                beads.nodes[i].layer,
                beads.nodes[i - 1].layer
            )));
        }
        let mut rank = 0i64;
        let blocks: Vec<Block> = beads
            .nodes
            .iter()
            .enumerate()
            .map(|(i, d)| {
                rank = match i {
                    0 => 0,
                    _ if beads.nodes[i - 1].layer == d.layer => rank + 1,
                    _ => 0,
                };
                [rank, 0, d.layer as i64]
            })
            .collect();
        let [w, h] = beads.bead_mm;
        let mut part = Part::from_blocks(
            beads.name.clone(),
            [w, w, h],
            [0.0, 0.0, beads.base_z_mm],
            beads.max_fragments,
            blocks,
        )?;
        part.windows = beads.windows.clone();
        part.windows.sort_by_key(|&(i, _)| i);
        part.thermal = beads.thermal;
        part.warnings = beads.warnings.clone();
        part.beads = Some(std::sync::Arc::new(beads));
        Ok(part)
    }

    /// Replaces k, the most weld paths a plan may use (a graph part's too, so that it is
    /// written and checked with the new k).
    pub fn set_max_fragments(&mut self, k: usize) {
        self.max_fragments = k;
        if let Some(beads) = &mut self.beads {
            std::sync::Arc::make_mut(beads).max_fragments = k;
        }
    }

    /// How messages name deposit `i`: `node 12` in a graph part, `block [x,y,z]` else.
    pub fn deposit_name(&self, i: usize) -> String {
        match self.beads {
            Some(_) => format!("node {i}"),
            None => format!("block {}", BlockDisplay(self.block(i))),
        }
    }

    /// The graph part behind this part, if it is one.
    pub fn bead_part(&self) -> Option<&BeadPart> {
        self.beads.as_deref()
    }

    /// Number of blocks.
    pub fn len(&self) -> usize {
        self.blocks.len()
    }

    /// A part always has at least one block; this is here for clippy's sake.
    pub fn is_empty(&self) -> bool {
        self.blocks.is_empty()
    }

    /// All blocks, sorted by (z, y, x); a block's position here is its index.
    pub fn blocks(&self) -> &[Block] {
        &self.blocks
    }

    /// The coordinates of block `i`.
    pub fn block(&self, i: usize) -> Block {
        self.blocks[i]
    }

    /// The index of the block at `b`, if the part has one there.
    pub fn index_of(&self, b: Block) -> Option<usize> {
        self.index.get(&b).copied()
    }

    /// The index of the block at `b + d`, if the part has one there (no overflow).
    pub fn neighbour(&self, b: Block, d: [i64; 3]) -> Option<usize> {
        let n = [
            b[0].checked_add(d[0])?,
            b[1].checked_add(d[1])?,
            b[2].checked_add(d[2])?,
        ];
        self.index_of(n)
    }

    /// t8/5 windows as (block index, window), sorted by block index.
    pub fn windows(&self) -> &[(usize, Window)] {
        &self.windows
    }

    /// The window of block `i`, if it has one.
    pub fn window_of(&self, i: usize) -> Option<Window> {
        self.windows
            .binary_search_by_key(&i, |(b, _)| *b)
            .ok()
            .map(|k| self.windows[k].1)
    }

    /// Sets (or replaces) the window of block `i`.
    pub fn set_window(&mut self, i: usize, window: Window) {
        match self.windows.binary_search_by_key(&i, |(b, _)| *b) {
            Ok(k) => self.windows[k].1 = window,
            Err(k) => self.windows.insert(k, (i, window)),
        }
    }

    /// Number of layers (1 + the highest z).
    pub fn layers(&self) -> i64 {
        // Saturating: the spec bounds no coordinate, and z = i64::MAX is a valid (odd) part.
        self.blocks.last().map_or(0, |b| b[2].saturating_add(1))
    }

    /// Centre of block `b` in the part frame, millimetres (of a graph part: its deposit's
    /// centre).
    pub fn centre_mm(&self, b: Block) -> [f64; 3] {
        if let (Some(beads), Some(i)) = (&self.beads, self.index_of(b)) {
            return beads.nodes[i].centre_mm;
        }
        std::array::from_fn(|d| self.origin_mm[d] + (b[d] as f64 + 0.5) * self.block_mm[d])
    }

    /// How far the point `p` (part frame, mm) lies from block `i`'s volume, mm: 0 inside or
    /// on it. A block is its cell of `block_mm`; a graph part's deposit is, in its bead's
    /// own coordinates, the box of its arc-length interval along the centre line, W across
    /// and its layer's height.
    pub fn distance_to_mm(&self, i: usize, p: [f64; 3]) -> f64 {
        let outside = |v: f64, lo: f64, hi: f64| (lo - v).max(v - hi).max(0.0);
        if let Some(beads) = &self.beads {
            let node = &beads.nodes[i];
            let bead = &beads.beads[node.bead];
            let (at, off) = bead.project_mm([p[0], p[1]]);
            // A closed bead's arc length wraps at its length.
            let length = bead.length_mm();
            let along = if bead.closed {
                [at - length, at, at + length]
                    .map(|a| outside(a, node.from_mm, node.to_mm))
                    .into_iter()
                    .fold(f64::INFINITY, f64::min)
            } else {
                outside(at, node.from_mm, node.to_mm)
            };
            let [w, h] = beads.bead_mm;
            let across = (off - w / 2.0).max(0.0);
            let lo = beads.base_z_mm + node.layer as f64 * h;
            let up = outside(p[2], lo, lo + h);
            return (along * along + across * across + up * up).sqrt();
        }
        let b = self.blocks[i];
        let d: [f64; 3] = std::array::from_fn(|d| {
            let lo = self.origin_mm[d] + b[d] as f64 * self.block_mm[d];
            outside(p[d], lo, lo + self.block_mm[d])
        });
        (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()
    }

    fn parse_windows(&mut self, t85: &Value) -> Result<(), PartError> {
        let entries = match t85 {
            Value::Sequence(s) => s,
            Value::Null => return Ok(()),
            other => {
                return Err(rule(format!(
                    "t85: expected a list of windows, got {}",
                    describe(other)
                )))
            }
        };
        for (w, entry) in entries.iter().enumerate() {
            let at = format!("t85[{w}]");
            let Value::Mapping(map) = entry else {
                return Err(rule(format!(
                    "{at}: expected a mapping, got {}",
                    describe(entry)
                )));
            };
            for key in map.keys() {
                if !matches!(key.as_str(), Some("block" | "box" | "min_s" | "max_s")) {
                    return Err(rule(format!(
                        "{at}: unknown key {} (allowed: block, box, min_s, max_s)",
                        describe_key(key)
                    )));
                }
            }
            let (block, bx) = (map.get("block"), map.get("box"));
            if block.is_some() == bx.is_some() {
                return Err(rule(format!("{at}: name exactly one of 'block' or 'box'")));
            }
            let bound = |key: &str| -> Result<f64, PartError> {
                let v = map
                    .get(key)
                    .ok_or_else(|| rule(format!("{at}: missing {key}")))?;
                finite(v).ok_or_else(|| {
                    rule(format!(
                        "{at}.{key}: expected a finite number, got {}",
                        describe(v)
                    ))
                })
            };
            let (min_s, max_s) = (bound("min_s")?, bound("max_s")?);
            if !(0.0 <= min_s && min_s <= max_s) {
                return Err(rule(format!(
                    "{at}: need 0 <= min_s <= max_s, got min_s={min_s} max_s={max_s}"
                )));
            }
            let targets: Vec<usize> = if let Some(b) = block {
                let b = int_triple(b, &format!("{at}.block"))?;
                vec![self.index_of(b).ok_or_else(|| {
                    rule(format!(
                        "{at}.block: no block {} in the part",
                        BlockDisplay(b)
                    ))
                })?]
            } else {
                let bx = bx.expect("one of block/box is present");
                let Value::Mapping(m) = bx else {
                    return Err(rule(format!(
                        "{at}.box: expected a mapping with exactly 'min' and 'max'"
                    )));
                };
                let keys_ok = m.len() == 2 && m.contains_key("min") && m.contains_key("max");
                if !keys_ok {
                    return Err(rule(format!(
                        "{at}.box: expected a mapping with exactly 'min' and 'max'"
                    )));
                }
                let lo = int_triple(&m["min"], &format!("{at}.box.min"))?;
                let hi = int_triple(&m["max"], &format!("{at}.box.max"))?;
                let inside = |b: &Block| (0..3).all(|d| lo[d] <= b[d] && b[d] <= hi[d]);
                let t: Vec<usize> = (0..self.len())
                    .filter(|&i| inside(&self.blocks[i]))
                    .collect();
                if t.is_empty() {
                    return Err(rule(format!("{at}.box: holds no block of the part")));
                }
                t
            };
            for i in targets {
                if self.window_of(i).is_some() {
                    self.warnings.push(format!(
                        "{at} overrides an earlier window on block {}",
                        BlockDisplay(self.blocks[i])
                    ));
                }
                self.set_window(i, Window { min_s, max_s });
            }
        }
        Ok(())
    }
}

fn parse_layers(layers: &Value) -> Result<Vec<Block>, PartError> {
    let list = match layers {
        Value::Sequence(s) if !s.is_empty() => s,
        other => {
            return Err(rule(format!(
                "layers: expected a non-empty list of strings (one per layer), got {}",
                describe(other)
            )))
        }
    };
    let mut blocks = Vec::new();
    for (z, layer) in list.iter().enumerate() {
        let Value::String(text) = layer else {
            return Err(rule(format!(
                "layers[{z}]: expected a string, got {}",
                describe(layer)
            )));
        };
        for (y, line) in text.split('\n').enumerate() {
            for (x, ch) in line.trim_end_matches('\r').chars().enumerate() {
                match ch {
                    '#' => blocks.push([x as i64, y as i64, z as i64]),
                    '.' | ' ' => {}
                    _ => {
                        return Err(rule(format!(
                            "layers[{z}] line {} column {}: unexpected character {ch:?} \
                             (use '#', '.' or ' ')",
                            y + 1,
                            x + 1
                        )))
                    }
                }
            }
        }
    }
    Ok(blocks)
}

fn parse_blocks(blocks: &Value) -> Result<Vec<Block>, PartError> {
    let Value::Sequence(list) = blocks else {
        return Err(rule(format!(
            "blocks: expected a list of [x, y, z], got {}",
            describe(blocks)
        )));
    };
    let mut out = Vec::with_capacity(list.len());
    let mut seen = HashMap::with_capacity(list.len());
    for (i, b) in list.iter().enumerate() {
        let t = int_triple(b, &format!("blocks[{i}]"))?;
        if t.iter().any(|&c| c < 0) {
            return Err(rule(format!(
                "blocks[{i}]: negative coordinate in block {}",
                BlockDisplay(t)
            )));
        }
        if let Some(first) = seen.insert(t, i) {
            return Err(rule(format!(
                "blocks[{i}]: duplicate block {} (first at blocks[{first}])",
                BlockDisplay(t)
            )));
        }
        out.push(t);
    }
    Ok(out)
}

/// A finite number (integer or float, not a bool).
pub(crate) fn finite(v: &Value) -> Option<f64> {
    v.as_f64().filter(|x| x.is_finite())
}

fn int_triple(v: &Value, what: &str) -> Result<Block, PartError> {
    let bad = || {
        rule(format!(
            "{what}: expected a list of 3 integers, got {}",
            describe(v)
        ))
    };
    let Value::Sequence(s) = v else {
        return Err(bad());
    };
    if s.len() != 3 {
        return Err(bad());
    }
    let mut out = [0i64; 3];
    for (d, c) in s.iter().enumerate() {
        out[d] = match c {
            Value::Number(n) if n.is_i64() => n.as_i64().expect("checked is_i64"),
            _ => return Err(bad()),
        };
    }
    Ok(out)
}

fn real_triple(v: &Value, what: &str) -> Result<[f64; 3], PartError> {
    let bad = || {
        rule(format!(
            "{what}: expected a list of 3 finite numbers, got {}",
            describe(v)
        ))
    };
    let Value::Sequence(s) = v else {
        return Err(bad());
    };
    if s.len() != 3 {
        return Err(bad());
    }
    let mut out = [0.0; 3];
    for (d, c) in s.iter().enumerate() {
        out[d] = finite(c).ok_or_else(bad)?;
    }
    Ok(out)
}

/// A short, bounded rendering of a YAML value for error messages.
pub(crate) fn describe(v: &Value) -> String {
    let text = match v {
        Value::Null => "nothing (null)".to_string(),
        Value::Bool(b) => format!("the boolean {b}"),
        Value::Number(n) => format!("the number {n}"),
        Value::String(s) => format!("the text {s:?}"),
        Value::Sequence(s) => format!("a list of {} item(s)", s.len()),
        Value::Mapping(m) => format!("a mapping of {} key(s)", m.len()),
        Value::Tagged(t) => format!("a value tagged {}", t.tag),
    };
    truncate(text, 80)
}

/// A mapping key for error messages: strings as 'key', anything else described.
pub(crate) fn describe_key(k: &Value) -> String {
    match k {
        Value::String(s) => truncate(format!("'{s}'"), 80),
        other => describe(other),
    }
}

fn truncate(mut s: String, max: usize) -> String {
    if s.chars().count() > max {
        s = s.chars().take(max).collect::<String>() + "…";
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    fn err(text: &str) -> String {
        Part::parse(text).unwrap_err().to_string()
    }

    const HEAD: &str = "name: t\nblock_mm: [6, 6, 2.5]\nmax_fragments: 2\n";

    #[test]
    fn layers_are_read_line_by_line_and_sorted() {
        let p = Part::parse(&format!(
            "{HEAD}layers:\n  - |\n    ##\n    .#\n  - |\n    .#\n"
        ))
        .unwrap();
        assert_eq!(p.blocks(), &[[0, 0, 0], [1, 0, 0], [1, 1, 0], [1, 0, 1]]);
        assert_eq!(p.layers(), 2);
        assert_eq!(p.index_of([1, 1, 0]), Some(2));
    }

    #[test]
    fn every_rule_is_named() {
        assert!(err("").contains("empty"));
        assert!(err("- 1\n- 2\n").contains("must be a YAML mapping"));
        assert!(
            err(&format!("{HEAD}blocks: [[0,0,0]]\nmax_fragment: 2\n")).contains("'max_fragment'")
        );
        assert!(err("name: t\nmax_fragments: 1\nblocks: [[0,0,0]]\n").contains("'block_mm'"));
        assert!(err(HEAD).contains("exactly one of 'layers' or 'blocks'"));
        assert!(
            err(&format!("{HEAD}layers: ['#']\nblocks: [[0,0,0]]\n")).contains("exactly one of")
        );
        assert!(err(&format!("{HEAD}blocks: [[0,0,0], [0,0,0]]\n"))
            .contains("blocks[1]: duplicate block [0,0,0]"));
        assert!(err(&format!("{HEAD}blocks: [[0,-1,0]]\n")).contains("blocks[0]: negative"));
        assert!(err(&format!("{HEAD}blocks: [[0,0.5,0]]\n")).contains("blocks[0]"));
        assert!(err(&format!("{HEAD}layers: ['#x']\n")).contains("layers[0] line 1 column 2"));
        assert!(
            err("name: t\nblock_mm: [6, 6, 2.5]\nmax_fragments: 0\nblocks: [[0,0,0]]\n")
                .contains("max_fragments")
        );
        assert!(
            err("name: t\nblock_mm: [6, 0, 2.5]\nmax_fragments: 1\nblocks: [[0,0,0]]\n")
                .contains("block_mm: entries must be > 0")
        );
        assert!(
            err("name: t\nblock_mm: [6, .nan, 2.5]\nmax_fragments: 1\nblocks: [[0,0,0]]\n")
                .contains("block_mm: expected a list of 3 finite numbers")
        );
        let b = format!("{HEAD}blocks: [[0,0,0], [1,0,0]]\n");
        assert!(err(&format!("{b}t85: [{{block: [0,0,0], box: {{min: [0,0,0], max: [1,0,0]}}, min_s: 1, max_s: 2}}]\n"))
            .contains("t85[0]: name exactly one"));
        assert!(err(&format!("{b}t85: [{{min_s: 1, max_s: 2}}]\n"))
            .contains("t85[0]: name exactly one"));
        assert!(err(&format!(
            "{b}t85: [{{block: [5,0,0], min_s: 1, max_s: 2}}]\n"
        ))
        .contains("t85[0].block: no block [5,0,0]"));
        assert!(err(&format!(
            "{b}t85: [{{box: {{min: [3,3,3], max: [4,4,4]}}, min_s: 1, max_s: 2}}]\n"
        ))
        .contains("t85[0].box: holds no block"));
        assert!(err(&format!(
            "{b}t85: [{{block: [0,0,0], min_s: 3, max_s: 2}}]\n"
        ))
        .contains("t85[0]: need 0 <= min_s <= max_s"));
        assert!(err(&format!(
            "{b}t85: [{{block: [0,0,0], min_s: -1, max_s: 2}}]\n"
        ))
        .contains("t85[0]: need 0 <= min_s"));
        assert!(err(&format!(
            "{b}t85: [{{block: [0,0,0], min_s: .inf, max_s: .inf}}]\n"
        ))
        .contains("t85[0].min_s: expected a finite number"));
        assert!(err(&format!("{b}t85: [{{block: [0,0,0], min_s: 1}}]\n"))
            .contains("t85[0]: missing max_s"));
        assert!(err(&format!("{b}thermal: {{substep: 3}}\n"))
            .contains("thermal: unknown key 'substep'"));
    }

    #[test]
    fn later_window_wins_with_a_warning() {
        let p = Part::parse(&format!(
            "{HEAD}blocks: [[0,0,0], [1,0,0]]\nt85:\n  - {{box: {{min: [0,0,0], max: [1,0,0]}}, min_s: 1, max_s: 5}}\n  - {{block: [1,0,0], min_s: 2, max_s: 3}}\n"
        ))
        .unwrap();
        assert_eq!(
            p.window_of(0),
            Some(Window {
                min_s: 1.0,
                max_s: 5.0
            })
        );
        assert_eq!(
            p.window_of(1),
            Some(Window {
                min_s: 2.0,
                max_s: 3.0
            })
        );
        assert_eq!(p.warnings.len(), 1);
    }

    #[test]
    fn garbage_and_duplicate_keys_are_errors() {
        assert!(matches!(
            Part::from_bytes(&[0xff, 0xfe, 0x00]),
            Err(PartError::NotUtf8(0))
        ));
        assert!(matches!(
            Part::parse("name: a\nname: b\n"),
            Err(PartError::Yaml(_))
        ));
        assert!(Part::parse("{{{{").is_err());
    }

    /// Issue #30: a part beyond any cell (a huge coordinate or pitch) is refused when read,
    /// naming the axis, instead of overflowing or failing after planning.
    #[test]
    fn parts_beyond_any_cell_are_refused_when_read() {
        let e = Part::parse(&format!("{HEAD}blocks: [[9223372036854775807, 0, 0]]\n"))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("the part reaches 5.5") && e.contains("along x"),
            "{e}"
        );
        let e = Part::parse(
            "name: c\nblock_mm: [6, 1e308, 2.5]\nmax_fragments: 1\nblocks: [[0,0,0]]\n",
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("along y") && e.contains("pitch 1e308"), "{e}");
        let e = Part::parse(&format!(
            "{HEAD}origin_mm: [0, 0, -2e6]\nblocks: [[0,0,0]]\n"
        ))
        .unwrap_err()
        .to_string();
        assert!(e.contains("along z"), "{e}");
        // A part 1 km long is still a part.
        Part::parse("name: c\nblock_mm: [1e5, 1, 1]\nmax_fragments: 1\nblocks: [[9,0,0]]\n")
            .unwrap();
    }
}
