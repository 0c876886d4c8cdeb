//! Linear assignment (Hungarian method with potentials) and the dual it leaves: the part
//! of the search's bound that knows every torch position is welded exactly once.
//!
//! The bound needs the *dual* of the assignment problem (a number per position and one per
//! time slot whose sums cover every gain), not just its optimum, so the remaining
//! positions of any search node can be bounded from one solve at the root. Crates that
//! solve assignments (`pathfinding`'s Kuhn–Munkres) take integer weights and return no
//! potentials, hence these few lines.

/// Row and column potentials of a maximum-weight assignment of every row to a distinct
/// column (rows ≤ columns): `row[i] + col[j] ≥ gain[i][j]` for every i and j (enforced
/// exactly after the solve, so it holds whatever the rounding), and Σ row + Σ of the
/// matched columns' `col` equals the optimum (up to rounding).
#[derive(Debug, Clone, PartialEq)]
pub struct AssignmentDual {
    pub row: Vec<f64>,
    pub col: Vec<f64>,
}

/// Solves max Σ_i gain(i, σ(i)) over injective σ: rows → columns and returns its dual.
/// `gain` is a row-major `rows × cols` matrix; needs rows ≤ cols. O(rows² · cols): a
/// layer of 420 segments is 3·10^10 operations (80 s here), so `stop` is asked before every
/// row (one row is at most rows · cols operations, milliseconds) and `None` returned once
/// it says so.
pub fn max_assignment_dual(
    gain: &[f64],
    rows: usize,
    cols: usize,
    stop: impl Fn() -> bool,
) -> Option<AssignmentDual> {
    assert!(rows <= cols, "more rows than columns");
    assert_eq!(gain.len(), rows * cols, "a rows × cols matrix");
    // Minimise cost = −gain with the classic shortest-augmenting-path method; indices
    // 1-based, column 0 a virtual start. u[i] + v[j] ≤ cost(i, j) throughout.
    let cost = |i: usize, j: usize| -gain[(i - 1) * cols + (j - 1)];
    let mut u = vec![0.0f64; rows + 1];
    let mut v = vec![0.0f64; cols + 1];
    let mut matched = vec![0usize; cols + 1]; // row matched to column j (0: none)
    let mut way = vec![0usize; cols + 1];
    for i in 1..=rows {
        if stop() {
            return None;
        }
        matched[0] = i;
        let mut j0 = 0;
        let mut min_to = vec![f64::INFINITY; cols + 1];
        let mut used = vec![false; cols + 1];
        loop {
            used[j0] = true;
            let i0 = matched[j0];
            let (mut delta, mut j1) = (f64::INFINITY, 0);
            for j in 1..=cols {
                if !used[j] {
                    let reduced = cost(i0, j) - u[i0] - v[j];
                    if reduced < min_to[j] {
                        min_to[j] = reduced;
                        way[j] = j0;
                    }
                    if min_to[j] < delta {
                        delta = min_to[j];
                        j1 = j;
                    }
                }
            }
            for j in 0..=cols {
                if used[j] {
                    u[matched[j]] += delta;
                    v[j] -= delta;
                } else {
                    min_to[j] -= delta;
                }
            }
            j0 = j1;
            if matched[j0] == 0 {
                break;
            }
        }
        loop {
            let j1 = way[j0];
            matched[j0] = matched[j1];
            j0 = j1;
            if j0 == 0 {
                break;
            }
        }
    }
    // gain(i, j) ≤ −u[i] − v[j]: columns get −v, rows the least value that covers every
    // column (recomputed, so the cover is exact and not at the mercy of the updates).
    let col: Vec<f64> = (1..=cols).map(|j| -v[j]).collect();
    let row = (0..rows)
        .map(|i| {
            (0..cols)
                .map(|j| gain[i * cols + j] - col[j])
                .fold(f64::NEG_INFINITY, f64::max)
        })
        .collect();
    Some(AssignmentDual { row, col })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Best assignment by trying every injective map (tiny sizes only).
    fn brute(gain: &[f64], rows: usize, cols: usize) -> f64 {
        fn go(gain: &[f64], rows: usize, cols: usize, i: usize, used: &mut [bool]) -> f64 {
            if i == rows {
                return 0.0;
            }
            let mut best = f64::NEG_INFINITY;
            for j in 0..cols {
                if !used[j] {
                    used[j] = true;
                    best = best.max(gain[i * cols + j] + go(gain, rows, cols, i + 1, used));
                    used[j] = false;
                }
            }
            best
        }
        go(gain, rows, cols, 0, &mut vec![false; cols])
    }

    #[test]
    fn dual_covers_every_gain_and_meets_the_optimum() {
        // A small deterministic pseudo-random generator: no test dependency needed here.
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state % 1000) as f64 / 10.0 - 20.0
        };
        for (rows, cols) in [(1, 1), (2, 3), (3, 3), (4, 6), (5, 5), (6, 7)] {
            for _ in 0..20 {
                let gain: Vec<f64> = (0..rows * cols).map(|_| next()).collect();
                let d = max_assignment_dual(&gain, rows, cols, || false).unwrap();
                for i in 0..rows {
                    for j in 0..cols {
                        assert!(d.row[i] + d.col[j] >= gain[i * cols + j]);
                    }
                }
                // The dual bound with the `rows` largest column values meets the optimum.
                let mut c = d.col.clone();
                c.sort_by(|a, b| b.total_cmp(a));
                let bound: f64 = d.row.iter().sum::<f64>() + c[..rows].iter().sum::<f64>();
                let best = brute(&gain, rows, cols);
                assert!(bound >= best - 1e-9, "{bound} < {best}");
                assert!(
                    bound <= best + 1e-6,
                    "dual {bound} not tight, optimum {best}"
                );
            }
        }
    }
}
