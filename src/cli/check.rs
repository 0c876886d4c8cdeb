//! `waam check PART PLAN`: is a plan valid for a part, and does it keep every t8/5 window?

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use serde_json::json;
use waam_access::{Obstacle, TorchAccess, TorchSetup};
use waam_motion::toolpath::ProcessSettings;
use waam_part::graph::WeldGraph;
use waam_part::plan::Plan;
use waam_part::BlockDisplay;
use waam_thermal::{self as thermal, Interrupt, ThermalModel};

use super::{EXIT_NO, EXIT_OK};

/// Check a plan against a part: validity rules first, then the thermal t8/5 windows, and
/// with --torch or --process the torch's access.
///
/// Prints VALID or INVALID with the first broken rule, then FEASIBLE or INFEASIBLE with
/// the first violated window, then every t8/5 crossing of every windowed block; with a
/// torch, TORCH OK or TORCH BLOCKED with the first block the torch cannot reach.
/// Exit code 0: valid, feasible (and reachable); 1: invalid, infeasible, blocked, or not
/// decided within --timeout; 2: bad input.
///
/// A graph part (`kind: beads`, as `waam slice` writes) takes a plan of node ids and is
/// checked the same way with the graph thermal model, the torch on its beads.
#[derive(Debug, clap::Args)]
pub struct CheckArgs {
    /// The part file (YAML, shared part format, or a graph part), or an STL mesh with --pitch.
    pub part: PathBuf,
    #[command(flatten, next_help_heading = "Mesh input (PART is an .stl file)")]
    pub mesh: super::voxelize::MeshArgs,
    /// The plan file (YAML, or JSON when it ends in .json or starts with `{`).
    pub plan: PathBuf,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
    /// Also check torch access at every deposit, with the bundled process settings' torch
    /// (a typical GMAW torch) or --process's.
    #[arg(long)]
    pub torch: bool,
    /// Process settings (YAML, see config/process.yaml) whose torch and angles to check
    /// access with (implies --torch unless the file says `torch: null`).
    #[arg(long, value_name = "FILE")]
    pub process: Option<PathBuf>,
    /// Give up after this many seconds (reading the part counts against it): a part of
    /// many blocks, or a long transit or cooldown, takes minutes to simulate. Prints
    /// TIMEOUT (feasibility not decided), exit 1. Ctrl-C stops it at once.
    #[arg(long, value_name = "SECONDS")]
    pub timeout: Option<f64>,
}

