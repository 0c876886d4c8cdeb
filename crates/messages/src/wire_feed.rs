//! A weld path's wire feed per deposit as a `trajectory_msgs/JointTrajectory`: one joint,
//! [`JOINT`], one point per deposit, its feed (relative to nominal) from its start, timed
//! from the arc strike. A welder bridge sets each point's feed as the weld goal reaches it,
//! as a controller follows a joint's positions.

use waam_rosmsg::builtin_interfaces::Duration;
use waam_rosmsg::trajectory_msgs::{JointTrajectory, JointTrajectoryPoint};

/// The schedule's one joint name.
pub const JOINT: &str = "wire_feed";

/// The schedule of deposits starting `starts_s` after the arc strikes, at `feeds`.
pub fn schedule_msg(starts_s: &[f64], feeds: &[f64]) -> JointTrajectory {
    JointTrajectory {
        joint_names: vec![JOINT.into()],
        points: starts_s
            .iter()
            .zip(feeds)
            .map(|(&t, &feed)| JointTrajectoryPoint {
                positions: vec![feed],
                time_from_start: Duration::from_secs_f64(t),
                ..Default::default()
            })
            .collect(),
        ..Default::default()
    }
}

/// The feeds of a schedule, one per deposit; `None` when it is not one (another joint, or a
/// point without exactly one position).
pub fn schedule_feeds(msg: &JointTrajectory) -> Option<Vec<f64>> {
    if msg.joint_names != [JOINT] {
        return None;
    }
    msg.points
        .iter()
        .map(|p| match p.positions[..] {
            [feed] => Some(feed),
            _ => None,
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_schedule_reads_back_its_feeds_and_refuses_other_trajectories() {
        let msg = schedule_msg(&[0.0, 1.5, 3.0], &[1.3, 1.1, 1.0]);
        assert_eq!(schedule_feeds(&msg), Some(vec![1.3, 1.1, 1.0]));
        assert_eq!(msg.points[1].time_from_start.as_secs_f64(), 1.5);
        let mut other = msg.clone();
        other.joint_names = vec!["joint_1".into()];
        assert_eq!(schedule_feeds(&other), None);
        let mut two = msg;
        two.points[0].positions.push(0.0);
        assert_eq!(schedule_feeds(&two), None);
    }
}
