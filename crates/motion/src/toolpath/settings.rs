//! Process settings: where the part sits, how the torch is held and how fast it moves.
//! The documented file is `config/process.yaml`; every key is optional (defaults below).

use nalgebra::Isometry3;
use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::robot::{xyz_rpy, Solver, MAX_OFFSET_M};
use waam_access::{Torch, TorchSetup};

/// Longest approach, clearance (mm): 10 m is beyond any cell; near f64's range the
/// toolpath would need more poses than memory holds.
pub const MAX_TRAVEL_MM: f64 = 10_000.0;
/// Finest toolpath resolution (mm, degrees) and path tolerance (mm, degrees).
pub const MIN_STEP: f64 = 0.01;
pub const MIN_TOLERANCE: f64 = 0.001;
/// Default of `max_poses`: about 250 MB of toolpath and trajectory.
pub const DEFAULT_MAX_POSES: usize = 2_000_000;

/// A process-settings file that cannot be used, naming the key.
#[derive(Debug, Error)]
pub enum SettingsError {
    #[error("not valid process settings: {0}")]
    Yaml(String),
    #[error("{key}: {reason}")]
    Value { key: &'static str, reason: String },
}

/// A pose given as a position (m) and roll-pitch-yaw angles (degrees, URDF convention:
/// roll about x, then pitch about y, then yaw about z, all in the fixed frame).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PoseSetting {
    pub position_m: [f64; 3],
    #[serde(default)]
    pub rpy_deg: [f64; 3],
}

impl PoseSetting {
    pub fn isometry(&self) -> Isometry3<f64> {
        xyz_rpy(&self.position_m, &self.rpy_deg.map(f64::to_radians))
    }
}

/// The process settings (see `config/process.yaml` for the meaning of each key).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ProcessSettings {
    /// The part frame (z = 0 on the plate's top surface) in the robot's base link.
    pub plate: PoseSetting,
    /// The TCP in the tip link, for a URDF without a `tcp` link and no `--tcp`.
    pub tcp: PoseSetting,
    /// Torch tilt along the travel direction, degrees: + push (wire leads), - drag.
    pub travel_angle_deg: f64,
    /// Torch tilt across the travel direction, degrees: + leans the wire to the left.
    pub work_angle_deg: f64,
    /// Weld speed, mm/s; `null`: one block per the part's `block_time_s`.
    pub weld_speed_mm_s: Option<f64>,
    /// TCP speed on transit, approach and retract moves, mm/s (joint limits may slow it).
    pub transit_speed_mm_s: f64,
    /// Transit height above the tallest block welded so far, mm.
    pub clearance_mm: f64,
    /// Approach and retract distance along the torch axis, mm.
    pub approach_mm: f64,
    /// Dwell at the first block after arc-on, s.
    pub arc_on_dwell_s: f64,
    /// Dwell at the last block before arc-off (crater fill), s.
    pub arc_off_dwell_s: f64,
    /// Longest straight step between toolpath poses, mm.
    pub max_step_mm: f64,
    /// Largest torch rotation between toolpath poses, degrees.
    pub max_step_deg: f64,
    /// Fraction of each URDF joint velocity limit the trajectory may use, (0, 1].
    pub joint_speed_scale: f64,
    /// How far the TCP may stray from the straight line between two poses while the
    /// joints move linearly, mm; longer steps are split.
    pub path_tolerance_mm: f64,
    /// The same for the torch's orientation, degrees.
    pub path_tolerance_deg: f64,
    /// Inverse kinematics: `auto` (analytic OPW where the arm fits, else numeric) or
    /// `numeric` (damped least squares only).
    pub ik_solver: Solver,
    /// The torch whose access the planner checks at every deposit (`null`: none).
    pub torch: Option<Torch>,
    /// The most toolpath poses built; a toolpath estimated to need more is refused
    /// before it is built (memory), naming the move and the keys.
    pub max_poses: usize,
}

