//! Closed loop in the node (issue #31, parameter `closed_loop.enabled`): while `~/execute`
//! runs a plan, at each weld-path boundary (after `~/arc_on` false) the sensors' readings
//! so far go to a [`ClosedLoop`]; it fits the model and re-plans the rest from the
//! estimated state. A new remainder is never assembled here: the whole plan (the weld paths
//! welded, then the new ones) goes through the pipeline's stages in the plan's cell
//! ([`Cell::motion_until`]: plan rules, t8/5 windows under the estimated model, torch,
//! motion, and the windows again on the robot's executed time line, the time already spent
//! included). The execution goes on with its steps from where the robot stands. A re-plan
//! that finds nothing, fails there, or would not start where the robot stands keeps the
//! current plan.
//!
//! A weld path cut short by an arc fault ([`Replanner::cut_short`]) ends a boundary too: the
//! deposits welded by then are told, the loop marks the fault (what follows begins a new
//! weld path; the re-plan may use one more), and the new plan — its cut weld path ending
//! where the arc went out — is checked the same way and on the time line the robot really
//! follows: the cut path's arc off when the fault came, everything after moved by as much.
//! Its steps go on from the cut path's retract, the robot moving there from where it
//! stopped with the arc off.

use waam_cell::{CellError, ClosedLoop, Decision, LoopOptions, MeasureError, Measured};
use waam_messages::replay::decisions::{
    BoundaryRecord, FeedRevision, ReadingRef, ToldDeposit, FINISHED,
};
use waam_messages::status::JobStatus;
use waam_motion::toolpath::ExecutedTimes;
use waam_part::{Block, Part};
use waam_pipeline::{check_executed_times, Cell, ChosenPlan, Interrupt, PipelineError, Planned};
use waam_rosmsg::diagnostic_msgs::KeyValue;

use super::execute::{plan_steps, Step};

/// What the closed loop re-plans with: the cell the plans are made in and the planner's
/// options (its time limit bounds each re-plan; its cancel flag is the execution's), and
/// the wire feed the height rule may set, relative to nominal (the process limits), per
/// deposit or per weld path (what the welder takes). The
/// scan margin the sensors check scans with is recorded with each decision (a replay
/// places the recorded scans with it).
#[derive(Clone)]
pub struct ReplanSetup {
    pub cell: Cell,
    pub planner: waam_planner::Options,
    pub wire_feed: (f64, f64),
    pub wire_feed_per_deposit: bool,
    /// How long before a deposit begins its feed may still be revised while the arc is on,
    /// s of wall time: the revised schedule's way to the welder
    /// (`closed_loop.wire_feed_lead_s`).
    pub wire_feed_lead_s: f64,
    pub scan_margin_mm: f64,
    /// How many times as fast as its trajectory the robot moves (a dry run's time scale;
    /// set from the controller when an execution starts): the loop's clock rate.
    pub time_scale: f64,
}

/// A weld path's wire feeds: each deposit's start, s after the arc strikes (on the
/// trajectory's time line), and its feed relative to nominal; the layer it begins in.
#[derive(Debug, Clone, PartialEq)]
pub struct FeedSchedule {
    pub layer: i64,
    pub starts_s: Vec<f64>,
    pub feeds: Vec<f64>,
}

/// How a boundary ended.
#[derive(Debug)]
pub enum Outcome {
    /// The current remainder is still the plan's best.
    Unchanged,
    /// The current plan goes on; why the new one was not taken.
    Kept(NotTaken),
    /// The new plan (whole, checked, with its motion) and the steps that follow from where
    /// the robot stands.
    New(Box<Planned>, Vec<Step>),
}

/// Why a new plan was not taken at a boundary.
#[derive(Debug, thiserror::Error)]
pub enum NotTaken {
    #[error("no feasible completion from the estimated state")]
    NoCompletion,
    #[error("the new plan fails its check: {0}")]
    Check(PipelineError),
    #[error("the new plan has no weld path {0}")]
    NoWeldPath(usize),
    #[error("weld path {0} of the new plan does not end its arc")]
    NoArcOff(usize),
    #[error(
        "the new motion does not start where the robot stands (joints differ by up to {0:.2e} rad)"
    )]
    NotWhereItStands(f64),
    #[error("the new plan's time line differs from the executed one by {0:.3} s at the boundary")]
    OffTimeline(f64),
    #[error(
        "the new plan fails its check on the time line the robot follows after the arc fault: {0}"
    )]
    CheckAfterFault(PipelineError),
}

