//! The analytic OPW solver (`rs-opw-kinematics`) fitted to a URDF chain.
//!
//! OPW (Brandstötter, Angerer, Hofbaur 2014) covers 6-axis arms whose joints 2 and 3 are
//! parallel and orthogonal to joint 1 and whose wrist axes 4, 5, 6 meet in one point —
//! most industrial welding robots. [`OpwModel::derive`] reads the seven lengths, the joint
//! offsets and the axis signs off the chain's zero configuration, puts the rest (the
//! flange, the tool) into a fixed transform, and then *verifies* the result by comparing
//! OPW forward kinematics with the URDF chain on many joint vectors: a chain that only
//! looks like an OPW arm is refused and the numeric solver takes over.

use nalgebra::{
    Isometry3, Matrix3, Point3, Quaternion, Rotation3, Translation3, UnitQuaternion, Vector3,
};
use rs_opw_kinematics::glam::{DQuat, DVec3};
use rs_opw_kinematics::kinematic_traits::{Kinematics, Pose};
use rs_opw_kinematics::kinematics_impl::OPWKinematics;
use rs_opw_kinematics::parameters::opw_kinematics::Parameters;

use super::{pose_error, JointKind, Robot};

/// Structural tolerance when reading the chain (m, and cosines of angles).
const GEOMETRY_TOL: f64 = 1e-7;
/// The fitted model must reproduce the chain's FK to this (m, rad).
const VERIFY_TOL: f64 = 1e-9;

/// OPW parameters fitted to a URDF chain, and the transforms around them.
#[derive(Debug, Clone)]
pub struct OpwModel {
    pub parameters: Parameters,
    kinematics: OPWKinematics,
    /// The OPW base frame in the URDF base link.
    base: Isometry3<f64>,
    /// The tip link in the OPW flange frame (the flange sits at the wrist centre: c4 = 0).
    tool: Isometry3<f64>,
    /// Largest FK difference found in verification (m, rad).
    pub verified_error: (f64, f64),
}

fn line_closest(
    p1: &Point3<f64>,
    d1: &Vector3<f64>,
    p2: &Point3<f64>,
    d2: &Vector3<f64>,
) -> Option<(Point3<f64>, Point3<f64>)> {
    // Closest points of two non-parallel lines p1 + s d1, p2 + t d2.
    let r = p1 - p2;
    let (a, b, c) = (d1.dot(d1), d1.dot(d2), d2.dot(d2));
    let (d, e) = (d1.dot(&r), d2.dot(&r));
    let den = a * c - b * b;
    if den.abs() < 1e-12 {
        return None;
    }
    let s = (b * e - c * d) / den;
    let t = (a * e - b * d) / den;
    Some((p1 + d1 * s, p2 + d2 * t))
}

fn to_glam(t: &Isometry3<f64>) -> Pose {
    let v = t.translation.vector;
    let q = t.rotation.quaternion();
    Pose::from_parts(
        DVec3::new(v.x, v.y, v.z),
        DQuat::from_xyzw(q.i, q.j, q.k, q.w),
    )
}

fn from_glam(p: &Pose) -> Isometry3<f64> {
    let (v, q) = (p.translation, p.rotation);
    Isometry3::from_parts(
        Translation3::new(v.x, v.y, v.z),
        UnitQuaternion::from_quaternion(Quaternion::new(q.w, q.x, q.y, q.z)),
    )
}

fn sign(x: f64) -> i8 {
    if x >= 0.0 {
        1
    } else {
        -1
    }
}

/// Why the analytic OPW solver does not fit a robot (the numeric one is used instead).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{0}")]
pub struct OpwUnsupported(pub String);

impl From<String> for OpwUnsupported {
    fn from(message: String) -> Self {
        OpwUnsupported(message)
    }
}

impl From<&str> for OpwUnsupported {
    fn from(message: &str) -> Self {
        OpwUnsupported(message.to_string())
    }
}

