//! 3-D pictures of a block plan: every block a shaded box in an isometric view.
//!
//! The boxes are drawn back to front (painter's algorithm) with their three visible faces
//! (top, +x, +y) in three shades of one colour. [`plan_png`] colours them by weld path and
//! order and marks the arc starts; [`heat_png`] and [`heat_gif`] colour the welded blocks
//! by their simulated temperature during the build (like Figure 2 of Ehlers et al.), with a
//! colour bar and every windowed block's t8/5 time against its window.
//!
//! Why the order is right: the view direction is positive along every grid axis, so a box
//! can hide only boxes whose grid coordinates are all smaller or equal; drawing in order of
//! x + y + z therefore never paints a hidden face over a visible one.
//!
//! A graph part (beads) is drawn the same way, each node as its piece of bead: one prism
//! per segment of its centre line, W wide and one layer tall, in order of the prisms'
//! centres along the view direction (x + y + z in mm; exact for boxes that do not
//! interpenetrate in depth, close enough for beads).

use std::fs::File;
use std::io::BufWriter;
use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;

use waam_part::graph::WeldGraph;
use waam_part::{BlockDisplay, Part, Window};
use waam_thermal::{Interrupt, Simulation, ThermalModel, HOT_C, WARM_C};

use crate::{draw_err, font, PlotError, FONT};

/// Size of `plan3d.png`, pixels.
pub const PLAN_SIZE: (u32, u32) = (1000, 720);
/// Size of `heat.png` (four stages of the build side by side, colour bar, t8/5 table).
pub const HEAT_SIZE: (u32, u32) = (1400, 820);
/// Size of every frame of `heat.gif`.
pub const GIF_SIZE: (u32, u32) = (1000, 620);
/// Width of the colour bar and t8/5 table column.
const SIDE_W: u32 = 330;

/// Weld path colours (a colour-blind-safe set); path i uses `PATH_COLOURS[i % len]`.
const PATH_COLOURS: [RGBColor; 6] = [
    RGBColor(0, 114, 178),
    RGBColor(213, 94, 0),
    RGBColor(0, 158, 115),
    RGBColor(204, 121, 167),
    RGBColor(230, 159, 0),
    RGBColor(86, 180, 233),
];

/// The isometric projection of a part (mm) fitted into a pixel rectangle.
struct View {
    scale: f64,
    offset: (f64, f64),
}

const COS30: f64 = 0.866_025_403_784_438_6;

impl View {
    /// Screen position (before fitting) of a point in mm.
    fn raw(p: [f64; 3]) -> (f64, f64) {
        let [x, y, z] = p;
        ((x - y) * COS30, 0.5 * (x + y) - z)
    }

    /// Fits every prism of a part into `(w, h)` pixels at `(x0, y0)`.
    fn fit(prisms: &[Prism], (x0, y0): (i32, i32), (w, h): (u32, u32)) -> View {
        let (mut u0, mut u1, mut v0, mut v1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
        for c in prisms.iter().flat_map(Prism::points) {
            let (u, v) = View::raw(c);
            (u0, u1, v0, v1) = (u0.min(u), u1.max(u), v0.min(v), v1.max(v));
        }
        if u0 > u1 {
            (u0, u1, v0, v1) = (0.0, 1.0, 0.0, 1.0);
        }
        let scale =
            (0.92 * w as f64 / (u1 - u0).max(1e-9)).min(0.92 * h as f64 / (v1 - v0).max(1e-9));
        let offset = (
            x0 as f64 + 0.5 * w as f64 - scale * 0.5 * (u0 + u1),
            y0 as f64 + 0.5 * h as f64 - scale * 0.5 * (v0 + v1),
        );
        View { scale, offset }
    }

    fn px(&self, p: [f64; 3]) -> (i32, i32) {
        let (u, v) = View::raw(p);
        (
            (self.offset.0 + self.scale * u).round() as i32,
            (self.offset.1 + self.scale * v).round() as i32,
        )
    }
}

/// A solid drawn for a deposit, in mm: a block's box, or a segment of a bead.
struct Prism {
    /// The deposit (block or node index) it belongs to.
    owner: usize,
    /// The footprint, counter-clockwise.
    corners: [[f64; 2]; 4],
    z: [f64; 2],
    /// Drawn in increasing order of this (back to front).
    key: [f64; 4],
}

impl Prism {
    fn points(&self) -> impl Iterator<Item = [f64; 3]> + '_ {
        self.z
            .iter()
            .flat_map(move |&z| self.corners.iter().map(move |c| [c[0], c[1], z]))
    }
}

