//! Torch access as a planning constraint: plans the planner returns with a torch pass an
//! independent clearance check (its own geometry: points of the tilted torch in every
//! heading against the boxes of the blocks standing), the torch-feasible counts equal brute
//! force, and a part every plan of which is blocked says so.
//! (Through the binary: `tests/cli/torch.rs`.)

mod common;

use common::planner::*;
use proptest::prelude::*;
use waam_access::{Torch, TorchAccess, TorchSetup};
use waam_part::Part;
use waam_planner::{self as planner, Backend, CandidateVerdict, Event, NoPlan, Options};

/// The typical GMAW torch of the bundled process settings, at their 10° travel angle.
fn typical() -> TorchSetup {
    TorchSetup::new(Torch::default(), 10.0, 0.0)
}

fn with_torch(torch: TorchSetup) -> Options {
    Options {
        torch: Some(torch),
        ..Options::default()
    }
}

/// Points of the torch relative to its TCP, lowest first: a nozzle of radius 9 mm from 12 to
/// 72 mm up its axis and a body of radius 15 mm from 72 to 222 mm, the axis tilted
/// `tilt_deg` from the vertical and turned into every heading in steps of 15° (the heading
/// follows the travel direction).
fn torch_points(tilt_deg: f64) -> Vec<[f64; 3]> {
    let (st, ct) = tilt_deg.to_radians().sin_cos();
    let mut points: Vec<[f64; 3]> = Vec::new();
    let rings = [(9.0, 12.0, 72.0, 2.0), (15.0, 72.0, 222.0, 5.0)];
    for heading in 0..24 {
        let (sa, ca) = (heading as f64 * 15f64.to_radians()).sin_cos();
        let axis = [st * ca, st * sa, ct];
        let across = [ct * ca, ct * sa, -st];
        let side = [-sa, ca, 0.0];
        for &(radius, from, to, step) in &rings {
            let mut s: f64 = from;
            while s <= to + 1e-9 {
                for r in [0.0, radius * 0.5, radius] {
                    for j in 0..36 {
                        let (sp, cp) = (j as f64 * 10f64.to_radians()).sin_cos();
                        let (p, q) = (r * cp, r * sp);
                        points.push(std::array::from_fn(|d| {
                            s * axis[d] + p * across[d] + q * side[d]
                        }));
                    }
                }
                s += step;
            }
        }
    }
    points.sort_by(|a, b| a[2].total_cmp(&b[2]));
    points
}

/// Independent clearance check: the first deposit at which a point of the torch
/// ([`torch_points`]) lies inside a block deposited before it (more than 0.01 mm inside) or
/// below the plate. Returns (deposit position, block welded, block hit or None for the plate).
fn clearance(
    part: &Part,
    fragments: &[Vec<usize>],
    points: &[[f64; 3]],
) -> Option<(usize, usize, Option<usize>)> {
    let order: Vec<usize> = fragments.iter().flatten().copied().collect();
    let mut standing = vec![false; part.len()];
    let mut top = f64::NEG_INFINITY;
    let [px, py, pz] = part.block_mm;
    let o = part.origin_mm;
    let cell = |v: f64, o: f64, p: f64| {
        let t = (v - o) / p;
        let f = t.floor();
        ((t - f) * p > 0.01 && (1.0 - (t - f)) * p > 0.01).then_some(f as i64)
    };
    for (position, &b) in order.iter().enumerate() {
        let c = part.centre_mm(part.block(b));
        let tcp = [c[0], c[1], c[2] + 0.5 * pz];
        for q in points {
            let pt = [tcp[0] + q[0], tcp[1] + q[1], tcp[2] + q[2]];
            if pt[2] < -0.01 {
                return Some((position, b, None));
            }
            if pt[2] > top {
                break; // lowest first: nothing stands this high
            }
            if let (Some(x), Some(y), Some(z)) = (
                cell(pt[0], o[0], px),
                cell(pt[1], o[1], py),
                cell(pt[2], o[2], pz),
            ) {
                if let Some(i) = part.index_of([x, y, z]) {
                    if standing[i] {
                        return Some((position, b, Some(i)));
                    }
                }
            }
        }
        standing[b] = true;
        top = top.max(o[2] + (part.block(b)[2] + 1) as f64 * pz);
    }
    None
}

