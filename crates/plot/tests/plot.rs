//! The temperature curves are the thermal model's own temperatures.

mod common;

use waam_part::graph::WeldGraph;
use waam_thermal::{simulate, Simulation, ThermalModel};

#[test]
fn temperature_curves_follow_the_thermal_model() {
    for name in ["s3-ring", "s7-pad", "ex3-h-column"] {
        let (part, fragments) = common::part_and_plan(name);
        let curves = waam_plot::temperature_curves(&part, &fragments);
        assert_eq!(curves.len(), part.windows().len());
        let graph = WeldGraph::new(&part);
        let model = ThermalModel::new(&part, &graph);
        // While depositing, the samples are exactly the model's temperatures (an
        // infeasible plan is followed up to its first violation).
        let mut sim = Simulation::new(&model);
        'plan: for fragment in &fragments {
            for (p, &b) in fragment.iter().enumerate() {
                if sim.deposit(b, p == 0).is_err() {
                    break 'plan;
                }
                for (blk, t) in sim.temperatures() {
                    if let Some(c) = curves.iter().find(|c| c.block == part.block(blk)) {
                        let s = c.samples.iter().find(|s| s.0 == sim.time_s());
                        assert_eq!(
                            s.map(|s| s.1),
                            Some(t),
                            "{name} {:?} at {}",
                            c.block,
                            sim.time_s()
                        );
                    }
                }
            }
        }
        // Every curve ends below 500 °C, after the model's last t8/5 crossing of its block.
        let outcome = simulate(&model, &fragments).unwrap();
        for c in &curves {
            assert!(c.samples.windows(2).all(|w| w[1].0 > w[0].0));
            assert!(c.samples.last().unwrap().1 < 500.0, "{name} {:?}", c.block);
            let last_hot = c.samples.iter().rev().find(|s| s.1 >= 500.0).unwrap().0;
            let b = part.index_of(c.block).unwrap();
            if let Some(x) = outcome.crossings.iter().rfind(|x| x.block == b) {
                assert!(last_hot < x.time_s, "{name} {:?}", c.block);
            }
        }
    }
}

/// The build pictures' temperatures and t8/5 times are the thermal model's.
#[test]
fn heat_build_frames_follow_the_thermal_model() {
    // A feasible plan (the stored plans of the larger parts break a window).
    let (part, fragments) = common::part_and_plan("s3-ring");
    let build = waam_plot::blocks::heat_build(&part, &fragments, 8);
    // Eight stages of the build, then one after the cooldown.
    assert_eq!(build.frames.len(), 9);
    let last = build.frames.last().unwrap();
    assert!(
        last.cooled && last.welded == part.len(),
        "{} {} {}",
        last.cooled,
        last.welded,
        part.len()
    );
    for w in build.frames.windows(2) {
        assert!(w[1].welded > w[0].welded || w[1].cooled);
        assert!(w[1].time_s > w[0].time_s);
    }
    for f in &build.frames {
        let hot = f.temps.iter().filter(|t| t.is_finite()).count();
        assert_eq!(hot, f.welded);
        assert!(f.temps.iter().flatten_finite_max() <= part.thermal.deposit_c);
    }
    assert_eq!(build.frames[7].welded, part.len());
    // The t8/5 times are the last crossings of the model's own simulation.
    let graph = WeldGraph::new(&part);
    let model = ThermalModel::new(&part, &graph);
    let outcome = simulate(&model, &fragments).unwrap();
    assert!(outcome.violation.is_none());
    assert_eq!(build.windowed.len(), part.windows().len());
    for w in &build.windowed {
        let x = outcome
            .crossings
            .iter()
            .rfind(|x| x.block == w.block)
            .unwrap();
        assert_eq!(w.t85_s, Some((x.time_s, x.t85_s)));
        assert!(x.t85_s >= w.window.min_s && x.t85_s <= w.window.max_s);
    }
}

trait FiniteMax {
    fn flatten_finite_max(self) -> f64;
}

impl<'a, I: Iterator<Item = &'a f64>> FiniteMax for I {
    fn flatten_finite_max(self) -> f64 {
        self.filter(|t| t.is_finite())
            .fold(f64::MIN, |a, &b| a.max(b))
    }
}

