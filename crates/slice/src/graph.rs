//! Beads cut into deposits about W long, and the contacts between deposits.
//!
//! Contacts: Along (consecutive pieces of a bead; area W·H), Beside (same layer, other
//! bead of the same connected region of the section, centre lines within 1.25·W over a
//! shared length s; area H·s: beads of two regions have no material between them, so no
//! heat passes and no weld move may cross the gap, however narrow), Stacked (layers z and
//! z + 1 whose footprints — the pieces' centre lines widened to W with flat ends, so the
//! pieces of one bead tile its band — overlap by more than 5 % of W²; area = the overlap).
//! Candidates come from a uniform grid of 2·W cells per layer, so the work grows with the
//! number of nodes, not its square. Shared lengths and overlaps are midpoint-rule sums on a
//! W/4 (along) and W/8 × W/8 (footprint) sampling.

use rustc_hash::FxHashMap;

use waam_part::{Bead, Contact, ContactKind, Deposit};

/// A deposit's piece of centre line.
struct Piece {
    bead: usize,
    /// The bead's connected region of its layer's section.
    region: usize,
    layer: u32,
    pts: Vec<[f64; 2]>,
    len: f64,
    /// min x, min y, max x, max y.
    bbox: [f64; 4],
}

fn dist(a: [f64; 2], b: [f64; 2]) -> f64 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}

/// Rounds to 0.1 µm: the file stays short, and nothing is lost that a weld could show.
fn r4(x: f64) -> f64 {
    (x * 1e4).round() / 1e4
}

/// The bead's points with the first repeated at the end for a closed bead.
fn walk(bead: &Bead) -> Vec<[f64; 2]> {
    let mut pts = bead.points.clone();
    if bead.closed {
        pts.push(bead.points[0]);
    }
    pts
}

/// The point at arc length `s` of a polyline with cumulative lengths `cum`, and the unit
/// tangent there.
fn at(pts: &[[f64; 2]], cum: &[f64], s: f64) -> ([f64; 2], [f64; 2]) {
    let k = cum.partition_point(|&c| c <= s).clamp(1, pts.len() - 1);
    let (a, b) = (pts[k - 1], pts[k]);
    let l = cum[k] - cum[k - 1];
    let t = if l > 0.0 {
        ((s - cum[k - 1]) / l).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let tangent = if l > 0.0 {
        [(b[0] - a[0]) / l, (b[1] - a[1]) / l]
    } else {
        [1.0, 0.0]
    };
    (
        [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])],
        tangent,
    )
}

fn cumulative(pts: &[[f64; 2]]) -> Vec<f64> {
    let mut cum = Vec::with_capacity(pts.len());
    let mut s = 0.0;
    cum.push(0.0);
    for w in pts.windows(2) {
        s += dist(w[0], w[1]);
        cum.push(s);
    }
    cum
}

/// The sub-polyline between arc lengths `from` and `to`.
fn sub(pts: &[[f64; 2]], cum: &[f64], from: f64, to: f64) -> Vec<[f64; 2]> {
    let mut out = vec![at(pts, cum, from).0];
    for (k, &c) in cum.iter().enumerate() {
        if c > from && c < to {
            out.push(pts[k]);
        }
    }
    out.push(at(pts, cum, to).0);
    out
}

/// Distance from `p` to a polyline.
fn to_line(p: [f64; 2], line: &[[f64; 2]]) -> f64 {
    line.windows(2)
        .map(|s| segment_distance(p, s[0], s[1], false, false))
        .fold(f64::INFINITY, f64::min)
}

/// Distance from `p` to segment ab; with `flat_a` / `flat_b`, a point beyond that end
/// (its projection outside the segment there) is infinitely far (a flat end).
fn segment_distance(p: [f64; 2], a: [f64; 2], b: [f64; 2], flat_a: bool, flat_b: bool) -> f64 {
    let d = [b[0] - a[0], b[1] - a[1]];
    let l2 = d[0] * d[0] + d[1] * d[1];
    let mut t = if l2 > 0.0 {
        ((p[0] - a[0]) * d[0] + (p[1] - a[1]) * d[1]) / l2
    } else {
        0.0
    };
    if (flat_a && t < 0.0) || (flat_b && t > 1.0) {
        return f64::INFINITY;
    }
    t = t.clamp(0.0, 1.0);
    dist(p, [a[0] + t * d[0], a[1] + t * d[1]])
}

