//! The one cell loader: process settings, URDF, TCP, joint limits and torch, as the CLI's
//! `--robot`/`--process` options, the first run and the node's parameters name them.
//!
//! The torch the planner checks and the robot's check of every candidate on its executed
//! time line ([`Cell::executed_check`]) follow from the loaded cell: [`crate::plan`] sets
//! them.

use std::path::PathBuf;

use nalgebra::Isometry3;
use thiserror::Error;

use waam_motion::robot::limits::{JointLimitsFile, LimitsError};
use waam_motion::robot::{Robot, RobotError, TcpChoice};
use waam_motion::toolpath::{ProcessSettings, SettingsError};

use crate::{Cell, BUNDLED_URDF};

/// Where a cell's parts come from. The default is the node's default cell: the bundled
/// robot and process settings, its torch on.
#[derive(Debug, Clone, Default)]
pub struct CellSource {
    /// Process settings (YAML, see config/process.yaml); `None`: the built-in defaults.
    pub process: Option<PathBuf>,
    /// The robot's URDF; `None`: the bundled robot ([`BUNDLED_URDF`]).
    pub urdf: Option<PathBuf>,
    /// The link the TCP is attached to; `None`: a link named `tcp`, else the end of the
    /// URDF's longest chain.
    pub tip: Option<String>,
    /// The TCP in the tip link; `None`: none when the tip link is named `tcp`, else the
    /// process settings' `tcp`.
    pub tcp: Option<Isometry3<f64>>,
    /// Joint limits (MoveIt-style joint_limits.yaml); `None`: the URDF's velocity limits.
    pub joint_limits: Option<PathBuf>,
    /// No torch: neither the planner's access check nor the torch along the moves, as if
    /// the process settings said `torch: null`.
    pub no_torch: bool,
}

/// Why a cell could not be loaded: which file, and the error of its reader (callers word
/// the file by their own names for it: a command-line option or a node parameter).
#[derive(Debug, Error)]
pub enum CellError {
    #[error("cannot read process settings {path}: {source}")]
    ReadProcess {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("process settings {path}: {source}")]
    Process {
        path: PathBuf,
        source: SettingsError,
    },
    #[error("bundled robot: {0}")]
    BundledRobot(RobotError),
    #[error("robot {path}: {source}")]
    Robot { path: PathBuf, source: RobotError },
    #[error("cannot read joint limits {path}: {source}")]
    ReadLimits {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("joint limits {path}: {source}")]
    Limits { path: PathBuf, source: LimitsError },
}

impl CellSource {
    /// Reads the process settings, then the robot with its TCP and joint limits.
    pub fn load(&self) -> Result<Cell, CellError> {
        let mut settings = match &self.process {
            Some(path) => {
                let text =
                    std::fs::read_to_string(path).map_err(|source| CellError::ReadProcess {
                        path: path.clone(),
                        source,
                    })?;
                ProcessSettings::from_yaml(&text).map_err(|source| CellError::Process {
                    path: path.clone(),
                    source,
                })?
            }
            None => ProcessSettings::default(),
        };
        if self.no_torch {
            settings.torch = None;
        }
        let choice = TcpChoice {
            explicit: self.tcp,
            default: settings.tcp.isometry(),
        };
        let tip = self.tip.as_deref();
        let mut robot = match &self.urdf {
            Some(path) => {
                Robot::from_urdf_file(path, tip, choice).map_err(|source| CellError::Robot {
                    path: path.clone(),
                    source,
                })?
            }
            None => Robot::from_urdf(BUNDLED_URDF, tip, choice).map_err(CellError::BundledRobot)?,
        };
        if let Some(path) = &self.joint_limits {
            let text = std::fs::read_to_string(path).map_err(|source| CellError::ReadLimits {
                path: path.clone(),
                source,
            })?;
            robot = JointLimitsFile::from_yaml(&text)
                .and_then(|file| robot.with_limits(&file))
                .map_err(|source| CellError::Limits {
                    path: path.clone(),
                    source,
                })?;
        }
        Ok(Cell { settings, robot })
    }
}

impl Cell {
    /// The node's default cell: the bundled robot and process settings.
    pub fn bundled() -> Cell {
        CellSource::default()
            .load()
            .expect("the bundled robot and process settings are tested to load")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_default_source_is_the_bundled_cell_and_no_torch_takes_the_torch_off() {
        let cell = CellSource::default().load().unwrap();
        assert!(cell.settings.torch.is_some());
        let bare = CellSource {
            no_torch: true,
            ..CellSource::default()
        }
        .load()
        .unwrap();
        assert!(bare.settings.torch.is_none());
        assert_eq!(bare.robot.name, cell.robot.name);
        let err = CellSource {
            joint_limits: Some("/nonexistent/joint_limits.yaml".into()),
            ..CellSource::default()
        }
        .load()
        .unwrap_err();
        assert!(matches!(err, CellError::ReadLimits { .. }), "{err}");
    }
}
