//! No input makes the readers panic: random bytes, random YAML built from the part keys,
//! near-valid part files with one field mutated, random plans, mutated STL files. What
//! parses is pushed on through the weld graph, plan validation and (when small) the
//! thermal simulation.
//! (Through the binary: `tests/cli/robustness.rs`.)

use std::path::PathBuf;
use std::time::Instant;

use proptest::prelude::*;
use serde_yaml::{Mapping, Value};
use waam_mesh::{read_stl, voxelize, Units, VoxelizeOptions};
use waam_part::graph::WeldGraph;
use waam_part::plan::Plan;
use waam_part::Part;
use waam_thermal::{simulate, ThermalModel};

const TOP_KEYS: [&str; 8] = [
    "name",
    "block_mm",
    "origin_mm",
    "max_fragments",
    "layers",
    "blocks",
    "t85",
    "thermal",
];
const WINDOW_KEYS: [&str; 4] = ["block", "box", "min_s", "max_s"];
const THERMAL_KEYS: [&str; 9] = [
    "ambient_c",
    "deposit_c",
    "block_time_s",
    "substeps",
    "transit_time_s",
    "conduction_per_s",
    "substrate_per_s",
    "radiation_per_s_k3",
    "max_cooldown_s",
];

fn repo(path: &str) -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../..")).join(path)
}

/// The part files of config/parts, as text.
fn sample_parts() -> Vec<String> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(repo("config/parts"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "yaml"))
        .collect();
    files.sort();
    files
        .iter()
        .map(|p| std::fs::read_to_string(p).unwrap())
        .collect()
}

fn number() -> impl Strategy<Value = Value> {
    prop_oneof![
        any::<i64>().prop_map(Value::from),
        (-3i64..12).prop_map(Value::from),
        any::<u64>().prop_map(Value::from),
        any::<f64>().prop_map(Value::from),
        prop::sample::select(vec![
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            -0.0,
            1e308,
            -1e308,
            5e-324,
            0.5,
            2.5,
            1e-300,
        ])
        .prop_map(Value::from),
    ]
}

fn leaf() -> impl Strategy<Value = Value> {
    prop_oneof![
        Just(Value::Null),
        any::<bool>().prop_map(Value::Bool),
        number(),
        number(),
        "[#. \n]{0,30}".prop_map(Value::String),
        ".{0,12}".prop_map(Value::String),
        prop::sample::select(TOP_KEYS.to_vec()).prop_map(|s| Value::String(s.into())),
    ]
}

/// Any YAML value, keys drawn from the part format's own key names half the time.
fn value() -> impl Strategy<Value = Value> {
    leaf().prop_recursive(4, 48, 6, |inner| {
        let key = prop_oneof![
            prop::sample::select(
                [
                    &TOP_KEYS[..],
                    &WINDOW_KEYS[..],
                    &THERMAL_KEYS[..],
                    &["min", "max"]
                ]
                .concat()
            )
            .prop_map(|s| Value::String(s.into())),
            leaf(),
        ];
        prop_oneof![
            prop::collection::vec(inner.clone(), 0..6).prop_map(Value::Sequence),
            prop::collection::vec((key, inner), 0..6)
                .prop_map(|kv| Value::Mapping(kv.into_iter().collect())),
        ]
    })
}

fn triple() -> impl Strategy<Value = Value> {
    prop::collection::vec(prop_oneof![(0i64..5).prop_map(Value::from), number()], 3)
        .prop_map(Value::Sequence)
}

