//! Pictures a person can look at: the toolpath (top and side view, weld vs transit,
//! arc-on/off marked) and the temperature curves of the t8/5-windowed blocks.
//!
//! Text is drawn with DejaVu Sans, embedded from the `dejavu` crate, so no font has to be
//! installed on the machine. [`layer`] draws thick-wall layer trails and their heat.

pub mod blocks;
pub mod layer;

use std::fs::File;
use std::io::BufWriter;
use std::path::Path;
use std::sync::Once;

use plotters::coord::Shift;
use plotters::prelude::*;
use thiserror::Error;

use waam_motion::toolpath::ToolpathFile;
use waam_part::graph::WeldGraph;
use waam_part::{Block, BlockDisplay, Part, Window};
use waam_thermal::{Interrupt, Simulation, ThermalModel, HOT_C, WARM_C};

/// Size of `toolpath.png` (two panels side by side), pixels.
pub const TOOLPATH_SIZE: (u32, u32) = (1600, 800);
/// Size of `t85.png`, pixels.
pub const T85_SIZE: (u32, u32) = (1200, 800);

const FONT: &str = "sans-serif";

#[derive(Debug, Error)]
pub enum PlotError {
    #[error("cannot draw {file}: {reason}")]
    Draw { file: String, reason: String },
    #[error("the toolpath has no poses")]
    Empty,
    #[error("toolpath pose {index}: {reason}")]
    Pose { index: usize, reason: String },
    #[error("cannot draw {file}: the {what} axis would run from {lo:e} to {hi:e}{hint}; a plot shows at most ±{MAX_AXIS:e} with a span of at least {MIN_RELATIVE_SPAN:e} of that")]
    Axis {
        file: String,
        what: &'static str,
        lo: f64,
        hi: f64,
        hint: String,
    },
}

/// Largest axis value a plot accepts. plotters' tick code loops for ever on ranges near
/// f64's limits (or narrower than the spacing of floats there), so ranges are checked
/// before it sees them.
pub const MAX_AXIS: f64 = 1e12;
/// Smallest axis span relative to its largest value.
pub const MIN_RELATIVE_SPAN: f64 = 1e-9;
/// Largest toolpath coordinate drawn (m): far beyond any cell, far inside [`MAX_AXIS`] mm.
pub const MAX_TOOLPATH_M: f64 = 1e6;

/// Checks an axis range before plotters sees it (see [`MAX_AXIS`]).
fn check_axis(
    path: &Path,
    what: &'static str,
    lo: f64,
    hi: f64,
    hint: String,
) -> Result<(), PlotError> {
    let most = lo.abs().max(hi.abs());
    if lo.is_finite()
        && hi.is_finite()
        && most <= MAX_AXIS
        && hi - lo >= MIN_RELATIVE_SPAN * most
        && hi > lo
    {
        return Ok(());
    }
    Err(PlotError::Axis {
        file: path.display().to_string(),
        what,
        lo,
        hi,
        hint,
    })
}

fn font() {
    static REGISTER: Once = Once::new();
    REGISTER.call_once(|| {
        let _ = plotters::style::register_font(FONT, FontStyle::Normal, dejavu::sans::regular());
    });
}

fn draw_err(path: &Path) -> impl Fn(String) -> PlotError + '_ {
    move |reason| PlotError::Draw {
        file: path.display().to_string(),
        reason,
    }
}

