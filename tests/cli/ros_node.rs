//! ROS 2 interop: `waam node` against rclpy from ROS 2 Jazzy's PyPI wheels.
//!
//! Each test runs one script of `tests/ros/` with the venv's Python. The venv comes from
//! `scripts/ros-venv.sh`, which the project's test script runs and whose path it passes in
//! `WAAM_ROS_VENV`. Without it these tests fail with a message saying so, unless
//! `WAAM_SKIP_ROS=1` asks to skip them.
//!
//! Isolation: as root, each script runs in a private network namespace (`unshare -n`) where
//! only loopback exists; otherwise on loopback-only discovery. Either way with a domain id of
//! its own, so parallel tests and other DDS traffic on the machine never meet.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::atomic::{AtomicU16, Ordering};
use std::sync::{Mutex, OnceLock};

use crate::common;

/// The venv's Python, or `None` when the ROS tests are to be skipped.
fn ros_python() -> Option<PathBuf> {
    match std::env::var_os("WAAM_ROS_VENV") {
        Some(venv) => {
            let python = Path::new(&venv).join("bin/python");
            assert!(
                python.exists(),
                "WAAM_ROS_VENV={} has no bin/python: run scripts/ros-venv.sh",
                Path::new(&venv).display()
            );
            Some(python)
        }
        None if std::env::var("WAAM_SKIP_ROS").as_deref() == Ok("1") => {
            eprintln!("skipped: WAAM_SKIP_ROS=1");
            None
        }
        None => panic!(
            "the ROS 2 interop tests need rclpy: run `scripts/ros-venv.sh` and set \
             WAAM_ROS_VENV to the path it prints (scripts/test.sh does both), or set \
             WAAM_SKIP_ROS=1 to skip them"
        ),
    }
}

/// Whether `unshare -n` works here (root, and a kernel that allows network namespaces).
fn have_netns() -> bool {
    static NETNS: OnceLock<bool> = OnceLock::new();
    *NETNS.get_or_init(|| {
        Command::new("unshare")
            .args(["-n", "ip", "link", "set", "lo", "up"])
            .output()
            .is_ok_and(|o| o.status.success())
    })
}

/// A domain id no other test of this run uses (and, by the pid, unlikely any other run),
/// within ROS 2's safe range 1..=101 (RTPS ports overflow above 232).
fn fresh_domain_id() -> u16 {
    static NEXT: AtomicU16 = AtomicU16::new(0);
    let n = NEXT.fetch_add(1, Ordering::Relaxed);
    1 + ((std::process::id() % 20) as u16 * 5 + n) % 101
}

fn repo() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// The interpreter of scripts that need the interfaces `scripts/build-interfaces.sh` builds
/// (waam_interfaces' actions, the tests' control_msgs): `tests/ros/with-interfaces.sh VENV
/// INSTALL`, by default the repository's `.venv-ros-build` and `ros/install`
/// (`WAAM_ROS_BUILD_VENV`, `WAAM_ROS_INTERFACES` choose others). `None` when the ROS tests are
/// skipped.
fn interfaces_python() -> Option<Vec<PathBuf>> {
    ros_python()?;
    let path = |var: &str, default: &str| {
        std::env::var_os(var).map_or_else(|| repo().join(default), PathBuf::from)
    };
    let venv = path("WAAM_ROS_BUILD_VENV", ".venv-ros-build");
    let install = path("WAAM_ROS_INTERFACES", "ros/install");
    assert!(
        venv.join("bin/python").exists() && install.join("setup.bash").exists(),
        "no built ROS interfaces at {} (venv {}): run scripts/build-interfaces.sh \
         (scripts/test.sh does), or set WAAM_SKIP_ROS=1 to skip the ROS tests",
        install.display(),
        venv.display()
    );
    Some(vec![
        repo().join("tests/ros/with-interfaces.sh"),
        venv,
        install,
    ])
}

/// Runs `tests/ros/SCRIPT` (Python) isolated, with `WAAM_BIN` set; panics with its output
/// unless it exits 0. `None` when the ROS tests are skipped.
fn run_script(script: &str, args: &[&str]) -> Option<Output> {
    run_script_with(vec![ros_python()?], script, args)
}

/// [`run_script`] with the interpreter `python` (a program and its first arguments).
///
/// The scripts run one at a time: each starts DDS participants whose discovery bursts, on a
/// loaded 2-core CI machine, otherwise compete with the other scripts' for the CPU. A run
/// that failed only because a peer was never discovered (the script says `FAIL (discovery)`)
/// is run once more in a fresh domain, with the first run's output printed; a second such
/// failure, or any failure of the node's behaviour, fails the test.
fn run_script_with(python: Vec<PathBuf>, script: &str, args: &[&str]) -> Option<Output> {
    static ONE_AT_A_TIME: Mutex<()> = Mutex::new(());
    let _turn = ONE_AT_A_TIME
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner());
    let (output, text) = run_once(&python, script, args);
    if output.status.success() {
        eprintln!("{text}");
        return Some(output);
    }
    let discovery_only = |o: &Output| {
        String::from_utf8_lossy(&o.stdout).contains("FAIL (discovery)")
            || String::from_utf8_lossy(&o.stderr).contains("FAIL (discovery)")
    };
    assert!(discovery_only(&output), "{text}");
    eprintln!("note: a DDS peer was not discovered; running {script} once more\n{text}");
    let (output, text) = run_once(&python, script, args);
    assert!(output.status.success(), "{text}");
    eprintln!("{text}");
    Some(output)
}

/// `tests/ros/SCRIPT BAG` with the built interfaces (as [`run_script_with`]), the node
/// recording into BAG, a new folder `name` in a temporary directory: the directory (kept
/// while the caller holds it) and BAG; None without a ROS 2 environment (the test skips).
fn recorded_script_run(script: &str, name: &str) -> Option<(tempfile::TempDir, PathBuf)> {
    let python = interfaces_python()?;
    let dir = tempfile::tempdir().unwrap();
    let bag = dir.path().join(name);
    run_script_with(python, script, &[bag.to_str().unwrap()]);
    Some((dir, bag))
}

