//! Robot programs from a validated motion, for cells that run without ROS: ABB RAPID
//! ([`rapid`]), KUKA KRL with ArcTech ([`krl`]), Yaskawa INFORM ([`inform`]), Fanuc LS
//! ([`fanuc`]) and G-code for gantries ([`gcode`]).
//!
//! Everything comes from one [`Program`], built by [`Program::new`] from the toolpath and
//! the joint trajectory that `waam plan --robot`, `waam motion` and `waam layer plan --robot`
//! write (`toolpath.yaml`, `trajectory.yaml`):
//!
//! * one target per toolpath pose, at that pose (the robot formats in the plate frame, as
//!   the controller's work object / base / user frame; G-code in the part frame);
//! * the timing of the validated trajectory: the move into a pose that changes the TCP's
//!   position runs at distance / time, a move that only turns the torch takes its time, and
//!   a move that changes nothing is a wait (the arc-on dwell, the crater fill);
//! * the arc on exactly from each pose where the toolpath switches it on to the pose where
//!   it switches it off;
//! * the robot's configuration at every target from the validated joint solution
//!   ([`ArmConfig`]).

pub mod fanuc;
pub mod gcode;
pub mod inform;
pub mod krl;
pub mod rapid;

use std::collections::BTreeMap;
use std::fmt;
use std::ops::Range;
use std::path::Path;
use std::str::FromStr;

use nalgebra::{Isometry3, UnitQuaternion};
use serde::{Deserialize, Serialize};
use thiserror::Error;
use waam_motion::robot::Robot;
use waam_motion::toolpath::ToolpathFile;
use waam_motion::trajectory::TrajectoryFile;

/// A move shorter than this (mm) does not change the TCP's position.
const SAME_POSITION_MM: f64 = 1e-3;
/// A move that turns the torch by less than this (deg) does not change its orientation.
const SAME_ROTATION_DEG: f64 = 1e-3;
/// FK of the given robot must reproduce every toolpath pose to this (mm, deg).
const FK_TOL_MM: f64 = 0.01;
const FK_TOL_DEG: f64 = 0.01;

/// Why no program could be written.
#[derive(Debug, Error)]
pub enum ExportError {
    // `error`, not `source`: the message already carries it, so a chain prints it once.
    #[error("cannot read {path}: {error}")]
    Read { path: String, error: std::io::Error },
    #[error("{path}: {reason}")]
    Parse { path: String, reason: String },
    #[error("the toolpath has {toolpath} poses but the trajectory {trajectory} points: they are not one motion")]
    Mismatch { toolpath: usize, trajectory: usize },
    #[error("the motion is empty")]
    Empty,
    #[error("trajectory point {point}: {reason}")]
    BadPoint { point: usize, reason: String },
    #[error(
        "{format} needs the robot (--robot URDF) to write the arm configuration of every target"
    )]
    NeedsRobot { format: Format },
    #[error("robot {robot}: {reason}")]
    Robot { robot: String, reason: String },
    #[error("weld pass {pass} has {targets} targets, more than the {limit} one {format} program may hold (max_targets.{key} in the cell settings)", key = format.key())]
    PassTooLong {
        format: Format,
        pass: usize,
        targets: usize,
        limit: usize,
    },
    #[error("cell settings: {0}")]
    Settings(String),
}

/// The program formats.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Format {
    Rapid,
    Krl,
    Inform,
    Fanuc,
    Gcode,
}

impl Format {
    /// Every format with its name and a help line.
    pub const ALL: [(Format, &'static str, &'static str); 5] = [
        (
            Format::Rapid,
            "rapid",
            "ABB RAPID modules (.mod) with ArcLStart/ArcL/ArcLEnd (RobotWare Arc)",
        ),
        (
            Format::Krl,
            "krl",
            "KUKA KRL .src/.dat with ArcTech ARCON/ARCSWI/ARCOFF inline forms",
        ),
        (
            Format::Inform,
            "inform",
            "Yaskawa INFORM jobs (.JBI) with ARCON/ARCOF",
        ),
        (
            Format::Fanuc,
            "fanuc",
            "Fanuc TP programs (.ls) with Arc Start/Arc End (Arc Tool)",
        ),
        (
            Format::Gcode,
            "gcode",
            "G-code (.gcode) for a gantry: G0/G1, arc on/off commands, G4 dwells, part frame",
        ),
    ];