/// A mapping with a random subset of the part keys, each with a plausible or random value.
fn part_doc() -> impl Strategy<Value = Value> {
    let window = prop::collection::vec(
        (
            prop::sample::select(WINDOW_KEYS.to_vec()),
            prop_oneof![triple(), number(), value()],
        ),
        0..5,
    )
    .prop_map(|kv| {
        Value::Mapping(
            kv.into_iter()
                .map(|(k, v)| (Value::String(k.into()), v))
                .collect(),
        )
    });
    let field = |key: &'static str| -> BoxedStrategy<Value> {
        match key {
            "layers" => prop_oneof![
                prop::collection::vec(
                    "[#. ]{0,5}(\n[#. ]{0,5}){0,4}".prop_map(Value::String),
                    0..4
                )
                .prop_map(Value::Sequence),
                value(),
            ]
            .boxed(),
            "blocks" => prop_oneof![
                prop::collection::vec(triple(), 0..8).prop_map(Value::Sequence),
                value(),
            ]
            .boxed(),
            "block_mm" | "origin_mm" => prop_oneof![triple(), value()].boxed(),
            "t85" => prop::collection::vec(window.clone(), 0..3)
                .prop_map(Value::Sequence)
                .boxed(),
            "thermal" => prop::collection::vec(
                (prop::sample::select(THERMAL_KEYS.to_vec()), number()),
                0..4,
            )
            .prop_map(|kv| {
                Value::Mapping(
                    kv.into_iter()
                        .map(|(k, v)| (Value::String(k.into()), v))
                        .collect(),
                )
            })
            .boxed(),
            _ => prop_oneof![number(), value()].boxed(),
        }
    };
    // Plausible values most of the time, so that many documents parse and go further.
    let plausible = |key: &'static str| -> BoxedStrategy<Value> {
        match key {
            "name" => "[a-z]{1,8}".prop_map(Value::String).boxed(),
            "block_mm" | "origin_mm" => prop::array::uniform3(0.5f64..10.0)
                .prop_map(|v| Value::Sequence(v.iter().map(|&x| x.into()).collect()))
                .boxed(),
            "max_fragments" => (1i64..4).prop_map(Value::from).boxed(),
            "t85" => prop::collection::vec(
                (prop::array::uniform3(0i64..3), 0.0f64..5.0, 0.0f64..20.0),
                0..3,
            )
            .prop_map(|ws| {
                let ws = ws.into_iter().map(|(b, lo, hi)| {
                    let mut m = Mapping::new();
                    m.insert("block".into(), b.iter().map(|&c| Value::from(c)).collect());
                    m.insert("min_s".into(), lo.into());
                    m.insert("max_s".into(), (lo + hi).into());
                    Value::Mapping(m)
                });
                Value::Sequence(ws.collect())
            })
            .boxed(),
            "thermal" => prop::collection::vec(
                (prop::sample::select(THERMAL_KEYS.to_vec()), 0.01f64..3.0),
                0..3,
            )
            .prop_map(|kv| {
                let kv = kv.into_iter().map(|(k, v)| {
                    let v = if k == "substeps" {
                        Value::from((v * 10.0) as i64 + 1)
                    } else {
                        v.into()
                    };
                    (Value::String(k.into()), v)
                });
                Value::Mapping(kv.collect())
            })
            .boxed(),
            _ => field(key),
        }
    };
    let fields: Vec<BoxedStrategy<Option<(Value, Value)>>> = TOP_KEYS
        .iter()
        .map(|&k| {
            let present = match k {
                "name" | "block_mm" | "max_fragments" => 0.95,
                "layers" => 0.6,
                "blocks" => 0.45,
                _ => 0.5,
            };
            prop::option::weighted(present, prop_oneof![4 => plausible(k), 1 => field(k)])
                .prop_map(move |v| v.map(|v| (Value::String(k.into()), v)))
                .boxed()
        })
        .collect();
    (fields, prop::option::weighted(0.1, (leaf(), value()))).prop_map(|(fields, extra)| {
        let mut map: Mapping = fields.into_iter().flatten().collect();
        if let Some((k, v)) = extra {
            map.insert(k, v);
        }
        Value::Mapping(map)
    })
}

