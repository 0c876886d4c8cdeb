//! Thick-wall layers and parts end to end, what `waam layer plan`, `waam layer slice` and
//! `waam layer plan-part` run: one layer read, searched, written, moved and recorded
//! ([`layer`]); a mesh sliced into a part directory ([`slice_to_dir`]), every layer's trail
//! searched bottom up (`waam_layer::part`), each layer's files, its motion at the layer's
//! height and its recording, and the summary `part-plan.yaml` ([`plan_part_to_dir`],
//! [`PartPlanLayer`]). The binary parses arguments, prints and publishes; the domain work
//! is here.

pub mod layer;

use std::path::{Path, PathBuf};

use serde_json::json;
use thiserror::Error;
use waam_layer::output::TrailFile;
use waam_layer::part::{plan_part, ManifestLayer, PartError, PartManifest, PartOptions};
use waam_layer::search::TooLarge;
use waam_layer::slice::{slice_mesh, LayerDoc, LayerParams, SliceError, SliceOptions, SlicedLayer};
use waam_layer::{plan_layer_motion_at, LayerError, Model, ModelError, SearchResult};
use waam_mesh::{read_stl, MeshError, Units};
use waam_messages::convert::{ConvertError, PlanMessages};
use waam_messages::layer::{plan_messages, LayerRecording, MotionOutcome};
use waam_motion::robot::Robot;
use waam_motion::toolpath::{MotionSummary, ProcessSettings, Toolpath};
use waam_motion::trajectory::JointTrajectory;
use waam_motion::{write_outputs, MotionError};
use waam_rosbag::{BagError, Recorder};
use waam_rosmsg::builtin_interfaces::Time;
use waam_rosmsg::std_msgs::Header;

pub use waam_layer::part::PlannedLayer;

