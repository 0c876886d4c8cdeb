//! A warm start for graph parts: each layer walked bead by bead from where the layer below
//! ended, so that one weld path climbs on through the part as a cell welds a tube (a ring,
//! then up onto the next ring: a spiral).
//!
//! Within a layer the walk keeps to the bead it is on (a ring is welded round before the
//! torch steps beside onto the next one); among several next nodes it takes the one with
//! the fewest unwelded neighbours left in the layer (Warnsdorff's rule, which leaves no
//! stranded nodes behind on rings, rasters and strips), then the nearest. Where it is stuck
//! with nodes left, a new weld path starts at the loneliest of them. Each layer's walk is
//! tried from every node that stands on where the layer below ended and in both directions
//! along its bead, and the walk with the fewest weld paths that ends under the next layer
//! is kept. Layers are welded whole, one after the other, so gravity holds by construction.
//!
//! The plan is a hint, never a claim: the global search judges it like any candidate and
//! decides what is feasible, best or impossible.

use waam_part::graph::WeldGraph;
use waam_part::{BeadPart, Part};

use crate::constructive::Limits;

/// A valid plan of the graph part `part` with at most `k` fragments, built layer by layer;
/// `None` when this construction needs more, or the limits stop it.
pub fn layered_plan(
    part: &Part,
    graph: &WeldGraph,
    k: usize,
    limits: &Limits,
) -> Option<Vec<Vec<usize>>> {
    let beads = part.bead_part()?;
    let layer = |i: usize| part.block(i)[2];
    let mut plan: Vec<Vec<usize>> = Vec::new();
    let mut start = 0;
    let mut welded = vec![false; part.len()];
    while start < part.len() {
        if limits.stopped() {
            return None;
        }
        let z = layer(start);
        let end = (start..part.len())
            .find(|&i| layer(i) != z)
            .unwrap_or(part.len());
        let next_layer = (end < part.len()).then(|| layer(end));
        // Where the weld path arriving from below may go on: onto what stands on its end.
        let arriving: Vec<usize> = plan
            .last()
            .and_then(|f| f.last())
            .map(|&e| {
                graph
                    .successors(e)
                    .iter()
                    .map(|&j| j as usize)
                    .filter(|&j| (start..end).contains(&j))
                    .collect()
            })
            .unwrap_or_default();
        let walker = Walker {
            graph,
            beads,
            range: start..end,
            next_layer,
            layer: &layer,
        };
        let starts = if arriving.is_empty() {
            walker.loneliest(&welded, 4)
        } else {
            arriving.clone()
        };
        let pieces = starts
            .iter()
            .flat_map(|&s| [false, true].map(|reverse| walker.walk(s, reverse, &welded)))
            .min_by_key(|w| (w.len(), !walker.ends_under_next(w)))?;
        for (p, piece) in pieces.into_iter().enumerate() {
            for &i in &piece {
                welded[i] = true;
            }
            match plan.last_mut() {
                Some(f) if p == 0 && arriving.contains(&piece[0]) => f.extend(piece),
                _ => plan.push(piece),
            }
        }
        if plan.len() > k {
            tracing::debug!(
                "contour warm start: {} weld paths by layer {z} (of {}), more than k = {k}",
                plan.len(),
                part.layers()
            );
            return None;
        }
        start = end;
    }
    Some(plan)
}

/// One layer's walk.
struct Walker<'a, L: Fn(usize) -> i64> {
    graph: &'a WeldGraph,
    beads: &'a BeadPart,
    range: std::ops::Range<usize>,
    next_layer: Option<i64>,
    layer: &'a L,
}

