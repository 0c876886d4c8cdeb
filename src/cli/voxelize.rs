//! `waam voxelize MESH.stl --pitch "X Y Z"`: turn a CAD mesh into a part file.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{bail, Context};
use waam_mesh::{self as mesh, Units, VoxelizeOptions, WindowRule, DEFAULT_MAX_CELLS};
use waam_part::writer;
use waam_part::{Part, Window};

use super::EXIT_OK;

/// Voxelize an STL mesh (binary or ASCII) into a part file in the shared part format.
///
/// The mesh must be closed and consistently oriented. A block belongs to the part when
/// its centre lies inside the mesh; the grid's block (0,0,0) has its min corner at the
/// mesh's min corner unless --grid-origin says otherwise. The part file (layers form)
/// goes to --out or to standard output; `waam check` and the planner read it.
#[derive(Debug, clap::Args)]
pub struct VoxelizeArgs {
    /// The mesh: an STL file, binary or ASCII.
    pub mesh: PathBuf,
    #[command(flatten)]
    pub options: MeshArgs,
    /// Write the part file here instead of to standard output.
    #[arg(short, long)]
    pub out: Option<PathBuf>,
}

/// How a mesh becomes a part: the options of every subcommand that accepts an STL file.
#[derive(Debug, Clone, clap::Args)]
pub struct MeshArgs {
    /// Block pitch "X Y Z" in millimetres: bead width, bead width, layer height (e.g. "6 6 2.5").
    #[arg(long, value_parser = parse_pitch, conflicts_with = "bead")]
    pub pitch: Option<[f64; 3]>,
    /// Bead width and layer height "W H" in millimetres (e.g. "6 2.5"): slice the mesh into
    /// beads along its contours (a graph part, as `waam slice` does) instead of voxelizing
    /// it into blocks. Round parts (tubes, nozzles, flanges) want this.
    #[arg(long, value_parser = super::slice::parse_bead)]
    pub bead: Option<[f64; 2]>,
    /// k: the most weld paths (arc starts) a plan of the part may use [default: 1 for a
    /// mesh]. With a part file (cube or graph part), replaces the file's max_fragments.
    #[arg(short, long, value_parser = clap::value_parser!(u32).range(1..))]
    pub k: Option<u32>,
    /// The part's name [default: the mesh file's name without extension].
    #[arg(long)]
    pub name: Option<String>,
    /// Unit of the mesh's coordinates.
    #[arg(long, value_enum, default_value_t = UnitArg::Mm)]
    pub units: UnitArg,
    /// A t8/5 window: "MIN_S MAX_S" on every block, "MIN_S MAX_S X Y Z" on one block or
    /// "MIN_S MAX_S X0 Y0 Z0 X1 Y1 Z1" on a box of blocks (inclusive). Repeatable; a later
    /// window overrides an earlier one on the same block.
    #[arg(long = "window", value_name = "SPEC", value_parser = parse_window)]
    pub windows: Vec<WindowRule>,
    /// Min corner "X Y Z" (mm) of block (0,0,0) [default: the mesh's min corner].
    #[arg(long, value_parser = parse_triple)]
    pub grid_origin: Option<[f64; 3]>,
    /// Refuse a grid of more cells than this (a tiny pitch would otherwise run for ever).
    #[arg(long, default_value_t = DEFAULT_MAX_CELLS)]
    pub max_cells: u64,
}

/// Unit of mesh coordinates on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum UnitArg {
    /// Millimetres.
    Mm,
    /// Metres.
    M,
}

impl MeshArgs {
    /// Reads and voxelizes an STL file into a part, logging what it did.
    pub fn voxelize(&self, path: &Path) -> anyhow::Result<Part> {
        if let Some(bead) = self.bead {
            return self.slice(path, bead);
        }
        let Some(pitch) = self.pitch else {
            bail!(
                "{}: a mesh needs --pitch \"X Y Z\" (block size in mm) or --bead \"W H\" \
                 (bead width and layer height in mm)",
                path.display()
            );
        };
        let bytes =
            std::fs::read(path).with_context(|| format!("cannot read mesh {}", path.display()))?;
        let units = match self.units {
            UnitArg::Mm => Units::Mm,
            UnitArg::M => Units::M,
        };
        let name = self.name.clone().unwrap_or_else(|| {
            path.file_stem()
                .map_or("part".into(), |s| s.to_string_lossy().into_owned())
        });
        let options = VoxelizeOptions {
            origin_mm: self.grid_origin,
            max_fragments: self.k.unwrap_or(1) as usize,
            windows: self.windows.clone(),
            max_cells: self.max_cells,
            ..VoxelizeOptions::new(name, pitch)
        };
        let voxels = mesh::read_stl(&bytes, units)
            .and_then(|m| mesh::voxelize(&m, &options))
            .with_context(|| format!("in mesh {}", path.display()))?;
        for warning in &voxels.warnings {
            tracing::warn!("{}: {warning}", path.display());
        }
        let [nx, ny, nz] = voxels.grid;
        tracing::info!(
            "{}: {} triangles -> {} blocks on a {nx} x {ny} x {nz} grid",
            path.display(),
            voxels.triangles,
            voxels.part.len()
        );
        Ok(voxels.part)
    }

