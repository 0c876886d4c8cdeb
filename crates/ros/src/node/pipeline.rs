//! What a planning job does: input → part → plan → check → toolpath → joint trajectory.
//!
//! Runs on a worker thread ([`super::worker`]). Every stage reports progress and checks the
//! cancel flag between stages; any failure is a reason string for an ERROR status, never a
//! panic, and a plan is handed on only after it passed validation and the thermal check.

use std::sync::Arc;

use nalgebra::Isometry3;

use super::convert::PlanSummary;
use super::params::NodeParams;
use super::worker::{JobContext, Pipeline};
use crate::planning::CandidateRecorder;
use waam_mesh::{voxelize_indexed, Units, VoxelizeOptions, WindowRule};
use waam_motion::robot::{xyz_rpy, Robot, TcpChoice};
use waam_motion::toolpath::{ProcessSettings, Toolpath};
use waam_motion::trajectory::JointTrajectory;
use waam_motion::{plan_motion, weld_speed};
use waam_part::graph::WeldGraph;
use waam_part::plan::Plan;
use waam_part::{BlockDisplay, Part, Window};
use waam_rosbag::Recorder;
use waam_rosmsg::diagnostic_msgs::KeyValue;
use waam_rosmsg::shape_msgs::Mesh;
use waam_rosmsg::waam_interfaces::PlanStatistics;
use waam_thermal::{self as thermal, ThermalModel};

/// The robot the project ships, used when the parameters name no URDF.
pub const BUNDLED_URDF: &str = include_str!("../../../../urdf/waam_robot.urdf");

/// A part as it arrives: a part document (`~/part`) or a triangle mesh in metres
/// (`~/part_mesh`).
#[derive(Debug, Clone)]
pub enum PartInput {
    Document(String),
    Mesh {
        name: String,
        vertices: Vec<[f64; 3]>,
        triangles: Vec<[u32; 3]>,
    },
}

impl PartInput {
    /// A few words on what arrived, for status and logs.
    pub fn describe(&self) -> String {
        match self {
            PartInput::Document(text) => format!("part document, {} bytes", text.len()),
            PartInput::Mesh {
                vertices,
                triangles,
                ..
            } => format!(
                "mesh, {} vertices, {} triangles",
                vertices.len(),
                triangles.len()
            ),
        }
    }
}

impl PartInput {
    /// A `~/part_mesh` message as an input named `name`.
    pub fn from_mesh(name: String, mesh: &Mesh) -> PartInput {
        let (vertices, triangles) = mesh_arrays(mesh);
        PartInput::Mesh {
            name,
            vertices,
            triangles,
        }
    }
}

/// A shape_msgs/Mesh's vertices (m) and triangles as plain arrays.
fn mesh_arrays(mesh: &Mesh) -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
    (
        mesh.vertices.iter().map(|p| [p.x, p.y, p.z]).collect(),
        mesh.triangles.iter().map(|t| t.vertex_indices).collect(),
    )
}

/// How the node turns a mesh into a part: the block pitch, the t8/5 window every block
/// gets, and the part's max_fragments. Recorded with every mesh received (as status values
/// `mesh.*`), so that a replay voxelizes it the same way.
#[derive(Debug, Clone, PartialEq)]
pub struct MeshSettings {
    pub block_mm: [f64; 3],
    pub window: Option<Window>,
    pub max_fragments: usize,
}

/// Status keys of [`MeshSettings`] and of the mesh part's name.
pub mod mesh_keys {
    pub const NAME: &str = "mesh.name";
    pub const BLOCK_MM: &str = "mesh.block_mm";
    pub const T85_WINDOW_S: &str = "mesh.t85_window_s";
    pub const MAX_FRAGMENTS: &str = "mesh.max_fragments";
}

impl MeshSettings {
    pub fn from_params(params: &NodeParams) -> Result<Self, String> {
        let [a, b, c] = params.mesh.block_mm[..] else {
            return Err("mesh.block_mm: expected three lengths".into());
        };
        Ok(MeshSettings {
            block_mm: [a, b, c],
            window: match params.mesh.t85_window_s[..] {
                [min_s, max_s] => Some(Window { min_s, max_s }),
                _ => None,
            },
            max_fragments: params.planner.default_max_fragments.max(1) as usize,
        })
    }

