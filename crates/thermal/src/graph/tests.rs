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
