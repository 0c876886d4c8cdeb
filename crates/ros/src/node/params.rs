//! The node's parameters, read from a ROS 2 parameters file.
//!
//! The file is the one `ros2 run … --ros-args --params-file` takes: a mapping from the node
//! name (`waam_planner`, `/waam_planner` or the wildcard `/**`) to `ros__parameters`. Every
//! key has a default, so a file only needs the keys it changes; an unknown key is an error
//! that names it, because a typo in a cell's config must not be silently ignored.

use std::path::{Path, PathBuf};

use serde::Deserialize;

/// The parameters file shipped with the project; also the defaults of `waam node`.
pub const DEFAULT_PARAMS_YAML: &str = include_str!("../../../../config/waam_planner.params.yaml");

#[derive(Debug, thiserror::Error)]
pub enum ParamsError {
    #[error("cannot read parameters file {path}: {source}")]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("parameters file{where_}: {msg}")]
    Invalid { where_: String, msg: String },
    /// A `-p NAME:=VALUE` the node cannot take.
    #[error("-p {msg}")]
    Override { name: String, msg: String },
}

/// Everything `waam node` can be told through its parameters.
#[derive(Debug, Clone, Default, PartialEq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct NodeParams {
    /// Process settings file (toolpath: placement, TCP angles, speeds, dwell); "" = built-in.
    pub process_file: String,
    pub robot: RobotParams,
    pub planner: PlannerParams,
    pub mesh: MeshParams,
    pub topics: TopicParams,
    pub execution: ExecutionParams,
    pub dry_run: DryRunParams,
    pub closed_loop: ClosedLoopParams,
}

#[derive(Debug, Clone, Default, PartialEq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RobotParams {
    /// URDF of the welding robot; "" = the project's bundled robot.
    pub urdf: String,
    /// Link the TCP is attached to; "" = the URDF's own `tcp` frame.
    pub tip_link: String,
    /// TCP in the tip link: [x, y, z (m), roll, pitch, yaw (rad)]; [] = none (use `tcp` frame).
    pub tcp: Vec<f64>,
    /// MoveIt-style joint_limits.yaml (velocity and acceleration limits); "" = the URDF's
    /// velocity limits and no acceleration limits.
    pub joint_limits: String,
}

#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PlannerParams {
    /// Stop a planning run after this many seconds and use the best plan found (0 = no limit).
    pub timeout_s: f64,
    /// k for parts that do not name one (meshes): the most weld paths allowed.
    pub default_max_fragments: i64,
    /// Refuse a part whose search would need more memory than this, MB (estimated from
    /// its blocks and k before planning starts).
    pub max_memory_mb: i64,
    /// The most threads a planning run uses (racers, workers, each thermal check's
    /// steps); 0 = all cores. Less leaves cores to the robot's driver on a shared PC.
    pub threads: i64,
}

impl PlannerParams {
    /// `max_memory_mb` as the planner takes it (checked positive when read).
    pub fn memory_limit_mb(&self) -> u64 {
        self.max_memory_mb.max(1) as u64
    }

    /// `threads` as the planner takes it (checked in [0, MAX_THREADS] when read).
    pub fn thread_count(&self) -> usize {
        self.threads.max(0) as usize
    }
}

#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MeshParams {
    /// Block pitch [x, y, z] in millimetres for voxelizing `~/part_mesh`.
    pub block_mm: Vec<f64>,
    /// Bead width and layer height [W, H] in millimetres: `~/part_mesh` is sliced into
    /// beads along its contours (a graph part); [] = voxelized with `block_mm`.
    pub bead_mm: Vec<f64>,
    /// A t8/5 window [min_s, max_s] given to every voxelized block; [] = no windows.
    pub t85_window_s: Vec<f64>,
}

/// Topic names: `~/x` is private to the node, `/x` absolute, `x` relative to its namespace.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TopicParams {
    pub part: String,
    pub part_mesh: String,
    pub joint_trajectory: String,
    pub poses: String,
    pub path: String,
    pub markers: String,
    pub weld_plan: String,
    pub status: String,
    pub arc_on: String,
    pub wire_feed: String,
    pub wire_feed_schedule: String,
    pub joint_states: String,
}

