//! `waam plan` without a part: the whole chain on the bundled sample part and robot, every
//! output in one new folder, and a short summary of what was made and how to look at it;
//! then the same for a round part, a ring mesh sliced into beads (in `ring/`).

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use anyhow::{bail, Context};
use waam_motion::toolpath::ToolpathFile;
use waam_part::Part;
use waam_pipeline::{CellSource, Interrupt, Objective, Progress, BUNDLED_URDF};
use waam_plot as plot;
use waam_rosbag::Bag;

use super::motion::MotionSummary;
use super::plan::PlanArgs;
use super::{record, GlobalArgs, DEFAULT_PART, EXIT_NO, EXIT_OK};

/// The default output folder; when it exists, `waam-out-2`, `waam-out-3`, … are tried.
pub const DEFAULT_OUT: &str = "waam-out";
/// Frames of heat.gif during the build (one more after the cooldown).
pub const GIF_FRAMES: usize = 24;
/// Time between the frames of heat.gif, ms.
pub const GIF_DELAY_MS: u32 = 250;

/// The folder to write: `--out DIR` when it does not exist or is empty, else the first of
/// `waam-out`, `waam-out-2`, … that does not exist. Never an existing, non-empty folder.
pub fn output_dir(out: Option<&Path>) -> anyhow::Result<PathBuf> {
    if let Some(dir) = out {
        let empty = match std::fs::read_dir(dir) {
            Ok(mut entries) => entries.next().is_none(),
            Err(_) => !dir.exists(),
        };
        if !empty {
            bail!(
                "--out {}: exists and is not empty (choose a new folder; nothing is overwritten)",
                dir.display()
            );
        }
        return Ok(dir.to_path_buf());
    }
    let mut n = 1;
    loop {
        let dir = if n == 1 {
            PathBuf::from(DEFAULT_OUT)
        } else {
            PathBuf::from(format!("{DEFAULT_OUT}-{n}"))
        };
        if !dir.exists() {
            return Ok(dir);
        }
        n += 1;
    }
}

