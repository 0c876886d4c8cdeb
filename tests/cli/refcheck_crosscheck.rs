//! `waam check --json` against the independent checker (shared/tools/refcheck).
//!
//! Runs only when `WAAM_REFCHECK_PY` names a python that has refcheck's requirements
//! (`export WAAM_REFCHECK_PY="$(scripts/refcheck.sh)"`); the checker's folder is
//! `WAAM_REFCHECK_DIR` or `../shared/tools/refcheck`. Otherwise it says it skipped.
//!
//! For every part of `config/parts/` it generates plans of each kind with a fixed seed —
//! random valid plans (a random depth-first search over the weld graph that keeps the
//! rules), feasible and infeasible where both exist, and invalid plans breaking each of
//! the four rules — and demands the same verdicts, the same invalidity message, the same
//! first violation (block, kind, step, time, prefix) and every t8/5 crossing to 1e-6 s.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use serde_json::{json, Value};
use waam_part::graph::WeldGraph;
use waam_part::plan::Plan;
use waam_part::{Block, Part};
use waam_thermal::{simulate, ThermalModel};

/// SplitMix64: a fixed-seed generator, so that every run checks the same plans.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }

    fn shuffle<T>(&mut self, v: &mut [T]) {
        for i in (1..v.len()).rev() {
            v.swap(i, self.below(i + 1));
        }
    }
}

const NO: usize = usize::MAX;

/// A random plan with at most `k` fragments that keeps rules 1-3, and rule 4 too when
/// `gravity`. A fragment never moves down, so it is one run of sideways moves per layer,
/// joined by up moves: the search builds all fragments together, layer by layer
/// (depth-first with backtracking), and orders them at the end so that no fragment comes
/// before the one that welded a block under it.
struct Search<'a> {
    part: &'a Part,
    graph: &'a WeldGraph,
    k: usize,
    gravity: bool,
    layers: Vec<Vec<usize>>,
    fragment_of: Vec<usize>,
    fragments: Vec<Vec<usize>>,
    /// before[a][b]: fragment a must be welded before fragment b (transitively closed).
    before: Vec<Vec<bool>>,
    budget: u64,
}

