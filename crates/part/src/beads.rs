//! Graph parts: a part as a graph of deposits along weld beads (`docs/graph-part-format.md`).
//!
//! A cube part ([`Part`](crate::Part)) is one special case of a graph part: blocks on a grid
//! whose contacts are their shared faces. Round parts (tubes, nozzles, flanges) are welded as
//! beads along their contours instead, and a [`BeadPart`] describes them: the beads' centre
//! lines, per layer; the deposits (nodes) cut from them, each about one bead width long, with
//! its volume and free surface; and the contacts between deposits, each with its area and
//! kind. The weld moves and the gravity rule of a plan follow from the contacts
//! ([`WeldMoves`]), and [`GraphPlan::validate`] checks a plan of node ids with the four rules
//! of the cube plan format.

use std::collections::HashSet;
use std::fmt::Write as _;

use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::writer::{real, write_thermal};
use crate::{ThermalParams, Window};

/// Coordinates beyond ±1 km are a unit or typing error, not a part (and would leave no
/// precision for the geometry built on them).
pub const MAX_COORD_MM: f64 = 1.0e6;
/// The widest bead or highest layer accepted, mm.
pub const MAX_BEAD_MM: f64 = 1.0e3;
/// The largest area (mm²) or volume (mm³) a single deposit or contact may have: a cube of
/// MAX_BEAD_MM has 10^9 mm³; more is an error.
pub const MAX_AMOUNT: f64 = 1.0e9;

/// How two deposits touch.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ContactKind {
    /// Consecutive pieces of one bead (and the last and first piece of a closed bead).
    Along,
    /// Same layer, side by side (neighbouring beads).
    Beside,
    /// One layer above the other, footprints overlapping.
    Stacked,
}

impl ContactKind {
    /// The name used in files: `along`, `beside`, `stacked`.
    pub fn name(self) -> &'static str {
        match self {
            ContactKind::Along => "along",
            ContactKind::Beside => "beside",
            ContactKind::Stacked => "stacked",
        }
    }
}

/// A bead's centre line in one layer, in the part frame (mm).
#[derive(Debug, Clone, PartialEq)]
pub struct Bead {
    pub layer: u32,
    /// A closed bead runs from its last point back to its first.
    pub closed: bool,
    pub points: Vec<[f64; 2]>,
}

impl Bead {
    /// The centre line's length, mm (with the closing segment of a closed bead).
    pub fn length_mm(&self) -> f64 {
        let n = self.points.len();
        let seg = |a: [f64; 2], b: [f64; 2]| (b[0] - a[0]).hypot(b[1] - a[1]);
        let open: f64 = self.points.windows(2).map(|w| seg(w[0], w[1])).sum();
        if self.closed && n > 1 {
            open + seg(self.points[n - 1], self.points[0])
        } else {
            open
        }
    }

    /// The distance from `xy` to the centre line, mm (the closing segment of a closed bead
    /// included): a point within W/2 of it lies on the bead.
    pub fn distance_mm(&self, xy: [f64; 2]) -> f64 {
        self.project_mm(xy).1
    }

