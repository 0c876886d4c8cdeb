//! One layer end to end, what `waam layer plan` runs: the layer file read and its heat model
//! built ([`LayerInput`]), the trail searched within the command's deadline, its files, its
//! motion and its recording ([`plan_layer`]), the result as JSON ([`LayerPlan::json`]), and
//! a written layer directory read back for plotting ([`read_layer_dir`]). Printing and
//! publishing stay with the caller.

use std::path::Path;
use std::time::Instant;

use serde_json::json;
use waam_layer::output::TrailFile;
use waam_layer::{plan_layer_motion, search, Layer, Model, SearchOptions, SearchResult, Trail};
use waam_messages::convert::PlanMessages;
use waam_messages::layer::LayerRecording;
use waam_motion::robot::Robot;
use waam_motion::toolpath::{MotionSummary, ProcessSettings};
use waam_motion::write_outputs;
use waam_rosbag::Recorder;

use crate::{finish_recording, layer_messages, write, write_trail, LayerMotion, WallError};

/// A layer file read, with its heat model built: what `waam layer plan` checks before it
/// loads a robot or starts a recording.
pub struct LayerInput {
    /// The document as received (recordings hold it).
    pub text: String,
    pub model: Model,
}

impl LayerInput {
    /// Reads the layer file at `path` and builds its heat model.
    pub fn read(path: &Path) -> Result<LayerInput, WallError> {
        let (text, layer) = read_layer(path)?;
        let model = build_model(&layer)?;
        Ok(LayerInput { text, model })
    }
}

/// The layer file at `path` and its text.
pub fn read_layer(path: &Path) -> Result<(String, Layer), WallError> {
    let bytes = std::fs::read(path).map_err(|source| WallError::ReadLayer {
        path: path.into(),
        source,
    })?;
    let layer = Layer::from_bytes(&bytes).map_err(|source| WallError::Layer {
        path: path.into(),
        source,
    })?;
    // from_bytes accepts only UTF-8.
    Ok((String::from_utf8_lossy(&bytes).into_owned(), layer))
}

/// The layer's heat model; an error names the layer.
pub fn build_model(layer: &Layer) -> Result<Model, WallError> {
    Model::new(layer).map_err(|source| WallError::Model {
        layer: layer.name.clone(),
        source,
    })
}

/// Where and how one layer is planned.
pub struct LayerRun<'a> {
    /// Writes `trail.yaml`, a copy of the layer as `layer.yaml` and, with a motion,
    /// `toolpath.yaml` and `trajectory.yaml` (created if missing).
    pub out: Option<&'a Path>,
    /// The search settings; its `time_limit` and `give_up` are replaced by what is left of
    /// `deadline` when the search starts.
    pub options: SearchOptions,
    /// The command's deadline: reading the layer and loading the robot count against it,
    /// and it acts before the first trail too (a large layer answers "no trail").
    pub deadline: Option<Instant>,
    /// The cell the layer is welded in; without one, no motion.
    pub cell: Option<(&'a ProcessSettings, &'a Robot)>,
    /// Records the layer document before the search and its outcome after it.
    pub recorder: Option<&'a Recorder>,
}

/// What one layer's run produced.
#[derive(Debug)]
pub struct LayerPlan {
    pub result: SearchResult,
    /// The validated motion or why the robot cannot weld the trail; none without a cell or
    /// without a trail.
    pub motion: Option<LayerMotion>,
    /// The validated motion's messages (the robot's base link), for recording and publishing.
    pub messages: Option<PlanMessages>,
    /// The heat frames recorded, with a recorder and a trail.
    pub heat_frames: Option<usize>,
}

impl LayerPlan {
    /// The run's figures and its trail as `waam layer plan --json` prints them; `motion` is
    /// the motion's [`MotionSummary`], `{error: …}`, or null without a robot.
    pub fn json(&self, model: &Model) -> serde_json::Value {
        let r = &self.result;
        let id = |v: usize| model.layer.nodes[v].id.clone();
        let moves: Vec<_> = r
            .trail
            .moves
            .iter()
            .map(|m| {
                let (a, b) = model.ends(m);
                json!({"segment": m.segment, "from": id(a), "to": id(b), "reversed": m.reversed,
                       "deadhead_before": m.deadhead_before})
            })
            .collect();
        json!({
            "layer": model.layer.name,
            "objective": r.objective,
            "lower_bound": r.lower_bound,
            "proven_optimal": r.proven_optimal,
            "gap": r.gap,
            "relative_gap": r.relative_gap,
            "nodes_explored": r.nodes_explored,
            "leaves": r.leaves,
            "seconds": r.seconds,
            "symmetries": r.symmetries,
            "deadheads": model.deadheads,
            "mesh_nodes": model.mesh.points.len(),
            "time_steps": model.horizon,
            "trail": moves,
            "motion": match &self.motion {
                None => serde_json::Value::Null,
                Some(Ok((tp, _))) => json!(MotionSummary::of(tp)),
                Some(Err(e)) => json!({ "error": e.to_string() }),
            },
        })
    }

