//! Moves with the arc off (transit, approach, retract, wait) against the part as built:
//! the TCP's straight line between two poses must not enter a block welded so far, nor go
//! below the plate's surface. The toolpath routes transits above the tallest block welded
//! so far plus `clearance_mm`; this check makes sure no such move is ever returned.

use nalgebra::{Isometry3, Point3, Vector3};
use thiserror::Error;

use crate::toolpath::{PoseKind, Toolpath};
use waam_part::{BlockDisplay, Part};

/// Faces may be touched (a retract starts on the top of the block just welded): a block is
/// entered only deeper than this, mm.
const TOUCH_MM: f64 = 1e-3;

/// A move with the arc off that passes through the part as built.
#[derive(Debug, Error, PartialEq)]
#[error("the {what} move ending at pose {pose} (weld path {}) passes through {obstacle}", .fragment + 1)]
pub struct Collision {
    pub what: &'static str,
    pub pose: usize,
    pub fragment: usize,
    /// "block [x,y,z]" or "the plate".
    pub obstacle: String,
}

/// Whether the segment `a`–`b` enters the box `lo`–`hi` (slab test).
pub fn segment_enters_box(a: &Point3<f64>, b: &Point3<f64>, lo: [f64; 3], hi: [f64; 3]) -> bool {
    let d: Vector3<f64> = b - a;
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    for i in 0..3 {
        if d[i].abs() < 1e-15 {
            if a[i] <= lo[i] || a[i] >= hi[i] {
                return false;
            }
        } else {
            let (mut u, mut v) = ((lo[i] - a[i]) / d[i], (hi[i] - a[i]) / d[i]);
            if u > v {
                std::mem::swap(&mut u, &mut v);
            }
            t0 = t0.max(u);
            t1 = t1.min(v);
            if t0 >= t1 {
                return false;
            }
        }
    }
    true
}

/// Checks every arc-off move of a block plan's toolpath against the blocks welded before
/// it and the plate (`plate`: the part frame in the toolpath's frame).
pub fn check_moves(
    part: &Part,
    fragments: &[Vec<usize>],
    tp: &Toolpath,
    plate: &Isometry3<f64>,
) -> Result<(), Collision> {
    let to_part = plate.inverse();
    let mm = |k: usize| -> Point3<f64> {
        let p = to_part * Point3::from(tp.poses[k].pose.translation.vector);
        Point3::from(p.coords * 1000.0)
    };
    let half = part.block_mm.map(|v| 0.5 * v - TOUCH_MM);
    let offs: Vec<usize> = (0..tp.poses.len())
        .filter(|&k| tp.poses[k].kind == PoseKind::ArcOff)
        .collect();
    for k in 1..tp.poses.len() {
        let (prev, pose) = (&tp.poses[k - 1], &tp.poses[k]);
        if prev.arc_on {
            continue;
        }
        let what = match pose.kind {
            PoseKind::Approach | PoseKind::ArcOn => "approach",
            PoseKind::Retract => "retract",
            _ => "transit",
        };
        // Welded so far: every path whose arc went off before this move.
        let done = offs.iter().filter(|&&off| off < k).count();
        let (a, b) = (mm(k - 1), mm(k));
        if a.z.min(b.z) < -TOUCH_MM {
            return Err(Collision {
                what,
                pose: k,
                fragment: pose.fragment,
                obstacle: "the plate".into(),
            });
        }
        for &block in fragments[..done.min(fragments.len())].iter().flatten() {
            let c = part.centre_mm(part.block(block));
            let lo = [c[0] - half[0], c[1] - half[1], c[2] - half[2]];
            let hi = [c[0] + half[0], c[1] + half[1], c[2] + half[2]];
            if segment_enters_box(&a, &b, lo, hi) {
                return Err(Collision {
                    what,
                    pose: k,
                    fragment: pose.fragment,
                    obstacle: format!("block {}", BlockDisplay(part.block(block))),
                });
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_slab_test_sees_crossings_and_not_touches() {
        let (lo, hi) = ([0.0; 3], [1.0; 3]);
        let p = |x, y, z| Point3::new(x, y, z);
        assert!(segment_enters_box(
            &p(-1.0, 0.5, 0.5),
            &p(2.0, 0.5, 0.5),
            lo,
            hi
        ));
        assert!(segment_enters_box(
            &p(0.5, 0.5, 0.5),
            &p(0.5, 0.5, 0.6),
            lo,
            hi
        ));
        assert!(!segment_enters_box(
            &p(-1.0, 0.5, 1.0),
            &p(2.0, 0.5, 1.0),
            lo,
            hi
        ));
        assert!(!segment_enters_box(
            &p(-1.0, 0.5, 2.0),
            &p(2.0, 0.5, 1.5),
            lo,
            hi
        ));
        assert!(!segment_enters_box(
            &p(-1.0, -1.0, 0.5),
            &p(-0.1, 2.0, 0.5),
            lo,
            hi
        ));
    }
}