/// A weld path cut short by an arc fault.
#[derive(Debug, Clone, PartialEq)]
pub struct CutShort {
    /// The weld path (from 0, of the plan being executed), its deposits, and how many of
    /// them were welded.
    pub fragment: usize,
    pub of: usize,
    pub deposits: usize,
    /// When the arc went out, on the controller's clock and on the plan's trajectory time
    /// line, s.
    pub fault_s: f64,
    pub trajectory_s: f64,
}

/// A fault's shift of the executed time line: weld path `fragment`'s arc went out at
/// `arc_off_s` (trajectory time) and everything after it runs `shift_s` later than the
/// plan that ends it there says.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Shift {
    fragment: usize,
    arc_off_s: f64,
    shift_s: f64,
}

/// A plan's executed times as the robot follows them after the faults so far.
fn shifted(mut times: ExecutedTimes, shifts: &[Shift]) -> ExecutedTimes {
    for s in shifts {
        if let Some(off) = times.arc_off_s.get_mut(s.fragment) {
            *off = s.arc_off_s;
        }
        for g in s.fragment + 1..times.arc_off_s.len() {
            times.arc_off_s[g] += s.shift_s;
            if let Some(d) = times.deposits_s.get_mut(g) {
                d.iter_mut().for_each(|t| *t += s.shift_s);
            }
        }
    }
    times
}

/// One boundary: the decision, what came of it, and the readings that could not be placed.
#[derive(Debug)]
pub struct Replan {
    pub decision: Decision,
    pub outcome: Outcome,
    pub ignored: Vec<MeasureError>,
    /// Readings the loop placed and fitted the model to.
    pub used: usize,
    /// Weld paths welded when it was made.
    pub welded: usize,
    /// Blocks whose t8/5 windows the welded deposits broke under the estimate (not judged
    /// again by the new plan's check).
    pub broken: Vec<Block>,
    /// Wall-clock time of the whole boundary (estimate, re-plan, check and motion), s.
    pub latency_s: f64,
    /// What `waam replay` needs to make the decision again (recorded in the status).
    pub record: BoundaryRecord,
    /// The weld path an arc fault cut short, when that ended this boundary.
    pub cut: Option<CutShort>,
}

impl Replan {
    /// The status entry of this boundary (reason, latency, estimate, remainder).
    pub fn status(&self, job: u64) -> JobStatus {
        let d = &self.decision;
        let e = &d.estimate;
        let reason = match &self.outcome {
            Outcome::New(..) => d.reason,
            Outcome::Unchanged => "unchanged",
            Outcome::Kept(_) => "kept",
        };
        let left = match &self.outcome {
            Outcome::New(p, _) => p.found.fragments.len() - self.welded,
            _ => d.remainder().len(),
        };
        let mut message = format!(
            "part {job}: {reason} after {} weld path(s) ({} deposits): {left} weld path(s) \
             left; model loss x{:.3}, conduction x{:.3} (rms {:.1} -> {:.1} °C); {:.3} s",
            self.welded,
            d.at_deposit,
            e.loss,
            e.conduction,
            e.rmse_before_c,
            e.rmse_after_c,
            self.latency_s
        );
        if let Some(c) = &self.cut {
            message.push_str(&format!(
                "; weld path {} cut short by an arc fault after {} of {} deposits",
                c.fragment + 1,
                c.deposits,
                c.of
            ));
        }
        if let Outcome::Kept(why) = &self.outcome {
            message.push_str(&format!("; {why}"));
        }
        if !self.broken.is_empty() {
            message.push_str(&format!(
                "; windows already broken by the welded deposits (under the estimate), not \
                 judged again: {:?}",
                self.broken
            ));
        }
        JobStatus::Replanned {
            job,
            reason: reason.into(),
            latency_s: self.latency_s,
            message,
            values: vec![
                KeyValue::new("weld_paths_welded", self.welded),
                KeyValue::new("deposits", d.at_deposit),
                KeyValue::new("weld_paths_left", left),
                KeyValue::new("loss_factor", format!("{:.4}", e.loss)),
                KeyValue::new("conduction_factor", format!("{:.4}", e.conduction)),
                KeyValue::new("rmse_before_c", format!("{:.2}", e.rmse_before_c)),
                KeyValue::new("rmse_after_c", format!("{:.2}", e.rmse_after_c)),
                KeyValue::new("planner_s", format!("{:.3}", d.latency_s)),
                KeyValue::new("readings_used", self.used),
                KeyValue::new("readings_ignored", self.ignored.len()),
                KeyValue::new("windows_broken_before", self.broken.len()),
            ]
            .into_iter()
            .chain(self.cut.iter().flat_map(|c| {
                [
                    KeyValue::new("cut_short_weld_path", c.fragment + 1),
                    KeyValue::new("cut_short_deposits", c.deposits),
                    KeyValue::new("arc_fault_s", format!("{:.3}", c.fault_s)),
                ]
            }))
            .chain(self.record.values())
            .collect(),
        }
    }
}

