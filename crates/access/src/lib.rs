//! Torch access: whether the welding torch fits at a block, beside the blocks deposited
//! before it and above the plate.
//!
//! The torch ([`Torch`]) is a straight stack of three coaxial cylinders on its axis, measured
//! from the tool-centre point (TCP: the wire's end, at the top centre of the block being
//! welded): the gas nozzle from `nozzle_standoff_mm` up along the axis, the torch body
//! (neck) above the nozzle, and a simple volume for the robot's wrist above the body
//! ([`Torch::cylinders`]; the motion stage checks the same cylinders along every move with
//! the arc off). The axis is tilted from the vertical by the process settings'
//! travel and work angles ([`TorchSetup`]). Which way it leans depends on the travel heading
//! at the block, and that depends on the *next* move, which the planner has not fixed when
//! it checks a deposit. So the check takes the torch turned about the vertical through the
//! TCP into every heading, as a solid of revolution that contains that sweep: at height h
//! above the TCP a disc of radius |h|·tan θ + r / cos θ (θ the tilt, r a cylinder's
//! radius). A deposit is blocked when that solid overlaps the box of a block deposited
//! before it by more than a micrometre (touching is clearance), or reaches below the
//! plate's top (z < 0 in the part frame).
//!
//! The check of a deposit depends only on the set of blocks deposited before it, and more
//! deposited blocks never unblock it: a blocked deposit rules out exactly the plans that
//! deposit the same blocks before it (the planner's prefix clause is sound).
//!
//! A graph part ([`TorchAccess::of_beads`]) is checked on its beads, not on its stand-in
//! blocks: the TCP anywhere on the node's piece of centre line, the other nodes' beads
//! as their pieces widened to the bead width.

use rustc_hash::FxHashMap;
use serde::{Deserialize, Serialize};
use thiserror::Error;

use waam_part::{BeadPart, Part};

/// Overlaps and clearances below this (mm) count as touching, not as a collision.
const EPS_MM: f64 = 1e-3;

/// A torch model that cannot be used, naming the key.
#[derive(Debug, Error, PartialEq)]
#[error("torch.{key}: {reason}")]
pub struct TorchError {
    pub key: &'static str,
    pub reason: String,
}

/// The welding torch as the access check sees it: a gas nozzle, a body above it and the
/// robot's wrist above that, all cylinders on the torch axis. Lengths in mm.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Torch {
    /// Outer diameter of the gas nozzle.
    pub nozzle_diameter_mm: f64,
    /// From the TCP (the wire's end on the top of the block being welded) to the nozzle's
    /// end, along the torch axis.
    pub nozzle_standoff_mm: f64,
    /// Length of the nozzle along the axis, from its end up.
    pub nozzle_length_mm: f64,
    /// Diameter of the torch body (neck) above the nozzle.
    pub body_diameter_mm: f64,
    /// Length of the body along the axis, from the nozzle's top up.
    pub body_length_mm: f64,
    /// Diameter of the cylinder that stands for the robot's wrist (the last links and the
    /// torch mount) above the body.
    pub wrist_diameter_mm: f64,
    /// Length of that cylinder along the axis, from the body's top up (0: no wrist).
    pub wrist_length_mm: f64,
}

/// One cylinder of the torch on its axis: from `from_mm` to `to_mm` up the axis from the
/// TCP, of radius `radius_mm`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cylinder {
    pub from_mm: f64,
    pub to_mm: f64,
    pub radius_mm: f64,
}

impl Default for Torch {
    /// A typical GMAW torch: a gas nozzle 18 mm across whose end is 12 mm above the top of
    /// the block being welded, 60 mm long, under a straight 30 mm body 150 mm long, under a
    /// wrist 100 mm across and 120 mm long (a 6-axis arm's flange and last links).
    fn default() -> Self {
        Torch {
            nozzle_diameter_mm: 18.0,
            nozzle_standoff_mm: 12.0,
            nozzle_length_mm: 60.0,
            body_diameter_mm: 30.0,
            body_length_mm: 150.0,
            wrist_diameter_mm: 100.0,
            wrist_length_mm: 120.0,
        }
    }
}

