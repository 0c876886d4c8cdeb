//! One time line: the plan the pipeline returns (to publish, record, export) is thermally
//! checked on the time line its motion executes, and the robot is timed to the model.
//! The executed times are read here from the toolpath's arc flags and weld poses, not with
//! the pipeline's own reader.

mod common;

use std::time::Duration;

use common::{our_robot, part};
use waam_motion::toolpath::{PoseKind, ProcessSettings, Toolpath};
use waam_part::graph::WeldGraph;
use waam_part::Part;
use waam_pipeline::{Cell, ChosenPlan, PipelineError};
use waam_thermal::{simulate_on, ThermalModel, Timeline};

/// Every sample part, including those without a (feasible) plan.
const SAMPLES: [&str; 10] = [
    "s1-wall",
    "s2-corner",
    "s3-ring",
    "s4-tee-k1",
    "s5-ledge",
    "s6-channel",
    "s7-pad",
    "ex1-plate-boss",
    "ex2-bracket",
    "ex3-h-column",
];

/// The torch is not modelled here (the plans are planned without it; ex3's first plan is
/// one the torch cannot weld): the time line is this file's subject, the torch
/// access.rs's.
fn cell() -> Cell {
    Cell {
        settings: ProcessSettings {
            torch: None,
            ..ProcessSettings::default()
        },
        robot: our_robot(),
    }
}

fn found(fragments: Vec<Vec<usize>>) -> ChosenPlan {
    ChosenPlan {
        fragments,
        stats: Default::default(),
        proven: false,
        worst_margin_s: 0.0,
    }
}

/// The planner's first feasible plan, if any.
fn first_plan(part: &Part) -> Option<Vec<Vec<usize>>> {
    let opts = waam_planner::Options {
        timeout: Some(Duration::from_secs(60)),
        ..Default::default()
    };
    let report = waam_planner::first(part, &opts, &mut |_| {}).ok()?;
    report.best.map(|b| b.fragments)
}

/// Deposit times per weld path and arc-off times, read from the poses: the arc strikes
/// where a pose's arc flag turns on (the first block's deposit), goes off where it turns
/// off; every later block is deposited when a weld pose sits on its point.
fn executed(tp: &Toolpath) -> (Vec<Vec<f64>>, Vec<f64>) {
    let mut deposits: Vec<Vec<f64>> = Vec::new();
    let mut off = Vec::new();
    let mut on = false;
    for p in &tp.poses {
        if p.arc_on && !on {
            deposits.push(vec![p.time_s]);
        } else if !p.arc_on && on {
            off.push(p.time_s);
        } else if on && p.kind == PoseKind::Weld && p.at_point && p.point > 0 {
            deposits.last_mut().unwrap().push(p.time_s);
        }
        on = p.arc_on;
    }
    (deposits, off)
}

fn model(part: &Part) -> ThermalModel {
    ThermalModel::new(part, &WeldGraph::new(part))
}

#[test]
fn every_sample_part_is_checked_on_the_time_line_it_executes() {
    let cell = cell();
    let mut planned_parts = Vec::new();
    let mut rejected = Vec::new();
    for name in SAMPLES {
        let part = part(name);
        let Some(fragments) = first_plan(&part) else {
            assert!(
                matches!(name, "s4-tee-k1" | "s6-channel"),
                "{name}: no plan"
            );
            continue;
        };
        match cell.motion(part.clone(), found(fragments.clone())) {
            Ok(planned) => {
                let dt = part.thermal.dt();
                let (deposits, off) = executed(&planned.toolpath);
                let t = &planned.timeline;
                assert_eq!(deposits.len(), fragments.len(), "{name}");
                assert_eq!(off.len(), fragments.len(), "{name}");
                let t0 = deposits[0][0];
                // Every deposit and arc-off (hence every arc-off gap) within one Euler step
                // (in fact half a step: the nearest step) of the checked time line.
                for (f, d) in deposits.iter().enumerate() {
                    assert_eq!(d.len(), fragments[f].len(), "{name} path {f}");
                    for (k, &s) in d.iter().enumerate() {
                        let want = t.deposits[f][k] as f64 * dt;
                        assert!(
                            (s - t0 - want).abs() <= 0.5 * dt + 1e-9,
                            "{name}: path {f} block {k} deposited at {} s, checked at {want} s",
                            s - t0
                        );
                    }
                    let want = t.arc_off[f] as f64 * dt;
                    assert!(
                        (off[f] - t0 - want).abs() <= 0.5 * dt + 1e-9,
                        "{name}: arc-off {f}"
                    );
                }
                for f in 1..fragments.len() {
                    let gap = deposits[f][0] - off[f - 1];
                    let checked = (t.deposits[f][0] - t.arc_off[f - 1]) as f64 * dt;
                    assert!((gap - checked).abs() <= dt + 1e-9, "{name}: gap {f}");
                }
                // The robot is timed to the model: every arc strikes at its modelled step.
                let m = model(&part);
                let modelled = Timeline::modelled(&m, &fragments);
                for f in 0..fragments.len() {
                    assert_eq!(t.deposits[f][0], modelled.deposits[f][0], "{name}: {f}");
                }
                // And the plan keeps every window on the times read here.
                let here = Timeline::from_seconds(&deposits, &off, dt).unwrap();
                assert_eq!(&here, t, "{name}");
                let out = simulate_on(&m, &fragments, &here).unwrap();
                assert!(out.violation.is_none(), "{name}: {:?}", out.violation);
                planned_parts.push(name);
            }
            Err(PipelineError::InfeasibleExecuted { .. }) => rejected.push(name),
            Err(e) => panic!("{name}: {e}"),
        }
    }
    eprintln!("planned: {planned_parts:?}; rejected on the executed time line: {rejected:?}");
    // Every sample part with a feasible plan is either planned (its checks above hold) or
    // refused on its executed time line. Which first plan the search finds depends on its
    // order: with the thermal check inside the search, s1-wall's first plan (feasible on
    // the model's time line) breaks a window when timed, and is refused.
    assert_eq!(
        planned_parts.len() + rejected.len(),
        8,
        "{planned_parts:?} {rejected:?}"
    );
    assert!(
        planned_parts.len() > rejected.len(),
        "{planned_parts:?} {rejected:?}"
    );
}

