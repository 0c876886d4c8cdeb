//! `waam bag` on recordings made by a separate `waam` process: a finished session and one
//! killed with SIGKILL mid-recording, read with our own reader.

use std::path::Path;

use serde_json::Value;

use crate::common;
use common::run::{kill_a_recording, last_json, run_ok, waam};

fn info_json(bag: &Path) -> Value {
    let stdout = run_ok(waam().args(["bag", "info", "--json"]).arg(bag));
    serde_json::from_str(&stdout).unwrap()
}

#[test]
fn info_reports_a_finished_session() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("session");
    let stdout = run_ok(waam().args(["bag", "sample", "--rounds", "2"]).arg(&dir));
    let written: Value = serde_json::from_str(&stdout).unwrap();
    let info = info_json(&dir);
    assert_eq!(info["truncated"], Value::Null);
    assert_eq!(info["ros_distro"], "jazzy");
    assert_eq!(info["profile"], "ros2");
    let topics = info["topics"].as_array().unwrap();
    assert_eq!(topics.len(), written.as_object().unwrap().len());
    for t in topics {
        let w = &written[t["name"].as_str().unwrap()];
        assert_eq!(t["type"], w["type"]);
        assert_eq!(t["count"], w["count"]);
    }
    let text = waam().args(["bag", "info"]).arg(&dir).output().unwrap();
    let text = String::from_utf8(text.stdout).unwrap();
    assert!(text.contains("Storage id:        mcap"), "{text}");
    assert!(text.contains(
        "Topic: /waam_planner/plan/weld_plan | Type: waam_interfaces/msg/WeldPlan | Count: 2 | Serialization Format: cdr"
    ), "{text}");
    assert!(!text.contains("Truncated"), "{text}");
}

#[test]
fn a_recording_killed_with_sigkill_reads_up_to_its_last_chunk() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("killed");
    let flushed = kill_a_recording(&dir, 300);
    let info = info_json(&dir);
    let truncated = &info["truncated"];
    assert!(truncated.is_object(), "not reported as truncated: {info}");
    let read = info["message_count"].as_u64().unwrap();
    // Everything flushed before the last metadata.yaml refresh is readable (a chunk closed
    // after that refresh adds more).
    assert!(read >= flushed, "read {read} of {flushed} flushed messages");
    assert!(info["chunks"].as_u64().unwrap() >= 1, "{info}");
    let text = waam().args(["bag", "info"]).arg(&dir).output().unwrap();
    assert!(text.status.success());
    let text = String::from_utf8(text.stdout).unwrap();
    assert!(text.contains("Truncated:         yes"), "{text}");
    assert!(text.contains("waam bag reindex"), "{text}");

    // `waam bag reindex` completes it with every message that was read; a second run finds
    // it complete.
    let out = run_ok(waam().args(["bag", "reindex", "--json"]).arg(&dir));
    let done = last_json(&out);
    assert_eq!(done["was_complete"], false, "{done}");
    assert_eq!(done["messages"].as_u64(), Some(read), "{done}");
    let after = info_json(&dir);
    assert_eq!(after["truncated"], Value::Null, "{after}");
    assert_eq!(after["message_count"].as_u64(), Some(read));
    assert_eq!(after["topics"], info["topics"]);
    let again = last_json(&run_ok(waam().args(["bag", "reindex", "--json"]).arg(&dir)));
    assert_eq!(again["was_complete"], true, "{again}");
    assert_eq!(again["messages"].as_u64(), Some(read));
}

#[test]
fn info_names_a_file_that_is_not_a_bag() {
    let tmp = tempfile::tempdir().unwrap();
    let file = tmp.path().join("x.mcap");
    std::fs::write(&file, b"hello").unwrap();
    let out = waam().args(["bag", "info"]).arg(&file).output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("x.mcap") && err.contains("not an MCAP file"),
        "{err}"
    );
    let out = waam()
        .args(["bag", "info"])
        .arg(tmp.path().join("missing"))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    // reindex: a bag directory only, and it says what is wrong with its file.
    let out = waam().args(["bag", "reindex"]).arg(&file).output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("not a directory"), "{err}");
    let dir = tmp.path().join("junk");
    std::fs::create_dir(&dir).unwrap();
    std::fs::write(dir.join("junk_0.mcap"), b"hello").unwrap();
    let out = waam().args(["bag", "reindex"]).arg(&dir).output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("junk_0.mcap") && err.contains("not an MCAP file"),
        "{err}"
    );
    assert_eq!(std::fs::read(dir.join("junk_0.mcap")).unwrap(), b"hello");
}