/// Why a thick-wall part cannot be sliced, planned or written; each names the file or layer.
#[derive(Debug, Error)]
pub enum WallError {
    #[error("cannot read layer {}", path.display())]
    ReadLayer {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("in layer {}", path.display())]
    Layer {
        path: PathBuf,
        #[source]
        source: LayerError,
    },
    #[error("layer {layer}")]
    Model {
        layer: String,
        #[source]
        source: ModelError,
    },
    #[error(transparent)]
    TooLarge(#[from] TooLarge),
    #[error("cannot read {}", path.display())]
    Read {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("in {}", path.display())]
    Parse {
        path: PathBuf,
        #[source]
        source: serde_yaml::Error,
    },
    #[error("{}", path.display())]
    Trail {
        path: PathBuf,
        #[source]
        source: ModelError,
    },
    #[error("cannot read mesh {}", path.display())]
    ReadMesh {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("in mesh {}", path.display())]
    Mesh {
        path: PathBuf,
        #[source]
        source: MeshError,
    },
    #[error("in mesh {}", path.display())]
    Slice {
        path: PathBuf,
        #[source]
        source: SliceError,
    },
    #[error("cannot create {}", path.display())]
    Create {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("cannot write {}", path.display())]
    Write {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("cannot write motion files in {}", dir.display())]
    WriteMotion {
        dir: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("cannot write {}", path.display())]
    Yaml {
        path: PathBuf,
        #[source]
        source: serde_yaml::Error,
    },
    #[error("layer {layer}: cannot build its messages")]
    Messages {
        layer: String,
        #[source]
        source: ConvertError,
    },
    #[error("layer {layer}: cannot record it")]
    Record {
        layer: String,
        #[source]
        source: BagError,
    },
    #[error(transparent)]
    Part(#[from] PartError),
}

/// Cuts the STL mesh `mesh_path` into layers and writes them into the part directory `out`
/// (created if missing): `layer-KKK.yaml` per layer and `part.yaml` listing them.
pub fn slice_to_dir(
    mesh_path: &Path,
    layer_height: f64,
    wall_width: Option<f64>,
    params: LayerParams,
    out: &Path,
) -> Result<(PartManifest, Vec<SlicedLayer>), WallError> {
    let bytes = std::fs::read(mesh_path).map_err(|source| WallError::ReadMesh {
        path: mesh_path.into(),
        source,
    })?;
    let mesh = read_stl(&bytes, Units::Mm).map_err(|source| WallError::Mesh {
        path: mesh_path.into(),
        source,
    })?;
    let name = mesh_path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "part".into());
    let options = SliceOptions {
        name: name.clone(),
        layer_height_mm: layer_height,
        wall_width_mm: wall_width,
        params,
    };
    let layers = slice_mesh(&mesh, &options).map_err(|source| WallError::Slice {
        path: mesh_path.into(),
        source,
    })?;
    create_dir(out)?;
    let mut manifest = PartManifest {
        name,
        source: mesh_path.display().to_string(),
        layer_height_mm: layer_height,
        layers: Vec::new(),
    };
    for (k, l) in layers.iter().enumerate() {
        let file = format!("layer-{k:03}.yaml");
        write(&out.join(&file), LayerDoc::of(&l.layer).to_yaml())?;
        manifest.layers.push(ManifestLayer { file, z_mm: l.z_mm });
    }
    write_yaml(&out.join("part.yaml"), &manifest)?;
    Ok((manifest, layers))
}

/// Writes `dir/trail.yaml`: the trail's moves, deadheading and torch position per step.
pub fn write_trail(dir: &Path, model: &Model, r: &SearchResult) -> Result<(), WallError> {
    let file = TrailFile::new(
        model,
        &r.trail,
        r.objective,
        r.lower_bound,
        r.proven_optimal,
    );
    write_yaml(&dir.join("trail.yaml"), &file)
}

/// One layer's line in `OUT/part-plan.yaml`.
#[derive(Debug, Clone, serde::Serialize)]
pub struct PartPlanLayer {
    pub layer: String,
    /// The layer's directory in OUT.
    pub dir: String,
    pub z_mm: f64,
    pub objective: f64,
    pub lower_bound: f64,
    pub proven_optimal: bool,
    pub relative_gap: f64,
    /// Node ids of the trail's first and last node.
    pub start: String,
    pub end: String,
    pub deadheading: Vec<[String; 2]>,
    /// What the layer below forbade (node ids).
    pub forbidden_starts: Vec<String>,
    pub forbidden_deadheads: Vec<[String; 2]>,
    /// False when no trail obeyed the forbidden moves and the layer was planned without them.
    pub varied: bool,
    /// The carried-over heat at the layer's start, °C.
    pub initial_max_c: f64,
    pub initial_mean_c: f64,
    pub end_max_c: f64,
    pub seconds: f64,
    /// The motion's [`MotionSummary`], or `{error: …}` when the robot cannot weld the trail;
    /// none without a robot.
    pub motion: Option<serde_json::Value>,
}

impl PartPlanLayer {
    /// The line of layer `k`, `p` as planned, with its motion's outcome.
    pub fn of(k: usize, p: &PlannedLayer, motion: Option<&LayerMotion>) -> PartPlanLayer {
        let layer = &p.model.layer;
        let r = &p.result;
        let id = |v: usize| layer.nodes[v].id.clone();
        let amb = layer.temperatures.ambient_c;
        let max = |u: &[f64]| u.iter().copied().fold(f64::NEG_INFINITY, f64::max) + amb;
        let mean = p.model.initial_field.iter().sum::<f64>()
            / p.model.initial_field.len().max(1) as f64
            + amb;
        PartPlanLayer {
            layer: layer.name.clone(),
            dir: layer_dir(k),
            z_mm: p.z_mm,
            objective: r.objective,
            lower_bound: r.lower_bound,
            proven_optimal: r.proven_optimal,
            relative_gap: r.relative_gap,
            start: p.start_node().map(id).unwrap_or_default(),
            end: p.end_node().map(id).unwrap_or_default(),
            deadheading: p.deadheads().iter().map(|&[a, b]| [id(a), id(b)]).collect(),
            forbidden_starts: p.forbidden_starts.iter().map(|&v| id(v)).collect(),
            forbidden_deadheads: p
                .forbidden_deadheads
                .iter()
                .map(|&[a, b]| [id(a), id(b)])
                .collect(),
            varied: p.varied,
            initial_max_c: max(&p.model.initial_field),
            initial_mean_c: mean,
            end_max_c: max(&p.end_field),
            seconds: r.seconds,
            motion: motion.map(|m| match m {
                Ok((tp, _)) => json!(MotionSummary::of(tp)),
                Err(e) => json!({ "error": e.to_string() }),
            }),
        }
    }
}

/// A layer's validated motion, or why the robot cannot weld its trail.
pub type LayerMotion = Result<(Toolpath, JointTrajectory), MotionError>;

/// The directory of layer `k` in a part plan's output: `layer-KKK`.
pub fn layer_dir(k: usize) -> String {
    format!("layer-{k:03}")
}

/// Where and how a part is planned.
pub struct PartRun<'a> {
    /// The directory for the results (created if missing).
    pub out: &'a Path,
    pub options: &'a PartOptions,
    /// The cell the layers are welded in; without one, no motion.
    pub cell: Option<(&'a ProcessSettings, &'a Robot)>,
    /// Records every layer as `waam layer plan --record` does.
    pub recorder: Option<&'a Recorder>,
}