impl Torch {
    /// Checks every value's range.
    pub fn validate(&self) -> Result<(), TorchError> {
        let check = |key: &'static str, v: f64, zero_ok: bool| {
            if v.is_finite() && (v > 0.0 || (zero_ok && v == 0.0)) {
                Ok(())
            } else {
                let bound = if zero_ok { ">= 0" } else { "> 0" };
                Err(TorchError {
                    key,
                    reason: format!("must be a number {bound}, got {v}"),
                })
            }
        };
        check("nozzle_diameter_mm", self.nozzle_diameter_mm, false)?;
        check("nozzle_standoff_mm", self.nozzle_standoff_mm, true)?;
        check("nozzle_length_mm", self.nozzle_length_mm, false)?;
        check("body_diameter_mm", self.body_diameter_mm, true)?;
        check("body_length_mm", self.body_length_mm, true)?;
        check("wrist_diameter_mm", self.wrist_diameter_mm, true)?;
        check("wrist_length_mm", self.wrist_length_mm, true)?;
        Ok(())
    }

    /// The nozzle, the body and the wrist, bottom up; pieces of zero size left out.
    pub fn cylinders(&self) -> Vec<Cylinder> {
        let mut out = Vec::new();
        let mut from = self.nozzle_standoff_mm;
        for (d, len) in [
            (self.nozzle_diameter_mm, self.nozzle_length_mm),
            (self.body_diameter_mm, self.body_length_mm),
            (self.wrist_diameter_mm, self.wrist_length_mm),
        ] {
            if d > 0.0 && len > 0.0 {
                out.push(Cylinder {
                    from_mm: from,
                    to_mm: from + len,
                    radius_mm: 0.5 * d,
                });
            }
            from += len;
        }
        out
    }
}

/// A torch held at a fixed tilt from the vertical: what the planner checks access with.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TorchSetup {
    pub torch: Torch,
    /// Angle between the torch axis and the vertical, degrees, in [0, 90).
    pub tilt_deg: f64,
}

impl TorchSetup {
    /// The torch tilted by a travel angle and a work angle (degrees, as in the process
    /// settings): the axis leans by θ from the vertical with cos θ = cos(travel)·cos(work).
    pub fn new(torch: Torch, travel_angle_deg: f64, work_angle_deg: f64) -> TorchSetup {
        let c = travel_angle_deg.to_radians().cos() * work_angle_deg.to_radians().cos();
        TorchSetup {
            torch,
            tilt_deg: c.clamp(-1.0, 1.0).acos().to_degrees(),
        }
    }

    /// Checks the torch and the tilt.
    pub fn validate(&self) -> Result<(), TorchError> {
        self.torch.validate()?;
        if !(self.tilt_deg.is_finite() && (0.0..90.0).contains(&self.tilt_deg)) {
            return Err(TorchError {
                key: "tilt_deg",
                reason: format!("must be in [0, 90), got {}", self.tilt_deg),
            });
        }
        Ok(())
    }

    /// The lowest point of the torch in any heading, mm above the TCP (negative: below it).
    /// A transit at safe height keeps the whole torch this much lower than the TCP.
    pub fn lowest_mm(&self) -> f64 {
        Envelope::new(self).lowest()
    }

    /// One line on the torch, for logs and reports.
    pub fn describe(&self) -> String {
        let t = &self.torch;
        format!(
            "nozzle {} mm across, its end {} mm from the wire's end, {} mm long; body {} mm \
             across, {} mm long; wrist {} mm across, {} mm long; tilted {:.1}° from the vertical",
            t.nozzle_diameter_mm,
            t.nozzle_standoff_mm,
            t.nozzle_length_mm,
            t.body_diameter_mm,
            t.body_length_mm,
            t.wrist_diameter_mm,
            t.wrist_length_mm,
            self.tilt_deg
        )
    }
}

/// One cylinder of the torch, swept about the vertical through the TCP: heights (mm above
/// the TCP) it spans, and its radius bound `(max(h, 0) + extra)·tan θ + r / cos θ`.
#[derive(Debug, Clone, Copy)]
struct Segment {
    lo: f64,
    hi: f64,
    r_eff: f64,
    extra: f64,
}

/// The swept torch: a solid of revolution about the vertical through the TCP.
#[derive(Debug, Clone)]
struct Envelope {
    tan: f64,
    segments: Vec<Segment>,
}

impl Envelope {
    fn new(setup: &TorchSetup) -> Envelope {
        let t = &setup.torch;
        let theta = setup.tilt_deg.to_radians();
        let (sin, cos) = theta.sin_cos();
        let mut segments = Vec::new();
        let mut push = |r: f64, s0: f64, s1: f64| {
            if r <= 0.0 || s1 <= s0 {
                return;
            }
            // The cylinder's lowest and highest points; between them, a point at height h
            // lies within |h|·tan θ + r / cos θ of the vertical axis (triangle inequality),
            // which the bound keeps monotone in h when the cylinder dips below the TCP.
            let lo = s0 * cos - r * sin;
            segments.push(Segment {
                lo,
                hi: s1 * cos + r * sin,
                r_eff: r / cos,
                extra: (-lo).max(0.0),
            });
        };
        for c in t.cylinders() {
            push(c.radius_mm, c.from_mm, c.to_mm);
        }
        Envelope {
            tan: theta.tan(),
            segments,
        }
    }

