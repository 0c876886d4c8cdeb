//! How the planner searches ([`Options`]) and the check of a robot's time line it may be
//! given ([`ExecutedCheck`]).

use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Duration;

use waam_access::TorchSetup;

use crate::{Acyclicity, Backend};

/// How the planner searches.
#[derive(Debug, Clone)]
pub struct Options {
    pub acyclicity: Acyclicity,
    /// Block-steps the thermal model may simulate per violation to prove a shorter
    /// clause (0: learn the plain violating prefix, as the paper does), in the thermal loop
    /// and inside the search alike.
    pub lookahead_budget: usize,
    /// Stop and return the best found so far (not proven) after this long.
    pub timeout: Option<Duration>,
    /// Override the part's max_fragments.
    pub max_fragments: Option<usize>,
    /// Set from another thread to stop the run (as a timeout does): the node cancels a plan
    /// when a newer part arrives. CaDiCaL stops inside a solve; varisat after it.
    pub cancel: Option<Arc<AtomicBool>>,
    /// The SAT solver.
    pub solver: Backend,
    /// Check torch access at every deposit (None: the torch is not modelled, as the
    /// shared specs and their counts assume).
    pub torch: Option<TorchSetup>,
    /// Start from a plan built layer by layer ([`constructive`](crate::constructive)): judged first, and the
    /// solver's phases point at it. Plans and proofs are the same with or without it.
    pub warm_start: bool,
    /// Judge every candidate that keeps its windows (and the torch) once more, on the time
    /// line a robot would weld it on (None: no robot, as the shared specs and their counts
    /// assume). A rejection is learned like a violation.
    pub executed: Option<ExecutedCheck>,
    /// Refuse a part whose search would need more memory than this, MB, by the estimate
    /// of [`estimated_memory_mb`] (checked before anything is built).
    pub max_memory_mb: u64,
    /// Worker threads of [`count`](crate::count) and [`enumerate`](crate::enumerate), each searching its own cubes of the
    /// plans ([`cubes`](crate::cubes); 0: the thermal model's default, the available cores unless set),
    /// of [`first`](crate::first)'s race (one racer each) and of the varied starts (0: all cores);
    /// also the most threads one simulation of a candidate steps on (0: the thermal model's
    /// default), so a run on one thread keeps to one core. Counts and the order of the plans
    /// are the same on any number.
    pub threads: usize,
}

/// Why a candidate fails when a robot welds it (its transit cannot be made in the
/// modelled time, or a window breaks on the executed time line), as the plans to rule
/// out with it.
#[derive(Debug, Clone, PartialEq)]
pub struct Rejection {
    /// Every plan that begins with these fragments (block indices) fails the same way:
    /// the last fragment ends there when `closed`, else it may go on.
    pub prefix: Vec<Vec<usize>>,
    pub closed: bool,
    /// One line on what failed.
    pub reason: String,
}

/// A candidate's fragments in, its [`Rejection`] out (`None`: the candidate passes, or fails
/// for a reason the caller reports itself).
pub type JudgeExecuted = dyn Fn(&[Vec<usize>]) -> Option<Rejection> + Send + Sync;

/// The check behind [`Options::executed`].
#[derive(Clone)]
pub struct ExecutedCheck(pub Arc<JudgeExecuted>);

impl std::fmt::Debug for ExecutedCheck {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("ExecutedCheck(..)")
    }
}

/// The default of [`Options::max_memory_mb`]: a part the planner would need more for (at
/// k = 2, more than about 100,000 blocks) is refused unless the limit is raised.
pub const DEFAULT_MAX_MEMORY_MB: u64 = 2048;

/// The most threads [`Options::threads`] may ask for, as the command line and the node
/// check it: more is a typo (each racer encodes the part, each thread reserves its stack
/// whether it has a core or not).
pub const MAX_THREADS: usize = 1024;

/// What searching a part of `blocks` blocks with at most `k` fragments takes, MB: the
/// encoding, CaDiCaL's clause database and the layer-by-layer warm start grow with the
/// blocks and with k. Measured peaks lie at or below 12 KiB + 4 KiB x k per block: plates
/// of 10^4 to 1.6 x 10^5 blocks and cubes of 2.7 x 10^4 and 6.4 x 10^4 at k = 1 and 8 (at
/// most 10 + 3k), and the 62,614-block flanged tube at k = 6 (31.5 KiB per block in 300 s).
pub fn estimated_memory_mb(blocks: usize, k: usize) -> u64 {
    let per_block_kib = 12 + 4 * k as u64;
    (blocks as u64).saturating_mul(per_block_kib) / 1024
}

impl Default for Options {
    fn default() -> Self {
        Options {
            acyclicity: Acyclicity::Lazy,
            lookahead_budget: 2_000_000,
            timeout: None,
            max_fragments: None,
            cancel: None,
            solver: Backend::default(),
            torch: None,
            warm_start: true,
            executed: None,
            max_memory_mb: DEFAULT_MAX_MEMORY_MB,
            threads: 0,
        }
    }
}
