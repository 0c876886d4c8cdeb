//! Planning the rest of a part from a built state (`plan_rest`): against brute force on
//! small random parts, from states of the planner's own model and of another one.

mod common;

use common::planner::*;
use proptest::prelude::*;
use waam_part::graph::WeldGraph;
use waam_part::plan::Plan;
use waam_part::{Part, ThermalParams};
use waam_planner::{self as planner, Backend, Built, Options, RestError};
use waam_thermal::{BuildState, Simulation, ThermalModel};

/// The deposit sequence of a plan, as (block, begins a weld path).
fn sequence(plan: &[Vec<usize>]) -> Vec<(usize, bool)> {
    plan.iter()
        .flat_map(|f| f.iter().enumerate().map(|(p, &b)| (b, p == 0)))
        .collect()
}

/// The state after the first `cut` deposits of `plan` under `model` (None: a window broke
/// on the way).
fn state_after(model: &ThermalModel, plan: &[Vec<usize>], cut: usize) -> Option<BuildState> {
    let mut sim = Simulation::new(model);
    for &(b, new) in &sequence(plan)[..cut] {
        sim.deposit(b, new).ok()?;
    }
    Some(sim.state())
}

/// Whether the rest of `plan` after `state` keeps every window, simulated from the state.
fn completes(model: &ThermalModel, state: &BuildState, plan: &[Vec<usize>]) -> bool {
    let mut sim = Simulation::from_state(model, state).unwrap();
    for &(b, new) in &sequence(plan)[state.order.len()..] {
        if sim.deposit(b, new).is_err() {
            return false;
        }
    }
    matches!(sim.finish(), Ok(Ok(())))
}

/// Brute force: the valid plans that begin with the built prefix (a closed prefix: the next
/// deposit begins a weld path).
fn completions(part: &Part, built: &Built) -> Vec<Vec<Vec<usize>>> {
    let prefix = &built.state.order;
    brute_force_plans(part, part.max_fragments)
        .into_iter()
        .filter(|p| {
            let seq = sequence(p);
            seq[..prefix.len()] == prefix[..]
                && (built.open || seq.get(prefix.len()).is_none_or(|&(_, new)| new))
        })
        .collect()
}

fn small_part() -> impl Strategy<Value = Part> {
    grown_part("rest", [3, 2, 3], 8, 4)
}

/// The part with other thermal constants (a "true" cell: lower losses).
fn with_params(part: &Part, params: ThermalParams) -> Part {
    let mut other = part.clone();
    other.thermal = params;
    other
}

fn check_against_brute_force(part: &Part, built: &Built, truth: &ThermalModel) {
    let all = completions(part, built);
    let feasible: Vec<_> = all
        .iter()
        .filter(|p| completes(truth, &built.state, p))
        .collect();
    for solver in [Backend::Cadical, Backend::Varisat] {
        let opts = Options {
            solver,
            ..Options::default()
        };
        let report = planner::plan_rest(part, built, &opts, &mut |_| {}).unwrap();
        assert!(report.proven);
        match &report.best {
            None => assert!(
                feasible.is_empty(),
                "{solver:?}: no completion found, brute force has {}: {:?}",
                feasible.len(),
                feasible[0]
            ),
            Some(found) => {
                let plan = &found.fragments;
                let graph = WeldGraph::new(part);
                Plan::from_indices(part, plan)
                    .validate(part, &graph)
                    .expect("the completion is a valid plan of the whole part");
                assert_eq!(
                    sequence(plan)[..built.state.order.len()],
                    built.state.order[..]
                );
                assert!(completes(truth, &built.state, plan), "{solver:?}: {plan:?}");
                let fewest = feasible.iter().map(|p| p.len()).min().unwrap();
                assert_eq!(plan.len(), fewest, "{solver:?}: not the fewest weld paths");
            }
        }
        if report.best.is_none() {
            assert!(report.no_plan.is_some());
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, ..ProptestConfig::default() })]

    /// From a state of the planner's own model, cut anywhere in a valid plan: a completion
    /// is found exactly when brute force has one, with the fewest weld paths.
    #[test]
    fn the_rest_is_found_exactly_when_brute_force_has_one(
        part in small_part(),
        pick in any::<u32>(),
        cut in any::<u32>(),
    ) {
        let plans = brute_force_plans(&part, part.max_fragments);
        prop_assume!(!plans.is_empty());
        let plan = &plans[pick as usize % plans.len()];
        let cut = 1 + cut as usize % part.len();
        let graph = WeldGraph::new(&part);
        let model = ThermalModel::new(&part, &graph);
        let state = state_after(&model, plan, cut);
        prop_assume!(state.is_some());
        let built = Built { state: state.unwrap(), open: false };
        check_against_brute_force(&part, &built, &model);
    }

    /// From the state a different ("true") model reached: the rest is judged from that
    /// state (the true model's, measured warmer), not from the planner's own replay of the
    /// prefix.
    #[test]
    fn the_rest_is_judged_from_the_given_state(
        part in small_part(),
        pick in any::<u32>(),
        cut in any::<u32>(),
        warmer in 0.0f64..400.0,
    ) {
        let plans = brute_force_plans(&part, part.max_fragments);
        prop_assume!(!plans.is_empty());
        let plan = &plans[pick as usize % plans.len()];
        let cut = 1 + cut as usize % part.len();
        let hot = ThermalParams {
            substrate_per_s: part.thermal.substrate_per_s * 0.5,
            radiation_per_s_k3: part.thermal.radiation_per_s_k3 * 0.5,
            conduction_per_s: part.thermal.conduction_per_s * 0.8,
            ..part.thermal
        };
        let truth_part = with_params(&part, hot);
        let graph = WeldGraph::new(&part);
        let truth = ThermalModel::new(&truth_part, &graph);
        let state = state_after(&truth, plan, cut);
        prop_assume!(state.is_some());
        let mut state = state.unwrap();
        // And measured warmer still (a pyrometer's reading).
        for t in &mut state.temperatures {
            *t += warmer;
        }
        let built = Built { state, open: false };
        // The planner's model of the rest is the part's own; only the state is the truth's.
        let own = ThermalModel::new(&part, &graph);
        check_against_brute_force(&part, &built, &own);
    }
}

