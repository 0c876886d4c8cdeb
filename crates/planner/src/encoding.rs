//! The CNF encoding of fragmented Hamiltonian weld paths (Ehlers, Treutler, Wesling, SAT 2020).
//!
//! Variables:
//! - `e(u,v)` for every weld-graph edge: the torch moves from block u straight to v;
//! - `start(v)`: v begins a weld path (it has no incoming edge), `end(v)`: v ends one;
//! - `le(v,i)` = "the fragment index of v is at most i" (order encoding of z(v,i));
//! - `sz(v,i)`: v is the start of fragment i; `used(i)`: fragment i exists.
//!
//! Constraints: at most one incoming and one outgoing edge per block; start(v) exactly
//! when no incoming edge; at most k starts (a sequential counter); an edge keeps the
//! fragment index; distinct starts take distinct indices, used without gaps from 0, so a
//! model is exactly one ordered plan; gravity: a block's index is never below the index
//! of the block it stands on; no cycles (only a layer can hold one, since the torch never
//! moves down), eagerly by a rank order per layer or lazily by cuts between solves.

// Clauses are written over block and fragment indices, as in the paper: index loops read
// closer to the maths than iterator chains here.
#![allow(clippy::needless_range_loop)]

use waam_part::graph::WeldGraph;
use waam_part::Part;

use super::sat::{Lit, SatSolver};

/// How cycles are kept out of the models.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Acyclicity {
    /// A binary rank per block and `e(u,v) -> rank(u) < rank(v)` within each layer.
    Eager,
    /// Solve, find the cycles in the model, add a clause cutting each, solve again.
    Lazy,
    /// Lazy, but a layer that shows a cycle once gets the eager rank order from then on.
    Hybrid,
}

impl Acyclicity {
    /// Every method with its name (as settings and recordings write it) and a one-line help.
    pub const ALL: [(Acyclicity, &'static str, &'static str); 3] = [
        (
            Acyclicity::Eager,
            "eager",
            "a binary rank per block, e(u,v) -> rank(u) < rank(v) within each layer",
        ),
        (
            Acyclicity::Lazy,
            "lazy",
            "solve, cut each cycle found in the model, solve again",
        ),
        (
            Acyclicity::Hybrid,
            "hybrid",
            "lazy, but a layer that shows a cycle gets the eager rank order",
        ),
    ];

    /// The method's name, as settings and recordings write it.
    pub fn name(self) -> &'static str {
        Self::ALL
            .iter()
            .find(|(a, _, _)| *a == self)
            .map_or("", |(_, n, _)| n)
    }
}

/// A name that is not an acyclicity method.
#[derive(Debug, Clone, thiserror::Error)]
#[error("unknown acyclicity method {0:?} (expected eager, lazy or hybrid)")]
pub struct UnknownAcyclicity(pub String);

impl std::str::FromStr for Acyclicity {
    type Err = UnknownAcyclicity;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Self::ALL
            .iter()
            .find(|(_, n, _)| n.eq_ignore_ascii_case(s))
            .map(|(a, _, _)| *a)
            .ok_or_else(|| UnknownAcyclicity(s.to_string()))
    }
}

