//! A mutation fuzzer per reader, run for a bounded number of cases in the normal test
//! suite (issue #18): part files, plan files, STL meshes, layer files, process settings,
//! node parameters, URDF, bags (MCAP) and the CDR of every message a recorded bag holds.
//! (`robustness.rs` beside it adds structure-aware generators for parts, plans and STL.)
//! `scripts/test.sh` runs it once more with more cases, bounded in time. Each case takes a
//! corpus file (`tests/data/fuzz/READER/`)
//! and applies a few byte edits a fuzzer would (bit flips, boundary integers written over
//! length fields, insertions, deletions, duplicated ranges); the reader must return,
//! never panic (a panic fails the case, proptest shrinks it) or abort (the test binary
//! dies). `WAAM_FUZZ_CASES` raises the case count for a longer run. Crashes found become
//! named regression tests (in this file or next to the reader).

use std::path::{Path, PathBuf};

use proptest::prelude::*;
use waam_rosmsg::dispatch::{visit_type, TypeVisitor};
use waam_rosmsg::AnyMessage;

fn corpus(reader: &str) -> Vec<Vec<u8>> {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../tests/data/fuzz")
        .join(reader);
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| e.unwrap().path())
        .collect();
    files.sort();
    assert!(!files.is_empty(), "{}: empty corpus", dir.display());
    files.iter().map(|p| std::fs::read(p).unwrap()).collect()
}

fn cases() -> u32 {
    std::env::var("WAAM_FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(160)
}

/// One byte-level edit; positions are fractions of the current length.
#[derive(Debug, Clone)]
enum Edit {
    FlipBit(prop::sample::Index, u8),
    SetByte(prop::sample::Index, u8),
    Insert(prop::sample::Index, Vec<u8>),
    Delete(prop::sample::Index, usize),
    Duplicate(prop::sample::Index, usize),
    /// A boundary value written over 4 or 8 bytes (length fields, counts).
    Boundary(prop::sample::Index, u64, bool),
}

fn edit() -> impl Strategy<Value = Edit> {
    let boundary = prop::sample::select(vec![
        0u64,
        1,
        0x7f,
        0xff,
        0xffff,
        0x7fff_ffff,
        0xffff_ffff,
        0x1_0000_0000,
        i64::MAX as u64,
        u64::MAX,
        1 << 40,
    ]);
    prop_oneof![
        3 => (any::<prop::sample::Index>(), 0u8..8).prop_map(|(i, b)| Edit::FlipBit(i, b)),
        2 => (any::<prop::sample::Index>(), any::<u8>()).prop_map(|(i, b)| Edit::SetByte(i, b)),
        1 => (any::<prop::sample::Index>(), prop::collection::vec(any::<u8>(), 1..16))
            .prop_map(|(i, v)| Edit::Insert(i, v)),
        1 => (any::<prop::sample::Index>(), 1usize..64).prop_map(|(i, n)| Edit::Delete(i, n)),
        1 => (any::<prop::sample::Index>(), 1usize..256).prop_map(|(i, n)| Edit::Duplicate(i, n)),
        2 => (any::<prop::sample::Index>(), boundary, any::<bool>())
            .prop_map(|(i, v, wide)| Edit::Boundary(i, v, wide)),
    ]
}

fn apply(bytes: &mut Vec<u8>, edits: &[Edit]) {
    for e in edits {
        let n = bytes.len();
        match e {
            Edit::FlipBit(i, b) if n > 0 => bytes[i.index(n)] ^= 1 << b,
            Edit::SetByte(i, v) if n > 0 => bytes[i.index(n)] = *v,
            Edit::Insert(i, v) => {
                let at = i.index(n + 1);
                bytes.splice(at..at, v.iter().copied());
            }
            Edit::Delete(i, len) if n > 0 => {
                let at = i.index(n);
                bytes.drain(at..(at + len).min(n));
            }
            Edit::Duplicate(i, len) if n > 0 => {
                let at = i.index(n);
                let range: Vec<u8> = bytes[at..(at + len).min(n)].to_vec();
                bytes.splice(at..at, range);
            }
            Edit::Boundary(i, v, wide) => {
                let le = v.to_le_bytes();
                let width = if *wide { 8 } else { 4 };
                if n >= width {
                    let at = i.index(n - width + 1);
                    bytes[at..at + width].copy_from_slice(&le[..width]);
                }
            }
            _ => {}
        }
    }
}

/// A corpus entry with a few edits applied.
fn mutated(reader: &'static str) -> impl Strategy<Value = Vec<u8>> {
    let files = corpus(reader);
    (0..files.len(), prop::collection::vec(edit(), 1..6)).prop_map(move |(which, edits)| {
        let mut bytes = files[which].clone();
        apply(&mut bytes, &edits);
        bytes
    })
}

fn config() -> ProptestConfig {
    ProptestConfig {
        failure_persistence: None,
        ..ProptestConfig::with_cases(cases())
    }
}

/// Decodes CDR as the message type named at run time.
struct Decode<'a>(&'a [u8]);

impl TypeVisitor for Decode<'_> {
    type Output = bool;
    fn visit<M: AnyMessage>(self) -> bool {
        waam_rosmsg::from_cdr::<M>(self.0).is_ok()
    }
}

