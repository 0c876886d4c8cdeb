//! What the robot welds is what was checked (#13), the parts the torch and the robot add:
//! - the torch (nozzle, body, wrist) along every move with the arc off, against the part as
//!   built — checked here by an independent sampling of the torch's volume, not by
//!   `waam_motion::clearance`;
//! - plans that enter from outside (`waam motion`, `waam publish --plan`) get the planner's
//!   torch check;
//! - the planner learns from a candidate the robot cannot weld on the model's time line.
//!
//! (Through the binary: `tests/cli/access.rs`.)

mod common;

use std::sync::{Arc, Mutex};

use common::{our_robot, part_and_plan, root};
use nalgebra::{Point3, UnitQuaternion, Vector3};
use waam_access::Torch;
use waam_motion::robot::limits::JointLimitsFile;
use waam_motion::toolpath::{ProcessSettings, Toolpath};
use waam_motion::MotionError;
use waam_part::Part;
use waam_pipeline::{Cell, ChosenPlan, PipelineError, Progress};
use waam_planner::{self as planner, CandidateVerdict, Event, NoPlan, Options};

fn cell() -> Cell {
    Cell {
        settings: ProcessSettings::default(),
        robot: our_robot(),
    }
}

/// A pose of the toolpath in the part frame: TCP (mm) and orientation (z: the wire).
fn in_part(tp: &Toolpath, s: &ProcessSettings, k: usize) -> (Point3<f64>, UnitQuaternion<f64>) {
    let pose = s.plate.isometry().inverse() * tp.poses[k].pose;
    (
        Point3::from(pose.translation.vector * 1000.0),
        pose.rotation,
    )
}

/// Points filling the torch's three cylinders (axis every 2 mm; on the axis and on rings at
/// half and full radius, every 22.5°), for the TCP at `tcp` turned by `rot`.
fn torch_points(torch: &Torch, tcp: &Point3<f64>, rot: &UnitQuaternion<f64>) -> Vec<Point3<f64>> {
    let up = -(rot * Vector3::z());
    let across1 = rot * Vector3::x();
    let across2 = rot * Vector3::y();
    let nozzle_end = torch.nozzle_standoff_mm;
    let body_end = nozzle_end + torch.nozzle_length_mm;
    let wrist_end = body_end + torch.body_length_mm;
    let pieces = [
        (nozzle_end, body_end, 0.5 * torch.nozzle_diameter_mm),
        (body_end, wrist_end, 0.5 * torch.body_diameter_mm),
        (
            wrist_end,
            wrist_end + torch.wrist_length_mm,
            0.5 * torch.wrist_diameter_mm,
        ),
    ];
    let mut out = Vec::new();
    for (from, to, r) in pieces {
        let n = ((to - from) / 2.0).ceil() as usize;
        for i in 0..=n {
            let s = from + (to - from) * i as f64 / n as f64;
            let c = tcp + up * s;
            out.push(c);
            for ring in [0.5 * r, r] {
                for j in 0..16 {
                    let phi = j as f64 * std::f64::consts::PI / 8.0;
                    out.push(c + (across1 * phi.cos() + across2 * phi.sin()) * ring);
                }
            }
        }
    }
    out
}

/// Every arc-off move sampled every 0.5 mm of TCP travel (and 0.5° of turn): no point of the
/// torch inside a block welded before the move (deeper than 0.01 mm) or below the plate.
/// Returns the number of moves checked.
fn assert_torch_clear(
    name: &str,
    part: &Part,
    fragments: &[Vec<usize>],
    tp: &Toolpath,
    s: &ProcessSettings,
) -> usize {
    let (checked, hit) = torch_hit(part, fragments, tp, s, &s.torch.expect("a torch"));
    assert_eq!(hit, None, "{name}");
    checked
}