    /// Voxelizes a mesh in metres into the part `name`.
    pub fn voxelize(
        &self,
        name: String,
        vertices: &[[f64; 3]],
        triangles: &[[u32; 3]],
    ) -> Result<Part, String> {
        let mut options = VoxelizeOptions::new(name, self.block_mm);
        options.max_fragments = self.max_fragments;
        options.windows = self
            .window
            .map(WindowRule::everywhere)
            .into_iter()
            .collect();
        let voxelized = voxelize_indexed(vertices, triangles, Units::M, &options)
            .map_err(|e| format!("bad part mesh: {e}"))?;
        for w in &voxelized.warnings {
            tracing::warn!("part mesh: {w}");
        }
        Ok(voxelized.part)
    }

    /// Voxelizes a `~/part_mesh` message into the part `name`.
    pub fn voxelize_message(&self, name: String, mesh: &Mesh) -> Result<Part, String> {
        let (vertices, triangles) = mesh_arrays(mesh);
        self.voxelize(name, &vertices, &triangles)
    }

    /// The settings and the part's name as status values.
    pub fn to_values(&self, name: &str) -> Vec<KeyValue> {
        let [a, b, c] = self.block_mm;
        let mut values = vec![
            KeyValue::new(mesh_keys::NAME, name),
            KeyValue::new(mesh_keys::BLOCK_MM, format!("{a} {b} {c}")),
            KeyValue::new(mesh_keys::MAX_FRAGMENTS, self.max_fragments),
        ];
        if let Some(w) = self.window {
            values.push(KeyValue::new(
                mesh_keys::T85_WINDOW_S,
                format!("{} {}", w.min_s, w.max_s),
            ));
        }
        values
    }

    /// Settings and name from recorded status values (the last value of a key wins);
    /// `None` when no `mesh.block_mm` was recorded.
    pub fn from_values(values: &[(String, String)]) -> Result<Option<(Self, String)>, String> {
        let get = |key: &str| values.iter().rev().find(|(k, _)| k == key).map(|(_, v)| v);
        let numbers = |key: &str, n: usize| -> Result<Option<Vec<f64>>, String> {
            let Some(v) = get(key) else { return Ok(None) };
            let xs: Vec<f64> = v
                .split_whitespace()
                .map(str::parse)
                .collect::<Result<_, _>>()
                .map_err(|_| format!("recorded {key}={v:?}: not numbers"))?;
            if xs.len() != n || xs.iter().any(|x| !x.is_finite()) {
                return Err(format!("recorded {key}={v:?}: expected {n} finite numbers"));
            }
            Ok(Some(xs))
        };
        let Some(block) = numbers(mesh_keys::BLOCK_MM, 3)? else {
            return Ok(None);
        };
        let window = numbers(mesh_keys::T85_WINDOW_S, 2)?.map(|w| Window {
            min_s: w[0],
            max_s: w[1],
        });
        let max_fragments = match get(mesh_keys::MAX_FRAGMENTS) {
            Some(v) => v
                .parse()
                .map_err(|_| format!("recorded {}={v:?}: not a count", mesh_keys::MAX_FRAGMENTS))?,
            None => {
                return Err(format!(
                    "{} recorded without {}",
                    mesh_keys::BLOCK_MM,
                    mesh_keys::MAX_FRAGMENTS
                ))
            }
        };
        let name = get(mesh_keys::NAME)
            .cloned()
            .unwrap_or_else(|| "mesh".into());
        Ok(Some((
            MeshSettings {
                block_mm: [block[0], block[1], block[2]],
                window,
                max_fragments,
            },
            name,
        )))
    }
}

/// What the planner answers for a part.
#[derive(Debug, Clone)]
pub struct PlannerOutput {
    /// Fragments of block indices, in weld order.
    pub fragments: Vec<Vec<usize>>,
    pub statistics: PlanStatistics,
    /// Smallest distance of a t8/5 value to its window bounds, s (+inf without windows).
    pub worst_margin_s: f64,
}

