//! Layer trails through the binary: `waam layer plan --record` (a rosbag2 bag read back
//! here) and `--publish` (received by `waam bag echo` in a separate process). The trail's
//! toolpath and trajectory are waam-layer's tests (`crates/layer/tests/layer_motion.rs`),
//! its heat frames waam-messages' (`crates/messages/tests/layer.rs`).

use std::collections::BTreeMap;

use serde_json::Value;
use waam_layer::output::TrailFile;
use waam_messages::topics;
use waam_ros::node::frames::TF_STATIC;
use waam_rosbag::Bag;
use waam_rosmsg::diagnostic_msgs::DiagnosticArray;
use waam_rosmsg::sensor_msgs::PointCloud2;
use waam_rosmsg::std_msgs::String as RosString;
use waam_rosmsg::trajectory_msgs::JointTrajectory;
use waam_rosmsg::visualization_msgs::MarkerArray;
use waam_rosmsg::waam_interfaces::{WeldPlan, WeldPoint};

use crate::common;
use common::run::{run_isolated, waam};

const PAPER: &str = "config/layers/paper-16mm.yaml";
const ROBOT: &str = "urdf/waam_robot.urdf";

/// The URDF's topic in recordings (the node's, unnamespaced).
const ROBOT_DESCRIPTION: &str = "/robot_description";

/// Topic name -> (type, message count).
fn topic_counts(bag: &Bag) -> BTreeMap<String, (String, u64)> {
    bag.topics
        .iter()
        .map(|t| (t.name.clone(), (t.type_name.clone(), t.count)))
        .collect()
}

fn expected(list: &[(&str, &str, u64)]) -> BTreeMap<String, (String, u64)> {
    list.iter()
        .map(|(n, t, c)| (n.to_string(), (t.to_string(), *c)))
        .collect()
}