/// The corpus bag's messages: (type name, CDR).
fn recorded_cdr() -> Vec<(String, Vec<u8>)> {
    let bytes = &corpus("bag")[0];
    let bag = waam_rosbag::Bag::from_bytes(Path::new("sample.mcap"), bytes).unwrap();
    bag.messages
        .iter()
        .map(|m| (bag.topic_of(m).type_name.clone(), m.data.clone()))
        .collect()
}

/// What parses is pushed on (weld graph, and for small parts the thermal simulation of a
/// layer-by-layer order), as `waam plan` and `waam check` would.
fn exercise_part(part: &waam_part::Part) {
    let graph = waam_part::graph::WeldGraph::new(part);
    if part.len() <= 200 {
        let model = waam_thermal::ThermalModel::new(part, &graph);
        let order: Vec<usize> = (0..part.len()).collect();
        let deadline = std::time::Instant::now() + std::time::Duration::from_millis(200);
        let _ = waam_thermal::simulate_until(&model, &[order], Some(deadline), None);
    }
}

#[test]
fn the_corpus_reads_cleanly() {
    for bytes in corpus("part") {
        exercise_part(&waam_part::Part::from_bytes(&bytes).unwrap());
    }
    for bytes in corpus("plan") {
        waam_part::plan::Plan::from_bytes(&bytes, false).unwrap();
    }
    for bytes in corpus("stl") {
        waam_mesh::read_stl(&bytes, waam_mesh::Units::Mm).unwrap();
    }
    for bytes in corpus("layer") {
        waam_layer::Layer::from_bytes(&bytes).unwrap();
    }
    for bytes in corpus("process") {
        waam_motion::toolpath::ProcessSettings::from_yaml(std::str::from_utf8(&bytes).unwrap())
            .unwrap();
    }
    for bytes in corpus("params") {
        waam_ros::node::params::NodeParams::parse(std::str::from_utf8(&bytes).unwrap()).unwrap();
    }
    for bytes in corpus("urdf") {
        urdf(&bytes).unwrap();
    }
    let cdr = recorded_cdr();
    assert!(cdr.len() > 10);
    for (type_name, data) in &cdr {
        assert_eq!(
            visit_type(type_name, Decode(data)),
            Some(true),
            "{type_name}"
        );
    }
}

/// Why fuzzed bytes are no robot.
#[derive(Debug, thiserror::Error)]
enum UrdfInputError {
    #[error(transparent)]
    Utf8(#[from] std::str::Utf8Error),
    #[error(transparent)]
    Robot(#[from] waam_motion::robot::RobotError),
}

fn urdf(bytes: &[u8]) -> Result<waam_motion::robot::Robot, UrdfInputError> {
    use waam_motion::robot::{Robot, TcpChoice};
    let text = std::str::from_utf8(bytes)?;
    let choice = TcpChoice {
        explicit: None,
        default: nalgebra::Isometry3::identity(),
    };
    Ok(Robot::from_urdf(text, None, choice)?)
}

proptest! {
    #![proptest_config(config())]

    #[test]
    fn part_files(bytes in mutated("part")) {
        if let Ok(part) = waam_part::Part::from_bytes(&bytes) {
            exercise_part(&part);
        }
    }

    #[test]
    fn plan_files(bytes in mutated("plan"), json in any::<bool>()) {
        if let Ok(plan) = waam_part::plan::Plan::from_bytes(&bytes, json) {
            // Validated against the corpus part it may belong to.
            for text in corpus("part") {
                let part = waam_part::Part::from_bytes(&text).unwrap();
                let graph = waam_part::graph::WeldGraph::new(&part);
                let _ = plan.validate(&part, &graph);
            }
        }
    }

    #[test]
    fn stl_meshes(bytes in mutated("stl")) {
        if let Ok(mesh) = waam_mesh::read_stl(&bytes, waam_mesh::Units::Mm) {
            let mut options = waam_mesh::VoxelizeOptions::new("fuzz", [2.0, 2.0, 2.0]);
            options.max_cells = 100_000;
            let _ = waam_mesh::voxelize(&mesh, &options);
        }
    }

    #[test]
    fn layer_files(bytes in mutated("layer")) {
        let _ = waam_layer::Layer::from_bytes(&bytes);
    }

    #[test]
    fn process_settings(bytes in mutated("process")) {
        if let Ok(text) = std::str::from_utf8(&bytes) {
            let _ = waam_motion::toolpath::ProcessSettings::from_yaml(text);
        }
    }

    #[test]
    fn node_parameters(bytes in mutated("params")) {
        if let Ok(text) = std::str::from_utf8(&bytes) {
            let _ = waam_ros::node::params::NodeParams::parse(text);
        }
    }

    #[test]
    fn urdf_files(bytes in mutated("urdf")) {
        let _ = urdf(&bytes);
    }

    #[test]
    fn bags(bytes in mutated("bag")) {
        let _ = waam_rosbag::Bag::from_bytes(Path::new("fuzz.mcap"), &bytes);
    }

    #[test]
    fn cdr_messages(
        which in any::<prop::sample::Index>(),
        edits in prop::collection::vec(edit(), 1..5),
        as_other in any::<Option<prop::sample::Index>>(),
    ) {
        let recorded = recorded_cdr();
        let (type_name, data) = &recorded[which.index(recorded.len())];
        let mut bytes = data.clone();
        apply(&mut bytes, &edits);
        // Also decode the bytes as another recorded type: a wrong type must be an error.
        let type_name = as_other.map_or(type_name, |i| &recorded[i.index(recorded.len())].0);
        visit_type(type_name, Decode(&bytes));
    }
}
