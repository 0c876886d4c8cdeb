//! A layer trail through the block plans' motion pipeline (`plan_layer_motion`): toolpath
//! and joint trajectory, the arc off on every deadheading move, the wall named when the robot
//! cannot reach it. The recording and publishing of a layer are the CLI's tests
//! (`tests/cli/layer_motion.rs`).

mod common;

use nalgebra::Point3;
use waam_layer::output::TrailFile;
use waam_layer::plan_layer_motion;
use waam_motion::toolpath::{PoseKind, ProcessSettings};

const PAPER: &str = "config/layers/paper-16mm.yaml";

#[test]
fn the_arc_is_off_on_every_deadheading_move_and_on_along_every_wall() {
    let robot = common::our_robot();
    let settings = ProcessSettings::default();
    let plate = settings.plate.isometry();
    // A layer point (mm, z = 0) in the robot's base link (m).
    let at = |p: [f64; 2]| plate * Point3::new(p[0] / 1000.0, p[1] / 1000.0, 0.0);
    for file in [
        "config/layers/grid-4x4.yaml",
        "config/layers/honeycomb-12.yaml",
    ] {
        let model = common::layer_model(file);
        let r = common::quick_search(&model);
        let (tp, traj) = plan_layer_motion(&model, &r.trail, &settings, &robot)
            .unwrap_or_else(|e| panic!("{file}: {e}"));
        let on: Vec<usize> = (0..tp.poses.len())
            .filter(|&k| tp.poses[k].kind == PoseKind::ArcOn)
            .collect();
        let off: Vec<usize> = (0..tp.poses.len())
            .filter(|&k| tp.poses[k].kind == PoseKind::ArcOff)
            .collect();
        assert_eq!(on.len(), model.deadheads + 1, "{file}: one arc start a run");
        assert_eq!(off.len(), on.len(), "{file}");
        // The arc burns exactly from each arc-on marker to its arc-off marker: off before
        // the first pass, on every pose between one pass's end and the next one's start,
        // and after the last.
        for (k, p) in tp.poses.iter().enumerate() {
            let welding = on.iter().zip(&off).any(|(&a, &b)| a <= k && k < b);
            assert_eq!(p.arc_on, welding, "{file}: pose {k} ({:?})", p.kind);
        }
        // Those arc-off gaps are the trail's deadheading moves: each leaves the node where
        // the run before it ends and reaches the node where the next run starts.
        let file_of_trail = TrailFile::new(&model, &r.trail, r.objective, r.lower_bound, false);
        assert_eq!(file_of_trail.deadheading.len(), model.deadheads);
        let node = |id: &str| {
            let v = model.layer.nodes.iter().position(|n| n.id == id).unwrap();
            at(model.layer.point(v))
        };
        let near = |k: usize, p: Point3<f64>| {
            (tp.poses[k].pose.translation.vector - p.coords).norm() < 1e-9
        };
        for (f, d) in file_of_trail.deadheading.iter().enumerate() {
            assert!(
                near(off[f], node(&d.from)),
                "{file}: gap {f} from {}",
                d.from
            );
            assert!(near(on[f + 1], node(&d.to)), "{file}: gap {f} to {}", d.to);
        }
        // Every point of every welded wall (one a time step) is passed with the arc on.
        for m in &r.trail.moves {
            let (a, b) = model.ends(m);
            let (pa, pb) = (model.layer.point(a), model.layer.point(b));
            let n = model.steps[m.segment];
            for k in 0..=n {
                let t = k as f64 / n as f64;
                let p = at([pa[0] + t * (pb[0] - pa[0]), pa[1] + t * (pb[1] - pa[1])]);
                assert!(
                    (0..tp.poses.len()).any(|q| tp.poses[q].arc_on && near(q, p)),
                    "{file}: {} step {k} not welded",
                    model.layer.segment_name(m.segment)
                );
            }
        }
        // The torch welds at the layer's weld speed (what the heat model assumed), plus the
        // dwells at each arc start and end.
        let arc_s: f64 = tp
            .poses
            .windows(2)
            .filter(|w| w[0].arc_on)
            .map(|w| w[1].time_s - w[0].time_s)
            .sum();
        let length: f64 = (0..model.layer.segments.len())
            .map(|s| model.layer.length(s))
            .sum();
        let expected = length / model.layer.process.weld_speed_mm_s
            + on.len() as f64 * (settings.arc_on_dwell_s + settings.arc_off_dwell_s);
        assert!(
            (arc_s - expected).abs() < 1e-6,
            "{file}: {arc_s} s vs {expected} s"
        );
        // The validated trajectory spans the whole toolpath.
        let end = traj.points.last().unwrap().time_from_start;
        assert!(
            (end - tp.poses.last().unwrap().time_s).abs() < 1e-9,
            "{file}"
        );
    }
}

#[test]
fn an_unreachable_layer_names_the_wall_and_gives_no_motion() {
    let model = common::layer_model(PAPER);
    let r = common::quick_search(&model);
    let mut settings = ProcessSettings::default();
    settings.plate.position_m = [3.0, 0.0, 0.35]; // beyond the arm's 1.2 m reach
    let e = plan_layer_motion(&model, &r.trail, &settings, &common::our_robot())
        .unwrap_err()
        .to_string();
    // The first pose (the transit to the first wall) is already out of reach.
    let wall = model.layer.segment_name(r.trail.moves[0].segment);
    assert!(e.contains("unreachable") && e.contains(&wall), "{e}");
}