/// The prisms of every deposit: a cube part's blocks as boxes, a graph part's nodes as
/// their pieces of bead (one prism per segment of the centre line).
fn prisms(part: &Part) -> Vec<Prism> {
    let Some(beads) = part.bead_part() else {
        let (o, mm) = (part.origin_mm, part.block_mm);
        return (0..part.len())
            .map(|i| {
                let b = part.block(i);
                let lo: [f64; 3] = std::array::from_fn(|d| o[d] + b[d] as f64 * mm[d]);
                let hi: [f64; 3] = std::array::from_fn(|d| lo[d] + mm[d]);
                Prism {
                    owner: i,
                    corners: [
                        [lo[0], lo[1]],
                        [hi[0], lo[1]],
                        [hi[0], hi[1]],
                        [lo[0], hi[1]],
                    ],
                    z: [lo[2], hi[2]],
                    key: [
                        (b[0] + b[1] + b[2]) as f64,
                        b[2] as f64,
                        b[0] as f64,
                        b[1] as f64,
                    ],
                }
            })
            .collect();
    };
    let [w, h] = beads.bead_mm;
    let mut out = Vec::new();
    for (i, d) in beads.nodes.iter().enumerate() {
        let z0 = beads.base_z_mm + d.layer as f64 * h;
        let piece = beads.beads[d.bead].piece_mm(d.from_mm, d.to_mm);
        for seg in piece.windows(2) {
            let (p, q) = (seg[0], seg[1]);
            let len = (q[0] - p[0]).hypot(q[1] - p[1]);
            if len < 1e-9 {
                continue;
            }
            // To the right of the travel direction, half a bead width.
            let r = [
                0.5 * w * (q[1] - p[1]) / len,
                -0.5 * w * (q[0] - p[0]) / len,
            ];
            let (cx, cy, cz) = (0.5 * (p[0] + q[0]), 0.5 * (p[1] + q[1]), z0 + 0.5 * h);
            out.push(Prism {
                owner: i,
                corners: [
                    [p[0] + r[0], p[1] + r[1]],
                    [q[0] + r[0], q[1] + r[1]],
                    [q[0] - r[0], q[1] - r[1]],
                    [p[0] - r[0], p[1] - r[1]],
                ],
                z: [z0, z0 + h],
                key: [cx + cy + cz, cz, cx, cy],
            });
        }
    }
    out
}

/// The top centre of deposit `i`, mm: where its number goes.
fn top_mm(part: &Part, i: usize) -> [f64; 3] {
    let c = part.centre_mm(part.block(i));
    let half = match part.bead_part() {
        Some(b) => 0.5 * b.bead_mm[1],
        None => 0.5 * part.block_mm[2],
    };
    [c[0], c[1], c[2] + half]
}

/// What the pictures call a deposit ("blocks", "nodes").
fn deposits(part: &Part) -> &'static str {
    match part.bead_part() {
        Some(_) => "nodes",
        None => "blocks",
    }
}

/// A deposit in a short label: `[x,y,z]` for a block, `node 12`.
fn short_name(part: &Part, i: usize) -> String {
    match part.bead_part() {
        Some(_) => format!("node {i}"),
        None => BlockDisplay(part.block(i)).to_string(),
    }
}

