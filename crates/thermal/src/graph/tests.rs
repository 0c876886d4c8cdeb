//! The fast step against the reference, bit for bit; the block model as a graph; bad
//! inputs; the throughput measurement (ignored: run it in release).

use super::*;
use crate::{Simd, Simulation, ThermalModel};
use proptest::prelude::*;
use waam_part::graph::{WeldGraph, NONE};
use waam_part::Part;

fn bits(t: &[f64]) -> Vec<u64> {
    t.iter().map(|x| x.to_bits()).collect()
}

fn params(h: f64, hs: f64, r: f64, ambient: f64, deposit: f64, substeps: u32) -> ThermalParams {
    ThermalParams {
        ambient_c: ambient,
        deposit_c: deposit,
        block_time_s: 1.0,
        substeps,
        transit_time_s: 2.0,
        conduction_per_s: h,
        substrate_per_s: hs,
        radiation_per_s_k3: r,
        max_cooldown_s: 0.0,
    }
}

prop_compose! {
    /// A random small graph: chains (i, i + 1) and strides (i, i + s), which give the
    /// kernel consecutive columns, plus random pairs; areas up to 2·A0 (some exactly 0);
    /// volumes 0.2..3·V0; a random weld order with a random number of steps after each.
    fn case()(
        n in 1usize..48,
        stride in 2usize..9,
        chain in any::<u64>(),
        strided in any::<u64>(),
        extra in proptest::collection::vec((0u32..48, 0u32..48, 0.0f64..2.0), 0..30),
        geo in proptest::collection::vec((0.2f64..3.0, 0.0f64..8.0, 0.0f64..2.0, any::<bool>()), 48),
        areas in proptest::collection::vec(prop_oneof![Just(0.0), 0.0f64..2.0], 96),
        sorted in any::<bool>(),
        seed in any::<u64>(),
        runs in proptest::collection::vec(0u64..30, 48),
        h in 0.0f64..3.0,
        hs in 0.0f64..3.0,
        r in 0.0f64..5e-12,
        ambient in -30.0f64..120.0,
        deposit in 300.0f64..3000.0,
        substeps in 1u32..25,
    ) -> (GraphModel, Vec<usize>, Vec<u64>) {
        let (w, hh) = (6.0, 2.5);
        let (a0, v0) = (w * hh, w * w * hh);
        let nodes: Vec<NodeGeometry> = geo[..n]
            .iter()
            .map(|&(v, s, b, on)| NodeGeometry {
                volume: v * v0,
                surface: s * a0,
                substrate: if on { b * a0 } else { 0.0 },
            })
            .collect();
        let mut contacts = Vec::new();
        let mut seen = std::collections::HashSet::new();
        let mut push = |a: usize, b: usize, area: f64, contacts: &mut Vec<(u32, u32, f64)>| {
            if a != b && a < n && b < n && seen.insert((a.min(b), a.max(b))) {
                contacts.push((a as u32, b as u32, area * a0));
            }
        };
        for i in 0..n {
            if chain >> (i % 64) & 1 != 0 {
                push(i, i + 1, areas[i], &mut contacts);
            }
            if strided >> (i % 64) & 1 != 0 {
                push(i, i + stride, areas[48 + i], &mut contacts);
            }
        }
        for &(a, b, area) in &extra {
            push(a as usize, b as usize, area, &mut contacts);
        }
        if sorted {
            contacts.sort_by_key(|&(a, b, _)| (a, b));
        }
        let p = params(h, hs, r, ambient, deposit, substeps);
        let model = GraphModel::new(p, w, hh, &nodes, &contacts).expect("a generated graph");
        let mut order: Vec<usize> = (0..n).collect();
        let mut x = seed | 1;
        for i in (1..n).rev() {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            order.swap(i, (x % (i as u64 + 1)) as usize);
        }
        (model, order, runs[..n].to_vec())
    }
}

