//! Pairing recorded parts with their outcomes, and the comparison.

use super::*;
use crate::topics;
use waam_rosbag::{BagOptions, BagWriter, Qos};
use waam_rosmsg::std_msgs::Header;
use waam_rosmsg::waam_interfaces::{Block as MsgBlock, WeldFragment};

const T0: u64 = 1_700_000_000_000_000_000;

fn weld_plan(fragments: &[Vec<Block>], candidates: u64) -> WeldPlan {
    WeldPlan {
        fragments: fragments
            .iter()
            .map(|f| WeldFragment {
                blocks: f.iter().map(|&b| MsgBlock::from_part(b).unwrap()).collect(),
            })
            .collect(),
        statistics: PlanStatistics {
            candidates,
            ..Default::default()
        },
        ..Default::default()
    }
}

fn error_status(message: &str) -> DiagnosticArray {
    DiagnosticArray {
        header: Header::default(),
        status: vec![DiagnosticStatus {
            level: DiagnosticStatus::ERROR,
            message: message.into(),
            ..Default::default()
        }],
    }
}

fn wall(n: i64) -> Vec<Vec<Block>> {
    vec![(0..n).map(|x| [x, 0, 0]).collect()]
}

/// Part "a" planned, "b" failed, "c" superseded by "d", "d" planned.
fn session() -> Bag {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("s");
    let mut w = BagWriter::create(&dir, BagOptions::default()).unwrap();
    let part = |w: &mut BagWriter, t: u64, text: &str| {
        w.write(topics::PART, &Qos::reliable(10), t, &RosString::from(text))
            .unwrap()
    };
    let plan = |w: &mut BagWriter, t: u64, p: &WeldPlan| {
        w.write(topics::WELD_PLAN, &Qos::latched(), t, p).unwrap()
    };
    part(&mut w, T0, "a");
    plan(&mut w, T0 + 1, &weld_plan(&wall(3), 5));
    part(&mut w, T0 + 2, "b");
    w.write(
        topics::STATUS,
        &Qos::latched(),
        T0 + 3,
        &error_status("bad part b"),
    )
    .unwrap();
    part(&mut w, T0 + 4, "c");
    part(&mut w, T0 + 5, "d");
    plan(&mut w, T0 + 6, &weld_plan(&wall(4), 9));
    // A later plan for the same part (a re-publish) does not replace the first.
    plan(&mut w, T0 + 7, &weld_plan(&wall(1), 1));
    w.finish().unwrap();
    Bag::open(&dir).unwrap()
}

fn text(input: &CaseInput) -> &str {
    match input {
        CaseInput::PartText(t) => t,
        CaseInput::Mesh(_) => panic!("no meshes here"),
    }
}

#[test]
fn parts_are_paired_with_their_plans_and_errors() {
    let cases = recorded_cases(&session()).unwrap();
    let names: Vec<&str> = cases.iter().map(|c| text(&c.input)).collect();
    assert_eq!(names, ["a", "b", "c", "d"]);
    assert_eq!(cases[0].plan.as_ref().unwrap().part_fragments(), wall(3));
    assert_eq!(cases[1].error.as_deref(), Some("bad part b"));
    assert!(cases[1].plan.is_none());
    assert!(cases[2].plan.is_none() && cases[2].error.is_none());
    assert_eq!(cases[3].plan.as_ref().unwrap().part_fragments(), wall(4));
    assert_eq!(cases[0].log_time, T0);
}

/// A planner that plans walls of length given by the part text ("a" = 3, "d" = 4), fails on
/// "b" and plans "c".
fn honest(case: &RecordedCase) -> Replanned {
    let n = match text(&case.input) {
        "a" => 3,
        "c" => 2,
        "d" => 4,
        _ => return Replanned::NoPlan("bad part".into()),
    };
    Replanned::Plan {
        fragments: wall(n),
        statistics: PlanStatistics {
            candidates: if n == 3 { 5 } else { 9 },
            ..Default::default()
        },
    }
}

