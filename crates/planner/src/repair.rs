//! A repair of a warm start that breaks a t8/5 window, around the window the simulator
//! names: the plan is changed from one layer piece on (the layer the broken block stands on,
//! its own, and each layer welded until the window broke), re-simulated from the unchanged
//! prefix, and the change that keeps every window longest is kept; again, until a plan
//! keeps them all or no change gets further.
//!
//! Why these changes: a block's t8/5 is decided by when it and its neighbours are welded —
//! which way its layer goes round (so how soon the block above comes back over it) and
//! whether a weld path ends before its layer (a transit to cool in). The layer-by-layer
//! construction fixes both for every layer by its first; a plan that keeps the window may
//! differ only from some layer on. The changes at a piece: the rest of its weld path
//! mirrored over the piece's footprint (a ring: the other way round from the same start; an
//! open path: from its other end), and, while fewer than k weld paths are used, a new weld
//! path from there on, as it was or mirrored. A ring piece where a weld path starts (or may
//! start: the broken block's piece and the one under it) may also start further round: a path
//! climbing a tube keeps its seam near where it started, and a block's t8/5 depends on how
//! far it lies from the seam (just before it, the block above comes soon, while the block
//! is still hot; across the tube, a lap later), so the rotations tried put the start at
//! the broken block's column first, then 1, 2, 4, ... blocks either side. The first piece
//! of the broken block's weld path (its seam, which every layer's seam above follows) is
//! rotated too when no nearer change gets further: on a double tube that seam is the lever.
//! Which piece and change is kept is the simulator's verdict (the furthest first broken
//! window, counted in blocks welded): no threshold. Where the same block's Max window
//! breaks again, the count can mislead: a block staying between 500 and 800 °C breaks its
//! window `max_s` after it was last above 800 °C, so a later break may mean only that the
//! blocks above reheated it later, while what keeps the window may be that it dips below
//! 500 °C, where its time stops counting (the hidden plans of two generated tubes do so).
//! A repair that ends on such a break is tried again from its first plan, keeping at each
//! step the change under which that block got lowest in the band ([`Measure`]); as the
//! only measure, it lost a double tube whose repair needs the later reheat. A block
//! cooling too fast misleads the count the same way (reheated above 800 °C later, its
//! time starts afresh, as short): a repair that ends on one is tried again keeping at
//! each step the change that misses its window by least (a generated cup, none in 60 s
//! before, got its plan in 10 s so). When no
//! single change gets further, the ways round are searched ([`Repair::ways_round`]): each
//! piece welded while the broken block cools (from the one under it to the one its window
//! breaks in) going round as now or the other way, depth first from the break back, a way
//! that breaks a window before its next piece taken no further. A mirror turns every layer
//! above it too, where a generated part's hidden plan sets off each layer either way: a
//! box whose repair had missed a Min window by 100 s got its plan in 6 s so, where none
//! came in 60 s. The search simulates at most as many deposits as the plan has (what
//! judging one change of its first layer costs; 2^n ways of n pieces can cost more);
//! where it stops before judging every way, two mirrors at once are judged (a piece and a
//! later one: the layers between go round the other way, those above as they went), as
//! before: two generated double tubes whose repair had ended with a block one step too
//! long in the band, at 500.001 °C, got their plans through such pairs (9 s and 15 s,
//! where none came in 60 s). The mirrors and new weld paths of a step are
//! judged all up to the first that keeps every window (those after it could not be
//! chosen); the rotations (in order of promise) and the pairs up to the first that breaks
//! later than the plan now (the nearest start that helps: on a generated box,
//! judging all 26 of a first step took 6.2 s, eight of them simulated 6,000 deposits on to
//! the same far window; up to the first that got further, 0.7 s). Either way the choice
//! does not depend on the thread count.
//!
//! Why no wider neighbourhood: changes further down, down to the first layer, are what the
//! warm-start portfolio tries next (other starts and covers of the first layer, varisat's
//! plan), each judged whole. The repair once grew its neighbourhood back, twice as many
//! pieces each time no change got further, to the whole plan: on the 72 generated parts at
//! 10^4 blocks no repair got its plan that way (every one that succeeded did so around the
//! window), and on a T-wall the growing cost 6.8 s before the portfolio's fourth start kept
//! every window.
//!
//! How long: the first step ends at `yield_at` (half the time left when the repair began:
//! the search keeps the rest); once a step got further, the repair goes on to the run's
//! deadline. At 10^5 blocks one step re-simulates tens of thousands of deposits per change
//! (minutes), and a double tube's repair was cut off after a step that had got from 3,234
//! to 53,281 blocks, leaving the time to a search that found nothing in it.

use std::cell::RefCell;
use std::collections::{HashMap, HashSet};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;
use std::time::Instant;

use waam_part::graph::WeldGraph;
use waam_part::plan::Plan;
use waam_part::Part;
use waam_thermal::{Simulation, Snapshot, ThermalModel};

use crate::constructive::Limits;
use crate::prefix_cache::deposits;

/// What the repair works with.
pub struct Repair<'a> {
    pub part: &'a Part,
    pub graph: &'a WeldGraph,
    pub k: usize,
    pub model: &'a ThermalModel,
    pub limits: &'a Limits,
    /// When a repair's first step gives up (none: at the deadline); once a step got
    /// further, the repair goes on to the deadline.
    pub yield_at: Option<Instant>,
    /// Threads judging one step's candidates.
    pub workers: usize,
    /// Where the plan simulated so far may start from: a simulation of the longest prefix
    /// of the given deposits that is simulated already (the search's snapshots of the plan
    /// it judged), and its length; none: from the first deposit.
    pub resume: Option<&'a Resume<'a>>,
    /// Where the plans its runs got to first break a window, per [`Measure`] (empty at
    /// first: see [`Repair::repaired`]).
    pub(crate) reached: RefCell<[Vec<Broken>; MEASURES]>,
}

/// A simulation at the longest known prefix of a deposit sequence, and its length.
pub type Resume<'a> = dyn Fn(&[(usize, bool)]) -> (Simulation<'a>, usize) + 'a;

/// A plan simulated: `Ok(())` keeps every window, else where it first breaks one; `None`:
/// the run stopped the simulation.
type Verdict = Option<Result<(), Broken>>;

/// A changed warm start that keeps every window (repaired here, or a variant of the
/// portfolio's), and its simulation after its last deposit (before cooling down): the
/// search's own verdict on the plan resumes from there instead of simulating it again.
pub struct Repaired {
    pub plan: Vec<Vec<usize>>,
    pub end: Option<Snapshot>,
}

/// Where a plan first breaks a window: after how many blocks welded, whose window, and by
/// how much (s) the block's t8/5 misses it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Broken {
    blocks: usize,
    block: usize,
    miss_s: f64,
    /// The block cooled too fast (a Min window): its miss says how near the window is.
    too_fast: bool,
    /// A block that stayed too long between 500 and 800 °C (a Max window): the lowest it
    /// got there, °C (+inf: not known). Its miss is always about one step, but the nearer
    /// it came to 500 °C, the nearer it came to dipping below, where its time stops
    /// counting (the hidden plans of two generated tubes keep such a window that way).
    low_c: f64,
}

impl Broken {
    /// `v`, broken in `sim` after `welded` deposits.
    fn of(v: &waam_thermal::Violation, welded: usize, sim: &Simulation) -> Broken {
        let too_fast = v.kind == waam_thermal::ViolationKind::Min;
        Broken {
            blocks: v.prefix_len.max(welded),
            block: v.block,
            miss_s: (v.window.min_s - v.t85_s).max(v.t85_s - v.window.max_s),
            too_fast,
            low_c: match too_fast {
                true => f64::INFINITY,
                false => sim.lowest_in_band_c(v.block).unwrap_or(f64::INFINITY),
            },
        }
    }

    /// Whether `self` is the same block cooling too fast as `other`, missed by less,
    /// however many blocks come before the break: a seam moved round a ring moves when the
    /// block is welded. (A block staying too long in the band: see [`Measure`].)
    fn nearer_than(&self, other: &Broken) -> bool {
        self.block == other.block && self.too_fast && other.too_fast && self.miss_s < other.miss_s
    }

    /// Whether `self` gets further than `other` by `measure`: [`Broken::later_than`], or
    /// with [`Measure::Lower`] the same block staying too long in the band the lower it
    /// got there, with [`Measure::Nearer`] the same block cooling too fast the nearer its
    /// window.
    fn further_than(&self, other: &Broken, measure: Measure) -> bool {
        if measure == Measure::Nearer && (self.nearer_than(other) || other.nearer_than(self)) {
            return self.nearer_than(other);
        }
        if measure == Measure::Lower
            && self.block == other.block
            && !self.too_fast
            && !other.too_fast
            && self.low_c.is_finite()
            && self.low_c != other.low_c
        {
            return self.low_c < other.low_c;
        }
        self.later_than(other)
    }