    /// Slices an STL file into beads (`--bead`): the planning view of its graph part, with
    /// the `--window` rules applied by layer.
    fn slice(&self, path: &Path, bead: [f64; 2]) -> anyhow::Result<Part> {
        let mut beads = super::slice::slice_mesh(
            path,
            self.units,
            self.name.clone(),
            bead,
            self.k.unwrap_or(1),
            super::slice::DEFAULT_PERIMETERS,
            super::slice::DEFAULT_JOIN_MM,
        )?
        .part;
        for rule in &self.windows {
            let whole_layers = rule.min[..2] == [0, 0] && rule.max[..2] == [i64::MAX; 2];
            if !whole_layers {
                bail!(
                    "--window: a graph part (--bead) takes windows on every node (\"MIN_S MAX_S\") \
                     or on whole layers, not on block boxes"
                );
            }
            let layers = rule.min[2]..=rule.max[2];
            for i in 0..beads.nodes.len() {
                if layers.contains(&(beads.nodes[i].layer as i64)) {
                    beads.set_window(i, rule.window);
                }
            }
        }
        tracing::info!(
            "{}: sliced into {} nodes on {} layers (bead {} x {} mm)",
            path.display(),
            beads.len(),
            beads.layers(),
            bead[0],
            bead[1]
        );
        Part::of_beads(beads).with_context(|| format!("in mesh {}", path.display()))
    }

    /// A part from a part file, or from an STL mesh (by its `.stl` extension): for the
    /// subcommands that take a PART argument (flatten `MeshArgs` into their arguments).
    pub fn read_part_or_mesh(&self, path: &Path) -> anyhow::Result<Part> {
        let is_stl = path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("stl"));
        if is_stl {
            return self.voxelize(path);
        }
        let mut part = super::read_part(path)?;
        if let Some(k) = self.k {
            part.set_max_fragments(k as usize);
        }
        Ok(part)
    }
}

pub fn run(args: VoxelizeArgs) -> anyhow::Result<ExitCode> {
    let part = args.options.voxelize(&args.mesh)?;
    let text = writer::to_yaml(&part);
    // What we write must read back: a failure here is a bug of ours, not bad input.
    Part::parse(&text).context("internal error: the written part file does not read back")?;
    match &args.out {
        Some(out) => std::fs::write(out, &text)
            .with_context(|| format!("cannot write part file {}", out.display()))?,
        None => print!("{text}"),
    }
    Ok(ExitCode::from(EXIT_OK))
}

fn numbers(text: &str) -> Result<Vec<f64>, String> {
    text.split(|c: char| c.is_whitespace() || c == ',')
        .filter(|s| !s.is_empty())
        .map(|s| {
            s.parse::<f64>()
                .ok()
                .filter(|x| x.is_finite())
                .ok_or_else(|| format!("{s:?} is not a finite number"))
        })
        .collect()
}

fn parse_triple(text: &str) -> Result<[f64; 3], String> {
    let v = numbers(text)?;
    <[f64; 3]>::try_from(v.as_slice())
        .map_err(|_| format!("expected 3 numbers \"X Y Z\", got {}", v.len()))
}

pub fn parse_pitch(text: &str) -> Result<[f64; 3], String> {
    let p = parse_triple(text)?;
    if p.iter().any(|&x| x <= 0.0) {
        return Err(format!("every pitch must be > 0, got {text:?}"));
    }
    Ok(p)
}

fn parse_window(text: &str) -> Result<WindowRule, String> {
    let v = numbers(text)?;
    if !matches!(v.len(), 2 | 5 | 8) {
        return Err(format!(
            "expected \"MIN_S MAX_S\", \"MIN_S MAX_S X Y Z\" or \"MIN_S MAX_S X0 Y0 Z0 X1 Y1 Z1\", got {} numbers",
            v.len()
        ));
    }
    let window = Window {
        min_s: v[0],
        max_s: v[1],
    };
    if !(0.0 <= window.min_s && window.min_s <= window.max_s) {
        return Err(format!("need 0 <= MIN_S <= MAX_S, got {text:?}"));
    }
    let mut coords = [0i64; 6];
    for (c, &x) in coords.iter_mut().zip(&v[2..]) {
        if x.fract() != 0.0 || x < 0.0 || x > i64::MAX as f64 {
            return Err(format!("block coordinates must be integers >= 0, got {x}"));
        }
        *c = x as i64;
    }
    Ok(match v.len() {
        2 => WindowRule::everywhere(window),
        5 => WindowRule::block([coords[0], coords[1], coords[2]], window),
        _ => WindowRule {
            min: [coords[0], coords[1], coords[2]],
            max: [coords[3], coords[4], coords[5]],
            window,
        },
    })
}