/// One run of `tests/ros/SCRIPT` in a fresh domain: its output and a report of it.
fn run_once(python: &[PathBuf], script: &str, args: &[&str]) -> (Output, String) {
    let script_path = repo().join("tests/ros").join(script);
    let mut command = if have_netns() {
        let mut c = Command::new("unshare");
        c.arg("-n")
            .arg(repo().join("tests/ros/netns.sh"))
            .args(python);
        c
    } else {
        eprintln!("note: no network namespace (not root?): using loopback-only discovery");
        let mut c = Command::new(&python[0]);
        c.args(&python[1..]);
        c
    };
    let domain = fresh_domain_id();
    command
        .arg(&script_path)
        .args(args)
        .current_dir(repo())
        .env("WAAM_BIN", env!("CARGO_BIN_EXE_waam"))
        .env("ROS_DOMAIN_ID", domain.to_string())
        .env("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
        .env_remove("ROS_LOCALHOST_ONLY")
        .env_remove("ROS_STATIC_PEERS");
    let output = command
        .output()
        .unwrap_or_else(|e| panic!("cannot run {}: {e}", python[0].display()));
    let text = format!(
        "{script} (domain {domain}) exited with {}\n--- stdout ---\n{}\n--- stderr ---\n{}",
        output.status,
        String::from_utf8_lossy(&output.stdout),
        String::from_utf8_lossy(&output.stderr)
    );
    (output, text)
}

/// `waam bag info BAG`'s listing, asserting that it lists every one of `topics`.
fn assert_bag_lists(bag: &Path, topics: &[&str]) {
    let out = crate::common::run::waam()
        .args(["bag", "info"])
        .arg(bag)
        .output()
        .unwrap();
    let info = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{info}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    for topic in topics {
        assert!(
            info.contains(topic),
            "bag info does not list {topic}:\n{info}"
        );
    }
}

/// `waam replay --json BAG`: its exit code and JSON report.
fn replay_json(bag: &Path) -> (Option<i32>, serde_json::Value) {
    let out = crate::common::run::waam()
        .args(["replay", "--json"])
        .arg(bag)
        .output()
        .unwrap();
    let json: serde_json::Value = serde_json::from_slice(&out.stdout)
        .unwrap_or_else(|_| panic!("no JSON: {}", String::from_utf8_lossy(&out.stderr)));
    (out.status.code(), json)
}

#[test]
fn rclpy_part_yields_trajectory_poses_markers_and_errors_on_bad_parts() {
    run_script("part_to_plan.py", &[]);
}

#[test]
fn rclpy_mesh_box_is_planned_and_the_latest_part_wins() {
    run_script("mesh_and_latest.py", &[]);
}

/// A ring mesh with `mesh.bead_mm` set is sliced into beads and planned as a graph part: the
/// weld plan's weld points and the markers' deposits lie on the ring's centre line
/// (mesh_beads.py). The node's recording of it lists the graph part's topics in `waam bag
/// info`, and `waam replay` slices the mesh again with the recorded bead size and finds the
/// same plan.
#[test]
fn rclpy_ring_mesh_as_beads_is_welded_on_its_centre_line_and_its_recording_replays() {
    let Some((_dir, bag)) = recorded_script_run("mesh_beads.py", "ring") else {
        return;
    };

    assert_bag_lists(
        &bag,
        &[
            "/waam_planner/part_mesh",
            "/waam_planner/plan/weld_plan",
            "/waam_planner/plan/joint_trajectory",
            "/waam_planner/plan/markers",
        ],
    );

    // The recorded markers: one cube per bead node, at the node's centre on the ring's
    // centre line (radius 20 mm about the nodes' mean, which for a whole ring of equally
    // spaced nodes is its centre; 0.1 mm as in mesh_beads.py).
    let recording = waam_rosbag::Bag::open(&bag).unwrap();
    let markers: Vec<waam_rosmsg::visualization_msgs::MarkerArray> = recording.decode().unwrap();
    let cubes: Vec<[f64; 3]> = markers
        .last()
        .expect("no markers recorded")
        .markers
        .iter()
        .filter(|m| m.ns == "blocks")
        .flat_map(|m| m.points.iter().map(|p| [p.x * 1e3, p.y * 1e3, p.z * 1e3]))
        .collect();
    assert_eq!(cubes.len(), 42, "a cube per node: 2 layers of 21");
    let (z_lo, z_hi) = cubes.iter().fold((f64::MAX, f64::MIN), |(lo, hi), c| {
        (lo.min(c[2]), hi.max(c[2]))
    });
    assert!((z_hi - z_lo - 2.5).abs() < 1e-6, "layers {z_lo}..{z_hi} mm");
    for layer in [z_lo, z_hi] {
        let ring: Vec<&[f64; 3]> = cubes.iter().filter(|c| c[2] == layer).collect();
        let n = ring.len() as f64;
        let centre = [0, 1].map(|d| ring.iter().map(|c| c[d]).sum::<f64>() / n);
        for c in ring {
            let r = (c[0] - centre[0]).hypot(c[1] - centre[1]);
            assert!(
                (r - 20.0).abs() < 0.1,
                "a node's marker at {c:?}, {r} mm from the ring's centre"
            );
        }
    }

    let (code, json) = replay_json(&bag);
    assert_eq!(code, Some(0), "{json}");
    assert_eq!(json["identical"], 1, "{json}");
    assert_eq!(json["skipped"], 0, "{json}");
}

/// The closed loop's sensors on a namespaced node (closed_loop_sensors.py): good scans and
/// temperatures are used, each kind of bad one is a WARN on /diagnostics naming the topic and
/// the reason until good data comes again; a scan in a frame known from /tf_static (the
/// tests' tf2_msgs, hence the built interfaces) is placed on the part. The node's recording
/// holds every message the sensors sent (the bad ones too, the welder's arc faults
/// included), `waam bag info` lists their topics and `waam replay` re-plans the recorded part
/// identically, passing over the measurements.
#[test]
fn rclpy_sensors_warn_on_bad_data_and_their_measurements_are_recorded() {
    let Some((_dir, bag)) = recorded_script_run("closed_loop_sensors.py", "sensors") else {
        return;
    };
    assert_bag_lists(
        &bag,
        &[
            "/cellX/waam_planner/scan",
            "/cellX/waam_planner/temperature",
            "/cellX/waam_planner/thermal_image",
            "/cellX/waam_planner/arc_fault",
        ],
    );

    let recording = waam_rosbag::Bag::open(&bag).unwrap();
    // The arc faults, the late one too.
    let faults: Vec<waam_rosmsg::std_msgs::Header> = recording.decode().unwrap();
    assert!(faults.len() >= 2 && faults.iter().all(|h| h.frame_id == "welder"));
    let temperatures: Vec<waam_rosmsg::sensor_msgs::Temperature> = recording.decode().unwrap();
    let celsius: Vec<f64> = temperatures.iter().map(|t| t.temperature).collect();
    assert!(celsius.contains(&650.0), "{celsius:?}");
    assert!(
        celsius.contains(&5000.0),
        "the implausible one is recorded too"
    );
    assert!(
        celsius.iter().any(|c| c.is_nan()),
        "the NaN one is recorded too"
    );
    let scans: Vec<waam_rosmsg::sensor_msgs::PointCloud2> = recording.decode().unwrap();
    assert!(scans.iter().any(|s| s.header.frame_id == "scanner_link"));
    // The transforms the node received are recorded too: the fixture scanner's mount.
    let frames: Vec<waam_rosmsg::tf2_msgs::TFMessage> = recording.decode().unwrap();
    assert!(
        frames
            .iter()
            .flat_map(|f| &f.transforms)
            .any(|t| t.child_frame_id == "fixture_scanner"),
        "the received /tf_static is recorded"
    );
    let good = scans
        .iter()
        .filter(|s| s.header.frame_id == "part" && s.width == 5)
        .count();
    assert!(good >= 6, "{good} good scans recorded, 6 or more sent");

    let (code, json) = replay_json(&bag);
    assert_eq!(code, Some(0), "{json}");
    assert_eq!(json["identical"], 1, "{json}");
}

/// The closed loop fed over DDS (#31, closed_loop.py): a namespaced dry run with
/// `closed_loop.enabled`, rclpy publishing while the arc is on what the pyrometer of a cell with
/// 25 % lower heat losses reads (computed here); at the weld-path boundary the `replanned`
/// status counts the readings used and a fitted loss factor below 0.9, the windowed wall still
/// to come is re-planned and the new plan published, the execution succeeds, and the recording
/// holds the temperatures, that status and the new plan.
#[test]
fn rclpy_sensor_readings_reach_the_closed_loop_and_its_decision_is_recorded() {
    let Some(python) = interfaces_python() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let bag = dir.path().join("closed-loop");
    let truth = dir.path().join("truth.json");
    std::fs::write(&truth, lower_loss_pyrometer().to_string()).unwrap();
    run_script_with(
        python,
        "closed_loop.py",
        &[bag.to_str().unwrap(), truth.to_str().unwrap()],
    );

    let recording = waam_rosbag::Bag::open(&bag).unwrap();
    assert!(
        recording.count("/cellY/waam_planner/temperature") > 0,
        "no temperature recorded"
    );
    let statuses = recording
        .decode_all::<waam_rosmsg::diagnostic_msgs::DiagnosticArray>()
        .unwrap();
    let replanned: Vec<_> = statuses
        .iter()
        .filter(|(_, topic, _)| *topic == "/cellY/waam_planner/status")
        .flat_map(|(_, _, a)| &a.status)
        .filter(|s| {
            s.values
                .iter()
                .any(|kv| kv.key == "state" && kv.value == "replanned")
        })
        .collect();
    assert!(!replanned.is_empty(), "no replanned status recorded");
    let value = |key: &str| {
        replanned[0]
            .values
            .iter()
            .find(|kv| kv.key == key)
            .unwrap_or_else(|| panic!("no {key} in {:?}", replanned[0]))
            .value
            .clone()
    };
    assert!(value("readings_used").parse::<u64>().unwrap() > 0);
    assert!(value("loss_factor").parse::<f64>().unwrap() < 0.9);
    assert_eq!(value("reason"), "replan");
    let plans: Vec<waam_rosmsg::waam_interfaces::WeldPlan> = recording.decode().unwrap();
    assert!(plans.len() >= 2, "{} weld plans recorded", plans.len());
    assert_ne!(plans[0].fragments, plans.last().unwrap().fragments);
    // `waam replay` makes each decision again from the recorded temperatures: the same
    // readings, estimate and plan.
    let json = decisions_replayed_identically(&bag);
    assert_eq!(json["decisions_identical"], replanned.len(), "{json}");
    assert_eq!(json["decisions"][0]["recorded_reason"], "replan", "{json}");
    assert_eq!(
        json["decisions"][0]["readings"].as_u64().unwrap(),
        value("readings_used").parse::<u64>().unwrap()
            + value("readings_ignored").parse::<u64>().unwrap(),
        "{json}"
    );
}

/// The simulated cell as a node (#31, sim_cell_node.py): `waam sim-cell --node
/// --thermal-camera` publishes the true cell's temperatures, thermal images and scans for a
/// namespaced dry run with the closed loop on, which re-plans from them; rclpy only sends the
/// part and the goal. The node's recording replays its decisions identically (the images
/// re-fed from it).
#[test]
fn rclpy_simulated_cell_node_feeds_the_closed_loop() {
    let Some((_dir, bag)) = recorded_script_run("sim_cell_node.py", "sim-cell") else {
        return;
    };
    // `waam replay` makes each decision again from the recorded readings. (The scans come
    // after a boundary — a layer spans both walls, so it is finished late — and so reach
    // no decision here; the estimate and the re-plan do not use them.)
    let recording = waam_rosbag::Bag::open(&bag).unwrap();
    assert!(
        recording.count("/cellZ/waam_planner/scan") > 0,
        "no scan recorded"
    );
    assert!(
        recording.count("/cellZ/waam_planner/thermal_image") > 0,
        "no thermal image recorded"
    );
    let json = decisions_replayed_identically(&bag);
    assert!(json["decisions_identical"].as_u64().unwrap() >= 1, "{json}");
}

/// Wire feeds revised while the arc is on (#31, sim_cell_spiral.py): a square tube welded in
/// one weld path that climbs its four layers, beside `waam sim-cell --node` with beads 10 %
/// low. The scans of the layers it finishes revise the feeds still to come, its top ends
/// within 0.5 mm of nominal, and `waam replay` makes every revision again from the recording.
#[test]
fn rclpy_simulated_cell_scans_revise_the_wire_feeds_of_a_spiral_while_the_arc_is_on() {
    let Some((_dir, bag)) = recorded_script_run("sim_cell_spiral.py", "spiral") else {
        return;
    };
    let json = decisions_replayed_identically(&bag);
    let finished: Vec<_> = json["decisions"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|d| d["recorded_decision"] == "finished")
        .collect();
    assert_eq!(finished.len(), 1, "{json}");
    assert!(
        finished[0]["feed_revisions"].as_u64().unwrap() >= 1,
        "{json}"
    );
    assert_eq!(finished[0]["verdict"], "identical", "{json}");
}

/// An arc fault from the simulated cell's welder (#31, sim_cell_fault.py): `waam sim-cell
/// --node` with TRUTH.yaml's `cut_short` publishes the fault halfway through the first weld
/// path; the namespaced dry run stops that weld path, re-plans the rest (`reason: fault`) and
/// completes the part. The fault is in the node's recording and its decisions replay
/// identically.
#[test]
fn rclpy_simulated_cell_arc_fault_cuts_a_weld_path_short_and_the_rest_is_re_planned() {
    let Some((_dir, bag)) = recorded_script_run("sim_cell_fault.py", "fault") else {
        return;
    };
    let recording = waam_rosbag::Bag::open(&bag).unwrap();
    assert_eq!(recording.count("/cellF/waam_planner/arc_fault"), 1);
    let json = decisions_replayed_identically(&bag);
    assert!(json["decisions_identical"].as_u64().unwrap() >= 1, "{json}");
}

/// What the pyrometer of a cell with 25 % lower heat losses than twin-walls' model reads on
/// the first weld path of the plan `waam plan` makes (the node's, as the script checks): each
/// deposit's true temperature at its end, in weld order, welded when the dry run's robot (the
/// bundled cell) makes it, as `crates/ros/tests/closed_loop.rs` computes it.
fn lower_loss_pyrometer() -> serde_json::Value {
    let path = repo().join("tests/data/twin-walls.yaml");
    let out = crate::common::run::waam()
        .args(["plan", "--json", "-q"])
        .arg(&path)
        .output()
        .unwrap();
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let fragments: Vec<Vec<waam_part::Block>> =
        serde_json::from_value(json["plan"]["fragments"].clone()).unwrap();
    let first = &fragments[0];
    let part = waam_part::Part::parse(&std::fs::read_to_string(&path).unwrap()).unwrap();
    // The first weld path's deposit times on the robot's trajectory.
    let chosen = waam_pipeline::ChosenPlan {
        fragments: fragments
            .iter()
            .map(|f| f.iter().map(|&b| part.index_of(b).unwrap()).collect())
            .collect(),
        stats: Default::default(),
        proven: false,
        worst_margin_s: f64::NAN,
    };
    let times = waam_pipeline::Cell::bundled()
        .motion(part.clone(), chosen)
        .unwrap()
        .toolpath
        .executed_times();
    let (starts, off) = (&times.deposits_s[0], times.arc_off_s[0]);
    let truth = waam_cell::estimate::counting_part(
        &part,
        waam_cell::estimate::scaled(part.thermal, 0.75, 1.0),
    );
    let graph = waam_part::graph::WeldGraph::new(&truth);
    let model = waam_thermal::ThermalModel::new(&truth, &graph);
    let mut sim = waam_thermal::Simulation::new(&model).with_threads(1);
    let deposits: Vec<serde_json::Value> = first
        .iter()
        .enumerate()
        .map(|(j, &block)| {
            let b = truth.index_of(block).unwrap();
            let step = |t: f64| ((t - starts[0]) / model.dt).round() as u64;
            let end = starts.get(j + 1).copied().unwrap_or(off);
            sim.deposit_at(b, j == 0, None, step(starts[j])).unwrap();
            sim.run_to(step(end), false).unwrap();
            let celsius = sim.temperatures().find(|&(o, _)| o == b).unwrap().1;
            serde_json::json!({"block": block, "celsius": celsius})
        })
        .collect();
    serde_json::Value::Array(deposits)
}

/// Two nodes side by side (`--ros-args -r __ns:=/cell1`, `-r __ns:=/cell2 -r __node:=...`),
/// parameters listed, read, described, refused and set through the standard services.
#[test]
fn rclpy_two_cells_and_parameters_through_the_standard_services() {
    run_script("cells_and_params.py", &[]);
}

#[test]
fn rclpy_receives_dry_run_joint_states() {
    run_script("dry_run.py", &[]);
}

/// `~/execute` of a plan made through `~/plan`, against a FollowJointTrajectory controller in
/// rclpy that checks each goal's mapped joint names and tolerances: the goals are the
/// trajectory, no goal boundary falls inside an arc-on stretch of the published weld plan,
/// feedback per goal chunk, cancel = controller goal cancelled and arc off (execute_fjt.py).
#[test]
fn rclpy_execute_action_runs_goals_split_only_where_the_arc_is_off() {
    if let Some(python) = interfaces_python() {
        run_script_with(python, "execute_fjt.py", &[]);
    }
}

// ---------------------------------------------------------------------------------------
// Rust peers: the raw weld_plan bytes, and a FollowJointTrajectory action server.
// These run in this process on loopback-only discovery with a domain id of their own.

mod rust_peer {
    use std::process::{Child, Stdio};
    use std::time::{Duration, Instant};

    use ros2_client::dds::rustdds::{
        self, no_key::DeserializerAdapter, DomainParticipantBuilder, RepresentationIdentifier,
        TopicKind,
    };
    use ros2_client::{Context, NodeName, NodeOptions, QosProfile};
    use waam_ros::node::ros::{DiscoveryRange, RosEnv};

    /// `waam ARGS` on `domain`, loopback-only, its output captured.
    pub fn start(args: &[&str], domain: u16) -> Child {
        crate::common::run::waam()
            .args(args)
            .current_dir(super::repo())
            .env("ROS_DOMAIN_ID", domain.to_string())
            .env("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
            .env_remove("ROS_LOCALHOST_ONLY")
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("cannot start waam")
    }

    /// Waits (bounded) for `child` to exit; its status and output.
    pub fn finish(mut child: Child, limit: Duration) -> (bool, String) {
        let start = Instant::now();
        while child.try_wait().unwrap().is_none() {
            if start.elapsed() > limit {
                let _ = child.kill();
                break;
            }
            std::thread::sleep(Duration::from_millis(50));
        }
        let out = child.wait_with_output().unwrap();
        let text = format!(
            "{}{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
        (out.status.success(), text)
    }

    pub fn context(domain: u16) -> Context {
        RosEnv {
            domain_id: domain,
            range: DiscoveryRange::Localhost,
        }
        .context()
        .unwrap()
    }

    pub fn node(context: &Context, name: &str) -> ros2_client::Node {
        let mut node = context
            .new_node(NodeName::new("/", name).unwrap(), NodeOptions::new())
            .unwrap();
        let spinner = node.spinner().unwrap();
        std::thread::spawn(move || futures::executor::block_on(spinner.spin()));
        node
    }

    /// The first message on `sub` within `limit` (polling; never blocks for good).
    pub fn take_within<M: 'static + serde::de::DeserializeOwned>(
        sub: &ros2_client::Subscription<M>,
        limit: Duration,
        what: &str,
    ) -> M {
        let start = Instant::now();
        loop {
            if let Ok(Some((msg, _))) = sub.take() {
                return msg;
            }
            assert!(start.elapsed() < limit, "no {what} within {limit:?}");
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// A sample's bytes exactly as they came over the wire (with the encapsulation header).
    pub struct RawCdr(pub Vec<u8>);
    pub struct RawAdapter;
    #[derive(Clone)]
    pub struct RawDecoder;

    #[derive(Debug)]
    pub struct NoError;
    impl std::fmt::Display for NoError {
        fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
            f.write_str("unsupported encoding")
        }
    }
    impl std::error::Error for NoError {}

    impl DeserializerAdapter<RawCdr> for RawAdapter {
        type Error = NoError;
        type Decoded = RawCdr;
        fn supported_encodings() -> &'static [RepresentationIdentifier] {
            &[
                RepresentationIdentifier::CDR_LE,
                RepresentationIdentifier::CDR_BE,
            ]
        }
        fn transform_decoded(decoded: RawCdr) -> RawCdr {
            decoded
        }
    }
    impl rustdds::no_key::DefaultDecoder<RawCdr> for RawAdapter {
        type Decoder = RawDecoder;
        const DECODER: RawDecoder = RawDecoder;
    }
    impl<'de> rustdds::no_key::Decode<'de, RawCdr> for RawDecoder {
        type Error = NoError;
        fn decode_bytes(
            self,
            input: &'de [u8],
            encoding: RepresentationIdentifier,
        ) -> Result<RawCdr, NoError> {
            let header = if encoding == RepresentationIdentifier::CDR_LE {
                [0u8, 1, 0, 0]
            } else if encoding == RepresentationIdentifier::CDR_BE {
                [0u8, 0, 0, 0]
            } else {
                return Err(NoError);
            };
            Ok(RawCdr([&header[..], input].concat()))
        }
    }

    /// The first sample on a latched (Reliable, TransientLocal) topic, as raw bytes.
    pub fn take_raw(domain: u16, dds_topic: &str, dds_type: &str, limit: Duration) -> Vec<u8> {
        let participant = DomainParticipantBuilder::new(domain)
            .with_only_networks([std::net::IpAddr::V4(std::net::Ipv4Addr::LOCALHOST)])
            .build()
            .unwrap();
        let qos: rustdds::QosPolicies = QosProfile::publisher_default()
            .durability(ros2_client::qos::Durability::TransientLocal)
            .history(ros2_client::qos::History::KeepLast { depth: 1 })
            .into();
        let topic = participant
            .create_topic(dds_topic.into(), dds_type.into(), &qos, TopicKind::NoKey)
            .unwrap();
        let subscriber = participant.create_subscriber(&qos).unwrap();
        let reader = subscriber
            .create_simple_datareader_no_key::<RawCdr, RawAdapter>(&topic, Some(qos))
            .unwrap();
        let start = Instant::now();
        loop {
            if let Ok(Some(sample)) = reader.try_take_one() {
                return sample.into_value().0;
            }
            assert!(
                start.elapsed() < limit,
                "no sample on {dds_topic} within {limit:?}"
            );
            std::thread::sleep(Duration::from_millis(20));
        }
    }
}

/// The weld_plan's raw CDR bytes, as a peer receives them, decode against the interface
/// package's `.msg` files with an independent decoder (tests/ros/msgdef.py), and agree with
/// the PoseArray and the part.
#[test]
fn weld_plan_raw_cdr_decodes_against_the_msg_files() {
    use std::time::Duration;
    let Some(python) = ros_python() else { return };
    let domain = fresh_domain_id();
    let child = rust_peer::start(
        &["publish", "config/parts/s1-wall.yaml", "--linger", "20"],
        domain,
    );
    let raw = rust_peer::take_raw(
        domain,
        "rt/waam_planner/plan/weld_plan",
        "waam_interfaces::msg::dds_::WeldPlan_",
        Duration::from_secs(60),
    );
    let context = rust_peer::context(domain);
    let mut node = rust_peer::node(&context, "weld_plan_check");
    let topic = node
        .create_topic(
            &ros2_client::Name::new("/waam_planner/plan", "poses").unwrap(),
            ros2_client::MessageTypeName::new("geometry_msgs", "PoseArray"),
            &waam_ros::node::io::latched_qos(),
        )
        .unwrap();
    let poses = node
        .create_subscription::<waam_rosmsg::geometry_msgs::PoseArray>(&topic, None)
        .unwrap();
    let pose_array = rust_peer::take_within(&poses, Duration::from_secs(60), "PoseArray");
    let (_, log) = rust_peer::finish(child, Duration::from_secs(60));

    let file = tempfile::NamedTempFile::new().unwrap();
    std::fs::write(file.path(), &raw).unwrap();
    let out = Command::new(&python)
        .arg(repo().join("tests/ros/decode_cdr.py"))
        .arg(file.path())
        .arg("waam_interfaces/msg/WeldPlan")
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "the weld_plan bytes do not decode against ros/waam_interfaces/msg: {}\nwaam log:\n{log}",
        String::from_utf8_lossy(&out.stderr)
    );
    let plan: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(plan["part_name"], "s1-wall");
    assert_eq!(plan["block_pitch"].as_f64(), Some(0.006));
    let fragments = plan["fragments"].as_array().unwrap();
    let blocks: usize = fragments
        .iter()
        .map(|f| f["blocks"].as_array().unwrap().len())
        .sum();
    assert_eq!(blocks, 12, "s1-wall has 12 blocks");
    let points = plan["points"].as_array().unwrap();
    assert_eq!(
        points.len(),
        pose_array.poses.len(),
        "one pose per toolpath point"
    );
    for (point, pose) in points.iter().zip(&pose_array.poses) {
        let x = point["pose"]["position"]["x"].as_f64().unwrap();
        assert!((x - pose.position.x).abs() < 1e-12);
    }
    let kind_count = |k: u64| points.iter().filter(|p| p["kind"] == k).count();
    assert_eq!(
        kind_count(1),
        fragments.len(),
        "one ARC_ON point per fragment"
    );
    assert_eq!(
        kind_count(3),
        fragments.len(),
        "one ARC_OFF point per fragment"
    );
    let times: Vec<f64> = points
        .iter()
        .map(|p| {
            p["time_from_start"]["sec"].as_f64().unwrap()
                + p["time_from_start"]["nanosec"].as_f64().unwrap() * 1e-9
        })
        .collect();
    assert!(
        times.windows(2).all(|w| w[1] >= w[0]),
        "toolpath times go back"
    );
    assert_eq!(plan["header"]["frame_id"], pose_array.header.frame_id);
}

/// `/tf_static`, as a peer receives its raw bytes, decodes against tf2_msgs/TFMessage.msg
/// (no tf2_msgs wheel exists for rclpy) and ties the robot's base link (the frame of every
/// plan message) to the part frame (the heat cloud's, at the plate pose) and the tip link to
/// the TCP.
#[test]
fn tf_static_ties_the_base_to_the_part_and_the_tip_to_the_tcp() {
    use std::time::Duration;
    use waam_motion::robot::{Robot, TcpChoice};
    use waam_motion::toolpath::ProcessSettings;
    let Some(python) = ros_python() else { return };
    let domain = fresh_domain_id();
    let child = rust_peer::start(&["node", "--ros-args", "-r", "__ns:=/cell7"], domain);
    let raw = rust_peer::take_raw(
        domain,
        "rt/tf_static",
        "tf2_msgs::msg::dds_::TFMessage_",
        Duration::from_secs(30),
    );
    let mut child = child;
    let _ = child.kill();
    let _ = child.wait();
    let file = tempfile::NamedTempFile::new().unwrap();
    std::fs::write(file.path(), &raw).unwrap();
    let out = Command::new(&python)
        .arg(repo().join("tests/ros/decode_cdr.py"))
        .arg(file.path())
        .arg("tf2_msgs/msg/TFMessage")
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "the /tf_static bytes do not decode: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let tf: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let settings = ProcessSettings::default();
    let robot = Robot::from_urdf(
        waam_pipeline::BUNDLED_URDF,
        None,
        TcpChoice {
            explicit: None,
            default: settings.tcp.isometry(),
        },
    )
    .unwrap();
    let find = |child: &str| -> serde_json::Value {
        tf["transforms"]
            .as_array()
            .unwrap()
            .iter()
            .find(|t| t["child_frame_id"] == child)
            .unwrap_or_else(|| panic!("no transform to {child} in {tf}"))
            .clone()
    };
    let xyz = |t: &serde_json::Value| -> Vec<f64> {
        let v = &t["transform"]["translation"];
        ["x", "y", "z"]
            .iter()
            .map(|k| v[k].as_f64().unwrap())
            .collect()
    };
    let part = find(waam_messages::planning::PART_FRAME);
    assert_eq!(part["header"]["frame_id"], robot.base_link.as_str());
    assert_eq!(xyz(&part), settings.plate.position_m.to_vec());
    assert_eq!(part["transform"]["rotation"]["w"].as_f64(), Some(1.0));
    let tcp = find(waam_ros::node::frames::TCP_FRAME);
    assert_eq!(tcp["header"]["frame_id"], robot.tip_link.as_str());
    let expected: Vec<f64> = robot.tcp.translation.vector.iter().copied().collect();
    assert_eq!(xyz(&tcp), expected);
}

/// `~/plan` (waam_interfaces/action/PlanPart) from an action client in this test: a goal
/// gets feedback and a result with the plan; a long goal is cancelled within a second and the
/// node answers the next goal; a goal without a part ends at once with the reason.
#[test]
fn plan_action_gives_feedback_and_a_result_and_cancels_within_a_second() {
    use std::time::{Duration, Instant};

    use ros2_client::action::{ActionClientQosPolicies, GoalStatusEnum};
    use ros2_client::{ActionTypeName, Name, QosProfile, ServiceMapping};
    use waam_ros::node::fjt::{TriggerRequest, TriggerResponse};
    use waam_ros::node::plan_action::{PlanPartFeedback, PlanPartGoal, PlanPartResult};

    if ros_python().is_none() {
        return;
    }
    let domain = fresh_domain_id();
    let child = rust_peer::start(&["node", "--ros-args", "-r", "__ns:=/cell3"], domain);
    let context = rust_peer::context(domain);
    let mut node = rust_peer::node(&context, "plan_client");
    let service =
        QosProfile::publisher_default().history(ros2_client::qos::History::KeepLast { depth: 10 });
    let client = node
        .create_action_client::<PlanPartGoal, PlanPartResult, PlanPartFeedback>(
            ServiceMapping::Enhanced,
            &Name::new("/cell3/waam_planner", "plan").unwrap(),
            &ActionTypeName::new("waam_interfaces", "PlanPart"),
            ActionClientQosPolicies {
                goal_service: service.clone(),
                result_service: service.clone(),
                cancel_service: service.clone(),
                feedback_subscription: service.clone(),
                status_subscription: service
                    .clone()
                    .durability(ros2_client::qos::Durability::TransientLocal)
                    .history(ros2_client::qos::History::KeepLast { depth: 1 }),
            },
        )
        .unwrap();
    let poll = |what: &str, limit: Duration, mut f: Box<dyn FnMut() -> bool + '_>| {
        let start = Instant::now();
        while !f() {
            assert!(start.elapsed() < limit, "{what}: nothing within {limit:?}");
            std::thread::sleep(Duration::from_millis(10));
        }
        start.elapsed()
    };
    let part =
        |name: &str| std::fs::read_to_string(repo().join("config/parts").join(name)).unwrap();
    // The goal service is discovered when a goal is answered: resend until then.
    let send = |goal: PlanPartGoal| {
        let start = Instant::now();
        loop {
            let (req, id) = client.send_goal(goal.clone()).unwrap();
            let until = Instant::now() + Duration::from_secs(2);
            while Instant::now() < until {
                if let Ok(Some(r)) = client.receive_goal_response(req) {
                    assert!(r.accepted);
                    return id;
                }
                std::thread::sleep(Duration::from_millis(10));
            }
            assert!(
                start.elapsed() < Duration::from_secs(30),
                "no answer to a goal"
            );
        }
    };
    let result = |id, limit: Duration| {
        let req = client.request_result(id).unwrap();
        let mut got = None;
        poll(
            "the result",
            limit,
            Box::new(|| {
                got = client.receive_result(req).ok().flatten();
                got.is_some()
            }),
        );
        got.unwrap()
    };

    // 1. A long part (a ring tower whose window no plan keeps: it plans until stopped) is
    //    cancelled after its first planning feedback.
    let long = send(PlanPartGoal {
        part_document: std::fs::read_to_string(repo().join("tests/data/endless-ring.yaml"))
            .unwrap(),
        timeout_s: 60.0,
        ..PlanPartGoal::default()
    });
    let mut feedback = Vec::new();
    poll(
        "planning feedback of the long goal",
        Duration::from_secs(60),
        Box::new(|| {
            while let Ok(Some(f)) = client.receive_feedback(long) {
                feedback.push(f);
            }
            feedback
                .iter()
                .any(|f| f.stage == "planning" && f.candidates > 0)
        }),
    );
    let cancel_sent = Instant::now();
    client.cancel_goal(long).unwrap();
    let (status, r) = result(long, Duration::from_secs(5));
    let took = cancel_sent.elapsed();
    assert_eq!(status, GoalStatusEnum::Canceled);
    assert_eq!(r.outcome, PlanPartResult::CANCELLED, "{}", r.reason);
    assert!(
        took < Duration::from_secs(1),
        "cancel answered after {took:?}"
    );
    eprintln!("cancel answered after {took:?}");

    // 2. The next goal: s1-wall, first feasible plan, k = 2, with feedback and the plan.
    let next = send(PlanPartGoal {
        part_document: part("s1-wall.yaml"),
        max_fragments: 2,
        first_feasible: true,
        ..PlanPartGoal::default()
    });
    let (status, r) = result(next, Duration::from_secs(60));
    assert_eq!(status, GoalStatusEnum::Succeeded, "{}", r.reason);
    assert_eq!(r.outcome, PlanPartResult::PLANNED);
    assert_eq!(r.plan.part_name, "s1-wall");
    let blocks: usize = r.plan.fragments.iter().map(|f| f.blocks.len()).sum();
    assert_eq!(blocks, 12);
    assert!(!r.plan.fragments.is_empty() && r.plan.fragments.len() <= 2);
    let mut stages = Vec::new();
    poll(
        "the last feedback of the second goal",
        Duration::from_secs(5),
        Box::new(|| {
            while let Ok(Some(f)) = client.receive_feedback(next) {
                stages.push((f.stage.clone(), f.best_margin_s, f.elapsed_s));
            }
            stages.iter().any(|s| s.0 == "planned")
        }),
    );
    let last = stages.iter().find(|s| s.0 == "planned").unwrap();
    assert_eq!(last.1, r.plan.worst_margin_s, "final feedback margin");
    assert!(last.2 > 0.0);

    // 3. A goal without a part ends at once with the reason.
    let empty = send(PlanPartGoal::default());
    let (status, r) = result(empty, Duration::from_secs(5));
    assert_eq!(status, GoalStatusEnum::Aborted);
    assert_eq!(r.outcome, PlanPartResult::BAD_INPUT);
    assert!(r.reason.contains("part_document"), "{}", r.reason);

    // 4. `~/stop` (std_srvs/Trigger) stops a long goal's planning too.
    let stop = node
        .create_client::<TriggerRequest, TriggerResponse>(
            ServiceMapping::Enhanced,
            &Name::new("/cell3/waam_planner", "stop").unwrap(),
            &ros2_client::ServiceTypeName::new("std_srvs", "Trigger"),
            service.clone(),
            service.clone(),
        )
        .unwrap();
    let long = send(PlanPartGoal {
        part_document: part("ex3-h-column.yaml"),
        timeout_s: 60.0,
        ..PlanPartGoal::default()
    });
    poll(
        "planning feedback of the second long goal",
        Duration::from_secs(60),
        Box::new(|| matches!(client.receive_feedback(long), Ok(Some(f)) if f.stage == "planning")),
    );
    // Until the service is discovered a request may go unheard: ask again after a second.
    let asked = Instant::now();
    let answer = 'ask: loop {
        assert!(
            asked.elapsed() < Duration::from_secs(30),
            "no answer of ~/stop"
        );
        stop.send_request(TriggerRequest::default()).unwrap();
        let until = Instant::now() + Duration::from_secs(1);
        while Instant::now() < until {
            // The first answer is that of the first request heard: the one that stopped.
            if let Ok(Some((_, r))) = stop.receive_response() {
                break 'ask r;
            }
            std::thread::sleep(Duration::from_millis(10));
        }
    };
    assert!(answer.success, "{}", answer.message);
    assert!(
        answer.message.contains("planning of part"),
        "{}",
        answer.message
    );
    let (status, r) = result(long, Duration::from_secs(2));
    assert_eq!(status, GoalStatusEnum::Canceled);
    assert!(r.reason.contains("~/stop"), "{}", r.reason);

    let mut child = child;
    let _ = child.kill();
    let _ = child.wait();
}