/// One execution's closed loop.
pub struct Replanner {
    setup: ReplanSetup,
    closed: ClosedLoop,
    welded: usize,
    /// Boundaries decided so far, and the deposits told since the last one (recorded).
    boundaries: usize,
    told: Vec<ToldDeposit>,
    /// The cut weld path the next boundary follows, and the time line's shifts so far.
    cut: Option<CutShort>,
    shifts: Vec<Shift>,
    /// What came while the current weld path's arc was on.
    arc_on: ArcOn,
    /// After the plan's last weld path: its record, if feeds were revised while its arc was
    /// on, with the readings used and ignored.
    finished: Option<(BoundaryRecord, usize, usize)>,
}

/// The weld path under way: its deposits told so far (those begun by a reading's stamp),
/// the feeds it was sent, and the readings fed and feed revisions made since the last
/// boundary (recorded there).
#[derive(Default)]
struct ArcOn {
    told: usize,
    feeds: Vec<f64>,
    fed: Vec<ReadingRef>,
    ignored: Vec<MeasureError>,
    used: usize,
    revisions: Vec<FeedRevision>,
}

impl Replanner {
    /// The loop of an execution of `planned` (a block part or a graph part).
    pub fn new(planned: &Planned, setup: ReplanSetup) -> Result<Replanner, CellError> {
        let opts = LoopOptions {
            planner: setup.planner.clone(),
            wire_feed: setup.wire_feed,
            wire_feed_per_deposit: setup.wire_feed_per_deposit,
            clock_rate: setup.time_scale,
        };
        let closed = ClosedLoop::new(&planned.part, &planned.found.fragments, opts, 0.0)?;
        Ok(Replanner {
            setup,
            closed,
            welded: 0,
            boundaries: 0,
            told: Vec::new(),
            cut: None,
            shifts: Vec::new(),
            arc_on: ArcOn::default(),
            finished: None,
        })
    }

    /// After the plan's last weld path (`at_boundary` had nothing left to decide): a
    /// `replanned` status with reason `finished` that records the feeds revised while its arc
    /// was on (with the deposits and readings they came from), so that `waam replay` makes
    /// them again; none when nothing was revised.
    pub fn finished(&mut self, job: u64) -> Option<JobStatus> {
        let (record, used, ignored) = self.finished.take()?;
        Some(JobStatus::Replanned {
            job,
            reason: FINISHED.into(),
            latency_s: 0.0,
            message: format!(
                "part {job}: finished; its last weld path's wire feeds revised {} time(s) while \
                 the arc was on",
                record.feed_revisions.len()
            ),
            values: vec![
                KeyValue::new("weld_paths_welded", self.welded),
                KeyValue::new("readings_used", used),
                KeyValue::new("readings_ignored", ignored),
            ]
            .into_iter()
            .chain(record.values())
            .collect(),
        })
    }