impl Search<'_> {
    fn run(
        part: &Part,
        graph: &WeldGraph,
        k: usize,
        gravity: bool,
        rng: &mut Rng,
    ) -> Option<Vec<Vec<usize>>> {
        let mut layers = vec![Vec::new(); part.layers() as usize];
        for i in 0..part.len() {
            layers[part.block(i)[2] as usize].push(i);
        }
        let mut s = Search {
            part,
            graph,
            k,
            gravity,
            layers,
            fragment_of: vec![NO; part.len()],
            fragments: Vec::new(),
            before: vec![vec![false; k]; k],
            budget: 20_000,
        };
        if !s.layer(0, Vec::new(), rng) {
            return None;
        }
        // A random order of the fragments that keeps `before` (any order without gravity).
        let mut left: Vec<usize> = (0..s.fragments.len()).collect();
        let mut order = Vec::new();
        while !left.is_empty() {
            let ready: Vec<usize> = (0..left.len())
                .filter(|&i| !left.iter().any(|&a| s.gravity && s.before[a][left[i]]))
                .collect();
            let pick = ready[rng.below(ready.len())];
            order.push(left.remove(pick));
        }
        Some(order.into_iter().map(|f| s.fragments[f].clone()).collect())
    }

    fn sideways(&self, b: usize) -> Vec<usize> {
        let z = self.part.block(b)[2];
        self.graph
            .successors(b)
            .iter()
            .map(|&s| s as usize)
            .filter(|&s| self.part.block(s)[2] == z && self.fragment_of[s] == NO)
            .collect()
    }

    /// Welds `b` into fragment `f` unless gravity forbids it; returns the undo state.
    fn place(&mut self, b: usize, f: usize) -> Option<Vec<Vec<bool>>> {
        let saved = self.before.clone();
        if let Some(j) = self.graph.below(b) {
            let g = self.fragment_of[j];
            if g != f {
                if self.gravity && self.before[f][g] {
                    return None;
                }
                // g before f, and everything before g before everything after f.
                for a in 0..self.k {
                    for c in 0..self.k {
                        if (a == g || self.before[a][g]) && (c == f || self.before[f][c]) {
                            self.before[a][c] = true;
                        }
                    }
                }
            }
        }
        self.fragment_of[b] = f;
        self.fragments[f].push(b);
        Some(saved)
    }

    fn unplace(&mut self, b: usize, f: usize, saved: Vec<Vec<bool>>) {
        self.fragment_of[b] = NO;
        self.fragments[f].pop();
        self.before = saved;
    }

    /// Layer `z`: each fragment of `open` (it ran in layer z - 1) may go on up.
    fn layer(&mut self, z: usize, open: Vec<usize>, rng: &mut Rng) -> bool {
        if z == self.layers.len() {
            return true;
        }
        let can_go_on: Vec<usize> = open
            .into_iter()
            .filter(|&f| {
                let last = *self.fragments[f].last().expect("ran");
                self.graph.above(last).is_some()
            })
            .collect();
        // Subsets of the fragments that go on, most of them first, in random order.
        let mut subsets: Vec<(usize, u64, u32)> = (0..1u32 << can_go_on.len())
            .map(|m| (m.count_ones() as usize, rng.next(), m))
            .collect();
        subsets.sort_by_key(|&(ones, r, _)| (std::cmp::Reverse(ones * (r % 4 != 0) as usize), r));
        for (_, _, mask) in subsets {
            let going: Vec<usize> = (0..can_go_on.len())
                .filter(|i| mask & (1 << i) != 0)
                .map(|i| can_go_on[i])
                .collect();
            if self.runs(z, &going, Vec::new(), rng) {
                return true;
            }
            if self.budget == 0 {
                return false;
            }
        }
        false
    }

    /// Covers layer `z` with runs: first those of `going` (each starts above its last
    /// block), then new fragments; `ran` collects the fragments that ran in this layer.
    fn runs(&mut self, z: usize, going: &[usize], ran: Vec<usize>, rng: &mut Rng) -> bool {
        if self.budget == 0 {
            return false;
        }
        self.budget -= 1;
        if let Some((&f, rest)) = going.split_first() {
            let last = *self.fragments[f].last().expect("ran");
            let b = self.graph.above(last).expect("checked");
            // An earlier run of this layer may have taken it.
            if self.fragment_of[b] != NO {
                return false;
            }
            let Some(saved) = self.place(b, f) else {
                return false;
            };
            let mut ran2 = ran.clone();
            ran2.push(f);
            if self.run_on(z, b, f, rest, ran2, rng) {
                return true;
            }
            self.unplace(b, f, saved);
            return false;
        }
        let uncovered: Vec<usize> = self.layers[z]
            .iter()
            .copied()
            .filter(|&b| self.fragment_of[b] == NO)
            .collect();
        if uncovered.is_empty() {
            return self.layer(z + 1, ran, rng);
        }
        if self.fragments.len() == self.k
            || self.regions(&uncovered) > self.k - self.fragments.len()
        {
            return false;
        }
        let mut starts = uncovered;
        rng.shuffle(&mut starts);
        // Ends of the layer's paths make the best starts: try blocks with few free neighbours first.
        starts.sort_by_key(|&b| self.sideways(b).len());
        let f = self.fragments.len();
        self.fragments.push(Vec::new());
        for b in starts.into_iter().take(4) {
            let Some(saved) = self.place(b, f) else {
                continue;
            };
            let mut ran2 = ran.clone();
            ran2.push(f);
            if self.run_on(z, b, f, &[], ran2, rng) {
                return true;
            }
            self.unplace(b, f, saved);
            if self.budget == 0 {
                break;
            }
        }
        self.fragments.pop();
        false
    }

    /// Fragment `f` is at `b` in layer `z`: go on sideways, or end its run here.
    fn run_on(
        &mut self,
        z: usize,
        b: usize,
        f: usize,
        going: &[usize],
        ran: Vec<usize>,
        rng: &mut Rng,
    ) -> bool {
        let mut next = self.sideways(b);
        rng.shuffle(&mut next);
        let stop_first = next.is_empty() || rng.below(8) == 0;
        if stop_first && self.runs(z, going, ran.clone(), rng) {
            return true;
        }
        for c in next {
            if self.budget == 0 {
                return false;
            }
            let Some(saved) = self.place(c, f) else {
                continue;
            };
            if self.run_on(z, c, f, going, ran.clone(), rng) {
                return true;
            }
            self.unplace(c, f, saved);
        }
        !stop_first && self.budget > 0 && self.runs(z, going, ran, rng)
    }

    /// Connected regions of `blocks` within their layer: each needs a run of its own.
    fn regions(&self, blocks: &[usize]) -> usize {
        let mut seen = vec![false; self.part.len()];
        let mut count = 0;
        for &b in blocks {
            if seen[b] {
                continue;
            }
            count += 1;
            let mut stack = vec![b];
            seen[b] = true;
            while let Some(v) = stack.pop() {
                for w in self.sideways(v) {
                    if !seen[w] {
                        seen[w] = true;
                        stack.push(w);
                    }
                }
            }
        }
        count
    }
}

