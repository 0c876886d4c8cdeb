//! `waam export DIR --format F`: a planned motion as a robot program for a cell without ROS.
//! [`export_dir`] also serves `--export` on `waam plan` and `waam layer plan`.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::Context;
use waam_export::{arm_configs, export, read_toolpath_dir, CellSettings, Format, Program};
use waam_motion::robot::Robot;
use waam_motion::toolpath::{ProcessSettings, PART_FRAME};
use waam_pipeline::Cell;

use super::motion::RobotArgs;
use super::EXIT_OK;

/// Write a planned motion as a robot program: ABB RAPID, KUKA KRL (ArcTech), Yaskawa
/// INFORM, Fanuc LS, or G-code for a gantry.
///
/// DIR holds toolpath.yaml and trajectory.yaml, as `waam plan PART --robot URDF --out DIR`,
/// `waam motion` or `waam layer plan --robot URDF --out DIR` write them; for gcode,
/// toolpath.yaml alone will do (`waam plan PART --out DIR` without a robot: the part frame,
/// the toolpath's timing, moves with the arc off as G0). The program has one
/// target per toolpath pose (in the plate frame: the work object / base / user frame), the
/// trajectory's timing (speeds, dwells), the arc on exactly where the toolpath has it, and
/// for the robot formats the arm configuration of the validated joint solution — for which
/// the robot formats need the same --robot (and --tcp / --tip) the motion was planned with.
/// Long programs are split between weld passes into part programs that a main program calls
/// (see docs/export.md). Exit code 0: written; 2: bad input.
#[derive(Debug, clap::Args)]
pub struct ExportArgs {
    /// The motion directory (toolpath.yaml, trajectory.yaml; gcode: toolpath.yaml alone).
    pub dir: PathBuf,
    /// The program format.
    #[arg(long, value_parser = format_parser())]
    pub format: Format,
    /// The directory the program's files are written to (created if missing). Default: DIR.
    #[arg(long, value_name = "PATH")]
    pub out: Option<PathBuf>,
    /// The program's name (a letter, then letters, digits or underscores; at most 24).
    #[arg(long, default_value = "WAAM")]
    pub name: String,
    /// Cell settings (YAML, see config/export.yaml): weld schedule, wire feed, voltage,
    /// current, frame and tool numbers, program size limits, G-code arc commands. Default:
    /// the values in config/export.yaml, built in.
    #[arg(long, value_name = "FILE")]
    pub cell: Option<PathBuf>,
    /// The robot's URDF the motion was planned for (needed by every format but gcode).
    #[arg(long, value_name = "URDF")]
    pub robot: Option<PathBuf>,
    /// With --robot: the TCP in the tip link as "x y z roll pitch yaw" (m, rad), as planned.
    #[arg(
        long,
        value_name = "\"x y z roll pitch yaw\"",
        allow_hyphen_values = true,
        requires = "robot"
    )]
    pub tcp: Option<String>,
    /// With --robot: the link the TCP is attached to (the controller's flange: the tool
    /// data is the TCP in this link).
    #[arg(long, value_name = "LINK", requires = "robot")]
    pub tip: Option<String>,
    /// The process settings the motion was planned with (YAML, see config/process.yaml):
    /// the plate frame becomes the work object / base / user frame. Default: built in.
    #[arg(long, value_name = "FILE")]
    pub process: Option<PathBuf>,
}

/// clap's parser of the formats, each listed with its help line.
pub fn format_parser() -> impl clap::builder::TypedValueParser<Value = Format> {
    use clap::builder::{PossibleValue, PossibleValuesParser, TypedValueParser as _};
    PossibleValuesParser::new(
        Format::ALL.map(|(_, name, help)| PossibleValue::new(name).help(help)),
    )
    .map(|name| name.parse().expect("clap accepts only listed names"))
}

