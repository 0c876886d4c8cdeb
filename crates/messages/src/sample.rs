//! A synthetic session with one message of every recorded type per round, on the node's
//! topics, built from a real part and a real thermal simulation (but a fixed serpentine weld
//! order and made-up joint angles, not a planned and solved trajectory). For tests of the
//! recording path and the readers, and for trying Foxglove on a bag without a cell.

use std::collections::BTreeMap;

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};

use crate::convert::{
    block_fragments, markers, path, pose_array, trajectory_msg, WeldPlanOf, NODE_NAME,
};
use crate::heat::{heat_frames, HeatOptions};
use crate::status::Status;
use crate::topics;
use waam_motion::toolpath::{PoseKind, ToolPose, Toolpath};
use waam_motion::trajectory::TrajectoryPoint;
use waam_part::graph::WeldGraph;
use waam_part::Part;
use waam_rosbag::{BagError, Qos, Recorder};
use waam_rosmsg::builtin_interfaces::Time;
use waam_rosmsg::diagnostic_msgs::KeyValue;
use waam_rosmsg::geometry_msgs::Point;
use waam_rosmsg::rcl_interfaces::Log;
use waam_rosmsg::sensor_msgs::{JointState, PointCloud2};
use waam_rosmsg::shape_msgs::{Mesh, MeshTriangle};
use waam_rosmsg::std_msgs::{Bool, Header, String as RosString};
use waam_rosmsg::waam_interfaces::{Block, PlanCandidate, PlanStatistics};
use waam_rosmsg::RosMessage;
use waam_thermal::ThermalModel;

/// The part the sample session builds.
pub const PART_TEXT: &str = include_str!("../../../config/parts/s1-wall.yaml");
/// Frame of the sample's poses.
pub const FRAME: &str = "base_link";
const JOINTS: [&str; 6] = [
    "joint_1", "joint_2", "joint_3", "joint_4", "joint_5", "joint_6",
];

/// Per topic: type name and messages recorded.
pub type Counts = BTreeMap<String, (String, u64)>;

/// Records sample rounds into a recorder, counting what it wrote.
pub struct SampleSession {
    part: Part,
    fragments: Vec<Vec<usize>>,
    heat: Vec<PointCloud2>,
    pub counts: Counts,
}

impl SampleSession {
    pub fn new() -> SampleSession {
        let part = Part::parse(PART_TEXT).expect("the bundled sample part is valid");
        // Serpentine: each layer along x, alternating direction, one fragment per layer pair.
        let mut order: Vec<usize> = Vec::new();
        for z in 0..part.layers() {
            let mut layer: Vec<usize> =
                (0..part.len()).filter(|&i| part.block(i)[2] == z).collect();
            if z % 2 == 1 {
                layer.reverse();
            }
            order.extend(layer);
        }
        let fragments = vec![order];
        let graph = WeldGraph::new(&part);
        let model = ThermalModel::new(&part, &graph);
        let mut heat = Vec::new();
        heat_frames(
            &part,
            &model,
            &fragments,
            "part",
            Time::default(),
            HeatOptions { max_frames: 4 },
            |f| {
                heat.push(f.cloud);
                Ok::<_, ()>(())
            },
        )
        .expect("collecting frames cannot fail");
        SampleSession {
            part,
            fragments,
            heat,
            counts: Counts::new(),
        }
    }

    fn record<M: RosMessage>(
        &mut self,
        recorder: &Recorder,
        topic: &str,
        qos: &Qos,
        message: &M,
    ) -> Result<(), BagError> {
        recorder.record(topic, qos, message)?;
        let entry = self
            .counts
            .entry(topic.to_string())
            .or_insert_with(|| (M::TYPE_NAME.to_string(), 0));
        entry.1 += 1;
        Ok(())
    }