    fn radius(&self, s: &Segment, h: f64) -> f64 {
        (h.max(0.0) + s.extra) * self.tan + s.r_eff
    }

    /// The lowest point of the torch, mm above the TCP.
    fn lowest(&self) -> f64 {
        self.segments
            .iter()
            .map(|s| s.lo)
            .fold(f64::INFINITY, f64::min)
    }

    /// The farthest the torch reaches from the vertical through the TCP, mm.
    fn reach(&self) -> f64 {
        self.segments
            .iter()
            .map(|s| self.radius(s, s.hi))
            .fold(0.0, f64::max)
    }
}

/// What the torch hits at a deposit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(tag = "kind", content = "block", rename_all = "snake_case")]
pub enum Obstacle {
    /// The plate (the torch would reach below its top).
    Plate,
    /// A block deposited before (its index in the part).
    Block(usize),
}

/// The first deposit of a weld order whose torch is blocked.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Blocked {
    /// Its position in the weld order, from 0 (the blocks before it are deposited).
    pub position: usize,
    /// The block that cannot be welded (its index in the part).
    pub block: usize,
    pub obstacle: Obstacle,
}

/// Torch access of every block of one part: for each block, the few blocks whose
/// deposit before it blocks the torch there.
///
/// Only the lowest such block of each stack (a column's run of blocks one on another) is
/// kept: the plan rules weld a block only on the block below it, so when any block of a
/// stack stands, so does the stack's lowest. [`TorchAccess::obstacle`] and
/// [`TorchAccess::first_blocked`] are exact for deposit orders that keep that rule (every
/// valid plan does).
#[derive(Debug, Clone)]
pub struct TorchAccess {
    setup: TorchSetup,
    /// `probes[offsets[b]..offsets[b + 1]]`: the blocks to look at for block `b`.
    offsets: Vec<usize>,
    probes: Vec<u32>,
    /// Blocks whose torch reaches below the plate's top.
    plate: Vec<bool>,
}

impl TorchAccess {
    /// The access of every block of `part` for the torch `setup` (of every node, for a
    /// graph part: [`TorchAccess::of_beads`]).
    pub fn new(part: &Part, setup: &TorchSetup) -> TorchAccess {
        if let Some(beads) = part.bead_part() {
            return TorchAccess::of_beads(beads, setup);
        }
        let env = Envelope::new(setup);
        let [px, py, pz] = part.block_mm;
        let oz = part.origin_mm[2];
        // Columns: the blocks at one (x, y), bottom up, and where each stack starts.
        let mut columns: FxHashMap<(i64, i64), Column> = FxHashMap::default();
        for (i, b) in part.blocks().iter().enumerate() {
            let c = columns.entry((b[0], b[1])).or_default();
            if c.z.last().is_none_or(|&z| z.checked_add(1) != Some(b[2])) {
                c.run_starts.push(c.z.len());
            }
            c.z.push(b[2]);
            c.index.push(i as u32);
        }
        let reach = env.reach();
        let rx = (reach / px).ceil() as i64 + 1;
        let ry = (reach / py).ceil() as i64 + 1;
        let keys: Vec<(i64, i64)> = columns.keys().copied().collect();
        // The columns near each column, with their horizontal distance from its centre line:
        // found by scanning the square around it, or all columns when they are fewer.
        let scan = (2 * rx + 1).saturating_mul(2 * ry + 1);
        let mut per_block: Vec<Vec<u32>> = vec![Vec::new(); part.len()];
        let mut plate = vec![false; part.len()];
        for &(x, y) in &keys {
            let mut near: Vec<(f64, &Column)> = Vec::new();
            let mut consider = |(cx, cy): (i64, i64)| {
                let (Some(dx), Some(dy)) = (cx.checked_sub(x), cy.checked_sub(y)) else {
                    return;
                };
                let rho = near_distance(dx, dy, px, py);
                if rho < reach {
                    if let Some(c) = columns.get(&(cx, cy)) {
                        near.push((rho, c));
                    }
                }
            };
            if scan <= keys.len() as i64 {
                for dx in -rx..=rx {
                    for dy in -ry..=ry {
                        if let (Some(cx), Some(cy)) = (x.checked_add(dx), y.checked_add(dy)) {
                            consider((cx, cy));
                        }
                    }
                }
            } else {
                keys.iter().for_each(|&k| consider(k));
            }
            let own = &columns[&(x, y)];
            for (&zb, &b) in own.z.iter().zip(&own.index) {
                let top = oz + (zb as f64 + 1.0) * pz;
                plate[b as usize] = top + env.lowest() < -EPS_MM;
                let probes = &mut per_block[b as usize];
                for &(rho, c) in &near {
                    for s in &env.segments {
                        // Heights of layer z's box relative to the TCP.
                        let zlo = |k: usize| (c.z[k] as f64 - zb as f64 - 1.0) * pz;
                        let zhi = |k: usize| (c.z[k] as f64 - zb as f64) * pz;
                        // The hit layers form one range: from the first box that
                        // rises into the segment within its radius, to the last box
                        // that starts below the segment's top.
                        let k0 = first(c.z.len(), |k| {
                            zhi(k) > s.lo + EPS_MM && env.radius(s, zhi(k).min(s.hi)) > rho + EPS_MM
                        });
                        let k1 = first(c.z.len(), |k| zlo(k) >= s.hi - EPS_MM);
                        if k0 >= k1 {
                            continue;
                        }
                        probes.push(c.index[k0]);
                        let r0 = c.run_starts.partition_point(|&r| r <= k0);
                        let r1 = c.run_starts.partition_point(|&r| r < k1);
                        probes.extend(c.run_starts[r0..r1].iter().map(|&r| c.index[r]));
                    }
                }
                probes.retain(|&p| p != b);
                probes.sort_unstable();
                probes.dedup();
            }
        }
        let mut offsets = Vec::with_capacity(part.len() + 1);
        offsets.push(0);
        let mut probes = Vec::new();
        for p in per_block {
            probes.extend(p);
            offsets.push(probes.len());
        }
        TorchAccess {
            setup: *setup,
            offsets,
            probes,
            plate,
        }
    }

