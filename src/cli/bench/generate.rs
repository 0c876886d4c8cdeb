//! `waam bench scale --generate N`: benchmark families generated from seeds
//! (`waam_bench`), each part planned for its first feasible plan; per family and size the
//! solve rate and the median and worst time to that plan.

use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::Duration;

use anyhow::Context;
use waam_bench::{generate, summarize, Family, Sample, Spec};
use waam_planner::Options;
use waam_thermal::Interrupt;

use super::scale::{timed, ScaleArgs};
use crate::cli::{EXIT_INTERRUPTED, EXIT_OK};

/// Generated benchmark parts (used with --generate).
#[derive(Debug, Clone, clap::Args)]
pub struct GenerateArgs {
    /// Generate N parts per family and size (seeds S, S+1, ... S+N-1) and time the first
    /// feasible plan of each, instead of reading a folder.
    #[arg(long, value_name = "N")]
    pub generate: Option<u64>,
    /// The first seed of --generate.
    #[arg(long, default_value_t = 1, value_name = "S")]
    pub seed: u64,
    /// Only this family (repeatable): tube, box, double-tube, l-wall, t-wall, cup
    /// [default: all].
    #[arg(long = "family", value_name = "F", value_parser = parse_family)]
    pub families: Vec<Family>,
    /// About this many blocks per generated part (repeatable: one row per size).
    #[arg(long = "blocks", value_name = "B", default_values_t = [2000usize])]
    pub blocks: Vec<usize>,
    /// The generated parts' k (most weld paths).
    #[arg(long, default_value_t = 2, value_name = "K")]
    pub max_fragments: usize,
    /// Windowed blocks per generated part, 1 to 4 [default: 1 to 4 from the seed].
    #[arg(long = "windows", value_name = "W")]
    pub window_count: Option<usize>,
    /// Write each generated part and its witness plan (the plan its windows come from) to
    /// DIR as NAME.yaml and NAME.witness.yaml (`waam bench scale DIR` times the parts and
    /// leaves the witnesses out).
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
}

fn parse_family(s: &str) -> Result<Family, String> {
    Family::parse(s).map_err(|e| e.to_string())
}

pub fn run(args: &ScaleArgs, n: u64) -> anyhow::Result<ExitCode> {
    let g = &args.generated;
    let timeout =
        Duration::try_from_secs_f64(args.timeout).context("--timeout: expected seconds >= 0")?;
    let families = if g.families.is_empty() {
        Family::ALL.to_vec()
    } else {
        g.families.clone()
    };
    if let Some(dir) = &g.out {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    }
    let stop = crate::cli::node::stop_on_signal()?;
    println!(
        "{:<24} {:>7} {:>4} {:>10} {:>7}",
        "part", "blocks", "win", "first (s)", "checked"
    );
    let mut samples = Vec::new();
    'all: for &blocks in &g.blocks {
        for &family in &families {
            for seed in g.seed..g.seed.saturating_add(n) {
                let spec = Spec {
                    family,
                    blocks,
                    k: g.max_fragments,
                    windows: g.window_count,
                    seed,
                };
                let interrupt = Interrupt {
                    deadline: None,
                    cancel: Some(Arc::clone(&stop)),
                };
                let generated = match generate(&spec, &interrupt) {
                    Ok(generated) => generated,
                    Err(_) if stop.load(Ordering::Relaxed) => break 'all,
                    Err(e) => {
                        return Err(e).context(format!("generating {} seed {seed}", family.name()))
                    }
                };
                let part = &generated.part;
                if let Some(dir) = &g.out {
                    let path = dir.join(format!("{}.yaml", part.name));
                    std::fs::write(&path, waam_part::writer::to_yaml(part))
                        .with_context(|| format!("cannot write {}", path.display()))?;
                    let path = dir.join(format!("{}.witness.yaml", part.name));
                    std::fs::write(&path, generated.witness_plan().to_yaml())
                        .with_context(|| format!("cannot write {}", path.display()))?;
                }
                let opts = Options {
                    timeout: Some(timeout),
                    cancel: Some(Arc::clone(&stop)),
                    solver: args.solver,
                    warm_start: !args.no_warm_start,
                    threads: args.threads(),
                    ..Options::default()
                };
                let run = timed(part, &opts, false, &stop)?;
                // Only a plan the independent check accepts counts as solved.
                let first_s = run.first_feasible_s.filter(|_| run.checked == Some(true));
                println!(
                    "{:<24} {:>7} {:>4} {:>10} {:>7}",
                    part.name,
                    part.len(),
                    part.windows().len(),
                    first_s.map_or(format!("> {:.0}", run.total_s), |t| format!("{t:.2}")),
                    match run.checked {
                        Some(true) => "ok",
                        Some(false) => "FAILED",
                        None => "-",
                    }
                );
                if stop.load(Ordering::Relaxed) {
                    println!("stopped (Ctrl-C)");
                    break 'all;
                }
                samples.push(Sample {
                    family: family.name().to_string(),
                    blocks,
                    seed,
                    first_s,
                });
            }
        }
    }
    let summaries = summarize(&samples);
    println!();
    println!(
        "{:<12} {:>7} {:>6} {:>7} {:>10} {:>10}",
        "family", "blocks", "parts", "solved", "median (s)", "worst (s)"
    );
    let secs = |t: Option<f64>| t.map_or(format!("> {}", args.timeout), |t| format!("{t:.2}"));
    for s in &summaries {
        println!(
            "{:<12} {:>7} {:>6} {:>6.0}% {:>10} {:>10}",
            s.family,
            s.blocks,
            s.parts,
            100.0 * s.rate(),
            secs(s.median_s),
            secs(s.worst_s)
        );
    }
    if let Some(file) = &args.json {
        let json = serde_json::json!({ "runs": samples, "summary": summaries });
        std::fs::write(file, serde_json::to_string_pretty(&json)?)
            .with_context(|| format!("cannot write {}", file.display()))?;
    }
    Ok(ExitCode::from(if stop.load(Ordering::Relaxed) {
        EXIT_INTERRUPTED
    } else {
        EXIT_OK
    }))
}
