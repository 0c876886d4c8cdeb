//! The SAT planner: exact counts, soundness against brute force, and the no-plan answers.
//! (Through the `waam` binary: `tests/cli/planner.rs`.)

mod common;

use common::planner::*;
use proptest::prelude::*;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};
use waam_part::Part;
use waam_planner::{self as planner, Acyclicity, Backend, NoPlan, Options};

/// (part, plans, feasible) from config/parts/COUNTS.md (a copy of shared/parts/COUNTS.md).
fn expected_counts() -> Vec<(String, u64, u64)> {
    let text = std::fs::read_to_string(root().join("config/parts/COUNTS.md")).unwrap();
    text.lines()
        .filter(|l| l.starts_with("| s") || l.starts_with("| ex"))
        .filter_map(|l| {
            let cells: Vec<&str> = l.split('|').map(str::trim).collect();
            let name = cells[1].split_whitespace().next()?.to_string();
            Some((name, cells[5].parse().ok()?, cells[6].parse().ok()?))
        })
        .collect()
}

/// On one worker thread and on several (each searching its own cubes of the plans), with
/// either solver: the published counts.
#[test]
fn counts_match_the_published_numbers() {
    let expected = expected_counts();
    assert_eq!(expected.len(), 10, "COUNTS.md lists 10 parts");
    // varisat on several threads only: the parallel path is the one to check against it.
    for (solver, threads) in [
        (Backend::Cadical, 1),
        (Backend::Cadical, 3),
        (Backend::Varisat, 3),
    ] {
        let opts = Options {
            solver,
            threads,
            ..Options::default()
        };
        for (name, plans, feasible) in &expected {
            let part = read_part(name);
            let counts = planner::count(&part, &opts, true, &mut |_| {}).unwrap();
            assert!(counts.complete);
            let what = format!("{name} {solver:?} on {threads} thread(s)");
            assert_eq!(counts.plans, Some(*plans), "{what}: plans");
            assert_eq!(counts.feasible, *feasible, "{what}: feasible plans");
        }
    }
}

/// Every plan lies in exactly one of the first cubes, and in exactly one part of every
/// cube that holds it, split after split (the counts of the workers add up exactly).
#[test]
fn every_plan_lies_in_exactly_one_cube_at_every_depth() {
    use proptest::strategy::ValueTree;
    let mut parts: Vec<Part> = ["s1-wall", "s5-ledge", "s7-pad", "s3-ring"]
        .iter()
        .map(|n| read_part(n))
        .collect();
    let mut runner = proptest::test_runner::TestRunner::deterministic();
    for _ in 0..16 {
        parts.push(small_part().new_tree(&mut runner).unwrap().current());
    }
    for part in &parts {
        let graph = waam_part::graph::WeldGraph::new(part);
        let plans = brute_force_plans(part, part.max_fragments);
        let mut level = planner::cubes::first_cubes(part, &graph);
        for depth in 0..8 {
            for plan in &plans {
                let holding = level.iter().filter(|c| c.holds(plan)).count();
                assert_eq!(holding, 1, "{} depth {depth}: {plan:?}", part.name);
            }
            // One step deeper: every cube split (a closed cube holds on as it is).
            level = level
                .into_iter()
                .flat_map(|c| {
                    let parts = c.parts(&graph, part.max_fragments);
                    if parts.is_empty() {
                        vec![c]
                    } else {
                        parts
                    }
                })
                .collect();
        }
    }
}

/// The feasible plans of `part` as `enumerate` hands them over on `threads` threads.
fn enumerated(part: &Part, solver: Backend, threads: usize) -> Vec<Vec<Vec<usize>>> {
    let opts = Options {
        solver,
        threads,
        ..Options::default()
    };
    let mut plans = Vec::new();
    let counts = planner::enumerate(part, &opts, &mut |_| {}, &mut |p| {
        plans.push(p.to_vec());
        Ok(())
    })
    .unwrap();
    assert!(counts.complete);
    assert_eq!(counts.feasible, plans.len() as u64);
    plans
}

/// The same plans in the same order on 1 and 3 threads (and with either solver): the
/// lexicographic order of their fragments, each plan once and feasible.
#[test]
fn all_plans_come_in_the_same_order_on_any_number_of_threads() {
    for (name, _, feasible) in expected_counts().iter().filter(|(_, _, f)| *f > 0) {
        let part = read_part(name);
        let one = enumerated(&part, Backend::Cadical, 1);
        assert_eq!(one.len() as u64, *feasible, "{name}");
        assert!(
            one.windows(2).all(|w| w[0] < w[1]),
            "{name}: sorted, distinct"
        );
        assert_eq!(
            enumerated(&part, Backend::Cadical, 3),
            one,
            "{name}: 3 threads"
        );
        if part.len() <= 50 {
            assert_eq!(
                enumerated(&part, Backend::Varisat, 3),
                one,
                "{name}: varisat"
            );
        }
        for plan in &one {
            assert!(is_feasible(&part, plan), "{name}: {plan:?}");
        }
    }
}

