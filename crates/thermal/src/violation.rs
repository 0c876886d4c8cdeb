//! What a run reports: broken t8/5 windows ([`Violation`], [`ViolationKind`], the
//! [`Phase`] they broke in), the crossings of 500 °C ([`Crossing`]) and a part the cooldown
//! cannot cool ([`NotCooled`]).

use thiserror::Error;

use waam_part::Window;

/// Which way a t8/5 window was broken.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum ViolationKind {
    /// Crossed 500 °C downwards after less than `min_s` between 800 and 500 °C.
    Min,
    /// Spent more than `max_s` between 800 and 500 °C.
    Max,
}

/// Where in the time line a step happened.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Phase {
    /// The steps after depositing a block.
    Deposit,
    /// The steps between two fragments (the earlier fragment is closed).
    Transit,
    /// The steps after the last block (the plan is complete).
    Cooldown,
}

/// The first t8/5 window broken by a plan, and the prefix of the plan that forces it.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Violation {
    /// Index of the block whose window is broken.
    pub block: usize,
    pub kind: ViolationKind,
    pub window: Window,
    /// The block's t8/5 time (n·dt) when judged, s.
    pub t85_s: f64,
    /// Steps done, including the violating one.
    pub step: u64,
    /// `step · dt`, s.
    pub time_s: f64,
    /// Blocks deposited when the window broke: the violating prefix.
    pub prefix_len: usize,
    /// Fragments begun when the window broke.
    pub prefix_fragments: usize,
    /// Deposit: the last fragment of the prefix is open; transit or cooldown: it is closed.
    pub phase: Phase,
}

/// One downward crossing of 500 °C by a windowed block.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Crossing {
    pub block: usize,
    /// Time spent between 800 and 500 °C since the block was last above 800 °C, s.
    pub t85_s: f64,
    /// Time of the crossing, s.
    pub time_s: f64,
}

/// A windowed block that was still at or above 500 °C after `max_cooldown_s`.
#[derive(Debug, Clone, Error, PartialEq)]
#[error("block {block} is still at or above 500 °C after max_cooldown_s = {max_cooldown_s} s (thermal constants cannot cool it)")]
pub struct NotCooled {
    pub block: String,
    pub max_cooldown_s: f64,
}
