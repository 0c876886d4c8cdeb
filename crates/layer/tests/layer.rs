//! Thick-wall layers: the file format's rules, the finite-element model, the search.
//! (Through the binary: `tests/cli/layer.rs`; the layer plots: `crates/plot/tests/layer.rs`.)

use waam_layer::fem::Matrices;
use waam_layer::mesh::Mesh;
use waam_layer::output::TrailFile;
use waam_layer::{search, Layer, Model, SearchOptions, Trail};

const PAPER: &str = include_str!("../../../config/layers/paper-16mm.yaml");

fn paper() -> Layer {
    Layer::parse(PAPER).expect("the bundled paper layer reads")
}

/// A 2x1-cell layer ("domino"): 6 nodes, 7 walls, small enough to enumerate.
fn domino() -> Layer {
    let text = PAPER.split("nodes:").next().unwrap().to_string()
        + "nodes:
  - {id: A, x: 1.0, y: 1.0}
  - {id: B, x: 8.0, y: 1.0}
  - {id: C, x: 15.0, y: 1.0}
  - {id: D, x: 1.0, y: 8.0}
  - {id: E, x: 8.0, y: 8.0}
  - {id: F, x: 15.0, y: 8.0}
segments:
  - [A, B]
  - [B, C]
  - [D, E]
  - [E, F]
  - [A, D]
  - [B, E]
  - [C, F]
" + &PAPER[PAPER.find("process:").unwrap()..];
    Layer::parse(&text.replace("name: paper-16mm", "name: domino")).expect("domino reads")
}

fn err(text: &str) -> String {
    Layer::parse(text).expect_err("must be refused").to_string()
}

fn edited(from: &str, to: &str) -> String {
    assert!(
        PAPER.contains(from),
        "test edit {from:?} not in the paper layer"
    );
    PAPER.replacen(from, to, 1)
}

#[test]
fn format_rules_are_enforced_with_named_errors() {
    assert!(err("").contains("empty"));
    assert!(Layer::from_bytes(&[0xff, 0xfe, 0x00])
        .unwrap_err()
        .to_string()
        .contains("UTF-8"));
    let e = err(&edited(
        "wall_width_mm: 2.0",
        "wall_width_mm: 2.0\ncolour: red",
    ));
    assert!(
        e.contains("unknown field `colour`") && e.contains("line"),
        "{e}"
    );
    let e = err(&edited("wall_width_mm: 2.0\n", ""));
    assert!(e.contains("missing field `wall_width_mm`"), "{e}");
    let e = err(&edited("wall_width_mm: 2.0", "wall_width_mm: -2"));
    assert!(e.contains("wall_width_mm") && e.contains("> 0"), "{e}");
    let e = err(&edited(
        "{id: B, x: 8.0, y: 1.0}",
        "{id: A, x: 8.0, y: 1.0}",
    ));
    assert!(
        e.contains("nodes[1]") && e.contains("id A is used twice"),
        "{e}"
    );
    let e = err(&edited(
        "{id: B, x: 8.0, y: 1.0}",
        "{id: B, x: .nan, y: 1.0}",
    ));
    assert!(e.contains("nodes[1] (id B): x"), "{e}");
    let e = err(&edited("  - [A, B]", "  - [A, Z]"));
    assert!(
        e.contains("segments[0] (A -> Z): node Z is not in 'nodes'"),
        "{e}"
    );
    let e = err(&edited("  - [A, B]", "  - [A, A]"));
    assert!(
        e.contains("segments[0]") && e.contains("two different nodes"),
        "{e}"
    );
    let e = err(&edited("  - [B, C]", "  - [B, A]"));
    assert!(
        e.contains("segments[1] (B -> A): the same wall as segments[0]"),
        "{e}"
    );
    let e = err(&edited(
        "  - {id: I, x: 15.0, y: 15.0}",
        "  - {id: I, x: 15.0, y: 15.0}\n  - {id: J, x: 30, y: 30}",
    ));
    assert!(e.contains("id J") && e.contains("on no segment"), "{e}");
    // A diagonal wall meets others at 45°.
    let e = err(&edited("  - [F, I]", "  - [F, I]\n  - [A, E]"));
    assert!(
        e.contains("segments[12] (A -> E)") && e.contains("45.0°"),
        "{e}"
    );
    // Walls that cross without a shared node.
    let e = err(&edited(
        "  - {id: I, x: 15.0, y: 15.0}",
        "  - {id: I, x: 15.0, y: 15.0}\n  - {id: P, x: 4.5, y: 4.0}\n  - {id: Q, x: 4.5, y: 12.0}",
    )
    .replace("  - [F, I]", "  - [F, I]\n  - [P, Q]"));
    assert!(
        e.contains("segments[12] (P -> Q)") && e.contains("without sharing a node"),
        "{e}"
    );
    let e = err(&edited("wall_width_mm: 2.0", "wall_width_mm: 6.0"));
    assert!(
        e.contains("segments[0] (A -> B)") && e.contains("too short"),
        "{e}"
    );
    let e = err(&edited("weights: [1.0, 0.4]", "weights: [1.0]"));
    assert!(e.contains("source.weights: 1 weights for 2 radii"), "{e}");
    let e = err(&edited("radii_mm: [1.0, 2.0]", "radii_mm: [2.0, 1.0]"));
    assert!(e.contains("source.radii_mm[1]"), "{e}");
    let e = err(&edited("time_step_s: 0.1", "time_step_s: 0"));
    assert!(e.contains("process.time_step_s"), "{e}");
    let e = err(&edited("time_step_s: 0.1", "time_step_s: 0.000001"));
    assert!(e.contains("weld time steps"), "{e}");
    let e = err(&edited("target_c: 400.0", "target_c: 1e9"));
    assert!(e.contains("temperatures.target_c"), "{e}");
}