    /// The name on the command line and in the cell settings.
    pub fn key(self) -> &'static str {
        Format::ALL
            .iter()
            .find(|(f, _, _)| *f == self)
            .map(|(_, n, _)| *n)
            .expect("every format is listed")
    }

    /// Whether a weld may go on across a call of the next part program. RAPID: a
    /// procedure call is no stop point, so `ArcL` in one procedure continues the seam that
    /// `ArcLStart` opened in the one before (the arc stays on until `ArcLEnd`). The other
    /// controllers' program calls are not documented to keep the arc and path running.
    pub fn weld_spans_calls(self) -> bool {
        self == Format::Rapid
    }

    /// Whether the format needs the robot's arm configuration.
    pub fn is_robot(self) -> bool {
        self != Format::Gcode
    }
}

impl fmt::Display for Format {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.key())
    }
}

/// A name that is not an export format.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("unknown format {0:?} (rapid, krl, inform, fanuc, gcode)")]
pub struct UnknownFormat(pub String);

impl FromStr for Format {
    type Err = UnknownFormat;
    fn from_str(s: &str) -> Result<Format, UnknownFormat> {
        Format::ALL
            .iter()
            .find(|(_, n, _)| *n == s)
            .map(|(f, _, _)| *f)
            .ok_or_else(|| UnknownFormat(s.to_string()))
    }
}

/// The most targets one program may hold, per format.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MaxTargets {
    pub rapid: usize,
    pub krl: usize,
    pub inform: usize,
    pub fanuc: usize,
}

impl Default for MaxTargets {
    fn default() -> Self {
        MaxTargets {
            rapid: 500,
            krl: 1000,
            inform: 999,
            fanuc: 999,
        }
    }
}

/// The cell's process data (see `config/export.yaml` for the meaning of each key).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CellSettings {
    pub schedule: u32,
    pub wire_feed_m_min: f64,
    pub voltage_v: f64,
    pub current_a: f64,
    pub preflow_s: f64,
    pub postflow_s: f64,
    pub tool_mass_kg: f64,
    pub user_frame: u32,
    pub tool: u32,
    pub max_targets: MaxTargets,
    pub gcode_arc_on: String,
    pub gcode_arc_off: String,
}

impl Default for CellSettings {
    fn default() -> Self {
        CellSettings {
            schedule: 1,
            wire_feed_m_min: 6.0,
            voltage_v: 20.0,
            current_a: 160.0,
            preflow_s: 0.5,
            postflow_s: 1.0,
            tool_mass_kg: 3.0,
            user_frame: 1,
            tool: 1,
            max_targets: MaxTargets::default(),
            gcode_arc_on: "M3".into(),
            gcode_arc_off: "M5".into(),
        }
    }
}

impl CellSettings {
    /// Reads a cell-settings file's text; missing keys take their defaults.
    pub fn from_yaml(text: &str) -> Result<CellSettings, ExportError> {
        let s: CellSettings = if text.trim().is_empty() {
            CellSettings::default()
        } else {
            serde_yaml::from_str(text).map_err(|e| ExportError::Settings(e.to_string()))?
        };
        let bad = |key: &str, v: f64| {
            if v.is_finite() && v >= 0.0 {
                Ok(())
            } else {
                Err(ExportError::Settings(format!(
                    "{key}: must be a number >= 0, got {v}"
                )))
            }
        };
        bad("wire_feed_m_min", s.wire_feed_m_min)?;
        bad("voltage_v", s.voltage_v)?;
        bad("current_a", s.current_a)?;
        bad("preflow_s", s.preflow_s)?;
        bad("postflow_s", s.postflow_s)?;
        bad("tool_mass_kg", s.tool_mass_kg)?;
        let m = s.max_targets;
        if [m.rapid, m.krl, m.inform, m.fanuc].contains(&0) {
            return Err(ExportError::Settings(
                "max_targets: every limit must be at least 1".into(),
            ));
        }
        for (key, cmd) in [
            ("gcode_arc_on", &s.gcode_arc_on),
            ("gcode_arc_off", &s.gcode_arc_off),
        ] {
            if cmd.trim().is_empty() || cmd.contains('\n') {
                return Err(ExportError::Settings(format!(
                    "{key}: must be one non-empty line, got {cmd:?}"
                )));
            }
        }
        Ok(s)
    }
}

