//! `waam bench`: throughput of the thermal model and of the planner (benchmarks, not tests).

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use serde_json::json;
use waam_part::graph::WeldGraph;
use waam_part::Part;
use waam_planner::{self as planner, Options};
use waam_thermal::{Simulation, ThermalModel};

use super::{read_part, EXIT_OK};

/// Measure the simulator (block-steps per second on a ~10,000-block part) and the planner
/// (time to the first feasible plan and to all feasible plans of every part in a folder).
#[derive(Debug, clap::Args)]
pub struct BenchArgs {
    #[command(subcommand)]
    pub what: BenchWhat,
}

#[derive(Debug, clap::Subcommand)]
pub enum BenchWhat {
    /// Simulator throughput: a hollow square tower of about 10,000 blocks, welded ring by
    /// ring, simulated from the first block to the last.
    Thermal {
        /// Repeat the run this many times and report the best.
        #[arg(long, default_value_t = 3)]
        repeat: usize,
    },
    /// Planner on three generated parts of about 10,000 blocks (a thin wall, a ring tower
    /// and a closed hollow box): time to the first feasible plan.
    Large {
        /// Stop each part after this many seconds (checked between SAT calls).
        #[arg(long, default_value_t = 120.0)]
        timeout: f64,
        /// Only the parts whose name contains this.
        #[arg(long)]
        only: Option<String>,
        /// How cycles are excluded.
        #[arg(long, value_parser = super::acyclicity_parser(), default_value = "lazy")]
        acyclicity: waam_planner::Acyclicity,
    },
    /// Planner: first feasible plan and all feasible plans of each part file in DIR.
    Planner {
        /// A folder of part files (e.g. ../shared/parts).
        dir: PathBuf,
        /// Skip enumerating all feasible plans of parts with more blocks than this.
        #[arg(long, default_value_t = 200)]
        all_up_to: usize,
        /// Print JSON lines instead of a table.
        #[arg(long)]
        json: bool,
    },
}

pub fn run(args: BenchArgs) -> anyhow::Result<ExitCode> {
    match args.what {
        BenchWhat::Thermal { repeat } => bench_thermal(repeat),
        BenchWhat::Planner {
            dir,
            all_up_to,
            json,
        } => bench_planner(&dir, all_up_to, json),
        BenchWhat::Large {
            timeout,
            only,
            acyclicity,
        } => bench_large(timeout, only.as_deref(), acyclicity),
    }
}

/// A hollow square tower: `side` blocks along each outer edge, `layers` high.
pub fn hollow_tower(side: i64, layers: i64) -> Part {
    let mut blocks = Vec::new();
    for z in 0..layers {
        for y in 0..side {
            for x in 0..side {
                if x == 0 || y == 0 || x == side - 1 || y == side - 1 {
                    blocks.push([x, y, z]);
                }
            }
        }
    }
    Part::from_blocks("hollow-tower".into(), [6.0, 6.0, 2.5], [0.0; 3], 1, blocks)
        .expect("a generated part is valid")
}

/// The three large benchmark parts, each about 10,000 blocks, with a few t8/5 windows.
pub fn large_parts() -> Vec<Part> {
    let wall: Vec<[i64; 3]> = (0..100)
        .flat_map(|z| (0..100).map(move |x| [x, 0, z]))
        .collect();
    let tower = hollow_tower(26, 100);
    // A closed box: full floor, walls, and a full lid over the hollow (overhanging blocks).
    let (side, height) = (30i64, 15i64);
    let mut closed = Vec::new();
    for z in 0..height {
        for y in 0..side {
            for x in 0..side {
                let wall = x == 0 || y == 0 || x == side - 1 || y == side - 1;
                if wall || z == 0 || z == height - 1 {
                    closed.push([x, y, z]);
                }
            }
        }
    }
    let make = |name: &str, k: usize, blocks: Vec<[i64; 3]>| {
        Part::from_blocks(name.into(), [6.0, 6.0, 2.5], [0.0; 3], k, blocks).expect("valid part")
    };
    let mut parts = vec![
        make("wall-100x100", 1, wall),
        make("ring-tower-26x26x100", 1, tower.blocks().to_vec()),
        make("hollow-box-30x30x15", 2, closed),
    ];
    for part in &mut parts {
        // Generous windows on a few blocks of the top layer, so the thermal loop runs.
        let top = part.layers() - 1;
        let picks: Vec<usize> = (0..part.len())
            .filter(|&i| part.block(i)[2] == top)
            .step_by(17)
            .take(4)
            .collect();
        for i in picks {
            part.set_window(
                i,
                waam_part::Window {
                    min_s: 0.5,
                    max_s: 120.0,
                },
            );
        }
    }
    parts
}

