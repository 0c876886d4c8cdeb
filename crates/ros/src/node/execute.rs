//! Executing a plan on a controller: the trajectory cut into goals, the arc switched between.
//!
//! A welding controller (MotoROS2, a `joint_trajectory_controller`) takes one
//! FollowJointTrajectory goal at a time, and some cap the points per goal (MotoROS2: 200).
//! The arc must strike when the torch reaches a fragment's first block and go out when it
//! reaches the arc-off point after the last, so goals end exactly there: per fragment, the
//! approach (arc off) up to the arc-on point, then `~/arc_on` true, then the weld in goals of
//! at most `max_points` points up to the arc-off point, then `~/arc_on` false. Each goal
//! starts where the previous one ended, with the robot at rest.

use std::ops::RangeInclusive;

/// One step of running a trajectory: a goal over a span of trajectory points, or an arc switch.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Step {
    /// Send points `span` (indices into the trajectory). The robot stands on the point before
    /// the span (the end of the previous goal), or anywhere for the very first goal.
    Goal {
        span: RangeInclusive<usize>,
        /// The fragment being welded, or `None` for approach, transit and retract moves.
        welding: Option<usize>,
    },
    /// Switch the arc on or off (after the previous goal has finished).
    Arc(bool),
}

/// Cuts a trajectory, given by the arc state of each of its points (a point's state holds
/// from that point on), into execution steps of at most `max_points` points per goal.
pub fn plan_steps(arc_on: &[bool], max_points: usize) -> Vec<Step> {
    assert!(max_points >= 1, "a goal needs room for a point");
    let mut steps = Vec::new();
    let n = arc_on.len();
    let mut next = 0; // the next point to send
    let mut fragment = 0;
    let mut i = 0;
    while i < n {
        if !arc_on[i] {
            i += 1;
            continue;
        }
        // A weld run: points start..=end are arc-on; the arc goes out at end + 1.
        let start = i;
        let mut end = i;
        while end + 1 < n && arc_on[end + 1] {
            end += 1;
        }
        let off = (end + 1).min(n - 1);
        push_goals(&mut steps, next, start, max_points, None);
        steps.push(Step::Arc(true));
        push_goals(&mut steps, start + 1, off, max_points, Some(fragment));
        steps.push(Step::Arc(false));
        next = off + 1;
        fragment += 1;
        i = off + 1;
    }
    if n > 0 {
        push_goals(&mut steps, next, n - 1, max_points, None);
    }
    steps
}

/// Goals sending points `from..=to`, at most `max_points` each (nothing when `from > to`).
fn push_goals(
    steps: &mut Vec<Step>,
    from: usize,
    to: usize,
    max_points: usize,
    welding: Option<usize>,
) {
    let mut next = from;
    while next <= to {
        let last = (next + max_points - 1).min(to);
        steps.push(Step::Goal {
            span: next..=last,
            welding,
        });
        next = last + 1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use Step::*;

    fn goal(a: usize, b: usize, welding: Option<usize>) -> Step {
        Goal {
            span: a..=b,
            welding,
        }
    }

    #[test]
    fn goals_end_at_arc_switches() {
        // transit 0,1; weld 2..=4 (arc off at 5); transit 6; weld 7,8 (off at 9); retract 10
        let arc = [
            false, false, true, true, true, false, false, true, true, false, false,
        ];
        assert_eq!(
            plan_steps(&arc, 200),
            vec![
                goal(0, 2, None),
                Arc(true),
                goal(3, 5, Some(0)),
                Arc(false),
                goal(6, 7, None),
                Arc(true),
                goal(8, 9, Some(1)),
                Arc(false),
                goal(10, 10, None),
            ]
        );
    }

    #[test]
    fn long_welds_split_at_the_cap_and_send_every_point_once() {
        let mut arc = vec![false; 3];
        arc.extend(vec![true; 500]);
        arc.extend(vec![false; 4]);
        arc.extend(vec![true; 7]);
        arc.extend(vec![false; 2]);
        for cap in [1, 2, 3, 7, 200] {
            let steps = plan_steps(&arc, cap);
            let mut sent = Vec::new();
            let mut arc_state = false;
            for s in &steps {
                match s {
                    Goal { span, welding } => {
                        assert!(span.clone().count() <= cap, "cap {cap}: {span:?}");
                        assert_eq!(welding.is_some(), arc_state);
                        // Points reached with the arc on are arc-on points, except the
                        // arc-off point that ends a weld.
                        for p in span.clone() {
                            if p != *span.end() {
                                assert_eq!(arc[p], arc_state, "cap {cap}, point {p}");
                            }
                        }
                        sent.extend(span.clone());
                    }
                    Arc(on) => {
                        assert_ne!(*on, arc_state);
                        arc_state = *on;
                    }
                }
            }
            assert_eq!(sent, (0..arc.len()).collect::<Vec<_>>(), "cap {cap}");
            assert_eq!(steps.iter().filter(|s| **s == Arc(true)).count(), 2);
            assert!(!arc_state);
        }
    }

    #[test]
    fn edge_cases() {
        assert!(plan_steps(&[], 5).is_empty());
        assert_eq!(plan_steps(&[false, false], 5), vec![goal(0, 1, None)]);
        // A trajectory ending with the arc on still switches it off at its last point.
        assert_eq!(
            plan_steps(&[true, true], 5),
            vec![goal(0, 0, None), Arc(true), goal(1, 1, Some(0)), Arc(false)]
        );
    }
}
