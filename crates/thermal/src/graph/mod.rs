//! The lumped thermal model of a *graph part* (`docs/graph-thermal-model.md`): nodes with a
//! volume, a free surface and a substrate area, joined by contacts with an area, instead of
//! equal blocks on a grid. Written out to the operation, as the block model is, so that two
//! programs agree on every verdict.
//!
//! - [`GraphModel`]: the per-part constants, built from plain per-node and per-contact
//!   numbers (no graph-part type: the glue to one comes later);
//! - [`GraphReference`]: the doc's step written plainly, the yardstick of the tests;
//! - [`GraphSimulation`]: the fast step (slots, a padded neighbour table, AVX2), bit for
//!   bit the reference's.
//!
//! Areas are measured in A0 = W·H and volumes in V0 = W·W·H (W bead width, H layer
//! height), so the block model's constants keep their meaning: a node of volume V0 whose
//! contacts all have area A0 is a block.

mod kernel;
mod reference;

#[cfg(test)]
mod tests;

pub use kernel::{bench_graph, ring_graph, GraphSimulation, Ring, GRAPH_PARALLEL_MIN_WORK};
pub use reference::GraphReference;

pub(crate) use kernel::{graph_blocks, graph_slots, GraphTable};

use thiserror::Error;

use crate::{ThermalParams, MAX_STEPS};

/// One node as given: volume (mm³), free surface when alone (mm²), substrate contact area
/// (mm², 0 above layer 0).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NodeGeometry {
    pub volume: f64,
    pub surface: f64,
    pub substrate: f64,
}

impl From<(f64, f64, f64)> for NodeGeometry {
    fn from((volume, surface, substrate): (f64, f64, f64)) -> Self {
        NodeGeometry {
            volume,
            surface,
            substrate,
        }
    }
}

/// A graph that the model cannot take; every variant names the node or contact.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum GraphError {
    #[error("reference bead width W = {w} mm and layer height H = {h} mm must be finite and > 0")]
    Reference { w: f64, h: f64 },
    #[error("node {node}: volume {value} mm³ must be finite and > 0")]
    Volume { node: usize, value: f64 },
    #[error("node {node}: volume {value} mm³ would take more than {max} deposit steps")]
    VolumeTooLarge { node: usize, value: f64, max: u64 },
    #[error("node {node}: free surface {value} mm² must be finite and >= 0")]
    Surface { node: usize, value: f64 },
    #[error("node {node}: substrate area {value} mm² must be finite and >= 0")]
    Substrate { node: usize, value: f64 },
    #[error("contact {contact} ({a}, {b}): area {value} mm² must be finite and >= 0")]
    Area {
        contact: usize,
        a: u32,
        b: u32,
        value: f64,
    },
    #[error(
        "contact {contact} ({a}, {b}): node {node} out of range (the graph has {nodes} nodes)"
    )]
    OutOfRange {
        contact: usize,
        a: u32,
        b: u32,
        node: u32,
        nodes: usize,
    },
    #[error("contact {contact} joins node {node} to itself")]
    SelfContact { contact: usize, node: u32 },
    #[error("contact {contact} ({a}, {b}) repeats contact {first}")]
    Duplicate {
        contact: usize,
        first: usize,
        a: u32,
        b: u32,
    },
    #[error("{nodes} nodes: more than the {max} a simulation can hold")]
    TooManyNodes { nodes: usize, max: usize },
}

/// One entry of a node's contact list: the other node and the coefficients of the contact
/// as seen from this node.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Link {
    pub other: u32,
    /// a_ik = A_ik / A0.
    pub area: f64,
    /// g_ik = (h · a_ik) · (V0 / V_i), 1/s.
    pub coef: f64,
}

/// The per-part constants of the graph model, computed once and shared by every
/// simulation.
#[derive(Debug, Clone)]
pub struct GraphModel {
    pub params: ThermalParams,
    pub dt: f64,
    pub transit_steps: u64,
    pub cooldown_steps: u64,
    /// A0 = W·H, mm².
    pub area_ref: f64,
    /// V0 = W·W·H, mm³.
    pub volume_ref: f64,
    /// (ambient + 273.15)^4, as the block model computes it.
    pub(crate) ambient_k4: f64,
    /// Per node: V0 / V_i.
    pub(crate) inv_volume: Vec<f64>,
    /// Per node: S_i / A0 and B_i / A0.
    pub(crate) surface: Vec<f64>,
    pub(crate) base: Vec<f64>,
    /// Per node: s_i = (h_s · B_i / A0) · (V0 / V_i), 1/s.
    pub(crate) substrate: Vec<f64>,
    pub(crate) deposit_steps: Vec<u64>,
    /// Node i's contacts are `links[start[i]..start[i + 1]]`, in contact-list order.
    pub(crate) start: Vec<u32>,
    pub(crate) links: Vec<Link>,
    /// Per link: the index of the same contact's link in the other node's list.
    pub(crate) mirror: Vec<u32>,
}

