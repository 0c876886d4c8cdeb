//! Toolpaths: torch poses with arc-on / arc-off markers, approach, retract and transit.
//!
//! The input is a list of [`WeldPass`]es — torch target points along which the arc
//! burns — so that block plans ([`passes_from_plan`]) and other planners (layer trails)
//! feed the same builder. For each pass [`build`] emits:
//!
//! transit at safe height (arc off) → approach along the torch axis → **arc-on marker**
//! at the first point → dwell → one weld pose per point (plus interpolated poses) →
//! **arc-off marker** after the dwell at the last point → retract along the torch axis.
//!
//! A pose's `arc_on` is the arc's state from that pose on: the arc-on marker is the first
//! pose with the arc on, the arc-off marker the first with it off again.

pub mod beads;
pub mod settings;

use std::fmt::Write as _;

use nalgebra::{Isometry3, Point3, Translation3, Unit, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};
use thiserror::Error;

pub use beads::{toolpath_of_graph_plan, ToolpathFrame, PART_FRAME};
pub use settings::{ProcessSettings, SettingsError};
use waam_part::Part;

/// One weld path: torch target points (TCP) in the part frame, mm; the arc burns along it.
#[derive(Debug, Clone, PartialEq)]
pub struct WeldPass {
    pub points_mm: Vec<Point3<f64>>,
}

/// One pass per fragment, one point per block at the top centre of the block (the torch
/// rises one layer height on an up move).
pub fn passes_from_plan(part: &Part, fragments: &[Vec<usize>]) -> Vec<WeldPass> {
    fragments
        .iter()
        .map(|f| WeldPass {
            points_mm: f
                .iter()
                .map(|&b| {
                    let c = part.centre_mm(part.block(b));
                    Point3::new(c[0], c[1], c[2] + 0.5 * part.block_mm[2])
                })
                .collect(),
        })
        .collect()
}

/// The toolpath of a plan of `part` in `frame`: for a graph part
/// ([`Part::bead_part`]) along its beads ([`toolpath_of_graph_plan`]), for a cube part
/// through the blocks' top centres ([`passes_from_plan`]) at [`WeldTiming::of_plan`].
pub fn toolpath_of_plan(
    part: &Part,
    fragments: &[Vec<usize>],
    settings: &ProcessSettings,
    frame: ToolpathFrame,
) -> Result<Toolpath, ToolpathError> {
    if let Some(beads) = part.bead_part() {
        return toolpath_of_graph_plan(beads, fragments, settings, frame);
    }
    let timing = WeldTiming::of_plan(part, settings);
    let routes: Vec<Route> = passes_from_plan(part, fragments)
        .iter()
        .map(|p| Route::of_pass(p, timing))
        .collect();
    let (plate, name) = frame.placement(settings);
    build_routes(&routes, settings, plate, &name)
}

/// How long the torch takes from one weld point to the next.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum WeldTiming {
    /// The same time for every step, s (a block plan: the thermal model's `block_time_s`).
    PerPoint(f64),
    /// A constant speed, mm/s.
    Speed(f64),
}

impl WeldTiming {
    /// A block plan's: the process settings' weld speed, else one block per the part's
    /// `block_time_s`.
    pub fn of_plan(part: &Part, settings: &ProcessSettings) -> WeldTiming {
        match settings.weld_speed_mm_s {
            Some(v) => WeldTiming::Speed(v),
            None => WeldTiming::PerPoint(part.thermal.block_time_s),
        }
    }
}

/// What a pose is for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PoseKind {
    Transit,
    Approach,
    /// The arc turns on here (first point of a pass).
    ArcOn,
    Weld,
    /// The arc turns off here (last point of a pass, after the dwell).
    ArcOff,
    Retract,
}

/// One TCP pose of a toolpath.
#[derive(Debug, Clone, PartialEq)]
pub struct ToolPose {
    /// Time from the start, s.
    pub time_s: f64,
    /// The TCP in the robot's base link (m); z is the wire direction.
    pub pose: Isometry3<f64>,
    /// The arc's state from this pose on.
    pub arc_on: bool,
    /// Index of the pass (fragment) this pose belongs to, from 0.
    pub fragment: usize,
    /// Index of the pass point this pose is at (weld, markers) or next to (approach:
    /// the first point; retract: the last; transit: the next pass's first point).
    pub point: usize,
    pub kind: PoseKind,
    /// True at a pass point itself, false for an interpolated pose.
    pub at_point: bool,
}

