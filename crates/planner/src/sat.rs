//! A small solver interface of our own, so that the encoding does not depend on one
//! SAT backend: add clauses, solve under assumptions, read the model.
//!
//! Two backends: [`Varisat`] (pure Rust) and `cadical::Cadical` (CaDiCaL through pindakaas),
//! which keeps cycles out inside its search and can be interrupted mid-solve;
//! [`crate::new_solver`] makes either.

use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Instant;

use varisat::ExtendFormula;
use waam_thermal::ThermalModel;

pub use crate::lit::Lit;
use crate::thermal_prefix::{PrefixReport, ThermalPrefix};

/// Which SAT solver runs the search.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Backend {
    /// CaDiCaL (C++, through pindakaas): acyclicity checked inside the search by a user
    /// propagator (IPASIR-UP), and solves stop at the deadline or on cancel.
    #[default]
    Cadical,
    /// varisat (pure Rust, vendored with an interrupt): cycles cut between solves, and
    /// solves stop at the deadline or on cancel.
    Varisat,
}

/// A name that is not a SAT solver.
#[derive(Debug, Clone, thiserror::Error)]
#[error("unknown SAT solver {0:?} (expected cadical or varisat)")]
pub struct UnknownBackend(pub String);

impl std::str::FromStr for Backend {
    type Err = UnknownBackend;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Self::ALL
            .iter()
            .find(|(_, n, _)| n.eq_ignore_ascii_case(s))
            .map(|(b, _, _)| *b)
            .ok_or_else(|| UnknownBackend(s.to_string()))
    }
}

impl Backend {
    /// Every backend with its name (as settings and recordings write it) and a one-line help.
    pub const ALL: [(Backend, &'static str, &'static str); 2] = [
        (
            Backend::Cadical,
            "cadical",
            "CaDiCaL: cycles kept out inside the search, stops inside a solve at the deadline",
        ),
        (
            Backend::Varisat,
            "varisat",
            "varisat (pure Rust): cycles cut between solves, stops inside a solve at the deadline",
        ),
    ];

    /// The backend's name, as settings and recordings write it.
    pub fn name(self) -> &'static str {
        Self::ALL
            .iter()
            .find(|(b, _, _)| *b == self)
            .map_or("", |(_, n, _)| n)
    }
}

/// What the encoding needs of a SAT solver.
pub trait SatSolver {
    /// A fresh variable's positive literal.
    fn new_lit(&mut self) -> Lit;
    fn add_clause(&mut self, lits: &[Lit]);
    /// Solves under the given assumptions: `Some(true)` satisfiable (a model can be
    /// read), `Some(false)` unsatisfiable, `None` the solver failed.
    fn solve(&mut self, assumptions: &[Lit]) -> Option<bool>;
    /// The value of `lit` in the last model (false if unassigned).
    fn value(&self, lit: Lit) -> bool;
    /// Variables and clauses given so far.
    fn size(&self) -> (usize, usize);
    /// The value the solver tries first for `lit`'s variable (`lit` true) when it decides
    /// on it, e.g. a known plan as a warm start. A hint only: backends without phases
    /// (varisat) ignore it.
    fn set_phase(&mut self, lit: Lit) {
        let _ = lit;
    }
    /// Varies the solver's own random choices (a racer of [`crate::race`]); backends
    /// without a seed ignore it.
    fn set_seed(&mut self, seed: u32) {
        let _ = seed;
    }
    /// Makes solves stop at `deadline`, or soon after `cancel` is set: `solve` then returns
    /// `None`.
    fn set_interrupt(&mut self, deadline: Option<Instant>, cancel: Option<Arc<AtomicBool>>) {
        let _ = (deadline, cancel);
    }
    /// Keeps cycles out of the models inside the search, given every edge that can be on a
    /// cycle as (u, v, e(u,v)). True when the backend does (its models are then acyclic);
    /// false when the caller must cut cycles between solves.
    fn exclude_cycles(&mut self, blocks: usize, edges: &[(usize, usize, Lit)]) -> bool {
        let _ = (blocks, edges);
        false
    }
    /// Cycle cuts the backend added by itself so far (with [`SatSolver::exclude_cycles`]).
    fn cycle_cuts(&self) -> u64 {
        0
    }
    /// Simulates the plan prefix of every partial assignment inside the search and rules
    /// out the prefixes that break a window, as they arise. True when the backend does;
    /// false when only the complete models are judged (between solves).
    fn judge_prefixes(&mut self, prefix: ThermalPrefix) -> bool {
        let _ = prefix;
        false
    }
    /// Judges the prefixes by `model` from now on (with [`SatSolver::judge_prefixes`]).
    fn set_prefix_model(&mut self, model: Arc<ThermalModel>) {
        let _ = model;
    }
    /// What the prefix check did since the last call.
    fn take_prefix_report(&mut self) -> PrefixReport {
        PrefixReport::default()
    }
}

impl<S: SatSolver + ?Sized> SatSolver for Box<S> {
    fn new_lit(&mut self) -> Lit {
        (**self).new_lit()
    }
    fn add_clause(&mut self, lits: &[Lit]) {
        (**self).add_clause(lits)
    }
    fn solve(&mut self, assumptions: &[Lit]) -> Option<bool> {
        (**self).solve(assumptions)
    }
    fn value(&self, lit: Lit) -> bool {
        (**self).value(lit)
    }
    fn size(&self) -> (usize, usize) {
        (**self).size()
    }
    fn set_phase(&mut self, lit: Lit) {
        (**self).set_phase(lit)
    }
    fn set_interrupt(&mut self, deadline: Option<Instant>, cancel: Option<Arc<AtomicBool>>) {
        (**self).set_interrupt(deadline, cancel)
    }
    fn exclude_cycles(&mut self, blocks: usize, edges: &[(usize, usize, Lit)]) -> bool {
        (**self).exclude_cycles(blocks, edges)
    }
    fn cycle_cuts(&self) -> u64 {
        (**self).cycle_cuts()
    }
    fn judge_prefixes(&mut self, prefix: ThermalPrefix) -> bool {
        (**self).judge_prefixes(prefix)
    }
    fn set_prefix_model(&mut self, model: Arc<ThermalModel>) {
        (**self).set_prefix_model(model)
    }
    fn take_prefix_report(&mut self) -> PrefixReport {
        (**self).take_prefix_report()
    }
}

