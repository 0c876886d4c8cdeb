//! Issue #18: the planner's limits at library level, as the node runs it — a cancel stops a
//! search within a second, and every entry refuses a part too large for its memory limit
//! (the binary's own: `tests/cli/harden.rs`).

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use waam_fixtures::{plate_layers, two_towers};
use waam_part::Part;

/// Issue #18, H1: the planner (as the node runs it, with a cancel flag) stops within a
/// second of a cancel while simulating a 10^8-step transit.
#[test]
fn a_cancelled_planner_stops_within_a_second() {
    let part = Part::parse(&two_towers(5.0e7)).unwrap();
    let cancel = Arc::new(AtomicBool::new(false));
    let opts = waam_planner::Options {
        cancel: Some(Arc::clone(&cancel)),
        ..waam_planner::Options::default()
    };
    let raiser = {
        let cancel = Arc::clone(&cancel);
        std::thread::spawn(move || {
            std::thread::sleep(Duration::from_millis(500));
            cancel.store(true, Ordering::Relaxed);
            Instant::now()
        })
    };
    let report = waam_planner::plan(&part, &opts, &mut |_| {}).unwrap();
    let stopped = Instant::now();
    let raised = raiser.join().unwrap();
    assert!(!report.proven);
    assert!(
        stopped.duration_since(raised) < Duration::from_secs(1),
        "{:?} after the cancel",
        stopped.duration_since(raised)
    );
}

/// Issue #18, H2: the limit is the planner's, so the node (and `count`, `--all`) refuse
/// the same part by the same estimate; a raised limit lets a part through.
#[test]
fn the_memory_limit_is_checked_by_every_planner_entry_and_can_be_raised() {
    let part = Part::parse(&plate_layers(300)).unwrap();
    let small = waam_planner::Options {
        max_memory_mb: 100,
        timeout: Some(Duration::from_millis(1)),
        ..waam_planner::Options::default()
    };
    let t = Instant::now();
    for err in [
        waam_planner::plan(&part, &small, &mut |_| {}).err(),
        waam_planner::first(&part, &small, &mut |_| {}).err(),
        waam_planner::count(&part, &small, true, &mut |_| {}).err(),
        waam_planner::enumerate(&part, &small, &mut |_| {}, &mut |_| Ok(())).err(),
    ] {
        let err = err.expect("refused").to_string();
        assert!(err.contains("max_memory_mb = 100"), "{err}");
    }
    assert!(t.elapsed() < Duration::from_secs(1), "{:?}", t.elapsed());
    // The estimate for a plate this size (90,000 blocks, k = 1) is about 1.4 GB.
    let estimate = waam_planner::estimated_memory_mb(part.len(), 1);
    assert!((1300..1500).contains(&estimate), "{estimate}");
    let tiny = Part::parse(&plate_layers(10)).unwrap();
    let raised = waam_planner::Options {
        max_memory_mb: 100,
        ..waam_planner::Options::default()
    };
    assert!(waam_planner::plan(&tiny, &raised, &mut |_| {})
        .unwrap()
        .best
        .is_some());
}