    /// The wire feeds (relative to nominal) of weld path `fragment` of `planned`, about to
    /// start: the height rule's for each deposit (what the scans of the deposits under them
    /// asked for; their mean for each with a welder that holds one feed per weld path).
    pub fn wire_feeds(&mut self, planned: &Planned, fragment: usize) -> Option<FeedSchedule> {
        let blocks = planned.found.fragments.get(fragment)?;
        let starts = planned
            .toolpath
            .executed_times()
            .deposits_s
            .get(fragment)?
            .clone();
        let (&first, &on) = (blocks.first()?, starts.first()?);
        let feeds = self.closed.path_feeds(blocks);
        self.arc_on.told = 0;
        self.arc_on.feeds = feeds.clone();
        Some(FeedSchedule {
            layer: planned.part.block(first)[2],
            starts_s: starts.iter().map(|t| t - on).collect(),
            feeds,
        })
    }

    /// While weld path `fragment` of `planned` is welded by a goal that began at
    /// `goal_start_s` (as for [`Replanner::welded`]), the controller's clock reading `now_s`:
    /// `readings` are fed to the loop, each after the deposits begun by its stamp are told.
    /// After a scan, the deposits that begin more than the setup's `wire_feed_lead_s` from now get
    /// their wire feeds again ([`ClosedLoop::revise_feeds`]): a path that climbs through
    /// the layers (a spiral) is corrected by the scans of the layers it has finished. Returns
    /// the revised rest of the schedule (timed from the arc strike) when a feed changed.
    pub fn during_weld(
        &mut self,
        planned: &Planned,
        fragment: usize,
        goal_start_s: f64,
        time_scale: f64,
        now_s: f64,
        readings: impl IntoIterator<Item = Measured>,
    ) -> Result<Option<FeedSchedule>, CellError> {
        // Called every few milliseconds while a weld goal runs: nothing to do most times.
        let readings: Vec<Measured> = readings.into_iter().collect();
        if readings.is_empty() {
            return Ok(None);
        }
        let times = planned.toolpath.executed_times();
        let (Some(blocks), Some(starts)) = (
            planned.found.fragments.get(fragment),
            times.deposits_s.get(fragment),
        ) else {
            return Ok(None);
        };
        let Some(&on) = starts.first() else {
            return Ok(None);
        };
        let trajectory_s = |clock_s: f64| on + (clock_s - goal_start_s) * time_scale;
        let mut scanned = false;
        for m in readings {
            let stamp = trajectory_s(m.stamp_s());
            self.tell(planned, fragment, goal_start_s, time_scale, |t, _| {
                t <= stamp
            })?;
            self.arc_on.fed.push(ReadingRef::of(&m));
            match self.closed.measured(&m) {
                Ok(()) => {
                    self.arc_on.used += 1;
                    scanned |= matches!(m, Measured::Scan { .. });
                }
                Err(e) => self.arc_on.ignored.push(e),
            }
        }
        let ahead = trajectory_s(now_s + self.setup.wire_feed_lead_s);
        let from = starts
            .iter()
            .position(|&t| t > ahead)
            .map(|j| j.max(self.arc_on.told));
        let (true, true, Some(from)) = (
            scanned,
            self.setup.wire_feed_per_deposit,
            from.filter(|&j| j < blocks.len() && self.arc_on.feeds.len() == blocks.len()),
        ) else {
            return Ok(None);
        };
        let feeds = self.closed.revise_feeds(&blocks[..from], &blocks[from..]);
        let same = feeds
            .iter()
            .zip(&self.arc_on.feeds[from..])
            .all(|(a, b)| a.to_bits() == b.to_bits());
        if same {
            return Ok(None);
        }
        self.arc_on.feeds[from..].copy_from_slice(&feeds);
        self.arc_on.revisions.push(FeedRevision {
            told: self.told.len(),
            fed: self.arc_on.fed.len(),
            weld_path: fragment + 1,
            from,
            feeds: feeds.clone(),
        });
        Ok(Some(FeedSchedule {
            layer: planned.part.block(blocks[from])[2],
            starts_s: starts[from..].iter().map(|t| t - on).collect(),
            feeds,
        }))
    }