#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ExecutionParams {
    /// Send plans to the robot controller (FollowJointTrajectory). Off by default.
    pub enabled: bool,
    /// Run each new plan at once; false: only when a `~/execute` goal asks.
    pub auto_execute: bool,
    /// The controller's FollowJointTrajectory action.
    pub controller_action: String,
    /// The most trajectory points in one goal (MotoROS2 accepts 200).
    pub max_points_per_goal: i64,
    /// Seconds to wait for the action server before giving up on a plan.
    pub server_timeout_s: f64,
    /// Seconds the first goal gives the robot to reach the trajectory's first point.
    pub lead_in_s: f64,
    /// The controller's joint names, in the URDF's joint order (MotoROS2: `group_1/joint_1`
    /// ...); [] = the URDF's names.
    pub joint_names: Vec<String>,
    /// Position tolerance at each goal's end, rad (0 = the controller's default).
    pub goal_tolerance_rad: f64,
    /// Position tolerance along each goal, rad (0 = the controller's default).
    pub path_tolerance_rad: f64,
    /// Time a goal may take beyond its duration, s (0 = the controller's default).
    pub goal_time_tolerance_s: f64,
    /// A std_srvs/Trigger service called before each plan runs (MotoROS2:
    /// `/start_traj_mode`); "" = none.
    pub start_service: String,
}

#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DryRunParams {
    /// Simulated time runs this many times faster than real time (1 = real time).
    pub time_scale: f64,
    /// `/joint_states` messages per second of wall-clock time.
    pub rate_hz: f64,
}

/// The closed loop (#31): the cell's sensors — what they publish on and when their data is
/// too old — and whether to re-plan the rest at each weld-path boundary of an execution.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ClosedLoopParams {
    /// Estimate the model from the sensors and re-plan while `~/execute` runs. Off by
    /// default.
    pub enabled: bool,
    /// In: sensor_msgs/PointCloud2, a layer height scan in the part frame, the base link or
    /// a frame /tf and /tf_static connect to them.
    pub scan_topic: String,
    /// In: sensor_msgs/Temperature, a pyrometer aimed at the torch.
    pub temperature_topic: String,
    /// In: sensor_msgs/PointCloud2 with a `temperature` field (°C), a thermal camera's
    /// image mapped onto the part, placed like a scan.
    pub thermal_camera_topic: String,
    /// In: std_msgs/Header, the welding power source's arc fault (the arc went out on its
    /// own: a wire fault, an arc loss), stamped when the arc went out.
    pub arc_fault_topic: String,
    /// Data stamped longer ago than this (or as far ahead) is late, s.
    pub max_age_s: f64,
    /// Scan and thermal image points farther than this from the part's box are off the
    /// part, mm.
    pub scan_margin_mm: f64,
    /// Each sensor's cadence: it publishes at least this often while an execution runs, s;
    /// a longer silence is a WARN on /diagnostics. 0: no cadence expected (e.g. a scanner
    /// that scans when a layer is done).
    pub scan_period_s: f64,
    pub temperature_period_s: f64,
    pub thermal_camera_period_s: f64,
    /// The wire feed the height rule may set for a weld path, relative to the welder's
    /// nominal schedule: the process limits (1 and 1: the rule is off).
    pub wire_feed_min: f64,
    pub wire_feed_max: f64,
    /// The welder takes a wire feed per deposit along a weld path (`~/wire_feed_schedule`);
    /// false: one per weld path (`~/wire_feed`), the mean of its deposits'.
    pub wire_feed_per_deposit: bool,
    /// How long before a deposit begins its feed may still be revised while the arc is on, s
    /// (the way of `~/wire_feed_schedule` through the welder's bridge).
    pub wire_feed_lead_s: f64,
}

impl Default for ClosedLoopParams {
    fn default() -> Self {
        ClosedLoopParams {
            enabled: false,
            scan_topic: "~/scan".into(),
            temperature_topic: "~/temperature".into(),
            thermal_camera_topic: "~/thermal_image".into(),
            arc_fault_topic: "~/arc_fault".into(),
            max_age_s: 2.0,
            scan_margin_mm: 10.0,
            scan_period_s: 0.0,
            temperature_period_s: 0.0,
            thermal_camera_period_s: 0.0,
            wire_feed_min: 0.7,
            wire_feed_max: 1.3,
            wire_feed_per_deposit: true,
            wire_feed_lead_s: 0.25,
        }
    }
}

impl Default for PlannerParams {
    fn default() -> Self {
        PlannerParams {
            timeout_s: 60.0,
            default_max_fragments: 2,
            max_memory_mb: waam_planner::DEFAULT_MAX_MEMORY_MB as i64,
            threads: 0,
        }
    }
}