fn shade(c: RGBColor, f: f64) -> RGBColor {
    let s = |v: u8| (v as f64 * f).round().clamp(0.0, 255.0) as u8;
    RGBColor(s(c.0), s(c.1), s(c.2))
}

fn mix(a: RGBColor, b: RGBColor, t: f64) -> RGBColor {
    let m = |x: u8, y: u8| (x as f64 + (y as f64 - x as f64) * t).round() as u8;
    RGBColor(m(a.0, b.0), m(a.1, b.1), m(a.2, b.2))
}

/// A drawing backend's complaint; the caller names the file in its `PlotError`.
struct Reason(String);

impl From<String> for Reason {
    fn from(message: String) -> Self {
        Reason(message)
    }
}

/// Draws the deposits with a colour (`None`: not drawn) back to front; returns the pixel
/// centre of each drawn deposit's top.
fn draw_blocks<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    part: &Part,
    prisms: &[Prism],
    view: &View,
    colours: &[Option<RGBColor>],
) -> Result<Vec<Option<(i32, i32)>>, Reason> {
    let e = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    // The plate: the part's footprint and a block (bead) width around it, under its foot.
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    let zmin = prisms.iter().map(|p| p.z[0]).fold(f64::INFINITY, f64::min);
    for c in prisms.iter().flat_map(|p| p.corners) {
        (x0, x1, y0, y1) = (x0.min(c[0]), x1.max(c[0]), y0.min(c[1]), y1.max(c[1]));
    }
    if x0 <= x1 {
        let [mx, my, _] = part.block_mm;
        let (fx0, fx1, fy0, fy1) = (x0 - mx, x1 + mx, y0 - my, y1 + my);
        let plate = vec![
            view.px([fx0, fy0, zmin]),
            view.px([fx1, fy0, zmin]),
            view.px([fx1, fy1, zmin]),
            view.px([fx0, fy1, zmin]),
        ];
        area.draw(&Polygon::new(plate, RGBColor(225, 225, 225).filled()))
            .map_err(e)?;
    }
    let mut order: Vec<&Prism> = prisms
        .iter()
        .filter(|p| colours[p.owner].is_some())
        .collect();
    order.sort_by(|a, b| {
        a.key
            .iter()
            .zip(&b.key)
            .map(|(x, y)| x.total_cmp(y))
            .find(|o| o.is_ne())
            .unwrap_or(std::cmp::Ordering::Equal)
    });
    let mut tops = vec![None; part.len()];
    let edge = RGBColor(40, 40, 40).mix(0.55);
    for prism in order {
        let c = colours[prism.owner].expect("filtered");
        let [z0, z1] = prism.z;
        let k = prism.corners;
        // The top, then the sides that face the viewer (outward normal towards +x+y),
        // shaded by their normal: +x 0.78, +y 0.6.
        let mut faces = vec![(
            k.iter()
                .map(|p| view.px([p[0], p[1], z1]))
                .collect::<Vec<_>>(),
            1.0,
        )];
        for j in 0..4 {
            let (a, b) = (k[j], k[(j + 1) % 4]);
            let (nx, ny) = (b[1] - a[1], a[0] - b[0]);
            let len = nx.hypot(ny);
            if len < 1e-12 || nx + ny <= 1e-9 * len {
                continue;
            }
            let pts = vec![
                view.px([a[0], a[1], z0]),
                view.px([b[0], b[1], z0]),
                view.px([b[0], b[1], z1]),
                view.px([a[0], a[1], z1]),
            ];
            faces.push((pts, 0.6 + 0.18 * (nx / len).powi(2)));
        }
        for (pts, f) in faces {
            area.draw(&Polygon::new(pts.clone(), shade(c, f).filled()))
                .map_err(e)?;
            let mut closed = pts;
            closed.push(closed[0]);
            area.draw(&PathElement::new(closed, edge)).map_err(e)?;
        }
        tops[prism.owner] = Some(view.px(top_mm(part, prism.owner)));
    }
    Ok(tops)
}