/// True when `p` lies in the band of half width `r` around `line` with flat ends.
fn in_band(p: [f64; 2], line: &[[f64; 2]], r: f64) -> bool {
    let last = line.len().saturating_sub(2);
    line.windows(2)
        .enumerate()
        .any(|(i, s)| segment_distance(p, s[0], s[1], i == 0, i == last) <= r)
}

/// A uniform grid of pieces per layer.
struct Grid {
    cell: f64,
    cells: FxHashMap<(u32, i64, i64), Vec<u32>>,
}

impl Grid {
    fn key(&self, x: f64) -> i64 {
        (x / self.cell).floor() as i64
    }

    fn insert(&mut self, id: u32, layer: u32, b: [f64; 4]) {
        for cx in self.key(b[0])..=self.key(b[2]) {
            for cy in self.key(b[1])..=self.key(b[3]) {
                self.cells.entry((layer, cx, cy)).or_default().push(id);
            }
        }
    }

    /// Pieces of `layer` in cells meeting the box, each once (`stamp` marks them).
    fn query(&self, layer: u32, b: [f64; 4], stamp: &mut [u32], mark: u32, out: &mut Vec<u32>) {
        out.clear();
        for cx in self.key(b[0])..=self.key(b[2]) {
            for cy in self.key(b[1])..=self.key(b[3]) {
                for &id in self
                    .cells
                    .get(&(layer, cx, cy))
                    .map_or(&[][..], Vec::as_slice)
                {
                    if stamp[id as usize] != mark {
                        stamp[id as usize] = mark;
                        out.push(id);
                    }
                }
            }
        }
    }
}

fn grow(b: [f64; 4], r: f64) -> [f64; 4] {
    [b[0] - r, b[1] - r, b[2] + r, b[3] + r]
}