/// A parallel enumeration stops within a second of its deadline or of a cancel, and says
/// it is incomplete.
#[test]
fn a_parallel_enumeration_stops_within_a_second_of_a_timeout_or_cancel() {
    let part = read_part("ex3-h-column");
    let timed = Options {
        threads: 3,
        timeout: Some(Duration::from_millis(200)),
        ..Options::default()
    };
    let t = Instant::now();
    let counts = planner::enumerate(&part, &timed, &mut |_| {}, &mut |_| Ok(())).unwrap();
    assert!(!counts.complete);
    assert!(
        t.elapsed() < Duration::from_millis(1200),
        "{:?}",
        t.elapsed()
    );
    assert!(counts.feasible < 253);

    let cancel = Arc::new(AtomicBool::new(false));
    let opts = Options {
        threads: 3,
        cancel: Some(Arc::clone(&cancel)),
        ..Options::default()
    };
    let raise = {
        let cancel = Arc::clone(&cancel);
        std::thread::spawn(move || {
            std::thread::sleep(Duration::from_millis(200));
            cancel.store(true, Ordering::Relaxed);
            Instant::now()
        })
    };
    let counts = planner::count(&part, &opts, true, &mut |_| {}).unwrap();
    let raised = raise.join().unwrap();
    assert!(!counts.complete);
    assert!(
        raised.elapsed() < Duration::from_secs(1),
        "{:?}",
        raised.elapsed()
    );
}

#[test]
fn eager_acyclicity_and_plain_clauses_count_the_same() {
    for name in ["s3-ring", "s7-pad", "s5-ledge"] {
        let part = read_part(name);
        let reference = planner::count(&part, &Options::default(), true, &mut |_| {}).unwrap();
        for opts in [
            Options {
                acyclicity: Acyclicity::Eager,
                ..Options::default()
            },
            Options {
                lookahead_budget: 0,
                ..Options::default()
            },
        ] {
            let c = planner::count(&part, &opts, true, &mut |_| {}).unwrap();
            assert_eq!(
                (c.plans, c.feasible),
                (reference.plans, reference.feasible),
                "{name} {opts:?}"
            );
        }
    }
}

/// With CaDiCaL the thermal check runs inside the search: every plan that breaks a window is
/// cut from a partial assignment by its prefix clause, so the only complete models judged
/// by the loop are the feasible plans; varisat judges complete models only. Same counts.
#[test]
fn the_thermal_check_inside_the_search_leaves_only_feasible_models() {
    let mut cooled_by_the_loop = false;
    for (name, _, feasible) in expected_counts().iter().filter(|(_, p, f)| p > f) {
        let part = read_part(name);
        if part.len() > 50 {
            continue; // ex2 and ex3: the counts test covers them
        }
        let count = |solver| {
            let opts = Options {
                solver,
                ..Options::default()
            };
            planner::count(&part, &opts, false, &mut |_| {}).unwrap()
        };
        let (inside, outside) = (count(Backend::Cadical), count(Backend::Varisat));
        assert_eq!(
            (inside.feasible, outside.feasible),
            (*feasible, *feasible),
            "{name}"
        );
        assert_eq!(inside.stats.candidates, *feasible, "{name}: CaDiCaL models");
        assert_eq!(
            inside.stats.inside_clauses, inside.stats.learned_clauses,
            "{name}"
        );
        assert!(inside.stats.inside_clauses > 0, "{name}");
        // Each feasible plan's cooldown was simulated inside the search: the loop does not
        // simulate it again (varisat's loop does, where a window is still open at the end).
        assert_eq!(inside.stats.cooldown_steps, 0, "{name}: CaDiCaL cooldowns");
        cooled_by_the_loop |= outside.stats.cooldown_steps > 0;
        assert_eq!(outside.stats.inside_clauses, 0, "{name}");
        assert!(
            outside.stats.candidates > *feasible,
            "{name}: varisat models"
        );
    }
    assert!(
        cooled_by_the_loop,
        "some part needs a cooldown after its last deposit"
    );
}

/// A random small part: up to 12 blocks in a 4 x 3 x 3 grid, with random windows.
fn small_part() -> impl Strategy<Value = Part> {
    grown_part("random", [4, 3, 3], 12, 4)
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

    /// The planner's exact counts, with every clause shortening on, equal brute force.
    #[test]
    fn counts_equal_brute_force(part in small_part()) {
        let all = brute_force_plans(&part, part.max_fragments);
        let feasible = all.iter().filter(|p| is_feasible(&part, p)).count() as u64;
        for solver in [Backend::Cadical, Backend::Varisat] {
            for acyclicity in [Acyclicity::Lazy, Acyclicity::Eager] {
                let opts = Options { acyclicity, solver, ..Options::default() };
                let counts = planner::count(&part, &opts, true, &mut |_| {}).unwrap();
                prop_assert_eq!(counts.plans, Some(all.len() as u64), "{:?} {:?}", solver, acyclicity);
                prop_assert_eq!(counts.feasible, feasible, "{:?} {:?}", solver, acyclicity);
            }
        }
    }
}

#[test]
fn the_best_plan_is_feasible_with_fewest_fragments_and_best_margin() {
    let part = read_part("s7-pad");
    let report = planner::plan(&part, &Options::default(), &mut |_| {}).unwrap();
    assert!(report.proven);
    let best = report.best.unwrap();
    // Brute force: among feasible plans with the fewest fragments, the largest margin.
    let graph = waam_part::graph::WeldGraph::new(&part);
    let model = waam_thermal::ThermalModel::new(&part, &graph);
    let feasible: Vec<_> = brute_force_plans(&part, part.max_fragments)
        .into_iter()
        .filter(|p| is_feasible(&part, p))
        .collect();
    let fewest = feasible.iter().map(Vec::len).min().unwrap();
    let best_margin = feasible
        .iter()
        .filter(|p| p.len() == fewest)
        .map(|p| model.margin(&waam_thermal::simulate(&model, p).unwrap().crossings))
        .fold(f64::NEG_INFINITY, f64::max);
    assert_eq!(best.fragments.len(), fewest);
    assert!(
        (best.margin - best_margin).abs() < 1e-9,
        "{} vs {best_margin}",
        best.margin
    );
}