/// A toolpath: poses in time order, in the robot's base link.
#[derive(Debug, Clone, PartialEq)]
pub struct Toolpath {
    /// The frame of every pose (the robot's base link).
    pub frame: String,
    pub poses: Vec<ToolPose>,
}

/// A toolpath's figures: what `waam plan --robot` prints and `--json` and `part-plan.yaml`
/// report.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct MotionSummary {
    pub poses: usize,
    /// Weld poses at pass points (blocks, layer steps).
    pub weld_points: usize,
    /// Arc-on markers: one per weld pass.
    pub passes: usize,
    pub duration_s: f64,
    pub arc_on_s: f64,
}

impl MotionSummary {
    pub fn of(tp: &Toolpath) -> MotionSummary {
        MotionSummary {
            poses: tp.poses.len(),
            weld_points: tp
                .poses
                .iter()
                .filter(|p| p.kind == PoseKind::Weld && p.at_point)
                .count(),
            passes: tp
                .poses
                .iter()
                .filter(|p| p.kind == PoseKind::ArcOn)
                .count(),
            duration_s: tp.poses.last().map_or(0.0, |p| p.time_s),
            arc_on_s: tp
                .poses
                .windows(2)
                .filter(|w| w[0].arc_on)
                .map(|w| w[1].time_s - w[0].time_s)
                .sum(),
        }
    }
}

/// A toolpath that cannot be built.
#[derive(Debug, Error, PartialEq)]
pub enum ToolpathError {
    #[error("no weld passes")]
    NoPasses,
    #[error("weld pass {0} has no points")]
    EmptyPass(usize),
    #[error("weld pass {pass} point {point} is not a finite point")]
    BadPoint { pass: usize, point: usize },
    #[error("fragment {pass} position {point}: no node {node} (the part has {nodes})")]
    UnknownNode {
        pass: usize,
        point: usize,
        node: usize,
        nodes: usize,
    },
    #[error(
        "the toolpath would need about {poses:.2e} poses, more than max_poses = {max} \
         (its longest move, {what}, is {longest_mm:.3e} mm at max_step_mm = {step_mm}); \
         raise max_step_mm or max_poses in the process settings, or check the part's size"
    )]
    TooManyPoses {
        poses: f64,
        max: usize,
        what: &'static str,
        longest_mm: f64,
        step_mm: f64,
    },
}

/// An upper bound of the poses [`build`] emits, computed in f64 before anything is
/// allocated (block_mm near f64's range or a tiny max_step_mm asked for more poses than
/// memory holds). A straight line gets at most length / max_step_mm + 1 poses, plus
/// its turn / max_step_deg where the torch turns: on the travel lines (6 a pass) and on the
/// two weld steps around each point where the pass changes direction (the torch heading
/// changes nowhere else; a bead route's chord heading may change at any point, so its
/// every step counts as turning). Travel lines are bounded by the passes' bounding box.
fn check_pose_budget<P: AsRef<[Point3<f64>]>>(
    passes: &[P],
    s: &ProcessSettings,
    every_step_turns: bool,
) -> Result<(), ToolpathError> {
    let (mut poses, longest) = pose_bound(passes, s);
    if every_step_turns {
        let steps: usize = passes.iter().map(|p| p.as_ref().len()).sum();
        let turn_deg = (2.0 * (s.travel_angle_deg.abs() + s.work_angle_deg.abs())).min(180.0);
        poses += 2.0 * steps as f64 * turn_deg / s.max_step_deg;
    }
    if poses.is_nan() || poses > s.max_poses as f64 {
        return Err(ToolpathError::TooManyPoses {
            poses,
            max: s.max_poses,
            what: longest.1,
            longest_mm: longest.0,
            step_mm: s.max_step_mm,
        });
    }
    Ok(())
}

