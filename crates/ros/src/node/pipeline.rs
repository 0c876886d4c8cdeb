//! The node's planning job: [`waam_pipeline`] (input → part → plan → check → motion) on a
//! worker thread, with progress and cancellation between stages.
//!
//! Runs on a worker thread ([`super::worker`]). Every stage reports progress and checks the
//! cancel flag between stages; any failure is a [`JobError`] for an ERROR status, never a
//! panic, and a plan is handed on only after it passed validation and the thermal check.

use std::sync::Arc;

use super::params::NodeParams;
use super::worker::{JobContext, Pipeline};
use waam_messages::planning::CandidateRecorder;
use waam_motion::robot::limits::LimitsError;
use waam_motion::robot::{xyz_rpy, RobotError};
use waam_motion::toolpath::SettingsError;
use waam_part::{Part, Window};
use waam_pipeline::{
    read_input, Cell, CellError, CellSource, ChosenPlan, Interrupt, Objective, Outcome,
    PipelineError, Progress,
};
pub use waam_pipeline::{MeshSettings, PartInput, Planned};
use waam_rosbag::Recorder;
use waam_rosmsg::shape_msgs::Mesh;

/// Why a planning job has no plan for its part.
#[derive(Debug, thiserror::Error)]
pub enum JobError {
    #[error("cancelled")]
    Cancelled,
    #[error(transparent)]
    Pipeline(#[from] PipelineError),
    #[error("planning failed: {0}")]
    Planner(#[from] waam_planner::PlanError),
    #[error("no plan for part {part}: {reason}")]
    NoPlan {
        part: String,
        reason: waam_planner::NoPlan,
    },
    #[error("no plan for part {part} found within the planner timeout of {timeout_s} s")]
    Timeout { part: String, timeout_s: f64 },
    /// A planner injected by a test or another front end.
    #[error("{0}")]
    Other(String),
}

/// Why the node's pipeline could not be set up from its parameters.
#[derive(Debug, thiserror::Error)]
pub enum SetupError {
    #[error("process_file: cannot read {path}: {source}")]
    ReadProcess {
        path: String,
        source: std::io::Error,
    },
    #[error("process_file {path}: {source}")]
    Process { path: String, source: SettingsError },
    #[error("bundled robot: {0}")]
    BundledRobot(RobotError),
    #[error("robot.urdf {path}: {source}")]
    Robot { path: String, source: RobotError },
    #[error("robot.joint_limits: cannot read {path}: {source}")]
    ReadLimits {
        path: String,
        source: std::io::Error,
    },
    #[error("robot.joint_limits {path}: {source}")]
    Limits { path: String, source: LimitsError },
    #[error("mesh.block_mm: expected three lengths")]
    MeshBlock,
    #[error("mesh.bead_mm: expected [] or two lengths")]
    MeshBead,
}

impl From<CellError> for SetupError {
    /// The cell loader's error, worded by the node's parameters.
    fn from(e: CellError) -> SetupError {
        let path = |p: std::path::PathBuf| p.display().to_string();
        match e {
            CellError::ReadProcess { path: p, source } => SetupError::ReadProcess {
                path: path(p),
                source,
            },
            CellError::Process { path: p, source } => SetupError::Process {
                path: path(p),
                source,
            },
            CellError::BundledRobot(e) => SetupError::BundledRobot(e),
            CellError::Robot { path: p, source } => SetupError::Robot {
                path: path(p),
                source,
            },
            CellError::ReadLimits { path: p, source } => SetupError::ReadLimits {
                path: path(p),
                source,
            },
            CellError::Limits { path: p, source } => SetupError::Limits {
                path: path(p),
                source,
            },
        }
    }
}

/// A `~/part_mesh` message as an input named `name`.
pub fn mesh_input(name: String, mesh: &Mesh) -> PartInput {
    let (vertices, triangles) = mesh_arrays(mesh);
    PartInput::Mesh {
        name,
        vertices,
        triangles,
    }
}

/// A shape_msgs/Mesh's vertices (m) and triangles as plain arrays.
pub fn mesh_arrays(mesh: &Mesh) -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
    (
        mesh.vertices.iter().map(|p| [p.x, p.y, p.z]).collect(),
        mesh.triangles.iter().map(|t| t.vertex_indices).collect(),
    )
}

/// The mesh settings the parameters give.
pub fn mesh_settings(params: &NodeParams) -> Result<MeshSettings, SetupError> {
    let [a, b, c] = params.mesh.block_mm[..] else {
        return Err(SetupError::MeshBlock);
    };
    Ok(MeshSettings {
        block_mm: [a, b, c],
        bead_mm: match params.mesh.bead_mm[..] {
            [] => None,
            [w, h] => Some([w, h]),
            _ => return Err(SetupError::MeshBead),
        },
        window: match params.mesh.t85_window_s[..] {
            [min_s, max_s] => Some(Window { min_s, max_s }),
            _ => None,
        },
        max_fragments: params.planner.default_max_fragments.max(1) as usize,
    })
}

/// One part to plan, with the settings of its request (a `~/plan` goal) over the node's.
#[derive(Clone)]
pub struct Job {
    pub input: PartInput,
    /// Voxelizing a mesh; `None`: the node's.
    pub mesh: Option<MeshSettings>,
    /// k over the part's own.
    pub max_fragments: Option<usize>,
    /// Time limit (s); `None`: the node's.
    pub timeout_s: Option<f64>,
    /// Stop at the first feasible plan.
    pub first_feasible: bool,
}

impl From<PartInput> for Job {
    fn from(input: PartInput) -> Job {
        Job {
            input,
            mesh: None,
            max_fragments: None,
            timeout_s: None,
            first_feasible: false,
        }
    }
}

/// What a pipeline asks its planner.
pub struct PlanRequest<'a> {
    pub part: &'a Part,
    /// Time limit, s (0 = none).
    pub timeout_s: f64,
    /// Memory limit of the search, MB (`planner.max_memory_mb`).
    pub max_memory_mb: u64,
    /// The most threads the run uses, 0 = all cores (`planner.threads`).
    pub threads: usize,
    /// Stop at the first feasible plan instead of the best within the limit.
    pub first_feasible: bool,
    /// The job: cancel flag and progress.
    pub ctx: &'a JobContext,
    /// When recording: where the planner's verdict on every candidate goes.
    pub recorder: Option<&'a Recorder>,
    /// The cell the plan is welded in: its torch and robot check the planner's candidates,
    /// and the plan's motion is planned in it.
    pub cell: &'a Cell,
}