/// Deposits `order` with `runs[k]` steps after the k-th deposit on the reference and on
/// `sims`, comparing every temperature bit after each.
fn compare(
    model: &GraphModel,
    sims: &mut [GraphSimulation<'_>],
    order: &[usize],
    runs: &[u64],
) -> Result<(), TestCaseError> {
    let mut reference = GraphReference::new(model);
    for (&node, &steps) in order.iter().zip(runs) {
        reference.deposit(node);
        reference.run(steps);
        let want = bits(reference.temperatures());
        for sim in sims.iter_mut() {
            sim.deposit(node);
            sim.step(steps);
            prop_assert_eq!(sim.steps(), reference.steps());
            prop_assert_eq!(
                bits(sim.temperatures()),
                want.clone(),
                "kernel {:?}",
                sim.simd()
            );
        }
    }
    Ok(())
}

fn kernels(model: &GraphModel) -> Vec<GraphSimulation<'_>> {
    Simd::available()
        .into_iter()
        .map(|s| GraphSimulation::new(model).with_simd(s))
        .collect()
}

prop_compose! {
    /// A small [`ring_graph`] (consecutive columns: the AVX2 kernel's loads), random
    /// constants, weld order and steps.
    fn ring_case()(
        layers in 1usize..5,
        ring in 1usize..14,
        rings in 1usize..3,
        shuffle in any::<bool>(),
        seed in any::<u64>(),
        runs in proptest::collection::vec(0u64..30, 4 * 13 * 2),
        h in 0.0f64..3.0,
        hs in 0.0f64..3.0,
        r in 0.0f64..5e-12,
        ambient in -30.0f64..120.0,
        deposit in 300.0f64..3000.0,
        substeps in 1u32..25,
    ) -> (GraphModel, Vec<usize>, Vec<u64>) {
        let (nodes, contacts) = ring_graph(Ring { layers, ring, rings, shuffle });
        let p = params(h, hs, r, ambient, deposit, substeps);
        let model = GraphModel::new(p, 6.0, 2.5, &nodes, &contacts).expect("a ring graph");
        let n = model.len();
        // Mostly bottom-up, as plans weld, with random swaps.
        let mut order: Vec<usize> = (0..n).collect();
        let mut x = seed | 1;
        for i in 1..n {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            if x % 4 == 0 {
                order.swap(i, (x >> 8) as usize % n);
            }
        }
        (model, order, runs[..n].to_vec())
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]
    /// Every kernel of the fast step gives the reference's bits after every deposit.
    #[test]
    fn fast_step_is_bit_identical_to_the_reference((model, order, runs) in case()) {
        compare(&model, &mut kernels(&model), &order, &runs)?;
    }

    /// The same on ring graphs.
    #[test]
    fn fast_step_is_bit_identical_on_rings((model, order, runs) in ring_case()) {
        compare(&model, &mut kernels(&model), &order, &runs)?;
    }
}

proptest! {
    // Fewer cases: every step(n) call starts threads.
    #![proptest_config(ProptestConfig::with_cases(100))]
    /// The threaded step gives the reference's bits.
    #[test]
    fn threaded_step_is_bit_identical_to_the_reference((model, order, runs) in case()) {
        let mut sims = [2, 3].map(|t| GraphSimulation::new(&model).with_threads(t).with_parallel_min(0));
        compare(&model, &mut sims, &order, &runs)?;
    }

    #[test]
    fn threaded_step_is_bit_identical_on_rings((model, order, runs) in ring_case()) {
        let mut sims = [2, 3].map(|t| GraphSimulation::new(&model).with_threads(t).with_parallel_min(0));
        compare(&model, &mut sims, &order, &runs)?;
    }
}

