//! `waam bench`: throughput of the thermal model and of the planner (benchmarks, not tests).

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use anyhow::Context;
use indicatif::{ProgressBar, ProgressStyle};
use serde_json::json;
use waam_part::graph::WeldGraph;
use waam_part::Part;
use waam_planner::{self as planner, Options};
use waam_thermal::{Simulation, ThermalModel};

use super::{read_part, EXIT_OK};

mod generate;
mod scale;

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
    /// ring, simulated from the first block to the last; or, with --part, one full-build
    /// check (every deposit, then the cooldown) of any part.
    Thermal {
        /// Repeat the run this many times and report the best [default: 3, 1 with --part].
        #[arg(long)]
        repeat: Option<usize>,
        /// Threads of the multi-threaded run [default: the available cores]; the
        /// 1-thread figure is printed beside it.
        #[arg(long, value_parser = crate::cli::thread_count)]
        threads: Option<usize>,
        /// Step kernel: scalar, avx2 or avx512 [default: the best the CPU runs].
        #[arg(long, value_parser = ["scalar", "avx2", "avx512"])]
        kernel: Option<String>,
        /// Check this part instead (a part file, or an STL mesh with --pitch). Without
        /// --plan the deposit order is constructive, for timing only: layer by layer, rows
        /// in y order walked boustrophedon along x, one fragment per layer (not
        /// necessarily a valid plan of the part's k).
        #[arg(long)]
        part: Option<PathBuf>,
        #[command(flatten, next_help_heading = "Mesh input (--part is an .stl file)")]
        mesh: super::voxelize::MeshArgs,
        /// Deposit order of the --part check: a plan file (YAML or JSON), validated.
        #[arg(long, requires = "part")]
        plan: Option<PathBuf>,
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
    /// Planner on parts shaped like real work (plates, solids, tubes, meshes): time to the
    /// first feasible plan (and with --best to the best), each part file or STL in DIR.
    Scale(scale::ScaleArgs),
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
        BenchWhat::Thermal {
            repeat,
            threads,
            kernel,
            part: Some(path),
            mesh,
            plan,
        } => bench_part(
            &path,
            &mesh,
            plan.as_deref(),
            threads,
            kernel.as_deref(),
            repeat.unwrap_or(1),
        ),
        BenchWhat::Thermal {
            repeat,
            threads,
            kernel,
            ..
        } => bench_thermal(repeat.unwrap_or(3), threads, kernel.as_deref()),
        BenchWhat::Planner {
            dir,
            all_up_to,
            json,
        } => bench_planner(&dir, all_up_to, json),
        BenchWhat::Scale(args) => scale::run(args),
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

/// The model stepped by the named kernel (the scalar one if the CPU lacks it).
fn with_kernel(model: ThermalModel, kernel: Option<&str>) -> ThermalModel {
    use waam_thermal::Simd;
    match kernel {
        Some("scalar") => model.with_simd(Simd::Scalar),
        Some("avx2") => model.with_simd(Simd::Avx2),
        Some("avx512") => model.with_simd(Simd::Avx512),
        _ => model,
    }
}

fn bench_thermal(
    repeat: usize,
    threads: Option<usize>,
    kernel: Option<&str>,
) -> anyhow::Result<ExitCode> {
    let (side, layers) = (26, 100);
    let part = hollow_tower(side, layers);
    let graph = WeldGraph::new(&part);
    let model = with_kernel(ThermalModel::new(&part, &graph), kernel);
    let order: Vec<usize> = (0..layers)
        .flat_map(|z| ring_order(&part, side, z))
        .collect();
    let threads = threads.unwrap_or_else(waam_thermal::default_threads).max(1);
    let mut counts = vec![1];
    if threads > 1 {
        counts.push(threads);
    }
    for threads in counts {
        let mut best = f64::INFINITY;
        let mut block_steps = 0u64;
        for _ in 0..repeat.max(1) {
            let mut sim = Simulation::new(&model).with_threads(threads);
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
            "thermal: {} blocks, {} steps, {:.3e} block-steps in {:.3} s: {:.3e} block-steps/s on {} thread{} ({:?} kernel, best of {})",
            part.len(),
            order.len() as u64 * model.params.substeps as u64,
            block_steps as f64,
            best,
            block_steps as f64 / best,
            threads,
            if threads == 1 { "" } else { "s" },
            model.simd(),
            repeat.max(1)
        );
    }
    Ok(ExitCode::from(EXIT_OK))
}

/// Layer by layer, rows in y order walked boustrophedon along x, one fragment per layer.
pub fn constructive_order(part: &Part) -> Vec<Vec<usize>> {
    let blocks = part.blocks();
    let mut layers: Vec<Vec<usize>> = Vec::new();
    let mut row_start = 0;
    let mut rows = 0usize;
    for i in 1..=blocks.len() {
        let row_ends = i == blocks.len() || blocks[i][1..] != blocks[row_start][1..];
        if !row_ends {
            continue;
        }
        if row_start == 0 || blocks[row_start][2] != blocks[row_start - 1][2] {
            layers.push(Vec::new());
            rows = 0;
        }
        let layer = layers.last_mut().expect("just pushed");
        if rows % 2 == 0 {
            layer.extend(row_start..i);
        } else {
            layer.extend((row_start..i).rev());
        }
        rows += 1;
        row_start = i;
    }
    layers
}

/// The largest resident set of this process so far, bytes.
fn peak_rss_bytes() -> Option<u64> {
    #[cfg(unix)]
    {
        // SAFETY: getrusage writes the struct we pass; all-zero is a valid rusage.
        let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
        if unsafe { libc::getrusage(libc::RUSAGE_SELF, &mut usage) } == 0 {
            // Linux reports KiB (macOS bytes; this is a Linux tool).
            return Some(usage.ru_maxrss as u64 * 1024);
        }
    }
    None
}

/// One full-build check of a part: every deposit in order, then the cooldown.
fn bench_part(
    path: &std::path::Path,
    mesh: &super::voxelize::MeshArgs,
    plan: Option<&std::path::Path>,
    threads: Option<usize>,
    kernel: Option<&str>,
    repeat: usize,
) -> anyhow::Result<ExitCode> {
    let part = mesh.read_part_or_mesh(path)?;
    let graph = WeldGraph::new(&part);
    let fragments = match plan {
        Some(plan) => {
            let bytes = std::fs::read(plan)
                .with_context(|| format!("cannot read plan {}", plan.display()))?;
            let is_json = plan.extension().is_some_and(|e| e == "json");
            waam_part::plan::Plan::from_bytes(&bytes, is_json)
                .with_context(|| format!("in plan {}", plan.display()))?
                .validate(&part, &graph)
                .map_err(|e| anyhow::anyhow!("plan {}: {e}", plan.display()))?
        }
        None => constructive_order(&part),
    };
    let model = with_kernel(ThermalModel::new(&part, &graph), kernel);
    let threads = threads.unwrap_or_else(waam_thermal::default_threads).max(1);
    let stop = super::node::stop_on_signal()?;
    let n = part.len();
    let steps_estimate = model.params.substeps as f64 * (n as f64) * (n as f64 + 1.0) / 2.0;
    println!(
        "{}: {} blocks, {} layers, {} fragments, {} ({}); about {:.2e} block-steps",
        part.name,
        n,
        part.layers(),
        fragments.len(),
        if plan.is_some() {
            "plan"
        } else {
            "constructive order"
        },
        if threads == 1 {
            "1 thread".to_string()
        } else {
            format!("{threads} threads")
        },
        steps_estimate
    );
    for _ in 0..repeat.max(1) {
        let bar = ProgressBar::new(n as u64);
        bar.set_style(
            ProgressStyle::with_template(
                "[{elapsed_precise}] {bar:40} {pos}/{len} blocks, eta {eta} {msg}",
            )
            .expect("a valid template"),
        );
        let mut sim = Simulation::new(&model)
            .with_threads(threads)
            .with_cancel(stop.clone());
        let t = Instant::now();
        let mut block_steps = 0u64;
        let mut verdict = "feasible".to_string();
        'plan: for fragment in &fragments {
            for (p, &b) in fragment.iter().enumerate() {
                let before = sim.steps();
                let welded = sim.welded() as u64;
                let r = sim.deposit(b, p == 0);
                // Transit steps (before the deposit) step the blocks welded before it.
                let deposit_steps = (sim.steps() - before).min(model.params.substeps as u64);
                block_steps += (sim.steps() - before - deposit_steps) * welded
                    + deposit_steps * sim.welded() as u64;
                if let Err(v) = r {
                    verdict = format!("violation: {v:?}");
                    break 'plan;
                }
                if sim.cancelled() {
                    break 'plan;
                }
                bar.inc(1);
            }
        }
        if verdict == "feasible" && !sim.cancelled() {
            let before = sim.steps();
            match sim.finish() {
                Ok(Ok(())) => {}
                Ok(Err(v)) => verdict = format!("violation while cooling: {v:?}"),
                Err(e) => verdict = format!("not cooled: {e}"),
            }
            block_steps += (sim.steps() - before) * sim.welded() as u64;
        }
        bar.finish_and_clear();
        let secs = t.elapsed().as_secs_f64();
        if sim.cancelled() {
            println!(
                "cancelled after {} of {} blocks, {:.3} s",
                sim.welded(),
                n,
                secs
            );
            return Ok(ExitCode::from(130));
        }
        println!(
            "thermal check: {} blocks, {} steps, {:.3e} block-steps in {:.3} s: {:.3e} block-steps/s on {} thread{} ({:?} kernel), peak memory {:.1} MiB; {}",
            n,
            sim.steps(),
            block_steps as f64,
            secs,
            block_steps as f64 / secs,
            threads,
            if threads == 1 { "" } else { "s" },
            model.simd(),
            peak_rss_bytes().map_or(f64::NAN, |b| b as f64 / (1 << 20) as f64),
            verdict
        );
    }
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
            "{:<16} {:>6} {:>3} {:>11} {:>6} {:>11} {:>9} {:>8} {:>8} {:>8} {:>8} {:>6}",
            "part",
            "blocks",
            "k",
            "first (s)",
            "cands",
            "all (s)",
            "feasible",
            "cands",
            "inside",
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
        // "inside": clauses learned inside the search from a prefix that broke a window
        // (their simulations count as SAT time, they run inside the solver).
        let (all_s, feas, cands, inside, sat, sim, clause) = match &all {
            Some(a) => {
                let s = &a.stats;
                (
                    format!("{:.4}", s.total_s),
                    a.feasible.to_string(),
                    s.candidates.to_string(),
                    s.inside_clauses.to_string(),
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
                "-".into(),
            ),
        };
        println!(
            "{:<16} {:>6} {:>3} {:>11.4} {:>6} {:>11} {:>9} {:>8} {:>8} {:>8} {:>8} {:>6}",
            part.name,
            part.len(),
            part.max_fragments,
            first_s,
            first.stats.candidates,
            all_s,
            feas,
            cands,
            inside,
            sat,
            sim,
            clause
        );
    }
    Ok(ExitCode::from(EXIT_OK))
}
