//! Joint trajectories: inverse kinematics along a toolpath on one consistent arm
//! configuration, time parameterization within the URDF's velocity limits, and a final
//! validation so that no trajectory with a violation is ever returned.
//!
//! 1. Every pose gets all its IK solutions (analytic solver) and one configuration is
//!    chosen for the whole path by dynamic programming: consecutive solutions must share
//!    the arm configuration (shoulder, elbow, wrist) — or cross a singular pose with
//!    every joint moving less than 0.2 rad — and among those the path with the least
//!    joint motion wins. The numeric solver instead follows the path by
//!    continuation from a few starting seeds.
//! 2. Controllers move joints linearly between points; where that lets the TCP stray from
//!    the straight line by more than `path_tolerance_mm`, the step is split (new
//!    interpolated toolpath poses) and step 1 runs again.
//! 3. Each step takes its toolpath time, or longer when a joint would exceed
//!    `joint_speed_scale` × its velocity limit (slow down, never violate).

use std::fmt;
use std::fmt::Write as _;

use nalgebra::{Isometry3, Translation3, UnitQuaternion};
use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::robot::ik::max_abs_diff;
use crate::robot::{pose_error, Robot};
use crate::toolpath::{list, PoseKind, ProcessSettings, Toolpath};

/// FK of every trajectory point reproduces its toolpath pose to this (m, rad).
pub const POSE_TOL: f64 = 1e-6;
/// Largest joint move (rad) between two poses in different arm configurations: the
/// path crosses a singular pose continuously; anything larger is a branch switch.
const SINGULAR_CROSSING_RAD: f64 = 0.2;
/// Rounds of step splitting before a path that strays is an error.
const MAX_SPLIT_ROUNDS: usize = 8;

/// A joint trajectory for the robot, with the arc state at every point.
#[derive(Debug, Clone, PartialEq)]
pub struct JointTrajectory {
    pub base_link: String,
    pub tip_link: String,
    /// The TCP in the tip link.
    pub tcp_offset: Isometry3<f64>,
    pub joint_names: Vec<String>,
    pub points: Vec<TrajectoryPoint>,
}

/// One trajectory point (rad or m, rad/s or m/s, s).
#[derive(Debug, Clone, PartialEq)]
pub struct TrajectoryPoint {
    pub positions: Vec<f64>,
    pub velocities: Vec<f64>,
    pub accelerations: Vec<f64>,
    pub time_from_start: f64,
    pub arc_on: bool,
}

/// Where on the toolpath something went wrong.
#[derive(Debug, Clone, PartialEq)]
pub struct At {
    /// Index of the toolpath pose.
    pub pose: usize,
    pub kind: PoseKind,
    /// Pass (fragment) index, from 0, and point index within it.
    pub fragment: usize,
    pub point: usize,
    /// What is welded at that point, when the caller knows ("block [x,y,z]" of a block
    /// plan, "segments[3] (A -> B)" of a layer trail).
    pub block: Option<String>,
    /// The TCP position in the base link, m.
    pub position_m: [f64; 3],
}

impl fmt::Display for At {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let what = match self.kind {
            PoseKind::Transit => "transit to",
            PoseKind::Approach => "approach to",
            PoseKind::ArcOn => "arc-on at",
            PoseKind::Weld => "weld at",
            PoseKind::ArcOff => "arc-off at",
            PoseKind::Retract => "retract from",
        };
        let p = self.position_m;
        write!(f, "pose {} ({what} ", self.pose)?;
        match &self.block {
            Some(b) => write!(f, "{b}, ")?,
            None => write!(f, "point {}, ", self.point + 1)?,
        }
        write!(
            f,
            "fragment {}; TCP at [{:.4}, {:.4}, {:.4}] m)",
            self.fragment + 1,
            p[0],
            p[1],
            p[2]
        )
    }
}

