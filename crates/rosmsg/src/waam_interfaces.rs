//! `waam_interfaces`: our own messages, defined in `ros/waam_interfaces/msg/*.msg` (a colcon
//! package a cell can build). Field order here must match those files exactly; the type hashes
//! are checked against the definitions by a unit test.

use serde::{Deserialize, Serialize};

use super::builtin_interfaces::Duration;
use super::geometry_msgs::Pose;
use super::ros_message;
use super::std_msgs::Header;

/// One deposit of a part: a block part's grid coordinates (z = layer); a graph part's
/// stand-in `[rank among its layer's nodes, 0, layer]` (its place is in the plan's points).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct Block {
    pub x: i32,
    pub y: i32,
    pub z: i32,
}
impl Block {
    /// From part grid coordinates; `None` when a coordinate does not fit in int32.
    pub fn from_part(b: [i64; 3]) -> Option<Block> {
        Some(Block {
            x: i32::try_from(b[0]).ok()?,
            y: i32::try_from(b[1]).ok()?,
            z: i32::try_from(b[2]).ok()?,
        })
    }

    /// As part grid coordinates.
    pub fn to_part(self) -> [i64; 3] {
        [self.x.into(), self.y.into(), self.z.into()]
    }
}

ros_message!(
    Block,
    "waam_interfaces/msg/Block",
    "RIHS01_4ea196c2f40597a0324533ff10da477dd0109bc0fcb658088b34d8bb3db3a964"
);

/// One weld path: blocks deposited one after the other with the arc on.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct WeldFragment {
    pub blocks: Vec<Block>,
}
ros_message!(
    WeldFragment,
    "waam_interfaces/msg/WeldFragment",
    "RIHS01_e75a921c1e3532901b2abce7027eede905dea9af32f6c7ba0db29f93b0e16d85"
);

/// One point of the torch toolpath.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct WeldPoint {
    /// Tool-centre point pose in the plan's frame (m).
    pub pose: Pose,
    pub time_from_start: Duration,
    /// One of the kind constants below.
    pub kind: u8,
    pub arc_on: bool,
    /// Index into `WeldPlan::fragments`, or -1 for a transit between fragments.
    pub fragment: i32,
    /// Index into that fragment's blocks of the block deposited here, or -1.
    pub block: i32,
    /// Commanded TCP speed on the move ending here (m/s).
    pub speed: f64,
}
ros_message!(
    WeldPoint,
    "waam_interfaces/msg/WeldPoint",
    "RIHS01_6f2995cb390859909ac070f0de55edff2694638c1240d49574409fdfa7e2675f"
);

impl WeldPoint {
    pub const APPROACH: u8 = 0;
    pub const ARC_ON: u8 = 1;
    pub const WELD: u8 = 2;
    pub const ARC_OFF: u8 = 3;
    pub const RETRACT: u8 = 4;
    pub const TRANSIT: u8 = 5;
}

/// How the planner found a plan.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct PlanStatistics {
    pub candidates: u64,
    pub feasible: u64,
    pub optimal: bool,
    pub time_to_first_feasible_s: f64,
    pub total_time_s: f64,
    pub sat_time_s: f64,
    pub acyclicity_time_s: f64,
    pub simulation_time_s: f64,
    pub learned_clauses: u32,
    pub learned_clause_min: u32,
    pub learned_clause_max: u32,
    pub learned_clause_mean: f64,
}
ros_message!(
    PlanStatistics,
    "waam_interfaces/msg/PlanStatistics",
    "RIHS01_97061f4016afe4a81401b4e4cf277352c375224ef3ba1ea3267783998b7df7d9"
);

/// A weld plan for one part: fragments in weld order and the toolpath that deposits them.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct WeldPlan {
    /// stamp: when planned; frame_id: frame of the toolpath poses.
    pub header: Header,
    pub part_name: String,
    /// Block edge length (m).
    pub block_pitch: f64,
    pub fragments: Vec<WeldFragment>,
    pub points: Vec<WeldPoint>,
    /// TCP speeds (m/s).
    pub weld_speed: f64,
    pub transit_speed: f64,
    /// Smallest margin of any t8/5 value to its window bounds (s); +inf without windows.
    pub worst_margin_s: f64,
    pub statistics: PlanStatistics,
}
impl WeldPlan {
    /// The fragments as part grid coordinates.
    pub fn part_fragments(&self) -> Vec<Vec<[i64; 3]>> {
        self.fragments
            .iter()
            .map(|f| f.blocks.iter().map(|b| b.to_part()).collect())
            .collect()
    }
}

ros_message!(
    WeldPlan,
    "waam_interfaces/msg/WeldPlan",
    "RIHS01_d6bfff53d44b248e340fc65dc3273d3e420f8bdce888ed13d631eda46a01dd3f"
);

/// The planner's verdict on one candidate plan.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct PlanCandidate {
    pub header: Header,
    /// 1 for the first candidate of a planning run.
    pub index: u64,
    /// One of the verdict constants below.
    pub verdict: u8,
    /// Blocks deposited up to and including the violation; 0 when feasible.
    pub prefix_len: u32,
    /// The violating block (unset when feasible).
    pub block: Block,
    /// Simulated time of the violation (s).
    pub time_s: f64,
    /// Literals in the clause learned from this candidate; 0 when none.
    pub learned_clause_len: u32,
}
ros_message!(
    PlanCandidate,
    "waam_interfaces/msg/PlanCandidate",
    "RIHS01_b1a6b6c241a850d4cb341fd2f50ad0059be2a063a29b07c503640a3516766282"
);

impl PlanCandidate {
    pub const FEASIBLE: u8 = 0;
    pub const VIOLATED: u8 = 1;
    pub const TOO_SHORT: u8 = 2;
    pub const TOO_LONG: u8 = 3;
    pub const NOT_COOLED: u8 = 4;
    pub const TORCH_BLOCKED: u8 = 5;
}
