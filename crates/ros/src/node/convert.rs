//! A planned part as ROS 2 messages: poses, path, weld plan, markers, status.
//!
//! Every output message carries the same header (the time of planning, the robot's base
//! link), so a viewer can line them up.

use nalgebra::{Isometry3, Point3};

use super::controller::trajectory_msg;

use crate::topics;
use waam_motion::toolpath::{PoseKind, Toolpath};
use waam_motion::trajectory::JointTrajectory;
use waam_part::Part;
use waam_rosbag::{BagError, Qos, Recorder};
use waam_rosmsg::builtin_interfaces::{Duration, Time};
use waam_rosmsg::diagnostic_msgs::{DiagnosticArray, DiagnosticStatus, KeyValue};
use waam_rosmsg::geometry_msgs::{Point, Pose, PoseArray, PoseStamped, Quaternion, Vector3};
use waam_rosmsg::nav_msgs::Path;
use waam_rosmsg::std_msgs::{ColorRGBA, Header};
use waam_rosmsg::trajectory_msgs::JointTrajectory as TrajectoryMsg;
use waam_rosmsg::visualization_msgs::{Marker, MarkerArray};
use waam_rosmsg::waam_interfaces::{Block, PlanStatistics, WeldFragment, WeldPlan, WeldPoint};

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

