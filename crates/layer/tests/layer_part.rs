//! Thick-wall parts: the bundled STLs sliced into the bundled layer files, bad sections
//! refused with a named error, and a 20-layer part planned end to end with the heat carried
//! from layer to layer (trails, motion, recording).
//! (Through the binary: `tests/cli/layer_part.rs`.)

use std::path::Path;
use std::time::{Duration, Instant};

use waam_fixtures::grid_layer;
use waam_layer::part::{plan_part, PartManifest, PartOptions};
use waam_layer::slice::{slice_mesh, LayerDoc, LayerParams, SliceOptions};
use waam_layer::{Layer, SearchOptions};
use waam_mesh::{read_stl, Units};

mod common;

fn slice_bundled(stl: &str, h: f64, w: Option<f64>) -> Vec<(f64, Layer)> {
    let bytes = std::fs::read(common::root().join(stl)).unwrap();
    let mesh = read_stl(&bytes, Units::Mm).unwrap();
    let name = Path::new(stl)
        .file_stem()
        .unwrap()
        .to_string_lossy()
        .into_owned();
    slice_mesh(
        &mesh,
        &SliceOptions {
            name,
            layer_height_mm: h,
            wall_width_mm: w,
            params: LayerParams::default(),
        },
    )
    .unwrap()
    .into_iter()
    .map(|l| (l.z_mm, l.layer))
    .collect()
}

/// Node positions (µm) and walls as position pairs: a graph independent of node ids.
fn graph(l: &Layer) -> (i64, Vec<[[i64; 2]; 2]>) {
    let p = |v: usize| l.point(v).map(|c| (c * 1000.0).round() as i64);
    let mut segs: Vec<[[i64; 2]; 2]> = l
        .segments
        .iter()
        .map(|&[a, b]| {
            let (pa, pb) = (p(a), p(b));
            if pa <= pb {
                [pa, pb]
            } else {
                [pb, pa]
            }
        })
        .collect();
    segs.sort_unstable();
    ((l.wall_width_mm * 1000.0).round() as i64, segs)
}

#[test]
fn the_bundled_rib_web_slices_into_the_hand_made_layer_and_the_bundled_files() {
    let hand = Layer::parse(
        &std::fs::read_to_string(common::root().join("config/layers/rib-web-3x3.yaml")).unwrap(),
    )
    .unwrap();
    let layers = slice_bundled("config/rib-web-3x3.stl", 2.0, None);
    assert_eq!(layers.len(), 20);
    let (manifest, files) =
        PartManifest::read_dir(&common::root().join("config/layers/rib-web-3x3")).unwrap();
    assert_eq!(manifest.layers.len(), 20);
    for (k, (z, l)) in layers.iter().enumerate() {
        assert!(
            (z - (1.0 + 2.0 * k as f64)).abs() < 1e-6,
            "z of layer {k}: {z}"
        );
        assert_eq!(graph(l), graph(&hand), "layer {k}");
        assert_eq!(l.nodes.len(), 16);
        assert_eq!(l.segments.len(), 24);
        // The committed sliced files are what slicing gives today.
        assert_eq!(files[k].0, *z);
        assert_eq!(
            LayerDoc::of(&files[k].1).to_yaml(),
            LayerDoc::of(l).to_yaml()
        );
    }
    let honey = Layer::parse(
        &std::fs::read_to_string(common::root().join("config/layers/honeycomb-12.yaml")).unwrap(),
    )
    .unwrap();
    let layers = slice_bundled("config/honeycomb-12.stl", 2.0, Some(2.0));
    let (_, files) =
        PartManifest::read_dir(&common::root().join("config/layers/honeycomb-12")).unwrap();
    assert_eq!((layers.len(), files.len()), (10, 10));
    for ((_, l), (_, f)) in layers.iter().zip(&files) {
        assert_eq!(l.segments.len(), honey.segments.len());
        assert_eq!(l.nodes.len(), honey.nodes.len());
        assert_eq!(graph(l), graph(f));
        // Positions within the slicing tolerance of the hand-made honeycomb (1 µm: its
        // coordinates are written with 9 decimals, the STL with f32).
        for v in 0..honey.nodes.len() {
            let p = honey.point(v);
            assert!(
                (0..l.nodes.len()).any(|k| {
                    let q = l.point(k);
                    (p[0] - q[0]).abs() < 1e-3 && (p[1] - q[1]).abs() < 1e-3
                }),
                "node {} of the honeycomb",
                honey.nodes[v].id
            );
        }
    }
}