struct Case {
    id: String,
    part: PathBuf,
    plan: PathBuf,
    /// What the plan was made to be.
    kind: String,
}

fn coords(part: &Part, fragments: &[Vec<usize>]) -> Vec<Vec<Block>> {
    fragments
        .iter()
        .map(|f| f.iter().map(|&i| part.block(i)).collect())
        .collect()
}

/// Our own verdict: Ok(feasible) for a valid plan, Err(rule) for an invalid one.
fn verdict(part: &Part, graph: &WeldGraph, fragments: &[Vec<Block>]) -> Result<bool, u8> {
    let plan = Plan {
        part: None,
        fragments: fragments.to_vec(),
        nodes: None,
    };
    let indexed = plan.validate(part, graph).map_err(|e| e.rule())?;
    let model = ThermalModel::new(part, graph);
    Ok(simulate(&model, &indexed).is_ok_and(|o| o.violation.is_none()))
}

/// Plans of every kind for one part.
fn plans_for(part: &Part, rng: &mut Rng) -> Vec<(String, Vec<Vec<Block>>)> {
    let graph = WeldGraph::new(part);
    let k = part.max_fragments;
    let mut out: Vec<(String, Vec<Vec<Block>>)> = Vec::new();
    let (mut feasible, mut infeasible) = (0, 0);
    let mut base: Option<Vec<Vec<Block>>> = None;
    for _ in 0..400 {
        if feasible >= 4 && infeasible >= 4 {
            break;
        }
        let Some(found) = Search::run(part, &graph, k, true, rng) else {
            continue;
        };
        let plan = coords(part, &found);
        match verdict(part, &graph, &plan) {
            Ok(true) if feasible < 4 => feasible += 1,
            Ok(false) if infeasible < 4 => infeasible += 1,
            Ok(_) => continue,
            Err(rule) => panic!("the search made an invalid plan (rule {rule})"),
        }
        out.push((
            if verdict(part, &graph, &plan) == Ok(true) {
                "feasible"
            } else {
                "infeasible"
            }
            .into(),
            plan.clone(),
        ));
        base.get_or_insert(plan);
    }
    // No valid plan (k too small): start the broken ones from a plan with more fragments.
    let base = match base {
        Some(b) => b,
        None => match (k + 1..k + 4).find_map(|kk| Search::run(part, &graph, kk, true, rng)) {
            Some(f) => coords(part, &f),
            None => return out,
        },
    };
    let mut broken = |name: &str, plan: Vec<Vec<Block>>| out.push((name.to_string(), plan));
    let far = [
        part.blocks().iter().map(|b| b[0]).max().unwrap_or(0) + 1,
        0,
        0,
    ];
    let mut p = base.clone();
    p.last_mut().unwrap().push(far);
    broken("rule1-unknown", p);
    let mut p = base.clone();
    p.last_mut().unwrap().push(base[0][0]);
    broken("rule1-repeated", p);
    let mut p = base.clone();
    p.last_mut().unwrap().pop();
    broken("rule1-missing", p);
    // Rule 2: one fragment too many (split a long fragment), and an empty fragment.
    let mut p = base.clone();
    while p.len() <= k {
        let Some(f) = p.iter().position(|f| f.len() >= 2) else {
            break;
        };
        let cut = 1 + rng.below(p[f].len() - 1);
        let tail = p[f].split_off(cut);
        p.insert(f + 1, tail);
    }
    broken("rule2-count", p);
    let mut p = base.clone();
    p.push(Vec::new());
    broken("rule2-empty", p);
    // Rule 3: swap two blocks of a fragment, or run a fragment backwards.
    if let Some(f) = base.iter().position(|f| f.len() >= 3) {
        let mut p = base.clone();
        let n = p[f].len();
        p[f].swap(0, n - 1);
        broken("rule3-swap", p);
        let mut p = base.clone();
        p[f].reverse();
        broken("rule3-reversed", p);
    }
    // Rule 4: a search that ignores gravity, kept when gravity is what it breaks.
    let mut found = 0;
    for _ in 0..40 {
        if found == 2 {
            break;
        }
        if let Some(f) = Search::run(part, &graph, k, false, rng) {
            let p = coords(part, &f);
            if verdict(part, &graph, &p) == Err(4) {
                broken("rule4-gravity", p);
                found += 1;
            }
        }
    }
    out
}

