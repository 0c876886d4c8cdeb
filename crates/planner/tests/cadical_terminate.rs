//! The vendored CaDiCaL's patch (`vendor/README.md`): the terminate callback is polled after
//! a conflict too. Unpatched, CaDiCaL asks it only after a propagation without a conflict,
//! so a run of conflicts in a row is deaf to a cancel for as long as it lasts; this test
//! builds such a run and cancels inside it.

use std::num::NonZeroI32;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use pindakaas::solver::cadical::Cadical;
use pindakaas::solver::{Assumptions, SolveResult, TermSignal, TerminateCallback};
use pindakaas::ClauseDatabase;

/// Decision levels of the run: about 2.5 µs a conflict, so 2–3 s of conflicts in a row.
const LEVELS: i32 = 1_000_000;

fn lit(v: i32) -> pindakaas::Lit {
    pindakaas::Lit::from_raw(NonZeroI32::new(v).expect("literals are non-zero"))
}

/// A formula whose search runs into `levels` conflicts in a row (with `clash`; without it,
/// the same descent and then a model).
///
/// CaDiCaL decides x_1, …, x_L true in that order (they have the highest variable indices,
/// where its decision queue starts, and its default phase is true). B_i says x_{i-1} ∧ x_i
/// → x_{i+1}, split on an auxiliary b_i so that it propagates nothing while x_{i+1} is open;
/// A says not both x_{L-1} and x_L. The clash at level L learns ¬x_{L-1} ∨ ¬x_L, backjumps
/// to level L-1 and asserts ¬x_L, which breaks B_{L-1} at once: it learns ¬x_{L-2} ∨ ¬x_{L-1},
/// and so on, one conflict per level down to the root, none of them followed by a quiet
/// propagation.
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

fn terminate_on(s: &mut Cadical, flag: &Arc<AtomicBool>) {
    let flag = Arc::clone(flag);
    s.set_terminate_callback(Some(move || {
        if flag.load(Ordering::Relaxed) {
            TermSignal::Terminate
        } else {
            TermSignal::Continue
        }
    }));
}

#[test]
fn a_cancel_is_heard_inside_a_run_of_conflicts() {
    // The descent alone (no clash: decisions only, then a model), to know when the run
    // of conflicts has begun on this machine.
    let never = Arc::new(AtomicBool::new(false));
    let mut s = cascade(LEVELS, false);
    terminate_on(&mut s, &never);
    let started = Instant::now();
    assert!(matches!(
        s.solve_assuming(std::iter::empty()),
        SolveResult::Satisfied(_)
    ));
    let descent = started.elapsed();
    drop(s);

    let cancel = Arc::new(AtomicBool::new(false));
    let mut s = cascade(LEVELS, true);
    terminate_on(&mut s, &cancel);
    // Half a descent and 100 ms past its end: inside the run of conflicts.
    let after = descent + descent / 2 + Duration::from_millis(100);
    let raised = {
        let cancel = Arc::clone(&cancel);
        std::thread::spawn(move || {
            std::thread::sleep(after);
            cancel.store(true, Ordering::Relaxed);
            Instant::now()
        })
    };
    let started = Instant::now();
    let result = s.solve_assuming(std::iter::empty());
    let (returned, solve) = (Instant::now(), started.elapsed());
    let raised = raised.join().expect("the cancelling thread");
    let late = returned.saturating_duration_since(raised);
    eprintln!(
        "descent {:.3} s, cancel at {:.3} s, solve returned after {:.3} s: {:.3} s after the cancel",
        descent.as_secs_f64(),
        after.as_secs_f64(),
        solve.as_secs_f64(),
        late.as_secs_f64()
    );
    assert!(
        matches!(result, SolveResult::Unknown),
        "the solve ended ({}) before the cancel at {:.3} s: make LEVELS larger",
        if matches!(result, SolveResult::Satisfied(_)) {
            "SAT"
        } else {
            "UNSAT"
        },
        after.as_secs_f64()
    );
    assert!(
        late < Duration::from_secs(1),
        "the solve went on for {:.3} s after the cancel",
        late.as_secs_f64()
    );
}
