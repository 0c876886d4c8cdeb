//! The robot welds a graph part along its beads (#29): the validated joint trajectory,
//! through the robot's forward kinematics, keeps the torch on the bead's centre line; the
//! plan is checked on the executed time line and the torch on the beads' geometry.

mod common;

use std::f64::consts::TAU;

use common::our_robot;
use waam_motion::toolpath::ProcessSettings;
use waam_part::{Bead, BeadPart, Contact, ContactKind, Deposit, Part, ThermalParams};
use waam_pipeline::{Cell, ChosenPlan, Options, PipelineError};

const R: f64 = 30.0;
const W: f64 = 6.0;
const H: f64 = 2.5;

/// `layers` rings of radius R (256 vertices: the polygon is within 0.01 mm of the circle),
/// cut into pieces of about W; contacts along each ring and stacked between the pieces
/// one above the other (and their neighbours).
fn rings(layers: u32) -> Part {
    let points: Vec<[f64; 2]> = (0..256)
        .map(|i| {
            let a = TAU * i as f64 / 256.0;
            [R * a.cos(), R * a.sin()]
        })
        .collect();
    let mut beads = Vec::new();
    let mut nodes = Vec::new();
    let mut contacts = Vec::new();
    let mut n = 0;
    for layer in 0..layers {
        let bead = Bead {
            layer,
            closed: true,
            points: points.clone(),
        };
        let len = bead.length_mm();
        n = (len / W).round() as usize;
        let first = nodes.len();
        for i in 0..n {
            let (from_mm, to_mm) = (len * i as f64 / n as f64, len * (i + 1) as f64 / n as f64);
            let piece = bead.piece_mm(from_mm, to_mm);
            let c = piece[piece.len() / 2];
            nodes.push(Deposit {
                bead: layer as usize,
                from_mm,
                to_mm,
                layer,
                centre_mm: [c[0], c[1], (layer as f64 + 0.5) * H],
                volume_mm3: W * H * (to_mm - from_mm),
                surface_mm2: 2.0 * (to_mm - from_mm) * (W + H),
                substrate_mm2: if layer == 0 {
                    W * (to_mm - from_mm)
                } else {
                    0.0
                },
            });
        }
        for i in 0..n {
            let (a, b) = (first + i, first + (i + 1) % n);
            contacts.push(Contact {
                a: a.min(b),
                b: a.max(b),
                area_mm2: W * H,
                kind: ContactKind::Along,
            });
            if layer > 0 {
                for d in [n - 1, 0, 1] {
                    contacts.push(Contact {
                        a: first - n + (i + d) % n,
                        b: first + i,
                        area_mm2: if d == 0 { W * W } else { 1.0 },
                        kind: ContactKind::Stacked,
                    });
                }
            }
        }
        beads.push(bead);
    }
    contacts.sort_by_key(|c| (c.a, c.b));
    let part = BeadPart {
        name: "ring".into(),
        max_fragments: 2,
        bead_mm: [W, H],
        base_z_mm: 0.0,
        beads,
        nodes,
        contacts,
        windows: Vec::new(),
        thermal: ThermalParams::default(),
        warnings: Vec::new(),
    };
    // What the reader accepts: the part written and read back.
    let part = BeadPart::parse(&part.to_yaml()).unwrap();
    assert_eq!(part.nodes.len(), n * layers as usize);
    Part::of_beads(part).unwrap()
}

fn cell() -> Cell {
    Cell {
        settings: ProcessSettings::default(),
        robot: our_robot(),
    }
}

fn chosen(fragments: Vec<Vec<usize>>) -> ChosenPlan {
    ChosenPlan {
        fragments,
        stats: Default::default(),
        proven: false,
        worst_margin_s: f64::INFINITY,
    }
}

/// Where the robot's TCP is (part frame, mm) at every trajectory point with the arc on and
/// halfway between two such points (joints interpolated linearly, as a controller does
/// between close points).
fn welded_by_the_robot(cell: &Cell, planned: &waam_pipeline::Planned) -> Vec<[f64; 3]> {
    let to_part = cell.settings.plate.isometry().inverse();
    let tcp = |q: &[f64]| {
        let p = to_part * cell.robot.tcp_pose(q);
        (p.translation.vector * 1000.0).into()
    };
    let pts = &planned.trajectory.points;
    let mut out = Vec::new();
    for k in 1..pts.len() {
        if !(pts[k - 1].arc_on && pts[k].arc_on) {
            continue;
        }
        let mid: Vec<f64> = pts[k - 1]
            .positions
            .iter()
            .zip(&pts[k].positions)
            .map(|(a, b)| 0.5 * (a + b))
            .collect();
        out.push(tcp(&pts[k - 1].positions));
        out.push(tcp(&mid));
        out.push(tcp(&pts[k].positions));
    }
    out
}