/// Draws a `size` picture with `draw` into memory and writes it to `path` as PNG. The `png`
/// crate encodes it: plotters' own file output would build the whole `image` crate (JPEG and
/// BMP codecs too) for this one format, a needless part of the first build.
fn png<E>(
    path: &Path,
    size: (u32, u32),
    err: impl Fn(String) -> E,
    draw: impl FnOnce(&DrawingArea<BitMapBackend<'_>, Shift>) -> Result<(), E>,
) -> Result<(), E> {
    let mut rgb = vec![0; 3 * size.0 as usize * size.1 as usize];
    {
        let root = BitMapBackend::with_buffer(&mut rgb, size).into_drawing_area();
        draw(&root)?;
        root.present().map_err(|e| err(e.to_string()))?;
    }
    let file = File::create(path).map_err(|e| err(e.to_string()))?;
    let mut encoder = ::png::Encoder::new(BufWriter::new(file), size.0, size.1);
    encoder.set_color(::png::ColorType::Rgb);
    encoder.set_depth(::png::BitDepth::Eight);
    // As plotters (through `image`) wrote them: the smaller files for plots with flat areas.
    encoder.set_adaptive_filter(::png::AdaptiveFilterType::Adaptive);
    let mut writer = encoder.write_header().map_err(|e| err(e.to_string()))?;
    writer
        .write_image_data(&rgb)
        .map_err(|e| err(e.to_string()))?;
    writer.finish().map_err(|e| err(e.to_string()))
}

/// A range around `values` with a margin, at least `min_span` wide.
fn range(values: impl Iterator<Item = f64>, min_span: f64) -> (f64, f64) {
    let (lo, hi) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
        (a.min(v), b.max(v))
    });
    let mid = 0.5 * (lo + hi);
    let half = 0.5 * (hi - lo).max(min_span) * 1.08;
    (mid - half, mid + half)
}

/// Draws `toolpath.png`: top view (x, y) and side view (x, z) in mm in the toolpath's
/// frame; weld moves red, arc-off moves blue, arc-on green dots, arc-off black crosses.
pub fn toolpath_png(tp: &ToolpathFile, path: &Path) -> Result<(), PlotError> {
    if tp.poses.is_empty() {
        return Err(PlotError::Empty);
    }
    for (index, p) in tp.poses.iter().enumerate() {
        if let Some(v) = p
            .position
            .iter()
            .find(|v| v.is_nan() || v.abs() > MAX_TOOLPATH_M)
        {
            return Err(PlotError::Pose {
                index,
                reason: format!(
                    "position {:?} has {v}, not a finite coordinate within ±{MAX_TOOLPATH_M:e} m",
                    p.position
                ),
            });
        }
    }
    font();
    let err = draw_err(path);
    let mm: Vec<[f64; 3]> = tp
        .poses
        .iter()
        .map(|p| p.position.map(|v| v * 1000.0))
        .collect();
    crate::png(path, TOOLPATH_SIZE, &err, |root| {
        root.fill(&WHITE).map_err(|e| err(e.to_string()))?;
        let (left, right) = root.split_horizontally(TOOLPATH_SIZE.0 / 2);
        // Equal scales on both axes of each panel.
        let span = |a: usize, b: usize| {
            let (x0, x1) = range(mm.iter().map(|p| p[a]), 1.0);
            let (y0, y1) = range(mm.iter().map(|p| p[b]), 1.0);
            let s = (x1 - x0).max(y1 - y0);
            let (cx, cy) = (0.5 * (x0 + x1), 0.5 * (y0 + y1));
            (
                (cx - s / 2.0)..(cx + s / 2.0),
                (cy - s / 2.0)..(cy + s / 2.0),
            )
        };
        for (area, (a, b), title, ylabel) in [
            (&left, (0, 1), "Toolpath, top view", "y (mm)"),
            (&right, (0, 2), "Toolpath, side view", "z (mm)"),
        ] {
            let (xr, yr) = span(a, b);
            check_axis(path, "x (mm)", xr.start, xr.end, String::new())?;
            check_axis(path, "y/z (mm)", yr.start, yr.end, String::new())?;
            let mut chart = ChartBuilder::on(area)
                .caption(format!("{title} ({})", tp.frame), (FONT, 24))
                .margin(15)
                .x_label_area_size(45)
                .y_label_area_size(70)
                .build_cartesian_2d(xr, yr)
                .map_err(|e| err(e.to_string()))?;
            chart
                .configure_mesh()
                .x_desc("x (mm)")
                .y_desc(ylabel)
                .label_style((FONT, 15))
                .draw()
                .map_err(|e| err(e.to_string()))?;
            let xy = |k: usize| (mm[k][a], mm[k][b]);
            // Polylines of equal arc state (a move's state is its first pose's).
            let mut start = 0;
            let (mut weld_label, mut transit_label) = (false, false);
            for k in 1..=tp.poses.len() {
                let end_run = k == tp.poses.len() || tp.poses[k].arc_on != tp.poses[start].arc_on;
                if !end_run {
                    continue;
                }
                let last = k.min(tp.poses.len() - 1);
                let on = tp.poses[start].arc_on;
                let style = if on {
                    RED.stroke_width(3)
                } else {
                    BLUE.mix(0.6).stroke_width(1)
                };
                let series = chart
                    .draw_series(LineSeries::new((start..=last).map(xy), style))
                    .map_err(|e| err(e.to_string()))?;
                if on && !weld_label {
                    weld_label = true;
                    series.label("weld (arc on)").legend(|(x, y)| {
                        PathElement::new(vec![(x, y), (x + 20, y)], RED.stroke_width(3))
                    });
                } else if !on && !transit_label {
                    transit_label = true;
                    series
                        .label("approach / retract / transit")
                        .legend(|(x, y)| {
                            PathElement::new(vec![(x, y), (x + 20, y)], BLUE.mix(0.6))
                        });
                }
                start = last;
            }
            let ons: Vec<usize> = (0..tp.poses.len())
                .filter(|&k| tp.poses[k].arc_on && (k == 0 || !tp.poses[k - 1].arc_on))
                .collect();
            let offs: Vec<usize> = (1..tp.poses.len())
                .filter(|&k| !tp.poses[k].arc_on && tp.poses[k - 1].arc_on)
                .collect();
            chart
                .draw_series(ons.iter().map(|&k| Circle::new(xy(k), 6, GREEN.filled())))
                .map_err(|e| err(e.to_string()))?
                .label("arc on")
                .legend(|(x, y)| Circle::new((x + 10, y), 6, GREEN.filled()));
            chart
                .draw_series(
                    offs.iter()
                        .map(|&k| Cross::new(xy(k), 7, BLACK.stroke_width(2))),
                )
                .map_err(|e| err(e.to_string()))?
                .label("arc off")
                .legend(|(x, y)| Cross::new((x + 10, y), 7, BLACK.stroke_width(2)));
            chart
                .configure_series_labels()
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK)
                .label_font((FONT, 15))
                .position(SeriesLabelPosition::UpperRight)
                .draw()
                .map_err(|e| err(e.to_string()))?;
        }
        Ok(())
    })
}