/// The bound of [`check_pose_budget`], and the longest move (mm, what).
fn pose_bound<P: AsRef<[Point3<f64>]>>(
    passes: &[P],
    s: &ProcessSettings,
) -> (f64, (f64, &'static str)) {
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    let mut lines = 2.0;
    let mut turning_lines = 2.0;
    let mut weld_mm = 0.0;
    let mut longest = (0.0f64, "a weld step");
    for pass in passes {
        let pts = pass.as_ref();
        lines += pts.len() as f64 + 6.0;
        turning_lines += 6.0;
        let direction = |i: usize| {
            let d = pts[i + 1] - pts[i];
            let h = Vector3::new(d.x, d.y, 0.0);
            (h.norm() > 1e-9).then(|| h.normalize())
        };
        for i in 0..pts.len().saturating_sub(1) {
            let d = (pts[i + 1] - pts[i]).norm();
            weld_mm += d;
            if d > longest.0 {
                longest = (d, "a weld step");
            }
            let turns = i > 0
                && match (direction(i - 1), direction(i)) {
                    (Some(a), Some(b)) => (a - b).norm() > 1e-9,
                    (None, None) => false,
                    _ => true,
                };
            if turns || i == 0 {
                turning_lines += 2.0;
            }
        }
        for p in pts {
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
    }
    let diagonal = (0..3).map(|k| (hi[k] - lo[k]).powi(2)).sum::<f64>().sqrt();
    let travel = diagonal + s.transit_height_mm() + 2.0 * s.approach_mm;
    if travel > longest.0 {
        longest = (travel, "a transit across the part");
    }
    let travel_mm = 4.0 * travel * passes.len() as f64;
    // Every torch orientation is the vertical torch tilted by at most |travel| + |work|
    // angle, so two of them differ by at most twice that.
    let turn_deg = (2.0 * (s.travel_angle_deg.abs() + s.work_angle_deg.abs())).min(180.0);
    let poses =
        (weld_mm + travel_mm) / s.max_step_mm + lines + turning_lines * turn_deg / s.max_step_deg;
    (poses, longest)
}

/// A waypoint in the part frame while building.
#[derive(Debug, Clone, Copy)]
struct Way {
    p: Point3<f64>,
    r: UnitQuaternion<f64>,
}

struct Builder<'a> {
    s: &'a ProcessSettings,
    plate: Isometry3<f64>,
    poses: Vec<ToolPose>,
    at: Option<Way>,
    time: f64,
}

impl Builder<'_> {
    /// Moves in a straight line (position and rotation) from the current waypoint to `to`
    /// in `duration` s, emitting interpolated poses; the last gets `last_kind`/`last_arc`.
    #[allow(clippy::too_many_arguments)]
    fn line(
        &mut self,
        to: Way,
        duration: f64,
        kind: PoseKind,
        arc: bool,
        last_kind: PoseKind,
        last_arc: bool,
        fragment: usize,
        point: usize,
        at_point: bool,
    ) {
        let Some(from) = self.at else {
            self.push(to, kind, arc, fragment, point, at_point);
            return;
        };
        let dist = (to.p - from.p).norm();
        let rel = to.r * from.r.inverse();
        let angle = rel.angle();
        let n = ((dist / self.s.max_step_mm).ceil())
            .max((angle.to_degrees() / self.s.max_step_deg).ceil())
            .max(1.0) as usize;
        let axis = rel.axis().unwrap_or(Vector3::z_axis());
        for k in 1..=n {
            let t = k as f64 / n as f64;
            let way = Way {
                p: from.p + (to.p - from.p) * t,
                r: UnitQuaternion::from_axis_angle(&axis, angle * t) * from.r,
            };
            self.time += duration / n as f64;
            if k == n {
                self.push(to, last_kind, last_arc, fragment, point, at_point);
            } else {
                self.push(way, kind, arc, fragment, point, false);
            }
        }
    }

    /// A transit/approach/retract line at the transit speed (skipped when too short).
    fn travel(&mut self, to: Way, kind: PoseKind, fragment: usize, point: usize) {
        let from = self.at.expect("travel starts from a pose");
        let dist = (to.p - from.p).norm();
        if dist < 1e-6 && to.r.angle_to(&from.r) < 1e-9 {
            return;
        }
        let duration = dist / self.s.transit_speed_mm_s;
        self.line(
            to, duration, kind, false, kind, false, fragment, point, false,
        );
    }

    fn push(
        &mut self,
        w: Way,
        kind: PoseKind,
        arc_on: bool,
        fragment: usize,
        point: usize,
        at_point: bool,
    ) {
        let part = Isometry3::from_parts(Translation3::from(w.p.coords / 1000.0), w.r);
        let mut pose = self.plate * part;
        // Keep consecutive quaternions in one hemisphere: no sign flips.
        if let Some(prev) = self.poses.last() {
            if prev.pose.rotation.coords.dot(&pose.rotation.coords) < 0.0 {
                pose.rotation = UnitQuaternion::new_unchecked(-pose.rotation.into_inner());
            }
        }
        self.poses.push(ToolPose {
            time_s: self.time,
            pose,
            arc_on,
            fragment,
            point,
            kind,
            at_point,
        });
        self.at = Some(w);
    }
}