/// Replaces the value at a random path of `doc` (chosen by `picks`) with `new`.
fn mutate(doc: &mut Value, picks: &[usize], new: Value) {
    if let Some((&p, rest)) = picks.split_first() {
        // Stop early sometimes, so that whole sub-trees get replaced too.
        if p % 5 != 0 {
            match doc {
                Value::Mapping(m) if !m.is_empty() => {
                    let k = m.keys().nth(p % m.len()).cloned().expect("in range");
                    return mutate(m.get_mut(&k).expect("present"), rest, new);
                }
                Value::Sequence(s) if !s.is_empty() => {
                    let n = s.len();
                    return mutate(&mut s[p % n], rest, new);
                }
                _ => {}
            }
        }
    }
    *doc = new;
}

/// Everything downstream of a part that parsed: graph, validation, bounded simulation.
fn exercise(part: &Part) {
    let graph = WeldGraph::new(part);
    let model = ThermalModel::new(part, &graph);
    // One block per fragment, bottom layer first: valid when k allows it.
    let mut many = part.clone();
    many.max_fragments = part.len();
    let singles = Plan {
        part: None,
        fragments: part.blocks().iter().map(|&b| vec![b]).collect(),
        nodes: None,
    };
    let whole = Plan {
        part: None,
        fragments: vec![part.blocks().to_vec()],
        nodes: None,
    };
    for (part, plan) in [(&many, singles), (part, whole)] {
        if let Ok(fragments) = plan.validate(part, &graph) {
            let n = part.len() as f64;
            let steps = n * model.params.substeps as f64
                + n * model.transit_steps as f64
                + model.cooldown_steps as f64;
            if steps * n < 2e7 {
                let _ = simulate(&model, &fragments);
            }
        }
    }
}

/// The JSON form of a YAML value: keys become strings, NaN and infinities null.
fn to_json(v: &Value) -> serde_json::Value {
    match v {
        Value::Mapping(m) => m
            .iter()
            .map(|(k, v)| {
                let key = match k {
                    Value::String(s) => s.clone(),
                    other => serde_yaml::to_string(other).unwrap(),
                };
                (key, to_json(v))
            })
            .collect::<serde_json::Map<_, _>>()
            .into(),
        Value::Sequence(s) => s.iter().map(to_json).collect(),
        Value::Tagged(t) => to_json(&t.value),
        other => serde_json::to_value(other).unwrap_or(serde_json::Value::Null),
    }
}

fn parse_and_exercise(text: &str) {
    if let Ok(part) = Part::parse(text) {
        exercise(&part);
    }
}