    /// The point of the centre line nearest `xy`: its arc length from the bead's first
    /// point and its distance from `xy`, mm (the closing segment of a closed bead included).
    pub fn project_mm(&self, xy: [f64; 2]) -> (f64, f64) {
        let n = self.points.len();
        let closing = (self.closed && n > 1).then(|| [self.points[n - 1], self.points[0]]);
        let mut s = 0.0;
        let mut best = (0.0, f64::INFINITY);
        for [a, b] in self
            .points
            .windows(2)
            .map(|w| [w[0], w[1]])
            .chain(closing)
            .chain((n == 1).then(|| [self.points[0], self.points[0]]))
        {
            let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
            let len2 = dx * dx + dy * dy;
            let t = if len2 > 0.0 {
                (((xy[0] - a[0]) * dx + (xy[1] - a[1]) * dy) / len2).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let d = (xy[0] - (a[0] + t * dx)).hypot(xy[1] - (a[1] + t * dy));
            if d < best.1 {
                best = (s + t * len2.sqrt(), d);
            }
            s += len2.sqrt();
        }
        best
    }

    /// The centre line from arc length `from_mm` to `to_mm` (clamped to the line, from
    /// <= to): the point at each end and the vertices between, in order. A node's piece
    /// (its footprint's spine, for torch access and clearance).
    pub fn piece_mm(&self, from_mm: f64, to_mm: f64) -> Vec<[f64; 2]> {
        let mut line = self.points.clone();
        if self.closed && !line.is_empty() {
            line.push(self.points[0]);
        }
        let seg = |a: [f64; 2], b: [f64; 2]| (b[0] - a[0]).hypot(b[1] - a[1]);
        let total = self.length_mm();
        let (from, to) = (from_mm.clamp(0.0, total), to_mm.clamp(0.0, total));
        let mut out = Vec::new();
        let mut s = 0.0;
        for w in line.windows(2) {
            let len = seg(w[0], w[1]);
            let at = |t: f64| {
                let u = if len > 0.0 {
                    ((t - s) / len).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                [
                    w[0][0] + (w[1][0] - w[0][0]) * u,
                    w[0][1] + (w[1][1] - w[0][1]) * u,
                ]
            };
            if out.is_empty() && from <= s + len {
                out.push(at(from));
            }
            if !out.is_empty() {
                if to <= s + len {
                    out.push(at(to));
                    return out;
                }
                out.push(w[1]);
            }
            s += len;
        }
        if out.is_empty() {
            out.extend(line.last().copied());
        }
        out
    }
}

/// One deposit (a node of the graph): a piece of a bead.
#[derive(Debug, Clone, PartialEq)]
pub struct Deposit {
    /// Index of the bead it is cut from.
    pub bead: usize,
    /// Arc-length interval on the bead's centre line, mm from the bead's first point.
    pub from_mm: f64,
    pub to_mm: f64,
    pub layer: u32,
    /// Centre of the deposit in the part frame, mm; z is the layer's mid-height.
    pub centre_mm: [f64; 3],
    pub volume_mm3: f64,
    /// Its whole free surface when it stands alone, mm².
    pub surface_mm2: f64,
    /// Contact with the substrate plate, mm² (layer 0 only, else 0).
    pub substrate_mm2: f64,
}

/// An undirected contact between deposits `a < b`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Contact {
    pub a: usize,
    pub b: usize,
    pub area_mm2: f64,
    pub kind: ContactKind,
}

/// A graph part ("bead part"): beads, their deposits and the contacts between deposits.
#[derive(Debug, Clone, PartialEq)]
pub struct BeadPart {
    pub name: String,
    /// k: the most weld paths (arc starts) a plan may use.
    pub max_fragments: usize,
    /// Bead width W and layer height H, mm.
    pub bead_mm: [f64; 2],
    /// z of the plate's top face in the part frame, mm: layer i's centre lines lie at
    /// `base_z_mm + (i + 0.5) * H`.
    pub base_z_mm: f64,
    pub beads: Vec<Bead>,
    /// The deposits; a node's id is its index here.
    pub nodes: Vec<Deposit>,
    pub contacts: Vec<Contact>,
    /// (node id, window), sorted by node id; one window per node.
    pub windows: Vec<(usize, Window)>,
    pub thermal: ThermalParams,
    /// Non-fatal remarks made while reading (a window overriding an earlier one).
    pub warnings: Vec<String>,
}

/// A graph-part file that cannot be read or breaks a rule of the format.
#[derive(Debug, Error, PartialEq)]
pub enum BeadPartError {
    #[error("the part file is not UTF-8 text (first bad byte at offset {0})")]
    NotUtf8(usize),
    #[error("not a graph part: {0}")]
    Yaml(String),
    /// A rule broken at a place (`nodes[3].volume_mm3`, `contacts[7]`, ...).
    #[error("{at}: {what}")]
    Rule { at: String, what: String },
}

fn broken(at: impl Into<String>, what: impl Into<String>) -> BeadPartError {
    BeadPartError::Rule {
        at: at.into(),
        what: what.into(),
    }
}

// The file as serde reads it; `deny_unknown_fields` refuses a misspelt key by name.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPart {
    kind: String,
    name: String,
    max_fragments: u64,
    bead_mm: [f64; 2],
    #[serde(default)]
    base_z_mm: f64,
    beads: Vec<RawBead>,
    nodes: Vec<RawNode>,
    #[serde(default)]
    contacts: Vec<(u64, u64, f64, ContactKind)>,
    #[serde(default)]
    t85: Vec<RawWindow>,
    #[serde(default)]
    thermal: Option<serde_yaml::Value>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawBead {
    layer: u32,
    closed: bool,
    points: Vec<[f64; 2]>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawNode {
    bead: u64,
    from_mm: f64,
    to_mm: f64,
    layer: u32,
    centre_mm: [f64; 3],
    volume_mm3: f64,
    surface_mm2: f64,
    #[serde(default)]
    substrate_mm2: f64,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawWindow {
    node: Option<u64>,
    #[serde(rename = "box")]
    box_mm: Option<RawBox>,
    z_mm: Option<[f64; 2]>,
    min_s: f64,
    max_s: f64,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawBox {
    min: [f64; 3],
    max: [f64; 3],
}

/// True when the text is a graph part: it has the top-level line `kind: beads` (which
/// [`BeadPart::to_yaml`] writes first). Cube part files have no `kind` key.
pub fn is_bead_part(text: &str) -> bool {
    text.lines().any(|line| {
        let line = line.split('#').next().unwrap_or("").trim_end();
        matches!(line, "kind: beads" | "kind: 'beads'" | "kind: \"beads\"")
    })
}

/// A number that must be finite and within `lo..=hi`.
fn ranged(x: f64, lo: f64, hi: f64, at: impl Fn() -> String) -> Result<f64, BeadPartError> {
    if !x.is_finite() {
        return Err(broken(at(), format!("expected a finite number, got {x:?}")));
    }
    if !(lo..=hi).contains(&x) {
        return Err(broken(
            at(),
            format!("{x:?} is out of range {lo:?}..={hi:?}"),
        ));
    }
    Ok(x)
}

/// A number that must be finite, > 0 and <= `hi`.
fn positive(x: f64, hi: f64, at: impl Fn() -> String) -> Result<f64, BeadPartError> {
    let x = ranged(x, 0.0, hi, &at)?;
    if x == 0.0 {
        return Err(broken(at(), "must be > 0, got 0"));
    }
    Ok(x)
}

fn coords<const N: usize>(v: [f64; N], at: impl Fn() -> String) -> Result<[f64; N], BeadPartError> {
    for x in v {
        ranged(x, -MAX_COORD_MM, MAX_COORD_MM, &at)?;
    }
    Ok(v)
}

impl BeadPart {
    /// Reads a graph-part file given as raw bytes (garbage gives an error, never a panic).
    pub fn from_bytes(bytes: &[u8]) -> Result<BeadPart, BeadPartError> {
        let text =
            std::str::from_utf8(bytes).map_err(|e| BeadPartError::NotUtf8(e.valid_up_to()))?;
        BeadPart::parse(text)
    }

    /// Parses graph-part text and enforces every rule of `docs/graph-part-format.md`.
    pub fn parse(text: &str) -> Result<BeadPart, BeadPartError> {
        crate::yaml::check(text).map_err(|e| BeadPartError::Yaml(e.to_string()))?;
        let raw: RawPart =
            serde_yaml::from_str(text).map_err(|e| BeadPartError::Yaml(e.to_string()))?;
        if raw.kind != "beads" {
            return Err(broken(
                "kind",
                format!("expected 'beads', got {:?}", raw.kind),
            ));
        }
        if raw.max_fragments == 0 {
            return Err(broken("max_fragments", "expected an integer >= 1, got 0"));
        }
        let max_fragments =
            usize::try_from(raw.max_fragments).map_err(|_| broken("max_fragments", "too large"))?;
        for (d, x) in raw.bead_mm.into_iter().enumerate() {
            positive(x, MAX_BEAD_MM, || format!("bead_mm[{d}]"))?;
        }
        let [_, h] = raw.bead_mm;
        let base_z_mm = ranged(raw.base_z_mm, -MAX_COORD_MM, MAX_COORD_MM, || {
            "base_z_mm".into()
        })?;
        let mut beads = Vec::with_capacity(raw.beads.len());
        for (i, b) in raw.beads.into_iter().enumerate() {
            let at = |what: &str| format!("beads[{i}]{what}");
            let least = if b.closed { 3 } else { 2 };
            if b.points.len() < least {
                return Err(broken(
                    at(".points"),
                    format!(
                        "a {} bead needs at least {least} points, got {}",
                        if b.closed { "closed" } else { "open" },
                        b.points.len()
                    ),
                ));
            }
            for (p, &pt) in b.points.iter().enumerate() {
                coords(pt, || at(&format!(".points[{p}]")))?;
            }
            let bead = Bead {
                layer: b.layer,
                closed: b.closed,
                points: b.points,
            };
            if bead.length_mm() <= 0.0 {
                return Err(broken(at(""), "the centre line has zero length"));
            }
            beads.push(bead);
        }
        let lengths: Vec<f64> = beads.iter().map(Bead::length_mm).collect();
        if raw.nodes.is_empty() {
            return Err(broken("nodes", "the part has no nodes"));
        }
        let mut nodes = Vec::with_capacity(raw.nodes.len());
        for (i, n) in raw.nodes.into_iter().enumerate() {
            let at = |what: &str| format!("nodes[{i}]{what}");
            let bead = usize::try_from(n.bead)
                .ok()
                .filter(|&b| b < beads.len())
                .ok_or_else(|| {
                    broken(
                        at(".bead"),
                        format!("no bead {} (the part has {})", n.bead, beads.len()),
                    )
                })?;
            if n.layer != beads[bead].layer {
                return Err(broken(
                    at(".layer"),
                    format!(
                        "{} is not the layer {} of its bead {bead}",
                        n.layer, beads[bead].layer
                    ),
                ));
            }
            let len = lengths[bead];
            // Arc lengths are sums of floats: allow a rounding error at the far end.
            let slack = 1e-6 * len.max(1.0);
            let from_mm = ranged(n.from_mm, 0.0, len + slack, || at(".from_mm"))?;
            let to_mm = ranged(n.to_mm, 0.0, len + slack, || at(".to_mm"))?;
            if from_mm >= to_mm {
                return Err(broken(
                    at(""),
                    format!("need from_mm < to_mm, got {from_mm} and {to_mm}"),
                ));
            }
            let centre_mm = coords(n.centre_mm, || at(".centre_mm"))?;
            let z = base_z_mm + (n.layer as f64 + 0.5) * h;
            if (centre_mm[2] - z).abs() > 1e-6 * z.abs().max(1.0) {
                return Err(broken(
                    at(".centre_mm"),
                    format!(
                        "z = {} is not the layer's mid-height base_z_mm + (layer + 0.5) * H = {z}",
                        centre_mm[2]
                    ),
                ));
            }
            let volume_mm3 = positive(n.volume_mm3, MAX_AMOUNT, || at(".volume_mm3"))?;
            let surface_mm2 = ranged(n.surface_mm2, 0.0, MAX_AMOUNT, || at(".surface_mm2"))?;
            let substrate_mm2 = ranged(n.substrate_mm2, 0.0, MAX_AMOUNT, || at(".substrate_mm2"))?;
            if substrate_mm2 > 0.0 && n.layer != 0 {
                return Err(broken(
                    at(".substrate_mm2"),
                    format!(
                        "only layer 0 touches the plate, this node is in layer {}",
                        n.layer
                    ),
                ));
            }
            nodes.push(Deposit {
                bead,
                from_mm,
                to_mm,
                layer: n.layer,
                centre_mm,
                volume_mm3,
                surface_mm2,
                substrate_mm2,
            });
        }
        let mut contacts = Vec::with_capacity(raw.contacts.len());
        let mut seen = HashSet::with_capacity(raw.contacts.len());
        for (i, &(a, b, area, kind)) in raw.contacts.iter().enumerate() {
            let at = format!("contacts[{i}]");
            let id = |x: u64| {
                usize::try_from(x)
                    .ok()
                    .filter(|&x| x < nodes.len())
                    .ok_or_else(|| {
                        broken(&at, format!("no node {x} (the part has {})", nodes.len()))
                    })
            };
            let (a, b) = (id(a)?, id(b)?);
            if a == b {
                return Err(broken(&at, format!("node {a} in contact with itself")));
            }
            if a > b {
                return Err(broken(
                    &at,
                    format!("write the smaller id first: [{b}, {a}, ...]"),
                ));
            }
            let area_mm2 = positive(area, MAX_AMOUNT, || format!("{at}.area_mm2"))?;
            let (na, nb) = (&nodes[a], &nodes[b]);
            let consistent = match kind {
                ContactKind::Along => na.bead == nb.bead,
                ContactKind::Beside => na.layer == nb.layer,
                ContactKind::Stacked => na.layer.abs_diff(nb.layer) == 1,
            };
            if !consistent {
                let need = match kind {
                    ContactKind::Along => "both nodes on one bead",
                    ContactKind::Beside => "both nodes in one layer",
                    ContactKind::Stacked => "the nodes in consecutive layers",
                };
                return Err(broken(
                    &at,
                    format!(
                        "a {} contact needs {need}: node {a} is on bead {} in layer {}, node {b} on bead {} in layer {}",
                        kind.name(),
                        na.bead,
                        na.layer,
                        nb.bead,
                        nb.layer
                    ),
                ));
            }
            if !seen.insert((a, b)) {
                return Err(broken(&at, format!("a second contact between {a} and {b}")));
            }
            contacts.push(Contact {
                a,
                b,
                area_mm2,
                kind,
            });
        }
        let thermal =
            ThermalParams::from_yaml(raw.thermal.as_ref()).map_err(|e| broken("thermal", e.0))?;
        let mut part = BeadPart {
            name: raw.name,
            max_fragments,
            bead_mm: raw.bead_mm,
            base_z_mm,
            beads,
            nodes,
            contacts,
            windows: Vec::new(),
            thermal,
            warnings: Vec::new(),
        };
        for (i, w) in raw.t85.iter().enumerate() {
            part.read_window(i, w)?;
        }
        Ok(part)
    }

    fn read_window(&mut self, i: usize, w: &RawWindow) -> Result<(), BeadPartError> {
        let at = format!("t85[{i}]");
        let named = [w.node.is_some(), w.box_mm.is_some(), w.z_mm.is_some()];
        if named.iter().filter(|&&x| x).count() != 1 {
            return Err(broken(&at, "name exactly one of 'node', 'box' or 'z_mm'"));
        }
        let min_s = ranged(w.min_s, 0.0, f64::MAX, || format!("{at}.min_s"))?;
        let max_s = ranged(w.max_s, 0.0, f64::MAX, || format!("{at}.max_s"))?;
        if min_s > max_s {
            return Err(broken(
                &at,
                format!("need 0 <= min_s <= max_s, got min_s={min_s} max_s={max_s}"),
            ));
        }
        let targets: Vec<usize> = if let Some(n) = w.node {
            let n = usize::try_from(n)
                .ok()
                .filter(|&n| n < self.nodes.len())
                .ok_or_else(|| {
                    broken(
                        format!("{at}.node"),
                        format!("no node {n} (the part has {})", self.nodes.len()),
                    )
                })?;
            vec![n]
        } else {
            let (lo, hi) = match (&w.box_mm, w.z_mm) {
                (Some(b), _) => (
                    coords(b.min, || format!("{at}.box.min"))?,
                    coords(b.max, || format!("{at}.box.max"))?,
                ),
                (None, Some(z)) => {
                    let z = coords(z, || format!("{at}.z_mm"))?;
                    ([f64::MIN, f64::MIN, z[0]], [f64::MAX, f64::MAX, z[1]])
                }
                (None, None) => unreachable!("exactly one key is named"),
            };
            let t: Vec<usize> = (0..self.nodes.len())
                .filter(|&n| {
                    let c = self.nodes[n].centre_mm;
                    (0..3).all(|d| lo[d] <= c[d] && c[d] <= hi[d])
                })
                .collect();
            if t.is_empty() {
                return Err(broken(&at, "holds no node centre of the part"));
            }
            t
        };
        for n in targets {
            if self.window_of(n).is_some() {
                self.warnings
                    .push(format!("{at} overrides an earlier window on node {n}"));
            }
            self.set_window(n, Window { min_s, max_s });
        }
        Ok(())
    }

    /// Number of nodes.
    pub fn len(&self) -> usize {
        self.nodes.len()
    }

    /// A read part always has nodes; this is here for clippy's sake.
    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    /// Number of layers (1 + the highest layer of a node).
    pub fn layers(&self) -> u32 {
        self.nodes.iter().map(|n| n.layer + 1).max().unwrap_or(0)
    }

    /// The window of node `i`, if it has one.
    pub fn window_of(&self, i: usize) -> Option<Window> {
        self.windows
            .binary_search_by_key(&i, |(n, _)| *n)
            .ok()
            .map(|k| self.windows[k].1)
    }

    /// Sets (or replaces) the window of node `i`.
    pub fn set_window(&mut self, i: usize, window: Window) {
        match self.windows.binary_search_by_key(&i, |(n, _)| *n) {
            Ok(k) => self.windows[k].1 = window,
            Err(k) => self.windows.insert(k, (i, window)),
        }
    }

    /// The moves a plan may make and what each node stands on.
    pub fn moves(&self) -> WeldMoves {
        WeldMoves::new(self)
    }

    /// The part as a graph-part file: flow style, one bead, node or contact per line;
    /// numbers written so that they read back bit for bit.
    pub fn to_yaml(&self) -> String {
        let mut out = String::new();
        let quoted = serde_json::to_string(&self.name).expect("a string serializes");
        let _ = writeln!(out, "kind: beads");
        let _ = writeln!(out, "name: {quoted}");
        let _ = writeln!(out, "max_fragments: {}", self.max_fragments);
        let _ = writeln!(
            out,
            "bead_mm: [{}, {}]",
            real(self.bead_mm[0]),
            real(self.bead_mm[1])
        );
        let _ = writeln!(out, "base_z_mm: {}", real(self.base_z_mm));
        out.push_str("beads:\n");
        for b in &self.beads {
            let pts: Vec<String> = b
                .points
                .iter()
                .map(|p| format!("[{}, {}]", real(p[0]), real(p[1])))
                .collect();
            let _ = writeln!(
                out,
                "  - {{layer: {}, closed: {}, points: [{}]}}",
                b.layer,
                b.closed,
                pts.join(", ")
            );
        }
        out.push_str("nodes:\n");
        for n in &self.nodes {
            let c = n.centre_mm;
            let _ = writeln!(
                out,
                "  - {{bead: {}, from_mm: {}, to_mm: {}, layer: {}, centre_mm: [{}, {}, {}], volume_mm3: {}, surface_mm2: {}, substrate_mm2: {}}}",
                n.bead,
                real(n.from_mm),
                real(n.to_mm),
                n.layer,
                real(c[0]),
                real(c[1]),
                real(c[2]),
                real(n.volume_mm3),
                real(n.surface_mm2),
                real(n.substrate_mm2)
            );
        }
        if self.contacts.is_empty() {
            out.push_str("contacts: []\n");
        } else {
            out.push_str("contacts:\n");
        }
        for c in &self.contacts {
            let _ = writeln!(
                out,
                "  - [{}, {}, {}, {}]",
                c.a,
                c.b,
                real(c.area_mm2),
                c.kind.name()
            );
        }
        if !self.windows.is_empty() {
            out.push_str("t85:\n");
            for (n, w) in &self.windows {
                let _ = writeln!(
                    out,
                    "  - {{node: {n}, min_s: {}, max_s: {}}}",
                    real(w.min_s),
                    real(w.max_s)
                );
            }
        }
        write_thermal(&mut out, &self.thermal);
        out
    }
}

/// The directed moves of a graph part and its gravity relation, as adjacency lists.
///
/// A weld path may move between two nodes of one layer that touch (Along or Beside, both
/// ways) and from a node to one stacked on it (up, never down). A node stands on the nodes
/// of the layer below it has a Stacked contact with.
#[derive(Debug, Clone)]
pub struct WeldMoves {
    succ: Vec<Vec<u32>>,
    below: Vec<Vec<u32>>,
}

impl WeldMoves {
    /// Builds the moves of a part.
    pub fn new(part: &BeadPart) -> WeldMoves {
        let n = part.nodes.len();
        let (mut succ, mut below) = (vec![Vec::new(); n], vec![Vec::new(); n]);
        for c in &part.contacts {
            match c.kind {
                ContactKind::Along | ContactKind::Beside => {
                    succ[c.a].push(c.b as u32);
                    succ[c.b].push(c.a as u32);
                }
                ContactKind::Stacked => {
                    let (lo, hi) = if part.nodes[c.a].layer < part.nodes[c.b].layer {
                        (c.a, c.b)
                    } else {
                        (c.b, c.a)
                    };
                    succ[lo].push(hi as u32);
                    below[hi].push(lo as u32);
                }
            }
        }
        for list in succ.iter_mut().chain(below.iter_mut()) {
            list.sort_unstable();
        }
        WeldMoves { succ, below }
    }

    /// The nodes a weld path may move to from `u`, sorted.
    pub fn successors(&self, u: usize) -> &[u32] {
        &self.succ[u]
    }

    /// True when a weld path may move from `a` straight to `b`.
    pub fn has_move(&self, a: usize, b: usize) -> bool {
        u32::try_from(b).is_ok_and(|b| self.succ[a].binary_search(&b).is_ok())
    }

    /// The nodes `u` stands on (layer below, Stacked contact), sorted.
    pub fn stands_on(&self, u: usize) -> &[u32] {
        &self.below[u]
    }

    /// Number of directed moves.
    pub fn move_count(&self) -> usize {
        self.succ.iter().map(Vec::len).sum()
    }
}

/// A plan for a graph part: fragments of node ids, welded in order. Same file format as a
/// cube plan (`part`, `fragments`), with node ids instead of [x, y, z] blocks.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GraphPlan {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub part: Option<String>,
    pub fragments: Vec<Vec<usize>>,
}

/// A graph plan file that cannot be read as a plan at all.
#[derive(Debug, Error)]
pub enum GraphPlanReadError {
    #[error("the plan file is not UTF-8 text (first bad byte at offset {0})")]
    NotUtf8(usize),
    #[error("plan is not valid JSON: {0}")]
    Json(String),
    #[error("plan is not valid YAML or not a graph plan ('part' and a 'fragments' list of lists of node ids): {0}")]
    Yaml(String),
}

/// The first validity rule a graph plan breaks (rule numbers as in the cube plan format).
#[derive(Debug, Clone, Error, PartialEq, Eq)]
pub enum GraphInvalid {
    #[error("rule 1: node {node} (fragment {fragment}, position {position}) is not a node of the part ({count} nodes)")]
    UnknownNode {
        node: usize,
        count: usize,
        fragment: usize,
        position: usize,
    },
    #[error("rule 1: node {node} appears twice (fragment {fragment}, position {position})")]
    Repeated {
        node: usize,
        fragment: usize,
        position: usize,
    },
    #[error("rule 1: node {node} does not appear in the plan")]
    Missing { node: usize },
    #[error("rule 2: {count} fragments, allowed 1..{max}")]
    FragmentCount { count: usize, max: usize },
    #[error("rule 2: fragment {fragment} is empty")]
    EmptyFragment { fragment: usize },
    #[error("rule 3: fragment {fragment} moves {from} -> {to} (position {position}), not a weld move (no contact in one layer, and not up onto a stacked node)")]
    NotAMove {
        from: usize,
        to: usize,
        fragment: usize,
        position: usize,
    },
    #[error("rule 4: node {node} is in fragment {fragment}, node {below} it stands on in fragment {below_fragment}")]
    Gravity {
        node: usize,
        fragment: usize,
        below: usize,
        below_fragment: usize,
    },
}

impl GraphInvalid {
    /// The rule number (1 to 4).
    pub fn rule(&self) -> u8 {
        match self {
            GraphInvalid::UnknownNode { .. }
            | GraphInvalid::Repeated { .. }
            | GraphInvalid::Missing { .. } => 1,
            GraphInvalid::FragmentCount { .. } | GraphInvalid::EmptyFragment { .. } => 2,
            GraphInvalid::NotAMove { .. } => 3,
            GraphInvalid::Gravity { .. } => 4,
        }
    }
}

impl GraphPlan {
    /// Reads a plan from bytes: JSON when `json` (or when it starts with `{`), else YAML.
    pub fn from_bytes(bytes: &[u8], json: bool) -> Result<GraphPlan, GraphPlanReadError> {
        let text =
            std::str::from_utf8(bytes).map_err(|e| GraphPlanReadError::NotUtf8(e.valid_up_to()))?;
        if json || text.trim_start().starts_with('{') {
            serde_json::from_str(text).map_err(|e| GraphPlanReadError::Json(e.to_string()))
        } else {
            crate::yaml::check(text).map_err(|e| GraphPlanReadError::Yaml(e.to_string()))?;
            serde_yaml::from_str(text).map_err(|e| GraphPlanReadError::Yaml(e.to_string()))
        }
    }

    /// The plan as YAML, one fragment per line.
    pub fn to_yaml(&self) -> String {
        let mut out = String::new();
        if let Some(name) = &self.part {
            let quoted = serde_json::to_string(name).expect("a string serializes");
            let _ = writeln!(out, "part: {quoted}");
        }
        out.push_str("fragments:\n");
        for f in &self.fragments {
            let ids: Vec<String> = f.iter().map(usize::to_string).collect();
            let _ = writeln!(out, "  - [{}]", ids.join(", "));
        }
        out
    }

    /// Checks the four rules in order: every node exactly once; 1..=k non-empty fragments;
    /// consecutive nodes joined by a weld move; no node welded in an earlier fragment than
    /// a node it stands on.
    pub fn validate(&self, part: &BeadPart, moves: &WeldMoves) -> Result<(), GraphInvalid> {
        const UNSEEN: usize = usize::MAX;
        let count = part.nodes.len();
        let mut fragment_of = vec![UNSEEN; count];
        for (f, fragment) in self.fragments.iter().enumerate() {
            for (p, &node) in fragment.iter().enumerate() {
                let (fragment, position) = (f + 1, p + 1);
                if node >= count {
                    return Err(GraphInvalid::UnknownNode {
                        node,
                        count,
                        fragment,
                        position,
                    });
                }
                if fragment_of[node] != UNSEEN {
                    return Err(GraphInvalid::Repeated {
                        node,
                        fragment,
                        position,
                    });
                }
                fragment_of[node] = f;
            }
        }
        if let Some(node) = fragment_of.iter().position(|&f| f == UNSEEN) {
            return Err(GraphInvalid::Missing { node });
        }
        let n = self.fragments.len();
        if n == 0 || n > part.max_fragments {
            return Err(GraphInvalid::FragmentCount {
                count: n,
                max: part.max_fragments,
            });
        }
        if let Some(f) = self.fragments.iter().position(Vec::is_empty) {
            return Err(GraphInvalid::EmptyFragment { fragment: f + 1 });
        }
        for (f, ids) in self.fragments.iter().enumerate() {
            for (p, pair) in ids.windows(2).enumerate() {
                if !moves.has_move(pair[0], pair[1]) {
                    return Err(GraphInvalid::NotAMove {
                        from: pair[0],
                        to: pair[1],
                        fragment: f + 1,
                        position: p + 1,
                    });
                }
            }
        }
        for (f, ids) in self.fragments.iter().enumerate() {
            for &u in ids {
                for &below in moves.stands_on(u) {
                    let below = below as usize;
                    if fragment_of[below] > f {
                        return Err(GraphInvalid::Gravity {
                            node: u,
                            fragment: f + 1,
                            below,
                            below_fragment: fragment_of[below] + 1,
                        });
                    }
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_piece_follows_the_centre_line_across_vertices_and_the_closing_segment() {
        let square = Bead {
            layer: 0,
            closed: true,
            points: vec![[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]],
        };
        assert_eq!(square.piece_mm(2.0, 5.0), vec![[2.0, 0.0], [5.0, 0.0]]);
        assert_eq!(
            square.piece_mm(5.0, 15.0),
            vec![[5.0, 0.0], [10.0, 0.0], [10.0, 5.0]]
        );
        // The closing segment, from (0, 10) back to (0, 0), and clamped at the end.
        assert_eq!(square.piece_mm(35.0, 99.0), vec![[0.0, 5.0], [0.0, 0.0]]);
        let open = Bead {
            closed: false,
            ..square
        };
        assert_eq!(open.piece_mm(25.0, 30.0), vec![[5.0, 10.0], [0.0, 10.0]]);
    }

    /// Two layers of one closed bead of 3 pieces (a triangle of side 6, W 6, H 2.5).
    fn sample() -> String {
        let mut s = String::from(
            "kind: beads\nname: ring\nmax_fragments: 2\nbead_mm: [6, 2.5]\nbase_z_mm: 0\nbeads:\n",
        );
        for l in 0..2 {
            let _ = writeln!(
                s,
                "  - {{layer: {l}, closed: true, points: [[0, 0], [6, 0], [3, 5.196152422706632]]}}"
            );
        }
        s.push_str("nodes:\n");
        for l in 0..2 {
            let z = (l as f64 + 0.5) * 2.5;
            let sub = if l == 0 { 15.0 } else { 0.0 };
            for p in 0..3 {
                let _ = writeln!(
                    s,
                    "  - {{bead: {l}, from_mm: {}, to_mm: {}, layer: {l}, centre_mm: [{p}, 1, {z}], volume_mm3: 37.5, surface_mm2: 100, substrate_mm2: {sub}}}",
                    p * 6,
                    p * 6 + 6
                );
            }
        }
        s.push_str("contacts:\n");
        for l in 0..2 {
            let b = 3 * l;
            let _ = writeln!(
                s,
                "  - [{b}, {}, 15, along]\n  - [{}, {}, 15, along]\n  - [{b}, {}, 15, along]",
                b + 1,
                b + 1,
                b + 2,
                b + 2
            );
        }
        for p in 0..3 {
            let _ = writeln!(s, "  - [{p}, {}, 36, stacked]", p + 3);
        }
        s.push_str(
            "t85:\n  - {z_mm: [0, 2], min_s: 1, max_s: 9}\n  - {node: 4, min_s: 2, max_s: 8}\n",
        );
        s.push_str("thermal: {block_time_s: 2.0}\n");
        s
    }

    #[test]
    fn a_part_reads_writes_and_reads_back_equal() {
        let p = BeadPart::parse(&sample()).unwrap();
        assert_eq!((p.len(), p.contacts.len(), p.layers()), (6, 9, 2));
        assert_eq!(p.windows.len(), 4);
        assert_eq!(p.window_of(4).map(|w| w.min_s), Some(2.0));
        assert_eq!(p.thermal.block_time_s, 2.0);
        assert!(is_bead_part(&p.to_yaml()));
        let back = BeadPart::parse(&p.to_yaml()).unwrap();
        assert_eq!(back, p);
        let moves = p.moves();
        assert_eq!(moves.successors(0), &[1, 2, 3]);
        assert_eq!(moves.successors(3), &[4, 5]);
        assert_eq!(moves.stands_on(4), &[1]);
        assert!(!moves.has_move(3, 0), "never down");
        assert_eq!(moves.move_count(), 12 + 3);
    }

    fn err(text: &str) -> String {
        BeadPart::parse(text).unwrap_err().to_string()
    }

    #[test]
    fn each_rule_is_refused_with_its_place() {
        let s = sample();
        assert!(err(&s.replace("base_z_mm: 0", "base_z_mm: 0\ncolour: red"))
            .contains("unknown field `colour`"));
        assert!(err(&s.replace(
            "volume_mm3: 37.5, surface_mm2: 100, substrate_mm2: 15}",
            "volume_mm3: 37.5, surface_mm2: 100, substrate_mm2: 15, heat: 1}"
        ))
        .contains("unknown field `heat`"));
        assert_eq!(
            err(&s.replace("bead_mm: [6, 2.5]", "bead_mm: [1e308, 2.5]")),
            "bead_mm[0]: 1e308 is out of range 0.0..=1000.0"
        );
        assert_eq!(
            err(&s.replace("bead_mm: [6, 2.5]", "bead_mm: [6, 0]")),
            "bead_mm[1]: must be > 0, got 0"
        );
        assert!(err(&s.replacen("[0, 0], [6, 0]", "[1e308, 0], [6, 0]", 1))
            .starts_with("beads[0].points[0]: 1e308 is out of range"));
        assert!(err(&s.replacen("volume_mm3: 37.5", "volume_mm3: .nan", 1))
            .starts_with("nodes[0].volume_mm3: expected a finite number"));
        assert!(err(&s.replacen("volume_mm3: 37.5", "volume_mm3: 1e300", 1))
            .starts_with("nodes[0].volume_mm3: 1e300 is out of range"));
        assert!(
            err(&s.replacen("[0, 1, 15, along]", "[0, 0, 15, along]", 1))
                .starts_with("contacts[0]: node 0 in contact with itself")
        );
        assert!(
            err(&s.replacen("[0, 1, 15, along]", "[0, 9, 15, along]", 1))
                .starts_with("contacts[0]: no node 9")
        );
        assert!(
            err(&s.replacen("[0, 1, 15, along]", "[1, 0, 15, along]", 1))
                .starts_with("contacts[0]: write the smaller id first")
        );
        assert!(
            err(&s.replacen("[0, 1, 15, along]", "[0, 4, 15, along]", 1))
                .contains("along contact needs both nodes on one bead")
        );
        assert!(
            err(&s.replacen("[0, 3, 36, stacked]", "[0, 1, 36, stacked]", 1))
                .contains("stacked contact needs the nodes in consecutive layers")
        );
        assert!(
            err(&s.replacen("[0, 3, 36, stacked]", "[0, 1, 36, along]", 1))
                .contains("a second contact between 0 and 1")
        );
        assert!(
            err(&s.replacen("[0, 3, 36, stacked]", "[0, 3, 36, glued]", 1))
                .contains("unknown variant `glued`")
        );
        assert!(err(&s.replacen("bead: 0,", "bead: 7,", 1)).starts_with("nodes[0].bead: no bead 7"));
        assert!(err(&s.replacen("layer: 0, centre", "layer: 1, centre", 1))
            .starts_with("nodes[0].layer: 1 is not the layer 0"));
        assert!(err(&s.replacen("to_mm: 6,", "to_mm: 60,", 1))
            .starts_with("nodes[0].to_mm: 60.0 is out of range"));
        assert!(
            err(&s.replacen("centre_mm: [0, 1, 1.25]", "centre_mm: [0, 1, 3]", 1))
                .starts_with("nodes[0].centre_mm: z = 3 is not the layer's mid-height")
        );
        assert!(err(&s.replace("substrate_mm2: 0}", "substrate_mm2: 5}"))
            .contains("only layer 0 touches the plate"));
        assert!(err(&s.replace("kind: beads", "kind: cubes")).starts_with("kind: expected 'beads'"));
        assert!(
            err(&s.replace("max_fragments: 2", "max_fragments: 0")).starts_with("max_fragments")
        );
        assert!(
            err(&s.replace("{node: 4,", "{node: 4, z_mm: [0, 1],")).contains("name exactly one")
        );
        assert!(err(&s.replace("{node: 4,", "{node: 44,")).starts_with("t85[1].node: no node 44"));
        assert!(
            err(&s.replace("z_mm: [0, 2]", "z_mm: [50, 60]")).starts_with("t85[0]: holds no node")
        );
        assert!(err(&s.replace("block_time_s: 2.0", "blok_time_s: 2.0"))
            .contains("thermal: unknown key 'blok_time_s'"));
        assert!(matches!(
            BeadPart::from_bytes(&[0xff]),
            Err(BeadPartError::NotUtf8(0))
        ));
        assert!(BeadPart::parse("{{{{").is_err());
        assert!(BeadPart::parse("").is_err());
    }

    #[test]
    fn graph_plans_are_checked_rule_by_rule() {
        let p = BeadPart::parse(&sample()).unwrap();
        let m = p.moves();
        let check = |f: Vec<Vec<usize>>| {
            GraphPlan {
                part: None,
                fragments: f,
            }
            .validate(&p, &m)
        };
        assert_eq!(check(vec![vec![0, 1, 2, 5, 3, 4]]), Ok(()));
        assert_eq!(check(vec![vec![0, 1, 2], vec![3, 4, 5]]), Ok(()));
        let e = check(vec![vec![0, 1, 2, 5, 3, 4, 9]]).unwrap_err();
        assert_eq!(
            e.to_string(),
            "rule 1: node 9 (fragment 1, position 7) is not a node of the part (6 nodes)"
        );
        assert_eq!(e.rule(), 1);
        let e = check(vec![vec![0, 1, 2, 5, 3, 4, 0]]).unwrap_err();
        assert_eq!(
            e.to_string(),
            "rule 1: node 0 appears twice (fragment 1, position 7)"
        );
        assert_eq!(
            check(vec![vec![0, 1, 2]]).unwrap_err().to_string(),
            "rule 1: node 3 does not appear in the plan"
        );
        assert_eq!(
            check(vec![vec![0], vec![1], vec![2, 5, 3, 4]])
                .unwrap_err()
                .to_string(),
            "rule 2: 3 fragments, allowed 1..2"
        );
        assert_eq!(
            check(vec![vec![0, 1, 2, 5, 3, 4], vec![]])
                .unwrap_err()
                .to_string(),
            "rule 2: fragment 2 is empty"
        );
        assert_eq!(check(vec![vec![0, 1, 2, 5, 4, 3]]), Ok(()));
        let e = check(vec![vec![0, 1, 2, 3, 5, 4]]).unwrap_err();
        assert!(
            matches!(e, GraphInvalid::NotAMove { from: 2, to: 3, .. }),
            "{e}"
        );
        assert_eq!(
            check(vec![vec![3, 4, 5, 2, 0, 1]]).unwrap_err().to_string(),
            "rule 3: fragment 1 moves 5 -> 2 (position 3), not a weld move (no contact in one layer, and not up onto a stacked node)"
        );
        let e = check(vec![vec![3, 4, 5], vec![0, 1, 2]]).unwrap_err();
        assert_eq!(
            e.to_string(),
            "rule 4: node 3 is in fragment 1, node 0 it stands on in fragment 2"
        );
    }

    #[test]
    fn the_documented_example_reads() {
        let doc = include_str!("../../../docs/graph-part-format.md");
        let yaml = doc
            .split("```yaml\n")
            .nth(1)
            .and_then(|rest| rest.split("```").next())
            .unwrap();
        let p = BeadPart::parse(yaml).unwrap();
        assert_eq!((p.len(), p.contacts.len(), p.windows.len()), (3, 3, 3));
        assert_eq!(p.window_of(2).map(|w| w.max_s), Some(12.0));
        assert_eq!(p.warnings.len(), 2);
    }

    #[test]
    fn graph_plan_files_read_alike_in_yaml_and_json() {
        let y = GraphPlan::from_bytes(b"part: ring\nfragments:\n  - [0, 1, 2]\n  - [3]\n", false)
            .unwrap();
        let j = GraphPlan::from_bytes(br#"{"part": "ring", "fragments": [[0,1,2],[3]]}"#, true)
            .unwrap();
        assert_eq!(y, j);
        assert_eq!(
            GraphPlan::from_bytes(y.to_yaml().as_bytes(), false).unwrap(),
            y
        );
        assert!(GraphPlan::from_bytes(b"fragments: [[-1]]", false).is_err());
        assert!(GraphPlan::from_bytes(b"fragments: [[0.5]]", false).is_err());
        assert!(GraphPlan::from_bytes(b"fragment: [[0]]", false).is_err());
    }
}