/// The torch's travel heading at each point of a pass: the bisector of the incoming and
/// outgoing horizontal moves (a corner turns in two halves, a U-turn over an up move in
/// two quarter turns); a point without horizontal moves keeps the previous heading.
fn headings(points: &[Point3<f64>], mut carry: Vector3<f64>) -> Vec<Vector3<f64>> {
    let horizontal = |a: &Point3<f64>, b: &Point3<f64>| {
        let d = Vector3::new(b.x - a.x, b.y - a.y, 0.0);
        (d.norm() > 1e-9).then(|| d.normalize())
    };
    let n = points.len();
    let mut out = Vec::with_capacity(n);
    for i in 0..n {
        let h_in = (i > 0)
            .then(|| horizontal(&points[i - 1], &points[i]))
            .flatten();
        let h_out = (i + 1 < n)
            .then(|| horizontal(&points[i], &points[i + 1]))
            .flatten();
        let a = h_in.or(if i == 0 { h_out } else { None }).unwrap_or(carry);
        let b = h_out.unwrap_or(a);
        let sum = a + b;
        let h = if sum.norm() < 1e-9 {
            Vector3::new(-a.y, a.x, 0.0)
        } else {
            sum.normalize()
        };
        out.push(h);
        carry = h;
    }
    out
}

/// The torch's travel heading at each point of a pass: the horizontal chord from the point
/// `window` mm of path behind it to the point `window` mm ahead (less near the pass's
/// ends, so that the chord stays centred on the point). On a circle that is the tangent; a corner or a U-turn is turned over 2·`window`
/// of path, however short the segments around it. Without a horizontal chord (a climb),
/// the previous heading.
fn chord_headings(
    points: &[Point3<f64>],
    window: f64,
    mut carry: Vector3<f64>,
) -> Vec<Vector3<f64>> {
    let mut at = Vec::with_capacity(points.len());
    let mut s = 0.0;
    for (i, p) in points.iter().enumerate() {
        if i > 0 {
            s += (p - points[i - 1]).norm();
        }
        at.push(s);
    }
    // The point `t` mm along the pass.
    let point = |t: f64| -> Point3<f64> {
        let t = t.clamp(0.0, s);
        let i = at
            .partition_point(|&a| a <= t)
            .clamp(1, points.len().max(2) - 1);
        if points.len() < 2 {
            return points[0];
        }
        let len = at[i] - at[i - 1];
        let u = if len > 0.0 {
            (t - at[i - 1]) / len
        } else {
            0.0
        };
        points[i - 1] + (points[i] - points[i - 1]) * u
    };
    let n = points.len();
    at.iter()
        .enumerate()
        .map(|(i, &t)| {
            // Symmetric about the point (a circle's tangent), so narrower near the ends;
            // at an end, its segment.
            let w = window.min(t).min(s - t);
            let d = match i {
                _ if w > 1e-6 => point(t + w) - point(t - w),
                0 if n > 1 => points[1] - points[0],
                _ if n > 1 => points[i] - points[i - 1],
                _ => Vector3::zeros(),
            };
            let h = Vector3::new(d.x, d.y, 0.0);
            if h.norm() > 1e-9 {
                carry = h.normalize();
            }
            carry
        })
        .collect()
}

/// The torch orientation for a heading: z (the wire) points down, tilted forward by the
/// travel angle and sideways by the work angle. The torch does not spin about its own
/// axis: its frame is the vertical torch (x along the part's +x, z down) tilted the
/// shortest way, so rings and spirals do not wind up the last joint.
fn torch_rotation(h: &Vector3<f64>, s: &ProcessSettings) -> UnitQuaternion<f64> {
    let (alpha, beta) = (
        s.travel_angle_deg.to_radians(),
        s.work_angle_deg.to_radians(),
    );
    let down = -Vector3::z();
    let z0 = down * alpha.cos() + h * alpha.sin();
    let z = UnitQuaternion::from_axis_angle(&Unit::new_normalize(*h), beta) * z0;
    let vertical = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI);
    let tilt = UnitQuaternion::rotation_between(&down, &z).unwrap_or_else(UnitQuaternion::identity);
    tilt * vertical
}

