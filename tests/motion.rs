//! Toolpaths and joint trajectories for the sample parts on two robots: ours and the
//! ABB IRB 1600 URDF published by ROS-Industrial (no torch; meshes absent on disk).

mod common;

use waam::motion::{plan_motion, MotionError};
use waam::robot::{pose_error, Robot};
use waam::toolpath::{PoseKind, ProcessSettings, Toolpath};
use waam::trajectory::{JointTrajectory, TrajectoryError};

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
    let settings = ProcessSettings::default();
    for name in common::PARTS {
        let (part, fragments) = common::part_and_plan(name);
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
    let first = waam::part::BlockDisplay(part.block(fragments[0][0])).to_string();
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