    /// Whether the block stayed too long between 500 and 800 °C, and how low it got there
    /// is known.
    fn too_long_in_band(&self) -> bool {
        !self.too_fast && self.low_c.is_finite()
    }

    /// Whether `self` breaks later than `other`: more blocks welded before a window breaks,
    /// or as many with the same window missed by less. A batch of changes judged up to the
    /// first that gets further ends at the first that breaks later: that a block got lower
    /// in the band by a hundredth of a degree is no reason to leave the rest unjudged (on a
    /// generated box the rotation that kept every window came after one that did).
    fn later_than(&self, other: &Broken) -> bool {
        self.blocks > other.blocks
            || (self.blocks == other.blocks
                && self.block == other.block
                && self.miss_s < other.miss_s)
    }
}

/// For the repair's trace: "after 9977 blocks, block 8741 too long in the band by 0.01 s
/// (lowest 500.04 °C)".
impl std::fmt::Display for Broken {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let how = if self.too_fast {
            "too fast"
        } else {
            "too long in the band"
        };
        write!(
            f,
            "after {} blocks, block {} {how} by {:.2} s",
            self.blocks, self.block, self.miss_s
        )?;
        if self.low_c.is_finite() {
            write!(f, " (lowest {:.2} °C)", self.low_c)?;
        }
        Ok(())
    }
}

/// What gets a repair further when the same block's window breaks again. A Max window's
/// break may come later because the blocks above reheat the block above 800 °C later (its
/// time starts afresh: a generated double tube is repaired that way) or because it dips
/// below 500 °C (its time stops counting: two generated tubes are repaired that way, and
/// there a later break says only the first, and misleads). A Min window's break comes
/// later when the blocks above reheat the block above 800 °C again, its time starting
/// afresh as short or shorter: on a generated cup a later break had missed by 86 s where
/// the plan before had missed by 12, and only the misses getting smaller led to a plan.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Measure {
    /// More blocks before a window breaks.
    Later,
    /// For the same block staying too long in the band: lower there.
    Lower,
    /// For the same block cooling too fast: its window missed by less.
    Nearer,
}

/// How many [`Measure`]s there are (a repair keeps the states its runs reached per measure).
const MEASURES: usize = 3;

/// The blocks `i..j` of weld path `f`, all in one layer; `at`: deposits before it.
#[derive(Debug, Clone, Copy)]
struct Piece {
    f: usize,
    i: usize,
    j: usize,
    at: usize,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
enum Change {
    Mirror,
    NewPath,
    NewPathMirrored,
    /// A ring piece started `r` blocks further round (same way round), the rest of its
    /// weld path rotated with it: at a weld path's first piece in place, elsewhere as a
    /// new weld path.
    Rotate(usize),
    /// Mirrored here and again at the later piece that begins this many deposits in: the
    /// pieces between go the other way, those from it on as they went (where a mirror
    /// turns every piece after it too).
    MirrorTwice(usize),
    /// Each piece from here to the break turned or not, as [`Repair::ways_round`] found
    /// (this many of them turned).
    WaysRound(usize),
}

impl<'a> Repair<'a> {
    /// A plan that keeps every window, changed from `plan` (valid, breaking a window after
    /// `broken` blocks); `None` when no sequence of changes gets there (or the run stopped).
    /// A run that gets to where an earlier run of this repair got (the same window broken
    /// after as many blocks, missed by the same amount to the bit: the same plan up to
    /// there, as far as the simulator can tell) ends there: the earlier run went on from
    /// that point without keeping every window (on a cup, a raster's repair retraced the
    /// first repair's steps to its dead end, 13 s), and, where that run was an earlier
    /// call's, is not tried again by another measure (that run went on to that too).
    /// A repair that gets more blocks welded each step ([`Measure::Later`]) and ends on a
    /// block staying too long in the band is tried again from `plan`, each step getting
    /// that block lower there ([`Measure::Lower`]); one that ends on a block cooling too
    /// fast, each step missing that block's window by less ([`Measure::Nearer`]).
    pub fn repaired(&self, plan: &[Vec<usize>], blocks: usize, block: usize) -> Option<Repaired> {
        // The states earlier calls' runs got to: a run that gets to one of them ends, and
        // what that run went on to do (trying again by another measure too) is not redone.
        let known: [usize; MEASURES] = std::array::from_fn(|i| self.reached.borrow()[i].len());
        let mut ended = None;
        let found = self.repaired_by(plan, (blocks, block), Measure::Later, known, &mut ended);
        if found.is_some() {
            return found;
        }
        let again = match ended {
            Some(b) if b.too_long_in_band() => Measure::Lower,
            Some(b) if b.too_fast => Measure::Nearer,
            _ => return None,
        };
        if self.limits.stopped() {
            return None;
        }
        tracing::debug!("warm-start repair: again, by {again:?}");
        self.repaired_by(plan, (blocks, block), again, known, &mut ended)
    }

