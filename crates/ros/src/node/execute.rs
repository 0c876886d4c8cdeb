//! Executing a plan on a controller: the trajectory cut into goals, the arc switched between.
//!
//! A welding controller (MotoROS2, a `joint_trajectory_controller`) takes one
//! FollowJointTrajectory goal at a time, and some cap the points per goal (MotoROS2: 200).
//! The arc must strike when the torch reaches a fragment's first block and go out when it
//! reaches the arc-off point after the last, so goals end exactly there: per fragment, the
//! approach (arc off) up to the arc-on point, then `~/arc_on` true, then the whole weld up to
//! the arc-off point as **one** goal, then `~/arc_on` false. Each goal starts where the
//! previous one ended, with the robot at rest — so a goal boundary inside a weld would stop
//! the torch with the arc burning (a crater, a lump of wire). Only the arc-off stretches
//! (approach, transit, retract) are cut at `max_points`; a weld longer than the cap goes
//! whole, and [`oversized_welds`] names it so the node can say so.

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
/// from that point on), into execution steps: arc-off stretches in goals of at most
/// `max_points` points, each weld (arc-on point + 1 up to its arc-off point) as one goal.
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
        // The whole weld in one goal: never a stop with the arc on.
        push_goals(&mut steps, start + 1, off, usize::MAX, Some(fragment));
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
        let last = next.saturating_add(max_points - 1).min(to);
        steps.push(Step::Goal {
            span: next..=last,
            welding,
        });
        next = last + 1;
    }
}

/// The welds (fragment index, points) whose single goal has more than `max_points` points.
pub fn oversized_welds(steps: &[Step], max_points: usize) -> Vec<(usize, usize)> {
    steps
        .iter()
        .filter_map(|s| match s {
            Step::Goal {
                span,
                welding: Some(f),
            } if span.clone().count() > max_points => Some((*f, span.clone().count())),
            _ => None,
        })
        .collect()
}

/// Whether the robot, stopped at point `p` between two goals, would stand inside an arc-on
/// stretch: the moves into and out of `p` both weld. (Stopping on the arc-on point, before
/// the arc strikes, or on the arc-off point, after it goes out, is how welds start and end.)
pub fn inside_weld(arc_on: &[bool], p: usize) -> bool {
    p > 0 && p < arc_on.len() && arc_on[p - 1] && arc_on[p]
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

    /// Checks what every execution must keep: each point sent once and in order, arc-off
    /// goals within the cap, goals alternating with the arc switches, the arc on exactly
    /// while a weld goal runs, and no goal boundary inside an arc-on stretch.
    fn check_steps(arc: &[bool], cap: usize) {
        let steps = plan_steps(arc, cap);
        let mut sent = Vec::new();
        let mut arc_state = false;
        let mut boundaries = Vec::new();
        for s in &steps {
            match s {
                Goal { span, welding } => {
                    assert_eq!(welding.is_some(), arc_state, "cap {cap}: {steps:?}");
                    if welding.is_none() {
                        assert!(span.clone().count() <= cap, "cap {cap}: {span:?}");
                    }
                    // Points reached with the arc on are arc-on points, except the arc-off
                    // point that ends a weld.
                    for p in span.clone() {
                        if p != *span.end() {
                            assert_eq!(arc[p], arc_state, "cap {cap}, point {p}");
                        }
                    }
                    sent.extend(span.clone());
                    boundaries.push(*span.end());
                }
                Arc(on) => {
                    assert_ne!(*on, arc_state, "cap {cap}: {steps:?}");
                    arc_state = *on;
                }
            }
        }
        assert_eq!(sent, (0..arc.len()).collect::<Vec<_>>(), "cap {cap}");
        assert!(!arc_state, "the arc is left on: {steps:?}");
        // Where the robot stops between two goals (the last goal's end is the finish).
        boundaries.pop();
        for p in boundaries {
            assert!(
                !inside_weld(arc, p),
                "cap {cap}: a goal ends at point {p}, inside a weld: {arc:?} -> {steps:?}"
            );
        }
    }

    #[test]
    fn long_welds_go_whole_and_transits_split_at_the_cap() {
        let mut arc = vec![false; 12];
        arc.extend(vec![true; 500]);
        arc.extend(vec![false; 4]);
        arc.extend(vec![true; 7]);
        arc.extend(vec![false; 2]);
        for cap in [1, 2, 3, 7, 200] {
            check_steps(&arc, cap);
            let steps = plan_steps(&arc, cap);
            assert_eq!(steps.iter().filter(|s| **s == Arc(true)).count(), 2);
            // The 500-point weld is one goal: points 13..=512 (its arc-off point).
            assert!(
                steps.contains(&goal(13, 512, Some(0))),
                "cap {cap}: {steps:?}"
            );
            let oversized = oversized_welds(&steps, cap);
            let expected: Vec<(usize, usize)> = [(0, 500), (1, 7)]
                .into_iter()
                .filter(|(_, n)| *n > cap)
                .collect();
            assert_eq!(oversized, expected, "cap {cap}");
        }
        // The 12-point approach is cut at the cap of 5: 0..=4, 5..=9, 10..=12.
        let steps = plan_steps(&arc, 5);
        assert_eq!(
            steps[..4],
            [
                goal(0, 4, None),
                goal(5, 9, None),
                goal(10, 12, None),
                Arc(true)
            ]
        );
    }

    proptest::proptest! {
        /// Any arc pattern, any cap: never a goal boundary inside an arc-on stretch.
        #[test]
        fn no_goal_boundary_inside_an_arc_on_stretch(
            arc in proptest::collection::vec(proptest::bool::weighted(0.6), 0..120),
            cap in 1usize..12,
        ) {
            check_steps(&arc, cap);
        }
    }

    #[test]
    fn inside_weld_is_where_both_moves_weld() {
        let arc = [false, true, true, true, false];
        let inside: Vec<usize> = (0..arc.len()).filter(|&p| inside_weld(&arc, p)).collect();
        assert_eq!(inside, vec![2, 3]);
        // Cutting that weld at the cap would stop the robot there: the old behaviour.
        assert!(inside_weld(&arc, 2));
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
