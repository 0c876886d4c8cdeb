//! A planned layer as ROS 2 messages, for `waam layer plan --record / --publish`: the same
//! plan messages a block plan goes out as (joint trajectory, poses, path, markers, weld
//! plan), a status with the search's figures, and the finite-element temperature field over
//! time as point clouds.

use nalgebra::{Isometry3, Point3};

use crate::convert::{
    delete_all, new_marker, ns, path, point_msg, pose_array, toolpath_markers, trajectory_msg,
    ConvertError, PlanMessages, WeldPlanOf,
};
use crate::heat::point_cloud;
use crate::planning::{recorded, PART_FRAME};
use crate::status::Status;
use crate::topics;
use waam_layer::model::{Model, Trail};
use waam_layer::search::SearchResult;
use waam_motion::toolpath::{ProcessSettings, Toolpath};
use waam_motion::trajectory::JointTrajectory;
use waam_rosbag::{BagError, Qos, Recorder};
use waam_rosmsg::builtin_interfaces::Time;
use waam_rosmsg::diagnostic_msgs::{DiagnosticArray, KeyValue};
use waam_rosmsg::sensor_msgs::PointCloud2;
use waam_rosmsg::std_msgs::{ColorRGBA, Header, String as RosString};
use waam_rosmsg::visualization_msgs::{Marker, MarkerArray};
use waam_rosmsg::waam_interfaces::PlanStatistics;

/// At most this many heat frames per recording (one per time step on the bundled layers).
pub const MAX_HEAT_FRAMES: usize = 600;

/// The search's figures, as the status carries them.
pub fn status_values(model: &Model, r: &SearchResult) -> Vec<KeyValue> {
    vec![
        KeyValue::new("layer", &model.layer.name),
        KeyValue::new("objective", r.objective),
        KeyValue::new("lower_bound", r.lower_bound),
        KeyValue::new("proven_optimal", r.proven_optimal),
        KeyValue::new("gap", r.gap),
        KeyValue::new("relative_gap", r.relative_gap),
        KeyValue::new("nodes_explored", r.nodes_explored),
        KeyValue::new("deadheads", model.deadheads),
        KeyValue::new("seconds", r.seconds),
    ]
}

/// The "planned" status of a searched layer. It is OK even when the time limit cut the
/// proof short: the trail is valid, and `proven_optimal` / `gap` say how good it is.
pub fn planned_status(model: &Model, r: &SearchResult) -> DiagnosticArray {
    recorded(Status::ok("planned", status_values(model, r)))
}

/// The ERROR status of a layer whose motion could not be planned.
pub fn no_motion_status(reason: &str) -> DiagnosticArray {
    recorded(Status::error(format!("no motion: {reason}"), vec![]))
}

/// The search's figures in the block planner's statistics message: every complete trail
/// reached counts as a feasible candidate (a layer has no thermal windows to break).
fn statistics(r: &SearchResult) -> PlanStatistics {
    PlanStatistics {
        candidates: r.leaves,
        feasible: r.leaves,
        optimal: r.proven_optimal,
        time_to_first_feasible_s: f64::NAN,
        total_time_s: r.seconds,
        ..PlanStatistics::default()
    }
}

/// The messages of a layer's validated motion, all with `header` (the robot's base link).
/// The weld plan has no fragments (a layer has no blocks); its `block_pitch` is the wall
/// width, and its points are the toolpath's.
pub fn plan_messages(
    model: &Model,
    r: &SearchResult,
    toolpath: &Toolpath,
    trajectory: &JointTrajectory,
    settings: &ProcessSettings,
    header: &Header,
) -> Result<PlanMessages, ConvertError> {
    let width = model.layer.wall_width_mm / 1000.0;
    let mut markers = vec![
        delete_all(header),
        walls_marker(model, &settings.plate.isometry(), header),
    ];
    markers.extend(toolpath_markers(toolpath, 0.25 * width, header));
    let weld_plan = WeldPlanOf {
        part_name: &model.layer.name,
        block_pitch: width,
        fragments: Vec::new(),
        toolpath: Some(toolpath),
        weld_speed: model.layer.process.weld_speed_mm_s / 1000.0,
        transit_speed: settings.transit_speed_mm_s / 1000.0,
        worst_margin_s: f64::INFINITY,
        statistics: statistics(r),
    }
    .to_msg(header)?;
    Ok(PlanMessages {
        joint_trajectory: trajectory_msg(trajectory, header),
        poses: pose_array(toolpath, header),
        path: path(toolpath, header),
        markers: MarkerArray { markers },
        weld_plan,
    })
}