/// Whether each deposit is under a drawn one: a block with one on top of it, a node that
/// a drawn node stands on (its number would be hidden).
fn covered(part: &Part, colours: &[Option<RGBColor>]) -> Vec<bool> {
    let mut out = vec![false; part.len()];
    match part.bead_part() {
        Some(beads) => {
            let moves = beads.moves();
            for j in (0..part.len()).filter(|&j| colours[j].is_some()) {
                for &u in moves.stands_on(j) {
                    out[u as usize] = true;
                }
            }
        }
        None => {
            for (i, c) in out.iter_mut().enumerate() {
                let b = part.block(i);
                *c = part
                    .index_of([b[0], b[1], b[2] + 1])
                    .is_some_and(|above| colours[above].is_some());
            }
        }
    }
    out
}

/// Small x/y/z arrows in a corner, so the view can be matched with the part file.
fn draw_axes<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    at: (i32, i32),
) -> Result<(), Reason> {
    let e = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    for (axis, name) in ["x", "y", "z"].iter().enumerate() {
        let mut p = [0.0; 3];
        p[axis] = 1.0;
        let (u, v) = View::raw(p);
        let end = (
            at.0 + (28.0 * u).round() as i32,
            at.1 + (28.0 * v).round() as i32,
        );
        area.draw(&PathElement::new(vec![at, end], BLACK.stroke_width(2)))
            .map_err(e)?;
        let label = (
            end.0 + (8.0 * u).round() as i32 - 4,
            end.1 + (8.0 * v).round() as i32 - 8,
        );
        area.draw(&Text::new(name.to_string(), label, (FONT, 16)))
            .map_err(e)?;
    }
    Ok(())
}

/// The colour of the top face of the `k`-th of `len` blocks of weld path `f` in
/// `plan3d.png`: the path's hue, light for the first block, dark for the last.
pub fn path_colour(f: usize, k: usize, len: usize) -> RGBColor {
    let base = PATH_COLOURS[f % PATH_COLOURS.len()];
    let t = k as f64 / (len.max(2) - 1) as f64;
    mix(mix(base, WHITE, 0.6), shade(base, 0.6), t)
}

/// Draws `plan3d.png`: every block as a box coloured by its weld path (hue) and its place
/// in the path (light = early, dark = late), arc starts numbered in weld order.
pub fn plan_png(part: &Part, fragments: &[Vec<usize>], path: &Path) -> Result<(), PlotError> {
    font();
    let err = draw_err(path);
    crate::png(path, PLAN_SIZE, &err, |root| {
        root.fill(&WHITE).map_err(|e| err(e.to_string()))?;
        let title = format!(
            "{}: {} {} in {} weld path(s) — colour = path, light → dark = weld order",
            part.name,
            part.len(),
            deposits(part),
            fragments.len()
        );
        root.draw(&Text::new(title, (20, 12), (FONT, 20)))
            .map_err(|e| err(e.to_string()))?;
        let legend_w = 250;
        let prisms = prisms(part);
        let view = View::fit(
            &prisms,
            (10, 50),
            (PLAN_SIZE.0 - legend_w - 20, PLAN_SIZE.1 - 60),
        );
        let mut colours = vec![None; part.len()];
        for (f, fragment) in fragments.iter().enumerate() {
            for (k, &b) in fragment.iter().enumerate() {
                colours[b] = Some(path_colour(f, k, fragment.len()));
            }
        }
        let tops = draw_blocks(root, part, &prisms, &view, &colours).map_err(|r| err(r.0))?;
        // Arc starts: a numbered disc on the first block of every path.
        for (f, fragment) in fragments.iter().enumerate() {
            let Some(Some(c)) = fragment.first().map(|&b| tops[b]) else {
                continue;
            };
            root.draw(&Circle::new(c, 11, WHITE.filled()))
                .and_then(|_| root.draw(&Circle::new(c, 11, BLACK.stroke_width(2))))
                .and_then(|_| {
                    root.draw(&Text::new(
                        format!("{}", f + 1),
                        (c.0 - 5, c.1 - 9),
                        (FONT, 16).into_font().color(&BLACK),
                    ))
                })
                .map_err(|e| err(e.to_string()))?;
        }
        // Legend: one gradient bar per path.
        let x = (PLAN_SIZE.0 - legend_w) as i32;
        let mut y = 70;
        for (f, fragment) in fragments.iter().enumerate() {
            let start = fragment.first().map(|&b| short_name(part, b));
            root.draw(&Text::new(
                format!("path {}: {} {}", f + 1, fragment.len(), deposits(part)),
                (x, y),
                (FONT, 16),
            ))
            .map_err(|e| err(e.to_string()))?;
            for k in 0..160 {
                let c = path_colour(f, k as usize, 160);
                root.draw(&Rectangle::new(
                    [(x + k, y + 22), (x + k + 1, y + 36)],
                    c.filled(),
                ))
                .map_err(|e| err(e.to_string()))?;
            }
            root.draw(&Text::new(
                format!("arc start {} at {}", f + 1, start.unwrap_or_default()),
                (x, y + 40),
                (FONT, 13),
            ))
            .map_err(|e| err(e.to_string()))?;
            y += 72;
        }
        let last = format!(
            "first → last {}",
            &deposits(part)[..deposits(part).len() - 1]
        );
        root.draw(&Text::new(last, (x, y), (FONT, 13)))
            .map_err(|e| err(e.to_string()))?;
        draw_axes(root, (x + 40, PLAN_SIZE.1 as i32 - 60)).map_err(|r| err(r.0))?;
        Ok(())
    })
}