/// What a pipeline asks its planner.
pub struct PlanRequest<'a> {
    pub part: &'a Part,
    /// Time limit, s (0 = none).
    pub timeout_s: f64,
    /// The job: cancel flag and progress.
    pub ctx: &'a JobContext,
    /// When recording: where the planner's verdict on every candidate goes.
    pub recorder: Option<&'a Recorder>,
}

/// The planner a pipeline calls. `Err` is the reason there is no plan.
pub type PlanFn = dyn Fn(&PlanRequest) -> Result<PlannerOutput, String> + Send + Sync;

/// A planned part, checked and ready to publish and execute.
#[derive(Debug, Clone)]
pub struct Planned {
    pub part: Part,
    pub fragments: Vec<Vec<usize>>,
    pub statistics: PlanStatistics,
    pub worst_margin_s: f64,
    pub toolpath: Toolpath,
    pub trajectory: JointTrajectory,
    /// The part frame in the robot's base link (m).
    pub plate: Isometry3<f64>,
    /// TCP speeds, m/s.
    pub weld_speed: f64,
    pub transit_speed: f64,
}

impl Planned {
    /// Everything about the plan but the joint trajectory, for the message converters.
    pub fn summary(&self) -> PlanSummary<'_> {
        PlanSummary {
            part: &self.part,
            fragments: &self.fragments,
            toolpath: &self.toolpath,
            weld_speed: self.weld_speed,
            transit_speed: self.transit_speed,
            worst_margin_s: self.worst_margin_s,
            statistics: self.statistics.clone(),
        }
    }
}

/// The node's planning pipeline: process settings, robot, mesh options and a planner.
pub struct PlanningPipeline {
    pub settings: ProcessSettings,
    pub robot: Robot,
    pub mesh: MeshSettings,
    pub timeout_s: f64,
    pub planner: Arc<PlanFn>,
    /// The session's recording, if any.
    pub recorder: Option<Recorder>,
}

impl PlanningPipeline {
    /// Loads the process settings and the robot the parameters name.
    pub fn from_params(params: &NodeParams, planner: Arc<PlanFn>) -> Result<Self, String> {
        let settings = if params.process_file.is_empty() {
            ProcessSettings::default()
        } else {
            let text = std::fs::read_to_string(&params.process_file)
                .map_err(|e| format!("process_file: cannot read {}: {e}", params.process_file))?;
            ProcessSettings::from_yaml(&text)
                .map_err(|e| format!("process_file {}: {e}", params.process_file))?
        };
        let explicit = match params.robot.tcp[..] {
            [x, y, z, r, p, w] => Some(xyz_rpy(&[x, y, z], &[r, p, w])),
            _ => None,
        };
        let choice = TcpChoice {
            explicit,
            default: settings.tcp.isometry(),
        };
        let tip = (!params.robot.tip_link.is_empty()).then_some(params.robot.tip_link.as_str());
        let robot = if params.robot.urdf.is_empty() {
            Robot::from_urdf(BUNDLED_URDF, tip, choice)
                .map_err(|e| format!("bundled robot: {e}"))?
        } else {
            Robot::from_urdf_file(std::path::Path::new(&params.robot.urdf), tip, choice)
                .map_err(|e| format!("robot.urdf {}: {e}", params.robot.urdf))?
        };
        Ok(PlanningPipeline {
            settings,
            robot,
            mesh: MeshSettings::from_params(params)?,
            timeout_s: params.planner.timeout_s,
            planner,
            recorder: None,
        })
    }

    /// Turns the input into a part (reading the document or voxelizing the mesh).
    pub fn part_of(&self, input: PartInput) -> Result<Part, String> {
        match input {
            PartInput::Document(text) => {
                let part = Part::parse(&text).map_err(|e| format!("bad part document: {e}"))?;
                for w in &part.warnings {
                    tracing::warn!("part {}: {w}", part.name);
                }
                Ok(part)
            }
            PartInput::Mesh {
                name,
                vertices,
                triangles,
            } => self.mesh.voxelize(name, &vertices, &triangles),
        }
    }

