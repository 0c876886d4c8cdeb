//! Domain values as ROS 2 messages, each converted in exactly one place: poses, path,
//! joint trajectory, the weld plan, markers and the planner's statistics (status reports:
//! [`crate::status`]).
//!
//! Every output message of a plan carries the same header (the time of planning, the
//! robot's base link), so a viewer can line them up.

use nalgebra::{Isometry3, Point3};

use crate::topics;
use waam_motion::toolpath::{PoseKind, Toolpath};
use waam_motion::trajectory::{JointTrajectory, TrajectoryPoint};
use waam_part::{BlockDisplay, Part};
use waam_pipeline::Planned;
use waam_planner::Stats;
use waam_rosbag::{BagError, Qos, Recorder};
use waam_rosmsg::builtin_interfaces::{Duration, Time};
use waam_rosmsg::geometry_msgs::{Point, Pose, PoseArray, PoseStamped, Quaternion, Vector3};
use waam_rosmsg::nav_msgs::Path;
use waam_rosmsg::std_msgs::{ColorRGBA, Header};
use waam_rosmsg::trajectory_msgs::{JointTrajectory as TrajectoryMsg, JointTrajectoryPoint};
use waam_rosmsg::visualization_msgs::{Marker, MarkerArray};
use waam_rosmsg::waam_interfaces::{Block, PlanStatistics, WeldFragment, WeldPlan, WeldPoint};

/// The node's name, and the `name` of every status it reports.
pub const NODE_NAME: &str = "waam_planner";

/// A node's fully qualified name, `/namespace/name` (`namespace` absolute, `/` for none):
/// the `hardware_id` of every status it reports, as an integrator looks it up.
pub fn fully_qualified(namespace: &str, name: &str) -> String {
    format!("{}/{}", namespace.trim_end_matches('/'), name)
}

/// A domain value that has no message form.
#[derive(Debug, thiserror::Error)]
pub enum ConvertError {
    #[error("block {0} does not fit in the message's int32 coordinates")]
    BlockOutOfRange(BlockDisplay),
}

/// A block's coordinates as our message carries them (int32): checked, never truncated.
pub fn block_msg(b: waam_part::Block) -> Result<Block, ConvertError> {
    Block::from_part(b).ok_or(ConvertError::BlockOutOfRange(BlockDisplay(b)))
}

/// The planner's statistics as our message carries them.
pub fn statistics(stats: &Stats, proven: bool) -> PlanStatistics {
    let count = |n: usize| u32::try_from(n).unwrap_or(u32::MAX);
    PlanStatistics {
        candidates: stats.candidates,
        feasible: stats.feasible,
        optimal: proven,
        time_to_first_feasible_s: stats.first_feasible_s.unwrap_or(f64::NAN),
        total_time_s: stats.total_s,
        sat_time_s: stats.sat_s,
        acyclicity_time_s: stats.acyclicity_s,
        simulation_time_s: stats.simulator_s,
        learned_clauses: u32::try_from(stats.learned_clauses).unwrap_or(u32::MAX),
        learned_clause_min: stats.clause_len_min.map_or(0, count),
        learned_clause_max: stats.clause_len_max.map_or(0, count),
        learned_clause_mean: stats.clause_len_mean.unwrap_or(0.0),
    }
}

/// The whole trajectory as a trajectory_msgs/JointTrajectory.
pub fn trajectory_msg(trajectory: &JointTrajectory, header: &Header) -> TrajectoryMsg {
    TrajectoryMsg {
        header: header.clone(),
        joint_names: trajectory.joint_names.clone(),
        points: trajectory
            .points
            .iter()
            .map(|p| trajectory_point(p, p.time_from_start))
            .collect(),
    }
}