#[test]
fn no_valid_plan_names_the_fragments_needed_and_the_layer() {
    let part = read_part("s4-tee-k1");
    let report = planner::plan(&part, &Options::default(), &mut |_| {}).unwrap();
    assert!(report.best.is_none() && report.proven);
    let reason = report.no_plan.unwrap();
    assert_eq!(
        reason,
        NoPlan::NoValidPlan {
            max_fragments: 1,
            needs_at_least: Some(2),
            layer: Some((0, 2, 3))
        }
    );
    assert!(
        reason.to_string().contains("needs at least 2 fragments"),
        "{reason}"
    );
}

#[test]
fn all_plans_breaking_windows_names_the_window() {
    let part = read_part("s6-channel");
    let report = planner::plan(&part, &Options::default(), &mut |_| {}).unwrap();
    assert!(report.best.is_none() && report.proven);
    match report.no_plan.unwrap() {
        NoPlan::AllBreakWindows { block, times } => {
            assert!(block == [0, 1, 2] || block == [3, 1, 2], "{block:?}");
            assert!(times > 0);
        }
        other => panic!("expected AllBreakWindows, got {other:?}"),
    }
}

/// A ring tower whose one window no plan keeps (tests/data/endless-ring.yaml): the planner
/// runs until it is stopped.
fn hard_part() -> std::path::PathBuf {
    root().join("tests/data/endless-ring.yaml")
}

#[test]
fn a_cancel_stops_a_solve_within_a_second() {
    let part = Part::parse(&std::fs::read_to_string(hard_part()).unwrap()).unwrap();
    let cancel = Arc::new(AtomicBool::new(false));
    let opts = Options {
        cancel: Some(Arc::clone(&cancel)),
        solver: Backend::Cadical,
        ..Options::default()
    };
    let flag = Arc::clone(&cancel);
    let setter = std::thread::spawn(move || {
        std::thread::sleep(Duration::from_secs(1));
        flag.store(true, Ordering::Relaxed);
        Instant::now()
    });
    let report = planner::plan(&part, &opts, &mut |_| {}).unwrap();
    let returned = Instant::now();
    let cancelled = setter.join().unwrap();
    assert!(report.best.is_none() && !report.proven);
    assert!(report.no_plan.is_none());
    assert!(
        returned.duration_since(cancelled) < Duration::from_secs(1),
        "returned {:?} after the cancel",
        returned.duration_since(cancelled)
    );
}

/// A part of solid layers (plates are what the global search finds hardest).
fn solid(w: i64, d: i64, h: i64, k: usize) -> Part {
    let blocks = (0..h)
        .flat_map(|z| (0..d).flat_map(move |y| (0..w).map(move |x| [x, y, z])))
        .collect();
    Part::from_blocks("solid".into(), [6.0, 6.0, 2.5], [0.0; 3], k, blocks).unwrap()
}

#[test]
fn the_warm_start_is_the_first_plan_of_a_solid_block() {
    for solver in [Backend::Cadical, Backend::Varisat] {
        let part = solid(10, 10, 10, 1);
        let opts = Options {
            solver,
            ..Options::default()
        };
        let report = planner::first(&part, &opts, &mut |_| {}).unwrap();
        let best = report.best.expect("a plan of a solid cube");
        assert_eq!(
            report.stats.candidates, 1,
            "{solver:?}: the warm start is the plan"
        );
        assert_eq!(best.fragments.len(), 1);
        let graph = waam_part::graph::WeldGraph::new(&part);
        best.plan(&part).validate(&part, &graph).unwrap();
    }
}

#[test]
fn the_warm_start_changes_no_answer() {
    // The best plan (fewest weld paths, then largest margin, proven) is the same with and
    // without the warm start, on every sample part that is quick to optimize.
    for name in [
        "ex1-plate-boss",
        "s1-wall",
        "s2-corner",
        "s3-ring",
        "s4-tee-k1",
        "s5-ledge",
        "s6-channel",
        "s7-pad",
    ] {
        let part = read_part(name);
        let answer = |warm_start| {
            let opts = Options {
                warm_start,
                ..Options::default()
            };
            let r = planner::plan(&part, &opts, &mut |_| {}).unwrap();
            assert!(r.proven, "{name}: proven");
            r.best.map(|b| (b.fragments.len(), b.margin))
        };
        assert_eq!(answer(true), answer(false), "{name}");
    }
}

#[test]
fn a_layer_in_more_pieces_than_k_is_no_plan_at_once() {
    // Two separate rows per layer, k = 1: each layer alone needs two weld paths.
    let blocks: Vec<_> = (0..3)
        .flat_map(|z| (0..4).flat_map(move |x| [[x, 0, z], [x, 2, z]]))
        .collect();
    let part = Part::from_blocks("rows".into(), [6.0, 6.0, 2.5], [0.0; 3], 1, blocks).unwrap();
    let report = planner::plan(&part, &Options::default(), &mut |_| {}).unwrap();
    assert!(report.best.is_none() && report.proven);
    assert_eq!(report.stats.candidates, 0);
    match report.no_plan {
        Some(NoPlan::NoValidPlan {
            layer: Some((_, 2, _)),
            ..
        }) => {}
        other => panic!("expected a layer needing 2 weld paths, got {other:?}"),
    }
}

/// A one-block rectangular ring `w` x `d`, `h` layers high (a tube), k = 1.
fn ring_tower(w: i64, d: i64, h: i64) -> Part {
    let blocks = (0..h)
        .flat_map(|z| {
            (0..d).flat_map(move |y| {
                (0..w)
                    .filter(move |&x| y == 0 || y == d - 1 || x == 0 || x == w - 1)
                    .map(move |x| [x, y, z])
            })
        })
        .collect();
    Part::from_blocks("ring".into(), [6.0, 6.0, 2.5], [0.0; 3], 1, blocks).unwrap()
}