pub fn run(args: ExportArgs) -> anyhow::Result<ExitCode> {
    check_name(&args.name)?;
    let cell = read_cell(args.cell.as_deref())?;
    let (settings, robot) = match &args.robot {
        Some(urdf) => {
            let cell = RobotArgs {
                robot: urdf.clone(),
                tcp: args.tcp.clone(),
                tip: args.tip.clone(),
                process: args.process.clone(),
                // The program carries positions and timing, not limits.
                limits: None,
            }
            .load()?;
            (cell.settings, Some(cell.robot))
        }
        None => {
            let s = match &args.process {
                Some(path) => {
                    let text = std::fs::read_to_string(path).with_context(|| {
                        format!("cannot read process settings {}", path.display())
                    })?;
                    ProcessSettings::from_yaml(&text)
                        .with_context(|| format!("in process settings {}", path.display()))?
                }
                None => ProcessSettings::default(),
            };
            (s, None)
        }
    };
    let out = args.out.as_deref().unwrap_or(&args.dir);
    let exported = export_dir(
        &args.dir,
        args.format,
        robot.as_ref(),
        &settings,
        &cell,
        &args.name,
        out,
    )?;
    println!("{exported}");
    Ok(ExitCode::from(EXIT_OK))
}

fn check_name(name: &str) -> anyhow::Result<()> {
    let ok = name.len() <= 24
        && name.chars().next().is_some_and(|c| c.is_ascii_alphabetic())
        && name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_');
    anyhow::ensure!(
        ok,
        "--name {name:?}: expected a letter, then letters, digits or underscores (at most 24)"
    );
    Ok(())
}

/// Reads the cell settings (defaults without a file).
pub fn read_cell(path: Option<&Path>) -> anyhow::Result<CellSettings> {
    match path {
        Some(path) => {
            let text = std::fs::read_to_string(path)
                .with_context(|| format!("cannot read cell settings {}", path.display()))?;
            CellSettings::from_yaml(&text)
                .with_context(|| format!("in cell settings {}", path.display()))
        }
        None => Ok(CellSettings::default()),
    }
}

/// What [`export_dir`] wrote; displayed as the `EXPORT:` line.
pub struct Exported {
    format: Format,
    targets: usize,
    passes: usize,
    files: Vec<PathBuf>,
}

impl std::fmt::Display for Exported {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let files: Vec<_> = self.files.iter().map(|p| p.display().to_string()).collect();
        write!(
            f,
            "EXPORT: {}, {} targets, {} weld pass(es), {} file(s): {}",
            self.format,
            self.targets,
            self.passes,
            files.len(),
            files.join(", ")
        )
    }
}

/// Reads the motion in `dir` and writes its program in `format` into `out`.
pub fn export_dir(
    dir: &Path,
    format: Format,
    robot: Option<&Robot>,
    settings: &ProcessSettings,
    cell: &CellSettings,
    name: &str,
    out: &Path,
) -> anyhow::Result<Exported> {
    let (tp, traj) = read_toolpath_dir(dir)?;
    let program = match traj {
        Some(traj) => {
            let configs = match (robot, format.is_robot()) {
                (Some(robot), true) => Some(arm_configs(robot, &tp, &traj)?),
                (None, true) => anyhow::bail!(
                    "--format {format} needs --robot URDF (the robot the motion in {} was planned for) to write the arm configuration of every target",
                    dir.display()
                ),
                (_, false) => None,
            };
            let tcp = robot.map_or_else(nalgebra::Isometry3::identity, |r| r.tcp);
            Program::new(name, &tp, &traj, settings.plate.isometry(), tcp, configs)
        }
        // A plan without a robot: the toolpath alone, for a gantry.
        None => {
            anyhow::ensure!(
                !format.is_robot(),
                "--format {format} needs a robot motion: {} has toolpath.yaml but no trajectory.yaml (plan with --robot URDF); --format gcode takes the toolpath alone",
                dir.display()
            );
            let plate = if tp.frame == PART_FRAME {
                nalgebra::Isometry3::identity()
            } else {
                settings.plate.isometry()
            };
            Program::from_toolpath(name, &tp, plate)
        }
    }
    .with_context(|| format!("in the motion in {}", dir.display()))?;
    let files = export(&program, format, cell)?;
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    let mut written = Vec::new();
    for f in &files {
        let path = out.join(&f.name);
        std::fs::write(&path, &f.text)
            .with_context(|| format!("cannot write {}", path.display()))?;
        written.push(path);
    }
    Ok(Exported {
        format,
        targets: program.targets.len(),
        passes: program.passes(),
        files: written,
    })
}

/// `--export FORMAT` of `waam plan` / `waam layer plan`: the motion just written to `dir`
/// as a program named WAAM in `dir`, with the default cell settings.
pub fn export_default(dir: &Path, format: Format, cell: &Cell) -> anyhow::Result<Exported> {
    export_dir(
        dir,
        format,
        Some(&cell.robot),
        &cell.settings,
        &CellSettings::default(),
        "WAAM",
        dir,
    )
}
