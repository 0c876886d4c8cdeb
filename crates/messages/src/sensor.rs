//! A sensor message checked before the closed loop may use it: its stamp's age, a
//! pyrometer's reading, a scan's or a thermal image's frame and whether it lies on the part. What fails is a
//! [`BadReading`] that names the reason; the node reports it on `/diagnostics` and drops the
//! message.

use nalgebra::Isometry3;
use thiserror::Error;
use waam_cell::Measured;
use waam_part::Part;
use waam_rosmsg::builtin_interfaces::Time;
use waam_rosmsg::sensor_msgs::{PointCloud2, Temperature};
use waam_rosmsg::std_msgs::Header;

use crate::planning::PART_FRAME;
use crate::scan::{scan_points, thermal_points, ScanError};
use crate::tf_buffer::{TfBuffer, TfError};

/// The temperatures a pyrometer on a WAAM cell can read, °C: from a cold cell to above the
/// boiling point of iron (2862 °C). Anything outside is a broken sensor or wrong units.
pub const PLAUSIBLE_C: [f64; 2] = [-50.0, 3000.0];

/// Why a sensor message is not used.
#[derive(Debug, Error, PartialEq)]
pub enum BadReading {
    #[error("no stamp (header.stamp is 0)")]
    NoStamp,
    #[error("late: stamped {age_s:.1} s ago, more than closed_loop.max_age_s = {max_age_s} s")]
    Late { age_s: f64, max_age_s: f64 },
    #[error("stamped {ahead_s:.1} s in the future (is the sensor's clock synchronised?)")]
    Future { ahead_s: f64 },
    #[error("temperature {0} °C is not a number")]
    NotFinite(f64),
    #[error(
        "temperature {0} °C is outside the plausible {lo}..{hi} °C",
        lo = PLAUSIBLE_C[0],
        hi = PLAUSIBLE_C[1]
    )]
    Implausible(f64),
    #[error(
        "image point {index}: temperature {celsius} °C is outside the plausible {lo}..{hi} °C \
         (the field must be in °C)",
        lo = PLAUSIBLE_C[0],
        hi = PLAUSIBLE_C[1]
    )]
    ImplausiblePoint { index: usize, celsius: f64 },
    #[error("the camera read no temperature on the part (all {points} points on it are NaN)")]
    NothingRead { points: usize },
    #[error("variance {0} is negative or not a number (0 = unknown)")]
    Variance(f64),
    #[error(transparent)]
    Scan(#[from] ScanError),
    #[error(
        "cloud in frame '{got}': neither '{PART_FRAME}' nor the robot's base link '{base}', and \
         /tf and /tf_static do not connect it to the base link: {why}"
    )]
    NoTransform {
        got: String,
        base: String,
        why: Box<TfError>,
    },
    #[error("no part planned yet: the cloud cannot be placed on it")]
    NoPart,
    #[error(
        "off the part: no point of the cloud ({points} in all) lies within {margin_mm} mm of \
         the part's box ({lo:?}..{hi:?} mm in '{PART_FRAME}'); the first is at {first:?} mm"
    )]
    OffPart {
        points: usize,
        margin_mm: f64,
        lo: [f64; 3],
        hi: [f64; 3],
        first: [f64; 3],
    },
}

/// What a scan is checked against: the part being built and where it sits in the cell.
#[derive(Debug, Clone, PartialEq)]
pub struct ScanTarget {
    /// The part's box in the part frame, mm: its lowest and highest corners.
    pub lo_mm: [f64; 3],
    pub hi_mm: [f64; 3],
    /// The robot's base link, the other frame a scan may be in.
    pub base_link: String,
    /// The part frame in the base link (m): the plan's plate.
    pub plate: Isometry3<f64>,
}

