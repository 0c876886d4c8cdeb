//! `waam layer …`: thick-wall layers welded as one trail under a finite-element heat model.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Duration;

use anyhow::Context;
use clap::{Args, Subcommand};
use serde_json::json;
use waam::layer::output::TrailFile;
use waam::layer::plot::{plot_temperature, plot_trail};
use waam::layer::{search, Layer, Model, SearchOptions, SearchResult};

use super::{EXIT_NO, EXIT_OK};

/// Plan, draw and benchmark weld trails for layers of walls (see docs/layer-format.md).
#[derive(Debug, Args)]
pub struct LayerArgs {
    #[command(subcommand)]
    pub command: LayerCommand,
}

#[derive(Debug, Subcommand)]
pub enum LayerCommand {
    Plan(PlanArgs),
    Plot(PlotArgs),
    Bench(BenchArgs),
}

/// Find the weld trail (segment order, directions, the fewest deadheading moves) that keeps
/// the layer's temperature field closest to its target, and prove it optimal.
///
/// Exit code 0: proven optimal; 1: time limit reached (best trail and its gap reported);
/// 2: bad input.
#[derive(Debug, Args)]
pub struct PlanArgs {
    /// The layer file (YAML, docs/layer-format.md).
    pub layer: PathBuf,
    /// Write DIR/trail.yaml (moves, deadheading, torch position per step) and a copy of
    /// the layer as DIR/layer.yaml, for `waam layer plot DIR`.
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
    /// Stop after this many seconds and return the best trail with its proven gap.
    #[arg(long, value_name = "S")]
    pub time_limit: Option<f64>,
    /// Do not prune symmetric trails (slower; for checking).
    #[arg(long)]
    pub no_symmetry: bool,
}

/// Draw a planned layer: DIR/trail.png (trail over the walls: weld order numbers, dashed
/// deadheading, start marked) and DIR/temperature.png (one node's temperature over time).
#[derive(Debug, Args)]
pub struct PlotArgs {
    /// A directory written by `waam layer plan --out DIR`.
    pub dir: PathBuf,
    /// The node whose temperature is drawn: a mesh node index, or a layer node id (its
    /// nearest mesh node). Default: the layer's first node.
    #[arg(long, value_name = "N")]
    pub node: Option<String>,
}

/// Benchmark the search on layer files: time to proven optimum, or the gap at the limit.
#[derive(Debug, Args)]
pub struct BenchArgs {
    /// Layer files (default: the bundled config/layers/*.yaml).
    pub layers: Vec<PathBuf>,
    /// Time limit per layer in seconds.
    #[arg(long, value_name = "S", default_value_t = 600.0)]
    pub time_limit: f64,
}

pub fn run(args: LayerArgs) -> anyhow::Result<ExitCode> {
    match args.command {
        LayerCommand::Plan(a) => plan(a),
        LayerCommand::Plot(a) => plot(a),
        LayerCommand::Bench(a) => bench(a),
    }
}

fn read_layer(path: &Path) -> anyhow::Result<Layer> {
    let bytes =
        std::fs::read(path).with_context(|| format!("cannot read layer {}", path.display()))?;
    Layer::from_bytes(&bytes).with_context(|| format!("in layer {}", path.display()))
}

fn build_model(layer: &Layer) -> anyhow::Result<Model> {
    Model::new(layer).map_err(|e| anyhow::anyhow!("layer {}: {e}", layer.name))
}

fn time_limit(seconds: Option<f64>) -> anyhow::Result<Option<Duration>> {
    seconds
        .map(|s| {
            Duration::try_from_secs_f64(s)
                .map_err(|_| anyhow::anyhow!("--time-limit: {s} is not a number of seconds >= 0"))
        })
        .transpose()
}

fn result_json(model: &Model, r: &SearchResult) -> serde_json::Value {
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
    })
}