fn waam_check(part: &Path, plan: &Path) -> (Option<i32>, Value) {
    let out = crate::common::run::waam()
        .args(["-q", "check", "--json"])
        .arg(part)
        .arg(plan)
        .output()
        .expect("waam runs");
    let text = String::from_utf8_lossy(&out.stdout);
    let value = serde_json::from_str(text.trim()).unwrap_or_else(
        |_| json!({"error": String::from_utf8_lossy(&out.stderr).trim().to_string()}),
    );
    (out.status.code(), value)
}

/// Drops the spaces inside brackets: refcheck writes `[1, 0, 2]`, we write `[1,0,2]`.
fn squeeze(message: &str) -> String {
    let mut depth = 0;
    message
        .chars()
        .filter(|&c| {
            match c {
                '[' => depth += 1,
                ']' => depth -= 1,
                ' ' if depth > 0 => return false,
                _ => {}
            }
            true
        })
        .collect()
}

fn close(a: &Value, b: &Value, tol: f64) -> bool {
    matches!((a.as_f64(), b.as_f64()), (Some(x), Some(y)) if (x - y).abs() <= tol)
}

/// Every difference between our answer and refcheck's for one case.
fn compare(ours: &Value, code: Option<i32>, theirs: &Value) -> Vec<String> {
    let mut diffs = Vec::new();
    let mut differ = |what: &str, a: &Value, b: &Value| {
        diffs.push(format!("{what}: waam {a}, refcheck {b}"));
    };
    if !theirs["error"].is_null() || ours.get("error").is_some() {
        if theirs["error"].is_null() || ours.get("error").is_none() {
            differ("error", &ours["error"], &theirs["error"]);
        }
        return diffs;
    }
    if ours["valid"] != theirs["valid"] {
        differ("valid", &ours["valid"], &theirs["valid"]);
        return diffs;
    }
    if ours["valid"] == false {
        let a = squeeze(ours["invalid"]["message"].as_str().unwrap_or(""));
        let b = squeeze(theirs["invalid"].as_str().unwrap_or(""));
        if a != b {
            differ("invalid message", &json!(a), &json!(b));
        }
        if code != Some(1) {
            differ("exit code", &json!(code), &json!(1));
        }
        return diffs;
    }
    if ours["feasible"] != theirs["feasible"] {
        differ("feasible", &ours["feasible"], &theirs["feasible"]);
    }
    let expected_code = if theirs["feasible"] == true { 0 } else { 1 };
    if code != Some(expected_code) {
        differ("exit code", &json!(code), &json!(expected_code));
    }
    let (v, w) = (&ours["violation"], &theirs["violation"]);
    if v.is_null() != w.is_null() {
        differ("violation", v, w);
    } else if !v.is_null() {
        for key in [
            "block",
            "kind",
            "step",
            "prefix_len",
            "prefix_fragments",
            "phase",
        ] {
            if v[key] != w[key] {
                differ(&format!("violation.{key}"), &v[key], &w[key]);
            }
        }
        for key in ["time_s", "t85_s"] {
            if !close(&v[key], &w[key], 1e-6) {
                differ(&format!("violation.{key}"), &v[key], &w[key]);
            }
        }
    }
    // Our crossings come in time order; gather them per block like refcheck's.
    let mut per_block: BTreeMap<String, Vec<Value>> = BTreeMap::new();
    for c in ours["crossings"].as_array().into_iter().flatten() {
        per_block
            .entry(c["block"].to_string())
            .or_default()
            .push(c["t85_s"].clone());
    }
    let theirs_per_block: BTreeMap<String, Vec<Value>> = theirs["crossings"]
        .as_array()
        .into_iter()
        .flatten()
        .map(|c| {
            (
                c["block"].to_string(),
                c["t85_s"].as_array().cloned().unwrap_or_default(),
            )
        })
        .collect();
    let keys: Vec<&String> = per_block.keys().chain(theirs_per_block.keys()).collect();
    for key in keys {
        let (a, b) = (
            per_block.get(key).cloned().unwrap_or_default(),
            theirs_per_block.get(key).cloned().unwrap_or_default(),
        );
        let same = a.len() == b.len() && a.iter().zip(&b).all(|(x, y)| close(x, y, 1e-6));
        if !same {
            differ(&format!("crossings of {key}"), &json!(a), &json!(b));
        }
    }
    diffs.dedup();
    diffs
}

