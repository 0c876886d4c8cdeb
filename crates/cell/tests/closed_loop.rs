//! The done-criteria of issue #31 on a small wall: the simulated cell, open and closed loop.
//!
//! The wall: 6 x 1 x 4 blocks, at most 2 weld paths, t8/5 windows of at most 9 s on the
//! upper two layers. How it was found: with the spec's constants the planner's best plan
//! (one serpentine weld path) keeps those windows with a margin of 1.05 s (its t8/5 values
//! on the upper layers are 7.35 to 7.95 s); on a cell whose losses to the outside
//! (`substrate_per_s`, `radiation_per_s_k3`) are 25 % lower they grow past 9 s. We tried
//! max_s = 8.2, 8.5, 9, 9.5 and 10 with `waam sim-cell`: at 9.5 and 10 open loop keeps
//! them, at 8.2 and 8.5 closed loop breaks them too (the first layers are welded before
//! anything is measured), at 9 open loop breaks one and closed loop keeps every one. The
//! tests check each claim again by simulation, not by these numbers.

mod support;

use std::collections::HashSet;

use waam_cell::{CellOptions, Executed, Truth};
use waam_part::graph::WeldGraph;
use waam_part::Part;
use waam_thermal::{simulate, ThermalModel};

use support::first_plan;

const WALL: &str = "name: wall\nblock_mm: [6, 6, 2.5]\nmax_fragments: 2\n\
                    layers: ['######', '######', '######', '######']\n";

fn wall(max_s: f64) -> Part {
    Part::parse(&format!(
        "{WALL}t85: [{{box: {{min: [0,0,2], max: [5,0,3]}}, min_s: 0, max_s: {max_s}}}]\n"
    ))
    .unwrap()
}

/// 25 % lower heat losses than the spec's defaults.
const LOWER_LOSSES: &str = "thermal: {substrate_per_s: 0.375, radiation_per_s_k3: 0.75e-12}\n";

fn execute(part: &Part, truth: &str, closed_loop: bool) -> Executed {
    let truth = Truth::parse(truth, part).unwrap();
    let opts = CellOptions {
        closed_loop,
        ..CellOptions::default()
    };
    let executed = waam_cell::run(
        part,
        &first_plan(part),
        0.0,
        &truth,
        &opts,
        &mut |_| {},
        None,
    )
    .unwrap();
    assert!(executed.complete);
    // executed.yaml reads back as written.
    let text = executed.to_yaml().unwrap();
    let back: Executed = serde_yaml::from_str(&text).unwrap();
    assert_eq!(back, executed);
    executed
}

/// Every block deposited exactly once, in a valid order (moves along the weld graph, nothing
/// under what stands), with `paths` weld paths at most.
fn assert_every_block_once(part: &Part, e: &Executed, paths: usize) {
    let fragments = e.fragments(part).unwrap();
    let seen: HashSet<usize> = fragments.iter().flatten().copied().collect();
    assert_eq!(seen.len(), part.len(), "a block missing or deposited twice");
    assert_eq!(fragments.iter().map(Vec::len).sum::<usize>(), part.len());
    assert!(fragments.len() <= paths, "{} weld paths", fragments.len());
    // A fault's arc start comes on top of the part's k.
    let mut part = part.clone();
    part.max_fragments = paths;
    let plan = waam_part::plan::Plan::from_indices(&part, &fragments);
    plan.validate(&part, &WeldGraph::new(&part))
        .expect("the executed order is a valid plan");
}

