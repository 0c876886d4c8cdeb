//! Torch access as a planning constraint.

mod common;

use common::planner::*;
use waam_access::{Torch, TorchSetup};
use waam_planner::{self as planner, Options};

#[test]
fn explore_all() {
    for name in ["s1-wall","s2-corner","s3-ring","s5-ledge","s6-channel","s7-pad","ex1-plate-boss","ex2-bracket","ex3-h-column"] {
        let part = read_part(name);
        let opts = Options {
            torch: Some(TorchSetup::new(Torch::default(), 10.0, 0.0)),
            timeout: Some(std::time::Duration::from_secs(30)),
            ..Options::default()
        };
        let t = std::time::Instant::now();
        let base = planner::plan(&part, &Options::default(), &mut |_| {}).unwrap();
        let report = planner::plan(&part, &opts, &mut |_| {}).unwrap();
        let same = base.best.as_ref().map(|b| &b.fragments) == report.best.as_ref().map(|b| &b.fragments);
        eprintln!("{name}: {:?} found={} proven={} same_as_no_torch={same} no_plan={:?} cands={}",
            t.elapsed(), report.best.is_some(), report.proven, report.no_plan.map(|n| n.to_string()), report.stats.candidates);
    }
}