#[test]
fn random_input_never_panics() {
    use proptest::prelude::*;
    let mut runner = proptest::test_runner::TestRunner::new(ProptestConfig::with_cases(300));
    runner
        .run(&proptest::collection::vec(any::<u8>(), 0..400), |bytes| {
            let _ = Layer::from_bytes(&bytes);
            Ok(())
        })
        .unwrap();
    // Mutations of a valid file: cut anywhere, or one byte changed.
    for cut in (0..PAPER.len()).step_by(7) {
        let _ = Layer::parse(&PAPER[..cut]);
        let mut b = PAPER.as_bytes().to_vec();
        b[cut] = b"9-:[]{}x .\n"[cut % 11];
        let _ = Layer::from_bytes(&b);
    }
}

#[test]
fn mass_matrix_sums_to_the_meshed_area_and_the_walls_area() {
    let layer = paper();
    for refinement in 0..=1 {
        let mesh = Mesh::with_refinement(&layer, refinement);
        let m = Matrices::assemble(&mesh, 5.0, 0.5);
        let total: f64 = m.mass.triplet_iter().map(|(_, _, v)| v).sum();
        let lumped: f64 = m.lumped_mass.iter().sum();
        assert!((total - mesh.total_area()).abs() < 1e-9);
        assert!((lumped - mesh.total_area()).abs() < 1e-9);
        // The walls of the paper layer: 16 x 16 mm minus four 5 x 5 mm holes.
        assert!((total - 156.0).abs() < 1e-9, "meshed area {total}");
        // Boundary length: outer 64 mm plus four holes of 20 mm.
        let boundary: f64 = mesh
            .boundary
            .iter()
            .map(|&[a, b]| waam_layer::format::dist(mesh.points[a], mesh.points[b]))
            .sum();
        assert!((boundary - 144.0).abs() < 1e-9, "boundary {boundary}");
    }
}

#[test]
fn without_a_source_the_field_decays_to_ambient() {
    let mut layer = paper();
    layer.temperatures.initial_c = 900.0;
    let model = Model::new(&layer).unwrap();
    let mut u = vec![model.initial; model.heat.len()];
    let mut last = f64::INFINITY;
    for _ in 0..3000 {
        model.heat.step(&mut u, &[]);
        let max = u.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
        assert!(
            max <= last + 1e-12,
            "the maximum must not grow without a source"
        );
        last = max;
    }
    let worst = u.iter().map(|x| x.abs()).fold(0.0, f64::max);
    assert!(worst < 1e-3, "still {worst} K above ambient");
    assert!(u.iter().all(|&x| x >= 0.0), "never below ambient");
}