/// The moves with the arc off checked, and where the torch first meets the part as built
/// or the plate on one of them.
fn torch_hit(
    part: &Part,
    fragments: &[Vec<usize>],
    tp: &Toolpath,
    s: &ProcessSettings,
    torch: &Torch,
) -> (usize, Option<String>) {
    let mut welded: Vec<usize> = Vec::new();
    let mut checked = 0;
    for k in 1..tp.poses.len() {
        if tp.poses[k - 1].arc_on {
            if !tp.poses[k].arc_on {
                welded.extend(&fragments[tp.poses[k].fragment]);
            }
            continue;
        }
        let ((a, ra), (b, rb)) = (in_part(tp, s, k - 1), in_part(tp, s, k));
        let turn = ra.angle_to(&rb).to_degrees();
        let n = ((b - a).norm() / 0.5).max(turn / 0.5).ceil().max(1.0) as usize;
        let top = welded
            .iter()
            .map(|&w| part.centre_mm(part.block(w))[2] + 0.5 * part.block_mm[2])
            .fold(0.0, f64::max);
        for i in 0..=n {
            let t = i as f64 / n as f64;
            for p in torch_points(torch, &(a + (b - a) * t), &ra.slerp(&rb, t)) {
                if p.z < -0.01 {
                    let hit =
                        format!("the torch goes below the plate on the move to pose {k}: {p}");
                    return (checked, Some(hit));
                }
                if p.z > top {
                    continue;
                }
                for &w in &welded {
                    let c = part.centre_mm(part.block(w));
                    let inside =
                        (0..3).all(|j| (p[j] - c[j]).abs() < 0.5 * part.block_mm[j] - 0.01);
                    if inside {
                        let hit = format!(
                            "the torch passes through block {:?} at {p} on the {:?} move to pose {k}",
                            part.block(w),
                            tp.poses[k].kind
                        );
                        return (checked, Some(hit));
                    }
                }
            }
        }
        checked += 1;
    }
    (checked, None)
}

/// A wall ten layers (25 mm) tall at x = 3 between single blocks at x = 0 and x = 6, 15 mm
/// from its faces (room for the nozzle): welded wall first, then the blocks.
fn wall_between_two_blocks() -> (Part, Vec<Vec<usize>>) {
    let mut text = String::from(
        "name: wall-between\nblock_mm: [6, 6, 2.5]\nmax_fragments: 3\nlayers: ['#..#..#'",
    );
    for _ in 1..10 {
        text.push_str(", '...#...'");
    }
    text.push_str("]\n");
    let part = Part::parse(&text).unwrap();
    let wall: Vec<usize> = std::iter::once(1).chain(3..12).collect();
    (part, vec![wall, vec![0], vec![2]])
}

#[test]
fn the_transit_over_a_tall_wall_clears_it_with_the_whole_torch() {
    let (part, fragments) = wall_between_two_blocks();
    let cell = cell();
    let s = &cell.settings;
    let (tp, _) = cell.plan_motion(&part, &fragments).unwrap();
    assert!(assert_torch_clear("wall-between", &part, &fragments, &tp, s) > 0);
    // From the arc-off at x = 0 to the arc-on at x = 6 the TCP rises above the wall's top
    // (25 mm) by the transit height and crosses it.
    let k_off = (1..tp.poses.len())
        .find(|&k| tp.poses[k].fragment == 1 && !tp.poses[k].arc_on && tp.poses[k - 1].arc_on)
        .unwrap();
    let k_on = (0..tp.poses.len())
        .find(|&k| tp.poses[k].fragment == 2 && tp.poses[k].arc_on)
        .unwrap();
    let tcp: Vec<Point3<f64>> = (k_off..k_on).map(|k| in_part(&tp, s, k).0).collect();
    let peak = tcp.iter().map(|p| p.z).fold(f64::MIN, f64::max);
    assert!(
        peak >= 25.0 + s.transit_height_mm() - 1e-6,
        "transit peaks at {peak} mm"
    );
    assert!(tcp.iter().any(|p| p.x < 18.0) && tcp.iter().any(|p| p.x > 24.0));
}

#[test]
fn every_sample_part_s_moves_clear_the_whole_torch() {
    let cell = cell();
    // ex3's sample plan is one the torch cannot weld (crates/planner/tests/torch.rs): not here.
    for name in common::PARTS.iter().filter(|&&n| n != "ex3-h-column") {
        let (part, fragments) = part_and_plan(name);
        let (tp, _) = cell.plan_motion(&part, &fragments).unwrap();
        assert!(assert_torch_clear(name, &part, &fragments, &tp, &cell.settings) > 0);
    }
}