proptest! {
    #![proptest_config(ProptestConfig {
        failure_persistence: None,
        ..ProptestConfig::with_cases(400)
    })]

    #[test]
    fn random_bytes_never_panic(bytes in prop::collection::vec(any::<u8>(), 0..600)) {
        if let Ok(part) = Part::from_bytes(&bytes) {
            exercise(&part);
        }
        let _ = Plan::from_bytes(&bytes, false);
        let _ = Plan::from_bytes(&bytes, true);
        let _ = read_stl(&bytes, Units::Mm);
    }

    #[test]
    fn random_part_documents_never_panic(doc in part_doc()) {
        let text = serde_yaml::to_string(&doc).unwrap();
        parse_and_exercise(&text);
    }

    #[test]
    fn sample_parts_with_one_field_mutated_never_panic(
        which in any::<prop::sample::Index>(),
        picks in prop::collection::vec(any::<usize>(), 1..6),
        new in prop_oneof![value(), number(), triple()],
    ) {
        let samples = sample_parts();
        let text = &samples[which.index(samples.len())];
        let mut doc: Value = serde_yaml::from_str(text).unwrap();
        mutate(&mut doc, &picks, new);
        parse_and_exercise(&serde_yaml::to_string(&doc).unwrap());
    }

    #[test]
    fn sample_parts_with_bytes_edited_never_panic(
        which in any::<prop::sample::Index>(),
        edits in prop::collection::vec((any::<prop::sample::Index>(), any::<u8>(), 0u8..3), 1..4),
    ) {
        let samples = sample_parts();
        let mut bytes = samples[which.index(samples.len())].clone().into_bytes();
        for (at, byte, op) in edits {
            let i = at.index(bytes.len() + 1);
            match op {
                0 => bytes.insert(i, byte),
                1 if i < bytes.len() => { bytes.remove(i); }
                _ if i < bytes.len() => bytes[i] = byte,
                _ => {}
            }
        }
        if let Ok(part) = Part::from_bytes(&bytes) {
            exercise(&part);
        }
    }

    #[test]
    fn random_plans_never_panic(
        fragments in prop::collection::vec(prop::collection::vec(triple(), 0..8), 0..4),
        extra in prop::option::of((leaf(), value())),
        json in any::<bool>(),
    ) {
        let mut doc = Mapping::new();
        doc.insert("part".into(), "s3-ring".into());
        doc.insert("fragments".into(), Value::Sequence(fragments.into_iter().map(Value::Sequence).collect()));
        if let Some((k, v)) = extra {
            doc.insert(k, v);
        }
        let text = if json {
            to_json(&Value::Mapping(doc)).to_string()
        } else {
            serde_yaml::to_string(&doc).unwrap()
        };
        let part = Part::parse(&sample_parts()[2]).unwrap();
        let graph = WeldGraph::new(&part);
        if let Ok(plan) = Plan::from_bytes(text.as_bytes(), json) {
            let _ = plan.validate(&part, &graph);
        }
    }

    #[test]
    fn mutated_stl_files_never_panic(
        which in 0usize..4,
        edits in prop::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 0..4),
        pitch in prop::array::uniform3(prop_oneof![0.01f64..20.0, Just(1e-12)]),
    ) {
        let file = ["box_binary.stl", "box_ascii.stl", "tube_binary.stl", "ring_binary.stl"][which];
        let mut bytes = std::fs::read(repo("tests/data").join(file)).unwrap();
        for (at, byte) in edits {
            let i = at.index(bytes.len());
            bytes[i] = byte;
        }
        if let Ok(mesh) = read_stl(&bytes, Units::Mm) {
            let mut options = VoxelizeOptions::new("m", pitch);
            options.max_cells = 200_000;
            if let Ok(v) = voxelize(&mesh, &options) {
                exercise(&v.part);
            }
        }
    }
}

#[test]
fn pathological_yaml_is_an_error_not_a_crash() {
    let deep = format!("name: {}{}", "[".repeat(10_000), "]".repeat(10_000));
    assert!(Part::parse(&deep).is_err());
    let laughs = "a: &a [x, x, x, x, x, x, x, x, x]\nb: &b [*a, *a, *a, *a, *a, *a, *a, *a, *a]\n\
                  c: &c [*b, *b, *b, *b, *b, *b, *b, *b, *b]\nd: &d [*c, *c, *c, *c, *c, *c, *c, *c, *c]\n\
                  e: &e [*d, *d, *d, *d, *d, *d, *d, *d, *d]\nf: &f [*e, *e, *e, *e, *e, *e, *e, *e, *e]\n\
                  g: &g [*f, *f, *f, *f, *f, *f, *f, *f, *f]\nh: [*g, *g, *g, *g, *g, *g, *g, *g, *g]\n";
    assert!(Part::parse(laughs).is_err());
    assert!(Plan::from_bytes(laughs.as_bytes(), false).is_err());
    let deep_json = format!(
        "{{\"fragments\": {}{}}}",
        "[".repeat(10_000),
        "]".repeat(10_000)
    );
    assert!(Plan::from_bytes(deep_json.as_bytes(), true).is_err());
}