impl<L: Fn(usize) -> i64> Walker<'_, L> {
    /// The moves from `i` that stay in the layer.
    fn sideways(&self, i: usize) -> impl Iterator<Item = usize> + '_ {
        self.graph
            .successors(i)
            .iter()
            .map(|&j| j as usize)
            .filter(|j| self.range.contains(j))
    }

    fn free_neighbours(&self, i: usize, welded: &[bool]) -> usize {
        self.sideways(i).filter(|&j| !welded[j]).count()
    }

    fn distance(&self, a: usize, b: usize) -> f64 {
        let (p, q) = (self.beads.nodes[a].centre_mm, self.beads.nodes[b].centre_mm);
        (p[0] - q[0]).hypot(p[1] - q[1])
    }

    /// Up to `count` unwelded nodes of the layer with the fewest unwelded neighbours (the
    /// ends of open beads first), lowest index first on a tie.
    fn loneliest(&self, welded: &[bool], count: usize) -> Vec<usize> {
        let mut free: Vec<usize> = self.range.clone().filter(|&i| !welded[i]).collect();
        free.sort_by_key(|&i| (self.free_neighbours(i, welded), i));
        free.truncate(count);
        free
    }

    /// Whether the walk's last node has a node of the next layer standing on it (there is
    /// no next layer: it does not matter).
    fn ends_under_next(&self, pieces: &[Vec<usize>]) -> bool {
        let Some(next) = self.next_layer else {
            return true;
        };
        pieces.last().and_then(|p| p.last()).is_some_and(|&e| {
            self.graph
                .successors(e)
                .iter()
                .any(|&j| (self.layer)(j as usize) == next)
        })
    }

    /// Covers the layer's unwelded nodes from `first`, setting off the other way along its
    /// bead when `reverse`: the pieces (weld paths within the layer) in weld order.
    fn walk(&self, first: usize, reverse: bool, welded: &[bool]) -> Vec<Vec<usize>> {
        let mut welded = welded.to_vec();
        let mut left = self.range.clone().filter(|&i| !welded[i]).count();
        let mut pieces: Vec<Vec<usize>> = Vec::new();
        let mut at = first;
        let mut piece = vec![first];
        welded[first] = true;
        left -= 1;
        while left > 0 {
            let bead = self.beads.nodes[at].bead;
            let mut options: Vec<usize> = self.sideways(at).filter(|&j| !welded[j]).collect();
            // The first step sets the direction along the bead: `reverse` takes the other
            // neighbour on it.
            if piece.len() == 1 && pieces.is_empty() && reverse {
                let along: Vec<usize> = options
                    .iter()
                    .copied()
                    .filter(|&j| self.beads.nodes[j].bead == bead)
                    .collect();
                if along.len() == 2 {
                    options.retain(|&j| j != along[0]);
                }
            }
            let next = options.into_iter().min_by(|&a, &b| {
                let key = |j: usize| {
                    (
                        self.beads.nodes[j].bead != bead,
                        self.free_neighbours(j, &welded),
                    )
                };
                key(a)
                    .cmp(&key(b))
                    .then(self.distance(at, a).total_cmp(&self.distance(at, b)))
                    .then(a.cmp(&b))
            });
            let next = match next {
                Some(j) => j,
                None => {
                    // Stuck: a new weld path at the loneliest node left, nearest first.
                    let mut lonely = self.loneliest(&welded, usize::MAX);
                    let fewest = self.free_neighbours(lonely[0], &welded);
                    lonely.retain(|&j| self.free_neighbours(j, &welded) == fewest);
                    let j = lonely
                        .into_iter()
                        .min_by(|&a, &b| self.distance(at, a).total_cmp(&self.distance(at, b)))
                        .expect("a node left");
                    pieces.push(std::mem::take(&mut piece));
                    j
                }
            };
            welded[next] = true;
            left -= 1;
            piece.push(next);
            at = next;
        }
        pieces.push(piece);
        pieces
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::fmt::Write as _;

    /// A graph part of `layers` layers, each `rings` concentric rings of `n` nodes, the
    /// rings side by side (node j beside node j of the next ring) and each node standing on
    /// the same node of the layer below (`flange` layers have all rings, the rest only the
    /// innermost, as a tube on a flange).
    fn tube_on_flange(flange: usize, layers: usize, rings: usize, n: usize, k: usize) -> Part {
        let (w, h) = (6.0, 2.5);
        let mut yaml =
            format!("kind: beads\nname: t\nmax_fragments: {k}\nbead_mm: [{w}, {h}]\nbeads:\n");
        let mut beads = Vec::new(); // (layer, ring)
        for z in 0..layers {
            for r in 0..if z < flange { rings } else { 1 } {
                let radius = 30.0 + w * r as f64;
                let points: Vec<String> = (0..n)
                    .map(|j| {
                        let a = std::f64::consts::TAU * j as f64 / n as f64;
                        format!("[{}, {}]", radius * a.cos(), radius * a.sin())
                    })
                    .collect();
                let _ = writeln!(
                    yaml,
                    "  - {{layer: {z}, closed: true, points: [{}]}}",
                    points.join(", ")
                );
                beads.push((z, r, radius));
            }
        }
        yaml.push_str("nodes:\n");
        let mut id = std::collections::HashMap::new();
        for (b, &(z, r, radius)) in beads.iter().enumerate() {
            let side = 2.0 * radius * (std::f64::consts::PI / n as f64).sin();
            let length = side * n as f64;
            for j in 0..n {
                let a = std::f64::consts::TAU * (j as f64 + 0.5) / n as f64;
                let (x, y) = (
                    radius * (std::f64::consts::PI / n as f64).cos() * a.cos(),
                    radius * (std::f64::consts::PI / n as f64).cos() * a.sin(),
                );
                let sub = if z == 0 { w * side } else { 0.0 };
                let _ = writeln!(
                    yaml,
                    "  - {{bead: {b}, from_mm: {}, to_mm: {}, layer: {z}, centre_mm: [{x}, {y}, {}], volume_mm3: {}, surface_mm2: {}, substrate_mm2: {sub}}}",
                    side * j as f64,
                    if j + 1 == n { length } else { side * (j + 1) as f64 },
                    (z as f64 + 0.5) * h,
                    w * h * side,
                    2.0 * side * (w + h) + 2.0 * w * h,
                );
                id.insert((z, r, j), id.len());
            }
        }
        yaml.push_str("contacts:\n");
        let mut contacts = Vec::new();
        for (&(z, r, j), &a) in &id {
            let mut add = |b: Option<&usize>, kind: &str| {
                if let Some(&b) = b {
                    contacts.push((a.min(b), a.max(b), kind.to_string()));
                }
            };
            add(id.get(&(z, r, (j + 1) % n)), "along");
            add(id.get(&(z, r + 1, j)), "beside");
            add(id.get(&(z + 1, r, j)), "stacked");
        }
        contacts.sort_by_key(|c| (c.0, c.1));
        contacts.dedup_by(|a, b| (a.0, a.1) == (b.0, b.1));
        for (a, b, kind) in contacts {
            let _ = writeln!(yaml, "  - [{a}, {b}, 10.0, {kind}]");
        }
        Part::of_beads(BeadPart::parse(&yaml).unwrap()).unwrap()
    }

    fn limits() -> Limits {
        Limits {
            deadline: None,
            cancel: None,
        }
    }

    /// A tube on a flange of three rings is welded as one weld path: each flange layer
    /// ring by ring, each tube layer round its ring, always going on from where the layer
    /// below ended; the plan is valid by the graph part's own rules.
    #[test]
    fn a_tube_on_a_flange_is_one_weld_path() {
        let part = tube_on_flange(2, 6, 3, 12, 1);
        let graph = WeldGraph::new(&part);
        let plan = layered_plan(&part, &graph, 1, &limits()).expect("a plan");
        assert_eq!(plan.len(), 1);
        let beads = part.bead_part().unwrap();
        let graph_plan = waam_part::GraphPlan {
            part: None,
            fragments: plan,
        };
        graph_plan.validate(beads, &beads.moves()).unwrap();
    }

    /// Rings side by side whose layer below ended where nothing stands need a second weld
    /// path; with k = 1 the construction says no.
    #[test]
    fn more_weld_paths_than_allowed_is_no_plan() {
        // Three rings on the plate and nothing joining them: three weld paths.
        let part = tube_on_flange(1, 1, 3, 8, 1);
        let part = {
            let mut beads = part.bead_part().unwrap().clone();
            beads
                .contacts
                .retain(|c| c.kind != waam_part::ContactKind::Beside);
            Part::of_beads(beads).unwrap()
        };
        let graph = WeldGraph::new(&part);
        assert!(layered_plan(&part, &graph, 2, &limits()).is_none());
        assert_eq!(layered_plan(&part, &graph, 3, &limits()).unwrap().len(), 3);
    }
}
