//! `rcl_interfaces`: log records (`/rosout`).

use serde::{Deserialize, Serialize};

use super::builtin_interfaces::Time;
use super::ros_message;

/// One log record, as nodes publish it on `/rosout`.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Log {
    pub stamp: Time,
    /// One of the level constants below.
    pub level: u8,
    pub name: String,
    pub msg: String,
    pub file: String,
    pub function: String,
    pub line: u32,
}
ros_message!(
    Log,
    "rcl_interfaces/msg/Log",
    "RIHS01_e28ce254ca8abc06abf92773b74602cdbf116ed34fbaf294fb9f81da9f318eac"
);

impl Log {
    pub const DEBUG: u8 = 10;
    pub const INFO: u8 = 20;
    pub const WARN: u8 = 30;
    pub const ERROR: u8 = 40;
    pub const FATAL: u8 = 50;
}