#[test]
fn closed_loop_keeps_the_windows_that_open_loop_breaks_on_the_true_model() {
    let part = wall(9.0);
    let truth = Truth::parse(LOWER_LOSSES, &part).unwrap();
    let open = execute(&part, LOWER_LOSSES, false);
    let closed = execute(&part, LOWER_LOSSES, true);
    // The planner's own plan is feasible on its own model: the model is what is wrong.
    let planned = open.fragments(&part).unwrap();
    let model = ThermalModel::new(&part, &WeldGraph::new(&part));
    assert!(simulate(&model, &planned).unwrap().violation.is_none());
    // Re-simulated on the true model along executed.yaml's time line.
    let v = open.check(&part, truth.thermal).unwrap().violation;
    assert!(
        v.is_some(),
        "open loop keeps every window on the true model"
    );
    let v = closed.check(&part, truth.thermal).unwrap().violation;
    assert!(v.is_none(), "closed loop breaks {v:?}");
    assert_every_block_once(&part, &closed, 2);
    // The estimate found the lower losses from the exact temperatures.
    let last = closed.estimates.last().unwrap();
    assert!((last.loss_factor - 0.75).abs() < 0.01, "{last:?}");
    assert!(last.rmse_after_c < last.rmse_before_c / 10.0, "{last:?}");
    // And the re-plan changed the order (a second weld path), at a boundary.
    assert!(closed.plans.len() > 1);
    assert_ne!(planned, closed.fragments(&part).unwrap());
}

#[test]
fn closed_loop_brings_the_height_back_when_every_layer_comes_out_ten_percent_low() {
    let part = wall(1000.0);
    let truth = "height_factor: 0.9\n";
    let open = execute(&part, truth, false);
    let closed = execute(&part, truth, true);
    let nominal = 4.0 * 2.5;
    assert_eq!(open.nominal_top_mm, nominal);
    assert!(
        (open.top_mm - 0.9 * nominal).abs() < 1e-9,
        "{}",
        open.top_mm
    );
    assert!((closed.top_mm - nominal).abs() < 0.5, "{}", closed.top_mm);
    // Within the process limits, layer by layer.
    for l in &closed.layers {
        assert!((0.7..=1.3).contains(&l.wire_feed), "{l:?}");
    }
    assert_eq!(closed.layers.len(), 4);
}

#[test]
fn closed_loop_brings_each_column_back_when_one_end_of_the_wall_comes_out_low() {
    let part = wall(1000.0);
    // The wall's left half (block centres x = 3, 9, 15 mm) deposits 15 % low.
    let truth = "height_zones: [{min_mm: [0, -10, 0], max_mm: [18, 10, 100], factor: 0.85}]\n";
    let column_tops = |e: &Executed| {
        let mut tops = [0.0; 6];
        for d in &e.deposits {
            tops[d.block[0] as usize] += d.height_mm;
        }
        tops
    };
    let nominal = 4.0 * 2.5;
    let open = column_tops(&execute(&part, truth, false));
    let closed_run = execute(&part, truth, true);
    let closed = column_tops(&closed_run);
    for x in 0..6 {
        let want_open = if x < 3 { 0.85 * nominal } else { nominal };
        assert!(
            (open[x] - want_open).abs() < 1e-9,
            "open, column {x}: {open:?}"
        );
        assert!(
            (closed[x] - nominal).abs() < 0.5,
            "closed, column {x}: {closed:?}"
        );
    }
    // The low end was fed more than the rest, within the process limits.
    for d in closed_run.deposits.iter().filter(|d| d.block[2] > 0) {
        assert!((0.7..=1.3).contains(&d.wire_feed), "{d:?}");
        assert_eq!(d.wire_feed > 1.0 + 1e-9, d.block[0] < 3, "{d:?}");
    }
}

#[test]
fn a_weld_path_cut_short_halfway_is_re_planned_and_completed() {
    let part = wall(9.0);
    let truth = format!("{LOWER_LOSSES}cut_short: {{path: 1, after: 12}}\n");
    let closed = execute(&part, &truth, true);
    // The first weld path stops after 12 of the 24 deposits.
    let fragments = closed.fragments(&part).unwrap();
    assert_eq!(fragments[0].len(), 12);
    let fault = closed
        .plans
        .iter()
        .find(|p| p.reason == "fault")
        .expect("a re-plan at the fault");
    assert_eq!(fault.at_deposit, 12);
    assert!(
        !fault.continues,
        "a path cut short resumes with a new arc start"
    );
    // Completed: every block once, the fault's arc start counted on top of k = 2.
    assert_every_block_once(&part, &closed, 3);
    let t = Truth::parse(&truth, &part).unwrap();
    assert!(closed.check(&part, t.thermal).unwrap().violation.is_none());
    // Open loop completes too, resuming where the path stopped with a new arc start.
    let open = execute(&part, &truth, false);
    assert_every_block_once(&part, &open, 3);
}

