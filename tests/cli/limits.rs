//! Joint velocity and acceleration limits from a MoveIt-style joint_limits.yaml hold in
//! `trajectory.yaml`, checked here on the file alone (positions, velocities,
//! accelerations, times) for the bundled robot and the ABB IRB 1600; welds keep their
//! speed: where the limits would slow a weld, that is an error naming the block.

use crate::common;

use std::path::Path;

use common::{plan_path, root, ABB_TCP};
use serde_yaml::Value;
use waam_motion::robot::limits::JointLimitsFile;
use waam_motion::toolpath::ProcessSettings;
use waam_pipeline::Cell;

/// (max velocity, max acceleration) per joint name, read from the limits file.
fn limits(path: &Path) -> Vec<(String, f64, f64)> {
    let v: Value = serde_yaml::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    v["joint_limits"]
        .as_mapping()
        .unwrap()
        .iter()
        .map(|(k, e)| {
            (
                k.as_str().unwrap().to_string(),
                e["max_velocity"].as_f64().unwrap(),
                e["max_acceleration"].as_f64().unwrap(),
            )
        })
        .collect()
}

/// The worst ratios (velocity, acceleration) to the limits over `trajectory.yaml`: the
/// points' velocities and accelerations, and between points the mean velocity Δq/Δt and
/// the velocity change Δv/Δt.
fn worst_ratios(trajectory: &Path, limits: &[(String, f64, f64)]) -> (f64, f64) {
    let v: Value = serde_yaml::from_str(&std::fs::read_to_string(trajectory).unwrap()).unwrap();
    let names: Vec<&str> = v["joint_names"]
        .as_sequence()
        .unwrap()
        .iter()
        .map(|n| n.as_str().unwrap())
        .collect();
    let lim: Vec<(f64, f64)> = names
        .iter()
        .map(|n| {
            let l = limits.iter().find(|l| l.0 == *n).unwrap();
            (l.1, l.2)
        })
        .collect();
    let floats = |p: &Value, key: &str| -> Vec<f64> {
        p[key]
            .as_sequence()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect()
    };
    let points = v["points"].as_sequence().unwrap();
    let (mut wv, mut wa) = (0.0f64, 0.0f64);
    for (i, p) in points.iter().enumerate() {
        let (q, vel, acc) = (
            floats(p, "positions"),
            floats(p, "velocities"),
            floats(p, "accelerations"),
        );
        assert_eq!(acc.len(), names.len(), "point {i} carries accelerations");
        for j in 0..names.len() {
            wv = wv.max(vel[j].abs() / lim[j].0);
            wa = wa.max(acc[j].abs() / lim[j].1);
        }
        if i > 0 {
            let prev = &points[i - 1];
            let dt =
                p["time_from_start"].as_f64().unwrap() - prev["time_from_start"].as_f64().unwrap();
            assert!(dt > 0.0);
            let (q0, v0) = (floats(prev, "positions"), floats(prev, "velocities"));
            for j in 0..names.len() {
                wv = wv.max((q[j] - q0[j]).abs() / dt / lim[j].0);
                wa = wa.max((vel[j] - v0[j]).abs() / dt / lim[j].1);
            }
        }
    }
    (wv, wa)
}

fn waam_motion(urdf: &str, tcp: Option<&str>, limits: Option<&Path>, out: &Path) {
    let part = root().join("config/parts/ex2-bracket.yaml");
    let mut cmd = crate::common::run::waam();
    cmd.arg("motion")
        .arg(&part)
        .arg(plan_path("ex2-bracket"))
        .args(["--robot", urdf])
        .arg("--out")
        .arg(out);
    if let Some(tcp) = tcp {
        cmd.args(["--tcp", tcp]);
    }
    if let Some(l) = limits {
        cmd.arg("--limits").arg(l);
    }
    let o = cmd.output().unwrap();
    assert!(
        o.status.success(),
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
}

#[test]
fn no_joint_goes_over_its_velocity_or_acceleration_limit_in_trajectory_yaml() {
    let file = root().join("config/joint_limits.yaml");
    let lims = limits(&file);
    let robots = [
        (root().join("urdf/waam_robot.urdf"), None),
        (root().join("tests/data/abb_irb1600_12.urdf"), Some(ABB_TCP)),
    ];
    for (i, (urdf, tcp)) in robots.iter().enumerate() {
        let urdf = urdf.to_str().unwrap();
        let dir = std::env::temp_dir().join(format!("waam-limits-{}-{i}", std::process::id()));
        waam_motion(urdf, *tcp, Some(&file), &dir.join("limited"));
        let (wv, wa) = worst_ratios(&dir.join("limited/trajectory.yaml"), &lims);
        assert!(wv <= 1.0 + 1e-6, "{urdf}: velocity at {wv} of its limit");
        assert!(
            wa <= 1.0 + 1e-6,
            "{urdf}: acceleration at {wa} of its limit"
        );
        // The limits bind: without them the same motion goes over the accelerations.
        waam_motion(urdf, *tcp, None, &dir.join("free"));
        let (_, free) = worst_ratios(&dir.join("free/trajectory.yaml"), &lims);
        assert!(free > 1.0, "{urdf}: the limits file does not bind ({free})");
        eprintln!("{urdf}: limited {wv:.3} / {wa:.3} of the limits; unlimited accelerations reach {free:.1}×");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}

#[test]
fn a_weld_the_limits_would_slow_down_is_an_error_naming_the_block() {
    let (part, fragments) = common::part_and_plan("s3-ring");
    let tight = "joint_limits: {joint_1: {has_acceleration_limits: true, max_acceleration: 0.001}}";
    let robot = common::our_robot()
        .with_limits(&JointLimitsFile::from_yaml(tight).unwrap())
        .unwrap();
    let cell = Cell {
        settings: ProcessSettings::default(),
        robot,
    };
    let err = cell.plan_motion(&part, &fragments).unwrap_err().to_string();
    assert!(
        err.contains("weld at block [") && err.contains("joint_1") && err.contains("rad/s²"),
        "{err}"
    );
    // The velocity limit likewise.
    let slow = "joint_limits: {joint_1: {has_velocity_limits: true, max_velocity: 0.0001}}";
    let robot = common::our_robot()
        .with_limits(&JointLimitsFile::from_yaml(slow).unwrap())
        .unwrap();
    let cell = Cell {
        settings: ProcessSettings::default(),
        robot,
    };
    let err = cell.plan_motion(&part, &fragments).unwrap_err().to_string();
    assert!(err.contains("block [") && err.contains("rad/s,"), "{err}");
}

#[test]
fn a_bad_limits_file_is_a_one_line_error_naming_the_joint() {
    let dir = std::env::temp_dir().join(format!("waam-badlimits-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let bad = dir.join("limits.yaml");
    std::fs::write(
        &bad,
        "joint_limits: {joint_9: {has_velocity_limits: true, max_velocity: 1}}\n",
    )
    .unwrap();
    let o = crate::common::run::waam()
        .arg("motion")
        .arg(root().join("config/parts/s1-wall.yaml"))
        .arg(plan_path("s1-wall"))
        .arg("--robot")
        .arg(root().join("urdf/waam_robot.urdf"))
        .arg("--limits")
        .arg(&bad)
        .arg("--out")
        .arg(dir.join("out"))
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("joint_limits.joint_9: not a joint"), "{err}");
    std::fs::remove_dir_all(&dir).unwrap();
}
