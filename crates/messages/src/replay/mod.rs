//! Replay: find every part a recording received, re-plan it, and compare the new plan with
//! the one recorded. A regression check for the planner and a way to debug plans away from
//! the cell.
//!
//! The comparison is independent of the planner: [`replay`] takes the re-planning as a
//! function, so the same code serves the CLI and tests.

pub mod decisions;

use std::fmt;

use waam_part::Block;
use waam_rosbag::{Bag, BagError};
use waam_rosmsg::diagnostic_msgs::{DiagnosticArray, DiagnosticStatus};
use waam_rosmsg::shape_msgs::Mesh;
use waam_rosmsg::std_msgs::String as RosString;
use waam_rosmsg::waam_interfaces::{PlanStatistics, WeldPlan};
use waam_rosmsg::{from_cdr, RosMessage};

/// What the node was given.
#[derive(Debug, Clone, PartialEq)]
pub enum CaseInput {
    /// A part document (`~/part`).
    PartText(String),
    /// A mesh (`~/part_mesh`).
    Mesh(Mesh),
}

/// One part the recording received and what the recording says came of it.
#[derive(Debug, Clone, PartialEq)]
pub struct RecordedCase {
    /// Receive time of the part, ns since the epoch.
    pub log_time: u64,
    pub topic: String,
    pub input: CaseInput,
    /// The first plan published after this part and before the next one.
    pub plan: Option<WeldPlan>,
    /// The first ERROR status published after this part and before the next one.
    pub error: Option<String>,
    /// Key-value pairs of the statuses published after this part and before the next one
    /// (the planner's settings among them).
    pub status_values: Vec<(String, String)>,
}

/// Parts are recognised on `std_msgs/String` topics whose name ends in `/part`, meshes on any
/// `shape_msgs/Mesh` topic, plans on any `waam_interfaces/WeldPlan` topic and errors in
/// `diagnostic_msgs/DiagnosticArray` statuses of level ERROR.
pub fn recorded_cases(bag: &Bag) -> Result<Vec<RecordedCase>, BagError> {
    let mut order: Vec<usize> = (0..bag.messages.len()).collect();
    order.sort_by_key(|&i| bag.messages[i].log_time); // stable: file order breaks ties
    let mut cases: Vec<RecordedCase> = Vec::new();
    for i in order {
        let m = &bag.messages[i];
        let topic = bag.topic_of(m);
        let decode_error = |source| BagError::Decode {
            topic: topic.name.clone(),
            log_time: m.log_time,
            source,
        };
        let input = if topic.type_name == RosString::TYPE_NAME && topic.name.ends_with("/part") {
            Some(CaseInput::PartText(
                from_cdr::<RosString>(&m.data).map_err(decode_error)?.data,
            ))
        } else if topic.type_name == Mesh::TYPE_NAME {
            Some(CaseInput::Mesh(from_cdr(&m.data).map_err(decode_error)?))
        } else {
            None
        };
        if let Some(input) = input {
            cases.push(RecordedCase {
                log_time: m.log_time,
                topic: topic.name.clone(),
                input,
                plan: None,
                error: None,
                status_values: Vec::new(),
            });
            continue;
        }
        let Some(case) = cases.last_mut() else {
            continue;
        };
        if topic.type_name == WeldPlan::TYPE_NAME && case.plan.is_none() && case.error.is_none() {
            case.plan = Some(from_cdr(&m.data).map_err(decode_error)?);
        } else if topic.type_name == DiagnosticArray::TYPE_NAME {
            let status: DiagnosticArray = from_cdr(&m.data).map_err(decode_error)?;
            for s in &status.status {
                case.status_values
                    .extend(s.values.iter().map(|kv| (kv.key.clone(), kv.value.clone())));
            }
            if case.plan.is_none() && case.error.is_none() {
                case.error = status
                    .status
                    .iter()
                    .find(|s| s.level == DiagnosticStatus::ERROR)
                    .map(|s| s.message.clone());
            }
        }
    }
    Ok(cases)
}

/// The outcome of planning a part again.
#[derive(Debug, Clone, PartialEq)]
pub enum Replanned {
    /// A plan: fragments of block coordinates and how it was found.
    Plan {
        fragments: Vec<Vec<Block>>,
        statistics: PlanStatistics,
    },
    /// No plan, and why (bad part, no feasible plan, ...).
    NoPlan(String),
    /// This input cannot be re-planned here (and why).
    Unsupported(String),
}

/// One way a new plan differs from the recorded one.
#[derive(Debug, Clone, PartialEq)]
pub enum Difference {
    /// The recording has a plan, re-planning gives none.
    PlanLost {
        reason: String,
    },
    /// The recording has an error, re-planning gives a plan.
    PlanGained {
        recorded_error: String,
    },
    FragmentCount {
        recorded: usize,
        new: usize,
    },
    /// The first block that differs, in weld order.
    Block {
        fragment: usize,
        position: usize,
        recorded: Option<Block>,
        new: Option<Block>,
    },
    /// A statistic that should be reproducible (counts, learned clauses) differs.
    Statistic {
        name: &'static str,
        recorded: String,
        new: String,
    },
}

fn block_text(b: Option<Block>) -> String {
    b.map_or("(none)".into(), |b| format!("[{},{},{}]", b[0], b[1], b[2]))
}

