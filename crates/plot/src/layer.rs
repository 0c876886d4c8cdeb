//! Pictures of a planned layer: the trail (segment numbers in weld order, deadheading
//! dashed, start marked) over the meshed walls, and the temperature of one mesh node over
//! time against the target (like Figure 2 of Schmidt, Buhl & Fügenschuh 2021).
//!
//! Text is drawn with DejaVu Sans embedded from the `dejavu` crate (as the crate root
//! does), so no font has to be installed.

use std::path::{Path, PathBuf};
use std::sync::Once;

use plotters::prelude::*;
use plotters::style::FontStyle;
use thiserror::Error;

use waam_layer::model::{Model, Trail};

/// Sizes of `waam layer plot`'s trail.png and temperature.png, pixels.
pub const TRAIL_SIZE: (u32, u32) = (900, 900);
pub const TEMPERATURE_SIZE: (u32, u32) = (1000, 600);

#[derive(Debug, Error)]
pub enum PlotError {
    #[error("drawing {path}: {reason}")]
    Draw { path: PathBuf, reason: String },
    #[error("mesh node {node} does not exist (the mesh has {count} nodes)")]
    NoSuchNode { node: usize, count: usize },
}

/// Registers the label font once per process.
fn load_font() {
    static REGISTER: Once = Once::new();
    REGISTER.call_once(|| {
        // The embedded font is valid; a failure could only leave labels undrawn.
        let _ = plotters::style::register_font(
            "sans-serif",
            FontStyle::Normal,
            dejavu::sans::regular(),
        );
    });
}

fn draw_err(path: &Path) -> impl Fn(String) -> PlotError + '_ {
    move |reason| PlotError::Draw {
        path: path.to_path_buf(),
        reason,
    }
}

/// Draws the trail over the walls into a PNG of `size` pixels.
pub fn plot_trail(
    model: &Model,
    trail: &Trail,
    path: &Path,
    size: (u32, u32),
) -> Result<(), PlotError> {
    load_font();
    let err = draw_err(path);
    let pts = &model.mesh.points;
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for p in pts {
        lo = [lo[0].min(p[0]), lo[1].min(p[1])];
        hi = [hi[0].max(p[0]), hi[1].max(p[1])];
    }
    let pad = 0.05 * (hi[0] - lo[0]).max(hi[1] - lo[1]) + 1.0;
    crate::png(path, size, &err, |root| {
        root.fill(&WHITE).map_err(|e| err(e.to_string()))?;
        let mut chart = ChartBuilder::on(root)
            .caption(
                format!(
                    "{}: weld trail, {} deadheading move{}",
                    model.layer.name,
                    model.deadheads,
                    if model.deadheads == 1 { "" } else { "s" }
                ),
                ("sans-serif", 20),
            )
            .margin(10)
            .x_label_area_size(30)
            .y_label_area_size(40)
            .build_cartesian_2d(lo[0] - pad..hi[0] + pad, lo[1] - pad..hi[1] + pad)
            .map_err(|e| err(e.to_string()))?;
        chart
            .configure_mesh()
            .x_desc("x (mm)")
            .y_desc("y (mm)")
            .disable_mesh()
            .draw()
            .map_err(|e| err(e.to_string()))?;
        // The walls: the mesh's triangles, lightly.
        chart
            .draw_series(model.mesh.triangles.iter().map(|t| {
                Polygon::new(
                    t.iter()
                        .map(|&i| (pts[i][0], pts[i][1]))
                        .collect::<Vec<_>>(),
                    RGBColor(225, 225, 225).filled(),
                )
            }))
            .map_err(|e| err(e.to_string()))?;
        let mut at: Option<[f64; 2]> = None;
        for (k, m) in trail.moves.iter().enumerate() {
            let (a, b) = model.ends(m);
            let (pa, pb) = (model.layer.point(a), model.layer.point(b));
            if let (true, Some(prev)) = (m.deadhead_before, at) {
                // Dashed deadheading move.
                let dashes = 12;
                let seg: Vec<PathElement<(f64, f64)>> = (0..dashes)
                    .step_by(2)
                    .map(|i| {
                        let t0 = i as f64 / dashes as f64;
                        let t1 = (i + 1) as f64 / dashes as f64;
                        let lerp = |t: f64| {
                            (
                                prev[0] + t * (pa[0] - prev[0]),
                                prev[1] + t * (pa[1] - prev[1]),
                            )
                        };
                        PathElement::new(vec![lerp(t0), lerp(t1)], RED.stroke_width(2))
                    })
                    .collect();
                chart.draw_series(seg).map_err(|e| err(e.to_string()))?;
            }
            chart
                .draw_series(std::iter::once(PathElement::new(
                    vec![(pa[0], pa[1]), (pb[0], pb[1])],
                    BLUE.stroke_width(3),
                )))
                .map_err(|e| err(e.to_string()))?;
            // Arrow head near the end, and the weld-order number at the middle.
            let (dx, dy) = (pb[0] - pa[0], pb[1] - pa[1]);
            let len = (dx * dx + dy * dy).sqrt().max(1e-9);
            let (ux, uy) = (dx / len, dy / len);
            let tip = (pa[0] + 0.7 * dx, pa[1] + 0.7 * dy);
            let w = 0.6;
            chart
                .draw_series(std::iter::once(Polygon::new(
                    vec![
                        (tip.0 + w * ux, tip.1 + w * uy),
                        (tip.0 - w * ux - w * uy, tip.1 - w * uy + w * ux),
                        (tip.0 - w * ux + w * uy, tip.1 - w * uy - w * ux),
                    ],
                    BLUE.filled(),
                )))
                .map_err(|e| err(e.to_string()))?;
            chart
                .draw_series(std::iter::once(Text::new(
                    format!("{}", k + 1),
                    (pa[0] + 0.4 * dx - 0.8 * uy, pa[1] + 0.4 * dy + 0.8 * ux),
                    ("sans-serif", 16).into_font().color(&BLACK),
                )))
                .map_err(|e| err(e.to_string()))?;
            if k == 0 {
                chart
                    .draw_series([
                        EmptyElement::at((pa[0], pa[1])) + Circle::new((0, 0), 7, GREEN.filled())
                    ])
                    .map_err(|e| err(e.to_string()))?;
                chart
                    .draw_series(std::iter::once(Text::new(
                        "start".to_string(),
                        (pa[0] + 0.5, pa[1] - 0.5),
                        ("sans-serif", 16).into_font().color(&GREEN),
                    )))
                    .map_err(|e| err(e.to_string()))?;
            }
            at = Some(pb);
        }
        Ok(())
    })
}

