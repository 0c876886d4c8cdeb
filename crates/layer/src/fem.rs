//! Linear-triangle finite elements for dT/dt = a ΔT + q with -a dT/dn = b (T - T_amb),
//! stepped by implicit Euler with one sparse Cholesky factorization for all steps.
//!
//! Written for the deviation u = T - T_amb, the Robin term has no constant part (the
//! stiffness matrix annihilates constants and the boundary matrix maps the constant
//! T_amb onto exactly the ambient load), so every step is the *linear* map
//! u' = A⁻¹ (M u + dt F), A = M + dt (K + R). The time stepper uses the row-sum lumped
//! mass and boundary matrices: with them A has no positive off-diagonal entry on meshes
//! without obtuse angles, so A⁻¹ ≥ 0 and heat input never lowers a temperature — the
//! property the optimizer's lower bound relies on (and checks, see [`Heat::monotone`]).

use nalgebra_sparse::factorization::CscCholesky;
use nalgebra_sparse::{CooMatrix, CscMatrix};

use super::mesh::Mesh;

/// Assembled finite-element matrices of a mesh (coordinate lists, duplicates summed).
#[derive(Debug, Clone)]
pub struct Matrices {
    /// Consistent mass matrix ∫ φi φj.
    pub mass: CscMatrix<f64>,
    /// Stiffness matrix a ∫ ∇φi·∇φj.
    pub stiffness: CscMatrix<f64>,
    /// Consistent Robin boundary matrix b ∫∂ φi φj.
    pub robin: CscMatrix<f64>,
    /// Row sums of the mass matrix (lumped mass, mm² per node).
    pub lumped_mass: Vec<f64>,
    /// Row sums of the Robin matrix.
    pub lumped_robin: Vec<f64>,
}

impl Matrices {
    pub fn assemble(mesh: &Mesh, diffusivity: f64, robin: f64) -> Matrices {
        let n = mesh.points.len();
        let mut mass = CooMatrix::new(n, n);
        let mut stiff = CooMatrix::new(n, n);
        let mut rob = CooMatrix::new(n, n);
        let mut lumped_mass = vec![0.0; n];
        let mut lumped_robin = vec![0.0; n];
        for (t, tri) in mesh.triangles.iter().enumerate() {
            let area = mesh.area(t);
            let p = tri.map(|i| mesh.points[i]);
            // Gradients of the barycentric basis functions: (y_j - y_k, x_k - x_j) / 2A.
            let grad: [[f64; 2]; 3] = std::array::from_fn(|i| {
                let (j, k) = ((i + 1) % 3, (i + 2) % 3);
                [
                    (p[j][1] - p[k][1]) / (2.0 * area),
                    (p[k][0] - p[j][0]) / (2.0 * area),
                ]
            });
            for i in 0..3 {
                for j in 0..3 {
                    let m = area / 12.0 * if i == j { 2.0 } else { 1.0 };
                    mass.push(tri[i], tri[j], m);
                    lumped_mass[tri[i]] += m;
                    let k =
                        diffusivity * area * (grad[i][0] * grad[j][0] + grad[i][1] * grad[j][1]);
                    stiff.push(tri[i], tri[j], k);
                }
            }
        }
        for &[a, b] in &mesh.boundary {
            let (p, q) = (mesh.points[a], mesh.points[b]);
            let len = ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2)).sqrt();
            for (i, j) in [(a, a), (a, b), (b, a), (b, b)] {
                let r = robin * len / 6.0 * if i == j { 2.0 } else { 1.0 };
                rob.push(i, j, r);
                lumped_robin[i] += r;
            }
        }
        Matrices {
            mass: CscMatrix::from(&mass),
            stiffness: CscMatrix::from(&stiff),
            robin: CscMatrix::from(&rob),
            lumped_mass,
            lumped_robin,
        }
    }
}

/// A Cholesky factor L (A = L Lᵀ), stored for solves by contiguous, vectorizable loops:
/// by column envelope for L (column j densely from its diagonal to its last nonzero) and by
/// row envelope for Lᵀ (row i densely from its first nonzero to just before the diagonal),
/// zeros included. The mesh's reverse Cuthill–McKee numbering keeps both close to L's own
/// nonzeros (Cholesky fills the profile anyway); a zero changes nothing (`x − 0·y = x`).
#[derive(Debug, Clone)]
struct Factor {
    /// Column j of L is `columns[col_start[j]..col_start[j + 1]]`, its diagonal first.
    col_start: Vec<usize>,
    columns: Vec<f64>,
    /// Row i of L left of the diagonal is `rows[row_start[i]..row_start[i + 1]]`, from
    /// column `row_first[i]`.
    row_start: Vec<usize>,
    row_first: Vec<usize>,
    rows: Vec<f64>,
    /// Nonzeros of L.
    nnz: usize,
}

