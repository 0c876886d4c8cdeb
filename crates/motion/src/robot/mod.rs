//! The welding robot: a serial chain read from URDF, forward kinematics and inverse
//! kinematics on `nalgebra`.
//!
//! [`Robot::from_urdf`] keeps only what kinematics needs: the chain of joints from the
//! root link to the tip link (meshes, inertia and materials are never opened, so a URDF
//! whose meshes are absent on disk loads fine). The tool-centre point (TCP) is a fixed
//! pose in the tip link. Inverse kinematics is analytic (OPW, through `rs-opw-kinematics`)
//! when the chain is an ortho-parallel arm with a spherical wrist — checked, not assumed —
//! and a damped-least-squares solver otherwise; see [`ik`].

pub mod ik;
pub mod limits;
pub mod opw;

use std::collections::HashMap;
use std::f64::consts::PI;

use nalgebra::{Isometry3, Point3, Translation3, Unit, UnitQuaternion, Vector3};
use thiserror::Error;

/// Largest joint offset or TCP distance accepted (m). A welding cell is a few metres; far
/// larger numbers are typing errors, and numbers near f64's range overflow in the
/// kinematics (and panic inside rs-opw-kinematics).
pub const MAX_OFFSET_M: f64 = 1000.0;
/// Largest angle accepted in an origin or a joint limit (rad): more than a few turns is a
/// typing error, and sin/cos of huge angles carry no precision.
pub const MAX_ANGLE_RAD: f64 = 1000.0;
/// Deepest element nesting accepted in a URDF. Real ones nest 4–6 deep; urdf-rs parses
/// recursively, so a file nested tens of thousands deep would overflow the stack.
pub const MAX_URDF_DEPTH: usize = 64;

/// A URDF that cannot serve as a welding robot, naming the link or joint at fault.
#[derive(Debug, Error)]
pub enum RobotError {
    #[error("cannot read URDF: {0}")]
    Urdf(String),
    #[error("the URDF has no links")]
    NoLinks,
    #[error("the URDF has {0} root links ({1}); a robot needs exactly one")]
    Roots(usize, String),
    #[error("tip link '{0}' is not a link of the URDF")]
    UnknownTip(String),
    #[error("cannot choose the tip link: the chains end in {0}; name one with --tip")]
    AmbiguousTip(String),
    #[error("link '{0}' is the child of more than one joint")]
    TwoParents(String),
    #[error("joint '{joint}': {reason}")]
    Joint { joint: String, reason: String },
    #[error("the chain from '{base}' to '{tip}' has no movable joint")]
    NoJoints { base: String, tip: String },
    #[error("joint '{joint}': its {role} link '{link}' is not a link of the URDF")]
    MissingLink {
        joint: String,
        role: &'static str,
        link: String,
    },
    #[error("the URDF nests elements more than {MAX_URDF_DEPTH} deep (line {line})")]
    TooDeep { line: usize },
}

/// Refuses XML nested deeper than [`MAX_URDF_DEPTH`] before urdf-rs's recursive parser sees
/// it. quick-xml reads as a stream, so the check itself needs no stack.
fn check_depth(text: &str) -> Result<(), RobotError> {
    use quick_xml::events::Event;
    let mut reader = quick_xml::Reader::from_str(text);
    let mut depth = 0usize;
    loop {
        match reader.read_event() {
            Ok(Event::Start(_)) => {
                depth += 1;
                if depth > MAX_URDF_DEPTH {
                    let at = reader.buffer_position() as usize;
                    let line = 1 + text.as_bytes()[..at.min(text.len())]
                        .iter()
                        .filter(|&&b| b == b'\n')
                        .count();
                    return Err(RobotError::TooDeep { line });
                }
            }
            Ok(Event::End(_)) => depth = depth.saturating_sub(1),
            Ok(Event::Eof) => return Ok(()),
            Ok(_) => {}
            // Not well-formed: urdf-rs says why, and it has not nested deep before here.
            Err(_) => return Ok(()),
        }
    }
}

/// A joint origin whose numbers cannot be right.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
enum OriginError {
    #[error("origin has a non-finite value")]
    NotFinite,
    #[error("origin xyz {0:e} m is beyond {max} m (a typing error?)", max = MAX_OFFSET_M)]
    Offset(f64),
    #[error("origin rpy {0:e} rad is beyond {max} rad", max = MAX_ANGLE_RAD)]
    Angle(f64),
}