impl Default for MeshParams {
    fn default() -> Self {
        MeshParams {
            block_mm: vec![6.0, 6.0, 2.5],
            bead_mm: Vec::new(),
            t85_window_s: Vec::new(),
        }
    }
}

impl Default for TopicParams {
    fn default() -> Self {
        TopicParams {
            part: "~/part".into(),
            part_mesh: "~/part_mesh".into(),
            joint_trajectory: "~/plan/joint_trajectory".into(),
            poses: "~/plan/poses".into(),
            path: "~/plan/path".into(),
            markers: "~/plan/markers".into(),
            weld_plan: "~/plan/weld_plan".into(),
            status: "~/status".into(),
            arc_on: "~/arc_on".into(),
            wire_feed: "~/wire_feed".into(),
            wire_feed_schedule: "~/wire_feed_schedule".into(),
            joint_states: "/joint_states".into(),
        }
    }
}

impl Default for ExecutionParams {
    fn default() -> Self {
        ExecutionParams {
            enabled: false,
            auto_execute: true,
            controller_action: "/joint_trajectory_controller/follow_joint_trajectory".into(),
            max_points_per_goal: 200,
            server_timeout_s: 10.0,
            lead_in_s: 2.0,
            joint_names: Vec::new(),
            goal_tolerance_rad: 0.0,
            path_tolerance_rad: 0.0,
            goal_time_tolerance_s: 0.0,
            start_service: String::new(),
        }
    }
}

impl Default for DryRunParams {
    fn default() -> Self {
        DryRunParams {
            time_scale: 1.0,
            rate_hz: 50.0,
        }
    }
}

/// The longest time limit or wait a parameter may set, s (a week): longer is a typo, and
/// every duration stays far inside what `Duration` and `Instant` can hold.
pub const MAX_WAIT_S: f64 = 7.0 * 24.0 * 3600.0;

/// The most threads `planner.threads` may ask for: the planner's limit.
pub const MAX_THREADS: i64 = waam_planner::MAX_THREADS as i64;

/// Whether a parameters-file node key addresses the node `fqn` (`/ns/name`): its name
/// (`waam_planner`, as this project's files have always said), its full name, or an rcl
/// wildcard (`/**`, `/cell1/*`).
pub fn key_matches(key: &str, fqn: &str) -> bool {
    let base = fqn.rsplit('/').next().unwrap_or(fqn);
    if key == base || key == fqn {
        return true;
    }
    let Some(pattern) = key.strip_prefix('/') else {
        return false;
    };
    let pattern: Vec<&str> = pattern.split('/').collect();
    let name: Vec<&str> = fqn.trim_start_matches('/').split('/').collect();
    glob(&pattern, &name)
}

/// Token glob: `*` one token, `**` any number of tokens.
fn glob(pattern: &[&str], name: &[&str]) -> bool {
    match (pattern.first(), name.first()) {
        (None, None) => true,
        (Some(&"**"), _) => {
            glob(&pattern[1..], name) || (!name.is_empty() && glob(pattern, &name[1..]))
        }
        (Some(&p), Some(&n)) if p == "*" || p == n => glob(&pattern[1..], &name[1..]),
        _ => false,
    }
}

/// A parameter out of its range (the message names it and its value).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{0}")]
pub struct ParamRule(pub String);

impl From<String> for ParamRule {
    fn from(message: String) -> Self {
        ParamRule(message)
    }
}

impl From<&str> for ParamRule {
    fn from(message: &str) -> Self {
        ParamRule(message.to_string())
    }
}

impl NodeParams {
    /// Reads a parameters file for the node `/waam_planner`.
    pub fn from_file(path: &Path) -> Result<NodeParams, ParamsError> {
        NodeParams::load(&[path.to_path_buf()], "/waam_planner", &[])
    }

