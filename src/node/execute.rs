//! Executing a plan on a controller: the trajectory cut into goals, the arc switched between.
//!
//! A welding controller (MotoROS2, a `joint_trajectory_controller`) takes one
//! FollowJointTrajectory goal at a time, and some cap the points per goal (MotoROS2: 200).
//! The arc must strike where the torch reaches a fragment's first block and go out at its
//! last, so goals end exactly there: per fragment, the approach (arc off) up to the arc-on
//! point, then `~/arc_on` true, then the weld in goals of at most `max_points` points, then
//! `~/arc_on` false. Each goal starts where the previous one ended, the robot at rest.

use std::ops::RangeInclusive;

/// One step of running a trajectory: a goal over a span of trajectory points, or an arc switch.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Step {
    /// Move through points `span` (indices into the trajectory). The first point of the span
    /// is where the robot already stands (the end of the previous goal), except for the
    /// very first goal, which starts at point 0.
    Goal {
        span: RangeInclusive<usize>,
        /// The fragment being welded, or `None` for approach, transit and retract moves.
        welding: Option<usize>,
    },
    /// Switch the arc on or off (after the previous goal has finished).
    Arc(bool),
}

/// Cuts a trajectory, given by the arc state of each of its points, into execution steps with
/// at most `max_points` points per goal (counting the shared start point; `max_points >= 2`).
pub fn plan_steps(arc_on: &[bool], max_points: usize) -> Vec<Step> {
    assert!(
        max_points >= 2,
        "a goal needs room for a start and an end point"
    );
    let mut steps = Vec::new();
    if arc_on.is_empty() {
        return steps;
    }
    let last = arc_on.len() - 1;
    let mut at = 0; // the point the robot stands on after the steps so far
    let mut fragment = 0;
    let mut i = 0;
    while i <= last {
        if !arc_on[i] {
            i += 1;
            continue;
        }
        // A weld run: points start..=end are arc-on.
        let start = i;
        let mut end = i;
        while end < last && arc_on[end + 1] {
            end += 1;
        }
        push_goals(&mut steps, at, start, max_points, None);
        steps.push(Step::Arc(true));
        push_goals(&mut steps, start, end, max_points, Some(fragment));
        steps.push(Step::Arc(false));
        at = end;
        fragment += 1;
        i = end + 1;
    }
    push_goals(&mut steps, at, last, max_points, None);
    steps
}

/// Goals from point `from` to point `to`, each at most `max_points` points long, each starting
/// at the previous one's end. Nothing when there is nowhere to go (except a lone start point).
fn push_goals(
    steps: &mut Vec<Step>,
    from: usize,
    to: usize,
    max_points: usize,
    welding: Option<usize>,
) {
    if from == to {
        if from == 0 && steps.is_empty() {
            // The trajectory starts at its first arc-on point: still send point 0, so the
            // controller goes there before the arc strikes.
            steps.push(Step::Goal {
                span: 0..=0,
                welding,
            });
        }
        return;
    }
    let mut a = from;
    while a < to {
        let b = (a + max_points - 1).min(to);
        steps.push(Step::Goal {
            span: a..=b,
            welding,
        });
        a = b;
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
        // approach 0,1; weld 2..=4; transit 5,6; weld 7,8; retract 9
        let arc = [
            false, false, true, true, true, false, false, true, true, false,
        ];
        let steps = plan_steps(&arc, 200);
        assert_eq!(
            steps,
            vec![
                goal(0, 2, None),
                Arc(true),
                goal(2, 4, Some(0)),
                Arc(false),
                goal(4, 7, None),
                Arc(true),
                goal(7, 8, Some(1)),
                Arc(false),
                goal(8, 9, None),
            ]
        );
    }

    #[test]
    fn long_welds_split_at_the_cap_and_cover_every_point() {
        let mut arc = vec![false; 3];
        arc.extend(vec![true; 500]);
        arc.extend(vec![false; 4]);
        for cap in [2, 3, 7, 200] {
            let steps = plan_steps(&arc, cap);
            let mut next = 0;
            let mut arc_state = false;
            for (k, s) in steps.iter().enumerate() {
                let strikes_next = steps.get(k + 1) == Some(&Arc(true));
                match s {
                    Goal { span, welding } => {
                        assert!(span.end() - span.start() < cap, "cap {cap}: {span:?}");
                        // Contiguous: each goal starts where the last one ended.
                        assert!(*span.start() == next || (next == 0 && *span.start() == 0));
                        next = *span.end();
                        // Welding goals run with the arc on, the others with it off.
                        assert_eq!(welding.is_some(), arc_state);
                        // (An approach ends on the arc-on point, reached with the arc off.)
                        for p in span.clone().skip(1) {
                            if !(strikes_next && p == *span.end()) {
                                assert_eq!(arc[p], arc_state, "point {p}");
                            }
                        }
                    }
                    Arc(on) => {
                        assert_ne!(*on, arc_state);
                        arc_state = *on;
                    }
                }
            }
            assert_eq!(next, arc.len() - 1);
            assert!(!arc_state);
        }
    }

    #[test]
    fn edge_cases() {
        assert!(plan_steps(&[], 5).is_empty());
        assert_eq!(plan_steps(&[false, false], 5), vec![goal(0, 1, None)]);
        assert_eq!(
            plan_steps(&[true, true], 5),
            vec![goal(0, 0, None), Arc(true), goal(0, 1, Some(0)), Arc(false)]
        );
    }
}