/// Why no trajectory could be made.
#[derive(Debug, Error, PartialEq)]
pub enum TrajectoryError {
    #[error("unreachable: {0} has no inverse-kinematics solution within the joint limits")]
    Unreachable(At),
    #[error("branch switch {}: {at} cannot be reached in the arm configuration of the poses before it; the arm would have to change configuration (shoulder, elbow or wrist)", if *.in_weld { "mid-weld" } else { "on a move between welds" })]
    BranchSwitch { at: At, in_weld: bool },
    #[error("the numeric solver cannot follow the path continuously at {0}")]
    Discontinuous(At),
    #[error("the TCP strays {deviation_mm:.2} mm / {deviation_deg:.2} deg from the path before {at} even after splitting the step (a joint would turn the long way round)")]
    Strays {
        at: At,
        deviation_mm: f64,
        deviation_deg: f64,
    },
    #[error("{at}: the weld would need joint {joint} at {needed:.4} {unit}, over its limit of {limit:.4} {unit}; a weld is never slowed down (a slower weld is a different weld): lower the weld speed or raise the limit")]
    WeldTooFast {
        at: Box<At>,
        joint: String,
        needed: f64,
        limit: f64,
        unit: &'static str,
    },
    #[error("the robot needs {needed_s:.3} s from the arc-off of weld path {fragment} to the arc-on of weld path {} but the thermal model allows {allowed_s:.3} s (transit_time_s): raise transit_time_s or the transit speed", .fragment + 1)]
    TransitTooLong {
        /// The weld path (from 1) whose arc-off starts the transit.
        fragment: usize,
        needed_s: f64,
        allowed_s: f64,
    },
    #[error("internal check failed, no trajectory returned: {0}")]
    Violation(String),
}

impl TrajectoryError {
    /// The location, for naming the block afterwards.
    pub fn at_mut(&mut self) -> Option<&mut At> {
        match self {
            TrajectoryError::Unreachable(at)
            | TrajectoryError::Discontinuous(at)
            | TrajectoryError::BranchSwitch { at, .. }
            | TrajectoryError::Strays { at, .. } => Some(at),
            TrajectoryError::WeldTooFast { at, .. } => Some(&mut **at),
            TrajectoryError::Violation(_) | TrajectoryError::TransitTooLong { .. } => None,
        }
    }
}

fn at(tp: &Toolpath, k: usize) -> At {
    let p = &tp.poses[k];
    let t = p.pose.translation.vector;
    At {
        pose: k,
        kind: p.kind,
        fragment: p.fragment,
        point: p.point,
        block: None,
        position_m: [t.x, t.y, t.z],
    }
}

/// Weighted joint distance: the time the move takes at full joint speed.
fn move_time(robot: &Robot, a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .zip(&robot.joints)
        .map(|((x, y), j)| (x - y).abs() / j.velocity)
        .fold(0.0, f64::max)
}

/// One joint vector per toolpath pose on a single arm configuration.
fn joint_path(robot: &Robot, tp: &Toolpath) -> Result<Vec<Vec<f64>>, TrajectoryError> {
    if robot.opw().is_some() {
        analytic_path(robot, tp)
    } else {
        numeric_path(robot, tp)
    }
}

fn analytic_path(robot: &Robot, tp: &Toolpath) -> Result<Vec<Vec<f64>>, TrajectoryError> {
    let mut cands = Vec::with_capacity(tp.poses.len());
    for (k, p) in tp.poses.iter().enumerate() {
        let sols = robot.inverse(&p.pose, None);
        if sols.is_empty() {
            return Err(TrajectoryError::Unreachable(at(tp, k)));
        }
        cands.push(sols);
    }
    // Dynamic programming: cost = sum of squared full-speed move times; a transition
    // must keep the arm configuration.
    let mut cost: Vec<Vec<f64>> = vec![vec![0.0; cands[0].len()]];
    let mut back: Vec<Vec<usize>> = vec![vec![usize::MAX; cands[0].len()]];
    for k in 1..cands.len() {
        let mut ck = vec![f64::INFINITY; cands[k].len()];
        let mut bk = vec![usize::MAX; cands[k].len()];
        for (c, sol) in cands[k].iter().enumerate() {
            for (p, prev) in cands[k - 1].iter().enumerate() {
                if !cost[k - 1][p].is_finite() {
                    continue;
                }
                // A configuration may change only through a singular pose, where the
                // joints stay close: a larger change is a jump to another branch.
                let mut penalty = 0.0;
                if prev.configuration != sol.configuration {
                    if max_abs_diff(&prev.q, &sol.q) > SINGULAR_CROSSING_RAD {
                        continue;
                    }
                    penalty = 1.0;
                }
                let t = move_time(robot, &prev.q, &sol.q);
                let total = cost[k - 1][p] + t * t + penalty;
                if total < ck[c] {
                    ck[c] = total;
                    bk[c] = p;
                }
            }
        }
        if ck.iter().all(|c| !c.is_finite()) {
            let kind = tp.poses[k].kind;
            let in_weld = matches!(kind, PoseKind::Weld | PoseKind::ArcOff)
                && tp.poses[k - 1].fragment == tp.poses[k].fragment;
            return Err(TrajectoryError::BranchSwitch {
                at: at(tp, k),
                in_weld,
            });
        }
        cost.push(ck);
        back.push(bk);
    }
    let last = cands.len() - 1;
    let mut c = (0..cands[last].len())
        .min_by(|&a, &b| cost[last][a].total_cmp(&cost[last][b]))
        .expect("candidates exist");
    let mut path = vec![Vec::new(); cands.len()];
    for k in (0..cands.len()).rev() {
        path[k] = cands[k][c].q.clone();
        c = back[k][c];
    }
    Ok(path)
}

