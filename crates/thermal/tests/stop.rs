//! Issue #18, H1: a simulation is stopped by a cancel flag or a deadline, however long its
//! transits (the binary's own time limits: `tests/cli/harden.rs`).

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use waam_fixtures::two_towers;
use waam_part::graph::WeldGraph;
use waam_part::Part;
use waam_thermal::ThermalModel;

/// Issue #18, H1 (library level, the node's case): raising the cancel flag stops a whole
/// simulation with a 10^8-step transit within a second, and a passed deadline stops it at
/// once.
#[test]
fn a_cancel_stops_a_long_simulation_within_a_second() {
    let part = Part::parse(&two_towers(5.0e7)).unwrap();
    let graph = WeldGraph::new(&part);
    let model = ThermalModel::new(&part, &graph);
    let fragments = vec![vec![0], vec![1]];
    let cancel = Arc::new(AtomicBool::new(false));
    let raiser = {
        let cancel = Arc::clone(&cancel);
        std::thread::spawn(move || {
            std::thread::sleep(Duration::from_millis(300));
            cancel.store(true, Ordering::Relaxed);
            Instant::now()
        })
    };
    let outcome = waam_thermal::simulate_until(&model, &fragments, None, Some(cancel)).unwrap();
    let stopped = Instant::now();
    let raised = raiser.join().unwrap();
    assert!(outcome.is_none(), "a cancelled run has no outcome");
    assert!(
        stopped.duration_since(raised) < Duration::from_secs(1),
        "{:?} after the cancel",
        stopped.duration_since(raised)
    );
    let t = Instant::now();
    let outcome =
        waam_thermal::simulate_until(&model, &fragments, Some(Instant::now()), None).unwrap();
    assert!(outcome.is_none());
    assert!(t.elapsed() < Duration::from_secs(1), "{:?}", t.elapsed());
}