/// A joint origin's numbers: finite and within [`MAX_OFFSET_M`] / [`MAX_ANGLE_RAD`].
fn check_origin(xyz: &[f64; 3], rpy: &[f64; 3]) -> Result<(), OriginError> {
    if xyz.iter().chain(rpy).any(|v| !v.is_finite()) {
        return Err(OriginError::NotFinite);
    }
    if let Some(v) = xyz.iter().find(|v| v.abs() > MAX_OFFSET_M) {
        return Err(OriginError::Offset(*v));
    }
    if let Some(v) = rpy.iter().find(|v| v.abs() > MAX_ANGLE_RAD) {
        return Err(OriginError::Angle(*v));
    }
    Ok(())
}

/// How a movable joint moves.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum JointKind {
    /// Rotation about the axis, radians.
    Revolute,
    /// Translation along the axis, metres.
    Prismatic,
}

/// A movable joint of the chain with its limits (URDF units: rad, m, rad/s, m/s).
#[derive(Debug, Clone)]
pub struct Joint {
    pub name: String,
    pub kind: JointKind,
    /// The axis in the joint frame.
    pub axis: Unit<Vector3<f64>>,
    /// Position limits; infinite for a continuous joint.
    pub lower: f64,
    pub upper: f64,
    /// Velocity limit (> 0): the URDF's, or a joint limits file's.
    pub velocity: f64,
    /// Acceleration limit (> 0), from a joint limits file; `None`: unlimited.
    pub acceleration: Option<f64>,
}

impl Joint {
    /// True when `q` lies within the position limits (to `tol`).
    pub fn within(&self, q: f64, tol: f64) -> bool {
        q >= self.lower - tol && q <= self.upper + tol
    }

    /// True for a joint without position limits.
    pub fn is_continuous(&self) -> bool {
        !self.lower.is_finite() || !self.upper.is_finite()
    }
}

/// One step from the root link to the tip: a fixed transform, then (maybe) a joint motion.
#[derive(Debug, Clone)]
struct Step {
    origin: Isometry3<f64>,
    /// Index into [`Robot::joints`]; `None` for a fixed joint.
    joint: Option<usize>,
}

/// Which inverse-kinematics solver to use.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Solver {
    /// The analytic OPW solver when the chain fits it, damped least squares otherwise.
    #[default]
    Auto,
    /// Damped least squares only (for comparison and for arms OPW does not fit).
    Numeric,
}

/// A serial robot: the joints from the base link to the tip link, and the TCP in the tip.
#[derive(Debug, Clone)]
pub struct Robot {
    pub name: String,
    pub base_link: String,
    pub tip_link: String,
    /// The movable joints, base to tip; a joint vector is in this order.
    pub joints: Vec<Joint>,
    steps: Vec<Step>,
    /// The TCP in the tip link.
    pub tcp: Isometry3<f64>,
    opw: Option<opw::OpwModel>,
    /// Why the analytic solver does not apply, when it does not.
    pub opw_reason: Option<String>,
    solver: Solver,
}

/// Where the TCP comes from: [`Robot::from_urdf`] uses `explicit` when given, no offset
/// when the tip link is named `tcp` (the URDF carries its torch), else `default`.
#[derive(Debug, Clone, Copy)]
pub struct TcpChoice {
    pub explicit: Option<Isometry3<f64>>,
    pub default: Isometry3<f64>,
}