#[test]
fn noisy_sensors_still_give_an_estimate_near_the_truth() {
    let part = wall(1000.0);
    let truth = format!("{LOWER_LOSSES}sensors: {{noise_c: 10, seed: 5}}\n");
    let closed = execute(&part, &truth, true);
    let last = closed.estimates.last().unwrap();
    assert!((last.loss_factor - 0.75).abs() < 0.05, "{last:?}");
    // The same seed gives the same run (but for the wall-clock latencies).
    let timeless = |mut e: Executed| {
        e.plans.iter_mut().for_each(|p| p.latency_s = 0.0);
        e.estimates.iter_mut().for_each(|p| p.latency_s = 0.0);
        e
    };
    assert_eq!(timeless(execute(&part, &truth, true)), timeless(closed));
}

#[test]
fn a_stopped_run_reports_the_top_of_the_layers_it_finished() {
    // Open loop, every layer 10 % low, stopped when the first weld path is cut short (after
    // 15 deposits: two layers and a half of the wall, a serpentine of 6 per layer).
    let part = wall(1000.0);
    let truth = Truth::parse(
        "height_factor: 0.9\ncut_short: {path: 1, after: 15}\n",
        &part,
    )
    .unwrap();
    let cancel = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let opts = CellOptions {
        closed_loop: false,
        planner: waam_planner::Options {
            cancel: Some(cancel.clone()),
            ..Default::default()
        },
        ..CellOptions::default()
    };
    let stop = |line: &str| {
        if line.contains("cut short") {
            cancel.store(true, std::sync::atomic::Ordering::Relaxed);
        }
    };
    let plan = first_plan(&part);
    let executed = waam_cell::run(&part, &plan, 0.0, &truth, &opts, &mut { stop }, None).unwrap();
    assert!(!executed.complete);
    assert_eq!(executed.deposits.len(), 15);
    assert_eq!(executed.layers.len(), 2, "{:?}", executed.layers);
    assert!(
        (executed.nominal_top_mm - 5.0).abs() < 1e-9,
        "{}",
        executed.nominal_top_mm
    );
    assert!(
        (executed.top_mm - 0.9 * 5.0).abs() < 1e-9,
        "{}",
        executed.top_mm
    );
}

/// The bundled ring sliced into beads (a graph part: two rings a layer, 4 layers), without
/// its window so that its best plan is proven at once.
fn ring_beads() -> Part {
    let text = include_str!("../../../tests/data/ring-beads.yaml");
    let text = text.split("\nt85:").next().unwrap();
    Part::of_beads(waam_part::BeadPart::parse(text).unwrap()).unwrap()
}

#[test]
fn a_graph_part_runs_closed_loop_and_its_height_comes_back() {
    let part = ring_beads();
    let truth = "height_factor: 0.9\n";
    let open = execute(&part, truth, false);
    let closed = execute(&part, truth, true);
    let nominal = 4.0 * 2.5;
    assert!(
        (open.top_mm - 0.9 * nominal).abs() < 1e-9,
        "{}",
        open.top_mm
    );
    assert!((closed.top_mm - nominal).abs() < 0.5, "{}", closed.top_mm);
    assert_eq!(closed.layers.len(), 4);
    assert!(closed.plans.len() > 1, "re-planned at its boundaries");
    assert_every_block_once(&part, &closed, part.max_fragments);
}