#[test]
fn a_warm_start_that_breaks_windows_is_set_off_elsewhere() {
    // The layer-by-layer plan walks each ring layer back over the one below, so where it
    // starts decides how soon each block gets the block above it. The windows here are
    // those of a hidden plan of the same kind started elsewhere on the ring (three blocks,
    // each [0.95 x shortest, 1.01 x longest t8/5] in it): the plain warm start breaks
    // them, and the portfolio of other starts finds a plan that keeps them, checked afresh.
    let mut part = ring_tower(8, 10, 40);
    let graph = waam_part::graph::WeldGraph::new(&part);
    let limits = planner::constructive::Limits {
        deadline: None,
        cancel: None,
    };
    let base = planner::constructive::layered_plan(&part, &graph, 1, Backend::Cadical, &limits)
        .expect("a ring tower has a layer-by-layer plan");
    // The hidden plan: the base's first layer (the ring in order) from 13 blocks on, each
    // layer walked back over the one below.
    let ring: Vec<[i64; 3]> = base[0][..32].iter().map(|&b| part.block(b)).collect();
    let rotated: Vec<[i64; 3]> = ring[13..].iter().chain(&ring[..13]).copied().collect();
    let hidden: Vec<Vec<usize>> = vec![(0..40)
        .flat_map(|z| {
            let layer: Vec<[i64; 3]> = if z % 2 == 0 {
                rotated.clone()
            } else {
                rotated.iter().rev().copied().collect()
            };
            layer.into_iter().map(move |[x, y, _]| [x, y, z])
        })
        .map(|b| part.index_of(b).unwrap())
        .collect()];
    let watched: Vec<usize> = [[0, 0, 10], [7, 4, 20], [3, 9, 30]]
        .iter()
        .map(|&b| part.index_of(b).unwrap())
        .collect();
    let simulate = |part: &Part, plan: &[Vec<usize>]| simulated(part, &graph, plan);
    windows_around(&mut part, &graph, &hidden, &watched);
    assert!(
        simulate(&part, &base).violation.is_some(),
        "the plain warm start breaks a window"
    );

    // One configuration (no race): the portfolio's choice, deterministically.
    let report = first_alone_twice(&part);
    let best = report.best.expect("another start keeps the windows");
    assert_eq!(
        report.stats.candidates, 2,
        "the plain warm start, then the portfolio's choice"
    );
    best.plan(&part).validate(&part, &graph).unwrap();
    assert!(simulate(&part, &best.fragments).violation.is_none());
}

#[test]
fn a_warm_start_that_breaks_a_window_high_up_is_repaired_from_a_layer_on() {
    // The generator's walls: one weld path walks each layer back over the one below, and
    // at some layer a second weld path takes over from the wall's other end. The windows
    // high up are those of that hidden plan. Only the plan from that layer on differs from
    // the plain warm start, so no other start or cover of the first layer (the portfolio's
    // variants) gives it: the repair changes the plan around the broken window, re-simulated
    // from the unchanged prefix, guided by where each change first breaks a window.
    let (len, h, take_over) = (40, 14, 7);
    let blocks = (0..h)
        .flat_map(|z| (0..len).map(move |x| [x, 0, z]))
        .collect();
    let mut part = Part::from_blocks("wall".into(), [6.0, 6.0, 2.5], [0.0; 3], 2, blocks).unwrap();
    let graph = waam_part::graph::WeldGraph::new(&part);
    let limits = planner::constructive::Limits {
        deadline: None,
        cancel: None,
    };
    let base = planner::constructive::layered_plan(&part, &graph, 2, Backend::Cadical, &limits)
        .expect("a wall has a layer-by-layer plan");
    assert_eq!(base.len(), 1, "one serpentine");
    // Whether layer z of the plain warm start goes towards +x.
    let up_x = |z: i64| (part.block(base[0][0])[0] == 0) == (z % 2 == 0);
    let layer = |z: i64, forward: bool| -> Vec<usize> {
        let xs: Vec<i64> = if forward {
            (0..len).collect()
        } else {
            (0..len).rev().collect()
        };
        xs.into_iter()
            .map(|x| part.index_of([x, 0, z]).unwrap())
            .collect()
    };
    // From the take-over on, each layer goes the way the plain warm start's layer below it
    // went: the second path starts at the end where the first did not stop.
    let hidden: Vec<Vec<usize>> = vec![
        (0..take_over).flat_map(|z| layer(z, up_x(z))).collect(),
        (take_over..h).flat_map(|z| layer(z, up_x(z - 1))).collect(),
    ];
    // Every block of the layer the second path begins with, and one near the top.
    let watched: Vec<usize> = (0..len)
        .map(|x| [x, 0, take_over])
        .chain([[len / 2, 0, h - 3]])
        .map(|b| part.index_of(b).unwrap())
        .collect();
    windows_around(&mut part, &graph, &hidden, &watched);
    let report = the_repaired_warm_start_is_the_first_plan(&part, &graph, &base);
    judged_without_simulating_it_again(&part, &graph, &base, &report);
}