    /// Plans motion for checked fragments of `part` and assembles the result.
    pub fn motion(&self, part: Part, found: PlannerOutput) -> Result<Planned, String> {
        let (toolpath, trajectory) =
            plan_motion(&part, &found.fragments, &self.settings, &self.robot)
                .map_err(|e| format!("no robot motion for the plan: {e}"))?;
        let weld_speed = weld_speed(&part, &self.settings);
        Ok(Planned {
            plate: self.settings.plate.isometry(),
            weld_speed,
            transit_speed: self.settings.transit_speed_mm_s / 1000.0,
            part,
            fragments: found.fragments,
            statistics: found.statistics,
            worst_margin_s: found.worst_margin_s,
            toolpath,
            trajectory,
        })
    }
}

/// Checks a plan before anything is published: the plan rules, then every t8/5 window.
pub fn check_plan(part: &Part, fragments: &[Vec<usize>]) -> Result<(), String> {
    let graph = WeldGraph::new(part);
    Plan::from_indices(part, fragments)
        .validate(part, &graph)
        .map_err(|e| format!("the planner's plan is invalid: {e}"))?;
    let model = ThermalModel::new(part, &graph);
    let outcome = thermal::simulate(&model, fragments)
        .map_err(|e| format!("the planner's plan cannot be simulated: {e}"))?;
    if let Some(v) = outcome.violation {
        return Err(format!(
            "the planner's plan breaks the t8/5 window of block {}",
            BlockDisplay(part.block(v.block))
        ));
    }
    Ok(())
}

impl Pipeline for PlanningPipeline {
    type Input = PartInput;
    type Output = Box<Planned>;

    fn run(&self, input: PartInput, ctx: &JobContext) -> Result<Box<Planned>, String> {
        let cancelled = || ctx.cancel.is_cancelled();
        ctx.progress("reading part", None, input.describe());
        let part = self.part_of(input)?;
        if cancelled() {
            return Err("cancelled".into());
        }
        ctx.progress(
            "planning",
            Some(0.0),
            format!(
                "{}: {} blocks, k = {}",
                part.name,
                part.len(),
                part.max_fragments
            ),
        );
        let found = (self.planner)(&PlanRequest {
            part: &part,
            timeout_s: self.timeout_s,
            ctx,
            recorder: self.recorder.as_ref(),
        })?;
        if cancelled() {
            return Err("cancelled".into());
        }
        ctx.progress("checking plan", None, "");
        check_plan(&part, &found.fragments)?;
        ctx.progress(
            "robot motion",
            None,
            format!("{} fragment(s)", found.fragments.len()),
        );
        self.motion(part, found).map(Box::new)
    }
}