/// The arm configuration of a joint solution, as the controllers name it:
///
/// * `behind`: the wrist centre lies behind axis 1 (shoulder "back");
/// * `elbow_down`: the elbow is the other of the two elbow solutions than the upright arm
///   at the zero pose (the elbow bit of the analytic solver's configuration);
/// * `wrist_negative`: joint 5 is negative (the wrist is flipped).
///
/// The first two are the shoulder and elbow bits of the analytic (OPW) solver's
/// configuration, the same the trajectory keeps for a whole path; the third is the sign of
/// joint 5. `joints_deg` are the joint positions in degrees, as in the URDF (the
/// controller's axis values are assumed to equal the URDF's joint positions).
#[derive(Debug, Clone, PartialEq)]
pub struct ArmConfig {
    pub behind: bool,
    pub elbow_down: bool,
    pub wrist_negative: bool,
    pub joints_deg: Vec<f64>,
}

impl ArmConfig {
    /// ABB `confdata` [cf1, cf4, cf6, cfx]: the quadrants of joints 1, 4 and 6
    /// (floor(angle / 90°): 0 for 0..90°, -1 for -90..0°, ...) and
    /// cfx = 4·behind + 2·elbow_down + wrist_negative (the RobotWare table: wrist centre in
    /// front of / behind axis 1, forward / backward of the lower arm, axis 5 positive /
    /// negative).
    pub fn abb_confdata(&self) -> [i32; 4] {
        let q = |i: usize| (self.joints_deg[i] / 90.0).floor() as i32;
        [
            q(0),
            q(3),
            q(5),
            4 * self.behind as i32 + 2 * self.elbow_down as i32 + self.wrist_negative as i32,
        ]
    }

    /// KUKA Status: bit 0 wrist centre behind A1, bit 1 elbow, bit 2 A5 negative.
    pub fn kuka_status(&self) -> u32 {
        self.behind as u32 | (self.elbow_down as u32) << 1 | (self.wrist_negative as u32) << 2
    }

    /// KUKA Turn: bit i set when axis i+1 is negative.
    pub fn kuka_turn(&self) -> u32 {
        self.joints_deg
            .iter()
            .take(6)
            .enumerate()
            .filter(|(_, q)| **q < 0.0)
            .map(|(i, _)| 1 << i)
            .sum()
    }

    /// Turn number of a joint angle: 0 for (-180°, 180°], 1 for (180°, 540°], -1 below.
    pub fn turn(q_deg: f64) -> i32 {
        ((q_deg - 180.0) / 360.0).ceil() as i32
    }
}

/// How the TCP gets into a target from the one before.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Move {
    /// The first target: a joint move, untimed.
    First,
    /// A straight move at this TCP speed, mm/s.
    Linear { speed_mm_s: f64 },
    /// The torch turns in place in this time, s (the rotation in `deg`).
    Turn { duration_s: f64, deg: f64 },
    /// Nothing moves for this long, s: a wait (dwell), then a zero-length move.
    Wait { duration_s: f64 },
}

/// What happens to the arc on arriving at a target.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Arc {
    Keep,
    On,
    Off,
}

/// One target: a toolpath pose with its joint solution and how it is reached.
#[derive(Debug, Clone)]
pub struct Target {
    /// The TCP in the robot's base link, m.
    pub base: Isometry3<f64>,
    /// The TCP in the plate (part) frame, m.
    pub part: Isometry3<f64>,
    pub config: Option<ArmConfig>,
    pub time_s: f64,
    pub how: Move,
    /// The arc's state on the move into this target.
    pub arc_during: bool,
    /// The arc's event on arrival.
    pub arc: Arc,
    /// The weld pass (fragment) the pose belongs to, from 0.
    pub pass: usize,
}

