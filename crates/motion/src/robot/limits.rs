//! MoveIt-style `joint_limits.yaml`: velocity and acceleration limits that override or
//! add to the URDF's. Only the velocity and acceleration entries are used; position,
//! jerk and effort entries are accepted (a MoveIt file loads as it is) and ignored, as are
//! MoveIt's `default_*_scaling_factor`s (the process settings' `joint_speed_scale` scales
//! speeds here).

use std::collections::BTreeMap;

use serde::Deserialize;
use thiserror::Error;

use super::Robot;

/// A joint limits file that cannot be used, naming the joint and key.
#[derive(Debug, Error, PartialEq)]
pub enum LimitsError {
    #[error("not a valid joint limits file: {0}")]
    Yaml(String),
    #[error("joint_limits.{0}: not a joint of the robot (its joints: {1})")]
    UnknownJoint(String, String),
    #[error("joint_limits.{joint}.{key}: must be a number > 0, got {value}")]
    Value {
        joint: String,
        key: &'static str,
        value: f64,
    },
    #[error("joint_limits.{joint}: has_{key}_limits is true but max_{key} is missing")]
    Missing { joint: String, key: &'static str },
}

/// The file: `joint_limits: {JOINT: {has_velocity_limits, max_velocity, ...}}`.
#[derive(Debug, Clone, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct JointLimitsFile {
    #[serde(default)]
    pub default_velocity_scaling_factor: Option<f64>,
    #[serde(default)]
    pub default_acceleration_scaling_factor: Option<f64>,
    #[serde(default)]
    pub joint_limits: BTreeMap<String, JointLimit>,
}

/// One joint's entry (MoveIt's keys; ros2_control's deceleration keys too).
#[derive(Debug, Clone, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct JointLimit {
    #[serde(default)]
    pub has_velocity_limits: bool,
    pub max_velocity: Option<f64>,
    #[serde(default)]
    pub has_acceleration_limits: bool,
    pub max_acceleration: Option<f64>,
    // Accepted and not used.
    pub has_position_limits: Option<bool>,
    pub min_position: Option<f64>,
    pub max_position: Option<f64>,
    pub has_deceleration_limits: Option<bool>,
    pub max_deceleration: Option<f64>,
    pub has_jerk_limits: Option<bool>,
    pub max_jerk: Option<f64>,
    pub has_effort_limits: Option<bool>,
    pub max_effort: Option<f64>,
    pub angle_wraps: Option<bool>,
}

impl JointLimitsFile {
    pub fn from_yaml(text: &str) -> Result<JointLimitsFile, LimitsError> {
        serde_yaml::from_str(text).map_err(|e| LimitsError::Yaml(e.to_string()))
    }
}

impl Robot {
    /// The robot with a joint limits file applied: a joint's `max_velocity` replaces the
    /// URDF's velocity limit, its `max_acceleration` becomes its acceleration limit.
    pub fn with_limits(mut self, file: &JointLimitsFile) -> Result<Robot, LimitsError> {
        for (name, limit) in &file.joint_limits {
            let Some(joint) = self.joints.iter_mut().find(|j| &j.name == name) else {
                let names: Vec<&str> = self.joints.iter().map(|j| j.name.as_str()).collect();
                return Err(LimitsError::UnknownJoint(name.clone(), names.join(", ")));
            };
            let value = |has: bool, v: Option<f64>, key: &'static str| match (has, v) {
                (false, _) => Ok(None),
                (true, None) => Err(LimitsError::Missing {
                    joint: name.clone(),
                    key,
                }),
                (true, Some(v)) if v.is_finite() && v > 0.0 => Ok(Some(v)),
                (true, Some(v)) => Err(LimitsError::Value {
                    joint: name.clone(),
                    key: if key == "velocity" {
                        "max_velocity"
                    } else {
                        "max_acceleration"
                    },
                    value: v,
                }),
            };
            if let Some(v) = value(limit.has_velocity_limits, limit.max_velocity, "velocity")? {
                joint.velocity = v;
            }
            if let Some(a) = value(
                limit.has_acceleration_limits,
                limit.max_acceleration,
                "acceleration",
            )? {
                joint.acceleration = Some(a);
            }
        }
        Ok(self)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn robot() -> Robot {
        crate::robot::bundled_for_tests()
    }

    #[test]
    fn a_moveit_file_sets_velocity_and_acceleration_limits() {
        let r = robot();
        let name = r.joints[0].name.clone();
        let urdf_v1 = r.joints[1].velocity;
        let text = format!(
            "default_velocity_scaling_factor: 0.1\njoint_limits:\n  {name}:\n    has_position_limits: false\n    has_velocity_limits: true\n    max_velocity: 0.5\n    has_acceleration_limits: true\n    max_acceleration: 2.0\n    has_jerk_limits: false\n"
        );
        let r = r
            .with_limits(&JointLimitsFile::from_yaml(&text).unwrap())
            .unwrap();
        assert_eq!(r.joints[0].velocity, 0.5);
        assert_eq!(r.joints[0].acceleration, Some(2.0));
        assert_eq!(r.joints[1].velocity, urdf_v1);
        assert_eq!(r.joints[1].acceleration, None);
    }

    #[test]
    fn bad_entries_name_the_joint_and_key() {
        let e = robot()
            .with_limits(&JointLimitsFile::from_yaml("joint_limits: {nope: {}}").unwrap())
            .unwrap_err();
        assert!(
            e.to_string().starts_with("joint_limits.nope: not a joint"),
            "{e}"
        );
        let name = robot().joints[2].name.clone();
        let text = format!(
            "joint_limits: {{{name}: {{has_acceleration_limits: true, max_acceleration: -1}}}}"
        );
        let e = robot()
            .with_limits(&JointLimitsFile::from_yaml(&text).unwrap())
            .unwrap_err();
        assert_eq!(
            e.to_string(),
            format!("joint_limits.{name}.max_acceleration: must be a number > 0, got -1")
        );
        let text = format!("joint_limits: {{{name}: {{has_acceleration_limits: true}}}}");
        assert!(robot()
            .with_limits(&JointLimitsFile::from_yaml(&text).unwrap())
            .is_err());
        assert!(JointLimitsFile::from_yaml("joint_limits: {a: {max_velocty: 1}}").is_err());
    }
}