/// The goal trajectory for points `span`: times count from the point before the span (where
/// the robot stands), or from `lead_in_s` before the first point for the very first goal;
/// the last point has zero velocity, since the robot stops there until the next goal.
pub fn goal_msg(
    trajectory: &JointTrajectory,
    span: std::ops::RangeInclusive<usize>,
    lead_in_s: f64,
) -> TrajectoryMsg {
    let points = &trajectory.points;
    let (first, last) = (*span.start(), *span.end());
    let t0 = if first == 0 {
        points[0].time_from_start - lead_in_s
    } else {
        points[first - 1].time_from_start
    };
    let mut out: Vec<JointTrajectoryPoint> = points[span]
        .iter()
        .map(|p| trajectory_point(p, p.time_from_start - t0))
        .collect();
    if let Some(end) = out.last_mut() {
        end.velocities.iter_mut().for_each(|v| *v = 0.0);
        end.accelerations.iter_mut().for_each(|a| *a = 0.0);
    }
    debug_assert_eq!(out.len(), last + 1 - first);
    TrajectoryMsg {
        header: Header::new(Time::default(), ""), // stamp 0: start on receipt
        joint_names: trajectory.joint_names.clone(),
        points: out,
    }
}

/// One trajectory point, reached `time_from_start` seconds after its trajectory's start.
fn trajectory_point(p: &TrajectoryPoint, time_from_start: f64) -> JointTrajectoryPoint {
    JointTrajectoryPoint {
        positions: p.positions.clone(),
        velocities: p.velocities.clone(),
        accelerations: p.accelerations.clone(),
        time_from_start: Duration::from_secs_f64(time_from_start),
        ..JointTrajectoryPoint::default()
    }
}

/// A geometry_msgs/Pose from an isometry (metres).
pub fn pose_msg(pose: &Isometry3<f64>) -> Pose {
    let t = pose.translation.vector;
    let q = pose.rotation.coords;
    Pose {
        position: Point {
            x: t.x,
            y: t.y,
            z: t.z,
        },
        orientation: Quaternion {
            x: q.x,
            y: q.y,
            z: q.z,
            w: q.w,
        },
    }
}

/// A geometry_msgs/Point (metres).
pub fn point_msg(p: &Point3<f64>) -> Point {
    Point {
        x: p.x,
        y: p.y,
        z: p.z,
    }
}

/// One pose per toolpath point, in time order.
pub fn pose_array(toolpath: &Toolpath, header: &Header) -> PoseArray {
    PoseArray {
        header: header.clone(),
        poses: toolpath.poses.iter().map(|p| pose_msg(&p.pose)).collect(),
    }
}

/// The toolpath as a nav_msgs/Path; each pose stamped with the plan's start plus its time.
pub fn path(toolpath: &Toolpath, header: &Header) -> Path {
    let start = header.stamp.to_nanos();
    Path {
        header: header.clone(),
        poses: toolpath
            .poses
            .iter()
            .map(|p| PoseStamped {
                header: Header::new(
                    Time::from_nanos(start + (p.time_s * 1e9).round() as i64),
                    header.frame_id.clone(),
                ),
                pose: pose_msg(&p.pose),
            })
            .collect(),
    }
}

fn kind_code(kind: PoseKind) -> u8 {
    match kind {
        PoseKind::Transit => WeldPoint::TRANSIT,
        PoseKind::Approach => WeldPoint::APPROACH,
        PoseKind::ArcOn => WeldPoint::ARC_ON,
        PoseKind::Weld => WeldPoint::WELD,
        PoseKind::ArcOff => WeldPoint::ARC_OFF,
        PoseKind::Retract => WeldPoint::RETRACT,
    }
}

/// What a `WeldPlan` message says, from the domain: the one builder of that message.
#[derive(Debug, Clone)]
pub struct WeldPlanOf<'a> {
    pub part_name: &'a str,
    /// Block pitch along x, m.
    pub block_pitch: f64,
    /// Block coordinates per fragment, in weld order (none for a layer's trail).
    pub fragments: Vec<Vec<waam_part::Block>>,
    /// The toolpath, when the plan has motion: every point with its arc state and timing.
    pub toolpath: Option<&'a Toolpath>,
    /// TCP speeds, m/s.
    pub weld_speed: f64,
    pub transit_speed: f64,
    pub worst_margin_s: f64,
    pub statistics: PlanStatistics,
}

