//! The node's settings as declared ROS 2 parameters: every key of the parameters file under
//! its dotted name (`planner.timeout_s`), with type, range, description and whether it may
//! change while the node runs. `-p NAME:=VALUE` and the parameter services go through here.

use ros2_client::parameters::{NumericRange, ParameterDescriptor, ParameterType};
use ros2_client::ParameterValue;

use super::params::{NodeParams, MAX_THREADS, MAX_WAIT_S};

/// One declared parameter.
pub struct Declared {
    pub name: &'static str,
    pub description: &'static str,
    /// Rules the range cannot say.
    pub constraints: &'static str,
    pub range: Range,
    /// Read at start only (topics, execution, robot): a change needs a restart.
    pub read_only: bool,
    get: fn(&NodeParams) -> ParameterValue,
    set: fn(&mut NodeParams, &ParameterValue) -> Result<(), ParamError>,
}

/// A parameter that cannot be set (`-p`, the parameter services), and why.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ParamError {
    #[error("{name}: expected a {expected}, got a {got}")]
    Type {
        name: &'static str,
        expected: &'static str,
        got: &'static str,
    },
    #[error("{}: this node runs on wall-clock time only (false)", USE_SIM_TIME)]
    SimTime,
    #[error("{0}: no such parameter")]
    Unknown(String),
    #[error("{0} is read only while the node runs (restart it with -p {0}:=VALUE)")]
    ReadOnly(String),
    #[error("{text:?} is not YAML: {reason}")]
    NotYaml { text: String, reason: String },
    #[error("{0:?}: not a parameter value (a scalar or a list of one type)")]
    NotAValue(String),
}

#[derive(Clone, Copy)]
pub enum Range {
    None,
    Int(i64, i64),
    Float(f64, f64),
}

/// A Rust type a parameter holds.
trait Kind: Sized {
    const TYPE: ParameterType;
    fn to_value(&self) -> ParameterValue;
    fn from_value(v: &ParameterValue) -> Option<Self>;
}

impl Kind for f64 {
    const TYPE: ParameterType = ParameterType::Double;
    fn to_value(&self) -> ParameterValue {
        ParameterValue::Double(*self)
    }
    fn from_value(v: &ParameterValue) -> Option<f64> {
        match v {
            ParameterValue::Double(d) => Some(*d),
            // `ros2 param set … 5` sends an integer; a whole number of seconds is meant.
            ParameterValue::Integer(i) => Some(*i as f64),
            _ => None,
        }
    }
}

impl Kind for i64 {
    const TYPE: ParameterType = ParameterType::Integer;
    fn to_value(&self) -> ParameterValue {
        ParameterValue::Integer(*self)
    }
    fn from_value(v: &ParameterValue) -> Option<i64> {
        match v {
            ParameterValue::Integer(i) => Some(*i),
            _ => None,
        }
    }
}

impl Kind for bool {
    const TYPE: ParameterType = ParameterType::Bool;
    fn to_value(&self) -> ParameterValue {
        ParameterValue::Boolean(*self)
    }
    fn from_value(v: &ParameterValue) -> Option<bool> {
        match v {
            ParameterValue::Boolean(b) => Some(*b),
            _ => None,
        }
    }
}

impl Kind for String {
    const TYPE: ParameterType = ParameterType::String;
    fn to_value(&self) -> ParameterValue {
        ParameterValue::String(self.clone())
    }
    fn from_value(v: &ParameterValue) -> Option<String> {
        match v {
            ParameterValue::String(s) => Some(s.clone()),
            _ => None,
        }
    }
}

impl Kind for Vec<f64> {
    const TYPE: ParameterType = ParameterType::DoubleArray;
    fn to_value(&self) -> ParameterValue {
        ParameterValue::DoubleArray(self.clone())
    }
    fn from_value(v: &ParameterValue) -> Option<Vec<f64>> {
        match v {
            ParameterValue::DoubleArray(d) => Some(d.clone()),
            ParameterValue::IntegerArray(i) => Some(i.iter().map(|&i| i as f64).collect()),
            // An empty list has no element type on the command line.
            ParameterValue::StringArray(a) if a.is_empty() => Some(Vec::new()),
            ParameterValue::BooleanArray(a) if a.is_empty() => Some(Vec::new()),
            _ => None,
        }
    }
}

