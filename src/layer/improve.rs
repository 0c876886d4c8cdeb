//! Local search on complete trails, to find a good incumbent early when the branch and
//! bound cannot finish (large layers under a time limit). It never proves anything: the
//! search's lower bound stays the only proof; a better incumbent just prunes more and
//! shrinks the reported gap.
//!
//! A trail is a sequence of runs (walks welded without deadheading). Neighbours keep the
//! number of runs, so the deadheading count stays the minimum: reverse a run, move a run
//! elsewhere in the order, start a closed run at another of its nodes, or reverse a
//! closed piece inside a run (a sub-walk that returns to its first node).

use std::time::Instant;

use super::model::{Model, Move, Trail};

type Run = Vec<Move>;

fn runs_of(trail: &Trail) -> Vec<Run> {
    let mut runs: Vec<Run> = Vec::new();
    for (i, m) in trail.moves.iter().enumerate() {
        if i == 0 || m.deadhead_before {
            runs.push(Vec::new());
        }
        runs.last_mut().expect("a run was just started").push(Move {
            deadhead_before: false,
            ..*m
        });
    }
    runs
}

fn trail_of(runs: &[Run]) -> Trail {
    let mut moves = Vec::new();
    for (r, run) in runs.iter().enumerate() {
        for (k, m) in run.iter().enumerate() {
            moves.push(Move {
                deadhead_before: r > 0 && k == 0,
                ..*m
            });
        }
    }
    Trail { moves }
}

fn flipped(m: &Move) -> Move {
    Move {
        reversed: !m.reversed,
        ..*m
    }
}

/// All neighbours of a trail (as run lists).
fn neighbours(model: &Model, runs: &[Run]) -> Vec<Vec<Run>> {
    let mut out = Vec::new();
    for r in 0..runs.len() {
        let mut v = runs.to_vec();
        v[r] = runs[r].iter().rev().map(flipped).collect();
        out.push(v);
        for to in 0..runs.len() {
            if to != r {
                let mut v = runs.to_vec();
                let run = v.remove(r);
                v.insert(to, run);
                out.push(v);
            }
        }
        let run = &runs[r];
        let start = |k: usize| model.ends(&run[k]).0;
        let end = |k: usize| model.ends(&run[k]).1;
        if start(0) == end(run.len() - 1) {
            for k in 1..run.len() {
                let mut v = runs.to_vec();
                v[r] = run[k..].iter().chain(&run[..k]).copied().collect();
                out.push(v);
            }
        }
        for i in 0..run.len() {
            for j in i + 1..run.len() {
                if start(i) == end(j) && (i, j) != (0, run.len() - 1) {
                    let mut v = runs.to_vec();
                    let piece = run[i..=j].iter().rev().map(flipped);
                    v[r] = run[..i]
                        .iter()
                        .copied()
                        .chain(piece)
                        .chain(run[j + 1..].iter().copied())
                        .collect();
                    out.push(v);
                }
            }
        }
    }
    out
}

/// First-improvement hill climbing from `trail` until no neighbour is better or the
/// deadline passes. Returns the best trail and its objective.
pub fn improve(model: &Model, trail: &Trail, objective: f64, deadline: Instant) -> (Trail, f64) {
    let mut runs = runs_of(trail);
    let mut best = objective;
    'climb: loop {
        for candidate in neighbours(model, &runs) {
            if Instant::now() >= deadline {
                break 'climb;
            }
            let t = trail_of(&candidate);
            debug_assert!(model.check_trail(&t).is_ok());
            let value = model.simulate(&t, None);
            if value < best {
                best = value;
                runs = candidate;
                continue 'climb;
            }
        }
        break;
    }
    (trail_of(&runs), best)
}
