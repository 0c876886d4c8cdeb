//! The one entry that runs the pipeline past the part: plan (the SAT planner, with the
//! cell's torch and robot checks), then, with a cell and a plan, the plan's check and its
//! validated motion ([`plan`]).

use waam_part::Part;
use waam_planner::{self as planner, Report};

use crate::{Cell, ChosenPlan, Interrupt, PipelineError, Planned};

/// Which plan the planner looks for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Objective {
    /// The best plan: fewest weld paths, then the largest worst-case t8/5 margin
    /// ([`waam_planner::plan`]); within the time limit, the best so far.
    #[default]
    Best,
    /// The first feasible plan found, without optimizing ([`waam_planner::first`]).
    First,
}

/// How [`plan`] runs.
#[derive(Debug, Clone, Default)]
pub struct Options {
    /// The planner's search: time limit, cancel flag, solver, warm start, k, memory limit.
    /// With a cell, its `torch` and `executed` are the cell's (whatever they say here):
    /// the process settings' torch and the robot's check of every candidate on its
    /// executed time line, stopped by the planner's own time limit and cancel flag.
    /// Without a cell they are used as given (`torch`: a torch checked without a robot).
    pub planner: planner::Options,
    pub objective: Objective,
    /// Stops the stages after planning (the plan's check, its motion). The planner's
    /// cancel flag does not: a listener may raise it to stop the search at the first
    /// feasible plan, which is then still checked and moved.
    pub motion: Interrupt,
}

/// What [`plan`] tells its caller while it runs.
#[derive(Debug, Clone, Copy)]
pub enum Progress<'a> {
    /// An event of the planner (every candidate's verdict, with its statistics).
    Planner(planner::Event<'a>),
    /// The planner is done with a plan of this many weld paths; with a cell, the plan is
    /// now checked and its motion planned.
    Motion { fragments: usize },
}

/// What [`plan`] found.
#[derive(Debug)]
pub struct Outcome {
    /// The planner's answer: its best plan (or why there is none) and its statistics.
    pub report: Report,
    /// With a cell and a plan: the plan checked, with its validated motion, or why the
    /// robot cannot weld it. `None` without a cell or without a plan.
    pub motion: Option<Result<Planned, PipelineError>>,
}

impl Outcome {
    /// The planner's plan with what it did to find it (none without a plan).
    pub fn chosen(&self) -> Option<ChosenPlan> {
        ChosenPlan::from_report(&self.report)
    }
}

impl ChosenPlan {
    /// The report's best plan, with the report's statistics and proof.
    pub fn from_report(report: &Report) -> Option<ChosenPlan> {
        report.best.as_ref().map(|best| ChosenPlan {
            fragments: best.fragments.clone(),
            stats: report.stats.clone(),
            proven: report.proven,
            worst_margin_s: best.margin,
        })
    }
}