/// One layer planned and written, for the caller's progress.
pub struct LayerDone<'a> {
    pub index: usize,
    pub total: usize,
    pub planned: &'a PlannedLayer,
    pub line: &'a PartPlanLayer,
    pub motion: Option<&'a LayerMotion>,
}

/// What a part plan produced.
#[derive(Debug)]
pub struct PartPlan {
    pub layers: Vec<PlannedLayer>,
    pub summary: Vec<PartPlanLayer>,
    /// `OUT/part-plan.yaml`.
    pub path: PathBuf,
    /// Some layer's trail could not be welded by the robot (NO MOTION).
    pub motion_failed: bool,
}

/// Plans the part's `layers` (z, layer; bottom first) as [`plan_part`] does and writes per
/// layer `OUT/layer-KKK/` (trail.yaml, layer.yaml and, with a cell, toolpath.yaml and
/// trajectory.yaml at the layer's height), records it with a recorder, then writes
/// `OUT/part-plan.yaml`. `progress` hears of each layer when it is written. A layer the
/// robot cannot weld is reported in its line and in [`PartPlan::motion_failed`], not as an
/// error; the first error (a file, the recording) stops the run.
pub fn plan_part_to_dir(
    layers: &[(f64, waam_layer::Layer)],
    run: &PartRun,
    mut progress: impl FnMut(&LayerDone),
) -> Result<PartPlan, WallError> {
    create_dir(run.out)?;
    let total = layers.len();
    let mut summary: Vec<PartPlanLayer> = Vec::new();
    let mut motion_failed = false;
    let mut error: Option<WallError> = None;
    let planned = plan_part(layers, run.options, |k, p| {
        // After an error the search goes on (plan_part has no stop), but nothing is written.
        if error.is_some() {
            return;
        }
        match write_layer(k, p, run) {
            Ok((line, motion)) => {
                motion_failed |= matches!(motion, Some(Err(_)));
                progress(&LayerDone {
                    index: k,
                    total,
                    planned: p,
                    line: &line,
                    motion: motion.as_ref(),
                });
                summary.push(line);
            }
            Err(e) => error = Some(e),
        }
    })?;
    if let Some(e) = error {
        return Err(e);
    }
    let path = run.out.join("part-plan.yaml");
    write_yaml(&path, &summary)?;
    Ok(PartPlan {
        layers: planned,
        summary,
        path,
        motion_failed,
    })
}