/// Builds the toolpath of the passes, in the robot's `frame` (the base link).
pub fn build(
    passes: &[WeldPass],
    settings: &ProcessSettings,
    timing: WeldTiming,
    frame: &str,
) -> Result<Toolpath, ToolpathError> {
    let routes: Vec<Route> = passes.iter().map(|p| Route::of_pass(p, timing)).collect();
    build_routes(&routes, settings, settings.plate.isometry(), frame)
}

/// A weld pass as the builder walks it: stations (torch targets, part frame, mm) with the
/// time from the station before and the pass point each is at or next to. A block plan
/// has one station per block; a bead path ([`beads`]) also has the centre line's
/// vertices, which are not deposits (`at_point` false) and so add no deposit time to
/// [`Toolpath::executed_times`].
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Route {
    pub points_mm: Vec<Point3<f64>>,
    /// Time from the station before, s (the first station's is not used).
    pub step_s: Vec<f64>,
    /// (pass point, at the point itself) of every station.
    pub marks: Vec<(usize, bool)>,
    /// 0: the torch heads along the bisector at each station ([`headings`]); else along
    /// the chord from this far (mm of path) behind the station to this far ahead
    /// ([`chord_headings`]): a bead's centre line, whose short segments and corners
    /// would turn the torch faster than the arm's joints can.
    pub heading_window_mm: f64,
}

impl Route {
    fn of_pass(pass: &WeldPass, timing: WeldTiming) -> Route {
        let pts = &pass.points_mm;
        let step_s = (0..pts.len())
            .map(|i| match (i, timing) {
                (0, _) => 0.0,
                (_, WeldTiming::PerPoint(t)) => t,
                (_, WeldTiming::Speed(v)) => (pts[i] - pts[i - 1]).norm() / v,
            })
            .collect();
        Route {
            points_mm: pts.clone(),
            step_s,
            marks: (0..pts.len()).map(|i| (i, true)).collect(),
            heading_window_mm: 0.0,
        }
    }
}

impl AsRef<[Point3<f64>]> for Route {
    fn as_ref(&self) -> &[Point3<f64>] {
        &self.points_mm
    }
}

impl AsRef<[Point3<f64>]> for WeldPass {
    fn as_ref(&self) -> &[Point3<f64>] {
        &self.points_mm
    }
}