#[test]
fn a_tube_whose_windows_want_a_seam_elsewhere_from_some_layer_on_gets_a_weld_path_started_there() {
    // A square tube climbed by one weld path keeps its seam (where each layer turns back)
    // above where its first layer starts: a block just before the seam gets the block
    // above it soon, still hot; one across the tube a lap later. The windows are those of
    // a plan whose second weld path takes over at some layer half way round the tube, so
    // only the seam's place from there on differs from the plain warm start: no start of
    // the first layer (the portfolio's variants), mirror or new weld path from the same
    // place gives it; the repair's rotation of a new weld path does.
    let (side, h, take_over) = (10, 12, 5);
    let ring: Vec<[i64; 2]> = (0..side)
        .map(|x| [x, 0])
        .chain((1..side).map(|y| [side - 1, y]))
        .chain((0..side - 1).rev().map(|x| [x, side - 1]))
        .chain((1..side - 1).rev().map(|y| [0, y]))
        .collect();
    let blocks = (0..h)
        .flat_map(|z| ring.iter().map(move |&[x, y]| [x, y, z]))
        .collect();
    let mut part = Part::from_blocks("tube".into(), [6.0, 6.0, 2.5], [0.0; 3], 2, blocks).unwrap();
    let graph = waam_part::graph::WeldGraph::new(&part);
    let limits = planner::constructive::Limits {
        deadline: None,
        cancel: None,
    };
    let base = planner::constructive::layered_plan(&part, &graph, 2, Backend::Cadical, &limits)
        .expect("a tube has a layer-by-layer plan");
    assert_eq!(base.len(), 1, "one weld path climbs the tube");
    // The plain warm start, from the take-over on a second weld path with every layer's
    // ring turned half way round.
    let n = ring.len();
    let split = take_over as usize * n;
    let layer_below: Vec<[i64; 3]> = base[0][split - n..split]
        .iter()
        .map(|&b| part.block(b))
        .collect();
    let turned = |b: usize| {
        let [x, y, z] = part.block(b);
        let m = layer_below
            .iter()
            .position(|&[fx, fy, _]| (fx, fy) == (x, y))
            .expect("every layer has the same footprint");
        let [tx, ty, _] = layer_below[(m + n / 2) % n];
        part.index_of([tx, ty, z]).unwrap()
    };
    let hidden = vec![
        base[0][..split].to_vec(),
        base[0][split..].iter().map(|&b| turned(b)).collect(),
    ];
    // The blocks beside the hidden plan's seam, from the take-over up.
    let watched: Vec<usize> = (take_over..h - 1)
        .step_by(2)
        .flat_map(|z| {
            let at = (z - take_over) as usize * n;
            let layer = &hidden[1][at..at + n];
            [layer[0], layer[1], layer[n - 2], layer[n - 1]]
        })
        .collect();
    windows_around(&mut part, &graph, &hidden, &watched);
    let report = the_repaired_warm_start_is_the_first_plan(&part, &graph, &base);
    judged_without_simulating_it_again(&part, &graph, &base, &report);
}

#[test]
fn a_plate_whose_windows_want_its_rows_the_other_way_is_rastered_that_way() {
    // A raster's direction decides when each block's neighbour in the next row is welded:
    // a row's length later, or at once at a turn. The windows are those of a raster along
    // y; the layer solve rasters a plate one way for every start, and a mirror only
    // reverses it, so only a raster the other way keeps them.
    let (w, d) = (9, 6);
    let blocks = (0..d)
        .flat_map(|y| (0..w).map(move |x| [x, y, 0]))
        .collect();
    let mut part = Part::from_blocks("plate".into(), [6.0, 6.0, 2.5], [0.0; 3], 1, blocks).unwrap();
    let graph = waam_part::graph::WeldGraph::new(&part);
    let limits = planner::constructive::Limits {
        deadline: None,
        cancel: None,
    };
    let base = planner::constructive::layered_plan(&part, &graph, 1, Backend::Cadical, &limits)
        .expect("a plate has a layer-by-layer plan");
    let along_y = |part: &Part, plan: &[Vec<usize>]| {
        plan[0]
            .windows(2)
            .filter(|p| part.block(p[0])[0] == part.block(p[1])[0])
            .count()
            > plan[0].len() / 2
    };
    assert!(!along_y(&part, &base), "the layer solve rasters along x");
    let hidden = vec![(0..w)
        .flat_map(|x| {
            let column: Vec<i64> = match x % 2 {
                0 => (0..d).collect(),
                _ => (0..d).rev().collect(),
            };
            column.into_iter().map(move |y| [x, y, 0])
        })
        .map(|b| part.index_of(b).unwrap())
        .collect::<Vec<usize>>()];
    let watched: Vec<usize> = [[2, 1, 0], [4, 3, 0], [6, 4, 0], [1, 5, 0]]
        .iter()
        .map(|&b| part.index_of(b).unwrap())
        .collect();
    windows_around(&mut part, &graph, &hidden, &watched);
    // Rastered, not repaired; judged from the portfolio's simulation of the raster.
    let report = the_repaired_warm_start_is_the_first_plan(&part, &graph, &base);
    judged_without_simulating_it_again(&part, &graph, &base, &report);
    let best = first_alone_twice(&part).best.unwrap();
    assert!(along_y(&part, &best.fragments), "rastered along y");
}

/// A one-block T `h` layers high: a bar of `bar` blocks along x with a stem of `stem`
/// blocks along y from its block `junction`, k = 2 (a T layer needs two weld paths).
fn t_tower(bar: i64, junction: i64, stem: i64, h: i64) -> Part {
    let blocks = (0..h)
        .flat_map(|z| {
            (0..bar)
                .map(move |x| [x, 0, z])
                .chain((1..=stem).map(move |y| [junction, y, z]))
        })
        .collect();
    Part::from_blocks("t".into(), [6.0, 6.0, 2.5], [0.0; 3], 2, blocks).unwrap()
}