fn numeric_path(robot: &Robot, tp: &Toolpath) -> Result<Vec<Vec<f64>>, TrajectoryError> {
    let first = robot.inverse(&tp.poses[0].pose, None);
    if first.is_empty() {
        return Err(TrajectoryError::Unreachable(at(tp, 0)));
    }
    let mut best: Option<(f64, Vec<Vec<f64>>)> = None;
    let mut furthest = 0;
    for start in first {
        let mut path = vec![start.q];
        let mut cost = 0.0;
        for k in 1..tp.poses.len() {
            let prev = path[k - 1].clone();
            match follow(robot, &tp.poses[k - 1].pose, &tp.poses[k].pose, &prev) {
                Some(q) => {
                    let t = move_time(robot, &prev, &q);
                    cost += t * t;
                    path.push(q);
                }
                None => break,
            }
        }
        if path.len() == tp.poses.len() {
            if best.as_ref().is_none_or(|b| cost < b.0) {
                best = Some((cost, path));
            }
        } else {
            furthest = furthest.max(path.len());
        }
    }
    match best {
        Some((_, path)) => Ok(path),
        None => {
            if robot.inverse(&tp.poses[furthest].pose, None).is_empty() {
                Err(TrajectoryError::Unreachable(at(tp, furthest)))
            } else {
                Err(TrajectoryError::Discontinuous(at(tp, furthest)))
            }
        }
    }
}

/// Follows the straight line between two poses with the numeric solver, in finer steps
/// when a single step does not converge.
fn follow(robot: &Robot, a: &Isometry3<f64>, b: &Isometry3<f64>, q: &[f64]) -> Option<Vec<f64>> {
    let tcp_inv = robot.tcp.inverse();
    for n in [1usize, 4, 16] {
        let mut cur = q.to_vec();
        let mut ok = true;
        for i in 1..=n {
            let target = interpolate(a, b, i as f64 / n as f64) * tcp_inv;
            match robot.solve_dls(&target, &cur, 100) {
                Some(next) if move_time(robot, &cur, &next) < 0.5 => cur = next,
                _ => {
                    ok = false;
                    break;
                }
            }
        }
        if ok {
            return Some(cur);
        }
    }
    None
}

/// The straight-line pose between `a` and `b` at fraction `t` (rotation about one axis).
pub fn interpolate(a: &Isometry3<f64>, b: &Isometry3<f64>, t: f64) -> Isometry3<f64> {
    let p = a.translation.vector.lerp(&b.translation.vector, t);
    let rel = b.rotation * a.rotation.inverse();
    let r = match rel.axis_angle() {
        Some((axis, angle)) => UnitQuaternion::from_axis_angle(&axis, angle * t) * a.rotation,
        None => a.rotation,
    };
    Isometry3::from_parts(Translation3::from(p), r)
}