impl Robot {
    /// Reads a URDF file. `tip`: the link the TCP is attached to (default: a link named
    /// `tcp`, else the end of the longest chain).
    pub fn from_urdf_file(
        path: &std::path::Path,
        tip: Option<&str>,
        tcp: TcpChoice,
    ) -> Result<Robot, RobotError> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| RobotError::Urdf(format!("{}: {e}", path.display())))?;
        Robot::from_urdf(&text, tip, tcp)
    }

    /// Reads URDF text; see [`Robot::from_urdf_file`].
    pub fn from_urdf(text: &str, tip: Option<&str>, tcp: TcpChoice) -> Result<Robot, RobotError> {
        check_depth(text)?;
        let urdf = urdf_rs::read_from_string(text).map_err(|e| RobotError::Urdf(e.to_string()))?;
        if urdf.links.is_empty() {
            return Err(RobotError::NoLinks);
        }
        let links: std::collections::HashSet<&str> =
            urdf.links.iter().map(|l| l.name.as_str()).collect();
        let mut parent_joint: HashMap<&str, &urdf_rs::Joint> = HashMap::new();
        for j in &urdf.joints {
            // A joint hanging from a link nobody defined would silently cut the chain there.
            for (role, link) in [("parent", &j.parent.link), ("child", &j.child.link)] {
                if !links.contains(link.as_str()) {
                    return Err(RobotError::MissingLink {
                        joint: j.name.clone(),
                        role,
                        link: link.clone(),
                    });
                }
            }
            if parent_joint.insert(j.child.link.as_str(), j).is_some() {
                return Err(RobotError::TwoParents(j.child.link.clone()));
            }
        }
        let roots: Vec<&str> = urdf
            .links
            .iter()
            .map(|l| l.name.as_str())
            .filter(|l| !parent_joint.contains_key(l))
            .collect();
        if roots.len() != 1 {
            return Err(RobotError::Roots(roots.len(), roots.join(", ")));
        }
        let base = roots[0].to_string();
        // The chain of joints from a link up to the root (guarding against cycles).
        let chain_to = |link: &str| -> Result<Vec<&urdf_rs::Joint>, RobotError> {
            let mut chain = Vec::new();
            let mut at = link;
            while let Some(j) = parent_joint.get(at) {
                chain.push(*j);
                if chain.len() > parent_joint.len() {
                    return Err(RobotError::Joint {
                        joint: j.name.clone(),
                        reason: "the joints form a cycle".into(),
                    });
                }
                at = j.parent.link.as_str();
            }
            chain.reverse();
            Ok(chain)
        };
        let is_movable = |j: &&&urdf_rs::Joint| j.joint_type != urdf_rs::JointType::Fixed;
        let tip = match tip {
            Some(t) => {
                if !urdf.links.iter().any(|l| l.name == t) {
                    return Err(RobotError::UnknownTip(t.to_string()));
                }
                t.to_string()
            }
            None if urdf.links.iter().any(|l| l.name == "tcp") => "tcp".to_string(),
            None => {
                // Leaves with the most movable joints on their chain; one must win.
                let has_child: std::collections::HashSet<&str> =
                    urdf.joints.iter().map(|j| j.parent.link.as_str()).collect();
                let mut best: Vec<(usize, &str)> = Vec::new();
                for l in urdf.links.iter().map(|l| l.name.as_str()) {
                    if has_child.contains(l) {
                        continue;
                    }
                    let n = chain_to(l)?.iter().filter(is_movable).count();
                    match best.first() {
                        Some(&(m, _)) if n < m => {}
                        Some(&(m, _)) if n == m => best.push((n, l)),
                        _ => best = vec![(n, l)],
                    }
                }
                if best.len() != 1 {
                    let names: Vec<&str> = best.iter().map(|b| b.1).collect();
                    return Err(RobotError::AmbiguousTip(names.join(", ")));
                }
                best[0].1.to_string()
            }
        };
        let mut joints = Vec::new();
        let mut steps = Vec::new();
        for j in chain_to(&tip)? {
            let bad = |reason: String| RobotError::Joint {
                joint: j.name.clone(),
                reason,
            };
            let o = &j.origin;
            check_origin(&o.xyz.0, &o.rpy.0).map_err(|e| bad(e.to_string()))?;
            let origin = Isometry3::from_parts(
                Translation3::new(o.xyz.0[0], o.xyz.0[1], o.xyz.0[2]),
                UnitQuaternion::from_euler_angles(o.rpy.0[0], o.rpy.0[1], o.rpy.0[2]),
            );
            use urdf_rs::JointType as T;
            let kind = match j.joint_type {
                T::Fixed => {
                    steps.push(Step {
                        origin,
                        joint: None,
                    });
                    continue;
                }
                T::Revolute | T::Continuous => JointKind::Revolute,
                T::Prismatic => JointKind::Prismatic,
                ref other => {
                    return Err(bad(format!(
                        "type {other:?} is not a joint of a serial arm"
                    )))
                }
            };
            if j.mimic.is_some() {
                return Err(bad("mimic joints are not supported".into()));
            }
            let a = Vector3::from(j.axis.xyz.0);
            if !(a.iter().all(|v| v.is_finite()) && a.norm() > 1e-12) {
                return Err(bad(format!("axis {:?} is not a direction", j.axis.xyz.0)));
            }
            let (lower, upper) = if j.joint_type == T::Continuous {
                (f64::NEG_INFINITY, f64::INFINITY)
            } else {
                let (lo, hi) = (j.limit.lower, j.limit.upper);
                if !(lo.is_finite() && hi.is_finite() && lo < hi) {
                    return Err(bad(format!(
                        "needs finite position limits lower < upper, got lower={lo} upper={hi}"
                    )));
                }
                let most = match kind {
                    JointKind::Revolute => MAX_ANGLE_RAD,
                    JointKind::Prismatic => MAX_OFFSET_M,
                };
                if lo.abs() > most || hi.abs() > most {
                    return Err(bad(format!(
                        "position limits lower={lo} upper={hi} reach beyond ±{most}"
                    )));
                }
                (lo, hi)
            };
            let velocity = j.limit.velocity;
            if !(velocity.is_finite() && velocity > 0.0) {
                return Err(bad(format!(
                    "needs a velocity limit > 0 to time a trajectory, got {velocity}"
                )));
            }
            steps.push(Step {
                origin,
                joint: Some(joints.len()),
            });
            joints.push(Joint {
                name: j.name.clone(),
                kind,
                axis: Unit::new_normalize(a),
                lower,
                upper,
                velocity,
                acceleration: None,
            });
        }
        if joints.is_empty() {
            return Err(RobotError::NoJoints { base, tip });
        }
        let tcp = match tcp.explicit {
            Some(t) if t.translation.vector.norm() > MAX_OFFSET_M => {
                return Err(RobotError::Urdf(format!(
                    "the TCP is {} m from the tip link, beyond {MAX_OFFSET_M} m",
                    t.translation.vector.norm()
                )))
            }
            Some(t) => t,
            None if tip == "tcp" => Isometry3::identity(),
            None => tcp.default,
        };
        let mut robot = Robot {
            name: urdf.name.clone(),
            base_link: base,
            tip_link: tip,
            joints,
            steps,
            tcp,
            opw: None,
            opw_reason: None,
            solver: Solver::Auto,
        };
        match opw::OpwModel::derive(&robot) {
            Ok(model) => robot.opw = Some(model),
            Err(reason) => robot.opw_reason = Some(reason.0),
        }
        Ok(robot)
    }

    /// Chooses the IK solver (the analytic one is used only where it was verified).
    pub fn with_solver(mut self, solver: Solver) -> Robot {
        self.solver = solver;
        self
    }

    /// The OPW model, when the chain is an OPW arm and the analytic solver is chosen.
    pub fn opw(&self) -> Option<&opw::OpwModel> {
        match self.solver {
            Solver::Auto => self.opw.as_ref(),
            Solver::Numeric => None,
        }
    }

    /// Number of movable joints.
    pub fn dof(&self) -> usize {
        self.joints.len()
    }

    /// Joint names, base to tip.
    pub fn joint_names(&self) -> Vec<String> {
        self.joints.iter().map(|j| j.name.clone()).collect()
    }

    /// The tip link's pose in the base link for joint positions `q`.
    pub fn tip_pose(&self, q: &[f64]) -> Isometry3<f64> {
        let mut t = Isometry3::identity();
        for s in &self.steps {
            t *= s.origin;
            if let Some(i) = s.joint {
                t *= self.motion(i, q[i]);
            }
        }
        t
    }

    /// The TCP's pose in the base link for joint positions `q`.
    pub fn tcp_pose(&self, q: &[f64]) -> Isometry3<f64> {
        self.tip_pose(q) * self.tcp
    }

    fn motion(&self, i: usize, q: f64) -> Isometry3<f64> {
        let j = &self.joints[i];
        match j.kind {
            JointKind::Revolute => Isometry3::from_parts(
                Translation3::identity(),
                UnitQuaternion::from_axis_angle(&j.axis, q),
            ),
            JointKind::Prismatic => {
                Isometry3::translation(j.axis.x * q, j.axis.y * q, j.axis.z * q)
            }
        }
    }

    /// Every movable joint's axis line in the base frame (point, direction) for `q`.
    pub fn joint_axes(&self, q: &[f64]) -> Vec<(Point3<f64>, Unit<Vector3<f64>>)> {
        let mut t = Isometry3::identity();
        let mut out = Vec::with_capacity(self.joints.len());
        for s in &self.steps {
            t *= s.origin;
            if let Some(i) = s.joint {
                let p = t * Point3::origin();
                out.push((
                    p,
                    Unit::new_normalize(t.rotation * self.joints[i].axis.into_inner()),
                ));
                t *= self.motion(i, q[i]);
            }
        }
        out
    }

    /// True when every joint is within its limits (to `tol`).
    pub fn within_limits(&self, q: &[f64], tol: f64) -> bool {
        self.joints.iter().zip(q).all(|(j, &v)| j.within(v, tol))
    }

    /// The middle of every joint's range (0 for continuous joints).
    pub fn mid_range(&self) -> Vec<f64> {
        self.joints
            .iter()
            .map(|j| {
                if j.is_continuous() {
                    0.0
                } else {
                    0.5 * (j.lower + j.upper)
                }
            })
            .collect()
    }
}