impl ScanTarget {
    /// The box around every block (bead node) of `part`, placed on `plate` in `base_link`.
    pub fn of_part(part: &Part, base_link: &str, plate: Isometry3<f64>) -> ScanTarget {
        let half = part.block_mm.map(|v| v / 2.0);
        let (mut lo_mm, mut hi_mm) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        for &b in part.blocks() {
            let c = part.centre_mm(b);
            for d in 0..3 {
                lo_mm[d] = lo_mm[d].min(c[d] - half[d]);
                hi_mm[d] = hi_mm[d].max(c[d] + half[d]);
            }
        }
        ScanTarget {
            lo_mm,
            hi_mm,
            base_link: base_link.to_string(),
            plate,
        }
    }

    fn holds(&self, p: &[f64; 3], margin_mm: f64) -> bool {
        (0..3).all(|d| self.lo_mm[d] - margin_mm <= p[d] && p[d] <= self.hi_mm[d] + margin_mm)
    }
}

/// The stamp in seconds, unless it is unset, older than `max_age_s` or as far in the future.
pub fn check_stamp(stamp: Time, now: Time, max_age_s: f64) -> Result<f64, BadReading> {
    if stamp == Time::default() {
        return Err(BadReading::NoStamp);
    }
    let secs = |t: Time| t.to_nanos() as f64 * 1e-9;
    let age_s = secs(now) - secs(stamp);
    if age_s > max_age_s {
        return Err(BadReading::Late { age_s, max_age_s });
    }
    if -age_s > max_age_s {
        return Err(BadReading::Future { ahead_s: -age_s });
    }
    Ok(secs(stamp))
}

/// An arc fault from the welding power source (`std_msgs/Header`, stamped when the arc went
/// out), checked: stamped within `max_age_s` of `now` — a late fault cannot say which
/// deposits were welded. Returns its stamp, s.
pub fn arc_fault(msg: &Header, now: Time, max_age_s: f64) -> Result<f64, BadReading> {
    check_stamp(msg.stamp, now, max_age_s)
}

/// A pyrometer's reading, checked: stamped within `max_age_s` of `now`, a plausible
/// temperature, a sane variance. Its frame is not checked: the reading has no position (the
/// deposit under the torch).
pub fn temperature(msg: &Temperature, now: Time, max_age_s: f64) -> Result<Measured, BadReading> {
    let stamp_s = check_stamp(msg.header.stamp, now, max_age_s)?;
    let celsius = msg.temperature;
    if !celsius.is_finite() {
        return Err(BadReading::NotFinite(celsius));
    }
    if !(PLAUSIBLE_C[0]..=PLAUSIBLE_C[1]).contains(&celsius) {
        return Err(BadReading::Implausible(celsius));
    }
    if !(msg.variance.is_finite() && msg.variance >= 0.0) {
        return Err(BadReading::Variance(msg.variance));
    }
    Ok(Measured::Temperature { stamp_s, celsius })
}

/// A scan that can be used: its points on the part (part frame, mm), and how many of the
/// cloud's points were dropped as off the part (a line scanner sees the plate beside it).
#[derive(Debug, Clone, PartialEq)]
pub struct GoodScan {
    pub stamp_s: f64,
    pub points: Vec<[f64; 3]>,
    pub dropped: usize,
}

impl GoodScan {
    /// The scan as the closed loop takes it.
    pub fn measured(self) -> Measured {
        Measured::Scan {
            stamp_s: self.stamp_s,
            points: self.points,
        }
    }
}

/// A layer height scan, checked: stamped within `max_age_s` of `now`, readable, in the part
/// frame (metres, as REP 103 has it), the robot's base link or a frame `frames` connects to
/// the base link at the scan's stamp, with at least one point within `margin_mm` of the
/// part's box. The points off it are dropped.
pub fn scan(
    cloud: &PointCloud2,
    target: Option<&ScanTarget>,
    frames: &TfBuffer,
    margin_mm: f64,
    now: Time,
    max_age_s: f64,
) -> Result<GoodScan, BadReading> {
    let stamp_s = check_stamp(cloud.header.stamp, now, max_age_s)?;
    let points = scan_points(cloud)?;
    let (in_part, on_part) = place(cloud, points.iter(), target, frames, margin_mm)?;
    Ok(GoodScan {
        stamp_s,
        dropped: in_part.len() - on_part.len(),
        points: on_part.into_iter().map(|i| in_part[i]).collect(),
    })
}