fn run_ok(out: &std::process::Output) -> String {
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    assert_eq!(
        out.status.code(),
        Some(0),
        "{stdout}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    stdout
}

/// The temperatures (°C) of a heat frame, checking its layout.
fn temperatures(cloud: &PointCloud2) -> Vec<f32> {
    assert_eq!(cloud.point_step, 16);
    assert_eq!(cloud.data.len(), 16 * cloud.width as usize);
    cloud
        .data
        .chunks(16)
        .map(|p| f32::from_le_bytes(p[12..16].try_into().unwrap()))
        .collect()
}

#[test]
fn a_recording_holds_the_layer_its_status_motion_and_heat() {
    let tmp = tempfile::tempdir().unwrap();
    let (bag_dir, out) = (tmp.path().join("bag"), tmp.path().join("out"));
    let run = waam()
        .args(["-q", "layer", "plan", PAPER, "--robot", ROBOT, "--record"])
        .arg(&bag_dir)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    let stdout = run_ok(&run);
    assert!(
        stdout.contains("PROVEN OPTIMAL") && stdout.contains("MOTION:"),
        "{stdout}"
    );
    let model = common::layer_model(PAPER);
    let bag = Bag::open(&bag_dir).unwrap();
    assert_eq!(bag.truncated, None);
    let heat = model.horizon as u64;
    let latched: &[(&str, &str, u64)] = &[
        (topics::LAYER, "std_msgs/msg/String", 1),
        (topics::STATUS, "diagnostic_msgs/msg/DiagnosticArray", 2),
        (
            topics::JOINT_TRAJECTORY,
            "trajectory_msgs/msg/JointTrajectory",
            1,
        ),
        (topics::POSES, "geometry_msgs/msg/PoseArray", 1),
        (topics::PATH, "nav_msgs/msg/Path", 1),
        (topics::MARKERS, "visualization_msgs/msg/MarkerArray", 1),
        (topics::WELD_PLAN, "waam_interfaces/msg/WeldPlan", 1),
        (topics::HEAT, "sensor_msgs/msg/PointCloud2", heat),
        // What ties the frames together, as the node publishes it.
        (TF_STATIC, "tf2_msgs/msg/TFMessage", 1),
        (ROBOT_DESCRIPTION, "std_msgs/msg/String", 1),
    ];
    assert_eq!(topic_counts(&bag), expected(latched));

    // The layer as received.
    let layer: Vec<_> = bag
        .decode_all::<RosString>()
        .unwrap()
        .into_iter()
        .filter(|(_, topic, _)| *topic == topics::LAYER)
        .collect();
    assert_eq!(
        layer[0].2.data,
        std::fs::read_to_string(common::root().join(PAPER)).unwrap()
    );
    // Statuses: received, then planned with the search's figures.
    let statuses: Vec<_> = bag.decode_all::<DiagnosticArray>().unwrap();
    assert_eq!(statuses[0].2.status[0].message, "received");
    let planned = &statuses[1].2.status[0];
    assert_eq!(planned.message, "planned");
    let value = |key: &str| {
        planned
            .values
            .iter()
            .find(|kv| kv.key == key)
            .unwrap_or_else(|| panic!("no {key}"))
            .value
            .clone()
    };
    assert_eq!(value("proven_optimal"), "true");
    assert_eq!(value("deadheads"), "1");
    assert_eq!(value("gap").parse::<f64>().unwrap(), 0.0);
    assert!(value("nodes_explored").parse::<u64>().unwrap() > 0);
    let objective: f64 = value("objective").parse().unwrap();
    let trail: TrailFile =
        serde_yaml::from_str(&std::fs::read_to_string(out.join("trail.yaml")).unwrap()).unwrap();
    assert_eq!(objective, trail.objective);

    // The trajectory is the one written to trajectory.yaml in the same run.
    let (_, _, traj) = bag.decode_all::<JointTrajectory>().unwrap().pop().unwrap();
    let written: serde_yaml::Value =
        serde_yaml::from_str(&std::fs::read_to_string(out.join("trajectory.yaml")).unwrap())
            .unwrap();
    let points = written["points"].as_sequence().unwrap();
    assert_eq!(traj.points.len(), points.len());
    assert_eq!(traj.joint_names.len(), 6);
    assert_eq!(traj.header.frame_id, "base_link");
    let last = traj.points.last().unwrap();
    let written_end = points.last().unwrap()["time_from_start"].as_f64().unwrap();
    assert!((last.time_from_start.as_secs_f64() - written_end).abs() < 1e-6);
    for (p, w) in traj.points.iter().zip(points) {
        let w: Vec<f64> = serde_yaml::from_value(w["positions"].clone()).unwrap();
        assert_eq!(p.positions, w);
    }
    // The weld plan: one point per toolpath pose, an arc start per run, no blocks.
    let toolpath: serde_yaml::Value =
        serde_yaml::from_str(&std::fs::read_to_string(out.join("toolpath.yaml")).unwrap()).unwrap();
    let (_, _, plan) = bag.decode_all::<WeldPlan>().unwrap().pop().unwrap();
    assert_eq!(plan.part_name, "paper-16mm");
    assert!(plan.fragments.is_empty());
    assert_eq!(
        plan.points.len(),
        toolpath["poses"].as_sequence().unwrap().len()
    );
    let arc_on = plan
        .points
        .iter()
        .filter(|p| p.kind == WeldPoint::ARC_ON)
        .count();
    assert_eq!(arc_on, model.deadheads + 1);
    assert!((plan.weld_speed - 0.010).abs() < 1e-12);
    // Markers: clear the old plan, draw the walls, then the toolpath.
    let (_, _, markers) = bag.decode_all::<MarkerArray>().unwrap().pop().unwrap();
    assert_eq!(markers.markers[0].action, 3, "DELETEALL first");
    let walls = markers.markers.iter().find(|m| m.ns == "walls").unwrap();
    assert_eq!(walls.points.len(), 2 * model.layer.segments.len());

    // Heat: the FEM field at every time step, every mesh node, heated past the target by
    // the torch and cooling after the trail ends.
    let clouds: Vec<PointCloud2> = bag.decode::<PointCloud2>().unwrap();
    let stamps: Vec<i64> = clouds.iter().map(|c| c.header.stamp.to_nanos()).collect();
    assert!(stamps.windows(2).all(|w| w[1] > w[0]));
    let mut fields = Vec::new();
    model.simulate(&trail.trail(&model).unwrap(), Some(&mut fields));
    let ambient = model.layer.temperatures.ambient_c;
    for (n, cloud) in clouds.iter().enumerate() {
        assert_eq!(cloud.width as usize, model.mesh.points.len());
        for (t, u) in temperatures(cloud).iter().zip(&fields[n]) {
            assert!((f64::from(*t) - (ambient + u)).abs() < 1e-4 * (1.0 + u.abs()));
        }
    }
    let hottest = clouds
        .iter()
        .flat_map(temperatures)
        .fold(f32::MIN, f32::max);
    assert!(hottest > 400.0, "hottest {hottest} °C");

    // `waam bag info --json` lists the same topics.
    let info = waam()
        .args(["bag", "info", "--json"])
        .arg(&bag_dir)
        .output()
        .unwrap();
    let info: Value = serde_json::from_str(&run_ok(&info)).unwrap();
    let listed: BTreeMap<String, (String, u64)> = info["topics"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| {
            (
                t["name"].as_str().unwrap().to_string(),
                (
                    t["type"].as_str().unwrap().to_string(),
                    t["count"].as_u64().unwrap(),
                ),
            )
        })
        .collect();
    assert_eq!(listed, expected(latched));
}

#[test]
fn without_a_motion_nothing_of_a_motion_is_recorded() {
    let tmp = tempfile::tempdir().unwrap();
    let heat = common::layer_model(PAPER).horizon as u64;
    // No robot: the layer, its statuses and the heat.
    let bag_dir = tmp.path().join("no-robot");
    let run = waam()
        .args(["-q", "layer", "plan", PAPER, "--record"])
        .arg(&bag_dir)
        .output()
        .unwrap();
    run_ok(&run);
    let bag = Bag::open(&bag_dir).unwrap();
    assert_eq!(
        topic_counts(&bag),
        expected(&[
            (topics::LAYER, "std_msgs/msg/String", 1),
            (topics::STATUS, "diagnostic_msgs/msg/DiagnosticArray", 2),
            (topics::HEAT, "sensor_msgs/msg/PointCloud2", heat),
            (TF_STATIC, "tf2_msgs/msg/TFMessage", 1),
        ])
    );

    // A plate out of the robot's reach: NO MOTION, exit 1, an ERROR status and no
    // trajectory anywhere.
    let process = tmp.path().join("far.yaml");
    std::fs::write(&process, "plate:\n  position_m: [3.0, 0.0, 0.35]\n").unwrap();
    let (bag_dir, out) = (tmp.path().join("far"), tmp.path().join("out"));
    let run = waam()
        .args(["layer", "plan", PAPER, "--robot", ROBOT, "--process"])
        .arg(&process)
        .arg("--record")
        .arg(&bag_dir)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert_eq!(run.status.code(), Some(1), "{stdout}");
    assert!(
        stdout.contains("NO MOTION: unreachable") && stdout.contains("segments["),
        "{stdout}"
    );
    assert!(out.join("trail.yaml").exists());
    assert!(!out.join("toolpath.yaml").exists() && !out.join("trajectory.yaml").exists());
    let bag = Bag::open(&bag_dir).unwrap();
    assert_eq!(
        topic_counts(&bag),
        expected(&[
            (topics::LAYER, "std_msgs/msg/String", 1),
            (topics::STATUS, "diagnostic_msgs/msg/DiagnosticArray", 3),
            (topics::HEAT, "sensor_msgs/msg/PointCloud2", heat),
            (TF_STATIC, "tf2_msgs/msg/TFMessage", 1),
            (ROBOT_DESCRIPTION, "std_msgs/msg/String", 1),
        ])
    );
    let statuses = bag.decode_all::<DiagnosticArray>().unwrap();
    let last = &statuses.last().unwrap().2.status[0];
    assert_eq!(last.level, 2, "ERROR");
    assert!(
        last.message.starts_with("no motion: unreachable"),
        "{}",
        last.message
    );

    // Bad robot input fails before the search, naming the file; no bag is left behind.
    let bag_dir = tmp.path().join("bad");
    let run = waam()
        .args([
            "layer",
            "plan",
            PAPER,
            "--robot",
            "no/such.urdf",
            "--record",
        ])
        .arg(&bag_dir)
        .output()
        .unwrap();
    assert_eq!(run.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&run.stderr).contains("no/such.urdf"));
    assert!(!bag_dir.exists());
}

