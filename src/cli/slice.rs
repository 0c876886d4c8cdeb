//! `waam slice MESH.stl --bead "W H"`: cut a round part into layers of weld beads, as a
//! graph part (`docs/graph-part-format.md`).

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{bail, Context};
use waam_mesh::{self as mesh, Units};
use waam_part::BeadPart;
use waam_slice::{SliceOptions, Sliced};

use super::voxelize::UnitArg;
use super::EXIT_OK;

/// Slice an STL mesh into beads along its contours: a graph part for round parts (tubes,
/// nozzles, flanges) that a block grid turns into staircases.
///
/// Layer i is cut at z = (i + 0.5)·H above the mesh's lowest point. In each section a
/// wall at most 1.5·W wide gets one bead on its centre line; a wider region gets contour
/// rings W apart from its outside and its holes (up to --perimeters rounds), and a core
/// left after that a raster of straight beads. Beads are cut into deposits about W long
/// (nodes), with their contacts: along a bead, beside in a layer, stacked between layers.
/// Prints a summary (layers, beads, nodes, contacts, coverage of the sections by the
/// beads) and writes the part file to --out, or to standard output without --out (the
/// summary then goes to standard error).
#[derive(Debug, clap::Args)]
pub struct SliceArgs {
    /// The mesh: an STL file, binary or ASCII, z up.
    pub mesh: PathBuf,
    /// Bead width and layer height "W H" in millimetres (e.g. "6 2.5").
    #[arg(long, value_parser = parse_bead)]
    pub bead: [f64; 2],
    /// k: the most weld paths (arc starts) a plan of the part may use.
    #[arg(short, long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..))]
    pub k: u32,
    /// Contour rounds from each boundary before a core is filled with a raster.
    #[arg(long, default_value_t = DEFAULT_PERIMETERS, value_parser = clap::value_parser!(u32).range(1..))]
    pub perimeters: u32,
    /// Join open contour ends at most this far apart (mm): CAD exports have small gaps.
    #[arg(long, default_value_t = DEFAULT_JOIN_MM, value_name = "MM")]
    pub join: f64,
    /// The part's name [default: the mesh file's name without extension].
    #[arg(long)]
    pub name: Option<String>,
    /// Unit of the mesh's coordinates.
    #[arg(long, value_enum, default_value_t = UnitArg::Mm)]
    pub units: UnitArg,
    /// Write the part file here instead of to standard output.
    #[arg(short, long)]
    pub out: Option<PathBuf>,
    /// Print the report of every layer, not only the summary.
    #[arg(long)]
    pub layers: bool,
}

pub fn parse_bead(text: &str) -> anyhow::Result<[f64; 2]> {
    let v = text
        .split(|c: char| c.is_whitespace() || c == ',')
        .filter(|s| !s.is_empty())
        .map(|s| {
            s.parse::<f64>()
                .ok()
                .filter(|x| x.is_finite() && *x > 0.0)
                .with_context(|| format!("{s:?} is not a number > 0"))
        })
        .collect::<anyhow::Result<Vec<f64>>>()?;
    match v.as_slice() {
        &[w, h] => Ok([w, h]),
        _ => bail!(
            "expected 2 numbers \"W H\" (bead width, layer height), got {}",
            v.len()
        ),
    }
}

/// `--perimeters`' default.
pub const DEFAULT_PERIMETERS: u32 = 3;
/// `--join`'s default, mm.
pub const DEFAULT_JOIN_MM: f64 = 0.05;

/// Reads an STL file and slices it into beads (`waam slice`, and `--bead` wherever a
/// command takes a mesh).
pub fn slice_mesh(
    path: &Path,
    units: UnitArg,
    name: Option<String>,
    bead: [f64; 2],
    k: u32,
    perimeters: u32,
    join_mm: f64,
) -> anyhow::Result<Sliced> {
    let bytes =
        std::fs::read(path).with_context(|| format!("cannot read mesh {}", path.display()))?;
    let units = match units {
        UnitArg::Mm => Units::Mm,
        UnitArg::M => Units::M,
    };
    let mesh =
        mesh::read_stl(&bytes, units).with_context(|| format!("in mesh {}", path.display()))?;
    let name = name.unwrap_or_else(|| {
        path.file_stem()
            .map_or("part".into(), |s| s.to_string_lossy().into_owned())
    });
    let options = SliceOptions {
        max_fragments: k as usize,
        perimeters: perimeters as usize,
        join_mm,
        ..SliceOptions::new(name, bead)
    };
    waam_slice::slice(&mesh, &options).with_context(|| format!("slicing mesh {}", path.display()))
}

pub fn run(args: SliceArgs) -> anyhow::Result<ExitCode> {
    if !(args.join.is_finite() && args.join >= 0.0) {
        bail!("--join: expected a distance >= 0 mm, got {}", args.join);
    }
    let sliced = slice_mesh(
        &args.mesh,
        args.units,
        args.name.clone(),
        args.bead,
        args.k,
        args.perimeters,
        args.join,
    )?;
    let text = sliced.part.to_yaml();
    // What we write must read back: a failure here is a bug of ours, not bad input.
    BeadPart::parse(&text).context("internal error: the written graph part does not read back")?;
    let summary = summary(&sliced, args.layers);
    match &args.out {
        Some(out) => {
            std::fs::write(out, &text)
                .with_context(|| format!("cannot write part file {}", out.display()))?;
            print!("{summary}");
            println!("wrote {}", out.display());
        }
        None => {
            eprint!("{summary}");
            print!("{text}");
        }
    }
    Ok(ExitCode::from(EXIT_OK))
}

fn summary(s: &Sliced, every_layer: bool) -> String {
    use std::fmt::Write as _;
    let mut out = String::new();
    let (nodes, [along, beside, stacked]) = s.counts();
    let beads: usize = s.layers.iter().map(|l| l.beads).sum();
    let [w, h] = s.part.bead_mm;
    let _ = writeln!(
        out,
        "{}: bead {w} x {h} mm, {} layers, {beads} beads, {nodes} nodes, contacts {} ({along} along, {beside} beside, {stacked} stacked), {:.2} s",
        s.part.name,
        s.layers.len(),
        along + beside + stacked,
        s.elapsed.as_secs_f64()
    );
    if every_layer {
        for l in &s.layers {
            let _ = writeln!(
                out,
                "  layer {:>4} z {:>9.3}: {:>3} beads ({} closed), {:>5} nodes, covered {:5.1} %, outside {:4.1} %",
                l.layer,
                l.z_mm,
                l.beads,
                l.closed_beads,
                l.nodes,
                100.0 * l.covered,
                100.0 * l.outside
            );
        }
    }
    let worst = s.worst_covered();
    let outside = s.worst_outside();
    let _ = writeln!(
        out,
        "coverage: mean {:.1} %, worst {:.1} % (layer {}), bead outside the section at most {:.1} % (layer {})",
        100.0 * s.mean_covered(),
        100.0 * worst.map_or(0.0, |l| l.covered),
        worst.map_or(0, |l| l.layer),
        100.0 * outside.map_or(0.0, |l| l.outside),
        outside.map_or(0, |l| l.layer)
    );
    out
}