impl PlanRequest<'_> {
    /// The stages after planning for a plan a planner chose (a given plan: `waam publish
    /// --plan`, tests): the plan checked and its motion planned in the request's cell
    /// ([`Cell::motion_until`]), stopped by a cancel of the job.
    pub fn motion(&self, chosen: ChosenPlan) -> Result<Box<Planned>, JobError> {
        if self.ctx.cancel.is_cancelled() {
            return Err(JobError::Cancelled);
        }
        motion_progress(self.ctx, chosen.fragments.len());
        let planned =
            self.cell
                .motion_until(self.part.clone(), chosen, &motion_interrupt(self.ctx));
        job_motion(planned)
    }
}

/// The stages after planning stop at a superseded or cancelled job, within a simulation
/// step: the cancel flag, not the planner's stop flag, which a first feasible plan raises.
fn motion_interrupt(ctx: &JobContext) -> Interrupt {
    Interrupt::default().with_cancel(Some(ctx.cancel.cancelled_flag()))
}

fn motion_progress(ctx: &JobContext, fragments: usize) {
    ctx.progress(
        "checking plan and robot motion",
        None,
        format!("{fragments} fragment(s)"),
    );
}

/// The motion stage's answer as the job's.
fn job_motion(planned: Result<Planned, PipelineError>) -> Result<Box<Planned>, JobError> {
    match planned {
        Ok(planned) => Ok(Box::new(planned)),
        Err(PipelineError::Interrupted(_)) => Err(JobError::Cancelled),
        Err(e) => Err(e.into()),
    }
}

/// The planner a pipeline calls, through to the plan's validated motion in the request's
/// cell ([`sat_planner`]: the pipeline's entry, [`waam_pipeline::plan`]). `Err` says why
/// there is no plan or no motion.
pub type PlanFn = dyn Fn(&PlanRequest) -> Result<Box<Planned>, JobError> + Send + Sync;

/// The node's planning pipeline: the cell (process settings, robot), mesh options and a
/// planner.
pub struct PlanningPipeline {
    pub cell: Cell,
    pub mesh: MeshSettings,
    pub timeout_s: f64,
    pub max_memory_mb: u64,
    pub threads: usize,
    pub planner: Arc<PlanFn>,
    /// The session's recording, if any.
    pub recorder: Option<Recorder>,
}