impl GraphModel {
    /// Builds the model of `nodes` joined by `contacts` (a, b, area in mm²), with the
    /// constants `params` and the reference bead width `w` and layer height `h` (mm).
    /// Node i's contacts are summed in the order they appear in `contacts`.
    pub fn new(
        params: ThermalParams,
        w: f64,
        h: f64,
        nodes: &[NodeGeometry],
        contacts: &[(u32, u32, f64)],
    ) -> Result<GraphModel, GraphError> {
        if !(w.is_finite() && w > 0.0 && h.is_finite() && h > 0.0) {
            return Err(GraphError::Reference { w, h });
        }
        let n = nodes.len();
        // Slots are gather indices (i32) and the kernels pad to a multiple of 4.
        let max = i32::MAX as usize - 8;
        if n > max {
            return Err(GraphError::TooManyNodes { nodes: n, max });
        }
        let area_ref = w * h;
        let volume_ref = w * w * h;
        let dt = params.dt();
        let p = &params;
        let mut inv_volume = Vec::with_capacity(n);
        let mut surface = Vec::with_capacity(n);
        let mut base = Vec::with_capacity(n);
        let mut substrate = Vec::with_capacity(n);
        let mut deposit_steps = Vec::with_capacity(n);
        let good = |x: f64| x.is_finite() && x >= 0.0;
        for (node, g) in nodes.iter().enumerate() {
            if !(g.volume.is_finite() && g.volume > 0.0) {
                return Err(GraphError::Volume {
                    node,
                    value: g.volume,
                });
            }
            if !good(g.surface) {
                return Err(GraphError::Surface {
                    node,
                    value: g.surface,
                });
            }
            if !good(g.substrate) {
                return Err(GraphError::Substrate {
                    node,
                    value: g.substrate,
                });
            }
            let steps = deposit_steps_of(p.substeps, g.volume / volume_ref);
            if steps > MAX_STEPS {
                return Err(GraphError::VolumeTooLarge {
                    node,
                    value: g.volume,
                    max: MAX_STEPS,
                });
            }
            let v = volume_ref / g.volume;
            let b = g.substrate / area_ref;
            inv_volume.push(v);
            surface.push(g.surface / area_ref);
            base.push(b);
            substrate.push((p.substrate_per_s * b) * v);
            deposit_steps.push(steps);
        }
        let mut degree = vec![0u32; n + 1];
        let mut seen = pairs::PairSet::with_capacity(contacts.len());
        for (contact, &(a, b, area)) in contacts.iter().enumerate() {
            for node in [a, b] {
                if node as usize >= n {
                    return Err(GraphError::OutOfRange {
                        contact,
                        a,
                        b,
                        node,
                        nodes: n,
                    });
                }
            }
            if a == b {
                return Err(GraphError::SelfContact { contact, node: a });
            }
            if !good(area) {
                return Err(GraphError::Area {
                    contact,
                    a,
                    b,
                    value: area,
                });
            }
            if let Some(first) = seen.insert(a.min(b), a.max(b), contact) {
                return Err(GraphError::Duplicate {
                    contact,
                    first,
                    a,
                    b,
                });
            }
            degree[a as usize] += 1;
            degree[b as usize] += 1;
        }
        // Counting sort into per-node lists; walking the contacts in order keeps each
        // node's list in contact-list order, the doc's order of summation.
        let mut start = vec![0u32; n + 1];
        for i in 0..n {
            start[i + 1] = start[i] + degree[i];
        }
        let mut fill: Vec<u32> = start[..n].to_vec();
        let empty = Link {
            other: 0,
            area: 0.0,
            coef: 0.0,
        };
        let mut links = vec![empty; start[n] as usize];
        let mut mirror = vec![0u32; links.len()];
        for &(a, b, area) in contacts {
            let a_n = area / area_ref;
            let (at_a, at_b) = (fill[a as usize], fill[b as usize]);
            for (i, j, at) in [(a, b, at_a), (b, a, at_b)] {
                links[at as usize] = Link {
                    other: j,
                    area: a_n,
                    coef: (p.conduction_per_s * a_n) * inv_volume[i as usize],
                };
                fill[i as usize] += 1;
            }
            mirror[at_a as usize] = at_b;
            mirror[at_b as usize] = at_a;
        }
        Ok(GraphModel {
            params,
            dt,
            transit_steps: round_steps(p.transit_time_s / dt),
            cooldown_steps: round_steps(p.max_cooldown_s / dt),
            area_ref,
            volume_ref,
            // powf, not powi: the same libm pow as the block model and its checker.
            ambient_k4: (p.ambient_c + 273.15).powf(4.0),
            inv_volume,
            surface,
            base,
            substrate,
            deposit_steps,
            start,
            links,
            mirror,
        })
    }