/// The temperature of one windowed block over time.
#[derive(Debug, Clone)]
pub struct Curve {
    /// The block (a graph part's: its node's stand-in block).
    pub block: Block,
    /// Its name in the legend: `[x,y,z]`, or `node 12` of a graph part.
    pub label: String,
    pub window: Window,
    /// (time s, temperature °C), from its deposit on.
    pub samples: Vec<(f64, f64)>,
}

/// Simulates a plan with the part's thermal model and samples every windowed block's
/// temperature at its deposit and after each deposit, then through the cooldown until all are below
/// 500 °C. The samples are exact model values at block-time intervals.
///
/// The simulation runs on a copy of the part without windows (temperatures do not
/// depend on them, and an infeasible plan is then still simulated to its end). The
/// cooldown is stepped by depositing isolated probe blocks far from the part: they share
/// no face with it, so each only advances time by one `block_time_s`.
pub fn temperature_curves(part: &Part, fragments: &[Vec<usize>]) -> Vec<Curve> {
    temperature_curves_until(part, fragments, &Interrupt::default())
        .expect("a simulation without deadline or cancel runs to its end")
}

/// [`temperature_curves`], stopped by `interrupt`: `None` then.
pub fn temperature_curves_until(
    part: &Part,
    fragments: &[Vec<usize>],
    interrupt: &Interrupt,
) -> Option<Vec<Curve>> {
    if part.bead_part().is_some() {
        return graph_temperature_curves(part, fragments, interrupt);
    }
    let params = part.thermal;
    let max_x = part.blocks().iter().map(|b| b[0]).max().unwrap_or(0);
    let probes = ((params.max_cooldown_s / params.block_time_s).ceil() as i64).clamp(1, 20_000);
    let mut blocks = part.blocks().to_vec();
    let probe_at = |i: i64| [max_x.saturating_add(4).saturating_add(2 * i), 0, 0];
    blocks.extend((0..probes).map(probe_at));
    let Ok(mut sim_part) = Part::from_blocks(
        part.name.clone(),
        part.block_mm,
        part.origin_mm,
        part.max_fragments,
        blocks,
    ) else {
        return Some(Vec::new());
    };
    sim_part.thermal = params;
    let graph = WeldGraph::new(&sim_part);
    let model = ThermalModel::new(&sim_part, &graph);
    let mut sim = Simulation::new(&model).interrupted_by(interrupt);
    let index = |b: usize| sim_part.index_of(part.block(b)).expect("same blocks");
    let windowed: Vec<(usize, Window)> =
        part.windows().iter().map(|&(b, w)| (index(b), w)).collect();
    let mut curves: Vec<Curve> = part
        .windows()
        .iter()
        .map(|&(b, w)| Curve {
            block: part.block(b),
            label: BlockDisplay(part.block(b)).to_string(),
            window: w,
            samples: Vec::new(),
        })
        .collect();
    let mut temps = vec![f64::NAN; sim_part.len()];
    for fragment in fragments {
        for (p, &b) in fragment.iter().enumerate() {
            // No windows: a deposit cannot fail.
            let _ = sim.deposit(index(b), p == 0);
            if sim.cancelled() {
                return None;
            }
            // The block starts at the deposit temperature one block time ago.
            if let Some(k) = windowed.iter().position(|w| w.0 == index(b)) {
                let placed = sim.time_s() - params.dt() * params.substeps as f64;
                curves[k].samples.push((placed, params.deposit_c));
            }
            sample(&sim, &mut temps, &windowed, &mut curves);
        }
    }
    for i in 0..probes {
        let Some(probe) = sim_part.index_of(probe_at(i)) else {
            break;
        };
        let _ = sim.deposit(probe, false);
        if sim.cancelled() {
            return None;
        }
        if !sample(&sim, &mut temps, &windowed, &mut curves) {
            break;
        }
    }
    Some(curves)
}

