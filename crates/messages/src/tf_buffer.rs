//! The cell's frames as `/tf` and `/tf_static` tell them, so that a scan may come in any
//! frame they connect to the robot's base link (a scanner on the flange, one fixed in the
//! cell), looked up at the scan's stamp as tf2 does: translations interpolated linearly,
//! rotations by slerp, static transforms valid at every time. The tree and its lookups are
//! the `transforms` crate's; here ROS messages go in and `nalgebra` isometries come out.

use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion};
use thiserror::Error;
use transforms::geometry::{Quaternion as TfQuaternion, Transform, Vector3};
use transforms::time::{Stamp, Timestamp};
use transforms::Registry;
use waam_rosmsg::builtin_interfaces::Time;
use waam_rosmsg::geometry_msgs::TransformStamped;
use waam_rosmsg::tf2_msgs::TFMessage;

/// How long dynamic transforms are kept: tf2's default cache.
pub const HISTORY_S: u64 = 10;

/// A transform that could not join the tree, or a lookup that failed.
#[derive(Debug, Error, PartialEq)]
pub enum TfError {
    #[error("transform '{parent}' -> '{child}': {why}")]
    Rejected {
        parent: String,
        child: String,
        why: String,
    },
    #[error("no transform from '{source_frame}' to '{target}' at the stamp {stamp_s:.3} s: {why}")]
    NoTransform {
        target: String,
        source_frame: String,
        stamp_s: f64,
        why: String,
    },
    #[error("cannot read a tf2_msgs/TFMessage: {0}")]
    Unreadable(String),
}

impl TfError {
    /// The frames the fault is about (parent or target first), to report it once per pair.
    pub fn frames(&self) -> (String, String) {
        match self {
            TfError::Rejected { parent, child, .. } => (parent.clone(), child.clone()),
            TfError::NoTransform {
                target,
                source_frame,
                ..
            } => (target.clone(), source_frame.clone()),
            TfError::Unreadable(_) => Default::default(),
        }
    }
}

/// The frame tree of `/tf` (dynamic, kept [`HISTORY_S`]) and `/tf_static`.
#[derive(Debug)]
pub struct TfBuffer {
    tree: Registry,
}

impl Default for TfBuffer {
    fn default() -> Self {
        TfBuffer {
            tree: Registry::with_max_age(std::time::Duration::from_secs(HISTORY_S)),
        }
    }
}

impl TfBuffer {
    /// Adds every transform of `msg` (from `/tf_static` when `fixed`); the ones that cannot
    /// join the tree (no unit rotation, a second parent, a cycle, no stamp on `/tf`) are
    /// returned, the others kept.
    pub fn add(&mut self, msg: &TFMessage, fixed: bool) -> Vec<TfError> {
        msg.transforms
            .iter()
            .filter_map(|t| self.add_one(t, fixed).err())
            .collect()
    }

    fn add_one(&mut self, t: &TransformStamped, fixed: bool) -> Result<(), TfError> {
        let (parent, child) = (frame(&t.header.frame_id), frame(&t.child_frame_id));
        let rejected = |why: String| TfError::Rejected {
            parent: parent.to_string(),
            child: child.to_string(),
            why,
        };
        let stamp = if fixed {
            Stamp::Static
        } else {
            Stamp::At(timestamp(t.header.stamp).ok_or_else(|| rejected("no stamp".into()))?)
        };
        let (v, q) = (t.transform.translation, t.transform.rotation);
        let transform = Transform::new(
            parent,
            child,
            Vector3::new(v.x, v.y, v.z),
            TfQuaternion {
                w: q.w,
                x: q.x,
                y: q.y,
                z: q.z,
            },
            stamp,
        )
        .map_err(|e| rejected(e.to_string()))?;
        self.tree
            .add_transform(transform)
            .map_err(|e| rejected(e.to_string()))
    }

    /// The pose of `source` in `target` at `stamp`: what maps a point given in `source`
    /// into `target` (tf2's `lookupTransform(target, source, stamp)`).
    pub fn lookup(
        &self,
        target: &str,
        source: &str,
        stamp: Time,
    ) -> Result<Isometry3<f64>, TfError> {
        let failed = |why: String| TfError::NoTransform {
            target: frame(target).to_string(),
            source_frame: frame(source).to_string(),
            stamp_s: stamp.to_nanos() as f64 * 1e-9,
            why,
        };
        let at = timestamp(stamp).ok_or_else(|| failed("no stamp".into()))?;
        let t = self
            .tree
            .get_transform(frame(target), frame(source), at)
            .map_err(|e| failed(e.to_string()))?;
        let (v, q) = (t.translation(), t.rotation());
        Ok(Isometry3::from_parts(
            Translation3::new(v.x, v.y, v.z),
            UnitQuaternion::from_quaternion(Quaternion::new(q.w, q.x, q.y, q.z)),
        ))
    }
}