impl PlanningPipeline {
    /// Loads the process settings and the robot the parameters name.
    pub fn from_params(params: &NodeParams, planner: Arc<PlanFn>) -> Result<Self, SetupError> {
        let path = |p: &str| (!p.is_empty()).then(|| std::path::PathBuf::from(p));
        let cell = CellSource {
            process: path(&params.process_file),
            urdf: path(&params.robot.urdf),
            tip: (!params.robot.tip_link.is_empty()).then(|| params.robot.tip_link.clone()),
            tcp: match params.robot.tcp[..] {
                [x, y, z, r, p, w] => Some(xyz_rpy(&[x, y, z], &[r, p, w])),
                _ => None,
            },
            joint_limits: path(&params.robot.joint_limits),
            no_torch: false,
        }
        .load()?;
        Ok(PlanningPipeline {
            cell,
            mesh: mesh_settings(params)?,
            timeout_s: params.planner.timeout_s,
            max_memory_mb: params.planner.memory_limit_mb(),
            threads: params.planner.thread_count(),
            planner,
            recorder: None,
        })
    }

    /// Turns the input into a part (reading the document, or voxelizing or slicing the mesh).
    pub fn part_of(&self, input: PartInput) -> Result<Part, PipelineError> {
        read_input(input, &self.mesh)
    }
}

impl Pipeline for PlanningPipeline {
    type Input = Job;
    type Output = Box<Planned>;
    type Error = JobError;

    fn run(&self, job: Job, ctx: &JobContext) -> Result<Box<Planned>, JobError> {
        let cancelled = || ctx.cancel.is_cancelled();
        ctx.progress("reading part", None, job.input.describe());
        let mut part = read_input(job.input, job.mesh.as_ref().unwrap_or(&self.mesh))?;
        if let Some(k) = job.max_fragments {
            part.max_fragments = k;
        }
        if cancelled() {
            return Err(JobError::Cancelled);
        }
        ctx.progress(
            "planning",
            Some(0.0),
            format!(
                "{}: {} {}, k = {}",
                part.name,
                part.len(),
                if part.bead_part().is_some() {
                    "bead nodes"
                } else {
                    "blocks"
                },
                part.max_fragments
            ),
        );
        let timeout_s = job.timeout_s.unwrap_or(self.timeout_s);
        (self.planner)(&PlanRequest {
            part: &part,
            timeout_s,
            max_memory_mb: self.max_memory_mb,
            threads: self.threads,
            first_feasible: job.first_feasible,
            ctx,
            recorder: self.recorder.as_ref(),
            cell: &self.cell,
        })
    }
}

