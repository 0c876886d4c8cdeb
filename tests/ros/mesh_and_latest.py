"""A shape_msgs/Mesh box is voxelized and planned; a newer part cancels the one in progress.

1. A closed box of 24 x 12 x 5 mm (in metres, as shape_msgs/Mesh is) with the default pitch
   of 6 x 6 x 2.5 mm becomes 4 x 2 x 2 = 16 blocks and is planned.
2. A broken mesh (a triangle index out of range) gives an ERROR status.
3. The 168-block ex3 part is sent and, while it is being planned, s1-wall: the status says
   the first planning was cancelled, and only s1-wall's plan is published.
"""

import os

from diagnostic_msgs.msg import DiagnosticArray
from shape_msgs.msg import Mesh
from std_msgs.msg import String
from trajectory_msgs.msg import JointTrajectory

import waamtest
from waamtest import REPO, box_mesh, check

NS = "/waam_planner"


def all_status(peer):
    return [
        (waamtest.level(s), s.message, {kv.key: kv.value for kv in s.values})
        for a in peer.received[NS + "/status"]
        for s in a.status
    ]


def outcome(peer, job, timeout=120):
    def done():
        return any(
            v.get("job") == str(job) and v["state"] in ("planned", "error")
            for _, _, v in all_status(peer)
        )

    peer.spin_until(f"the outcome of part {job}", done, timeout)
    return [s for s in all_status(peer) if s[2].get("job") == str(job)][-1]


def test(peer, waam):
    peer.listen(NS + "/status", DiagnosticArray, qos=waamtest.INPUT_QOS)
    peer.listen(NS + "/plan/joint_trajectory", JointTrajectory)
    mesh = peer.publisher(NS + "/part_mesh", Mesh)
    part = peer.publisher(NS + "/part", String)
    peer.wait_for_subscriber(mesh)
    peer.wait_for_subscriber(part)

    # 1. A box mesh.
    mesh.publish(box_mesh(0.024, 0.012, 0.005))
    level, message, values = outcome(peer, 1)
    check(values["state"] == "planned", f"box mesh not planned: {message}")
    check(values["blocks"] == "16", f"box voxelized to {values['blocks']} blocks, expected 16")
    peer.spin_until("the box's trajectory", lambda: peer.received[NS + "/plan/joint_trajectory"], 30)

    # 2. A broken mesh.
    broken = box_mesh(0.024, 0.012, 0.005)
    broken.triangles[3].vertex_indices = [0, 1, 99]
    mesh.publish(broken)
    level, message, values = outcome(peer, 2)
    check(level == 2 and "mesh" in message, f"broken mesh gave {message!r}")

    # 3. Latest wins.
    trajectories = len(peer.received[NS + "/plan/joint_trajectory"])
    with open(os.path.join(REPO, "config", "parts", "ex3-h-column.yaml")) as f:
        part.publish(String(data=f.read()))
    peer.spin_until(
        "planning of part 3 to start",
        lambda: any(v.get("job") == "3" and v["state"] == "planning" for _, _, v in all_status(peer)),
        30,
    )
    with open(os.path.join(REPO, "config", "parts", "s1-wall.yaml")) as f:
        part.publish(String(data=f.read()))
    level, message, values = outcome(peer, 4)
    check(values["state"] == "planned", f"part 4 not planned: {message}")
    received4 = [v for _, _, v in all_status(peer) if v.get("job") == "4" and v["state"] == "received"]
    check(received4 and received4[0].get("cancelled_job") == "3",
          f"part 4's arrival does not say it cancelled part 3: {received4}")
    # Part 3 never gets a plan; give a stale result time to (wrongly) appear.
    peer.spin_for(3)
    check(not any(v.get("job") == "3" and v["state"] == "planned" for _, _, v in all_status(peer)),
          "the cancelled part 3 was published")
    check(len(peer.received[NS + "/plan/joint_trajectory"]) == trajectories + 1,
          "expected exactly one new trajectory (part 4's)")
    check(waam.alive(), "waam node exited")


waamtest.run(test, "node")