    /// The defaults, then each file's sections for the node `fqn` in order, then `overrides`
    /// (`-p NAME:=VALUE`), as rcl layers `--params-file` and `-p`.
    pub fn load(
        files: &[PathBuf],
        fqn: &str,
        overrides: &[(String, ros2_client::ParameterValue)],
    ) -> Result<NodeParams, ParamsError> {
        let mut merged = serde_yaml::Mapping::new();
        for path in files {
            let text = std::fs::read_to_string(path).map_err(|source| ParamsError::Read {
                path: path.clone(),
                source,
            })?;
            let found = sections(&text, fqn).map_err(|e| ParamsError::Invalid {
                where_: format!(" {}", path.display()),
                msg: e.to_string(),
            })?;
            merge(&mut merged, &found);
        }
        let invalid = |where_: String, msg: String| ParamsError::Invalid { where_, msg };
        let mut params = from_mapping(merged)
            .map_err(|e| invalid(format!(" {}", join(files)), e.to_string()))?;
        params
            .check()
            .map_err(|e| invalid(format!(" {}", join(files)), e.0))?;
        for (name, value) in overrides {
            super::declared::set(&mut params, name, value, false).map_err(|e| {
                ParamsError::Override {
                    name: name.clone(),
                    msg: e.to_string(),
                }
            })?;
        }
        params.check().map_err(|e| ParamsError::Override {
            name: overrides
                .iter()
                .map(|(n, _)| n.as_str())
                .collect::<Vec<_>>()
                .join(", "),
            msg: e.0,
        })?;
        Ok(params)
    }

    /// Parses parameters-file text for the node `/waam_planner`: the sections of every node
    /// key that names it are merged, later ones winning, as rcl does.
    pub fn parse(text: &str) -> Result<NodeParams, ParamsError> {
        let invalid = |msg: String| ParamsError::Invalid {
            where_: String::new(),
            msg,
        };
        waam_part::yaml::check(text).map_err(|e| invalid(format!("not valid YAML: {e}")))?;
        let merged = sections(text, "/waam_planner").map_err(|e| invalid(e.to_string()))?;
        let params = from_mapping(merged).map_err(|e| invalid(e.to_string()))?;
        params.check().map_err(|e| invalid(e.0))?;
        Ok(params)
    }

    /// The shipped defaults.
    pub fn defaults() -> NodeParams {
        NodeParams::parse(DEFAULT_PARAMS_YAML).expect("the bundled parameters file is valid")
    }