pub fn run(args: CheckArgs) -> anyhow::Result<ExitCode> {
    let is_stl = args
        .part
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("stl"));
    if !is_stl {
        let bytes = std::fs::read(&args.part)
            .with_context(|| format!("cannot read part {}", args.part.display()))?;
        if std::str::from_utf8(&bytes).is_ok_and(waam_part::is_bead_part) {
            return check_graph(&args, &bytes);
        }
    }
    let timeout = super::timeout_arg(args.timeout)?;
    let interrupt = Interrupt::after(timeout);
    let (mesh, path) = (args.mesh.clone(), args.part.clone());
    let what = format!("reading {}", path.display());
    let part = super::within(timeout, &what, move || mesh.read_part_or_mesh(&path))?;
    let torch = torch(&args)?;
    let bytes = std::fs::read(&args.plan)
        .with_context(|| format!("cannot read plan {}", args.plan.display()))?;
    let is_json = args.plan.extension().is_some_and(|e| e == "json");
    let plan = Plan::from_bytes(&bytes, is_json)
        .with_context(|| format!("in plan {}", args.plan.display()))?;
    if let Some(name) = plan.part.as_deref().filter(|n| *n != part.name) {
        tracing::warn!("plan names part {name:?}, the part file is {:?}", part.name);
    }
    let graph = WeldGraph::new(&part);
    let fragments = match plan.validate(&part, &graph) {
        Ok(fragments) => fragments,
        Err(invalid) => {
            if args.json {
                let out = json!({
                    "valid": false,
                    "feasible": false,
                    "invalid": {"rule": invalid.rule(), "block": invalid.block(), "message": invalid.to_string()},
                    "violation": null,
                    "crossings": [],
                });
                println!("{out}");
            } else {
                println!("INVALID: {invalid}");
                println!("INFEASIBLE (the plan is not valid)");
            }
            return Ok(ExitCode::from(EXIT_NO));
        }
    };
    let model = ThermalModel::new(&part, &graph);
    let outcome = thermal::simulate_until(&model, &fragments, interrupt.deadline, None)
        .with_context(|| format!("simulating plan {}", args.plan.display()))?;
    let Some(outcome) = outcome else {
        let limit = timeout.unwrap_or_default().as_secs_f64();
        if args.json {
            println!(
                "{}",
                json!({"valid": true, "feasible": null, "timeout_s": limit})
            );
        } else {
            println!(
                "VALID: {} fragment(s), {} blocks",
                fragments.len(),
                part.len()
            );
            println!("TIMEOUT: the simulation did not end within --timeout {limit} s (feasibility not decided)");
        }
        return Ok(ExitCode::from(EXIT_NO));
    };
    let feasible = outcome.violation.is_none();
    let blocked = torch
        .map(|t| TorchAccess::new(&part, &t).first_blocked(fragments.iter().flatten().copied()));
    let obstacle = |o: Obstacle| match o {
        Obstacle::Plate => json!("plate"),
        Obstacle::Block(i) => json!(part.block(i)),
    };
    if args.json {
        let violation = outcome.violation.as_ref().map(|v| {
            json!({
                "block": part.block(v.block),
                "kind": v.kind,
                "window": {"min_s": v.window.min_s, "max_s": v.window.max_s},
                "t85_s": v.t85_s,
                "time_s": v.time_s,
                "step": v.step,
                "prefix_len": v.prefix_len,
                "prefix_fragments": v.prefix_fragments,
                "phase": v.phase,
            })
        });
        let crossings: Vec<_> = outcome
            .crossings
            .iter()
            .map(|c| json!({"block": part.block(c.block), "t85_s": c.t85_s, "time_s": c.time_s}))
            .collect();
        let out = json!({
            "valid": true,
            "feasible": feasible,
            "fragments": fragments.len(),
            "blocks": part.len(),
            "violation": violation,
            "crossings": crossings,
            "steps": outcome.steps,
            "time_s": outcome.time_s,
            "torch": blocked.map(|b| json!({
                "reachable": b.is_none(),
                "blocked": b.map(|x| json!({
                    "block": part.block(x.block),
                    "deposit": x.position + 1,
                    "obstacle": obstacle(x.obstacle),
                })),
            })),
        });
        println!("{out}");
    } else {
        println!(
            "VALID: {} fragment(s), {} blocks",
            fragments.len(),
            part.len()
        );
        println!("{}", if feasible { "FEASIBLE" } else { "INFEASIBLE" });
        if let Some(v) = &outcome.violation {
            let closed = if v.phase == thermal::Phase::Deposit {
                ""
            } else {
                ", last fragment closed"
            };
            println!(
                "first violation: block {} window [{}, {}] s, {:?}: t8/5 = {:.2} s at t = {:.2} s \
                 (step {}, {:?}); prefix {} blocks in {} fragment(s){closed}",
                BlockDisplay(part.block(v.block)),
                v.window.min_s,
                v.window.max_s,
                v.kind,
                v.t85_s,
                v.time_s,
                v.step,
                v.phase,
                v.prefix_len,
                v.prefix_fragments,
            );
        }
        println!(
            "simulated {} steps ({:.2} s)",
            outcome.steps, outcome.time_s
        );
        println!("t8/5 crossings (s) per windowed block:");
        for &(i, w) in part.windows() {
            let values: Vec<String> = outcome
                .crossings
                .iter()
                .filter(|c| c.block == i)
                .map(|c| format!("{:.2}", c.t85_s))
                .collect();
            let values = if values.is_empty() {
                "-".to_string()
            } else {
                values.join(" ")
            };
            println!(
                "  {} [{}, {}]: {values}",
                BlockDisplay(part.block(i)),
                w.min_s,
                w.max_s
            );
        }
        match (&blocked, &torch) {
            (Some(None), Some(t)) => println!("TORCH OK: every block reachable ({})", t.describe()),
            (Some(Some(x)), Some(t)) => println!(
                "TORCH BLOCKED: the torch cannot reach block {} (deposit {} of {}): {} stands \
                 in its way ({})",
                BlockDisplay(part.block(x.block)),
                x.position + 1,
                part.len(),
                match x.obstacle {
                    Obstacle::Plate => "the plate".to_string(),
                    Obstacle::Block(i) => format!(
                        "block {}, deposited before it,",
                        BlockDisplay(part.block(i))
                    ),
                },
                t.describe()
            ),
            _ => {}
        }
    }
    let reachable = !matches!(blocked, Some(Some(_)));
    Ok(ExitCode::from(if feasible && reachable {
        EXIT_OK
    } else {
        EXIT_NO
    }))
}