pub fn run(args: PlanArgs, global: &GlobalArgs) -> anyhow::Result<ExitCode> {
    let started = Instant::now();
    let part = Part::parse(DEFAULT_PART).context("the bundled sample part")?;
    let opts = super::plan::options(&args)?;
    let dir = output_dir(args.out.as_deref())?;
    std::fs::create_dir_all(&dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let write = |name: &str, text: &str| -> anyhow::Result<()> {
        let path = dir.join(name);
        std::fs::write(&path, text).with_context(|| format!("cannot write {}", path.display()))
    };
    write("part.yaml", DEFAULT_PART)?;
    // The bundled robot and torch, as with --robot (--no-torch: none, and the moves keep
    // only the TCP's path clear of the part).
    let cell = CellSource {
        no_torch: args.no_torch,
        ..CellSource::default()
    }
    .load()
    .map_err(super::motion::cell_error)?;
    let robot_name = cell.robot.name.clone();
    // The planner checks the same torch (the robot then welds only what the torch reaches)
    // and learns from a candidate the robot cannot weld on the model's time line.
    let opts = waam_pipeline::planner_options(&part, Some(&cell), &opts);
    let bag_dir = dir.join("recording");
    let (recorder, mut planning) =
        record::start_planning(&bag_dir, None, &part, &opts, Some((&cell, BUNDLED_URDF)))?;
    let mut bar = super::plan::LazyBar::new(global.quiet);
    let objective = if args.first {
        Objective::First
    } else {
        Objective::Best
    };
    let options = waam_pipeline::Options {
        planner: opts.clone(),
        objective,
        motion: Interrupt::default(),
    };
    let outcome = waam_pipeline::plan(&part, Some(&cell), &options, &mut |p| {
        if let Progress::Planner(event) = p {
            bar.update(event.stats());
            planning.on_event(&event);
        }
    })?;
    let report = outcome.report;
    bar.finish();
    let say = |line: String| {
        if !global.quiet {
            println!("{line}");
        }
    };
    say(format!(
        "planned the bundled sample part {:?}: {} blocks in {} layers, at most {} weld paths, {} blocks with t8/5 windows",
        part.name,
        part.len(),
        part.layers(),
        opts.max_fragments.unwrap_or(part.max_fragments),
        part.windows().len()
    ));
    let Some(best) = &report.best else {
        record::finish_planning(recorder, planning, &part, &report, None)?;
        match &report.no_plan {
            Some(reason) => println!("NO PLAN: {reason}"),
            None => println!("NO PLAN: none found before the timeout"),
        }
        println!("recorded the search in {}", bag_dir.display());
        return Ok(ExitCode::from(EXIT_NO));
    };
    let plan = best.plan(&part);
    write("plan.yaml", &plan.to_yaml())?;
    let proof = match (report.proven, args.first) {
        (true, false) => "optimal (proven)",
        (true, true) => "first found (not optimized)",
        (false, _) => "best found before the timeout (optimality NOT proven)",
    };
    let starts: Vec<String> = best
        .fragments
        .iter()
        .filter_map(|f| f.first())
        .map(|&b| waam_part::BlockDisplay(part.block(b)).to_string())
        .collect();
    say(format!(
        "  plan:  {} weld path(s), arc starts at {} — {proof}",
        best.fragments.len(),
        starts.join(" ")
    ));
    say(format!(
        "         worst t8/5 margin {}, {} candidates checked in {:.1} s",
        best.margin_text(),
        report.stats.candidates,
        report.stats.total_s
    ));
    if let Some(t) = &opts.torch {
        say(format!(
            "         torch access checked at every deposit (nozzle {} mm across; --no-torch: off)",
            t.torch.nozzle_diameter_mm
        ));
    }
    if global.verbose > 0 || args.print_plan {
        print!("{}", plan.to_yaml());
    }
    let motion = match outcome.motion {
        Some(Ok(planned)) => Some(planned),
        Some(Err(e)) => {
            println!("NO MOTION: {e}");
            None
        }
        None => None,
    };
    let messages = motion.as_ref().map(record::plan_messages).transpose()?;
    record::finish_planning(recorder, planning, &part, &report, messages.as_ref())?;
    let bag = Bag::open(&bag_dir).context("reading back the recording")?;
    if let Some(m) = &motion {
        super::motion::write_motion(&m.toolpath, &m.trajectory, &dir)?;
        let s = MotionSummary::of(&m.toolpath);
        say(format!(
            "  robot: {robot_name}: {} poses, {} weld pass(es), {:.0} s of motion ({:.0} s arc on), joint trajectory validated",
            s.poses, s.passes, s.duration_s, s.arc_on_s
        ));
    }
    // Pictures.
    let t85 = plot::temperature_curves(&part, &best.fragments);
    plot::t85_png(&part, &t85, &dir.join("t85.png"))?;
    plot::blocks::plan_png(&part, &best.fragments, &dir.join("plan3d.png"))?;
    let build = plot::blocks::heat_build(&part, &best.fragments, GIF_FRAMES);
    plot::blocks::heat_png(&part, &build, &dir.join("heat.png"))?;
    plot::blocks::heat_gif(&part, &build, &dir.join("heat.gif"), GIF_DELAY_MS)?;
    if motion.is_some() {
        let text = std::fs::read_to_string(dir.join("toolpath.yaml"))?;
        let tp: ToolpathFile = serde_yaml::from_str(&text).context("toolpath.yaml")?;
        plot::toolpath_png(&tp, &dir.join("toolpath.png"))?;
    }
    let d = dir.display();
    let mcap = bag.mcap_file.display();
    say(format!(
        "wrote {d}/ in {:.1} s:",
        started.elapsed().as_secs_f64()
    ));
    say(format!(
        "  part.yaml plan.yaml           the part and its weld order    waam check {d}/part.yaml {d}/plan.yaml"
    ));
    if motion.is_some() {
        say("  toolpath.yaml trajectory.yaml torch poses, robot joint trajectory (for the robot controller)".into());
    }
    say(
        "  plan3d.png                    3-D: blocks by weld path and order, arc starts numbered"
            .into(),
    );
    say(
        "  heat.png heat.gif             3-D: temperatures during the build, t8/5 vs windows"
            .into(),
    );
    say(format!(
        "  {:<30}t8/5 curves{}",
        if motion.is_some() {
            "t85.png toolpath.png"
        } else {
            "t85.png"
        },
        if motion.is_some() {
            "; toolpath top and side view"
        } else {
            ""
        }
    ));
    say(format!(
        "  recording/                    rosbag2 bag, {} messages: open {mcap} in Foxglove; waam replay {d}/recording",
        bag.messages.len()
    ));
    say(format!(
        "redraw the pictures: waam plot {d}    print the block lists: waam plan --print-plan"
    ));
    let ring_ok = ring_run(&cell, &dir.join("ring"), objective, &say)?;
    let ok = motion.is_some() && ring_ok;
    Ok(ExitCode::from(if ok { EXIT_OK } else { EXIT_NO }))
}

/// The sample ring: a tube 40 mm across its wall's centre line, 6 mm thick, 5 mm tall.
const RING_MM: (f64, f64, f64) = (17.0, 23.0, 5.0);
/// Its bead: width and layer height, mm (one bead on the wall's centre line, 2 layers).
const RING_BEAD_MM: [f64; 2] = [6.0, 2.5];

/// A closed tube about the z axis (metres, outward-facing triangles, `n` segments), as a
/// mesh arrives on `~/part_mesh`.
fn tube_mesh(r_in: f64, r_out: f64, height: f64, n: u32) -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
    let mut vertices = Vec::new();
    for z in [0.0, height] {
        for r in [r_in, r_out] {
            vertices.extend((0..n).map(|i| {
                let a = std::f64::consts::TAU * f64::from(i) / f64::from(n);
                [r * a.cos(), r * a.sin(), z]
            }));
        }
    }
    // Vertex (level, wall, i): level 0 bottom, 1 top; wall 0 inner, 1 outer.
    let at = |level: u32, wall: u32, i: u32| i % n + n * (wall + 2 * level);
    let mut triangles = Vec::new();
    for i in 0..n {
        let j = i + 1;
        triangles.extend([
            [at(0, 1, i), at(0, 1, j), at(1, 1, j)],
            [at(0, 1, i), at(1, 1, j), at(1, 1, i)],
            [at(0, 0, i), at(1, 0, j), at(0, 0, j)],
            [at(0, 0, i), at(1, 0, i), at(1, 0, j)],
            [at(1, 0, i), at(1, 1, i), at(1, 1, j)],
            [at(1, 0, i), at(1, 1, j), at(1, 0, j)],
            [at(0, 0, i), at(0, 1, j), at(0, 1, i)],
            [at(0, 0, i), at(0, 0, j), at(0, 1, j)],
        ]);
    }
    (vertices, triangles)
}