impl std::fmt::Display for Acyclicity {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// The variables of one part's encoding.
pub struct Encoding {
    k: usize,
    /// Per block: (successor, e(u,v)).
    out: Vec<Vec<(u32, Lit)>>,
    /// Per block: (predecessor, e(u,v)).
    inc: Vec<Vec<(u32, Lit)>>,
    start: Vec<Lit>,
    end: Vec<Lit>,
    /// le[v][i] for i in 0..k (le[v][k-1] is the constant true literal).
    le: Vec<Vec<Lit>>,
    sz: Vec<Vec<Lit>>,
    used: Vec<Lit>,
    truth: Lit,
}

/// A model read back as a plan, or the cycles that make it no plan.
pub enum Decoded {
    Plan(Vec<Vec<usize>>),
    Cycles(Vec<Vec<usize>>),
}

impl Encoding {
    /// Encodes the weld paths of `part` with at most `k` fragments into `solver`; `None`
    /// when `stopped` (asked every few thousand blocks: encoding 10^5 blocks takes seconds)
    /// says so first, the solver then holding part of the encoding.
    pub fn new(
        part: &Part,
        graph: &WeldGraph,
        k: usize,
        acyclicity: Acyclicity,
        solver: &mut impl SatSolver,
        stopped: &dyn Fn() -> bool,
    ) -> Option<Encoding> {
        let n = part.len();
        let stop_at = |v: usize| v % 4096 == 0 && stopped();
        let truth = solver.new_lit();
        solver.add_clause(&[truth]);
        let mut out = vec![Vec::new(); n];
        let mut inc = vec![Vec::new(); n];
        for u in 0..n {
            if stop_at(u) {
                return None;
            }
            for &v in graph.successors(u) {
                let e = solver.new_lit();
                out[u].push((v, e));
                inc[v as usize].push((u as u32, e));
            }
        }
        let start: Vec<Lit> = (0..n).map(|_| solver.new_lit()).collect();
        let end: Vec<Lit> = (0..n).map(|_| solver.new_lit()).collect();
        for v in 0..n {
            if stop_at(v) {
                return None;
            }
            degree_constraints(solver, &inc[v], start[v]);
            degree_constraints(solver, &out[v], end[v]);
        }
        // A torch move and its reverse never both happen (the only cycles of length 2).
        for u in 0..n {
            if stop_at(u) {
                return None;
            }
            for &(v, e) in &out[u] {
                if (v as usize) > u {
                    if let Some(&(_, back)) = out[v as usize].iter().find(|(w, _)| *w as usize == u)
                    {
                        solver.add_clause(&[!e, !back]);
                    }
                }
            }
        }
        at_most_k(solver, &start, k);

        // Fragment index, order-encoded: le[v][i] -> le[v][i+1].
        let le: Vec<Vec<Lit>> = (0..n)
            .map(|_| {
                let mut row: Vec<Lit> = (0..k - 1).map(|_| solver.new_lit()).collect();
                row.push(truth);
                for i in 0..k - 1 {
                    solver.add_clause(&[!row[i], row[i + 1]]);
                }
                row
            })
            .collect();
        for u in 0..n {
            if stop_at(u) {
                return None;
            }
            for &(v, e) in &out[u] {
                for i in 0..k - 1 {
                    solver.add_clause(&[!e, !le[u][i], le[v as usize][i]]);
                    solver.add_clause(&[!e, le[u][i], !le[v as usize][i]]);
                }
            }
            // Gravity: what the block stands on is welded in the same or an earlier
            // fragment (on a cube part, the block below).
            for &below in graph.supports(u) {
                for i in 0..k - 1 {
                    solver.add_clause(&[!le[u][i], le[below as usize][i]]);
                }
            }
        }
        // sz(v,i) <-> start(v) & idx(v) = i.
        let sz: Vec<Vec<Lit>> = (0..n)
            .map(|v| {
                (0..k)
                    .map(|i| {
                        let s = solver.new_lit();
                        solver.add_clause(&[!s, start[v]]);
                        solver.add_clause(&[!s, le[v][i]]);
                        let mut back = vec![!start[v], !le[v][i], s];
                        if i > 0 {
                            solver.add_clause(&[!s, !le[v][i - 1]]);
                            back.push(le[v][i - 1]);
                        }
                        solver.add_clause(&back);
                        s
                    })
                    .collect()
            })
            .collect();
        // Each index is taken by at most one start, and indices are used from 0 without gaps.
        let used: Vec<Lit> = (0..k)
            .map(|i| {
                let column: Vec<Lit> = (0..n).map(|v| sz[v][i]).collect();
                at_most_k(solver, &column, 1);
                let u = solver.new_lit();
                let mut any = column.clone();
                any.push(!u);
                solver.add_clause(&any);
                for &s in &column {
                    solver.add_clause(&[!s, u]);
                }
                u
            })
            .collect();
        solver.add_clause(&[used[0]]);
        for i in 1..k {
            solver.add_clause(&[!used[i], used[i - 1]]);
        }
        if stopped() {
            return None;
        }
        let enc = Encoding {
            k,
            out,
            inc,
            start,
            end,
            le,
            sz,
            used,
            truth,
        };
        if acyclicity == Acyclicity::Eager {
            enc.encode_ranks(part, solver, |_| true);
        }
        Some(enc)
    }

