//! The simulated heat of a build as `sensor_msgs/PointCloud2` frames (x, y, z, temperature),
//! so Foxglove can play the build's temperatures back in 3D.

use waam_part::Part;
use waam_rosmsg::builtin_interfaces::Time;
use waam_rosmsg::sensor_msgs::{PointCloud2, PointField};
use waam_rosmsg::std_msgs::Header;
use waam_thermal::{Simulation, ThermalModel};

/// Bytes per point: x, y, z, temperature as little-endian float32.
pub const POINT_STEP: u32 = 16;

/// How many frames to make.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HeatOptions {
    /// At most this many frames over the build (one per deposited block when the part is
    /// small enough), plus one after the cooldown.
    pub max_frames: usize,
}

impl Default for HeatOptions {
    fn default() -> Self {
        HeatOptions { max_frames: 600 }
    }
}

/// One frame: the welded blocks and their temperatures at one simulated time.
#[derive(Debug, Clone, PartialEq)]
pub struct HeatFrame {
    /// Simulated time since the first deposit, s.
    pub time_s: f64,
    /// Blocks deposited so far.
    pub welded: usize,
    pub cloud: PointCloud2,
}

/// The point layout: x, y, z in metres, temperature in °C.
pub fn fields() -> Vec<PointField> {
    ["x", "y", "z", "temperature"]
        .iter()
        .enumerate()
        .map(|(i, name)| PointField {
            name: name.to_string(),
            offset: i as u32 * 4,
            datatype: PointField::FLOAT32,
            count: 1,
        })
        .collect()
}

/// A cloud of the given blocks (block index, °C) at their centres, in metres.
pub fn cloud(
    part: &Part,
    temperatures: impl Iterator<Item = (usize, f64)>,
    header: Header,
) -> PointCloud2 {
    point_cloud(
        temperatures.map(|(block, celsius)| {
            let c = part.centre_mm(part.block(block));
            ([c[0] / 1000.0, c[1] / 1000.0, c[2] / 1000.0], celsius)
        }),
        header,
    )
}

/// A cloud of points (position in metres, °C), in the layout of [`fields`].
pub fn point_cloud(points: impl Iterator<Item = ([f64; 3], f64)>, header: Header) -> PointCloud2 {
    let mut data = Vec::new();
    let mut n = 0u32;
    for ([x, y, z], celsius) in points {
        for v in [x, y, z, celsius] {
            data.extend_from_slice(&(v as f32).to_le_bytes());
        }
        n += 1;
    }
    PointCloud2 {
        header,
        height: 1,
        width: n,
        fields: fields(),
        is_bigendian: false,
        point_step: POINT_STEP,
        row_step: POINT_STEP * n,
        data,
        is_dense: true,
    }
}

/// Simulates `fragments` (block indices, weld order) and hands `emit` the heat frames: after
/// deposits, evenly spaced so that there are at most `options.max_frames`, and one after the
/// cooldown. Frame stamps are `start` plus the simulated time. Stops early, after a last
/// frame, at the first t8/5 violation (the frames show the heat up to it).
pub fn heat_frames<E>(
    part: &Part,
    model: &ThermalModel,
    fragments: &[Vec<usize>],
    frame_id: &str,
    start: Time,
    options: HeatOptions,
    mut emit: impl FnMut(HeatFrame) -> Result<(), E>,
) -> Result<(), E> {
    let total: usize = fragments.iter().map(Vec::len).sum();
    let stride = total.div_ceil(options.max_frames.max(1)).max(1);
    let mut sim = Simulation::new(model);
    let frame = |sim: &Simulation| {
        let stamp = Time::from_nanos(start.to_nanos() + (sim.time_s() * 1e9).round() as i64);
        HeatFrame {
            time_s: sim.time_s(),
            welded: sim.welded(),
            cloud: cloud(part, sim.temperatures(), Header::new(stamp, frame_id)),
        }
    };
    let mut deposited = 0;
    for fragment in fragments {
        for (p, &block) in fragment.iter().enumerate() {
            let outcome = sim.deposit(block, p == 0);
            deposited += 1;
            if outcome.is_err() {
                return emit(frame(&sim));
            }
            if deposited % stride == 0 || deposited == total {
                emit(frame(&sim))?;
            }
        }
    }
    // A part that cannot cool within max_cooldown_s still gets its frame at the end.
    let _ = sim.finish();
    emit(frame(&sim))
}

/// Records the heat frames of a plan on [`crate::topics::HEAT`], each at its simulated time
/// after `start` (the build's own time line: Foxglove plays it back at any speed). Returns
/// the number of frames.
pub fn record_heat(
    recorder: &waam_rosbag::Recorder,
    part: &Part,
    model: &ThermalModel,
    fragments: &[Vec<usize>],
    frame_id: &str,
    start: Time,
    options: HeatOptions,
) -> Result<usize, waam_rosbag::BagError> {
    let mut frames = 0;
    let qos = waam_rosbag::Qos::reliable(10);
    heat_frames(part, model, fragments, frame_id, start, options, |frame| {
        frames += 1;
        let stamp = frame.cloud.header.stamp;
        recorder.record_at(crate::topics::HEAT, &qos, stamp, &frame.cloud)
    })?;
    Ok(frames)
}