/// A motion ready to be written in any format.
#[derive(Debug, Clone)]
pub struct Program {
    /// The program's name (letters, digits, underscores; starts with a letter).
    pub name: String,
    /// The robot's base link (the frame of `base` poses).
    pub frame: String,
    /// The part (plate) frame in the base link, m.
    pub plate: Isometry3<f64>,
    /// The TCP in the tool flange (the URDF tip link), m.
    pub tcp: Isometry3<f64>,
    pub targets: Vec<Target>,
    /// The timing is the toolpath's own, not a validated robot trajectory's: a gantry
    /// makes moves with the arc off at its rapid traverse (G-code `G0`).
    pub rapid_travel: bool,
}

/// Reads `DIR/toolpath.yaml` and `DIR/trajectory.yaml`.
pub fn read_motion_dir(dir: &Path) -> Result<(ToolpathFile, TrajectoryFile), ExportError> {
    Ok((
        read_yaml(&dir.join("toolpath.yaml"))?,
        read_yaml(&dir.join("trajectory.yaml"))?,
    ))
}

/// Reads `DIR/toolpath.yaml` and, when there is one, `DIR/trajectory.yaml` (a plan without
/// a robot has a toolpath in the part frame only).
pub fn read_toolpath_dir(
    dir: &Path,
) -> Result<(ToolpathFile, Option<TrajectoryFile>), ExportError> {
    let tp = read_yaml(&dir.join("toolpath.yaml"))?;
    let traj = dir.join("trajectory.yaml");
    Ok((tp, traj.exists().then(|| read_yaml(&traj)).transpose()?))
}

fn read_yaml<T: serde::de::DeserializeOwned>(path: &Path) -> Result<T, ExportError> {
    let text = std::fs::read_to_string(path).map_err(|error| ExportError::Read {
        path: path.display().to_string(),
        error,
    })?;
    serde_yaml::from_str(&text).map_err(|e| ExportError::Parse {
        path: path.display().to_string(),
        reason: e.to_string(),
    })
}

/// The arm configuration of every trajectory point, from the robot's analytic solver; the
/// robot must reproduce every toolpath pose from the trajectory's joints (the same URDF
/// and TCP as planned).
pub fn arm_configs(
    robot: &Robot,
    tp: &ToolpathFile,
    traj: &TrajectoryFile,
) -> Result<Vec<ArmConfig>, ExportError> {
    let fail = |reason: String| ExportError::Robot {
        robot: robot.name.clone(),
        reason,
    };
    let opw =
        robot.opw().ok_or_else(|| {
            fail(format!(
            "the analytic solver does not fit this arm ({}), so its configuration cannot be named",
            robot.opw_reason.as_deref().unwrap_or("not a spherical-wrist arm")
        ))
        })?;
    if traj.joint_names != robot.joint_names() {
        return Err(fail(format!(
            "its joints {:?} are not the trajectory's {:?}",
            robot.joint_names(),
            traj.joint_names
        )));
    }
    let mut out = Vec::with_capacity(traj.points.len());
    for (i, (p, pose)) in traj.points.iter().zip(&tp.poses).enumerate() {
        let (dm, dr) =
            waam_motion::robot::pose_error(&robot.tcp_pose(&p.positions), &pose.isometry());
        if dm * 1000.0 > FK_TOL_MM || dr.to_degrees() > FK_TOL_DEG {
            return Err(fail(format!(
                "its TCP at trajectory point {i} is {:.3} mm / {:.3} deg off the toolpath pose: not the robot and TCP the motion was planned for (check --tcp / --tip)",
                dm * 1000.0,
                dr.to_degrees()
            )));
        }
        let c = opw.configuration(&p.positions);
        out.push(ArmConfig {
            behind: c & 1 != 0,
            elbow_down: c & 2 != 0,
            wrist_negative: p.positions.get(4).is_some_and(|q| *q < 0.0),
            joints_deg: p.positions.iter().map(|q| q.to_degrees()).collect(),
        });
    }
    Ok(out)
}