prop_compose! {
    /// A random block part (as the block model's own test makes them) and deposit order.
    fn cube_case()(
        dims in (1i64..7, 1i64..6, 1i64..6),
        fill in proptest::collection::vec(any::<u8>(), 6 * 5 * 5),
        density in 96u8..=255,
        seed in any::<u64>(),
        news in proptest::collection::vec(any::<u8>(), 150),
        h in 0.0f64..3.0,
        hs in 0.0f64..3.0,
        r in 0.0f64..5e-12,
        ambient in -30.0f64..120.0,
        deposit in 300.0f64..3000.0,
        substeps in 1u32..25,
    ) -> (Part, Vec<(usize, bool)>) {
        let (nx, ny, nz) = dims;
        let mut blocks = Vec::new();
        for z in 0..nz {
            for y in 0..ny {
                for x in 0..nx {
                    if fill[(z * 30 + y * 6 + x) as usize] <= density {
                        blocks.push([x, y, z]);
                    }
                }
            }
        }
        if blocks.is_empty() {
            blocks.push([0, 0, 0]);
        }
        let mut part = Part::from_blocks("p".into(), [6.0, 6.0, 2.5], [0.0; 3], 3, blocks)
            .expect("a generated part");
        part.thermal = params(h, hs, r, ambient, deposit, substeps);
        let mut order: Vec<usize> = (0..part.len()).collect();
        let mut x = seed | 1;
        for i in (1..order.len()).rev() {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            order.swap(i, (x % (i as u64 + 1)) as usize);
        }
        let seq = order
            .into_iter()
            .enumerate()
            .map(|(p, b)| (b, p == 0 || news[p] < 40))
            .collect();
        (part, seq)
    }
}

/// A block part as a graph: every node V0, S = 6·A0, B = A0 on layer 0, and one contact of
/// area A0 per pair of face-neighbours, listed axis by axis (x, y, z), each axis by lower
/// block: then every node meets its contacts in the block model's face order.
fn cube_graph(part: &Part) -> GraphModel {
    let (w, h) = (part.block_mm[0], part.block_mm[2]);
    let (a0, v0) = (w * h, w * w * h);
    let graph = WeldGraph::new(part);
    let nodes: Vec<NodeGeometry> = part
        .blocks()
        .iter()
        .map(|b| NodeGeometry {
            volume: v0,
            surface: 6.0 * a0,
            substrate: if b[2] == 0 { a0 } else { 0.0 },
        })
        .collect();
    let mut contacts = Vec::new();
    for axis in 0..3 {
        for i in 0..part.len() {
            let j = graph.faces(i)[2 * axis + 1];
            if j != NONE {
                contacts.push((i as u32, j, a0));
            }
        }
    }
    GraphModel::new(part.thermal, w, h, &nodes, &contacts).expect("a block graph")
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(150))]
    /// With W·H, W·W·H and 6·W·H exact (W = 6, H = 2.5), the graph model of a block part
    /// is the block model bit for bit, time line included.
    #[test]
    fn a_block_part_is_the_block_model((part, seq) in cube_case()) {
        let graph = WeldGraph::new(&part);
        let cube = ThermalModel::new(&part, &graph);
        let model = cube_graph(&part);
        let mut blocks = Simulation::new(&cube).with_threads(1);
        let mut sim = GraphSimulation::new(&model);
        let mut fragments = 0;
        for &(b, new) in &seq {
            blocks.deposit(b, new).unwrap();
            if new && fragments > 0 {
                sim.step(model.transit_steps);
            }
            fragments += new as usize;
            sim.deposit(b);
            sim.step(model.deposit_steps(b));
            prop_assert_eq!(sim.steps(), blocks.steps());
            for (i, t) in blocks.temperatures() {
                prop_assert_eq!(sim.temperatures()[i].to_bits(), t.to_bits(), "block {}", i);
            }
        }
    }
}

#[test]
fn deposit_steps_follow_the_volume() {
    let p = ThermalParams::default();
    let v0 = 6.0 * 6.0 * 2.5;
    let nodes: Vec<NodeGeometry> = [1.0, 0.5, 0.524, 0.526, 0.01, 2.0]
        .iter()
        .map(|&v| (v * v0, 0.0, 0.0).into())
        .collect();
    let m = GraphModel::new(p, 6.0, 2.5, &nodes, &[]).unwrap();
    let steps: Vec<u64> = (0..nodes.len()).map(|i| m.deposit_steps(i)).collect();
    assert_eq!(steps, [20, 10, 10, 11, 1, 40]);
}

