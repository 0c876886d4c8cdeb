//! The MILP of the paper's formulation and the branch and bound agree on a reduced layer.
#![cfg(feature = "milp")]

use waam_layer::{milp, search, Layer, Model, SearchOptions};

/// A triangle with a tail, every wall 4 mm long and welded in two 2 mm steps: four
/// possible trails, no deadheading, a coarse mesh — small enough for a pure-Rust MILP.
const REDUCED: &str = "
name: triangle-tail
wall_width_mm: 1.0
nodes:
  - {id: A, x: 0.0, y: 0.0}
  - {id: B, x: 4.0, y: 0.0}
  - {id: C, x: 2.0, y: 3.4641016151377544}
  - {id: D, x: 8.0, y: 0.0}
segments:
  - [A, B]
  - [B, C]
  - [C, A]
  - [B, D]
process:
  weld_speed_mm_s: 20.0
  time_step_s: 0.1
  transit_speed_mm_s: 50.0
material:
  diffusivity_mm2_s: 5.0
  robin_mm_s: 0.5
temperatures:
  ambient_c: 20.0
  initial_c: 20.0
  target_c: 400.0
source:
  peak_k_s: 8000.0
  radii_mm: [1.0, 2.0]
  weights: [1.0, 0.4]
";

#[test]
fn milp_optimum_equals_the_search_optimum() {
    let layer = Layer::parse(REDUCED).unwrap();
    let model = Model::new(&layer).unwrap();
    let found = search(&model, &SearchOptions::default());
    assert!(found.proven_optimal);
    let lp = milp::solve(&model).unwrap();
    model.check_trail(&lp.trail).unwrap();
    let rel = (lp.objective - found.objective).abs() / found.objective;
    assert!(
        rel < 1e-6,
        "MILP {} vs search {}",
        lp.objective,
        found.objective
    );
    // The MILP's trail, simulated, scores the optimum too.
    let sim = model.simulate(&lp.trail, None);
    assert!((sim - found.objective).abs() / found.objective < 1e-6);
}
