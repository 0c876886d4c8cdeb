//! A layer height scan (`sensor_msgs/PointCloud2` from a laser line scanner) read into
//! points, with an error naming what is wrong and where — the node reports it on
//! `/diagnostics` instead of using the data. Which frame the points are in, and whether they
//! lie on the part, is [`crate::sensor`]'s to check.

use nalgebra::Point3;
use thiserror::Error;
use waam_rosmsg::sensor_msgs::{PointCloud2, PointField};

/// Why a scan cannot be used.
#[derive(Debug, Error, PartialEq)]
pub enum ScanError {
    #[error("scan has no FLOAT32 or FLOAT64 field '{0}'")]
    MissingField(&'static str),
    #[error("scan is big-endian (only little-endian clouds are read)")]
    BigEndian,
    #[error("scan data holds {got} bytes, {need} needed for {points} points of {step} bytes")]
    Truncated {
        got: usize,
        need: usize,
        points: usize,
        step: u32,
    },
    #[error("scan field '{field}' at byte {offset} does not fit a point of {step} bytes")]
    FieldOutsidePoint {
        field: &'static str,
        offset: u32,
        step: u32,
    },
    #[error("scan point {index} is not finite ({value:?})")]
    NotFinite { index: usize, value: [f64; 3] },
    #[error("scan is empty")]
    Empty,
}

/// The points of `cloud` in its own frame, which must all have finite x, y, z.
pub fn scan_points(cloud: &PointCloud2) -> Result<Vec<Point3<f64>>, ScanError> {
    if cloud.is_bigendian {
        return Err(ScanError::BigEndian);
    }
    let axes = [axis(cloud, "x")?, axis(cloud, "y")?, axis(cloud, "z")?];
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
                Ok(Point3::from(value))
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
    let fields = ["x", "y", "z"]
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
        point_step: 12,
        row_step: 12 * points.len() as u32,
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