    /// Number of nodes.
    pub fn len(&self) -> usize {
        self.inv_volume.len()
    }

    /// True for a model of no nodes.
    pub fn is_empty(&self) -> bool {
        self.inv_volume.is_empty()
    }

    /// Euler steps that follow the deposit of `node`: max(1, round(substeps · V_i / V0)).
    pub fn deposit_steps(&self, node: usize) -> u64 {
        self.deposit_steps[node]
    }

    /// The most contacts of one node.
    pub fn max_degree(&self) -> usize {
        self.start
            .windows(2)
            .map(|w| (w[1] - w[0]) as usize)
            .max()
            .unwrap_or(0)
    }

    /// The largest dt · (Σ_k g_ik + s_i) over the nodes: the explicit step oscillates
    /// above 1 and diverges above 2 (radiation aside). Slivers (V_i ≪ V0 with large
    /// contacts) drive it up; the graph maker should merge them.
    pub fn stiffness(&self) -> f64 {
        (0..self.len())
            .map(|i| {
                let g: f64 = self.links(i).iter().map(|l| l.coef).sum();
                self.dt * (g + self.substrate[i])
            })
            .fold(0.0, f64::max)
    }

    /// Node i's contacts in the order of summation.
    pub(crate) fn links(&self, i: usize) -> &[Link] {
        &self.links[self.start[i] as usize..self.start[i + 1] as usize]
    }

    /// ρ_i = (r · F_i) · (V0 / V_i), F_i the free surface in A0 of node i while the
    /// nodes with `welded` are welded: S_i/A0 − B_i/A0, minus the welded contacts' a_ik in
    /// contact order, 0 if that is <= 0.
    pub(crate) fn radiation(&self, i: usize, welded: impl Fn(u32) -> bool) -> f64 {
        let mut free = self.surface[i] - self.base[i];
        for l in self.links(i) {
            if welded(l.other) {
                free -= l.area;
            }
        }
        if free <= 0.0 {
            free = 0.0;
        }
        (self.params.radiation_per_s_k3 * free) * self.inv_volume[i]
    }
}

/// Rounds a non-negative step count, halves away from zero (as the block model does).
fn round_steps(x: f64) -> u64 {
    (x + 0.5).floor() as u64
}

/// max(1, round(substeps · ratio)), halves away from zero; saturates for huge ratios.
fn deposit_steps_of(substeps: u32, ratio: f64) -> u64 {
    let x = substeps as f64 * ratio;
    if x >= 2f64.powi(62) {
        return u64::MAX;
    }
    round_steps(x).max(1)
}

/// A small open-addressing set of node pairs, to find a repeated contact without a
/// dependency (rustc-hash is not one of this crate's).
mod pairs {
    pub struct PairSet {
        keys: Vec<u64>,
        vals: Vec<usize>,
        mask: usize,
    }

    const EMPTY: u64 = u64::MAX;

    impl PairSet {
        pub fn with_capacity(n: usize) -> PairSet {
            let size = (2 * n + 2).next_power_of_two();
            PairSet {
                keys: vec![EMPTY; size],
                vals: vec![0; size],
                mask: size - 1,
            }
        }

        /// Inserts (a, b) with `val`; returns the value of an earlier equal pair instead.
        pub fn insert(&mut self, a: u32, b: u32, val: usize) -> Option<usize> {
            let key = (a as u64) << 32 | b as u64;
            let mut at = (key.wrapping_mul(0x9e37_79b9_7f4a_7c15) >> 32) as usize & self.mask;
            loop {
                if self.keys[at] == EMPTY {
                    self.keys[at] = key;
                    self.vals[at] = val;
                    return None;
                }
                if self.keys[at] == key {
                    return Some(self.vals[at]);
                }
                at = (at + 1) & self.mask;
            }
        }
    }
}