#[test]
fn bad_inputs_name_the_node_or_contact() {
    let p = ThermalParams::default();
    let ok: NodeGeometry = (90.0, 90.0, 15.0).into();
    let new = |nodes: &[NodeGeometry], contacts: &[(u32, u32, f64)]| {
        GraphModel::new(p, 6.0, 2.5, nodes, contacts).map(|_| ())
    };
    let e = |r: Result<(), GraphError>| r.unwrap_err();
    assert_eq!(
        GraphModel::new(p, 0.0, 2.5, &[ok], &[]).map(|_| ()),
        Err(GraphError::Reference { w: 0.0, h: 2.5 })
    );
    assert!(matches!(
        e(new(&[ok, (0.0, 1.0, 0.0).into()], &[])),
        GraphError::Volume { node: 1, .. }
    ));
    assert!(matches!(
        e(new(&[(f64::NAN, 1.0, 0.0).into()], &[])),
        GraphError::Volume { node: 0, .. }
    ));
    assert!(matches!(
        e(new(&[ok, (1.0, -1.0, 0.0).into()], &[])),
        GraphError::Surface { node: 1, .. }
    ));
    assert!(matches!(
        e(new(&[(1.0, 1.0, f64::INFINITY).into()], &[])),
        GraphError::Substrate { node: 0, .. }
    ));
    assert!(matches!(
        e(new(&[(1e300, 1.0, 0.0).into()], &[])),
        GraphError::VolumeTooLarge { node: 0, .. }
    ));
    assert!(matches!(
        e(new(&[ok, ok], &[(0, 1, 1.0), (1, 0, -1.0)])),
        GraphError::Area { contact: 1, .. }
    ));
    assert_eq!(
        e(new(&[ok, ok], &[(0, 1, 1.0), (1, 2, 1.0)])),
        GraphError::OutOfRange {
            contact: 1,
            a: 1,
            b: 2,
            node: 2,
            nodes: 2
        }
    );
    assert_eq!(
        e(new(&[ok, ok], &[(1, 1, 1.0)])),
        GraphError::SelfContact {
            contact: 0,
            node: 1
        }
    );
    let err = e(new(&[ok, ok, ok], &[(0, 1, 1.0), (1, 2, 1.0), (1, 0, 2.0)]));
    assert_eq!(
        err,
        GraphError::Duplicate {
            contact: 2,
            first: 0,
            a: 1,
            b: 0
        }
    );
    assert_eq!(err.to_string(), "contact 2 (1, 0) repeats contact 0");
}

/// A free surface smaller than the welded contacts is floored at 0: no negative radiation.
#[test]
fn free_surface_is_floored_at_zero() {
    let p = ThermalParams::default();
    let nodes: Vec<NodeGeometry> = vec![(90.0, 15.0, 0.0).into(), (90.0, 90.0, 0.0).into()];
    let m = GraphModel::new(p, 6.0, 2.5, &nodes, &[(0, 1, 30.0)]).unwrap();
    assert_eq!(m.radiation(0, |_| true).to_bits(), 0f64.to_bits());
    assert_eq!(m.radiation(1, |_| true), p.radiation_per_s_k3 * 4.0);
    assert_eq!(m.radiation(1, |_| false), p.radiation_per_s_k3 * 6.0);
}