/// Adds the simulation's temperature of every windowed block (`windowed`: sim index, window)
/// to its curve; `temps` is scratch, one per sim block. True while any is still warm.
fn sample(
    sim: &Simulation,
    temps: &mut [f64],
    windowed: &[(usize, Window)],
    curves: &mut [Curve],
) -> bool {
    temps.iter_mut().for_each(|t| *t = f64::NAN);
    for (b, t) in sim.temperatures() {
        temps[b] = t;
    }
    let mut warm = false;
    for (c, &(b, _)) in curves.iter_mut().zip(windowed) {
        if temps[b].is_finite() {
            c.samples.push((sim.time_s(), temps[b]));
            warm |= temps[b] >= WARM_C;
        }
    }
    warm
}

/// [`temperature_curves_until`] of a graph part: its own model (the stand-in blocks'
/// neighbours are not its contacts), sampled after every deposit and, through the
/// cooldown, after every `transit_time_s` of cooling (the model's steps with the arc off)
/// until all are below 500 °C or `max_cooldown_s` has passed.
fn graph_temperature_curves(
    part: &Part,
    fragments: &[Vec<usize>],
    interrupt: &Interrupt,
) -> Option<Vec<Curve>> {
    let params = part.thermal;
    let graph = WeldGraph::new(part);
    let model = ThermalModel::new(part, &graph);
    let mut sim = Simulation::new(&model).interrupted_by(interrupt);
    let windowed: Vec<(usize, Window)> = part.windows().to_vec();
    let mut curves: Vec<Curve> = windowed
        .iter()
        .map(|&(b, w)| Curve {
            block: part.block(b),
            label: format!("node {b}"),
            window: w,
            samples: Vec::new(),
        })
        .collect();
    let mut temps = vec![f64::NAN; part.len()];
    for fragment in fragments {
        for (p, &b) in fragment.iter().enumerate() {
            // A broken window does not stop the picture.
            let _ = sim.deposit(b, p == 0);
            if sim.cancelled() {
                return None;
            }
            if let Some(k) = windowed.iter().position(|w| w.0 == b) {
                let placed = sim.time_s() - model.dt * model.deposit_steps(b) as f64;
                curves[k].samples.push((placed, params.deposit_c));
            }
            sample(&sim, &mut temps, &windowed, &mut curves);
        }
    }
    let pauses = (params.max_cooldown_s / params.transit_time_s.max(1e-9)).ceil() as usize;
    for _ in 0..pauses.min(100_000) {
        let _ = sim.transit();
        if sim.cancelled() {
            return None;
        }
        if !sample(&sim, &mut temps, &windowed, &mut curves) {
            break;
        }
    }
    Some(curves)
}

