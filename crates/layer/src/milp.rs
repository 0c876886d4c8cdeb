//! The paper's mixed-integer formulation, for cross-checking the search on small layers:
//! temperatures of every mesh node at every step are variables tied by the implicit-Euler
//! finite-element equations, binaries choose the trail, and |T − T*| is linearised by
//! one auxiliary variable per node and step. Solved with good_lp's pure-Rust `microlp`.
//!
//! Reduced to what a small cross-check needs: layers that need no deadheading and whose
//! segments all take the same number of steps, so that slot k of the trail (one directed
//! segment) covers steps k·n .. (k+1)·n exactly.

use good_lp::{
    constraint, microlp, variable, variables, Expression, Solution, SolverModel, Variable,
};

use super::model::{Model, Move, Trail};

/// The MILP optimum and its trail.
#[derive(Debug, Clone)]
pub struct MilpResult {
    pub objective: f64,
    pub trail: Trail,
}

/// Solves the layer's trail problem as a MILP.
pub fn solve(model: &Model) -> Result<MilpResult, crate::ModelError> {
    let segs = model.layer.segments.len();
    let n = model.steps[0];
    if model.deadheads != 0 || model.steps.iter().any(|&s| s != n) {
        return Err(
            "the MILP cross-check needs a layer without deadheading whose segments \
                    all take the same number of steps"
                .into(),
        );
    }
    let nodes = model.heat.len();
    let horizon = segs * n;
    // A = M_L + dt (K + R_L) as rows, from the model's own matrices.
    let mats = super::fem::Matrices::assemble(
        &model.mesh,
        model.layer.material.diffusivity_mm2_s,
        model.layer.material.robin_mm_s,
    );
    let dt = model.heat.dt;
    let scale = mats
        .stiffness
        .triplet_iter()
        .filter(|(i, j, _)| i == j)
        .map(|(_, _, v)| v.abs())
        .fold(0.0, f64::max);
    let mut rows: Vec<Vec<(usize, f64)>> = vec![Vec::new(); nodes];
    for (i, j, &v) in mats.stiffness.triplet_iter() {
        if i != j && v.abs() <= 1e-9 * scale {
            continue; // the same rounding residues the stepper drops
        }
        rows[i].push((j, dt * v));
    }
    for (i, row) in rows.iter_mut().enumerate() {
        row.push((i, mats.lumped_mass[i] + dt * mats.lumped_robin[i]));
    }

    let mut vars = variables!();
    // z[k][d]: slot k welds directed segment d = 2 s + reversed.
    let z: Vec<Vec<Variable>> = (0..segs)
        .map(|_| {
            (0..2 * segs)
                .map(|_| vars.add(variable().binary()))
                .collect()
        })
        .collect();
    let u: Vec<Vec<Variable>> = (0..horizon)
        .map(|_| (0..nodes).map(|_| vars.add(variable())).collect())
        .collect();
    let dev: Vec<Vec<Variable>> = (0..horizon)
        .map(|_| (0..nodes).map(|_| vars.add(variable().min(0.0))).collect())
        .collect();
    let objective: Expression = dev.iter().flatten().copied().sum();
    let mut problem = vars.minimise(objective).using(microlp);
    for zk in &z {
        let one: Expression = zk.iter().copied().sum();
        problem = problem.with(constraint!(one == 1.0));
    }
    for s in 0..segs {
        let once: Expression = (0..segs).map(|k| z[k][2 * s] + z[k][2 * s + 1]).sum();
        problem = problem.with(constraint!(once == 1.0));
    }
    for k in 0..segs.saturating_sub(1) {
        for v in 0..model.layer.nodes.len() {
            let arrive: Expression = (0..2 * segs)
                .filter(|&d| model.ends(&Move::directed(d)).1 == v)
                .map(|d| z[k][d])
                .sum();
            let leave: Expression = (0..2 * segs)
                .filter(|&d| model.ends(&Move::directed(d)).0 == v)
                .map(|d| z[k + 1][d])
                .sum();
            problem = problem.with(constraint!(arrive == leave));
        }
    }
    for t in 0..horizon {
        let (k, j) = (t / n, t % n);
        // Heat input of step t: Σ_d z[k][d] dt F(position of d at step j).
        let mut load: Vec<Expression> = vec![Expression::from(0.0); nodes];
        for (d, &zd) in z[k].iter().enumerate() {
            for &(i, f) in &model.loads[model.position(&Move::directed(d), j)] {
                load[i] += dt * f * zd;
            }
        }
        for i in 0..nodes {
            let lhs: Expression = rows[i].iter().map(|&(c, a)| a * u[t][c]).sum();
            let prev: Expression = if t == 0 {
                Expression::from(mats.lumped_mass[i] * model.initial)
            } else {
                mats.lumped_mass[i] * u[t - 1][i]
            };
            let rhs = prev + load[i].clone();
            problem = problem.with(constraint!(lhs == rhs));
            problem = problem.with(constraint!(dev[t][i] >= u[t][i] - model.target));
            problem = problem.with(constraint!(dev[t][i] >= model.target - u[t][i]));
        }
    }
    let solution = problem.solve().map_err(|e| format!("MILP solver: {e}"))?;
    let moves = (0..segs)
        .map(|k| {
            let d = (0..2 * segs)
                .max_by(|&a, &b| solution.value(z[k][a]).total_cmp(&solution.value(z[k][b])))
                .unwrap_or(0);
            Move::directed(d)
        })
        .collect();
    let objective = dev.iter().flatten().map(|&v| solution.value(v)).sum();
    Ok(MilpResult {
        objective,
        trail: Trail { moves },
    })
}