#[test]
fn a_warm_start_on_a_t_that_breaks_windows_takes_another_cover_of_its_layers() {
    // A T layer is a tree with three ends, so both its weld paths run end to end and no
    // path can start inside a branch: the first moves of the start portfolio cannot be
    // built. What can change is the layer's cover: which half of the bar goes with the
    // junction (or whether the stem is welded alone), each path's way and their order. The
    // windows are those of a hidden plan as the generator's T-walls have: two weld paths,
    // each climbing its piece of every layer, their cover not the plain warm start's.
    let (bar, junction, stem, h) = (9, 3, 5, 24);
    let mut part = t_tower(bar, junction, stem, h);
    let graph = waam_part::graph::WeldGraph::new(&part);
    let limits = planner::constructive::Limits {
        deadline: None,
        cancel: None,
    };
    let base = planner::constructive::layered_plan(&part, &graph, 2, Backend::Cadical, &limits)
        .expect("a T tower has a layer-by-layer plan");
    // The three covers of a T layer, as (x, y) in weld order.
    let left: Vec<(i64, i64)> = (0..junction).map(|x| (x, 0)).collect();
    let right: Vec<(i64, i64)> = (junction + 1..bar).rev().map(|x| (x, 0)).collect();
    let down: Vec<(i64, i64)> = (1..=stem).map(|y| (junction, y)).collect();
    let through = |a: &[(i64, i64)], b: &[(i64, i64)]| -> Vec<(i64, i64)> {
        let mut p = a.to_vec();
        p.push((junction, 0));
        p.extend(b.iter().rev());
        p
    };
    let covers = [
        [through(&left, &down), right.clone()],
        [through(&right, &down), left.clone()],
        [through(&left, &right), down.clone()],
    ];
    let pairs = |pieces: &[Vec<(i64, i64)>]| {
        let mut p: Vec<_> = pieces
            .iter()
            .flat_map(|p| p.windows(2).map(|w| (w[0].min(w[1]), w[0].max(w[1]))))
            .collect();
        p.sort();
        p
    };
    let base_cover: Vec<Vec<(i64, i64)>> = base
        .iter()
        .map(|f| {
            f.iter()
                .map(|&b| part.block(b))
                .take_while(|b| b[2] == 0)
                .map(|[x, y, _]| (x, y))
                .collect()
        })
        .collect();
    let cover = covers
        .iter()
        .find(|c| pairs(&c[..]) != pairs(&base_cover))
        .expect("the warm start takes one cover of three");
    // The hidden plan: each piece climbs, walked back over itself layer by layer.
    let hidden: Vec<Vec<usize>> = cover
        .iter()
        .map(|piece| {
            (0..h)
                .flat_map(|z| {
                    let layer: Vec<(i64, i64)> = if z % 2 == 0 {
                        piece.clone()
                    } else {
                        piece.iter().rev().copied().collect()
                    };
                    layer.into_iter().map(move |(x, y)| [x, y, z])
                })
                .map(|b| part.index_of(b).unwrap())
                .collect()
        })
        .collect();
    let watched: Vec<usize> = [[1, 0, 8], [junction, stem - 1, 14], [bar - 2, 0, 20]]
        .iter()
        .map(|&b| part.index_of(b).unwrap())
        .collect();
    let simulate = |part: &Part, plan: &[Vec<usize>]| simulated(part, &graph, plan);
    windows_around(&mut part, &graph, &hidden, &watched);
    assert!(
        simulate(&part, &base).violation.is_some(),
        "the plain warm start breaks a window"
    );

    // One configuration (no race): the portfolio's choice, before any solve of the search.
    let report = first_alone_twice(&part);
    let best = report
        .best
        .as_ref()
        .expect("another cover keeps the windows");
    assert_eq!(
        (report.stats.candidates, report.stats.sat_solves),
        (2, 0),
        "the plain warm start, then the portfolio's choice; no search"
    );
    best.plan(&part).validate(&part, &graph).unwrap();
    let outcome = simulate(&part, &best.fragments);
    assert!(outcome.violation.is_none());
    // Judged from the portfolio's simulation of it, to the same margin.
    judged_without_simulating_it_again(&part, &graph, &base, &report);
    let model = waam_thermal::ThermalModel::new(&part, &graph);
    assert_eq!(
        best.margin.to_bits(),
        model.margin(&outcome.crossings).to_bits()
    );
}

#[test]
fn a_race_finds_a_checked_plan_and_proofs_are_the_defaults() {
    // Any number of racers: the plan is valid and keeps its windows in a fresh simulation.
    let part = read_part("ex2-bracket");
    let graph = waam_part::graph::WeldGraph::new(&part);
    for threads in [2, 3, 6] {
        let opts = Options {
            threads,
            ..Options::default()
        };
        let report = planner::first(&part, &opts, &mut |_| {}).unwrap();
        let best = report.best.expect("ex2 has feasible plans");
        best.plan(&part).validate(&part, &graph).unwrap();
        let model = waam_thermal::ThermalModel::new(&part, &graph);
        let outcome = waam_thermal::simulate(&model, &best.fragments).unwrap();
        assert!(outcome.violation.is_none(), "{threads} threads");
        assert!(report.stats.first_feasible_s.is_some());
    }
    // No plan: the race answers what the default configuration alone answers.
    let part = read_part("s6-channel");
    let alone = planner::first(
        &part,
        &Options {
            threads: 1,
            ..Options::default()
        },
        &mut |_| {},
    )
    .unwrap();
    for threads in [2, 4] {
        let opts = Options {
            threads,
            ..Options::default()
        };
        let raced = planner::first(&part, &opts, &mut |_| {}).unwrap();
        assert!(raced.best.is_none() && raced.proven, "{threads} threads");
        assert_eq!(raced.no_plan, alone.no_plan, "{threads} threads");
    }
}