#[test]
fn the_comparison_notices_each_kind_of_difference() {
    let theirs = json!({"valid": true, "invalid": null, "feasible": false, "error": null,
        "violation": {"block": [1, 0, 1], "kind": "min", "time_s": 12.5, "step": 250,
                      "prefix_len": 7, "prefix_fragments": 1, "phase": "deposit", "t85_s": 1.2},
        "crossings": [{"block": [1, 0, 1], "t85_s": [3.0, 1.2]}]});
    let ours = json!({"valid": true, "feasible": false,
        "violation": {"block": [1, 0, 1], "kind": "min", "time_s": 12.5, "step": 250,
                      "prefix_len": 7, "prefix_fragments": 1, "phase": "deposit", "t85_s": 1.2},
        "crossings": [{"block": [1, 0, 1], "t85_s": 3.0}, {"block": [1, 0, 1], "t85_s": 1.2}]});
    assert!(compare(&ours, Some(1), &theirs).is_empty());
    let changed = |path: &[&str], v: Value| {
        let mut o = ours.clone();
        let mut at = &mut o;
        for p in path {
            at = &mut at[*p];
        }
        *at = v;
        compare(&o, Some(1), &theirs)
    };
    assert!(!changed(&["feasible"], json!(true)).is_empty());
    assert!(!changed(&["violation", "block"], json!([0, 0, 1])).is_empty());
    assert!(!changed(&["violation", "kind"], json!("max")).is_empty());
    assert!(!changed(&["violation", "prefix_len"], json!(8)).is_empty());
    assert!(!changed(&["violation", "time_s"], json!(12.55)).is_empty());
    assert!(!changed(&["crossings"], json!([{"block": [1, 0, 1], "t85_s": 3.0}])).is_empty());
    assert!(!changed(
        &["crossings"],
        json!([{"block": [1, 0, 1], "t85_s": 3.0}, {"block": [1, 0, 1], "t85_s": 1.2000011}])
    )
    .is_empty());
    assert!(!compare(&ours, Some(0), &theirs).is_empty());
    let invalid_theirs = json!({"valid": false, "invalid": "rule 1: block [1, 0, 0] does not appear in the plan", "error": null});
    let invalid_ours = json!({"valid": false, "invalid": {"rule": 1, "message": "rule 1: block [1,0,0] does not appear in the plan"}});
    assert!(compare(&invalid_ours, Some(1), &invalid_theirs).is_empty());
    let other = json!({"valid": false, "invalid": {"rule": 1, "message": "rule 1: block [2,0,0] does not appear in the plan"}});
    assert!(!compare(&other, Some(1), &invalid_theirs).is_empty());
}