    /// Weld path `fragment` of `planned` was welded by a goal that began at `goal_start_s`
    /// on the controller's clock, moving `time_scale` times as fast as the trajectory.
    pub fn welded(
        &mut self,
        planned: &Planned,
        fragment: usize,
        goal_start_s: f64,
        time_scale: f64,
    ) -> Result<(), CellError> {
        self.tell(planned, fragment, goal_start_s, time_scale, |_, _| true)?;
        self.arc_on.told = 0;
        self.welded = fragment + 1;
        Ok(())
    }

    /// Weld path `fragment` of `planned`, whose goal began at `goal_start_s` (as for
    /// [`Replanner::welded`]), was cut short: the arc went out at `fault_s` on the
    /// controller's clock. The block model welds whole blocks, so a deposit counts as
    /// welded when the fault came after its middle (the nearest deposit boundary); those
    /// are told to the loop, which marks the fault. `None` (nothing told) when every deposit
    /// of the path counts: it ended as planned, an ordinary boundary follows
    /// ([`Replanner::welded`]). With no deposit welded
    /// nothing is told (the path never began).
    pub fn cut_short(
        &mut self,
        planned: &Planned,
        fragment: usize,
        goal_start_s: f64,
        time_scale: f64,
        fault_s: f64,
    ) -> Result<Option<CutShort>, CellError> {
        let times = planned.toolpath.executed_times();
        let (Some(starts), Some(&off)) = (
            times.deposits_s.get(fragment),
            times.arc_off_s.get(fragment),
        ) else {
            return Err(CellError::OffPlan(format!(
                "weld path {} is not in the plan",
                fragment + 1
            )));
        };
        let on = starts.first().copied().unwrap_or(off);
        let trajectory_s = on + (fault_s - goal_start_s) * time_scale;
        let welded = |start: f64, end: f64| (start + end) / 2.0 <= trajectory_s;
        let ends = starts.iter().skip(1).copied().chain([off]);
        if starts.iter().zip(ends).all(|(&t, end)| welded(t, end)) {
            // Told by `welded` at the boundary that follows, as any weld path.
            return Ok(None);
        }
        let deposits = self.tell(planned, fragment, goal_start_s, time_scale, welded)?;
        self.arc_on.told = 0;
        if deposits > 0 {
            self.welded = fragment + 1;
            self.closed.path_ended();
        }
        let cut = CutShort {
            fragment,
            of: starts.len(),
            deposits,
            fault_s,
            trajectory_s,
        };
        self.cut = (deposits > 0).then(|| cut.clone());
        Ok(Some(cut))
    }

    /// Tells the loop the deposits of weld path `fragment` not told yet that
    /// `welded(start, end)` (their trajectory times) accepts, in order up to the first it
    /// does not; returns how many of the path are told.
    fn tell(
        &mut self,
        planned: &Planned,
        fragment: usize,
        goal_start_s: f64,
        time_scale: f64,
        welded: impl Fn(f64, f64) -> bool,
    ) -> Result<usize, CellError> {
        let times = planned.toolpath.executed_times();
        let (Some(blocks), Some(starts), Some(&off)) = (
            planned.found.fragments.get(fragment),
            times.deposits_s.get(fragment),
            times.arc_off_s.get(fragment),
        ) else {
            return Err(CellError::OffPlan(format!(
                "weld path {} is not in the plan",
                fragment + 1
            )));
        };
        let on = starts.first().copied().unwrap_or(off);
        let clock = |t: f64| goal_start_s + (t - on) / time_scale;
        let mut told = self.arc_on.told;
        for (j, (&b, &t)) in blocks.iter().zip(starts).enumerate().skip(told) {
            let end = starts.get(j + 1).copied().unwrap_or(off);
            if !welded(t, end) {
                break;
            }
            told += 1;
            self.arc_on.told = told;
            let (start_s, duration_s) = (clock(t), (end - t) / time_scale);
            self.closed.deposited(b, j == 0, start_s, duration_s)?;
            self.told.push(ToldDeposit {
                block: planned.part.block(b),
                arc_start: j == 0,
                start_s,
                duration_s,
            });
        }
        Ok(told)
    }