impl Program {
    /// The program of a motion. `plate`: the part frame in the base link (the process
    /// settings' plate); `tcp`: the TCP in the flange; `configs`: one per point (from
    /// [`arm_configs`]) for the robot formats.
    pub fn new(
        name: &str,
        tp: &ToolpathFile,
        traj: &TrajectoryFile,
        plate: Isometry3<f64>,
        tcp: Isometry3<f64>,
        configs: Option<Vec<ArmConfig>>,
    ) -> Result<Program, ExportError> {
        if tp.poses.len() != traj.points.len() {
            return Err(ExportError::Mismatch {
                toolpath: tp.poses.len(),
                trajectory: traj.points.len(),
            });
        }
        if let Some(i) = (0..tp.poses.len()).find(|&i| tp.poses[i].arc_on != traj.points[i].arc_on)
        {
            return Err(ExportError::BadPoint {
                point: i,
                reason: "the toolpath and the trajectory disagree on the arc".into(),
            });
        }
        let times = traj.points.iter().map(|p| p.time_from_start);
        Program::of_poses(name, tp, times, plate, tcp, configs, false)
    }

    /// The program of a toolpath alone (`waam plan --out` without a robot; G-code): the
    /// toolpath's own timing, no arm configuration, and moves with the arc off at the
    /// machine's rapid traverse (`rapid_travel`). `plate`: the toolpath's frame's placement
    /// of the part frame (identity for a toolpath in the part frame).
    pub fn from_toolpath(
        name: &str,
        tp: &ToolpathFile,
        plate: Isometry3<f64>,
    ) -> Result<Program, ExportError> {
        let times = tp.poses.iter().map(|p| p.time);
        Program::of_poses(name, tp, times, plate, Isometry3::identity(), None, true)
    }

    fn of_poses(
        name: &str,
        tp: &ToolpathFile,
        times: impl Iterator<Item = f64>,
        plate: Isometry3<f64>,
        tcp: Isometry3<f64>,
        configs: Option<Vec<ArmConfig>>,
        rapid_travel: bool,
    ) -> Result<Program, ExportError> {
        if tp.poses.is_empty() {
            return Err(ExportError::Empty);
        }
        let mut configs = configs.map(|c| c.into_iter());
        let mut targets: Vec<Target> = Vec::with_capacity(tp.poses.len());
        let mut arc_before = false;
        for (i, (pose, t)) in tp.poses.iter().zip(times).enumerate() {
            let base = pose.isometry();
            if !t.is_finite() || !base.translation.vector.iter().all(|v| v.is_finite()) {
                return Err(ExportError::BadPoint {
                    point: i,
                    reason: "not a finite pose or time".into(),
                });
            }
            let how = match targets.last() {
                None => Move::First,
                Some(prev) => {
                    let dt = t - prev.time_s;
                    if dt <= 0.0 {
                        return Err(ExportError::BadPoint {
                            point: i,
                            reason: format!("time {t} s does not follow {} s", prev.time_s),
                        });
                    }
                    let dist =
                        (base.translation.vector - prev.base.translation.vector).norm() * 1000.0;
                    let deg = base.rotation.angle_to(&prev.base.rotation).to_degrees();
                    if dist >= SAME_POSITION_MM {
                        Move::Linear {
                            speed_mm_s: dist / dt,
                        }
                    } else if deg >= SAME_ROTATION_DEG {
                        Move::Turn {
                            duration_s: dt,
                            deg,
                        }
                    } else {
                        Move::Wait { duration_s: dt }
                    }
                }
            };
            let arc = match (arc_before, pose.arc_on) {
                (false, true) => Arc::On,
                (true, false) => Arc::Off,
                _ => Arc::Keep,
            };
            targets.push(Target {
                base,
                part: plate.inverse() * base,
                config: configs.as_mut().and_then(|c| c.next()),
                time_s: t,
                how,
                arc_during: arc_before,
                arc,
                pass: pose.fragment,
            });
            arc_before = pose.arc_on;
        }
        Ok(Program {
            name: name.to_string(),
            frame: tp.frame.clone(),
            plate,
            tcp,
            targets,
            rapid_travel,
        })
    }

    /// The number of weld passes (arc-on events).
    pub fn passes(&self) -> usize {
        self.targets.iter().filter(|t| t.arc == Arc::On).count()
    }

    /// The distinct weld speeds (mm/s, rounded to 0.01) in order of first use; a weld move
    /// uses the data set at its index.
    pub fn weld_speeds(&self) -> Vec<f64> {
        let mut seen = BTreeMap::new();
        let mut out = Vec::new();
        for t in &self.targets {
            if let (true, Move::Linear { speed_mm_s }) = (t.arc_during, t.how) {
                let key = (speed_mm_s * 100.0).round() as i64;
                seen.entry(key).or_insert_with(|| {
                    out.push(key as f64 / 100.0);
                    out.len() - 1
                });
            }
        }
        out
    }

