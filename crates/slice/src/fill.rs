//! One layer's section filled with bead centre lines.
//!
//! For each connected region C of the section:
//! - C eroded by 0.75·W is empty: a thin wall (at most 1.5·W wide), welded as ONE bead on
//!   its centre line;
//! - else contour beads on the boundary loops of C eroded by W/2 (outer and holes), then the
//!   same again on C eroded by W, up to `perimeters` rounds, and on as long as the core has
//!   a hole (an annulus, as on a flange: its rings never shrink to small loops, and a
//!   raster across it would be cut in two by the hole into many short beads that no few
//!   weld paths can join); a core left after that is filled with a raster of open beads W
//!   apart (along x on even layers, y on odd ones).
//!
//! The centre line of a thin ring (one outline, one hole) is its outline moved in by half
//! its mean width (area over mean perimeter): one closed bead even where the width varies
//! (a square tube's offset corners). Of any other thin region it is found by erosion: the largest inset that leaves
//! something (bisection) is its half width; the region eroded to 0.02·W less than that is
//! a sliver around the centre line, 0.04·W wide. A sliver with a hole is a ring: its outer
//! loop is the closed bead (within 0.02·W of the true centre). One without holes is a strip:
//! its loop is cut at its two farthest points and one side is the open bead. This is exact
//! for walls of even width (tubes, straight walls), which is what round parts are made of;
//! a wall of varying width keeps only its widest part (reported by the coverage figures),
//! and a thin region with branches (a rib web) needs a true medial axis: not done here.

use clipper2_rust::{Path64, Paths64, Point64};

use crate::poly::{self, from64, SCALE};

/// A bead's centre line as the fill made it.
#[derive(Debug, Clone, PartialEq)]
pub struct RawBead {
    pub closed: bool,
    pub points: Vec<[f64; 2]>,
    /// The connected region of the section it fills (numbered within the layer): beads
    /// of different regions have no material between them.
    pub region: usize,
}

/// The beads of one layer whose section is `section`.
pub fn fill(section: &Paths64, w: f64, perimeters: usize, layer: u32) -> Vec<RawBead> {
    let mut out = Vec::new();
    for (r, region) in poly::regions(section).into_iter().enumerate() {
        let first = out.len();
        fill_region(&region, w, perimeters.max(1), 1, layer, &mut out);
        for bead in &mut out[first..] {
            bead.region = r;
        }
    }
    out
}

fn fill_region(
    region: &Paths64,
    w: f64,
    perimeters: usize,
    round: usize,
    layer: u32,
    out: &mut Vec<RawBead>,
) {
    if poly::offset(region, -0.75 * w).is_empty() || ring_width(region) <= 1.5 * w {
        centre_line(region, w, out);
        return;
    }
    for path in poly::offset(region, -w / 2.0) {
        push_closed(&path, w, out);
    }
    let core = poly::offset(region, -w);
    for inner in poly::regions(&core) {
        let annulus = inner.len() > 1;
        if round < perimeters || annulus {
            fill_region(&inner, w, perimeters, round + 1, layer, out);
        } else if poly::offset(&inner, -0.75 * w).is_empty() {
            centre_line(&inner, w, out);
        } else {
            raster(&inner, w, layer, out);
        }
    }
}

fn push_closed(path: &Path64, w: f64, out: &mut Vec<RawBead>) {
    let p = poly::simplify(path, 0.005 * w, true);
    if p.len() >= 3 {
        out.push(RawBead {
            closed: true,
            points: from64(&p),
            region: 0,
        });
    }
}

fn push_open(path: &Path64, w: f64, out: &mut Vec<RawBead>) {
    let p = poly::simplify(path, 0.005 * w, false);
    let pts = from64(&p);
    let len: f64 = pts
        .windows(2)
        .map(|s| (s[1][0] - s[0][0]).hypot(s[1][1] - s[0][1]))
        .sum();
    // A scrap shorter than a fifth of a bead width is no bead.
    if pts.len() >= 2 && len >= 0.2 * w {
        out.push(RawBead {
            closed: false,
            points: pts,
            region: 0,
        });
    }
}