/// How far (mm, deg) the TCP strays from the straight line from pose `k-1` to `k` while
/// the joints move linearly.
fn deviation(robot: &Robot, tp: &Toolpath, path: &[Vec<f64>], k: usize) -> (f64, f64) {
    let (a, b) = (&tp.poses[k - 1].pose, &tp.poses[k].pose);
    let mut worst = (0.0f64, 0.0f64);
    for t in [0.25, 0.5, 0.75] {
        let q: Vec<f64> = path[k - 1]
            .iter()
            .zip(&path[k])
            .map(|(x, y)| x + (y - x) * t)
            .collect();
        let (dp, dr) = pose_error(&robot.tcp_pose(&q), &interpolate(a, b, t));
        worst.0 = worst.0.max(dp * 1000.0);
        worst.1 = worst.1.max(dr.to_degrees());
    }
    worst
}

/// Splits toolpath step `k-1 -> k` in two, inserting the interpolated pose.
fn split(tp: &mut Toolpath, k: usize) {
    let (a, b) = (&tp.poses[k - 1], &tp.poses[k]);
    let mut mid = b.clone();
    mid.pose = interpolate(&a.pose, &b.pose, 0.5);
    mid.time_s = 0.5 * (a.time_s + b.time_s);
    mid.at_point = false;
    // The arc state between two poses is the earlier pose's.
    mid.arc_on = a.arc_on;
    mid.kind = match b.kind {
        PoseKind::ArcOn => PoseKind::Approach,
        PoseKind::ArcOff => PoseKind::Weld,
        k => k,
    };
    tp.poses.insert(k, mid);
}

/// Solves the toolpath's joint path (splitting steps where the TCP would stray), times
/// it within the joint limits, and validates the result. The toolpath's times are
/// updated to the trajectory's.
///
/// With `arc_on_at_s` (one time per pass, s after the first pass's arc-on: the thermal
/// model's time line) the robot waits at each later pass's approach point until its
/// arc-on time; a transit that cannot make it is [`TrajectoryError::TransitTooLong`].
pub fn plan_trajectory(
    robot: &Robot,
    tp: &mut Toolpath,
    settings: &ProcessSettings,
    arc_on_at_s: Option<&[f64]>,
) -> Result<JointTrajectory, TrajectoryError> {
    let (tol_mm, tol_deg) = (settings.path_tolerance_mm, settings.path_tolerance_deg);
    let mut path = joint_path(robot, tp)?;
    for round in 0..=MAX_SPLIT_ROUNDS {
        let straying: Vec<(usize, (f64, f64))> = (1..tp.poses.len())
            .map(|k| (k, deviation(robot, tp, &path, k)))
            .filter(|(_, (mm, deg))| *mm > tol_mm || *deg > tol_deg)
            .collect();
        if straying.is_empty() {
            break;
        }
        if round == MAX_SPLIT_ROUNDS {
            let (k, (mm, deg)) = straying[0];
            return Err(TrajectoryError::Strays {
                at: at(tp, k),
                deviation_mm: mm,
                deviation_deg: deg,
            });
        }
        tracing::debug!("splitting {} steps where the TCP strays", straying.len());
        for &(k, _) in straying.iter().rev() {
            split(tp, k);
        }
        path = joint_path(robot, tp)?;
    }
    let waits = match arc_on_at_s {
        Some(schedule) => Some(insert_waits(tp, &mut path, schedule)?),
        None => None,
    };
    // A step between equal poses (a dwell, a wait) keeps the joints exactly still.
    for k in 1..path.len() {
        if tp.poses[k].pose == tp.poses[k - 1].pose {
            path[k] = path[k - 1].clone();
        }
    }
    let traj = time_parameterize(robot, tp, path, settings, waits)?;
    validate(robot, tp, &traj)?;
    Ok(traj)
}

/// The indices of the arc-on markers, one per pass.
fn arc_ons(tp: &Toolpath) -> Vec<usize> {
    (0..tp.poses.len())
        .filter(|&k| tp.poses[k].kind == PoseKind::ArcOn)
        .collect()
}