    /// The access of every node of a graph part: the torch's TCP anywhere on the node's
    /// piece of centre line, at the top of its layer; a node deposited before it is in the
    /// way when the swept torch overlaps its bead (its piece widened by W/2 each side, from
    /// its layer's bottom to its top) by more than a micrometre. The horizontal distance is
    /// taken between the two pieces (the nearest TCP on the piece), so the check holds
    /// wherever along its piece the torch is. The plate's top is `base_z_mm`. Every node
    /// in the way is probed (the stack shortcut of blocks assumes a grid).
    pub fn of_beads(part: &BeadPart, setup: &TorchSetup) -> TorchAccess {
        let env = Envelope::new(setup);
        let [w, h] = part.bead_mm;
        let n = part.nodes.len();
        let pieces: Vec<Vec<[f64; 2]>> = part
            .nodes
            .iter()
            .map(|d| part.beads[d.bead].piece_mm(d.from_mm, d.to_mm))
            .collect();
        let bbox = |p: &[[f64; 2]]| {
            p.iter().fold(
                [
                    f64::INFINITY,
                    f64::INFINITY,
                    f64::NEG_INFINITY,
                    f64::NEG_INFINITY,
                ],
                |b, q| {
                    [
                        b[0].min(q[0]),
                        b[1].min(q[1]),
                        b[2].max(q[0]),
                        b[3].max(q[1]),
                    ]
                },
            )
        };
        let boxes: Vec<[f64; 4]> = pieces.iter().map(|p| bbox(p)).collect();
        // Nodes by layer and grid cell: a node's candidates in a layer lie within that
        // layer's reach (the widest the swept torch is at the layer's heights).
        let layers = part.layers() as usize;
        let cell = 4.0 * w;
        let key = |x: f64, y: f64| ((x / cell).floor() as i64, (y / cell).floor() as i64);
        let mut grids: Vec<FxHashMap<(i64, i64), Vec<u32>>> = vec![FxHashMap::default(); layers];
        for (j, (b, d)) in boxes.iter().zip(&part.nodes).enumerate() {
            let (lo, hi) = (key(b[0], b[1]), key(b[2], b[3]));
            for x in lo.0..=hi.0 {
                for y in lo.1..=hi.1 {
                    grids[d.layer as usize]
                        .entry((x, y))
                        .or_default()
                        .push(j as u32);
                }
            }
        }
        let lowest = env.lowest();
        let mut offsets = Vec::with_capacity(n + 1);
        offsets.push(0);
        let mut probes: Vec<u32> = Vec::new();
        let mut plate = Vec::with_capacity(n);
        // seen[j] == i + 1: node j was looked at for node i.
        let mut seen = vec![0u32; n];
        for (i, d) in part.nodes.iter().enumerate() {
            plate.push((d.layer as f64 + 1.0) * h + lowest < -EPS_MM);
            let start = probes.len();
            for (layer, grid) in grids.iter().enumerate() {
                // That layer's heights relative to the TCP, and the torch's widest there.
                let zhi = (layer as f64 - d.layer as f64) * h;
                let zlo = zhi - h;
                let Some(radius) = env
                    .segments
                    .iter()
                    .filter(|s| zhi > s.lo + EPS_MM && zlo < s.hi - EPS_MM)
                    .map(|s| env.radius(s, zhi.min(s.hi)))
                    .reduce(f64::max)
                else {
                    continue;
                };
                let reach = radius + 0.5 * w;
                let b = boxes[i];
                let (lo, hi) = (
                    key(b[0] - reach, b[1] - reach),
                    key(b[2] + reach, b[3] + reach),
                );
                for x in lo.0..=hi.0 {
                    for y in lo.1..=hi.1 {
                        for &j in grid.get(&(x, y)).into_iter().flatten() {
                            let ju = j as usize;
                            if ju == i || seen[ju] == i as u32 + 1 {
                                continue;
                            }
                            seen[ju] = i as u32 + 1;
                            // Boxes farther apart than the reach cannot be closer.
                            let o = boxes[ju];
                            let gap_x = (o[0] - b[2]).max(b[0] - o[2]).max(0.0);
                            let gap_y = (o[1] - b[3]).max(b[1] - o[3]).max(0.0);
                            if gap_x * gap_x + gap_y * gap_y >= reach * reach {
                                continue;
                            }
                            let rho =
                                (polyline_distance(&pieces[i], &pieces[ju]) - 0.5 * w).max(0.0);
                            if radius > rho + EPS_MM {
                                probes.push(j);
                            }
                        }
                    }
                }
            }
            probes[start..].sort_unstable();
            offsets.push(probes.len());
        }
        TorchAccess {
            setup: *setup,
            offsets,
            probes,
            plate,
        }
    }

