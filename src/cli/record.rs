//! Recording a planning run of the CLI (`waam plan --record DIR`) as the node records one.

use std::path::Path;

use anyhow::Context;
use waam_messages::convert::PlanMessages;
use waam_messages::planning::PlanningRecorder;
use waam_part::writer;
use waam_part::Part;
use waam_pipeline::{Cell, Planned};
use waam_planner::{Options, Report};
use waam_ros::node::frames;
use waam_rosbag::Recorder;
use waam_rosmsg::builtin_interfaces::Time;
use waam_rosmsg::std_msgs::Header;

/// Opens the recording of `waam plan --record DIR` and records the part as a part document
/// (synced to disk before this returns, so before planning starts):
/// a part file's own text, the bundled sample's, or, for an STL mesh, the voxelized part that
/// was planned (so that `waam replay` can plan it again). Also records what ties its frames
/// together, as the node publishes it: `/tf_static` (robot base → part, tip → TCP) of the
/// robot's cell, or of the node's default cell without one, and with a robot
/// (`(cell, URDF text)`) its URDF on `/robot_description`.
pub fn start_planning(
    dir: &Path,
    part_file: Option<&Path>,
    part: &Part,
    opts: &Options,
    robot: Option<(&Cell, &str)>,
) -> anyhow::Result<(Recorder, PlanningRecorder)> {
    let is_stl = |p: &Path| p.extension().is_some_and(|e| e.eq_ignore_ascii_case("stl"));
    let text = match part_file {
        Some(path) if is_stl(path) => writer::to_yaml(part),
        Some(path) => std::fs::read_to_string(path)
            .with_context(|| format!("cannot read part {}", path.display()))?,
        None => super::DEFAULT_PART.to_string(),
    };
    let recorder = Recorder::create(dir)?;
    record_frames(&recorder, robot)?;
    let planning = PlanningRecorder::start(&recorder, &text, &part.name, opts)?;
    // Debug: the first run's summary says where the recording is; the kill test waits for
    // this line (`RUST_LOG=waam=debug`).
    tracing::debug!(
        "recording to {}: the part is on disk; planning starts",
        dir.display()
    );
    Ok((recorder, planning))
}

/// Records `/tf_static` (robot base → part, tip → TCP) of the robot's cell, or of the node's
/// default cell without one, and with a robot (`(cell, URDF text)`) `/robot_description`:
/// the frames every recorded message names are then tied together, with the node's names.
pub fn record_frames(recorder: &Recorder, robot: Option<(&Cell, &str)>) -> anyhow::Result<()> {
    match robot {
        Some((cell, urdf)) => frames::record_cell(recorder, cell, Some(urdf), Time::now())?,
        None => frames::record_cell(recorder, &frames::bundled_cell(), None, Time::now())?,
    }
    Ok(())
}

/// A new recording in `dir` (None: not recording) that starts with the cell's frames: the
/// robot's (URDF read from `urdf_path`) or, without one, the node's default cell's.
pub fn layer_recorder(
    dir: Option<&Path>,
    urdf_path: Option<&Path>,
    cell: Option<&Cell>,
) -> anyhow::Result<Option<Recorder>> {
    let Some(dir) = dir else {
        return Ok(None);
    };
    let recorder =
        Recorder::create(dir).with_context(|| format!("cannot record into {}", dir.display()))?;
    let urdf = urdf_text(urdf_path)?;
    record_frames(&recorder, cell.zip(urdf.as_deref()))?;
    Ok(Some(recorder))
}

/// The URDF file's text, when there is one (`--robot`).
pub fn urdf_text(path: Option<&Path>) -> anyhow::Result<Option<String>> {
    path.map(|p| {
        std::fs::read_to_string(p).with_context(|| format!("cannot read robot {}", p.display()))
    })
    .transpose()
}

/// The messages of a planned part, as the node publishes them.
pub fn plan_messages(planned: &Planned) -> anyhow::Result<PlanMessages> {
    let header = Header::new(Time::now(), planned.toolpath.frame.clone());
    Ok(PlanMessages::of_planned(planned, &header)?)
}

/// Records the outcome of a planning run (with the motion's messages when there is one)
/// and closes the recording; what was recorded, for the caller's summary.
pub fn finish_planning(
    recorder: Recorder,
    planning: PlanningRecorder,
    part: &Part,
    report: &Report,
    motion: Option<&PlanMessages>,
) -> anyhow::Result<waam_rosbag::BagSummary> {
    planning.finish(part, report, motion)?;
    Ok(recorder.finish()?)
}