impl Kind for Vec<String> {
    const TYPE: ParameterType = ParameterType::StringArray;
    fn to_value(&self) -> ParameterValue {
        ParameterValue::StringArray(self.clone())
    }
    fn from_value(v: &ParameterValue) -> Option<Vec<String>> {
        match v {
            ParameterValue::StringArray(a) => Some(a.clone()),
            ParameterValue::DoubleArray(a) if a.is_empty() => Some(Vec::new()),
            ParameterValue::IntegerArray(a) if a.is_empty() => Some(Vec::new()),
            ParameterValue::BooleanArray(a) if a.is_empty() => Some(Vec::new()),
            _ => None,
        }
    }
}

fn type_name(t: ParameterType) -> &'static str {
    match t {
        ParameterType::NotSet => "not set",
        ParameterType::Bool => "bool",
        ParameterType::Integer => "integer",
        ParameterType::Double => "double",
        ParameterType::String => "string",
        ParameterType::ByteArray => "byte array",
        ParameterType::BoolArray => "bool array",
        ParameterType::IntegerArray => "integer array",
        ParameterType::DoubleArray => "double array",
        ParameterType::StringArray => "string array",
    }
}

macro_rules! declare {
    ($name:literal, $($field:ident).+ : $ty:ty, $ro:expr, $range:expr, $desc:literal, $cons:literal) => {
        Declared {
            name: $name,
            description: $desc,
            constraints: $cons,
            range: $range,
            read_only: $ro,
            get: |p| <$ty as Kind>::to_value(&p.$($field).+),
            set: |p, v| {
                p.$($field).+ = <$ty as Kind>::from_value(v).ok_or_else(|| ParamError::Type {
                    name: $name,
                    expected: type_name(<$ty as Kind>::TYPE),
                    got: type_name(v.to_parameter_type()),
                })?;
                Ok(())
            },
        }
    };
}

const RUNTIME: bool = false;
const AT_START: bool = true;