impl Default for ProcessSettings {
    fn default() -> Self {
        ProcessSettings {
            plate: PoseSetting {
                position_m: [0.80, -0.05, 0.35],
                rpy_deg: [0.0, 0.0, 0.0],
            },
            tcp: PoseSetting {
                position_m: [0.0, 0.0, 0.35],
                rpy_deg: [0.0, 0.0, 0.0],
            },
            travel_angle_deg: 10.0,
            work_angle_deg: 0.0,
            weld_speed_mm_s: None,
            transit_speed_mm_s: 100.0,
            clearance_mm: 20.0,
            approach_mm: 15.0,
            arc_on_dwell_s: 0.3,
            arc_off_dwell_s: 0.5,
            max_step_mm: 5.0,
            max_step_deg: 5.0,
            joint_speed_scale: 1.0,
            path_tolerance_mm: 0.2,
            path_tolerance_deg: 0.5,
            ik_solver: Solver::Auto,
            torch: Some(Torch::default()),
            max_poses: DEFAULT_MAX_POSES,
        }
    }
}

impl ProcessSettings {
    /// The torch held at the settings' travel and work angles, if there is a torch.
    pub fn torch_setup(&self) -> Option<TorchSetup> {
        self.torch
            .map(|t| TorchSetup::new(t, self.travel_angle_deg, self.work_angle_deg))
    }

    /// How far above the tallest block welded so far the TCP moves on a transit, mm:
    /// `clearance_mm`, plus however far the torch (turned into any heading) reaches below
    /// the TCP, so that the whole torch, not only the TCP, keeps `clearance_mm`; plus the
    /// margin the move check keeps around the torch ([`crate::clearance::SAMPLE_MM`]).
    pub fn transit_height_mm(&self) -> f64 {
        match self.torch_setup() {
            Some(t) => self.clearance_mm + (-t.lowest_mm()).max(0.0) + crate::clearance::SAMPLE_MM,
            None => self.clearance_mm,
        }
    }

    /// Reads a settings file's text; missing keys take their defaults.
    pub fn from_yaml(text: &str) -> Result<ProcessSettings, SettingsError> {
        let s: ProcessSettings = if text.trim().is_empty() {
            ProcessSettings::default()
        } else {
            waam_part::yaml::check(text).map_err(|e| SettingsError::Yaml(e.to_string()))?;
            serde_yaml::from_str(text).map_err(|e| SettingsError::Yaml(e.to_string()))?
        };
        s.validate()?;
        Ok(s)
    }