impl Factor {
    fn new(a: &CscMatrix<f64>) -> Result<Factor, crate::ModelError> {
        let chol =
            CscCholesky::factor(a).map_err(|e| format!("Cholesky factorization failed: {e:?}"))?;
        let l = chol.take_l();
        let (cs, row_of, vals) = l.disassemble();
        let n = cs.len() - 1;
        let mut col_start = Vec::with_capacity(n + 1);
        let mut columns = Vec::new();
        let mut row_first: Vec<usize> = (0..n).collect();
        for j in 0..n {
            // Each column must start with its diagonal entry (rows sorted, lower triangle).
            let (start, end) = (cs[j], cs[j + 1]);
            if start == end || row_of[start] != j {
                return Err(crate::ModelError(format!(
                    "Cholesky factor column {j} has no leading diagonal"
                )));
            }
            col_start.push(columns.len());
            let base = columns.len();
            columns.resize(base + row_of[end - 1] - j + 1, 0.0);
            for k in start..end {
                columns[base + row_of[k] - j] = vals[k];
                row_first[row_of[k]] = row_first[row_of[k]].min(j);
            }
        }
        col_start.push(columns.len());
        let mut row_start = Vec::with_capacity(n + 1);
        let mut rows = Vec::new();
        for (i, &first) in row_first.iter().enumerate() {
            row_start.push(rows.len());
            rows.resize(rows.len() + i - first, 0.0);
        }
        row_start.push(rows.len());
        for j in 0..n {
            for k in cs[j] + 1..cs[j + 1] {
                let i = row_of[k];
                rows[row_start[i] + j - row_first[i]] = vals[k];
            }
        }
        Ok(Factor {
            col_start,
            columns,
            row_start,
            row_first,
            rows,
            nnz: vals.len(),
        })
    }

    /// Solves L Lᵀ x = b in place: L by columns, then Lᵀ by the rows of L (each solved
    /// entry is subtracted from the entries before it, an axpy instead of a dot product
    /// whose every step waits for the last).
    fn solve(&self, x: &mut [f64]) {
        let n = x.len();
        for j in 0..n {
            let col = &self.columns[self.col_start[j]..self.col_start[j + 1]];
            let xj = x[j] / col[0];
            x[j] = xj;
            for (xi, l) in x[j + 1..j + col.len()].iter_mut().zip(&col[1..]) {
                *xi -= l * xj;
            }
        }
        for i in (0..n).rev() {
            let xi = x[i] / self.columns[self.col_start[i]];
            x[i] = xi;
            let row = &self.rows[self.row_start[i]..self.row_start[i + 1]];
            for (xj, l) in x[self.row_first[i]..i].iter_mut().zip(row) {
                *xj -= l * xi;
            }
        }
    }

    fn nnz(&self) -> usize {
        self.nnz
    }
}

/// The implicit-Euler heat stepper for the deviation from ambient u = T - T_amb.
#[derive(Debug, Clone)]
pub struct Heat {
    pub dt: f64,
    pub lumped_mass: Vec<f64>,
    factor: Factor,
    /// True when A has no positive off-diagonal entry: then A⁻¹ ≥ 0 and every step is
    /// monotone (more heat in never means a lower temperature anywhere).
    pub monotone: bool,
    /// Stiffness plus lumped Robin matrix, kept for steady states.
    k_plus_r: CscMatrix<f64>,
}

impl Heat {
    pub fn new(m: &Matrices, dt: f64) -> Result<Heat, crate::ModelError> {
        let n = m.lumped_mass.len();
        let scale = m
            .stiffness
            .triplet_iter()
            .filter(|(i, j, _)| i == j)
            .map(|(_, _, v)| v.abs())
            .fold(0.0, f64::max);
        let mut coo = CooMatrix::new(n, n);
        let mut kr = CooMatrix::new(n, n);
        let mut monotone = true;
        for (i, j, &v) in m.stiffness.triplet_iter() {
            // Right angles give exact zeros that rounding turns into ±1e-16: drop them.
            if i != j && v.abs() <= 1e-9 * scale {
                continue;
            }
            monotone &= i == j || v < 0.0;
            coo.push(i, j, dt * v);
            kr.push(i, j, v);
        }
        for i in 0..n {
            coo.push(i, i, m.lumped_mass[i] + dt * m.lumped_robin[i]);
            kr.push(i, i, m.lumped_robin[i]);
        }
        let a = CscMatrix::from(&coo);
        Ok(Heat {
            dt,
            lumped_mass: m.lumped_mass.clone(),
            factor: Factor::new(&a)?,
            monotone,
            k_plus_r: CscMatrix::from(&kr),
        })
    }

    pub fn len(&self) -> usize {
        self.lumped_mass.len()
    }

    pub fn is_empty(&self) -> bool {
        self.lumped_mass.is_empty()
    }

    /// Non-zeros of the Cholesky factor.
    pub fn factor_nnz(&self) -> usize {
        self.factor.nnz()
    }

    /// One step: u ← A⁻¹ (M u + dt F), F given sparsely as (node, load) pairs.
    pub fn step(&self, u: &mut [f64], load: &[(usize, f64)]) {
        for (ui, m) in u.iter_mut().zip(&self.lumped_mass) {
            *ui *= m;
        }
        for &(i, f) in load {
            u[i] += self.dt * f;
        }
        self.factor.solve(u);
    }

    /// One step of the adjoint: a ← M A⁻¹ a (Gᵀ for G = A⁻¹ M, both matrices symmetric).
    pub fn adjoint_step(&self, a: &mut [f64]) {
        self.factor.solve(a);
        for (ai, m) in a.iter_mut().zip(&self.lumped_mass) {
            *ai *= m;
        }
    }

    /// Solves A x = b in place.
    pub fn solve(&self, x: &mut [f64]) {
        self.factor.solve(x);
    }

    /// The steady state of the discrete system under a constant load: (K + R) u = F.
    pub fn steady_state(&self, load: &[(usize, f64)]) -> Result<Vec<f64>, crate::ModelError> {
        let factor = Factor::new(&self.k_plus_r)?;
        let mut u = vec![0.0; self.len()];
        for &(i, f) in load {
            u[i] += f;
        }
        factor.solve(&mut u);
        Ok(u)
    }
}