/// The temperatures of one moment of the build.
#[derive(Debug, Clone)]
pub struct Frame {
    /// Simulated time, s.
    pub time_s: f64,
    /// Blocks welded so far.
    pub welded: usize,
    /// Whether the cooldown after the last block has run.
    pub cooled: bool,
    /// Temperature of every block (part index), °C; NaN while not welded.
    pub temps: Vec<f64>,
}

/// A windowed block's t8/5 time (once it has crossed 500 °C) against its window.
#[derive(Debug, Clone, Copy)]
pub struct WindowedT85 {
    pub block: usize,
    pub window: Window,
    /// (time of the crossing s, t8/5 s) of every 500 °C crossing, the last one counts.
    pub t85_s: Option<(f64, f64)>,
}

/// The build of a plan, simulated with the part's thermal model: frames after evenly
/// spaced deposits (and after the cooldown), and the t8/5 time of every windowed block.
#[derive(Debug, Clone)]
pub struct HeatBuild {
    pub frames: Vec<Frame>,
    pub windowed: Vec<WindowedT85>,
    /// The deposit temperature, °C (the top of the colour bar).
    pub deposit_c: f64,
    pub ambient_c: f64,
}

impl HeatBuild {
    /// The t8/5 values known at `time_s` (crossings up to then).
    fn t85_at(&self, w: &WindowedT85, time_s: f64) -> Option<f64> {
        w.t85_s.filter(|&(at, _)| at <= time_s).map(|(_, v)| v)
    }
}

/// Simulates `fragments` of `part` and keeps `frames` snapshots after evenly spaced
/// deposits (the last right after the last block) plus one after the cooldown. An
/// infeasible plan is followed to its end all the same (windows are not judged here).
pub fn heat_build(part: &Part, fragments: &[Vec<usize>], frames: usize) -> HeatBuild {
    heat_build_until(part, fragments, frames, &Interrupt::default())
        .expect("a simulation without deadline or cancel runs to its end")
}