    /// Records one round: a part in (as text and as a mesh), everything the node publishes for
    /// it, a log line, a planner candidate and the heat frames.
    pub fn round(&mut self, recorder: &Recorder, round: u64) -> Result<(), BagError> {
        let now = Time::now();
        let header = Header::new(now, FRAME);
        let part_msg = RosString::from(PART_TEXT);
        self.record(recorder, topics::PART, &Qos::reliable(10), &part_msg)?;
        let mesh = self.mesh();
        self.record(recorder, topics::PART_MESH, &Qos::reliable(10), &mesh)?;

        // The made-up motion as domain values, then through the one builder of each message.
        let toolpath = self.toolpath();
        let trajectory = self.trajectory(toolpath.poses.len());
        let latched = Qos::latched();
        let joint_trajectory = trajectory_msg(&trajectory, &header);
        self.record(
            recorder,
            topics::JOINT_TRAJECTORY,
            &latched,
            &joint_trajectory,
        )?;
        self.record(
            recorder,
            topics::POSES,
            &latched,
            &pose_array(&toolpath, &header),
        )?;
        self.record(recorder, topics::PATH, &latched, &path(&toolpath, &header))?;
        let markers = markers(
            &self.part,
            &self.fragments,
            &toolpath,
            &Isometry3::identity(),
            &header,
        );
        self.record(recorder, topics::MARKERS, &latched, &markers)?;
        let plan = WeldPlanOf {
            part_name: &self.part.name,
            block_pitch: self.part.block_mm[0] / 1000.0,
            fragments: block_fragments(&self.part, &self.fragments),
            toolpath: Some(&toolpath),
            weld_speed: 0.006,
            transit_speed: 0.1,
            worst_margin_s: 0.5,
            statistics: PlanStatistics::default(),
        }
        .to_msg(&header)
        .map_err(|e| BagError::Corrupt {
            path: "sample".into(),
            reason: e.to_string(),
        })?;
        self.record(recorder, topics::WELD_PLAN, &latched, &plan)?;
        let status = Status::ok(
            format!("planned (sample round {round})"),
            vec![
                KeyValue::new("part", &self.part.name),
                KeyValue::new("fragments", self.fragments.len()),
            ],
        )
        .to_msg(header.stamp, NODE_NAME);
        self.record(recorder, topics::STATUS, &Qos::latched(), &status)?;
        for on in [true, false] {
            self.record(
                recorder,
                topics::ARC_ON,
                &Qos::reliable(10),
                &Bool { data: on },
            )?;
        }
        let joints = JointState {
            header: header.clone(),
            name: joint_trajectory.joint_names.clone(),
            position: joint_trajectory.points[0].positions.clone(),
            velocity: vec![0.0; 6],
            effort: Vec::new(),
        };
        self.record(
            recorder,
            topics::JOINT_STATES,
            &Qos::best_effort(10),
            &joints,
        )?;
        let log = Log {
            stamp: now,
            level: Log::INFO,
            name: "waam_planner".into(),
            msg: format!("sample round {round}"),
            file: file!().into(),
            function: "round".into(),
            line: line!(),
        };
        self.record(recorder, topics::ROSOUT, &Qos::rosout(), &log)?;
        let candidate = PlanCandidate {
            header: header.clone(),
            index: round + 1,
            verdict: PlanCandidate::TOO_SHORT,
            prefix_len: 3,
            block: Block { x: 1, y: 0, z: 0 },
            time_s: 4.5,
            learned_clause_len: 7,
        };
        self.record(
            recorder,
            topics::CANDIDATES,
            &Qos::reliable(100),
            &candidate,
        )?;
        for cloud in self.heat.clone() {
            let mut cloud = cloud;
            cloud.header.stamp = now;
            self.record(recorder, topics::HEAT, &Qos::reliable(10), &cloud)?;
        }
        Ok(())
    }

    /// The torch along the serpentine, one pose a second at the top centre of each block
    /// (metres, pointing down), arc on from the first to the last.
    fn toolpath(&self) -> Toolpath {
        let order = &self.fragments[0];
        let down = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI);
        let poses = order
            .iter()
            .enumerate()
            .map(|(i, &b)| {
                let c = self.part.centre_mm(self.part.block(b));
                let top = Translation3::new(
                    c[0] / 1000.0,
                    c[1] / 1000.0,
                    (c[2] + self.part.block_mm[2] / 2.0) / 1000.0,
                );
                ToolPose {
                    time_s: i as f64,
                    pose: Isometry3::from_parts(top, down),
                    arc_on: true,
                    fragment: 0,
                    point: i,
                    kind: match i {
                        0 => PoseKind::ArcOn,
                        _ if i + 1 == order.len() => PoseKind::ArcOff,
                        _ => PoseKind::Weld,
                    },
                    at_point: true,
                }
            })
            .collect();
        Toolpath {
            frame: FRAME.into(),
            poses,
        }
    }

    /// Made-up joint angles, one point a second.
    fn trajectory(&self, n: usize) -> waam_motion::trajectory::JointTrajectory {
        waam_motion::trajectory::JointTrajectory {
            base_link: FRAME.into(),
            tip_link: "tool0".into(),
            tcp_offset: Isometry3::identity(),
            joint_names: JOINTS.iter().map(|s| s.to_string()).collect(),
            points: (0..n)
                .map(|i| TrajectoryPoint {
                    positions: (0..6).map(|j| 0.1 * j as f64 + 0.01 * i as f64).collect(),
                    velocities: vec![0.01; 6],
                    accelerations: Vec::new(),
                    time_from_start: i as f64,
                    arc_on: true,
                })
                .collect(),
        }
    }

    /// The part's bounding box as a triangle mesh (metres).
    fn mesh(&self) -> Mesh {
        let lo = self.part.centre_mm(self.part.block(0));
        let hi = self.part.centre_mm(self.part.block(self.part.len() - 1));
        let h = self.part.block_mm.map(|v| v / 2.0);
        let (lo, hi) = (
            [lo[0] - h[0], lo[1] - h[1], lo[2] - h[2]],
            [hi[0] + h[0], hi[1] + h[1], hi[2] + h[2]],
        );
        let vertices = (0..8)
            .map(|i| Point {
                x: if i & 1 == 0 { lo[0] } else { hi[0] } / 1000.0,
                y: if i & 2 == 0 { lo[1] } else { hi[1] } / 1000.0,
                z: if i & 4 == 0 { lo[2] } else { hi[2] } / 1000.0,
            })
            .collect();
        const FACES: [[u32; 3]; 12] = [
            [0, 2, 1],
            [1, 2, 3],
            [4, 5, 6],
            [5, 7, 6],
            [0, 1, 4],
            [1, 5, 4],
            [2, 6, 3],
            [3, 6, 7],
            [0, 4, 2],
            [2, 4, 6],
            [1, 3, 5],
            [3, 7, 5],
        ];
        Mesh {
            triangles: FACES
                .iter()
                .map(|&vertex_indices| MeshTriangle { vertex_indices })
                .collect(),
            vertices,
        }
    }
}

impl Default for SampleSession {
    fn default() -> Self {
        SampleSession::new()
    }
}