    /// [`Repair::repaired`] by one measure; `ended`: where the last plan it had breaks a
    /// window (none when the run got to one of the first `known` states an earlier call's
    /// runs got to, by this measure).
    fn repaired_by(
        &self,
        plan: &[Vec<usize>],
        (blocks, block): (usize, usize),
        by: Measure,
        known: [usize; MEASURES],
        ended: &mut Option<Broken>,
    ) -> Option<Repaired> {
        let mut plan = plan.to_vec();
        // By how much it is missed is measured in the first step.
        let mut broken = Broken {
            blocks,
            block,
            miss_s: f64::INFINITY,
            too_fast: false,
            low_c: f64::INFINITY,
        };
        let mut step = 0;
        // The plan now simulated up to some deposits (the prefix every later plan shares up
        // to where it is changed).
        let mut saved: Vec<(usize, Simulation)> = Vec::new();
        // Whether a step got further: the next may then run to the deadline.
        let mut got_further = false;
        loop {
            // This step's end: the deadline, or the time to yield before a step got further.
            let until = match (self.limits.deadline, self.yield_at) {
                (d, Some(y)) if !got_further => Some(d.map_or(y, |d| d.min(y))),
                (d, _) => d,
            };
            let this_step = Limits {
                deadline: until,
                cancel: self.limits.cancel.clone(),
            };
            if this_step.stopped() {
                return None;
            }
            step += 1;
            let pieces = pieces(self.part, &plan);
            let seq = deposits(&plan);
            let anchor = self.first_piece_to_change(&pieces, &seq, broken.block);
            // The broken block's own piece (the anchor's or a later one).
            let own = seq
                .iter()
                .position(|&(b, _)| b == broken.block)
                .and_then(|at| pieces.iter().rposition(|p| p.at <= at))
                .unwrap_or(anchor);
            let around = pieces[anchor].at..=pieces[own.max(anchor)].at;
            // The changes that give a valid plan.
            let valid = |changes: Vec<(Piece, Change)>| -> Vec<_> {
                changes
                    .into_iter()
                    .filter_map(|(p, c)| Some((p, c, self.changed(&plan, p, c)?)))
                    .collect()
            };
            let near = valid(
                pieces[anchor..]
                    .iter()
                    .filter(|p| p.at < broken.blocks)
                    .flat_map(|&p| {
                        let rotations = if p.i == 0 || around.contains(&p.at) {
                            self.rotations(&plan, p, broken.block)
                        } else {
                            Vec::new()
                        };
                        [Change::Mirror, Change::NewPath, Change::NewPathMirrored]
                            .into_iter()
                            .chain(rotations.into_iter().map(Change::Rotate))
                            .map(move |c| (p, c))
                    })
                    .collect(),
            );
            // The seam of the broken block's weld path (its first piece), when it lies below
            // the anchor: where the path starts decides every layer's seam above it.
            let own_path = pieces[own.max(anchor)].f;
            let seam = pieces
                .iter()
                .position(|p| p.f == own_path)
                .filter(|&s| s < anchor)
                .map(|s| pieces[s]);
            let seam_rotated = valid(
                seam.into_iter()
                    .flat_map(|p| {
                        self.rotations(&plan, p, broken.block)
                            .into_iter()
                            .map(move |r| (p, Change::Rotate(r)))
                    })
                    .collect(),
            );
            if near.is_empty() && seam_rotated.is_empty() {
                tracing::debug!(
                    "warm-start repair: step {step}: no change gets past {} blocks",
                    broken.blocks
                );
                return None;
            }
            // The rotations (many, each re-simulating a weld path from its start) are
            // judged only when no mirror or new weld path keeps every window, and only up
            // to the first that breaks later; the seam's (re-simulating the plan from the
            // path's start) only when nothing nearer breaks later either.
            let (plain, rotated): (Vec<_>, Vec<_>) = near
                .into_iter()
                .partition(|(_, c, _)| !matches!(c, Change::Rotate(_)));
            // Where a mirror is valid: two of them at once are judged when no single
            // change gets further.
            let mirrored: Vec<Piece> = plain
                .iter()
                .filter(|(_, c, _)| *c == Change::Mirror)
                .map(|&(p, _, _)| p)
                .collect();
            let mut batches = [plain, rotated, seam_rotated];
            let mut candidates = Vec::new();
            let mut verdicts: Vec<Verdict> = Vec::new();
            // The first feasible candidate's simulation at its end.
            let mut end = None;
            // The states kept by the candidates that may be chosen.
            let mut kept = Vec::new();
            // Whether the search over the ways round judged every way (the pairs are
            // among them).
            let mut every_way = false;
            for n in 0..5 {
                let further = |v: &Verdict| matches!(v, Some(Err(b)) if b.later_than(&broken));
                if n == 2 && verdicts.iter().any(further) {
                    break;
                }
                let got_further = verdicts
                    .iter()
                    .any(|v| matches!(v, Some(Err(b)) if b.further_than(&broken, by)));
                // When no single change got further: each piece up to the break turned or
                // not, searched; its plan that gets furthest is one more candidate.
                if n == 3 {
                    if got_further {
                        break;
                    }
                    let to = pieces
                        .iter()
                        .rposition(|p| p.at < broken.blocks)
                        .unwrap_or(anchor)
                        .max(anchor);
                    let sim = self.state_at(&seq, pieces[anchor].at, &saved)?;
                    let t = Instant::now();
                    // At most as many deposits as the plan has: what judging a change
                    // of its first layer costs.
                    let budget = seq.len();
                    let ways =
                        self.ways_round(&plan, &pieces, (anchor, to), sim, budget, until, by);
                    let furthest = match &ways.best {
                        Some((turned, _, Some(Ok(())))) => {
                            format!("{turned} turned: keeps every window")
                        }
                        Some((turned, _, Some(Err(b)))) => format!("{turned} turned: {b}"),
                        _ => "no way judged".into(),
                    };
                    tracing::debug!(
                        "warm-start repair: step {step}: the ways round of pieces {anchor}..={to} judged in {:.2} s ({}): furthest {furthest}",
                        t.elapsed().as_secs_f64(),
                        if ways.every_way { "every way" } else { "stopped short" },
                    );
                    if ways.stopped && this_step.stopped() {
                        return None;
                    }
                    every_way = ways.every_way;
                    if let Some((turned, found, verdict)) = ways.best {
                        if let Some(snap) = ways.end {
                            end = end.or(Some((candidates.len(), snap)));
                        }
                        candidates.push((pieces[anchor], Change::WaysRound(turned), found));
                        verdicts.push(verdict);
                    }
                    if verdicts.iter().any(|v| matches!(v, Some(Ok(())))) {
                        break;
                    }
                    continue;
                }
                // The mirrors and new paths, the rotations, the seam's rotations; last the
                // pairs of mirrors, built only when nothing got further and the search over
                // the ways round stopped before judging them all.
                let batch = match batches.get_mut(n) {
                    Some(batch) => std::mem::take(batch),
                    None if got_further || every_way => break,
                    None => valid(
                        mirrored
                            .iter()
                            .enumerate()
                            .flat_map(|(a, &p)| {
                                mirrored[a + 1..]
                                    .iter()
                                    .map(move |q| (p, Change::MirrorTwice(q.at)))
                            })
                            .collect(),
                    ),
                };
                if batch.is_empty() {
                    continue;
                }
                // How far the plan now gets is measured once, with the first candidates.
                let measure = broken.miss_s.is_infinite() && candidates.is_empty();
                // Every mirror and new weld path; the rotations (nearest the broken
                // block's column first) up to the first that breaks later.
                let first_further = n > 0;
                let judged = self.judge(
                    &seq,
                    &batch,
                    &mut saved,
                    (measure, broken, by),
                    first_further,
                    until,
                );
                let offset = candidates.len();
                end = end.or(judged.end.map(|(c, snap)| (offset + c, snap)));
                if judged.verdicts.iter().any(Option::is_none) && this_step.stopped() {
                    return None;
                }
                if let Some(Err(now)) = judged.now.filter(|_| measure) {
                    broken = now;
                }
                for (c, b, states) in judged.states {
                    keep(&mut kept, offset + c, b, states, by);
                }
                candidates.extend(batch);
                verdicts.extend(judged.verdicts);
                if verdicts.iter().any(|v| matches!(v, Some(Ok(())))) {
                    break;
                }
            }
            for ((p, c, _), v) in candidates.iter().zip(&verdicts) {
                tracing::trace!(
                    "warm-start repair: step {step}: {c:?} at piece {} ({} blocks in): {v:?}",
                    p.at,
                    p.i
                );
            }
            // A plan that keeps every window (the first such); else the one that breaks
            // one latest (ties: the first), if later than now.
            let feasible = verdicts.iter().position(|v| matches!(v, Some(Ok(()))));
            if let Some(c) = feasible {
                tracing::debug!(
                    "warm-start repair: step {step}: {:?} at {:?} keeps every window",
                    candidates[c].1,
                    self.part.block(plan[candidates[c].0.f][candidates[c].0.i])
                );
                return candidates.into_iter().nth(c).map(|(_, _, plan)| Repaired {
                    plan,
                    end: end.filter(|(e, _)| *e == c).map(|(_, snap)| snap),
                });
            }
            let best = verdicts
                .iter()
                .enumerate()
                .filter_map(|(c, v)| match v {
                    Some(Err(b)) => Some((c, *b)),
                    _ => None,
                })
                // The first of those that get furthest.
                .fold(None, |best: Option<(usize, Broken)>, (c, b)| match best {
                    Some((_, kept)) if !b.further_than(&kept, by) => best,
                    _ => Some((c, b)),
                });
            // None gets further: the one that misses the same too-fast window by least, if
            // by less than now (the step does not count as getting further).
            let nearer = || {
                verdicts
                    .iter()
                    .enumerate()
                    .filter_map(|(c, v)| match v {
                        Some(Err(b)) if b.nearer_than(&broken) => Some((c, *b)),
                        _ => None,
                    })
                    // The first of those nearest.
                    .min_by(|(_, a), (_, b)| a.miss_s.total_cmp(&b.miss_s))
            };
            *ended = Some(broken);
            let (chosen, ahead) = match best.filter(|(_, b)| b.further_than(&broken, by)) {
                Some(best) => (Some(best), true),
                None => (nearer(), false),
            };
            let Some((c, further)) = chosen else {
                tracing::debug!(
                    "warm-start repair: step {step}: none of {} changes gets past {} blocks",
                    candidates.len(),
                    broken.blocks
                );
                return None;
            };
            tracing::debug!(
                "warm-start repair: step {step}: {:?} at {:?} of {} changes: a window breaks {further}; before: {broken}",
                candidates[c].1,
                self.part.block(plan[candidates[c].0.f][candidates[c].0.i]),
                candidates.len(),
            );
            let i = by as usize;
            if let Some(at) = self.reached.borrow()[i].iter().position(|b| *b == further) {
                tracing::debug!(
                    "warm-start repair: step {step}: an earlier repair got here and no further"
                );
                if at < known[i] {
                    *ended = None;
                }
                return None;
            }
            self.reached.borrow_mut()[i].push(further);
            let changed_at = candidates[c].0.at;
            plan = candidates.into_iter().nth(c).map(|(_, _, plan)| plan)?;
            broken = further;
            *ended = Some(broken);
            got_further |= ahead;
            saved.retain(|&(at, _)| at <= changed_at);
            // The chosen plan's states from its run, where the next step may change it.
            if let Some((_, _, states)) = kept.into_iter().find(|(k, _, _)| *k == c) {
                saved.extend(states);
            }
        }
    }

    /// The index (in `pieces`) of the first piece a change may start at: the piece of the
    /// block under the broken one when it has one (the broken block's heat starts there),
    /// else the broken block's own piece.
    fn first_piece_to_change(
        &self,
        pieces: &[Piece],
        seq: &[(usize, bool)],
        block: usize,
    ) -> usize {
        let [x, y, z] = self.part.block(block);
        let under = self.part.index_of([x, y, z - 1]);
        let position = |b: usize| seq.iter().position(|&(s, _)| s == b);
        let at = under
            .and_then(position)
            .or_else(|| position(block))
            .unwrap_or(0);
        pieces.iter().rposition(|p| p.at <= at).unwrap_or(0)
    }

    /// The rotations worth trying of a ring piece (a weld path's first, or where a new
    /// weld path may start, next to the broken block): those that start it at the ring
    /// block nearest to the broken block's column, and 1, 2, 4, ... blocks either side of
    /// it, in that order. Where a ring starts is where its seam lies, and a weld path climbing a tube keeps
    /// its seam near there: a block just before the seam gets the block above it soon
    /// after, hot (long t8/5), one far from it only after a lap (short). None on a piece
    /// that is no ring.
    fn rotations(&self, plan: &[Vec<usize>], piece: Piece, broken: usize) -> Vec<usize> {
        let blocks = &plan[piece.f][piece.i..piece.j];
        let n = blocks.len();
        if !is_ring(self.graph, blocks) {
            return Vec::new();
        }
        let [bx, by, _] = self.part.block(broken);
        let nearest = (0..n)
            .min_by_key(|&m| {
                let [x, y, _] = self.part.block(blocks[m]);
                ((x - bx).abs() + (y - by).abs(), m)
            })
            .expect("a ring has blocks");
        let mut out: Vec<usize> = std::iter::once(0)
            .chain(
                std::iter::successors(Some(1usize), |d| Some(2 * d)).take_while(|&d| d < n / 2 + 1),
            )
            .flat_map(|d| [(nearest + d) % n, (nearest + n - d % n) % n])
            .filter(|&r| r != 0)
            .collect();
        // Nearest first: those after the first that breaks later (or keeps every window)
        // are not judged (on a double tube the column's own rotation came eighth of
        // fifteen when sorted by index, 0.75 s of simulation each).
        let mut seen = HashSet::new();
        out.retain(|&r| seen.insert(r));
        out
    }