#[test]
fn constant_source_reaches_the_discrete_steady_state() {
    let model = Model::new(&paper()).unwrap();
    let load = &model.loads[model.offset[4] + 3];
    let steady = model.heat.steady_state(load).unwrap();
    let mut u = vec![0.0; model.heat.len()];
    for _ in 0..5000 {
        model.heat.step(&mut u, load);
    }
    let scale = steady.iter().cloned().fold(0.0, f64::max);
    assert!(scale > 100.0, "the source heats: steady max {scale}");
    let diff = u
        .iter()
        .zip(&steady)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(
        diff < 1e-6 * scale,
        "transient {diff} K away from the steady state"
    );
}

#[test]
fn mesh_refinement_converges() {
    // Steady state under a smooth (Gaussian) heat input at the centre node E, read at a
    // point 3.5 mm away on the wall centre line, on meshes refined 0..=3 times.
    let layer = paper();
    let probe = [8.0, 4.5];
    let mut values = Vec::new();
    for refinement in 0..=3 {
        let mesh = Mesh::with_refinement(&layer, refinement);
        let at = mesh.nearest(probe);
        assert!(waam_layer::format::dist(mesh.points[at], probe) < 1e-9);
        let model = Model::with_mesh(&layer, mesh).unwrap();
        let load: Vec<(usize, f64)> = (0..model.mesh.points.len())
            .map(|i| {
                let r2 = (model.mesh.points[i][0] - 8.0).powi(2)
                    + (model.mesh.points[i][1] - 8.0).powi(2);
                (i, model.heat.lumped_mass[i] * 1000.0 * (-r2).exp())
            })
            .collect();
        let u = model.heat.steady_state(&load).unwrap();
        values.push(u[at]);
    }
    let d: Vec<f64> = values.windows(2).map(|w| (w[1] - w[0]).abs()).collect();
    assert!(
        d[1] < 0.5 * d[0] && d[2] < 0.5 * d[1],
        "no convergence: {values:?}"
    );
}

#[test]
fn branch_and_bound_finds_the_enumerated_optimum() {
    for layer in [domino(), paper()] {
        let model = Model::new(&layer).unwrap();
        let enumerate = search(
            &model,
            &SearchOptions {
                bound: false,
                symmetry: layer.segments.len() > 8,
                ..SearchOptions::default()
            },
        );
        assert!(enumerate.proven_optimal);
        for symmetry in [false, true] {
            let r = search(
                &model,
                &SearchOptions {
                    symmetry,
                    ..SearchOptions::default()
                },
            );
            assert!(r.proven_optimal && r.gap == 0.0);
            let rel = (r.objective - enumerate.objective).abs() / enumerate.objective;
            assert!(
                rel < 1e-9,
                "{}: B&B {} vs enumeration {}",
                layer.name,
                r.objective,
                enumerate.objective
            );
            if symmetry == (layer.segments.len() > 8) {
                assert!(r.nodes_explored <= enumerate.nodes_explored);
            }
            model.check_trail(&r.trail).unwrap();
            let again = model.simulate(&r.trail, None);
            assert!((again - r.objective).abs() <= 1e-9 * again);
            assert!(r.root_bound <= r.objective);
        }
        if layer.name == "paper-16mm" {
            // 1488 trails with one deadheading move (an independent count), 8 symmetries.
            assert_eq!(enumerate.leaves * 8, 1488);
        }
    }
}

#[test]
fn deadheading_count_is_the_chinese_postman_minimum() {
    assert_eq!(Model::new(&paper()).unwrap().deadheads, 1);
    assert_eq!(Model::new(&domino()).unwrap().deadheads, 0);
    let grid = Layer::parse(include_str!("../../../config/layers/grid-4x4.yaml")).unwrap();
    assert_eq!(waam_layer::model::min_deadheads(&grid), 5);
}

#[test]
fn a_time_limit_returns_a_valid_trail_with_a_sound_gap() {
    let grid = Layer::parse(include_str!("../../../config/layers/grid-4x4.yaml")).unwrap();
    let model = Model::new(&grid).unwrap();
    let r = search(
        &model,
        &SearchOptions {
            time_limit: Some(std::time::Duration::from_millis(300)),
            ..SearchOptions::default()
        },
    );
    model.check_trail(&r.trail).unwrap();
    assert!(!r.proven_optimal);
    assert!(r.lower_bound <= r.objective && r.gap > 0.0);
    assert!((model.simulate(&r.trail, None) - r.objective).abs() <= 1e-9 * r.objective);
}