    /// The torch this access was computed for.
    pub fn setup(&self) -> &TorchSetup {
        &self.setup
    }

    /// What the torch hits at block `b` when `deposited(i)` tells which blocks stand
    /// (`None`: it fits).
    pub fn obstacle(&self, b: usize, deposited: impl Fn(usize) -> bool) -> Option<Obstacle> {
        if self.plate[b] {
            return Some(Obstacle::Plate);
        }
        self.probes[self.offsets[b]..self.offsets[b + 1]]
            .iter()
            .find(|&&p| deposited(p as usize))
            .map(|&p| Obstacle::Block(p as usize))
    }

    /// The first deposit of `order` (block indices in weld order) whose torch is blocked.
    pub fn first_blocked(&self, order: impl IntoIterator<Item = usize>) -> Option<Blocked> {
        let mut deposited = vec![false; self.plate.len()];
        for (position, b) in order.into_iter().enumerate() {
            if let Some(obstacle) = self.obstacle(b, |i| deposited[i]) {
                return Some(Blocked {
                    position,
                    block: b,
                    obstacle,
                });
            }
            deposited[b] = true;
        }
        None
    }
}

/// The least distance between two polylines in the plane.
fn polyline_distance(a: &[[f64; 2]], b: &[[f64; 2]]) -> f64 {
    let segs = |p: &[[f64; 2]]| -> Vec<([f64; 2], [f64; 2])> {
        match p.len() {
            0 => Vec::new(),
            1 => vec![(p[0], p[0])],
            _ => p.windows(2).map(|w| (w[0], w[1])).collect(),
        }
    };
    let (sa, sb) = (segs(a), segs(b));
    let mut best = f64::INFINITY;
    for &(p, q) in &sa {
        for &(r, s) in &sb {
            best = best.min(segment_distance(p, q, r, s));
        }
    }
    best
}