fn bench_large(
    timeout: f64,
    only: Option<&str>,
    acyclicity: waam_planner::Acyclicity,
) -> anyhow::Result<ExitCode> {
    for part in large_parts() {
        if only.is_some_and(|o| !part.name.contains(o)) {
            continue;
        }
        let opts = Options {
            acyclicity,
            timeout: Some(std::time::Duration::from_secs_f64(timeout)),
            ..Options::default()
        };
        let t = Instant::now();
        let report = planner::first(&part, &opts, &mut |_| {})?;
        let s = &report.stats;
        println!(
            "{:<22} {:>6} blocks k={} first feasible: {} in {:.2} s ({} candidates, {} cycle cuts, SAT {:.2} s, sim {:.2} s, {} vars, {} clauses)",
            part.name,
            part.len(),
            part.max_fragments,
            if report.best.is_some() { "found" } else if report.proven { "none exists" } else { "not found (timeout)" },
            t.elapsed().as_secs_f64(),
            s.candidates,
            s.cycle_cuts,
            s.sat_s,
            s.simulator_s,
            s.variables,
            s.clauses
        );
    }
    Ok(ExitCode::from(EXIT_OK))
}

/// The ring of a hollow tower's layer in walking order.
fn ring_order(part: &Part, side: i64, z: i64) -> Vec<usize> {
    let mut cells = Vec::new();
    cells.extend((0..side).map(|x| [x, 0, z]));
    cells.extend((1..side).map(|y| [side - 1, y, z]));
    cells.extend((0..side - 1).rev().map(|x| [x, side - 1, z]));
    cells.extend((1..side - 1).rev().map(|y| [0, y, z]));
    cells
        .iter()
        .map(|&b| part.index_of(b).expect("ring block"))
        .collect()
}

fn bench_thermal(repeat: usize) -> anyhow::Result<ExitCode> {
    let (side, layers) = (26, 100);
    let part = hollow_tower(side, layers);
    let graph = WeldGraph::new(&part);
    let model = ThermalModel::new(&part, &graph);
    let order: Vec<usize> = (0..layers)
        .flat_map(|z| ring_order(&part, side, z))
        .collect();
    let mut best = f64::INFINITY;
    let mut block_steps = 0u64;
    for _ in 0..repeat.max(1) {
        let mut sim = Simulation::new(&model);
        let t = Instant::now();
        block_steps = 0;
        for (p, &b) in order.iter().enumerate() {
            let before = sim.steps();
            sim.deposit(b, p == 0)
                .map_err(|v| anyhow::anyhow!("unexpected violation {v:?}"))?;
            block_steps += (sim.steps() - before) * sim.welded() as u64;
        }
        best = best.min(t.elapsed().as_secs_f64());
    }
    println!(
        "thermal: {} blocks, {} steps, {:.3e} block-steps in {:.3} s: {:.3e} block-steps/s (best of {})",
        part.len(),
        order.len() as u64 * model.params.substeps as u64,
        block_steps as f64,
        best,
        block_steps as f64 / best,
        repeat.max(1)
    );
    Ok(ExitCode::from(EXIT_OK))
}

fn bench_planner(dir: &std::path::Path, all_up_to: usize, json: bool) -> anyhow::Result<ExitCode> {
    let mut paths: Vec<PathBuf> = std::fs::read_dir(dir)?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "yaml"))
        .collect();
    paths.sort();
    if !json {
        println!(
            "{:<16} {:>6} {:>3} {:>11} {:>6} {:>11} {:>9} {:>8} {:>8} {:>8} {:>6}",
            "part",
            "blocks",
            "k",
            "first (s)",
            "cands",
            "all (s)",
            "feasible",
            "cands",
            "SAT %",
            "sim %",
            "clause"
        );
    }
    for path in paths {
        let part = read_part(&path)?;
        let opts = Options::default();
        let t = Instant::now();
        let first = planner::first(&part, &opts, &mut |_| {})?;
        let first_s = t.elapsed().as_secs_f64();
        let all = (part.len() <= all_up_to)
            .then(|| planner::enumerate(&part, &opts, &mut |_| {}, &mut |_| Ok(())))
            .transpose()?;
        if json {
            println!(
                "{}",
                json!({"part": part.name, "blocks": part.len(), "first_s": first_s,
                       "first_found": first.best.is_some(), "first_stats": first.stats,
                       "all": all.as_ref().map(|a| json!({"feasible": a.feasible, "stats": a.stats}))})
            );
            continue;
        }
        let (all_s, feas, cands, sat, sim, clause) = match &all {
            Some(a) => {
                let s = &a.stats;
                (
                    format!("{:.4}", s.total_s),
                    a.feasible.to_string(),
                    s.candidates.to_string(),
                    format!("{:.0}", 100.0 * s.sat_s / s.total_s.max(1e-12)),
                    format!("{:.0}", 100.0 * s.simulator_s / s.total_s.max(1e-12)),
                    s.clause_len_mean.map_or("-".into(), |m| format!("{m:.1}")),
                )
            }
            None => (
                "-".into(),
                "-".into(),
                "-".into(),
                "-".into(),
                "-".into(),
                "-".into(),
            ),
        };
        println!(
            "{:<16} {:>6} {:>3} {:>11.4} {:>6} {:>11} {:>9} {:>8} {:>8} {:>8} {:>6}",
            part.name,
            part.len(),
            part.max_fragments,
            first_s,
            first.stats.candidates,
            all_s,
            feas,
            cands,
            sat,
            sim,
            clause
        );
    }
    Ok(ExitCode::from(EXIT_OK))
}