#[test]
fn passes_and_trail_file_round_trip() {
    let model = Model::new(&paper()).unwrap();
    let r = search(&model, &SearchOptions::default());
    let passes = model.passes(&r.trail);
    assert_eq!(passes.len(), model.deadheads + 1);
    let points: usize = passes.iter().map(|p| p.points_mm.len() - 1).sum();
    assert_eq!(points, model.steps.iter().sum::<usize>());
    for pass in &passes {
        for w in pass.points_mm.windows(2) {
            assert!(((w[1] - w[0]).norm() - 1.0).abs() < 1e-9 && w[1].z == 0.0);
        }
    }
    // Each pass starts where its first move starts; deadheading separates passes.
    let first = model.ends(&r.trail.moves[0]).0;
    assert_eq!(passes[0].points_mm[0].x, model.layer.point(first)[0]);
    let file = TrailFile::new(&model, &r.trail, r.objective, r.lower_bound, true);
    let yaml = serde_yaml::to_string(&file).unwrap();
    let back: TrailFile = serde_yaml::from_str(&yaml).unwrap();
    assert_eq!(back, file);
    assert_eq!(back.trail(&model).unwrap(), r.trail);
    assert_eq!(file.steps.len(), model.horizon);
    assert_eq!(file.deadheading.len(), 1);
    let bad = Trail {
        moves: r.trail.moves[1..].to_vec(),
    };
    assert!(model
        .check_trail(&bad)
        .unwrap_err()
        .to_string()
        .contains("never welded"));
}

#[test]
fn the_lower_bound_never_exceeds_any_completion() {
    // Every prefix of every trail of the domino, of a three-wall star that needs one
    // deadheading move, and of the paper's layer (all 1488 trails).
    let star = PAPER
        .split("nodes:")
        .next()
        .unwrap()
        .replace("name: paper-16mm", "name: star")
        + "nodes:
  - {id: O, x: 8.0, y: 8.0}
  - {id: E, x: 15.0, y: 8.0}
  - {id: N, x: 8.0, y: 15.0}
  - {id: W, x: 1.0, y: 8.0}
segments:
  - [O, E]
  - [O, N]
  - [O, W]
" + &PAPER[PAPER.find("process:").unwrap()..];
    for layer in [domino(), Layer::parse(&star).unwrap(), paper()] {
        let model = Model::new(&layer).unwrap();
        let checked = waam_layer::search::check_bound(&model).unwrap();
        assert!(checked > 20, "{}: only {checked} prefixes", layer.name);
    }
}

#[test]
fn local_search_keeps_trails_valid_and_never_worsens() {
    use waam_layer::improve::improve;
    let model = Model::new(&paper()).unwrap();
    let r = search(
        &model,
        &SearchOptions {
            bound: false,
            ..SearchOptions::default()
        },
    );
    assert!(r.proven_optimal);
    // Another valid trail: the optimum welded backwards.
    let mut moves: Vec<_> = r
        .trail
        .moves
        .iter()
        .rev()
        .map(|m| waam_layer::Move {
            reversed: !m.reversed,
            deadhead_before: false,
            ..*m
        })
        .collect();
    // Re-mark the deadheading move where the reversed order breaks continuity.
    for k in 1..moves.len() {
        let (_, prev_end) = model.ends(&moves[k - 1]);
        let (start, _) = model.ends(&moves[k]);
        moves[k].deadhead_before = prev_end != start;
    }
    let start = waam_layer::Trail { moves };
    model.check_trail(&start).unwrap();
    let value = model.simulate(&start, None);
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(2);
    let (better, v) = improve(&model, &start, value, deadline);
    model.check_trail(&better).unwrap();
    assert!(v <= value);
    assert!((model.simulate(&better, None) - v).abs() <= 1e-9 * v);
    assert!(
        v >= r.objective * (1.0 - 1e-12),
        "never below the proven optimum"
    );
}
