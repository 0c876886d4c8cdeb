//! `builtin_interfaces`: time stamps and durations.

use serde::{Deserialize, Serialize};

use super::ros_message;

/// A point in time: seconds and nanoseconds since the Unix epoch (or since the start of a
/// simulated clock).
#[derive(
    Debug, Clone, Copy, Default, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize,
)]
pub struct Time {
    pub sec: i32,
    pub nanosec: u32,
}
ros_message!(
    Time,
    "builtin_interfaces/msg/Time",
    "RIHS01_b106235e25a4c5ed35098aa0a61a3ee9c9b18d197f398b0e4206cea9acf9c197"
);

/// A span of time: seconds plus nanoseconds in `[0, 1e9)`.
#[derive(
    Debug, Clone, Copy, Default, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize,
)]
pub struct Duration {
    pub sec: i32,
    pub nanosec: u32,
}
ros_message!(
    Duration,
    "builtin_interfaces/msg/Duration",
    "RIHS01_e8d009f659816f758b75334ee1a9ca5b5c0b859843261f14c7f937349599d93b"
);

/// Splits nanoseconds into (seconds, nanoseconds in `[0, 1e9)`), saturating at the i32 range.
fn split_nanos(nanos: i64) -> (i32, u32) {
    let sec = nanos.div_euclid(1_000_000_000);
    let nanosec = nanos.rem_euclid(1_000_000_000) as u32;
    match i32::try_from(sec) {
        Ok(sec) => (sec, nanosec),
        Err(_) if sec < 0 => (i32::MIN, 0),
        Err(_) => (i32::MAX, 999_999_999),
    }
}

impl Time {
    /// From nanoseconds since the epoch.
    pub fn from_nanos(nanos: i64) -> Time {
        let (sec, nanosec) = split_nanos(nanos);
        Time { sec, nanosec }
    }

    /// Nanoseconds since the epoch.
    pub fn to_nanos(self) -> i64 {
        i64::from(self.sec) * 1_000_000_000 + i64::from(self.nanosec)
    }

    /// The system clock now.
    pub fn now() -> Time {
        let since = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .unwrap_or_default();
        Time::from_nanos(i64::try_from(since.as_nanos()).unwrap_or(i64::MAX))
    }
}

impl Duration {
    /// From (possibly fractional, possibly negative) seconds, rounded to the nanosecond.
    pub fn from_secs_f64(seconds: f64) -> Duration {
        let nanos = (seconds * 1e9).round();
        let nanos = if nanos.is_nan() { 0 } else { nanos as i64 };
        let (sec, nanosec) = split_nanos(nanos);
        Duration { sec, nanosec }
    }

    /// In seconds.
    pub fn as_secs_f64(self) -> f64 {
        f64::from(self.sec) + f64::from(self.nanosec) * 1e-9
    }
}
