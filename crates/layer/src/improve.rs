//! Local search on complete trails, to find a good incumbent early when the branch and
//! bound cannot finish (large layers under a time limit). It never proves anything: the
//! search's lower bound stays the only proof; a better incumbent just prunes more and
//! shrinks the reported gap.
//!
//! A trail is a sequence of runs (walks welded without deadheading). Neighbours keep the
//! number of runs, so the deadheading count stays the minimum: reverse a run, move a run
//! elsewhere in the order, start a closed run at another of its nodes, reverse a closed
//! piece inside a run (a sub-walk that returns to its first node), or move such a piece
//! into another run that passes its node. Hill climbing stops in a local optimum; random
//! kicks of three neighbour steps then restart it (iterated local search with a fixed
//! seed, so runs repeat).

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
                if start(i) != end(j) || (i, j) == (0, run.len() - 1) {
                    continue;
                }
                let mut v = runs.to_vec();
                let piece = run[i..=j].iter().rev().map(flipped);
                v[r] = run[..i]
                    .iter()
                    .copied()
                    .chain(piece)
                    .chain(run[j + 1..].iter().copied())
                    .collect();
                out.push(v);
                // Move the closed piece i..=j (either way round) into another run.
                let rest: Run = run[..i].iter().chain(&run[j + 1..]).copied().collect();
                for (o, other) in runs.iter().enumerate() {
                    if o == r {
                        continue;
                    }
                    for p in 0..=other.len() {
                        let at = if p == 0 {
                            model.ends(&other[0]).0
                        } else {
                            model.ends(&other[p - 1]).1
                        };
                        if at != start(i) {
                            continue;
                        }
                        for backwards in [false, true] {
                            let piece: Run = if backwards {
                                run[i..=j].iter().rev().map(flipped).collect()
                            } else {
                                run[i..=j].to_vec()
                            };
                            let mut v = runs.to_vec();
                            v[r] = rest.clone();
                            v[o] = other[..p]
                                .iter()
                                .chain(&piece)
                                .chain(&other[p..])
                                .copied()
                                .collect();
                            out.push(v);
                        }
                    }
                }
            }
        }
    }
    out
}

/// Kicks in a row without a better trail after which the local search gives up.
pub const STALL_KICKS: usize = 30;

/// Iterated first-improvement hill climbing from `trail` until the deadline or
/// [`STALL_KICKS`] fruitless kicks. Returns the best trail found and its objective.
pub fn improve(model: &Model, trail: &Trail, objective: f64, deadline: Instant) -> (Trail, f64) {
    let mut best_runs = runs_of(trail);
    let mut best = objective;
    let mut runs = best_runs.clone();
    let mut value = objective;
    let mut seed: u64 = 0x9e37_79b9_7f4a_7c15;
    let mut random = move |n: usize| {
        // xorshift64*: a fixed sequence, so a run repeats.
        seed ^= seed >> 12;
        seed ^= seed << 25;
        seed ^= seed >> 27;
        (seed.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 33) as usize % n.max(1)
    };
    let mut stalled = 0;
    while Instant::now() < deadline && stalled < STALL_KICKS {
        // Climb to a local optimum.
        'climb: loop {
            for candidate in neighbours(model, &runs) {
                if Instant::now() >= deadline {
                    break 'climb;
                }
                let v = model.simulate(&trail_of(&candidate), None);
                if v < value {
                    value = v;
                    runs = candidate;
                    continue 'climb;
                }
            }
            break;
        }
        if value < best {
            best = value;
            best_runs = runs.clone();
            stalled = 0;
        } else {
            stalled += 1;
        }
        // Kick: three random neighbour steps from the best trail, then climb again.
        runs = best_runs.clone();
        for _ in 0..3 {
            let mut next = neighbours(model, &runs);
            if next.is_empty() {
                return (trail_of(&best_runs), best);
            }
            let k = random(next.len());
            runs = next.swap_remove(k);
        }
        value = model.simulate(&trail_of(&runs), None);
    }
    (trail_of(&best_runs), best)
}