/// `waam plan --robot --record`: the bag holds the motion as the node publishes it
/// (trajectory, poses, path, markers, a weld plan with its toolpath points) and one
/// PlanCandidate per candidate with the planner's verdict: the broken window's block, the
/// violating prefix and the learned clause.
#[test]
fn plan_with_a_robot_records_the_motion_and_every_candidates_verdict() {
    use waam_messages::topics;
    use waam_part::Part;
    use waam_rosbag::Bag;
    use waam_rosmsg::geometry_msgs::PoseArray;
    use waam_rosmsg::trajectory_msgs::JointTrajectory;
    use waam_rosmsg::visualization_msgs::MarkerArray;
    use waam_rosmsg::waam_interfaces::{PlanCandidate, WeldPlan};

    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let part_path = root.join("config/parts/s1-wall.yaml");
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("session");
    let stdout = run_ok(
        waam()
            .args(["-q", "plan", "--json", "--robot"])
            .arg(root.join("urdf/waam_robot.urdf"))
            .arg("--record")
            .arg(&dir)
            .arg(&part_path),
    );
    let report = last_json(&stdout);
    let stats = &report["stats"];

    let bag = Bag::open(&dir).unwrap();
    for topic in [
        topics::JOINT_TRAJECTORY,
        topics::POSES,
        topics::PATH,
        topics::MARKERS,
        topics::WELD_PLAN,
    ] {
        assert_eq!(bag.count(topic), 1, "{topic} recorded once");
    }
    assert!(bag.count(topics::HEAT) > 0, "heat frames recorded");
    fn only<M: waam_rosmsg::RosMessage>(bag: &Bag) -> M {
        bag.decode_all::<M>().unwrap().remove(0).2
    }
    let trajectory: JointTrajectory = only(&bag);
    let poses: PoseArray = only(&bag);
    let markers: MarkerArray = only(&bag);
    let plan: WeldPlan = only(&bag);
    assert_eq!(trajectory.joint_names.len(), 6);
    assert!(trajectory.points.len() >= poses.poses.len() && !poses.poses.is_empty());
    assert_eq!(
        plan.points.len(),
        poses.poses.len(),
        "one weld point per pose"
    );
    assert_eq!(
        plan.fragments.len(),
        report["plan"]["fragments"].as_array().unwrap().len()
    );
    assert!(markers.markers.len() > 3, "blocks, weld lines, arc markers");
    assert_eq!(
        trajectory.header, poses.header,
        "one header for all outputs"
    );

    let part = Part::parse(&std::fs::read_to_string(&part_path).unwrap()).unwrap();
    let windowed: Vec<[i64; 3]> = part.windows().iter().map(|&(i, _)| part.block(i)).collect();
    let candidates: Vec<PlanCandidate> = bag.decode::<PlanCandidate>().unwrap();
    assert_eq!(
        candidates.len() as u64,
        stats["candidates"].as_u64().unwrap()
    );
    let indices: Vec<u64> = candidates.iter().map(|c| c.index).collect();
    assert_eq!(indices, (1..=candidates.len() as u64).collect::<Vec<_>>());
    let feasible = candidates
        .iter()
        .filter(|c| c.verdict == PlanCandidate::FEASIBLE)
        .count();
    assert_eq!(feasible as u64, stats["feasible"].as_u64().unwrap());
    let violated: Vec<_> = candidates
        .iter()
        .filter(|c| c.verdict != PlanCandidate::FEASIBLE)
        .collect();
    // With CaDiCaL most infeasible plans are cut inside the search, from a partial
    // assignment: they are no candidates, and their clauses are counted apart.
    let inside = stats["inside_clauses"].as_u64().unwrap();
    assert!(
        !violated.is_empty() || inside > 0,
        "s1-wall has infeasible plans"
    );
    let mut clause_sum = 0u64;
    for c in &violated {
        assert!(
            [PlanCandidate::TOO_SHORT, PlanCandidate::TOO_LONG].contains(&c.verdict),
            "{c:?}"
        );
        assert!(
            windowed.contains(&c.block.to_part()),
            "{c:?}: not a windowed block"
        );
        assert!((1..=part.len() as u32).contains(&c.prefix_len), "{c:?}");
        assert!(c.time_s > 0.0 && c.learned_clause_len > 0, "{c:?}");
        clause_sum += u64::from(c.learned_clause_len);
    }
    let mean = stats["clause_len_mean"].as_f64().unwrap();
    let learned = stats["learned_clauses"].as_u64().unwrap();
    assert_eq!(learned, violated.len() as u64 + inside);
    if inside == 0 {
        assert!((clause_sum as f64 - mean * learned as f64).abs() < 1e-6);
    }
}