/// A plan that keeps its windows with the modelled 5 s transits but breaks one when the
/// robot goes on as soon as it can (its natural transit, about a second) is timed to pass
/// or rejected: never returned as feasible with the natural timing.
#[test]
fn a_plan_that_needs_the_modelled_transit_is_timed_to_it_or_rejected() {
    let part = part("s1-wall");
    let m = model(&part);
    let cell = cell();
    let plans: Vec<Vec<Vec<usize>>> = common::planner::brute_force_plans(&part, part.max_fragments)
        .into_iter()
        .filter(|p| p.len() > 1 && common::planner::is_feasible(&part, p))
        .collect();
    assert!(!plans.is_empty());
    let mut natural_fails = 0;
    for fragments in &plans {
        // The robot's natural timing: no waiting at the approach points.
        let (tp, _) =
            waam_motion::plan_motion(&part, fragments, &cell.settings, &cell.robot).unwrap();
        let (deposits, off) = executed(&tp);
        let natural = Timeline::from_seconds(&deposits, &off, m.dt).unwrap();
        let gap = deposits[1][0] - off[0];
        assert!(gap < 2.0, "natural transit {gap} s");
        let fails_naturally = simulate_on(&m, fragments, &natural)
            .unwrap()
            .violation
            .is_some();
        natural_fails += fails_naturally as usize;
        match cell.motion(part.clone(), found(fragments.clone())) {
            Ok(planned) => {
                let (deposits, off) = executed(&planned.toolpath);
                let timed = Timeline::from_seconds(&deposits, &off, m.dt).unwrap();
                assert!(simulate_on(&m, fragments, &timed)
                    .unwrap()
                    .violation
                    .is_none());
                // Timed: the arc-off gap is the model's transit less the dwells.
                let gap = deposits[1][0] - off[0];
                assert!(gap > 4.0, "timed transit {gap} s");
            }
            Err(PipelineError::InfeasibleExecuted { .. }) => {}
            Err(e) => panic!("{fragments:?}: {e}"),
        }
    }
    eprintln!(
        "s1-wall: {natural_fails} of {} feasible two-path plans break a window with the natural transit",
        plans.len()
    );
    assert!(
        natural_fails > 0,
        "no feasible s1-wall plan breaks a window with the natural transit"
    );
}

/// A transit the robot cannot make within transit_time_s is a clear error.
#[test]
fn a_transit_slower_than_the_model_is_an_error() {
    let mut part = part("s1-wall");
    part.thermal.transit_time_s = 0.0;
    let plan = common::planner::brute_force_plans(&part, 2)
        .into_iter()
        .find(|p| p.len() == 2)
        .unwrap();
    let err = cell().plan_motion(&part, &plan).unwrap_err().to_string();
    assert!(
        err.contains("from the arc-off of weld path 1 to the arc-on of weld path 2")
            && err.contains("transit_time_s"),
        "{err}"
    );
}

/// Dwells the model does not know are on the executed time line: with a 2 s arc-on dwell
/// (the later blocks of each weld path 2 s later than modelled) some feasible s1-wall plans
/// break a window there and are rejected, naming the block; none is returned that does.
#[test]
fn a_plan_that_fails_on_its_executed_time_line_is_rejected() {
    let part = part("s1-wall");
    let m = model(&part);
    let mut cell = cell();
    cell.settings.arc_on_dwell_s = 2.0;
    let (mut ok, mut rejected) = (0, 0);
    for fragments in common::planner::brute_force_plans(&part, part.max_fragments)
        .into_iter()
        .filter(|p| common::planner::is_feasible(&part, p))
    {
        match cell.motion(part.clone(), found(fragments.clone())) {
            Ok(planned) => {
                let (deposits, off) = executed(&planned.toolpath);
                let t = Timeline::from_seconds(&deposits, &off, m.dt).unwrap();
                assert!(simulate_on(&m, &fragments, &t).unwrap().violation.is_none());
                ok += 1;
            }
            Err(e @ PipelineError::InfeasibleExecuted { .. }) => {
                let text = e.to_string();
                assert!(
                    text.contains("executed time line") && text.contains("block ["),
                    "{text}"
                );
                rejected += 1;
            }
            Err(e) => panic!("{fragments:?}: {e}"),
        }
    }
    eprintln!("2 s arc-on dwell: {ok} feasible plans kept, {rejected} rejected");
    assert!(
        rejected > 0 && ok + rejected == 21,
        "{ok} kept, {rejected} rejected"
    );
}