#[test]
fn published_once_the_motion_reaches_a_late_subscriber() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path().display();
    let root = common::root();
    let script = format!(
        r#"
"$W" bag echo /waam_planner/plan/joint_trajectory --type trajectory_msgs/msg/JointTrajectory --transient-local --count 1 --timeout 60 > {d}/trajectory.jsonl &
T=$!
"$W" bag echo /waam_planner/status --type diagnostic_msgs/msg/DiagnosticArray --transient-local --count 1 --timeout 60 > {d}/status.jsonl &
S=$!
"$W" layer plan {root}/{PAPER} --robot {root}/{ROBOT} --out {d}/out --publish --linger 8 > {d}/plan.txt
wait $T
wait $S
"#,
        root = root.display()
    );
    let out = run_isolated(tmp.path(), &script);
    let read = |name: &str| std::fs::read_to_string(tmp.path().join(name)).unwrap_or_default();
    assert!(
        out.status.success(),
        "{}\nplan: {}\nstderr: {}",
        out.status,
        read("plan.txt"),
        String::from_utf8_lossy(&out.stderr)
    );
    // The received trajectory is the one written in the same run.
    let received: Value = serde_json::from_str(read("trajectory.jsonl").trim()).unwrap();
    let written: serde_yaml::Value = serde_yaml::from_str(&read("out/trajectory.yaml")).unwrap();
    let points = received["points"].as_array().unwrap();
    assert_eq!(points.len(), written["points"].as_sequence().unwrap().len());
    assert_eq!(received["header"]["frame_id"], "base_link");
    let first: Vec<f64> =
        serde_yaml::from_value(written["points"][0]["positions"].clone()).unwrap();
    let got: Vec<f64> = serde_json::from_value(points[0]["positions"].clone()).unwrap();
    assert_eq!(got, first);
    let status: Value = serde_json::from_str(read("status.jsonl").trim()).unwrap();
    assert_eq!(status["status"][0]["message"], "planned");
    assert_eq!(status["status"][0]["name"], "waam_planner");
}
