//! A small solver interface of our own, so that the encoding does not depend on one
//! SAT backend: add clauses, solve under assumptions, read the model.

use varisat::ExtendFormula;

/// A literal: variable number (from 1) with a sign, DIMACS style.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Lit(i32);

impl Lit {
    /// The positive literal of variable `var` (numbered from 1).
    pub fn positive(var: u32) -> Lit {
        Lit(var as i32)
    }

    /// The variable number (from 1).
    pub fn var(self) -> u32 {
        self.0.unsigned_abs()
    }

    /// True for a negated literal.
    pub fn is_negative(self) -> bool {
        self.0 < 0
    }

    /// DIMACS form.
    pub fn to_dimacs(self) -> i32 {
        self.0
    }
}

impl std::ops::Not for Lit {
    type Output = Lit;
    fn not(self) -> Lit {
        Lit(-self.0)
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
}

/// The default backend: varisat, a CDCL solver in pure Rust.
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
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn solves_under_assumptions() {
        let mut s = Varisat::default();
        let (a, b) = (s.new_lit(), s.new_lit());
        s.add_clause(&[a, b]);
        s.add_clause(&[!a, b]);
        assert_eq!(s.solve(&[]), Some(true));
        assert!(s.value(b));
        assert_eq!(s.solve(&[!b]), Some(false));
        assert_eq!(s.solve(&[]), Some(true));
    }
}