#[test]
fn layer_n_plus_1_starts_warm_where_layer_n_ended_and_consecutive_layers_differ() {
    let layers = slice_bundled("config/rib-web-3x3.stl", 2.0, None);
    let options = PartOptions {
        interlayer_s: 1.0,
        search: SearchOptions {
            time_limit: Some(Duration::from_millis(200)),
            ..SearchOptions::default()
        },
        vary: true,
    };
    let mut seen = 0;
    let planned = plan_part(&layers[..4], &options, |k, _| {
        assert_eq!(k, seen);
        seen += 1;
    })
    .unwrap();
    assert_eq!(seen, 4);
    // The bottom layer starts cold and uniform.
    assert!(planned[0].model.initial_field.iter().all(|&u| u == 0.0));
    for n in 0..3 {
        let (below, above) = (&planned[n], &planned[n + 1]);
        above.model.check_trail(&above.result.trail).unwrap();
        let layer = &below.model.layer;
        let end = layer.point(below.end_node().unwrap());
        let start = layer.point(below.start_node().unwrap());
        let u = &above.model.initial_field;
        let at = |p: [f64; 2]| u[above.model.mesh.nearest(p)];
        // Warmer where the layer below ended (hot) than where it started (long cooled),
        // and warmer than ambient there.
        assert!(
            at(end) > 50.0,
            "layer {}: {} K above ambient at the end",
            n + 1,
            at(end)
        );
        assert!(
            at(end) > at(start) + 20.0,
            "layer {}: end {} K, start {} K",
            n + 1,
            at(end),
            at(start)
        );
        // The carried field is the one the layer below left, after the interlayer time.
        let hottest = below.end_field.iter().copied().fold(0.0, f64::max);
        assert!(u.iter().all(|&x| x <= hottest + 1e-9));
        // Consecutive layers differ: another start, no deadheading move repeated.
        assert_ne!(above.start_node(), below.start_node(), "layer {}", n + 1);
        assert!(above.varied);
        for [a, b] in above.deadheads() {
            assert!(
                !below
                    .deadheads()
                    .iter()
                    .any(|&[c, d]| (a, b) == (c, d) || (a, b) == (d, c)),
                "layer {} repeats the deadheading move {a} -> {b}",
                n + 1
            );
        }
    }
    // Carried heat changes the objective: the same layer from cold scores differently.
    let cold = waam_layer::Model::new(&layers[1].1).unwrap();
    assert!(cold.simulate(&planned[1].result.trail, None) != planned[1].result.objective);
}

const PAPER: &str = include_str!("../../../config/layers/paper-16mm.yaml");

/// The paper's parameters on a 2 x 1 domino of cells (7 walls, 1 deadheading move).
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
    Layer::parse(&text.replace("name: paper-16mm", "name: domino")).unwrap()
}

#[test]
fn from_a_carried_field_with_forbidden_moves_the_bound_holds_and_matches_enumeration() {
    let layer = domino();
    let below = waam_layer::Model::new(&layer).unwrap();
    let first = waam_layer::search(&below, &SearchOptions::default());
    let mut model = waam_layer::Model::new(&layer).unwrap();
    let u = waam_layer::part::carry(
        &below,
        &waam_layer::part::end_field(&below, &first.trail),
        0.5,
        &model,
    );
    assert!(u.iter().any(|&x| x > 50.0) && u.iter().all(|&x| x >= 0.0));
    model.set_initial_field(u);
    // The bound stays below every completion from the warm, uneven field.
    assert!(waam_layer::search::check_bound(&model).unwrap() > 20);
    let start = below.ends(&first.trail.moves[0]).0;
    let pairs = waam_layer::part::deadhead_pairs(&below, &first.trail);
    let constrained = |bound: bool| SearchOptions {
        bound,
        forbidden_starts: vec![start],
        forbidden_deadheads: pairs.clone(),
        ..SearchOptions::default()
    };
    let bb = waam_layer::search(&model, &constrained(true));
    let all = waam_layer::search(&model, &constrained(false));
    assert!(bb.proven_optimal);
    assert!((bb.objective - all.objective).abs() <= 1e-9 * all.objective);
    assert!(constrained(true).allows(&model, &bb.trail));
    assert_ne!(model.ends(&bb.trail.moves[0]).0, start);
    // Unconstrained from the same field, the optimum is at least as good.
    let free = waam_layer::search(&model, &SearchOptions::default());
    assert!(free.objective <= bb.objective * (1.0 + 1e-12));
}

/// Issue #18: a part's layers (`waam layer plan-part`) are held to the same memory limit,
/// each before its search.
#[test]
fn a_part_with_a_1000_segment_layer_is_refused_by_the_memory_limit() {
    let layer = Layer::parse(&grid_layer(22)).unwrap();
    let t = Instant::now();
    let err = match plan_part(&[(0.0, layer)], &Default::default(), |_, _| {}) {
        Ok(_) => panic!("a 1,000-segment layer was searched"),
        Err(e) => e.to_string(),
    };
    assert!(
        err.starts_with("layer 0 (grid22)") && err.contains("max_memory_mb = 1024"),
        "{err}"
    );
    assert!(t.elapsed() < Duration::from_secs(15), "{:?}", t.elapsed());
}