/// Runs `search` (the first plan's race or the best plan's) on the hard part on three
/// threads, cancelled after 0.5 s and then with a 0.7 s timeout: each answer comes within
/// a second, not proven; `cancelled` checks the cancelled run's report.
fn stops_within_a_second(
    search: fn(&Part, &Options, planner::Progress) -> Result<planner::Report, planner::PlanError>,
    cancelled: impl Fn(&planner::Report) -> bool,
) {
    let part = Part::parse(&std::fs::read_to_string(hard_part()).unwrap()).unwrap();
    let cancel = Arc::new(AtomicBool::new(false));
    let flag = Arc::clone(&cancel);
    let setter = std::thread::spawn(move || {
        std::thread::sleep(Duration::from_millis(500));
        flag.store(true, Ordering::Relaxed);
    });
    let opts = Options {
        threads: 3,
        cancel: Some(cancel),
        ..Options::default()
    };
    let t = Instant::now();
    let report = search(&part, &opts, &mut |_| {}).unwrap();
    setter.join().unwrap();
    assert!(
        t.elapsed() < Duration::from_millis(1500),
        "{:?}",
        t.elapsed()
    );
    assert!(cancelled(&report), "{:?}", report.stats);
    let opts = Options {
        threads: 3,
        timeout: Some(Duration::from_millis(700)),
        ..Options::default()
    };
    let t = Instant::now();
    let report = search(&part, &opts, &mut |_| {}).unwrap();
    assert!(
        t.elapsed() < Duration::from_millis(1700),
        "{:?}",
        t.elapsed()
    );
    assert!(!report.proven);
}

#[test]
fn a_race_stops_within_a_second_of_a_cancel_or_timeout() {
    stops_within_a_second(planner::first, |r| r.best.is_none() && !r.proven);
}

/// The best plan's fewest weld paths and margin, or why there is none (margins to 1 µs:
/// the search proves a margin to that much).
fn best_answer(part: &Part, threads: usize) -> (bool, Option<(usize, f64)>, Option<NoPlan>) {
    let opts = Options {
        threads,
        ..Options::default()
    };
    let r = planner::plan(part, &opts, &mut |_| {}).unwrap();
    if let Some(best) = &r.best {
        let graph = waam_part::graph::WeldGraph::new(part);
        best.plan(part).validate(part, &graph).unwrap();
        assert!(is_feasible(part, &best.fragments), "{threads} threads");
    }
    let best = r.best.map(|b| (b.fragments.len(), b.margin));
    (r.proven, best, r.no_plan)
}

fn same_best(
    a: &(bool, Option<(usize, f64)>, Option<NoPlan>),
    b: &(bool, Option<(usize, f64)>, Option<NoPlan>),
) -> bool {
    let close = match (a.1, b.1) {
        (Some((ka, ma)), Some((kb, mb))) => ka == kb && (ma == mb || (ma - mb).abs() <= 1e-6),
        (x, y) => x.is_none() && y.is_none(),
    };
    a.0 == b.0 && close && a.2 == b.2
}

#[test]
fn the_best_plan_is_the_same_on_one_and_on_several_threads() {
    // With more than one thread the first plan comes from a race; the proven answer is
    // that of one thread: the same plan (not only as many weld paths and the same margin)
    // and the same candidates, so a recording replays identically on any number of threads.
    for name in [
        "ex1-plate-boss",
        "ex2-bracket",
        "s1-wall",
        "s2-corner",
        "s3-ring",
        "s4-tee-k1",
        "s5-ledge",
        "s6-channel",
        "s7-pad",
    ] {
        let part = read_part(name);
        let alone = best_answer(&part, 1);
        assert!(alone.0, "{name}: proven alone");
        let plan = |threads: usize| {
            let opts = Options {
                threads,
                ..Options::default()
            };
            let r = planner::plan(&part, &opts, &mut |_| {}).unwrap();
            (r.best.map(|b| b.fragments), r.stats.candidates)
        };
        let one = plan(1);
        for threads in [2, 3] {
            let raced = best_answer(&part, threads);
            assert!(
                same_best(&raced, &alone),
                "{name} on {threads} threads: {raced:?}, alone {alone:?}"
            );
            assert_eq!(plan(threads), one, "{name} on {threads} threads");
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 32, ..ProptestConfig::default() })]

    /// The best plan on two threads (a race for the first plan) is brute force's: among
    /// the feasible plans with the fewest weld paths, the largest margin.
    #[test]
    fn the_raced_best_plan_equals_brute_force(part in small_part()) {
        let graph = waam_part::graph::WeldGraph::new(&part);
        let model = waam_thermal::ThermalModel::new(&part, &graph);
        let feasible: Vec<_> = brute_force_plans(&part, part.max_fragments)
            .into_iter()
            .filter(|p| is_feasible(&part, p))
            .collect();
        let expected = feasible.iter().map(Vec::len).min().map(|fewest| {
            let margin = feasible
                .iter()
                .filter(|p| p.len() == fewest)
                .map(|p| model.margin(&waam_thermal::simulate(&model, p).unwrap().crossings))
                .fold(f64::NEG_INFINITY, f64::max);
            (fewest, margin)
        });
        let (proven, best, _) = best_answer(&part, 2);
        prop_assert!(proven);
        match (best, expected) {
            (Some((k, m)), Some((ek, em))) => {
                prop_assert_eq!(k, ek);
                prop_assert!(m == em || (m - em).abs() <= 1e-6, "{} vs {}", m, em);
            }
            (got, want) => prop_assert!(got.is_none() && want.is_none(), "{:?} vs {:?}", got, want),
        }
    }
}

#[test]
fn a_raced_best_plan_stops_within_a_second_of_a_cancel_or_timeout() {
    stops_within_a_second(planner::plan, |r| {
        r.best.is_none() && !r.proven && r.no_plan.is_none()
    });
}

