//! Inverse kinematics: every solution of the analytic solver (with the extra turns the
//! joint limits allow), or a damped-least-squares solution near a seed.

use std::f64::consts::PI;

use nalgebra::{DMatrix, DVector, Isometry3, Vector6};

use super::{pose_error, JointKind, Robot};

/// An IK solution must reproduce the target to this (m, rad).
pub const IK_TOL: f64 = 1e-9;

/// One inverse-kinematics solution and its arm configuration (analytic solver only).
#[derive(Debug, Clone)]
pub struct Solution {
    pub q: Vec<f64>,
    pub configuration: Option<u8>,
}

impl Robot {
    /// Every solution for a TCP pose within the joint limits. With the analytic solver:
    /// all branches, each joint also with the ±2π turns its limits allow. With the
    /// numeric solver: the solution reached from `seed` (or from a few standard seeds).
    pub fn inverse(&self, tcp: &Isometry3<f64>, seed: Option<&[f64]>) -> Vec<Solution> {
        let tip = tcp * self.tcp.inverse();
        let Some(opw) = self.opw() else {
            let seeds: Vec<Vec<f64>> = match seed {
                Some(s) => vec![s.to_vec()],
                None => self.standard_seeds(),
            };
            let mut out: Vec<Solution> = Vec::new();
            for s in seeds {
                if let Some(q) = self.solve_dls(&tip, &s, 200) {
                    let dup = out.iter().any(|o| max_abs_diff(&o.q, &q) < 1e-6);
                    if !dup {
                        out.push(Solution {
                            q,
                            configuration: None,
                        });
                    }
                }
            }
            return out;
        };
        let mut out = Vec::new();
        for base in opw.inverse(&tip) {
            // Each joint may take its angle plus whole turns inside its limits.
            let options: Vec<Vec<f64>> = base
                .iter()
                .zip(&self.joints)
                .map(|(&v, j)| {
                    let (lo, hi) = if j.is_continuous() {
                        (-2.0 * PI, 2.0 * PI)
                    } else {
                        (j.lower, j.upper)
                    };
                    (-2..=2)
                        .map(|k| v + 2.0 * PI * k as f64)
                        .filter(|x| *x >= lo - 1e-12 && *x <= hi + 1e-12)
                        .map(|x| x.clamp(lo, hi))
                        .collect()
                })
                .collect();
            if options.iter().any(Vec::is_empty) {
                continue;
            }
            let mut idx = [0usize; 6];
            'combos: loop {
                let raw: Vec<f64> = (0..6).map(|i| options[i][idx[i]]).collect();
                // Polish to full precision with a few Newton steps on our own chain; keep
                // it only if it stayed on the analytic solution.
                if let Some(q) = self.solve_dls(&tip, &raw, 8) {
                    let dup = out.iter().any(|o: &Solution| max_abs_diff(&o.q, &q) < 1e-9);
                    if !dup && max_abs_diff(&q, &raw) < 1e-4 {
                        out.push(Solution {
                            configuration: Some(opw.configuration(&q)),
                            q,
                        });
                    }
                }
                for i in 0..6 {
                    idx[i] += 1;
                    if idx[i] < options[i].len() {
                        continue 'combos;
                    }
                    idx[i] = 0;
                }
                break;
            }
        }
        out
    }

    /// Seeds for the numeric solver when there is no previous solution: the middle of the
    /// joint ranges, zero, and a few elbow/wrist variants.
    fn standard_seeds(&self) -> Vec<Vec<f64>> {
        let mid = self.mid_range();
        let mut seeds = vec![mid.clone(), vec![0.0; self.dof()]];
        for (k, &v) in [0.5, -0.5, 1.0, -1.0].iter().enumerate() {
            let mut s = mid.clone();
            for (i, x) in s.iter_mut().enumerate() {
                if (i + k) % 2 == 1 {
                    *x += v;
                }
            }
            seeds.push(s);
        }
        for s in &mut seeds {
            for (x, j) in s.iter_mut().zip(&self.joints) {
                if !j.is_continuous() {
                    *x = x.clamp(j.lower, j.upper);
                }
            }
        }
        seeds
    }

    /// Damped least squares (Levenberg–Marquardt) on the tip pose from `seed`, staying in
    /// the joint limits; `None` unless it converges to [`IK_TOL`].
    pub fn solve_dls(
        &self,
        tip: &Isometry3<f64>,
        seed: &[f64],
        max_iter: usize,
    ) -> Option<Vec<f64>> {
        let n = self.dof();
        let mut q = seed.to_vec();
        self.clamp(&mut q);
        let mut err = self.tip_error(tip, &q);
        let mut lambda = 1e-3;
        for _ in 0..max_iter {
            let (dp, dr) = (err.fixed_rows::<3>(0).norm(), err.fixed_rows::<3>(3).norm());
            if dp < IK_TOL * 0.1 && dr < IK_TOL * 0.1 {
                break;
            }
            let jac = self.jacobian(&q);
            let jt = jac.transpose();
            let mut a = &jac * &jt;
            for i in 0..6 {
                a[(i, i)] += lambda * lambda;
            }
            let e = DVector::from_column_slice(err.as_slice());
            let Some(y) = a.lu().solve(&e) else {
                lambda *= 10.0;
                continue;
            };
            let mut dq = &jt * y;
            let step = dq.amax();
            if step > 0.3 {
                dq *= 0.3 / step;
            }
            let mut trial: Vec<f64> = (0..n).map(|i| q[i] + dq[i]).collect();
            self.clamp(&mut trial);
            let trial_err = self.tip_error(tip, &trial);
            if trial_err.norm() < err.norm() {
                q = trial;
                err = trial_err;
                lambda = (lambda * 0.3).max(1e-9);
            } else {
                lambda *= 10.0;
                if lambda > 1e3 {
                    break;
                }
            }
        }
        let (dp, dr) = pose_error(&self.tip_pose(&q), tip);
        (dp < IK_TOL && dr < IK_TOL).then_some(q)
    }

    fn clamp(&self, q: &mut [f64]) {
        for (x, j) in q.iter_mut().zip(&self.joints) {
            if !j.is_continuous() {
                *x = x.clamp(j.lower, j.upper);
            }
        }
    }

    /// Position error and rotation error (as a rotation vector) of the tip, base frame.
    fn tip_error(&self, target: &Isometry3<f64>, q: &[f64]) -> Vector6<f64> {
        let t = self.tip_pose(q);
        let dp = target.translation.vector - t.translation.vector;
        let dr = (target.rotation * t.rotation.inverse()).scaled_axis();
        Vector6::new(dp.x, dp.y, dp.z, dr.x, dr.y, dr.z)
    }

    /// The geometric Jacobian of the tip origin (rows: linear, angular).
    pub fn jacobian(&self, q: &[f64]) -> DMatrix<f64> {
        let axes = self.joint_axes(q);
        let p = self.tip_pose(q).translation.vector;
        let mut jac = DMatrix::zeros(6, self.dof());
        for (i, (o, a)) in axes.iter().enumerate() {
            let (lin, ang) = match self.joints[i].kind {
                JointKind::Revolute => (a.cross(&(p - o.coords)), a.into_inner()),
                JointKind::Prismatic => (a.into_inner(), nalgebra::Vector3::zeros()),
            };
            jac.fixed_view_mut::<3, 1>(0, i).copy_from(&lin);
            jac.fixed_view_mut::<3, 1>(3, i).copy_from(&ang);
        }
        jac
    }
}

/// The largest absolute difference between two joint vectors.
pub fn max_abs_diff(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}