    // Eager acyclicity: a binary rank per block, increasing along every sideways edge.
    /// Eager acyclicity for the layers `only` admits (all layers: `|_| true`).
    pub fn encode_ranks(
        &self,
        part: &Part,
        solver: &mut impl SatSolver,
        only: impl Fn(i64) -> bool,
    ) {
        let n = part.len();
        let mut layer_size = std::collections::HashMap::<i64, usize>::new();
        for b in part.blocks() {
            *layer_size.entry(b[2]).or_default() += 1;
        }
        let bits_of = |z: i64| {
            let size = layer_size[&z];
            (usize::BITS - (size.max(2) - 1).leading_zeros()) as usize
        };
        let rank: Vec<Vec<Lit>> = (0..n)
            .map(|v| {
                let z = part.block(v)[2];
                let bits = if only(z) { bits_of(z) } else { 0 };
                (0..bits).map(|_| solver.new_lit()).collect()
            })
            .collect();
        for u in 0..n {
            if !only(part.block(u)[2]) {
                continue;
            }
            for &(v, e) in &self.out[u] {
                let v = v as usize;
                if part.block(v)[2] != part.block(u)[2] {
                    continue; // up moves cannot close a cycle
                }
                let (a, b) = (&rank[u], &rank[v]);
                let bits = a.len();
                // e -> OR_i d_i; d_i: a < b decided at bit i (a_i = 0, b_i = 1, equal above).
                let mut decide = vec![!e];
                let mut equal_above = self.truth;
                for i in (0..bits).rev() {
                    let d = solver.new_lit();
                    solver.add_clause(&[!d, !a[i]]);
                    solver.add_clause(&[!d, b[i]]);
                    solver.add_clause(&[!d, equal_above]);
                    decide.push(d);
                    if i > 0 {
                        let p = solver.new_lit();
                        solver.add_clause(&[!p, equal_above]);
                        solver.add_clause(&[!p, !a[i], b[i]]);
                        solver.add_clause(&[!p, a[i], !b[i]]);
                        equal_above = p;
                    }
                }
                solver.add_clause(&decide);
            }
        }
    }

    /// The most fragments this encoding allows.
    pub fn max_fragments(&self) -> usize {
        self.k
    }

    /// Assumption literal: "at most `f` fragments" (for f < k).
    pub fn at_most_fragments(&self, f: usize) -> Option<Lit> {
        (f < self.k).then(|| !self.used[f])
    }

    /// Reads the solver's model back as a plan, or as the cycles it holds.
    pub fn decode(&self, solver: &impl SatSolver) -> Decoded {
        let n = self.start.len();
        let next: Vec<Option<usize>> = (0..n)
            .map(|u| {
                self.out[u]
                    .iter()
                    .find(|(_, e)| solver.value(*e))
                    .map(|(v, _)| *v as usize)
            })
            .collect();
        let mut starts: Vec<(usize, usize)> = (0..n)
            .filter(|&v| solver.value(self.start[v]))
            .map(|v| (self.index(solver, v), v))
            .collect();
        starts.sort_unstable();
        let mut seen = vec![false; n];
        let fragments: Vec<Vec<usize>> = starts
            .iter()
            .map(|&(_, s)| {
                let mut path = vec![s];
                seen[s] = true;
                let mut at = s;
                while let Some(v) = next[at] {
                    if seen[v] {
                        break;
                    }
                    seen[v] = true;
                    path.push(v);
                    at = v;
                }
                path
            })
            .collect();
        // Blocks no start reaches each have one incoming edge: they form whole cycles.
        let mut cycles = Vec::new();
        for v in 0..n {
            if seen[v] {
                continue;
            }
            let mut cycle = Vec::new();
            let mut at = v;
            loop {
                seen[at] = true;
                cycle.push(at);
                match next[at] {
                    Some(w) if !seen[w] => at = w,
                    _ => break,
                }
            }
            cycles.push(cycle);
        }
        if cycles.is_empty() {
            Decoded::Plan(fragments)
        } else {
            Decoded::Cycles(cycles)
        }
    }

    fn index(&self, solver: &impl SatSolver, v: usize) -> usize {
        (0..self.k)
            .find(|&i| solver.value(self.le[v][i]))
            .unwrap_or(self.k - 1)
    }

    /// The clause cutting a cycle (a list of blocks, each moving to the next, the last to
    /// the first): not all of its edges.
    pub fn cycle_cut(&self, cycle: &[usize]) -> Vec<Lit> {
        (0..cycle.len())
            .filter_map(|p| self.edge(cycle[p], cycle[(p + 1) % cycle.len()]))
            .map(|e| !e)
            .collect()
    }

    /// The edges that can lie on a cycle, as (u, v, e(u,v)): the sideways ones (a cycle
    /// never leaves its layer, since the torch never moves down).
    pub fn cycle_edges(&self, part: &Part) -> Vec<(usize, usize, Lit)> {
        let z = |b: usize| part.block(b)[2];
        (0..self.out.len())
            .flat_map(|u| {
                self.out[u]
                    .iter()
                    .filter(move |&&(v, _)| z(v as usize) == z(u))
                    .map(move |&(v, e)| (u, v as usize, e))
            })
            .collect()
    }