    /// Checks every value's range.
    pub fn validate(&self) -> Result<(), SettingsError> {
        let bad = |key: &'static str, reason: &str| SettingsError::Value {
            key,
            reason: reason.to_string(),
        };
        let finite = |v: &[f64]| v.iter().all(|x| x.is_finite());
        if !finite(&self.plate.position_m) || !finite(&self.plate.rpy_deg) {
            return Err(bad("plate", "every value must be a finite number"));
        }
        if !finite(&self.tcp.position_m) || !finite(&self.tcp.rpy_deg) {
            return Err(bad("tcp", "every value must be a finite number"));
        }
        for (key, pose) in [("plate", &self.plate), ("tcp", &self.tcp)] {
            if pose.position_m.iter().any(|v| v.abs() > MAX_OFFSET_M)
                || pose.rpy_deg.iter().any(|v| v.abs() > 3600.0)
            {
                return Err(bad(
                    key,
                    &format!("position_m within ±{MAX_OFFSET_M} m and rpy_deg within ±3600"),
                ));
            }
        }
        let angle = |key, v: f64| {
            if v.is_finite() && v.abs() < 60.0 {
                Ok(())
            } else {
                Err(bad(
                    key,
                    &format!("must be within -60..60 degrees, got {v}"),
                ))
            }
        };
        angle("travel_angle_deg", self.travel_angle_deg)?;
        angle("work_angle_deg", self.work_angle_deg)?;
        let positive = |key, v: f64| {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(bad(key, &format!("must be a number > 0, got {v}")))
            }
        };
        if let Some(v) = self.weld_speed_mm_s {
            positive("weld_speed_mm_s", v)?;
        }
        positive("transit_speed_mm_s", self.transit_speed_mm_s)?;
        positive("approach_mm", self.approach_mm)?;
        positive("arc_on_dwell_s", self.arc_on_dwell_s)?;
        positive("arc_off_dwell_s", self.arc_off_dwell_s)?;
        positive("max_step_mm", self.max_step_mm)?;
        positive("max_step_deg", self.max_step_deg)?;
        positive("path_tolerance_mm", self.path_tolerance_mm)?;
        positive("path_tolerance_deg", self.path_tolerance_deg)?;
        if !(self.clearance_mm.is_finite() && self.clearance_mm >= 0.0) {
            return Err(bad(
                "clearance_mm",
                &format!("must be a number >= 0, got {}", self.clearance_mm),
            ));
        }
        if let Some(t) = &self.torch {
            t.validate()
                .map_err(|e| SettingsError::Yaml(e.to_string()))?;
        }
        for (key, v, lo, hi) in [
            ("approach_mm", self.approach_mm, 0.0, MAX_TRAVEL_MM),
            ("clearance_mm", self.clearance_mm, 0.0, MAX_TRAVEL_MM),
            ("max_step_mm", self.max_step_mm, MIN_STEP, f64::MAX),
            ("max_step_deg", self.max_step_deg, MIN_STEP, f64::MAX),
            (
                "path_tolerance_mm",
                self.path_tolerance_mm,
                MIN_TOLERANCE,
                f64::MAX,
            ),
            (
                "path_tolerance_deg",
                self.path_tolerance_deg,
                MIN_TOLERANCE,
                f64::MAX,
            ),
        ] {
            if v < lo || v > hi {
                return Err(bad(
                    key,
                    &format!(
                        "{v:e} is outside {lo}..={hi:e} (the toolpath would not fit in memory)"
                    ),
                ));
            }
        }
        if self.max_poses == 0 {
            return Err(bad("max_poses", "must be at least 1"));
        }
        let s = self.joint_speed_scale;
        if !(s.is_finite() && s > 0.0 && s <= 1.0) {
            return Err(bad(
                "joint_speed_scale",
                &format!("must be in (0, 1], got {s}"),
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_bundled_file_holds_the_defaults() {
        let text = include_str!("../../../../config/process.yaml");
        assert_eq!(
            ProcessSettings::from_yaml(text).unwrap(),
            ProcessSettings::default()
        );
    }

    #[test]
    fn bad_values_name_their_key() {
        let e = ProcessSettings::from_yaml("clearence_mm: 3\n").unwrap_err();
        assert!(
            e.to_string().contains("unknown field `clearence_mm`"),
            "{e}"
        );
        let e = ProcessSettings::from_yaml("approach_mm: 0\n").unwrap_err();
        assert_eq!(e.to_string(), "approach_mm: must be a number > 0, got 0");
        let e = ProcessSettings::from_yaml("travel_angle_deg: 75\n").unwrap_err();
        assert!(e.to_string().starts_with("travel_angle_deg:"), "{e}");
        let e = ProcessSettings::from_yaml("joint_speed_scale: 1.5\n").unwrap_err();
        assert!(e.to_string().starts_with("joint_speed_scale:"), "{e}");
        let e = ProcessSettings::from_yaml("ik_solver: magic\n").unwrap_err();
        assert!(e.to_string().contains("magic"), "{e}");
        let s = ProcessSettings::from_yaml("weld_speed_mm_s: 8\n").unwrap();
        assert_eq!(s.weld_speed_mm_s, Some(8.0));
        let e = ProcessSettings::from_yaml("torch:\n  nozzle_diameter_mm: -1\n").unwrap_err();
        assert!(e.to_string().contains("torch.nozzle_diameter_mm"), "{e}");
        let e = ProcessSettings::from_yaml("torch:\n  nozle_diameter_mm: 9\n").unwrap_err();
        assert!(e.to_string().contains("nozle_diameter_mm"), "{e}");
    }

    #[test]
    fn the_torch_defaults_to_a_typical_gmaw_torch_and_null_turns_it_off() {
        let s = ProcessSettings::default();
        let setup = s.torch_setup().unwrap();
        assert_eq!(setup.torch.nozzle_diameter_mm, 18.0);
        assert_eq!(setup.torch.nozzle_standoff_mm, 12.0);
        assert!((setup.tilt_deg - s.travel_angle_deg).abs() < 1e-9);
        let s = ProcessSettings::from_yaml("torch: null\n").unwrap();
        assert_eq!(s.torch_setup(), None);
        let s = ProcessSettings::from_yaml("torch:\n  nozzle_diameter_mm: 16\n").unwrap();
        assert_eq!(s.torch.unwrap().nozzle_diameter_mm, 16.0);
        assert_eq!(s.torch.unwrap().nozzle_standoff_mm, 12.0);
    }
}