/// The pipeline's entry ([`waam_pipeline::plan`]) as the node's planner: the SAT
/// planner's best plan by the documented objective within the time limit, checked by the
/// cell's torch and robot, then the plan's validated motion in the cell.
pub fn sat_planner() -> Arc<PlanFn> {
    Arc::new(|request: &PlanRequest| {
        let (part, timeout_s, ctx) = (request.part, request.timeout_s, request.ctx);
        let options = waam_pipeline::Options {
            planner: waam_planner::Options {
                timeout: std::time::Duration::try_from_secs_f64(timeout_s)
                    .ok()
                    .filter(|t| !t.is_zero()),
                // A newer part or a cancelled goal stops this run (inside a solve with
                // CaDiCaL); the worker then drops it. The first feasible plan stops it too
                // when asked. The same time limit and flag bound the robot checks of its
                // candidates.
                cancel: Some(ctx.cancel.flag()),
                max_memory_mb: request.max_memory_mb,
                threads: request.threads,
                ..waam_planner::Options::default()
            },
            objective: Objective::Best,
            motion: motion_interrupt(ctx),
        };
        let mut candidates = request.recorder.map(CandidateRecorder::new);
        let mut last = std::time::Instant::now();
        let mut progress = |progress: Progress| {
            let event = match progress {
                Progress::Planner(event) => event,
                Progress::Motion { fragments } => {
                    if !ctx.cancel.is_cancelled() {
                        motion_progress(ctx, fragments);
                    }
                    return;
                }
            };
            if let Some(c) = candidates.as_mut() {
                c.on_event(&event);
            }
            let s = event.stats();
            if request.first_feasible && s.feasible > 0 {
                ctx.cancel.stop_early(); // the planner returns the plan it has
            }
            if last.elapsed() >= std::time::Duration::from_millis(200) {
                last = std::time::Instant::now();
                let fraction = (timeout_s > 0.0).then(|| (s.total_s / timeout_s).min(1.0));
                ctx.report(super::worker::Progress {
                    stage: "planning",
                    fraction,
                    detail: format!("{} candidates, {} feasible", s.candidates, s.feasible),
                    counts: Some(super::worker::Counts {
                        candidates: s.candidates,
                        feasible: s.feasible,
                        cuts: s.cycle_cuts,
                        best_margin_s: s.best_margin_s,
                    }),
                });
            }
        };
        let outcome = waam_pipeline::plan(part, Some(request.cell), &options, &mut progress);
        if let Some(Err(e)) = candidates.map(CandidateRecorder::finish) {
            tracing::warn!("recording the planner's candidates: {e}");
        }
        let Outcome { report, motion } = match outcome {
            Ok(outcome) => outcome,
            Err(PipelineError::Planner(e)) => return Err(JobError::Planner(e)),
            Err(e) => return Err(e.into()),
        };
        match motion {
            // Planned past a cancel: not handed on.
            Some(_) if ctx.cancel.is_cancelled() => Err(JobError::Cancelled),
            Some(planned) => job_motion(planned),
            None => Err(match report.no_plan {
                Some(reason) => JobError::NoPlan {
                    part: part.name.clone(),
                    reason,
                },
                None => JobError::Timeout {
                    part: part.name.clone(),
                    timeout_s,
                },
            }),
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use waam_pipeline::check_plan;

    fn pipeline() -> PlanningPipeline {
        let planner: Arc<PlanFn> =
            Arc::new(|_: &PlanRequest| Err(JobError::Other("no planner in this test".into())));
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
        assert!(err.to_string().starts_with("bad part document"), "{err}");
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
        assert!(err.to_string().starts_with("bad part mesh"), "{err}");
    }

    #[test]
    fn the_bead_parameter_slices_meshes_into_beads() {
        let planner: Arc<PlanFn> =
            Arc::new(|_: &PlanRequest| Err(JobError::Other("no planner in this test".into())));
        let mut params = NodeParams::default();
        params.mesh.bead_mm = vec![6.0, 2.5];
        let p = PlanningPipeline::from_params(&params, planner).unwrap();
        // A 24 x 12 mm box, 5 mm tall: two layers of 2.5 mm, each a ring of beads inside
        // its 24 x 12 mm section, not the 16 voxels of 6 x 6 x 2.5 mm.
        let part = p.part_of(box_mesh([0.024, 0.012, 0.005])).unwrap();
        let beads = part.bead_part().expect("a graph part");
        assert_eq!(beads.layers(), 2);
        assert_eq!(beads.bead_mm, [6.0, 2.5]);
        for node in &beads.nodes {
            let [x, y, _] = node.centre_mm;
            assert!(
                (0.0..=24.0).contains(&x) && (0.0..=12.0).contains(&y),
                "{x}, {y}"
            );
        }
        params.mesh.bead_mm = vec![6.0, 0.0];
        let err = params.check().unwrap_err().to_string();
        assert!(err.contains("mesh.bead_mm"), "{err}");
    }

    #[test]
    fn the_joint_limits_parameter_sets_the_robots_limits() {
        let planner: Arc<PlanFn> =
            Arc::new(|_: &PlanRequest| Err(JobError::Other("no planner in this test".into())));
        let mut params = NodeParams::default();
        params.robot.joint_limits = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../config/joint_limits.yaml"
        )
        .into();
        let p = PlanningPipeline::from_params(&params, planner.clone()).unwrap();
        assert_eq!(p.cell.robot.joints[0].acceleration, Some(2.0));
        assert_eq!(p.cell.robot.joints[0].velocity, 1.5);
        assert_eq!(pipeline().cell.robot.joints[0].acceleration, None);
        params.robot.joint_limits = "/nonexistent/joint_limits.yaml".into();
        let err = PlanningPipeline::from_params(&params, planner)
            .err()
            .unwrap();
        assert!(
            err.to_string()
                .starts_with("robot.joint_limits: cannot read"),
            "{err}"
        );
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
        assert!(err.to_string().contains("invalid"), "{err}");
        // A block missing.
        assert!(check_plan(&part, &[vec![0, 1, 3]]).is_err());
    }

    /// The planner parameters reach the planner's request: `planner.threads` bounds the
    /// run as `waam plan --threads` does, `planner.max_memory_mb` its memory.
    #[test]
    fn the_planner_parameters_reach_the_request() {
        let mut params = NodeParams::default();
        params.planner.threads = 3;
        params.planner.max_memory_mb = 512;
        let planner: Arc<PlanFn> = Arc::new(|r: &PlanRequest| {
            Err(JobError::Other(format!(
                "threads {} memory {}",
                r.threads, r.max_memory_mb
            )))
        });
        let pipeline = PlanningPipeline::from_params(&params, planner).unwrap();
        let job = Job::from(PartInput::Document(
            "name: w\nblock_mm: [6, 6, 2.5]\nmax_fragments: 1\nlayers:\n  - |\n    ##\n".into(),
        ));
        let ctx = JobContext::new(1, crate::node::worker::Cancel::new(), |_| {});
        let Err(err) = pipeline.run(job, &ctx) else {
            panic!("the test planner refuses every part");
        };
        assert_eq!(err.to_string(), "threads 3 memory 512");
        assert_eq!(
            NodeParams::default().planner.threads,
            0,
            "all cores by default"
        );
    }
}