#[test]
fn an_open_prefix_may_be_continued_without_a_new_arc_start() {
    // A 4-block wall at k = 1: after two deposits with the arc on, the only completion
    // goes on in the same weld path; closed, there is none (a second path is not allowed).
    let part =
        Part::parse("name: w\nblock_mm: [6,6,2.5]\nmax_fragments: 1\nlayers: ['####']\n").unwrap();
    let graph = WeldGraph::new(&part);
    let model = ThermalModel::new(&part, &graph);
    let state = state_after(&model, &[vec![0, 1, 2, 3]], 2).unwrap();
    let open = Built {
        state: state.clone(),
        open: true,
    };
    let report = planner::plan_rest(&part, &open, &Options::default(), &mut |_| {}).unwrap();
    let found = report.best.expect("the path goes on");
    assert_eq!(found.fragments, vec![vec![0, 1, 2, 3]]);
    assert_eq!(open.remainder(&found.fragments), (true, vec![vec![2, 3]]));
    let closed = Built { state, open: false };
    let report = planner::plan_rest(&part, &closed, &Options::default(), &mut |_| {}).unwrap();
    assert!(report.best.is_none() && report.proven);
    assert!(report
        .no_plan
        .unwrap()
        .to_string()
        .contains("no valid plan"));
}

#[test]
fn a_prefix_that_breaks_the_rules_is_refused_with_its_deposit() {
    let part =
        Part::parse("name: t\nblock_mm: [6,6,2.5]\nmax_fragments: 2\nlayers: ['##', '##']\n")
            .unwrap();
    let built = |order: Vec<(usize, bool)>| Built {
        state: BuildState {
            temperatures: vec![600.0; order.len()],
            order,
            t85_steps: vec![],
            steps: 100,
        },
        open: false,
    };
    let err = |b: Built| match planner::plan_rest(&part, &b, &Options::default(), &mut |_| {}) {
        Err(RestError::Prefix(m)) => m,
        other => panic!("{other:?}"),
    };
    // Block 2 is [0,0,1], standing on block 0.
    let m = err(built(vec![(2, true)]));
    assert!(m.contains("deposit 1") && m.contains("stands on"), "{m}");
    let m = err(built(vec![(0, true), (3, false)]));
    assert!(m.contains("deposit 2: no weld move"), "{m}");
    let m = err(built(vec![(0, true), (1, true), (2, true)]));
    assert!(m.contains("3 weld paths"), "{m}");
    // A state that does not fit (too few temperatures) is named too.
    let mut b = built(vec![(0, true)]);
    b.state.temperatures.clear();
    let e = planner::plan_rest(&part, &b, &Options::default(), &mut |_| {}).unwrap_err();
    assert!(e.to_string().contains("0 temperatures for 1"), "{e}");
}

/// A graph part's first layer welded as one closed weld path: the rest (three layers of two
/// rings) is planned at once with one more arc start. Asking the solver first whether no
/// further arc start could do kept CaDiCaL refuting Hamiltonian paths for minutes.
#[test]
fn a_closed_layer_of_a_ring_of_beads_is_completed_with_one_more_weld_path_at_once() {
    let text = include_str!("../../../tests/data/ring-beads.yaml");
    let beads = waam_part::BeadPart::parse(text.split("\nt85:").next().unwrap()).unwrap();
    let mut part = Part::of_beads(beads).unwrap();
    part.set_max_fragments(4);
    let graph = WeldGraph::new(&part);
    let model = ThermalModel::new(&part, &graph);
    let whole = planner::plan(&part, &Options::default(), &mut |_| {})
        .unwrap()
        .best
        .unwrap()
        .fragments
        .concat();
    let layer0 = whole.iter().take_while(|&&b| part.block(b)[2] == 0).count();
    let state = state_after(&model, std::slice::from_ref(&whole), layer0).unwrap();
    let built = Built { state, open: false };
    let opts = Options {
        timeout: Some(std::time::Duration::from_secs(20)),
        ..Options::default()
    };
    let report = planner::plan_rest(&part, &built, &opts, &mut |_| {}).unwrap();
    assert!(report.proven, "the best completion is proven");
    assert_eq!(report.best.unwrap().fragments.len(), 2);
}
