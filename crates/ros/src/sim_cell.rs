//! The simulated cell as a ROS 2 node (`waam sim-cell PART --truth TRUTH.yaml --node`): the
//! sensors of a cell whose true model differs from the planner's, for a `waam node` that
//! executes PART (a dry run, or a real controller without real sensors). It follows the
//! planner's `~/plan/weld_plan`, `~/arc_on` and `~/wire_feed` and publishes on the planner's
//! `~/temperature` what a pyrometer aimed at the torch reads on the true model — each
//! deposit's true temperature at its end, stamped in its middle — and on `~/scan`, when a
//! weld path ends, the true top of each layer it finished (beads `height_factor` × the wire
//! feed high). With `thermal_camera`, it also publishes on `~/thermal_image`, with each
//! pyrometer reading, what a thermal camera registered onto the part sees: every welded
//! block's true temperature at its centre (a `PointCloud2` with a `temperature` field, part
//! frame). The deposits are timed by the weld plan, from the moment the arc strikes,
//! `time_scale` times as fast as planned (the planner's `dry_run.time_scale`).
//!
//! TRUTH.yaml's `cut_short` (weld path `path`, counted as the arc strikes, stops after
//! `after` deposits) is the welder's arc fault: when that deposit ends the cell publishes on
//! the planner's `~/arc_fault` a `std_msgs/Header` stamped then, and welds nothing more of
//! the path (the planner stops it and re-plans the rest). The true model's temperatures
//! follow the planned transit between weld paths, as `waam sim-cell` does.

use std::collections::HashMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use ros2_client::{ROSTime, Subscription};
use waam_cell::estimate::counting_part;
use waam_cell::{Noise, Truth};
use waam_part::graph::WeldGraph;
use waam_part::Part;
use waam_rosbag::qos::Qos;
use waam_rosmsg::builtin_interfaces::Time;
use waam_rosmsg::sensor_msgs::{PointCloud2, Temperature};
use waam_rosmsg::std_msgs::{Bool, Float64, Header};
use waam_rosmsg::trajectory_msgs::JointTrajectory;
use waam_rosmsg::waam_interfaces::{WeldPlan, WeldPoint};
use waam_thermal::{Simulation, ThermalModel};

use crate::node::io::{latched_qos, sensor_qos, stream_qos, subscribe, Output};
use crate::node::names::NodeNames;
use crate::node::ros::RosEnv;
use crate::node::{start_node, NodeError};

/// How the simulated cell runs.
#[derive(Debug, Clone)]
pub struct SimCellOptions {
    /// This node's names (`--ros-args`).
    pub names: NodeNames,
    /// The planner node whose topics are followed, resolved as a topic name in this node's
    /// namespace (`waam_planner`: `/<ns>/waam_planner/...`).
    pub planner: String,
    /// How many times as fast as planned the planner executes (its `dry_run.time_scale`).
    pub time_scale: f64,
    /// Publish a thermal camera's images too.
    pub thermal_camera: bool,
}

