//! Torch access through the binary: `waam plan --torch` on a part every plan of which is
//! blocked, `waam check --torch`, and the recording's torch-blocked candidates; the
//! planner library's own torch tests are `crates/planner/tests/torch.rs`.

use crate::common;

use common::planner::*;
use common::run::run_quiet;
use waam_access::{Torch, TorchSetup};
use waam_part::Part;
use waam_planner::{self as planner, Options};

/// The typical GMAW torch of the bundled process settings, at their 10° travel angle.
fn typical() -> TorchSetup {
    TorchSetup::new(Torch::default(), 10.0, 0.0)
}

fn with_torch(torch: TorchSetup) -> Options {
    Options {
        torch: Some(torch),
        ..Options::default()
    }
}

#[test]
fn a_part_whose_every_plan_is_blocked_answers_torch_cannot_reach() {
    // Two towers 8 layers tall, 6 mm apart (not neighbours: one weld path each); whichever
    // is welded second starts beside the other, which stands 17.5 mm above its first bead.
    let path = root().join("tests/data/torch-two-towers.yaml");
    let part = Part::parse(&std::fs::read_to_string(&path).unwrap()).unwrap();
    let free = planner::plan(&part, &Options::default(), &mut |_| {}).unwrap();
    assert!(free.best.is_some(), "plans exist without a torch");
    let report = planner::plan(&part, &with_torch(typical()), &mut |_| {}).unwrap();
    assert!(report.best.is_none() && report.proven);
    let path = path.to_str().unwrap();
    let run = run_quiet(&["plan", path, "--torch"]);
    assert_eq!(run.status.code(), Some(1), "{}", stderr(&run));
    let out = stdout(&run);
    assert!(
        out.starts_with("NO PLAN: torch cannot reach: every valid plan welds a block after"),
        "{out}"
    );
    assert!(
        stderr(&run).contains("torch access checked: nozzle 18 mm across"),
        "{}",
        stderr(&run)
    );
    // Without --torch the plain planner keeps no torch.
    let run = run_quiet(&["plan", path]);
    assert_eq!(run.status.code(), Some(0), "{}", stderr(&run));
}

#[test]
fn waam_check_reports_torch_access_when_asked() {
    let dir = scratch("torch-check");
    let part = part_path("ex3-h-column");
    let part = part.to_str().unwrap();
    let plan = dir.join("plan.yaml");
    let run = run_quiet(&["-q", "plan", part, "--out", dir.to_str().unwrap()]);
    assert_eq!(run.status.code(), Some(0), "{}", stderr(&run));
    let plan = plan.to_str().unwrap();
    // Without a torch: feasible, nothing said about the torch.
    let run = run_quiet(&["check", part, plan]);
    assert_eq!(run.status.code(), Some(0));
    assert!(!stdout(&run).contains("TORCH"));
    let run = run_quiet(&["check", part, plan, "--torch"]);
    assert_eq!(run.status.code(), Some(1), "{}", stdout(&run));
    let out = stdout(&run);
    assert!(out.contains("FEASIBLE\n"), "{out}");
    assert!(
        out.contains("TORCH BLOCKED: the torch cannot reach block ["),
        "{out}"
    );
    let run = run_quiet(&["check", part, plan, "--torch", "--json"]);
    let json: serde_json::Value = serde_json::from_str(&stdout(&run)).unwrap();
    assert_eq!(json["torch"]["reachable"], false);
    assert!(json["torch"]["blocked"]["block"].is_array());
    // A process file without a torch checks none; a plan the torch can weld passes.
    let off = dir.join("no-torch.yaml");
    std::fs::write(&off, "torch: null\n").unwrap();
    let run = run_quiet(&["check", part, plan, "--process", off.to_str().unwrap()]);
    assert_eq!(run.status.code(), Some(0));
    let s1 = part_path("s1-wall");
    let s1 = s1.to_str().unwrap();
    let s1dir = dir.join("s1");
    let run = run_quiet(&[
        "-q",
        "plan",
        s1,
        "--torch",
        "--out",
        s1dir.to_str().unwrap(),
    ]);
    assert_eq!(run.status.code(), Some(0), "{}", stderr(&run));
    let s1plan = s1dir.join("plan.yaml");
    let run = run_quiet(&["check", s1, s1plan.to_str().unwrap(), "--torch"]);
    assert_eq!(run.status.code(), Some(0), "{}", stdout(&run));
    assert!(stdout(&run).contains("TORCH OK: every block reachable"));
}

/// A recording of a run with the torch has one PlanCandidate per candidate, the blocked ones
/// as TORCH_BLOCKED naming the block, and the torch among the planner settings.
#[test]
fn a_recording_marks_torch_blocked_candidates() {
    use waam_rosbag::Bag;
    use waam_rosmsg::waam_interfaces::PlanCandidate;

    let dir = scratch("torch-record").join("session");
    let path = root().join("tests/data/torch-two-towers.yaml");
    let run = run_quiet(&[
        "-q",
        "plan",
        path.to_str().unwrap(),
        "--torch",
        "--json",
        "--record",
        dir.to_str().unwrap(),
    ]);
    assert_eq!(run.status.code(), Some(1), "{}", stderr(&run));
    let json: serde_json::Value = serde_json::from_str(&stdout(&run)).unwrap();
    assert_eq!(json["no_plan"]["kind"], "torch_cannot_reach", "{json}");
    let blocked = json["stats"]["torch_blocked"].as_u64().unwrap();
    assert!(blocked > 0);
    let bag = Bag::open(&dir).unwrap();
    let candidates: Vec<PlanCandidate> = bag.decode::<PlanCandidate>().unwrap();
    assert_eq!(
        candidates.len() as u64,
        json["stats"]["candidates"].as_u64().unwrap()
    );
    let torch: Vec<&PlanCandidate> = candidates
        .iter()
        .filter(|c| c.verdict == PlanCandidate::TORCH_BLOCKED)
        .collect();
    assert_eq!(torch.len() as u64, blocked);
    // The blocked block is the first of a tower welded second: at z = 0.
    assert!(
        torch.iter().all(|c| c.block.z == 0 && c.prefix_len > 8),
        "{torch:?}"
    );
}

/// `waam check --torch` of a graph part checks the torch on its beads (it was refused):
/// the sliced ring planned with the torch is TORCH OK, in text and JSON.
#[test]
fn check_torch_of_a_graph_part_is_on_its_beads() {
    use crate::common::run::{last_json, run_at_root};
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path().to_str().unwrap();
    let out = run_at_root(&[
        "plan",
        "tests/data/ring-beads.yaml",
        "--torch",
        "--first",
        "-q",
        "--out",
        d,
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let plan = dir.path().join("plan.yaml");
    let args = [
        "check",
        "tests/data/ring-beads.yaml",
        plan.to_str().unwrap(),
        "--torch",
    ];
    let out = run_at_root(&args);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{text}");
    assert!(text.contains("TORCH OK: every node reachable"), "{text}");
    let mut json_args = args.to_vec();
    json_args.push("--json");
    let out = run_at_root(&json_args);
    let v = last_json(&String::from_utf8_lossy(&out.stdout));
    assert_eq!(v["torch"]["reachable"], true, "{v}");
}