/// FollowJointTrajectory execution against a small action server in this test: the start
/// service is called first; goals carry the mapped joint names and the tolerances; only a
/// weld (one goal per fragment) may have more than `max_points_per_goal` points, the goals
/// together are the whole trajectory, each arc switch happens at a goal boundary, and
/// `~/arc_on` goes true/false once per fragment. (`rclpy_execute_action_...` checks that no
/// goal boundary falls inside a weld.)
#[test]
fn follow_joint_trajectory_goals_respect_the_cap_and_switch_the_arc_between_goals() {
    use std::sync::{Arc, Mutex};
    use std::time::{Duration, Instant};

    use ros2_client::action::ActionServerQosPolicies;
    use ros2_client::action::{GetResultResponse, SendGoalResponse};
    use ros2_client::action_msgs::GoalStatusEnum;
    use ros2_client::{ActionTypeName, MessageTypeName, Name, QosProfile, ServiceMapping};
    use waam_ros::node::fjt::{TriggerRequest, TriggerResponse};
    use waam_rosmsg::control_msgs::{
        FollowJointTrajectoryFeedback as Feedback, FollowJointTrajectoryGoal as Goal,
        FollowJointTrajectoryResult as FjtResult,
    };
    use waam_rosmsg::std_msgs::Bool;
    use waam_rosmsg::trajectory_msgs::JointTrajectory;

    if ros_python().is_none() {
        return;
    }
    const CAP: usize = 5;
    let domain = fresh_domain_id();
    let context = rust_peer::context(domain);
    let mut node = rust_peer::node(&context, "test_controller");
    let service =
        QosProfile::publisher_default().history(ros2_client::qos::History::KeepLast { depth: 10 });
    let server = node
        .create_action_server::<Goal, FjtResult, Feedback>(
            ServiceMapping::Enhanced,
            &Name::new("/test_controller", "follow_joint_trajectory").unwrap(),
            &ActionTypeName::new("control_msgs", "FollowJointTrajectory"),
            ActionServerQosPolicies {
                goal_service: service.clone(),
                result_service: service.clone(),
                cancel_service: service.clone(),
                feedback_publisher: service.clone(),
                status_publisher: service
                    .clone()
                    .durability(ros2_client::qos::Durability::TransientLocal)
                    .history(ros2_client::qos::History::KeepLast { depth: 1 }),
            },
        )
        .unwrap();
    let arc_topic = node
        .create_topic(
            &Name::new("/waam_planner", "arc_on").unwrap(),
            MessageTypeName::new("std_msgs", "Bool"),
            &service,
        )
        .unwrap();
    let arc = node.create_subscription::<Bool>(&arc_topic, None).unwrap();
    // MotoROS2's "start trajectory mode" (std_srvs/Trigger), as fjt.params.yaml names it.
    let start_mode = node
        .create_server::<TriggerRequest, TriggerResponse>(
            ServiceMapping::Enhanced,
            &Name::new("/test_controller", "start_traj_mode").unwrap(),
            &ros2_client::ServiceTypeName::new("std_srvs", "Trigger"),
            service.clone(),
            service.clone(),
        )
        .unwrap();
    let traj_topic = node
        .create_topic(
            &Name::new("/waam_planner/plan", "joint_trajectory").unwrap(),
            MessageTypeName::new("trajectory_msgs", "JointTrajectory"),
            &waam_ros::node::io::latched_qos(),
        )
        .unwrap();
    let trajectory_sub = node
        .create_subscription::<JointTrajectory>(&traj_topic, None)
        .unwrap();

    /// What the server saw, in order: goals (their trajectories) and arc switches (with the
    /// number of goals received before).
    #[derive(Debug)]
    enum Seen {
        Goal(JointTrajectory),
        Arc(bool),
        StartMode,
    }
    // Each goal's tolerances: (path, goal, goal time).
    let mut tolerances = Vec::new();
    let seen = Arc::new(Mutex::new(Vec::<Seen>::new()));

    let child = rust_peer::start(
        &[
            "publish",
            "config/parts/s1-wall.yaml",
            "--params",
            "tests/ros/fjt.params.yaml",
            "--execute",
            "--wait-for-subscriber",
            "60",
            "--linger",
            "0",
        ],
        domain,
    );
    let start = Instant::now();
    let mut pending_results = Vec::new();
    let mut goals_done = Vec::new();
    let mut child = Some(child);
    let mut log = String::new();
    let mut exit_ok = false;
    let mut trajectory = None;
    while start.elapsed() < Duration::from_secs(180) {
        if let Ok(Some((t, _))) = trajectory_sub.take() {
            trajectory = Some(t);
        }
        if let Ok(Some((req, _))) = start_mode.receive_request() {
            seen.lock().unwrap().push(Seen::StartMode);
            start_mode
                .send_response(
                    req,
                    TriggerResponse {
                        success: true,
                        message: String::new(),
                    },
                )
                .unwrap();
        }
        if let Ok(Some((req, goal))) = server.receive_goal() {
            tolerances.push((
                goal.goal.path_tolerance.clone(),
                goal.goal.goal_tolerance.clone(),
                goal.goal.goal_time_tolerance.as_secs_f64(),
            ));
            seen.lock()
                .unwrap()
                .push(Seen::Goal(goal.goal.trajectory.clone()));
            server
                .send_goal_response(
                    req,
                    SendGoalResponse {
                        accepted: true,
                        stamp: ros2_client::builtin_interfaces::Time::now(),
                    },
                )
                .unwrap();
            goals_done.push(goal.goal_id);
        }
        if let Ok(Some((req, request))) = server.receive_result_request() {
            pending_results.push((req, request.goal_id));
        }
        // Answer result requests of goals we have (a goal "executes" instantly).
        pending_results.retain(|(req, goal_id)| {
            if goals_done.contains(goal_id) {
                server
                    .send_result(
                        *req,
                        GetResultResponse {
                            status: GoalStatusEnum::Succeeded,
                            result: FjtResult::default(),
                        },
                    )
                    .unwrap();
                false
            } else {
                true
            }
        });
        while let Ok(Some((msg, _))) = arc.take() {
            seen.lock().unwrap().push(Seen::Arc(msg.data));
        }
        if child.as_mut().unwrap().try_wait().unwrap().is_some() {
            let (ok, text) = rust_peer::finish(child.take().unwrap(), Duration::from_secs(1));
            exit_ok = ok;
            log = text;
            break;
        }
        std::thread::sleep(Duration::from_millis(2));
    }
    // Late arc messages (the last arc-off) may still be on their way.
    let settle = Instant::now();
    while settle.elapsed() < Duration::from_secs(2) {
        while let Ok(Some((msg, _))) = arc.take() {
            seen.lock().unwrap().push(Seen::Arc(msg.data));
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    if let Some(c) = child {
        let (_, text) = rust_peer::finish(c, Duration::from_secs(1));
        panic!("waam publish --execute did not finish in time:\n{text}");
    }
    assert!(exit_ok, "waam publish --execute failed:\n{log}");
    if trajectory.is_none() {
        trajectory = Some(rust_peer::take_within(
            &trajectory_sub,
            Duration::from_secs(5),
            "joint trajectory",
        ));
    }
    let trajectory = trajectory.unwrap();
    let seen = seen.lock().unwrap();

    // Goals: at most CAP points, the URDF's joints, increasing times from > 0, and together
    // exactly the whole trajectory.
    let goals: Vec<&JointTrajectory> = seen
        .iter()
        .filter_map(|s| match s {
            Seen::Goal(g) => Some(g),
            _ => None,
        })
        .collect();
    assert!(
        goals.len() > 1,
        "expected several goals, got {}",
        goals.len()
    );
    let mut all_points = Vec::new();
    let mut over_cap = 0;
    for (i, g) in goals.iter().enumerate() {
        assert!(!g.points.is_empty(), "goal {i} has no points");
        if g.points.len() > CAP {
            over_cap += 1; // a weld, sent whole
        }
        // The controller's names (execution.joint_names), in the URDF's joint order.
        let mapped: Vec<String> = (1..=trajectory.joint_names.len())
            .map(|j| format!("group_1/joint_{j}"))
            .collect();
        assert_eq!(g.joint_names, mapped, "goal {i}");
        let (path, at_end, time) = &tolerances[i];
        for (tolerance, expected) in [(path, 0.1), (at_end, 0.01)] {
            let names: Vec<&String> = tolerance.iter().map(|t| &t.name).collect();
            assert_eq!(names, mapped.iter().collect::<Vec<_>>(), "goal {i}");
            assert!(tolerance.iter().all(|t| t.position == expected), "goal {i}");
        }
        assert_eq!(*time, 0.5, "goal {i}");
        let t: Vec<f64> = g
            .points
            .iter()
            .map(|p| p.time_from_start.as_secs_f64())
            .collect();
        assert!(t[0] > 0.0, "goal {i} starts at time {}", t[0]);
        assert!(
            t.windows(2).all(|w| w[1] > w[0]),
            "goal {i}: times not increasing"
        );
        let last = g.points.last().unwrap();
        assert!(
            last.velocities.iter().all(|v| *v == 0.0),
            "goal {i} does not end at rest"
        );
        all_points.extend(g.points.iter().map(|p| p.positions.clone()));
    }
    let whole: Vec<Vec<f64>> = trajectory
        .points
        .iter()
        .map(|p| p.positions.clone())
        .collect();
    assert_eq!(
        all_points, whole,
        "the goals are not the trajectory, in order, once"
    );

    // Arc: true/false alternating, once per fragment (s1-wall plans into 2 fragments or
    // fewer), each switch after at least one goal, never two switches without a goal between.
    let arcs: Vec<bool> = seen
        .iter()
        .filter_map(|s| match s {
            Seen::Arc(on) => Some(*on),
            _ => None,
        })
        .collect();
    assert!(
        !arcs.is_empty() && arcs.len() % 2 == 0,
        "arc sequence {arcs:?}"
    );
    for (i, on) in arcs.iter().enumerate() {
        assert_eq!(*on, i % 2 == 0, "arc sequence {arcs:?}");
    }
    assert!(
        over_cap <= arcs.len() / 2,
        "{over_cap} goals over the cap of {CAP} points, but only {} welds",
        arcs.len() / 2
    );
    assert!(
        matches!(seen.first(), Some(Seen::StartMode)),
        "the start service was not called before the first goal"
    );
    assert_eq!(
        seen.iter().filter(|s| matches!(s, Seen::StartMode)).count(),
        1,
        "one start call per plan"
    );
    let first_arc = seen.iter().position(|s| matches!(s, Seen::Arc(_))).unwrap();
    assert!(first_arc > 0, "the arc came on before any goal");
    assert!(
        log.contains("execution finished"),
        "no end of execution in the log:\n{log}"
    );
}

/// A box mesh sent to `waam node --record` is voxelized, planned and recorded with the
/// node's voxelizing settings; `waam replay` voxelizes it again and finds the same plan,
/// while a doctored recording (the mesh stretched) is reported as a difference. The
/// recording also holds the planner's verdict on every candidate and the motion.
#[test]
fn a_mesh_the_node_recorded_replays_identically() {
    use std::time::{Duration, Instant};

    use waam_messages::topics;
    use waam_rosbag::Bag;
    use waam_rosmsg::geometry_msgs::Point;
    use waam_rosmsg::shape_msgs::{Mesh, MeshTriangle};
    use waam_rosmsg::waam_interfaces::{PlanCandidate, WeldPlan};
    use waam_rosmsg::{from_cdr, to_cdr};

    if ros_python().is_none() {
        return;
    }
    // A closed 24 x 12 x 5 mm box (metres), outward-facing: 16 blocks at 6 x 6 x 2.5 mm.
    let corner = |i: usize| Point {
        x: (i & 1) as f64 * 0.024,
        y: ((i >> 1) & 1) as f64 * 0.012,
        z: ((i >> 2) & 1) as f64 * 0.005,
    };
    let faces = [
        [0, 2, 3, 1],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 4, 6, 2],
        [1, 3, 7, 5],
    ];
    let mesh = Mesh {
        vertices: (0..8).map(corner).collect(),
        triangles: faces
            .iter()
            .flat_map(|&[a, b, c, d]| [[a, b, c], [a, c, d]])
            .map(|vertex_indices| MeshTriangle { vertex_indices })
            .collect(),
    };

    let dir = tempfile::tempdir().unwrap();
    let bag_dir = dir.path().join("session");
    let domain = fresh_domain_id();
    let child = rust_peer::start(&["node", "--record", bag_dir.to_str().unwrap()], domain);
    let context = rust_peer::context(domain);
    let mut node = rust_peer::node(&context, "mesh_sender");
    let mesh_topic = node
        .create_topic(
            &ros2_client::Name::new("/waam_planner", "part_mesh").unwrap(),
            ros2_client::MessageTypeName::new("shape_msgs", "Mesh"),
            &waam_ros::node::io::input_qos(),
        )
        .unwrap();
    let sender = node.create_publisher::<Mesh>(&mesh_topic, None).unwrap();
    let plan_topic = node
        .create_topic(
            &ros2_client::Name::new("/waam_planner/plan", "weld_plan").unwrap(),
            ros2_client::MessageTypeName::new("waam_interfaces", "WeldPlan"),
            &waam_ros::node::io::latched_qos(),
        )
        .unwrap();
    let plans = node
        .create_subscription::<WeldPlan>(&plan_topic, None)
        .unwrap();
    let start = Instant::now();
    while sender.get_subscription_count(&node) == 0 {
        assert!(
            start.elapsed() < Duration::from_secs(30),
            "the node never subscribed to ~/part_mesh"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
    sender.publish(mesh.clone()).unwrap();
    let plan = rust_peer::take_within(&plans, Duration::from_secs(120), "WeldPlan");
    let blocks: usize = plan.fragments.iter().map(|f| f.blocks.len()).sum();
    assert_eq!(blocks, 16, "the box voxelizes to 16 blocks");
    // Stop the node as Ctrl-C would, so it closes the recording.
    let _ = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status();
    let (ok, log) = rust_peer::finish(child, Duration::from_secs(30));
    assert!(ok, "the node did not stop cleanly on SIGINT:\n{log}");

    let bag = Bag::open(&bag_dir).unwrap();
    for topic in [
        topics::PART_MESH,
        topics::JOINT_TRAJECTORY,
        topics::POSES,
        topics::PATH,
        topics::MARKERS,
        topics::WELD_PLAN,
    ] {
        assert_eq!(bag.count(topic), 1, "{topic} recorded once\n{log}");
    }
    let candidates: Vec<PlanCandidate> = bag.decode::<PlanCandidate>().unwrap();
    assert_eq!(
        candidates.len() as u64,
        plan.statistics.candidates,
        "one PlanCandidate per candidate the planner judged"
    );
    assert_eq!(
        candidates
            .iter()
            .filter(|c| c.verdict == PlanCandidate::FEASIBLE)
            .count() as u64,
        plan.statistics.feasible
    );

    let (code, json) = replay_json(&bag_dir);
    assert_eq!(code, Some(0), "{json}");
    assert_eq!(json["identical"], 1, "{json}");
    assert_eq!(json["skipped"], 0, "{json}");

    // The same session with the mesh half again as long: 24 blocks, not the recorded 16.
    let doctored = dir.path().join("doctored");
    common::run::copy_bag(&bag_dir, &doctored, |topic, data| {
        if topic != topics::PART_MESH {
            return Some(data.to_vec());
        }
        let mut mesh: Mesh = from_cdr(data).unwrap();
        for v in &mut mesh.vertices {
            v.x *= 1.5;
        }
        Some(to_cdr(&mesh).unwrap())
    });
    let (code, json) = replay_json(&doctored);
    assert_eq!(code, Some(1), "{json}");
    assert_eq!(json["different"], 1, "{json}");
}

/// Issue #31: with `closed_loop.enabled` a dry run decides at each weld-path boundary. The
/// two walls welded one after the other: after the first weld path (no sensor readings:
/// the model stays nominal) the node re-plans the rest, says so on `~/status` with reason
/// and latency, records it, and the execution ends.
#[test]
fn closed_loop_dry_run_decides_at_the_weld_path_boundary_and_records_it() {
    use waam_rosmsg::diagnostic_msgs::DiagnosticArray;
    let tmp = tempfile::tempdir().unwrap();
    let bag_dir = tmp.path().join("bag");
    let out = common::run::waam()
        .args([
            "publish",
            "tests/data/two-walls.yaml",
            "--plan",
            "tests/data/plans/two-walls.yaml",
            "--params",
            "tests/ros/closed_loop.params.yaml",
            "--dry-run",
            "--linger",
            "0",
            "--record",
        ])
        .arg(&bag_dir)
        .current_dir(repo())
        .env("ROS_DOMAIN_ID", fresh_domain_id().to_string())
        .env("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
        .env_remove("ROS_LOCALHOST_ONLY")
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    let bag = waam_rosbag::Bag::open(&bag_dir).unwrap();
    let statuses: Vec<_> = bag
        .decode_all::<DiagnosticArray>()
        .unwrap()
        .into_iter()
        .flat_map(|(_, _, m)| m.status)
        .collect();
    let value = |s: &waam_rosmsg::diagnostic_msgs::DiagnosticStatus, key: &str| {
        s.values
            .iter()
            .find(|v| v.key == key)
            .map(|v| v.value.clone())
    };
    let replanned: Vec<_> = statuses
        .iter()
        .filter(|s| value(s, "state").as_deref() == Some("replanned"))
        .collect();
    // One boundary with weld paths left: after the first.
    assert_eq!(replanned.len(), 1, "{stderr}");
    let r = replanned[0];
    assert_eq!(value(r, "weld_paths_welded").as_deref(), Some("1"));
    let reason = value(r, "reason").unwrap();
    assert!(
        ["replan", "unchanged", "kept"].contains(&reason.as_str()),
        "{reason}"
    );
    let latency: f64 = value(r, "latency_s").unwrap().parse().unwrap();
    assert!(latency > 0.0 && latency < 60.0, "{latency}");
    // No readings: the nominal model, fitted to nothing.
    assert_eq!(value(r, "loss_factor").as_deref(), Some("1.0000"));
    assert!(statuses.iter().any(|s| s.message == "part 1: executed"));

    // `waam replay` makes the decision again from the recording (the plan was given with
    // --plan, not planned: only the decisions are compared).
    let replay = |bag: &Path| {
        let out = common::run::waam()
            .args(["replay", "--json", "--decisions-only"])
            .arg(bag)
            .output()
            .unwrap();
        let json: serde_json::Value = serde_json::from_slice(&out.stdout)
            .unwrap_or_else(|_| panic!("no JSON: {}", String::from_utf8_lossy(&out.stderr)));
        (out.status.code(), json)
    };
    let (code, json) = replay(&bag_dir);
    assert_eq!(code, Some(0), "{json}");
    assert_eq!(json["decisions_identical"], 1, "{json}");
    assert_eq!(
        json["decisions"][0]["recorded_reason"],
        reason.as_str(),
        "{json}"
    );
    // The recorded decision's plan altered: its last two blocks swapped.
    let doctored = tmp.path().join("doctored");
    common::run::copy_bag(&bag_dir, &doctored, |topic, data| {
        if !topic.ends_with("/status") {
            return Some(data.to_vec());
        }
        let mut msg: DiagnosticArray = waam_rosmsg::from_cdr(data).unwrap();
        for kv in msg.status.iter_mut().flat_map(|s| s.values.iter_mut()) {
            if kv.key == "loop.fragments" {
                let mut plan: Vec<Vec<[i64; 3]>> = serde_json::from_str(&kv.value).unwrap();
                let last = plan.last_mut().unwrap();
                let n = last.len();
                last.swap(n - 1, n - 2);
                kv.value = serde_json::to_string(&plan).unwrap();
            }
        }
        Some(waam_rosmsg::to_cdr(&msg).unwrap())
    });
    let (code, json) = replay(&doctored);
    assert_eq!(code, Some(1), "{json}");
    assert_eq!(json["decisions_different"], 1, "{json}");
    let details = json["decisions"][0]["details"].to_string();
    assert!(details.contains("first differing block"), "{details}");
}

/// `waam replay --decisions-only --json BAG`: every recorded closed-loop decision made again
/// identically (exit 0, none different, none unreproducible); the JSON.
fn decisions_replayed_identically(bag: &std::path::Path) -> serde_json::Value {
    let out = common::run::waam()
        .args(["replay", "--json", "--decisions-only"])
        .arg(bag)
        .output()
        .unwrap();
    let json: serde_json::Value = serde_json::from_slice(&out.stdout)
        .unwrap_or_else(|_| panic!("no JSON: {}", String::from_utf8_lossy(&out.stderr)));
    assert_eq!(out.status.code(), Some(0), "{json}");
    assert_eq!(json["decisions_different"], 0, "{json}");
    assert_eq!(json["decisions_not_reproducible"], 0, "{json}");
    json
}