/// Position and rotation distance between two poses (m, rad).
pub fn pose_error(a: &Isometry3<f64>, b: &Isometry3<f64>) -> (f64, f64) {
    let dp = (a.translation.vector - b.translation.vector).norm();
    let dr = a.rotation.angle_to(&b.rotation);
    (dp, dr)
}

/// Text that is not six numbers "x y z roll pitch yaw".
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{0}")]
pub struct PoseParseError(pub String);

impl From<String> for PoseParseError {
    fn from(message: String) -> Self {
        PoseParseError(message)
    }
}

impl From<&str> for PoseParseError {
    fn from(message: &str) -> Self {
        PoseParseError(message.to_string())
    }
}

/// A pose from "x y z roll pitch yaw" (m, rad), as `--tcp` takes it.
pub fn parse_xyz_rpy(text: &str) -> Result<Isometry3<f64>, PoseParseError> {
    let v: Vec<f64> = text
        .split(|c: char| c.is_whitespace() || c == ',')
        .filter(|s| !s.is_empty())
        .map(|s| {
            s.parse::<f64>()
                .map_err(|_| format!("'{s}' is not a number"))
        })
        .collect::<Result<_, _>>()?;
    if v.len() != 6 || v.iter().any(|x| !x.is_finite()) {
        return Err(PoseParseError(format!(
            "expected 6 finite numbers \"x y z roll pitch yaw\" (m, rad), got {} value(s)",
            v.len()
        )));
    }
    if v[..3].iter().any(|x| x.abs() > MAX_OFFSET_M)
        || v[3..].iter().any(|x| x.abs() > MAX_ANGLE_RAD)
    {
        return Err(PoseParseError(format!(
            "\"{text}\": x y z within ±{MAX_OFFSET_M} m and angles within ±{MAX_ANGLE_RAD} rad"
        )));
    }
    Ok(xyz_rpy(&[v[0], v[1], v[2]], &[v[3], v[4], v[5]]))
}

