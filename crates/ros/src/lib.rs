//! The ROS 2 node over DDS (`ros2-client`), on top of `waam-messages`.
//!
//! `waam-messages` turns domain values into messages, records sessions and replays them
//! without DDS; here those messages go out over DDS: the node `waam_planner` runs the
//! pipeline on parts that arrive over ROS 2, and recordings are played back to ROS 2.

pub mod node;
pub mod playback;
pub mod qos;
pub mod sim_cell;