/// A column 20 layers (50 mm) tall, then the block beside it: the TCP's line down to it is
/// clear of the column, the nozzle around it is not.
fn block_beside_a_column() -> (Part, Vec<Vec<usize>>) {
    let mut text =
        String::from("name: column\nblock_mm: [6, 6, 2.5]\nmax_fragments: 2\nlayers: ['##'");
    for _ in 1..20 {
        text.push_str(", '#.'");
    }
    text.push_str("]\n");
    let part = Part::parse(&text).unwrap();
    let column: Vec<usize> = std::iter::once(0).chain(2..21).collect();
    (part, vec![column, vec![1]])
}

#[test]
fn a_move_the_torch_body_cannot_make_is_an_error_naming_the_move_and_the_block() {
    let (part, fragments) = block_beside_a_column();
    let robot = our_robot();
    let settings = ProcessSettings::default();
    let err = waam_motion::plan_motion(&part, &fragments, &settings, &robot).unwrap_err();
    let MotionError::Collision(c) = &err else {
        panic!("expected a collision, got: {err}");
    };
    assert_eq!(c.fragment, 1, "{err}");
    let text = err.to_string();
    assert!(
        text.contains("move ending at pose")
            && text.contains("(weld path 2) passes through block [0,0,")
            && text.contains("the torch's nozzle"),
        "{text}"
    );
    // Without a torch only the TCP's line is checked: it is clear.
    let no_torch = ProcessSettings {
        torch: None,
        ..ProcessSettings::default()
    };
    let (tp, _) = waam_motion::plan_motion(&part, &fragments, &no_torch, &robot).unwrap();
    // ... and the test's own check sees the torch pass through the column on that motion
    // (so it can fail).
    let (_, hit) = torch_hit(&part, &fragments, &tp, &no_torch, &Torch::default());
    assert!(
        hit.as_ref()
            .is_some_and(|h| h.contains("through block [0, 0,")),
        "{hit:?}"
    );
    // The pipeline refuses the plan before any motion: the torch cannot weld block [1,0,0].
    let err = cell()
        .plan_motion(&part, &fragments)
        .unwrap_err()
        .to_string();
    assert!(err.contains("cannot reach block [1,0,0]"), "{err}");
}

#[test]
fn the_transit_height_keeps_a_torch_that_reaches_below_the_tcp_clear() {
    let s = ProcessSettings::default();
    // The typical torch at 10°: its lowest point is above the TCP.
    assert_eq!(
        s.transit_height_mm(),
        s.clearance_mm + waam_motion::clearance::SAMPLE_MM
    );
    // A wide nozzle close to the wire, tilted 30°: its rim is 2·cos 30° - 15·sin 30° =
    // -5.77 mm below the TCP; the transit rises that much more.
    let s = ProcessSettings {
        travel_angle_deg: 30.0,
        torch: Some(Torch {
            nozzle_diameter_mm: 30.0,
            nozzle_standoff_mm: 2.0,
            ..Torch::default()
        }),
        ..ProcessSettings::default()
    };
    let below = 15.0 * 0.5 - 2.0 * 30f64.to_radians().cos();
    let extra = s.transit_height_mm() - s.clearance_mm - waam_motion::clearance::SAMPLE_MM;
    assert!((extra - below).abs() < 1e-9, "{extra} vs {below}");
}

#[test]
fn a_plan_given_to_the_pipeline_is_refused_when_the_torch_cannot_weld_it() {
    // The path `waam publish --plan` and the node take: Cell::motion.
    let (part, fragments) = block_beside_a_column();
    let found = ChosenPlan {
        fragments: fragments.clone(),
        stats: Default::default(),
        proven: false,
        worst_margin_s: f64::INFINITY,
    };
    let err = cell().motion(part.clone(), found.clone()).unwrap_err();
    assert!(
        matches!(err, PipelineError::TorchBlocked { .. })
            && err
                .to_string()
                .contains("cannot reach block [1,0,0] (deposit 21 of 21)"),
        "{err}"
    );
    let no_torch = Cell {
        settings: ProcessSettings {
            torch: None,
            ..ProcessSettings::default()
        },
        robot: our_robot(),
    };
    no_torch.motion(part, found).unwrap();
}