impl fmt::Display for Difference {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Difference::PlanLost { reason } => {
                write!(f, "recorded a plan, re-planning finds none: {reason}")
            }
            Difference::PlanGained { recorded_error } => write!(
                f,
                "recorded an error ({recorded_error}), re-planning finds a plan"
            ),
            Difference::FragmentCount { recorded, new } => {
                write!(f, "fragments: recorded {recorded}, new {new}")
            }
            Difference::Block {
                fragment,
                position,
                recorded,
                new,
            } => write!(
                f,
                "first differing block: fragment {fragment}, position {position}: recorded {}, \
                 new {}",
                block_text(*recorded),
                block_text(*new)
            ),
            Difference::Statistic {
                name,
                recorded,
                new,
            } => write!(f, "statistics: {name} recorded {recorded}, new {new}"),
        }
    }
}

/// The verdict on one case.
#[derive(Debug, Clone, PartialEq)]
pub enum Verdict {
    Identical,
    Different(Vec<Difference>),
    /// Not compared, and why (e.g. the recording shows no outcome: a newer part superseded it).
    Skipped(String),
}

/// The replay of one recorded case.
#[derive(Debug, Clone, PartialEq)]
pub struct CaseReport {
    pub case: RecordedCase,
    pub replanned: Replanned,
    pub verdict: Verdict,
}

/// Compares fragments: the count, then the first differing block in weld order.
pub fn diff_fragments(recorded: &[Vec<Block>], new: &[Vec<Block>]) -> Vec<Difference> {
    let mut out = Vec::new();
    if recorded.len() != new.len() {
        out.push(Difference::FragmentCount {
            recorded: recorded.len(),
            new: new.len(),
        });
    }
    'outer: for f in 0..recorded.len().max(new.len()) {
        let (a, b) = (recorded.get(f), new.get(f));
        let len = a.map_or(0, Vec::len).max(b.map_or(0, Vec::len));
        for p in 0..len {
            let (x, y) = (
                a.and_then(|a| a.get(p)).copied(),
                b.and_then(|b| b.get(p)).copied(),
            );
            if x != y {
                out.push(Difference::Block {
                    fragment: f,
                    position: p,
                    recorded: x,
                    new: y,
                });
                break 'outer;
            }
        }
    }
    out
}

/// Compares the statistics a deterministic planner reproduces (not the times).
pub fn diff_statistics(recorded: &PlanStatistics, new: &PlanStatistics) -> Vec<Difference> {
    let mut out = Vec::new();
    let mut check = |name: &'static str, a: String, b: String| {
        if a != b {
            out.push(Difference::Statistic {
                name,
                recorded: a,
                new: b,
            });
        }
    };
    check(
        "candidates",
        recorded.candidates.to_string(),
        new.candidates.to_string(),
    );
    check(
        "feasible",
        recorded.feasible.to_string(),
        new.feasible.to_string(),
    );
    check(
        "optimal",
        recorded.optimal.to_string(),
        new.optimal.to_string(),
    );
    check(
        "learned clauses",
        recorded.learned_clauses.to_string(),
        new.learned_clauses.to_string(),
    );
    check(
        "learned clause length min/max/mean",
        format!(
            "{}/{}/{:.3}",
            recorded.learned_clause_min, recorded.learned_clause_max, recorded.learned_clause_mean
        ),
        format!(
            "{}/{}/{:.3}",
            new.learned_clause_min, new.learned_clause_max, new.learned_clause_mean
        ),
    );
    out
}

/// Re-plans every recorded case with `replan` and compares. With `compare_statistics` off,
/// only the plans themselves are compared.
pub fn replay(
    cases: Vec<RecordedCase>,
    compare_statistics: bool,
    mut replan: impl FnMut(&RecordedCase) -> Replanned,
) -> Vec<CaseReport> {
    cases
        .into_iter()
        .map(|case| {
            let replanned = replan(&case);
            let verdict = match (&case.plan, &case.error, &replanned) {
                (_, _, Replanned::Unsupported(why)) => Verdict::Skipped(why.clone()),
                (None, None, _) => Verdict::Skipped(
                    "the recording shows no plan and no error for this part (superseded by a \
                     newer part, or recorded before planning ended)"
                        .into(),
                ),
                (
                    Some(recorded),
                    _,
                    Replanned::Plan {
                        fragments,
                        statistics,
                    },
                ) => {
                    let mut d = diff_fragments(&recorded.part_fragments(), fragments);
                    if compare_statistics {
                        d.extend(diff_statistics(&recorded.statistics, statistics));
                    }
                    if d.is_empty() {
                        Verdict::Identical
                    } else {
                        Verdict::Different(d)
                    }
                }
                (Some(_), _, Replanned::NoPlan(reason)) => {
                    Verdict::Different(vec![Difference::PlanLost {
                        reason: reason.clone(),
                    }])
                }
                (None, Some(_), Replanned::NoPlan(_)) => Verdict::Identical,
                (None, Some(error), Replanned::Plan { .. }) => {
                    Verdict::Different(vec![Difference::PlanGained {
                        recorded_error: error.clone(),
                    }])
                }
            };
            CaseReport {
                case,
                replanned,
                verdict,
            }
        })
        .collect()
}

/// When to send each recorded message to play the recording back with its original timing:
/// (delay from the start, index into `bag.messages`), in receive-time order. `rate` > 1 plays
/// faster.
pub fn schedule(bag: &Bag, rate: f64) -> Vec<(std::time::Duration, usize)> {
    let mut order: Vec<usize> = (0..bag.messages.len()).collect();
    order.sort_by_key(|&i| bag.messages[i].log_time);
    let Some(&first) = order.first() else {
        return Vec::new();
    };
    let t0 = bag.messages[first].log_time;
    let rate = if rate.is_finite() && rate > 0.0 {
        rate
    } else {
        1.0
    };
    order
        .into_iter()
        .map(|i| {
            let ns = (bag.messages[i].log_time - t0) as f64 / rate;
            (std::time::Duration::from_nanos(ns.round() as u64), i)
        })
        .collect()
}

#[cfg(test)]
mod tests;