/// A 100 x 100 x 100 cube (10^6 blocks) written as layers: it parses, its weld graph
/// builds and a one-fragment serpentine plan validates. Timings go to the test output.
#[test]
fn a_million_block_part_parses_and_builds_its_graph() {
    let n = 100;
    let layer = format!("  - |\n{}", format!("    {}\n", "#".repeat(n)).repeat(n));
    let text = format!(
        "name: cube\nblock_mm: [6, 6, 2.5]\nmax_fragments: 1\nlayers:\n{}",
        layer.repeat(n)
    );
    let t = Instant::now();
    let part = Part::parse(&text).unwrap();
    let parsed = t.elapsed();
    assert_eq!(part.len(), n * n * n);
    let t = Instant::now();
    let graph = WeldGraph::new(&part);
    let built = t.elapsed();
    // Faces: 3 axes x 99 x 100 x 100 neighbour pairs; sideways edges both ways, up one way.
    assert_eq!(graph.edge_count(), 4 * 99 * 100 * 100 + 99 * 100 * 100);
    // Serpentine: rows alternate direction; odd layers run the same path backwards, so
    // each layer starts right above where the one below ended.
    let layer: Vec<[i64; 2]> = (0..n as i64)
        .flat_map(|y| {
            (0..n as i64).map(move |i| [if y % 2 == 0 { i } else { n as i64 - 1 - i }, y])
        })
        .collect();
    let mut path = Vec::with_capacity(n * n * n);
    for z in 0..n as i64 {
        let cells: Box<dyn Iterator<Item = &[i64; 2]>> = if z % 2 == 0 {
            Box::new(layer.iter())
        } else {
            Box::new(layer.iter().rev())
        };
        path.extend(cells.map(|&[x, y]| [x, y, z]));
    }
    let plan = Plan {
        part: None,
        fragments: vec![path],
        nodes: None,
    };
    let t = Instant::now();
    let checked = plan.validate(&part, &graph);
    let validated = t.elapsed();
    assert!(checked.is_ok(), "{:?}", checked.err());
    let t = Instant::now();
    let model = ThermalModel::new(&part, &graph);
    let modelled = t.elapsed();
    assert_eq!(model.len(), n * n * n);
    println!(
        "10^6 blocks: parse {parsed:?}, weld graph {built:?}, validate {validated:?}, thermal model {modelled:?}"
    );
}

/// Issue #18, P1: a block at the top of the i64 grid overflowed when its layers were
/// counted; issue #30: such a part lies beyond any cell and is refused when read, naming
/// the axis, before anything counts its layers.
#[test]
fn a_block_at_the_top_of_the_grid_is_refused_when_read() {
    let err = Part::parse(
        "name: z\nblock_mm: [6, 6, 2.5]\nmax_fragments: 1\nblocks: [[0,0,9223372036854775807]]\n",
    )
    .unwrap_err()
    .to_string();
    assert!(err.contains("along z"), "{err}");
}

/// Issue #18, P5/P6: time limits too long for a `Duration` are refused, naming the key.
#[test]
fn node_time_limits_beyond_a_week_are_refused_by_key() {
    use waam_ros::node::params::NodeParams;
    for (text, key) in [
        ("planner: {timeout_s: 1.0e300}\n", "planner.timeout_s"),
        (
            "execution: {enabled: true, server_timeout_s: 1.0e300}\n",
            "execution.server_timeout_s",
        ),
    ] {
        let file = format!("waam_planner:\n  ros__parameters:\n    {text}");
        let err = NodeParams::parse(&file).unwrap_err().to_string();
        assert!(err.contains(key), "{text}: {err}");
    }
}

const ROBOT_URDF: &str = include_str!("../../../urdf/waam_robot.urdf");

fn load_robot(text: &str) -> Result<waam_motion::robot::Robot, waam_motion::robot::RobotError> {
    use waam_motion::robot::{Robot, TcpChoice};
    let choice = TcpChoice {
        explicit: None,
        default: nalgebra::Isometry3::identity(),
    };
    Robot::from_urdf(text, None, choice)
}