/// Every parameter of the node, in the order of the parameters file.
pub static DECLARED: &[Declared] = &[
    declare!("process_file", process_file: String, RUNTIME, Range::None,
        "Process settings file (part placement, torch angles, speeds, dwell); \"\" = built-in",
        "a readable process settings YAML file, or \"\""),
    declare!("robot.urdf", robot.urdf: String, AT_START, Range::None,
        "URDF of the welding robot; \"\" = the project's bundled robot", ""),
    declare!("robot.tip_link", robot.tip_link: String, AT_START, Range::None,
        "Link carrying the TCP; \"\" = the URDF's own `tcp` frame", ""),
    declare!("robot.tcp", robot.tcp: Vec<f64>, AT_START, Range::None,
        "TCP in the tip link: [x, y, z (m), roll, pitch, yaw (rad)]; [] = the tcp frame",
        "[] or 6 finite numbers"),
    declare!("robot.joint_limits", robot.joint_limits: String, AT_START, Range::None,
        "MoveIt-style joint_limits.yaml (velocity, acceleration limits); \"\" = the URDF's velocity limits only",
        "a readable joint limits YAML file, or \"\""),
    declare!("planner.timeout_s", planner.timeout_s: f64, RUNTIME, Range::Float(0.0, MAX_WAIT_S),
        "Stop a planning run after this many seconds and use the best plan found (0 = no limit)", ""),
    declare!("planner.default_max_fragments", planner.default_max_fragments: i64, RUNTIME,
        Range::Int(1, 1000),
        "k for parts that do not name one (meshes): the most weld paths allowed", ""),
    declare!("planner.max_memory_mb", planner.max_memory_mb: i64, RUNTIME,
        Range::Int(1, 1 << 40),
        "Refuse a part whose search would need more memory than this, MB (estimated from its blocks and k)", ""),
    declare!("planner.threads", planner.threads: i64, RUNTIME, Range::Int(0, MAX_THREADS),
        "The most threads a planning run uses: the race's racers, the workers, each thermal check's steps (0 = all cores)", ""),
    declare!("mesh.block_mm", mesh.block_mm: Vec<f64>, RUNTIME, Range::None,
        "Block pitch [x, y, z] in mm for voxelizing ~/part_mesh", "3 lengths > 0"),
    declare!("mesh.bead_mm", mesh.bead_mm: Vec<f64>, RUNTIME, Range::None,
        "Bead width and layer height [W, H] in mm: slice ~/part_mesh into beads along its contours (a graph part); [] = voxelize with mesh.block_mm",
        "[] or 2 lengths > 0"),
    declare!("mesh.t85_window_s", mesh.t85_window_s: Vec<f64>, RUNTIME, Range::None,
        "t8/5 window [min_s, max_s] given to every voxelized block or bead node; [] = none",
        "[] or [min_s, max_s] with 0 <= min_s <= max_s"),
    declare!("topics.part", topics.part: String, AT_START, Range::None,
        "In: std_msgs/String, a part document", ""),
    declare!("topics.part_mesh", topics.part_mesh: String, AT_START, Range::None,
        "In: shape_msgs/Mesh in metres", ""),
    declare!("topics.joint_trajectory", topics.joint_trajectory: String, AT_START, Range::None,
        "Out: trajectory_msgs/JointTrajectory of the plan", ""),
    declare!("topics.poses", topics.poses: String, AT_START, Range::None,
        "Out: geometry_msgs/PoseArray of the toolpath", ""),
    declare!("topics.path", topics.path: String, AT_START, Range::None,
        "Out: nav_msgs/Path of the toolpath", ""),
    declare!("topics.markers", topics.markers: String, AT_START, Range::None,
        "Out: visualization_msgs/MarkerArray of the plan", ""),
    declare!("topics.weld_plan", topics.weld_plan: String, AT_START, Range::None,
        "Out: waam_interfaces/WeldPlan", ""),
    declare!("topics.status", topics.status: String, AT_START, Range::None,
        "Out: diagnostic_msgs/DiagnosticArray on every event", ""),
    declare!("topics.arc_on", topics.arc_on: String, AT_START, Range::None,
        "Out: std_msgs/Bool, the arc state during execution", ""),
    declare!("topics.wire_feed", topics.wire_feed: String, AT_START, Range::None,
        "Out: std_msgs/Float64, with the closed loop: the wire feed of the weld path about to start, relative to nominal", ""),
    declare!("topics.wire_feed_schedule", topics.wire_feed_schedule: String, AT_START, Range::None,
        "Out: trajectory_msgs/JointTrajectory, with the closed loop, before each weld path's arc strikes: one point per deposit, joint \"wire_feed\", its feed relative to nominal at its start (time from the arc strike); after a scan while the arc is on, the rest of it revised (its first point after the strike)", ""),
    declare!("topics.joint_states", topics.joint_states: String, AT_START, Range::None,
        "Out (dry run): sensor_msgs/JointState of the simulated robot", ""),
    declare!("execution.enabled", execution.enabled: bool, AT_START, Range::None,
        "Send each plan to the robot controller (FollowJointTrajectory)", ""),
    declare!("execution.auto_execute", execution.auto_execute: bool, AT_START, Range::None,
        "Run each new plan at once (with a controller or --dry-run); false: only on a ~/execute goal", ""),
    declare!("execution.controller_action", execution.controller_action: String, AT_START,
        Range::None, "The controller's FollowJointTrajectory action", ""),
    declare!("execution.max_points_per_goal", execution.max_points_per_goal: i64, AT_START,
        Range::Int(1, 1_000_000), "The most trajectory points in one goal (MotoROS2: 200)", ""),
    declare!("execution.server_timeout_s", execution.server_timeout_s: f64, AT_START,
        Range::Float(0.0, MAX_WAIT_S), "Seconds to wait for the action server", "> 0"),
    declare!("execution.lead_in_s", execution.lead_in_s: f64, AT_START,
        Range::Float(0.0, MAX_WAIT_S),
        "Seconds the first goal gives the robot to reach the trajectory's first point", ""),
    declare!("execution.joint_names", execution.joint_names: Vec<String>, AT_START, Range::None,
        "The controller's joint names in the URDF's joint order (MotoROS2: group_1/joint_1 ...); [] = the URDF's",
        "[] or one distinct name per URDF joint"),
    declare!("execution.goal_tolerance_rad", execution.goal_tolerance_rad: f64, AT_START,
        Range::Float(0.0, MAX_WAIT_S), "Position tolerance at each goal's end, rad (0 = the controller's default)", ""),
    declare!("execution.path_tolerance_rad", execution.path_tolerance_rad: f64, AT_START,
        Range::Float(0.0, MAX_WAIT_S), "Position tolerance along each goal, rad (0 = the controller's default)", ""),
    declare!("execution.goal_time_tolerance_s", execution.goal_time_tolerance_s: f64, AT_START,
        Range::Float(0.0, MAX_WAIT_S), "Time a goal may take beyond its duration, s (0 = the controller's default)", ""),
    declare!("execution.start_service", execution.start_service: String, AT_START, Range::None,
        "std_srvs/Trigger service called before each plan runs (MotoROS2: /start_traj_mode); \"\" = none", ""),
    declare!("dry_run.time_scale", dry_run.time_scale: f64, AT_START, Range::Float(0.0, 1e6),
        "Simulated time runs this many times faster than real time", "> 0"),
    declare!("dry_run.rate_hz", dry_run.rate_hz: f64, AT_START, Range::Float(0.0, 1000.0),
        "/joint_states messages per second of wall-clock time", "> 0"),
    declare!("closed_loop.enabled", closed_loop.enabled: bool, AT_START, Range::None,
        "Closed loop: at each weld-path boundary of an execution, fit the model to the sensors and re-plan the rest", ""),
    declare!("closed_loop.scan_topic", closed_loop.scan_topic: String, AT_START, Range::None,
        "In: sensor_msgs/PointCloud2, a layer height scan (metres) in the part frame, the robot's base link or a frame /tf connects", ""),
    declare!("closed_loop.temperature_topic", closed_loop.temperature_topic: String, AT_START,
        Range::None, "In: sensor_msgs/Temperature, a pyrometer aimed at the torch (°C)", ""),
    declare!("closed_loop.thermal_camera_topic", closed_loop.thermal_camera_topic: String,
        AT_START, Range::None,
        "In: sensor_msgs/PointCloud2 with a temperature field (°C), a thermal camera's image on the part (metres; frames as scans)", ""),
    declare!("closed_loop.arc_fault_topic", closed_loop.arc_fault_topic: String, AT_START,
        Range::None, "In: std_msgs/Header, the welding power source's arc fault (wire fault, arc loss), stamped when the arc went out: the weld path stops and the rest is re-planned", ""),
    declare!("closed_loop.max_age_s", closed_loop.max_age_s: f64, AT_START,
        Range::Float(0.0, MAX_WAIT_S),
        "Sensor data stamped longer ago than this (or as far ahead) is late and not used, s", "> 0"),
    declare!("closed_loop.scan_margin_mm", closed_loop.scan_margin_mm: f64, AT_START,
        Range::Float(0.0, 1e6),
        "Scan and thermal image points farther than this from the part's box are off the part (dropped; a cloud with none on it is bad), mm", ""),
    declare!("closed_loop.scan_period_s", closed_loop.scan_period_s: f64, AT_START,
        Range::Float(0.0, MAX_WAIT_S),
        "The scanner's cadence while an execution runs: silent longer is a WARN on /diagnostics, s (0: none expected)", ""),
    declare!("closed_loop.temperature_period_s", closed_loop.temperature_period_s: f64, AT_START,
        Range::Float(0.0, MAX_WAIT_S),
        "The pyrometer's cadence while an execution runs: silent longer is a WARN on /diagnostics, s (0: none expected)", ""),
    declare!("closed_loop.thermal_camera_period_s", closed_loop.thermal_camera_period_s: f64,
        AT_START, Range::Float(0.0, MAX_WAIT_S),
        "The thermal camera's cadence while an execution runs: silent longer is a WARN on /diagnostics, s (0: none expected)", ""),
    declare!("closed_loop.wire_feed_min", closed_loop.wire_feed_min: f64, AT_START,
        Range::Float(0.0, 1.0),
        "The least wire feed the height rule may set, relative to nominal (process limit)", "> 0"),
    declare!("closed_loop.wire_feed_max", closed_loop.wire_feed_max: f64, AT_START,
        Range::Float(1.0, 10.0),
        "The most wire feed the height rule may set, relative to nominal (process limit)", ""),
    declare!("closed_loop.wire_feed_per_deposit", closed_loop.wire_feed_per_deposit: bool,
        AT_START, Range::None,
        "The welder follows ~/wire_feed_schedule, a feed per deposit; false: it holds ~/wire_feed for the whole weld path (the mean of its deposits' feeds)", ""),
    declare!("closed_loop.wire_feed_lead_s", closed_loop.wire_feed_lead_s: f64, AT_START,
        Range::Float(0.0, 10.0),
        "While the arc is on, a scan revises the feeds of the deposits that begin at least this long after it, s (the schedule's way through the welder's bridge)", ""),
];