    /// `plan` with `change` made at `piece`; `None` when that is not a valid plan.
    fn changed(
        &self,
        plan: &[Vec<usize>],
        piece: Piece,
        change: Change,
    ) -> Option<Vec<Vec<usize>>> {
        let new_path = match change {
            Change::NewPath | Change::NewPathMirrored => true,
            Change::Rotate(_) => piece.i > 0,
            Change::Mirror => false,
            Change::WaysRound(_) => return None,
            Change::MirrorTwice(at) => {
                let once = self.changed(plan, piece, Change::Mirror)?;
                let then = pieces(self.part, &once).into_iter().find(|p| p.at == at)?;
                return self.changed(&once, then, Change::Mirror);
            }
        };
        if new_path && (piece.i == 0 || plan.len() >= self.k) {
            return None;
        }
        let mut tail = plan[piece.f][piece.i..].to_vec();
        let blocks = &plan[piece.f][piece.i..piece.j];
        let map = match change {
            Change::Mirror | Change::NewPathMirrored => {
                Some(mirror(self.part, self.graph, blocks)?)
            }
            Change::Rotate(r) => Some(rotation(self.part, self.graph, blocks, r)?),
            Change::NewPath | Change::MirrorTwice(_) | Change::WaysRound(_) => None,
        };
        if let Some(map) = map {
            for b in &mut tail {
                let [x, y, z] = self.part.block(*b);
                let &(x, y) = map.get(&(x, y))?;
                *b = self.part.index_of([x, y, z])?;
            }
        }
        // A change that changes nothing (a new weld path changes where one starts).
        if !new_path && tail == plan[piece.f][piece.i..] {
            return None;
        }
        let mut out = plan.to_vec();
        out[piece.f].truncate(piece.i);
        if new_path {
            out.insert(piece.f + 1, tail);
        } else {
            out[piece.f].extend(tail);
        }
        Plan::from_indices(self.part, &out)
            .validate(self.part, self.graph)
            .ok()?;
        Some(out)
    }

    /// Each candidate simulated from the prefix it shares with `seq` (the plan now, which
    /// breaks a window at `broken`, measured again when `measure`), on `workers` threads;
    /// slot i holds candidate i's verdict whichever thread judged it. The candidates are
    /// judged up to the first that keeps every window, or with `first_further` up to the
    /// first that breaks later than the plan now ([`Broken::later_than`]): those after it
    /// are not judged (their slots stay empty), on any number of threads.
    fn judge<'s>(
        &'s self,
        seq: &[(usize, bool)],
        candidates: &[(Piece, Change, Vec<Vec<usize>>)],
        saved: &mut Vec<(usize, Simulation<'s>)>,
        (measure, broken, by): (bool, Broken, Measure),
        first_further: bool,
        until: Option<Instant>,
    ) -> Judged<'s> {
        // The plan now, simulated once up to each candidate's first change (from the
        // latest state saved before the first not saved yet).
        let mut starts: Vec<usize> = candidates.iter().map(|(p, _, _)| p.at).collect();
        starts.sort_unstable();
        starts.dedup();
        let last = starts[starts.len() - 1];
        let first = starts
            .iter()
            .copied()
            .find(|&s| !saved.iter().any(|(at, _)| *at == s))
            .unwrap_or(last);
        let (from, sim) = self.state_before(seq, first, saved);
        // Alone until the candidates are judged: on every thread; stopped at this step's end.
        let mut sim = sim.with_deadline(until);
        sim.set_threads(self.workers);
        for (d, &(b, new)) in seq.iter().enumerate().take(last + 1).skip(from) {
            if starts.binary_search(&d).is_ok() && !saved.iter().any(|(at, _)| *at == d) {
                saved.push((d, sim.clone()));
            }
            if d == last {
                break;
            }
            // The plan now keeps every window up to the broken one, after every start.
            if sim.deposit(b, new).is_err() || sim.cancelled() {
                return Judged {
                    verdicts: vec![None; candidates.len()],
                    ..Judged::default()
                };
            }
        }
        saved.sort_by_key(|(at, _)| *at);
        // The plan now, on to where it breaks (how much it misses its window by).
        let now = if measure {
            run_from(sim, seq, last, (&[], 0), &|| Some(self.workers)).verdict
        } else {
            None
        };
        let saved = &*saved;
        let broken = match now {
            Some(Err(now)) => now,
            _ => broken,
        };
        let next = AtomicUsize::new(0);
        // The candidate that ends the judging: the first found to keep every window (or,
        // with `first_further`, to break later); a later one is not judged, or no further
        // (the choice stays the same on any number of threads).
        let last_judged = AtomicUsize::new(usize::MAX);
        let ends_judging = |v: &Verdict| match v {
            Some(Ok(())) => true,
            Some(Err(b)) => first_further && b.later_than(&broken),
            None => false,
        };
        // Candidates being simulated. The last one still running (often the one that gets
        // furthest, simulated far beyond the others) steps on every thread, not on one
        // while the others idle; one after the one that ends the judging stops (it cannot be
        // chosen).
        let running = AtomicUsize::new(0);
        let workers = self.workers;
        let states_per_run = kept_states(self.part.len(), workers);
        let threads = |c: usize| {
            if c > last_judged.load(Ordering::Relaxed) {
                return None;
            }
            let alone = next.load(Ordering::Relaxed) >= candidates.len()
                && running.load(Ordering::Relaxed) == 1;
            Some(if alone { workers } else { 1 })
        };
        let results: Mutex<Vec<Verdict>> = Mutex::new(vec![None; candidates.len()]);
        // The end state of the feasible candidate of the lowest index.
        let end: Mutex<Option<(usize, Snapshot)>> = Mutex::new(None);
        // The states kept by candidates that may be chosen (see [`Judged::states`]).
        let states: Mutex<Vec<KeptStates<'s>>> = Mutex::new(Vec::new());
        std::thread::scope(|scope| {
            for _ in 0..self.workers.clamp(1, candidates.len().max(1)) {
                scope.spawn(|| loop {
                    let c = next.fetch_add(1, Ordering::Relaxed);
                    let Some((piece, _, plan)) = candidates.get(c) else {
                        break;
                    };
                    if c > last_judged.load(Ordering::Relaxed) {
                        continue;
                    }
                    let Some((_, sim)) = saved.iter().find(|(at, _)| *at == piece.at) else {
                        continue;
                    };
                    running.fetch_add(1, Ordering::Relaxed);
                    let t = std::time::Instant::now();
                    let sim = sim.clone().with_deadline(until);
                    let piece_starts: Vec<usize> =
                        pieces(self.part, plan).iter().map(|p| p.at).collect();
                    let run = run_from(
                        sim,
                        &deposits(plan),
                        piece.at,
                        (&piece_starts, states_per_run),
                        &|| threads(c),
                    );
                    let verdict = run.verdict;
                    running.fetch_sub(1, Ordering::Relaxed);
                    tracing::trace!(
                        "warm-start repair: candidate {c} judged in {:.2} s",
                        t.elapsed().as_secs_f64()
                    );
                    if ends_judging(&verdict) {
                        last_judged.fetch_min(c, Ordering::Relaxed);
                    }
                    if matches!(verdict, Some(Ok(()))) {
                        let mut end = end.lock().expect("no worker panics");
                        if end.as_ref().is_none_or(|(e, _)| c < *e) {
                            *end = run.end.map(|snap| (c, snap));
                        }
                    }
                    if let Some(Err(b)) = verdict {
                        keep(
                            &mut states.lock().expect("no worker panics"),
                            c,
                            b,
                            run.states,
                            by,
                        );
                    }
                    results.lock().expect("no worker panics")[c] = verdict;
                });
            }
        });
        // Those after the one that ended the judging may have been judged on another
        // thread before it ended: dropped, as on one thread.
        let last = last_judged.into_inner();
        let mut verdicts = results.into_inner().expect("no worker panics");
        verdicts
            .iter_mut()
            .skip(last.saturating_add(1))
            .for_each(|v| *v = None);
        let mut states = states.into_inner().expect("no worker panics");
        states.retain(|(c, _, _)| *c <= last);
        Judged {
            now,
            verdicts,
            end: end
                .into_inner()
                .expect("no worker panics")
                .filter(|(c, _)| *c <= last),
            states,
        }
    }