/// The deposits and contacts of beads of width `w` and layer height `h`; `regions[i]` is
/// the connected region of its layer's section that bead i fills.
pub fn build(
    beads: &[Bead],
    regions: &[usize],
    w: f64,
    h: f64,
    base_z: f64,
) -> (Vec<Deposit>, Vec<Contact>) {
    let mut nodes = Vec::new();
    let mut pieces = Vec::new();
    let mut contacts = Vec::new();
    for (bi, bead) in beads.iter().enumerate() {
        let pts = walk(bead);
        let cum = cumulative(&pts);
        let len = bead.length_mm();
        let count = if bead.closed {
            ((len / w).round() as usize).max(3)
        } else {
            ((len / w).round() as usize).max(1)
        };
        let first = nodes.len();
        for k in 0..count {
            let from = len * k as f64 / count as f64;
            // The last piece ends exactly at the bead's length as the reader computes it.
            let to = if k + 1 == count {
                len
            } else {
                len * (k + 1) as f64 / count as f64
            };
            let piece = sub(&pts, &cum, from, to);
            let plen = to - from;
            let (c, _) = at(&pts, &cum, 0.5 * (from + to));
            let z = base_z + (bead.layer as f64 + 0.5) * h;
            nodes.push(Deposit {
                bead: bi,
                from_mm: if k == 0 { 0.0 } else { r4(from) },
                to_mm: if k + 1 == count { to } else { r4(to) },
                layer: bead.layer,
                centre_mm: [r4(c[0]), r4(c[1]), z],
                volume_mm3: r4(w * h * plen).max(1e-4),
                surface_mm2: r4(2.0 * plen * (w + h) + 2.0 * w * h),
                substrate_mm2: if bead.layer == 0 { r4(w * plen) } else { 0.0 },
            });
            let mut bbox = [f64::MAX, f64::MAX, f64::MIN, f64::MIN];
            for p in &piece {
                bbox = [
                    bbox[0].min(p[0]),
                    bbox[1].min(p[1]),
                    bbox[2].max(p[0]),
                    bbox[3].max(p[1]),
                ];
            }
            pieces.push(Piece {
                bead: bi,
                region: regions[bi],
                layer: bead.layer,
                pts: piece,
                len: plen,
                bbox,
            });
            if k > 0 {
                contacts.push(along(nodes.len() - 2, nodes.len() - 1, w, h));
            }
        }
        if bead.closed {
            contacts.push(along(first, nodes.len() - 1, w, h));
        }
    }
    let mut grid = Grid {
        cell: 2.0 * w,
        cells: FxHashMap::default(),
    };
    for (i, p) in pieces.iter().enumerate() {
        grid.insert(i as u32, p.layer, p.bbox);
    }
    let mut stamp = vec![u32::MAX; pieces.len()];
    let mut mark = 0u32;
    let mut cand = Vec::new();
    // Beside: shared length, each sample of u given to the nearest piece of every other bead.
    let reach = 1.25 * w;
    let mut shared: FxHashMap<(u32, u32), f64> = FxHashMap::default();
    let mut nearest: Vec<(usize, u32, f64)> = Vec::new();
    for (u, pu) in pieces.iter().enumerate() {
        let cum = cumulative(&pu.pts);
        let m = ((pu.len / (0.25 * w)).ceil() as usize).max(1);
        let step = pu.len / m as f64;
        for k in 0..m {
            let (p, _) = at(&pu.pts, &cum, (k as f64 + 0.5) * step);
            mark = mark.wrapping_add(1);
            grid.query(
                pu.layer,
                [p[0] - reach, p[1] - reach, p[0] + reach, p[1] + reach],
                &mut stamp,
                mark,
                &mut cand,
            );
            nearest.clear();
            for &v in &cand {
                let pv = &pieces[v as usize];
                if pv.bead == pu.bead || pv.region != pu.region {
                    continue;
                }
                let d = to_line(p, &pv.pts);
                if d > reach {
                    continue;
                }
                match nearest.iter_mut().find(|e| e.0 == pv.bead) {
                    Some(e) if d < e.2 || (d == e.2 && v < e.1) => *e = (pv.bead, v, d),
                    Some(_) => {}
                    None => nearest.push((pv.bead, v, d)),
                }
            }
            for &(_, v, _) in &nearest {
                *shared.entry((u as u32, v)).or_default() += step;
            }
        }
    }
    let mut beside: Vec<Contact> = Vec::new();
    for (&(u, v), &s) in &shared {
        if u < v {
            let back = shared.get(&(v, u)).copied().unwrap_or(0.0);
            let area = r4(h * 0.5 * (s + back));
            if area > 0.0 {
                beside.push(Contact {
                    a: u as usize,
                    b: v as usize,
                    area_mm2: area,
                    kind: ContactKind::Beside,
                });
            }
        } else if !shared.contains_key(&(v, u)) {
            let area = r4(h * 0.5 * s);
            if area > 0.0 {
                beside.push(Contact {
                    a: v as usize,
                    b: u as usize,
                    area_mm2: area,
                    kind: ContactKind::Beside,
                });
            }
        }
    }
    contacts.extend(beside);
    // Stacked: footprint overlap with the layer above.
    let cells_across = 8;
    let mut foot = Vec::new();
    for (u, pu) in pieces.iter().enumerate() {
        let cum = cumulative(&pu.pts);
        let m = ((pu.len / (w / 8.0)).ceil() as usize).max(2);
        let step = pu.len / m as f64;
        foot.clear();
        for k in 0..m {
            let (p, t) = at(&pu.pts, &cum, (k as f64 + 0.5) * step);
            for j in 0..cells_across {
                let off = ((j as f64 + 0.5) / cells_across as f64 - 0.5) * w;
                foot.push([p[0] - t[1] * off, p[1] + t[0] * off]);
            }
        }
        let cell_area = step * w / cells_across as f64;
        mark = mark.wrapping_add(1);
        grid.query(pu.layer + 1, grow(pu.bbox, w), &mut stamp, mark, &mut cand);
        for &v in &cand {
            let pv = &pieces[v as usize];
            let inside = foot
                .iter()
                .filter(|&&p| in_band(p, &pv.pts, 0.5 * w))
                .count();
            let area = r4(inside as f64 * cell_area);
            if area > 0.05 * w * w {
                contacts.push(Contact {
                    a: u,
                    b: v as usize,
                    area_mm2: area,
                    kind: ContactKind::Stacked,
                });
            }
        }
    }
    contacts.sort_by_key(|c| (c.a, c.b));
    (nodes, contacts)
}

fn along(a: usize, b: usize, w: f64, h: f64) -> Contact {
    Contact {
        a,
        b,
        area_mm2: r4(w * h),
        kind: ContactKind::Along,
    }
}