/// The declared parameter `name`.
pub fn find(name: &str) -> Option<&'static Declared> {
    DECLARED.iter().find(|d| d.name == name)
}

impl Declared {
    pub fn get(&self, params: &NodeParams) -> ParameterValue {
        (self.get)(params)
    }

    /// Sets the value in `params` (type checked; ranges are [`NodeParams::check`]'s).
    pub fn set(&self, params: &mut NodeParams, value: &ParameterValue) -> Result<(), ParamError> {
        (self.set)(params, value)
    }

    pub fn descriptor(&self, params: &NodeParams) -> ParameterDescriptor {
        ParameterDescriptor {
            name: self.name.to_string(),
            param_type: self.get(params).to_parameter_type(),
            description: self.description.to_string(),
            additional_constraints: if self.read_only {
                format!(
                    "{} (read at start: set it with -p or --params-file)",
                    self.constraints
                )
                .trim_start()
                .to_string()
            } else {
                self.constraints.to_string()
            },
            read_only: self.read_only,
            dynamic_typing: false,
            range: match self.range {
                Range::None => NumericRange::NotSpecified,
                Range::Int(from_value, to_value) => NumericRange::IntegerRange {
                    from_value,
                    to_value,
                    step: 0,
                },
                Range::Float(from_value, to_value) => NumericRange::FloatingPointRange {
                    from_value,
                    to_value,
                    step: 0.0,
                },
            },
        }
    }
}