    /// At the boundary after the last weld path welded, with the robot standing on point
    /// `standing` of `planned`'s trajectory at `now_s`: the readings fed, the decision
    /// made, and a new remainder checked and moved from where the robot stands. `None`
    /// after the last weld path: nothing is left to re-plan.
    pub fn at_boundary(
        &mut self,
        planned: &Planned,
        readings: impl IntoIterator<Item = Measured>,
        standing: usize,
        max_points: usize,
        now_s: f64,
    ) -> Result<Option<Replan>, CellError> {
        let started = std::time::Instant::now();
        // Which readings had come by now (and while the arc was on) is a matter of
        // wall-clock timing: recorded.
        let arc_on = std::mem::take(&mut self.arc_on);
        let (mut used, mut fed, mut ignored) = (arc_on.used, arc_on.fed, arc_on.ignored);
        for m in readings {
            fed.push(ReadingRef::of(&m));
            match self.closed.measured(&m) {
                Ok(()) => used += 1,
                Err(e) => ignored.push(e),
            }
        }
        self.boundaries += 1;
        // The plan executed (not the loop's: a fault has split it already).
        let plan = (self.boundaries == 1).then(|| blocks(&planned.part, &planned.found.fragments));
        let record = BoundaryRecord {
            boundary: self.boundaries,
            now_s,
            deposits: std::mem::take(&mut self.told),
            readings: fed,
            feed_revisions: arc_on.revisions,
            plan,
            scan_margin_mm: self.setup.scan_margin_mm,
            wire_feed_limits: Some(self.setup.wire_feed),
            wire_feed_per_deposit: Some(self.setup.wire_feed_per_deposit),
            time_scale: self.setup.time_scale,
            timeout_s: self.setup.planner.timeout.map(|t| t.as_secs_f64()),
            decision: FINISHED.into(),
            changed: false,
            estimate: [f64::NAN; 4],
            fragments: blocks(&planned.part, &self.closed.fragments()),
            proven: false,
            cut_short: false,
        };
        if self.closed.next().is_none() {
            // Nothing is left to decide; the feeds revised while the last weld path's arc
            // was on are recorded all the same (`Replanner::finished`).
            if !record.feed_revisions.is_empty() {
                self.finished = Some((record, used, ignored.len()));
            }
            return Ok(None);
        }
        let cut = self.cut.take();
        let decision = self.closed.at_boundary(true, now_s)?;
        let e = &decision.estimate;
        let record = BoundaryRecord {
            decision: decision.reason.into(),
            changed: decision.changed,
            estimate: [e.loss, e.conduction, e.rmse_before_c, e.rmse_after_c],
            fragments: blocks(&planned.part, &decision.fragments()),
            proven: decision.proven,
            cut_short: cut.is_some(),
            ..record
        };
        let mut broken = Vec::new();
        let outcome = if decision.reason == "kept" {
            Outcome::Kept(NotTaken::NoCompletion)
        } else if !decision.changed && cut.is_none() {
            Outcome::Unchanged
        } else {
            // Windows the welded deposits already broke under the estimate are not judged
            // again: the check judges what is still to come.
            let (part, past) = self.closed.part_to_check(&decision);
            broken = past;
            match self.motion(planned, part, &decision, standing, max_points, cut.as_ref()) {
                Ok((new, steps, shift)) => {
                    self.shifts.extend(shift);
                    Outcome::New(Box::new(new), steps)
                }
                Err(why) => Outcome::Kept(why),
            }
        };
        match &outcome {
            Outcome::Kept(_) => self.closed.reject(&decision, now_s),
            _ => self.closed.adopt(&decision, now_s),
        }
        Ok(Some(Replan {
            decision,
            outcome,
            ignored,
            used,
            welded: self.welded,
            broken,
            latency_s: started.elapsed().as_secs_f64(),
            record,
            cut,
        }))
    }