fn perimeter(p: &Path64) -> f64 {
    let pts = from64(p);
    (0..pts.len())
        .map(|i| {
            let (a, b) = (pts[i], pts[(i + 1) % pts.len()]);
            (b[0] - a[0]).hypot(b[1] - a[1])
        })
        .sum()
}

/// The mean width of a ring (one outline, one hole: area over mean perimeter); infinite
/// for any other region. A square tube's wall eroded by a bead is a ring whose corners are
/// wider than its sides: by its mean width it is one bead, not four corner loops.
fn ring_width(region: &Paths64) -> f64 {
    if region.len() != 2 {
        return f64::INFINITY;
    }
    2.0 * poly::area_mm2(region) / (perimeter(&region[0]) + perimeter(&region[1]))
}

fn centre_line(region: &Paths64, w: f64, out: &mut Vec<RawBead>) {
    // A thin ring of uneven width, as a square tube's wall whose offset corners are wider
    // than its sides: erosion would keep only the corners. Its centre line is the outline
    // moved in by half the mean width, one closed bead: exact for even widths, the middle
    // on average otherwise.
    if region.len() == 2 {
        let half = ring_width(region) / 2.0;
        let line = poly::offset(&vec![region[0].clone()], -half);
        if half >= 0.02 * w && line.len() == 1 {
            push_closed(&line[0], w, out);
            return;
        }
    }
    let (mut lo, mut hi) = (0.0, 0.75 * w);
    for _ in 0..14 {
        let mid = 0.5 * (lo + hi);
        if poly::offset(region, -mid).is_empty() {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    // A region under 0.04·W wide is a sliver of the section, not a wall.
    if lo < 0.02 * w {
        return;
    }
    let sliver = poly::offset(region, -(lo - 0.02 * w));
    for r in poly::regions(&sliver) {
        if r.len() >= 2 {
            push_closed(&r[0], w, out);
        } else {
            push_open(&half_loop(&r[0]), w, out);
        }
    }
}

/// One side of a thin loop: from one of its two farthest-apart points to the other.
fn half_loop(path: &Path64) -> Path64 {
    let n = path.len();
    let d2 = |a: Point64, b: Point64| {
        let (dx, dy) = ((a.x - b.x) as f64, (a.y - b.y) as f64);
        dx * dx + dy * dy
    };
    let far = |from: usize| {
        (0..n)
            .max_by(|&i, &j| d2(path[from], path[i]).total_cmp(&d2(path[from], path[j])))
            .unwrap_or(0)
    };
    let a = far(0);
    let b = far(a);
    let (s, e) = (a.min(b), a.max(b));
    path[s..=e].to_vec()
}

fn raster(core: &Paths64, w: f64, layer: u32, out: &mut Vec<RawBead>) {
    let along_x = layer % 2 == 0;
    let (mut lo, mut hi) = (f64::MAX, f64::MIN);
    let (mut a_lo, mut a_hi) = (f64::MAX, f64::MIN);
    for p in core.iter().flatten() {
        let (across, along) = if along_x { (p.y, p.x) } else { (p.x, p.y) };
        lo = lo.min(across as f64 / SCALE);
        hi = hi.max(across as f64 / SCALE);
        a_lo = a_lo.min(along as f64 / SCALE);
        a_hi = a_hi.max(along as f64 / SCALE);
    }
    // Lines W apart, centred on the core's extent: each line's band of width W tiles it.
    let count = (((hi - lo) / w).round() as usize).max(1);
    let first = 0.5 * (lo + hi) - 0.5 * (count - 1) as f64 * w;
    let lines: Paths64 = (0..count)
        .map(|i| {
            let c = first + i as f64 * w;
            let (a, b) = (a_lo - w, a_hi + w);
            let pts = if along_x {
                [[a, c], [b, c]]
            } else {
                [[c, a], [c, b]]
            };
            poly::to64(&pts)
        })
        .collect();
    let mut clipped = poly::clip_lines(&lines, core);
    // Serpentine-friendly order: by line, then along it.
    clipped.sort_by_key(|p| {
        let q = p[0];
        if along_x {
            (q.y, q.x)
        } else {
            (q.x, q.y)
        }
    });
    for p in clipped {
        push_open(&p, w, out);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{section::section_paths, shapes};

    fn radius(p: [f64; 2]) -> f64 {
        p[0].hypot(p[1])
    }

    #[test]
    fn a_thin_ring_is_one_closed_bead_on_its_centre_circle() {
        let w = 6.0;
        let mesh = shapes::ring(30.0, 36.0, 10.0, 128);
        let s = section_paths(&mesh, 2.5, 0.0).unwrap();
        let beads = fill(&s, w, 3, 0);
        assert_eq!(beads.len(), 1, "{beads:?}");
        assert!(beads[0].closed);
        // The mesh's inscribed polygon sags 33 (1 - cos(pi/128)) = 0.01 mm mid-facet.
        for &p in &beads[0].points {
            assert!(
                (radius(p) - 33.0).abs() < 0.05 * w,
                "{p:?}: r = {}",
                radius(p)
            );
        }
        // Also a ring a little narrower than W.
        let s = section_paths(&shapes::ring(30.0, 35.0, 10.0, 96), 2.5, 0.0).unwrap();
        let beads = fill(&s, w, 3, 0);
        assert_eq!(beads.len(), 1);
        assert!(beads[0]
            .points
            .iter()
            .all(|&p| (radius(p) - 32.5).abs() < 0.05 * w));
    }

    #[test]
    fn a_wide_flange_gets_rings_from_both_sides() {
        // 24 mm = 4 W: two rings from the outside, two from the inside.
        let w = 6.0;
        let s = section_paths(&shapes::ring(30.0, 54.0, 5.0, 128), 1.0, 0.0).unwrap();
        let beads = fill(&s, w, 3, 0);
        let mut radii: Vec<f64> = beads
            .iter()
            .map(|b| b.points.iter().map(|&p| radius(p)).sum::<f64>() / b.points.len() as f64)
            .collect();
        radii.sort_by(f64::total_cmp);
        assert_eq!(radii.len(), 4, "{radii:?}");
        for (r, want) in radii.iter().zip([33.0, 39.0, 45.0, 51.0]) {
            assert!((r - want).abs() < 0.1, "{radii:?}");
        }
    }

    #[test]
    fn a_thin_straight_wall_is_one_open_bead() {
        let cells: Vec<[i64; 3]> = (0..20).flat_map(|x| [[x, 0, 0], [x, 1, 0]]).collect();
        let s = section_paths(&shapes::voxels(&cells), 0.5, 0.0).unwrap();
        let beads = fill(&s, 2.0, 3, 0);
        assert_eq!(beads.len(), 1, "{beads:?}");
        assert!(!beads[0].closed);
        assert!(beads[0].points.iter().all(|p| (p[1] - 1.0).abs() < 0.1));
    }

    #[test]
    fn a_plate_gets_perimeters_and_a_raster_core() {
        let cells: Vec<[i64; 3]> = (0..40)
            .flat_map(|x| (0..40).map(move |y| [x, y, 0]))
            .collect();
        let s = section_paths(&shapes::voxels(&cells), 0.5, 0.0).unwrap();
        let beads = fill(&s, 2.0, 3, 0);
        let closed = beads.iter().filter(|b| b.closed).count();
        assert_eq!(closed, 3);
        // Core: 40 - 2·6 = 28 mm wide: 14 lines 2 mm apart.
        assert_eq!(beads.len() - closed, 14, "{beads:?}");
    }
}
