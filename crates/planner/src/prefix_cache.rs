//! Snapshots of simulated plan prefixes, so that a prefix shared by many candidates (or
//! reached again by the solver) is simulated once.

use std::cell::RefCell;
use std::rc::Rc;

use waam_thermal::{Simulation, Snapshot, ThermalModel};

/// One cache shared by the thermal loop and the prefix check inside the search: a plan
/// the solver hands out was simulated inside it already, up to its cooldown.
pub type SharedCache = Rc<RefCell<PrefixCache>>;

/// Which prefix lengths are snapshotted (multiples of it): snapshots of every prefix cost
/// n²/2 temperatures, so they are spaced on big parts.
pub fn snapshot_spacing(blocks: usize) -> usize {
    (blocks / 1000).max(1)
}

/// A simulation at the longest cached prefix of `seq` (all of it, or of a length that is
/// a multiple of `spacing`), and that prefix's length.
pub fn resume<'m>(
    model: &'m ThermalModel,
    cache: &PrefixCache,
    spacing: usize,
    seq: &[(usize, bool)],
    keys: &[Key],
) -> (Simulation<'m>, usize) {
    let mut sim = Simulation::new(model);
    // The whole sequence too: a plan another simulation judged leaves its last state.
    let whole = Some(seq.len()).filter(|&len| len > 0 && len % spacing != 0);
    let spaced = (1..=seq.len()).rev().filter(|len| len % spacing == 0);
    for len in whole.into_iter().chain(spaced) {
        if let Some(snap) = cache.get(keys[len - 1], len) {
            sim.restore_from_trail(snap, seq);
            return (sim, len);
        }
    }
    (sim, 0)
}

/// A plan's deposits in weld order, each with whether it begins a weld path: the
/// sequence a simulation and the cache's keys follow.
pub fn deposits(plan: &[Vec<usize>]) -> Vec<(usize, bool)> {
    plan.iter()
        .flat_map(|f| f.iter().enumerate().map(|(p, &b)| (b, p == 0)))
        .collect()
}

/// A 128-bit hash of a deposit sequence prefix (two independent 64-bit mixes).
pub type Key = (u64, u64);

/// The key of every prefix of `seq`: `keys[j]` is the key of `seq[..=j]`.
pub fn prefix_keys(seq: &[(usize, bool)]) -> Vec<Key> {
    let mut h = EMPTY_KEY;
    seq.iter()
        .map(|&(b, new)| {
            h = extend_key(h, b, new);
            h
        })
        .collect()
}

/// The key of the empty prefix.
pub const EMPTY_KEY: Key = (0x9e37_79b9_7f4a_7c15, 0xc2b2_ae3d_27d4_eb4f);

/// The key of a prefix (key `h`) followed by depositing `b` (a new fragment if `new`).
pub fn extend_key(h: Key, b: usize, new: bool) -> Key {
    let x = (b as u64) << 1 | new as u64;
    (
        mix(h.0 ^ x),
        mix(h.1.wrapping_add(x.wrapping_mul(0xff51_afd7_ed55_8ccd))),
    )
}

/// splitmix64's finalizer.
fn mix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// Snapshots of simulated prefixes within a byte budget ([`PrefixCache::for_blocks`]).
/// When a new snapshot would not fit, the least recently used half of the snapshots is
/// dropped (a use is an insert or a resume from it): the prefixes the solver's latest
/// candidates share stay, old branches go. A snapshot of `m` welded blocks costs about
/// 8·m bytes (plus the t8/5 counters): about 0.5 MB at the end of a 62,614-block part, so
/// the largest budget holds at least ~500 of the largest.
pub struct PrefixCache {
    /// The most bytes of snapshots kept.
    budget: usize,
    map: rustc_hash::FxHashMap<Key, (Snapshot, std::cell::Cell<u64>)>,
    /// Bytes held by the snapshots in `map` (their buffers and entries).
    bytes: usize,
    /// Use counter: the last use of an entry is its tick.
    tick: std::cell::Cell<u64>,
}

impl Default for PrefixCache {
    fn default() -> Self {
        PrefixCache::with_budget(Self::MAX_BUDGET_BYTES)
    }
}

impl PrefixCache {
    /// The most bytes of snapshots any cache keeps: 256 MiB.
    const MAX_BUDGET_BYTES: usize = 256 << 20;
    /// The least: 8 MiB.
    const MIN_BUDGET_BYTES: usize = 8 << 20;
    /// Full plans' worth of snapshots a cache keeps (between the two limits).
    const TRAILS: usize = 256;