#[test]
fn the_same_planner_reproduces_the_session() {
    let reports = replay(recorded_cases(&session()).unwrap(), true, honest);
    let verdicts: Vec<&Verdict> = reports.iter().map(|r| &r.verdict).collect();
    assert_eq!(verdicts[0], &Verdict::Identical);
    assert_eq!(verdicts[1], &Verdict::Identical);
    assert!(matches!(verdicts[2], Verdict::Skipped(_)));
    assert_eq!(verdicts[3], &Verdict::Identical);
}

#[test]
fn a_changed_plan_names_the_first_differing_block() {
    let reports = replay(
        recorded_cases(&session()).unwrap(),
        true,
        |case| match text(&case.input) {
            "d" => Replanned::Plan {
                fragments: vec![vec![[0, 0, 0], [1, 0, 0], [2, 0, 1], [3, 0, 0]]],
                statistics: PlanStatistics {
                    candidates: 10,
                    ..Default::default()
                },
            },
            "b" => Replanned::Plan {
                fragments: wall(1),
                statistics: PlanStatistics::default(),
            },
            _ => honest(case),
        },
    );
    let Verdict::Different(d) = &reports[3].verdict else {
        panic!("{:?}", reports[3].verdict)
    };
    assert_eq!(
        d[0],
        Difference::Block {
            fragment: 0,
            position: 2,
            recorded: Some([2, 0, 0]),
            new: Some([2, 0, 1])
        }
    );
    assert_eq!(
        d[0].to_string(),
        "first differing block: fragment 0, position 2: recorded [2,0,0], new [2,0,1]"
    );
    assert!(
        d[1].to_string().contains("candidates recorded 9, new 10"),
        "{}",
        d[1]
    );
    assert!(matches!(
        &reports[1].verdict,
        Verdict::Different(d) if matches!(&d[0], Difference::PlanGained { .. })
    ));
    // Statistics left out: only the plan counts.
    let reports = replay(recorded_cases(&session()).unwrap(), false, |case| {
        let mut r = honest(case);
        if let Replanned::Plan { statistics, .. } = &mut r {
            statistics.candidates += 1;
        }
        r
    });
    assert_eq!(reports[3].verdict, Verdict::Identical);
}

#[test]
fn fragment_differences() {
    let a = vec![vec![[0, 0, 0], [1, 0, 0]], vec![[2, 0, 0]]];
    let b = vec![vec![[0, 0, 0], [1, 0, 0], [2, 0, 0]]];
    let d = diff_fragments(&a, &b);
    assert_eq!(
        d[0],
        Difference::FragmentCount {
            recorded: 2,
            new: 1
        }
    );
    assert_eq!(
        d[1],
        Difference::Block {
            fragment: 0,
            position: 2,
            recorded: None,
            new: Some([2, 0, 0])
        }
    );
    assert!(diff_fragments(&a, &a).is_empty());
    let lost = replay(recorded_cases(&session()).unwrap(), true, |_| {
        Replanned::NoPlan("no feasible plan".into())
    });
    assert!(matches!(
        &lost[0].verdict,
        Verdict::Different(d) if d[0].to_string().contains("no feasible plan")
    ));
}

#[test]
fn playback_keeps_the_recorded_timing() {
    let bag = session();
    let plan = schedule(&bag, 1.0);
    assert_eq!(plan.len(), bag.messages.len());
    assert_eq!(plan[0].0, std::time::Duration::ZERO);
    assert_eq!(plan[3].0, std::time::Duration::from_nanos(3));
    let fast = schedule(&bag, 2.0);
    assert_eq!(fast.last().unwrap().0, std::time::Duration::from_nanos(4)); // 7 ns / 2
    assert!(plan.windows(2).all(|w| w[0].0 <= w[1].0));
}
