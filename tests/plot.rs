//! The temperature curves are the thermal model's own temperatures.

mod common;

use waam_part::graph::WeldGraph;
use waam_thermal::{simulate, Simulation, ThermalModel};

#[test]
fn temperature_curves_follow_the_thermal_model() {
    for name in ["s3-ring", "s7-pad", "ex3-h-column"] {
        let (part, fragments) = common::part_and_plan(name);
        let curves = waam_plot::temperature_curves(&part, &fragments);
        assert_eq!(curves.len(), part.windows().len());
        let graph = WeldGraph::new(&part);
        let model = ThermalModel::new(&part, &graph);
        // While depositing, the samples are exactly the model's temperatures (an
        // infeasible plan is followed up to its first violation).
        let mut sim = Simulation::new(&model);
        'plan: for fragment in &fragments {
            for (p, &b) in fragment.iter().enumerate() {
                if sim.deposit(b, p == 0).is_err() {
                    break 'plan;
                }
                for (blk, t) in sim.temperatures() {
                    if let Some(c) = curves.iter().find(|c| c.block == part.block(blk)) {
                        let s = c.samples.iter().find(|s| s.0 == sim.time_s());
                        assert_eq!(
                            s.map(|s| s.1),
                            Some(t),
                            "{name} {:?} at {}",
                            c.block,
                            sim.time_s()
                        );
                    }
                }
            }
        }
        // Every curve ends below 500 °C, after the model's last t8/5 crossing of its block.
        let outcome = simulate(&model, &fragments).unwrap();
        for c in &curves {
            assert!(c.samples.windows(2).all(|w| w[1].0 > w[0].0));
            assert!(c.samples.last().unwrap().1 < 500.0, "{name} {:?}", c.block);
            let last_hot = c.samples.iter().rev().find(|s| s.1 >= 500.0).unwrap().0;
            let b = part.index_of(c.block).unwrap();
            if let Some(x) = outcome.crossings.iter().rfind(|x| x.block == b) {
                assert!(last_hot < x.time_s, "{name} {:?}", c.block);
            }
        }
    }
}