/// Where the robot waits for a pass's arc-on time: a copy of the pose before the pass's
/// approach (its approach point), inserted after it. Returns, per pass from the second
/// on, the wait step (the index of the copy) and the pass's arc-on time.
fn insert_waits(
    tp: &mut Toolpath,
    path: &mut Vec<Vec<f64>>,
    schedule: &[f64],
) -> Result<Vec<(usize, f64)>, TrajectoryError> {
    let passes = arc_ons(tp).len();
    if schedule.len() != passes || schedule.iter().any(|t| !t.is_finite()) {
        return Err(TrajectoryError::Violation(format!(
            "{} arc-on times for {passes} weld passes",
            schedule.len()
        )));
    }
    let mut waits = Vec::new();
    for (f, &at_s) in schedule.iter().enumerate().skip(1) {
        let start = tp
            .poses
            .iter()
            .position(|p| p.fragment == f && matches!(p.kind, PoseKind::Approach | PoseKind::ArcOn))
            .expect("every pass has an arc-on marker");
        let mut wait = tp.poses[start - 1].clone();
        wait.kind = PoseKind::Transit;
        wait.at_point = false;
        wait.arc_on = false;
        tp.poses.insert(start, wait);
        path.insert(start, path[start - 1].clone());
        waits.push((start, at_s));
    }
    Ok(waits)
}

/// Rounds of stretching before a trajectory that still exceeds an acceleration limit is
/// an error.
const MAX_ACCEL_ROUNDS: usize = 500;
/// Relative margin kept below every limit, so that rounding never crosses one.
const LIMIT_MARGIN: f64 = 1e-9;

/// Joint velocities at the points: the mean of the two adjacent steps' velocities, zero
/// at the ends and where the robot stands still (a dwell, a wait) on either side.
fn point_velocities(path: &[Vec<f64>], dt: &[f64], still: &[bool]) -> Vec<Vec<f64>> {
    let n = path.len();
    let dof = path[0].len();
    let seg = |k: usize, j: usize| (path[k][j] - path[k - 1][j]) / dt[k];
    (0..n)
        .map(|k| {
            if k == 0 || k == n - 1 || still[k] || still[k + 1] {
                vec![0.0; dof]
            } else {
                (0..dof)
                    .map(|j| 0.5 * (seg(k, j) + seg(k + 1, j)))
                    .collect()
            }
        })
        .collect()
}

/// Per step `k` (from point k-1 to k), the largest ratio of a joint's acceleration
/// `(v_k - v_{k-1}) / dt_k` to its limit, and that joint.
fn accel_ratios(robot: &Robot, v: &[Vec<f64>], dt: &[f64]) -> Vec<(f64, usize)> {
    (0..v.len())
        .map(|k| {
            if k == 0 {
                return (0.0, 0);
            }
            let mut worst = (0.0, 0);
            for (j, joint) in robot.joints.iter().enumerate() {
                if let Some(a) = joint.acceleration {
                    let r = (v[k][j] - v[k - 1][j]).abs() / dt[k] / a;
                    if r > worst.0 {
                        worst = (r, j);
                    }
                }
            }
            worst
        })
        .collect()
}