    /// Rules serde cannot express: ranges and list lengths.
    pub fn check(&self) -> Result<(), ParamRule> {
        let finite_pos = |v: f64| v.is_finite() && v > 0.0;
        if !(self.planner.timeout_s.is_finite()
            && (0.0..=MAX_WAIT_S).contains(&self.planner.timeout_s))
        {
            return Err(ParamRule(format!(
                "planner.timeout_s: expected seconds in [0, {MAX_WAIT_S}], got {:?}",
                self.planner.timeout_s
            )));
        }
        if self.planner.max_memory_mb < 1 {
            return Err(ParamRule(format!(
                "planner.max_memory_mb: expected an integer >= 1 (MB), got {}",
                self.planner.max_memory_mb
            )));
        }
        if !(0..=MAX_THREADS).contains(&self.planner.threads) {
            return Err(ParamRule(format!(
                "planner.threads: expected an integer in [0, {MAX_THREADS}] (0 = all cores), got {}",
                self.planner.threads
            )));
        }
        if self.planner.default_max_fragments < 1 {
            return Err(ParamRule(format!(
                "planner.default_max_fragments: expected an integer >= 1, got {}",
                self.planner.default_max_fragments
            )));
        }
        if self.mesh.block_mm.len() != 3 || !self.mesh.block_mm.iter().all(|&v| finite_pos(v)) {
            return Err(ParamRule(format!(
                "mesh.block_mm: expected three lengths > 0 (mm), got {:?}",
                self.mesh.block_mm
            )));
        }
        match self.mesh.bead_mm[..] {
            [] => {}
            [w, h] if finite_pos(w) && finite_pos(h) => {}
            _ => {
                return Err(ParamRule(format!(
                    "mesh.bead_mm: expected [] or [width, layer height] > 0 (mm), got {:?}",
                    self.mesh.bead_mm
                )))
            }
        }
        match self.mesh.t85_window_s[..] {
            [] => {}
            [min, max] if min.is_finite() && max.is_finite() && 0.0 <= min && min <= max => {}
            _ => {
                return Err(ParamRule(format!(
                    "mesh.t85_window_s: expected [] or [min_s, max_s] with 0 <= min_s <= max_s, got {:?}",
                    self.mesh.t85_window_s
                )))
            }
        }
        if !(self.robot.tcp.is_empty() || self.robot.tcp.len() == 6)
            || self.robot.tcp.iter().any(|v| !v.is_finite())
        {
            return Err(ParamRule(format!(
                "robot.tcp: expected [] or [x, y, z, roll, pitch, yaw] (m, rad), got {:?}",
                self.robot.tcp
            )));
        }
        if self.execution.max_points_per_goal < 1 {
            return Err(ParamRule(format!(
                "execution.max_points_per_goal: expected an integer >= 1, got {}",
                self.execution.max_points_per_goal
            )));
        }
        if !(finite_pos(self.execution.server_timeout_s)
            && self.execution.server_timeout_s <= MAX_WAIT_S)
        {
            return Err(ParamRule(format!(
                "execution.server_timeout_s: expected seconds in (0, {MAX_WAIT_S}], got {:?}",
                self.execution.server_timeout_s
            )));
        }
        if !(self.execution.lead_in_s.is_finite() && self.execution.lead_in_s >= 0.0) {
            return Err(ParamRule(format!(
                "execution.lead_in_s: expected seconds >= 0, got {:?}",
                self.execution.lead_in_s
            )));
        }
        for (key, v) in [
            ("goal_tolerance_rad", self.execution.goal_tolerance_rad),
            ("path_tolerance_rad", self.execution.path_tolerance_rad),
            (
                "goal_time_tolerance_s",
                self.execution.goal_time_tolerance_s,
            ),
        ] {
            if !(v.is_finite() && (0.0..=MAX_WAIT_S).contains(&v)) {
                return Err(ParamRule(format!(
                    "execution.{key}: expected a tolerance >= 0 (0 = the controller's default), got {v}"
                )));
            }
        }
        let names = &self.execution.joint_names;
        if names.iter().any(|n| n.trim().is_empty())
            || names
                .iter()
                .enumerate()
                .any(|(i, n)| names[..i].contains(n))
        {
            return Err(ParamRule(format!(
                "execution.joint_names: expected [] or distinct, non-empty names, got {names:?}"
            )));
        }
        if !finite_pos(self.dry_run.time_scale) {
            return Err(ParamRule(format!(
                "dry_run.time_scale: expected a factor > 0, got {:?}",
                self.dry_run.time_scale
            )));
        }
        if !(finite_pos(self.dry_run.rate_hz) && self.dry_run.rate_hz <= 1000.0) {
            return Err(ParamRule(format!(
                "dry_run.rate_hz: expected 0 < rate <= 1000, got {:?}",
                self.dry_run.rate_hz
            )));
        }
        let cl = &self.closed_loop;
        if !(finite_pos(cl.max_age_s) && cl.max_age_s <= MAX_WAIT_S) {
            return Err(ParamRule(format!(
                "closed_loop.max_age_s: expected seconds in (0, {MAX_WAIT_S}], got {:?}",
                cl.max_age_s
            )));
        }
        if !(cl.scan_margin_mm.is_finite() && (0.0..=1e6).contains(&cl.scan_margin_mm)) {
            return Err(ParamRule(format!(
                "closed_loop.scan_margin_mm: expected a length in [0, 1e6] (mm), got {:?}",
                cl.scan_margin_mm
            )));
        }
        for (name, period_s) in [
            ("scan_period_s", cl.scan_period_s),
            ("temperature_period_s", cl.temperature_period_s),
            ("thermal_camera_period_s", cl.thermal_camera_period_s),
        ] {
            if !(period_s.is_finite() && (0.0..=MAX_WAIT_S).contains(&period_s)) {
                return Err(ParamRule(format!(
                    "closed_loop.{name}: expected seconds in [0, {MAX_WAIT_S}] (0: no \
                     cadence), got {period_s:?}"
                )));
            }
        }
        if !(finite_pos(cl.wire_feed_min)
            && cl.wire_feed_min <= 1.0
            && cl.wire_feed_max >= 1.0
            && cl.wire_feed_max <= 10.0)
        {
            return Err(ParamRule(format!(
                "closed_loop.wire_feed_min, wire_feed_max: expected 0 < min <= 1 <= max <= 10 \
                 (relative to the nominal wire feed), got {:?} and {:?}",
                cl.wire_feed_min, cl.wire_feed_max
            )));
        }
        Ok(())
    }
}

fn join(files: &[PathBuf]) -> String {
    let names: Vec<String> = files.iter().map(|f| f.display().to_string()).collect();
    names.join(", ")
}