/// Writes layer `k`'s directory, plans its motion and records it.
fn write_layer(
    k: usize,
    p: &PlannedLayer,
    run: &PartRun,
) -> Result<(PartPlanLayer, Option<LayerMotion>), WallError> {
    let layer = &p.model.layer;
    let r = &p.result;
    let dir = run.out.join(layer_dir(k));
    create_dir(&dir)?;
    write_trail(&dir, &p.model, r)?;
    write(&dir.join("layer.yaml"), LayerDoc::of(layer).to_yaml())?;
    let motion: Option<LayerMotion> = run
        .cell
        .map(|(settings, robot)| plan_layer_motion_at(&p.model, &r.trail, p.z_mm, settings, robot));
    if let Some(Ok((tp, traj))) = &motion {
        write_outputs(&dir, tp, traj).map_err(|source| WallError::WriteMotion {
            dir: dir.clone(),
            source,
        })?;
    }
    if let Some(recorder) = run.recorder {
        record_layer(recorder, p, motion.as_ref(), run.cell.map(|c| c.0))?;
    }
    tracing::debug!("layer {k} ({}): wrote {}", layer.name, dir.display());
    Ok((PartPlanLayer::of(k, p, motion.as_ref()), motion))
}

/// Records one layer of a part as `waam layer plan --record` records a layer.
fn record_layer(
    recorder: &Recorder,
    p: &PlannedLayer,
    motion: Option<&LayerMotion>,
    settings: Option<&ProcessSettings>,
) -> Result<(), WallError> {
    let layer = &p.model.layer;
    let text = LayerDoc::of(layer).to_yaml();
    let recording = LayerRecording::start(recorder, &text, &layer.name).map_err(|source| {
        WallError::Record {
            layer: layer.name.clone(),
            source,
        }
    })?;
    let messages = layer_messages(&p.model, &p.result, motion, settings)?;
    finish_recording(recording, &p.model, &p.result, motion, messages.as_ref())?;
    Ok(())
}

/// The messages of a layer's validated motion (in the robot's base link); none without one.
fn layer_messages(
    model: &Model,
    r: &SearchResult,
    motion: Option<&LayerMotion>,
    settings: Option<&ProcessSettings>,
) -> Result<Option<PlanMessages>, WallError> {
    let (Some(Ok((tp, traj))), Some(settings)) = (motion, settings) else {
        return Ok(None);
    };
    let header = Header::new(Time::now(), tp.frame.clone());
    plan_messages(model, r, tp, traj, settings, &header)
        .map(Some)
        .map_err(|source| WallError::Messages {
            layer: model.layer.name.clone(),
            source,
        })
}

/// Records a layer's outcome (its motion's messages, or why it has none, and the heat) and
/// closes its recording; the heat frames recorded.
fn finish_recording(
    recording: LayerRecording,
    model: &Model,
    r: &SearchResult,
    motion: Option<&LayerMotion>,
    messages: Option<&PlanMessages>,
) -> Result<usize, WallError> {
    let failure = match motion {
        Some(Err(e)) => Some(e.to_string()),
        _ => None,
    };
    let outcome = match (&failure, messages) {
        (Some(e), _) => MotionOutcome::Failed(e),
        (_, Some(m)) => MotionOutcome::Planned(m),
        _ => MotionOutcome::NotPlanned,
    };
    recording
        .finish(model, r, outcome)
        .map_err(|source| WallError::Record {
            layer: model.layer.name.clone(),
            source,
        })
}

fn create_dir(path: &Path) -> Result<(), WallError> {
    std::fs::create_dir_all(path).map_err(|source| WallError::Create {
        path: path.into(),
        source,
    })
}

fn write(path: &Path, text: impl AsRef<[u8]>) -> Result<(), WallError> {
    std::fs::write(path, text).map_err(|source| WallError::Write {
        path: path.into(),
        source,
    })
}

fn write_yaml(path: &Path, value: &impl serde::Serialize) -> Result<(), WallError> {
    let text = serde_yaml::to_string(value).map_err(|source| WallError::Yaml {
        path: path.into(),
        source,
    })?;
    write(path, text)
}
