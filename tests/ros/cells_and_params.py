"""Two cells side by side, each configured through --ros-args, and parameters as rclpy sees them.

Node 1: `waam node --params tests/ros/fast.params.yaml --ros-args -r __ns:=/cell1
         -p planner.timeout_s:=20.0`
Node 2: `waam node --ros-args -r __ns:=/cell2 -r __node:=planner2 -r ~/status:=/cell2/state
         --params-file tests/ros/cell2.params.yaml` (rcl's form, keyed by the full node name)

1. rclpy lists node 1's parameters through the standard services (what `ros2 param list`
   calls): every setting of the parameters file is there; the values say where they came from
   (-p, --params, default); describe gives type, range and description.
2. Bad values are refused with a reason naming the parameter; a read-only one too.
3. mesh.block_mm is set to 12 x 6 x 2.5 mm: the next mesh (a 24 x 12 x 5 mm box, 16 blocks at
   the default pitch) is voxelized to 2 x 2 x 2 = 8 blocks.
4. Node 2 plans a part on its own topics (its status remapped) while node 1 runs.
5. Each node offers the URDF in use on <namespace>/robot_description (latched), and reports
   its state and last result on /diagnostics at least once a second.
(/tf_static is checked in tests/cli/ros_node.rs from its raw bytes: no tf2_msgs wheel exists.)
"""

import os
import time

from diagnostic_msgs.msg import DiagnosticArray
from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
from rcl_interfaces.srv import DescribeParameters, GetParameters, ListParameters, SetParameters
from shape_msgs.msg import Mesh
from std_msgs.msg import String

import waamtest
from waamtest import REPO, box_mesh, check

CELL1 = "/cell1/waam_planner"
CELL2 = "/cell2/planner2"
CELL2_STATUS = "/cell2/state"


def call(peer, srv_type, name, request, timeout=30, resend_after=3):
    """Calls service `name`, sending the request again every `resend_after` seconds.

    `service_is_ready` says only that the node's request reader was found; a request that
    arrives before the node has found this client's reply reader is answered into the void
    (seen once on a loaded CI machine). The requests here are reads and idempotent sets, so
    sending again is safe; no answer at all within `timeout` is a discovery failure."""
    client = peer.node.create_client(srv_type, name)
    peer.spin_until(f"service {name}", client.service_is_ready, timeout, discovery=True)
    deadline = time.monotonic() + timeout
    sent = []
    while True:
        sent.append(client.call_async(request))
        left = deadline - time.monotonic()
        try:
            peer.spin_until(f"the answer of {name}", lambda: any(f.done() for f in sent),
                            min(resend_after, max(left, 0)), discovery=True)
            return next(f for f in sent if f.done()).result()
        except waamtest.DiscoveryTimeout:
            if time.monotonic() >= deadline:
                raise


def get(peer, node, *names):
    reply = call(peer, GetParameters, node + "/get_parameters", GetParameters.Request(names=names))
    return reply.values


def set_one(peer, node, name, value):
    reply = call(peer, SetParameters, node + "/set_parameters",
                 SetParameters.Request(parameters=[Parameter(name=name, value=value)]))
    return reply.results[0]


def double_array(*v):
    return ParameterValue(type=ParameterType.PARAMETER_DOUBLE_ARRAY, double_array_value=list(v))


def double(v):
    return ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=v)


def states(peer, topic):
    return [
        (s.message, {kv.key: kv.value for kv in s.values})
        for a in peer.received[topic] for s in a.status
    ]


def outcome(peer, topic, job, timeout=120):
    def done():
        return any(v.get("job") == str(job) and v["state"] in ("planned", "error")
                   for _, v in states(peer, topic))
    # Nothing at all on the topic (not even "received" or "planning", which the node
    # publishes on every change) means its publisher was never matched: discovery.
    peer.spin_until(f"the outcome of part {job} on {topic}", done, timeout,
                    discovery=lambda: not peer.received[topic])
    return [s for s in states(peer, topic) if s[1].get("job") == str(job)][-1]


def test(peer, waam):
    cell2 = waamtest.WaamProcess(
        "node", "--ros-args", "-r", "__ns:=/cell2", "-r", "__node:=planner2",
        "-r", "~/status:=" + CELL2_STATUS, "--params-file", "tests/ros/cell2.params.yaml")
    try:
        run(peer, waam, cell2)
    except waamtest.Failure:
        print(f"--- log of node 2 ---\n{cell2.output()}")
        raise
    finally:
        cell2.stop()