/// Times the joint path: every step takes its toolpath time; a move between welds takes
/// longer where a joint would exceed its velocity or acceleration limit; a weld step
/// (arc on) never does: that is an error naming the block. Then the robot waits at the
/// approach points until the arc-on times of `waits`.
fn time_parameterize(
    robot: &Robot,
    tp: &mut Toolpath,
    path: Vec<Vec<f64>>,
    settings: &ProcessSettings,
    waits: Option<Vec<(usize, f64)>>,
) -> Result<JointTrajectory, TrajectoryError> {
    let n = path.len();
    let dof = robot.dof();
    let scale = settings.joint_speed_scale;
    // Steps with the arc on (welds, dwells) keep their time exactly.
    let fixed: Vec<bool> = (0..n).map(|k| k > 0 && tp.poses[k - 1].arc_on).collect();
    let still: Vec<bool> = (0..=n)
        .map(|k| k > 0 && k < n && path[k] == path[k - 1])
        .collect();
    let mut dt = vec![0.0; n];
    for k in 1..n {
        let nominal = tp.poses[k].time_s - tp.poses[k - 1].time_s;
        // A hair above the bound so that rounding never puts a step over the limit.
        let needed = move_time(robot, &path[k - 1], &path[k]) / scale * (1.0 + LIMIT_MARGIN);
        if fixed[k] && needed > nominal {
            let (j, joint) = robot
                .joints
                .iter()
                .enumerate()
                .max_by(|a, b| {
                    let r = |(j, jt): &(usize, &crate::robot::Joint)| {
                        (path[k][*j] - path[k - 1][*j]).abs() / jt.velocity
                    };
                    r(a).total_cmp(&r(b))
                })
                .expect("a robot has joints");
            return Err(TrajectoryError::WeldTooFast {
                at: Box::new(at(tp, k)),
                joint: joint.name.clone(),
                needed: (path[k][j] - path[k - 1][j]).abs() / nominal,
                limit: joint.velocity * scale,
                unit: "rad/s",
            });
        }
        dt[k] = nominal.max(needed).max(1e-6);
    }
    if robot.joints.iter().any(|j| j.acceleration.is_some()) {
        let mut round = 0;
        loop {
            let v = point_velocities(&path, &dt, &still);
            let ratios = accel_ratios(robot, &v, &dt);
            let over: Vec<usize> = (1..n).filter(|&k| ratios[k].0 > 1.0).collect();
            if over.is_empty() {
                break;
            }
            // Where only weld steps are involved, nothing may give: an error.
            let free = |m: usize| m >= 1 && m < n && !fixed[m];
            let stuck = over
                .iter()
                .find(|&&k| fixed[k] && !free(k - 1) && !free(k + 1));
            if let Some(&k) = stuck.or(if round == MAX_ACCEL_ROUNDS {
                over.first()
            } else {
                None
            }) {
                let (r, j) = ratios[k];
                let joint = &robot.joints[j];
                let limit = joint.acceleration.expect("a limited joint");
                if !fixed[k] {
                    return Err(TrajectoryError::Violation(format!(
                        "point {k}: joint {} acceleration {:.4} rad/s² still over its limit after {MAX_ACCEL_ROUNDS} rounds",
                        joint.name,
                        r * limit
                    )));
                }
                return Err(TrajectoryError::WeldTooFast {
                    at: Box::new(at(tp, k)),
                    joint: joint.name.clone(),
                    needed: r * limit,
                    limit,
                    unit: "rad/s²",
                });
            }
            for &k in &over {
                let r = ratios[k].0 * (1.0 + LIMIT_MARGIN);
                if !fixed[k] {
                    // The velocity change over step k does not depend on step k's own
                    // speed: stretching it by r brings this step to its limit.
                    dt[k] *= r;
                } else {
                    for m in [k - 1, k + 1] {
                        if m >= 1 && m < n && !fixed[m] {
                            dt[m] *= r.sqrt();
                        }
                    }
                }
            }
            round += 1;
        }
    }
    if let Some(waits) = waits {
        // Times so far, then each wait stretched so that its pass strikes the arc on time.
        let mut times = vec![0.0; n];
        for k in 1..n {
            times[k] = times[k - 1] + dt[k];
        }
        let ons = arc_ons(tp);
        let mut shift = 0.0;
        for (f, &(w, at_s)) in waits.iter().enumerate() {
            let pass = f + 1;
            let actual = times[ons[pass]] + shift - times[ons[0]];
            let deficit = at_s - actual;
            if deficit < -1e-9 {
                let off = (0..ons[pass])
                    .rev()
                    .find(|&k| tp.poses[k].kind == PoseKind::ArcOff)
                    .expect("an arc-off before every later arc-on");
                let gap = times[ons[pass]] - times[off];
                return Err(TrajectoryError::TransitTooLong {
                    fragment: pass,
                    needed_s: gap,
                    allowed_s: gap + deficit,
                });
            }
            dt[w] += deficit.max(0.0);
            shift += deficit.max(0.0);
        }
    }
    let mut times = vec![0.0; n];
    for k in 1..n {
        times[k] = times[k - 1] + dt[k];
    }
    let v = point_velocities(&path, &dt, &still);
    let seg_acc =
        |k: usize| -> Vec<f64> { (0..dof).map(|j| (v[k][j] - v[k - 1][j]) / dt[k]).collect() };
    let mut points = Vec::with_capacity(n);
    for k in 0..n {
        let accelerations = if n == 1 {
            vec![0.0; dof]
        } else if k == 0 {
            seg_acc(1)
        } else if k == n - 1 {
            seg_acc(k)
        } else {
            let (a, b) = (seg_acc(k), seg_acc(k + 1));
            (0..dof).map(|j| 0.5 * (a[j] + b[j])).collect()
        };
        tp.poses[k].time_s = times[k];
        points.push(TrajectoryPoint {
            positions: path[k].clone(),
            velocities: v[k].clone(),
            accelerations,
            time_from_start: times[k],
            arc_on: tp.poses[k].arc_on,
        });
    }
    Ok(JointTrajectory {
        base_link: robot.base_link.clone(),
        tip_link: robot.tip_link.clone(),
        tcp_offset: robot.tcp,
        joint_names: robot.joint_names(),
        points,
    })
}