    /// The latest state of the plan now (`seq`) at or before deposit `at` — one saved, else
    /// the search's, else none simulated — and where it is.
    fn state_before<'s>(
        &'s self,
        seq: &[(usize, bool)],
        at: usize,
        saved: &[(usize, Simulation<'s>)],
    ) -> (usize, Simulation<'s>) {
        match saved.iter().rev().find(|(s, _)| *s <= at) {
            Some((s, sim)) => (*s, sim.clone()),
            None => match self.resume {
                Some(resume) => {
                    let (sim, s) = resume(&seq[..at]);
                    (s, self.limited(sim))
                }
                None => (0, self.simulation()),
            },
        }
    }

    /// The plan now (`seq`) simulated up to deposit `at`, from the latest state saved at
    /// or before it; `None` when the run stopped.
    fn state_at<'s>(
        &'s self,
        seq: &[(usize, bool)],
        at: usize,
        saved: &[(usize, Simulation<'s>)],
    ) -> Option<Simulation<'s>> {
        let (from, mut sim) = self.state_before(seq, at, saved);
        sim.set_threads(self.workers);
        for &(b, new) in &seq[from..at] {
            if sim.deposit(b, new).is_err() || sim.cancelled() {
                return None;
            }
        }
        Some(sim)
    }

    /// The pieces `from..=to` (from the one under the broken block to the one it breaks
    /// in) each going round as now or turned: a mirror there, which turns every piece after
    /// it too, so each is turned against the one before it. A block's t8/5 is set by which
    /// way each layer welded while it cools goes round (where a layer's seam lies follows
    /// from the layers before), and a generated tube's hidden plan sets off each layer
    /// either way: a single change or a pair turns at most two of them alone.
    /// Depth first, each piece as now before turned (so the pieces nearest the break are
    /// changed first, and a way shares its prefix with the one before); a way that breaks
    /// a window before its next piece is not taken further (what comes after cannot
    /// mend it). Up to the first plan that keeps every window, `budget` deposits simulated
    /// or `until`. `sim`: the plan simulated up to piece `from`.
    #[allow(clippy::too_many_arguments)]
    fn ways_round<'s>(
        &'s self,
        plan: &[Vec<usize>],
        pieces: &[Piece],
        (from, to): (usize, usize),
        sim: Simulation<'s>,
        budget: usize,
        until: Option<Instant>,
        by: Measure,
    ) -> WaysRound {
        let mut left = budget;
        let mut ways = WaysRound {
            best: None,
            end: None,
            every_way: false,
            stopped: false,
        };
        let mut note = |turned: usize, plan: Vec<Vec<usize>>, verdict: Result<(), Broken>| {
            let further = match (&verdict, &ways.best) {
                (Ok(()), _) | (_, None) => true,
                (Err(b), Some((_, _, Some(Err(best))))) => b.further_than(best, by),
                _ => false,
            };
            if further {
                ways.best = Some((turned, plan, Some(verdict)));
            }
        };
        // Ways to take on: a plan, the piece of it to simulate next (its way decided), how
        // many pieces it turned, and the state at that piece's start. The last pushed is
        // taken first.
        let mut sim = sim.with_deadline(until);
        sim.set_threads(self.workers);
        let mut stack = Vec::new();
        let turn = |plan: &[Vec<usize>], j: usize| self.changed(plan, pieces[j], Change::Mirror);
        if let Some(turned) = turn(plan, from) {
            stack.push((turned, from, 1, sim.clone()));
        }
        stack.push((plan.to_vec(), from, 0, sim));
        while let Some((plan, j, turned, mut sim)) = stack.pop() {
            let p = pieces[j];
            let next = p.at + (p.j - p.i);
            let Some(spent) = left.checked_sub(p.j - p.i) else {
                return ways;
            };
            left = spent;
            let mut broke = None;
            // The piece's own deposits: the whole plan's sequence only for a way's rest.
            for (k, &b) in plan[p.f][p.i..p.j].iter().enumerate() {
                if let Err(v) = sim.deposit(b, p.i + k == 0) {
                    broke = Some(Broken::of(&v, p.at + k + 1, &sim));
                    break;
                }
                if sim.cancelled() {
                    ways.stopped = true;
                    return ways;
                }
            }
            if let Some(b) = broke {
                // The plan as it is breaks where it did: known.
                if turned > 0 {
                    note(turned, plan, Err(b));
                }
                continue;
            }
            if j < to {
                if let Some(other) = turn(&plan, j + 1) {
                    stack.push((other, j + 1, turned + 1, sim.clone()));
                }
                stack.push((plan, j + 1, turned, sim));
                continue;
            }
            if turned == 0 {
                continue;
            }
            // Every piece up to the break decided: the rest of the plan.
            let seq = deposits(&plan);
            let Some(spent) = left.checked_sub(seq.len() - next) else {
                return ways;
            };
            left = spent;
            let run = run_from(sim, &seq, next, (&[], 0), &|| Some(self.workers));
            match run.verdict {
                None => {
                    ways.stopped = true;
                    return ways;
                }
                Some(Ok(())) => {
                    note(turned, plan, Ok(()));
                    ways.end = run.end;
                    return ways;
                }
                Some(Err(b)) => note(turned, plan, Err(b)),
            }
        }
        ways.every_way = true;
        ways
    }

    fn simulation(&self) -> Simulation<'a> {
        self.limited(Simulation::new(self.model))
    }

    /// `sim` on one thread, stopped with the run.
    fn limited(&self, sim: Simulation<'a>) -> Simulation<'a> {
        let sim = sim.with_threads(1).with_deadline(self.limits.deadline);
        match &self.limits.cancel {
            Some(c) => sim.with_cancel(c.clone()),
            None => sim,
        }
    }
}

/// A step's candidates judged.
#[derive(Default)]
struct Judged<'s> {
    /// Where the plan now breaks its window (when measured).
    now: Verdict,
    /// Candidate i's verdict in slot i.
    verdicts: Vec<Verdict>,
    /// The first feasible candidate's index and its state after its last deposit.
    end: Option<(usize, Snapshot)>,
    /// The states the candidates that may be chosen kept from their runs.
    states: Vec<KeptStates<'s>>,
}

/// What [`Repair::ways_round`] found.
struct WaysRound {
    /// The way that got furthest (the first that keeps every window, else the first of
    /// those that break one latest): how many pieces it turned, its plan, its verdict.
    best: Option<(usize, Vec<Vec<usize>>, Verdict)>,
    /// A feasible way's state after its last deposit.
    end: Option<Snapshot>,
    /// Every way judged.
    every_way: bool,
    /// The run stopped it.
    stopped: bool,
}

/// A candidate's index, where it breaks a window, and the states its run kept.
type KeptStates<'s> = (usize, Broken, Vec<(usize, Simulation<'s>)>);

/// How many candidates' states are kept at most: those that break a window latest (only
/// those can be chosen), the lowest indices first (a tie goes to the first).
const KEPT_CANDIDATES: usize = 4;

/// Adds candidate `c`'s states (it breaks a window at `b`) to `kept` when it may be chosen:
/// none kept so far gets further (those it gets further than are dropped), and fewer than
/// [`KEPT_CANDIDATES`] kept are left, or it comes before one of them. Only speed depends on
/// it: a chosen candidate whose states were dropped is simulated again.
fn keep<'s>(
    kept: &mut Vec<KeptStates<'s>>,
    c: usize,
    b: Broken,
    states: Vec<(usize, Simulation<'s>)>,
    measure: Measure,
) {
    if states.is_empty() || kept.iter().any(|(_, k, _)| k.further_than(&b, measure)) {
        return;
    }
    kept.retain(|(_, k, _)| !b.further_than(k, measure));
    kept.push((c, b, states));
    kept.sort_by_key(|(c, _, _)| *c);
    kept.truncate(KEPT_CANDIDATES);
}

/// A plan simulated from some deposit on.
struct Run<'m> {
    verdict: Verdict,
    /// The state after the last deposit, when the plan keeps every window.
    end: Option<Snapshot>,
    /// The states at the last asked deposits (`keep_at`) passed, at most as many as asked.
    states: Vec<(usize, Simulation<'m>)>,
}

/// The memory a step's candidates may keep states in: those at the starts of their last
/// pieces before the window each breaks. Chosen, a candidate is the next step's plan, and
/// the next step changes it from the piece under the broken block on, welded as long
/// before the break as the block's t8/5 lasts (five pieces back on a double tube): these
/// states spare simulating it again up to there (0.8 s of a 1.9 s step). Shared by the
/// runs under way (one per worker) and the [`KEPT_CANDIDATES`] kept: on 2 workers 32 MB
/// each, which at [`STATE_BYTES_PER_BLOCK`] holds fifty states at 10^4 blocks, five at 10^5.
const KEPT_STATES_BYTES: usize = 192 << 20;