/// The builder shared by block plans, layer trails and bead paths: transit, approach,
/// arc on, the stations, arc off, retract, with `plate` the part frame in `frame`.
pub(crate) fn build_routes(
    routes: &[Route],
    settings: &ProcessSettings,
    plate: Isometry3<f64>,
    frame: &str,
) -> Result<Toolpath, ToolpathError> {
    if routes.is_empty() {
        return Err(ToolpathError::NoPasses);
    }
    for (f, route) in routes.iter().enumerate() {
        if route.points_mm.is_empty() {
            return Err(ToolpathError::EmptyPass(f));
        }
        if let Some(i) = route
            .points_mm
            .iter()
            .position(|p| !p.iter().all(|v| v.is_finite()))
        {
            return Err(ToolpathError::BadPoint {
                pass: f,
                point: route.marks[i].0,
            });
        }
    }
    let chords = routes.iter().any(|r| r.heading_window_mm > 0.0);
    check_pose_budget(routes, settings, chords)?;
    let s = settings;
    let mut b = Builder {
        s,
        plate,
        poses: Vec::new(),
        at: None,
        time: 0.0,
    };
    let back_off = |w: &Way| Way {
        p: w.p - (w.r * Vector3::z()) * s.approach_mm,
        r: w.r,
    };
    // The tallest point welded so far (the plate's surface at first).
    let mut tallest = 0.0f64;
    let mut heading = Vector3::x();
    for (f, route) in routes.iter().enumerate() {
        let pts = &route.points_mm;
        let hs = match route.heading_window_mm {
            w if w > 0.0 => chord_headings(pts, w, heading),
            _ => headings(pts, heading),
        };
        heading = *hs.last().expect("a pass has points");
        let ways: Vec<Way> = pts
            .iter()
            .zip(&hs)
            .map(|(p, h)| Way {
                p: *p,
                r: torch_rotation(h, s),
            })
            .collect();
        let first = route.marks[0].0;
        let approach = back_off(&ways[0]);
        let mut safe = (tallest + s.transit_height_mm()).max(approach.p.z);
        match b.at {
            None => {
                let start = Way {
                    p: Point3::new(approach.p.x, approach.p.y, safe),
                    r: approach.r,
                };
                b.line(
                    start,
                    0.0,
                    PoseKind::Transit,
                    false,
                    PoseKind::Transit,
                    false,
                    f,
                    first,
                    false,
                );
            }
            Some(at) => {
                safe = safe.max(at.p.z);
                b.travel(
                    Way {
                        p: Point3::new(at.p.x, at.p.y, safe),
                        r: at.r,
                    },
                    PoseKind::Transit,
                    f,
                    first,
                );
                b.travel(
                    Way {
                        p: Point3::new(approach.p.x, approach.p.y, safe),
                        r: approach.r,
                    },
                    PoseKind::Transit,
                    f,
                    first,
                );
            }
        }
        b.travel(approach, PoseKind::Transit, f, first);
        // Approach along the torch axis; its last pose is the arc-on marker.
        let dist = (ways[0].p - approach.p).norm();
        b.line(
            ways[0],
            dist / s.transit_speed_mm_s,
            PoseKind::Approach,
            false,
            PoseKind::ArcOn,
            true,
            f,
            first,
            true,
        );
        b.time += s.arc_on_dwell_s;
        b.push(ways[0], PoseKind::Weld, true, f, first, true);
        for ((way, &(point, at_point)), &step_s) in
            ways.iter().zip(&route.marks).zip(&route.step_s).skip(1)
        {
            b.line(
                *way,
                step_s,
                PoseKind::Weld,
                true,
                PoseKind::Weld,
                true,
                f,
                point,
                at_point,
            );
        }
        let last = ways.len() - 1;
        let (last_point, _) = route.marks[last];
        b.time += s.arc_off_dwell_s;
        b.push(ways[last], PoseKind::ArcOff, false, f, last_point, true);
        b.travel(back_off(&ways[last]), PoseKind::Retract, f, last_point);
        tallest = pts.iter().map(|p| p.z).fold(tallest, f64::max);
    }
    // Leave the part: up to safe height above the last retract.
    let at = b.at.expect("poses were emitted");
    let f = routes.len() - 1;
    let safe = (tallest + s.transit_height_mm()).max(at.p.z);
    let last_point = routes[f].marks.last().expect("a pass has points").0;
    b.travel(
        Way {
            p: Point3::new(at.p.x, at.p.y, safe),
            r: at.r,
        },
        PoseKind::Transit,
        f,
        last_point,
    );
    Ok(Toolpath {
        frame: frame.to_string(),
        poses: b.poses,
    })
}

/// When the torch deposits each block and switches the arc off, s from the start: the
/// executed time line the thermal check runs on.
#[derive(Debug, Clone, PartialEq)]
pub struct ExecutedTimes {
    /// Per pass, per point: the first point's at its arc-on marker (the arc strikes on
    /// it), every later point's when the torch reaches it.
    pub deposits_s: Vec<Vec<f64>>,
    /// Per pass: its arc-off marker.
    pub arc_off_s: Vec<f64>,
}

impl Toolpath {
    /// The deposit and arc-off times of every pass, read from the poses.
    pub fn executed_times(&self) -> ExecutedTimes {
        let mut deposits_s: Vec<Vec<f64>> = Vec::new();
        let mut arc_off_s = Vec::new();
        for p in &self.poses {
            match p.kind {
                PoseKind::ArcOn => deposits_s.push(vec![p.time_s]),
                PoseKind::Weld if p.at_point && p.point > 0 => {
                    if let Some(d) = deposits_s.last_mut() {
                        d.push(p.time_s);
                    }
                }
                PoseKind::ArcOff => arc_off_s.push(p.time_s),
                _ => {}
            }
        }
        ExecutedTimes {
            deposits_s,
            arc_off_s,
        }
    }
}

/// `toolpath.yaml`: exactly these keys (SI units, quaternions [x, y, z, w]).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ToolpathFile {
    pub frame: String,
    pub poses: Vec<ToolpathFilePose>,
}

/// One pose of `toolpath.yaml`.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ToolpathFilePose {
    pub time: f64,
    pub position: [f64; 3],
    pub orientation: [f64; 4],
    pub arc_on: bool,
    pub fragment: usize,
}

impl ToolpathFilePose {
    /// The pose as an isometry.
    pub fn isometry(&self) -> Isometry3<f64> {
        let [x, y, z, w] = self.orientation;
        Isometry3::from_parts(
            Translation3::new(self.position[0], self.position[1], self.position[2]),
            UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(w, x, y, z)),
        )
    }
}