def run(peer, waam, cell2):
    heard = {}  # diagnostics: hardware id -> [(arrival time, planner status)]

    def on_diagnostics(array):
        # Each node reports its planner and, as components of their own, its sensors.
        for s in array.status:
            if s.name.endswith(": planner"):
                heard.setdefault(s.hardware_id, []).append((time.monotonic(), s))

    peer.node.create_subscription(DiagnosticArray, "/diagnostics", on_diagnostics,
                                  waamtest.INPUT_QOS)
    peer.listen("/cell1/robot_description", String)
    peer.listen("/cell2/robot_description", String)
    peer.listen(CELL1 + "/status", DiagnosticArray, qos=waamtest.INPUT_QOS)
    peer.listen(CELL2_STATUS, DiagnosticArray, qos=waamtest.INPUT_QOS)
    mesh = peer.publisher(CELL1 + "/part_mesh", Mesh)
    part2 = peer.publisher(CELL2 + "/part", String)

    # 1. List, get, describe.
    listed = call(peer, ListParameters, CELL1 + "/list_parameters", ListParameters.Request())
    names = set(listed.result.names)
    expected = {
        "process_file", "robot.urdf", "robot.tip_link", "robot.tcp", "robot.joint_limits",
        "planner.timeout_s",
        "planner.default_max_fragments", "planner.max_memory_mb", "planner.threads",
        "mesh.block_mm", "mesh.bead_mm", "mesh.t85_window_s", "topics.part",
        "topics.part_mesh", "topics.joint_trajectory", "topics.poses", "topics.path",
        "topics.markers", "topics.weld_plan", "topics.status", "topics.arc_on",
        "topics.wire_feed", "topics.wire_feed_schedule", "topics.joint_states", "execution.enabled", "execution.auto_execute",
        "execution.controller_action",
        "execution.max_points_per_goal", "execution.server_timeout_s", "execution.lead_in_s",
        "execution.joint_names", "execution.goal_tolerance_rad", "execution.path_tolerance_rad",
        "execution.goal_time_tolerance_s", "execution.start_service",
        "dry_run.time_scale", "dry_run.rate_hz", "closed_loop.enabled", "closed_loop.scan_topic",
        "closed_loop.temperature_topic", "closed_loop.thermal_camera_topic",
        "closed_loop.arc_fault_topic", "closed_loop.max_age_s", "closed_loop.scan_margin_mm",
        "closed_loop.scan_period_s", "closed_loop.temperature_period_s",
        "closed_loop.thermal_camera_period_s",
        "closed_loop.wire_feed_min", "closed_loop.wire_feed_max",
        "closed_loop.wire_feed_per_deposit", "closed_loop.wire_feed_lead_s", "use_sim_time",
    }
    check(names == expected, f"parameters listed: {sorted(names)}; missing "
          f"{sorted(expected - names)}, unexpected {sorted(names - expected)}")
    timeout, lead_in, pitch = get(peer, CELL1, "planner.timeout_s", "execution.lead_in_s",
                                  "mesh.block_mm")
    check(timeout.type == ParameterType.PARAMETER_DOUBLE and timeout.double_value == 20.0,
          f"planner.timeout_s is {timeout} (expected 20.0 from -p)")
    check(lead_in.double_value == 1.0, f"execution.lead_in_s is {lead_in} (1.0 in --params)")
    check(list(pitch.double_array_value) == [6.0, 6.0, 2.5], f"mesh.block_mm is {pitch}")
    (timeout2,) = get(peer, CELL2, "planner.timeout_s")
    check(timeout2.double_value == 30.0,
          f"node 2's planner.timeout_s is {timeout2} (30.0 in its --params-file)")
    described = call(peer, DescribeParameters, CELL1 + "/describe_parameters",
                     DescribeParameters.Request(names=["planner.timeout_s", "topics.part"])).descriptors
    d = described[0]
    check(d.type == ParameterType.PARAMETER_DOUBLE and d.description
          and len(d.floating_point_range) == 1 and d.floating_point_range[0].from_value == 0.0
          and not d.read_only, f"planner.timeout_s described as {d}")
    check(described[1].read_only, f"topics.part is not read only: {described[1]}")

    # 2. Bad values are refused with a reason.
    for name, value, says in [
        ("mesh.block_mm", double_array(1.0, 2.0), "mesh.block_mm"),
        ("planner.timeout_s", double(-1.0), "planner.timeout_s"),
        ("planner.timeout_s", ParameterValue(type=ParameterType.PARAMETER_STRING,
                                             string_value="soon"), "expected a double"),
        ("topics.part", ParameterValue(type=ParameterType.PARAMETER_STRING,
                                       string_value="/x"), "read only"),
        ("no.such", double(1.0), "no such parameter"),
    ]:
        r = set_one(peer, CELL1, name, value)
        check(not r.successful and says in r.reason,
              f"setting {name} to {value} gave successful={r.successful}, reason {r.reason!r}")
    (timeout,) = get(peer, CELL1, "planner.timeout_s")
    check(timeout.double_value == 20.0, f"a refused set changed planner.timeout_s to {timeout}")

    # 3. A good value applies from the next plan.
    r = set_one(peer, CELL1, "mesh.block_mm", double_array(12.0, 6.0, 2.5))
    check(r.successful, f"setting mesh.block_mm refused: {r.reason}")
    (pitch,) = get(peer, CELL1, "mesh.block_mm")
    check(list(pitch.double_array_value) == [12.0, 6.0, 2.5], f"mesh.block_mm reads {pitch}")
    peer.wait_for_subscriber(mesh)
    mesh.publish(box_mesh(0.024, 0.012, 0.005))
    message, values = outcome(peer, CELL1 + "/status", 1)
    check(values["state"] == "planned", f"box not planned: {message}")
    check(values["blocks"] == "8", f"box voxelized to {values['blocks']} blocks, expected 8 "
          "(2 x 2 x 2 at the new pitch)")

    # 4. The second cell plans on its own topics.
    peer.wait_for_subscriber(part2)
    with open(os.path.join(REPO, "config", "parts", "s1-wall.yaml")) as f:
        part2.publish(String(data=f.read()))
    message, values = outcome(peer, CELL2_STATUS, 1)
    check(values["state"] == "planned", f"node 2 did not plan s1-wall: {message}")
    check(values["part"] == "s1-wall", f"node 2 planned {values.get('part')}")
    check(not any(v.get("part") == "s1-wall" for _, v in states(peer, CELL1 + "/status")),
          "node 1 saw node 2's part")
    check(waam.alive() and cell2.alive(), "a node exited")
    # Every status names its node by its fully qualified name, as /diagnostics does.
    for topic, node in ((CELL1 + "/status", CELL1), (CELL2_STATUS, CELL2)):
        ids = {s.hardware_id for a in peer.received[topic] for s in a.status}
        check(ids == {node}, f"{topic}: hardware_id {ids}, expected {node}")

    # 5. robot_description and /diagnostics.
    with open(os.path.join(REPO, "urdf", "waam_robot.urdf")) as f:
        urdf = f.read()
    for topic in ("/cell1/robot_description", "/cell2/robot_description"):
        peer.spin_until(topic, lambda: peer.received[topic], 10)
        check(peer.received[topic][-1].data == urdf, f"{topic} is not the bundled URDF")
    start = time.monotonic()
    peer.spin_for(3.5)
    for node, job in ((CELL1, "part 1"), (CELL2, "part 1")):
        times = [t for t, _ in heard.get(node, [])]
        check(len(times) >= 3, f"{len(times)} /diagnostics from {node}: {list(heard)}")
        recent = [t for t in times if t >= start]
        gaps = [b - a for a, b in zip(times, times[1:])]
        # Once a second; 0.5 s of slack for a loaded machine's scheduling.
        check(len(recent) >= 3 and max(gaps) < 1.5,
              f"/diagnostics from {node}: {len(recent)} in 3.5 s, largest gap {max(gaps):.2f} s")
        last = heard[node][-1][1]
        values = {kv.key: kv.value for kv in last.values}
        check(values.get("state") == "idle" and values.get("parts_planned") == "1"
              and values.get("last_result", "").startswith(job + ": planned"),
              f"/diagnostics of {node} say {last.message!r} {values}")


waamtest.run(test, "node", "--params", "tests/ros/fast.params.yaml",
             "--ros-args", "-r", "__ns:=/cell1", "-p", "planner.timeout_s:=20.0")