    /// The index in [`Program::weld_speeds`] of a weld speed.
    pub fn weld_speed_index(&self, speeds: &[f64], speed_mm_s: f64) -> usize {
        let key = (speed_mm_s * 100.0).round() / 100.0;
        speeds
            .iter()
            .position(|s| (s - key).abs() < 1e-9)
            .unwrap_or(0)
    }

    /// The weld speed data set of the pass a target is in (the first weld move's speed at
    /// or after it within its pass), as an index into `speeds`.
    pub fn pass_speed_index(&self, speeds: &[f64], at: usize) -> usize {
        let pass = self.targets[at].pass;
        self.targets[at..]
            .iter()
            .take_while(|t| t.pass == pass)
            .find_map(|t| match (t.arc_during, t.how) {
                (true, Move::Linear { speed_mm_s }) => Some(speed_mm_s),
                _ => None,
            })
            .map_or(0, |v| self.weld_speed_index(speeds, v))
    }

    /// Splits the targets into programs of at most `max` targets, where the arc is off
    /// (between weld passes) whenever one lies within the limit. A pass longer than `max`
    /// is split inside the weld only for a format whose weld continues across a program
    /// call ([`Format::weld_spans_calls`]); the others refuse it.
    pub fn chunks(&self, format: Format, max: usize) -> Result<Vec<Range<usize>>, ExportError> {
        let n = self.targets.len();
        let mut out = Vec::new();
        let (mut start, mut cut) = (0usize, None);
        for i in 0..n {
            // A program may start at i when the arc is off on the move into i.
            if i > start && !self.targets[i].arc_during {
                cut = Some(i);
            }
            if i + 1 - start > max {
                let at = match cut {
                    Some(c) if c > start => c,
                    _ if format.weld_spans_calls() => i,
                    _ => {
                        let pass = self.targets[i].pass;
                        let targets = self.targets.iter().filter(|t| t.pass == pass).count();
                        return Err(ExportError::PassTooLong {
                            format,
                            pass: pass + 1,
                            targets,
                            limit: max,
                        });
                    }
                };
                out.push(start..at);
                start = at;
                cut = (at + 1..=i).rev().find(|&j| !self.targets[j].arc_during);
            }
        }
        out.push(start..n);
        Ok(out)
    }

    /// Every arm configuration, for the robot formats.
    fn require_configs(&self, format: Format) -> Result<(), ExportError> {
        if self.targets.iter().any(|t| t.config.is_none()) {
            return Err(ExportError::NeedsRobot { format });
        }
        Ok(())
    }
}

/// One written file: its name (no directory) and text.
#[derive(Debug, Clone, PartialEq)]
pub struct File {
    pub name: String,
    pub text: String,
}

/// The program in a format: one or more files (a main program and its parts).
pub fn export(
    program: &Program,
    format: Format,
    cell: &CellSettings,
) -> Result<Vec<File>, ExportError> {
    if format.is_robot() {
        program.require_configs(format)?;
    }
    match format {
        Format::Rapid => rapid::write(program, cell),
        Format::Krl => krl::write(program, cell),
        Format::Inform => inform::write(program, cell),
        Format::Fanuc => fanuc::write(program, cell),
        Format::Gcode => Ok(vec![gcode::write(program, cell)]),
    }
}

/// Roll, pitch, yaw in degrees of a rotation with R = Rz(yaw)·Ry(pitch)·Rx(roll): KUKA's
/// (A, B, C) = (yaw, pitch, roll), Fanuc's and Yaskawa's (W, P, R) / (Rx, Ry, Rz) =
/// (roll, pitch, yaw).
pub fn rpy_deg(r: &UnitQuaternion<f64>) -> [f64; 3] {
    let (roll, pitch, yaw) = r.euler_angles();
    [roll.to_degrees(), pitch.to_degrees(), yaw.to_degrees()]
}