    /// The literal of edge `u -> v`.
    pub fn edge(&self, u: usize, v: usize) -> Option<Lit> {
        self.out[u]
            .iter()
            .find(|(w, _)| *w as usize == v)
            .map(|(_, e)| *e)
    }

    /// The literals that hold exactly for the plans beginning with `fragments` (block
    /// indices, in order). `closed`: the last fragment ends where it ends; otherwise it
    /// may go on. A complete plan is pinned down by its edges and starts alone.
    pub fn prefix_literals(&self, fragments: &[Vec<usize>], closed: bool) -> Vec<Lit> {
        let mut lits = Vec::new();
        for (f, fragment) in fragments.iter().enumerate() {
            lits.push(self.sz[fragment[0]][f]);
            for pair in fragment.windows(2) {
                lits.push(self.edge(pair[0], pair[1]).expect("plan moves along edges"));
            }
        }
        let open = usize::from(!closed);
        for fragment in &fragments[..fragments.len().saturating_sub(open)] {
            lits.push(self.end[*fragment.last().expect("fragments are non-empty")]);
        }
        lits
    }

    /// Binary clauses that hold exactly for the plans that weld block `b` in the same or an
    /// earlier fragment than block `a`: `idx(a) <= i -> idx(b) <= i` for every i. When `a`
    /// is higher than `b` (a fragment never moves down), they rule out exactly the plans
    /// that weld `a` before `b`.
    pub fn not_before(&self, a: usize, b: usize) -> Vec<[Lit; 2]> {
        (0..self.k - 1)
            .map(|i| [!self.le[a][i], self.le[b][i]])
            .collect()
    }

    /// The literals of a complete plan (its edges and its numbered starts).
    pub fn plan_literals(&self, fragments: &[Vec<usize>]) -> Vec<Lit> {
        let mut lits = Vec::new();
        for (f, fragment) in fragments.iter().enumerate() {
            lits.push(self.sz[fragment[0]][f]);
            for pair in fragment.windows(2) {
                lits.push(self.edge(pair[0], pair[1]).expect("plan moves along edges"));
            }
        }
        lits
    }

    /// Literal: block `v` starts fragment `i`.
    pub fn starts_fragment(&self, v: usize, i: usize) -> Lit {
        self.sz[v][i]
    }

    /// Literal: a weld path ends at block `v`.
    pub fn ends_at(&self, v: usize) -> Lit {
        self.end[v]
    }

    /// Every edge literal `e(u,v)`, as (u, v, e).
    pub fn edges(&self) -> impl Iterator<Item = (usize, usize, Lit)> + '_ {
        self.out
            .iter()
            .enumerate()
            .flat_map(|(u, out)| out.iter().map(move |&(v, e)| (u, v as usize, e)))
    }

    /// Number of incoming-edge literals (for statistics).
    pub fn edge_count(&self) -> usize {
        self.inc.iter().map(Vec::len).sum()
    }
}

/// At most one of `edges`, and `flag` exactly when none of them.
fn degree_constraints(solver: &mut impl SatSolver, edges: &[(u32, Lit)], flag: Lit) {
    for (a, &(_, x)) in edges.iter().enumerate() {
        solver.add_clause(&[!x, !flag]);
        for &(_, y) in &edges[a + 1..] {
            solver.add_clause(&[!x, !y]);
        }
    }
    let mut any: Vec<Lit> = edges.iter().map(|&(_, e)| e).collect();
    any.push(flag);
    solver.add_clause(&any);
}

/// At most `k` of `lits` true: Sinz's sequential counter (2005).
pub fn at_most_k(solver: &mut impl SatSolver, lits: &[Lit], k: usize) {
    let n = lits.len();
    if n <= k {
        return;
    }
    if k == 0 {
        for &x in lits {
            solver.add_clause(&[!x]);
        }
        return;
    }
    // s[i][j]: at least j+1 of lits[0..=i] are true.
    let mut prev: Vec<Lit> = Vec::new();
    for (i, &x) in lits.iter().enumerate().take(n - 1) {
        let row: Vec<Lit> = (0..k).map(|_| solver.new_lit()).collect();
        solver.add_clause(&[!x, row[0]]);
        if i > 0 {
            for j in 0..k {
                solver.add_clause(&[!prev[j], row[j]]);
            }
            for j in 1..k {
                solver.add_clause(&[!x, !prev[j - 1], row[j]]);
            }
            solver.add_clause(&[!x, !prev[k - 1]]);
        }
        prev = row;
    }
    solver.add_clause(&[!lits[n - 1], !prev[k - 1]]);
}