/// A thermal image that can be used: its points on the part (part frame, mm) with their
/// temperatures (°C), how many were dropped as off the part, and how many on it the camera
/// read no temperature for (NaN).
#[derive(Debug, Clone, PartialEq)]
pub struct GoodImage {
    pub stamp_s: f64,
    pub points: Vec<([f64; 3], f64)>,
    pub dropped: usize,
    pub unread: usize,
}

impl GoodImage {
    /// The image as the closed loop takes it.
    pub fn measured(self) -> Measured {
        Measured::ThermalImage {
            stamp_s: self.stamp_s,
            points: self.points,
        }
    }
}

/// A thermal camera's image mapped onto the part (a `PointCloud2` with a `temperature`
/// field, °C), checked like a [`scan`]: stamp, frame, points within `margin_mm` of the
/// part's box (the others dropped); every temperature on the part is plausible or NaN (not
/// read: dropped), and at least one is read.
pub fn thermal_image(
    cloud: &PointCloud2,
    target: Option<&ScanTarget>,
    frames: &TfBuffer,
    margin_mm: f64,
    now: Time,
    max_age_s: f64,
) -> Result<GoodImage, BadReading> {
    let stamp_s = check_stamp(cloud.header.stamp, now, max_age_s)?;
    let points = thermal_points(cloud)?;
    let xyz = points.iter().map(|(p, _)| p);
    let (in_part, on_part) = place(cloud, xyz, target, frames, margin_mm)?;
    let mut good = Vec::with_capacity(on_part.len());
    for &index in &on_part {
        let celsius = points[index].1;
        if celsius.is_nan() {
            continue;
        }
        if !(PLAUSIBLE_C[0]..=PLAUSIBLE_C[1]).contains(&celsius) {
            return Err(BadReading::ImplausiblePoint { index, celsius });
        }
        good.push((in_part[index], celsius));
    }
    if good.is_empty() {
        return Err(BadReading::NothingRead {
            points: on_part.len(),
        });
    }
    Ok(GoodImage {
        stamp_s,
        dropped: in_part.len() - on_part.len(),
        unread: on_part.len() - good.len(),
        points: good,
    })
}

/// How a cloud's points go into the part frame: it is in the part frame (metres, as REP 103
/// has it), the robot's base link, or a frame `frames` connects to either at its stamp.
fn to_part_frame(
    cloud: &PointCloud2,
    target: &ScanTarget,
    frames: &TfBuffer,
) -> Result<Isometry3<f64>, BadReading> {
    let frame = cloud.header.frame_id.trim_start_matches('/');
    if frame == PART_FRAME {
        return Ok(Isometry3::identity());
    }
    if frame == target.base_link {
        return Ok(target.plate.inverse());
    }
    // Through the base link (a sensor on the robot or in the cell), or straight to the part
    // frame (one mounted on the fixture).
    let stamp = cloud.header.stamp;
    match frames.lookup(&target.base_link, frame, stamp) {
        Ok(in_base) => Ok(target.plate.inverse() * in_base),
        Err(why) => frames
            .lookup(PART_FRAME, frame, stamp)
            .map_err(|_| BadReading::NoTransform {
                got: frame.to_string(),
                base: target.base_link.clone(),
                why: Box::new(why),
            }),
    }
}