/// The least distance between the segments p–q and r–s in the plane (0 when they cross).
fn segment_distance(p: [f64; 2], q: [f64; 2], r: [f64; 2], s: [f64; 2]) -> f64 {
    let cross = |o: [f64; 2], a: [f64; 2], b: [f64; 2]| {
        (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])
    };
    let (d1, d2) = (cross(p, q, r), cross(p, q, s));
    let (d3, d4) = (cross(r, s, p), cross(r, s, q));
    if d1 * d2 < 0.0 && d3 * d4 < 0.0 {
        return 0.0;
    }
    let to_segment = |x: [f64; 2], a: [f64; 2], b: [f64; 2]| {
        let d = [b[0] - a[0], b[1] - a[1]];
        let l2 = d[0] * d[0] + d[1] * d[1];
        let t = if l2 > 0.0 {
            (((x[0] - a[0]) * d[0] + (x[1] - a[1]) * d[1]) / l2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        // Not `hypot`: glibc's took half of the access set-up of an 11,827-node part.
        let (dx, dy) = (a[0] + t * d[0] - x[0], a[1] + t * d[1] - x[1]);
        (dx * dx + dy * dy).sqrt()
    };
    to_segment(p, r, s)
        .min(to_segment(q, r, s))
        .min(to_segment(r, p, q))
        .min(to_segment(s, p, q))
}

/// The blocks of one (x, y) column, bottom up.
#[derive(Debug, Default)]
struct Column {
    z: Vec<i64>,
    index: Vec<u32>,
    /// Positions in `z` where a stack (a run of blocks one on another) starts.
    run_starts: Vec<usize>,
}

/// The first `k` in `0..n` for which the monotone `pred` holds (`n`: none).
fn first(n: usize, pred: impl Fn(usize) -> bool) -> usize {
    let (mut lo, mut hi) = (0, n);
    while lo < hi {
        let mid = lo + (hi - lo) / 2;
        if pred(mid) {
            hi = mid;
        } else {
            lo = mid + 1;
        }
    }
    lo
}

/// Horizontal distance from a block's centre line to the box of the column `(dx, dy)`
/// blocks away: the gap to its near face along each axis.
fn near_distance(dx: i64, dy: i64, px: f64, py: f64) -> f64 {
    let g = |d: i64, p: f64| ((d.unsigned_abs() as f64) * p - 0.5 * p).max(0.0);
    g(dx, px).hypot(g(dy, py))
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn part(blocks: Vec<[i64; 3]>) -> Part {
        Part::from_blocks("t".into(), [6.0, 6.0, 2.5], [0.0; 3], 3, blocks).unwrap()
    }

    fn vertical() -> TorchSetup {
        TorchSetup::new(Torch::default(), 0.0, 0.0)
    }

    #[test]
    fn a_wall_beside_the_bead_blocks_the_nozzle_once_it_rises_past_the_nozzle_end() {
        // Block [1,0,0] beside a stack at x = 0 of h layers: the stack's face is 3 mm from
        // the bead's centre line, well inside the 9 mm nozzle; its top is h·2.5 - 2.5 mm
        // above the bead's top, and the nozzle's end 12 mm.
        for (h, blocked) in [(5, false), (6, true)] {
            let mut blocks: Vec<[i64; 3]> = (0..h).map(|z| [0, 0, z]).collect();
            blocks.push([1, 0, 0]);
            let p = part(blocks);
            let access = TorchAccess::new(&p, &vertical());
            let b = p.index_of([1, 0, 0]).unwrap();
            let stands = |i: usize| i != b;
            assert_eq!(
                access.obstacle(b, stands).is_some(),
                blocked,
                "stack of {h} layers"
            );
            // Only the stack's lowest block in the torch's way is probed (z = 5: its top is
            // 12.5 mm above the bead's): it stands whenever any above it does.
            if blocked {
                assert_eq!(
                    access.obstacle(b, stands),
                    Some(Obstacle::Block(p.index_of([0, 0, 5]).unwrap()))
                );
            }
            assert_eq!(access.obstacle(b, |_| false), None);
        }
    }

    /// A graph part: an inner ring of radius 20 mm, `inner` layers tall, and an outer ring
    /// of radius `outer_r` on layer 0 (nodes listed layer by layer), 8 nodes a ring.
    fn rings(inner: u32, outer_r: f64) -> Part {
        use waam_part::{Bead, Deposit};
        let ring = |r: f64, layer: u32| Bead {
            layer,
            closed: true,
            points: (0..64)
                .map(|i| {
                    let a = std::f64::consts::TAU * i as f64 / 64.0;
                    [r * a.cos(), r * a.sin()]
                })
                .collect(),
        };
        let mut beads = vec![ring(outer_r, 0)];
        beads.extend((0..inner).map(|l| ring(20.0, l)));
        let mut nodes = Vec::new();
        for (b, bead) in beads.iter().enumerate() {
            let len = bead.length_mm();
            for k in 0..8 {
                let (from_mm, to_mm) = (len * k as f64 / 8.0, len * (k + 1) as f64 / 8.0);
                let c = bead.piece_mm(from_mm, to_mm)[1];
                nodes.push(Deposit {
                    bead: b,
                    from_mm,
                    to_mm,
                    layer: bead.layer,
                    centre_mm: [c[0], c[1], (bead.layer as f64 + 0.5) * 2.5],
                    volume_mm3: 6.0 * 2.5 * (to_mm - from_mm),
                    surface_mm2: 1.0,
                    substrate_mm2: 0.0,
                });
            }
        }
        Part::of_beads(BeadPart {
            name: "rings".into(),
            max_fragments: 2,
            bead_mm: [6.0, 2.5],
            base_z_mm: 0.0,
            beads,
            nodes,
            contacts: Vec::new(),
            windows: Vec::new(),
            thermal: Default::default(),
            warnings: Vec::new(),
        })
        .unwrap()
    }

    #[test]
    fn a_graph_part_is_checked_on_its_beads_not_on_stand_in_blocks() {
        // The outer ring's centre line 7 mm from the inner tower's: its bead's side 4 mm
        // from the TCP, inside the 9 mm nozzle, whose end is 12 mm above the bead's top.
        for (layers, blocked) in [(5, false), (6, true)] {
            let p = rings(layers, 27.0);
            let access = TorchAccess::new(&p, &vertical());
            let stands = |i: usize| i >= 8;
            for b in 0..8 {
                assert_eq!(
                    access.obstacle(b, stands).is_some(),
                    blocked,
                    "tower of {layers} layers, node {b}"
                );
                assert_eq!(access.obstacle(b, |_| false), None);
            }
            if blocked {
                // The blocking nodes are those of layer 5, on the inner ring.
                let Some(Obstacle::Block(o)) = access.obstacle(0, stands) else {
                    panic!("node 0 is blocked by a node");
                };
                assert_eq!(p.bead_part().unwrap().nodes[o].layer, 5);
            }
            // Welded first, the outer ring is never in the tower's way.
            let order: Vec<usize> = (0..p.len()).collect();
            assert_eq!(access.first_blocked(order), None);
        }
        // 20 mm between the beads' sides: clear of the nozzle (the stand-in blocks of a
        // graph part would put both rings in one row of 6 mm blocks).
        let p = rings(12, 46.0);
        let access = TorchAccess::new(&p, &vertical());
        assert!((0..8).all(|b| access.obstacle(b, |i| i >= 8).is_none()));
    }

    #[test]
    fn the_nozzle_clears_a_wall_beyond_its_radius() {
        // Face 9 mm from the centre line (two blocks away): the 9 mm nozzle touches it,
        // which is clearance; the 15 mm body reaches it only above the nozzle (72 mm up).
        let mut blocks: Vec<[i64; 3]> = (0..20).map(|z| [0, 0, z]).collect();
        blocks.push([2, 0, 0]);
        let p = part(blocks);
        let access = TorchAccess::new(&p, &vertical());
        let b = p.index_of([2, 0, 0]).unwrap();
        assert_eq!(access.obstacle(b, |i| i != b), None);
        // 35 layers (87.5 mm) reach the body.
        let mut blocks: Vec<[i64; 3]> = (0..35).map(|z| [0, 0, z]).collect();
        blocks.push([2, 0, 0]);
        let p = part(blocks);
        let access = TorchAccess::new(&p, &vertical());
        let b = p.index_of([2, 0, 0]).unwrap();
        assert!(access.obstacle(b, |i| i != b).is_some());
    }

    #[test]
    fn a_torch_that_dips_below_the_plate_is_blocked_by_it() {
        let torch = Torch {
            nozzle_standoff_mm: 1.0,
            nozzle_diameter_mm: 30.0,
            ..Torch::default()
        };
        // Tilted 45°: the nozzle's rim is 0.7 - 10.6 mm from the bead's top, below the plate
        // for the first layer (2.5 mm up), not for the fifth (12.5 mm up).
        let setup = TorchSetup::new(torch, 45.0, 0.0);
        let p = part((0..5).map(|z| [0, 0, z]).collect());
        let access = TorchAccess::new(&p, &setup);
        assert_eq!(access.obstacle(0, |_| false), Some(Obstacle::Plate));
        assert_eq!(access.obstacle(4, |_| false), None);
        assert_eq!(
            access.first_blocked(0..5),
            Some(Blocked {
                position: 0,
                block: 0,
                obstacle: Obstacle::Plate
            })
        );
    }

    #[test]
    fn the_tilt_combines_travel_and_work_angles() {
        let s = TorchSetup::new(Torch::default(), 10.0, 0.0);
        assert!((s.tilt_deg - 10.0).abs() < 1e-9);
        let s = TorchSetup::new(Torch::default(), 30.0, 30.0);
        let expected = (30f64.to_radians().cos().powi(2)).acos().to_degrees();
        assert!((s.tilt_deg - expected).abs() < 1e-9);
        assert!(TorchSetup {
            tilt_deg: 95.0,
            ..s
        }
        .validate()
        .is_err());
        let bad = Torch {
            nozzle_diameter_mm: 0.0,
            ..Torch::default()
        };
        assert_eq!(
            bad.validate().unwrap_err().to_string(),
            "torch.nozzle_diameter_mm: must be a number > 0, got 0"
        );
    }

    /// A point of the tilted torch, heading `azimuth`: `s` along the axis, `(p, q)` across it.
    fn torch_point(setup: &TorchSetup, azimuth: f64, s: f64, p: f64, q: f64) -> [f64; 3] {
        let (st, ct) = setup.tilt_deg.to_radians().sin_cos();
        let (sa, ca) = azimuth.sin_cos();
        // Axis up from the TCP, leaning towards `azimuth`; u1 across it in the vertical
        // plane, u2 horizontal.
        let axis = [st * ca, st * sa, ct];
        let u1 = [ct * ca, ct * sa, -st];
        let u2 = [-sa, ca, 0.0];
        std::array::from_fn(|d| s * axis[d] + p * u1[d] + q * u2[d])
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(48))]

        /// Every point of the real (tilted, any heading) torch that lies inside a block
        /// standing before the deposit is found by the check; and the check equals a plain
        /// test of every standing block against the swept solid (the stack shortcut loses
        /// nothing when gravity holds).
        #[test]
        fn the_check_finds_every_collision_of_the_tilted_torch(
            cells in proptest::collection::btree_set((0i64..4, 0i64..3), 1..8),
            heights in proptest::collection::vec(1i64..16, 8),
            tilt in 0.0f64..50.0,
            standoff in 0.0f64..14.0,
            diameter in 4.0f64..30.0,
            pick in 0usize..1000,
            cut in proptest::collection::vec(0i64..16, 8),
        ) {
            let cells: Vec<(i64, i64)> = cells.into_iter().collect();
            let mut blocks = Vec::new();
            for (c, &(x, y)) in cells.iter().enumerate() {
                for z in 0..heights[c] {
                    blocks.push([x, y, z]);
                }
            }
            let p = part(blocks);
            let torch = Torch {
                nozzle_diameter_mm: diameter,
                nozzle_standoff_mm: standoff,
                nozzle_length_mm: 20.0,
                body_diameter_mm: diameter * 1.5,
                body_length_mm: 15.0,
                wrist_diameter_mm: 0.0,
                wrist_length_mm: 0.0,
            };
            let setup = TorchSetup::new(torch, tilt, 0.0);
            let access = TorchAccess::new(&p, &setup);
            // What stands: a bottom part of every column (gravity), not the block welded.
            let b = pick % p.len();
            let stands = |i: usize| {
                let k = p.block(i);
                let c = cells.iter().position(|&(x, y)| (x, y) == (k[0], k[1])).unwrap();
                i != b && k[2] < cut[c] && !(k[0] == p.block(b)[0] && k[1] == p.block(b)[1] && k[2] >= p.block(b)[2])
            };
            let found = access.obstacle(b, stands);
            let [bx, by, bz] = p.block(b);
            let tcp = [6.0 * bx as f64 + 3.0, 6.0 * by as f64 + 3.0, 2.5 * (bz + 1) as f64];
            let env = Envelope::new(&setup);
            // The plain test of every standing block against the swept solid.
            let plain = (0..p.len()).filter(|&i| stands(i)).any(|i| {
                let k = p.block(i);
                let rho = near_distance(k[0] - bx, k[1] - by, 6.0, 6.0);
                let (zlo, zhi) = (2.5 * k[2] as f64 - tcp[2], 2.5 * (k[2] + 1) as f64 - tcp[2]);
                env.segments.iter().any(|s| {
                    zhi > s.lo + EPS_MM && zlo < s.hi - EPS_MM
                        && env.radius(s, zhi.min(s.hi)) > rho + EPS_MM
                })
            }) || tcp[2] + env.lowest() < -EPS_MM;
            prop_assert_eq!(found.is_some(), plain);
            // Points of the real torch, every 15° of heading.
            for a in 0..24 {
                let az = a as f64 * std::f64::consts::PI / 12.0;
                for (r, s0, len) in [(diameter / 2.0, standoff, 20.0), (diameter * 0.75, standoff + 20.0, 15.0)] {
                    for i in 0..=8 {
                        for j in 0..16 {
                            let s = s0 + len * i as f64 / 8.0;
                            let phi = j as f64 * std::f64::consts::PI / 8.0;
                            let q = torch_point(&setup, az, s, r * phi.cos(), r * phi.sin());
                            let pt = [tcp[0] + q[0], tcp[1] + q[1], tcp[2] + q[2]];
                            let inside = |i: usize| {
                                let k = p.block(i);
                                let lo = [6.0 * k[0] as f64, 6.0 * k[1] as f64, 2.5 * k[2] as f64];
                                let hi = [lo[0] + 6.0, lo[1] + 6.0, lo[2] + 2.5];
                                (0..3).all(|d| pt[d] > lo[d] + 0.01 && pt[d] < hi[d] - 0.01)
                            };
                            let hit = pt[2] < -0.01 || (0..p.len()).any(|i| stands(i) && inside(i));
                            prop_assert!(!hit || found.is_some(),
                                "torch point {:?} (heading {}°) inside what stands, not found", pt, a * 15);
                        }
                    }
                }
            }
        }
    }
}