#[test]
fn the_race_gives_the_best_plan_its_first_plan() {
    // A generated 600-block tube whose first plan the search without the warm start finds
    // several times sooner than the default configuration (measured: 0.018 s against
    // 0.22 s, release build, `waam plan --threads 1`): on three threads (that racer is the
    // third) the best plan's first plan comes from it, and the optimisation goes on from
    // it. The timeout only bounds the run (the margin is not proven within it), long
    // enough for the default racer's own first plan, which the events report, on a loaded
    // machine (three racers on CI's two cores beside other tests: not within 3 s); nothing
    // here is timed.
    let path = root().join("tests/data/race-tube-600.yaml");
    let part = Part::parse(&std::fs::read_to_string(path).unwrap()).unwrap();
    let opts = Options {
        threads: 3,
        timeout: Some(Duration::from_secs(10)),
        ..Options::default()
    };
    let mut first_plan: Option<Vec<Vec<usize>>> = None;
    let report = planner::plan(&part, &opts, &mut |event| {
        if let planner::Event::Candidate {
            fragments,
            verdict: planner::CandidateVerdict::Feasible,
            ..
        } = event
        {
            first_plan.get_or_insert_with(|| fragments.to_vec());
        }
    })
    .unwrap();
    assert_eq!(
        report.stats.first_plan_racer.as_deref(),
        Some("no-warm-start"),
        "{:?}",
        report.stats
    );
    let best = report.best.expect("a plan");
    let graph = waam_part::graph::WeldGraph::new(&part);
    best.plan(&part).validate(&part, &graph).unwrap();
    assert!(is_feasible(&part, &best.fragments));
    // The answer is the race's plan or a better one.
    let first_plan = first_plan.expect("the race's plan was reported");
    let model = waam_thermal::ThermalModel::new(&part, &graph);
    let margin =
        |p: &[Vec<usize>]| model.margin(&waam_thermal::simulate(&model, p).unwrap().crossings);
    assert!(
        best.fragments.len() < first_plan.len()
            || (best.fragments.len() == first_plan.len()
                && margin(&best.fragments) >= margin(&first_plan) - 1e-9),
        "{} weld paths, margin {} against the race's {} and {}",
        best.fragments.len(),
        best.margin,
        first_plan.len(),
        margin(&first_plan)
    );
}

/// A simulation of `plan` on `part` (windows checked).
fn simulated(
    part: &Part,
    graph: &waam_part::graph::WeldGraph,
    plan: &[Vec<usize>],
) -> waam_thermal::Outcome {
    let model = waam_thermal::ThermalModel::new(part, graph);
    waam_thermal::simulate(&model, plan).unwrap()
}

/// `base` (the plain warm start) breaks a window of `part`, and one configuration (no race)
/// finds its first plan in the repaired warm start, before any solve of the search.
fn the_repaired_warm_start_is_the_first_plan(
    part: &Part,
    graph: &waam_part::graph::WeldGraph,
    base: &[Vec<usize>],
) -> planner::Report {
    assert!(
        simulated(part, graph, base).violation.is_some(),
        "the plain warm start breaks a window"
    );
    let report = first_alone_twice(part);
    let best = report
        .best
        .as_ref()
        .expect("the hidden plan keeps the windows");
    assert_eq!(
        (report.stats.candidates, report.stats.sat_solves),
        (2, 0),
        "the plain warm start, then the repaired one; no search"
    );
    best.plan(part).validate(part, graph).unwrap();
    let outcome = simulated(part, graph, &best.fragments);
    assert!(outcome.violation.is_none());
    // Its margin (from the search's last snapshot of it) is that of a simulation from
    // the first deposit.
    let model = waam_thermal::ThermalModel::new(part, graph);
    assert_eq!(
        best.margin.to_bits(),
        model.margin(&outcome.crossings).to_bits()
    );
    report
}

/// The search judged the changed warm start (repaired, a raster or another cover) from
/// the simulation that chose it: it simulated only the plain warm start `base`, up to the
/// window it breaks (and the deposit whose transit broke it, if one did), not the changed
/// plan again from where it changed.
fn judged_without_simulating_it_again(
    part: &Part,
    graph: &waam_part::graph::WeldGraph,
    base: &[Vec<usize>],
    report: &planner::Report,
) {
    let broken_after = simulated(part, graph, base).violation.unwrap().prefix_len as u64;
    assert!(
        report.stats.deposits_simulated <= broken_after + 1,
        "{} deposits simulated, the plain warm start breaks a window after {broken_after}",
        report.stats.deposits_simulated
    );
}

/// Windows on the `watched` blocks just around the t8/5 the `hidden` plan gives them (so
/// that plan keeps them, and plans that heat those blocks otherwise may not).
fn windows_around(
    part: &mut Part,
    graph: &waam_part::graph::WeldGraph,
    hidden: &[Vec<usize>],
    watched: &[usize],
) {
    for &b in watched {
        let wide = waam_part::Window {
            min_s: 0.0,
            max_s: 1e6,
        };
        part.set_window(b, wide);
    }
    let seen = simulated(part, graph, hidden).crossings;
    for &b in watched {
        let t85 = || seen.iter().filter(|c| c.block == b).map(|c| c.t85_s);
        let window = waam_part::Window {
            min_s: 0.95 * t85().fold(f64::INFINITY, f64::min),
            max_s: 1.01 * t85().fold(0.0, f64::max),
        };
        part.set_window(b, window);
    }
    assert!(simulated(part, graph, hidden).violation.is_none());
}

/// The first plan of one configuration (no race), run twice: the same plan both times.
fn first_alone_twice(part: &Part) -> planner::Report {
    let alone = Options {
        threads: 1,
        ..Options::default()
    };
    let run = || planner::first(part, &alone, &mut |_| {}).unwrap();
    let report = run();
    assert_eq!(
        run().best.map(|b| b.fragments),
        report.best.as_ref().map(|b| b.fragments.clone()),
        "the same choice"
    );
    report
}
