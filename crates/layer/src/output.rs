//! `trail.yaml`: the planned trail — segment order with directions, deadheading moves and
//! the torch position of every time step — written by `waam layer plan --out DIR` and
//! read back by `waam layer plot DIR`.

use serde::{Deserialize, Serialize};

use super::model::{Model, Move, StepKind, Trail};

/// One welded segment in order.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MoveRecord {
    pub segment: usize,
    pub from: String,
    pub to: String,
    pub reversed: bool,
    pub deadhead_before: bool,
}

/// One deadheading move (arc off).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DeadheadRecord {
    /// Index of the move it leads to.
    pub before_move: usize,
    pub from: String,
    pub to: String,
    pub steps: usize,
}

/// The torch in one time step.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StepRecord {
    pub step: usize,
    pub time_s: f64,
    /// Torch position (mm), null while deadheading or cooling after the trail.
    pub torch: Option<[f64; 2]>,
    pub arc_on: bool,
    /// Index of the move welded (or deadheaded to); null while cooling.
    #[serde(rename = "move")]
    pub move_index: Option<usize>,
}

/// The whole `trail.yaml` document.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TrailFile {
    pub layer: String,
    pub objective: f64,
    pub lower_bound: f64,
    pub proven_optimal: bool,
    pub deadheads: usize,
    pub time_step_s: f64,
    pub moves: Vec<MoveRecord>,
    pub deadheading: Vec<DeadheadRecord>,
    pub steps: Vec<StepRecord>,
}

impl TrailFile {
    pub fn new(
        model: &Model,
        trail: &Trail,
        objective: f64,
        lower_bound: f64,
        proven: bool,
    ) -> TrailFile {
        let id = |v: usize| model.layer.nodes[v].id.clone();
        let mut moves = Vec::new();
        let mut deadheading = Vec::new();
        let mut at = None;
        for (i, m) in trail.moves.iter().enumerate() {
            let (a, b) = model.ends(m);
            if let (true, Some(prev)) = (m.deadhead_before, at) {
                deadheading.push(DeadheadRecord {
                    before_move: i,
                    from: id(prev),
                    to: id(a),
                    steps: model.layer.transit_steps(prev, a),
                });
            }
            moves.push(MoveRecord {
                segment: m.segment,
                from: id(a),
                to: id(b),
                reversed: m.reversed,
                deadhead_before: m.deadhead_before && at.is_some(),
            });
            at = Some(b);
        }
        let dt = model.layer.process.time_step_s;
        let steps = model
            .schedule(trail)
            .into_iter()
            .enumerate()
            .map(|(n, kind)| {
                let (torch, arc_on, move_index) = match kind {
                    StepKind::Weld {
                        position,
                        move_index,
                    } => (Some(model.positions[position]), true, Some(move_index)),
                    StepKind::Transit { move_index } => (None, false, Some(move_index)),
                    StepKind::Cool => (None, false, None),
                };
                StepRecord {
                    step: n + 1,
                    time_s: (n + 1) as f64 * dt,
                    torch,
                    arc_on,
                    move_index,
                }
            })
            .collect();
        TrailFile {
            layer: model.layer.name.clone(),
            objective,
            lower_bound,
            proven_optimal: proven,
            deadheads: model.deadheads,
            time_step_s: dt,
            moves,
            deadheading,
            steps,
        }
    }

    /// The trail again, checked against the model's layer.
    pub fn trail(&self, model: &Model) -> Result<Trail, crate::ModelError> {
        let mut moves = Vec::new();
        for (i, m) in self.moves.iter().enumerate() {
            if m.segment >= model.layer.segments.len() {
                return Err(crate::ModelError(format!(
                    "moves[{i}]: segment {} is not in the layer",
                    m.segment
                )));
            }
            let mv = Move {
                segment: m.segment,
                reversed: m.reversed,
                deadhead_before: m.deadhead_before,
            };
            let (a, b) = model.ends(&mv);
            if model.layer.nodes[a].id != m.from || model.layer.nodes[b].id != m.to {
                return Err(crate::ModelError(format!(
                    "moves[{i}]: segment {} does not run from {} to {} in the layer",
                    m.segment, m.from, m.to
                )));
            }
            moves.push(mv);
        }
        let trail = Trail { moves };
        model.check_trail(&trail)?;
        Ok(trail)
    }
}