/// [`heat_build`], stopped by `interrupt`: `None` then.
pub fn heat_build_until(
    part: &Part,
    fragments: &[Vec<usize>],
    frames: usize,
    interrupt: &Interrupt,
) -> Option<HeatBuild> {
    let graph = WeldGraph::new(part);
    let model = ThermalModel::new(part, &graph);
    let mut sim = Simulation::new(&model)
        .recording()
        .interrupted_by(interrupt);
    let total: usize = fragments.iter().map(Vec::len).sum();
    let frames = frames.clamp(1, total.max(1));
    let at: Vec<usize> = (1..=frames).map(|k| (k * total).div_ceil(frames)).collect();
    let mut out = Vec::new();
    let snap = |sim: &Simulation, cooled: bool| {
        let mut temps = vec![f64::NAN; part.len()];
        for (b, t) in sim.temperatures() {
            temps[b] = t;
        }
        Frame {
            time_s: sim.time_s(),
            welded: sim.welded(),
            cooled,
            temps,
        }
    };
    let mut done = 0;
    for fragment in fragments {
        for (p, &b) in fragment.iter().enumerate() {
            // A violation does not stop the picture: keep depositing.
            let _ = sim.deposit(b, p == 0);
            if sim.cancelled() {
                return None;
            }
            done += 1;
            if at.contains(&done) {
                out.push(snap(&sim, false));
            }
        }
    }
    if total > 0 {
        let _ = sim.finish();
        if sim.cancelled() {
            return None;
        }
        out.push(snap(&sim, true));
    }
    let windowed = part
        .windows()
        .iter()
        .map(|&(block, window)| WindowedT85 {
            block,
            window,
            t85_s: sim
                .crossings()
                .iter()
                .rfind(|c| c.block == block)
                .map(|c| (c.time_s, c.t85_s)),
        })
        .collect();
    Some(HeatBuild {
        frames: out,
        windowed,
        deposit_c: part.thermal.deposit_c,
        ambient_c: part.thermal.ambient_c,
    })
}

/// The temperature colour map: ambient dark blue, through purple and red (500 °C) and
/// orange (800 °C) to pale yellow at the deposit temperature.
fn heat_map() -> DerivedColorMap<RGBColor> {
    DerivedColorMap::new(&[
        RGBColor(20, 30, 110),
        RGBColor(120, 40, 150),
        RGBColor(215, 50, 60),
        RGBColor(250, 140, 20),
        RGBColor(255, 235, 120),
        RGBColor(255, 255, 235),
    ])
}

fn heat_colour(build: &HeatBuild, t: f64) -> RGBColor {
    let lo = build.ambient_c;
    let hi = build.deposit_c.max(lo + 1.0);
    heat_map().get_color(((t - lo) / (hi - lo)).clamp(0.0, 1.0))
}

/// One 3-D view of a frame; windowed blocks numbered as in the table.
fn draw_frame<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    part: &Part,
    build: &HeatBuild,
    frame: &Frame,
    (w, h): (u32, u32),
    title_size: u32,
) -> Result<(), Reason> {
    let e = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    let caption = if frame.cooled {
        format!("after the cooldown, t = {:.0} s", frame.time_s)
    } else {
        format!(
            "{} of {} {} welded, t = {:.0} s",
            frame.welded,
            part.len(),
            deposits(part),
            frame.time_s
        )
    };
    area.draw(&Text::new(caption, (12, 6), (FONT, title_size)))
        .map_err(e)?;
    let prisms = prisms(part);
    let view = View::fit(
        &prisms,
        (0, title_size as i32 + 10),
        (w, h - title_size - 14),
    );
    let colours: Vec<Option<RGBColor>> = frame
        .temps
        .iter()
        .map(|&t| t.is_finite().then(|| heat_colour(build, t)))
        .collect();
    let tops = draw_blocks(area, part, &prisms, &view, &colours)?;
    let covered = covered(part, &colours);
    for (k, wt) in build.windowed.iter().enumerate() {
        let Some(c) = tops[wt.block] else { continue };
        // A deposit under a welded one is hidden: its number is in the table only.
        if covered[wt.block] {
            continue;
        }
        let ok = build
            .t85_at(wt, frame.time_s)
            .map(|v| v >= wt.window.min_s && v <= wt.window.max_s);
        let ring = match ok {
            Some(true) => RGBColor(0, 150, 60),
            Some(false) => RGBColor(200, 0, 0),
            None => BLACK,
        };
        area.draw(&Circle::new(c, 8, WHITE.mix(0.85).filled()))
            .map_err(e)?;
        area.draw(&Circle::new(c, 8, ring.stroke_width(2)))
            .map_err(e)?;
        let label = format!("{}", k + 1);
        let dx = if k + 1 >= 10 { 7 } else { 3 };
        area.draw(&Text::new(label, (c.0 - dx, c.1 - 6), (FONT, 11)))
            .map_err(e)?;
    }
    Ok(())
}

