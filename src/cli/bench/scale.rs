//! `waam bench scale DIR`: the planner on parts shaped like real work, each part file (or
//! STL mesh) in a folder: time to the first feasible plan and to the best, proven or not.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{bail, Context};
use serde::Serialize;
use waam_part::graph::WeldGraph;
use waam_part::Part;
use waam_pipeline::{Objective, Progress};
use waam_planner::{Backend, Options, Report};
use waam_thermal::ThermalModel;

use crate::cli::plan::LazyBar;
use crate::cli::voxelize::{parse_pitch, MeshArgs};
use crate::cli::{EXIT_INTERRUPTED, EXIT_OK};

/// Planner on every part in a folder: blocks, k, windows, time to the first feasible plan,
/// time to the best plan, proven or not, as a table (and as JSON with --json FILE).
#[derive(Debug, clap::Args)]
#[command(mut_arg("k", |k| k.help(
    "k of the meshes: the most weld paths (arc starts) a plan may use [default: 1]; a part \
     file keeps its own max_fragments"
)))]
pub struct ScaleArgs {
    /// A folder of part files (.yaml) and STL meshes (.stl), e.g. ../shared/parts/scale.
    #[arg(required_unless_present = "generate")]
    pub dir: Option<PathBuf>,
    /// Stop each run (first plan, then best plan) after this many seconds.
    #[arg(long, default_value_t = 60.0, value_name = "SECONDS")]
    pub timeout: f64,
    /// Also search for the best plan (fewest weld paths, then largest t8/5 margin) with
    /// the same timeout; by default only the first feasible plan is timed. Not with
    /// --generate: write the parts with --out, then time that folder with --best.
    #[arg(long, conflicts_with = "generate")]
    pub best: bool,
    /// The pitch of one mesh: "NAME.stl=X Y Z" (repeatable); others take --pitch.
    #[arg(long = "mesh-pitch", value_name = "NAME=X Y Z", value_parser = parse_mesh_pitch)]
    pub mesh_pitch: Vec<(String, [f64; 3])>,
    /// Slice one mesh into beads (a graph part): "NAME.stl=W H" (bead width and layer
    /// height, mm) or "NAME.stl=W H K" with its k (repeatable); others take --pitch or
    /// --bead and -k.
    #[arg(long = "mesh-bead", value_name = "NAME=W H [K]", value_parser = parse_mesh_bead)]
    pub mesh_bead: Vec<(String, [f64; 2], Option<u32>)>,
    /// Only the parts whose file name contains this.
    #[arg(long)]
    pub only: Option<String>,
    /// The SAT solver.
    #[arg(long, value_parser = crate::cli::solver_parser(), default_value = Backend::default().name())]
    pub solver: Backend,
    /// Search from scratch, without the layer-by-layer warm start.
    #[arg(long)]
    pub no_warm_start: bool,
    /// Planner threads: the race's racers, the portfolio's variants and the most a
    /// simulation steps on, 1 to 1024 [default: all cores].
    #[arg(long, value_name = "N", value_parser = crate::cli::thread_count)]
    pub threads: Option<usize>,
    /// Write the rows as a JSON array to FILE as well.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
    #[command(flatten, next_help_heading = "Meshes (every .stl in DIR)")]
    pub mesh: MeshArgs,
    #[command(flatten, next_help_heading = "Generated parts (--generate)")]
    pub generated: super::generate::GenerateArgs,
}

impl ScaleArgs {
    /// The planner's threads, all cores unless --threads says.
    pub(super) fn threads(&self) -> usize {
        self.threads
            .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()))
    }
}

fn parse_mesh_pitch(s: &str) -> Result<(String, [f64; 3]), String> {
    let (name, pitch) = s
        .split_once('=')
        .ok_or_else(|| format!("expected NAME.stl=\"X Y Z\", got {s:?}"))?;
    Ok((name.trim().to_string(), parse_pitch(pitch)?))
}

fn parse_mesh_bead(s: &str) -> Result<(String, [f64; 2], Option<u32>), String> {
    let (name, rest) = s
        .split_once('=')
        .ok_or_else(|| format!("expected NAME.stl=\"W H [K]\", got {s:?}"))?;
    let words: Vec<&str> = rest.split_whitespace().collect();
    let (bead, k) = match words.as_slice() {
        [w, h] => (format!("{w} {h}"), None),
        [w, h, k] => {
            let k = k
                .parse::<u32>()
                .ok()
                .filter(|&k| k >= 1)
                .ok_or_else(|| format!("{name}: K must be an integer >= 1, got {k:?}"))?;
            (format!("{w} {h}"), Some(k))
        }
        _ => return Err(format!("expected NAME.stl=\"W H [K]\", got {s:?}")),
    };
    let bead = crate::cli::slice::parse_bead(&bead).map_err(|e| format!("{name}: {e}"))?;
    Ok((name.trim().to_string(), bead, k))
}

/// One part's row.
#[derive(Debug, Serialize)]
struct Row {
    part: String,
    file: String,
    blocks: usize,
    layers: i64,
    k: usize,
    windows: usize,
    first: Run,
    best: Option<Run>,
}