/// The torch whose access is checked: --process's, with --torch the bundled one, else none.
fn torch(args: &CheckArgs) -> anyhow::Result<Option<TorchSetup>> {
    Ok(match &args.process {
        Some(path) => {
            let text = std::fs::read_to_string(path)
                .with_context(|| format!("cannot read process settings {}", path.display()))?;
            ProcessSettings::from_yaml(&text)
                .with_context(|| format!("in process settings {}", path.display()))?
                .torch_setup()
        }
        None if args.torch => ProcessSettings::default().torch_setup(),
        None => None,
    })
}

/// `waam check` of a graph part (`kind: beads`) and a plan of node ids: the validity rules,
/// then the graph thermal model's t8/5 check (docs/graph-thermal-model.md), reported as for
/// a cube part with nodes for blocks.
fn check_graph(args: &CheckArgs, bytes: &[u8]) -> anyhow::Result<ExitCode> {
    use waam_part::{BeadPart, GraphPlan, Part};
    let torch = torch(args)?;
    let timeout = super::timeout_arg(args.timeout)?;
    let interrupt = Interrupt::after(timeout);
    let mut beads = BeadPart::from_bytes(bytes)
        .with_context(|| format!("in graph part {}", args.part.display()))?;
    if let Some(k) = args.mesh.k {
        beads.max_fragments = k as usize;
    }
    for warning in &beads.warnings {
        tracing::warn!("{}: {warning}", args.part.display());
    }
    let plan_bytes = std::fs::read(&args.plan)
        .with_context(|| format!("cannot read plan {}", args.plan.display()))?;
    let is_json = args.plan.extension().is_some_and(|e| e == "json");
    let plan = GraphPlan::from_bytes(&plan_bytes, is_json)
        .with_context(|| format!("in plan {}", args.plan.display()))?;
    if let Some(name) = plan.part.as_deref().filter(|n| *n != beads.name) {
        tracing::warn!(
            "plan names part {name:?}, the part file is {:?}",
            beads.name
        );
    }
    if let Err(invalid) = plan.validate(&beads, &beads.moves()) {
        if args.json {
            println!(
                "{}",
                json!({
                    "valid": false,
                    "feasible": false,
                    "invalid": {"rule": invalid.rule(), "message": invalid.to_string()},
                    "violation": null,
                    "crossings": [],
                })
            );
        } else {
            println!("INVALID: {invalid}");
            println!("INFEASIBLE (the plan is not valid)");
        }
        return Ok(ExitCode::from(EXIT_NO));
    }
    let nodes = beads.len();
    let part =
        Part::of_beads(beads).with_context(|| format!("in graph part {}", args.part.display()))?;
    let model = ThermalModel::try_new(&part, &WeldGraph::new(&part))
        .with_context(|| format!("thermal model of graph part {}", args.part.display()))?;
    let fragments = &plan.fragments;
    let outcome = thermal::simulate_until(&model, fragments, interrupt.deadline, None)
        .with_context(|| format!("simulating plan {}", args.plan.display()))?;
    let Some(outcome) = outcome else {
        let limit = timeout.unwrap_or_default().as_secs_f64();
        if args.json {
            println!(
                "{}",
                json!({"valid": true, "feasible": null, "timeout_s": limit})
            );
        } else {
            println!("VALID: {} fragment(s), {nodes} nodes", fragments.len());
            println!("TIMEOUT: the simulation did not end within --timeout {limit} s (feasibility not decided)");
        }
        return Ok(ExitCode::from(EXIT_NO));
    };
    let feasible = outcome.violation.is_none();
    // Torch access on the beads (`TorchAccess::of_beads`).
    let blocked = torch
        .map(|t| TorchAccess::new(&part, &t).first_blocked(fragments.iter().flatten().copied()));
    let obstacle = |o: Obstacle| match o {
        Obstacle::Plate => "the plate".to_string(),
        Obstacle::Block(i) => format!("node {i}, deposited before it,"),
    };
    if args.json {
        let violation = outcome.violation.as_ref().map(|v| {
            json!({
                "node": v.block,
                "kind": v.kind,
                "window": {"min_s": v.window.min_s, "max_s": v.window.max_s},
                "t85_s": v.t85_s,
                "time_s": v.time_s,
                "step": v.step,
                "prefix_len": v.prefix_len,
                "prefix_fragments": v.prefix_fragments,
                "phase": v.phase,
            })
        });
        let crossings: Vec<_> = outcome
            .crossings
            .iter()
            .map(|c| json!({"node": c.block, "t85_s": c.t85_s, "time_s": c.time_s}))
            .collect();
        let out = json!({
            "valid": true,
            "feasible": feasible,
            "fragments": fragments.len(),
            "nodes": nodes,
            "violation": violation,
            "crossings": crossings,
            "steps": outcome.steps,
            "time_s": outcome.time_s,
            "torch": blocked.map(|b| json!({
                "reachable": b.is_none(),
                "blocked": b.map(|x| json!({
                    "node": x.block,
                    "deposit": x.position + 1,
                    "obstacle": match x.obstacle {
                        Obstacle::Plate => json!("plate"),
                        Obstacle::Block(i) => json!(i),
                    },
                })),
            })),
        });
        println!("{out}");
    } else {
        println!("VALID: {} fragment(s), {nodes} nodes", fragments.len());
        println!("{}", if feasible { "FEASIBLE" } else { "INFEASIBLE" });
        if let Some(v) = &outcome.violation {
            let closed = if v.phase == thermal::Phase::Deposit {
                ""
            } else {
                ", last fragment closed"
            };
            println!(
                "first violation: node {} window [{}, {}] s, {:?}: t8/5 = {:.2} s at t = {:.2} s \
                 (step {}, {:?}); prefix {} nodes in {} fragment(s){closed}",
                v.block,
                v.window.min_s,
                v.window.max_s,
                v.kind,
                v.t85_s,
                v.time_s,
                v.step,
                v.phase,
                v.prefix_len,
                v.prefix_fragments,
            );
        }
        println!(
            "simulated {} steps ({:.2} s)",
            outcome.steps, outcome.time_s
        );
        println!("t8/5 crossings (s) per windowed node:");
        for &(i, w) in part.windows() {
            let values: Vec<String> = outcome
                .crossings
                .iter()
                .filter(|c| c.block == i)
                .map(|c| format!("{:.2}", c.t85_s))
                .collect();
            let values = if values.is_empty() {
                "-".to_string()
            } else {
                values.join(" ")
            };
            println!("  node {i} [{}, {}]: {values}", w.min_s, w.max_s);
        }
        match (&blocked, &torch) {
            (Some(None), Some(t)) => println!("TORCH OK: every node reachable ({})", t.describe()),
            (Some(Some(x)), Some(t)) => println!(
                "TORCH BLOCKED: the torch cannot reach node {} (deposit {} of {nodes}): {} stands \
                 in its way ({})",
                x.block,
                x.position + 1,
                obstacle(x.obstacle),
                t.describe()
            ),
            _ => {}
        }
    }
    let reachable = !matches!(blocked, Some(Some(_)));
    Ok(ExitCode::from(if feasible && reachable {
        EXIT_OK
    } else {
        EXIT_NO
    }))
}