/// Parameters rcl gives every node; declared so launch files may set them.
pub const USE_SIM_TIME: &str = "use_sim_time";

/// Sets `name` to `value` in `params`, as `-p` or a parameter service asks; the message
/// says why not. `running`: refuse the read-only ones.
pub fn set(
    params: &mut NodeParams,
    name: &str,
    value: &ParameterValue,
    running: bool,
) -> Result<(), ParamError> {
    if name == USE_SIM_TIME {
        return match value {
            ParameterValue::Boolean(false) => Ok(()),
            _ => Err(ParamError::SimTime),
        };
    }
    let d = find(name).ok_or_else(|| ParamError::Unknown(name.to_string()))?;
    if running && d.read_only {
        return Err(ParamError::ReadOnly(name.to_string()));
    }
    d.set(params, value)
}

/// A `-p` value as rcl reads it: YAML (`5` integer, `5.0` double, `[1, 2]` array, `true`).
pub fn value_from_yaml(text: &str) -> Result<ParameterValue, ParamError> {
    use serde_yaml::Value;
    let v: Value = serde_yaml::from_str(text).map_err(|e| ParamError::NotYaml {
        text: text.to_string(),
        reason: e.to_string(),
    })?;
    let scalar = |v: &Value| -> Option<ParameterValue> {
        Some(match v {
            Value::Bool(b) => ParameterValue::Boolean(*b),
            Value::Number(n) if n.is_i64() => ParameterValue::Integer(n.as_i64()?),
            Value::Number(n) => ParameterValue::Double(n.as_f64()?),
            Value::String(s) => ParameterValue::String(s.clone()),
            Value::Null => ParameterValue::String(String::new()),
            _ => return None,
        })
    };
    let bad = || ParamError::NotAValue(text.to_string());
    match &v {
        Value::Sequence(items) => {
            let values: Vec<ParameterValue> = items
                .iter()
                .map(scalar)
                .collect::<Option<_>>()
                .ok_or_else(bad)?;
            let all = |f: fn(&ParameterValue) -> bool| values.iter().all(f);
            if all(|v| matches!(v, ParameterValue::Integer(_))) && !values.is_empty() {
                Ok(ParameterValue::IntegerArray(
                    values
                        .iter()
                        .filter_map(|v| match v {
                            ParameterValue::Integer(i) => Some(*i),
                            _ => None,
                        })
                        .collect(),
                ))
            } else if all(|v| matches!(v, ParameterValue::Integer(_) | ParameterValue::Double(_))) {
                Ok(ParameterValue::DoubleArray(
                    values
                        .iter()
                        .filter_map(|v| match v {
                            ParameterValue::Integer(i) => Some(*i as f64),
                            ParameterValue::Double(d) => Some(*d),
                            _ => None,
                        })
                        .collect(),
                ))
            } else if all(|v| matches!(v, ParameterValue::Boolean(_))) {
                Ok(ParameterValue::BooleanArray(
                    values
                        .iter()
                        .filter_map(|v| match v {
                            ParameterValue::Boolean(b) => Some(*b),
                            _ => None,
                        })
                        .collect(),
                ))
            } else if all(|v| matches!(v, ParameterValue::String(_))) {
                Ok(ParameterValue::StringArray(
                    values
                        .iter()
                        .filter_map(|v| match v {
                            ParameterValue::String(s) => Some(s.clone()),
                            _ => None,
                        })
                        .collect(),
                ))
            } else {
                Err(bad())
            }
        }
        other => scalar(other).ok_or_else(bad),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_setting_is_declared_and_round_trips() {
        let defaults = NodeParams::default();
        for d in DECLARED {
            let mut p = NodeParams::default();
            d.set(&mut p, &d.get(&defaults)).unwrap();
            assert_eq!(p, defaults, "{}", d.name);
            assert!(!d.description.is_empty(), "{}", d.name);
        }
        // The file's keys, flattened, are exactly the declared names.
        let doc: serde_yaml::Value =
            serde_yaml::from_str(super::super::params::DEFAULT_PARAMS_YAML).unwrap();
        let mut keys = Vec::new();
        flatten(&doc["waam_planner"]["ros__parameters"], "", &mut keys);
        let declared: Vec<&str> = DECLARED.iter().map(|d| d.name).collect();
        assert_eq!(keys, declared);
    }

    fn flatten(v: &serde_yaml::Value, prefix: &str, out: &mut Vec<String>) {
        for (k, v) in v.as_mapping().unwrap() {
            let name = format!("{prefix}{}", k.as_str().unwrap());
            match v {
                serde_yaml::Value::Mapping(_) => flatten(v, &format!("{name}."), out),
                _ => out.push(name),
            }
        }
    }

    #[test]
    fn set_checks_type_and_read_only() {
        let mut p = NodeParams::default();
        set(
            &mut p,
            "planner.timeout_s",
            &ParameterValue::Integer(5),
            true,
        )
        .unwrap();
        assert_eq!(p.planner.timeout_s, 5.0);
        let e = set(
            &mut p,
            "planner.timeout_s",
            &ParameterValue::String("x".into()),
            true,
        );
        assert_eq!(
            e.unwrap_err().to_string(),
            "planner.timeout_s: expected a double, got a string"
        );
        let e = set(
            &mut p,
            "topics.part",
            &ParameterValue::String("/p".into()),
            true,
        );
        assert!(e.unwrap_err().to_string().contains("read only"));
        set(
            &mut p,
            "topics.part",
            &ParameterValue::String("/p".into()),
            false,
        )
        .unwrap();
        assert_eq!(p.topics.part, "/p");
        assert!(set(&mut p, "nope", &ParameterValue::Boolean(true), false).is_err());
        assert!(set(&mut p, USE_SIM_TIME, &ParameterValue::Boolean(true), false).is_err());
    }

    #[test]
    fn yaml_values_as_rcl_reads_them() {
        let v = |t: &str| value_from_yaml(t).unwrap();
        assert_eq!(v("5"), ParameterValue::Integer(5));
        assert_eq!(v("5.5"), ParameterValue::Double(5.5));
        assert_eq!(v("true"), ParameterValue::Boolean(true));
        assert_eq!(v("abc"), ParameterValue::String("abc".into()));
        assert_eq!(
            v("[6, 6, 2.5]"),
            ParameterValue::DoubleArray(vec![6.0, 6.0, 2.5])
        );
        assert_eq!(v("[1, 2]"), ParameterValue::IntegerArray(vec![1, 2]));
        assert!(value_from_yaml("[1, a]").is_err());
    }
}
