//! Every family at a small size: the part reads back from its file unchanged, its witness
//! is a valid plan, and a fresh simulation of the witness keeps every window.

use waam_bench::{generate, Family, Spec};
use waam_part::graph::WeldGraph;
use waam_part::plan::Plan;
use waam_part::Part;
use waam_thermal::{Interrupt, ThermalModel};

fn spec(family: Family, blocks: usize, seed: u64) -> Spec {
    Spec {
        family,
        blocks,
        k: 2,
        windows: None,
        seed,
    }
}

#[test]
fn every_family_has_a_feasible_witness_that_survives_the_file() {
    for family in Family::ALL {
        for seed in 1..=3 {
            let g = generate(&spec(family, 600, seed), &Interrupt::after(None)).expect("generated");
            let text = waam_part::writer::to_yaml(&g.part);
            let part = Part::parse(&text).expect("the written part reads back");
            assert_eq!(part.blocks(), g.part.blocks());
            assert_eq!(part.windows(), g.part.windows());
            let n = part.len();
            assert!((300..=1200).contains(&n), "{}: {n} blocks", part.name);
            assert!(!part.windows().is_empty(), "{}: no window", part.name);
            // The witness as a plan file, read back and checked as `waam check` does.
            let plan_text = g.witness_plan().to_yaml();
            let plan = Plan::from_bytes(plan_text.as_bytes(), false).expect("plan reads back");
            let graph = WeldGraph::new(&part);
            let fragments = plan.validate(&part, &graph).expect("the witness is valid");
            assert!(fragments.len() <= part.max_fragments);
            let model = ThermalModel::new(&part, &graph);
            let outcome = waam_thermal::simulate(&model, &fragments).expect("cools");
            assert!(
                outcome.violation.is_none(),
                "{}: {:?}",
                part.name,
                outcome.violation
            );
        }
    }
}

#[test]
fn a_seed_gives_one_part_and_another_seed_another() {
    for family in Family::ALL {
        let a = generate(&spec(family, 500, 7), &Interrupt::after(None)).expect("generated");
        let b = generate(&spec(family, 500, 7), &Interrupt::after(None)).expect("generated");
        let c = generate(&spec(family, 500, 8), &Interrupt::after(None)).expect("generated");
        assert_eq!(a.part.blocks(), b.part.blocks());
        assert_eq!(a.part.windows(), b.part.windows());
        assert_eq!(a.witness, b.witness);
        assert!(
            a.part.blocks() != c.part.blocks() || a.witness != c.witness,
            "{}: seeds 7 and 8 gave the same part and witness",
            family.name()
        );
    }
}

#[test]
fn windows_are_tight_around_the_witness() {
    // ±10 % of a t8/5 time: a window is narrow, not "anything goes".
    let g = generate(&spec(Family::Tube, 800, 3), &Interrupt::after(None)).expect("generated");
    for (_, w) in g.part.windows() {
        assert!(w.min_s > 0.0 && w.max_s < 1.5 * w.min_s, "{w:?}");
    }
}

#[test]
fn bad_specs_are_refused_by_name() {
    let none = Interrupt::after(None);
    let err = |s: Spec| generate(&s, &none).expect_err("refused").to_string();
    assert!(err(spec(Family::Tube, 10, 1)).contains("blocks: 10"));
    assert!(err(Spec {
        windows: Some(5),
        ..spec(Family::Cup, 500, 1)
    })
    .contains("windows: 5"));
    assert!(err(Spec {
        k: 1,
        ..spec(Family::DoubleTube, 500, 1)
    })
    .contains("double-tube: needs k >= 2"));
    assert!(Family::parse("pipe")
        .unwrap_err()
        .to_string()
        .contains("\"pipe\""));
}

#[test]
fn a_cancelled_generation_stops() {
    let cancel = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(true));
    let stopped = Interrupt {
        deadline: None,
        cancel: Some(cancel),
    };
    let e = generate(&spec(Family::Tube, 5000, 1), &stopped).expect_err("stopped");
    assert!(e.to_string().contains("stopped"), "{e}");
}