/// A simulation's size per block of the part (temperatures before and after a step, the
/// neighbour slots, radiation, flags: 43 bytes per slot; the weld order: 13 per deposit).
const STATE_BYTES_PER_BLOCK: usize = 64;

/// How many states a candidate's run keeps on a part of `blocks` blocks, judged on
/// `workers` threads (at least two: the broken block's piece and the one under it).
fn kept_states(blocks: usize, workers: usize) -> usize {
    let each = KEPT_STATES_BYTES / (KEPT_CANDIDATES + workers.max(1));
    (each / (STATE_BYTES_PER_BLOCK * blocks.max(1))).max(2)
}

/// `seq` simulated on from deposit `from` (the simulation holds its prefix), each deposit
/// on as many threads as `threads` says then (none: no verdict is wanted any more),
/// keeping the states at the last `keep` deposits of `keep_at` (sorted) it passes (before
/// each is deposited).
fn run_from<'m>(
    mut sim: Simulation<'m>,
    seq: &[(usize, bool)],
    from: usize,
    (keep_at, keep): (&[usize], usize),
    threads: &dyn Fn() -> Option<usize>,
) -> Run<'m> {
    let stopped = || Run {
        verdict: None,
        end: None,
        states: Vec::new(),
    };
    let mut states = std::collections::VecDeque::new();
    for (d, &(b, new)) in seq.iter().enumerate().skip(from) {
        let Some(threads) = threads() else {
            return stopped();
        };
        if keep > 0 && d > from && keep_at.binary_search(&d).is_ok() {
            if states.len() == keep {
                states.pop_front();
            }
            states.push_back((d, sim.clone()));
        }
        sim.set_threads(threads);
        if let Err(v) = sim.deposit(b, new) {
            return Run {
                verdict: Some(Err(Broken::of(&v, d + 1, &sim))),
                end: None,
                states: states.into(),
            };
        }
        if sim.cancelled() {
            return stopped();
        }
    }
    let last = sim.snapshot();
    let Ok(end) = sim.finish() else {
        return stopped();
    };
    if sim.cancelled() {
        return stopped();
    }
    match end {
        Ok(()) => Run {
            verdict: Some(Ok(())),
            end: Some(last),
            states: Vec::new(),
        },
        Err(v) => Run {
            verdict: Some(Err(Broken::of(&v, seq.len(), &sim))),
            end: None,
            states: states.into(),
        },
    }
}

/// The plan's pieces (each weld path's runs of blocks in one layer), in weld order.
fn pieces(part: &Part, plan: &[Vec<usize>]) -> Vec<Piece> {
    let mut out = Vec::new();
    let mut at = 0;
    for (f, blocks) in plan.iter().enumerate() {
        let mut i = 0;
        while i < blocks.len() {
            let z = part.block(blocks[i])[2];
            let j = (i..blocks.len())
                .find(|&j| part.block(blocks[j])[2] != z)
                .unwrap_or(blocks.len());
            out.push(Piece { f, i, j, at });
            at += j - i;
            i = j;
        }
    }
    out
}

/// Whether a piece is a ring: at least three blocks, its ends weld to each other.
fn is_ring(graph: &WeldGraph, piece: &[usize]) -> bool {
    let n = piece.len();
    n >= 3 && (graph.has_edge(piece[n - 1], piece[0]) || graph.has_edge(piece[0], piece[n - 1]))
}

/// The rotation of a ring piece's footprint by `r` blocks: block m goes where block m + r
/// was. `None` on a piece that is no ring.
fn rotation(
    part: &Part,
    graph: &WeldGraph,
    piece: &[usize],
    r: usize,
) -> Option<HashMap<(i64, i64), (i64, i64)>> {
    if !is_ring(graph, piece) {
        return None;
    }
    let n = piece.len();
    let xy = |b: usize| {
        let [x, y, _] = part.block(b);
        (x, y)
    };
    Some(
        (0..n)
            .map(|m| (xy(piece[m]), xy(piece[(m + r) % n])))
            .collect(),
    )
}