    /// The robot could not weld the trail (NO MOTION).
    pub fn motion_failed(&self) -> bool {
        matches!(self.motion, Some(Err(_)))
    }
}

/// Plans one layer: refuses it when its search would need more than
/// `options.max_memory_mb`, records its document, searches its trail within the deadline
/// and, when there is one, writes its files, plans and validates its motion (only a
/// validated motion is written, recorded or returned as messages) and records the outcome.
/// Without a trail nothing is written and the recording is left unfinished; a layer the
/// robot cannot weld is [`LayerPlan::motion`], not an error.
pub fn plan_layer(input: &LayerInput, run: &LayerRun) -> Result<LayerPlan, WallError> {
    let model = &input.model;
    let layer = &model.layer;
    waam_layer::search::check_size(model, &run.options)?;
    if let Some(v) = run.cell.and_then(|(settings, _)| settings.weld_speed_mm_s) {
        if v != layer.process.weld_speed_mm_s {
            tracing::warn!(
                "process settings weld_speed_mm_s = {v} is not used: the layer is welded at its \
                 own weld speed, {} mm/s, as its heat model assumed",
                layer.process.weld_speed_mm_s
            );
        }
    }
    let recording = run
        .recorder
        .map(|r| LayerRecording::start(r, &input.text, &layer.name))
        .transpose()
        .map_err(|source| WallError::Record {
            layer: layer.name.clone(),
            source,
        })?;
    tracing::info!(
        "layer {}: {} segments, {} mesh nodes, {} time steps, {} deadheading moves",
        layer.name,
        layer.segments.len(),
        model.mesh.points.len(),
        model.horizon,
        model.deadheads
    );
    let left = run
        .deadline
        .map(|d| d.saturating_duration_since(Instant::now()));
    let options = SearchOptions {
        time_limit: left,
        give_up: left,
        ..run.options.clone()
    };
    let result = search(model, &options);
    if !result.found() {
        return Ok(LayerPlan {
            result,
            motion: None,
            messages: None,
            heat_frames: None,
        });
    }
    if let Some(dir) = run.out {
        crate::create_dir(dir)?;
        write_trail(dir, model, &result)?;
        write(&dir.join("layer.yaml"), &input.text)?;
    }
    let motion: Option<LayerMotion> = run
        .cell
        .map(|(settings, robot)| plan_layer_motion(model, &result.trail, settings, robot));
    if let (Some(Ok((tp, traj))), Some(dir)) = (&motion, run.out) {
        write_outputs(dir, tp, traj).map_err(|source| WallError::WriteMotion {
            dir: dir.into(),
            source,
        })?;
    }
    let messages = layer_messages(model, &result, motion.as_ref(), run.cell.map(|c| c.0))?;
    let heat_frames = recording
        .map(|rec| finish_recording(rec, model, &result, motion.as_ref(), messages.as_ref()))
        .transpose()?;
    Ok(LayerPlan {
        result,
        motion,
        messages,
        heat_frames,
    })
}

/// A layer directory as `waam layer plan --out DIR` (or one layer of `plan-part`) wrote
/// it: the layer's model from `DIR/layer.yaml` and the trail of `DIR/trail.yaml`.
pub fn read_layer_dir(dir: &Path) -> Result<(Model, Trail), WallError> {
    let (_, layer) = read_layer(&dir.join("layer.yaml"))?;
    let model = build_model(&layer)?;
    let path = dir.join("trail.yaml");
    let text = std::fs::read_to_string(&path).map_err(|source| WallError::Read {
        path: path.clone(),
        source,
    })?;
    let file: TrailFile = serde_yaml::from_str(&text).map_err(|source| WallError::Parse {
        path: path.clone(),
        source,
    })?;
    let trail = file
        .trail(&model)
        .map_err(|source| WallError::Trail { path, source })?;
    Ok((model, trail))
}
