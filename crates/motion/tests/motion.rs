//! Toolpaths and joint trajectories for the sample parts on two robots: ours and the
//! ABB IRB 1600 URDF published by ROS-Industrial (no torch; meshes absent on disk).

mod common;

use waam_motion::robot::{pose_error, Robot};
use waam_motion::toolpath::{PoseKind, ProcessSettings, Toolpath};
use waam_motion::trajectory::{JointTrajectory, TrajectoryError};
use waam_motion::{plan_motion, MotionError};

/// Checks everything the issue asks of a trajectory, independently of the library's
/// own validation.
fn check(robot: &Robot, tp: &Toolpath, traj: &JointTrajectory, name: &str) {
    assert_eq!(traj.points.len(), tp.poses.len(), "{name}");
    assert_eq!(traj.joint_names, robot.joint_names());
    for (k, (pt, pose)) in traj.points.iter().zip(&tp.poses).enumerate() {
        assert_eq!(pt.time_from_start, pose.time_s, "{name} point {k}");
        assert_eq!(pt.arc_on, pose.arc_on);
        let (dp, dr) = pose_error(&robot.tcp_pose(&pt.positions), &pose.pose);
        assert!(
            dp <= 1e-6 && dr <= 1e-6,
            "{name} point {k}: {dp:e} m {dr:e} rad"
        );
        for (j, joint) in robot.joints.iter().enumerate() {
            let q = pt.positions[j];
            assert!(
                q >= joint.lower && q <= joint.upper,
                "{name} point {k} {}",
                joint.name
            );
            assert!(
                pt.velocities[j].abs() <= joint.velocity,
                "{name} point {k} {}",
                joint.name
            );
        }
        if k > 0 {
            let prev = &traj.points[k - 1];
            let dt = pt.time_from_start - prev.time_from_start;
            assert!(dt > 0.0);
            for (j, joint) in robot.joints.iter().enumerate() {
                let jump = (pt.positions[j] - prev.positions[j]).abs();
                assert!(
                    jump <= joint.velocity * dt * (1.0 + 1e-9),
                    "{name} point {k} {} jumps {jump} in {dt} s",
                    joint.name
                );
            }
        }
    }
    // One arc-on and one arc-off marker per fragment.
    let count = |kind| tp.poses.iter().filter(|p| p.kind == kind).count();
    let fragments = tp.poses.last().unwrap().fragment + 1;
    assert_eq!(count(PoseKind::ArcOn), fragments);
    assert_eq!(count(PoseKind::ArcOff), fragments);
}

fn run_all(robot: &Robot) {
    for name in common::PARTS {
        let (part, fragments) = common::part_and_plan(name);
        // ex3's sample plan is one the torch cannot weld (planner and pipeline torch tests):
        // its moves are checked for the TCP only.
        let settings = ProcessSettings {
            torch: ProcessSettings::default()
                .torch
                .filter(|_| name != "ex3-h-column"),
            ..ProcessSettings::default()
        };
        let (tp, traj) = plan_motion(&part, &fragments, &settings, robot)
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        check(robot, &tp, &traj, name);
        // One weld pose at every block.
        let at_blocks = tp
            .poses
            .iter()
            .filter(|p| p.kind == PoseKind::Weld && p.at_point)
            .count();
        assert_eq!(at_blocks, part.len(), "{name}");
    }
}

#[test]
fn every_sample_part_on_our_robot() {
    let robot = common::our_robot();
    assert!(robot.opw().is_some());
    run_all(&robot);
}

#[test]
fn every_sample_part_on_the_abb_urdf_with_a_given_tcp() {
    let robot = common::abb_robot();
    assert_eq!(robot.tip_link, "tool0");
    assert!(robot.opw().is_some(), "{:?}", robot.opw_reason);
    run_all(&robot);
}

#[test]
fn a_part_five_metres_away_names_the_first_unreachable_block() {
    let (part, fragments) = common::part_and_plan("s1-wall");
    let mut settings = ProcessSettings::default();
    settings.plate.position_m[0] += 5.0;
    let first = waam_part::BlockDisplay(part.block(fragments[0][0])).to_string();
    for robot in [common::our_robot(), common::abb_robot()] {
        let err = plan_motion(&part, &fragments, &settings, &robot).unwrap_err();
        assert!(
            matches!(
                err,
                MotionError::Trajectory(TrajectoryError::Unreachable(_))
            ),
            "{err}"
        );
        let text = err.to_string();
        assert!(text.contains(&format!("block {first}")), "{text}");
        assert!(text.starts_with("unreachable: pose 0"), "{text}");
    }
}

#[test]
fn the_numeric_solver_follows_the_same_paths() {
    let settings = ProcessSettings {
        ik_solver: waam_motion::robot::Solver::Numeric,
        ..ProcessSettings::default()
    };
    for robot in [common::our_robot(), common::abb_robot()] {
        for name in ["s2-corner", "s7-pad"] {
            let (part, fragments) = common::part_and_plan(name);
            let (tp, traj) = plan_motion(&part, &fragments, &settings, &robot)
                .unwrap_or_else(|e| panic!("{name}: {e}"));
            check(&robot, &tp, &traj, name);
        }
    }
}