/// The colour bar (with the 500 and 800 °C marks) and the t8/5 table at `time_s`.
fn draw_side<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    build: &HeatBuild,
    part: &Part,
    time_s: f64,
) -> Result<(), Reason> {
    let e = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    let (x, top, bar_h) = (20, 40, 180);
    area.draw(&Text::new("temperature (°C)", (x, 12), (FONT, 15)))
        .map_err(e)?;
    let (lo, hi) = (build.ambient_c, build.deposit_c.max(build.ambient_c + 1.0));
    let y_of = |t: f64| top + bar_h - ((t - lo) / (hi - lo) * bar_h as f64).round() as i32;
    for k in 0..bar_h {
        let t = lo + (hi - lo) * (k as f64 + 0.5) / bar_h as f64;
        let y = top + bar_h - k - 1;
        area.draw(&Rectangle::new(
            [(x, y), (x + 26, y + 1)],
            heat_colour(build, t).filled(),
        ))
        .map_err(e)?;
    }
    area.draw(&Rectangle::new([(x, top), (x + 26, top + bar_h)], BLACK))
        .map_err(e)?;
    for (t, label) in [
        (hi, format!("{hi:.0}")),
        (HOT_C, "800 (t8/5 starts)".to_string()),
        (WARM_C, "500 (t8/5 ends)".to_string()),
        (lo, format!("{lo:.0}")),
    ] {
        let y = y_of(t);
        area.draw(&PathElement::new(vec![(x + 26, y), (x + 34, y)], BLACK))
            .map_err(e)?;
        area.draw(&Text::new(label, (x + 38, y - 7), (FONT, 13)))
            .map_err(e)?;
    }
    let mut y = top + bar_h + 24;
    if build.windowed.is_empty() {
        area.draw(&Text::new("no t8/5 windows", (x, y), (FONT, 14)))
            .map_err(e)?;
        return Ok(());
    }
    area.draw(&Text::new("t8/5 (s) vs window", (x, y), (FONT, 15)))
        .map_err(e)?;
    y += 22;
    let row_h = ((area.dim_in_pixel().1 as i32 - y - 8) / build.windowed.len() as i32).clamp(9, 19);
    let size = (row_h - 4).clamp(9, 14) as u32;
    for (k, wt) in build.windowed.iter().enumerate() {
        let (text, colour) = match build.t85_at(wt, time_s) {
            Some(v) => {
                let ok = v >= wt.window.min_s && v <= wt.window.max_s;
                (
                    format!(
                        "{:>2} {} {v:.1} in [{}, {}]{}",
                        k + 1,
                        short_name(part, wt.block),
                        wt.window.min_s,
                        wt.window.max_s,
                        if ok { "" } else { " BROKEN" }
                    ),
                    if ok {
                        RGBColor(0, 120, 50)
                    } else {
                        RGBColor(200, 0, 0)
                    },
                )
            }
            None => (
                format!(
                    "{:>2} {} – [{}, {}]",
                    k + 1,
                    short_name(part, wt.block),
                    wt.window.min_s,
                    wt.window.max_s
                ),
                RGBColor(90, 90, 90),
            ),
        };
        area.draw(&Text::new(
            text,
            (x, y),
            (FONT, size).into_font().color(&colour),
        ))
        .map_err(e)?;
        y += row_h;
    }
    Ok(())
}