/// The first run's round part: a ring mesh sliced into beads (a graph part), planned and
/// welded along its bead by the same cell, exported as G-code and drawn, in `dir`.
/// `Ok(false)`: no plan or no motion (said why).
fn ring_run(
    cell: &waam_pipeline::Cell,
    dir: &Path,
    objective: Objective,
    say: &dyn Fn(String),
) -> anyhow::Result<bool> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let (r_in, r_out, height) = RING_MM;
    let (vertices, triangles) = tube_mesh(r_in / 1e3, r_out / 1e3, height / 1e3, 128);
    let settings = waam_pipeline::MeshSettings {
        block_mm: [RING_BEAD_MM[0], RING_BEAD_MM[0], RING_BEAD_MM[1]],
        bead_mm: Some(RING_BEAD_MM),
        window: None,
        max_fragments: 2,
    };
    let part = settings
        .part_of_mesh("ring".into(), &vertices, &triangles)
        .context("the bundled ring mesh")?;
    let beads = part.bead_part().context("the ring is not a graph part")?;
    let write = |name: &str, text: &str| -> anyhow::Result<()> {
        let path = dir.join(name);
        std::fs::write(&path, text).with_context(|| format!("cannot write {}", path.display()))
    };
    write("part.yaml", &beads.to_yaml())?;
    // The cell's torch (none with --no-torch) and robot check the planner's candidates; the
    // best plan, as for the first part (the first found depends on which racer wins).
    let options = waam_pipeline::Options {
        planner: waam_pipeline::planner_options(&part, Some(cell), &Default::default()),
        objective,
        motion: Interrupt::default(),
    };
    let outcome = waam_pipeline::plan(&part, Some(cell), &options, &mut |_| {})?;
    let d = dir.display();
    say(format!(
        "planned a ring mesh sliced into beads of {} x {} mm: {} nodes in {} layers (a graph part, as waam slice MESH --bead \"W H\")",
        RING_BEAD_MM[0],
        RING_BEAD_MM[1],
        part.len(),
        beads.layers()
    ));
    let Some(best) = &outcome.report.best else {
        say("  ring:  NO PLAN".into());
        return Ok(false);
    };
    write("plan.yaml", &best.plan(&part).to_yaml())?;
    let planned = match outcome.motion {
        Some(Ok(planned)) => planned,
        Some(Err(e)) => {
            say(format!("  ring:  NO MOTION: {e}"));
            return Ok(false);
        }
        None => return Ok(false),
    };
    super::motion::write_motion(&planned.toolpath, &planned.trajectory, dir)?;
    super::export::export_default(dir, waam_export::Format::Gcode, cell)?;
    plot::blocks::plan_png(&part, &best.fragments, &dir.join("plan3d.png"))?;
    let text = std::fs::read_to_string(dir.join("toolpath.yaml"))?;
    let tp: ToolpathFile = serde_yaml::from_str(&text).context("ring/toolpath.yaml")?;
    plot::toolpath_png(&tp, &dir.join("toolpath.png"))?;
    let s = MotionSummary::of(&planned.toolpath);
    say(format!(
        "  ring:  {} weld path(s), the torch along the bead's centre line: {} poses, {:.0} s of motion, joint trajectory validated",
        best.fragments.len(),
        s.poses,
        s.duration_s
    ));
    say(format!(
        "  {d}/  part.yaml plan.yaml toolpath.yaml trajectory.yaml, G-code, plan3d.png toolpath.png    waam check {d}/part.yaml {d}/plan.yaml"
    ));
    Ok(true)
}