impl WeldPlanOf<'_> {
    /// The message; a block whose coordinates do not fit the message is an error.
    pub fn to_msg(&self, header: &Header) -> Result<WeldPlan, ConvertError> {
        let fragments = self
            .fragments
            .iter()
            .map(|f| {
                let blocks = f.iter().map(|&b| block_msg(b)).collect::<Result<_, _>>()?;
                Ok(WeldFragment { blocks })
            })
            .collect::<Result<_, ConvertError>>()?;
        Ok(WeldPlan {
            header: header.clone(),
            part_name: self.part_name.to_string(),
            block_pitch: self.block_pitch,
            fragments,
            points: self.toolpath.map(weld_points).unwrap_or_default(),
            weld_speed: self.weld_speed,
            transit_speed: self.transit_speed,
            worst_margin_s: self.worst_margin_s,
            statistics: self.statistics.clone(),
        })
    }
}

/// Fragments of block indices of `part` as block coordinates.
pub fn block_fragments(part: &Part, fragments: &[Vec<usize>]) -> Vec<Vec<waam_part::Block>> {
    fragments
        .iter()
        .map(|f| f.iter().map(|&i| part.block(i)).collect())
        .collect()
}

/// Every message a plan goes out as (published by the node, recorded by `--record`), all
/// with the same header so a viewer can line them up.
#[derive(Debug, Clone)]
pub struct PlanMessages {
    pub joint_trajectory: TrajectoryMsg,
    pub poses: PoseArray,
    pub path: Path,
    pub markers: MarkerArray,
    pub weld_plan: WeldPlan,
}

impl PlanMessages {
    /// The messages of a planned part (a checked block plan with its motion).
    pub fn of_planned(planned: &Planned, header: &Header) -> Result<Self, ConvertError> {
        let found = &planned.found;
        let weld_plan = WeldPlanOf {
            part_name: &planned.part.name,
            block_pitch: planned.part.block_mm[0] / 1000.0,
            fragments: block_fragments(&planned.part, &found.fragments),
            toolpath: Some(&planned.toolpath),
            weld_speed: planned.weld_speed,
            transit_speed: planned.transit_speed,
            worst_margin_s: found.worst_margin_s,
            statistics: statistics(&found.stats, found.proven),
        }
        .to_msg(header)?;
        Ok(PlanMessages {
            joint_trajectory: trajectory_msg(&planned.trajectory, header),
            poses: pose_array(&planned.toolpath, header),
            path: path(&planned.toolpath, header),
            markers: markers(
                &planned.part,
                &found.fragments,
                &planned.toolpath,
                &planned.plate,
                header,
            ),
            weld_plan,
        })
    }

    /// Records them on the node's default topics with the QoS the node offers (latched).
    pub fn record(&self, recorder: &Recorder) -> Result<(), BagError> {
        let stamp = self.weld_plan.header.stamp;
        let qos = Qos::latched();
        recorder.record_at(
            topics::JOINT_TRAJECTORY,
            &qos,
            stamp,
            &self.joint_trajectory,
        )?;
        recorder.record_at(topics::POSES, &qos, stamp, &self.poses)?;
        recorder.record_at(topics::PATH, &qos, stamp, &self.path)?;
        recorder.record_at(topics::MARKERS, &qos, stamp, &self.markers)?;
        recorder.record_at(topics::WELD_PLAN, &qos, stamp, &self.weld_plan)
    }
}