/// Node-steps per second of the fast step on ring graphs, every node welded:
/// `cargo test --release -p waam-thermal -- --ignored bench_graph --nocapture`.
#[test]
#[ignore]
fn bench_graph_throughput() {
    let kernels = Simd::available().into_iter().map(|s| (s, 1));
    for (simd, threads) in kernels.chain([(Simd::detect(), 2)]) {
        for &(layers, ring, rings, shuffle) in &[
            (100, 100, 1, false),
            (100, 300, 2, false),
            (100, 600, 1, false),
            (100, 300, 2, true),
        ] {
            let nodes = layers * ring * rings;
            let steps = (3e8 / nodes as f64) as u64;
            let spec = Ring {
                layers,
                ring,
                rings,
                shuffle,
            };
            let (n, wall, cpu) = bench_graph(spec, simd, threads, steps, 5);
            println!(
                "bench_graph {simd:?} x {threads} thread(s): {layers} layers x {rings} ring(s) x {ring} = {n} nodes{}: {wall:.3e} node-steps/s (wall), {cpu:.3e} per CPU-second",
                if shuffle { ", shuffled" } else { "" },
            );
        }
    }
}

/// The AVX2 step alone on 1 and 2 threads (for quick comparisons of kernel changes).
#[test]
#[ignore]
fn bench_graph_quick() {
    for threads in [1, 2] {
        for &(ring, rings) in &[(100, 1), (300, 2)] {
            let spec = Ring {
                layers: 100,
                ring,
                rings,
                shuffle: false,
            };
            let steps = (3e8 / (100 * ring * rings) as f64) as u64;
            let (n, wall, cpu) = bench_graph(spec, Simd::detect(), threads, steps, 5);
            println!(
                "bench_graph_quick {n} nodes, {threads} thread(s): {wall:.3e} node-steps/s (wall), {cpu:.3e} per CPU-second"
            );
        }
    }
}

// --- Undeposit, and the planner's `Simulation` on graph parts --------------------------

/// Deposits `order` on a fresh fast simulation, `runs[i]` steps after the i-th.
fn deposited<'m>(model: &'m GraphModel, order: &[usize], runs: &[u64]) -> GraphSimulation<'m> {
    let mut sim = GraphSimulation::new(model);
    for (i, &node) in order.iter().enumerate() {
        sim.deposit(node);
        sim.step(runs[i]);
    }
    sim
}

#[test]
fn undeposit_is_the_inverse_of_deposit() {
    let (nodes, contacts) = ring_graph(Ring {
        layers: 3,
        ring: 5,
        rings: 2,
        shuffle: false,
    });
    let model = GraphModel::new(ThermalParams::default(), 6.0, 2.5, &nodes, &contacts).unwrap();
    // a, b along the layer-0 ring; c (layer 1) stands on both.
    let (a, b, c) = (0, 1, 10);
    let mut three = deposited(&model, &[a, b, c], &[0, 0, 0]);
    three.undeposit(c);
    let two = deposited(&model, &[a, b], &[0, 0]);
    assert_eq!(three.table, two.table);
    assert_eq!((three.lo, three.hi), (two.lo, two.hi));
    assert_eq!(bits(three.temperatures()), bits(two.temperatures()));
    let (mut three, mut two) = (three, two);
    three.step(37);
    two.step(37);
    assert_eq!(bits(three.temperatures()), bits(two.temperatures()));
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    /// The step tables are a function of the welded set: undepositing any welded nodes,
    /// in any order, leaves those of depositing the others only.
    #[test]
    fn undeposit_leaves_the_tables_of_the_rest((model, order, runs) in case(), cut in any::<u64>()) {
        let n = order.len();
        let mut sim = deposited(&model, &order, &runs);
        let keep = (cut % (n as u64 + 1)) as usize;
        // Undo the nodes past `keep` in a scrambled order.
        let mut undo: Vec<usize> = order[keep..].to_vec();
        undo.sort_by_key(|&x| (x as u64).wrapping_mul(cut | 1) % 97);
        for &node in &undo {
            sim.undeposit(node);
        }
        let rest = deposited(&model, &order[..keep], &vec![0; keep]);
        prop_assert_eq!(&sim.table, &rest.table);
        prop_assert_eq!((sim.lo, sim.hi), (rest.lo, rest.hi));
    }
}