/// Issue #18: the node makes its input durable before planning it. `waam publish` (the node,
/// once) is killed with SIGKILL the moment it says the part was received — well inside the
/// 1 s a chunk may stay open — and the part is in the recording.
#[test]
fn the_node_has_its_input_on_disk_before_it_plans() {
    use std::io::BufRead;
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("node");
    let mut child = waam()
        .env("RUST_LOG", "info")
        .env("ROS_DOMAIN_ID", (150 + std::process::id() % 50).to_string())
        .env("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
        .args(["publish", "--dry-run", "--linger", "30", "--record"])
        .arg(&dir)
        .arg(root.join("config/parts/ex3-h-column.yaml"))
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let stderr = std::io::BufReader::new(child.stderr.take().unwrap());
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        for line in stderr.lines().map_while(Result::ok) {
            if line.contains("part 1 received") {
                let _ = tx.send(());
            }
        }
    });
    let said = rx.recv_timeout(std::time::Duration::from_secs(60));
    child.kill().unwrap(); // SIGKILL on Unix
    child.wait().unwrap();
    said.expect("the node never said it received the part");
    let killed = waam_rosbag::Bag::open(&dir).unwrap();
    assert!(
        killed.truncated.is_some(),
        "the node finished before the kill"
    );
    assert_eq!(killed.count("/waam_planner/part"), 1, "the part was lost");
    run_ok(waam().args(["bag", "reindex"]).arg(&dir));
    let bag = waam_rosbag::Bag::open(&dir).unwrap();
    assert!(bag.truncated.is_none());
    let strings = bag.decode_all::<waam_rosmsg::std_msgs::String>().unwrap();
    let (_, _, part) = strings
        .iter()
        .find(|(_, topic, _)| *topic == "/waam_planner/part")
        .expect("the part after reindex");
    let text = std::fs::read_to_string(root.join("config/parts/ex3-h-column.yaml")).unwrap();
    assert_eq!(part.data, text);
}