    /// A cache sized for a part of `blocks` blocks: room for the snapshots along a few
    /// hundred complete plans. The solver's recent branches are what it resumes from, and
    /// every byte beyond is memory the kernel must hand out fresh (on a 113-block part a
    /// 256 MiB budget grew to 160 MB and cost a tenth of the run in page faults, with 2 %
    /// fewer deposits simulated than with 8 MiB).
    pub fn for_blocks(blocks: usize) -> PrefixCache {
        let spacing = snapshot_spacing(blocks);
        // Snapshots at every `spacing` deposits, of 4·m bytes on average along a plan
        // (half its 8·n bytes at the end).
        let trail = (blocks / spacing) * (4 * blocks + std::mem::size_of::<Snapshot>());
        let budget = trail
            .saturating_mul(Self::TRAILS)
            .clamp(Self::MIN_BUDGET_BYTES, Self::MAX_BUDGET_BYTES);
        PrefixCache::with_budget(budget)
    }

    fn with_budget(budget: usize) -> PrefixCache {
        PrefixCache {
            budget,
            map: Default::default(),
            bytes: 0,
            tick: Default::default(),
        }
    }

    /// Forgets every snapshot (for a new thermal model), keeping the budget.
    pub fn clear(&mut self) {
        *self = PrefixCache::with_budget(self.budget);
    }

    fn use_tick(&self) -> u64 {
        let t = self.tick.get() + 1;
        self.tick.set(t);
        t
    }

    fn cost(snap: &Snapshot) -> usize {
        snap.bytes() + std::mem::size_of::<(Key, std::cell::Cell<u64>)>()
    }

    pub fn get(&self, key: Key, len: usize) -> Option<&Snapshot> {
        let (snap, used) = self.map.get(&key).filter(|(s, _)| s.welded() == len)?;
        used.set(self.use_tick());
        Some(snap)
    }

    pub fn insert(&mut self, key: Key, sim: &Simulation<'_>) {
        if let Some((_, used)) = self.map.get(&key) {
            used.set(self.use_tick());
            return;
        }
        self.insert_snapshot(key, sim.snapshot());
    }

    /// [`PrefixCache::insert`] of a snapshot taken already.
    pub fn insert_snapshot(&mut self, key: Key, snap: Snapshot) {
        if let Some((_, used)) = self.map.get(&key) {
            used.set(self.use_tick());
            return;
        }
        let cost = Self::cost(&snap);
        if cost > self.budget {
            return;
        }
        while self.bytes + cost > self.budget {
            self.evict_older_half();
        }
        self.bytes += cost;
        let tick = self.use_tick();
        self.map.insert(key, (snap, std::cell::Cell::new(tick)));
    }

    /// Drops the least recently used half of the snapshots.
    fn evict_older_half(&mut self) {
        let mut ticks: Vec<u64> = self.map.values().map(|(_, t)| t.get()).collect();
        let half = ticks.len() / 2;
        let (_, &mut median, _) = ticks.select_nth_unstable(half);
        self.map.retain(|_, (_, t)| t.get() > median);
        self.bytes = self.map.values().map(|(s, _)| Self::cost(s)).sum();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use waam_part::graph::WeldGraph;
    use waam_part::Part;

    #[test]
    fn the_prefix_cache_keeps_its_byte_budget_and_the_recent_snapshots() {
        let blocks: Vec<[i64; 3]> = (0..64).map(|x| [x, 0, 0]).collect();
        let part = Part::from_blocks("w".into(), [6.0, 6.0, 2.5], [0.0; 3], 1, blocks).unwrap();
        let graph = WeldGraph::new(&part);
        let model = ThermalModel::new(&part, &graph);
        let mut sim = Simulation::new(&model);
        for b in 0..64 {
            sim.deposit(b, b == 0).unwrap();
        }
        let mut cache = PrefixCache::default();
        let per = PrefixCache::cost(&sim.snapshot());
        let fits = cache.budget / per;
        for k in 0..fits as u64 + 10 {
            cache.insert((k, 0), &sim);
            // Keep the first key in use: it must survive every eviction.
            assert!(cache.get((0, 0), 64).is_some());
            assert!(cache.bytes <= cache.budget);
        }
        assert!(cache.map.len() < fits + 10);
        assert!(cache.get((fits as u64 + 9, 0), 64).is_some());
    }
}