/// A pose from a translation and URDF roll-pitch-yaw angles (rad).
pub fn xyz_rpy(xyz: &[f64; 3], rpy: &[f64; 3]) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(xyz[0], xyz[1], xyz[2]),
        UnitQuaternion::from_euler_angles(rpy[0], rpy[1], rpy[2]),
    )
}

/// Wraps an angle to (-π, π].
pub fn wrap(a: f64) -> f64 {
    let r = (a + PI).rem_euclid(2.0 * PI) - PI;
    if r <= -PI {
        r + 2.0 * PI
    } else {
        r
    }
}

/// The bundled robot with its default TCP, for the crate's unit tests.
#[cfg(test)]
pub(crate) fn bundled_for_tests() -> Robot {
    let choice = TcpChoice {
        explicit: None,
        default: Isometry3::identity(),
    };
    Robot::from_urdf(
        include_str!("../../../../urdf/waam_robot.urdf"),
        None,
        choice,
    )
    .expect("the bundled robot loads")
}

#[cfg(test)]
mod tests {
    use super::*;

    const OURS: &str = include_str!("../../../../urdf/waam_robot.urdf");
    const ABB: &str = include_str!("../../../../tests/data/abb_irb1600_12.urdf");

    fn load(text: &str, tcp: Option<Isometry3<f64>>) -> Robot {
        let choice = TcpChoice {
            explicit: tcp,
            default: Isometry3::identity(),
        };
        Robot::from_urdf(text, None, choice).unwrap()
    }