/// plan3d.png shows every weld path in its own colour.
#[test]
fn plan_picture_shows_every_weld_path() {
    let (part, fragments) = common::part_and_plan("ex2-bracket");
    assert!(fragments.len() >= 2);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("plan3d.png");
    waam_plot::blocks::plan_png(&part, &fragments, &path).unwrap();
    let decoder = png::Decoder::new(std::fs::File::open(&path).unwrap());
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!((info.width, info.height), waam_plot::blocks::PLAN_SIZE);
    let bpp = info.color_type.samples();
    let pixels: std::collections::HashSet<[u8; 3]> = buf[..info.buffer_size()]
        .chunks(bpp)
        .map(|p| [p[0], p[1], p[2]])
        .collect();
    for (f, fragment) in fragments.iter().enumerate() {
        // Top faces are drawn in the path colour itself: some block of each path shows.
        let shown = (0..fragment.len())
            .filter(|&k| {
                let c = waam_plot::blocks::path_colour(f, k, fragment.len());
                pixels.contains(&[c.0, c.1, c.2])
            })
            .count();
        assert!(
            shown > fragment.len() / 4,
            "path {f}: {shown} of {}",
            fragment.len()
        );
    }
}

/// The distinct colours of a PNG.
fn colours(path: &std::path::Path) -> std::collections::HashSet<[u8; 3]> {
    let decoder = png::Decoder::new(std::fs::File::open(path).unwrap());
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf).unwrap();
    let bpp = info.color_type.samples();
    buf[..info.buffer_size()]
        .chunks(bpp)
        .map(|p| [p[0], p[1], p[2]])
        .collect()
}

/// A graph part is drawn as its beads: plan3d.png in the weld paths' colours, heat.png by
/// the graph model's temperatures, t85.png from that model, toolpath.png along the beads.
#[test]
fn a_graph_part_is_drawn_as_its_beads() {
    let text = std::fs::read_to_string(common::root().join("tests/data/ring-beads.yaml")).unwrap();
    let part = waam_part::Part::of_beads(waam_part::BeadPart::parse(&text).unwrap()).unwrap();
    // Two weld paths, layer by layer (pictures do not judge validity).
    let n = part.len();
    let fragments = vec![(0..n / 2).collect::<Vec<_>>(), (n / 2..n).collect()];
    let dir = tempfile::tempdir().unwrap();

    let plan3d = dir.path().join("plan3d.png");
    waam_plot::blocks::plan_png(&part, &fragments, &plan3d).unwrap();
    let pixels = colours(&plan3d);
    for (f, fragment) in fragments.iter().enumerate() {
        let shown = (0..fragment.len())
            .filter(|&k| {
                let c = waam_plot::blocks::path_colour(f, k, fragment.len());
                pixels.contains(&[c.0, c.1, c.2])
            })
            .count();
        // The top layer's beads show in full, the lower ones along their outer sides.
        assert!(
            shown >= 10,
            "path {f}: {shown} of {} colours",
            fragment.len()
        );
    }

    // The curves are the graph model's temperatures (not the stand-in blocks' model).
    let curves = waam_plot::temperature_curves(&part, &fragments);
    assert_eq!(curves.len(), part.windows().len());
    assert!(curves.iter().all(|c| c.label.starts_with("node ")));
    let graph = WeldGraph::new(&part);
    let model = ThermalModel::new(&part, &graph);
    let mut sim = Simulation::new(&model);
    let mut checked = 0;
    for fragment in &fragments {
        for (p, &b) in fragment.iter().enumerate() {
            let _ = sim.deposit(b, p == 0);
            for (c, &(w, _)) in curves.iter().zip(part.windows()) {
                let t = sim.temperatures().find(|&(i, _)| i == w).map(|(_, t)| t);
                let s = c.samples.iter().find(|s| s.0 == sim.time_s());
                if let (Some(t), Some(s)) = (t, s) {
                    assert_eq!(s.1, t);
                    checked += 1;
                }
            }
        }
    }
    assert!(checked > 100, "{checked} samples compared");
    assert!(curves.iter().all(|c| c.samples.last().unwrap().1 < 500.0));
    let t85 = dir.path().join("t85.png");
    waam_plot::t85_png(&part, &curves, &t85).unwrap();

    let build = waam_plot::blocks::heat_build(&part, &fragments, 8);
    let heat = dir.path().join("heat.png");
    waam_plot::blocks::heat_png(&part, &build, &heat).unwrap();
    // Beads at many temperatures: many shades of the colour map.
    assert!(
        colours(&heat).len() > 200,
        "{} colours",
        colours(&heat).len()
    );

    let tp = waam_motion::toolpath::toolpath_of_plan(
        &part,
        &fragments,
        &waam_motion::toolpath::ProcessSettings::default(),
        waam_motion::toolpath::ToolpathFrame::Part,
    )
    .unwrap();
    let toolpath = dir.path().join("toolpath.png");
    waam_plot::toolpath_png(&tp.to_file(), &toolpath).unwrap();
    for png in [&plan3d, &t85, &heat, &toolpath] {
        assert!(std::fs::metadata(png).unwrap().len() > 10_000, "{png:?}");
    }
}