/// A graph part of `layers` rings of `ring` nodes (the [`ring_graph`] geometry), one closed
/// bead per layer, with `t85` windows (node, min_s, max_s) and `thermal` constants.
fn ring_part(
    layers: usize,
    ring: usize,
    t85: &[(usize, f64, f64)],
    thermal: ThermalParams,
) -> Part {
    use waam_part::beads::{Bead, BeadPart, Contact, ContactKind, Deposit};
    let (nodes, contacts) = ring_graph(Ring {
        layers,
        ring,
        rings: 1,
        shuffle: false,
    });
    let radius = 40.0;
    let corner = |p: usize| {
        let a = std::f64::consts::TAU * p as f64 / ring as f64;
        [radius * a.cos(), radius * a.sin()]
    };
    let beads: Vec<Bead> = (0..layers)
        .map(|z| Bead {
            layer: z as u32,
            closed: true,
            points: (0..ring).map(corner).collect(),
        })
        .collect();
    let side = beads[0].length_mm() / ring as f64;
    let deposits = nodes
        .iter()
        .enumerate()
        .map(|(i, g)| {
            let (z, p) = (i / ring, i % ring);
            let [x0, y0] = corner(p);
            let [x1, y1] = corner(p + 1);
            Deposit {
                bead: z,
                from_mm: p as f64 * side,
                to_mm: (p + 1) as f64 * side,
                layer: z as u32,
                centre_mm: [(x0 + x1) / 2.0, (y0 + y1) / 2.0, (z as f64 + 0.5) * 2.5],
                volume_mm3: g.volume,
                surface_mm2: g.surface,
                substrate_mm2: g.substrate,
            }
        })
        .collect();
    let contacts = contacts
        .iter()
        .map(|&(a, b, area)| Contact {
            a: a as usize,
            b: b as usize,
            area_mm2: area,
            kind: if a as usize / ring == b as usize / ring {
                ContactKind::Along
            } else {
                ContactKind::Stacked
            },
        })
        .collect();
    let part = BeadPart {
        name: "ring".into(),
        max_fragments: 3,
        bead_mm: [6.0, 2.5],
        base_z_mm: 0.0,
        beads,
        nodes: deposits,
        contacts,
        windows: t85
            .iter()
            .map(|&(i, min_s, max_s)| (i, waam_part::Window { min_s, max_s }))
            .collect(),
        thermal,
        warnings: Vec::new(),
    };
    Part::of_beads(part).unwrap()
}

fn graph_thermal(part: &Part) -> ThermalModel {
    ThermalModel::try_new(part, &WeldGraph::new(part)).unwrap()
}

/// A plan over 12 nodes in 3 layers: 3 fragments, layer by layer, mixed directions.
const RING_PLAN: [(usize, bool); 12] = [
    (0, true),
    (1, false),
    (2, false),
    (3, false),
    (7, true),
    (6, false),
    (5, false),
    (4, false),
    (9, true),
    (10, false),
    (11, false),
    (8, false),
];

/// The t8/5 rules of the doc, by hand over the reference: the first violation (step,
/// node, max?) of the windowed nodes, judged after every step.
struct Judge {
    count: Vec<u64>,
    dt: f64,
    windows: Vec<(usize, f64, f64)>,
}

impl Judge {
    fn step(&mut self, before: &[f64], after: &[f64], welded: &[bool]) -> Option<(usize, bool)> {
        let mut first = None;
        for (a, &(i, lo, hi)) in self.windows.iter().enumerate() {
            if !welded[i] {
                continue;
            }
            let (u, v) = (before[i], after[i]);
            let broken = if v > 800.0 {
                self.count[a] = 0;
                None
            } else if v >= 500.0 {
                self.count[a] += 1;
                (self.count[a] as f64 * self.dt > hi + 1e-9).then_some(true)
            } else if u >= 500.0 {
                (self.count[a] as f64 * self.dt < lo - 1e-9).then_some(false)
            } else {
                None
            };
            if let (Some(max), None) = (broken, first) {
                first = Some((i, max));
            }
        }
        first
    }
}

