//! The vendored CaDiCaL's patch (`vendor/README.md`): the terminate callback is polled after
//! a conflict too. Unpatched, CaDiCaL asks it only after a propagation without a conflict, so
//! a run of conflicts in a row is deaf to a cancel for as long as it lasts.
//!
//! The test counts instead of timing: a learn callback counts conflicts (one learned clause
//! each) and the terminator asks to stop from the first one on. Patched, the solve returns
//! after a handful of conflicts (the terminator is called every `terminateint` = 10 polls);
//! unpatched, it runs through the whole cascade of `LEVELS` conflicts first. Counting makes it
//! immune to a loaded machine. (The test lives here, not in `vendor/pindakaas-cadical`: that
//! crate is a `[patch.crates-io]` copy, not a workspace member, so `cargo test --workspace`
//! would never run a test of its own.)

use std::num::NonZeroI32;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use pindakaas::solver::cadical::Cadical;
use pindakaas::solver::{LearnCallback, SolveResult, Solver, TermSignal, TerminateCallback};
use pindakaas::ClauseDatabase;

/// Decision levels of the cascade: as many conflicts in a row (about 0.1 s of them).
const LEVELS: i32 = 50_000;

fn lit(v: i32) -> pindakaas::Lit {
    pindakaas::Lit::from_raw(NonZeroI32::new(v).expect("literals are non-zero"))
}

/// A formula whose search runs into `levels` conflicts in a row, none followed by a
/// propagation without a conflict (with `clash`; without it, the same descent and then a
/// model).
///
/// CaDiCaL decides x_1, …, x_L true in that order (they have the highest variable indices,
/// where its decision queue starts, and its default phase is true). B_i says x_{i-1} ∧ x_i →
/// x_{i+1}, split on an auxiliary b_i so that it propagates nothing while x_{i+1} is open; A
/// says not both x_{L-1} and x_L. The clash at level L learns ¬x_{L-1} ∨ ¬x_L, backjumps to
/// level L-1 and asserts ¬x_L, which breaks B_{L-1} at once: it learns ¬x_{L-2} ∨ ¬x_{L-1},
/// and so on, one conflict per level down to the root.
fn cascade(levels: i32, clash: bool) -> Cadical {
    let l = levels;
    let x = |i: i32| 2 * l + 2 - i;
    let b = |i: i32| i;
    let a = l + 1;
    let mut s = Cadical::default();
    // The options `waam_planner::cadical::Cadical::for_size` sets for big formulas (no
    // chronological backtracking, no inprocessing, which would resolve the b_i away), and
    // no lucky phases, which would find the all-false model before any search.
    s.set_option("chrono", 0);
    for option in [
        "reduce",
        "arena",
        "inprocessing",
        "walk",
        "compact",
        "lucky",
    ] {
        s.set_option(option, 0);
    }
    let _ = s.new_var_range(2 * l as usize + 1);
    let mut add = |c: &[i32]| {
        let c: Vec<_> = c.iter().map(|&v| lit(v)).collect();
        s.add_clause_from_slice(&c).expect("a clause");
    };
    if clash {
        add(&[-x(l - 1), -x(l), a]);
        add(&[-x(l - 1), -x(l), -a]);
    }
    for i in 1..l {
        let mut c = vec![-x(i), x(i + 1)];
        if i > 1 {
            c.push(-x(i - 1));
        }
        add(&[c.as_slice(), &[b(i)]].concat());
        add(&[c.as_slice(), &[-b(i)]].concat());
    }
    s
}

/// Counts the solver's learned clauses (its conflicts) in `learned`, and asks it to stop as
/// soon as there is one.
fn stop_at_first_conflict(s: &mut Cadical, learned: &Arc<AtomicU64>) {
    let counter = Arc::clone(learned);
    s.set_learn_callback(Some(move |_: &mut dyn Iterator<Item = pindakaas::Lit>| {
        counter.fetch_add(1, Ordering::Relaxed);
    }));
    let counter = Arc::clone(learned);
    s.set_terminate_callback(Some(move || {
        if counter.load(Ordering::Relaxed) > 0 {
            TermSignal::Terminate
        } else {
            TermSignal::Continue
        }
    }));
}

#[test]
fn the_descent_alone_has_no_conflict() {
    // Without the clash the same decisions end in a model: the conflicts of the test below
    // are the cascade's.
    let learned = Arc::new(AtomicU64::new(0));
    let mut s = cascade(LEVELS, false);
    stop_at_first_conflict(&mut s, &learned);
    assert!(matches!(s.solve(), SolveResult::Satisfied(_)));
    assert_eq!(learned.load(Ordering::Relaxed), 0);
}

#[test]
fn a_stop_is_heard_inside_a_run_of_conflicts() {
    let learned = Arc::new(AtomicU64::new(0));
    let mut s = cascade(LEVELS, true);
    stop_at_first_conflict(&mut s, &learned);
    let started = Instant::now();
    let result = s.solve();
    let took = started.elapsed();
    let conflicts = learned.load(Ordering::Relaxed);
    eprintln!(
        "stopped after {conflicts} conflicts of {LEVELS}, {:.3} s",
        took.as_secs_f64()
    );
    assert!(
        matches!(result, SolveResult::Unknown),
        "the solve was not stopped"
    );
    // Patched: the terminator is asked after every conflict, and answers on the tenth ask
    // at the latest (terminateint). Unpatched: not before the whole cascade has run.
    assert!(
        conflicts <= 20,
        "{conflicts} conflicts before the stop was heard: CaDiCaL did not poll its terminator \
         after a conflict (is the waam-planner patch in vendor/pindakaas-cadical missing?)"
    );
    assert!(took < Duration::from_secs(10), "{took:?}");
}