/// Every toolpath point with its arc state, kind, time, fragment, block and speed.
pub fn weld_points(toolpath: &Toolpath) -> Vec<WeldPoint> {
    let mut points = Vec::with_capacity(toolpath.poses.len());
    let mut previous: Option<&waam_motion::toolpath::ToolPose> = None;
    for p in &toolpath.poses {
        let speed = match previous {
            Some(q) if p.time_s > q.time_s => {
                (p.pose.translation.vector - q.pose.translation.vector).norm()
                    / (p.time_s - q.time_s)
            }
            _ => 0.0,
        };
        let on_block =
            p.at_point && matches!(p.kind, PoseKind::ArcOn | PoseKind::Weld | PoseKind::ArcOff);
        points.push(WeldPoint {
            pose: pose_msg(&p.pose),
            time_from_start: Duration::from_secs_f64(p.time_s),
            kind: kind_code(p.kind),
            arc_on: p.arc_on,
            fragment: if p.kind == PoseKind::Transit {
                -1
            } else {
                p.fragment as i32
            },
            block: if on_block { p.point as i32 } else { -1 },
            speed,
        });
        previous = Some(p);
    }
    points
}

/// A colour per fragment, well apart on the hue circle (golden-angle steps).
pub fn fragment_colour(fragment: usize) -> ColorRGBA {
    let h = (fragment as f64 * 0.381_966_011_250_105) % 1.0 * 6.0;
    let x = 1.0 - ((h % 2.0) - 1.0).abs();
    let (r, g, b) = match h as u32 {
        0 => (1.0, x, 0.0),
        1 => (x, 1.0, 0.0),
        2 => (0.0, 1.0, x),
        3 => (0.0, x, 1.0),
        4 => (x, 0.0, 1.0),
        _ => (1.0, 0.0, x),
    };
    // Soften towards white a little so the labels stay readable on top.
    let soft = |c: f64| (0.15 + 0.85 * c) as f32;
    ColorRGBA {
        r: soft(r),
        g: soft(g),
        b: soft(b),
        a: 1.0,
    }
}

const GREEN: ColorRGBA = ColorRGBA {
    r: 0.1,
    g: 0.9,
    b: 0.2,
    a: 1.0,
};
const RED: ColorRGBA = ColorRGBA {
    r: 0.95,
    g: 0.15,
    b: 0.1,
    a: 1.0,
};
const GREY: ColorRGBA = ColorRGBA {
    r: 0.6,
    g: 0.6,
    b: 0.6,
    a: 0.8,
};
const WHITE: ColorRGBA = ColorRGBA {
    r: 1.0,
    g: 1.0,
    b: 1.0,
    a: 1.0,
};

/// Marker namespaces, one per kind of thing drawn.
pub mod ns {
    pub const BLOCKS: &str = "blocks";
    /// A layer's walls (`waam layer plan`), in place of blocks.
    pub const WALLS: &str = "walls";
    pub const WELD: &str = "weld";
    pub const TRANSIT: &str = "transit";
    pub const ARC_ON: &str = "arc_on";
    pub const ARC_OFF: &str = "arc_off";
    pub const LABELS: &str = "labels";
}

/// The marker that clears whatever an earlier plan drew (first in every plan's array).
pub fn delete_all(header: &Header) -> Marker {
    Marker {
        header: header.clone(),
        action: Marker::DELETEALL,
        ..Marker::default()
    }
}

/// A marker to ADD, in `header`'s frame, of `type_`: the one builder every plan marker starts
/// from.
pub(crate) fn new_marker(header: &Header, ns: &str, id: i32, type_: i32) -> Marker {
    Marker {
        header: header.clone(),
        ns: ns.to_string(),
        id,
        type_,
        action: Marker::ADD,
        pose: Pose::default(),
        ..Marker::default()
    }
}