/// Runs the reference over the plan's time line (transit, deposit, deposit steps), then
/// `cooldown` more steps; returns per deposit the welded temperatures in weld order, the
/// final temperatures, and the first violation (step, node, max?) of `windows`.
#[allow(clippy::type_complexity)]
fn reference_run(
    model: &GraphModel,
    transit: u64,
    plan: &[(usize, bool)],
    windows: &[(usize, f64, f64)],
    cooldown: u64,
) -> (Vec<Vec<u64>>, Vec<u64>, Option<(u64, usize, bool)>) {
    let mut r = GraphReference::new(model);
    let mut judge = Judge {
        count: vec![0; windows.len()],
        dt: model.dt,
        windows: windows.to_vec(),
    };
    let mut violation = None;
    let mut welded = vec![false; model.len()];
    let run = |r: &mut GraphReference,
               judge: &mut Judge,
               n: u64,
               welded: &[bool],
               violation: &mut Option<_>| {
        for _ in 0..n {
            let before = r.temperatures().to_vec();
            r.step();
            if let Some((i, max)) = judge.step(&before, r.temperatures(), welded) {
                violation.get_or_insert((r.steps(), i, max));
            }
        }
    };
    let mut after = Vec::new();
    let mut order = Vec::new();
    for (p, &(b, new)) in plan.iter().enumerate() {
        if new && p > 0 {
            run(&mut r, &mut judge, transit, &welded, &mut violation);
        }
        r.deposit(b);
        welded[b] = true;
        if let Some(a) = windows.iter().position(|w| w.0 == b) {
            judge.count[a] = 0;
        }
        order.push(b);
        run(
            &mut r,
            &mut judge,
            model.deposit_steps(b),
            &welded,
            &mut violation,
        );
        after.push(
            order
                .iter()
                .map(|&i| r.temperatures()[i].to_bits())
                .collect(),
        );
    }
    run(&mut r, &mut judge, cooldown, &welded, &mut violation);
    (after, bits(r.temperatures()), violation)
}

fn welded_bits(sim: &Simulation) -> Vec<u64> {
    sim.temperatures().map(|(_, t)| t.to_bits()).collect()
}

#[test]
fn simulation_of_a_graph_part_is_the_reference_bit_for_bit() {
    let windows = [(2, 0.0, 1000.0), (9, 0.0, 1000.0)];
    let part = ring_part(3, 4, &windows, ThermalParams::default());
    let model = graph_thermal(&part);
    let gm = model.graph().expect("a graph model");
    // The ring's node lengths differ: so do their deposit times.
    let steps: Vec<u64> = (0..12).map(|i| gm.deposit_steps(i)).collect();
    assert!(steps.iter().any(|&s| s != steps[0]), "{steps:?}");
    for simd in [Simd::Scalar, Simd::detect()] {
        let model = graph_thermal(&part).with_simd(simd);
        let mut sim = Simulation::new(&model).with_threads(1);
        let mut per_deposit = Vec::new();
        for &(b, new) in &RING_PLAN {
            sim.deposit(b, new).unwrap();
            per_deposit.push(welded_bits(&sim));
        }
        let before = sim.steps();
        sim.finish().unwrap().unwrap();
        let cooldown = sim.steps() - before;
        assert!(cooldown > 0);
        let (after, last, violation) =
            reference_run(gm, model.transit_steps, &RING_PLAN, &windows, cooldown);
        assert_eq!(per_deposit, after, "{simd:?}");
        let mut fin = vec![0; 12];
        for (i, t) in sim.temperatures() {
            fin[i] = t.to_bits();
        }
        assert_eq!(fin, last, "{simd:?}");
        assert_eq!(violation, None);
        let total: u64 = steps.iter().sum::<u64>() + 2 * model.transit_steps + cooldown;
        assert_eq!(sim.steps(), total);
    }
}