    /// The decision's whole plan through the pipeline's stages, under the estimated model,
    /// and its steps after the weld paths welded. After an arc fault (`cut`) the plan is
    /// checked again on the time line the robot follows (the faults' shifts), and its steps
    /// go on from the cut path's retract; the new shift comes back with them.
    fn motion(
        &self,
        planned: &Planned,
        part: Part,
        decision: &Decision,
        standing: usize,
        max_points: usize,
        cut: Option<&CutShort>,
    ) -> Result<(Planned, Vec<Step>, Option<Shift>), NotTaken> {
        let chosen = ChosenPlan {
            fragments: decision.fragments(),
            stats: decision.stats.clone(),
            proven: decision.proven,
            worst_margin_s: decision.margin_s,
        };
        let opts = &self.setup.planner;
        let interrupt = Interrupt::after(opts.timeout).with_cancel(opts.cancel.clone());
        let new = self
            .setup
            .cell
            .motion_until(part.clone(), chosen, &interrupt)
            .map_err(NotTaken::Check)?;
        let times = new.toolpath.executed_times();
        let shift = match cut {
            Some(c) => Some(Shift {
                fragment: c.fragment,
                arc_off_s: c.trajectory_s,
                shift_s: c.trajectory_s
                    - times
                        .arc_off_s
                        .get(c.fragment)
                        .copied()
                        .ok_or(NotTaken::NoWeldPath(c.fragment + 1))?,
            }),
            None => None,
        };
        let shifts: Vec<Shift> = self.shifts.iter().copied().chain(shift).collect();
        if !shifts.is_empty() {
            check_executed_times(
                &part,
                &new.found.fragments,
                &shifted(times, &shifts),
                &interrupt,
            )
            .map_err(NotTaken::CheckAfterFault)?;
        }
        let steps = match cut {
            Some(c) => steps_after_fault(&new, c.fragment, max_points)?,
            None => steps_after(planned, &new, self.welded, standing, max_points)?,
        };
        Ok((new, steps, shift))
    }
}

/// The steps of `new` after its weld path `fragment` (from 0), the one an arc fault cut
/// short: from its retract on (the arc is out already; the robot moves to the retract from
/// where it stopped).
pub fn steps_after_fault(
    new: &Planned,
    fragment: usize,
    max_points: usize,
) -> Result<Vec<Step>, NotTaken> {
    let arc: Vec<bool> = new.trajectory.points.iter().map(|p| p.arc_on).collect();
    let steps = plan_steps(&arc, max_points);
    let weld = steps
        .iter()
        .position(|s| matches!(s, Step::Goal { welding: Some(w), .. } if *w == fragment))
        .ok_or(NotTaken::NoWeldPath(fragment + 1))?;
    match steps.get(weld + 1) {
        Some(Step::Arc(false)) => Ok(steps[weld + 2..].to_vec()),
        _ => Err(NotTaken::NoArcOff(fragment + 1)),
    }
}

/// Fragments of block indices as blocks of `part`.
fn blocks(part: &Part, fragments: &[Vec<usize>]) -> Vec<Vec<Block>> {
    fragments
        .iter()
        .map(|f| f.iter().map(|&i| part.block(i)).collect())
        .collect()
}

/// The steps of `new` after its weld path `welded` (1-based count) went out, when the robot
/// stands there as it does on point `standing` of `old`: same joints, same time on the
/// executed time line (the weld paths welded are the same in both plans).
pub fn steps_after(
    old: &Planned,
    new: &Planned,
    welded: usize,
    standing: usize,
    max_points: usize,
) -> Result<Vec<Step>, NotTaken> {
    let arc: Vec<bool> = new.trajectory.points.iter().map(|p| p.arc_on).collect();
    let steps = plan_steps(&arc, max_points);
    let weld = welded
        .checked_sub(1)
        .and_then(|f| {
            steps
                .iter()
                .position(|s| matches!(s, Step::Goal { welding: Some(w), .. } if *w == f))
        })
        .ok_or(NotTaken::NoWeldPath(welded))?;
    let (Step::Goal { span, .. }, Some(Step::Arc(false))) = (&steps[weld], steps.get(weld + 1))
    else {
        return Err(NotTaken::NoArcOff(welded));
    };
    let (a, b) = (
        &old.trajectory.points[standing],
        &new.trajectory.points[*span.end()],
    );
    let joints = a
        .positions
        .iter()
        .zip(&b.positions)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max);
    if a.positions.len() != b.positions.len() || joints > 1e-6 {
        return Err(NotTaken::NotWhereItStands(joints));
    }
    let dt = (a.time_from_start - b.time_from_start).abs();
    if dt > 1e-6 {
        return Err(NotTaken::OffTimeline(dt));
    }
    Ok(steps[weld + 2..].to_vec())
}
