//! The simulated cell on a robot: where the robot's trajectory makes each deposit of the
//! plan the loop follows, kept in step as re-plans and faults change it.

use waam_part::Part;

use crate::CellError;

/// A robot's executed time line of a whole plan: each weld path's deposit starts and its
/// arc-off, s (any origin).
#[derive(Debug, Clone, PartialEq)]
pub struct PlanTimes {
    pub deposits_s: Vec<Vec<f64>>,
    pub arc_off_s: Vec<f64>,
}

/// Times a whole plan (fragments of block indices) on the cell's robot. With `Some(part)`
/// the plan is checked first like any plan the robot receives, under `part`'s model (the
/// estimate's, after a decision); with `None` it is only timed (a plan executed anyway:
/// the first, which the planner checked, or one a fault split in open loop).
pub type Timing<'a> = dyn FnMut(Option<&Part>, &[Vec<usize>]) -> Result<PlanTimes, String> + 'a;

/// Where the robot makes each deposit of the plan now (by its index in weld order), on the
/// true model's clock (s from the first deposit): its start and end (the next deposit's
/// start, or the arc-off), and for the first of a weld path after another, the previous
/// path's arc-off.
pub(crate) struct Timed {
    fragments: Vec<Vec<usize>>,
    pub(crate) starts: Vec<f64>,
    pub(crate) ends: Vec<f64>,
    pub(crate) arc_off_before: Vec<Option<f64>>,
}

impl Timed {
    /// `times` of `fragments`, moved by `shift_s`.
    pub(crate) fn new(
        fragments: Vec<Vec<usize>>,
        times: &PlanTimes,
        shift_s: f64,
    ) -> Result<Timed, CellError> {
        let shapes: Vec<usize> = times.deposits_s.iter().map(Vec::len).collect();
        let want: Vec<usize> = fragments.iter().map(Vec::len).collect();
        if shapes != want || times.arc_off_s.len() != fragments.len() {
            return Err(CellError::Robot(format!(
                "its time line has weld paths of {shapes:?} deposits, the plan {want:?}"
            )));
        }
        let mut timed = Timed {
            fragments,
            starts: Vec::new(),
            ends: Vec::new(),
            arc_off_before: Vec::new(),
        };
        for (f, starts) in times.deposits_s.iter().enumerate() {
            for (p, &t) in starts.iter().enumerate() {
                let end = starts.get(p + 1).copied().unwrap_or(times.arc_off_s[f]);
                timed.starts.push(t + shift_s);
                timed.ends.push(end + shift_s);
                let first_after_another = p == 0 && f > 0;
                timed
                    .arc_off_before
                    .push(first_after_another.then(|| times.arc_off_s[f - 1] + shift_s));
            }
        }
        Ok(timed)
    }

    /// The plan now taken over after `done` deposits: timed by `times`, moved so that the
    /// last deposit made ends when it did.
    fn after(
        &self,
        fragments: Vec<Vec<usize>>,
        times: &PlanTimes,
        done: usize,
    ) -> Result<Timed, CellError> {
        let new = Timed::new(fragments, times, 0.0)?;
        let shift = match done.checked_sub(1) {
            Some(last) => self.ends[last] - new.ends[last],
            None => self.starts[0] - new.starts[0],
        };
        Timed::new(new.fragments, times, shift)
    }
}

/// `fragments` timed on the robot (checked under `check` when given) from where `done`
/// deposits of `old` left it; `None` when the plan is still `old`'s.
pub(crate) fn retimed(
    timing: &mut Timing,
    old: &Timed,
    check: Option<&Part>,
    fragments: Vec<Vec<usize>>,
    done: usize,
) -> Result<Option<Timed>, CellError> {
    if fragments == old.fragments {
        return Ok(None);
    }
    let times = timing(check, &fragments).map_err(CellError::Robot)?;
    old.after(fragments, &times, done).map(Some)
}