#[test]
fn ex3_has_no_plan_the_typical_torch_can_weld_and_its_plan_without_one_is_unweldable() {
    let part = read_part("ex3-h-column");
    // Without a torch: the published best plan, which welds beside a standing wall.
    let free = planner::plan(&part, &Options::default(), &mut |_| {}).unwrap();
    let plan = free.best.expect("ex3 has a plan without a torch");
    let (position, block, hit) = clearance(&part, &plan.fragments, &torch_points(10.0))
        .expect("the independent check finds a collision");
    let hit = hit.expect("a block, not the plate");
    let (b, h) = (part.block(block), part.block(hit));
    assert!(
        h[2] > b[2] + 4 && (h[0] - b[0]).abs() + (h[1] - b[1]).abs() <= 2,
        "deposit {position}: block {b:?} beside the standing block {h:?}"
    );
    // With the torch: every plan with 3 weld paths welds beside a standing wall (each of the
    // 3 paths climbs all 13 layers, one after the other) — proven, not timed out.
    let mut blocked = 0u64;
    let report = planner::plan(&part, &with_torch(typical()), &mut |e| {
        if let Event::Candidate {
            verdict: CandidateVerdict::TorchBlocked { .. },
            ..
        } = e
        {
            blocked += 1;
        }
    })
    .unwrap();
    assert!(report.best.is_none() && report.proven, "{:?}", report.best);
    assert!(blocked > 0 && report.stats.torch_blocked == blocked);
    assert!(
        matches!(
            report.no_plan,
            Some(NoPlan::WindowsOrTorch { .. } | NoPlan::TorchCannotReach { .. })
        ),
        "{:?}",
        report.no_plan
    );
    // Without the windows too, so the torch alone rules every plan out.
    let bare = Part::from_blocks(
        "ex3-no-windows".into(),
        part.block_mm,
        part.origin_mm,
        part.max_fragments,
        part.blocks().to_vec(),
    )
    .unwrap();
    let report = planner::plan(&bare, &with_torch(typical()), &mut |_| {}).unwrap();
    assert!(report.best.is_none() && report.proven);
    let reason = report.no_plan.unwrap().to_string();
    assert!(reason.starts_with("torch cannot reach"), "{reason}");
}

#[test]
fn every_plan_returned_with_the_typical_torch_passes_the_independent_clearance_check() {
    let points = torch_points(10.0);
    for name in common::PARTS.into_iter().filter(|&n| n != "ex3-h-column") {
        let part = read_part(name);
        let report = planner::plan(&part, &with_torch(typical()), &mut |_| {}).unwrap();
        assert!(report.proven, "{name}");
        let Some(best) = report.best else {
            continue;
        };
        assert_eq!(clearance(&part, &best.fragments, &points), None, "{name}");
        // The torch never makes a plan better; when the best plan without it is weldable
        // (the independent check), it costs no margin either.
        let free = planner::plan(&part, &Options::default(), &mut |_| {}).unwrap();
        let free = free.best.unwrap();
        assert!(best.margin <= free.margin + 1e-9, "{name}");
        if clearance(&part, &free.fragments, &points).is_none() {
            assert!(
                best.margin == free.margin || (best.margin - free.margin).abs() < 1e-9,
                "{name}: {} against {}",
                best.margin,
                free.margin
            );
        }
    }
    // Every feasible plan of the small parts, not only the best.
    for name in ["s1-wall", "s2-corner", "s5-ledge", "s7-pad"] {
        let part = read_part(name);
        let mut plans = Vec::new();
        let counts = planner::enumerate(&part, &with_torch(typical()), &mut |_| {}, &mut |f| {
            plans.push(f.to_vec());
            Ok(())
        })
        .unwrap();
        assert!(counts.complete && counts.feasible > 0, "{name}");
        for p in &plans {
            assert_eq!(clearance(&part, p, &points), None, "{name}: {p:?}");
        }
    }
}

/// Small grown parts (at most 3 × 2 × 4 blocks) with tall stacks, some windows.
fn tall_part() -> impl Strategy<Value = Part> {
    grown_part("tall", [3, 2, 4], 9, 3)
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, ..ProptestConfig::default() })]

    /// With a short, slim torch that a stack one layer taller already blocks, the planner's
    /// count of feasible plans equals brute force: every valid plan that keeps its windows and
    /// whose every deposit the torch reaches (the learned clauses cut off no such plan, and
    /// every plan counted is one).
    #[test]
    fn torch_feasible_counts_equal_brute_force(part in tall_part(), tilt in 0.0f64..30.0) {
        let torch = Torch {
            nozzle_diameter_mm: 8.0,
            nozzle_standoff_mm: 1.5,
            nozzle_length_mm: 10.0,
            body_diameter_mm: 14.0,
            body_length_mm: 20.0,
            wrist_diameter_mm: 0.0,
            wrist_length_mm: 0.0,
        };
        let setup = TorchSetup::new(torch, tilt, 0.0);
        let access = TorchAccess::new(&part, &setup);
        let expected = brute_force_plans(&part, part.max_fragments)
            .into_iter()
            .filter(|p| is_feasible(&part, p))
            .filter(|p| access.first_blocked(p.iter().flatten().copied()).is_none())
            .count() as u64;
        for solver in [Backend::Cadical, Backend::Varisat] {
            let opts = Options { solver, torch: Some(setup), ..Options::default() };
            let counts = planner::count(&part, &opts, false, &mut |_| {}).unwrap();
            prop_assert_eq!(counts.feasible, expected, "{:?}", solver);
        }
    }
}