/// Everything about a plan that is not the joint trajectory.
pub struct PlanSummary<'a> {
    pub part: &'a Part,
    /// Fragments in weld order, as block indices of `part`.
    pub fragments: &'a [Vec<usize>],
    pub toolpath: &'a Toolpath,
    pub weld_speed: f64,
    pub transit_speed: f64,
    pub worst_margin_s: f64,
    pub statistics: PlanStatistics,
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
    /// The messages of a block plan with its motion; `plate` places the part frame in the
    /// robot's base link.
    pub fn of_plan(
        plan: &PlanSummary,
        trajectory: &JointTrajectory,
        plate: &Isometry3<f64>,
        header: &Header,
    ) -> Self {
        PlanMessages {
            joint_trajectory: trajectory_msg(trajectory, header),
            poses: pose_array(plan.toolpath, header),
            path: path(plan.toolpath, header),
            markers: markers(plan, plate, header),
            weld_plan: weld_plan(plan, header),
        }
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

/// Our waam_interfaces/WeldPlan: the fragments, and every toolpath point with its arc
/// state, kind, time and commanded speed.
pub fn weld_plan(plan: &PlanSummary, header: &Header) -> WeldPlan {
    let part = plan.part;
    let block_msg = |i: usize| {
        let b = part.block(i);
        Block {
            x: b[0] as i32,
            y: b[1] as i32,
            z: b[2] as i32,
        }
    };
    let fragments = plan
        .fragments
        .iter()
        .map(|f| WeldFragment {
            blocks: f.iter().map(|&i| block_msg(i)).collect(),
        })
        .collect();
    WeldPlan {
        header: header.clone(),
        part_name: part.name.clone(),
        block_pitch: part.block_mm[0] / 1000.0,
        fragments,
        points: weld_points(plan.toolpath),
        weld_speed: plan.weld_speed,
        transit_speed: plan.transit_speed,
        worst_margin_s: plan.worst_margin_s,
        statistics: plan.statistics.clone(),
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

/// A marker to ADD, in `header`'s frame, of `type_`.
fn new_marker(header: &Header, ns: &str, id: i32, type_: i32) -> Marker {
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
pub fn markers(plan: &PlanSummary, plate: &Isometry3<f64>, header: &Header) -> MarkerArray {
    let part = plan.part;
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
    for (f, fragment) in plan.fragments.iter().enumerate() {
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
    out.extend(toolpath_markers(plan.toolpath, width, header));
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

/// The statuses the node reports on `~/status`, one DiagnosticStatus each.
#[derive(Debug, Clone, PartialEq)]
pub enum Status {
    /// An input arrived; `cancelled` names the job it superseded; `settings` are how it
    /// will be turned into a part (for a mesh: the voxelizing settings), for replays.
    Received {
        job: u64,
        source: String,
        cancelled: Option<u64>,
        settings: Vec<KeyValue>,
    },
    Planning {
        job: u64,
        stage: String,
        fraction: Option<f64>,
        detail: String,
    },
    Planned {
        job: u64,
        values: Vec<KeyValue>,
    },
    Error {
        job: Option<u64>,
        reason: String,
    },
    /// Execution news (goals sent, arc switched, done).
    Executing {
        job: u64,
        message: String,
        level: u8,
    },
}

/// The DiagnosticStatus `name` of every status of this node.
pub const STATUS_NAME: &str = "waam_planner";

impl Status {
    /// The status as a DiagnosticArray (level, one-line message, key-value details).
    pub fn to_msg(&self, stamp: Time, hardware_id: &str) -> DiagnosticArray {
        fn kv(key: &str, value: impl ToString) -> KeyValue {
            KeyValue::new(key, value)
        }
        let (level, message, values) = match self {
            Status::Received {
                job,
                source,
                cancelled,
                settings,
            } => {
                let mut message = format!("received part {job} ({source})");
                let mut values = vec![kv("state", "received"), kv("job", job)];
                if let Some(old) = cancelled {
                    message.push_str(&format!("; cancelled planning of part {old}"));
                    values.push(kv("cancelled_job", old));
                }
                values.extend(settings.iter().cloned());
                (DiagnosticStatus::OK, message, values)
            }
            Status::Planning {
                job,
                stage,
                fraction,
                detail,
            } => {
                let mut message = format!("planning part {job}: {stage}");
                let mut values = vec![kv("state", "planning"), kv("job", job), kv("stage", stage)];
                if let Some(f) = fraction {
                    message.push_str(&format!(" {:.0}%", f * 100.0));
                    values.push(kv("progress", format!("{f:.3}")));
                }
                if !detail.is_empty() {
                    message.push_str(&format!(" ({detail})"));
                    values.push(kv("detail", detail));
                }
                (DiagnosticStatus::OK, message, values)
            }
            Status::Planned { job, values } => {
                let mut all = vec![kv("state", "planned"), kv("job", job)];
                all.extend(values.iter().cloned());
                (DiagnosticStatus::OK, format!("planned part {job}"), all)
            }
            Status::Error { job, reason } => {
                let mut values = vec![kv("state", "error"), kv("reason", reason)];
                if let Some(job) = job {
                    values.push(kv("job", job));
                }
                (DiagnosticStatus::ERROR, reason.clone(), values)
            }
            Status::Executing {
                job,
                message,
                level,
            } => (
                *level,
                message.clone(),
                vec![kv("state", "executing"), kv("job", job)],
            ),
        };
        DiagnosticArray {
            header: Header::new(stamp, ""),
            status: vec![DiagnosticStatus {
                level,
                name: STATUS_NAME.to_string(),
                message,
                hardware_id: hardware_id.to_string(),
                values,
            }],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::node::controller::goal_msg;
    use crate::node::pipeline::BUNDLED_URDF;
    use waam_motion::robot::{Robot, TcpChoice};
    use waam_motion::toolpath::ProcessSettings;
    use waam_part::graph::WeldGraph;
    use waam_part::plan::Plan;

    /// s1-wall with its checked sample plan, through the real toolpath and trajectory.
    fn planned() -> (
        Part,
        Vec<Vec<usize>>,
        Toolpath,
        waam_motion::trajectory::JointTrajectory,
    ) {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
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
        let summary = PlanSummary {
            part: &part,
            fragments: &fragments,
            toolpath: &toolpath,
            weld_speed: 0.006,
            transit_speed: 0.1,
            worst_margin_s: 1.5,
            statistics: PlanStatistics::default(),
        };
        let header = Header::new(Time::from_nanos(5_000_000_000), "base_link");
        let plan = weld_plan(&summary, &header);
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
        let markers = markers(&summary, &plate, &header).markers;
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

    #[test]
    fn statuses_carry_state_level_and_reason() {
        let s = Status::Received {
            job: 3,
            source: "mesh".into(),
            cancelled: Some(2),
            settings: vec![KeyValue::new("mesh.name", "mesh-1")],
        }
        .to_msg(Time::default(), "");
        let st = &s.status[0];
        assert_eq!(st.level, DiagnosticStatus::OK);
        assert!(st.message.contains("cancelled planning of part 2"));
        assert!(st.values.contains(&KeyValue::new("cancelled_job", 2)));
        assert!(st.values.contains(&KeyValue::new("mesh.name", "mesh-1")));
        let e = Status::Error {
            job: Some(4),
            reason: "bad part document: x".into(),
        }
        .to_msg(Time::default(), "");
        assert_eq!(e.status[0].level, DiagnosticStatus::ERROR);
        assert_eq!(e.status[0].message, "bad part document: x");
        assert!(e.status[0]
            .values
            .contains(&KeyValue::new("state", "error")));
    }
}