/// The project's SAT planner ([`waam_planner::plan`]) as the node's planner: best plan by
/// the documented objective within the time limit.
pub fn sat_planner() -> Arc<PlanFn> {
    Arc::new(|request: &PlanRequest| {
        let (part, timeout_s, ctx) = (request.part, request.timeout_s, request.ctx);
        let options = waam_planner::Options {
            timeout: (timeout_s > 0.0).then(|| std::time::Duration::from_secs_f64(timeout_s)),
            // A newer part stops this run (inside a solve with CaDiCaL); the worker then drops it.
            cancel: Some(ctx.cancel.flag()),
            ..waam_planner::Options::default()
        };
        let mut candidates = request.recorder.map(CandidateRecorder::new);
        let mut last = std::time::Instant::now();
        let mut progress = |s: &waam_planner::Stats| {
            if let Some(c) = candidates.as_mut() {
                c.progress(s);
            }
            if last.elapsed() >= std::time::Duration::from_millis(200) {
                last = std::time::Instant::now();
                let fraction = (timeout_s > 0.0).then(|| (s.total_s / timeout_s).min(1.0));
                ctx.progress(
                    "planning",
                    fraction,
                    format!("{} candidates, {} feasible", s.candidates, s.feasible),
                );
            }
        };
        let report = waam_planner::plan(part, &options, &mut progress)
            .map_err(|e| format!("planning failed: {e}"))?;
        if let Some(Err(e)) = candidates.map(CandidateRecorder::finish) {
            tracing::warn!("recording the planner's candidates: {e}");
        }
        let statistics = crate::planning::statistics(&report.stats, report.proven);
        match report.best {
            Some(found) => Ok(PlannerOutput {
                fragments: found.fragments,
                statistics,
                worst_margin_s: found.margin,
            }),
            None => Err(match report.no_plan {
                Some(reason) => format!("no plan for part {}: {reason}", part.name),
                None => format!(
                    "no plan for part {} found within the planner timeout of {timeout_s} s",
                    part.name
                ),
            }),
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mesh_settings_round_trip_through_status_values_and_bad_ones_are_named() {
        let settings = MeshSettings {
            block_mm: [6.0, 5.5, 2.5],
            window: Some(Window {
                min_s: 3.0,
                max_s: 9.5,
            }),
            max_fragments: 3,
        };
        let values: Vec<(String, String)> = settings
            .to_values("mesh-2")
            .into_iter()
            .map(|kv| (kv.key, kv.value))
            .collect();
        assert_eq!(
            MeshSettings::from_values(&values).unwrap(),
            Some((settings, "mesh-2".to_string()))
        );
        assert_eq!(MeshSettings::from_values(&[]).unwrap(), None);
        let bad = [(mesh_keys::BLOCK_MM.to_string(), "6 x 2.5".to_string())];
        let err = MeshSettings::from_values(&bad).unwrap_err();
        assert!(
            err.contains("mesh.block_mm") && err.contains("6 x 2.5"),
            "{err}"
        );
        let short = [(mesh_keys::BLOCK_MM.to_string(), "6 6".to_string())];
        assert!(MeshSettings::from_values(&short).is_err());
    }

    fn pipeline() -> PlanningPipeline {
        let planner: Arc<PlanFn> =
            Arc::new(|_: &PlanRequest| Err("no planner in this test".to_string()));
        PlanningPipeline::from_params(&NodeParams::default(), planner).unwrap()
    }

    /// A closed box with one corner at the origin, in metres, as shape_msgs/Mesh carries it.
    fn box_mesh(s: [f64; 3]) -> PartInput {
        let vertices: Vec<[f64; 3]> = (0..8)
            .map(|i| {
                [
                    (i & 1) as f64 * s[0],
                    ((i >> 1) & 1) as f64 * s[1],
                    ((i >> 2) & 1) as f64 * s[2],
                ]
            })
            .collect();
        let quads = [
            [0, 2, 3, 1],
            [4, 5, 7, 6],
            [0, 1, 5, 4],
            [2, 6, 7, 3],
            [0, 4, 6, 2],
            [1, 3, 7, 5],
        ];
        let triangles = quads
            .iter()
            .flat_map(|[a, b, c, d]| [[*a, *b, *c], [*a, *c, *d]])
            .collect();
        PartInput::Mesh {
            name: "box".into(),
            vertices,
            triangles,
        }
    }

    #[test]
    fn inputs_become_parts_or_say_what_is_wrong() {
        let p = pipeline();
        let part = p.part_of(box_mesh([0.024, 0.012, 0.005])).unwrap();
        assert_eq!(part.len(), 16, "4 x 2 x 2 blocks of 6 x 6 x 2.5 mm");
        assert_eq!(part.max_fragments, 2);
        let err = p
            .part_of(PartInput::Document("layers: [".into()))
            .unwrap_err();
        assert!(err.starts_with("bad part document"), "{err}");
        let PartInput::Mesh {
            name,
            vertices,
            mut triangles,
        } = box_mesh([0.024, 0.012, 0.005])
        else {
            unreachable!()
        };
        triangles.pop(); // an open mesh
        let err = p
            .part_of(PartInput::Mesh {
                name,
                vertices,
                triangles,
            })
            .unwrap_err();
        assert!(err.starts_with("bad part mesh"), "{err}");
    }

    #[test]
    fn unchecked_plans_are_refused() {
        let part = Part::parse(
            "name: w\nblock_mm: [6, 6, 2.5]\nmax_fragments: 2\nlayers:\n  - |\n    ##\n  - |\n    ##\n",
        )
        .unwrap();
        assert!(check_plan(&part, &[vec![0, 1, 3, 2]]).is_ok());
        // Welding under a block that stands (the top layer before the bottom one).
        let err = check_plan(&part, &[vec![2, 3], vec![0, 1]]).unwrap_err();
        assert!(err.contains("invalid"), "{err}");
        // A block missing.
        assert!(check_plan(&part, &[vec![0, 1, 3]]).is_err());
    }
}
