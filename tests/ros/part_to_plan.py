"""rclpy sends part documents to waam_planner and checks every output.

1. a good part (s1-wall): JointTrajectory with the URDF's joint names and increasing times,
   a PoseArray and a Path with one pose per toolpath point, markers with one arc-on and one
   arc-off per fragment, and the status sequence received -> planning -> planned (the raw
   weld_plan is checked by tests/cli/ros_node.rs: rclpy has no type support for our message);
2. a malformed part: an ERROR status naming the problem, the node keeps running and
   publishes nothing new;
3. the next good part (s2-corner) is planned and published.
"""

import os
import xml.etree.ElementTree as ET

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseArray
from nav_msgs.msg import Path
from std_msgs.msg import String
from trajectory_msgs.msg import JointTrajectory
from visualization_msgs.msg import Marker, MarkerArray

import waamtest
from waamtest import REPO, check

NS = "/waam_planner"


def urdf_joint_names(path):
    """The movable joints of the URDF's chain, in file order."""
    root = ET.parse(path).getroot()
    return [
        j.get("name")
        for j in root.findall("joint")
        if j.get("type") in ("revolute", "continuous", "prismatic")
    ]


def statuses(peer):
    out = []
    for array in peer.received[NS + "/status"]:
        for s in array.status:
            out.append((waamtest.level(s), s.message, {kv.key: kv.value for kv in s.values}))
    return out


def wait_planned(peer, job, timeout=120):
    def done():
        return any(
            v.get("job") == str(job) and v.get("state") in ("planned", "error")
            for _, _, v in statuses(peer)
        )

    peer.spin_until(f"part {job} planned or failed", done, timeout)
    last = [s for s in statuses(peer) if s[2].get("job") == str(job)][-1]
    return last


def check_plan_outputs(peer, part_name, joint_names, values):
    """Checks the latest outputs against the URDF and the "planned" status values."""
    traj = peer.received[NS + "/plan/joint_trajectory"][-1]
    check(
        list(traj.joint_names) == joint_names,
        f"joint names {list(traj.joint_names)} are not the URDF's {joint_names}",
    )
    times = [p.time_from_start.sec + p.time_from_start.nanosec * 1e-9 for p in traj.points]
    check(len(times) >= 2, f"only {len(times)} trajectory points")
    check(
        all(b > a for a, b in zip(times, times[1:])),
        "trajectory times are not strictly increasing",
    )
    check(len(times) == int(values["trajectory_points"]), "trajectory length != status")
    for p in traj.points:
        check(len(p.positions) == len(joint_names), "a point without every joint position")

    poses = peer.received[NS + "/plan/poses"][-1]
    check(
        len(poses.poses) == int(values["toolpath_poses"]),
        f"{len(poses.poses)} poses for {values['toolpath_poses']} toolpath points",
    )
    check(poses.header.frame_id != "", "PoseArray without a frame")
    path = peer.received[NS + "/plan/path"][-1]
    check(len(path.poses) == len(poses.poses), "Path and PoseArray differ in length")
    for a, b in zip(path.poses, poses.poses):
        check(a.pose.position.x == b.position.x and a.pose.position.z == b.position.z,
              "Path and PoseArray disagree on a pose")

    fragments = int(values["fragments"])
    markers = peer.received[NS + "/plan/markers"][-1].markers
    check(markers[0].action == Marker.DELETEALL, "markers do not clear the previous plan")
    for ns in ("arc_on", "arc_off"):
        spheres = sorted(m.id for m in markers if m.ns == ns and m.action == Marker.ADD)
        check(
            spheres == list(range(fragments)),
            f"{ns} markers {spheres}, expected one per fragment 0..{fragments - 1}",
        )
    labels = sorted(m.text for m in markers if m.ns == "labels")
    expected = sorted([f"arc on {i + 1}" for i in range(fragments)]
                      + [f"arc off {i + 1}" for i in range(fragments)])
    check(labels == expected, f"labels {labels}")
    cubes = [m for m in markers if m.ns == "blocks"]
    check(len(cubes) == 1 and len(cubes[0].points) == int(values["blocks"]),
          "not one cube per block")
    check(len({(c.r, c.g, c.b) for c in cubes[0].colors}) == fragments,
          "cubes are not coloured by fragment")
    welds = [m for m in markers if m.ns == "weld"]
    check(len(welds) == fragments and all(len(w.points) >= 2 for w in welds),
          "not one weld line per fragment")
    check(any(m.ns == "transit" and m.points for m in markers), "no transit lines")


def test(peer, waam):
    joint_names = urdf_joint_names(os.path.join(REPO, "urdf", "waam_robot.urdf"))
    peer.listen(NS + "/status", DiagnosticArray, qos=waamtest.INPUT_QOS)
    peer.listen(NS + "/plan/joint_trajectory", JointTrajectory)
    peer.listen(NS + "/plan/poses", PoseArray)
    peer.listen(NS + "/plan/path", Path)
    peer.listen(NS + "/plan/markers", MarkerArray)
    part = peer.publisher(NS + "/part", String)
    peer.wait_for_subscriber(part)

    def send(name):
        with open(os.path.join(REPO, "config", "parts", name + ".yaml")) as f:
            part.publish(String(data=f.read()))

    # 1. A good part.
    send("s1-wall")
    level, message, values = wait_planned(peer, 1)
    check(values["state"] == "planned", f"part 1 not planned: {message}")
    states = [v["state"] for _, _, v in statuses(peer) if v.get("job") == "1"]
    check(states[0] == "received" and "planning" in states, f"status sequence {states}")
    check(values["part"] == "s1-wall" and values["blocks"] == "12", f"status values {values}")
    peer.spin_until(
        "all outputs of part 1",
        lambda: all(peer.received[t] for t in peer.received if "/plan/" in t),
        30,
    )
    check_plan_outputs(peer, "s1-wall", joint_names, values)

    # 2. A malformed part: ERROR status, node alive, nothing published.
    before = {t: len(v) for t, v in peer.received.items()}
    part.publish(String(data="name: broken\nblock_mm: [6, 6, 2.5]\nmax_fragments: 2\nlayers: [\n"))
    level, message, values = wait_planned(peer, 2)
    check(level == 2 and values["state"] == "error", f"malformed part gave {message!r}")
    check("bad part document" in message, f"error does not say what is wrong: {message!r}")
    check(waam.alive(), "waam node died on a malformed part")
    part.publish(String(data="name: x\nblock_mm: [6, 6, 2.5]\nmax_fragments: 0\nblocks: [[0,0,0]]\n"))
    level, message, values = wait_planned(peer, 3)
    check(level == 2 and "max_fragments" in message, f"bad max_fragments gave {message!r}")
    for t in before:
        if "/plan/" in t:
            check(len(peer.received[t]) == before[t], f"{t} published after a bad part")

    # 3. The next good part is planned.
    send("s2-corner")
    level, message, values = wait_planned(peer, 4)
    check(values["state"] == "planned", f"part after the errors not planned: {message}")
    peer.spin_until(
        "outputs of part 4",
        lambda: all(len(peer.received[t]) > before[t] for t in before if "/plan/" in t),
        30,
    )
    check_plan_outputs(peer, "s2-corner", joint_names, values)
    check(waam.alive(), "waam node exited")


waamtest.run(test, "node")