/// One planner run on a part.
#[derive(Debug, Serialize)]
pub(super) struct Run {
    /// The threads the planner was given (a chosen solver or --no-warm-start runs one
    /// configuration, its simulations on that many).
    threads: usize,
    /// The racer whose plan came first (None: no race, or no plan).
    racer: Option<String>,
    /// Seconds to the first feasible plan (None: none found).
    pub(super) first_feasible_s: Option<f64>,
    pub(super) total_s: f64,
    found: bool,
    proven: bool,
    fragments: Option<usize>,
    /// Worst-case t8/5 margin of the plan (None: no windows, or no plan).
    margin_s: Option<f64>,
    /// The plan passed the independent check (valid, and feasible in a fresh simulation).
    pub(super) checked: Option<bool>,
    candidates: u64,
    learned_clauses: u64,
    clause_len_mean: Option<f64>,
    sat_s: f64,
    simulator_s: f64,
    /// Seconds the warm start took (0: none).
    warm_start_s: f64,
}

pub fn run(args: ScaleArgs) -> anyhow::Result<ExitCode> {
    let dir = match (&args.dir, args.generated.generate) {
        (_, Some(n)) => return super::generate::run(&args, n),
        (Some(dir), None) => dir,
        (None, None) => bail!("expected a folder DIR or --generate N"),
    };
    let mut paths: Vec<PathBuf> = std::fs::read_dir(dir)
        .with_context(|| format!("cannot read folder {}", dir.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.extension()
                .is_some_and(|e| e.eq_ignore_ascii_case("yaml") || e.eq_ignore_ascii_case("stl"))
        })
        // The plans `--generate --out` writes beside its parts are not parts.
        .filter(|p| !file_name(p).ends_with(".witness.yaml"))
        .filter(|p| {
            args.only.as_ref().is_none_or(|o| {
                p.file_name()
                    .is_some_and(|n| n.to_string_lossy().contains(o.as_str()))
            })
        })
        .collect();
    paths.sort();
    if paths.is_empty() {
        bail!("{}: no part files (.yaml) or meshes (.stl)", dir.display());
    }
    let timeout =
        Duration::try_from_secs_f64(args.timeout).context("--timeout: expected seconds >= 0")?;
    let stop = crate::cli::node::stop_on_signal()?;
    println!(
        "{:<22} {:>7} {:>3} {:>4} {:>10} {:>6} {:>9} {:>10} {:>9} {:>7}",
        "part",
        "blocks",
        "k",
        "win",
        "first (s)",
        "cands",
        "paths",
        "best (s)",
        "proven",
        "checked"
    );
    let mut rows = Vec::new();
    for path in &paths {
        let part = match read(path, &args) {
            Ok(part) => part,
            Err(e) => {
                println!("{:<22} skipped: {e:#}", file_name(path));
                continue;
            }
        };
        let opts = Options {
            timeout: Some(timeout),
            cancel: Some(Arc::clone(&stop)),
            solver: args.solver,
            warm_start: !args.no_warm_start,
            threads: args.threads(),
            ..Options::default()
        };
        let first = timed(&part, &opts, false, &stop)?;
        let best = if args.best && !stop.load(Ordering::Relaxed) {
            Some(timed(&part, &opts, true, &stop)?)
        } else {
            None
        };
        let row = Row {
            part: part.name.clone(),
            file: file_name(path),
            blocks: part.len(),
            layers: part.layers(),
            k: part.max_fragments,
            windows: part.windows().len(),
            first,
            best,
        };
        print_row(&row);
        rows.push(row);
        if stop.load(Ordering::Relaxed) {
            println!("stopped (Ctrl-C)");
            break;
        }
    }
    // The rows so far, also after a stop.
    if let Some(file) = &args.json {
        std::fs::write(file, serde_json::to_string_pretty(&rows)?)
            .with_context(|| format!("cannot write {}", file.display()))?;
    }
    Ok(ExitCode::from(if stop.load(Ordering::Relaxed) {
        EXIT_INTERRUPTED
    } else {
        EXIT_OK
    }))
}

fn file_name(path: &Path) -> String {
    path.file_name()
        .map_or_else(String::new, |n| n.to_string_lossy().into_owned())
}

/// A part file as it is, or a mesh voxelized at its own pitch or sliced into its own
/// beads (else by --pitch or --bead).
fn read(path: &Path, args: &ScaleArgs) -> anyhow::Result<Part> {
    let name = file_name(path);
    let mut mesh = args.mesh.clone();
    let is_stl = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("stl"));
    if !is_stl {
        // -k is the meshes' k here: a part file keeps its own.
        mesh.k = None;
    }
    if let Some((_, pitch)) = args.mesh_pitch.iter().find(|(n, _)| *n == name) {
        (mesh.pitch, mesh.bead) = (Some(*pitch), None);
    }
    if let Some((_, bead, k)) = args.mesh_bead.iter().find(|(n, _, _)| *n == name) {
        (mesh.pitch, mesh.bead) = (None, Some(*bead));
        mesh.k = k.or(mesh.k);
    }
    mesh.read_part_or_mesh(path)
}