/// Why the simulated cell could not run.
#[derive(Debug, thiserror::Error)]
pub enum SimCellError {
    #[error(transparent)]
    Node(#[from] NodeError),
    #[error(transparent)]
    Env(#[from] crate::node::ros::RosEnvError),
    #[error(transparent)]
    Io(#[from] crate::node::io::IoError),
}

/// One weld path of the planner's plan: its deposits (part indices) and when each starts,
/// and when the arc goes out, on the plan's time line (s).
#[derive(Debug, Clone, PartialEq)]
struct WeldPath {
    blocks: Vec<usize>,
    starts_s: Vec<f64>,
    arc_off_s: f64,
}

/// The weld paths of a weld plan, for `part`; `None` when a block is not the part's (the
/// plan of another part) or a deposit has no time.
fn weld_paths(part: &Part, plan: &WeldPlan) -> Option<Vec<WeldPath>> {
    let secs = |p: &WeldPoint| p.time_from_start.as_secs_f64();
    let mut first: HashMap<(i32, i32), f64> = HashMap::new();
    let mut off: HashMap<i32, f64> = HashMap::new();
    for p in &plan.points {
        if p.arc_on && p.block >= 0 {
            let t = first.entry((p.fragment, p.block)).or_insert(secs(p));
            *t = t.min(secs(p));
        }
        if p.kind == WeldPoint::ARC_OFF {
            off.insert(p.fragment, secs(p));
        }
    }
    plan.fragments
        .iter()
        .enumerate()
        .map(|(f, fragment)| {
            let f = i32::try_from(f).ok()?;
            let blocks = fragment
                .blocks
                .iter()
                .map(|b| part.index_of(b.to_part()))
                .collect::<Option<Vec<_>>>()?;
            let starts_s = (0..blocks.len())
                .map(|j| first.get(&(f, i32::try_from(j).ok()?)).copied())
                .collect::<Option<Vec<_>>>()?;
            let arc_off_s = *off.get(&f)?;
            Some(WeldPath {
                blocks,
                starts_s,
                arc_off_s,
            })
        })
        .collect()
}

/// Runs the simulated cell for `part` on `truth` until `stop` is raised.
pub fn run(
    part: &Part,
    truth: &Truth,
    options: &SimCellOptions,
    stop: Arc<AtomicBool>,
) -> Result<(), SimCellError> {
    let env = RosEnv::from_env()?;
    let names = &options.names;
    let mut node = start_node(&env, names)?;
    let topic = |name: &str| format!("{}/{name}", options.planner.trim_end_matches('/'));
    let (_, plans): (_, Subscription<WeldPlan>) =
        subscribe(&mut node, names, &topic("plan/weld_plan"), latched_qos())?;
    let (_, arcs): (_, Subscription<Bool>) =
        subscribe(&mut node, names, &topic("arc_on"), stream_qos())?;
    let (_, feeds): (_, Subscription<Float64>) =
        subscribe(&mut node, names, &topic("wire_feed"), stream_qos())?;
    let (_, schedules): (_, Subscription<JointTrajectory>) =
        subscribe(&mut node, names, &topic("wire_feed_schedule"), stream_qos())?;
    let pyrometer = Output::<Temperature>::new(
        &mut node,
        names,
        &topic("temperature"),
        sensor_qos(),
        Qos::best_effort(10),
    )?;
    let scanner = Output::<PointCloud2>::new(
        &mut node,
        names,
        &topic("scan"),
        sensor_qos(),
        Qos::best_effort(10),
    )?;
    let camera = options
        .thermal_camera
        .then(|| {
            Output::<PointCloud2>::new(
                &mut node,
                names,
                &topic("thermal_image"),
                sensor_qos(),
                Qos::best_effort(10),
            )
        })
        .transpose()?;
    let sensors = Sensors {
        pyrometer,
        camera,
        time_scale: options.time_scale,
    };
    let welder = Output::<Header>::new(
        &mut node,
        names,
        &topic("arc_fault"),
        stream_qos(),
        Qos::reliable(10),
    )?;

    let true_part = counting_part(part, truth.thermal);
    let graph = WeldGraph::new(&true_part);
    let model = ThermalModel::new(&true_part, &graph);
    let mut cell = TrueCell {
        part,
        truth,
        sim: Simulation::new(&model).with_threads(1),
        noise: Noise::new(truth.seed, truth.noise_c),
        left_in_layer: layer_counts(part),
        top_mm: vec![0.0; part.len()],
        graph: &graph,
        scanned: 0,
        feed: 1.0,
        schedule: Vec::new(),
        struck: Vec::new(),
        first_strike: None,
        path_step: 0,
        end_step: 0,
    };
    tracing::info!(
        "simulated cell for {} ({} blocks) following {}: heat losses and heights of the true cell",
        part.name,
        part.len(),
        topic("")
    );
    let mut paths: Vec<WeldPath> = Vec::new();
    // The weld path being welded: its index, when its arc struck, deposits read so far.
    let mut welding: Option<(usize, Instant, std::time::SystemTime, usize)> = None;
    // Whether its arc went out by a fault (TRUTH.yaml's cut_short).
    let mut faulted = false;
    let mut welds = 0;
    while !stop.load(Ordering::Relaxed) {
        while let Ok(Some((plan, _))) = plans.take() {
            match weld_paths(part, &plan) {
                Some(p) => paths = p,
                None => tracing::warn!("a weld plan of another part ({}): ignored", plan.part_name),
            }
        }
        while let Ok(Some((feed, _))) = feeds.take() {
            cell.feed = feed.data;
        }
        while let Ok(Some((msg, _))) = schedules.take() {
            cell.follow(&msg);
        }
        let mut arc_changes = Vec::new();
        while let Ok(Some((arc, info))) = arcs.take() {
            arc_changes.push((arc.data, info.source_timestamp()));
        }
        for (on, published) in arc_changes {
            match (on, welding) {
                (true, None) => {
                    cell.struck.clear();
                    let (lit, wall) = struck_at(published);
                    welding = Some((welds, lit, wall, 0));
                    welds += 1;
                    faulted = false;
                }
                (false, Some((w, lit, wall, read))) => {
                    if let Some(path) = paths.get(w) {
                        // After a fault nothing more of the path was welded.
                        let all = if faulted { read } else { path.blocks.len() };
                        cell.strike(path, all);
                        cell.read(path, read..all, (lit, wall), &sensors);
                        cell.schedule.clear();
                        let before = cell.scanned;
                        cell.scan(&scanner);
                        tracing::info!(
                            "weld path {}: {all} deposits read by the pyrometer, struck at wire feed {:.3}; {} layer(s) scanned",
                            w + 1,
                            cell.feed,
                            cell.scanned - before
                        );
                    } else {
                        tracing::warn!("weld path {} is not in the weld plan received", w + 1);
                    }
                    welding = None;
                }
                _ => {}
            }
        }
        // The deposits ended by now on the weld path being welded.
        if let Some((w, lit, wall, read)) = &mut welding {
            if let Some(path) = paths.get(*w) {
                let t = path.starts_s[0] + lit.elapsed().as_secs_f64() * options.time_scale;
                // A fault where the path was meant to go on (as `waam sim-cell` cuts).
                let cut = truth
                    .cut_after(*w + 1)
                    .filter(|&after| after < path.blocks.len());
                let ended = (0..path.blocks.len())
                    .take_while(|&j| {
                        path.starts_s.get(j + 1).copied().unwrap_or(path.arc_off_s) <= t
                    })
                    .count()
                    .min(cut.unwrap_or(usize::MAX));
                // The welder sets each deposit's feed as it begins.
                let begun = path.starts_s.iter().take_while(|&&s| s <= t).count();
                cell.strike(path, begun.min(cut.map_or(usize::MAX, |c| c + 1)));
                if ended > *read {
                    cell.read(path, *read..ended, (*lit, *wall), &sensors);
                    *read = ended;
                    // The scanner follows the torch: a layer finished is scanned at once.
                    cell.scan(&scanner);
                }
                if let (Some(after), false) = (cut, faulted) {
                    if ended == after {
                        // Stamped when the deposit ended (the wall clock of the plan's time).
                        let out = path.starts_s[after] - path.starts_s[0];
                        let at =
                            *wall + Duration::from_secs_f64((out / options.time_scale).max(0.0));
                        welder.publish(&header(at, "welder"), None);
                        faulted = true;
                        tracing::info!(
                            "weld path {}: arc fault after {after} of {} deposits (TRUTH.yaml cut_short)",
                            *w + 1,
                            path.blocks.len()
                        );
                    }
                }
            }
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    drop(node);
    Ok(())
}

/// Blocks per layer.
fn layer_counts(part: &Part) -> Vec<usize> {
    let mut n = vec![0; part.layers().max(0) as usize];
    for i in 0..part.len() {
        n[part.block(i)[2] as usize] += 1;
    }
    n
}

/// What reads the true cell's heat, and how fast the plan runs.
struct Sensors {
    pyrometer: Output<Temperature>,
    camera: Option<Output<PointCloud2>>,
    time_scale: f64,
}

/// The true cell: its heat, its deposits' heights, and its sensors.
struct TrueCell<'a> {
    part: &'a Part,
    truth: &'a Truth,
    sim: Simulation<'a>,
    noise: Noise,
    left_in_layer: Vec<usize>,
    /// Each deposit's true top above the origin, mm: the mean top of what it stands on
    /// (nominal where nothing) plus its height, set by the wire feed it was welded at.
    top_mm: Vec<f64>,
    graph: &'a WeldGraph,
    /// Layers scanned so far (from the bottom).
    scanned: usize,
    /// The wire feed the planner asked for, relative to nominal; the schedule of the weld
    /// path under way (time from the arc strike, feed), revisions merged; and the feed each
    /// of its deposits began at.
    feed: f64,
    schedule: Vec<(f64, f64)>,
    struck: Vec<f64>,
    /// When the first weld path's arc struck (wall clock); the step of the true model the
    /// weld path under way struck at, and the step the last deposit ended at.
    first_strike: Option<Instant>,
    path_step: u64,
    end_step: u64,
}

impl TrueCell<'_> {
    /// A `~/wire_feed_schedule`: a weld path's (its first point at the arc strike), or a
    /// revision of the feeds from its first point on.
    fn follow(&mut self, msg: &JointTrajectory) {
        let Some(feeds) = waam_messages::wire_feed::schedule_feeds(msg) else {
            return;
        };
        let times: Vec<f64> = msg
            .points
            .iter()
            .map(|p| p.time_from_start.as_secs_f64())
            .collect();
        let from = times.first().copied().unwrap_or(0.0);
        self.schedule.retain(|&(t, _)| t < from - 1e-9);
        self.schedule.extend(times.into_iter().zip(feeds));
    }

    /// The deposits of `path` up to `begun` have begun: each takes the feed the schedule
    /// (else `~/wire_feed`) has for it now.
    fn strike(&mut self, path: &WeldPath, begun: usize) {
        let begun = begun.min(path.blocks.len());
        while self.struck.len() < begun {
            let at = path.starts_s[self.struck.len()] - path.starts_s[0];
            let feed = self
                .schedule
                .iter()
                .rev()
                .find(|&&(t, _)| t <= at + 1e-6)
                .map_or(self.feed, |&(_, f)| f);
            self.struck.push(feed);
        }
    }

    /// Deposits `range` of `path` welded on the true model, each read by the pyrometer: its
    /// true temperature at its end, stamped in its middle (on the wall clock: the arc struck
    /// at `lit`, the plan runs `time_scale` times as fast); the camera's image of every
    /// welded block with it.
    fn read(
        &mut self,
        path: &WeldPath,
        range: std::ops::Range<usize>,
        (strike, lit): (Instant, std::time::SystemTime),
        sensors: &Sensors,
    ) {
        let time_scale = sensors.time_scale;
        let dt = self.sim.dt();
        // The true model welds when the robot does: each weld path from when its arc struck
        // (on the plan's clock: the wall clock times the time scale), its deposits at their
        // times along the path.
        if range.start == 0 {
            let first = *self.first_strike.get_or_insert(strike);
            let since = strike.duration_since(first).as_secs_f64() * time_scale;
            self.path_step = ((since / dt).round() as u64).max(self.end_step);
        }
        let step = |t: f64| self.path_step + ((t - path.starts_s[0]) / dt).round().max(0.0) as u64;
        for j in range {
            let b = path.blocks[j];
            let end = path.starts_s.get(j + 1).copied().unwrap_or(path.arc_off_s);
            let (at, end_step) = (step(path.starts_s[j]), step(end));
            let arc_off = (j == 0).then_some(self.end_step);
            // Windows are widened on the true part: a deposit is never refused.
            let deposited = self
                .sim
                .deposit_at(b, j == 0, arc_off, at)
                .and_then(|()| self.sim.run_to(end_step, false));
            if deposited.is_err() {
                return;
            }
            self.end_step = end_step;
            let z = self.part.block(b)[2] as usize;
            let nominal = self.part.block_mm[2];
            let supports = self.graph.supports(b);
            let base = if supports.is_empty() {
                z as f64 * nominal
            } else {
                supports
                    .iter()
                    .map(|&s| self.top_mm[s as usize])
                    .sum::<f64>()
                    / supports.len() as f64
            };
            let factor = self
                .truth
                .height_factor_at(self.part.centre_mm(self.part.block(b)));
            let feed = self.struck.get(j).copied().unwrap_or(self.feed);
            self.top_mm[b] = base + nominal * factor * feed;
            self.left_in_layer[z] = self.left_in_layer[z].saturating_sub(1);
            let Some(celsius) = self.sim.temperatures().find(|&(o, _)| o == b).map(|t| t.1) else {
                continue;
            };
            let end = path.starts_s.get(j + 1).copied().unwrap_or(path.arc_off_s);
            let mid = (path.starts_s[j] + end) / 2.0 - path.starts_s[0];
            let stamp = lit + Duration::from_secs_f64((mid / time_scale).max(0.0));
            sensors.pyrometer.publish(
                &Temperature {
                    header: header(stamp, "pyrometer"),
                    temperature: celsius + self.noise.sample(),
                    variance: self.truth.noise_c * self.truth.noise_c,
                },
                None,
            );
            if let Some(camera) = &sensors.camera {
                let points: Vec<[f32; 4]> = self
                    .sim
                    .temperatures()
                    .collect::<Vec<_>>()
                    .into_iter()
                    .map(|(o, t)| {
                        // The deposit's centre where it stands: moved as far as its true
                        // top lies from the nominal one.
                        let [x, y, z] = self.part.centre_mm(self.part.block(o));
                        let nominal_top = z - self.part.origin_mm[2] + nominal / 2.0;
                        let z = z + self.top_mm[o] - nominal_top;
                        [x / 1000.0, y / 1000.0, z / 1000.0, t + self.noise.sample()]
                            .map(|v| v as f32)
                    })
                    .collect();
                let mut image = waam_messages::scan::thermal_cloud(
                    &points,
                    waam_messages::planning::PART_FRAME,
                );
                image.header.stamp = header(stamp, "").stamp;
                camera.publish(&image, None);
            }
        }
    }

    /// A scan of every layer finished and not scanned yet, bottom first: its blocks' centres
    /// at their true tops, in the part frame (metres).
    fn scan(&mut self, scanner: &Output<PointCloud2>) {
        while self.scanned < self.left_in_layer.len() && self.left_in_layer[self.scanned] == 0 {
            let z = self.scanned;
            let points: Vec<[f32; 3]> = (0..self.part.len())
                .filter(|&i| self.part.block(i)[2] as usize == z)
                .map(|i| {
                    let c = self.part.centre_mm(self.part.block(i));
                    [c[0], c[1], self.part.origin_mm[2] + self.top_mm[i]]
                        .map(|v| (v / 1000.0) as f32)
                })
                .collect();
            let mut cloud =
                waam_messages::scan::cloud(&points, waam_messages::planning::PART_FRAME);
            cloud.header.stamp = header(std::time::SystemTime::now(), "").stamp;
            scanner.publish(&cloud, None);
            self.scanned += 1;
        }
    }
}

/// When the arc struck, on this process's monotonic clock and on the wall clock: when the
/// planner published `~/arc_on` (its source timestamp), however late it was taken here on a
/// busy machine; now when the message has none.
fn struck_at(published: Option<ROSTime>) -> (Instant, std::time::SystemTime) {
    let now = (Instant::now(), std::time::SystemTime::now());
    let ago = published
        .and_then(|t| {
            let at =
                std::time::UNIX_EPOCH + Duration::from_nanos(u64::try_from(t.to_nanos()).ok()?);
            now.1.duration_since(at).ok()
        })
        .unwrap_or_default();
    match (now.0.checked_sub(ago), now.1.checked_sub(ago)) {
        (Some(lit), Some(wall)) => (lit, wall),
        _ => now,
    }
}

/// A header stamped `at` (wall clock) in `frame`.
fn header(at: std::time::SystemTime, frame: &str) -> Header {
    let nanos = at
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| i64::try_from(d.as_nanos()).unwrap_or(i64::MAX));
    Header {
        stamp: Time::from_nanos(nanos),
        frame_id: frame.into(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use waam_rosmsg::builtin_interfaces::Duration as RosDuration;
    use waam_rosmsg::waam_interfaces::{Block, WeldFragment};

    #[test]
    fn the_weld_plan_gives_each_deposit_its_start_and_each_path_its_arc_off() {
        let part =
            Part::parse("name: w\nblock_mm: [6, 6, 2.5]\nmax_fragments: 1\nlayers: ['##']\n")
                .unwrap();
        let point = |t: f64, kind: u8, arc_on: bool, block: i32| WeldPoint {
            time_from_start: RosDuration::from_secs_f64(t),
            kind,
            arc_on,
            fragment: 0,
            block,
            ..Default::default()
        };
        let plan = WeldPlan {
            fragments: vec![WeldFragment {
                blocks: vec![Block { x: 1, y: 0, z: 0 }, Block { x: 0, y: 0, z: 0 }],
            }],
            points: vec![
                point(0.0, WeldPoint::APPROACH, false, -1),
                point(1.0, WeldPoint::ARC_ON, true, 0),
                point(1.5, WeldPoint::WELD, true, 0),
                point(2.0, WeldPoint::WELD, true, 1),
                point(3.0, WeldPoint::ARC_OFF, false, -1),
            ],
            ..Default::default()
        };
        let paths = weld_paths(&part, &plan).unwrap();
        assert_eq!(
            paths,
            [WeldPath {
                blocks: vec![1, 0],
                starts_s: vec![1.0, 2.0],
                arc_off_s: 3.0
            }]
        );
        // A block the part does not have: another part's plan.
        let mut other = plan.clone();
        other.fragments[0].blocks[0].x = 7;
        assert!(weld_paths(&part, &other).is_none());
    }
}