#[test]
fn an_arm_without_a_spherical_wrist_uses_the_numeric_solver() {
    // Our arm with joint 5 moved 20 mm off the forearm axis: not an OPW arm any more.
    let text = std::fs::read_to_string(common::root().join("urdf/waam_robot.urdf")).unwrap();
    let moved = text.replace(
        "<origin xyz=\"0 0 0\" rpy=\"0 0 0\"/>\n    <axis xyz=\"0 1 0\"/>\n    <limit lower=\"-2.00713\"",
        "<origin xyz=\"0 0.02 0\" rpy=\"0 0 0\"/>\n    <axis xyz=\"0 1 0\"/>\n    <limit lower=\"-2.00713\"",
    );
    assert_ne!(moved, text);
    let choice = waam_motion::robot::TcpChoice {
        explicit: None,
        default: nalgebra::Isometry3::identity(),
    };
    let robot = Robot::from_urdf(&moved, None, choice).unwrap();
    assert!(robot.opw().is_none());
    assert!(
        robot
            .opw_reason
            .as_deref()
            .unwrap()
            .contains("spherical wrist"),
        "{:?}",
        robot.opw_reason
    );
    let (part, fragments) = common::part_and_plan("s3-ring");
    let (tp, traj) = plan_motion(&part, &fragments, &ProcessSettings::default(), &robot).unwrap();
    check(&robot, &tp, &traj, "s3-ring offset wrist");
}

#[test]
fn coarse_toolpaths_are_split_until_the_tcp_keeps_to_the_line() {
    let settings = ProcessSettings {
        max_step_mm: 500.0,
        max_step_deg: 90.0,
        ..ProcessSettings::default()
    };
    let robot = common::our_robot();
    let (part, fragments) = common::part_and_plan("s2-corner");
    let passes = waam_motion::toolpath::passes_from_plan(&part, &fragments);
    let timing = waam_motion::toolpath::WeldTiming::PerPoint(part.thermal.block_time_s);
    let coarse = waam_motion::toolpath::build(&passes, &settings, timing, "base_link").unwrap();
    let (tp, traj) = plan_motion(&part, &fragments, &settings, &robot).unwrap();
    assert!(tp.poses.len() > coarse.poses.len(), "some steps were split");
    check(&robot, &tp, &traj, "s2-corner coarse");
    for k in 1..tp.poses.len() {
        let (a, b) = (&traj.points[k - 1].positions, &traj.points[k].positions);
        let mid: Vec<f64> = a.iter().zip(b).map(|(x, y)| 0.5 * (x + y)).collect();
        let line =
            waam_motion::trajectory::interpolate(&tp.poses[k - 1].pose, &tp.poses[k].pose, 0.5);
        let (dp, dr) = pose_error(&robot.tcp_pose(&mid), &line);
        assert!(
            dp * 1000.0 <= settings.path_tolerance_mm + 1e-9,
            "step {k}: {} mm",
            dp * 1000.0
        );
        assert!(dr.to_degrees() <= settings.path_tolerance_deg + 1e-9);
    }
}

#[test]
fn output_files_have_exactly_the_documented_keys() {
    let (part, fragments) = common::part_and_plan("s5-ledge");
    let robot = common::abb_robot();
    let (tp, traj) = plan_motion(&part, &fragments, &ProcessSettings::default(), &robot).unwrap();
    let dir = tempfile::tempdir().unwrap();
    waam_motion::write_outputs(dir.path(), &tp, &traj).unwrap();
    let read = |f: &str| -> serde_yaml::Value {
        serde_yaml::from_str(&std::fs::read_to_string(dir.path().join(f)).unwrap()).unwrap()
    };
    let keys = |v: &serde_yaml::Value| -> Vec<String> {
        let mut k: Vec<String> = v
            .as_mapping()
            .unwrap()
            .keys()
            .map(|k| k.as_str().unwrap().to_string())
            .collect();
        k.sort();
        k
    };
    let t = read("toolpath.yaml");
    assert_eq!(keys(&t), ["frame", "poses"]);
    assert_eq!(t["frame"].as_str(), Some("base_link"));
    let poses = t["poses"].as_sequence().unwrap();
    assert_eq!(poses.len(), tp.poses.len());
    assert_eq!(
        keys(&poses[0]),
        ["arc_on", "fragment", "orientation", "position", "time"]
    );
    let j = read("trajectory.yaml");
    assert_eq!(
        keys(&j),
        [
            "base_link",
            "joint_names",
            "points",
            "tcp_offset",
            "tip_link"
        ]
    );
    assert_eq!(j["tip_link"].as_str(), Some("tool0"));
    assert_eq!(keys(&j["tcp_offset"]), ["orientation", "position"]);
    let points = j["points"].as_sequence().unwrap();
    assert_eq!(
        keys(&points[0]),
        [
            "accelerations",
            "arc_on",
            "positions",
            "time_from_start",
            "velocities"
        ]
    );
    // The files round-trip: FK of the written joints reproduces the written poses.
    let tf: waam_motion::toolpath::ToolpathFile = serde_yaml::from_value(t).unwrap();
    let jf: waam_motion::trajectory::TrajectoryFile = serde_yaml::from_value(j).unwrap();
    for (p, q) in tf.poses.iter().zip(&jf.points) {
        assert_eq!(p.time, q.time_from_start);
        let (dp, dr) = pose_error(&robot.tcp_pose(&q.positions), &p.isometry());
        assert!(dp <= 1e-6 && dr <= 1e-6);
    }
}