/// Millimetres of a translation in metres.
pub(crate) fn mm(iso: &Isometry3<f64>) -> [f64; 3] {
    let v = iso.translation.vector * 1000.0;
    [v.x, v.y, v.z]
}

/// A number with `d` decimals, never "-0.000".
pub(crate) fn num(x: f64, d: usize) -> String {
    let s = format!("{x:.d$}");
    if s.trim_start_matches('-')
        .chars()
        .all(|c| c == '0' || c == '.')
    {
        s.trim_start_matches('-').to_string()
    } else {
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use waam_motion::toolpath::ToolpathFilePose;
    use waam_motion::trajectory::{TcpOffsetFile, TrajectoryFilePoint};

    /// A straight motion along x: (x mm, time s, arc) per pose, fragment by arc stretch.
    fn motion(poses: &[(f64, f64, bool)]) -> (ToolpathFile, TrajectoryFile) {
        let tp = ToolpathFile {
            frame: "base_link".into(),
            poses: poses
                .iter()
                .map(|&(x, t, arc_on)| ToolpathFilePose {
                    time: t,
                    position: [x / 1000.0, 0.0, 0.0],
                    orientation: [1.0, 0.0, 0.0, 0.0],
                    arc_on,
                    fragment: 0,
                })
                .collect(),
        };
        let traj = TrajectoryFile {
            base_link: "base_link".into(),
            tip_link: "tcp".into(),
            tcp_offset: TcpOffsetFile {
                position: [0.0; 3],
                orientation: [0.0, 0.0, 0.0, 1.0],
            },
            joint_names: vec![],
            points: poses
                .iter()
                .map(|&(_, t, arc_on)| TrajectoryFilePoint {
                    positions: vec![],
                    velocities: vec![],
                    accelerations: vec![],
                    time_from_start: t,
                    arc_on,
                })
                .collect(),
        };
        (tp, traj)
    }

    fn program(poses: &[(f64, f64, bool)]) -> Program {
        let (tp, traj) = motion(poses);
        Program::new(
            "T",
            &tp,
            &traj,
            Isometry3::identity(),
            Isometry3::identity(),
            None,
        )
        .unwrap()
    }

    #[test]
    fn moves_waits_and_arc_events_come_from_the_timeline() {
        let p = program(&[
            (0.0, 0.0, false),
            (10.0, 0.1, true),
            (10.0, 0.4, true),
            (16.0, 1.4, true),
            (16.0, 1.9, false),
            (30.0, 2.04, false),
        ]);
        let how: Vec<Move> = p.targets.iter().map(|t| t.how).collect();
        assert_eq!(how[0], Move::First);
        assert!(matches!(how[1], Move::Linear { speed_mm_s } if (speed_mm_s - 100.0).abs() < 1e-9));
        assert!(matches!(how[2], Move::Wait { duration_s } if (duration_s - 0.3).abs() < 1e-9));
        assert!(matches!(how[3], Move::Linear { speed_mm_s } if (speed_mm_s - 6.0).abs() < 1e-9));
        let arcs: Vec<Arc> = p.targets.iter().map(|t| t.arc).collect();
        assert_eq!(
            arcs,
            [
                Arc::Keep,
                Arc::On,
                Arc::Keep,
                Arc::Keep,
                Arc::Off,
                Arc::Keep
            ]
        );
        assert_eq!(p.passes(), 1);
        assert_eq!(p.weld_speeds(), [6.0]);
        // The robot formats need configurations; G-code does not.
        assert!(matches!(
            export(&p, Format::Rapid, &CellSettings::default()),
            Err(ExportError::NeedsRobot { .. })
        ));
        let g = export(&p, Format::Gcode, &CellSettings::default()).unwrap();
        assert!(g[0].text.contains("G4 P0.300\nG1 X10.000 Y0.000 Z0.000\n"));
    }

    #[test]
    fn programs_split_only_where_the_arc_is_off() {
        // Two passes of 4 targets with 2 transit targets before each.
        let mut poses = Vec::new();
        let mut t = 0.0;
        for _ in 0..2 {
            for (x, arc) in [
                (0.0, false),
                (5.0, false),
                (10.0, true),
                (15.0, true),
                (20.0, true),
                (25.0, false),
            ] {
                poses.push((x, t, arc));
                t += 1.0;
            }
        }
        let p = program(&poses);
        assert_eq!(p.chunks(Format::Rapid, 100).unwrap(), vec![0..12]);
        assert_eq!(p.chunks(Format::Rapid, 6).unwrap(), [0..6, 6..12]);
        // Any target the arc is off on the way to may start a program; none inside a pass.
        assert_eq!(p.chunks(Format::Rapid, 7).unwrap(), [0..7, 7..12]);
        assert_eq!(p.chunks(Format::Rapid, 8).unwrap(), [0..8, 8..12]);
        for max in 4..12 {
            for r in p.chunks(Format::Rapid, max).unwrap() {
                assert!(
                    r.len() <= max && !p.targets[r.start].arc_during,
                    "{max}: {r:?}"
                );
            }
        }
        assert!(matches!(
            p.chunks(Format::Krl, 3),
            Err(ExportError::PassTooLong { limit: 3, .. })
        ));
    }

    #[test]
    fn rapid_splits_a_pass_longer_than_the_limit_inside_the_weld() {
        // One transit target, then a pass of 9 weld targets, then one more of 4 (the arc
        // comes on at targets 1 and 11: the moves into them are the programs' cut points).
        let mut poses = vec![(0.0, 0.0, false)];
        let mut t = 1.0;
        for x in 1..=9 {
            poses.push((x as f64 * 5.0, t, true));
            t += 1.0;
        }
        for x in [60.0, 65.0, 70.0, 75.0] {
            poses.push((x, t, x > 60.0));
            t += 1.0;
        }
        let p = program(&poses);
        assert!(matches!(
            p.chunks(Format::Krl, 4),
            Err(ExportError::PassTooLong { limit: 4, .. })
        ));
        for max in 1..14 {
            let chunks = p.chunks(Format::Rapid, max).unwrap();
            // Contiguous, in order, every target once, none longer than the limit.
            assert_eq!(chunks[0].start, 0);
            assert_eq!(chunks.last().unwrap().end, p.targets.len());
            for w in chunks.windows(2) {
                assert_eq!(w[0].end, w[1].start, "{max}: {chunks:?}");
            }
            assert!(chunks.iter().all(|r| !r.is_empty() && r.len() <= max));
            // A program ends inside a weld only when it is full.
            for w in chunks.windows(2) {
                if p.targets[w[1].start].arc_during {
                    assert_eq!(w[0].len(), max, "{max}: {chunks:?}");
                }
            }
        }
        assert_eq!(
            p.chunks(Format::Rapid, 4).unwrap(),
            [0..1, 1..5, 5..9, 9..11, 11..14]
        );
    }

    #[test]
    fn configuration_numbers_follow_the_documented_rules() {
        let c = ArmConfig {
            behind: true,
            elbow_down: false,
            wrist_negative: true,
            joints_deg: vec![-30.0, 10.0, 20.0, 95.0, -40.0, -181.0],
        };
        assert_eq!(c.abb_confdata(), [-1, 1, -3, 5]);
        assert_eq!(c.kuka_status(), 0b101);
        assert_eq!(c.kuka_turn(), 0b110001);
        assert_eq!(
            [
                ArmConfig::turn(0.0),
                ArmConfig::turn(180.0),
                ArmConfig::turn(181.0),
                ArmConfig::turn(-181.0)
            ],
            [0, 0, 1, -1]
        );
        assert_eq!(fanuc::config_string(&c), "F U B, 0, 0, -1");
    }

    #[test]
    fn cell_settings_name_the_bad_key() {
        let e = CellSettings::from_yaml("voltage_v: -3\n").unwrap_err();
        assert!(e.to_string().contains("voltage_v"), "{e}");
        let e = CellSettings::from_yaml("max_targets: {rapid: 0}\n").unwrap_err();
        assert!(e.to_string().contains("max_targets"), "{e}");
        let e = CellSettings::from_yaml("volts: 3\n").unwrap_err();
        assert!(e.to_string().contains("volts"), "{e}");
        let s = CellSettings::from_yaml(include_str!("../../../config/export.yaml")).unwrap();
        assert_eq!(
            s,
            CellSettings::default(),
            "config/export.yaml holds the defaults"
        );
    }
}