/// The walls as one LINE_LIST as wide as a wall, on the plate (`plate`: the layer frame in
/// the robot's base link), in place of the blocks of a block plan.
fn walls_marker(model: &Model, plate: &Isometry3<f64>, header: &Header) -> Marker {
    let layer = &model.layer;
    let point = |v: usize| {
        let [x, y] = layer.point(v);
        point_msg(&(plate * Point3::new(x / 1000.0, y / 1000.0, 0.0)))
    };
    let mut marker = new_marker(header, ns::WALLS, 0, Marker::LINE_LIST);
    marker.points = layer
        .segments
        .iter()
        .flat_map(|&[a, b]| [point(a), point(b)])
        .collect();
    marker.color = ColorRGBA {
        r: 1.0,
        g: 1.0,
        b: 1.0,
        a: 0.5,
    };
    marker.scale.x = layer.wall_width_mm / 1000.0;
    marker
}

/// The trail's temperature field (°C at every mesh node; x, y in metres in the layer frame
/// `frame_id`, z = 0) after every time step up to the model's horizon, thinned evenly to at
/// most `max_frames` frames (the last step always included). Stamps are `start` plus the
/// simulated time.
pub fn heat_frames(
    model: &Model,
    trail: &Trail,
    frame_id: &str,
    start: Time,
    max_frames: usize,
) -> Vec<PointCloud2> {
    let mut fields = Vec::new();
    model.simulate(trail, Some(&mut fields));
    let stride = fields.len().div_ceil(max_frames.max(1)).max(1);
    let dt = model.layer.process.time_step_s;
    let ambient = model.layer.temperatures.ambient_c;
    let last = fields.len().saturating_sub(1);
    fields
        .iter()
        .enumerate()
        .filter(|&(n, _)| (n + 1) % stride == 0 || n == last)
        .map(|(n, u)| {
            let stamp =
                Time::from_nanos(start.to_nanos() + ((n + 1) as f64 * dt * 1e9).round() as i64);
            let points = model
                .mesh
                .points
                .iter()
                .zip(u)
                .map(|(p, du)| ([p[0] / 1000.0, p[1] / 1000.0, 0.0], ambient + du));
            point_cloud(points, Header::new(stamp, frame_id))
        })
        .collect()
}

/// How the robot motion of a layer came out, for the recording.
#[derive(Debug, Clone, Copy)]
pub enum MotionOutcome<'a> {
    /// No robot was given.
    NotPlanned,
    /// The validated motion's messages.
    Planned(&'a PlanMessages),
    /// Why there is no motion.
    Failed(&'a str),
}

/// Records one `waam layer plan` run on the node's topics: the layer document as received,
/// a "received" and a "planned" status, the motion's messages (only a validated motion;
/// otherwise an ERROR status saying why there is none) and the temperature field.
pub struct LayerRecording {
    recorder: Recorder,
}

impl LayerRecording {
    /// Records the layer document (`layer_text`) on [`topics::LAYER`] and a "received"
    /// status, and syncs them to disk.
    pub fn start(recorder: &Recorder, layer_text: &str, name: &str) -> Result<Self, BagError> {
        recorder.record(
            topics::LAYER,
            &Qos::reliable(10),
            &RosString::from(layer_text),
        )?;
        recorder.record(
            topics::STATUS,
            &Qos::latched(),
            &recorded(Status::ok("received", vec![KeyValue::new("layer", name)])),
        )?;
        // On disk before the layer is planned (see `PlanningRecorder::start`).
        recorder.sync()?;
        Ok(LayerRecording {
            recorder: recorder.clone(),
        })
    }

    /// Records the outcome; returns the number of heat frames recorded on [`topics::HEAT`].
    pub fn finish(
        self,
        model: &Model,
        r: &SearchResult,
        motion: MotionOutcome,
    ) -> Result<usize, BagError> {
        let now = match motion {
            MotionOutcome::Planned(m) => m.weld_plan.header.stamp,
            _ => Time::now(),
        };
        let latched = Qos::latched();
        self.recorder
            .record_at(topics::STATUS, &latched, now, &planned_status(model, r))?;
        match motion {
            MotionOutcome::NotPlanned => {}
            MotionOutcome::Planned(m) => m.record(&self.recorder)?,
            MotionOutcome::Failed(reason) => {
                self.recorder
                    .record_at(topics::STATUS, &latched, now, &no_motion_status(reason))?
            }
        }
        let frames = heat_frames(model, &r.trail, PART_FRAME, now, MAX_HEAT_FRAMES);
        let qos = Qos::reliable(10);
        for frame in &frames {
            self.recorder
                .record_at(topics::HEAT, &qos, frame.header.stamp, frame)?;
        }
        Ok(frames.len())
    }
}
