//! Moves with the arc off never pass through the part as built or the plate: transits are
//! routed above the tallest block welded so far. The check here is written independently
//! of `waam_motion::clearance`: it samples every move densely and tests each sample point
//! against every block welded before the move. The torch is not modelled here (the TCP's
//! line is this file's subject; the torch's nozzle, body and wrist along the moves are
//! access.rs's): some of these plans are ones the torch cannot weld.

mod common;

use common::{our_robot, part_and_plan, PARTS};
use nalgebra::Point3;
use waam_motion::toolpath::{ProcessSettings, Toolpath};
use waam_part::Part;
use waam_pipeline::Cell;

fn cell() -> Cell {
    Cell {
        settings: ProcessSettings {
            torch: None,
            ..ProcessSettings::default()
        },
        robot: our_robot(),
    }
}

/// The TCP of pose `k` in the part frame, mm.
fn tcp_mm(tp: &Toolpath, settings: &ProcessSettings, k: usize) -> Point3<f64> {
    let p = settings.plate.isometry().inverse() * Point3::from(tp.poses[k].pose.translation.vector);
    Point3::from(p.coords * 1000.0)
}

/// Every arc-off move sampled every 0.05 mm: no sample inside a block welded before the
/// move (deeper than 0.01 mm) or below the plate. Returns the number of moves checked.
fn assert_clear(name: &str, part: &Part, fragments: &[Vec<usize>], tp: &Toolpath) -> usize {
    let s = ProcessSettings::default();
    let mut welded: Vec<usize> = Vec::new();
    let mut checked = 0;
    for k in 1..tp.poses.len() {
        if tp.poses[k - 1].arc_on {
            if !tp.poses[k].arc_on {
                // The arc went off: this path's blocks are built now.
                welded.extend(&fragments[tp.poses[k].fragment]);
            }
            continue;
        }
        let (a, b) = (tcp_mm(tp, &s, k - 1), tcp_mm(tp, &s, k));
        let n = ((b - a).norm() / 0.05).ceil().max(1.0) as usize;
        for i in 0..=n {
            let p = a + (b - a) * (i as f64 / n as f64);
            assert!(p.z > -0.01, "{name}: pose {k} goes below the plate: {p}");
            for &w in &welded {
                let c = part.centre_mm(part.block(w));
                let inside = (0..3).all(|j| (p[j] - c[j]).abs() < 0.5 * part.block_mm[j] - 0.01);
                assert!(
                    !inside,
                    "{name}: the move to pose {k} ({:?}) passes through block {:?} at {p}",
                    tp.poses[k].kind,
                    part.block(w)
                );
            }
        }
        checked += 1;
    }
    checked
}

#[test]
fn a_transit_is_routed_above_a_tall_wall_between_two_weld_paths() {
    // A wall ten layers (25 mm) tall at x = 2, welded first, then single blocks at x = 0
    // and x = 4: the transit from the one to the other must cross the wall.
    let mut text =
        String::from("name: tall-wall\nblock_mm: [6, 6, 2.5]\nmax_fragments: 3\nlayers: ['#.#.#'");
    for _ in 1..10 {
        text.push_str(", '..#..'");
    }
    text.push_str("]\n");
    let part = Part::parse(&text).unwrap();
    let wall: Vec<usize> = std::iter::once(1).chain(3..12).collect();
    let fragments = vec![wall, vec![0], vec![2]];
    let cell = cell();
    let (tp, _) = cell.plan_motion(&part, &fragments).unwrap();
    assert!(assert_clear("tall-wall", &part, &fragments, &tp) > 0);
    // Between the arc-off at x = 0 and the arc-on at x = 4 the torch rises above the
    // wall's top (25 mm) by the clearance.
    let s = &cell.settings;
    let k_off = (0..tp.poses.len())
        .find(|&k| tp.poses[k].fragment == 1 && !tp.poses[k].arc_on && tp.poses[k - 1].arc_on)
        .unwrap();
    let k_on = (0..tp.poses.len())
        .find(|&k| tp.poses[k].fragment == 2 && tp.poses[k].arc_on)
        .unwrap();
    let top = (k_off..k_on)
        .map(|k| tcp_mm(&tp, s, k).z)
        .fold(f64::MIN, f64::max);
    assert!(
        top >= 25.0 + s.clearance_mm - 1e-6,
        "transit peaks at {top} mm"
    );
    // And it does cross the wall's x (the move goes over it, not round it).
    let xs: Vec<f64> = (k_off..k_on).map(|k| tcp_mm(&tp, s, k).x).collect();
    assert!(xs.iter().any(|&x| x < 12.0) && xs.iter().any(|&x| x > 18.0));
}

#[test]
fn no_move_with_the_arc_off_passes_through_a_sample_part_as_built() {
    let cell = cell();
    for name in PARTS {
        let (part, fragments) = part_and_plan(name);
        let (tp, _) = cell.plan_motion(&part, &fragments).unwrap();
        assert!(assert_clear(name, &part, &fragments, &tp) > 0, "{name}");
    }
}