/// Draws `heat.png`: four stages of the build (a quarter, half, three quarters of the
/// blocks welded, and after the cooldown) coloured by temperature, the colour bar, and
/// every windowed block's final t8/5 time against its window (green kept, red broken).
pub fn heat_png(part: &Part, build: &HeatBuild, path: &Path) -> Result<(), PlotError> {
    font();
    let err = draw_err(path);
    crate::png(path, HEAT_SIZE, &err, |root| {
        root.fill(&WHITE).map_err(|e| err(e.to_string()))?;
        root.draw(&Text::new(
            format!(
                "{}: temperatures during the build (thermal model)",
                part.name
            ),
            (20, 10),
            (FONT, 22),
        ))
        .map_err(|e| err(e.to_string()))?;
        let (main, side) = root.split_horizontally(HEAT_SIZE.0 - SIDE_W);
        let main = main.margin(40, 0, 0, 0);
        let side = side.margin(40, 0, 0, 0);
        let n = build.frames.len();
        let pick: Vec<&Frame> = if n == 0 {
            Vec::new()
        } else {
            let mut idx: Vec<usize> = [n / 4, n / 2, 3 * n / 4]
                .iter()
                .map(|&k| k.saturating_sub(1).min(n - 1))
                .collect();
            idx.push(n - 1);
            idx.dedup();
            idx.iter().map(|&k| &build.frames[k]).collect()
        };
        let (w, h) = main.dim_in_pixel();
        let panels = main.split_evenly((2, 2));
        for (panel, frame) in panels.iter().zip(pick) {
            draw_frame(panel, part, build, frame, (w / 2, h / 2), 16).map_err(|r| err(r.0))?;
        }
        let end = build.frames.last().map_or(0.0, |f| f.time_s);
        draw_side(&side, build, part, end).map_err(|r| err(r.0))?;
        Ok(())
    })
}

/// Draws `heat.gif`: one frame per entry of `build.frames` (`delay_ms` apart; the last
/// held three times as long), coloured by temperature, with the colour bar and the t8/5
/// times known at that moment.
pub fn heat_gif(
    part: &Part,
    build: &HeatBuild,
    path: &Path,
    delay_ms: u32,
) -> Result<(), PlotError> {
    font();
    let err = draw_err(path);
    let file = File::create(path).map_err(|e| err(e.to_string()))?;
    let (w, h) = (GIF_SIZE.0 as u16, GIF_SIZE.1 as u16);
    let mut gif =
        gif::Encoder::new(BufWriter::new(file), w, h, &[]).map_err(|e| err(e.to_string()))?;
    gif.set_repeat(gif::Repeat::Infinite)
        .map_err(|e| err(e.to_string()))?;
    let mut rgb = vec![0; 3 * GIF_SIZE.0 as usize * GIF_SIZE.1 as usize];
    let n = build.frames.len();
    for (k, frame) in build.frames.iter().enumerate() {
        {
            let root = BitMapBackend::with_buffer(&mut rgb, GIF_SIZE).into_drawing_area();
            root.fill(&WHITE).map_err(|e| err(e.to_string()))?;
            let (main, side) = root.split_horizontally(GIF_SIZE.0 - SIDE_W);
            let (w, h) = main.dim_in_pixel();
            draw_frame(&main, part, build, frame, (w, h), 20).map_err(|r| err(r.0))?;
            draw_side(&side, build, part, frame.time_s).map_err(|r| err(r.0))?;
            root.present().map_err(|e| err(e.to_string()))?;
        }
        // Quantized to 256 colours as plotters' GIF backend did (speed 10 of 1..=30).
        let mut image = gif::Frame::from_rgb_speed(w, h, &rgb, 10);
        image.delay = ((delay_ms + 5) / 10) as u16; // GIF counts in 1/100 s
        let repeats = if k + 1 == n { 3 } else { 1 };
        for _ in 0..repeats {
            gif.write_frame(&image).map_err(|e| err(e.to_string()))?;
        }
    }
    Ok(())
}