/// One planner run (first plan, or best with `optimize`), its plan checked independently.
pub(super) fn timed(
    part: &Part,
    opts: &Options,
    optimize: bool,
    stop: &Arc<AtomicBool>,
) -> anyhow::Result<Run> {
    let mut bar = LazyBar::new(false);
    let mut warm_start_s = 0.0;
    let started = Instant::now();
    let mut progress = |progress: Progress| {
        let Progress::Planner(event) = progress else {
            return;
        };
        if warm_start_s == 0.0 && event.stats().candidates == 1 {
            warm_start_s = started.elapsed().as_secs_f64();
        }
        bar.update(event.stats());
    };
    let options = waam_pipeline::Options {
        planner: opts.clone(),
        objective: if optimize {
            Objective::Best
        } else {
            Objective::First
        },
        ..waam_pipeline::Options::default()
    };
    let report: Report = waam_pipeline::plan(part, None, &options, &mut progress)?.report;
    bar.finish();
    let s = &report.stats;
    let checked = match &report.best {
        Some(best) => check(part, &best.fragments, stop)?,
        None => None,
    };
    Ok(Run {
        threads: opts.threads,
        racer: s.first_plan_racer.clone(),
        first_feasible_s: s.first_feasible_s,
        total_s: s.total_s,
        found: report.best.is_some(),
        proven: report.proven,
        fragments: report.best.as_ref().map(|b| b.fragments.len()),
        margin_s: report
            .best
            .as_ref()
            .map(|b| b.margin)
            .filter(|m| m.is_finite()),
        checked,
        candidates: s.candidates,
        learned_clauses: s.learned_clauses,
        clause_len_mean: s.clause_len_mean,
        sat_s: s.sat_s,
        simulator_s: s.simulator_s,
        warm_start_s: if opts.warm_start { warm_start_s } else { 0.0 },
    })
}

/// What `waam check` asks of a plan: valid by the part's rules, and no window broken in a
/// simulation of its own; `None` when `stop` ends the simulation first (at 10^5 blocks it
/// takes a minute).
fn check(
    part: &Part,
    fragments: &[Vec<usize>],
    stop: &Arc<AtomicBool>,
) -> anyhow::Result<Option<bool>> {
    let graph = WeldGraph::new(part);
    if waam_part::plan::Plan::from_indices(part, fragments)
        .validate(part, &graph)
        .is_err()
    {
        return Ok(Some(false));
    }
    let model = ThermalModel::new(part, &graph);
    if !model.has_windows() {
        return Ok(Some(true));
    }
    let outcome = waam_thermal::simulate_until(&model, fragments, None, Some(Arc::clone(stop)))?;
    Ok(outcome.map(|o| o.violation.is_none()))
}

fn print_row(row: &Row) {
    // A time, "no plan" (proven: there is none), or "> T" (none found before the timeout).
    let secs = |r: &Run| match (r.first_feasible_s, r.proven) {
        (Some(t), _) => format!("{t:.2}"),
        (None, true) => "no plan".to_string(),
        (None, false) => format!("> {:.0}", r.total_s),
    };
    let (best_s, proven) = match &row.best {
        Some(b) => (
            if b.found {
                format!("{:.2}", b.total_s)
            } else {
                "-".into()
            },
            if b.proven { "yes" } else { "no" }.to_string(),
        ),
        None => ("-".into(), "-".into()),
    };
    let run = row.best.as_ref().unwrap_or(&row.first);
    println!(
        "{:<22} {:>7} {:>3} {:>4} {:>10} {:>6} {:>9} {:>10} {:>9} {:>7}",
        row.file,
        row.blocks,
        row.k,
        row.windows,
        secs(&row.first),
        row.first.candidates,
        run.fragments.map_or("-".into(), |f| f.to_string()),
        best_s,
        proven,
        match run.checked {
            Some(true) => "ok",
            Some(false) => "FAILED",
            None => "-",
        }
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The independent check of a plan stops when asked (Ctrl-C during a long check).
    #[test]
    fn the_check_stops_when_asked() {
        let blocks = (0..4)
            .flat_map(|z| (0..8).map(move |x| [x, 0, z]))
            .collect();
        let mut part =
            Part::from_blocks("wall".into(), [6.0, 6.0, 2.5], [0.0; 3], 1, blocks).unwrap();
        let top = part.index_of([3, 0, 3]).unwrap();
        part.set_window(
            top,
            waam_part::Window {
                min_s: 0.0,
                max_s: 1e6,
            },
        );
        // One weld path, each layer the other way round.
        let plan = vec![(0..4)
            .flat_map(|z| {
                let row: Vec<i64> = if z % 2 == 0 {
                    (0..8).collect()
                } else {
                    (0..8).rev().collect()
                };
                row.into_iter().map(move |x| [x, 0, z])
            })
            .map(|b| part.index_of(b).unwrap())
            .collect()];
        let go = Arc::new(AtomicBool::new(false));
        assert_eq!(check(&part, &plan, &go).unwrap(), Some(true));
        let stopped = Arc::new(AtomicBool::new(true));
        assert_eq!(check(&part, &plan, &stopped).unwrap(), None);
    }
}