#[test]
fn waam_check_agrees_with_refcheck() {
    let Ok(python) = std::env::var("WAAM_REFCHECK_PY") else {
        println!(
            "skipped: set WAAM_REFCHECK_PY to refcheck's python (export WAAM_REFCHECK_PY=\"$(scripts/refcheck.sh)\")"
        );
        return;
    };
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let refcheck_dir = std::env::var("WAAM_REFCHECK_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|_| root.join("../shared/tools/refcheck"));
    let dir = tempfile::tempdir().unwrap();
    let mut parts: Vec<PathBuf> = std::fs::read_dir(root.join("config/parts"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "yaml"))
        .collect();
    parts.sort();
    assert!(!parts.is_empty());

    let mut rng = Rng(0x5EED_2024);
    let mut cases = Vec::new();
    let mut kinds: BTreeMap<String, usize> = BTreeMap::new();
    for path in &parts {
        let part = Part::parse(&std::fs::read_to_string(path).unwrap()).unwrap();
        for (n, (kind, fragments)) in plans_for(&part, &mut rng).into_iter().enumerate() {
            let id = format!("{}#{n}-{kind}", part.name);
            // Every third plan as JSON, the rest as YAML: both readers get exercised.
            let plan = Plan {
                part: Some(part.name.clone()),
                fragments,
                nodes: None,
            };
            let file = if n % 3 == 2 {
                let f = dir.path().join(format!("{}-{n}.json", part.name));
                std::fs::write(&f, serde_json::to_string(&plan).unwrap()).unwrap();
                f
            } else {
                let f = dir.path().join(format!("{}-{n}.yaml", part.name));
                std::fs::write(&f, plan.to_yaml()).unwrap();
                f
            };
            *kinds.entry(kind.clone()).or_default() += 1;
            cases.push(Case {
                id,
                part: path.clone(),
                plan: file,
                kind,
            });
        }
    }

    let input: Vec<Value> = cases
        .iter()
        .map(|c| json!({"id": c.id, "part": c.part, "plan": c.plan}))
        .collect();
    let mut child = Command::new(&python)
        .arg(root.join("tests/py/refcheck_batch.py"))
        .arg(&refcheck_dir)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .spawn()
        .expect("refcheck's python runs");
    serde_json::to_writer(child.stdin.take().unwrap(), &input).unwrap();
    let out = child.wait_with_output().unwrap();
    assert!(out.status.success(), "refcheck_batch.py failed");
    let theirs: Vec<Value> = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(theirs.len(), cases.len());

    let mut failures = Vec::new();
    let mut seen: BTreeMap<String, usize> = BTreeMap::new();
    let (mut violations, mut crossings) = (0, 0);
    for (case, theirs) in cases.iter().zip(&theirs) {
        violations += !theirs["violation"].is_null() as usize;
        crossings += theirs["crossings"]
            .as_array()
            .into_iter()
            .flatten()
            .map(|c| c["t85_s"].as_array().map_or(0, Vec::len))
            .sum::<usize>();
        let (code, ours) = waam_check(&case.part, &case.plan);
        let label = match (&ours["valid"], &ours["feasible"]) {
            (Value::Bool(false), _) => format!("invalid rule {}", ours["invalid"]["rule"]),
            (_, Value::Bool(true)) => "feasible".into(),
            (Value::Bool(true), _) => "infeasible".into(),
            _ => "error".into(),
        };
        *seen.entry(label).or_default() += 1;
        for d in compare(&ours, code, theirs) {
            failures.push(format!("{} ({}): {d}", case.id, case.kind));
        }
    }
    println!(
        "{} cases over {} parts; made: {kinds:?}",
        cases.len(),
        parts.len()
    );
    println!(
        "verdicts (waam): {seen:?}; compared {violations} violations, {crossings} t8/5 crossings"
    );
    assert!(violations > 0 && crossings > 0);
    for rule in 1..=4 {
        assert!(
            seen.contains_key(&format!("invalid rule {rule}")),
            "no plan broke rule {rule}"
        );
    }
    assert!(seen.contains_key("feasible") && seen.contains_key("infeasible"));
    assert!(
        failures.is_empty(),
        "{} disagreement(s):\n{}",
        failures.len(),
        failures.join("\n")
    );
}
