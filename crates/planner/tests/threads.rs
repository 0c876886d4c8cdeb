//! `Options::threads` bounds the simulation too: a run on one thread steps every thermal
//! check on that thread, so a cell PC shared with the robot's driver keeps its other cores.
//! A test binary of its own: the simulation's worker pool is per process and started at its
//! first use, so whether it was started says whether any simulation stepped on it.

use std::time::Duration;

use waam_fixtures::stacked_plate;
use waam_part::Part;

/// The threads of this process named as the simulation pool's workers (Linux).
fn pool_workers() -> usize {
    std::fs::read_dir("/proc/self/task")
        .expect("/proc/self/task")
        .filter_map(|task| std::fs::read_to_string(task.ok()?.path().join("comm")).ok())
        .filter(|name| name.starts_with("thermal-"))
        .count()
}

#[test]
#[cfg(target_os = "linux")]
fn one_thread_keeps_every_simulation_off_the_pool_and_more_threads_use_it() {
    // 4,900 windowed blocks: the check of a plan steps ranges wider than the 4,096 slots
    // from which a simulation splits its steps.
    let (text, _) = stacked_plate(70, 70, 1);
    let part = Part::parse(&text).unwrap();
    assert!(part.len() > waam_thermal::PARALLEL_MIN_SLOTS);
    // The best plan's search goes on after its first plan: stopped after a while.
    let on = |threads: usize| waam_planner::Options {
        threads,
        timeout: Some(Duration::from_secs(5)),
        ..waam_planner::Options::default()
    };
    for entry in [waam_planner::first, waam_planner::plan] {
        let report = entry(&part, &on(1), &mut |_| {}).unwrap();
        assert!(report.best.is_some(), "the plate has a plan");
        assert!(report.stats.deposits_simulated > 4_096);
    }
    assert_eq!(pool_workers(), 0, "a run on one thread started the pool");
    // The same plan on two threads: its check steps on the pool (so the part is large
    // enough for the first half of this test to mean something).
    let report = waam_planner::first(&part, &on(2), &mut |_| {}).unwrap();
    assert!(report.best.is_some());
    assert!(
        pool_workers() > 0,
        "a run on two threads did not use the pool"
    );
}