/// A frame id as tf2 reads it: without a leading '/' (ROS 1 style names still come).
fn frame(id: &str) -> &str {
    id.strip_prefix('/').unwrap_or(id)
}

/// A ROS stamp on the buffer's clock; none for 0 or before 1970.
fn timestamp(t: Time) -> Option<Timestamp> {
    u64::try_from(t.to_nanos())
        .ok()
        .filter(|&n| n > 0)
        .map(Timestamp::from_nanos)
}

#[cfg(test)]
mod tests {
    use super::*;
    use waam_rosmsg::geometry_msgs::{self as geo};
    use waam_rosmsg::std_msgs::Header;

    fn tf(parent: &str, child: &str, at_s: f64, xyz: [f64; 3], wxyz: [f64; 4]) -> TransformStamped {
        TransformStamped {
            header: Header {
                stamp: Time::from_nanos((at_s * 1e9) as i64),
                frame_id: parent.into(),
            },
            child_frame_id: child.into(),
            transform: geo::Transform {
                translation: geo::Vector3 {
                    x: xyz[0],
                    y: xyz[1],
                    z: xyz[2],
                },
                rotation: geo::Quaternion {
                    w: wxyz[0],
                    x: wxyz[1],
                    y: wxyz[2],
                    z: wxyz[3],
                },
            },
        }
    }

    const NO_TURN: [f64; 4] = [1.0, 0.0, 0.0, 0.0];

    fn at(s: f64) -> Time {
        Time::from_nanos((s * 1e9) as i64)
    }

    #[test]
    fn a_chain_of_static_and_moving_frames_is_looked_up_at_the_stamp() {
        let mut buffer = TfBuffer::default();
        // The flange moves 0.1 m along x between t = 100 s and 101 s; the scanner sits
        // 0.05 m above the flange, turned a quarter about z.
        let s = std::f64::consts::FRAC_1_SQRT_2;
        let fixed = TFMessage {
            transforms: vec![tf(
                "flange",
                "scanner",
                0.0,
                [0.0, 0.0, 0.05],
                [s, 0.0, 0.0, s],
            )],
        };
        assert!(buffer.add(&fixed, true).is_empty());
        for (t, x) in [(100.0, 0.5), (101.0, 0.6)] {
            let moving = TFMessage {
                transforms: vec![tf("/base_link", "flange", t, [x, 0.0, 1.0], NO_TURN)],
            };
            assert!(buffer.add(&moving, false).is_empty());
        }
        let pose = buffer.lookup("base_link", "scanner", at(100.5)).unwrap();
        // The scanner's x axis is the base's y axis: (0.01, 0, 0) in the scanner is
        // (0.55, 0.01, 1.05) in the base link.
        let p = pose * nalgebra::Point3::new(0.01, 0.0, 0.0);
        let want = [0.55, 0.01, 1.05];
        assert!((0..3).all(|d| (p[d] - want[d]).abs() < 1e-9), "{p:?}");
        // After the newest sample: no extrapolation.
        let e = buffer
            .lookup("base_link", "scanner", at(102.0))
            .unwrap_err();
        assert!(matches!(e, TfError::NoTransform { .. }), "{e}");
        assert!(e.to_string().contains("'scanner' to 'base_link'"), "{e}");
    }

    #[test]
    fn bad_transforms_are_refused_and_named_and_the_rest_kept() {
        let mut buffer = TfBuffer::default();
        let msg = TFMessage {
            transforms: vec![
                tf("base_link", "a", 0.0, [1.0, 0.0, 0.0], NO_TURN),
                tf("base_link", "b", 0.0, [0.0; 3], [2.0, 0.0, 0.0, 0.0]),
                tf("a", "a", 0.0, [0.0; 3], NO_TURN),
                tf("base_link", "c", 0.0, [f64::NAN, 0.0, 0.0], NO_TURN),
            ],
        };
        let refused = buffer.add(&msg, true);
        assert_eq!(refused.len(), 3, "{refused:?}");
        assert!(
            refused[0].to_string().contains("'base_link' -> 'b'"),
            "{}",
            refused[0]
        );
        assert!(buffer.lookup("base_link", "a", at(5.0)).is_ok());
        assert!(buffer.lookup("base_link", "b", at(5.0)).is_err());
        // A dynamic transform needs a stamp; a lookup needs one too.
        let unstamped = TFMessage {
            transforms: vec![tf("base_link", "d", 0.0, [0.0; 3], NO_TURN)],
        };
        assert_eq!(buffer.add(&unstamped, false).len(), 1);
        assert!(buffer.lookup("base_link", "a", Time::default()).is_err());
    }
}
