//! The SAT planner: exact counts, soundness against brute force, and the no-plan answers.

mod common;

use common::planner::*;
use proptest::prelude::*;
use waam_part::{Part, Window};
use waam_planner::{self as planner, Acyclicity, NoPlan, Options};

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

#[test]
fn counts_match_the_published_numbers() {
    let expected = expected_counts();
    assert_eq!(expected.len(), 10, "COUNTS.md lists 10 parts");
    for (name, plans, feasible) in expected {
        let part = read_part(&name);
        let counts = planner::count(&part, &Options::default(), true, &mut |_| {}).unwrap();
        assert!(counts.complete);
        assert_eq!(counts.plans, Some(plans), "{name}: plans");
        assert_eq!(counts.feasible, feasible, "{name}: feasible plans");
    }
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

/// A random small part: grown block by block from [0,0,0] inside a 4 x 3 x 3 grid, each
/// new block face-adjacent to the part and standing on a block (or on the substrate), so
/// most parts have plans; with random windows.
fn small_part() -> impl Strategy<Value = Part> {
    (
        2usize..=12,
        proptest::collection::vec(any::<u32>(), 12),
        1usize..=3,
        proptest::collection::vec((0usize..12, 0.0f64..4.0, 1.0f64..15.0), 0..4),
    )
        .prop_map(|(size, picks, k, windows)| {
            let inside = |b: [i64; 3]| {
                (0..4).contains(&b[0]) && (0..3).contains(&b[1]) && (0..3).contains(&b[2])
            };
            let mut blocks = vec![[0i64, 0, 0]];
            for pick in picks.iter().take(size - 1) {
                let mut frontier: Vec<[i64; 3]> = Vec::new();
                for b in &blocks {
                    for d in waam_part::graph::FACE_DIRS {
                        let c = [b[0] + d[0], b[1] + d[1], b[2] + d[2]];
                        let stands = c[2] == 0 || blocks.contains(&[c[0], c[1], c[2] - 1]);
                        if inside(c) && stands && !blocks.contains(&c) && !frontier.contains(&c) {
                            frontier.push(c);
                        }
                    }
                }
                if frontier.is_empty() {
                    break;
                }
                blocks.push(frontier[*pick as usize % frontier.len()]);
            }
            let mut part = Part::from_blocks("random".into(), [6.0, 6.0, 2.5], [0.0; 3], k, blocks)
                .expect("a grown part is valid");
            for (b, lo, width) in windows {
                let b = b % part.len();
                part.set_window(
                    b,
                    Window {
                        min_s: lo,
                        max_s: lo + width,
                    },
                );
            }
            part
        })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

    /// The planner's exact counts, with every clause shortening on, equal brute force.
    #[test]
    fn counts_equal_brute_force(part in small_part()) {
        let all = brute_force_plans(&part, part.max_fragments);
        let feasible = all.iter().filter(|p| is_feasible(&part, p)).count() as u64;
        for acyclicity in [Acyclicity::Lazy, Acyclicity::Eager] {
            let opts = Options { acyclicity, ..Options::default() };
            let counts = planner::count(&part, &opts, true, &mut |_| {}).unwrap();
            prop_assert_eq!(counts.plans, Some(all.len() as u64));
            prop_assert_eq!(counts.feasible, feasible);
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

#[test]
fn every_plan_written_passes_waam_check() {
    for name in [
        "s1-wall",
        "s3-ring",
        "s5-ledge",
        "s7-pad",
        "ex1-plate-boss",
        "ex3-h-column",
    ] {
        let dir = scratch(&format!("plan-check-{name}"));
        let part = part_path(name);
        let out = waam(&[
            "-q",
            "plan",
            part.to_str().unwrap(),
            "--out",
            dir.to_str().unwrap(),
        ]);
        assert_eq!(out.status.code(), Some(0), "{name}: {}", stderr(&out));
        let plan = dir.join("plan.yaml");
        let check = waam(&["check", part.to_str().unwrap(), plan.to_str().unwrap()]);
        assert_eq!(check.status.code(), Some(0), "{name}: {}", stdout(&check));
        assert!(stdout(&check).contains("VALID") && stdout(&check).contains("FEASIBLE"));
    }
}

#[test]
fn enumerated_plans_are_all_feasible_and_distinct() {
    let dir = scratch("all-s1");
    let part = part_path("s1-wall");
    let out = waam(&[
        "-q",
        "plan",
        part.to_str().unwrap(),
        "--all",
        "--out",
        dir.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    let text = std::fs::read_to_string(dir.join("feasible-plans.yaml")).unwrap();
    let docs: Vec<&str> = text
        .split("---\n")
        .filter(|d| !d.trim().is_empty())
        .collect();
    assert_eq!(docs.len(), 21);
    let p = read_part("s1-wall");
    let g = waam_part::graph::WeldGraph::new(&p);
    let mut seen = std::collections::HashSet::new();
    for d in docs {
        let plan = waam_part::plan::Plan::from_bytes(d.as_bytes(), false).unwrap();
        let idx = plan.validate(&p, &g).unwrap();
        assert!(is_feasible(&p, &idx));
        assert!(seen.insert(idx));
    }
}

#[test]
fn count_json_has_plans_and_feasible() {
    let part = part_path("s2-corner");
    let out = waam(&["plan", part.to_str().unwrap(), "--count", "--json"]);
    assert_eq!(out.status.code(), Some(0));
    let v: serde_json::Value = serde_json::from_str(&stdout(&out)).unwrap();
    assert_eq!(v["plans"], 122);
    assert_eq!(v["feasible"], 23);
}
