//! The SAT planner through the `waam` binary (plans written pass `waam check`, counts as
//! JSON, the no-plan answers and the timeout) and inside the node's worker; the planner
//! library's own tests are `crates/planner/tests/planner.rs`.

use crate::common;

use common::planner::*;
use common::run::run_quiet;
use std::time::{Duration, Instant};

#[test]
fn every_plan_written_passes_waam_check() {
    for name in [
        "s1-wall",
        "s3-ring",
        "s5-ledge",
        "s7-pad",
        "ex1-plate-boss",
        "ex3-h-column",
    ] {
        let dir = scratch(&format!("plan-check-{name}"));
        let part = part_path(name);
        let out = run_quiet(&[
            "-q",
            "plan",
            part.to_str().unwrap(),
            "--out",
            dir.to_str().unwrap(),
        ]);
        assert_eq!(out.status.code(), Some(0), "{name}: {}", stderr(&out));
        let plan = dir.join("plan.yaml");
        let check = run_quiet(&["check", part.to_str().unwrap(), plan.to_str().unwrap()]);
        assert_eq!(check.status.code(), Some(0), "{name}: {}", stdout(&check));
        assert!(stdout(&check).contains("VALID") && stdout(&check).contains("FEASIBLE"));
    }
}

#[test]
fn enumerated_plans_are_all_feasible_and_distinct() {
    // On 3 worker threads: every plan written passes the plan checks.
    for (name, feasible) in [("s1-wall", 21), ("s3-ring", 827)] {
        let dir = scratch(&format!("all-{name}"));
        let part = part_path(name);
        let out = run_quiet(&[
            "-q",
            "plan",
            part.to_str().unwrap(),
            "--all",
            "--threads",
            "3",
            "--out",
            dir.to_str().unwrap(),
        ]);
        assert_eq!(out.status.code(), Some(0), "{name}: {}", stderr(&out));
        let text = std::fs::read_to_string(dir.join("feasible-plans.yaml")).unwrap();
        let docs: Vec<&str> = text
            .split("---\n")
            .filter(|d| !d.trim().is_empty())
            .collect();
        assert_eq!(docs.len(), feasible, "{name}");
        let p = read_part(name);
        let g = waam_part::graph::WeldGraph::new(&p);
        let mut seen = std::collections::HashSet::new();
        for d in docs {
            let plan = waam_part::plan::Plan::from_bytes(d.as_bytes(), false).unwrap();
            let idx = plan.validate(&p, &g).unwrap();
            assert!(is_feasible(&p, &idx), "{name}: {idx:?}");
            assert!(seen.insert(idx), "{name}: a plan written twice");
        }
    }
}

#[test]
fn count_json_has_plans_and_feasible() {
    let part = part_path("s2-corner");
    let out = run_quiet(&["plan", part.to_str().unwrap(), "--count", "--json"]);
    assert_eq!(out.status.code(), Some(0));
    let v: serde_json::Value = serde_json::from_str(&stdout(&out)).unwrap();
    assert_eq!(v["plans"], 122);
    assert_eq!(v["feasible"], 23);
}

/// A part no SAT solver plans quickly: one layer of `side` x `side` blocks without two
/// opposite corners, in one weld path. A path alternates the two colours of the
/// checkerboard, and two same-coloured blocks are missing, so there is no plan; proving it
/// is a counting argument, which resolution (CDCL) cannot do in short.
fn parity_part(side: usize) -> std::path::PathBuf {
    let mut text = format!(
        "name: parity-{side}\nblock_mm: [6.0, 6.0, 2.5]\nmax_fragments: 1\nlayers:\n  - |\n"
    );
    for y in 0..side {
        let row: String = (0..side)
            .map(|x| {
                let corner = (x == 0 && y == 0) || (x == side - 1 && y == side - 1);
                if corner {
                    '.'
                } else {
                    '#'
                }
            })
            .collect();
        text.push_str(&format!("    {row}\n"));
    }
    let path = scratch(&format!("parity-{side}")).join("part.yaml");
    std::fs::write(&path, text).unwrap();
    path
}

/// A ring tower whose one window no plan keeps (tests/data/endless-ring.yaml): the planner
/// runs until it is stopped.
fn hard_part() -> std::path::PathBuf {
    root().join("tests/data/endless-ring.yaml")
}