fn plan(args: PlanArgs) -> anyhow::Result<ExitCode> {
    let layer = read_layer(&args.layer)?;
    let model = build_model(&layer)?;
    let options = SearchOptions {
        time_limit: time_limit(args.time_limit)?,
        symmetry: !args.no_symmetry,
        ..SearchOptions::default()
    };
    tracing::info!(
        "layer {}: {} segments, {} mesh nodes, {} time steps, {} deadheading moves",
        layer.name,
        layer.segments.len(),
        model.mesh.points.len(),
        model.horizon,
        model.deadheads
    );
    let r = search(&model, &options);
    if let Some(dir) = &args.out {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
        let file = TrailFile::new(
            &model,
            &r.trail,
            r.objective,
            r.lower_bound,
            r.proven_optimal,
        );
        let yaml = serde_yaml::to_string(&file)?;
        std::fs::write(dir.join("trail.yaml"), yaml)
            .with_context(|| format!("cannot write {}", dir.join("trail.yaml").display()))?;
        std::fs::copy(&args.layer, dir.join("layer.yaml"))
            .with_context(|| format!("cannot write {}", dir.join("layer.yaml").display()))?;
    }
    if args.json {
        println!("{}", result_json(&model, &r));
    } else {
        println!(
            "{}: objective {:.6e} K·steps, {} (lower bound {:.6e}, gap {:.3}%)",
            layer.name,
            r.objective,
            if r.proven_optimal {
                "PROVEN OPTIMAL"
            } else {
                "NOT PROVEN (time limit)"
            },
            r.lower_bound,
            100.0 * r.relative_gap
        );
        println!(
            "{} search nodes, {} complete trails, {:.3} s, {} symmetries",
            r.nodes_explored, r.leaves, r.seconds, r.symmetries
        );
        for (k, m) in r.trail.moves.iter().enumerate() {
            let (a, b) = model.ends(m);
            println!(
                "{:>3}. {}{} -> {}",
                k + 1,
                if m.deadhead_before { "(deadhead) " } else { "" },
                layer.nodes[a].id,
                layer.nodes[b].id
            );
        }
    }
    Ok(ExitCode::from(if r.proven_optimal {
        EXIT_OK
    } else {
        EXIT_NO
    }))
}

fn plot(args: PlotArgs) -> anyhow::Result<ExitCode> {
    let layer = read_layer(&args.dir.join("layer.yaml"))?;
    let model = build_model(&layer)?;
    let path = args.dir.join("trail.yaml");
    let text = std::fs::read_to_string(&path)
        .with_context(|| format!("cannot read {}", path.display()))?;
    let file: TrailFile =
        serde_yaml::from_str(&text).with_context(|| format!("in {}", path.display()))?;
    let trail = file
        .trail(&model)
        .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
    let node = match args.node.as_deref() {
        None => model.mesh.nearest(layer.point(0)),
        Some(s) => match s.parse::<usize>() {
            Ok(i) => i,
            Err(_) => {
                let v = layer
                    .nodes
                    .iter()
                    .position(|n| n.id == s)
                    .with_context(|| {
                        format!("--node {s}: neither a mesh node index nor a node id of the layer")
                    })?;
                model.mesh.nearest(layer.point(v))
            }
        },
    };
    let trail_png = args.dir.join("trail.png");
    let temp_png = args.dir.join("temperature.png");
    plot_trail(&model, &trail, &trail_png, (900, 900))?;
    plot_temperature(&model, &trail, node, &temp_png, (1000, 600))?;
    println!("wrote {} and {}", trail_png.display(), temp_png.display());
    Ok(ExitCode::from(EXIT_OK))
}

fn bench(args: BenchArgs) -> anyhow::Result<ExitCode> {
    let layers = if args.layers.is_empty() {
        let mut v: Vec<PathBuf> = std::fs::read_dir("config/layers")
            .context(
                "cannot list config/layers (run from the repository root or name layer files)",
            )?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|e| e == "yaml"))
            .collect();
        v.sort();
        v
    } else {
        args.layers
    };
    let limit = time_limit(Some(args.time_limit))?;
    println!("layer | segments | mesh nodes | steps | deadheads | objective | proven | gap % | nodes | seconds");
    for path in layers {
        let layer = read_layer(&path)?;
        let model = build_model(&layer)?;
        let r = search(
            &model,
            &SearchOptions {
                time_limit: limit,
                ..SearchOptions::default()
            },
        );
        println!(
            "{} | {} | {} | {} | {} | {:.6e} | {} | {:.3} | {} | {:.2}",
            layer.name,
            layer.segments.len(),
            model.mesh.points.len(),
            model.horizon,
            model.deadheads,
            r.objective,
            r.proven_optimal,
            100.0 * r.relative_gap,
            r.nodes_explored,
            r.seconds
        );
    }
    Ok(ExitCode::from(EXIT_OK))
}