#[test]
fn a_ring_is_welded_by_the_robot_within_a_tenth_of_a_millimetre_of_its_circle() {
    let part = rings(2);
    let cell = cell();
    // One spiral: layer 0 round, up, layer 1 round, starting mid-ring (across the seam).
    let n = part.len() / 2;
    let spiral: Vec<usize> = (0..n)
        .map(|i| (i + n / 3) % n)
        .chain((0..n).map(|i| n + (i + n / 3) % n))
        .collect();
    let planned = cell.motion(part.clone(), chosen(vec![spiral])).unwrap();
    let welded = welded_by_the_robot(&cell, &planned);
    assert!(welded.len() > 2 * 256, "{} samples", welded.len());
    let mut worst: f64 = 0.0;
    let mut angle_covered = [vec![false; 360], vec![false; 360]];
    for p in &welded {
        let r = p[0].hypot(p[1]);
        worst = worst.max((r - R).abs());
        // On the top of layer 0 or 1 (or climbing between them).
        assert!(p[2] > H - 0.1 && p[2] < 2.0 * H + 0.1, "{p:?}");
        let layer = usize::from(p[2] > 1.5 * H);
        let a = p[1].atan2(p[0]).rem_euclid(TAU).to_degrees() as usize % 360;
        angle_covered[layer][a] = true;
    }
    assert!(worst < 0.1, "the TCP strays {worst} mm from the circle");
    // The whole circle on both layers.
    for (layer, covered) in angle_covered.iter().enumerate() {
        let missing = covered.iter().filter(|&&c| !c).count();
        assert_eq!(missing, 0, "layer {layer}: {missing} degrees never welded");
    }
    // Checked on the executed time line: one deposit per node.
    let deposits: usize = planned.timeline.deposits.iter().map(Vec::len).sum();
    assert_eq!(deposits, part.len());
    assert_eq!(planned.toolpath.frame, cell.robot.base_link);
}

#[test]
fn the_pipeline_plans_a_graph_part_with_the_robot_and_its_torch_on_the_beads() {
    let part = rings(3);
    let cell = Cell::bundled();
    assert!(cell.settings.torch.is_some());
    let outcome = waam_pipeline::plan(&part, Some(&cell), &Options::default(), &mut |_| {})
        .expect("the planner runs");
    let planned = outcome
        .motion
        .expect("a plan and a cell: a motion")
        .expect("the bundled robot welds three rings");
    assert!(planned.found.fragments.len() <= 2);
    // The toolpath goes round the beads, not through stand-in blocks in a row.
    let to_part = cell.settings.plate.isometry().inverse();
    for p in planned.toolpath.poses.iter().filter(|p| p.arc_on) {
        let t = (to_part * p.pose).translation.vector * 1000.0;
        assert!((t.x.hypot(t.y) - R).abs() < 0.1, "{t}");
    }
}

#[test]
fn the_torch_check_of_a_given_graph_plan_names_the_node_in_its_way() {
    // A tower beside a ring: the inner tower (radius R) first, then the outer ring on
    // layer 0, whose bead is 1 mm from the tower's: the nozzle cannot get down there.
    let tower = rings(8);
    let mut beads = tower.bead_part().unwrap().clone();
    let outer = Bead {
        layer: 0,
        closed: true,
        points: beads.beads[0]
            .points
            .iter()
            .map(|p| [p[0] * (R + 7.0) / R, p[1] * (R + 7.0) / R])
            .collect(),
    };
    let len = outer.length_mm();
    let c = outer.piece_mm(0.0, len)[0];
    beads.beads.push(outer);
    // Nodes stay listed layer by layer: the new layer-0 node goes before layer 1.
    let n = tower.len() / 8;
    beads.nodes.insert(
        n,
        Deposit {
            bead: 8,
            from_mm: 0.0,
            to_mm: len,
            layer: 0,
            centre_mm: [c[0], c[1], 0.5 * H],
            volume_mm3: W * H * len,
            surface_mm2: 1.0,
            substrate_mm2: W * len,
        },
    );
    for c in &mut beads.contacts {
        c.a += usize::from(c.a >= n);
        c.b += usize::from(c.b >= n);
    }
    let part = Part::of_beads(beads).unwrap();
    let tower_first: Vec<usize> = (0..part.len()).filter(|&i| i != n).collect();
    let fragments = vec![tower_first, vec![n]];
    let err =
        waam_pipeline::check_torch(&part, &fragments, &ProcessSettings::default()).unwrap_err();
    assert!(matches!(err, PipelineError::TorchBlocked { .. }), "{err}");
    let text = err.to_string();
    assert!(text.contains(&format!("cannot reach node {n} ")), "{text}");
    assert!(text.contains("deposited before it"), "{text}");
    // The ring first, then the tower: the torch fits everywhere.
    let ring_first = vec![vec![n], (0..part.len()).filter(|&i| i != n).collect()];
    waam_pipeline::check_torch(&part, &ring_first, &ProcessSettings::default()).unwrap();
}