/// Issue #18, P2: a joint origin of 1e200 m panicked inside rs-opw-kinematics ("joint 2
/// offset must be finite"); now the URDF is refused, naming the joint and the limit.
#[test]
fn a_urdf_origin_of_1e200_is_refused_by_joint() {
    let from = r#"origin xyz="0.150 0 0.4865""#;
    assert!(ROBOT_URDF.contains(from));
    for big in ["1e200", "1e308", "-5e4"] {
        let text = ROBOT_URDF.replace(from, &format!(r#"origin xyz="{big} 0 0.4865""#));
        let err = load_robot(&text).unwrap_err().to_string();
        assert!(
            err.starts_with("joint '") && err.contains("beyond 1000 m"),
            "{big}: {err}"
        );
    }
    let text = ROBOT_URDF.replace(r#"0.4865" rpy="0 0 0""#, r#"0.4865" rpy="1e300 0 0""#);
    let err = load_robot(&text).unwrap_err().to_string();
    assert!(err.contains("rpy"), "{err}");
}

/// Issue #18, C1: a URDF nested 30,000 elements deep overflowed the stack in urdf-rs;
/// now it is refused before urdf-rs parses it.
#[test]
fn a_urdf_nested_30000_deep_is_refused() {
    let deep = format!(
        "<robot name=\"r\"><link name=\"a\">{}{}</link></robot>",
        "<visual>".repeat(30_000),
        "</visual>".repeat(30_000)
    );
    let t = Instant::now();
    let err = load_robot(&deep).unwrap_err().to_string();
    assert!(err.contains("more than 64 deep"), "{err}");
    assert!(t.elapsed().as_secs_f64() < 2.0, "{:?}", t.elapsed());
}

/// Issue #18: a joint whose parent link does not exist was accepted and the chain cut.
#[test]
fn a_urdf_joint_with_a_missing_parent_link_is_refused() {
    let from = r#"<parent link="link_2"/>"#;
    assert!(ROBOT_URDF.contains(from), "the test's anchor moved");
    let text = ROBOT_URDF.replacen(from, r#"<parent link="link_two"/>"#, 1);
    let err = load_robot(&text).unwrap_err().to_string();
    assert!(
        err.contains("parent link 'link_two' is not a link of the URDF"),
        "{err}"
    );
}

const PAPER_LAYER: &str = include_str!("../../../config/layers/paper-16mm.yaml");

fn layer_error(from: &str, to: &str) -> String {
    assert!(
        PAPER_LAYER.contains(from),
        "the test's anchor moved: {from}"
    );
    let text = PAPER_LAYER.replace(from, to);
    waam_layer::Layer::parse(&text).unwrap_err().to_string()
}

/// Issue #18, P3: a speed or time step of 1e-300 overflowed the step count in
/// `Layer::check_size`; now it is refused, naming the keys to raise and the limit.
#[test]
fn a_layer_speed_or_time_step_of_1e_300_is_refused() {
    for (from, to, key) in [
        (
            "weld_speed_mm_s: 10.0",
            "weld_speed_mm_s: 1.0e-300",
            "weld_speed_mm_s",
        ),
        ("time_step_s: 0.1", "time_step_s: 1.0e-300", "time_step_s"),
        (
            "transit_speed_mm_s: 50.0",
            "transit_speed_mm_s: 1.0e-300",
            "transit_speed_mm_s",
        ),
    ] {
        let err = layer_error(from, to);
        assert!(
            err.contains(key) && err.contains("more than 20000"),
            "{to}: {err}"
        );
    }
}

/// Issue #18, W1: `peak_k_s: 1e308` made every trail's objective infinite and the search
/// printed "objective inf … PROVEN OPTIMAL" with no moves; a wall 1e-300 mm wide ended in
/// a Cholesky message. Both are refused at the input, by key.
#[test]
fn a_layer_peak_of_1e308_or_a_wall_of_1e_300_is_refused_by_key() {
    let err = layer_error("peak_k_s: 8000.0", "peak_k_s: 1.0e308");
    assert!(
        err.contains("source.peak_k_s") && err.contains("1e7"),
        "{err}"
    );
    let err = layer_error("wall_width_mm: 2.0", "wall_width_mm: 1.0e-300");
    assert!(
        err.contains("wall_width_mm") && err.contains("min 0.1"),
        "{err}"
    );
}

/// Issue #18: a YAML document nested 100,000 deep took 14–22 s to reject (18 s in the
/// node, a minute here for `{a: {a: …}}`); now every reader refuses it at once.
#[test]
fn yaml_nested_100000_deep_is_refused_within_a_second_by_every_reader() {
    let flow = format!("name: {}{}", "[".repeat(100_000), "]".repeat(100_000));
    let maps = format!("name: {}1{}", "{a: ".repeat(100_000), "}".repeat(100_000));
    for deep in [&flow, &maps] {
        let t = Instant::now();
        let part = Part::parse(deep).unwrap_err().to_string();
        assert!(part.contains("more than 128 levels deep"), "{part}");
        let plan = Plan::from_bytes(deep.as_bytes(), false).unwrap_err();
        assert!(plan.to_string().contains("more than 128"), "{plan}");
        let layer = waam_layer::Layer::parse(deep).unwrap_err().to_string();
        assert!(layer.contains("more than 128"), "{layer}");
        let settings = waam_motion::toolpath::ProcessSettings::from_yaml(deep).unwrap_err();
        assert!(settings.to_string().contains("more than 128"), "{settings}");
        let params = waam_ros::node::params::NodeParams::parse(deep).unwrap_err();
        assert!(params.to_string().contains("more than 128"), "{params}");
        assert!(t.elapsed().as_secs_f64() < 1.0, "{:?}", t.elapsed());
    }
}

/// Issue #18, C2: resolution and travel settings that would need more poses than memory
/// holds are refused by key.
#[test]
fn process_settings_that_would_exhaust_memory_are_refused_by_key() {
    use waam_motion::toolpath::ProcessSettings;
    for (text, key) in [
        ("max_step_mm: 1.0e-9\n", "max_step_mm"),
        ("max_step_deg: 1.0e-9\n", "max_step_deg"),
        ("approach_mm: 1.0e308\n", "approach_mm"),
        ("clearance_mm: 1.0e308\n", "clearance_mm"),
        ("path_tolerance_mm: 1.0e-300\n", "path_tolerance_mm"),
        ("plate: {position_m: [1.0e300, 0, 0]}\n", "plate"),
    ] {
        let err = ProcessSettings::from_yaml(text).unwrap_err().to_string();
        assert!(err.starts_with(key), "{text}: {err}");
    }
}

/// Issue #18, C2: the 81-byte two-block part with 1e308 mm blocks grew memory until
/// allocation failed in `plan --robot` / `motion`; now the motion is refused before the
/// toolpath is built, naming the limit.
#[test]
fn a_part_of_1e308_mm_blocks_is_refused_before_its_toolpath_is_built() {
    use waam_motion::robot::{Robot, TcpChoice};
    use waam_motion::toolpath::ProcessSettings;
    let part = Part::parse(
        "name: c2\nblock_mm: [1e308, 1e308, 1e308]\nmax_fragments: 1\nblocks: [[0,0,0],[1,0,0]]\n",
    );
    let Ok(part) = part else {
        // Refusing the part itself is as good.
        return;
    };
    let choice = TcpChoice {
        explicit: None,
        default: nalgebra::Isometry3::identity(),
    };
    let robot = Robot::from_urdf(ROBOT_URDF, None, choice).unwrap();
    let t = Instant::now();
    let err = waam_motion::plan_motion(&part, &[vec![0, 1]], &ProcessSettings::default(), &robot)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("max_poses") || err.contains("not a finite point"),
        "{err}"
    );
    assert!(t.elapsed().as_secs() < 2, "{:?}", t.elapsed());
}

/// Issue #18: `substeps: 1000000000` was blamed on `transit_time_s`.
#[test]
fn a_billion_substeps_is_blamed_on_substeps() {
    let err = Part::parse(
        "name: s\nblock_mm: [6, 6, 2.5]\nmax_fragments: 1\nblocks: [[0,0,0]]\n\
         thermal: {substeps: 1000000000}\n",
    )
    .unwrap_err()
    .to_string();
    assert!(err.starts_with("thermal.substeps:"), "{err}");
}