/// `waam plan --record`, with and without a robot: every frame a recorded message names is
/// tied by `/tf_static` (and, with a robot, the URDF on `/robot_description`) to the robot's
/// base, with the node's frame names — so Foxglove shows part, path and heat together.
#[test]
fn plan_recordings_tie_every_frame_they_name_to_the_robot_base() {
    use std::collections::BTreeSet;
    use waam_messages::planning::PART_FRAME;
    use waam_messages::topics;
    use waam_ros::node::frames::{TCP_FRAME, TF_STATIC};
    use waam_rosbag::Bag;
    use waam_rosmsg::geometry_msgs::PoseArray;
    use waam_rosmsg::nav_msgs::Path as PathMsg;
    use waam_rosmsg::sensor_msgs::PointCloud2;
    use waam_rosmsg::std_msgs::String as RosString;
    use waam_rosmsg::tf2_msgs::TFMessage;
    use waam_rosmsg::trajectory_msgs::JointTrajectory;
    use waam_rosmsg::visualization_msgs::MarkerArray;
    use waam_rosmsg::waam_interfaces::{PlanCandidate, WeldPlan};

    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let urdf_path = root.join("urdf/waam_robot.urdf");
    let urdf = std::fs::read_to_string(&urdf_path).unwrap();
    // The URDF's links (robot_state_publisher ties them to its root by /tf).
    let links: BTreeSet<String> = urdf
        .split("<link name=\"")
        .skip(1)
        .map(|s| s[..s.find('"').unwrap()].to_string())
        .collect();
    assert!(links.len() > 3, "{links:?}");
    let tmp = tempfile::tempdir().unwrap();
    for with_robot in [true, false] {
        let dir = tmp.path().join(format!("session-{with_robot}"));
        let mut cmd = waam();
        cmd.args(["-q", "plan"]);
        if with_robot {
            cmd.arg("--robot").arg(&urdf_path);
        }
        cmd.arg("--record")
            .arg(&dir)
            .arg(root.join("config/parts/s1-wall.yaml"));
        run_ok(&mut cmd);
        let bag = Bag::open(&dir).unwrap();

        // The transforms: base link -> part, tip link -> TCP, the node's names.
        assert_eq!(bag.count(TF_STATIC), 1, "with robot: {with_robot}");
        let tf: TFMessage = bag.decode().unwrap().remove(0);
        let edges: Vec<(String, String)> = tf
            .transforms
            .iter()
            .map(|t| (t.header.frame_id.clone(), t.child_frame_id.clone()))
            .collect();
        let children: Vec<&str> = edges.iter().map(|(_, c)| c.as_str()).collect();
        assert_eq!(children, [PART_FRAME, TCP_FRAME], "{edges:?}");
        for (parent, _) in &edges {
            assert!(links.contains(parent), "{parent} is no link of the robot");
        }
        let descriptions: Vec<RosString> = bag
            .decode_all::<RosString>()
            .unwrap()
            .into_iter()
            .filter(|(_, topic, _)| *topic == "/robot_description")
            .map(|(_, _, m)| m)
            .collect();
        // Connected to the base: the URDF's links when it is recorded, and the tf children.
        let mut connected: BTreeSet<String> = BTreeSet::new();
        if with_robot {
            assert_eq!(descriptions.len(), 1);
            assert_eq!(descriptions[0].data, urdf, "the URDF in use");
            connected.extend(links.iter().cloned());
        } else {
            assert!(descriptions.is_empty(), "no robot, no robot_description");
            connected.insert(edges[0].0.clone()); // the base of the node's default cell
        }
        for (parent, child) in &edges {
            if connected.contains(parent) {
                connected.insert(child.clone());
            }
        }

        // Every frame a recorded message names.
        let mut named: Vec<(String, String)> = Vec::new();
        let mut add = |topic: &str, frame: &str| named.push((topic.to_string(), frame.to_string()));
        for (_, topic, m) in bag.decode_all::<PointCloud2>().unwrap() {
            add(topic, &m.header.frame_id);
        }
        for (_, topic, m) in bag.decode_all::<WeldPlan>().unwrap() {
            add(topic, &m.header.frame_id);
        }
        for (_, topic, m) in bag.decode_all::<PlanCandidate>().unwrap() {
            add(topic, &m.header.frame_id);
        }
        for (_, topic, m) in bag.decode_all::<JointTrajectory>().unwrap() {
            add(topic, &m.header.frame_id);
        }
        for (_, topic, m) in bag.decode_all::<PoseArray>().unwrap() {
            add(topic, &m.header.frame_id);
        }
        for (_, topic, m) in bag.decode_all::<PathMsg>().unwrap() {
            add(topic, &m.header.frame_id);
            for p in &m.poses {
                add(topic, &p.header.frame_id);
            }
        }
        for (_, topic, m) in bag.decode_all::<MarkerArray>().unwrap() {
            for marker in &m.markers {
                add(topic, &marker.header.frame_id);
            }
        }
        assert!(bag.count(topics::HEAT) > 0 && bag.count(topics::WELD_PLAN) == 1);
        if with_robot {
            assert_eq!(bag.count(topics::JOINT_TRAJECTORY), 1);
        }
        for (topic, frame) in &named {
            assert!(
                connected.contains(frame),
                "with robot: {with_robot}: {topic} names frame {frame:?}, which TF does not \
                 tie to the robot base (tied: {connected:?})"
            );
        }
        let heat_frames: BTreeSet<&str> = named
            .iter()
            .filter(|(t, _)| t == topics::HEAT)
            .map(|(_, f)| f.as_str())
            .collect();
        assert_eq!(
            heat_frames,
            BTreeSet::from([PART_FRAME]),
            "the node's heat frame"
        );
    }
}