/// Checks a trajectory against the robot and its toolpath: one point per pose at the
/// same time, FK reproduces every pose, positions and velocities within the limits, no
/// step faster than the velocity limits allow.
pub fn validate(
    robot: &Robot,
    tp: &Toolpath,
    traj: &JointTrajectory,
) -> Result<(), TrajectoryError> {
    let fail = |m: String| Err(TrajectoryError::Violation(m));
    if traj.points.len() != tp.poses.len() {
        return fail(format!(
            "{} points for {} poses",
            traj.points.len(),
            tp.poses.len()
        ));
    }
    for (k, (pt, pose)) in traj.points.iter().zip(&tp.poses).enumerate() {
        if pt.time_from_start != pose.time_s || pt.arc_on != pose.arc_on {
            return fail(format!(
                "point {k} does not match its toolpath pose's time or arc state"
            ));
        }
        let (dp, dr) = pose_error(&robot.tcp_pose(&pt.positions), &pose.pose);
        if dp > POSE_TOL || dr > POSE_TOL {
            return fail(format!(
                "point {k}: FK misses its pose by {dp:.2e} m / {dr:.2e} rad"
            ));
        }
        for (j, joint) in robot.joints.iter().enumerate() {
            if !joint.within(pt.positions[j], 1e-12) {
                return fail(format!(
                    "point {k}: joint {} at {} outside its limits",
                    joint.name, pt.positions[j]
                ));
            }
            if pt.velocities[j].abs() > joint.velocity * (1.0 + 1e-9) {
                return fail(format!(
                    "point {k}: joint {} velocity {} over its limit",
                    joint.name, pt.velocities[j]
                ));
            }
            if let Some(a) = joint.acceleration {
                if pt.accelerations[j].abs() > a * (1.0 + 1e-6) {
                    return fail(format!(
                        "point {k}: joint {} acceleration {} over its limit",
                        joint.name, pt.accelerations[j]
                    ));
                }
            }
        }
        if k > 0 {
            let prev = &traj.points[k - 1];
            let dt = pt.time_from_start - prev.time_from_start;
            if dt <= 0.0 {
                return fail(format!("point {k}: time does not increase"));
            }
            for (j, joint) in robot.joints.iter().enumerate() {
                if (pt.positions[j] - prev.positions[j]).abs() > joint.velocity * dt * (1.0 + 1e-9)
                {
                    return fail(format!(
                        "point {k}: joint {} jumps further than its limit allows in {dt} s",
                        joint.name
                    ));
                }
                let dv = (pt.velocities[j] - prev.velocities[j]).abs();
                if joint
                    .acceleration
                    .is_some_and(|a| dv > a * dt * (1.0 + 1e-6))
                {
                    return fail(format!(
                        "point {k}: joint {} changes speed faster than its acceleration limit",
                        joint.name
                    ));
                }
            }
        }
    }
    Ok(())
}

/// `trajectory.yaml`: exactly these keys (SI units, quaternions [x, y, z, w]).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct TrajectoryFile {
    pub base_link: String,
    pub tip_link: String,
    pub tcp_offset: TcpOffsetFile,
    pub joint_names: Vec<String>,
    pub points: Vec<TrajectoryFilePoint>,
}

#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct TcpOffsetFile {
    pub position: [f64; 3],
    pub orientation: [f64; 4],
}

#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct TrajectoryFilePoint {
    pub positions: Vec<f64>,
    pub velocities: Vec<f64>,
    /// Absent in files written before accelerations were: read as none.
    #[serde(default)]
    pub accelerations: Vec<f64>,
    pub time_from_start: f64,
    pub arc_on: bool,
}