/// varisat, a CDCL solver in pure Rust.
pub struct Varisat {
    solver: varisat::Solver<'static>,
    model: Vec<bool>,
    vars: usize,
    clauses: usize,
    buf: Vec<varisat::Lit>,
}

impl Default for Varisat {
    fn default() -> Self {
        Varisat {
            solver: varisat::Solver::new(),
            model: Vec::new(),
            vars: 0,
            clauses: 0,
            buf: Vec::new(),
        }
    }
}

impl SatSolver for Varisat {
    fn new_lit(&mut self) -> Lit {
        let v = self.solver.new_var();
        self.vars += 1;
        Lit::positive(v.to_dimacs() as u32)
    }

    fn add_clause(&mut self, lits: &[Lit]) {
        self.buf.clear();
        self.buf.extend(
            lits.iter()
                .map(|l| varisat::Lit::from_dimacs(l.to_dimacs() as isize)),
        );
        self.solver.add_clause(&self.buf);
        self.clauses += 1;
    }

    fn solve(&mut self, assumptions: &[Lit]) -> Option<bool> {
        let a: Vec<varisat::Lit> = assumptions
            .iter()
            .map(|l| varisat::Lit::from_dimacs(l.to_dimacs() as isize))
            .collect();
        self.solver.assume(&a);
        let sat = self.solver.solve().ok()?;
        if sat {
            let model = self.solver.model().unwrap_or_default();
            self.model.clear();
            self.model.resize(self.vars + 1, false);
            for l in model {
                let v = l.var().to_dimacs() as usize;
                if v < self.model.len() {
                    self.model[v] = l.is_positive();
                }
            }
        }
        Some(sat)
    }

    fn value(&self, lit: Lit) -> bool {
        let v = self.model.get(lit.var() as usize).copied().unwrap_or(false);
        v != lit.is_negative()
    }

    fn size(&self) -> (usize, usize) {
        (self.vars, self.clauses)
    }

    fn set_interrupt(&mut self, deadline: Option<Instant>, cancel: Option<Arc<AtomicBool>>) {
        // The vendored varisat's one patch (vendor/README.md).
        self.solver.set_interrupt(deadline, cancel);
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    #[test]
    fn solves_under_assumptions() {
        for backend in [Backend::Varisat, Backend::Cadical] {
            let mut s = crate::new_solver(backend, 0);
            let (a, b) = (s.new_lit(), s.new_lit());
            s.add_clause(&[a, b]);
            s.add_clause(&[!a, b]);
            assert_eq!(s.solve(&[]), Some(true), "{backend:?}");
            assert!(s.value(b));
            assert_eq!(s.solve(&[!b]), Some(false), "{backend:?}");
            assert_eq!(s.solve(&[]), Some(true), "{backend:?}");
            assert_eq!(s.size(), (2, 2));
        }
    }

    /// Pigeonhole `p` into `h` (`x[pigeon][hole]`): unsatisfiable for p > h, and for 11 into
    /// 10 far beyond a millisecond for a CDCL solver.
    pub(crate) fn pigeonhole(s: &mut dyn SatSolver, p: usize, h: usize) -> Vec<Vec<Lit>> {
        let x: Vec<Vec<Lit>> = (0..p)
            .map(|_| (0..h).map(|_| s.new_lit()).collect())
            .collect();
        for row in &x {
            s.add_clause(row);
        }
        #[allow(clippy::needless_range_loop)] // a hole, two pigeons: the maths reads so
        for hole in 0..h {
            for a in 0..p {
                for b in a + 1..p {
                    s.add_clause(&[!x[a][hole], !x[b][hole]]);
                }
            }
        }
        x
    }

    #[test]
    fn a_varisat_solve_stops_at_its_deadline_or_cancel_and_the_solver_stays_usable() {
        let mut s = Varisat::default();
        let x = pigeonhole(&mut s, 11, 10);
        let t = Instant::now();
        s.set_interrupt(Some(t + std::time::Duration::from_millis(200)), None);
        assert_eq!(s.solve(&[]), None);
        assert!(t.elapsed().as_secs_f64() < 1.2, "{:?}", t.elapsed());
        // A cancel raised from another thread during the solve.
        let cancel = Arc::new(AtomicBool::new(false));
        s.set_interrupt(None, Some(cancel.clone()));
        let raise = std::thread::spawn(move || {
            std::thread::sleep(std::time::Duration::from_millis(200));
            cancel.store(true, std::sync::atomic::Ordering::Relaxed);
        });
        let t = Instant::now();
        assert_eq!(s.solve(&[]), None);
        assert!(t.elapsed().as_secs_f64() < 1.2, "{:?}", t.elapsed());
        raise.join().unwrap();
        // Usable after the interrupts: pigeon 0 in no hole is refuted at once.
        s.set_interrupt(None, None);
        let none: Vec<Lit> = x[0].iter().map(|&l| !l).collect();
        assert_eq!(s.solve(&none), Some(false));
    }
}