/// The bundled robot with its arm joints at 0.05 rad/s (tests/data/slow_joint_limits.yaml).
fn slow_cell() -> Cell {
    let text = std::fs::read_to_string(root().join("tests/data/slow_joint_limits.yaml")).unwrap();
    let limits = JointLimitsFile::from_yaml(&text).unwrap();
    Cell {
        settings: ProcessSettings::default(),
        robot: our_robot().with_limits(&limits).unwrap(),
    }
}

fn two_pads(transit_time_s: f64) -> Part {
    let text = std::fs::read_to_string(root().join("tests/data/two-pads.yaml")).unwrap();
    let mut part = Part::parse(&text).unwrap();
    part.thermal.transit_time_s = transit_time_s;
    part
}

/// Plans `part` in `cell` (the pipeline's entry: its torch and its robot's check); the
/// outcome and the verdicts of every candidate in order.
fn plan_with_robot(part: &Part, cell: &Cell) -> (waam_pipeline::Outcome, Vec<CandidateVerdict>) {
    let verdicts = Arc::new(Mutex::new(Vec::new()));
    let seen = Arc::clone(&verdicts);
    let outcome = waam_pipeline::plan(
        part,
        Some(cell),
        &waam_pipeline::Options::default(),
        &mut |p| {
            if let Progress::Planner(Event::Candidate { verdict, .. }) = p {
                seen.lock().unwrap().push(verdict);
            }
        },
    )
    .unwrap();
    let verdicts = verdicts.lock().unwrap().clone();
    (outcome, verdicts)
}

#[test]
fn with_a_slow_robot_the_planner_learns_from_a_transit_it_cannot_make_and_goes_on() {
    let part = two_pads(3.0);
    let cell = slow_cell();
    // The first candidate's transit is too long for the slow robot.
    let first: Vec<Vec<usize>> = vec![(0..4).collect(), (4..8).rev().collect()];
    let err = cell.motion(
        part.clone(),
        ChosenPlan {
            fragments: first,
            stats: Default::default(),
            proven: false,
            worst_margin_s: f64::INFINITY,
        },
    );
    assert!(
        err.as_ref()
            .is_err_and(|e| e.to_string().contains("transit_time_s")),
        "{:?}",
        err.map(|_| ())
    );
    let (outcome, verdicts) = plan_with_robot(&part, &cell);
    let report = &outcome.report;
    assert!(
        matches!(verdicts[0], CandidateVerdict::ExecutedRejected { .. }),
        "{verdicts:?}"
    );
    assert!(report.stats.executed_rejected >= 1);
    assert!(report.proven);
    assert!(
        report.best.is_some(),
        "a plan whose transit the slow robot makes"
    );
    // The plan the planner returns is one the robot welds on the model's time line.
    let planned = outcome.motion.expect("a plan in a cell").unwrap();
    let times = planned.toolpath.executed_times();
    let gap = times.deposits_s[1][0] - times.arc_off_s[0];
    assert!(gap > 0.0, "{gap}");
    // Without the robot nothing changes: all 8 orders of the two pads are plans.
    let counts = planner::count(&part, &Options::default(), true, &mut |_| {}).unwrap();
    assert_eq!((counts.plans, counts.feasible), (Some(8), 8));
}