    #[test]
    fn our_robot_is_an_opw_arm_with_a_torch() {
        let r = load(OURS, None);
        assert_eq!(
            (r.base_link.as_str(), r.tip_link.as_str()),
            ("base_link", "tcp")
        );
        assert_eq!(r.dof(), 6);
        let opw = r.opw().unwrap_or_else(|| panic!("{:?}", r.opw_reason));
        let p = &opw.parameters;
        assert!((p.a1 - 0.15).abs() < 1e-12 && (p.c1 - 0.4865).abs() < 1e-12);
        assert!((p.c2 - 0.475).abs() < 1e-12 && (p.c3 - 0.6).abs() < 1e-12);
        assert!(p.a2.abs() < 1e-12 && p.b.abs() < 1e-12);
        // At zero the TCP is 0.065 + 0.35 m beyond the wrist centre along +x.
        let t = r.tcp_pose(&[0.0; 6]).translation.vector;
        assert!(
            (t - Vector3::new(0.75 + 0.415, 0.0, 0.9615)).norm() < 1e-9,
            "{t}"
        );
    }

    #[test]
    fn analytic_and_numeric_ik_reproduce_fk() {
        for (text, tcp) in [
            (OURS, None),
            (ABB, Some(xyz_rpy(&[0.05, 0.0, 0.3], &[0.0, 1.2, 0.0]))),
        ] {
            let r = load(text, tcp);
            let opw = r.opw().unwrap_or_else(|| panic!("{:?}", r.opw_reason));
            eprintln!("{}: OPW fit error {:?}", r.name, opw.verified_error);
            assert!(opw.verified_error.0 < 1e-12 && opw.verified_error.1 < 1e-12);
            let q = [0.3, 0.2, -0.4, 0.5, 1.0, -0.7];
            let target = r.tcp_pose(&q);
            let sols = r.inverse(&target, None);
            assert!(sols.len() >= 4, "{} solutions", sols.len());
            assert!(sols.iter().any(|s| ik::max_abs_diff(&s.q, &q) < 1e-7));
            for s in &sols {
                let (dp, dr) = pose_error(&r.tcp_pose(&s.q), &target);
                assert!(dp < 1e-9 && dr < 1e-9);
                assert!(r.within_limits(&s.q, 1e-12));
            }
            let numeric = r.clone().with_solver(Solver::Numeric);
            let seed = [0.25, 0.25, -0.3, 0.4, 0.9, -0.6];
            let s = numeric.inverse(&target, Some(&seed));
            assert_eq!(s.len(), 1);
            assert!(ik::max_abs_diff(&s[0].q, &q) < 1e-7);
        }
    }

    #[test]
    fn bad_urdfs_are_named() {
        let choice = TcpChoice {
            explicit: None,
            default: Isometry3::identity(),
        };
        let e = Robot::from_urdf("<robot name='x'>", None, choice).unwrap_err();
        assert!(e.to_string().contains("cannot read URDF"), "{e}");
        let e = Robot::from_urdf(OURS, Some("nose"), choice).unwrap_err();
        assert_eq!(e.to_string(), "tip link 'nose' is not a link of the URDF");
        let broken = OURS.replace("velocity=\"2.79253\"", "velocity=\"0\"");
        let e = Robot::from_urdf(&broken, None, choice).unwrap_err();
        assert!(
            e.to_string()
                .starts_with("joint 'joint_2': needs a velocity limit"),
            "{e}"
        );
        assert!(parse_xyz_rpy("1 2 3").is_err());
        assert!(parse_xyz_rpy("0 0 0.3 0 1.57 x").is_err());
    }
}
