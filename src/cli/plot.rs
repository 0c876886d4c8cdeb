//! `waam plot DIR`: PNG pictures of a planned build.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{bail, Context};
use waam_motion::toolpath::ToolpathFile;
use waam_plot as plot;
use waam_thermal::Interrupt;

use super::{read_part, EXIT_NO, EXIT_OK};

/// Draw a planned build or layer as PNG pictures in DIR.
///
/// DIR/toolpath.png (from DIR/toolpath.yaml): top and side view of the torch path, weld
/// moves red, approach/retract/transit blue, arc-on green dots, arc-off black crosses.
/// With --part, or DIR/part.yaml as `waam plan` without PART writes it, for the plan in
/// DIR/plan.yaml or --plan: DIR/t85.png, the simulated temperature of every t8/5-windowed
/// block over time with the 800 °C and 500 °C lines; DIR/plan3d.png, every block as a box
/// in a 3-D view coloured by weld path (hue) and order (light = early), arc starts
/// numbered; DIR/heat.png and DIR/heat.gif, the blocks coloured by temperature at four
/// stages of the build (an animation of the whole build), with a colour bar and every
/// windowed block's t8/5 time against its window.
/// DIR/trail.png and DIR/temperature.png (from DIR/trail.yaml of `waam layer plan --out
/// DIR`, as `waam layer plot DIR` draws them): the layer's trail over its walls (weld order
/// numbers on the segments, deadheading dashed, start marked) and the temperature of one
/// node (--node) over time against the target.
#[derive(Debug, clap::Args)]
pub struct PlotArgs {
    /// The output directory of `waam plan` / `waam motion` / `waam layer plan`.
    pub dir: PathBuf,
    /// With DIR/trail.yaml: the node whose temperature is drawn, a mesh node index or a
    /// layer node id (its nearest mesh node). Default: the layer's first node.
    #[arg(long, value_name = "N")]
    pub node: Option<String>,
    /// The part file: also draw its 3-D views and temperatures (default: DIR/part.yaml
    /// when it exists).
    #[arg(long, value_name = "PART")]
    pub part: Option<PathBuf>,
    /// The plan for the temperature curves (default: DIR/plan.yaml).
    #[arg(long, value_name = "PLAN")]
    pub plan: Option<PathBuf>,
    /// Give up after this many seconds: the temperature pictures simulate the whole build
    /// and its cooldown, which takes minutes for a part of many blocks or a long transit.
    /// The pictures not drawn by then are named, exit 1. Ctrl-C stops it at once.
    #[arg(long, value_name = "SECONDS")]
    pub timeout: Option<f64>,
}

pub fn run(args: PlotArgs) -> anyhow::Result<ExitCode> {
    let timeout = super::timeout_arg(args.timeout)?;
    let interrupt = Interrupt::after(timeout);
    let stopped = |what: &str| {
        println!(
            "TIMEOUT: {what} not drawn within --timeout {} s",
            timeout.unwrap_or_default().as_secs_f64()
        );
        Ok(ExitCode::from(EXIT_NO))
    };
    let mut drew = 0;
    let toolpath = args.dir.join("toolpath.yaml");
    if toolpath.exists() {
        let text = std::fs::read_to_string(&toolpath)
            .with_context(|| format!("cannot read {}", toolpath.display()))?;
        waam_part::yaml::check(&text)
            .with_context(|| format!("{} is not a toolpath file", toolpath.display()))?;
        let tp: ToolpathFile = serde_yaml::from_str(&text)
            .with_context(|| format!("{} is not a toolpath file", toolpath.display()))?;
        let out = args.dir.join("toolpath.png");
        plot::toolpath_png(&tp, &out)?;
        println!("wrote {}", out.display());
        drew += 1;
    }
    let trail = args.dir.join("trail.yaml");
    if trail.exists() {
        for png in super::layer::plot_dir(&args.dir, args.node.as_deref())? {
            println!("wrote {}", png.display());
            drew += 1;
        }
    } else if args.node.is_some() {
        bail!(
            "--node: {} does not exist (it draws a layer's temperature)",
            trail.display()
        );
    }
    // The part: --part, else the part.yaml that the first run (`waam plan`) writes.
    let part_yaml = args.dir.join("part.yaml");
    let part_path = args
        .part
        .clone()
        .or_else(|| part_yaml.exists().then_some(part_yaml));
    if let Some(part_path) = &part_path {
        let part = read_part(part_path)?;
        let plan_path = args
            .plan
            .clone()
            .unwrap_or_else(|| args.dir.join("plan.yaml"));
        let fragments = match super::read_plan(&part, &plan_path)? {
            Ok(f) => f,
            Err(invalid) => {
                println!("INVALID: {invalid}");
                return Ok(ExitCode::from(EXIT_NO));
            }
        };
        let Some(curves) = plot::temperature_curves_until(&part, &fragments, &interrupt) else {
            return stopped("t85.png, plan3d.png, heat.png and heat.gif");
        };
        let out = args.dir.join("t85.png");
        plot::t85_png(&part, &curves, &out)?;
        println!("wrote {}", out.display());
        let out = args.dir.join("plan3d.png");
        plot::blocks::plan_png(&part, &fragments, &out)?;
        println!("wrote {}", out.display());
        let frames = super::first_run::GIF_FRAMES;
        let Some(build) = plot::blocks::heat_build_until(&part, &fragments, frames, &interrupt)
        else {
            return stopped("heat.png and heat.gif");
        };
        for (name, gif) in [("heat.png", false), ("heat.gif", true)] {
            let out = args.dir.join(name);
            if gif {
                plot::blocks::heat_gif(&part, &build, &out, super::first_run::GIF_DELAY_MS)?;
            } else {
                plot::blocks::heat_png(&part, &build, &out)?;
            }
            println!("wrote {}", out.display());
        }
        drew += 4;
    }
    if drew == 0 {
        bail!(
            "nothing to draw: no {}, no {}, no {} and no --part",
            toolpath.display(),
            trail.display(),
            args.dir.join("part.yaml").display()
        );
    }
    Ok(ExitCode::from(EXIT_OK))
}