#[test]
fn with_a_robot_too_slow_for_any_transit_the_planner_proves_there_is_no_plan() {
    let part = two_pads(0.5);
    let (outcome, verdicts) = plan_with_robot(&part, &slow_cell());
    let report = outcome.report;
    assert!(report.best.is_none() && report.proven);
    assert_eq!(verdicts.len(), 8, "{verdicts:?}");
    assert!(verdicts
        .iter()
        .all(|v| matches!(v, CandidateVerdict::ExecutedRejected { .. })));
    match report.no_plan {
        Some(NoPlan::RobotTimeline { times, last }) => {
            assert_eq!(times, 8);
            assert!(last.contains("transit_time_s"), "{last}");
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn a_planner_without_the_torch_learns_it_from_the_cell_s_check() {
    // A column 20 layers tall at x = 0 and a block at x = 2, 9 mm from its face: welded
    // after the column, the tilted nozzle does not fit beside it; welded first, it does.
    let mut text = String::from(
        "name: column-and-block\nblock_mm: [6, 6, 2.5]\nmax_fragments: 2\nlayers: ['#.#'",
    );
    for _ in 1..20 {
        text.push_str(", '#..'");
    }
    text.push_str("]\n");
    let part = Part::parse(&text).unwrap();
    let cell = cell();
    let block = part.index_of([2, 0, 0]).unwrap();
    // Without the torch both orders are plans.
    let count = |opts: &Options| {
        let mut rejected = 0;
        let counts = planner::count(&part, opts, false, &mut |e: Event| {
            if let Event::Candidate {
                verdict: CandidateVerdict::ExecutedRejected { .. },
                ..
            } = e
            {
                rejected += 1;
            }
        })
        .unwrap();
        (counts.feasible, rejected)
    };
    assert_eq!(count(&Options::default()), (2, 0));
    // The planner's own check off, the cell's torch teaches it: one plan, the block first.
    let taught = Options {
        executed: Some(cell.executed_check(&part, Default::default())),
        ..Options::default()
    };
    assert_eq!(count(&taught), (1, 1));
    let own = Options {
        torch: cell.settings.torch_setup(),
        ..Options::default()
    };
    assert_eq!(count(&own).0, 1);
    let report = planner::plan(&part, &taught, &mut |_| {}).unwrap();
    assert_eq!(report.best.unwrap().fragments[0], vec![block]);
}

/// With a 2 s arc-on dwell some feasible s1-wall plans break a window on the executed time
/// line (timeline.rs). The planner with the robot's check counts exactly the plans
/// that keep every window there (brute force: every valid plan, simulated on the model's
/// time line, then welded by the cell): what it learns from a rejection cuts off no plan
/// the robot can weld, and every plan it counts is one.
#[test]
fn the_planner_with_the_robot_counts_exactly_the_plans_that_pass_on_their_executed_time_line() {
    let part = common::part("s1-wall");
    let cell = Cell {
        settings: ProcessSettings {
            arc_on_dwell_s: 2.0,
            torch: None,
            ..ProcessSettings::default()
        },
        robot: our_robot(),
    };
    let mut expected = 0;
    let mut failing = 0;
    for fragments in common::planner::brute_force_plans(&part, part.max_fragments)
        .into_iter()
        .filter(|p| common::planner::is_feasible(&part, p))
    {
        let found = ChosenPlan {
            fragments,
            stats: Default::default(),
            proven: false,
            worst_margin_s: 0.0,
        };
        match cell.motion(part.clone(), found) {
            Ok(_) => expected += 1,
            Err(PipelineError::InfeasibleExecuted { .. }) => failing += 1,
            Err(e) => panic!("{e}"),
        }
    }
    assert!(
        failing > 0 && expected > 0,
        "{expected} pass, {failing} fail"
    );
    let opts = Options {
        executed: Some(cell.executed_check(&part, Default::default())),
        ..Options::default()
    };
    let counts = planner::count(&part, &opts, false, &mut |_| {}).unwrap();
    eprintln!(
        "s1-wall, 2 s arc-on dwell: {expected} plans pass, {failing} fail on the executed time \
         line; counted with the robot: {} ({} candidates rejected, {} clauses learned)",
        counts.feasible, counts.stats.executed_rejected, counts.stats.learned_clauses
    );
    assert_eq!(counts.feasible, expected, "{failing} fail");
    assert!(counts.stats.executed_rejected > 0);
    // And the best plan with the robot (the pipeline's entry) is one that passes.
    let outcome =
        waam_pipeline::plan(&part, Some(&cell), &Default::default(), &mut |_| {}).unwrap();
    assert!(outcome.report.best.is_some());
    outcome.motion.expect("a plan in a cell").unwrap();
}