#[test]
fn a_checkerboard_surplus_is_no_valid_plan_at_once() {
    // Two same-colour corners missing: no single path covers the layer (a counting
    // argument CDCL cannot make in short), but the layer bound says so at once.
    let t = Instant::now();
    let out = run_quiet(&["plan", parity_part(20).to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
    assert!(
        stdout(&out).contains("alone needs 2 weld paths") && stdout(&out).contains("checkerboard"),
        "{}",
        stdout(&out)
    );
    assert!(
        t.elapsed() < Duration::from_secs(5),
        "took {:?}",
        t.elapsed()
    );
}

#[test]
fn a_timeout_holds_inside_one_long_solve() {
    let part = hard_part();
    let t = Instant::now();
    let out = run_quiet(&[
        "plan",
        part.to_str().unwrap(),
        "--solver",
        "cadical",
        "--timeout",
        "5",
    ]);
    let took = t.elapsed();
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
    assert!(
        stdout(&out).contains("none found before the timeout"),
        "{}",
        stdout(&out)
    );
    assert!(took < Duration::from_secs(6), "took {took:?}");
}

/// Issue #12: the node's "latest part wins" — a newer part cancels the plan in progress, and
/// the superseded job (the real node pipeline and SAT planner) ends within a second.
#[test]
fn a_newer_part_cancels_the_running_plan_within_a_second() {
    use std::sync::mpsc::channel;
    use waam_ros::node::params::NodeParams;
    use waam_ros::node::pipeline::{sat_planner, Job, PlanningPipeline};
    use waam_ros::node::worker::{JobFailure, Worker, WorkerEvent};
    let pipeline = PlanningPipeline::from_params(&NodeParams::default(), sat_planner()).unwrap();
    let (tx, rx) = channel();
    let mut worker = Worker::new(pipeline, move |event| {
        let _ = tx.send((Instant::now(), event));
    });
    let document = waam_pipeline::PartInput::Document;
    let (first, _) = worker.submit(Job::from(document(
        std::fs::read_to_string(hard_part()).unwrap(),
    )));
    // Let it get deep into planning (candidates examined), then send a newer part.
    let started = Instant::now();
    while started.elapsed() < Duration::from_secs(3) {
        if let Ok((_, WorkerEvent::Finished { job, result })) =
            rx.recv_timeout(Duration::from_millis(50))
        {
            panic!(
                "part {job} ended before it was superseded: {:?}",
                result.err()
            );
        }
    }
    let small = std::fs::read_to_string(part_path("s1-wall")).unwrap();
    let superseded_at = Instant::now();
    let (second, cancelled) = worker.submit(Job::from(document(small)));
    assert_eq!(cancelled, Some(first));
    let mut ended = std::collections::HashMap::new();
    while ended.len() < 2 {
        let (at, event) = rx
            .recv_timeout(Duration::from_secs(60))
            .expect("both jobs end");
        if let WorkerEvent::Finished { job, result } = event {
            ended.insert(job, (at, result));
        }
    }
    let (at, result) = &ended[&first];
    assert!(
        matches!(result, Err(JobFailure::Superseded)),
        "{:?}",
        result.as_ref().err()
    );
    let took = at.duration_since(superseded_at);
    eprintln!("the superseded plan ended {took:?} after the newer part");
    assert!(
        took < Duration::from_secs(1),
        "the superseded plan ran on for {took:?}"
    );
    assert!(
        ended[&second].1.is_ok(),
        "{:?}",
        ended[&second].1.as_ref().err()
    );
}

/// `-k` replaces a part file's max_fragments, for a cube part and a graph part alike (it
/// was a mesh's k only): s1-wall needs two weld paths, so `-k 1` leaves it none; a graph
/// part written with k = 1 is planned, written and checked with the k of `-k`.
#[test]
fn k_overrides_the_max_fragments_of_a_part_file() {
    use common::run::{last_json, run_at_root};
    let json = |out: std::process::Output| last_json(&String::from_utf8(out.stdout).unwrap());
    let s1 = json(run_at_root(&[
        "plan",
        "config/parts/s1-wall.yaml",
        "-q",
        "--json",
    ]));
    assert_eq!(s1["found"], true);
    assert_eq!(s1["plan"]["fragments"].as_array().unwrap().len(), 2);
    let k1 = json(run_at_root(&[
        "plan",
        "config/parts/s1-wall.yaml",
        "-k",
        "1",
        "-q",
        "--json",
    ]));
    assert_eq!(k1["found"], false, "{k1}");

    let dir = tempfile::tempdir().unwrap();
    let part = dir.path().join("ring.yaml");
    let out = run_at_root(&[
        "slice",
        "tests/data/ring_binary.stl",
        "--bead",
        "6 2.5",
        "-k",
        "1",
        "--out",
        part.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = std::fs::read_to_string(&part).unwrap();
    assert!(text.contains("max_fragments: 1\n"));
    let planned = dir.path().join("planned");
    let out = run_at_root(&[
        "plan",
        part.to_str().unwrap(),
        "-k",
        "3",
        "--first",
        "-q",
        "--json",
        "--out",
        planned.to_str().unwrap(),
    ]);
    let plan = json(out);
    assert_eq!(plan["found"], true, "{plan}");
    // The plan names node ids (not stand-in blocks), and the part beside it has k = 3.
    let mut fragments: Vec<Vec<u64>> = plan["plan"]["fragments"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| {
            f.as_array()
                .unwrap()
                .iter()
                .map(|v| v.as_u64().unwrap())
                .collect()
        })
        .collect();
    let nodes: usize = fragments.iter().map(Vec::len).sum();
    assert!(text.matches("{bead:").count() == nodes, "one id per node");
    let written = std::fs::read_to_string(planned.join("part.yaml")).unwrap();
    assert!(written.contains("max_fragments: 3\n"), "{written}");
    // A plan of two weld paths or more (one path split after its first node): invalid
    // with the file's k = 1, valid with -k as large.
    if fragments.len() == 1 {
        let rest = fragments[0].split_off(1);
        fragments.push(rest);
    }
    let k = fragments.len().to_string();
    let lines: Vec<String> = fragments
        .iter()
        .map(|f| {
            let ids: Vec<String> = f.iter().map(u64::to_string).collect();
            format!("  - [{}]\n", ids.join(", "))
        })
        .collect();
    let split = dir.path().join("split.yaml");
    std::fs::write(&split, format!("fragments:\n{}", lines.concat())).unwrap();
    let check = |extra: &[&str]| {
        let mut args = vec!["check", part.to_str().unwrap(), split.to_str().unwrap()];
        args.extend_from_slice(extra);
        String::from_utf8(run_at_root(&args).stdout).unwrap()
    };
    assert!(check(&[]).starts_with("INVALID"), "{}", check(&[]));
    assert!(
        check(&["-k", &k]).starts_with("VALID"),
        "{}",
        check(&["-k", &k])
    );
}