/// The mirror of a piece's footprint that keeps it a weld path: on a ring (its ends weld
/// to each other) the other way round from the same first block; on an open path from its
/// other end. `None` on a piece of fewer than two blocks.
fn mirror(
    part: &Part,
    graph: &WeldGraph,
    piece: &[usize],
) -> Option<HashMap<(i64, i64), (i64, i64)>> {
    let n = piece.len();
    if n < 2 {
        return None;
    }
    let ring = is_ring(graph, piece);
    let xy = |b: usize| {
        let [x, y, _] = part.block(b);
        (x, y)
    };
    Some(
        (0..n)
            .map(|m| {
                let to = if ring { (n - m) % n } else { n - 1 - m };
                (xy(piece[m]), xy(piece[to]))
            })
            .collect(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::constructive;
    use crate::sat::Backend;
    use waam_part::Window;

    /// A 40 x 14 wall whose windows are those of a plan that a second weld path takes over
    /// half way up, from the wall's other end; and the plain warm start (one serpentine),
    /// which breaks them.
    fn wall_and_warm_start() -> (Part, WeldGraph, Vec<Vec<usize>>) {
        let (len, h, take_over) = (40, 14, 7);
        let blocks = (0..h)
            .flat_map(|z| (0..len).map(move |x| [x, 0, z]))
            .collect();
        let mut part =
            Part::from_blocks("wall".into(), [6.0, 6.0, 2.5], [0.0; 3], 2, blocks).expect("a wall");
        let graph = WeldGraph::new(&part);
        let limits = Limits {
            deadline: None,
            cancel: None,
        };
        let warm = constructive::layered_plan(&part, &graph, 2, Backend::Cadical, &limits)
            .expect("a wall has a layer-by-layer plan");
        let up_x = |z: i64| (part.block(warm[0][0])[0] == 0) == (z % 2 == 0);
        let layer = |z: i64, forward: bool| -> Vec<usize> {
            let mut xs: Vec<i64> = (0..len).collect();
            if !forward {
                xs.reverse();
            }
            xs.into_iter()
                .map(|x| part.index_of([x, 0, z]).expect("a block"))
                .collect()
        };
        let hidden: Vec<Vec<usize>> = vec![
            (0..take_over).flat_map(|z| layer(z, up_x(z))).collect(),
            (take_over..h).flat_map(|z| layer(z, up_x(z - 1))).collect(),
        ];
        let watched: Vec<usize> = (0..len)
            .map(|x| part.index_of([x, 0, take_over]).expect("a block"))
            .collect();
        let wide = Window {
            min_s: 0.0,
            max_s: 1e6,
        };
        for &b in &watched {
            part.set_window(b, wide);
        }
        let seen = waam_thermal::simulate(&ThermalModel::new(&part, &graph), &hidden)
            .expect("cools")
            .crossings;
        for &b in &watched {
            let t85 = || seen.iter().filter(|c| c.block == b).map(|c| c.t85_s);
            let window = Window {
                min_s: 0.95 * t85().fold(f64::INFINITY, f64::min),
                max_s: 1.01 * t85().fold(0.0, f64::max),
            };
            part.set_window(b, window);
        }
        (part, graph, warm)
    }

    /// The wall of [`wall_and_warm_start`] with, on its top layer, a window no plan keeps.
    fn wall_with_a_window_no_plan_keeps() -> (Part, WeldGraph, Vec<Vec<usize>>) {
        let (mut part, graph, warm) = wall_and_warm_start();
        let top = part.index_of([20, 0, 13]).expect("a top block");
        let never = Window {
            min_s: 0.0,
            max_s: 1e-3,
        };
        part.set_window(top, never);
        (part, graph, warm)
    }

    const NO_LIMITS: Limits = Limits {
        deadline: None,
        cancel: None,
    };

    /// A repair of the wall's warm start on one thread, yielding at `yield_at`.
    fn repair_of<'a>(
        part: &'a Part,
        graph: &'a WeldGraph,
        model: &'a ThermalModel,
        yield_at: Option<Instant>,
    ) -> Repair<'a> {
        Repair {
            part,
            graph,
            k: 2,
            model,
            limits: &NO_LIMITS,
            yield_at,
            workers: 1,
            resume: None,
            reached: Default::default(),
        }
    }

    /// Where `warm` first breaks a window: after how many blocks, and whose.
    fn first_broken(model: &ThermalModel, warm: &[Vec<usize>]) -> (usize, usize) {
        let v = waam_thermal::simulate(model, warm)
            .expect("cools")
            .violation
            .expect("the warm start breaks a window");
        (v.prefix_len, v.block)
    }

    /// A one-block 8 x 8 ring, 4 layers, and its layer-by-layer plan (one weld path).
    fn ring_and_warm_start() -> (Part, WeldGraph, Vec<Vec<usize>>) {
        let blocks = (0..4)
            .flat_map(|z| {
                (0..8).flat_map(move |y| {
                    (0..8)
                        .filter(move |&x| y % 7 == 0 || x % 7 == 0)
                        .map(move |x| [x, y, z])
                })
            })
            .collect();
        let part =
            Part::from_blocks("ring".into(), [6.0, 6.0, 2.5], [0.0; 3], 1, blocks).expect("a ring");
        let graph = WeldGraph::new(&part);
        let plan = constructive::layered_plan(&part, &graph, 1, Backend::Cadical, &NO_LIMITS)
            .expect("a ring has a layer-by-layer plan");
        (part, graph, plan)
    }

    #[test]
    fn a_seam_is_turned_to_the_broken_blocks_column_first() {
        // The rotations of the ring's first layer, for a broken block on the third, start
        // at the ring block under it, then 1, 2, 4 either side.
        let (part, graph, plan) = ring_and_warm_start();
        let model = ThermalModel::new(&part, &graph);
        let first = pieces(&part, &plan)[0];
        let ring = &plan[0][first.i..first.j];
        assert_eq!(ring.len(), 28);
        // Across the ring from where it starts.
        let [x, y, _] = part.block(ring[14]);
        let broken = part.index_of([x, y, 2]).expect("a block above");
        let repair = repair_of(&part, &graph, &model, None);
        let rotations = repair.rotations(&plan, first, broken);
        assert_eq!(rotations[..5], [14, 15, 13, 16, 12], "{rotations:?}");
        let mut distinct = rotations.clone();
        distinct.sort_unstable();
        distinct.dedup();
        assert_eq!(distinct.len(), rotations.len(), "each rotation once");
    }

    #[test]
    fn two_mirrors_turn_the_layers_between_them_alone() {
        let (part, graph, plan) = ring_and_warm_start();
        let model = ThermalModel::new(&part, &graph);
        let repair = repair_of(&part, &graph, &model, None);
        // Which way round a ring piece goes: the sign of the area it encloses.
        let way = |plan: &[Vec<usize>], p: Piece| -> i64 {
            let ring = &plan[p.f][p.i..p.j];
            let area: i64 = (0..ring.len())
                .map(|a| {
                    let [x0, y0, _] = part.block(ring[a]);
                    let [x1, y1, _] = part.block(ring[(a + 1) % ring.len()]);
                    x0 * y1 - x1 * y0
                })
                .sum();
            area.signum()
        };
        let ways = |plan: &[Vec<usize>]| -> Vec<i64> {
            pieces(&part, plan)
                .into_iter()
                .map(|p| way(plan, p))
                .collect()
        };
        let before = ways(&plan);
        assert_eq!(before.len(), 4);
        assert!(before.iter().all(|&w| w != 0), "{before:?}");
        let layers = pieces(&part, &plan);
        let once = repair
            .changed(&plan, layers[1], Change::Mirror)
            .expect("a valid mirror");
        let twice = repair
            .changed(&plan, layers[1], Change::MirrorTwice(layers[2].at))
            .expect("a valid pair of mirrors");
        // One mirror turns its layer and every layer above; two turn the second alone.
        let turned =
            |w: &[i64]| -> Vec<bool> { w.iter().zip(&before).map(|(a, b)| a != b).collect() };
        assert_eq!(turned(&ways(&once)), [false, true, true, true]);
        assert_eq!(turned(&ways(&twice)), [false, true, false, false]);
        assert_eq!(deposits(&twice).len(), deposits(&plan).len());
    }

    #[test]
    fn the_ways_round_turn_layers_no_single_change_or_pair_turns() {
        // A hidden plan whose second and fourth layers go the other way round, alone: no
        // single mirror and no pair of them gives it.
        let (mut part, graph, warm) = ring_and_warm_start();
        let layers = pieces(&part, &warm);
        // Windows around the hidden plan's t8/5 on the second and third layers (crossings
        // are recorded for blocks with a window).
        let watched: Vec<usize> = warm[0][layers[1].i..layers[3].i].to_vec();
        let wide = Window {
            min_s: 0.0,
            max_s: 1e6,
        };
        for &b in &watched {
            part.set_window(b, wide);
        }
        let (hidden, seen) = {
            let model = ThermalModel::new(&part, &graph);
            let repair = repair_of(&part, &graph, &model, None);
            let second = repair
                .changed(&warm, layers[1], Change::MirrorTwice(layers[2].at))
                .expect("a valid pair of mirrors");
            let hidden = repair
                .changed(&second, layers[3], Change::Mirror)
                .expect("a valid mirror");
            let seen = waam_thermal::simulate(&model, &hidden)
                .expect("cools")
                .crossings;
            (hidden, seen)
        };
        for &b in &watched {
            let t85 = || seen.iter().filter(|c| c.block == b).map(|c| c.t85_s);
            if t85().next().is_none() {
                continue;
            }
            let window = Window {
                min_s: 0.99 * t85().fold(f64::INFINITY, f64::min),
                max_s: 1.01 * t85().fold(0.0, f64::max),
            };
            part.set_window(b, window);
        }
        let model = ThermalModel::new(&part, &graph);
        let keeps = |plan: &[Vec<usize>]| {
            waam_thermal::simulate(&model, plan)
                .expect("cools")
                .violation
                .is_none()
        };
        assert!(keeps(&hidden));
        assert!(!keeps(&warm), "the warm start breaks a window");
        let repair = repair_of(&part, &graph, &model, None);
        for (a, &p) in layers.iter().enumerate() {
            let mirrors = std::iter::once(Change::Mirror)
                .chain(layers[a + 1..].iter().map(|q| Change::MirrorTwice(q.at)));
            for change in mirrors {
                let changed = repair.changed(&warm, p, change);
                assert!(
                    !changed.is_some_and(|c| keeps(&c)),
                    "{change:?} at {} keeps every window",
                    p.at
                );
            }
        }
        let ways = repair.ways_round(
            &warm,
            &layers,
            (0, 3),
            repair.simulation(),
            usize::MAX,
            None,
            Measure::Later,
        );
        let Some((turned, plan, Some(Ok(())))) = ways.best else {
            panic!(
                "no way round keeps every window: {:?}",
                ways.best.map(|b| b.2)
            );
        };
        assert!(keeps(&plan), "the plan found keeps every window");
        assert!(turned >= 1 && plan != warm);
        assert!(ways.end.is_some(), "its state after the last deposit");
    }

    #[test]
    fn a_run_keeps_its_last_piece_starts_as_a_run_from_the_first_deposit_has_them() {
        let (part, graph, warm) = wall_and_warm_start();
        let model = ThermalModel::new(&part, &graph);
        let (blocks, _) = first_broken(&model, &warm);
        let seq = deposits(&warm);
        let starts: Vec<usize> = pieces(&part, &warm).iter().map(|p| p.at).collect();
        let repair = repair_of(&part, &graph, &model, None);
        // From the second piece on: the state there is given, not kept.
        let mut sim = repair.simulation();
        for &(b, new) in &seq[..starts[1]] {
            sim.deposit(b, new)
                .expect("the first piece keeps its windows");
        }
        let run = run_from(sim, &seq, starts[1], (&starts, 3), &|| Some(1));
        assert!(matches!(run.verdict, Some(Err(b)) if b.blocks == blocks));
        // Only the last three starts passed before the window broke; none at the first.
        let passed: Vec<usize> = starts
            .iter()
            .copied()
            .filter(|&s| s > starts[1] && s < blocks)
            .collect();
        assert!(passed.len() > 3, "the wall breaks a window pieces in");
        let kept: Vec<usize> = run.states.iter().map(|(at, _)| *at).collect();
        assert_eq!(kept, passed[passed.len() - 3..]);
        for (at, sim) in &run.states {
            let mut fresh = Simulation::new(&model);
            for &(b, new) in &seq[..*at] {
                fresh
                    .deposit(b, new)
                    .expect("no window breaks before the break");
            }
            assert_eq!(sim.state(), fresh.state(), "the state at deposit {at}");
        }
    }

    #[test]
    fn the_same_block_cooling_too_fast_is_nearer_by_its_miss_alone() {
        let broken = |blocks, block, miss_s, too_fast| Broken {
            blocks,
            block,
            miss_s,
            too_fast,
            low_c: f64::INFINITY,
        };
        // A seam moved so the block is welded sooner: fewer blocks, nearer its window.
        let now = broken(8802, 7, 10.8, true);
        assert!(broken(8684, 7, 9.7, true).nearer_than(&now));
        assert!(!broken(8684, 7, 9.7, true).further_than(&now, Measure::Later));
        assert!(!broken(8900, 7, 11.0, true).nearer_than(&now));
        // Another block, or the block's Max window: not.
        assert!(!broken(8684, 8, 9.7, true).nearer_than(&now));
        assert!(!broken(8684, 7, 0.05, false).nearer_than(&now));
        // Reheated above 800 °C later and cooled fast again: later, so further by `Later`;
        // by `Nearer` the same block's miss alone decides, however many blocks.
        let reheated = broken(8900, 7, 85.0, true);
        assert!(reheated.further_than(&now, Measure::Later));
        assert!(!reheated.further_than(&now, Measure::Nearer));
        assert!(broken(8684, 7, 9.7, true).further_than(&now, Measure::Nearer));
        // Another block, or the block's Max window: by blocks.
        assert!(broken(8900, 8, 85.0, true).further_than(&now, Measure::Nearer));
        assert!(!broken(8684, 8, 9.7, true).further_than(&now, Measure::Nearer));
        assert!(!broken(8684, 7, 0.05, false).further_than(&now, Measure::Nearer));
    }

    #[test]
    fn the_same_block_too_long_in_the_band_is_further_the_lower_it_got() {
        let broken = |blocks, block, miss_s, too_fast, low_c| Broken {
            blocks,
            block,
            miss_s,
            too_fast,
            low_c,
        };
        // A Max window is missed by about a step whenever it breaks, and breaks the later
        // the later the block was last above 800 °C: with `Later` further, with `Lower` not.
        let now = broken(6201, 7, 0.03, false, 512.0);
        assert!(broken(6205, 7, 0.01, false, 530.0).further_than(&now, Measure::Later));
        assert!(!broken(6205, 7, 0.01, false, 530.0).further_than(&now, Measure::Lower));
        assert!(!broken(6197, 7, 0.03, false, 504.0).further_than(&now, Measure::Later));
        // Lower in the band, nearer to dipping below 500 °C: further, however many blocks.
        assert!(broken(6197, 7, 0.03, false, 504.0).further_than(&now, Measure::Lower));
        // Another block: by blocks alone.
        assert!(!broken(6197, 8, 0.03, false, 504.0).further_than(&now, Measure::Lower));
        assert!(broken(6205, 8, 0.03, false, 530.0).further_than(&now, Measure::Lower));
        // The same block cooling too fast, or with no temperature known: by blocks.
        assert!(!broken(6197, 7, 0.03, true, 504.0).further_than(&now, Measure::Lower));
        assert!(!broken(6197, 7, 0.03, false, f64::INFINITY).further_than(&now, Measure::Lower));
        assert!(broken(6205, 7, 0.03, false, f64::INFINITY).further_than(&now, Measure::Lower));
    }

    #[test]
    fn a_block_too_long_in_the_band_says_how_low_it_got_there() {
        // A wall whose one window, on a block of its second layer, cannot be kept: the
        // block spends more than a step between 500 and 800 °C.
        let blocks = (0..4)
            .flat_map(|z| (0..10).map(move |x| [x, 0, z]))
            .collect();
        let mut part =
            Part::from_blocks("wall".into(), [6.0, 6.0, 2.5], [0.0; 3], 1, blocks).expect("a wall");
        let b = part
            .index_of([4, 0, 1])
            .expect("a block of the second layer");
        part.set_window(
            b,
            Window {
                min_s: 0.0,
                max_s: 0.01,
            },
        );
        let graph = WeldGraph::new(&part);
        let model = ThermalModel::new(&part, &graph);
        let serpentine: Vec<usize> = (0..4)
            .flat_map(|z| (0..10).map(move |x| [if z % 2 == 0 { x } else { 9 - x }, 0, z]))
            .map(|p| part.index_of(p).expect("a block"))
            .collect();
        let mut sim = Simulation::new(&model);
        let v = deposits(&[serpentine])
            .into_iter()
            .find_map(|(b, new)| sim.deposit(b, new).err())
            .or_else(|| sim.finish().ok()?.err())
            .expect("the window breaks");
        assert_eq!((v.block, v.kind), (b, waam_thermal::ViolationKind::Max));
        let b = Broken::of(&v, v.prefix_len, &sim);
        assert!((500.0..=800.0).contains(&b.low_c), "{} °C", b.low_c);
        assert!(!b.too_fast);
    }

    #[test]
    fn only_candidates_that_may_be_chosen_keep_their_states() {
        let (part, graph, _) = wall_and_warm_start();
        let model = ThermalModel::new(&part, &graph);
        let sim = Simulation::new(&model);
        let broken = |blocks| Broken {
            blocks,
            block: 0,
            miss_s: 0.0,
            too_fast: false,
            low_c: f64::INFINITY,
        };
        let states = || vec![(1, sim.clone())];
        let indices = |kept: &Vec<KeptStates>| kept.iter().map(|(c, _, _)| *c).collect::<Vec<_>>();
        let mut kept = Vec::new();
        keep(&mut kept, 5, broken(10), states(), Measure::Later);
        // One that gets less far can never be chosen.
        keep(&mut kept, 2, broken(8), states(), Measure::Later);
        assert_eq!(indices(&kept), [5]);
        // One that gets further: the others can no longer be chosen.
        keep(&mut kept, 7, broken(12), states(), Measure::Later);
        assert_eq!(indices(&kept), [7]);
        // As far: on a tie the first is chosen, so the lowest indices are kept.
        for c in [9, 3, 8, 11, 4, 6] {
            keep(&mut kept, c, broken(12), states(), Measure::Later);
        }
        assert_eq!(indices(&kept), [3, 4, 6, 7][..KEPT_CANDIDATES]);
        // A run that kept no state adds nothing.
        keep(&mut kept, 1, broken(20), Vec::new(), Measure::Later);
        assert_eq!(indices(&kept), [3, 4, 6, 7][..KEPT_CANDIDATES]);
    }

    #[test]
    fn a_batch_that_ends_at_the_first_change_that_gets_further_judges_none_after_it() {
        // A change that keeps the broken window gets further, to the top, and no change
        // keeps every window.
        let (part, graph, warm) = wall_with_a_window_no_plan_keeps();
        let model = ThermalModel::new(&part, &graph);
        let (blocks, block) = first_broken(&model, &warm);
        let broken = Broken {
            blocks,
            block,
            miss_s: f64::INFINITY,
            too_fast: false,
            low_c: f64::INFINITY,
        };
        let seq = deposits(&warm);
        let repair = repair_of(&part, &graph, &model, None);
        let candidates: Vec<_> = pieces(&part, &warm)
            .into_iter()
            .filter(|p| p.at < blocks)
            .flat_map(|p| [(p, Change::Mirror), (p, Change::NewPath)])
            .filter_map(|(p, c)| Some((p, c, repair.changed(&warm, p, c)?)))
            .collect();
        // The plan now, the verdicts and the candidates whose states are kept.
        let judged = |repair: &Repair, first_further| {
            let j = repair.judge(
                &seq,
                &candidates,
                &mut Vec::new(),
                (true, broken, Measure::Later),
                first_further,
                None,
            );
            let kept: Vec<usize> = j.states.iter().map(|(c, _, _)| *c).collect();
            (j.now, j.verdicts, kept)
        };
        let (now, verdicts, _) = judged(&repair, false);
        let Some(Err(now)) = now else {
            panic!("the plan now breaks its window: {now:?}");
        };
        let first = verdicts
            .iter()
            .position(|v| matches!(v, Some(Err(b)) if b.later_than(&now)))
            .expect("a change breaks later");
        assert!(
            verdicts[first + 1..].iter().any(Option::is_some),
            "changes after it are judged when the batch does not end there"
        );
        for workers in [1, 2] {
            let repair = Repair {
                workers,
                ..repair_of(&part, &graph, &model, None)
            };
            let (_, cut, kept) = judged(&repair, true);
            assert_eq!(cut[..=first], verdicts[..=first], "{workers} workers");
            assert!(
                cut[first + 1..].iter().all(Option::is_none),
                "none judged after the first that breaks later, on {workers} workers"
            );
            assert!(kept.iter().all(|&c| c <= first));
        }
    }

    #[test]
    fn a_repair_that_gets_no_further_yields_at_its_time() {
        let (part, graph, warm) = wall_and_warm_start();
        let model = ThermalModel::new(&part, &graph);
        let (blocks, block) = first_broken(&model, &warm);
        let repaired = |r: Repair| r.repaired(&warm, blocks, block);
        let found = repaired(repair_of(&part, &graph, &model, None))
            .expect("the repair keeps every window");
        let outcome = waam_thermal::simulate(&model, &found.plan).expect("cools");
        assert!(outcome.violation.is_none());
        // Before any step has got further, the time to yield ends the repair.
        let now = Some(Instant::now());
        assert!(repaired(repair_of(&part, &graph, &model, now)).is_none());
    }

    #[test]
    fn a_repair_ends_where_an_earlier_run_of_it_got() {
        // A run gets further (past the windows at the take-over), then no change gets past
        // the top.
        let (part, graph, warm) = wall_with_a_window_no_plan_keeps();
        let model = ThermalModel::new(&part, &graph);
        let (blocks, block) = first_broken(&model, &warm);
        let repair = repair_of(&part, &graph, &model, None);
        assert!(repair.repaired(&warm, blocks, block).is_none());
        let reached = repair.reached.borrow().clone();
        assert!(
            !reached[Measure::Later as usize].is_empty(),
            "the first run got further before its dead end"
        );
        // The same plan again: its first step that gets further gets where the first run
        // got, and the run ends there instead of walking on to the same dead end.
        assert!(repair.repaired(&warm, blocks, block).is_none());
        assert_eq!(*repair.reached.borrow(), reached, "no state reached twice");
    }
}