#[test]
fn snapshots_replay_bit_for_bit_on_a_graph_part() {
    let part = ring_part(
        3,
        4,
        &[(1, 0.0, 1000.0), (6, 0.0, 1000.0)],
        ThermalParams::default(),
    );
    let model = graph_thermal(&part);
    let mut a = Simulation::new(&model);
    for &(b, new) in &RING_PLAN[..5] {
        a.deposit(b, new).unwrap();
    }
    let snap = a.snapshot();
    // Down another branch (touching the prefix's nodes from above), then back.
    a.deposit(8, true).unwrap();
    a.deposit(4, false).unwrap();
    a.deposit(6, false).unwrap();
    a.restore(&snap);
    for &(b, new) in &RING_PLAN[5..] {
        a.deposit(b, new).unwrap();
    }
    let mut fresh = Simulation::new(&model);
    for &(b, new) in &RING_PLAN {
        fresh.deposit(b, new).unwrap();
    }
    assert_eq!(welded_bits(&a), welded_bits(&fresh));
    assert_eq!(a.steps(), fresh.steps());
    assert_eq!(a.graph_table(), fresh.graph_table());
    a.finish().unwrap().unwrap();
    fresh.finish().unwrap().unwrap();
    assert_eq!(a.steps(), fresh.steps());
    assert_eq!(welded_bits(&a), welded_bits(&fresh));

    // A snapshot resumed in another simulation that went elsewhere first.
    let mut other = Simulation::new(&model);
    for &(b, new) in &[(0, true), (3, false), (4, false), (11, true)] {
        other.deposit(b, new).unwrap();
    }
    other.restore_from_trail(&snap, &RING_PLAN);
    for &(b, new) in &RING_PLAN[5..] {
        other.deposit(b, new).unwrap();
    }
    let mut fresh = Simulation::new(&model);
    for &(b, new) in &RING_PLAN {
        fresh.deposit(b, new).unwrap();
    }
    assert_eq!(welded_bits(&other), welded_bits(&fresh));
    assert_eq!(other.steps(), fresh.steps());
    assert_eq!(other.graph_table(), fresh.graph_table());
}

#[test]
fn a_broken_window_on_a_graph_part_is_the_references() {
    // Node 5 (layer 1) must stay between 800 and 500 °C for at most 0.5 s: it cools more
    // slowly once the layer above covers it.
    for (window, max) in [((5, 0.0, 0.5), true), ((5, 60.0, 1000.0), false)] {
        let windows = [window];
        let part = ring_part(3, 4, &windows, ThermalParams::default());
        let model = graph_thermal(&part);
        let mut sim = Simulation::new(&model);
        let mut v = None;
        for &(b, new) in &RING_PLAN {
            if let Err(e) = sim.deposit(b, new) {
                v = Some(e);
                break;
            }
        }
        let v = match v {
            Some(v) => v,
            None => sim.finish().unwrap().unwrap_err(),
        };
        let gm = model.graph().unwrap();
        let (_, _, expected) = reference_run(
            gm,
            model.transit_steps,
            &RING_PLAN,
            &windows,
            gm.cooldown_steps,
        );
        let (step, node, is_max) = expected.expect("the reference breaks the window");
        assert_eq!(
            (v.step, v.block, v.kind == crate::ViolationKind::Max),
            (step, node, is_max)
        );
        assert_eq!(is_max, max);
    }
}

#[test]
fn a_graph_part_the_model_rejects_is_an_error() {
    let thermal = ThermalParams {
        substeps: 1_000_000,
        ..ThermalParams::default()
    };
    // Nodes of 9000 V0: more than MAX_STEPS deposit steps each.
    let part = ring_part(1, 3, &[], thermal);
    let mut beads = part.bead_part().unwrap().clone();
    for d in &mut beads.nodes {
        d.volume_mm3 *= 9000.0;
    }
    let part = Part::of_beads(beads).unwrap();
    let err = ThermalModel::try_new(&part, &WeldGraph::new(&part)).unwrap_err();
    assert!(
        matches!(err, GraphError::VolumeTooLarge { node: 0, .. }),
        "{err}"
    );
}