/// The pipeline from a part on: the planner's plan of `part` by `options` (with a cell,
/// checked for the cell's torch at every deposit and for the robot on every candidate's
/// executed time line), then, with a cell and a plan, the plan's check and its motion
/// ([`Cell::motion_until`], stopped by `options.motion`). `Err`: the planner could not
/// run (the part too large for its memory limit, a model that does not cool); no plan or
/// no motion is an [`Outcome`].
pub fn plan(
    part: &Part,
    cell: Option<&Cell>,
    options: &Options,
    progress: &mut dyn FnMut(Progress<'_>),
) -> Result<Outcome, PipelineError> {
    let opts = planner_options(part, cell, &options.planner);
    let mut events = |event: planner::Event| progress(Progress::Planner(event));
    let report = match options.objective {
        Objective::Best => planner::plan(part, &opts, &mut events),
        Objective::First => planner::first(part, &opts, &mut events),
    }?;
    let motion = match (cell, ChosenPlan::from_report(&report)) {
        (Some(cell), Some(chosen)) => {
            progress(Progress::Motion {
                fragments: chosen.fragments.len(),
            });
            Some(cell.motion_until(part.clone(), chosen, &options.motion))
        }
        _ => None,
    };
    Ok(Outcome { report, motion })
}

/// The planner's options of a run of [`plan`]: `base`, with a cell its torch and its
/// robot's check (stopped by `base`'s time limit from now and its cancel flag).
pub fn planner_options(
    part: &Part,
    cell: Option<&Cell>,
    base: &planner::Options,
) -> planner::Options {
    let mut opts = base.clone();
    if let Some(cell) = cell {
        opts.torch = cell.settings.torch_setup();
        let interrupt = Interrupt::after(opts.timeout).with_cancel(opts.cancel.clone());
        opts.executed = Some(cell.executed_check(part, interrupt));
    }
    opts
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Cell;

    fn s1_wall() -> Part {
        Part::parse(include_str!("../../../config/parts/s1-wall.yaml")).unwrap()
    }

    /// The planner alone, with the options the entry gives it.
    fn planner_alone(part: &Part, cell: Option<&Cell>) -> Report {
        let opts = planner_options(part, cell, &planner::Options::default());
        planner::plan(part, &opts, &mut |_| {}).unwrap()
    }

    #[test]
    fn the_entry_plans_as_the_planner_does_and_with_a_cell_validates_the_motion() {
        let part = s1_wall();
        let mut events = 0;
        let mut motion_events = Vec::new();
        let bare = plan(&part, None, &Options::default(), &mut |p| match p {
            Progress::Planner(_) => events += 1,
            Progress::Motion { fragments } => motion_events.push(fragments),
        })
        .unwrap();
        let alone = planner_alone(&part, None);
        let best = bare.report.best.as_ref().expect("s1-wall has a plan");
        assert_eq!(best.fragments, alone.best.unwrap().fragments);
        assert_eq!(bare.report.proven, alone.proven);
        assert_eq!(bare.report.stats.candidates, events);
        assert!(bare.motion.is_none() && motion_events.is_empty());

        let cell = Cell::bundled();
        let with_cell = plan(&part, Some(&cell), &Options::default(), &mut |p| {
            if let Progress::Motion { fragments } = p {
                motion_events.push(fragments);
            }
        })
        .unwrap();
        let alone = planner_alone(&part, Some(&cell));
        let chosen = with_cell.chosen().expect("a plan with the bundled cell");
        assert_eq!(chosen.fragments, alone.best.unwrap().fragments);
        assert_eq!(motion_events, vec![chosen.fragments.len()]);
        let planned = with_cell
            .motion
            .expect("a cell and a plan: a motion")
            .expect("the bundled robot welds s1-wall");
        assert_eq!(planned.found.fragments, chosen.fragments);
        assert!(!planned.trajectory.points.is_empty());
        // The motion is the cell's for the chosen plan, checked on its executed time line.
        let again = cell.motion(part.clone(), chosen).unwrap();
        assert_eq!(again.toolpath.poses.len(), planned.toolpath.poses.len());
        assert_eq!(again.timeline, planned.timeline);
    }

    #[test]
    fn the_first_objective_is_the_planners_first_and_the_motion_interrupt_stops_the_motion() {
        let part = s1_wall();
        // One racer: on more, whichever configuration finds a plan first wins, and two runs
        // may differ (only proven answers are the same on any number of threads).
        let one = planner::Options {
            threads: 1,
            ..planner::Options::default()
        };
        let options = Options {
            objective: Objective::First,
            planner: one.clone(),
            ..Options::default()
        };
        let first = plan(&part, None, &options, &mut |_| {}).unwrap();
        let alone = planner::first(&part, &one, &mut |_| {}).unwrap();
        assert_eq!(
            first.report.best.map(|b| b.fragments),
            alone.best.map(|b| b.fragments)
        );
        // A motion stage stopped before it starts: the plan is there, the motion is not.
        let stopped = Options {
            motion: Interrupt::after(Some(std::time::Duration::ZERO)),
            ..Options::default()
        };
        let outcome = plan(&part, Some(&Cell::bundled()), &stopped, &mut |_| {}).unwrap();
        assert!(outcome.report.best.is_some());
        assert!(matches!(
            outcome.motion,
            Some(Err(PipelineError::Interrupted(_)))
        ));
    }
}