/// Draws `t85.png`: each windowed block's temperature over time, with the 800 °C and
/// 500 °C lines between which its t8/5 time is counted.
pub fn t85_png(part: &Part, curves: &[Curve], path: &Path) -> Result<(), PlotError> {
    let t_end = curves
        .iter()
        .flat_map(|c| c.samples.last().map(|s| s.0))
        .fold(1.0, f64::max);
    let (y0, y1) = (part.thermal.ambient_c.min(0.0), 1600.0);
    let p = &part.thermal;
    let hint = format!(
        " (thermal.block_time_s = {:e} s, transit_time_s = {:e} s)",
        p.block_time_s, p.transit_time_s
    );
    check_axis(path, "time (s)", 0.0, t_end * 1.02, hint)?;
    let hint = format!(" (thermal.ambient_c = {:e} °C)", p.ambient_c);
    check_axis(path, "temperature (°C)", y0, y1, hint)?;
    font();
    let err = draw_err(path);
    crate::png(path, T85_SIZE, &err, |root| {
        root.fill(&WHITE).map_err(|e| err(e.to_string()))?;
        let title = if curves.is_empty() {
            format!("{}: no t8/5 windows", part.name)
        } else {
            format!(
                "{}: temperatures of the {} windowed blocks",
                part.name,
                curves.len()
            )
        };
        let mut chart = ChartBuilder::on(root)
            .caption(title, (FONT, 24))
            .margin(15)
            .x_label_area_size(45)
            .y_label_area_size(70)
            .build_cartesian_2d(0.0..t_end * 1.02, y0..y1)
            .map_err(|e| err(e.to_string()))?;
        chart
            .configure_mesh()
            .x_desc("time (s)")
            .y_desc("temperature (°C)")
            .label_style((FONT, 15))
            .draw()
            .map_err(|e| err(e.to_string()))?;
        for (level, name) in [(HOT_C, "800 °C"), (WARM_C, "500 °C")] {
            chart
                .draw_series(LineSeries::new(
                    vec![(0.0, level), (t_end * 1.02, level)],
                    BLACK.mix(0.5).stroke_width(1),
                ))
                .map_err(|e| err(e.to_string()))?;
            chart
                .draw_series(std::iter::once(Text::new(
                    name,
                    (t_end * 0.005, level + 15.0),
                    (FONT, 14),
                )))
                .map_err(|e| err(e.to_string()))?;
        }
        for (i, c) in curves.iter().enumerate() {
            let colour = Palette99::pick(i).to_rgba();
            let points = c.samples.iter().map(|&(t, v)| (t, v.clamp(y0, y1)));
            chart
                .draw_series(LineSeries::new(points, colour.stroke_width(2)))
                .map_err(|e| err(e.to_string()))?
                .label(format!(
                    "{} [{}, {}] s",
                    c.label, c.window.min_s, c.window.max_s
                ))
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(2))
                });
        }
        if !curves.is_empty() {
            chart
                .configure_series_labels()
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK)
                .label_font((FONT, 13))
                .position(SeriesLabelPosition::UpperRight)
                .draw()
                .map_err(|e| err(e.to_string()))?;
        }
        Ok(())
    })
}
