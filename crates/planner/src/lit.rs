//! The literal every part of the search speaks: the encoding, the solvers, the thermal
//! clauses (its own module, so that those depend on it and not on each other).

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

    /// From DIMACS form (non-zero).
    pub fn from_dimacs(lit: i32) -> Lit {
        debug_assert_ne!(lit, 0);
        Lit(lit)
    }
}

impl std::ops::Not for Lit {
    type Output = Lit;
    fn not(self) -> Lit {
        Lit(-self.0)
    }
}
