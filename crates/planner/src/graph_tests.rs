//! Planning graph parts with the graph thermal model: the plan found keeps its windows
//! when a fresh simulation checks it.

use super::*;
use waam_part::BeadPart;
use waam_thermal::Simulation;

/// A graph part of `layers` square rings of 4 nodes (side `side_mm`), Along contacts around
/// each ring and Stacked contacts onto the node below, with the `t85` lines given.
pub(crate) fn square_rings(layers: usize, side_mm: f64, t85: &str) -> Part {
    let (w, h) = (6.0, 2.5);
    let half = side_mm / 2.0;
    let corners = [[-half, -half], [half, -half], [half, half], [-half, half]];
    let mut text =
        format!("kind: beads\nname: rings\nmax_fragments: 2\nbead_mm: [{w}, {h}]\nbeads:\n");
    for z in 0..layers {
        text +=
            &format!(
            "  - {{layer: {z}, closed: true, points: [[{}, {}], [{}, {}], [{}, {}], [{}, {}]]}}\n",
            corners[0][0], corners[0][1], corners[1][0], corners[1][1],
            corners[2][0], corners[2][1], corners[3][0], corners[3][1]
        );
    }
    text += "nodes:\n";
    for z in 0..layers {
        for p in 0..4 {
            let [x0, y0] = corners[p];
            let [x1, y1] = corners[(p + 1) % 4];
            let l = side_mm;
            text += &format!(
                "  - {{bead: {z}, from_mm: {}, to_mm: {}, layer: {z}, centre_mm: [{}, {}, {}], volume_mm3: {}, surface_mm2: {}, substrate_mm2: {}}}\n",
                p as f64 * l,
                (p + 1) as f64 * l,
                (x0 + x1) / 2.0,
                (y0 + y1) / 2.0,
                (z as f64 + 0.5) * h,
                l * w * h,
                2.0 * l * (w + h) + 2.0 * w * h,
                if z == 0 { l * w } else { 0.0 },
            );
        }
    }
    text += "contacts:\n";
    let mut contacts = Vec::new();
    for z in 0..layers {
        for p in 0..4 {
            let i = 4 * z + p;
            let next = 4 * z + (p + 1) % 4;
            contacts.push((i.min(next), i.max(next), w * h, "along"));
            if z > 0 {
                contacts.push((i - 4, i, side_mm * w, "stacked"));
            }
        }
    }
    contacts.sort_by_key(|c| (c.0, c.1));
    for (a, b, area, kind) in contacts {
        text += &format!("  - [{a}, {b}, {area}, {kind}]\n");
    }
    text += t85;
    Part::of_beads(BeadPart::parse(&text).unwrap()).unwrap()
}

/// Node 5 (layer 1) may spend at most 2 s between 800 and 500 °C at each crossing: over
/// all valid plans of three rings its t8/5 times range 0.55..4.55 s, so the window rules
/// out some plans and not all.
#[test]
fn a_graph_part_plan_keeps_its_window() {
    let part = square_rings(3, 12.0, "t85:\n  - {node: 5, min_s: 0, max_s: 2.0}\n");
    let opts = Options::default();
    let counts = count(&part, &opts, true, &mut |_| {}).unwrap();
    let plans = counts.plans.unwrap();
    assert!(
        0 < counts.feasible && counts.feasible < plans,
        "{} feasible of {plans}",
        counts.feasible
    );
    let report = first(&part, &opts, &mut |_| {}).unwrap();
    let found = report.best.expect("a feasible plan");
    // Checked by a fresh simulation, deposit by deposit.
    let model = ThermalModel::new(&part, &WeldGraph::new(&part));
    let mut sim = Simulation::new(&model).recording();
    for fragment in &found.fragments {
        for (p, &node) in fragment.iter().enumerate() {
            sim.deposit(node, p == 0).unwrap();
        }
    }
    sim.finish().unwrap().unwrap();
    let t85: Vec<f64> = sim
        .crossings()
        .iter()
        .filter(|c| c.block == 5)
        .map(|c| c.t85_s)
        .collect();
    assert!(!t85.is_empty() && t85.iter().all(|&t| t <= 2.0), "{t85:?}");
    assert!(
        found.margin >= 0.0 && found.margin.is_finite(),
        "{}",
        found.margin
    );
}

/// A graph part the graph model refuses is a typed error, not a panic.
#[test]
fn a_graph_part_the_model_refuses_is_an_error() {
    // Sides of 12 m: nodes of 2000 V0, 2·10^9 deposit steps each at 10^6 substeps.
    let part = square_rings(
        1,
        12_000.0,
        "thermal: {substeps: 1000000, max_cooldown_s: 100, transit_time_s: 1}\n",
    );
    let err = first(&part, &Options::default(), &mut |_| {}).unwrap_err();
    assert!(matches!(err, PlanError::Graph(_)), "{err}");
}