/// What is wrong with the node sections of a parameters file.
#[derive(Debug, thiserror::Error)]
enum SectionError {
    #[error("not valid YAML: {0}")]
    Yaml(#[from] serde_yaml::Error),
    #[error("expected a mapping from node name to ros__parameters")]
    NotAMapping,
    #[error("'{0}' must be a mapping with 'ros__parameters'")]
    SectionNotAMapping(String),
    #[error("'{name}': unknown key {key:?} (only 'ros__parameters')")]
    UnknownKey { name: String, key: String },
    #[error("'{0}.ros__parameters' must be a mapping")]
    ParametersNotAMapping(String),
    #[error("no section for this node: expected one of {base}, {fqn}, /** (or an rcl wildcard)")]
    NoSection { base: String, fqn: String },
    #[error("use_sim_time: this node runs on wall-clock time only (false)")]
    SimTime,
}

/// A parameter with a value of the wrong type, or one this node does not have, named by its
/// path (`ros__parameters.closed_loop.enabled: invalid type ...`), not only by its type.
#[derive(Debug, thiserror::Error)]
#[error("ros__parameters{path}: {msg}")]
struct WrongValue {
    path: String,
    msg: String,
}

/// The merged `ros__parameters` as parameters.
fn from_mapping(merged: serde_yaml::Mapping) -> Result<NodeParams, WrongValue> {
    serde_path_to_error::deserialize(serde_yaml::Value::Mapping(merged)).map_err(|e| {
        let path = e.path().to_string();
        WrongValue {
            path: if path == "." {
                String::new()
            } else {
                format!(".{path}")
            },
            msg: e.into_inner().to_string(),
        }
    })
}

/// The `ros__parameters` of every section of `text` whose key addresses the node `fqn`,
/// merged in file order.
fn sections(text: &str, fqn: &str) -> Result<serde_yaml::Mapping, SectionError> {
    let doc: serde_yaml::Value = serde_yaml::from_str(text)?;
    let serde_yaml::Value::Mapping(nodes) = doc else {
        return Err(SectionError::NotAMapping);
    };
    let mut merged = serde_yaml::Mapping::new();
    let mut found = false;
    for (key, section) in &nodes {
        let Some(name) = key.as_str().filter(|k| key_matches(k, fqn)) else {
            continue; // parameters for other nodes of the same launch
        };
        found = true;
        let section = section
            .as_mapping()
            .ok_or_else(|| SectionError::SectionNotAMapping(name.to_string()))?;
        for (k, v) in section {
            if k.as_str() != Some("ros__parameters") {
                return Err(SectionError::UnknownKey {
                    name: name.to_string(),
                    key: k.as_str().unwrap_or("?").to_string(),
                });
            }
            let serde_yaml::Value::Mapping(params) = v else {
                return Err(SectionError::ParametersNotAMapping(name.to_string()));
            };
            merge(&mut merged, params);
        }
    }
    if !found {
        let base = fqn.rsplit('/').next().unwrap_or(fqn);
        return Err(SectionError::NoSection {
            base: base.to_string(),
            fqn: fqn.to_string(),
        });
    }
    // rcl's node-wide `use_sim_time` is declared by every node; only `false` is honoured.
    if let Some(v) = merged.remove("use_sim_time") {
        if v != serde_yaml::Value::Bool(false) {
            return Err(SectionError::SimTime);
        }
    }
    Ok(merged)
}

/// Deep-merges `from` into `into` (nested mappings merge, everything else replaces).
fn merge(into: &mut serde_yaml::Mapping, from: &serde_yaml::Mapping) {
    for (k, v) in from {
        match (into.get_mut(k), v) {
            (Some(serde_yaml::Value::Mapping(a)), serde_yaml::Value::Mapping(b)) => merge(a, b),
            _ => {
                into.insert(k.clone(), v.clone());
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bundled_file_is_the_defaults() {
        assert_eq!(NodeParams::defaults(), NodeParams::default());
    }

    #[test]
    fn sections_merge_and_later_wins() {
        let p = NodeParams::parse(
            "/**:\n  ros__parameters:\n    planner: {timeout_s: 5.0}\n\
             waam_planner:\n  ros__parameters:\n    planner: {default_max_fragments: 3}\n\
             other_node:\n  ros__parameters: {x: 1}\n",
        )
        .unwrap();
        assert_eq!(p.planner.timeout_s, 5.0);
        assert_eq!(p.planner.default_max_fragments, 3);
        assert_eq!(p.topics.part, "~/part");
    }

    #[test]
    fn node_keys_match_as_rcl_does() {
        for key in [
            "waam_planner",
            "/cell1/waam_planner",
            "/**",
            "/cell1/*",
            "/**/waam_planner",
        ] {
            assert!(key_matches(key, "/cell1/waam_planner"), "{key}");
        }
        for key in ["/waam_planner", "/cell2/*", "/*", "other"] {
            assert!(!key_matches(key, "/cell1/waam_planner"), "{key}");
        }
    }

    #[test]
    fn files_then_overrides() {
        let dir = tempfile::tempdir().unwrap();
        let a = dir.path().join("a.yaml");
        let b = dir.path().join("b.yaml");
        std::fs::write(
            &a,
            "/**:\n  ros__parameters:\n    planner: {timeout_s: 5.0}\n    use_sim_time: false\n",
        )
        .unwrap();
        std::fs::write(
            &b,
            "/cell1/waam_planner:\n  ros__parameters:\n    planner: {default_max_fragments: 3}\n",
        )
        .unwrap();
        let p = NodeParams::load(
            &[a.clone(), b.clone()],
            "/cell1/waam_planner",
            &[(
                "mesh.block_mm".into(),
                ros2_client::ParameterValue::IntegerArray(vec![12, 6, 2]),
            )],
        )
        .unwrap();
        assert_eq!(p.planner.timeout_s, 5.0);
        assert_eq!(p.planner.default_max_fragments, 3);
        assert_eq!(p.mesh.block_mm, vec![12.0, 6.0, 2.0]);
        let e = NodeParams::load(
            &[a],
            "/cell1/waam_planner",
            &[(
                "mesh.block_mm".into(),
                ros2_client::ParameterValue::IntegerArray(vec![1]),
            )],
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("mesh.block_mm"), "{e}");
        let e = NodeParams::load(&[b], "/cell2/waam_planner", &[])
            .unwrap_err()
            .to_string();
        assert!(e.contains("no section"), "{e}");
    }

    #[test]
    fn errors_name_the_key() {
        let err = |text: &str| NodeParams::parse(text).unwrap_err().to_string();
        let e = err("waam_planner:\n  ros__parameters:\n    planer: {timeout_s: 1}\n");
        assert!(e.contains("unknown field `planer`"), "{e}");
        let e = err("waam_planner:\n  ros__parameters:\n    execution: {max_points_per_goal: 0}\n");
        assert!(e.contains("execution.max_points_per_goal"), "{e}");
        let e = err("waam_planner:\n  ros__parameters:\n    mesh: {block_mm: [1, 2]}\n");
        assert!(e.contains("mesh.block_mm"), "{e}");
        let e = err("waam_planner:\n  ros__parameters:\n    mesh: {t85_window_s: [5, 1]}\n");
        assert!(e.contains("mesh.t85_window_s"), "{e}");
        let e = err("waam_planner:\n  ros__parameters:\n    robot: {tcp: [0, 0]}\n");
        assert!(e.contains("robot.tcp"), "{e}");
        let e = err("waam_planner:\n  ros__parameters:\n    closed_loop: {max_age_s: 0}\n");
        assert!(e.contains("closed_loop.max_age_s"), "{e}");
        let e = err("waam_planner:\n  ros__parameters:\n    closed_loop: {scan_margin_mm: -1}\n");
        assert!(e.contains("closed_loop.scan_margin_mm"), "{e}");
        let e = err(
            "waam_planner:\n  ros__parameters:\n    closed_loop: {temperature_period_s: -0.1}\n",
        );
        assert!(e.contains("closed_loop.temperature_period_s"), "{e}");
        let e = err("waam_planner:\n  ros__parameters:\n    closed_loop: {enabled: \"yes\"}\n");
        assert!(e.contains("closed_loop.enabled: invalid type"), "{e}");
        let e = err("someone_else:\n  ros__parameters: {}\n");
        assert!(e.contains("no section for this node"), "{e}");
        let e = err("/cell1/*:\n  ros__parameters: {}\n");
        assert!(e.contains("no section for this node"), "{e}");
        let e = err("waam_planner:\n  params: {}\n");
        assert!(e.contains("only 'ros__parameters'"), "{e}");
        let e = err("[1, 2");
        assert!(e.contains("not valid YAML"), "{e}");
    }
}