impl JointTrajectory {
    /// `trajectory.yaml` text, one point per line.
    pub fn to_yaml(&self) -> String {
        let q = self.tcp_offset.rotation.coords;
        let t = self.tcp_offset.translation.vector;
        let mut out = String::new();
        let quote = |s: &str| serde_json::to_string(s).expect("a string");
        let _ = writeln!(out, "base_link: {}", quote(&self.base_link));
        let _ = writeln!(out, "tip_link: {}", quote(&self.tip_link));
        let _ = writeln!(
            out,
            "tcp_offset: {{position: {}, orientation: {}}}",
            list(&[t.x, t.y, t.z]),
            list(&[q.x, q.y, q.z, q.w])
        );
        let names: Vec<String> = self.joint_names.iter().map(|n| quote(n)).collect();
        let _ = writeln!(out, "joint_names: [{}]", names.join(", "));
        out.push_str("points:\n");
        for p in &self.points {
            let _ = writeln!(
                out,
                "  - {{positions: {}, velocities: {}, accelerations: {}, time_from_start: {:?}, arc_on: {}}}",
                list(&p.positions),
                list(&p.velocities),
                list(&p.accelerations),
                p.time_from_start,
                p.arc_on
            );
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::toolpath::ToolPose;

    fn robot() -> Robot {
        crate::robot::bundled_for_tests()
    }

    fn weld(pose: Isometry3<f64>, time_s: f64, point: usize) -> ToolPose {
        ToolPose {
            time_s,
            pose,
            arc_on: true,
            fragment: 0,
            point,
            kind: PoseKind::Weld,
            at_point: true,
        }
    }

    /// The test robot with joint ranges narrowed so that each pose has a single arm and
    /// wrist configuration.
    fn narrowed_robot() -> Robot {
        let mut r = robot();
        for (j, lo, hi) in [
            (0, -0.5, 0.5),
            (1, 0.0, 0.6),
            (2, -0.5, 0.1),
            (3, -0.5, 0.5),
            (5, -0.5, 0.5),
        ] {
            r.joints[j].lower = lo;
            r.joints[j].upper = hi;
        }
        r
    }

    #[test]
    fn a_configuration_change_mid_weld_is_an_error_naming_the_pose() {
        // The second pose needs the wrist flipped.
        let r = narrowed_robot();
        let a = r.tcp_pose(&[0.0, 0.3, -0.2, 0.2, 0.5, 0.1]);
        let b = r.tcp_pose(&[0.0, 0.3, -0.2, 0.2, -0.5, 0.1]);
        let mut tp = Toolpath {
            frame: "base_link".into(),
            poses: vec![weld(a, 0.0, 0), weld(b, 1.0, 1)],
        };
        let err = plan_trajectory(&r, &mut tp, &ProcessSettings::default(), None).unwrap_err();
        assert!(
            matches!(err, TrajectoryError::BranchSwitch { in_weld: true, .. }),
            "{err}"
        );
        assert!(
            err.to_string()
                .starts_with("branch switch mid-weld: pose 1 (weld at point 2, fragment 1"),
            "{err}"
        );
    }

    #[test]
    fn a_path_may_cross_the_wrist_singularity_continuously() {
        let r = narrowed_robot();
        let poses = (0..5)
            .map(|i| {
                let q5 = 0.04 - 0.02 * i as f64;
                weld(r.tcp_pose(&[0.0, 0.3, -0.2, 0.2, q5, 0.1]), i as f64, i)
            })
            .collect();
        let mut tp = Toolpath {
            frame: "base_link".into(),
            poses,
        };
        let traj = plan_trajectory(&r, &mut tp, &ProcessSettings::default(), None).unwrap();
        let q5: Vec<f64> = traj.points.iter().map(|p| p.positions[4]).collect();
        assert!(q5.windows(2).all(|w| (w[1] - w[0]).abs() < 0.05), "{q5:?}");
    }

    #[test]
    fn interpolation_runs_along_one_axis() {
        let a = Isometry3::translation(0.1, 0.0, 0.0);
        let b = Isometry3::from_parts(
            Translation3::new(0.3, 0.0, 0.0),
            UnitQuaternion::from_euler_angles(0.0, 0.0, 1.0),
        );
        let m = interpolate(&a, &b, 0.5);
        assert!((m.translation.x - 0.2).abs() < 1e-15);
        assert!((m.rotation.angle() - 0.5).abs() < 1e-12);
    }
}