impl Toolpath {
    /// The file form of the toolpath.
    pub fn to_file(&self) -> ToolpathFile {
        ToolpathFile {
            frame: self.frame.clone(),
            poses: self
                .poses
                .iter()
                .map(|p| {
                    let t = p.pose.translation.vector;
                    let q = p.pose.rotation.coords;
                    ToolpathFilePose {
                        time: p.time_s,
                        position: [t.x, t.y, t.z],
                        orientation: [q.x, q.y, q.z, q.w],
                        arc_on: p.arc_on,
                        fragment: p.fragment,
                    }
                })
                .collect(),
        }
    }

    /// `toolpath.yaml` text, one pose per line.
    pub fn to_yaml(&self) -> String {
        let file = self.to_file();
        let mut out = String::new();
        let _ = writeln!(
            out,
            "frame: {}",
            serde_json::to_string(&file.frame).expect("a string")
        );
        out.push_str("poses:\n");
        for p in &file.poses {
            let _ = writeln!(
                out,
                "  - {{time: {:?}, position: {}, orientation: {}, arc_on: {}, fragment: {}}}",
                p.time,
                list(&p.position),
                list(&p.orientation),
                p.arc_on,
                p.fragment
            );
        }
        out
    }
}

/// A flow-style YAML list of floats written to full precision.
pub(crate) fn list(v: &[f64]) -> String {
    let items: Vec<String> = v.iter().map(|x| format!("{x:?}")).collect();
    format!("[{}]", items.join(", "))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn straight(n: usize) -> WeldPass {
        WeldPass {
            points_mm: (0..n)
                .map(|i| Point3::new(6.0 * i as f64, 0.0, 2.5))
                .collect(),
        }
    }

    #[test]
    fn a_pass_has_markers_dwells_and_transits() {
        let s = ProcessSettings::default();
        let tp = build(
            &[straight(3), straight(2)],
            &s,
            WeldTiming::PerPoint(1.0),
            "base_link",
        )
        .unwrap();
        let kinds: Vec<PoseKind> = tp.poses.iter().map(|p| p.kind).collect();
        assert_eq!(kinds.iter().filter(|k| **k == PoseKind::ArcOn).count(), 2);
        assert_eq!(kinds.iter().filter(|k| **k == PoseKind::ArcOff).count(), 2);
        // Times strictly increase.
        assert!(tp.poses.windows(2).all(|w| w[1].time_s > w[0].time_s));
        // The arc is on exactly from each arc-on marker to the next arc-off marker.
        let mut on = false;
        for p in &tp.poses {
            match p.kind {
                PoseKind::ArcOn => {
                    assert!(!on && p.arc_on);
                    on = true;
                }
                PoseKind::ArcOff => {
                    assert!(on && !p.arc_on);
                    on = false;
                }
                _ => assert_eq!(p.arc_on, on, "{:?}", p.kind),
            }
        }
        // Weld: three key poses in pass 0, one block time apart after the dwell.
        let keys: Vec<&ToolPose> = tp
            .poses
            .iter()
            .filter(|p| p.fragment == 0 && p.kind == PoseKind::Weld && p.at_point)
            .collect();
        assert_eq!(keys.len(), 3);
        assert!((keys[1].time_s - keys[0].time_s - 1.0).abs() < 1e-12);
        let on = tp.poses.iter().find(|p| p.kind == PoseKind::ArcOn).unwrap();
        assert!((keys[0].time_s - on.time_s - s.arc_on_dwell_s).abs() < 1e-12);
        // Weld poses sit on the points (plate offset added, metres).
        let plate = s.plate.isometry();
        let expect = plate * Point3::new(0.012, 0.0, 0.0025);
        assert!((keys[2].pose.translation.vector - expect.coords).norm() < 1e-12);
        // Transit clears the tallest block by the clearance.
        let top = tp
            .poses
            .iter()
            .filter(|p| p.kind == PoseKind::Transit)
            .map(|p| p.pose.translation.z)
            .fold(f64::MIN, f64::max);
        assert!(top >= plate.translation.z + 0.0025 + 0.020 - 1e-12);
        // Steps stay within the resolution.
        for w in tp.poses.windows(2) {
            let d = (w[1].pose.translation.vector - w[0].pose.translation.vector).norm();
            assert!(d <= s.max_step_mm / 1000.0 + 1e-12);
            assert!(w[0].pose.rotation.coords.dot(&w[1].pose.rotation.coords) >= 0.0);
        }
    }

    #[test]
    fn the_torch_leans_along_travel_and_keeps_heading_on_up_moves() {
        let s = ProcessSettings::default();
        let pass = WeldPass {
            points_mm: vec![
                Point3::new(0.0, 0.0, 2.5),
                Point3::new(6.0, 0.0, 2.5),
                Point3::new(6.0, 0.0, 5.0),
                Point3::new(0.0, 0.0, 5.0),
            ],
        };
        let hs = headings(&pass.points_mm, Vector3::x());
        assert!((hs[0] - Vector3::x()).norm() < 1e-12);
        assert!(
            (hs[1] - Vector3::x()).norm() < 1e-12,
            "up move keeps the heading"
        );
        assert!(hs[2].x.abs() < 1e-12, "a U-turn turns in quarters");
        assert!((hs[3] + Vector3::x()).norm() < 1e-12);
        let r = torch_rotation(&Vector3::x(), &s);
        let z = r * Vector3::z();
        assert!(
            z.z < 0.0 && z.x > 0.0,
            "push: the wire points down and forward"
        );
        assert!((z.x - s.travel_angle_deg.to_radians().sin()).abs() < 1e-12);
        // The torch does not spin with the heading: its x axis stays near the part's +x.
        for h in [Vector3::x(), Vector3::y(), -Vector3::x(), -Vector3::y()] {
            let r = torch_rotation(&h, &s);
            assert!((r * Vector3::x()).x > 0.98, "{h}");
            let tilt = (r * Vector3::z()).angle(&-Vector3::z());
            assert!((tilt - s.travel_angle_deg.to_radians()).abs() < 1e-12);
        }
    }

    #[test]
    fn empty_input_is_refused() {
        let s = ProcessSettings::default();
        assert_eq!(
            build(&[], &s, WeldTiming::PerPoint(1.0), "b"),
            Err(ToolpathError::NoPasses)
        );
        let e = build(
            &[straight(1), WeldPass { points_mm: vec![] }],
            &s,
            WeldTiming::PerPoint(1.0),
            "b",
        );
        assert_eq!(e, Err(ToolpathError::EmptyPass(1)));
    }

    /// The pose budget (issue #18, C2) bounds what `build` emits, and is not far above
    /// it on ordinary passes (so it refuses absurd inputs, not large parts).
    #[test]
    fn the_pose_bound_holds_and_is_not_wildly_loose() {
        let ring = WeldPass {
            points_mm: (0..40)
                .map(|i| {
                    let a = i as f64 * std::f64::consts::TAU / 40.0;
                    Point3::new(30.0 * a.cos(), 30.0 * a.sin(), 2.5 + 0.1 * i as f64)
                })
                .collect(),
        };
        let up_and_back = WeldPass {
            points_mm: vec![
                Point3::new(0.0, 0.0, 2.5),
                Point3::new(6.0, 0.0, 2.5),
                Point3::new(6.0, 0.0, 5.0),
                Point3::new(0.0, 0.0, 5.0),
                Point3::new(0.0, 6.0, 5.0),
            ],
        };
        for (passes, step_deg) in [
            (vec![straight(50), straight(3)], 5.0),
            (vec![ring.clone(), up_and_back.clone()], 5.0),
            (vec![ring, up_and_back, straight(7)], 0.5),
        ] {
            let s = ProcessSettings {
                max_step_deg: step_deg,
                ..ProcessSettings::default()
            };
            let tp = build(&passes, &s, WeldTiming::PerPoint(1.0), "b").unwrap();
            let (bound, _) = pose_bound(&passes, &s);
            let n = tp.poses.len() as f64;
            assert!(bound >= n && bound < 60.0 * n, "{n} poses, bound {bound}");
            let tight = ProcessSettings {
                max_poses: tp.poses.len() - 1,
                ..s
            };
            let e = build(&passes, &tight, WeldTiming::PerPoint(1.0), "b").unwrap_err();
            assert!(matches!(e, ToolpathError::TooManyPoses { .. }), "{e}");
        }
        // Blocks of 1e308 mm: refused at once, naming the keys.
        let huge = WeldPass {
            points_mm: vec![
                Point3::new(0.5e308, 0.0, 0.0),
                Point3::new(1.5e308, 0.0, 0.0),
            ],
        };
        let e = build(
            &[huge],
            &ProcessSettings::default(),
            WeldTiming::PerPoint(1.0),
            "b",
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("max_poses = 2000000") && e.contains("max_step_mm"),
            "{e}"
        );
    }
}
