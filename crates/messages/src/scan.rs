//! A layer height scan (`sensor_msgs/PointCloud2` from a laser line scanner), or a thermal
//! camera's image mapped onto the part (the same with a `temperature` field), read into
//! points, with an error naming what is wrong and where — the node reports it on
//! `/diagnostics` instead of using the data. Which frame the points are in, and whether they
//! lie on the part, is [`crate::sensor`]'s to check.

use nalgebra::Point3;
use thiserror::Error;
use waam_rosmsg::sensor_msgs::{PointCloud2, PointField};

/// Why a scan's or a thermal image's cloud cannot be read.
#[derive(Debug, Error, PartialEq)]
pub enum ScanError {
    #[error("cloud has no FLOAT32 or FLOAT64 field '{0}'")]
    MissingField(&'static str),
    #[error("cloud is big-endian (only little-endian clouds are read)")]
    BigEndian,
    #[error("cloud data holds {got} bytes, {need} needed for {points} points of {step} bytes")]
    Truncated {
        got: usize,
        need: usize,
        points: usize,
        step: u32,
    },
    #[error("cloud field '{field}' at byte {offset} does not fit a point of {step} bytes")]
    FieldOutsidePoint {
        field: &'static str,
        offset: u32,
        step: u32,
    },
    #[error("cloud point {index} is not finite ({value:?})")]
    NotFinite { index: usize, value: [f64; 3] },
    #[error("cloud is empty")]
    Empty,
}

/// The points of `cloud` in its own frame, which must all have finite x, y, z.
pub fn scan_points(cloud: &PointCloud2) -> Result<Vec<Point3<f64>>, ScanError> {
    Ok(points_with(cloud, None)?
        .into_iter()
        .map(|(p, _)| p)
        .collect())
}

/// The points of a thermal camera's cloud in its own frame, each with its `temperature`
/// field (°C, as `sensor_msgs/Temperature` has it; NaN where the camera read nothing).
/// x, y, z must all be finite.
pub fn thermal_points(cloud: &PointCloud2) -> Result<Vec<(Point3<f64>, f64)>, ScanError> {
    Ok(points_with(cloud, Some(TEMPERATURE))?
        .into_iter()
        .map(|(p, t)| (p, t.unwrap_or(f64::NAN)))
        .collect())
}

/// The field a thermal camera's cloud carries its temperatures in.
pub const TEMPERATURE: &str = "temperature";

/// A point and the value of one more field, when asked for.
type PointWith = (Point3<f64>, Option<f64>);

/// x, y, z of every point, and the value of field `extra` when asked for.
fn points_with(
    cloud: &PointCloud2,
    extra: Option<&'static str>,
) -> Result<Vec<PointWith>, ScanError> {
    if cloud.is_bigendian {
        return Err(ScanError::BigEndian);
    }
    let axes = [axis(cloud, "x")?, axis(cloud, "y")?, axis(cloud, "z")?];
    let extra = extra.map(|name| axis(cloud, name)).transpose()?;
    let points = cloud.width as usize * cloud.height as usize;
    if points == 0 {
        return Err(ScanError::Empty);
    }
    let step = cloud.point_step as usize;
    // Saturating: width x height x point_step of a hostile header exceeds any memory.
    let need = points.saturating_mul(step);
    if cloud.data.len() < need {
        return Err(ScanError::Truncated {
            got: cloud.data.len(),
            need,
            points,
            step: cloud.point_step,
        });
    }
    (0..points)
        .map(|index| {
            let bytes = &cloud.data[index * step..(index + 1) * step];
            let value = axes.map(|a| a.read(bytes));
            if value.iter().all(|v| v.is_finite()) {
                Ok((Point3::from(value), extra.map(|a| a.read(bytes))))
            } else {
                Err(ScanError::NotFinite { index, value })
            }
        })
        .collect()
}

/// Where one coordinate sits in a point and how wide it is.
#[derive(Clone, Copy)]
struct Axis {
    offset: usize,
    wide: bool,
}

impl Axis {
    fn read(self, point: &[u8]) -> f64 {
        let at = &point[self.offset..];
        if self.wide {
            f64::from_le_bytes(at[..8].try_into().expect("8 bytes checked"))
        } else {
            f32::from_le_bytes(at[..4].try_into().expect("4 bytes checked")) as f64
        }
    }
}

fn axis(cloud: &PointCloud2, name: &'static str) -> Result<Axis, ScanError> {
    let field = cloud
        .fields
        .iter()
        .find(|f| f.name == name && matches!(f.datatype, PointField::FLOAT32 | PointField::FLOAT64))
        .ok_or(ScanError::MissingField(name))?;
    let wide = field.datatype == PointField::FLOAT64;
    let size = if wide { 8 } else { 4 };
    if field.offset as usize + size > cloud.point_step as usize {
        return Err(ScanError::FieldOutsidePoint {
            field: name,
            offset: field.offset,
            step: cloud.point_step,
        });
    }
    Ok(Axis {
        offset: field.offset as usize,
        wide,
    })
}

/// A cloud of FLOAT32 x, y, z points (metres) in `frame`, as a laser line scanner's driver
/// sends them (the simulated cell's scanner, tests).
pub fn cloud(points: &[[f32; 3]], frame: &str) -> PointCloud2 {
    float_cloud(&["x", "y", "z"], points, frame)
}

/// A cloud of FLOAT32 x, y, z (metres) and temperature (°C) points in `frame`, as a thermal
/// camera mapped onto the part sends them (the simulated cell's camera, tests).
pub fn thermal_cloud(points: &[[f32; 4]], frame: &str) -> PointCloud2 {
    float_cloud(&["x", "y", "z", TEMPERATURE], points, frame)
}

/// A dense cloud of FLOAT32 fields `names`, one row per point.
fn float_cloud<const N: usize>(names: &[&str; N], points: &[[f32; N]], frame: &str) -> PointCloud2 {
    let step = 4 * N as u32;
    let fields = names
        .iter()
        .enumerate()
        .map(|(i, name)| PointField {
            name: name.to_string(),
            offset: 4 * i as u32,
            datatype: PointField::FLOAT32,
            count: 1,
        })
        .collect();
    let mut c = PointCloud2 {
        height: 1,
        width: points.len() as u32,
        fields,
        point_step: step,
        row_step: step * points.len() as u32,
        data: points
            .iter()
            .flatten()
            .flat_map(|v| v.to_le_bytes())
            .collect(),
        ..Default::default()
    };
    c.header.frame_id = frame.to_string();
    c
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_the_points_of_a_good_scan() {
        let c = cloud(&[[1.0, 2.0, 3.5], [-1.0, 0.0, 9.0]], "part");
        let p = scan_points(&c).unwrap();
        assert_eq!(
            p,
            vec![Point3::new(1.0, 2.0, 3.5), Point3::new(-1.0, 0.0, 9.0)]
        );
    }

    #[test]
    fn reads_a_thermal_cloud_and_names_a_missing_temperature() {
        let c = thermal_cloud(&[[1.0, 2.0, 3.0, 850.5], [0.0, 0.0, 0.0, f32::NAN]], "part");
        let p = thermal_points(&c).unwrap();
        assert_eq!(p[0], (Point3::new(1.0, 2.0, 3.0), 850.5));
        assert!(p[1].1.is_nan());
        // A scan is a thermal image without temperatures: not one.
        let scan = cloud(&[[1.0, 2.0, 3.0]], "part");
        assert_eq!(
            thermal_points(&scan),
            Err(ScanError::MissingField(TEMPERATURE))
        );
        // A scan reader ignores the temperatures.
        assert_eq!(scan_points(&c).unwrap()[0], Point3::new(1.0, 2.0, 3.0));
    }

    #[test]
    fn names_what_is_wrong() {
        let good = cloud(&[[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]], "part");
        let mut nan = good.clone();
        nan.data[12 + 8..12 + 12].copy_from_slice(&f32::NAN.to_le_bytes());
        assert!(matches!(
            scan_points(&nan),
            Err(ScanError::NotFinite { index: 1, .. })
        ));

        let mut no_z = good.clone();
        no_z.fields[2].name = "intensity".into();
        assert_eq!(scan_points(&no_z), Err(ScanError::MissingField("z")));

        let mut short = good.clone();
        short.data.truncate(20);
        assert!(matches!(
            scan_points(&short),
            Err(ScanError::Truncated { need: 24, .. })
        ));

        let mut outside = good.clone();
        outside.fields[2].offset = 10;
        assert!(matches!(
            scan_points(&outside),
            Err(ScanError::FieldOutsidePoint { .. })
        ));

        assert_eq!(scan_points(&cloud(&[], "part")), Err(ScanError::Empty));

        // A header claiming about 2^64 points of 12 bytes is refused, neither overflowing
        // nor read.
        let mut huge = good.clone();
        (huge.width, huge.height) = (u32::MAX, u32::MAX);
        assert!(matches!(
            scan_points(&huge),
            Err(ScanError::Truncated {
                need: usize::MAX,
                ..
            })
        ));
    }
}