/// The plan for RViz / Foxglove: blocks as cubes coloured by fragment, a weld line per
/// fragment, the transit moves, and an arc-on and an arc-off marker per fragment with
/// labels. The first marker deletes whatever an earlier plan drew.
pub fn markers(
    part: &Part,
    fragments: &[Vec<usize>],
    toolpath: &Toolpath,
    plate: &Isometry3<f64>,
    header: &Header,
) -> MarkerArray {
    let base = |ns: &str, id: i32, type_: i32| new_marker(header, ns, id, type_);
    let mut out = vec![delete_all(header)];

    // Blocks: one CUBE_LIST, each cube at its block centre, coloured by its fragment.
    let mut cubes = base(ns::BLOCKS, 0, Marker::CUBE_LIST);
    let [bx, by, bz] = part.block_mm.map(|v| v / 1000.0);
    cubes.scale = Vector3 {
        x: bx * 0.95,
        y: by * 0.95,
        z: bz * 0.95,
    };
    cubes.color = WHITE;
    for (f, fragment) in fragments.iter().enumerate() {
        for &i in fragment {
            let c = part.centre_mm(part.block(i)).map(|v| v / 1000.0);
            cubes.points.push(point_msg(&(plate * Point3::from(c))));
            let mut colour = fragment_colour(f);
            colour.a = 0.6;
            cubes.colors.push(colour);
        }
    }
    out.push(cubes);

    let width = 0.25 * bx.min(by);
    out.extend(toolpath_markers(toolpath, width, header));
    MarkerArray { markers: out }
}