/// Draws the temperature of mesh node `node` over the trail's time steps, with the target.
pub fn plot_temperature(
    model: &Model,
    trail: &Trail,
    node: usize,
    path: &Path,
    size: (u32, u32),
) -> Result<(), PlotError> {
    if node >= model.mesh.points.len() {
        return Err(PlotError::NoSuchNode {
            node,
            count: model.mesh.points.len(),
        });
    }
    load_font();
    let err = draw_err(path);
    let mut fields = Vec::new();
    model.simulate(trail, Some(&mut fields));
    let ambient = model.layer.temperatures.ambient_c;
    let dt = model.layer.process.time_step_s;
    let mut series = vec![(0.0, model.layer.temperatures.initial_c)];
    series.extend(
        fields
            .iter()
            .enumerate()
            .map(|(n, u)| ((n + 1) as f64 * dt, ambient + u[node])),
    );
    let target = model.layer.temperatures.target_c;
    let tmax = series.iter().map(|p| p.1).fold(target, f64::max) * 1.05 + 1.0;
    let tmin = series
        .iter()
        .map(|p| p.1)
        .fold(target.min(ambient), f64::min)
        - 10.0;
    let end = series.last().map_or(1.0, |p| p.0);
    crate::png(path, size, &err, |root| {
        root.fill(&WHITE).map_err(|e| err(e.to_string()))?;
        let p = model.mesh.points[node];
        let mut chart = ChartBuilder::on(root)
            .caption(
                format!(
                    "{}: temperature at mesh node {node} ({:.1}, {:.1}) mm",
                    model.layer.name, p[0], p[1]
                ),
                ("sans-serif", 20),
            )
            .margin(10)
            .x_label_area_size(35)
            .y_label_area_size(55)
            .build_cartesian_2d(0.0..end, tmin..tmax)
            .map_err(|e| err(e.to_string()))?;
        chart
            .configure_mesh()
            .x_desc("time (s)")
            .y_desc("temperature (°C)")
            .draw()
            .map_err(|e| err(e.to_string()))?;
        chart
            .draw_series(LineSeries::new(series, BLUE.stroke_width(2)))
            .map_err(|e| err(e.to_string()))?
            .label("node temperature")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLUE));
        chart
            .draw_series(LineSeries::new(vec![(0.0, target), (end, target)], RED))
            .map_err(|e| err(e.to_string()))?
            .label("target")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], RED));
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(|e| err(e.to_string()))?;
        Ok(())
    })
}