impl OpwModel {
    /// Fits OPW parameters to the robot's chain, or says why the chain is not an OPW arm.
    pub fn derive(robot: &Robot) -> Result<OpwModel, OpwUnsupported> {
        if robot.dof() != 6 {
            return Err(OpwUnsupported(format!(
                "the chain has {} movable joints, OPW needs 6",
                robot.dof()
            )));
        }
        if let Some(j) = robot.joints.iter().find(|j| j.kind != JointKind::Revolute) {
            return Err(OpwUnsupported(format!(
                "joint '{}' is not revolute",
                j.name
            )));
        }
        let axes = robot.joint_axes(&[0.0; 6]);
        let (o, a): (Vec<Point3<f64>>, Vec<Vector3<f64>>) =
            axes.iter().map(|(p, d)| (*p, d.into_inner())).unzip();
        let perpendicular = |i: usize, j: usize| a[i].dot(&a[j]).abs() < GEOMETRY_TOL;
        let parallel = |i: usize, j: usize| (a[i].dot(&a[j]).abs() - 1.0).abs() < GEOMETRY_TOL;
        if !perpendicular(0, 1) {
            return Err(OpwUnsupported(
                "joint 2 is not perpendicular to joint 1".into(),
            ));
        }
        if !parallel(1, 2) {
            return Err(OpwUnsupported("joints 2 and 3 are not parallel".into()));
        }
        // OPW base: z along joint 1, x towards joint 2, origin on joint 1 level with the
        // URDF base origin.
        let z = a[0];
        let b0 = o[0] + z * (Point3::origin() - o[0]).dot(&z);
        let (f1, p2) =
            line_closest(&o[0], &a[0], &o[1], &a[1]).ok_or("joints 1 and 2 are parallel")?;
        let r = p2 - f1;
        let x = if r.norm() > GEOMETRY_TOL {
            r.normalize()
        } else {
            a[1].cross(&z).normalize()
        };
        let y = z.cross(&x);
        let rot = Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[x, y, z]));
        let base = Isometry3::from_parts(
            Translation3::from(b0.coords),
            UnitQuaternion::from_rotation_matrix(&rot),
        );
        let local = |p: &Point3<f64>| rot.inverse() * (p - b0);
        let a1 = r.norm();
        let c1 = local(&p2).z;
        // Wrist centre: where axes 4, 5 (and 6) meet.
        let (w4, w5) =
            line_closest(&o[3], &a[3], &o[4], &a[4]).ok_or("joints 4 and 5 are parallel")?;
        if (w4 - w5).norm() > GEOMETRY_TOL {
            return Err(OpwUnsupported(format!(
                "axes 4 and 5 miss each other by {:.3e} m: no spherical wrist",
                (w4 - w5).norm()
            )));
        }
        let w = nalgebra::center(&w4, &w5);
        let off6 = (w - o[5]) - a[5] * (w - o[5]).dot(&a[5]);
        if off6.norm() > GEOMETRY_TOL {
            return Err(OpwUnsupported(format!(
                "axis 6 misses the wrist centre by {:.3e} m: no spherical wrist",
                off6.norm()
            )));
        }
        let wl = local(&w);
        let b = wl.y;
        // Joint 3's axis where it crosses the arm plane y = b.
        let a3l = rot.inverse() * a[2];
        let o3l = local(&o[2]);
        let t = (b - o3l.y) / a3l.y;
        let p3 = o3l + a3l * t;
        let upper = Vector3::new(p3.x - a1, 0.0, p3.z - c1);
        let c2 = upper.norm();
        let theta2 = upper.x.atan2(upper.z);
        let sign2 = sign(a[1].dot(&y));
        let sign3 = sign(a[2].dot(&y));
        // Forearm: along joint 4's axis (c3) and across it (a2).
        let a4l = rot.inverse() * a[3];
        if a4l.y.abs() > GEOMETRY_TOL {
            return Err(OpwUnsupported(
                "joint 4 is not perpendicular to joints 2 and 3".into(),
            ));
        }
        let fore = wl - p3;
        let sign4 = sign(fore.dot(&a4l));
        let d4 = a4l * sign4 as f64;
        let theta23 = d4.x.atan2(d4.z);
        let n4 = Vector3::new(theta23.cos(), 0.0, -theta23.sin());
        let c3 = fore.dot(&d4);
        let a2 = fore.dot(&n4);
        let theta3 = theta23 - theta2;
        // Wrist angles at the zero configuration (in the OPW base frame).
        let a5l = rot.inverse() * a[4];
        let a6l = rot.inverse() * a[5];
        if a5l.dot(&d4).abs() > GEOMETRY_TOL || a6l.dot(&a5l).abs() > GEOMETRY_TOL {
            return Err(OpwUnsupported(
                "the wrist axes are not mutually orthogonal".into(),
            ));
        }
        let (x3, y3) = (n4, Vector3::y());
        let theta4 = (-a5l.dot(&x3)).atan2(a5l.dot(&y3));
        let x4 = x3 * theta4.cos() + y3 * theta4.sin();
        let theta5 = a6l.dot(&x4).atan2(a6l.dot(&d4));
        let parameters = Parameters {
            a1,
            a2,
            b,
            c1,
            c2,
            c3,
            c4: 0.0,
            offsets: [0.0, -theta2, -theta3, -theta4, -theta5, 0.0],
            sign_corrections: [1, sign2, sign3, sign4, 1, 1],
            dof: 6,
        };
        // rs-opw-kinematics panics on a non-finite parameter: refuse it here instead.
        let lengths = [a1, a2, b, c1, c2, c3];
        if lengths
            .iter()
            .chain(&parameters.offsets)
            .any(|v| !v.is_finite())
        {
            return Err(OpwUnsupported(
                "the chain's lengths or offsets are not finite".into(),
            ));
        }
        let kinematics = OPWKinematics::new(parameters);
        let flange0 = from_glam(&kinematics.forward(&[0.0; 6]));
        let tool = flange0.inverse() * base.inverse() * robot.tip_pose(&[0.0; 6]);
        let mut model = OpwModel {
            parameters,
            kinematics,
            base,
            tool,
            verified_error: (0.0, 0.0),
        };
        // Verify on a deterministic spread of joint vectors inside the limits.
        let mut seed = 0x9e37_79b9_7f4a_7c15_u64;
        let mut unit = || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        for _ in 0..200 {
            let q: Vec<f64> = robot
                .joints
                .iter()
                .map(|j| {
                    let (lo, hi) = if j.is_continuous() {
                        (-std::f64::consts::PI, std::f64::consts::PI)
                    } else {
                        (j.lower, j.upper)
                    };
                    lo + (hi - lo) * unit()
                })
                .collect();
            let (dp, dr) = pose_error(&model.tip_pose(&q), &robot.tip_pose(&q));
            model.verified_error.0 = model.verified_error.0.max(dp);
            model.verified_error.1 = model.verified_error.1.max(dr);
        }
        if model.verified_error.0 > VERIFY_TOL || model.verified_error.1 > VERIFY_TOL {
            return Err(OpwUnsupported(format!(
                "fitted OPW parameters miss the URDF chain by {:.2e} m / {:.2e} rad",
                model.verified_error.0, model.verified_error.1
            )));
        }
        Ok(model)
    }

    /// The tip link's pose by OPW forward kinematics (for verification).
    pub fn tip_pose(&self, q: &[f64]) -> Isometry3<f64> {
        let q: [f64; 6] = std::array::from_fn(|i| q[i]);
        self.base * from_glam(&self.kinematics.forward(&q)) * self.tool
    }

    /// Every analytic solution for a tip-link pose (no limits applied, angles near 0).
    pub fn inverse(&self, tip: &Isometry3<f64>) -> Vec<[f64; 6]> {
        let flange = self.base.inverse() * tip * self.tool.inverse();
        self.kinematics.inverse(&to_glam(&flange))
    }

    /// The arm configuration of a joint vector: shoulder (front/back), elbow (up/down),
    /// wrist (flip/no flip) as three bits. A path that keeps its configuration moves
    /// continuously; a change needs a singular pose in between.
    pub fn configuration(&self, q: &[f64]) -> u8 {
        let p = &self.parameters;
        let t: [f64; 6] =
            std::array::from_fn(|i| q[i] * p.sign_corrections[i] as f64 - p.offsets[i]);
        let psi3 = p.a2.atan2(p.c3);
        let k = (p.a2 * p.a2 + p.c3 * p.c3).sqrt();
        let radial = p.c2 * t[1].sin() + k * (t[1] + t[2] + psi3).sin() + p.a1;
        let elbow = (t[2] + psi3).sin();
        let wrist = t[4].sin();
        (radial < 0.0) as u8 | ((elbow < 0.0) as u8) << 1 | ((wrist < 0.0) as u8) << 2
    }
}