/// A cloud's `points` (its frame, metres) in the part frame in mm, and the indices of those
/// within `margin_mm` of the part's box (at least one).
fn place<'a>(
    cloud: &PointCloud2,
    points: impl Iterator<Item = &'a nalgebra::Point3<f64>>,
    target: Option<&ScanTarget>,
    frames: &TfBuffer,
    margin_mm: f64,
) -> Result<(Vec<[f64; 3]>, Vec<usize>), BadReading> {
    let target = target.ok_or(BadReading::NoPart)?;
    let to_part = to_part_frame(cloud, target, frames)?;
    let in_part: Vec<[f64; 3]> = points
        .map(|p| (to_part * p).coords.map(|v| v * 1000.0).into())
        .collect();
    let on: Vec<usize> = (0..in_part.len())
        .filter(|&i| target.holds(&in_part[i], margin_mm))
        .collect();
    if on.is_empty() {
        return Err(BadReading::OffPart {
            points: in_part.len(),
            margin_mm,
            lo: target.lo_mm,
            hi: target.hi_mm,
            first: in_part[0],
        });
    }
    Ok((in_part, on))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scan::cloud;
    use nalgebra::{Translation3, UnitQuaternion};

    const NOW: i64 = 1_800_000_000_000_000_000;

    fn at(offset_s: f64) -> Time {
        Time::from_nanos(NOW + (offset_s * 1e9) as i64)
    }

    fn reading(celsius: f64, offset_s: f64) -> Temperature {
        Temperature {
            header: Header::new(at(offset_s), "pyrometer"),
            temperature: celsius,
            variance: 0.0,
        }
    }

    /// A 3 x 1 x 2 wall of 6 x 6 x 2.5 mm blocks: 18 x 6 x 5 mm from the part origin, its
    /// plate 0.5 m in front of the robot and turned a quarter about z.
    fn wall() -> ScanTarget {
        let part = Part::parse(
            "name: w\nblock_mm: [6, 6, 2.5]\nmax_fragments: 1\nlayers:\n  - \"###\"\n  - \"###\"\n",
        )
        .unwrap();
        let plate = Isometry3::from_parts(
            Translation3::new(0.5, 0.0, 0.0),
            UnitQuaternion::from_euler_angles(0.0, 0.0, std::f64::consts::FRAC_PI_2),
        );
        ScanTarget::of_part(&part, "base_link", plate)
    }

    #[test]
    fn a_plausible_fresh_temperature_is_measured() {
        let m = temperature(&reading(612.5, -0.5), at(0.0), 2.0).unwrap();
        assert_eq!(
            m,
            Measured::Temperature {
                stamp_s: at(-0.5).to_nanos() as f64 * 1e-9,
                celsius: 612.5
            }
        );
    }

    #[test]
    fn bad_temperatures_say_why() {
        let now = at(0.0);
        let bad = |msg: Temperature| temperature(&msg, now, 2.0).unwrap_err();
        assert!(bad(reading(f64::NAN, 0.0))
            .to_string()
            .contains("not a number"));
        assert_eq!(bad(reading(5000.0, 0.0)), BadReading::Implausible(5000.0));
        assert_eq!(bad(reading(-273.0, 0.0)), BadReading::Implausible(-273.0));
        assert!(
            matches!(bad(reading(500.0, -3.0)), BadReading::Late { age_s, .. } if (age_s - 3.0).abs() < 1e-6)
        );
        assert!(matches!(
            bad(reading(500.0, 10.0)),
            BadReading::Future { .. }
        ));
        let mut unset = reading(500.0, 0.0);
        unset.header.stamp = Time::default();
        assert_eq!(bad(unset), BadReading::NoStamp);
        let mut variance = reading(500.0, 0.0);
        variance.variance = -1.0;
        assert_eq!(bad(variance), BadReading::Variance(-1.0));
        let late = bad(reading(500.0, -3.0)).to_string();
        assert!(late.contains("closed_loop.max_age_s = 2"), "{late}");
    }

    #[test]
    fn an_arc_fault_is_its_stamp_unless_late_or_unstamped() {
        let now = at(0.0);
        let fault = |offset_s: f64| arc_fault(&Header::new(at(offset_s), "welder"), now, 2.0);
        assert_eq!(fault(-0.25), Ok(at(-0.25).to_nanos() as f64 * 1e-9));
        assert!(matches!(fault(-3.0), Err(BadReading::Late { .. })));
        assert!(matches!(fault(5.0), Err(BadReading::Future { .. })));
        let unset = Header::new(Time::default(), "welder");
        assert_eq!(arc_fault(&unset, now, 2.0), Err(BadReading::NoStamp));
    }

    #[test]
    fn the_part_box_covers_every_block() {
        let t = wall();
        assert_eq!((t.lo_mm, t.hi_mm), ([0.0; 3], [18.0, 6.0, 5.0]));
    }

    #[test]
    fn a_scan_in_the_part_frame_is_kept_on_the_part_in_mm() {
        // Metres: two points on the top of the wall, one on the plate 0.1 m away.
        let mut c = cloud(
            &[
                [0.003, 0.003, 0.005],
                [0.015, 0.003, 0.0051],
                [0.1, 0.0, 0.0],
            ],
            "part",
        );
        c.header.stamp = at(-1.0);
        let good = scan(&c, Some(&wall()), &TfBuffer::default(), 5.0, at(0.0), 2.0).unwrap();
        assert_eq!(good.dropped, 1);
        assert_eq!(good.stamp_s, at(-1.0).to_nanos() as f64 * 1e-9);
        assert_eq!(good.points.len(), 2);
        for (p, want) in good.points.iter().zip([[3.0, 3.0, 5.0], [15.0, 3.0, 5.1]]) {
            assert!(
                (0..3).all(|d| (p[d] - want[d]).abs() < 1e-3),
                "{p:?} != {want:?}"
            );
        }
    }

    #[test]
    fn a_scan_in_the_base_link_is_moved_into_the_part_frame() {
        // Part point (3, 3, 5) mm is, in the base link, 0.5 m ahead, turned a quarter: x' = -y.
        let mut c = cloud(&[[0.497, 0.003, 0.005]], "base_link");
        c.header.stamp = at(0.0);
        let good = scan(&c, Some(&wall()), &TfBuffer::default(), 0.0, at(0.0), 2.0).unwrap();
        let want = [3.0, 3.0, 5.0];
        let p = good.points[0];
        assert!((0..3).all(|d| (p[d] - want[d]).abs() < 1e-3), "{p:?}");
        assert_eq!(
            good.clone().measured(),
            Measured::Scan {
                stamp_s: good.stamp_s,
                points: good.points
            }
        );
    }

    #[test]
    fn a_thermal_image_keeps_the_temperatures_read_on_the_part() {
        use crate::scan::thermal_cloud;
        let target = wall();
        let image = |points: &[[f32; 4]]| {
            let mut c = thermal_cloud(points, "part");
            c.header.stamp = at(0.0);
            thermal_image(&c, Some(&target), &TfBuffer::default(), 5.0, at(0.0), 2.0)
        };
        // On the wall (metres), a pixel the camera did not read, and the cell's far wall.
        let good = image(&[
            [0.003, 0.003, 0.005, 850.0],
            [0.009, 0.003, 0.005, f32::NAN],
            [2.0, 0.0, 0.0, 25.0],
        ])
        .unwrap();
        assert_eq!((good.dropped, good.unread, good.points.len()), (1, 1, 1));
        let (p, t) = good.points[0];
        assert!(
            (p[0] - 3.0).abs() < 1e-3 && (p[2] - 5.0).abs() < 1e-3,
            "{p:?}"
        );
        assert_eq!(t, 850.0);
        assert!(matches!(good.measured(), Measured::ThermalImage { .. }));
        // Kelvin, or a broken camera: named with the point.
        assert_eq!(
            image(&[[0.003, 0.003, 0.005, 850.0], [0.003, 0.003, 0.005, 5000.0]]),
            Err(BadReading::ImplausiblePoint {
                index: 1,
                celsius: 5000.0
            })
        );
        assert_eq!(
            image(&[[0.003, 0.003, 0.005, f32::NAN]]),
            Err(BadReading::NothingRead { points: 1 })
        );
        // A scan is not a thermal image.
        let mut scan = cloud(&[[0.003, 0.003, 0.005]], "part");
        scan.header.stamp = at(0.0);
        assert_eq!(
            thermal_image(
                &scan,
                Some(&target),
                &TfBuffer::default(),
                5.0,
                at(0.0),
                2.0
            ),
            Err(BadReading::Scan(ScanError::MissingField("temperature")))
        );
    }

    /// A frame tree of one static transform: `child` at `xyz` (m) in `parent`, not turned.
    fn mounted(parent: &str, child: &str, xyz: [f64; 3]) -> TfBuffer {
        use waam_rosmsg::geometry_msgs::{Transform, TransformStamped, Vector3};
        let mount = TransformStamped {
            header: waam_rosmsg::std_msgs::Header {
                stamp: Time::default(),
                frame_id: parent.into(),
            },
            child_frame_id: child.into(),
            transform: Transform {
                translation: Vector3 {
                    x: xyz[0],
                    y: xyz[1],
                    z: xyz[2],
                },
                ..Transform::default()
            },
        };
        let mut frames = TfBuffer::default();
        let transforms = vec![mount];
        let msg = waam_rosmsg::tf2_msgs::TFMessage { transforms };
        assert!(frames.add(&msg, true).is_empty());
        frames
    }

    #[test]
    fn a_scan_in_a_frame_tf_connects_is_moved_into_the_part_frame() {
        let on = |frames: &TfBuffer, point: [f32; 3], frame: &str| {
            let mut c = cloud(&[point], frame);
            c.header.stamp = at(0.0);
            scan(&c, Some(&wall()), frames, 0.0, at(0.0), 2.0)
                .unwrap()
                .points[0]
        };
        let near = |p: [f64; 3], want: [f64; 3]| {
            assert!(
                (0..3).all(|d| (p[d] - want[d]).abs() < 1e-3),
                "{p:?} != {want:?}"
            );
        };
        // A scanner fixed 0.4 m along the base link's x axis: the part point (3, 3, 5) mm
        // is (0.497, 0.003, 0.005) m in the base link, so (0.097, 0.003, 0.005) m in the
        // scanner's frame (named the ROS 1 way, with a leading '/').
        let cell = mounted("base_link", "scanner_link", [0.4, 0.0, 0.0]);
        near(
            on(&cell, [0.097, 0.003, 0.005], "/scanner_link"),
            [3.0, 3.0, 5.0],
        );
        // A scanner 0.1 m above the part frame's origin, tied to the part frame only.
        let fixture = mounted(PART_FRAME, "fixture_scanner", [0.0, 0.0, 0.1]);
        near(
            on(&fixture, [0.003, 0.003, -0.096], "fixture_scanner"),
            [3.0, 3.0, 4.0],
        );
    }

    #[test]
    fn bad_scans_say_why() {
        let target = wall();
        let no_tf = TfBuffer::default();
        let check = |c: &PointCloud2, t: Option<&ScanTarget>| scan(c, t, &no_tf, 5.0, at(0.0), 2.0);
        let mut c = cloud(&[[0.003, 0.003, 0.005]], "part");
        c.header.stamp = at(0.0);
        assert!(check(&c, Some(&target)).is_ok());
        assert_eq!(check(&c, None), Err(BadReading::NoPart));

        let mut camera = c.clone();
        camera.header.frame_id = "scanner_link".into();
        let e = check(&camera, Some(&target)).unwrap_err().to_string();
        assert!(
            e.contains("'scanner_link'") && e.contains("'base_link'"),
            "{e}"
        );

        // Millimetres sent as metres: 3 m away, off the part.
        let mut mm = cloud(&[[3.0, 3.0, 5.0]], "part");
        mm.header.stamp = at(0.0);
        let e = check(&mm, Some(&target)).unwrap_err();
        assert!(matches!(e, BadReading::OffPart { points: 1, .. }), "{e}");
        assert!(e.to_string().contains("[3000.0, 3000.0, 5000.0]"), "{e}");

        let mut nan = c.clone();
        nan.data[8..12].copy_from_slice(&f32::NAN.to_le_bytes());
        assert!(matches!(
            check(&nan, Some(&target)),
            Err(BadReading::Scan(ScanError::NotFinite { index: 0, .. }))
        ));

        let mut no_z = c.clone();
        no_z.fields[2].name = "intensity".into();
        let e = check(&no_z, Some(&target)).unwrap_err().to_string();
        assert!(e.contains("'z'"), "{e}");

        let mut late = c.clone();
        late.header.stamp = at(-5.0);
        assert!(matches!(
            check(&late, Some(&target)),
            Err(BadReading::Late { .. })
        ));
    }
}
