//! executed.yaml: every deposit as it happened, the plans used, the estimates and the layer
//! heights (docs/closed-loop.md), and the check of an execution on a thermal model.

use serde::{Deserialize, Serialize};

use waam_part::graph::WeldGraph;
use waam_part::{Block, Part, ThermalParams};
use waam_thermal::{simulate_on, Outcome, SimulateError, ThermalModel, Timeline};

/// One deposit as the cell made it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Deposit {
    pub block: Block,
    /// When the arc reached the block and how long it stayed, s from the first deposit.
    pub start_s: f64,
    pub duration_s: f64,
    /// The height the deposit came out, mm.
    pub height_mm: f64,
    /// It began a weld path (an arc start).
    pub arc_start: bool,
    /// Wire feed relative to nominal (the height controller's output; 1 in open loop).
    pub wire_feed: f64,
}

/// A plan the cell used from `at_deposit` deposits on.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PlanUsed {
    pub at_deposit: usize,
    pub at_s: f64,
    /// initial, replan, fault (a path cut short) or kept (no feasible completion found).
    pub reason: String,
    /// Wall-clock time the planner took, s.
    pub latency_s: f64,
    /// The weld paths still to come, blocks in weld order (the first may continue the
    /// path in progress: `continues`).
    pub continues: bool,
    pub remainder: Vec<Vec<Block>>,
}

/// One run of the estimator.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EstimateRecord {
    pub at_deposit: usize,
    pub at_s: f64,
    pub loss_factor: f64,
    pub conduction_factor: f64,
    pub rmse_before_c: f64,
    pub rmse_after_c: f64,
    pub latency_s: f64,
}

/// One layer's measured height (its median top over the layers below), the mean wire feed
/// its deposits got, and the lowest and highest top of its deposits above the origin (mm;
/// the spread a single height hides).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LayerRecord {
    pub z: i64,
    pub nominal_mm: f64,
    pub height_mm: f64,
    pub wire_feed: f64,
    pub tops_mm: [f64; 2],
}

/// The whole execution.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Executed {
    pub part: String,
    /// "closed" or "open".
    #[serde(rename = "loop")]
    pub loop_mode: String,
    pub deposits: Vec<Deposit>,
    pub plans: Vec<PlanUsed>,
    pub estimates: Vec<EstimateRecord>,
    pub layers: Vec<LayerRecord>,
    /// The top of the layers finished (the whole part when complete), measured and
    /// nominal, mm.
    pub top_mm: f64,
    pub nominal_top_mm: f64,
    /// False when the run was stopped before every block was deposited.
    pub complete: bool,
}

/// Why an execution cannot be re-simulated.
#[derive(Debug, thiserror::Error)]
pub enum CheckError {
    #[error("executed.yaml: deposit {0}: block {1:?} is not in the part")]
    UnknownBlock(usize, Block),
    #[error("executed.yaml: no deposits")]
    Empty,
    #[error(transparent)]
    Simulate(#[from] SimulateError),
}

impl Executed {
    /// executed.yaml: the record with one deposit a line, `{block: [x, y, z], start_s, …}`
    /// (serde_yaml reads it back; floats are written so that they read back exactly).
    pub fn to_yaml(&self) -> Result<String, serde_yaml::Error> {
        let head = Executed {
            deposits: Vec::new(),
            ..self.clone()
        };
        let mut text = serde_yaml::to_string(&head)?;
        text = text.replace("deposits: []\n", "");
        text.push_str("deposits:\n");
        for d in &self.deposits {
            let [x, y, z] = d.block;
            text.push_str(&format!(
                "- {{block: [{x}, {y}, {z}], start_s: {:?}, duration_s: {:?}, height_mm: {:?}, arc_start: {}, wire_feed: {:?}}}\n",
                d.start_s, d.duration_s, d.height_mm, d.arc_start, d.wire_feed
            ));
        }
        Ok(text)
    }

    /// The deposits as fragments of block indices of `part`.
    pub fn fragments(&self, part: &Part) -> Result<Vec<Vec<usize>>, CheckError> {
        let mut out: Vec<Vec<usize>> = Vec::new();
        for (p, d) in self.deposits.iter().enumerate() {
            let i = part
                .index_of(d.block)
                .ok_or(CheckError::UnknownBlock(p + 1, d.block))?;
            match out.last_mut() {
                Some(f) if !d.arc_start => f.push(i),
                _ => out.push(vec![i]),
            }
        }
        Ok(out)
    }

    /// Re-simulates the execution under `params` (the part's windows) on its own time
    /// line: each block deposited at its `start_s`, each weld path's arc off at the end of
    /// its last deposit. The verdict the true cell's blocks got.
    pub fn check(&self, part: &Part, params: ThermalParams) -> Result<Outcome, CheckError> {
        let fragments = self.fragments(part)?;
        if fragments.is_empty() {
            return Err(CheckError::Empty);
        }
        let mut starts: Vec<Vec<f64>> = Vec::new();
        let mut off = Vec::new();
        for d in &self.deposits {
            if d.arc_start || starts.is_empty() {
                starts.push(Vec::new());
                off.push(0.0);
            }
            starts.last_mut().expect("pushed").push(d.start_s);
            *off.last_mut().expect("pushed") = d.start_s + d.duration_s;
        }
        let mut p = part.clone();
        p.thermal = params;
        let model = ThermalModel::new(&p, &WeldGraph::new(&p));
        let timeline = Timeline::from_seconds(&starts, &off, model.dt)
            .map_err(|e| CheckError::Simulate(e.into()))?;
        Ok(simulate_on(&model, &fragments, &timeline)?)
    }
}