/// The toolpath for RViz / Foxglove: a weld line per fragment (in its colour), the transit
/// moves, and an arc-on and an arc-off marker per fragment with labels; `width` is the weld
/// line's width in metres.
pub fn toolpath_markers(toolpath: &Toolpath, width: f64, header: &Header) -> Vec<Marker> {
    let base = |ns: &str, id: i32, type_: i32| new_marker(header, ns, id, type_);
    let mut out = Vec::new();
    let poses = &toolpath.poses;
    let fragments = poses.iter().map(|p| p.fragment + 1).max().unwrap_or(0);
    // Weld lines (arc on) per fragment and transit lines (arc off) between.
    let mut transit = base(ns::TRANSIT, 0, Marker::LINE_LIST);
    transit.scale.x = 0.4 * width;
    transit.color = GREY;
    for f in 0..fragments {
        let mut weld = base(ns::WELD, f as i32, Marker::LINE_STRIP);
        weld.scale.x = width;
        weld.color = fragment_colour(f);
        weld.points = poses
            .iter()
            .filter(|p| p.arc_on && p.fragment == f)
            .map(|p| point_msg(&Point3::from(p.pose.translation.vector)))
            .collect();
        out.push(weld);
    }
    for pair in poses.windows(2) {
        if !pair[0].arc_on {
            for p in pair {
                transit
                    .points
                    .push(point_msg(&Point3::from(p.pose.translation.vector)));
            }
        }
    }
    out.push(transit);

    // Arc-on and arc-off markers with labels.
    let mut label_id = 0;
    for (kind, namespace, colour, word) in [
        (PoseKind::ArcOn, ns::ARC_ON, GREEN, "arc on"),
        (PoseKind::ArcOff, ns::ARC_OFF, RED, "arc off"),
    ] {
        for p in poses.iter().filter(|p| p.kind == kind) {
            let mut sphere = base(namespace, p.fragment as i32, Marker::SPHERE);
            sphere.pose = pose_msg(&Isometry3::from_parts(
                p.pose.translation,
                nalgebra::UnitQuaternion::identity(),
            ));
            sphere.scale = Vector3 {
                x: 2.0 * width,
                y: 2.0 * width,
                z: 2.0 * width,
            };
            sphere.color = colour;
            out.push(sphere);
            let mut label = base(ns::LABELS, label_id, Marker::TEXT_VIEW_FACING);
            label_id += 1;
            let mut at = pose_msg(&p.pose);
            at.orientation = Quaternion::default();
            at.position.z += 3.0 * width;
            label.pose = at;
            label.scale.z = 2.5 * width;
            label.color = colour;
            label.text = format!("{word} {}", p.fragment + 1);
            out.push(label);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use waam_motion::robot::{Robot, TcpChoice};
    use waam_motion::toolpath::ProcessSettings;
    use waam_part::graph::WeldGraph;
    use waam_part::plan::Plan;
    use waam_pipeline::BUNDLED_URDF;

    /// s1-wall with its checked sample plan, through the real toolpath and trajectory.
    fn planned() -> (
        Part,
        Vec<Vec<usize>>,
        Toolpath,
        waam_motion::trajectory::JointTrajectory,
    ) {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
        let part =
            Part::from_bytes(&std::fs::read(root.join("config/parts/s1-wall.yaml")).unwrap())
                .unwrap();
        let plan = Plan::from_bytes(
            &std::fs::read(root.join("tests/data/plans/s1-wall.yaml")).unwrap(),
            false,
        )
        .unwrap();
        let fragments = plan.validate(&part, &WeldGraph::new(&part)).unwrap();
        let settings = ProcessSettings::default();
        let robot = Robot::from_urdf(
            BUNDLED_URDF,
            None,
            TcpChoice {
                explicit: None,
                default: settings.tcp.isometry(),
            },
        )
        .unwrap();
        let (toolpath, trajectory) =
            waam_motion::plan_motion(&part, &fragments, &settings, &robot).unwrap();
        (part, fragments, toolpath, trajectory)
    }

    #[test]
    fn messages_describe_the_plan() {
        let (part, fragments, toolpath, trajectory) = planned();
        let header = Header::new(Time::from_nanos(5_000_000_000), "base_link");
        let plan = WeldPlanOf {
            part_name: &part.name,
            block_pitch: part.block_mm[0] / 1000.0,
            fragments: block_fragments(&part, &fragments),
            toolpath: Some(&toolpath),
            weld_speed: 0.006,
            transit_speed: 0.1,
            worst_margin_s: 1.5,
            statistics: PlanStatistics::default(),
        }
        .to_msg(&header)
        .unwrap();
        assert_eq!(plan.points.len(), toolpath.poses.len());
        let blocks: usize = plan.fragments.iter().map(|f| f.blocks.len()).sum();
        assert_eq!(blocks, part.len());
        let count = |k: u8| plan.points.iter().filter(|p| p.kind == k).count();
        assert_eq!(count(WeldPoint::ARC_ON), fragments.len());
        assert_eq!(count(WeldPoint::ARC_OFF), fragments.len());
        // Every block is deposited at some point with its index in its fragment.
        for (f, fragment) in fragments.iter().enumerate() {
            for b in 0..fragment.len() {
                assert!(plan
                    .points
                    .iter()
                    .any(|p| p.fragment == f as i32 && p.block == b as i32 && p.arc_on));
            }
        }

        let poses = pose_array(&toolpath, &header);
        let path = path(&toolpath, &header);
        assert_eq!(poses.poses.len(), toolpath.poses.len());
        assert_eq!(path.poses.len(), toolpath.poses.len());
        assert!(path
            .poses
            .windows(2)
            .all(|w| w[1].header.stamp >= w[0].header.stamp));
        assert_eq!(path.poses[0].header.stamp.sec, 5);

        let plate = ProcessSettings::default().plate.isometry();
        let markers = markers(&part, &fragments, &toolpath, &plate, &header).markers;
        assert_eq!(markers[0].action, Marker::DELETEALL);
        let in_ns = |ns: &str| markers.iter().filter(|m| m.ns == ns).count();
        assert_eq!(in_ns(ns::ARC_ON), fragments.len());
        assert_eq!(in_ns(ns::ARC_OFF), fragments.len());
        assert_eq!(in_ns(ns::LABELS), 2 * fragments.len());
        assert_eq!(in_ns(ns::WELD), fragments.len());
        let cubes = markers.iter().find(|m| m.ns == ns::BLOCKS).unwrap();
        assert_eq!(cubes.points.len(), part.len());
        assert_eq!(cubes.colors.len(), part.len());

        // Goals are re-timed from where the robot stands and end at rest.
        let first = goal_msg(&trajectory, 0..=3, 2.0);
        assert!((first.points[0].time_from_start.as_secs_f64() - 2.0).abs() < 1e-6);
        let next = goal_msg(&trajectory, 4..=6, 2.0);
        let t3 = trajectory.points[3].time_from_start;
        let t4 = trajectory.points[4].time_from_start;
        assert!((next.points[0].time_from_start.as_secs_f64() - (t4 - t3)).abs() < 1e-6);
        assert!(next.points[2].velocities.iter().all(|v| *v == 0.0));
    }
}
