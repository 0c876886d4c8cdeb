//! Planner test helpers: sample parts, their checks, brute-force enumeration. Shared by the
//! library crates' tests and the CLI's: each includes it (`#[path]`) in its `common` module,
//! which supplies `root()`, the repository root.

use std::path::{Path, PathBuf};
use std::process::Output;

use waam_part::graph::WeldGraph;
use waam_part::plan::Plan;
use waam_part::Part;
use waam_thermal::{self as thermal, ThermalModel};

pub use super::root;

/// A sample part bundled in config/parts.
pub fn part_path(name: &str) -> PathBuf {
    root().join("config/parts").join(format!("{name}.yaml"))
}

pub fn read_part(name: &str) -> Part {
    Part::parse(&std::fs::read_to_string(part_path(name)).unwrap()).unwrap()
}

pub fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// A new empty folder under the target dir, named after the test.
pub fn scratch(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Brute force, written independently of the planner: every valid plan of a part, by
/// trying every block in every position, checked with the plan validator.
pub fn brute_force_plans(part: &Part, k: usize) -> Vec<Vec<Vec<usize>>> {
    let graph = WeldGraph::new(part);
    let n = part.len();
    let mut out = Vec::new();
    let mut seq: Vec<Vec<usize>> = Vec::new();
    let mut used = vec![false; n];
    fn go(
        part: &Part,
        graph: &WeldGraph,
        k: usize,
        seq: &mut Vec<Vec<usize>>,
        used: &mut Vec<bool>,
        placed: usize,
        out: &mut Vec<Vec<Vec<usize>>>,
    ) {
        let n = part.len();
        if placed == n {
            let plan = Plan::from_indices(part, seq);
            if plan.validate(part, graph).is_ok() {
                out.push(seq.clone());
            }
            return;
        }
        for b in 0..n {
            if used[b] {
                continue;
            }
            // Continue the current fragment, or begin a new one.
            for new in [false, true] {
                if !new && seq.is_empty() {
                    continue;
                }
                if new && seq.len() == k {
                    continue;
                }
                if !new {
                    let last = *seq.last().unwrap().last().unwrap();
                    if !graph.has_edge(last, b) {
                        continue;
                    }
                }
                used[b] = true;
                if new {
                    seq.push(vec![b]);
                } else {
                    seq.last_mut().unwrap().push(b);
                }
                go(part, graph, k, seq, used, placed + 1, out);
                if new {
                    seq.pop();
                } else {
                    seq.last_mut().unwrap().pop();
                }
                used[b] = false;
            }
        }
    }
    go(part, &graph, k, &mut seq, &mut used, 0, &mut out);
    out
}

/// Whether a plan keeps every window (full simulation, no shortcuts).
pub fn is_feasible(part: &Part, fragments: &[Vec<usize>]) -> bool {
    let graph = WeldGraph::new(part);
    let model = ThermalModel::new(part, &graph);
    thermal::simulate(&model, fragments)
        .unwrap()
        .violation
        .is_none()
}

/// A random small part named `name`: grown block by block from [0,0,0] inside a grid of
/// `grid` blocks (x, y, z), up to `most` blocks, each new block face-adjacent to the part
/// and standing on a block (or on the substrate), so most parts have plans; k in 1..=3 and
/// fewer than `windows` random t8/5 windows.
pub fn grown_part(
    name: &'static str,
    grid: [i64; 3],
    most: usize,
    windows: usize,
) -> impl proptest::strategy::Strategy<Value = Part> {
    use proptest::prelude::*;
    (
        2usize..=most,
        proptest::collection::vec(any::<u32>(), most),
        1usize..=3,
        proptest::collection::vec((0usize..most, 0.0f64..4.0, 1.0f64..15.0), 0..windows),
    )
        .prop_map(move |(size, picks, k, windows)| {
            let inside = |b: [i64; 3]| (0..3).all(|a| (0..grid[a]).contains(&b[a]));
            let mut blocks = vec![[0i64, 0, 0]];
            for pick in picks.iter().take(size - 1) {
                let mut frontier: Vec<[i64; 3]> = Vec::new();
                for b in &blocks {
                    for d in waam_part::graph::FACE_DIRS {
                        let c = [b[0] + d[0], b[1] + d[1], b[2] + d[2]];
                        let stands = c[2] == 0 || blocks.contains(&[c[0], c[1], c[2] - 1]);
                        if inside(c) && stands && !blocks.contains(&c) && !frontier.contains(&c) {
                            frontier.push(c);
                        }
                    }
                }
                if frontier.is_empty() {
                    break;
                }
                blocks.push(frontier[*pick as usize % frontier.len()]);
            }
            let mut part = Part::from_blocks(name.into(), [6.0, 6.0, 2.5], [0.0; 3], k, blocks)
                .expect("a grown part is valid");
            for (b, lo, width) in windows {
                let b = b % part.len();
                part.set_window(
                    b,
                    waam_part::Window {
                        min_s: lo,
                        max_s: lo + width,
                    },
                );
            }
            part
        })
}
